"""Compiled evaluation: the model's CasADi function as C, looped over poses, compiled once and cached.

:func:`call` is the backend of :func:`mtcomp.models.evaluate.evaluate`. For a function of
``(q, p, c)`` it

1. splits off what depends on the parameters alone (computed once per call) and densifies the
   outputs (:func:`split_function`);
2. writes C for the rest that evaluates two poses at a time with SIMD vector extensions
   (:func:`batched_source`; ``p`` shared, ``q`` and ``c`` one row per pose, each output one row per
   pose, column-major within the row: exactly the layout of
   :func:`mtcomp.models.evaluate.casadi_map_call`), or, for operations that emitter does not know,
   CasADi's own generated code called once per pose. sin and cos of a per-pose angle are inline
   Taylor polynomials while the angle is small (below :data:`TAYLOR_LIMIT`, 2^-6 rad: the error
   angles of linear axes) and glibc's ``sincos`` otherwise (rotary axis angles). The pose body is
   written twice: a fast one with the polynomials only, straight-line code that the compiler can
   schedule as a whole, which reports a batch with a large angle, and an exact one that takes
   the polynomial or glibc lane by lane and reruns such a batch (and the next 64, so that a
   function with a rotary axis does not pay for both bodies);
3. compiles it with the system C compiler into a shared library in the cache directory, named by
   the hash of source, compiler and flags (``$MTCOMP_CACHE_DIR``, else ``$XDG_CACHE_HOME/mtcomp``,
   else ``~/.cache/mtcomp``), written to a temporary file and renamed so that concurrent processes
   never load a half-written library; a small index file lets a later process find it without
   generating the C again;
4. loads it with ctypes and calls it on numpy arrays.

Compiler flags keep IEEE semantics (no ``-ffast-math``, no ``-march``: SSE2, any x86-64; FMA
contraction off) and every arithmetic operation is the one CasADi's own evaluation does. The only
difference is sin and cos of small angles: the polynomials are within about half an ulp of the true
value, as glibc's are, so they agree with glibc's value to an ulp (in tests, bit for bit on all
error-model poses tried) and the results agree with CasADi's to the model's own rounding (1e-13 mm
and better; tests check 1e-13 times max(1, size of the output)). A pose's result does not depend on
the poses batched with it.

Environment:

* ``MTCOMP_CC``: the compiler to use (default: ``$CC``, else ``cc``, ``gcc``, ``clang`` on PATH). A
  path that does not exist means "no compiler": evaluation falls back to CasADi's map.
* ``MTCOMP_CACHE_DIR``: where libraries are kept.
* ``MTCOMP_COMPILE_MIN_POSES``: ``backend='auto'`` compiles a function that is not compiled yet
  once the process has evaluated it on this many poses in all (default 50,000). Compiling a 5-axis
  Jacobian takes tens of seconds, and the knots that the data choose make every campaign a new
  structure: a diagnosis of a 10,500-row 5-axis campaign (five evaluations of each file) took 42 s
  with compilation and 20 s on CasADi's map (10 s once compiled). A large fit (100,000 points)
  passes the threshold on its first call and compiles at once.
"""
from __future__ import annotations

import ctypes
import hashlib
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

import casadi as ca
import numpy as np

#: flags that keep results bit-compatible with plain double arithmetic on any x86-64
CFLAGS = ("-O3", "-fPIC", "-shared", "-fno-math-errno", "-ffp-contract=off", "-std=c99")
#: added for GCC to sources marked with :data:`SCHEDULE_MARK`: scheduling before register
#: allocation, register-pressure aware, and register renaming after it; the arithmetic is unchanged.
#: The fast pose body of a small function is one long basic block that this makes 15-20 % faster
#: (xfyz deviation and J_q); for larger bodies it raises register pressure more than it gains
#: (cafxyz deviation and J_q 5 % slower, J_p 40 % slower), so they are not marked
GCC_FLAGS = ("-fschedule-insns", "-fsched-pressure", "-frename-registers")
SCHEDULE_MARK = "/* mtcomp: schedule before register allocation */\n"
#: largest pose body (CasADi instructions) whose source is marked
SCHEDULE_MAX_INSTRUCTIONS = 1200

#: number of compiler runs in this process (tests read it to check cache reuse)
compile_count = 0

_NOTICE = "mtcomp: no C compiler found; using CasADi's own evaluation (slower)"
_notice_given = False
_said: set = set()
_lock = threading.Lock()
_loaded: dict = {}  # (structure key, function name, fingerprint) -> _Compiled


class CompileError(RuntimeError):
    """The C compiler is missing or failed."""


def cache_dir() -> Path:
    """Directory of compiled libraries (created on demand)."""
    env = os.environ.get("MTCOMP_CACHE_DIR")
    if env:
        return Path(env)
    xdg = os.environ.get("XDG_CACHE_HOME")
    base = Path(xdg) if xdg else Path.home() / ".cache"
    return base / "mtcomp"


def _private_cache_dir() -> Path:
    """The cache directory, created if needed, after checking that only this user can write to it
    (libraries are loaded from it). Raises CompileError otherwise."""
    d = cache_dir()
    try:
        d.mkdir(parents=True, exist_ok=True, mode=0o700)
        st = d.stat()
    except OSError as exc:
        raise CompileError(f"cannot create cache directory {d}: {exc}") from None
    if hasattr(os, "getuid") and (st.st_uid != os.getuid() or st.st_mode & 0o022):
        raise CompileError(f"cache directory {d} is writable by other users; not loading code from it")
    return d


def find_compiler() -> str | None:
    """Path of the C compiler, or None. ``MTCOMP_CC`` overrides (a missing path means none)."""
    env = os.environ.get("MTCOMP_CC")
    if env is not None:
        return shutil.which(env) if env else None
    cc = os.environ.get("CC")
    for cand in ([cc] if cc else []) + ["cc", "gcc", "clang"]:
        path = shutil.which(cand)
        if path:
            return path
    return None


#: a function is compiled once it has been evaluated at this many poses (MTCOMP_COMPILE_MIN_POSES)
MIN_POSES = 50_000


def _min_poses() -> int:
    """MTCOMP_COMPILE_MIN_POSES when it is an integer, else MIN_POSES."""
    try:
        return int(os.environ.get("MTCOMP_COMPILE_MIN_POSES", MIN_POSES))
    except ValueError:
        return MIN_POSES


def _notice():
    global _notice_given
    if not _notice_given:
        _notice_given = True
        print(_NOTICE, file=sys.stderr)


# --------------------------------------------------------------------------------- code generation
def split_function(function: ca.Function) -> tuple[ca.Function, ca.Function, list[tuple[int, int]]]:
    """Split ``function`` of (q, p, c) for the pose loop.

    Returns (pre, body, shapes): ``pre(p) -> w`` computes once per call every subexpression that
    depends on p alone (trigonometry of squareness and location errors ...), ``body(q, p, w, c)``
    gives every output densified and stacked column by column, with common subexpressions merged;
    ``shapes`` are the (rows, cols) of the outputs. The arithmetic of every node is unchanged, so
    the results are those of ``function``.
    """
    if function.is_a("SXFunction"):
        q, p, c = function.sx_in()
    else:
        q, p, c = (ca.SX.sym(function.name_in(k), function.sparsity_in(k)) for k in range(3))
    outs = [ca.densify(o) for o in function.call([q, p, c])]
    shapes = [o.shape for o in outs]
    stacked = ca.vertcat(*[ca.vec(o) for o in outs])
    body_expr, symbols, parametric = ca.extract_parametric(stacked, p)
    w = ca.vertcat(*symbols) if symbols else ca.SX.sym("w", 0)
    w_expr = ca.vertcat(*parametric) if parametric else ca.SX(0, 1)
    pre = ca.Function("mtcomp_pre", [p], [w_expr], {"cse": True})
    body = ca.Function("mtcomp_f", [q, p, w, c], [body_expr], {"cse": True})
    return pre, body, shapes


_LOOP = r"""
/* ---- mtcomp: loop over poses (p shared, q and c one row per pose) ---- */
#include <stdlib.h>
int mtcomp_loop(long long n, const double* q, const double* p, const double* c, double** out) {
  const casadi_real* arg[%(sz_arg)d + 1];
  casadi_real* res[%(sz_res)d + 1];
  casadi_int iw[%(sz_iw)d + 1];
  casadi_real* w = (casadi_real*)malloc(sizeof(casadi_real) * (%(sz_w)d + %(nw)d + %(nout)d + 1));
  casadi_real* pw;
  casadi_real* buf;
  long long i;
  int k;
  if (!w) return 1;
  pw = w + %(sz_w)d;
  buf = pw + %(nw)d;
  for (k = 0; k < %(sz_arg)d; ++k) arg[k] = 0;
  for (k = 0; k < %(sz_res)d; ++k) res[k] = 0;
  arg[0] = p;
  res[0] = pw;
  if (mtcomp_pre(arg, res, iw, w, 0)) { free(w); return 2; }
  arg[1] = p;
  arg[2] = pw;
  res[0] = buf;
  for (i = 0; i < n; ++i) {
    arg[0] = q + i * %(nq)d;
    arg[3] = c + i * %(nc)d;
    if (mtcomp_f(arg, res, iw, w, 0)) { free(w); return 2; }
%(scatter)s
  }
  free(w);
  return 0;
}
"""


_TRIG = re.compile(r"^(\s*)(a\w+)=(sin|cos)\((a\w+)\);$")
_ASSIGN = re.compile(r"^\s*(a\w+)=")


def merge_sincos(src: str) -> str:
    """Replace each pair sin(a), cos(a) of the same value in the generated straight-line code by
    one call of glibc's ``sincos`` (which returns bit for bit what sin and cos return; half the
    cost). Variables are reassigned in CasADi's code, so a pair is only merged while its argument
    keeps its value."""
    lines = src.split("\n")
    version: dict[str, int] = {}
    first: dict[tuple[str, int], tuple[int, str]] = {}  # (arg, version) -> (line, 'sin' or 'cos')
    pairs = []
    for i, line in enumerate(lines):
        if line and not line[0].isspace():  # a new function: its variables are new
            first.clear()
        m = _TRIG.match(line)
        if m:
            arg = m.group(4)
            key = (arg, version.get(arg, 0))
            if key in first and first[key][1] != m.group(3):
                pairs.append((first.pop(key)[0], i))
            elif key not in first:
                first[key] = (i, m.group(3))
        a = _ASSIGN.match(line)
        if a:
            version[a.group(1)] = version.get(a.group(1), 0) + 1
    for k, (i, j) in enumerate(pairs):
        mi, mj = _TRIG.match(lines[i]), _TRIG.match(lines[j])
        s_var, c_var = f"mtcomp_s{k}", f"mtcomp_c{k}"
        lines[i] = (f"{mi.group(1)}casadi_real {s_var}, {c_var}; sincos({mi.group(4)}, &{s_var}, &{c_var}); "
                    f"{mi.group(2)}={s_var if mi.group(3) == 'sin' else c_var};")
        lines[j] = f"{mj.group(1)}{mj.group(2)}={s_var if mj.group(3) == 'sin' else c_var};"
    if not pairs:
        return src
    return "void sincos(double, double*, double*);\n" + "\n".join(lines)


def generate_source(function: ca.Function, merge: bool = True) -> tuple[str, list[int]]:
    """C source of ``function`` (split by :func:`split_function`) with the pose loop appended.

    ``merge`` (glibc only): the fast form, poses in SIMD pairs (:func:`batched_source`) or, for an
    operation the batched emitter does not know, CasADi's code per pose with sin/cos pairs merged
    (:func:`merge_sincos`). Otherwise CasADi's code per pose as it is (any C99 compiler and libm).
    Returns (source, output sizes per pose: rows*cols of each output).
    """
    fast = merge and sys.platform.startswith("linux")
    if fast:
        try:
            return batched_source(function)
        except _Unsupported:
            pass
    pre, body, shapes = split_function(function)
    src = _casadi_source([pre, body])
    if fast:
        src = merge_sincos(src)
    sizes = [r * k for r, k in shapes]
    scatter, offset = [], 0
    for k, size in enumerate(sizes):
        scatter.append(f"    for (k = 0; k < {size}; ++k) out[{k}][i * {size} + k] = buf[{offset} + k];")
        offset += size
    sz = lambda name: max(getattr(pre, name)(), getattr(body, name)())  # noqa: E731
    src += _LOOP % {"sz_arg": sz("sz_arg"), "sz_res": sz("sz_res"), "sz_iw": sz("sz_iw"),
                    "sz_w": sz("sz_w"), "nw": pre.numel_out(0), "nout": offset,
                    "nq": body.numel_in(0), "nc": body.numel_in(3), "scatter": "\n".join(scatter)}
    return src, sizes


# --------------------------------------------------------------------------------- batched C
#: poses per SIMD vector (SSE2, the x86-64 baseline, holds two doubles)
LANES = 2

_OPS = {getattr(ca, n): n for n in dir(ca) if n.startswith("OP_")}
_UNARY = {"OP_ASSIGN": "{0}", "OP_NEG": "(-{0})", "OP_SQ": "({0}*{0})", "OP_TWICE": "(2.*{0})",
         "OP_SIN": "sin({0})", "OP_COS": "cos({0})", "OP_TAN": "tan({0})", "OP_SQRT": "sqrt({0})",
         "OP_INV": "(1./{0})", "OP_FABS": "fabs({0})", "OP_EXP": "exp({0})", "OP_LOG": "log({0})",
         "OP_ASIN": "asin({0})", "OP_ACOS": "acos({0})", "OP_ATAN": "atan({0})"}
_BINARY = {"OP_ADD": "({0}+{1})", "OP_SUB": "({0}-{1})", "OP_MUL": "({0}*{1})", "OP_DIV": "({0}/{1})",
          "OP_POW": "pow({0},{1})", "OP_CONSTPOW": "pow({0},{1})", "OP_ATAN2": "atan2({0},{1})",
          "OP_FMIN": "fmin({0},{1})", "OP_FMAX": "fmax({0},{1})"}



class _Unsupported(Exception):
    """The batched emitter does not know an operation of the function."""


def batched_body(body: ca.Function, lanes: int, varying_inputs: set, out_map: dict,
                 name: str = "mtcomp_batch", trig: str = "exact") -> tuple[str, list[tuple[int, int]], bool]:
    """C of ``body`` evaluated on ``lanes`` poses at once with GCC/Clang vector extensions.

    ``static int name(const double** in, const vd* shared, double** out)``: ``in[k]`` points at
    the first pose's row of input k (rows of ``numel_in(k)`` values) for k in ``varying_inputs``;
    the stacked output's entry nz goes to ``out[k][pose * row + m]`` with ``(k, m, row) =
    out_map[nz]``. Per-pose values are vectors of ``lanes`` doubles, so +, -, *, / run as SIMD
    instructions (IEEE results, lane by lane the same as scalar code). Entries of the shared inputs
    are read from ``shared[slot]``, the entry broadcast to all lanes once per call by the caller
    (so that they enter SIMD instructions as memory operands), with ``slots[slot] = (input, nz)``.
    sin and cos go through ``mt_sincos`` (``trig='exact'``) or ``mt_sincos_small`` (``trig='fast'``:
    polynomials only; the function returns nonzero when an angle was outside their range and the
    outputs are then to be discarded) (:func:`_trig_source`); other library functions are called
    per lane. Returns (C source, slots, whether there are sin/cos pairs). Raises _Unsupported for an
    operation it does not know.
    """
    n = body.n_instructions()
    ids = [_OPS.get(body.instruction_id(k), "?") for k in range(n)]
    # pair sin/cos of the same value: pair_id[k] = (t, is_first)
    version, first, pair_id = {}, {}, {}
    n_pairs = 0
    for k in range(n):
        op = ids[k]
        if op in ("OP_SIN", "OP_COS"):
            i = body.instruction_input(k)[0]
            key = (i, version.get(i, 0))
            if key in first and ids[first[key]] != op:
                pair_id[first.pop(key)] = (n_pairs, True)
                pair_id[k] = (n_pairs, False)
                n_pairs += 1
            elif key not in first:
                first[key] = k
        if op != "OP_OUTPUT":
            o = body.instruction_output(k)[0]
            version[o] = version.get(o, 0) + 1
    uni = {}
    slots: dict = {}
    used_u, used_v = set(), set()
    lines = []
    L = lanes

    ARITH = {"OP_ASSIGN", "OP_NEG", "OP_SQ", "OP_TWICE", "OP_INV", "OP_ADD", "OP_SUB", "OP_MUL", "OP_DIV"}
    lane = {"j": None}

    def opnd(i):
        if uni[i]:
            used_u.add(i)
            return f"u{i}"
        used_v.add(i)
        return f"v{i}" if lane["j"] is None else f"v{i}[{lane['j']}]"

    def assign(o, is_uni, expr, fn=None):
        uni[o] = is_uni
        if is_uni:
            used_u.add(o)
            lines.append(f"  u{o}={expr};")
        elif fn is None:  # vector arithmetic
            used_v.add(o)
            lines.append(f"  v{o}={expr};")
        else:  # lane by lane
            used_v.add(o)
            parts = []
            for jj in range(L):
                lane["j"] = jj
                parts.append(fn())
            lane["j"] = None
            lines.append(f"  v{o}=(vd){{{', '.join(parts)}}};")

    for k in range(n):
        op = ids[k]
        ins = body.instruction_input(k)
        if op == "OP_INPUT":
            idx, nz = ins
            o = body.instruction_output(k)[0]
            if idx in varying_inputs:
                row = body.numel_in(idx)
                assign(o, False, None, fn=lambda: f"in[{idx}][{lane['j']}*{row}+{nz}]")
            else:
                slot = slots.setdefault((idx, nz), len(slots))
                assign(o, False, f"shared[{slot}]")
        elif op == "OP_OUTPUT":
            idx, nz = body.instruction_output(k)
            kk, m, row = out_map[nz]
            i = ins[0]
            if uni[i]:
                lines.append(f"  for (j=0;j<{L};++j) out[{kk}][j*{row}+{m}]=u{i};")
                used_u.add(i)
            else:
                lines.append(f"  for (j=0;j<{L};++j) out[{kk}][j*{row}+{m}]=v{i}[j];")
                used_v.add(i)
        elif op == "OP_CONST":
            c = body.instruction_constant(k)
            if not math.isfinite(c):
                raise _Unsupported("non-finite constant")
            assign(body.instruction_output(k)[0], True, float.hex(c))
        elif op in ("OP_SIN", "OP_COS") and not uni[ins[0]]:
            i, o = ins[0], body.instruction_output(k)[0]
            t, is_first = pair_id.get(k, (None, True))
            if t is None:  # sin or cos alone: the other result goes unused
                t = n_pairs
                n_pairs += 1
            if is_first:
                used_v.add(i)
                if trig == "exact":
                    lines.append(f"  mt_sincos(v{i},&vs{t},&vc{t});")
                else:
                    lines.append(f"  mt_sincos_small(v{i},&vs{t},&vc{t},&large);")
            assign(o, False, f"vs{t}" if op == "OP_SIN" else f"vc{t}")
        elif op in _UNARY:
            i, o = ins[0], body.instruction_output(k)[0]
            if op in ARITH or uni[i]:
                assign(o, uni[i], _UNARY[op].format(opnd(i)))
            else:
                assign(o, False, None, fn=lambda: _UNARY[op].format(opnd(i)))
        elif op in _BINARY:
            a, b = ins[0], ins[1]
            o = body.instruction_output(k)[0]
            if op in ARITH or (uni[a] and uni[b]):
                assign(o, uni[a] and uni[b], _BINARY[op].format(opnd(a), opnd(b)))
            else:
                assign(o, False, None, fn=lambda: _BINARY[op].format(opnd(a), opnd(b)))
        else:
            raise _Unsupported(op)
    decl = [f"static __attribute__((noinline)) int {name}(const double** in, const vd* shared, "
            f"double** out) {{", "  int j;"]
    if trig != "exact":
        decl.append("  vl large = {0};")
    if used_u:
        decl.append("  double " + ", ".join(f"u{i}" for i in sorted(used_u)) + ";")
    if used_v:
        decl.append("  vd " + ", ".join(f"v{i}" for i in sorted(used_v)) + ";")
    if n_pairs:
        decl.append("  vd " + ", ".join(f"vs{t}, vc{t}" for t in range(n_pairs)) + ";")
    any_large = " | ".join(f"large[{j}]" for j in range(L)) if trig != "exact" and n_pairs else "0"
    return "\n".join(decl + lines + [f"  return ({any_large}) != 0;", "}"]) + "\n", list(slots), n_pairs > 0


#: run the fast body (sin and cos as polynomials) on a batch, and the exact one on a batch where a
#: polynomial did not hold; after such a batch, the next ones go to the exact body directly (a
#: function with a large angle, a rotary axis's, does not pay for both bodies every time)
_RUN_TWO = r"""
static void mtcomp_run(const double** in, const vd* shared, double** o, int* skip) {
  if (*skip > 0) {
    --*skip;
    mtcomp_exact(in, shared, o);
  } else if (mtcomp_fast(in, shared, o)) {
    mtcomp_exact(in, shared, o);
    *skip = 64;
  }
}
"""
_RUN_ONE = r"""
static void mtcomp_run(const double** in, const vd* shared, double** o, int* skip) {
  (void)skip;
  mtcomp_exact(in, shared, o);
}
"""

_BATCH_LOOP = r"""
/* ---- mtcomp: loop over poses, %(L)d at a time (p shared, q and c one row per pose) ---- */
void sincos(double, double*, double*);
typedef double vd __attribute__((vector_size(%(vbytes)d)));
typedef long long vl __attribute__((vector_size(%(vbytes)d)));
%(trig)s
%(batch)s
int mtcomp_loop(long long n, const double* q, const double* p, const double* c, double** out) {
  const casadi_real* arg[%(sz_arg)d + 1];
  casadi_real* res[%(sz_res)d + 1];
  casadi_int iw[%(sz_iw)d + 1];
  casadi_real w[%(sz_w)d + 1], pw[%(nw)d + 1];
  const double* in[4];
  double* o[%(nout)d];
  double qb[%(L)d * %(nq)d + 1], cb[%(L)d * %(nc)d + 1];
  vd shared[%(n_shared)d + 1];
%(obuf)s
  long long i;
  int k, j, r, skip = 0;
  for (k = 0; k < %(sz_arg)d; ++k) arg[k] = 0;
  for (k = 0; k < %(sz_res)d; ++k) res[k] = 0;
  arg[0] = p;
  res[0] = pw;
  if (mtcomp_pre(arg, res, iw, w, 0)) return 2;
  in[1] = p;
  in[2] = pw;
%(broadcast)s
  for (i = 0; i + %(L)d <= n; i += %(L)d) {
    in[0] = q + i * %(nq)d;
    in[3] = c + i * %(nc)d;
%(oset)s
    mtcomp_run(in, shared, o, &skip);
  }
  if (i < n) {
    r = (int)(n - i);
    for (j = 0; j < %(L)d; ++j) {
      int src = j < r ? j : r - 1;
      for (k = 0; k < %(nq)d; ++k) qb[j * %(nq)d + k] = q[(i + src) * %(nq)d + k];
      for (k = 0; k < %(nc)d; ++k) cb[j * %(nc)d + k] = c[(i + src) * %(nc)d + k];
    }
    in[0] = qb;
    in[3] = cb;
%(obset)s
    mtcomp_run(in, shared, o, &skip);
%(obcopy)s
  }
  return 0;
}
"""



def _trig_source(lanes: int) -> str:
    """C of the sin/cos of a vector of ``lanes`` angles: ``mt_sincos(x, &s, &c)`` (exact body:
    lane by lane the Taylor polynomials of :data:`_TAYLOR` for |x| < :data:`TAYLOR_LIMIT`, glibc's
    ``sincos`` otherwise, inf and NaN included) and ``mt_sincos_small(x, &s, &c, &large)`` (fast
    body: the polynomials, lanes outside their range marked in ``large``)."""
    L = lanes
    all_small = " & ".join(f"small[{j}]" for j in range(L))
    return _TRIG_C % {"all_small": all_small, "L": L,
                      **{k: float.hex(v) for k, v in _TAYLOR.items()}, "lim": float.hex(TAYLOR_LIMIT)}


#: |x| below which sin and cos are the Taylor polynomials of :data:`_TAYLOR`
TAYLOR_LIMIT = 2.0 ** -6

#: Taylor coefficients of sin (x^3 .. x^7) and cos (x^2 .. x^6), rounded to double. For |x| <
#: TAYLOR_LIMIT the first omitted terms are below x^9/9! (relative to sin x: < 2^-48/9! ~ 1e-20)
#: and x^8/8! (< 2^-48/8! ~ 9e-20), far below half an ulp (1.1e-16). The rounding errors of the
#: correction term (x^3/6 or x^2/2 and beyond, at most 2^-12 of the result) are below 2^-12 ulp, so
#: the error is the last addition's, about half an ulp, as glibc's sin and cos
_TAYLOR = {"s3": -1 / 6, "s5": 1 / 120, "s7": -1 / 5040,
           "c2": -1 / 2, "c4": 1 / 24, "c6": -1 / 720}

_TRIG_C = r"""
static void __attribute__((noinline, cold)) mt_sincos_libm(vd x, vl small, vd* s, vd* c) {
  int j;
  double sj, cj;  /* not &(*s)[j]: Clang refuses the address of a vector element */
  for (j = 0; j < %(L)d; ++j)
    if (!small[j]) {
      sincos(x[j], &sj, &cj);
      (*s)[j] = sj;
      (*c)[j] = cj;
    }
}
/* the polynomials in every lane; returns the lanes where they hold (|x| < lim; not NaN). sin(-0)
   comes out as +0 (-0 + 0 = +0): equal values; fixing the sign costs ~7 %% of the whole body */
static inline __attribute__((always_inline)) vl mt_sincos_poly(vd x, vd* s, vd* c) {
  vd x2 = x * x;
  vd ax = (vd)((vl)x & 0x7fffffffffffffffLL);
  *s = x + x * (x2 * (%(s3)s + x2 * (%(s5)s + x2 * %(s7)s)));
  *c = 1. + x2 * (%(c2)s + x2 * (%(c4)s + x2 * %(c6)s));
  return ax < %(lim)s;
}
/* fast body: polynomials only, lanes where they do not hold are marked in *large */
static inline __attribute__((always_inline)) void mt_sincos_small(vd x, vd* s, vd* c, vl* large) {
  *large |= ~mt_sincos_poly(x, s, c);
}
/* exact body: polynomials where they hold, glibc's sincos in the other lanes */
static inline __attribute__((always_inline)) void mt_sincos(vd x, vd* s, vd* c) {
  vl small = mt_sincos_poly(x, s, c);
  if (__builtin_expect(!(%(all_small)s), 0)) mt_sincos_libm(x, small, s, c);
}
"""


def batched_source(function: ca.Function, lanes: int = LANES) -> tuple[str, list[int]]:
    """C source of ``function`` with the pose loop running :func:`batched_body` on ``lanes`` poses at
    a time (the last, partial batch is padded with copies of the last pose). Raises _Unsupported."""
    pre, body, shapes = split_function(function)
    sizes = [r * k for r, k in shapes]
    out_map, off = {}, 0
    for kk, size in enumerate(sizes):
        for m in range(size):
            out_map[off + m] = (kk, m, size)
        off += size
    batch, slots, has_trig = batched_body(body, lanes, {0, 3}, out_map, "mtcomp_exact", "exact")
    if has_trig:
        fast, slots_fast, _ = batched_body(body, lanes, {0, 3}, out_map, "mtcomp_fast", "fast")
        assert slots_fast == slots
        batch += fast + _RUN_TWO
    else:
        batch += _RUN_ONE
    src = _casadi_source([pre])
    L = lanes
    fill = {"batch": batch, "trig": _trig_source(lanes), "vbytes": 8 * lanes,
            "sz_arg": pre.sz_arg(), "sz_res": pre.sz_res(),
            "sz_iw": pre.sz_iw(), "sz_w": pre.sz_w(), "nw": pre.numel_out(0), "nout": len(sizes),
            "n_shared": len(slots),
            "broadcast": "\n".join(f"  for (j = 0; j < {L}; ++j) shared[{s}][j] = in[{i}][{nz}];"
                                   for s, (i, nz) in enumerate(slots)),
            "L": L, "nq": body.numel_in(0), "nc": body.numel_in(3),
            "obuf": "\n".join(f"  double ob{k}[{L} * {s}];" for k, s in enumerate(sizes)),
            "oset": "\n".join(f"    o[{k}] = out[{k}] + i * {s};" for k, s in enumerate(sizes)),
            "obset": "\n".join(f"    o[{k}] = ob{k};" for k in range(len(sizes))),
            "obcopy": "\n".join(f"    for (j = 0; j < r * {s}; ++j) out[{k}][i * {s} + j] = ob{k}[j];"
                                for k, s in enumerate(sizes))}
    mark = SCHEDULE_MARK if has_trig and body.n_instructions() <= SCHEDULE_MAX_INSTRUCTIONS else ""
    return mark + src + _BATCH_LOOP % fill, sizes


def _casadi_source(functions) -> str:
    with tempfile.TemporaryDirectory() as tmp:
        cg = ca.CodeGenerator("mtcomp_f.c", {"with_header": False, "casadi_real": "double",
                                            "casadi_int": "long long"})
        for f in functions:
            cg.add(f)
        path = cg.generate(tmp + os.sep)
        return Path(path).read_text()


_is_gcc: dict = {}  # compiler path -> whether it is GCC


def compile_flags(compiler: str, src: str = SCHEDULE_MARK) -> tuple[str, ...]:
    """Flags for ``compiler`` and ``src``: :data:`CFLAGS`, plus :data:`GCC_FLAGS` when it is GCC
    and the source starts with :data:`SCHEDULE_MARK`."""
    if compiler not in _is_gcc:
        try:  # the predefined macros tell GCC (__GNUC__ alone) from Clang (which also defines it)
            out = subprocess.run([compiler, "-E", "-dM", "-x", "c", "-"], input="", capture_output=True,
                                 text=True, timeout=60).stdout
        except (OSError, subprocess.SubprocessError):
            out = ""
        _is_gcc[compiler] = "#define __GNUC__ " in out and "__clang__" not in out
    return CFLAGS + (GCC_FLAGS if _is_gcc[compiler] and src.startswith(SCHEDULE_MARK) else ())


def compile_source(src: str, compiler: str) -> Path:
    """Compile ``src`` into the cache (or reuse a cached library). Raises CompileError."""
    global compile_count
    flags = compile_flags(compiler, src)
    key = hashlib.sha256("\0".join([src, compiler, *flags]).encode()).hexdigest()[:24]
    out_dir = _private_cache_dir()
    lib = out_dir / f"mtcomp_{key}.so"
    if lib.exists():
        return lib
    with tempfile.TemporaryDirectory(dir=out_dir, prefix=".build-") as tmp:
        c_file = Path(tmp) / f"mtcomp_{key}.c"
        c_file.write_text(src)
        tmp_lib = Path(tmp) / f"mtcomp_{key}.so"
        cmd = [compiler, *flags, str(c_file), "-o", str(tmp_lib), "-lm"]
        try:
            proc = subprocess.run(cmd, capture_output=True, text=True)
        except OSError as exc:
            raise CompileError(f"cannot run {compiler}: {exc}") from None
        compile_count += 1
        if proc.returncode != 0 or not tmp_lib.exists():
            raise CompileError(f"{compiler} failed: {proc.stderr.strip()[:2000]}")
        os.replace(tmp_lib, lib)  # atomic: another process sees the old state or the whole file
    return lib


class _Compiled:
    def __init__(self, lib_path: Path, sizes: list[int], nq: int, nc: int, n_p: int):
        self.lib = ctypes.CDLL(str(lib_path))
        self.fn = self.lib.mtcomp_loop
        self.fn.restype = ctypes.c_int
        self.fn.argtypes = [ctypes.c_longlong, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p,
                            ctypes.POINTER(ctypes.c_void_p)]
        self.sizes, self.nq, self.nc, self.n_p = sizes, nq, nc, n_p

    def __call__(self, q: np.ndarray, p: np.ndarray, c: np.ndarray) -> list[np.ndarray]:
        n = q.shape[0]
        q = np.ascontiguousarray(q, dtype=np.float64)
        p = np.ascontiguousarray(p, dtype=np.float64)
        c = np.ascontiguousarray(c, dtype=np.float64)
        if q.shape != (n, self.nq) or p.shape != (self.n_p,) or c.shape != (n, self.nc):
            raise ValueError("compiled call: shapes of q, p, c do not match the function")
        outs = [np.empty((n, s)) for s in self.sizes]
        ptrs = (ctypes.c_void_p * max(1, len(outs)))(*[o.ctypes.data for o in outs])
        status = self.fn(n, q.ctypes.data, p.ctypes.data, c.ctypes.data, ptrs)
        if status != 0:
            raise RuntimeError(f"compiled evaluation failed (status {status})")
        return outs


_sources: dict = {}  # ((structure key, function name, fingerprint), merged) -> (source, sizes)
_failed: dict = {}  # (structure key, function name, compiler) -> message of the failure


def forget_loaded():
    """Drop the in-process caches of libraries, sources, failures, lookups and use counts (the disk
    cache stays)."""
    with _lock:
        _loaded.clear()
        _failed.clear()
        _sources.clear()
        _not_on_disk.clear()
        _poses_used.clear()


def _source(skey, function, merge: bool):
    if (skey, merge) not in _sources:
        _sources[(skey, merge)] = generate_source(function, merge=merge)
    return _sources[(skey, merge)]


def _generator_fingerprint() -> str:
    """Hash of this module's code and CasADi's version: a change of either makes new libraries."""
    global _GENERATOR
    if _GENERATOR is None:
        _GENERATOR = hashlib.sha256(Path(__file__).read_bytes() + ca.__version__.encode()).hexdigest()
    return _GENERATOR


_GENERATOR = None
#: (structure key, compiler) of functions with no library on disk when last looked for
_not_on_disk: set = set()
#: (model structure key, function name) -> poses evaluated in this process
_poses_used: dict = {}


def _index_path(function: ca.Function, compiler: str) -> Path:
    """Small file naming the library built for this function (so that a new process finds a cached
    library without generating the C again)."""
    key = hashlib.sha256(b"\0".join([function.serialize().encode(), compiler.encode(),
                                      " ".join(compile_flags(compiler)).encode(),
                                      _generator_fingerprint().encode()]))
    return cache_dir() / f"index-{key.hexdigest()[:24]}"


def _from_index(function: ca.Function, compiler: str) -> Path | None:
    try:
        name = _index_path(function, compiler).read_text().strip()
    except OSError:
        return None
    lib = cache_dir() / name
    return lib if name.startswith("mtcomp_") and lib.exists() else None


def _write_index(function: ca.Function, compiler: str, lib: Path):
    path = _index_path(function, compiler)
    try:
        with tempfile.NamedTemporaryFile("w", dir=path.parent, prefix=".index-", delete=False) as fh:
            fh.write(lib.name)
        os.replace(fh.name, path)
    except OSError:
        pass  # the index only saves time


def get_compiled(model, name: str, function: ca.Function, compile_if_missing: bool = True):
    """The loaded compiled form of ``function`` (model.<name>), or None if not compiled and
    ``compile_if_missing`` is False. Raises CompileError when compilation is impossible."""
    # the name alone could be reused for another function of the same model: add a fingerprint
    shape = tuple(function.size_in(k) for k in range(function.n_in())) + \
        tuple(function.size_out(k) for k in range(function.n_out()))
    size = function.n_instructions() if function.is_a("SXFunction") else function.n_nodes()
    skey = (model.structure_key(), name, shape, size)
    with _lock:
        if skey in _loaded:
            return _loaded[skey]
        compiler = find_compiler()
        if compiler is None:
            raise CompileError("no C compiler")
        if (skey, compiler) in _failed:
            raise CompileError(_failed[(skey, compiler)])
        sizes = [function.numel_out(k) for k in range(function.n_out())]
        if not compile_if_missing and (skey, compiler) in _not_on_disk:
            return None             # looked for already in this process (a lookup hashes the function)
        _private_cache_dir()
        lib = _from_index(function, compiler)
        if lib is None:
            if not compile_if_missing:
                _not_on_disk.add((skey, compiler))
                return None
            # first with the fast form, then (a compiler or libm without what it needs) plain
            variants = [True, False] if (skey, compiler, "merged") not in _failed else [False]
            for merge in variants:
                src, sizes = _source(skey, function, merge)
                try:
                    lib = compile_source(src, compiler)
                    break
                except CompileError as exc:
                    _failed[(skey, compiler, "merged") if merge else (skey, compiler)] = str(exc)
                    if not merge:
                        raise
            _write_index(function, compiler, lib)
        comp = _Compiled(lib, sizes, function.numel_in(0), function.numel_in(2), function.numel_in(1))
        _loaded[skey] = comp
        return comp


def call(model, name, function, q, p, c, required=False):
    """Evaluate ``function`` (= ``model.<name>``) on N poses with compiled C.

    q (N, n_axes), p (n_params,), c (N, n_context), internal units. Returns a list of (N, rows*cols)
    arrays (column-major per pose, as :func:`mtcomp.models.evaluate.casadi_map_call`), or None to let
    the caller fall back to CasADi's map: no compiler (a one-line notice on stderr, once), a failed
    compilation, or a function not compiled yet that this process has evaluated on fewer than
    ``MTCOMP_COMPILE_MIN_POSES`` poses in all (this call's included). ``required=True`` raises instead of
    returning None.
    """
    n = np.asarray(q).shape[0]
    used = (model.structure_key(), name)
    _poses_used[used] = _poses_used.get(used, 0) + n
    try:
        comp = get_compiled(model, name, function,
                            compile_if_missing=required or _poses_used[used] >= _min_poses())
    except CompileError as exc:
        if required:
            raise RuntimeError(f"compiled backend not available: {exc}") from None
        if "no C compiler" in str(exc):
            _notice()
        elif str(exc) not in _said:  # each problem once per process
            _said.add(str(exc))
            print(f"mtcomp: compiling the model failed; using CasADi's own evaluation ({exc})"[:300],
                  file=sys.stderr)
        return None
    if comp is None:
        return None
    return comp(q, p, c)

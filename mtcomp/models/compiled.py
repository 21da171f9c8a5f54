"""Compiled evaluation: the model's CasADi function as C, looped over poses, compiled once and cached.

:func:`call` is the backend of :func:`mtcomp.models.evaluate.evaluate`. For a function of
``(q, p, c)`` it

1. splits off what depends on the parameters alone (computed once per call) and densifies the
   outputs (:func:`split_function`);
2. writes C for the rest that evaluates two poses at a time with SIMD vector extensions (four on a
   CPU with AVX2, :func:`wide_simd`)
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
   the hash of source, compiler and flags (:mod:`mtcomp.io.cache`: ``$MTCOMP_CACHE_DIR``, else
   ``$XDG_CACHE_HOME/mtcomp``, else ``~/.cache/mtcomp``, else a folder in the temporary
   directory), written to a temporary file and renamed so that concurrent processes never load a
   half-written library; a small index file lets a later process find it without
   generating the C again;
4. loads it with ctypes and calls it on numpy arrays.

Compiler flags keep IEEE semantics (no ``-ffast-math``, no ``-march``: SSE2, any x86-64, and
``-mavx2`` for the four-pose loops where the CPU has AVX2, a library of its own in the cache; FMA
contraction off) and every arithmetic operation is the one CasADi's own evaluation does. The only
difference is sin and cos of small angles: the polynomials are within about half an ulp of the true
value, as glibc's are, so they agree with glibc's value to an ulp (in tests, bit for bit on all
error-model poses tried) and the results agree with CasADi's to the model's own rounding (1e-13 mm
and better; tests check 1e-13 times max(1, size of the output)). A pose's result does not depend on
the poses batched with it.

Environment:

* ``MTCOMP_CC``: the compiler to use (default: ``$CC``, else ``cc``, ``gcc``, ``clang`` on PATH). A
  path that does not exist means "no compiler": evaluation falls back to CasADi's map.
* ``MTCOMP_CACHE_DIR``: where libraries are kept (the G-code scanner's library too).
* ``MTCOMP_NO_AVX2``: set (non-empty): two-pose SSE2 loops even on a CPU with AVX2.
* ``MTCOMP_COMPILE_MIN_POSES``: ``backend='auto'`` compiles a function that is not compiled yet
  once the process has evaluated it on this many poses in all (default 50,000; 5,000 for the tip
  deviation's parameter Jacobian, :data:`MIN_POSES_OF`). Compiling a 5-axis
  Jacobian takes tens of seconds, and the knots that the data choose make every campaign a new
  structure: a diagnosis of a 10,500-row 5-axis campaign (five evaluations of each file) took 42 s
  with compilation and 20 s on CasADi's map (10 s once compiled). A large fit (100,000 points)
  passes the threshold on its first call and compiles at once.
"""
from __future__ import annotations

import contextlib
import ctypes
import hashlib
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

import casadi as ca
import numpy as np

from ..io.cache import CacheDirError, private_cache_dir
# the batched pose body's C; TAYLOR_LIMIT and _TAYLOR are read from here too
from ._simd import (_RUN_ONE, _RUN_TWO, TAYLOR_LIMIT, _TAYLOR, _Unsupported,  # noqa: F401
                    _trig_source, batched_body)

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
    """Directory of compiled libraries, created on demand: mtcomp's one cache folder
    (:func:`mtcomp.io.cache.private_cache_dir`). Raises CompileError when no folder can be used
    (code is only loaded from a folder that belongs to this user and nobody else can write to)."""
    try:
        return private_cache_dir()
    except CacheDirError as exc:
        raise CompileError(str(exc)) from None


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
#: the same for the functions named here. The standard error of the tip deviation
#: (``tip_pjacobian_function``) is what compensate's check of a correction's standard error evaluates
#: at every block of every program run with one model, and nothing else does: compiling it (3-6 s
#: once per model structure, then cached on disk) costs what CasADi's map takes on 8,000-15,000
#: poses, so a shop's programs of a few thousand blocks pay it once instead of at every run
MIN_POSES_OF = {"tip_pjacobian_function": 5_000}


def _min_poses(name: str | None = None) -> int:
    """MTCOMP_COMPILE_MIN_POSES when it is an integer, else the threshold of the function ``name``
    (:data:`MIN_POSES_OF`, else :data:`MIN_POSES`)."""
    default = MIN_POSES_OF.get(name, MIN_POSES)
    try:
        return int(os.environ.get("MTCOMP_COMPILE_MIN_POSES", default))
    except ValueError:
        return default


#: told ``(function name, True)`` before a compiler run and ``(name, False)`` after it, or None
#: (:func:`compile_notices`: a command's progress lines say what the wait is)
_on_compile = None


@contextlib.contextmanager
def compile_notices(callback):
    """Within the context, ``callback(function name, started)`` is told before each compiler run
    (``started`` True) and after it (False): a 5-axis model's Jacobian takes tens of seconds to
    compile, once per model structure (then it comes from the cache). ``callback`` None: nobody."""
    global _on_compile
    before, _on_compile = _on_compile, callback
    try:
        yield
    finally:
        _on_compile = before


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
            return batched_source(function, WIDE_LANES if wide_simd() else LANES)
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
#: poses per SIMD vector on a CPU with AVX2 (:func:`wide_simd`): four doubles. The same IEEE
#: operations lane by lane (AVX2 has no fused multiply-add; FMA contraction is off anyway), so the
#: same results, about twice as fast (xfyz deviation and its q-Jacobian: 2.1x and 2.5x)
WIDE_LANES = 4
#: added to the flags of a source marked with :data:`WIDE_MARK` (a pose loop of WIDE_LANES)
WIDE_FLAGS = ("-mavx2",)
WIDE_MARK = "/* mtcomp: avx2 */\n"
#: set (to anything but empty): no AVX2 even where the CPU has it
NO_WIDE_ENV = "MTCOMP_NO_AVX2"
_wide: bool | None = None


def wide_simd() -> bool:
    """Whether the pose loops are written for AVX2: an x86-64 CPU whose flags (Linux's
    /proc/cpuinfo) name avx2, and :data:`NO_WIDE_ENV` not set. Read once per process. A library
    built for AVX2 is named by the flags in the cache, so a CPU without it never loads one."""
    global _wide
    if os.environ.get(NO_WIDE_ENV):
        return False
    if _wide is None:
        _wide = False
        if sys.platform.startswith("linux") and platform.machine() in ("x86_64", "AMD64"):
            try:
                with open("/proc/cpuinfo") as fh:
                    for line in fh:
                        if line.startswith("flags"):
                            _wide = "avx2" in line.split()
                            break
            except OSError:
                pass
    return _wide


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
    if lanes == WIDE_LANES:
        mark = WIDE_MARK + mark
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


def _asks_gcc(compiler: str) -> bool:
    """Whether ``compiler`` is GCC: its predefined macros have __GNUC__ and not __clang__ (Clang
    defines both)."""
    try:
        out = subprocess.run([compiler, "-E", "-dM", "-x", "c", "-"], input="", capture_output=True,
                             text=True, timeout=60).stdout
    except (OSError, subprocess.SubprocessError):
        out = ""
    return "#define __GNUC__ " in out and "__clang__" not in out


def _gcc_remembered(compiler: str) -> bool:
    """:func:`_asks_gcc`, asked once per compiler binary (path, size, time) and remembered in the
    cache folder: running the preprocessor took 30-40 ms of every process that evaluates a model."""
    try:
        st = os.stat(compiler)
        key = hashlib.sha256(f"{compiler}\0{st.st_size}\0{st.st_mtime_ns}".encode()).hexdigest()
        mark = cache_dir() / f"compiler-{key[:24]}"
    except (OSError, CompileError):
        return _asks_gcc(compiler)
    try:
        said = mark.read_text()
        if said in ("gcc", "other"):
            return said == "gcc"
    except OSError:
        pass
    is_gcc = _asks_gcc(compiler)
    try:
        with tempfile.NamedTemporaryFile("w", dir=mark.parent, prefix=".compiler-", delete=False) as fh:
            fh.write("gcc" if is_gcc else "other")
        os.replace(fh.name, mark)
    except OSError:
        pass                # remembering only saves time
    return is_gcc


def compile_flags(compiler: str, src: str = SCHEDULE_MARK) -> tuple[str, ...]:
    """Flags for ``compiler`` and ``src``: :data:`CFLAGS`, plus :data:`GCC_FLAGS` when it is GCC
    and the source opens with :data:`SCHEDULE_MARK`, plus :data:`WIDE_FLAGS` when it opens with
    :data:`WIDE_MARK`."""
    if compiler not in _is_gcc:
        _is_gcc[compiler] = _gcc_remembered(compiler)
    if src.startswith(WIDE_MARK):
        return compile_flags(compiler, src[len(WIDE_MARK):]) + WIDE_FLAGS
    return CFLAGS + (GCC_FLAGS if _is_gcc[compiler] and src.startswith(SCHEDULE_MARK) else ())


def compile_source(src: str, compiler: str, name: str = "") -> Path:
    """Compile ``src`` (the function ``name``'s) into the cache (or reuse a cached library); the
    run is told to :func:`compile_notices`' callback. Raises CompileError."""
    global compile_count
    flags = compile_flags(compiler, src)
    key = hashlib.sha256("\0".join([src, compiler, *flags]).encode()).hexdigest()[:24]
    out_dir = cache_dir()
    lib = out_dir / f"mtcomp_{key}.so"
    if lib.exists():
        return lib
    with tempfile.TemporaryDirectory(dir=out_dir, prefix=".build-") as tmp:
        c_file = Path(tmp) / f"mtcomp_{key}.c"
        c_file.write_text(src)
        tmp_lib = Path(tmp) / f"mtcomp_{key}.so"
        cmd = [compiler, *flags, str(c_file), "-o", str(tmp_lib), "-lm"]
        told = _on_compile
        if told is not None:
            told(name, True)
        try:
            proc = subprocess.run(cmd, capture_output=True, text=True)
        except OSError as exc:
            raise CompileError(f"cannot run {compiler}: {exc}") from None
        finally:
            if told is not None:
                told(name, False)
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
    key = (skey, merge, wide_simd())      # the lanes the C is written for are part of it
    if key not in _sources:
        _sources[key] = generate_source(function, merge=merge)
    return _sources[key]


def _generator_fingerprint() -> str:
    """Hash of the code that writes the C (this module's and :mod:`mtcomp.models._simd`'s) and
    CasADi's version: a change of any makes new libraries."""
    global _GENERATOR
    if _GENERATOR is None:
        code = Path(__file__).read_bytes() + Path(__file__).with_name("_simd.py").read_bytes()
        _GENERATOR = hashlib.sha256(code + ca.__version__.encode()).hexdigest()
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
                                      b"avx2" if wide_simd() else b"sse2",
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
        cache_dir()
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
                    lib = compile_source(src, compiler, name)
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
                            compile_if_missing=required or _poses_used[used] >= _min_poses(name))
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

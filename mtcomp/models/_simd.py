"""The C of a model function's pose body evaluated on several poses at once with GCC/Clang vector
extensions (:func:`batched_body`), and the sin and cos of its angles (:func:`_trig_source`): the
emitter :func:`mtcomp.models.compiled.batched_source` puts into the loop over poses. Every
arithmetic operation is CasADi's own, lane by lane; sin and cos of small angles are Taylor
polynomials within about half an ulp (:data:`TAYLOR_LIMIT`)."""
from __future__ import annotations

import math

import casadi as ca


_OPS = {getattr(ca, n): n for n in dir(ca) if n.startswith("OP_")}
_UNARY = {"OP_ASSIGN": "{0}", "OP_NEG": "(-{0})", "OP_SQ": "({0}*{0})", "OP_TWICE": "(2.*{0})",
         "OP_SIN": "sin({0})", "OP_COS": "cos({0})", "OP_TAN": "tan({0})", "OP_SQRT": "sqrt({0})",
         "OP_INV": "(1./{0})", "OP_FABS": "fabs({0})", "OP_EXP": "exp({0})", "OP_LOG": "log({0})",
         "OP_ASIN": "asin({0})", "OP_ACOS": "acos({0})", "OP_ATAN": "atan({0})"}
_BINARY = {"OP_ADD": "({0}+{1})", "OP_SUB": "({0}-{1})", "OP_MUL": "({0}*{1})", "OP_DIV": "({0}/{1})",
          "OP_POW": "pow({0},{1})", "OP_CONSTPOW": "pow({0},{1})", "OP_ATAN2": "atan2({0},{1})",
          "OP_FMIN": "fmin({0},{1})", "OP_FMAX": "fmax({0},{1})"}


#: comparisons, not and if_else_zero: (scalar C, as CasADi's generated code has them; vector C
#: on two vectors of lanes). A vector comparison gives all-ones lanes where true: and-ed with the
#: bits of 1.0 it is 1.0 or +0.0, the double the scalar code converts its int to; if_else_zero(c, x)
#: keeps x's bits where c != 0 (NaN included, as C's c ? x : 0) and +0.0 elsewhere
_ONE_BITS = "0x3ff0000000000000LL"
_LOGIC = {"OP_LT": ("({0}<{1})", f"(vd)(({{0}}<{{1}})&{_ONE_BITS})"),
          "OP_LE": ("({0}<={1})", f"(vd)(({{0}}<={{1}})&{_ONE_BITS})"),
          "OP_EQ": ("({0}=={1})", f"(vd)(({{0}}=={{1}})&{_ONE_BITS})"),
          "OP_NE": ("({0}!={1})", f"(vd)(({{0}}!={{1}})&{_ONE_BITS})"),
          "OP_NOT": ("(!{0})", f"(vd)(({{0}}==0.)&{_ONE_BITS})"),
          "OP_IF_ELSE_ZERO": ("({0}?{1}:0)", "(vd)(({0}!=0.)&(vl)({1}))")}


class _Unsupported(Exception):
    """The batched emitter does not know an operation of the function."""


def batched_body(body: ca.Function, lanes: int, varying_inputs: set, out_map: dict,
                 name: str = "mtcomp_batch", trig: str = "exact") -> tuple[str, list[tuple[int, int]], bool]:
    # long because the loop over the instructions shares the emitter's state (per-pose values,
    # slots, lines) through opnd and assign: one table from CasADi instruction to C line
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
    pair_id, n_pairs = _sincos_pairs(body, ids)
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
        if fn is not None:  # lane by lane; the operands read before o changes kind (o may be one)
            parts = []
            for jj in range(L):
                lane["j"] = jj
                parts.append(fn())
            lane["j"] = None
            expr = f"(vd){{{', '.join(parts)}}}"
        uni[o] = is_uni
        if is_uni:
            used_u.add(o)
            lines.append(f"  u{o}={expr};")
        else:
            used_v.add(o)
            lines.append(f"  v{o}={expr};")

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
        elif op in _LOGIC:
            o = body.instruction_output(k)[0]
            args = ins[:1] if op == "OP_NOT" else ins[:2]
            if all(uni[i] for i in args):
                assign(o, True, _LOGIC[op][0].format(*(opnd(i) for i in args)))
            else:       # a value shared by the poses enters as a vector of copies of it
                vec = [f"(vd){{{', '.join([opnd(i)] * L)}}}" if uni[i] else opnd(i) for i in args]
                assign(o, False, _LOGIC[op][1].format(*vec))
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
    decl = _declarations(name, trig, used_u, used_v, n_pairs)
    any_large = " | ".join(f"large[{j}]" for j in range(L)) if trig != "exact" and n_pairs else "0"
    return "\n".join(decl + lines + [f"  return ({any_large}) != 0;", "}"]) + "\n", list(slots), n_pairs > 0


def _sincos_pairs(body: ca.Function, ids: list) -> tuple[dict, int]:
    """({instruction: (pair, is_first)}, number of pairs): the sin and cos instructions of
    ``body`` (``ids``: each instruction's OP_ name) that take the same value (the same version of
    the same work variable), paired so that one ``sincos`` computes both."""
    version, first, pair_id = {}, {}, {}
    n_pairs = 0
    for k in range(len(ids)):
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
    return pair_id, n_pairs


def _declarations(name: str, trig: str, used_u: set, used_v: set, n_pairs: int) -> list[str]:
    """The C lines that open :func:`batched_body`'s function ``name``: its signature and the
    variables it uses (u: one value for all poses, v: a vector, vs/vc: sin and cos pairs)."""
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
    return decl


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


#: |x| below which sin and cos are the Taylor polynomials of :data:`_TAYLOR`
TAYLOR_LIMIT = 2.0 ** -6


#: Taylor coefficients of sin (x^3 .. x^7) and cos (x^2 .. x^6), rounded to double. For |x| <
#: TAYLOR_LIMIT the first omitted terms are below x^9/9! (relative to sin x: < 2^-48/9! ~ 1e-20)
#: and x^8/8! (< 2^-48/8! ~ 9e-20), far below half an ulp (1.1e-16). The rounding errors of the
#: correction term (x^3/6 or x^2/2 and beyond, at most 2^-12 of the result) are below 2^-12 ulp, so
#: the error is the last addition's, about half an ulp, as glibc's sin and cos
_TAYLOR = {"s3": -1 / 6, "s5": 1 / 120, "s7": -1 / 5040,
           "c2": -1 / 2, "c4": 1 / 24, "c6": -1 / 720}


def _trig_source(lanes: int) -> str:
    """C of the sin/cos of a vector of ``lanes`` angles: ``mt_sincos(x, &s, &c)`` (exact body:
    lane by lane the Taylor polynomials of :data:`_TAYLOR` for |x| < :data:`TAYLOR_LIMIT`, glibc's
    ``sincos`` otherwise, inf and NaN included) and ``mt_sincos_small(x, &s, &c, &large)`` (fast
    body: the polynomials, lanes outside their range marked in ``large``)."""
    L = lanes
    all_small = " & ".join(f"small[{j}]" for j in range(L))
    return _TRIG_C % {"all_small": all_small, "L": L,
                      **{k: float.hex(v) for k, v in _TAYLOR.items()}, "lim": float.hex(TAYLOR_LIMIT)}


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

"""The batched (SIMD) C of a model function with comparisons, not and if_else_zero (a B-spline's
clipped position, a profile's end), two poses at a time (SSE2) and four (AVX2, where the CPU has
it): bit for bit the per-pose C CasADi generates, and the model's deviation and its Jacobian take
the batched path."""
import numpy as np
import pytest

from mtcomp import load_machine
from mtcomp.models import ErrorModel, compiled
from mtcomp.models.evaluate import casadi_map_call
from test_models_compiled import cache, small_model  # noqa: F401  (cache: a folder of the test's own)

pytestmark = pytest.mark.skipif(compiled.find_compiler() is None, reason="no C compiler here")


LANES = [2, pytest.param(4, marks=pytest.mark.skipif(not compiled.wide_simd(),
                                                     reason="no AVX2 on this CPU"))]


def _both(f, lanes):
    """(batched, per-pose) compiled forms of f: the SIMD emitter's and CasADi's own C per pose."""
    out = []
    for src, sizes in (compiled.batched_source(f, lanes), compiled.generate_source(f, merge=False)):
        lib = compiled.compile_source(src, compiled.find_compiler())
        out.append(compiled._Compiled(lib, sizes, f.numel_in(0), f.numel_in(2), f.numel_in(1)))
    return out


def _same_bits(a, b):
    """Equal bit for bit (signed zeros told apart), NaN where the other is NaN."""
    nan = np.isnan(a)
    assert np.array_equal(nan, np.isnan(b))
    assert np.array_equal(a[~nan].view(np.int64), b[~nan].view(np.int64))


def _logic_function():
    """Every logic operation on two per-pose values, on a per-pose and a shared value (either side),
    and on results the next operation overwrites (CasADi reuses its work variables in place, a
    constant's for the result of the operation that reads it)."""
    import casadi as ca
    q, p, c = ca.SX.sym("q", 2), ca.SX.sym("p", 2), ca.SX.sym("c", 1)
    a, b, s = q[0], q[1], p[0]
    outs = []
    for x, y in ((a, b), (a, s), (s, a)):
        outs += [x < y, x <= y, x == y, x != y, ca.logic_not(x), ca.if_else(x, y, 0),
                 ca.if_else(x < y, y * p[1], x - c[0])]
    outs += [ca.if_else(a < 1.0, 1.0, ca.if_else(a > 3.0, 3.0, a)) * b,
             ca.fmax(a - 2.0, 0.0) ** 3 * s, ca.if_else(a < s, -b, 0) + ca.logic_not(b) * a,
             # library functions lane by lane, a shared operand's variable taken for the result
             ca.fmax(a, 2.0), ca.fmin(1.5, b), ca.atan2(s, a) + ca.fmax(b, s)]
    return ca.Function("logic_test", [q, p, c], [ca.vertcat(*outs)])


@pytest.mark.parametrize("lanes", LANES)
def test_logic_operations_bit_for_bit(cache, lanes):
    f = _logic_function()
    special = np.array([0.0, -0.0, 1.0, -1.0, 2.5, 3.0, 4.0, np.inf, -np.inf, np.nan, 5e-324])
    qa, qb = np.meshgrid(special, special)
    rng = np.random.default_rng(4)
    q = np.vstack([np.column_stack([qa.ravel(), qb.ravel()]), rng.normal(0, 3, (61, 2))])
    c = rng.normal(size=(q.shape[0], 1))
    for p in (np.array([2.5, -1.5]), np.array([0.0, 2.0]), np.array([np.nan, 1.0])):
        fast, plain = _both(f, lanes)
        got, want = fast(q, p, c)[0], plain(q, p, c)[0]
        _same_bits(got, want)
        np.testing.assert_allclose(got, casadi_map_call(f, q, p, c)[0], rtol=0, atol=0)
        assert np.isnan(got).any() and np.isin(got, [0.0, 1.0]).all(axis=0).any()


@pytest.mark.parametrize("lanes", LANES)
@pytest.mark.parametrize("name", ["xfyz", "cafxyz"])
def test_model_functions_take_the_batched_path_and_match_per_pose(shared_cache, name, lanes):
    """The deviation and its Jacobian in q, at poses inside and beyond the B-splines' range (the
    clip's both branches and its ends), as the per-pose C gives them (on a model with fewer spline
    intervals than the machine file's, the same operations: test_models_compiled.small_model)."""
    model = small_model(name)
    rng = np.random.default_rng(11)
    lo, hi = model.machine.travel_bounds()
    n = 301
    q = rng.uniform(lo - 0.2 * (hi - lo), hi + 0.2 * (hi - lo), (n, model.machine.n_axes))
    q[:5], q[5:10] = lo, hi
    p = rng.normal(size=model.n_params) * 1e-3
    c = model.default_context(n)
    for fname in ("deviation_function", "deviation_qjacobian_function"):
        f = getattr(model, fname)
        src, _ = compiled.batched_source(f, lanes)     # raised _Unsupported on OP_LT before
        assert "mtcomp_run(in, shared, o, &skip)" in src
        assert src.startswith(compiled.WIDE_MARK) == (lanes == 4)
        fast, plain = _both(f, lanes)
        for g, r in zip(fast(q, p, c), plain(q, p, c)):
            _same_bits(g, r)


def test_four_lanes_where_the_cpu_has_avx2_and_the_flags_say_so(cache, monkeypatch):
    f = ErrorModel(load_machine("xfyz")).deviation_function
    compiler = compiled.find_compiler()
    monkeypatch.setattr(compiled, "_wide", True)
    src, _ = compiled.generate_source(f)
    assert "vector_size(32)" in src and "-mavx2" in compiled.compile_flags(compiler, src)
    monkeypatch.setenv(compiled.NO_WIDE_ENV, "1")
    src, _ = compiled.generate_source(f)
    assert "vector_size(16)" in src and "-mavx2" not in compiled.compile_flags(compiler, src)
    monkeypatch.delenv(compiled.NO_WIDE_ENV)
    monkeypatch.setattr(compiled, "_wide", False)
    assert "vector_size(16)" in compiled.generate_source(f)[0]


def test_the_avx2_reading_agrees_with_the_compiler(monkeypatch):
    """The CPU's AVX2 as /proc/cpuinfo names it (wide_simd) against a second source: whether the
    compiler, told to build for this CPU (-march=native), defines __AVX2__."""
    import platform
    import subprocess
    if platform.machine() not in ("x86_64", "AMD64"):
        pytest.skip("AVX2 is an x86-64 extension")
    monkeypatch.delenv(compiled.NO_WIDE_ENV, raising=False)
    monkeypatch.setattr(compiled, "_wide", None)         # read again
    try:
        macros = subprocess.run([compiled.find_compiler(), "-march=native", "-dM", "-E", "-x", "c",
                                 "/dev/null"], capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.TimeoutExpired) as e:
        pytest.skip(f"the compiler could not list its macros: {e}")
    if macros.returncode != 0:
        pytest.skip(f"the compiler does not take -march=native: {macros.stderr.strip()[:80]}")
    assert compiled.wide_simd() == ("#define __AVX2__ 1" in macros.stdout)


def test_whether_the_compiler_is_gcc_is_asked_once_and_remembered(cache, monkeypatch):
    """The preprocessor run that tells GCC from Clang is remembered in the cache folder: a second
    process (here: the in-process answers forgotten) does not run the compiler again."""
    compiler = compiled.find_compiler()
    first = compiled._gcc_remembered(compiler)
    assert first == compiled._asks_gcc(compiler)

    def no_run(*args, **kwargs):
        raise AssertionError("the compiler was run again")
    monkeypatch.setattr(compiled.subprocess, "run", no_run)
    monkeypatch.setattr(compiled, "_is_gcc", {})
    assert compiled._gcc_remembered(compiler) == first
    assert compiled.compile_flags(compiler) == compiled.compile_flags(compiler)

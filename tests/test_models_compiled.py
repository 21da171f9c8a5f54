"""The compiled C backend against CasADi's own map; fallback without a compiler; cache reuse."""
import math
import os
import shutil

import numpy as np
import pytest

from mtcomp import load_machine
from mtcomp.models import Backlash, ErrorModel, FeedOffset, RotaryErrorMotion, compiled, evaluate
from mtcomp.models.evaluate import casadi_map_call
from test_models_chain import machine_size_params, random_context, random_poses

pytestmark = pytest.mark.skipif(compiled.find_compiler() is None, reason="no C compiler here")

FUNCTIONS = ["deviation_function", "deviation_qjacobian_function", "deviation_jacobian_function"]


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("MTCOMP_CACHE_DIR", str(tmp_path / "cache"))
    compiled.forget_loaded()
    yield tmp_path / "cache"
    compiled.forget_loaded()


def _atol(ref):
    """Tolerance of compiled against CasADi's evaluation: the model's own rounding.

    sin and cos of small error angles are Taylor polynomials in the compiled code (glibc's sincos
    in CasADi's): both within an ulp of the true value, so a result may differ by an ulp of a
    sin or cos times a lever of up to ~1000 mm, 1e-13 mm, in quantities (positions of hundreds of
    mm, their derivatives, unit vectors) of order max(1, |output|). A real error is far larger: a
    wrong operation gives 1e-7 mm and more (a wrong polynomial coefficient is caught by
    test_small_angle_sin_cos, near the limit where the polynomial's last terms count).
    """
    return 1e-13 * max(1.0, float(np.abs(ref).max()))


def _inputs(model, seed, n):
    rng = np.random.default_rng(seed)
    return (random_poses(model.machine, rng, n), machine_size_params(model, rng),
            random_context(model, rng, n))


def small_model(name, terms=()):
    """An ErrorModel of machine ``name`` with two cubic B-spline intervals per linear axis instead
    of eight: the same topology and the same CasADi operations in every function (the same C to
    write), in functions a third smaller whose compilation takes a third of the time (the parameter
    Jacobian's most: 20-60 s on eight intervals)."""
    return ErrorModel(load_machine(name).with_basis("bspline", spline_intervals=2), list(terms))


def _operations(function):
    """The set of CasADi operation codes in ``function``'s instructions."""
    return {function.instruction_id(k) for k in range(function.n_instructions())}


@pytest.mark.parametrize("name,terms", [("xfyz", False), ("cafxyz", True)])
def test_compiled_matches_casadi_map(shared_cache, name, terms):
    model = small_model(name, [Backlash("X"), FeedOffset("Y"), RotaryErrorMotion("EXC", 1)] if terms else [])
    q, p, c = _inputs(model, 3, 41)  # odd: the last SIMD pair is padded
    full = ErrorModel(load_machine(name), model.terms)    # the machine file's eight intervals
    for fname in FUNCTIONS:
        function = getattr(model, fname)
        assert _operations(function) == _operations(getattr(full, fname))
        got = compiled.call(model, fname, function, q, p, c, required=True)
        ref = casadi_map_call(function, q, p, c)
        assert len(got) == len(ref) == function.n_out()
        for g, r in zip(got, ref):
            assert g.shape == r.shape
            np.testing.assert_allclose(g, r, rtol=0, atol=_atol(r))
    # the public evaluate() gives the same (N, rows, cols) arrays on both backends
    for a, b in zip(evaluate(model, "deviation_jacobian_function", q, p, c, backend="compiled"),
                    evaluate(model, "deviation_jacobian_function", q, p, c, backend="casadi")):
        np.testing.assert_allclose(a, b, rtol=0, atol=_atol(b))


def test_other_operations_and_shared_outputs(cache):
    """A function like the measurement models' (norm, division, power, an output that depends on
    p alone, extra context columns) compiles and matches CasADi's map."""
    import casadi as ca
    model = ErrorModel(load_machine("cafxyz"))
    q = ca.SX.sym("q", 5)
    p = ca.SX.sym("p", model.n_params)
    c = ca.SX.sym("c", model.n_context + 3)
    tip, axis = model.pose_function(q, p, c[:model.n_context])
    length = ca.norm_2(tip - c[model.n_context:])
    outs = [length, ca.atan2(axis[1], axis[0]) / (1 + p[0] ** 2), ca.sqrt(1 + p[1] ** 2) * ca.exp(p[2])]
    f = ca.Function("mm_test", [q, p, c], outs)
    qv, pv, cv = _inputs(model, 8, 7)
    cv = np.hstack([cv, np.random.default_rng(9).normal(size=(7, 3)) * 100])
    got = compiled.call(model, "mm_test", f, qv, pv, cv, required=True)
    for g, r in zip(got, casadi_map_call(f, qv, pv, cv)):
        np.testing.assert_allclose(g, r, rtol=0, atol=_atol(r))


def test_per_pose_variants_match(cache):
    """The per-pose forms (plain CasADi code, and with sin/cos merged into sincos) used where the
    batched form cannot be built."""
    model = ErrorModel(load_machine("cafxyz"))
    f = model.deviation_qjacobian_function
    q, p, c = _inputs(model, 10, 9)
    ref = casadi_map_call(f, q, p, c)
    plain, sizes = compiled.generate_source(f, merge=False)
    assert "sincos" not in plain
    variants = [plain]
    if "linux" in compiled.sys.platform:
        merged = compiled.merge_sincos(plain)
        assert merged.count("sincos(") >= 10  # five angles per pose, sin and cos of each
        variants.append(merged)
    for src in variants:
        lib = compiled.compile_source(src, compiled.find_compiler())
        got = compiled._Compiled(lib, sizes, 5, model.n_context, model.n_params)(q, p, c)
        for g, r in zip(got, ref):
            np.testing.assert_allclose(g, r, rtol=0, atol=_atol(r))


def _trig_function(n_angles=3):
    """(q, p, c) -> (sin q_k, cos q_k) for k < n_angles, and a product that mixes them."""
    import casadi as ca
    q, p, c = ca.SX.sym("q", n_angles), ca.SX.sym("p", 1), ca.SX.sym("c", 1)
    outs = [ca.vertcat(*[ca.sin(q[k]) for k in range(n_angles)]),
            ca.vertcat(*[ca.cos(q[k]) for k in range(n_angles)]),
            ca.sin(q[0]) * ca.cos(q[n_angles - 1]) * p[0] + c[0]]
    return ca.Function("trig_test", [q, p, c], outs)


def _compile_direct(f, cache):
    src, sizes = compiled.generate_source(f)
    lib = compiled.compile_source(src, compiled.find_compiler())
    return compiled._Compiled(lib, sizes, f.numel_in(0), f.numel_in(2), f.numel_in(1))


def _trig_angles(rng):
    """Angles (rad) for the sin/cos tests: error-angle sizes, both sides of the polynomial's limit
    (where its last terms count most), large angles, signed zeros, subnormals, inf and NaN."""
    lim = compiled.TAYLOR_LIMIT
    special = [0.0, -0.0, 5e-324, -1e-310, 1e-300, 1e-12, -3e-8, 1e-4, -5e-4, 1e-2,
               np.nextafter(lim, 0), -np.nextafter(lim, 0), lim, -lim, np.nextafter(lim, 1),
               0.5 * lim, 0.999 * lim, 0.1, -1.0, 3.0, 100.0, 1e6, np.inf, -np.inf, np.nan]
    near = rng.uniform(0.9, 1.0, 300) * lim * rng.choice([-1, 1], 300)
    small = rng.uniform(-lim, lim, 300)
    tiny = 10.0 ** rng.uniform(-9, -2, 300) * rng.choice([-1, 1], 300)
    large = rng.uniform(-10, 10, 60)
    return np.concatenate([special, near, small, tiny, large])


def test_small_angle_sin_cos(cache):
    """sin and cos in the compiled code (polynomials below TAYLOR_LIMIT, glibc's sincos otherwise)
    against Python's math (glibc): within an ulp everywhere, exactly where glibc is used, NaN for
    inf and NaN (sin(-0) may come out as +0, an equal value). Near the limit a wrong coefficient is
    several ulps off (test_wrong_polynomial_coefficient_is_caught)."""
    f = _trig_function()
    src = compiled.generate_source(f)[0]
    if "linux" in compiled.sys.platform:  # both pose bodies are built (else CasADi's code per pose)
        assert "mt_sincos_small(" in src and "mt_sincos(" in src
    comp = _compile_direct(f, cache)
    rng = np.random.default_rng(21)
    angles = _trig_angles(rng)
    angles = angles[rng.permutation(len(angles))]  # large and small angles share SIMD batches
    n = len(angles) // 3 * 3
    q = angles[:n].reshape(-1, 3)
    sin_c, cos_c, mixed = comp(q, np.array([2.0]), np.zeros((len(q), 1)))
    for got, fn in ((sin_c, math.sin), (cos_c, math.cos)):
        for x, g in zip(q.ravel(), got.ravel()):
            if not math.isfinite(x):
                assert math.isnan(g), (fn.__name__, x, g)
                continue
            ref = fn(x)
            assert abs(g - ref) <= np.spacing(abs(ref)), (fn.__name__, x, g, ref)
            if abs(x) >= compiled.TAYLOR_LIMIT:
                assert g == ref, (fn.__name__, x, g, ref)  # glibc's own value
    ok = np.isfinite(q).all(axis=1)
    np.testing.assert_allclose(mixed[ok, 0], 2 * sin_c[ok, 0] * cos_c[ok, 2], rtol=1e-15, atol=0)


def test_wrong_polynomial_coefficient_is_caught(cache, monkeypatch):
    """The check of test_small_angle_sin_cos fails for a last sin coefficient 10 % off: near the
    limit that term is ~26 ulps of sin x (x^6/7! relative, x = 2^-6), so 10 % is ~3 ulps."""
    monkeypatch.setitem(compiled._TAYLOR, "s7", compiled._TAYLOR["s7"] * 1.1)
    f = _trig_function(1)
    comp = _compile_direct(f, cache)
    x = np.random.default_rng(23).uniform(0.95, 1.0, (50, 1)) * compiled.TAYLOR_LIMIT
    got = comp(x, np.array([1.0]), np.zeros((50, 1)))[0][:, 0]
    ref = np.array([math.sin(v) for v in x[:, 0]])
    assert (np.abs(got - ref) > np.spacing(ref)).any()


def test_result_of_a_pose_does_not_depend_on_its_batch(cache):
    """Poses share SIMD batches; the fast body (polynomials only) gives way to the exact one for a
    batch with a large angle, and to it alone for a while after. Each pose's result must be the
    same bit for bit whatever it is batched with: here, evaluated alone."""
    f = _trig_function()
    comp = _compile_direct(f, cache)
    rng = np.random.default_rng(22)
    angles = _trig_angles(rng)
    angles = angles[np.isfinite(angles)]
    n = len(angles) // 3 * 3
    q = angles[rng.permutation(len(angles))][:n].reshape(-1, 3)
    q[:150] = rng.uniform(-1e-3, 1e-3, (150, 3))  # a run of small-angle batches before the mix
    p, c = np.array([1.5]), rng.normal(size=(len(q), 1))
    whole = comp(q, p, c)
    for i in list(range(0, len(q), 7)) + [len(q) - 1]:
        alone = comp(q[i:i + 1], p, c[i:i + 1])
        for a, b in zip(alone, whole):
            np.testing.assert_array_equal(a[0], b[i])


def test_cache_is_reused(cache, monkeypatch):
    model = ErrorModel(load_machine("xfyz"))
    q, p, c = _inputs(model, 4, 10)
    before = compiled.compile_count
    first = compiled.call(model, "deviation_function", model.deviation_function, q, p, c, required=True)
    assert compiled.compile_count == before + 1
    libs = list(cache.glob("mtcomp_*.so"))
    assert len(libs) == 1
    mtime = libs[0].stat().st_mtime_ns
    compiled.forget_loaded()  # as a new process would: only the disk cache is left

    def no_codegen(*args, **kwargs):
        raise AssertionError("a cached library must be found without generating C")

    monkeypatch.setattr(compiled, "generate_source", no_codegen)
    second = compiled.call(model, "deviation_function", model.deviation_function, q, p, c, required=True)
    assert compiled.compile_count == before + 1
    assert libs[0].stat().st_mtime_ns == mtime
    assert not [f for f in cache.iterdir() if f.name.startswith(".build-")]  # no temp left over
    np.testing.assert_array_equal(first[0], second[0])


def test_small_batches_do_not_compile_unless_cached(cache, monkeypatch):
    monkeypatch.setenv("MTCOMP_COMPILE_MIN_POSES", "1000")
    model = ErrorModel(load_machine("xfyz"))
    q, p, c = _inputs(model, 5, 10)
    before = compiled.compile_count
    assert compiled.call(model, "deviation_function", model.deviation_function, q, p, c) is None
    assert compiled.compile_count == before


def test_a_function_used_on_many_poses_in_all_gets_compiled(cache, monkeypatch):
    """A fit evaluates one function on the same few thousand poses many times: once the poses add
    up to MTCOMP_COMPILE_MIN_POSES it is compiled, though no single call reaches it."""
    monkeypatch.setenv("MTCOMP_COMPILE_MIN_POSES", "25")
    model = ErrorModel(load_machine("xfyz"))
    q, p, c = _inputs(model, 8, 10)
    before = compiled.compile_count
    assert compiled.call(model, "deviation_function", model.deviation_function, q, p, c) is None
    assert compiled.call(model, "deviation_function", model.deviation_function, q, p, c) is None
    out = compiled.call(model, "deviation_function", model.deviation_function, q, p, c)
    assert compiled.compile_count == before + 1
    np.testing.assert_allclose(out[0], casadi_map_call(model.deviation_function, q, p, c)[0],
                               rtol=0, atol=1e-12)


def test_fallback_without_compiler(cache, monkeypatch, capsys):
    monkeypatch.setenv("MTCOMP_CC", "/nonexistent/cc")
    monkeypatch.setenv("MTCOMP_COMPILE_MIN_POSES", "1")
    monkeypatch.setattr(compiled, "_notice_given", False)
    model = ErrorModel(load_machine("xfyz"))
    q, p, c = _inputs(model, 6, 20)
    dev = evaluate(model, "deviation_function", q, p, c)[0]
    evaluate(model, "deviation_function", q, p, c)
    err = capsys.readouterr().err
    assert err == "mtcomp: no C compiler found; using CasADi's own evaluation (slower)\n"
    ref = casadi_map_call(model.deviation_function, q, p, c)[0]
    np.testing.assert_array_equal(dev, ref)
    with pytest.raises(RuntimeError, match="not available"):
        evaluate(model, "deviation_function", q, p, c, backend="compiled")
    assert not cache.exists() or not list(cache.glob("*.so"))


@pytest.mark.skipif(shutil.which("false") is None, reason="needs the 'false' program")
def test_fallback_when_compilation_fails(cache, monkeypatch, capsys):
    monkeypatch.setattr(compiled, "_said", set())
    monkeypatch.setenv("MTCOMP_CC", shutil.which("false"))
    monkeypatch.setenv("MTCOMP_COMPILE_MIN_POSES", "1")
    model = ErrorModel(load_machine("xfyz"))
    q, p, c = _inputs(model, 7, 5)
    dev = evaluate(model, "deviation_function", q, p, c)[0]
    np.testing.assert_array_equal(dev, casadi_map_call(model.deviation_function, q, p, c)[0])
    assert "compiling the model failed" in capsys.readouterr().err
    assert not list(cache.glob("*.so"))


def test_shared_cache_dir_is_refused(tmp_path, monkeypatch, capsys):
    """Code is only loaded from a directory nobody else can write to."""
    shared = tmp_path / "shared"
    shared.mkdir()
    shared.chmod(0o777)
    monkeypatch.setenv("MTCOMP_CACHE_DIR", str(shared))
    compiled.forget_loaded()
    model = ErrorModel(load_machine("xfyz"))
    q, p, c = _inputs(model, 11, 4)
    monkeypatch.setattr(compiled, "_said", set())
    for _ in range(2):
        assert compiled.call(model, "deviation_function", model.deviation_function, q, p, c) is None
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "writable by other users" in err
    assert not list(shared.iterdir())
    compiled.forget_loaded()


def test_cache_dir_follows_environment(monkeypatch, tmp_path):
    monkeypatch.delenv("MTCOMP_CACHE_DIR", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert compiled.cache_dir() == tmp_path / "mtcomp"
    monkeypatch.setenv("MTCOMP_CACHE_DIR", os.fspath(tmp_path / "x"))
    assert compiled.cache_dir() == tmp_path / "x"

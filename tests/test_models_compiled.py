"""The compiled C backend against CasADi's own map; fallback without a compiler; cache reuse."""
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


def _inputs(model, seed, n):
    rng = np.random.default_rng(seed)
    return (random_poses(model.machine, rng, n), machine_size_params(model, rng),
            random_context(model, rng, n))


@pytest.mark.parametrize("name,terms", [("xfyz", False), ("cafxyz", True)])
def test_compiled_matches_casadi_map(cache, name, terms):
    m = load_machine(name)
    model = ErrorModel(m, [Backlash("X"), FeedOffset("Y"), RotaryErrorMotion("EXC", 1)] if terms else [])
    q, p, c = _inputs(model, 3, 41)  # odd: the last SIMD pair is padded
    for fname in FUNCTIONS:
        function = getattr(model, fname)
        got = compiled.call(model, fname, function, q, p, c, required=True)
        ref = casadi_map_call(function, q, p, c)
        assert len(got) == len(ref) == function.n_out()
        for g, r in zip(got, ref):
            assert g.shape == r.shape
            np.testing.assert_allclose(g, r, rtol=0, atol=1e-13 * np.abs(r).max())
    # the public evaluate() gives the same (N, rows, cols) arrays on both backends
    for a, b in zip(evaluate(model, "deviation_jacobian_function", q, p, c, backend="compiled"),
                    evaluate(model, "deviation_jacobian_function", q, p, c, backend="casadi")):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-13 * np.abs(b).max())


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
        np.testing.assert_allclose(g, r, rtol=0, atol=1e-13 * np.abs(r).max())


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
            np.testing.assert_allclose(g, r, rtol=0, atol=1e-13 * np.abs(r).max())


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

"""The fit's fast paths against straightforward formulations written here.

A large points file's normal equations are formed block by block (``jacobian_blocks``: each block of
the Jacobian weighted, multiplied and added while in cache) and its gradient summed block by block;
here both are compared with the whole stacked Jacobian multiplied out with numpy, and a fit in blocks
with the fit of the whole file. The fit's dense algebra runs on one BLAS thread, restored after.
The blocked path is taken only once a model's chain function is compiled; the tests force it (the
evaluation then falls back to CasADi's map, block by block) and make the blocks small, so that a
few hundred points make dozens of blocks, with a last one shorter than the others.
"""
from __future__ import annotations

import numpy as np
import pytest

from mtcomp.identification import _linalg, fit
from mtcomp.identification.fit import identify
from mtcomp.identification.problem import FitProblem
from mtcomp.machine import load_machine
from mtcomp.measurement import readings
from mtcomp.models import ErrorModel, basis
from mtcomp.sim import make_points, random_parameters, simulate

N_POINTS = 401          # 1203 observations: with blocks of 64 observations (21 rows) the last is short


def _campaign(seed: int, n: int = N_POINTS):
    rng = np.random.default_rng(seed)
    machine = load_machine("xfyz")
    model = ErrorModel(machine)
    lo, hi = machine.travel_bounds()
    xyz = rng.uniform(lo, hi, (n, 3))
    p = random_parameters(model, rng, mask=model.base_mask)
    data = simulate(model, make_points(xyz, None, tool=rng.choice([0.0, 100.0, 200.0], n)), p,
                    noise_um=0.5, rng=rng)
    return model, data


@pytest.fixture
def small_blocks(monkeypatch):
    """Blocks of 64 observations, taken whether or not the model is compiled."""
    monkeypatch.setattr(_linalg, "BLOCK_BYTES", 1)
    monkeypatch.setattr(readings, "compiled_ready", lambda model, name: True)
    monkeypatch.setattr(readings.PointsModel, "GRADIENT_ROWS", 37)


def _stacked(problem, x, w):
    """The straightforward formulation: the whole weighted Jacobian of the unknowns (free
    parameters, then the file's set-up), its Gram matrix and gradient."""
    (m,) = problem.mms
    p = problem.params(x)
    pred, Jp, Jn = m.predict_and_jacobian(p, x[problem.nuis_slices[0]])
    Jw = w[:, None] * np.hstack([Jp[:, problem.free_idx], Jn])
    rw = w * (m.observed - pred)
    return pred, Jw.T @ Jw, Jw.T @ rw


@pytest.mark.parametrize("block_rows", [None, 1100])
def test_normal_equations_in_blocks_are_those_of_the_whole_jacobian(small_blocks, monkeypatch, block_rows):
    """Blocks of 64 observations (dense products), and blocks of 1100 rows per reading direction
    (more than 4 times the columns: the products of the non-zero columns only; the last block of 100
    rows dense)."""
    if block_rows is not None:
        # 16 functions per axis, as the block sizes are written for (2300 rows would take more)
        monkeypatch.setattr(basis, "FIT_SIZE_BUDGET", 0.0)
    model, data = _campaign(1, N_POINTS if block_rows is None else 2300)
    fp = FitProblem.from_data(model, [data])
    problem = fit._Problem(fp.model, fp.measurements, np.asarray(fp.free, dtype=bool), fp.start)
    if block_rows is not None:
        monkeypatch.setattr(_linalg, "BLOCK_BYTES", 8 * fp.model.n_params * 3 * block_rows)
        assert block_rows > 4 * fp.model.n_params
    rng = np.random.default_rng(2)
    w = problem.unit_weights() * rng.uniform(0.5, 2.0, problem.n_obs)
    assert _linalg.block_obs(fp.model.n_params) < problem.n_obs / 2
    # at the start (machine errors zero: a reading direction's Jacobian has zero columns; set-up
    # not zero) and away from it (every term of the chain counts: no column is zero)
    at_start = np.zeros(problem.n_unknowns)
    at_start[problem.n_free:] = rng.normal(0.0, 1e-3, problem.n_unknowns - problem.n_free)
    for x in (at_start, rng.normal(0.0, 1e-4, problem.n_unknowns)):
        pred, A, g = problem.normal_equations(x, w)
        pred0, A0, g0 = _stacked(problem, x, w)
        np.testing.assert_allclose(pred, pred0, rtol=0, atol=1e-15 * np.abs(pred0).max())
        np.testing.assert_allclose(A, A0, rtol=0, atol=1e-12 * np.abs(A0).max())
        np.testing.assert_allclose(g, g0, rtol=0, atol=1e-12 * np.abs(g0).max())
        # the gradient alone (the Gauss-Newton steps after the first): the reverse sweep in blocks
        pred1, A1, g1 = problem.normal_equations(x, w, gram=False)
        assert A1 is None
        np.testing.assert_allclose(pred1, pred0, rtol=0, atol=1e-15 * np.abs(pred0).max())
        np.testing.assert_allclose(g1, g0, rtol=0, atol=1e-12 * np.abs(g0).max())


def test_leverages_in_blocks_are_the_hat_matrix_diagonal(small_blocks):
    model, data = _campaign(3, 150)
    fp = FitProblem.from_data(model, [data])
    problem = fit._Problem(fp.model, fp.measurements, np.asarray(fp.free, dtype=bool), fp.start)
    x = np.zeros(problem.n_unknowns)
    w = problem.unit_weights()
    _, A, _ = problem.normal_equations(x, w)
    scale = _linalg.column_scale(A)
    rel, V = _linalg._relative_singular_values(A * np.outer(scale, scale))
    B = V[:, rel > 1e-6]
    H = B.T @ (A * np.outer(scale, scale)) @ B
    lev = problem.leverages(x, w, scale, B, _linalg.psd_factor(np.linalg.inv(H)))
    # oracle: diag(Js B H^-1 B^T Js^T) from the whole scaled Jacobian
    _, Jw, _ = _stacked(problem, x, w)[0], None, None
    (m,) = problem.mms
    _, Jp, Jn = m.predict_and_jacobian(problem.params(x), x[problem.nuis_slices[0]])
    Js = w[:, None] * np.hstack([Jp[:, problem.free_idx], Jn]) * scale[None, :]
    JB = Js @ B
    expected = np.einsum("ij,ji->i", JB, np.linalg.solve(H, JB.T))
    np.testing.assert_allclose(lev, expected, rtol=1e-9, atol=1e-12)
    assert lev.sum() == pytest.approx(B.shape[1], rel=1e-9)


def test_a_fit_in_blocks_is_the_fit_of_the_whole_file(monkeypatch):
    """Covariance and penalty weights the same to 1e-9 relative, through the penalty search, the
    Gauss-Newton steps and the hold of weak directions. The sums only change their order, but the
    combinations the data barely fix (held by the penalty and the least error) amplify that
    round-off, as a change of the number of BLAS threads does: their values agree to 1e-7 of the
    largest (3e-8 here, 1e-6 um), the determined ones to 2e-7 of their standard errors (1.07e-7 on
    the straightness EXZ of the ram, which the 0 and 200 mm tools read up to 100 mm either side of
    the tips: a smooth combination of its coefficients is fixed only weakly), the fitted readings to
    1e-6 um."""
    # the knots of the 16-function rule (as the case was built): the finer knots the fit's size
    # budget allows on this small campaign (473 unknowns) amplify the reordered sums' round-off
    # past 1e-7 of the standard errors on the combinations the penalty holds
    monkeypatch.setattr(basis, "FIT_SIZE_BUDGET", 0.0)
    model, data = _campaign(4)
    monkeypatch.setattr(readings, "compiled_ready", lambda model, name: False)
    whole = identify(model, [data])
    monkeypatch.setattr(_linalg, "BLOCK_BYTES", 1)
    monkeypatch.setattr(readings, "compiled_ready", lambda model, name: True)
    monkeypatch.setattr(readings.PointsModel, "GRADIENT_ROWS", 37)
    blocks = identify(model, [data])
    assert blocks.rank == whole.rank and blocks.iterations == whole.iterations
    se = whole.std_errors
    seen = np.isfinite(se) & (se > 0)
    assert seen.sum() > 20
    np.testing.assert_allclose(blocks.values[seen] / se[seen], whole.values[seen] / se[seen], rtol=0,
                               atol=2e-7)
    np.testing.assert_allclose(blocks.values, whole.values, rtol=0,
                               atol=1e-7 * np.abs(whole.values).max())
    np.testing.assert_allclose(blocks.files[0].residual, whole.files[0].residual, rtol=0, atol=1e-6)
    fin = np.isfinite(whole.covariance)
    np.testing.assert_array_equal(np.isfinite(blocks.covariance), fin)
    # 5e-9: the angular error motions this points file leaves open are held at zero by constraints
    # (docs/identification.md, rule 3), whose projection carries the reordered sums' round-off
    # into the covariance (1.3e-9 of its largest at most here; 1e-9 before the rule applied to
    # points alone); the turn of the machine held by the convention (rule 2, EYX's and EZX's slopes)
    # is one more such constraint: 3.4e-9 of the largest (48 of 61009 entries past 2e-9)
    np.testing.assert_allclose(blocks.covariance[fin], whole.covariance[fin], rtol=0,
                               atol=5e-9 * np.abs(whole.covariance[fin]).max())
    assert set(blocks.smoothing.rho) == set(whole.smoothing.rho)
    # REML's log weights to 3e-9: with the convention's constraint they differ by 1.5e-9 (-3.59888098)
    for k, rho in whole.smoothing.rho.items():
        assert blocks.smoothing.rho[k] == pytest.approx(rho, rel=3e-9, abs=1e-9)


def test_the_fit_runs_blas_on_one_thread_and_restores_it(monkeypatch):
    threadpoolctl = pytest.importorskip("threadpoolctl")
    seen = []
    original = fit._Problem.solve

    def spy(self, *args, **kwargs):
        seen.extend(i["num_threads"] for i in threadpoolctl.threadpool_info() if i["user_api"] == "blas")
        return original(self, *args, **kwargs)

    monkeypatch.setattr(fit._Problem, "solve", spy)
    model, data = _campaign(5, 60)
    with threadpoolctl.threadpool_limits(limits=2, user_api="blas"):
        identify(model, [data])
        after = [i["num_threads"] for i in threadpoolctl.threadpool_info() if i["user_api"] == "blas"]
    assert seen and set(seen) == {1}
    assert after and set(after) == {2}

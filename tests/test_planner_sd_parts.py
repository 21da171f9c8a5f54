"""The correction standard-error gate evaluates the model's parameter Jacobian part by part: its
working memory does not grow with the number of blocks (a whole program chunk's Jacobians of a
spline model took a gigabyte), and the parts give each block the standard error of its own.

Oracle: the covariance applied by hand to central differences of the model's deviation (a second
formulation: not the parameter Jacobian, nor the matrix products, the gate uses)."""
import tracemalloc

import numpy as np

from mtcomp import load_machine
from mtcomp.models import ErrorModel, FittedModel, deviation
from mtcomp.planner import CompensationProblem, Planner, PlannerOptions
from mtcomp.planner import _evaluate

PART = 64          # poses a part, in place of SD_ROWS: many parts on few poses


def _fitted(names=None):
    """xfyz with polynomial errors of some um, and a covariance over ``names`` (every parameter)."""
    fitted = FittedModel.zero(ErrorModel(load_machine("xfyz").with_basis("polynomial")))
    rng = np.random.default_rng(5)
    p = fitted.params.values
    p[:] = rng.normal(size=p.size) * 1e-3
    names = list(fitted.params.names) if names is None else names
    A = rng.normal(size=(len(names), len(names))) * 1e-4
    fitted.uncertainty = {"names": names, "covariance": A @ A.T,
                          "undetermined": np.zeros((len(names), 0))}
    return fitted


def _poses(n):
    rng = np.random.default_rng(6)
    return rng.uniform([-300.0, -200.0, -200.0], [300.0, 200.0, 100.0], size=(n, 3))


def _evaluator(fitted):
    return Planner(CompensationProblem.from_machine(fitted),
                   PlannerOptions(threads=1, max_correction_sd_um=5.0)).ev


def _oracle_um(fitted, q):
    """(n, 3) each tip component's standard error, um: central differences of the deviation,
    parameter by parameter, under the covariance."""
    p = np.asarray(fitted.params.values, dtype=float)
    u = fitted.uncertainty
    cols = []
    for name in u["names"]:
        dp = np.zeros_like(p)
        dp[fitted.params.index(name)] = 1e-6
        cols.append((deviation(fitted.model, q, p + dp)[:, :3]
                     - deviation(fitted.model, q, p - dp)[:, :3]) / 2e-6)
    J = np.stack(cols, axis=2)                                   # (n, 3, k) mm per unit
    return np.sqrt(np.einsum("nik,kl,nil->ni", J, u["covariance"], J)) * 1e3


def test_parts_give_each_block_its_own_standard_error(monkeypatch):
    """Blocks on either side of the parts' borders (and a covariance naming only some parameters,
    in another order) get the standard error central differences give."""
    monkeypatch.setattr(_evaluate, "SD_ROWS", 7)
    q = _poses(23)
    for names in (None, ["EZY_3", "EXX_1", "EYX_2", "A0Z"]):
        fitted = _fitted(names)
        ev = _evaluator(fitted)
        got = ev.correction_sd_assumed(q, fitted.context(len(q)))[:, :3]
        np.testing.assert_allclose(got, _oracle_um(fitted, q), rtol=1e-6, atol=1e-9)


def test_working_memory_does_not_grow_with_the_blocks(monkeypatch):
    """64 parts of poses: the peak of what the gate allocates stays under a quarter of what the
    whole program's Jacobian alone takes (the previous code held it whole, and copies of it)."""
    monkeypatch.setattr(_evaluate, "SD_ROWS", PART)
    fitted = _fitted()
    ev = _evaluator(fitted)
    n = 64 * PART
    q = _poses(n)
    ctx = fitted.context(n)
    ev.correction_sd_assumed(q[:PART], ctx[:PART])           # compiled and loaded outside the count
    tracemalloc.start()
    try:
        sd = ev.correction_sd_assumed(q, ctx)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    whole = n * 3 * fitted.model.n_params * 8
    assert np.all(np.isfinite(sd[:, :3])) and np.all(sd[:, :3] > 0)
    assert peak < whole / 4, (peak, whole)

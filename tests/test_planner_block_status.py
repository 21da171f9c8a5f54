"""Planner.block_status: what the planner's rules say of each block, against the model's support
by hand and a standard error from finite differences of the deviation."""
import numpy as np

from mtcomp import load_machine
from mtcomp.models import ErrorModel, FittedModel, deviation
from mtcomp.planner import CompensationProblem, Planner, PlannerOptions


def _planner(limit_um):
    machine = load_machine("xfyz").with_basis("polynomial")
    fitted = FittedModel.zero(ErrorModel(machine))
    fitted.params.set_file_value("EXX_1", 40.0)
    fitted.support = {"X": (-20.0, 0.0)}                  # the data reached x in [-20, 0] mm only
    sigma = 3e-3                                          # standard error of EXX_1, internal units
    fitted.uncertainty = {"names": ["EXX_1"], "covariance": np.array([[sigma ** 2]]),
                          "undetermined": np.zeros((1, 0))}
    options = PlannerOptions(threads=1, max_correction_sd_um=limit_um)
    return machine, fitted, sigma, Planner(CompensationProblem.from_machine(fitted), options)


def test_block_status_names_unknown_and_outside_axes_and_the_standard_error():
    machine, fitted, sigma, planner = _planner(limit_um=1e6)
    q = np.array([[-10.0, 5.0, -3.0], [-15.0, 0.0, 0.0], [10.0, 0.0, 0.0], [-5.0, 1.0, 2.0],
                  [-20.0 - 1e-7, 0.0, 0.0]])
    known = np.ones(q.shape, bool)
    known[1, 2] = False                                   # Z of the second block not given
    known[3, 0] = False                                   # X of the fourth: outside never applies
    q[3, 0] = 50.0
    feed = np.full(5, 1000.0)
    dirs = np.ones(q.shape)
    unknown, outside, sd, _ = planner.block_status(q, known, feed, dirs)
    np.testing.assert_array_equal(unknown, ~known)
    expected_out = np.zeros(q.shape, bool)
    expected_out[2, 0] = True                             # x = 10 mm > 0; -20 - 1e-7 is within slack
    np.testing.assert_array_equal(outside, expected_out)
    # not corrected anyway (an unknown axis, outside the support): no standard error evaluated
    assert np.isnan(sd[[1, 2, 3]]).all()
    # corrected blocks: sigma times the largest tip component's sensitivity to EXX_1 (um)
    p = np.asarray(fitted.params.values, dtype=float)
    i = fitted.params.index("EXX_1")
    h = 1e-6
    dp = np.zeros_like(p)
    dp[i] = h
    ok = [0, 4]
    d = (deviation(fitted.model, q[ok], p + dp)[:, :3] - deviation(fitted.model, q[ok], p - dp)[:, :3]) / (2 * h)
    expected_sd = 1e3 * sigma * np.max(np.abs(d), axis=1)
    np.testing.assert_allclose(sd[ok], expected_sd, rtol=1e-6, atol=1e-12)
    assert np.all(expected_sd > 1e-2)                     # the check sees a standard error at all


def test_block_status_without_a_limit_evaluates_no_standard_error():
    _, _, _, planner = _planner(limit_um=0.0)
    q = np.array([[-10.0, 5.0, -3.0]])
    unknown, outside, sd, _ = planner.block_status(q, np.ones(q.shape, bool), np.full(1, 1000.0),
                                                np.ones(q.shape))
    assert not unknown.any() and not outside.any()
    assert np.isnan(sd).all()

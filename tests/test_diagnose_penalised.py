"""The model diagnose writes is the penalised fit: between measured targets its profile follows the
smoothest curve through them, and its standard error says where it rests on the penalty.

The truth is a positioning profile written here (a sine and a slope, sharing no code with mtcomp's
models), read by a laser at coarse targets with seeded noise; the oracle is that truth itself.
"""
from __future__ import annotations

import csv

import numpy as np
import pytest

from mtcomp.diagnose import diagnose
from mtcomp.identification.predict import predict_readings
from mtcomp.machine import load_machine
from mtcomp.measurement.files import read_measurements

TARGETS = np.arange(0.0, 201.0, 20.0)       # mm: a pitch table's coarse targets
NOISE_UM = 0.4


def truth_um(x):
    """The true positioning error of X, um: a 70 mm wave, 3.5 targets a period."""
    return 9.0 * np.sin(2.0 * np.pi * x / 70.0 + 0.4) + 0.03 * x


def _write(path, rows):
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["axis", "component", "target_mm", "dir", "run", "value_um"])
        w.writerows(rows)


@pytest.fixture(scope="module")
def diagnosed(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("penalised")
    rng = np.random.default_rng(20261)
    rows = []
    for run in range(1, 6):
        for d in (1, -1):
            for x in TARGETS[::d]:
                rows.append(["X", "EXX", f"{x:.3f}", d, run, f"{truth_um(x) + rng.normal(0, NOISE_UM):.5f}"])
    _write(tmp / "runs.csv", rows)
    machine = load_machine("xfyz")
    d = diagnose(machine, [read_measurements(tmp / "runs.csv")])
    grid = np.arange(0.0, 200.5, 1.0)
    _write(tmp / "grid.csv", [["X", "EXX", f"{x:.3f}", 1, 1, ""] for x in grid])
    pred = predict_readings(d.model, read_measurements(tmp / "grid.csv"), machine)
    return d, grid, pred.columns["pred_value_um"], pred.columns["pred_value_um_sd"]


def test_between_targets_the_profile_stays_within_its_standard_error_of_the_truth(diagnosed):
    d, grid, value, sd = diagnosed
    assert [f.effect for f in d.findings] == []        # nothing beyond the base is in the data
    at = np.isin(grid, TARGETS)
    # a new file's zero is unknown to the model: compare up to the mean offset at the targets
    offset = np.mean(value[at] - truth_um(grid[at]))
    err = value - offset - truth_um(grid)
    mid = np.isin(grid, TARGETS[:-1] + 10.0)
    assert np.all(np.isfinite(sd))
    assert np.max(np.abs(err[mid]) / sd[mid]) < 3.0, np.abs(err[mid]) / sd[mid]
    # and the curve between targets is the truth's to a small share of its 18 um swing
    assert np.max(np.abs(err)) < 3.0, np.max(np.abs(err))


def test_standard_error_grows_between_targets(diagnosed):
    _, grid, _, sd = diagnosed
    at = np.isin(grid, TARGETS)
    mid = np.isin(grid, TARGETS[:-1] + 10.0)
    # every midpoint's sd above the larger of its two targets' (the data are there, not between)
    sd_at = sd[at]
    assert np.all(sd[mid] > 1.2 * np.maximum(sd_at[:-1], sd_at[1:])), (sd[mid], sd_at)


def test_the_report_describes_the_penalised_model(diagnosed):
    d, _, _, _ = diagnosed
    fin = d.final
    # the penalised fit spends fewer effective degrees of freedom than it has parameters, and its
    # rms residual is that of the model written: the readings' noise, not less
    assert 0 < fin["edf"] < fin["n_params"]
    assert fin["rms_um"] == pytest.approx(NOISE_UM, rel=0.3, abs=0.0)
    assert fin["heldout_rms_um"] >= fin["rms_um"]
    assert d.model.info["smoothing"]["criterion"] == "REML"


def test_left_out_residuals_are_those_of_a_fit_without_the_readings():
    """The held-out figure's identity against its definition: a penalised least-squares fit solved
    again, by numpy, without the readings left out (random design, penalty and readings)."""
    from mtcomp.diagnose._penalised import left_out_residuals
    rng = np.random.default_rng(7)
    n, k = 60, 12
    X = rng.normal(size=(n, k))
    D = np.diff(np.eye(k), 2, axis=0)
    S = 3.0 * D.T @ D                                   # a second-difference roughness penalty
    y = X @ rng.normal(size=k) + rng.normal(0, 0.3, n)
    P = X.T @ X + S
    r = y - X @ np.linalg.solve(P, X.T @ y)
    out = np.zeros(n, dtype=bool)
    out[rng.choice(n, 15, replace=False)] = True
    b = np.linalg.solve(X[~out].T @ X[~out] + S, X[~out].T @ y[~out])
    np.testing.assert_allclose(left_out_residuals(X[out], P, r[out]), y[out] - X[out] @ b,
                               rtol=1e-9, atol=1e-12)
    # a coefficient held at the full fit's value in the refit
    b_full = np.linalg.solve(P, X.T @ y)
    keep = np.arange(1, k)
    bk = np.linalg.solve((X[~out].T @ X[~out] + S)[np.ix_(keep, keep)],
                         X[~out][:, keep].T @ (y[~out] - X[~out][:, 0] * b_full[0])
                         - S[np.ix_(keep, [0])][:, 0] * b_full[0])
    expected = y[out] - X[out][:, 0] * b_full[0] - X[out][:, keep] @ bk
    np.testing.assert_allclose(left_out_residuals(X[out], P, r[out], np.eye(k)[:1]), expected,
                               rtol=1e-6, atol=1e-9)


def _knots_of_x(tmp_path, targets):
    """(base intervals of X, the final fit's intervals of X) for a laser run of X over ``targets``."""
    from mtcomp.diagnose._diagnose import _base_machine
    from mtcomp.diagnose._penalised import fine_machine
    rows = [["X", "EXX", f"{x:.3f}", d, 1, "0.0"] for d in (1, -1) for x in targets]
    _write(tmp_path / "run.csv", rows)
    data = [read_measurements(tmp_path / "run.csv")]
    base, _ = _base_machine(load_machine("xfyz"), data, None, None)
    fine = fine_machine(base, data, len(rows), {"X"})
    return base.axis("X").spline_intervals, fine.axis("X").spline_intervals


def test_only_an_axis_read_at_few_positions_gets_finer_knots(tmp_path):
    # nine targets 5 mm apart: nine functions (six cubic intervals), then knots a quarter of the
    # spacing apart over the 40 mm: 40 / 1.25 = 32 intervals
    assert _knots_of_x(tmp_path, np.arange(-20.0, 20.5, 5.0)) == (6, 32)
    # 41 positions 1 mm apart: more positions than the base's 16 functions, whose profile the
    # readings already fix between its knots; the knots stay
    assert _knots_of_x(tmp_path, np.arange(0.0, 40.5, 1.0)) == (13, 13)


def test_setups_carry_no_variance_and_readings_keep_theirs():
    """Two profile values p1, p2 and a laser zero s; a reading is p + s, so (1, 0, -1) is left open.
    Moved along it, the zero's variance goes to zero and every reading keeps its variance (hand
    derived: P x = (p1 + s, p2 + s, 0), so var(p1') = var(p1 + s))."""
    from mtcomp.identification.unmeasured import setups_without_variance
    rng = np.random.default_rng(3)
    L = rng.normal(size=(3, 3))
    cov = L @ L.T
    null = np.array([[1.0], [1.0], [-1.0]])          # the levels of p1, p2 against the zero
    held = rng.normal(size=(3, 1))
    moved, held2, sd2 = setups_without_variance(cov, held, np.array([2.0]), null, n_free=2)
    J = np.array([[1.0, 0.0, 1.0], [0.0, 1.0, 1.0], [1.0, -1.0, 0.0]])     # J @ null == 0
    np.testing.assert_allclose(np.diag(J @ moved @ J.T), np.diag(J @ cov @ J.T), rtol=1e-12, atol=0)
    np.testing.assert_allclose(moved[2], 0.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(moved[0, 0], cov[0, 0] + 2 * cov[0, 2] + cov[2, 2], rtol=1e-12, atol=0)
    # the held direction moved with it, its variance unchanged in the product
    np.testing.assert_allclose(sd2[0] ** 2 * np.outer(held2[:, 0], held2[:, 0]),
                               4.0 * np.outer(*(2 * [np.array([held[0, 0] + held[2, 0],
                                                               held[1, 0] + held[2, 0], 0.0])])),
                               rtol=1e-12, atol=1e-12)


def test_the_penalised_fit_is_written_unless_it_predicts_held_out_readings_clearly_worse():
    """The choice against its definition, by hand: the held-out sums of squares in noise variances
    (each reading's residual over its own noise), the slack 2 sqrt(2 k) of the selection's k
    determined directions; the penalised fit is written up to the slack, the least squares beyond."""
    from types import SimpleNamespace

    from mtcomp.diagnose._written import choose
    rng = np.random.default_rng(7)
    n, k = 60, 8                                   # slack 2 sqrt(16) = 8 noise variances
    noise = np.where(np.arange(n) < 40, 0.5, 2.0)  # um: two files, each its own floor
    st = SimpleNamespace(unit=np.array(["um"] * n))
    design = SimpleNamespace(w=1.0 / noise)
    ls = rng.normal(0.0, 1.0, n) * noise
    ls[5] = np.nan                                 # a reading no fold held out counts in neither
    ls[50] = 4.0                                   # 4 noise variances: room for an excess of -3
    for excess, taken in ((7.9, "penalised"), (8.1, "least_squares"), (-3.0, "penalised")):
        pen = ls.copy()
        # the excess put on one reading of the 2 um file: (r^2 - r0^2) / 2^2 = excess
        pen[50] = np.sqrt(ls[50] ** 2 + excess * 4.0)
        current = SimpleNamespace(cv_resid=ls, rank=k)
        w = choose(st, design, current, SimpleNamespace(cv_resid=pen))
        assert w["model"] == taken, (excess, w)
        assert w["heldout_excess_noise_variances"] == pytest.approx(excess, rel=0.0, abs=1e-3)
        assert w["heldout_slack_noise_variances"] == pytest.approx(8.0, rel=0.0, abs=1e-3)
        ok = np.isfinite(ls)
        assert w["heldout_rms_least_squares_um"] == pytest.approx(np.sqrt(np.mean(ls[ok] ** 2)), rel=0.0,
                                                                  abs=1e-4)
        assert w["heldout_rms_penalised_um"] == pytest.approx(np.sqrt(np.mean(pen[ok] ** 2)), rel=0.0,
                                                              abs=1e-4)


def test_the_report_says_which_model_is_written(diagnosed):
    """The smooth profile of the fixture: the penalised fit predicts held-out runs as well as the
    least squares, and is written; REPORT.json's figures are that fit's, the summary says so."""
    d, _, _, _ = diagnosed
    w = d.final["written"]
    assert w["model"] == "penalised"
    assert w["heldout_rms_penalised_um"] == d.final["heldout_rms_um"]
    assert w["heldout_excess_noise_variances"] <= w["heldout_slack_noise_variances"]
    assert d.to_dict()["final"]["written"]["model"] == "penalised"
    assert "model written: the penalised fit (held-out rms" in d.summary()

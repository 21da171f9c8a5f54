"""Knots at the data's spacing: a dense line of points gets as many spline functions as it has
positions (knots no closer than ``MIN_KNOT_MM``), so that the roughness penalty, not the knot count,
sets how smooth a profile is.

The counts are hand-derived; the profile is a sine of the independent machine (tests/truth), and the
oracle of what a basis size can follow is a least-squares fit of scipy's B-splines to it.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.interpolate import BSpline

from mtcomp.identification.fit import identify
from mtcomp.machine import load_machine
from mtcomp.measurement.files import read_measurements
from mtcomp.models.basis import MAX_BASIS, MIN_KNOT_MM, auto_spline, axis_spline, with_data_basis
from mtcomp.models.chain import linear_components


@pytest.mark.parametrize("positions, max_basis, expected", [
    # 41 points 18 mm apart over 720 mm: one function per point, 38 intervals of 18 mm
    (np.linspace(-360.0, 360.0, 41), None, (-360.0, 360.0, 38, 3)),
    # a laser run over 9 targets: one function per target, as a pitch table
    (np.linspace(-200.0, 200.0, 9), None, (-200.0, 200.0, 6, 3)),
    # 30 points over 100 mm: knots 16 mm apart would allow 9 functions; a short axis keeps 16
    (np.linspace(0.0, 100.0, 30), None, (0.0, 100.0, 13, 3)),
    # single-axis runs that ask for 16 functions keep 16, however dense the data
    (np.linspace(-360.0, 360.0, 41), 16, (-360.0, 360.0, 13, 3)),
])
def test_knots_follow_the_data_spacing(positions, max_basis, expected):
    assert auto_spline(positions, (-400.0, 400.0), max_basis=max_basis) == expected


def test_dense_data_stop_at_the_closest_knots_and_the_cap():
    """Every position distinct (a scan): over 400 mm the knots stop at 16 mm (25 intervals, 28
    functions); over 800 mm at the cap on functions, whichever is fewer."""
    rng = np.random.default_rng(0)
    lo, hi, n, degree = auto_spline(np.r_[-250.0, 150.0, rng.uniform(-250.0, 150.0, 5000)], (-250.0, 150.0))
    assert (lo, hi, n, degree) == (-250.0, 150.0, 25, 3)
    assert (hi - lo) / n >= MIN_KNOT_MM
    lo, hi, n, degree = auto_spline(np.r_[-400.0, 400.0, rng.uniform(-400.0, 400.0, 5000)], (-400.0, 400.0))
    assert n + degree == min(MAX_BASIS, 50 + 3)


PERIOD_MM, AMPLITUDE_UM = 90.0, 2.0


def _sine(s):
    return AMPLITUDE_UM * 1e-3 * np.sin(2.0 * np.pi * np.asarray(s, float) / PERIOD_MM + 0.4)


def _rms_about_line(s, v):
    r = v - np.polyval(np.polyfit(s, v, 1), s)
    return float(np.sqrt(np.mean(r ** 2)))


def _best_fit_rms_um(lo, hi, n_functions, s):
    """rms (about a line) of what the best cubic B-spline fit on n functions over [lo, hi] leaves of
    the sine at s: the most any fit on those knots can follow."""
    h = (hi - lo) / (n_functions - 3)
    x = np.linspace(lo, hi, 4001)
    t = lo + h * np.arange(-3, n_functions + 1)
    c = np.linalg.lstsq(BSpline.design_matrix(x, t, 3).toarray(), _sine(x) * 1e3, rcond=None)[0]
    return _rms_about_line(s, _sine(s) * 1e3 - BSpline(t, c, 3)(s))


def test_a_straightness_at_the_lines_spacing_is_followed(tmp_path):
    """A straightness of X (EYX) with a 90 mm wave, read by a tracker line of 41 points 18 mm apart
    on the independent machine: the fitted profile follows it between the points (within 0.1 um
    rms, about its least-squares line), where 16 functions (knots 55 mm apart) cannot follow it at
    all."""
    from truth import TruthMachine, campaigns
    truth = TruthMachine("xfyz")
    truth.components["X"]["EYX"] = _sine
    rng = np.random.default_rng(5)
    path = campaigns.points(truth, tmp_path / "line_x.csv", rng, grid=(41, 1, 1), margin=0.05,
                            plane={"Y": 0.0, "Z": 0.0}, tool_lengths_mm=(100.0,), repeats=2,
                            noise_um=0.1).path
    fm = identify(load_machine("xfyz"), [read_measurements(str(path))], hold=["Y", "Z"]).fitted_model
    spline = axis_spline(fm.model.machine.axis("X"))
    assert (spline.lo, spline.hi, spline.n_basis) == (-360.0, 360.0, 41)
    s = np.linspace(-330.0, 330.0, 661)                  # between the points as well as at them
    values = dict(zip(fm.params.names, fm.params.values))
    eyx = linear_components(fm.model.machine, "X", s, lambda n: values.get(n, 0.0))["EYX"] * 1e3
    off = _rms_about_line(s, eyx - _sine(s) * 1e3)
    assert _best_fit_rms_um(-360.0, 360.0, 16, s) > 1.0          # the oracle: 16 functions miss it
    assert off < 0.1, off


def test_an_unpenalised_fit_keeps_sixteen_functions():
    """diagnose's base fit carries no roughness penalty: the data's spacing gives it no more than 16
    functions per axis (its held-out comparisons refine an axis where the data ask), while a
    penalised fit of the same 41 positions gets one function per position."""
    machine = load_machine("xfyz")
    positions = {"X": np.linspace(-360.0, 360.0, 41), "Y": np.zeros(41), "Z": np.zeros(41)}
    n_basis = {penalised: axis_spline(with_data_basis(machine, positions, penalised=penalised).axis("X")).n_basis
               for penalised in (True, False)}
    assert n_basis == {True: 41, False: 16}
    # a large data set keeps 16 whether penalised or not: 100,000 rows over the budget
    rows = {a: np.resize(v, 100_000) for a, v in positions.items()}
    assert axis_spline(with_data_basis(machine, rows).axis("X")).n_basis == 16

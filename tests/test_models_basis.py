"""The base's resolution along a linear axis, chosen from single-axis runs (models.basis.spline_size_by_cv).

Each line is made here from its definition (numpy sines, a raised cosine, a screw's sine) with known
noise; none comes from mtcomp's model. Two runs over 200 irregular targets on 240 mm of a 540 mm
axis, as a fine laser run is taken.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.interpolate import BSpline

from mtcomp.models.basis import SPLINE_SIZES, SplineBasis, spline_size_by_cv

LO, HI = -270.0, 270.0
NOISE = 0.3


def _line(profile, seed=0, runs=2):
    rng = np.random.default_rng(seed)
    targets = np.sort(rng.uniform(-120.0, 120.0, 200))
    s = np.tile(targets, 2 * runs)
    run = np.repeat(np.arange(runs), 2 * targets.size)
    return s, profile(s) + rng.normal(0.0, NOISE, s.size), run


def _smooth(s):
    return 3.0 * np.sin(2 * np.pi * s / 700.0) + 1.5 * np.cos(2 * np.pi * s / 400.0)


def _rms_misfit(profile, n):
    """rms of the least-squares fit of ``profile`` on n uniform cubic B-splines over [LO, HI]."""
    x = np.linspace(-120.0, 120.0, 2001)
    h = (HI - LO) / (n - 3)
    X = BSpline.design_matrix(x, LO + h * np.arange(-3, n + 1), 3).toarray()
    y = profile(x)
    return float(np.sqrt(np.mean((y - X @ np.linalg.lstsq(X, y, rcond=None)[0]) ** 2)))


def test_a_smooth_line_keeps_the_default_size():
    n, scores = spline_size_by_cv([_line(_smooth)], LO, HI)
    assert n == SPLINE_SIZES[0]
    assert len(scores) > 1                    # the finer sizes were tried, and did not pay


def test_a_line_finer_than_the_default_gets_more_functions():
    def wavy(s):                              # 60 mm waves: 16 functions (knots 42 mm apart) miss them
        return _smooth(s) + 2.0 * np.sin(2 * np.pi * s / 60.0 + 0.4)
    assert _rms_misfit(wavy, 16) > 1.0 > 10 * _rms_misfit(wavy, 32)     # the oracle: what each size can follow
    n, scores = spline_size_by_cv([_line(wavy)], LO, HI)
    assert n > SPLINE_SIZES[0]
    assert _rms_misfit(wavy, n) < NOISE / 2
    # held-out score in noise variances: near the 800 readings at the chosen size, far above at 16
    assert scores[n] < 1.15 * 800 < scores[16] / 3


def test_a_local_bump_is_left_to_diagnose():
    def bump(s):
        u = (s - 30.0) / 20.0
        return _smooth(s) + np.where(np.abs(u) < 0.5, 2.0 * (1 + np.cos(2 * np.pi * u)), 0.0)
    n, scores = spline_size_by_cv([_line(bump)], LO, HI)
    assert n == SPLINE_SIZES[0]
    assert scores[16] > 1.5 * 800              # the bump is in the data: the default misses it


def test_a_screw_period_is_not_followed(monkeypatch):
    def screw(s):
        return _smooth(s) + 2.0 * np.sin(2 * np.pi * s / 10.0)
    n, _ = spline_size_by_cv([_line(screw)], LO, HI)
    assert n == SPLINE_SIZES[0]                 # the 10 mm line is left to diagnose
    # the rules that leave it: without the local rival and the 16 mm knots, the finest size wins
    import mtcomp.models.basis as basis
    monkeypatch.setattr(basis, "RIVAL_SHARE", 2.0)
    monkeypatch.setattr(basis, "MIN_KNOT_MM", 1.0)
    assert spline_size_by_cv([_line(screw)], LO, HI)[0] == SPLINE_SIZES[-1]


def test_a_single_run_cannot_tell():
    def wavy(s):
        return 2.0 * np.sin(2 * np.pi * s / 60.0)
    assert spline_size_by_cv([_line(wavy, runs=1)], LO, HI) == (SPLINE_SIZES[0], {})


def test_the_held_out_design_is_the_model_basis():
    """The size chooser's scipy design spans what SplineBasis builds (the same knots and degree)."""
    b = SplineBasis(LO, HI, 21, 3)
    s = np.linspace(LO, HI, 301)
    raw = np.array(b.raw(s)).T
    h = (HI - LO) / 21
    X = BSpline.design_matrix(s, LO + h * np.arange(-3, 25), 3).toarray()
    assert raw.shape == X.shape
    np.testing.assert_allclose(raw, X, atol=1e-10)     # truncated powers: round-off ~1e-16 (n+k)^k


@pytest.mark.parametrize("backlash_um", [0.0, 5.0])
def test_a_reversal_error_is_not_read_as_noise(tmp_path, backlash_um):
    """A bidirectional laser file (SPEC 3.2, written here by hand) of X with 60 mm waves: the size
    chosen from the file must not depend on the axis's backlash. Pooled about each target's mean over
    both directions, the repeats' scatter would be sigma^2 + B^2/4, and the waves drowned in it."""
    from mtcomp.machine import load_machine
    from mtcomp.measurement.files import read_measurements
    from mtcomp.measurement.readings import data_spline_sizes

    def wavy(s):
        return _smooth(s) + 0.5 * np.sin(2 * np.pi * s / 60.0 + 0.4)
    rng = np.random.default_rng(3)
    targets = np.sort(rng.uniform(LO, HI, 300))
    rows = ["axis,component,target_mm,dir,run,value_um"]
    for run in (1, 2):
        for d in (1, -1):
            for t in targets[::d]:
                v = wavy(t) + d * backlash_um / 2 + rng.normal(0.0, NOISE)
                rows.append(f"X,EXX,{t:.4f},{d},{run},{v:.5f}")
    path = tmp_path / "laser_x.csv"
    path.write_text("\n".join(rows) + "\n")
    sizes = data_spline_sizes(load_machine("xfyz"), [read_measurements(path)])
    assert sizes["X"] >= 32


def test_the_slope_at_the_ends_of_the_knots_is_the_one_from_inside():
    """A velocity read where the data end (the last knot) sees the error's slope there: the CasADi
    basis's derivative at lo and hi is the one-sided one from inside the range (a clip by fmin/fmax
    gave half of it), and zero beyond (the error stays at its end value)."""
    import casadi as ca
    basis = SplineBasis(-100.0, 100.0, 8, 3)
    s = ca.SX.sym("s")
    f = ca.Function("f", [s], [ca.jacobian(ca.vertcat(*basis.functions(s, False)), s)])
    h = 1e-6
    for end, inside in ((-100.0, -100.0 + h), (100.0, 100.0 - h)):
        got = np.asarray(f(end)).ravel()
        one_sided = (np.array(basis.functions(inside, False)) - np.array(basis.functions(end, False))) \
            / (inside - end)
        assert np.abs(one_sided).max() > 1e-3
        np.testing.assert_allclose(got, one_sided, rtol=0, atol=1e-6)
        np.testing.assert_allclose(np.asarray(f(end + np.sign(end) * 1.0)).ravel(), 0.0, rtol=0, atol=0)

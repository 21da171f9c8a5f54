"""A combination the data cannot determine that turns an instrument's frame (a CMM's or a
tracker's set-up rotation) goes to whichever side makes the smaller displacement where it acts: the
machine parameters by their rms tool-tip error over the data's region, the frames by their rms
displacement over their own files' extents (the machine only where it moves at most half as much).

* The rule itself on a hand-built problem: one machine parameter m and a frame rotation ry that the
  readings see only as the sum m + ry; the solution derived by hand (the side that moves less takes
  it; with two files the machine takes the files' mean, weighted by their points).
* Plates with holes at two depths 2.2 mm apart, read in X and Y only, each plate with its own
  (known to the test) set-up translation and turn about Z and no tilt; every deep hole is off the
  shallow ones by the same (dX, dY), which the machine's Z motion makes (a squareness or a
  straightness of Z over 2.2 mm). The frames' tilts about X and Y would move a plate's 90 x 55 mm
  box by 16 and 26 mm per rad (rms), the machine's term moves the tool tip over the 2.2 mm of Z the
  data cover by 1.3 mm per rad, so the machine takes the offset: every fitted tilt is zero (to
  0.5 urad) and a new plate (set-up unknown) is predicted with its deep holes off by (dX, dY).
  Before, every frame was tilted by dY / 2.2 mm about X and dX / 2.2 mm about Y (682 and
  1364 urad) and the new plate was predicted without the offset.
* What the data determine of a set-up is still fitted: each plate's turn about Z (which the
  machine's squareness and straightness of X in Y could carry only by a rotation about the machine's
  origin, which moves the region's points more than the turn about the plate's centre moves
  them), and a tracker frame tilted about all three axes over a volume read in X, Y and Z.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mtcomp.identification.fit import identify
from mtcomp.identification.predict import predict_readings
from mtcomp.identification.problem import build_measurement_models, frame_rotations, frame_rule_complement
from mtcomp.machine import load_machine
from mtcomp.models.chain import ErrorModel
from mtcomp.sim import make_points

ROOT = Path(__file__).resolve().parents[1]
#: a vertical machining centre (table on X on Y, spindle on Z) around the plates
MACHINE = ROOT / "examples" / "hurco_vmx_plates.toml"
DEPTH_MM = 2.2
#: the deep holes' offset from the shallow ones, um (what the machine's Z motion makes)
OFFSET_UM = (3.0, -1.5)


# --------------------------------------------------------------------------- the rule itself
def _rule_solution(m_size_mm: float, frames: list[tuple[float, int]], sums_mm: list[float]):
    """Solve readings ``m + ry_f = sums_mm[f]`` (one per frame; every other set-up unknown read
    alone, at zero) in the directions :func:`frame_rule_complement` leaves free. Unknowns (all
    column scales 1): m (moves the tool tip by ``m_size_mm`` per unit over the region), then per
    frame tx ty tz rx ry rz, each frame's rotation moving its points by ``size`` (rms, mm per unit)
    over ``count`` points. Returns (m, [ry_f])."""
    nf = len(frames)
    n = 1 + 6 * nf
    J, d = [], []
    for f, s in enumerate(sums_mm):
        row = np.zeros(n)
        row[0], row[1 + 6 * f + 4] = 1.0, 1.0
        J.append(row)
        d.append(s)
        for k in (0, 1, 2, 3, 5):                    # tx ty tz rx rz: read alone, at zero
            row = np.zeros(n)
            row[1 + 6 * f + k] = 1.0
            J.append(row)
            d.append(0.0)
    J, d = np.array(J), np.array(d)
    null = np.zeros((n, 1))
    null[0] = 1.0
    for f in range(nf):
        null[1 + 6 * f + 4] = -1.0
    null /= np.linalg.norm(null)
    assert np.allclose(J @ null, 0.0, rtol=0.0, atol=1e-15)
    metric = np.zeros((n, n))
    metric[0, 0] = m_size_mm ** 2
    rotations = [(np.arange(1 + 6 * f + 3, 1 + 6 * f + 6), size ** 2 * np.eye(3), count)
                 for f, (size, count) in enumerate(frames)]
    B = frame_rule_complement(null, np.ones(n), np.arange(n) == 0, None, metric, rotations)
    assert B.shape == (n, n - 1)
    np.testing.assert_allclose(B.T @ B, np.eye(n - 1), rtol=0.0, atol=1e-12)
    y, *_ = np.linalg.lstsq(J @ B, d, rcond=None)
    x = B @ y
    np.testing.assert_allclose(J @ x, d, rtol=0.0, atol=1e-12)   # every fit of the data is reached
    return x[0], [x[1 + 6 * f + 4] for f in range(nf)]


def test_the_side_that_moves_less_takes_the_combination():
    # the frame moves its points 40 mm per rad, the machine the tool tip 1.3 mm per rad: machine
    m, (ry,) = _rule_solution(1.3, [(40.0, 10)], [2e-3])
    assert m == pytest.approx(2e-3, rel=1e-12, abs=0.0)
    assert ry == pytest.approx(0.0, rel=0.0, abs=1e-15)
    # the other way round: the set-up takes it, and no machine error is made up
    m, (ry,) = _rule_solution(40.0, [(1.3, 10)], [2e-3])
    assert m == pytest.approx(0.0, rel=0.0, abs=1e-8)           # the set-ups' rule: 1e-6 of it
    assert ry == pytest.approx(2e-3, rel=1e-5, abs=0.0)


def test_the_machine_takes_the_files_mean_weighted_by_their_points():
    # frames of 1 and 3 points, the same size: held is 1/4 ry_1 + 3/4 ry_2 = 0, with ry_f = k_f - m:
    # m = (k_1 + 3 k_2) / 4 (derived by hand)
    k1, k2 = 1e-3, 3e-3
    m, (ry1, ry2) = _rule_solution(1.3, [(40.0, 1), (40.0, 3)], [k1, k2])
    assert m == pytest.approx((k1 + 3.0 * k2) / 4.0, rel=1e-12, abs=0.0)
    assert ry1 == pytest.approx(k1 - m, rel=1e-12, abs=0.0)
    assert ry2 == pytest.approx(k2 - m, rel=1e-12, abs=0.0)


def test_a_frames_turn_is_measured_over_the_box_its_points_span(tmp_path):
    # a 120 x 60 mm plate at one height (5 x 3 points, one row without readings), a tracker line;
    # mean of |w x r|^2 over the box about its centre: G = tr(S) I - S, S = diag(L^2 / 12)
    machine = load_machine(str(MACHINE))
    xy = np.array([(x, y, 0.0) for x in np.linspace(0.0, 120.0, 5) for y in (-60.0, -30.0, 0.0)])
    dev = np.zeros((len(xy), 3))
    dev[:, 2] = np.nan
    dev[-1] = np.nan                                   # x 120, y 0 read nothing: the box stays 120 x 60
    plate = make_points(xy, deviation=dev, path=str(tmp_path / "plate.csv"))
    line = make_points(np.column_stack([np.linspace(10, 50, 5), np.zeros(5), np.full(5, -20.0)]),
                       path=str(tmp_path / "line.csv"))
    known = make_points(xy, path=str(tmp_path / "known.csv"))
    mms = build_measurement_models(ErrorModel(machine), [plate, known, line], known_setup=["known"])
    (i1, G1, n1), (i2, G2, n2) = frame_rotations(mms, n_free=7)
    np.testing.assert_array_equal(i1, [7 + 3, 7 + 4, 7 + 5])       # rx ry rz after tx ty tz
    np.testing.assert_array_equal(i2, [7 + 6 + 3, 7 + 6 + 4, 7 + 6 + 5])   # the known file has none
    assert (n1, n2) == (14, 5)                          # measured rows
    np.testing.assert_allclose(G1, np.diag([60.0 ** 2, 120.0 ** 2, 120.0 ** 2 + 60.0 ** 2]) / 12.0,
                               rtol=1e-12, atol=0.0)
    # a line along X: a turn about X moves none of it
    np.testing.assert_allclose(G2, np.diag([0.0, 40.0 ** 2, 40.0 ** 2]) / 12.0, rtol=1e-12, atol=1e-12)


# --------------------------------------------------------------------------- plates at two depths
def _holes() -> np.ndarray:
    """(n, 3) mm: nine shallow holes (z 0) and four deep ones (z -2.2) on a 100 x 60 mm plate."""
    shallow = [(x, y, 0.0) for x in (20.0, 60.0, 110.0) for y in (-65.0, -35.0, -10.0)]
    deep = [(x, y, -DEPTH_MM) for x in (25.0, 100.0) for y in (-60.0, -12.0)]
    return np.array(shallow + deep)


def _plate(path: Path, xyz: np.ndarray, t_um, rz_urad: float):
    """A plate's points read in X and Y: the deep holes off by OFFSET_UM, seen through a CMM frame
    translated by t_um and turned by rz_urad about Z (about the holes' centroid), no tilt."""
    arm = xyz - xyz.mean(axis=0)
    deep = xyz[:, 2] < -1.0
    dx = OFFSET_UM[0] * deep + t_um[0] - rz_urad * 1e-6 * arm[:, 1] * 1e3
    dy = OFFSET_UM[1] * deep + t_um[1] + rz_urad * 1e-6 * arm[:, 0] * 1e3
    dev = np.column_stack([dx, dy, np.full(len(xyz), np.nan)]) * 1e-3
    return make_points(xyz, deviation=dev, path=str(path))


@pytest.fixture(scope="module")
def plates_fit(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("plates")
    rng = np.random.default_rng(24)
    xyz = _holes()
    truth = {f"plate{k}": (rng.normal(0.0, 5.0, 2), float(rng.normal(0.0, 80.0))) for k in range(4)}
    files = [_plate(tmp / f"{tag}.csv", xyz, t, rz) for tag, (t, rz) in truth.items()]
    machine = load_machine(str(MACHINE))
    return machine, identify(machine, files), truth, xyz, tmp


def test_plates_depth_offset_goes_to_the_machine_not_to_the_frames_tilts(plates_fit):
    _, result, truth, _, _ = plates_fit
    setup = dict(zip((s.name for s in result.nuisance_specs), result.nuisance_values * 1e6))
    for tag in truth:
        # urad; before: each frame tilted by the offset over the depth, 682 and 1364 urad. (Not
        # 0 exactly: the directions the rule judges one by one mix the tilts a little with the
        # frames' common turn about Z, which the set-ups keep)
        assert setup[f"{tag}:setup:rx"] == pytest.approx(0.0, rel=0.0, abs=0.5)
        assert setup[f"{tag}:setup:ry"] == pytest.approx(0.0, rel=0.0, abs=0.5)
    # the data are fitted exactly (noise-free, and the machine's Z motion can make the offset)
    for f in result.files:
        np.testing.assert_allclose(f.residual, 0.0, rtol=0.0, atol=1e-6)


def test_a_new_plate_is_predicted_with_its_deep_holes_offset(plates_fit):
    machine, result, _, xyz, tmp = plates_fit
    new = make_points(xyz, deviation=np.full((len(xyz), 3), np.nan), path=str(tmp / "new_plate.csv"))
    pred = predict_readings(result.fitted_model, new, machine)
    deep = xyz[:, 2] < -1.0
    for col, offset in zip(("pred_dx_um", "pred_dy_um"), OFFSET_UM):
        p = pred.columns[col]
        # deep minus shallow: the offset (before: 0, the frames had taken it)
        assert p[deep].mean() - p[~deep].mean() == pytest.approx(offset, rel=1e-3, abs=1e-4)
        # and nothing else: the plates show no other variation with position
        np.testing.assert_allclose(p[deep] - p[deep].mean(), 0.0, rtol=0.0, atol=1e-3)
        np.testing.assert_allclose(p[~deep] - p[~deep].mean(), 0.0, rtol=0.0, atol=1e-3)


def test_plates_keep_the_set_up_they_determine(plates_fit):
    _, result, truth, _, _ = plates_fit
    setup = dict(zip((s.name for s in result.nuisance_specs), result.nuisance_values * 1e6))
    for tag, (t_um, rz_urad) in truth.items():
        # the turn about Z: the machine could carry the plates' common turn only as a rotation about
        # its origin, which moves the region's points more than a turn about the plate's centre
        assert setup[f"{tag}:setup:rz"] == pytest.approx(rz_urad, rel=0.0, abs=0.05)
        # a translation stays the set-up's (um; the machine's term is zero at the shallow holes'
        # depth, the machine's Z = 0)
        assert setup[f"{tag}:setup:tx"] * 1e-3 == pytest.approx(t_um[0], rel=0.0, abs=1e-3)
        assert setup[f"{tag}:setup:ty"] * 1e-3 == pytest.approx(t_um[1], rel=0.0, abs=1e-3)


# --------------------------------------------------------------------------- a tilted tracker
def test_a_tracker_frame_tilted_about_every_axis_is_fitted(tmp_path):
    """A tracker aligned to nothing: a 3 x 3 x 3 grid over 200 x 160 x 120 mm read in X, Y and Z,
    through a frame turned by (300, -200, 150) urad and shifted by (4, -2, 3) um, on a machine
    without errors. The data determine the frame; the rule leaves it to the set-up."""
    g = np.array(np.meshgrid([-100.0, 0.0, 100.0], [-80.0, 0.0, 80.0], [-200.0, -140.0, -80.0],
                             indexing="ij")).reshape(3, -1).T
    w = np.array([300.0, -200.0, 150.0]) * 1e-6
    t = np.array([4.0, -2.0, 3.0]) * 1e-3
    dev = t + np.cross(w, g - g.mean(axis=0))
    data = make_points(g, deviation=dev, path=str(tmp_path / "tracker.csv"))
    result = identify(load_machine(str(MACHINE)), [data])
    setup = dict(zip((s.name for s in result.nuisance_specs), result.nuisance_values))
    np.testing.assert_allclose([setup[f"tracker:setup:r{a}"] for a in "xyz"], w, rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose([setup[f"tracker:setup:t{a}"] for a in "xyz"], t, rtol=0.0, atol=1e-7)
    p = result.fitted_model.params.values
    # no machine error made up (mm and rad: 1 nm, 1 urad; the frame's turn is 150 to 300 urad)
    np.testing.assert_allclose(p, 0.0, rtol=0.0, atol=1e-6)

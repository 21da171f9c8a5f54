"""The truth machine (tests/truth) against hand-derived cases; nothing here uses mtcomp."""
import csv
import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from truth import (Backlash, Context, FeedAbbe, FeedOffset, LocalDefect, PeriodicError, RotaryBacklash,
                   RotaryRunout, SpindleSchedule, ThermalDrift, TruthMachine, campaigns, form_error)
from truth import profiles as P

UM, URAD = 1e-3, 1e-6


def _read(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def _rx(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def _ry(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _rz(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def _q3(rng, n=20):
    return np.column_stack([rng.uniform(-300, 300, n), rng.uniform(-250, 250, n), rng.uniform(-200, 100, n)])


# ------------------------------------------------------------------------------------- nominal
@pytest.mark.parametrize("topology", ["XFYZ", "CAFXYZ", "CBFXYZ"])
def test_zero_machine_has_no_deviation(topology, tmp_path):
    rng = np.random.default_rng(0)
    m = TruthMachine.zero(topology)
    q = np.zeros((30, m.n_axes))
    q[:, :3] = _q3(rng, 30)
    q[:, 3:] = rng.uniform(-2, 2, (30, m.n_axes - 3))
    ctx = Context(feed_mm_min=3000.0, dirs={"X": -1}, t_s=500.0)
    d_tip, d_axis = m.true_deviation(q, rng.uniform(0, 200, 30), ctx)
    assert_allclose(d_tip, 0.0, rtol=0, atol=1e-12)
    assert_allclose(d_axis, 0.0, rtol=0, atol=1e-12)
    res = campaigns.points(m, tmp_path / "p.csv", rng, grid=(2, 2, 2), setup=False, noise_um=0.0)
    assert_allclose(res.columns["dx_um"], 0.0, rtol=0, atol=1e-9)
    res = campaigns.ballbar_circles(m, tmp_path / "b.csv", rng, setup=False, noise_mm=0.0, n_points=12)
    assert_allclose(res.columns["length_mm"], 100.0, rtol=0, atol=1e-12)


def test_tool_fixed_offsets_are_given_in_the_workpiece_frame():
    m = TruthMachine.zero("CAFXYZ")
    q = np.array([[40.0, -20.0, 60.0, math.radians(25.0), math.radians(90.0)]])
    b = np.array([0.0, 100.0, 0.0])
    tip0, _ = m.nominal_pose(q)
    assert_allclose(m.point_position(q, b), tip0 + b, rtol=0, atol=1e-12)
    assert_allclose(m.point_deviation(q, b), 0.0, rtol=0, atol=1e-12)
    assert_allclose(m.ballbar_length(q, tip0[0] + [0.0, 0.0, 50.0], b), math.hypot(100.0, 50.0), rtol=0,
                    atol=1e-12)


def test_q_from_file_units():
    m = TruthMachine.zero("CAFXYZ")
    assert_allclose(m.q_from(1.0, 2.0, 3.0, a_deg=90.0, c_deg=[0.0, 180.0]),
                    [[1, 2, 3, math.pi / 2, 0.0], [1, 2, 3, math.pi / 2, math.pi]], rtol=1e-15, atol=0)
    with pytest.raises(ValueError, match="no axis B"):
        m.q_from(b_deg=10.0)


def test_nominal_xfyz_tip_is_q():
    m = TruthMachine.zero("XFYZ")
    q = _q3(np.random.default_rng(1))
    tip, axis = m.nominal_pose(q, 130.0)
    assert_allclose(tip, q, rtol=0, atol=1e-12)
    assert_allclose(axis, np.tile([0, 0, 1.0], (len(q), 1)), rtol=0, atol=1e-12)


def test_nominal_five_axis_by_hand():
    m = TruthMachine.zero("CAFXYZ")          # A axis point (0, 0, -100), C through the origin
    p = np.array([50.0, 20.0, 30.0])
    a, c = math.radians(30.0), math.radians(90.0)
    tip, axis = m.nominal_pose(np.array([[*p, a, c]]))
    ap = np.array([0, 0, -100.0])
    # wp2bed = A C: bed point p in the workpiece frame is C^-1 A^-1 p
    expected = _rz(-c) @ (_rx(-a) @ (p - ap) + ap)
    assert_allclose(tip[0], expected, rtol=0, atol=1e-12)
    assert_allclose(axis[0], _rz(-c) @ _rx(-a) @ [0, 0, 1.0], rtol=0, atol=1e-12)
    m = TruthMachine.zero("CBFXYZ")
    b = math.radians(-40.0)
    tip, _ = m.nominal_pose(np.array([[*p, b, 0.0]]))
    assert_allclose(tip[0], _ry(-b) @ (p - ap) + ap, rtol=0, atol=1e-12)


# ------------------------------------------------------------------------------------- linear axes
def test_squareness_signs():
    q = _q3(np.random.default_rng(2))
    x, y, z = q.T
    m = TruthMachine.zero("XFYZ")
    c0y = 40 * URAD
    m.squareness["C0Y"] = c0y
    d, _ = m.true_deviation(q)
    assert_allclose(d[:, 0], -y * math.sin(c0y), rtol=1e-12, atol=1e-12)
    assert_allclose(d[:, 1], y * (math.cos(c0y) - 1), rtol=1e-9, atol=1e-12)
    assert_allclose(d[:, 2], 0.0, rtol=0, atol=1e-12)
    m = TruthMachine.zero("CAFXYZ")
    a0z, b0z = -25 * URAD, 55 * URAD
    m.squareness.update(A0Z=a0z, B0Z=b0z)
    qq = np.column_stack([q, np.zeros((len(q), 2))])
    d, _ = m.true_deviation(qq)
    assert_allclose(d[:, 0], z * math.sin(b0z) * math.cos(a0z), rtol=1e-12, atol=1e-12)
    assert_allclose(d[:, 1], -z * math.sin(a0z), rtol=1e-12, atol=1e-12)
    # first order as in docs/conventions.md
    assert_allclose(d[:, :2], np.column_stack([z * b0z, -z * a0z]), rtol=1e-6, atol=1e-12)


def test_table_pitch_about_its_pivot_by_hand():
    m = TruthMachine.zero("XFYZ")
    eps = 30 * URAD
    p = np.array([120.0, -40.0, -60.0])
    m.components["X"]["EBX"] = P.Constant(eps)
    m.pivots["X"] = p
    q = _q3(np.random.default_rng(3))
    d, d_axis = m.true_deviation(q, 80.0)
    # the tool relative to the table turns by Ry(eps) about p (table coordinates)
    expected = (q - p) @ (_ry(eps) - np.eye(3)).T
    assert_allclose(d, expected, rtol=1e-12, atol=1e-12)
    assert_allclose(d_axis, np.tile(_ry(eps) @ [0, 0, 1.0] - [0, 0, 1.0], (len(q), 1)), rtol=1e-12,
                    atol=1e-14)


def test_tool_side_yaw_about_carriage_pivot_by_hand():
    m = TruthMachine.zero("XFYZ")
    eps = -20 * URAD
    p = np.array([30.0, 70.0, 250.0])
    m.components["Y"]["ECY"] = P.Constant(eps)
    m.pivots["Y"] = p
    q = _q3(np.random.default_rng(4))
    d, _ = m.true_deviation(q)
    L0 = m.reference_tool_mm
    arm = np.column_stack([np.zeros(len(q)), np.zeros(len(q)), q[:, 2] - L0]) - p    # tip in the Y carriage
    assert_allclose(d, arm @ (_rz(eps) - np.eye(3)).T, rtol=1e-12, atol=1e-12)


def test_tool_side_pitch_arm_does_not_depend_on_the_tool_length():
    """The Y slide's pivot is fixed on the slide, and with tool length compensation the tip of any
    tool is at the commanded point (the ram stands higher for a longer tool): a pitch of the slide,
    which carries the ram and the tool rigidly, moves that point the same for every tool."""
    m = TruthMachine.zero("XFYZ")
    L0 = m.reference_tool_mm
    eps = 25 * URAD
    p = np.array([10.0, -40.0, 120.0])                   # relative to the gauge point at q = 0
    m.components["Y"]["EAY"] = P.Constant(eps)
    m.pivots["Y"] = p
    q = _q3(np.random.default_rng(8), 5)
    arm = np.column_stack([np.zeros(len(q)), np.zeros(len(q)), q[:, 2] - L0]) - p
    for L in (0.0, 90.0, 250.0):
        d, _ = m.true_deviation(q, L)
        assert_allclose(d, arm @ (_rx(eps) - np.eye(3)).T, rtol=1e-9, atol=1e-12)


def test_spindle_carriage_pivot_is_fixed_to_the_gauge_point():
    m = TruthMachine.zero("XFYZ")
    eps = 18 * URAD
    p = np.array([-20.0, 40.0, 150.0])                   # relative to the spindle gauge point
    m.components["Z"]["EAZ"] = P.Constant(eps)
    m.pivots["Z"] = p
    q = _q3(np.random.default_rng(30), 4)
    for L in (0.0, 90.0, 200.0):
        d, _ = m.true_deviation(q, L)
        arm = -(p + [0.0, 0.0, L])                       # tip relative to the pivot
        assert_allclose(d, np.tile((_rx(eps) - np.eye(3)) @ arm, (4, 1)), rtol=1e-9, atol=1e-12)


def test_translational_components_add_on_either_side():
    m = TruthMachine.zero("XFYZ")
    m.components["X"]["EYX"] = P.Linear(2 * UM, 10 * UM / 400.0)
    m.components["Z"]["EXZ"] = P.Constant(-3 * UM)
    q = _q3(np.random.default_rng(5))
    d, _ = m.true_deviation(q)
    assert_allclose(d[:, 0], -3 * UM, rtol=1e-12, atol=1e-12)
    assert_allclose(d[:, 1], 2 * UM + 10 * UM / 400.0 * q[:, 0], rtol=1e-12, atol=1e-12)
    assert_allclose(d[:, 2], 0.0, rtol=0, atol=1e-12)


def test_spindle_tilt_with_two_tool_lengths():
    m = TruthMachine.zero("XFYZ")
    ta, tb = 12 * URAD, -25 * URAD
    m.spindle_tilt = np.array([ta, tb])
    q = _q3(np.random.default_rng(6), 5)
    for L in (0.0, 100.0, 250.0):
        d, d_axis = m.true_deviation(q, L)
        expected = L * np.array([-math.cos(ta) * math.sin(tb), math.sin(ta), 1 - math.cos(ta) * math.cos(tb)])
        assert_allclose(d, np.tile(expected, (5, 1)), rtol=1e-12, atol=1e-12)
        assert_allclose(d_axis[0], _ry(tb) @ _rx(ta) @ [0, 0, 1.0] - [0, 0, 1], rtol=1e-12, atol=1e-14)


def test_ram_errors_at_its_machine_position():
    """Tool length compensation puts the ram at z + L - L0 for the tip of a tool of length L at z
    (L0 = 100 mm, the xfyz file's): its positioning error, straightness and the squareness of its
    travel are those of that position; the tool hangs along Z from it."""
    m = TruthMachine.zero("XFYZ")
    assert m.reference_tool_mm == 100.0
    m.components["Z"]["EZZ"] = P.Linear(0.0, 20 * UM / 400.0)
    m.components["Z"]["EXZ"] = P.Linear(1 * UM, 8 * UM / 400.0)
    b0z = 30 * URAD
    m.squareness["B0Z"] = b0z
    q = np.array([[0.0, 0.0, -100.0]])
    for L, zr in ((100.0, -100.0), (160.0, -40.0), (0.0, -200.0)):
        d = m.true_deviation(q, L)[0][0]
        assert_allclose(d[2], zr * 20 * UM / 400.0 + zr * (math.cos(b0z) - 1), rtol=1e-9, atol=1e-12)
        assert_allclose(d[0], 1 * UM + zr * 8 * UM / 400.0 + zr * math.sin(b0z), rtol=1e-9, atol=1e-12)


# ------------------------------------------------------------------------------------- rotary axes
def test_rotary_offset_x0c_by_hand():
    m = TruthMachine.zero("CAFXYZ")
    x0c = 25 * UM
    m.location["X0C"] = x0c
    th = np.radians([0.0, 30.0, 90.0, 200.0])
    q = np.zeros((4, 5))
    q[:, :3] = [80.0, -40.0, 20.0]
    q[:, 4] = th
    d, _ = m.true_deviation(q)
    assert_allclose(d[:, 0], x0c * (1 - np.cos(th)), rtol=1e-9, atol=1e-12)
    assert_allclose(d[:, 1], x0c * np.sin(th), rtol=1e-9, atol=1e-12)
    assert_allclose(d[:, 2], 0.0, rtol=0, atol=1e-12)


def test_rotary_positioning_and_tilt_location_by_hand():
    m = TruthMachine.zero("CAFXYZ")
    e = 15 * URAD
    m.components["C"]["ECC"] = P.Constant(e)
    th = math.radians(60.0)
    p = np.array([100.0, 50.0, 30.0])
    d, _ = m.true_deviation(np.array([[*p, 0.0, th]]))
    assert_allclose(d[0], _rz(-(th + e)) @ p - _rz(-th) @ p, rtol=1e-12, atol=1e-12)
    m = TruthMachine.zero("CAFXYZ")
    a0c = 40 * URAD
    m.location["A0C"] = a0c
    d, _ = m.true_deviation(np.array([[*p, 0.0, th]]))
    u = _rx(a0c) @ [0, 0, 1.0]
    K = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
    R = np.eye(3) + math.sin(th) * K + (1 - math.cos(th)) * K @ K
    assert_allclose(d[0], R.T @ p - _rz(-th) @ p, rtol=1e-10, atol=1e-12)


def test_a_axis_offset_z0a_by_hand():
    m = TruthMachine.zero("CAFXYZ")
    z0a = -30 * UM
    m.location["Z0A"] = z0a
    a = math.radians(45.0)
    p = np.array([10.0, 20.0, 30.0])
    d, _ = m.true_deviation(np.array([[*p, a, 0.0]]))
    c = np.array([0, 0, -100.0 + z0a])
    c0 = np.array([0, 0, -100.0])
    assert_allclose(d[0], (_rx(-a) @ (p - c) + c) - (_rx(-a) @ (p - c0) + c0), rtol=1e-9, atol=1e-12)


def test_rotary_runout_and_backlash():
    m = TruthMachine.zero("CBFXYZ").with_effects(RotaryRunout("C", eccentricity_um=4.0, phase_rad=0.3),
                                                 RotaryBacklash("C", magnitude_urad=20.0))
    th = np.radians([0.0, 45.0, 170.0])
    p = np.array([0.0, 0.0, 50.0])
    q = np.zeros((3, 5))
    q[:, :3] = p
    q[:, 4] = th
    for sign in (1, -1):
        d, _ = m.true_deviation(q, context=Context(dirs={"C": sign}))
        e = 4 * UM * np.column_stack([np.cos(th + 0.3), np.sin(th + 0.3), np.zeros(3)])
        # table turned by theta + sign*10 urad and shifted by e (bed frame); the tip on the axis sees -e
        for k in range(3):
            Rt = _rz(th[k] + sign * 10 * URAD)
            assert_allclose(d[k], Rt.T @ (p - e[k]) - _rz(th[k]).T @ p, rtol=1e-9, atol=1e-12)


# ------------------------------------------------------------------------------------- hidden effects
def test_backlash_step_equals_magnitude_in_laser_file(tmp_path):
    m = TruthMachine.zero("XFYZ").with_effects(Backlash("X", magnitude_um=-7.5))
    res = campaigns.laser(m, tmp_path / "x.csv", np.random.default_rng(7), "X", components=("EXX",),
                          setup=False, noise_um=0.0)
    rows = _read(res.path)
    v = np.array([float(r["value_um"]) for r in rows])
    d = np.array([int(r["dir"]) for r in rows])
    assert_allclose(v[d > 0], -3.75, rtol=0, atol=1e-9)
    assert_allclose(v[d < 0], 3.75, rtol=0, atol=1e-9)
    assert len(rows) == 11 * 5 * 2


def test_periodic_feed_offset_and_local_defect():
    m = TruthMachine.zero("XFYZ").with_effects(PeriodicError("Y", 16.0, 1.5, 0.2),
                                               FeedOffset("X", 0.8, signed=True),
                                               LocalDefect("Z", -50.0, 20.0, 3.0))
    q = np.array([[10.0, 37.0, -45.0], [10.0, 37.0, -80.0]])
    d, _ = m.true_deviation(q, context=Context(feed_mm_min=2500.0, dirs={"X": -1}))
    assert_allclose(d[:, 0], -0.8 * 2.5 * UM, rtol=1e-9, atol=1e-12)
    assert_allclose(d[:, 1], 1.5 * UM * math.sin(2 * math.pi * 37.0 / 16.0 + 0.2), rtol=1e-9, atol=1e-12)
    assert_allclose(d[:, 2], [3.0 * UM * 0.5 * (1 + math.cos(2 * math.pi * 5.0 / 20.0)), 0.0], rtol=1e-12,
                    atol=1e-14)


def test_feed_dependent_abbe_gain_and_irc_shift():
    eps, p = 20 * URAD, np.array([50.0, 100.0, -40.0])
    q = np.array([[200.0, 30.0, -10.0]])
    feed = 3000.0
    m = TruthMachine.zero("XFYZ")
    m.components["X"]["ECX"] = P.Constant(eps)
    m.pivots["X"] = p
    g = TruthMachine.copy(m).with_effects(FeedAbbe("X", "C", angle_gain_per_m_min=0.1))
    d, _ = g.true_deviation(q, context=Context(feed_mm_min=feed))
    assert_allclose(d[0], (_rz(eps * 1.3) - np.eye(3)) @ (q[0] - p), rtol=1e-12, atol=1e-12)
    s = m.with_effects(FeedAbbe("X", "C", irc_shift_mm_per_m_min=(0.0, 40.0, 0.0)))
    d, _ = s.true_deviation(q, context=Context(feed_mm_min=feed))
    p_feed = p + [0.0, 120.0, 0.0]
    assert_allclose(d[0], (_rz(eps) - np.eye(3)) @ (q[0] - p_feed), rtol=1e-12, atol=1e-12)


def test_thermal_drift_moves_the_spindle_along_machine_axes():
    m = TruthMachine.zero("CAFXYZ").with_effects(ThermalDrift("linear", (3.0, 0.0, -6.0)))
    th = math.radians(90.0)
    q = np.array([[50.0, 10.0, 0.0, 0.0, th]])
    d, _ = m.true_deviation(q, context=Context(t_s=7200.0))
    # 2 h of drift (6, 0, -12) um along the machine axes, seen from the table turned by 90 deg
    assert_allclose(d[0], _rz(-th) @ [6 * UM, 0.0, -12 * UM], rtol=1e-9, atol=1e-12)


def test_spindle_schedule_lag_against_fine_integration():
    sched = SpindleSchedule(((0.0, 0.0), (600.0, 3000.0), (2400.0, 6000.0), (4000.0, 0.0)))
    tau, ref = 900.0, 6000.0
    dt = 0.05
    t = np.arange(0.0, 6000.0, dt)
    h = np.zeros_like(t)
    u = sched.rpm(t) / ref
    for k in range(1, len(t)):          # trapezoidal step of dh/dt = (u - h)/tau
        h[k] = (h[k - 1] * (1 - dt / (2 * tau)) + dt / tau * 0.5 * (u[k - 1] + u[k])) / (1 + dt / (2 * tau))
    probe = np.array([500.0, 1000.0, 2400.0, 3000.0, 5000.0])
    idx = np.round(probe / dt).astype(int)
    assert_allclose(sched.lag(probe, tau, ref), h[idx], rtol=0, atol=2e-5)


def test_thermal_drivers_translate_the_tool():
    sched = SpindleSchedule(((0.0, 6000.0),))
    q = np.array([[100.0, 0.0, 0.0]] * 2)
    t = np.array([300.0, 3600.0])
    m = TruthMachine.zero("XFYZ").with_effects(ThermalDrift("time", (1.0, 0.0, -8.0), tau_s=1200.0))
    d, _ = m.true_deviation(q, context=Context(t_s=t))
    assert_allclose(d[:, 2], -8 * UM * (1 - np.exp(-t / 1200.0)), rtol=1e-9, atol=1e-12)
    m = TruthMachine.zero("XFYZ").with_effects(ThermalDrift("spindle", (0, 0, -10.0), tau_s=1000.0,
                                                            schedule=sched))
    d, _ = m.true_deviation(q, context=Context(t_s=t))
    assert_allclose(d[:, 2], -10 * UM * (1 - np.exp(-t / 1000.0)), rtol=1e-9, atol=1e-12)
    m = TruthMachine.zero("XFYZ").with_effects(ThermalDrift("temperature", (0, 2.0, 0), channel="bed"))
    d, _ = m.true_deviation(q, context=Context(temperatures={"bed": [21.0, 19.5]}))
    assert_allclose(d[:, 1], [2 * UM, -1 * UM], rtol=1e-9, atol=1e-12)


# ------------------------------------------------------------------------------------- random machine
@pytest.mark.parametrize("topology", ["XFYZ", "CAFXYZ", "CBFXYZ"])
def test_random_machine_magnitudes_and_constant_angles(topology):
    m = TruthMachine.random(topology, np.random.default_rng(11))
    for a in m.axis_names:
        if a not in "XYZ":
            assert abs(m.components[a][f"E{a}{a}"](np.array([0.0]))[0]) > 0.5 * URAD
            continue
        lo, hi = m.travel[a]
        for c, f in m.components[a].items():
            pp = P.peak_to_peak(f, lo, hi)
            if c[1] == a:
                assert 4.9 * UM < pp < 30.1 * UM
            elif c[1] in "XYZ":
                assert 1.9 * UM < pp < 10.1 * UM
            else:
                assert 4.9 * URAD < pp < 30.1 * URAD
                assert 3 * URAD - 1e-12 <= abs(f(np.array([0.0]))[0]) <= 20 * URAD + 1e-12
    q = np.zeros((1, m.n_axes))
    d, _ = m.true_deviation(q)
    assert 0 < np.linalg.norm(d) < 0.1                   # nonzero, below 100 um at the origin
    assert all(abs(v) >= 10 * URAD for k, v in m.squareness.items())


def test_random_machine_is_reproducible():
    q = _q3(np.random.default_rng(0))
    d1 = TruthMachine.random("XFYZ", np.random.default_rng(5)).true_deviation(q)[0]
    d2 = TruthMachine.random("XFYZ", np.random.default_rng(5)).true_deviation(q)[0]
    assert_allclose(d1, d2, rtol=0, atol=0)


# ------------------------------------------------------------------------------------- campaigns
def test_points_setup_rotation_and_translation(tmp_path):
    m = TruthMachine.zero("XFYZ")
    res = campaigns.points(m, tmp_path / "p.csv", np.random.default_rng(8), grid=(3, 3, 2), noise_um=0.0)
    rows = _read(res.path)
    w = res.setup["rotation_urad"] * URAD
    t = res.setup["translation_um"]
    assert np.all(np.abs(w) >= 5 * URAD) and np.all(np.abs(t) >= 2.0)
    theta = np.linalg.norm(w)
    u = w / theta
    K = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
    R = np.eye(3) + math.sin(theta) * K + (1 - math.cos(theta)) * K @ K
    p = np.array([[float(r[k]) for k in ("x_mm", "y_mm", "z_mm")] for r in rows])
    dev = np.array([[float(r[k]) for k in ("dx_um", "dy_um", "dz_um")] for r in rows])
    assert_allclose(dev, (p @ (R - np.eye(3)).T) * 1e3 + t, rtol=0, atol=1e-6)
    assert {r["tool_mm"] for r in rows} == {"100", "160"}
    assert {r["dir_x"] for r in rows} == {"1", "-1"}
    assert len({r["feed_mm_min"] for r in rows}) == 3
    t_s = np.array([float(r["t_s"]) for r in rows])
    assert np.all(np.diff(t_s) > 0)


def test_points_plane_and_five_axis_columns(tmp_path):
    m = TruthMachine.random("CBFXYZ", np.random.default_rng(9))
    res = campaigns.points(m, tmp_path / "p.csv", np.random.default_rng(9), grid=(3, 3, 1), plane={"z": 0.0},
                           rotary_deg=[(0.0, 0.0), (-30.0, 90.0)], tool_lengths_mm=(50.0, 100.0, 150.0),
                           repeats=2, noise_um=0.0, setup=False)
    rows = _read(res.path)
    assert len(rows) == 9 * 2 * 3 * 2 * 2
    assert {r["z_mm"] for r in rows} == {"0"}
    assert {r["b_deg"] for r in rows} == {"0", "-30"} and {r["run"] for r in rows} == {"1", "2"}
    d, _ = m.true_deviation(res.q, res.columns["tool_mm"], res.context)
    assert_allclose(np.array([float(r["dy_um"]) for r in rows]), d[:, 1] * 1e3, rtol=0, atol=1e-7)


def test_laser_positioning_with_optic_offset_is_the_abbe_formula(tmp_path):
    m = TruthMachine.zero("XFYZ")
    eps = 25 * URAD
    p = np.array([40.0, -30.0, -50.0])
    m.components["X"]["ECX"] = P.Constant(eps)
    m.pivots["X"] = p
    optic = np.array([0.0, 150.0, 80.0])
    res = campaigns.laser(m, tmp_path / "x.csv", np.random.default_rng(10), "X",
                          components=("EXX", "ECX", "EYX"), static={"Y": 100.0, "Z": -20.0},
                          optic_mm=optic, setup=False, noise_um=0.0, noise_urad=0.0, n_runs=2)
    rows = _read(res.path)
    for r in rows:
        x = float(r["target_mm"])
        v = np.array([x, 100.0, -20.0]) + optic - p            # arm from the table pivot
        if r["component"] == "EXX":
            assert r["value_urad"] == ""
            expected = ((math.cos(eps) - 1) * v[0] - math.sin(eps) * v[1]) * 1e3
            assert_allclose(float(r["value_um"]), expected, rtol=1e-9, atol=1e-9)
            assert_allclose(float(r["value_um"]), -eps * v[1] * 1e3, rtol=1e-3, atol=0)
        elif r["component"] == "EYX":
            expected = (math.sin(eps) * v[0] + (math.cos(eps) - 1) * v[1]) * 1e3
            assert_allclose(float(r["value_um"]), expected, rtol=1e-9, atol=1e-9)
        else:
            assert r["value_um"] == ""
            assert_allclose(float(r["value_urad"]), 25.0, rtol=1e-9, atol=0)
    seq = [int(r["seq"]) for r in rows if r["component"] == "EXX"]
    assert seq == list(range(1, 2 * 2 * 11 + 1))
    assert {r["y_mm"] for r in rows} == {"100"} and rows[0]["x_mm"] == rows[0]["target_mm"]


def test_laser_setup_offsets_and_slopes(tmp_path):
    m = TruthMachine.random("XFYZ", np.random.default_rng(12))
    rng = np.random.default_rng(13)
    res = campaigns.laser(m, tmp_path / "y.csv", rng, "Y", noise_um=0.0, noise_urad=0.0)
    comp = np.array(res.columns["component"])
    tg = res.columns["target_mm"]
    for c in ("EYY", "EXY", "EBY"):
        sel = comp == c
        col = "value_urad" if c[1] in "ABC" else "value_um"
        extra = res.columns[col][sel] - res.ideal[col][sel]
        assert_allclose(extra, res.setup["offset"][c] + res.setup["slope_urad"][c] * tg[sel] / 1000.0,
                        rtol=0, atol=1e-9)
    assert res.setup["slope_urad"]["EYY"] == 0.0 and abs(res.setup["slope_urad"]["EXY"]) >= 5.0


def test_rotary_laser_reads_actual_minus_commanded_angle(tmp_path):
    m = TruthMachine.zero("CAFXYZ")
    f = P.Fourier(12 * URAD, (5 * URAD,), (-3 * URAD,))
    m.components["C"]["ECC"] = f
    m.location["X0C"] = 20 * UM                          # location errors do not change the angle
    res = campaigns.laser(m, tmp_path / "c.csv", np.random.default_rng(14), "C", setup=False, noise_urad=0.0)
    rows = _read(res.path)
    assert "target_deg" in rows[0] and rows[0]["value_um"] == ""
    th = np.radians([float(r["target_deg"]) for r in rows])
    assert_allclose([float(r["value_urad"]) for r in rows], f(th) / URAD, rtol=1e-9, atol=1e-9)


def test_ballbar_circle_length_by_hand(tmp_path):
    m = TruthMachine.zero("XFYZ")
    m.components["X"]["EXX"] = P.Constant(6 * UM)
    res = campaigns.ballbar_circles(m, tmp_path / "b.csv", np.random.default_rng(15), planes=("XY", "ZX"),
                                    radius_mm=150.0, n_points=36, noise_mm=0.0)
    rows = _read(res.path)
    off = res.setup["length_offset_mm"]
    assert 1e-3 <= abs(off) <= 20e-3
    for r in rows:
        d = np.array([float(r[f"{c}_mm"]) - float(r[f"table_ball_{c}_mm"]) for c in "xyz"]) + [6 * UM, 0, 0]
        assert_allclose(float(r["length_mm"]), np.linalg.norm(d) + off, rtol=0, atol=1e-9)
    xy = [r for r in rows if r["z_mm"] == rows[0]["z_mm"] and r["run"] in ("1", "2")]
    assert len(xy) == 72 and {r["dir_z"] for r in xy} == {"1"}
    r1 = [r for r in rows if r["run"] == "1"]
    assert r1[1]["dir_x"] == "-1" and r1[1]["dir_y"] == "1"           # counter-clockwise from phi = 0


def test_three_sphere_by_hand(tmp_path):
    m = TruthMachine.zero("CAFXYZ")
    m.location["X0C"] = 30 * UM
    res = campaigns.three_sphere(m, tmp_path / "t.csv", np.random.default_rng(16), angles_deg=[0, 90, 180],
                                 n_runs=1, setup=False, noise_mm=0.0)
    rows = _read(res.path)
    assert len(rows) == 2 * 3 * 2 * 3
    for r in rows:
        th = math.radians(float(r["c_deg"]))
        tool = np.array([float(r[f"{c}_mm"]) for c in "xyz"])          # bed = wp at C = 0
        ball = np.array([float(r[f"table_ball_{c}_mm"]) for c in "xyz"])
        c = np.array([30 * UM, 0, 0])
        ball_bed = _rz(th) @ (ball - c) + c          # the table ball turns about the actual line
        assert_allclose(float(r["length_mm"]), np.linalg.norm(tool - ball_bed), rtol=0, atol=1e-9)
    assert {r["dir_c"] for r in rows} == {"1", "-1"}


def test_thermal_file_zeroed_at_start(tmp_path):
    sched = SpindleSchedule(((0.0, 0.0), (600.0, 6000.0)))
    m = TruthMachine.random("XFYZ", np.random.default_rng(17)).with_effects(
        ThermalDrift("spindle", (0.0, 0.0, -12.0), tau_s=1200.0, schedule=sched))
    res = campaigns.thermal(m, tmp_path / "th.csv", np.random.default_rng(18), duration_h=1.0,
                            noise_um=0.0, noise_c=0.0)
    rows = _read(res.path)
    t = np.array([float(r["t_s"]) for r in rows])
    dz = np.array([float(r["disp_z_um"]) for r in rows])
    expected = -12.0 * np.where(t > 600, 1 - np.exp(-(t - 600) / 1200.0), 0.0)
    assert_allclose(dz, expected, rtol=0, atol=1e-7)
    assert {r["spindle_rpm"] for r in rows} == {"0", "6000"}
    assert {"temp_spindle_c", "temp_ambient_c", "temp_bed_c"} <= set(rows[0])


def test_noise_has_the_given_sigma(tmp_path):
    m = TruthMachine.zero("XFYZ")
    res = campaigns.points(m, tmp_path / "p.csv", np.random.default_rng(19), grid=(6, 6, 6), setup=False,
                           noise_um=0.5)
    r = np.concatenate([res.columns[k] - res.ideal[k] for k in ("dx_um", "dy_um", "dz_um")])
    assert 0.45 < r.std() < 0.55


# ------------------------------------------------------------------------------------- cut, form error
def test_form_error_removes_rigid_motion_only():
    rng = np.random.default_rng(20)
    nominal = rng.uniform(-50, 50, (200, 3))
    w = np.array([30, -20, 50.0]) * URAD
    R = _rz(w[2]) @ _ry(w[1]) @ _rx(w[0])
    moved = nominal @ R.T + [0.01, -0.02, 0.005]
    fe = form_error(moved, nominal)
    assert fe.rms_um < 1e-9 and fe.max_um < 1e-9
    bump = np.zeros_like(nominal)
    bump[:, 2] = 2 * UM * np.sign(nominal[:, 0]) * (np.abs(nominal[:, 0]) > 25)   # not rigid
    fe = form_error(moved + bump, nominal)
    assert 0.5 < fe.rms_um < 2.0 and fe.max_um <= 2.0 + 1e-9


def test_cut_equals_true_pose():
    m = TruthMachine.random("XFYZ", np.random.default_rng(21))
    q = _q3(np.random.default_rng(22))
    ctx = Context(feed_mm_min=1500.0)
    assert_allclose(m.cut(q, 90.0, ctx)[0], m.true_pose(q, 90.0, ctx)[0], rtol=0, atol=0)


def test_truth_does_not_import_mtcomp():
    import pathlib
    import truth
    for f in pathlib.Path(truth.__file__).parent.glob("*.py"):
        text = f.read_text()
        assert "import mtcomp" not in text and "from mtcomp" not in text, f.name


def test_velocity_irc_is_the_table_pivot_shifted_by_feed(tmp_path):
    m = TruthMachine.zero("XFYZ")
    m.components["X"]["ECX"] = P.Linear(5 * URAD, 40 * URAD / 400.0)
    p = np.array([120.0, 30.0, -50.0])
    m.pivots["X"] = p
    m = m.with_effects(FeedAbbe("X", irc_shift_mm_per_m_min=(10.0, -20.0, 0.0)))
    res = campaigns.velocity(m, tmp_path / "v.csv", np.random.default_rng(23), n_runs=1, noise_mm_min=0.0)
    rows = _read(res.path)
    assert len(rows) == 3 * 41 and {r["dir_x"] for r in rows} == {"1"}
    feed = res.columns["feed_mm_min"]
    expected = p[:2] + np.outer(feed / 1000.0, [10.0, -20.0])
    assert_allclose(res.setup["irc_xy_mm"], expected, rtol=0, atol=0.02)
    # first order by hand: v = V e_x + Omega e_z x (P - O), Omega = V dECX/ds
    V, om = feed, feed * 40 * URAD / 400.0
    M = np.array([50.0, 150.0])
    assert_allclose(res.columns["m_vy_mm_min"], om * (M[0] - expected[:, 0]), rtol=1e-3, atol=1e-6)
    assert_allclose(res.columns["m_vx_mm_min"], V - om * (M[1] - expected[:, 1]), rtol=0, atol=1e-5)


def test_rotary_run_translational_reading_is_the_table_motion(tmp_path):
    m = TruthMachine.zero("CAFXYZ").with_effects(RotaryRunout("C", eccentricity_um=5.0))
    res = campaigns.laser(m, tmp_path / "c.csv", np.random.default_rng(24), "C", components=("EXC", "EYC"),
                          setup=False, noise_um=0.0, n_targets=8, n_runs=1)
    rows = _read(res.path)
    # the table shifted by e (cos th, sin th) in the bed is, seen along the workpiece axes that turn with
    # it, a constant (e, 0): the reading (table relative to tool) is +5 um on EXC and 0 on EYC
    for r in rows:
        expected = 5.0 if r["component"] == "EXC" else 0.0
        assert_allclose(float(r["value_um"]), expected, rtol=0, atol=1e-8)
    assert len(rows) == 2 * 8 * 2


@pytest.mark.parametrize("kind", ["backlash", "rotary_backlash", "periodic_error", "feed_dependent_offset",
                                  "feed_dependent_abbe", "thermal_drift", "rotary_pdge", "local_defect"])
def test_random_effects_change_the_truth(kind):
    from truth import random_effect
    rng = np.random.default_rng(25)
    base = TruthMachine.random("CBFXYZ", rng)
    eff = random_effect(kind, base, rng)
    m = base.with_effects(eff)
    n = 400
    q = np.zeros((n, 5))
    q[:, :3] = _q3(rng, n)
    q[:, 3:] = rng.uniform(-1.5, 1.5, (n, 2))
    if kind == "local_defect":
        q[:, "XYZ".index(eff.axis)] = eff.centre_mm + rng.uniform(-0.3, 0.3, n) * eff.width_mm
    ctx = Context(feed_mm_min=rng.uniform(500, 5000, n),
                  dirs={a: rng.choice([-1.0, 1.0], n) for a in "XYZBC"}, t_s=rng.uniform(0, 20000, n),
                  temperatures={"spindle": rng.uniform(19, 26, n)})
    diff = m.true_deviation(q, context=ctx)[0] - base.true_deviation(q, context=ctx)[0]
    assert 0.3 * UM < np.abs(diff).max() < 60 * UM


def test_full_campaign_writes_every_file(tmp_path):
    m = TruthMachine.random("CAFXYZ", np.random.default_rng(26))
    out = campaigns.full_campaign(m, tmp_path, np.random.default_rng(27), points_grid=(2, 2, 2),
                                  laser_targets=5)
    assert set(out) == {"points", "laser_x", "laser_y", "laser_z", "laser_a", "laser_c", "ballbar",
                        "three_sphere"}
    starts = [out[k].columns["t_s"][0] for k in ("points", "laser_x", "laser_y", "ballbar", "three_sphere")]
    assert np.all(np.diff(starts) > 0)
    for res in out.values():
        assert res.path.parent == tmp_path and len(_read(res.path)) == len(res.q)


def test_laser_runs_at_several_feeds_see_the_feed_offset(tmp_path):
    m = TruthMachine.zero("XFYZ").with_effects(FeedOffset("Z", 1.5))
    res = campaigns.laser(m, tmp_path / "z.csv", np.random.default_rng(28), "Z", components=("EZZ",),
                          feed_mm_min=(1000.0, 4000.0), n_runs=2, n_targets=4, setup=False, noise_um=0.0)
    rows = _read(res.path)
    assert [r["run"] for r in rows[::8]] == ["1", "2", "3", "4"]
    for r in rows:
        assert_allclose(float(r["value_um"]), 1.5 * float(r["feed_mm_min"]) / 1000.0, rtol=1e-9, atol=1e-9)


def test_thermal_machine_records_its_environment_in_every_file(tmp_path):
    drift = ThermalDrift("temperature", (0.0, 0.0, -2.0), channel="spindle", t_ref_c=20.0)
    m = TruthMachine.zero("XFYZ").with_effects(drift)
    out = campaigns.full_campaign(m, tmp_path, np.random.default_rng(29), points_grid=(2, 2, 2),
                                  laser_targets=3, setup=False, noise_um=0.0, noise_urad=0.0, noise_mm=0.0)
    for name in ("points", "laser_z", "ballbar"):
        rows = _read(out[name].path)
        assert {"spindle_rpm", "temp_spindle_c", "temp_ambient_c"} <= set(rows[0]), name
    rows = _read(out["points"].path)
    temp = np.array([float(r["temp_spindle_c"]) for r in rows])
    assert_allclose([float(r["dz_um"]) for r in rows], -2.0 * (temp - 20.0), rtol=1e-9, atol=1e-8)
    rows = [r for r in _read(out["laser_z"].path) if r["component"] == "EZZ"]
    temp = np.array([float(r["temp_spindle_c"]) for r in rows])
    assert_allclose([float(r["value_um"]) for r in rows], -2.0 * (temp - 20.0), rtol=1e-9, atol=1e-8)

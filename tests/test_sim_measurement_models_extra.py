"""cmm, thermal and velocity measurement models and the drift features: hand-derived values, a second
formulation (points model on the ball centre), finite-difference Jacobians."""
import math

import numpy as np
import pytest

from mtcomp import load_machine
from mtcomp.errors import InputError
from mtcomp.measurement.readings import model_class_for
from mtcomp.measurement.drift import spindle_heat, thermal_features
from mtcomp.measurement.files import Context
from mtcomp.models import (AbbeIRC, Backlash, ChannelDrift, ErrorModel, FittedModel, ParameterSet,
                           ThermalDrift, deviation)
from mtcomp.sim import VirtualMachine, cmm_plan, random_truth, thermal_plan, velocity_plan
from mtcomp.toolpaths.cutter import read_cut_program


def fd_jacobian(mm, p, nu, step=1e-5):
    # central differences; step 1e-5 keeps rounding (positions ~1e2 mm) and curvature below 1e-8
    J = np.zeros((mm.n_obs, p.size))
    for k in range(p.size):
        dp = np.zeros(p.size)
        dp[k] = step
        J[:, k] = (mm.predict(p + dp, nu) - mm.predict(p - dp, nu)) / (2 * step)
    return J


def ctx(t, rpm=None, temps=None):
    n = len(t)
    return Context(feed=np.full(n, np.nan), dirs=np.zeros((n, 6), np.int8), t=np.asarray(t, float),
                   run=np.full(n, -1),
                   spindle_rpm=np.full(n, np.nan) if rpm is None else np.asarray(rpm, float),
                   temperatures=temps or {})


def test_spindle_heat_is_the_exact_step_response():
    t = np.arange(0.0, 7200.0, 37.0)
    rpm = np.where(t >= 370.0, 6000.0, 0.0)
    h = spindle_heat(t, rpm, 900.0)
    expect = np.where(t > 370.0, 6.0 * (1 - np.exp(-(t - 370.0) / 900.0)), 0.0)
    np.testing.assert_allclose(h, expect, rtol=0, atol=1e-12)
    # rows out of time order give the same values row by row
    perm = np.random.default_rng(0).permutation(t.size)
    np.testing.assert_allclose(spindle_heat(t[perm], rpm[perm], 900.0), expect[perm], rtol=0, atol=1e-12)


def test_thermal_features_names_and_values():
    t = np.array([0.0, 1800.0, 3600.0])
    f = thermal_features(ctx(t, [0.0, 3000.0, 3000.0], {"s1": np.array([21.0, 21.5, 22.25])}),
                         time_constants_s=(600.0,))
    assert list(f) == ["time_h", "dtemp_s1", "spindle_heat_600"]
    np.testing.assert_allclose(f["time_h"], [0.0, 0.5, 1.0], rtol=0, atol=1e-15)
    np.testing.assert_allclose(f["dtemp_s1"], [0.0, 0.5, 1.25], rtol=0, atol=1e-12)
    np.testing.assert_allclose(f["spindle_heat_600"], [0.0, 0.0, 3.0 * (1 - math.exp(-3))], rtol=0,
                               atol=1e-12)


def thermal_truth():
    m = load_machine("xfyz").with_basis("polynomial")
    model = ErrorModel(m, [ThermalDrift("time", ("time_h",)), ThermalDrift("spindle", ("spindle_heat_900",)),
                           ChannelDrift("spindle", ("spindle_heat_900",), ("ch1",))])
    p = ParameterSet(model.param_specs)
    p["TD_X_time_h"], p["TD_Z_spindle_heat_900"], p["TD_ch1_spindle_heat_900"] = 2e-3, -4e-3, 1.5e-3
    p["EXX_1"] = 8e-3                                     # geometry: cancels at a fixed set-up
    return m, FittedModel(model, p)


def test_thermal_channels_follow_their_drift_terms(tmp_path):
    m, truth = thermal_truth()
    plan = thermal_plan(m, duration_h=3.0, interval_s=120.0, channels=("x", "z", "ch1"),
                        setup_q=[200.0, 0.0, -50.0], start_s=1800.0)
    data = VirtualMachine(m, truth, noise_um=0.0).measure(plan, tmp_path / "th.csv")
    heat = spindle_heat(data.t, data.context.spindle_rpm, 900.0)   # 10 significant digits in the CSV
    np.testing.assert_allclose(data.channels["x"], 2e-3 * (data.t - 1800.0) / 3600.0, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(data.channels["z"], -4e-3 * heat, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(data.channels["ch1"], 1.5e-3 * heat, rtol=1e-9, atol=1e-15)
    mm = model_class_for("thermal")(truth.model, data, setup_q=[200.0, 0.0, -50.0])
    nu = np.array([1e-3, -2e-3, 0.5e-3])
    np.testing.assert_allclose(mm.predict(truth.params.values, nu) - mm.predict(truth.params.values, 0 * nu),
                               np.tile(nu, len(data)), rtol=0, atol=1e-15)
    J, Jn = mm.jacobian(truth.params.values, nu)
    np.testing.assert_allclose(J, fd_jacobian(mm, truth.params.values, nu), rtol=0, atol=1e-7)
    assert Jn.shape == (mm.n_obs, 3)


def test_velocity_model_hand_formula_and_jacobian():
    m = load_machine("xfyz").with_basis("polynomial")
    model = ErrorModel(m, [AbbeIRC("X", angles="C", static=True, feed=True)])
    p = ParameterSet(model.param_specs)
    p["ECX_1"], p["ECX_2"] = 300e-6, -200e-6
    p["IRC_CX_x0"], p["IRC_CX_y0"], p["IRC_CX_y_f"] = 40.0, -25.0, 90.0
    # the carriage's own translation errors move every table point: positioning and straightness
    p["EXX_1"], p["EXX_2"], p["EYX_2"] = 20e-3, -10e-3, 15e-3           # mm per (s / m)^k
    truth = FittedModel(model, p)
    data = VirtualMachine(m, truth, noise_velocity_mm_min=0.0).measure(velocity_plan(m, n_runs=1))
    s, V = data.position, data.feed
    omega = (300e-6 / 1000 + 2 * -200e-6 * s / 1e6) * V
    dexx = (20e-3 / 1000 + 2 * -10e-3 * s / 1e6) * V                     # V dEXX/ds
    deyx = 2 * 15e-3 * s / 1e6 * V
    O = np.column_stack([np.full(s.size, 40.0), -25.0 + 90.0 * V / 1000])
    mm = model_class_for("velocity")(model, data)
    pred = mm.predict_columns(p.values)
    for pt, xy in (("m", data.m_xy), ("n", data.n_xy)):
        r = xy - O
        np.testing.assert_allclose(pred[f"pred_{pt}_vx_mm_min"], V + dexx - omega * r[:, 1], rtol=1e-14, atol=1e-12)
        np.testing.assert_allclose(pred[f"pred_{pt}_vy_mm_min"], deyx + omega * r[:, 0], rtol=1e-12, atol=1e-15)
    # the file holds them to 10 significant digits
    np.testing.assert_allclose(data.m_v[:, 1], pred["pred_m_vy_mm_min"], rtol=1e-9, atol=0)
    J, _ = mm.jacobian(p.values, mm.zero_nuisance())
    # v is bilinear in (yaw, centre) parameters: central differences are exact up to rounding
    np.testing.assert_allclose(J, fd_jacobian(mm, p.values, mm.zero_nuisance(), 1e-3), rtol=0, atol=1e-10)
    assert np.abs(J).max() > 1e-3
    # eq. 1 on these velocities finds the point moving at exactly V e_x: the model's rotation centre
    # shifted by the translation's slope: v - V e = t' + Omega e_z x (P - O) vanishes at
    # P = O + e_z x t' / Omega = O + (-V dEYX/ds, V dEXX/ds) / Omega
    centre = mm.rotation_centre(p.values)
    np.testing.assert_allclose(centre, O + np.column_stack([-deyx, dexx]) / omega[:, None], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(data.rotation_centre(), centre, rtol=0, atol=1e-3)   # file: 10 digits


def test_velocity_of_a_y_table_follows_its_squareness():
    # Y moves along Rz(C0Y) e_y: its points move at V (-sin C0Y, cos C0Y) when nothing else errs
    m = load_machine("xfyz").with_basis("polynomial")
    model = ErrorModel(m)
    p = ParameterSet(model.param_specs)
    p["C0Y"] = 50e-6
    data = VirtualMachine(m, FittedModel(model, p), noise_velocity_mm_min=0.0).measure(
        velocity_plan(m, axis="Y", n_runs=1))
    pred = model_class_for("velocity")(model, data).predict_columns(p.values)
    V = data.feed
    for pt in ("m", "n"):
        np.testing.assert_allclose(pred[f"pred_{pt}_vx_mm_min"], -V * np.sin(50e-6), rtol=1e-12, atol=0)
        np.testing.assert_allclose(pred[f"pred_{pt}_vy_mm_min"], V * np.cos(50e-6), rtol=1e-14, atol=0)


WALL = """%
G21 G90
G0 X300 Y-30 Z5
G1 Z-10 F500
G1 Y30 F1000
G0 Z5
M30
%
"""


def test_cmm_dn_is_the_ball_centre_deviation_along_the_normal(tmp_path):
    m = load_machine("xfyz").with_basis("polynomial")
    prog = tmp_path / "wall.nc"
    prog.write_text(WALL)
    truth = random_truth(m, np.random.default_rng(3), terms=[Backlash("Y")])
    r = 3.0
    y = np.linspace(-25.0, 25.0, 11)
    # the wall on the +x side of the tool: surface x = r, outward normal -x
    pts = np.column_stack([np.full(y.size, 300.0 + r), y, np.full(y.size, -7.0)])
    nrm = np.tile([-1.0, 0.0, 0.0], (y.size, 1))
    cut = read_cut_program(prog, m)
    data = VirtualMachine(m, truth, noise_um=0.0).measure(cmm_plan(pts, nrm, cut, r), tmp_path / "c.csv")
    # second formulation: the official deviation (tip and tool axis) at the cutter location the
    # program gives by hand: x = 300, z = -10, y = the point's y; feed 1000, X never moved (+1), Y up,
    # Z down, the machine's tool length
    model = truth.model
    q = np.column_stack([np.full(y.size, 300.0), y, np.full(y.size, -10.0)])
    c = model.default_context(y.size)
    for name, v in (("feed", 1000.0), ("dir_X", 1.0), ("dir_Y", 1.0), ("dir_Z", -1.0)):
        c[:, model.context_names.index(name)] = v
    dev = deviation(model, q, truth.params.values, c)
    oracle = np.einsum("ij,ij->i", nrm, dev[:, :3] + r * dev[:, 3:]) * 1e3
    assert np.abs(np.einsum("ij,ij->i", nrm, r * dev[:, 3:])).max() * 1e3 > 1e-3   # the tilt acts
    mm = model_class_for("cmm")(truth.model, data, cut=cut, tool_radius_mm=r)
    np.testing.assert_array_equal(mm.line, np.full(y.size, 5))           # the G1 Y30 block
    # nuisance: the tool's radius error (dn -= dr), then the CMM frame's translation and rotation
    # (about the points' centroid): dn += n . (t + w x (x - c))
    assert [s.name.split(":", 1)[1] for s in mm.nuisance_specs] == [
        "radius_offset", "setup:tx", "setup:ty", "setup:tz", "setup:rx", "setup:ry", "setup:rz"]
    p0 = mm.predict(truth.params.values, np.zeros(7))
    nu = np.array([2e-3, 0, 0, 0, 0, 0, 0])
    np.testing.assert_allclose(mm.predict(truth.params.values, nu) - p0, -2e-3, rtol=0, atol=1e-15)
    nu = np.array([0, 1e-3, 0, 0, 0, 0, 1e-5])           # tx 1 um, rz 10 urad
    arm_y = pts[:, 1] - pts[:, 1].mean()
    np.testing.assert_allclose(mm.predict(truth.params.values, nu) - p0, -1e-3 + 1e-5 * arm_y,
                               rtol=0, atol=1e-15)
    J, Jn = mm.jacobian(truth.params.values, nu)
    np.testing.assert_allclose(J, fd_jacobian(mm, truth.params.values, nu), rtol=0, atol=1e-7)


def test_cmm_point_the_program_did_not_cut_is_refused(tmp_path):
    m = load_machine("xfyz").with_basis("polynomial")
    prog = tmp_path / "wall.nc"
    prog.write_text(WALL)
    plan = cmm_plan([[303.0, 0.0, -7.0], [303.0, 80.0, -7.0]], [[-1.0, 0, 0], [-1.0, 0, 0]],
                    read_cut_program(prog, m), 3.0)
    vm = VirtualMachine(m, random_truth(m, np.random.default_rng(0)))
    with pytest.raises(InputError, match=r"row 2.*did not cut|did not cut"):
        vm.measure(plan)


def test_cmm_on_the_seed001_bowl_finds_the_cutter_locations(tmp_path):
    from mtcomp.toolpaths.parts import write_bowl_program
    m = load_machine("xfyz").with_basis("polynomial")
    bowl = write_bowl_program(tmp_path / "bowl.nc", stepover_mm=1.0, step_mm=1.0)
    pick = np.random.default_rng(5).choice(len(bowl.contact_points), 100, replace=False)
    truth = random_truth(m, np.random.default_rng(6))
    plan = cmm_plan(bowl.contact_points[pick], bowl.normals[pick], read_cut_program(bowl.path, m),
                    bowl.ball_radius)
    data = VirtualMachine(m, truth, noise_um=0.0).measure(plan, tmp_path / "cmm.csv")
    mm = model_class_for("cmm")(truth.model, data, **plan.options)
    # each point was cut where the program put the ball centre on it: the programmed tip (the
    # program holds 4 decimals, so the exact centre lies up to 5e-5 mm off the programmed path)
    np.testing.assert_allclose(mm.q, bowl.tool_tips[pick], rtol=0, atol=1e-4)
    tips = mm.q
    c = truth.model.default_context(100)
    c[:, truth.model.context_names.index("feed")] = 1200.0
    for a in m.axis_names:                 # approach directions: checked in the wall test above
        k = truth.model.context_names.index(f"dir_{a}")
        c[:, k] = mm.c[:, k]
    dev = deviation(truth.model, tips, truth.params.values, c)
    n = bowl.normals[pick]
    oracle = np.einsum("ij,ij->i", n, dev[:, :3] + bowl.ball_radius * dev[:, 3:]) * 1e3
    np.testing.assert_allclose(data.normal_deviation * 1e3, oracle, rtol=1e-7, atol=1e-6)

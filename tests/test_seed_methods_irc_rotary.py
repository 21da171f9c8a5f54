"""Seed 000 eq. 1 (IRC from two-point velocities) and seed 002 (rotary positioning and backlash)
against hand-derived rigid motions and known truth from the virtual machine."""
import math

import numpy as np

from mtcomp import load_machine
from mtcomp.identification import seed_methods as sm
from mtcomp.measurement.readings import model_class_for
from mtcomp.models import AbbeIRC, Backlash, ErrorModel, FittedModel, ParameterSet
from mtcomp.sim import VirtualMachine, rotary_laser_plan, velocity_plan


def test_eq1_on_a_hand_built_rigid_motion():
    # v(P) = V0 e_x + w e_z x (P - O): the velocities of M and N of a table turning about O
    rng = np.random.default_rng(0)
    O = rng.uniform(-300, 300, size=(20, 2))
    w = rng.uniform(1e-4, 1e-3, 20) * rng.choice([-1, 1], 20)
    V0 = rng.uniform(100, 400, 20)
    M = np.array([50.0, 150.0]) + rng.normal(size=(20, 2))
    N = np.array([250.0, 100.0]) + rng.normal(size=(20, 2))

    def vel(P):
        r = P - O
        return np.column_stack([V0 - w * r[:, 1], w * r[:, 0]])

    got = sm.irc_from_velocities(M, vel(M), N, vel(N), V0)
    np.testing.assert_allclose(got, O, rtol=0, atol=1e-8)
    # no yaw rate: no centre
    assert np.isnan(sm.irc_from_velocities(M[:1], [[V0[0], 0.0]], N[:1], [[V0[0], 0.0]], V0[:1])).all()


def test_eq3_abbe_error_is_the_small_rotation_about_the_centre():
    eps, B, O = 40e-6, np.array([[120.0, -30.0]]), np.array([[10.0, 80.0]])
    c, s = math.cos(eps), math.sin(eps)
    exact = (np.array([[c, -s], [s, c]]) @ (B - O)[0]) + O[0] - B[0]
    # first order is ~6 um here; the exact rotation differs by eps^2 |B - O| / 2 ~ 0.1 nm
    np.testing.assert_allclose(sm.abbe_error_about_irc([eps], B, O)[0], exact, rtol=0, atol=1e-6)


def irc_truth():
    m = load_machine("xfyz").with_basis("polynomial")
    model = ErrorModel(m, [AbbeIRC("X", angles="C", static=True, position=True, feed=True)])
    p = ParameterSet(model.param_specs)
    p["ECX_1"], p["ECX_2"] = 2000e-6, -1500e-6          # a large yaw so the CSV digits do not matter
    p["IRC_CX_x0"], p["IRC_CX_y0"] = 120.0, -60.0
    p["IRC_CX_x_s"], p["IRC_CX_y_f"] = 80.0, 150.0         # mm per m of travel, per m/min of feed
    return m, FittedModel(model, p)


def test_irc_from_simulated_velocities_matches_the_model_centre():
    m, truth = irc_truth()
    data = VirtualMachine(m, truth, noise_velocity_mm_min=0.0).measure(velocity_plan(m))
    assert len(data) == 41 * 3 * 3                       # 200 mm / 5 mm, 3 repeats, 3 feeds
    centre = model_class_for("velocity")(truth.model, data).rotation_centre(truth.params.values)
    got = sm.irc_from_velocities(data.m_xy, data.m_v, data.n_xy, data.n_v, data.feed)
    np.testing.assert_allclose(got, centre, rtol=0, atol=2e-3)
    # second formulation: the reader's perpendicular-lines solve
    np.testing.assert_allclose(got, data.rotation_centre(), rtol=0, atol=1e-6)
    # by hand: the table turns by E(s) about O(s) = (120 + 80 s/m, -60 + 150 f/(m/min)), so a point's
    # velocity is V d/ds[E e_z x (P - O)] = V E' e_z x (P - O - (E / E') O'): the instantaneous
    # centre is O + (E / E') O' (O' = (0.08, 0)); it moves with feed as the truth says, 150 mm per
    # m/min in y
    s = data.position / 1000.0
    E, dE = 2000e-6 * s - 1500e-6 * s ** 2, (2000e-6 - 3000e-6 * s) / 1000.0
    x0 = centre[:, 0] - 120.0 - 80.0 * s - E / dE * 0.08
    np.testing.assert_allclose(x0, 0.0, rtol=0, atol=1e-9)
    np.testing.assert_allclose(got[:, 1] + 60.0, 150.0 * data.feed / 1000.0, rtol=0, atol=2e-3)


def test_rotary_positioning_backlash_and_compensation():
    m = load_machine("cafxyz")
    model = ErrorModel(m, [Backlash("C")])
    p = ParameterSet(model.param_specs)
    p["ECC_0"], p["ECC_c1"], p["ECC_s2"], p["BL_C"] = 5e-6, 12e-6, -7e-6, 20e-6
    truth = FittedModel(model, p)
    plan = rotary_laser_plan(m)
    data = VirtualMachine(m, truth, noise_urad=0.0).measure(plan)
    res = sm.rotary_positioning(data, "C")
    th = res.targets
    ecc = 5e-6 + 12e-6 * np.cos(th) - 7e-6 * np.sin(2 * th)
    np.testing.assert_allclose(np.degrees(th), np.arange(0, 360, 30), rtol=0, atol=1e-9)
    np.testing.assert_allclose(res.mean, ecc, rtol=0, atol=1e-12)
    np.testing.assert_allclose(res.backlash, 20e-6, rtol=0, atol=1e-12)
    np.testing.assert_allclose(res.mean_up - res.mean_down, res.backlash, rtol=0, atol=1e-15)
    np.testing.assert_allclose([res.residual_up, res.residual_down], 0.0, rtol=0, atol=1e-12)
    # with noise: the residual after compensation is the noise of a 5-run mean
    noisy = VirtualMachine(m, truth, noise_urad=1.0, rng=np.random.default_rng(2)).measure(plan)
    r = sm.rotary_positioning(noisy, "C")
    before = np.abs(np.concatenate([r.mean_up, r.mean_down])).max()
    after = np.abs(np.concatenate([r.residual_up, r.residual_down])).max()
    assert before > 15e-6 and after < 2.5e-6
    assert "backlash compensation" in r.table()


def test_seed_method_starts_the_joint_fit_of_velocity_files():
    # eq. 1 gives O per reading, then the yaw rate; both regressed on feed and position give start
    # values from which identify() fits the AbbeIRC term (at zero the yaw hides the centre)
    from mtcomp.identification.fit import identify
    m = load_machine("xfyz").with_basis("polynomial")
    model = ErrorModel(m, [AbbeIRC("X", angles="C", static=True, feed=True)])
    p = ParameterSet(model.param_specs)
    truth_values = {"ECX_1": 20e-6, "ECX_2": -15e-6, "ECX_3": 10e-6, "IRC_CX_x0": 120.0,
                    "IRC_CX_y0": -60.0, "IRC_CX_x_f": -40.0, "IRC_CX_y_f": 150.0}
    for k, v in truth_values.items():
        p[k] = v
    vm = VirtualMachine(m, FittedModel(model, p), noise_velocity_mm_min=1e-5, rng=np.random.default_rng(4))
    data = vm.measure(velocity_plan(m))
    O = sm.irc_from_velocities(data.m_xy, data.m_v, data.n_xy, data.n_v, data.feed)
    A = np.column_stack([np.ones(len(data)), data.feed / 1000.0])
    (x0, xf), (y0, yf) = (np.linalg.lstsq(A, O[:, k], rcond=None)[0] for k in range(2))
    slope = sm.yaw_rate_from_velocities(data.n_xy, data.n_v, O, data.feed) / data.feed   # rad/mm
    s_m = data.position / 1000.0
    B = np.column_stack([np.ones_like(s_m), 2 * s_m, 3 * s_m ** 2]) / 1000.0
    e1, e2, e3 = np.linalg.lstsq(B, slope, rcond=None)[0]
    start = ParameterSet(model.param_specs)
    for k, v in zip(truth_values, (e1, e2, e3, x0, y0, xf, yf)):
        start[k] = v
    np.testing.assert_allclose(start["IRC_CX_y_f"], 150.0, rtol=0.2, atol=0)
    res = identify(model, [data], free=list(truth_values), initial=start.values)
    assert res.converged and not res.undetermined
    for k, v in truth_values.items():
        value, se = res.value(k)
        assert abs(value / p.specs[p.index(k)].to_file - v) < 4 * se / p.specs[p.index(k)].to_file, k

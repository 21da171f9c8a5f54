"""Inverse kinematics against mtcomp.kinematics.forward (the oracle), and hand-derived poses."""
import math

import numpy as np
import pytest

from mtcomp import InputError, load_machine
from mtcomp.kinematics import forward
from mtcomp.machine import machine_from_dict
from mtcomp.toolpaths.inverse import fit_rotary_travel, inverse_kinematics


def _random_q(machine, rng, n, tilt_scale=1.0):
    lo, hi = machine.travel_bounds()
    q = rng.uniform(lo, hi, size=(n, machine.n_axes))
    tilt = machine.index(machine.workpiece_chain[0]) if machine.is_five_axis else None
    if tilt is not None:
        q[:, tilt] *= tilt_scale
    return q


@pytest.mark.parametrize("name", ["cafxyz", "cbfxyz", "xfyz"])
def test_ik_reproduces_forward(name):
    m = load_machine(name)
    rng = np.random.default_rng(7)
    q = _random_q(m, rng, 120)
    if m.is_five_axis:
        tilt = m.index(m.workpiece_chain[0])
        # tilt exactly 0 (C free), near-singular tilts, and large ones
        q[:10, tilt] = 0.0
        q[10:20, tilt] = rng.choice([-1, 1], 10) * 10.0 ** rng.uniform(-9, -5, 10)
    tip, k = forward(m, q)
    branch = np.sign(q[:, m.index(m.workpiece_chain[0])]) if m.is_five_axis else np.ones(len(q))
    for i in range(len(q)):    # pose by pose: branch and previous vary
        qi = inverse_kinematics(m, tip[i], k[i], branch=int(branch[i] or 1), previous=q[i])
        t2, k2 = forward(m, qi)
        np.testing.assert_allclose(t2[0], tip[i], rtol=0, atol=1e-9)
        np.testing.assert_allclose(k2[0], k[i], rtol=0, atol=1e-12)
        # starting from the true pose as "previous", the same pose comes back (also at tilt 0,
        # where C is free and keeps its previous value)
        np.testing.assert_allclose(qi[0], q[i], rtol=0, atol=1e-6 if 10 <= i < 20 else 1e-9)
    # all poses at once, one branch: every pose still reaches its tip and tool axis
    qa = inverse_kinematics(m, tip, k, branch=-1)
    t3, k3 = forward(m, qa)
    np.testing.assert_allclose(t3, tip, rtol=0, atol=1e-9)
    np.testing.assert_allclose(k3, k, rtol=0, atol=1e-12)


def test_hand_derived_branches_cafxyz():
    m = load_machine("cafxyz")
    # A = a, C = 0 tilts the tool axis to (0, sin a, cos a) in the workpiece frame
    k = np.array([[0.0, 0.5, math.sqrt(3) / 2]])
    tip = np.array([[10.0, 20.0, 30.0]])
    qp = inverse_kinematics(m, tip, k, branch=+1)[0]
    qn = inverse_kinematics(m, tip, k, branch=-1)[0]
    assert math.degrees(qp[3]) == pytest.approx(30.0, rel=0, abs=1e-12)
    assert math.degrees(qp[4]) == pytest.approx(0.0, rel=0, abs=1e-12)
    assert math.degrees(qn[3]) == pytest.approx(-30.0, rel=0, abs=1e-12)
    assert abs(math.degrees(qn[4])) == pytest.approx(180.0, rel=0, abs=1e-12)
    # position by hand for A = 30 deg, C = 0: tip_wp = Rx(-a) (tip_bed - p) + p, p = (0, 0, -100)
    a = math.radians(30.0)
    p = np.array([0, 0, -100.0])
    Rx = np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])
    expected_bed = Rx @ (tip[0] - p) + p
    np.testing.assert_allclose(qp[:3], expected_bed, rtol=0, atol=1e-12)


def test_wrap_follows_previous_and_travel():
    m = load_machine("cafxyz")
    # the tool axis turning once around the cone of half-angle 20 deg: C must keep turning
    phi = np.linspace(0, 2 * math.pi, 73)
    k = np.stack([np.sin(0.35) * np.cos(phi), np.sin(0.35) * np.sin(phi), np.full_like(phi, math.cos(0.35))], 1)
    tip = np.zeros_like(k)
    q = inverse_kinematics(m, tip, k, previous=np.zeros(5))
    c = q[:, 4]
    assert np.all(np.abs(np.diff(c)) < math.radians(6))           # no jump of 360 deg
    assert abs(c[-1] - c[0]) == pytest.approx(2 * math.pi, rel=0, abs=1e-9)
    # with C limited to -10..10 deg, the tool axis (sin 20deg, 0, cos 20deg) needing C = -90 deg
    # (A > 0) is out of travel
    d = m.to_dict()
    d["axes"]["C"]["travel_deg"] = [-10.0, 10.0]
    small = machine_from_dict(d)
    with pytest.raises(InputError, match="outside its travel"):
        inverse_kinematics(small, tip[:1], k[:1])


def test_unreachable_and_unsupported():
    m = load_machine("xfyz")
    with pytest.raises(InputError, match="only reaches the tool axis"):
        inverse_kinematics(m, [[0, 0, 0]], [[0, 1.0, 0]])
    d = {"topology": "XYZFA", "axes": {"X": {"travel_mm": [0, 1]}, "Y": {"travel_mm": [0, 1]},
         "Z": {"travel_mm": [0, 1]}, "A": {"travel_deg": [-90, 90], "axis_point_mm": [0, 0, 0]}}}
    with pytest.raises(InputError, match="tool side"):
        inverse_kinematics(machine_from_dict(d), [[0, 0, 0]], [[0, 0, 1.0]])


def test_fit_rotary_travel_removes_jumps():
    m = load_machine("cafxyz")
    c = np.radians(np.array([-350.0, -355.0, -359.0, 2.0, 7.0]))   # 2 deg is really -358 deg
    q = np.zeros((5, 5))
    q[:, 4] = c
    q[:, 3] = np.radians(20.0)
    out = fit_rotary_travel(m, q)
    np.testing.assert_allclose(np.degrees(out[:, 4]), [10.0, 5.0, 1.0, 2.0, 7.0], rtol=0, atol=1e-9)
    np.testing.assert_allclose(out[:, :4], q[:, :4], rtol=0, atol=0)
    turn = np.zeros((41, 5))
    turn[:, 4] = np.radians(np.linspace(0, 800, 41) % 360)      # 800 deg in 20 deg steps
    with pytest.raises(InputError, match="more than its travel"):
        fit_rotary_travel(m, turn)

"""The nominal kinematics is written once (mtcomp.kinematics) and every place that needs it calls it:
the numpy forward kinematics and 4x4 transforms, the planner's pose and Jacobian, the error model's
CasADi nominal chain, the test-part writers. Each is checked against the independent oracles (the
virtual machine of tests/truth and the product of exponentials of tests/oracles), on random poses of
the three topologies and of machines whose rotary axis lines are off the origin; and each is checked
to go through mtcomp.kinematics.axis_motion."""
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

import mtcomp
from mtcomp import kinematics
from mtcomp.machine import load_machine
from mtcomp.models import ErrorModel
from mtcomp.planner import _evaluate, nominal_pose_jacobian
from mtcomp.toolpaths.parts import tool_poses
from oracles.poe import poe_tool_pose
from truth.machine import TruthMachine

TOPOLOGIES = ["xfyz", "cafxyz", "cbfxyz"]


def _shifted_machine_file(tmp_path, name):
    """The built-in machine ``name`` with its rotary axis lines moved off the machine origin."""
    text = (Path(mtcomp.__file__).parent / "machines" / f"{name}.toml").read_text()
    text = text.replace("axis_point_mm = [0.0, 0.0, -100.0]", "axis_point_mm = [12.5, -35.0, -110.0]")
    text = text.replace("axis_point_mm = [0.0, 0.0, 0.0]", "axis_point_mm = [40.0, 25.0, -7.5]")
    path = tmp_path / f"{name}_shifted.toml"
    path.write_text(text)
    return path


@pytest.fixture(params=TOPOLOGIES + ["cafxyz_shifted", "cbfxyz_shifted"])
def machine_pair(request, tmp_path):
    """(mtcomp Machine, TruthMachine of the same file)."""
    name = request.param
    source = _shifted_machine_file(tmp_path, name.split("_")[0]) if name.endswith("shifted") else name
    m = load_machine(str(source))
    if name.endswith("shifted"):
        assert any(a.is_rotary and any(a.axis_point) for a in m.axes)     # the file took
    return m, TruthMachine(str(source))


def _random_q(m, seed, n=40):
    rng = np.random.default_rng(seed)
    lo, hi = m.travel_bounds()
    return rng.uniform(lo, hi, (n, m.n_axes))


def test_forward_and_transforms_match_both_oracles(machine_pair):
    m, truth = machine_pair
    q = _random_q(m, 1)
    tip_t, axis_t = truth.nominal_pose(q)
    tip, axis = kinematics.forward(m, q)
    np.testing.assert_allclose(tip, tip_t, rtol=0, atol=1e-11)
    np.testing.assert_allclose(axis, axis_t, rtol=0, atol=1e-14)
    model = ErrorModel(m)
    tip_p, axis_p = poe_tool_pose(model, np.zeros(model.n_params), q, errors=False)
    np.testing.assert_allclose(tip, tip_p, rtol=0, atol=1e-11)
    np.testing.assert_allclose(axis, axis_p, rtol=0, atol=1e-14)
    T = kinematics.tool2wp(m, q)
    np.testing.assert_array_equal(T[:, :3, 3], tip)
    np.testing.assert_array_equal(T[:, :3, 2], axis)
    # W^-1 T from the 4x4 chains: the same pose
    T2 = kinematics.rigid_inverse(kinematics.wp2bed(m, q)) @ kinematics.tool2bed(m, q)
    np.testing.assert_allclose(T2, T, rtol=0, atol=1e-11)


def test_every_call_site_gives_the_same_pose(machine_pair):
    m, truth = machine_pair
    q = _random_q(m, 2)
    tip, axis = kinematics.forward(m, q)
    tip_t, axis_t = truth.nominal_pose(q)
    # the planner: the same numbers bit for bit, and its Jacobian against finite differences of the
    # independent virtual machine
    tip_j, axis_j, J = nominal_pose_jacobian(m, q)
    np.testing.assert_array_equal(tip_j, tip)
    np.testing.assert_array_equal(axis_j, axis)
    Jf = np.zeros_like(J)
    for j in range(m.n_axes):
        h = np.zeros(m.n_axes)
        h[j] = 1e-5
        plus, minus = truth.nominal_pose(q + h), truth.nominal_pose(q - h)
        Jf[:, :3, j] = (plus[0] - minus[0]) / 2e-5
        Jf[:, 3:, j] = (plus[1] - minus[1]) / 2e-5
    np.testing.assert_allclose(J, Jf, rtol=0, atol=2e-6)
    # the error model's CasADi nominal chain
    model = ErrorModel(m)
    f = model.nominal_function.map(q.shape[0])
    tip_c, axis_c = (np.asarray(v).T for v in f(q.T))
    np.testing.assert_allclose(tip_c, tip_t, rtol=0, atol=1e-11)
    np.testing.assert_allclose(axis_c, axis_t, rtol=0, atol=1e-14)
    np.testing.assert_allclose(tip_c, tip, rtol=0, atol=1e-12)
    # the test-part writers
    tip_w, axis_w = tool_poses(m, q)
    np.testing.assert_array_equal(tip_w, tip)
    np.testing.assert_array_equal(axis_w, axis)


@pytest.mark.parametrize("name", TOPOLOGIES)
def test_symbolic_form_is_the_numpy_form(name):
    """One set of formulas: the CasADi form of mtcomp.kinematics evaluated at a pose gives the numpy
    form's numbers, and the error model's nominal chain is that CasADi form."""
    m = load_machine(name)
    q = _random_q(m, 3, 10)
    qs = ca.SX.sym("q", m.n_axes)
    tip_s, axis_s, R_s = kinematics.symbolic_pose(m, qs)
    model = ErrorModel(m)
    p, c = ca.SX.sym("p", model.n_params), ca.SX.sym("c", model.n_context)
    tip_m, axis_m, R_m = model.symbolic(qs, p, c, errors=False)
    f = ca.Function("both", [qs], [tip_s, axis_s, ca.vec(R_s), tip_m, axis_m, ca.vec(R_m)])
    T = kinematics.tool2wp(m, q)
    for i in range(len(q)):
        out = [np.asarray(v).ravel() for v in f(q[i])]
        np.testing.assert_allclose(out[0], T[i, :3, 3], rtol=0, atol=1e-12)
        np.testing.assert_allclose(out[1], T[i, :3, 2], rtol=0, atol=1e-15)
        np.testing.assert_allclose(out[2], T[i, :3, :3].ravel(order="F"), rtol=0, atol=1e-15)
        for a, b in zip(out[:3], out[3:]):
            np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("name", ["cafxyz", "xfyz"])
def test_every_call_site_goes_through_the_one_axis_motion(name, monkeypatch):
    """Each call site builds its poses from mtcomp.kinematics.axis_motion (a second implementation
    somewhere would not call it)."""
    m = load_machine(name)
    q = _random_q(m, 4, 5)
    calls = []
    original = kinematics.axis_motion

    def counting(machine, axis_name, value, ops=kinematics.NUMPY):
        calls.append(ops)
        return original(machine, axis_name, value, ops)

    monkeypatch.setattr(kinematics, "axis_motion", counting)
    m5 = load_machine("cafxyz")          # rotary axes: the planner's Jacobian takes the chain
    sites = {
        "forward": lambda: kinematics.forward(m5, _random_q(m5, 5, 3)),
        "tool2wp": lambda: kinematics.tool2wp(m, q),
        "planner Jacobian": lambda: nominal_pose_jacobian(m5, _random_q(m5, 5, 3)),
        "planner target": lambda: _evaluate.nominal_pose(m5, _random_q(m5, 5, 3)),
        "part writers": lambda: tool_poses(m5, _random_q(m5, 5, 3)),
        "error model": lambda: ErrorModel(m).symbolic(ca.SX.sym("q", m.n_axes), None, None, errors=False),
    }
    for what, call in sites.items():
        calls.clear()
        call()
        assert calls, f"{what} does not use mtcomp.kinematics.axis_motion"
    assert calls[-1] is kinematics.CASADI

"""A tool of another length than the machine's reference tool, by hand (docs/conventions.md, "Tool
length"): at the same commanded tip, a carriage that does not carry the spindle turns about a point
fixed on it (its Abbe arm does not depend on the tool), and the ram stands at its machine position
q_Z + L - L0, where its errors are read."""
import math

import numpy as np
import pytest

from mtcomp import load_machine
from mtcomp.kinematics import forward
from mtcomp.models import ErrorModel, deviation

L0 = 100.0                   # tool_length_mm of the built-in xfyz
Q = np.array([[40.0, 200.0, -120.0]])
TOOLS = (0.0, L0, 200.0)


def _model():
    m = load_machine("xfyz").with_basis("polynomial")   # values set through the powers (s / 1 m)^k
    assert m.tool_length == L0
    return ErrorModel(m)


def _dev(model, name, value, L):
    p = np.zeros(model.n_params)
    p[model.param_names.index(name)] = value
    c = model.default_context(1)
    c[0, model.context_names.index("tool_length")] = L
    return deviation(model, Q, p, c, backend="casadi")[0, :3]


@pytest.mark.parametrize("L", TOOLS)
def test_pitch_of_y_turns_about_a_point_fixed_on_the_y_carriage(L):
    """EAY turns the Y carriage, with the ram and whatever tool it holds, about the gauge point at
    q = 0 with the reference tool, (0, y, L0): the tip at (x, y, z) moves by Rx(eps) (0, 0, z - L0)
    - (0, 0, z - L0), the same for every tool (the old arm z - L gave 200 mm x eps between tools 0
    and 200 mm)."""
    model = _model()
    a = 30e-6                                    # EAY_1: eps = a * y / 1 m
    eps = a * Q[0, 1] / 1000.0
    arm = Q[0, 2] - L0
    want = [0.0, -math.sin(eps) * arm, (math.cos(eps) - 1.0) * arm]
    np.testing.assert_allclose(_dev(model, "EAY_1", a, L), want, rtol=0, atol=1e-12)


@pytest.mark.parametrize("L", TOOLS)
def test_ram_errors_are_read_at_its_machine_position(L):
    """The ram stands at zr = z + L - L0 for the tip at z: its straightness, its pitch (about the
    gauge point, L above the tip) and the squareness of its travel all act at zr."""
    model = _model()
    zr = Q[0, 2] + L - L0
    b = 8e-3                                     # EXZ_2: b (zr / 1 m)^2 (EXZ_1 is B0Z's slope)
    np.testing.assert_allclose(_dev(model, "EXZ_2", b, L), [b * (zr / 1000.0) ** 2, 0.0, 0.0],
                               rtol=0, atol=1e-12)
    a = 40e-6                                    # EAZ_1: eps = a zr / 1 m about X, tip L below
    eps = a * zr / 1000.0
    np.testing.assert_allclose(_dev(model, "EAZ_1", a, L), [0.0, L * math.sin(eps), L * (1 - math.cos(eps))],
                               rtol=0, atol=1e-12)
    t = 50e-6                                    # B0Z: the ram travels along (sin t, 0, cos t), the
    np.testing.assert_allclose(_dev(model, "B0Z", t, L),   # tool hangs along Z from it
                               [zr * math.sin(t), 0.0, zr * (math.cos(t) - 1.0)], rtol=0, atol=1e-12)


def test_nominal_chain_is_exact_for_every_tool():
    """Zero parameters give the nominal tip bit for bit at any tool length (the ram's transform is
    written in the frame of the tool's own tip: no (z + L - L0) - (L - L0) rounding)."""
    model = _model()
    rng = np.random.default_rng(5)
    lo, hi = model.machine.travel_bounds()
    q = rng.uniform(lo, hi, (20, 3))
    c = model.default_context(20)
    c[:, model.context_names.index("tool_length")] = rng.uniform(0, 300, 20)
    dev = deviation(model, q, np.zeros(model.n_params), c, backend="casadi")
    assert np.all(dev == 0.0)
    tip, _ = forward(model.machine, q)
    got = np.array([np.array(model.pose_function(q[i], np.zeros(model.n_params), c[i])[0]).ravel()
                    for i in range(20)])
    assert np.array_equal(got, tip)


def test_the_ram_s_knots_span_where_it_stood(tmp_path):
    """A campaign's knots go where each axis stood on its guideway: for the ram q_Z + tool_mm - L0
    (a 200 mm stylus at z = 50 read the ram's profiles at 150 mm); so does the region the model
    applies to (data_support), which compensate and export test the ram's position against."""
    from mtcomp.measurement import read_measurements
    from mtcomp.measurement.readings import data_positions, data_support
    f = tmp_path / "p.csv"
    f.write_text("x_mm,y_mm,z_mm,tool_mm,dx_um,dy_um,dz_um\n"
                 "0,0,-100,0,1,1,1\n0,0,50,200,1,1,1\n10,0,0,,1,1,1\n")
    data = read_measurements(f, "points")
    m = load_machine("xfyz")
    np.testing.assert_array_equal(data_positions(m, [data])["Z"], [-200.0, 150.0, 0.0])
    np.testing.assert_array_equal(data_positions(m, [data])["X"], [0.0, 0.0, 10.0])
    assert data_support(m, [data])["Z"] == (-200.0, 150.0)

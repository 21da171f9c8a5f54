"""The CasADi error model against the independent numpy oracle, nominal kinematics and finite
differences."""
import math

import numpy as np
import pytest

from mtcomp import InputError, load_machine
from mtcomp.kinematics import forward
from mtcomp.models import (AbbeIRC, Backlash, ErrorModel, FeedOffset, FittedModel, PeriodicError,
                           RotaryErrorMotion, deviation, deviation_and_jacobians, load_model, save_model)
from reference_model import reference_deviation

MACHINES = ["xfyz", "cafxyz", "cbfxyz"]


def machine_size_params(model, rng, scale=1.0):
    """Random parameters of machine-tool size: ~10 um and ~20 urad per term."""
    unit_scale = {"um": 10e-3, "urad": 20e-6, "mm": 50.0, "1": 0.05}
    return rng.normal(size=model.n_params) * np.array([unit_scale[s.unit] for s in model.param_specs]) * scale


def random_context(model, rng, n):
    c = model.default_context(n)
    idx = {name: i for i, name in enumerate(model.context_names)}
    c[:, idx["feed"]] = rng.uniform(50, 8000, n)
    c[:, idx["tool_length"]] = rng.uniform(30, 250, n)
    for a in model.machine.axis_names:
        c[:, idx[f"dir_{a}"]] = rng.choice([-1.0, 1.0], n)
    return c


def random_poses(machine, rng, n):
    lo, hi = machine.travel_bounds()
    q = rng.uniform(lo, hi, size=(n, machine.n_axes))
    # the rotary angles the issue names explicitly: 0, +-90 and 180 deg
    special = np.radians([0.0, 90.0, -90.0, 180.0])
    for j, ax in enumerate(machine.axes):
        if ax.is_rotary:
            q[: len(special), j] = np.clip(special, lo[j], hi[j])
    return q


def extension_terms(machine):
    terms = [Backlash("X"), PeriodicError("Y", 5.0), FeedOffset("Z", signed=True),
             AbbeIRC("X", static=True, position=True, feed=True, angle_gain=True, angle_feed=True)]
    if machine.is_five_axis:
        terms += [Backlash("C"), RotaryErrorMotion("EXC", 2), RotaryErrorMotion("EBC", 2)]
    return terms


@pytest.mark.parametrize("name", MACHINES)
def test_zero_parameters_give_nominal_kinematics(name):
    m = load_machine(name)
    model = ErrorModel(m)
    rng = np.random.default_rng(3)
    q = random_poses(m, rng, 30)
    tip, axis = forward(m, q)
    for i in range(len(q)):
        t0, a0 = model.pose_function(q[i], np.zeros(model.n_params), model.default_context(1)[0])
        np.testing.assert_allclose(np.array(t0).ravel(), tip[i], rtol=0, atol=1e-10)
        np.testing.assert_allclose(np.array(a0).ravel(), axis[i], rtol=0, atol=1e-14)
    np.testing.assert_array_equal(deviation(model, q, np.zeros(model.n_params)), np.zeros((30, 6)))


@pytest.mark.parametrize("name", MACHINES)
@pytest.mark.parametrize("with_terms", [False, True])
@pytest.mark.parametrize("basis", ["bspline", "polynomial"])
def test_casadi_model_matches_numpy_oracle(name, with_terms, basis):
    m = load_machine(name).with_basis(basis)
    terms = extension_terms(m) if with_terms else []
    model = ErrorModel(m, terms)
    rng = np.random.default_rng(11)
    q = random_poses(m, rng, 25)
    p = machine_size_params(model, rng)
    c = random_context(model, rng, 25)
    dev = deviation(model, q, p, c)
    pd = dict(zip(model.param_names, p))
    ref = np.array([reference_deviation(m, pd, q[i], dict(zip(model.context_names, c[i])), terms)
                    for i in range(len(q))])
    assert np.abs(ref[:, :3]).max() > 1e-3  # errors of machine size actually act
    np.testing.assert_allclose(dev, ref, rtol=0, atol=1e-12 * max(1.0, np.abs(ref).max()) + 1e-13)


def test_hand_case_xfyz_positioning_and_yaw():
    """Polynomial basis: EXX_1 = 10 um/m at x = 200 mm gives dx = 2 um; a yaw ECX_1 of X turns the table about the
    workpiece origin, so the tool at (x, y) sees dy = +eps*x... with the table's inverse motion."""
    m = load_machine("xfyz").with_basis("polynomial")
    model = ErrorModel(m)
    p = np.zeros(model.n_params)
    p[model.param_names.index("EXX_1")] = 10e-3  # 10 um per metre
    d = deviation(model, [[200.0, 50.0, -20.0]], p)[0]
    # rounding: the deviation is a difference of positions of ~200 mm
    np.testing.assert_allclose(d[:3], [2e-3, 0, 0], rtol=0, atol=1e-12)
    # constant-looking yaw: ECX_1 = 100 urad/m -> eps = 20 urad at x = 200 mm. The tool relative to
    # the table: rotation eps about Z at the table origin applied to the relative motion: the tool
    # point (x, y, z) moves by eps x (-y, x, 0) to first order.
    p[:] = 0
    p[model.param_names.index("ECX_1")] = 100e-6
    q = np.array([[200.0, 50.0, -20.0]])
    d = deviation(model, q, p)[0]
    eps = 100e-6 * 0.2
    # exact: table transform inverse of Trans(x e_x) Rz(eps); tool at T_rel = Trans(x) Rz(eps) (y, z)
    Rz = np.array([[math.cos(eps), -math.sin(eps), 0], [math.sin(eps), math.cos(eps), 0], [0, 0, 1]])
    tip = np.array([200.0, 0, 0]) + Rz @ np.array([0, 50.0, -20.0])
    np.testing.assert_allclose(d[:3], tip - q[0], rtol=0, atol=1e-13)
    # first order: (-eps y, 0); the second-order term 50 (cos eps - 1) = -1e-8 mm
    np.testing.assert_allclose(d[:2], [-eps * 50.0, 0.0], rtol=0, atol=2e-8)


@pytest.mark.parametrize("name", MACHINES)
def test_jacobians_match_finite_differences(name):
    m = load_machine(name)
    model = ErrorModel(m, extension_terms(m))
    rng = np.random.default_rng(5)
    q = random_poses(m, rng, 6)
    p = machine_size_params(model, rng)
    c = random_context(model, rng, 6)
    dev, Jq, Jp = deviation_and_jacobians(model, q, p, c)
    for j in range(m.n_axes):
        h = 1e-3 if not m.axes[j].is_rotary else 1e-4
        qp, qm = q.copy(), q.copy()
        qp[:, j] += h
        qm[:, j] -= h
        fd = (deviation(model, qp, p, c) - deviation(model, qm, p, c)) / (2 * h)
        # central differences: truncation O(h^2 * d3dev) and rounding O(1e-16 * |tip| / h)
        np.testing.assert_allclose(Jq[:, :, j], fd, rtol=1e-5, atol=2e-10)
    # steps per unit: large enough that rounding in (tip - nominal tip), ~1e-13 mm, stays far below
    # the derivative (the model is close to linear in its parameters, so truncation stays small)
    step = {"um": 1e-3, "urad": 1e-4, "mm": 1.0, "1": 1e-2}
    for k in rng.choice(model.n_params, size=20, replace=False):
        h = step[model.param_specs[k].unit]
        pp, pm = p.copy(), p.copy()
        pp[k] += h
        pm[k] -= h
        fd = (deviation(model, q, pp, c) - deviation(model, q, pm, c)) / (2 * h)
        # atol: the rounding floor of the difference quotient, ~1e-13 mm / h
        np.testing.assert_allclose(Jp[:, :, k], fd, rtol=1e-6, atol=1e-12 / h)


def test_model_file_round_trip(tmp_path):
    m = load_machine("cafxyz")
    model = ErrorModel(m, [Backlash("X"), PeriodicError("Y", 4.0)])
    fitted = FittedModel.zero(model)
    fitted.params.values[:] = machine_size_params(model, np.random.default_rng(2))
    save_model(tmp_path / "m.json", fitted)
    back = load_model(tmp_path / "m.json", m)
    assert back.model.param_names == model.param_names
    assert [t.to_dict() for t in back.model.terms] == [t.to_dict() for t in model.terms]
    np.testing.assert_allclose(back.params.values, fitted.params.values, rtol=1e-15, atol=0)


def test_model_file_errors(tmp_path):
    p = tmp_path / "bad.json"
    p.write_text("{not json")
    with pytest.raises(InputError, match="not valid JSON"):
        load_model(p)
    fitted = FittedModel.zero(ErrorModel(load_machine("xfyz")))
    save_model(tmp_path / "x.json", fitted)
    with pytest.raises(InputError, match="made for a XFYZ machine"):
        load_model(tmp_path / "x.json", load_machine("cafxyz"))
    # an older mtcomp's error motion with a first harmonic of a radial motion: named, and why
    import json
    path = tmp_path / "old.json"
    save_model(path, FittedModel.zero(ErrorModel(load_machine("cafxyz"), [RotaryErrorMotion("EXC", 2)])))
    data = json.loads(path.read_text())
    data["parameters"]["EXC_c1"] = {"value": 1.0, "unit": "um"}
    path.write_text(json.dumps(data))
    with pytest.raises(InputError, match=r"'EXC_c1' is not part of this model \(a first harmonic of a radial"):
        load_model(path)


def test_hand_case_spline_component_and_spindle_tilt():
    """One interior cubic B-spline coefficient: at its central knot B_j = 4/6 and its mean over the
    range is h / L = 1 / n, so EXX = c (4/6 - 1/6). A spindle tilt A0S turns the tool about the gauge
    point: with tool length L the tip moves by +L A0S along Y (first order)."""
    m = load_machine("xfyz").with_basis("bspline", spline_range=(-300.0, 300.0), spline_intervals=6,
                                        degree=3)
    model = ErrorModel(m)
    p = np.zeros(model.n_params)
    # basis j = 3 spans intervals 0..3 (knots -300 .. -100 .. 100 mm), its centre knot is x = -100 mm
    p[model.param_names.index("EXX_b3")] = 6e-3            # 6 um
    d = deviation(model, [[-100.0, 0.0, 0.0]], p)[0]
    np.testing.assert_allclose(d[0], 6e-3 * (4 / 6 - 1 / 6), rtol=0, atol=1e-12)
    # outside the range the error stays at its end value (B_3 is 0 at x = 300, mean 1/6 removed)
    d_out = deviation(model, [[350.0, 0.0, 0.0]], p)[0]
    np.testing.assert_allclose(d_out[0], 6e-3 * (0.0 - 1 / 6), rtol=0, atol=1e-12)
    p[:] = 0.0
    p[model.param_names.index("A0S")] = 20e-6
    c = model.default_context(2)
    c[:, model.context_names.index("tool_length")] = [100.0, 200.0]
    d = deviation(model, [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]], p, c)
    # Rx(a) turns the tip at (0, 0, -L) below the gauge point to (0, +L sin a, -L cos a)
    np.testing.assert_allclose(d[:, 1], [100.0 * np.sin(20e-6), 200.0 * np.sin(20e-6)], rtol=1e-12, atol=0)
    np.testing.assert_allclose(d[:, 4], [-np.sin(20e-6)] * 2, rtol=1e-9, atol=0)


def test_radial_and_tilt_error_motions_start_at_the_second_harmonic():
    """A rotary axis's error motions in the frame that does not turn with it: an offset v of the line
    moves a carried point by v - R(theta) v, an artefact off centre by w by R(theta) w, so the
    constant and the first harmonic of the radial pair (and, likewise, of the tilt pair) are the
    location and the set-up; only the axial motion keeps harmonic 1 (ISO 230-7). Written out by hand
    for C (about Z: axial EZC) and A (about X: axial EXA), in the base model and in the term."""
    import dataclasses
    m = load_machine("cafxyz")
    m = dataclasses.replace(m, axes=tuple(dataclasses.replace(a, error_motion_order=3)
                                          if a.is_rotary else a for a in m.axes))
    names = ErrorModel(m).param_names
    got = {c: [n.split("_")[1] for n in names if n.startswith(c + "_")]
           for c in ("EXC", "EYC", "EZC", "EAC", "EBC", "EXA", "EYA", "EZA", "EBA", "ECA")}
    two, one = ["c2", "s2", "c3", "s3"], ["c1", "s1", "c2", "s2", "c3", "s3"]
    assert got == {"EXC": two, "EYC": two, "EZC": one, "EAC": two, "EBC": two,
                   "EXA": one, "EYA": two, "EZA": two, "EBA": two, "ECA": two}
    term = RotaryErrorMotion("EYC", order=1)
    assert term.param_specs(load_machine("cafxyz")) == []
    assert [s.name for s in RotaryErrorMotion("EZC", order=1).param_specs(m)] == ["EZC_c1", "EZC_s1"]

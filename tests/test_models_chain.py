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
    save_model(path, FittedModel.zero(ErrorModel(load_machine("cafxyz"), [RotaryErrorMotion("EYC", 2)])))
    data = json.loads(path.read_text())
    data["parameters"]["EYC_c1"] = {"value": 1.0, "unit": "um"}
    path.write_text(json.dumps(data))
    with pytest.raises(InputError, match=r"'EYC_c1' is not part of this model \(a first harmonic of EYC "
                                         r"alone.*EXC_c1 and EXC_s1"):
        load_model(path)
    # the leader's first harmonic meant EXC alone in a version-1 file, both EXC and EYC now: refused
    save_model(path, FittedModel.zero(ErrorModel(load_machine("cafxyz"), [RotaryErrorMotion("EXC", 2)])))
    data = json.loads(path.read_text())
    assert data["version"] == 2
    load_model(path)
    data["version"] = 1
    path.write_text(json.dumps(data))
    with pytest.raises(InputError, match=r"'EXC_c1' of a version-1 model file.*moves EYC too"):
        load_model(path)
    del data["parameters"]["EXC_c1"], data["parameters"]["EXC_s1"]
    data["terms"] = []
    for name in [n for n in data["parameters"] if n.startswith("EXC_")]:
        del data["parameters"][name]
    path.write_text(json.dumps(data))
    load_model(path)            # a version-1 file without such a harmonic: read as before


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


def test_radial_and_tilt_pairs_keep_only_the_counter_rotating_first_harmonic():
    """A rotary axis's error motions in the frame that does not turn with it: an offset v of the line
    moves a carried point by v - R(theta) v, an artefact off centre by w by R(theta) w, so of the
    first harmonic of the radial pair (and of the tilt pair) the part turning with the axis is the
    location and the set-up, and only the counter-rotating part is a parameter, on the pair's first
    direction; the axial motion keeps harmonic 1. Names written out by hand for C and A (base, term);
    the motion by hand for C and B (B turns Z towards X: its counter-rotating vector e (cos, 0, sin))."""
    import dataclasses

    import casadi as ca

    from mtcomp.models.terms import motion_errors
    m = load_machine("cafxyz")
    m = dataclasses.replace(m, axes=tuple(dataclasses.replace(a, error_motion_order=3)
                                          if a.is_rotary else a for a in m.axes))
    names = ErrorModel(m).param_names
    got = {c: [n.split("_")[1] for n in names if n.startswith(c + "_")]
           for c in ("EXC", "EYC", "EZC", "EAC", "EBC", "EXA", "EYA", "EZA", "EBA", "ECA")}
    two, one = ["c2", "s2", "c3", "s3"], ["c1", "s1", "c2", "s2", "c3", "s3"]
    assert got == {"EXC": one, "EYC": two, "EZC": one, "EAC": one, "EBC": two,
                   "EXA": one, "EYA": one, "EZA": two, "EBA": one, "ECA": two}
    assert RotaryErrorMotion("EYC", order=1).param_specs(m) == []
    assert [s.name for s in RotaryErrorMotion("EZC", order=1).param_specs(m)] == ["EZC_c1", "EZC_s1"]
    assert [s.name for s in RotaryErrorMotion("EXC", order=1).param_specs(m)] == ["EXC_c1", "EXC_s1"]
    th = 0.7
    for comp, partner, want in [("EXC", "EYC", (np.cos(th), -np.sin(th))),     # R_z(-th) (1, 0)
                                ("EAC", "EBC", (np.cos(th), -np.sin(th))),
                                ("EXB", "EZB", (np.cos(th), np.sin(th)))]:     # R_y(-th) (1, 0, 0)
        got = motion_errors(comp, 2, th, lambda n: {f"{comp}_c1": 1.0}.get(n, 0.0))
        assert set(got) == {comp, partner}
        np.testing.assert_allclose([float(ca.evalf(got[comp])), float(ca.evalf(got[partner]))], want,
                                   rtol=0, atol=1e-15)
        # the sine coefficient: the same vector a quarter turn on, (0, 1) at th = 0 for C
        got = motion_errors(comp, 1, 0.0, lambda n: {f"{comp}_s1": 1.0}.get(n, 0.0))
        np.testing.assert_allclose([float(ca.evalf(got[comp])), float(ca.evalf(got[partner]))],
                                   [0.0, 1.0 if comp[2] != "B" else -1.0], rtol=0, atol=1e-15)

def test_first_harmonic_turning_with_the_axis_is_location_and_set_up():
    """Rank check on the model's own Jacobian (60 random poses of a CBFXYZ machine, error motions of
    order 1, a workpiece set-up's translation and rotation among the columns): for each radial and
    tilt pair of B and C, the first harmonic turning with the axis (written with two free harmonics
    of each direction, a term of this test) lies in the span of the rest; the counter-rotating one
    the model keeps (its leader's _c1, _s1) adds rank 2, and equals the free harmonics' combination."""
    import dataclasses

    import casadi as ca

    from mtcomp.models.params import ParamSpec
    from mtcomp.models.terms import Term, motion_pair

    @dataclasses.dataclass(frozen=True)
    class Free1(Term):
        component: str
        kind = "free1"

        def key(self):
            return f"free1:{self.component}"

        def param_specs(self, machine):
            return [ParamSpec(f"F_{self.component}_{cs}1", "um", self.key(), False, "") for cs in "cs"]

        def axis_errors(self, machine, axis, s, ctx, P, components):
            if axis.name != self.component[2]:
                return {}
            return {self.component: P[f"F_{self.component}_c1"] * ca.cos(s) + P[f"F_{self.component}_s1"] * ca.sin(s)}

    m = load_machine("cbfxyz")
    m = dataclasses.replace(m, axes=tuple(dataclasses.replace(a, error_motion_order=1) if a.is_rotary else a
                                          for a in m.axes))
    pairs = [(c, *motion_pair(c)) for a in "BC" for c in (f"EX{a}", f"EY{a}", f"EA{a}", f"EB{a}")
             if motion_pair(c)]
    assert [(a, b, s) for a, b, s in pairs] == [("EXB", "EZB", -1), ("EAB", "ECB", -1),
                                                ("EXC", "EYC", 1), ("EAC", "EBC", 1)]
    model = ErrorModel(m, [Free1(x) for a, b, _ in pairs for x in (a, b)])
    ix = {n: i for i, n in enumerate(model.param_names)}
    rng = np.random.default_rng(0)
    lo, hi = (np.array([a.travel[k] for a in m.axes]) for k in (0, 1))
    f = model.deviation_jacobian_function
    c = model.default_context(1).ravel()
    J = np.vstack([np.array(f(q, np.zeros(model.n_params), c)[2]) for q in lo + (hi - lo) * rng.random((60, 5))])
    J = np.hstack([J, np.kron(np.ones((60, 1)), np.eye(6))])          # the set-up
    first = {ix[f"{a}_{cs}1"] for a, _, _ in pairs for cs in "cs"}
    rest = J[:, [i for i in range(model.n_params) if i not in first and not model.param_names[i].startswith("F_")]
             + list(range(model.n_params, J.shape[1]))]
    rest = rest / np.maximum(np.linalg.norm(rest, axis=0), 1e-300)
    U, sv, _ = np.linalg.svd(rest, full_matrices=False)
    U = U[:, sv > sv[0] * 1e-9]
    unexplained = lambda v: np.linalg.norm(v - U @ (U.T @ v)) / np.linalg.norm(v)  # noqa: E731
    for a, b, sg in pairs:
        c1a, s1a, c1b, s1b = (J[:, ix[f"F_{x}_{cs}1"]] for x, cs in ((a, "c"), (a, "s"), (b, "c"), (b, "s")))
        for v in (c1a + sg * s1b, s1a - sg * c1b):                  # R(theta) u: turns with the axis
            assert unexplained(v) < 1e-6, (a, unexplained(v))
        kept = (J[:, ix[f"{a}_c1"]], J[:, ix[f"{a}_s1"]])
        np.testing.assert_allclose(np.column_stack(kept), np.column_stack([c1a - sg * s1b, s1a + sg * c1b]),
                                   rtol=0, atol=1e-12)
        assert min(unexplained(v) for v in kept) > 0.03, a          # B: 7 %, C: 85 %
        both = np.column_stack([rest, *(v / np.linalg.norm(v) for v in kept)])
        assert np.linalg.matrix_rank(both, tol=sv[0] * 1e-9) == U.shape[1] + 2, a

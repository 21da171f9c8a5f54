"""Measurement models (points, laser, ballbar): predictions against the numpy reference chain and
hand-derived cases, CasADi Jacobians against finite differences, observation bookkeeping, context."""
from __future__ import annotations

import numpy as np
import pytest

from mtcomp.errors import InputError
from mtcomp.measurement import readings as mmod
from mtcomp.measurement.readings import context_matrix, measurement_model
from mtcomp.machine import load_machine
from mtcomp.models import ErrorModel, ThermalDrift
from mtcomp.sim import make_ballbar, make_laser, make_points, random_parameters, simulate
from reference_model import reference_deviation


def _params_dict(model, p):
    return dict(zip(model.param_names, p))


def test_points_prediction_matches_numpy_reference(cafxyz):
    machine, model = cafxyz
    rng = np.random.default_rng(1)
    p = random_parameters(model, rng)
    n = 12
    lo, hi = machine.travel_bounds()
    q = rng.uniform(np.maximum(lo, -3), np.minimum(hi, 3), size=(n, 5))
    tool = rng.choice([0.0, 80.0, 150.0], n)
    normal = rng.normal(size=(n, 3))
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    data = make_points(q[:, :3], np.column_stack([q[:, 3], np.zeros(n), q[:, 4]]), tool=tool,
                       normal=normal)
    cols = measurement_model(model, data).predict_columns(p)
    P = _params_dict(model, p)
    for i in range(n):
        ref = reference_deviation(machine, P, q[i], {"tool_length": tool[i]})[:3] * 1e3
        got = [cols["pred_dx_um"][i], cols["pred_dy_um"][i], cols["pred_dz_um"][i]]
        np.testing.assert_allclose(got, ref, rtol=1e-10, atol=1e-10)
        np.testing.assert_allclose(cols["pred_dn_um"][i], normal[i] @ ref, rtol=1e-10, atol=1e-10)


def test_laser_translational_with_optic_offset_matches_reference(xfyz):
    # on a 3-axis machine R0 = I, so a point o = (0, 0, h) on the tool axis moves by the tip deviation
    # plus h times the tool-axis deviation (both from the numpy reference)
    machine, model = xfyz
    rng = np.random.default_rng(2)
    p = random_parameters(model, rng)
    P = _params_dict(model, p)
    n = 9
    axis = rng.choice(list("XYZ"), n)
    comp = np.array([f"E{rng.choice(list('XYZ'))}{a}" for a in axis])
    target = rng.uniform(-200, 100, n)
    static = np.zeros((n, 6))
    static[:, :3] = rng.uniform(-200, 100, (n, 3))
    h = rng.uniform(-80, 80, n)
    optic = np.column_stack([np.zeros(n), np.zeros(n), h])
    data = make_laser(axis, comp, target, static=static, optic=optic)
    pred = measurement_model(model, data).predict(p, None)
    for i in range(n):
        q = static[i, :3].copy()
        q["XYZ".index(axis[i])] = target[i]
        ref = reference_deviation(machine, P, q, {"tool_length": machine.tool_length})
        point = ref[:3] + h[i] * ref[3:]
        np.testing.assert_allclose(pred[i], point["XYZ".index(comp[i][1])], rtol=1e-10, atol=1e-13)


def test_laser_angular_hand_cases(cafxyz):
    # only EAX_1 = a: the X roll reading at target s is a * (s / 1 m); ECY_2 = b: b * (s / 1 m)^2
    machine = load_machine("xfyz").with_basis("polynomial")
    model = ErrorModel(machine)
    p = np.zeros(model.n_params)
    p[model.param_names.index("EAX_1")] = 30e-6
    p[model.param_names.index("ECY_2")] = -25e-6
    s = np.array([-300.0, -100.0, 50.0, 350.0])
    static = np.tile([10.0, -20.0, 40.0, 0, 0, 0], (4, 1))
    data = make_laser(["X"] * 4 + ["Y"] * 4, ["EAX"] * 4 + ["ECY"] * 4, np.r_[s, s * 0.5],
                      static=np.vstack([static, static]), optic=np.tile([50.0, 30.0, -20.0], (8, 1)))
    pred = measurement_model(model, data).predict(p, None)
    expected = np.r_[30e-6 * s / 1000, -25e-6 * (s * 0.5 / 1000) ** 2]
    np.testing.assert_allclose(pred, expected, rtol=1e-9, atol=1e-15)
    # rotary C on the table: ECC reading is actual minus commanded angle = ECC_0 + ECC_c1 cos(theta)
    machine, model = cafxyz
    p = np.zeros(model.n_params)
    p[model.param_names.index("ECC_0")] = 12e-6
    p[model.param_names.index("ECC_c1")] = -7e-6
    theta = np.radians([0.0, 45.0, 170.0, -90.0])
    data = make_laser(["C"] * 4, ["ECC"] * 4, theta)
    pred = measurement_model(model, data).predict(p, None)
    np.testing.assert_allclose(pred, 12e-6 - 7e-6 * np.cos(theta), rtol=1e-9, atol=1e-15)


def test_ballbar_length_matches_reference(xfyz):
    machine, model = xfyz
    rng = np.random.default_rng(3)
    p = random_parameters(model, rng)
    P = _params_dict(model, p)
    n = 8
    xyz = rng.uniform(-200, 100, (n, 3))
    table = np.array([10.0, 20.0, -30.0])
    bz = 25.0  # tool ball 25 mm above the tip, on the tool axis
    data = make_ballbar(xyz, table, [0.0, 0.0, bz])
    pred = measurement_model(model, data).predict(p, np.array([2e-3]))
    for i in range(n):
        dev = reference_deviation(machine, P, xyz[i], {"tool_length": machine.tool_length})
        ball = xyz[i] + [0, 0, bz] + dev[:3] + bz * dev[3:]
        np.testing.assert_allclose(pred[i], np.linalg.norm(ball - table) + 2e-3, rtol=1e-13, atol=1e-12)


@pytest.mark.parametrize("kind", ["points", "points_dn", "laser", "ballbar"])
def test_jacobians_match_finite_differences(cafxyz, kind):
    machine, model = cafxyz
    rng = np.random.default_rng(4)
    n = 6
    q = rng.uniform([-300, -200, -200, -1.5, -3], [300, 200, 200, 1.5, 3], (n, 5))
    abc = np.column_stack([q[:, 3], np.zeros(n), q[:, 4]])
    if kind == "points":
        data = make_points(q[:, :3], abc, tool=rng.uniform(0, 200, n))
    elif kind == "points_dn":   # blank cells and normal deviations: the gathered Jacobian
        normal = rng.normal(size=(n, 3))
        normal /= np.linalg.norm(normal, axis=1, keepdims=True)
        dev = np.zeros((n, 3))
        dev[::2, 1] = np.nan
        dev[1, :] = np.nan
        data = make_points(q[:, :3], abc, deviation=dev, normal=normal)
    elif kind == "laser":
        axis = np.array(list("XYZACX"))
        comp = np.array(["EYX", "EBY", "EZZ", "EAA", "ECC", "ECX"])
        static = np.column_stack([q[:, :3], abc])
        target = np.array([q[i, "XYZAC".index(a)] for i, a in enumerate(axis)])
        data = make_laser(axis, comp, target, static=static, optic=rng.uniform(-100, 100, (n, 3)))
    else:
        data = make_ballbar(q[:, :3], rng.uniform(-50, 50, (n, 3)), rng.uniform(-30, 30, (n, 3)), abc)
    mm = measurement_model(model, data)
    p = random_parameters(model, rng) * 5
    nu = rng.normal(size=mm.n_nuisance) * 1e-3
    J, Jn = mm.jacobian(p, nu)
    h = 1e-7
    for j in range(model.n_params):
        e = np.zeros(model.n_params)
        e[j] = h
        fd = (mm.predict(p + e, nu) - mm.predict(p - e, nu)) / (2 * h)
        np.testing.assert_allclose(J[:, j], fd, rtol=1e-5, atol=1e-6 * max(1.0, np.abs(J).max()))
    for j in range(mm.n_nuisance):
        e = np.zeros(mm.n_nuisance)
        e[j] = 1e-3
        fd = (mm.predict(p, nu + e) - mm.predict(p, nu - e)) / 2e-3
        np.testing.assert_allclose(Jn[:, j], fd, rtol=1e-8, atol=1e-10)


def test_laser_nuisance_offsets_and_slopes(xfyz):
    machine, model = xfyz
    target = np.array([0.0, 100.0, 200.0, 0.0, 100.0, 0.0])
    data = make_laser(list("XXXXXY"), ["EXX", "EXX", "EXX", "EYX", "EYX", "EAY"], target, path="run7.csv")
    mm = measurement_model(model, data)
    assert mm.nuisance_names == ("run7:X:EXX:offset", "run7:X:EYX:offset", "run7:X:EYX:slope",
                                 "run7:Y:EAY:offset")
    assert [s.unit for s in mm.nuisance_specs] == ["um", "um", "urad", "urad"]
    nu = np.array([1e-3, 2e-3, 5e-6, 3e-6])
    p = np.zeros(model.n_params)
    expected = np.array([1e-3, 1e-3, 1e-3, 2e-3, 2e-3 + 5e-6 * 100.0, 3e-6])
    np.testing.assert_allclose(mm.predict(p, nu), expected, rtol=1e-12, atol=1e-15)


def test_observations_drop_blank_cells(xfyz):
    machine, model = xfyz
    dev = np.array([[1e-3, np.nan, 2e-3], [np.nan, np.nan, 4e-3]])
    data = make_points([[0, 0, 0], [10, 0, 0]], deviation=dev)
    mm = measurement_model(model, data)
    assert mm.n_obs == 3
    np.testing.assert_array_equal(mm.obs_row, [0, 0, 1])
    assert list(mm.obs_column) == ["dx_um", "dz_um", "dz_um"]
    np.testing.assert_allclose(mm.observed, [1e-3, 2e-3, 4e-3], rtol=0, atol=0)
    np.testing.assert_allclose(mm.obs_unit_scale, [1e3, 1e3, 1e3], rtol=0, atol=0)
    cols = mm.predict_columns(np.zeros(model.n_params))
    assert set(cols) == {"pred_dx_um", "pred_dy_um", "pred_dz_um"}
    assert all(v.shape == (2,) for v in cols.values())


def test_context_matrix_maps_columns(xfyz):
    machine, _ = xfyz
    model = ErrorModel(machine, [ThermalDrift("temperature", ("temp_spindle",))])
    data = make_points([[0, 0, 0], [1, 0, 0], [2, 0, 0]], tool=[50.0, np.nan, 70.0])
    data.context.feed[:] = [1000.0, np.nan, 2000.0]
    data.context.dirs[:, 1] = [1, -1, 0]
    data.context.temperatures["spindle"] = np.array([20.5, 21.0, np.nan])
    data.context.temperatures["other"] = np.array([1.0, 2.0, 3.0])
    c = context_matrix(model, data, {"temp_spindle": 20.0})
    col = {name: c[:, i] for i, name in enumerate(model.context_names)}
    np.testing.assert_allclose(col["feed"], [1000.0, 0.0, 2000.0], rtol=0, atol=0)
    np.testing.assert_allclose(col["dir_Y"], [1.0, -1.0, 0.0], rtol=0, atol=0)
    np.testing.assert_allclose(col["dir_X"], [0.0, 0.0, 0.0], rtol=0, atol=0)
    np.testing.assert_allclose(col["tool_length"], [50.0, machine.tool_length, 70.0], rtol=0, atol=0)
    np.testing.assert_allclose(col["temp_spindle"], [20.5, 21.0, 20.0], rtol=0, atol=0)
    assert "temp_other" not in model.context_names


def test_simulate_round_trip_and_unknown_kind(xfyz, monkeypatch):
    machine, model = xfyz
    rng = np.random.default_rng(5)
    p = random_parameters(model, rng)
    data = simulate(model, make_points(rng.uniform(-100, 100, (5, 3))), p)
    mm = measurement_model(model, data)
    np.testing.assert_allclose(mm.residuals(p, None), 0.0, rtol=0, atol=1e-9)
    monkeypatch.delitem(mmod.MEASUREMENT_MODELS, "points")
    with pytest.raises(InputError, match="no measurement model for points files"):
        measurement_model(model, data)


def test_context_matrix_computes_drift_features_from_the_file(tmp_path):
    """A ThermalDrift term's features come from the file's t_s and temperature columns."""
    from mtcomp import load_machine
    from mtcomp.measurement.readings import context_matrix
    from mtcomp.measurement.files import read_measurements
    from mtcomp.models import ErrorModel, ThermalDrift

    p = tmp_path / "pts.csv"
    p.write_text("x_mm,y_mm,z_mm,dx_um,t_s,temp_spindle_c\n"
                 "0,0,0,1.0,0,20.0\n10,0,0,1.5,1800,21.5\n20,0,0,2.0,7200,23.0\n")
    machine = load_machine("xfyz")
    model = ErrorModel(machine, [ThermalDrift("temperature", ("time_h", "dtemp_spindle"))])
    c = context_matrix(model, read_measurements(p))
    names = list(model.context_names)
    np.testing.assert_allclose(c[:, names.index("time_h")], [0.0, 0.5, 2.0], rtol=0, atol=1e-15)
    np.testing.assert_allclose(c[:, names.index("dtemp_spindle")], [0.0, 1.5, 3.0], rtol=0, atol=1e-12)


def test_held_axes_round_trip_and_clamp(tmp_path):
    """MODEL.json 'held' (file units, deg for rotary axes) survives save/load; clamp puts the held
    axes at their positions and leaves the others; a bad entry is refused naming the key."""
    import json
    from mtcomp.errors import InputError
    from mtcomp.models import ErrorModel, FittedModel, load_model, save_model
    machine = load_machine("cafxyz")
    fm = FittedModel.zero(ErrorModel(machine))
    fm.held = {"Z": -40.0, "A": np.radians(30.0)}
    path = tmp_path / "m.json"
    save_model(path, fm)
    data = json.loads(path.read_text())
    assert data["held"] == {"Z": -40.0, "A": pytest.approx(30.0)}
    back = load_model(path)
    q = np.array([[1.0, 2.0, 3.0, 0.1, 0.2], [4.0, 5.0, 6.0, 0.3, 0.4]])
    qc, cols = back.clamp(q)
    assert cols == [2]              # a held rotary axis is not clamped (compensate pins it instead)
    np.testing.assert_allclose(qc, [[1, 2, -40, 0.1, 0.2], [4, 5, -40, 0.3, 0.4]])
    np.testing.assert_array_equal(q[0], [1.0, 2.0, 3.0, 0.1, 0.2])      # the input is not changed
    data["held"] = {"Q": 1.0}
    path.write_text(json.dumps(data))
    with pytest.raises(InputError, match="'held' names axis 'Q'"):
        load_model(path)

"""`mtcomp predict`: every input column repeated verbatim, pred_<column> per measured column, values
from the model (checked against the model's own deviation function and the numpy reference)."""
from __future__ import annotations

import csv

import numpy as np
import pytest

from mtcomp.cli import main
from mtcomp.measurement import readings as mmod
from mtcomp.measurement.files import read_measurements
from mtcomp.machine import load_machine
from mtcomp.models import ErrorModel, FittedModel, ParameterSet, deviation, save_model
from mtcomp.sim import make_ballbar, make_laser, make_points, write_measurements
from reference_model import reference_deviation


@pytest.fixture(scope="module")
def model_file(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("predict")
    # polynomial basis: every linear-axis error is zero at the axis zero, which the hand cases use
    machine = load_machine("cafxyz").with_basis("polynomial")
    model = ErrorModel(machine)
    rng = np.random.default_rng(40)
    values = np.where(model.base_mask, rng.normal(size=model.n_params), 0.0)
    values *= np.array([1e-2 if s.unit == "um" else 2e-5 for s in model.param_specs])
    path = tmp / "model.json"
    save_model(path, FittedModel(model, ParameterSet(model.param_specs, values)))
    return tmp, path, model, values


def _by_name(header, rows, names) -> np.ndarray:
    """(n_rows, len(names)) floats of the named columns, blank cells NaN."""
    return np.array([[float(r[header.index(n)]) if r[header.index(n)] != "" else np.nan for n in names]
                     for r in rows])


def _read(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], rows[1:]


def test_predict_points(model_file):
    tmp, mpath, model, p = model_file
    rng = np.random.default_rng(41)
    n = 7
    xyz = rng.uniform(-200, 200, (n, 3))
    abc = np.column_stack([rng.uniform(-1, 1, n), np.zeros(n), rng.uniform(-3, 3, n)])
    normal = np.tile([0.0, 0.6, 0.8], (n, 1))
    data = make_points(xyz, abc, tool=np.full(n, 120.0), normal=normal)
    src = tmp / "pts.csv"
    write_measurements(src, data)
    out = tmp / "pts_pred.csv"
    assert main(["predict", "cafxyz", str(mpath), str(src), "-o", str(out)]) == 0
    header, rows = _read(out)
    in_header, in_rows = _read(src)
    preds = ["pred_dx_um", "pred_dy_um", "pred_dz_um", "pred_dn_um"]
    assert header == in_header + [c for p in preds for c in (p, f"{p}_sd")]
    assert [r[:len(in_header)] for r in rows] == in_rows           # verbatim
    pred = _by_name(header, rows, preds)
    # a model written by hand carries no uncertainty: its standard errors are blank
    assert np.isnan(_by_name(header, rows, [f"{p}_sd" for p in preds])).all()
    q = np.column_stack([xyz, abc[:, 0], abc[:, 2]])
    c = model.default_context(n)
    c[:, model.context_names.index("tool_length")] = 120.0
    dev = deviation(model, q, p, c)[:, :3] * 1e3
    np.testing.assert_allclose(pred[:, :3], dev, rtol=1e-8, atol=1e-8)
    np.testing.assert_allclose(pred[:, 3], dev @ normal[0], rtol=1e-8, atol=1e-8)
    ref = reference_deviation(model.machine, dict(zip(model.param_names, p)), q[0], {"tool_length": 120.0})
    np.testing.assert_allclose(pred[0, :3], ref[:3] * 1e3, rtol=1e-8, atol=1e-8)


def test_predict_laser_and_ballbar(model_file):
    tmp, mpath, model, p = model_file
    laser = make_laser(["X", "X", "C"], ["EXX", "EBX", "ECC"], [100.0, -50.0, np.radians(30.0)])
    lpath = tmp / "las.csv"
    write_measurements(lpath, laser)
    out = tmp / "las_pred.csv"
    assert main(["predict", "cafxyz", str(mpath), str(lpath), "-o", str(out)]) == 0
    header, rows = _read(out)
    assert header[-4:] == ["pred_value_um", "pred_value_um_sd", "pred_value_urad", "pred_value_urad_sd"]
    rows = [[r[header.index(c)] for c in ("pred_value_um", "pred_value_urad")] for r in rows]
    # hand case for ECC: actual minus commanded angle = ECC_0 + c1 cos + s1 sin + c2 cos 2 + s2 sin 2
    names = list(model.param_names)
    th = np.radians(30.0)
    ecc = sum(p[names.index(n)] * f for n, f in [("ECC_0", 1.0), ("ECC_c1", np.cos(th)),
                                                   ("ECC_s1", np.sin(th)), ("ECC_c2", np.cos(2 * th)),
                                                   ("ECC_s2", np.sin(2 * th))])
    assert rows[2][-2] == "" and rows[0][-1] == ""
    # (the other angular errors of ~20 urad add second-order terms of ~(2e-5)^2 rad = 4e-4 urad each)
    np.testing.assert_allclose(float(rows[2][-1]), ecc * 1e6, rtol=0, atol=1e-2)
    ref = reference_deviation(model.machine, dict(zip(names, p)), [100.0, 0, 0, 0, 0],
                              {"tool_length": model.machine.tool_length})
    np.testing.assert_allclose(float(rows[0][-2]), ref[0] * 1e3, rtol=1e-8, atol=1e-8)

    bb = make_ballbar([[100.0, 0.0, 0.0], [0.0, 100.0, 0.0]], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0])
    bpath = tmp / "bb.csv"
    write_measurements(bpath, bb)
    out = tmp / "bb_pred.csv"
    assert main(["predict", "cafxyz", str(mpath), str(bpath), "-o", str(out)]) == 0
    header, rows = _read(out)
    assert header[-2:] == ["pred_length_mm", "pred_length_mm_sd"]
    rows = [[r[header.index("pred_length_mm")]] for r in rows]
    for row, q in zip(rows, ([100.0, 0, 0, 0, 0], [0, 100.0, 0, 0, 0])):
        ref = reference_deviation(model.machine, dict(zip(names, p)), q,
                                  {"tool_length": model.machine.tool_length})
        np.testing.assert_allclose(float(row[-1]), np.linalg.norm(np.array(q[:3]) + ref[:3]),
                                   rtol=0, atol=1e-8)  # 10 digits in the file


def test_predict_kind_without_model_and_bad_input(model_file, capsys, monkeypatch):
    tmp, mpath, model, p = model_file
    src = tmp / "pts2.csv"
    write_measurements(src, make_points([[0.0, 0.0, 0.0]]))
    out = tmp / "never.csv"
    monkeypatch.delitem(mmod.MEASUREMENT_MODELS, "points")
    assert main(["predict", "cafxyz", str(mpath), str(src), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "no measurement model for points files" in err and err.count("\n") == 1
    assert not out.exists()
    monkeypatch.undo()
    # output onto the model or the data file is refused; a model of another topology too
    assert main(["predict", "cafxyz", str(mpath), str(src), "-o", str(src)]) == 2
    assert main(["predict", "xfyz", str(mpath), str(src), "-o", str(out)]) == 2
    assert "CAFXYZ" in capsys.readouterr().err
    assert not out.exists()
    assert read_measurements(src).kind == "points"


def test_predict_uses_context_columns(tmp_path):
    # backlash on X: EXX += BL/2 * dir_x, so rows approached from + and - differ by BL in dx
    machine = load_machine("xfyz").with_basis("polynomial")
    from mtcomp.models import Backlash
    model = ErrorModel(machine, [Backlash("X")])
    values = np.zeros(model.n_params)
    values[model.param_names.index("BL_X")] = 4e-3
    values[model.param_names.index("EXX_1")] = 2e-3
    mpath = tmp_path / "bl.json"
    save_model(mpath, FittedModel(model, ParameterSet(model.param_specs, values)))
    src = tmp_path / "dir.csv"
    src.write_text("x_mm,y_mm,z_mm,dx_um,dir_x\n100,0,0,0,1\n100,0,0,0,-1\n100,0,0,0,\n")
    out = tmp_path / "dir_pred.csv"
    assert main(["predict", "xfyz", str(mpath), str(src), "-o", str(out)]) == 0
    header, rows = _read(out)
    dx = np.array([float(r[header.index("pred_dx_um")]) for r in rows])
    # EXX_1 = 2 um per m at 100 mm: 0.2 um; +-2 um of backlash; blank dir (unknown): no step
    np.testing.assert_allclose(dx, [0.2 + 2.0, 0.2 - 2.0, 0.2], rtol=1e-9, atol=1e-9)


def test_a_diagnosed_model_gives_every_prediction_its_standard_error(tmp_path):
    """A diagnosed model carries its covariance (as identify's does): laser runs of X positioning at
    13 targets, five bidirectional runs (10 readings a target), no hidden effect. The base follows
    every target (one function a target), so the least squares' prediction at a target is its
    readings' mean less the reference: its standard error is the noise over sqrt(10) (a
    hand-derived oracle), to within the reference's share (1/13 of the variance) and the noise
    estimate. The model written is the penalised fit, whose smooth profile also leans on the
    neighbouring targets: its standard errors are at most that, and not below half of it."""
    from mtcomp.diagnose import diagnose
    from mtcomp.identification.predict import predict_readings
    from mtcomp.machine import load_machine
    from mtcomp.measurement.files import read_measurements
    from laser_files import write_x_positioning
    path = write_x_positioning(tmp_path / "laser_x.csv", np.arange(-300, 301, 50.0),
                               lambda t, d: 10 * np.sin(t / 150), 5, 0.5, np.random.default_rng(3))
    data = read_measurements(str(path))
    diag = diagnose(load_machine("xfyz"), [data])
    assert diag.findings == [] and diag.model.uncertainty is not None
    sd = predict_readings(diag.model, data).columns["pred_value_um_sd"]
    expected = diag.noise["um"].sigma / np.sqrt(10)
    assert np.all(np.isfinite(sd))
    assert np.all(sd <= 1.12 * expected) and np.all(sd >= 0.5 * expected), (sd, expected)


def test_predictions_outside_the_region_get_no_standard_error(tmp_path, capsys):
    """A model identified from X runs over -300..300 mm holds its profiles' end values beyond them, a
    guess its posterior does not size: predict leaves those rows' standard errors blank (the rows at
    |X| > 300, by hand) and says how many and where; inside every row gets one."""
    from laser_files import write_x_positioning
    runs = write_x_positioning(tmp_path / "laser_x.csv", np.arange(-300, 301, 50.0),
                               lambda t, d: 10 * np.sin(t / 150), 3, 0.5, np.random.default_rng(3))
    model = tmp_path / "m.json"
    assert main(["identify", "xfyz", str(runs), "-o", str(model)]) == 0
    targets = np.arange(-400, 401, 25.0)
    grid = tmp_path / "grid.csv"
    grid.write_text("axis,component,target_mm,dir,run,value_um\n"
                    + "".join(f"X,EXX,{t},1,1,\n" for t in targets))
    capsys.readouterr()
    out = tmp_path / "p.csv"
    assert main(["predict", "xfyz", str(model), str(grid), "-o", str(out)]) == 0
    err = capsys.readouterr().err
    header, rows = _read(out)
    sd = _by_name(header, rows, ["pred_value_um_sd"])[:, 0]
    value = _by_name(header, rows, ["pred_value_um"])[:, 0]
    outside = np.abs(targets) > 300
    assert np.isnan(sd[outside]).all() and np.isfinite(sd[~outside]).all()
    assert np.isfinite(value).all()                  # the prediction itself is still written
    assert f"{int(outside.sum())} row(s) lie outside the region" in err and "X -300 .. 300 mm" in err
    assert "the prediction is written, its _sd column left blank" in err

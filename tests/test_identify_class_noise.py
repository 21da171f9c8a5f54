"""Under weights "unit" each class of readings (um, urad) gets its own residual variance: the class
variances and the standard errors of predictions checked against closed-form least squares written
out by hand (no code of the package)."""
from __future__ import annotations

import json

import numpy as np
import pytest

from mtcomp.identification.fit import solve
from mtcomp.identification.predict import predict_readings
from mtcomp.identification.problem import FitProblem
from mtcomp.machine import load_machine
from mtcomp.measurement.files import read_measurements
from mtcomp.models import save_model

TARGETS = np.linspace(-300.0, 300.0, 7)
RUNS = 3
#: component, its reading (noise-free, file units) at a target, its noise, its unit
LINES = (("EXX", lambda t: 4.0 + 0 * t, 0.3, "um"),
         ("EYX", lambda t: -2.0 + 0.03 * t, 0.3, "um"),
         ("EBX", lambda t: 15.0 + 0 * t, 2.0, "urad"))


@pytest.fixture
def laser(tmp_path):
    """A laser file of X, forward runs only (no reversal to take out): positioning and straightness
    read in um with 0.3 um of noise, pitch in urad with 2 urad; {component: (targets, readings)}."""
    rng = np.random.default_rng(3)
    rows, data = ["axis,component,target_mm,dir,run,value_um,value_urad"], {}
    for comp, f, noise, unit in LINES:
        t = np.tile(TARGETS, RUNS)
        v = f(t) + rng.normal(0.0, noise, t.size)
        data[comp] = (t, v)
        rows += [f"X,{comp},{a},1,{1 + i // TARGETS.size}," + (f"{b:.9f}," if unit == "um" else f",{b:.9f}")
                 for i, (a, b) in enumerate(zip(t, v))]
    path = tmp_path / "laser_x.csv"
    path.write_text("\n".join(rows) + "\n")
    return path, data


def _design(comp, t):
    """The set-up's design by hand: a zero offset, and for a straightness also the optic's slope."""
    return np.column_stack([np.ones_like(t), t / 1000.0]) if comp == "EYX" else np.ones((t.size, 1))


def test_each_unit_gets_its_own_residual_variance(laser, tmp_path):
    path, data = laser
    # the machine's errors held (one a laser run of X does not see left free): the fit is the
    # set-ups', each component's line by least squares
    problem = FitProblem.from_data(load_machine("xfyz"), [read_measurements(path)], free=["EZX_b1"],
                                   penalty=False, hold_weak=False)
    res = solve(problem)
    rss = {"um": 0.0, "urad": 0.0}
    n = {"um": 0, "urad": 0}
    edf = {"um": 0, "urad": 0}
    lines = {}
    for comp, _, _, unit in LINES:
        t, v = data[comp]
        X = _design(comp, t)
        b = np.linalg.lstsq(X, v, rcond=None)[0]
        rss[unit] += float(np.sum((v - X @ b) ** 2))
        n[unit] += t.size
        edf[unit] += X.shape[1]
        lines[comp] = (X, np.linalg.inv(X.T @ X))
    s = {u: np.sqrt(rss[u] / (n[u] - edf[u])) for u in rss}
    assert res.noise == pytest.approx(s, rel=1e-6)
    assert s["urad"] / s["um"] > 3.0          # one pooled variance would be far off for both
    # each reading's prediction (its component's fitted set-up) and its standard error
    pred = predict_readings(res.fitted_model, read_measurements(path)).columns
    k = 0
    for comp, _, _, unit in LINES:
        X, inv = lines[comp]
        sd = s[unit] * np.sqrt(np.einsum("ij,jk,ik->i", X, inv, X))
        got = pred[f"pred_value_{unit}_sd"][k:k + X.shape[0]]
        np.testing.assert_allclose(got, sd, rtol=1e-6)
        k += X.shape[0]
    # MODEL.json says which noise each class got, and so does the report
    save_model(tmp_path / "model.json", res.fitted_model)
    written = json.loads((tmp_path / "model.json").read_text())["info"]["identify"]["noise"]
    assert written == pytest.approx(s, rel=1e-6)
    assert f"um {s['um']:.3g}, urad {s['urad']:.3g}" in res.summary()


def test_a_model_with_no_machine_parameter_free_predicts_with_the_set_up_s_sd(tmp_path):
    """Every machine parameter held, only the file's set-up (its zero) fitted: predict raised
    "cannot reshape array of size 0" on such a model. Its prediction of each reading is the
    readings' mean, with the standard error of a mean, s / sqrt(n), by hand."""
    values = 4.0 + 0.01 * np.arange(11)
    rows = ["axis,component,target_mm,dir,run,value_um"]
    rows += [f"X,EXX,{t},1,1,{v}" for t, v in zip(np.linspace(0.0, 500.0, 11), values)]
    path = tmp_path / "laser_x.csv"
    path.write_text("\n".join(rows) + "\n")
    problem = FitProblem.from_data(load_machine("xfyz"), [read_measurements(path)], free=[],
                                   penalty=False, hold_weak=False)
    pred = predict_readings(solve(problem).fitted_model, read_measurements(path)).columns
    s = np.std(values, ddof=1)
    np.testing.assert_allclose(pred["pred_value_um"], values.mean(), rtol=0, atol=1e-9)
    np.testing.assert_allclose(pred["pred_value_um_sd"], s / np.sqrt(values.size), rtol=1e-6)

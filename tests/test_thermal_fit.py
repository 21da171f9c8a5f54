"""mtcomp.thermal: forward-chaining folds, ridge regression, spindle heat lags, absolute drift terms.

Oracles: hand-derived folds and lag responses, the ridge solution from a second formulation
(augmented least squares), predictions of the thermal measurement model and of the kinematic chain
against the drift written out by hand.
"""
import json

import numpy as np
import pytest

from mtcomp.cli import main
from mtcomp.measurement.files import read_measurements
from mtcomp.measurement.readings import model_class_for
from mtcomp.measurement.drift import spindle_heat
from mtcomp.models import ChannelDrift, ErrorModel, ThermalDrift
from mtcomp.models.evaluate import deviation
from mtcomp.models.model_file import FittedModel
from mtcomp.models.params import ParameterSet
from mtcomp.models.terms import term_from_dict
from mtcomp.thermal import fit_ridge, forward_folds
from mtcomp.thermal._fit import CandidateScore, choose


def test_forward_folds_train_on_the_past_and_test_the_next_block():
    folds = forward_folds(12, 5)
    assert [(tr.start, tr.stop, te.start, te.stop) for tr, te in folds] == [
        (0, 2, 2, 4), (0, 4, 4, 6), (0, 6, 6, 8), (0, 8, 8, 10), (0, 10, 10, 12)]
    with pytest.raises(ValueError):
        forward_folds(11, 5)


@pytest.mark.parametrize("penalty", [0.0, 0.05])
def test_ridge_matches_augmented_least_squares(penalty):
    rng = np.random.default_rng(3)
    n, k, m = 40, 4, 2
    X = rng.normal(size=(n, k)) * [1.0, 10.0, 0.1, 3.0] + [20.0, 0.0, 5.0, -1.0]
    Y = rng.normal(size=(n, m))
    r = fit_ridge(X, Y, penalty)
    # second formulation: minimise |Y - b - X C|^2 + penalty n |S C|^2 as one least-squares problem
    S = np.diag(X.std(axis=0))
    A = np.block([[np.ones((n, 1)), X], [np.zeros((k, 1)), np.sqrt(penalty * n) * S]])
    sol = np.linalg.lstsq(A, np.vstack([Y, np.zeros((k, m))]), rcond=None)[0]
    np.testing.assert_allclose(r.intercept, sol[0], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(r.coef, sol[1:], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(r.predict(X[:3]), sol[0] + X[:3] @ sol[1:], rtol=1e-9, atol=1e-9)


def test_spindle_lag_from_rest_and_from_steady_state():
    t = np.arange(0.0, 6000.0, 60.0)
    tau = 900.0
    rpm = np.full(t.shape, 3000.0)
    np.testing.assert_allclose(spindle_heat(t, rpm, tau), 3.0 * (1 - np.exp(-t / tau)), rtol=0, atol=1e-12)
    np.testing.assert_allclose(spindle_heat(t, rpm, tau, steady_start=True), 3.0, rtol=0, atol=1e-12)
    # steady at 3000 rpm, stopped from reading j on: the speed holds until the next reading
    j = 30
    rpm[j:] = 0.0
    h = spindle_heat(t, rpm, tau, steady_start=True)
    expect = np.where(t <= t[j], 3.0, 3.0 * np.exp(-(t - t[j]) / tau))
    np.testing.assert_allclose(h, expect, rtol=0, atol=1e-12)


def _thermal_file(path, n=200, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 60.0
    temp = 20.0 + 2.0 * np.sin(t / 3000.0) + rng.normal(0, 0.01, n)
    rpm = np.where((t // 1800) % 2 == 1, 4000.0, 0.0)
    d1 = 3.0 * (temp - 20.0) + rng.normal(0, 0.05, n)
    d2 = rng.normal(0, 0.05, n)
    lines = ["t_s,spindle_rpm,disp_a_um,disp_ch3_um,temp_s_c"]
    lines += [f"{a:g},{b:g},{c:.4f},{d:.4f},{e:.4f}" for a, b, c, d, e in zip(t, rpm, d1, d2, temp)]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_absolute_drift_terms_read_the_features_themselves(tmp_path, xfyz):
    machine = xfyz[0]
    data = read_measurements(_thermal_file(tmp_path / "th.csv"))
    feats = ("temp_s", "spindle_lag_900")
    terms = [ChannelDrift("temperature", feats, ("a",), absolute=True),
             ThermalDrift("temperature", feats, "Z", absolute=True, channels=("ch3",))]
    for term in terms:                               # MODEL.json round trip of the new fields
        assert term_from_dict(json.loads(json.dumps(term.to_dict()))) == term
    model = ErrorModel(machine, terms)
    params = ParameterSet(model.param_specs)
    values = {"TD_a_temp_s": 2.5, "TD_a_spindle_lag_900": -0.7, "TD_a_zero": 4.0,
              "TD_Z_temp_s": -1.5, "TD_Z_spindle_lag_900": 0.3, "TD_Z_zero": 30.0}      # um
    for name, v in values.items():
        params[name] = v * 1e-3
    mm = model_class_for("thermal", "th.csv")(model, data, {}, machine=machine)
    cols = mm.predict_columns(params.values, mm.zero_nuisance())
    temp = data.context.temperatures["s"]
    lag = spindle_heat(data.t, data.context.spindle_rpm, 900.0, steady_start=True)
    np.testing.assert_allclose(cols["pred_disp_a_um"], 4.0 + 2.5 * temp - 0.7 * lag, rtol=0, atol=1e-9)
    np.testing.assert_allclose(cols["pred_disp_ch3_um"], 30.0 - 1.5 * temp + 0.3 * lag, rtol=0, atol=1e-9)
    # the channel read as Z acts on the tool tip at any pose: what compensate corrects
    q = np.array([[100.0, 50.0, -20.0], [300.0, 200.0, -100.0]])
    c = FittedModel(model, params).context(2, {"temp_s": [21.0, 23.0], "spindle_lag_900": [0.0, 4.0]})
    d = deviation(model, q, params.values, c) * 1e3
    np.testing.assert_allclose(d[:, 2], [30.0 - 1.5 * 21.0, 30.0 - 1.5 * 23.0 + 0.3 * 4.0], rtol=0, atol=1e-9)
    np.testing.assert_allclose(d[:, :2], 0.0, rtol=0, atol=1e-12)


def test_parsimony_keeps_the_simpler_driver_within_the_margin():
    def cand(label, complexity, sse):
        return CandidateScore(label, label, [label], [], complexity, forward_sse=np.array([sse]))
    a, b, c = cand("none", 0, 100.0), cand("temperature", 4, 10.0), cand("both", 5, 9.8)
    assert choose([a, b, c]) is b
    c.forward_sse = np.array([9.0])
    assert choose([a, b, c]) is c


def test_diagnose_thermal_cli_maps_a_channel_to_an_axis_and_plots(tmp_path, capsys):
    path = _thermal_file(tmp_path / "th.csv", n=400)
    rep, model, png = tmp_path / "r.json", tmp_path / "m.json", tmp_path / "d.png"
    assert main(["diagnose", "xfyz", str(path), "--json", str(rep), "-o", str(model), "--plot", str(png),
                 "--channel-axis", "a=Y", "-q"]) == 0
    report = json.loads(rep.read_text())
    drift = [f for f in report["findings"] if f["effect"] == "thermal_drift"]
    assert drift and drift[0]["params"]["driver"] == "temperature" and drift[0]["axis"] == "Y"
    assert drift[0]["params"]["channels"] == {"a": "Y", "ch3": ""}
    # the keys of every drift finding: temperatures used, the channel that drifts most, its direction
    # and its drift (largest |reading - first reading|, from the file itself)
    cols = np.genfromtxt(path, delimiter=",", names=True)
    p = drift[0]["params"]
    assert p["temperatures"] == ["s"] and p["channel"] == "a" and p["direction"] == "Y"
    assert p["drift_range_um"] == pytest.approx(np.max(np.abs(cols["disp_a_um"] - cols["disp_a_um"][0])),
                                                abs=2e-3)
    assert "forward-chained" in report["heldout"]
    saved = json.loads(model.read_text())
    kinds = {t["kind"]: t for t in saved["terms"]}
    assert kinds["thermal_drift"]["channels"] == ["a"] and kinds["thermal_drift"]["directions"] == "Y"
    import matplotlib.image
    img = matplotlib.image.imread(png)               # spindle panel + one per channel, 190 px each
    assert img.shape[:2] == (190 * 3, 1100)
    assert img[..., :3].std() > 0.05                 # something is drawn
    capsys.readouterr()


@pytest.mark.parametrize("flags,needle", [(["--channel-axis", "a"], "NAME=AXIS"),
                                          (["--channel-axis", "nope=X"], "nope"),
                                          (["--channel-axis", "a=Q"], "X, Y or Z"),
                                          (["--plot", "drift.jpg"], ".png name")])
def test_bad_channel_axis_exits_2_with_one_line_and_writes_nothing(tmp_path, capsys, flags, needle):
    path = _thermal_file(tmp_path / "th.csv")
    rep = tmp_path / "r.json"
    assert main(["diagnose", "xfyz", str(path), "--json", str(rep), "-q", *flags]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and needle in err[0] and "Traceback" not in err[0]
    assert not rep.exists()


@pytest.mark.parametrize("flags,needle", [(["--temperature", "nope=20"], "nope"),
                                          (["--temperature", "s"], "NAME=VALUE"),
                                          (["--spindle-rpm", "-5"], "0 or more")])
def test_compensate_refuses_a_thermal_state_the_model_cannot_use(tmp_path, capsys, flags, needle):
    path = _thermal_file(tmp_path / "th.csv", n=400)
    model = tmp_path / "m.json"
    assert main(["diagnose", "xfyz", str(path), "--json", str(tmp_path / "r.json"), "-o", str(model),
                 "--channel-axis", "a=Y", "-q"]) == 0
    prog, out = tmp_path / "in.nc", tmp_path / "out.nc"
    prog.write_text("G21 G90\nG0 X10 Y10 Z20\nG1 X50 F600\n")
    capsys.readouterr()
    assert main(["compensate", "xfyz", str(model), str(prog), "-o", str(out), "--quiet", *flags]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and needle in err[0] and "Traceback" not in err[0]
    assert not out.exists()


def test_blank_temperature_is_left_out_and_named_short_file_is_refused(tmp_path, capsys):
    path = _thermal_file(tmp_path / "th.csv", n=300)
    lines = path.read_text().splitlines()
    lines[0] += ",temp_broken_c"
    lines[1:] = [ln + ("," if k == 5 else ",21.0") for k, ln in enumerate(lines[1:])]
    path.write_text("\n".join(lines) + "\n")
    rep = tmp_path / "r.json"
    assert main(["diagnose", "xfyz", str(path), "--json", str(rep), "-q"]) == 0
    drift = [f for f in json.loads(rep.read_text())["findings"] if f["effect"] == "thermal_drift"]
    assert drift[0]["params"]["temperatures_left_out"] == ["broken"]
    assert "temp_broken" not in drift[0]["params"]["features"]
    short = tmp_path / "short.csv"
    short.write_text("\n".join(lines[:8]) + "\n")
    capsys.readouterr()
    assert main(["diagnose", "xfyz", str(short), "--json", str(tmp_path / "s.json"), "-q"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "short.csv" in err[0] and "too few" in err[0]
    assert not (tmp_path / "s.json").exists()


@pytest.mark.parametrize("penalty", [0.0, 0.03])
def test_ridge_covariance_is_the_posterior_of_the_raw_problem(penalty):
    """A second formulation: in raw feature units, with the intercept as a column of ones, the
    ridge's penalty is lam n sum_i s_i^2 c_i^2 (s_i the feature's standard deviation, the intercept
    free), so the posterior covariance of (c, b) is sigma^2 (X1^T X1 + P)^-1, P = diag(lam n s^2, 0),
    sigma^2 the residual sum of squares over n - edf."""
    from mtcomp.thermal._fit import ridge_covariance
    rng = np.random.default_rng(2)
    n = 300
    X = np.column_stack([rng.normal(20.0, 2.0, n), rng.normal(3.0, 0.5, n)])
    Y = np.column_stack([X @ [1.5, -4.0] + 7.0 + rng.normal(0, 0.3, n),
                         X @ [-0.5, 2.0] + rng.normal(0, 0.6, n)])
    ridge = fit_ridge(X, Y, penalty)
    cov = ridge_covariance(X, Y, ridge)
    X1 = np.column_stack([X, np.ones(n)])
    P = np.diag(np.r_[penalty * n * X.std(axis=0) ** 2, 0.0])
    H = np.linalg.inv(X1.T @ X1 + P)
    edf = np.trace(H @ X1.T @ X1)
    for j in range(2):
        s2 = np.sum((Y[:, j] - ridge.predict(X)[:, j]) ** 2) / (n - edf)
        np.testing.assert_allclose(cov[j], s2 * H, rtol=1e-9, atol=1e-14)

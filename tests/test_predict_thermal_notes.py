"""predict on a thermal file the model was not fitted on says what each channel's prediction is
referenced to (a channel of an absolute drift term: the fitted record's zero; any other: the change
since the file's first reading), and names the model's channels the file has no column for.

The model is written by hand (tests/test_thermal_fit.py's terms): channel `a` absolute, 4 + 2.5 T
- 0.7 L um (T the temperature, L the spindle's heat lag), channel `b` relative, 1.5 L um."""
from __future__ import annotations

import numpy as np

from mtcomp.cli import main
from mtcomp.machine import load_machine
from mtcomp.measurement.drift import spindle_heat
from mtcomp.models import ChannelDrift, ErrorModel
from mtcomp.models.model_file import FittedModel, save_model
from mtcomp.models.params import ParameterSet


def _file(path, columns=("disp_a_um", "disp_b_um"), n=50):
    t = np.arange(n) * 60.0
    temp = 21.0 + 0.02 * np.arange(n)
    rpm = np.where(np.arange(n) > 20, 3000.0, 0.0)
    lines = [",".join(("t_s", "spindle_rpm", *columns, "temp_s_c"))]
    lines += [f"{a:g},{b:g},1.0,2.0,{c:.4f}" for a, b, c in zip(t, rpm, temp)]
    path.write_text("\n".join(lines) + "\n")
    return t, temp, rpm


def _model(path):
    feats = ("temp_s", "spindle_lag_900")
    model = ErrorModel(load_machine("xfyz"), [ChannelDrift("temperature", feats, ("a",), absolute=True),
                                              ChannelDrift("spindle", ("spindle_lag_900",), ("b",))])
    params = ParameterSet(model.param_specs)
    for name, v in {"TD_a_temp_s": 2.5, "TD_a_spindle_lag_900": -0.7, "TD_a_zero": 4.0,
                    "TD_b_spindle_lag_900": 1.5}.items():
        params[name] = v * 1e-3
    save_model(path, FittedModel(model, params))


def test_each_channel_is_predicted_in_its_own_reference_and_the_note_says_which(tmp_path, capsys):
    _model(tmp_path / "m.json")
    t, temp, rpm = _file(tmp_path / "next.csv")
    assert main(["predict", "xfyz", str(tmp_path / "m.json"), str(tmp_path / "next.csv"),
                 "-o", str(tmp_path / "p.csv")]) == 0
    err = capsys.readouterr().err
    assert "channel(s) a predicted in the zero of the record the model was fitted on" in err
    assert "channel(s) b predicted as the change since this file's first reading" in err
    assert "taken as zero" not in err
    got = np.genfromtxt(tmp_path / "p.csv", delimiter=",", names=True)
    lag = spindle_heat(t, rpm, 900.0, steady_start=True)
    np.testing.assert_allclose(got["pred_disp_a_um"], 4.0 + 2.5 * temp - 0.7 * lag, rtol=0, atol=1e-6)
    np.testing.assert_allclose(got["pred_disp_b_um"], 1.5 * (lag - lag[0]), rtol=0, atol=1e-6)


def test_a_channel_the_file_lacks_is_named(tmp_path, capsys):
    _model(tmp_path / "m.json")
    _file(tmp_path / "next.csv", columns=("disp_a_um", "dsp_b_um"))
    assert main(["predict", "xfyz", str(tmp_path / "m.json"), str(tmp_path / "next.csv"),
                 "-o", str(tmp_path / "p.csv")]) == 0
    err = capsys.readouterr().err
    assert "next has no column for the model's channel(s) b (disp_b_um): not predicted" in err


def test_a_broken_model_file_names_line_and_column(tmp_path, capsys):
    bad = tmp_path / "m.json"
    bad.write_text('{"format": "x",\n "a": "one\ttab"}')
    _file(tmp_path / "next.csv")
    assert main(["predict", "xfyz", str(bad), str(tmp_path / "next.csv"), "-o",
                 str(tmp_path / "p.csv")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.endswith("not valid JSON at line 2, column 11: Invalid control character"), err
    assert not (tmp_path / "p.csv").exists()


def test_a_file_without_a_spindle_speed_is_not_said_to_lie_beyond_the_records_speeds(tmp_path):
    """A geometric file gives no spindle speed: its blank speed is not 0 rpm outside a record's
    1000..6000 rpm; a thermal file's speed of 0 rpm is."""
    from mtcomp.measurement import read_measurements
    from mtcomp.models.model_file import load_model
    from mtcomp.thermal.context import record_state_note
    _model(tmp_path / "m.json")
    fitted = load_model(tmp_path / "m.json")
    fitted.info["context_ranges"] = {"temp_s": [20.0, 25.0], "spindle_rpm": [1000.0, 6000.0]}
    laser = tmp_path / "x.csv"
    laser.write_text("axis,component,target_mm,dir,run,value_um\n"
                     + "".join(f"X,EXX,{x},{d},1,0.5\n" for x in (0, 50, 100, 150) for d in (1, -1)))
    assert record_state_note(fitted, read_measurements(laser)) == ""
    _file(tmp_path / "rec.csv")
    note = record_state_note(fitted, read_measurements(tmp_path / "rec.csv"))
    assert "21 of 50 row(s) lie outside" in note and "spindle_rpm 21 row(s) at 0 to 0 rpm" in note

"""A thermal drift in time (diagnose's "steady drift in time" or "settling drift in time": features
``time_h``, ``time_exp_<tau>``) moves with the time since its record began, which compensate is not
told, and with no temperature or spindle speed: compensate says so instead of asking for a
temperature (a new user gave --temperature and --spindle-rpm, which such a model refused as "no
drift term that reads that sensor"); given one, it is refused in one line saying why."""
from __future__ import annotations

import pytest

from mtcomp.cli import main
from mtcomp.machine import load_machine
from mtcomp.models import ErrorModel, FittedModel, save_model
from mtcomp.models.terms import ThermalDrift
from mtcomp.thermal.context import time_driven

PROGRAM = "G21 G90\nG0 X0 Y0 Z10\nG1 X10 F500\nG1 Y10\nM30\n"


def _model(tmp_path, feature):
    machine = load_machine("xfyz").with_basis("polynomial")
    fitted = FittedModel.zero(ErrorModel(machine, [ThermalDrift(
        "time" if feature.startswith("time") else "temperature", (feature,), "Z", absolute=True)]))
    fitted.params.set_file_value(f"TD_Z_{feature}", 15.0)
    path = tmp_path / "model.json"
    save_model(path, fitted)
    (tmp_path / "in.nc").write_text(PROGRAM)
    return path


@pytest.mark.parametrize("feature, in_time", [("time_exp_5400", True), ("time_h", True),
                                              ("temp_spindle", False)])
def test_which_drift_is_in_time(tmp_path, feature, in_time):
    from mtcomp.models import load_model
    assert time_driven(load_model(_model(tmp_path, feature)).model) is in_time


def test_a_drift_in_time_is_not_compensated_and_the_output_says_why(tmp_path, capsys):
    model = _model(tmp_path, "time_exp_5400")
    assert main(["compensate", "xfyz", str(model), str(tmp_path / "in.nc"), "-o",
                 str(tmp_path / "out.nc")]) == 0
    out = capsys.readouterr().out
    assert "thermal drift not compensated: the model's thermal drift is a drift in time" in out
    assert "give --temperature" not in out
    for flag in (["--spindle-rpm", "8000"], ["--temperature", "spindle=27"]):
        assert main(["compensate", "xfyz", str(model), str(tmp_path / "in.nc"), "-o",
                     str(tmp_path / "out2.nc"), *flag]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "a temperature or spindle speed was given, but the model's " \
            "thermal drift is a drift in time" in err[0]
        assert not (tmp_path / "out2.nc").exists()


def test_render_of_a_drift_in_time_says_why_it_is_not_mapped(tmp_path, capsys):
    """render's note for a drift in time is compensate's reason, not "give render the --temperature
    ... that compensate was given" (compensate refuses a temperature for this model)."""
    pytest.importorskip("matplotlib")
    model = _model(tmp_path, "time_h")
    assert main(["render", "xfyz", str(model), str(tmp_path / "in.nc"), "-o",
                 str(tmp_path / "map.png"), "--backend", "matplotlib", "--size", "300x200"]) == 0
    out = capsys.readouterr().out
    assert "thermal drift not mapped: the model's thermal drift is a drift in time" in out
    assert "--temperature" not in out.split("thermal drift not mapped")[1].split("\n")[0]

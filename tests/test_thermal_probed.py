"""The thermal drift a program is compensated for is the drift since the part's datum was probed:
the probe put the drift of its time into the work offset (G54). A new user's warm machine got its
whole drift since the thermal record's first reading corrected (+16 um on every Z word at spindle
30 degC), twice what the probed offset left to correct. Hand-derived case: a model whose only error
is dz = -2 um/degC (T_spindle - 22), cut at 30 degC: -16 um since the record's 22 degC, -8 um since
a probing at 26 degC, so the Z words move +0.016 mm by default and +0.008 mm probed at 26."""
from __future__ import annotations

import argparse
import re

import numpy as np
import pytest

from mtcomp.cli import main
from mtcomp.machine import load_machine
from mtcomp.models import ErrorModel, FittedModel, save_model
from mtcomp.models.terms import ThermalDrift

PROGRAM = "G21 G90\nG0 X0 Y0 Z10\nG1 Z5 F500\nG1 X10\nG1 Y10 Z4\nG1 X0 Z3\nM30\n"


def _fitted():
    machine = load_machine("xfyz").with_basis("polynomial")
    fitted = FittedModel.zero(ErrorModel(machine, [ThermalDrift(
        "temperature", ("temp_spindle",), "Z", absolute=True)]))
    fitted.params.set_file_value("TD_Z_temp_spindle", -2.0)      # um/degC
    fitted.params.set_file_value("TD_Z_zero", 44.0)              # zero at 22 degC
    fitted.info["context_ranges"] = {"temp_spindle": [20.0, 35.0]}
    fitted.info["thermal_first_reading"] = {"temp_spindle": 22.0}     # as diagnose writes it
    return fitted


@pytest.fixture
def files(tmp_path):
    save_model(tmp_path / "model.json", _fitted())
    (tmp_path / "in.nc").write_text(PROGRAM)
    return tmp_path


def _z_shifts(path) -> np.ndarray:
    """mm: each Z word of the output less the program's (the lines correspond one to one)."""
    z = lambda text: [float(m) for m in re.findall(r"Z(-?[\d.]+)", text)]   # noqa: E731
    return np.array(z(path.read_text())) - np.array(z(PROGRAM))


def _compensate(files, *flags):
    return main(["compensate", "xfyz", str(files / "model.json"), str(files / "in.nc"), "-o",
                 str(files / "out.nc"), "-q", "--temperature", "spindle=30", *flags])


def test_the_drift_since_probing_is_corrected_not_the_drift_since_the_record(files, capsys):
    assert _compensate(files) == 0
    out = capsys.readouterr().out
    np.testing.assert_allclose(_z_shifts(files / "out.nc"), 0.016, atol=1e-4)
    assert "thermal drift referenced to the record's first reading (" in out
    assert "give --probed-at-temperature if the datum was probed warm" in out
    assert _compensate(files, "--probed-at-temperature", "spindle=26") == 0
    out = capsys.readouterr().out
    np.testing.assert_allclose(_z_shifts(files / "out.nc"), 0.008, atol=1e-4)
    assert "referenced to the datum's probing" in out and "spindle=26 degC" in out
    # probed at the cutting temperature: nothing has drifted since the probe
    assert _compensate(files, "--probed-at-temperature", "spindle=30") == 0
    np.testing.assert_allclose(_z_shifts(files / "out.nc"), 0.0, atol=1e-4)


def test_a_temperature_series_is_referenced_to_the_probing_too(files):
    (files / "temps.csv").write_text("t_s,temp_spindle_c\n0,30\n600,30\n")
    assert main(["compensate", "xfyz", str(files / "model.json"), str(files / "in.nc"), "-o",
                 str(files / "out.nc"), "-q", "--temperatures", str(files / "temps.csv"),
                 "--probed-at-temperature", "spindle=26"]) == 0
    np.testing.assert_allclose(_z_shifts(files / "out.nc"), 0.008, atol=1e-4)


@pytest.mark.parametrize("flags, words", [
    (["--probed-at-temperature", "spindle=26"], "without the state while the program runs"),
    (["--temperature", "spindle=30", "--probed-at-temperature", "column=26"],
     "gives no temperature of sensor spindle"),
    (["--temperature", "spindle=30", "--probed-at-temperature", "spindle=86"],
     "temperature of sensor spindle: 86 degC is outside the range"),
])
def test_a_probed_state_that_cannot_be_taken_is_refused_in_one_line(files, capsys, flags, words):
    assert main(["compensate", "xfyz", str(files / "model.json"), str(files / "in.nc"), "-o",
                 str(files / "out.nc"), *flags]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0] and "model.json" in err[0]
    assert not (files / "out.nc").exists()


def test_render_maps_the_drift_since_probing():
    """render's model: its datum deviation holds the drift at probing, -8 um from the record's zero
    (the same FittedModel.datum_deviation compensate and the map reference to)."""
    from mtcomp.commands.render import _thermal_state
    args = argparse.Namespace(temperature=["spindle=30"], spindle_rpm=None, extrapolate=False,
                              probed_at_temperature=["spindle=26"], probed_at_spindle_rpm=None,
                              model="model.json")
    fitted, note = _thermal_state(args, _fitted())
    assert note == ""
    datum = fitted.datum_deviation(np.zeros((1, 3)), [0.0])
    np.testing.assert_allclose(datum[0] * 1e3, [0.0, 0.0, -8.0], atol=1e-9)
    args.probed_at_temperature = []
    fitted, note = _thermal_state(args, _fitted())
    np.testing.assert_allclose(fitted.datum_deviation(np.zeros((1, 3)), [0.0]), 0.0, atol=1e-12)
    assert note.startswith("thermal drift referenced to the record's first reading")


def test_a_spindle_heat_drift_is_referenced_to_the_spindle_speed_at_probing(tmp_path):
    """dz = -2 um per 1000 rpm of spindle heat at steady state: run at 8000 rpm, probed warm at 4000
    rpm: -16 um since a cold start, -8 um since probing."""
    machine = load_machine("xfyz").with_basis("polynomial")
    fitted = FittedModel.zero(ErrorModel(machine, [ThermalDrift(
        "spindle", ("spindle_lag_1800",), "Z", absolute=True)]))
    fitted.params.set_file_value("TD_Z_spindle_lag_1800", -2.0)
    save_model(tmp_path / "model.json", fitted)
    (tmp_path / "in.nc").write_text(PROGRAM)
    for probed, shift in (([], 0.016), (["--probed-at-spindle-rpm", "4000"], 0.008)):
        assert main(["compensate", "xfyz", str(tmp_path / "model.json"), str(tmp_path / "in.nc"),
                     "-o", str(tmp_path / "out.nc"), "-q", "--spindle-rpm", "8000", *probed]) == 0
        np.testing.assert_allclose(_z_shifts(tmp_path / "out.nc"), shift, atol=1e-4)

"""A thermal state that lacks a sensor the drift reads is refused, not filled in (docs/thermal.md).

The hand-written model reads two correlated sensors with large and opposite coefficients, as a fit
on sensors that warm together gives: dz = -2.7 T_head + 5.1 T_column um, its record's first
reading 20 degC on both. Warm (head 24, column 22 degC) the drift since that reading is
-2.7 * 4 + 5.1 * 2 = -0.6 um (by hand); with the column left at any stand-in value it is another
number, which no reading gave. So a readings file without a sensor's column, with it in degF or
blank, and --temperature flags that leave one out are refused in one line (exit 2, nothing
written), naming the file and the column, or the sensors."""
from __future__ import annotations

import csv

import numpy as np
import pytest

from mtcomp import load_machine
from mtcomp.cli import main
from mtcomp.models import ErrorModel, FittedModel, save_model
from mtcomp.models.terms import ThermalDrift

PROGRAM = "G21 G90\nG0 X0 Y0 Z10\nG1 Z5 F500\nG1 X10\nM30\n"


def _model(path):
    fitted = FittedModel.zero(ErrorModel(load_machine("xfyz").with_basis("polynomial"), [
        ThermalDrift("temperature", ("temp_head", "temp_column"), "Z", absolute=True,
                     channels=("z",))]))
    fitted.params.set_file_value("TD_Z_temp_head", -2.7)        # um/degC
    fitted.params.set_file_value("TD_Z_temp_column", 5.1)
    fitted.info["context_ranges"] = {"temp_head": [18.0, 30.0], "temp_column": [18.0, 30.0]}
    fitted.info["thermal_first_reading"] = {"temp_head": 20.0, "temp_column": 20.0}
    fitted.context_defaults.update(temp_head=23.0, temp_column=21.0)   # the record's mean
    save_model(path, fitted)
    return path


def _compensate(tmp_path, capsys, *flags):
    (tmp_path / "in.nc").write_text(PROGRAM)
    capsys.readouterr()
    rc = main(["compensate", "xfyz", str(_model(tmp_path / "m.json")), str(tmp_path / "in.nc"),
               "-o", str(tmp_path / "out.nc"), "--report", str(tmp_path / "B.csv"), "-q", *flags])
    return rc, capsys.readouterr().err.strip().splitlines()


@pytest.mark.parametrize("readings, needle", [
    ("temp_head_c\n24\n", "warm.csv: no reading in column(s) temp_column_c (nor --temperature "
                          "column=...): the model's thermal drift reads sensor(s) head, column"),
    ("temp_head_c,temp_column_c\n24,\n", "warm.csv: no reading in column(s) temp_column_c"),
    ("temp_head_c,temp_column_F\n24,71.6\n", "warm.csv: row 0: column temp_column_F: mtcomp reads "
                                             "temperature sensor column as temp_column_c, in degC"),
    ("t_s,temp_head_c\n0,24\n600,24.5\n", "warm.csv: row 0: no column temp_column_c"),
])
def test_a_readings_file_without_a_sensor_is_refused_naming_the_column(tmp_path, capsys, readings,
                                                                       needle):
    (tmp_path / "warm.csv").write_text(readings)
    rc, err = _compensate(tmp_path, capsys, "--temperatures", str(tmp_path / "warm.csv"))
    assert rc == 2 and len(err) == 1 and needle in err[0] and "Traceback" not in err[0], err
    assert not (tmp_path / "out.nc").exists() and not (tmp_path / "B.csv").exists()


def test_temperature_flags_that_leave_a_sensor_out_are_refused_naming_it(tmp_path, capsys):
    rc, err = _compensate(tmp_path, capsys, "--temperature", "head=24")
    assert rc == 2 and len(err) == 1, err
    assert err[0].endswith("m.json: no temperature of sensor(s) column is given (--temperature "
                           "NAME=DEGC): the model's thermal drift reads sensor(s) head, column: give "
                           "every sensor's temperature (one left out is not taken at its mean over "
                           "the record: the coefficients of correlated sensors are fitted together, "
                           "and one sensor's without the others' corrects a drift that is not there)"), err
    assert not (tmp_path / "out.nc").exists()


def test_the_help_of_temperature_says_a_missing_sensor_is_refused(capsys):
    # what the refusal above does, the help says (it said sensors not given keep the model's
    # reference, which no run does)
    with pytest.raises(SystemExit):
        main(["compensate", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    start = text.index("--temperature NAME=DEGC temperature of sensor")
    said = text[start:text.index("--temperatures READINGS.csv", start)]
    assert "a missing one is refused" in said and "reference" not in said, said


def test_every_sensor_given_a_file_and_a_flag_together_corrects_the_drift_by_hand(tmp_path, capsys):
    (tmp_path / "warm.csv").write_text("temp_head_c\n24\n")
    rc, err = _compensate(tmp_path, capsys, "--temperatures", str(tmp_path / "warm.csv"),
                          "--temperature", "column=22")
    assert rc == 0, err
    with open(tmp_path / "B.csv", newline="") as f:
        rows = [r for r in csv.DictReader(f) if r["ez_before_um"]]
    assert len(rows) >= 2
    # the drift since the record's first reading: -2.7 * (24 - 20) + 5.1 * (22 - 20) = -0.6 um
    np.testing.assert_allclose([float(r["ez_before_um"]) for r in rows], -0.6, rtol=0, atol=1e-6)


def test_render_refuses_a_state_that_leaves_a_sensor_out(tmp_path, capsys):
    (tmp_path / "in.nc").write_text(PROGRAM)
    capsys.readouterr()
    assert main(["render", "xfyz", str(_model(tmp_path / "m.json")), str(tmp_path / "in.nc"), "-o",
                 str(tmp_path / "map.png"), "--temperature", "column=22"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no temperature of sensor(s) head is given" in err[0], err
    assert not (tmp_path / "map.png").exists()


def test_a_study_whose_temperatures_leave_a_sensor_out_is_refused_before_it_starts(tmp_path, capsys):
    _model(tmp_path / "m.json")
    (tmp_path / "in.nc").write_text(PROGRAM)
    study = tmp_path / "STUDY.toml"
    study.write_text('machine = "xfyz"\nprograms = ["in.nc"]\nmodels = ["m.json"]\n'
                     "temperatures = [{head = 24.0, column = 22.0}, {head = 24.0}]\n")
    capsys.readouterr()
    assert main(["study", str(study), "-o", str(tmp_path / "R")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "STUDY.toml" in err[0], err
    assert "temperatures {'head': 24.0}: " in err[0] and "sensor(s) column is given" in err[0], err
    assert not (tmp_path / "R").exists()

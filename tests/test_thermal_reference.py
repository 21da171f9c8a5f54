"""The thermal drift compensate corrects by default is the drift since the thermal record's first
reading, never the drift model's absolute value: that value's constant holds the set-up zero of the
record's probe (where it was zeroed), which no data determine. A new user's model corrected Z by
+11.0 um where the drift since the first reading was 14.3 um, and by -9.0 um from the same record
with the probe zeroed 20 um higher.

Oracle: a record written here by hand from a known law (plain numpy, not mtcomp's simulator):
    dz = ZERO + A (T_spindle - 20) + B (T_bed - 20)   (um; ZERO the probe's set-up zero)
with the two temperatures following different curves, so the drift since the first reading at a
running state T is A (T_spindle - T_spindle[0]) + B (T_bed - T_bed[0]), whatever ZERO is, and the Z
words move by minus that (the correction is minus the error)."""
from __future__ import annotations

import re

import numpy as np
import pytest

from mtcomp.cli import main
from mtcomp.machine import load_machine
from mtcomp.models import ErrorModel, FittedModel, save_model
from mtcomp.models.terms import ThermalDrift

A_UM, B_UM = -1.5, 0.8          # um per degC
PROGRAM = "G21 G90\nG0 X0 Y0 Z10\nG1 Z5 F500\nG1 X10\nG1 Y10 Z4\nM30\n"
RUN = {"spindle": 26.0, "bed": 20.3}


def _record(path, zero_um: float) -> dict:
    """A 6 h record, a reading every 2 min (noise 0.02 um): the spindle warming and cooling, the bed
    following the room. Returns the first reading's temperatures."""
    t = np.arange(0.0, 6 * 3600.0 + 1, 120.0)
    h = t / 3600.0
    spindle = 20.2 + 8.0 * (1 - np.exp(-h / 1.2)) - 5.0 * np.clip(h - 4.0, 0, None) / 2.0
    bed = 20.1 + 0.6 * np.sin(2 * np.pi * h / 9.0)
    dz = zero_um + A_UM * (spindle - 20) + B_UM * (bed - 20)
    dz = dz + np.random.default_rng(3).normal(0.0, 0.02, t.size)
    rows = ["t_s,disp_z_um,temp_spindle_c,temp_bed_c"]
    rows += [f"{a:g},{b:.4f},{c:.4f},{d:.4f}" for a, b, c, d in zip(t, dz, spindle, bed)]
    path.write_text("\n".join(rows) + "\n")
    return {"spindle": round(float(spindle[0]), 4), "bed": round(float(bed[0]), 4)}


def _z_shifts(text) -> np.ndarray:
    z = lambda s: [float(m) for m in re.findall(r"Z(-?[\d.]+)", s)]   # noqa: E731
    return np.array(z(text)) - np.array(z(PROGRAM))


def _compensate(tmp_path, model, *flags) -> tuple[np.ndarray, str]:
    prog, out = tmp_path / "in.nc", tmp_path / "out.nc"
    prog.write_text(PROGRAM)
    temps = [x for k, v in RUN.items() for x in ("--temperature", f"{k}={v}")]
    assert main(["compensate", "xfyz", str(model), str(prog), "-o", str(out), "--max-correction-um",
                 "100", "--max-step-um", "100", "--max-correction-sd-um", "100", *temps,
                 *flags]) == 0
    return _z_shifts(out.read_text()), out.read_text()


def test_the_default_correction_is_the_drift_since_the_first_reading_whatever_the_probe_zero(
        tmp_path, capsys):
    shifts = []
    for zero in (3.0, 23.0):
        first = _record(tmp_path / f"rec{zero:g}.csv", zero)
        model = tmp_path / f"m{zero:g}.json"
        assert main(["diagnose", "xfyz", str(tmp_path / f"rec{zero:g}.csv"), "--json",
                     str(tmp_path / "r.json"), "-o", str(model), "-q"]) == 0
        shift, _ = _compensate(tmp_path, model)
        shifts.append(shift)
    said = capsys.readouterr().out
    assert "thermal drift referenced to the record's first reading" in said
    since_um = A_UM * (RUN["spindle"] - first["spindle"]) + B_UM * (RUN["bed"] - first["bed"])
    # the probe's zero moved by 20 um: the same correction (to the words' 1e-4 mm)
    np.testing.assert_allclose(shifts[0], shifts[1], rtol=0, atol=1e-4)
    # and it is the law's drift since the first reading (9.3 um here), not its absolute value
    np.testing.assert_allclose(shifts[0], -since_um * 1e-3, rtol=0, atol=1e-4)


def _old_model(tmp_path, defaults):
    """A model file an older mtcomp wrote: no first reading of its record. dz = 44 - 2 T_spindle."""
    fitted = FittedModel.zero(ErrorModel(load_machine("xfyz").with_basis("polynomial"), [
        ThermalDrift("temperature", ("temp_spindle",), "Z", absolute=True)]))
    fitted.params.set_file_value("TD_Z_temp_spindle", -2.0)
    fitted.params.set_file_value("TD_Z_zero", 44.0)
    fitted.context_defaults.update(defaults)
    fitted.info["context_ranges"] = {"temp_spindle": [20.0, 35.0]}
    save_model(tmp_path / "old.json", fitted)
    return tmp_path / "old.json"


def test_a_model_file_without_a_first_reading_is_referenced_to_the_records_mean(tmp_path, capsys):
    """Mean spindle temperature 25 degC in the file, run at 30: -10 um since the mean, so the Z words
    move +0.010 mm (the absolute value, -16 um, would move them +0.016)."""
    model = _old_model(tmp_path, {"temp_spindle": 25.0})
    prog, out = tmp_path / "in.nc", tmp_path / "out.nc"
    prog.write_text(PROGRAM)
    assert main(["compensate", "xfyz", str(model), str(prog), "-o", str(out), "--temperature",
                 "spindle=30"]) == 0
    np.testing.assert_allclose(_z_shifts(out.read_text()), 0.010, rtol=0, atol=1e-4)
    said = capsys.readouterr().out
    assert "referenced to the record's mean temperatures spindle=25 degC" in said
    assert "records no first reading" in said


def test_a_model_file_without_any_reference_temperature_is_refused_in_one_line(tmp_path, capsys):
    model = _old_model(tmp_path, {})
    prog, out = tmp_path / "in.nc", tmp_path / "out.nc"
    prog.write_text(PROGRAM)
    assert main(["compensate", "xfyz", str(model), str(prog), "-o", str(out), "--temperature",
                 "spindle=30"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "old.json" in err[0] and "--probed-at-temperature" in err[0]
    assert not out.exists()
    # told the state at probing, it corrects the drift since then: -2 (30 - 26) um
    assert main(["compensate", "xfyz", str(model), str(prog), "-o", str(out), "--temperature",
                 "spindle=30", "--probed-at-temperature", "spindle=26", "-q"]) == 0
    np.testing.assert_allclose(_z_shifts(out.read_text()), 0.008, rtol=0, atol=1e-4)


def test_a_drift_of_rises_since_each_files_first_reading_is_refused_in_one_line(tmp_path, capsys):
    """Several records diagnosed together give a drift in each sensor's rise since each file's
    first reading (dtemp_<s>): no temperature while a program runs gives it, so there is no first
    reading to reference a correction to; the line says how to get a drift compensate can follow."""
    fitted = FittedModel.zero(ErrorModel(load_machine("xfyz").with_basis("polynomial"), [
        ThermalDrift("temperature", ("dtemp_spindle",), "Z")]))
    fitted.params.set_file_value("TD_Z_dtemp_spindle", -2.0)
    save_model(tmp_path / "m.json", fitted)
    (tmp_path / "in.nc").write_text(PROGRAM)
    assert main(["compensate", "xfyz", str(tmp_path / "m.json"), str(tmp_path / "in.nc"), "-o",
                 str(tmp_path / "out.nc"), "--temperature", "spindle=30"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "m.json" in err[0] and "dtemp_spindle" in err[0]
    assert "diagnose one thermal record" in err[0]
    assert not (tmp_path / "out.nc").exists()


@pytest.mark.parametrize("fmt", ["heidenhain", "fanuc"])
def test_export_writes_the_geometry_without_the_drift(tmp_path, capsys, fmt):
    """A model with X positioning 20 um/m and a drift of dz = 44 - 2 T_spindle (-6 um at its mean 25
    degC): the tables hold the 20 um/m alone, every table (and every column) zero at the reference
    position, and nothing of the drift is said to be there (it was: "with every axis at its
    reference position the model predicts dz -6.00 um")."""
    from mtcomp.models import load_model
    path = _old_model(tmp_path, {"temp_spindle": 25.0})
    fitted = load_model(path)
    fitted.params.set_file_value("EXX_1", 20.0)
    save_model(path, fitted)
    out = tmp_path / "comp"
    assert main(["export", "xfyz", str(path), "--format", fmt, "-o", str(out)]) == 0
    cap = capsys.readouterr()
    said = cap.out + cap.err + (out / "README.txt").read_text()
    assert "reference position the model predicts" not in said and "dz" not in said
    assert "the tables leave out the thermal drift (thermal_drift:temperature)" in said
    if fmt == "heidenhain":
        from test_export_formats import read_heidenhain_table
        for table in out.glob("*.COM"):
            cols, rows = read_heidenhain_table(table)
            at_ref = next(r for r in rows if float(r["AXISPOS"]) == 0.0)
            np.testing.assert_allclose([float(at_ref[c]) for c in cols[2:]], 0.0, rtol=0, atol=0)
        cols, rows = read_heidenhain_table(out / "X.COM")
        x = np.array([float(r["AXISPOS"]) for r in rows])
        # the correction (minus the error): -20 um/m of X, in mm
        np.testing.assert_allclose([float(r["X"]) for r in rows], -0.02 * x * 1e-3, rtol=0,
                                   atol=6e-6)

"""Thermal inputs a user gets wrong (docs/thermal.md, docs/measurements.md): a wrong input is refused
in one line naming the file, the row or column and the problem (exit 2, nothing written); a
suspicious one gets a one-line note saying what looks wrong and what to check.

Hand-made records: 30 s steps over 10 h, a drift of 12 um, sensors that move by a degree or two.
The predict and compensate cases use a hand-written model, dz = 44 - 2 T_spindle um (zero at
22 degC), its record spanning 20 to 35 degC, with standard errors of 0.1 um/degC and 1 um
(independent), so a prediction's standard error is sqrt((0.1 T)^2 + 1) um by hand."""
from __future__ import annotations

import numpy as np
import pytest

from mtcomp import load_machine
from mtcomp.cli import main
from mtcomp.commands import note_outside_travel
from mtcomp.measurement.files import read_measurements
from mtcomp.models import ErrorModel, FittedModel, save_model
from mtcomp.models.terms import ThermalDrift

N = 1201
T_S = np.arange(N) * 30.0


def _record(path, t=T_S, disp_scale=1.0, header=None, blank=None):
    """A 10 h record: z drifts 12 um with the spindle temperature, y 3 um; ``blank`` (row, column
    index) leaves one cell empty."""
    n = len(t)
    temp = 20.0 + 2.0 * np.sin(np.linspace(0, 3, n))
    cols = [t, np.where(np.arange(n) > n // 4, 6000, 0), disp_scale * (3.1 - 6.0 * (temp - 20.0)),
            disp_scale * (1.5 * (temp - 20.0)), temp, 20.0 + 0.5 * (temp - 20.0)]
    head = header or "t_s,spindle_rpm,disp_z_um,disp_y_um,temp_spindle_c,temp_head_c"
    lines = [head]
    for i in range(n):
        cells = [f"{c[i]:.6g}" for c in cols]
        if blank and blank[0] == i + 1:
            cells[blank[1]] = ""
        lines.append(",".join(cells))
    path.write_text("\n".join(lines) + "\n")
    return path


def _notes(path, capsys) -> list[str]:
    capsys.readouterr()
    note_outside_travel(load_machine("xfyz"), [read_measurements(path)])
    return [ln for ln in capsys.readouterr().err.splitlines() if ln]


@pytest.mark.parametrize("column, meant, unit", [("disp_z_mm", "disp_z_um", "um"),
                                                 ("temp_head_F", "temp_head_c", "degC"),
                                                 ("temp_head_degf", "temp_head_c", "degC")])
def test_a_thermal_column_in_another_unit_is_refused_naming_it(tmp_path, capsys, column, meant, unit):
    head = "t_s,spindle_rpm,disp_z_um,disp_y_um,temp_spindle_c,temp_head_c".replace(meant, column)
    path = _record(tmp_path / "rec.csv", header=head)
    assert main(["diagnose", "xfyz", str(path), "--json", str(tmp_path / "r.json")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.endswith(f"rec.csv: row 0: column {column}: mtcomp reads "
                        f"{'displacement channel' if unit == 'um' else 'temperature sensor'} "
                        f"{meant.split('_')[1]} as {meant}, in {unit}, and does not read {column}; "
                        f"convert the values to {unit} and rename the column"), err
    assert len(err.splitlines()) == 1 and not (tmp_path / "r.json").exists()


def test_a_unit_column_beside_the_right_one_is_an_extra_column(tmp_path):
    path = _record(tmp_path / "rec.csv")
    text = path.read_text().splitlines()
    path.write_text("\n".join([text[0] + ",temp_head_f"] + [r + ",70" for r in text[1:]]) + "\n")
    assert set(read_measurements(path).context.temperatures) == {"spindle", "head"}


def test_a_time_that_goes_back_is_refused_at_its_row(tmp_path, capsys):
    t = np.concatenate([T_S[:500], [T_S[501], T_S[500]], T_S[502:]])
    path = _record(tmp_path / "rec.csv", t=t)
    assert main(["diagnose", "xfyz", str(path), "--json", str(tmp_path / "r.json")]) == 2
    err = capsys.readouterr().err.strip()
    assert "rec.csv: row 502: column t_s: 15000 s goes back from 15030 s in the row before: a " \
        "thermal record's readings are in time order" in err, err
    assert len(err.splitlines()) == 1 and not (tmp_path / "r.json").exists()


def test_a_repeated_time_is_read_and_noted_once(tmp_path, capsys):
    # a logger writing whole seconds that samples faster: rows 701 and 901 repeat the row before's t_s
    t = T_S.copy()
    t[700], t[900] = t[699], t[899]
    notes = _notes(_record(tmp_path / "rec.csv", t=t), capsys)
    assert notes == [f"note: {tmp_path / 'rec.csv'}: 2 reading(s) at the t_s of "
                     "the row before, the first at row 701 (t_s 20970): read in file order, as taken "
                     "within the logger's time resolution; if they are duplicated rows, remove them"]


def test_the_spindle_lag_holds_over_a_repeated_time():
    """By hand: h_k = h_(k-1) + (1 - exp(-dt / tau)) (u_(k-1) - h_(k-1)); dt 0 leaves h as it was,
    whatever the speed read at the repeated time."""
    from mtcomp.measurement.drift import spindle_heat
    a = 1.0 - np.exp(-10.0 / 900.0)
    h1 = a * 1.0
    want = [0.0, h1, h1, h1 + a * (3.0 - h1)]
    got = spindle_heat(np.array([0.0, 10.0, 10.0, 20.0]), np.array([1000, 1000, 3000, 3000.0]), 900.0)
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=0)


def test_a_temperature_in_degc_named_deg_c_is_read(tmp_path):
    head = "t_s,spindle_rpm,disp_z_um,disp_y_um,temp_spindle_deg_c,temp_head_c"
    data = read_measurements(_record(tmp_path / "rec.csv", header=head))
    assert set(data.context.temperatures) == {"spindle_deg", "head"}


def test_a_clean_record_gets_none_of_these_notes(tmp_path, capsys):
    assert _notes(_record(tmp_path / "rec.csv"), capsys) == []


def test_readings_in_mm_under_um_are_noted(tmp_path, capsys):
    # drift 12 um written in mm: 0.012 "um" from the first reading, below 0.05 um
    notes = _notes(_record(tmp_path / "rec.csv", disp_scale=1e-3), capsys)
    assert len(notes) == 1 and "every reading (disp_z_um, disp_y_um) stays within 0.012 um of " \
        "the first over 10 h, below 0.05 um" in notes[0], notes
    assert "written in mm under *_um columns? if so multiply them by 1000" in notes[0]


def test_times_in_hours_make_a_record_too_short_and_are_noted(tmp_path, capsys):
    notes = _notes(_record(tmp_path / "rec.csv", t=T_S / 3600.0), capsys)
    assert len(notes) == 1 and "the record spans 10 s (t_s 0 to 10), shorter than the heat flows " \
        "a drift model follows (900 s and more): was t_s written in hours or minutes?" in notes[0], notes


def test_a_gap_is_noted_with_its_time_and_length(tmp_path, capsys):
    t = np.concatenate([T_S[:241], T_S[360:]])          # 7200 s, then 10800 s: 1 h missing
    notes = _notes(_record(tmp_path / "rec.csv", t=t), capsys)
    assert len(notes) == 1 and "1 gap(s) in the record, the longest 3600 s (1 h) from t_s 7200 to " \
        "10800 (rows 241 to 242), against a step of 30 s" in notes[0], notes


def test_one_blank_temperature_cell_is_noted_at_its_row(tmp_path, capsys):
    notes = _notes(_record(tmp_path / "rec.csv", blank=(301, 5)), capsys)
    assert notes == [f"note: {tmp_path / 'rec.csv'}: column temp_head_c is blank "
                     "at row 301 (1 of 1201 readings): diagnose leaves a sensor out of the drift fit "
                     "unless every reading has it; fill the cell or remove the row to keep sensor head"]


# ------------------------------------------------------------------- predict and compensate
def _model(path):
    fitted = FittedModel.zero(ErrorModel(load_machine("xfyz").with_basis("polynomial"), [
        ThermalDrift("temperature", ("temp_spindle",), "Z", absolute=True, channels=("z",))]))
    fitted.params.set_file_value("TD_Z_temp_spindle", -2.0)      # um/degC
    fitted.params.set_file_value("TD_Z_zero", 44.0)
    fitted.info["context_ranges"] = {"temp_spindle": [20.0, 35.0]}
    fitted.uncertainty = {"names": ["TD_Z_temp_spindle", "TD_Z_zero"],
                          "covariance": np.diag([(0.1e-3) ** 2, (1e-3) ** 2]),
                          "undetermined": np.zeros((2, 0))}
    save_model(path, fitted)
    return path


def _day(path, temps, column="temp_spindle_c"):
    rows = [f"t_s,disp_z_um,{column}"] + [f"{3600 * i},1.0,{v}" for i, v in enumerate(temps)]
    path.write_text("\n".join(rows) + "\n")
    return path


def test_predict_notes_rows_beyond_the_record(tmp_path, capsys):
    temps = [19.0, 21.0, 30.0, 36.0, 40.0]                     # rows 1, 4, 5 outside 20..35
    model, day = _model(tmp_path / "m.json"), _day(tmp_path / "day2.csv", temps)
    assert main(["predict", "xfyz", str(model), str(day), "-o", str(tmp_path / "p.csv")]) == 0
    err = capsys.readouterr().err
    assert "day2.csv: 3 of 5 row(s) lie outside the thermal state the model's record spans " \
        "(spindle 3 row(s) at 19 to 40 degC against 20 to 35): the drift model carries on " \
        "linearly there, beyond what it saw; their standard errors take it to hold and do not size " \
        "that" in err, err
    got = np.genfromtxt(tmp_path / "p.csv", delimiter=",", names=True)
    T = np.array(temps)
    np.testing.assert_allclose(got["pred_disp_z_um"], 44.0 - 2.0 * T, rtol=0, atol=1e-9)
    # written on every row, as the covariance gives it (the note says what it does not cover)
    np.testing.assert_allclose(got["pred_disp_z_um_sd"], np.sqrt((0.1 * T) ** 2 + 1.0), rtol=1e-6, atol=0)


def test_predict_refuses_temperatures_in_degf(tmp_path, capsys):
    # 70, 80, 86 degF are 21.1, 26.7, 30 degC, inside the record's 20..35; read as degC all beyond it
    day = _day(tmp_path / "day2.csv", [34.0, 70.0, 80.0, 86.0])
    assert main(["predict", "xfyz", str(_model(tmp_path / "m.json")), str(day), "-o",
                 str(tmp_path / "p.csv")]) == 2
    err = capsys.readouterr().err.strip()
    assert err == (f"mtcomp predict: {day}: row 2: column temp_spindle_c: temperatures of sensor "
                   "spindle: 34 to 86 degC, median 75 degC, outside the range the model's thermal "
                   "record spans (20 to 35 degC); as degF their median would be 23.9 degC, inside it: "
                   "temperatures are in degC: refused (write them in degC: (F - 32) / 1.8)"), err
    assert not (tmp_path / "p.csv").exists()


@pytest.mark.parametrize("temps, hint", [([40.0, 45.0, 50.0], ""),        # as degF below 20 degC too
                                         ([25.0, 26.0, 27.0, 80.0, 86.0], "; as degF their median "
                                          "would be 28.3 degC, inside it: temperatures are in degC")])
def test_predict_notes_readings_beyond_the_record_that_are_no_degf_column(tmp_path, capsys, temps, hint):
    # beyond the record in degC and not a column in degF (median outside 20..35 both ways, or
    # inside it): extrapolation, predicted and noted, every note with the one prefix 'note: '
    temps = temps + [30.0] * (12 - len(temps))                    # 12 rows: the mm note too
    day = _day(tmp_path / "day2.csv", temps)
    assert main(["predict", "xfyz", str(_model(tmp_path / "m.json")), str(day), "-o",
                 str(tmp_path / "p.csv")]) == 0
    lines = capsys.readouterr().err.strip().splitlines()
    beyond = [t for t in temps if t > 35.0]
    assert f"note: {day}: {len(beyond)} of 12 row(s) lie outside the thermal state the model's record " \
        f"spans (spindle {len(beyond)} row(s) at {min(beyond):g} to {max(beyond):g} degC against 20 to " \
        f"35{hint}): " in "\n".join(lines), lines
    assert any("were the readings written in mm" in ln for ln in lines), lines
    assert all(ln.startswith("note: ") for ln in lines), lines
    got = np.genfromtxt(tmp_path / "p.csv", delimiter=",", names=True)
    np.testing.assert_allclose(got["pred_disp_z_um"], 44.0 - 2.0 * np.array(temps), rtol=0, atol=1e-9)


def test_predict_refuses_a_file_without_a_sensor_the_model_reads(tmp_path, capsys):
    day = _day(tmp_path / "day2.csv", [25.0, 26.0], column="temp_head_c")
    assert main(["predict", "xfyz", str(_model(tmp_path / "m.json")), str(day), "-o",
                 str(tmp_path / "p.csv")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.endswith("day2.csv: row 0: no column temp_spindle_c: the model's thermal drift reads "
                        "sensor(s) spindle (it reads spindle); give every sensor's readings, in degC"), err
    assert not (tmp_path / "p.csv").exists()


@pytest.mark.parametrize("readings, row", [("temp_spindle_c\n86\n", 1),
                                           ("t_s,temp_spindle_c\n0,25\n600,30\n1200,95\n", 3)])
def test_compensate_names_the_readings_file_and_row_beyond_the_record(tmp_path, capsys, readings, row):
    (tmp_path / "in.nc").write_text("G21 G90\nG0 X0 Y0 Z10\nG1 Z5 F500\nG1 X10\nM30\n")
    (tmp_path / "warm.csv").write_text(readings)
    assert main(["compensate", "xfyz", str(_model(tmp_path / "m.json")), str(tmp_path / "in.nc"),
                 "-o", str(tmp_path / "out.nc"), "-q", "--temperatures", str(tmp_path / "warm.csv")]) == 2
    err = capsys.readouterr().err.strip()
    value = "86" if row == 1 else "95"
    assert err.endswith(f"warm.csv: row {row}: column temp_spindle_c: temperature of sensor spindle: "
                        f"{value} degC is outside the range the model's thermal record spans (20 to 35 "
                        f"degC); as degF it would be {(float(value) - 32) / 1.8:.3g} degC, inside it: "
                        "temperatures are in degC: refused; give --extrapolate to correct beyond it"), err
    assert not (tmp_path / "out.nc").exists()

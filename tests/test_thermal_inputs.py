"""Thermal inputs a user gets wrong (docs/thermal.md, docs/measurements.md): a wrong input is refused
in one line naming the file, the row or column and the problem (exit 2, nothing written); a
suspicious one gets a one-line note saying what looks wrong and what to check.

Hand-made records: 30 s steps over 10 h, a drift of 12 um, sensors that move by a degree or two."""
from __future__ import annotations

import numpy as np
import pytest

from mtcomp import load_machine
from mtcomp.cli import main
from mtcomp.commands import note_outside_travel
from mtcomp.measurement.files import read_measurements

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
    note_outside_travel("diagnose", load_machine("xfyz"), [read_measurements(path)])
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


@pytest.mark.parametrize("swap, row, words", [
    (lambda t: np.concatenate([t[:500], [t[501], t[500]], t[502:]]), 502,
     "column t_s: 15000 s goes back from 15030 s in the row before"),
    (lambda t: np.concatenate([t[:700], [t[699]], t[701:]]), 701,
     "column t_s: 20970 s repeats the row before's")])
def test_a_time_that_goes_back_or_repeats_is_refused_at_its_row(tmp_path, capsys, swap, row, words):
    path = _record(tmp_path / "rec.csv", t=swap(T_S))
    assert main(["diagnose", "xfyz", str(path), "--json", str(tmp_path / "r.json")]) == 2
    err = capsys.readouterr().err.strip()
    assert f"rec.csv: row {row}: {words}: a thermal record's readings are in time order" in err, err
    assert not (tmp_path / "r.json").exists()


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
    assert notes == [f"mtcomp diagnose: note: {tmp_path / 'rec.csv'}: column temp_head_c is blank "
                     "at row 301 (1 of 1201 readings): diagnose leaves a sensor out of the drift fit "
                     "unless every reading has it; fill the cell or remove the row to keep sensor head"]

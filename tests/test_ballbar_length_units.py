"""A ball-bar file whose length_mm holds the deviation in um (what ball-bar software reports) is no
bar length: identify and diagnose refuse it in one line naming the row, where they took it and fitted
millimetre errors (a new user's model predicted 5 mm). predict takes any placeholder (0, blank) in
the column, as before. The nominal distance is hand-derived: balls 150 mm apart along X."""
from __future__ import annotations

import pytest

from mtcomp.cli import main

HEADER = ("x_mm,y_mm,z_mm,table_ball_x_mm,table_ball_y_mm,table_ball_z_mm,tool_ball_x_mm,"
          "tool_ball_y_mm,tool_ball_z_mm,length_mm\n")


def _file(path, lengths):
    rows = [(150.0, 0.0), (0.0, 150.0), (-150.0, 0.0), (0.0, -150.0)]
    path.write_text(HEADER + "".join(f"{x:g},{y:g},-100,0,0,-100,0,0,0,{v}\n"
                                     for (x, y), v in zip(rows, lengths)))


@pytest.mark.parametrize("command", ["identify", "diagnose"])
def test_a_deviation_in_um_under_length_mm_is_refused(tmp_path, capsys, command):
    _file(tmp_path / "bb.csv", ["150.0021", "150.0013", "2.9", "150.0008"])
    argv = [command, "xfyz", str(tmp_path / "bb.csv"), "-o", str(tmp_path / "m.json")]
    if command == "diagnose":
        argv += ["--json", str(tmp_path / "r.json"), "-q"]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "bb.csv: row 3: length_mm 2.9 is 147.1 mm from the distance of the " \
        "balls there (150.0000 mm)" in err[0]
    assert not (tmp_path / "m.json").exists() and not (tmp_path / "r.json").exists()


def test_lengths_within_a_millimetre_are_taken_and_predict_takes_placeholders(tmp_path, capsys):
    _file(tmp_path / "bb.csv", ["150.0021", "150.0013", "150.0009", "150.0008"])
    assert main(["identify", "xfyz", str(tmp_path / "bb.csv"), "-o", str(tmp_path / "m.json")]) == 0
    _file(tmp_path / "blank.csv", ["0", "", "0", ""])
    assert main(["predict", "xfyz", str(tmp_path / "m.json"), str(tmp_path / "blank.csv"), "-o",
                 str(tmp_path / "p.csv")]) == 0


def test_a_rotary_machine_names_its_axis_points_among_the_causes(tmp_path, capsys):
    """On a machine with rotary axes the balls' distance also rests on the axis points: a B axis
    point typed in metres made the bar's true length look wrong, and the message blamed only the
    length's unit. XFYZ has none to name (the test above: no 'axis_point_mm')."""
    _file(tmp_path / "bb.csv", ["150.0021", "150.0013", "2.9", "150.0008"])
    assert main(["identify", "cafxyz", str(tmp_path / "bb.csv"), "-o", str(tmp_path / "m.json")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "the row's ball positions or the machine file's axis_point_mm (in mm) " \
        "are off" in err[0]
    _file(tmp_path / "bb.csv", ["150.0021", "150.0013", "2.9", "150.0008"])
    assert main(["identify", "xfyz", str(tmp_path / "bb.csv"), "-o", str(tmp_path / "m.json")]) == 2
    err = capsys.readouterr().err
    assert "the row's ball positions are off" in err and "axis_point_mm" not in err

"""CSV files that are cut off, written with semicolons or decimal commas: refused in one line that
names the fix (mtcomp.io.csvtable, through every reader and the command line)."""
import pytest

from mtcomp import InputError
from mtcomp.cli import main
from mtcomp.measurement.files import read_measurements

HEADER = "axis,component,target_mm,dir,run,value_um"
ROWS = ["X,EXX,0,1,1,1.2500", "X,EXX,0,1,2,2.2500", "X,EXX,0,-1,1,3.0000", "X,EXX,0,-1,2,4.1250"]


def _write(tmp_path, text, name="laser.csv"):
    p = tmp_path / name
    p.write_text(text)
    return p


def _refused(path, pattern):
    with pytest.raises(InputError, match=pattern) as info:
        read_measurements(path)
    assert "\n" not in info.value.one_line()
    return info.value


def test_last_row_with_fewer_cells_is_a_cut_off_file(tmp_path):
    p = _write(tmp_path, "\n".join([HEADER] + ROWS[:3] + ["X,EXX,0,-1"]))
    err = _refused(p, r"row 4: 4 cells but the header has 6 columns in the last row: the file looks cut off")
    assert err.row == 4 and "re-export" in err.message
    # a short row in the middle is a ragged row, not a cut: the plain message
    p = _write(tmp_path, "\n".join([HEADER, ROWS[0], "X,EXX,0,1", *ROWS[1:]]) + "\n", "mid.csv")
    err = _refused(p, r"^.*row 2: 4 cells but the header has 6 columns")
    assert "cut off" not in err.message


def test_file_ending_mid_number_without_a_line_break(tmp_path):
    # every value has 4 decimals, the last one 1 and no line break follows: cut off mid-number
    cut = "\n".join([HEADER] + ROWS[:3] + ["X,EXX,0,-1,2,4.1"])
    err = _refused(_write(tmp_path, cut), r"row 4: .*'4\.1'.* the file looks cut off")
    assert "line break" in err.message
    # the same row ended by a line break is a complete file (the reader takes the writer's word)
    assert len(read_measurements(_write(tmp_path, cut + "\n", "ok.csv"))) == 4
    # a complete file without a final line break, and one whose values carry no fixed decimals
    assert len(read_measurements(_write(tmp_path, "\n".join([HEADER] + ROWS), "nolf.csv"))) == 4
    loose = "\n".join([HEADER, "X,EXX,0,1,1,1.25", "X,EXX,0,1,2,2", "X,EXX,0,-1,1,3.5", "X,EXX,0,-1,2,4"])
    assert len(read_measurements(_write(tmp_path, loose, "loose.csv"))) == 4
    # cut right after the last comma: a blank last cell where every other row has a value
    err = _refused(_write(tmp_path, "\n".join([HEADER] + ROWS[:3] + ["X,EXX,0,-1,2,"]), "c.csv"),
                   r"row 4: .*blank.*the file looks cut off")


@pytest.mark.parametrize("sep, name", [(";", "semicolons"), ("\t", "tabs")])
def test_semicolon_or_tab_separated_file_names_the_fix(tmp_path, sep, name):
    rows = [HEADER.replace(",", sep)] + [r.replace(",", sep).replace(".", ",") if sep == ";" else
                                         r.replace(",", sep) for r in ROWS]
    err = _refused(_write(tmp_path, "\n".join(rows) + "\n"), rf"row 0: .*separated by {name}")
    assert "comma separated" in err.message and "decimal point" in err.message


def test_decimal_commas_in_a_comma_separated_file(tmp_path):
    # unquoted: the number splits into two cells
    p = _write(tmp_path, "\n".join([HEADER, "X,EXX,0,1,1,1,25", *ROWS[1:]]) + "\n")
    _refused(p, r"row 1: 7 cells but the header has 6 columns.*decimal comma.*1\.5")
    # quoted: one cell that is not a number
    p = _write(tmp_path, "\n".join([HEADER, 'X,EXX,0,1,1,"1,25"', *ROWS[1:]]) + "\n", "q.csv")
    _refused(p, r"row 1: column value_um: '1,25' is not a number \(a decimal comma\? write 1\.25\)")


def test_cli_cut_off_file_one_line_exit_2(tmp_path, capsys):
    p = _write(tmp_path, "\n".join([HEADER] + ROWS[:3] + ["X,EXX,0,-1,2,4.1"]))
    out = tmp_path / "o.json"
    assert main(["iso230-2", str(p), "--json", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"mtcomp iso230-2: {p}: row 4: ") and "cut off" in err
    assert not out.exists()


def test_a_machine_or_model_file_given_as_measurements_is_named(tmp_path):
    """Read as CSV a machine file's first line passes for a header, and the message blamed a
    decimal comma in a row; a model file's JSON the same."""
    toml = _write(tmp_path, 'name = "vf2"\ntopology = "XFYZ"\n[axes.X]\ntravel_mm = [0, 500]\n',
                  "machine.toml")
    _refused(toml, r"a TOML file \(a machine file\?\), not a CSV measurement file")
    model = _write(tmp_path, '{\n  "format": "mtcomp-model",\n  "machine": {}\n}\n', "MODEL.json")
    _refused(model, r"a JSON file \(a model file\?\), not a CSV measurement file")


def test_a_model_file_given_as_the_machine_is_named(tmp_path, capsys):
    model = _write(tmp_path, '{\n  "format": "mtcomp-model"\n}\n', "MODEL.json")
    laser = _write(tmp_path, "\n".join([HEADER] + ROWS) + "\n")
    assert main(["identify", str(model), str(laser), "-o", str(tmp_path / "M.json")]) == 2
    err = capsys.readouterr().err
    assert "not valid TOML" in err and "it looks like a JSON file (a model file?)" in err
    assert not (tmp_path / "M.json").exists()


def test_report_lines_before_the_header_are_named(tmp_path):
    """An instrument's export with its report lines above the table (a laser software's title,
    date and machine): the title is read as a one-column header, and the message blamed a decimal
    comma."""
    p = _write(tmp_path, "Laser calibration X axis\n" + "\n".join([HEADER] + ROWS) + "\n")
    err = _refused(p, r"row 1: 6 cells but the header has 1 columns; the first line, read as the "
                      r"header, is one cell: a title")
    assert "decimal comma" not in err.message

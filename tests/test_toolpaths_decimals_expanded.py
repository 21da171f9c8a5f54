"""Computed words keep the decimals of the numbers they are computed from: a LinuxCNC or Fanuc
program's parameters and expressions are expanded into words with those decimals, and compensate
writes a corrected word with at least them (and at least 4 in mm, 5 in inch).

The expectations are counted by hand on hand-made programs. The compensation uses a model with one
term, EXX = 40 um per metre of X (``EXX_1 = 40``): the tip stands at x (1 + 40e-6), so the
corrected word is x / (1 + 40e-6), x (1 - 40e-6) to well below the last decimal written here."""
from __future__ import annotations

from pathlib import Path

import pytest

from mtcomp.cli import main
from mtcomp.toolpaths.expr import format_value
from mtcomp.toolpaths.source import open_program
from test_viz_inplane import exx  # noqa: F401  (the fixture: the EXX model)

#: an inch program whose moves are parameters and expressions of 6-decimal numbers
INCH = """G20 G90 G17
#<_depth> = -0.062500
#<_x0> = 2.000000
o100 sub
  G0 X[#1] Y[#2]
  G1 Z#<_depth> F12.0
  G1 X[#1 + 0.500000]
  G0 Z0.250000
o100 endsub
G0 X0.000000 Y0.000000 Z0.250000
o100 call [#<_x0>] [1.000000]
M2
"""


def _expanded(tmp_path, text, dialect="linuxcnc", name="in.ngc"):
    p = tmp_path / name
    p.write_text(text)
    with open_program(p, dialect) as src:
        assert src.expanded
        return Path(src.path).read_text().splitlines()[1:]


@pytest.fixture()
def exx_model(tmp_path, exx):
    """MODEL.json of the EXX model (written by the fixture of tests/test_viz_inplane.py)."""
    return tmp_path / "model.json"


def test_expanded_words_keep_the_decimals_of_their_numbers(tmp_path):
    lines = _expanded(tmp_path, INCH)
    assert [ln.strip() for ln in lines] == [
        "G20 G90 G17", "G0 X0.000000 Y0.000000 Z0.250000",
        "G0 X2.000000 Y1.000000", "G1 Z-0.062500 F12.0", "G1 X2.500000", "G0 Z0.250000", "M2"]


@pytest.mark.parametrize("expr, params, text", [
    ("[#1 * 2]", "#1 = 1.5", "3.0"),            # one decimal in 1.5
    ("[#1 / 3]", "#1 = 1.000", "0.333333"),     # more than the numbers have: up to 6
    ("[#1 + 0.25]", "#1 = 1", "1.25"),          # the literal's two
    ("[2 * 3]", "", "6"),                       # no decimals anywhere (LinuxCNC reads X6 as 6 mm)
    ("[#2]", "#1 = 1.00000000\n#2 = [#1 * 2]", "2.00000000"),   # through a parameter, 8 kept
    ("[-#1 + 0.1]", "#1 = 0.100", "0.000"),     # zero: no '-0'
])
def test_a_computed_word_has_the_most_decimals_of_what_it_reads(tmp_path, expr, params, text):
    lines = _expanded(tmp_path, f"G21 G90\n{params}\nG0 X{expr} Y0 Z5\nM2\n")
    assert lines[-2] == f"G0 X{text} Y0 Z5"


def test_a_computed_whole_dimension_has_a_point_and_other_words_do_not(tmp_path):
    """Fanuc reads a program's 'X6' as 6 least input increments (6 um in mm) and a macro variable
    of 6 in 'X#1' as 6 mm: the expanded word must say 'X6.'. A code, a tool, a dwell or a repeat
    count takes no point and no decimals, whatever its variable carries: Fanuc alarms on 'T3.'
    and Haas reads 'G4 P2.' as 2 s, 'G4 P2' as 2 ms; a drilling cycle's K is a repeat count, an
    arc's K a centre offset."""
    text = ("%\nO1000\nG21 G90\n#1 = 2\n#2 = 3\n#3 = 3.0\nG0 X[#1 * 3] Y#2 Z[#1] T#2\n"
            "T#3 M#3 H#3 S[#3 * 400]\nG4 P#3\nG81 X1. Y1. Z-#1 R1. K#3 F100.\nG80\n"
            "G18 G2 X0. Z0. I1. K#3\nM30\n%\n")
    lines = _expanded(tmp_path, text, "fanuc", "in.nc")
    assert "G0 X6. Y3. Z2. T3" in lines
    assert "T3 M3 H3 S1200" in lines
    assert "G4 P3" in lines
    assert "G81 X1. Y1. Z-2. R1. K3 F100." in lines
    assert "G18 G2 X0. Z0. I1. K3.0" in lines


def test_linuxcnc_codes_computed_from_decimals_take_no_point(tmp_path):
    text = "G21 G90\n#1 = 3.0\nT#1 M6\nG4 P#1\nG0 X[#1] Y0 Z5\nM2\n"
    lines = _expanded(tmp_path, text)
    assert lines[1:4] == ["T3 M6", "G4 P3", "G0 X3.0 Y0 Z5"]


def test_format_value_pads_to_the_decimals_asked():
    assert format_value(-0.0625, 6) == "-0.062500"
    assert format_value(1.0, 0) == "1"
    assert format_value(-1e-9, 3) == "0.000"
    assert format_value(0.1234567, 2) == "0.123457"


def test_fanuc_macro_variables_keep_their_decimals(tmp_path):
    text = "%\nO1000\nG21 G90\n#100 = 12.500\nG0 X#100 Y[#100 / 5] Z5.\nM30\n%\n"
    lines = _expanded(tmp_path, text, "fanuc", "in.nc")
    assert "G0 X12.500 Y2.500 Z5." in lines


def test_compensate_writes_computed_words_with_the_programs_decimals(tmp_path, exx_model):
    (tmp_path / "in.ngc").write_text(INCH)
    out = tmp_path / "out.ngc"
    assert main(["compensate", "xfyz", str(exx_model), str(tmp_path / "in.ngc"), "-o", str(out),
                 "--dialect", "linuxcnc"]) == 0
    lines = [ln.strip() for ln in out.read_text().splitlines()[1:]]
    # X 2 in and 2.5 in: 50.8 and 63.5 mm, tips off by 2.032 um (0.00008 in) and 2.54 um
    # (0.0001 in): X 1.99992 and 2.4999, written with the program's 6 decimals; Y and Z need no
    # correction and keep the expansion's spelling (6 decimals, not Z-0.0625)
    assert lines[2] == "G0 X1.999920 Y1.000000"
    assert lines[3] == "G1 Z-0.062500 F12.0"
    assert lines[4] == "G1 X2.499900"


def test_a_computed_word_without_decimals_is_written_with_at_least_4_in_mm(tmp_path, exx_model):
    (tmp_path / "in.ngc").write_text("G21 G90\n#1 = 100\nG0 X0 Y0 Z5\nG1 X[#1 / 4] F100\nM2\n")
    out = tmp_path / "out.ngc"
    assert main(["compensate", "xfyz", str(exx_model), str(tmp_path / "in.ngc"), "-o", str(out),
                 "--dialect", "linuxcnc"]) == 0
    # X 25 mm: the tip off by 1 um, written with 4 decimals (the expansion writes X25)
    assert out.read_text().splitlines()[-2] == "G1 X24.9990 F100"

"""compensate's summary counts every motion line it leaves uncorrected: the blocks the plan leaves
alone have their BLOCKS.csv rows (``unknown_axes`` ...), and the moves that are no block of the plan
(an incremental move of an axis whose position is not known, a home move, a move in machine
coordinates) are counted in a line of their own, by why, with their source line; and it says which
blocks were compensated in tool centre point mode and which code switched the mode on.

The expectations are counted by hand on the hand-made programs below (their lines numbered in the
comments)."""
from __future__ import annotations

import csv
import json

import pytest

from mtcomp.cli import main
from mtcomp.machine import load_machine
from mtcomp.models import ErrorModel, FittedModel, save_model
from mtcomp.toolpaths import _fast

#: a mm program: 4 motion lines that are no block (two blind increments, a home move, a G53 move)
PASSED = """G21 G90 G17
G0 X10 Y10 Z10
G1 X20 F100
T2 M6
G43 H2
G91 G0 Z-5
Z-1
G90 G0 Z10
G1 X30
G91 G28 Z0
G90 G53 G0 Z0
M30
"""
PASSED_LINE = ("4 motion lines passed through uncorrected, with no BLOCKS.csv row: 2 incremental "
               "(G91) moves of an axis whose position the program has not given (first at line 6: "
               "the controller moves it from wherever it stands); 1 move to the home position "
               "(G28/G30, grbl's $H; line 10); 1 move in machine coordinates (G53, line 11)")

#: LinuxCNC with a subroutine: the expanded program's lines are not the source's; the blind
#: increment is source line 9 (expanded line 7)
EXPANDED = """G20 G90
o100 sub
  G1 X#1 F10
o100 endsub
G0 X0 Y0 Z1
o100 call [1.0]
T2 M6
G43 H2
G91 G0 Z-0.25
G90 G0 Z1
M2
"""

#: tool centre point mode on a 5-axis machine: LinuxCNC's M428 at line 3, blocks on lines 4-6 (3),
#: off at line 7, on again at line 9 for line 10 (1 more)
TCP_M428 = """G21 G90
G0 X0 Y0 Z50 A0 C0
M428
G0 X10 Y0 Z20 A0 C0
G1 Z5 F500
G1 X20 C30
M429
G0 X0 Y0 Z50 A0 C0
M428 (again)
G0 X10 Y0 Z20 A0 C0
M429
M30
"""
#: Fanuc's G43.4 at line 5, on the line of no move, for the moves of lines 6 and 7
TCP_G434 = """%
O1000
G21 G90
G0 X0 Y0 Z50. A0 C0
G43.4 H1
G0 X10. Y0 Z20. A0 C0
G1 Z5. F500
G49
M30
%
"""


def _compensate(tmp_path, machine_name, text, capsys, *extra, name="in.nc"):
    machine = load_machine(machine_name).with_basis("polynomial")
    model = tmp_path / "model.json"
    if not model.exists():
        save_model(model, FittedModel.zero(ErrorModel(machine)))
    (tmp_path / name).write_text(text)
    assert main(["compensate", machine_name, str(model), str(tmp_path / name), "-o",
                 str(tmp_path / "out.nc"), "--report", str(tmp_path / "blocks.csv"), *extra]) == 0
    with open(tmp_path / "blocks.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    return capsys.readouterr().out.splitlines(), rows


@pytest.mark.parametrize("compiled", [True, False])
def test_moves_that_are_no_block_are_counted_with_their_lines(tmp_path, capsys, monkeypatch,
                                                             compiled):
    if not compiled:
        monkeypatch.setattr(_fast, "available", lambda: False)
    elif not _fast.available():
        pytest.skip("the compiled G-code scanner is not built here")
    out, rows = _compensate(tmp_path, "xfyz", PASSED, capsys)
    assert PASSED_LINE in out
    # the moves counted there have no row; every other motion line has its own
    assert [int(r["line"]) for r in rows] == [2, 3, 8, 9]
    # line 8 (Z after the tool change) gives Z again: every axis known, the block corrected
    assert [r["unknown_axes"] for r in rows] == ["", "", "", ""]


def test_the_summary_file_counts_them_by_why(tmp_path, capsys):
    _compensate(tmp_path, "xfyz", PASSED, capsys, "--json", str(tmp_path / "summary.json"))
    figures = json.loads((tmp_path / "summary.json").read_text())
    assert figures["passed_through_moves"] == {"increment": 2, "home": 1, "machine": 1}
    _compensate(tmp_path, "xfyz", "G21 G90\nG0 X1 Y1 Z1\nG1 X2 F100\nM30\n", capsys, "--json",
                str(tmp_path / "summary.json"))
    assert json.loads((tmp_path / "summary.json").read_text())["passed_through_moves"] == {}


def test_the_moves_are_named_by_their_source_lines_in_an_expanded_program(tmp_path, capsys):
    out, rows = _compensate(tmp_path, "xfyz", EXPANDED, capsys, "--dialect", "linuxcnc",
                            name="in.ngc")
    assert ("1 motion line passed through uncorrected, with no BLOCKS.csv row: 1 incremental (G91) "
            "move of an axis whose position the program has not given (line 9: the controller "
            "moves it from wherever it stands)") in out
    assert [int(r["line"]) for r in rows] == [5, 3, 10]


def test_grbl_homing_and_jogging_are_counted(tmp_path, capsys):
    text = "G21 G90\n$H\nG0 X1 Y1 Z1\n$J=G91 X5 F500\nG1 X2 F100\nM30\n"
    out, rows = _compensate(tmp_path, "xfyz", text, capsys, "--dialect", "grbl")
    assert ("2 motion lines passed through uncorrected, with no BLOCKS.csv row: 1 move to the home "
            "position (G28/G30, grbl's $H; line 2); 1 grbl jog ($J=, line 4)") in out
    # after the jog no axis is known: line 5 has its row, uncorrected, Y and Z unknown
    assert [(int(r["line"]), r["unknown_axes"]) for r in rows] == [(3, ""), (5, "YZ")]


def test_a_program_without_such_moves_has_no_such_line(tmp_path, capsys):
    out, _rows = _compensate(tmp_path, "xfyz", "G21 G90\nG0 X1 Y1 Z1\nG1 X2 F100\nM30\n", capsys)
    assert not any("passed through uncorrected" in line for line in out)
    assert not any("tool centre point" in line for line in out)


def test_tool_centre_point_blocks_are_counted_with_the_code_that_switched_the_mode_on(tmp_path,
                                                                                   capsys):
    out, rows = _compensate(tmp_path, "cafxyz", TCP_M428, capsys)
    assert ("4 blocks in tool centre point mode (M428 at line 3, M428 at line 9): tip positions "
            "and tool angles in the workpiece frame, compensated there and written so; the "
            "controller solves the kinematics") in out
    assert [int(r["line"]) for r in rows] == [2, 4, 5, 6, 8, 10]


def test_fanucs_g43_4_is_named_at_its_line(tmp_path, capsys):
    out, _rows = _compensate(tmp_path, "cafxyz", TCP_G434, capsys, "--dialect", "fanuc")
    assert any(line.startswith("2 blocks in tool centre point mode (G43.4 at line 5): ")
               for line in out)

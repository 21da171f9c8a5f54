"""A home move (G28, G30) or a move in machine coordinates (G53) in tool centre point mode.

LinuxCNC keeps the kinematics a program selected (M428) through a home move: G28 goes to the
stored position in the coordinates of the kinematics in force, and the mode stays (LinuxCNC
documentation, "Switchable Kinematics": the selection is cancelled only by the program). The move
passes through uncorrected and the axes it moves are not known afterwards, as in any program.
Fanuc's G43.4 mode at a home move is not determined here: refused in one line naming it."""
from __future__ import annotations

import pytest

from mtcomp.cli import main

FANUC = """%
O0001
G21 G90 G94 G17
G54
G43.4 H1
G0 X40. Y0. Z60. A-30. C0.
G1 Z20. F400.
{home}
G0 X10. Y5. Z30. A0. C0.
G49
M30
%
"""


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    from mtcomp.models import Backlash, save_model
    from test_export_formats import random_model
    path = tmp_path_factory.mktemp("model") / "model.json"
    save_model(path, random_model("cafxyz", (Backlash("X"),), 3, 1.0, None))
    return path


def _compensate(model, prog, out):
    return main(["compensate", "cafxyz", str(model), str(prog), "-o", str(out), "--quiet",
                 "--tool-length", "H1=100"])


@pytest.mark.parametrize("home, code", [("G91 G28 Z0.", "G28"), ("G30 Z80.", "G30"),
                                        ("G53 G0 Z0.", "G53")])
def test_a_home_move_in_fanuc_tcp_mode_is_refused_in_one_line(model, tmp_path, capsys, home, code):
    prog, out = tmp_path / "p.nc", tmp_path / "out.nc"
    prog.write_text(FANUC.format(home=home))
    assert _compensate(model, prog, out) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "Traceback" not in err[0]
    assert f"p.nc:8: {code} in tool centre point mode (G43.4) is not supported" in err[0]
    assert "G49" in err[0]
    assert not out.exists()


def test_the_mode_cancelled_before_the_home_move_is_read(model, tmp_path):
    prog, out = tmp_path / "p.nc", tmp_path / "out.nc"
    prog.write_text(FANUC.format(home="G49\nG91 G28 Z0.\nG90 G43.4 H1"))
    assert _compensate(model, prog, out) == 0
    assert "G91 G28 Z0.\n" in out.read_text()


def test_linuxcnc_keeps_its_kinematics_through_g28(model, tmp_path):
    """M428 ... G28 Z80 ...: the home move passes through as written and the blocks after it are
    tool centre point blocks still (their words corrected as tip and angles)."""
    prog, out = tmp_path / "p.ngc", tmp_path / "out.ngc"
    prog.write_text("G21 G90 G94 G17\nM428\nG0 X40 Y0 Z60 A-30 C0\nG1 Z20 F400\nG28 Z80\n"
                    "G0 X10 Y5 Z30 A0 C0\nG1 X20\nM429\nM30\n")
    assert _compensate(model, prog, out) == 0
    lines = out.read_text().splitlines()
    assert lines[4] == "G28 Z80"
    assert lines[5].startswith("G0 X10") and lines[5] != "G0 X10 Y5 Z30 A0 C0"    # corrected

"""Heidenhain conversational radius compensation (RL/RR on an L block, R0 off; TNC 640 User's
Manual) is put on the blocks as G41/G42 is, so an arc under it gets one correction for all its
nodes, a translation that its moved circle centre CC carries exactly, and the arc stays one C block.
The oracle samples the WRITTEN circle from the CC and C words and adds the model's error (a
backlash of X, which flips with X's direction around the circle) by hand."""
import contextlib
import csv
import io
import re

import numpy as np
import pytest

from mtcomp.cli import main
from mtcomp.machine import load_machine
from mtcomp.toolpaths import read_program
from mtcomp.toolpaths.heidenhain import translate
from test_planner_crc_arcs import check_written_circle
from test_planner_reversal_written import _model

CIRCLE = ("0 BEGIN PGM C MM\n1 TOOL CALL 1 Z S1000\n2 L X+140 Y-30 Z+5 R0 FMAX\n3 L Z-2 F100\n"
          "4 L X+150 Y+0 {on}F300\n5 CC X+180 Y+0\n6 C X+150 Y+0 DR-\n7 L X+140 Y-30 {off}\n"
          "8 L Z+5 FMAX\n9 L X+100\n10 END PGM C MM\n")
ARC_LINE = "7"          # the C block's line (1-based)


def _run(tmp_path, text, name="c", tol_um="1"):
    prog, out, rep = tmp_path / f"{name}.h", tmp_path / f"{name}_o.h", tmp_path / f"{name}.csv"
    prog.write_text(text)
    assert main(["compensate", "xfyz", str(_model(tmp_path)), str(prog), "-o", str(out), "--report",
                 str(rep), "--chord-tol-um", tol_um, "--quiet"]) == 0
    with open(rep, newline="") as f:
        rows = list(csv.DictReader(f))
    return out.read_text().splitlines(), rows


def _written_circle(lines):
    """(start (2,), centre (2,)) of the written full circle C, from the written CC and the X Y
    written before it (absolute words only, as in CIRCLE)."""
    pos, centre = {}, None
    for line in lines:
        words = {k: float(v.replace(" ", "")) for k, v in
                 re.findall(r"(?<![A-Z])([XY])\s*([+-]?[\d.]+)", line.split(";")[0])}
        body = line.split(maxsplit=1)[1] if " " in line else ""
        if body.startswith("CC "):
            centre = np.array([words["X"], words["Y"]])
        elif body.startswith("C "):
            assert words == {"X": pos["X"], "Y": pos["Y"]}      # a full circle still
            return np.array([pos["X"], pos["Y"]]), centre
        elif body.startswith("L "):
            pos.update(words)
    raise AssertionError("no C block written")


def test_rl_and_rr_are_read_as_g41_g42_where_they_switch(tmp_path):
    """RL/RR/R0 become G41/G42/G40 on the lines where they change what is in force; repeated
    words and R0 while none is in force add nothing."""
    text = ("0 BEGIN PGM C MM\n1 L X+0 Y+0 Z+5 R0 FMAX\n2 L X+10 RR F100\n3 L X+20 RR\n"
            "4 L X+30 RL\n5 L Y+10\n6 L X+0 R0\n7 L R0 F200\n8 END PGM C MM\n")
    p = tmp_path / "r.h"
    p.write_text(text)
    g = translate(p).gcode
    blocks = read_program(p, load_machine("xfyz")).blocks
    assert g[1:8] == ["G0 X0 Y0 Z5", "G42 G1 X10 F100", "G1 X20", "G41 G1 X30", "G1 Y10",
                      "G40 G1 X0", "F200"]
    assert {b.line: b.cutter_comp for b in blocks} == {2: False, 3: True, 4: True, 5: True,
                                                       6: True, 7: True}


def test_a_switch_on_an_arc_is_refused_in_one_line(tmp_path):
    p = tmp_path / "a.h"
    p.write_text("0 BEGIN PGM C MM\n1 L X+0 Y+0 Z+5 FMAX\n2 CC X+5 Y+0\n3 C X+10 Y+0 DR- RL\n"
                 "4 END PGM C MM\n")
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        assert main(["compensate", "xfyz", str(_model(tmp_path)), str(p), "-o",
                     str(tmp_path / "o.h"), "--quiet"]) == 2
    lines = err.getvalue().strip().splitlines()
    assert len(lines) == 1 and "a.h:4" in lines[0] and "RL switched on an arc C" in lines[0]
    assert not (tmp_path / "o.h").exists()


@pytest.mark.parametrize("on", ["RL ", "RR "])
def test_a_circle_under_rl_rr_is_written_as_planned_and_never_worse(tmp_path, on):
    lines, rows = _run(tmp_path, CIRCLE.format(on=on, off="R0 "))
    start, centre = _written_circle(lines)
    check_written_circle(start, centre, rows, ARC_LINE, "5")


def test_without_radius_compensation_the_circle_is_corrected_piecewise(tmp_path):
    """The same circle without RL: its nodes corrected one by one (the tie is only under RL/RR),
    so one moved CC holds it only within a wide tolerance."""
    lines, rows = _run(tmp_path, CIRCLE.format(on="", off=""), "plain", tol_um="40")
    arc = [row for row in rows if row["line"] == ARC_LINE]
    assert len({row["cx_um"] for row in arc}) > 1
    assert not any("arc_" in row["active_bounds"] for row in rows)

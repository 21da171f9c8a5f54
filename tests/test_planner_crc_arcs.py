"""Under cutter radius compensation (G41/G42) the writer keeps every arc one arc (the controller
offsets it as written), so the planner plans what one arc can carry: one correction for all of an
arc's nodes, a translation, written exactly. The oracle samples the WRITTEN circle from its words
and adds the model's error (a backlash of X, which flips with X's direction around the circle) by
hand."""
import csv
import math
import os
import re

import numpy as np
import pytest

from mtcomp.cli import main
from test_planner_reversal_written import BL_UM, _model

CIRCLE = ("G21 G90 G17 G54\nG0 X140 Y-30 Z5\nG1 Z-2 F100\n{on}G1 X150 Y0 F300\n"
          "G2 X150 Y0 I30 J0\n{off}G1 X140 Y-30\nG0 Z5\nG1 X100\nM2\n")
CENTRE, RADIUS = (180.0, 0.0), 30.0


def _run(tmp_path, text, name="c"):
    prog, out, rep = tmp_path / f"{name}.ngc", tmp_path / f"{name}_o.ngc", tmp_path / f"{name}.csv"
    prog.write_text(text)
    assert main(["compensate", "xfyz", str(_model(tmp_path)), str(prog), "-o", str(out), "--report",
                 str(rep), "--chord-tol-um", "1", "--quiet"]) == 0
    with open(rep, newline="") as f:
        rows = list(csv.DictReader(f))
    return out.read_text().splitlines(), rows


def _written_circle(lines):
    """(start, centre, end) of the written G2 line, from its words and the written point before."""
    pos = {}
    for line in lines:
        words = dict(re.findall(r"([XYIJ])(-?[\d.]+)", line.upper()))
        if re.match(r"G0*2(?![\d.])", line.upper()):
            start = np.array([pos["X"], pos["Y"]])
            centre = start + [float(words.get("I", 0.0)), float(words.get("J", 0.0))]
            end = np.array([float(words.get("X", pos["X"])), float(words.get("Y", pos["Y"]))])
            return start, centre, end
        pos.update({k: float(v) for k, v in words.items() if k in "XY"})
    raise AssertionError("no G2 line written")


def test_a_g41_circle_is_written_as_planned_and_never_worse(tmp_path):
    lines, rows = _run(tmp_path, CIRCLE.format(on="G41 D1 ", off="G40 "))
    start, centre, end = _written_circle(lines)
    np.testing.assert_allclose(end, start, rtol=0, atol=1e-9)          # still a full circle
    check_written_circle(start, centre, rows, "5", "4")


def check_written_circle(start, centre, rows, arc_line, entry_line):
    """The written full circle (start, centre (2,) mm) of the arc of line ``arc_line`` against
    the plan (its corrected points on it) and the oracle (never worse than the backlash alone,
    one correction along the arc, the tie named in the bounds)."""
    r = float(np.hypot(*(start - centre)))
    # the plan's corrected points of the arc lie on the written circle (within the chord tolerance)
    arc = [row for row in rows if row["line"] == arc_line]
    pts = np.array([[float(row["x_mm"]), float(row["y_mm"])] for row in arc])
    miss_um = np.abs(np.hypot(*(pts - centre).T) - r) * 1e3
    assert miss_um.max() <= 1.0, miss_um.max()
    # the oracle's sign from the entry move (+X: the backlash's + half): before = s * BL/2 * d_x
    entry = next(row for row in rows if row["line"] == entry_line)
    s = math.copysign(1.0, float(entry["ex_before_um"]))
    assert abs(float(entry["ex_before_um"])) == pytest.approx(BL_UM / 2, abs=1e-6)
    # the written circle sampled (clockwise from its start), each sample paired with the nominal
    # circle's point at the same angle; X's direction there is that of the clockwise motion
    a0 = math.atan2(start[1] - centre[1], start[0] - centre[0])
    theta = a0 - (np.arange(720) + 0.37) / 720 * 2 * np.pi
    written = centre + r * np.c_[np.cos(theta), np.sin(theta)]
    nominal = np.array(CENTRE) + RADIUS * np.c_[np.cos(theta), np.sin(theta)]
    d_x = np.sign(np.sin(theta))
    c_um = (written - nominal) * 1e3
    before_x = s * BL_UM / 2 * d_x
    after_x = s * (c_um[:, 0] + BL_UM / 2 * d_x)
    assert np.all(np.abs(after_x) <= np.abs(before_x) + 0.1), np.max(np.abs(after_x) - np.abs(before_x))
    # Y has no error: the written circle does not move it off either
    assert np.all(np.abs(c_um[:, 1]) <= 0.1), np.max(np.abs(c_um[:, 1]))
    # one correction along the arc, named by the rule where it took something away
    cx = {(row["cx_um"], row["cy_um"]) for row in arc}
    assert len(cx) == 1
    assert any("arc_x" in row["active_bounds"] for row in arc)


def test_without_cutter_compensation_the_circle_is_corrected_piecewise(tmp_path):
    """The same circle without G41: pieces, each corrected (the tie is only for G41/G42)."""
    lines, rows = _run(tmp_path, CIRCLE.format(on="", off=""), "plain")
    arc = [row for row in rows if row["line"] == "5"]
    assert len({row["cx_um"] for row in arc}) > 1
    assert not any("arc_" in row["active_bounds"] for row in rows)


def _both_readers(p, m, monkeypatch):
    """The program's segments as the compiled and the Python reader read them."""
    from mtcomp.toolpaths import gcode
    from mtcomp.toolpaths.source import open_program
    chunks = []
    for fast in (True, False):
        if fast:
            monkeypatch.delenv("MTCOMP_NO_FAST_GCODE", raising=False)
        else:
            monkeypatch.setenv("MTCOMP_NO_FAST_GCODE", "1")
        with open_program(p, None) as src:
            chunks.append(gcode.SegmentChunk.concatenate(list(gcode.iter_segment_chunks(src, m)), 3))
    return chunks


def test_blocks_carry_cutter_compensation(tmp_path, monkeypatch):
    """The reader puts G41/G42 on the blocks (in force, or switched on or off by the line itself,
    as the writer keeps them whole), and the compiled and the Python readers agree."""
    from mtcomp.machine import load_machine
    from mtcomp.toolpaths import gcode
    p = tmp_path / "c.ngc"
    p.write_text(CIRCLE.format(on="G41 D1 ", off="G40 "))
    m = load_machine("xfyz")
    blocks = gcode.read_program(p, m).blocks
    assert [b.cutter_comp for b in blocks] == [False, False, True, True, True, False, False]
    fast, slow = _both_readers(p, m, monkeypatch)
    np.testing.assert_array_equal(fast.cutter_comp, slow.cutter_comp)
    assert fast.cutter_comp[fast.from_arc].all() and not fast.cutter_comp[fast.line == 8].any()
    # plain feed lines under G41 (lines 5 and 6), which the compiled scanner reads itself
    p.write_text("G21 G90 G17 G54\nG0 X140 Y-30 Z5\nG1 Z-2 F100\nG41 D1 G1 X150 Y0 F300\n"
                 "G1 X150 Y10\nG1 X160 Y10\nG40 G1 X140 Y-30\nG0 Z5\nM2\n")
    for c in _both_readers(p, m, monkeypatch):
        assert c.cutter_comp[np.isin(c.line, [4, 5, 6, 7])].all()
        assert not c.cutter_comp[np.isin(c.line, [2, 3, 8])].any()
    assert os.environ.get("MTCOMP_NO_FAST_GCODE") == "1"

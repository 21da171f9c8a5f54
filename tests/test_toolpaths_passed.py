"""The moves passed through as written with their end known (mtcomp/toolpaths/passed.py): an arc
from a position the program has not given, a G5 spline, Fanuc's G60. The block after one starts
from its written end, where the output stands uncorrected, not from the end of the block before
it: its first row is a jump (no node on a line from the block before), and the output's move is
the input's from that end to the block's end plus the block's correction, along the same line.

The oracle is the input's geometry: each point written for the block after must lie on the input's
segment from the passed move's end to the block's end, within the correction bound (0.05 mm here);
a node on the line from the block before the passed move lies hundreds of mm off it."""
from __future__ import annotations

import csv
import re

import numpy as np
import pytest

from mtcomp.cli import main
from mtcomp.machine import load_machine
from mtcomp.toolpaths import iter_segment_chunks
from mtcomp.toolpaths.source import open_program
from test_gcode_corpus import _machine_file, _model_file
from test_toolpaths_dialect import mode  # noqa: F401  (the fixture: both reader paths)

#: a long cut to (800, 300), the passed move to (-300, -400), then a cut along Y = -400 (line 5)
HEAD = "G21 G90 G17\nG0 X10. Y5. Z20.\nG01 X800. Y300. F100\n"
CASES = {
    "g60": ("fanuc", HEAD + "G60 G00 X-300. Y-400.\nG01 X900. Y-400. F100\nM30\n"),
    "spline": ("linuxcnc", HEAD + "G5 X-300. Y-400. I1 J1 P1 Q1\nG01 X900. Y-400. F100\nM30\n"),
    # X and Y not given before the arc (the first move is Z): the arc runs from wherever they stand
    "arc": ("fanuc", "G21 G90 G17\nG0 Z20.\nG01 Z10. F100\nG02 X-300. Y-400. R2000.\n"
                     "G01 X900. Y-400. F100\nM30\n"),
}
LINE_AFTER = {"g60": 5, "spline": 5, "arc": 5}


@pytest.mark.parametrize("case", sorted(CASES))
def test_the_row_after_a_passed_move_starts_at_its_end(tmp_path, mode, case):
    dialect, text = CASES[case]
    p = tmp_path / "p.nc"
    p.write_text(text)
    with open_program(p, dialect) as src:
        chunks = list(iter_segment_chunks(src, load_machine("xfyz")))
    line = np.concatenate([c.line for c in chunks])
    start = np.vstack([c.start for c in chunks])
    jump = np.concatenate([c.jump for c in chunks])
    r = int(np.flatnonzero(line == LINE_AFTER[case])[0])
    np.testing.assert_allclose(start[r, :2], [-300.0, -400.0], rtol=0, atol=1e-12)
    assert jump[r], "the row after the passed move is planned as if it came from the row before"


def _points(lines: list, after: int):
    """(x, y) at the end of each output line after index ``after`` (the X and Y words carried
    over), up to the program's end."""
    x = y = np.nan
    out = []
    for k, ln in enumerate(lines):
        if ln == "M30":
            break
        m = re.search(r"X(-?[\d.]+)", ln)
        x = float(m.group(1)) if m else x
        m = re.search(r"Y(-?[\d.]+)", ln)
        y = float(m.group(1)) if m else y
        if k > after:
            out.append((x, y))
    return np.array(out)


@pytest.mark.parametrize("case", sorted(CASES))
def test_the_block_after_a_passed_move_is_written_along_its_own_path(tmp_path, case):
    dialect, text = CASES[case]
    machine = _machine_file(tmp_path, "XFYZ")
    model = _model_file(tmp_path, machine, factor=30.0)     # tens of um, varying along the cut
    (tmp_path / "p.nc").write_text(text)
    assert main(["compensate", str(machine), str(model), str(tmp_path / "p.nc"), "-o",
                 str(tmp_path / "o.nc"), "--report", str(tmp_path / "r.csv"), "--dialect",
                 dialect, "--units", "mm", "--quiet"]) == 0
    out = (tmp_path / "o.nc").read_text().splitlines()
    # the passed move as written, and the block after it (its pieces) from there
    passed = text.splitlines()[LINE_AFTER[case] - 2]
    assert out.count(passed) == 1
    pts = _points(out, out.index(passed))
    assert len(pts) >= 1
    # on the input's segment from (-300, -400) to (900, -400), within the correction bound
    assert np.all(np.abs(pts[:, 1] + 400.0) <= 0.05), pts
    assert np.all((pts[:, 0] >= -300.05) & (pts[:, 0] <= 900.05)), pts
    # its end is the input's plus the block's correction (BLOCKS.csv), to the output's 0.1 um grid
    with open(tmp_path / "r.csv") as f:
        rows = [r for r in csv.DictReader(f) if int(r["line"]) == LINE_AFTER[case]]
    c = np.array([float(rows[-1]["cx_um"]), float(rows[-1]["cy_um"])]) * 1e-3
    np.testing.assert_allclose(pts[-1], np.array([900.0, -400.0]) + c, rtol=0, atol=1.01e-4)

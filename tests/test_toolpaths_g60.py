"""Fanuc's G60, single-direction positioning: the line passes through uncorrected, its end the
written point (the axes known there, in the output too), the named axes' approach direction unknown
after it (parameter No. 5440 sets it, not the program). Hand-derived ends, output lines and
directions under a constant correction; each refusal through the command line."""
from __future__ import annotations

import numpy as np
import pytest

from mtcomp.toolpaths import iter_segment_chunks
from mtcomp.toolpaths.source import open_program
from test_compensate_cli import _model, _run
from test_toolpaths_dialect import mode  # noqa: F401  (the fixture: both reader paths)
from test_toolpaths_frames import XFYZ, _constant, _corrected

PROGRAM = "G21 G90 G17\nG0 X10. Y5. Z20.\nG01 X12. F100\nG60 G00 X-3. Y4.\nX6.\nY2.\nM30\n"


def test_g60_passes_through_its_end_known(tmp_path, mode):
    """The G60 line is written as it is and is no row; the rows after it start from its end
    (-3, 4): X6 is a rapid from there, and the output, standing at the written Y4 (uncorrected),
    gets Y's correction written back with X's."""
    ends, known, out = _corrected(tmp_path, PROGRAM, "fanuc", _constant([0.001, 0.002, 0.003]))
    np.testing.assert_allclose(ends, [[10, 5, 20], [12, 5, 20], [6, 4, 20], [6, 2, 20]],
                               rtol=0, atol=1e-12)
    assert known.all()
    assert out[3] == "G60 G00 X-3. Y4.", out
    assert out[4:6] == ["X6.0010 Y4.0020", "Y2.0020"], out


def test_g60_leaves_the_approach_direction_unknown(tmp_path, mode):
    """The row X6 after G60 X-3. Y4.: X moves + (from -3 to 6); Y stands, and its last approach
    was G60's, the control's parameter: unknown (0), not the -1 of its move from 5 to 4. The row
    Y2 after it: X stands, its last move + (into X6); Y moves - (from 4 to 2)."""
    p = tmp_path / "p.nc"
    p.write_text(PROGRAM)
    with open_program(p, "fanuc") as src:
        dirs = np.vstack([c.dirs for c in iter_segment_chunks(src, XFYZ)])
    np.testing.assert_array_equal(dirs[2, :2], [1, 0])
    np.testing.assert_array_equal(dirs[3, :2], [1, -1])


def test_compensate_counts_the_g60_line(tmp_path, capsys):
    _, _, model = _model(tmp_path, "xfyz", seed=5)
    p, out = tmp_path / "p.nc", tmp_path / "o.nc"
    p.write_text(PROGRAM)
    code, stdout, err = _run(["compensate", "xfyz", str(model), str(p), "-o", str(out),
                              "--dialect", "fanuc"], capsys)
    assert code == 0, err
    assert "1 single-direction positioning (Fanuc G60, line 4" in stdout, stdout
    assert out.read_text().splitlines()[3] == "G60 G00 X-3. Y4."


@pytest.mark.parametrize("dialect, body, line, words", [
    ("fanuc", "G60 G01 X1. F100\n", 3, "G60 (single-direction positioning) with motion G1"),
    ("fanuc", "G81 Z-1. R1. F100\nG60 X1.\n", 4, "G60 (single-direction positioning) in a drilling"),
    ("fanuc", "G60 G53 X1.\n", 3, "G60 (single-direction positioning) with G53"),
    # no motion code after G60: G60 may be modal (parameter No. 5431#0), so no mode is in force
    ("fanuc", "G60 X1. Y1.\nX2.\n", 4, "coordinates without a motion mode"),
    ("fanuc", "G00 G60 X1. Y1.\nX2.\n", 4, "coordinates without a motion mode"),
    ("haas", "G60 G00 X1.\n", 3, "G60 is not a code mtcomp follows"),
])
def test_g60_refusals(tmp_path, capsys, dialect, body, line, words):
    _, _, model = _model(tmp_path, "xfyz", seed=5)
    p, out = tmp_path / "p.nc", tmp_path / "o.nc"
    p.write_text("G21 G90 G17\nG0 X0 Y0 Z5.\n" + body + "M30\n")
    code, _o, err = _run(["compensate", "xfyz", str(model), str(p), "-o", str(out), "--quiet",
                          "--dialect", dialect], capsys)
    assert code == 2 and f"p.nc:{line}:" in err and words in err, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err and not out.exists()

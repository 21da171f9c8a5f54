"""G codes of different groups in one block, as Fanuc and Haas read them: a home move with a motion
code (`G00 G91 G28 Z0`: the home move, then G0 the mode of the blocks after it), and a frame code
with a motion code but no axis word (`G0 G50`: nothing moves, the mode is set). RS274/NGC
(LinuxCNC, grbl) refuses the first (two codes that use the axis words)."""
from __future__ import annotations

import numpy as np
import pytest

from test_compensate_cli import _model, _run
from test_toolpaths_dialect import mode  # noqa: F401  (the fixture: both reader paths)
from test_toolpaths_frames import _constant, _corrected

HOME = "G21 G90 G17\nG0 X10. Y5. Z20.\nG01 X12. F100\nG00 G91 G28 Z0\nG90 X15.\nY8.\nM30\n"


@pytest.mark.parametrize("dialect", ["fanuc", "haas"])
def test_a_home_move_with_g0_homes_z_and_leaves_g0_in_force(tmp_path, mode, dialect):
    """After `G00 G91 G28 Z0` Z is at home (unknown to the program: never written) and the blocks
    after it, X15 and Y8 at rapid, are not corrected (a block with an axis the program has not
    given is not); Y, corrected before, is written back to its value (the machine stood off by
    its correction)."""
    ends, known, out = _corrected(tmp_path, HOME, dialect, _constant([0.001, 0.002, 0.003]))
    body = [ln for ln in out if ln.startswith(("G90 X", "Y8"))]
    assert body == ["G90 X15. Y5.0000", "Y8."], out
    assert "G00 G91 G28 Z0" in out
    # the rows after the home move: X and Y known, Z not
    np.testing.assert_array_equal(known[-2:], [[True, True, False]] * 2)
    np.testing.assert_allclose(ends[-2:, :2], [[15.0, 5.0], [15.0, 8.0]], rtol=0, atol=0)


def test_the_mode_after_it_is_g0(tmp_path, capsys):
    """compensate's BLOCKS.csv: the block after `G00 G91 G28 Z0` is a rapid (the G01 before it is
    no longer in force)."""
    import csv
    _, _, model = _model(tmp_path, "xfyz", seed=5)
    p, out, rep = tmp_path / "p.nc", tmp_path / "o.nc", tmp_path / "b.csv"
    p.write_text(HOME)
    code, _o, err = _run(["compensate", "xfyz", str(model), str(p), "-o", str(out), "--quiet",
                          "--dialect", "fanuc", "--report", str(rep)], capsys)
    assert code == 0, err
    with open(rep, newline="") as f:
        rows = {r["line"]: r for r in csv.DictReader(f)}
    assert rows["3"]["rapid"] == "0" and rows["5"]["rapid"] == "1" and rows["6"]["rapid"] == "1"


@pytest.mark.parametrize("dialect", ["linuxcnc", "grbl"])
def test_rs274ngc_refuses_a_home_move_with_a_motion_code(tmp_path, capsys, dialect):
    _, _, model = _model(tmp_path, "xfyz", seed=5)
    p, out = tmp_path / "p.nc", tmp_path / "o.nc"
    p.write_text(HOME)
    code, _o, err = _run(["compensate", "xfyz", str(model), str(p), "-o", str(out), "--quiet",
                          "--dialect", dialect], capsys)
    assert code == 2 and "p.nc:4:" in err and "G28 and motion G0 in one block" in err
    assert len(err.strip().splitlines()) == 1 and not out.exists()


def _rapid_per_line(tmp_path, text, dialect) -> dict:
    """source line -> whether its move is a rapid, as the reader reads it."""
    from mtcomp.machine import load_machine
    from mtcomp.toolpaths import iter_segment_chunks
    from mtcomp.toolpaths.source import open_program
    p = tmp_path / "r.nc"
    p.write_text(text)
    out = {}
    with open_program(p, dialect) as src:
        for chunk in iter_segment_chunks(src, load_machine("xfyz")):
            out.update({int(ln): bool(r) for ln, r in zip(chunk.line, chunk.rapid)})
    return out


def test_a_frame_code_with_a_motion_code_and_no_axis_word_sets_the_mode(tmp_path, mode):
    """`G0 G50 G90` (Fanuc: scaling off; a header line of many posts): no move; the next block
    `X5. Y5.` moves at rapid. With an axis word (`G0 X1. G50`) it stays refused."""
    text = "G21 G90 G17\nG0 X0 Y0 Z5.\nG1 X1. F100\nG0 G50 G90\nX5. Y5.\nM30\n"
    ends, known, out = _corrected(tmp_path, text, "fanuc", _constant([0.001, 0, 0]))
    assert "G0 G50 G90" in out and "X5.0010 Y5." in out
    np.testing.assert_allclose(ends[-1], [5.0, 5.0, 5.0], rtol=0, atol=0)
    assert _rapid_per_line(tmp_path, text, "fanuc") == {2: True, 3: False, 5: True}
    with pytest.raises(Exception, match="G50 and a move in one block"):
        _corrected(tmp_path, text.replace("G0 G50 G90", "G0 X1. G50"), "fanuc",
                   _constant([0.001, 0, 0]), name="q")


# ------------------------------------------------------------------ Fanuc's G74 and G76 cycles
CYCLE = ("O1000\nG21 G90 G17 G54\nG0 X10. Y5. Z20.\nZ3.\nG99 {code} Z-5. R2. F200.\nX30. Y8.\n"
         "G98 X40. Y-4.\nG80\nM30\n")


@pytest.mark.parametrize("dialect", ["fanuc", "haas"])
@pytest.mark.parametrize("code, twin", [("G76", "G86"), ("G74", "G84")])
def test_fanuc_g74_and_g76_are_drilling_cycles_like_g84_and_g86(tmp_path, mode, dialect, code, twin):
    """G76 fine boring and G74 left-hand tapping have the holes of G86 and G84 (from R to Z at X Y):
    the program with them is compensated exactly as the same program with G86 / G84, line for
    line but the G code (a second formulation), its holes corrected."""
    correction = _constant([0.002, -0.001, 0.003])
    ends, known, out = _corrected(tmp_path, CYCLE.format(code=code), dialect, correction, name="a")
    ends2, known2, out2 = _corrected(tmp_path, CYCLE.format(code=twin), dialect, correction, name="b")
    np.testing.assert_array_equal(ends, ends2)
    np.testing.assert_array_equal(known, known2)
    assert [ln.replace(code, twin) for ln in out] == out2
    assert f"G99 {code} Z-4.9970 R2.0030 F200." in out and "X30.0020 Y7.9990" in out


@pytest.mark.parametrize("code", ["G74", "G76"])
def test_g74_and_g76_are_refused_where_they_mean_something_else(tmp_path, capsys, code):
    _, _, model = _model(tmp_path, "xfyz", seed=5)
    p, out = tmp_path / "p.nc", tmp_path / "o.nc"
    p.write_text(CYCLE.format(code=code))
    rc, _o, err = _run(["compensate", "xfyz", str(model), str(p), "-o", str(out), "--quiet",
                        "--dialect", "linuxcnc"], capsys)
    assert rc == 2 and "p.nc:5:" in err and f"canned cycle {code}" in err and not out.exists()


def test_a_cycle_passed_through_leaves_the_block_before_where_it_was(tmp_path, mode):
    """A back boring G87 is passed through uncorrected; the block before it (Z3.) keeps its own
    end, X15.114 Y0.143 (the pure-Python reader moved it to the next hole's X Y, by changing the
    position it held in place)."""
    text = "O1000\nG21 G90 G54\nG0 X15.114 Y.143\nZ3.\nG99 G87 Z-5. R3. F250.\nX9.977 Y-6.803\nG80\nM30\n"
    ends, known, out = _corrected(tmp_path, text, "fanuc", _constant([0.001, 0.002, 0.003]))
    np.testing.assert_allclose(ends[:2], [[15.114, 0.143, 0.0], [15.114, 0.143, 3.0]], rtol=0,
                               atol=1e-12)
    # its correction (the first block, Z unknown, has none): X and Y stated beside Z
    assert out[3] == "Z3.0030 X15.1150 Y0.1450", out

"""A full circle of zero radius about its own start (``G3 X30.42 Y26.924 I0``, what Eagle's
stepcraft post writes for a hole smaller than the tool): a block that does not move. Read on both
reader paths as one row from the tool's position to itself, with the approach directions and the
feed of the move before it; written with the same correction as the position the tool is at
(hand-derived from a model of one linear positioning error); refused under LinuxCNC, which
refuses it, and wherever it would move (an end off its start, a zero R, a helix)."""
import re

import numpy as np
import pytest

from mtcomp.cli import main
from mtcomp.errors import InputError
from mtcomp.machine import load_machine
from mtcomp.models import ErrorModel, FittedModel, save_model
from mtcomp.toolpaths import iter_segment_chunks
from mtcomp.toolpaths.source import open_program
from test_toolpaths_dialect import mode  # noqa: F401  (the fixture: both reader paths)

XFYZ = load_machine("xfyz")
#: the tool comes down at X40 Y10 moving X in -; the circle names where it stands
PROGRAM = ("G21 G90\nG0 X50 Y10 Z5\nG1 X40 Z-1 F100\nG3 F360\nX40 Y10 I0.000\n"
           "G1 X20 Y10\nM30\n")


def _rows(path, dialect=None):
    with open_program(path, dialect) as src:
        chunks = list(iter_segment_chunks(src, XFYZ))
    return (np.concatenate([c.line for c in chunks]), np.vstack([c.start for c in chunks]),
            np.vstack([c.end for c in chunks]), np.vstack([c.dirs for c in chunks]),
            np.concatenate([c.feed for c in chunks]))


def test_the_circle_is_one_row_that_does_not_move(tmp_path, mode):
    p = tmp_path / "p.nc"
    p.write_text(PROGRAM)
    line, start, end, dirs, feed = _rows(p)
    # rows: the rapid (line 2), the feed move (3), the circle (5), the move off (6)
    assert line.tolist() == [2, 3, 5, 6]
    np.testing.assert_allclose(start[2], [40, 10, -1], rtol=0, atol=0)
    np.testing.assert_allclose(end[2], [40, 10, -1], rtol=0, atol=0)
    # X last moved in -, Z in -, Y only from a position not given (0: not known): kept by the circle
    assert dirs[2].tolist() == dirs[1].tolist() == [-1, 0, -1]
    # the tool stands where the feed move left it: that move's feed, not the circle's F360
    assert feed[2] == pytest.approx(100.0, rel=0, abs=0)
    # the F360 of the circle's line is the next move's
    assert feed[3] == pytest.approx(360.0, rel=0, abs=0)


def _linear_x_model(tmp_path, um_per_m):
    """A model whose only error is X's positioning error ``um_per_m`` * (X / 1 m)."""
    machine = load_machine("xfyz").with_basis("polynomial")
    model = ErrorModel(machine)
    fitted = FittedModel.zero(model)
    names = [s.name for s in model.param_specs]
    fitted.params.values[names.index("EXX_1")] = um_per_m * 1e-3      # internal unit: mm
    path = tmp_path / "model.json"
    save_model(path, fitted)
    return path


def _words(line: str) -> dict:
    return {m.group(1): m.group(2) for m in re.finditer(r"([A-Z])([-+]?[\d.]+)", line)}


def test_the_circle_is_written_with_the_correction_of_where_the_tool_stands(tmp_path, capsys):
    """EXX = 100 um/m * X: the tool reaches X (1 + 1e-4) for a programmed X, so the correction puts
    X at X / (1 + 1e-4): X40 -> 39.996 (written 39.9960), Y and Z have no error. The circle is
    written at the same corrected point as the move before it, its I unchanged: still a circle of
    zero radius, so it does not move in the output either."""
    model = _linear_x_model(tmp_path, 100.0)
    prog = tmp_path / "p.nc"
    prog.write_text(PROGRAM)
    out = tmp_path / "out.nc"
    code = main(["compensate", "xfyz", str(model), str(prog), "-o", str(out), "--quiet"])
    assert code == 0, capsys.readouterr().err
    lines = out.read_text().splitlines()
    src = PROGRAM.splitlines()
    assert len(lines) == len(src)
    feed_move, circle = _words(lines[2]), _words(lines[4])
    assert float(feed_move["X"]) == pytest.approx(40.0 / (1.0 + 1e-4), rel=0, abs=0.5e-4)
    # the circle: X as the corrected end of the move before (the same word), I 0 as written
    assert circle["X"] == feed_move["X"] and float(circle["Y"]) == 10.0
    assert circle["I"] == "0.000" and "J" not in circle
    assert lines[3] == src[3] == "G3 F360"
    # and the move off it: X20 -> 19.998
    assert float(_words(lines[5])["X"]) == pytest.approx(20.0 / (1.0 + 1e-4), rel=0, abs=0.5e-4)


def test_linuxcnc_refuses_it_as_its_interpreter_does(tmp_path):
    p = tmp_path / "p.nc"
    p.write_text(PROGRAM)
    with pytest.raises(InputError) as exc:
        _rows(p, "linuxcnc")
    assert exc.value.line == 5
    assert "arc with zero radius" in exc.value.message and "Zero-radius arc" in exc.value.message
    # grbl runs it as a block that does not move
    assert _rows(p, "grbl")[0].tolist() == [2, 3, 5, 6]


@pytest.mark.parametrize("block, words", [
    ("X41 Y10 I0", "zero radius"),              # from the centre to 1 mm away: it would move
    ("X40 Y10 Z-2 I0", "zero radius"),          # a helix of zero radius: a plunge
    ("X41 Y10 R0", "R arc with zero radius"),
    ("X40 Y10 R0", "R arc with start = end"),
    ("X40 Y10 I0.001", None),                   # a circle of radius 1 um: a real one, accepted
])
def test_a_zero_radius_arc_that_would_move_stays_refused(tmp_path, mode, block, words):
    p = tmp_path / "p.nc"
    p.write_text(PROGRAM.replace("X40 Y10 I0.000", block))
    if words is None:
        line = _rows(p)[0]
        assert (line == 5).sum() > 1          # its chords
        return
    with pytest.raises(InputError) as exc:
        _rows(p)
    assert exc.value.line == 5 and words in exc.value.message

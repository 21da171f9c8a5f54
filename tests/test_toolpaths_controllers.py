"""What controllers accept that a strict reading of RS-274 would not, each against a hand-derived
case on both reader and writer paths: absolute arc centres (G90.1)."""
import numpy as np
import pytest

from mtcomp.errors import InputError
from mtcomp.machine import load_machine
from mtcomp.toolpaths import iter_segment_chunks
from test_toolpaths_output import _write_with, gcode_path  # noqa: F401  (the fixture)

XFYZ = load_machine("xfyz")


def _ends(tmp_path, text, **kw):
    p = tmp_path / "p.nc"
    p.write_text(text)
    return np.vstack([c.end for c in iter_segment_chunks(p, XFYZ, **kw)])


def test_g90_1_reads_the_centre_as_a_position(tmp_path, gcode_path):
    # from (2, 0) to (8, 0) clockwise about the centre (5, 0) (I5 J0 absolute): radius 3, over
    # the top (5, 3); read as offsets the centre (7, 0) would leave the end 1 from it (refused)
    ends = _ends(tmp_path, "G21 G90 G90.1\nG0 X2 Y0 Z0\nG2 X8 Y0 I5 J0 F100\nM30\n")
    arc = ends[1:]
    np.testing.assert_allclose(np.hypot(arc[:, 0] - 5.0, arc[:, 1]), 3.0, rtol=0, atol=1e-12)
    assert arc[:, 1].max() == pytest.approx(3.0, rel=0, abs=1e-3)
    with pytest.raises(InputError, match="radius"):
        _ends(tmp_path, "G21 G90 G91.1\nG0 X2 Y0 Z0\nG2 X8 Y0 I5 J0 F100\nM30\n")
    with pytest.raises(InputError, match="without both I and J"):
        _ends(tmp_path, "G21 G90 G90.1\nG0 X2 Y0 Z0\nG2 X8 Y0 I5 F100\nM30\n")


def test_g90_1_centre_moves_with_the_correction(tmp_path, gcode_path):
    text = "G21 G90 G90.1\nG0 X2 Y0 Z0\nG2 X8 Y0 I5 J0 F100\nG91.1\nG3 X2 Y0 I-3 J0\nM30\n"
    shift = lambda p: np.tile([0.001, 0.002, 0.0], (len(p), 1))      # noqa: E731
    out = _write_with(tmp_path, text, field=shift).splitlines()
    # by hand: the whole arc shifted by (1, 2) um: its absolute centre (5, 0) too; the
    # incremental offsets of the next arc (G91.1) do not change
    assert out[2] == "G2 X8.0010 Y0.0020 I5.0010 J0.0020 F100"
    assert out[4] == "G3 X2.0010 Y0.0020 I-3 J0"

"""The first error in program order is the one told: a move beyond the travel at one line and a bad
arc at the next are refused at the first (the reader hands out the rows before a bad line before
its error, so the planner's check of their travel comes first)."""
import pytest

from mtcomp.errors import InputError
from mtcomp.machine import load_machine
from mtcomp.toolpaths import iter_segment_chunks

XFYZ = load_machine("xfyz")
#: the lab's typo4.ngc on xfyz (Y travel -300 .. 300 mm): line 5 goes to Y1200, line 6's arc
#: (centre 20 mm from its start, 1060 mm from its end) is one no controller accepts
TYPO = ("G21 G90 G17 G94\nG0 X-20. Y60. Z80.\nG1 Z40. F300\nG2 X20. Y60. I20. J0.\n"
        "G1 Y1200.\nG3 X20. Y140. I-20. J0.\nG1 X-20.\nM2\n")


def test_the_rows_before_a_bad_line_come_out_before_its_error(tmp_path, reader_path):
    p = tmp_path / "p.nc"
    p.write_text(TYPO)
    seen = []
    with pytest.raises(InputError, match="arc radius inconsistent") as exc:
        for chunk in iter_segment_chunks(p, XFYZ, chunk_size=1000):
            seen += [int(x) for x in chunk.line]
    assert exc.value.line == 6
    # the arc of line 4 is cut into chords, all with its line; line 5 is the last row
    assert sorted(set(seen)) == [2, 3, 4, 5] and seen[-1] == 5


def test_compensate_tells_the_move_beyond_the_travel_first(tmp_path, reader_path,
                                                           refused_on_xfyz):
    err = refused_on_xfyz("typo4.ngc", TYPO)
    assert f"{tmp_path / 'typo4.ngc'}:5: Y 1200.0000 mm is outside the travel of axis Y" in err

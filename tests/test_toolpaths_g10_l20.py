"""G10 L20 at a known position: the compensated program's line is the source's, read where the
corrected tool stands, so its controller sets the offset off by the correction there; the words
written after it in that system take the correction back. Hand-derived words (a correction linear
in machine X, as the G92 tests build), and compensated programs replayed by the test-side
controller (tests/replay.py, which follows G10 L20 by its own code) against the source plus the
corrections BLOCKS.csv reports."""
import math

import numpy as np
import pytest

from mtcomp.errors import InputError
from mtcomp.machine import load_machine
from mtcomp.toolpaths import iter_segment_chunks
from mtcomp.toolpaths.source import open_program
from replay import replay
from test_toolpaths_dialect import mode  # noqa: F401  (the fixture: both reader paths)
from test_toolpaths_frames import corrected_with_notes
from test_toolpaths_g92 import _compensated

XFYZ = load_machine("xfyz")


def _linear_x(q):
    """A correction that depends on machine X only: 1e-4 x (mm), so +1 um at X10."""
    return np.column_stack([1e-4 * q[:, 0], 0 * q[:, 0], 0 * q[:, 0]])


def _lines(tmp_path, text, dialect="linuxcnc"):
    ends, known, lines, notes = corrected_with_notes(tmp_path, text, dialect, _linear_x)
    return ends, known, lines, notes


#: G54 is the program's (L2), so an L20 at a known position is followed
HEAD = "G21 G90 G54\nG10 L2 P1 X0 Y0 Z0\nG0 X10. Y0 Z5.\n"


@pytest.mark.parametrize("dialect", ["linuxcnc", "grbl"])
def test_l20_at_a_known_position_takes_its_correction_back(tmp_path, mode, dialect):
    """At X10, `G10 L20 P1 X0`: G54's X offset is 10, so `X5` is machine 15 (correction 1.5 um).
    The output's L20 is read where the corrected tool stands (X10.0010), so its offset is 10.0010
    and the word reaching machine 15.0015 is X5.0005 (not X5.0015); X-2 (machine 8) is X-2.0002."""
    text = HEAD + "G10 L20 P1 X0\nG1 X5. F100\nX-2.\nM30\n"
    ends, known, lines, notes = _lines(tmp_path, text, dialect)
    np.testing.assert_allclose(ends[:, 0], [10.0, 15.0, 8.0], rtol=0, atol=1e-12)
    assert known.all() and not notes
    assert lines[2:6] == ["G0 X10.0010 Y0 Z5.", "G10 L20 P1 X0", "G1 X5.0005 F100", "X-2.0002"]
    offset = 10.0010 - 0.0               # the output's controller: where it stands less the value
    for word, machine in ((5.0005, 15.0), (-2.0002, 8.0)):
        assert math.isclose(word + offset, machine * (1 + 1e-4), rel_tol=0, abs_tol=1e-9)


def test_a_second_l20_replaces_the_shift_with_the_correction_at_its_line(tmp_path, mode):
    """After X5 (machine 15, written X5.0005), `G10 L20 P1 X0` again: the source's offset is 15,
    the output's 10.0010 + 5.0005 = 15.0015; X5 (machine 20, +2 um) is 20.0020 - 15.0015."""
    text = HEAD + "G10 L20 P1 X0\nG1 X5. F100\nG10 L20 P1 X0\nG1 X5.\nM30\n"
    ends, _known, lines, _notes = _lines(tmp_path, text)
    np.testing.assert_allclose(ends[:, 0], [10.0, 15.0, 20.0], rtol=0, atol=1e-12)
    assert lines[4:8] == ["G1 X5.0005 F100", "G10 L20 P1 X0", "G1 X5.0005", "M30"]


def test_l20_of_another_system_applies_when_the_program_selects_it(tmp_path, mode):
    """`G10 L20 P2 X0` at X10 in G54: G55's X offset is 10 (10.0010 in the output). G54's blocks
    keep their words (X20: +2 um, X20.0020); in G55 X5 is machine 15: 15.0015 - 10.0010."""
    text = (HEAD + "G10 L20 P2 X0\nG10 L2 P2 Y0 Z0\nG1 X20. F100\nG55\nG0 X5. Y0 Z5.\n"
            "G54\nG0 X5. Y0 Z5.\nM30\n")
    ends, known, lines, _notes = _lines(tmp_path, text)
    np.testing.assert_allclose(ends[:, 0], [10.0, 20.0, 15.0, 5.0], rtol=0, atol=1e-12)
    assert known.all()
    assert lines[5] == "G1 X20.0020 F100"
    assert lines[7] == "G0 X5.0005 Y0 Z5."
    assert lines[9] == "G0 X5.0005 Y0 Z5."          # G54 again: machine 5, +0.5 um, no shift


def test_l2_of_that_system_ends_the_shift(tmp_path, mode):
    """`G10 L2 P2 X50` after the L20 sets G55's X absolutely, in both programs: X5 in G55 is
    machine 55 (+5.5 um), X5.0055."""
    text = (HEAD + "G10 L20 P2 X0\nG10 L2 P2 X50. Y0 Z0\nG55\nG0 X5. Y0 Z5.\nM30\n")
    ends, _known, lines, _notes = _lines(tmp_path, text)
    np.testing.assert_allclose(ends[:, 0], [10.0, 55.0], rtol=0, atol=1e-12)
    assert lines[6] == "G0 X5.0055 Y0 Z5."


def test_l2_of_the_active_system_after_l20_forgets_the_axis(tmp_path, mode):
    """`G10 L2 P1 X50` in G54 after an L20 there: the output's position in G54 is not the source's
    plus a correction the writer follows, so X is unknown (no correction, no word added) until
    the program names it; then X5 is machine 55 (+5.5 um), X5.0055."""
    text = HEAD + "G10 L20 P1 X0\nG10 L2 P1 X50.\nG1 Y1. F100\nX5.\nM30\n"
    ends, known, lines, _notes = _lines(tmp_path, text)
    assert known[1].tolist() == [False, True, True] and known[2].all()
    assert lines[5:7] == ["G1 Y1. F100", "X5.0055"]


def test_l20_with_g92_in_force(tmp_path, mode):
    """LinuxCNC and grbl: L20 sets the offset so that the position reads the value, G92's offset
    taken into account. At X10, `G92 X0` (the output's G92 offset 10.0010), X5 (machine 15, X5.0005),
    `G10 L20 P1 X0`: G54's X offset 5 in the source, 15.0015 - 10.0010 = 5.0005 in the output;
    X3 is machine 18 (+1.8 um): 18.0018 - 10.0010 - 5.0005 = 3.0003."""
    text = HEAD + "G92 X0\nG1 X5. F100\nG10 L20 P1 X0\nG1 X3.\nM30\n"
    ends, _known, lines, _notes = _lines(tmp_path, text)
    np.testing.assert_allclose(ends[:, 0], [10.0, 15.0, 18.0], rtol=0, atol=1e-12)
    assert lines[4:7] == ["G1 X5.0005 F100", "G10 L20 P1 X0", "G1 X3.0003"]


def test_g92_after_l20(tmp_path, mode):
    """The other order: at X10 `G10 L20 P1 X0` (output offset 10.0010), X5 (X5.0005), `G92 X0`:
    the source's G92 offset 5, the output's 15.0015 - 10.0010 = 5.0005; X3 (machine 18) is
    18.0018 - 10.0010 - 5.0005 = 3.0003."""
    text = HEAD + "G10 L20 P1 X0\nG1 X5. F100\nG92 X0\nG1 X3.\nM30\n"
    ends, _known, lines, _notes = _lines(tmp_path, text)
    np.testing.assert_allclose(ends[:, 0], [10.0, 15.0, 18.0], rtol=0, atol=1e-12)
    assert lines[4] == "G1 X5.0005 F100" and lines[6] == "G1 X3.0003"


def test_l20_in_inch(tmp_path, mode):
    """G20: at X1. (25.4 mm, +2.54 um = +0.0001 in) `G10 L20 P1 X0`; X0.5 is machine 38.1 mm
    (+3.81 um = +0.00015 in): 0.5 + 0.00015 - 0.0001 = 0.50005."""
    text = "G20 G90 G54\nG10 L2 P1 X0 Y0 Z0\nG0 X1. Y0 Z0.2\nG10 L20 P1 X0\nG1 X0.5 F10\nM30\n"
    ends, _known, lines, _notes = _lines(tmp_path, text)
    np.testing.assert_allclose(ends[:, 0], [25.4, 38.1], rtol=0, atol=1e-12)
    assert lines[2] == "G0 X1.00010 Y0 Z0.2"
    assert lines[4] == "G1 X0.50005 F10"


def test_l20_under_g91_moves_from_the_given_value(tmp_path, mode):
    """After the L20 the output's controller reads X0 where it stands (10.0010 on the machine):
    the increment to the written X5.0005 is 5.0005."""
    text = HEAD + "G10 L20 P1 X0\nG91\nG1 X5. F100\nX-7.\nG90\nM30\n"
    _ends, _known, lines, _notes = _lines(tmp_path, text)
    assert lines[5:7] == ["G1 X5.0005 F100", "X-7.0007"]


def test_touch_off_is_unchanged(tmp_path, mode):
    """After homing the L20 is a touch-off: the offset comes from outside (here 0), the same in
    both programs, so the words carry their own corrections only."""
    text = "G21\n$H\nG10 L20 P1 X0 Y0 Z50\nG54\nG0 X10 Y20 Z40\nG1 X15 F100\nM30\n"
    ends, _known, lines, notes = _lines(tmp_path, text, "grbl")
    np.testing.assert_allclose(ends[:, 0], [10.0, 15.0], rtol=0, atol=1e-12)
    assert lines[4:6] == ["G0 X10.0010 Y20 Z40", "G1 X15.0015 F100"]
    assert len(notes) == 1 and "touch-off" in notes[0]


@pytest.mark.parametrize("text, axis", [
    ("G0 X1 Y1 Z1\nT2 M6\nG10 L20 P1 Z0\n", "Z"),
    ("G0 X1 Y1 Z1\nG55\nG10 L20 P1 X0\n", "X"),
])
def test_l20_where_a_given_position_was_lost_is_refused(tmp_path, mode, text, axis):
    """The output stands there off by a correction the controller may or may not have moved away
    from (a tool change may move to a change position): refused in one line, as G92 there."""
    p = tmp_path / "p.nc"
    p.write_text(text)
    with pytest.raises(InputError) as exc, open_program(p, "linuxcnc") as src:
        list(iter_segment_chunks(src, XFYZ))
    err = exc.value
    assert err.line == 3 and "\n" not in err.message
    assert f"G10 L20 {axis} where the program has lost the position" in err.message


# ------------------------------------------------------------- compensated and replayed
def test_replay_follows_l20_of_another_system_from_the_active_one(tmp_path):
    """The test-side controller by hand: at G54 X10 (origin 100), `G10 L20 P2 X0` makes G55's
    origin 110, whatever G55's was; G55 X5 is machine 115."""
    moves = replay(b"G21 G90\nG10 L2 P1 X100 Y0 Z0\nG10 L2 P2 X7 Y0 Z0\nG0 X10 Y0 Z0\n"
                   b"G10 L20 P2 X0\nG55\nG0 X5 Y0 Z0\n", placed=True).moves
    assert [m.end["X"] for m in moves] == [110.0, 115.0]


def test_output_reaches_the_source_position_plus_the_reported_correction(tmp_path, capsys):
    """Each block of the output, replayed on the controller (its own L20 offsets, set where the
    output stands), ends on the machine at the source's replayed end plus BLOCKS.csv's correction:
    L20 of the active system, of another selected later, a second one, with G92, then L2."""
    text = ("G21 G90\nG10 L2 P1 X0 Y0 Z0\nG10 L2 P2 X0 Y0 Z0\nG0 X10. Y20. Z5.\nG1 X40. F500\n"
            "G10 L20 P1 X0 Y0\nG1 X30. Y10.\nG10 L20 P2 X5. Z1.\nG1 X-20.\nG10 L20 P1 Y3.\n"
            "G1 Y13.\nG92 X1.\nG1 X11. Y-5.\nG10 L20 P1 X2.\nG1 X12.\nG55\nG0 X12. Y3. Z4.\n"
            "G1 X-8. Y13.\nG92.1\nG10 L2 P2 X3. Y4. Z0\nG0 X1. Y1. Z1.\nM30\n")
    src, out, rows = _compensated(tmp_path, capsys, text, "p", "linuxcnc")
    a, b = replay(src, placed=True).moves, replay(out, placed=True).moves
    assert len(a) == len(b) == len(rows) == 10
    assert [m.line + 1 for m in a] == [int(r["line"]) for r in rows]
    got = np.array([[n.end[axis] - m.end[axis] for axis in "XYZ"] for m, n in zip(a, b)])
    want = np.array([[float(r[f"c{axis}_um"]) for axis in "xyz"] for r in rows]) * 1e-3
    np.testing.assert_allclose(got, want, rtol=0, atol=1.5e-4)
    assert np.abs(want).max() > 1e-3          # the corrections are not zero

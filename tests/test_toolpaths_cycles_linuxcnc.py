"""LinuxCNC's drilling cycles with R and Z kept as the numbers last written and read in the
distance mode of each line: a G81 in G90 repeated in G91 with L, read, written and replayed.

The expectations are derived by hand from LinuxCNC's interp_cycles.cc (convert_cycle and
convert_cycle_xy): a line without Z or R takes the number last written (``block->z_number =
block->z_flag ? block->z_number : settings->cycle_cc``, R from ``settings->cycle_r``); in G90 the
numbers are the levels, in G91 ``r = R + old_cc`` with old_cc the series' initial level (cycle_il,
the Z before the first cycle line) and ``cc = r + Z``; X and Y are steps repeated L times. The
corrections move X by +1.2 um, Y by -2.1 um and Z by +3.3 um on every known axis.
"""
import numpy as np
import pytest

from mtcomp import InputError, load_machine
from mtcomp.toolpaths import iter_segment_chunks, read_program, write_corrected
from replay import Tolerance, compare
from test_toolpaths_gcode import gcode_path  # noqa: F401  (autouse: compiled and Python path)

XFYZ = load_machine("xfyz")
SHIFT = np.array([0.0012, -0.0021, 0.0033])

# the initial level is Z10; line 3 in G90, line 4 repeats it in G91 keeping its Z number -5 with
# R0, line 5 in G91 with R-1 and the same Z number, line 6 in G90 reading both numbers as levels
PROGRAM = ("G21 G90 G17\nG0 X0 Y0 Z10\nG99 G81 X3 Y4 R2 Z-5 F100\nX1 Y0 R0 G91 L3\nY-2 R-1\n"
           "G90 X7 Y7\nG80\nM30\n")

#: the same in Fanuc's spelling (a dimension word with a decimal point)
MIXED = "G0 X0. Y0. Z10.\nG99 G81 X3. Y4. R2. Z-5. F100\nX1. Y0 R0 G91 L3\n"


def test_g91_repeats_read_the_held_r_and_z_as_numbers(tmp_path):
    p = tmp_path / "in.nc"
    p.write_text(PROGRAM)
    blocks = [b for b in read_program(p, XFYZ, dialect="linuxcnc").blocks if b.cycle is not None]
    holes = {b.line: b.points.tolist() for b in blocks}
    assert holes == {3: [[3, 4, -5]],
                     # R = 10 + 0 = 10, bottom = 10 + (-5) = 5; X from 3 in steps of 1
                     4: [[4, 4, 5], [5, 4, 5], [6, 4, 5]],
                     # R = 10 + (-1) = 9 (from the initial level, not from the tool at R10),
                     # bottom 9 - 5 = 4; Y from 4 by -2
                     5: [[6, 2, 4]],
                     # G90: the numbers -1 and -5 are the levels
                     6: [[7, 7, -5]]}
    assert [(b.cycle.r_level, b.cycle.z_bottom) for b in blocks] == [(2, -5), (10, 5), (9, 4),
                                                                     (-1, -5)]
    # G99: each line leaves the tool at its R plane
    assert [b.end[2] for b in blocks] == [2, 10, 9, -1]
    assert all(b.known.all() for b in blocks)


def test_g91_repeats_are_written_absolute_and_replay_as_the_source(tmp_path):
    p = tmp_path / "in.nc"
    p.write_text(PROGRAM)
    out = p.with_name("out.nc")
    corr = [(c, c.end + np.where(c.known, SHIFT, 0.0), np.ones(len(c), int))
            for c in iter_segment_chunks(p, XFYZ, dialect="linuxcnc")]
    write_corrected(p, out, XFYZ, iter(corr), dialect="linuxcnc")
    text = out.read_text()
    assert text.splitlines() == [
        "G21 G90 G17",
        "G0 X0.0012 Y-0.0021 Z10.0033",
        "G99 G81 X3.0012 Y3.9979 R2.0033 Z-4.9967 F100",
        # one absolute line per repeat, G91 and L3 dropped; R and Z as levels, moved with Z
        "X4.0012 Y3.9979 R10.0033 Z5.0033",
        "X5.0012 Y3.9979",
        "X6.0012 Y3.9979",
        "Y1.9979 R9.0033 Z4.0033",
        # the source's G90 line reads its held numbers -1 and -5: the output restates them
        "G90 X7.0012 Y6.9979 Z-4.9967 R-0.9967",
        "G80",
        "M30"]
    # the controller-style replay (R and Z as numbers, from LinuxCNC's source) of both programs:
    # the same holes up to the correction
    compare(PROGRAM.encode(), text.encode(), Tolerance(axis_mm=0.005, axis_deg=0.01, path_mm=0.01))


def test_g91_holes_need_the_initial_level_only(tmp_path):
    # no G98/G99 and the R plane below the start: Z is not known after line 3, but the G91 line's
    # R is measured from the initial level 10: R 9, bottom 9 - 5 = 4 (refused before: Z unknown)
    p = tmp_path / "in.nc"
    p.write_text("G21 G90\nG0 X0 Y0 Z10\nG81 X3 Y4 R2 Z-5 F100\nG91 X1 R-1\nG80\n")
    b = read_program(p, XFYZ, dialect="linuxcnc").blocks
    assert not b[2].start_known          # Z after line 3 not known
    assert b[2].points.tolist() == [[4, 4, 4]]
    assert (b[2].cycle.r_level, b[2].cycle.z_bottom) == (9, 4)


@pytest.mark.parametrize("text, dialect, line, words", [
    # the initial level is where the machine stood when the program began: not known
    ("G0 X0 Y0\nG99 G81 X3 Y4 R2 Z-5 F100\nG91 X1 R0 L3\n", "linuxcnc", 3,
     "its R is measured from the initial level, the Z where the cycles began, which the program "
     "has not given"),
    # the other controllers keep their rule: a Z given in G90 is not read in G91
    (MIXED, "fanuc", 3, "its R or Z was given in the other distance mode"),
    (MIXED, "generic", 3, "its R or Z was given in the other distance mode"),
    # a G90 line passed through (G18) would read the R of a G91 line the output writes absolute
    ("G0 X0 Y0 Z10\nG99 G81 X3 Y4 R2 Z-5 F100\nG91 X1 R0\nG90 G18 X7\n", "linuxcnc", 4,
     "passed through uncorrected (drilling along another axis than Z (G18)) with the R of an "
     "incremental (G91) cycle line"),
])
def test_unreadable_retained_words_are_refused(tmp_path, text, dialect, line, words):
    p = tmp_path / "in.nc"
    p.write_text("G21 G90\n" + text)
    with pytest.raises(InputError) as e:
        read_program(p, XFYZ, dialect=dialect)
    msg = str(e.value)
    assert words in msg and f":{line + 1}:" in msg and "\n" not in msg

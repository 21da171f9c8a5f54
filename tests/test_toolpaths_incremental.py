"""Incremental (G91) programs come out incremental, and nothing after the program's end changes.

Expected lines are written by hand from the rule: a corrected G91 word is the line's own increment
plus the change of the correction, the corrected end less the input's end less the correction the
output carries where it stands, that change rounded to the word's decimals; in a program in one
unit the increments then add up exactly to the rounded corrected positions, and a line whose
correction does not change keeps its word as written. Every test runs on the compiled and the
pure-Python path (the ``gcode_path`` fixture)."""
from decimal import Decimal

import numpy as np
import pytest

from mtcomp import load_machine
from mtcomp.toolpaths import iter_segment_chunks, read_program, write_corrected
from test_toolpaths_gcode import gcode_path  # noqa: F401  (autouse: compiled and Python path)

XFYZ = load_machine("xfyz")
ORIGIN = np.zeros(3)


def _write(tmp_path, text, field, *, counts=None, **kw):
    """Write ``text`` with every segment end moved by ``field(end)`` (n, 3) mm; counts: points per
    row given as (row -> list of (3,) corrected points) for split blocks."""
    src = tmp_path / "in.nc"
    src.write_text(text)
    out = tmp_path / "out.nc"

    def corrections():
        for c in iter_segment_chunks(src, XFYZ, **kw):
            yield c, c.end + field(c.end), np.ones(len(c), np.int64)
    write_corrected(src, out, XFYZ, corrections() if counts is None else counts(src), **kw)
    return out.read_text().splitlines()


def _constant_x(end):
    return np.where(np.arange(3) == 0, 0.001, 0.0) * np.ones_like(end)


def _linear(end):
    """dX = 1e-3 X, dY = 2e-4 X (mm)."""
    d = np.zeros_like(end)
    d[:, 0] = 1e-3 * end[:, 0]
    d[:, 1] = 2e-4 * end[:, 0]
    return d


def test_constant_correction_changes_only_the_first_increment(tmp_path):
    # from X0 (given as the start): X 1.5 -> 1.501, then every end moves by the same 1 um, so the
    # later increments are the source's, as written
    text = "G21 G91\nG1 X1.5 F100\nX2\ny-1 (c)\nG0 X-0.25\n"
    out = _write(tmp_path, text, _constant_x, initial_position=ORIGIN)
    assert out == ["G21 G91", "G1 X1.5010 F100", "X2", "y-1 (c)", "G0 X-0.25"]


def test_linear_correction_changes_the_increments_by_its_difference(tmp_path):
    # absolute X 10, 20, 15 -> corrected 10.01, 20.02, 15.015: increments 10.01, 10.01, -5.005;
    # Y (not named) moves with 2e-4 X: 0.002, 0.004, 0.003 -> increments 0.002, 0.002, -0.001,
    # added after the line's last axis word with 4 decimals
    text = "G21 G91\nG1 X10. F100\nX10.\nX-5. (back)\n"
    out = _write(tmp_path, text, _linear, initial_position=ORIGIN)
    assert out == ["G21 G91", "G1 X10.0100 Y0.0020 F100", "X10.0100 Y0.0020",
                   "X-5.0050 Y-0.0010 (back)"]


def test_absolute_then_incremental_keeps_the_words_g90_and_g91_as_written(tmp_path):
    text = "G21 G90\nG0 X0 Y0 Z5\nG91 G1 X1.5 F100\nX2\nG90 G0 X10\n"
    out = _write(tmp_path, text, _constant_x)
    assert out == ["G21 G90", "G0 X0.0010 Y0 Z5", "G91 G1 X1.5 F100", "X2", "G90 G0 X10.0010"]


def test_increments_add_up_exactly_to_the_rounded_corrected_ends(tmp_path):
    """A long incremental program under a smooth correction: at every block the sum of the
    written increments equals the corrected end rounded to 4 decimals, exactly (decimal sums)."""
    rng = np.random.default_rng(7)
    steps = np.round(rng.uniform(-5, 5, size=(2000, 2)), 3)
    lines = ["G21 G91 G1 F500"] + [f"X{x:.3f} Y{y:.3f}" for x, y in steps]

    def field(end):
        return np.stack([3e-3 * np.sin(end[:, 0] / 7.0), 2e-3 * np.cos(end[:, 1] / 5.0),
                         np.zeros(len(end))], axis=1)

    start = np.array([1.2345, -2.5, 0.0])
    out = _write(tmp_path, "\n".join(lines) + "\n", field, initial_position=start)
    assert len(out) == len(lines) and out[0] == lines[0]
    ends = start[:2] + np.cumsum(steps, axis=0)
    corrected = np.column_stack([ends, np.zeros(len(ends))])
    corrected = corrected + field(corrected)
    total = [Decimal("1.2345"), Decimal("-2.5")]
    changed = 0
    for k, line in enumerate(out[1:]):
        words = dict((w[0], Decimal(w[1:])) for w in line.split())
        changed += line != lines[k + 1]
        for j, c in enumerate("XY"):
            total[j] += words[c]
            assert total[j] == Decimal(f"{corrected[k, j]:.4f}"), (k, c, line)
    assert changed > 1000          # the correction changes most increments


def test_a_split_block_writes_its_later_pieces_as_increments(tmp_path):
    def counts(src):
        for c in iter_segment_chunks(src, XFYZ, initial_position=ORIGIN):
            pts = np.array([[5.002, 0.0, 0.0], [10.001, 0.0, 0.0]])
            yield c, pts, np.array([2])
    out = _write(tmp_path, "G21 G91\nG1 X10. F100\n", None, counts=counts,
                 initial_position=ORIGIN)
    assert out == ["G21 G91", "G1 X5.0020 F100", "X4.9990"]


def test_a_passed_through_increment_moves_the_output_from_where_it_stands(tmp_path):
    # Z is unknown after the tool change, so line 4 passes through as written: the output's X
    # goes from 0 to 5 with the source's. Line 5 ends at X6, corrected 6.006: the increment is
    # from 5 (1.006), not from the last corrected end written (0)
    text = "G21 G90\nG0 X0 Y0 Z50\nT1 M6\nG91 G0 X5 Z-10.\nG1 X1 F100\n"
    out = _write(tmp_path, text, _linear)
    assert out == ["G21 G90", "G0 X0 Y0 Z50", "T1 M6", "G91 G0 X5 Z-10.",
                   "G1 X1.0060 Y0.0012 F100"]


def test_an_incremental_arc_keeps_its_centre_offsets_under_a_shift(tmp_path):
    text = "G21 G90 G17\nG0 X0 Y0 Z0\nG91 G2 X10 Y0 I5 J0 F100\n"
    out = _write(tmp_path, text, _constant_x)
    assert out == ["G21 G90 G17", "G0 X0.0010 Y0 Z0", "G91 G2 X10 Y0 I5 J0 F100"]


def test_an_incremental_drilling_cycle_is_written_absolute_and_g91_comes_back(tmp_path):
    # G91 G99 G81 from Z10: R 10-8 = 2, bottom 2-5 = -3 at X 0+5; with +1 um in X the line is
    # written absolute (G91 dropped, X Z R the cycle's levels; Y stays 0, not written), and the
    # next incremental line gets its G91 in front (X: from the hole's 5.001 by 1, as written)
    text = "G21 G90\nG0 X0 Y0 Z10\nG91 G99 G81 X5 R-8 Z-5 F100\nG80\nG0 X1\n"
    out = _write(tmp_path, text, _constant_x)
    assert out[:2] == ["G21 G90", "G0 X0.0010 Y0 Z10"]
    assert out[2] == "G99 G81 X5.0010 R2.0000 Z-3.0000 F100"
    assert out[3:] == ["G80", "G91 G0 X1"]


def test_nothing_after_the_program_end_is_read_or_corrected(tmp_path):
    text = "G21 G90\nG0 X1 Y1 Z1\nM30\nG0 X2 Y2\nG91 G1 X1 F100\n"
    assert [b.line for b in read_program(_path(tmp_path, text), XFYZ).blocks] == [2]
    out = _write(tmp_path, text, _constant_x)
    assert out == ["G21 G90", "G0 X1.0010 Y1 Z1", "M30", "G0 X2 Y2", "G91 G1 X1 F100"]
    # M2 ends it too; a move on the M2 line itself is run (and corrected)
    text = "G21 G90\nG0 X1 Y1 Z1\nG1 X3 F100 M2\nG0 X2 Y2\n"
    out = _write(tmp_path, text, _constant_x)
    assert out == ["G21 G90", "G0 X1.0010 Y1 Z1", "G1 X3.0010 F100 M2", "G0 X2 Y2"]


def _path(tmp_path, text):
    p = tmp_path / "read.nc"
    p.write_text(text)
    return p


@pytest.mark.parametrize("text", ["G21 G91\nG1 X1.5 F100\nX2\n", "G20 G91\nG1 X.5 Y-.25 F10\n"])
def test_round_trip_of_an_incremental_program(tmp_path, text):
    out = tmp_path / "out.nc"
    _path(tmp_path, text)
    write_corrected(tmp_path / "read.nc", out, XFYZ, None, initial_position=ORIGIN)
    assert out.read_text() == text


def test_an_increment_after_g52_starts_where_the_machine_stands(tmp_path):
    # G52 X10 moves nothing: the machine stays at X 0.001 (corrected), whose program coordinate
    # becomes -9.999. The next G91 X5 ends at program -5 -> corrected -4.999: the increment from
    # where the machine stands is 5.000, the source's (an output that forgot the shift wrote
    # X-5.0000: 10 mm the wrong way)
    text = "G21 G90 G54\nG0 X0 Y0 Z0\nG52 X10.\nG91 G1 X5. F100\nX5.\nG90 G1 X0\n"
    out = _write(tmp_path, text, _constant_x, initial_position=ORIGIN, dialect="fanuc")
    assert out == ["G21 G90 G54", "G0 X0.0010 Y0 Z0", "G52 X10.", "G91 G1 X5. F100", "X5.",
                   "G90 G1 X0.0010"]


@pytest.mark.parametrize("dialect,last", [("grbl", "G0 X5.0010"), ("linuxcnc", "G0 X5")])
def test_grbl_runs_on_after_m30_with_its_modes_reset(tmp_path, dialect, last):
    # grbl 1.1 (gcode.c) resets G1 G17 G90 G94 G54 at M2/M30 and runs the lines a sender streams
    # after it: X5 is absolute again and corrected; LinuxCNC runs nothing after M30
    text = "G21 G90\nG0 X0 Y0 Z5\nG91 G0 X1\nM30\nG0 X5\n"
    out = _write(tmp_path, text, _constant_x, initial_position=ORIGIN, dialect=dialect)
    assert out[:4] == ["G21 G90", "G0 X0.0010 Y0 Z5", "G91 G0 X1", "M30"]
    assert out[4] == last


CAFXYZ = load_machine("cafxyz")
#: programs with nothing to correct that switch units (G20/G21) around G91 lines; the generated
#: programs of test_toolpaths_fuzz found them: mm words written from positions reached in
#: inches (X1.5 -> X1.49996, Z-2 -> Z-1.99998), and incremental full circles split in two arcs
UNIT_SWITCHES = [
    "G0 X0 Y0 Z0 A0\n\nG20\nG17 G2 X1.4161 Y-0.9093 I0.4161 J-0.9093 F300\n\n\n\nG91\nG21\n\n"
    "G0 X1.5 Y0 Z0 A0\n\nG20\n\nG0 X0",
    "%\nG0 X-0. Y-30 Z-89.0 A0. C8.3 F1851\n\nG20\nG18 G3 X14.7298 Z-17.8303 R14.4759 F300\n\n\t\n"
    "\nG91\nG21\n\t\nG17 G2 X-4.9609 Y-2.2704 R3.0000 F300\n\n\n\nG0 X37.217 Y0 Z-2 A0\n\nG20\n\n\n"
    "\nG17 G2 X0.0000 Y0.0000 I-0.5000 J0.0000 F300\n\n%",
    "G0 X1\nG91\nG20\nG17 G2 X0.0000 Y0.0000 I-1.0000 J0.0000 F300\n",
    "G20\nG0 X1.2812 Y0 Z0\nG21\nG91\nG0 X0\n",
]


@pytest.mark.parametrize("text", UNIT_SWITCHES, ids=["mm-after-inch-arc", "inch-circle-after-mm",
                                                      "circle-after-mm-move", "mm-after-inch"])
def test_a_program_with_nothing_to_correct_comes_back_byte_for_byte(tmp_path, text):
    src = _path(tmp_path, text)
    out = tmp_path / "out.nc"
    write_corrected(src, out, CAFXYZ, None, chord_tol_mm=0.05, initial_known=True)
    assert out.read_bytes() == src.read_bytes()


def test_a_g91_word_after_a_change_of_units_changes_by_the_change_of_correction(tmp_path):
    # +1 um in X everywhere. X0.0591 in = 1.50114 mm, corrected 1.50214 mm = 0.0591394 in, written
    # X0.05914: the output stands at 1.502156 mm, carrying 1.016 um. The G91 X1.5 in mm: the
    # change, 1 - 1.016 um, is 0.0000 at 4 decimals, so X1.5 stays as written and so does X2
    # (an increment between rounded ends wrote X1.499944: 3.0021 less 1.502156)
    text = "G21 G90\nG0 X0\nG20\nG1 X0.0591 F100\nG91 G21\nG1 X1.5\nX2\n"
    out = _write(tmp_path, text, _constant_x)
    assert out == ["G21 G90", "G0 X0.0010", "G20", "G1 X0.05914 F100", "G91 G21", "G1 X1.5", "X2"]


def test_an_incremental_full_circle_in_other_units_stays_one_block(tmp_path):
    # +1 um in X: X12.7 is written X12.7010. The G20 G91 full circle from there keeps X0 Y0 (its
    # correction does not change) and its centre I: (0.001 - 12.701) mm = -0.5 in, as written
    text = "G21 G90 G17\nG0 X12.7 Y0 Z0\nG20 G91\nG2 X0 Y0 I-0.5 J0 F100\n"
    out = _write(tmp_path, text, _constant_x)
    assert out == ["G21 G90 G17", "G0 X12.7010 Y0 Z0", "G20 G91", "G2 X0 Y0 I-0.5 J0 F100"]

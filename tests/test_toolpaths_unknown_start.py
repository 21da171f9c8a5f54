"""Arcs that move an axis whose position the program has not given (a helix from a height nobody
gave, an incremental arc from wherever the tool stands): passed through byte for byte, uncorrected;
the blocks after them corrected exactly as in the same program with the position given (the second
program is the oracle), and moving like the source up to the correction (the independent replay,
tests/replay.py). An absolute one from a start where the output stands corrected is refused."""
import pytest

from replay import compare
from test_toolpaths_beagleg import TOL, _compensate
from test_gcode_corpus import _check_output

#: a G91 helix excerpt (as a thread-milling program starts: Z down, cutter radius compensation on,
#: helices), then absolute moves; and the same program with its incremental lines left out: the
#: absolute lines start from the same place, a position the program had not given
INCREMENTAL = ("G21 G90 G17\nG91 G1 Z-1 F300\nG1 G42 D1 X0.5 Y-0.5\nG3 X1 Y1 Z0.1 R1\n"
               "G3 X-1 Y1 Z0.1 R1\nG90 G40 G1 X20 Y10 Z-2\nG1 X40 Y30\nG1 Y50\n")
INCREMENTAL_GIVEN = "G21 G90 G17\nG1 X20 Y10 Z-2 F300\nG1 X40 Y30\nG1 Y50\n"
#: a helix from a height nobody gave, then straight moves; the same program with the helix's end
#: given instead (a G0 to it, Z known from there)
HELIX = "G21 G90 G17\nG0 X0 Y0\nG2 X10 Y0 Z-2 I5 J0 F300\nG1 X20\nG1 Y10\nG1 X0 Z-3\n"
HELIX_GIVEN = "G21 G90 G17\nG0 X10 Y0 Z-2\nG1 X20 F300\nG1 Y10\nG1 X0 Z-3\n"


def _run(tmp_path, name, text):
    folder = tmp_path / name
    folder.mkdir()
    code, out, err, written = _compensate(folder, text, factor=30.0)
    assert code == 0, err
    _check_output(text.encode(), written.encode())
    return out, written.splitlines()


@pytest.mark.parametrize("text, given, passed, note", [
    (INCREMENTAL, INCREMENTAL_GIVEN, 4,
     "4 incremental (G91) moves of an axis whose position the program has not given"),
    (HELIX, HELIX_GIVEN, 2, "1 arc from a position the program has not given (line 3"),
], ids=["incremental", "helix"])
def test_an_arc_from_a_position_not_given_passes_and_the_rest_is_corrected(tmp_path, text, given,
                                                                           passed, note,
                                                                           reader_path):
    out, lines = _run(tmp_path, "a", text)
    assert note in out
    src = text.splitlines()
    n = 1 + passed
    assert lines[:n] == src[:n]                          # byte for byte, uncorrected
    assert all(a != b for a, b in zip(lines[n:], src[n:])), lines    # corrected (model x30)
    # the same corrections as the program that gives the position: the second oracle
    _out, given_lines = _run(tmp_path, "b", given)
    words = [t.replace("G90 G40 ", "") for t in lines[n:]]     # its codes, then the same words
    assert words == [t.replace(" F300", "") for t in given_lines[-len(words):]]
    compare(text.encode(), "\n".join(lines).encode() + b"\n", TOL)


@pytest.mark.parametrize("text, line, off, again", [
    # Z lost by the tool change, X Y corrected by the first line: passed through, the arc's centre
    # would move with the correction and its end stay (a full circle shrunk to a sliver)
    ("G21 G90 G17\nG0 X0 Y0 Z50\nM6 T2\nG3 X0 Y0 Z-2 I5 J0 F300\n", 4, "X Y", "G0 X0 Y0"),
    ("G21 G90 G18\nG0 X50 Y20 Z-10\nG28 Y0\nG2 X60 Z-10 Y-1 I5 K0 F300\n", 4, "Z X",
     "G0 X50 Z-10"),
], ids=["G17-tool-change", "G18-home"])
def test_an_absolute_arc_from_a_corrected_start_is_refused(tmp_path, text, line, off, again,
                                                           reader_path):
    code, _out, err, written = _compensate(tmp_path, text, factor=30.0)
    assert code == 2 and written is None and len(err.strip().splitlines()) == 1, err
    assert f"prog.gcode:{line}: arc G" in err and f"output stands corrected on {off}" in err, err
    # positioned again before it (uncorrected: an axis there is not known), the arc passes
    lines = text.splitlines()
    fixed = "\n".join(lines[:line - 1] + [again] + lines[line - 1:]) + "\n"
    code, _out, err, written = _compensate(tmp_path, fixed, factor=30.0)
    assert code == 0, err
    assert written.splitlines()[line - 1:] == [again, lines[-1]]

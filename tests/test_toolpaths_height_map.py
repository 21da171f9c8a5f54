"""uCNC's height map (G39 probes a grid and applies it to Z; G39.1 off, G39.2 on): the G39 line
passes through as written, Z is unknown until a block names it, X and Y stay correctable; what
uCNC refuses (src/core/parser.c) is refused. Checked by hand and by the corpus oracle
(tests/test_gcode_corpus.py, _check_output)."""
import pytest

from replay import compare, replay
from test_gcode_corpus import _check_output
from test_toolpaths_beagleg import TOL, _compensate

MAP = ("G90 G21 G17\nG0 X5 Y5 Z3\nG39 X0 Y0 Z-1 R2 I10 J10 F50\nG1 X10 F600\nG0 Z1\n"
       "G1 X0 Y10\nG39.1\nG1 X5\n")


@pytest.mark.parametrize("dialect", ["generic", "grbl"])
def test_the_probing_line_passes_and_z_is_lost_until_named(tmp_path, dialect):
    code, out, err, written = _compensate(tmp_path, MAP, "--dialect", dialect, factor=30.0)
    assert code == 0, err
    lines, source = written.splitlines(), MAP.splitlines()
    assert lines[2] == source[2]                                   # as written
    # Z lost at the probing: the next line not corrected (a block with an axis not known is not)
    assert lines[3] == source[3]
    assert lines[4].startswith("G0 Z") and lines[4] != source[4]  # Z named: corrected
    assert lines[5].startswith("G1 X") and lines[5] != source[5]
    assert lines[6] == "G39.1" and lines[7] != source[7]
    assert "1 height map probing (uCNC's G39, line 3" in out
    assert "assumed: G39 at line 3 (uCNC's height map)" in out
    _check_output(MAP.encode(), written.encode())
    compare(MAP.encode(), written.encode(), TOL)
    # the replay (tests/replay.py) of uCNC's G39: X Y at the grid's start, Z not known
    probing = replay(MAP.encode()).moves[1]
    assert (probing.end["X"], probing.end["Y"], probing.end["Z"]) == (0, 0, None)
    wrong = written.replace(lines[3], lines[3] + " Z-1")
    with pytest.raises(AssertionError, match="writes \\['Z'\\]"):
        _check_output(MAP.encode(), wrong.encode())


def test_the_map_ends_with_the_program_on_grbl(tmp_path):
    # uCNC resets its modes at M2 (parser.c, parser_reset: height_map_active = 0) and a sender
    # streams on: an arc in G18 after it is read
    text = "G0 X0 Y0 Z1\nG39 Z-1 R1 I10 J10\nG0 Z1\nM2\nG18 G2 X5 Z1 I2.5 K0\n"
    code, _out, err, written = _compensate(tmp_path, text, "--dialect", "grbl")
    assert code == 0, err
    code, _out, err, written = _compensate(tmp_path, text.replace("M2\n", ""), "--dialect", "grbl")
    assert code == 2 and "while uCNC's height map (G39) is on" in err


@pytest.mark.parametrize("text, extra, message", [
    ("G0 X0 Y0 Z1\nG39 Z-1 I10 J10\n", [], "G39 (uCNC's height map) without R"),
    ("G0 X0 Y0 Z1\nG18\nG39 Z-1 R1 I10 J10\n", [], "G39 (uCNC's height map) not in G17"),
    ("G0 X0 Y0 Z1\nG39 Z-1 R1 I-10 J10\n", [], "with a negative I or J"),
    ("G0 X0 Y0 Z1\nG39 G1 Z-1 R1 I10 J10\n", [], "G39 (uCNC's height map) and motion G1"),
    ("G0 X0 Y0 Z1\nG39 Z-1 R1 I10 J10\nX5\n", [], "coordinates without a motion mode"),
    ("G0 X0 Y0 Z1\nG39 Z-1 R1 I10 J10\nG0 Z1\nG18 G2 X5 Z1 I2.5 K0\n", [],
     "arc G2 in G18 while uCNC's height map (G39) is on"),
    ("G0 X0. Y0. Z1.\nG39 Z-1. R1. I10. J10.\n", ["--dialect", "fanuc"], "G39 is not a code mtcomp "
     "follows on fanuc"),
])
def test_what_ucnc_refuses_or_mtcomp_does_not_read(tmp_path, text, extra, message):
    code, _out, err, written = _compensate(tmp_path, text, *extra)
    assert code == 2 and written is None and message in err, err
    assert len(err.strip().splitlines()) == 1

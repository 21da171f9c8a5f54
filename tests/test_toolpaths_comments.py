"""A comment that holds parentheses, `(HSS Twist Drill, 3mm (R))` (Estlcam's tool names) and
`(2D Contour (cutout))` (a Fusion 360 post's operation names), on both reader paths: read as one
comment where every reading agrees that it holds no word (a control that nests parentheses, and one
that ends the comment at its first ')' and finds only ')' after it), the line written as it is
(in a move only the corrected words change), said once; refused where a reading sees code after
the first ')', and on the controllers that stop on it (LinuxCNC: "Nested comment found"; grbl:
error 1 on the ')' left after the comment).

The expected moves are written out by hand; the old reader refused every one of these lines
("comment '(' is not closed on this line (or is nested)")."""
import numpy as np
import pytest

from mtcomp.errors import InputError
from mtcomp.machine import load_machine
from mtcomp.toolpaths import iter_segment_chunks
from mtcomp.toolpaths.gcode import write_corrected
from mtcomp.toolpaths.source import open_program
from mtcomp.toolpaths.words import SourceLine, strip_comments, tokenize
from replay import without_comments
from test_toolpaths_dialect import mode  # noqa: F401  (the fixture: both reader paths)

XFYZ = load_machine("xfyz")
ESTLCAM = "(HSS Twist Drill, 3mm (R))"
FUSION = "(2D Contour (cutout))"
PROGRAM = ("G21 G90\n" + ESTLCAM + "\nG0 X1. Y2. Z3.\n" + FUSION + "\n"
           "G1 X4. F100 (T1 D=3 (flat) (end mill)) Y5.\nM30\n")


def _written(tmp_path, text: str, dialect: str | None = None) -> tuple[list, list, list]:
    """(the written lines, the rows' end points, the notes) of a program written with every row
    corrected by dX = +10 um, dY = -20 um, dZ = +30 um."""
    src_path, out = tmp_path / "in.nc", tmp_path / "out.nc"
    src_path.write_text(text)
    with open_program(src_path, dialect) as src:
        chunks = list(iter_segment_chunks(src, XFYZ))
        delta = np.array([0.010, -0.020, 0.030])
        corrections = [(c, c.end + delta, np.ones(len(c), np.int64)) for c in chunks]
        write_corrected(src, out, XFYZ, corrections)
        notes = list(src.notes)
    ends = np.vstack([c.end for c in chunks])
    return out.read_text().splitlines(), ends, notes


@pytest.mark.parametrize("dialect", [None, "generic", "fanuc", "haas"])
def test_the_two_real_forms_pass_as_written(tmp_path, mode, dialect):
    lines, ends, notes = _written(tmp_path, PROGRAM, dialect)
    src = PROGRAM.splitlines()
    assert lines[1] == src[1] and lines[3] == src[3] and lines[5] == src[5]
    # by hand: X 1 + 0.010, Y 2 - 0.020, Z 3 + 0.030; then X 4.010, Y 4.980, the comment kept
    # between the corrected words
    assert lines[2] == "G0 X1.0100 Y1.9800 Z3.0300"
    assert lines[4] == "G1 X4.0100 F100 (T1 D=3 (flat) (end mill)) Y4.9800"
    np.testing.assert_allclose(ends, [[1, 2, 3], [4, 5, 3]], rtol=0, atol=1e-12)
    said = [n for n in notes if "comment holding parentheses" in n]
    assert len(said) == 1 and "line 2" in said[0] and ESTLCAM in said[0]


@pytest.mark.parametrize("line", [
    "(a (b) X1)",                     # a first-')' reading moves X
    "G1 X1 (tool (R) Y2)",
    "(Drill (3mm) bit)",              # and here reads 'bit' as code
])
def test_a_reading_that_sees_code_after_the_first_paren_is_refused(tmp_path, mode, line):
    p = tmp_path / "p.nc"
    p.write_text("G21 G90\nG0 X0 Y0 Z0\n" + line + "\n")
    with pytest.raises(InputError, match=r"p\.nc:3: comment '\(' holds parentheses, and a "
                                         r"control that ends it at its first '\)' reads"):
        list(iter_segment_chunks(p, XFYZ, dialect="generic"))


@pytest.mark.parametrize("dialect, rule", [
    ("linuxcnc", "Nested comment found"),
    ("grbl", "error 1"),
])
def test_the_controllers_that_stop_on_it_refuse_it(tmp_path, mode, dialect, rule):
    p = tmp_path / "p.nc"
    p.write_text(PROGRAM)
    with pytest.raises(InputError, match="comment '\\(' holds parentheses") as exc:
        list(iter_segment_chunks(p, XFYZ, dialect=dialect))
    assert rule in exc.value.message and ":2:" in str(exc.value)


def test_a_comment_not_closed_is_still_refused(tmp_path, mode):
    p = tmp_path / "p.nc"
    p.write_text("G21\n(a (b)\n")
    with pytest.raises(InputError, match=r"p\.nc:2: comment '\(' is not closed on this line"):
        list(iter_segment_chunks(p, XFYZ, dialect="generic"))


@pytest.mark.parametrize("text, code", [
    (ESTLCAM, ""), (FUSION, ""), ("G1 X1 ( a ( b ) ) Y 2", "G1 X1  Y 2"),
    ("(a (b) (c)) Z1", " Z1"), ("X1 (a) Y2 ;c (d (e", "X1  Y2 "),
])
def test_the_words_outside_comments_match_the_replay(text, code):
    # the replay's reading (innermost comments removed until none is left, against the one that
    # ends a comment at its first ')') and the reader's give the same code
    assert strip_comments(text) == code
    assert without_comments(text).replace(" ", "") == code.replace(" ", "")
    words = [t for t in tokenize(text) if t[0] not in "(;"]
    assert "".join(w[2] for w in words) == code.replace(" ", "")


def test_the_source_line_keeps_the_comment_whole():
    line = SourceLine("G1 X1 (2D Contour (cutout)) Y 2")
    assert [w[0] for w in line.words] == ["G", "X", "(", "Y"]
    comment = line.words[2]
    assert line.text[comment[1]:comment[3]] == FUSION

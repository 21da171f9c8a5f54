"""Heidenhain TNC conversational programs: read as the TNC moves (hand-derived from the
conversational manuals' rules), written back with only the corrected numbers changed, refused in
one line naming the construct."""
import contextlib
import io

import numpy as np
import pytest

import replay_heidenhain
from mtcomp.cli import main
from mtcomp.errors import InputError
from mtcomp.machine import load_machine
from mtcomp.toolpaths import iter_segment_chunks, read_program, write_corrected
from mtcomp.toolpaths.source import open_program

XFYZ = load_machine("xfyz")

PROGRAM = """0 BEGIN PGM T MM
1 CYCL DEF 7.0 DATUM SHIFT
2 CYCL DEF 7.1 X+10
3 TOOL CALL 1 Z S1000
4 L X+0 Y+0 Z+5 FMAX
5 L Z-1 F100
6 L IX+20
7 CC X+25 Y+0
8 C X+30 Y+0 DR+
9 L Z+5 FMAX
10 CYCL DEF 1.0 PECKING
11 CYCL DEF 1.1 DIST2
12 CYCL DEF 1.2 DEPTH-10
13 CYCL DEF 1.3 PLNGNG3
14 CYCL DEF 1.4 DWELL0
15 CYCL DEF 1.5 F200
16 L X+50 Y+10 FMAX M99
17 L Z-10 FMAX M91
18 END PGM T MM
"""


def _write(tmp_path, text, name="p.h"):
    p = tmp_path / name
    p.write_bytes(text.encode("latin-1"))
    return p


def test_detected_and_read_as_the_tnc_moves(tmp_path):
    """By hand: the datum shift X+10 moves every X by 10; IX+20 goes 20 on from X+10; the arc
    about CC (25, 0) + shift runs from X30 to X40 counter-clockwise (DR+: from the angle of 180
    deg up to 360, through Y-5); the hole
    drills from the start Z+5 down by the set-up clearance 2 and the depth 10 (Z-7)."""
    p = _write(tmp_path, PROGRAM)
    with open_program(p) as src:
        assert src.dialect.name == "heidenhain" and "line 1" in src.why
    prog = read_program(p, XFYZ)
    ends = {b.line: b.end.tolist() for b in prog.blocks}
    assert ends == {5: [10, 0, 5], 6: [10, 0, -1], 7: [30, 0, -1], 9: [40, 0, -1],
                    10: [40, 0, 5], 17: [60, 10, 5]}
    arc = next(b for b in prog.blocks if b.line == 9)
    assert arc.motion == 3
    np.testing.assert_allclose(arc.centre[:2], [35.0, 0.0], rtol=0, atol=1e-12)
    mid = arc.points[len(arc.points) // 2]
    assert mid[1] < -4.9                     # counter-clockwise from X30: through Y-5
    hole = next(b for b in prog.blocks if b.line == 17)
    assert hole.cycle.r_level == 5.0 and hole.points.tolist() == [[60, 10, -7]]
    # TOOL CALL: the tool length of H1 (frame 16 * H), Z unknown until line 5 names it
    assert {b.frame for b in prog.blocks} == {16}


def _shifted(path, c):
    for chunk in iter_segment_chunks(path, XFYZ):
        yield chunk, chunk.end + c, np.ones(len(chunk), np.int64)


def test_a_constant_correction_is_written_in_place(tmp_path):
    """A correction of (+1, -2, +3) um everywhere: every written position is the source's plus it,
    in the signed form with 4 decimals, the centre moved with it, IX+20 unchanged (both of its
    ends move alike), the hole's start level moved by the Z correction; every other line as it
    was."""
    p = _write(tmp_path, PROGRAM)
    out = tmp_path / "o.h"
    write_corrected(p, out, XFYZ, _shifted(p, np.array([0.001, -0.002, 0.003])))
    expected = PROGRAM.splitlines()
    expected[4] = "4 L X+0.0010 Y-0.0020 Z+5.0030 FMAX"
    expected[5] = "5 L Z-0.9970 F100"
    expected[7] = "7 CC X+25.0010 Y-0.0020"
    expected[8] = "8 C X+30.0010 Y-0.0020 DR+"
    expected[9] = "9 L Z+5.0030 FMAX"
    expected[16] = "16 L X+50.0010 Y+9.9980 FMAX M99"
    assert out.read_text().splitlines() == expected
    # no correction: the same bytes
    write_corrected(p, out, XFYZ, None)
    assert out.read_bytes() == p.read_bytes()


def test_an_axis_the_block_does_not_name_is_added_and_incremental_words_take_the_difference(
        tmp_path):
    """A correction that grows with X (1 um per 10 mm on Y): the IX+20 block ends at X30 (G-code
    frame) where Y is corrected by 3 um, its start X10 by 1 um: Y-0.0030 is added after IX+20,
    the X correction 0 keeps IX+20."""
    p = _write(tmp_path, PROGRAM)
    out = tmp_path / "o.h"

    def corrections():
        for chunk in iter_segment_chunks(p, XFYZ):
            pts = chunk.end.copy()
            pts[:, 1] += 1e-4 * chunk.end[:, 0]
            yield chunk, pts, np.ones(len(chunk), np.int64)
    write_corrected(p, out, XFYZ, corrections())
    lines = out.read_text().splitlines()
    assert lines[4] == "4 L X+0 Y+0.0010 Z+5 FMAX"
    assert lines[6] == "6 L IX+20 Y+0.0030"


def test_the_replay_sees_the_arc_and_the_hole():
    moves = replay_heidenhain.replay(PROGRAM.encode()).moves
    arc = next(m for m in moves if m.kind == "arc")
    assert arc.centre == (35.0, 0.0) and arc.sweep == pytest.approx(np.pi, rel=0, abs=1e-12)
    holes = [m for m in moves if m.line == 16]
    assert [(m.end["X"], m.end["Y"], m.end["Z"]) for m in holes] == [
        (60, 10, 5), (60, 10, -7), (60, 10, 5)]


def test_an_arc_that_no_centre_holds_is_refused(tmp_path):
    """Two arcs about one CC whose corrections differ by 20 um: no single centre holds both within
    the chord tolerance, and no CC line can be added: refused, naming the arc."""
    text = ("0 BEGIN PGM T MM\n1 L X+0 Y+0 Z+0 FMAX\n2 CC X+10 Y+0\n3 C X+20 Y+0 DR-\n"
            "4 C X+0 Y+0 DR-\n5 END PGM T MM\n")
    p = _write(tmp_path, text)

    def corrections():
        for chunk in iter_segment_chunks(p, XFYZ):
            pts = chunk.end.copy()
            pts[:, 1] += np.where(chunk.line == 5, 0.02, 0.0)
            yield chunk, pts, np.ones(len(chunk), np.int64)
    with pytest.raises(InputError) as exc:
        write_corrected(p, tmp_path / "o.h", XFYZ, corrections())
    assert exc.value.line in (4, 5) and "circle centre (CC of line 3)" in exc.value.message
    assert not (tmp_path / "o.h").exists()


@pytest.mark.parametrize("block, words", [
    ("CC X+10 Y+0 RL", "radius compensation RL"),
    ("LBL 1", "label (LBL)"),
    ("CALL LBL 1", "(CALL)"),
    ("FN 0: Q1 = +5", "Q parameter function (FN)"),
    ("L X+Q1", "Q parameters"),
    ("CYCL DEF 200 DRILLING", "CYCL DEF 200"),
    ("CC IX+1 IY+1", "CC needs absolute X and Y"),
    ("CR X+1 Y+1 R+5 DR+", "radius (CR)"),
    ("L X+1 FMAX M128", "M128"),
    ("CYCL CALL", "CYCL CALL"),
    ("TOOL CALL 1 X", "tool axis X"),
    ("L X+1 FMAX M99", "without a pecking cycle"),
    ("PLANE SPATIAL SPA+0 SPB+0 SPC+0", "PLANE"),
    # the whole construct, never cut off mid-word
    ("FUNCTION TCPM F TCP AXIS POS PATHCTRL AXIS", "'FUNCTION TCPM F TCP AXIS POS PATHCTRL AXIS' is not"),
])
def test_refused_in_one_line_naming_the_construct(tmp_path, block, words):
    p = _write(tmp_path, f"0 BEGIN PGM T MM\n1 L X+0 Y+0 Z+5 FMAX\n2 {block}\n3 END PGM T MM\n")
    out = tmp_path / "o.h"
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        code = main(["compensate", "xfyz", _zero_model(tmp_path), str(p), "-o", str(out),
                     "--quiet"])
    lines = err.getvalue().strip().splitlines()
    assert code == 2 and not out.exists() and len(lines) == 1, err.getvalue()
    assert "p.h:3:" in lines[0] and words in lines[0], lines[0]
    assert lines[0].endswith("(block 2)"), lines[0]        # the TNC's block number of line 3


def _zero_model(tmp_path) -> str:
    from mtcomp.models import ErrorModel, FittedModel, save_model
    path = tmp_path / "zero.json"
    if not path.exists():
        save_model(path, FittedModel.zero(ErrorModel(XFYZ)))
    return str(path)


def test_a_gcode_program_given_as_heidenhain_is_refused_at_its_first_line(tmp_path):
    p = _write(tmp_path, "G0 X1 Y2\n", "p.nc")
    with pytest.raises(InputError) as exc:
        with open_program(p, "heidenhain"):
            pass
    assert exc.value.line == 1 and "Heidenhain" in exc.value.message


@pytest.mark.parametrize("shift_um, noted", [(0.0, False), (20.0, True)])
def test_an_arc_kept_within_a_larger_tolerance_says_how_far_it_misses(tmp_path, shift_um, noted):
    """The same two arcs with a chord tolerance of 25 um: one centre holds both, and the note says
    by how much the written arcs miss their corrected path (at most the tolerance; none when the
    correction is constant and the arcs follow it exactly)."""
    text = ("0 BEGIN PGM T MM\n1 L X+0 Y+0 Z+0 FMAX\n2 CC X+10 Y+0\n3 C X+20 Y+0 DR-\n"
            "4 C X+0 Y+0 DR-\n5 END PGM T MM\n")
    p = _write(tmp_path, text)
    with open_program(p) as src:
        def corrections():
            for chunk in iter_segment_chunks(src, XFYZ, chord_tol_mm=0.025):
                pts = chunk.end.copy()
                pts[:, 1] += np.where(chunk.line == 5, shift_um * 1e-3, 0.0) + 0.001
                yield chunk, pts, np.ones(len(chunk), np.int64)
        write_corrected(src, tmp_path / "o.h", XFYZ, corrections(), chord_tol_mm=0.025)
        notes = [n for n in src.notes if "miss their corrected path" in n]
    assert (tmp_path / "o.h").is_file()
    assert bool(notes) == noted, src.notes
    if noted:
        miss = float(notes[0].split("by up to ")[1].split(" um")[0])
        assert 0.5 < miss <= 25.0, notes[0]


def test_the_pecking_cycle_in_the_tnc_english_dialogue_reads_as_the_short_words(tmp_path):
    """CYCL DEF 1.1 SET UP and 1.3 PECKG (the TNC's English dialogue, as NX's Heidenhain posts
    write them) are the set-up clearance and the plunging depth of DIST and PLNGNG: the same
    hole (by hand above: from Z+5 down by 2 and 10 to Z-7) and, written back, the words kept."""
    english = PROGRAM.replace("1.1 DIST2", "1.1 SET UP 2").replace("1.3 PLNGNG3", "1.3 PECKG 3")
    assert english != PROGRAM
    p = _write(tmp_path, english)
    hole = next(b for b in read_program(p, XFYZ).blocks if b.line == 17)
    assert hole.cycle.r_level == 5.0 and hole.points.tolist() == [[60, 10, -7]]
    # corrected, the hole's start level moves with Z as with the short words; the rest is kept
    out = tmp_path / "o.h"
    write_corrected(p, out, XFYZ, _shifted(p, np.array([0.001, -0.002, 0.003])))
    lines = out.read_text().splitlines()
    assert lines[11] == "11 CYCL DEF 1.1 SET UP 2" and lines[13] == "13 CYCL DEF 1.3 PECKG 3"
    assert lines[16] == "16 L X+50.0010 Y+9.9980 FMAX M99"

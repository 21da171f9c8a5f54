"""Heidenhain TNC programs in DIN/ISO: read as the TNC moves (hand-derived from the iTNC 530 ISO
programming manual's rules: `%NAME G71 *` ... `N99999999 %NAME G71 *`, blocks ending in `*`,
modal G00-G03, G90/G91, the circle centre I J), written back with only the corrected numbers
changed, refused in one line naming the construct."""
import numpy as np
import pytest

from mtcomp.machine import load_machine
from mtcomp.toolpaths import read_program, write_corrected
from mtcomp.toolpaths.source import open_program
from test_toolpaths_heidenhain import _written_with, assert_refused

XFYZ = load_machine("xfyz")

PROGRAM = """%KONTUR G71 *
N10 G30 G17 X+0 Y+0 Z-20 *
N20 G31 G90 X+100 Y+100 Z+0 *
N30 G99 T1 L+0 R+5 *
N40 T1 G17 S2000 *
N50 G00 G40 G90 Z+50 M3 *
N55 ;ROUGHING * NO MOVE *
N60 X+0 Y+0 *
N70 G01 Z-1 F200 *
N80 G91 X+20 *
N90 G90 I+25 J+0 *
N100 G03 X+30 Y+0 *
N110 G02 X+20 *
N120 G00 Z+50 *
N99999999 %KONTUR G71 *
"""


def _write(tmp_path, text, name="p.i"):
    p = tmp_path / name
    p.write_bytes(text.encode("latin-1"))
    return p


def test_detected_and_read_as_the_tnc_moves(tmp_path):
    """By hand: the blank form (G30/G31), the tool definition G99 and the comment make no move;
    N60 moves at rapid (G00 in force) to X0 Y0; G91 X+20 goes 20 on from X0; the arc N100 about
    I J (25, 0) runs counter-clockwise from X20 to X30 (through Y-5), N110 back clockwise to X20
    (its Y the last programmed, 0); the tool call leaves Z unknown until N50 names it."""
    p = _write(tmp_path, PROGRAM)
    with open_program(p) as src:
        assert src.dialect.name == "heidenhain" and "line 1" in src.why
    blocks = read_program(p, XFYZ).blocks
    ends = {b.line: [None if not k else float(v) for v, k in zip(b.end, b.known)]
            for b in blocks}
    assert ends == {6: [None, None, 50], 8: [0, 0, 50], 9: [0, 0, -1], 10: [20, 0, -1],
                    12: [30, 0, -1], 13: [20, 0, -1], 14: [20, 0, 50]}
    motions = {b.line: b.motion for b in blocks}
    assert (motions[8], motions[9], motions[12], motions[13], motions[14]) == (0, 1, 3, 2, 0)
    for line in (12, 13):
        arc = next(b for b in blocks if b.line == line)
        np.testing.assert_allclose(arc.centre[:2], [25.0, 0.0], rtol=0, atol=1e-12)
        assert arc.points[len(arc.points) // 2][1] < -4.9          # through Y-5
    # the first block numbered as the TNC numbers the last one reads alike
    again = _write(tmp_path, PROGRAM.replace("%KONTUR", "N99999999 %KONTUR", 1), "q.i")
    assert [b.end.tolist() for b in read_program(again, XFYZ).blocks] == \
        [b.end.tolist() for b in blocks]


def test_written_back_with_only_the_corrected_words(tmp_path):
    """A correction of (+1, -2, +3) um everywhere: every written position is the source's plus it
    in the signed form with 4 decimals, the centre I J moved with it, G91 X+20 unchanged (both of
    its ends move alike), X+20 of N110 with its Y unwritten (it stays -0.002, as written before);
    every other line, the ` *` block ends and the first and last blocks, byte for byte."""
    lines, _notes = _written_with(tmp_path, PROGRAM, lambda c: np.tile([0.001, -0.002, 0.003],
                                                                       (len(c), 1)))
    changed = {5: "N50 G00 G40 G90 Z+50.0030 M3 *", 7: "N60 X+0.0010 Y-0.0020 *",
               8: "N70 G01 Z-0.9970 F200 *", 10: "N90 G90 I+25.0010 J-0.0020 *",
               11: "N100 G03 X+30.0010 Y-0.0020 *", 12: "N110 G02 X+20.0010 *",
               13: "N120 G00 Z+50.0030 *"}
    assert lines == [changed.get(i, ln) for i, ln in enumerate(PROGRAM.splitlines())]
    p = _write(tmp_path, PROGRAM)
    write_corrected(p, tmp_path / "same.i", XFYZ, None)
    assert (tmp_path / "same.i").read_bytes() == p.read_bytes()


def test_words_added_to_a_g91_block_are_increments(tmp_path):
    """Y corrected by 1 um plus 1 um per 10 mm of X. By hand: N20 (G91 X+20, from X0 Y+0.0010
    written) ends where Y is corrected by 3 um: Y+0.0020 is added, the increment; N30 ends at X30
    (Y+0.0040, absolute under G90); the incremental arc N40 back to X20 ends at Y 0.003:
    Y-0.0010 from the 0.004 written before."""
    text = ("%T G71 *\nN10 G00 X+0 Y+0 Z+5 *\nN20 G91 G01 X+20 F100 *\nN25 G90 I+25 J+0 *\n"
            "N30 G02 X+30 *\nN40 G91 G03 X-10 *\nN99999999 %T G71 *\n")
    lines, _notes = _written_with(tmp_path, text, lambda c: np.column_stack(
        [np.zeros(len(c)), 0.001 + 1e-4 * c.end[:, 0], np.zeros(len(c))]))
    assert lines[1] == "N10 G00 X+0 Y+0.0010 Z+5 *"
    assert lines[2] == "N20 G91 G01 X+20 Y+0.0020 F100 *"
    assert lines[4] == "N30 G02 X+30 Y+0.0040 *"
    assert lines[5] == "N40 G91 G03 X-10 Y-0.0010 *"


def test_machine_move_before_any_path_function_passes_through(tmp_path):
    """`N10 G90 Z-25. M91 *` before any G00/G01 (Siemens NX's Mikron post begins so): a straight
    move to a machine position, at rapid or at the feed alike, passed through as written; Z is not
    known after it (machine coordinates), so N30 writes X and Y only and N40's Z is corrected;
    the path function is still not in force after it (N20 without G00-G03 is refused)."""
    text = ("%T G71 *\nN10 G90 Z-25. M91 *\nN20 G0 X+50 Y-10 *\nN30 X+60 *\nN40 Z+110 *\n"
            "N99999999 %T G71 *\n")
    blocks = read_program(_write(tmp_path, text), XFYZ).blocks
    assert [(b.line, b.known.tolist()) for b in blocks] == [
        (3, [True, True, False]), (4, [True, True, False]), (5, [True, True, True])]
    lines, _notes = _written_with(tmp_path, text, lambda c: np.where(c.known, 0.001, 0.0))
    assert lines[1:5] == ["N10 G90 Z-25. M91 *", "N20 G0 X+50.0010 Y-9.9990 *",
                          "N30 X+60.0010 *", "N40 Z+110.0010 *"]
    p = _write(tmp_path, text.replace("N20 G0 X+50", "N20 X+50"), "q.i")
    assert_refused(tmp_path, p, "q.i:3:", "axis words without G00, G01, G02 or G03 in force",
                   "(block N20)")


#: a block of the program and what its refusal names
REFUSED = {
    "G05 X+10 Y+10": "circle without a direction of rotation (G05)",
    "G11 R+10 H+30": "polar coordinates",
    "G98 L1": "label (G98)",
    "G01 X+Q1": "Q parameters",
    "G200 Q200=+2": "Q parameters",
    "G201": "the cycle G201",
    "G01 X+1 M128 M91": "M91, M92, M99 or radius compensation RL/RR in tool centre point mode",
    "G91 I+5 J+5": "absolute I and J",
    "I+5 J+5 X+1": "absolute I and J",
    "G02 X+10 Y+10 R+5": "a radius (R)",
    "G54 X+10": "datum shift (G54)",
    "G18": "working plane other than XY (G18)",
    "K+5": "circle centre K",
    "G01 X+1 M99": "M99",
    "G02 X+10": "before any circle centre I J",
}


@pytest.mark.parametrize("block, words", sorted(REFUSED.items()))
def test_refused_in_one_line_naming_the_construct(tmp_path, block, words):
    p = _write(tmp_path, f"%T G71 *\nN10 G00 X+0 Y+0 Z+5 *\nN20 {block} *\nN99999999 %T G71 *\n")
    assert_refused(tmp_path, p, "p.i:3:", words, "(block N20)")


# M128 ... M129 in a DIN/ISO program (HEIDENHAIN, TNC 620 User's Manual for DIN/ISO Programming,
# 2013, "Maintaining the position of the tool tip when positioning with tilted axes (TCPM): M128"):
# the tool centre point mode as in a conversational program, M129 ending it at the end of its block
ISO_TCP = """%TCP G71 *
N10 G00 X+40 Y+0 Z+60 A-30 C+10 M128 *
N20 G01 Z+20 F400 *
N30 X+30 Y+10 A-20 C+20 *
N40 X+20 *
N50 G00 Z+50 M129 *
N99999999 %TCP G71 *
"""
CONVERSATIONAL_TCP = """0 BEGIN PGM TCP MM
1 L X+40 Y+0 Z+60 A-30 C+10 FMAX M128
2 L Z+20 F400
3 L X+30 Y+10 A-20 C+20
4 L X+20
5 L Z+50 FMAX M129
6 END PGM TCP MM
"""


def _axis_words(text: str) -> list:
    """The axis words of each line with a move, in order: [{letter: value}]."""
    import re
    rows = [dict((a, float(v)) for a, v in re.findall(r"(?<![A-Z])([XYZAC])([-+]\d+\.?\d*)", line))
            for line in text.splitlines()]
    return [r for r in rows if r]


def test_m128_in_an_iso_program_is_compensated_as_its_conversational_twin(tmp_path):
    """The DIN/ISO program and its conversational twin (the same moves in M128), compensated with
    one model on the five-axis CAFXYZ (a 30 um X backlash, random geometry), are written with the
    same numbers: the twin's tool centre point compensation is checked on the independent machine
    (test_toolpaths_tcp.py, test_toolpaths_tcp_directions.py)."""
    from mtcomp.cli import main
    from mtcomp.models import Backlash, save_model
    from test_export_formats import random_model
    fm = random_model("cafxyz", (Backlash("X"),), 5, 3.0, None)
    fm.params.set_file_value("BL_X", 30.0)
    model = tmp_path / "model.json"
    save_model(model, fm)
    written = []
    for name, text in (("p.i", ISO_TCP), ("p.h", CONVERSATIONAL_TCP)):
        src, out = _write(tmp_path, text, name), tmp_path / ("o" + name)
        assert main(["compensate", "cafxyz", str(model), str(src), "-o", str(out), "--quiet"]) == 0
        written.append(_axis_words(out.read_text()))
    iso, conv = written
    assert len(iso) == len(conv) == 5
    assert iso == conv
    assert iso != _axis_words(ISO_TCP)                  # corrected
    assert "M128" in out.read_text() and "M129" in out.read_text()


def test_the_tcp_mode_refuses_in_an_iso_program_what_it_refuses_in_a_conversational_one(tmp_path):
    for block, words in (("T1 G17 S1000", "a tool call T (the TNC asks for the mode reset before "
                                           "it)"), ("I+5 J+0", "a circle centre I J"),
                         ("G41 G01 X+5", "radius compensation RL/RR")):
        p = _write(tmp_path, f"%T G71 *\nN10 G00 X+0 Y+0 Z+5 M128 *\nN20 {block} *\n"
                             "N99999999 %T G71 *\n")
        assert_refused(tmp_path, p, "p.i:3:", words + " in tool centre point mode", "(block N20)")

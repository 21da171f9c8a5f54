"""The Siemens Sinumerik dialect (mtcomp.toolpaths.sinumerik, sinumerik_out) against hand-derived
cases, and a compensated program against the independent replay of tests/replay_sinumerik.py."""
import csv
import math
import re

import numpy as np
import pytest

import replay_sinumerik
from replay import Tolerance
from mtcomp.cli import main
from mtcomp.errors import InputError
from mtcomp.machine import load_machine
from mtcomp.toolpaths.dialect import detect
from mtcomp.toolpaths.gcode import iter_segment_chunks, read_program, write_corrected
from mtcomp.toolpaths.offsets import ProgramSetup
from mtcomp.toolpaths.sinumerik import translate
from mtcomp.toolpaths.source import open_program
from mtcomp.toolpaths.sinumerik_lang import evaluate
from mtcomp.toolpaths.sinumerik_out import corrected_text
from test_gcode_corpus import _machine_file, _model_file

HEAD = "%_N_TEST_MPF\r\n;$PATH=/_N_MPF_DIR\r\n"


def _write(tmp_path, body: str, name="t.mpf"):
    path = tmp_path / name
    path.write_bytes((HEAD + body.replace("\n", "\r\n")).encode("latin-1"))
    return path


def _blocks(path, machine="xfyz"):
    return read_program(path, load_machine(machine)).blocks


def _source_lines(path, lines):
    """The source lines (1-based) of lines of the program's G-code equivalent."""
    with open_program(path) as src:
        return src.source_lines_of(lines).tolist()


def test_a_sinumerik_program_is_detected_from_its_header_or_a_def(tmp_path):
    d, why = detect(_write(tmp_path, "G0 X1\n"))
    assert d.name == "sinumerik" and why == "detected from line 1: %_N_TEST_MPF"
    plain = tmp_path / "p.nc"
    plain.write_text("N10 DEF REAL A=1\nG0 X=A\n")
    assert detect(plain)[0].name == "sinumerik"


def test_a_program_that_sets_r_parameters_is_read_as_sinumerik(tmp_path):
    """No header, DEF, cycle or MSG: blocks that set arithmetic parameters (`R1=5`; Fundamentals,
    "Arithmetic parameters (R)") show a Sinumerik program, to the reader and to the replay alike
    (read as generic G-code, `R1=5` was refused: "unexpected character '='"). By hand: R1 = 5,
    R2 = 5 * 2 + 1 = 11; the blocks go to (5, 11, 10), then X = 5 + 11 = 16 at F = 1100."""
    p = tmp_path / "p.nc"
    p.write_text("; a plate\nR1=5 ; origin X\nR2=R1*2+1\nG17 G90 G94\nG0 X=R1 Y=R2 Z10\n"
                 "G1 X=R1+R2 F=R2*100\nM30\n")
    d, why = detect(p)
    assert d.name == "sinumerik" and why == "detected from line 2: R1=5 ; origin X"
    assert replay_sinumerik.is_sinumerik(p.read_bytes())
    first, second = _blocks(p)
    np.testing.assert_allclose([first.end[:3], second.end[:3]], [[5, 11, 10], [16, 11, 10]],
                               rtol=0, atol=1e-12)
    assert second.feed == pytest.approx(1100.0, rel=0, abs=1e-9)


@pytest.mark.parametrize("head", ["%_N_PART_MPF\n;$PATH=/_N_MPF_DIR\nG0 X1\n",
                                  "%MPF  90\n( SINUMERIK 850 )\nG0 X1\n"])
def test_the_840d_and_850_headers_are_read_as_sinumerik(tmp_path, head):
    p = tmp_path / "p.nc"
    p.write_text(head)
    with open_program(p) as src:
        assert src.dialect.name == "sinumerik" and src.sinumerik.gcode == ["G0 X1"]


def test_def_real_and_r_parameters_give_the_value_of_an_expression(tmp_path):
    # A = 12.5, B = 2 * 12.5 + 1. = 26, R1 = (26 - 6) / 4 = 5: by hand
    path = _write(tmp_path, "DEF REAL A=12.5\nDEF REAL B=A*2+1.\nN10 R1=(B-6)/4\n"
                            "N20 G0 X=B Y=R1 Z=A+60 F1000\nN30 M30\n")
    (block,) = _blocks(path)
    np.testing.assert_allclose(block.end[:3], [26.0, 5.0, 72.5], rtol=0, atol=1e-12)
    assert _source_lines(path, [block.line]) == [6]     # the source line (1-based)
    # the manual's functions take degrees
    assert evaluate("SIN(30)+SQRT(16)", {}.__getitem__) == pytest.approx(4.5, rel=0, abs=1e-15)


def test_a_full_circle_about_an_absolute_centre_ends_where_it_starts(tmp_path):
    # from (0, 140) about (0, 92.07), G3 without an end point: the full circle, radius 47.93
    path = _write(tmp_path, "DEF REAL H=143.35\nN10 G0 G17 X0 Y140 Z=H F500\n"
                            "N20 G1 Y140.\nN30 G3 I=AC(0) J=AC(92.07)\nN40 G2 I0 J-47.93\nM30\n")
    blocks = _blocks(path)
    for arc, ccw in zip(blocks[-2:], (True, False)):
        np.testing.assert_allclose(arc.end[:3], [0.0, 140.0, 143.35], rtol=0, atol=1e-12)
        np.testing.assert_allclose(arc.centre[:2], [0.0, 92.07], rtol=0, atol=1e-12)
        assert arc.motion == (3 if ccw else 2)
        # its chords go once around: the point across from the start is on it
        assert np.min(np.hypot(arc.points[:, 0], arc.points[:, 1] - (92.07 - 47.93))) < 0.5


def test_holes2_drills_its_six_holes_on_the_circle(tmp_path):
    # HOLES2(CPA 0, CPO 0, RAD 10, STA1 0, INDA 60, NUM 6): the holes at 0, 60, ... 300 deg, by
    # hand (10 cos, 10 sin) with sin 60 = sqrt(3)/2; each drilled to RFP 5 less DPR 3 = 2 (the
    # G-code equivalent holds 10 decimals)
    s = 10 * math.sqrt(3) / 2
    path = _write(tmp_path, "N10 G0 X0 Y0 Z20 F300\nN20 MCALL CYCLE81(15,5,1,,3)\n"
                            "N30 HOLES2(0,0,10,0,60,6)\nN40 MCALL\nM30\n")
    holes = [b for b in _blocks(path) if b.cycle is not None]
    want = [(10, 0), (5, s), (-5, s), (-10, 0), (-5, -s), (5, -s)]
    np.testing.assert_allclose([b.points[-1][:3] for b in holes],
                               [(x, y, 2.0) for x, y in want], rtol=0, atol=1e-9)
    assert all(b.cycle.r_level == pytest.approx(6.0, rel=0, abs=1e-12) for b in holes)
    # after each hole the tool stands at RTP 15 (the retract the translation adds)
    gcode = translate(path).gcode
    ends = [k for k, g in enumerate(gcode) if g == "G80"]
    assert len(ends) == 6 and all(gcode[k + 1] == "G0 Z15" for k in ends)


def test_a_subprogram_not_in_the_file_makes_every_axis_unknown(tmp_path):
    path = _write(tmp_path, "N10 G0 X1 Y2 Z3 F100\nN20 L54\nN30 X4\nN40 Y5 Z6\nM30\n")
    blocks = _blocks(path)
    assert _source_lines(path, [b.line for b in blocks]) == [3, 5, 6]
    assert blocks[1].known.tolist() == [True, False, False]
    assert blocks[2].known.tolist() == [True, True, True]
    # an R parameter the subprogram may have set is refused where a move uses it
    bad = _write(tmp_path, "N10 R1=5\nN20 L54\nN30 G0 X=R1\n", "r.mpf")
    with pytest.raises(InputError, match="R1 may hold a value a subprogram set") as e:
        translate(bad)
    assert e.value.line == 5


@pytest.mark.parametrize("body, line, words", [
    ("N10 @371 R52 K2 K0\n", 3, "the computation instruction @371"),
    ("N10 G0 X1\nN20 GOTOF END\n", 4, "program jumps (GOTOF)"),
    ("/N10 G0 X1\n", 3, "skippable block '/' that moves"),
    ("N10 G0 X1 Y1\nN20 G3 X2 Y2 AR=90\n", 4, "a circle by its opening angle (AR=)"),
    ("N10 G91 G0 X1\n", 3, "incremental dimensions G91"),
])
def test_what_is_not_read_is_refused_in_one_line(tmp_path, capsys, body, line, words):
    path = _write(tmp_path, body)
    out = tmp_path / "out.mpf"
    machine = _machine_file(tmp_path, "XFYZ")
    code = main(["compensate", str(machine), str(_model_file(tmp_path, machine)), str(path),
                 "-o", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and not out.exists()
    assert len(err) == 1 and f"t.mpf:{line}:" in err[0] and words in err[0], err


def test_a_skippable_block_that_moves_nothing_passes(tmp_path):
    path = _write(tmp_path, "N10 G0 X1 Y1 Z1 F100\n/N20 M90\nN30 X2\nM30\n")
    assert _source_lines(path, [b.line for b in _blocks(path)]) == [3, 5]


@pytest.mark.parametrize("text, nominal, corrected, want", [
    ("WYSSRU+60", 186.55, 186.5512, ("WYSSRU+60+0.0012", 186.5512)),
    ("WYSSRU+60", 186.55, 186.54876, ("WYSSRU+60-0.0012", 186.5488)),
    ("WYSSRU", 126.55, 126.55004, ("WYSSRU", 126.55)),         # rounds to nothing: kept
    ("57", 57.0, 57.00123, ("57.0012", 57.0012)),
    ("-8.", -8.0, -8.00004, ("-8.", -8.0)),
    ("92.07125", 92.07125, 92.0713, ("92.07130", 92.0713)),      # the source's 5 decimals
])
def test_a_corrected_word_keeps_its_form(text, nominal, corrected, want):
    got, said = corrected_text(text, nominal, corrected)
    assert got == want[0]
    assert said == pytest.approx(want[1], rel=0, abs=1e-12)


PROGRAM = """DEF REAL TOP=40
N10 T1
N20 M6
N30 G0 G54 X10 Y10 Z=TOP+20 F500
N40 MCALL CYCLE81(TOP+10,TOP,2,,6)
N50 X120 Y15
N60 Y80
N70 X100
N80 MCALL
N90 G0 X60 Y60 Z=TOP+30
N100 CYCLE81(TOP+30,TOP,2,,6)
N110 MCALL CYCLE81(TOP+10,TOP,2,,6)
N120 HOLES2(60,60,25,0,90,4)
N130 MCALL
N140 G1 X10 Y60 Z=TOP+2
N150 G3 I=AC(40) J=AC(60)
N160 G0 Z=TOP+50
N170 L55
N175 G0 Z=TOP+60
N180 M30
"""


def test_a_compensated_program_drills_where_the_plan_says(tmp_path, capsys):
    """The compensated program replayed as the controller runs it (tests/replay_sinumerik.py)
    drills every hole at the corrected bottom of BLOCKS.csv (each written number rounds to 0.05
    um), cuts the same circles up to the correction, and writes no axis after the L call."""
    machine = _machine_file(tmp_path, "XFYZ")
    model = _model_file(tmp_path, machine, factor=5.0)
    src = _write(tmp_path, PROGRAM)
    out, report = tmp_path / "out.mpf", tmp_path / "blocks.csv"
    code = main(["compensate", str(machine), str(model), str(src), "-o", str(out), "--report",
                 str(report), "--chord-tol-um", "5", "--units", "mm"])
    stdout, err = capsys.readouterr()
    assert code == 0, err
    assert "1 call of a subprogram not in the file (line 20" in stdout
    assert "warning: 1 call of subprograms or cycles not in the file (L55 at line 20)" in stdout
    with open(report, newline="") as f:
        rows = list(csv.DictReader(f))
    # the holes' rows: nominal Z at a bottom (RFP 40 less DPR 6 = 34)
    bottoms = [[float(r[c]) for c in ("x_mm", "y_mm", "z_mm")] for r in rows
               if r["z_mm"] and abs(float(r["z_mm"]) - float(r["cz_um"]) * 1e-3 - 34) < 1e-9]
    assert len(bottoms) == 3 + 1 + 4
    assert max(abs(float(r["cz_um"])) for r in rows if r["cz_um"]) > 1.0   # a Z correction
    drilled = [[m.end[a] for a in "XYZ"] for m in replay_sinumerik.replay(out.read_bytes()).moves
               if m.kind == "feed" and m.start["Z"] is not None and m.end["Z"] < m.start["Z"]
               and m.start["X"] == m.end["X"]]
    np.testing.assert_allclose(drilled, bottoms, rtol=0, atol=1.5e-4)
    # HOLES2 with four different corrections is written as explicit positions, and said so
    text = out.read_text(encoding="latin-1")
    assert text.splitlines()[2].startswith("; mtcomp:") and "HOLES2(" not in text
    replay_sinumerik.compare(src.read_bytes(), out.read_bytes(),
                             Tolerance(axis_mm=0.06, axis_deg=0.1, path_mm=0.1), name="t")
    # after the L call no X or Y is written (their positions are the subprogram's), and the
    # Z move is written as it stands (a block with an axis not known is not corrected)
    assert text.splitlines()[-3:] == ["N170 L55", "N175 G0 Z=TOP+60", "N180 M30"]


def _shifted(path, machine, shift, chord_tol_mm=0.001):
    """The corrections that move every point by ``shift(points)`` (mm), for write_corrected."""
    for chunk in iter_segment_chunks(path, machine, chord_tol_mm):
        yield chunk, chunk.end + shift(chunk.end), np.ones(len(chunk), np.int64)


def test_a_holes2_circle_with_one_correction_gets_its_centre_moved(tmp_path):
    # every point 10 um further in X: the circle's centre CPA 0 becomes 0.0100, the hole depth
    # and the call stay (no Z correction), the move before gets X10.0100
    machine = load_machine("xfyz")
    path = _write(tmp_path, "N10 G0 X10 Y0 Z20 F300\nN20 MCALL CYCLE81(15,5,1,,3)\n"
                            "N30 HOLES2(0,0,10,0,60,6)\nN40 MCALL\nM30\n")
    out = tmp_path / "out.mpf"
    write_corrected(path, out, machine, _shifted(path, machine, lambda p: [0.01, 0, 0]))
    lines = out.read_text(encoding="latin-1").splitlines()
    assert lines[2:6] == ["N10 G0 X10.0100 Y0 Z20 F300", "N20 MCALL CYCLE81(15,5,1,,3)",
                          "N30 HOLES2(0.0100,0,10,0,60,6)", "N40 MCALL"]


def test_holes_of_one_call_at_different_depths_restate_the_call(tmp_path):
    # Z corrected by x / 1000 (mm): the holes at X 10, 20 and 20 need RFP 5.0100, 5.0200, 5.0200:
    # the call carries the first, is restated before the second, and holds for the third
    machine = load_machine("xfyz")
    path = _write(tmp_path, "N10 G0 X0 Y0 Z20 F300\nN20 MCALL CYCLE81(15,5,1,,3)\nN30 X10\n"
                            "N40 X20\nN50 Y5\nN60 MCALL\nM30\n")
    out = tmp_path / "out.mpf"
    write_corrected(path, out, machine, _shifted(path, machine,
                                                 lambda p: np.outer([0, 0, 1e-3], p[:, 0]).T))
    lines = out.read_text(encoding="latin-1").splitlines()
    assert lines[2].startswith("; mtcomp: 1 block added")
    assert lines[4:9] == ["N20 MCALL CYCLE81(15,5.0100,1,,3)", "N30 X10",
                          "MCALL CYCLE81(15,5.0200,1,,3)", "N40 X20", "N50 Y5"]


def _lines_after(path, machine, shift, name="out.mpf"):
    """The program written with every point moved by ``shift(points)`` (mm): its lines."""
    out = path.parent / name
    write_corrected(path, out, machine, _shifted(path, machine, shift))
    return out.read_text(encoding="latin-1").splitlines()


def test_a_tool_change_makes_every_axis_unknown_until_named(tmp_path):
    # the machine maker's tool change cycle may move X, Y and Z: after M6 the block that names Z
    # alone writes Z alone, and X Y come back only where the program names them
    machine = load_machine("xfyz")
    path = _write(tmp_path, "N10 T1 M6\nN20 G54 G0 X80 Y90 Z50 F300\nN30 G1 X120 Y60\n"
                            "N40 G0 Z100\nN50 T2 M6\nN60 D1\nN70 G0 Z20\nN80 G1 X100\nN90 Y50\n"
                            "N100 M30\n")
    blocks = _blocks(path)
    assert [b.known.tolist() for b in blocks[-3:]] == [[False, False, True], [True, False, True],
                                                       [True, True, True]]
    # X and Y corrected by 1 um per 10 mm of Z: every block's written value differs from the
    # last, so the writer would add X Y wherever it held them known
    lines = _lines_after(path, machine, lambda p: np.outer(p[:, 2], [1e-4, -1e-4, 0.0]))
    assert lines[7:11] == ["N60 D1", "N70 G0 Z20", "N80 G1 X100.0020", "N90 Y49.9980"]
    # the replay of the output: Y unknown from the tool change until N90 names it
    positioned = replay_sinumerik.positioned_per_line("\n".join(lines))
    assert positioned[7][1] == set() and positioned[9][1] == {"X", "Z"}


@pytest.mark.parametrize("cycle", ["CYCLE82", "CYCLE83", "CYCLE84", "CYCLE85", "CYCLE86",
                                   "CYCLE87", "CYCLE88", "CYCLE89"])
def test_the_standard_drilling_cycles_drill_the_hole_of_cycle81(tmp_path, cycle):
    # (RTP 15, RFP 5, SDIS 1, DP -30) and the cycle's own parameters after them: the hole at
    # the positioning block's X Y, from RFP+SDIS = 6 down to DP = -30, then back to RTP 15
    more = {"CYCLE83": ",-5,,3,0.5,0.5,1,0", "CYCLE86": ",1,3,-1,-1,0,45"}.get(cycle, ",1")
    path = _write(tmp_path, f"N10 G0 X0 Y0 Z20 F300\nN20 MCALL {cycle}(15,5,1,-30,{more})\n"
                            "N30 X100 Y20\nN40 MCALL\nN50 G0 Z40\nM30\n")
    blocks = _blocks(path)
    (hole,) = [b for b in blocks if b.cycle is not None]
    np.testing.assert_allclose(hole.points[-1][:3], [100.0, 20.0, -30.0], rtol=0, atol=1e-12)
    assert hole.cycle.r_level == pytest.approx(6.0, rel=0, abs=1e-12)
    np.testing.assert_allclose(blocks[-1].start[:3], [100.0, 20.0, 15.0], rtol=0, atol=1e-12)
    # the output: the hole's levels moved by the Z correction, no Z word on the positioning block
    lines = _lines_after(path, load_machine("xfyz"), lambda p: [0.0, 0.0, 0.002])
    assert lines[3:5] == [f"N20 MCALL {cycle}(15,5.0020,1,-29.9980,{more})", "N30 X100 Y20"]


def test_an_mcall_of_a_cycle_not_read_passes_its_blocks_through(tmp_path):
    # POCKET4 runs at each positioning block: that block is kept as written (no correction, no
    # Z word), every axis is unknown after it, and the block after the cancel writes Z alone
    machine = load_machine("xfyz")
    path = _write(tmp_path, "N10 G0 X0 Y0 Z20 F300\nN20 MCALL POCKET4(15,5,1,-3,20)\n"
                            "N30 X100 Y20\nN40 Y60\nN50 MCALL\nN60 G0 Z40\nN70 X10\nM30\n")
    lines = _lines_after(path, machine, lambda p: [0.01, -0.01, 0.002])
    assert lines[2:9] == ["N10 G0 X0.0100 Y-0.0100 Z20.0020 F300",
                           "N20 MCALL POCKET4(15,5,1,-3,20)", "N30 X100 Y20", "N40 Y60",
                           "N50 MCALL", "N60 G0 Z40.0020", "N70 X10.0100"]
    with open_program(path) as src:
        assert [(k + 1, name) for k, name in src.sinumerik.subprograms] == [(5, "POCKET4"),
                                                                            (6, "POCKET4")]


def test_holes1_drills_its_row_of_holes(tmp_path):
    # HOLES1(SPCA 20, SPCO 100, STA1 30, FDIS 10, DBH 15, NUM 3): the holes 10, 25 and 40 mm from
    # (20, 100) along 30 deg, by hand with cos 30 = sqrt(3)/2, sin 30 = 1/2
    c = math.sqrt(3) / 2
    path = _write(tmp_path, "N10 G0 X0 Y0 Z20 F300\nN20 MCALL CYCLE81(15,5,1,,3)\n"
                            "N30 HOLES1(20,100,30,10,15,3)\nN40 MCALL\nM30\n")
    holes = [b.points[-1][:3] for b in _blocks(path) if b.cycle is not None]
    want = [(20 + d * c, 100 + d / 2, 2.0) for d in (10, 25, 40)]
    np.testing.assert_allclose(holes, want, rtol=0, atol=1e-9)
    # one correction for the row: its reference point moved; different ones: explicit positions
    machine = load_machine("xfyz")
    lines = _lines_after(path, machine, lambda p: [0.01, 0, 0])
    assert lines[4] == "N30 HOLES1(20.0100,100,30,10,15,3)"
    lines = _lines_after(path, machine, lambda p: np.outer(p[:, 0], [1e-4, 0, 0]))
    x = [f"{v * 1.0001:.4f}" for v, _y, _z in want]
    assert lines[5:8] == [f"N30 X{x[0]} Y{want[0][1]:.4f}", f"X{x[1]} Y{want[1][1]:.4f}",
                          f"X{x[2]} Y{want[2][1]:.4f}"]


def test_g500_returns_to_the_basic_frame_and_every_axis_is_unknown(tmp_path):
    # G54 moves everything by (100, 0, 0) mm; G500 has no settable work offset: X5 after it is
    # the machine position 5, Y and Z are not known until named
    path = _write(tmp_path, "N10 G17 G90 G71 G40 G500\nN20 G54 G0 X1 Y2 Z3 F100\nN30 G500\n"
                            "N40 X5\nN50 G0 G54 X6 Y7 Z8\nM30\n")
    blocks = _blocks(path)
    assert [b.known.tolist() for b in blocks] == [[True] * 3, [True, False, False], [True] * 3]
    with open_program(path) as src:
        chunks = list(iter_segment_chunks(path, load_machine("xfyz")))
        assert src.sinumerik.gcode.count("G59.3") == 2
    setup = ProgramSetup(load_machine("xfyz"), work_offsets={0: np.array([100.0, 0.0, 0.0])})
    ends = np.vstack([setup.apply(c)[0].end for c in chunks])
    np.testing.assert_allclose(ends[:, 0], [101.0, 5.0, 106.0], rtol=0, atol=1e-12)


@pytest.mark.parametrize("chord_tol_mm", [0.001, 0.05])
def test_a_circle_whose_rotary_correction_varies_is_refused_for_that_cause(tmp_path, chord_tol_mm):
    # B corrected by 1e-7 rad per mm of X along a full circle of radius 47.93 at B 90: its
    # correction varies by about 2 * 47.93 * 1e-7 rad = 0.00055 deg along it (by hand), more than
    # the 1e-4 deg a circle holds B within; no chord tolerance changes that
    machine = load_machine(_machine_file(tmp_path, "BFXYZ"))
    b = machine.axis_names.index("B")
    path = _write(tmp_path, "N10 G0 B90\nN20 G0 X0 Y140 Z150 F500\nN30 G1 Y140.\n"
                            "N40 G3 I=AC(0) J=AC(92.07)\nN50 G0 Z200\nM30\n")
    unit = np.zeros(machine.n_axes)
    unit[b] = 1e-7
    out = tmp_path / "out.mpf"
    with pytest.raises(InputError) as e:
        write_corrected(path, out, machine, _shifted(path, machine, lambda p: np.outer(
            p[:, machine.axis_names.index("X")], unit), chord_tol_mm), chord_tol_mm)
    assert e.value.line == 6 and not out.exists()
    got = re.search(r"the correction of B varies along the circle G2/G3 of line 6 by ([0-9.]+) "
                    r"deg", e.value.message)
    assert got is not None, e.value.message
    assert float(got.group(1)) == pytest.approx(math.degrees(2 * 47.93e-7), rel=0.02, abs=0)
    assert "--max-correction-urad 0.4" in e.value.message and "chord" in e.value.message
    # what it advises: B corrected within +-0.4 urad, the same circle is written
    write_corrected(path, out, machine, _shifted(path, machine, lambda p: np.outer(
        np.clip(p[:, machine.axis_names.index("X")], -4, 4), unit), chord_tol_mm), chord_tol_mm)
    assert out.read_text(encoding="latin-1").splitlines()[5] == "N40 G3 I=AC(0) J=AC(92.07)"


def _along(move, n=400):
    """Points (n, 3) along a replayed circle move: the angle and the radius go linearly from the
    start to the end, Z too (a controller's helix)."""
    cx, cy = move.centre
    s, e = move.start, move.end
    a0 = math.atan2(s["Y"] - cy, s["X"] - cx)
    r0, r1 = math.hypot(s["X"] - cx, s["Y"] - cy), math.hypot(e["X"] - cx, e["Y"] - cy)
    u = np.linspace(0.0, 1.0, n)
    r = r0 + (r1 - r0) * u
    return np.column_stack([cx + r * np.cos(a0 + move.sweep * u), cy + r * np.sin(a0 + move.sweep * u),
                            s["Z"] + (e["Z"] - s["Z"]) * u])


def test_a_circle_the_correction_bends_is_written_in_pieces_within_the_tolerance(tmp_path):
    # a full circle of radius 20 about (0, 0) from (20, 0) at Z -1; every point moved by 2e-4 * y
    # in X: the corrected path (20 cos t + 0.004 sin t, 20 sin t) is an ellipse whose radius
    # about any centre changes by about 4 um (by hand: r = 20 + 0.002 sin 2t), which no circle
    # holds within the 1 um default; the pieces written, replayed independently, stay within
    # 1 um of it (and 0.1 um for the written decimals) and go once around
    path = _write(tmp_path, "N10 G0 X20 Y0 Z5 F300\nN20 G1 Z-1\nN30 G3 I=AC(0) J=AC(0) F200\n"
                            "N40 G0 Z20\nM30\n")
    lines = _lines_after(path, load_machine("xfyz"), lambda p: np.outer(p[:, 1], [2e-4, 0, 0]))
    assert lines[2].startswith("; mtcomp: ") and "circle written in pieces" in lines[2]
    assert re.fullmatch(r"N30 G3 X\S+ Y\S+ I=AC\(\S+\) J=AC\(\S+\) F200", lines[5]), lines[5]
    arcs = [m for m in replay_sinumerik.replay("\n".join(lines).encode("latin-1")).moves
            if m.kind == "arc"]
    assert len(arcs) >= 2 and all(re.fullmatch(r"X\S+ Y\S+ I=AC\(\S+\) J=AC\(\S+\)",
                                               lines[m.line]) for m in arcs[1:])
    assert sum(m.sweep for m in arcs) == pytest.approx(2 * math.pi, rel=0, abs=1e-3)
    # each point's place on the ellipse (exact on it: x - 2e-4 y = 20 cos t), then searched about
    # it in steps of 1e-6 rad (0.02 um)
    got = np.vstack([_along(m) for m in arcs])
    t = np.arctan2(got[:, 1], got[:, 0] - 2e-4 * got[:, 1])[:, None] + np.linspace(-2e-4, 2e-4, 401)
    corrected = np.stack([20 * np.cos(t) + 0.004 * np.sin(t), 20 * np.sin(t), -np.ones_like(t)], -1)
    nearest = np.min(np.linalg.norm(corrected - got[:, None, :], axis=2), axis=1)
    assert nearest.max() <= 1.1e-3
    assert nearest.max() > 0.3e-3            # the pieces do use the tolerance (it is not trivial)


def test_a_bent_circle_after_lines_without_moves_is_written_in_pieces(tmp_path):
    # the circle above after comment lines and R parameters: its source line lies past the last
    # line of the program's G-code translation, and finding that no centre holds it once raised an
    # IndexError (a traceback, from looking up the radius of a translation line by a source line)
    # instead of writing it in pieces: the pieces go once around, replayed independently
    body = ("; a plate\n" * 6 + "R1=20\nR2=0\nR3=-1\nR4=200\n"
            "N10 G0 X=R1 Y=R2 Z5 F300\nN20 G1 Z=R3\nN30 G3 I=AC(0) J=AC(0) F=R4\nN40 G0 Z20\nM30\n")
    lines = _lines_after(_write(tmp_path, body), load_machine("xfyz"),
                         lambda p: np.outer(p[:, 1], [2e-4, 0, 0]))
    assert "circle written in pieces" in lines[2]
    arcs = [m for m in replay_sinumerik.replay("\n".join(lines).encode("latin-1")).moves
            if m.kind == "arc"]
    assert len(arcs) >= 2
    assert sum(m.sweep for m in arcs) == pytest.approx(2 * math.pi, rel=0, abs=1e-3)
    assert [m.end["Z"] for m in arcs] == [-1.0] * len(arcs)


def test_a_circle_whose_z_correction_changes_gets_the_corrected_z(tmp_path):
    # a half circle from (20, 0) to (-20, 0) about (0, 0), Z corrected by 1e-4 * x: from +2 um to
    # -2 um along it, so one circle at the start's Z misses the end by 4 um; as a helix to the
    # corrected Z -1.0020 it misses by at most 2 cos t - (2 - 4 t / pi) um, 0.42 um (by hand):
    # one block, the end point and centre as the source wrote them
    path = _write(tmp_path, "N10 G0 X20 Y0 Z5 F300\nN20 G1 Z-1\nN30 G3 X-20 Y0 I=AC(0) J=AC(0) F200\n"
                            "N40 G0 Z20\nM30\n")
    lines = _lines_after(path, load_machine("xfyz"), lambda p: np.outer(p[:, 0], [0, 0, 1e-4]))
    assert lines[3:6] == ["N20 G1 Z-0.9980", "N30 G3 X-20 Y0 Z-1.0020 I=AC(0) J=AC(0) F200",
                          "N40 G0 Z19.9980"]


def test_work_offset_and_cutting_edge_changes_in_blocks_without_a_move(tmp_path):
    """A G55 in a block that calls a cycle, and D0 / D1 blocks: the G-code equivalent changes the
    work system there (every axis unknown), and a change of cutting edge changes the tool length
    (Z unknown until named), where a Siemens controller does; a D that names the edge in force
    changes nothing."""
    path = _write(tmp_path, "N05 T3 M6\nN10 G0 X0 Y0 Z20 F300\nN20 G55 MCALL CYCLE81(50,0,2,-10)\n"
                            "N30 X10 Y10\nN40 MCALL\nN45 G55 G0 Z60\nN50 D0\nN60 G0 X5 Z30\nN70 D1\nN75 D1\n"
                            "N80 G0 Z40\nM30\n")
    gcode = translate(path).gcode
    assert gcode.index("G55 G43.1") < next(k for k, g in enumerate(gcode) if g.startswith("G99 G81"))
    assert gcode.count("G55 G43.1") == 1 and "G0 Z60" in gcode     # G55 named again: no change
    assert gcode.count("G49") == 1 and gcode.count("G43 H3") == 1      # D1 after D0, not N75's
    assert gcode.index("G49") < gcode.index("G0 X5 Z30") < gcode.index("G43 H3") < gcode.index("G0 Z40")


def test_a_pattern_argument_with_a_comma_in_parentheses_is_refused(tmp_path):
    """HOLES1(MINVAL(A,B), ...): its arguments' places on the line cannot be told by its commas,
    so the writer could not move its reference point in place: one line naming it, not a wrong
    edit."""
    path = _write(tmp_path, "DEF REAL A=1\nDEF REAL B=2\nN10 G0 X0 Y0 Z20 F300\n"
                            "N20 MCALL CYCLE81(15,5,1,,3)\nN30 HOLES1(MINVAL(A,B),0,0,10,10,3)\n"
                            "N40 MCALL\nM30\n")
    with pytest.raises(InputError, match=r":7: HOLES1 with a comma inside an argument's parentheses"):
        translate(path)

"""Controller dialects: detection on real headers, the G80 and G98 rules per dialect (on both reader
paths), Fanuc macro B expanded or refused per construct."""
from pathlib import Path

import numpy as np
import pytest

from mtcomp.errors import InputError
from mtcomp.machine import load_machine
from mtcomp.toolpaths import _fast, iter_segment_chunks, read_program
from mtcomp.toolpaths.dialect import detect
from mtcomp.toolpaths.source import open_program

CORPUS = Path(__file__).parent / "data" / "gcode_corpus"
XFYZ = load_machine("xfyz")
G80_PROGRAM = ("G90 G21\nG0 X0 Y0 Z10.\nG1 F100 Z5.\nG81 X1. Y1. Z-2. R1. F100\nX3. Y3.\nG80\nZ5.533\n"
               "X10. Y10.\nM30\n")


@pytest.fixture(params=["compiled", "python"])
def mode(request, monkeypatch):
    if request.param == "python":
        monkeypatch.setenv("MTCOMP_NO_FAST_GCODE", "1")
    elif not _fast.available():
        pytest.skip("no C compiler: the compiled G-code path is not available")
    return request.param


@pytest.mark.parametrize("name, dialect, line", [
    ("gcodeworkshop_HAAS.nc", "haas", 2), ("gcodeworkshop_FANUC0M.nc", "fanuc", 2),
    ("gcodes_simple_mill.gcode", "fanuc", 4), ("linuxcnc_cone.ngc", "linuxcnc", 4),
    ("ugs_square.nc", "generic", None),
    # LinuxCNC's 5-axis demo: its switchable kinematics M428 (tool centre point) is the clue
    ("linuxcnc_boat-xyzac.ngc", "linuxcnc", 2),
])
def test_detection_on_real_headers(name, dialect, line):
    d, why = detect(CORPUS / name)
    assert d.name == dialect
    assert why.startswith(f"detected from line {line}:") if line else "nothing" in why


@pytest.mark.parametrize("code, dialect", [
    ("N12 G187 P3 E0.01 (SMOOTHING)", "haas"), ("G154 P12", "haas"), ("G103 P1", "haas"),
    ("M97 P2000", "haas"), ("G54.1 P12", "fanuc"), ("(G187 ON A HAAS ONLY)".replace("HAAS", "VMC"),
                                                    "fanuc"), ("G1870", "fanuc"), ("M98 P2000", "fanuc")])
def test_a_code_only_haas_has_names_haas(tmp_path, code, dialect):
    """A Fusion 360 Haas post's program names no controller (a job shop's was read as fanuc from
    its O number); the codes of the Haas mill control a Fanuc does not have name haas (not in a
    comment, not as another number)."""
    p = tmp_path / "p.nc"
    p.write_text(f"%\nO01001 (PART)\nG90 G94 G17\n{code}\nG0 X0 Y0\nM30\n%\n")
    d, why = detect(p)
    assert d.name == dialect
    assert why == "detected from line 2: O01001 (PART)"


@pytest.mark.parametrize("text, dialect", [
    ("G21 G90\nN50 M428 (tool centre point on)\nG0 X1\n", "linuxcnc"),
    ("G21\nm0429\n", "linuxcnc"), ("G0 X1\nM430 ; identity kinematics\n", "linuxcnc"),
    # in a comment, as another number or with a decimal part: no clue
    ("G21\n(M428 on a LinuxCNC machine only)\nM3\n".replace("LinuxCNC", "our"), "generic"),
    ("G21\nM4280\n", "generic"), ("G21\nM428.1\n", "generic"),
])
def test_linuxcnc_switchable_kinematics_codes_name_linuxcnc(tmp_path, text, dialect):
    p = tmp_path / "p.ngc"
    p.write_text(text)
    d, why = detect(p)
    assert d.name == dialect
    if dialect == "linuxcnc":
        assert why.startswith("detected from line 2:")


def test_grbl_is_detected_and_its_commands_pass_through(tmp_path):
    p = tmp_path / "g.nc"
    p.write_text("$H\nG21 G90\nG0 X1 Y1 Z1\n?\nG1 X2 F100\n")
    assert detect(p)[0].name == "grbl"
    assert len(read_program(p, XFYZ).blocks) == 2


@pytest.mark.parametrize("dialect", ["fanuc", "haas"])
def test_g80_brings_back_the_motion_mode_on_fanuc_and_haas(tmp_path, mode, dialect):
    p = tmp_path / "p.nc"
    p.write_text(G80_PROGRAM)
    rows = np.vstack([c.end for c in iter_segment_chunks(p, XFYZ, dialect=dialect)])
    feed = np.concatenate([c.feed for c in iter_segment_chunks(p, XFYZ, dialect=dialect)])
    # after G80 the G1 of line 3 is in force again: Z5.533 is a feed move at F100, then X10 Y10
    np.testing.assert_allclose(rows[-2:], [[3, 3, 5.533], [10, 10, 5.533]], rtol=0, atol=1e-12)
    np.testing.assert_allclose(feed[-2:], [100.0, 100.0], rtol=0, atol=0)


@pytest.mark.parametrize("dialect", ["linuxcnc", "generic", "grbl"])
def test_g80_leaves_no_motion_mode_elsewhere(tmp_path, mode, dialect):
    p = tmp_path / "p.nc"
    p.write_text(G80_PROGRAM)
    with pytest.raises(InputError, match="coordinates without a motion mode") as exc:
        list(iter_segment_chunks(p, XFYZ, dialect=dialect))
    assert exc.value.line == 7


@pytest.mark.parametrize("dialect, z_known", [("linuxcnc", True), ("fanuc", False),
                                              ("generic", False)])
def test_g98_with_the_r_plane_above_the_initial_level(tmp_path, mode, dialect, z_known):
    # LinuxCNC retracts to the higher of the two (here R2 above the initial Z1); the others are
    # not followed there, so Z stays unknown after the cycle
    p = tmp_path / "p.nc"
    p.write_text("G90 G21\nG0 X0 Y0 Z1.\nG98 G81 X1. Y1. Z-2. R2. F100\nG80\nG0 X5.\n")
    prog = read_program(p, XFYZ, dialect=dialect)
    last = prog.blocks[-1]
    assert bool(last.known[XFYZ.index("Z")]) == z_known
    if z_known:
        assert last.end[XFYZ.index("Z")] == pytest.approx(2.0, rel=0, abs=1e-12)


def test_linuxcnc_incremental_cycles_measure_r_from_the_initial_level(tmp_path):
    # LinuxCNC (interp_cycles.cc): r = R + initial level for every hole of the series, so the second
    # hole under G99 drills from R = 10 - 2 = 8 to 8 - 3 = 5, as the first
    p = tmp_path / "p.nc"
    p.write_text("G90 G21\nG0 X0 Y0 Z10.\nG91 G99 G81 X1. Z-3. R-2. F100\nX1.\nG80\n")
    blocks = read_program(p, XFYZ, dialect="linuxcnc").blocks
    np.testing.assert_allclose([b.cycle.z_bottom for b in blocks[1:]], [5.0, 5.0], rtol=0, atol=1e-12)
    with pytest.raises(InputError, match="continued without G98"):
        read_program(p, XFYZ, dialect="fanuc")


def test_fanuc_macro_b_while_if_goto_expanded(tmp_path):
    p = tmp_path / "m.nc"
    p.write_text("%\nO1234\nG90 G21 G0 X0 Y0 Z5\n#100=0\n#101=2.5\nWHILE [#100 LT 3] DO1\n"
                 "G1 X[#100*#101] Y#100 F100\n#100=#100+1\nEND1\nIF [#101 GT 2] GOTO 20\n"
                 "G1 X99\nN20 G0 Z#101\nM30\n%\n")
    with open_program(p) as src:
        assert src.dialect.name == "fanuc" and src.expanded
        lines = Path(src.path).read_text().splitlines()
    # the header comment after the tape's opening % and its program number (which Fanuc wants
    # first: it takes the number from the line after the %)
    assert lines[:2] == ["%", "O1234"]
    assert lines[2].startswith("(expanded by mtcomp from m.nc for fanuc")
    # X[#100*#101] has the one decimal of #101 = 2.5; Y#100 is whole and gets its point (Fanuc
    # reads 'Y1' as 1 least input increment, the variable's 1 as 1 mm)
    assert lines[3:] == ["G90 G21 G0 X0 Y0 Z5", "G1 X0.0 Y0. F100", "G1 X2.5 Y1. F100",
                         "G1 X5.0 Y2. F100", "N20 G0 Z2.5", "M30", "%"]


@pytest.mark.parametrize("text, line, msg", [
    ("O1\nG0 X#1\n", 2, "variable #1 is read before it is set"),
    ("O1\n#1=#5001\n", 2, "system variable #5001"),
    ("O1\n#1=[3 AND 5]\n", 2, "bitwise on a Fanuc"),
    ("O1\nWHILE [1 EQ 1] DO1\nG0 X1\n", 2, "WHILE ... DO1 without its END1"),
    ("O1\nGOTO 50\n", 2, "no line with sequence number N50"),
    ("O1\nIF [1 EQ 1] THEN G0 X1\n", 2, "THEN takes one assignment"),
    ("O1\nG0 X0 Y0 Z0\nM98 P1000\n", 3, "M98 P1000: no program O1000 in this file"),
])
def test_fanuc_macro_constructs_refused_in_one_line(tmp_path, text, line, msg):
    p = tmp_path / "m.nc"
    p.write_text(text)
    with pytest.raises(InputError, match=msg) as exc:
        read_program(p, XFYZ, dialect="fanuc")
    assert exc.value.line == line and str(exc.value).count("\n") == 0


def test_compensate_prints_the_dialect(tmp_path, capsys):
    from mtcomp.cli import main
    from mtcomp.models import ErrorModel, FittedModel, save_model
    fitted = FittedModel.zero(ErrorModel(XFYZ))
    save_model(tmp_path / "model.json", fitted)
    p = tmp_path / "p.nc"
    p.write_text("%\nO0001\n" + G80_PROGRAM)
    out = tmp_path / "out.nc"
    code = main(["compensate", "xfyz", str(tmp_path / "model.json"), str(p), "-o", str(out),
                 "--quiet"])
    stdout = capsys.readouterr().out
    assert code == 0
    assert "dialect: fanuc (detected from line 2: O0001)" in stdout
    code = main(["compensate", "xfyz", str(tmp_path / "model.json"), str(p), "-o", str(out),
                 "--quiet", "--dialect", "linuxcnc"])
    assert code == 2 and "p.nc:9: coordinates without a motion mode" in capsys.readouterr().err


DWELL_AND_MOVE = "G20 G90\nG0 X0 Y0 Z1\nG04 P.001 G0 X1.0 Y1.0\nG0 Z0.25\nM30\n"


@pytest.mark.parametrize("dialect", ["linuxcnc", "generic", "grbl"])
def test_a_dwell_with_a_move_in_one_block_moves(tmp_path, mode, dialect):
    """LinuxCNC's skeleton.ngc: 'G04 P.001 G0 X1.0 Y1.0' dwells (P) and moves to X1 Y1 (LinuxCNC
    G-code reference, G4: the dwell time is P); the next Z move starts there."""
    p = tmp_path / "p.nc"
    p.write_text(DWELL_AND_MOVE)
    rows = np.vstack([c.end for c in iter_segment_chunks(p, XFYZ, dialect=dialect)])
    np.testing.assert_allclose(rows[-2:], [[25.4, 25.4, 25.4], [25.4, 25.4, 6.35]], rtol=0,
                               atol=1e-12)


@pytest.mark.parametrize("dialect", ["fanuc", "haas"])
def test_a_dwell_with_a_move_is_refused_where_x_is_the_dwell_time(tmp_path, mode, dialect):
    p = tmp_path / "p.nc"
    p.write_text(DWELL_AND_MOVE.replace("Z1\n", "Z1.\n"))     # Z1 would be 0.0001 in there
    with pytest.raises(InputError, match="G4 with G0 and axis words in one block") as exc:
        list(iter_segment_chunks(p, XFYZ, dialect=dialect))
    assert exc.value.line == 3


@pytest.mark.parametrize("text", ["G21 G90\nG0 X1 Y1 Z1\nN4 M30\nN5 %\n",
                                  "G21 G90\nG0 X1 Y1 Z1\nM99\n"])
def test_a_numbered_end_of_tape_mark_and_a_main_program_m99_pass_through(tmp_path, mode, text):
    """'N194 %' (a post that numbers every line) and M99 ending a main program (Centroid) are read
    as the program's end marks, not refused; the motion is the program's."""
    p = tmp_path / "p.nc"
    p.write_text(text)
    rows = np.vstack([c.end for c in iter_segment_chunks(p, XFYZ)])
    np.testing.assert_allclose(rows, [[1.0, 1.0, 1.0]], rtol=0, atol=0)


@pytest.mark.parametrize("head, line, name", [
    ("$OKUMA.MIN%\nOSTRT\nG0 X1\n", 1, "an Okuma OSP program"),
])
def test_other_controller_languages_refused_at_their_first_line(tmp_path, head, line, name):
    p = tmp_path / "p.nc"
    p.write_text(head)
    with pytest.raises(InputError) as exc:
        with open_program(p):
            pass
    assert exc.value.line == line and name in exc.value.message


def test_plain_programs_with_a_percent_line_are_not_taken_for_another_language(tmp_path):
    p = tmp_path / "p.nc"
    p.write_text("%\nO1000 (MPF)\nG0 X1 Y2\n%\n")
    with open_program(p) as src:
        assert src.dialect.name == "fanuc"
    # and a Sinumerik program of plain G-code is read when the dialect is given
    q = tmp_path / "q.nc"
    q.write_text("%_N_PART_MPF\nG0 X1 Y2\nM30\n")
    rows = [c for c in iter_segment_chunks(q, load_machine("xfyz"), dialect="generic")]
    assert rows

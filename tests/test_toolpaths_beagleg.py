"""BeagleG's G-code (--dialect beagleg): its parameters named without brackets, its WHILE loops and
operators, checked against hand-derived expansions; its arcs that do not stay in force, checked by
the independent replay (tests/replay.py) of the compensated program; its G codes; an arc from a
position the program has not given and G5/G5.1 splines (LinuxCNC's and BeagleG's), passed through
as written."""
import contextlib
import io
from pathlib import Path

import pytest

from mtcomp.cli import main
from mtcomp.errors import InputError
from mtcomp.toolpaths.beagleg import to_ngc
from mtcomp.toolpaths.dialect import detect
from mtcomp.toolpaths.source import open_program
from replay import Tolerance, compare, replay
from test_gcode_corpus import CORPUS, _check_output, _machine_file, _model_file

TOL = Tolerance(axis_mm=0.0213, axis_deg=0.03, path_mm=0.04)


def _expanded(tmp_path, text, dialect="beagleg"):
    """(the expanded lines after the header, the dialect's name, why); the error that stopped the
    expansion raised."""
    p = tmp_path / "in.gcode"
    p.write_text(text)
    with open_program(p, dialect) as src:
        src.raise_error()
        return Path(src.path).read_text().splitlines()[1:], src.dialect.name, src.why


def _compensate(tmp_path, text, *extra, factor=1.0):
    """(exit status, stdout, stderr, output text or None) of compensating ``text``."""
    prog = tmp_path / "prog.gcode"
    prog.write_text(text)
    machine = _machine_file(tmp_path, "XFYZ")
    model = _model_file(tmp_path, machine, factor=factor)
    out = tmp_path / "out.gcode"
    out_buf, err_buf = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out_buf), contextlib.redirect_stderr(err_buf):
        code = main(["compensate", str(machine), str(model), str(prog), "-o", str(out),
                     "--units", "mm", *extra])
    return code, out_buf.getvalue(), err_buf.getvalue(), out.read_text() if out.exists() else None


def test_parameters_named_without_brackets_and_the_update_operators():
    lines = to_ngc(["#faces=24 ; count", "#angle=[360/#faces]", "G1 X#r Y[#R*2] (r)", "#i++",
                    "#i -= [#a*2]", "#<b c>=1", "#1=[#2 <= #3]"], "p.gcode")
    assert lines == ["#<faces>=24 ; count", "#<angle>=[360/#<faces>]", "G1 X#<r> Y[#<r>*2] (r)",
                     "#<i>=[#<i>+1]", "#<i>=[#<i>-[[#<a>*2]]]", "#<bc>=1", "#1=[#2  LE  #3]"]


def test_while_loops_become_o_word_loops_and_run(tmp_path):
    text = "G0 X0 Y0 Z0\n#i=0\nWHILE [#i < 3] DO\n  G1 X[#i * 10] Y[#r * cos[60]] F100\n" \
           "  #i++\nEND\n#r=4\n"
    assert to_ngc(text.splitlines(), "p")[2:6] == [
        "o<beagleg_while_3> while [#<i>  LT  3]", "  G1 X[#<i> * 10] Y[#<r> * cos[60]] F100",
        "  #<i>=[#<i>+1]", "o<beagleg_while_3> endwhile"]
    # #r is not set before the loop: LinuxCNC's rule (a named parameter used before it is set) is
    # kept, where BeagleG reads 0; set it first and the loop runs three times
    with pytest.raises(InputError, match="#<r>: used before it is set"):
        _expanded(tmp_path, text)
    lines, name, why = _expanded(tmp_path, "#r=4\n" + text)
    assert name == "beagleg" and why == "given"
    # Y = 4 cos 60 deg = 2
    assert lines == ["G0 X0 Y0 Z0", "  G1 X0 Y2 F100", "  G1 X10 Y2 F100", "  G1 X20 Y2 F100"]


@pytest.mark.parametrize("text, line, message", [
    ("WHILE [1] DO\nWHILE [1] DO\nEND\nEND\n", 2, "WHILE inside the WHILE of line 1"),
    ("G0 X0\nWHILE [1] DO\nX1\n", 2, "WHILE without its END"),
    ("IF [#1 > 2] THEN #2=1\n", 1, "one-line IF"),
    ("#a=[#b > 1] ? 2 : 3\n", 1, "ternary"),
    ("#a=2 G1 X#a\n", 1, "#a is set and read in one line"),
    ("#i=1\nG0 X#i++ Y0\n", 2, r"'#i\+\+' updates a parameter inside a value: BeagleG reads #i as"),
])
def test_what_is_refused_by_name(tmp_path, text, line, message):
    with pytest.raises(InputError, match=message) as exc:
        _expanded(tmp_path, text)
    assert exc.value.line == line


def test_detected_by_a_parameter_named_without_brackets(tmp_path):
    for text, name in [("; spiral\n#r=50\nG1 X#r\n", "beagleg"), ("#i++\n", "beagleg"),
                       ("#<r>=50\nG1 X#<r>\n", "linuxcnc"), ("#1=50\nG1 X#1\n", "generic"),
                       ("(for BeagleG)\nG1 X1\n", "beagleg"), ("G1 X1 (#r=5)\n", "generic")]:
        p = tmp_path / "d.gcode"
        p.write_text(text)
        assert detect(p)[0].name == name, text


ARCS = ("G0 X0 Y0 Z0\nG1 X10 F600\nG3 X20 Y10 I0 J10\nX30\nG2 X40 Y0 I0 J-10\nY-10\n"
        "G0 Z5\nG2 X20 Y-10 R10\nX0 Y0\n")


def test_axis_words_after_an_arc_move_in_the_last_g0_g1_mode(tmp_path):
    # read as RS274 (the arc in force) `X30` is an arc without centre; on BeagleG a line
    code, _out, err, _text = _compensate(tmp_path, ARCS)
    assert code == 2 and "prog.gcode:4: arc without centre" in err
    code, _out, err, text = _compensate(tmp_path, ARCS, "--dialect", "beagleg")
    assert code == 0, err
    src = replay(ARCS.encode(), beagleg=True).moves
    assert [m.kind for m in src] == ["rapid", "feed", "arc", "feed", "arc", "feed", "rapid", "arc",
                                     "rapid"]
    compare(ARCS.encode(), text.encode(), TOL, beagleg=True)
    _check_output(ARCS.encode(), text.encode())
    # the three lines of axis words alone stay so (the output's G0/G1 mode is the source's)
    assert sum(not t.startswith("G") for t in text.splitlines()) == 3, text


def test_an_arc_split_into_pieces_restates_its_g2_g3(tmp_path):
    # a model 30 times the usual size: the corrected arc is written as several arcs, each with its
    # own G2/G3 (on BeagleG a piece without it would be a line), and the line after it moves
    # in G1 again
    code, _out, err, text = _compensate(tmp_path, ARCS, "--dialect", "beagleg", "--chord-tol-um",
                                        "0.2", factor=30.0)
    assert code == 0, err
    pieces = [t for t in text.splitlines() if "I" in t or "J" in t or "R" in t]
    assert len(pieces) > 3
    assert all(t.split()[0] in ("G2", "G3") for t in pieces), pieces
    compare(ARCS.encode(), text.encode(), TOL, beagleg=True)
    # a piece without its G2/G3 is a line on BeagleG: the replay tells it apart
    second = pieces[1]
    wrong = text.replace(second, second.split(" ", 1)[1], 1)
    with pytest.raises(AssertionError):
        compare(ARCS.encode(), wrong.encode(), TOL, beagleg=True)


@pytest.mark.parametrize("text, message", [
    ("G0 X0 Y0 Z0\nG81 X1 Y1 Z-1 R1 F100\n", "G81 is not a BeagleG code"),
])
def test_codes_beagleg_does_not_run_as_rs274_are_refused(tmp_path, text, message):
    code, _out, err, text = _compensate(tmp_path, text, "--dialect", "beagleg")
    assert code == 2 and text is None and message in err and len(err.strip().splitlines()) == 1


@pytest.mark.parametrize("dialect", ["generic", "beagleg"])
def test_an_arc_from_a_position_not_given_passes_through(tmp_path, dialect):
    # after G28 Y stands wherever home is: the arc's path is not known; it is written as the source
    # has it, and the lines after it (their start the arc's end) are corrected
    text = "G28\nG0 Z0\nG1 X95 F600\nG3 X100 Y5 J5\nG1 Y15\nG1 X50\n"
    code, out, err, written = _compensate(tmp_path, text, "--dialect", dialect)
    assert code == 0, err
    assert "1 arc from a position the program has not given (line 4" in out
    lines = written.splitlines()
    assert lines[2:4] == ["G1 X95 F600", "G3 X100 Y5 J5"]     # Y not known: both as written
    assert lines[4] != "G1 Y15" and lines[5] != "G1 X50"      # corrected
    compare(text.encode(), written.encode(), TOL)
    _check_output(text.encode(), written.encode())


def test_the_corpus_program_that_names_no_controller_is_accepted_with_the_dialect_given(tmp_path):
    # rounded-bracket-simple is refused without --dialect (tests/test_gcode_corpus.py, DIALECTS)
    text = "G0 Z0\n" + (CORPUS / "beagleg_rounded-bracket-simple.gcode").read_text()
    code, _out, err, written = _compensate(tmp_path, text)
    assert code == 2 and written is None and ":7: arc without centre" in err, err
    code, _out, err, written = _compensate(tmp_path, text, "--dialect", "beagleg")
    assert code == 0, err
    with open_program(tmp_path / "prog.gcode", "beagleg") as src:    # F[150 * 60] computed
        expanded = Path(src.path).read_bytes()
    compare(expanded, written.encode(), TOL, beagleg=True)
    _check_output(expanded, written.encode())


SPLINES = ("G0 X0 Y0 Z0\nG1 X10 Y10 F600\nG5 I0 J60 P0 Q-60 X30 Y30\nG5 P0 Q-60 X50 Y50\n"
           "G5.1 X60 I5 J-10\nG1 X100 Y100\n")


@pytest.mark.parametrize("dialect", ["generic", "beagleg"])
def test_splines_pass_through_with_their_ends_known(tmp_path, dialect):
    code, out, err, text = _compensate(tmp_path, SPLINES, "--dialect", dialect)
    assert code == 0, err
    assert "3 splines (G5, G5.1; first at line 3" in out
    lines = text.splitlines()
    assert lines[2:5] == SPLINES.splitlines()[2:5]          # as written
    assert lines[1] != "G1 X10 Y10 F600" and lines[5] != "G1 X100 Y100"    # corrected
    src = replay(SPLINES.encode()).moves
    assert [m.kind for m in src] == ["rapid", "feed", "spline", "spline", "spline", "feed"]
    # the first spline's control points: (10, 10) + (0, 60) and (30, 30) + (0, -60); the second's
    # first one continues the first's tangent: (30, 30) - (0, -60)
    assert src[2].controls == ((10, 10), (10, 70), (30, -30), (30, 30))
    assert src[3].controls[1] == (30, 90)
    compare(SPLINES.encode(), text.encode(), TOL)
    _check_output(SPLINES.encode(), text.encode())


def test_an_incremental_spline_moves_the_output_by_its_increments(tmp_path):
    # the output stands a correction off the program before the spline, and after it too: the next
    # increment is taken from there, so the output reaches the same corrected point as the same
    # program written absolute (the second oracle)
    text = "G0 X0 Y0 Z0\nG1 X10 Y10 F600\nG91 G5 I0 J20 P0 Q-20 X20 Y20\nG1 X20 Y-5\nG90 G1 X0 Y0\n"
    absolute = "G0 X0 Y0 Z0\nG1 X10 Y10 F600\nG5 I0 J20 P0 Q-20 X30 Y30\nG1 X50 Y25\nG1 X0 Y0\n"
    ends = []
    for k, program in enumerate((text, absolute)):
        folder = tmp_path / str(k)
        folder.mkdir()
        code, _out, err, written = _compensate(folder, program, "--dialect", "beagleg",
                                               factor=30.0)
        assert code == 0, err
        assert written.splitlines()[1] != "G1 X10 Y10 F600"          # corrected before the spline
        assert written.splitlines()[2] == program.splitlines()[2]     # the spline as written
        compare(program.encode(), written.encode(), TOL, beagleg=True)
        _check_output(program.encode(), written.encode())
        moves = replay(written.encode(), beagleg=True).moves
        ends.append((moves[3].end["X"], moves[3].end["Y"]))
    assert ends[0] == pytest.approx(ends[1], abs=2.5e-4)
    assert ends[0] != pytest.approx((50.0, 25.0), abs=2.5e-4)       # the correction is there


@pytest.mark.parametrize("text, message", [
    ("G18\nG5 I1 J1 P1 Q1 X1 Y1\n", "G5 (cubic spline) not in G17"),
    ("G5 I1 J1 P1 Q1 X1 Z1\n", "G5 (cubic spline) with Z: its axes are X and Y only"),
    ("G5 I1 J1 P1 X1 Y1\n", "G5 (cubic spline) without both P and Q"),
    ("G5 I1 P1 Q1 X1 Y1\n", "G5 (cubic spline) with only one of I and J"),
    ("G5.1 X1 Y1\n", "G5.1 (quadratic spline) without I or J"),
    ("G1 G5 I1 J1 P1 Q1 X1 Y1\n", "with motion G1"),
    ("(grbl)\nG5 I1 J1 P1 Q1 X1 Y1\n", "G5 (cubic spline) is not supported"),
])
def test_splines_refused_as_linuxcnc_refuses_them(tmp_path, text, message):
    code, _out, err, written = _compensate(tmp_path, "G0 X0 Y0 Z0 F100\n" + text)
    assert code == 2 and written is None and message in err, err


#: the reviewer's program: line 4 moves to X5 in G90 on BeagleG, and G91 applies after it
WORD_ORDER = "#a=1\nG21 G17 G90\nG0 X10 Y0 Z5\nX5 G91\nX1\nM2\n"


def test_the_replay_reads_a_line_word_by_word_as_beagleg(tmp_path):
    # by hand: BeagleG moves to X5 (G90) and then to 5 + 1 = 6 (G91); read as one block the line
    # moves by +5 (10 + 5 = 15, then 16)
    def ends(program, beagleg):
        return [(m.line, m.end["X"], m.end["Z"])
                for m in replay(program.encode(), beagleg=beagleg).moves]
    assert ends(WORD_ORDER, True) == [(2, 10, 5), (3, 5, 5), (4, 6, 5)]
    assert ends(WORD_ORDER, False) == [(2, 10, 5), (3, 15, 5), (4, 16, 5)]
    assert ends("G0 X0 Y0 Z5\nX5 M3 Y2\n", True) == [(0, 0, 5), (1, 5, 5), (1, 5, 5)]
    # what mtcomp wrote for it before it refused the line (a model 30 times the usual size): Y and
    # Z beside X, read by BeagleG in G90, plunge Z from 5 to 0.0051; the replay tells it apart
    written = WORD_ORDER.replace("X5 G91", "X4.9969 Y-0.0014 Z0.0051 G91")
    assert ends(written, True)[1] == (3, 4.9969, 0.0051)
    with pytest.raises(AssertionError):
        compare(WORD_ORDER.encode(), written.encode(), TOL, beagleg=True)


@pytest.mark.parametrize("text, line, message", [
    (WORD_ORDER, 4, "X5 comes before G91 on this line: BeagleG reads a line's words in turn"),
    ("G91\nG0 X1 Y0 Z5\nX5 G90\nX1\n", 3, "X5 comes before G90"),
    ("G0 X0 Y0 Z5\nG1 X1 F100 G0 Y2\n", 2, "X1 comes before G0"),
    ("G0 X0 Y0 Z5\nX1 G20\n", 2, "X1 comes before G20"),
    ("G0 X0 Y0 Z5\nX1 G55\n", 2, "X1 comes before G55"),
    ("G0 X0 Y0 Z5\nX1 G18\n", 2, "X1 comes before G18"),
    ("G0 X0 Y0 Z5\nG92 Z0 G0 X5\n", 2, "Z0 comes before G0"),
    ("G0 X0 Y0 Z5\nF100 G20 G1 X1\n", 2, "F100 comes before G20"),
    ("G0 X0 Y0 Z5\nX5 M3 Y2\n", 2, "Y2 comes after M3, which ends the move of X5"),
    ("G0 X0 Y0 Z5\nG1 X5 F100 N7 Y2\n", 2, "Y2 comes after N7, which ends the move of X5"),
])
def test_a_line_beagleg_reads_as_two_blocks_is_refused(tmp_path, text, line, message):
    code, _out, err, written = _compensate(tmp_path, text, "--dialect", "beagleg", factor=30.0)
    assert code == 2 and written is None, err
    assert f"prog.gcode:{line}: {message}" in err and len(err.strip().splitlines()) == 1, err


def test_the_same_lines_with_their_g_words_first_are_corrected(tmp_path):
    text = "#a=1\nG21 G17 G90\nG0 X10 Y0 Z5\nG91 X5\nX1\nS1000 M3 G1 X2 F100\nG1 X1 F100 S9 M5\n"
    code, _out, err, written = _compensate(tmp_path, text, "--dialect", "beagleg", factor=30.0)
    assert code == 0, err
    with open_program(tmp_path / "prog.gcode", "beagleg") as src:
        expanded = Path(src.path).read_bytes()
    compare(expanded, written.encode(), TOL, beagleg=True)
    _check_output(expanded, written.encode())


def test_g70_g71_are_inch_and_mm(tmp_path):
    # BeagleG's parser reads G70/G71 as G20/G21 (gcode-parser.cc, ParseBlock): X1 after G70 is
    # 25.4 mm, by hand; the output keeps G70 and writes that line in inches
    text = "G21\nG0 X10 Y0 Z5\nG70 X1\nG71 X30\n"
    moves = replay(text.encode(), beagleg=True).moves
    assert [m.end["X"] for m in moves] == pytest.approx([10.0, 25.4, 30.0], abs=1e-12)
    code, _out, err, written = _compensate(tmp_path, text, "--dialect", "beagleg")
    assert code == 0, err
    out = written.splitlines()
    assert out[2].startswith("G70 X") and out[3].startswith("G71 X")
    assert float(out[2].split()[1][1:]) == pytest.approx(1.0, abs=1e-3)
    compare(text.encode(), written.encode(), TOL, beagleg=True)
    _check_output(text.encode(), written.encode())


#: BeagleG's Z probe: `G30` moves Z down to the probe's switch and sets the G92 offset of Z so that
#: the tool reads the thickness there (its own Z word, 0 without); the words after its own F and Z
#: act as usual (gcode-parser.cc, handle_z_probe and ParseBlock)
PROBE = ("G0 X0 Y0 Z5\nG1 X10 Y10 F600\nG4 P25 G30 G1 Z0\nG1 X20 Y10\nG1 Z5\nG30 Z1.5 F100\n"
         "G1 X30\nG0 Z10\nG1 X40\n")


def test_a_probe_loses_z_until_a_move_names_it(tmp_path):
    code, out, err, written = _compensate(tmp_path, PROBE, "--dialect", "beagleg", factor=30.0)
    assert code == 0, err
    lines, source = written.splitlines(), PROBE.splitlines()
    # the probe lines as written; after line 3's `G1 Z0` Z stands at 0, after line 6 nowhere known
    assert lines[2] == source[2] and lines[5] == source[5]
    assert lines[3].startswith("G1 X19.99") and lines[4].startswith("G1 Z4.99")  # corrected
    assert lines[6].startswith("G1 X30") and "Z" not in lines[6]  # Z lost: not written
    assert lines[7].startswith("G0 Z10") and lines[7] != source[7]
    assert "2 Z probes (BeagleG's G30, first at line 3" in out
    assert "assumed: G30 at line 3 (BeagleG's Z probe) sets the G92 offset of Z" in out
    _check_output(PROBE.encode(), written.encode(), beagleg=True)
    compare(PROBE.encode(), written.encode(), TOL, beagleg=True)
    # the oracle: a Z word after the second probe, before `G0 Z10`, is caught
    wrong = written.replace(lines[6], lines[6] + " Z1.5")
    with pytest.raises(AssertionError, match="writes \\['Z'\\]"):
        _check_output(PROBE.encode(), wrong.encode(), beagleg=True)


@pytest.mark.parametrize("text, message", [
    ("G0 X0 Y0 Z5\nM3 G30\n", "M3 before G30 (BeagleG's Z probe) on one line"),
    ("G0 X0 Y0 Z5\nG30 G2 X1 Y1 I1\n", "G30 (BeagleG's Z probe) and an arc G2 on one line"),
    ("G0 X0 Y0 Z5\nG92 X0\nG30\n", "while a G52 or G92 offset is in force"),
])
def test_what_a_probe_line_may_not_hold(tmp_path, text, message):
    code, _out, err, written = _compensate(tmp_path, text, "--dialect", "beagleg")
    assert code == 2 and written is None and message in err, err
    assert len(err.strip().splitlines()) == 1

"""LinuxCNC's RS274/NGC front end: O-word control flow, parameters and expressions expanded into the
lines the controller executes, checked against hand-derived expansions and Python's math."""
import math
from pathlib import Path

import numpy as np
import pytest

from mtcomp.errors import InputError
from mtcomp.machine import load_machine
from mtcomp.toolpaths import iter_segment_chunks, read_program
from mtcomp.toolpaths.expr import Evaluator, ExprError
from mtcomp.toolpaths.ngc import NgcParams
from mtcomp.toolpaths.source import open_program

DATA = Path(__file__).parent / "data"
XFYZ = load_machine("xfyz")


def _expanded(tmp_path, text, **kw):
    p = tmp_path / "in.ngc"
    p.write_text(text)
    with open_program(p, "linuxcnc", **kw) as src:
        lines = Path(src.path).read_text().splitlines()
        return lines, src.expanded, list(src.line_map) if src.expanded else None


def test_sub_called_twice_appears_twice_with_its_arguments(tmp_path):
    text = ("G21 G90\n"
            "o100 sub\n"
            "  G1 X[#1 * 2] Y#2 F100 (side)\n"
            "o100 endsub\n"
            "G0 X0 Y0 Z5\n"
            "o100 call [1.5] [-2]\n"
            "o100 call [3] [4]\n"
            "M2\n")
    lines, expanded, line_map = _expanded(tmp_path, text)
    assert expanded and lines[0].startswith("(expanded by mtcomp from in.ngc")
    # X[#1 * 2] with #1 = 1.5: the decimals of the numbers it is computed from (one)
    assert lines[1:] == ["G21 G90", "G0 X0 Y0 Z5", "  G1 X3.0 Y-2 F100 (side)",
                         "  G1 X6 Y4 F100 (side)", "M2"]
    assert line_map == [0, 1, 5, 3, 3, 8]
    # two corrections: the reader sees two moves, both from source line 3
    prog = read_program(tmp_path / "in.ngc", XFYZ, dialect="linuxcnc")
    ends = [b.end for b in prog.blocks]
    np.testing.assert_allclose(ends[1:], [[3, -2, 5], [6, 4, 5]], rtol=0, atol=1e-12)


def test_nested_loops_if_elseif_else_and_parameters_after_the_line(tmp_path):
    text = ("G90 G0 X0 Y0 Z0\n"
            "#1 = 0\n"
            "o10 while [#1 LT 3]\n"
            "  #2 = 0\n"
            "  o20 repeat [2]\n"
            "    o30 if [#1 EQ 0]\n"
            "      G1 X#1 Y#2 F10\n"
            "    o30 elseif [#1 EQ 1]\n"
            "      G1 X[10 + #1] Y#2\n"
            "    o30 else\n"
            "      #2 = [#2 + 5] G1 X[20 + #1] Y#2\n"
            "    o30 endif\n"
            "    #2 = [#2 + 1]\n"
            "  o20 endrepeat\n"
            "  #1 = [#1 + 1]\n"
            "o10 endwhile\n"
            "M30\n")
    lines, _, _ = _expanded(tmp_path, text)
    # hand expansion: #1 = 0, 1, 2; each pass two inner passes with #2 = 0, 1 (and for #1 = 2 the
    # assignment on the G1 line takes effect after the line: Y uses the old #2, then +5, then +1)
    assert lines[2:] == ["      G1 X0 Y0 F10", "      G1 X0 Y1 F10",
                         "      G1 X11 Y0", "      G1 X11 Y1",
                         "      G1 X22 Y0", "      G1 X22 Y6", "M30"]


def test_do_while_break_continue_return_value_and_named_parameters(tmp_path):
    text = ("G0 X0 Y0 Z0\n"
            "o<sq> sub\n"
            "  o<sq> return [#1 * #1]\n"
            "o<sq> endsub\n"
            "#<i> = 0\n"
            "o1 do\n"
            "  #<i> = [#<i> + 1]\n"
            "  o2 if [#<i> EQ 2]\n"
            "    o1 continue\n"
            "  o2 endif\n"
            "  o3 if [#<i> GT 4]\n"
            "    o1 break\n"
            "  o3 endif\n"
            "  o<sq> call [#<i>]\n"
            "  G1 X#<_value> F1\n"
            "o1 while [1]\n"
            "M2\n")
    lines, _, _ = _expanded(tmp_path, text)
    assert lines[2:] == ["  G1 X1 F1", "  G1 X9 F1", "  G1 X16 F1", "M2"]


def test_polar_words_absolute_and_incremental(tmp_path):
    text = "G90 G0 X0 Y0 Z0\nG1 @2 ^90 F10\nG91 ^90\nG90\n@4\nM2\n"
    lines, _, _ = _expanded(tmp_path, text)
    # LinuxCNC G-code reference, Polar Coordinates: @ distance, ^ angle from +X, about the XY zero;
    # in G91 the angle is added to the current one (at 90 deg, distance 2: to 180 deg); a distance
    # alone keeps the current angle
    assert lines[2] == "G1 X0 Y2 F10"
    assert lines[3] == "G91 X-2 Y-2"           # from (0, 2) to (-2, 0), written as increments
    assert lines[5] == "x-4 y0"             # a line in lower case gets lower-case words



def test_a_function_as_a_word_value_without_brackets_around_it(tmp_path):
    # LinuxCNC G-code reference, Unary Operation Value: a real value may be a function applied to a
    # value in brackets, `X SIN[30]`, as `X[SIN[30]]` (the RS274/NGC interpreter's own expression
    # test writes `x sin[30]`, `x atan[1.7321]/[1.0]`: tests/data/gcode_corpus/printhor_example2)
    text = ("G90 G0 X0 Y0 Z0\nG1 X SIN[30] Y cos[60] F100\nX ATAN[1]/[1] Y-SQRT[4]\n"
            "X abs[-2.5] Y ROUND[2.5]\nM2\n")
    lines, expanded, _ = _expanded(tmp_path, text)
    assert expanded
    # sin 30 deg = cos 60 deg = 0.5, atan2(1, 1) = 45 deg, -sqrt 4 = -2, |-2.5|, 2.5 rounded away
    # (the blank after the letter is kept; a value has the decimals of the numbers it comes from)
    assert lines[2:5] == ["G1 X 0.5 Y 0.5 F100", "X 45 Y-2", "X 2.5 Y 3.0"]
    prog = read_program(tmp_path / "in.ngc", XFYZ, dialect="linuxcnc")
    np.testing.assert_allclose([b.end for b in prog.blocks][1:],
                               [[0.5, 0.5, 0], [45, -2, 0], [2.5, 3, 0]], rtol=0, atol=1e-12)


def test_polar_words_given_by_parameters_in_a_drilling_cycle(tmp_path):
    # Kurt Jacobson's hole circle (tests/data/gcode_corpus/hazzy_hole circle.ngc): a G83 cycle whose
    # holes are polar words with a named parameter for the distance, the later holes a line of
    # polar words alone. LinuxCNC reads a parameter as a word's value in any word (G-code
    # reference, Parameters), so @#<r>^45 with #<r>=2 is @2^45: X = 2 cos 45, Y = 2 sin 45
    text = "#<r>=2\nG17 G20 G90\nG0 X0 Y0 Z1\nG83 @#<r>^45 Z-.5 R.1 Q.35 F10\n@#<r>^90\nG80\nM2\n"
    lines, _, _ = _expanded(tmp_path, text)
    c = 2 * math.cos(math.radians(45))
    # (the blank after the polar words goes with them: RS274/NGC ignores blanks between words)
    assert lines[3] == f"G83 X{c:.6f} Y{c:.6f}Z-.5 R.1 Q.35 F10"
    assert lines[4] == "x0 y2"               # a line in lower case gets lower-case words

@pytest.mark.parametrize("expr, expected", [
    ("[1 + 2 * 3]", 7.0), ("[2 ** 3 ** 2]", 64.0), ("[7 MOD 3]", 1.0), ("[-7 MOD 3]", 2.0),
    ("[10 / 4]", 2.5), ("[5 - 2 - 1]", 2.0), ("[2.0 / 3 * 1.5 - 5.5 / 11.0]", 0.5),
    ("[1 EQ 1.0000001]", 1.0), ("[1 NE 1.1]", 1.0), ("[2 GT 2]", 0.0), ("[2 GE 2]", 1.0),
    ("[1 LT 2]", 1.0), ("[3 LE 2]", 0.0), ("[1 AND 0]", 0.0), ("[0 OR 2]", 1.0),
    ("[1 XOR 1]", 0.0), ("[1 + 1 EQ 2 AND 3 GT 2]", 1.0),
    ("ABS[-2.5]", 2.5), ("ACOS[0.5]", math.degrees(math.acos(0.5))),
    ("ASIN[0.5]", math.degrees(math.asin(0.5))), ("ATAN[1]/[-1]", math.degrees(math.atan2(1, -1))),
    ("COS[30]", math.cos(math.radians(30))), ("SIN[30]", math.sin(math.radians(30))),
    ("TAN[30]", math.tan(math.radians(30))), ("EXP[1.5]", math.exp(1.5)), ("LN[2]", math.log(2)),
    ("SQRT[2]", math.sqrt(2)), ("FIX[-2.8]", -3.0), ("FUP[-2.8]", -2.0), ("FIX[2.8]", 2.0),
    ("FUP[2.8]", 3.0), ("ROUND[2.5]", 3.0), ("ROUND[-2.5]", -3.0), ("ROUND[2.4]", 2.0),
    ("[#3 + #<_g> * 2]", 6.0 + 1.5 * 2), ("##4", 6.0), ("#[1 + 2]", 6.0),
    ("EXISTS[#<_g>]", 1.0), ("EXISTS[#<_nope>]", 0.0), ("-[2 + 1]", -3.0),
])
def test_expressions_against_python_math(expr, expected):
    params = NgcParams()
    params.numbered[3] = 6.0
    params.numbered[4] = 3.0
    params.globals["_g"] = 1.5
    v, end = Evaluator(params).value(expr.lower().replace(" ", ""), 0)
    assert end == len(expr.replace(" ", ""))
    assert v == pytest.approx(expected, rel=1e-12, abs=1e-12)


@pytest.mark.parametrize("expr, msg", [
    ("[1 / 0]", "division by zero"), ("SQRT[-1]", "SQRT of -1"), ("ACOS[2]", "ACOS of 2"),
    ("LN[0]", "LN of 0"), ("[-2 ** 0.5]", "non-integer power"), ("#<nope>", "used before it is set"),
    ("#5221", "controller state"), ("[1 + ]", "number is expected"), ("[1 + 2", "closing ']'"),
])
def test_expression_errors(expr, msg):
    with pytest.raises(ExprError, match=msg):
        Evaluator(NgcParams()).value(expr.lower().replace(" ", ""), 0)


def test_runaway_loop_is_refused_in_one_line(tmp_path):
    p = tmp_path / "in.ngc"
    p.write_text("G0 X0 Y0 Z0\n#1 = 0\no5 while [1]\n  #1 = [#1 + 1]\no5 endwhile\nM2\n")
    with pytest.raises(InputError) as exc:
        with open_program(p, "linuxcnc", max_steps=10_000):
            pass
    msg = str(exc.value)
    assert msg.count("\n") == 0 and f"{p}:" in msg
    assert "more than 10000 lines executed (the loop at line 3)" in msg


@pytest.mark.parametrize("text, line, msg", [
    ("o<elsewhere> call\n", 1, "no subroutine o<elsewhere> in this program"),
    ("o1 sub\no2 sub\no2 endsub\no1 endsub\n", 2, "o2 sub inside another subroutine"),
    ("o1 while [1]\no2 endwhile\n", 2, "o2 endwhile without its o2 while"),
    ("o1 if [1]\n", 1, "o1 if without its o1 endif"),
    ("o1 break\n", 1, "o1 break outside its o1 loop"),
    ("G0 X0 Y0\nG1 X#<depth>\n", 2, "#<depth>: used before it is set"),
    ("G0 X0 Y0\nG1 X#<_feed>\n", 2, "global parameter used before the program sets it"),
    ("#5221 = 1\n", 1, "assignment to parameter #5221"),
    ("G0 X0 Y0\nG1 @1 X2\n", 2, "polar words @ \\^ and X or Y"),
    ("G20\nG0 X1.5 Y0 Z0\nG81 R.1 Z-.5 ^60 L6 F10\n", 3, "repeat count L"),
    ("o1 sub\no1 call [1]\no1 endsub\no1 call [1]\n", 2, "nested more than 10 deep"),
])
def test_unsupported_constructs_are_refused_in_one_line(tmp_path, text, line, msg):
    p = tmp_path / "in.ngc"
    p.write_text(text)
    with pytest.raises(InputError, match=msg) as exc:
        read_program(p, XFYZ, dialect="linuxcnc")
    assert exc.value.line == line and exc.value.path == str(p)
    assert str(exc.value).count("\n") == 0


def test_a_program_without_code_is_read_as_it_is(tmp_path):
    p = tmp_path / "in.ngc"
    p.write_text("G21 G90 (no # here: [x])\nG0 X1 Y2 Z3 ; @ ^\nM2\n")
    with open_program(p) as src:
        assert not src.expanded and src.path == str(p)


def test_an_error_after_expansion_names_the_source_line(tmp_path):
    p = tmp_path / "in.ngc"
    p.write_text("G0 X0 Y0 Z0\n#1 = 5\nG1 X#1 F10\nG1 A[#1]\n")
    with pytest.raises(InputError, match="no A axis") as exc:
        read_program(p, XFYZ)
    assert exc.value.line == 4 and "(line 4 of the expanded program)" in str(exc.value)


@pytest.mark.parametrize("mode", ["compiled", "python"])
def test_linuxcnc_cone_expanded_motion_against_hand_computed_positions(tmp_path, monkeypatch, mode):
    """LinuxCNC's cone.ngc (its nc_files): the sub o200 runs twice; in each pass the while loop
    moves to x = 100 cos(a), y = 100 sin(a), c = a for a = -180, -170, ... 180 degrees."""
    if mode == "python":
        monkeypatch.setenv("MTCOMP_NO_FAST_GCODE", "1")
    src = (DATA / "gcode_corpus" / "linuxcnc_cone.ngc").read_text().splitlines()
    # the drilling loop after the two calls moves W only (passed through: see
    # test_toolpaths_controllers.py): cut off here
    cut = next(i for i, t in enumerate(src) if t.startswith("g61"))
    p = tmp_path / "cone.ngc"
    p.write_text("\n".join(src[:cut]) + "\nm2\n")
    machine = tmp_path / "cb.toml"
    machine.write_text('name = "cb"\ntopology = "CBFXYZ"\n'
                       + "".join(f'[axes.{a}]\ntravel_deg = [-1000.0, 1000.0]\n'
                                 'axis_point_mm = [0.0, 0.0, 0.0]\n' for a in "CB")
                       + "".join(f"[axes.{a}]\ntravel_mm = [-500.0, 500.0]\n" for a in "XYZ"))
    m = load_machine(machine)
    rows = np.vstack([c.end for c in iter_segment_chunks(p, m)])
    x, y, c = (m.index(a) for a in "XYC")
    feed = [r for r in rows if abs(r[m.index("Z")] + 100) < 1e-9 and abs(r[m.index("B")] + math.pi / 4) < 1e-9]
    # per pass: g1 z-100 (at x-100 y0 c-180), then 37 loop moves
    a = np.radians(np.arange(-180, 181, 10))
    expect = np.column_stack([100 * np.cos(a), 100 * np.sin(a), a])
    got = np.array(feed)[:, [x, y, c]]
    assert got.shape[0] == 2 * (1 + 37)
    for k in range(2):
        np.testing.assert_allclose(got[k * 38 + 1:k * 38 + 38], expect, rtol=0, atol=1e-6)

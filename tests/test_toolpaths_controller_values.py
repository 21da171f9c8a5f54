"""Values the controller holds (its position #<_x>, a probe's result #5063, FluidNC's #</...>
settings) and probing moves G38.x: the lines that use them pass through as written, the axes they
move are not written again until the program positions them, and control flow on them is refused.
Each program is hand-made; the output is checked with the corpus' oracle of positioned axes
(tests/test_gcode_corpus.py, written from the RS-274 rules, sharing no code with the reader)."""
import contextlib
import io
import math

import pytest

from mtcomp.cli import main
from mtcomp.toolpaths.expr import Evaluator
from mtcomp.toolpaths.ngc import NgcParams
from test_gcode_corpus import _check_output, _model_file, program_machine_file, source_bytes


def _compensate(tmp_path, text, name="in.ngc"):
    """(exit status, stdout, stderr, output lines or None) of compensating ``text`` on an XYZ
    machine with a model of large random errors (every corrected word changes)."""
    prog = tmp_path / name
    prog.write_text(text)
    machine = program_machine_file(tmp_path, prog)
    model = _model_file(tmp_path, machine, factor=30.0)
    out = tmp_path / "out.nc"
    o, e = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(o), contextlib.redirect_stderr(e):
        code = main(["compensate", str(machine), str(model), str(prog), "-o", str(out),
                     "--units", "mm"])
    if code == 0:
        _check_output(source_bytes(prog), out.read_bytes())
    return code, o.getvalue(), e.getvalue(), (out.read_text().splitlines() if code == 0 else None)


def test_unknown_propagates_through_expressions_and_functions():
    ev = Evaluator(NgcParams())
    for text in ("[#<_z>+5]", "[#5063*2-1]", "[SIN[#<_abs_x>]]", "[#</axes/z/max_travel_mm>]",
                 "[#5420gt1]", "[abs[#5061]and1]"):
        assert math.isnan(ev.bracket(text.lower(), 0)[0]), text
    assert ev.bracket("[2*[1+3]]", 0)[0] == 8.0


def test_a_word_of_a_controller_value_passes_and_its_axis_is_not_written(tmp_path):
    src = ("G21 G90\nG0 X0 Y0 Z5\n#<a> = 2\nG1 X10 F100\nG0 Z[#<_z>+#<a>] (up)\n"
           "G1 X20\nG0 Z3\nG1 X30\nM2\n")
    code, _o, err, out = _compensate(tmp_path, src)
    assert code == 0, err
    body = out[1:]                              # after the expansion's header comment
    # the known parameter is put in as its number, the controller's value kept as written
    assert body[3] == "G0 Z[#<_z>+2] (up)"
    assert body[2] != "G1 X10 F100"             # corrected before it
    assert "Z" not in body[4].upper()          # Z unknown: the X20 move writes no Z
    assert body[5].startswith("G0 Z3") and body[5] != "G0 Z3"     # positioned again: corrected


def test_a_position_read_into_a_parameter_is_kept_with_its_assignment(tmp_path):
    # the assignment of a controller value stays in the output: the line using it needs it
    src = "G21 G90\nG0 X0 Y0 Z5\n#<sx> = #<_x>\nG1 X10 F100\nG0 X#<sx>\nM2\n"
    code, _o, err, out = _compensate(tmp_path, src)
    assert code == 0, err
    assert out[3] == "#<sx> = #<_x>" and out[5:] == ["G0 X#<sx>", "M2"]
    assert out[4] != "G1 X10 F100"              # corrected (with the axis words it needs)


def test_a_probing_move_leaves_its_axes_unknown(tmp_path):
    src = "G21 G90\nG0 X0 Y0 Z5\nG38.2 Z-10 F50\nG1 X10 F100\nG0 Z5\nG1 X20\nM2\n"
    code, _o, err, out = _compensate(tmp_path, src, "in.nc")
    assert code == 0, err
    assert out[2] == "G38.2 Z-10 F50"
    assert "Z" not in out[3].upper() and out[3] != "G1 X10 F100"
    assert out[4] != "G0 Z5"                    # Z positioned again: corrected


def test_axis_words_alone_after_a_probing_move_are_refused(tmp_path):
    code, _o, err, out = _compensate(tmp_path, "G21 G90\nG0 X0 Y0 Z5\nG38.2 Z-10 F50\nZ-12\n",
                                     "in.nc")
    assert code == 2 and out is None and err.count("\n") == 1
    assert "in.nc:4:" in err and "Traceback" not in err


def test_a_tool_length_from_a_probe_stops_every_correction_until_g49(tmp_path):
    # every axis positioned again after the G43.1 (which loses them all): still not corrected
    src = ("G21 G90\nG0 X0 Y0 Z5\n#<tlo> = [#5063-1]\nG43.1 Z#<tlo>\nG0 X0 Y0 Z5\n"
           "G1 X10 F100\nG49\nG0 X0 Y0 Z5\nG1 X20\nM2\n")
    code, stdout, err, out = _compensate(tmp_path, src)
    assert code == 0, err
    body = out[1:]
    assert body[2:6] == ["#<tlo> = [#5063-1]", "G43.1 Z#<tlo>", "G0 X0 Y0 Z5", "G1 X10 F100"]
    assert body[7] != "G0 X0 Y0 Z5" and body[8] != "G1 X20"   # after G49: corrected again
    assert "no block is corrected until G49" in stdout


@pytest.mark.parametrize("text, line, what", [
    ("G0 X0 Y0 Z0\no1 if [#<_z> GT 0]\nG0 X1\no1 endif\nM2\n", 2, "o1 if reads a value"),
    ("G0 X0 Y0 Z0\n#1 = 0\no2 while [#1 LT #5063]\n#1 = [#1 + 1]\no2 endwhile\nM2\n", 3,
     "o2 while reads a value"),
    ("G0 X0 Y0 Z0\no3 repeat [#<_x>]\nG0 X1\no3 endrepeat\nM2\n", 2, "o3 repeat reads a value"),
    ("G0 X0 Y0 Z0\nG92 X#<_x>\nM2\n", 2, "an offset (G10, G52, G92) set from a value"),
    ("o1 sub\n#<a> = #<_x>\no1 endsub\nG0 X0 Y0 Z0\no1 call\nM2\n", 2,
     "assigned to #<a> inside a subroutine call"),
    ("o1 sub\nG0 X#1\no1 endsub\nG0 X0 Y0 Z0\no1 call [#<_x>]\nM2\n", 5, "o1 call argument"),
    ("G0 X0 Y0 Z0\nG0 X##5063\nM2\n", 2, "a parameter number computed from a value"),
    ("G0 X0 Y0 Z0\nG81 X1 Y1 Z#5063 R1 F100\nM2\n", 2, "a drilling cycle given a value"),
])
def test_control_flow_and_offsets_on_a_controller_value_are_refused(tmp_path, text, line, what):
    code, _o, err, out = _compensate(tmp_path, text)
    assert code == 2 and out is None and err.count("\n") == 1 and "Traceback" not in err
    assert f"in.ngc:{line}:" in err and what in err, err


def test_words_of_no_axis_pass_as_written(tmp_path):
    # FluidNC's D (prints a value), a spindle speed from a setting: passed as written
    src = ("G21 G90\nG0 X0 Y0 Z5\n#<t> = #5063\nD#<t>\nS#</spindle/max_rpm> M3\n"
           "G1 X10 F100\nM2\n")
    code, _o, err, out = _compensate(tmp_path, src)
    assert code == 0, err
    assert out[3:6] == ["#<t> = #5063", "D#<t>", "S#</spindle/max_rpm> M3"]
    assert out[6] != "G1 X10 F100"

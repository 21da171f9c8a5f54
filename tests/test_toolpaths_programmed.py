"""Work offsets a program sets itself (G10 L2 / L20) on both reader paths, and Haas' alarm-only IF
on a system variable: the hand-derived machine positions, the same corrections as the same offset
given on the command line, the refusals where the controllers differ."""
import numpy as np
import pytest

from mtcomp.errors import InputError
from mtcomp.machine import load_machine
from mtcomp.toolpaths import iter_segment_chunks
from mtcomp.toolpaths.offsets import ProgramSetup, load_setup
from mtcomp.toolpaths.source import open_program
from test_compensate_cli import _model, _run
from test_toolpaths_dialect import mode  # noqa: F401  (the fixture: both reader paths)

XFYZ = load_machine("xfyz")


def _machine_rows(path, setup, dialect=None):
    """(machine end positions (n, 3), known (n, 3)) of a program's rows, offsets applied."""
    ends, known = [], []
    with open_program(path, dialect) as src:
        for chunk in iter_segment_chunks(src, XFYZ):
            mchunk, _off = setup.apply(chunk, src)
            ends.append(mchunk.end)
            known.append(chunk.known)
    return np.vstack(ends), np.vstack(known)


def test_g10_l2_places_the_blocks_at_the_offset_the_program_sets(tmp_path, mode):
    p = tmp_path / "p.nc"
    # G54 from the command line (X10) until the program sets X100 Y50 Z-20 (Y and Z were 0)
    p.write_text("G21 G90 G54\nG0 X1 Y2 Z3\nG10 L2 P1 X100 Y50 Z-20\nG0 X5\nG0 Y6 Z7\n"
                 "G10 L2 P2 X-1 Y-2 Z-3\nG55 G0 X1 Y1 Z1\nM30\n")
    setup = load_setup(XFYZ, work_offset_flags=["G54=X10"])
    ends, known = _machine_rows(p, setup)
    # the positions by hand: program position + offset; G55 set before it is selected
    np.testing.assert_allclose(ends[[0, 1, 2, 3]],
                               [[11, 2, 3], [105, 52, -17], [105, 56, -13], [0, -1, -2]],
                               rtol=0, atol=1e-12)
    # the offset of the active system changed under Y and Z (from outside the program, so the
    # program's position there is not known any more) until the program names them again
    assert known[1].tolist() == [True, False, False] and known[2].all()
    assert setup.programmed_wcs == {0, 1}


@pytest.mark.parametrize("dialect", ["linuxcnc", "grbl"])     # grbl's gcode.c does as LinuxCNC
def test_g10_l20_makes_the_current_position_read_the_values(tmp_path, mode, dialect):
    p = tmp_path / "p.nc"
    # G91 on the G10 line changes nothing: its values are set, not added
    p.write_text("G21 G90\nG10 L2 P1 X100 Y0 Z0\nG0 X1 Y2 Z3\nG91 G10 L20 P1 X0\nG90 G0 X4\n"
                 "G10 L20 P0 Y10\nG0 Y11\nM30\n")
    ends, known = _machine_rows(p, ProgramSetup(XFYZ), dialect)
    # X offset 1 + 100 - 0 = 101: X4 is 105; Y offset 2 + 0 - 10 = -8: Y11 is 3
    np.testing.assert_allclose(ends, [[101, 2, 3], [105, 2, 3], [105, 3, 3]], rtol=0, atol=1e-12)
    assert known.all()


def test_g10_l2_shifts_a_known_position_by_the_change(tmp_path, mode):
    p = tmp_path / "p.nc"
    # the program set G54 itself: after the new X offset X reads 1 - (50 - 100) = 51, so the
    # incremental move goes from there
    p.write_text("G21 G90\nG10 L2 P1 X100 Y0 Z0\nG0 X1 Y2 Z3\nG10 L2 P1 X50\nG91 G0 X1\nM30\n")
    ends, known = _machine_rows(p, ProgramSetup(XFYZ))
    np.testing.assert_allclose(ends[-1], [102, 2, 3], rtol=0, atol=1e-12)
    assert known.all()


@pytest.mark.parametrize("line, dialect, words", [
    ("G10 L1 P1 Z100", "linuxcnc", "G10 L1"),
    ("G10 L2 P0 X5", "generic", "P0"),
    ("G10 L2 P1 X5 R30", "linuxcnc", "rotation"),
    ("G91 G10 L2 P1 X5.", "fanuc", "under G91"),
    ("G10 L20 P1 X5.", "haas", "G54.1"),
    ("G10 L2 P12 X5", "linuxcnc", "P word 0-9"),
    # X is known, but G54's offset is the command line's: the new one would be that one shifted
    ("G10 L20 P1 X5", "linuxcnc", "axis X: the active system's offset (G54) comes from outside"),
    ("G10 L20 P1 Y5", "grbl", "shifted by -3 mm"),
])
def test_g10_where_it_is_not_clear_is_refused_by_name(tmp_path, line, dialect, words):
    p = tmp_path / "p.nc"
    p.write_text(f"G21 G90\nG0 X1. Y2.\n{line}\nG0 X3.\nM30\n")
    with pytest.raises(InputError) as exc:
        _machine_rows(p, ProgramSetup(XFYZ), dialect)
    assert exc.value.line == 3 and words in exc.value.message


TOUCH_OFF = "G21\n$H\nG10 L20 P1 X0 Y0 Z50\nG54\nG0 X10 Y20 Z40\nG1 X15 F100\nM30\n"


def test_g10_l20_after_homing_takes_the_offset_from_the_command_line(tmp_path, mode):
    """After $H the program does not say where the machine is: the L20 is a touch-off, its offset
    the command line's (G54 X100 Y200 Z-300), and X Y Z read 0 0 50 from there on."""
    p = tmp_path / "p.nc"
    p.write_text(TOUCH_OFF)
    setup = load_setup(XFYZ, work_offset_flags=["G54=X100,Y200,Z-300"])
    ends, known = _machine_rows(p, setup)
    # program position + the command line's offset, by hand
    np.testing.assert_allclose(ends, [[110, 220, -260], [115, 220, -260]], rtol=0, atol=0)
    assert known.all()
    assert setup.used_wcs == {0} and not setup.programmed_wcs
    # the axes the L20 names are known after it: a move naming X alone comes from Y0 Z50
    p.write_text(TOUCH_OFF.replace("G0 X10 Y20 Z40", "G0 X10"))
    ends, known = _machine_rows(p, setup)
    np.testing.assert_allclose(ends[0], [110, 200, -250], rtol=0, atol=0)
    assert known.all()


def test_g10_l20_after_homing_replaces_an_offset_the_program_set(tmp_path, mode):
    """G54 X was the program's (L2, 100) until homing and a touch-off of X: from then on X's offset
    is the command line's (7); Y and Z keep the program's (0, 0)."""
    p = tmp_path / "p.nc"
    p.write_text("G21\nG10 L2 P1 X100 Y0 Z0\nG0 X1 Y2 Z3\n$H\nG10 L20 P1 X0\nG0 X4 Y5 Z6\nM30\n")
    ends, _known = _machine_rows(p, load_setup(XFYZ, work_offset_flags=["G54=X7,Y70,Z700"]))
    np.testing.assert_allclose(ends, [[101, 2, 3], [11, 5, 6]], rtol=0, atol=0)


#: moves that name every axis first, compensated after different ways of setting G54
BODY = "G0 X-50 Y-40 Z20\nG1 Z-5 F800\nX60\nG2 X60 Y40 I0 J40\nG1 X-50\nM30\n"


def _compensated(tmp_path, capsys, name, text, extra) -> tuple[list, str]:
    """(output lines, stdout) of compensating ``text`` with the xfyz model of seed 8."""
    _machine, _fitted, model = _model(tmp_path, "xfyz", seed=8)
    prog, out = tmp_path / f"{name}.nc", tmp_path / f"{name}.out.nc"
    prog.write_text(text)
    code, stdout, err = _run(["compensate", "xfyz", str(model), str(prog), "-o", str(out)] + extra,
                             capsys)
    assert code == 0, err
    return out.read_text().splitlines(), stdout


def test_compensate_after_a_touch_off_is_as_with_the_offset_given(tmp_path, capsys):
    """A program that homes and touches off, and the same moves without: with the same
    --work-offset the same corrections; the note names the line and the flag, once."""
    flag = ["--work-offset", "G54=X100,Y50,Z-200"]
    touch, stdout = _compensated(tmp_path, capsys, "touch",
                                 "G21 G90\n$H\nG10 L20 P1 X0 Y0 Z50\n" + BODY, flag)
    plain, _ = _compensated(tmp_path, capsys, "plain", "G21 G90\n" + BODY, flag)
    notes = [n for n in stdout.splitlines() if "G10 L20" in n]
    assert notes == ["note: G10 L20 at line 3 sets G54 X Y Z where the program has not given the "
                     "position (a touch-off, as after homing): that offset is taken as given on "
                     "the command line (--work-offset G54=..., or --offsets)"]
    assert touch[1:3] == ["$H", "G10 L20 P1 X0 Y0 Z50"]
    assert touch[:1] + touch[3:] == plain
    assert plain[1] != "G0 X-50 Y-40 Z20"          # corrected


def test_compensate_corrects_as_with_the_same_offset_given(tmp_path, capsys):
    """The program's own G10 offset and the same offset given with --work-offset give the same
    output (corrections referenced to the same origin); a different offset does not."""
    own, stdout = _compensated(tmp_path, capsys, "own",
                               "G21 G90\nG10 L2 P1 X100 Y50 Z-200\nG54\n" + BODY, [])
    assert "G54 as the program sets it (G10" in stdout and "assumed: work offset" not in stdout
    given, _ = _compensated(tmp_path, capsys, "given", "G21 G90\nG54\n" + BODY,
                            ["--work-offset", "G54=X100,Y50,Z-200"])
    zero, _ = _compensated(tmp_path, capsys, "zero", "G21 G90\nG54\n" + BODY, [])
    assert own[1] == "G10 L2 P1 X100 Y50 Z-200"
    assert own[:1] + own[2:] == given
    assert given != zero


HAAS = ("%\nO00094 ( HAAS )\nN10 G17 G40 G21 G90\nN30 T5 M06\n"
        "N40 IF [ #5405 GE 6000 ] THEN #3000= 15 ( TOOL LIFE EXPIRED )\n"
        "N70 G00 G54 X5.25 Y0.\nN80 G43 Z50. H05\nN90 G01 Z-5. F200\nN370 M30\n%\n")


def test_haas_alarm_on_a_system_variable_passes_through(tmp_path, mode):
    p = tmp_path / "haas.nc"
    p.write_text(HAAS)
    with open_program(p) as src:
        assert src.dialect.name == "haas"
        text = open(src, encoding="latin-1").read()
        ends = np.vstack([c.end for c in iter_segment_chunks(src, XFYZ)])
    # the line is in the expansion as written, and the motion is the program's
    assert "N40 IF [ #5405 GE 6000 ] THEN #3000= 15 ( TOOL LIFE EXPIRED )\n" in text
    np.testing.assert_allclose(ends, [[5.25, 0, 0], [5.25, 0, 50], [5.25, 0, -5]], rtol=0, atol=0)


@pytest.mark.parametrize("line, words", [
    ("N40 IF [ 1 EQ 1 ] THEN #3000= 15", "the program stops here"),
    ("N40 IF [ #5405 GE 6000 ] THEN #100= 15", "system variable #5405"),
    ("N40 G0 X#5021", "system variable #5021"),
])
def test_other_uses_of_system_variables_are_refused(tmp_path, line, words):
    p = tmp_path / "haas.nc"
    p.write_text(HAAS.replace("N40 IF [ #5405 GE 6000 ] THEN #3000= 15 ( TOOL LIFE EXPIRED )", line))
    with pytest.raises(InputError) as exc:
        with open_program(p) as src:
            list(iter_segment_chunks(src, XFYZ))
    assert exc.value.line == 5 and words in exc.value.message

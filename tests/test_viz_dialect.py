"""render reads the program by the same controller rules as compensate (--dialect): a full circle
of zero radius at the tool's position is refused by LinuxCNC ("Zero-radius arc", interp_arc.cc) and
run without motion by grbl; the map of a grbl program given --dialect linuxcnc is refused in one
line naming it, and with the compensated program beside it the pairing reads both by grbl's rules."""
import pytest

from mtcomp.cli import main
from test_compensate_cli import _model

pytest.importorskip("matplotlib")

PROGRAM = """G21 G90 G17
G0 X10 Y10 Z5
G1 Z-1 F300
G1 X60 Y10
G1 X60 Y50
G3 X60 Y50 I0 J0
G1 X10 Y50
G1 X10 Y10
G0 Z5
M2
"""


def test_render_reads_the_program_by_the_dialect_given(tmp_path, capsys):
    _, _, model = _model(tmp_path, "xfyz", seed=5, scale=3.0)
    prog = tmp_path / "square.nc"
    prog.write_text(PROGRAM)
    comp = tmp_path / "square_c.nc"
    assert main(["compensate", "xfyz", str(model), str(prog), "-o", str(comp), "--quiet",
                 "--dialect", "grbl"]) == 0
    png = tmp_path / "map.png"
    args = ["render", "xfyz", str(model), str(prog), "--compensated", str(comp), "-o", str(png),
            "--backend", "matplotlib"]
    assert main(args + ["--dialect", "grbl"]) == 0
    assert png.is_file() and png.with_suffix(".vtp").is_file()
    png.unlink()
    png.with_suffix(".vtp").unlink()
    capsys.readouterr()
    assert main(args + ["--dialect", "linuxcnc"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "square.nc:6:" in err[0] and "zero radius" in err[0].lower(), err
    assert not png.exists() and not png.with_suffix(".vtp").exists()


ARCS = """G21 G90 G17
G0 X0 Y0 Z5
G1 Z-1 F300
G2 X100 Y0 I50 J0
G2 X0 Y0 I-50 J0
G0 Z5
M2
"""


def test_render_reads_arcs_at_the_chord_tolerance_compensate_was_given(tmp_path, capsys):
    """A report of compensate --chord-tol-um 10 holds the chords of that tolerance: render pairs it
    with the program read at the same tolerance, and at another names the likely cause."""
    _, _, model = _model(tmp_path, "xfyz", seed=5, scale=3.0)
    prog = tmp_path / "arcs.nc"
    prog.write_text(ARCS)
    comp, rep = tmp_path / "arcs_c.nc", tmp_path / "b.csv"
    assert main(["compensate", "xfyz", str(model), str(prog), "-o", str(comp), "--quiet",
                 "--report", str(rep), "--chord-tol-um", "10"]) == 0
    png = tmp_path / "map.png"
    args = ["render", "xfyz", str(model), str(prog), "--report", str(rep), "-o", str(png),
            "--backend", "matplotlib"]
    capsys.readouterr()
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "b.csv" in err[0] and "--chord-tol-um" in err[0], err
    assert not png.exists()
    assert main(args + ["--chord-tol-um", "10"]) == 0
    assert png.is_file()

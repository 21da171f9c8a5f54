"""What a new user of a 5-axis machine found on the command line: an option that takes one value
given twice is refused (argparse lets the last one win silently: `-o a.json -o b.json` wrote only
b.json, `--format linuxcnc --format siemens` wrote Siemens tables); render takes `--tool-length` as
compensate does (it was an unrecognised argument); and render's default map of a program whose tool
axis turns against the part while it cuts (simultaneous 5-axis, tool centre point mode) is the path
in space, not a triangulation of its tips seen along Z (a sliver "surface" of a ring that showed
1.6 um along Z where the path is 17.7 um off)."""
from __future__ import annotations

import re

import numpy as np
import pytest

from mtcomp.cli import main
from mtcomp.machine import load_machine
from mtcomp.models import ErrorModel, FittedModel, save_model
from mtcomp.viz.surface import program_error_map


def _model(tmp_path, name="xfyz", **file_values):
    machine = load_machine(name).with_basis("polynomial")
    fitted = FittedModel.zero(ErrorModel(machine))
    for k, v in file_values.items():
        fitted.params.set_file_value(k, v)
    path = tmp_path / "model.json"
    save_model(path, fitted)
    return machine, fitted, path


@pytest.mark.parametrize("argv", [
    ["export", "xfyz", "MODEL", "--format", "linuxcnc", "--format", "siemens", "-o", "OUT"],
    ["export", "xfyz", "MODEL", "--format", "linuxcnc", "-o", "OUT", "--output", "OUT2"],
])
def test_an_option_that_takes_one_value_given_twice_is_refused(tmp_path, capsys, argv):
    _, _, model = _model(tmp_path)
    argv = [str(model) if a == "MODEL" else str(tmp_path / a) if a.startswith("OUT") else a
            for a in argv]
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "given twice" in err[0]
    assert re.search(r"(--format|-o/--output) given twice", err[0])
    assert not (tmp_path / "OUT").exists() and not (tmp_path / "OUT2").exists()


#: a square with the tool of H1, tilted: its side at x = +10 at Z-10, at x = -10 at Z0. A tool's length
#: decides where the ram stands for these tips (z + L - L0), so the straightness of Z it meets there
SQUARE_H1 = """G21 G90 G17
G43 H1
G0 X-10 Y-10 Z5
G1 Z0 F300
G1 X10 Z-10
G1 Y10
G1 X-10 Z0
G1 Y-10
G0 Z5
M30
"""


def _render_max(tmp_path, capsys, model, *extra):
    assert main(["render", "xfyz", str(model), str(tmp_path / "sq.nc"), "-o",
                 str(tmp_path / "map.png"), "--backend", "matplotlib", *extra]) == 0
    out = capsys.readouterr().out
    return float(re.search(r"model prediction before: RMS [0-9.]+ um, max ([0-9.]+) um", out).group(1))


def test_render_takes_tool_lengths_as_compensate_does(tmp_path, capsys):
    """EXZ_2 = 500 um: Z's straightness in X is 500 um (s / 1 m)^2 at ram position s = z + L - L0
    (L0 = 100 mm, the machine's). Against the datum as the probe found it in X (z = 0, the
    machine's 100 mm: s = 0, no error), a tip at z (0 .. -10 on the square) is off in X by
    500 um s^2 / 1e6 mm^2; along the tilted square's normal (1, 0, 2) / sqrt(5) at most: 0.559 um
    with L = 150 mm (s = 50 at z = 0: 2500 mm^2), 2.236 um with 10 mm (s = -100 at z = -10:
    10000 mm^2), 0.022 um with the machine's 100 mm (s = -10: 100 mm^2) (hand-derived). Each tool
    referenced to its own tip at the datum, as before, gave 0.201 and 0.425 um: the X offset of
    the tool's tip from the probe's at the datum left out."""
    _, _, model = _model(tmp_path, EXZ_2=500.0)
    (tmp_path / "sq.nc").write_text(SQUARE_H1)
    (tmp_path / "offsets.toml").write_text("[tool_lengths]\nH1 = 150.0\n")
    assert _render_max(tmp_path, capsys, model, "--tool-length", "H1=150") == pytest.approx(
        500 * 2500e-6 / 5 ** 0.5, rel=0, abs=1e-3)
    assert _render_max(tmp_path, capsys, model, "--offsets", str(tmp_path / "offsets.toml")) == \
        pytest.approx(500 * 2500e-6 / 5 ** 0.5, rel=0, abs=1e-3)
    assert _render_max(tmp_path, capsys, model, "--tool-length", "H1=10") == pytest.approx(
        500 * 10000e-6 / 5 ** 0.5, rel=0, abs=1e-3)


#: a ring in tool centre point mode: the table tilts (A) and turns (C) while the tool cuts
RING_TCP = "G21 G90 G17\nG0 X40 Y0 Z60 A-30 C0\nM428\nG1 Z20 F400\n" + "".join(
    f"G1 X{40 * np.cos(np.radians(t)):.3f} Y{40 * np.sin(np.radians(t)):.3f} "
    f"A{-30 - 10 * np.sin(np.radians(t)):.3f} C{t:.3f}\n" for t in range(5, 361, 5)) + \
    "G0 Z60\nM429\nM30\n"

#: 3+2: the rotary axes index between two faces by rapids; on each face the tool cuts a ramp
THREE_PLUS_TWO = "G21 G90 G17\n" + "".join(
    f"G0 A-30 C{c}\nG0 X-10 Y-10 Z5\nG1 Z0 F300\nG1 X10 Y-5 Z-1\nG1 X-10 Y0 Z-2\nG1 X10 Y5 Z-1\n"
    "G1 X-10 Y10 Z0\nG0 Z5\n" for c in (0, 90)) + "M30\n"


@pytest.mark.parametrize("text, kind", [(RING_TCP, "path"), (THREE_PLUS_TWO, "surface")],
                         ids=["tcp-ring", "3+2"])
def test_a_simultaneous_five_axis_program_is_mapped_as_its_path(tmp_path, text, kind):
    machine, fitted, _ = _model(tmp_path, "cafxyz", C0Y=50.0)
    (tmp_path / "p.nc").write_text(text)
    smap = program_error_map(machine, fitted, tmp_path / "p.nc", normal="auto")
    assert smap.normal_kind == kind


#: the square of SQUARE_H1 in a Sinumerik program whose tool is called by name
SQUARE_NAMED = ('G17 G71 G90\nT="CUTTER 10"\nM6\nD1\nG0 X-10 Y-10 Z5\nG1 Z0 F300\nG1 X10 Z-10\nG1 Y10\n'
                'G1 X-10 Z0\nG1 Y-10\nG0 Z5\nM30\n')


def test_render_takes_the_length_of_a_tool_called_by_name(tmp_path, capsys):
    """As above (0.559 um with 150 mm, 0.022 um at the machine's 100 mm), the tool given by name."""
    _, _, model = _model(tmp_path, EXZ_2=500.0)
    (tmp_path / "sq.nc").write_text(SQUARE_NAMED)
    named = _render_max(tmp_path, capsys, model, "--dialect", "sinumerik",
                        "--tool-length", "CUTTER 10=150")
    assert named == pytest.approx(500 * 2500e-6 / 5 ** 0.5, rel=0, abs=1e-3)
    assert main(["render", "xfyz", str(model), str(tmp_path / "sq.nc"), "-o", str(tmp_path / "m.png"),
                 "--backend", "matplotlib", "--dialect", "sinumerik", "--tool-length", "H1=150"]) == 0
    out = capsys.readouterr().out
    assert "max 0.022 um" in out
    assert 'assumed: tool length of "CUTTER 10" = the machine\'s tool_length_mm (100 mm)' in out

"""What a new user of a Haas UMC-750 (CAFXYZ: a trunnion A carrying a C table) hit on the command
line beside the map of a turned table (tests/test_render_turned_table.py):

* a machine file whose A axis line (``axis_point_mm``) lay 50 mm from the one the model was fitted
  with was accepted, and compensate wrote other corrections with exit status 0: the model's errors
  of a rotary axis are about its own line. Refused now, naming both lines and both files;
* a machine file with the rotary axes stacked the wrong way round (ACFXYZ) was refused on a
  ball-bar row whose length it blamed on the bar or on ``axis_point_mm``: now the topology is
  named, the one the file fits (CAFXYZ, by the independent truth machine's lengths);
* the tool-length note said "the program's tools are 0 .. 100 mm long" of a program that used H01
  alone: the 0 was the blocks after a home move under G49, which are not corrected.
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

import mtcomp
from mtcomp.cli import main
from mtcomp.machine import load_machine
from mtcomp.models import ErrorModel, FittedModel, save_model
from truth.machine import TruthMachine

#: the built-in cafxyz's machine file
CAFXYZ = (Path(mtcomp.__file__).parent / "machines" / "cafxyz.toml").read_text()
PROGRAM = "G21 G90 G17\nG0 X10 Y10 Z10 A0 C0\nG1 Z0 F300\nG1 X30\nG1 Y30\nG0 Z10\nM30\n"


def _machine_file(path, a_point="[0.0, 0.0, -100.0]", topology="CAFXYZ"):
    """cafxyz as a machine file at ``path``, with its A axis line through ``a_point`` and the
    ``topology`` given."""
    text = CAFXYZ.replace('topology = "CAFXYZ"', f'topology = "{topology}"')
    path.write_text(text.replace("axis_point_mm = [0.0, 0.0, -100.0]", f"axis_point_mm = {a_point}"))
    assert load_machine(str(path)).axes[3].axis_point == tuple(eval(a_point))
    return path


def _model(tmp_path, machine_file, info=None):
    """A model of ``machine_file`` with Y0A = 15 um, its data region the whole travel."""
    machine = load_machine(str(machine_file)).with_basis("polynomial")
    model = ErrorModel(machine, ())
    fitted = FittedModel.zero(model)
    fitted.params.values[model.param_names.index("Y0A")] = 15e-3
    fitted.support = {ax.name: tuple(ax.travel) for ax in machine.axes}
    fitted.info.update(info or {})
    save_model(tmp_path / "model.json", fitted)
    return tmp_path / "model.json"


@pytest.mark.parametrize("a_point, refused", [("[0.0, 0.0, -150.0]", True),
                                              ("[0.0, 0.002, -100.0]", True),
                                              ("[50.0, 0.0, -100.0]", False),      # the same line
                                              ("[0.0, 0.0005, -100.0]", False)])   # within 1 um
def test_a_machine_file_whose_rotary_axis_line_is_not_the_models_is_refused(tmp_path, capsys,
                                                                            a_point, refused):
    model = _model(tmp_path, _machine_file(tmp_path / "fitted.toml"))
    other = _machine_file(tmp_path / "given.toml", a_point)
    (tmp_path / "p.nc").write_text(PROGRAM)
    out = tmp_path / "out.nc"
    argv = ["compensate", str(other), str(model), str(tmp_path / "p.nc"), "-o", str(out), "--quiet"]
    if not refused:
        assert main(argv) == 0 and out.exists()
        return
    assert main(argv) == 2 and not out.exists()
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    given = ", ".join(f"{v:g}" for v in eval(a_point))
    assert "model.json" in err[0] and "given.toml" in err[0]
    assert "rotary axis A" in err[0] and "(0, 0, -100) mm" in err[0] and f"({given}) mm" in err[0]


def test_a_topology_with_the_rotary_axes_the_wrong_way_round_is_named(tmp_path, capsys):
    """A ball-bar file of a CAFXYZ trunnion (lengths by the independent truth machine) given with a
    machine file that says ACFXYZ: the rows where both A and C have turned put the balls tens of mm
    from the bar's length, and the message names the topology that fits every row."""
    truth = TruthMachine.zero("cafxyz")
    c = np.arange(0.0, 360.0, 30.0)
    a = np.repeat([0.0, -60.0], c.size)
    c = np.tile(c, 2)
    x, y, z = 100 * np.cos(np.radians(c)), 100 * np.sin(np.radians(c)), np.full(c.size, 50.0)
    q = truth.q_from(x, y, z, a_deg=a, c_deg=c)
    table = np.array([0.0, 0.0, 50.0])
    length = truth.ballbar_length(q, table)
    rows = ["x_mm,y_mm,z_mm,a_deg,c_deg,table_ball_x_mm,table_ball_y_mm,table_ball_z_mm,"
            "tool_ball_x_mm,tool_ball_y_mm,tool_ball_z_mm,length_mm"]
    rows += [f"{x[i]:.5f},{y[i]:.5f},{z[i]:.5f},{a[i]:g},{c[i]:g},0,0,50,0,0,0,{length[i]:.5f}"
             for i in range(c.size)]
    (tmp_path / "bar.csv").write_text("\n".join(rows) + "\n")
    wrong = _machine_file(tmp_path / "wrong.toml", topology="ACFXYZ")
    assert main(["identify", str(wrong), str(tmp_path / "bar.csv"), "-o",
                 str(tmp_path / "m.json")]) == 2
    assert not (tmp_path / "m.json").exists()
    err = capsys.readouterr().err.strip().splitlines()[-1]
    first = 1 + int(np.flatnonzero((a != 0) & (c != 0))[0])     # the data row: A and C turned
    assert f"row {first}" in err
    assert "topology ACFXYZ (A carried by C" in err and "with CAFXYZ (C carried by A)" in err
    assert "axis_point_mm" not in err


TOOLS = ("G21 G90 G17\nG0 A0 C0\nG43 H1 Z20\nG0 X10 Y10\nG1 Z-1 F300\nG1 X20\nG0 Z5\nG49\n"
         "G28 G91 Z0\nG90\nG0 X0 Y0\nM30\n")


@pytest.mark.parametrize("h1, said", [(100.0, None), (150.0, "150 .. 150")])
def test_the_tool_length_note_names_the_tools_of_the_blocks_corrected(tmp_path, capsys, h1, said):
    """The data were taken with 100 mm tools; the program uses H1 only. The block after the home
    move (G49 in force: length 0, Z not known, not corrected) made it "0 .. 100 mm" (and "0 ..
    150")."""
    model = _model(tmp_path, _machine_file(tmp_path / "m.toml"), {"tool_length_mm": [100.0, 100.0]})
    (tmp_path / "p.nc").write_text(TOOLS)
    assert main(["compensate", str(tmp_path / "m.toml"), str(model), str(tmp_path / "p.nc"), "-o",
                 str(tmp_path / "out.nc"), "--tool-length", f"H1={h1:g}"]) == 0
    out = capsys.readouterr().out
    note = re.search(r"the program's tools are ([0-9.]+ \.\. [0-9.]+) mm", out)
    assert (note and note.group(1)) == (said or None), out

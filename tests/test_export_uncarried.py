"""What no exported table carries is listed with its tool-tip error over the volume: a machine-tool
builder's Fanuc export of a trunnion whose C line sat 15 um off in X and -10 um in Y (35 um at the
tool tip in its tool-centre-point blocks) said nothing of it, and its 'remaining' figures were at
the one pose where the offset vanishes.

Hand-derived oracles (a positioning error of X, 10 um/m, gives the Fanuc export a table):
* a rotary table's line offset e (X0C, Y0C) moves the tool tip relative to the part by (R(C) - I) e
  (the table turns the offset with it), |.| = 2 |e| sin(C / 2): zero at C = 0, where the tables are
  read, 2 |e| at C = 180 deg (30 um for X0C = 15 um alone, 36.06 um for X0C = 15, Y0C = -10 um);
* a squareness B0Z (Z leaning in X) moves the tip by z B0Z in X: over Z -250 .. 150 mm from the
  tables' pose Z = -50 (the middle), at most 200 mm x 20 urad = 4 um. LinuxCNC's matrixkins carries it (nothing listed); Fanuc's pitch
  tables do not (listed).
"""
from __future__ import annotations

import re

import numpy as np

import pytest

from mtcomp.cli import main
from mtcomp.machine import load_machine
from mtcomp.models import ErrorModel, FittedModel, save_model


def _model(tmp_path, machine, values):
    """A model of built-in ``machine`` whose parameters ``values`` (name -> um or urad) are set, its
    data region the whole travel."""
    m = load_machine(machine)
    model = ErrorModel(m.with_basis("polynomial"), ())
    fitted = FittedModel.zero(model)
    names = [s.name for s in model.param_specs]
    for name, value in values.items():
        i = names.index(name)
        fitted.params.values[i] = value * {"um": 1e-3, "urad": 1e-6}[model.param_specs[i].unit]
    fitted.support = {ax.name: tuple(ax.travel) for ax in m.axes}
    path = tmp_path / "m.json"
    save_model(path, fitted)
    return path


def _export(tmp_path, capsys, machine, path, fmt):
    out = tmp_path / fmt
    assert main(["export", machine, str(path), "--format", fmt, "-o", str(out)]) == 0
    return (out / "README.txt").read_text(), capsys.readouterr().err


def _up_to(text, name):
    m = re.search(rf"^\s*- {name} \(.*?\): up to ([0-9.]+) um at the tool tip \(at ([^)]*)\)", text, re.M)
    assert m, text
    return float(m.group(1)), m.group(2)


def test_rotary_line_offset_listed_with_its_tool_tip_error_swept(tmp_path, capsys):
    path = _model(tmp_path, "cbfxyz", {"X0C": 15.0, "Y0C": -10.0, "EXX_1": 10.0})
    readme, err = _export(tmp_path, capsys, "cbfxyz", path, "fanuc")
    up, at = _up_to(readme, "X0C")
    assert up == pytest.approx(30.0, abs=0.01)
    assert re.search(r"C-?180$", at), at        # half a turn from where the tables are read
    assert _up_to(readme, "Y0C")[0] == pytest.approx(20.0, abs=0.01)
    together = float(re.search(r"from these together: up to ([0-9.]+) um", readme).group(1))
    assert together == pytest.approx(2 * (15.0 ** 2 + 10.0 ** 2) ** 0.5, abs=0.01)
    assert "19703-19705" in readme                  # Fanuc's TCP parameters that hold the line
    # and a Haas control's: its machine rotary zero point (Haas mill operator's manual, settings)
    assert "machine rotary zero point (MRZP), settings 255-257" in readme
    assert "not carried: X0C" in err and "together: up to 36.06 um" in err
    assert "the others at the one pose the tables are read at" in readme


@pytest.mark.parametrize("fmt, listed", [("fanuc", True), ("linuxcnc", False)])
def test_squareness_listed_only_where_the_format_has_no_table_for_it(tmp_path, capsys, fmt, listed):
    path = _model(tmp_path, "xfyz", {"B0Z": 20.0})
    readme, _ = _export(tmp_path, capsys, "xfyz", path, fmt)
    if listed:
        assert _up_to(readme, "B0Z")[0] == pytest.approx(4.0, abs=0.01)
        assert "mtcomp compensate" in readme
    else:
        assert "B0Z" not in readme, readme


def test_an_offset_the_data_do_not_determine_is_advised_as_no_correction(tmp_path, capsys):
    """A new user's Haas trunnion (one stylus length): the Fanuc export advised correcting the MRZP
    settings by X0C +9.75 um and X0B +7.80 um, each 'no standard error: the data do not fix it
    alone' (truth 15 and 12 um): with one stylus length such an offset trades with the spindle's
    tilt and the tool's length. Here X0C (15 um) moves along a direction the data left open
    (MODEL.json uncertainty.undetermined) and Y0C (-10 um) is fitted, +- 0.5 um: Y0C keeps its value,
    standard error, tool-tip error (20 um, 2 |e| at C 180) and the parameters that hold a line;
    X0C is named not determined, with no value and no size, and what would measure it; 'together'
    is Y0C's alone."""
    m = load_machine("cbfxyz")
    model = ErrorModel(m.with_basis("polynomial"), ())
    fitted = FittedModel.zero(model)
    for name, value in (("X0C", 15.0), ("Y0C", -10.0), ("EXX_1", 10.0)):
        fitted.params.set_file_value(name, value)
    fitted.support = {ax.name: tuple(ax.travel) for ax in m.axes}
    sd = 0.5e-3                                                      # mm
    fitted.uncertainty = {"names": ["X0C", "Y0C"], "covariance": np.diag([sd ** 2, sd ** 2]),
                          "undetermined": np.array([[1e-3], [0.0]]),
                          "held": np.zeros((2, 0)), "held_sd_um": np.zeros(0)}
    path = tmp_path / "m.json"
    save_model(path, fitted)
    readme, err = _export(tmp_path, capsys, "cbfxyz", path, "fanuc")
    lines = err.splitlines()

    def said(name):         # (the line on ``name``, the line its mark [n] points to)
        line = next(ln for ln in lines if f"not carried: {name} " in ln)
        mark = re.search(r"\[(\d)\]$", line).group(1)
        return line, next(ln for ln in lines if f"not carried: [{mark}] " in ln)
    x0c, advice = said("X0C")
    assert "not determined by the data" in x0c and "+15" not in x0c and "up to" not in x0c, x0c
    assert "no value of it is a correction to enter" in advice and "two stylus lengths" in advice
    assert "19703" not in advice and "MRZP" not in advice, advice
    y0c, advice = said("Y0C")
    assert "-10.00 +- 0.5 um: up to 20.00 um at the tool tip" in y0c, y0c
    assert "19703-19705" in advice and "MRZP" in advice, advice
    assert "together: up to 20.00 um" in err
    assert "- X0C (location of C: offset): not determined by the data" in readme

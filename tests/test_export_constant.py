"""What no compensation table carries is said: every table is measured from the deviation with every
axis at its reference position (each table is zero there), so a rotary table's zero offset, a
constant turn of the workpiece, is in no table. A user's LinuxCNC export of a model with the A
axis's zero offset EAA_0 = 40 urad wrote an all-zero A table and said nothing, while compensate
corrected the 40 urad on every block.

Hand-derived: with only EAA_0 = e, the table (and the workpiece on it) stands turned by e about X
at every position; the tool relative to the workpiece is turned by -e about X, the tip at the
machine's tool length displaced only by the second-order e^2 terms (no translation to note)."""
from __future__ import annotations

import re

import numpy as np

from mtcomp.cli import main
from mtcomp.machine import load_machine
from mtcomp.models import ErrorModel, FittedModel, save_model


def _model(tmp_path, name, value):
    """A model (polynomial profiles: E(s) = sum_k E_k (s / 1 m)^k) whose one parameter ``name`` is
    ``value`` in its unit (um or urad; stored in mm, rad)."""
    model = ErrorModel(load_machine("cafxyz").with_basis("polynomial"), ())
    fitted = FittedModel.zero(model)
    i = [s.name for s in model.param_specs].index(name)
    fitted.params.values[i] = value * {"um": 1e-3, "urad": 1e-6}[model.param_specs[i].unit]
    path = tmp_path / "m.json"
    save_model(path, fitted)
    return path


def test_a_rotary_zero_offset_no_table_carries_is_said(tmp_path, capsys):
    path = _model(tmp_path, "EAA_0", 40.0)
    out = tmp_path / "comp"
    assert main(["export", "cafxyz", str(path), "--format", "linuxcnc", "-o", str(out)]) == 0
    said = capsys.readouterr().out + (out / "README.txt").read_text()
    assert "a turn of -40.00 urad about X" in said, said
    assert "no table carries it" in said


def test_nothing_is_said_of_a_model_without_a_constant(tmp_path, capsys):
    # a positioning error that is zero at X's reference position (X = 0): 20 um/m of X
    path = _model(tmp_path, "EXX_1", 20.0)
    out = tmp_path / "comp"
    assert main(["export", "cafxyz", str(path), "--format", "linuxcnc", "-o", str(out)]) == 0
    said = capsys.readouterr().out + (out / "README.txt").read_text()
    assert "no table carries it" not in said
    assert np.ptp(np.loadtxt(out / "x.comp")[:, 1]) > 0          # the slope is in X's table


def test_a_turn_on_a_machine_without_rotary_axes_is_said_as_a_tilted_tool(tmp_path, capsys):
    """A 3-axis machine's spindle tilt A0S = 30 urad: the tool stands turned by 30 urad about X at
    every position; no axis could turn it back, so the note must not call it a rotary axis's zero
    offset (it did, on a user's VMC)."""
    model = ErrorModel(load_machine("xfyz").with_basis("polynomial"), ())
    fitted = FittedModel.zero(model)
    fitted.params.set_file_value("A0S", 30.0)
    fitted.params.set_file_value("EXX_1", 20.0)           # a table to write
    path = tmp_path / "m.json"
    save_model(path, fitted)
    out = tmp_path / "comp"
    assert main(["export", "xfyz", str(path), "--format", "linuxcnc", "-o", str(out)]) == 0
    said = capsys.readouterr().err + (out / "README.txt").read_text()
    assert re.search(r"a turn of [+-]30\.00 urad about X", said), said
    assert "rotary axis's zero offset" not in said
    assert "a machine without rotary axes has no axis that could turn it back" in said


def test_a_turn_the_data_do_not_determine_is_said_to_be_none_of_their_making(tmp_path, capsys):
    """A service engineer's Fanuc export reported "a turn of +4.62 urad about X" at the reference
    position: the spindle tilt A0S that the fit held there, which the data read only in combination
    with set-ups and rolls no file measured (MODEL.json lists it among the undetermined directions;
    no truth had it). With A0S along an undetermined direction the turn is marked not determined;
    with the same value determined (a standard error, no such direction) it is not."""
    model = ErrorModel(load_machine("xfyz").with_basis("polynomial"), ())
    names = ["A0S", "EXX_1"]
    said = {}
    for case, undetermined in (("open", [[1e-5], [0.0]]), ("fixed", [[0.0], [0.0]])):
        fitted = FittedModel.zero(model)
        fitted.params.set_file_value("A0S", 30.0)
        fitted.params.set_file_value("EXX_1", 20.0)
        fitted.uncertainty = {"names": names, "covariance": np.diag([1e-12, 1e-8]),
                              "undetermined": np.array(undetermined)[:, :1 if case == "open" else 0]}
        path = tmp_path / f"{case}.json"
        save_model(path, fitted)
        out = tmp_path / case
        assert main(["export", "xfyz", str(path), "--format", "linuxcnc", "-o", str(out)]) == 0
        said[case] = capsys.readouterr().err + (out / "README.txt").read_text()
    assert re.search(r"a turn of [+-]30\.00 urad about X \(not determined by the data\)", said["open"])
    assert "the fit's choice among models that fit the data alike" in said["open"]
    assert re.search(r"a turn of [+-]30\.00 urad about X:", said["fixed"]), said["fixed"]
    assert "not determined by the data" not in said["fixed"]

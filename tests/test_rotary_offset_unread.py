"""A rotary axis's zero offset (the constant of its angular positioning error over the turn) from
data that hold the axis at one angle, or read it over part of a turn only: the data read the offset
and the error at those angles as one number. identify keeps the sum (its value is the truth's error
at the angle read) but reports the offset as not determined, and export says so.

Oracle: the independent truth machine (tests/truth, no code shared with the model) whose rotary
axis's angular positioning error grows by 50 urad per rad from zero at 0 deg (its error at 30 deg,
26.2 urad, is the profile's, not an offset); noise-free R-test readings of a 2 x 2 grid of balls,
the set-up known and the linear axes, squareness and spindle held."""
import math
import re

import numpy as np
import pytest

from mtcomp.cli import main
from mtcomp.models.model_file import load_model

RATE = 50e-6        # rad of angular positioning error per rad of the axis


def _rtest(tmp_path, machine, axis, angles):
    from truth import TruthMachine
    from truth import campaigns as tc
    from truth import profiles as P
    truth = TruthMachine.zero(machine)
    truth.components[axis][f"E{axis}{axis}"] = P.Linear(0.0, RATE)
    path = tmp_path / "rtest.csv"
    tc.points(truth, path, np.random.default_rng(5), grid=(2, 2, 1), plane={"Z": 0.0},
              rotary_deg=angles, directions=(1,), setup=False, noise_um=0.0, tool_lengths_mm=(100.0,))
    return path


@pytest.mark.parametrize("machine, axis, angles", [
    ("cafxyz", "A", [(30.0, c) for c in range(0, 360, 30)]),      # A at one tilt
    ("cbfxyz", "B", [(30.0, c) for c in range(0, 360, 30)]),      # B at one tilt
    ("cafxyz", "C", [(0.0, c) for c in (0, 30, 60, 90)]),         # C over a quarter of a turn
])
def test_an_offset_read_with_its_profile_is_not_determined(tmp_path, capsys, machine, axis, angles):
    path = _rtest(tmp_path, machine, axis, angles)
    model = tmp_path / "m.json"
    assert main(["identify", machine, str(path), "--known-setup", str(path), "--hold",
                 "X,Y,Z,squareness,spindle", "-o", str(model), "-v"]) == 0
    out = capsys.readouterr().out
    name = f"E{axis}{axis}_0"
    row = next(ln for ln in out.splitlines() if re.search(rf"zero offset of {axis}\s+{name}", ln))
    assert row.rstrip().endswith("not determined by the data"), row
    assert re.search(rf"^{name}\s+\S+\s+undeterm\.", out, re.M)
    fitted = load_model(model)
    if axis != "C":
        # what the data do read: the error at the one angle, the truth's profile there
        value = fitted.params.values[fitted.params.index(name)]
        np.testing.assert_allclose(value, RATE * math.radians(30.0), rtol=1e-8, atol=0)
        assert main(["export", machine, str(model), "--format", "linuxcnc", "-o", str(tmp_path / "exp")]) == 0
        err = capsys.readouterr()
        text = err.out + err.err
        line = next(ln for ln in text.splitlines() if f"not carried: {name}" in ln)
        assert "+-" not in line and "no standard error" in line, line
        note = next(ln for ln in text.splitlines() if "reference position the model predicts" in ln)
        assert re.search(rf"about {'X' if axis == 'A' else 'Y'} \(not determined by the data\)", note), note


def test_an_axis_read_round_its_turn_keeps_its_offset(tmp_path):
    from mtcomp.identification._offsets import unread_offsets
    path = _rtest(tmp_path, "cafxyz", "C", [(0.0, c) for c in range(0, 360, 45)] +
                  [(30.0, c) for c in range(0, 360, 45)])
    model = tmp_path / "m.json"
    assert main(["identify", "cafxyz", str(path), "--known-setup", str(path), "--hold",
                 "X,Y,Z,squareness,spindle", "-o", str(model)]) == 0
    unread = unread_offsets(load_model(model))
    assert "ECC_0" not in unread and "EAA_0" in unread, unread

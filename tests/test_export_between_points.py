"""A table's points sample the model's error along its axis; between them the controller
interpolates. An error of a period shorter than a few grid steps (a ball screw's 10 mm wave against
points every 5 mm: every point on a zero of the wave) is carried by no table, and export says so
with how much it misses, where a new user's Fanuc table silently dropped the screw wave diagnose had
just found. Hand case: EXX = 2 um sin(2 pi x / 10 mm) exactly (PeriodicError), nothing else; at
the points x = 0, -5, -10 ... the wave is zero, at the quarter points -2.5, -7.5 ... +-2 um."""
from __future__ import annotations

import numpy as np

from mtcomp.export._tables import component_tables
from mtcomp.machine import load_machine
from mtcomp.models import ErrorModel, FittedModel
from mtcomp.models.terms import PeriodicError


def _wave(amplitude_um=2.0, period_mm=10.0):
    machine = load_machine("xfyz")
    model = ErrorModel(machine, [PeriodicError("X", period_mm)])
    fitted = FittedModel.zero(model)
    fitted.params.set_file_value("PER_X_s", amplitude_um)
    return machine, fitted


def _notes(fitted, step):
    lo, hi = fitted.machine.axis("X").travel
    grid = np.arange(lo, hi + step / 2, step)
    return [n for n in component_tables(fitted, {"X": grid}).notes if n.startswith("axis X: its table")]


def test_a_wave_between_the_points_is_named_with_its_size():
    machine, fitted = _wave()
    notes = _notes(fitted, 5.0)
    assert len(notes) == 1 and "every 5 mm miss up to 2 um" in notes[0], notes
    # points every 2.5 mm stand on the wave's crests and zeros: linear interpolation misses
    # 2 sin(pi/4) - 1 = 0.414 um at the quarter points: below the note's 0.5 um
    assert _notes(fitted, 2.5) == []


def test_a_smooth_error_gets_no_note():
    machine, fitted = _wave(amplitude_um=0.4)
    assert _notes(fitted, 5.0) == []

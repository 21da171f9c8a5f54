"""diagnose refines the base along a linear axis when its own held-out data ask for it, and not for a
defect in one place (mtcomp.diagnose._resolution).

The readings are written here from their definitions (numpy sines and a raised cosine, known noise)
into a points file (SPEC 3.1, every 2.5 mm, three runs); the machine's X base is fixed at 8 intervals over 600 mm (knots 75 mm
apart), too coarse for a 150 mm wave.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from mtcomp.diagnose import diagnose
from mtcomp.machine import load_machine
from mtcomp.measurement.files import read_measurements

NOISE = 0.3


def _machine():
    m = load_machine("xfyz")
    return replace(m, axes=tuple(replace(ax, spline_range=(-300.0, 300.0), spline_intervals=8, degree=3)
                                 if ax.name == "X" else ax for ax in m.axes))


def _points(tmp_path, profile, seed=0):
    rng = np.random.default_rng(seed)
    x = np.linspace(-300.0, 300.0, 241)             # 2.5 mm apart: a 20 mm bump is read at 8 positions
    rows = ["x_mm,y_mm,z_mm,dx_um,run"]
    for run in (1, 2, 3):
        for xi in x:
            rows.append(f"{xi:.3f},0,0,{profile(xi) + rng.normal(0.0, NOISE):.5f},{run}")
    path = tmp_path / "points.csv"
    path.write_text("\n".join(rows) + "\n")
    return [read_measurements(path)]


def test_a_wave_finer_than_the_knots_refines_the_base(tmp_path):
    def wave(x):
        return 3.0 * np.sin(2 * np.pi * x / 150.0 + 0.3)
    d = diagnose(_machine(), _points(tmp_path, wave))
    assert d.base["refined"]["X"] > 8 + 3
    assert d.verdict == "none" and not d.findings
    # the finer knots are in the model, and it follows the wave to within the noise
    assert d.model.model.machine.axis("X").spline_intervals > 8
    assert d.final["heldout_rms_um"] < 1.2 * NOISE


def test_a_narrow_bump_is_reported_not_absorbed(tmp_path):
    def bump(x):
        u = (x - 90.0) / 20.0
        return 2.0 * np.sin(2 * np.pi * x / 900.0) + np.where(np.abs(u) < 0.5, 3.0 * (1 + np.cos(2 * np.pi * u)), 0.0)
    d = diagnose(_machine(), _points(tmp_path, bump))
    assert "refined" not in d.base
    assert d.verdict == "unexplained"
    assert d.findings[-1].effect == "unexplained" and d.findings[-1].axis == "X"

"""diagnose refines the base along a linear axis when its own held-out data ask for it, and not for a
defect in one place (mtcomp.diagnose._resolution).

The readings are written here from their definitions (numpy sines and a raised cosine, known noise)
into a points file (SPEC 3.1, every 2.5 mm, three runs); the machine's X base is fixed at 8 intervals over 600 mm (knots 75 mm
apart), too coarse for a 150 mm wave.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

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


def test_components_no_reading_sees_get_no_finer_columns(tmp_path):
    """Readings of dx along X at Y 0, Z 0 and no tool: only the positioning error EXX moves them to
    first order (the angles have no arm, the straightnesses move Y and Z). The other components'
    columns at the fitted base are the chain's round-off (1e-56 to 1e-9 of EXX's); scaled up in the
    held-out fits they once passed for information, a roll on finer knots "gaining" 572 noise
    variances to EXX's 375, so that which component spoke for the axis was round-off's choice."""
    import mtcomp.diagnose._diagnose as D
    from mtcomp.diagnose._resolution import finer_base_columns
    from mtcomp.diagnose._stack import build_stack

    def bump(x):
        return 2.0 * np.sin(2 * np.pi * x / 900.0)
    data = _points(tmp_path, bump)
    machine, values = D._base_machine(_machine(), data, None, None)
    st = build_stack(machine, data)
    D._base_fit(st, values, False, lambda s: None)        # leaves the stack at the fitted base
    by_comp, _ = finer_base_columns(st, "X")
    assert set(by_comp) == {"EXX"}


def test_a_finer_base_that_predicts_worse_is_not_kept(monkeypatch):
    """The rerun loop of diagnose(), with stand-in diagnoses: a finer base whose diagnosis predicts
    held-out readings worse (scored with the first run's noise floor) is dropped and listed under
    rejected; one that predicts better is kept, and refinement stops after MAX_REFINEMENTS."""
    from types import SimpleNamespace

    import mtcomp.diagnose._diagnose as D
    from mtcomp.diagnose._analysis import Noise
    from mtcomp.diagnose._resolution import MAX_REFINEMENTS
    from mtcomp.models.basis import spline_basis

    def stub(resid_um, rank, finer):
        d = SimpleNamespace(noise={"um": Noise("um", 0.5, 100, "repeats")}, heldout_resid=np.asarray(resid_um),
                            units=np.array(["um"] * len(resid_um)), rank=rank, rejected=[])
        return d, finer

    fine = spline_basis(-300.0, 300.0, 16, 3)
    calls = []

    def worse(machine, datasets, progress, max_findings, start, refine, may_refine, known_setup=()):
        calls.append(dict(refine))
        if not refine:
            return stub([0.5] * 100, 10, ("X", fine, "finer X"))
        return stub([0.9] * 100, 18, None)                     # 324 against 100 noise variances
    monkeypatch.setattr(D, "_diagnose", worse)
    d = D.diagnose(load_machine("xfyz"), [SimpleNamespace(kind="points")])
    assert len(calls) == 2 and d.heldout_resid[0] == 0.5
    assert d.rejected and d.rejected[0]["effect"] == "finer base" and d.rejected[0]["axis"] == "X"

    calls.clear()

    def better(machine, datasets, progress, max_findings, start, refine, may_refine, known_setup=()):
        calls.append((dict(refine), may_refine))
        # every run finds structure a finer base of Y would take, and predicts better than the one
        # before; the loop must stop on its own
        k = len(calls) - 1
        return stub([0.5 - 0.1 * k] * 100, 10 + 8 * k, ("Y", fine, "finer Y"))
    monkeypatch.setattr(D, "_diagnose", better)
    d = D.diagnose(load_machine("xfyz"), [SimpleNamespace(kind="points")])
    assert len(calls) == MAX_REFINEMENTS + 1
    assert calls[-1][1] is False                                # the last rerun may not refine
    assert d.heldout_resid[0] == pytest.approx(0.5 - 0.1 * MAX_REFINEMENTS)


def test_a_start_model_gives_no_values_to_a_refined_axis(tmp_path):
    """With identify's model as the start (X fixed at 8 intervals), the wave refines X; the rerun
    must not take the start's X coefficients, which belong to other functions (their names, EXX_b1
    ..., exist in the finer base too)."""
    import re

    from mtcomp.identification.fit import identify

    def wave(x):
        return 3.0 * np.sin(2 * np.pi * x / 150.0 + 0.3)
    data = _points(tmp_path, wave)
    start = identify(_machine(), data).fitted_model
    lines = []
    d = diagnose(_machine(), data, start=start, progress=lines.append)
    assert d.base["refined"]["X"] > 8 + 3
    taken = [tuple(int(v) for v in re.findall(r"\d+", s)[:2]) for s in lines if s.startswith("start:")]
    assert len(taken) >= 2
    # first run: every base value the start's data determined (those with a standard error)
    determined = sum(ps.base and np.isfinite(e) for ps, e in zip(start.model.param_specs,
                                                                 start.params.std_errors))
    assert taken[0][0] == determined >= 8 + 3 - 1
    # the rerun: at least the positioning error's 10 coefficients of X (8 + 3 functions, less the
    # mean) are not taken
    assert taken[-1][0] <= taken[0][0] - (8 + 3 - 1)

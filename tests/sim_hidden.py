"""Measurement campaigns with a hidden effect on mtcomp's own virtual machine (mtcomp.sim), for the
tests and benchmarks of `diagnose` (test code: the independent machine of tests/truth has its own).

:func:`hidden_case` draws a machine (xfyz or cafxyz), a random base truth (:func:`mtcomp.sim.random_truth`)
and one effect of docs/diagnose.md's list (which effect, which axis, a magnitude between 4 and 20 times
the noise), and simulates the campaign of :func:`mtcomp.sim.campaign_plans` on the virtual machine,
the repeats of its points grid joined into one file of three runs.

The magnitude is defined on the campaign itself: the largest change the effect makes to any reading
is ``magnitude`` times the noise of that reading. The effect is simulated exactly (the readings are
those of the truth with the effect term), and noise is Gaussian (``noise_um``, ``noise_urad``).
A *local defect* (a bump on one guideway, not periodic, not a term of the model) can be added instead
of, or on top of, an effect. :func:`score` checks a diagnosis against the truth.
"""
from __future__ import annotations

import math
import tempfile
from dataclasses import dataclass, field, replace

import numpy as np

from mtcomp.machine import Machine, load_machine
from mtcomp.models import ErrorModel, FittedModel, ParameterSet
from mtcomp.models.terms import (AbbeIRC, Backlash, FeedOffset, PeriodicError, RotaryErrorMotion,
                                 ThermalDrift, motion_harmonics)
from mtcomp.sim import campaign_plans, with_values

EFFECTS = ("backlash", "rotary_backlash", "thermal_drift", "feed_dependent_abbe",
           "feed_dependent_offset", "periodic_error", "rotary_pdge")
#: effects that need a rotary axis
ROTARY_EFFECTS = ("rotary_backlash", "rotary_pdge")
#: periods (mm) a hidden cyclic error is drawn from (ball-screw leads)
PERIODS = (16.0, 20.0, 25.0, 32.0, 40.0)

_MODELS: dict = {}


def _model(machine: Machine, terms=()) -> ErrorModel:
    """One ErrorModel per (machine, terms), so CasADi functions are built once per process."""
    key = (machine.name, machine.topology, tuple(t.key() + repr(t) for t in terms))
    if key not in _MODELS:
        _MODELS[key] = ErrorModel(machine, tuple(terms))
    return _MODELS[key]


@dataclass
class HiddenCase:
    """A simulated campaign and what it hides.

    machine : the machine. datasets : measurement sets (mtcomp.io), readings in internal units.
    effects : [{'effect', 'axis', 'magnitude' (times the noise), 'params' ...}] hidden effects.
    defect : {'axis', 'centre_mm', 'width_mm', 'height_um'} of a local bump, or None.
    truth : the FittedModel that produced the readings (without the bump).
    noise_um, noise_urad : noise of the readings. seed : the seed.
    """

    machine: Machine
    datasets: list
    effects: list
    truth: FittedModel
    noise_um: float
    noise_urad: float
    seed: int
    defect: dict | None = None
    info: dict = field(default_factory=dict)

    @property
    def n_obs(self) -> int:
        return int(sum(_n_readings(d) for d in self.datasets))

    def write(self, folder) -> list:
        """Write every data set as a measurement CSV file in ``folder``; returns the paths."""
        import csv
        from pathlib import Path
        paths = []
        for d in self.datasets:
            p = Path(folder) / Path(str(d.path)).name
            with open(p, "w", newline="", encoding="utf-8") as f:
                w = csv.writer(f, lineterminator="\n")
                w.writerow(d.header)
                w.writerows(d.rows)
            paths.append(p)
        return paths


def _n_readings(d) -> int:
    if d.kind == "points":
        return int(np.isfinite(d.deviation).sum())
    if d.kind == "laser":
        return int(np.isfinite(d.value).sum())
    if d.kind == "ballbar":
        return int(np.isfinite(d.length).sum())
    return len(d)


def _join_repeat(plans):
    """Fold the repeats of the points grid ('points_mid', 'points_end') into 'points' as runs 2, 3
    (times kept as they are): one file, so that the repeats count for the noise floor."""
    names = [p.name for p in plans]
    repeats = ("points_mid", "points_end")
    if "points" not in names or not any(n in repeats for n in names):
        return plans
    first = plans[names.index("points")]
    cols = {k: list(v) for k, v in first.columns.items()}
    for rep in (p for p in plans if p.name in repeats):
        top = max(cols["run"])
        for k in cols:
            w = rep.columns[k]
            cols[k].extend(list(np.asarray(w, dtype=float) + top) if k == "run" else list(w))
    cols = {k: (v if isinstance(v[0], str) else np.asarray(v)) for k, v in cols.items()}
    joined = replace(first, columns=cols)
    return [joined if p.name == "points" else p for p in plans if p.name not in repeats]


def _readings(d) -> np.ndarray:
    """(n, k) measured arrays of a set, internal units."""
    if d.kind == "points":
        return d.deviation.copy()
    if d.kind == "laser":
        return d.value[:, None].copy()
    return d.length[:, None].copy()


def _put(d, arr):
    if d.kind == "points":
        return with_values(d, {"dx_um": arr[:, 0], "dy_um": arr[:, 1], "dz_um": arr[:, 2]})
    if d.kind == "laser":
        return with_values(d, {"value": arr[:, 0]})
    return with_values(d, {"length_mm": arr[:, 0]})


def _sigma(d, noise_um, noise_urad) -> np.ndarray:
    """(n, k) noise standard deviation of each reading, internal units."""
    if d.kind == "laser":
        return np.where(d.angular, noise_urad * 1e-6, noise_um * 1e-3)[:, None]
    return np.full(_readings(d).shape, noise_um * 1e-3)


def _effect_term(effect: str, axis: str, rng):
    """(terms, parameter values name -> internal value at a small unit size, description) of one
    effect; the readings are later scaled to the drawn magnitude (every effect is linear in its own
    parameters, so the scaling is exact)."""
    if effect in ("backlash", "rotary_backlash"):
        return [Backlash(axis)], {f"BL_{axis}": 1e-5 if effect == "rotary_backlash" else 1e-3}, {}
    if effect == "periodic_error":
        period = float(rng.choice(PERIODS))
        ph = rng.uniform(0, 2 * math.pi)
        return [PeriodicError(axis, period)], {f"PER_{axis}_c": 1e-3 * math.cos(ph),
                                               f"PER_{axis}_s": 1e-3 * math.sin(ph)}, {"period_mm": period}
    if effect == "feed_dependent_offset":
        return [FeedOffset(axis)], {f"FOFF_{axis}": 1e-3}, {}
    if effect == "feed_dependent_abbe":
        # an angular error of the axis that tilts its positioning reading (rotation about one of the
        # other two directions) turns about a centre that moves with feed (seed 000), or grows with feed
        own = "XYZ".index(axis)
        a = str(rng.choice([c for i, c in enumerate("ABC") if i != own]))
        c = [x for i, x in enumerate("XYZ") if i not in (own, "ABC".index(a))][0]
        if rng.random() < 0.5:
            name = f"IRC_{a}{axis}_{c.lower()}_f"
            return [AbbeIRC(axis, angles="ABC", feed=True)], {name: 10.0}, {"what": name}
        name = f"AG_{a}{axis}"
        return [AbbeIRC(axis, angles="ABC", feed=False, angle_gain=True)], {name: 0.01}, {"what": name}
    if effect == "thermal_drift":
        # a steady drift, or a warm-up that settles with a time constant of 0.5 to 2 h
        feature = "time_h" if rng.random() < 0.5 else f"time_exp_{int(rng.choice([1800, 3600, 7200]))}"
        return [ThermalDrift("time", (feature,), "XYZ")], {f"TD_{axis}_{feature}": 1e-3}, \
            {"driver": "time", "feature": feature}
    if effect == "rotary_pdge":
        comp = str(rng.choice(["EXC", "EYC", "EZC", "EAC", "EBC"]))
        order = 2
        unit = 1e-5 if comp[1] in "ABC" else 1e-3
        vals = {f"{comp}_{cs}{k}": unit * rng.normal() for k in motion_harmonics(comp, order) for cs in "cs"}
        return [RotaryErrorMotion(comp, order=order)], vals, {"component": comp}
    raise ValueError(effect)


def _effect_axes(machine: Machine, effect: str) -> list[str]:
    if effect == "rotary_backlash":
        return [a.name for a in machine.rotary_axes]
    if effect == "rotary_pdge":
        return ["C"] if "C" in machine.axis_names else []
    if effect == "thermal_drift":
        return ["X", "Y", "Z"]
    return [a.name for a in machine.linear_axes]


def hidden_case(seed: int, effects=None, machine: str | Machine | None = None, size: str = "small",
                magnitude=None, defect: bool = False, noise_um: float = 0.3,
                noise_urad: float = 0.5) -> HiddenCase:
    """Simulate a campaign hiding ``effects`` (names from :data:`EFFECTS`; None: one drawn at random,
    [] : none) on ``machine`` (None: xfyz or cafxyz at random; cafxyz when a rotary effect is asked).

    magnitude : times the noise (None: uniform in [4, 20] per effect). defect : add a local bump
    (4-20 times the noise high, 3-8 % of the travel wide) on the positioning of one linear axis.
    """
    import mtcomp.sim as sim
    rng = np.random.default_rng(seed)
    if effects is None:
        effects = [str(rng.choice(EFFECTS))]
    effects = list(effects)
    if machine is None:
        machine = "cafxyz" if any(e in ROTARY_EFFECTS for e in effects) or rng.random() < 0.3 else "xfyz"
    m = machine if isinstance(machine, Machine) else load_machine(machine)
    base_model = _model(m)
    truth0 = sim.random_truth(m, rng)
    base_truth = FittedModel(base_model, ParameterSet(base_model.param_specs, truth0.params.values))
    plans = campaign_plans(m, size)
    t = 0.0
    shifted = []
    for p in plans:
        p2 = p.shifted(t)
        shifted.append(p2)
        t = max(t, p2.duration_s) + 600.0
    shifted = _join_repeat(shifted)
    with tempfile.TemporaryDirectory(prefix="mtcomp-hidden-") as tmp:
        vm0 = sim.VirtualMachine(m, base_truth, 0.0, 0.0, rng=0)
        data0 = [vm0.measure(p, f"{tmp}/{p.name}.csv", noise=False) for p in shifted]
        readings = [_readings(d) for d in data0]
        sig = [_sigma(d, noise_um, noise_urad) for d in data0]
        hidden, all_terms, values = [], [], {}
        for eff in effects:
            axes = _effect_axes(m, eff)
            axis = str(rng.choice(axes))
            terms, unit_vals, desc = _effect_term(eff, axis, rng)
            model1 = _model(m, terms)
            p1 = ParameterSet(model1.param_specs).reindexed(model1.param_specs)
            p1.values[:] = 0.0
            for i, s in enumerate(model1.param_specs):
                if s.base:
                    p1.values[i] = base_truth.params[s.name]
            for nm, v in unit_vals.items():
                p1[nm] = v
            vm1 = sim.VirtualMachine(m, FittedModel(model1, p1), 0.0, 0.0, rng=0)
            data1 = [vm1.measure(p, f"{tmp}/{p.name}.csv", noise=False) for p in shifted]
            deltas = [np.nan_to_num(_readings(d1) - r0) for d1, r0 in zip(data1, readings)]
            peak = max(float(np.max(np.abs(dl) / s)) for dl, s in zip(deltas, sig))
            mag = float(rng.uniform(4.0, 20.0) if magnitude is None else magnitude)
            scale = mag / peak
            for k in range(len(readings)):
                readings[k] = readings[k] + scale * deltas[k]
            vals = {nm: v * scale for nm, v in unit_vals.items()}
            values.update(vals)
            all_terms.extend(t for t in terms if t.key() not in {x.key() for x in all_terms})
            hidden.append({"effect": eff, "axis": axis, "magnitude": mag, "params": vals, **desc})
        bump = None
        if defect:
            lin = [a.name for a in m.linear_axes]
            axis = str(rng.choice(lin))
            lo, hi = m.axis(axis).travel
            centre = float(rng.uniform(lo + 0.3 * (hi - lo), hi - 0.3 * (hi - lo)))
            width = float(rng.uniform(0.03, 0.08) * (hi - lo))
            height = float(rng.uniform(4.0, 20.0) * noise_um * rng.choice([-1, 1]))
            bump = {"axis": axis, "centre_mm": centre, "width_mm": width, "height_um": height}
            for k, d in enumerate(data0):
                readings[k] = readings[k] + _bump(m, d, bump)
        noisy = [r + rng.normal(size=r.shape) * s for r, s in zip(readings, sig)]
        datasets = [_put(d, np.where(np.isfinite(_readings(d)), r, np.nan)) for d, r in zip(data0, noisy)]
    model_t = _model(m, all_terms)
    pt = ParameterSet(model_t.param_specs)
    for i, s in enumerate(model_t.param_specs):
        pt.values[i] = base_truth.params[s.name] if s.base else values.get(s.name, 0.0)
    return HiddenCase(m, datasets, hidden, FittedModel(model_t, pt), noise_um, noise_urad, seed, bump)


def _bump(m: Machine, d, bump) -> np.ndarray:
    """(n, k) change of the readings of set ``d`` by a positioning bump of one axis (internal units)."""
    a = bump["axis"]
    out = np.zeros(_readings(d).shape)

    def shape(s):
        return bump["height_um"] * 1e-3 * np.exp(-0.5 * ((s - bump["centre_mm"]) / bump["width_mm"]) ** 2)

    if d.kind == "laser":
        sel = (d.axis == a) & (d.component == f"E{a}{a}")
        out[sel, 0] = shape(d.target[sel])
    elif d.kind == "points":
        k = "XYZ".index(a)
        out[:, k] = shape(d.xyz[:, k])
    return out


def score(case: HiddenCase, diagnosis) -> dict:
    """How a diagnosis did on a hidden case: named (every hidden effect named on its axis), extra
    (named effects that were not hidden), final held-out rms over the noise, verdict."""
    named = [(f.effect, f.axis, f.params) for f in diagnosis.findings if f.effect != "unexplained"]
    hits = []
    for h in case.effects:
        ok = any(e == h["effect"] and ax == h["axis"] for e, ax, _ in named)
        hits.append(ok)
    wanted = {(h["effect"], h["axis"]) for h in case.effects}
    extra = [(e, ax) for e, ax, _ in named if (e, ax) not in wanted]
    held = diagnosis.final.get("heldout_rms_um")
    return {"named": all(hits), "hits": hits, "extra": extra,
            "ratio": (held / case.noise_um) if held else float("nan"), "verdict": diagnosis.verdict,
            "found": [(e, ax) for e, ax, _ in named]}

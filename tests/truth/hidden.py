"""Campaigns on the independent machine that hide one known effect, for diagnose's tests and benchmark.

Nothing here imports mtcomp. :func:`hidden_case` draws a random machine of a topology, hides one
effect (or none: a clean case) and writes a campaign of one kind:

* ``rich``: volumetric points (two tool lengths, both directions, three feeds, two passes), laser
  runs of every linear axis (six components, an optic offset, two feeds, both directions; and a fine
  positioning run at 200 irregular targets over 240 mm) and of the rotary axes, ball-bar circles, and the three-sphere set-up on machines with C;
* ``laser``: ISO 230-2 runs of the effect's axis alone at three feeds, positioning at two Abbe
  offsets and the two angular errors that have an arm (the seed 000 set-up, any axis), and a fine
  positioning run at 200 irregular targets over 240 mm;
* ``rotary_laser``: positioning runs of the rotary axes at two feeds, both directions;
* ``ballbar``: ball-bar circles in three planes (and the three-sphere set-up with C), two feeds;
* ``mixture``: the laser runs of the effect's axis plus ball-bar circles.

A thermal case adds a 4 h ``thermal`` file. :func:`seed000_case` builds the paper's set-up.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from . import campaigns as tc
from .effects import FeedAbbe, random_effect
from .machine import TruthMachine

NOISE_UM = 0.3
NOISE_URAD = 0.5
NOISE_MM = NOISE_UM * 1e-3
KINDS = ("rich", "laser", "rotary_laser", "ballbar", "mixture")
#: seed 000: feeds (mm/min), Abbe offset of the positioning line (mm), X targets (mm)
SEED000_FEEDS = (180.0, 240.0, 300.0)
SEED000_OFFSET_MM = 210.0
SEED000_TARGETS = np.arange(-100.0, 100.0 + 1e-9, 5.0)


@dataclass
class HiddenCase:
    """machine : the truth. paths : files written. effect : SPEC 6 name of the hidden effect ('' for
    a clean case); axis : its axis ('' when campaign-wide); kind : campaign kind; topology.
    hidden : the effect object (or None). defect : True for a local defect (must be 'unexplained')."""

    machine: TruthMachine
    paths: list
    effect: str
    axis: str
    kind: str
    topology: str
    hidden: object = None
    info: dict = field(default_factory=dict)


def compatible_kinds(effect: str, topology: str) -> tuple:
    """Campaign kinds in which ``effect`` can be seen on a ``topology`` machine."""
    rotary = topology != "xfyz"
    if effect in ("rotary_backlash", "rotary_pdge"):
        return ("rich", "rotary_laser") if effect == "rotary_backlash" else ("rich",)
    if effect in ("feed_dependent_offset", "feed_dependent_abbe"):
        return ("rich", "laser", "mixture")
    if effect in ("backlash", "periodic_error", "local_defect"):
        return ("rich", "laser", "mixture")
    if effect == "thermal_drift":
        return ("rich", "laser")
    return KINDS if rotary else tuple(k for k in KINDS if k != "rotary_laser")


def _fine_run(m, folder, rng, axis, feed, t):
    """A fine bidirectional positioning run of ``axis``: 200 targets drawn at random over 240 mm in the
    middle of the travel (irregular, so that no period aliases; about 1.2 mm apart, so that a 5 mm
    screw period is seen), two runs. Returns (path, time after it)."""
    mid = 0.5 * sum(m.travel[axis])
    r = tc.laser(m, folder / f"laser_{axis.lower()}_fine.csv", rng, axis, components=(f"E{axis}{axis}",),
                 targets=np.sort(rng.uniform(mid - 120.0, mid + 120.0, 200)), n_runs=2, feed_mm_min=feed,
                 noise_um=NOISE_UM, t0_s=t)
    return r.path, float(np.max(r.columns["t_s"])) + 60.0


def _laser_runs(m, folder, rng, axis, feeds, t0=0.0):
    """Seed 000 style runs of a linear ``axis``: positioning at 0 and at an Abbe offset across the
    axis, yaw and pitch, at each feed, three runs both ways."""
    lo, hi = m.travel[axis]
    targets = np.linspace(lo + 0.05 * (hi - lo), hi - 0.05 * (hi - lo), 21)
    across = "Y" if axis != "Y" else "X"
    offset = np.zeros(3)
    offset["XYZ".index(across)] = 150.0
    pos = f"E{axis}{axis}"
    angles = tuple(f"E{b}{axis}" for b in "ABC" if b != "ABC"["XYZ".index(axis)])
    paths, t = [], t0
    p, t = _fine_run(m, folder, rng, axis, feeds[0], t)
    paths.append(p)
    for name, comps, optic in ((f"laser_{axis.lower()}_0", (pos,), (0.0, 0.0, 0.0)),
                               (f"laser_{axis.lower()}_abbe", (pos,), tuple(offset)),
                               (f"laser_{axis.lower()}_angles", angles, (0.0, 0.0, 0.0))):
        r = tc.laser(m, folder / f"{name}.csv", rng, axis, components=comps, targets=targets, n_runs=2,
                     optic_mm=optic, feed_mm_min=feeds, noise_um=NOISE_UM, noise_urad=NOISE_URAD, t0_s=t)
        paths.append(r.path)
        t = float(np.max(r.columns["t_s"])) + 60.0
    return paths, t


def hidden_case(seed: int, effect: str, kind: str, topology: str, folder, hidden=None) -> HiddenCase:
    """One case: machine drawn from ``seed``, ``effect`` ('' for none) hidden, a ``kind`` campaign
    written into ``folder``. ``hidden``: the effect object to hide instead of a random one of kind
    ``effect``."""
    rng = np.random.default_rng(seed)
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    probe = TruthMachine(topology)
    axis = ""
    if hidden is not None:
        axis = getattr(hidden, "axis", "")
    elif effect:
        axis_pick = None
        if kind in ("laser", "mixture") and effect in ("backlash", "periodic_error", "local_defect",
                                                       "feed_dependent_offset"):
            axis_pick = str(rng.choice([a for a in probe.axis_names if a in "XYZ"]))
        hidden = random_effect(effect, probe, rng, axis=axis_pick)
        if effect == "thermal_drift":
            hidden = random_effect(effect, probe, rng, driver="time")
        if effect == "local_defect":
            # where the campaign's fine run passes (mid-travel +-120 mm, see _fine_run): a defect
            # between the coarse targets of the other runs is in no reading, and nothing can report it
            mid, half = 0.5 * sum(probe.travel[hidden.axis]), 120.0 - 0.5 * hidden.width_mm
            hidden = replace(hidden, centre_mm=float(rng.uniform(mid - half, mid + half)))
        axis = getattr(hidden, "axis", "")
    m = TruthMachine.random(topology, rng, effects=[hidden] if hidden else [], error_motions=False)
    paths: list[Path] = []
    t = 0.0
    linear = [a for a in m.axis_names if a in "XYZ"]
    rot = [a for a in m.axis_names if a in "ABC"]
    feeds2 = (1000.0, 3000.0)
    if kind == "rich":
        r = tc.points(m, folder / "points.csv", rng, grid=(4, 4, 3), repeats=2, noise_um=NOISE_UM)
        paths.append(r.path)
        t = float(np.max(r.columns["t_s"])) + 60.0
        for a in linear:
            static = {b: rng.uniform(*m.travel[b]) * 0.5 for b in "XYZ" if b != a}
            r = tc.laser(m, folder / f"laser_{a.lower()}.csv", rng, a, n_runs=2, static=static,
                         optic_mm=tuple(rng.uniform(-150, 150, 3)), feed_mm_min=feeds2, noise_um=NOISE_UM,
                         noise_urad=NOISE_URAD, t0_s=t)
            paths.append(r.path)
            t = float(np.max(r.columns["t_s"])) + 60.0
            p, t = _fine_run(m, folder, rng, a, feeds2[0], t)
            paths.append(p)
        for a in rot:
            r = tc.laser(m, folder / f"laser_{a.lower()}.csv", rng, a, n_runs=2, feed_mm_min=feeds2,
                         noise_urad=NOISE_URAD, t0_s=t)
            paths.append(r.path)
            t = float(np.max(r.columns["t_s"])) + 60.0
        paths.append(tc.ballbar_circles(m, folder / "ballbar.csv", rng, noise_mm=NOISE_MM, t0_s=t).path)
        if "C" in rot:
            paths.append(tc.three_sphere(m, folder / "three_sphere.csv", rng, noise_mm=NOISE_MM).path)
    elif kind in ("laser", "mixture"):
        a = axis if axis in linear else str(rng.choice(linear))
        p, t = _laser_runs(m, folder, rng, a, (1000.0, 2000.0, 3000.0))
        paths += p
        if kind == "mixture":
            paths.append(tc.ballbar_circles(m, folder / "ballbar.csv", rng, noise_mm=NOISE_MM, t0_s=t).path)
    elif kind == "rotary_laser":
        for a in rot:
            r = tc.laser(m, folder / f"laser_{a.lower()}.csv", rng, a, n_runs=3, feed_mm_min=feeds2,
                         noise_urad=NOISE_URAD, t0_s=t)
            paths.append(r.path)
            t = float(np.max(r.columns["t_s"])) + 60.0
    elif kind == "ballbar":
        for i, f in enumerate(feeds2):
            paths.append(tc.ballbar_circles(m, folder / f"ballbar_{i}.csv", rng, feed_mm_min=f,
                                            noise_mm=NOISE_MM, t0_s=t).path)
        if "C" in rot:
            paths.append(tc.three_sphere(m, folder / "three_sphere.csv", rng, noise_mm=NOISE_MM).path)
    else:
        raise ValueError(f"unknown campaign kind {kind!r}; one of {KINDS}")
    if effect == "thermal_drift":
        paths.append(tc.thermal(m, folder / "thermal.csv", rng, duration_h=4.0, noise_um=NOISE_UM / 3).path)
    return HiddenCase(m, paths, effect, axis, kind, topology, hidden,
                      {"defect": effect == "local_defect", "seed": seed})


def seed000_case(seed: int, folder, irc_shift_mm_per_m_min: float = -800.0,
                 velocity_noise_mm_min: float | None = None, effects: tuple = ()) -> HiddenCase:
    """Seed 000's experiment on a random XFYZ machine: laser runs of the table axis X over 200 mm in
    5 mm steps, three runs both ways at 180, 240 and 300 mm/min: positioning at 0 and at 210 mm Abbe
    offset (along Y), yaw (ECX) and pitch (EBX). The table yaws about a centre that moves along Y by
    ``irc_shift_mm_per_m_min`` per m/min of feed (the default, -800, moves it 144-240 mm over the
    paper's feeds: a traditional model's error at the 210 mm line is then of the order the paper
    reports, about 1 um). ``velocity_noise_mm_min``: also the paper's two-point velocities over the
    same 200 mm at the same feeds (SPEC 3.6), with that noise (mm/min). ``effects``: further effects
    of the machine besides the feed-dependent Abbe error."""
    rng = np.random.default_rng(seed)
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    eff = FeedAbbe("X", angles="C", irc_shift_mm_per_m_min=(0.0, irc_shift_mm_per_m_min, 0.0))
    m = TruthMachine.random("xfyz", rng, effects=[eff, *effects], error_motions=False)
    paths = []
    t = 0.0
    for name, comps, optic in (("pos_0", ("EXX",), (0.0, 0.0, 0.0)),
                               ("pos_210", ("EXX",), (0.0, SEED000_OFFSET_MM, 0.0)),
                               ("yaw_pitch", ("ECX", "EBX"), (0.0, 0.0, 0.0))):
        r = tc.laser(m, folder / f"{name}.csv", rng, "X", components=comps, targets=SEED000_TARGETS, n_runs=3,
                     optic_mm=optic, feed_mm_min=SEED000_FEEDS, noise_um=0.2, noise_urad=0.3, t0_s=t)
        paths.append(r.path)
        t = float(np.max(r.columns["t_s"])) + 60.0
    if velocity_noise_mm_min is not None:
        paths.append(tc.velocity(m, folder / "velocity.csv", rng, start_mm=SEED000_TARGETS[0],
                                 length_mm=float(np.ptp(SEED000_TARGETS)), feeds_mm_min=SEED000_FEEDS,
                                 noise_mm_min=velocity_noise_mm_min, t0_s=t).path)
    return HiddenCase(m, paths, "feed_dependent_abbe", "X", "seed000", "xfyz", eff)

"""Hidden effects of the truth machine (test-only; independent of mtcomp). Each is off unless passed.

An effect may act in three places, each a method (default: nothing):

* ``component_delta(machine, axis, s, ctx, base)``: additions to the component errors of ``axis``
  (dict component name -> (N,) in mm or rad); ``base`` holds the values so far (so a gain can scale them).
* ``pivot_shift(machine, axis, s, ctx)``: (N, 3) mm shift, in the carriage frame, of the point about
  which the angular errors of linear ``axis`` act.
* ``spindle_offset(machine, q, ctx)``: (N, 3) mm translation of the spindle (the tool frame) relative
  to the last tool-side carriage, along the machine axes X, Y, Z (a thermal growth of the head).

Units of the parameters are in their names (um, urad, mm, s, degC, rpm; feeds per m/min = 1000 mm/min).
Component errors of a table (workpiece-side) linear axis are the error motion of the tool relative to
the table (see :mod:`truth.machine`), so e.g. a ``Backlash`` on X reads the same on a laser whichever
side X is on.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

UM = 1e-3      # mm per um
URAD = 1e-6    # rad per urad

#: for a rotary axis: (axial, radial pair, tilt pair) component names
ROTARY_COMPONENTS = {
    "A": ("EXA", ("EYA", "EZA"), ("EBA", "ECA")),
    "B": ("EYB", ("EZB", "EXB"), ("ECB", "EAB")),
    "C": ("EZC", ("EXC", "EYC"), ("EAC", "EBC")),
}


class Effect:
    """Base class: contributes nothing unless a hook is overridden."""

    name = "effect"

    def component_delta(self, machine, axis, s, ctx, base) -> dict:
        return {}

    def pivot_shift(self, machine, axis, s, ctx):
        return None

    def spindle_offset(self, machine, q, ctx):
        return None


@dataclass(frozen=True)
class Backlash(Effect):
    """Lost motion of linear ``axis``: ``E<axis><axis> += dir_<axis> * magnitude_um / 2``, so the ISO 230-2
    reversal value B (mean up minus mean down) equals ``magnitude_um`` (give it negative for a lag)."""

    axis: str
    magnitude_um: float
    name = "backlash"

    def component_delta(self, machine, axis, s, ctx, base):
        if axis != self.axis:
            return {}
        return {f"E{axis}{axis}": 0.5 * self.magnitude_um * UM * ctx.dir(axis)}


@dataclass(frozen=True)
class RotaryBacklash(Effect):
    """Lost motion of rotary ``axis`` (seed 002): ``E<axis><axis> += dir_<axis> * magnitude_urad / 2``."""

    axis: str
    magnitude_urad: float
    name = "rotary_backlash"

    def component_delta(self, machine, axis, s, ctx, base):
        if axis != self.axis:
            return {}
        return {f"E{axis}{axis}": 0.5 * self.magnitude_urad * URAD * ctx.dir(axis)}


@dataclass(frozen=True)
class PeriodicError(Effect):
    """Cyclic positioning error: ``E<axis><axis> += amplitude_um sin(2 pi s / period_mm + phase_rad)``."""

    axis: str
    period_mm: float
    amplitude_um: float
    phase_rad: float = 0.0
    name = "periodic_error"

    def component_delta(self, machine, axis, s, ctx, base):
        if axis != self.axis:
            return {}
        return {f"E{axis}{axis}": self.amplitude_um * UM * np.sin(2 * np.pi * s / self.period_mm
                                                                    + self.phase_rad)}


@dataclass(frozen=True)
class FeedOffset(Effect):
    """Positioning offset proportional to feed, uniform along the axis (a dynamic lag of the reading):
    ``E<axis><axis> += um_per_m_min * feed_mm_min / 1000`` (times ``dir_<axis>`` when ``signed``)."""

    axis: str
    um_per_m_min: float
    signed: bool = False
    name = "feed_dependent_offset"

    def component_delta(self, machine, axis, s, ctx, base):
        if axis != self.axis:
            return {}
        v = self.um_per_m_min * UM * ctx.feed / 1000.0
        if self.signed:
            v = v * ctx.dir(axis)
        return {f"E{axis}{axis}": v}


@dataclass(frozen=True)
class FeedAbbe(Effect):
    """Seed 000: the Abbe error of linear ``axis`` changes with feed.

    * ``angle_gain_per_m_min``: the angular errors named in ``angles`` (letters of the rotation, e.g.
      ``"C"`` for ECX of X) scale with feed: ``E<a><axis> *= 1 + gain * feed_mm_min / 1000``;
    * ``irc_shift_mm_per_m_min``: (3,) the point about which the angular errors of ``axis`` act moves,
      in the carriage frame, by ``shift * feed_mm_min / 1000`` mm (the instantaneous rotation centre).
    """

    axis: str
    angles: str = "C"
    angle_gain_per_m_min: float = 0.0
    irc_shift_mm_per_m_min: tuple = (0.0, 0.0, 0.0)
    name = "feed_dependent_abbe"

    def component_delta(self, machine, axis, s, ctx, base):
        if axis != self.axis or not self.angle_gain_per_m_min:
            return {}
        g = self.angle_gain_per_m_min * ctx.feed / 1000.0
        return {f"E{a}{axis}": base[f"E{a}{axis}"] * g for a in self.angles}

    def pivot_shift(self, machine, axis, s, ctx):
        if axis != self.axis:
            return None
        return np.asarray(self.irc_shift_mm_per_m_min, float)[None, :] * (ctx.feed / 1000.0)[:, None]


@dataclass(frozen=True)
class SpindleSchedule:
    """Spindle speed as blocks: ``blocks = ((t_start_s, rpm), ...)`` sorted by time; 0 rpm before the
    first block. ``lag(t, tau_s, rpm_ref)`` is the first-order response h (dh/dt = (rpm/rpm_ref - h)/tau,
    h = 0 before the first block), exact for piecewise-constant speed."""

    blocks: tuple

    def rpm(self, t):
        t = np.atleast_1d(np.asarray(t, dtype=float))
        out = np.zeros(t.shape)
        for t0, r in self.blocks:
            out = np.where(t >= t0, float(r), out)
        return out

    def lag(self, t, tau_s, rpm_ref):
        t = np.atleast_1d(np.asarray(t, dtype=float))
        h = np.zeros(t.shape)
        starts = [float(b[0]) for b in self.blocks] + [np.inf]
        for k, (t0, r) in enumerate(self.blocks):
            t1 = starts[k + 1]
            u = float(r) / rpm_ref
            dt = np.clip(np.minimum(t, t1) - t0, 0.0, None)
            h = u + (h - u) * np.exp(-dt / tau_s)
        return h


@dataclass(frozen=True)
class ThermalDrift(Effect):
    """Thermal drift of the tool relative to the workpiece: the spindle moves by
    ``vector_um * driver`` (along the machine axes, through ``spindle_offset``), with ``driver``:

    * ``"time"``: settling exponential ``1 - exp(-t_s / tau_s)`` (vector_um is the final drift);
    * ``"linear"``: ``t_s / 3600`` (vector_um is the drift per hour);
    * ``"temperature"``: ``temp_<channel>_c - t_ref_c`` from the context (vector_um per degC);
    * ``"spindle"``: first-order lag of ``rpm / rpm_ref`` with time constant ``tau_s`` over
      ``schedule`` (a :class:`SpindleSchedule`; vector_um is the drift at steady ``rpm_ref``).
    """

    driver: str
    vector_um: tuple
    tau_s: float = 1800.0
    channel: str = "spindle"
    t_ref_c: float = 20.0
    rpm_ref: float = 6000.0
    schedule: SpindleSchedule | None = None
    name = "thermal_drift"

    def driver_value(self, ctx):
        t = ctx.t_s
        if self.driver == "time":
            return 1.0 - np.exp(-t / self.tau_s)
        if self.driver == "linear":
            return t / 3600.0
        if self.driver == "temperature":
            if self.channel not in ctx.temperatures:
                raise KeyError(f"ThermalDrift needs the temperature channel {self.channel!r} in the "
                               f"context (have {sorted(ctx.temperatures)})")
            return ctx.temperatures[self.channel] - self.t_ref_c
        if self.driver == "spindle":
            if self.schedule is None:
                raise ValueError("ThermalDrift(driver='spindle') needs a schedule")
            return self.schedule.lag(t, self.tau_s, self.rpm_ref)
        raise ValueError(f"unknown thermal driver {self.driver!r}")

    def spindle_offset(self, machine, q, ctx):
        return np.asarray(self.vector_um, float)[None, :] * UM * self.driver_value(ctx)[:, None]


@dataclass(frozen=True)
class RotaryRunout(Effect):
    """Once-per-revolution error motions of rotary ``axis`` beyond its location errors (seed 003):
    eccentricity (radial pair ``e cos(theta + phase), e sin(theta + phase)``, for C: EXC, EYC),
    wobble (tilt pair, for C: EAC, EBC, same form) and axial run-out (for C: EZC ``a cos(theta + phase)``),
    and a once-per-revolution motion along the first radial direction alone (``along_um``: for C,
    EXC += a cos(theta + phase), EYC unchanged; a table that shakes along X once a turn).
    Magnitudes in um and urad; theta in rad."""

    axis: str
    eccentricity_um: float = 0.0
    wobble_urad: float = 0.0
    axial_um: float = 0.0
    phase_rad: float = 0.0
    along_um: float = 0.0
    name = "rotary_pdge"

    def component_delta(self, machine, axis, s, ctx, base):
        if axis != self.axis:
            return {}
        axial, (r1, r2), (t1, t2) = ROTARY_COMPONENTS[axis]
        c, sn = np.cos(s + self.phase_rad), np.sin(s + self.phase_rad)
        return {r1: (self.eccentricity_um + self.along_um) * UM * c, r2: self.eccentricity_um * UM * sn,
                t1: self.wobble_urad * URAD * c, t2: self.wobble_urad * URAD * sn,
                axial: self.axial_um * UM * c}


@dataclass(frozen=True)
class LocalDefect(Effect):
    """A bump on one component of linear ``axis``: ``amplitude_um (1 + cos(2 pi (s - centre)/width)) / 2``
    for ``|s - centre| < width / 2`` (a raised cosine of full width ``width_mm``), zero elsewhere.
    ``component`` defaults to the positioning error E<axis><axis>."""

    axis: str
    centre_mm: float
    width_mm: float
    amplitude_um: float
    component: str | None = None
    name = "local_defect"

    def component_delta(self, machine, axis, s, ctx, base):
        if axis != self.axis:
            return {}
        u = (s - self.centre_mm) / self.width_mm
        bump = np.where(np.abs(u) < 0.5, 0.5 * (1.0 + np.cos(2 * np.pi * u)), 0.0)
        comp = self.component or f"E{axis}{axis}"
        scale = URAD if comp[1] in "ABC" else UM
        return {comp: self.amplitude_um * scale * bump}


@dataclass(frozen=True)
class ThermalEnvironment:
    """Temperatures of a thermal campaign: ``ambient`` = ambient_c + slow wander (two sines),
    ``spindle`` = ambient + spindle_gain_c * (first-order lag of rpm / rpm_ref, time constant
    spindle_tau_s), ``bed`` = the steady-state response of a first-order lag (bed_tau_s) to the ambient
    wander, around ambient_c."""

    schedule: SpindleSchedule
    ambient_c: float = 20.0
    wander_c: tuple = (0.6, 0.25)
    wander_period_s: tuple = (86400.0, 9000.0)
    wander_phase: tuple = (0.0, 1.0)
    spindle_gain_c: float = 8.0
    spindle_tau_s: float = 1500.0
    rpm_ref: float = 6000.0
    bed_tau_s: float = 5400.0

    def ambient(self, t):
        t = np.atleast_1d(np.asarray(t, float))
        return self.ambient_c + sum(a * np.sin(2 * np.pi * t / p + ph) for a, p, ph in
                                    zip(self.wander_c, self.wander_period_s, self.wander_phase))

    def temperatures(self, t) -> dict:
        t = np.atleast_1d(np.asarray(t, float))
        amb = self.ambient(t)
        spindle = amb + self.spindle_gain_c * self.schedule.lag(t, self.spindle_tau_s, self.rpm_ref)
        # the bed follows each wander sine through a first-order lag (steady-state response)
        bed = np.full(t.shape, self.ambient_c)
        for a, p, ph in zip(self.wander_c, self.wander_period_s, self.wander_phase):
            w = 2 * np.pi / p
            g = 1.0 / np.sqrt(1.0 + (w * self.bed_tau_s) ** 2)
            bed = bed + a * g * np.sin(w * t + ph - np.arctan(w * self.bed_tau_s))
        return {"ambient": amb, "spindle": spindle, "bed": bed}


EFFECT_KINDS = ("backlash", "rotary_backlash", "periodic_error", "feed_dependent_offset",
                "feed_dependent_abbe", "thermal_drift", "rotary_pdge", "local_defect")


def random_effect(kind: str, machine, rng, axis: str | None = None, **overrides) -> Effect:
    """One hidden effect of ``kind`` (one of :data:`EFFECT_KINDS`, the SPEC 6 effect names) with
    realistic random parameters drawn from ``rng``, on ``axis`` (default: a random suitable axis of
    ``machine``; feed_dependent_abbe prefers a table axis). ``overrides`` replace drawn fields
    (e.g. ``driver="temperature"`` for thermal_drift)."""
    linear = [a for a in machine.axis_names if a in "XYZ"]
    rotary = [a for a in machine.axis_names if a in "ABC"]
    sign = lambda: float(rng.choice([-1.0, 1.0]))  # noqa: E731
    pick = lambda pool: axis or str(rng.choice(pool))  # noqa: E731
    if kind == "backlash":
        kw = dict(axis=pick(linear), magnitude_um=sign() * rng.uniform(3, 12))
        cls = Backlash
    elif kind == "rotary_backlash":
        if not rotary:
            raise ValueError(f"{machine.topology} has no rotary axis")
        kw = dict(axis=pick(rotary), magnitude_urad=sign() * rng.uniform(10, 40))
        cls = RotaryBacklash
    elif kind == "periodic_error":
        kw = dict(axis=pick(linear), period_mm=float(rng.choice([5.0, 10.0, 16.0, 20.0, 25.0, 32.0])),
                  amplitude_um=rng.uniform(1, 4), phase_rad=rng.uniform(0, 2 * np.pi))
        cls = PeriodicError
    elif kind == "feed_dependent_offset":
        kw = dict(axis=pick(linear), um_per_m_min=sign() * rng.uniform(0.5, 2.0))
        cls = FeedOffset
    elif kind == "feed_dependent_abbe":
        table = [a for a in linear if machine.side(a) == "workpiece"]
        a = pick(table or linear)
        shift = np.zeros(3)
        shift[int(rng.integers(0, 2))] = sign() * rng.uniform(20, 100)
        kw = dict(axis=a, angles=str(rng.choice(["B", "C"])) if a == "X" else "C",
                  angle_gain_per_m_min=rng.uniform(0.05, 0.3), irc_shift_mm_per_m_min=tuple(shift))
        cls = FeedAbbe
    elif kind == "thermal_drift":
        driver = overrides.pop("driver", None) or str(rng.choice(["time", "temperature", "spindle",
                                                                  "linear"]))
        vec = (sign() * rng.uniform(1, 5), sign() * rng.uniform(1, 5), -rng.uniform(5, 20))
        if driver == "temperature":
            vec = tuple(v / 5.0 for v in vec)                   # um per degC
        elif driver == "linear":
            vec = tuple(v / 4.0 for v in vec)                   # um per hour
        kw = dict(driver=driver, vector_um=vec, tau_s=rng.uniform(1200, 3600), channel="spindle",
                  schedule=SpindleSchedule(((0.0, 0.0), (1800.0, 2000.0), (5400.0, 6000.0), (12600.0, 0.0),
                                            (16200.0, 4000.0), (21600.0, 0.0))))
        cls = ThermalDrift
    elif kind == "rotary_pdge":
        if not rotary:
            raise ValueError(f"{machine.topology} has no rotary axis")
        kw = dict(axis=pick(rotary), eccentricity_um=rng.uniform(3, 10), wobble_urad=rng.uniform(5, 20),
                  axial_um=rng.uniform(1, 4), phase_rad=rng.uniform(0, 2 * np.pi))
        cls = RotaryRunout
    elif kind == "local_defect":
        a = pick(linear)
        lo, hi = machine.travel[a]
        kw = dict(axis=a, centre_mm=rng.uniform(lo + 0.2 * (hi - lo), hi - 0.2 * (hi - lo)),
                  width_mm=rng.uniform(10, 40), amplitude_um=sign() * rng.uniform(2, 6))
        cls = LocalDefect
    else:
        raise ValueError(f"unknown effect kind {kind!r}; one of {EFFECT_KINDS}")
    kw.update(overrides)
    return cls(**kw)

"""Smooth error profiles of one axis position (test-only; independent of mtcomp).

A profile is a callable ``f(s) -> (N,)`` in internal units (mm for translational errors, rad for
angular ones) of the axis position ``s`` (mm for linear axes, rad for rotary axes). Linear-axis
profiles are held constant outside the travel they were built for (the position is clipped), so that a
pose slightly outside the travel does not extrapolate a spline.
"""
from __future__ import annotations

import csv
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.interpolate import CubicSpline

#: folder of the real ISO 230-2 runs (optional; the real-profile option is skipped when absent)
REAL_ISO230_2 = Path("/work/shared/data/real/iso230_2")


@dataclass(frozen=True)
class Constant:
    """f(s) = value."""

    value: float = 0.0

    def __call__(self, s):
        s = np.asarray(s, dtype=float)
        return np.full(s.shape, float(self.value))


ZERO = Constant(0.0)


@dataclass(frozen=True)
class Linear:
    """f(s) = value0 + slope * s (for hand-derived tests)."""

    value0: float = 0.0
    slope: float = 0.0

    def __call__(self, s):
        return self.value0 + self.slope * np.asarray(s, dtype=float)


@dataclass(frozen=True)
class Sum:
    """f(s) = sum of the parts."""

    parts: tuple

    def __call__(self, s):
        s = np.asarray(s, dtype=float)
        out = np.zeros(s.shape)
        for p in self.parts:
            out = out + p(s)
        return out


@dataclass(frozen=True)
class Scaled:
    """f(s) = scale * g(s)."""

    scale: float
    inner: object

    def __call__(self, s):
        return self.scale * self.inner(s)


@dataclass(frozen=True)
class Spline:
    """Cubic spline (scipy ``CubicSpline``, not-a-knot) through (knots, values); s clipped to the knots."""

    knots: np.ndarray
    values: np.ndarray
    _cs: object = field(default=None, compare=False, repr=False)

    def __post_init__(self):
        object.__setattr__(self, "_cs", CubicSpline(np.asarray(self.knots, float),
                                                    np.asarray(self.values, float)))

    def __call__(self, s):
        s = np.clip(np.asarray(s, dtype=float), self.knots[0], self.knots[-1])
        return self._cs(s)


@dataclass(frozen=True)
class Sines:
    """f(s) = sum_k amplitude_k sin(2 pi s / period_k + phase_k); s clipped to ``bounds``."""

    amplitudes: tuple
    periods: tuple
    phases: tuple
    bounds: tuple = (-np.inf, np.inf)

    def __call__(self, s):
        s = np.clip(np.asarray(s, dtype=float), *self.bounds)
        out = np.zeros(s.shape)
        for a, p, ph in zip(self.amplitudes, self.periods, self.phases):
            out = out + a * np.sin(2.0 * np.pi * s / p + ph)
        return out


@dataclass(frozen=True)
class Fourier:
    """Rotary profile: f(theta) = c0 + sum_k (a_k cos k theta + b_k sin k theta), k = 1..len(a)
    (theta in rad). Use ``orders`` to give other harmonic orders than 1..n."""

    c0: float
    a: tuple
    b: tuple
    orders: tuple | None = None

    def __call__(self, theta):
        theta = np.asarray(theta, dtype=float)
        out = np.full(theta.shape, float(self.c0))
        orders = self.orders if self.orders is not None else tuple(range(1, len(self.a) + 1))
        for k, ak, bk in zip(orders, self.a, self.b):
            out = out + ak * np.cos(k * theta) + bk * np.sin(k * theta)
        return out


def normalised(f, lo, hi, n=801):
    """f shifted and scaled to mean 0 and peak-to-peak 1 over [lo, hi]."""
    v = f(np.linspace(lo, hi, n))
    pp = float(v.max() - v.min())
    return Sum((Scaled(1.0 / pp, f), Constant(-float(v.mean()) / pp)))


def peak_to_peak(f, lo, hi, n=801) -> float:
    v = f(np.linspace(lo, hi, n))
    return float(v.max() - v.min())


def random_shape(rng, lo, hi, n_knots=None, n_sines=None):
    """A smooth non-polynomial shape over [lo, hi] (unit-free, peak-to-peak about 1, mean 0): a cubic
    spline through random values at random knots plus a few sines of random period and phase."""
    span = hi - lo
    n_knots = int(rng.integers(6, 11)) if n_knots is None else n_knots
    inner = np.sort(rng.uniform(lo, hi, n_knots - 2))
    knots = np.concatenate([[lo], inner, [hi]])
    # keep knots apart so that the spline stays smooth
    knots = np.unique(np.round(knots, 9))
    gaps = np.diff(knots)
    while len(knots) > 4 and gaps.min() < 0.04 * span:
        knots = np.delete(knots, 1 + int(np.argmin(gaps[1:])) if len(gaps) > 1 else 1)
        gaps = np.diff(knots)
    values = rng.normal(0.0, 1.0, len(knots))
    spline = Spline(knots, values)
    n_sines = int(rng.integers(1, 4)) if n_sines is None else n_sines
    amps = tuple(rng.uniform(0.05, 0.25, n_sines))
    periods = tuple(span * rng.uniform(0.08, 0.7, n_sines))
    phases = tuple(rng.uniform(0.0, 2 * np.pi, n_sines))
    sines = Sines(amps, periods, phases, (lo, hi))
    shape = Sum((spline, sines))
    grid = np.linspace(lo, hi, 801)
    v = shape(grid)
    return Sum((Scaled(1.0 / (v.max() - v.min()), shape), Constant(-float(v.mean()) / (v.max() - v.min()))))


def random_profile(rng, lo, hi, range_, constant=0.0):
    """Shape from :func:`random_shape` scaled to peak-to-peak ``range_`` plus ``constant``."""
    return Sum((Scaled(float(range_), random_shape(rng, lo, hi)), Constant(float(constant))))


def real_positioning_shape(axis: str, lo: float, hi: float, folder: Path = REAL_ISO230_2):
    """The mean (over runs and directions) per target of the real ISO 230-2 run ``ess_b02_<axis>.csv``,
    stretched over [lo, hi] and interpolated by a cubic spline; normalised to peak-to-peak 1, mean 0.
    None when the file is absent."""
    path = Path(folder) / f"ess_b02_{axis.lower()}.csv"
    if not path.is_file():
        return None
    sums: dict = {}
    with open(path, newline="") as fh:
        for row in csv.DictReader(fh):
            t = float(row["target_mm"])
            sums.setdefault(t, []).append(float(row["value_um"]))
    targets = np.array(sorted(sums))
    means = np.array([np.mean(sums[t]) for t in targets])
    knots = lo + (targets - targets[0]) / (targets[-1] - targets[0]) * (hi - lo)
    shape = Spline(knots, means)
    v = shape(np.linspace(lo, hi, 801))
    return Sum((Scaled(1.0 / (v.max() - v.min()), shape), Constant(-float(v.mean()) / (v.max() - v.min()))))


def random_fourier(rng, amplitude, constant=0.0, orders=(1, 2, 3, 4)):
    """Rotary profile with harmonics ``orders``, amplitudes decaying with order, the largest about
    ``amplitude``, plus ``constant``."""
    orders = tuple(int(k) for k in orders)
    mag = amplitude * rng.uniform(0.5, 1.0, len(orders)) / np.sqrt(np.arange(1, len(orders) + 1))
    ph = rng.uniform(0, 2 * np.pi, len(orders))
    return Fourier(float(constant), tuple(mag * np.cos(ph)), tuple(mag * np.sin(ph)), orders)

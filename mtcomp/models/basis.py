"""Smooth bases for the component errors of a linear axis: uniform B-splines (default) and polynomials.

A component error of a linear axis (EXX, EYX, ..., ECX) is a linear combination of basis functions
of the axis position ``s`` (mm):

    E(s) = sum_j c_j phi_j(s)

**B-splines** (``basis = "bspline"``): ``B_j`` are the uniform B-splines of degree k on ``n`` equal
intervals of ``[lo, hi]`` (``n + k`` functions; Eilers & Marx's P-spline basis). Each is written with
truncated powers of its clipped local coordinate, which is exact, smooth and branch-free, so CasADi
differentiates and compiles it like any other expression:

    N_k(u) = 1/k! sum_{i=0}^{k+1} (-1)^i C(k+1, i) (u - i)_+^k,   u clipped to [0, k+1]
    B_j(s) = N_k((s - lo) / h - j + k),   h = (hi - lo) / n

(the truncated powers are shared between neighbouring functions, see ``SplineBasis.raw``).

Outside ``[lo, hi]`` the position is clipped: the error stays at its value at the nearer end. A model
knows nothing there (see ``FittedModel.support``), and a constant continuation never runs away.

A B-spline space holds the constants (the functions sum to one), and a reference for each component
must be fixed, or the errors and the set-ups (laser zero, tracker origin) trade a constant against
each other. mtcomp follows ISO 230-1: a component error is reported about a reference. For every
component the **mean over [lo, hi] is zero**; for the straightnesses whose slope a squareness carries
(EXY, EXZ, EYZ when the machine has C0Y, B0Z, A0Z) also the **least-squares slope over [lo, hi] is
zero** (the squareness is the angle between the least-squares reference lines, as ISO 230-1
defines it). So ``phi_j = B_j - (a_j + b_j (s - mid))`` with ``a_j + b_j (s - mid)`` the continuous
least-squares line (or mean) of ``B_j`` over ``[lo, hi]``, computed exactly by Gauss-Legendre
quadrature. One basis function (two for the straightnesses) carries nothing new after that, and is
dropped: the first (and the last).

**Polynomials** (``basis = "polynomial"``, the earlier default): ``phi_k(s) = (s / 1 m)^k`` for
k = 1..degree, zero at the axis zero, less k = 1 for the straightnesses whose slope a squareness
carries.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property, lru_cache
from math import comb, factorial

import casadi as ca
import numpy as np

from ..machine import DEFAULT_SPLINE_INTERVALS, Machine

#: component errors whose linear part (slope) a squareness carries (ISO 230-1 reference lines)
SLOPE_CARRIED_BY_SQUARENESS = {"EXY": "C0Y", "EXZ": "B0Z", "EYZ": "A0Z"}
#: straightnesses whose slope, with the squareness named and a frame's turn, is a rigid rotation of the
#: machine against the workpiece frame (X the reference axis, then Y): their slopes are zero where the
#: data leave that rotation open (no file's frame known)
SLOPE_OF_RIGID_ROTATION = {"EYX": "C0Y", "EZX": "B0Z", "EZY": "A0Z"}


def _clip(x, lo, hi):
    """Works on numpy arrays and CasADi expressions alike. In CasADi the slope at lo and at hi is the
    one from inside the range (fmin/fmax would give half of it there, and a velocity read at the end
    of the data, where the knots end, would be predicted at half its slope)."""
    if isinstance(x, (ca.SX, ca.MX)):
        return ca.if_else(x < lo, lo, ca.if_else(x > hi, hi, x))
    return np.minimum(np.maximum(x, lo), hi)


def _positive_part(x):
    if isinstance(x, (ca.SX, ca.MX)):
        return ca.fmax(x, 0)
    return np.maximum(x, 0.0)


@dataclass(frozen=True)
class SplineBasis:
    """Uniform B-spline basis of one linear axis.

    lo, hi : mm, the range the knots span. n_intervals : equal intervals. degree : 1 to 3.
    """

    lo: float
    hi: float
    n_intervals: int
    degree: int = 3

    def __post_init__(self):
        if not self.hi > self.lo:
            raise ValueError(f"spline range must have hi > lo, got [{self.lo}, {self.hi}]")
        if self.n_intervals < 1 or not 1 <= self.degree <= 3:
            raise ValueError("spline needs n_intervals >= 1 and degree 1..3")

    @property
    def n_basis(self) -> int:
        return self.n_intervals + self.degree

    @property
    def h(self) -> float:
        return (self.hi - self.lo) / self.n_intervals

    @property
    def mid(self) -> float:
        return 0.5 * (self.lo + self.hi)

    def raw(self, s):
        """[B_j(s) for j in 0..n_basis-1], numpy arrays or CasADi expressions (s clipped to range).

        With x = (s - lo) / h in [0, n], B_j(x) = N_k(x - j + k) is a sum of the truncated powers
        T_m = (x - m)_+^k, m = j - k .. j + 1, which the functions share: each T_m is built once (for
        m < 0 it is a plain power, x >= 0). Beyond B_j's support the terms cancel exactly in exact
        arithmetic; in floating point to ~1e-16 (n + k)^k, far below any error an axis has.
        """
        k = self.degree
        x = (_clip(s, self.lo, self.hi) - self.lo) / self.h
        T = {}
        for m in range(-k, self.n_intervals):
            T[m] = (x - m) ** k if m < 0 else _positive_part(x - m) ** k
        coef = [((-1) ** i) * comb(k + 1, i) / factorial(k) for i in range(k + 2)]
        out = []
        for j in range(self.n_basis):
            b = 0
            for i, c in enumerate(coef):
                m = j - k + i
                if m in T:          # T_m = 0 for m >= n (x <= n)
                    b = b + c * T[m]
            out.append(b)
        return out

    def functions_by_reference(self, s) -> dict:
        """{False: functions(s, False), True: functions(s, True)} from one evaluation of the basis."""
        mean, slope = self._moments
        raw = self.raw(s)
        sc = _clip(s, self.lo, self.hi)
        out = {}
        for carried in (False, True):
            out[carried] = [raw[j] - mean[j] - (slope[j] * (sc - self.mid) if carried else 0.0)
                            for j in self.kept(carried)]
        return out

    @cached_property
    def _moments(self) -> tuple[np.ndarray, np.ndarray]:
        """(a, b): least-squares line a_j + b_j (s - mid) of each B_j over [lo, hi] (exact quadrature)."""
        g, w = np.polynomial.legendre.leggauss(4)      # exact for the quartic B_j(s) * s per interval
        edges = np.linspace(self.lo, self.hi, self.n_intervals + 1)
        s = (0.5 * (edges[1:, None] + edges[:-1, None]) + 0.5 * self.h * g[None, :]).ravel()
        wt = np.tile(0.5 * self.h * w, self.n_intervals)
        B = np.array(self.raw(s))                     # (n_basis, n_nodes)
        L = self.hi - self.lo
        x = s - self.mid
        mean = B @ wt / L
        slope = (B @ (wt * x)) / float(np.sum(wt * x * x))
        return mean, slope

    def kept(self, carried_slope: bool) -> list[int]:
        """Indices of the basis functions a component keeps (the first, and the last when the slope
        is carried elsewhere, are redundant after the reference is removed)."""
        idx = list(range(1, self.n_basis))
        if carried_slope:
            idx = idx[:-1]
        return idx

    def functions(self, s, carried_slope: bool):
        """[phi_j(s) for j in kept(carried_slope)]: B_j less its mean (and least-squares line), all
        evaluated at the clipped position (constant beyond the range). numpy or CasADi."""
        return self.functions_by_reference(s)[carried_slope]


@lru_cache(maxsize=256)
def spline_basis(lo: float, hi: float, n_intervals: int, degree: int) -> SplineBasis:
    """The (shared, immutable) basis of one knot layout: built, and its moments integrated, once."""
    return SplineBasis(lo, hi, n_intervals, degree)


#: the closest knots the data choose (mm): a cubic spline on knots h apart follows little of a sine
#: shorter than 2.5 h, so the base leaves what repeats at a ball screw's lead (5 to 40 mm) to
#: diagnose, which names it a periodic error
MIN_KNOT_MM = 16.0
#: the functions an axis may always have, whatever its range (on a short axis knots closer than
#: ``MIN_KNOT_MM``: as many functions as a short laser run's targets, up to this)
DEFAULT_MAX_BASIS = 16
#: the most functions per axis that the data's spacing chooses (single-axis runs may ask for more,
#: :data:`SPLINE_SIZES`)
MAX_BASIS = 48
#: functions beyond ``DEFAULT_MAX_BASIS`` are given only while the fit's rows times the square of
#: the functions summed over the linear axes stays within this: the normal matrix's cost grows so.
#: 1,500 rows of tracker lines take up to ``MAX_BASIS`` per axis; 20,000 rows and more keep 16, so a
#: fit of 100,000 points keeps its time
FIT_SIZE_BUDGET = 4e7


def max_intervals(lo: float, hi: float) -> int:
    """The most equal knot intervals over [lo, hi] whose knots stay ``MIN_KNOT_MM`` apart."""
    return int((hi - lo) // MIN_KNOT_MM)


def auto_spline(positions, travel: tuple[float, float], max_basis: int | None = None,
                resolution_mm: float = 1e-3, finest: int = MAX_BASIS,
                room: bool = False) -> tuple[float, float, int, int]:
    """Knots that the data can determine: (lo, hi, n_intervals, degree) for one linear axis.

    positions : every position the axis took in the data (mm). The range is that of the data; the
    number of basis functions is the number of distinct positions (at ``resolution_mm``), so that a
    laser run over m targets is followed at every target (a pitch table's resolution) and a dense
    line of points at its own spacing; the roughness penalty, not the knot count, sets how smooth
    the fitted profile is. ``max_basis`` : at most this many functions (single-axis runs' choice,
    :func:`spline_size_by_cv`); by default the knots stay ``MIN_KNOT_MM`` apart and there are at
    most ``finest`` functions (never fewer than ``DEFAULT_MAX_BASIS`` allowed). Degree 3 when there
    are four or more functions, less below.
    room : the fit carries the roughness penalty: an axis read at three or more positions, fewer
    than ``DEFAULT_MAX_BASIS``, still gets that many functions (knots ``MIN_KNOT_MM`` apart at the
    closest; two positions keep their straight line: they read no curvature at all),
    so that between its positions the penalty, not the basis, decides the profile, and the
    penalised fit's posterior gives what it does there its variance (a basis of as many functions
    as positions is fixed by them, and claimed to know the profile between them).
    An axis that did not move gets the travel and one linear piece (its errors are undetermined and
    held at zero).
    """
    distinct = _distinct(positions, resolution_mm)
    if distinct.size < 2:
        return float(travel[0]), float(travel[1]), 1, 1
    n_basis = _n_functions(distinct, max_basis, finest, room)
    degree = min(3, n_basis - 1)
    return float(distinct[0]), float(distinct[-1]), n_basis - degree, degree


def _distinct(positions, resolution_mm: float = 1e-3) -> np.ndarray:
    """The distinct finite positions (mm) at ``resolution_mm``, sorted."""
    pos = np.asarray(positions, dtype=float)
    pos = pos[np.isfinite(pos)]
    return np.unique(np.round(pos / resolution_mm)) * resolution_mm if pos.size else pos


def _n_functions(distinct: np.ndarray, max_basis: int | None, finest: int, room: bool = False) -> int:
    """The functions :func:`auto_spline` gives an axis with these distinct positions (two or more)."""
    if max_basis is None:
        max_basis = max(DEFAULT_MAX_BASIS, min(finest, max_intervals(distinct[0], distinct[-1]) + 3))
    n = distinct.size
    spans = max_intervals(distinct[0], distinct[-1])
    if room and spans >= 1 and n >= 3:
        n = max(n, min(DEFAULT_MAX_BASIS, spans + 3))
    return int(min(n, max_basis))


def finest_within_budget(machine: Machine, distinct: dict, sizes: dict | None, rows: int) -> int:
    """The most functions per axis (``finest`` of :func:`auto_spline`, from ``DEFAULT_MAX_BASIS`` to
    ``MAX_BASIS``) for which ``rows`` times the square of the functions summed over the linear axes
    stays within ``FIT_SIZE_BUDGET``; ``DEFAULT_MAX_BASIS`` when even that does not.

    distinct : axis name -> the distinct positions of every linear axis whose knots the data choose.
    sizes : axis name -> single-axis runs' cap (:func:`with_data_basis`). rows : the data's rows.
    """
    def total(finest):
        n = 0
        for a in machine.axes:
            if a.is_rotary:
                continue
            if a.name in distinct:
                if a.spline_intervals is not None:
                    n += a.spline_intervals + a.degree
                elif distinct[a.name].size >= 2:
                    n += _n_functions(distinct[a.name], (sizes or {}).get(a.name), finest, True)
                else:
                    n += 2
            else:
                n += axis_spline(a).n_basis if a.basis == "bspline" else a.degree
        return n

    best = DEFAULT_MAX_BASIS
    for finest in range(DEFAULT_MAX_BASIS + 1, MAX_BASIS + 1):
        if rows * total(finest) ** 2 > FIT_SIZE_BUDGET:
            break
        best = finest
    return best


#: basis sizes (functions per linear axis) that single-axis runs may choose beyond ``auto_spline``'s
#: default cap (:func:`spline_size_by_cv`)
SPLINE_SIZES = (16, 20, 24, 32, 40, 48, 64)
#: a larger basis must lower the held-out sum of squares (in noise variances) by this many standard
#: deviations of a chi-square with the added functions as degrees of freedom, plus their number
SIZE_CV_Z = 2.0
#: a line whose finer bases gain (held-out) at most 1 / this share more than one window of fine
#: functions gains does not ask for a finer basis
RIVAL_SHARE = 0.9
#: the window of the local rival of a finer basis, as a share of the line's span
LOCAL_WINDOW = 1.0 / 8.0


def spline_size_by_cv(series, lo: float, hi: float, sizes=SPLINE_SIZES) -> tuple[int, dict]:
    """The number of cubic B-spline functions over [lo, hi] that single-axis runs ask for, chosen by
    leave-one-run-out cross-validation.

    series : list of (s, y, run) arrays, one per measured line (a laser file's component at one
        optic offset, static position, feed and approach direction): position (mm), reading (any
        unit), run number. Each is modelled as a spline of s alone (its own profile, which absorbs
        the laser zero and the Abbe offsets of that line), fitted with one run left out and scored
        on it, in units of that line's noise variance (the scatter of repeated readings about their
        target's mean).
    sizes : candidate numbers of functions, increasing; the first is the default. Each line's number
        of distinct positions between the first and the last is tried too.

    A size replaces a smaller one only when it lowers the summed held-out score by more than
    ``SIZE_CV_Z * sqrt(2 dk) + dk`` (dk: the functions it adds over the lines that can take it), on
    the lines that can take both. A line with fewer than two runs, or no more distinct positions
    than the first size, says nothing; one with fewer distinct positions than a size says nothing
    about that size. Returns (size, {size: summed score}); the first size when no line can tell.
    (A component finer than the others of its axis may be averaged away here; diagnose checks the
    final residual component by component, mtcomp.diagnose._resolution.)
    """
    # each line's own number of positions is a size too (one function per target, a pitch table's
    # resolution), where it lies between the first and the last
    counts = {np.unique(np.round(np.asarray(s, dtype=float)[np.isfinite(s)], 3)).size for s, _, _ in series}
    sizes = sorted({int(n) for n in sizes} | {c for c in counts if sizes[0] < c < max(sizes)})
    lines = []                                  # per line: {size: held-out score}
    for s, y, run in series:
        s, y, run = (np.asarray(v) for v in (s, y, run))
        ok = np.isfinite(s) & np.isfinite(y)
        s, y, run = s[ok].astype(float), y[ok].astype(float), run[ok]
        runs = np.unique(run)
        distinct, inv = np.unique(np.round(s, 3), return_inverse=True)
        if runs.size < 2 or distinct.size <= sizes[0]:
            continue
        cnt = np.bincount(inv)
        mean = np.bincount(inv, weights=y) / cnt
        dof = int(y.size - distinct.size)
        pure = float(np.sum((y - mean[inv]) ** 2))
        if dof < 2 or not pure > 0:
            continue
        var = pure / dof
        x = np.clip(s, lo, hi)
        score = {n: _held_out(_bspline_design(x, lo, hi, n), y, run) / var
                 for n in sizes if n <= distinct.size and (n == sizes[0] or n - 3 <= max_intervals(lo, hi))}
        finer = [n for n in score if n > sizes[0]]
        if finer:
            base = _bspline_design(x, lo, hi, sizes[0])
            finest = max(n for n in sizes if n <= distinct.size)
            cols = _local_columns(x, y - base @ np.linalg.lstsq(base, y, rcond=None)[0], lo, hi, finest)
            rival = _held_out(np.hstack([base, cols]), y, run) / var
            best = min(finer, key=lambda n: score[n])
            gain = score[sizes[0]] - score[best]
            # a window holding as many functions as the line has targets beyond the default size is
            # no narrower than the line itself (21 targets: the default misses a few of them, and
            # any few are "one place")
            narrow = cols.shape[1] <= 0.5 * (distinct.size - sizes[0])
            if gain > 0 and narrow and score[sizes[0]] - rival >= RIVAL_SHARE * gain:
                # one place explains what the finer bases gain: that is for diagnose to name (a
                # local defect), not for the base to absorb
                score = {sizes[0]: score[sizes[0]]}
        lines.append(score)
    chosen = sizes[0]
    for n in sizes[1:]:
        both = [sc for sc in lines if n in sc]
        if not both:
            break
        dk = (n - chosen) * len(both)
        gain = sum(sc[chosen] - sc[n] for sc in both)
        if gain > SIZE_CV_Z * np.sqrt(2.0 * dk) + dk:
            chosen = n
    totals = {n: float(sum(sc[n] for sc in lines if n in sc)) for n in sizes}
    return chosen, {n: v for n, v in totals.items() if any(n in sc for sc in lines)}


def _bspline_design(x, lo, hi, n):
    """(len(x), n) cubic (degree n - 1 below four functions) uniform B-splines over [lo, hi]:
    the same functions as :class:`SplineBasis` (scipy's design matrix)."""
    from scipy.interpolate import BSpline
    k = min(3, n - 1)
    h = (hi - lo) / (n - k)
    t = lo + h * np.arange(-k, n + 1)
    # t[n] may round a hair below hi: a position at hi is then out of scipy's bounds
    return BSpline.design_matrix(np.clip(x, t[k], t[n]), t, k).toarray()


def _held_out(X, y, run) -> float:
    """Sum of squares of each run predicted by least squares on the others."""
    sse = 0.0
    for r in np.unique(run):
        out = run == r
        c, *_ = np.linalg.lstsq(X[~out], y[~out], rcond=None)
        sse += float(np.sum((y[out] - X[out] @ c) ** 2))
    return sse


def _local_columns(x, r, lo, hi, n_fine):
    """The narrow explanation a finer basis competes with on one line: the functions of the finest
    basis the line can take (``n_fine``, by its number of targets alone: a defect may be narrower
    than the ``MIN_KNOT_MM`` knots of the bases it competes with) over one window (``LOCAL_WINDOW``
    of the line's span) centred where the per-target mean of ``r`` (the residual of the default
    basis), smoothed over five targets, peaks."""
    ux, inv = np.unique(np.round(x, 3), return_inverse=True)
    mean = np.bincount(inv, weights=r) / np.bincount(inv)
    smooth = np.convolve(mean, np.ones(5) / 5.0, mode="same")
    c = float(ux[int(np.argmax(np.abs(smooth)))])
    half = 0.5 * LOCAL_WINDOW * float(ux[-1] - ux[0])
    fine = _bspline_design(x, lo, hi, n_fine)
    h = (hi - lo) / (n_fine - 3)
    centre = lo + h * (np.arange(n_fine) - 1.0)          # centre of B_j's support [j-3, j+1] h
    return fine[:, np.abs(centre - c) <= half + h]


#: the highest harmonic of a rotary axis's angular positioning error chosen from data
MAX_FOURIER_ORDER = 6


def auto_fourier_order(angles, resolution_rad: float = 1e-6) -> int:
    """Harmonics of a rotary axis's positioning error that the data can determine: with m distinct
    angles (modulo one turn) a Fourier series of order (m - 1) // 2 has no more coefficients than
    angles; at most :data:`MAX_FOURIER_ORDER`."""
    a = np.asarray(angles, dtype=float)
    a = a[np.isfinite(a)]
    if a.size == 0:
        return 0
    distinct = np.unique(np.round(np.mod(a, 2 * np.pi) / resolution_rad))
    return int(min(MAX_FOURIER_ORDER, max(0, (distinct.size - 1) // 2)))


# ------------------------------------------------------------------ the basis of a machine's axes
def axis_spline(axis) -> SplineBasis:
    """The :class:`SplineBasis` of a linear axis (mtcomp.machine.Axis) with basis 'bspline': its
    knots' range (the travel until the data choose one) and intervals."""
    lo, hi = axis.spline_range if axis.spline_range is not None else axis.travel
    return spline_basis(float(lo), float(hi), int(axis.spline_intervals or DEFAULT_SPLINE_INTERVALS),
                        int(axis.degree))


def with_data_basis(machine: Machine, positions: dict, fourier: bool = True,
                    sizes: dict | None = None, penalised: bool = True,
                    room: bool | None = None) -> Machine:
    """The machine with the spline knots of every 'bspline' axis without fixed knots, and the Fourier
    order of every rotary axis whose machine file leaves it open, chosen from the data
    (:func:`mtcomp.models.basis.auto_spline`, :func:`~mtcomp.models.basis.auto_fourier_order`).

    positions : axis name -> array of every position that axis took in the data (mm).
    fourier : also choose the Fourier orders (False keeps the machine's).
    sizes : axis name -> the most spline functions for that axis (default: ``auto_spline``'s cap),
        e.g. from :func:`mtcomp.measurement.readings.data_spline_sizes`.

    penalised : the fit carries the roughness penalty (identify). The other axes then get as many
        functions as their distinct positions, knots ``MIN_KNOT_MM`` apart at the closest, and at
        most as many as :func:`finest_within_budget` allows the data's rows; False (an unpenalised
        fit, diagnose's base, whose held-out comparisons refine an axis where the data ask): at most
        ``DEFAULT_MAX_BASIS``.
    room : an axis read at 3 to 15 positions gets ``DEFAULT_MAX_BASIS`` functions
        (:func:`auto_spline`'s ``room``); default: ``penalised``. Diagnose's model written (the
        penalised fit on its unpenalised base's knots) asks for it without the finer knots.
    """
    from dataclasses import replace

    chosen = [a for a in machine.axes if not a.is_rotary and a.basis_from_data]
    distinct = {a.name: _distinct(positions.get(a.name, ())) for a in chosen}
    rows = max((np.size(v) for v in positions.values()), default=0)
    finest = finest_within_budget(machine, distinct, sizes, rows) if penalised else DEFAULT_MAX_BASIS
    axes = []
    for a in machine.axes:
        if a.is_rotary and a.fourier_from_data and fourier:
            a = replace(a, fourier_order=auto_fourier_order(positions.get(a.name, ())),
                        fourier_from_data=False)
        if not a.is_rotary and a.basis_from_data:
            cap = {"max_basis": int(sizes[a.name])} if sizes and a.name in sizes else {}
            lo, hi, n, degree = auto_spline(distinct[a.name], a.travel, finest=finest,
                                         room=penalised if room is None else room, **cap)
            if a.spline_range is not None:
                lo, hi = a.spline_range
            if a.spline_intervals is not None:
                n, degree = a.spline_intervals, a.degree
            a = replace(a, spline_range=(lo, hi), spline_intervals=n, degree=degree)
        axes.append(a)
    return replace(machine, axes=tuple(axes))

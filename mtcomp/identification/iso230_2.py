"""ISO 230-2:2014 evaluation of bidirectional positioning runs (laser files, docs/iso230_2.md).

For each axis, every target position ``P_i`` is approached ``n`` times (runs ``j``) in each direction
(up: ``dir = +1``, down: ``dir = -1``); each reading is the positional deviation ``x_ij = P_ij - P_i``
(actual minus target: the ``value`` of the positioning component EXX, EYY, EZZ, EAA, EBB or ECC).
With ``up``/``down`` for the arrows of the standard:

* mean unidirectional positional deviation  ``xbar_i_up = mean_j x_ij_up`` (likewise down)
* mean bidirectional positional deviation   ``xbar_i = (xbar_i_up + xbar_i_down) / 2``
* reversal value                            ``B_i = xbar_i_up - xbar_i_down``
* unidirectional repeatability estimator    ``s_i_up = sqrt(sum_j (x_ij_up - xbar_i_up)^2 / (n - 1))``
* unidirectional repeatability              ``R_i_up = 4 s_i_up``
* bidirectional repeatability               ``R_i = max(2 s_i_up + 2 s_i_down + |B_i|, R_i_up, R_i_down)``

and for the axis:

* reversal value ``B``: the ``B_i`` of largest magnitude, with its sign (docs/iso230_2.md); mean
  ``B_mean``
* ``R_up = max_i R_i_up``, ``R_down``, ``R = max_i R_i``
* systematic ``E_up = max xbar_i_up - min xbar_i_up``, ``E_down``,
  ``E = max(xbar_up, xbar_down) - min(xbar_up, xbar_down)``
* mean bidirectional ``M = max xbar_i - min xbar_i``
* accuracy ``A_up = max(xbar_i_up + 2 s_i_up) - min(xbar_i_up - 2 s_i_up)``, ``A_down``,
  ``A = max(xbar_up + 2 s_up, xbar_down + 2 s_down) - min(xbar_up - 2 s_up, xbar_down - 2 s_down)``

Arrays and values are in internal units: mm for linear axes, rad for rotary ones; :meth:`to_dict`
gives um (linear) or urad and arcsec (rotary).

Outlier readings are flagged, never removed (the standard evaluates every reading): at a target and
direction with n >= 3 runs, a reading is an outlier when it departs from the median of the *other*
runs there by more than ``OUTLIER_K`` = 4 times what the axis's repeatability allows,
``s_ref sqrt(1 + pi / (2 (n - 1)))`` (the spread of a reading about a median of n - 1 others), with
``s_ref`` the median of the axis's ``s_i_up`` and ``s_i_down``. Medians, so that one wild reading
neither inflates the scale nor drags its neighbours over the line. For normal readings a false flag
has a chance of about 1e-4 per reading.

Run-to-run drift (:class:`RunDrift`, not part of the standard): the readings are fitted with the
additive model ``x = mu_(target, dir) + r_run + e``; the runs drift when the F test of the run
effects against the within-run scatter rejects at ``DRIFT_ALPHA`` = 1 %. Reported with the run means,
their range and linear trend, and R with the run offsets removed.

Units: a linear axis whose targets span 100 mm or more, with every reading below
max(0.05 um, 0.5 ppm of the span), reads below what a laser measures reliably there: its values were
likely written in mm under ``value_um`` (:func:`unit_check`; flagged, not refused).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..io.atomic import atomic_write
from ..machine import ROTARY
# the unit check (values in mm written under value_um) is the measurement files' own
from ..measurement.units import UNIT_CHECK_FLOOR_URAD, unit_check, unit_limit_um

UM_PER_MM = 1e3
URAD_PER_RAD = 1e6
ARCSEC_PER_RAD = 180.0 / math.pi * 3600.0
#: number of runs per direction the standard cycle asks for
STANDARD_RUNS = 5
#: targets closer than this (mm or rad) are the same target
TARGET_TOLERANCE = 1e-9
#: outlier rule: |reading - median of the other runs| > OUTLIER_K * s_ref * sqrt(1 + pi / (2 (n - 1)))
OUTLIER_K = 4.0
#: run-to-run drift is reported when the F test of the runs has a p-value below this
DRIFT_ALPHA = 0.01
#: run means that differ by less than this are no drift to warn of, however significant (mm for a
#: linear axis: 0.1 um; rad for a rotary one: 0.5 urad): values in mm read as um have scatter so
#: small that a 0.001 um change passes the test
MIN_DRIFT = {"linear": 1e-4, "rotary": 5e-7}

_PER_TARGET = ("mean_up", "mean_down", "mean", "reversal", "s_up", "s_down", "R_i_up", "R_i_down", "R_i")
_PER_AXIS = ("A", "A_up", "A_down", "B", "B_mean", "E", "E_up", "E_down", "M", "R", "R_up", "R_down")


def positioning_component(axis: str) -> str:
    """ISO 230-1 name of the positioning error of ``axis``: 'X' -> 'EXX', 'C' -> 'ECC'."""
    return f"E{axis}{axis}"


@dataclass(frozen=True)
class Outlier:
    """A flagged reading: target (mm or rad), dir (+1 / -1), run, value (mm or rad), departure from
    the median of the other runs at that target and direction (mm or rad), score (departure over its
    expected spread), row (data row of the file)."""

    target: float
    dir: int
    run: int
    value: float
    departure: float
    score: float
    row: int


@dataclass(frozen=True, eq=False)
class RunDrift:
    """Run-to-run drift of one axis (docs/iso230_2.md). Units: mm (linear axis) or rad (rotary).

    The readings are fitted with the additive model ``x = mu_(target, dir) + r_run + e`` (least
    squares, ``sum r_run = 0``); the runs differ when the F test of that model against
    ``x = mu_(target, dir) + e`` rejects at :data:`DRIFT_ALPHA`.

    runs : (n,) int run numbers, in increasing order (the order the runs were made in).
    run_means : (n,) mean deviation of each run: the mean of the fitted ``mu`` over the (target,
        direction) cells plus ``r_run``; the plain mean of the run's readings when every run reads
        every cell.
    size : max - min of ``run_means``.
    trend : least-squares slope of ``run_means`` against the run number, per run.
    within_s : residual standard deviation of the additive model: the scatter left within runs.
    F, p : F statistic of the runs (``n - 1`` and ``N - cells - n + 1`` degrees of freedom), p-value.
    drift : True when ``p < DRIFT_ALPHA``.
    R_without : bidirectional repeatability R of the readings with each run's ``r_run`` removed.
    """

    runs: np.ndarray
    run_means: np.ndarray
    size: float
    trend: float
    within_s: float
    F: float
    p: float
    drift: bool
    R_without: float


@dataclass(frozen=True, eq=False)
class AxisPositioning:
    """ISO 230-2 figures of one axis. Units: mm (linear axis) or rad (rotary axis).

    axis : 'X' ... 'C'; rotary : True for A, B, C.
    targets : (m,) target positions P_i, increasing, mm or rad.
    n_up, n_down : (m,) int number of runs at each target in each direction.
    mean_up, mean_down : (m,) mean unidirectional positional deviations.
    mean : (m,) mean bidirectional positional deviation; reversal : (m,) B_i.
    s_up, s_down : (m,) estimators of the unidirectional repeatability standard uncertainty.
    R_i_up, R_i_down, R_i : (m,) unidirectional and bidirectional repeatability at each target.
    A, A_up, A_down, B, B_mean, E, E_up, E_down, M, R, R_up, R_down : axis figures (module docstring).
    outliers : flagged readings (:class:`Outlier`, module docstring).
    readings : the readings evaluated, {'target', 'dir', 'run', 'value'} -> (n,) arrays, for plots.
    drift : run-to-run drift (:class:`RunDrift`); None with a single run (see :func:`run_drift`).
    unit_suspect : True when every reading is smaller than a laser measures over the axis's travel
        (:func:`unit_check`): the values were likely written in mm (rad) under value_um (value_urad).
    """

    axis: str
    rotary: bool
    targets: np.ndarray
    n_up: np.ndarray
    n_down: np.ndarray
    mean_up: np.ndarray
    mean_down: np.ndarray
    mean: np.ndarray
    reversal: np.ndarray
    s_up: np.ndarray
    s_down: np.ndarray
    R_i_up: np.ndarray
    R_i_down: np.ndarray
    R_i: np.ndarray
    A: float
    A_up: float
    A_down: float
    B: float
    B_mean: float
    E: float
    E_up: float
    E_down: float
    M: float
    R: float
    R_up: float
    R_down: float
    outliers: tuple = ()
    readings: dict | None = None
    drift: RunDrift | None = None
    unit_suspect: bool = False

    @property
    def unit(self) -> str:
        """The report unit: 'um' (linear) or 'urad' (rotary)."""
        return "urad" if self.rotary else "um"

    @property
    def scale(self) -> float:
        """Factor from internal units to :attr:`unit`."""
        return URAD_PER_RAD if self.rotary else UM_PER_MM

    def to_dict(self) -> dict:
        """JSON object of one axis (docs/iso230_2.md): ``A_um`` ... ``R_down_um`` (``_urad`` and
        ``_arcsec`` for rotary axes), ``B_mean_*``, and the per-target arrays (``targets_mm`` or
        ``targets_deg``, ``n_up``, ``n_down``, ``mean_up_*``, ``mean_down_*``, ``mean_*``,
        ``reversal_*``, ``s_up_*``, ``s_down_*``, ``R_i_up_*``, ``R_i_down_*``, ``R_i_*``)."""
        units = [(self.unit, self.scale)]
        if self.rotary:
            units.append(("arcsec", ARCSEC_PER_RAD))
        out: dict = {"axis_type": "rotary" if self.rotary else "linear"}
        for unit, scale in units:
            for key in _PER_AXIS:
                out[f"{key}_{unit}"] = float(getattr(self, key)) * scale
        if self.rotary:
            out["targets_deg"] = [float(v) for v in np.degrees(self.targets)]
        else:
            out["targets_mm"] = [float(v) for v in self.targets]
        out["n_up"] = [int(v) for v in self.n_up]
        out["n_down"] = [int(v) for v in self.n_down]
        for unit, scale in units:
            for key in _PER_TARGET:
                out[f"{key}_{unit}"] = [float(v) * scale for v in getattr(self, key)]
        tgt = ("target_deg", 180.0 / math.pi) if self.rotary else ("target_mm", 1.0)
        out["outliers"] = [{tgt[0]: o.target * tgt[1], "dir": o.dir, "run": o.run, "row": o.row,
                            f"value_{self.unit}": o.value * self.scale,
                            f"departure_{self.unit}": o.departure * self.scale, "score": o.score}
                           for o in self.outliers]
        if self.drift is not None:
            dr = self.drift
            out["runs"] = [int(v) for v in dr.runs]
            out["drift"] = bool(dr.drift)
            out["drift_F"] = float(dr.F)
            out["drift_p"] = float(dr.p)
            for unit, scale in units:
                out[f"run_means_{unit}"] = [float(v) * scale for v in dr.run_means]
                out[f"drift_{unit}"] = float(dr.size) * scale
                out[f"drift_trend_{unit}_per_run"] = float(dr.trend) * scale
                out[f"within_run_s_{unit}"] = float(dr.within_s) * scale
                out[f"R_without_drift_{unit}"] = float(dr.R_without) * scale
        out["unit_suspect"] = bool(self.unit_suspect)
        return out

    def table(self) -> str:
        """A readable table: per target and direction, then the axis figures."""
        s = self.scale
        u = self.unit
        tgt_unit = "deg" if self.rotary else "mm"
        targets = np.degrees(self.targets) if self.rotary else self.targets
        head = (f"{'target_' + tgt_unit:>11} {'n_up':>4} {'n_dn':>4} {'mean_up':>9} {'mean_dn':>9} "
                f"{'mean':>9} {'B_i':>9} {'s_up':>8} {'s_dn':>8} {'R_i_up':>8} {'R_i_dn':>8} {'R_i':>8}")
        lines = [f"axis {self.axis} ({'rotary' if self.rotary else 'linear'}), component "
                 f"{positioning_component(self.axis)}, deviations in {u}", head]
        for i in range(len(self.targets)):
            lines.append(f"{targets[i]:11.4f} {self.n_up[i]:4d} {self.n_down[i]:4d} "
                         f"{self.mean_up[i] * s:9.3f} {self.mean_down[i] * s:9.3f} {self.mean[i] * s:9.3f} "
                         f"{self.reversal[i] * s:9.3f} {self.s_up[i] * s:8.3f} {self.s_down[i] * s:8.3f} "
                         f"{self.R_i_up[i] * s:8.3f} {self.R_i_down[i] * s:8.3f} {self.R_i[i] * s:8.3f}")
        units = [(u, s)] + ([("arcsec", ARCSEC_PER_RAD)] if self.rotary else [])
        lines.append("")
        lines.append(f"{'axis figures':44}" + "".join(f"{'up_' + un:>10} {'down_' + un:>10} "
                                                      f"{'bidir_' + un:>12}  " for un, _ in units))
        rows = [("A  accuracy (mean +- 2 s)", self.A_up, self.A_down, self.A),
                ("E  systematic positional deviation", self.E_up, self.E_down, self.E),
                ("R  repeatability (4 s, with B_i)", self.R_up, self.R_down, self.R),
                ("M  mean bidirectional deviation", None, None, self.M),
                ("B  reversal (largest |B_i|, signed)", None, None, self.B),
                ("   mean reversal B_mean", None, None, self.B_mean)]
        for label, up, down, bi in rows:
            cells = ""
            for _, sc in units:
                f = (lambda v, w=10: f"{'':>{w}}" if v is None else f"{v * sc:{w}.3f}")
                cells += f"{f(up)} {f(down)} {f(bi, 12)}  "
            lines.append(f"{label:44}{cells}")
        if self.drift is not None:
            lines += ["", *self._drift_lines()]
        for o in self.outliers:
            t = math.degrees(o.target) if self.rotary else o.target
            lines.append(f"outlier: target {t:g} {tgt_unit}, dir {o.dir:+d}, run {o.run} (row {o.row}): "
                         f"{o.value * s:.3f} {u}, {o.departure * s:+.3f} {u} from the median of the "
                         f"other runs ({o.score:.1f} x the spread the repeatability allows)")
        return "\n".join(line.rstrip() for line in lines)

    def _drift_lines(self) -> list[str]:
        dr, s, u = self.drift, self.scale, self.unit
        lines = [f"{'run':16}" + "".join(f"{int(j):>9d}" for j in dr.runs),
                 f"{'run mean ' + u:16}" + "".join(f"{v * s:9.3f}" for v in dr.run_means)]
        verdict = "drift between runs" if dr.drift else "no drift between runs detected"
        lines.append(f"{verdict}: range of the run means {dr.size * s:.3f} {u}, trend {dr.trend * s:+.3f} "
                     f"{u} per run, within-run s {dr.within_s * s:.3f} {u}, F = {dr.F:.2f} "
                     f"(p = {dr.p:.2g}); R without the run offsets {dr.R_without * s:.3f} {u}")
        return lines

    def drift_note(self) -> str | None:
        """One sentence on the run-to-run drift when it is detected, else None."""
        dr = self.drift
        if dr is None or not dr.drift:
            return None
        s, u = self.scale, self.unit
        return (f"axis {self.axis}: the runs drift: run means {', '.join(f'{v * s:.1f}' for v in dr.run_means)} "
                f"{u} (range {dr.size * s:.1f} {u}, trend {dr.trend * s:+.1f} {u} per run; F = {dr.F:.1f} "
                f"against a within-run s of {dr.within_s * s:.1f} {u}, p = {dr.p:.1g}); R ({self.R * s:.1f} "
                f"{u}) includes this drift ({dr.R_without * s:.1f} {u} without it): let the machine and the "
                "laser set-up reach a steady temperature (warm-up) and check the optics' mounting before "
                "repeating the cycle")

    def unit_note(self) -> str | None:
        """One sentence when the readings look written in mm (rad) under value_um (value_urad)."""
        if not self.unit_suspect:
            return None
        biggest = float(np.abs(self.readings["value"]).max()) * self.scale
        if self.rotary:
            return (f"axis {self.axis}: every reading is below {UNIT_CHECK_FLOOR_URAD:g} urad in magnitude "
                    f"(largest {biggest:.3g} urad) over {math.degrees(np.ptp(self.targets)):g} deg, less "
                    "than any angular instrument resolves: were the values written in rad under "
                    "value_urad? if so multiply them by 1e6")
        span = float(np.ptp(self.targets))
        return (f"axis {self.axis}: every reading is below {unit_limit_um(span):.2g} um in magnitude "
                f"(largest {biggest:.3g} um) over {span:g} mm of travel, below what a laser measures "
                "reliably there: were the values written in mm under value_um? if so multiply them by 1000")


@dataclass(frozen=True, eq=False)
class Iso230_2Report:
    """ISO 230-2 evaluation of a laser file: one :class:`AxisPositioning` per axis, and notices.

    axes : axis name -> figures, in X Y Z A B C order.
    notices : sentences about what was ignored or falls short of the standard cycle.
    path : the evaluated file.
    """

    axes: dict
    notices: tuple[str, ...]
    path: str = ""

    def to_dict(self) -> dict:
        """OUT.json of ``mtcomp iso230-2``: one object per axis (docs/iso230_2.md)."""
        return {name: ax.to_dict() for name, ax in self.axes.items()}

    def summary(self) -> str:
        parts = [f"ISO 230-2 evaluation of {self.path}" if self.path else "ISO 230-2 evaluation"]
        parts += [f"note: {n}" for n in self.notices]
        for ax in self.axes.values():
            parts += ["", ax.table()]
        return "\n".join(parts)


def evaluate_axis(axis: str, target: np.ndarray, direction: np.ndarray, run: np.ndarray,
                  value: np.ndarray, path: str | None = None, row: np.ndarray | None = None,
                  with_drift: bool = True) -> AxisPositioning:
    """ISO 230-2 figures of one axis from its positioning readings.

    axis : 'X' ... 'C' (A, B, C are rotary).
    target : (n,) target position of each reading, mm or rad.
    direction : (n,) approach direction +1 (up) or -1 (down).
    run : (n,) run number.
    value : (n,) positional deviation x_ij (actual minus target), mm or rad.
    path, row : the file and (n,) data rows, for error messages.
    with_drift : also fit the run-to-run drift (:func:`run_drift`).
    Raises InputError when a (target, direction, run) is read twice, a value is blank, or a target
    has fewer than 2 runs in a direction (the repeatability needs a standard deviation).
    """
    target = np.asarray(target, dtype=float)
    direction = np.asarray(direction)
    run = np.asarray(run)
    value = np.asarray(value, dtype=float)
    row = np.arange(1, len(value) + 1) if row is None else np.asarray(row)
    rotary = axis in ROTARY
    tgt_text = (lambda t: f"{math.degrees(t):g} deg") if rotary else (lambda t: f"{t:g} mm")

    blank = np.flatnonzero(~np.isfinite(value))
    if blank.size:
        raise InputError(f"axis {axis}: the value is blank; ISO 230-2 needs every reading", path,
                         row=int(row[blank[0]]))
    order = np.argsort(target, kind="stable")
    # targets within TARGET_TOLERANCE of the previous one are the same target
    new = np.r_[True, np.diff(target[order]) > TARGET_TOLERANCE]
    label = np.empty(len(target), dtype=np.int64)
    label[order] = np.cumsum(new) - 1
    targets = np.array([target[label == k].mean() for k in range(label.max() + 1)])

    m = len(targets)
    stats = {d: (np.zeros(m, dtype=np.int64), np.zeros(m), np.zeros(m)) for d in (1, -1)}
    groups = []
    for k in range(m):
        for d, name in ((1, "+1 (up)"), (-1, "-1 (down)")):
            sel = np.flatnonzero((label == k) & (direction == d))
            runs, first = np.unique(run[sel], return_index=True)
            if len(runs) != len(sel):
                dup = np.setdiff1d(np.arange(len(sel)), first)[0]
                raise InputError(f"axis {axis}: target {tgt_text(targets[k])}, dir {d:+d}, run "
                                 f"{run[sel][dup]} is read twice", path, row=int(row[sel][dup]))
            if len(sel) < 2:
                where = int(row[np.flatnonzero(label == k)[0]])
                raise InputError(f"axis {axis}: target {tgt_text(targets[k])} has {len(sel)} run(s) in "
                                 f"direction {name}; ISO 230-2 needs at least 2 per direction to "
                                 f"estimate the repeatability ({STANDARD_RUNS} in the standard cycle)",
                                 path, row=where)
            x = value[sel]
            groups.append((k, d, sel))
            stats[d][0][k] = len(sel)
            stats[d][1][k] = x.mean()
            stats[d][2][k] = x.std(ddof=1)
    n_up, mean_up, s_up = stats[1]
    n_down, mean_down, s_down = stats[-1]
    mean = (mean_up + mean_down) / 2.0
    reversal = mean_up - mean_down
    R_i_up, R_i_down = 4.0 * s_up, 4.0 * s_down
    R_i = np.maximum.reduce([2.0 * s_up + 2.0 * s_down + np.abs(reversal), R_i_up, R_i_down])
    outliers = flag_outliers(targets, groups, run, value, row, np.concatenate([s_up, s_down]))
    both = np.concatenate([mean_up, mean_down])
    hi = np.concatenate([mean_up + 2.0 * s_up, mean_down + 2.0 * s_down])
    lo = np.concatenate([mean_up - 2.0 * s_up, mean_down - 2.0 * s_down])
    return AxisPositioning(
        axis=axis, rotary=rotary, targets=targets, n_up=n_up, n_down=n_down, mean_up=mean_up,
        mean_down=mean_down, mean=mean, reversal=reversal, s_up=s_up, s_down=s_down, R_i_up=R_i_up,
        R_i_down=R_i_down, R_i=R_i,
        A=float(hi.max() - lo.min()),
        A_up=float((mean_up + 2 * s_up).max() - (mean_up - 2 * s_up).min()),
        A_down=float((mean_down + 2 * s_down).max() - (mean_down - 2 * s_down).min()),
        B=float(reversal[np.argmax(np.abs(reversal))]), B_mean=float(reversal.mean()),
        E=float(both.max() - both.min()), E_up=float(np.ptp(mean_up)), E_down=float(np.ptp(mean_down)),
        M=float(np.ptp(mean)), R=float(R_i.max()), R_up=float(R_i_up.max()), R_down=float(R_i_down.max()),
        outliers=outliers, readings={"target": target, "dir": direction, "run": run, "value": value},
        drift=run_drift(axis, label * 2 + (direction < 0), target, direction, run, value) if with_drift
        else None,
        unit_suspect=unit_check(rotary, targets, value))


def run_drift(axis: str, cell: np.ndarray, target: np.ndarray, direction: np.ndarray, run: np.ndarray,
              value: np.ndarray) -> RunDrift | None:
    """Run-to-run drift of one axis (:class:`RunDrift`): the additive model ``x = mu_cell + r_run``
    fitted by least squares and its F test against ``x = mu_cell``.

    cell : (n,) int label of each reading's (target, direction) cell; target, direction, run, value:
    as :func:`evaluate_axis`. None when there are fewer than 2 runs, no degree of freedom is left for
    the scatter, or the runs cannot be told from the cells (a run that shares no cell with the others).
    """
    import scipy.stats

    runs, r_index = np.unique(run, return_inverse=True)
    cells, c_index = np.unique(cell, return_inverse=True)
    n, c, N = len(runs), len(cells), len(value)
    df1, df2 = n - 1, N - c - n + 1
    if n < 2 or df2 < 1:
        return None
    # sum-to-zero coding of the runs: the last run's effect is minus the sum of the others
    coding = np.vstack([np.eye(n - 1), -np.ones((1, n - 1))])
    design = np.hstack([np.eye(c)[c_index], coding[r_index]])
    if np.linalg.matrix_rank(design) < c + n - 1:
        return None
    coef, *_ = np.linalg.lstsq(design, value, rcond=None)
    effect = coding @ coef[c:]
    ss_full = float(np.sum((value - design @ coef) ** 2))
    cell_mean = np.bincount(c_index, weights=value) / np.bincount(c_index)
    ss_cells = float(np.sum((value - cell_mean[c_index]) ** 2))
    # exact data (no scatter at all) would divide by zero: round-off level counts as zero
    zero = N * (1e-9 * float(np.abs(value).max())) ** 2
    if ss_full <= zero:
        F, p = (math.inf, 0.0) if ss_cells - ss_full > zero else (0.0, 1.0)
    else:
        F = ((ss_cells - ss_full) / df1) / (ss_full / df2)
        p = float(scipy.stats.f.sf(F, df1, df2))
    run_means = coef[:c].mean() + effect
    without = evaluate_axis(axis, target, direction, run, value - effect[r_index], with_drift=False)
    return RunDrift(runs=runs, run_means=run_means, size=float(np.ptp(run_means)),
                    trend=float(np.polyfit(runs.astype(float), run_means, 1)[0]),
                    within_s=math.sqrt(ss_full / df2), F=float(F), p=p,
                    drift=bool(p < DRIFT_ALPHA and np.ptp(run_means) >= MIN_DRIFT[
                        "rotary" if axis.upper() in "ABC" else "linear"]),
                    R_without=without.R)


def flag_outliers(targets, groups, run, value, row, s_all) -> tuple:
    """Readings that depart from the median of the other runs at their target and direction by more
    than OUTLIER_K s_ref sqrt(1 + pi / (2 (n - 1))), s_ref = median of ``s_all`` (module docstring).

    groups : (target index, dir, (n,) reading indices) per target and direction.
    """
    s_ref = float(np.median(s_all))
    if not s_ref > 0:
        return ()
    out = []
    for k, d, sel in groups:
        n = len(sel)
        if n < 3:
            continue
        x = value[sel]
        others = np.array([np.median(np.delete(x, i)) for i in range(n)])
        departure = x - others
        score = np.abs(departure) / (s_ref * math.sqrt(1.0 + math.pi / (2.0 * (n - 1))))
        for i in np.flatnonzero(score > OUTLIER_K):
            out.append(Outlier(float(targets[k]), int(d), int(run[sel][i]), float(x[i]),
                               float(departure[i]), float(score[i]), int(row[sel][i])))
    return tuple(out)


def evaluate_iso230_2(data) -> Iso230_2Report:
    """ISO 230-2 evaluation of a :class:`mtcomp.measurement.files.LaserData`, axis by axis.

    Only the positioning component of each axis (EXX, EYY, EZZ, EAA, EBB, ECC) is used; readings of
    other components are ignored and said so in ``notices``. InputError when the file holds no
    positioning readings or an axis lacks what the evaluation needs (see :func:`evaluate_axis`).
    """
    positioning = np.array([c == positioning_component(a) for a, c in zip(data.axis, data.component)],
                           dtype=bool)
    notices = []
    if (~positioning).any():
        others = sorted(set(data.component[~positioning]))
        notices.append(f"ignored {int((~positioning).sum())} readings of components {', '.join(others)} "
                       "(ISO 230-2 evaluates positioning only: EXX, EYY, EZZ, EAA, EBB, ECC)")
    if not positioning.any():
        raise InputError("no positioning readings (component EXX, EYY, EZZ, EAA, EBB or ECC) to "
                         "evaluate", data.path)
    axes = {}
    for axis in "XYZABC":
        sel = np.flatnonzero(positioning & (data.axis == axis))
        if not sel.size:
            continue
        res = evaluate_axis(axis, data.target[sel], data.dir[sel], data.run[sel], data.value[sel],
                            data.path, data.row[sel])
        fewest = int(min(res.n_up.min(), res.n_down.min()))
        if fewest < STANDARD_RUNS:
            notices.append(f"axis {axis}: as few as {fewest} runs per target and direction; the "
                           f"standard cycle has {STANDARD_RUNS}")
        if res.outliers:
            notices.append(f"axis {axis}: {len(res.outliers)} outlier reading(s) flagged (more than "
                           f"{OUTLIER_K:g} x the spread the repeatability allows from the median of "
                           "the other runs; kept in the figures, as the standard requires)")
        if len(res.targets) < 5:
            notices.append(f"axis {axis}: {len(res.targets)} targets; ISO 230-2 asks for at least 5")
        notices += [n for n in (res.unit_note(), res.drift_note()) if n]
        axes[axis] = res
    return Iso230_2Report(axes=axes, notices=tuple(notices), path=data.path)


def plot_runs(reports, path) -> None:
    """Write the PNG of :func:`runs_figure` to ``path``. Needs matplotlib."""
    import matplotlib.pyplot as plt

    fig = runs_figure(reports)
    with atomic_write(path, "wb") as fh:
        fig.savefig(fh, format="png", dpi=110)
    plt.close(fig)


def runs_figure(reports):
    """A matplotlib figure of the runs of every axis of ``reports`` (Iso230_2Report list), one row per
    axis. Left, as ISO 230-2 reports draw them: each run's passes drawn apart (one colour per run, up
    triangles and solid line, down triangles and dotted line), the mean unidirectional positional
    deviations of both directions with their +-2 s bands, the mean bidirectional deviation, and the
    flagged outliers ringed. Right: the mean of each run against its number (the run-to-run drift),
    with the band +-2 within-run s / sqrt(readings per run) that the run means keep to without drift,
    and the trend line when drift is detected. Lines carry gids ('run 3 up', 'run means') for tests.
    Needs matplotlib (imported here, not with mtcomp)."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise InputError("--plot needs matplotlib (pip install matplotlib)") from None
    panels = [(rep, ax) for rep in reports for ax in rep.axes.values()]
    fig, grid = plt.subplots(len(panels), 2, figsize=(11.0, 3.8 * len(panels)), squeeze=False,
                             gridspec_kw={"width_ratios": [3, 1]})
    for (rep, ax), (pl, pr) in zip(panels, grid):
        s, u = ax.scale, ax.unit
        f = 180.0 / math.pi if ax.rotary else 1.0
        tx = ax.targets * f
        r = ax.readings
        runs = np.unique(r["run"])
        colours = plt.get_cmap("viridis")(np.linspace(0.0, 0.85, len(runs)))
        for j, colour in zip(runs, colours):
            for d, marker, style, name in ((1, "^", "-", "up"), (-1, "v", ":", "down")):
                sel = (r["run"] == j) & (r["dir"] == d)
                order = np.argsort(r["target"][sel], kind="stable")
                pl.plot(r["target"][sel][order] * f, r["value"][sel][order] * s, marker=marker,
                        linestyle=style, color=colour, ms=4, lw=0.8, alpha=0.8, gid=f"run {j} {name}",
                        label=f"run {j}" if d == 1 else None)
        for d, colour, mean, sd, label in ((1, "tab:blue", ax.mean_up, ax.s_up, "up"),
                                           (-1, "tab:red", ax.mean_down, ax.s_down, "down")):
            pl.plot(tx, mean * s, "-", color=colour, lw=1.8, label=f"mean {label}")
            pl.fill_between(tx, (mean - 2 * sd) * s, (mean + 2 * sd) * s, color=colour, alpha=0.12,
                            label=f"mean +- 2 s, {label}")
        pl.plot(tx, ax.mean * s, "k--", lw=1, label="mean bidirectional")
        if ax.outliers:
            pl.plot([o.target * f for o in ax.outliers], [o.value * s for o in ax.outliers], "o", ms=10,
                    mfc="none", mec="k", label="outlier (flagged)")
        name = Path(rep.path).name if rep.path else ""
        pl.set_title(f"{name} axis {ax.axis}: A {ax.A * s:.2f}  B {ax.B * s:.2f}  E {ax.E * s:.2f}  "
                     f"R {ax.R * s:.2f} {u}", fontsize=9)
        pl.set_xlabel(f"target ({'deg' if ax.rotary else 'mm'})")
        pl.set_ylabel(f"deviation ({u})")
        pl.grid(alpha=0.3)
        # below the axes: inside, it hid the readings it explains
        pl.legend(fontsize=7, ncol=5, loc="upper center", bbox_to_anchor=(0.5, -0.24),
                  frameon=False)
        _draw_run_means(pr, ax, runs, colours)
    fig.tight_layout()
    return fig


def _draw_run_means(pr, ax: AxisPositioning, runs, colours) -> None:
    """The right-hand panel of :func:`runs_figure`: run means against run number."""
    s, u, dr = ax.scale, ax.unit, ax.drift
    pr.set_xlabel("run")
    pr.set_ylabel(f"run mean ({u})")
    pr.grid(alpha=0.3)
    if dr is None:
        pr.set_title("one run: no drift to compare", fontsize=9)
        return
    x = dr.runs.astype(float)
    centre = float(np.mean(dr.run_means))
    per_run = len(ax.readings["value"]) / len(dr.runs)
    band = 2.0 * dr.within_s / math.sqrt(per_run)
    pr.fill_between([x[0], x[-1]], [(centre - band) * s] * 2, [(centre + band) * s] * 2, color="0.5",
                    alpha=0.2, label="+- 2 s / sqrt(readings per run)")
    pr.plot(x, dr.run_means * s, "k-", lw=1, zorder=2, gid="run means", label="run mean")
    pr.scatter(x, dr.run_means * s, c=colours, s=36, zorder=3)
    if dr.drift:
        fit = np.polyval([dr.trend, centre - dr.trend * x.mean()], x)
        pr.plot(x, fit * s, "--", color="tab:orange", lw=1, label=f"trend {dr.trend * s:+.2f} {u}/run")
    pr.set_xticks(x)
    verdict = "drift" if dr.drift else "no drift detected"
    pr.set_title(f"{verdict}\nrange {dr.size * s:.2f} {u}, p = {dr.p:.1g}", fontsize=9)
    pr.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.24), frameon=False)

"""Readings that disagree with their own repeats: flagged, reported, and left out of a fit.

A repeat group is the set of readings of one file taken at the same set-up of the machine: the same
measured column, positions, approach directions, feed, tool and optic, in different runs. Within each
group with three or more readings, a reading's deviation from the group's median is compared with the
robust spread of all such deviations in the file (1.4826 times their median absolute value, the
normal-consistent MAD). A reading more than :data:`OUTLIER_K` robust standard deviations off is an
outlier: a glitch of the first run after homing, a bumped optic. It stays in the file and in every
report; a fit leaves it out and says which rows.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .files import LaserData, MeasurementSet, PointsData

#: robust standard deviations beyond which a reading is an outlier of its repeat group
OUTLIER_K = 5.0


@dataclass(frozen=True)
class Outlier:
    """One flagged reading: file, 1-based data row, column, value and its deviation from the median
    of its repeats, both in file units."""

    path: str
    row: int
    column: str
    value: float
    deviation: float

    def __str__(self):
        return (f"{self.path} row {self.row} {self.column} = {self.value:.4g} "
                f"({self.deviation:+.3g} off the median of its repeats)")


def setup_keys(data: MeasurementSet, directions: bool = True) -> np.ndarray | None:
    """(n,) integer id of each row's set-up (everything but the run, time and the reading): rows with
    the same id are repeats. ``directions=False`` leaves the approach directions out of the set-up
    (rows read at one target from both sides share an id). None for kinds without that structure
    (only laser and points files)."""
    if not isinstance(data, (LaserData, PointsData)):
        return None
    ctx = data.context
    parts = [np.round(np.nan_to_num(ctx.feed, nan=-1.0), 3)[:, None]]
    if directions:
        parts.append(ctx.dirs.astype(float))
    if isinstance(data, LaserData):
        parts += [np.unique(data.axis, return_inverse=True)[1][:, None].astype(float),
                  np.unique(data.component, return_inverse=True)[1][:, None].astype(float),
                  np.round(data.target, 9)[:, None]]
        if directions:
            parts.append(data.dir.astype(float)[:, None])
        parts += [np.round(np.nan_to_num(data.xyz, nan=-1e9), 6),
                  np.round(np.nan_to_num(data.abc, nan=-1e9), 9), np.round(data.optic, 6)]
    else:
        parts += [np.round(data.xyz, 6), np.round(data.abc, 9), np.round(np.nan_to_num(data.tool, nan=-1.0), 6)[:, None]]
    return row_groups(np.hstack(parts))


def row_groups(keys: np.ndarray) -> np.ndarray:
    """(n,) integer id of each row of ``keys`` (n, k): equal rows get equal ids, numbered in the
    rows' sorted order (what ``np.unique(keys, axis=0, return_inverse=True)`` gives, by a lexical
    sort of the columns, many times faster on large files)."""
    keys = np.asarray(keys, dtype=float)
    n = keys.shape[0]
    if n == 0:
        return np.zeros(0, dtype=int)
    order = np.lexsort(keys.T[::-1])
    s = keys[order]
    new = np.ones(n, dtype=bool)
    new[1:] = np.any(s[1:] != s[:-1], axis=1)
    ids = np.empty(n, dtype=int)
    ids[order] = np.cumsum(new) - 1
    return ids


def _flag(values: np.ndarray, groups: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(flag (n,), deviation from the group median (n,)) for one column of readings."""
    n = values.size
    dev = np.full(n, np.nan)
    ok = np.isfinite(values)
    for g in np.unique(groups[ok]):
        idx = np.flatnonzero(ok & (groups == g))
        if idx.size >= 3:
            dev[idx] = values[idx] - np.median(values[idx])
    have = np.isfinite(dev)
    flag = np.zeros(n, dtype=bool)
    # the median reading of an odd group is 0 off its own median: it says nothing of the spread
    spread = np.abs(dev[have])
    spread = spread[spread > 0]
    if spread.size < 6:
        return flag, dev
    scale = 1.4826 * float(np.median(spread))
    if scale > 0:
        flag[have] = np.abs(dev[have]) > OUTLIER_K * scale
    return flag, dev


def find_outliers(data: MeasurementSet) -> tuple[MeasurementSet, list[Outlier]]:
    """(the set with outlying readings blanked, the outliers). Kinds other than laser and points
    come back unchanged: they have no repeat structure to judge by."""
    groups = setup_keys(data)
    if groups is None or len(data) < 6:
        return data, []
    found: list[Outlier] = []
    if isinstance(data, LaserData):
        flag, dev = _flag(data.value, groups)
        if not flag.any():
            return data, []
        for i in np.flatnonzero(flag):
            scale = 1e6 if data.angular[i] else 1e3
            col = "value_urad" if data.angular[i] else "value_um"
            found.append(Outlier(str(data.path), int(data.row[i]), col, data.value[i] * scale, dev[i] * scale))
        return replace(data, value=np.where(flag, np.nan, data.value)), found
    deviation = data.deviation.copy()
    for j, col in enumerate(("dx_um", "dy_um", "dz_um")):
        flag, dev = _flag(deviation[:, j], groups)
        for i in np.flatnonzero(flag):
            found.append(Outlier(str(data.path), int(data.row[i]), col, deviation[i, j] * 1e3, dev[i] * 1e3))
        deviation[flag, j] = np.nan
    if not found:
        return data, []
    return replace(data, deviation=deviation), found

"""Approach directions of the machine's axes: the reader's rule, in one place.

An axis's approach direction at the end of a segment is the sign of its last move (+1, -1): an
axis that moves less than :data:`~.words.DIR_EPS` in a segment keeps the direction it had, and an
axis moving from a position the program has not given has no known direction (0) until its next
move. The reader (:mod:`.modal`) applies the rule to the program's steps (:func:`step_directions`).

Units: mm and rad; arrays (k, na) in ``machine.axis_names`` order, directions int8.
"""
from __future__ import annotations

import numpy as np

from .words import DIR_EPS


def step_signs(step: np.ndarray) -> np.ndarray:
    """The sign (int8: +1, -1, 0 for a move of at most DIR_EPS) of each step (mm, rad)."""
    return np.where(step > DIR_EPS, 1, np.where(step < -DIR_EPS, -1, 0)).astype(np.int8)


def held_directions(prev: np.ndarray, value: np.ndarray, sets: np.ndarray) -> np.ndarray:
    """(k, na) int8 directions after each of k segments: where ``sets`` (k, na) bool, the segment
    sets the axis's direction to ``value`` (k, na) int8; elsewhere the axis keeps the direction of
    the last segment that set it, before the first ``prev`` (na,) int8."""
    k = value.shape[0]
    last = np.where(sets, np.arange(k)[:, None], -1)
    np.maximum.accumulate(last, axis=0, out=last)
    cols = np.arange(value.shape[1])
    out = np.where(last >= 0, value[np.maximum(last, 0), cols], np.asarray(prev)[None, :])
    return out.astype(np.int8)


def step_directions(prev: np.ndarray, start: np.ndarray, pts: np.ndarray, fresh=None) -> np.ndarray:
    """(k, na) int8 approach directions at the end of each of the k segments from ``start`` (na,)
    through the points ``pts`` (k, na); ``prev`` (na,) int8 the directions before the first (not
    changed). ``fresh`` (na,) bool or None: axes moving from a position not given, whose direction
    is not known (0) until their next segment."""
    if pts.shape[0] == 1:                 # the common straight move, without array arithmetic
        cur = np.array(prev, np.int8)
        for j, (a, b) in enumerate(zip(start.tolist(), pts[0].tolist())):
            step = b - a
            if step > DIR_EPS:
                cur[j] = 1
            elif step < -DIR_EPS:
                cur[j] = -1
        if fresh is not None:
            cur[fresh] = 0
        return cur[None, :]
    value = step_signs(pts - np.vstack([start[None, :], pts[:-1]]))
    sets = value != 0
    if fresh is not None:
        sets[0, fresh] = True
        value[0, fresh] = 0
    return held_directions(prev, value, sets)


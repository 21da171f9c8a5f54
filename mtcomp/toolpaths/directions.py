"""Approach directions of the machine's axes: the one rule the reader and the machine frame share.

An axis's approach direction at the end of a segment is the sign of its last move (+1, -1): an
axis that moves less than :data:`~.words.DIR_EPS` in a segment keeps the direction it had, and an
axis moving from a position the program has not given has no known direction (0) until its next
move. The reader (:mod:`.modal`) applies the rule to the program's steps (:func:`step_directions`).

In tool centre point mode (:mod:`.tcp`) a program's X Y Z are the tool tip in the workpiece frame,
not axis positions: where a rotary axis turns the part, the tip moving one way can be a linear axis
moving the other. :class:`AxisDirections` takes the directions of the linear axes again, by the same
rule, from the axis positions the controller reaches (after the inverse kinematics), and carries
them into the rows after a TCP run until an axis moves again.

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


class AxisDirections:
    """The approach directions of the linear axes along one program in machine axis positions, in
    chunks in program order: the reader's where the program's words are axis positions, the axes'
    own in tool centre point rows (module docstring).

    linear : (na,) bool, the axes whose TCP words are not their positions (X, Y, Z).
    """

    def __init__(self, linear: np.ndarray):
        self.linear = np.asarray(linear, bool)
        na = self.linear.size
        self.reader = np.zeros(na, np.int8)    # the reader's directions at the last row
        self.axes = np.zeros(na, np.int8)      # the axes' directions there

    def chunk(self, dirs: np.ndarray, start: np.ndarray, end: np.ndarray, tcp: np.ndarray,
              stepped: np.ndarray) -> np.ndarray:
        """(n, na) int8 the directions of n rows. dirs : (n, na) the reader's. start, end : (n, na)
        the rows' machine axis positions (mm, rad). tcp : (n,) bool, TCP rows. stepped : (n,) bool,
        the TCP rows whose start and end are both axis positions (every axis given before and in
        the block); a TCP row that is not moves its linear axes from positions not known (0).
        Elsewhere an axis takes the reader's direction where it moves or where the reader's
        changed without a row (a home move, a fresh axis), and keeps the one it had otherwise."""
        n = len(dirs)
        if n == 0 or not (tcp.any() or np.any(self.reader != self.axes)):
            if n:
                self.reader, self.axes = np.array(dirs[-1], np.int8), np.array(dirs[-1], np.int8)
            return dirs
        lin = self.linear
        reader = np.asarray(dirs)[:, lin]
        value = step_signs(end[:, lin] - start[:, lin])
        sets = (value != 0) | (reader != np.vstack([self.reader[None, lin], reader[:-1]]))
        plain = ~tcp
        value[plain] = reader[plain]
        rows = tcp & stepped
        sets[rows] = value[rows] != 0
        rows = tcp & ~stepped
        sets[rows], value[rows] = True, 0
        out = np.array(dirs, np.int8)
        out[:, lin] = held_directions(self.axes[lin], value, sets)
        self.reader = np.array(dirs[-1], np.int8)
        self.axes = out[-1].copy()
        return out

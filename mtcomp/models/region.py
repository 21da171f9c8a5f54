"""The region a model's data reached (``FittedModel.support``) as bounds on the axis positions, and
the test of positions against it: one rule for compensate (a block outside is left uncorrected
unless the options extrapolate) and predict (a reading outside gets no standard error)."""
from __future__ import annotations

import numpy as np

from .chain import guideway_positions

#: slack of the support test (mm for linear axes, rad for rotary ones): a position this close to the
#: edge of the region the model's data reached counts as inside
SUPPORT_TOL = 1e-6
#: a rotary axis whose data reached all of a turn but a gap this wide (rad) counts as measured all
#: around: its profiles are periodic, so the gap is between data on both sides like any other
WRAP_GAP_RAD = np.radians(45.0)


def support_bounds(fitted) -> tuple[np.ndarray, np.ndarray] | None:
    """(lo, hi) each (na,), internal units: the region ``fitted`` (a FittedModel) says its data
    reached, +-inf for axes it does not limit (a rotary axis held at one angle: that angle only);
    None when the model does not say."""
    support = fitted.support
    if support is None:
        return None
    machine = fitted.machine
    na = machine.n_axes
    lo, hi = np.full(na, -np.inf), np.full(na, np.inf)
    held = fitted.held or {}
    for j, a in enumerate(machine.axis_names):
        if a in support:
            lo[j], hi[j] = support[a]
        elif a in held and machine.axis(a).is_rotary:
            lo[j] = hi[j] = held[a]              # measured at one angle only: no other is corrected
    for j, a in enumerate(machine.axes):
        # a rotary axis measured around its turn but for a gap of at most WRAP_GAP_RAD (sampled
        # every 10 deg from 0 to 350): its periodic profiles reach across the gap
        if a.is_rotary and np.isfinite(lo[j]) and 2 * np.pi - (hi[j] - lo[j]) <= WRAP_GAP_RAD:
            hi[j] = lo[j] + 2 * np.pi
    return lo, hi


def outside_bounds(machine, bounds, q, known=None, tool_length=None) -> np.ndarray:
    """(n, na) bool: the axes of the positions ``q`` ((n, na), mm and rad) that are given
    (``known``, (n, na) bool; None: all) and lie outside ``bounds`` (:func:`support_bounds`, with
    ``SUPPORT_TOL`` of slack; a rotary axis's angle taken modulo a turn, its error profiles being
    periodic); all False for ``bounds`` None. Each axis is tested where it stands on its guideway,
    as the region was recorded: the ram where the tool (``tool_length``, (n,) mm; None: the
    machine's) puts it (:func:`mtcomp.models.chain.guideway_positions`)."""
    q = np.asarray(q, dtype=float)
    if bounds is None:
        return np.zeros(q.shape, bool)
    q = guideway_positions(machine, q, tool_length)
    lo, hi = bounds
    rotary = np.array([a.is_rotary for a in machine.axes]) & np.isfinite(lo)
    if rotary.any():
        # an angle a turn away from one the data reached is that angle (C at 270 deg is C at -90)
        q = q.copy()
        q[:, rotary] = lo[rotary] - SUPPORT_TOL + np.mod(q[:, rotary] - lo[rotary] + SUPPORT_TOL,
                                                        2.0 * np.pi)
    out = (q < lo - SUPPORT_TOL) | (q > hi + SUPPORT_TOL)
    return out if known is None else known & out

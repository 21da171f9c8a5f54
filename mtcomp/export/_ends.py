"""Where a table ends: no correction beyond the span its data reached.

A controller holds a table's end values beyond it (LinuxCNC: the entries at -DBL_MAX and +DBL_MAX
take the first and last values, src/emc/motion/command.c, EMCMOT_SET_JOINT_COMP; Sinumerik: values
outside _MIN .. _MAX keep the end values). A table that stops where the data stop would so correct
the axis everywhere beyond them by its end value, where ``mtcomp compensate`` leaves a block
uncorrected (docs/planner.md, *Blocks that get no correction*): a C table of data over 0 .. 180 deg
applied its 180 deg value over the other half turn. So wherever the axis can stand beyond the span
(a linear axis whose data stop short of its travel; a rotary axis not measured around its turn, by
compensate's rule :data:`~mtcomp.models.region.WRAP_GAP_RAD`), the grid gets a point at or beyond
the span's end (the end value, as inside) and one grid step further a point of zero correction:
the table ramps to zero over that one step, outside the span, and is zero from there on (the
controller holds that zero). The ramp is the one stretch where the table corrects what the data
do not determine.
"""
from __future__ import annotations

import math

import numpy as np

from ..models.region import WRAP_GAP_RAD


def open_ends(machine, a: str, lo: float, hi: float) -> tuple[bool, bool]:
    """(low, high): whether axis ``a`` can stand beyond the span ``lo`` .. ``hi`` (mm, rad) at that
    end: where the span stops short of the axis's travel, unless the axis is rotary and the span
    covers its turn (but for a gap of at most WRAP_GAP_RAD, as compensate counts it)."""
    ax = machine.axis(a)
    if ax.is_rotary and 2.0 * math.pi - (hi - lo) <= WRAP_GAP_RAD + 1e-12:
        return False, False
    t_lo, t_hi = ax.travel
    tol = 1e-9 * max(1.0, abs(t_lo), abs(t_hi))
    return bool(lo > t_lo + tol), bool(hi < t_hi - tol)


def close_grid(g: np.ndarray, lo: float, hi: float, step: float, ends: tuple) -> np.ndarray:
    """The grid ``g`` (increasing) with, at each open end of ``ends`` (:func:`open_ends`), a point
    at or beyond the span's end ``lo`` / ``hi`` (when ``g`` has none) and a point one ``step``
    beyond that (when ``g`` has none beyond it: a grid through the reference position may)."""
    g = np.asarray(g, dtype=float)
    tol = 1e-9 * max(1.0, abs(lo), abs(hi))
    if ends[0]:
        at = g <= lo + tol
        first = g[at].max() if at.any() else g[0] - step
        if not (g < first - tol).any():
            g = np.r_[first - step, first, g[g > first + tol]]
    if ends[1]:
        at = g >= hi - tol
        last = g[at].min() if at.any() else g[-1] + step
        if not (g > last + tol).any():
            g = np.r_[g[g < last - tol], last, last + step]
    return g


def points_inside(g: np.ndarray, lo: float, hi: float) -> int:
    """How many points of the grid ``g`` lie in the span ``lo`` .. ``hi`` (a table needs two)."""
    tol = 1e-9 * max(1.0, abs(lo), abs(hi))
    g = np.asarray(g, dtype=float)
    return int(np.count_nonzero((g >= lo - tol) & (g <= hi + tol)))


def beyond_span(positions: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """(n,) bool: the points past the last point at or beyond each end of the span ``lo`` .. ``hi``
    (the points where the table is zero: :func:`close_grid`)."""
    p = np.asarray(positions, dtype=float)
    tol = 1e-9 * max(1.0, abs(lo), abs(hi))
    below, above = p[p <= lo + tol], p[p >= hi - tol]
    first = below.max() if below.size else p[0]
    last = above.min() if above.size else p[-1]
    return (p < first - tol) | (p > last + tol)


def ends_sentence(t) -> str:
    """What the AxisTable ``t`` holds beyond the data's region (when any of its points lie there)."""
    u, f = ("deg", 180.0 / math.pi) if t.rotary else ("mm", 1.0)
    lo, hi = t.data_region
    zero = beyond_span(t.positions, lo, hi)
    held = t.held & ~zero
    live = np.flatnonzero(~zero)
    p = t.positions
    ramps = [p[live[0]] - p[live[0] - 1]] if live[0] > 0 else []
    ramps += [p[live[-1] + 1] - p[live[-1]]] if live[-1] < len(p) - 1 else []
    text = f"the data reach {lo * f:g} .. {hi * f:g} {u}"
    if held.any():
        text += f"; the {int(held.sum())} point(s) just past them hold the value at the nearest end"
    if zero.any():
        text += (f"; beyond them the table ramps to zero over one grid step "
                 f"({max(ramps, default=0.0) * f:g} {u}) and is zero from there on "
                 f"({int(zero.sum())} point(s)), as compensate corrects nothing there: the ramp is "
                 "where the table corrects what the data do not determine")
    return text

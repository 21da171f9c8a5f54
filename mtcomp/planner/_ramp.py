"""Nodes that let the step bound ramp a correction in along the move that enters it.

A block that gets no correction (outside the region the model's data reached, an axis the program
has not given, a correction too uncertain or not told from zero) followed by a feed move that needs
one: the step bound (``max_step`` per output block) ramps the correction in from zero, and with the
move's end as its only node the rest of the ramp fell on the blocks after it, in the cut. A quality
engineer's pocket: ``G0 Z20.`` above the data (no correction), the plunge ``G1 Z-4. F250.``
needing 11 um in X and Z: 5 um at the plunge's bottom, 10 um at the end of the first wall, which
was cut tilted (its X error falling from 5.6 to -0.8 um along it on their own simulator).

So that move gets nodes of its own, as many as the step bound needs to reach the correction its
end wants (``ceil(largest |correction| / step) - 1``): the first where the move enters the region
(the part before it is outside and can carry none), the others evenly from there to its end. The
ramp then ends where the move ends, and the cut after it is corrected whole; the nodes are in the
move, which the summary counts as blocks in the cut that carry a ramp. A rapid, a hole, a move from
a position the program has not given have no step bound into them and need none (the correction
jumps during the rapid).
"""
from __future__ import annotations

import numpy as np

#: at most this many nodes per move (a correction over 100 step bounds is a bound's matter)
MAX_RAMP_NODES = 100
#: the entry into the region is found on this many points along the move, then by halving
_SAMPLES, _HALVINGS = 32, 10


def entry_rows(x_end: np.ndarray, step: np.ndarray, pinned: np.ndarray, prev_pinned: bool,
               exempt: np.ndarray, skip: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(rows, k): the moves that follow a block left uncorrected (``pinned``; ``prev_pinned`` for
    the row before the first) with the step bound into them (not ``exempt``) and no reason of their
    own to stay as they are (not ``skip``), whose free correction at the end ``x_end`` (n, na)
    exceeds the step bound ``step`` (na,) on some axis; ``k`` the nodes each needs."""
    n = x_end.shape[0]
    if n == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    before = np.empty(n, bool)
    before[0] = prev_pinned
    before[1:] = pinned[:-1]
    rows = np.flatnonzero(before & ~exempt & ~skip)
    if rows.size == 0:
        return rows, rows
    axes = step > 0
    ratio = np.max(np.abs(x_end[np.ix_(rows, np.flatnonzero(axes))]) / step[axes], axis=1,
                   initial=0.0)
    k = np.minimum(np.ceil(ratio - 1e-9).astype(np.int64) - 1, MAX_RAMP_NODES)
    keep = k > 0
    return rows[keep], k[keep]


def entry_parameters(rows: np.ndarray, k: np.ndarray, start: np.ndarray, end: np.ndarray,
                     outside) -> tuple[np.ndarray, np.ndarray]:
    """(rows_i, t_i): the nodes of the moves ``rows`` (``k`` each) at their parameters along the
    move start -> end: the first where it enters the region (``outside(q, rows)`` (m,) bool: the
    points q (m, na) of the moves ``rows`` (m,) that get no correction), the others evenly to its
    end; a move that starts inside gets them evenly over its whole length."""
    out_rows, out_t = [], []
    for r, m in zip(rows.tolist(), k.tolist()):
        t_in = _entry(r, start[r], end[r], outside)
        if t_in is None:
            continue
        t = (t_in + (1.0 - t_in) * np.arange(m) / m if t_in > 0.0
             else np.arange(1, m + 1) / (m + 1.0))
        t = t[(t > 0.0) & (t < 1.0)]
        out_rows.append(np.full(t.size, r, np.int64))
        out_t.append(t)
    if not out_rows:
        return np.zeros(0, np.int64), np.zeros(0)
    return np.concatenate(out_rows), np.concatenate(out_t)


def _entry(r: int, s: np.ndarray, e: np.ndarray, outside) -> float | None:
    """Where along the move s -> e (row r) the points start to get a correction: 0 where its start
    does, the first such parameter (found on _SAMPLES points, then by halving) otherwise; None
    where its end is the first."""
    t = np.linspace(0.0, 1.0, _SAMPLES + 1)
    out = outside(s + t[:, None] * (e - s), np.full(t.size, r))
    if not out[0]:
        return 0.0
    inside = np.flatnonzero(~out[1:-1]) + 1
    if inside.size == 0:
        return None
    lo, hi = float(t[inside[0] - 1]), float(t[inside[0]])
    for _ in range(_HALVINGS):
        mid = 0.5 * (lo + hi)
        if outside((s + mid * (e - s))[None, :], np.array([r]))[0]:
            lo = mid
        else:
            hi = mid
    # a micrometre on, so that the node rounded to the output grid stays inside
    length = float(np.sqrt(np.sum((e - s) ** 2)))
    return min(hi + 1e-3 / length, 1.0) if length > 0.0 else None


def ramp_nodes(planner, chunk, start, end, x_end, pinned, exempt, skip, ctx, ref):
    """(rows, (rows_i, t_i, q_i, lin_i) or None): the straight moves of ``chunk`` (not chords of
    an arc, which carry a ramp as blocks) given ramp nodes and their nodes, as
    :meth:`~.engine.Planner._subdivide` gives its own (see the module docstring); ``pinned`` the
    rows left uncorrected for good (not a contour's rows the gate may yet correct whole: the row
    after one in its contour is in ``skip`` anyway); ``planner``'s ``_ramp_prev`` carries whether
    the last row of the last chunk was left uncorrected."""
    prev, planner._ramp_prev = planner._ramp_prev, bool(pinned[-1]) if len(pinned) else \
        planner._ramp_prev
    if planner.problem.step_across_rapids or not planner.options.ramp_nodes:
        return np.zeros(0, np.int64), None
    if chunk.from_arc is not None:
        skip = skip | np.asarray(chunk.from_arc, bool)
    rows, k = entry_rows(x_end, planner.bounds.S, pinned, prev, exempt, skip)
    if rows.size == 0:
        return rows, None
    known = np.asarray(chunk.known, bool)
    lengths = None if chunk.tool_length is None else np.asarray(chunk.tool_length)

    def outside(q, r):       # rows r are not pinned (skip): only the support leaves their points
        out = planner.outside_support(q, known[r], None if lengths is None else lengths[r])
        return planner.ram.whole_outside(out)

    rows_i, t_i = entry_parameters(rows, k, start, end, outside)
    if rows_i.size == 0:
        return rows, None
    q_i = planner.bounds.snap(start[rows_i] + t_i[:, None] * (end[rows_i] - start[rows_i]))
    return rows, (rows_i, t_i, q_i, planner._solve_free(q_i, ctx[rows_i], ref[rows_i]))


def merged(inner, ramp):
    """The internal nodes of the midpoint test (``inner``) and the ramp's, as one tuple (or None)."""
    if ramp is None or inner is None:
        return inner if ramp is None else ramp
    from ._pointwise import Linearization
    return (np.concatenate([inner[0], ramp[0]]), np.concatenate([inner[1], ramp[1]]),
            np.concatenate([inner[2], ramp[2]]), Linearization.concatenate([inner[3], ramp[3]]))

"""Bounds of the corrections, in optimisation units (um, urad), and the exact enforcement on the output.

Per block and axis: ``|x| <= B`` (max correction), ``lo <= q + x / scale <= hi`` (travel), and between
consecutive blocks ``|x_i - x_(i-1)| <= S`` (max step; not into the end of a rapid unless the problem
says so), and the link bounds of :mod:`._links` on the same differences (a correction that keeps each
axis's direction where the model's error depends on it; one correction along an arc under cutter
radius compensation; the offset plane's corrections held or limited under it). With an output grid
every bound is first rounded inwards to whole grid steps; corrections
rounded to the nearest grid step then keep every bound (rounding is monotone and commutes with
shifts by whole steps), and :meth:`Bounds.enforce` makes sure of it, clamping what a method without
bounds (pinv, newton) produced and saying which bound acted.
"""
from __future__ import annotations

import numpy as np

from ._small import any_rows, column_extremes, down_columns
from .problem import CompensationProblem

#: the kinds of bound, in the order of the flag array's last axis
FLAG_KINDS = ("max", "min", "travel_max", "travel_min", "step", "reversal", "arc", "crc", "standing")
#: the kinds that can hold an axis's whole correction where the block asks for one: the travel
#: and the link bounds (an axis one of them leaves at zero keeps its whole error). Not the step
#: bound, whose ramp only passes zero, nor the correction bound, zero only where the axis gets no
#: correction by design (a rotary axis the model's data held at one angle), nor the standing
#: rule's (a rotary axis the program does not move keeps its correction; the linear axes take the
#: tip: the summary says so on a line of its own)
HOLDING = np.array([kind in ("travel_max", "travel_min", "reversal", "arc", "crc")
                    for kind in FLAG_KINDS])
INF = 1e30
#: kinds of link bound (:mod:`._links`), as stored per node and axis (0: none)
REVERSAL, ARC, STANDING, CRC = 1, 2, 3, 4


def flag_name(kind: str, axis: str) -> str:
    """Column text of one active bound: cx_max, cx_min, travel_x_max, travel_x_min, step_x,
    reversal_x (the correction held so that X keeps its direction), arc_x (one correction along an
    arc under cutter radius compensation), standing_c (a rotary axis the program does not move
    there, outside tool centre point mode, keeps the correction it has: its word is not written),
    crc_x (under cutter radius compensation, an axis of the offset plane held at the correction
    of the block before, or changed by no more than turns the block by CRC_TURN: :mod:`._links`)."""
    a = axis.lower()
    return {"max": f"c{a}_max", "min": f"c{a}_min", "travel_max": f"travel_{a}_max",
            "travel_min": f"travel_{a}_min", "step": f"step_{a}", "reversal": f"reversal_{a}",
            "arc": f"arc_{a}", "standing": f"standing_{a}", "crc": f"crc_{a}"}[kind]



def _round_to(x, step):
    """x rounded to whole multiples of step (a new array; in place from the division on)."""
    t = down_columns(np.divide, x, step)
    np.round(t, out=t)
    return down_columns(np.multiply, t, step, out=t)

def _one_row(a: np.ndarray) -> np.ndarray:
    """a (n, m), or its first row (1, m) when a is one row broadcast over n (:meth:`Bounds.limits_lazy`):
    what a comparison with a needs, without making the broadcast whole."""
    return a[:1] if a.ndim == 2 and a.shape[0] > 1 and a.strides[0] == 0 else a


class Bounds:
    """Bounds of one problem. Everything in optimisation units: um (linear), urad (rotary)."""

    def __init__(self, problem: CompensationProblem):
        self.problem = problem
        self.D = problem.axis_scale
        self.lo, self.hi = problem.travel()
        self.grid = None if problem.grid is None else np.asarray(problem.grid, dtype=float)
        # u: the unit of the clamp; whole numbers of grid steps with a grid, plain x otherwise
        self.unit = np.ones(problem.n_axes) if self.grid is None else self.grid * self.D
        # how far a correction must be from the one wanted to count as taken away by a bound, and
        # how close to a bound counts as on it
        self.took_tol = 0.5 * self.unit + 1e-9 if self.grid is not None else np.full(len(self.D), 1e-4)
        self.on_tol = 1e-9 * self.unit if self.grid is not None else np.full(len(self.D), 1e-6)
        self.B = self._floor(problem.max_correction * self.D)
        self.S = self._floor(problem.max_step * self.D)
        #: (na,) bool, the axes whose correction bound is zero (--max-correction-urad 0, a rotary
        #: axis the model's data held at one angle): no correction by design, that bound named
        self._none = np.broadcast_to(self.B <= 0, (problem.n_axes,))

    def _floor(self, x):
        if self.grid is None:
            return np.asarray(x, dtype=float)
        t = np.divide(x, self.unit)         # in place from here: fewer large temporaries
        t += 1e-6
        np.floor(t, out=t)
        t *= self.unit
        return t

    def _ceil(self, x):
        if self.grid is None:
            return np.asarray(x, dtype=float)
        t = np.divide(x, self.unit)
        t -= 1e-6
        np.ceil(t, out=t)
        t *= self.unit
        return t

    def snap(self, q: np.ndarray) -> np.ndarray:
        """Nominal positions rounded to the output grid (mm, rad): the program as written."""
        if self.grid is None:
            return np.asarray(q, dtype=float)
        return _round_to(q, self.grid)

    def travel_x(self, q):
        """(lo, hi) each (n, na): the travel as bounds of the correction x."""
        lo = np.subtract(self.lo, q)
        lo *= self.D
        hi = np.subtract(self.hi, q)
        hi *= self.D
        return self._ceil(lo), self._floor(hi)

    def box(self, q, pinned=None):
        """(l, u) each (n, na): max correction and travel together."""
        return self.limits(q, pinned)[:2]

    def limits(self, q, pinned=None):
        """(l, u, travel_lo, travel_hi), each (n, na): box bounds and the travel part of them.
        pinned : (n,) bool or None, blocks that get no correction (l = u = 0); (n, na): their axes
        that get none (:meth:`~._nodes.NodeSet.box_pins`)."""
        tlo, thi = self.travel_x(q)
        l, u = np.maximum(-self.B, tlo), np.minimum(self.B, thi)
        if pinned is not None and np.any(pinned):
            l[pinned] = 0.0
            u[pinned] = 0.0
        return l, u, tlo, thi

    def limits_lazy(self, q, pinned=None):
        """As :meth:`limits`, but where the travel is nowhere tighter than the correction bound
        (the usual case) ``(-B, B, None, None)`` as read-only broadcasts, the travel part left for
        :meth:`enforce` to compute if it needs it: the same l and u (the travel bounds of x fall
        with q, so those of the per-axis extremes of q bound every node's)."""
        if q.shape[0] == 0 or (pinned is not None and np.any(pinned)):
            return self.limits(q, pinned)
        q_min, q_max = column_extremes(q)
        tlo, _ = self.travel_x(q_min[None, :])
        _, thi = self.travel_x(q_max[None, :])
        if np.all(tlo[0] <= -self.B) and np.all(thi[0] >= self.B):
            return (np.broadcast_to(-self.B, q.shape), np.broadcast_to(self.B, q.shape), None, None)
        return self.limits(q)

    def quantize(self, x):
        """Corrections (scaled units) rounded to whole output-grid steps (a copy)."""
        if self.grid is None:
            return np.array(x, dtype=float)
        return _round_to(x, self.unit)

    def _quantize_runs(self, x, links):
        """:meth:`quantize`, but on a grid coarser than the millimetre one (inch programs: 0.254 um,
        more than twice the never-worse rows' room) a run of nodes tied into one correction (an arc
        under cutter radius compensation, its start included) is rounded towards zero: its
        correction sits on the never-worse rows of its tightest node, which the nearest grid step
        can overstep, while every node's rows hold between zero and the planned correction."""
        y = self.quantize(x)
        if links is None or self.grid is None:
            return y
        coarse = self.unit > 0.1 + 1e-9
        arc = np.any(links[2] == ARC, axis=1)
        if not coarse.any() or not arc.any():
            return y
        rows = arc.copy()
        rows[:-1] |= arc[1:]
        sel = np.ix_(rows, coarse)
        t = np.divide(x[sel], self.unit[coarse])
        y[sel] = np.trunc(t + np.sign(t) * 1e-6) * self.unit[coarse]
        return y

    def enforce(self, x, q, exempt, prev, desired=None, following=None, limits=None, planned=None,
                links=None):
        """The written corrections and the bounds that acted.

        x : (n, na) corrections found (x units). q : (n, na) nominal positions (mm, rad).
        exempt : (n,) bool, no step bound into this block. prev : (na,) correction of the block
        before (x units), or None. desired : (n, na) the corrections the blocks would take without
        bounds (default x), to tell which bounds acted. following : (na,) correction of the block
        after when it is known and not exempt, else None. limits : :meth:`limits` of q if known.
        planned : (n, na) the plan before its rotary corrections were rounded and its linear ones
        solved again for them, or None: a step it put on its bound is named too (the re-solve can
        move the written pair off the bound, the ramp being the step bound's all the same).
        links : (lo, hi, kind) each (n, na), the link bounds of x_i - x_(i-1) (:mod:`._links`), or
        None; they apply into every block but the first of a program, and the box wins over them.

        Returns (y (n, na) on the grid, flags (n, na, len(FLAG_KINDS)) bool): a flag is set where
        y sits on that bound and differs from ``desired`` by more than half a grid step (the bound
        took something away); ``step`` also where the step to the next block is on its bound.
        """
        desired = x if desired is None else desired
        l, u, tlo, thi = self.limits(q) if limits is None else limits
        base = self._quantize_runs(x, links)          # a new array: clipped in place
        # np.clip's arithmetic (the larger of base and l, then the smaller of that and u), on one
        # row of a broadcast bound
        down_columns(np.maximum, base, _one_row(l), out=base)
        down_columns(np.minimum, base, _one_row(u), out=base)
        y = base.copy()
        n = y.shape[0]
        tol = 1e-9 * np.maximum(self.unit, 1.0)
        start = 0
        while True:
            j = self._next_violation(y, exempt, prev, start, tol, links)
            if j is None:
                break
            while j < n:
                before = y[j - 1] if j > 0 else prev
                if exempt[j] or before is None:
                    new = base[j]
                else:
                    new = np.clip(np.clip(base[j], before - self.S, before + self.S), l[j], u[j])
                if links is not None and before is not None:
                    new = np.clip(np.clip(new, before + links[0][j], before + links[1][j]), l[j], u[j])
                unchanged = np.all(new == base[j])
                y[j] = new
                if unchanged:
                    break
                j += 1
            start = j + 1
        flags = np.zeros((n, y.shape[1], len(FLAG_KINDS)), bool)
        took = np.subtract(desired, y)
        np.abs(took, out=took)
        took = down_columns(np.greater, took, self.took_tol)
        if not took.any():          # every flag needs the bound to have taken something away
            return y, flags
        if tlo is None:             # limits_lazy: the travel part was not computed
            tlo, thi = self.travel_x(q)
        tol = self.on_tol
        flags[..., 0] = took & (y >= self.B - tol)
        flags[..., 1] = took & (y <= -self.B + tol)
        flags[..., 2] = took & (y >= thi - tol)
        flags[..., 3] = took & (y <= tlo + tol)
        prev_rows = np.vstack([prev[None, :] if prev is not None else y[:1], y[:-1]]) if n else y
        has_prev = ~exempt.copy()
        if prev is None and n:
            has_prev[0] = False
        flags[..., 4] = took & self._on_step(y, prev_rows, has_prev, exempt, following, tol)
        if planned is not None:
            pp = np.vstack([prev[None, :] if prev is not None else planned[:1], planned[:-1]])
            flags[..., 4] |= took & self._on_step(planned, pp, has_prev, exempt, None, tol)
        if links is not None:
            self._link_flags(flags, took, y, prev_rows, prev is not None, links, tol, desired)
        if self._none.any():
            self._zero_bound_flags(flags, desired, y)
        return y, flags

    def _zero_bound_flags(self, flags, desired, y):
        """An axis whose correction bound is zero (no correction by design) names that bound alone,
        on the side its correction wanted to go (at zero it sits on both): not its step bound
        (zero too) nor the standing rule, which take nothing from it."""
        nz = self._none
        up = desired[:, nz] > y[:, nz]
        flags[:, nz, 0] &= up
        flags[:, nz, 1] &= ~up
        flags[:, nz, FLAG_KINDS.index("step")] = False
        flags[:, nz, FLAG_KINDS.index("standing")] = False

    def _link_flags(self, flags, took, y, prev_rows, has_prev, links, tol, desired):
        """Set the reversal, arc and standing flags: the bound took something away and the change
        of the correction into the block sits on the link bound, or the change out of it to the
        next block sits on that block's link bound on the side this block's correction wanted to
        go (the block before one where X stands after a +X move: its correction can be no larger
        than the one X stands with there)."""
        lo, hi, kind = links
        d = y - prev_rows
        at_lo, at_hi = np.abs(d - lo) <= tol + 1e-6, np.abs(d - hi) <= tol + 1e-6
        on = at_lo | at_hi
        if not has_prev and y.shape[0]:
            on[0] = False
        want = desired[:-1] - y[:-1]
        out = (at_lo[1:] & (want > 0)) | (at_hi[1:] & (want < 0))
        for name, k in (("reversal", REVERSAL), ("arc", ARC), ("standing", STANDING), ("crc", CRC)):
            f = flags[..., FLAG_KINDS.index(name)]
            f[:] = took & on & (kind == k)
            f[:-1] |= took[:-1] & out & (kind[1:] == k)

    def _on_step(self, y, prev_rows, has_prev, exempt, following, tol):
        """(n, na) bool: the step into a block (from prev_rows) or out of it to the next is on its
        bound: a block held back by the step bound (a ramp into a bound) either way."""
        n = y.shape[0]
        step_in = has_prev[:, None] & (np.abs(y - prev_rows) >= self.S - tol)
        step_out = np.zeros_like(step_in)
        if n > 1:
            step_out[:-1] = ~exempt[1:, None] & (np.abs(y[1:] - y[:-1]) >= self.S - tol)
        if n and following is not None:
            step_out[-1] = np.abs(following - y[-1]) >= self.S - tol
        return step_in | step_out

    def _next_violation(self, y, exempt, prev, start, tol, links=None, block=8192):
        n = y.shape[0]
        s = max(start, 0)
        while s < n:
            e = min(n, s + block)
            if s == 0:
                if prev is None:
                    before = np.vstack([y[:1], y[:e - 1]])
                    ok0 = np.ones(1, bool)
                else:
                    before = np.vstack([prev[None, :], y[:e - 1]])
                    ok0 = None
            else:
                before = y[s - 1:e - 1]
                ok0 = None
            d = y[s:e] - before
            viol = any_rows(down_columns(np.greater, np.abs(d), self.S + tol))
            viol &= ~exempt[s:e]
            if links is not None:
                viol |= any_rows((d < links[0][s:e] - tol) | (d > links[1][s:e] + tol))
            if ok0 is not None and s == 0:
                viol[0] = False
            idx = np.flatnonzero(viol)
            if idx.size:
                return s + int(idx[0])
            s = e
        return None

    def feasible(self, x, l, u, exempt, prev, tol=1e-9, links=None):
        """True if corrections x (n, na) keep box bounds l, u, the step bound (from prev too) and
        the link bounds ``links`` ((lo, hi, kind) of :mod:`._links`, or None)."""
        return self.first_violation(x, l, u, exempt, prev, tol, links) is None

    def first_violation(self, x, l, u, exempt, prev, tol=1e-9, links=None) -> int | None:
        """The first block whose correction (x (n, na)) breaks its box bounds l, u, the step bound
        from the block before it (from prev for the first) or its link bounds ``links``, or None
        when every block keeps them."""
        n = x.shape[0]
        bad = any_rows(down_columns(np.less, x, _one_row(l) - tol))
        bad |= any_rows(down_columns(np.greater, x, _one_row(u) + tol))
        if n > 1:
            d = np.diff(x, axis=0)
            np.abs(d, out=d)
            step = any_rows(down_columns(np.greater, d, self.S + tol))
            step &= ~exempt[1:]
            bad[1:] |= step
        if prev is not None and n and not exempt[0]:
            bad[0] |= bool(np.any(np.abs(x[0] - prev) > self.S + tol))
        if links is not None and n:
            d = np.diff(np.vstack([x[:1] if prev is None else prev[None, :], x]), axis=0)
            bad |= any_rows(d < links[0] - tol)
            bad |= any_rows(d > links[1] + tol)
        return int(np.argmax(bad)) if bad.any() else None

"""The planner: output blocks (nodes), their corrections, streamed through a program of any length.

Flow per :class:`~mtcomp.toolpaths.SegmentChunk`:

1. nodes: the end of every segment (nominal positions rounded to the output grid), and internal
   nodes in feed moves where the corrected path would miss its midpoint by more than
   ``subdivide_tol_um`` (recursively); each node gets its block context (feed, approach direction of
   every axis, tool length; the approach direction of the nominal motion, also for the corrected one);
2. per node the correction without bounds (``pinv``: one step of Qi and Yang (2016); ``newton`` and ``qp``:
   iterated to convergence);
3. ``qp``: windows of ``window`` nodes plus ``overlap`` nodes of look-ahead; a window whose unbounded
   solution keeps every bound (the anchor included) is that solution; otherwise OSQP solves the
   window's bounded problem, re-linearised until the corrections change by less than
   ``step_tol_um``. The first node of a window is the previous window's last committed node, fixed.
   ``pinv`` and ``newton`` clamp their result to the bounds instead;
4. the corrections are rounded to the output grid, every bound is enforced exactly, the bounds that
   acted are recorded, and the predicted deviation after correction is computed.

Memory holds at most two chunks and one window, whatever the length of the program.
"""
from __future__ import annotations

import time
from collections import deque
from typing import Iterable, Iterator

import numpy as np

from ._bounds import HOLDING, INF, Bounds
from ._contours import ContourGate
from ._evaluate import Evaluator, objective_residual
from ._grouped import GroupedQP, tied
from ._interleave import placed, positions
from ._links import LinkRules, run_start, standing_axes, undirected_axes
from ._local_qp import LazyQP, solve_stretches
from ._nodes import NodeSet
from ._parallel import read_ahead, resolve_threads, split_rows
from ._pointwise import Linearization, solve_newton, solve_pinv
from ._qp import WindowQP, never_worse_rows, prefetch_solver, reachable_nodes
from ._ramp import merged, ramp_nodes
from ._datum import DatumRule
from ._direction import DirectionRule, note_unsure, unsure_rows
from ._ram import RamRule
from ._result import PlanResult, as_list, first_rows
from ._rotary_grid import rotary_columns, round_rotary, solve_with_rotary_fixed
from ._partial import PartialRule
from ._small import a_x, any_rows, at_b, down_columns, gram, row_max_abs, row_norm
from .problem import CompensationProblem, PlannerOptions
from ..models.region import outside_bounds, support_bounds


class Planner:
    """Plans the corrections of a stream of output blocks for one problem (see module docstring).

    The planner keeps state between chunks (the last committed correction, the OSQP problems of
    each window size); use one Planner per program.
    """

    def __init__(self, problem: CompensationProblem, options: PlannerOptions | None = None,
                 source: str | None = None):
        self.problem = problem
        self.options = options or PlannerOptions()
        self.source = source
        self.ev = Evaluator(problem)
        self.bounds = Bounds(problem)
        self.machine = problem.machine
        self.na = self.machine.n_axes
        self._rotary = rotary_columns(self.machine)
        self._qps: dict[tuple[int, int], WindowQP] = {}
        self._prev: np.ndarray | None = None        # last committed correction (x units)
        self._last_end: tuple | None = None         # (q, x_free) of the last node of the last chunk
        self._after_cycle = False                   # the last row of the last chunk was a hole
        self._ramp_prev = False                     # ... was left uncorrected (_ramp)
        self._buffer: list[tuple[NodeSet, Linearization]] = []
        self._done = 0
        self._last_progress = time.monotonic()
        self.stats = {"windows": 0, "windows_qp": 0, "qp_solves": 0, "qp_status": {}}
        self.threads = resolve_threads(self.options.threads)
        #: (lo, hi) each (na,): the model's support, +-inf for axes it does not limit; None: unknown
        self.support = support_bounds(problem.fitted)
        #: a block whose ram alone is outside the support has its other axes corrected (:mod:`._ram`)
        self.ram = RamRule(self.machine, self.options.extrapolate, self.support,
                           problem.fitted.info.get("tool_length_mm"))
        self._split = self.threads          # parts a chunk's per-block work is cut into
        #: the link bounds (:mod:`._links`): each axis keeps the direction the model evaluated it
        #: with, one correction along an arc under cutter radius compensation
        self.links = LinkRules(problem, self.bounds)
        #: the standard-error gate acts per contour (:mod:`._contours`)
        self.gate = ContourGate(self.options.max_correction_sd_um, self.ev.has_uncertainty)
        #: a part's datum outside the support leaves the blocks referenced to it unsure (:mod:`._datum`)
        self.datum = DatumRule(self)
        self.direction = DirectionRule(self)      # an approach its data never read (_direction)
        #: a tool axis the data do not determine is not corrected (:mod:`._partial`)
        self.partial = PartialRule(problem, self.options.max_correction_sd_um)

    # ------------------------------------------------------------------ nodes
    def _context(self, feed, dirs, n, tool_length=None, extra=None):
        """(n, n_context) the blocks' context: feed, approach directions, tool lengths and the
        chunk's further columns (``extra``: name -> (n,), e.g. temperatures along the run)."""
        cols = dict(extra or {})
        cols["feed"] = feed
        for j, a in enumerate(self.machine.axis_names):
            cols[f"dir_{a}"] = dirs[:, j].astype(float)
        if tool_length is not None:
            cols["tool_length"] = tool_length
        return self.problem.fitted.context(n, cols)

    def outside_support(self, q, known, tool_length=None) -> np.ndarray:
        """(n, na) bool: the axes of the blocks at ``q`` ((n, na) axis positions, mm and rad) whose
        position is given (``known``, (n, na) bool) and lies outside the region the model's data
        reached (:attr:`support`: :func:`mtcomp.models.region.outside_bounds`; the ram where the
        block's tool, ``tool_length`` (n,) mm or None for the machine's, puts it); all False when
        the model does not say where its data reached. A block with such an axis is left
        uncorrected unless the options extrapolate."""
        return self.ram.widen(outside_bounds(self.machine, self.support, q, known, tool_length), q,
                              known)

    def block_status(self, q, known, feed, dirs, datum=None, tool_length=None):
        """What the planner's rules say of each block, before any correction is planned.

        q : (n, na) nominal axis positions, mm and rad. known : (n, na) bool, the program has given
        that axis's position. feed : (n,) mm/min (NaN: the model's default). dirs : (n, na) approach
        directions, +-1 or 0 (unknown). datum : (n, na) machine positions of the part's datum, mm and
        rad (the corrections are referenced to it), or None (the raw deviation). tool_length : (n,)
        mm or None (the model's default).

        Returns (unknown, outside, sd_um, in_sd): (n, na) bool, the axis positions the program has
        not given; (n, na) bool, the known axes outside the model's support
        (:meth:`outside_support`); (n,) the standard error of each block's correction, um, NaN for
        blocks not corrected anyway (an unknown axis, or outside the support unless the options
        extrapolate) and for every block when the options set no limit on it
        (``max_correction_sd_um``); (n,) each block's correction in its standard errors
        (:func:`._uncertainty.in_sd`; NaN where not judged, everywhere without a limit). A block is
        left uncorrected when any of the first three says so, and so is its contour when its sd is
        over, or when no block of it is told from zero (:mod:`._contours`)."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        unknown = ~np.asarray(known, bool)
        outside = self.outside_support(q, ~unknown, tool_length)
        ctx = self._context(feed, np.asarray(dirs), q.shape[0], tool_length)
        inf = unsure_rows(self, datum, tool_length, dirs)[2]
        sd, _, _, each = self._sd_um(q, ctx, unknown, outside, datum, inf)
        correction = None if each is None else self.ev.correction_um(q, ctx, datum)
        return unknown, outside, sd, self.partial.judged(None if each is None else each[:, :3],
                                                         correction)[0]

    def _pinned(self, unknown, outside, sd_um):
        pinned = any_rows(unknown)
        pinned |= self.ram.whole_outside(outside)
        limit = self.options.max_correction_sd_um
        if limit:
            pinned |= sd_um > limit            # NaN (not evaluated) compares False
        return pinned

    def _sd_um(self, q, ctx, unknown, outside, datum=None, datum_out=None):
        """((n,) the standard error of each block's correction (um), NaN for blocks that are not
        corrected anyway (an unknown axis, outside the support) and when no limit is asked; (n, w)
        what the correction assumes at zero there (:meth:`Evaluator.correction_sd_assumed`), or None
        when the model assumes nothing; (n,) bool or None, the blocks gated for ``datum_out``).
        ``datum_out`` (n,) bool or None: the blocks whose datum lies outside the support, or whose
        approach the data never read (:func:`._direction.unsure_rows`): where a limit is asked,
        their standard error is infinite (unless left uncorrected for an unknown axis or the ram
        already); (n, 3) or None (no limit asked), each tip component's standard error (NaN where
        not evaluated), then on 5-axis machines each tool-axis component's (urad), for
        :meth:`PartialRule.judged`."""
        sd = np.full(q.shape[0], np.nan)
        each = None
        assumed = self.ev.assumed
        out = None if assumed is None else np.zeros((q.shape[0], assumed.width))
        limit = bool(self.options.max_correction_sd_um)
        gated = None
        if not (limit or assumed) or not self.ev.has_uncertainty:
            return sd, out, gated, each
        todo = ~any_rows(unknown)
        todo &= ~self.ram.whole_outside(outside)
        if todo.any():
            qt, ct = q[todo], ctx[todo]
            args = (qt, ct) if datum is None else (qt, ct, datum[todo])
            parts = split_rows(lambda *a: self.ev.correction_sd_assumed(*a, sd=limit),
                               qt.shape[0], self._split, *args)
            both = np.concatenate(parts)
            sd[todo] = both[:, :3].max(axis=1)
            k = 3 + self.ev.axis_columns            # the tool axis's (urad) after the tip's
            if limit:
                each = np.full((q.shape[0], k), np.nan)
                each[todo] = both[:, :k]
            if out is not None:
                out[todo] = both[:, k:]
            if limit and datum_out is not None:
                gated = todo & datum_out
                sd[gated] = np.inf
        return sd, out, gated, each

    def _solve_free(self, q, ctx, reference) -> Linearization:
        parts = split_rows(self._solve_free_part, q.shape[0], self._split, q, ctx, reference)
        return parts[0] if len(parts) == 1 else Linearization.concatenate(parts)

    def _solve_free_part(self, q, ctx, reference) -> Linearization:
        o = self.options
        if o.method == "pinv":
            return solve_pinv(self.ev, q, ctx, self.problem.regularization_weights, reference)
        return solve_newton(self.ev, q, ctx, self.problem.regularization_weights, o.step_tol_um,
                            o.max_iterations, reference)

    def _reference(self, datum, ctx) -> np.ndarray:
        """(n, rows) the deviation at the part's datum of each block (Evaluator.datum_reference);
        zeros without a datum (the raw deviation is corrected)."""
        if datum is None:
            return np.zeros((ctx.shape[0], self.ev.rows))
        return self.ev.datum_reference(datum, ctx)

    def _check_travel(self, q, line, known=None):
        self.machine.check_travel(q, line, known, self.source)

    def nodes_from_arrays(self, q, feed=None, dirs=None, rapid=None, line=None, datum=None):
        """Nodes for blocks given directly (no segments, so no internal nodes).

        q : (n, na) nominal positions, mm and rad. feed : (n,) mm/min or None (model default).
        dirs : (n, na) approach directions +-1 or None (unknown). rapid : (n,) bool or None.
        line : (n,) labels or None (1..n). datum : (n, na) machine positions of the part's datum
        (the corrections are referenced to it), or None (the raw deviation is corrected).
        """
        q = self.bounds.snap(np.atleast_2d(np.asarray(q, dtype=float)))
        n = q.shape[0]
        line = np.arange(1, n + 1) if line is None else np.asarray(line)
        self._check_travel(q, line)
        feed = np.full(n, np.nan) if feed is None else np.asarray(feed, dtype=float)
        dirs = np.zeros((n, self.na)) if dirs is None else np.asarray(dirs)
        rapid = np.zeros(n, bool) if rapid is None else np.asarray(rapid, bool)
        exempt = rapid & (not self.problem.step_across_rapids)
        if self._last_end is None and n:
            exempt = exempt.copy()
            exempt[0] = True
        unknown = np.zeros(q.shape, bool)
        outside = self.outside_support(q, ~unknown)
        ctx = self._context(feed, dirs, n)
        datum = None if datum is None else np.broadcast_to(np.asarray(datum, dtype=float), q.shape)
        datum_out, unread, inf = unsure_rows(self, datum, None, dirs)
        sd, assumed, gated, each = self._sd_um(q, ctx, unknown, outside, datum, inf)
        pinned = self._pinned(unknown, outside, sd)
        unread = note_unsure(self, datum, dirs, gated, datum_out, unread, line)
        links = self.links.arrays(q, dirs, None if self._last_end is None else self._last_end[0])
        lin = self._solve_free(q, ctx, self._reference(datum, ctx))
        in_sd, axis_left = self.partial.judged(each, lin.b0)
        nodes = NodeSet(q, ctx, exempt, line, np.zeros(n, bool), rapid, unknown, outside,
                        pinned, sd, np.zeros(n, bool), np.zeros(n, bool),
                        *(links or (None, None, None)), assumed=assumed, in_sd=in_sd,
                        axis_left=axis_left, unread=unread)
        nodes, lin = self.gate.feed(nodes, lin, final=True)     # the arrays are whole contours
        if n:
            self._last_end = (nodes.q[-1], lin.x[-1])
        return nodes, lin

    def nodes_from_chunk(self, chunk):
        """Nodes of one SegmentChunk: segment ends plus internal nodes. Returns (nodes, lin, counts)."""
        nrows = len(chunk)
        end = self.bounds.snap(chunk.end)
        known = np.asarray(chunk.known, bool)
        self._check_travel(end, chunk.line, known)
        ctx = self._context(chunk.feed, chunk.dirs, nrows, chunk.tool_length,
                            getattr(chunk, "context", None))
        rapid = np.asarray(chunk.rapid, bool)
        # a drilling cycle's hole: one block, reached by rapids, never subdivided
        cycle = np.zeros(nrows, bool) if chunk.cycle is None else np.asarray(chunk.cycle, bool)
        # internal nodes lie on the line from the previous node: not where the move starts from a
        # position the program has not given (an axis unknown before it), nor after a hole (the
        # cycle leaves the tool at its retract plane, not at the hole's bottom)
        jump = np.zeros(nrows, bool) if chunk.jump is None else np.asarray(chunk.jump, bool)
        no_line = jump.copy()
        if nrows:
            no_line[1:] |= cycle[:-1]
            no_line[0] |= self._after_cycle
            self._after_cycle = bool(cycle[-1])
        unknown = ~known
        outside = self.outside_support(end, known, chunk.tool_length)
        datum_out, unread, inf = unsure_rows(self, chunk.datum, chunk.tool_length, chunk.dirs)
        sd, assumed, gated, each = self._sd_um(end, ctx, unknown, outside, chunk.datum, inf)
        pinned = self._pinned(unknown, outside, sd)
        unread = note_unsure(self, chunk.datum, chunk.dirs, gated, datum_out, unread, chunk.line)
        self.ram.note(end, outside, pinned, chunk.tool_length, ~any_rows(unknown))
        lin_end = self._solve_free(end, ctx, ref := self._reference(chunk.datum, ctx))
        in_sd, axis_left = self.partial.judged(each, lin_end.b0)
        first = self._last_end is None
        # no step bound into a rapid, a hole, or a move that starts where the program has not said
        # (after a home move or a tool change: the machine did not come along the cut)
        exempt = (rapid | cycle | jump) & (not self.problem.step_across_rapids)
        if first and nrows:
            exempt[0] = True
        start, x_start = self._row_starts(chunk, end, lin_end.x, ctx, ref)
        # no internal nodes in a contour the standard-error gate leaves uncorrected either
        cut_start = cycle | no_line
        gated = self.gate.rows_gated(~rapid & ~any_rows(unknown), cut_start, sd, in_sd)
        skip = rapid | pinned | cycle | no_line | gated
        # a straight move after a block left uncorrected (or a rapid the gate leaves): ramp nodes
        ramped, ramp = ramp_nodes(self, chunk, start, end, lin_end.x, pinned | (gated & rapid),
                                  exempt, skip, ctx, ref)
        skip[ramped] = True
        inner = merged(self._subdivide(start, end, x_start, lin_end.x, ctx, ref, skip), ramp)
        counts = np.ones(nrows, np.int64)
        each_row = dict(assumed=assumed, in_sd=in_sd, axis_left=axis_left, unread=unread)
        if inner is None:
            links = self.links.chunk(chunk, end, np.arange(nrows), np.ones(nrows, bool), first, cycle)
            nodes = NodeSet(end, ctx, exempt, np.asarray(chunk.line), np.zeros(nrows, bool), rapid,
                            unknown, outside, pinned, sd, cut_start, np.zeros(nrows, bool),
                            *(links or (None, None, None)), **each_row)
            return nodes, lin_end, counts
        rows_i, t_i, q_i, lin_i = inner
        np.add.at(counts, rows_i, 1)
        pos_end, pos_i = positions(counts, rows_i, t_i)
        row_sorted = np.repeat(np.arange(nrows), counts)
        ins_all = np.zeros(row_sorted.size, bool)
        ins_all[pos_i] = True
        # an inserted node outside the region the data reached (a move from outside into it) is
        # not corrected, as a block ending there would not be
        out_i = self.outside_support(q_i, known[rows_i],
                                     None if chunk.tool_length is None else np.asarray(chunk.tool_length)[rows_i])
        pin_i = pinned[rows_i] | self.ram.whole_outside(out_i)
        q_all = placed(end, q_i, pos_end, pos_i)
        firsts = np.zeros(row_sorted.size, bool)
        firsts[np.cumsum(counts) - counts] = True
        cut_all = np.repeat(cut_start, counts) & firsts
        # the first node of a row (inserted or its end) takes the row's exemption
        ex_all = np.repeat(exempt, counts) & firsts
        links = self.links.chunk(chunk, q_all, row_sorted, firsts, first, cycle)
        nodes = NodeSet(q_all, ctx[row_sorted], ex_all, np.asarray(chunk.line)[row_sorted],
                        ins_all, rapid[row_sorted], unknown[row_sorted],
                        placed(outside, out_i, pos_end, pos_i),
                        placed(pinned, pin_i, pos_end, pos_i), sd[row_sorted], cut_all,
                        np.zeros(row_sorted.size, bool), *(links or (None, None, None)),
                        **{k: None if v is None else v[row_sorted] for k, v in each_row.items()})
        lin = Linearization(*(placed(getattr(lin_end, f), getattr(lin_i, f), pos_end, pos_i)
                              for f in Linearization.FIELDS))
        return nodes, lin, counts

    def _row_starts(self, chunk, end, x_end, ctx, ref):
        """(start, x_start) (n, na): where each row's move starts and its free correction there."""
        start = np.empty_like(end)
        x_start = np.empty_like(x_end)
        if end.shape[0]:
            start[1:] = end[:-1]
            x_start[1:] = x_end[:-1]
            if self._last_end is None:
                s0 = self.bounds.snap(chunk.start[:1])
                start[0] = s0[0]
                x_start[0] = self._solve_free(s0, ctx[:1], ref[:1]).x[0]
            else:
                start[0], x_start[0] = self._last_end
            self._last_end = (end[-1], x_end[-1])
        return start, x_start

    def _subdivide(self, start, end, x_start, x_end, ctx, ref, skip):
        """Internal nodes (rows, t, q, lin) where the interpolated correction misses the midpoint.
        skip : (n,) bool, rows never subdivided (rapids, pinned blocks, cycles, moves without a start)."""
        o = self.options
        if not o.subdivide_tol_um or o.max_subdivision_depth < 1 or start.shape[0] == 0:
            return None
        moving = ~skip & (row_max_abs(end - start) > 0)
        rows = np.flatnonzero(moving)
        if rows.size == moving.size:      # every row moves (the common case): no copies
            s0, e0, x0, x1, c, rf = start, end, x_start, x_end, ctx, ref
        else:
            s0, e0, x0, x1, c, rf = start[rows], end[rows], x_start[rows], x_end[rows], ctx[rows], ref[rows]
        t0, t1 = np.zeros(rows.size), np.ones(rows.size)
        found_rows, found_t, found_q, found_lin = [], [], [], []
        for _depth in range(o.max_subdivision_depth):
            if rows.size == 0:
                break
            tm = 0.5 * (t0 + t1)
            parts = split_rows(self._midpoint_miss, rows.size, self._split, s0, e0, tm, x0, x1, c, rf)
            err = np.concatenate([p[0] for p in parts]) if len(parts) > 1 else parts[0][0]
            hit = err > o.subdivide_tol_um
            if not np.any(hit):
                break
            qm = np.concatenate([p[1] for p in parts]) if len(parts) > 1 else parts[0][1]
            rows, t0, t1, x0, x1, tm, qm, c, rf, s0, e0 = (
                a[hit] for a in (rows, t0, t1, x0, x1, tm, qm, c, rf, s0, e0))
            lin = self._solve_free(qm, c, rf)
            found_rows.append(rows)
            found_t.append(tm)
            found_q.append(qm)
            found_lin.append(lin)
            rows = np.concatenate([rows, rows])
            t0, t1 = np.concatenate([t0, tm]), np.concatenate([tm, t1])
            x0, x1 = np.concatenate([x0, lin.x]), np.concatenate([lin.x, x1])
            s0, e0, c = np.concatenate([s0, s0]), np.concatenate([e0, e0]), np.concatenate([c, c])
            rf = np.concatenate([rf, rf])
        if not found_rows:
            return None
        return (np.concatenate(found_rows), np.concatenate(found_t), np.concatenate(found_q),
                Linearization.concatenate(found_lin))

    def _midpoint_miss(self, start, end, t, x0, x1, c, ref):
        """(err (n,), qm (n, na)): the node at parameter t (n,) of the moves start -> end (n, na),
        rounded to the grid, and how far (weighted, um / urad) the correction interpolated between
        the corrections x0 and x1 of the ends misses there."""
        qm = self.bounds.snap(start + t[:, None] * (end - start))
        target, M = self.ev.target_and_orientation_rows(qm)
        target = down_columns(np.add, target, ref)
        # as the objective counts it: a tool-axis deviation no rotary axis can remove there is
        # missed by any correction and says nothing about the interpolation
        miss = objective_residual(M, self.ev.residual(qm, 0.5 * (x0 + x1), c, target))
        return row_norm(miss), qm

    # ------------------------------------------------------------------ committing
    def _commit(self, nodes: NodeSet, lin: Linearization, x: np.ndarray,
                following: np.ndarray | None = None, limits=None, planned=None,
                desired=None) -> PlanResult:
        """Round, enforce bounds exactly, predict the deviation after correction (``planned``: the
        window's plan before its turn was rounded, whose step bounds the flags name too;
        ``desired``: the unbounded correction with its turn on the grid, when the caller has it)."""
        if limits is None:
            limits = self.bounds.limits(nodes.q, self.ram.pins(nodes))
        # flags compare with the unbounded correction (its turn on the grid): what the bounds took
        if desired is None:
            desired = self._round_rotary(lin, lin.x)
        y, flags = self.bounds.enforce(x, nodes.q, nodes.exempt, self._prev, desired=desired,
                                       following=following, limits=limits, planned=planned,
                                       links=nodes.links)
        held = np.zeros(y.shape, bool)
        if flags.any():
            # a pinned block is left alone for its own reason, not held by a bound; the travel or
            # a link bound holds an axis's whole correction where it acted and the axis is written
            # without any (the step bound's ramp only passes zero: _bounds.HOLDING)
            flags[nodes.pinned] = False
            self.ram.unflag(flags, nodes)
            held = flags[..., HOLDING].any(axis=2) & (np.abs(y) <= self.bounds.on_tol)
        if len(nodes):
            self._prev = y[-1].copy()
        D = self.bounds.D
        if self.bounds.grid is not None:
            g = self.bounds.grid
            # in place from here: fewer temporaries
            corrected = down_columns(np.divide, nodes.q, g)
            np.round(corrected, out=corrected)
            steps = down_columns(np.divide, y, self.bounds.unit)
            np.round(steps, out=steps)
            corrected += steps
            down_columns(np.multiply, corrected, g, out=corrected)
        else:
            corrected = nodes.q + down_columns(np.divide, y, D)
        correction = corrected - nodes.q
        # first order around the last linearisation where the written correction is close to it
        # (the iterations end there); the exact model where it is not (pinv, clamped blocks)
        dy = y - lin.x_lin
        after_w = a_x(lin.A, dy)
        after_w += lin.b
        far = np.flatnonzero(row_max_abs(dy) > 0.5)
        if far.size:
            after_w[far] = self.ev.residual(nodes.q[far], y[far], nodes.context[far],
                                            lin.target[far])
        S = self.ev.S
        before = down_columns(np.divide, lin.b0, S)
        after = down_columns(np.divide, after_w, S, out=after_w)    # a new array: in place
        five = self.problem.correct_orientation
        self._done += len(nodes)
        self._tick()
        return PlanResult(nodes.line, nodes.inserted, nodes.rapid, nodes.q, corrected, correction,
                          before[:, :3], after[:, :3], before[:, 3:6] if five else None,
                          after[:, 3:6] if five else None, flags, lin.iterations, lin.converged,
                          nodes.unknown, nodes.outside, nodes.pinned, nodes.sd_um, nodes.gated,
                          held, undirected=undirected_axes(nodes), standing=standing_axes(nodes),
                          assumed=nodes.assumed, indistinct=nodes.indistinct, unread=nodes.unread,
                          axis_left=nodes.axis_left)

    def _tick(self):
        cb = self.options.progress
        if cb is not None and time.monotonic() - self._last_progress > 3.0:
            self._last_progress = time.monotonic()
            cb(self._done)

    # ------------------------------------------------------------------ windows (qp)
    def _window_qp(self, n_nodes: int, rows: int) -> WindowQP:
        qp = self._qps.get((n_nodes, rows))
        if qp is None:
            qp = self._qps[(n_nodes, rows)] = WindowQP(n_nodes, self.na, rows, self.options.osqp_eps)
        return qp

    def _solve_window(self, nodes: NodeSet, lin: Linearization, limits):
        """(x, planned): corrections (n, na) of one window, and the QP's before its turn was rounded
        (None when the QP was not needed); updates lin in place when re-linearised."""
        b, o = self.bounds, self.options
        self.stats["windows"] += 1
        l, u = limits[:2]
        prev = self._prev
        links = nodes.links
        if not o.always_qp and b.feasible(lin.x, l, u, nodes.exempt, prev, links=links):
            x = self._round_rotary(lin, lin.x)
            if b.feasible(x, l, u, nodes.exempt, prev, links=links):
                return x, None
        self.stats["windows_qp"] += 1
        n, na = lin.x.shape
        lam = self.problem.regularization_weights
        lower = np.vstack([np.zeros((1, na)) if prev is None else prev[None, :], l])
        upper = np.vstack([np.zeros((1, na)) if prev is None else prev[None, :], u])
        S = np.broadcast_to(b.S, (n, na))
        free = nodes.exempt.copy()
        if prev is None and n:
            free[0] = True
        step_lo = np.where(free[:, None], -INF, -S)
        step_hi = np.where(free[:, None], INF, S)
        full = LazyQP(lambda: self._window_qp(n + 1, lin.b.shape[1]))   # b's rows: the objective's
        qp, local = full, None
        if links is None:
            reachable = reachable_nodes(self._prev, free, np.asarray(b.S, dtype=float))
        else:
            step_lo, step_hi, reachable = self.links.window(links, prev, l, u, step_lo, step_hi,
                                                            self.stats, nodes.line)
            if tied(step_lo, step_hi).any():      # one variable per run of tied nodes
                qp = GroupedQP(o.osqp_eps)

        def relinearise(idx, xi):
            return self.ev.residual_jacobian(nodes.q[idx], xi, nodes.context[idx],
                                             lin.target[idx])[:2]

        if not o.always_qp and qp is full:        # tied runs: GroupedQP on the whole window
            local = solve_stretches(lin, (lower, upper), (step_lo, step_hi), reachable, lam,
                                    o.step_tol_um, o.max_iterations, self._window_qp, relinearise)
        if local is not None:
            x, solves = local
            self.stats["qp_solves"] += solves
            self.stats["qp_status"]["solved"] = self.stats["qp_status"].get("solved", 0) + solves
        else:
            x = self._solve_whole_window(lin, qp, (lower, upper), (step_lo, step_hi), reachable,
                                         relinearise)
            if x is None:
                # keep going with the unbounded solution; enforce() clamps it and flags the bounds
                self.stats["qp_failed"] = self.stats.get("qp_failed", 0) + 1
                return self._round_rotary(lin, np.clip(lin.x, l, u)), None
        solves = qp.solves
        fixed = solve_with_rotary_fixed(qp, b, lin, x, (lower, upper), (step_lo, step_hi), reachable,
                                        lam, self._rotary)
        self.stats["qp_solves"] += qp.solves - solves
        return fixed, x

    def _solve_whole_window(self, lin: Linearization, qp, box, steps, reachable, relinearise):
        """The bounded window's corrections (n, na) from OSQP on the whole window, re-linearised until
        they stop moving (lin updated in place); None when OSQP fails."""
        o = self.options
        lower, upper = box
        step_lo, step_hi = steps
        lam = self.problem.regularization_weights
        na = lin.x.shape[1]
        eye = np.eye(na)
        x = np.clip(lin.x, lower[1:], upper[1:])
        for _it in range(o.max_iterations):
            c, A = lin.objective()
            H = gram(A, lam)
            g = at_b(A, c)
            Hall = np.concatenate([eye[None], H])
            gall = np.vstack([np.zeros((1, na)), g])
            x0 = np.vstack([lower[:1], x])
            worse = never_worse_rows(objective_residual(lin.orientation_rows, lin.b0), c, A,
                                     reachable)
            sol, status = qp.solve(Hall, gall, lower, upper, step_lo, step_hi, x0, *worse)
            if status not in ("solved", "solved inaccurate"):
                # never worse is out of reach (the bounds forbid leaving a block as it was): the
                # least error within the bounds, the blocks made worse counted in the summary
                self.stats["never_worse_dropped"] = self.stats.get("never_worse_dropped", 0) + 1
                sol, status = qp.solve(Hall, gall, lower, upper, step_lo, step_hi, x0)
            self.stats["qp_solves"] += 1
            self.stats["qp_status"][status] = self.stats["qp_status"].get(status, 0) + 1
            if status not in ("solved", "solved inaccurate"):
                return None
            x = sol[1:]
            moved = row_max_abs(x - lin.x_lin) >= o.step_tol_um
            if not np.any(moved):
                break
            idx = np.flatnonzero(moved)
            lin.b[idx], lin.A[idx] = relinearise(idx, x[idx])
            lin.x_lin[idx] = x[idx]
            lin.iterations[idx] += 1
        return x

    def _round_rotary(self, lin: Linearization, x: np.ndarray) -> np.ndarray:
        """x with the rotary corrections on the output grid, the linear ones re-solved for them."""
        return round_rotary(self.bounds, lin, x, self._rotary, self.problem.regularization_weights)

    def _feasible_run(self, nodes: NodeSet, lin: Linearization, pos: int, total: int, final: bool):
        """Commit at once the run of full windows from ``pos`` on whose unbounded solution keeps every
        bound (those before the first block that breaks one): ``(result, nodes committed)``, or
        ``(None, 0)`` when fewer than two such windows.

        The same plan as window by window: each of these windows would be its unbounded solution
        (checked here as :meth:`_solve_window` does, the anchor of a window being the written,
        rounded correction of the node before it), and rounding a solution that keeps the bounds
        changes none of them, so committing the run in one piece writes the same corrections.
        """
        W, O = self.options.window, self.options.overlap
        room = total - pos - W - O - (1 if final else 0)
        if room < W:          # at most one full window: the plain path
            return None, 0
        count = room // W + 1
        end = pos + count * W + O
        x = self._round_rotary(lin.take(slice(pos, end)), lin.x[pos:end])
        exempt = nodes.exempt[pos:end]
        limits = self.bounds.limits_lazy(nodes.q[pos:end], self.ram.pins(nodes)[pos:end])
        b = self.bounds
        links = None if nodes.link_lo is None else tuple(a[pos:end] for a in nodes.links)
        k = b.first_violation(x, limits[0], limits[1], exempt, self._prev, links=links)
        if k is not None:
            # the windows wholly before it, as window by window (x is lin.x without a rotary axis)
            count = 0 if self._rotary.any() else (k - O) // W
            if count < 2:
                return None, 0
            x, exempt = x[:count * W + O], exempt[:count * W + O]
            limits = tuple(None if a is None else a[:count * W + O] for a in limits)
        # window k > 0 starts at k * W, anchored at the rounded correction of the node before it
        starts = np.arange(1, count) * W
        anchor = b.quantize(x[starts - 1])
        bad = np.any(np.abs(x[starts] - anchor) > b.S + 1e-9, axis=1) & ~exempt[starts]
        if links is not None:
            d = x[starts] - anchor
            bad |= np.any((d < links[0][starts] - 1e-9) | (d > links[1][starts] + 1e-9), axis=1)
        if np.any(bad):
            count = 1 + int(np.flatnonzero(bad)[0])
            if count < 2:
                return None, 0
        nc = count * W
        if nodes.link_lo is not None:           # no commit inside a run of tied nodes
            nc = run_start(nodes.link_lo, nodes.link_hi, pos + nc, pos + 1) - pos
        self.stats["windows"] += count
        following = x[nc] if nc < x.shape[0] and not exempt[nc] else None
        csl = slice(pos, pos + nc)
        # x is the run's unbounded correction with its turn on the grid: the flags' reference too
        res = self._commit(nodes.take(csl), lin.take(csl), x[:nc].copy(), following,
                           tuple(None if a is None else a[:nc] for a in limits), desired=x[:nc])
        return res, nc

    # ------------------------------------------------------------------ driving
    def iter_chunks(self, chunks: Iterable) -> Iterator[tuple[object, PlanResult]]:
        """Plan a stream of SegmentChunks; yields ``(chunk, result)`` per chunk, in order.

        With more than one thread (``PlannerOptions.threads``) the chunks are read and planned one
        result ahead of the consumer in a thread of their own (the consumer, e.g. the writer of the
        corrected program, works on the previous result meanwhile).
        """
        gen = self._iter_chunks(chunks)
        if self.threads < 2:
            return gen
        # the chunks are still cut into ``threads`` parts: the planning thread is the longest by far
        # (the consumer, the writer of the program, waits for it most of the time)
        return read_ahead(gen, name="mtcomp-planner")

    def _iter_chunks(self, chunks: Iterable) -> Iterator[tuple[object, PlanResult]]:
        pending: deque = deque()   # (chunk, counts, n_nodes) planned but not yet yielded
        done: list[PlanResult] = []
        n_done = 0

        def ready():
            nonlocal n_done
            while pending and n_done >= pending[0][2]:
                chunk, counts, n = pending.popleft()
                res = first_rows(done, n)
                n_done -= n
                res.counts = counts
                yield chunk, res

        n_chunks = 0
        for chunk in chunks:
            if len(chunk) == 0:
                continue
            n_chunks += 1
            if n_chunks == 2 and self.threads > 1 and self.options.method == "qp":
                prefetch_solver()       # a long program: OSQP imported meanwhile on a spare CPU
            nodes, lin, counts = self.nodes_from_chunk(chunk)
            pending.append((chunk, counts, len(nodes)))
            nodes, lin = self.gate.feed(nodes, lin)     # holds back a contour still open
            for res in as_list(self.plan_nodes(nodes, lin, final=False, join=False)):
                done.append(res)
                n_done += len(res)
            yield from ready()
        last = self.gate.finish() or (
            NodeSet.empty(self.na, self.problem.fitted.model.n_context),
            Linearization.empty(self.na, self.ev.rows, 3 if self.problem.correct_orientation else 0))
        for res in as_list(self.plan_nodes(*last, join=False)):
            done.append(res)
            n_done += len(res)
        yield from ready()

    def plan_nodes(self, nodes: NodeSet, lin: Linearization, final: bool = True,
                   join: bool = True) -> PlanResult | list[PlanResult] | None:
        """Plan a batch of nodes (program order, after the ones planned before). With ``final`` every
        node is committed; otherwise qp keeps the last ``overlap`` (or fewer) for the next call
        (``join=False``: qp's results as the list of its committed runs, not copied into one)."""
        o = self.options
        self.partial.apply(nodes, lin)
        if o.method != "qp":
            x = self._round_rotary(lin, lin.x)
            return self._commit(nodes, lin, x, desired=x)
        results = []
        if self._buffer:
            (prev_n, prev_l), = self._buffer
            head = self._plan_head(prev_n, prev_l, nodes, lin, final)
            if head is None:        # too few new nodes: plan the two batches joined
                nodes = NodeSet.concatenate([prev_n, nodes])
                lin = Linearization.concatenate([prev_l, lin])
            else:
                results, start, left = head
                nodes, lin = nodes.take(slice(start, None)), lin.take(slice(start, None))
                if left is not None:
                    nodes = NodeSet.concatenate([left[0], nodes])
                    lin = Linearization.concatenate([left[1], lin])
        more, pos = self._plan_windows(nodes, lin, final)
        results += more
        total = len(nodes)
        self._buffer = [(nodes.take(slice(pos, total)), lin.take(slice(pos, total)))] if pos < total \
            else []
        if not results or not join:
            return results or None
        return results[0] if len(results) == 1 else PlanResult.concatenate(results)

    def _plan_head(self, prev_n: NodeSet, prev_l: Linearization, nodes: NodeSet, lin: Linearization,
                   final: bool):
        """The windows that start in the nodes kept from the last call (r of them), planned on those
        joined with only the first new nodes they need: k = ceil(r / window) full windows, which end
        exactly k * window - r nodes into the new batch. Returns (results, that offset, None), or
        None when the new batch is too short (then the windows would not be the same as on the
        whole); where a run of tied nodes held the last commit back into the kept nodes,
        (results, 0, (the kept nodes not committed, their linearisation)).

        Saves joining (copying) every new batch to the few nodes kept from the last one."""
        W, O = self.options.window, self.options.overlap
        r = len(prev_n)
        k = -(-r // W)
        h = k * W + O - r                       # new nodes the k windows need
        if h > len(nodes) or (final and h == len(nodes)):
            return None
        hn = NodeSet.concatenate([prev_n, nodes.take(slice(0, h))])
        hl = Linearization.concatenate([prev_l, lin.take(slice(0, h))])
        results, pos = self._plan_windows(hn, hl, final=False)
        # re-linearisations of new nodes made there (the overlap of the last head window)
        for f in ("b", "A", "x_lin", "iterations"):
            getattr(lin, f)[:h] = getattr(hl, f)[r:]
        if pos >= r:
            return results, pos - r, None
        # a run of tied nodes held the last commit back into the kept nodes: they go on first
        return results, 0, (hn.take(slice(pos, r)), hl.take(slice(pos, r)))

    def _plan_windows(self, nodes: NodeSet, lin: Linearization, final: bool):
        """Windows over ``nodes`` from the first on: (results, nodes committed)."""
        o = self.options
        total = len(nodes)
        W, O = o.window, o.overlap
        results = []
        pos = 0
        while total - pos > 0:
            left = total - pos
            if not final and left < W + O:
                break
            if not o.always_qp:
                res, n_run = self._feasible_run(nodes, lin, pos, total, final)
                if n_run:
                    results.append(res)
                    pos += n_run
                    continue
            nw = min(left, W + O)
            nc = nw if (final and left <= W + O) else min(W, nw)
            if nc < nw and nodes.link_lo is not None:
                # no commit inside a run of tied nodes (an arc under cutter radius compensation):
                # the next window would find the run's correction fixed by its anchor
                nc = run_start(nodes.link_lo, nodes.link_hi, pos + nc, pos + 1) - pos
            sl = slice(pos, pos + nw)
            wn, wl = nodes.take(sl), lin.take(sl)
            limits = self.bounds.limits(wn.q, self.ram.pins(wn))
            x, planned = self._solve_window(wn, wl, limits)
            # keep the re-linearisation for the overlap nodes of the next window
            lin.b[sl], lin.A[sl], lin.x_lin[sl], lin.iterations[sl] = wl.b, wl.A, wl.x_lin, wl.iterations
            csl = slice(0, nc)
            following = x[nc] if nc < nw and not wn.exempt[nc] else None
            results.append(self._commit(wn.take(csl), wl.take(csl), x[:nc], following,
                                        tuple(a[csl] for a in limits),
                                        None if planned is None else planned[:nc]))
            pos += nc
        return results, pos


def plan_arrays(problem: CompensationProblem, q, feed=None, dirs=None, rapid=None,
                options: PlannerOptions | None = None) -> PlanResult:
    """Plan corrections for blocks given as arrays (one output block each, no internal nodes).

    q : (n, n_axes) nominal axis positions, mm and rad. feed : (n,) mm/min or None. dirs : (n, n_axes)
    approach directions (+1/-1) or None. rapid : (n,) bool or None.
    """
    planner = Planner(problem, options)
    nodes, lin = planner.nodes_from_arrays(q, feed, dirs, rapid)
    return planner.plan_nodes(nodes, lin, final=True)


def plan_chunks(problem: CompensationProblem, chunks: Iterable, options: PlannerOptions | None = None,
                source: str | None = None) -> Iterator[tuple[object, PlanResult]]:
    """Plan a program streamed as SegmentChunks; yields ``(chunk, result)`` in order, where
    ``result.counts`` gives the output blocks per segment row (``write_corrected``'s counts) and
    ``result.corrected`` the points to write."""
    return Planner(problem, options, source).iter_chunks(chunks)

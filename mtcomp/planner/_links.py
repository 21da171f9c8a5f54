"""Bounds that tie a block's correction to the one before it, besides the step bound: the written
program must be the one the planner evaluated.

Rules, each a bound on the change of a correction between consecutive output blocks,
``lo <= x_i - x_(i-1) <= hi`` (optimisation units: um, urad), of the same kind as the step bound:

* **reversal** (axes whose error the model makes depend on the approach direction: a backlash or
  reversal term, a lag that follows the motion). The model evaluates block i with the direction
  state d_i of the nominal program (the sign of the axis's nominal move dp_i into the block, or
  where the axis does not move nominally, the sign of its last move). The written move dp_i + dc_i
  (dc_i the change of the correction) keeps that direction: ``d_i (dp_i + dc_i) >= m_i``, with the
  margin m_i one output-grid step (at most |dp_i|) where the axis moves nominally (a written move
  of zero would leave the machine in its old direction at a nominal reversal) and 0 where it does
  not. A correction may then never move an axis backwards where the program moves it forwards, nor
  move an axis that stands still against its last direction. Where the direction state is unknown
  (the axis has not moved from a position the program gave) and the axis does not move nominally,
  its correction does not change (dc_i = 0): the written program moves that axis exactly when the
  program does, so the machine's state is the one the uncorrected program leaves.
* **arc** (an arc block under cutter radius compensation, G41/G42): the controller offsets the
  arc as written, so the writer writes it as one arc; every node of it (its start, its chord ends,
  its end) carries the same correction (``x_i = x_(i-1)``), a translation of the arc, which one arc
  with the same centre offsets writes exactly.
* **standing** (a rotary axis the program does not move into the node, outside tool centre point
  mode: 3+2 machining, an indexed table): its correction does not change (``x_i = x_(i-1)``), so
  its word is never added or changed where the program holds it; the axis stands (and may be
  clamped, Fanuc and Haas M10/M11, M12/M13) where it was put with the correction it had when it last
  moved, and the linear axes alone take the tip. A rotary axis gets a correction only in a block
  that moves it; in tool centre point mode the controller moves the rotary axes anyway, and no
  such bound applies.
* **crc** (a block under cutter radius compensation, G41/G42 in force or switched by its line;
  the offset plane's two axes, X Y in G17, Z X in G18, Y Z in G19): the controller offsets every
  move in the plane perpendicular to its own direction, so the change of the correction into the
  block must not turn that direction. A block that does not move in the plane (a plunge, a G41 or
  G40 line naming Z alone) keeps the plane correction of the block before (``x_i = x_(i-1)``): no
  plane word is added, where one would be a move of a few um whose offset points anywhere. A
  block that does may change it by at most its length in the plane times ``CRC_TURN / sqrt(2)``
  per axis, in whole grid steps (0 for a block shorter than about 70 um on the 0.1 um grid), so
  the written move turns by at most ``CRC_TURN`` (tan 0.11 deg): the offset vector turns with it,
  and at an inside corner the tool centre moves by the tool radius times that tangent besides the
  correction (10 um at 5 mm: a short block's swing). On a pinned block (no correction) the held
  plane axes keep the correction they stand with, as standing rotary axes do
  (:meth:`~._nodes.NodeSet.box_pins`).

Zero correction change always keeps every rule, so a plan from zero stays feasible; from a window's
anchor (a committed correction) a rule can meet a bound it cannot get past (a block that gets no
correction right after a stand-still with a correction on): :func:`propagate` finds such nodes
and lets the step bound alone hold there, and tells which nodes can still reach zero correction
(the never-worse rows of the QP need it).
"""
from __future__ import annotations

import numpy as np

from ._bounds import ARC, CRC, INF, REVERSAL, STANDING

#: under cutter radius compensation, the largest turn of a block's direction in the offset plane
#: that the change of its correction may make, as its tangent (0.002: 0.11 deg; module docstring)
CRC_TURN = 0.002
#: the offset plane's axes of G17, G18, G19 (the axes the controller offsets the tool along)
PLANE_AXES = {17: ("X", "Y"), 18: ("Z", "X"), 19: ("Y", "Z")}

__all__ = ["ARC", "CRC", "CRC_TURN", "REVERSAL", "STANDING", "LinkRules", "direction_axes",
           "node_links", "propagate",
           "run_start", "standing_axes", "undirected_axes"]


def direction_axes(model) -> np.ndarray:
    """(na,) bool: the axes whose approach direction the error model's tool pose depends on
    (:meth:`mtcomp.models.ErrorModel.direction_axes`)."""
    return model.direction_axes()


def node_links(dp, dirs, reversal_axes, tie, no_link, unit, standing=None, plane=None):
    """The link bounds of n nodes: ``(lo, hi, kind)``, each (n, na), or None when no node has one.

    dp : (n, na) nominal move into each node from the node before (optimisation units, on the
    output grid when there is one). dirs : (n, na) the direction state the model evaluates the node
    with (+1, -1, 0 unknown). reversal_axes : (na,) bool, axes with a direction-dependent error.
    tie : (n,) bool, nodes of an arc under cutter radius compensation. no_link : (n, na) bool, no
    link bound (the first node of a program, a move from a position not given, a hole's tool axis).
    unit : (na,) one output-grid step (optimisation units), the margin of a nominal move.
    standing : (n, na) bool or None, the rotary axes the standing rule holds (no change of their
    correction into the node, whatever ``no_link`` says: :meth:`LinkRules.standing`).
    plane : (n, na) or None, the room of the change of the correction of the offset plane's axes
    into a node under cutter radius compensation (``-plane <= x_i - x_(i-1) <= plane``; INF on the
    other axes and nodes: :meth:`LinkRules.plane_room`); named where it is at least as tight as the
    reversal bound on both sides.
    """
    n, na = dp.shape
    stands = standing is not None and bool(standing.any())
    if n == 0 or not (reversal_axes.any() or tie.any() or stands or plane is not None):
        return None
    lo = np.full((n, na), -INF)
    hi = np.full((n, na), INF)
    kind = np.zeros((n, na), np.int8)
    for j in np.flatnonzero(reversal_axes):
        p = dp[:, j]
        s = np.sign(p)
        d = np.where(s != 0, s, np.sign(dirs[:, j]))   # the written move follows the nominal one
        margin = np.minimum(unit[j], np.abs(p))
        lo[:, j] = np.where(d > 0, margin - p, np.where(d == 0, 0.0, -INF))
        hi[:, j] = np.where(d < 0, -margin - p, np.where(d == 0, 0.0, INF))
        kind[:, j] = REVERSAL
    if plane is not None:
        kind[(plane < INF) & (-plane >= lo) & (plane <= hi)] = CRC
        np.maximum(lo, -plane, out=lo)
        np.minimum(hi, plane, out=hi)
    if tie.any():
        lo[tie] = 0.0
        hi[tie] = 0.0
        kind[tie] = ARC
    lo[no_link] = -INF
    hi[no_link] = INF
    kind[no_link] = 0
    if stands:
        lo[standing] = 0.0
        hi[standing] = 0.0
        kind[standing] = STANDING
    if not kind.any():
        return None
    return lo, hi, kind


def undirected_axes(nodes):
    """(n, na) bool: the axes of the nodes (a :class:`~._nodes.NodeSet`) whose reversal link keeps
    their correction at the node before's because their direction state is unknown and they do
    not move (both bounds 0: the first positioning after the start, a tool change or a home move,
    such as a G43 line's X and Y), or None where no node has a link bound."""
    if nodes.link_kind is None:
        return None
    return (nodes.link_kind == REVERSAL) & (nodes.link_lo == 0.0) & (nodes.link_hi == 0.0)


def standing_axes(nodes):
    """(n, na) bool: the rotary axes of the nodes (a :class:`~._nodes.NodeSet`) the standing rule
    keeps at the node before's correction, or None where no node has a link bound."""
    return None if nodes.link_kind is None else nodes.link_kind == STANDING


def combined_steps(step_lo, step_hi, links):
    """The step bounds (n, na) intersected with the link bounds ``(lo, hi, kind)`` (or as they are
    when ``links`` is None)."""
    if links is None:
        return step_lo, step_hi
    return np.maximum(step_lo, links[0]), np.minimum(step_hi, links[1])


def propagate(prev, lower, upper, step_lo, step_hi, plain_lo, plain_hi):
    """Make a window's bounds feasible from its anchor and tell which nodes can reach zero.

    prev : (na,) the anchor's correction or None (the start: free). lower, upper : (n, na) box of
    the nodes. step_lo, step_hi : (n, na) bounds of x_i - x_(i-1) with the links; plain_lo,
    plain_hi : the same without them (the step bound alone). Per axis the correction a node can
    take lies in an interval carried forward from the anchor; where the links would empty it, they
    give way to the step bound at that node. Returns (step_lo, step_hi, reachable (n,) bool: zero
    correction is within every axis's interval, the never-worse rows can hold) and (n,) bool, the
    nodes whose links gave way.
    """
    n, na = lower.shape
    step_lo, step_hi = step_lo.copy(), step_hi.copy()
    reachable = np.ones(n, bool)
    relaxed = np.zeros(n, bool)
    if prev is None:
        a, b = [-INF] * na, [INF] * na
    else:
        a = np.asarray(prev, dtype=float).tolist()
        b = list(a)
    for j in range(na):
        # one axis at a time, on Python floats (a loop over the nodes: each interval is the one
        # before carried one step; per node numpy calls cost more than the arithmetic)
        ok, gave = _propagate_axis(a[j], b[j], lower[:, j].tolist(), upper[:, j].tolist(),
                                   step_lo[:, j].tolist(), step_hi[:, j].tolist(),
                                   plain_lo[:, j], plain_hi[:, j])
        reachable &= np.frombuffer(ok, dtype=bool)
        if gave:
            step_lo[gave, j], step_hi[gave, j] = plain_lo[gave, j], plain_hi[gave, j]
            relaxed[gave] = True
    return step_lo, step_hi, reachable, relaxed


def _propagate_axis(a, b, lower, upper, step_lo, step_hi, plain_lo, plain_hi):
    """:func:`propagate` along one axis from the anchor's interval [a, b]: (bytearray of 1 where
    the axis's interval holds zero, list of the nodes where its link gave way). ``x if x > y
    else y`` is ``max(y, x)`` of the same floats (and ``min`` likewise), without the calls."""
    ok = bytearray(len(lower))
    gave = []
    for i, (lo, hi, s, t) in enumerate(zip(lower, upper, step_lo, step_hi)):
        x, y = a + s, b + t
        aj = lo if lo > x else x
        bj = hi if hi < y else y
        if aj > bj:             # the links cannot be kept from here: the step bound alone
            gave.append(i)
            x, y = a + plain_lo[i], b + plain_hi[i]
            aj = lo if lo > x else x
            bj = hi if hi < y else y
            if aj > bj:         # not even so (the step bound's own conflict): the box
                aj, bj = lo, hi
        a = -INF if -INF > aj else aj
        b = INF if INF < bj else bj
        if aj <= 1e-9 and bj >= -1e-9:
            ok[i] = 1
    return ok, gave


def run_start(link_lo, link_hi, k: int, lowest: int) -> int:
    """The first node of the run of tied nodes (every correction equal to the one before) that node
    k belongs to, k itself when it is not tied to the node before; k when the run reaches back to
    ``lowest`` or before it (it cannot be kept whole)."""
    j = k
    while j >= lowest and not np.any(link_lo[j]) and not np.any(link_hi[j]):
        j -= 1
    return j if j >= lowest else k


class LinkRules:
    """The link bounds of one problem's nodes, as the planner makes them (module docstring).

    reversal_axes : (na,) bool, the axes with a direction-dependent error (:func:`direction_axes`).
    unit : (na,) the margin of a nominal move: one output-grid step (x units; 1e-3 without a grid).
    """

    def __init__(self, problem, bounds):
        self.bounds = bounds
        self.reversal_axes = direction_axes(problem.fitted.model)
        self.unit = bounds.unit if bounds.grid is not None else np.full(problem.n_axes, 1e-3)
        names = list(problem.machine.axis_names)
        # the tool axis: a drilling cycle feeds it down to the hole whatever the correction
        self.tool_axis = names.index("Z") if "Z" in names else -1
        self.rotary = np.array([a.is_rotary for a in problem.machine.axes], bool)
        self.plane_cols = {code: [names.index(a) for a in axes] for code, axes in PLANE_AXES.items()
                           if all(a in names for a in axes)}
        self._last_known = None       # the known axes of the last row of the last chunk

    def steps(self, dq):
        """(n, na) moves dq (mm, rad) in x units, whole output-grid steps when there is a grid."""
        dx = dq * self.bounds.D
        return dx if self.bounds.grid is None else self.bounds.quantize(dx)

    def arrays(self, q, dirs, last):
        """Links of nodes given as arrays (q (n, na), dirs (n, na)) after the node at ``last``
        ((na,) or None: the program's start)."""
        n = q.shape[0]
        before = np.vstack([q[:1] if last is None else np.asarray(last)[None, :], q[:-1]])
        no_link = np.zeros(q.shape, bool)
        if last is None and n:
            no_link[0] = True
        return node_links(self.steps(q - before), dirs, self.reversal_axes, np.zeros(n, bool),
                          no_link, self.unit)

    def chunk(self, chunk, q, rows, firsts, first, cycle):
        """Links of a SegmentChunk's nodes ``q`` (m, na): ``rows`` (m,) their rows, ``firsts`` (m,)
        bool the first node of its row (its move starts at the row's start: after a drilling cycle
        where the cycle left the tool), ``first`` the chunk starts the program, ``cycle`` (nrows,)
        bool the rows that are holes."""
        codes = getattr(chunk, "cutter_comp", None)
        codes = np.zeros(rows.size, np.int8) if codes is None else np.asarray(codes)[rows]
        tie = (codes != 0) & np.asarray(chunk.from_arc, bool)[rows]
        known_rows = np.asarray(chunk.known, bool)
        last_known = self._last_known
        if len(known_rows):
            self._last_known = known_rows[-1].copy()
        if rows.size == 0 or not (self.reversal_axes.any() or codes.any() or self.rotary.any()):
            return None
        was_known = np.empty_like(known_rows)       # known at the row's start
        was_known[1:] = known_rows[:-1]
        was_known[0] = False if last_known is None else last_known
        before = np.empty_like(q)
        before[1:] = q[:-1]
        before[firsts] = self.bounds.snap(np.asarray(chunk.start)[rows[firsts]])
        # no link on an axis not known at the node or at its move's start, into the program's
        # first node, into a move from a position the program has not given (a home move, a tool
        # change), nor on a hole's tool axis. A tool centre point move (marked jump: the axes do
        # not move along a line) whose start is known on every axis is linked: its axes move from
        # the kinematics' inverse at its start to that at its end, the move its directions are of
        # (:mod:`mtcomp.toolpaths.directions`); one whose start is not known on every axis moves
        # its linear axes from positions not known
        no_link = ~known_rows[rows]
        no_link[firsts] |= ~was_known[rows[firsts]]
        jump = np.zeros(rows.size, bool) if chunk.jump is None else np.asarray(chunk.jump, bool)[rows]
        jump &= firsts
        marked = getattr(chunk, "tcp", None)       # set where the program's setup was applied
        in_tcp = np.zeros(rows.size, bool) if marked is None else np.asarray(marked, bool)[rows]
        tcp = in_tcp & firsts
        whole = was_known[rows].all(axis=1)
        no_link[(jump & ~tcp & whole) | (tcp & ~whole)] = True
        if first:
            no_link[0] = True
        if self.tool_axis >= 0:
            no_link[np.asarray(cycle, bool)[rows], self.tool_axis] = True
        dp = self.steps(q - before)
        start_known = known_rows[rows].copy()
        start_known[firsts] &= was_known[rows[firsts]]
        standing = self.standing(dp, start_known, in_tcp)
        if first and standing is not None:
            standing[0] = False
        return node_links(dp, np.asarray(chunk.dirs)[rows], self.reversal_axes, tie & ~jump,
                          no_link, self.unit, standing, self.plane_room(codes, dp))

    def plane_room(self, codes, dp):
        """(n, na) the room of the change of the offset plane's corrections into nodes under
        cutter radius compensation (module docstring), INF elsewhere, or None where no node is
        under it. codes : (n,) the rows' ``SegmentChunk.cutter_comp`` codes (0, or the plane 17,
        18, 19). dp : (n, na) the nominal moves into the nodes (x units, on the output grid).
        The room is the move's length in the plane times CRC_TURN / sqrt(2) on each of the two
        axes (so the change turns the move by at most CRC_TURN), whole grid steps down: 0, a tie,
        where the block does not move in the plane or is too short for one step."""
        if not codes.any():
            return None
        room = np.full(dp.shape, INF)
        for code, cols in self.plane_cols.items():
            on = codes == code
            if not on.any():
                continue
            r = np.hypot(dp[on, cols[0]], dp[on, cols[1]]) * (CRC_TURN / np.sqrt(2.0))
            for j in cols:
                room[on, j] = r if self.bounds.grid is None else \
                    np.floor(r / self.unit[j] + 1e-6) * self.unit[j]
        return room

    def standing(self, dp, known, tcp):
        """(n, na) bool, the rotary axes the standing rule holds (module docstring), or None on a
        machine without one: known at the node and at its move's start (``known`` (n, na)), not
        moved into it (``dp`` (n, na), the nominal move on the output grid), outside tool centre
        point mode (``tcp`` (n,) bool)."""
        if not self.rotary.any():
            return None
        return (dp == 0) & known & self.rotary[None, :] & ~np.asarray(tcp, bool)[:, None]

    def window(self, links, prev, l, u, step_lo, step_hi, stats, lines):
        """A window's step bounds with its link bounds, made feasible from the anchor
        (:func:`propagate`; the program lines of the nodes where the links gave way are kept in
        ``stats['links_relaxed']``, a set: a node in two windows' overlap counts once), and the
        nodes that can reach zero correction. lines : (n,) the nodes' program lines."""
        lo, hi = combined_steps(step_lo, step_hi, links)
        lo, hi, reachable, relaxed = propagate(prev, l, u, lo, hi, step_lo, step_hi)
        if relaxed.any():
            stats.setdefault("links_relaxed", set()).update(np.asarray(lines)[relaxed].tolist())
        return lo, hi, reachable

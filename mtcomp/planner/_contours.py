"""The standard-error gate acts per contour: a cut is corrected whole or not at all.

A block whose correction's standard error exceeds ``PlannerOptions.max_correction_sd_um`` gets no
correction. Decided block by block, a contour whose blocks straddle the limit was cut with a dent:
the blocks under it kept their corrections (on a real laser model about 50 um), those over it none,
and the step bound ramped the correction down and up between them, a form error the uncorrected
program does not have. So the gate leaves the whole contour uncorrected.

A **contour** is a maximal run of consecutive feed nodes (not a rapid, every axis known) that the
machine cuts one after the other: it ends at a rapid, at a block with an axis the program has not
given, at a drilling cycle's hole (a contour of its own) and at a move that does not start where the
node before it ended (after a home move, a tool change, a hole). Rapids are in no contour: each keeps
its own rule, so the correction ramps in and out between contours as at the edge of the model's
support. Nodes outside the support stay in their contour (they are not corrected anyway).

The program is planned in batches (chunks), so the contour still open at a batch's end is held back
until the batch that closes it, or until it is found over the limit, or until it is longer than
``HOLD_NODES`` (then it is planned as it stands and a node over the limit later in it leaves only the
rest of the contour uncorrected; counted in ``ContourGate.released_open``).
"""
from __future__ import annotations

import numpy as np

from ._nodes import NodeSet
from ._pointwise import Linearization
from ._small import any_rows
from ._uncertainty import SMALL_IN_SD
#: the longest open contour held back for the batch that closes it (nodes; about 250 bytes each)
HOLD_NODES = 1 << 18


def gated_contours(member, start, over, carry_open=False, carry_gated=False):
    """Which nodes the gate leaves uncorrected for their contour.

    member : (n,) bool, the node belongs to a contour (a feed node with every axis known).
    start : (n,) bool, the node does not continue the cut of the node before (its move starts
        elsewhere: after a hole, a home move ...); a member after a non-member starts one anyway.
    over : (n,) bool, the node's own standard error exceeds the limit.
    carry_open : the node before the first (an earlier batch) is a member whose contour may go on
        here; carry_gated : that contour is left uncorrected.

    Returns (gated, tail): (n,) bool, the members of a contour with a node over the limit (or
    continuing a gated one); and the index of the first node of the last contour when the last node
    is a member (the contour may go on in the next batch), else n.
    """
    member = np.asarray(member, bool)
    n = member.size
    if n == 0:
        return np.zeros(0, bool), 0
    cid = contour_ids(member, start, carry_open)
    bad = np.bincount(cid[member & np.asarray(over, bool)], minlength=int(cid[-1]) + 1) > 0
    bad[0] |= bool(carry_gated)
    gated = member & bad[cid]
    tail = int(np.searchsorted(cid, cid[-1])) if member[-1] else n
    return gated, tail


def contour_ids(member, start, carry_open) -> np.ndarray:
    """(n,) the number of each node's contour in the batch (:func:`gated_contours`'s arguments); 0:
    the contour carried from the batch before."""
    prev = np.empty(member.size, bool)
    prev[0] = carry_open
    prev[1:] = member[:-1]
    return np.cumsum(member & (np.asarray(start, bool) | ~prev))


def quiet_contours(member, start, in_sd, carry_open=False, carried_whole=True) -> np.ndarray:
    """(n,) bool: the nodes left uncorrected because their correction is not told from zero by its
    standard error (``in_sd`` (n,): the correction in its standard errors, NaN where not judged;
    under :data:`SMALL_IN_SD` in every component): a node in no contour on its own; a contour's
    members when every member judged is, at least one was judged, and (for the contour carried from
    the batch before, ``carry_open``) the batch holds it whole (``carried_whole``). A contour with
    one correction told from zero is corrected whole: left in part it would step where its
    correction stops (module docstring). member, start, carry_open : as :func:`gated_contours`."""
    member, in_sd = np.asarray(member, bool), np.asarray(in_sd, dtype=float)
    if member.size == 0:
        return np.zeros(0, bool)
    with np.errstate(invalid="ignore"):
        small = in_sd < SMALL_IN_SD
    cid = contour_ids(member, start, carry_open)
    size = int(cid[-1]) + 1
    counted = member & np.isfinite(in_sd)
    loud = np.bincount(cid[counted & ~small], minlength=size) > 0
    quiet = (np.bincount(cid[counted], minlength=size) > 0) & ~loud
    quiet[0] &= bool(carried_whole) or not carry_open
    return (member & quiet[cid]) | (~member & small)


def one_contour_left(sd_um, in_sd, limit) -> str | None:
    """Why the gate leaves a whole contour of nodes uncorrected ('over': some node's standard error
    ``sd_um`` (n,) exceeds ``limit``; 'indistinct': no node's correction is told from zero by its
    standard errors, ``in_sd`` (n,) as :func:`quiet_contours`), or None (corrected whole). None
    too without a limit (None or 0): neither rule acts then, as in :class:`ContourGate`. An export
    table is one such contour: its axis moving through its points (docs/export.md)."""
    if not limit:
        return None
    sd_um = np.asarray(sd_um, dtype=float)
    member, start = np.ones(sd_um.size, bool), np.zeros(sd_um.size, bool)
    with np.errstate(invalid="ignore"):
        if gated_contours(member, start, sd_um > limit)[0].any():
            return "over"
    return "indistinct" if quiet_contours(member, start, in_sd).any() else None


class ContourGate:
    """The gate of one program's nodes, batch by batch (module docstring).

    limit : the standard-error limit, um; None or 0, or ``active`` False (no limit, or a model
    without a covariance): the gate does nothing and holds nothing back.
    """

    def __init__(self, limit: float | None, active: bool, hold: int = HOLD_NODES):
        self.limit = limit
        self.active = bool(limit) and active
        self.hold = hold
        self._held: tuple[NodeSet, Linearization] | None = None
        self._open = False        # the last node passed on is a member: its contour may go on
        self._gated = False       # ... and that contour is left uncorrected
        #: open contours planned before their end because they were longer than ``hold``
        self.released_open = 0

    def _over(self, sd_um):
        with np.errstate(invalid="ignore"):
            return np.asarray(sd_um) > self.limit          # NaN (not evaluated) is never over

    def _carry(self):
        return (True, False) if self._held is not None else (self._open, self._gated)

    def rows_gated(self, member, start, sd_um, in_sd=None) -> np.ndarray:
        """(n,) bool: the rows of a batch about to be made into nodes that the gate will leave
        uncorrected as far as the batch tells (no internal nodes are placed in them); the state is
        not changed. member, start : (n,) bool as in :func:`gated_contours`; sd_um : (n,); in_sd :
        (n,) or None, as :func:`quiet_contours`."""
        if not self.active:
            return np.zeros(len(member), bool)
        gated = gated_contours(member, start, self._over(sd_um), *self._carry())[0]
        if in_sd is not None:
            gated |= quiet_contours(member, start, in_sd, self._carry()[0], self._held is not None)
        return gated

    def feed(self, nodes: NodeSet, lin: Linearization, final: bool = False):
        """The nodes of the next batch (after those fed before) that can be planned now, with the
        gate's decision in ``pinned`` and ``gated``: (nodes, lin). Without ``final`` the contour
        open at the batch's end is held back (while no node of it is over the limit)."""
        if not self.active:
            return nodes, lin
        carry = self._carry()
        whole = self._held is not None          # the contour carried in is here from its start
        if self._held is not None:
            hn, hl = self._held
            self._held = None
            nodes, lin = NodeSet.concatenate([hn, nodes]), Linearization.concatenate([hl, lin])
        n = len(nodes)
        if n == 0:
            return nodes, lin
        member = ~nodes.rapid & ~any_rows(nodes.unknown)
        gated, tail = gated_contours(member, nodes.cut_start, self._over(nodes.sd_um), *carry)
        if gated.any():
            nodes.gated = nodes.gated | (gated & ~nodes.pinned)
            nodes.pinned = nodes.pinned | gated
        quiet = None if nodes.in_sd is None else quiet_contours(member, nodes.cut_start,
                                                                nodes.in_sd, carry[0], whole)
        self._open, self._gated = bool(member[-1]), bool(gated[-1])
        if final or tail == n or self._gated:
            return _leave_quiet(nodes, quiet), lin
        if n - tail > self.hold:
            self.released_open += 1
            return _leave_quiet(nodes, quiet), lin
        # the open contour goes back unjudged: one correction told from zero later keeps it whole
        self._held = (nodes.take(slice(tail, n)), lin.take(slice(tail, n)))
        if quiet is not None:
            quiet[tail:] = False
        return _leave_quiet(nodes, quiet).take(slice(0, tail)), lin.take(slice(0, tail))

    def finish(self):
        """The nodes still held back at the end of the program, (nodes, lin) or None: their contour
        ended there with no node over the limit, and is judged by the two-standard-error rule as
        one ended by a rapid is (:meth:`feed` with ``final``)."""
        if self._held is None:
            self._open = self._gated = False
            return None
        none = slice(0, 0)
        held = self.feed(self._held[0].take(none), self._held[1].take(none), final=True)
        self._open = self._gated = False
        return held


def _leave_quiet(nodes: NodeSet, quiet) -> NodeSet:
    """``nodes`` with the ``quiet`` ones (:func:`quiet_contours`; None: none) not pinned already
    pinned and marked ``indistinct``."""
    if quiet is not None:
        quiet = quiet & ~nodes.pinned
        nodes.indistinct = quiet
        nodes.pinned = nodes.pinned | quiet
    return nodes

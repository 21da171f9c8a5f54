"""The planner's output blocks (nodes) in program order: :class:`NodeSet`."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._bounds import CRC, INF, STANDING


@dataclass
class NodeSet:
    """Output blocks in program order.

    q : (n, na) nominal axis positions, mm and rad (on the output grid when the problem has one).
    context : (n, n_context) block context in the model's context_names order.
    exempt : (n,) bool, no step bound from the block before (the move into it is a rapid, a hole,
        one from a position the program has not given, or it is the first block of the program).
    line : (n,) source line. inserted : (n,) bool, an internal node the planner added.
    rapid : (n,) bool, the node ends (or lies in) a G0 move.
    unknown : (n, na) bool, axes whose position the program has not given at this block.
    outside : (n, na) bool, axes outside the region the model's data reached (its ``support``).
    pinned : (n,) bool, the block gets no correction (an unknown axis, outside the support without
        ``PlannerOptions.extrapolate``, or a correction less certain than
        ``PlannerOptions.max_correction_sd_um``): its correction bounds are zero.
    sd_um : (n,) standard error of the block's correction (um; NaN where not evaluated: unknown
        axes, outside the support, or a model without uncertainty).
    cut_start : (n,) bool, the node does not continue the cut of the node before: its move starts
        elsewhere (a hole of a drilling cycle, the move after one, a move from a position the
        program has not given); with ``rapid`` and ``unknown`` it ends a contour (:mod:`._contours`).
    gated : (n,) bool, pinned only because its contour has a node over the standard-error limit.
    link_lo, link_hi, link_kind : (n, na) the link bounds of the change of each correction into
        the node (x units; :mod:`._links`: an axis keeping its direction, one correction along an
        arc under cutter radius compensation) and their kind, or all None when no node has one.
    assumed : (n, w) what each node's correction assumes at zero (:mod:`._assumed`), or None when
        the model assumes nothing.
    in_sd : (n,) the node's correction in its standard errors, the largest over the tip's
        components (:mod:`._contours`: under two it is not told from zero); NaN where not judged
        (its standard error not evaluated or infinite, a correction under 0.01 um), or None (no
        limit, no covariance).
    indistinct : (n,) bool, pinned because its correction, or every one of its contour's, is not
        told from zero by its standard error (:mod:`._contours`), or None (none is).
    axis_left : (n,) bool, a 5-axis node whose tool-axis correction is not made (:mod:`._partial`:
        its rotary axes keep their words), or None (none is).
    unread : (n,) bool, its standard error made infinite because an axis its data read from one
        side only approaches it from the other or a side not known (:mod:`._direction`), or None.
    """

    q: np.ndarray
    context: np.ndarray
    exempt: np.ndarray
    line: np.ndarray
    inserted: np.ndarray
    rapid: np.ndarray
    unknown: np.ndarray
    outside: np.ndarray
    pinned: np.ndarray
    sd_um: np.ndarray
    cut_start: np.ndarray
    gated: np.ndarray
    link_lo: np.ndarray | None = None
    link_hi: np.ndarray | None = None
    link_kind: np.ndarray | None = None
    assumed: np.ndarray | None = None
    in_sd: np.ndarray | None = None
    indistinct: np.ndarray | None = None
    axis_left: np.ndarray | None = None
    unread: np.ndarray | None = None

    FIELDS = ("q", "context", "exempt", "line", "inserted", "rapid", "unknown", "outside", "pinned",
              "sd_um", "cut_start", "gated")
    LINKS = ("link_lo", "link_hi", "link_kind")
    #: (n,) fields that may be None, and what a None stands for when joined with others
    FLAGS = {"in_sd": np.nan, "indistinct": False, "axis_left": False, "unread": False}

    def __len__(self):
        return int(self.q.shape[0])

    @property
    def links(self):
        """(lo, hi, kind) or None (:meth:`Bounds.enforce`'s ``links``)."""
        return None if self.link_lo is None else (self.link_lo, self.link_hi, self.link_kind)

    def box_pins(self) -> np.ndarray:
        """What :meth:`~._bounds.Bounds.limits` pins to zero: ``pinned`` (n,), or (n, na) where a
        pinned block has a rotary axis the standing rule holds, or an axis of the offset plane
        that cutter radius compensation ties to the block before's correction (the block does not
        move in the plane; :mod:`._links`): the axis stands with the correction it has, which the
        block does not write."""
        if self.link_kind is None or not self.pinned.any():
            return self.pinned
        stand = (self.link_kind == STANDING) | \
            ((self.link_kind == CRC) & (self.link_lo == 0.0) & (self.link_hi == 0.0))
        if not (stand & self.pinned[:, None]).any():
            return self.pinned
        return self.pinned[:, None] & ~stand

    def pins(self, rotary) -> np.ndarray:
        """:meth:`box_pins`, and the rotary axes (``rotary`` (na,) bool) of a node whose tool-axis
        correction is not made (``axis_left``)."""
        pins = self.box_pins()
        if self.axis_left is None or not self.axis_left.any():
            return pins
        pins = np.array(np.broadcast_to(pins[:, None] if pins.ndim == 1 else pins, self.q.shape))
        pins[np.ix_(self.axis_left, rotary)] = True
        return pins

    def take(self, idx) -> "NodeSet":
        links = {} if self.link_lo is None else {f: getattr(self, f)[idx] for f in self.LINKS}
        flags = {f: None if getattr(self, f) is None else getattr(self, f)[idx] for f in self.FLAGS}
        return NodeSet(*(getattr(self, f)[idx] for f in self.FIELDS), **links, **flags,
                       assumed=None if self.assumed is None else self.assumed[idx])

    @staticmethod
    def concatenate(parts: list["NodeSet"]) -> "NodeSet":
        links = {}
        if any(p.link_lo is not None for p in parts):
            filled = [p.links or _no_links(p.q.shape) for p in parts]
            links = {f: np.concatenate([t[k] for t in filled]) for k, f in enumerate(NodeSet.LINKS)}
        flags = {f: concatenate_flags([getattr(p, f) for p in parts], [len(p) for p in parts], fill)
                 for f, fill in NodeSet.FLAGS.items()}
        return NodeSet(*(np.concatenate([getattr(p, f) for p in parts]) for f in NodeSet.FIELDS),
                       **links, **flags, assumed=concatenate_rows([p.assumed for p in parts]))


    @staticmethod
    def empty(na: int, n_context: int) -> "NodeSet":
        """No nodes (na axes, n_context context columns)."""
        b = np.zeros(0, bool)
        return NodeSet(np.zeros((0, na)), np.zeros((0, n_context)), b, np.zeros(0, np.int64), b, b,
                       np.zeros((0, na), bool), np.zeros((0, na), bool), b, np.zeros(0), b, b)


def concatenate_rows(parts: list) -> np.ndarray | None:
    """The (n_i, w) arrays of ``parts`` stacked, a part's None as zero rows of the others' width
    (an empty part); None when every part is None."""
    w = next((a.shape[1] for a in parts if a is not None), None)
    if w is None:
        return None
    return np.concatenate([np.zeros((0, w)) if a is None else a for a in parts])


def concatenate_flags(parts: list, lengths: list, fill=False) -> np.ndarray | None:
    """The (n_i,) arrays of ``parts`` joined, a part's None as ``fill`` over its ``lengths``; None
    when every part is None."""
    if all(a is None for a in parts):
        return None
    return np.concatenate([np.full(k, fill) if a is None else a for a, k in zip(parts, lengths)])


def _no_links(shape):
    return np.full(shape, -INF), np.full(shape, INF), np.zeros(shape, np.int8)

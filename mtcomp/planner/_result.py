"""The planner's result: one row per output block (node), in program order (:class:`PlanResult`)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._bounds import FLAG_KINDS, flag_name
from ._nodes import concatenate_flags, concatenate_rows
from ._small import any_rows


@dataclass
class PlanResult:
    """Planned output blocks (one row per node), in program order.

    line : (n,) source line. inserted, rapid : (n,) bool.
    nominal : (n, na) nominal axis positions (mm, rad), as the uncorrected program would be written.
    corrected : (n, na) corrected axis positions to write (mm, rad).
    correction : (n, na) corrected minus nominal (mm, rad).
    before, after : (n, 3) tip deviation (mm) of the uncorrected and corrected block, workpiece frame;
    before_axis, after_axis : (n, 3) tool-axis deviation (actual minus nominal unit vector), 5-axis
        machines only (None otherwise).
    flags : (n, na, len(FLAG_KINDS)) bool, bounds that acted (see ``FLAG_KINDS``); none on a
        pinned block.
    iterations : (n,) model linearisations used per node. converged : (n,) bool.
    unknown, outside : (n, na) bool, axes not known / outside the model's support (see NodeSet).
    pinned : (n,) bool, the block was given no correction (bounds zero) for any of the reasons.
    gated : (n,) bool, pinned only because its contour has a block over the standard-error limit.
    held : (n, na) bool, the axes of a block (not pinned) whose whole correction a bound held (the
        travel or a link bound: ``HOLDING``): the axis is written without correction though the
        block asked for one (``flags`` names the bound).
    sd_um : (n,) standard error of the block's correction, um (see NodeSet).
    counts : (rows,) nodes per segment row of the source chunk (for write_corrected), or None.
    undirected : (n, na) bool, the axes the reversal rule keeps at the correction of the block
        before because their approach direction is not known there (they have not moved since
        the start, a tool change or a home move: a G43 line's X and Y), or None (no such rule).
    standing : (n, na) bool, the rotary axes the standing rule keeps at the correction of the block
        before (the program does not move them there, outside tool centre point mode), or None.
    assumed : (n, w) what each block's correction assumes at zero (:mod:`._assumed`), or None.
    indistinct : (n,) bool, pinned because its correction (or every one of its contour's) is not
        told from zero by its standard error (NodeSet), or None (none is).
    axis_left : (n,) bool, the tool-axis correction not made (NodeSet), or None (none is).
    unread : (n,) bool, left uncorrected because an axis its data read from one side only
        approaches it from the other or a side not known (NodeSet), or None (none is).
    """

    line: np.ndarray
    inserted: np.ndarray
    rapid: np.ndarray
    nominal: np.ndarray
    corrected: np.ndarray
    correction: np.ndarray
    before: np.ndarray
    after: np.ndarray
    before_axis: np.ndarray | None
    after_axis: np.ndarray | None
    flags: np.ndarray
    iterations: np.ndarray
    converged: np.ndarray
    unknown: np.ndarray
    outside: np.ndarray
    pinned: np.ndarray
    sd_um: np.ndarray
    gated: np.ndarray
    held: np.ndarray
    counts: np.ndarray | None = None
    undirected: np.ndarray | None = None
    standing: np.ndarray | None = None
    assumed: np.ndarray | None = None
    indistinct: np.ndarray | None = None
    axis_left: np.ndarray | None = None
    unread: np.ndarray | None = None

    FIELDS = ("line", "inserted", "rapid", "nominal", "corrected", "correction", "before", "after",
              "before_axis", "after_axis", "flags", "iterations", "converged", "unknown", "outside",
              "pinned", "sd_um", "gated", "held")

    def __len__(self):
        return int(self.line.shape[0])

    def take(self, sl) -> "PlanResult":
        return PlanResult(*(None if getattr(self, f) is None else getattr(self, f)[sl]
                            for f in self.FIELDS),
                          **{f: None if getattr(self, f) is None else getattr(self, f)[sl]
                             for f in self.MASKS},
                          assumed=None if self.assumed is None else self.assumed[sl],
                          **{f: None if getattr(self, f) is None else getattr(self, f)[sl]
                             for f in self.FLAGS})

    #: (n, na) masks that may be None (no node has one)
    MASKS = ("undirected", "standing")
    #: (n,) flags that may be None (no node has one)
    FLAGS = ("indistinct", "unread", "axis_left")

    @staticmethod
    def concatenate(parts: list["PlanResult"]) -> "PlanResult":
        out = []
        for f in PlanResult.FIELDS:
            vals = [getattr(p, f) for p in parts]
            out.append(None if vals[0] is None else np.concatenate(vals))
        masks = {}
        for f in PlanResult.MASKS:
            if any(getattr(p, f) is not None for p in parts):
                masks[f] = np.concatenate([np.zeros(p.held.shape, bool) if getattr(p, f) is None
                                           else getattr(p, f) for p in parts])
        flags = {f: concatenate_flags([getattr(p, f) for p in parts], [len(p) for p in parts])
                 for f in PlanResult.FLAGS}
        return PlanResult(*out, **masks, assumed=concatenate_rows([p.assumed for p in parts]), **flags)

    def corrected_blocks(self) -> np.ndarray:
        """(n,) bool: the blocks written with their correction on every axis that asked for one (in
        full or as far as a bound let it: BLOCKS.csv ``corrected`` = 1); not a pinned block, nor one
        with an axis whose whole correction a bound held (``held``)."""
        done = ~self.pinned
        if self.held.any():
            done &= ~any_rows(self.held)
        return done

    def active_bounds(self, axis_names) -> list[str]:
        """Per node the active bounds as text, e.g. 'cx_max;step_y' ('' when none)."""
        out = [""] * len(self)
        rows = np.flatnonzero(any_rows(self.flags))
        for i in rows:
            names = [flag_name(FLAG_KINDS[k], axis_names[j])
                     for j in range(self.flags.shape[1]) for k in range(self.flags.shape[2])
                     if self.flags[i, j, k]]
            out[i] = ";".join(names)
        return out


def first_rows(done: list, n: int) -> PlanResult:
    """The first n (>= 1) rows of the results ``done`` (in program order) as one PlanResult, taken
    off the list: the results they span joined, those after left as they are (of a result cut at
    the n-th row, the rows after stay first, a view). Joining every result and cutting that copied
    most rows twice: the windows of the next chunk are planned before this one is handed on."""
    parts, got = [], 0
    while got < n:
        r = done.pop(0)
        if got + len(r) > n:
            done.insert(0, r.take(slice(n - got, len(r))))
            r = r.take(slice(0, n - got))
        parts.append(r)
        got += len(r)
    return parts[0] if len(parts) == 1 else PlanResult.concatenate(parts)


def as_list(res) -> list:
    return [r for r in (res if isinstance(res, list) else [res]) if r is not None and len(r)]

"""The tool axis is corrected only where the data determine it (docs/planner.md, *Blocks where the
model is unsure*).

A 5-axis block's tool-axis correction is the model's tool-axis deviation there (probing a datum
removes none of it). Where that deviation's standard error exceeds the limit
(``--max-correction-sd-um`` over ``--orientation-weight``: W um of tip weigh as 1 urad), is
infinite (it moves with what the data leave open: a spindle's tilt that data taken with one stylus
length do not tell from a table's) or where the deviation is within two of its standard errors of
zero in every component, the block's rotary axes keep their words (their bounds are zero, as
``--max-correction-urad 0`` makes them everywhere) and the linear axes alone correct the tip.
``NodeSet.axis_left`` marks such a block; the tip's own rules (:mod:`._contours`) are unchanged.

The same holds for a tip component: where its standard error is infinite (a height across the
table that rests on a tilt the data leave open) while the others' are finite and within the limit, the block is corrected in those others; the solve's target in that component is the
uncorrected pose (:func:`._uncertainty.with_hold`), so the correction keeps its deviation there
(within the never-worse tolerance), and ``NodeSet.tip_left`` marks which component was left.
"""
from __future__ import annotations

import numpy as np

from ._contours import contour_ids
from ._rotary_grid import set_turn
from ._uncertainty import components_left, in_sd, left_mask, orientation_left


class PartialRule:
    """The rule for one problem (module docstring); ``limit`` the standard-error limit (um)."""

    def __init__(self, problem, limit):
        self.problem = problem
        self.limit = limit
        self.weight = problem.orientation_weight
        self.rotary = np.array([a.is_rotary for a in problem.machine.axes], bool)
        self.lam = problem.regularization_weights
        #: BLOCKS.csv has the ``components_left`` column: a limit is asked of a model with a
        #: covariance (else no component is ever judged)
        self.column = bool(limit) and problem.fitted.uncertainty is not None

    @property
    def limit_urad(self) -> float | None:
        """The limit on a tool-axis deviation's standard error, urad: the tip's limit over the
        orientation weight (W um of tip weigh as 1 urad of tool axis); None without a limit."""
        return self.limit / self.weight if self.limit and self.weight > 0 else None

    def judged(self, each, b0, tip_left=False):
        """(in_sd, axis_left, tip_left): (n,) the corrections (``b0``'s tip rows, um) in their
        standard errors ``each`` (n, 3 + k) from :meth:`Planner._sd_um`, the tool axis's (urad)
        after the tip's on 5-axis machines (:func:`._uncertainty.in_sd`, over the tip components
        the block corrects), (n,) bool the blocks whose tool-axis correction is not made (or None:
        none) and (n,) int8 the tip components left (``tip_left`` as :meth:`tip_left` gave it,
        or computed here per block when not given; None: none); (None, None, None) without a
        limit (``each`` None)."""
        if each is None:
            return None, None, None
        tip_left = self.tip_left(each) if tip_left is False else tip_left
        tip, tip_each = np.array(b0[:, :3], dtype=float), np.array(each[:, :3], dtype=float)
        if tip_left is not None:
            mask = left_mask(tip_left, tip.shape[0])
            tip[mask], tip_each[mask] = 0.0, 1.0     # a component left is judged by none of this
        tip = in_sd(tip, tip_each)
        if each.shape[1] < 6 or self.limit_urad is None:
            return tip, None, tip_left
        left = orientation_left(b0[:, 3:6] / self.weight, each[:, 3:6], self.limit_urad)
        return tip, (left if left.any() else None), tip_left

    def tip_left(self, each, member=None, start=None):
        """(n,) int8 or None: :func:`._uncertainty.components_left` of ``each`` (None: no limit),
        and with ``member``, ``start`` (as :func:`._contours.gated_contours` takes them) the same
        for every node of a contour: a component left at one of its nodes is left at all (else the
        cut steps in it where it stops). A contour the batch before began is judged from this
        batch's nodes only."""
        left = None if each is None else components_left(each[:, :3], self.limit)
        if left is None or member is None or not len(left):
            return left
        cid = contour_ids(member, start, False)
        whole = np.zeros(int(cid[-1]) + 1, np.int8)
        np.bitwise_or.at(whole, cid[member], left[member])
        return np.where(member, whole[cid], left).astype(np.int8)

    def apply(self, nodes, lin) -> None:
        """The free corrections of the blocks ``axis_left`` of ``nodes`` with their rotary part set
        to zero and the linear part re-solved for that turn, and their tool axis out of the
        objective (``lin`` changed in place): no axis there turns the tool, and the linear axes'
        traces of it (their angular errors along a few um) would only slow the bounded solve."""
        if nodes.axis_left is None:
            return
        rows = np.flatnonzero(nodes.axis_left)
        if rows.size:
            sub = lin.take(rows)
            x = set_turn(sub, np.array(sub.x), np.zeros((rows.size, int(self.rotary.sum()))),
                         self.rotary, self.lam)
            lin.x = np.array(lin.x)
            lin.x[rows] = x
            lin.orientation_rows = np.array(lin.orientation_rows)
            lin.orientation_rows[rows] = 0.0


class PartialTally:
    """What the summary says of the rule (module docstring): the blocks whose tool axis was not
    corrected, the first one's line and the largest tool-axis deviation they keep; and the largest
    tool-axis deviation after over the blocks whose tool axis was corrected (None: no such block).
    ``limit_urad``: :attr:`PartialRule.limit_urad`; ``rotary`` (na,) bool: the machine's rotary
    axes (a block whose program holds them all is counted by the standing rule's line)."""

    def __init__(self, limit_urad: float | None = None, rotary=None):
        self.limit_urad, self.rotary = limit_urad, rotary
        self.axis_blocks = self.axis_line = 0
        self.axis_urad = 0.0
        self.axis_after_urad = None
        #: the blocks corrected in part (:func:`._uncertainty.components_left`), the first one's
        #: line, and per tip component the blocks that leave it
        self.tip_blocks = self.tip_line = 0
        self.tip_each = [0, 0, 0]

    def add(self, r) -> None:
        """Count the blocks of the PlanResult ``r`` (those whose every axis is known)."""
        if r.tip_left is not None:
            part = (np.asarray(r.tip_left) != 0) & ~r.pinned
            if part.any():
                self.tip_blocks += int(part.sum())
                self.tip_line = self.tip_line or int(r.line[np.argmax(part)])
                mask = left_mask(r.tip_left, len(r))[part]
                self.tip_each = [a + int(b) for a, b in zip(self.tip_each, mask.sum(axis=0))]
        left = np.zeros(len(r), bool) if r.axis_left is None else r.axis_left & ~r.pinned
        if r.standing is not None and self.rotary is not None and left.any():
            left &= ~r.standing[:, self.rotary].all(axis=1)
        if r.after_axis is not None and (~left).any():
            aa = float(np.sqrt(np.sum(r.after_axis[~left] ** 2, axis=1)).max()) * 1e6
            self.axis_after_urad = max(self.axis_after_urad or 0.0, aa)
        if left.any():
            self.axis_blocks += int(left.sum())
            self.axis_line = self.axis_line or int(r.line[np.argmax(left)])
            a = np.sqrt(np.sum(r.after_axis[left] ** 2, axis=1)).max() * 1e6
            self.axis_urad = max(self.axis_urad, float(a))

    def as_dict(self) -> dict:
        return {"tool_axis_not_corrected": {"blocks": self.axis_blocks, "line": self.axis_line,
                                            "max_axis_urad": self.axis_urad},
                "components_left": {"blocks": self.tip_blocks, "line": self.tip_line,
                                    **dict(zip("xyz", self.tip_each))}}

    def axis_text(self, before_urad: float, after_urad: float) -> str:
        """The summary's line on the tool-axis deviation: the figure after only over the blocks
        whose tool axis was corrected."""
        line = f"predicted tool-axis deviation: max {before_urad:.3f} urad before, "
        if not self.axis_blocks:
            return line + f"{after_urad:.3f} urad after"
        if self.axis_after_urad is None:
            return line + "not corrected (below)"
        return line + (f"{self.axis_after_urad:.3f} urad after over the blocks whose tool axis was "
                       f"corrected (not corrected at {self.axis_blocks}: below)")

    def tip_lines(self) -> list:
        """The summary's line on the blocks corrected in part (none: [])."""
        if not self.tip_blocks:
            return []
        k = self.tip_blocks
        named = ", ".join(f"{c} at {n}" for c, n in zip("xyz", self.tip_each) if n)
        return [f"{k} block{'' if k == 1 else 's'} corrected in part (first at line {self.tip_line};"
                f" components left: {named}): the correction in those tip components is not "
                "determined by the model's data (a height across the table that rests on a part's "
                "tilt its own alignment took), "
                "while the other components' are within it: the block is corrected in those, and "
                "keeps its deviation in these (BLOCKS.csv components_left); measure there (the "
                "heights with one alignment, e.g. a test bar or a laser along Z) to correct them"]

    def lines(self) -> list:
        """The summary's lines on the blocks whose tool axis was not corrected and on those
        corrected in part (none: [])."""
        if not self.axis_blocks:
            return self.tip_lines()
        k = self.axis_blocks
        return self.tip_lines() + [f"{k} block{'' if k == 1 else 's'} with the tool axis not corrected (first at line "
                f"{self.axis_line}): the standard error of its deviation exceeds {self.limit_urad:g} "
                "urad (--max-correction-sd-um over --orientation-weight) or is not determined by the "
                "model's data (a spindle's tilt, or a rotary axis's, that data taken with one "
                "stylus or tool length do not tell apart), or the deviation is within two of its "
                "standard errors of zero: the rotary axes keep their words (in tool centre point "
                "mode the tool angles stay as written), the linear axes alone correct the tip, and "
                f"the tool-axis deviation stays: up to {self.axis_urad:.3f} urad there (BLOCKS.csv "
                "e_axis_after_urad); measure the tool axis (two stylus lengths, or the spindle's "
                "tilt) to correct it"]

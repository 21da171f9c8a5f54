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
"""
from __future__ import annotations

import numpy as np

from ._rotary_grid import set_turn
from ._uncertainty import in_sd, orientation_left


class PartialRule:
    """The rule for one problem (module docstring); ``limit`` the standard-error limit (um)."""

    def __init__(self, problem, limit):
        self.problem = problem
        self.limit = limit
        self.weight = problem.orientation_weight
        self.rotary = np.array([a.is_rotary for a in problem.machine.axes], bool)
        self.lam = problem.regularization_weights

    @property
    def limit_urad(self) -> float | None:
        """The limit on a tool-axis deviation's standard error, urad: the tip's limit over the
        orientation weight (W um of tip weigh as 1 urad of tool axis); None without a limit."""
        return self.limit / self.weight if self.limit and self.weight > 0 else None

    def judged(self, each, b0):
        """(in_sd, axis_left): (n,) the corrections (``b0``'s tip rows, um) in their standard errors
        ``each`` (n, 3 + k) from :meth:`Planner._sd_um`, the tool axis's (urad) after the tip's on
        5-axis machines (:func:`._uncertainty.in_sd`), and (n,) bool the blocks whose tool-axis
        correction is not made (or None: none); (None, None) without a limit (``each`` None)."""
        if each is None:
            return None, None
        tip = in_sd(b0[:, :3], each[:, :3])
        if each.shape[1] < 6 or self.limit_urad is None:
            return tip, None
        left = orientation_left(b0[:, 3:6] / self.weight, each[:, 3:6], self.limit_urad)
        return tip, (left if left.any() else None)

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

    def add(self, r) -> None:
        """Count the blocks of the PlanResult ``r`` (those whose every axis is known)."""
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
                                            "max_axis_urad": self.axis_urad}}

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

    def lines(self) -> list:
        """The summary's line on the blocks whose tool axis was not corrected (none: [])."""
        if not self.axis_blocks:
            return []
        k = self.axis_blocks
        return [f"{k} block{'' if k == 1 else 's'} with the tool axis not corrected (first at line "
                f"{self.axis_line}): the standard error of its deviation exceeds {self.limit_urad:g} "
                "urad (--max-correction-sd-um over --orientation-weight) or is not determined by the "
                "model's data (a spindle's tilt, or a rotary axis's, that data taken with one "
                "stylus or tool length do not tell apart), or the deviation is within two of its "
                "standard errors of zero: the rotary axes keep their words (in tool centre point "
                "mode the tool angles stay as written), the linear axes alone correct the tip, and "
                f"the tool-axis deviation stays: up to {self.axis_urad:.3f} urad there (BLOCKS.csv "
                "e_axis_after_urad); measure the tool axis (two stylus lengths, or the spindle's "
                "tilt) to correct it"]

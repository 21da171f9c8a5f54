"""Corrections made in part: what the data do not determine of a block's correction is not made,
while the rest of it is (docs/planner.md, *Blocks where the model is unsure*).

* **The tool axis** (5-axis machines): a block's tool-axis correction is the model's tool-axis
  deviation there (probing a datum removes none of it). Where that deviation's standard error
  exceeds the limit (``--max-correction-sd-um`` over ``--orientation-weight``: W um of tip weigh as
  1 urad), is infinite (it moves with what the data leave open: a spindle's tilt that data taken
  with one stylus length do not tell from a table's) or where the deviation is within two of its
  standard errors of zero in every component, the block's rotary axes keep their words (their
  bounds are zero, as ``--max-correction-urad 0`` makes them everywhere) and the linear axes alone
  correct the tip. ``NodeSet.axis_left`` marks it.
* **A tip component** (x, y or z) whose correction is within two of its standard errors of zero
  in a block whose others are told from zero (a contour's component only where it holds on every
  block of the contour, :mod:`._contours`): the plan's target of that component is the deviation
  the block has (its correction left at zero), so the solve keeps that component as it is while it
  corrects the others, also where the axes that correct them move it (a tilted tool).
  ``NodeSet.kept`` marks it, and holds the correction left (um) that the figures before and after
  add back.
"""
from __future__ import annotations

import numpy as np

from ._evaluate import objective_jacobian, objective_residual
from ._rotary_grid import set_turn
from ._small import NormalFactor, a_x
from ._uncertainty import in_sd_each, orientation_left
from ..models.model_file import UNDETERMINED_UM


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
        """(in_sd, axis_left): (n, 3) each tip component of the corrections (``b0``'s tip rows, um)
        in its standard error (``each`` (n, 3 + k) from :meth:`Planner._sd_um`, the tool axis's
        (urad) after the tip's on 5-axis machines), and (n,) bool the blocks whose tool-axis
        correction is not made (or None: none); (None, None) without a limit (``each`` None)."""
        if each is None:
            return None, None
        tip = in_sd_each(b0[:, :3], each[:, :3])
        if each.shape[1] < 6 or self.limit_urad is None:
            return tip, None
        left = orientation_left(b0[:, 3:6] / self.weight, each[:, 3:6], self.limit_urad)
        return tip, (left if left.any() else None)

    def apply(self, nodes, lin) -> None:
        """Set the plan of ``nodes`` to the rule (module docstring), in place: the target of each
        component ``kept`` moved to the block's deviation (``nodes.kept`` then holds the
        correction left, um) and the free correction re-solved for it; the rotary corrections of
        the blocks ``axis_left`` set to zero, the linear ones re-solved for that turn."""
        if nodes.kept is not None:
            # a component under 0.01 um is no question either way (written as it is)
            mask = np.isfinite(nodes.kept) & ~nodes.pinned[:, None]
            mask &= np.abs(lin.b0[:, :3]) >= UNDETERMINED_UM
            nodes.kept = None
            if mask.any():
                self._keep(nodes, lin, mask)
        if nodes.axis_left is not None:
            rows = np.flatnonzero(nodes.axis_left)
            if rows.size:
                sub = lin.take(rows)
                x = set_turn(sub, np.array(sub.x), np.zeros((rows.size, int(self.rotary.sum()))),
                             self.rotary, self.lam)
                lin.x = np.array(lin.x)
                lin.x[rows] = x

    def _keep(self, nodes, lin, mask) -> None:
        S = self.problem.residual_scale
        shift = np.zeros(lin.b0.shape)
        shift[:, :3] = np.where(mask, lin.b0[:, :3], 0.0)
        nodes.kept = np.where(mask, shift[:, :3], np.nan)
        lin.b0 = lin.b0 - shift
        lin.b = lin.b - shift
        lin.target = lin.target + shift / S
        rows = np.flatnonzero(mask.any(axis=1))
        A, M = lin.A[rows], lin.orientation_rows[rows]
        c = objective_residual(M, lin.b[rows] + a_x(A, lin.x[rows] - lin.x_lin[rows]))
        lin.x = np.array(lin.x)
        lin.x[rows] += NormalFactor(objective_jacobian(M, A), self.lam).step(c, lin.x[rows])

    def restore(self, nodes, before, after) -> None:
        """The figures ``before`` and ``after`` (n, rows, mm) of ``nodes`` with the correction left
        in their ``kept`` components added back (the plan's target was moved by it), in place."""
        if nodes.kept is not None:
            back = np.nan_to_num(nodes.kept) / self.problem.residual_scale[:3]
            before[:, :3] += back
            after[:, :3] += back


class PartialTally:
    """What the summary says of the rule (module docstring): the blocks whose tool axis was not
    corrected and the largest tool-axis deviation they keep, the blocks corrected without some tip
    component (per component), each with the first one's line; and the largest tool-axis deviation
    after over the blocks whose tool axis was corrected (None: no such block)."""

    def __init__(self, limit_urad: float | None = None, rotary=None):
        #: the limit on the tool-axis deviation's standard error (:attr:`PartialRule.limit_urad`)
        #: and the machine's rotary axes ((na,) bool)
        self.limit_urad, self.rotary = limit_urad, rotary
        self.axis_blocks = self.axis_line = 0
        self.axis_urad = 0.0
        self.kept_blocks = self.kept_line = 0
        self.kept_counts = [0, 0, 0]
        self.axis_after_urad = None

    def add(self, r) -> None:
        """Count the blocks of the PlanResult ``r`` (those whose every axis is known)."""
        left = np.zeros(len(r), bool) if r.axis_left is None else r.axis_left & ~r.pinned
        if r.standing is not None and self.rotary is not None and left.any():
            # the program holds the rotary axes there anyway (its own summary line)
            left &= ~r.standing[:, self.rotary].all(axis=1)
        if r.after_axis is not None and (~left).any():
            aa = float(np.sqrt(np.sum(r.after_axis[~left] ** 2, axis=1)).max()) * 1e6
            self.axis_after_urad = max(self.axis_after_urad or 0.0, aa)
        if left.any():
            self.axis_blocks += int(left.sum())
            self.axis_line = self.axis_line or int(r.line[np.argmax(left)])
            a = np.sqrt(np.sum(r.after_axis[left] ** 2, axis=1)).max() * 1e6
            self.axis_urad = max(self.axis_urad, float(a))
        if r.kept is not None:
            kept = r.kept & ~r.pinned[:, None]
            some = kept.any(axis=1)
            if some.any():
                self.kept_blocks += int(some.sum())
                self.kept_line = self.kept_line or int(r.line[np.argmax(some)])
                for k in range(3):
                    self.kept_counts[k] += int(kept[:, k].sum())

    def as_dict(self) -> dict:
        return {"tool_axis_not_corrected": {"blocks": self.axis_blocks, "line": self.axis_line,
                                            "max_axis_urad": self.axis_urad},
                "tip_components_not_corrected": {"blocks": self.kept_blocks,
                                                 "line": self.kept_line,
                                                 **dict(zip("xyz", self.kept_counts))}}

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
        """The summary's lines on the blocks the rule acted on."""
        out = []
        if self.axis_blocks:
            out.append(
                f"{_blocks(self.axis_blocks)} with the tool axis not corrected (first at line "
                f"{self.axis_line}): the standard error of its deviation exceeds {self.limit_urad:g} urad "
                "(--max-correction-sd-um over --orientation-weight) or is not determined by the "
                "model's data (a spindle's tilt, or a rotary axis's, that data taken with one "
                "stylus or tool length do not tell apart), or the deviation is within two of its "
                "standard errors of zero: the rotary axes keep their words (in tool centre point "
                "mode the tool angles stay as written), the linear axes alone correct the tip, and "
                f"the tool-axis deviation stays: up to {self.axis_urad:.3f} urad there (BLOCKS.csv "
                "e_axis_after_urad); measure the tool axis (two stylus lengths, or the spindle's "
                "tilt) to correct it")
        if self.kept_blocks:
            what = ", ".join(f"{c} {k}" for c, k in zip("xyz", self.kept_counts) if k)
            out.append(
                f"{_blocks(self.kept_blocks)} corrected without a component of the tip ({what}; "
                f"first at line {self.kept_line}): that component's correction is within two of "
                "its standard errors of zero (over a contour, on every one of its blocks), so the "
                "data do not tell it from none; it is left as it is (BLOCKS.csv e*_after_um), the "
                "other components corrected")
        return out


def _blocks(k: int) -> str:
    return f"{k} block" if k == 1 else f"{k} blocks"

"""The residual the planner drives to zero, and its Jacobian, in optimisation units.

For a block with nominal axis positions q (mm, rad) and context c, and a correction x (um for linear
axes, urad for rotary axes; dq = x / axis_scale):

    r(x) = actual_pose(q + dq, c) - nominal_pose(q)
         = nominal(q + dq) + deviation(q + dq, c) - nominal(q)

(tip rows in mm; on 5-axis machines also the tool-axis rows), returned weighted: ``b = S r`` with S
from :attr:`CompensationProblem.residual_scale` (um, and urad times the orientation weight), and the
Jacobian ``A = S (J_nominal + J_q) / axis_scale`` (weighted residual per um or urad of correction).
"""
from __future__ import annotations

import threading

import numpy as np

from ..models.evaluate import evaluate
from ._nominal import nominal_pose, nominal_pose_jacobian
from .problem import CompensationProblem


class Evaluator:
    """Residuals and Jacobians of one problem, vectorised over blocks."""

    def __init__(self, problem: CompensationProblem):
        self.problem = problem
        self.model = problem.fitted.model
        self.p = np.asarray(problem.fitted.params.values, dtype=float)
        self.machine = problem.machine
        self.rows = 6 if problem.correct_orientation else 3
        self.S = problem.residual_scale
        self.D = problem.axis_scale
        self.evaluations = 0
        self._count_lock = threading.Lock()     # parts of a chunk are evaluated in threads

    def _count(self, n: int):
        with self._count_lock:
            self.evaluations += n

    def _deviation(self, q, ctx):
        """(n, 6) the model's deviation at q, evaluated at the held position of every axis the
        model's data held still (FittedModel.clamp)."""
        return evaluate(self.model, "deviation_function", self.problem.fitted.clamp(q)[0], self.p, ctx)[0]

    def _deviation_and_qjacobian(self, q, ctx):
        """(deviation (n, 6), d deviation / d q (n, 6, n_axes)) as :meth:`_deviation`: along a held
        axis the deviation does not change."""
        qc, held = self.problem.fitted.clamp(q)
        dev, Jd = evaluate(self.model, "deviation_qjacobian_function", qc, self.p, ctx)
        if held:
            Jd = np.array(Jd, copy=True)
            Jd[:, :, held] = 0.0
        return dev, Jd

    def target(self, q: np.ndarray) -> np.ndarray:
        """(n, rows) nominal pose (tip mm, tool axis) of q: what the program means."""
        tip, axis = nominal_pose(self.machine, q)
        return tip if self.rows == 3 else np.concatenate([tip, axis], axis=1)

    def residual_jacobian(self, q, x, ctx, target=None):
        """Weighted residual b (n, rows) and Jacobian A (n, rows, n_axes) at corrections x (n, n_axes)
        (None: zero).

        Returns (b, A, target): target (n, rows) is computed when not given (at x = 0 it is free).
        """
        q = np.asarray(q, dtype=float)
        zero = x is None or not np.any(x)
        qq = q if zero else q + x / self.D
        dev, Jd = self._deviation_and_qjacobian(qq, ctx)
        tip, axis, Jn = nominal_pose_jacobian(self.machine, qq)
        self._count(q.shape[0])
        rows = self.rows
        if target is None:
            target = (tip if rows == 3 else np.concatenate([tip, axis], axis=1)) if zero \
                else self.target(q)
        r = dev[:, :rows] + tip if rows == 3 else dev + np.concatenate([tip, axis], axis=1)
        r -= target
        r *= self.S
        # stored entry by entry, (rows, n_axes, n) contiguous, returned as its (n, rows, n_axes)
        # view: every entry is one contiguous vector (as NormalFactor and a_x read them)
        na = Jd.shape[2]
        scale = self.S[:, None] / self.D[None, :]
        Jt = np.empty((rows, na, q.shape[0]))
        for i in range(rows):
            for j in range(na):
                np.add(Jd[:, i, j], Jn[:, i, j], out=Jt[i, j])
                if scale[i, j] != 1.0:
                    Jt[i, j] *= scale[i, j]
        return r, Jt.transpose(2, 0, 1), target

    def residual(self, q, x, ctx, target):
        """Weighted residual b (n, rows) only (cheaper: no Jacobian of the model)."""
        q = np.asarray(q, dtype=float)
        qq = q + x / self.D
        dev = self._deviation(qq, ctx)
        self._count(q.shape[0])
        r = dev[:, :self.rows] + self.target(qq)
        r -= target
        r *= self.S
        return r

    def deviation_only(self, q, ctx):
        """Weighted model deviation (n, rows) at q (the residual of the uncorrected program)."""
        dev = self._deviation(q, ctx)
        return dev[:, :self.rows] * self.S

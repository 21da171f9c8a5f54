"""Per-block solutions without bounds: the pseudo-inverse step of Qi and Yang (2016) and its Newton
iteration.

Qi and Yang (2016), eqs. 27-30: the machine Jacobian J maps axis motions to the tool's motion; the
axis corrections that cancel an error E are ``dq = (J^T J)^-1 J^T E`` subtracted from the nominal
motion, i.e. ``dq = -pinv(J) e`` with e the deviation (actual minus nominal). Here J is the Jacobian of the
*actual* tool pose (nominal kinematics plus the error model's J_q) and e is the weighted residual of
:mod:`mtcomp.planner._evaluate` (tip in um, tool axis in urad on 5-axis machines, where the tool-axis
deviation vector takes the place of the paper's three small rotation angles). Both minimise the
objective of :mod:`mtcomp.planner._evaluate`: the tool-axis rows count only in the directions the
rotary axes can turn the tool at the block (``orientation_rows``), so at a singular pose they do not
turn a rotary axis after a deviation it cannot remove.

``newton`` iterates that step on the exact model (Gauss-Newton, with the problem's small
regularisation so that it solves the same problem as the QP when no bound is active).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._evaluate import Evaluator, objective_jacobian, objective_residual
from ._small import NormalFactor, a_x, normal_step, row_max_abs


@dataclass
class Linearization:
    """Where the residual was last linearised, per block: b(x) ~ b + A (x - x_lin).

    x : (n, na) corrections found (um, urad). x_lin : (n, na). b : (n, rows). A : (n, rows, na).
    b0 : (n, rows) weighted residual of the uncorrected block (x = 0). target : (n, rows) nominal pose.
    iterations : (n,) evaluations used. converged : (n,) bool.
    orientation_rows : (n, 3, 3), (n, 0, 0) on 3-axis machines: the objective counts the tool-axis
        rows e of b as ``orientation_rows @ e`` (:meth:`Evaluator.orientation_rows`); fixed per block.
    """

    x: np.ndarray
    x_lin: np.ndarray
    b: np.ndarray
    A: np.ndarray
    b0: np.ndarray
    target: np.ndarray
    iterations: np.ndarray
    converged: np.ndarray
    orientation_rows: np.ndarray

    FIELDS = ("x", "x_lin", "b", "A", "b0", "target", "iterations", "converged", "orientation_rows")

    def predict(self, x: np.ndarray) -> np.ndarray:
        """(n, rows) weighted residual at corrections x, to first order around x_lin."""
        return self.b + a_x(self.A, x - self.x_lin)

    def take(self, idx) -> "Linearization":
        return Linearization(*(getattr(self, f)[idx] for f in Linearization.FIELDS))

    def objective(self) -> tuple[np.ndarray, np.ndarray]:
        """(c (n, rows), A (n, rows, na)): the objective's residual ``c + A x`` as a function of the
        corrections x, linearised at x_lin."""
        Aw = objective_jacobian(self.orientation_rows, self.A)
        c = objective_residual(self.orientation_rows, self.b)
        c = c - a_x(Aw, self.x_lin)
        return c, Aw

    @staticmethod
    def concatenate(parts: list["Linearization"]) -> "Linearization":
        return Linearization(*(np.concatenate([getattr(p, f) for p in parts])
                               for f in Linearization.FIELDS))


def pinv_step(A: np.ndarray, b: np.ndarray, lam=0.0) -> np.ndarray:
    """Qi and Yang (2016), eqs. 29-30: the correction ``-(A^T A)^-1 A^T b`` of each block (the normal
    equations of eq. 29; with ``lam`` > 0 regularised: ``-(A^T A + diag(lam))^-1 A^T b``, which stays finite at
    singular poses). A (n, rows, na), b (n, rows), lam a number or (na,)."""
    if np.all(np.asarray(lam) <= 0):
        return -np.einsum("nij,nj->ni", np.linalg.pinv(A), b)
    return normal_step(A, b, None, lam)


def regularized_step(A: np.ndarray, b: np.ndarray, x: np.ndarray, lam) -> np.ndarray:
    """Gauss-Newton step of min ||b + A dx||^2 + sum_j lam_j (x + dx)_j^2 per block: (n, na)."""
    return normal_step(A, b, x, lam)


def solve_pinv(ev: Evaluator, q: np.ndarray, ctx: np.ndarray, lam=0.0, reference=None) -> Linearization:
    """One pseudo-inverse step (Qi and Yang 2016) per block at the nominal position (no iteration).
    reference: see :meth:`Evaluator.residual_jacobian_rows`."""
    n, na = q.shape
    b0, A0, target, M = ev.residual_jacobian_rows(q, ctx, reference)
    x = pinv_step(objective_jacobian(M, A0), objective_residual(M, b0), lam)
    return Linearization(x, np.zeros_like(x), b0, A0, b0, target, np.ones(n, int), np.ones(n, bool), M)


def solve_newton(ev: Evaluator, q: np.ndarray, ctx: np.ndarray, lam, tol: float,
                 max_iterations: int, reference=None) -> Linearization:
    """Per-block Newton iteration of the (regularised) pseudo-inverse step until the step is below tol.

    Every block is iterated on its own; blocks that have converged are not evaluated again. The
    Jacobian is kept while the step shrinks at least tenfold per iteration (the chord method: the
    model's Jacobian changes by ~1e-4 over a correction, so this converges to the same point) and
    re-evaluated with the residual otherwise.
    """
    n, na = q.shape
    x = np.zeros((n, na))
    b, A, target, M = ev.residual_jacobian_rows(q, ctx, reference)
    b0 = b.copy()
    x_lin = x.copy()
    iterations = np.ones(n, int)
    converged = np.zeros(n, bool)
    active = np.arange(n)
    last = np.full(n, np.inf)
    factor = None                         # of the blocks in sel, while their A is kept
    for _ in range(max_iterations):
        every = active.size == n          # plain slices while every block is still iterating
        sel = slice(None) if every else active
        if factor is None:
            factor = NormalFactor(objective_jacobian(M[sel], A[sel]), lam)
        dx = factor.step(objective_residual(M[sel], b[sel]), x[sel])
        x[sel] += dx
        size = row_max_abs(dx)
        done = size < tol
        slow = size > 0.1 * last[sel]
        last[sel] = size
        if np.any(done):
            converged[active[done]] = True
            active, slow = active[~done], slow[~done]
            every = False
            factor = factor.take(~done) if active.size else None
        if active.size == 0:
            break
        if not np.any(slow):
            refresh, keep = None, (slice(None) if every else active)
        elif np.all(slow):
            refresh, keep = (slice(None) if every else active), None
        else:
            refresh, keep = active[slow], active[~slow]
        if refresh is not None:
            factor = None
            bb, AA, _ = ev.residual_jacobian(q[refresh], x[refresh], ctx[refresh], target[refresh])
            b[refresh], A[refresh], x_lin[refresh] = bb, AA, x[refresh]
        if keep is not None:
            # b(x) exactly, A from before: store the linearisation point so that predict() holds
            bb = ev.residual(q[keep], x[keep], ctx[keep], target[keep])
            b[keep], x_lin[keep] = bb, x[keep]
        iterations[sel if every else active] += 1
    return Linearization(x, x_lin, b, A, b0, target, iterations, converged, M)

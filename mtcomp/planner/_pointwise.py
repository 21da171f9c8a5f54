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
    held : (n, rows) the weighted deviation of the tip components the target holds (zero elsewhere,
        :meth:`Evaluator.residual_jacobian_rows`): b0 + held is the uncorrected block's residual
        against the program's pose, b + held the corrected one's.
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
    held: np.ndarray | None = None

    def __post_init__(self):
        if self.held is None:
            self.held = np.zeros(self.b.shape)

    FIELDS = ("x", "x_lin", "b", "A", "b0", "target", "iterations", "converged", "orientation_rows",
              "held")

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
    def empty(na: int, rows: int, k: int) -> "Linearization":
        """No blocks (na axes, rows residual rows, k tool-axis rows of the objective)."""
        z = np.zeros
        return Linearization(z((0, na)), z((0, na)), z((0, rows)), z((0, rows, na)), z((0, rows)),
                             z((0, rows)), z(0, int), z(0, bool), z((0, k, k)), z((0, rows)))

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
    b0, A0, target, M, held = ev.residual_jacobian_rows(q, ctx, reference)
    x = pinv_step(objective_jacobian(M, A0), objective_residual(M, b0), lam)
    return Linearization(x, np.zeros_like(x), b0, A0, b0, target, np.ones(n, int), np.ones(n, bool), M,
                         held)


def solve_newton(ev: Evaluator, q: np.ndarray, ctx: np.ndarray, lam, tol: float,
                 max_iterations: int, reference=None) -> Linearization:
    """Per-block Newton iteration of the (regularised) pseudo-inverse step until the step is below tol.

    Every block is iterated on its own; the Jacobian is kept while the step shrinks at least
    tenfold per iteration (the chord method: the model's Jacobian changes by ~1e-4 over a
    correction, so this converges to the same point) and re-evaluated with the residual otherwise.
    Blocks that have converged keep their values. While most blocks still iterate, every block is
    computed and only those still iterating are updated (:func:`_whole_iteration`: a few blocks
    done early, e.g. where the deviation is zero, no longer make every array of the chunk copied
    to and from the rest); once fewer than :data:`WHOLE_SHARE` do, only those are evaluated.
    """
    n, na = q.shape
    *rows, held = ev.residual_jacobian_rows(q, ctx, reference)
    st = _NewtonState(q, ctx, *rows, na)
    for _ in range(max_iterations):
        if st.live is not None or st.active.size == n:
            _whole_iteration(ev, st, lam, tol)
        else:
            _compact_iteration(ev, st, lam, tol)
        if st.active.size == 0:
            break
    return Linearization(st.x, st.x_lin, st.b, st.A, st.b0, st.target, st.iterations, st.converged,
                         st.M, held)


#: the share of a chunk's blocks that must still iterate for :func:`solve_newton` to compute every
#: block (an evaluation of a converged block costs less than copying the others out and back)
WHOLE_SHARE = 0.75


class _NewtonState:
    """What :func:`solve_newton` iterates: the blocks' values, ``active`` (indices of the blocks
    still iterating), ``live`` ((n,) bool of them while every block is computed; None at first,
    when all iterate, and once only the active ones are), the factor of the kept Jacobians (of
    every block, or of the active ones only) and each block's last step size."""

    def __init__(self, q, ctx, b, A, target, M, na):
        n = q.shape[0]
        self.q, self.ctx, self.b, self.A, self.target, self.M = q, ctx, b, A, target, M
        self.x = np.zeros((n, na))
        self.b0 = b.copy()
        self.x_lin = self.x.copy()
        self.iterations = np.ones(n, int)
        self.converged = np.zeros(n, bool)
        self.active = np.arange(n)
        self.live = None
        self.last = np.full(n, np.inf)
        self.factor = None


def _whole_iteration(ev: Evaluator, st: _NewtonState, lam, tol: float) -> None:
    """One Newton iteration computed on every block, kept for the live ones (all when st.live is
    None): per block the same numbers as :func:`_compact_iteration` gives them."""
    live = st.live
    if st.factor is None:
        st.factor = NormalFactor(objective_jacobian(st.M, st.A), lam)
    dx = st.factor.step(objective_residual(st.M, st.b), st.x)
    if live is None:
        st.x += dx
    else:
        np.add(st.x, dx, out=st.x, where=live[:, None])
    size = row_max_abs(dx)
    done = size < tol
    slow = size > 0.1 * st.last
    if live is None:
        st.last[:] = size
    else:
        np.copyto(st.last, size, where=live)
        done &= live
        slow &= live
    if np.any(done):
        st.converged[done] = True
        live = ~st.converged if live is None else live & ~done
        st.active = np.flatnonzero(live)
        if st.active.size < WHOLE_SHARE * live.size:
            # from here on only the active blocks are computed (positions in st.active)
            st.live = None
            st.factor = st.factor.take(st.active) if st.active.size else None
            if st.active.size:
                _relinearise(ev, st, st.active, slow[st.active])
            return
        st.live = live
    if st.active.size == 0:
        return
    if np.any(slow):            # a Jacobian to evaluate again: as on the active blocks alone
        _relinearise(ev, st, st.active, slow[st.active])
        return
    # b(x) exactly, A from before: store the linearisation point so that predict() holds
    bb = ev.residual(st.q, st.x, st.ctx, st.target)
    if st.live is None:
        st.b[:] = bb
        st.x_lin[:] = st.x
        st.iterations += 1
    else:
        keep = st.live[:, None]
        np.copyto(st.b, bb, where=keep)
        np.copyto(st.x_lin, st.x, where=keep)
        np.add(st.iterations, 1, out=st.iterations, where=st.live)


def _compact_iteration(ev: Evaluator, st: _NewtonState, lam, tol: float) -> None:
    """One Newton iteration on the active blocks only (st.factor is theirs)."""
    active = st.active
    if st.factor is None:
        st.factor = NormalFactor(objective_jacobian(st.M[active], st.A[active]), lam)
    dx = st.factor.step(objective_residual(st.M[active], st.b[active]), st.x[active])
    st.x[active] += dx
    size = row_max_abs(dx)
    done = size < tol
    slow = size > 0.1 * st.last[active]
    st.last[active] = size
    if np.any(done):
        st.converged[active[done]] = True
        st.active, slow = active[~done], slow[~done]
        st.factor = st.factor.take(~done) if st.active.size else None
    if st.active.size:
        _relinearise(ev, st, st.active, slow)


def _relinearise(ev: Evaluator, st: _NewtonState, active, slow) -> None:
    """The residual at the new corrections of the active blocks (index array), with the Jacobian
    again for the slow ones (their factor dropped)."""
    if not np.any(slow):
        refresh, keep = None, active
    elif np.all(slow):
        refresh, keep = active, None
    else:
        refresh, keep = active[slow], active[~slow]
    if refresh is not None:
        st.factor = None
        bb, AA, _ = ev.residual_jacobian(st.q[refresh], st.x[refresh], st.ctx[refresh],
                                         st.target[refresh])
        st.b[refresh], st.A[refresh], st.x_lin[refresh] = bb, AA, st.x[refresh]
    if keep is not None:
        # b(x) exactly, A from before: store the linearisation point so that predict() holds
        bb = ev.residual(st.q[keep], st.x[keep], st.ctx[keep], st.target[keep])
        st.b[keep], st.x_lin[keep] = bb, st.x[keep]
    st.iterations[active] += 1

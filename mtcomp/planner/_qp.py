"""The windowed QP: one OSQP problem per window size, built once, then updated and warm-started.

Variables of a window: the corrections of ``n + 1`` blocks in optimisation units (um, urad), block
0 being the anchor (the last block committed by the previous window, fixed by its bounds) and blocks
1..n the window. Node-major order: x[i * na + j].

    minimise    1/2 sum_i ||b_i + A_i (x_i - x_lin,i)||^2 + 1/2 sum_i x_i^T diag(lam) x_i
    subject to  l_i <= x_i <= u_i                         (correction bound and travel, per block)
                -S_j <= x_i,j - x_(i-1),j <= S_j          (step bound; +-inf where exempt)

with b_i, A_i the objective's residual and Jacobian (``Linearization.objective``) and lam the
per-axis regularisation (``CompensationProblem.regularization_weights``). P is block diagonal (upper
triangle stored, fixed pattern), A is constant: identity rows then difference rows. Only P's values, q, l and u change between windows and SQP iterations.
"""
from __future__ import annotations

import numpy as np


class WindowQP:
    """An OSQP problem for windows of ``n_nodes`` blocks (anchor included) of ``na`` axes."""

    def __init__(self, n_nodes: int, na: int, eps: float = 1e-7):
        import osqp                      # imported here: most programs never need a QP
        import scipy.sparse as sp
        self.N, self.na = int(n_nodes), int(na)
        N, na = self.N, self.na
        nv = N * na
        # upper triangle of each na x na block, column-major, as (row, col) within the block
        self._tri_r, self._tri_c = [], []
        for c in range(na):
            for r in range(c + 1):
                self._tri_r.append(r)
                self._tri_c.append(c)
        self._tri_r = np.array(self._tri_r)
        self._tri_c = np.array(self._tri_c)
        indptr = [0]
        indices = []
        for i in range(N):
            for c in range(na):
                indices.extend(range(i * na, i * na + c + 1))
                indptr.append(len(indices))
        H0 = np.broadcast_to(np.eye(na), (N, na, na))
        P = sp.csc_matrix((self._p_data(H0), np.array(indices), np.array(indptr)), shape=(nv, nv))
        rows = np.arange((N - 1) * na)
        D = sp.csc_matrix((np.concatenate([np.ones(rows.size), -np.ones(rows.size)]),
                           (np.concatenate([rows, rows]), np.concatenate([rows + na, rows]))),
                          shape=((N - 1) * na, nv))
        A = sp.vstack([sp.identity(nv, format="csc"), D], format="csc")
        self.m = A.shape[0]
        self.solver = osqp.OSQP()
        self.solver.setup(P, np.zeros(nv), A, -np.ones(self.m), np.ones(self.m), verbose=False,
                          eps_abs=eps, eps_rel=eps, polishing=True, max_iter=200000,
                          warm_starting=True, adaptive_rho=True, polish_refine_iter=10)
        self.solves = 0

    def _p_data(self, H: np.ndarray) -> np.ndarray:
        return np.ascontiguousarray(H[:, self._tri_r, self._tri_c]).reshape(-1)

    def solve(self, H, g, lower, upper, step_lo, step_hi, x0):
        """Solve one window.

        H : (N, na, na) Hessian blocks. g : (N, na) linear term. lower, upper : (N, na) bounds of x.
        step_lo, step_hi : (N - 1, na) bounds of x_i - x_(i-1), i = 1..N-1. x0 : (N, na) warm start.
        Returns (x (N, na), status string).
        """
        l = np.concatenate([lower.reshape(-1), step_lo.reshape(-1)])
        u = np.concatenate([upper.reshape(-1), step_hi.reshape(-1)])
        self.solver.update(Px=self._p_data(H), q=np.ascontiguousarray(g.reshape(-1)), l=l, u=u)
        self.solver.warm_start(x=np.ascontiguousarray(x0.reshape(-1)))
        res = self.solver.solve(raise_error=False)
        self.solves += 1
        return np.asarray(res.x).reshape(self.N, self.na), res.info.status

"""The windowed QP: one OSQP problem per window size, built once, then updated and warm-started.

Variables of a window: the corrections of ``n + 1`` blocks in optimisation units (um, urad), block
0 being the anchor (the last block committed by the previous window, fixed by its bounds) and blocks
1..n the window. Node-major order: x[i * na + j].

    minimise    1/2 sum_i ||b_i + A_i (x_i - x_lin,i)||^2 + 1/2 sum_i x_i^T diag(lam) x_i
    subject to  l_i <= x_i <= u_i                         (correction bound and travel, per block)
                -S_j <= x_i,j - x_(i-1),j <= S_j          (step bound; +-inf where exempt)

                |b_i + A_i (x_i - x_lin,i)| <= |b0_i| + tau        (never worse, per row, i >= 1)

with b_i, A_i the objective's residual and Jacobian (``Linearization.objective``), b0_i the residual
of the uncorrected block, and lam the per-axis regularisation
(``CompensationProblem.regularization_weights``). The last rows keep every block at least as good
as uncorrected in each direction the objective counts (to ``tau``, the output grid's rounding):
where the bounds do not let a correction follow the error (a backlash reversal under the step
bound), the blocks on either side are corrected partly rather than pushed past their error. P is
block diagonal (upper triangle stored, fixed pattern); A is identity rows, difference rows (both
constant) and the blocks' Jacobians (values change, pattern fixed). Only P's and A's values, q, l
and u change between windows and SQP iterations.
"""
from __future__ import annotations

import sys
import threading

import numpy as np

from ._bounds import INF

#: OSQP's status value when it stopped on a Ctrl-C (osqp.interface.SolverStatus.OSQP_SIGINT): OSQP
#: catches SIGINT during a solve and returns, so the interrupt is raised again here
OSQP_SIGINT = 10
#: ... and when it stopped at its iteration limit (OSQP_MAX_ITER_REACHED)
OSQP_MAX_ITER_REACHED = 7


#: OSQP's iterations at most on one window (its setting ``max_iter``). OSQP (first-order, ADMM)
#: solves the common window in tens of iterations, and the planner's tests' hardest in 17,475; a
#: window of 2,011 blocks under a backlash's reversal rule (a user's router program) had not
#: converged after 20,000 (11 s) and took 200,000 (245 s of a loaded machine) to "solved
#: inaccurate". Past this count the window goes to the interior-point solver below.
OSQP_MAX_ITER = 20000


#: whether :func:`prefetch_solver` has started its thread in this process
_prefetching = False


def prefetch_solver() -> None:
    """Import OSQP and scipy.sparse (0.13-0.16 s of CPU, almost all of it scipy.sparse's own
    imports) in a thread of their own, once per process: a long program planned
    with CPUs to spare has them imported by the time its first window needs the QP, instead of its
    planning thread stopping for them there. An import that fails is left to that window to raise
    (with its message)."""
    global _prefetching
    if _prefetching or "osqp" in sys.modules:
        return
    _prefetching = True

    def work():
        try:
            import osqp  # noqa: F401
            import scipy.sparse  # noqa: F401
        except Exception:            # raised again where the QP is set up
            pass
    threading.Thread(target=work, name="mtcomp-import-qp", daemon=True).start()


def osqp_solve(solver):
    """``solver.solve()`` (an ``osqp.OSQP``), its result; KeyboardInterrupt when a Ctrl-C stopped it
    (OSQP traps the signal and returns its best iterate so far: planning on with that would write a
    program the user asked not to have)."""
    res = solver.solve(raise_error=False)
    if res.info.status_val == OSQP_SIGINT:
        raise KeyboardInterrupt
    return res


def _with_data(pattern, data: np.ndarray):
    """The sparse matrix ``pattern`` (CSC) with the values ``data`` (no copy of its structure)."""
    m = pattern.copy()
    m.data = data
    return m


_CLARABEL_STATUS = {"Solved": "solved", "AlmostSolved": "solved inaccurate",
                    "PrimalInfeasible": "primal infeasible",
                    "AlmostPrimalInfeasible": "primal infeasible"}


def interior_point_solve(P, q, A, lower, upper):
    """``min 1/2 x'Px + q'x`` s.t. ``lower <= A x <= upper`` (OSQP's form: P upper triangle, CSC;
    bounds of magnitude >= INF are absent, equal ones equalities) by Clarabel's interior-point
    method, which converges in a few tens of iterations whatever the conditioning, where OSQP
    did not within OSQP_MAX_ITER. Returns (x, status in OSQP's words: 'solved', 'solved
    inaccurate', 'primal infeasible', or Clarabel's own)."""
    import clarabel
    import scipy.sparse as sp
    eq = lower == upper
    hi = ~eq & (upper < INF)
    lo = ~eq & (lower > -INF)
    M = sp.vstack([A[eq], A[hi], -A[lo]], format="csc")
    b = np.concatenate([upper[eq], upper[hi], -lower[lo]])
    cones = [clarabel.ZeroConeT(int(eq.sum())), clarabel.NonnegativeConeT(int(hi.sum() + lo.sum()))]
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    sol = clarabel.DefaultSolver(sp.triu(P, format="csc"), np.asarray(q, float), M, b, cones,
                                 settings).solve()
    status = str(sol.status)
    return np.asarray(sol.x, dtype=float), _CLARABEL_STATUS.get(status, status)


def solve_data(solver, data):
    """(x, status) of the QP an ``osqp.OSQP`` ``solver`` was set up (or updated) with: OSQP's
    solution, or the interior-point one where OSQP ran out of iterations
    (:func:`interior_point_solve` of ``data()``, a callable returning the same problem's P, q, A,
    lower, upper: built only then, not on every window)."""
    res = osqp_solve(solver)
    if res.info.status_val != OSQP_MAX_ITER_REACHED:
        x = res.x                        # None, or Nones, where OSQP has no iterate (infeasible)
        x = None if x is None or (len(x) and x[0] is None) else np.asarray(x, dtype=float)
        return x, res.info.status
    return interior_point_solve(*data())

#: a bounded window keeps every block's deviation, per direction the objective counts, within this
#: (um, or the weighted urad of the tool axis) of the uncorrected one: half the output grid (the
#: written correction is rounded to it)
NEVER_WORSE_TOL = 0.05


def never_worse_rows(b0: np.ndarray, c: np.ndarray, A: np.ndarray, reachable: np.ndarray):
    """(J, lo, hi) of the never-worse rows of a window's nodes: ``|c + A x| <= |b0| + NEVER_WORSE_TOL``
    per objective row (b0 (n, rows) the objective's residual of the uncorrected blocks, c + A x its
    linearisation); no bound where a node cannot reach zero correction (``reachable`` False)."""
    room = np.abs(b0) + NEVER_WORSE_TOL
    lo, hi = -room - c, room - c
    lo[~reachable], hi[~reachable] = -INF, INF
    return A, lo, hi


def reachable_nodes(prev: np.ndarray | None, free: np.ndarray, S: np.ndarray) -> np.ndarray:
    """(n,) bool: nodes of a window that zero correction can reach from its anchor ``prev`` (the
    last committed correction, None at the start) through the step bound S: the anchor's distance
    from zero in steps; a node free of the step bound (``free``) resets it."""
    n = free.size
    if prev is None:
        return np.ones(n, dtype=bool)
    with np.errstate(divide="ignore", invalid="ignore"):
        need = np.max(np.where(S > 0, np.abs(prev) / S, 0.0))
    since = np.arange(1, n + 1, dtype=float)
    last_free = np.maximum.accumulate(np.where(free, np.arange(n), -1))
    since = np.where(last_free >= 0, np.inf, since)
    return since >= need - 1e-9


class WindowQP:
    """An OSQP problem for windows of ``n_nodes`` blocks (anchor included) of ``na`` axes."""

    def __init__(self, n_nodes: int, na: int, rows: int, eps: float = 1e-7):
        import osqp                      # imported here: most programs never need a QP
        import scipy.sparse as sp
        self.N, self.na, self.rows = int(n_nodes), int(na), int(rows)
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
        # marks: -1 for +1 entries, -3 for -1 entries (told apart from the Jacobian's ids >= 2)
        D = sp.csc_matrix((np.concatenate([-np.ones(rows.size), -3 * np.ones(rows.size)]),
                           (np.concatenate([rows, rows]), np.concatenate([rows + na, rows]))),
                          shape=((N - 1) * na, nv))
        A = sp.vstack([-sp.identity(nv, format="csc"), D, self._jacobian_rows(sp)], format="csc")
        # where each Jacobian entry sits in A.data (CSC order): entry k of the blocks (node-major,
        # row-major within a block) was stored as the value k + 2 in the pattern matrix above
        order = np.rint(A.data).astype(np.int64)
        self._fixed = np.where(order == -1, 1.0, -1.0)    # the identity and difference rows
        self._jac_pos = np.flatnonzero(order >= 2)
        self._jac_src = order[self._jac_pos] - 2
        self.m = A.shape[0]
        A.data = self._values(np.zeros((N - 1, self.rows, na)))
        self.solver = osqp.OSQP()
        self._P, self._A = P, A                    # the patterns, for the interior-point solver
        self.solver.setup(P, np.zeros(nv), A, -np.ones(self.m), np.ones(self.m), verbose=False,
                          eps_abs=eps, eps_rel=eps, polishing=True, max_iter=OSQP_MAX_ITER,
                          warm_starting=True, adaptive_rho=True, polish_refine_iter=10)
        self.solves = 0

    def _p_data(self, H: np.ndarray) -> np.ndarray:
        return np.ascontiguousarray(H[:, self._tri_r, self._tri_c]).reshape(-1)

    def _jacobian_rows(self, sp):
        """The pattern of the never-worse rows: block i (rows x na) of nodes 1..N-1 at columns of node
        i, its entries numbered 2, 3, ... node-major and row-major."""
        N, na, r = self.N, self.na, self.rows
        node, row, col = np.meshgrid(np.arange(1, N), np.arange(r), np.arange(na), indexing="ij")
        ids = np.arange(node.size, dtype=float) + 2
        return sp.csc_matrix((ids, (((node - 1) * r + row).reshape(-1),
                                    (node * na + col).reshape(-1))), shape=((N - 1) * r, N * na))

    def _values(self, J: np.ndarray) -> np.ndarray:
        """A.data (CSC order) with the Jacobian blocks J (N - 1, rows, na) of nodes 1..N-1."""
        data = self._fixed.copy()
        data[self._jac_pos] = J.reshape(-1)[self._jac_src]
        return data

    def solve(self, H, g, lower, upper, step_lo, step_hi, x0, J=None, worse_lo=None, worse_hi=None):
        """Solve one window.

        H : (N, na, na) Hessian blocks. g : (N, na) linear term. lower, upper : (N, na) bounds of x.
        step_lo, step_hi : (N - 1, na) bounds of x_i - x_(i-1), i = 1..N-1. x0 : (N, na) warm start.
        J : (N - 1, rows, na) the objective's Jacobian of nodes 1..N-1, worse_lo, worse_hi :
        (N - 1, rows) bounds of J x (None: no never-worse rows). Returns (x (N, na), status string).
        """
        if J is None:
            J = np.zeros((self.N - 1, self.rows, self.na))
            worse_lo = np.full((self.N - 1, self.rows), -1e30)
            worse_hi = -worse_lo
        l = np.concatenate([lower.reshape(-1), step_lo.reshape(-1), worse_lo.reshape(-1)])
        u = np.concatenate([upper.reshape(-1), step_hi.reshape(-1), worse_hi.reshape(-1)])
        Px, q, Ax = self._p_data(H), np.ascontiguousarray(g.reshape(-1)), self._values(J)
        self.solver.update(Px=Px, q=q, l=l, u=u, Ax=Ax)
        self.solver.warm_start(x=np.ascontiguousarray(x0.reshape(-1)))
        x, status = solve_data(self.solver, lambda: (_with_data(self._P, Px), q,
                                                     _with_data(self._A, Ax), l, u))
        self.solves += 1
        if x is None:
            return np.full((self.N, self.na), np.nan), status
        return x.reshape(self.N, self.na), status

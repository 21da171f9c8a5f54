"""A window's QP with its tied nodes merged: one variable per run of nodes that carry one correction.

An arc under cutter radius compensation carries one correction over all its nodes (the link bound
``x_i = x_(i-1)`` on every axis, :mod:`._links`). Posed as equality rows of the window QP
(:class:`~._qp.WindowQP`), long chains of them make OSQP's iterations crawl (a program that is
mostly such arcs took minutes per window). Here every run of tied nodes is one variable: its
Hessian and linear term are the sums of its nodes', its box the intersection of theirs, the step
and link bounds apply between runs, and every node keeps its own never-worse rows on its run's
variable, except that a run's rows of one direction that differ by at most ``MERGE_TOL_UM`` are
merged into one, tightened by at most that much (:func:`merged_rows`): the solution is that of the
equality-constrained problem with those rows tightened by at most 0.01 um, feasible for it, its
optimum where no merged row is active. It is built for each solve (the pattern changes with the ties),
which costs little against the iterations it saves.
"""
from __future__ import annotations

import numpy as np

from ._qp import OSQP_MAX_ITER, solve_data


def tied(step_lo: np.ndarray, step_hi: np.ndarray) -> np.ndarray:
    """(n,) bool: nodes whose every correction equals the one before (both step bounds zero)."""
    return np.all((step_lo == 0.0) & (step_hi == 0.0), axis=1)


class GroupedQP:
    """Drop-in for :class:`~._qp.WindowQP` (the same ``solve`` arguments and result) for windows
    whose tied nodes are merged (module docstring)."""

    def __init__(self, eps: float = 1e-7):
        self.eps = eps
        self.solves = 0

    def solve(self, H, g, lower, upper, step_lo, step_hi, x0, J=None, worse_lo=None, worse_hi=None):
        """As :meth:`WindowQP.solve` (row 0 the anchor; ``step_*`` and ``J`` rows for nodes
        1..N-1). Returns (x (N, na), status)."""
        import osqp
        import scipy.sparse as sp
        N, na = lower.shape
        tie = np.concatenate([[False], tied(step_lo, step_hi)])
        gid = np.cumsum(~tie) - 1
        G = int(gid[-1]) + 1
        Hg = np.zeros((G, na, na))
        np.add.at(Hg, gid, H)
        gg = np.zeros((G, na))
        np.add.at(gg, gid, g)
        lo = np.full((G, na), -np.inf)
        hi = np.full((G, na), np.inf)
        np.maximum.at(lo, gid, lower)
        np.minimum.at(hi, gid, upper)
        self.solves += 1
        if np.any(lo > hi + 1e-9):
            return np.zeros((N, na)), "primal infeasible"
        hi = np.maximum(hi, lo)
        firsts = np.flatnonzero(~tie)[1:]            # first node of groups 1..G-1
        blocks = [sp.identity(G * na, format="csc")]
        l_parts, u_parts = [lo.reshape(-1)], [hi.reshape(-1)]
        if G > 1:
            r = np.arange((G - 1) * na)
            blocks.append(sp.csc_matrix((np.concatenate([np.ones(r.size), -np.ones(r.size)]),
                                         (np.concatenate([r, r]), np.concatenate([r + na, r]))),
                                        shape=((G - 1) * na, G * na)))
            l_parts.append(step_lo[firsts - 1].reshape(-1))
            u_parts.append(step_hi[firsts - 1].reshape(-1))
        if J is not None:
            Jr, gr, wl, wu = merged_rows(J, gid[1:], worse_lo, worse_hi, np.maximum(-lo, hi), G)
            m = Jr.shape[0]
            blocks.append(sp.csc_matrix((Jr.reshape(-1), (np.repeat(np.arange(m), na),
                                                          (gr[:, None] * na + np.arange(na)).reshape(-1))),
                                        shape=(m, G * na)))
            l_parts.append(wl)
            u_parts.append(wu)
        A = sp.vstack(blocks, format="csc")
        P = sp.block_diag(list(Hg), format="csc")
        P = sp.triu(P, format="csc")
        x_start = np.zeros((G, na))
        np.add.at(x_start, gid, x0)
        x_start /= np.bincount(gid, minlength=G)[:, None]
        q, lower, upper = gg.reshape(-1), np.concatenate(l_parts), np.concatenate(u_parts)
        solver = osqp.OSQP()
        solver.setup(P, q, A, lower, upper, verbose=False, eps_abs=self.eps, eps_rel=self.eps,
                     polishing=True, max_iter=OSQP_MAX_ITER, warm_starting=True, adaptive_rho=True, polish_refine_iter=10)
        solver.warm_start(x=np.ascontiguousarray(np.clip(x_start, lo, hi).reshape(-1)))
        x, status = solve_data(solver, lambda: (P, q, A, lower, upper))
        if x is None or not np.all(np.isfinite(x)):
            return np.zeros((N, na)), status
        return x.reshape(G, na)[gid], status


#: a run's never-worse rows become one row per direction where its nodes' rows differ by so little
#: that the merged row, tightened by what the difference can make, implies every node's (um)
MERGE_TOL_UM = 0.01


def merged_rows(J, gid, lo, hi, reach, G):
    """The never-worse rows ``lo <= J_i x_g(i) <= hi`` of nodes i (J (n, rows, na), gid (n,) their
    runs, lo/hi (n, rows)), with the rows of a run merged where that is exact enough: the run's
    mean row a, bounded by ``max(lo_i + e_i) <= a x <= min(hi_i - e_i)`` with e_i = sum_j
    |J_i,j - a_j| reach_j (reach (G, na): the largest |x| the run's box allows), which implies
    every node's row. A run's direction whose e_i exceed MERGE_TOL_UM keeps its nodes' rows.
    Returns (rows (m, na), their runs (m,), lower (m,), upper (m,))."""
    n, r, na = J.shape
    count = np.bincount(gid, minlength=G).astype(float)
    mean = np.zeros((G, r, na))
    np.add.at(mean, gid, J)
    mean /= np.maximum(count, 1.0)[:, None, None]
    e = np.einsum("nrj,nj->nr", np.abs(J - mean[gid]), reach[gid])
    emax = np.zeros((G, r))
    np.maximum.at(emax, gid, e)
    glo = np.full((G, r), -np.inf)
    ghi = np.full((G, r), np.inf)
    np.maximum.at(glo, gid, lo + e)
    np.minimum.at(ghi, gid, hi - e)
    ok = (emax <= MERGE_TOL_UM) & (glo <= ghi) & (count[:, None] > 1)
    keep = ~ok[gid]                                   # (n, r) node rows kept as they are
    gi, ri = np.nonzero(ok)
    ni, rk = np.nonzero(keep)
    rows = np.concatenate([mean[gi, ri], J[ni, rk]])
    runs = np.concatenate([gi, gid[ni]])
    return rows, runs, np.concatenate([glo[gi, ri], lo[ni, rk]]), np.concatenate([ghi[gi, ri],
                                                                                   hi[ni, rk]])

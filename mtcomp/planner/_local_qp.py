"""A bounded window solved on the stretches of nodes where its bounds act, the rest left at their own
optimum.

The window's QP (:mod:`mtcomp.planner._qp`) is a sum of per-node objectives coupled only by the step
bound between neighbours. A node whose own bounds (box, never worse) and both steps are inactive at
the optimum sits at its own unconstrained optimum, the minimiser of its linearised objective with the
regularisation, ``x* = -(A^T A + diag(lam))^-1 A^T c``. So where ``x*`` breaks a bound only at a few
nodes (a backlash reversal under the step bound, a correction over its bound for a few blocks), the
window's optimum is found on the stretches around those nodes alone, each with its outer neighbours
fixed at their ``x*``: the nodes outside keep every bound at ``x*`` (checked), and when no step bound
between a stretch and a fixed neighbour is active in the stretch's solution (checked), the KKT
conditions of the whole window hold with zero multipliers outside the stretches. The QP being
strictly convex, that is the window's one optimum; OSQP solves a few hundred nodes instead of
thousands. When a check fails with the widest margin, :func:`solve_stretches` returns None and the
caller solves the whole window as before.

The stretches of a window are joined into one chain for one OSQP problem: the anchor first, then
each stretch between its fixed neighbours, a free link (no step bound) from one stretch's right
neighbour to the next one's left neighbour, and fixed padding nodes at the end, so that chain lengths
fall on a few sizes (an OSQP problem is set up once per size).
"""
from __future__ import annotations

import numpy as np

from ._bounds import INF
from ._evaluate import objective_residual
from ._qp import never_worse_rows
from ._small import any_rows, at_b, gram, normal_step, row_max_abs

#: nodes either side of the nodes where x* breaks a bound, tried in turn
MARGINS = (48, 192)
#: chains are padded to a multiple of this many nodes
PAD = 64
#: a step within this (um, urad) of its bound between a stretch and a fixed neighbour counts as
#: active: the stretch's solution is not taken
ACTIVE_TOL = 1e-3


def violations(x, lower, upper, step_lo, step_hi, worse) -> np.ndarray:
    """(n,) bool: the nodes whose corrections x (n, na) break a bound of the window: its box
    (``lower``, ``upper`` (n + 1, na), anchor row first), a step into or out of the node
    (``step_lo``, ``step_hi`` (n, na), the step into node i from node i - 1 or the anchor), or a
    never-worse row (``worse`` = (J, lo, hi) of :func:`~mtcomp.planner._qp.never_worse_rows`).
    Exactly, no tolerance: a node at x* counts as free only where the QP would not move it."""
    J, lo, hi = worse
    bad = any_rows(x < lower[1:]) | any_rows(x > upper[1:])
    d = np.diff(np.vstack([lower[:1], x]), axis=0)
    step = any_rows(d < step_lo) | any_rows(d > step_hi)
    bad |= step
    bad[:-1] |= step[1:]
    if J is not None:
        jx = np.einsum("nrj,nj->nr", J, x)
        bad |= any_rows(jx < lo) | any_rows(jx > hi)
    return bad


def stretches(bad: np.ndarray, margin: int) -> list[tuple[int, int]]:
    """The stretches (first, last node, inclusive) that cover the nodes ``bad`` (n,) with ``margin``
    nodes either side, joined where their fixed neighbours would meet or overlap."""
    n = bad.size
    idx = np.flatnonzero(bad)
    if idx.size == 0:
        return []
    cut = np.flatnonzero(np.diff(idx) > 2 * margin + 2)
    firsts = np.maximum(idx[np.r_[0, cut + 1]] - margin, 0)
    lasts = np.minimum(idx[np.r_[cut, idx.size - 1]] + margin, n - 1)
    return list(zip(firsts.tolist(), lasts.tolist()))


def _chain(parts, n):
    """(node, fixed, link) per chain node after the anchor: the window node it is (-1: padding),
    whether it is fixed, and the window node whose step bound links it to the chain node before
    (-1: a free link)."""
    node, fixed, link = [], [], []
    for a, b in parts:
        if a > 0:
            node.append(a - 1), fixed.append(True), link.append(-1)
        for i in range(a, b + 1):
            node.append(i), fixed.append(False), link.append(i)
        if b < n - 1:
            node.append(b + 1), fixed.append(True), link.append(b + 1)
    pad = -(len(node) + 1) % PAD
    node += [-1] * pad
    fixed += [True] * pad
    link += [-1] * pad
    return np.array(node, np.int64), np.array(fixed, bool), np.array(link, np.int64)


def _boundary_free(x, inside, step_lo, step_hi) -> bool:
    """Whether every step bound between a stretch node and a node outside (both in the window) is
    inactive, by :data:`ACTIVE_TOL`, at the corrections x (n, na)."""
    cross = np.flatnonzero(inside[1:] != inside[:-1]) + 1        # the step into node i
    if cross.size == 0:
        return True
    d = x[cross] - x[cross - 1]
    return not (np.any(d <= step_lo[cross] + ACTIVE_TOL) or np.any(d >= step_hi[cross] - ACTIVE_TOL))


def _chain_qp(get_qp, parts, n, xs, c, A, lam, box, steps, worse):
    """Solve the chain of ``parts``: (x (n, na) with the stretches' solution and xs elsewhere,
    status)."""
    lower, upper = box
    step_lo, step_hi = steps
    J, lo, hi = worse
    node, fixed, link = _chain(parts, n)
    N, na, rows = node.size + 1, xs.shape[1], c.shape[1]
    free_nodes = node[~fixed]
    at = 1 + np.flatnonzero(~fixed)                   # their rows in the chain (anchor row 0)
    H = np.broadcast_to(np.eye(na), (N, na, na)).copy()
    H[at] = gram(A[free_nodes], lam)
    g = np.zeros((N, na))
    g[at] = at_b(A[free_nodes], c[free_nodes])
    held = np.zeros((N, na))
    real = fixed & (node >= 0)
    held[1 + np.flatnonzero(real)] = xs[node[real]]
    ql, qu = held.copy(), held.copy()
    ql[0], qu[0] = lower[0], upper[0]
    ql[at], qu[at] = lower[1 + free_nodes], upper[1 + free_nodes]
    sl, sh = np.full((N - 1, na), -INF), np.full((N - 1, na), INF)
    linked = link >= 0
    sl[linked], sh[linked] = step_lo[link[linked]], step_hi[link[linked]]
    Jc = np.zeros((N - 1, rows, na))
    wl, wh = np.full((N - 1, rows), -INF), np.full((N - 1, rows), INF)
    Jc[at - 1], wl[at - 1], wh[at - 1] = J[free_nodes], lo[free_nodes], hi[free_nodes]
    x0 = held.copy()
    x0[0] = lower[0]
    x0[at] = np.clip(xs[free_nodes], lower[1 + free_nodes], upper[1 + free_nodes])
    sol, status = get_qp(N, rows).solve(H, g, ql, qu, sl, sh, x0, Jc, wl, wh)
    x = xs.copy()
    x[free_nodes] = sol[at]
    return x, status


def solve_stretches(work, box, steps, reachable, lam, step_tol, max_iterations, get_qp, relinearise):
    """The window's bounded optimum found on stretches (module docstring), or None when the checks
    fail (then the caller solves the whole window).

    work : the window's :class:`~mtcomp.planner._pointwise.Linearization`, a copy this updates where
    nodes are re-linearised (their b, A, x_lin and iterations). box = (lower, upper) (n + 1, na) and
    steps = (step_lo, step_hi) (n, na) as :meth:`WindowQP.solve` takes them; reachable (n,) bool
    (:func:`~mtcomp.planner._qp.reachable_nodes`); lam (na,) the regularisation; get_qp(N, rows) a
    :class:`~mtcomp.planner._qp.WindowQP` of N nodes; relinearise(idx, x) -> (b, A) at x of the nodes
    idx. Returns (x (n, na), solves), solves being the QPs of the window the whole-window loop would
    have counted (one per iteration)."""
    n = work.x.shape[0]
    step_lo, step_hi = steps
    for margin in MARGINS:
        trial = work.take(slice(None))
        trial.b, trial.A, trial.x_lin, trial.iterations = (
            np.array(a, copy=True) for a in (work.b, work.A, work.x_lin, work.iterations))
        parts, inside, solves, x = None, None, 0, None
        for _it in range(max_iterations):
            c, A = trial.objective()
            xs = normal_step(A, c, None, lam)
            worse = never_worse_rows(objective_residual(trial.orientation_rows, trial.b0), c, A,
                                     reachable)
            bad = violations(xs, box[0], box[1], step_lo, step_hi, worse)
            if parts is None:
                parts = stretches(bad, margin)
                inside = np.zeros(n, bool)
                for a, b in parts:
                    inside[a:b + 1] = True
                if 2 * inside.sum() > n:
                    return None                # no gain over the whole window (nor at a wider margin)
            elif np.any(bad & ~inside):
                break
            solves += 1
            if parts:
                x, status = _chain_qp(get_qp, parts, n, xs, c, A, lam, box, steps, worse)
                if status != "solved" or not _boundary_free(x, inside, step_lo, step_hi):
                    break
            else:
                x = xs
            moved = row_max_abs(x - trial.x_lin) >= step_tol
            if not np.any(moved):
                return _accept(work, trial, x, solves)
            idx = np.flatnonzero(moved)
            trial.b[idx], trial.A[idx] = relinearise(idx, x[idx])
            trial.x_lin[idx] = x[idx]
            trial.iterations[idx] += 1
        else:
            return _accept(work, trial, x, solves)
    return None


def _accept(work, trial, x, solves):
    work.b[...], work.A[...], work.x_lin[...], work.iterations[...] = (
        trial.b, trial.A, trial.x_lin, trial.iterations)
    return x, solves


class LazyQP:
    """A window's :class:`~mtcomp.planner._qp.WindowQP` (``make()``), set up when first solved: a
    window solved on its stretches rarely needs it."""

    def __init__(self, make):
        self._make = make
        self._qp = None
        self.solves = 0

    def solve(self, *args):
        if self._qp is None:
            self._qp = self._make()
        self.solves += 1
        return self._qp.solve(*args)

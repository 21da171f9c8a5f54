"""Roughness penalties on the error profiles and the choice of their weights (penalised splines).

What the data leave open between what they measured (an angular profile between the nodes of a
coarse grid, seen only through the difference of two styli; the coefficients of a spline between
two laser targets) is not free: a profile follows the smoothest curve through what was measured.

**The penalty** (Eilers and Marx 1996, "Flexible smoothing with B-splines and penalties", eq. 5 and
its integrated form): a component error ``E(s) = sum_j c_j B_j(s)`` of a linear axis on uniform
B-splines with knot spacing h carries

    P(c) = h^-3 |D2 c|^2  ~=  integral of E''(s)^2 ds,

D2 the second-difference matrix of the full coefficient vector (the function mtcomp drops to fix
the reference, ``SplineBasis.kept``, has coefficient 0; a constant and a straight line have no
second difference, so the reference does not change the penalty). The factor h^-3 makes one weight
mean the same curvature on axes with different knot spacing. A rotary axis's Fourier series
``f = sum_k a_k cos k theta + b_k sin k theta`` (its positioning error, its error motions) carries
the exact integral ``pi sum_k k^4 (a_k^2 + b_k^2)`` of ``f''(theta)^2`` over a turn, the periodic
counterpart.

**One weight per class** of component (positioning, straightness and angular errors of linear axes;
angular and translational errors of rotary axes), chosen by REML (Wood 2011, "Fast stable restricted
maximum likelihood and marginal likelihood estimation of semiparametric generalized linear models",
eq. 4 with the scale profiled out) on the linearised problem: the model is linear in its parameters
up to products of the errors, so the normal matrix at the start point serves. With y the
coefficients in the fitted directions, ``AB`` the data's normal matrix there and ``S(l) = sum l_k
S_k`` the penalty,

    V(rho) = (n - M_p)/2 log(RSS + pen) + 1/2 log|AB + S| - 1/2 log|S|+,  l_k = exp(rho_k)

(log|S|+ the log product of the non-zero eigenvalues of S: ``sum_k r_k rho_k`` plus a constant when
the penalties' ranges are independent, r_k the rank of S_k; evaluated itself where they overlap,
:class:`_PenaltySpan`. M_p the dimension of the unpenalised directions). REML is preferred to GCV:
it is less prone to undersmoothing and its optimum is well defined (Wood 2011, section 1).

**Uncertainty**: the Bayesian posterior covariance ``phi (AB + S)^-1`` (Wood 2006, "On confidence
intervals for generalized additive models based on penalized regression splines", eq. 3): where a
prediction rests on the penalty rather than on data, its standard error says so.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.optimize

from ..models.basis import axis_spline

#: the classes of component that share one penalty weight
CLASSES = ("positioning", "straightness", "angular", "rotary angular", "rotary translational")
#: log weights are searched in [-RHO_BOUND, RHO_BOUND] about the class's normalised penalty
RHO_BOUND = 30.0
#: grid weights whose fast criterion is within this (relative to the least, and at least 1e3 times
#: this absolute) of the least are compared by the exact one: above the two formulations' difference
#: (both lose digits to the residual sum's cancellation at the grid's largest weights, ~6e-6
#: relative), far below a difference that would matter to REML
GRID_SHORTLIST = 1e-5


def component_class(machine, group: str) -> str | None:
    """The penalty class of a parameter group ('X:EXX' -> 'positioning'), None for groups without a
    profile (squareness, locations, set-ups ...)."""
    if ":" not in group:
        return None
    axis, comp = group.split(":", 1)
    if len(comp) != 3 or not comp.startswith("E") or axis not in machine.axis_names:
        return None
    direction, of = comp[1], comp[2]
    if of != axis:
        return None
    if machine.axis(axis).is_rotary:
        return "rotary angular" if direction in "ABC" else "rotary translational"
    if direction in "ABC":
        return "angular"
    return "positioning" if direction == axis else "straightness"


def penalty_factors(model, free_idx: np.ndarray, n_unknowns: int) -> dict[str, np.ndarray]:
    """{class: (m_k, n_unknowns) F_k}, the factors of the penalties: ``S_k = F_k^T F_k`` (the second
    differences over h^1.5 of a spline's coefficients, sqrt(pi) k^2 of a harmonic), in internal
    units of the unknowns (free parameters in the order of ``free_idx``, then nuisance: unpenalised).
    A penalty is evaluated as ``|F_k z|^2``: never below zero, and without the round-off of ``z^T S_k
    z``, which at REML's largest weights outgrew the fit's residual sum (a profile in the penalty's
    null space, a straight line, costs exactly its second differences' round-off). Classes without a
    penalised parameter are left out."""
    machine = model.machine
    specs = model.param_specs
    position = {int(i): k for k, i in enumerate(free_idx)}
    groups: dict[str, list[int]] = {}
    for i, s in enumerate(specs):
        if i in position:
            groups.setdefault(s.group, []).append(i)
    rows: dict[str, list[np.ndarray]] = {}
    for group, idx in groups.items():
        cls = component_class(machine, group)
        if cls is None:
            continue
        axis = machine.axis(group.split(":", 1)[0])
        names = [specs[i].name.rsplit("_", 1)[1] for i in idx]
        block = _block(axis, names)
        if block is None:
            continue
        keep, P = block
        F = np.zeros((P.shape[0], n_unknowns))
        F[:, [position[idx[j]] for j in keep]] = P
        rows.setdefault(cls, []).append(F)
    return {cls: np.vstack(Fs) for cls, Fs in rows.items()}


def penalty_matrices(model, free_idx: np.ndarray, n_unknowns: int) -> dict[str, np.ndarray]:
    """{class: (n_unknowns, n_unknowns) S_k = F_k^T F_k} of :func:`penalty_factors`."""
    return {cls: F.T @ F for cls, F in penalty_factors(model, free_idx, n_unknowns).items()}


def _block(axis, suffixes: list[str]):
    """(indices into suffixes, (rows, len(indices)) factor F of the penalty F^T F) of one
    component's parameters, or None."""
    if axis.is_rotary:
        # Fourier harmonics c<k>, s<k>: integral of f''^2 over a turn = pi sum k^4 (a_k^2 + b_k^2)
        keep, diag = [], []
        for j, suf in enumerate(suffixes):
            if suf[:1] in ("c", "s") and suf[1:].isdigit():
                keep.append(j)
                diag.append(np.sqrt(np.pi) * int(suf[1:]) ** 2)
        return (keep, np.diag(diag)) if keep else None
    if axis.basis != "bspline":
        return None
    spline = axis_spline(axis)
    n = spline.n_basis
    if n < 3:
        return None
    keep, cols = [], []
    for j, suf in enumerate(suffixes):
        if suf.startswith("b") and suf[1:].isdigit():
            keep.append(j)
            cols.append(int(suf[1:]))
    if not keep:
        return None
    D2 = np.diff(np.eye(n), 2, axis=0)
    return keep, D2[:, cols] / spline.h ** 1.5


@dataclass
class Smoothing:
    """The penalty weights chosen for a fit.

    weights : {class: exp(rho)}, dimensionless multiples of the class's normalised penalty (each
        class's penalty is scaled so that 1 weighs a profile's curvature about as much as the data
        weigh one well-seen coefficient). rho : {class: log weight}. edf : effective degrees of
        freedom of the fit (trace of the hat matrix). criterion : 'REML'.
    """

    weights: dict
    rho: dict
    edf: float
    criterion: str = "REML"

    def to_dict(self) -> dict:
        return {"criterion": self.criterion, "edf": float(self.edf),
                "weights": {k: float(v) for k, v in self.weights.items()}}


def _logdet_solve(M: np.ndarray, b: np.ndarray):
    """(log|M|, M^-1 b) of a symmetric positive definite M, by Cholesky (eigenvalues where it fails)."""
    try:
        c, low = scipy.linalg.cho_factor(M)
        return 2.0 * float(np.sum(np.log(np.diag(c)))), scipy.linalg.cho_solve((c, low), b)
    except np.linalg.LinAlgError:
        # at the edge of the weights' range round-off leaves M not quite positive definite:
        # eigenvalues below 1e-14 of the largest count at that floor
        w, V = np.linalg.eigh(0.5 * (M + M.T))
        w = np.clip(w, 1e-14 * max(float(w.max()), 1e-300), None)
        return float(np.sum(np.log(w))), V @ ((V.T @ b) / w)


class _PenaltySpan:
    """The penalised part of the fitted directions: log|S(l)|+ (the log product of the non-zero
    eigenvalues of ``S(l) = sum l_k SB_k``) and its rank, the REML criterion's terms of the penalty.

    When the penalties' ranges are independent (the rank of their sum is the sum of their ranks),
    ``log|S(l)|+ = sum r_k rho_k`` plus a constant. When they overlap (a fitted direction that moves
    profiles of two classes at once, as the directions left after holding what the data leave open
    may), that sum counts the shared dimensions twice and the criterion falls without bound as the
    weights grow: REML then smoothed every profile flat. There the determinant is evaluated (the
    log|S|+ of the summed penalty in Wood 2011, eq. 4): with the square roots ``R_k`` of the SB_k on
    the range U of their sum, ``S(l) = sum l_k R_k^T R_k = Q^T Q`` on U (QR of the rows sqrt(l_k) R_k,
    the largest weights first), log|S(l)|+ = 2 sum log|diag Q| and its derivative by rho_k is
    ``l_k |R_k Q^-1|_F^2``."""

    def __init__(self, SB: list, ranks: np.ndarray):
        self.ranks = np.asarray(ranks)
        total = sum(SB)
        self.rank = int(_ranks([total])[0]) if len(SB) > 1 else int(self.ranks.sum())
        self.overlap = self.rank < int(self.ranks.sum())
        if not self.overlap:
            self.rank = int(self.ranks.sum())
            return
        ev, U = np.linalg.eigh(0.5 * (total + total.T))
        U = U[:, np.argsort(ev)[::-1][:self.rank]]
        self.roots = []
        for S in SB:
            e, V = np.linalg.eigh(0.5 * (S + S.T))
            on = e > 1e-9 * max(float(np.abs(S).max()), 1e-300)
            self.roots.append((np.sqrt(e[on])[:, None] * V[:, on].T) @ U)

    def logdet(self, rho: np.ndarray, gradient: bool = True):
        """(log|S(l)|+ up to a constant, its gradient by rho or None)."""
        rho = np.asarray(rho, dtype=float)
        if not self.overlap:
            return float(self.ranks @ rho), (self.ranks.astype(float) if gradient else None)
        order = np.argsort(-rho, kind="stable")
        rows = np.vstack([np.exp(0.5 * rho[k]) * self.roots[k] for k in order])
        Q = scipy.linalg.qr(rows, mode="r")[0][:self.rank]
        value = 2.0 * float(np.sum(np.log(np.abs(np.diag(Q)))))
        if not gradient:
            return value, None
        grad = np.array([np.exp(rho[k]) * float(np.sum(scipy.linalg.solve_triangular(
            Q, R.T, trans="T") ** 2)) for k, R in enumerate(self.roots)])
        return value, grad


def reml_criterion(rho: np.ndarray, AB: np.ndarray, gB: np.ndarray, rss0: float, SB: list, bz: list,
                   cz: list, n_obs: int, gradient: bool = True, ranks: np.ndarray | None = None,
                   span: _PenaltySpan | None = None):
    """(V, dV/drho or None, AB + S) of the REML criterion of the module docstring at log weights rho
    (the arguments as :func:`reml_weights` takes them; ``ranks``: the penalties' ranks, computed
    when not given; ``span``: their :class:`_PenaltySpan`, likewise)."""
    ranks = _ranks(SB) if ranks is None else ranks
    span = _PenaltySpan(SB, ranks) if span is None else span
    mp = AB.shape[0] - span.rank
    lam = np.exp(rho)
    H = AB + sum(l * Sk for l, Sk in zip(lam, SB))
    b = gB - sum(l * bk for l, bk in zip(lam, bz))
    try:
        factor = scipy.linalg.cho_factor(H)
        logdet = 2.0 * float(np.sum(np.log(np.diag(factor[0]))))
        y = scipy.linalg.cho_solve(factor, b)
        Hinv = scipy.linalg.cho_solve(factor, np.eye(H.shape[0])) if gradient else None
    except np.linalg.LinAlgError:
        # at the edge of the weights' range round-off leaves H not quite positive definite:
        # eigenvalues below 1e-14 of the largest count at that floor
        w, V = np.linalg.eigh(0.5 * (H + H.T))
        w = np.clip(w, 1e-14 * max(float(w.max()), 1e-300), None)
        logdet = float(np.sum(np.log(w)))
        y = V @ ((V.T @ b) / w)
        Hinv = (V / w) @ V.T if gradient else None
    pen_k = np.array([float(y @ Sk @ y + 2.0 * y @ bk + ck) for Sk, bk, ck in zip(SB, bz, cz)])
    data = rss0 - 2.0 * float(gB @ y) + float(y @ AB @ y)
    if data < 0.0:
        # a residual sum of squares below zero: y went so far along what the data leave nearly open
        # that the linearisation's digits are gone (REML at a fit the penalty held at e^30 took the
        # weights e^-24 for its least); no weight there is one the data choose
        return np.inf, (np.zeros(len(SB)) if gradient else None), H
    total = max(data + float(lam @ pen_k), 1e-300)
    logdet_s, dlogdet_s = span.logdet(rho, gradient)
    value = 0.5 * (n_obs - mp) * np.log(total) + 0.5 * logdet - 0.5 * logdet_s
    if not gradient:
        return value, None, H
    # y minimises the penalised sum, so its derivative by rho_k is lam_k pen_k(y) alone (envelope
    # theorem); d log|H| / d rho_k = lam_k tr(H^-1 S_k)
    # tr(H^-1 S_k) = sum of the elementwise product (both symmetric): one inverse for every class
    grad = (0.5 * (n_obs - mp) * lam * pen_k / total
            + 0.5 * lam * np.array([float(np.sum(Hinv * Sk)) for Sk in SB]) - 0.5 * dlogdet_s)
    return value, grad, H


def _ranks(SB) -> np.ndarray:
    """The ranks of the penalties: their eigenvalues above 1e-9 of the largest entry (a symmetric
    matrix's singular values are its eigenvalues' magnitudes; eigenvalues cost a third of an SVD)."""
    return np.array([int(np.sum(np.abs(scipy.linalg.eigvalsh(S)) > 1e-9 * max(np.abs(S).max(), 1e-300)))
                     for S in SB])


def penalty_ranks(SB: list[np.ndarray]) -> np.ndarray:
    """(m,) ranks of the penalties SB, to pass to :func:`reml_weights` when it runs more than once on
    the same penalties."""
    return _ranks(SB)


def _common_weight_grid(grid: np.ndarray, args: tuple, ranks: np.ndarray,
                        rank: int | None = None) -> np.ndarray | None:
    """(len(grid),) the REML criterion at one common log weight r for every class, at each r of
    ``grid``, from one eigen-decomposition (None where it does not exist).

    In the eigenvectors U of the summed penalty S (null part 0, range p with eigenvalues L), the
    unpenalised coefficients are eliminated (Schur complement C of the data's normal matrix on
    them); with ``L^-1/2 C L^-1/2 = Q diag(w) Q^T`` the penalised matrix ``AB + lam S`` has
    log-determinant ``log|A_00| + log|L| + sum log(w + lam)`` and its solve is a division by
    ``w + lam``: each weight costs O(k^2) where a Cholesky factor per weight costs O(k^3) (Wood 2011,
    section 3.2, diagonalises the same way for one smoothing parameter). The null part is exactly
    unpenalised, but at the largest weights the penalised residual sum may still lose its digits to
    cancellation (a value far below the criterion's: :func:`_grid_start` checks the least)."""
    AB, gB, rss0, SB, bz, cz, n_obs = args
    S = sum(SB)
    ev, U = np.linalg.eigh(0.5 * (S + S.T))
    on = ev > 1e-9 * max(float(np.abs(S).max()), 1e-300)
    if not on.any():
        return None
    U0, Up, lam_p = U[:, ~on], U[:, on], ev[on]
    A00, A0p, App = U0.T @ AB @ U0, U0.T @ AB @ Up, Up.T @ AB @ Up
    bt = sum(bz)
    try:
        if U0.shape[1]:
            f00 = scipy.linalg.cho_factor(A00)
            logdet_00 = 2.0 * float(np.sum(np.log(np.diag(f00[0]))))
            G = scipy.linalg.cho_solve(f00, np.column_stack([A0p, U0.T @ gB, U0.T @ bt]))
            G, e1, e2 = G[:, :-2], G[:, -2], G[:, -1]
        else:
            logdet_00, G, e1, e2 = 0.0, np.zeros((0, Up.shape[1])), np.zeros(0), np.zeros(0)
    except (np.linalg.LinAlgError, ValueError):
        return None
    C = App - A0p.T @ G
    d = 1.0 / np.sqrt(lam_p)
    w, Q = np.linalg.eigh(0.5 * (d[:, None] * (C + C.T) * d[None, :]))
    R = d[:, None] * Q                          # y_p = R u
    q1 = R.T @ (Up.T @ gB - A0p.T @ e1)
    q2 = R.T @ (Up.T @ bt - A0p.T @ e2)
    rank = int(ranks.sum()) if rank is None else rank     # of the summed penalty (_PenaltySpan)
    mp = AB.shape[0] - rank
    logdet_fixed = logdet_00 + float(np.sum(np.log(lam_p)))
    out = np.empty(len(grid))
    for i, r in enumerate(grid):
        lam = np.exp(r)
        if np.any(w + lam <= 0):
            return None
        yp = R @ ((q1 - lam * q2) / (w + lam))
        y = Up @ yp + U0 @ (e1 - lam * e2 - G @ yp)
        pen = float(y @ S @ y + 2.0 * y @ bt) + float(sum(cz))
        total = max(rss0 - 2.0 * float(gB @ y) + float(y @ AB @ y) + lam * pen, 1e-300)
        out[i] = (0.5 * (n_obs - mp) * np.log(total) + 0.5 * (logdet_fixed + float(np.sum(np.log(w + lam))))
                  - 0.5 * rank * r)
    return out


def _grid_start(grid: np.ndarray, criterion, args: tuple, ranks: np.ndarray, m: int,
                rank: int | None = None) -> float:
    """The grid's common log weight with the least criterion (the first of equals, in grid order).
    The fast values of :func:`_common_weight_grid` shortlist the points within round-off of their
    least; those are evaluated by the exact criterion, and again with what that changes, until every
    point of the shortlist has its exact value: the choice is the exact criterion's, even where a
    fast value lost its digits and fell below the least (the exact one where it is NaN)."""
    values = _common_weight_grid(grid, args, ranks, rank)
    if values is None:
        return float(min(grid, key=lambda r: criterion(np.full(m, r))))
    exact = ~np.isfinite(values)
    values[exact] = [criterion(np.full(m, r)) for r in grid[exact]]
    while True:
        least = float(values.min())
        near = np.flatnonzero(values <= least + GRID_SHORTLIST * max(abs(least), 1e3))
        todo = near[~exact[near]]
        if not todo.size:
            return float(grid[near[int(np.argmin(values[near]))]])
        values[todo] = [criterion(np.full(m, grid[i])) for i in todo]
        exact[todo] = True


def reml_weights(AB: np.ndarray, gB: np.ndarray, rss0: float, SB: list[np.ndarray],
                 bz: list[np.ndarray], cz: list[float], n_obs: int,
                 start: np.ndarray | None = None, ranks: np.ndarray | None = None,
                 with_edf: bool = True) -> tuple[np.ndarray, float]:
    """Log weights rho (one per penalty) minimising the REML criterion of the module docstring, and
    the effective degrees of freedom at them (NaN when ``with_edf`` is False: the caller computes
    them at its own fit).

    AB : (k, k) data normal matrix in the fitted directions. gB : (k,) gradient of the data term
    (J^T r at the linearisation point). rss0 : the residual sum of squares there. SB : the penalties
    (k, k) in those directions, each normalised. bz, cz : the penalties' linear and constant parts
    from a non-zero start point, pen_k(y) = y^T SB_k y + 2 y^T bz_k + cz_k. start : log weights to
    refine from (skips the coarse grid). ranks : the penalties' ranks (:func:`penalty_ranks`;
    computed when not given).
    """
    m = len(SB)
    args = (AB, gB, rss0, SB, bz, cz, n_obs)
    ranks = _ranks(SB) if ranks is None else np.asarray(ranks)
    span = _PenaltySpan(SB, ranks)
    values = {}

    def criterion(rho):
        key = tuple(np.asarray(rho, dtype=float).tolist())
        if key not in values:
            values[key] = reml_criterion(rho, *args, gradient=False, ranks=ranks, span=span)[0]
        return values[key]

    # a common weight on a coarse grid first (the criterion is flat far out and may have shallow
    # local minima), then every class's own from there, with the exact gradient
    if start is None:
        grid = np.arange(-RHO_BOUND, RHO_BOUND + 1e-9, 2.0)
        rho = np.full(m, _grid_start(grid, criterion, args, ranks, m, span.rank))
    else:
        rho = np.asarray(start, dtype=float)
    res = scipy.optimize.minimize(lambda r: reml_criterion(r, *args, ranks=ranks, span=span)[:2], rho, jac=True,
                                  method="L-BFGS-B", bounds=[(-RHO_BOUND, RHO_BOUND)] * m,
                                  options={"maxiter": 500, "ftol": 1e-12, "gtol": 1e-6})
    if res.fun <= criterion(rho):
        rho = res.x
    if not with_edf:
        return rho, float("nan")
    H = reml_criterion(rho, *args, gradient=False, ranks=ranks, span=span)[2]
    edf = float(np.trace(_logdet_solve(H, AB)[1]))
    return rho, edf

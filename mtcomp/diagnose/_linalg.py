"""Weighted linear least squares on column blocks, with K-fold held-out residuals.

The diagnosis compares many models that share a common block of columns (base parameters and
nuisance) and differ by a few extension columns. :class:`Design` keeps the weighted common block and
its per-fold Gram matrices once, so that fitting a model with extra columns costs a few small
matrix products. Rank-deficient designs are the rule in metrology (a laser run along X says nothing
about EZY): the common block is reduced once, by an eigen-decomposition of its column-scaled normal
matrix, to the directions the data determine; every later fit is then a Cholesky solve of a small,
well-posed normal matrix (with an eigen-decomposition fallback).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

#: the fit engine's rank rule with diagnose's threshold: a relative singular value of the
#: column-scaled weighted Jacobian at or below this is undetermined (identify's 1e-6 determines
#: directions the held-out selection then follows into noise: a feed-dependent Abbe error's moving
#: centre was lost)
RCOND = 1e-5
#: the same on the eigenvalues of the normal matrix
RANK_TOLERANCE = RCOND ** 2
#: share of the information on a direction that a fold must keep for that direction to be fitted
FOLD_TOLERANCE = 1e-4
#: a reading is extrapolated in its fold when the directions its fold leaves out move it by more than
#: this share of its noise in the fit on all the data (:meth:`Design.extrapolated`)
EXTRAPOLATED_SHARE = 0.1


def solve_normal(G: np.ndarray, b: np.ndarray, tol: float = RANK_TOLERANCE) -> tuple[np.ndarray, int]:
    """Minimum-norm solution of G theta = b for a symmetric positive semi-definite G, and its rank.

    The columns are scaled to unit diagonal first, so the tolerance is relative to each column's size.
    """
    d = np.sqrt(np.clip(np.diag(G), 0.0, None))
    keep = d > 0
    theta = np.zeros(G.shape[0])
    if not keep.any():
        return theta, 0
    dk = d[keep]
    Gs = G[np.ix_(keep, keep)] / np.outer(dk, dk)
    w, V = _eigh(Gs)
    ok = w > tol * max(w.max(), 1e-300)
    bs = b[keep] / dk
    x = V[:, ok] @ ((V[:, ok].T @ bs) / w[ok])
    theta[keep] = x / dk
    return theta, int(ok.sum())


@dataclass
class FitResult:
    """A weighted least-squares fit on all data and its K-fold held-out residuals.

    theta : (k,) coefficients of the model's columns (common block first, then the extras).
    rank : number of determined directions (the effective number of parameters).
    sse : weighted sum of squared residuals on all data (in units of the weights: sigma^2 = 1).
    resid : (n,) residuals on all data, file units (um/urad), unweighted.
    cv_resid : (n,) held-out residuals (each observation predicted by the fit without its fold).
    cv_sse : weighted sum of squares of ``cv_resid``.
    """

    theta: np.ndarray
    rank: int
    sse: float
    resid: np.ndarray
    cv_resid: np.ndarray
    cv_sse: float

    def bic(self, n: int) -> float:
        """Bayesian information criterion with the noise known (weights are 1/sigma, sigma the noise
        floor from repeated readings, i.e. the pure error of the classical lack-of-fit test):
        SSE + rank ln n. With sigma known, structure the model lacks (a position-dependent error
        the polynomials cannot follow) does not hide an effect that is orthogonal to it, such as a
        reversal seen at matched positions."""
        return self.sse + self.rank * np.log(n)


def _fold_eig(kept: np.ndarray, d: np.ndarray, L: np.ndarray) -> tuple:
    """(lam, U): the eigenpairs of L^-1 (kept / d d^T) L^-T, for ``kept`` the normal matrix of the
    data a fold keeps and (d, L) the scaled Cholesky factor of all the data's
    (:func:`_scaled_cholesky`): on the directions :func:`_fold_directions` makes of U, ``kept`` is
    diag(lam) and all the data's normal matrix the identity."""
    tri = scipy.linalg.solve_triangular
    M = tri(L, tri(L, kept / np.outer(d, d), lower=True).T, lower=True)
    return _eigh((M + M.T) / 2)


def _fold_directions(d: np.ndarray, L: np.ndarray, U: np.ndarray) -> np.ndarray:
    """V = d^-1 L^-T U: the directions of :func:`_fold_eig`'s eigenvectors U, in the unknowns."""
    return scipy.linalg.solve_triangular(L.T, U, lower=False) / d[:, None]


def _scaled_cholesky(G: np.ndarray):
    """(d, L): the diagonal scaling d of a symmetric positive (semi-)definite G and the Cholesky factor
    L of the unit-diagonal matrix G / (d d^T) with a tiny ridge; L is None when that fails."""
    d = np.sqrt(np.clip(np.diag(G), 0.0, None))
    d = np.where(d > 0, d, 1.0)
    Gs = G / np.outer(d, d)
    try:
        return d, np.linalg.cholesky(Gs + 1e-11 * np.eye(len(Gs)))
    except np.linalg.LinAlgError:
        return d, None


def _chol_solve(G: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Solve G x = b for symmetric positive (semi-)definite G: scaled Cholesky; the minimum-norm
    eigen-decomposition route when that fails."""
    d, L = _scaled_cholesky(G)
    if L is None:
        return solve_normal(G, b)[0]
    return scipy.linalg.cho_solve((L, True), b / d) / d


def _eigh(M: np.ndarray):
    """Symmetric eigen-decomposition; LAPACK's divide-and-conquer occasionally fails to converge on
    nearly singular matrices, then the relatively robust representation driver is used."""
    try:
        return np.linalg.eigh(M)
    except np.linalg.LinAlgError:
        return scipy.linalg.eigh(M, driver="evr")


def _fold_solve(Gk: np.ndarray, bk: np.ndarray, G: np.ndarray) -> np.ndarray:
    """Least squares on the part of the data a fold keeps (normal matrix Gk), with G the normal
    matrix of all the data: the generalised eigenproblem Gk v = lambda G v gives, per direction, the
    share lambda of its information the fold keeps; directions with lambda < FOLD_TOLERANCE are left
    out (held-out readings would be extrapolated along a direction the fold hardly determines).
    Otherwise this is the plain least-squares solution."""
    d, L = _scaled_cholesky(G)
    if L is None:
        return solve_normal(Gk, bk, FOLD_TOLERANCE)[0]
    tri = scipy.linalg.solve_triangular
    M = tri(L, tri(L, Gk / np.outer(d, d), lower=True).T, lower=True)
    lam, U = _eigh((M + M.T) / 2)
    ok = lam > FOLD_TOLERANCE
    y = tri(L, bk / d, lower=True)
    return tri(L.T, U[:, ok] @ ((U[:, ok].T @ y) / lam[ok]), lower=False) / d


def determined_subspace(A: np.ndarray, w: np.ndarray | None = None,
                        setup: np.ndarray | None = None,
                        unmeasured: np.ndarray | None = None) -> np.ndarray:
    """(m, r) basis T of the parameter directions a fit moves in: T = S B with S the inverse column
    norms and B the directions of the scaled problem complementary to its null space (eigenvalues
    of the scaled normal matrix not above RANK_TOLERANCE of the largest), chosen as identify does
    (:func:`mtcomp.identification.fit.held_complement`): ``setup`` (m,) bool marks set-up columns,
    which take what an undetermined combination trades with machine parameters (None: all machine);
    ``unmeasured`` (m,) bool marks machine columns no laser file names, held at zero there.
    Fixed once, at the start point of a fit, so that combinations determined only through
    second-order effects of the errors stay undetermined."""
    from ..identification._linalg import column_scale, held_complement
    Aw = A if w is None else A * np.asarray(w, dtype=float)[:, None]
    # identify's rule: a column at round-off level (a rotary location error the data never turn,
    # seen only through the rounding of the chain) is not scaled up to pass for information
    S = column_scale(np.diag(np.sum(Aw ** 2, axis=0)))
    G0 = (Aw * S).T @ (Aw * S)
    ev, V = _eigh(G0)
    ok = ev > RANK_TOLERANCE * max(ev.max(), 1e-300)
    machine = np.ones(A.shape[1], dtype=bool) if setup is None else ~np.asarray(setup, dtype=bool)
    return S[:, None] * held_complement(V[:, ~ok], machine, unmeasured)


class Design:
    """The common weighted column block of every model, fold structure and target.

    A : (n, m) common columns (base parameters and nuisance), file units per parameter unit.
    z : (n,) target (observations made linear: y - f(p0) + A p0), file units.
    w : (n,) weights, 1 / sigma of each observation (sigma in file units).
    folds : (n,) fold of each observation, 0..K-1 (held out together).

    Everything about the common block is factored once: the Cholesky factor of its normal matrix,
    and for each fold the directions of the block that the data the fold keeps determine (the
    generalised eigenproblem of :func:`_fold_solve`, in which the fold's normal matrix is diagonal).
    A fit with k extra columns then costs products with them and k x k solves (block elimination).
    """

    def __init__(self, A: np.ndarray, z: np.ndarray, w: np.ndarray, folds: np.ndarray,
                 T: np.ndarray | None = None):
        A = np.asarray(A, dtype=float)
        self.w = np.asarray(w, dtype=float)
        # reduce the common block to the directions the (weighted) data determine: A T
        self.T = determined_subspace(A, self.w) if T is None else T
        self.A_original = A
        self.A = A @ self.T
        self.z = np.asarray(z, dtype=float)
        self.folds = np.asarray(folds, dtype=np.int64)
        self.K = int(self.folds.max()) + 1 if len(self.folds) else 0
        self.n = len(self.z)
        self.Aw = self.A * self.w[:, None]
        self.zw = self.z * self.w
        self._fold_index = [np.flatnonzero(self.folds == k) for k in range(self.K)]
        # the rows sorted by fold, once: each fold is then a slice (a view, not a copy per fit)
        self._order = np.concatenate(self._fold_index) if self.K else np.zeros(0, dtype=np.int64)
        ends = np.cumsum([0] + [ix.size for ix in self._fold_index])
        self._slices = [slice(int(a), int(b)) for a, b in zip(ends[:-1], ends[1:])]
        self._Aws = self.Aw[self._order]
        self._As = self.A[self._order]
        self.G = self.Aw.T @ self.Aw
        self.b = self.Aw.T @ self.zw
        self.Gk = [self._Aws[sl].T @ self._Aws[sl] for sl in self._slices]
        self.bk = [self._Aws[sl].T @ self.zw[ix] for sl, ix in zip(self._slices, self._fold_index)]
        # G = (d L)(d L)^T: the block's directions are determined (T), so this factor exists
        self._d, self._L = _scaled_cholesky(self.G)
        # per fold: the kept data's normal matrix is diagonal, diag(lam), on the basis
        # V = d^-1 L^-T U of the common block (U, lam: eigenpairs of L^-1 G_kept L^-T, scaled).
        # A fold that keeps less than FOLD_TOLERANCE of the information on some direction (None)
        # takes the general route of _fold_solve, which leaves such directions out
        self._fold_basis = []
        if self._L is not None and self.K >= 2:
            for Gk in self.Gk:
                lam, U = _fold_eig(self.G - Gk, self._d, self._L)
                V = _fold_directions(self._d, self._L, U)
                self._fold_basis.append((V, lam) if lam.size and lam.min() > FOLD_TOLERANCE else None)

    def extrapolated(self, theta: np.ndarray, share: float = EXTRAPOLATED_SHARE) -> np.ndarray:
        """(n,) bool: the readings whose held-out prediction rests on what only their own fold
        determines. A fold that keeps less than FOLD_TOLERANCE of the information on a direction of
        the common block leaves it out (:func:`_fold_solve`): its readings are predicted as if the
        machine had no error along it. Where the fit on all the data, ``theta`` (:meth:`fit`'s, common
        block first), moves a reading by more than ``share`` of its noise along such directions, its
        held-out residual measures what the other folds cannot see (a stretch of a ball-bar circle
        no other reading passes), not what the model lacks."""
        out = np.zeros(self.n, dtype=bool)
        if self._L is None or self.K < 2:
            return out
        tA = np.linalg.lstsq(self.T, np.asarray(theta, dtype=float)[:self.T.shape[0]], rcond=None)[0]
        GtA = self.G @ tA
        for kk, ix in enumerate(self._fold_index):
            if self._fold_basis[kk] is not None:
                continue
            lam, U = _fold_eig(self.G - self.Gk[kk], self._d, self._L)
            drop = lam <= FOLD_TOLERANCE
            if not drop.any():
                continue
            # V^T G V = I: the full fit's coordinates on the left-out directions are V^T G tA
            V = _fold_directions(self._d, self._L, U[:, drop])
            moved = self.Aw[ix] @ (V @ (V.T @ GtA))
            out[ix] = np.abs(moved) > share
        return out

    def leverage(self) -> np.ndarray:
        """(n,) the hat matrix's diagonal of the fit of the common block on all the data: the share of
        each reading's residual the fit takes (their sum is the directions fitted)."""
        if self._L is None:
            return np.full(self.n, self.A.shape[1] / max(self.n, 1))
        P = scipy.linalg.solve_triangular(self._L, (self.Aw / self._d).T, lower=True)
        return np.sum(P ** 2, axis=0)

    def heldout_variance(self, extra: np.ndarray | None = None) -> np.ndarray:
        """(n,) the variance of each reading's held-out prediction under a right model, in noise
        variances: h_i = x_i G_k^+ x_i for the weighted row x_i of the common block plus ``extra``
        and G_k the normal matrix of the data its fold keeps, on the directions :func:`_fold_solve`
        fits (those the fold keeps more than FOLD_TOLERANCE of). A right model's held-out residual
        then has variance 1 + h_i noise variances (the reading's own noise and the error of the fit
        that predicts it, which shares none of it): a reading whose fold removes most of what fixes
        its prediction (the only points of a part that read one spline function) is predicted
        loosely by the other folds, however right the model is. :meth:`fit` predicts with the same
        directions; the readings whose prediction rests on the directions left out are
        :meth:`extrapolated`."""
        X = self.Aw if extra is None or np.size(extra) == 0 else \
            np.hstack([self.Aw, np.asarray(extra, dtype=float).reshape(self.n, -1) * self.w[:, None]])
        h = np.zeros(self.n)
        if self.K < 2:
            return h
        G = X.T @ X
        d, L = _scaled_cholesky(G)
        if L is None:
            return h
        for ix in self._fold_index:
            lam, U = _fold_eig(G - X[ix].T @ X[ix], d, L)
            ok = lam > FOLD_TOLERANCE
            # V^T G_k V = diag(lam): the kept data's normal matrix is diagonal on these directions
            P = X[ix] @ _fold_directions(d, L, U[:, ok])
            h[ix] = np.sum(P ** 2 / lam[ok], axis=1)
        return h

    def _solve_all(self, AE, EE, bE):
        """(theta_A, theta_E, S): least squares on all data by block elimination; S the Schur
        complement of the extra columns (their information beyond the common block)."""
        d, L = self._d, self._L
        GiAE = scipy.linalg.cho_solve((L, True), AE / d[:, None]) / d[:, None]
        Gib = scipy.linalg.cho_solve((L, True), self.b / d) / d
        S = EE - AE.T @ GiAE
        rhs = bE - AE.T @ Gib
        tE = _chol_solve(S, rhs) if S.size else np.zeros(0)
        return Gib - GiAE @ tE, tE, S

    def fit(self, extra: np.ndarray | None = None, cv: bool = True) -> FitResult:
        """Fit the common block plus ``extra`` (n, k) columns; held-out residuals when ``cv``."""
        if self._L is None:
            return self._fit_dense(extra, cv)
        if extra is None or extra.size == 0:
            E = np.zeros((self.n, 0))
        else:
            E = np.asarray(extra, dtype=float).reshape(self.n, -1)
        Ew = E * self.w[:, None]
        m, k = self.A.shape[1], E.shape[1]
        AE = self.Aw.T @ Ew
        EE = Ew.T @ Ew
        bE = Ew.T @ self.zw
        tA, tE, S = self._solve_all(AE, EE, bE)
        rank = m + self._extra_rank(S, EE)
        resid = self.z - self.A @ tA - E @ tE
        sse = float(np.sum((resid * self.w) ** 2))
        cv_resid = np.full(self.n, np.nan)
        if cv and self.K >= 2:
            for kk, ix in enumerate(self._fold_index):
                sl = self._slices[kk]
                Ek = Ew[ix]
                AEk = self._Aws[sl].T @ Ek
                EEk = EE - Ek.T @ Ek
                bEk = bE - Ek.T @ self.zw[ix]
                fast = self._fold_basis[kk]
                if fast is not None:
                    # normal equations of the kept data in (alpha, theta_E), theta_A = V alpha
                    V, lam = fast
                    C = V.T @ (AE - AEk)                                  # (m, k)
                    ba = V.T @ (self.b - self.bk[kk])
                    Sk = EEk - C.T @ (C / lam[:, None])
                    # the fold keeps more than FOLD_TOLERANCE of every direction's information,
                    # common and extra together, else the general route
                    if k == 0 or _keeps_all(lam, C - FOLD_TOLERANCE * (V.T @ AE), EEk - FOLD_TOLERANCE * EE):
                        th_E = _chol_solve(Sk, bEk - C.T @ (ba / lam)) if k else np.zeros(0)
                        alpha = (ba - C @ th_E) / lam
                        cv_resid[ix] = self.z[ix] - self._As[sl] @ (V @ alpha) - E[ix] @ th_E
                        continue
                G = np.block([[self.G, AE], [AE.T, EE]])
                Gk = G - np.block([[self.Gk[kk], AEk], [AEk.T, Ek.T @ Ek]])
                bk = np.concatenate([self.b - self.bk[kk], bEk])
                th = _fold_solve(Gk, bk, G)
                cv_resid[ix] = self.z[ix] - self._As[sl] @ th[:m] - E[ix] @ th[m:]
        cv_sse = float(np.nansum((cv_resid * self.w) ** 2)) if cv and self.K >= 2 else float("nan")
        theta = np.concatenate([self.T @ tA, tE])
        return FitResult(theta, rank, sse, resid, cv_resid, cv_sse)

    def _fit_dense(self, extra, cv):
        """The plain route (the common block's normal matrix has no Cholesky factor: never with a
        reduced block, kept for safety): one (m + k) solve per fit and per fold."""
        E = np.zeros((self.n, 0)) if extra is None or extra.size == 0 else \
            np.asarray(extra, dtype=float).reshape(self.n, -1)
        Ew = E * self.w[:, None]
        m = self.A.shape[1]
        AE = self.Aw.T @ Ew
        G = np.block([[self.G, AE], [AE.T, Ew.T @ Ew]])
        b = np.concatenate([self.b, Ew.T @ self.zw])
        theta = _chol_solve(G, b)
        resid = self.z - self.A @ theta[:m] - E @ theta[m:]
        GiAE = np.column_stack([solve_normal(self.G, AE[:, j])[0] for j in range(AE.shape[1])]) \
            if AE.shape[1] else np.zeros((m, 0))
        rank = m + self._extra_rank(G[m:, m:] - AE.T @ GiAE, G[m:, m:])
        cv_resid = np.full(self.n, np.nan)
        if cv and self.K >= 2:
            for kk, ix in enumerate(self._fold_index):
                Ek = Ew[ix]
                AEk = self.Aw[ix].T @ Ek
                Gk = G - np.block([[self.Gk[kk], AEk], [AEk.T, Ek.T @ Ek]])
                bk = b - np.concatenate([self.bk[kk], Ek.T @ self.zw[ix]])
                th = _fold_solve(Gk, bk, G)
                cv_resid[ix] = self.z[ix] - self.A[ix] @ th[:m] - E[ix] @ th[m:]
        cv_sse = float(np.nansum((cv_resid * self.w) ** 2)) if cv and self.K >= 2 else float("nan")
        return FitResult(np.concatenate([self.T @ theta[:m], theta[m:]]), rank, float(np.sum((resid * self.w) ** 2)),
                         resid, cv_resid, cv_sse)

    @staticmethod
    def _extra_rank(S: np.ndarray, EE: np.ndarray, tol: float = 1e-6) -> int:
        """Number of directions the extra columns add to the common block: eigenvalues of the Gram
        matrix of their part orthogonal to it (the Schur complement S), with the columns scaled to
        unit norm, above ``tol``."""
        if S.size == 0:
            return 0
        nrm = np.sqrt(np.clip(np.diag(EE), 0.0, None))
        nrm = np.where(nrm > 0, nrm, 1.0)
        ev = np.linalg.eigvalsh(S / np.outer(nrm, nrm))
        return int(np.sum(ev > tol))

    def gram(self, extra: np.ndarray) -> np.ndarray:
        """Weighted normal matrix of the ORIGINAL common columns plus ``extra`` (for covariances)."""
        Aw = self.A_original * self.w[:, None]
        Ew = extra * self.w[:, None]
        return np.block([[Aw.T @ Aw, Aw.T @ Ew], [Ew.T @ Aw, Ew.T @ Ew]])


def _keeps_all(lam: np.ndarray, D: np.ndarray, E: np.ndarray) -> bool:
    """True when a fold's kept normal matrix minus FOLD_TOLERANCE times the all-data one is positive
    definite, i.e. the fold keeps more than that share of the information on every direction of the
    joint (common + extra) parameters. On the fold's basis of the common block that difference is
    [[diag(lam - tol), D], [D^T, E]] (``D``, ``E`` already shifted by the tolerance); it is positive
    definite when lam > tol and its Schur complement E - D^T diag(1 / (lam - tol)) D is (Cholesky)."""
    gap = lam - FOLD_TOLERANCE
    if gap.min() <= 0:
        return False
    try:
        np.linalg.cholesky(E - D.T @ (D / gap[:, None]))
    except np.linalg.LinAlgError:
        return False
    return True


def rms(values: np.ndarray) -> float:
    """Root mean square of the finite entries (NaN when there are none)."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    return float(np.sqrt(np.mean(v * v))) if v.size else float("nan")

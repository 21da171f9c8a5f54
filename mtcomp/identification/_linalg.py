"""Linear algebra of the fit: column scaling, rank and null space of the scaled normal matrix, the
directions a fit moves in when some combinations are held, penalties with coefficients left free,
Cholesky solves, and readable names of undetermined combinations."""
from __future__ import annotations

import numpy as np
import scipy.linalg

from .._threads import one_blas_thread  # noqa: F401  (the fit's algebra runs under it)
from .result import UndeterminedCombination, error_scale


#: an unknown whose weight in the (orthonormal, scaled) null space exceeds this is undetermined; below
#: it, eigenvector round-off between a null direction and a weak determined one (~1e-6) is ignored
NULL_WEIGHT = 1e-4


#: a parameter is named in an undetermined combination when its weight exceeds this share of the largest
NAME_SHARE = 0.1


#: weight of a set-up unknown (a file's zero offset, its alignment) against a machine parameter when a
#: combination the data cannot determine is held: the set-up takes what it trades with machine errors
SETUP_WEIGHT = 1e-3
#: weight (against 1) of a machine parameter no laser file names in :func:`held_complement`
UNMEASURED_WEIGHT = 1e3


def held_complement(null: np.ndarray, machine: np.ndarray,
                    unmeasured: np.ndarray | None = None) -> np.ndarray:
    """(n, n - k) orthonormal directions a fit moves in, given the k orthonormal directions ``null``
    (column-scaled coordinates) the data do not determine and ``machine`` (n,) bool, True for machine
    parameters, False for set-up unknowns: ``{z : null^T W z = 0}`` with W = 1 on machine parameters,
    SETUP_WEIGHT^2 on set-ups and UNMEASURED_WEIGHT^2 on the machine parameters ``unmeasured`` (n,)
    bool marks (error components no laser file names; None: none). W is positive definite, so these
    directions and ``null`` together span everything: every fit of the data is reached, with the
    least weighted machine part of each undetermined combination.

    A constant the readings share between a laser's zero offset and the angle of an axis that never
    moved (through its Abbe arm) is the offset's: the plain minimum norm split it three ways and made
    a pitch of Z of 105 urad out of a laser run of X. Likewise a positioning run of Y at one tool
    length reads EYY plus the tool length times the pitch EAY: the positioning error the file names
    takes it, the pitch nobody measured stays at zero (the minimum norm made half of a real stage's
    84 um a pitch of 430 urad, which the controller tables then wrote)."""
    k = null.shape[1]
    if k == 0:
        return np.eye(null.shape[0])
    w = np.where(machine, 1.0, SETUP_WEIGHT ** 2)
    if unmeasured is not None:
        w = np.where(np.asarray(unmeasured, bool) & machine, UNMEASURED_WEIGHT ** 2, w)
    _, _, Vt = np.linalg.svd((w[:, None] * null).T, full_matrices=True)
    return Vt[k:].T


def _error_scales(columns) -> np.ndarray:
    """(n,) :func:`error_scale` of each column name (computed once per distinct name)."""
    columns = np.asarray(columns, dtype=object)
    out = np.empty(columns.shape[0])
    for name in set(columns.tolist()):
        out[columns == name] = error_scale(name)
    return out


def column_scale(A: np.ndarray) -> np.ndarray:
    """1 / sqrt(diag A): unit columns for the eigen-analysis. A column at round-off level (below
    1e-9 of the largest: a straightness no file measures, seen only through the rounding of the
    chain) keeps scale 1, so that it stays at zero size and counts as undetermined; scaled to unit
    norm, its round-off would pass for information and the step would follow it to 1e12."""
    norms = np.sqrt(np.clip(np.diag(A), 0.0, None))
    real = _seen_columns(A)
    return np.where(real, 1.0 / np.where(real, norms, 1.0), 1.0)


#: singular values of the dropped coefficients' factor below this share of the largest are round-off
#: in :func:`_eliminate` (the square of the 1e-15 at which a pseudo-inverse of their penalty cut)
ELIMINATE_RCOND = 3e-8


def _eliminate(F: np.ndarray, drop: np.ndarray) -> np.ndarray:
    """The penalty ``F^T F`` (F its factor) with the coefficients ``drop`` left free, as a factor:
    ``(I - Q Q^T) F_k`` on the others (zero columns for the dropped), Q an orthonormal basis of what
    the dropped columns ``F_d`` reach, so that ``|F z|^2`` is the least penalty over every value of
    theirs (the Schur complement ``S_kk - S_kd S_dd^+ S_dk`` of ``S = F^T F``). Cutting them out
    instead would price the kept ones as if the dropped were 0, and a straight line through the kept
    ones would cost something."""
    if not drop.any():
        return F
    keep = ~drop
    U, s, _ = np.linalg.svd(F[:, drop], full_matrices=False)
    Q = U[:, s > ELIMINATE_RCOND * max(float(s.max()) if s.size else 0.0, 1e-300)]
    out = np.zeros_like(F)
    Fk = F[:, keep]
    out[:, keep] = Fk - Q @ (Q.T @ Fk)
    return out


#: a column below this share of the largest column norm is round-off: the data do not see it
SEEN_SHARE = 1e-9


def _seen_columns(A: np.ndarray) -> np.ndarray:
    """(n,) bool: the unknowns the data see at all, columns of the normal matrix A above round-off
    (:data:`SEEN_SHARE` of the largest column norm)."""
    norms = np.sqrt(np.clip(np.diag(A), 0.0, None))
    return norms > SEEN_SHARE * max(float(norms.max()) if norms.size else 0.0, 1e-300)


def _unseen_apart(A: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """The column-scaled normal matrix ``D A D`` with the unknowns the data do not see at all
    (:func:`_seen_columns`) cut off from the rest: their rows and columns zero, so that each is a
    direction the data leave undetermined by itself. Left in, their round-off (1e-10 of a column,
    against 1e7 of the largest) couples them to the weakest directions the data do fix, whose
    eigenvalues are as small: a rotary axis's location error, seen by no reading while the axis
    stands at 0, took 1e-5 of such a direction and moved with it to 48 mrad."""
    As = A * np.outer(scale, scale)
    unseen = ~_seen_columns(A)
    As[unseen, :] = 0.0
    As[:, unseen] = 0.0
    return As


def _relative_singular_values(As: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(relative singular values s / s_max descending, eigenvectors) of a scaled normal matrix."""
    evals, V = np.linalg.eigh(As)
    order = np.argsort(evals)[::-1]
    evals, V = evals[order], V[:, order]
    sv = np.sqrt(np.clip(evals, 0.0, None))
    s_max = sv[0] if sv.size and sv[0] > 0 else 1.0
    return sv / s_max, V


def _gram(J: np.ndarray) -> np.ndarray:
    """J^T J with BLAS syrk (half the work of a general product)."""
    if J.dtype == np.float64 and J.flags.c_contiguous and J.shape[0] > 4 * J.shape[1]:
        from scipy.linalg.blas import dsyrk
        upper = dsyrk(1.0, J.T, trans=0, lower=0)      # J.T is Fortran-ordered: no copy
        return np.triu(upper) + np.triu(upper, 1).T
    return J.T @ J


#: bytes of one block of a file's Jacobian (:func:`file_normal_equations`): a block small enough to
#: stay in the processor's cache while it is weighted, multiplied and added to the normal equations
BLOCK_BYTES = 8 << 20


#: a block (of a file of several blocks, and of more rows than 4 times its columns) whose share of
#: non-zero Jacobian columns is at most this has the Gram matrix of those columns only
SPARSE_SHARE = 0.8


def block_obs(n_params: int) -> int:
    """Observations per block of a Jacobian with ``n_params`` columns (:data:`BLOCK_BYTES`)."""
    return max(64, BLOCK_BYTES // (8 * max(n_params, 1)))


def file_normal_equations(m, p, nuisance, ww, observed, pred, g_n, A_nn):
    """One file's part of the normal equations, block by block (``m.jacobian_blocks``): returns
    (J_p^T W r (n_params,), J_p^T W^2 J_p (n_params, n_params) or None, J_p^T W^2 J_n (n_params,
    n_nuisance) or None) and fills, in place, ``pred`` (the file's predictions), ``g_n`` (+= J_n^T W r)
    and ``A_nn`` (+= J_n^T W^2 J_n; None: the Gram matrices are skipped). ww: the file's weights."""
    n_p = m.model.n_params
    gp = np.zeros(n_p)
    App = np.zeros((n_p, n_p)) if A_nn is not None else None
    Apn = np.zeros((n_p, m.n_nuisance)) if A_nn is not None else None
    size = block_obs(n_p)
    # a file of one block (a few thousand readings or fewer) keeps one dense product, bit for bit
    # the earlier result: whether diagnose refines a small file's knots can turn on round-off
    sparse = A_nn is not None and m.n_obs > size
    for blk, y, Jp, Jn in m.jacobian_blocks(p, nuisance, size):
        pred[blk] = y
        wb = ww[blk]
        rw = wb * (observed[blk] - y)
        g_n += Jn.T @ (wb * rw)
        Jnw = Jn * wb[:, None] if A_nn is not None else None
        if A_nn is not None:
            A_nn += Jnw.T @ Jnw
        on = np.flatnonzero(Jp.any(axis=0)) if sparse and Jp.shape[0] > 4 * n_p else None
        if on is not None and on.size <= SPARSE_SHARE * n_p:
            # the columns that are zero all through the block add nothing: the products of the
            # rest (a block of one reading direction sees about a third of the parameters)
            Jon = Jp[:, on] * wb[:, None]
            gp[on] += Jon.T @ rw
            App[np.ix_(on, on)] += _gram(Jon)
            Apn[on] += Jon.T @ Jnw
            continue
        gp += Jp.T @ (wb * rw)
        if A_nn is not None:
            Jw = np.multiply(Jp, wb[:, None], out=Jp if Jp.flags.writeable else None)
            App += _gram(Jw)
            Apn += Jw.T @ Jnw
    return gp, App, Apn


#: a penalty that outweighs the data by at most this (largest diagonal entries) is added to their
#: normal matrix before its factor: the sum then loses at most 6 of its 16 digits to the penalty
PLAIN_FACTOR_RANGE = 1e6


def _solver(AB, FB=None):
    """A function gs_B -> (AB + FB^T FB)^-1 gs_B for the reduced normal matrix AB and the penalty's
    factor FB in the same directions (None: no penalty): its Cholesky factor, formed once and used
    by every step that shares them (the pseudo-inverse where round-off at the edge of the rank makes
    it not quite positive definite).

    Where the penalty outweighs the data by more than :data:`PLAIN_FACTOR_RANGE` (its largest
    diagonal entry against theirs) the factor is that of ``U^T AB U + diag(l)`` (U, sqrt(l) the
    right singular vectors and singular values of FB), scaled to a unit diagonal. At the largest
    weights REML may choose (1e13 times a well-seen coefficient's) the penalty's directions outweigh
    the data's by 1e17, and a factor of the plain sum lost the steps' digits along what the data
    alone fix: a noise-free laser run and ball-bar circle, their pitch held
    (:mod:`mtcomp.identification.unmeasured`), stopped after 20 iterations at 1e-4 um^2 of
    residual; in the penalty's singular vectors, each scaled by its own size, 1e-11 um^2.

    The basis comes from the factor, never from the formed square ``FB^T FB``: at a weight of e^28
    the square's entries are 1e14 and carry 1e-2 of round-off, which its eigen-decomposition spread
    over the directions the penalty does not see, where the data's curvature is 1e-4. The steps then
    solved a matrix a hundred times off in those directions and Gauss-Newton crept (a 3-axis campaign
    with a backlash the model lacks: 40 steps, cost still falling by 1e-5 a step). The singular
    vectors of FB are exact to 1e-16 of its largest singular value, the penalty along its null
    directions to 1e-18."""
    if AB.shape[0] == 0:
        return lambda v: v
    if FB is None or FB.shape[0] == 0:
        return _cholesky_solver(AB)
    if np.einsum("ij,ij->j", FB, FB).max() <= PLAIN_FACTOR_RANGE * np.abs(np.diag(AB)).max():
        return _cholesky_solver(AB + FB.T @ FB)
    _, sv, Vt = np.linalg.svd(FB, full_matrices=True)
    U = Vt.T
    H = U.T @ AB @ U
    H[np.diag_indices(sv.size)] += sv ** 2
    d = 1.0 / np.sqrt(np.maximum(np.diag(H), 1e-300))
    inner = _cholesky_solver(d[:, None] * H * d[None, :])
    return lambda v: U @ (d * inner(d * (U.T @ v)))


def _cholesky_solver(M):
    """:func:`_solver` of a matrix M without a penalty."""
    try:
        cho = scipy.linalg.cho_factor(M)
        return lambda v: scipy.linalg.cho_solve(cho, v)
    except np.linalg.LinAlgError:
        pinv = scipy.linalg.pinvh(M)
        return lambda v: pinv @ v


def _step(B, solve, gs):
    """Scaled Gauss-Newton step restricted to span(B): B (B^T As B)^-1 B^T gs, with ``solve`` from
    :func:`_solver`."""
    return B @ solve(B.T @ gs)


def _name_null_space(null, scale, to_file, names, svals) -> list[UndeterminedCombination]:
    """Readable basis of the null space: pivoted so that each direction has one leading unknown.

    null : (n, k) orthonormal null directions in scaled coordinates. A step ``D v`` of the unknowns
    (internal units) is ``D v * to_file`` in file units.
    """
    k = null.shape[1]
    if k == 0:
        return []
    # pivot on the unknowns with the largest weight (in scaled coordinates, where weights compare)
    _, _, piv = scipy.linalg.qr(null.T, pivoting=True)
    piv = piv[:k]
    M = null[piv, :]                                   # (k, k)
    basis_scaled = null @ np.linalg.solve(M, np.eye(k))   # 1 at its own pivot, 0 at the others
    out = []
    for j in range(k):
        v = basis_scaled[:, j]
        big = np.abs(v) >= NAME_SHARE * np.abs(v).max()
        f = v * scale * to_file
        pivot = piv[j]
        idx = [pivot] + [i for i in np.flatnonzero(big) if i != pivot]
        coef = f / f[pivot]
        out.append(UndeterminedCombination([(names[i], float(coef[i])) for i in idx],
                                           float(svals[j]) if j < len(svals) else 0.0))
    return out


def penalised_inverse(H: np.ndarray, S: np.ndarray | None = None, *,
                      factor: np.ndarray | None = None) -> np.ndarray:
    """(H + S)^-1 of a penalised fit's matrix, H the data's part and S the penalty's (symmetric
    positive definite together in the fitted directions; S None: H is the whole matrix),
    accurate where the penalty is many orders above the data.

    With S given, the inverse is taken in S's eigenbasis, where the directions the penalty does not
    see (a profile's offset and slope) carry the data's part alone, and its eigenvalues at the
    round-off of its largest are zero (Wood 2011's stable reparametrisation splits the penalty's
    range from its null space for the same reason). Summed first, H + S loses the data's part in those directions
    to the round-off of the penalty: at REML's largest roughness weight (1.4e12) a 5-axis
    campaign's matrix had a condition number of 4e17 after scaling, its inverse was wrong in every
    digit (50-digit arithmetic), and the posterior put 4e-4 um of standard error on a laser-measured
    positioning profile and variance on combinations the data leave open.

    The matrix is then scaled to a unit diagonal (Jacobi: D H D), so that each direction is judged
    at its own size, and inverted through its Cholesky factor; the pseudo-inverse only where
    round-off makes it not quite positive definite. A pseudo-inverse of H itself cuts at a share of
    its largest eigenvalue: beside a roughness weight of 1e12 it dropped the directions the data fix
    and the penalty does not see, and the fit's values, standard errors and degrees of freedom came
    out wrong.

    Given the penalty's factor F (S = F^T F) instead, its eigenbasis comes from F's singular
    vectors and keeps every eigenvalue above the round-off of F itself: the cut at the round-off of
    the formed square (n eps times its largest eigenvalue) took a class at a weight of e^-3 for zero
    beside one at e^28, and the posterior gave what that class's penalty fixes (positioning
    profiles' curvature between laser targets) 10 um of tool-tip standard error."""
    if H.shape[0] == 0:
        return np.zeros_like(H)
    if factor is not None and factor.shape[0]:
        _, sv, Vt = np.linalg.svd(factor, full_matrices=True)
        s = np.zeros(H.shape[0])
        s[:sv.size] = np.where(sv > H.shape[0] * np.finfo(float).eps * float(sv.max()), sv, 0.0) ** 2
        Ht = Vt @ H @ Vt.T
        return Vt.T @ penalised_inverse(0.5 * (Ht + Ht.T) + np.diag(s)) @ Vt
    if S is not None:
        s, U = np.linalg.eigh(0.5 * (S + S.T))
        s = np.where(s > S.shape[0] * np.finfo(float).eps * max(float(s.max()), 0.0), s, 0.0)
        Ht = U.T @ H @ U
        return U @ penalised_inverse(0.5 * (Ht + Ht.T) + np.diag(s)) @ U.T
    d = np.sqrt(np.clip(np.diag(H), 0.0, None))
    d = np.where(d > 0.0, 1.0 / np.where(d > 0.0, d, 1.0), 1.0)
    Hs = H * np.outer(d, d)
    try:
        inv = scipy.linalg.cho_solve(scipy.linalg.cho_factor(Hs), np.eye(H.shape[0]))
    except np.linalg.LinAlgError:
        inv = scipy.linalg.pinvh(Hs)
    return inv * np.outer(d, d)


def psd_factor(C: np.ndarray) -> np.ndarray:
    """R with R R^T the nearest positive semi-definite matrix to the symmetric ``C`` (its
    eigenvalues below zero, round-off of an inverse near the edge of the rank, set to zero)."""
    ev, V = np.linalg.eigh(0.5 * (C + C.T))
    return V * np.sqrt(np.clip(ev, 0.0, None))[None, :]

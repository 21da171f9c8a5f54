"""The covariance of a diagnosed model: of the common block's parameters and the extension terms'
coefficients (noise variance 1 after weighting), which of them the data determine, and the model
file's ``uncertainty`` (as identify writes it)."""
from __future__ import annotations

import numpy as np

from ..models.chain import ErrorModel
from ._linalg import RANK_TOLERANCE, Design, _eigh


def _subspace(design: Design, k: int) -> np.ndarray:
    """(m + k, r + k) the subspace a fit with k extra columns moves in: parameters = [T 0; 0 I]
    (the common block's determined directions ``design.T``, the extras' coefficients)."""
    m = design.A_original.shape[1]
    B = np.zeros((m + k, design.T.shape[1] + k))
    B[:m, :design.T.shape[1]] = design.T
    B[m:, design.T.shape[1]:] = np.eye(k)
    return B


def _determined(design: Design, extra: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(G, E, lam): the weighted normal matrix G (m + k, m + k) of the common block's columns and the
    extras (noise variance 1 after weighting), and the directions E (m + k, r) the data determine,
    with ``E^T G E = diag(lam)``: the subspace fixed at the start (``design.T``) and the extras, less
    what they leave undetermined between them (relative eigenvalue at most RANK_TOLERANCE)."""
    G = design.gram(extra)
    B = _subspace(design, extra.shape[1])
    H = B.T @ G @ B
    d = np.sqrt(np.clip(np.diag(H), 0, None))
    d = np.where(d > 0, d, 1.0)
    wv, V = _eigh(H / np.outer(d, d))
    ok = wv > RANK_TOLERANCE * wv.max()
    return G, B @ (V[:, ok] / d[:, None]), wv[ok]


def _covariance(design: Design, extra: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(covariance (m + k, m + k) of the common-block parameters and the extra columns'
    coefficients, noise variance 1 after weighting; determined (m + k,) bool): a parameter is
    determined unless it lies partly in a direction the data do not determine (outside the
    subspace fixed at the start, or in the null space of the extras)."""
    G, E, lam = _determined(design, extra)
    cov = (E / lam) @ E.T
    B = _subspace(design, extra.shape[1])
    # a parameter is determined when its unit vector lies in the span of B (scaled coordinates)
    scale = np.sqrt(np.clip(np.diag(G), 0, None))
    scale = np.where(scale > 0, scale, 1.0)
    Bs = B * scale[:, None]
    Qb, rb = np.linalg.qr(Bs)
    Qb = Qb[:, np.abs(np.diag(rb)) > 1e-8 * max(np.abs(np.diag(rb)).max(), 1e-300)]
    return cov, np.sum(Qb ** 2, axis=1) > 0.999


def _uncertainty(model: ErrorModel, design: Design, extra: np.ndarray, cov: np.ndarray, names: list,
                 theta_idx: list, machine_cols: np.ndarray) -> dict:
    """The model file's ``uncertainty`` of a diagnosed model (as identify writes it): the machine
    parameters' covariance (internal units, noise variance 1 after weighting) and the combinations
    of them the data do not see at all, each scaled to 1 um rms tool-tip error over the travel
    (mtcomp.identification.fit.travel_metric), so that a prediction resting on one is blank.

    cov : the covariance of the common block's parameters and the extras' coefficients (the final
    fit's). names : the machine parameters' names. theta_idx : their positions among the common block
    and the extras. machine_cols : (m,) bool, the common block's machine (not set-up) columns."""
    from ..identification.problem import DEFAULT_RCOND, travel_metric
    idx = np.asarray(theta_idx, dtype=int)
    C = cov[np.ix_(idx, idx)]
    # what the data do not see among the machine parameters alone (set-ups free to follow)
    A = np.hstack([design.A_original[:, machine_cols], extra]) * design.w[:, None]
    order = np.r_[np.flatnonzero(machine_cols), design.A_original.shape[1] + np.arange(extra.shape[1])]
    pos = {int(t): j for j, t in enumerate(order)}
    A = A[:, [pos[int(t)] for t in idx]]
    norms = np.sqrt(np.einsum("ij,ij->j", A, A))
    seen = norms > 1e-9 * max(float(norms.max()) if norms.size else 0.0, 1e-300)
    s = np.where(seen, 1.0 / np.where(seen, norms, 1.0), 1.0)
    w, V = _eigh((A * s).T @ (A * s))
    # identify's rule: a relative singular value at most DEFAULT_RCOND (these are its squares)
    N = s[:, None] * V[:, w <= DEFAULT_RCOND ** 2 * max(float(w.max()), 1e-300)]
    free = np.array([model.param_names.index(n) for n in names], dtype=int)
    if N.shape[1]:
        M = travel_metric(model, free, free.size)
        size = np.sqrt(np.clip(np.einsum("ik,ij,jk->k", N, M, N), 0.0, None))
        keep = size > 1e-12 * np.linalg.norm(N, axis=0)
        N = N[:, keep] * (1e-3 / size[keep])
    return {"names": tuple(names), "covariance": np.nan_to_num(C), "undetermined": N}

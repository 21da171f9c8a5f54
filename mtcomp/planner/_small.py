"""Many small dense problems at once (one per block): loops over the few rows and columns, vector
operations over the blocks. For n blocks of 3 to 6 rows this is several times faster than numpy's
batched matmul / solve, which pay a per-matrix overhead."""
from __future__ import annotations

import numpy as np


def gram(A: np.ndarray, lam: float = 0.0) -> np.ndarray:
    """(n, m, m): A^T A + lam I for A (n, r, m)."""
    n, r, m = A.shape
    H = np.empty((n, m, m))
    for i in range(m):
        ai = A[:, :, i]
        for j in range(i, m):
            h = np.einsum("nk,nk->n", ai, A[:, :, j])
            H[:, i, j] = h
            H[:, j, i] = h
        H[:, i, i] += lam
    return H


def at_b(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(n, m): A^T b for A (n, r, m), b (n, r)."""
    return np.einsum("nkm,nk->nm", A, b, optimize=False)


def a_x(A: np.ndarray, x: np.ndarray) -> np.ndarray:
    """(n, r): A x for A (n, r, m), x (n, m)."""
    out = A[:, :, 0] * x[:, 0:1]
    for j in range(1, A.shape[2]):
        out += A[:, :, j] * x[:, j:j + 1]
    return out


def spd_solve(H: np.ndarray, g: np.ndarray) -> np.ndarray:
    """(n, m): H^-1 g for symmetric positive definite H (n, m, m) by Cholesky, vectorised over n
    (explicit loops over the m <= 6 rows: no reductions over short strided axes)."""
    n, m, _ = H.shape
    L = [[None] * m for _ in range(m)]
    inv_diag = [None] * m
    for j in range(m):
        s = H[:, j, j].copy()
        for k in range(j):
            s -= L[j][k] * L[j][k]
        d = np.sqrt(s)
        inv_diag[j] = 1.0 / d
        for i in range(j + 1, m):
            t = H[:, i, j].copy()
            for k in range(j):
                t -= L[i][k] * L[j][k]
            L[i][j] = t * inv_diag[j]
    y = [None] * m
    for i in range(m):
        t = g[:, i].copy()
        for k in range(i):
            t -= L[i][k] * y[k]
        y[i] = t * inv_diag[i]
    x = np.empty((n, m))
    for i in range(m - 1, -1, -1):
        t = y[i]
        for k in range(i + 1, m):
            t = t - L[k][i] * x[:, k]
        x[:, i] = t * inv_diag[i]
    return x

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
    """(n, m): H^-1 g for symmetric positive definite H (n, m, m) by Cholesky, vectorised over n."""
    n, m, _ = H.shape
    L = np.zeros_like(H)
    for j in range(m):
        s = H[:, j, j] - np.sum(L[:, j, :j] ** 2, axis=1)
        L[:, j, j] = np.sqrt(s)
        for i in range(j + 1, m):
            L[:, i, j] = (H[:, i, j] - np.sum(L[:, i, :j] * L[:, j, :j], axis=1)) / L[:, j, j]
    y = np.empty((n, m))
    for i in range(m):
        y[:, i] = (g[:, i] - np.sum(L[:, i, :i] * y[:, :i], axis=1)) / L[:, i, i]
    x = np.empty((n, m))
    for i in range(m - 1, -1, -1):
        x[:, i] = (y[:, i] - np.sum(L[:, i + 1:, i] * x[:, i + 1:], axis=1)) / L[:, i, i]
    return x

"""Many small dense problems at once (one per block): loops over the few rows and columns, vector
operations over the blocks. For n blocks of 3 to 6 rows this is several times faster than numpy's
batched matmul / solve, which pay a per-matrix overhead."""
from __future__ import annotations

import numpy as np


_COMPARISONS = (np.less, np.less_equal, np.greater, np.greater_equal, np.equal, np.not_equal)


def down_columns(op, a, b, out=None) -> np.ndarray:
    """``op(a, b)`` (a numpy ufunc: arithmetic on floats, or a comparison) for (n, k) operands of
    which one is a row broadcast over the n rows (a (k,) vector, a (1, k) row, a read-only
    broadcast) or a column slice of a wider array, computed down the columns into a C-ordered array
    (``out`` when given; it may be ``a``).

    The same numbers as numpy's own order, which for these operands loops over each row's k entries
    one row at a time: for k = 3 five to ten times slower than one pass down each column (a
    compensation of a million blocks made some fifty million such row loops)."""
    shape = np.broadcast_shapes(np.shape(a), np.shape(b))
    if out is None:
        dtype = bool if op in _COMPARISONS else np.result_type(a, b)
        out = np.empty(shape, dtype)
    whole = all(isinstance(v, np.ndarray) and v.shape == shape and v.flags.c_contiguous
                for v in (a, b))
    # two whole C-ordered arrays (a 5-axis machine's six rows of six): numpy's order is the fast one
    return op(a, b, out=out, order="K" if whole else "F")


def _diagonal(lam, m: int) -> np.ndarray:
    """(m,) the regularisation weights: lam a number (the same for every column) or (m,)."""
    return np.broadcast_to(np.asarray(lam, dtype=float), (m,))


def gram(A: np.ndarray, lam=0.0) -> np.ndarray:
    """(n, m, m): A^T A + diag(lam) for A (n, r, m), lam a number or (m,)."""
    n, r, m = A.shape
    lam = _diagonal(lam, m)
    H = np.empty((n, m, m))
    for i in range(m):
        ai = A[:, :, i]
        for j in range(i, m):
            h = np.einsum("nk,nk->n", ai, A[:, :, j])
            H[:, i, j] = h
            H[:, j, i] = h
        H[:, i, i] += lam[i]
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


def row_max_abs(a: np.ndarray) -> np.ndarray:
    """(n,): the largest |a_ij| of each row of a (n, m) (a loop over the few columns: numpy's
    reductions along a short last axis are slow)."""
    out = np.abs(a[:, 0])
    for j in range(1, a.shape[1]):
        np.maximum(out, np.abs(a[:, j]), out=out)
    return out


def row_max(a: np.ndarray) -> np.ndarray:
    """(n,): the largest a_ij of each row of a (n, m), ``a.max(axis=1)`` (NaN where a row has one)
    as a loop over the few columns, like :func:`row_max_abs`."""
    out = a[:, 0].copy()
    for j in range(1, a.shape[1]):
        np.maximum(out, a[:, j], out=out)
    return out


def any_rows(a: np.ndarray) -> np.ndarray:
    """(n,) bool: whether any entry of each row of a (n, ...) is true, ``a.any(axis=(1, ...))``, as
    an or over the few columns (numpy's any along short axes took 50 ms per million blocks, the
    column loop 2 ms), and nothing more when no entry at all is true (the usual case)."""
    n = a.shape[0]
    flat = a.reshape(n, int(np.prod(a.shape[1:])))
    out = np.zeros(n, bool)
    if flat.shape[1] == 0 or not flat.any():
        return out
    for j in range(flat.shape[1]):
        out |= flat[:, j]
    return out


def any_rows_but(a: np.ndarray, col: int) -> np.ndarray:
    """(n,) bool: :func:`any_rows` of a (n, k) without its column ``col``, ``np.delete(a, col,
    axis=1).any(axis=1)`` without the copy, and nothing more when no entry is true (the usual
    case)."""
    out = np.zeros(a.shape[0], bool)
    if not a.any():
        return out
    for j in range(a.shape[1]):
        if j != col:
            out |= a[:, j]
    return out


def column_extremes(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """((m,) smallest, (m,) largest entry of each column of a (n, m), n > 0): ``a.min(axis=0)``
    and ``a.max(axis=0)`` column by column (numpy's reduction over the rows of a few columns took
    90 ms a million rows, a column 2 ms)."""
    return (np.array([a[:, j].min() for j in range(a.shape[1])]),
            np.array([a[:, j].max() for j in range(a.shape[1])]))


def row_norm(a: np.ndarray) -> np.ndarray:
    """(n,): Euclidean length of each row of a (n, m), summed in column order as ``np.sum(a**2, 1)``."""
    out = a[:, 0] * a[:, 0]
    for j in range(1, a.shape[1]):
        out += a[:, j] * a[:, j]
    return np.sqrt(out, out=out)


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


def normal_step(A: np.ndarray, b: np.ndarray, x: np.ndarray | None = None,
                lam=0.0) -> np.ndarray:
    """(n, m): the Gauss-Newton step ``-(A^T A + L)^-1 (A^T b + L x)`` of each block, L = diag(lam).

    A (n, r, m), b (n, r), x (n, m) or None (zero), lam a number or (m,). The same numbers as ``-spd_solve(gram(A, lam),
    at_b(A, b) + lam x)`` with the normal equations formed and factored entry by entry on contiguous
    (n,) vectors (one transposed copy of A and b, then no strided passes): the per-block 3 x 3 (or
    6 x 6) problems of a chunk cost a few dozen vector operations in all.
    """
    return NormalFactor(A, lam).step(b, x)


class NormalFactor:
    """The Cholesky factors of ``A^T A + diag(lam)`` of many blocks, kept for further right-hand
    sides (Newton steps that keep the Jacobian: the chord method). A (n, r, m), lam a number or
    (m,)."""

    def __init__(self, A: np.ndarray, lam=0.0, _parts=None):
        if _parts is not None:
            self.Ac, self.L, self.inv_diag, self.lam = _parts
            return
        n, r, m = A.shape
        self.lam = lam = _diagonal(lam, m)
        self.Ac = Ac = np.ascontiguousarray(A.transpose(1, 2, 0))   # (r, m, n)
        H = [[None] * m for _ in range(m)]
        for i in range(m):
            for j in range(i, m):
                h = Ac[0, i] * Ac[0, j]
                for k in range(1, r):
                    h += Ac[k, i] * Ac[k, j]
                H[i][j] = h
            H[i][i] += lam[i]
        # H = L L^T (lower triangle from the upper one stored)
        L = [[None] * m for _ in range(m)]
        inv_diag = [None] * m
        for j in range(m):
            s = H[j][j]
            for k in range(j):
                s = s - L[j][k] * L[j][k]
            inv_diag[j] = 1.0 / np.sqrt(s)
            for i in range(j + 1, m):
                t = H[j][i]
                for k in range(j):
                    t = t - L[i][k] * L[j][k]
                L[i][j] = t * inv_diag[j]
        self.L, self.inv_diag = L, inv_diag

    def __len__(self):
        return self.Ac.shape[2]

    def take(self, idx) -> "NormalFactor":
        """The factors of the blocks idx (index array or boolean mask)."""
        L = [[None if v is None else v[idx] for v in row] for row in self.L]
        return NormalFactor(None, _parts=(self.Ac[:, :, idx], L, [v[idx] for v in self.inv_diag],
                                          self.lam))

    def step(self, b: np.ndarray, x: np.ndarray | None = None) -> np.ndarray:
        """(n, m): ``-(A^T A + L)^-1 (A^T b + L x)`` for b (n, r), x (n, m) or None."""
        Ac, L, inv_diag, lam = self.Ac, self.L, self.inv_diag, self.lam
        r, m, n = Ac.shape
        bc = np.ascontiguousarray(b.T)                     # (r, n)
        y = [None] * m
        for i in range(m):
            t = Ac[0, i] * bc[0]
            for k in range(1, r):
                t += Ac[k, i] * bc[k]
            if lam[i] and x is not None:
                t += lam[i] * x[:, i]
            for k in range(i):
                t = t - L[i][k] * y[k]
            y[i] = t * inv_diag[i]
        sol = [None] * m
        for i in range(m - 1, -1, -1):
            t = y[i]
            for k in range(i + 1, m):
                t = t - L[k][i] * sol[k]
            sol[i] = t * inv_diag[i]
        out = np.empty((n, m))
        for i in range(m):
            np.negative(sol[i], out=out[:, i])
        return out

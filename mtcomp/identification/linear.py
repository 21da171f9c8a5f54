"""The fit engine on a problem that is linear from the start (a design matrix, not an error model):
penalised least squares with the engine's rank rule and posterior covariance, returning the one
result type, :class:`~.result.FitResult`. Thermal's drift fit is such a problem (its ridge is the
penalty)."""
from __future__ import annotations

import numpy as np
import scipy.linalg

from ._linalg import _relative_singular_values, column_scale, penalised_inverse
from .problem import DEFAULT_RCOND
from .result import FitResult


def solve_linear(X: np.ndarray, y: np.ndarray, specs, penalty: np.ndarray | None = None,
                 rcond: float = DEFAULT_RCOND, weighting: str = "unit (um)") -> FitResult:
    """Minimise ``|y - X b|^2 + b^T P b`` over b.

    X : (n, k) design, file units of y per internal unit of each parameter (``specs``, ParamSpec).
    y : (n,) readings, file units. penalty : (k, k) P (file units), None for plain least squares.
    A direction counts as determined when the data fix it (relative singular value of the
    column-scaled design above ``rcond``) or the penalty does; the rest is held at zero. The
    covariance is the penalised fit's posterior (Wood 2006): ``s2 (X^T X + P)^-1`` on the determined
    directions, ``s2`` the residual sum of squares over ``n - edf``, edf the trace of the hat matrix.
    Values and standard errors are returned in internal units (file value / ``to_file``).
    """
    X = np.asarray(X, dtype=float)
    y = np.asarray(y, dtype=float)
    n, k = X.shape
    specs = tuple(specs)
    P = np.zeros((k, k)) if penalty is None else np.asarray(penalty, dtype=float)
    G = X.T @ X
    d = column_scale(G)
    rel, V = _relative_singular_values(G * np.outer(d, d))
    Ps = P * np.outer(d, d)
    null = V[:, rel <= rcond]
    if null.shape[1]:
        ev, U = np.linalg.eigh(null.T @ Ps @ null)
        null = null @ U[:, ev <= rcond * max(float(np.trace(Ps)), 1e-300)]
    B = scipy.linalg.null_space(null.T) if null.shape[1] else np.eye(k)
    Gs = B.T @ (G * np.outer(d, d)) @ B
    Hinv = penalised_inverse(Gs, B.T @ Ps @ B)
    b = d * (B @ (Hinv @ (B.T @ (d * (X.T @ y)))))
    resid = y - X @ b
    cost = float(resid @ resid)
    edf = float(np.trace(Hinv @ Gs))
    dof = n - edf
    s2 = cost / dof if dof > 0 else np.nan
    cov = s2 * (d[:, None] * (B @ Hinv @ B.T) * d[None, :])
    determined = np.linalg.norm(null, axis=1) <= 1e-4 if null.shape[1] else np.ones(k, dtype=bool)
    to_file = np.array([s.to_file for s in specs])
    se = np.where(determined, np.sqrt(np.clip(np.diag(cov), 0.0, None)), np.nan)
    rank = int(B.shape[1])
    kept = rel[rel > rcond]
    return FitResult(
        model=None, specs=specs, values=b / to_file, std_errors=se / to_file,
        free=np.ones(k, dtype=bool), determined=determined, nuisance_specs=[],
        nuisance_values=np.zeros(0), nuisance_std_errors=np.zeros(0),
        unknown_names=tuple(s.name for s in specs),
        covariance=cov / np.outer(to_file, to_file), undetermined=[], rank=rank,
        condition_number=float(kept[0] / kept[-1]) if kept.size else np.inf, singular_values=rel,
        files=[], n_obs=n, n_params=k, dof=dof, sigma=float(np.sqrt(s2)) if dof > 0 else float("nan"),
        iterations=1, converged=True, cost=cost, seconds=0.0, weighting=weighting,
        directions=(d[:, None] * B) / to_file[:, None], residual=resid)

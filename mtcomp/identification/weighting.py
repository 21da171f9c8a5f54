"""The weights of identify's fit (:func:`.fit.identify`'s ``weights``): one per observation.

``"unit"``: every residual in um (translational readings, lengths), urad (angles) or um/min
(velocities). ``"noise"``: iteratively reweighted, ``w = 1 / noise`` per file and unit, each noise
estimated from the previous fit's residuals with the degrees of freedom its observations use (the
sum of their leverages). A dict ``{tag: noise}`` fixes the noise of some files; an (n_obs,) array
gives each reading's noise (diagnose's floors).
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from ._linalg import _error_scales
from .result import error_unit

#: most fits with weights='noise' (each re-estimates the noise of every file and unit)
NOISE_PASSES = 5


def unit_weights(mms) -> np.ndarray:
    """(n_obs,) internal -> error unit of each observation of the measurement models ``mms``."""
    return np.concatenate([_error_scales(m.obs_column) for m in mms])


def fit_weights(problem, weights, rcond: float, max_iterations: int, tol: float):
    """((n_obs,) weights of the observations of ``problem`` (:class:`.fit._Problem`), their label for
    the report) of :func:`.fit.identify`'s ``weights``."""
    if isinstance(weights, str) and weights == "unit":
        return unit_weights(problem.mms), "unit (um, urad)"
    if isinstance(weights, str) and weights == "noise":
        w = unit_weights(problem.mms)
        for _ in range(NOISE_PASSES):
            sol = problem.solve(w, rcond, max_iterations, tol, leverage=True)
            w_new = noise_weights(problem, sol, w)
            change = np.max(np.abs(w_new / w - 1.0))
            w = w_new
            if change < 0.01:
                break
        return w, "1/noise per file"
    if isinstance(weights, dict):
        return dict_weights(problem, weights), "given noise per file"
    if isinstance(weights, np.ndarray) and weights.shape == (problem.n_obs,):
        # each reading's noise in its error unit (um, urad, um/min): diagnose's floors
        return unit_weights(problem.mms) / weights, "given noise per reading"
    raise ValueError(f"weights must be 'unit', 'noise', a dict or one noise per reading, not {weights!r}")


def _groups(problem):
    """(file index, scale, observation index array) per file and error unit (um, urad and um/min
    are separate groups: a velocity's noise is not a position's)."""
    for i, (m, sl) in enumerate(zip(problem.mms, problem.obs_slices)):
        scales = _error_scales(m.obs_column)
        units = np.array([error_unit(c) for c in m.obs_column])
        for u in np.unique(units):
            sel = units == u
            yield i, scales[sel][0], np.arange(sl.start, sl.stop)[sel]


def noise_weights(problem, sol, w_used):
    """1/noise per file and unit from the residuals of a fit ``sol`` with weights ``w_used``:
    noise^2 = sum of squared residuals / (n - sum of the leverages of those observations)."""
    w = unit_weights(problem.mms)
    for _, s, idx in _groups(problem):
        resid = sol.r[idx] / w_used[idx] * s   # error units
        dof = idx.size - float(np.sum(sol.leverage[idx]))
        noise = np.sqrt(np.sum(resid ** 2) / max(dof, 1e-12))
        if noise > 0:
            w[idx] = s / noise
    return w


def dict_weights(problem, noise: dict):
    """The weights of a dict ``{tag: noise}`` (um or urad): 1/noise for the files it names, unit
    weights for the rest."""
    w = unit_weights(problem.mms)
    tags = {m.tag: i for i, m in enumerate(problem.mms)}
    for tag in noise:
        if tag not in tags:
            raise InputError(f"weights name file {tag!r}, which is not among the data "
                             f"({', '.join(tags)})")
    for i, s, idx in _groups(problem):
        tag = problem.mms[i].tag
        if tag in noise:
            sigma = float(noise[tag])
            if not sigma > 0:
                raise InputError(f"noise of file {tag!r} must be positive, got {sigma}")
            w[idx] = s / sigma
    return w

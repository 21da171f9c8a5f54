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
#: under weights 'unit', the least noise a unit is weighted by (um, urad, um/min): below it the
#: residuals are the readings' round-off (a noise-free simulation), whose ratio between the units
#: says nothing (weights 1e9 apart took directions the data fix below the rank threshold)
UNIT_NOISE_FLOOR = 1e-4


def unit_weights(mms) -> np.ndarray:
    """(n_obs,) internal -> error unit of each observation of the measurement models ``mms``."""
    return np.concatenate([_error_scales(m.obs_column) for m in mms])


def fit_weights(problem, weights, rcond: float, max_iterations: int, tol: float):
    """((n_obs,) weights of the observations of ``problem`` (:class:`.fit._Problem`), their label for
    the report, the fit at those weights when the reweighting already made it, else None) of
    :func:`.fit.identify`'s ``weights``."""
    if isinstance(weights, str) and weights == "unit":
        w = unit_weights(problem.mms)
        classes = list(unit_groups(problem))
        if len(classes) < 2:
            return w, "unit (um, urad)", None
        # one residual variance for um and urad alike sizes one class's standard errors by the
        # other's noise: each unit gets its own (a variance-components step, feasible GLS)
        w, sol, _ = _reweighted(problem, classes, w, rcond, max_iterations, tol, UNIT_NOISE_FLOOR)
        return w, "unit, 1/noise per unit", sol
    if isinstance(weights, str) and weights == "noise":
        _, _, w = _reweighted(problem, list(file_groups(problem)), unit_weights(problem.mms), rcond,
                              max_iterations, tol)
        return w, "1/noise per file", None
    if isinstance(weights, dict):
        return dict_weights(problem, weights), "given noise per file", None
    if isinstance(weights, np.ndarray) and weights.shape == (problem.n_obs,):
        # each reading's noise in its error unit (um, urad, um/min): diagnose's floors
        return unit_weights(problem.mms) / weights, "given noise per reading", None
    raise ValueError(f"weights must be 'unit', 'noise', a dict or one noise per reading, not {weights!r}")


def _reweighted(problem, groups: list, w, rcond: float, max_iterations: int, tol: float,
                floor: float = 0.0):
    """(weights, the fit at them, the weights that fit gives) of iterated reweighting from ``w`` by
    1/noise per group of observations: each fit's residuals give each group's noise
    (:func:`noise_weights`) until the weights change by less than 1 % (at most :data:`NOISE_PASSES`
    fits; when they run out, the last weights and no fit); no group's noise below ``floor``."""
    for _ in range(NOISE_PASSES):
        sol = problem.solve(w, rcond, max_iterations, tol, leverage=True)
        w_new = noise_weights(sol, w, groups, floor)
        if np.max(np.abs(w_new / w - 1.0)) < 0.01:
            return w, sol, w_new
        w = w_new
    return w, None, w


def unit_groups(problem):
    """(label, scale, observation index array) per error unit of the readings of every file: um, urad
    and um/min (a velocity's noise is not a position's)."""
    units = np.concatenate([[error_unit(c) for c in m.obs_column] for m in problem.mms])
    scales = unit_weights(problem.mms)
    for u in np.unique(units):
        idx = np.flatnonzero(units == u)
        yield str(u), scales[idx[0]], idx


def file_groups(problem):
    """(label "tag unit", scale, observation index array) per file and error unit."""
    for m, u, s, idx in _file_units(problem):
        yield f"{m.tag} {u}", s, idx


def _file_units(problem):
    """(measurement model, error unit, scale, observation index array) per file and error unit."""
    for m, sl in zip(problem.mms, problem.obs_slices):
        scales = _error_scales(m.obs_column)
        units = np.array([error_unit(c) for c in m.obs_column])
        for u in np.unique(units):
            sel = units == u
            yield m, str(u), scales[sel][0], np.arange(sl.start, sl.stop)[sel]


def noise_weights(sol, w_used, groups, floor: float = 0.0):
    """1/noise per group of observations (``groups``: :func:`unit_groups`, :func:`file_groups`) from
    the residuals of a fit ``sol`` with weights ``w_used``: noise^2 = sum of squared residuals / (n -
    sum of the leverages of those observations), the penalised fit's effective degrees of freedom
    split by the observations that spend them, at least ``floor``. A group without degrees of
    freedom left, or without residual, keeps its weight."""
    w = np.array(w_used, dtype=float)
    for _, s, idx in groups:
        resid = sol.r[idx] / w_used[idx] * s   # error units
        dof = idx.size - float(np.sum(sol.leverage[idx]))
        noise = np.sqrt(np.sum(resid ** 2) / dof) if dof > 0 else 0.0
        if noise > 0:
            noise = max(noise, floor)
            w[idx] = s / noise
    return w


def group_noise(problem, label: str, w, s2: float) -> dict:
    """{group label: noise} that the fit's covariance takes for each group of observations (um, urad,
    um/min): the noise its weights give, ``scale / w``, times the posterior's sqrt(s2). Under
    ``"unit"`` weights one per unit, under ``"noise"`` or a dict one per file and unit; {} for weights
    given per reading."""
    if label == "given noise per reading" or not np.isfinite(s2):
        return {}
    groups = unit_groups(problem) if label.startswith("unit") else file_groups(problem)
    return {name: float(s / np.median(w[idx]) * np.sqrt(s2)) for name, s, idx in groups}


def dict_weights(problem, noise: dict):
    """The weights of a dict ``{tag: noise}`` (um or urad): 1/noise for the files it names, unit
    weights for the rest."""
    w = unit_weights(problem.mms)
    tags = {m.tag: i for i, m in enumerate(problem.mms)}
    for tag in noise:
        if tag not in tags:
            raise InputError(f"weights name file {tag!r}, which is not among the data "
                             f"({', '.join(tags)})")
    for m, _, s, idx in _file_units(problem):
        tag = m.tag
        if tag in noise:
            sigma = float(noise[tag])
            if not sigma > 0:
                raise InputError(f"noise of file {tag!r} must be positive, got {sigma}")
            w[idx] = s / sigma
    return w

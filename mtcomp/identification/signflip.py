"""Whether a laser file that disagrees with the others agrees with them with its sign reversed.

A laser file written as target minus measured (ISO 230-2 defines the deviation of position as the
position reached minus the target), or taken with the laser's direction set the wrong way, holds every
error of its run with the sign reversed. The fit of it with other files of the machine then leaves
it, or them, far off (:func:`.agreement.disagreement_note`). The test: the fit again with that
file's readings negated, linearised at the fit (the model is linear in its parameters up to
products of errors, 1e-5 of a reading): the directions the fit moved in (``FitResult.directions``)
and the weighted Jacobian of the readings there, the fit's own residual and the change the reversal
makes for each laser file as right-hand sides of one least-squares solve, all without the roughness
penalty so that they are compared alike. When a file reversed comes to the other files' level from
clearly above it (:func:`_agrees_reversed`) and the whole fit improves, a note names it; the file is
never reversed by mtcomp. Laser runs alone carry no sign of their own (the others reversed instead
fit as well): the note then says so.
"""
from __future__ import annotations

import numpy as np

from ._linalg import block_obs
from .result import error_scale, error_unit

#: with its sign reversed, a file's mean square residual beyond the other files' must fall by at
#: least this factor squared, or the whole fit's weighted sum of squares by this factor
FLIP_GAIN = 3.0
#: ... and its rms residual must come within this factor of the largest of the other files'
NEAR = 1.5
#: another file's reversal whose sum of squares is within this share of the best fits as well
SAME_FIT = 0.01


def _weighted_blocks(problem, result, w):
    """Yield (observation indices of the stacked problem, the weighted Jacobian of those readings
    along the fit's directions) of every block of every file, at the fit."""
    free_idx = np.flatnonzero(problem.free)
    n_free = free_idx.size
    D = np.asarray(result.directions, dtype=float)
    p = np.asarray(result.values, dtype=float)
    nuis = np.asarray(result.nuisance_values, dtype=float)
    k_obs = k_nuis = 0
    for m in problem.measurements:
        sn = slice(n_free + k_nuis, n_free + k_nuis + m.n_nuisance)
        if m.n_obs:
            for blk, _, Jp, Jn in m.jacobian_blocks(p, nuis[k_nuis:k_nuis + m.n_nuisance],
                                                    block_obs(m.model.n_params)):
                idx = np.arange(k_obs, k_obs + m.n_obs)[blk]
                M = Jp[:, free_idx] @ D[:n_free] + Jn @ D[sn]
                yield idx, M * w[idx][:, None]
        k_obs += m.n_obs
        k_nuis += m.n_nuisance


def _refits(problem, result, flips: list[int]) -> np.ndarray:
    """(n_obs, 1 + len(flips)) weighted residuals of the linearised least squares: as fitted, then
    with the readings of each measurement of ``flips`` negated (one solve, every right-hand side)."""
    mms = problem.measurements
    w = np.concatenate([f.weight for f in result.files])
    ends = np.cumsum([0] + [m.n_obs for m in mms])
    V = np.zeros((w.size, 1 + len(flips)))
    V[:, 0] = result.residual
    for j, i in enumerate(flips, start=1):
        sl = slice(ends[i], ends[i + 1])
        V[sl, j] = -2.0 * w[sl] * mms[i].observed
    r = result.directions.shape[1]
    G, c = np.zeros((r, r)), np.zeros((r, V.shape[1]))
    blocks = list(_weighted_blocks(problem, result, w))    # each file's Jacobian evaluated once
    for idx, M in blocks:
        G += M.T @ M
        c += M.T @ V[idx]
    coef = np.linalg.lstsq(G, c, rcond=1e-12)[0]
    R = V.copy()
    for idx, M in blocks:
        R[idx] -= M @ coef
    R[:, 1:] += R[:, :1]
    return R


def _file_rms(result, R) -> np.ndarray:
    """(n_files, columns of R) rms residual of each file in error units (um, urad)."""
    out, k = np.zeros((len(result.files), R.shape[1])), 0
    for i, f in enumerate(result.files):
        unit_w = np.array([error_scale(c) for c in f.columns])
        e = R[k:k + f.n_obs] / f.weight[:, None] * unit_w[:, None]
        out[i] = np.sqrt(np.mean(e ** 2, axis=0)) if f.n_obs else 0.0
        k += f.n_obs
    return out


def _agrees_reversed(rms: np.ndarray, sse: np.ndarray, i: int, j: int) -> bool:
    """File ``i`` reversed (column ``j``) agrees clearly better: the whole fit's sum of squares falls,
    and either the file stood out as written and no longer does (its mean square residual beyond
    the other files' largest, ``rest``, more than ``rest`` squared and :data:`FLIP_GAIN` squared
    times what is left beyond it reversed; reversed, within :data:`NEAR` of ``rest``), or the whole
    fit's sum of squares falls by :data:`FLIP_GAIN` or more with no file left more than :data:`NEAR`
    times as far off as before (the others may be the ones the reversed file pulled off)."""
    if not sse[j] < sse[0]:
        return False
    rest = max((rms[k, j] for k in range(rms.shape[0]) if k != i), default=0.0)
    before, after = rms[i, 0] ** 2 - rest ** 2, max(rms[i, j] ** 2 - rest ** 2, 0.0)
    if before >= max(rest ** 2, FLIP_GAIN ** 2 * after) and rms[i, j] <= NEAR * rest:
        return True
    return bool(sse[j] * FLIP_GAIN <= sse[0] and np.all(rms[:, j] <= NEAR * rms[:, 0]))


def reversed_sign_note(result, datasets, problem) -> str | None:
    """One line naming the laser file whose readings agree with the others' with their sign
    reversed (module docstring); None when reversing none helps clearly."""
    if len(datasets) < 2 or getattr(result, "directions", None) is None or not result.directions.shape[1]:
        return None
    lasers = [i for i, f in enumerate(result.files) if f.kind == "laser" and f.n_obs]
    if not lasers:
        return None
    R = _refits(problem, result, lasers)
    return sign_note(_file_rms(result, R), np.sum(R ** 2, axis=0), lasers,
                     [(f.path, error_unit(str(f.columns[0])) if f.n_obs else "") for f in result.files])


def sign_note(rms: np.ndarray, sse: np.ndarray, lasers: list, files: list) -> str | None:
    """The note of :func:`reversed_sign_note` from a fit's refits: ``rms`` (n_files, 1 + len(lasers))
    each file's rms residual as fitted, then with each laser file of ``lasers`` (file indices)
    reversed; ``sse`` (1 + len(lasers),) the whole fit's weighted sums of squares; ``files`` each
    file's (path, error unit)."""
    agree = [(i, j) for j, i in enumerate(lasers, start=1) if _agrees_reversed(rms, sse, i, j)]
    if not agree:
        return None
    i, j = min(agree, key=lambda ij: sse[ij[1]])
    others = [k for k in range(rms.shape[0]) if k != i]
    rest, rest0 = max(rms[k, j] for k in others), max(rms[k, 0] for k in others)
    # laser runs alone carry no sign of their own: reversing the others instead fits as well
    alike = [files[k][0] for jj, k in enumerate(lasers, start=1)
             if k != i and sse[jj] <= sse[j] * (1 + SAME_FIT)]
    also = (f" (or {' and '.join(map(str, alike))} reversed instead: the fit is the same, and the data "
            "cannot tell which)" if alike else "")
    path, u = files[i]
    return (f"{path}: its readings agree with the other files with their sign reversed: the fit then "
            f"leaves it {rms[i, j]:.3g} {u} rms and the others {rest:.3g} {u} at most, against "
            f"{rms[i, 0]:.3g} and {rest0:.3g} {u} as written{also}; error = measured - target (ISO 230-2): "
            "was the file written as target - measured, or taken with the laser's direction set the wrong "
            "way? check the laser's direction setting (mtcomp reverses nothing)")

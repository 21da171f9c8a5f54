"""The model diagnose writes: the selected model refitted by the package's penalised fit.

The held-out selection compares extensions on the base's own least squares (``_linalg.Design``),
whose profiles have as many functions as the data have positions: between two laser targets such a
profile is whatever the knots make of it, and its standard error counts only what the data
determine. The model written (MODEL.json, the report's ``final`` figures) is the selected model
(base and the chosen terms) fitted again by identify's engine (:func:`mtcomp.identification.fit.
solve`) with the roughness penalty on every profile, a reversal profile included, and REML weights
(Eilers and Marx 1996; Wood 2011): the axes read at few positions get knots finer than the data's
spacing, so that between what was measured a profile follows the smoothest curve through it, and
the posterior standard error grows where it rests on the penalty rather than on data.

Its held-out figure refits the same penalised problem, at the penalty weights chosen on all data,
without each fold (whole runs, as the selection holds them out) and predicts the fold's readings,
each file's set-up fitted on the readings the fold keeps (:func:`_held_out`).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

#: a penalised fit whose weighted residual sum of squares exceeds the selection's by more than this
#: factor went astray (the penalty costs the fit a few noise variances: 1.00 to 1.09 of the
#: selection's on five simulated campaigns; astray, about 7, 50 and 1000 on three)
MISFIT_SLACK = 1.5
#: knots per median spacing of an axis's distinct positions (the final fit's finer basis); on the
#: real run ess_b02_x two gave standard errors between targets too small for the profile's
#: departure from the pitch table's line (up to 2.8 of them, 84 % within 2), four up to 2.1
KNOTS_PER_SPACING = 4


@dataclass
class PenalisedFit:
    """The final penalised fit: ``result`` (:class:`mtcomp.identification.result.FitResult`),
    ``resid`` and ``cv_resid`` ((n,) residuals on all data and held out, um/urad, in the stack's
    order of observations), ``data_rank`` (directions the data alone determine, set-ups included)."""

    result: object
    resid: np.ndarray
    cv_resid: np.ndarray
    data_rank: int

    @property
    def rank(self) -> int:
        return self.data_rank


def fine_machine(machine, datasets, rows: int, axes: set):
    """``machine`` with the linear axes among ``axes`` (names: those whose knots the data choose,
    not the machine file or a start model) that the data read at few positions (no more distinct
    positions within the knots' range than the axis has functions: a pitch table's targets, each
    with a function of its own) on knots ``KNOTS_PER_SPACING`` to the median spacing of those
    positions (within the knots' range), at
    most ``MAX_BASIS`` functions per axis and within the fit's size budget (rows times the square of
    the functions summed over the linear axes, :data:`mtcomp.models.basis.FIT_SIZE_BUDGET`). An axis
    whose knots are already that fine keeps them."""
    from ..measurement.readings import data_positions
    from ..models.basis import FIT_SIZE_BUDGET, MAX_BASIS
    positions = data_positions(machine, datasets)
    wanted = {}
    for a in machine.axes:
        if (a.is_rotary or a.basis != "bspline" or a.spline_range is None or a.name not in positions
                or a.name not in axes):
            continue
        lo, hi = a.spline_range
        s = np.unique(np.round(positions[a.name][np.isfinite(positions[a.name])], 3))
        s = s[(s >= lo - 1e-9) & (s <= hi + 1e-9)]
        n_now = int(a.spline_intervals or 0)
        if s.size < 3 or not n_now or s.size > n_now + a.degree:
            # more positions than functions (a fine run, a ball-bar circle): the data, not the
            # knots, already say what lies between readings
            continue
        n = int(np.ceil((hi - lo) / (float(np.median(np.diff(s))) / KNOTS_PER_SPACING) - 1e-9))
        n = min(n, MAX_BASIS - a.degree)
        if n > n_now:
            wanted[a.name] = (n_now, n)

    def total(k: float) -> int:
        return sum(max(n_now, int(k * n)) + machine.axis(name).degree
                   for name, (n_now, n) in wanted.items())

    k = 1.0
    while wanted and k > 0.05 and rows * total(k) ** 2 > FIT_SIZE_BUDGET:
        k *= 0.8
    fine = tuple(replace(a, spline_intervals=max(wanted[a.name][0], int(k * wanted[a.name][1])))
                 if a.name in wanted else a for a in machine.axes)
    return replace(machine, axes=fine)


def penalised_fit(st, w: np.ndarray, model, starts: list, folds: np.ndarray, rcond: float,
                  selected_resid: np.ndarray) -> PenalisedFit:
    """Fit ``model`` (ErrorModel: the fine base and the chosen terms) to the stack's data sets
    (``st.datasets``) with the roughness penalty, every parameter free, from the first of ``starts``
    (dicts name -> value, internal units; others from zero). A fit that does not converge, or whose
    weighted residual sum of squares exceeds :data:`MISFIT_SLACK` times the selection's
    (``selected_resid``, (n,) um or urad, the selection's final fit), is tried again from the next
    start; the fit with the least sum is kept. Each file is weighted by its noise floor (``w``,
    (n,) the selection's weights, 1 / noise of each of the stack's observations); held out by
    ``folds`` ((n,) fold of each of the stack's observations: :func:`_held_out`)."""
    from ..identification.problem import build_measurement_models
    weights = _file_noise(st, w)
    bound = MISFIT_SLACK * float(np.sum((w * selected_resid) ** 2))
    best = None
    for start in starts:
        p0 = np.array([start.get(n, 0.0) for n in model.param_names], dtype=float)
        mms = build_measurement_models(model, st.datasets)
        result = _solve(model, mms, p0, weights, rcond)
        order = _stack_order(st, mms)
        resid = _residuals(mms, result.values, _nuisance(result, mms, {}))[order]
        sse = float(np.sum((w * resid) ** 2))
        if best is None or sse < best[0]:
            best = (sse, result, mms, order, resid)
        if result.converged and sse <= bound:
            break
    _, result, mms, order, resid = best
    cv = _held_out(st, result, mms, weights, folds, order)
    data_rank = int(np.sum(result.singular_values > rcond))
    return PenalisedFit(result, resid, cv, data_rank)


def _held_out(st, result, mms, weights: dict, folds: np.ndarray, order: np.ndarray) -> np.ndarray:
    """(n,) each of the stack's readings predicted by the penalised fit refitted without its fold
    (every reading of a row the fold touches left out), reading minus prediction, um or urad.

    The refit keeps the penalty weights REML chose on all data and is exact for the problem
    linearised at the full fit: a penalised least-squares fit is a linear smoother, and the
    residuals of the readings o it leaves out are ``(I - H_oo)^-1 r_o`` (r the full fit's weighted
    residuals, H_oo the block of its hat matrix, ``J_o C J_o^T`` with C the posterior covariance
    over the residual variance; Wood 2017, the leave-one-out identity of a linear smoother, for a
    group). Each file's set-up is refitted on the readings the fold keeps, in the whole file's own
    terms (a thermal file reads drift since its first reading, a tracker's turn is about the centre
    of all its points); the set-up of a file the fold leaves without readings keeps the full fit's."""
    J, sigma, nuis_cols = _weighted_jacobian(result, mms, weights)
    D = np.asarray(result.directions, dtype=float)
    K = J @ D
    P = _penalised_normal(result, mms, J, D)
    r = np.asarray(result.residual, dtype=float)
    # each observation's file and row, as integer keys
    big = 1 + max(int(st.row.max(initial=0)), max((int(m.obs_row.max(initial=0)) for m in mms), default=0))
    obs_key = np.concatenate([i * big + np.asarray(m.obs_row, dtype=np.int64) for i, m in enumerate(mms)])
    stack_key = st.file.astype(np.int64) * big + st.row.astype(np.int64)
    cv = np.full(len(st), np.nan)
    for k in np.unique(folds):
        o = np.isin(obs_key, stack_key[folds == k])
        if not o.any():
            continue
        # a file with no reading left keeps its set-up (the refit cannot move it)
        held = [nuis_cols[i] for i, m in enumerate(mms) if nuis_cols[i].size and o[_file_slice(mms, i)].all()]
        hold = D[np.concatenate(held), :] if held else None
        full = np.full(len(r), np.nan)
        full[o] = left_out_residuals(K[o], P, r[o], hold) * sigma[o]
        cv[folds == k] = full[order][folds == k]
    return cv


def left_out_residuals(K_o: np.ndarray, P: np.ndarray, r_o: np.ndarray, hold: np.ndarray | None = None
                       ) -> np.ndarray:
    """(m,) the residuals of m readings left out of a penalised linear least-squares fit:
    ``(I - K_o P^-1 K_o^T)^-1 r_o = r_o + K_o (P - K_o^T K_o)^-1 K_o^T r_o`` (Woodbury), K_o (m, k)
    their rows of the weighted design, P (k, k) the fit's penalised normal matrix ``K^T K + S`` on
    all readings, r_o (m,) their weighted residuals in that fit. hold : (h, k) combinations held at
    the fit's values in the refit. What only these readings fix cannot be refitted without them:
    it keeps the fit's value (the least-squares solution of the refit's normal equations)."""
    Pk = P - K_o.T @ K_o
    if hold is not None and hold.size:
        Pk = Pk + 1e10 * max(float(np.abs(np.diag(P)).max()), 1e-300) * (hold.T @ hold)
    step = np.linalg.lstsq(0.5 * (Pk + Pk.T), K_o.T @ r_o, rcond=1e-12)[0]
    return r_o + K_o @ step


def _penalised_normal(result, mms, J: np.ndarray, D: np.ndarray) -> np.ndarray:
    """(k, k) the penalised normal matrix ``J^T J + S`` in the directions the fit moved in (D, (n_unknowns,
    k), ``result.directions``): J the weighted Jacobian at the fit, S the roughness penalty at the
    weights REML chose, each class's penalty normalised as the fit normalises it. Its inverse over the
    residual variance is the fit's posterior covariance, also where the fit reports a parameter as
    undetermined."""
    from ..identification._linalg import column_scale
    from ..identification.fit import _Problem
    A = J.T @ J
    P = A.copy()
    if result.smoothing is not None:
        stacked = _Problem(result.model, mms, result.free, None)
        scale = column_scale(A)
        for cls, S in stacked.scaled_penalties(A, scale).items():
            if cls in result.smoothing.weights:
                P += result.smoothing.weights[cls] * S / np.outer(scale, scale)
    H = D.T @ P @ D
    return 0.5 * (H + H.T)


def _file_slice(mms, i: int) -> slice:
    start = sum(m.n_obs for m in mms[:i])
    return slice(start, start + mms[i].n_obs)


def _weighted_jacobian(result, mms, weights: dict):
    """((n_obs, n_unknowns) Jacobian of the weighted residuals' predictions at the fit ``result``,
    in the order of its unknowns; (n_obs,) each reading's noise (the file's, um or urad); per file
    the indices of its set-up among the unknowns)."""
    index = {n: i for i, n in enumerate(result.unknown_names)}
    nuisance = _nuisance(result, mms, {})
    blocks, sigma, cols = [], [], []
    for m, nu in zip(mms, nuisance):
        _, Jp, Jn = m.predict_and_jacobian(result.values, nu)
        scale = np.where(m.obs_unit_scale == 1.0, 1e3, m.obs_unit_scale)
        s = weights[m.tag]
        Jfull = np.zeros((m.n_obs, len(result.unknown_names)))
        Jfull[:, :int(result.free.sum())] = Jp[:, result.free]
        c = np.array([index[n] for n in m.nuisance_names], dtype=int)
        Jfull[:, c] = Jn
        blocks.append(Jfull * (scale / s)[:, None])
        sigma.append(np.full(m.n_obs, s))
        cols.append(c)
    return np.vstack(blocks), np.concatenate(sigma), cols


def _solve(model, mms, p0, weights: dict, rcond: float):
    from ..identification.fit import solve
    from ..identification.problem import FitProblem, SolverOptions
    free = np.ones(model.n_params, dtype=bool)
    tags = {m.tag for m in mms}
    # no weak-direction pass (identify's, :mod:`mtcomp.identification._weak`): on ess_b02_x it held
    # the profile between targets 2.7 of its standard errors off the pitch table's line. On knots finer than a laser's targets the penalty alone fixes a profile's values at the targets
    # against its values between them, and such a combination can move the file's zero with the
    # targets' values: written so that the set-ups carry none of it, a reading the data fix keeps only
    # the variance they leave (:func:`mtcomp.identification.unmeasured.setups_without_variance`)
    problem = FitProblem(model, mms, free, p0, weights={t: s for t, s in weights.items() if t in tags},
                         penalty=True, hold_weak=False, setups_free=True)
    return solve(problem, SolverOptions(rcond=rcond))


def _file_noise(st, w: np.ndarray) -> dict:
    """{file tag: noise floor} of the weights ``w`` (1 / noise of each of the stack's observations:
    the median over the file's readings in its most frequent unit, um or urad), as identify's
    per-file weights take it."""
    from ..identification.problem import unique_tags
    out = {}
    for fi, tag in enumerate(unique_tags(st.datasets)):
        sel = st.file == fi
        units, counts = np.unique(st.unit[sel], return_counts=True)
        main = sel & (st.unit == units[np.argmax(counts)])
        out[tag] = float(np.median(1.0 / w[main]))
    return out


def _nuisance(result, mms, fixed: dict) -> list:
    """Each file's set-up values: ``fixed``'s by name, else the fit ``result``'s."""
    full = dict(zip(result.unknown_names[int(result.free.sum()):], result.nuisance_values))
    return [np.array([fixed.get(n, full.get(n, 0.0)) for n in m.nuisance_names]) for m in mms]


def _residuals(mms, values, nuisance: list) -> np.ndarray:
    """(n,) reading minus prediction of every file's observations in file order, um or urad."""
    # ball-bar lengths: mm -> um (their unit scale is 1, as the stack reads them)
    return np.concatenate([(m.observed - m.predict(values, x)) * np.where(m.obs_unit_scale == 1.0, 1e3,
                                                                           m.obs_unit_scale)
                           for m, x in zip(mms, nuisance)])


def _stack_order(st, mms) -> np.ndarray:
    """(n,) index of each stack observation among the measurement models' observations."""
    keys = {}
    k = 0
    for fi, m in enumerate(mms):
        for r, c in zip(m.obs_row, m.obs_column):
            keys[(fi, int(r), str(c))] = k
            k += 1
    return np.array([keys[(int(f), int(r), str(c))] for f, r, c in zip(st.file, st.row, st.column)])

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

Its held-out figure refits the same penalised problem without each fold (whole runs, as the
selection holds them out) and predicts the fold's readings, each file's set-up fitted on the
readings the fold keeps.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

#: knots per median spacing of an axis's distinct positions (the final fit's finer basis)
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
    not the machine file or a start model) that the data read at few positions on knots
    ``KNOTS_PER_SPACING`` to the median spacing of those positions (within the knots' range), at
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
        if s.size < 3 or not n_now:
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


def penalised_fit(st, w: np.ndarray, model, start: dict, folds: np.ndarray, rcond: float) -> PenalisedFit:
    """Fit ``model`` (ErrorModel: the fine base and the chosen terms) to the stack's data sets
    (``st.datasets``) with the roughness penalty, every parameter free, from ``start`` (name ->
    value, internal units; others from zero), each file weighted by its noise floor (``w``, (n,) the
    selection's weights, 1 / noise of each of the stack's observations); held out by ``folds``
    ((n,) fold of each of the stack's observations)."""
    from ..identification.problem import build_measurement_models, unique_tags
    from ..measurement.drift import drift_context
    from ..measurement.readings import measurement_model
    datasets = st.datasets
    weights = _file_noise(st, w)
    p0 = np.array([start.get(n, 0.0) for n in model.param_names], dtype=float)
    mms = build_measurement_models(model, datasets)
    result = _solve(model, mms, p0, weights, rcond)
    order = _stack_order(st, mms)
    resid = _residuals(mms, result.values, _nuisance(result, mms, {}))[order]
    cv = np.full(len(st), np.nan)
    for k in np.unique(folds):
        out = folds == k
        sub, keeps = [], []
        for fi, (d, tag) in enumerate(zip(datasets, unique_tags(datasets))):
            keep = np.ones(len(d), dtype=bool)
            keep[np.unique(st.row[(st.file == fi) & out])] = False
            keeps.append(keep)
            if keep.any():
                # drift features computed on the whole file (a time since its first reading must not
                # move when the fold leaves that reading out)
                ctx = {n: v[keep] for n, v in drift_context(model, d).items()}
                sub.append(measurement_model(model, d.subset(keep), None, tag=tag, extra_context=ctx))
        if sum(m.n_obs for m in sub) == 0:
            continue
        fold = _solve(model, sub, p0, weights, rcond)
        # each file's set-up refitted, at the fold's parameters, on the readings the fold keeps in
        # the whole file's own terms (a thermal file reads drift since its first row, a set-up
        # rotates about the points' centre: the fold's subset has its own first row and centre)
        fixed = dict(zip(fold.unknown_names[int(fold.free.sum()):], fold.nuisance_values))
        kept = np.concatenate([keep[m.obs_row] for m, keep in zip(mms, keeps)])
        nuisance = _setups_on_kept(mms, fold.values, _nuisance(result, mms, fixed), kept)
        cv[out] = _residuals(mms, fold.values, nuisance)[order][out]
    data_rank = int(np.sum(result.singular_values > rcond))
    return PenalisedFit(result, resid, cv, data_rank)


def _solve(model, mms, p0, weights: dict, rcond: float):
    from ..identification.fit import solve
    from ..identification.problem import FitProblem, SolverOptions
    free = np.ones(model.n_params, dtype=bool)
    tags = {m.tag for m in mms}
    problem = FitProblem(model, mms, free, p0, weights={t: s for t, s in weights.items() if t in tags},
                         penalty=True, hold_weak=False)
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


def _setups_on_kept(mms, values, nuisance: list, kept: np.ndarray, iterations: int = 3) -> list:
    """Each file's set-up (``nuisance``, the start) fitted by Gauss-Newton at the parameters
    ``values`` on its observations ``kept`` ((n,) bool over every file's observations in file
    order; residuals in reading units, um or urad); a file with none kept keeps its start."""
    out, k = [], 0
    for m, nu in zip(mms, nuisance):
        sel = kept[k:k + m.n_obs]
        k += m.n_obs
        nu = np.array(nu, dtype=float)
        if not sel.any() or nu.size == 0:
            out.append(nu)
            continue
        scale = np.where(m.obs_unit_scale == 1.0, 1e3, m.obs_unit_scale)[sel]
        for _ in range(iterations):
            pred, _, Jn = m.predict_and_jacobian(values, nu)
            r = (m.observed - pred)[sel] * scale
            step = np.linalg.lstsq(Jn[sel] * scale[:, None], r, rcond=None)[0]
            nu = nu + step
            if np.max(np.abs(step), initial=0.0) < 1e-12:
                break
        out.append(nu)
    return out


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

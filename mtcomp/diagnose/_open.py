"""The model diagnose writes: identify's penalised fit of the diagnosis's final model.

The selection's final least squares (``_linalg.Design``) is the data's own fit in every direction
the rank test keeps. Some of those directions the data fix only weakly: a ball-bar circle alone reads
one radial deviation per angle, which the positioning, straightness and angular profiles of two axes
share; the least squares splits it between them as the noise falls, a millimetre each, with standard
errors of thousands of um. Between sparse readings it is no better: laser targets about 29 mm apart
on 16 mm knots leave the spline's coefficients between two targets to the noise and to the other
terms (a screw period aliased at the targets), and the least squares' profile there was 100 um rms
off the truth while every combination counted as fixed to better than 5 um of rms tool-tip error over
the travel. Identify's fit does not (:func:`mtcomp.identification.fit.solve`): its profiles carry the
roughness penalty (Eilers and Marx 1996, eq. 5; weights by REML, Wood 2011, eq. 4), so that where the
data are silent they follow the smoothest curve, and what the data then still fix only weakly is held
at the least predicted error, its variance kept apart. So the model written is always that fit, never
the least squares' free coefficients.

The weak combinations are reported as identify judges them (:func:`mtcomp.identification._weak.
weak_directions`: a combination whose rms tool-tip error over the data's region the data fix only to
worse than 1 um, and which the fit does not put more than 3 of its standard errors from zero), with
the noise floor as the scale. The model written is the same model (base and chosen terms, on the
selection's knots, but for an axis read at 3 to 15 positions, which gets 16 functions as in
identify's fit: :mod:`mtcomp.identification._sparse`) fitted by identify's engine, each reading
weighted by the diagnosis's noise floor: the chosen terms start at the selection's values (a
feed-dependent Abbe term's moving centre multiplies its angle: from zero it stays unseen), the base
where the base fit started (zero, or a start model's determined values: at the least squares'
millimetres the chain's products of errors would pass for information); what the data do not
determine stays there. What they determine is judged by identify's rank rule (``DEFAULT_RCOND``,
not the selection's ``_linalg.RCOND``: at that threshold a margin combination of the pitch, roll and
yaw no laser names, held at zero, moved a trunnion's squarenesses' standard errors from 4 to 33 urad
and X's positioning profile's to 55 um) and where the base starts, with the chosen terms at
zero, as identify judges its model: at the selection's values a term's products with the base's
columns are second-order effects, which no reading fixes, yet they passed the rank test (a backlash
of 8 um made one more combination of a 5-axis model count as determined, fixed only to 24 um; the
fit moved it to 470 urad of C's angular positioning and 330 urad of its tilt, 32 um off the truth at
unseen poses). A factor seen only through another chosen factor (that moving centre) then stays at
the selection's value. It is written with the fit's posterior covariance (its residual variance the
fit's own, as identify's, but not below a noise floor measured on repeated readings: residuals that
scatter less than the repeats have taken noise for information). When it fits the data clearly worse
than the least squares, or Gauss-Newton did not converge, it is still written, and the report says
so (:func:`open_fit`).

No gate on the weak combinations' standard errors decides it: one at compensate's 5 um limit
(``--max-correction-sd-um``) as an rms over the region let through a least squares whose standard
error passes that limit where the region ends (two CMM plates of 11 x 7 holes: a weakest combination
of 3.8 um rms, 5.0 to 5.7 um at holes between the measured ones, which compensate left uncorrected;
the least squares 0.57 um from the truth over the plates rigid-aligned, identify's fit of the same
model 0.15 um, as identify's own model), and the sparse targets above had no weak combination at all.

The selection is untouched: its findings, their parameters and the final held-out figures are the
least squares'.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np


@dataclass
class OpenFit:
    """Identify's fit of the model written: ``result`` (its
    :class:`~mtcomp.identification.result.FitResult`), ``n_weak`` (combinations the least squares'
    data fix only weakly), ``sse`` and ``sse_lsq`` (its weighted sum of squares and the least
    squares', noise variances), ``sd`` and ``sd_lsq`` (their residual standard deviations: sum of
    squares over the degrees of freedom, noise floors), ``rms_um`` (its rms residual of the readings
    in um, None without), ``worse`` (``sd`` exceeds ``sd_lsq`` by more than the excess ratio)."""

    result: object
    n_weak: int
    sse: float
    sse_lsq: float
    sd: float = float("nan")
    sd_lsq: float = float("nan")
    rms_um: float | None = None
    worse: bool = False
    by_file: dict | None = None
    heldout_rms_um: float | None = None

    def report(self) -> dict:
        """REPORT.json's ``final.written`` (docs/diagnose.md)."""
        r = self.result
        out = {"model": "penalised", "weak": int(self.n_weak), "held": int(len(r.held_sd_um)),
               "rms_um": None if self.rms_um is None else round(self.rms_um, 4),
               "sum_of_squares": round(float(self.sse), 4),
               "sum_of_squares_least_squares": round(float(self.sse_lsq), 4),
               "residual_sd": round(float(self.sd), 4), "residual_sd_least_squares": round(float(self.sd_lsq), 4),
               "converged": bool(r.converged), "fits_worse": bool(self.worse)}
        if r.smoothing is not None:
            out["penalty_weights"] = {k: float(v) for k, v in r.smoothing.weights.items()}
        if self.by_file:
            out["by_file"] = self.by_file
        if self.heldout_rms_um is not None:
            out["heldout_rms_um"] = round(self.heldout_rms_um, 4)
        if "sparse" in r.info:              # (mtcomp.identification._sparse.sparse_note)
            out["sparse"] = r.info["sparse"]
        return out


def _metric(st, model, names: list, theta_idx: np.ndarray, size: int) -> np.ndarray:
    """(size, size) the mean squared tool-tip error (mm^2) over the data's region per coefficient
    (:func:`mtcomp.identification.problem.travel_metric`) at the machine parameters' positions
    ``theta_idx`` among the coefficients; zero for the set-ups and what moves no tip."""
    from ..identification.problem import data_region, fitted_axes, travel_metric
    free = np.array([model.param_names.index(n) for n in names], dtype=int)
    mask = np.zeros(model.n_params, dtype=bool)
    mask[free] = True
    region = data_region(model.machine, st.datasets, fitted_axes(model, mask))
    M = np.zeros((size, size))
    M[np.ix_(theta_idx, theta_idx)] = travel_metric(model, free, free.size, region)
    return M


def weak_combinations(st, design, extra: np.ndarray, theta: np.ndarray, model, names: list,
                      theta_idx) -> np.ndarray:
    """(k,) the standard errors (um of rms tool-tip error over the data's region) of the combinations
    of the final least squares (``theta``: the common block's parameters, then the extras'
    coefficients) its data fix only weakly, by identify's rule (module docstring), with the noise
    floor as the residual scale (the design's weights are 1 / noise)."""
    from ..identification._weak import held_directions, weak_directions
    from ._covariance import _determined
    theta_idx = np.asarray(theta_idx, dtype=int)
    G, E, lam = _determined(design, extra)
    if not lam.size:
        return np.zeros(0)
    M = _metric(st, model, names, theta_idx, G.shape[0])
    y = (E.T @ (G @ theta)) / lam                      # the fit's coordinates on E
    W, Q = weak_directions(M, np.diag(lam), E, np.ones(G.shape[0]), 1.0, y)
    return np.sqrt(held_directions(np.diag(lam), W, Q)[1])


def _stack_order(st, mms) -> np.ndarray:
    """(n,) index of each of the stack's readings among the measurement models' readings."""
    keys, k = {}, 0
    for fi, m in enumerate(mms):
        for r, c in zip(np.asarray(m.obs_row).tolist(), np.asarray(m.obs_column).tolist()):
            keys[(fi, int(r), str(c))] = k
            k += 1
    return np.array([keys[(int(f), int(r), str(c))] for f, r, c in zip(st.file, st.row, st.column)],
                    dtype=np.int64)


def open_fit(st, model, start: np.ndarray, noise: np.ndarray, lsq: tuple, n_weak: int,
             repeats: bool, excess_ratio: float) -> OpenFit:
    """Identify's fit of ``model`` (the base and the chosen terms) to the stack's files from
    ``start`` ((n_params,) internal units), each reading weighted by its noise floor ``noise`` ((n,)
    in the stack's order, um or urad ...); ``lsq``: the least squares' (weighted sum of squares,
    rank). What the data determine is judged with the chosen terms at zero (module docstring). The
    posterior's residual variance is the fit's own, not below the noise floor's when ``repeats``
    (every floor measured on repeated readings). ``worse`` when its residual standard deviation (sum
    of squares over its degrees of freedom) exceeds the least squares' by more than
    ``excess_ratio``, the factor by which the diagnosis's held-out residual may exceed the noise
    floor before it counts as structure (``mtcomp.diagnose._diagnose.EXCESS_RATIO``): what the
    penalty then takes from the data's fit is structure of its own, which the report names."""
    from ..identification.fit import solve
    from ..identification.problem import FitProblem, SolverOptions, build_measurement_models
    mms = build_measurement_models(model, st.datasets, known_setup=st.known_setup)
    n_obs = sum(m.n_obs for m in mms)
    order = _stack_order(st, mms)
    if order.size != n_obs:          # (the stack and identify's models read the same files)
        raise RuntimeError(f"diagnose: identify's models of the files hold {n_obs} readings, the "
                           f"diagnosis's {order.size}")
    per_reading = np.empty(n_obs)
    per_reading[order] = noise
    base = np.array([s.base for s in model.param_specs], dtype=bool)

    def fit(sd_of_reading):
        problem = FitProblem(model, mms, np.ones(model.n_params, dtype=bool), start,
                             weights=sd_of_reading, penalty=True, hold_weak=True,
                             rank_point=np.where(base, start, 0.0), known_noise=repeats)
        return solve(problem, SolverOptions())
    result = fit(per_reading)
    sse = float(result.residual @ result.residual)
    sse_lsq, rank, resid_lsq, folds = lsq
    sd = np.sqrt(sse / max(float(result.dof), 1.0))
    sd_lsq = np.sqrt(sse_lsq / max(n_obs - float(rank), 1.0))
    um = st.unit == "um"
    resid = (result.residual * per_reading)[order]      # reading less prediction, stack order
    done = OpenFit(result, n_weak, sse, sse_lsq, float(sd), float(sd_lsq),
                   float(np.sqrt(np.mean(resid[um] ** 2))) if um.any() else None,
                   worse=not sd <= excess_ratio * sd_lsq,
                   by_file=_by_file(st, resid, resid_lsq, excess_ratio))
    if done.worse and um.any():
        done.heldout_rms_um = _heldout_rms_um(fit, per_reading, order, folds, um)
    return done


def _by_file(st, resid: np.ndarray, resid_lsq: np.ndarray, excess_ratio: float) -> dict:
    """Per file and unit: the rms residual of the model written and of the least squares (stack
    order, file units), and whether the first exceeds the second by more than ``excess_ratio``."""
    from ..identification.problem import unique_tags
    out = {}
    for fi, tag in enumerate(unique_tags(st.datasets)):
        for u in np.unique(st.unit[st.file == fi]):
            sel = (st.file == fi) & (st.unit == u)
            rms, rms_lsq = (float(np.sqrt(np.mean(r[sel] ** 2))) for r in (resid, resid_lsq))
            out[f"{tag}" if len(np.unique(st.unit[st.file == fi])) == 1 else f"{tag} ({u})"] = {
                "unit": str(u), "rms": round(rms, 4), "rms_least_squares": round(rms_lsq, 4),
                "worse": bool(rms > excess_ratio * rms_lsq)}
    return out


#: standard deviation (file units) that leaves a held-out reading out of identify's fit
LEFT_OUT_SD = 1e9


def _heldout_rms_um(fit, per_reading: np.ndarray, order: np.ndarray, folds: np.ndarray,
                    um: np.ndarray) -> float:
    """Held-out rms (um) of the model written: identify's fit (``fit``: noise floors per reading ->
    its result) once per fold of the diagnosis's held-out evaluation, the fold's readings left out
    (their standard deviation ``LEFT_OUT_SD``), each reading predicted by the fit without its fold.
    Costs one fit per fold: made only when the model written fits clearly worse than the least
    squares, whose held-out figures then do not describe it."""
    cv = np.full(order.size, np.nan)
    for k in np.unique(folds):
        out = np.flatnonzero(folds == k)                 # stack order
        sd = per_reading.copy()
        sd[order[out]] = LEFT_OUT_SD
        cv[out] = (fit(sd).residual * sd)[order[out]]
    return float(np.sqrt(np.nanmean(cv[um] ** 2)))


def written_model(st, design, fit, fitted, where: tuple, start: dict, say, floor: tuple,
                  machine=None) -> tuple:
    """(the model diagnose writes, identify's fit of ``fitted``'s model (module docstring) with
    ``fitted``'s support, held axes and notes; REPORT.json's ``final.written``). ``fitted``: the
    final least squares ``fit`` as a model with its covariance; ``where``: (the extras' columns, the
    machine parameters' names, their positions among the fit's coefficients); ``start``: the base
    fit's start values (name -> value); ``floor``: (every noise floor was measured on repeated
    readings, the factor by which a residual may exceed the floor before it counts as structure),
    :func:`open_fit`'s. ``machine``: the base of the model written, when its knots differ from the
    diagnosis's (room between sparse positions, ``_diagnose._base_machines``): the chosen terms
    start at their values, the base where the base fit started, as on the diagnosis's knots."""
    from ..models.chain import ErrorModel
    extra, names, theta_idx = where
    sd = weak_combinations(st, design, extra, fit.theta, fitted.model, names, theta_idx)
    model = fitted.model
    if machine is not None and machine != model.machine:
        model = ErrorModel(machine, model.terms)
    p0 = np.array([start.get(n, 0.0) if s.base else fitted.params[n]
                   for n, s in zip(model.param_names, model.param_specs)])
    done = open_fit(st, model, p0, 1.0 / design.w, (fit.sse, fit.rank, fit.resid, design.folds),
                    sd.size, *floor)
    r = done.result
    weakest = (f"the data fix {sd.size} combination(s) of the least squares only weakly, to "
               f"{sd.max():.3g} um of tool-tip error at worst; " if sd.size else "")
    caveat = "".join(
        [f"; it fits the data clearly worse than the least squares (residual {done.sd:.3g} against "
         f"{done.sd_lsq:.3g} noise floors{worse_files(done.report())}): structure the model lacks"
         if done.worse else "",
         "; Gauss-Newton did not converge within its iterations" if not r.converged else ""])
    say(f"model written: identify's penalised fit of the final model ({weakest}"
        f"{len(r.held_sd_um)} held at the least error{caveat})")
    info = dict(fitted.info)
    info["nuisance"] = {n: float(v) for n, v in zip(r.unknown_names[model.n_params:], r.nuisance_values)}
    s2 = float(r.sigma) ** 2 if np.isfinite(r.sigma) else 1.0
    params, uncertainty = seen_through_factor(fitted, r.fitted_model, max(s2, 1.0) if floor[0] else s2)
    largest = round(float(sd.max()), 4) if sd.size else 0.0
    return (replace(fitted, model=model, params=params, info=info, uncertainty=uncertainty),
            {**done.report(), "largest_sd_um": largest})


def worse_files(written: dict) -> str:
    """'; <file> <rms> against <rms of the least squares> <unit>, ...' for the files the model written
    (REPORT.json's ``final.written``) fits more than the excess ratio worse than the least squares
    (their ``worse``), and its held-out rms when it was measured; '' when neither."""
    out = [f"{name} {v['rms']:.3g} against {v['rms_least_squares']:.3g} {v['unit']}"
           for name, v in (written.get("by_file") or {}).items() if v["worse"]]
    text = f"; {', '.join(out)}" if out else ""
    if written.get("heldout_rms_um") is not None:
        text += f"; held-out {written['heldout_rms_um']:.4g} um"
    return text


def seen_through_factor(lsq, penalised, s2: float) -> tuple:
    """(params, uncertainty) of the penalised fit ``penalised`` (a FittedModel) with the chosen
    terms' parameters it leaves undetermined, though the least squares ``lsq`` determines them, given
    the least squares' standard errors (its covariance is at the noise floor: times ``s2``, the
    penalised posterior's residual variance).

    Such a parameter is a factor seen only through another chosen factor (a feed-dependent Abbe
    term's moving rotation centre multiplies the fitted angular error): judged at the base's start,
    where that angle is zero, it moves no reading, and the penalised fit holds it at the selection's
    value. There the least squares, linearised at the selection's values, measures it (on a
    double turntable's campaign a centre moving 79.96 +- 0.27 mm per m/min, the truth's 80). Its
    variance is that of the least squares, its covariance with the rest and with the files' set-ups
    left out (the penalised fit did not move it), and the combinations the data leave open no longer
    hold it: alone it lies in their span, so each of them less its part is still one of them."""
    u = penalised.uncertainty
    if u is None or lsq.params.std_errors is None:
        return penalised.params, u
    names = list(u["names"])
    se = penalised.params.std_errors
    N = np.asarray(u["undetermined"], dtype=float).reshape(len(names), -1)
    Q = np.linalg.svd(N, full_matrices=False)[0][:, :np.linalg.matrix_rank(N)] if N.size else N
    # alone, the parameter moves no reading (it lies in the span the data leave open): not a part
    # of a combination the data cannot tell apart (two terms' parameters that act alike on these
    # readings), which the least squares on its own subspace may call determined
    alone = 1.0 - np.sum(Q ** 2, axis=1) < 1e-6
    specs = penalised.params.specs
    take = [n for k, n in enumerate(names) if alone[k] and not specs[penalised.params.index(n)].base
            and np.isfinite(lsq.params.std_errors[lsq.params.index(n)])
            and (se is None or not np.isfinite(se[penalised.params.index(n)]))]
    if not take:
        return penalised.params, u
    params = penalised.params.copy()
    std = params.std_errors if params.std_errors is not None else np.full(len(params), np.nan)
    C = np.array(u["covariance"], dtype=float, copy=True)
    rows = [names.index(n) for n in take]
    for n, k in zip(take, rows):
        v = float(lsq.params.std_errors[lsq.params.index(n)]) ** 2 * s2
        C[k, :], C[:, k] = 0.0, 0.0
        C[k, k] = v
        std[params.index(n)] = np.sqrt(v)
    params.std_errors = std
    out = {**u, "covariance": C, "undetermined": _less_rows(N, rows)}
    if "setup" in u:
        # nor with the fitted files' set-ups (predict's covariance of a fitted file's readings)
        cross = np.array(u["setup"]["cross"], dtype=float, copy=True)
        cross[:, rows] = 0.0
        out["setup"] = {**u["setup"], "cross": cross}
    return params, out


def _less_rows(N: np.ndarray, rows: list) -> np.ndarray:
    """The directions ``N`` (columns) less their part in ``rows``, each of which alone lies in their
    span: a direction less that part is still one the data leave open. The columns that had none
    are kept as they are (so that what the report counts as open does not change with the basis);
    of the others, those that add a direction to them, in turn: the span is one dimension less per
    row, and two directions left parallel let the model file's split of its values along them
    (FittedModel.undetermined_values) take 0.69 um of a laser-measured positioning profile."""
    had = np.abs(N[rows]).max(axis=0, initial=0.0) > 0
    N = N.copy()
    N[rows] = 0.0
    kept, basis = [], np.zeros((N.shape[0], 0))
    for j in list(np.flatnonzero(~had)) + list(np.flatnonzero(had)):
        n = np.linalg.norm(N[:, j])
        if not n > 0:
            continue
        r = N[:, j] / n - basis @ (basis.T @ (N[:, j] / n))
        if np.linalg.norm(r) > 1e-6:
            kept.append(j)
            basis = np.column_stack([basis, r / np.linalg.norm(r)])
    return N[:, sorted(kept)]

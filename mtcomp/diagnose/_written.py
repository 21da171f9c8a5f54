"""The model diagnose writes: the penalised refit of the selected model, or the selection's own least
squares where that predicts held-out readings clearly better.

The penalised refit (:mod:`._penalised`) gives a profile between measured targets the smoothest curve
through them and a standard error that says the curve rests on the penalty there; the selection's
least squares (one function a target) claims more between targets than it knows. Held-out readings
sit where readings were taken, so they cannot see that; they can see a penalty that smooths what the
data hold (REML weights that flatten a rotary axis's error motions, a reversal drawn toward a line
while the runs repeat each target's own). Both are held out on the same folds; the refit is written
unless its held-out sum of squares exceeds the selection's by more than two standard deviations of
the chi-square scatter two equally good fits show in the selection's determined directions
(:func:`choose`), and the report gives both figures and the choice (``final.written``).
"""
from __future__ import annotations

import numpy as np

from ..models.chain import ErrorModel
from ..models.model_file import FittedModel
from ..models.params import ParameterSet
from ._linalg import Design, rms
from ._report import written_line
from .result import UNIT_KEYS, _r

#: the penalised refit is written unless the selection's least squares predicts held-out readings
#: better by more than this many standard deviations of the chi-square scatter of two alike fits
#: (:func:`choose`)
CHOICE_Z = 2.0


#: the unit whose held-out rms the selection follows: the first of these the data hold
MAIN_UNITS = ("um", "urad", "um/min")


def heldout_unit(st) -> str:
    """um, else urad (angular laser runs alone), else um/min (velocities alone)."""
    return next((u for u in MAIN_UNITS if np.any(st.unit == u)), MAIN_UNITS[0])


def metrics(st, fit, n_params: int) -> dict:
    """The report's figures of a fit (``resid``, ``cv_resid``: (n,) um/urad/um/min; ``rank``)."""
    um = st.unit == "um"
    out = {"n_params": int(n_params), "n_determined": int(fit.rank) - len(st.nuisance_names),
           "n_nuisance": len(st.nuisance_names),
           "rms_um": _r(rms(fit.resid[um])) if um.any() else None,
           "heldout_rms_um": _r(rms(fit.cv_resid[um])) if um.any() else None}
    for unit in ("urad", "um/min"):
        sel = st.unit == unit
        if sel.any():
            out[f"rms_{UNIT_KEYS[unit]}"] = _r(rms(fit.resid[sel]))
            out[f"heldout_rms_{UNIT_KEYS[unit]}"] = _r(rms(fit.cv_resid[sel]))
    return out


def heldout_sse(w: np.ndarray, cv: np.ndarray) -> float:
    """The held-out sum of squares in noise variances: w (n,) 1 / noise of each reading, cv (n,) its
    held-out residual (NaN where none)."""
    ok = np.isfinite(cv) & np.isfinite(w)
    return float(np.sum((w[ok] * cv[ok]) ** 2))


def choose(st, design: Design, current, penalised) -> dict:
    """The report's ``final.written``: which model is written (``model``: ``penalised`` or
    ``least_squares``), both fits' held-out rms in the held-out unit (``heldout_rms_penalised_um``,
    ``heldout_rms_least_squares_um``, or ``_urad``/``_um_min``), the penalised fit's excess of
    held-out sum of squares over the selection's and the slack it is allowed, in noise variances.
    ``current``: the selection's final fit (:class:`._linalg.FitResult`), ``penalised``:
    :class:`._penalised.PenalisedFit`.

    Two fits that predict alike differ in held-out sum of squares by about a chi-square's scatter
    in the directions where they differ: the penalty can shrink each of the selection's determined
    directions (``current.rank``, k), so the slack is 2 sd of a chi-square on k degrees of freedom,
    ``2 sqrt(2 k)``, as a finer base is judged (:func:`._diagnose.diagnose`). The penalised fit is
    written unless its excess is beyond that."""
    unit = heldout_unit(st)
    sel = st.unit == unit
    excess = heldout_sse(design.w, penalised.cv_resid) - heldout_sse(design.w, current.cv_resid)
    slack = CHOICE_Z * np.sqrt(2.0 * max(int(current.rank), 1))
    key = UNIT_KEYS[unit]
    return {"model": "least_squares" if excess > slack else "penalised",
            f"heldout_rms_penalised_{key}": _r(rms(penalised.cv_resid[sel])),
            f"heldout_rms_least_squares_{key}": _r(rms(current.cv_resid[sel])),
            "heldout_excess_noise_variances": _r(excess), "heldout_slack_noise_variances": _r(slack)}


def least_squares_model(st, design: Design, chosen: list, fit) -> FittedModel:
    """The selection's own least-squares model (base and chosen terms at the selection's final
    values ``fit.theta``) with its covariance: that of the determined directions (noise variance 1
    after weighting), and the combinations the data do not see, each scaled to 1 um of tool-tip
    error over the travel, by identify's rank rule (:mod:`._covariance`)."""
    from ._covariance import _cov_diag, _uncertainty
    terms = _terms(chosen)
    model = ErrorModel(st.machine, terms)
    params = ParameterSet(model.param_specs)
    base = [n for n, s in zip(st.probe.param_names, st.probe.param_specs) if s.base]
    m = design.A_original.shape[1]
    std = np.full(model.n_params, np.nan)
    extra = np.hstack([c.columns for c in chosen]) if chosen else np.zeros((design.n, 0))
    cov_diag = _cov_diag(design, extra)
    names, theta_idx = list(base), list(range(len(base)))
    for i, name in enumerate(base):
        params[name] = fit.theta[i]
        std[params.index(name)] = cov_diag[i]
    k = m
    for c in chosen:
        for j, name in enumerate(c.params):
            if name in params:
                params[name] = fit.theta[k + j]
                std[params.index(name)] = cov_diag[k + j]
                if name not in names:
                    names.append(name)
                    theta_idx.append(k + j)
        k += c.columns.shape[1]
    params.std_errors = np.sqrt(np.where(np.isfinite(std), std, np.nan))
    info = {"fitted_by": "mtcomp diagnose",
            "nuisance": {n: float(v) for n, v in zip(st.nuisance_names, fit.theta[len(base):m])}}
    machine_cols = np.r_[np.ones(len(base), dtype=bool), np.zeros(m - len(base), dtype=bool)]
    uncertainty = _uncertainty(model, design, extra, names, theta_idx, machine_cols)
    return FittedModel(model, params, {}, info, uncertainty=uncertainty)


def _terms(chosen: list) -> list:
    terms = []
    for c in chosen:
        for t in c.terms:
            if t.key() not in {x.key() for x in terms}:
                terms.append(t)
    return terms


def penalised_model(st, design: Design, chosen: list, starts: tuple, folds, free_knots: set,
                    selected_resid: np.ndarray):
    """(FittedModel, PenalisedFit, axes whose knots were refined): the base and the chosen terms
    fitted again with the roughness penalty (:mod:`._penalised`), on knots finer than the data's
    spacing where the data read an axis at few positions (of the axes ``free_knots``, whose knots
    the data choose), from the first of ``starts`` (name -> value dicts) and, when that fit does not
    converge or fits far worse than the selection (``selected_resid``, (n,) its final residuals),
    from the others too (:func:`._penalised.penalised_fit`)."""
    from ._linalg import RCOND
    from ._penalised import fine_machine, penalised_fit
    machine = fine_machine(st.machine, st.datasets, len(st), free_knots)
    refined = {a.name for a, b in zip(machine.axes, st.machine.axes) if a != b}
    model = ErrorModel(machine, _terms(chosen))
    # the start model's values of what the finer knots keep (a spline coefficient of a refined axis
    # is another function's)
    specs = dict(zip(model.param_names, model.param_specs))
    starts = [{n: v for n, v in values.items()
               if n in specs and not (_is_spline(n) and refined & set(specs[n].group.split(":")))}
              for values in starts]
    fit = penalised_fit(st, design.w, model, starts, folds, RCOND, selected_resid)
    res = fit.result
    info = {"fitted_by": "mtcomp diagnose",
            "nuisance": {n: float(v) for n, v in zip(res.unknown_names[int(res.free.sum()):],
                                                     res.nuisance_values)},
            "smoothing": res.smoothing.to_dict() if res.smoothing is not None else None}
    fitted = res.fitted_model
    return FittedModel(model, fitted.params, {}, info, uncertainty=fitted.uncertainty), fit, refined


def final_model(st, design: Design, chosen: list, current, starts: tuple, folds, free_knots: set, say):
    """(FittedModel, the report's ``final`` figures): the penalised refit (:func:`penalised_model`)
    or, where it predicts held-out readings clearly worse (:func:`choose`), the selection's least
    squares (``current``, its final fit: :func:`least_squares_model`); the figures are the written
    model's, and ``written`` says which it is, with both held-out figures."""
    model, fit, refined = penalised_model(st, design, chosen, starts, folds, free_knots, current.resid)
    written = choose(st, design, current, fit)
    if written["model"] == "penalised":
        res = fit.result
        out = metrics(st, fit, model.model.n_params)
        out["edf"] = _r(res.smoothing.edf - len(st.nuisance_names)) if res.smoothing is not None else None
    else:
        model = least_squares_model(st, design, chosen, current)
        out = metrics(st, current, int(st.probe.base_mask.sum()) + sum(c.columns.shape[1] for c in chosen))
    out["written"] = written
    say(f"final model: {written_line(written)}"
        + (f" (knots refined along {', '.join(sorted(refined))})" if refined else ""))
    feats = sorted({f for c in chosen for f in c.info.get("features", [])})
    if feats:
        model.info["drift_features"] = feats
    return model, out


def selected_values(st, design: Design, chosen: list, fit) -> tuple[dict, dict]:
    """({name: value, internal units} of the selection's final fit, the base's parameters and the
    chosen terms'; the same of the chosen terms alone). The penalised fit starts from the second
    (the base where identify starts it, a term's values where the selection found them: an Abbe
    error's moving centre multiplies its angle and shows the data nothing at zero); the selection's
    values of combinations that the finer knots and the penalty leave open (a squareness of 680
    urad traded against a straightness's slope) would stay where they start, and their products
    with the other errors led Gauss-Newton astray. The first is the other start, for a fit that
    needs the base's values to get anywhere (a rotary axis's error motions about a location 10 mm
    off its nominal line)."""
    base = [n for n, s in zip(st.probe.param_names, st.probe.param_specs) if s.base]
    out = {name: float(fit.theta[i]) for i, name in enumerate(base)}
    terms = {}
    k = design.A_original.shape[1]
    for c in chosen:
        for j, name in enumerate(c.params):
            if name not in out:
                terms.setdefault(name, float(fit.theta[k + j]))
        k += c.columns.shape[1]
    return {**out, **terms}, terms


def _is_spline(name: str) -> bool:
    """A spline coefficient (``EXX_b3``, ``BL_X_b3``): its function depends on the axis's knots."""
    tail = name.rsplit("_", 1)[-1]
    return tail[:1] == "b" and tail[1:].isdigit()

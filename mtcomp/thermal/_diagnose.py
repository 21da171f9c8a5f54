"""`diagnose` of a thermal file: the drift model that predicts the future, as a report and a model.

The chosen drift (``_fit.fit_thermal``) becomes model terms that give each channel's reading itself
(``absolute``): a :class:`~mtcomp.models.ThermalDrift` on the tool tip for the channels that read a
machine axis (channels named x, y, z, or mapped by ``channel_axes``), a
:class:`~mtcomp.models.ChannelDrift` for the others. Temperatures enter as read (``temp_<s>``,
degC); their means over the file become the model's context defaults (a program compensated
without temperatures gets the mean drift of the file).
"""
from __future__ import annotations

import re
import time
from pathlib import Path

import numpy as np
from scipy.stats import f as f_dist

from ..errors import InputError
from ..models.chain import ErrorModel
from ..models.model_file import FittedModel
from ..models.params import ParameterSet
from ..models.terms import ChannelDrift, ThermalDrift
from ._fit import (_rms, feature_matrix, fit_ridge, fit_thermal, forward_folds, forward_sse, thermal_arrays,
                   usable_temperatures)


#: the column of a thermal file that names the machine axis channel ``disp_<name>_um`` reads
AXIS_COLUMN = re.compile(r"^axis_(.+)$")


def declared_channel_axes(data) -> dict:
    """Channel name -> axis letter (X, Y, Z) the thermal file ``data`` declares in its columns
    ``axis_<name>`` (docs/thermal.md): every cell X, Y or Z (any case) or blank, the given ones alike.
    A column whose every cell is blank declares nothing. InputError naming the row otherwise, or for
    a column that names no channel of the file."""
    out = {}
    names = [h.strip().lower() for h in data.header]
    for j, name in enumerate(names):
        m = AXIS_COLUMN.match(name)
        if not m:
            continue
        ch = m.group(1)
        if ch not in data.channels:
            data.fail(f"column {name} names channel {ch!r}, but the file's channels are "
                      f"{', '.join(data.channels)} (disp_<name>_um)")
        axis = None
        for i, cells in enumerate(data.rows):
            cell = cells[j].strip().upper()
            if not cell:
                continue
            if cell not in ("X", "Y", "Z"):
                data.fail(f"column {name}: {cells[j].strip()!r} is not a machine axis (X, Y or Z)", i)
            if axis is not None and cell != axis:
                data.fail(f"column {name}: {cell} where the rows before say {axis} (a channel reads "
                          "one axis for the whole record)", i)
            axis = cell
        if axis is not None:
            out[ch] = axis
    return out


def channel_axes_for(channels, channel_axes: dict | None, path=None, declared: dict | None = None) -> dict:
    """Channel name -> machine axis letter (X, Y, Z) it reads: channels x, y, z, those the file
    declares (``declared``, :func:`declared_channel_axes`) and ``channel_axes`` (``--channel-axis``).
    InputError for an unknown channel, an axis other than X, Y, Z, a flag that contradicts the file
    or two channels on one axis."""
    out = {ch: ch.upper() for ch in channels if ch in ("x", "y", "z")}
    for ch, axis in (declared or {}).items():
        if ch in out and out[ch] != axis:
            raise InputError(f"column axis_{ch} says channel {ch} reads {axis}, but a channel named "
                             f"{ch} reads {out[ch]}", path)
        out[ch] = axis
    for ch, axis in (channel_axes or {}).items():
        if ch not in channels:
            raise InputError(f"--channel-axis names channel {ch!r}, but the file has "
                             f"{', '.join(channels)}", path)
        if axis.upper() not in ("X", "Y", "Z"):
            raise InputError(f"--channel-axis {ch}={axis}: the axis must be X, Y or Z", path)
        if ch in out and out[ch] != axis.upper():
            said = f"column axis_{ch}" if ch in (declared or {}) else f"the channel's name {ch}"
            raise InputError(f"--channel-axis {ch}={axis.upper()} contradicts {said}, which says "
                             f"{out[ch]}", path)
        out[ch] = axis.upper()
    seen = {}
    for ch, axis in out.items():
        if axis in seen:
            raise InputError(f"channels {seen[axis]} and {ch} both read axis {axis}", path)
        seen[axis] = ch
    return out


def context_ranges(fit) -> dict:
    """The thermal state the record spans, as MODEL.json's ``info["context_ranges"]``: ``temp_<s>``
    -> [lowest, highest] reading (degC) of each sensor the drift reads, and ``spindle_rpm`` ->
    [lowest, highest] speed (rev/min) when it reads spindle heat. compensate refuses a state outside
    them unless told to extrapolate (:func:`mtcomp.thermal.context.thermal_context`)."""
    out = {f"temp_{s}": [lo, hi] for s, (lo, hi) in fit.temperature_ranges.items()}
    rpm = fit.spindle_rpm[np.isfinite(fit.spindle_rpm)]
    if any(f.startswith("spindle_") for f in fit.chosen.features) and rpm.size:
        out["spindle_rpm"] = [float(rpm.min()), float(rpm.max())]
    return out


def drift_uncertainty(fit, axes: dict) -> dict | None:
    """The model file's ``uncertainty`` of a drift model (as identify writes it): the covariance of
    every channel's coefficients and intercept for forward predictions (``ThermalFit.covariance``:
    the posterior for residuals correlated in time, the model error on the intercept; um -> mm;
    channels independent), nothing undetermined; ``model_error`` the sd of that model error (mm) by
    intercept's name."""
    if fit.covariance is None:
        return None
    feats = tuple(fit.chosen.features)
    names, blocks = [], []
    for j, ch in enumerate(fit.channels):
        name = axes.get(ch, ch)
        names += [f"TD_{name}_{f}" for f in feats] + [f"TD_{name}_zero"]
        blocks.append(fit.covariance[j] * 1e-6)
    import scipy.linalg
    # the model error on each intercept, kept apart too: a correction referenced to a known state
    # (the record's first reading) differences the intercept away and adds it once (at_datum)
    error = {f"TD_{axes.get(ch, ch)}_zero": float(e) * 1e-3
             for ch, e in zip(fit.channels, fit.chosen.forward_rms_um)}
    return {"names": tuple(names), "covariance": scipy.linalg.block_diag(*blocks),
            "undetermined": np.zeros((len(names), 0)), "model_error": error}


def drift_terms_and_values(fit, axes: dict):
    """(terms, {parameter name: internal value}) of a :class:`ThermalFit` (um -> mm)."""
    c = fit.chosen
    feats = tuple(c.features)
    values = {}
    terms = []
    tip = [ch for ch in fit.channels if ch in axes]
    other = [ch for ch in fit.channels if ch not in axes]
    if tip:
        dirs = "".join(axes[ch] for ch in tip)
        terms.append(ThermalDrift(c.driver, feats, dirs, absolute=True, channels=tuple(tip)))
    if other:
        terms.append(ChannelDrift(c.driver, feats, tuple(other), absolute=True))
    for j, ch in enumerate(fit.channels):
        name = axes.get(ch, ch)
        for i, f in enumerate(feats):
            values[f"TD_{name}_{f}"] = fit.ridge.coef[i, j] * 1e-3
        values[f"TD_{name}_zero"] = fit.ridge.intercept[j] * 1e-3
    return terms, values


def diagnose_thermal(machine, data, channel_axes: dict | None = None, progress=None):
    """Diagnosis (mtcomp.diagnose) of one thermal file: the drift model chosen by forward-chaining
    validation, its report (the keys of docs/diagnose.md) and the model (base model at zero plus the drift terms)."""
    from ..diagnose._analysis import Noise
    from ..diagnose.result import Diagnosis, Finding, _r
    t0 = time.perf_counter()
    say = progress or (lambda s: None)
    axes = channel_axes_for(list(data.channels), channel_axes, data.path, declared_channel_axes(data))
    if not axes:
        say(f"note: no channel of {Path(str(data.path)).name} reads a machine axis (channels "
            f"{', '.join(data.channels)}): its drift is modelled per channel and compensate cannot "
            "correct it; say which axis a channel reads with --channel-axis NAME=AXIS or a column "
            "axis_<name>")
    fit = fit_thermal(data)
    c = fit.chosen
    # the table itself is the summary's (printed once, at the end)
    say(f"{len(fit.scores)} drift models compared forward in time on {len(fit.channels)} channel(s); "
        f"chosen: {c.label}")
    none = next(s for s in fit.scores if s.driver == "none")
    n_obs = fit.measured_um.size
    noise = {"um": Noise("um", fit.noise_um, max(n_obs - len(fit.channels), 1), "robust", 0)}
    base = {"n_params": 0, "n_determined": 0, "n_nuisance": len(fit.channels),
            "rms_um": _r(_rms(fit.measured_um - fit.measured_um.mean(axis=0))),
            "heldout_rms_um": _r(_rms(none.forward_rms_um))}
    k = len(c.features) + 1
    final = {"n_params": k * len(fit.channels), "n_determined": k * len(fit.channels), "n_nuisance": 0,
             "rms_um": _r(_rms(fit.fitted_um - fit.measured_um)),
             "heldout_rms_um": _r(_rms(c.forward_rms_um))}
    findings = [_drift_finding(fit, axes)] if c.driver != "none" else []
    ratio = _rms(c.forward_rms_um) / fit.noise_um if fit.noise_um > 0 else np.inf
    verdict = "none" if c.driver == "none" and ratio <= 1.5 else ("explained" if ratio <= 1.5 else "unexplained")
    if verdict == "unexplained":
        runs = np.unique(data.context.run[data.context.run >= 0])
        p = float(f_dist.sf(ratio ** 2, n_obs, max(n_obs - len(fit.channels), 1)))
        findings.append(Finding("unexplained", "", {"where": "the drift predicted forward in time",
                                                    "correlates_with": ["time"],
                                                    "runs": [int(r) for r in runs], "p_value": p},
                                f"the forward-validated rms {_rms(c.forward_rms_um):.3g} um is "
                                f"{ratio:.3g} times the noise of one reading", _rms(c.forward_rms_um),
                                _rms(c.forward_rms_um)))
    fitted = _thermal_model(machine, fit, axes)
    how = (f"forward-chained in time: the readings cut into {fit.n_folds + 1} blocks, each of the last "
           f"{fit.n_folds} predicted from the blocks before it")
    reference = {"linear_regression_all_temperatures": _temperature_regression(data, fit)}
    diag = Diagnosis(verdict, noise, base, findings, final, fitted, how, n_obs, reference=reference)
    diag.thermal = fit
    diag.seconds = time.perf_counter() - t0
    fitted.info["thermal_record"] = str(data.path)
    fitted.info["diagnose"] = diag.to_dict()
    return diag


def _drift_finding(fit, axes: dict):
    """The thermal_drift finding of the chosen drift model of ``fit`` (channel -> axis ``axes``)."""
    from ..diagnose.result import Finding, _r
    c = fit.chosen
    none = next(s for s in fit.scores if s.driver == "none")
    params = {"driver": c.driver, "drivers": c.drivers, "features": list(c.features),
              "time_constants_s": c.time_constants_s, "ridge_penalty": c.penalty,
              "channels": {ch: axes.get(ch, "") for ch in fit.channels},
              "max_drift_um": {ch: _r(v, 3) for ch, v in zip(fit.channels, fit.max_drift_um)},
              "forward_rms_um": {ch: _r(v, 3) for ch, v in zip(fit.channels, c.forward_rms_um)},
              "temperatures_left_out": fit.left_out}
    # the keys every drift finding has (docs/diagnose.md): the temperatures it uses, the channel
    # that drifts most (and its tip direction, when it reads one) and that channel's drift
    params["temperatures"] = [f[len("temp_"):] for f in c.features if f.startswith("temp_")]
    worst = int(np.argmax(fit.max_drift_um))
    params["channel"] = fit.channels[worst]
    if fit.channels[worst] in axes:
        params["direction"] = axes[fit.channels[worst]]
    params["drift_range_um"] = _r(float(fit.max_drift_um[worst]), 3)
    # every tip direction the drift term holds (and corrects), not only the one that drifts most
    held = [(axes[ch], v) for ch, v in zip(fit.channels, fit.max_drift_um) if ch in axes]
    if held:
        params["directions"] = [a for a, _ in held]
        params["drift_range_by_direction_um"] = {a: _r(float(v), 3) for a, v in held}
    runner_up = sorted((s for s in fit.scores if s is not c), key=lambda s: s.total_sse)[0]
    evidence = (f"predicting each next block of the record from the readings before it, "
                f"{c.label} leaves {_rms(c.forward_rms_um):.3g} um rms against "
                f"{_rms(none.forward_rms_um):.3g} um without a drift model and "
                f"{_rms(runner_up.forward_rms_um):.3g} um for the next best ({runner_up.label})")
    axis = params.get("direction", "")
    return Finding("thermal_drift", axis, params, evidence + _compensable_words(fit),
                   _rms(none.forward_rms_um), _rms(c.forward_rms_um))


def _compensable_words(fit) -> str:
    """What the choice means for compensate: a drift in time it cannot follow, and how its rival that
    compensate can follow compares (:func:`._fit.alike_z`), or that such a rival predicted the record
    alike and was kept for that."""
    from ._fit import ALIKE_Z, COMPENSABLE, alike, alike_z, best_of
    c = fit.chosen
    t, u = best_of(fit.scores, ("time",)), best_of(fit.scores, COMPENSABLE)
    if c.driver in COMPENSABLE and t is not None and alike(t, c):
        return (f"; {t.label} predicts it alike ({_rms(t.forward_rms_um):.3g} um: the difference of "
                f"their forward sums of squares is {alike_z(t, c):+.2g} standard errors, within "
                f"{ALIKE_Z:g}, Diebold and Mariano 1995): the drift on {c.label} is kept, which "
                "compensate can follow, where a time since the record began is nothing it is told")
    if c.driver != "time":
        return ""
    words = ("; compensate cannot use a drift in time (it is told temperatures and a spindle speed, "
             "not when in the record a program runs)")
    if u is None:
        return words + (": a record with temperature sensors near the heat sources gives a model it "
                        "can use")
    return (words + f": {u.label}, which it could use, predicts the record {alike_z(u, c):.2g} "
            f"standard errors worse ({_rms(u.forward_rms_um):.3g} um; Diebold and Mariano 1995); "
            "sensors nearer the heat sources, or a longer record, may give one that predicts as well")


def _thermal_model(machine, fit, axes: dict) -> FittedModel:
    """The fitted model of a thermal diagnosis: the base model at zero plus the chosen drift terms."""
    c = fit.chosen
    terms, values = drift_terms_and_values(fit, axes) if c.driver != "none" else ([], {})
    model = ErrorModel(machine, terms)
    params = ParameterSet(model.param_specs)
    for name, v in values.items():
        params[name] = v
    defaults = {f"temp_{s}": v for s, v in fit.temperature_means.items()}
    info = {"fitted_by": "mtcomp diagnose (thermal drift)", "drift_features": list(c.features),
            "time_constants_s": c.time_constants_s,
            "context_ranges": context_ranges(fit) if c.driver != "none" else {}}
    if c.driver != "none":
        # the state a correction is referenced to by default: the drift since the record's first
        # reading (its absolute value holds the probe's set-up zero, which no data determine)
        info["thermal_first_reading"] = dict(fit.first_reading)
    # support {}: the record moved no axis, and the drift model has no error that varies along one
    # (no region bounds where it applies)
    fitted = FittedModel(model, params, defaults, info, support={},
                         uncertainty=drift_uncertainty(fit, axes) if c.driver != "none" else None)
    return fitted


def _temperature_regression(data, fit) -> dict | None:
    """Plain least squares on every temperature, scored like the candidates (a reference)."""
    order, _, Y = thermal_arrays(data)
    ctx = data.context.subset(order)
    temps = usable_temperatures(ctx)
    if not temps:
        return None
    X = feature_matrix(ctx, [f"temp_{s}" for s in temps])
    folds = forward_folds(len(Y), fit.n_folds)
    n_test = sum(te.stop - te.start for _, te in folds)
    r = fit_ridge(X, Y, 0.0).predict(X) - Y
    return {"n_params": (len(temps) + 1) * Y.shape[1], "rms_um": round(_rms(r), 4),
            "heldout_rms_um": round(_rms(np.sqrt(forward_sse(X, Y, 0.0, folds) / n_test)), 4),
            "temperatures": temps}

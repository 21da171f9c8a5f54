"""Predictions of a fitted model for the rows of any measurement file, with their standard errors
(what ``mtcomp predict`` writes)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..machine import Machine
from ..measurement.files import MeasurementSet
from ..measurement.readings import MeasurementModel
from ..models.model_file import FittedModel
from .problem import KNOWN_SETUP_KINDS, _unique_tags, build_measurement_models


@dataclass
class Prediction:
    """What :func:`predict_readings` returns.

    columns : 'pred_<column>' -> (n_rows,) predicted readings, FILE units, and 'pred_<column>_sd'
        -> its standard error (NaN where the data behind the model do not determine it).
    setup_known : True when the file was part of the fit and its fitted set-up (laser zero, tracker
        frame, bar calibration) is used; False: the set-up is unknown and taken as zero.
    notes : lines for the user.
    """

    columns: dict
    setup_known: bool
    notes: list


def stored_setup(fitted: FittedModel, mm: MeasurementModel) -> tuple[np.ndarray, bool]:
    """The fitted set-up (nuisance) of a file that was part of the fit, recognised by its tag (file
    stem), internal units; (zeros, False) when the model has none for it."""
    stored = fitted.info.get("identify", {}).get("nuisance", {})
    internal = fitted.info.get("nuisance", {})        # mtcomp diagnose: internal units
    values = np.zeros(mm.n_nuisance)
    for i, spec in enumerate(mm.nuisance_specs):
        entry = stored.get(spec.name)
        if isinstance(entry, dict) and "value" in entry:
            values[i] = float(entry["value"]) / spec.to_file
        elif isinstance(internal.get(spec.name), (int, float)):
            values[i] = float(internal[spec.name])
        else:
            return np.zeros(mm.n_nuisance), mm.n_nuisance == 0
    return values, True


def predict_readings(fitted: FittedModel, data: MeasurementSet, machine: Machine | None = None) -> Prediction:
    """Predict every row of a measurement file with a fitted model: the same measurement model,
    context defaults and set-up that :func:`identify` used, so that a file that was fitted is
    reproduced exactly (its readings minus the prediction are the fit's residuals)."""
    tag = _unique_tags([data])[0]
    known = [tag] if tag in fitted.info.get("known_setup", ()) and data.kind in KNOWN_SETUP_KINDS else []
    mm = build_measurement_models(fitted.model, [data], fitted.context_defaults, machine=machine,
                                  known_setup=known)[0]
    nuisance, known = stored_setup(fitted, mm)
    p = fitted.params.values
    columns = mm.predict_columns(p, nuisance)
    jac = mm.column_jacobians(p)
    notes = []
    for name in list(columns):
        if name in jac:
            columns[f"{name}_sd"] = fitted.prediction_std(np.nan_to_num(jac[name]))
            columns[f"{name}_sd"][~np.isfinite(columns[name])] = np.nan
        else:
            columns[f"{name}_sd"] = np.full(len(data), np.nan)
    if fitted.uncertainty is None:
        notes.append("the model carries no uncertainty (mtcomp identify and diagnose write one; a "
                     "model file of an older mtcomp may not): the _sd columns are blank")
    if not known:
        notes.append(f"{mm.tag} was not part of the fit: its set-up ({', '.join(s.name.split(':', 1)[1] for s in mm.nuisance_specs)}) "
                     "is unknown and taken as zero; compare readings up to that set-up")
    return Prediction(columns, known, notes)

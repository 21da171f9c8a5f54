"""Predictions of a fitted model for the rows of any measurement file, with their standard errors
(what ``mtcomp predict`` writes), blank where the model's data do not determine them.

A standard error comes from the model's covariance, which includes the variance the data leave
along the directions the fit held because the data fix them only weakly (the model file's
``uncertainty.held``, with ``held_sd_um``): such a prediction gets that variance, the square of its
change along each held direction times the square of the direction's standard error. That variance
is on the assumption that the components no laser file names are zero (what only splits readings
between a named component and one of those has none). Only the directions the data do not
determine at all (``uncertainty.undetermined``) blank a prediction."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..machine import Machine
from ..measurement.files import MeasurementSet
from ..measurement.readings import MeasurementModel
from ..models.model_file import UNDETERMINED_UM, FittedModel
from ._linalg import one_blas_thread
from ..models.assumed import model_note
from .problem import KNOWN_SETUP_KINDS, unique_tags, build_measurement_models


@dataclass
class Undetermined:
    """What the data behind a model left undetermined, to blank predictions that rest on it, and the
    covariance that gives the others their standard errors.

    index : (k,) positions in the model's parameters of the fitted ones (the covariance's order).
    directions : (k, m) directions of those parameters the data did not determine (the model
        file's ``uncertainty.undetermined``), internal units, each scaled to 1 um rms tool-tip error
        over the machine's travel. None: the model carries no uncertainty. The directions the fit
        held because the data fix them only weakly are not among them: their variance is in the
        covariance (``factor``).
    to_file : (k,) file unit per internal unit of each fitted parameter.
    largest_sd : the largest standard error of any combination of unit size of the fitted
        parameters in file units (um, urad): below :attr:`ROUNDING` of it a standard error counts
        as none at all (parameters held with no variance).
    """

    index: np.ndarray | None
    directions: np.ndarray | None
    to_file: np.ndarray | None = None
    largest_sd: float = 0.0
    #: (indices, F) with F F^T the covariance (:meth:`FittedModel.covariance_factor`), computed once
    factor: tuple | None = None
    #: (k,) each fitted parameter's standard error (internal units; the factor's order)
    parameter_sd: np.ndarray | None = None

    #: a prediction whose standard error is below this share of what its own parameters' standard
    #: errors could give it (all moving together) has none: the fit held what it rests on (a held
    #: combination has no variance at all, to rounding), it did not measure it
    NO_VARIANCE = 1e-9
    #: nor one below this share of the model's largest standard error (per unit of its Jacobian):
    #: parameters held with no variance at all, to rounding. A model of the real ISO 230-2 run of
    #: X (ess_b02_x) predicts its own readings at 0.018 to 0.022 of it, the Y run (held) at 1e-26;
    #: a laser-measured positioning profile beside a spline function of 2e7 um, 1.3e-9
    ROUNDING = 1e-13

    @classmethod
    def of(cls, fitted: FittedModel) -> "Undetermined":
        u = fitted.uncertainty
        if u is None:
            return cls(None, None)
        idx = np.array([fitted.params.index(n) for n in u["names"]], dtype=int)
        f = np.array([fitted.params.specs[i].to_file for i in idx])
        factor = fitted.covariance_factor()
        scaled = factor[1] * f[:, None]          # the same parameters, in the same order
        with one_blas_thread():
            top = float(np.linalg.norm(scaled, 2)) if scaled.size else 0.0
        # (no parameter free: no direction left open either)
        undetermined = np.asarray(u["undetermined"], dtype=float).reshape(idx.size, -1) if idx.size \
            else np.zeros((0, 0))
        return cls(idx, undetermined, f, top, factor, np.linalg.norm(factor[1], axis=1))

    def std(self, J: np.ndarray, setup: np.ndarray | None = None,
            J_first: np.ndarray | None = None) -> np.ndarray:
        """(n,) standard error of n predictions whose Jacobian with respect to the model's parameters
        is J (n, n_params; file units per internal unit), from the model's covariance; NaN where the
        data behind the model do not determine a prediction (:meth:`assess`), or where the model
        carries no uncertainty."""
        return self.assess(J, setup, J_first)[0]

    def assess(self, J: np.ndarray, setup: np.ndarray | None = None,
               J_first: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(sd (n,), unknown (n,) bool) of n predictions whose Jacobian is J (:meth:`std`).

        sd is NaN where a prediction moves by more than 0.01 (um, urad) along an undetermined
        direction (judged with the Jacobian ``J_first`` when given: at zero errors, see
        :func:`predict_readings`), or where it is unknown. unknown: the prediction rests only on
        what the fit held (its standard error is no more than :attr:`NO_VARIANCE` of the model's
        largest while it moves with the fitted parameters): the model knows nothing of it, and the
        number it holds there (zero, or 1e-9) is no prediction. False everywhere for a model
        without uncertainty.

        setup : (n, k) the predictions' derivatives with respect to their file's set-up (a laser's
            zero, a tracker's frame). Readings are compared up to their set-up: what a set-up would
            absorb (a constant on every reading of a laser component) is taken out of each
            direction's effect before the 0.01 test; and the rows of one set-up parameter are
            unknown together when none of them with any content is known (the reading of a Y laser
            run at Y = 0, where a profile is zero by its reference, is no better known than the
            others); a row that shares no set-up parameter is judged on its own.
        """
        J = np.atleast_2d(np.asarray(J, dtype=float))
        if self.factor is None:
            return np.full(J.shape[0], np.nan), np.zeros(J.shape[0], dtype=bool)
        idx, F = self.factor
        sd = np.linalg.norm(J[:, idx] @ F, axis=1)
        open_ = np.zeros(J.shape[0], dtype=bool)
        if self.directions.shape[1]:
            moved = (J if J_first is None else np.atleast_2d(J_first))[:, self.index] @ self.directions
            if setup is not None and setup.shape[1]:
                rows = np.all(np.isfinite(setup), axis=1)
                D = setup[rows]
                moved[rows] -= D @ np.linalg.lstsq(D, moved[rows], rcond=None)[0]
            open_ |= np.abs(moved).max(axis=1) > UNDETERMINED_UM
        # what the prediction's own parameters could give it at most (all of them moving together,
        # each by its standard error): a held combination of them leaves only rounding of that; and
        # ROUNDING of the model's largest standard error (parameters held with no variance at all).
        # Judged against the largest alone, one spline coefficient of 2e7 um at the data's edge
        # blanked every range of a laser-measured profile
        content = np.any(J[:, self.index] != 0, axis=1)
        size = np.abs(J[:, idx]) @ self.parameter_sd
        largest = np.linalg.norm(J[:, self.index] / self.to_file, axis=1) * self.largest_sd
        held_only = content & (sd <= self.NO_VARIANCE * size + self.ROUNDING * largest)
        if setup is None or not setup.shape[1]:
            unknown = held_only
        else:
            acts = np.abs(np.nan_to_num(setup)) > 1e-6 * np.abs(np.nan_to_num(setup)).max(axis=0)
            unknown = held_only & ~acts.any(axis=1)
            for k in range(acts.shape[1]):
                group = acts[:, k]
                if np.any(group & content) and np.all(held_only[group & content]):
                    unknown |= group
        return np.where(open_ | unknown, np.nan, sd), unknown


@dataclass
class Prediction:
    """What :func:`predict_readings` returns.

    columns : 'pred_<column>' -> (n_rows,) predicted readings, FILE units, and 'pred_<column>_sd'
        -> its standard error: NaN where the prediction depends on what the data behind the model
        do not determine; both NaN where it rests only on that (the model knows nothing of it:
        :meth:`Undetermined.assess`).
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


def joint_covariance(fitted: FittedModel, mm: MeasurementModel):
    """(parameter indices, C) of a file the fit saw: C the joint covariance of the fitted
    parameters and the file's set-up (a laser component's zero and slope, a tracker's frame: the
    model file's ``uncertainty.setup``), for :func:`with_fitted_setup`; None where the model holds
    no such covariance of this file's set-up."""
    u = fitted.uncertainty
    s = None if u is None else u.get("setup")
    if s is None or not mm.n_nuisance:
        return None
    names = list(s["names"])
    if any(spec.name not in names for spec in mm.nuisance_specs):
        return None
    k = [names.index(spec.name) for spec in mm.nuisance_specs]
    idx = [fitted.params.index(n) for n in u["names"]]
    cross = np.asarray(s["cross"])[k]
    C = np.block([[np.nan_to_num(np.asarray(u["covariance"], dtype=float)), cross.T],
                  [cross, np.asarray(s["covariance"])[np.ix_(k, k)]]])
    return idx, C


def with_fitted_setup(joint, J: np.ndarray, D: np.ndarray | None, sd: np.ndarray) -> np.ndarray:
    """(n,) standard error of predictions of a file the fit saw, made with its fitted set-up: the
    set-up was fitted with the parameters, so the prediction moves with both, ``[J D] C [J D]^T``
    with ``joint`` = (indices, C) of :func:`joint_covariance`. What a set-up absorbs cancels: the
    other axes' errors at a laser run's fixed positions (in its zero), a squareness the fit held but
    the run's optic slope follows. ``sd`` (the parameters' share alone) where ``joint`` is None.

    J : (n, n_params) file units per internal unit; D : (n, k) the same per internal unit of the
    file's k set-up parameters (:func:`_setup_derivatives`)."""
    if joint is None or D is None or not D.shape[1]:
        return sd
    idx, C = joint
    A = np.hstack([np.nan_to_num(J)[:, idx], np.nan_to_num(D)])
    with one_blas_thread():
        return np.sqrt(np.clip(np.sum((A @ C) * A, axis=1), 0.0, None))


def _setup_derivatives(mm: MeasurementModel, p, nuisance, columns, step: float = 1e-6) -> dict:
    """'pred_<column>' -> (n, k): how each prediction moves with each of the file's k set-up
    (nuisance) parameters, per internal unit (forward differences of ``step`` mm or rad)."""
    out = {name: np.zeros((len(np.asarray(v)), mm.n_nuisance)) for name, v in columns.items()}
    for k in range(mm.n_nuisance):
        moved_setup = np.array(nuisance, dtype=float, copy=True)
        moved_setup[k] += step
        moved = mm.predict_columns(p, moved_setup)
        for name in out:
            out[name][:, k] = (np.asarray(moved[name]) - np.asarray(columns[name])) / step
    return out


def predict_readings(fitted: FittedModel, data: MeasurementSet, machine: Machine | None = None) -> Prediction:
    """Predict every row of a measurement file with a fitted model: the same measurement model,
    context defaults and set-up that :func:`identify` used, so that a file that was fitted is
    reproduced exactly (its readings minus the prediction are the fit's residuals)."""
    tag = unique_tags([data])[0]
    known = [tag] if tag in fitted.info.get("known_setup", ()) and data.kind in KNOWN_SETUP_KINDS else []
    mm = build_measurement_models(fitted.model, [data], fitted.context_defaults, machine=machine,
                                  known_setup=known)[0]
    nuisance, known = stored_setup(fitted, mm)
    p = fitted.params.values
    columns = mm.predict_columns(p, nuisance)
    jac = mm.column_jacobians(p)
    setup = _setup_derivatives(mm, p, nuisance, columns)
    undetermined = Undetermined.of(fitted)
    # whether a prediction rests on what the data left undetermined is a first-order question,
    # asked where the fit asked which combinations its data determine: at zero errors (identify's
    # start). At the fitted values a direction's effect also has a second-order part, its size times
    # the fitted errors, which no data could have fixed: on a direction of 1e4 urad of pitch and
    # yaw (1 um rms at the tool tip) it moved the fitted readings themselves by 0.03 um
    some = undetermined.directions is not None and undetermined.directions.shape[1] > 0
    jac0 = mm.column_jacobians(np.zeros_like(p)) if some else jac
    joint = joint_covariance(fitted, mm) if known else None     # once per file, not per column
    notes = []
    blank = open_sd = 0
    for name in list(columns):
        if name in jac:
            sd, unknown = undetermined.assess(np.nan_to_num(jac[name]), setup.get(name),
                                              np.nan_to_num(jac0[name]))
            if joint is not None:
                sd = np.where(np.isfinite(sd), with_fitted_setup(joint, jac[name], setup.get(name), sd),
                              sd)
            # what the model knows nothing of is no number (not the zero it is held at)
            unknown &= np.isfinite(columns[name])
            blank += int(unknown.sum())
            columns[name] = np.where(unknown, np.nan, columns[name])
            columns[f"{name}_sd"] = np.where(np.isfinite(columns[name]), sd, np.nan)
            open_sd += int(np.sum(np.isnan(sd) & np.isfinite(columns[name])))
        else:
            columns[f"{name}_sd"] = np.full(len(data), np.nan)
    if blank:
        notes.append(f"{blank} prediction(s) of {mm.tag} rest only on what the model's data did not "
                     "determine: left blank")
    if open_sd and fitted.uncertainty is not None:
        notes.append(f"{open_sd} prediction(s) of {mm.tag} depend on a combination of the model's "
                     "parameters its data did not determine (the model file's "
                     "uncertainty.undetermined): written with a blank standard error (what the "
                     "data say nothing of has none; compensate's correction_sd_um there is that of "
                     "the rest, since a correction has no part along that combination, unless a "
                     "file's set-up took it from the machine: then compensate corrects nothing there)")
    notes += _assumed_note(fitted, data, machine or fitted.machine, open_sd > 0)
    notes += _blank_outside_region(fitted, data, machine or fitted.machine, columns)
    if fitted.uncertainty is None:
        notes.append("the model carries no uncertainty (mtcomp identify and diagnose write one; a "
                     "model file of an older mtcomp may not): the _sd columns are blank")
    if getattr(mm, "kind", None) == "thermal":
        notes += _thermal_notes(fitted, mm, known)
    elif not known:
        notes.append(f"{mm.tag} was not part of the fit: its set-up ({', '.join(s.name.split(':', 1)[1] for s in mm.nuisance_specs)}) "
                     "is unknown and taken as zero; compare readings up to that set-up")
    return Prediction(columns, known, notes)


def _thermal_notes(fitted: FittedModel, mm, known: bool) -> list:
    """What a thermal file's predictions are referenced to, and the model's channels it lacks.

    A channel the model reads as an absolute value (a drift term with a zero of its own) is
    predicted in the zero of the record the model was fitted on, whatever file it is; any other
    channel as the change since the file's first reading (docs/thermal.md)."""
    from ..measurement.readings_extra import model_channels, tip_channels
    _, absolute = tip_channels(fitted.model)
    notes = []
    missing = sorted(model_channels(fitted.model) - set(mm.channels))
    if missing:
        notes.append(f"{mm.tag} has no column for the model's channel(s) "
                     f"{', '.join(missing)} ({', '.join(f'disp_{c}_um' for c in missing)}): not "
                     "predicted (a misspelt column name?)")
    if not known:
        absolute_here = [c for c in mm.channels if c in absolute]
        relative = [c for c in mm.channels if c not in absolute]
        if absolute_here:
            notes.append(f"{mm.tag} was not part of the fit: channel(s) {', '.join(absolute_here)} "
                         "predicted in the zero of the record the model was fitted on (the "
                         "sensors left in place since; if they were set to zero again, compare "
                         "each channel up to its own offset)")
        if relative:
            notes.append(f"{mm.tag} was not part of the fit: channel(s) {', '.join(relative)} "
                         "predicted as the change since this file's first reading")
    return notes


def _assumed_note(fitted, data, machine, acting: bool) -> list:
    """What the predictions assume at zero (compensate's rule, :mod:`mtcomp.models.assumed`):
    said when some prediction rests on what the data left open (``acting``) or a row stands away
    from where the data held an axis they never moved."""
    q = data.axis_positions(machine) if hasattr(data, "axis_positions") else None
    said = model_note(fitted, machine, "the predictions", q, acting)
    return [said[len("note: "):]] if said else []


def _blank_outside_region(fitted, data, machine, columns: dict) -> list:
    """Blank the standard errors (``*_sd`` columns) of the rows whose axis positions lie outside the
    region the model's data reached (there the model holds its profiles' end values: a guess its
    posterior does not size, and compensate and export do not correct there); the note saying so."""
    from ..models.region import outside_bounds, support_bounds
    bounds = support_bounds(fitted)
    if bounds is None or not hasattr(data, "axis_positions"):
        return []
    tool = getattr(data, "tool", None)
    out = outside_bounds(machine, bounds, data.axis_positions(machine),
                         tool_length=tool if isinstance(tool, np.ndarray) and tool.ndim == 1 else None)
    rows = out.any(axis=1)
    if not rows.any():
        return []
    for name, values in columns.items():
        if name.endswith("_sd"):
            values[rows] = np.nan
    lo, hi = bounds
    axes = []
    for j, a in enumerate(machine.axes):
        if out[:, j].any():
            f, unit = (np.degrees(1.0), "deg") if a.is_rotary else (1.0, "mm")
            axes.append(f"{a.name} {lo[j] * f:g} .. {hi[j] * f:g} {unit}: {int(out[:, j].sum())}")
    return [f"{data.path}: {int(rows.sum())} row(s) lie outside the region the model's data reached "
            f"({'; '.join(axes)}): the model holds its profiles' end values there, a guess its "
            "standard error does not size: the prediction is written, its _sd column left blank "
            "(compensate and export do not correct there)"]

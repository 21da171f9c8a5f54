"""Identification: one weighted least-squares fit of an error model to any mix of measurement files.

:func:`identify` fits the parameters of an :class:`~mtcomp.models.ErrorModel` (by default its base
parameters, ``model.base_mask``) and every file's nuisance parameters (laser zero offsets and optic
slopes, ball-bar length offsets ...) to all observations at once, and returns an
:class:`IdentificationResult`.

Method (docs/identification.md):

* Residuals ``r = w (observed - predicted)`` with one weight per observation. Default weighting
  ``"unit"``: every residual in um (translational, lengths) or urad (angular), i.e. ``w = 1e3`` per mm
  and ``1e6`` per rad, the same for every file. ``"noise"``: a first fit with unit weights estimates
  each file's noise (rms residual per file and unit, corrected for the degrees of freedom the file
  uses), then the fit is repeated with ``w = 1 / noise``. A dict ``{tag: noise}`` (um or urad) fixes
  the noise per file.
* Gauss-Newton on the unknowns x = (free parameters, nuisance parameters), with the exact CasADi
  Jacobian, columns scaled to unit norm (``D``), the normal equations of the scaled problem
  (accumulated file by file: the stacked Jacobian is never formed) solved in the subspace of
  well-determined directions. Each iteration recomputes the residuals exactly, which refines the
  normal-equation solution like iterative refinement. The model is nearly linear in p, so 2-3
  iterations converge; a step that increases the cost is halved (down to 1e-6).
* Rank: the singular values ``s`` of the scaled weighted Jacobian at the start point (the eigenvalues
  of its normal matrix). Directions with ``s / s_max <= rcond`` (default 1e-6) are the combinations the
  data cannot determine: they are named (the parameters with weight above 10 % of the largest in
  each direction, in file units, normalised on a pivot parameter) and held at their start values
  (zero by default) by solving only in the orthogonal complement, i.e. the minimum-norm solution of
  the scaled problem. The null space is fixed at the start point so that combinations that would be
  determined only by second-order effects of the errors themselves stay undetermined.
* Covariance of the unknowns: ``s2 D B (B^T Js^T Js B)^-1 B^T D`` with B the determined directions and
  ``s2 = sum r^2 / (n_obs - rank)``; standard errors are its diagonal. A parameter with weight in an
  undetermined direction gets std error NaN and ``determined = False``.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg

from ..errors import InputError
from ..io.atomic import same_file
from ..measurement.files import MeasurementSet
from ..machine import Machine
from ..models.chain import ErrorModel
from ..models.model_file import FittedModel
from ..models.params import ParameterSet, ParamSpec
from ..models.basis import with_data_basis
from ..measurement.readings import (MeasurementModel, data_held, data_positions, data_spline_sizes, data_support,
                                    measurement_model)

#: relative singular-value threshold below which a direction counts as undetermined
DEFAULT_RCOND = 1e-6
#: most fits with weights='noise' (each re-estimates the noise of every file and unit)
NOISE_PASSES = 5
#: an unknown whose weight in the (orthonormal, scaled) null space exceeds this is undetermined; below
#: it, eigenvector round-off between a null direction and a weak determined one (~1e-6) is ignored
NULL_WEIGHT = 1e-4
#: a parameter is named in an undetermined combination when its weight exceeds this share of the largest
NAME_SHARE = 0.1


def error_unit(column: str) -> str:
    """The unit a reading column's errors are weighed and reported in: 'urad' for angles, 'um/min'
    for velocities (two-point velocity files, mm/min), 'um' for lengths and positions."""
    column = str(column)
    if column.endswith("_urad"):
        return "urad"
    if column.endswith("_mm_min"):
        return "um/min"
    return "um"


def error_scale(column: str) -> float:
    """Internal -> error unit of a reading column (:func:`error_unit`): 1e6 for urad, 1e3 for um and
    um/min (internal mm and mm/min)."""
    return 1e6 if error_unit(column) == "urad" else 1e3


# ------------------------------------------------------------------------------------- results
@dataclass
class FileResiduals:
    """Residuals of one file at the solution.

    tag, path, kind : the file. rows : (n_obs,) 0-based data row of each observation.
    file_rows : (n_obs,) 1-based row in the file (header = row 0). columns : (n_obs,) measured column.
    residual : (n_obs,) observed minus predicted, FILE units (um, urad, mm as the column says).
    weight : (n_obs,) weight per internal unit used in the fit.
    """

    tag: str
    path: str
    kind: str
    rows: np.ndarray
    file_rows: np.ndarray
    columns: np.ndarray
    residual: np.ndarray
    weight: np.ndarray

    @property
    def n_obs(self) -> int:
        return int(self.residual.shape[0])

    def rms(self) -> dict[str, float]:
        """Root mean square residual per measured column, file units."""
        return {str(c): float(np.sqrt(np.mean(self.residual[self.columns == c] ** 2)))
                for c in dict.fromkeys(self.columns.tolist())}

    def rms_error_units(self) -> dict[str, float]:
        """rms per error unit ('um', 'urad', 'um/min'): lengths in mm are reported in um."""
        out = {}
        units = np.array([error_unit(c) for c in self.columns])
        for unit in ("um", "urad", "um/min"):
            sel = units == unit
            if sel.any():
                scale = np.array([error_scale(c) / _file_scale(c) for c in self.columns[sel]])
                out[unit] = float(np.sqrt(np.mean((self.residual[sel] * scale) ** 2)))
        return out


def _finite(x) -> float | None:
    """x as a float, or None when not finite (JSON has no NaN or Infinity)."""
    x = float(x)
    return x if np.isfinite(x) else None


def _file_scale(column: str) -> float:
    from ..measurement.files import file_unit_scale
    return file_unit_scale(str(column))


@dataclass
class UndeterminedCombination:
    """A direction of the unknowns the data cannot determine.

    terms : [(name, coefficient)], coefficients in FILE units of each unknown, normalised so that the
        pivot (first) has 1: moving the unknowns by ``t * coefficient`` leaves the prediction unchanged
        (to first order) for any t.
    singular_value : relative singular value s / s_max of the direction.
    """

    terms: list[tuple[str, float]]
    singular_value: float

    def __str__(self):
        parts = []
        for k, (name, coef) in enumerate(self.terms):
            sign = "-" if coef < 0 else ("+" if k else "")
            parts.append(f"{sign} {abs(coef):.3g} {name}" if k else f"{sign}{abs(coef):.3g} {name}")
        return " ".join(parts)

    @property
    def names(self) -> list[str]:
        return [n for n, _ in self.terms]


@dataclass
class IdentificationResult:
    """What :func:`identify` returns (values in internal units; ``summary()`` prints file units).

    model : the error model. specs : ParamSpec of every model parameter (``model.param_specs``).
    values : (n_params,) fitted values (held parameters keep their start values).
    std_errors : (n_params,) standard errors; NaN for held and undetermined parameters.
    free : (n_params,) bool, fitted. determined : (n_params,) bool, free and not in a null direction.
    nuisance_specs, nuisance_values, nuisance_std_errors : the files' nuisance parameters.
    unknown_names : names of the fitted unknowns (free parameters then nuisance), the order of
        ``covariance`` and ``correlation`` (internal units).
    undetermined : combinations the data cannot determine.
    rank, condition_number (of the determined part), singular_values (relative, descending).
    files : residuals per file. n_obs, n_params (fitted unknowns), dof = n_obs - rank.
    sigma : sqrt(weighted residual sum of squares / dof) (1 means residuals match the weights).
    iterations, converged, cost (weighted residual sum of squares), seconds.
    fitted_model : FittedModel (values and std errors) for save_model.
    """

    model: ErrorModel
    specs: tuple[ParamSpec, ...]
    values: np.ndarray
    std_errors: np.ndarray
    free: np.ndarray
    determined: np.ndarray
    nuisance_specs: list[ParamSpec]
    nuisance_values: np.ndarray
    nuisance_std_errors: np.ndarray
    unknown_names: tuple[str, ...]
    covariance: np.ndarray
    undetermined: list[UndeterminedCombination]
    rank: int
    condition_number: float
    singular_values: np.ndarray
    files: list[FileResiduals]
    n_obs: int
    n_params: int
    dof: float
    sigma: float
    iterations: int
    converged: bool
    cost: float
    seconds: float
    weighting: str
    fitted_model: FittedModel = None
    info: dict = field(default_factory=dict)
    #: the roughness penalty's weights (mtcomp.identification.penalty.Smoothing), None without one
    smoothing: object = None

    @property
    def param_names(self) -> tuple[str, ...]:
        return tuple(s.name for s in self.specs)

    @property
    def correlation(self) -> np.ndarray:
        """(n_unknowns, n_unknowns) correlation matrix of the unknowns (NaN where undetermined)."""
        sd = np.sqrt(np.diag(self.covariance))
        with np.errstate(invalid="ignore", divide="ignore"):
            corr = self.covariance / np.outer(sd, sd)
        return corr

    def value(self, name: str) -> tuple[float, float]:
        """(value, std error) of a parameter or nuisance parameter, FILE units."""
        for specs, vals, errs in ((self.specs, self.values, self.std_errors),
                                  (self.nuisance_specs, self.nuisance_values, self.nuisance_std_errors)):
            for i, s in enumerate(specs):
                if s.name == name:
                    return float(vals[i] * s.to_file), float(errs[i] * s.to_file)
        raise KeyError(name)

    def rms(self) -> dict[str, dict[str, float]]:
        """tag -> column -> rms residual, file units."""
        return {f.tag: f.rms() for f in self.files}

    def compare(self, extended: "IdentificationResult") -> dict:
        """F-test of this fit against an ``extended`` one of the same observations (statsmodels'
        ``compare_f_test``): does the extension lower the weighted residual sum of squares by more
        than its extra parameters would by chance?

        Returns {"F": F, "p_value": p, "df_num": extra effective degrees of freedom, "df_den":
        extended dof}; p small means the extension earns its place on these data (a held-out check
        is still the stronger test). With profiles under a roughness penalty the degrees of freedom
        are the fits' effective ones (trace of the hat matrix), not their ranks: a direction the
        penalty alone fixes costs the data nothing (for penalised fits the test is approximate).
        """
        from scipy import stats
        if extended.n_obs != self.n_obs:
            raise ValueError("compare needs fits of the same observations")
        df_num = float(self.dof - extended.dof)
        df_den = float(extended.dof)
        if df_num <= 0 or df_den <= 0:
            raise ValueError("the extended fit must determine more parameters and keep degrees of freedom")
        F = ((self.cost - extended.cost) / df_num) / (extended.cost / df_den)
        return {"F": float(F), "p_value": float(stats.f.sf(F, df_num, df_den)), "df_num": df_num,
                "df_den": df_den}

    def largest_correlations(self, k: int = 5, threshold: float = 0.9):
        """Up to k pairs (name_a, name_b, r) of determined unknowns with |r| >= threshold."""
        corr = self.correlation
        n = corr.shape[0]
        iu = np.triu_indices(n, 1)
        r = corr[iu]
        ok = np.isfinite(r) & (np.abs(r) >= threshold)
        order = np.argsort(-np.abs(r[ok]))[:k]
        a, b = iu[0][ok][order], iu[1][ok][order]
        return [(self.unknown_names[i], self.unknown_names[j], float(corr[i, j])) for i, j in zip(a, b)]

    def to_dict(self) -> dict:
        """Plain summary (file units) for MODEL.json ``info`` and reports."""
        return {"n_obs": self.n_obs, "n_params": self.n_params, "rank": self.rank, "dof": _finite(self.dof),
                "smoothing": self.smoothing.to_dict() if self.smoothing is not None else None,
                "sigma": _finite(self.sigma), "condition_number": _finite(self.condition_number),
                "iterations": self.iterations, "converged": self.converged, "weighting": self.weighting,
                "undetermined": [str(u) for u in self.undetermined],
                "files": [{"tag": f.tag, "path": f.path, "kind": f.kind, "n_obs": f.n_obs,
                           "rms": {c: _finite(v) for c, v in f.rms().items()}} for f in self.files],
                "nuisance": {s.name: {"value": float(v * s.to_file), "std_error": _finite(e * s.to_file),
                                      "unit": s.unit}
                             for s, v, e in zip(self.nuisance_specs, self.nuisance_values,
                                                self.nuisance_std_errors)}}

    def summary(self) -> str:
        """A table a person can read: parameters with value +- std error (file units), the nuisance
        parameters, the undetermined combinations and the rms residual of every file."""
        m = self.model.machine
        lines = [f"Identification of {m.name} ({m.topology}): {self.n_obs} observations in "
                 f"{len(self.files)} file(s), {self.n_params} unknowns, rank {self.rank}, dof {self.dof:.1f}",
                 f"weighting {self.weighting}; sigma {self.sigma:.4g}; condition number "
                 f"{self.condition_number:.3g}; {self.iterations} iteration(s)"
                 f"{'' if self.converged else ' (NOT converged)'}; {self.seconds:.2f} s", ""]
        lines.append(f"{'parameter':<28} {'value':>12} {'std error':>11}  unit")
        for i, s in enumerate(self.specs):
            if not self.free[i]:
                continue
            v = self.values[i] * s.to_file
            if self.determined[i]:
                e = f"{self.std_errors[i] * s.to_file:11.4g}"
            else:
                e = f"{'undeterm.':>11}"
            lines.append(f"{s.name:<28} {v:12.5g} {e}  {s.unit}")
        held = [s.name for i, s in enumerate(self.specs) if not self.free[i]]
        if held:
            lines.append(f"held at their start values: {len(held)} parameter(s)"
                         + (f" ({', '.join(held[:8])}{', ...' if len(held) > 8 else ''})"))
        if self.nuisance_specs:
            lines += ["", f"{'nuisance parameter':<28} {'value':>12} {'std error':>11}  unit"]
            for s, v, e in zip(self.nuisance_specs, self.nuisance_values, self.nuisance_std_errors):
                es = f"{e * s.to_file:11.4g}" if np.isfinite(e) else f"{'undeterm.':>11}"
                lines.append(f"{s.name:<28} {v * s.to_file:12.5g} {es}  {s.unit}")
        lines.append("")
        if self.undetermined:
            lines.append(f"{len(self.undetermined)} combination(s) the data cannot determine, or only "
                         "worse than 1 um of error over the travel (held where they predict the least "
                         "error; file units):")
            for u in self.undetermined:
                lines.append(f"  {u}")
        else:
            lines.append("every fitted parameter is determined by the data")
        if "weak_directions" in self.info:
            lines.append(f"weakly determined combinations {self.info['weak_directions']}")
        corr = self.largest_correlations()
        if corr:
            lines.append("strongest correlations: " + ", ".join(f"{a}/{b} {r:+.3f}" for a, b, r in corr))
        lines += ["", f"{'file':<24} {'kind':<8} {'n_obs':>7}  rms residual"]
        for f in self.files:
            rms = ", ".join(f"{c} {v:.4g}" + (f" ({v * 1e3:.4g} um)" if c.endswith("_mm") else "")
                            for c, v in f.rms().items())
            lines.append(f"{f.tag:<24} {f.kind:<8} {f.n_obs:>7}  {rms}")
        return "\n".join(lines)


# ------------------------------------------------------------------------------------- identify
def _free_mask(model: ErrorModel, free, hold) -> np.ndarray:
    names = model.param_names
    if free is None:
        mask = model.base_mask.copy()
    elif np.asarray(free).dtype == bool:
        mask = np.array(free, dtype=bool)
        if mask.shape != (model.n_params,):
            raise ValueError(f"free mask must have shape ({model.n_params},), got {mask.shape}")
    else:
        free = list(free)
        unknown = [n for n in free if n not in names]
        if unknown:
            raise InputError(f"unknown parameter(s) {', '.join(unknown)} (not in this model)")
        mask = np.isin(np.asarray(names), free)
    for name in hold or ():
        held = held_parameters(model, name)
        if not held.any():
            import difflib
            words = set(names) | _hold_groups(model) | {g.split(":")[0] for g in _hold_groups(model)}
            words |= {s.group.split(":", 1)[-1] for s in model.param_specs} | set(model.machine.axis_names)
            close = difflib.get_close_matches(name, sorted(words), n=1) or \
                difflib.get_close_matches(name.upper(), sorted(words), n=1)
            hint = f"did you mean {close[0]}? " if close else ""
            raise InputError(f"--hold {name}: no such parameter or group in this model ({hint}give a "
                             f"name such as EXX_b3, a component such as EXX, an axis letter such as X, "
                             f"or one of: {', '.join(sorted(_hold_groups(model)))})")
        mask[held] = False
    return mask


def _hold_groups(model: ErrorModel) -> set[str]:
    """Group names a hold may give besides parameter names: 'squareness', 'spindle', 'tool' and
    '<axis>:location' ... (the part of each parameter's group before any ':' is its axis)."""
    return {s.group for s in model.param_specs if ":" not in s.group or s.group.endswith(":location")}


def held_parameters(model: ErrorModel, name: str) -> np.ndarray:
    """(n_params,) bool: the parameters ``name`` stands for in a hold: a parameter name (EXX_b3), a
    component (EXX: all its terms), an axis letter (X: every component error of the axis; its
    location errors too for a rotary axis), or a group (squareness, spindle, tool, C:location)."""
    names = np.asarray(model.param_names)
    groups = np.array([s.group for s in model.param_specs])
    if name in model.param_names:
        return names == name
    axis = np.array([g.split(":", 1)[0] for g in groups])
    component = np.array([g.split(":", 1)[1] if ":" in g else "" for g in groups])
    return (groups == name) | (component == name) | ((axis == name) & (component != ""))


def _unique_tags(datasets) -> list[str]:
    from ..measurement.readings import file_tag
    tags, seen = [], {}
    for d in datasets:
        t = d.tag if isinstance(d, MeasurementModel) else file_tag(d)
        if t in seen:
            seen[t] += 1
            t = f"{t}#{seen[t]}"
        else:
            seen[t] = 1
        tags.append(t)
    return tags


def build_measurement_models(model: ErrorModel, datasets, context_defaults=None, machine=None,
                             known_setup=(), **options) -> list[MeasurementModel]:
    """A measurement model per data set (MeasurementModel instances are passed through), with unique
    tags (file stems, ``#2``... appended on repeats). ``known_setup``: tags or paths (as given, or
    any path to the same file) of files whose set-up is known: a points or cmm file whose instrument
    frame is the workpiece frame, a ball-bar file of a calibrated bar. One that names no data file, or a
    file of another kind, is an InputError."""
    out = []
    known = [str(k) for k in known_setup]
    used: set[str] = set()
    for d, tag in zip(datasets, _unique_tags(datasets)):
        if isinstance(d, MeasurementModel):
            out.append(d)
        elif isinstance(d, MeasurementSet):
            opts = dict(options)
            if machine is not None:
                opts["machine"] = machine
            hits = [k for k in known if k == tag or same_file(k, d.path)]
            if hits:
                if d.kind not in KNOWN_SETUP_KINDS:
                    raise InputError(f"--known-setup {hits[0]}: a {d.kind} file has no set-up to declare "
                                     f"known (only {' and '.join(KNOWN_SETUP_KINDS)} files)")
                used.update(hits)
                opts["setup"] = "known"
            out.append(measurement_model(model, d, context_defaults, tag=tag, **opts))
        else:
            raise TypeError(f"not a measurement set: {type(d).__name__}")
    for k in known:
        if k not in used:
            raise InputError(f"--known-setup {k}: names none of the data files")
    return out


#: kinds whose set-up ``known_setup`` can declare known (points, cmm: the instrument frame; ballbar:
#: the bar's length)
KNOWN_SETUP_KINDS = ("points", "ballbar", "cmm")


def identify(machine_or_model, datasets, *, free=None, hold=(), initial=None, weights="unit",
             rcond: float = DEFAULT_RCOND, max_iterations: int = 20, tol: float = 1e-10,
             context_defaults: dict | None = None, info: dict | None = None,
             known_setup=()) -> IdentificationResult:
    """Fit an error model to measurement files (all at once).

    Parameters
    ----------
    machine_or_model : Machine (its base model is fitted), ErrorModel, or FittedModel (its values are
        the start point and the values of held parameters; its context defaults are used).
    datasets : MeasurementSet or MeasurementModel instances (any mix of kinds with a registered model).
    free : None (``model.base_mask``), a bool mask (n_params,), or parameter names.
    hold : what to hold at the start values even if ``free`` includes it: parameter names, components
        (EXX), axis letters (X) or groups (squareness, spindle, tool, C:location); see
        :func:`held_parameters`.
    initial : (n_params,) start values, internal units (default zeros, or the FittedModel's).
    weights : ``"unit"`` (residuals in um and urad), ``"noise"`` (iteratively reweighted, 1/noise
        per file and unit) or a dict tag -> noise (um for translational/length columns, urad for
        angular ones).
    rcond : relative singular-value threshold for undetermined directions.
    max_iterations, tol : Gauss-Newton stops when the scaled step is below tol (relative).
    context_defaults : values of context channels the files lack.
    known_setup : tags (file stems) or paths of files whose set-up is known: points files whose
        instrument frame is the workpiece frame (no set-up translation and rotation is fitted), ball-bar
        files of a calibrated bar (no length offset). Recorded in the model (``info["known_setup"]``)
        so that predict treats those files alike.
    Returns an :class:`IdentificationResult`.

    Spline axes without fixed knots get them from the data first
    (:func:`mtcomp.models.basis.with_data_basis`): the fitted model's structure follows what was measured.
    """
    t0 = time.perf_counter()
    fitted_in = machine_or_model if isinstance(machine_or_model, FittedModel) else None
    if isinstance(machine_or_model, Machine):
        model = ErrorModel(machine_or_model)
    elif isinstance(machine_or_model, ErrorModel):
        model = machine_or_model
    elif fitted_in is not None:
        model = fitted_in.model
    else:
        raise TypeError("machine_or_model must be a Machine, ErrorModel or FittedModel")
    ctx_defaults = dict(fitted_in.context_defaults) if fitted_in is not None else {}
    ctx_defaults.update(context_defaults or {})
    datasets = list(datasets)
    model = model_for_data(model, datasets)
    p0 = np.zeros(model.n_params)
    if fitted_in is not None:
        p0 = fitted_in.params.reindexed(model.param_specs).values
    if initial is not None:
        p0 = np.asarray(initial, dtype=float).reshape(model.n_params).copy()
    mask = _free_mask(model, free, hold)
    mms = build_measurement_models(model, datasets, ctx_defaults, known_setup=known_setup)
    if not mms or sum(m.n_obs for m in mms) == 0:
        paths = [str(m.data.path) for m in mms if getattr(m.data, "path", None)]
        raise InputError("no observations to fit: every measured cell is blank"
                         + (f" in {', '.join(paths)}" if len(paths) > 1 else ""),
                         paths[0] if len(paths) == 1 else None)
    problem = _Problem(model, mms, mask, p0)
    problem.metric = travel_metric(model, problem.free_idx, problem.n_unknowns)

    if isinstance(weights, str) and weights == "unit":
        w = problem.unit_weights()
        label = "unit (um, urad)"
    elif isinstance(weights, str) and weights == "noise":
        w = problem.unit_weights()
        for _ in range(NOISE_PASSES):
            sol = problem.solve(w, rcond, max_iterations, tol, leverage=True)
            w_new = problem.noise_weights(sol, w)
            change = np.max(np.abs(w_new / w - 1.0))
            w = w_new
            if change < 0.01:
                break
        label = "1/noise per file"
    elif isinstance(weights, dict):
        w = problem.dict_weights(weights)
        label = "given noise per file"
    else:
        raise ValueError(f"weights must be 'unit', 'noise' or a dict, not {weights!r}")
    sol = problem.solve(w, rcond, max_iterations, tol)
    result = problem.result(sol, w, label, ctx_defaults, time.perf_counter() - t0, info)
    # an axis none of whose own errors were fitted (all held: the user says the controller already
    # compensates it) does not bound the model: what was fitted (a rotary table's motion) holds for
    # the rigid body wherever that axis stands
    fitted_axes = {model.param_specs[i].group.split(":", 1)[0] for i in np.flatnonzero(mask)}
    result.fitted_model.support = {a: r for a, r in data_support(model.machine, datasets).items()
                                   if a in fitted_axes}
    known = [m.tag for m in mms if m.options.get("setup") == "known"]
    if known:
        result.fitted_model.info["known_setup"] = known
    result.fitted_model.held = {a: v for a, v in data_held(model.machine, datasets).items()
                                if a in fitted_axes}
    if problem.weak_fallback:
        result.info["weak_directions"] = ("not held: holding them would have spoiled the fit of the "
                                          "data; the data's own least-squares fit is kept")
    return result


def model_for_data(model: ErrorModel, datasets) -> ErrorModel:
    """``model`` with the knots of its spline axes chosen from the data where the machine leaves them
    open (the same terms)."""
    m = model.machine
    if not any(a.basis_from_data for a in m.linear_axes):
        return model
    return ErrorModel(with_data_basis(m, data_positions(m, datasets), sizes=data_spline_sizes(m, datasets)),
                      model.terms)


#: poses drawn over the travel for the physical metric of :func:`travel_metric`
METRIC_POSES = 256
#: Gauss-Newton stops at a step that moves every combination of the unknowns by less than this
#: many of its standard errors (or by less than ``tol`` relative)
STEP_SE = 1e-3
#: a combination of parameters whose rms tool-tip error over the travel the data fix only to worse
#: than this standard error (um) is held at the least error, like one they do not see at all
WEAK_SD_UM = 1.0
#: ... unless the first fit puts it further from the start than this many of its standard errors:
#: then the data do see it (a real error of 28 um fixed to 1.2 um is fitted, not held at zero)
WEAK_SIGNIFICANT = 3.0
#: log penalty weights that the REML at the fit moves by less than this are those the fit used (a
#: factor 1.05: the profiles move by far less than their standard errors), and the fit stands
RHO_SETTLED = 0.05
#: the widest range of penalty on one class's coefficients (column-scaled) that a fit keeps
PENALTY_RANGE = 1e6
#: weight of a set-up unknown (a file's zero offset, its alignment) against a machine parameter when a
#: combination the data cannot determine is held: the set-up takes what it trades with machine errors
SETUP_WEIGHT = 1e-3


def held_complement(null: np.ndarray, machine: np.ndarray) -> np.ndarray:
    """(n, n - k) orthonormal directions a fit moves in, given the k orthonormal directions ``null``
    (column-scaled coordinates) the data do not determine and ``machine`` (n,) bool, True for machine
    parameters, False for set-up unknowns: ``{z : null^T W z = 0}`` with W = 1 on machine parameters
    and SETUP_WEIGHT^2 on set-ups. W is positive definite, so these directions and ``null`` together
    span everything: every fit of the data is reached, with the least machine part of each
    undetermined combination. A constant the readings share between a laser's zero offset and the
    angle of an axis that never moved (through its Abbe arm) is the offset's: the plain minimum norm
    split it three ways and made a pitch of Z of 105 urad out of a laser run of X."""
    k = null.shape[1]
    if k == 0:
        return np.eye(null.shape[0])
    w = np.where(machine, 1.0, SETUP_WEIGHT ** 2)
    _, _, Vt = np.linalg.svd((w[:, None] * null).T, full_matrices=True)
    return Vt[k:].T


def travel_metric(model: ErrorModel, free_idx: np.ndarray, n_unknowns: int) -> np.ndarray:
    """(n_unknowns, n_unknowns) M with ``x^T M x`` the mean squared tool-tip error (mm^2) over the
    machine's travel that the fitted parameters x predict (to first order); zero for nuisance
    parameters, which are not machine errors.

    The poses are drawn uniformly over the travel of every axis (fixed seed), at the machine's tool
    length and 100 mm longer, with random approach directions and feeds up to 5 m/min, so that
    every term that acts somewhere in normal use has its weight. What the data do not determine is
    resolved by the smallest ``x^T M x``: the smallest predicted error, in physical terms.
    """
    from ..measurement.readings import evaluate_chain
    m = model.machine
    rng = np.random.default_rng(20261123)
    lo, hi = m.travel_bounds()
    q = lo + (hi - lo) * rng.random((METRIC_POSES, m.n_axes))
    c = model.default_context(METRIC_POSES)
    names = model.context_names
    c[:, names.index("tool_length")] = m.tool_length + 100.0 * rng.integers(0, 2, METRIC_POSES)
    c[:, names.index("feed")] = 5000.0 * rng.random(METRIC_POSES)
    for a in m.axis_names:
        c[:, names.index(f"dir_{a}")] = rng.choice([-1.0, 1.0], METRIC_POSES)
    J = evaluate_chain(model, "tip_jac", q, np.zeros(model.n_params), c)[1]   # (N, n_params, 3)
    G = J.transpose(0, 2, 1).reshape(-1, model.n_params)[:, free_idx]
    M = np.zeros((n_unknowns, n_unknowns))
    M[:free_idx.size, :free_idx.size] = G.T @ G / METRIC_POSES
    return M


@dataclass
class _Solution:
    x: np.ndarray
    r: np.ndarray               # weighted residuals at x
    cov: np.ndarray             # covariance of the unknowns (internal units)
    null: np.ndarray            # (n_unknowns, n_null) null directions, scaled coordinates
    scale: np.ndarray           # column scaling D
    sv: np.ndarray              # relative singular values, descending
    rank: int
    cond: float
    iterations: int
    converged: bool
    leverage: np.ndarray        # (n_obs,) diagonal of the hat matrix (sums to the edf)
    edf: float = float("nan")   # effective degrees of freedom (the rank without a penalty)


class _Problem:
    """The stacked least-squares problem of several measurement models."""

    #: profiles carry a roughness penalty (mtcomp.identification.penalty)
    use_penalty = True

    def __init__(self, model, mms, mask, p0):
        self.model = model
        self.mms = mms
        self.mask = mask
        self.free_idx = np.flatnonzero(mask)
        self.p0 = p0
        self.n_free = self.free_idx.size
        self.nuis_slices = []
        k = self.n_free
        for m in mms:
            self.nuis_slices.append(slice(k, k + m.n_nuisance))
            k += m.n_nuisance
        self.n_unknowns = k
        self.obs_slices = []
        k = 0
        for m in mms:
            self.obs_slices.append(slice(k, k + m.n_obs))
            k += m.n_obs
        self.n_obs = k
        self.observed = np.concatenate([m.observed for m in mms])
        self.metric = None      # (n_unknowns, n_unknowns) mean squared tip error over the travel, mm^2
        self.weak_fallback = False  # the weak-direction pass was refused (see solve)
        self.S = None               # the penalty in scaled coordinates at the chosen weights
        self.smoothing = None       # penalty.Smoothing of the last solve
        self.smoothing_rho = {}     # class -> log weight of the last solve
        self.gradient_stale = False  # the last Gauss-Newton pass stopped on a step it did not evaluate

    # --------------------------------------------------------------- weights
    def unit_weights(self):
        return np.concatenate([_error_scales(m.obs_column) for m in self.mms])

    def _groups(self):
        """(file index, scale, observation index array) per file and error unit (um, urad and um/min
        are separate groups: a velocity's noise is not a position's)."""
        for i, (m, sl) in enumerate(zip(self.mms, self.obs_slices)):
            scales = _error_scales(m.obs_column)
            units = np.array([error_unit(c) for c in m.obs_column])
            for u in np.unique(units):
                sel = units == u
                yield i, scales[sel][0], np.arange(sl.start, sl.stop)[sel]

    def noise_weights(self, sol: "_Solution", w_used):
        """1/noise per file and unit from the residuals of a fit with weights ``w_used``: noise^2 =
        sum of squared residuals / (n - sum of the leverages of those observations)."""
        w = self.unit_weights()
        for _, s, idx in self._groups():
            resid = sol.r[idx] / w_used[idx] * s   # error units
            dof = idx.size - float(np.sum(sol.leverage[idx]))
            noise = np.sqrt(np.sum(resid ** 2) / max(dof, 1e-12))
            if noise > 0:
                w[idx] = s / noise
        return w

    def dict_weights(self, noise: dict):
        w = self.unit_weights()
        tags = {m.tag: i for i, m in enumerate(self.mms)}
        for tag in noise:
            if tag not in tags:
                raise InputError(f"weights name file {tag!r}, which is not among the data "
                                 f"({', '.join(tags)})")
        for i, s, idx in self._groups():
            tag = self.mms[i].tag
            if tag in noise:
                sigma = float(noise[tag])
                if not sigma > 0:
                    raise InputError(f"noise of file {tag!r} must be positive, got {sigma}")
                w[idx] = s / sigma
        return w

    # --------------------------------------------------------------- evaluation
    def params(self, x):
        p = self.p0.copy()
        p[self.free_idx] = x[:self.n_free]
        return p

    def evaluate(self, x):
        """(n_obs,) unweighted predictions at the unknowns x."""
        p = self.params(x)
        pred = np.empty(self.n_obs)
        for m, so, sn in zip(self.mms, self.obs_slices, self.nuis_slices):
            if m.n_obs:
                pred[so] = m.predict(p, x[sn])
        return pred

    def normal_equations(self, x, w, gram: bool = True):
        """Predictions and the normal equations of the weighted problem at x, file by file (the
        stacked Jacobian is never formed): A = Jw^T Jw (n_unknowns, n_unknowns), g = Jw^T r_w with
        Jw = w J and r_w = w (observed - predicted). ``gram=False`` skips A (returned as None)."""
        p = self.params(x)
        n_u, nf, fi = self.n_unknowns, self.n_free, self.free_idx
        pred = np.empty(self.n_obs)
        A = np.zeros((n_u, n_u)) if gram else None
        g = np.zeros(n_u)
        for m, so, sn in zip(self.mms, self.obs_slices, self.nuis_slices):
            if m.n_obs == 0:
                continue
            ww = w[so]
            if not gram and m.fast_gradient:
                y = m.predict(p, x[sn])
                pred[so] = y
                gp, gn = m.gradient(p, x[sn], ww * ww * (self.observed[so] - y))
                g[:nf] += gp[fi]
                g[sn] += gn
                continue
            y, Jp, Jn = m.predict_and_jacobian(p, x[sn])
            pred[so] = y
            rw = ww * (self.observed[so] - y)
            g[:nf] += (Jp.T @ (ww * rw))[fi]
            g[sn] += Jn.T @ (ww * rw)
            if gram:
                Jw = np.multiply(Jp, ww[:, None], out=Jp if Jp.flags.writeable else None)
                Jnw = Jn * ww[:, None]
                A[:nf, :nf] += _gram(Jw)[np.ix_(fi, fi)]
                Apn = (Jw.T @ Jnw)[fi]
                A[:nf, sn] += Apn
                A[sn, :nf] += Apn.T
                A[sn, sn] += Jnw.T @ Jnw
        return pred, A, g

    def leverages(self, x, w, scale, B, L):
        """(n_obs,) diagonal of the hat matrix Js B (B^T Js^T Js B)^-1 B^T Js^T, L L^T = B^T Js^T Js B."""
        p = self.params(x)
        out = np.zeros(self.n_obs)
        for m, so, sn in zip(self.mms, self.obs_slices, self.nuis_slices):
            if m.n_obs == 0:
                continue
            Jp, Jn = m.jacobian(p, x[sn])
            Js = np.zeros((m.n_obs, self.n_unknowns))
            Js[:, :self.n_free] = Jp[:, self.free_idx]
            Js[:, sn] = Jn
            Js *= w[so][:, None] * scale[None, :]
            M = scipy.linalg.solve_triangular(L, (Js @ B).T, lower=True)
            out[so] = np.einsum("ij,ij->j", M, M)
        return out

    def _repeat_scale(self, r, rank) -> float:
        """The scale of the weighted residuals r that noise alone makes: pooled over repeat groups
        (the same reading of the same set-up in several runs, mtcomp.measurement.outliers) when the
        files have at least 5 degrees of freedom of repeats, so that a model's misfit (an effect it
        lacks) is not taken for noise; else the rms residual."""
        from ..measurement.outliers import setup_keys
        ss, dof = 0.0, 0
        for m, so in zip(self.mms, self.obs_slices):
            keys = setup_keys(m.data)
            if keys is None or m.n_obs == 0:
                continue
            names, cols = np.unique(np.asarray(m.obs_column, dtype=str), return_inverse=True)
            group = keys[m.obs_row] * names.size + cols
            rr = r[so]
            counts = np.bincount(group)
            means = np.bincount(group, weights=rr) / np.maximum(counts, 1)
            rep = counts[group] >= 2
            ss += float(np.sum((rr[rep] - means[group[rep]]) ** 2))
            dof += int(np.sum(counts[counts >= 2] - 1))
        if dof >= 5:
            return float(np.sqrt(ss / dof))
        dof0 = max(self.n_obs - rank, 0)
        return float(np.sqrt(float(r @ r) / dof0)) if dof0 > 0 else 0.0

    def _damped_step(self, x, cost, B, AB, scale, grad, w):
        """Levenberg-Marquardt steps ``(AB + mu I)^-1`` with growing mu from the smallest that helps:
        (x, r, cost) of the first that lowers the objective (penalty included), or (None, None, None)."""
        gs = B.T @ (scale * grad - self.penalty_gradient(x, scale))
        mu = 1e-8 * max(float(np.trace(AB)) / max(AB.shape[0], 1), 1e-300)
        for _ in range(12):
            dz = B @ np.linalg.solve(AB + mu * np.eye(AB.shape[0]), gs)
            x_new = x + scale * dz
            r_new = w * (self.observed - self.evaluate(x_new))
            cost_new = float(r_new @ r_new) + self.penalty(x_new, scale)
            if cost_new < cost * (1 - 1e-12):
                return x_new, r_new, cost_new
            mu *= 30.0
        return None, None, None

    # --------------------------------------------------------------- penalty
    def penalty(self, x, scale) -> float:
        """The roughness penalty ``z^T S z`` at the unknowns x (z = x / scale), 0 without one."""
        if self.S is None:
            return 0.0
        z = x / scale
        return float(z @ self.S @ z)

    def penalty_gradient(self, x, scale) -> np.ndarray:
        """``S z``: half the gradient of the penalty in scaled coordinates (zeros without one)."""
        if self.S is None:
            return np.zeros_like(x)
        return self.S @ (x / scale)

    def scaled_penalties(self, A, scale) -> dict:
        """{class: S_k} in scaled coordinates, each normalised so that a weight of 1 weighs a
        profile's curvature about as much as the data weigh one well-seen coefficient (the median
        penalty on the coefficients the data see). Classes none of whose coefficients the data see
        are left out, and so are the coefficients the data do not see at all (a rotary axis's
        positioning harmonics under balls on its axis): what no data touch stays at zero, held with
        the null space, never set by the penalty alone."""
        from .penalty import penalty_matrices
        seen = _seen_columns(A)
        out = {}
        for cls, S in penalty_matrices(self.model, self.free_idx, self.n_unknowns).items():
            on = np.diag(S) > 0
            Ss = S * np.outer(scale, scale)
            d = np.diag(Ss)
            typical = d[on & seen]
            if typical.size == 0:
                continue
            Ss = Ss / float(np.median(typical))
            # a coefficient the data see a million times more weakly than the class's typical one
            # (a wall's angular profile seen through a 0.1 mm arm) is as good as unseen: its penalty
            # would dwarf every other direction and the solve would lose them to round-off
            drop = on & (~seen | (np.diag(Ss) > PENALTY_RANGE))
            out[cls] = _eliminate(Ss, drop)
        return {cls: Ss for cls, Ss in out.items() if np.diag(Ss).any()}

    def penalised_null(self, null, penalties: dict) -> np.ndarray:
        """The directions among ``null`` (the data's, orthonormal, scaled) that no penalty sees either
        (a straight line of a profile the data do not reach, a constant against a laser zero ...)."""
        if not penalties or null.shape[1] == 0:
            return null
        # each penalty is normalised to about 1 on a well-seen coefficient (scaled_penalties): a
        # direction it weighs below DEFAULT_RCOND of that is as good as unseen
        M = sum(null.T @ S @ null for S in penalties.values())
        ev, U = np.linalg.eigh(0.5 * (M + M.T))
        return null @ U[:, ev <= DEFAULT_RCOND]

    # --------------------------------------------------------------- weak directions
    def _weak_directions(self, AB, B, scale, sigma_w: float, y):
        """(n_seen, k) the weak directions among those the data see, as coordinates on B: what the
        data barely see, to be held at the least predicted error.

        The search space is x = x0 + scale * B y (B: the directions the data see, orthonormal in the
        scaled unknowns; AB = B^T As B, the data's normal matrix there). The travel metric
        ``Q = B^T D M D B`` measures a step's rms tool-tip error over the travel (um^2); steps it
        does not see (the files' set-ups, a thermal channel's drift ...) have no physical size and
        are marginalised out (Schur complement of AB). In the rest, whitened by Q, a direction
        whose standard error ``sigma_w / s`` (sigma_w the rms weighted residual, s^2 the data's
        information per um^2) exceeds :data:`WEAK_SD_UM` is weak: the data would fix its error over
        the travel only to worse than that; unless the first fit ``y`` moved it by more than
        :data:`WEAK_SIGNIFICANT` of those standard errors (then the data see it after all). The
        second pass holds each weak one at the start's value, zero error: directions the data see
        are fitted without bias. Weak and strong directions are orthogonal in the metric, so the
        result is the least-error completion of what the data determine.

        Returns W (n_seen, k) with the constraint ``W^T Q y = 0`` holding them, Q-orthonormal.
        """
        k = B.shape[1]
        if self.metric is None or k == 0:
            return np.zeros((k, 0)), None
        SB = scale[:, None] * B
        Q = SB.T @ (self.metric * 1e6) @ SB                 # um^2 of mean squared tip error per y^2
        Q = 0.5 * (Q + Q.T)
        m, W = np.linalg.eigh(Q)
        phys = m > 1e-9 * max(float(m.max()), 1e-300)
        if not phys.any():
            return np.zeros((k, 0)), Q
        R, N0 = W[:, phys], W[:, ~phys]
        H = R.T @ AB @ R
        if N0.shape[1]:
            Hrn = R.T @ AB @ N0
            H = H - Hrn @ scipy.linalg.pinvh(N0.T @ AB @ N0) @ Hrn.T
        d = 1.0 / np.sqrt(m[phys])
        Hw = d[:, None] * H * d[None, :]
        evals, U = np.linalg.eigh(0.5 * (Hw + Hw.T))
        sd = sigma_w / np.sqrt(np.clip(evals, 1e-300, None))
        c = U.T @ (np.sqrt(m[phys]) * (R.T @ y))            # each direction's size in the fit, um
        is_weak = (sd > WEAK_SD_UM) & (np.abs(c) < WEAK_SIGNIFICANT * sd)
        return R @ (d[:, None] * U[:, is_weak]), Q

    # --------------------------------------------------------------- Gauss-Newton
    def solve(self, w, rcond, max_iterations, tol, leverage=False) -> _Solution:
        """Penalised Gauss-Newton on the weighted residuals, in two passes.

        What the data determine (rank, the undetermined combinations, which parameters are
        determined) comes from the data alone: the eigen-decomposition of the column-scaled normal
        matrix at the start point. Of what they leave open, the profiles' roughness penalty
        (:mod:`mtcomp.identification.penalty`, weights by REML) fixes the curvature: between what
        was measured a profile follows the smoothest curve. What neither sees stays at its start
        values, set-ups taking what they trade with machine errors (:func:`held_complement`). The
        first pass fits the data and the penalty. Knowing the residual scale, the directions whose
        rms tool-tip error over the travel is fixed only to worse than :data:`WEAK_SD_UM` count as
        undetermined too: the second pass holds them at the least predicted error
        (:meth:`_weak_directions`), so that noise is never amplified into invented errors.
        """
        from .penalty import Smoothing, reml_weights
        self.smoothing, self.smoothing_rho = None, {}
        x = np.zeros(self.n_unknowns)
        x[:self.n_free] = self.p0[self.free_idx]
        pred, A, g = self.normal_equations(x, w)
        r = w * (self.observed - pred)
        scale = _column_scale(A)
        rel, V = _relative_singular_values(A * np.outer(scale, scale))
        keep = rel > rcond
        penalties = self.scaled_penalties(A, scale) if self.use_penalty else {}
        null = self.penalised_null(V[:, ~keep], penalties)
        data_rank = int(keep.sum())
        cond = float(rel[0] / rel[keep][-1]) if data_rank else np.inf
        start = (x, r, A, g)
        B1 = held_complement(null, np.arange(self.n_unknowns) < self.n_free)
        self.S = None
        iterations = 0
        # REML on the problem linearised at the start, then again at that fit: there the residuals
        # are small, so the criterion's residual sum of squares (the start's less what the step
        # explains) does not lose its digits to a large start misfit (a misaligned CMM frame)
        rho = None
        for k in range(2 if penalties else 1):
            if k and self.gradient_stale:
                # the gradient at the fit (Gauss-Newton stopped on a step whose gradient it did not
                # evaluate); the normal matrix is the start's (linear in p up to 1e-5)
                pred, _, g = self.normal_equations(x, w, gram=False)
                r = w * (self.observed - pred)
            if penalties:
                z0 = x / scale
                AB0 = B1.T @ (A * np.outer(scale, scale)) @ B1
                Ss = list(penalties.values())
                before = rho
                rho, _ = reml_weights(AB0, B1.T @ (scale * g), float(r @ r), [B1.T @ S @ B1 for S in Ss],
                                      [B1.T @ (S @ z0) for S in Ss], [float(z0 @ S @ z0) for S in Ss],
                                      self.n_obs, start=rho)
                if before is not None and np.max(np.abs(rho - before)) < RHO_SETTLED:
                    # the weights at the fit are those the fit used: it stands
                    rho = before
                    break
                self.S = sum(np.exp(rk) * S for rk, S in zip(rho, Ss))
                self.smoothing_rho = dict(zip(penalties, rho))
            x, r, A, g, B, AB, more, converged = self._gauss_newton(
                x, r, A, g, w, max_iterations, tol, B1, scale)
            iterations += more
        rank = self.n_unknowns - null.shape[1]
        sigma_w = self._repeat_scale(r, min(rank, data_rank))
        y1 = B1.T @ ((x - start[0]) / scale)
        weak, Q = self._weak_directions(AB + self._reduced_penalty(B), B1, scale, sigma_w, y1)
        first = (x, r, A, g, B, AB, iterations, converged, null, rank)
        if weak.shape[1]:
            # reported as undetermined: the weak directions, in scaled coordinates, orthonormalised
            U_, sv_, _ = np.linalg.svd(B1 @ weak, full_matrices=False)
            null = np.hstack([null, U_[:, sv_ > 1e-9 * sv_.max()]])
            rank = self.n_unknowns - null.shape[1]
            # from the start again (the data-only pass may have wandered far along the weak
            # directions), in the directions the data see less the weak ones: W^T Q y = 0
            C = weak.T @ Q
            _, sv_c, Vt = np.linalg.svd(C, full_matrices=True)
            k_c = int(np.sum(sv_c > 1e-9 * max(float(sv_c.max()), 1e-300)))
            B2 = B1 @ Vt[k_c:].T
            x, r, A, g, B, AB, more, converged = self._gauss_newton(
                *start, w, max_iterations, tol, B2, scale)
            iterations += more
            # holding weak directions may cost the data fit about one noise variance each; much more
            # means the split into weak and strong went wrong numerically: keep the data's own fit
            allowed = float(first[1] @ first[1]) + 4.0 * weak.shape[1] * sigma_w ** 2 + 1e-300
            if not converged or float(r @ r) > 1.01 * allowed:
                x, r, A, g, B, AB, iterations, converged, null, rank = first
                self.weak_fallback = True
        lev = np.zeros(self.n_obs)
        edf = float(rank)
        if B.shape[1]:
            # the Bayesian posterior covariance of a penalised fit (Wood 2006): phi (AB + S)^-1, phi
            # the residual variance over the effective degrees of freedom tr((AB + S)^-1 AB)
            H = AB + self._reduced_penalty(B)
            Hinv = scipy.linalg.pinvh(H)
            edf = float(np.trace(Hinv @ AB)) if self.S is not None else float(rank)
            dof = self.n_obs - edf
            s2 = float(r @ r) / dof if dof > 0 else np.nan
            cov = s2 * (scale[:, None] * (B @ Hinv @ B.T) * scale[None, :])
            if leverage:
                lev = self.leverages(x, w, scale, B, np.linalg.cholesky(H))
        else:
            cov = np.full((self.n_unknowns, self.n_unknowns), np.nan)
        if self.S is not None:
            lam = {k: float(np.exp(v)) for k, v in self.smoothing_rho.items()}
            self.smoothing = Smoothing(lam, dict(self.smoothing_rho), edf)
        return _Solution(x, r, cov, null, scale, rel, rank, cond, iterations, converged, lev, edf)

    def _reduced_penalty(self, B) -> np.ndarray:
        """B^T S B: the penalty in the directions B (zeros without one)."""
        if self.S is None:
            return np.zeros((B.shape[1], B.shape[1]))
        return B.T @ self.S @ B

    def _gauss_newton(self, x, r, A, g, w, max_iterations, tol, B, scale):
        """Minimise ``|r|^2 + z^T S z`` (the penalty, when the problem has one) from x (with its
        residuals r and normal equations A, g) along the orthonormal directions B of the scaled
        unknowns (x = x0 + scale * B y, z = x / scale). Returns (x, r, A, g, B, reduced data matrix
        B^T As B, iterations, converged)."""
        def reduced(A_):
            return B.T @ (A_ * np.outer(scale, scale)) @ B

        SB = self._reduced_penalty(B)
        cost = float(r @ r) + self.penalty(x, scale)
        converged = False
        iterations = 0
        AB = reduced(A)
        solve = _solver(AB + SB)
        # The model is linear in p up to products of errors (1e-5 of the readings), so the Gram
        # matrix at the start serves every step (the chord method: the gradient is exact at each
        # step, so the minimum is the exact one). It is formed anew only when a step fails to
        # descend or convergence is slow: signs that the problem is not nearly linear.
        refresh = False
        self.gradient_stale = False
        for it in range(1, max_iterations + 1):
            iterations = it
            gs = scale * g - self.penalty_gradient(x, scale)
            dz = _step(B, solve, gs)
            # small: below tol of the unknowns, or so small against their uncertainty that no
            # reading could tell (the step's Mahalanobis length gs.dz under STEP_SE standard
            # errors: every combination of the unknowns moves less than that)
            small = (np.linalg.norm(dz) <= tol * (1.0 + np.linalg.norm(x / scale))
                     or float(gs @ dz) <= STEP_SE ** 2 * cost / max(self.n_obs - B.shape[1], 1))
            if small and it > 1:
                # converged: a step this small changes nothing a user can see (below tol of the
                # unknowns), so it is not taken and x keeps the residuals and gradient just evaluated;
                # the covariance uses the normal matrix the steps used (the start's unless refreshed;
                # the model is linear in p to 1e-5)
                converged = True
                break
            x_new = x + scale * dz
            if small:
                pred_new, A_new, g_new = self.evaluate(x_new), None, None
            else:
                refresh = refresh or it >= 4
                pred_new, A_new, g_new = self.normal_equations(x_new, w, gram=refresh)
                A_new = A if A_new is None else A_new
            r_new = w * (self.observed - pred_new)
            cost_new = float(r_new @ r_new) + self.penalty(x_new, scale)
            step = 1.0
            while cost_new > cost * (1 + 1e-12) + 1e-300 and step > 1e-6:
                # backtracking, rarely needed: the model is nearly linear in p
                step *= 0.5
                x_new = x + step * scale * dz
                pred_new = self.evaluate(x_new)
                r_new = w * (self.observed - pred_new)
                cost_new = float(r_new @ r_new) + self.penalty(x_new, scale)
                A_new = None
                refresh = True
            if cost_new > cost * (1 + 1e-12) + 1e-300:
                # no descent along the Gauss-Newton step: either at the minimum, or the step is
                # dominated by nearly singular directions; Levenberg-Marquardt damping tells them apart
                x_new, r_new, cost_new = self._damped_step(x, cost, B, AB + SB, scale, g, w)
                if x_new is None:
                    converged = True
                    break
                A_new = None
                refresh = True
                small = False
            x, r, cost = x_new, r_new, cost_new
            if small or cost == 0.0:
                converged = True
                self.gradient_stale = True      # g is the last point's: the step was not evaluated
                break
            if A_new is None:
                _, A_new, g_new = self.normal_equations(x, w)
            if A_new is not A:
                AB = reduced(A_new)
                solve = _solver(AB + SB)
            A, g = A_new, g_new
        if A is None:
            _, A, g = self.normal_equations(x, w)
        return x, r, A, g, B, AB, iterations, converged

    # --------------------------------------------------------------- result
    def result(self, sol: _Solution, w, label, ctx_defaults, seconds, info) -> IdentificationResult:
        model = self.model
        nuis_specs = [s for m in self.mms for s in m.nuisance_specs]
        unknown_specs = [model.param_specs[i] for i in self.free_idx] + nuis_specs
        unknown_names = tuple(s.name for s in unknown_specs)
        to_file = np.array([s.to_file for s in unknown_specs])
        # undetermined unknowns: those with weight in a null direction
        if sol.null.shape[1]:
            in_null = np.linalg.norm(sol.null, axis=1) > NULL_WEIGHT
        else:
            in_null = np.zeros(self.n_unknowns, dtype=bool)
        se = np.sqrt(np.clip(np.diag(sol.cov), 0.0, None))
        se[in_null] = np.nan
        cov = sol.cov.copy()
        cov[in_null, :] = np.nan
        cov[:, in_null] = np.nan
        combos = _name_null_space(sol.null, sol.scale, to_file, unknown_names, sol.sv[sol.rank:])

        values = self.params(sol.x)
        std = np.full(model.n_params, np.nan)
        std[self.free_idx] = se[:self.n_free]
        determined = np.zeros(model.n_params, dtype=bool)
        determined[self.free_idx] = ~in_null[:self.n_free]
        files = []
        pred = self.observed - sol.r / w
        for m, so in zip(self.mms, self.obs_slices):
            resid = (m.observed - pred[so]) * m.obs_unit_scale
            files.append(FileResiduals(m.tag, str(m.data.path), m.kind, m.obs_row.copy(),
                                       np.asarray(m.data.row)[m.obs_row], np.asarray(m.obs_column),
                                       resid, w[so]))
        # a penalised fit spends its effective degrees of freedom, not its rank
        dof = max(self.n_obs - (sol.edf if np.isfinite(sol.edf) else sol.rank), 0)
        cost = float(sol.r @ sol.r)
        res = IdentificationResult(
            model=model, specs=model.param_specs, values=values, std_errors=std, free=self.mask.copy(),
            determined=determined, nuisance_specs=nuis_specs, nuisance_values=sol.x[self.n_free:].copy(),
            nuisance_std_errors=se[self.n_free:].copy(), unknown_names=unknown_names, covariance=cov,
            undetermined=combos, rank=sol.rank, condition_number=sol.cond, singular_values=sol.sv,
            files=files, n_obs=self.n_obs, n_params=self.n_unknowns, dof=dof,
            sigma=float(np.sqrt(cost / dof)) if dof else float("nan"), iterations=sol.iterations,
            converged=sol.converged, cost=cost, seconds=seconds, weighting=label, info=dict(info or {}))
        if self.smoothing is not None:
            res.smoothing = self.smoothing
        params = ParameterSet(model.param_specs, values, std)
        nf = self.n_free
        null_p = (sol.scale[:, None] * sol.null)[:nf]
        # directions that trade machine errors against a file's set-up (a constant against a laser
        # zero ...) change readings only as a set-up would: predictions "up to the set-up" do not
        # depend on them. Only directions among machine parameters alone leave predictions open.
        keep = np.linalg.norm(sol.null[nf:], axis=0) < 1e-6
        if self.metric is not None and null_p.shape[1]:
            # each direction scaled to 1 um rms tool-tip error over the travel; those that move the
            # tip nowhere (a turn about the tool axis ...) cannot change a prediction and are dropped
            rms = np.sqrt(np.clip(np.einsum("ik,ij,jk->k", null_p, self.metric[:nf, :nf], null_p), 0.0, None))
            keep &= rms > 1e-12 * np.linalg.norm(null_p, axis=0)
            null_p = null_p * (1e-3 / np.where(rms > 0, rms, 1.0))
        else:
            keep &= np.linalg.norm(null_p, axis=0) > 0
        uncertainty = {"names": tuple(model.param_names[i] for i in self.free_idx),
                       "covariance": np.nan_to_num(sol.cov[:nf, :nf]), "undetermined": null_p[:, keep]}
        res.fitted_model = FittedModel(model, params, dict(ctx_defaults),
                                       {"identify": res.to_dict(), **(info or {})},
                                       uncertainty=uncertainty)
        return res


def _error_scales(columns) -> np.ndarray:
    """(n,) :func:`error_scale` of each column name (computed once per distinct name)."""
    columns = np.asarray(columns, dtype=object)
    out = np.empty(columns.shape[0])
    for name in set(columns.tolist()):
        out[columns == name] = error_scale(name)
    return out


def _column_scale(A: np.ndarray) -> np.ndarray:
    """1 / sqrt(diag A): unit columns for the eigen-analysis. A column at round-off level (below
    1e-9 of the largest: a straightness no file measures, seen only through the rounding of the
    chain) keeps scale 1, so that it stays at zero size and counts as undetermined; scaled to unit
    norm, its round-off would pass for information and the step would follow it to 1e12."""
    norms = np.sqrt(np.clip(np.diag(A), 0.0, None))
    real = _seen_columns(A)
    return np.where(real, 1.0 / np.where(real, norms, 1.0), 1.0)


def _eliminate(S: np.ndarray, drop: np.ndarray) -> np.ndarray:
    """The penalty S with the coefficients ``drop`` left free: the Schur complement
    ``S_kk - S_kd S_dd^+ S_dk`` on the others (zero rows and columns for the dropped), the least
    penalty over every value of theirs. Cutting them out instead would price the kept ones as if the
    dropped were 0, and a straight line through the kept ones would cost something."""
    if not drop.any():
        return S
    keep = ~drop
    out = np.zeros_like(S)
    Skd = S[np.ix_(keep, drop)]
    out[np.ix_(keep, keep)] = S[np.ix_(keep, keep)] - Skd @ np.linalg.pinv(S[np.ix_(drop, drop)]) @ Skd.T
    return out


def _seen_columns(A: np.ndarray) -> np.ndarray:
    """(n,) bool: the unknowns the data see at all, columns of the normal matrix A above round-off
    (1e-9 of the largest column norm)."""
    norms = np.sqrt(np.clip(np.diag(A), 0.0, None))
    return norms > 1e-9 * max(float(norms.max()) if norms.size else 0.0, 1e-300)


def _relative_singular_values(As: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(relative singular values s / s_max descending, eigenvectors) of a scaled normal matrix."""
    evals, V = np.linalg.eigh(As)
    order = np.argsort(evals)[::-1]
    evals, V = evals[order], V[:, order]
    sv = np.sqrt(np.clip(evals, 0.0, None))
    s_max = sv[0] if sv.size and sv[0] > 0 else 1.0
    return sv / s_max, V


def _gram(J: np.ndarray) -> np.ndarray:
    """J^T J with BLAS syrk (half the work of a general product)."""
    if J.dtype == np.float64 and J.flags.c_contiguous and J.shape[0] > 4 * J.shape[1]:
        from scipy.linalg.blas import dsyrk
        upper = dsyrk(1.0, J.T, trans=0, lower=0)      # J.T is Fortran-ordered: no copy
        return np.triu(upper) + np.triu(upper, 1).T
    return J.T @ J


def _solver(AB):
    """A function gs_B -> (AB)^-1 gs_B for the reduced normal matrix: its Cholesky factor, formed
    once and used by every step that shares AB (the pseudo-inverse where round-off at the edge of
    the rank makes AB not quite positive definite)."""
    if AB.shape[0] == 0:
        return lambda v: v
    try:
        cho = scipy.linalg.cho_factor(AB)
        return lambda v: scipy.linalg.cho_solve(cho, v)
    except np.linalg.LinAlgError:
        pinv = scipy.linalg.pinvh(AB)
        return lambda v: pinv @ v


def _step(B, solve, gs):
    """Scaled Gauss-Newton step restricted to span(B): B (B^T As B)^-1 B^T gs, with ``solve`` from
    :func:`_solver`."""
    return B @ solve(B.T @ gs)


def _name_null_space(null, scale, to_file, names, svals) -> list[UndeterminedCombination]:
    """Readable basis of the null space: pivoted so that each direction has one leading unknown.

    null : (n, k) orthonormal null directions in scaled coordinates. A step ``D v`` of the unknowns
    (internal units) is ``D v * to_file`` in file units.
    """
    k = null.shape[1]
    if k == 0:
        return []
    # pivot on the unknowns with the largest weight (in scaled coordinates, where weights compare)
    _, _, piv = scipy.linalg.qr(null.T, pivoting=True)
    piv = piv[:k]
    M = null[piv, :]                                   # (k, k)
    basis_scaled = null @ np.linalg.solve(M, np.eye(k))   # 1 at its own pivot, 0 at the others
    out = []
    for j in range(k):
        v = basis_scaled[:, j]
        big = np.abs(v) >= NAME_SHARE * np.abs(v).max()
        f = v * scale * to_file
        pivot = piv[j]
        idx = [pivot] + [i for i in np.flatnonzero(big) if i != pivot]
        coef = f / f[pivot]
        out.append(UndeterminedCombination([(names[i], float(coef[i])) for i in idx],
                                           float(svals[j]) if j < len(svals) else 0.0))
    return out


# ------------------------------------------------------------------------------------- predict
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

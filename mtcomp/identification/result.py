"""The one result type of a fit (:func:`mtcomp.identification.fit.solve`, what identify, diagnose's
base fit and thermal's drift fit return): :class:`FitResult` (values, standard errors, covariance,
undetermined combinations, residuals per file, the figures of lmfit's MinimizerResult, a readable
summary and an F test against an extension), with :class:`FileResiduals` and
:class:`UndeterminedCombination`; the error units of reading columns."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..models.chain import ErrorModel
from ..models.model_file import FittedModel
from ..models.params import ParameterSet, ParamSpec


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


#: what 'undeterm.' in the parameter table means, beside the component table's ranges
_UNDETERMINED_LEGEND = [
    "undeterm.: part of a combination the data alone leave open (listed below); the value is where "
    "the fit holds it (the least",
    "  predicted error, the components no laser file names at zero), not a measurement. A "
    "component's range in the table above",
    "  is still given where such combinations move it only through a component held at zero (a "
    "positioning error beside",
    "  the pitch no laser file names, on one plane): it is determined on that assumption; a value "
    "printed 'not determined'",
    "  there is not"]


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
class FitResult:
    """What a fit returns (values in internal units; ``summary()`` prints file units), in the manner
    of lmfit's MinimizerResult: ``params`` (value, stderr, vary of every model parameter),
    ``covar``, ``ndata``, ``nvarys`` (the effective number of parameters), ``nfree``, ``chisqr``,
    ``redchi``, ``aic``, ``bic``.

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
    directions : (n_unknowns, r) the directions of the unknowns (internal units) the fit moved in:
        what the data (and, for a penalised fit, the penalty) determine; the rest was held.
    residual : (n_obs,) weighted residuals at the solution (in units of the weights).
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
    directions: np.ndarray = None
    residual: np.ndarray = None
    #: (k,) standard errors (um of rms tool-tip error over the data's region) of the combinations
    #: the data fix only weakly, held at the least error; their variance is in ``covariance``
    held_sd_um: np.ndarray = field(default_factory=lambda: np.zeros(0))
    #: how many more held combinations only split readings between a component a laser file names
    #: and one none names: held at zero by the assumption that those are zero, with no variance
    held_assumed: int = 0
    #: a fit that did not converge: {"moved": [(name, step in its file unit, unit, step in standard
    #: errors)] of the unknowns its last step moved most, "share": the share of the weighted residual
    #: sum that step took}; None when it converged
    unsettled: dict = None
    #: {class: noise}: the residual standard deviation the covariance takes for each class of readings
    #: (um, urad or um/min; under weights "noise" or given per file, each file's: "tag unit"); the
    #: weights' noise times the posterior's sqrt(s2)
    noise: dict = field(default_factory=dict)

    def _held_lines(self) -> list[str]:
        """The summary's sentences on the combinations held because the data fix them weakly."""
        lines = []
        if self.held_sd_um.size:
            lo, hi = float(np.min(self.held_sd_um)), float(np.max(self.held_sd_um))
            lines.append(f"{self.held_sd_um.size} combination(s) the data fix only weakly are held at the "
                         f"least error (standard error {lo:.2g} to {hi:.2g} um of rms tool-tip error over the "
                         "region the data cover, with the components no laser file names at zero); every "
                         "+- and standard error includes their variance")
        if self.held_assumed:
            lines.append(f"{self.held_assumed} more only split readings between a component a laser file "
                         "names and one none names: held at zero by that assumption, with no variance")
        if "open_weak" in self.info:            # mtcomp.identification._weak.open_note
            lines.append(self.info["open_weak"])
        if "sparse" in self.info:               # mtcomp.identification._sparse.sparse_note
            lines.append(self.info["sparse"])
        if "unread_offsets" in self.info:       # mtcomp.identification._offsets
            lines.append(self.info["unread_offsets"])
        for key in ("bar_scale", "frame_shift"):        # mtcomp.identification._traded
            if key in self.info:
                lines.append(self.info[key])
        return lines

    # ------------------------------------------------------------ lmfit's MinimizerResult figures
    @property
    def params(self) -> ParameterSet:
        """The model's parameters: value, stderr (NaN where held or undetermined), vary (fitted)."""
        return ParameterSet(self.specs, self.values, self.std_errors, vary=self.free)

    @property
    def nuisance(self) -> ParameterSet:
        """The files' set-up (nuisance) parameters, all varied."""
        return ParameterSet(self.nuisance_specs, self.nuisance_values, self.nuisance_std_errors,
                            vary=np.ones(len(self.nuisance_specs), dtype=bool))

    @property
    def var_names(self) -> tuple[str, ...]:
        return self.unknown_names

    @property
    def covar(self) -> np.ndarray:
        return self.covariance

    @property
    def ndata(self) -> int:
        return self.n_obs

    @property
    def nfree(self) -> float:
        """Degrees of freedom left: ndata - nvarys."""
        return self.dof

    @property
    def nvarys(self) -> float:
        """The effective number of parameters: the rank, or for a penalised fit the trace of its hat
        matrix."""
        return float(self.n_obs - self.dof)

    @property
    def chisqr(self) -> float:
        """Weighted residual sum of squares."""
        return self.cost

    @property
    def redchi(self) -> float:
        return self.cost / self.dof if self.dof > 0 else float("nan")

    @property
    def success(self) -> bool:
        return self.converged

    @property
    def aic(self) -> float:
        """Akaike's criterion as lmfit writes it: ndata ln(chisqr / ndata) + 2 nvarys."""
        n = self.n_obs
        return float(n * np.log(max(self.cost, 1e-300) / n) + 2.0 * self.nvarys)

    @property
    def bic(self) -> float:
        """Bayesian criterion as lmfit writes it: ndata ln(chisqr / ndata) + ln(ndata) nvarys."""
        n = self.n_obs
        return float(n * np.log(max(self.cost, 1e-300) / n) + np.log(n) * self.nvarys)

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

    def compare(self, extended: "FitResult") -> dict:
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
                "noise": {k: _finite(v) for k, v in self.noise.items()},
                "undetermined": [str(u) for u in self.undetermined],
                "files": [{"tag": f.tag, "path": f.path, "kind": f.kind, "n_obs": f.n_obs,
                           "rms": {c: _finite(v) for c, v in f.rms().items()}} for f in self.files],
                "nuisance": {s.name: {"value": float(v * s.to_file), "std_error": _finite(e * s.to_file),
                                      "unit": s.unit}
                             for s, v, e in zip(self.nuisance_specs, self.nuisance_values,
                                                self.nuisance_std_errors)}}

    def summary(self, verbose: bool = True, components=(), targets=()) -> str:
        """A report a person can read: the fit's figures, ``components`` (lines: the error components
        in a metrologist's terms, mtcomp.identification.report), the rms residual of every file,
        ``targets`` (lines: laser readings per target) and, with ``verbose``, every parameter with
        value +- std error (file units), the nuisance parameters and the combinations the data cannot
        determine (without it, their count)."""
        m = self.model.machine
        lines = [f"Identification of {m.name} ({m.topology}): {self.n_obs} observations in "
                 f"{len(self.files)} file(s), {self.n_params} unknowns, rank {self.rank}, dof {self.dof:.1f}",
                 f"weighting {self.weighting}; sigma {self.sigma:.4g}; condition number "
                 f"{self.condition_number:.3g}; {self.iterations} iteration(s)"
                 f"{'' if self.converged else ' (NOT converged)'}; {self.seconds:.2f} s"]
        if self.noise and self.weighting != "unit (um, urad)":
            lines.append("noise the standard errors take (residual sd, degrees of freedom counted): "
                         + ", ".join(f"{k} {v:.3g}" for k, v in self.noise.items()))
        lines.append("")
        if components:
            lines += list(components) + [""]
        lines.append(f"{'file':<24} {'kind':<8} {'n_obs':>7}  rms residual")
        for f in self.files:
            rms = ", ".join(f"{c} {v:.4g}" + (f" ({v * 1e3:.4g} um)" if c.endswith("_mm") else "")
                            for c, v in f.rms().items())
            lines.append(f"{f.tag:<24} {f.kind:<8} {f.n_obs:>7}  {rms}")
        if targets:
            lines += [""] + list(targets)
        lines.append("")
        lines += self._held_lines()
        if verbose:
            lines += self._parameter_lines()
        elif self.undetermined:
            lines += [f"{len(self.undetermined)} combination(s) of parameters the data cannot "
                      "determine are held where they predict the least error",
                      "(--verbose lists them, with every parameter's value)"]
        else:
            lines.append("every fitted parameter is determined by the data (--verbose lists them)")
        while lines and not lines[-1]:
            lines.pop()
        return "\n".join(lines)

    def _parameter_lines(self) -> list[str]:
        """Parameters with value +- std error (file units), the nuisance parameters, the undetermined
        combinations and the strongest correlations."""
        lines = [f"{'parameter':<28} {'value':>12} {'std error':>11}  unit"]
        for i, s in enumerate(self.specs):
            if not self.free[i]:
                continue
            v = self.values[i] * s.to_file
            if self.determined[i]:
                e = f"{self.std_errors[i] * s.to_file:11.4g}"
            else:
                e = f"{'undeterm.':>11}"
            lines.append(f"{s.name:<28} {v:12.5g} {e}  {s.unit}")
        if np.any(self.free & ~self.determined):
            lines += _UNDETERMINED_LEGEND
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
            lines.append(f"{len(self.undetermined)} combination(s) the data cannot determine (held where "
                         "they predict the least error; file units):")
            for u in self.undetermined:
                lines.append(f"  {u}")
        else:
            lines.append("every fitted parameter is determined by the data")
        if "weak_directions" in self.info:
            lines.append(f"weakly determined combinations {self.info['weak_directions']}")
        corr = self.largest_correlations()
        if corr:
            lines.append("strongest correlations: " + ", ".join(f"{a}/{b} {r:+.3f}" for a, b, r in corr))
        return lines


def unsettled_parameters(sol, se, specs, n: int = 3) -> dict | None:
    """:attr:`FitResult.unsettled` of a fit's solution ``sol`` (its ``unsettled``: the last step of
    the unknowns, internal units, and the share of the cost it took; None when it converged), with
    the unknowns' standard errors ``se`` (internal units, NaN where undetermined) and ``specs``: the
    ``n`` unknowns that step moved most against their standard errors (by size where none has one)."""
    if sol.unsettled is None:
        return None
    dx, share = sol.unsettled
    ok = np.isfinite(se) & (se > 0)
    size = np.where(ok, np.abs(dx) / np.where(ok, se, 1.0), 0.0) if ok.any() else np.abs(dx)
    order = [int(i) for i in np.argsort(-size)[:n] if size[i] > 0]
    moved = [(specs[i].name, float(dx[i] * specs[i].to_file), specs[i].unit,
              float(abs(dx[i]) / se[i]) if ok[i] else float("nan")) for i in order]
    return {"moved": moved, "share": float(share)}

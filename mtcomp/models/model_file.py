"""MODEL.json: one file that identify, diagnose, compensate, predict and render share.

Layout (file units: um, urad, mm; docs/identification.md, "MODEL.json")::

    {"format": "mtcomp-model", "version": 2,
     "machine": {... the machine description, as in its TOML ...},
     "terms": [{"kind": "backlash", "axis": "X"}, ...],        # extension terms, in order
     "parameters": {"EXX_1": {"value": 1.2, "unit": "um", "group": "X:EXX", "base": true,
                              "std_error": 0.1}, ...},
     "context_defaults": {"temp_t1": 21.0},                   # optional
     "support": {"X": [-20.0, 20.0], "C": [-180.0, 180.0]},   # optional: where the data reach
     "held": {"Y": 50.0, "Z": -40.0},                         # optional: axes the data held still
     "info": {...}}                                           # free: fit summary, provenance

``support`` is the identified region: for each axis that moved in the fitted data, the lowest and
highest position it took (mm, deg). An axis not listed never moved in the data (or stood at one
position): what its errors are is not known, and the model holds them at zero. A model without ``support`` (written by hand, or by
an older mtcomp) claims nothing about its region.

``held`` names the axes every fitted file held at one and the same position (mm, deg), among those
whose errors the fit identified (an axis whose errors were all held is left out): the static
axes of laser runs, the Z of points on one plane. How the errors change along such an axis is not
known, so the model is evaluated at that position wherever it is used for a correction: what was
measured there is applied along the whole axis (as a pitch table from a laser run is), and nothing
is extrapolated from it. A held rotary axis instead bounds the model like ``support``: blocks at
another angle are not corrected (the errors measured at one angle of a table say nothing at another).
"""
from __future__ import annotations

import json
import os
import re
from dataclasses import dataclass, field, replace

import numpy as np

from .._threads import one_blas_thread
from ..errors import InputError
from ..io.atomic import atomic_write
from ..machine import Machine, machine_from_dict
from .chain import ErrorModel
from .params import ParameterSet
from .terms import ChannelDrift, ThermalDrift, motion_pair, term_from_dict

FORMAT = "mtcomp-model"
#: 2: a radial or tilt pair's first harmonic is its counter-rotating motion, on the leader (EXC_c1 ...)
VERSION = 2

#: a prediction (um or urad) that moves by more than this along a direction the model's data left
#: undetermined (at the size of 1 um rms tool-tip error over the travel) rests on it: predict
#: leaves its standard error blank; a correction that moves by more than this with the part of the
#: model's values along those directions is unsure (FittedModel.tip_sd_um)
UNDETERMINED_UM = 0.01


def uncertainty_without(uncertainty: dict | None, names) -> dict | None:
    """A model's ``uncertainty`` (MODEL.json) without the parameters ``names``: their rows and
    columns of the covariance and their rows of the undetermined and held directions left out (the
    marginal of the others)."""
    if uncertainty is None:
        return None
    n = len(uncertainty["names"])
    keep = [k for k, nm in enumerate(uncertainty["names"]) if nm not in names]
    out = dict(uncertainty, names=[uncertainty["names"][k] for k in keep],
               covariance=np.asarray(uncertainty["covariance"])[np.ix_(keep, keep)],
               undetermined=np.asarray(uncertainty["undetermined"]).reshape(n, -1)[keep])
    for key in ("held", "choice", "traded", "open"):
        if key in uncertainty:
            out[key] = np.asarray(uncertainty[key]).reshape(n, -1)[keep]
    if "setup" in uncertainty:
        out["setup"] = dict(uncertainty["setup"], cross=np.asarray(uncertainty["setup"]["cross"])[:, keep])
    if "model_error" in uncertainty:
        out["model_error"] = {k: v for k, v in uncertainty["model_error"].items() if k not in names}
    return out


def setup_uncertainty(specs, cov: np.ndarray, n_params: int) -> dict:
    """The ``setup`` entry of a fit's uncertainty (:class:`FittedModel`): the files' set-up
    parameters ``specs`` (the unknowns after the first ``n_params`` of the covariance ``cov``, internal
    units), their covariance and their covariance with the fitted parameters."""
    return {"names": tuple(s.name for s in specs),
            "to_file": np.array([s.to_file for s in specs], dtype=float),
            "cross": np.nan_to_num(cov[n_params:, :n_params]),
            "covariance": np.nan_to_num(cov[n_params:, n_params:])}


def _columns(rows: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """``rows[:, idx]``, without the copy when ``idx`` takes every column in order (a fitted
    model's covariance usually names every parameter)."""
    if len(idx) == rows.shape[1] and np.array_equal(idx, np.arange(rows.shape[1])):
        return rows
    return rows[:, idx]


@dataclass
class FittedModel:
    """An error model with parameter values: what MODEL.json holds.

    model : the symbolic ErrorModel (machine + extension terms).
    params : ParameterSet on ``model.param_specs`` (internal units).
    context_defaults : values for context channels a data set may lack (e.g. reference temperatures).
    info : free-form provenance (fit summary, command line).
    support : axis name -> (lowest, highest) position the data reached, internal units (mm, rad),
        for the axes the data moved; the others are absent. ``None``: the region is not known.
    held : axis name -> the one position (internal units) at which every fitted file held that axis;
        a correction evaluates the model there (:meth:`clamp`). ``None`` or empty: none.
    uncertainty : None, or what the fit knows of its own precision, internal units:
        ``{"names": (k,) fitted parameter names, "covariance": (k, k), "undetermined": (k, m)}``,
        the covariance of those parameters and the m directions of them the data did not determine
        (moving the parameters along one leaves every fitted reading unchanged), each scaled to the
        size that predicts 1 um rms tool-tip error over the machine's travel; optionally ``"held"``
        (k, h) and ``"held_sd_um"`` (h,): the directions the data fix only weakly, which the fit held
        at the least error (each 1 um rms tool-tip error over the data's region), with their
        standard errors (um). Their variance is already in the covariance: they are listed so that
        its share can be told, and they are not undetermined. Optionally ``"choice"`` (k, c): the
        roughness penalty's split of what the data cannot see across penalty classes, one column
        per alternative split, each one standard error (:mod:`mtcomp.identification._choice`);
        their variance is in the covariance too. Optionally ``"setup"``: the fitted
        files' set-up parameters (laser zeros and slopes, a tracker's frame ...), ``{"names": (s,),
        "to_file": (s,), "cross": (s, k), "covariance": (s, s)}``, their covariance with the
        parameters and their own: a prediction of a fitted file with its fitted set-up moves with
        both (:func:`mtcomp.identification.predict.predict_readings`). Optionally ``"model_error"``:
        {intercept name: sd} of a drift model, the share of its intercept's variance that is the
        model error (what the drift model misses at a reading it was not fitted on), kept apart so
        that a correction, a difference from the datum's state, counts it once (:meth:`at_datum`).
    probed : None, or the drift terms' context (``temp_<s>`` degC, ``spindle_lag_<tau>`` ...) at
        which the part's datum was probed (:func:`mtcomp.thermal.context.probed_state`): the datum's
        deviation then holds the drift at probing. None: the drift terms' own zero (a model whose
        drift corrects nothing). Not saved.
    probed_from_record : True when ``probed`` is no state the user gave but the thermal record's
        reference (its first reading, :func:`mtcomp.thermal.context.record_reference`). Not saved.
    probe_tool_length : mm, the length of the tool (a probe) the part's datum was probed with in X
        and Y (:meth:`at_datum`); None: the machine's tool length. Not saved.
    """

    model: ErrorModel
    params: ParameterSet
    context_defaults: dict = field(default_factory=dict)
    info: dict = field(default_factory=dict)
    support: dict | None = None
    uncertainty: dict | None = None
    held: dict | None = None
    probed: dict | None = None
    probe_tool_length: float | None = None
    probed_from_record: bool = False

    def drift_param_indices(self) -> list[int]:
        """Indices into ``params`` of every drift term's parameters."""
        return [self.params.index(spec.name) for term in self.model.terms
                if isinstance(term, (ThermalDrift, ChannelDrift))
                for spec in term.param_specs(self.machine)]

    def without_drift(self) -> "FittedModel":
        """A copy whose drift terms contribute nothing (their parameters at zero and out of the
        covariance): the model to use where the thermal state is not known, so that no drift is
        corrected and none of its uncertainty counts. ``self`` when it has no drift terms."""
        idx = self.drift_param_indices()
        if not idx:
            return self
        params = self.params.copy()
        params.values[idx] = 0.0
        drift = {self.params.names[i] for i in idx}
        uncertainty = uncertainty_without(self.uncertainty, drift)
        return replace(self, params=params, uncertainty=uncertainty,
                       context_defaults=dict(self.context_defaults))

    def datum_params(self) -> np.ndarray:
        """(n_params,) the values the part's datum was probed with: every drift term's at zero when
        no drift is corrected (:attr:`probed` None), else all of them, the thermal state at probing
        in :meth:`datum_context` (given, or the thermal record's first reading)."""
        p = np.array(self.params.values, dtype=float, copy=True)
        if self.probed is None:
            p[self.drift_param_indices()] = 0.0
        return p

    def datum_context(self, tool_length) -> np.ndarray:
        """(n, n_context) the context the part's datum is probed in: the model's own reference
        conditions (every approach direction unknown, the mean of both; feed 0) with the tool
        lengths ``tool_length`` (n,) mm."""
        tool_length = np.atleast_1d(np.asarray(tool_length, dtype=float))
        c = self.model.default_context(tool_length.shape[0])
        if "tool_length" in self.model.context_names:
            c[:, self.model.context_names.index("tool_length")] = tool_length
        if self.probed is not None:
            # the thermal state at probing; a drift feature it does not give at the value the
            # program runs with (the model's reference unless given)
            names = self.model.context_names
            for f in (f for t in self.model.terms if isinstance(t, ThermalDrift) for f in t.features):
                c[:, names.index(f)] = self.probed.get(f, self.context_defaults.get(f, 0.0))
        return c

    def at_datum(self, name: str, datum, tool_length) -> np.ndarray:
        """The model's function ``name`` (e.g. 'deviation_function') at the part's datum (machine
        positions (n, na) of the program's origin) as it was probed (:meth:`datum_params`,
        :meth:`datum_context`), evaluated where the model is (:meth:`clamp`)."""
        from .evaluate import evaluate
        datum = np.atleast_2d(np.asarray(datum, dtype=float))
        qd, p = self.clamp(datum)[0], self.datum_params()
        out = evaluate(self.model, name, qd, p, self.datum_context(tool_length))[0]
        probe = self.machine.tool_length if self.probe_tool_length is None else self.probe_tool_length
        if not np.all(np.asarray(tool_length, dtype=float) == probe):
            # one datum in X and Y, probed once with the probe's length; each tool set in Z (a tool
            # setter or a touch-off): a tool of another length keeps, across the tool axis, the
            # offset its tip has at the datum from the probe's (docs/planner.md, "One datum")
            probe_ctx = self.datum_context(np.full(datum.shape[0], probe))
            lateral = evaluate(self.model, name, qd, p, probe_ctx)[0]
            out = np.array(out, copy=True)
            out[:, :2] = lateral[:, :2]
        if name.endswith("pjacobian_function") and (self.probed is None or (
                self.probed_from_record and not self.model_error())):
            # with no drift corrected the datum's drift parameters are zero; a model that does not
            # keep its model error apart (an older file) keeps it only in the intercept's variance,
            # which a difference from the record's first reading would cancel: the correction takes
            # the absolute drift's standard error (the parameters' share of the difference is then
            # not the difference's: see model_error_variance)
            out = np.array(out, copy=True)
            out[..., self.drift_param_indices()] = 0.0
        return out

    def model_error(self) -> dict:
        """{intercept parameter name: sd (internal units)} of a drift model's model error
        (``uncertainty["model_error"]``); {} when the model keeps none apart (older files)."""
        return dict((self.uncertainty or {}).get("model_error") or {})

    def model_error_variance(self, J: np.ndarray) -> np.ndarray | None:
        """(n, 3) mm^2: the model error's variance in each tip component of a correction whose
        Jacobian at the block (before the datum's is taken off) is J (n, 3, n_params), counted once:
        the correction is the drift since a known state, the datum's, so the intercept carrying the
        model error cancels and the parameters' share is that of the difference (J - J_datum) C
        (J - J_datum)^T; what the model misses at the block's state is not in it. None when the
        datum's drift Jacobian is not kept (:meth:`at_datum`) or no model error is kept apart."""
        error = self.model_error()
        if self.probed is None or not error:
            return None
        idx = [self.params.index(n) for n in error]
        sd = np.array(list(error.values()), dtype=float)
        return np.einsum("nik,k->ni", J[:, :, idx] ** 2, sd ** 2)

    def datum_deviation(self, datum, tool_length) -> np.ndarray:
        """(n, 3) mm: the tool tip's deviation at the part's datum as it was probed
        (:meth:`at_datum`): what the probed work offset already holds, the reference of every
        correction and error map."""
        return self.at_datum("deviation_function", datum, tool_length)[:, :3]

    def clamp(self, q: np.ndarray) -> tuple[np.ndarray, list[int]]:
        """(q with every held linear axis set to its held position (a copy when any is held), the
        indices of those axes): where the model is evaluated for a correction at poses q (n, n_axes).
        A held rotary axis is not clamped: its angle turns everything it carries, so the errors
        measured at one angle say nothing at another (compensate leaves such blocks uncorrected)."""
        held = {a: v for a, v in (self.held or {}).items() if not self.machine.axis(a).is_rotary}
        if not held:
            return q, []
        q = np.array(q, dtype=float, copy=True)
        cols = [self.machine.index(a) for a in held]
        for a, j in zip(held, cols):
            q[:, j] = held[a]
        return q, cols

    def covariance_factor(self, held: bool = True) -> tuple[np.ndarray, np.ndarray] | None:
        """(indices into ``params``, F) with F F^T the covariance of those parameters (internal
        units), from its positive eigenvalues; None when the model carries no uncertainty. What the
        data left undetermined is not in it: it is held at zero and corrects nothing.

        held : False leaves out the variance of the directions the fit held because the data fix
            them only weakly (``uncertainty["held"]``): the fitted values do not move along them
            whatever the data say, so a correction made from the model has none of that variance
            (it is the error left uncorrected there, which a prediction's standard error counts)."""
        if self.uncertainty is None:
            return None
        idx = np.array([self.params.index(n) for n in self.uncertainty["names"]], dtype=int)
        C = np.nan_to_num(np.asarray(self.uncertainty["covariance"], dtype=float))
        if not held and "held" in self.uncertainty:
            Gs = np.asarray(self.uncertainty["held"], dtype=float).reshape(idx.size, -1)
            Gs = Gs * np.asarray(self.uncertainty["held_sd_um"], dtype=float)[None, :]
            C = C - Gs @ Gs.T
        # decomposed as correlations: parameters in mm and rad differ by 1e6 in their variances, and
        # a relative cut on the raw eigenvalues dropped every angle's variance beside one profile
        # coefficient of 1e4 mm^2 (a printed sd of 0.57 urad where the covariance said 3.43)
        d = np.sqrt(np.clip(np.diag(C), 0.0, None))
        d = np.where(d > 0, d, 1.0)
        w, V = _eigh(0.5 * (C + C.T) / np.outer(d, d))
        keep = w > 1e-12 * max(float(w.max()) if w.size else 0.0, 1e-300)
        return idx, d[:, None] * V[:, keep] * np.sqrt(w[keep])

    def undetermined_values(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(indices into ``params``, (k, 1 + t) v): first the part of the values that lies along the
        directions the data left undetermined (``uncertainty["undetermined"]``), internal units,
        then the directions along which the fit held a machine error by giving a ball bar's
        uncalibrated length what it trades with (``uncertainty["traded"]``, each 1 um rms tool-tip
        error over the travel: :mod:`mtcomp.identification._traded`), and the directions of a
        part's tilts the data leave open (``uncertainty["open"]``, 1 um rms tool-tip error over
        the travel each, :func:`mtcomp.identification._rotation.plate_tilts`); None when the model
        carries no uncertainty or no such direction. A correction that moves along a column rests
        on numbers the data did not determine, or on the fit's choice (:meth:`tip_sd_um`).

        The values are split into what the fit moved (the covariance's range: a fit moves only
        along the directions it determines) and a combination of the undetermined directions; v is
        the latter. identify holds those directions at their start values, zero by default, so v
        is zero (to rounding) for its models: what the data left open corrects nothing. A model
        whose values do lie along them (a start model's, a fit that set them by other means)
        corrects there with numbers no data determined, which its covariance does not see."""
        u = self.uncertainty
        if u is None or not len(u["names"]):
            return None
        idx = np.array([self.params.index(n) for n in u["names"]], dtype=int)
        N = np.asarray(u["undetermined"], dtype=float).reshape(idx.size, -1)
        if not N.shape[1]:
            return None
        f = np.array([self.params.specs[i].to_file for i in idx])       # file units: um, urad
        C = np.nan_to_num(np.asarray(u["covariance"], dtype=float)) * np.outer(f, f)
        d = np.sqrt(np.clip(np.diag(C), 0.0, None))
        d = np.where(d > 0, d, 1.0)
        p, Nf = self.params.values[idx] * f, N * f[:, None]
        with one_blas_thread():
            w, V = np.linalg.eigh(0.5 * (C + C.T) / np.outer(d, d))    # correlations: unit-free
            Q = np.linalg.qr(d[:, None] * V[:, w > 1e-12 * max(float(w.max()), 1e-300)])[0]
            c = np.linalg.lstsq(Nf - Q @ (Q.T @ Nf), p - Q @ (Q.T @ p), rcond=None)[0]
        extra = [np.asarray(u.get(key, np.zeros((idx.size, 0))), dtype=float).reshape(idx.size, -1)
                 for key in ("traded", "open")]
        return idx, np.hstack([((Nf @ c) / f)[:, None], *extra])

    def choice_directions(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(indices into ``params``, (k, c) D): the roughness penalty's alternative splits across
        classes of what the data cannot see (``uncertainty["choice"]``, internal units, each one
        standard error); None when the model keeps none."""
        u = self.uncertainty
        if u is None or "choice" not in u or not len(u["names"]):
            return None
        idx = np.array([self.params.index(n) for n in u["names"]], dtype=int)
        D = np.asarray(u["choice"], dtype=float).reshape(idx.size, -1)
        return (idx, D) if D.shape[1] else None

    @staticmethod
    def tip_sd_um(J: np.ndarray, factor: tuple[np.ndarray, np.ndarray],
                  undetermined: tuple[np.ndarray, np.ndarray] | None = None,
                  extra: np.ndarray | None = None,
                  choice: tuple[np.ndarray, np.ndarray] | None = None,
                  components: bool = False) -> np.ndarray:
        """(n,) the standard error (um) of n tool-tip deviations whose Jacobian with respect to
        ``params`` is J (n, 3, n_params), mm: the largest of the three components' standard
        errors, under the covariance :meth:`covariance_factor` gives (``factor``); (n, 3) each
        component's with ``components``.

        undetermined : :meth:`undetermined_values`; where the deviation moves with that part of the
            values, or along a direction a bar's length trades with, by more than
            :data:`UNDETERMINED_UM`, that component's standard error is infinite: it rests on
            numbers the data did not determine (predict blanks its standard error there, by the
            same rule); the other components keep theirs (the largest is infinite all the same).
        choice : :meth:`choice_directions`; where a component's variance is more the penalty's
            choice of split than the data's, and that choice moves it by more than
            :data:`UNDETERMINED_UM`, that component's standard error is infinite too: it rests on
            how the penalty divided what the data cannot tell apart."""
        n = J.shape[0]
        rows = np.reshape(J, (3 * n, J.shape[2]))   # one matrix product for all rows (BLAS)
        idx, F = factor
        G = _columns(rows, idx) @ F                 # (3 n, rank), mm
        var = np.einsum("ij,ij->i", G, G).reshape(n, 3)
        sd = np.sqrt(var if extra is None else var + extra) * 1e3
        if undetermined is not None:
            ui, v = undetermined
            # per component: a height resting on an open tilt leaves the plane's components known
            moved = np.abs(_columns(rows, ui) @ np.reshape(v, (len(ui), -1)))
            moved = moved.reshape(n, 3, moved.shape[1]).max(axis=2, initial=0.0) * 1e3
            sd[moved > UNDETERMINED_UM] = np.inf
        if choice is not None:
            ci, D = choice
            Gc = _columns(rows, ci) @ D
            cvar = np.einsum("ij,ij->i", Gc, Gc).reshape(n, 3)
            chosen = (np.sqrt(cvar) * 1e3 > UNDETERMINED_UM) & (cvar > var - cvar)
            sd[chosen] = np.inf
        return sd if components else sd.max(axis=1)

    def prediction_std(self, J: np.ndarray) -> np.ndarray:
        """(n,) standard error of n predictions whose Jacobian with respect to ``params`` is J (n,
        n_params), internal units; NaN where a prediction depends on a direction the data did not
        determine, or where the model carries no uncertainty."""
        J = np.atleast_2d(np.asarray(J, dtype=float))
        if self.uncertainty is None:
            return np.full(J.shape[0], np.nan)
        idx = np.array([self.params.index(n) for n in self.uncertainty["names"]], dtype=int)
        Jf = J[:, idx]
        sd = np.sqrt(np.clip(np.einsum("ij,jk,ik->i", Jf, self.uncertainty["covariance"], Jf), 0, None))
        N = self.uncertainty["undetermined"]
        if N.shape[1]:
            # undetermined: a combination the data leave open, at the size of 1 um rms error over the
            # travel, moves the prediction by more than 1 % of that (0.01 um or urad; J is in file
            # units per internal unit)
            along = np.abs(Jf @ N).max(axis=1)
            sd = np.where(along > UNDETERMINED_UM, np.nan, sd)
        return sd

    @property
    def machine(self) -> Machine:
        return self.model.machine

    @classmethod
    def zero(cls, model: ErrorModel) -> "FittedModel":
        return cls(model, ParameterSet(model.param_specs))

    def context(self, n: int, columns: dict | None = None) -> np.ndarray:
        """(n, n_context) block context: given columns, else the model's defaults."""
        c = self.model.default_context(n)
        for i, name in enumerate(self.model.context_names):
            if columns is not None and name in columns:
                col = np.asarray(columns[name], dtype=float)
                c[:, i] = np.where(np.isfinite(col), col, c[:, i])
            elif name in self.context_defaults:
                c[:, i] = self.context_defaults[name]
        return c

    def to_json_dict(self) -> dict:
        return {"format": FORMAT, "version": VERSION, "machine": self.machine.to_dict(),
                "terms": [t.to_dict() for t in self.model.terms],
                "parameters": self.params.to_json_dict(),
                "context_defaults": dict(self.context_defaults),
                **({} if self.support is None else {"support": support_to_file(self.machine, self.support)}),
                **({"held": held_to_file(self.machine, self.held)} if self.held else {}),
                **({} if self.uncertainty is None else {"uncertainty": uncertainty_to_file(self)}),
                "info": self.info}


def _eigh(C: np.ndarray):
    """np.linalg.eigh on one BLAS thread (:func:`mtcomp._threads.one_blas_thread`: a covariance of a
    few hundred parameters is too small for threads to pay; on a busy 2-core machine each
    eigen-decomposition took 0.2 to 2.5 s on several threads, 0.04 s on one)."""
    with one_blas_thread():
        return np.linalg.eigh(C)


def _file_factors(params: ParameterSet, names) -> np.ndarray:
    return np.array([params.specs[params.index(n)].to_file for n in names])


def uncertainty_to_file(fitted: "FittedModel") -> dict:
    """The uncertainty in file units (um, urad ...): covariance f_i f_j C_ij, null directions f_i N_ij."""
    u = fitted.uncertainty
    f = _file_factors(fitted.params, u["names"])
    N = f[:, None] * u["undetermined"]
    out = {"parameters": list(u["names"]), "covariance": (u["covariance"] * np.outer(f, f)).tolist(),
           "undetermined": N.T.tolist()}
    if "held" in u and np.asarray(u["held"]).size:
        out["held"] = (f[:, None] * np.asarray(u["held"])).T.tolist()
        out["held_sd_um"] = np.asarray(u["held_sd_um"], dtype=float).tolist()
    for key in ("choice", "traded", "open"):
        if key in u and np.asarray(u[key]).size:
            out[key] = (f[:, None] * np.asarray(u[key])).T.tolist()
    if u.get("model_error"):
        out["model_error"] = {n: float(v) * float(_file_factors(fitted.params, [n])[0])
                              for n, v in u["model_error"].items()}
    if "setup" in u:
        g = np.asarray(u["setup"]["to_file"], dtype=float)
        out["setup"] = {"parameters": list(u["setup"]["names"]), "to_file": g.tolist(),
                        "cross": (np.asarray(u["setup"]["cross"]) * np.outer(g, f)).tolist(),
                        "covariance": (np.asarray(u["setup"]["covariance"]) * np.outer(g, g)).tolist()}
    return out


def _uncertainty_from_file(params: ParameterSet, data, path) -> dict | None:
    if data is None:
        return None
    try:
        names = [str(n) for n in data["parameters"]]
        cov = np.asarray(data["covariance"], dtype=float).reshape(len(names), len(names))
        null = np.asarray(data["undetermined"], dtype=float).reshape(-1, len(names)).T
    except (KeyError, TypeError, ValueError):
        raise InputError("'uncertainty' must hold 'parameters', a square 'covariance' and "
                         "'undetermined' directions", path) from None
    unknown = [n for n in names if n not in params]
    if unknown:
        raise InputError(f"'uncertainty' names parameter {unknown[0]!r}, which the model lacks", path)
    f = _file_factors(params, names)
    out = {"names": tuple(names), "covariance": cov / np.outer(f, f), "undetermined": null / f[:, None]}
    if "held" in data:      # optional (older files have none): weakly fixed directions, their sd
        try:
            held = np.asarray(data["held"], dtype=float).reshape(-1, len(names)).T
            sd = np.asarray(data["held_sd_um"], dtype=float).reshape(held.shape[1])
        except (KeyError, TypeError, ValueError):
            raise InputError("'uncertainty' 'held' must be directions over its parameters with one "
                             "'held_sd_um' each", path) from None
        out.update(held=held / f[:, None], held_sd_um=sd)
    # optional (older files have none): the penalty's splits across classes; what a bar's
    # uncalibrated length trades with; a part's tilts the data leave open
    for key in ("choice", "traded", "open"):
        if key in data:
            try:
                D = np.asarray(data[key], dtype=float).reshape(-1, len(names)).T
            except (TypeError, ValueError):
                raise InputError(f"'uncertainty' '{key}' must be directions over its parameters", path) from None
            out[key] = D / f[:, None]
    if "model_error" in data:   # optional (older files have none): a drift model's model error
        out["model_error"] = _model_error_from_file(params, data["model_error"], names, path)
    if "setup" in data:     # optional (older files have none): the fitted files' set-ups
        out["setup"] = _setup_from_file(data["setup"], f, path)
    return out


def _model_error_from_file(params: ParameterSet, data, names, path) -> dict:
    try:
        out = {str(n): float(v) for n, v in dict(data).items()}
    except (TypeError, ValueError):
        raise InputError("'uncertainty' 'model_error' must map intercept names to standard errors",
                         path) from None
    bad = [n for n, v in out.items() if n not in names or not np.isfinite(v) or v < 0]
    if bad:
        raise InputError(f"'uncertainty' 'model_error' of {bad[0]!r}: not a parameter of the "
                         "covariance or not a finite standard error >= 0", path)
    return {n: v / float(_file_factors(params, [n])[0]) for n, v in out.items()}


def _setup_from_file(data, f: np.ndarray, path) -> dict:
    try:
        names = tuple(str(n) for n in data["parameters"])
        g = np.asarray(data["to_file"], dtype=float).reshape(len(names))
        cross = np.asarray(data["cross"], dtype=float).reshape(len(names), f.size)
        cov = np.asarray(data["covariance"], dtype=float).reshape(len(names), len(names))
    except (KeyError, TypeError, ValueError):
        raise InputError("'uncertainty' 'setup' must hold 'parameters', 'to_file', 'cross' (one row per "
                         "set-up parameter over the parameters) and a square 'covariance'", path) from None
    if not np.all(g != 0):
        raise InputError("'uncertainty' 'setup' 'to_file' must be non-zero", path)
    for entry, v in (("to_file", g), ("cross", cross), ("covariance", cov)):
        if not np.all(np.isfinite(v)):      # a NaN would blank a standard error for another reason
            raise InputError(f"'uncertainty' 'setup' {entry!r} holds a value that is not a finite "
                             "number", path)
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise InputError(f"'uncertainty' 'setup' 'parameters' names {twice[0]!r} more than once", path)
    return {"names": names, "to_file": g, "cross": cross / np.outer(g, f), "covariance": cov / np.outer(g, g)}


def support_to_file(machine: Machine, support: dict) -> dict:
    """Support in file units (mm, deg), axes in machine order."""
    out = {}
    for a in machine.axis_names:
        if a in support:
            f = 180.0 / np.pi if machine.axis(a).is_rotary else 1.0
            out[a] = [float(support[a][0]) * f, float(support[a][1]) * f]
    return out


def held_to_file(machine: Machine, held: dict) -> dict:
    """Held positions in file units (mm, deg), axes in machine order."""
    return {a: float(held[a]) * (180.0 / np.pi if machine.axis(a).is_rotary else 1.0)
            for a in machine.axis_names if a in held}


def held_from_file(machine: Machine, data, path) -> dict | None:
    """Inverse of :func:`held_to_file`, with checks (InputError naming the key)."""
    if data is None:
        return None
    if not isinstance(data, dict):
        raise InputError("'held' must be an object axis -> position", path)
    out = {}
    for a, v in data.items():
        if a not in machine.axis_names:
            raise InputError(f"'held' names axis {a!r}, which the machine does not have", path)
        if not isinstance(v, (int, float)) or isinstance(v, bool) or not np.isfinite(v):
            raise InputError(f"'held' position of axis {a} must be a number", path)
        out[a] = float(v) * (np.pi / 180.0 if machine.axis(a).is_rotary else 1.0)
    return out


def support_from_file(machine: Machine, data, path) -> dict | None:
    """Inverse of :func:`support_to_file`, with checks (InputError naming the key)."""
    if data is None:
        return None
    if not isinstance(data, dict):
        raise InputError("'support' must be an object axis -> [low, high]", path)
    out = {}
    for a, v in data.items():
        if a not in machine.axis_names:
            raise InputError(f"'support' names axis {a!r}, which the machine does not have", path)
        if (not isinstance(v, list) or len(v) != 2
                or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v)
                or not v[0] <= v[1]):
            raise InputError(f"'support' of axis {a} must be [low, high] with low <= high", path)
        f = np.pi / 180.0 if machine.axis(a).is_rotary else 1.0
        out[a] = (float(v[0]) * f, float(v[1]) * f)
    return out


def save_model(path: str | os.PathLike, fitted: FittedModel) -> None:
    """Write MODEL.json atomically."""
    with atomic_write(path) as f:
        json.dump(fitted.to_json_dict(), f, indent=1, default=_json_default)
        f.write("\n")


def _json_default(o):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"not JSON serialisable: {type(o)}")


def _looks_like_gcode(path: str) -> bool:
    """Whether the file's first lines read as G-code: a G, M or N word, or a '%' or 'O' header."""
    import re
    try:
        with open(path, encoding="latin-1") as f:
            head = [f.readline() for _ in range(20)]
    except OSError:
        return False
    word = re.compile(r"^\s*(%|[OoNn]\d|[GgMm]\d|\(.*\)\s*$)")
    lines = [ln for ln in head if ln.strip()]
    return bool(lines) and sum(bool(word.match(ln)) for ln in lines) >= max(1, len(lines) // 2)


def _refuse_old_first_harmonic(data: dict, p) -> None:
    """A version-1 file (an older mtcomp) that names the first harmonic of a radial or tilt pair's
    leader ('EXC_c1' ...) meant that direction alone; version 2 reads it as the pair's motion turning
    against the axis, which moves the partner too (:func:`mtcomp.models.terms.motion_pair`). Refused,
    not read with another meaning; files without such a parameter are read as before."""
    version = data.get("version", 1)
    if not isinstance(data["parameters"], dict) or (isinstance(version, int) and version >= VERSION):
        return
    for name in data["parameters"]:
        pair = motion_pair(name[:3]) if re.fullmatch(r"E[XYZABC][ABC]_[cs]1", str(name)) else None
        if pair:
            raise InputError(f"parameter {name!r} of a version-{version} model file (an older mtcomp) is "
                             f"a first harmonic of {name[:3]} alone; mtcomp now reads it as the motion "
                             f"turning against the axis, which moves {pair[0]} too: fit the model again "
                             "with identify or diagnose", p)


def load_model(path: str | os.PathLike, machine: Machine | None = None,
               notes: list | None = None) -> FittedModel:
    """Read MODEL.json. With ``machine``, check that the file was made for a machine of that topology
    and the same axes (the machine given on the command line wins for travel and compensation);
    ``notes`` (a list) gets a sentence for the user when the file names another machine."""
    p = os.fspath(path)
    try:
        with open(p, encoding="utf-8") as f:
            data = json.load(f)
    except FileNotFoundError:
        raise InputError("no such model file", p) from None
    except json.JSONDecodeError as exc:
        hint = ""
        if _looks_like_gcode(p):
            hint = ("; it looks like a G-code program: the model file (from identify or diagnose) "
                    "comes before the program")
        what = exc.msg.removesuffix(" at")             # json's "Invalid control character at"
        raise InputError(f"not valid JSON at line {exc.lineno}, column {exc.colno}: {what}{hint}",
                         p) from None
    except UnicodeDecodeError:
        raise InputError("not a text file", p) from None
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise InputError(f"not an mtcomp model file (expected \"format\": \"{FORMAT}\")", p)
    if "machine" not in data or "parameters" not in data:
        raise InputError("model file needs 'machine' and 'parameters'", p)
    _refuse_old_first_harmonic(data, p)
    file_machine = machine_from_dict(data["machine"], path=p)
    if machine is not None:
        if machine.topology != file_machine.topology:
            raise InputError(f"model was made for a {file_machine.topology} machine, not "
                             f"{machine.topology}", p)
        _same_axis_lines(file_machine, machine, p)
        if notes is not None and machine.name != file_machine.name:
            notes.append(f"{p} was made for the machine {file_machine.name!r}; its errors are used "
                         f"on {machine.name!r}, the machine given (its travel, tool length and axis "
                         "points): give the machine the model was made for if that is not meant")
        # travel, tool length and compensation limits: the given machine's; the error-model
        # structure (bases, knots, Fourier orders): the model file's, which its parameters belong to
        axes = tuple(replace(a, travel=b.travel, axis_point=b.axis_point)
                     for a, b in zip(file_machine.axes, machine.axes))
        file_machine = replace(machine, axes=axes)
    terms = tuple(term_from_dict(t, p) for t in data.get("terms", []))
    try:
        model = ErrorModel(file_machine, terms)
    except ValueError as exc:
        raise InputError(f"inconsistent model terms: {exc}", p) from None
    if not isinstance(data["parameters"], dict):
        raise InputError("'parameters' must be an object", p)
    known = set(model.param_names)
    for name in data["parameters"]:
        hint = "" if name in known else older_hint(name)
        if hint:
            raise InputError(f"parameter {name!r} is not part of this model{hint}", p)
    params = ParameterSet(model.param_specs).with_values_from_json(data["parameters"], p)
    std = np.full(len(params), np.nan)
    for name, entry in data["parameters"].items():
        if isinstance(entry, dict) and "std_error" in entry:
            std[params.index(name)] = float(entry["std_error"]) / params.specs[params.index(name)].to_file
    params.std_errors = std
    cd = data.get("context_defaults", {})
    if not isinstance(cd, dict):
        raise InputError("'context_defaults' must be an object", p)
    support = support_from_file(model.machine, data.get("support"), p)
    uncertainty = _uncertainty_from_file(params, data.get("uncertainty"), p)
    held = held_from_file(model.machine, data.get("held"), p)
    return FittedModel(model, params, {str(k): float(v) for k, v in cd.items()}, data.get("info", {}),
                       support, uncertainty, held)


#: how far (mm) a rotary axis's line in the machine file given may lie from the one the model was
#: fitted with: the resolution of the files' values (a line 1 um away moves a turned tip by 1 um)
AXIS_LINE_TOL_MM = 1e-3


def _same_axis_lines(fitted_on, given, path) -> None:
    """InputError, naming both lines and the files, when a rotary axis's line (``axis_point_mm``,
    the control's rotary zero point) in the machine file ``given`` lies more than
    :data:`AXIS_LINE_TOL_MM` from the line of the machine the model was fitted on: the model's
    rotary errors (an axis's offset, its tilt) are deviations from that line, so on another one
    the model predicts, and compensate corrects, errors the machine does not have."""
    for a, b in zip(fitted_on.axes, given.axes):
        if not a.is_rotary:
            continue
        d = np.asarray(b.axis_point, float) - np.asarray(a.axis_point, float)
        apart = float(np.linalg.norm(d - (d @ a.direction) * a.direction))
        if apart > AXIS_LINE_TOL_MM:
            def where(v):
                return f"({', '.join(f'{x:g}' for x in v)}) mm"
            machine_file = f" in {given.source}" if given.source else ""
            raise InputError(f"rotary axis {a.name}: the model was fitted on a machine whose {a.name} "
                             f"axis runs through {where(a.axis_point)}, the machine file"
                             f"{machine_file} puts it through {where(b.axis_point)} ({apart:.4g} mm "
                             "apart): the model's errors of that axis are about its own line; give "
                             "the machine file the model was fitted with, or fit it again on this one",
                             path)


def older_hint(name: str) -> str:
    """Why a model file of an older mtcomp may name a parameter this one lacks: the first harmonic
    of the second direction of a rotary axis's radial or tilt pair ('EYC_c1', 'EBC_s1', 'EZB_c1' ...),
    which an older mtcomp fitted on its own. A pair's first harmonic is now its counter-rotating part
    alone, on the leader (:func:`mtcomp.models.terms.motion_pair`): the part that turned with the axis
    is the axis line's location, and no rule maps the old four without the fit's data."""
    from .terms import ANGLE_LETTERS, TRANSLATION_LETTERS
    m = re.fullmatch(r"E([XYZABC])([ABC])_[cs]1", name)
    if not m or m.group(1) in (m.group(2), TRANSLATION_LETTERS[ANGLE_LETTERS.index(m.group(2))]) \
            or motion_pair(name[:3]) is not None:
        return ""
    lead = next(c for c in (f"E{x}{name[2]}" for x in TRANSLATION_LETTERS + ANGLE_LETTERS)
                if c[1] != name[2] and (motion_pair(c) or ("",))[0] == name[:3])
    return (f" (a first harmonic of {name[:3]} alone, which an older mtcomp wrote: the first harmonic "
            f"of {lead} and {name[:3]} is now their counter-rotating motion alone, {lead}_c1 and "
            f"{lead}_s1; fit the model again with identify or diagnose)")

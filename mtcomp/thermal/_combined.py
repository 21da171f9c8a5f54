"""`diagnose` of a thermal record beside geometric files: one report and one model.

The two are diagnosed on their own paths and joined. The geometric files (laser, points, ballbar ...)
go through the general search of :func:`mtcomp.diagnose.diagnose`, exactly as without the record;
the record goes through :func:`diagnose_thermal` (drift models validated forward in time). A fixed
set-up's drift record says nothing about the geometry of the axes, and tens of thousands of drift
readings, stacked with a hundred laser readings in one search, would drown their findings (an X
backlash of 6 um was lost that way on the 46 h spindle record); each path judges its own data.

The model is the geometric model plus the drift terms (``ThermalDrift`` on the tool tip for the
channels that read a machine axis, ``ChannelDrift`` for the others), their covariances side by side
(the two fits share no data), the record's temperature means as the context defaults, its ranges
in ``info["context_ranges"]`` and its first reading in ``info["thermal_first_reading"]``.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..diagnose.result import Diagnosis
from ..errors import InputError
from ..models.chain import ErrorModel
from ..models.model_file import FittedModel, uncertainty_without
from ..models.params import ParameterSet
from ._diagnose import channel_axes_for, declared_channel_axes, diagnose_thermal

#: the record's keys that ``info`` takes from the thermal diagnosis's model
_THERMAL_INFO = ("drift_features", "time_constants_s", "context_ranges", "thermal_first_reading")


@dataclass
class RecordDiagnosis(Diagnosis):
    """A :class:`~mtcomp.diagnose.result.Diagnosis` of geometric files and a thermal record;
    ``record``: the record's own verdict, noise, base, final and held-out scheme (REPORT.json's
    ``thermal``)."""

    record: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {**super().to_dict(), "thermal": self.record}


def diagnose_with_record(machine, datasets, channel_axes: dict | None = None, progress=None, start=None,
                         known_setup=()):
    """Diagnosis (mtcomp.diagnose.result.Diagnosis) of exactly one thermal file among geometric ones.

    channel_axes : channel -> machine axis (X, Y, Z), beside the record's own ``axis_<name>`` columns.
    start : the start model of the geometric diagnosis (``--start``).
    The report's ``base`` and ``final`` are the geometric files'; ``findings`` holds the geometric
    findings, then the record's; ``thermal`` (REPORT.json) the record's own base, final and noise.
    InputError when the data are not one thermal file and at least one other."""
    from ..diagnose import diagnose
    t0 = time.perf_counter()
    say = progress or (lambda s: None)
    records = [d for d in datasets if d.kind == "thermal"]
    geometric = [d for d in datasets if d.kind != "thermal"]
    if len(records) != 1 or not geometric:
        raise InputError("a thermal record beside geometric files: give one thermal file and at least "
                         "one other")
    record = records[0]
    # the channels' axes are checked before the long geometric search
    channel_axes_for(list(record.channels), channel_axes, record.path, declared_channel_axes(record))
    name = Path(str(record.path)).name
    say(f"geometric files ({len(geometric)}): the general search, without the thermal record")
    geo = diagnose(machine, geometric, progress=progress, start=start, known_setup=known_setup)
    say(f"thermal record {name}: drift models validated forward in time")
    th = diagnose_thermal(machine, record, channel_axes, progress)
    dropped = _runs_own_drift(geo, th.model)
    model = _joined_model(geo.model, th.model, record.path, dropped)
    verdicts = {geo.verdict, th.verdict}
    verdict = next(v for v in ("unexplained", "explained", "none") if v in verdicts)
    reference = dict(th.reference) if th.reference.get("linear_regression_all_temperatures") else {}
    reference.update(geo.reference)
    record_report = {"file": str(record.path), **{k: v for k, v in th.to_dict().items()
                                                  if k in ("verdict", "noise_um", "base", "final", "heldout")}}
    diag = RecordDiagnosis(verdict, geo.noise, geo.base, list(geo.findings) + list(th.findings), geo.final,
                           model, f"{geo.folds}; thermal record {name}: {th.folds}", geo.n_obs + th.n_obs,
                           rejected=list(geo.rejected), reference=reference, outliers=list(geo.outliers),
                           thermal=th.thermal, record=record_report)
    diag.seconds = time.perf_counter() - t0
    model.info["diagnose"] = diag.to_dict()
    return diag


def _runs_own_drift(geo: Diagnosis, drift: FittedModel) -> set:
    """The keys of the geometric model's drift terms, which the record's drift replaces in the model
    written, each said in its finding's evidence.

    A drift the geometric search found on its own files (a laser run that drifts with its readings'
    times) is that campaign's drift on that campaign's clock: it belongs in the fit of those files
    (their geometry is fitted net of it), but the model written has one drift of each kind, and the
    record's, validated forward in time on the machine's own record, is the one to predict with
    (two drifts, of the laser runs' spindle and of the record's time, would both correct Z)."""
    kinds = ("thermal_drift", "channel_drift")
    if not any(t.kind in kinds for t in drift.model.terms):
        return set()
    dropped = {t.key() for t in geo.model.model.terms if t.kind in kinds}
    for f in geo.findings:
        c = f.candidate
        if c is not None and any(t.key() in dropped for t in c.terms):
            f.evidence += ("; a drift of these files' readings in their own time: it is fitted with "
                           "them, and the model written carries the thermal record's drift instead")
    return dropped


def _joined_model(geo: FittedModel, drift: FittedModel, record_path, dropped=frozenset()) -> FittedModel:
    """The geometric model (without its terms whose keys are ``dropped``) plus the drift model's
    terms, values, covariance, defaults and ranges."""
    kept = [t for t in geo.model.terms if t.key() not in dropped]
    gone = {ps.name for t in geo.model.terms if t.key() in dropped for ps in t.param_specs(geo.model.machine)}
    terms = kept + list(drift.model.terms)
    try:
        model = ErrorModel(geo.model.machine, terms)
    except ValueError as exc:
        raise InputError(f"the geometric files' own drift and the thermal record's drift cannot be held "
                         f"in one model ({exc}): diagnose the record alone, or the geometric files "
                         "without their time and temperature columns", record_path) from None
    params = ParameterSet(model.param_specs)
    std = np.full(len(params), np.nan)
    # the drift model's base is the machine's default one, all zero: only its drift terms are taken
    drift_names = {ps.name for t in drift.model.terms for ps in t.param_specs(drift.model.machine)}
    for part, names in ((geo, set(geo.params.names) - gone), (drift, drift_names)):
        se = part.params.std_errors
        for i, nm in enumerate(part.params.names):
            if nm in names:
                params[nm] = part.params.values[i]
                if se is not None:
                    std[params.index(nm)] = se[i]
    params.std_errors = std
    info = dict(geo.info)
    info.update({k: drift.info[k] for k in _THERMAL_INFO if k in drift.info})
    info["thermal_record"] = str(record_path)
    return FittedModel(model, params, {**geo.context_defaults, **drift.context_defaults}, info,
                       geo.support, _joined_uncertainty(uncertainty_without(geo.uncertainty, gone),
                                                        drift.uncertainty), geo.held)


def _joined_uncertainty(a: dict | None, b: dict | None) -> dict | None:
    """Two fits on different data: their covariances side by side, the undetermined and held
    directions of each padded with zeros for the other's parameters."""
    if a is None or b is None:
        return a if b is None else b
    import scipy.linalg
    na, nb = len(a["names"]), len(b["names"])
    und = scipy.linalg.block_diag(np.asarray(a["undetermined"]).reshape(na, -1),
                                  np.asarray(b["undetermined"]).reshape(nb, -1))
    out = {"names": tuple(a["names"]) + tuple(b["names"]),
           "covariance": scipy.linalg.block_diag(a["covariance"], b["covariance"]),
           "undetermined": und.reshape(na + nb, -1)}
    if "held" in a or "held" in b:
        # the combinations a fit held where its data fix them only weakly (diagnose's model written
        # where a ball-bar circle leaves its profiles open): their variance stays apart
        held = scipy.linalg.block_diag(np.asarray(a.get("held", np.zeros((na, 0)))).reshape(na, -1),
                                       np.asarray(b.get("held", np.zeros((nb, 0)))).reshape(nb, -1))
        out["held"] = held.reshape(na + nb, -1)
        out["held_sd_um"] = np.concatenate([np.asarray(a.get("held_sd_um", ()), dtype=float),
                                            np.asarray(b.get("held_sd_um", ()), dtype=float)])
    if "open" in a or "open" in b:      # a part's tilts the data leave open: as undetermined
        out["open"] = scipy.linalg.block_diag(*(np.asarray(u.get("open", np.zeros((k, 0)))).reshape(k, -1)
                                                for u, k in ((a, na), (b, nb))))
    if a.get("model_error") or b.get("model_error"):
        out["model_error"] = {**a.get("model_error", {}), **b.get("model_error", {})}
    if "setup" in a or "setup" in b:
        out["setup"] = _joined_setup(a, b)
    return out


def _joined_setup(a: dict, b: dict) -> dict:
    """The fitted files' set-ups of two fits on different data (the ``setup`` entry of
    :class:`mtcomp.models.model_file.FittedModel`'s uncertainty) side by side: a set-up's covariance
    with the other fit's parameters and set-ups is zero. Without it a fitted laser file beside a
    thermal record was predicted with the parameters' share of its standard error alone, which
    leaves out its zero's variance (docs/identification.md)."""
    import scipy.linalg
    na, nb = len(a["names"]), len(b["names"])
    empty = {"names": (), "to_file": np.zeros(0), "cross": np.zeros((0, 0)), "covariance": np.zeros((0, 0))}
    sa, sb = a.get("setup", empty), b.get("setup", empty)
    ka, kb = len(sa["names"]), len(sb["names"])
    return {"names": tuple(sa["names"]) + tuple(sb["names"]),
            "to_file": np.concatenate([np.asarray(sa["to_file"], dtype=float),
                                       np.asarray(sb["to_file"], dtype=float)]),
            "cross": scipy.linalg.block_diag(np.asarray(sa["cross"], dtype=float).reshape(ka, na),
                                             np.asarray(sb["cross"], dtype=float).reshape(kb, nb)),
            "covariance": scipy.linalg.block_diag(np.asarray(sa["covariance"], dtype=float).reshape(ka, ka),
                                                  np.asarray(sb["covariance"], dtype=float).reshape(kb, kb))}

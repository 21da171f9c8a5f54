"""What a diagnosis returns: :class:`Finding` (one entry of the report) and :class:`Diagnosis` (the
report, docs/diagnose.md, and the extended model). Low in the package so that the thermal diagnosis
(mtcomp.thermal) returns the same types without importing the geometric diagnosis."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..models.model_file import FittedModel

if TYPE_CHECKING:
    from ._candidates import Candidate

#: REPORT.json's key suffix of each error unit
UNIT_KEYS = {"um": "um", "urad": "urad", "um/min": "um_min"}


@dataclass
class Finding:
    """One entry of the report's ``findings`` (docs/diagnose.md): effect, axis, params, evidence, held-out rms
    before and after (in ``unit``: um, or urad when the data hold no positions). ``candidate`` is the
    extension chosen: None for ``unexplained``, except where the model holds a term whose rival the
    data do not tell apart (``rival_alike``)."""

    effect: str
    axis: str
    params: dict
    evidence: str
    heldout_rms_before: float
    heldout_rms_after: float
    candidate: Candidate | None = None
    step: tuple | None = None
    unit: str = "um"
    #: "effect axis" of a rival the data do not tell from this finding (see mtcomp.diagnose._selection._parsimony): the
    #: model holds this finding's term, the report names neither cause
    rival_alike: str = ""

    def to_dict(self) -> dict:
        # the stable keys (docs/diagnose.md) are in um; data without positions keep them (null) and add
        # their own unit's
        out = {"effect": self.effect, "axis": self.axis, "params": self.params, "evidence": self.evidence,
               "heldout_rms_before_um": None, "heldout_rms_after_um": None}
        key = UNIT_KEYS.get(self.unit, self.unit)
        out[f"heldout_rms_before_{key}"] = _r(self.heldout_rms_before)
        out[f"heldout_rms_after_{key}"] = _r(self.heldout_rms_after)
        return out


def _finite(obj):
    """The report with every non-finite number replaced by None (JSON has no NaN)."""
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    if isinstance(obj, (float, np.floating)):
        return float(obj) if np.isfinite(obj) else None
    if isinstance(obj, np.integer):
        return int(obj)
    return obj


def _r(v, nd=4):
    return None if v is None or not np.isfinite(v) else round(float(v), nd)


@dataclass
class Diagnosis:
    """What :func:`diagnose` returns: the report (docs/diagnose.md) plus the extended model.

    verdict : 'none', 'explained' or 'unexplained'.
    noise : unit ('um', 'urad') -> :class:`~mtcomp.diagnose._analysis.Noise`.
    base, final : {'n_params', 'rms_um', 'heldout_rms_um', ...}.
    findings : list of :class:`Finding`.
    model : the extended :class:`~mtcomp.models.FittedModel` (base + chosen terms).
    folds : how the held-out data were chosen (one sentence); folds_of_observations : (n_obs,) the
        fold of each observation (files in the order given, rows in file order, columns in order).
    seconds : wall time.
    """

    verdict: str
    noise: dict
    base: dict
    findings: list
    final: dict
    model: FittedModel
    folds: str
    n_obs: int
    seconds: float = 0.0
    rejected: list = field(default_factory=list)
    reference: dict = field(default_factory=dict)
    folds_of_observations: np.ndarray | None = None
    outliers: list = field(default_factory=list)
    thermal: object = None
    #: axis -> [{"effect", "reason"}]: what the data could not test on that axis (._untested)
    untested: dict = field(default_factory=dict)

    @property
    def noise_um(self) -> float:
        """The noise floor of the readings in um (NaN when the data hold none: then ``noise``
        has the urad or um/min floor)."""
        n = self.noise.get("um")
        return float(n.sigma) if n else float("nan")

    def to_dict(self) -> dict:
        """REPORT.json (the stable keys of docs/diagnose.md plus a few more)."""
        noise = {u: {"sigma": _r(n.sigma), "source": n.source, "dof": n.dof, "repeat_groups": n.n_groups,
                     **({"by_series": {k: _r(v) for k, v in n.by_series.items()}}
                        if getattr(n, "by_series", None) else {})}
                 for u, n in self.noise.items()}
        extra = {f"noise_{UNIT_KEYS[u]}": _r(n.sigma) for u, n in self.noise.items() if u != "um"}
        return _finite({"verdict": self.verdict, "noise_um": _r(self.noise_um), **extra,
                        "noise": noise, "base": self.base, "findings": [f.to_dict() for f in self.findings],
                        "final": self.final, "heldout": self.folds, "n_observations": self.n_obs,
                        "rejected": self.rejected, "untested": self.untested, "reference": self.reference,
                        "outliers": [{"file": o.path, "row": o.row, "column": o.column, "value": o.value,
                                      "off_median_of_repeats": o.deviation} for o in self.outliers]})

    def summary(self, details=()) -> str:
        """The printed report: noise, base fit, each finding with evidence and gain, final fit,
        ``details`` (lines: the final model in a metrologist's terms), the verdict."""
        from ._report import summary
        return summary(self, details)

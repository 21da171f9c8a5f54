"""Thermal drift of a fixed set-up over time (ISO 230-3): drift models that carry forward in time,
chosen by forward-chaining validation, written as model terms (docs/thermal.md).

The names below are imported when first asked for: ``mtcomp compensate`` reads a model's thermal
context (:mod:`mtcomp.thermal.context`) and needs none of the fitting, whose imports (scipy's
optimisation and signal packages, diagnose) take longer than a whole compensation of a short program.
"""

_FIT = ("DEFAULT_LAGS_S", "CandidateScore", "Ridge", "ThermalFit", "fit_ridge", "fit_thermal",
        "forward_folds", "forward_sse")

__all__ = [*_FIT, "diagnose_thermal", "RecordDiagnosis", "diagnose_with_record"]


def __getattr__(name):
    if name in _FIT:
        from . import _fit
        return getattr(_fit, name)
    if name == "diagnose_thermal":
        from ._diagnose import diagnose_thermal
        return diagnose_thermal
    if name in ("RecordDiagnosis", "diagnose_with_record"):
        from . import _combined
        return getattr(_combined, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

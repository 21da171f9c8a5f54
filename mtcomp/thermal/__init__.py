"""Thermal drift of a fixed set-up over time (ISO 230-3): drift models that carry forward in time,
chosen by forward-chaining validation, written as model terms (docs/thermal.md)."""
from ._fit import (DEFAULT_LAGS_S, CandidateScore, Ridge, ThermalFit, fit_ridge, fit_thermal,
                   forward_folds, forward_sse)
from ._diagnose import diagnose_thermal
from ._combined import RecordDiagnosis, diagnose_with_record

__all__ = ["DEFAULT_LAGS_S", "CandidateScore", "Ridge", "ThermalFit", "fit_ridge", "fit_thermal",
           "forward_folds", "forward_sse", "diagnose_thermal",
           "RecordDiagnosis", "diagnose_with_record"]

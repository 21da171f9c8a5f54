"""Model discovery (docs/diagnose.md): what the base model gets wrong, why, and what the fix gains.

Public names:

* :func:`diagnose` (machine, datasets) -> :class:`Diagnosis`: residual analysis of the base fit,
  greedy forward selection of extension terms on held-out data, the report (REPORT.json, whose keys
  docs/diagnose.md lists) and the extended model (``Diagnosis.model``, a
  :class:`~mtcomp.models.FittedModel`).
* :class:`Finding`: one entry of the report.
"""
from ._diagnose import Diagnosis, Finding, diagnose

__all__ = ["diagnose", "Diagnosis", "Finding"]

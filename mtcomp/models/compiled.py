"""Compiled evaluation (generated C looped over poses). Placeholder until the C backend lands:
``call`` returns None so that evaluation falls back to CasADi's own map."""
from __future__ import annotations


def call(model, name, function, q, p, c, required=False):
    if required:
        raise RuntimeError("compiled backend not available")
    return None

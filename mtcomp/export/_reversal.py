"""The reversal a model's data show and the model does not hold: one line for export and compensate.

A model from ``mtcomp identify`` has no dependence on the approach direction; MODEL.json records
what its laser data showed of each axis's reversal (``info["reversal"]``,
:func:`mtcomp.identification.reversal.data_reversal`). Where the data show one (p-value below
:data:`~mtcomp.identification.reversal.REVERSAL_P`) and the model has no backlash term on that axis,
its tables and corrections are the same in both directions, and :func:`reversal_note` says so, with
the size per axis and the command that fits it.
"""
from __future__ import annotations

import math

from ..identification.reversal import REVERSAL_P, one_direction_axes, unheld_records


def _number(x) -> float | None:
    return float(x) if isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) else None


def unheld_reversals(fitted) -> dict:
    """axis -> (mean reversal, largest reversal, unit) of every axis whose data show a reversal the
    model does not hold (no backlash term on that axis), file units (um, urad)."""
    out = {}
    for a, r in unheld_records(fitted).items():
        unit = "urad" if fitted.machine.axis(a).is_rotary else "um"
        p, mean, largest = (_number(r.get(k)) for k in ("p_value", f"B_mean_{unit}", f"B_{unit}"))
        if p is not None and mean is not None and largest is not None and p < REVERSAL_P:
            out[a] = (mean, largest, unit)
    return out


def one_direction_note(fitted) -> str | None:
    """One line (no 'note:' prefix) when the model's data read an axis approaching from one side
    only, else None: the reversal there is not measured; compensate leaves the blocks approaching
    from the other side (or a side not known) uncorrected, and export writes that side's column
    without correction where the format keeps the sides apart."""
    axes = one_direction_axes(fitted)
    if not axes:
        return None
    said = ", ".join(f"{a} in {sign} only" for a, sign in axes.items())
    other = ", ".join(f"{a} in {'-' if sign == '+' else '+'}" for a, sign in axes.items())
    return (f"the data read the approach {said}: the reversal (backlash) there is not measured; "
            f"compensate leaves uncorrected the blocks that approach {other}, or from a side not "
            "known, and a table from this model holds the side read: LinuxCNC's COMP_FILE has a "
            "column per side and the other one is written without correction, the other formats' "
            "tables apply it both ways (whatever reversal the axis has stays in the part there); "
            "measure both directions (ISO 230-2 runs are bidirectional) to know it")


def reversal_note(fitted) -> str | None:
    """One line (no trailing newline, no 'note:' prefix) when the data of ``fitted`` (a FittedModel)
    show a reversal the model does not hold, else None: the size per axis (ISO 230-2 mean reversal
    value, and the largest), that the model is the same in both approach directions, and the command
    that fits it; and, for an axis the laser data read from one side only, :func:`one_direction_note`."""
    missing = unheld_reversals(fitted)
    one_side = one_direction_note(fitted)
    if not missing:
        return one_side
    sizes = ", ".join(f"{a} {mean:+.1f} {unit} (largest {largest:+.1f} {unit})"
                      for a, (mean, largest, unit) in missing.items())
    if "diagnose" in fitted.info:
        advice = "mtcomp diagnose did not keep a backlash term for it (its report says why)"
    else:
        advice = ("mtcomp diagnose fits it (a backlash term): `mtcomp diagnose MACHINE DATA... --json "
                  "REPORT.json -o MODEL.json`, then use that model")
    return (f"the data show a reversal (mean up minus mean down, ISO 230-2) that this model does not "
            f"hold: {sizes}; the model, and every table and correction made from it, is the same in "
            f"both approach directions; {advice}" + (f"; {one_side}" if one_side else ""))

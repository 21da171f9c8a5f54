"""The thermal state a program is compensated for: temperatures and spindle speed given on the
command line become the context of the model's drift terms (``temp_<name>`` in degC,
``spindle_lag_<tau>`` / ``spindle_heat_<tau>`` in 1000 rpm at steady state)."""
from __future__ import annotations

import math
import re

from ..errors import InputError

_LAG = re.compile(r"^spindle_(lag|heat)_\d+(\.\d+)?$")


def parse_assignments(items, flag: str) -> dict:
    """['t1=24.5', ...] -> {'t1': 24.5}; InputError naming ``flag`` on a malformed item."""
    out = {}
    for item in items or []:
        name, sep, value = item.partition("=")
        try:
            v = float(value)
        except ValueError:
            v = math.nan
        if not sep or not name or not math.isfinite(v):
            raise InputError(f"{flag} {item!r}: write NAME=VALUE with a number, e.g. t1=24.5")
        out[name] = v
    return out


def thermal_context(fitted, temperatures: dict | None = None, spindle_rpm: float | None = None
                    ) -> tuple[dict, str]:
    """(context values to use, one sentence saying what is assumed) for the drift terms of
    ``fitted`` (a FittedModel). ``temperatures``: sensor name -> degC; ``spindle_rpm``: the speed the
    spindle has run at long enough to reach steady state. Sensors not given keep the model's
    reference (the mean over the thermal record it was fitted on). InputError for a sensor or a
    spindle speed the model does not use."""
    names = fitted.model.context_names
    temps = [n[5:] for n in names if n.startswith("temp_")]
    lags = [n for n in names if _LAG.match(n)]
    out = {}
    for sensor, v in (temperatures or {}).items():
        if sensor not in temps:
            raise InputError(f"--temperature {sensor}: the model has no drift term that reads that "
                             f"sensor (it reads: {', '.join(temps) or 'none'})")
        out[f"temp_{sensor}"] = float(v)
    if spindle_rpm is not None:
        if not math.isfinite(spindle_rpm) or spindle_rpm < 0:
            raise InputError(f"--spindle-rpm must be a speed of 0 or more, got {spindle_rpm:g}")
        if not lags:
            raise InputError("--spindle-rpm: the model has no drift term that reads spindle heat")
        out.update({n: spindle_rpm / 1000.0 for n in lags})
    if not temps and not lags:
        return out, ""
    parts = []
    if temps:
        given = [s for s in temps if f"temp_{s}" in out]
        rest = [s for s in temps if s not in given]
        if given:
            parts.append("temperatures " + ", ".join(f"{s}={out['temp_' + s]:g} degC" for s in given))
        if rest:
            parts.append(f"{'other ' if given else ''}temperatures ({', '.join(rest)}) at the model's "
                         "reference, their mean over the thermal record")
    if lags:
        parts.append(f"spindle heat at steady state of {spindle_rpm:g} rpm" if spindle_rpm is not None
                     else "spindle stopped for long (no spindle heat)")
    return out, "thermal drift assumed: " + "; ".join(parts)

"""Drift features of a measurement file: what its time, temperature and spindle columns give the
error model's drift terms (:class:`~mtcomp.models.ThermalDrift`, :class:`~mtcomp.models.ChannelDrift`).

``time_h`` (t / 3600), ``time_exp_<tau>`` (1 - exp(-t / tau), tau in s: a first-order warm-up),
``dtemp_<name>`` (K, temperature rise over the first reading of the file), ``temp_<name>`` (degC as
read), ``spindle_heat_<tau>`` (spindle speed in 1000 rpm through a first-order lag of time constant
tau seconds, from 0 at the first reading) and ``spindle_lag_<tau>`` (the same, started at the first
reading's speed). Every measurement model fills these context channels from its file
(:func:`mtcomp.measurement.readings.context_matrix`).
"""
from __future__ import annotations

import math
import re
from typing import TYPE_CHECKING

import numpy as np

from .files import Context, MeasurementSet

if TYPE_CHECKING:
    from ..models.chain import ErrorModel

#: default time constants (s) of the spindle heat features
DEFAULT_TIME_CONSTANTS_S = (900.0, 3600.0)
FEATURE_KINDS = ("time", "temperature", "spindle")
_HEAT = re.compile(r"^spindle_heat_(\d+(?:\.\d+)?)$")
_LAG = re.compile(r"^spindle_lag_(\d+(?:\.\d+)?)$")
_TEMP = re.compile(r"^temp_(.+)$")
_DTEMP = re.compile(r"^dtemp_(.+)$")
_TEXP = re.compile(r"^time_exp_(\d+(?:\.\d+)?)$")

def _time_order(t: np.ndarray) -> np.ndarray:
    """Indices of the rows with a finite time, in increasing time (stable)."""
    idx = np.flatnonzero(np.isfinite(t))
    return idx[np.argsort(t[idx], kind="stable")]


def spindle_heat(t: np.ndarray, rpm: np.ndarray, tau_s: float, steady_start: bool = False) -> np.ndarray:
    """(n,) spindle speed (1000 rpm) through a first-order lag of time constant ``tau_s`` (s).

    h' = (rpm/1000 - h) / tau, h = 0 at the first reading (``steady_start``: h = the first reading's
    speed, as if the spindle had run at it for long); the speed is held between readings (exact
    discretisation: h_k = h_{k-1} + (1 - exp(-dt/tau)) (u_{k-1} - h_{k-1})). Rows are processed in time
    order; rows without a time get NaN. A blank speed counts as 0.
    """
    t = np.asarray(t, dtype=float)
    u = np.nan_to_num(np.asarray(rpm, dtype=float)) / 1000.0
    out = np.full(t.shape, np.nan)
    order = _time_order(t)
    h = float(u[order[0]]) if steady_start and order.size else 0.0
    for k, i in enumerate(order):
        if k > 0:
            j = order[k - 1]
            h += (1.0 - math.exp(-(t[i] - t[j]) / tau_s)) * (u[j] - h)
        out[i] = h
    return out


def feature_value(name: str, context: Context, reference_temperatures: dict | None = None):
    """(n,) values of drift feature ``name`` for the rows of ``context``, or None if ``name`` is not a
    drift feature. ``time_h``: h; ``dtemp_<s>``: K above ``reference_temperatures[s]`` or else the
    first reading in time order; ``temp_<s>``: degC as read; ``spindle_heat_<tau>``: 1000 rpm (see
    :func:`spindle_heat`), ``spindle_lag_<tau>`` the same started at the first reading's speed."""
    t = np.asarray(context.t, dtype=float)
    if name == "time_h":
        return t / 3600.0
    m = _TEXP.match(name)
    if m:                                   # warm-up: 1 - exp(-t / tau), tau in s (diagnose)
        return 1.0 - np.exp(-t / float(m.group(1)))
    m = _DTEMP.match(name)
    if m:
        sensor = m.group(1)
        if sensor not in context.temperatures:
            return np.full(t.shape, np.nan)
        temp = np.asarray(context.temperatures[sensor], dtype=float)
        ref = (reference_temperatures or {}).get(sensor)
        if ref is None:
            order = _time_order(t)
            if order.size == 0:
                order = np.arange(len(temp))
            finite = order[np.isfinite(temp[order])]
            ref = temp[finite[0]] if finite.size else np.nan
        return temp - ref
    m = _HEAT.match(name) or _LAG.match(name)
    if m:
        return spindle_heat(t, context.spindle_rpm, float(m.group(1)), steady_start=m.re is _LAG)
    m = _TEMP.match(name)
    if m:
        temp = context.temperatures.get(m.group(1))
        return np.full(t.shape, np.nan) if temp is None else np.asarray(temp, dtype=float)
    return None


def feature_names(context: Context, kinds=FEATURE_KINDS,
                  time_constants_s=DEFAULT_TIME_CONSTANTS_S) -> list[str]:
    """Names of the drift features a file's context supports, for the given kinds."""
    names = []
    has_t = np.isfinite(context.t).any()
    if "time" in kinds and has_t:
        names.append("time_h")
    if "temperature" in kinds:
        names += [f"dtemp_{s}" for s in context.temperatures]
    if "spindle" in kinds and has_t and np.isfinite(context.spindle_rpm).any():
        names += [f"spindle_heat_{tau:g}" for tau in time_constants_s]
    return names


def thermal_features(context: Context, kinds=FEATURE_KINDS, time_constants_s=DEFAULT_TIME_CONSTANTS_S,
                     reference_temperatures: dict | None = None) -> dict[str, np.ndarray]:
    """Drift features of any file with ``t_s`` / ``temp_<name>_c`` / ``spindle_rpm``: name -> (n,).

    kinds : subset of ('time', 'temperature', 'spindle'). time_constants_s : lags of the spindle heat
    states (s). Units: time_h in h, dtemp_<name> in K, spindle_heat_<tau> in 1000 rpm.
    """
    return {name: feature_value(name, context, reference_temperatures)
            for name in feature_names(context, kinds, time_constants_s)}


def drift_context(model: "ErrorModel", data: MeasurementSet, reference_temperatures: dict | None = None
                  ) -> dict[str, np.ndarray]:
    """The drift-feature channels among ``model.context_names`` computed from ``data`` (name -> (n,)),
    for ``context_matrix(..., extra=...)``. NaN where a file lacks the input (the default applies)."""
    out = {}
    for name in model.context_names:
        v = feature_value(name, data.context, reference_temperatures)
        if v is not None:
            out[name] = v
    return out

"""What a thermal file's columns and values say beyond what the reader takes (docs/thermal.md,
docs/measurements.md).

* :func:`check_unit_columns` refuses a displacement channel or a temperature in another unit than
  mtcomp's (``disp_z_mm``, ``temp_head_F``) with no ``disp_z_um`` or ``temp_head_c`` beside it:
  read as a column mtcomp does not read, the channel or the sensor would vanish from the record
  with only a note, and the model would change without it.
* :func:`check_time_order` refuses a thermal record whose ``t_s`` goes back or repeats: a drift
  record is read in time order, and a row out of order is a join or an export gone wrong that
  sorting would hide.
* :func:`thermal_notes` says, per thermal file: readings that all stay within a sensor's noise
  (mm written under ``*_um``), a record shorter than the time constants a drift model uses (``t_s``
  in hours or minutes), a gap in the record, and a temperature column blank in some rows only.
"""
from __future__ import annotations

import re

import numpy as np

from ..errors import InputError
from .units import UM, UNIT_CHECK_FLOOR_UM

#: a displacement channel or a temperature in another unit than mtcomp's (um, degC)
_DISP_OTHER = re.compile(r"^disp_(.+)_(mm|m|cm|nm|in|inch|inches|mil|mils|thou|micron|microns|mu)$")
_TEMP_OTHER = re.compile(r"^temp_(.+)_(f|degf|deg_f|fahrenheit|k|kelvin|degc|deg_c|celsius|deg)$")
#: the least number of readings for these notes: what a drift fit takes (two per block of its
#: forward validation, 6 blocks); a few rows of states given to predict are no record
MIN_RECORD_READINGS = 12
#: a record spanning less than this (s) is shorter than the shortest spindle-heat lag of the combined
#: drift model (docs/thermal.md, 900 s): no drift model follows heat flows slower than the record
SHORTEST_RECORD_S = 900.0
#: a step of t_s longer than this many times the median step is a gap in the record
GAP_FACTOR = 10.0


def check_unit_columns(table) -> None:
    """InputError (row 0, the header) for ``disp_<name>_<unit>`` or ``temp_<name>_<unit>`` in
    another unit than um or degC, with no ``disp_<name>_um`` or ``temp_<name>_c`` beside it."""
    for j, name in enumerate(table.names):
        for pattern, unit, what, suffix in ((_DISP_OTHER, "um", "displacement channel", "um"),
                                            (_TEMP_OTHER, "degC", "temperature sensor", "c")):
            m = pattern.match(name)
            if m is None:
                continue
            column = f"disp_{m.group(1)}_{suffix}" if suffix == "um" else f"temp_{m.group(1)}_{suffix}"
            if column in table.names:
                continue
            given = table.header[j].strip()
            raise InputError(f"column {given}: mtcomp reads {what} {m.group(1)} as {column}, in "
                             f"{unit}, and does not read {given}; convert the values to {unit} and "
                             "rename the column", table.path, row=0)


def check_time_order(table, t: np.ndarray) -> None:
    """InputError naming the first row whose ``t_s`` is not later than the row before's."""
    step = np.diff(t)
    bad = np.flatnonzero(~(step > 0))
    if not bad.size:
        return
    i = int(bad[0]) + 1
    how = ("repeats the row before's" if step[i - 1] == 0
           else f"goes back from {t[i - 1]:.10g} s in the row before")
    table.fail(f"column t_s: {t[i]:.10g} s {how}: a thermal record's readings are in time order, each "
               "later than the one before (sort the rows by t_s, remove a duplicated reading, or "
               "join records in time order)", i)


def thermal_notes(data) -> list[str]:
    """One sentence per finding in a thermal file (module docstring)."""
    if getattr(data, "kind", "") != "thermal" or len(data) < MIN_RECORD_READINGS:
        return []
    t = np.asarray(data.t, dtype=float)
    return [line for line in (_small_drift(data), _short(data, t), _gap(data, t)) if line] \
        + _blank_temperatures(data)


def _small_drift(data) -> str | None:
    Y = np.column_stack([np.asarray(v, dtype=float) for v in data.channels.values()]) / UM
    if not np.isfinite(Y).any():
        return None
    first = np.array([col[np.isfinite(col)][0] if np.isfinite(col).any() else np.nan for col in Y.T])
    change = float(np.nanmax(np.abs(Y - first)))
    if change >= UNIT_CHECK_FLOOR_UM:
        return None
    cols = ", ".join(f"disp_{c}_um" for c in data.channels)
    return (f"{data.path}: every reading ({cols}) stays within {change:.3g} um of the first over "
            f"{np.ptp(data.t) / 3600:.3g} h, below {UNIT_CHECK_FLOOR_UM:g} um, less than a "
            "displacement sensor's noise: were the readings written in mm under *_um columns? if so "
            "multiply them by 1000")


def _short(data, t: np.ndarray) -> str | None:
    span = float(np.ptp(t))
    if not 0 < span < SHORTEST_RECORD_S:
        return None
    return (f"{data.path}: the record spans {span:.4g} s (t_s {t[0]:g} to {t[-1]:g}), shorter than "
            f"the heat flows a drift model follows ({SHORTEST_RECORD_S:g} s and more): was t_s "
            "written in hours or minutes? t_s is seconds")


def _gap(data, t: np.ndarray) -> str | None:
    step = np.diff(t)
    typical = float(np.median(step))
    if not typical > 0:
        return None
    gaps = np.flatnonzero(step > GAP_FACTOR * typical)
    if not gaps.size:
        return None
    i = int(gaps[np.argmax(step[gaps])])
    return (f"{data.path}: {gaps.size} gap(s) in the record, the longest {step[i]:g} s ("
            f"{step[i] / 3600:.3g} h) from t_s {t[i]:g} to {t[i + 1]:g} (rows {int(data.row[i])} to "
            f"{int(data.row[i + 1])}), against a step of {typical:g} s: the spindle's speed is taken "
            "as held through it; check the record for a pause or lost readings")


def _blank_temperatures(data) -> list[str]:
    out = []
    for sensor, v in data.context.temperatures.items():
        blank = np.flatnonzero(~np.isfinite(v))
        if 0 < blank.size < len(v):
            out.append(f"{data.path}: column temp_{sensor}_c is blank at row {int(data.row[blank[0]])}"
                       f" ({blank.size} of {len(v)} readings): diagnose leaves a sensor out of the "
                       f"drift fit unless every reading has it; fill the cell or remove the row to "
                       f"keep sensor {sensor}")
    return out

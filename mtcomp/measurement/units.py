"""The units of the measurement files: internal units (mm, rad, mm/min, s, degC) against the unit a
column name's suffix says, a number as a CSV cell, and a measurement file written back with added
columns (``mtcomp predict``)."""
from __future__ import annotations

import math
import os

import numpy as np

from ..errors import InputError

UM = 1e-3                      #: mm per um
URAD = 1e-6                    #: rad per urad
DEG = math.pi / 180.0          #: rad per deg

#: unit check: readings over positions spanning at least UNIT_CHECK_TRAVEL_MM whose every magnitude
#: stays below max(UNIT_CHECK_FLOOR_UM, UNIT_CHECK_PPM x span) are less than a laser measures
#: reliably over that travel (about 0.5 ppm with air compensation), and less than any machine's error
#: with any instrument's noise there: the values were likely written in mm under a ``*_um`` column
UNIT_CHECK_TRAVEL_MM = 100.0
UNIT_CHECK_FLOOR_UM = 0.05
UNIT_CHECK_PPM = 0.5
#: the same for a rotary axis: targets spanning at least 90 deg, every reading below 0.05 urad
UNIT_CHECK_TRAVEL_DEG = 90.0
UNIT_CHECK_FLOOR_URAD = 0.05

#: column-name suffix -> factor from internal units to file units
_SUFFIX_SCALE = (("_mm_min", 1.0), ("_urad", 1.0 / URAD), ("_um", 1.0 / UM), ("_mm", 1.0),
                 ("_deg", 1.0 / DEG), ("_s", 1.0), ("_c", 1.0), ("_rpm", 1.0))


def file_unit_scale(column: str) -> float:
    """Factor from internal units (mm, rad, mm/min, s, degC) to the unit a column name's suffix says.

    ``dx_um`` -> 1000 (mm to um), ``value_urad`` -> 1e6, ``a_deg`` -> 180/pi, ``x_mm`` -> 1.
    A name with no known unit suffix raises ValueError (a programming error, not bad input).
    """
    for suffix, scale in _SUFFIX_SCALE:
        if column.endswith(suffix):
            return scale
    raise ValueError(f"column name {column!r} carries no known unit suffix "
                     f"({', '.join(s for s, _ in _SUFFIX_SCALE)})")


def format_cell(value: float) -> str:
    """A number for a CSV cell: up to 10 significant digits; NaN -> blank (not measured)."""
    if value is None or not math.isfinite(value):
        return ""
    return f"{value:.10g}"


def write_csv_with_columns(path: str | os.PathLike, data,
                           new_columns: dict[str, np.ndarray], internal_units: bool = True) -> None:
    """Write every input column of ``data`` verbatim, then ``new_columns``, atomically.

    path : the output CSV; refused (InputError) when it is the input file or its folder is missing.
    data : the measurement set (:class:`mtcomp.measurement.files.MeasurementSet`) whose header and
        rows are repeated.
    new_columns : column name -> (n,) values, one per row of ``data``. With ``internal_units`` the
        values are in mm, rad, mm/min, s and are converted by the name's suffix (``pred_dx_um``:
        mm -> um); otherwise they are written as given. NaN is written as a blank cell.
    """
    import csv

    from ..io.atomic import atomic_write, check_output_path

    out = check_output_path(path, [data.path])
    existing = {h.strip().lower() for h in data.header}
    columns = []
    for name, values in new_columns.items():
        if name.lower() in existing:
            raise InputError(f"the input already has a column {name}; cannot add it again", data.path)
        values = np.asarray(values, dtype=float)
        if values.shape != (len(data),):
            raise ValueError(f"column {name}: {values.shape} values for {len(data)} rows")
        columns.append(values * (file_unit_scale(name) if internal_units else 1.0))
    with atomic_write(out, newline="") as f:
        writer = csv.writer(f, lineterminator="\n")
        writer.writerow([*data.header, *new_columns])
        for i, cells in enumerate(data.rows):
            writer.writerow([*cells, *(format_cell(float(c[i])) for c in columns)])


def unit_check(rotary: bool, targets: np.ndarray, value: np.ndarray) -> bool:
    """True when every reading is smaller than an instrument measures over the positions' span, so
    that the values were likely written in mm (rad) under a ``*_um`` (``*_urad``) column
    (docs/iso230_2.md, docs/measurements.md).

    Linear: the targets span at least UNIT_CHECK_TRAVEL_MM and every |value| is below
    max(UNIT_CHECK_FLOOR_UM, UNIT_CHECK_PPM ppm of the span). Rotary: the targets span at least
    UNIT_CHECK_TRAVEL_DEG and every |value| is below UNIT_CHECK_FLOOR_URAD.
    targets : (m,) mm or rad; value : (n,) mm or rad (internal units).
    """
    span = float(np.ptp(targets))
    biggest = float(np.abs(value).max())
    if rotary:
        return math.degrees(span) >= UNIT_CHECK_TRAVEL_DEG and biggest / URAD < UNIT_CHECK_FLOOR_URAD
    return span >= UNIT_CHECK_TRAVEL_MM and biggest / UM < unit_limit_um(span)


def unit_limit_um(span_mm: float) -> float:
    """The largest reading (um) the unit check takes for values in mm, over a span of ``span_mm``."""
    return max(UNIT_CHECK_FLOOR_UM, UNIT_CHECK_PPM * 1e-6 * span_mm / UM)

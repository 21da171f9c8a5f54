"""Beckhoff / ISG TwinCAT CNC, TF5280 volumetric compensation: the component errors as CSV.

One CSV per axis: ``//`` comment lines, a header naming the argument column (the axis, mm or deg)
and the ISO 230-1 component errors of that axis (``EXX, EYX, EZX, EAX, EBX, ECX`` for X), then one
row per grid point; translations in mm, rotations in rad, comma separated. Component errors here are
the model's deviation when only that axis moves (docs/export.md): the translations are those of the
tool tip at the table pose (the machine's tool length), so they already contain the Abbe effect
of the angular errors there, and the straightness columns contain the squareness (enter no separate
squareness). Volumetric compensation has no direction: the tables hold the mean of both approach
directions.

Beside them, one leadscrew error compensation list per linear axis (``achskw_<axis>.lis``, the
``kw.ssfk.*`` list of the ISG axis compensation): equidistant interpolation points (``interval``,
``kw_startpos`` in 0.1 um) or, where the last point sits at the high end of the region closer than one
step to the point before it, ``interval`` 0 and every point's ``table[i].setpoint`` (P-COMP-00018);
``table[i].pos`` / ``table[i].neg`` = actual minus setpoint moving
positive / negative, in 0.1 um (as in ISG's example: setpoint 19866.7 um, measured 19856.5 um ->
pos -102), ``bilateral`` 1 where the model has backlash. They carry the positioning error with its
direction dependence; load *either* the volumetric tables *or* these lists for the positioning,
never both (the positioning would be corrected twice).
"""
from __future__ import annotations

import math

import numpy as np

from ._output import FULL, MEAN, ExportResult, readme_text
from ._tables import component_names, own_column

NAME = "isg"
MAX_POINTS = 1024
SINGLE_FILE = False
INCLUDE_END = True   # the last point at the high end; kw.ssfk lists then name every position
LINEAR_ONLY = False


TENTH_UM_PER_MM = 1e4


def ssfk_list(tables, a: str, k: int) -> str:
    """The kw.ssfk compensation value list of linear axis ``a`` (logical axis number k)."""
    t = tables.tables[a]
    j = own_column(tables.machine, a)
    bilateral = tables.has_backlash(a)
    setpoints = np.round(t.positions * TENTH_UM_PER_MM).astype(np.int64)
    steps = np.diff(setpoints)
    # equidistant points: kw_startpos + i interval; else (the last point at the high end of the region,
    # off the step) interval 0 and each point's position, table[i].setpoint (P-COMP-00018)
    interval = int(steps[0]) if len(steps) and np.all(steps == steps[0]) else 0
    pos = t.forward[:, j] if bilateral else t.mean[:, j]
    neg = t.reverse[:, j] if bilateral else t.mean[:, j]
    lines = [f"# mtcomp export: leadscrew error compensation of axis {a} (values: actual minus setpoint, "
             "0.1 um)",
             f"kopf.log_achs_nr                     {k}",
             f"kopf.log_achs_name                   {a}",
             "kw.ssfk.unit                         1",
             f"kw.ssfk.interval                     {interval}",
             f"kw.ssfk.kw_startpos                  {setpoints[0]}",
             f"kw.ssfk.kw_nr_max                    {len(t.positions)}",
             f"kw.ssfk.bilateral                    {1 if bilateral else 0}",
             "kw.ssfk.modulo                       0"]
    if not interval:
        lines += [f"kw.ssfk.table[{i}].setpoint{'':<{11 - len(str(i))}}{v}" for i, v in enumerate(setpoints)]
    lines += [f"kw.ssfk.table[{i}].pos{'':<{16 - len(str(i))}}{round(v * TENTH_UM_PER_MM)}"
              for i, v in enumerate(pos)]
    if bilateral:
        lines += [f"kw.ssfk.table[{i}].neg{'':<{16 - len(str(i))}}{round(v * TENTH_UM_PER_MM)}"
                  for i, v in enumerate(neg)]
    return "\n".join(lines) + "\n"


def export(tables, **_) -> ExportResult:
    files, carried, notes = {}, {}, []
    listing = []
    m = tables.machine
    for a, t in tables.tables.items():
        if not t.rotary:
            files[f"achskw_{a.lower()}.lis"] = ssfk_list(tables, a, m.axis_names.index(a) + 1)
    uneven = [a for a, t in tables.tables.items() if len(t.positions) > 2 and not np.allclose(
        np.diff(t.positions), t.positions[1] - t.positions[0], rtol=1e-9, atol=1e-12)]
    if uneven:
        notes.append(f"axis {', '.join(uneven)}: the last point sits at the high end of the region, "
                     "closer than one step to the point before it (the kw.ssfk lists name every "
                     "position); a configuration that interpolates the volumetric tables on a grid "
                     "(P-VOLC-00014) needs equidistant rows: give --grid-mm (--grid-deg) that divides "
                     "the region")
    for k, (a, t) in enumerate(tables.tables.items()):
        f = 180.0 / math.pi if t.rotary else 1.0
        names = component_names(a)
        cols = [j for j in range(6) if np.isfinite(t.mean[:, j]).all()]
        lines = [f"// mtcomp export: component errors of axis {a} ({'deg' if t.rotary else 'mm'}); "
                 "translations in mm, rotations in rad",
                 f"// mean of both approach directions; reference position {t.reference[a] * f:g}",
                 ",".join([a] + [names[j] for j in cols])]
        for i, s in enumerate(t.positions):
            lines.append(",".join([f"{s * f:.6f}"] + [f"{t.mean[i, j] + 0.0:.9e}" for j in cols]))
        name = f"vc_{a.lower()}.csv"
        files[name] = "\n".join(lines) + "\n"
        listing.append(f"file[{k}]   {name}")
        for j in cols:
            carried[(a, names[j])] = MEAN
        if not t.rotary and tables.has_backlash(a):
            carried[(a, names[own_column(m, a)])] = FULL   # with the bilateral kw.ssfk list
        if tables.has_backlash(a):
            notes.append(f"axis {a}: the volumetric tables hold the mean of both directions; the "
                         f"backlash is in achskw_{a.lower()}.lis (bilateral)")
    notes.append("the angular columns act in the controller's kinematic model about its own reference "
                 "point; the translations given are at the tool tip of the table pose, which is "
                 "what a single-tool setup needs")
    notes.append("field separator ',' and '//' comments; check file_format (P-VOLC-00013) of your "
                 "configuration")
    result = ExportResult(NAME, files, False, carried, notes)
    header = ["mtcomp export: ISG / Beckhoff TF5280 volumetric compensation",
              "",
              "vc_<axis>.csv  one per axis: argument column, then the six component errors of that",
              "               axis (mm, rad) at each grid point; linear interpolation between points",
              "List them in the volumetric compensation parameters (P-VOLC-00012), e.g.:"] + \
        ["  " + line for line in listing] + [
              "achskw_<axis>.lis  leadscrew error compensation lists (kw.ssfk, 0.1 um, actual minus",
              "               setpoint; bilateral where the model has backlash): name them in the",
              "               start-up list (achs_kw[i], achs_kw_log_ax_nr[i]) and activate with the axis",
              "               parameter lr_param.ssfk. Load EITHER these OR the volumetric tables for the",
              "               positioning: together they would correct it twice."]
    files["README.txt"] = readme_text(result, tables, header)
    return result

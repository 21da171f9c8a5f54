"""Beckhoff / ISG TwinCAT CNC, TF5280 volumetric compensation: the component errors as CSV.

One CSV per axis: ``//`` comment lines, a header naming the argument column (the axis, mm or deg)
and the ISO 230-1 component errors of that axis (``EXX, EYX, EZX, EAX, EBX, ECX`` for X), then one
row per grid point; translations in mm, rotations in rad, comma separated. Component errors here are
the model's deviation when only that axis moves (docs/export.md): the translations are those of the
tool tip at the reference pose (the machine's tool length), so they already contain the Abbe effect
of the angular errors there, and the straightness columns contain the squareness (enter no separate
squareness). Volumetric compensation has no direction: the tables hold the mean of both approach
directions and the backlash is left out (the axis compensation ``kw.ssfk`` with ``bilateral`` holds
it, in 0.1 um: not written here).
"""
from __future__ import annotations

import math

import numpy as np

from ._output import MEAN, ExportResult, readme_text
from ._tables import component_names

NAME = "isg"
MAX_POINTS = 1024
SINGLE_FILE = False
INCLUDE_END = True
LINEAR_ONLY = False


def export(tables, **_) -> ExportResult:
    files, carried, notes = {}, {}, []
    listing = []
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
        if tables.has_backlash(a):
            notes.append(f"axis {a}: the backlash is left out (volumetric tables have no direction)")
    notes.append("the angular columns act in the controller's kinematic model about its own reference "
                 "point; the translations given are at the tool tip of the reference pose, which is "
                 "what a single-tool setup needs")
    notes.append("field separator ',' and '//' comments; check file_format (P-VOLC-00013) of your "
                 "configuration")
    result = ExportResult(NAME, files, False, carried, notes)
    header = ["mtcomp export: ISG / Beckhoff TF5280 volumetric compensation",
              "",
              "vc_<axis>.csv  one per axis: argument column, then the six component errors of that",
              "               axis (mm, rad) at each grid point; linear interpolation between points",
              "List them in the volumetric compensation parameters (P-VOLC-00012), e.g.:"] + \
        ["  " + line for line in listing]
    files["README.txt"] = readme_text(result, tables, header)
    return result

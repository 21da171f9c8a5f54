"""Heidenhain TNC: axis error compensation tables (``.COM``) and the table list (``.CMA``).

One ``.COM`` table per dependency: column ``AXISPOS`` (the position of the axis the compensation
depends on, from the machine datum, mm or deg), a value column named after the compensated axis, and
``BACKLASH`` (the extra value for the negative direction) in the tables of an axis's own positioning.
The ``.CMA`` lists the tables, one column per compensated axis; the line marked ``*`` in ``ACTIVE``
is in force. mtcomp writes line 0 (active) with each axis's own table and one line per cross
dependency (straightness: the compensated axis as another axis moves), inactive, to be merged as
your TNC's commissioning manual allows.

The sign is not public: by default the tables hold the correction (minus the error, mm);
``--sign error`` writes the error. BACKLASH is the correction moving negative minus the correction
moving positive.
"""
from __future__ import annotations

import math

from ._output import FULL, MEAN, ExportResult, readme_text, sign_factor_and_note
from ._tables import component_names, own_column

NAME = "heidenhain"
MAX_POINTS = 1024
SINGLE_FILE = False
INCLUDE_END = True
LINEAR_ONLY = False
DECIMALS = 5  # mm: 0.01 um


def com_table(name: str, axis: str, positions, values, backlash=None) -> str:
    """Text of a .COM table: BEGIN line, column header, one row per point, [END]."""
    cols = ["NR", "AXISPOS", axis] + (["BACKLASH"] if backlash is not None else [])
    lines = [f"BEGIN {name} MM", "  ".join(f"{c:<12}" for c in cols).rstrip()]
    for n, (p, v) in enumerate(zip(positions, values)):
        row = [f"{n:<12d}", f"{p:<+12.{DECIMALS}f}", f"{v + 0.0:<+12.{DECIMALS}f}"]
        if backlash is not None:
            row.append(f"{backlash[n] + 0.0:<+12.{DECIMALS}f}")
        lines.append("  ".join(row).rstrip())
    lines.append("[END]")
    return "\n".join(lines) + "\n"


def export(tables, sign: str | None = None, **_) -> ExportResult:
    m = tables.machine
    s, sign_note = sign_factor_and_note(sign, "values (mm, deg for a rotary axis)")
    files, carried, notes = {}, {}, []
    own, cross = {}, []
    for a, t in tables.tables.items():
        f = 180.0 / math.pi if t.rotary else 1.0
        j = own_column(m, a)
        name = f"{a}_{a}.COM"
        fwd, rev = s * t.forward[:, j] * f, s * t.reverse[:, j] * f
        has_bl = tables.has_backlash(a)
        files[name] = com_table(name, a, t.positions * f, fwd, (rev - fwd) if has_bl else None)
        carried[(a, component_names(a)[j])] = FULL if has_bl else MEAN
        own[a] = name
        if t.rotary:
            continue
        for d in "XYZ":
            if d == a or d not in m.axis_names:
                continue
            cname = f"{d}_{a}.COM"
            files[cname] = com_table(cname, d, t.positions, s * t.mean[:, "XYZ".index(d)])
            carried[(a, f"E{d}{a}")] = MEAN
            cross.append((d, cname))
    cols = list(m.axis_names)
    cma = ["BEGIN AXIS.CMA", "  ".join(f"{c:<12}" for c in ["NR", "ACTIVE"] + cols).rstrip()]
    cma.append("  ".join(f"{c:<12}" for c in ["0", "*"] + [own.get(c, "") for c in cols]).rstrip())
    for k, (d, cname) in enumerate(cross, start=1):
        cma.append("  ".join(f"{c:<12}" for c in [str(k), ""] + [cname if c == d else "" for c in cols]
                             ).rstrip())
    cma.append("[END]")
    files["AXIS.CMA"] = "\n".join(cma) + "\n"
    notes.append(sign_note)
    if cross:
        notes.append("the cross tables (straightness) are listed in inactive lines of AXIS.CMA: "
                     "activate or merge them as your TNC allows")
    result = ExportResult(NAME, files, False, carried, notes)
    header = ["mtcomp export: Heidenhain TNC axis error compensation",
              "",
              "<A>_<A>.COM  the own positioning of axis A: AXISPOS (mm from the machine datum, deg),",
              "             the value column named A, BACKLASH (extra value moving negative)",
              "<D>_<L>.COM  axis D as axis L moves (straightness of L along D): AXISPOS = position of L",
              "AXIS.CMA     the list: one column per axis, line 0 marked * in ACTIVE",
              "Copy the files to PLC:\\ (or where the machine parameters CfgAxisComp point) and",
              "activate the .CMA in the machine configuration (code number needed)."]
    files["README.txt"] = readme_text(result, tables, header)
    return result

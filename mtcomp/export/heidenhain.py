"""Heidenhain TNC: nonlinear axis error compensation, ``.COM`` tables and the ``.CMA`` assignment.

Per the TNC technical manuals (e.g. iTNC 530, MANUALplus 620, TNC 407: "Nonlinear axis error
compensation"): a ``.COM`` table holds, for one axis L the compensation depends on, the column
``AXISPOS`` (compensation points, positions of L from the machine datum), one value column per
compensated axis, named after it (X = F(L), Y = F(L) ...), and optionally ``BACKLASH``: the values
of L's own column measured in the negative direction of traverse. The ``.CMA`` table has one column
per axis; a line enters in the column of L the ``.COM`` table that depends on L; the line marked
``*`` in ``ACTIVE`` is in force (one line at a time). Older TNCs hold at most 256 points per table
(``--max-points``).

mtcomp writes ``<L>.COM`` per axis with its own positioning error and the straightness errors of the
other linear axes as L moves, and one active line in ``AXIS.CMA``. The sign of the values is not
public: by default they are the correction (minus the error, mm; deg for a rotary axis);
``--sign error`` writes the error.
"""
from __future__ import annotations

import math

from ._output import FULL, MEAN, ExportResult, readme_text, sign_factor_and_note
from ._tables import component_names, own_column

NAME = "heidenhain"
MAX_POINTS = 256
SINGLE_FILE = False
INCLUDE_END = True
LINEAR_ONLY = False
DECIMALS = 5  # mm: 0.01 um


def com_table(name: str, positions, columns: dict) -> str:
    """Text of a .COM table: BEGIN line, column header, one row per point, [END].
    columns : column name -> (n,) values (mm or deg)."""
    cols = ["NR", "AXISPOS"] + list(columns)
    lines = [f"BEGIN {name} MM", "  ".join(f"{c:<12}" for c in cols).rstrip()]
    for n, p in enumerate(positions):
        row = [f"{n:<12d}", f"{p:<+12.{DECIMALS}f}"]
        # rounded first: a value of -1e-7 would print as "-0.00000"
        row += [f"{round(float(v[n]), DECIMALS) + 0.0:<+12.{DECIMALS}f}" for v in columns.values()]
        lines.append("  ".join(row).rstrip())
    lines.append("[END]")
    return "\n".join(lines) + "\n"


def export(tables, sign: str | None = None, **_) -> ExportResult:
    m = tables.machine
    s, sign_note = sign_factor_and_note(sign, "values (mm, deg for a rotary axis)")
    files, carried, notes = {}, {}, []
    cma_row = {}
    for a, t in tables.tables.items():
        f = 180.0 / math.pi if t.rotary else 1.0
        j = own_column(m, a)
        has_bl = tables.has_backlash(a)
        own = t.forward[:, j] if has_bl else t.mean[:, j]
        columns = {a: s * own * f}
        carried[(a, component_names(a)[j])] = FULL if has_bl else MEAN
        if not t.rotary:
            for d in "XYZ":
                if d != a and d in m.axis_names:
                    columns[d] = s * t.mean[:, "XYZ".index(d)]
                    carried[(a, f"E{d}{a}")] = MEAN
        if has_bl:
            columns["BACKLASH"] = s * t.reverse[:, j] * f
        name = f"{a}.COM"
        files[name] = com_table(name, t.positions * f, columns)
        cma_row[a] = name
    cols = list(m.axis_names)
    cma = ["BEGIN AXIS.CMA", "  ".join(f"{c:<12}" for c in ["NR", "ACTIVE"] + cols).rstrip(),
           "  ".join(f"{c:<12}" for c in ["0", "*"] + [cma_row.get(c, "") for c in cols]).rstrip(),
           "[END]"]
    files["AXIS.CMA"] = "\n".join(cma) + "\n"
    notes.append(sign_note)
    if any(tables.has_backlash(a) for a in tables.tables):
        notes.append("BACKLASH holds the own axis's value for negative traverse (the manuals: 'the "
                     "compensation values measured in the negative direction of traverse'); the value "
                     "column holds it for positive traverse")
    result = ExportResult(NAME, files, False, carried, notes)
    header = ["mtcomp export: Heidenhain TNC nonlinear axis error compensation",
              "",
              "<L>.COM   the compensation that depends on axis L: AXISPOS (position of L from the",
              "          machine datum, mm or deg), a column per compensated axis (L itself: its",
              "          positioning; the others: L's straightness along them), BACKLASH (L moving -)",
              "AXIS.CMA  the assignment: one column per axis L naming <L>.COM, line 0 active (*)",
              "Copy the files to the PLC partition (where the machine configuration points for the",
              "axis compensation) and activate the .CMA in the machine configuration."]
    files["README.txt"] = readme_text(result, tables, header)
    return result

"""Siemens Sinumerik: leadscrew / measuring-system error (LEC) and cross-axis (CEC) tables.

``%_N_AX_EEC_INI`` (LEC, one table per axis, not directional): ``$AA_ENC_COMP[0,N,AXn]`` in mm at the
equidistant positions ``_MIN + N * _STEP``, with ``$AA_ENC_COMP_STEP``, ``_MIN``, ``_MAX``,
``_IS_MODULO``; a positive value moves the axis negative, so the table holds the error itself (actual
minus nominal); beyond ``_MIN`` / ``_MAX`` the end values hold. At most MD38000 MM_ENC_COMP_MAX_POINTS
points per table (``--max-points``, default 125).

``%_N_NC_CEC_INI`` (CEC, "sag" or cross-axis compensation): ``$AN_CEC[t,N]`` values of table t,
``$AN_CEC_INPUT_AXIS[t]`` (the axis whose position is looked up), ``$AN_CEC_OUTPUT_AXIS[t]`` (the
axis that is corrected), ``_STEP``, ``_MIN``, ``_MAX``, ``_DIRECTION`` (0: both directions, 1 / -1:
only when the input axis moves + / -), ``_MULT_BY_TABLE``, ``_IS_MODULO``. mtcomp writes one CEC
table per straightness (output axis d, input axis L: the deviation along d as L moves, squareness
included) and, where the model has backlash, two directional tables with the input and output both
the axis itself (the direction-dependent part of its positioning error: +-B/2). The sign of a CEC
value is not stated in the public material mtcomp relies on: by default the table holds the
correction (minus the error); ``--sign error`` writes the error.

Axes are named AX1, AX2 ... in the machine's order (X Y Z A B C as present): rename to your machine
axis names if they differ.
"""
from __future__ import annotations

import math

import numpy as np

from ._output import FULL, MEAN, ExportResult, readme_text, sign_factor_and_note
from ._tables import component_names, own_column

NAME = "siemens"
MAX_POINTS = 125
SINGLE_FILE = False
INCLUDE_END = False
LINEAR_ONLY = False
DECIMALS = 6  # mm (or deg): 1 nm


def axis_name(machine, a: str) -> str:
    return f"AX{machine.axis_names.index(a) + 1}"


def _fmt(v: float) -> str:
    return f"{v + 0.0:.{DECIMALS}f}"


def _cec_table(lines, t_no, values, table, inp, out, direction, factor):
    step = (table.positions[1] - table.positions[0]) * factor if len(table.positions) > 1 else 0.0
    for n, v in enumerate(values):
        lines.append(f"$AN_CEC[{t_no},{n}]={_fmt(v)}")
    lines += [f"$AN_CEC_INPUT_AXIS[{t_no}]=({inp})", f"$AN_CEC_OUTPUT_AXIS[{t_no}]=({out})",
              f"$AN_CEC_STEP[{t_no}]={_fmt(step)}", f"$AN_CEC_MIN[{t_no}]={_fmt(table.positions[0] * factor)}",
              f"$AN_CEC_MAX[{t_no}]={_fmt(table.positions[-1] * factor)}",
              f"$AN_CEC_DIRECTION[{t_no}]={direction}", f"$AN_CEC_MULT_BY_TABLE[{t_no}]=0",
              f"$AN_CEC_IS_MODULO[{t_no}]=0"]


def export(tables, sign: str | None = None, **_) -> ExportResult:
    m = tables.machine
    cec_sign, sign_note = sign_factor_and_note(sign, "CEC values")
    carried, notes = {}, []
    lec = ["%_N_AX_EEC_INI", "CHANDATA(1)"]
    cec = ["%_N_NC_CEC_INI", "CHANDATA(1)"]
    t_no = 0
    for a, t in tables.tables.items():
        ax = axis_name(m, a)
        j = own_column(m, a)
        factor = 180.0 / math.pi if t.rotary else 1.0
        step = (t.positions[1] - t.positions[0]) * factor if len(t.positions) > 1 else 0.0
        for n, v in enumerate(t.mean[:, j] * factor):
            lec.append(f"$AA_ENC_COMP[0,{n},{ax}]={_fmt(v)}")
        lec += [f"$AA_ENC_COMP_STEP[0,{ax}]={_fmt(step)}",
                f"$AA_ENC_COMP_MIN[0,{ax}]={_fmt(t.positions[0] * factor)}",
                f"$AA_ENC_COMP_MAX[0,{ax}]={_fmt(t.positions[-1] * factor)}",
                f"$AA_ENC_COMP_IS_MODULO[0,{ax}]=0"]
        carried[(a, component_names(a)[j])] = MEAN
        if tables.has_backlash(a):
            for direction, col in ((1, t.forward), (-1, t.reverse)):
                _cec_table(cec, t_no, cec_sign * (col[:, j] - t.mean[:, j]) * factor, t, ax, ax,
                           direction, factor)
                t_no += 1
            carried[(a, component_names(a)[j])] = FULL
            notes.append(f"axis {a}: the reversal (backlash) is in two directional CEC tables "
                         f"(input = output = {ax}, _DIRECTION 1 and -1); leave MD32450 BACKLASH at 0")
        if t.rotary:
            continue
        for d in "XYZ":
            if d == a or d not in m.axis_names or "XYZ".index(d) in t.left:
                continue            # a straightness left: the notes say why (no sag table)
            col = t.mean[:, "XYZ".index(d)]
            if not np.any(np.abs(col) >= 0.5e-6):
                # a straightness the model holds at zero (no data on it) would be a table of zeros
                notes.append(f"no CEC table for {ax} -> {axis_name(m, d)}: the model has no "
                             f"straightness E{d}{a} (zero to the table's 1 nm resolution)")
                continue
            _cec_table(cec, t_no, cec_sign * col, t, ax, axis_name(m, d), 0, factor)
            carried[(a, f"E{d}{a}")] = MEAN
            t_no += 1
    lec.append("M17")
    cec.append("M17")
    files = {"AX_EEC.INI": "\n".join(lec) + "\n", "NC_CEC.INI": "\n".join(cec) + "\n"}
    notes.append(sign_note)
    notes.append(f"{t_no} CEC tables: MD18342 MM_CEC_MAX_POINTS must allow {t_no} tables of up to "
                 f"{max(len(t.positions) for t in tables.tables.values())} points")
    result = ExportResult(NAME, files, False, carried, notes)
    header = ["mtcomp export: Siemens Sinumerik compensation tables",
              "",
              "AX_EEC.INI  leadscrew / measuring-system error compensation (LEC, %_N_AX_EEC_INI):",
              "            $AA_ENC_COMP = the error in mm (a positive value moves the axis negative);",
              "            load it as an INI file with the axes' MD32700 ENC_COMP_ENABLE = 0, then set",
              "            it to 1 and NEW CONF / reset",
              "NC_CEC.INI  cross-axis compensation (CEC, %_N_NC_CEC_INI): one table per straightness",
              "            (output axis corrected as the input axis moves) and the directional tables",
              "            of the backlash; activate with $SN_CEC_TABLE_ENABLE[t] = 1 and MD32710",
              "            CEC_ENABLE of the output axes",
              f"Points per table at most MD38000 MM_ENC_COMP_MAX_POINTS (here {MAX_POINTS} unless",
              "--max-points says otherwise); axes named AX1, AX2 ... in the order " + " ".join(m.axis_names)]
    files["README.txt"] = readme_text(result, tables, header)
    return result

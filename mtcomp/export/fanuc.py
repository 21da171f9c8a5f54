"""Fanuc: stored pitch error compensation as a parameter list (details vary by series).

Per axis: 3620 the compensation point number of the reference position, 3621 / 3622 the most
negative / most positive point number, 3623 the magnification, 3624 the interval (detection units);
bidirectional compensation (3605#0 = 1) adds 3626 (most negative point number of the table for
negative travel) and 3627 (the compensation at the reference position when moving negative, relative
to moving positive). The pitch error values are incremental: the value at point n is the change of
the compensation from point n - 1 to point n, in detection units times the magnification; the
compensation is 0 at the reference point (positive travel). Points sit at
``reference position + (n - 3620) * interval`` (FANUC Series 0i-PB parameter manual B-63980EN/01,
parameters 3620-3624: the reference position at machine coordinate 0 in its example). mtcomp puts
the reference point on the axis's reference position (machine coordinate 0, or the nearest end of
the travel when 0 lies outside it) and numbers the axes' blocks one after the other from 0. Where
the data's region does not reach the reference position, the table runs from the reference point
to the region with the compensation held at the region's end value (increments 0), and a note names
the points. Values are rounded as cumulative sums, so the rounding never accumulates.

``pitch_error.txt`` holds only what a Fanuc reads from a parameter tape (:func:`tape`): a line
``%``, one block per parameter with every axis's value (``N03620Q1A1P35A2P121``), the pitch error
data (``N10035Q0P-1``) and a line ``%``; no comment, no title. Parameter 3605 is a bit parameter,
read from a tape as its whole byte (``N03605Q1A1P00000001`` would clear its other seven bits, which
mtcomp does not know), so it is not written: the README says which axes need bit 0 set. Everything
mtcomp has to say goes to the README and the summary.

The sign of the values is not public: by default they are the correction (minus the error);
``--sign error`` writes the error. Linear axes only (a rotary table's values must sum to 0 over a
turn; not written here).
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from ._ends import beyond_span
from ._output import FULL, MEAN, ExportResult, readme_text, sign_factor_and_note
from ._tables import component_names, own_column

NAME = "fanuc"
MAX_POINTS = 128
SINGLE_FILE = False
INCLUDE_END = False
LINEAR_ONLY = True
ANCHOR_AT_REFERENCE = True
MAX_POINT_NUMBER = 1023


def cumulative_units(correction_mm: np.ndarray, unit_mm: float, max_value: int) -> tuple[np.ndarray, int]:
    """(rounded cumulative values in units of unit x magnification, magnification): the smallest
    magnification (1..100) whose increments fit +-max_value."""
    for mag in range(1, 101):
        cum = np.round(correction_mm / (unit_mm * mag)).astype(np.int64)
        if len(cum) < 2 or np.max(np.abs(np.diff(cum))) <= max_value:
            return cum, mag
    raise InputError(f"pitch error increments exceed {max_value} units even at magnification 100; "
                     "use a smaller --grid-mm or a larger --fanuc-max-value")


def held_note(t, a: str, first_point: int) -> str | None:
    """The line naming the points of axis ``a``'s table that lie beyond the data's region (between
    the reference position and the region, and one interval or two past its ends), or None."""
    held = np.flatnonzero(t.held)
    if not held.size:
        return None
    lo, hi = t.data_region
    zero = beyond_span(t.positions, lo, hi)

    def named(idx):
        i, j = first_point + idx[0], first_point + idx[-1]
        where = f"{t.positions[idx[0]]:g} .. {t.positions[idx[-1]]:g} mm" if i != j else \
            f"{t.positions[idx[0]]:g} mm"
        return f"point{'s' if i != j else ''} {i}{f' .. {j}' if i != j else ''} ({where})"
    parts = []
    for side, idx in (("below", held[t.positions[held] < lo]), ("above", held[t.positions[held] > hi])):
        end = lo if side == "below" else hi
        kept, none = idx[~zero[idx]], idx[zero[idx]]
        if kept.size:
            parts.append(f"{named(kept)} hold{'s' if kept.size == 1 else ''} the compensation at its "
                         f"value at {end:g} mm, the data's nearest end")
        if none.size:
            parts.append(f"{named(none)} carr{'ies' if none.size == 1 else 'y'} no compensation")
    return (f"axis {a}: the data reach {lo:g} .. {hi:g} mm and the table runs from the reference "
            f"position {t.reference[a]:g} mm (point 3620); " + "; ".join(parts)
            + ": nothing was measured there, where compensate corrects nothing")


def _axis_tables(t, j: int, s: float, bidir: bool) -> tuple[int, list]:
    """(index of the reference point, [(travel '+' / '-', correction relative to the reference point
    moving positive, mm)])."""
    pos = t.positions
    ref = t.reference[t.axis]
    i_ref = int(np.argmin(np.abs(pos - ref)))
    if abs(pos[i_ref] - ref) > 1e-9 * max(1.0, abs(ref)):
        raise InputError(f"axis {t.axis}: no grid point on the reference position {ref:g} mm")
    if not bidir:
        return i_ref, [("+", s * t.mean[:, j] - s * t.mean[i_ref, j])]
    corr_f, corr_r = s * t.forward[:, j], s * t.reverse[:, j]
    base = corr_f[i_ref]
    return i_ref, [("+", corr_f - base), ("-", corr_r - base)]


#: what a bidirectional pair of tables holds at the reference position (3627: parameter manual)
BACKLASH_ZERO = ("the table for positive travel; the table for negative travel (bidirectional, "
                 "3605#0 = 1) differs from it there by the reversal, which parameter 3627 holds (the "
                 "compensation at the reference position moving negative, relative to moving positive)")


def _general_notes(sign_note: str, max_value: int, machine) -> list:
    """The lines on signs, placement, limits and rotary axes every Fanuc export carries."""
    notes = [sign_note,
             "point 3620 sits on each axis's reference position (machine coordinate 0 after a reference "
             "return, as in the example of the FANUC Series 0i-PB parameter manual) and point n at "
             "reference + (n - 3620) * 3624; if your machine's reference position is not its machine "
             "zero, the table is placed off by that distance: pitch_points.csv lists the positions assumed",
             "the compensation is 0 at the reference point for positive travel: a constant offset of the "
             "whole table is absorbed by the reference position; reference return in the positive "
             "direction is assumed for 3627",
             f"one increment holds at most +-{max_value} units (--fanuc-max-value; the range depends on "
             "the series); the magnification 3623 was chosen to fit",
             "no smallest interval 3624 is applied: if your series' parameter manual sets one, give "
             "--grid-mm at least that large",
             "3624 (the interval) is written in detection units (--fanuc-unit-um), as the Series 0i-PB "
             "parameter manual gives it; mtcomp could not check the unit on the Series 30i/31i/32i "
             "(whose newer parameters are real values in mm): look up [Unit of data] of 3624 in your "
             "series' parameter manual, and if it is mm enter the interval in mm on the parameter "
             "screen (pitch_points.csv gives the positions the points must sit at)"]
    rotary = [ax.name for ax in machine.rotary_axes]
    if rotary:
        notes.append(f"rotary axes {' '.join(rotary)}: no table (not written by this exporter)")
    return notes


def bit_3605_note(bidir: dict, numbers: dict) -> str:
    """The line on parameter 3605 bit 0 (bidirectional pitch error compensation), which the tape
    does not carry: a bit parameter is read as its whole byte, whose other bits mtcomp does not know."""
    on = [f"{a} (A{numbers[a]})" for a, b in bidir.items() if b]
    off = [f"{a} (A{numbers[a]})" for a, b in bidir.items() if not b]
    parts = ([f"1 for {', '.join(on)} (bidirectional tables)"] if on else []) + \
        ([f"0 for {', '.join(off)}"] if off else [])
    return ("parameter 3605 bit 0 (bidirectional pitch error compensation) is not in pitch_error.txt: "
            "a tape sets a bit parameter's whole byte, which would clear its other seven bits, and "
            "mtcomp does not know them; set bit 0 on the parameter screen, where one bit changes at a "
            "time: " + ", ".join(parts))


def tape(params: dict, data: list) -> str:
    """The parameter tape: ``%``, one block per parameter (``N03620Q1A1P35A2P121``: the 5-digit
    parameter number, Q1 for parameter data, each axis's number and value), the pitch error data
    (``N10000Q0P-1``: 10000 + point number, Q0 for pitch error compensation data) and ``%``; nothing
    else (FANUC Series 30i/31i/32i-MODEL A parameter manual B-63950EN/02, section 3.3)."""
    lines = ["%"]
    for number in sorted(params):
        lines.append(f"N{number:05d}Q1" + "".join(f"A{k}P{v}" for k, v in sorted(params[number].items())))
    lines += [f"N{10000 + point:05d}Q0P{value}" for point, value in data]
    return "\n".join(lines + ["%"]) + "\n"


def _axis_blocks(t, a: str, j: int, bidir: bool, s: float, unit_mm: float, max_value: int,
                 next_point: int):
    """(parameters {number: value}, pitch data [(point, value)], csv rows, first point of '+',
    next free point) of axis ``a`` (its own component: column j), numbered from ``next_point``."""
    pos = t.positions
    step = pos[1] - pos[0] if len(pos) > 1 else 0.0
    interval = step / unit_mm
    if abs(interval - round(interval)) > 1e-6:
        raise InputError(f"axis {a}: the interval {step:g} mm is not a whole number of detection "
                         f"units ({unit_mm * 1e3:g} um)")
    i_ref, blocks = _axis_tables(t, j, s, bidir)
    n = len(pos)
    if next_point + n * len(blocks) - 1 > MAX_POINT_NUMBER:
        raise InputError(f"the pitch error tables need more than {MAX_POINT_NUMBER + 1} points; "
                         "use a larger --grid-mm")
    first = {label: next_point + b * n for b, (label, _c) in enumerate(blocks)}
    # one magnification for both travel directions
    mag = max(cumulative_units(c, unit_mm, max_value)[1] for _, c in blocks)
    par = {3620: first["+"] + i_ref, 3621: first["+"], 3622: first["+"] + n - 1, 3623: mag,
           3624: int(round(interval))}
    data, csv = [], []
    for label, corr in blocks:
        cum = np.round(corr / (unit_mm * mag)).astype(np.int64)
        if label == "-":
            offset = int(cum[i_ref])
            par.update({3626: first["-"], 3627: offset})
            cum = cum - offset
        inc = np.diff(np.r_[cum[0], cum])  # value at point n: change from n - 1 to n (first: 0)
        for i in range(n):
            data.append((first[label] + i, int(inc[i])))
            csv.append(f"{a},{first[label] + i},{pos[i]:.6f},{label},{int(inc[i])},"
                       f"{corr[i] * 1e3:.4f},{int(t.held[i])}")
    return par, data, csv, first["+"], next_point + n * len(blocks)


def export(tables, sign: str | None = None, unit_um: float = 1.0, max_value: int = 127, **_) -> ExportResult:
    m = tables.machine
    s, sign_note = sign_factor_and_note(sign, "values")
    if not unit_um > 0:
        raise InputError(f"--fanuc-unit-um must be positive, got {unit_um}")
    params, data, notes, bidir, numbers = {}, [], [], {}, {}
    csv = ["axis,point,position_mm,travel,value_units,compensation_um,held"]
    carried, next_point = {}, 0
    for a, t in tables.tables.items():
        numbers[a] = m.axis_names.index(a) + 1
        j = own_column(m, a)
        bidir[a] = tables.has_backlash(a)
        par, pitch, rows, first, next_point = _axis_blocks(t, a, j, bidir[a], s, unit_um * 1e-3,
                                                           max_value, next_point)
        for number, value in par.items():
            params.setdefault(number, {})[numbers[a]] = value
        data += pitch
        csv += rows
        carried[(a, component_names(a)[j])] = FULL if bidir[a] else MEAN
        if bidir[a]:
            notes.append(f"axis {a}: the reversal (backlash) is in the bidirectional tables (3605#0 = 1, "
                         "3626, 3627); the backlash compensation of parameter 1851 adds its own value "
                         "at every reversal: set it to 0, or the reversal is corrected twice")
        line = held_note(t, a, first)
        if line:
            notes.append(line)
    files = {"pitch_error.txt": tape(params, data), "pitch_points.csv": "\n".join(csv) + "\n"}
    if bidir:
        notes.append(bit_3605_note(bidir, numbers))
    notes += _general_notes(sign_note, max_value, m)
    result = ExportResult(NAME, files, False, carried, notes)
    files["README.txt"] = readme_text(result, tables, _readme_header(m, unit_um), BACKLASH_ZERO)
    return result


def _readme_header(machine, unit_um: float) -> list:
    order = ", ".join(f"A{k} = {a}" for k, a in enumerate(machine.axis_names, start=1))
    return ["mtcomp export: Fanuc stored pitch error compensation",
            "",
            "pitch_error.txt  a parameter tape as a FANUC Series 30i/31i/32i reads it (parameter",
            "                 manual B-63950EN/02, section 3.3): a line '%', the parameters 3620 ...",
            "                 3627 (N03620Q1A1P.. : parameter number, Q1 = parameter data, controlled",
            "                 axis number and value), the pitch error data N(10000 + point)Q0P(value)",
            "                 (Q0 = pitch error compensation data), and a line '%'; no comments.",
            "                 Read it in as your control reads a parameter tape (parameter write",
            "                 enabled, PWE = 1), or enter the values by hand on the parameter and",
            "                 PITCH ERROR screens. A series whose tapes have no Q keyword (Series",
            "                 15i: N00010P00000001) needs 'Q1' and 'Q0' deleted; compare with a tape",
            "                 your control punches out.",
            f"                 Controlled axis numbers: {order}; detection unit {unit_um:g} um",
            "pitch_points.csv the same points with their positions (machine coordinates, mm), the",
            "                 compensation in um, and held = 1 where the point lies beyond the data",
            "                 (the compensation held at the data's nearest end value)",
            "Power off and on after changing 3620 ... 3627."]

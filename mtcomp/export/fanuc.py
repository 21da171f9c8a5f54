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

The sign of the values is not public: by default they are the correction (minus the error);
``--sign error`` writes the error. Linear axes only (a rotary table's values must sum to 0 over a
turn; not written here).
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError
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
    """The line naming the points of axis ``a``'s table that lie between the reference position and
    the data's region (their increments are 0), or None when the data reach the reference."""
    held = np.flatnonzero(t.held)
    if not held.size:
        return None
    lo, hi = t.data_region
    parts = []
    for side, idx in (("below", held[t.positions[held] < lo]), ("above", held[t.positions[held] > hi])):
        if idx.size:
            end = lo if side == "below" else hi
            parts.append(f"points {first_point + idx[0]} .. {first_point + idx[-1]} "
                         f"({t.positions[idx[0]]:g} .. {t.positions[idx[-1]]:g} mm) hold the compensation "
                         f"at its value at {end:g} mm, the data's nearest end (increments 0)")
    return (f"axis {a}: the data reach {lo:g} .. {hi:g} mm and the table runs from the reference "
            f"position {t.reference[a]:g} mm (point 3620); " + "; ".join(parts)
            + ": nothing was measured there")


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
             "--grid-mm at least that large"]
    rotary = [ax.name for ax in machine.rotary_axes]
    if rotary:
        notes.append(f"rotary axes {' '.join(rotary)}: no table (not written by this exporter)")
    return notes


def export(tables, sign: str | None = None, unit_um: float = 1.0, max_value: int = 127, **_) -> ExportResult:
    m = tables.machine
    s, sign_note = sign_factor_and_note(sign, "values")
    if not unit_um > 0:
        raise InputError(f"--fanuc-unit-um must be positive, got {unit_um}")
    unit_mm = unit_um * 1e-3
    files, carried, notes = {}, {}, []
    par = [f"% mtcomp pitch error compensation; axis numbers A1, A2 ... in the order "
           f"{' '.join(m.axis_names)}; detection unit {unit_um:g} um"]
    data = []
    csv = ["axis,point,position_mm,travel,value_units,compensation_um,held"]
    next_point = 0
    for a, t in tables.tables.items():
        k = m.axis_names.index(a) + 1
        j = own_column(m, a)
        pos = t.positions
        step = pos[1] - pos[0] if len(pos) > 1 else 0.0
        interval = step / unit_mm
        if abs(interval - round(interval)) > 1e-6:
            raise InputError(f"axis {a}: the interval {step:g} mm is not a whole number of detection "
                             f"units ({unit_um:g} um)")
        bidir = tables.has_backlash(a)
        i_ref, blocks = _axis_tables(t, j, s, bidir)
        n = len(pos)
        if next_point + n * len(blocks) - 1 > MAX_POINT_NUMBER:
            raise InputError(f"the pitch error tables need more than {MAX_POINT_NUMBER + 1} points; "
                             "use a larger --grid-mm")
        first = {}
        for label, _corr in blocks:
            first[label] = next_point
            next_point += n
        # one magnification for both travel directions
        mag = max(cumulative_units(c, unit_mm, max_value)[1] for _, c in blocks)
        par += [f"; axis {a}", f"N3605 A{k} P{1 if bidir else 0}", f"N3620 A{k} P{first['+'] + i_ref}",
                f"N3621 A{k} P{first['+']}", f"N3622 A{k} P{first['+'] + n - 1}",
                f"N3623 A{k} P{mag}", f"N3624 A{k} P{int(round(interval))}"]
        held = t.held
        for label, corr in blocks:
            cum = np.round(corr / (unit_mm * mag)).astype(np.int64)
            if label == "-":
                offset = int(cum[i_ref])
                par += [f"N3626 A{k} P{first['-']}", f"N3627 A{k} P{offset}"]
                cum = cum - offset
            inc = np.diff(np.r_[cum[0], cum])  # value at point n: change from n - 1 to n (first: 0)
            for i in range(n):
                data.append(f"N{10000 + first[label] + i} P{int(inc[i])}")
                csv.append(f"{a},{first[label] + i},{pos[i]:.6f},{label},{int(inc[i])},"
                           f"{corr[i] * 1e3:.4f},{int(held[i])}")
        carried[(a, component_names(a)[j])] = FULL if bidir else MEAN
        if bidir:
            notes.append(f"axis {a}: the reversal (backlash) is in the bidirectional tables (3605#0 = 1, "
                         "3626, 3627); the backlash compensation of parameter 1851 adds its own value "
                         "at every reversal: set it to 0, or the reversal is corrected twice")
        line = held_note(t, a, first["+"])
        if line:
            notes.append(line)
    files["pitch_error.txt"] = "\n".join(par + ["; pitch error data: N(10000 + point number) P(value)"]
                                         + data) + "\n"
    files["pitch_points.csv"] = "\n".join(csv) + "\n"
    notes += _general_notes(sign_note, max_value, m)
    result = ExportResult(NAME, files, False, carried, notes)
    header = ["mtcomp export: Fanuc stored pitch error compensation",
              "",
              "pitch_error.txt  the parameters (N3605 bit 0, N3620 ... N3627, per axis A1, A2 ...) and",
              "                 the pitch error data N(10000 + point) P(value) in parameter-tape style;",
              "                 enter them on the SETTING / PITCH ERROR screens or load the tape",
              "pitch_points.csv the same points with their positions (machine coordinates, mm), the",
              "                 compensation in um, and held = 1 where the point lies beyond the data",
              "                 (the compensation held at the data's nearest end value)",
              "Power off and on after changing 3620 ... 3627."]
    files["README.txt"] = readme_text(result, tables, header)
    return result

"""Klipper: the squareness of X, Y, Z as a ``[skew_correction]`` profile (one file).

Klipper (klippy/extras/skew_correction.py) takes the machine to move to ``x + y xy_skew + z xz_skew``,
``y + z yz_skew`` when commanded to (x, y, z) and undoes it on every move. mtcomp fits, over each
axis's table, the least-squares slope of the deviation along the other axes; the angle between two
axes is the sum of the two slopes (e.g. xy_skew = d(dx)/dy + d(dy)/dx), which is what Klipper's
one-sided skew can carry: the axes come out square, and the frame as a whole may stay turned by the
second slope (a rigid rotation: shapes are right, absolute positions rotate slightly). Positioning
errors, curvature, angular errors and backlash are left out (Klipper has no table for them).
"""
from __future__ import annotations

from ._output import LINEAR, ExportResult, readme_text, slope

NAME = "klipper"
MAX_POINTS = 1024
SINGLE_FILE = True
INCLUDE_END = True
LINEAR_ONLY = True
PROFILE = "mtcomp"


def skew_factors(tables) -> dict:
    """{'xy_skew': .., 'xz_skew': .., 'yz_skew': ..} (tan of the angle, first order)."""
    out = {}
    for i, j in (("X", "Y"), ("X", "Z"), ("Y", "Z")):
        a = slope(tables, j, "XYZ".index(i))   # d(d_i)/d(q_j)
        b = slope(tables, i, "XYZ".index(j))   # d(d_j)/d(q_i)
        if a is None and b is None:
            continue
        out[f"{i.lower()}{j.lower()}_skew"] = (a or 0.0) + (b or 0.0)
    return out


def export(tables, **_) -> ExportResult:
    f = skew_factors(tables)
    carried = {}
    for key in f:
        i, j = key[0].upper(), key[1].upper()
        if j in tables.tables:
            carried[(j, f"E{i}{j}")] = LINEAR
    notes = ["load with SKEW_PROFILE LOAD=mtcomp (e.g. at the start of every print, after homing)"]
    if not f:
        notes.append("no pair of X, Y, Z axes has a table: all skew factors 0")
    result = ExportResult(NAME, {}, True, carried, notes)
    head = readme_text(result, tables, ["mtcomp export: Klipper skew correction"])
    body = ["[skew_correction]", "", f"[skew_correction {PROFILE}]"]
    for key in ("xy_skew", "xz_skew", "yz_skew"):
        body.append(f"{key} = {f.get(key, 0.0) + 0.0:.9f}")
    text = "\n".join("# " + line if line else "#" for line in head.rstrip("\n").split("\n"))
    result.files = {"skew.cfg": text + "\n\n" + "\n".join(body) + "\n"}
    return result

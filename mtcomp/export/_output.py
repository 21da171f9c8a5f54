"""What an exporter returns, what it left out, and writing it safely."""
from __future__ import annotations

import os
import shutil
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..io.atomic import atomic_write, check_output_path
# the writers import FULL, LINEAR, MEAN from here
from ._ends import ends_sentence
from ._tables import FULL, LINEAR, MEAN, component_names, fit_line  # noqa: F401

UM_PER_MM = 1e3
URAD_PER_RAD = 1e6

#: how much of a component an exporter carries


@dataclass
class ExportResult:
    """Files of one export, in memory until written.

    files : relative file name -> text. single_file : True when OUT is one file (the only entry).
    carried : (axis, component name) -> FULL, MEAN or LINEAR: what the controller takes.
    notes : sentences for the README and the summary (limits, signs, what was left out).
    """

    format: str
    files: dict
    single_file: bool = False
    carried: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)
    uncarried: tuple | None = None

    def not_carried(self, tables) -> tuple[list, float | None]:
        """(lines, largest um): the model's single-valued errors these tables do not carry
        (:func:`mtcomp.export._uncarried.uncarried_lines`), computed once."""
        if self.uncarried is None:
            from ._uncarried import uncarried_lines
            self.uncarried = (uncarried_lines(tables.fitted, tables, self.carried, self.format)
                              if tables.fitted is not None and tables.pose is not None else ([], None))
        return self.uncarried


def sign_factor_and_note(sign: str | None, what: str) -> tuple[float, str]:
    """For a controller whose sign is not public: (factor on the error, the loud note).

    sign : 'correction' (default: the table holds minus the error) or 'error'."""
    sign = sign or "correction"
    other = "error" if sign == "correction" else "correction"
    text = "minus the error" if sign == "correction" else "the error, actual minus nominal"
    return (-1.0 if sign == "correction" else 1.0,
            f"{what} are the {sign} ({text}): THIS SIGN IS NOT PUBLIC. Check one point on the machine "
            f"and rerun with --sign {other} if the error doubles instead of vanishing")


def slope(tables, moving: str, column: int) -> float | None:
    """Least-squares slope (mm/mm) of component ``column`` of axis ``moving`` (mean of directions)
    over its table, or None when the axis has no table."""
    t = tables.tables.get(moving)
    k = None if t is None else ~t.held      # the points inside the data's region (beyond: held)
    if k is None or k.sum() < 2:
        return None
    return fit_line(t.positions[k], t.mean[k, column])[1]


#: the pose the per-axis remaining figures hold at (the tables' own: each axis moving alone)
ONE_POSE = "with only that axis moving, the others at the one pose the tables are read at"

#: what is left out is said from this size on (um, urad): below it a fit's rounding (a component
#: the data held at zero, to 1e-3 urad), no error a table would carry
LEFT_OUT_FLOOR = 0.01


def left_out(tables, carried: dict) -> tuple[list, dict]:
    """Lines on what the tables do not carry, and the peak remaining translation per axis (mm).

    For each axis table and component: the part not carried (the whole component, its direction
    dependence, or what a straight line leaves), its largest magnitude over the grid's points
    inside the data's region (beyond it a table holds its end value, or a rotary's ramps to zero).
    """
    lines, worst = [], {}
    for a, t in tables.tables.items():
        k = ~t.held
        pos = t.positions[k]
        rem = np.zeros_like(t.forward[k])
        for j, name in enumerate(component_names(a)):
            how = carried.get((a, name))
            fwd, rev = t.forward[k, j], t.reverse[k, j]
            if how == FULL:
                r_f, r_r = 0 * fwd, 0 * rev
            elif how == MEAN:
                m = 0.5 * (fwd + rev)
                r_f, r_r = fwd - m, rev - m
            elif how == LINEAR:
                c0, c1 = fit_line(pos, 0.5 * (fwd + rev))
                line = c0 + c1 * pos
                r_f, r_r = fwd - line, rev - line
            else:
                r_f, r_r = fwd, rev
            rem[:, j] = np.where(np.abs(r_f) >= np.abs(r_r), r_f, r_r)
        trans = np.linalg.norm(rem[:, :3], axis=1)
        worst[a] = float(trans.max()) if len(trans) else 0.0
        # a straightness the table leaves (its values rest on what the data did not determine):
        # no size to give, and the remaining figure above does not count it
        lines += [f"{component_names(a)[j]} of axis {a}: left out all of it: not determined by the "
                  "data (not in the remaining figure)"
                  for j in getattr(t, "left", ())]
        for j, name in enumerate(component_names(a)):
            peak = np.nanmax(np.abs(rem[:, j])) if np.isfinite(rem[:, j]).any() else np.nan
            how = carried.get((a, name))
            if not np.isfinite(peak):
                if j >= 3:
                    lines.append(f"{name} of axis {a}: not evaluated (the model's rotations are not available)")
                continue
            scale, unit = (URAD_PER_RAD, "urad") if j >= 3 else (UM_PER_MM, "um")
            if peak * scale < LEFT_OUT_FLOOR:
                continue
            what = {FULL: None, MEAN: "its direction dependence (backlash)",
                    LINEAR: "what a straight line leaves (curvature)"}.get(how, "all of it")
            if what is None:
                continue
            # angular errors of linear axes act through arms; a rotary axis's own are its positioning
            extra = " (angular*)" if j >= 3 and not t.rotary else ""
            lines.append(f"{name} of axis {a}: left out {what}: up to {peak * scale:.3f} {unit}{extra}")
    if any(line.endswith("(angular*)") for line in lines):
        lines.append("* an angular error: no per-axis table can carry it; its Abbe effect at the "
                     "table pose is inside the translations above, elsewhere it grows with the arm "
                     "(other tool lengths, other positions of the axes)")
    return lines, worst


def region_line(tables, a: str) -> str:
    """One line on the table of axis ``a``: its span, points, where the data reached, what is held
    beyond them, and its reference position."""
    t = tables.tables[a]
    u, f = ("deg", 180 / np.pi) if t.rotary else ("mm", 1.0)
    src = {"data": "the data", "range": "--range", "travel": "the travel (NO data region known)"}
    line = (f"{a}: {t.positions[0] * f:g} .. {t.positions[-1] * f:g} {u}, {len(t.positions)} points, "
            f"from {src.get(tables.region_source.get(a), 'the given grid')}")
    if t.held.any():
        line += f" ({ends_sentence(t)})"
    return line + f"; reference position {t.reference[a] * f:g} {u}"


#: where a table with a backlash is zero, as the generic tables are (mtcomp.export._tables)
MEAN_ZERO = "the mean of the two approach directions, each holding half of it"


def pose_line(tables, backlash_zero: str = MEAN_ZERO) -> str:
    """The sentence saying where the other axes stood while each table was read, and where each
    table is zero (``backlash_zero``: where the model has a backlash, what is zero there)."""
    m = tables.machine
    deg = {a.name: 180 / np.pi if a.is_rotary else 1.0 for a in m.axes}
    ref = next(iter(tables.tables.values())).reference
    pose = tables.pose if tables.pose is not None else [ref[a] for a in m.axis_names]
    return ("component errors are the model's deviation when only that axis moves, every other axis "
            "at " + ", ".join(f"{a}={v * deg[a]:g}" for a, v in zip(m.axis_names, pose))
            + f" (--at; by default each linear axis at the middle of its data, where the least-squares "
            "best 1-D table of an error acting through that axis's arm is read, and a rotary axis at "
            f"its reference position), tool length {m.tool_length:g} mm; each table is zero at its "
            "axis's reference position (" + ", ".join(f"{a}={v * deg[a]:g}" for a, v in ref.items())
            + "; one outside its axis's data region at the region's nearest end; where the model "
            f"has a backlash, {backlash_zero}). "
            "Along a line "
            "through that pose the tables correct what mtcomp compensate corrects, up to one "
            "constant; elsewhere an angular error's arm differs (see 'What the controller cannot "
            "hold')")


def readme_text(result: ExportResult, tables, header: list, backlash_zero: str = MEAN_ZERO) -> str:
    """README.txt beside the tables: how to load them, the limits and signs, what was left out
    (``backlash_zero``: what the tables of an axis with a backlash hold at the reference position)."""
    lines = list(header)
    lines += ["", "Region of each table (where the model's data reached; positions are machine "
              "coordinates):"]
    for a, t in tables.tables.items():
        lines.append("  " + region_line(tables, a))
    if tables.tables:
        lines.append("  " + pose_line(tables, backlash_zero))
    lines += ["", "Notes:"] + [f"  - {n}" for n in tables.notes + result.notes]
    rest, worst = left_out(tables, result.carried)
    lines += ["", "What the controller cannot hold (left out of these files):"]
    lines += [f"  - {r}" for r in rest] or ["  - nothing above 0.0005 um / urad"]
    lines += [f"  remaining along {a} {ONE_POSE} (largest translation not carried): "
              f"{w * UM_PER_MM:.3f} um" for a, w in worst.items()]
    single, together = result.not_carried(tables)
    if single:
        lines += ["", "Single-valued errors of the model no table carries (value +- standard error; "
                  "the tool-tip error each makes over the volume the data reached, linear axes at "
                  "their ends, rotary axes swept; zero where the tables are read; a value the data "
                  "do not determine is named without a value):"]
        lines += [f"  - {s}" for s in single]
        if together is not None:
            lines.append(f"  remaining over the volume from these together: up to {together:.2f} um "
                         "at the tool tip (those with a standard error; on top of the figures above, "
                         "but for a squareness listed here: it is also the slope of its straightness "
                         "above)")
    return "\n".join(lines) + "\n"


def write_result(result: ExportResult, out, inputs=()) -> list[Path]:
    """Write the files: OUT is the file itself (single-file formats) or a directory that is created
    (or whose files of the same names are replaced). Everything is written to temporary files first
    and renamed at the end; an input is never overwritten."""
    as_given = str(out)
    out = Path(out)
    if result.single_file:
        (name, text), = result.files.items()
        if out.is_dir() or as_given.endswith(("/", os.sep)):
            # a directory (or a path written as one): the file goes inside it, under its own name
            if not out.is_dir():
                raise InputError(f"the {result.format} format writes one file; no such directory", out)
            out = out / name
        check_output_path(out, list(inputs))
        with atomic_write(out) as f:
            f.write(text)
        return [out]
    if out.exists() and not out.is_dir():
        raise InputError(f"the {result.format} format writes a directory of files; this is a file", out)
    targets = [out / name for name in result.files]
    for t in targets:
        if out.is_dir():
            check_output_path(t, list(inputs))
    parent = out.resolve().parent
    if not parent.is_dir():
        raise InputError(f"output folder {parent} does not exist", out)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".part", dir=parent))
    try:
        for name, text in result.files.items():
            with open(tmp / name, "w", encoding="utf-8", newline="\n") as f:
                f.write(text)
        if not out.exists():
            os.replace(tmp, out)
        else:
            for name in result.files:
                os.replace(tmp / name, out / name)
            shutil.rmtree(tmp, ignore_errors=True)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return targets

"""LinuxCNC: a COMP_FILE per joint, the ini lines, and the squareness as a ``matrixkins`` matrix.

Source: LinuxCNC/linuxcnc, docs/src/config/ini-config.adoc ([JOINT_n] COMP_FILE, COMP_FILE_TYPE) and
src/emc/motion/usrmotintf.cc (``usrmotLoadComp``): each line ``nominal forward reverse``; the reader
stops at the first line that is not three numbers (so no header or comment line at the top); type 0:
the columns are the positions actually reached moving forward / reverse to ``nominal`` and the
motion module adds ``nominal - column``; type 1: the columns are that trim itself, added to the
commanded joint position. Nominals ascending, linear interpolation, at most 256 lines per joint.
``matrixkins`` (tests/matrixkins in the same repository): joint = C . axis coordinates.
"""
from __future__ import annotations

import numpy as np

from ._output import FULL, LINEAR, ExportResult, readme_text, slope
from ._reversal import one_direction_axes
from ._tables import ZERO, component_names, own_column

MAX_POINTS = 256
NAME = "linuxcnc"
SINGLE_FILE = False
LINEAR_ONLY = False
INCLUDE_END = True
DECIMALS = 6  # machine units (mm, deg): 1 nm


def comp_lines(table, column: int, comp_type: int, factor: float, read: str | None = None) -> list[str]:
    """Lines ``nominal forward reverse`` of one joint (machine units: mm or deg); ``read`` '+' or
    '-': the model's data read the axis from that side only, and the other column carries no
    correction (the reversal there is not measured: what compensate leaves uncorrected)."""
    out = []
    forward, reverse = table.forward[:, column], table.reverse[:, column]
    if read is not None:
        none = np.zeros_like(forward)
        forward, reverse = (forward, none) if read == "+" else (none, reverse)
    for s, ef, er in zip(table.positions, forward, reverse):
        nom = s * factor
        if comp_type == 1:
            fwd, rev = -ef * factor + 0.0, -er * factor + 0.0
        else:
            fwd, rev = nom + ef * factor, nom + er * factor
        out.append(f"{nom:.{DECIMALS}f} {fwd:.{DECIMALS}f} {rev:.{DECIMALS}f}")
    return out


def measured(table, column: int) -> bool:
    """False when the component ``column`` of ``table`` is zero everywhere (to 1e-12 mm): the model
    holds it at zero, no data determined it."""
    return bool(np.nanmax(np.abs(table.mean[:, column])) > ZERO)


def backlash_comment(tables, a: str, read: str | None = None) -> str:
    """The ini comment on BACKLASH for axis ``a``: where the reversal is, or that there is none;
    ``read``: the one side the model's data read the axis from (:func:`comp_lines`)."""
    if read is not None:
        other = "reverse" if read == "+" else "forward"
        return (f"# BACKLASH is ignored when COMP_FILE is set; the data read {a} approaching in "
                f"{read} only: the {other} column carries no correction (its reversal not measured)")
    if tables.has_backlash(a):
        return "# BACKLASH is ignored when COMP_FILE is set: the reversal is in the two columns"
    line = ("# BACKLASH is ignored when COMP_FILE is set, and this model holds no reversal: the two "
            "columns are equal")
    if a in tables.unheld_reversal:
        mean, _, unit = tables.unheld_reversal[a]
        line += (f". ITS DATA SHOW ONE ({mean:+.1f} {unit}, mean up minus mean down): fit the model "
                 "with mtcomp diagnose and export again (README.txt)")
    return line


def export(tables, comp_type: int = 1, **_) -> ExportResult:
    m = tables.machine
    files, carried, notes = {}, {}, []
    ini = ["# paste into the machine's INI file (one [JOINT_n] per axis, trivkins order assumed: "
           "joint n = axis n of " + " ".join(m.axis_names) + ")"]
    one_side = one_direction_axes(tables.fitted) if tables.fitted is not None else {}
    for n, a in enumerate(m.axis_names):
        t = tables.tables.get(a)
        if t is None:
            continue
        j = own_column(m, a)
        factor = 180.0 / 3.141592653589793 if t.rotary else 1.0
        name = f"{a.lower()}.comp"
        files[name] = "\n".join(comp_lines(t, j, comp_type, factor, one_side.get(a))) + "\n"
        carried[(a, component_names(a)[j])] = FULL
        ini += ["", f"[JOINT_{n}]", f"COMP_FILE = {name}", f"COMP_FILE_TYPE = {comp_type}",
                backlash_comment(tables, a, one_side.get(a))]
    files["ini_lines.txt"] = "\n".join(ini) + "\n"
    # squareness (and the linear part of every cross straightness) as matrixkins C = I - S
    hal = ["# matrixkins: [KINS] KINEMATICS = matrixkins; joint = C . axis position",
           "# C = I - S, S[i][j] = slope of the deviation along i as axis j moves (least squares over "
           "its table); the diagonal stays 1 (the COMP_FILEs carry each axis's own scale)"]
    linear = [a for a in "XYZ" if a in tables.tables]
    unmeasured = []
    for i in "XYZ":
        for jx in "XYZ":
            if i == jx or i not in m.axis_names or jx not in linear:
                continue
            s = slope(tables, jx, "XYZ".index(i))
            name = f"C_{i.lower()}{jx.lower()}"
            if not measured(tables.tables[jx], "XYZ".index(i)):
                hal.append(f"# {name}: not measured: the model holds E{i}{jx} at zero (no data determined "
                           "it); written as 0")
                unmeasured.append(name)
            hal.append(f"setp matrixkins.{name} {round(-s, 9) + 0.0:.9f}")
            carried[(jx, f"E{i}{jx}")] = LINEAR
    missing = [f"C_{i.lower()}{jx.lower()}" for jx in "XYZ" if jx in m.axis_names and jx not in linear
               for i in "XYZ" if i != jx and i in m.axis_names]
    if missing:
        hal.append(f"# {', '.join(missing)}: not written: not measured (no table of axis "
                   f"{' '.join(sorted({c[-1].upper() for c in missing}))}); matrixkins keeps their values (0 unless set elsewhere)")
    if any(line.startswith("setp") for line in hal):
        files["matrixkins.hal"] = "\n".join(hal) + "\n"
    said = ([f"{', '.join(unmeasured)} written as 0 (the model holds those errors at zero: no data "
             "determined them)"] if unmeasured else []) + (
        [f"{', '.join(missing)} not written (those axes have no table)"] if missing else [])
    if said:
        notes.append("matrixkins.hal: not measured: " + "; ".join(said))
    notes.append(f"COMP_FILE_TYPE {comp_type}: " + (
        "columns are trims added to the command, -(actual - nominal)" if comp_type == 1 else
        "columns are the positions actually reached, nominal + (actual - nominal)"))
    notes.append("a COMP_FILE corrects each joint along its own line only; straightness beyond the "
                 "straight line of matrixkins, angular errors and Abbe terms stay")
    result = ExportResult(NAME, files, False, carried, notes)
    header = ["mtcomp export: LinuxCNC compensation files",
              "",
              "*.comp       one per joint: lines 'nominal forward reverse' in machine units (mm, deg),",
              "             no header line (LinuxCNC stops reading at the first line that is not three",
              f"             numbers), nominal ascending, at most {MAX_POINTS} lines, linear interpolation",
              "ini_lines.txt  the [JOINT_n] COMP_FILE / COMP_FILE_TYPE lines to paste",
              "matrixkins.hal the squareness as setp lines for the matrixkins kinematics (if X, Y, Z"
              " have tables)"]
    files["README.txt"] = readme_text(result, tables, header)
    return result

"""Turn the hole positions of a QIF 2 results file into mtcomp points files, one per measured part.

A CMM that inspects drilled or milled holes reports each hole's axis point (nominal, from the CAD,
and measured) in the part's datum frame. A hole's centre is where the spindle axis stood when the
hole was cut, so its deviation (measured minus nominal) is a deviation of the tool position at that
pose: mtcomp's *points* kind, with the CMM's alignment to the part as the file's set-up (a
translation and a rotation, fitted by `mtcomp identify`). What this script needs besides the QIF
file is where the part sat in the program: ``--part-to-program X0,Y0,DEG`` maps a part point
(x, y) to the program's coordinates ``(X0, Y0) + R(DEG) (x, y)`` (read it off the program: the
position of two holes is enough), ``--work-offset`` adds the work offset (G54) to give machine
positions, and ``--top-z`` is the part's top face in part coordinates (program Z 0).

    python examples/qif_holes_to_points.py PlateResults.QIF OUT/ \\
        --part-to-program 123.1752,-2.4121,180 --work-offset 0,0,0

writes OUT/part01.csv ... (columns x_mm, y_mm, z_mm, dx_um, dy_um, and the hole's name and
diameters for the reader's eye), one per MeasurementResults of the file, in the file's order. Only
cylinders are taken (slots and planes have no hole axis), and a cylinder whose measured axis point
lies more than ``--max-offset-mm`` from its nominal is left out with a note (the CMM fitted another
feature). The measured Z of a hole is its nominal projected onto the plane, so no dz is written.
Bad input: one line on stderr naming the file and the problem, exit status 2.
"""
from __future__ import annotations

import argparse
import csv
import math
import sys
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

QIF_NS = "{http://qifstandards.org/xsd/qif2}"


class QifError(Exception):
    """A QIF file this script cannot read; the message names the file and the problem."""


@dataclass(frozen=True)
class Hole:
    """One hole of one part, in the part's datum frame (mm)."""
    name: str
    nominal: tuple[float, float, float]
    measured: tuple[float, float, float]
    nominal_diameter: float
    measured_diameter: float


@dataclass(frozen=True)
class Part:
    """One measured part: its serial number (blank when the file has none) and its holes."""
    serial: str
    holes: list[Hole]


def _floats(elem, path: Path, what: str) -> tuple[float, ...]:
    if elem is None or not (elem.text or "").split():
        raise QifError(f"{path}: {what} is missing")
    try:
        return tuple(float(v) for v in elem.text.split())
    except ValueError:
        raise QifError(f"{path}: {what} is not a list of numbers: {elem.text.strip()!r}") from None


def _linear_unit_factor(root, path: Path) -> float:
    """mm per file unit (QIF files state their linear unit; millimetres and inches are read)."""
    name = root.findtext(f"{QIF_NS}FileUnits/{QIF_NS}PrimaryUnits/{QIF_NS}LinearUnit/{QIF_NS}UnitName")
    name = (name or "mm").strip().lower()
    factors = {"mm": 1.0, "millimeter": 1.0, "millimetre": 1.0, "in": 25.4, "inch": 25.4}
    if name not in factors:
        raise QifError(f"{path}: linear unit {name!r} is not mm or inch")
    return factors[name]


def _nominal_cylinders(root, path: Path, scale: float) -> dict[str, tuple[str, tuple, float]]:
    """Feature item id -> (name, nominal axis point in mm, nominal diameter in mm)."""
    diameters = {d.get("id"): float(d.findtext(f"{QIF_NS}Diameter", "nan")) * scale
                 for d in root.iter(f"{QIF_NS}CylinderFeatureDefinition")}
    nominals = {}
    for nom in root.iter(f"{QIF_NS}CylinderFeatureNominal"):
        point = _floats(nom.find(f"{QIF_NS}Axis/{QIF_NS}AxisPoint"), path,
                        f"the axis point of cylinder nominal {nom.get('id')}")
        definition = nom.findtext(f"{QIF_NS}FeatureDefinitionId", "").strip()
        nominals[nom.get("id")] = (tuple(v * scale for v in point), diameters.get(definition, math.nan))
    items = {}
    for item in root.iter(f"{QIF_NS}CylinderFeatureItem"):
        nominal_id = item.findtext(f"{QIF_NS}FeatureNominalId", "").strip()
        if nominal_id not in nominals:
            raise QifError(f"{path}: cylinder item {item.get('id')} names nominal {nominal_id!r}, "
                           f"which the file does not define")
        name = item.findtext(f"{QIF_NS}FeatureName", "").strip() or f"CYLINDER_{item.get('id')}"
        items[item.get("id")] = (name, *nominals[nominal_id])
    return items


def read_qif_holes(path) -> list[Part]:
    """Every measured part of a QIF 2 results file with its cylinders (nominal and measured axis
    point and diameter, mm), in the file's order of MeasurementResults."""
    path = Path(path)
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError) as exc:
        raise QifError(f"{path}: not a readable XML file ({exc})") from None
    scale = _linear_unit_factor(root, path)
    items = _nominal_cylinders(root, path, scale)
    serials = {c.get("id"): (c.findtext(f"{QIF_NS}SerialNumber") or "").strip()
               for c in root.iter(f"{QIF_NS}ActualComponent")}
    parts = []
    for results in root.iter(f"{QIF_NS}MeasurementResults"):
        holes = []
        for actual in results.iter(f"{QIF_NS}CylinderFeatureActual"):
            item_id = actual.findtext(f"{QIF_NS}FeatureItemId", "").strip()
            if item_id not in items:
                raise QifError(f"{path}: measured cylinder {actual.get('id')} names feature item "
                               f"{item_id!r}, which the file does not define")
            name, nominal, nominal_diameter = items[item_id]
            measured = _floats(actual.find(f"{QIF_NS}Axis/{QIF_NS}AxisPoint"), path,
                               f"the measured axis point of {name} (cylinder {actual.get('id')})")
            diameter = actual.findtext(f"{QIF_NS}Diameter")
            holes.append(Hole(name, nominal, tuple(v * scale for v in measured), nominal_diameter,
                              float(diameter) * scale if diameter else math.nan))
        component = results.findtext(f"{QIF_NS}ActualComponentIds/{QIF_NS}Id", "").strip()
        parts.append(Part(serials.get(component, ""), holes))
    if not parts:
        raise QifError(f"{path}: no MeasurementResults (a QIF plan or model without measured parts)")
    return parts


def points_rows(part: Part, part_to_program=(0.0, 0.0, 0.0), work_offset=(0.0, 0.0, 0.0),
                top_z=0.0, max_offset_mm=0.5):
    """The rows of the points file of one part, and the names of the holes left out.

    part_to_program : (X0 mm, Y0 mm, angle deg): a part point (x, y) sits at (X0, Y0) + R (x, y) in
        the program; deviations turn with R. work_offset : (3,) mm added to give machine positions.
    """
    x0, y0, angle = part_to_program
    c, s = math.cos(math.radians(angle)), math.sin(math.radians(angle))
    rows, left_out = [], []
    for hole in part.holes:
        dx, dy = hole.measured[0] - hole.nominal[0], hole.measured[1] - hole.nominal[1]
        if math.hypot(dx, dy) > max_offset_mm:
            left_out.append(hole.name)
            continue
        x, y, z = hole.nominal
        rows.append({
            "x_mm": f"{x0 + c * x - s * y + work_offset[0]:.4f}",
            "y_mm": f"{y0 + s * x + c * y + work_offset[1]:.4f}",
            "z_mm": f"{z - top_z + work_offset[2]:.4f}",
            "dx_um": f"{1000.0 * (c * dx - s * dy):.1f}",
            "dy_um": f"{1000.0 * (s * dx + c * dy):.1f}",
            "feature": hole.name,
            "diameter_mm": f"{hole.nominal_diameter:.4f}",
            "measured_diameter_mm": f"{hole.measured_diameter:.4f}",
        })
    return rows, left_out


def _triple(text: str, what: str, n: int = 3) -> tuple[float, ...]:
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != n:
        raise argparse.ArgumentTypeError(f"{what} takes {n} comma-separated numbers, not {text!r}")
    return values


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("qif", type=Path, help="QIF 2 results file")
    parser.add_argument("out", type=Path, help="folder for the points files (created)")
    parser.add_argument("--part-to-program", default="0,0,0",
                        type=lambda t: _triple(t, "--part-to-program"), metavar="X0,Y0,DEG")
    parser.add_argument("--work-offset", default="0,0,0",
                        type=lambda t: _triple(t, "--work-offset"), metavar="X,Y,Z")
    parser.add_argument("--top-z", type=float, default=0.0, help="part z of program Z 0, mm")
    parser.add_argument("--max-offset-mm", type=float, default=0.5)
    args = parser.parse_args(argv)
    try:
        parts = read_qif_holes(args.qif)
    except QifError as exc:
        print(exc, file=sys.stderr)
        return 2
    args.out.mkdir(parents=True, exist_ok=True)
    for number, part in enumerate(parts, start=1):
        rows, left_out = points_rows(part, args.part_to_program, args.work_offset, args.top_z,
                                     args.max_offset_mm)
        if left_out:
            print(f"part {number}: left out {', '.join(left_out)} (measured more than "
                  f"{args.max_offset_mm} mm from nominal)", file=sys.stderr)
        target = args.out / f"part{number:02d}.csv"
        partial = target.with_suffix(".csv.part")
        with open(partial, "w", newline="") as handle:
            writer = csv.DictWriter(handle, fieldnames=list(rows[0]) if rows else ["x_mm"])
            writer.writeheader()
            writer.writerows(rows)
        partial.replace(target)
        print(f"{target}: {len(rows)} holes, serial {part.serial or '(none)'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

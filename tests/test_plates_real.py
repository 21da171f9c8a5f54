"""Hole positions of machined plates from a QIF results file to mtcomp points files
(examples/qif_holes_to_points.py), on a hand-made QIF file and on the NIST plates
(tests/data/real/plates, public US government data, SOURCES.md there)."""
from __future__ import annotations

import csv
import re
import runpy
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from mtcomp.measurement.files import read_measurements

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "examples" / "qif_holes_to_points.py"
PLATES = ROOT / "tests" / "data" / "real" / "plates"
#: a part point (x, y) of the NIST plates is at program (123.175 - x, -2.412 - y) mm
NIST_TRANSFORM = (123.175, -2.412, 180.0)

qif = SimpleNamespace(**runpy.run_path(str(SCRIPT), run_name="qif_holes_to_points"))

_CYLINDER = """
<CylinderFeatureDefinition id="{d}"><Diameter>{diam}</Diameter></CylinderFeatureDefinition>"""
_NOMINAL = """
<CylinderFeatureNominal id="{n}"><FeatureDefinitionId>{d}</FeatureDefinitionId>
<Axis><AxisPoint>{x} {y} {z}</AxisPoint><Direction>0 0 -1</Direction></Axis></CylinderFeatureNominal>"""
_ITEM = """
<CylinderFeatureItem id="{i}"><FeatureNominalId>{n}</FeatureNominalId><FeatureName>{name}</FeatureName>
</CylinderFeatureItem>"""
_ACTUAL = """
<CylinderFeatureActual id="{a}"><FeatureItemId>{i}</FeatureItemId>
<Axis><AxisPoint>{x} {y} {z}</AxisPoint><Direction>0 0 -1</Direction></Axis><Diameter>{diam}</Diameter>
</CylinderFeatureActual>"""


def _qif_text(unit="mm"):
    """Two cylinders (H1 at (10, 20, 5), 4 mm; H2 at (30, 20, 5), 10 mm, measured 2 mm away on the
    second part), a slot, and two measured parts, the second without a serial number."""
    holes = [(1, "H1", 10.0, 20.0, 4.0), (2, "H2", 30.0, 20.0, 10.0)]
    measured = [{"H1": (10.003, 19.996, 3.99), "H2": (30.0, 20.001, 10.02)},
                {"H1": (9.999, 20.0, 4.01), "H2": (32.0, 20.0, 6.4)}]
    defs = "".join(_CYLINDER.format(d=10 + k, diam=diam) for k, _, _, _, diam in holes)
    noms = "".join(_NOMINAL.format(n=20 + k, d=10 + k, x=x, y=y, z=5.0) for k, _, x, y, _ in holes)
    items = "".join(_ITEM.format(i=30 + k, n=20 + k, name=name) for k, name, _, _, _ in holes)
    results, components = "", ""
    for p, part in enumerate(measured):
        actuals = "".join(_ACTUAL.format(a=100 * (p + 1) + k, i=30 + k, x=part[name][0],
                                         y=part[name][1], z=5.0, diam=part[name][2])
                          for k, name, _, _, _ in holes)
        slot = ('<OppositeParallelLinesFeatureActual id="99"><FeatureItemId>98</FeatureItemId>'
                '</OppositeParallelLinesFeatureActual>')
        results += (f"<MeasurementResults id='{50 + p}'><MeasuredFeatures><FeatureActuals>{actuals}"
                    f"{slot}</FeatureActuals></MeasuredFeatures><ActualComponentIds n='1'>"
                    f"<Id>{60 + p}</Id></ActualComponentIds></MeasurementResults>")
        serial = "<SerialNumber>PLATE_A01</SerialNumber>" if p == 0 else ""
        components += (f"<ActualComponentSet><ActualComponent id='{60 + p}'>{serial}"
                       f"</ActualComponent></ActualComponentSet>")
    return (f'<?xml version="1.0"?><QIFDocument xmlns="http://qifstandards.org/xsd/qif2">'
            f"<FileUnits><PrimaryUnits><LinearUnit><UnitName>{unit}</UnitName></LinearUnit>"
            f"</PrimaryUnits></FileUnits>"
            f"<Features><FeatureDefinitions>{defs}</FeatureDefinitions><FeatureNominals>{noms}"
            f"</FeatureNominals><FeatureItems>{items}</FeatureItems></Features><MeasurementsResults>"
            f"<MeasurementResultsSet>{results}</MeasurementResultsSet><ActualComponentSets>{components}"
            f"</ActualComponentSets></MeasurementsResults></QIFDocument>")


def _read_rows(path):
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


def test_read_qif_holes_gives_each_parts_cylinders(tmp_path):
    path = tmp_path / "two.qif"
    path.write_text(_qif_text())
    parts = qif.read_qif_holes(path)
    assert [p.serial for p in parts] == ["PLATE_A01", ""]
    assert [h.name for h in parts[0].holes] == ["H1", "H2"]          # the slot is no hole
    h1 = parts[0].holes[0]
    assert h1.nominal == (10.0, 20.0, 5.0) and h1.measured == (10.003, 19.996, 5.0)
    assert (h1.nominal_diameter, h1.measured_diameter) == (4.0, 3.99)
    inch = tmp_path / "inch.qif"
    inch.write_text(_qif_text("inch"))
    h1_inch = qif.read_qif_holes(inch)[0].holes[0]
    np.testing.assert_allclose(h1_inch.measured, (254.0762, 507.8984, 127.0), rtol=0, atol=1e-9)
    assert h1_inch.nominal_diameter == pytest.approx(101.6, rel=0, abs=1e-12)


@pytest.mark.parametrize("transform, xy, dxy", [
    # part (10, 20), error (+3, -4) um: no turn; turned by 180 deg about (100, 50); by 90 deg
    ((0.0, 0.0, 0.0), (10.0, 20.0), (3.0, -4.0)),
    ((100.0, 50.0, 180.0), (90.0, 30.0), (-3.0, 4.0)),
    ((100.0, 50.0, 90.0), (80.0, 60.0), (4.0, 3.0)),
])
def test_points_rows_turn_positions_and_errors_into_the_program_frame(tmp_path, transform, xy, dxy):
    path = tmp_path / "two.qif"
    path.write_text(_qif_text())
    part = qif.read_qif_holes(path)[0]
    rows, left_out = qif.points_rows(part, transform, work_offset=(1.0, 2.0, 3.0), top_z=5.0)
    assert left_out == []
    h1 = rows[0]
    got = [float(h1[c]) for c in ("x_mm", "y_mm", "z_mm", "dx_um", "dy_um")]
    np.testing.assert_allclose(got, [xy[0] + 1.0, xy[1] + 2.0, 3.0, *dxy], rtol=0, atol=1e-9)


def test_converter_leaves_out_a_cylinder_measured_far_away_and_writes_points_files(tmp_path):
    path = tmp_path / "two.qif"
    path.write_text(_qif_text())
    res = subprocess.run([sys.executable, str(SCRIPT), str(path), str(tmp_path / "out")],
                         capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    assert "part 2: left out H2" in res.stderr
    second = _read_rows(tmp_path / "out" / "part02.csv")
    assert [r["feature"] for r in second] == ["H1"]
    assert [float(second[0]["dx_um"]), float(second[0]["dy_um"])] == [-1.0, 0.0]
    data = read_measurements(tmp_path / "out" / "part01.csv")
    assert data.kind == "points" and data.measured == ("dx_um", "dy_um")
    np.testing.assert_allclose(data.deviation[:, :2], [[3e-3, -4e-3], [0.0, 1e-3]], rtol=0, atol=1e-12)


@pytest.mark.parametrize("text, problem", [
    ("not xml at all", "not a readable XML file"),
    ('<QIFDocument xmlns="http://qifstandards.org/xsd/qif2"/>', "no MeasurementResults"),
])
def test_converter_refuses_bad_input_in_one_line_and_writes_nothing(tmp_path, text, problem):
    path = tmp_path / "bad.qif"
    path.write_text(text)
    res = subprocess.run([sys.executable, str(SCRIPT), str(path), str(tmp_path / "out")],
                         capture_output=True, text=True)
    assert res.returncode == 2
    assert res.stderr.count("\n") == 1 and str(path) in res.stderr and problem in res.stderr
    assert "Traceback" not in res.stderr
    assert not (tmp_path / "out").exists()


def test_nist_plates_have_17_holes_each_in_the_program_frame():
    parts = qif.read_qif_holes(PLATES / "PlateResults_20_samples.QIF")
    assert len(parts) == 20
    assert parts[0].serial.startswith("PLATE_RESULTS_A01") and parts[19].serial == ""
    for part in parts:
        rows, left_out = qif.points_rows(part, NIST_TRANSFORM, top_z=4.5)
        assert left_out == ["CYLINDER3"] and len(rows) == 17
    rows, _ = qif.points_rows(parts[0], NIST_TRANSFORM, top_z=4.5)
    corner = next(r for r in rows if r["feature"] == "CYLINDER1")
    # the file: nominal (101.73, 5.5), measured (101.715, 5.48) mm; turned by 180 deg
    assert [float(corner[c]) for c in ("x_mm", "y_mm", "dx_um", "dy_um")] == [21.445, -7.912, 15.0, 20.0]


def _program_holes():
    """Hole centres the program of plate 1 cuts, in mm: its four G81 spot-drill positions and the
    centre of the 0.093 in end mill's first helix (the arc from N6690's end point, centre I J of
    N6700), read here with regular expressions, not with mtcomp."""
    text = (PLATES / "NIST_MTC_CRADA_PLATE-1.NC").read_text()
    block = re.search(r"G99G81Z-\.17R\.1F2\.\n(.*?)G80", text, re.S)
    first = re.search(r"N9820G0G90G54X([-.\d]+)Y([-.\d]+)", text)
    x, y = float(first[1]), float(first[2])
    spots = [(x, y)]
    for line in block[1].split():
        x = float(m[1]) if (m := re.search(r"X([-.\d]+)", line)) else x
        y = float(m[1]) if (m := re.search(r"Y([-.\d]+)", line)) else y
        if re.search(r"[XY]", line):
            spots.append((x, y))
    t1 = text[text.index("N6640T1M6"):]          # block numbers repeat in the program
    end = re.search(r"N6690G3X([-.\d]+)Y([-.\d]+)", t1)
    ij = re.search(r"N6700X[-.\d]+Z[-.\d]+I([-.\d]+)J([-.\d]+)", t1)
    helix = (float(end[1]) + float(ij[1]), float(end[2]) + float(ij[2]))
    return 25.4 * np.array(spots), 25.4 * np.array(helix)


def test_nist_part_frame_is_the_program_frame_turned_by_180_degrees():
    spots, helix = _program_holes()
    rows, _ = qif.points_rows(qif.read_qif_holes(PLATES / "PlateResults_20_samples.QIF")[0],
                              NIST_TRANSFORM, top_z=4.5)
    where = {r["feature"]: (float(r["x_mm"]), float(r["y_mm"])) for r in rows}
    corners = ["CYLINDER1", "CYLINDER-137", "CYLINDER2", "CYLINDER-140"]
    order = [min(corners, key=lambda c: np.hypot(*np.subtract(where[c], s))) for s in spots]
    assert sorted(order) == sorted(corners)
    np.testing.assert_allclose([where[c] for c in order], spots, rtol=0, atol=0.005)
    # the helix is the 3 mm hole at part (24.393, 25.607): a mirror instead of the turn would put
    # that hole 51 mm away in Y
    np.testing.assert_allclose(where["SIMPLE_HOLE11"], helix, rtol=0, atol=0.005)

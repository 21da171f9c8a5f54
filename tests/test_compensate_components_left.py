"""A block whose correction is undetermined in one tip component only is corrected in the others.

Three plates each read on a CMM in its own alignment (as tests/test_parts_heights_tilt.py) leave
the heights across the table open: a Z correction away from a part's datum has no standard error.
X's and Y's, at the datum's height, have finite ones. A pass over a plate's top face is then
corrected in X and Y, and keeps its Z deviation (BLOCKS.csv ``components_left`` "z", the summary's
``components_left``); main left every block of it uncorrected (its standard error was the largest
of the three components', infinite).

Oracle: the plain-numpy machine of tests/test_parts_heights_tilt.py (no mtcomp code) with X and Y
positioning errors of 30 and -20 um/m added, which the holes read: the truth at the corrected
positions less that at the datum."""
import csv
import json
import re

import numpy as np
import pytest

from mtcomp.cli import main
from test_parts_heights_tilt import PARTS, truth_um as tilt_truth_um, write_parts

DATUM = np.array(PARTS["part3"])


def truth_um(x, y, z):
    """(n, 3) um: the heights' machine of test_parts_heights_tilt with X and Y scale errors."""
    x, y, z = (np.asarray(v, dtype=float) for v in np.broadcast_arrays(x, y, z))
    return tilt_truth_um(x, y, z) + np.stack([30e-3 * x, -20e-3 * y, 0 * x], -1)


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    d = tmp_path_factory.mktemp("left")
    files = write_parts(d, truth_um)
    assert main(["identify", str(d / "vmc.toml"), *files, "-o", str(d / "m.json")]) == 0
    # a pass over part 3's top face (its datum at X200 Y60 Z-150), rows along X
    moves = ["G90 G54", "G0 X20 Y20", "G0 Z0"]
    for k, y in enumerate(range(20, 141, 40)):
        moves += [f"G1 X{180 if k % 2 == 0 else 20} Y{y} F1000", f"G1 Y{y + 40 if y < 140 else y}"]
    moves += ["G0 Z50", "M30"]
    (d / "face.nc").write_text("\n".join(moves) + "\n")
    assert main(["compensate", str(d / "vmc.toml"), str(d / "m.json"), str(d / "face.nc"),
                 "-o", str(d / "out.nc"), "--report", str(d / "blocks.csv"), "--json",
                 str(d / "sum.json"), "--work-offset", "G54=X200,Y60,Z-150"]) == 0
    rows = list(csv.DictReader(open(d / "blocks.csv")))
    return rows, json.loads((d / "sum.json").read_text()), d


def test_the_face_is_corrected_in_x_and_y_and_keeps_its_z(run):
    rows, summary, _ = run
    cut = [r for r in rows if r["rapid"] == "0"]
    assert cut and all(r["components_left"] == "z" and r["corrected"] == "1" for r in cut), cut
    f = lambda r, k: float(r[k])
    # Z's deviation kept (within the planner's never-worse tolerance), Z not moved by more
    assert all(abs(f(r, "ez_after_um") - f(r, "ez_before_um")) <= 0.06 for r in cut)
    assert all(abs(f(r, "cz_um")) <= 0.06 for r in cut)
    part = [r for r in rows if r["components_left"]]           # the cut and the rapid down to it
    assert all(r["components_left"] == "z" and r["corrected"] == "1" for r in part), part
    left = summary["components_left"]
    assert (left["blocks"], left["x"], left["y"], left["z"]) == (len(part), 0, 0, len(part)), left


def test_the_truth_after_is_better_in_x_and_y_and_unchanged_in_z(run):
    """The truth (numpy machine) at the written positions, less that at the datum: X and Y lose
    most of their deviation, no block gets worse in them, and Z's is the uncorrected one."""
    rows, _, _ = run
    cut = [r for r in rows if r["rapid"] == "0"]
    q = np.array([[float(r[k]) for k in ("x_mm", "y_mm", "z_mm")] for r in cut])
    c = np.array([[float(r[k]) for k in ("cx_um", "cy_um", "cz_um")] for r in cut]) * 1e-3
    nominal = q - c + DATUM
    before = truth_um(*nominal.T) - truth_um(*DATUM)
    # written q + c: the tip lands at q + c plus the truth there, wanted at q
    after = c * 1e3 + truth_um(*(nominal + c).T) - truth_um(*DATUM)
    rms = lambda e: np.sqrt(np.mean(e ** 2, axis=0))
    assert rms(before)[0] > 2.0, rms(before)
    assert np.all(rms(after)[:2] <= 0.3 * rms(before)[:2]), (rms(before), rms(after))
    assert np.all(np.abs(after[:, :2]) <= np.abs(before[:, :2]) + 0.3), (before, after)
    np.testing.assert_allclose(after[:, 2], before[:, 2], atol=0.06)


def test_export_writes_x_positioning_and_leaves_its_straightness_in_z(run, tmp_path, capsys):
    """Siemens keeps positioning (EEC) and sag (CEC) tables apart: X's positioning table is
    written (main wrote no table at all, exit 2: X's straightness in Z rests on the open tilts),
    its CEC table into Z is not. Oracle: the numpy machine's X error along X is 30 um/m of scale
    plus the pitch's Abbe effect, 15 urad / 400 mm times the height (0 .. 200 mm under the
    tables' zero): a slope of 30 to 38 um/m."""
    d = run[2]
    out = tmp_path / "siemens"
    assert main(["export", str(d / "vmc.toml"), str(d / "m.json"), "--format", "siemens",
                 "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert "axis X: its table carries its own error and leaves its straightness in Z (EZX)" in err
    eec = (out / "AX_EEC.INI").read_text()
    x = [float(v) for v in re.findall(r"\$AA_ENC_COMP\[0,\d+,AX1\]=([-0-9.eE+]+)", eec)]
    lo = float(re.search(r"\$AA_ENC_COMP_MIN\[0,AX1\]=([-0-9.eE+]+)", eec).group(1))
    hi = float(re.search(r"\$AA_ENC_COMP_MAX\[0,AX1\]=([-0-9.eE+]+)", eec).group(1))
    pos = np.linspace(lo, hi, len(x))
    inside = (pos > -300.0) & (pos < 400.0)          # the plates' span along X
    slope = np.polyfit(pos[inside], np.array(x)[inside] * 1e3, 1)[0]
    assert 0.029 <= slope <= 0.039, slope
    cec = (out / "NC_CEC.INI").read_text()
    pairs = re.findall(r"INPUT_AXIS\[(\d+)\]=\((AX\d)\)\s*\$AN_CEC_OUTPUT_AXIS\[\1\]=\((AX\d)\)", cec)
    assert ("AX1", "AX3") not in {(i, o) for _, i, o in pairs} and pairs, pairs


def test_a_component_left_at_one_node_of_a_contour_is_left_at_all_of_them():
    """Hand-made standard errors (um): contour 1 (nodes 0-2) has z undetermined at node 1 only,
    contour 2 (nodes 4-5, after a rapid at 3) none; node 6 starts contour 3 with x over the limit
    (finite: the block is left whole by the contour gate, not here) and node 7 has y undetermined.
    Left: z at nodes 0-2 (else the cut steps in z where node 1 stops correcting it), y at 6-7."""
    from types import SimpleNamespace
    from mtcomp.planner._partial import PartialRule
    inf = np.inf
    each = np.array([[1, 1, 1], [1, 1, inf], [1, 1, 1], [inf, inf, inf], [1, 1, 1], [1, 1, 1],
                     [9, 1, 1], [1, inf, 1]], dtype=float)
    member = np.array([1, 1, 1, 0, 1, 1, 1, 1], bool)
    start = np.array([0, 0, 0, 0, 0, 0, 1, 0], bool)
    problem = SimpleNamespace(orientation_weight=1.0, machine=SimpleNamespace(axes=[]),
                              regularization_weights=0.0, fitted=SimpleNamespace(uncertainty={}))
    rule = PartialRule(problem, 5.0)
    assert rule.tip_left(each).tolist() == [0, 4, 0, 0, 0, 0, 0, 2]
    assert rule.tip_left(each, member, start).tolist() == [4, 4, 4, 0, 0, 0, 2, 2]

"""compensate says what its corrections assume at zero: an axis the data never moved (Y, on a
campaign of laser runs of X and Z alone) and the angular motions the data held at zero, which act
on a block through its height above the laser's line (the summary's note, SUMMARY.json
``assumed_zero``, the "after" lines, BLOCKS.csv ``assumed_arm_mm``); predict says the same.

Oracles: the independent truth machine (tests/truth) writes the runs, on the line Y = 0, Z = 0 for
X and X = 0, Y = 0 for Z; the arms are the blocks' distances from those lines, by hand."""
import csv
import json

import pytest

from laser_files import xz_lasers
from mtcomp.cli import main

#: blocks on the laser's line of X (nothing assumed), at Y = 80 (Y never moved) and 120 mm below
#: the line (X's and Z's angular motions act over that height)
PROGRAM = """G21 G90 G17
G54
G0 X-100. Y0. Z0.
G1 X100. F500
G0 X-100. Y80. Z-120.
G1 X100.
M30
"""


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    folder = tmp_path_factory.mktemp("xz_lasers")
    paths = xz_lasers(folder)
    model = folder / "model.json"
    assert main(["identify", "xfyz", *paths, "-o", str(model)]) == 0
    prog = folder / "prog.nc"
    prog.write_text(PROGRAM)
    return folder, model, prog


def _compensate(folder, model, prog, capsys, *extra):
    out, rep, js = folder / "out.nc", folder / "blocks.csv", folder / "summary.json"
    capsys.readouterr()
    assert main(["compensate", "xfyz", str(model), str(prog), "-o", str(out), "--report", str(rep),
                 "--json", str(js), "--work-offset", "G54=X0,Y0,Z0", "--subdivide-tol-um", "0",
                 *extra]) == 0
    with open(rep, newline="") as f:
        rows = list(csv.DictReader(f))
    return capsys.readouterr().out, rows, json.loads(js.read_text())


def test_summary_names_what_the_corrections_assume(campaign, capsys):
    text, rows, summary = _compensate(*campaign, capsys)
    note = next(line for line in text.splitlines() if "corrections assume zero" in line)
    assert "Y's errors (never measured: the data held Y at 0 mm, the corrected blocks stand up " \
           "to 80 mm from it)" in note
    assert "X's angular motions" in note and "Z's angular motions" in note
    assert "not in the standard errors" in note
    after = next(line for line in text.splitlines() if line.startswith("predicted tool-tip deviation after"))
    assert after.endswith("(the model's, assuming zero where the note below says)")
    a = summary["assumed_zero"]
    # the two blocks of the second line, not those on the laser's line
    assert a["blocks"] == 2 and a["line"] == 5
    assert a["never_moved"] == {"Y": {"held_mm": 0.0, "largest_distance_mm": pytest.approx(80.0, abs=1e-3)}}
    assert {"X:EAX", "X:EBX", "Z:EAZ", "Z:EBZ"} <= set(a["held_components"])
    # the largest arm: 120 mm below the line of X's runs (more than Y's 80 mm)
    assert a["largest_arm_mm"] == pytest.approx(120.0, abs=3.0)
    arm = {r["line"]: r["assumed_arm_mm"] for r in rows}
    assert arm["3"] == "" and arm["4"] == ""
    assert float(arm["5"]) == pytest.approx(120.0, abs=3.0)
    assert float(arm["6"]) == pytest.approx(120.0, abs=3.0)


def test_no_limit_still_says_so(campaign, capsys):
    # the note does not hang on the standard-error gate: with no limit the same blocks are named
    text, _, summary = _compensate(*campaign, capsys, "--max-correction-sd-um", "0")
    assert "corrections assume zero for Y's errors" in text
    assert summary["assumed_zero"]["blocks"] == 2


def test_on_the_lines_nothing_is_said(campaign, capsys):
    folder, model, _ = campaign
    prog = folder / "line.nc"
    prog.write_text(PROGRAM.split("G0 X-100. Y80.")[0] + "M30\n")
    text, rows, summary = _compensate(folder, model, prog, capsys)
    assert "assume zero" not in text and "assumed_zero" not in summary
    assert "(the model's" not in text
    assert [r["assumed_arm_mm"] for r in rows] == ["", ""]


def test_predict_names_the_same(campaign, capsys, tmp_path):
    _, model, _ = campaign
    pts = tmp_path / "pts.csv"
    pts.write_text("x_mm,y_mm,z_mm,dx_um,dy_um,dz_um\n50,80,-120,0,0,0\n")
    capsys.readouterr()
    assert main(["predict", "xfyz", str(model), str(pts), "-o", str(tmp_path / "pred.csv")]) == 0
    err = capsys.readouterr().err
    assert "the predictions assume zero for Y's errors (never measured: the data held Y at 0 mm)" in err
    assert "X's angular motions" in err


def test_a_combination_of_straightness_profiles_gets_no_arm(tmp_path, capsys):
    """Positioning of X read at three targets only, on the laser's line: X's straightness profiles
    (no laser file names them) are held at zero, and the combinations the data leave open are
    mostly spline directions of those profiles with a trace of an angle. The arm is the motion the
    angles make per unit of angle: on the laser's line (Y = 0, Z = 0) it is 0, by hand (it was
    45667 mm when the whole combination's motion was divided by its trace of an angle)."""
    import numpy as np
    from truth import TruthMachine
    from truth import campaigns as tc
    from truth import profiles as P
    truth = TruthMachine.zero("xfyz")
    truth.components["X"]["EXX"] = P.Linear(0.0, 20e-6)
    laser = tc.laser(truth, tmp_path / "laser_x.csv", np.random.default_rng(7), "X",
                     components=["EXX"], n_targets=3, n_runs=1,
                     static={"Y": 0.0, "Z": 0.0}, noise_um=0.1).path
    model = tmp_path / "model.json"
    assert main(["identify", "xfyz", str(laser), "-o", str(model)]) == 0
    prog = tmp_path / "prog.nc"
    prog.write_text("G21 G90 G17\nG54\nG0 X-150. Y0. Z0.\nG1 X-60. F500\nG1 X40.\nG1 X150.\nM30\n")
    text, rows, summary = _compensate(tmp_path, model, prog, capsys, "--max-correction-sd-um", "0")
    arms = [float(r["assumed_arm_mm"]) for r in rows if r.get("assumed_arm_mm")]
    assert all(a < 1.0 for a in arms), arms
    a = summary.get("assumed_zero")
    assert a is None or a["largest_arm_mm"] < 1.0
    assert "arms up to" not in text

"""What predict, render and compensate say they assume at zero, after a grid plate: the plate on
one plane (Z never moved) shows X's roll (it tilts the plate's rows along Y: dz = EAX(x) y), so the
fit determines EAX and the notes must not name it; X's pitch (EBX: at one height it only moves X
like X's own positioning) is held at zero and is named.

Oracle: the independent truth machine (tests/truth): X rolls by 0.4 urad per mm of X (EAX: 0 to
about 380 urad over the plate) and X's scale is 400 um/m (EXX), nothing else; the ranges the fit
prints are compared with them."""
import re

import numpy as np
import pytest

from mtcomp.cli import main
from mtcomp.models.assumed import held_words

#: the roll of X per mm of X (rad/mm); X's scale (mm/mm)
ROLL, SCALE = 0.4e-6, 400e-6


@pytest.fixture(scope="module")
def plate(tmp_path_factory):
    from truth import TruthMachine
    from truth import campaigns as tc
    from truth import profiles as P
    folder = tmp_path_factory.mktemp("plate")
    truth = TruthMachine.zero("xfyz")
    truth.components["X"]["EAX"] = P.Linear(0.0, ROLL)
    truth.components["X"]["EXX"] = P.Linear(0.0, SCALE)
    res = tc.points(truth, folder / "plate.csv", np.random.default_rng(3), grid=(9, 6, 1),
                    plane={"Z": -100.0}, directions=(1,), setup=False, noise_um=0.5,
                    tool_lengths_mm=(truth.tool_length_mm,))
    model = folder / "model.json"
    return folder, res.path, model


def test_a_fitted_roll_is_not_named_held(plate, capsys):
    folder, path, model = plate
    assert main(["identify", "xfyz", str(path), "-o", str(model), "-v"]) == 0
    out = capsys.readouterr().out
    row = next(ln for ln in out.splitlines() if re.search(r"\broll\s+EAX", ln))
    m = re.search(r"range\s+([-\d.e+]+) \+- ([\d.e+-]+) urad", row)
    assert m, row
    lo, hi = _plate_x(path)
    np.testing.assert_allclose(float(m.group(1)), ROLL * (hi - lo) * 1e6, rtol=0.05, atol=0)
    # X's positioning: its range is determined on the assumption that X's pitch (which at one
    # height moves X alike) is zero, while its parameters are each open in the data alone: the
    # parameter table's legend says both
    row = next(ln for ln in out.splitlines() if re.search(r"\bpositioning\s+EXX", ln))
    m = re.search(r"range\s+([-\d.e+]+) \+- ([\d.e+-]+) um", row)
    assert m, row
    np.testing.assert_allclose(float(m.group(1)), SCALE * (hi - lo) * 1e3, rtol=0.02, atol=0)
    assert re.search(r"^EXX_b1\s+\S+\s+undeterm\.", out, re.M)
    legend = out[out.index("undeterm.: "):]
    assert "A component's range in the table above" in " ".join(legend.split())
    pts = folder / "pts.csv"
    pts.write_text("x_mm,y_mm,z_mm,dx_um,dy_um,dz_um\n100,100,-60,0,0,0\n")
    assert main(["predict", "xfyz", str(model), str(pts), "-o", str(folder / "pred.csv")]) == 0
    err = capsys.readouterr().err
    note = next(ln for ln in err.splitlines() if "the predictions assume zero" in ln)
    held = re.search(r"X's angular motions \(([^)]*)\)", note)
    assert held and "EBX" in held.group(1) and "EAX" not in held.group(1), note


def _plate_x(path):
    import csv
    with open(path, newline="") as f:
        x = [float(r["x_mm"]) for r in csv.DictReader(f)]
    return min(x), max(x)


def test_a_group_the_data_determine_in_part_is_said_so():
    words = held_words(["X:EBX", "Y:EBY", "squareness"], {"X:EBX", "Y:EBY"}, {"Y:EBY", "squareness"})
    assert words == ("X's angular motions (EBX), Y's angular motions (EBY in part) and the "
                     "squareness in part")

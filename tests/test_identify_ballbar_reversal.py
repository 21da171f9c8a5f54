"""identify's note of a reversal its model does not hold, from a ball-bar circle run both ways
(a new user's finding: the note came from laser files only, and identify's fit of a circle dropped
its reversal silently). The oracle is the independent truth machine (tests/truth, no code shared
with mtcomp): an XFYZ machine with a 10 um backlash on X, one circle in XY both ways (0.3 um noise)."""
from __future__ import annotations

import re

import numpy as np

from mtcomp.cli import main
from mtcomp.identification.reversal import REVERSAL_P, data_reversal
from mtcomp.measurement.files import read_measurements
from truth import Backlash, TruthMachine, campaigns

BACKLASH_UM = 10.0
SEED = 1


def _circle(folder, effects=()):
    """(truth machine, path): one circle in XY, both ways, of a random XFYZ machine with ``effects``."""
    rng = np.random.default_rng(SEED)
    truth = TruthMachine.random("xfyz", rng, effects=list(effects))
    path = folder / "circle.csv"
    campaigns.ballbar_circles(truth, path, rng, planes=("XY",))
    return truth, path


def test_identify_notes_the_reversal_a_circle_shows(tmp_path, capsys):
    _, path = _circle(tmp_path, [Backlash("X", BACKLASH_UM)])
    assert main(["identify", "xfyz", str(path), "-o", str(tmp_path / "m.json")]) == 0
    out = capsys.readouterr().out
    got = re.search(r"does not hold: X ([+-][0-9.]+) um", out)
    assert got and abs(float(got.group(1)) - BACKLASH_UM) < 0.5, out
    sizes = out.split("does not hold: ")[1].split("; the model")[0]
    assert "Y " not in sizes and "Z " not in sizes
    # a circle of a machine without one: none seen (what the note is made from)
    (tmp_path / "clean").mkdir()
    _, clean = _circle(tmp_path / "clean")
    seen = data_reversal([read_measurements(clean)])
    assert set(seen) == {"X", "Y"} and all(r["p_value"] > REVERSAL_P for r in seen.values()), seen

"""A ball bar noisier than the laser runs beside it is judged by its own noise floor, not by the
lasers' repeats: no structure is made of its noise.

Oracle: the independent truth machine (tests/truth, random geometric errors, no hidden effect),
positioning runs of X and Y (5 bidirectional runs, 0.2 um noise) and a ball-bar circle in XY
(R 150 mm, both directions, 0.3 um noise, read once per angle). The truth holds nothing the base
model lacks, so the diagnosis must find nothing. The lasers' repeats give the floor of um readings
(0.2 um); the circle has no repeats, and its own floor comes from its successive differences (the
truth's 0.3 um). The old code judged the circle by the lasers' 0.2 um and reported 'unexplained:
all data' (held-out residual 1.5 times that floor), on each of seeds 0, 1 and 2."""
from __future__ import annotations

import numpy as np

from mtcomp.diagnose import diagnose
from mtcomp.machine import load_machine
from mtcomp.measurement.files import read_measurements
from truth import TruthMachine
from truth import campaigns as tc

LASER_NOISE_UM = 0.2
BALLBAR_NOISE_UM = 0.3


def test_a_noisier_ball_bar_is_judged_by_its_own_floor(tmp_path):
    rng = np.random.default_rng(0)
    truth = TruthMachine.random("xfyz", rng)
    paths = [tc.laser(truth, tmp_path / "laser_x.csv", rng, "X", components=("EXX",),
                      noise_um=LASER_NOISE_UM).path,
             tc.laser(truth, tmp_path / "laser_y.csv", rng, "Y", components=("EYY",),
                      noise_um=LASER_NOISE_UM).path,
             tc.ballbar_circles(truth, tmp_path / "ballbar.csv", rng, planes=("XY",), radius_mm=150.0,
                                noise_mm=BALLBAR_NOISE_UM * 1e-3).path]
    d = diagnose(load_machine("xfyz"), [read_measurements(p) for p in paths])
    assert not [f for f in d.findings if f.effect == "unexplained"], [f.evidence for f in d.findings]
    assert d.verdict == "none"
    floor = d.noise["um"]
    # the lasers' floor from their repeats; the circle's its own, near the truth's noise
    assert floor.source == "repeats"
    np.testing.assert_allclose(floor.sigma, LASER_NOISE_UM, rtol=0.15, atol=0)
    assert set(floor.by_series) == {"ballbar:length_mm"}
    np.testing.assert_allclose(floor.by_series["ballbar:length_mm"], BALLBAR_NOISE_UM, rtol=0.2, atol=0)

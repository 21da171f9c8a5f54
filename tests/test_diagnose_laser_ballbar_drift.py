"""A shop's campaign through `mtcomp diagnose` (a new user's findings): laser runs of X, Y and Z, a
ball-bar circle in XY (its software writes no times) and a thermal record of the spindle.

Three things the report said wrong:

* the reversal of Y was given as -4.5 um where the lasers show -5.9 and the fit -5.93: the matched
  pairs of the ball bar, whose lengths see only part of Y's positioning, were averaged with the
  laser's as if they saw all of it;
* "unexplained: all data", 4.5 to 4.8 times the noise floor: the held-out residual of the stretch of
  the circle no other reading passes (the straightness of Y in X that only it reads) counted as
  structure the model lacks;
* a laser Z run that drifts in time was "unexplained" next to the record's own drift finding: the
  drift candidates needed times on half of all readings, and the circle's 144 readings without
  times outnumbered the lasers'.

The oracle is the independent truth machine (tests/truth, no code shared with mtcomp): an XFYZ
machine with random profiles, a 6 um backlash of Y and a settling drift of Z in time
(-15 um, 5400 s)."""
from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from mtcomp.cli import main
from truth import Backlash, ThermalDrift, TruthMachine, campaigns

BACKLASH_UM = 6.0


def _without(path, drop, one_run=False):
    """Rewrite a CSV without the columns ``drop`` returns True for (and with every row in run 1)."""
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    if one_run:
        for r in rows:
            r["run"] = "1"
    keep = [k for k in rows[0] if not drop(k)]
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, keep, extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)
    return path


def _campaign(folder, effects, z_laser: bool):
    rng = np.random.default_rng(7)
    truth = TruthMachine.random("xfyz", rng, effects=effects)
    files = []
    t0 = 0.0
    # Z first, from the machine's start, with a minute at each target (as a laser run takes it):
    # it spans the first two hours of the drift
    for axis in "ZXY" if z_laser else "XY":
        res = campaigns.laser(truth, folder / f"laser_{axis.lower()}.csv", rng, axis,
                              components=[f"E{axis}{axis}"], t0_s=t0, dwell_s=60.0 if axis == "Z" else 4.0)
        t0 = float(np.max(res.columns["t_s"])) + 60.0
        # the laser's software records the time of each reading, not the spindle or temperatures
        files.append(_without(res.path, lambda k: k == "spindle_rpm" or k.startswith("temp_")))
    # the bar's noise the lasers' (the noise floor is one per unit, from the lasers' repeats)
    bb = campaigns.ballbar_circles(truth, folder / "ballbar.csv", rng, planes=("XY",), radius_mm=150.0,
                                   noise_mm=0.0002)
    # a ball bar's own export: no times, both directions one run (held out a stretch at a time)
    files.append(_without(bb.path, lambda k: k == "t_s" or k == "spindle_rpm" or k.startswith("temp_"),
                          one_run=True))
    return truth, files


def _diagnose(folder, files):
    rep = folder / "r.json"
    assert main(["diagnose", "xfyz", *map(str, files), "--json", str(rep), "-o", str(folder / "m.json"),
                 "-q"]) == 0
    return json.loads(rep.read_text())


@pytest.fixture(scope="module")
def lasers_and_circle(tmp_path_factory):
    folder = tmp_path_factory.mktemp("shop")
    _, files = _campaign(folder, [Backlash("Y", BACKLASH_UM)], z_laser=False)
    return _diagnose(folder, files)


def test_the_reversal_is_the_axis_s_whatever_reads_it(lasers_and_circle):
    found = [f for f in lasers_and_circle["findings"] if f["effect"] == "backlash"]
    assert [f["axis"] for f in found] == ["Y"]
    # the old average: 4.5 um of a 6 um reversal (the circle's pairs read cos theta of it)
    assert found[0]["params"]["step_at_matched_positions"] == pytest.approx(BACKLASH_UM, abs=0.3)
    assert "of Y's positioning" in found[0]["evidence"]


def test_no_structure_is_named_where_only_the_held_out_stretch_reads(lasers_and_circle):
    # the old report: "unexplained: all data", the held-out residual 4.8 times the noise floor
    assert [f["effect"] for f in lasers_and_circle["findings"]] == ["backlash"]
    assert lasers_and_circle["verdict"] == "explained"


def test_a_laser_run_s_drift_is_named_beside_the_record_s(tmp_path):
    drift = ThermalDrift("time", (0.0, 0.0, -15.0), tau_s=5400.0)
    truth, files = _campaign(tmp_path, [Backlash("Y", BACKLASH_UM), drift], z_laser=True)
    record = campaigns.thermal(truth, tmp_path / "spindle.csv", np.random.default_rng(3), duration_h=6.0,
                               channels=("z",))
    report = _diagnose(tmp_path, [*files, record.path])
    effects = [(f["effect"], f["axis"]) for f in report["findings"]]
    # the old report: ("unexplained", "Z") for laser_z's drift, beside the record's finding
    assert ("unexplained", "Z") not in effects and "unexplained" not in [e for e, _ in effects]
    laser_drift = [f for f in report["findings"] if f["effect"] == "thermal_drift"
                   and "the model written carries the thermal record's drift" in f["evidence"]]
    assert len(laser_drift) == 1 and laser_drift[0]["axis"] == "Z"
    # the model written holds one drift in time, the record's (its settling time constant)
    from mtcomp.models import load_model
    fm = load_model(tmp_path / "m.json")
    drifts = [t for t in fm.model.terms if t.key() == "thermal_drift:time"]
    assert len(drifts) == 1 and not any("time_h" in f for f in drifts[0].features)

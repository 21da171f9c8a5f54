"""What a diagnosis could not test, per axis (docs/diagnose.md, REPORT.json ``untested``): laser runs
of Y in one direction only got the verdict "none" with no word that a backlash could not be seen
(``mtcomp iso230-2`` refuses the same file). The file is written by hand, so the expected entries
are known without running anything: one direction, one feed, times given; then both directions, two
feeds, no times."""
from __future__ import annotations

import json

import numpy as np

from mtcomp.cli import main


def _laser_y(path, dirs=(1,), feeds=(2000.0,), times=True):
    rng = np.random.default_rng(7)
    head = "axis,component,target_mm,dir,run,value_um,feed_mm_min" + (",t_s" if times else "")
    rows, t, run = [head], 0.0, 0
    for feed in feeds:
        for _ in range(3):
            run += 1
            for d in dirs:
                for y in np.linspace(-250.0, 250.0, 11)[::d]:
                    v = 2e-3 * y + 0.3 * rng.standard_normal()        # a scale error and noise, um
                    rows.append(f"Y,EYY,{y:g},{d},{run},{v:.4f},{feed:g}" + (f",{t:g}" if times else ""))
                    t += 10.0
    path.write_text("\n".join(rows) + "\n")
    return path


def _untested(tmp_path, capsys, **kw):
    src = _laser_y(tmp_path / "laser_Y.csv", **kw)
    report = tmp_path / "R.json"
    assert main(["diagnose", "xfyz", str(src), "--json", str(report)]) == 0
    return json.loads(report.read_text())["untested"], capsys.readouterr().out


def test_one_direction_and_one_feed_are_named_as_not_testable(tmp_path, capsys):
    untested, out = _untested(tmp_path, capsys)
    assert untested == {"Y": [{"effect": "backlash", "reason": "every reading approached in + only"},
                              {"effect": "feed_dependence", "reason": "one feed only (2000 mm/min)"}]}
    assert ("not testable on Y with these data: reversal (backlash): every reading approached in + "
            "only; feed dependence: one feed only (2000 mm/min)") in out
    assert "it says nothing of what these data could not test" in out


def test_both_directions_and_two_feeds_without_times_leave_only_the_drift(tmp_path, capsys):
    untested, out = _untested(tmp_path, capsys, dirs=(1, -1), feeds=(1000.0, 4000.0), times=False)
    assert untested == {"Y": [{"effect": "thermal_drift", "reason": "no times given (t_s)"}]}
    assert "not testable on Y with these data: drift in time: no times given (t_s)" in out

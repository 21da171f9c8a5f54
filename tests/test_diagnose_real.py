"""`diagnose` on real measurements (shared/data/real; skipped when the folder is absent).

* ISO 230-2 runs of a real linear stage (ess_b02_x, ess_b02_y): the reversal is found as backlash.
  Oracle: the ISO 230-2 evaluation (mtcomp.identification.iso230_2). Each target is approached
  equally often from both sides, so the least-squares backlash equals the mean reversal B_mean of
  the standard exactly; the reversal of largest magnitude B bounds it.
* A spindle's thermal drift (fl_thermal, 11,115 readings of 5 channels, 16 temperatures): found as
  thermal drift; the extended model's held-out residual (whole spindle-speed blocks held out) is
  compared with a plain linear regression on all 16 temperatures, recomputed here with numpy.
"""
from pathlib import Path

import numpy as np
import pytest

from mtcomp.diagnose import diagnose
from mtcomp.identification.iso230_2 import evaluate_iso230_2
from mtcomp.measurement.files import read_measurements
from mtcomp.machine import load_machine

REAL = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "real"
needs_real = pytest.mark.skipif(not REAL.is_dir(), reason=f"real data folder {REAL} is absent")


@needs_real
@pytest.mark.parametrize("name,axis", [("ess_b02_x", "X"), ("ess_b02_y", "Y")])
def test_reversal_of_a_real_stage_is_found_as_backlash(name, axis):
    data = read_measurements(REAL / "iso230_2" / f"{name}.csv")
    iso = evaluate_iso230_2(data).axes[axis]
    d = diagnose(load_machine("xfyz"), [data])
    found = [f for f in d.findings if f.effect == "backlash"]
    assert [f.axis for f in found] == [axis]
    mag = found[0].params["magnitude_um"]
    print(f"{name}: diagnose backlash {mag:.3f} um; ISO 230-2 B_mean {iso.B_mean * 1e3:.3f} um, "
          f"B {iso.B * 1e3:.3f} um; held-out rms {found[0].heldout_rms_before_um:.2f} -> "
          f"{found[0].heldout_rms_after_um:.2f} um, noise {d.noise_um:.2f} um, verdict {d.verdict}")
    assert mag == pytest.approx(iso.B_mean * 1e3, rel=1e-6, abs=1e-6)
    assert abs(mag) <= abs(iso.B * 1e3)
    assert found[0].heldout_rms_after_um < found[0].heldout_rms_before_um


def _plain_temperature_regression(data, folds) -> float:
    """Held-out rms (um) of channel = offset + sum_k c_k (T_k - T_k(first)), per channel, each fold
    fitted on the other folds: the usual thermal model, computed here independently of diagnose."""
    temps = sorted(data.context.temperatures)
    order = np.argsort(data.t, kind="stable")
    X = np.column_stack([np.ones(len(data))] + [data.context.temperatures[n] - data.context.temperatures[n][order[0]]
                                                 for n in temps])
    resid = []
    # observations are stacked row-major: row 0 channel 1..5, row 1 ...
    channels = list(data.channels)
    f = folds.reshape(len(data), len(channels))
    for j, ch in enumerate(channels):
        y = data.channels[ch] * 1e3
        for k in np.unique(f[:, j]):
            te = f[:, j] == k
            coef, *_ = np.linalg.lstsq(X[~te], y[~te], rcond=None)
            resid.append(y[te] - X[te] @ coef)
    r = np.concatenate(resid)
    return float(np.sqrt(np.mean(r ** 2)))


@needs_real
def test_spindle_thermal_drift_is_found_and_beats_a_plain_temperature_regression():
    data = read_measurements(REAL / "thermal" / "fl_thermal.csv")
    d = diagnose(load_machine("xfyz"), [data])
    assert "spindle-speed blocks" in d.folds
    drift = [f for f in d.findings if f.effect == "thermal_drift"]
    assert drift, [f.effect for f in d.findings]
    plain = _plain_temperature_regression(data, d.folds_of_observations)
    ref = d.reference["linear_regression_all_temperatures"]["heldout_rms_um"]
    final = d.final["heldout_rms_um"]
    print(f"fl_thermal: base held-out {d.base['heldout_rms_um']:.3f} um; plain linear regression on 16 "
          f"temperatures held-out {plain:.3f} um; extended model held-out {final:.3f} um "
          f"({', '.join(f['driver'] if isinstance(f, dict) else f.params['driver'] for f in drift)})")
    assert ref == pytest.approx(plain, rel=1e-4)
    assert final <= plain
    assert final < 0.5 * d.base["heldout_rms_um"]

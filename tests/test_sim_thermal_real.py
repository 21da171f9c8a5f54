"""The thermal measurement model and drift features on real data (CAIVIAC FL_THERMAL spindle run)."""

import numpy as np
import pytest

from mtcomp import load_machine
from mtcomp.identification.fit import identify
from mtcomp.measurement.files import read_measurements
from mtcomp.models import ChannelDrift, ErrorModel

from real_data import THERMAL


@pytest.mark.skipif(not THERMAL.exists(), reason=f"real data not present at {THERMAL}")
def test_spindle_heat_and_temperature_features_explain_the_real_drift():
    data = read_measurements(THERMAL)
    channels = tuple(data.channels)
    machine = load_machine("xfyz")
    raw = np.column_stack([data.channels[c] for c in channels]) * 1e3
    before = np.sqrt(np.nanmean((raw - np.nanmean(raw, axis=0)) ** 2))   # offsets only, um

    def rms_after(features):
        model = ErrorModel(machine, [ChannelDrift("drivers", features, channels)])
        res = identify(model, [data], free=[n for n in model.param_names if n.startswith("TD_")])
        return res.files[0].rms_error_units()["um"]

    spindle = rms_after(("spindle_heat_900", "spindle_heat_3600"))
    both = rms_after(("spindle_heat_900", "spindle_heat_3600", "dtemp_t1", "dtemp_t5"))
    print(f"\nreal thermal drift rms: offsets only {before:.2f} um, spindle heat {spindle:.2f} um, "
          f"+ two temperatures {both:.2f} um")
    assert before > 12.0
    assert spindle < 0.7 * before
    assert both < 0.6 * spindle

"""A drift correction is the drift since the record's first reading, and its standard error is that
of the difference: the parameters' share (J_now - J_first) C (J_now - J_first)^T, the intercept
cancelling, plus the model error (the forward-validated rms) once. Oracles: `mtcomp predict` on
record rows at the same temperatures and at the record's first reading (the measurement model's
predictions), and the covariance and model error the model file holds, by hand; on the real 46 h
record."""
import csv
import json

import numpy as np
import pytest

from mtcomp.cli import main
from real_data import THERMAL


def _rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_drift_correction_and_its_standard_error_are_the_drift_prediction(tmp_path, capsys):
    model = tmp_path / "M.json"
    assert main(["diagnose", "xfyz", str(THERMAL), "--channel-axis", "ch3=Z", "--json",
                 str(tmp_path / "R.json"), "-o", str(model)]) == 0
    row = dict(_rows(THERMAL)[6000])            # 25 h into the record, spindle warm before
    temps = [c for c in row if c.startswith("temp_")]
    (tmp_path / "T.csv").write_text(",".join(temps) + "\n" + ",".join(row[c] for c in temps) + "\n")
    # the same state as a record row the model predicts: spindle stopped long (no lag), t 0; and
    # the record's first reading, the reference the correction is taken from
    row.update(t_s="0", spindle_rpm="0")
    first = dict(_rows(THERMAL)[0], t_s="1", spindle_rpm="0")
    (tmp_path / "one.csv").write_text(",".join(row) + "\n" + ",".join(row.values()) + "\n"
                                      + ",".join(first[c] for c in row) + "\n")
    assert main(["predict", "xfyz", str(model), str(tmp_path / "one.csv"), "-o",
                 str(tmp_path / "P.csv")]) == 0
    pred, at_first = _rows(tmp_path / "P.csv")
    since = float(pred["pred_disp_ch3_um"]) - float(at_first["pred_disp_ch3_um"])
    prog = tmp_path / "p.nc"
    prog.write_text("G21 G90\nG0 X0 Y0 Z10\nG1 Z-5 F500\nG1 X100\nG1 Y100\nM30\n")
    # the drift's standard error carries the model error (the Z channel's forward-validated rms,
    # about 4.9 um): above the default limit of 2 um, so the limit is raised to see the corrections
    assert main(["compensate", "xfyz", str(model), str(prog), "-o", str(tmp_path / "o.nc"),
                 "--temperatures", str(tmp_path / "T.csv"), "--report", str(tmp_path / "B.csv"),
                 "--max-correction-sd-um", "8"]) == 0
    out = capsys.readouterr()
    said = out.out + out.err
    # a drift model has no error varying along an axis: no region to state, no note that it lacks one
    assert "does not state the region" not in said and "outside the region" not in said
    blocks = [r for r in _rows(tmp_path / "B.csv") if r["unknown_axes"] == ""]
    assert blocks and all(r["corrected"] == "1" for r in blocks)
    # by hand from the file: the Z channel's coefficients' covariance over the difference of the
    # features (the block's state: the row's temperatures, the spindle stopped; the first reading)
    saved = json.loads(model.read_text())
    u, info = saved["uncertainty"], saved["info"]
    names = [f"TD_Z_{f}" for f in info["drift_features"]] + ["TD_Z_zero"]
    k = [u["parameters"].index(n) for n in names]
    C = np.asarray(u["covariance"])[np.ix_(k, k)]
    now = [float(row[f + "_c"]) if f.startswith("temp_") else 0.0 for f in info["drift_features"]]
    d = np.r_[np.array(now) - [info["thermal_first_reading"][f] for f in info["drift_features"]], 0.0]
    drift = next(f for f in json.loads((tmp_path / "R.json").read_text())["findings"]
                 if f["effect"] == "thermal_drift")
    error = drift["params"]["forward_rms_um"]["ch3"]        # the model error, as diagnose reports it
    want = np.sqrt(d @ C @ d + error ** 2)
    assert 1.0 < np.sqrt(d @ C @ d) and error > 4.0         # both shares count (1.66, 4.94 um)
    for r in blocks:
        # the Z deviation of the tip is the Z channel's prediction (the same sign convention)
        assert float(r["ez_before_um"]) == pytest.approx(since, abs=2e-3)
        assert float(r["correction_sd_um"]) == pytest.approx(want, rel=2e-3, abs=1e-3)
    # the same state given as the probed one: the same correction and standard error
    probed = [f"--probed-at-temperature={f[5:]}={v!r}" for f, v in info["thermal_first_reading"].items()
              if f.startswith("temp_")]
    assert main(["compensate", "xfyz", str(model), str(prog), "-o", str(tmp_path / "o3.nc"),
                 "--temperatures", str(tmp_path / "T.csv"), "--report", str(tmp_path / "B3.csv"),
                 "--max-correction-sd-um", "8", "--quiet", *probed]) == 0
    explicit = [r for r in _rows(tmp_path / "B3.csv") if r["unknown_axes"] == ""]
    assert [(r["ez_before_um"], r["correction_sd_um"]) for r in explicit] == \
        [(r["ez_before_um"], r["correction_sd_um"]) for r in blocks]
    # a file of an older mtcomp (no model error kept apart) still compensates, with the absolute
    # drift's standard error, as it did
    del saved["uncertainty"]["model_error"]
    (tmp_path / "old.json").write_text(json.dumps(saved))
    assert main(["compensate", "xfyz", str(tmp_path / "old.json"), str(prog), "-o", str(tmp_path / "o4.nc"),
                 "--temperatures", str(tmp_path / "T.csv"), "--report", str(tmp_path / "B4.csv"),
                 "--max-correction-sd-um", "8", "--quiet"]) == 0
    older = [r for r in _rows(tmp_path / "B4.csv") if r["unknown_axes"] == ""]
    assert [r["ez_before_um"] for r in older] == [r["ez_before_um"] for r in blocks]
    assert all(float(r["correction_sd_um"]) == pytest.approx(float(pred["pred_disp_ch3_um_sd"]),
                                                             rel=2e-3, abs=1e-3) for r in older)
    # under the default limit (2 um) the same blocks are left uncorrected
    assert main(["compensate", "xfyz", str(model), str(prog), "-o", str(tmp_path / "o2.nc"),
                 "--temperatures", str(tmp_path / "T.csv"), "--report", str(tmp_path / "B2.csv"),
                 "--quiet"]) == 0
    gated = [r for r in _rows(tmp_path / "B2.csv") if r["unknown_axes"] == ""]
    assert len(gated) == len(blocks) and all(r["corrected"] == "0" for r in gated)


def test_a_time_series_of_temperatures_is_followed_along_the_program(tmp_path, capsys):
    """Readings at 0, 300 and 600 s; a program whose blocks end at 0.06 s (a 10 mm rapid at
    10 m/min), 1.86 s (15 mm at 500 mm/min), 601.86 s and 1201.86 s (100 mm at 10 mm/min each):
    each block's drift is the model's prediction at the temperatures interpolated at its end time
    (held after the last reading) less that at the record's first reading. Oracle: `mtcomp predict`
    on record rows at those temperatures and at the first reading."""
    import numpy as np
    model = tmp_path / "M.json"
    assert main(["diagnose", "xfyz", str(THERMAL), "--channel-axis", "ch3=Z", "--json",
                 str(tmp_path / "R.json"), "-o", str(model)]) == 0
    record = _rows(THERMAL)
    temps = [c for c in record[0] if c.startswith("temp_")]
    picks = [record[i] for i in (2000, 4000, 6000)]
    lines = ["t_s," + ",".join(temps)] + [f"{300 * k}," + ",".join(r[c] for c in temps)
                                          for k, r in enumerate(picks)]
    (tmp_path / "S.csv").write_text("\n".join(lines) + "\n")
    prog = tmp_path / "p.nc"
    prog.write_text("G21 G90\nG0 X0 Y0 Z10\nG1 Z-5 F500\nG1 X100 F10\nG1 Y100\nM30\n")
    assert main(["compensate", "xfyz", str(model), str(prog), "-o", str(tmp_path / "o.nc"),
                 "--temperatures", str(tmp_path / "S.csv"), "--report", str(tmp_path / "B.csv"),
                 "--max-correction-um", "200", "--max-step-um", "200"]) == 0
    said = capsys.readouterr().out
    assert "follow the readings along the program's run time (3 readings over 600 s; the program " \
           "takes 1202 s at its feeds, rapids at 10000 mm/min; the last reading holds after it)" in said
    ends = np.array([0.06, 1.86, 601.86, 1201.86])
    rows = []
    for k, t in enumerate(ends):
        row = dict(record[0], t_s=str(k), spindle_rpm="0")      # rows of states, in time order
        for c in temps:
            row[c] = repr(float(np.interp(t, [0, 300, 600], [float(r[c]) for r in picks])))
        rows.append(row)
    rows.append(dict(record[0], t_s=str(len(ends)), spindle_rpm="0"))   # the first reading, last
    (tmp_path / "rows.csv").write_text(",".join(rows[0]) + "\n"
                                       + "\n".join(",".join(r.values()) for r in rows) + "\n")
    assert main(["predict", "xfyz", str(model), str(tmp_path / "rows.csv"), "-o",
                 str(tmp_path / "P.csv")]) == 0
    *want, at_first = [float(r["pred_disp_ch3_um"]) for r in _rows(tmp_path / "P.csv")]
    want = np.array(want) - at_first
    blocks = [r for r in _rows(tmp_path / "B.csv") if r["inserted"] == "0"]
    got = [float(r["ez_before_um"]) for r in blocks]
    np.testing.assert_allclose(got, want, rtol=0, atol=2e-3)
    assert max(want) - min(want) > 5.0        # the drift does change along the program


def test_a_time_series_without_t_s_or_with_time_going_back_is_one_line(tmp_path, capsys):
    from mtcomp.thermal.context import read_temperature_row
    from mtcomp.errors import InputError
    bad = tmp_path / "S.csv"
    bad.write_text("temp_t1_c\n25\n26\n")
    with pytest.raises(InputError, match="no t_s column"):
        read_temperature_row(bad)
    bad.write_text("t_s,temp_t1_c\n0,25\n60,26\n30,27\n")
    with pytest.raises(InputError, match=r"row 3: column t_s: 30 s goes back from 60 s"):
        read_temperature_row(bad)
    bad.write_text("t_s,temp_t1_c\n0,25\n60,26\n60,27\n")      # a repeat: no time between them
    with pytest.raises(InputError, match=r"row 3: column t_s: 60 s repeats the row before's"):
        read_temperature_row(bad)


def test_without_a_thermal_state_the_drift_is_not_compensated(tmp_path, capsys):
    """No temperature, readings or spindle speed: the machine's state is not known, so nothing of the
    drift is corrected (its reference, the record's mean temperatures, would correct ~10 um nobody
    measured) and none of its uncertainty gates a block; the output says so. With a state given the
    drift is there."""
    model = tmp_path / "M.json"
    assert main(["diagnose", "xfyz", str(THERMAL), "--channel-axis", "ch3=Z", "--json",
                 str(tmp_path / "R.json"), "-o", str(model)]) == 0
    prog = tmp_path / "p.nc"
    prog.write_text("G21 G90\nG0 X0 Y0 Z10\nG1 Z-5 F500\nG1 X100\nM30\n")
    capsys.readouterr()
    assert main(["compensate", "xfyz", str(model), str(prog), "-o", str(tmp_path / "o.nc"),
                 "--report", str(tmp_path / "B.csv"), "--quiet"]) == 0
    said = capsys.readouterr().out
    assert "thermal drift not compensated: no temperature or spindle speed given" in said
    blocks = [r for r in _rows(tmp_path / "B.csv") if r["unknown_axes"] == ""]
    assert blocks and all(float(r["e_before_um"]) == 0.0 for r in blocks)
    assert (tmp_path / "o.nc").read_text() == prog.read_text()
    # every sensor the drift reads is given: the record's mean state of the others, t1 at 28 degC
    temps = json.loads(model.read_text())["context_defaults"]
    flags = [f"{k[5:]}={v:.6g}" for k, v in temps.items() if k.startswith("temp_") and k != "temp_t1"]
    assert main(["compensate", "xfyz", str(model), str(prog), "-o", str(tmp_path / "o2.nc"),
                 "--report", str(tmp_path / "B2.csv"), "--temperature", "t1=28", "--quiet",
                 *[w for f in flags for w in ("--temperature", f)]]) == 0
    warm = [r for r in _rows(tmp_path / "B2.csv") if r["unknown_axes"] == ""]
    assert all(abs(float(r["ez_before_um"])) > 1.0 for r in warm)


def test_a_sensor_given_twice_is_refused():
    from mtcomp.errors import InputError
    from mtcomp.thermal.context import parse_assignments
    assert parse_assignments(["t1=25", "t2=26"], "--temperature") == {"t1": 25.0, "t2": 26.0}
    with pytest.raises(InputError, match="t1 is given twice .25 and 26."):
        parse_assignments(["t1=25", "t1=26"], "--temperature")


def test_beside_a_record_the_geometric_files_residuals_are_the_fits_own(tmp_path, capsys):
    """diagnose of the record with a laser file: the laser file's rms in the per-file table is the
    model written's rms (it was predicted with the record's drift at its mean temperatures, a
    constant shift of several um), and `predict` of the laser file says the drift is left out."""
    import re

    import numpy as np
    from laser_files import write_x_positioning
    laser = write_x_positioning(tmp_path / "x.csv", (-100, -50, 0, 50, 100, 150),
                                lambda t, d: 1e-4 * t ** 2 + 3.0 * d, 3, 0.3,
                                np.random.default_rng(5))
    model = tmp_path / "M.json"
    assert main(["diagnose", "xfyz", str(THERMAL), str(laser), "--channel-axis", "ch1=X",
                 "--json", str(tmp_path / "R.json"), "-o", str(model)]) == 0
    out = capsys.readouterr().out
    final = float(re.search(r"^model written: .*\); rms ([\d.]+) um", out, re.M).group(1))
    table = float(re.search(r"^x\s+laser\s+\d+\s+value_um ([\d.]+)", out, re.M).group(1))
    assert table == pytest.approx(final, rel=0, abs=2e-3)
    assert main(["predict", "xfyz", str(model), str(laser), "-o", str(tmp_path / "P.csv")]) == 0
    assert "predicted without the model's thermal drift" in capsys.readouterr().err

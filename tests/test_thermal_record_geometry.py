"""A thermal record diagnosed beside geometric files, the axis a channel reads, and the thermal state
`compensate` is given (checked against the record's range; one row of readings from a file).

Oracles: a backlash put into a simulated laser file by hand (3 um each way, a 6 um step), and the
real stage's mean reversal recomputed here with numpy from its CSV; a drift written by hand
(3 um per degC on channel a), so a correction at two temperatures differs by 3 um per degC; the
record's temperature range recomputed with numpy from the file.
"""
import csv
import json

import numpy as np
import pytest

from mtcomp.cli import main

from laser_files import write_x_positioning
from real_data import SHARED_REAL, THERMAL

DRIFT_UM_PER_C = 3.0
BACKLASH_UM = 6.0
PROGRAM = "%\nG21 G90\nG0 X10 Y10 Z20\nG1 X50 Y20 Z5 F600\nX80 Y-30 Z5\nM30\n%\n"


def _record(path, axis_cell="Y", n=400, seed=0):
    """(path, sensor s as written, degC) of a thermal record: channel a drifts 3 um per degC of
    sensor s (plus 5 um of zero), channel b is noise; column axis_a says which axis a reads (no
    column when ``axis_cell`` is None)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 60.0
    temp = 20.0 + 2.0 * np.sin(t / 3000.0) + rng.normal(0, 0.01, n)
    a = 5.0 + DRIFT_UM_PER_C * (temp - 20.0) + rng.normal(0, 0.05, n)
    b = rng.normal(0, 0.05, n)
    head = "t_s,disp_a_um,disp_b_um,temp_s_c" + (",axis_a" if axis_cell is not None else "")
    rows = [f"{x:g},{y:.4f},{z:.4f},{w:.4f}" + (f",{axis_cell}" if axis_cell is not None else "")
            for x, y, z, w in zip(t, a, b, temp)]
    path.write_text("\n".join([head] + rows) + "\n")
    return path, np.array([float(f"{w:.4f}") for w in temp])      # as written


def _laser(path, seed=1):
    """Five bidirectional EXX runs over X's travel: a slope plus a 6 um reversal (+3 um up, -3 down)."""
    return write_x_positioning(path, np.linspace(-400, 400, 11), lambda t, d: 2e-3 * t + BACKLASH_UM / 2 * d,
                               5, 0.3, np.random.default_rng(seed))


def _diagnose(tmp_path, files, *flags, tag="d"):
    rep, model = tmp_path / f"{tag}.json", tmp_path / f"{tag}_model.json"
    rc = main(["diagnose", "xfyz", *map(str, files), "--json", str(rep), "-o", str(model), "-q", *flags])
    return rc, rep, model


def _compensate(tmp_path, model, *flags, tag="c"):
    """(exit status, BLOCKS.csv rows or None, output path) of compensating PROGRAM with ``model``."""
    prog, out, blocks = tmp_path / "in.nc", tmp_path / f"{tag}.nc", tmp_path / f"{tag}.csv"
    prog.write_text(PROGRAM)
    rc = main(["compensate", "xfyz", str(model), str(prog), "-o", str(out), "--report", str(blocks),
               "--quiet", *flags])
    if rc != 0:
        return rc, None, out
    with open(blocks, newline="") as f:
        return rc, [r for r in csv.DictReader(f) if r["ey_before_um"]], out


def _column(rows, name):
    return np.array([float(r[name]) for r in rows])


def _one_line(capsys, *needles):
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert "Traceback" not in err[0]
    for n in needles:
        assert n in err[0], (n, err[0])
    return err[0]


@pytest.fixture(scope="module")
def record_model(tmp_path_factory):
    """(folder, record path, sensor readings, MODEL.json) of the record alone, its axis from the file."""
    tmp = tmp_path_factory.mktemp("record")
    path, temp = _record(tmp / "record.csv")
    rc, rep, model = _diagnose(tmp, [path])
    assert rc == 0
    return tmp, path, temp, model


# ------------------------------------------------------------------------------ channel axes
def test_the_record_names_a_channels_axis_in_a_column_as_the_flag_does(tmp_path, record_model):
    _, path, temp, model = record_model
    saved = json.loads(model.read_text())
    drift = [t for t in saved["terms"] if t["kind"] == "thermal_drift"]
    assert drift and drift[0]["channels"] == ["a"] and drift[0]["directions"] == "Y"
    # the same record without the column, the axis given by --channel-axis: the same model
    bare, _ = _record(tmp_path / "bare.csv", axis_cell=None)
    rc, _, flagged = _diagnose(tmp_path, [bare], "--channel-axis", "a=Y")
    assert rc == 0
    other = json.loads(flagged.read_text())
    for name in ("TD_Y_temp_s", "TD_Y_zero", "TD_b_temp_s"):
        assert saved["parameters"][name]["value"] == pytest.approx(other["parameters"][name]["value"],
                                                                   rel=1e-12, abs=1e-12)
    # the drift written by hand: 3 um per degC
    assert saved["parameters"]["TD_Y_temp_s"]["value"] == pytest.approx(DRIFT_UM_PER_C, rel=0.01)
    # the model keeps the range of the record (for compensate's check)
    assert saved["info"]["context_ranges"]["temp_s"] == pytest.approx([temp.min(), temp.max()],
                                                                      rel=0, abs=1e-9)


@pytest.mark.parametrize("edit,flags,needles", [
    (lambda rows: rows[:5] + [rows[5].replace(",Y", ",Q")] + rows[6:], [], ["row 5", "axis_a", "'Q'"]),
    (lambda rows: rows[:9] + [r.replace(",Y", ",Z") for r in rows[9:]], [], ["row 9", "one axis"]),
    (lambda rows: [rows[0].replace("axis_a", "axis_nope")] + rows[1:], [], ["axis_nope", "'nope'"]),
    (lambda rows: rows, ["--channel-axis", "a=Z"], ["a=Z", "contradicts", "axis_a"]),
])
def test_a_bad_or_contradicted_axis_column_exits_2_with_one_line(tmp_path, capsys, edit, flags, needles):
    path, _ = _record(tmp_path / "record.csv")
    rows = path.read_text().splitlines()
    path.write_text("\n".join(edit(rows)) + "\n")
    rc, rep, model = _diagnose(tmp_path, [path], *flags)
    assert rc == 2
    _one_line(capsys, "record.csv", *needles)
    assert not rep.exists() and not model.exists()


def test_channel_axes_of_several_records_are_refused_in_one_line(tmp_path, capsys):
    a, _ = _record(tmp_path / "first.csv")
    b, _ = _record(tmp_path / "second.csv", seed=2)
    rc, rep, _ = _diagnose(tmp_path, [a, b])
    assert rc == 2
    _one_line(capsys, "first.csv", "axis_a", "join the records")
    assert not rep.exists()


# ------------------------------------------------------------------------------ beside geometry
def test_a_record_beside_a_laser_file_keeps_the_backlash_and_the_drift_acts_on_its_axis(tmp_path, capsys):
    laser = _laser(tmp_path / "laser.csv")
    record, temp = _record(tmp_path / "record.csv")
    rc, rep, model = _diagnose(tmp_path, [laser, record], tag="both")
    assert rc == 0
    report = json.loads(rep.read_text())
    found = {(f["effect"], f["axis"]): f for f in report["findings"]}
    assert found[("backlash", "X")]["params"]["magnitude_um"] == pytest.approx(BACKLASH_UM, abs=0.15)
    assert found[("thermal_drift", "Y")]["params"]["channels"] == {"a": "Y", "b": ""}
    assert report["thermal"]["file"] == str(record) and "forward-chained" in report["thermal"]["heldout"]
    # the laser file's findings are those it has alone
    rc, rep_alone, _ = _diagnose(tmp_path, [laser], tag="alone")
    alone = json.loads(rep_alone.read_text())
    assert [(f["effect"], f["axis"]) for f in alone["findings"]] == \
        [k for k in found if k[0] != "thermal_drift"]
    assert alone["findings"][0]["params"]["magnitude_um"] == pytest.approx(
        found[("backlash", "X")]["params"]["magnitude_um"], rel=1e-9, abs=0)
    # one model: compensate sees the drift on Y, 3 um per degC between two temperatures
    capsys.readouterr()
    lo, hi = 19.0, 21.5
    assert temp.min() < lo < hi < temp.max()
    rc, rows_lo, _ = _compensate(tmp_path, model, "--temperature", f"s={lo}", tag="lo")
    rc2, rows_hi, _ = _compensate(tmp_path, model, "--temperature", f"s={hi}", tag="hi")
    assert rc == rc2 == 0
    np.testing.assert_allclose(_column(rows_hi, "ey_before_um") - _column(rows_lo, "ey_before_um"),
                               DRIFT_UM_PER_C * (hi - lo), rtol=0, atol=0.05)
    np.testing.assert_allclose(_column(rows_hi, "ex_before_um") - _column(rows_lo, "ex_before_um"),
                               0.0, rtol=0, atol=1e-9)
    saved = json.loads(model.read_text())
    # each is the drift since the record's first reading, which the joined model keeps (the
    # record's 5 um probe zero is no drift)
    np.testing.assert_allclose(_column(rows_hi, "ey_before_um"), DRIFT_UM_PER_C * (hi - temp[0]),
                               rtol=0, atol=0.1)
    assert saved["info"]["thermal_first_reading"] == {"temp_s": pytest.approx(temp[0], abs=1e-12)}
    assert {t["kind"] for t in saved["terms"]} >= {"backlash", "thermal_drift", "channel_drift"}
    assert "uncertainty" in saved and "TD_Y_temp_s" in saved["uncertainty"]["parameters"]


def test_the_real_spindle_record_beside_a_laser_file_keeps_its_backlash(tmp_path, capsys):
    """The 46 h record (16 temperatures, 55,575 readings) stacked with 110 laser readings in one
    search lost the 6 um backlash; each on its own path, it is found, and the user's state checks
    hold: 86 (degF) for a sensor that read 22.8 to 28.9 degC, and a spindle faster than the record's."""
    laser = _laser(tmp_path / "laser.csv")
    rc, rep, model = _diagnose(tmp_path, [laser, THERMAL], "--channel-axis", "ch3=Z")
    assert rc == 0
    found = {(f["effect"], f["axis"]): f for f in json.loads(rep.read_text())["findings"]}
    assert found[("backlash", "X")]["params"]["magnitude_um"] == pytest.approx(BACKLASH_UM, abs=0.15)
    assert found[("thermal_drift", "Z")]["params"]["channel"] == "ch3"
    cols = np.genfromtxt(THERMAL, delimiter=",", names=True)
    lo, hi = cols["temp_t1_c"].min(), cols["temp_t1_c"].max()
    capsys.readouterr()
    rc, _, out = _compensate(tmp_path, model, "--temperature", "t1=86")
    assert rc == 2 and not out.exists()
    _one_line(capsys, str(model), "sensor t1", "86 degC", f"{lo:.4g} to {hi:.4g} degC", "--extrapolate")
    rc, _, out = _compensate(tmp_path, model, "--spindle-rpm", "9000")
    assert rc == 2 and not out.exists()
    _one_line(capsys, "9000 rpm", f"0 to {cols['spindle_rpm'].max():g} rpm")


needs_real = pytest.mark.skipif(not SHARED_REAL.is_dir(), reason=f"real data folder {SHARED_REAL} is absent")


@needs_real
def test_a_real_stages_reversal_is_kept_beside_the_real_spindle_record(tmp_path):
    """ess_b02_x (a real stage's ISO 230-2 runs) with the real record: its backlash is found, within
    10 % of the mean reversal (mean of the readings approached upwards minus downwards, numpy)."""
    path = SHARED_REAL / "iso230_2" / "ess_b02_x.csv"
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    value = np.array([float(r["value_um"]) for r in rows])
    up = np.array([int(r["dir"]) for r in rows]) > 0
    reversal = value[up].mean() - value[~up].mean()
    rc, rep, _ = _diagnose(tmp_path, [path, THERMAL])
    assert rc == 0
    found = [f for f in json.loads(rep.read_text())["findings"] if f["effect"] == "backlash"]
    assert [f["axis"] for f in found] == ["X"]
    assert found[0]["params"]["magnitude_um"] == pytest.approx(reversal, rel=0.1, abs=0)


# ------------------------------------------------------------------------------ compensate
def test_compensate_refuses_temperatures_for_a_drift_that_maps_to_no_axis(tmp_path, capsys):
    path, _ = _record(tmp_path / "record.csv", axis_cell=None)
    rc, _, model = _diagnose(tmp_path, [path])
    assert rc == 0
    capsys.readouterr()
    rc, _, out = _compensate(tmp_path, model, "--temperature", "s=20.5")
    assert rc == 2 and not out.exists() and not (tmp_path / "c.csv").exists()
    _one_line(capsys, str(model), "channels a, b", "none of which maps to a machine axis", "--channel-axis")
    # without a thermal state the program is compensated, and the output says the drift is not
    rc, _, out = _compensate(tmp_path, model)
    assert rc == 0 and out.exists()
    assert "thermal drift not compensated" in capsys.readouterr().out


def test_a_temperature_outside_the_record_is_refused_unless_extrapolating(tmp_path, capsys, record_model):
    _, _, temp, model = record_model
    lo, hi = temp.min(), temp.max()
    capsys.readouterr()
    rc, _, out = _compensate(tmp_path, model, "--temperature", "s=26")
    assert rc == 2 and not out.exists()
    _one_line(capsys, str(model), "sensor s", "26 degC", f"{lo:.4g} to {hi:.4g} degC")
    # 68 degF is 20 degC: the message says so
    _compensate(tmp_path, model, "--temperature", "s=68")
    _one_line(capsys, "68 degC", "as degF it would be 20 degC")
    # --extrapolate: the drift carried on linearly, 3 um per degC beyond the record
    rc, far, _ = _compensate(tmp_path, model, "--temperature", "s=26", "--extrapolate", tag="far")
    rc2, near, _ = _compensate(tmp_path, model, "--temperature", "s=20", tag="near")
    assert rc == rc2 == 0
    assert "beyond the record's" in capsys.readouterr().out
    np.testing.assert_allclose(_column(far, "ey_before_um") - _column(near, "ey_before_um"),
                               DRIFT_UM_PER_C * 6.0, rtol=0, atol=0.1)


def test_a_row_of_readings_from_a_file_is_the_same_as_the_flags(tmp_path, capsys, record_model):
    _, _, _, model = record_model
    readings = tmp_path / "now.csv"
    readings.write_text("t_s,spindle_rpm,temp_s_c\n0,3000,21.2\n")
    rc, from_file, _ = _compensate(tmp_path, model, "--temperatures", str(readings), tag="file")
    printed = capsys.readouterr().out
    assert rc == 0 and "s=21.2 degC" in printed and "spindle_rpm not read" in printed
    rc, from_flag, _ = _compensate(tmp_path, model, "--temperature", "s=21.2", tag="flag")
    assert rc == 0
    np.testing.assert_allclose(_column(from_file, "ey_before_um"), _column(from_flag, "ey_before_um"),
                               rtol=0, atol=1e-12)
    # a sensor given both ways: the flag wins
    readings.write_text("temp_s_c\n19.5\n")
    rc, both, _ = _compensate(tmp_path, model, "--temperatures", str(readings), "--temperature", "s=21.2",
                              tag="both")
    assert rc == 0
    np.testing.assert_allclose(_column(both, "ey_before_um"), _column(from_flag, "ey_before_um"),
                               rtol=0, atol=1e-12)


@pytest.mark.parametrize("text,needles", [
    ("t_s,temp_s_c\n0,20.5\n600,\n", ["row 2", "every reading of a time series"]),
    ("t_s,disp_a_um\n0,1.0\n", ["no temperature", "temp_<name>_c"]),
    ("temp_s_c,t_s\n,0\n", ["row 1", "no temperature"]),
    ("temp_s_c\nwarm\n", ["row 1", "temp_s_c"]),
])
def test_a_readings_file_that_is_not_one_row_of_temperatures_exits_2(tmp_path, capsys, record_model,
                                                                     text, needles):
    _, _, _, model = record_model
    readings = tmp_path / "now.csv"
    readings.write_text(text)
    capsys.readouterr()
    rc, _, out = _compensate(tmp_path, model, "--temperatures", str(readings))
    assert rc == 2 and not out.exists()
    _one_line(capsys, "now.csv", *needles)


def test_render_maps_the_drift_at_the_temperatures_compensate_was_given(tmp_path, capsys,
                                                                        record_model):
    """The drift moves Y by 3 um per degC. Compensated at s = 24 degC: render given the same
    temperature maps 'after' at ~0 and 'before' with the drift; without it render maps no drift
    (as compensate corrects none without a state) and says so, not a 'worse after' map."""
    _, _, temp, model = record_model
    t = float(np.round(temp.max() - 0.5, 1))
    rc, rows, out = _compensate(tmp_path, model, "--temperature", f"s={t}")
    assert rc == 0
    capsys.readouterr()
    args = ["render", "xfyz", str(model), str(tmp_path / "in.nc"), "--compensated", str(out),
            "-o", str(tmp_path / "map.png"), "--backend", "matplotlib", "--size", "400x200",
            "--normal", "path"]          # the deviation across the path: Y's drift
    assert main(args + ["--temperature", f"s={t}"]) == 0
    with_state = capsys.readouterr().out
    assert main(args) == 0
    without = capsys.readouterr().out

    def figures(text):
        return {k: float(text.split(f"model prediction {k}")[1].split("RMS")[1].split()[0])
                for k in ("before", "after")}
    a, b = figures(with_state), figures(without)
    # the path runs mostly across Y: the drift at s since the record's first reading (about
    # 20 degC, so some 4.5 um; the 5 um of the probe's set-up zero is no drift) is seen
    since = DRIFT_UM_PER_C * (t - temp[0])
    assert 0.7 * since < a["before"] < 1.05 * since and a["after"] < 0.05
    assert b["before"] < 0.05           # no drift mapped without a state
    assert "thermal drift not mapped" in without and "thermal drift not mapped" not in with_state


def test_the_geometric_fit_s_held_combinations_stay_apart_beside_a_drift():
    """A geometric model that holds combinations its data fix only weakly (diagnose's model written
    beside a ball-bar circle) keeps them, padded for the drift's parameters, when a thermal record's
    drift is joined to it: compensate then leaves their variance out as it does without the record."""
    from mtcomp.thermal._combined import _joined_uncertainty
    held = np.array([[1.0], [2.0]])
    geo = {"names": ("a", "b"), "covariance": np.diag([4.0, 9.0]) + 25.0 * held @ held.T,
           "undetermined": np.zeros((2, 0)), "held": held, "held_sd_um": np.array([5.0])}
    drift = {"names": ("d",), "covariance": np.array([[1.0]]), "undetermined": np.zeros((1, 0))}
    out = _joined_uncertainty(geo, drift)
    np.testing.assert_array_equal(out["held"], [[1.0], [2.0], [0.0]])
    np.testing.assert_array_equal(out["held_sd_um"], [5.0])
    G = out["held"] * out["held_sd_um"]
    np.testing.assert_allclose(out["covariance"] - G @ G.T, np.diag([4.0, 9.0, 1.0]), rtol=0, atol=1e-12)

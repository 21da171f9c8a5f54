"""ISO 230-2 evaluation: hand-computed cases, an independent loop-based oracle on the real runs, the
facts stated in the real-data README, and the command line."""
import csv
import json
import math
import statistics
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest

from mtcomp import InputError
from mtcomp.cli import main
from mtcomp.identification.iso230_2 import ARCSEC_PER_RAD, DRIFT_ALPHA, evaluate_axis, evaluate_iso230_2
from mtcomp.measurement.files import read_measurements

from real_data import ISO230_2 as REAL  # noqa: E402  ($MTCOMP_REAL_DATA, else ../shared/data/real)


def _laser(tmp_path, readings, axis="X", name="laser.csv"):
    """readings: {(target, dir): [run1, run2, ...]} in um (or urad for rotary axes)."""
    rotary = axis in "ABC"
    lines = [f"axis,component,{'target_deg' if rotary else 'target_mm'},dir,run,"
             f"{'value_urad' if rotary else 'value_um'}"]
    for (target, d), values in readings.items():
        for j, v in enumerate(values, start=1):
            lines.append(f"{axis},E{axis}{axis},{target},{d},{j},{v}")
    p = tmp_path / name
    p.write_text("\n".join(lines) + "\n")
    return p


# Hand case 1 (worked in docs/iso230_2.md). Two targets, three runs per direction, um.
#   P=0:  up 1 2 3   -> mean 2,  s 1;   down 4 6 8  -> mean 6, s 2
#   P=10: up 9 10 11 -> mean 10, s 1;   down -1 2 5 -> mean 2, s 3
# By hand: xbar = 4, 6; B_i = -4, +8; R_i_up = 4, 4; R_i_down = 8, 12;
#   R_i = max(2+4+4, 4, 8) = 10, max(2+6+8, 4, 12) = 16
#   B = +8 (largest |B_i|, signed); B_mean = 2; E_up = 10-2 = 8; E_down = 6-2 = 4;
#   E = max(2,10,6,2) - min(2,10,6,2) = 8; M = 6-4 = 2
#   A_up = max(2+2, 10+2) - min(2-2, 10-2) = 12; A_down = max(6+4, 2+6) - min(6-4, 2-6) = 14
#   A = max(4, 12, 10, 8) - min(0, 8, 2, -4) = 16; R_up = 4, R_down = 12, R = 16
CASE1 = {(0, 1): [1, 2, 3], (0, -1): [4, 6, 8], (10, 1): [9, 10, 11], (10, -1): [-1, 2, 5]}
CASE1_AXIS = {"A": 16, "A_up": 12, "A_down": 14, "B": 8, "B_mean": 2, "E": 8, "E_up": 8, "E_down": 4,
              "M": 2, "R": 16, "R_up": 4, "R_down": 12}

# Hand case 2: the R_i_down branch of R_i and a negative B.
#   P=0:  up 5 5 5 -> mean 5, s 0;  down 2 5 8 -> mean 5, s 3; B_0 = 0;
#         R_i = max(0 + 6 + 0, 0, 12) = 12 (the 4 s_down branch)
#   P=20: up 0 1 2 -> mean 1, s 1;  down 10 11 12 -> mean 11, s 1; B = -10;
#         R_i = max(2 + 2 + 10, 4, 4) = 14
#   B = -10; B_mean = -5; E_up = 5-1 = 4; E_down = 11-5 = 6; E = 11-1 = 10; M = xbar 5, 6 -> 1
#   A_up = max(5, 3) - min(5, -1) = 6; A_down = max(11, 13) - min(-1, 9) = 14
#   A = max(5, 3, 11, 13) - min(5, -1, -1, 9) = 14; R_up = 4, R_down = 12, R = 14
CASE2 = {(0, 1): [5, 5, 5], (0, -1): [2, 5, 8], (20, 1): [0, 1, 2], (20, -1): [10, 11, 12]}
CASE2_AXIS = {"A": 14, "A_up": 6, "A_down": 14, "B": -10, "B_mean": -5, "E": 10, "E_up": 4,
              "E_down": 6, "M": 1, "R": 14, "R_up": 4, "R_down": 12}


@pytest.mark.parametrize("case, expected", [(CASE1, CASE1_AXIS), (CASE2, CASE2_AXIS)])
def test_hand_cases_linear(tmp_path, case, expected):
    report = evaluate_iso230_2(read_measurements(_laser(tmp_path, case)))
    ax = report.axes["X"]
    d = ax.to_dict()
    for key, value in expected.items():
        assert getattr(ax, key) * 1e3 == pytest.approx(value, rel=0, abs=1e-9), key
        assert d[f"{key}_um"] == pytest.approx(value, rel=0, abs=1e-9), key


def test_hand_case_per_target_arrays(tmp_path):
    ax = evaluate_iso230_2(read_measurements(_laser(tmp_path, CASE1))).axes["X"]
    np.testing.assert_allclose(ax.targets, [0, 10], rtol=0, atol=0)
    np.testing.assert_array_equal(ax.n_up, [3, 3])
    scale = 1e3
    np.testing.assert_allclose(ax.mean_up * scale, [2, 10], rtol=0, atol=1e-12)
    np.testing.assert_allclose(ax.mean_down * scale, [6, 2], rtol=0, atol=1e-12)
    np.testing.assert_allclose(ax.mean * scale, [4, 6], rtol=0, atol=1e-12)
    np.testing.assert_allclose(ax.reversal * scale, [-4, 8], rtol=0, atol=1e-12)
    np.testing.assert_allclose(ax.s_up * scale, [1, 1], rtol=0, atol=1e-12)
    np.testing.assert_allclose(ax.s_down * scale, [2, 3], rtol=0, atol=1e-12)
    np.testing.assert_allclose(ax.R_i * scale, [10, 16], rtol=0, atol=1e-12)
    d = ax.to_dict()
    assert d["targets_mm"] == [0.0, 10.0] and d["n_down"] == [3, 3]
    np.testing.assert_allclose(d["R_i_down_um"], [8, 12], rtol=0, atol=1e-12)


def test_rotary_axis_in_urad_and_arcsec(tmp_path):
    # CASE1 again, read as urad of axis C at 0 and 10 deg
    report = evaluate_iso230_2(read_measurements(_laser(tmp_path, CASE1, axis="C")))
    ax = report.axes["C"]
    assert ax.rotary and ax.unit == "urad"
    np.testing.assert_allclose(ax.targets, [0, math.radians(10)], rtol=1e-15, atol=0)
    d = ax.to_dict()
    assert d["axis_type"] == "rotary" and d["targets_deg"] == pytest.approx([0, 10], rel=1e-15, abs=0)
    assert "A_um" not in d
    for key, value in CASE1_AXIS.items():
        assert d[f"{key}_urad"] == pytest.approx(value, rel=1e-12, abs=0), key
        # 1 urad = 0.206264806... arcsec
        assert d[f"{key}_arcsec"] == pytest.approx(value * 0.2062648062470964, rel=1e-12, abs=0), key
    assert ARCSEC_PER_RAD == pytest.approx(206264.80624709636, rel=1e-15, abs=0)


def test_other_components_ignored_with_a_notice(tmp_path):
    p = _laser(tmp_path, CASE1)
    with open(p, "a") as f:
        f.write("X,EYX,0,1,1,100\nX,EYX,10,1,1,-100\n")
    report = evaluate_iso230_2(read_measurements(p))
    assert report.axes["X"].E * 1e3 == pytest.approx(8, rel=0, abs=1e-9)
    assert any("ignored 2 readings of components EYX" in n for n in report.notices)
    assert any("as few as 3 runs" in n for n in report.notices)


def test_two_axes_in_one_file(tmp_path):
    p = _laser(tmp_path, CASE1)
    q = _laser(tmp_path, CASE2, axis="Y", name="y.csv")
    with open(p, "a") as f:
        f.write("".join(q.read_text().splitlines(keepends=True)[1:]))
    report = evaluate_iso230_2(read_measurements(p))
    assert list(report.axes) == ["X", "Y"]
    assert report.axes["Y"].B * 1e3 == pytest.approx(-10, rel=0, abs=1e-9)
    assert report.axes["X"].B * 1e3 == pytest.approx(8, rel=0, abs=1e-9)


@pytest.mark.parametrize("readings, msg", [
    ({(0, 1): [1], (0, -1): [2, 3]}, r"row 1: axis X: target 0 mm has 1 run\(s\) in direction \+1 "
                                     r"\(up\); ISO 230-2 needs at least 2"),
    ({(0, 1): [1, 2]}, r"target 0 mm has 0 run\(s\) in direction -1 \(down\)"),
    ({(0, 1): [1, 2], (0, -1): [2, ""]}, r"row 4: axis X: the value is blank"),
])
def test_not_enough_runs_or_blank(tmp_path, readings, msg):
    with pytest.raises(InputError, match=msg):
        evaluate_iso230_2(read_measurements(_laser(tmp_path, readings)))


def test_reading_twice_refused():
    with pytest.raises(InputError, match=r"f\.csv: row 3: axis X: target 5 mm, dir \+1, run 1 is read "
                                         r"twice"):
        evaluate_axis("X", np.array([5.0, 5.0, 5.0]), np.array([1, 1, 1]), np.array([1, 2, 1]),
                      np.zeros(3), "f.csv", np.array([1, 2, 3]))


def test_no_positioning_readings(tmp_path):
    p = tmp_path / "l.csv"
    p.write_text("axis,component,target_mm,dir,run,value_um\nX,EYX,0,1,1,2\n")
    with pytest.raises(InputError, match="no positioning readings"):
        evaluate_iso230_2(read_measurements(p))


# ---- real runs: an independent, loop-based evaluation straight from the CSV text ----------------

def _oracle(path):
    """ISO 230-2 figures from plain Python (csv + statistics), um, written from the formulas."""
    x = defaultdict(list)
    with open(path, newline="") as f:
        for r in csv.DictReader(f):
            if r["component"] == "E" + r["axis"] * 2:
                x[(float(r["target_mm"]), int(r["dir"]))].append(float(r["value_um"]))
    targets = sorted({t for t, _ in x})
    up = [statistics.mean(x[(t, 1)]) for t in targets]
    dn = [statistics.mean(x[(t, -1)]) for t in targets]
    su = [statistics.stdev(x[(t, 1)]) for t in targets]
    sd = [statistics.stdev(x[(t, -1)]) for t in targets]
    bi = [u - d for u, d in zip(up, dn)]
    ri = [max(2 * a + 2 * b + abs(c), 4 * a, 4 * b) for a, b, c in zip(su, sd, bi)]
    mean = [(u + d) / 2 for u, d in zip(up, dn)]
    return {
        "B_i": bi, "s_max": max(su + sd),
        "B_um": max(bi, key=abs), "B_mean_um": sum(bi) / len(bi),
        "E_up_um": max(up) - min(up), "E_down_um": max(dn) - min(dn), "E_um": max(up + dn) - min(up + dn),
        "M_um": max(mean) - min(mean),
        "R_up_um": 4 * max(su), "R_down_um": 4 * max(sd), "R_um": max(ri),
        "A_up_um": max(u + 2 * s for u, s in zip(up, su)) - min(u - 2 * s for u, s in zip(up, su)),
        "A_down_um": max(u + 2 * s for u, s in zip(dn, sd)) - min(u - 2 * s for u, s in zip(dn, sd)),
        "A_um": max([u + 2 * s for u, s in zip(up, su)] + [u + 2 * s for u, s in zip(dn, sd)])
        - min([u - 2 * s for u, s in zip(up, su)] + [u - 2 * s for u, s in zip(dn, sd)]),
    }


def _real(name):
    path = REAL / name
    if not path.exists():
        pytest.skip(f"real ISO 230-2 runs not found at {path}")
    return path


@pytest.mark.parametrize("name", ["ess_b02_x.csv", "ess_b02_y.csv", "ess_b02_z.csv", "ess_w42_x.csv",
                                  "ess_w42_back_x8a.csv", "psi_mcu1025_x.csv"])
def test_real_runs_match_independent_oracle(name):
    path = _real(name)
    report = evaluate_iso230_2(read_measurements(path))
    (axis,) = report.axes
    got = report.axes[axis].to_dict()
    want = _oracle(path)
    for key in [k for k in want if k.endswith("_um")]:
        assert got[key] == pytest.approx(want[key], rel=1e-12, abs=1e-9), key
    np.testing.assert_allclose(got["reversal_um"], want["B_i"], rtol=1e-12, atol=1e-9)


def test_real_ess_b02_x_readme_facts():
    ax = evaluate_iso230_2(read_measurements(_real("ess_b02_x.csv"))).axes["X"]
    reversal_um = ax.reversal * 1e3
    # README: steady reversal of about -25 um, B_i from -16 to -34 um, s up to 7 um
    assert ax.B_mean * 1e3 == pytest.approx(-25, rel=0, abs=1.0)
    assert reversal_um.min() == pytest.approx(-34, rel=0, abs=0.6)
    assert reversal_um.max() == pytest.approx(-16, rel=0, abs=0.6)
    assert np.all(reversal_um < 0)
    assert max(ax.s_up.max(), ax.s_down.max()) * 1e3 == pytest.approx(7, rel=0, abs=0.3)
    assert ax.B == ax.reversal.min()  # the largest-magnitude B_i, negative
    # "a large position-dependent error": the systematic deviation dwarfs the repeatability
    assert ax.E * 1e3 > 100 and ax.E > 5 * ax.R_up
    assert list(ax.n_up) == [5] * 9 and list(ax.n_down) == [5] * 9


def test_real_ess_b02_y_reversal():
    ax = evaluate_iso230_2(read_measurements(_real("ess_b02_y.csv"))).axes["Y"]
    assert ax.B_mean * 1e3 == pytest.approx(-13, rel=0, abs=1.0)


# ---- command line ----------------------------------------------------------------------------------

def test_cli_writes_json_and_table(tmp_path, capsys):
    p = _laser(tmp_path, CASE1)
    out = tmp_path / "iso.json"
    assert main(["iso230-2", str(p), "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert "axis X (linear), component EXX, deviations in um" in text
    assert "B  reversal (largest |B_i|, signed)" in text and "8.000" in text
    data = json.loads(out.read_text())
    assert set(data) == {"X"}
    for key in ("A_um", "A_up_um", "A_down_um", "B_um", "E_um", "E_up_um", "E_down_um", "M_um", "R_um",
                "R_up_um", "R_down_um"):
        assert data["X"][key] == pytest.approx(CASE1_AXIS[key[:-3]], rel=0, abs=1e-9), key


@pytest.mark.parametrize("text, msg", [
    ("axis,component,target_mm,dir,run,value_um\nX,EXX,0,1,1,abc\n", "row 1: column value_um: 'abc'"),
    ("axis,component,target_mm,dir,run,value_um\nX,EXX,0,1,1,1\n", "row 1: axis X: target 0 mm has 1"),
    ("x_mm,y_mm,z_mm,dx_um\n0,0,0,1\n", "this is a points file; iso230-2 needs a laser file"),
    ("", "empty file"),
])
def test_cli_bad_input_one_line_exit_2_nothing_written(tmp_path, capsys, text, msg):
    bad = tmp_path / "bad.csv"
    bad.write_text(text)
    out = tmp_path / "out.json"
    assert main(["iso230-2", str(bad), "--json", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith(f"mtcomp iso230-2: {bad}: ") and msg in err
    assert not out.exists()
    assert sorted(f.name for f in tmp_path.iterdir()) == ["bad.csv"]


def test_cli_refuses_to_overwrite_input(tmp_path, capsys):
    p = _laser(tmp_path, CASE1)
    before = p.read_text()
    assert main(["iso230-2", str(p), "--json", str(p)]) == 2
    assert "overwrite an input" in capsys.readouterr().err
    assert p.read_text() == before


def test_cli_process_bad_file_exit_2_no_traceback(tmp_path):
    import subprocess
    import sys
    bad = tmp_path / "bad.csv"
    bad.write_text("axis,component,target_mm,dir,run,value_um\nX,EXX,0,1,1,1\nX,EXX,0,3,2,1\n")
    proc = subprocess.run([sys.executable, "-m", "mtcomp", "iso230-2", str(bad)], capture_output=True,
                          text=True, cwd=tmp_path, timeout=60)
    assert proc.returncode == 2
    assert proc.stderr == (f"mtcomp iso230-2: {bad}: row 2: column dir: '3' is not an approach "
                           "direction (+1 or -1)\n")
    assert proc.stdout == ""


def test_invariances_offset_and_direction_swap():
    # second formulation: a constant offset moves every mean but no range, spread or reversal;
    # swapping the approach directions flips every B_i and swaps the up/down figures
    rng = np.random.default_rng(7)
    m, n = 6, 5
    target = np.repeat(np.linspace(0, 500, m), 2 * n)
    direction = np.tile(np.repeat([1, -1], n), m)
    run = np.tile(np.arange(1, n + 1), 2 * m)
    value = rng.normal(0, 0.004, m * 2 * n) + 0.003 * (direction > 0)
    base = evaluate_axis("Y", target, direction, run, value)
    shifted = evaluate_axis("Y", target, direction, run, value + 0.05)
    swapped = evaluate_axis("Y", target, -direction, run, value)
    for key in ("A", "A_up", "A_down", "B", "B_mean", "E", "E_up", "E_down", "M", "R", "R_up", "R_down"):
        assert getattr(shifted, key) == pytest.approx(getattr(base, key), rel=1e-9, abs=1e-12), key
    np.testing.assert_allclose(shifted.mean, base.mean + 0.05, rtol=0, atol=1e-12)
    np.testing.assert_allclose(swapped.reversal, -base.reversal, rtol=0, atol=1e-15)
    assert swapped.B == pytest.approx(-base.B, rel=0, abs=1e-15)
    for a, b in (("A_up", "A_down"), ("E_up", "E_down"), ("R_up", "R_down")):
        assert getattr(swapped, a) == pytest.approx(getattr(base, b), rel=0, abs=1e-15)
    for key in ("A", "E", "M", "R"):
        assert getattr(swapped, key) == pytest.approx(getattr(base, key), rel=0, abs=1e-15)
    assert base.B_mean == pytest.approx(np.mean(value[direction > 0]) - np.mean(value[direction < 0]),
                                        rel=1e-12, abs=0)


@pytest.mark.parametrize("name", ["ess_w42_back_x.csv", "ess_w42_back_x2.csv", "ess_w42_back_x8a.csv",
                                  "ess_w42_x.csv"])
def test_real_ess_w42_drift_shows_in_repeatability(name):
    # README: the ess_w42_* runs drift by up to 100 um or more from run to run. With n = 5 runs of
    # range r, s >= r / sqrt(2 (n - 1)), so 4 s >= sqrt(2) r: the unidirectional repeatability must
    # reflect the largest run-to-run spread read straight from the file.
    path = _real(name)
    data = read_measurements(path)
    spread_um = max(np.ptp(data.value[(data.target == t) & (data.dir == s)]) * 1e3
                    for t in np.unique(data.target) for s in (1, -1))
    assert spread_um > 100
    ax = evaluate_iso230_2(data).axes["X"]
    assert max(ax.R_up, ax.R_down) * 1e3 >= math.sqrt(2) * spread_um * (1 - 1e-12)


# ---- outliers, several files, the plot --------------------------------------------------------------
# Hand case 3: three targets, five runs per direction. Every group reads 1 2 3 2 2 (+ the target in
# um), s = sqrt((1 + 0 + 1 + 0 + 0) / 4) = sqrt(0.5), except up at 10 mm: 2 2 2 2 9. The median of the
# six s_i is sqrt(0.5). The 9 departs from the median of the others (2) by 7; the spread allowed is
# sqrt(0.5) sqrt(1 + pi / 8), so its score is 7 / (sqrt(0.5) sqrt(1 + pi / 8)) = 8.39 > 4: flagged.
# The clean readings depart by at most 1 (score 1.2): not flagged.
CASE3 = {(t, d): [1 + t, 2 + t, 3 + t, 2 + t, 2 + t] for t in (0, 10, 20) for d in (1, -1)}
CASE3[(10, 1)] = [12, 12, 12, 12, 19]


def test_outlier_rule_by_hand(tmp_path):
    ax = evaluate_iso230_2(read_measurements(_laser(tmp_path, CASE3))).axes["X"]
    assert len(ax.outliers) == 1
    o = ax.outliers[0]
    assert (o.target, o.dir, o.run) == (10.0, 1, 5)
    assert o.value * 1e3 == pytest.approx(19, abs=1e-9)
    assert o.departure * 1e3 == pytest.approx(7, abs=1e-9)
    assert o.score == pytest.approx(7 / (math.sqrt(0.5) * math.sqrt(1 + math.pi / 8)), rel=1e-12)
    clean = dict(CASE3)
    clean[(10, 1)] = [11, 12, 13, 12, 12]
    assert evaluate_iso230_2(read_measurements(_laser(tmp_path, clean, name="c.csv"))).axes["X"].outliers == ()


@pytest.mark.skipif(not REAL.is_dir(), reason=f"real data folder {REAL} is absent")
def test_real_outliers_are_the_first_readings_of_the_psi_cycle():
    rep = evaluate_iso230_2(read_measurements(REAL / "psi_mcu1025_x.csv"))
    assert [(o.run, o.row) for o in rep.axes["X"].outliers] == [(1, 1), (1, 2)]
    assert any("outlier" in n for n in rep.notices)
    assert evaluate_iso230_2(read_measurements(REAL / "ess_b02_y.csv")).axes["Y"].outliers == ()


def test_cli_several_files_json_per_file_and_plot(tmp_path, capsys):
    a = _laser(tmp_path, CASE1, name="a.csv")
    b = _laser(tmp_path, CASE3, name="b.csv")
    out, png = tmp_path / "iso.json", tmp_path / "runs.png"
    assert main(["iso230-2", str(a), str(b), "--json", str(out), "--plot", str(png)]) == 0
    text = capsys.readouterr().out
    assert f"ISO 230-2 evaluation of {a}" in text and f"ISO 230-2 evaluation of {b}" in text
    assert "outlier: target 10 mm, dir +1, run 5" in text
    data = json.loads(out.read_text())
    assert set(data) == {"a.csv", "b.csv"}
    assert data["a.csv"]["X"]["B_um"] == pytest.approx(8, abs=1e-9)
    assert data["b.csv"]["X"]["outliers"][0]["value_um"] == pytest.approx(19, abs=1e-9)
    single = tmp_path / "one.json"
    assert main(["iso230-2", str(a), "--json", str(single)]) == 0
    assert json.loads(single.read_text()) == data["a.csv"]
    image = pytest.importorskip("matplotlib.image").imread(png)
    assert image.shape[0] > 400 and image.shape[1] > 400       # two panels, stacked


def test_cli_plot_refused_onto_an_input(tmp_path, capsys):
    a = _laser(tmp_path, CASE1, name="a.csv")
    before = a.read_text()
    assert main(["iso230-2", str(a), "--plot", str(a)]) == 2
    assert "overwrite an input" in capsys.readouterr().err and a.read_text() == before
    # the plot is a PNG: another name is refused before anything is written
    assert main(["iso230-2", str(a), "--plot", str(tmp_path / "p.jpg"), "--json", str(tmp_path / "o.json")]) == 2
    assert ".png name" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.csv"]


def test_cli_runs_at_several_feeds_are_refused_with_the_way_out(tmp_path, capsys):
    """Runs at two feeds in one file: the same (target, dir, run) at each feed would be 'read twice';
    the command says the file holds two feeds and to give each its own file."""
    lines = ["axis,component,target_mm,dir,run,value_um,feed_mm_min"]
    for feed in (500, 1000):
        lines += [f"X,EXX,{t},{d},{r},{0.1 * r},{feed}" for t in (0, 10) for d in (1, -1) for r in (1, 2, 3)]
    p = tmp_path / "two_feeds.csv"
    p.write_text("\n".join(lines) + "\n")
    assert main(["iso230-2", str(p)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "runs of X at 2 feeds (500, 1000 mm/min)" in err and "its own file" in err
    # one feed per axis, and a straightness run (not evaluated) at another feed: evaluated
    lines = ["axis,component,target_mm,dir,run,value_um,feed_mm_min"]
    for axis, comp, feed in (("X", "EXX", 1000), ("Y", "EYY", 2000), ("X", "EYX", 500)):
        lines += [f"{axis},{comp},{t},{d},{r},{0.1 * r},{feed}" for t in (0, 10) for d in (1, -1) for r in (1, 2, 3)]
    p.write_text("\n".join(lines) + "\n")
    assert main(["iso230-2", str(p)]) == 0


# ---- run-to-run drift -------------------------------------------------------------------------------
# Hand case 4: one target, three runs each way (um). Up 1 3 5, down 2 4 9.
#   run means (1+2)/2 = 1.5, 3.5, 7; grand mean 4; cell means up 3, down 5
#   residuals x - cell mean - run mean + grand: up 0.5 0.5 -1, down -0.5 -0.5 1 -> SS_res = 3, df 2
#   SS_runs = 2 cells x ((-2.5)^2 + (-0.5)^2 + 3^2) = 31, df 2 -> F = (31/2) / (3/2) = 31/3
#   F(2, 2) has survival function 1 / (1 + F): p = 3/34; within-run s = sqrt(3/2)
#   trend: slope of 1.5, 3.5, 7 against 1, 2, 3 = ((-1)(-2.5) + (1)(3)) / 2 = 2.75; range 5.5
CASE4 = {(0, 1): [1, 3, 5], (0, -1): [2, 4, 9]}


def test_drift_hand_case(tmp_path):
    ax = evaluate_iso230_2(read_measurements(_laser(tmp_path, CASE4))).axes["X"]
    dr = ax.drift
    np.testing.assert_array_equal(dr.runs, [1, 2, 3])
    np.testing.assert_allclose(dr.run_means * 1e3, [1.5, 3.5, 7], rtol=0, atol=1e-12)
    assert dr.F == pytest.approx(31 / 3, rel=1e-12, abs=0)
    assert dr.p == pytest.approx(3 / 34, rel=1e-9, abs=0)
    assert dr.within_s * 1e3 == pytest.approx(math.sqrt(1.5), rel=1e-12, abs=0)
    assert dr.trend * 1e3 == pytest.approx(2.75, rel=1e-12, abs=0)
    assert dr.size * 1e3 == pytest.approx(5.5, rel=1e-12, abs=0)
    assert not dr.drift  # p = 0.088: three runs cannot tell this from scatter
    d = ax.to_dict()
    assert d["drift"] is False and d["run_means_um"] == pytest.approx([1.5, 3.5, 7], rel=0, abs=1e-12)
    assert d["drift_um"] == pytest.approx(5.5, rel=0, abs=1e-12) and d["runs"] == [1, 2, 3]


def test_drift_of_the_worked_example(tmp_path):
    # docs/iso230_2.md: CASE1 rises run by run in every cell. Run means 13/4, 20/4, 27/4; grand 5;
    # SS_runs = 4 (1.75^2 + 0 + 1.75^2) = 24.5 (df 2); residuals +-0.75, +-0.25, +-0.75, +-1.25 and
    # four zeros: SS_res = 5.5 (df 3 x 2 = 6); F = 12.25 / (5.5 / 6). Without the run offsets
    # (-1.75, 0, 1.75): s = 0.75, 0.25, 0.75, 1.25, so R_0 = max(1.5 + 0.5 + 4, 3, 1) = 6 and
    # R_10 = max(1.5 + 2.5 + 8, 3, 5) = 12: R = 12 (16 with the drift).
    dr = evaluate_iso230_2(read_measurements(_laser(tmp_path, CASE1))).axes["X"].drift
    np.testing.assert_allclose(dr.run_means * 1e3, [3.25, 5, 6.75], rtol=0, atol=1e-12)
    assert dr.F == pytest.approx(12.25 / (5.5 / 6), rel=1e-12, abs=0)
    assert dr.within_s * 1e3 == pytest.approx(math.sqrt(5.5 / 6), rel=1e-12, abs=0)
    assert dr.R_without * 1e3 == pytest.approx(12, rel=0, abs=1e-9)
    assert dr.trend * 1e3 == pytest.approx(1.75, rel=1e-12, abs=0)
    assert dr.drift and dr.p < DRIFT_ALPHA


def _drifting_file(tmp_path, offsets_um, noise_um, seed, name="drift.csv", missing=()):
    """X positioning: a position error, a backlash, a per-run offset and noise; rows of ``missing``
    (target, dir, run) left out."""
    rng = np.random.default_rng(seed)
    lines = ["axis,component,target_mm,dir,run,value_um"]
    for r, off in enumerate(offsets_um, start=1):
        for t in (0, 100, 200, 300, 400, 500):
            for d in (1, -1):
                v = 12 * math.sin(t / 80) + 3 * d + off + rng.normal(0, noise_um)
                if (t, d, r) not in missing:
                    lines.append(f"X,EXX,{t},{d},{r},{v:.4f}")
    p = tmp_path / name
    p.write_text("\n".join(lines) + "\n")
    return p


def _balanced_anova(path):
    """Second formulation: the balanced two-way analysis of variance, from the CSV text with plain
    Python (cells = target x direction, rows = runs). Returns run means, F, within-run s, um."""
    x = defaultdict(dict)
    with open(path, newline="") as f:
        for r in csv.DictReader(f):
            x[(float(r["target_mm"]), int(r["dir"]))][int(r["run"])] = float(r["value_um"])
    cells, runs = sorted(x), sorted(next(iter(x.values())))
    grand = statistics.mean(v for c in cells for v in x[c].values())
    cm = {c: statistics.mean(x[c].values()) for c in cells}
    rm = {j: statistics.mean(x[c][j] for c in cells) for j in runs}
    ss_run = len(cells) * sum((rm[j] - grand) ** 2 for j in runs)
    ss_res = sum((x[c][j] - cm[c] - rm[j] + grand) ** 2 for c in cells for j in runs)
    df1, df2 = len(runs) - 1, (len(cells) - 1) * (len(runs) - 1)
    return [rm[j] for j in runs], (ss_run / df1) / (ss_res / df2), math.sqrt(ss_res / df2)


def test_drift_against_balanced_anova_and_flag(tmp_path):
    p = _drifting_file(tmp_path, [0, 3, 6, 9, 12], 0.8, seed=11)
    ax = evaluate_iso230_2(read_measurements(p)).axes["X"]
    means, F, s = _balanced_anova(p)
    np.testing.assert_allclose(ax.drift.run_means * 1e3, means, rtol=0, atol=1e-9)
    assert ax.drift.F == pytest.approx(F, rel=1e-9, abs=0)
    assert ax.drift.within_s * 1e3 == pytest.approx(s, rel=1e-9, abs=0)
    assert ax.drift.drift and ax.drift.p < 1e-10
    # the drift put in is 3 um per run; the slope of five run means of 12 readings each has an sd of
    # 0.8 / sqrt(12) / sqrt(10) = 0.07 um per run
    assert ax.drift.trend * 1e3 == pytest.approx(3.0, rel=0, abs=0.3)
    # R with the run offsets taken out: the ISO R of the readings minus their run's offset
    shifted = _oracle_of_shifted(p, {j + 1: m - statistics.mean(means) for j, m in enumerate(means)},
                                 tmp_path)
    assert ax.drift.R_without * 1e3 == pytest.approx(shifted, rel=1e-9, abs=0)
    assert ax.drift.R_without < 0.5 * ax.R


def _oracle_of_shifted(path, offset_um, folder):
    """ISO R (um) of the file's readings minus ``offset_um[run]``, via the plain-Python oracle."""
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    q = folder / "shifted.csv"
    with open(q, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        for r in rows:
            w.writerow({**r, "value_um": float(r["value_um"]) - offset_um[int(r["run"])]})
    return _oracle(q)["R_um"]


def test_no_drift_not_flagged_and_missing_readings(tmp_path):
    flags = [evaluate_iso230_2(read_measurements(_drifting_file(tmp_path, [0] * 5, 1.0, seed=s,
                                                                name=f"n{s}.csv"))).axes["X"].drift.drift
             for s in range(20)]
    assert sum(flags) <= 2  # at 1 % per file, 20 clean files flag none or one, rarely two
    # a reading missing: run means are adjusted for it (the position error at 100 mm is not taken
    # for a drift of run 2), so they stay near the offsets put in
    p = _drifting_file(tmp_path, [0, 0, 20, 0, 0], 0.3, seed=3, missing={(100, 1, 2), (100, -1, 2)})
    dr = evaluate_iso230_2(read_measurements(p)).axes["X"].drift
    np.testing.assert_allclose(dr.run_means * 1e3 - np.median(dr.run_means * 1e3), [0, 0, 20, 0, 0],
                               rtol=0, atol=0.5)


def test_real_drift_of_the_w42_back_z_runs():
    path = _real("ess_w42_back_z.csv")
    rep = evaluate_iso230_2(read_measurements(path))
    ax = rep.axes["Z"]
    # run means straight from the CSV text
    by_run = defaultdict(list)
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    for r in rows:
        by_run[int(r["run"])].append(float(r["value_um"]))
    plain = [statistics.mean(by_run[j]) for j in sorted(by_run)]
    np.testing.assert_allclose(plain, [29.0, 156.4, 23.5, -70.2, -138.7], rtol=0, atol=0.05)
    np.testing.assert_allclose(ax.drift.run_means * 1e3, plain, rtol=0, atol=1e-9)
    assert ax.drift.drift and ax.drift.size * 1e3 == pytest.approx(max(plain) - min(plain), rel=1e-12)
    assert any(n.startswith("axis Z: the runs drift") for n in rep.notices)
    assert "drift" in ax.table() and "run mean" in ax.table()


@pytest.mark.parametrize("name, flagged", [("ess_b02_z.csv", False), ("psi_mcu1025_x.csv", False),
                                           ("ess_w42_y.csv", True), ("ess_b02_y.csv", True)])
def test_real_drift_flags(name, flagged):
    rep = evaluate_iso230_2(read_measurements(_real(name)))
    (ax,) = rep.axes.values()
    assert ax.drift.drift is flagged
    assert any("the runs drift" in n for n in rep.notices) is flagged


def test_cli_json_keeps_every_key_and_adds_the_drift(tmp_path, capsys):
    p = _drifting_file(tmp_path, [0, 3, 6, 9, 12], 0.8, seed=11)
    out = tmp_path / "o.json"
    assert main(["iso230-2", str(p), "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert "note: axis X: the runs drift" in text
    d = json.loads(out.read_text())["X"]
    old = {"axis_type", "A_um", "A_up_um", "A_down_um", "B_um", "B_mean_um", "E_um", "E_up_um",
           "E_down_um", "M_um", "R_um", "R_up_um", "R_down_um", "targets_mm", "n_up", "n_down",
           "mean_up_um", "mean_down_um", "mean_um", "reversal_um", "s_up_um", "s_down_um",
           "R_i_up_um", "R_i_down_um", "R_i_um", "outliers"}
    assert old <= set(d)
    assert d["drift"] is True and len(d["run_means_um"]) == 5
    for key in ("drift_um", "drift_trend_um_per_run", "drift_F", "drift_p", "within_run_s_um",
                "R_without_drift_um", "unit_suspect"):
        assert key in d, key


def test_runs_figure_draws_every_run_apart(tmp_path):
    pytest.importorskip("matplotlib")
    from mtcomp.identification.iso230_2 import runs_figure
    p = _drifting_file(tmp_path, [0, 3, 6, 9, 12], 0.8, seed=11)
    rep = evaluate_iso230_2(read_measurements(p))
    fig = runs_figure([rep])
    main_panel, runs_panel = fig.axes[:2]
    passes = {ln.get_gid(): ln for ln in main_panel.get_lines() if (ln.get_gid() or "").startswith("run ")}
    assert set(passes) == {f"run {j} {d}" for j in range(1, 6) for d in ("up", "down")}
    from matplotlib.colors import to_rgba
    assert len({to_rgba(passes[f"run {j} up"].get_color()) for j in range(1, 6)}) == 5  # one per run
    r = rep.axes["X"].readings
    sel = (r["run"] == 3) & (r["dir"] == -1)
    order = np.argsort(r["target"][sel])
    np.testing.assert_allclose(passes["run 3 down"].get_xdata(), r["target"][sel][order], rtol=0, atol=0)
    np.testing.assert_allclose(passes["run 3 down"].get_ydata(), r["value"][sel][order] * 1e3, rtol=0,
                               atol=1e-9)
    (means,) = [ln for ln in runs_panel.get_lines() if ln.get_gid() == "run means"]
    np.testing.assert_allclose(means.get_xdata(), [1, 2, 3, 4, 5], rtol=0, atol=0)
    np.testing.assert_allclose(means.get_ydata(), rep.axes["X"].drift.run_means * 1e3, rtol=0, atol=1e-12)
    import matplotlib.pyplot as plt
    plt.close(fig)


# ---- implausible units ------------------------------------------------------------------------------

def test_values_in_mm_under_value_um_are_flagged(tmp_path):
    # a 25 um error over 500 mm written in mm: every |value| below 0.05
    p = _drifting_file(tmp_path, [0] * 5, 0.5, seed=5)
    rows = p.read_text().splitlines()
    mm = [rows[0]] + [",".join(r.split(",")[:-1] + [f"{float(r.split(',')[-1]) / 1000:.6f}"]) for r in rows[1:]]
    q = tmp_path / "mm.csv"
    q.write_text("\n".join(mm) + "\n")
    rep = evaluate_iso230_2(read_measurements(q))
    note = [n for n in rep.notices if "value_um" in n]
    assert len(note) == 1 and "multiply them by 1000" in note[0] and "500 mm" in note[0]
    assert rep.axes["X"].to_dict()["unit_suspect"] is True
    # the same readings in um, and tiny values over a short travel, are not flagged
    assert evaluate_iso230_2(read_measurements(p)).axes["X"].to_dict()["unit_suspect"] is False
    short = _laser(tmp_path, {(t, d): [0.001 * t, 0.002, 0.003] for t in (0, 20) for d in (1, -1)},
                   name="short.csv")
    assert not any("value_um" in n for n in evaluate_iso230_2(read_measurements(short)).notices)


def test_a_run_drift_below_0_1_um_is_no_drift_however_significant():
    """Values in mm read as um have scatter so small that run means 0.001 um apart pass the F
    test: no drift is said below 0.1 um of range; 0.2 um is (hand-made runs)."""
    from mtcomp.identification.iso230_2 import run_drift
    rng = np.random.default_rng(0)
    runs, targets = np.repeat(np.arange(1, 6), 10), np.tile(np.repeat(np.arange(5.0), 2), 5)
    direction = np.tile([1, -1], 25)
    cell = (targets * 2 + (direction < 0)).astype(int)
    for step_mm, said in ((1e-6, False), (2e-4 / 4, True)):
        value = 1e-3 * targets + step_mm * (runs - 1) + rng.normal(0, 1e-9, runs.size)
        dr = run_drift("X", cell, targets, direction, runs, value)
        assert dr.p < 1e-6 and dr.drift == said

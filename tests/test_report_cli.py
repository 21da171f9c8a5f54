"""The printed reports of `mtcomp identify` and `mtcomp diagnose` in a metrologist's terms (error
components per axis with their range and its standard error, residuals per file and per laser
target; parameter rows only with --verbose), and `mtcomp predict` leaving blank what the model does
not determine. Numbers are checked against numpy means of the file's readings and the predict
command's output (the component ranges against the polynomial profiles: tests/test_identify_cli.py)."""
from __future__ import annotations

import csv
import re

import numpy as np
import pytest

from laser_files import write_x_positioning
from mtcomp.cli import main
from mtcomp.identification.report import component_meaning
from real_data import ISO230_2

X_TARGETS = [-200.0, -150.0, -100.0, -50.0, 0.0, 50.0, 100.0, 150.0, 200.0]


def _x_error_um(t, d):
    """A positioning error with a reversal of 4 um (mean up minus mean down)."""
    return 8.0 * np.sin(t / 90.0) + 0.00002 * t ** 2 + 2.0 * d


@pytest.fixture(scope="module")
def x_laser(tmp_path_factory):
    """Five bidirectional runs of X positioning (ISO 230-2), and a Y positioning run of the same
    machine."""
    tmp = tmp_path_factory.mktemp("xlaser")
    rng = np.random.default_rng(61)
    x = write_x_positioning(tmp / "x_pos.csv", X_TARGETS, _x_error_um, 5, 0.3, rng)
    rows = ["axis,component,target_mm,dir,run,value_um"]
    for run in (1, 2):
        for t in (-150.0, -50.0, 0.0, 50.0, 150.0):
            for d in (1, -1):
                rows.append(f"Y,EYY,{t},{d},{run},{3.0 * np.cos(t / 70.0) + rng.normal(0, 0.3):.4f}")
    y = tmp / "y_pos.csv"
    y.write_text("\n".join(rows) + "\n")
    return tmp, x, y


def _table(text, tag, comp):
    """Rows (target, measured +, measured -, model +, model -, resid +, resid -) of the per-target
    table of component ``comp`` of laser file ``tag`` in a printed report."""
    lines = text.splitlines()
    start = next(i for i, ln in enumerate(lines) if ln.startswith(f"laser {tag},") and f"({comp})" in ln)
    rows = []
    for ln in lines[start + 2:]:
        cells = ln.split()
        if len(cells) != 7 or not re.fullmatch(r"-?\d+\.\d+", cells[0]):
            break
        rows.append([float(c) for c in cells])
    return np.array(rows)


def _means(path, column="value_um"):
    """(target, dir) -> mean of the file's readings, straight from the CSV."""
    groups = {}
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            if row.get(column):
                groups.setdefault((float(row["target_mm"]), int(row["dir"])), []).append(float(row[column]))
    return {k: float(np.mean(v)) for k, v in groups.items()}


def test_identify_prints_components_and_per_target_table_not_parameter_rows(x_laser, tmp_path, capsys):
    tmp, x, _ = x_laser
    model = tmp_path / "m.json"
    assert main(["identify", "xfyz", str(x), "-o", str(model)]) == 0
    out = capsys.readouterr().out
    # the metrologist's terms: the positioning range with its standard error; what a positioning
    # run cannot see is said so, never printed as a number like 1e-10
    assert re.search(r"positioning\s+EXX\s+range\s+\d+\.?\d* \+- [\d.e-]+ um", out), out
    for comp in ("EYX", "EZX", "EAX", "EBX", "ECX"):
        assert re.search(rf"{comp}\s+range not measured: held at zero", out), out
    assert re.search(r"C0Y\s+not determined by the data", out)
    # and how many such rows there are, with what the data may still determine: their combinations
    n_open = len(re.findall(r"not determined by the data$", out, re.M))
    assert n_open > 0
    assert f"{n_open} of these are not determined by the data alone; combinations" in out
    assert "axes the data did not move: Y, Z" in out
    # no parameter rows, no null space: only their count
    assert "EXX_b1" not in out and "undeterm." not in out
    assert "combination(s) of parameters the data cannot determine" in out
    # the per-target table: measured means from the file, the model's prediction from predict
    pred = tmp_path / "pred.csv"
    assert main(["predict", "xfyz", str(model), str(x), "-o", str(pred)]) == 0
    capsys.readouterr()
    table = _table(out, "x_pos", "EXX")
    measured, predicted = _means(x), _means(pred, "pred_value_um")
    assert table[:, 0].tolist() == X_TARGETS
    for t, m_up, m_dn, p_up, p_dn, r_up, r_dn in table:
        np.testing.assert_allclose([m_up, m_dn], [measured[(t, 1)], measured[(t, -1)]], rtol=0, atol=6e-4)
        np.testing.assert_allclose([p_up, p_dn], [predicted[(t, 1)], predicted[(t, -1)]], rtol=0, atol=6e-4)
        np.testing.assert_allclose([r_up, r_dn], [measured[(t, 1)] - predicted[(t, 1)],
                                                  measured[(t, -1)] - predicted[(t, -1)]], rtol=0, atol=6e-4)
    # the base model has no reversal: the residuals split it, +2 and -2 um
    np.testing.assert_allclose(table[:, 5].mean() - table[:, 6].mean(), 4.0, rtol=0, atol=0.5)


def test_identify_verbose_prints_parameters_and_combinations(x_laser, tmp_path, capsys):
    _, x, _ = x_laser
    assert main(["identify", "xfyz", str(x), "-o", str(tmp_path / "m.json"), "--verbose"]) == 0
    out = capsys.readouterr().out
    assert re.search(r"^EXX_b1\s", out, re.M) and "undeterm." in out
    assert "combination(s) the data cannot determine" in out
    assert "positioning" in out and "x_pos" in out


def test_predict_leaves_blank_what_the_model_does_not_determine(x_laser, tmp_path, capsys):
    """A model of X alone predicts nothing of Y: its Y positioning readings are blank (not the
    -1e-9 the held parameters give), while the fitted X file is predicted in full."""
    _, x, y = x_laser
    model = tmp_path / "m.json"
    assert main(["identify", "xfyz", str(x), "-o", str(model)]) == 0
    for path, blank in ((y, True), (x, False)):
        out = tmp_path / f"pred_{path.stem}.csv"
        assert main(["predict", "xfyz", str(model), str(path), "-o", str(out)]) == 0
        with open(out, newline="") as f:
            rows = list(csv.DictReader(f))
        cells = [(r["pred_value_um"], r["pred_value_um_sd"]) for r in rows]
        if blank:
            assert all(c == ("", "") for c in cells), cells[:3]
        else:
            assert all(p and s for p, s in cells)
    err = capsys.readouterr().err
    assert "20 prediction(s) of y_pos rest only on what the model's data did not determine" in err


@pytest.mark.skipif(not ISO230_2.is_dir(), reason=f"real ISO 230-2 runs absent ({ISO230_2})")
def test_real_run_report_and_predict(tmp_path, capsys):
    """The real run of a stage's X (ess_b02_x): positioning 91 um over -20..20 mm, nothing else
    determined; predicting the same stage's Y run with it gives blanks."""
    model = tmp_path / "m.json"
    assert main(["identify", "xfyz", str(ISO230_2 / "ess_b02_x.csv"), "-o", str(model)]) == 0
    out = capsys.readouterr().out
    rng_um = float(re.search(r"positioning\s+EXX\s+range\s+([\d.]+) \+-", out).group(1))
    # the measured means of the file span 123 um (-52.6 .. 70.3); the base model has no reversal
    # and follows the mean of both directions, whose range is 96 um at the targets
    m = _means(ISO230_2 / "ess_b02_x.csv")
    both = [0.5 * (m[(t, 1)] + m[(t, -1)]) for t in sorted({t for t, _ in m})]
    assert 0.8 * np.ptp(both) < rng_um < 1.1 * np.ptp(both)
    assert re.search(r"EYX\s+range not measured: held at zero", out)
    pred = tmp_path / "pred.csv"
    assert main(["predict", "xfyz", str(model), str(ISO230_2 / "ess_b02_y.csv"), "-o", str(pred)]) == 0
    with open(pred, newline="") as f:
        assert all(r["pred_value_um"] == "" for r in csv.DictReader(f))


def test_component_names_a_metrologist_uses():
    expected = {("X", "EXX"): "positioning", ("X", "EYX"): "straightness in Y", ("X", "EAX"): "roll",
                ("X", "EBX"): "pitch", ("X", "ECX"): "yaw", ("Y", "EAY"): "pitch", ("Y", "EBY"): "roll",
                ("Y", "ECY"): "yaw", ("Z", "ECZ"): "roll", ("Z", "EAZ"): "tilt about X",
                ("C", "ECC"): "angular positioning", ("C", "EZC"): "axial", ("C", "EXC"): "radial in X",
                ("C", "EAC"): "tilt about X", ("A", "EXA"): "axial", ("A", "EYA"): "radial in Y"}
    assert {k: component_meaning(*k) for k in expected} == expected


def test_diagnose_prints_components_and_residuals_parameters_only_verbose(x_laser, tmp_path, capsys):
    """The diagnosis of the X run finds the 4 um reversal; its report gives the final model's
    components, the file's rms (the model written's rms of the report) and the per-target table, whose
    residuals no longer split the reversal; --verbose adds the parameter rows."""
    _, x, _ = x_laser
    args = ["diagnose", "xfyz", str(x), "--json", str(tmp_path / "r.json"), "-q"]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert re.search(r"positioning\s+EXX\s+range\s+[\d.]+ \+- [\d.e-]+ um", out), out
    assert re.search(r"EYX\s+range not measured: held at zero", out)
    final = float(re.search(r"^model written: .*\); rms ([\d.]+) um", out, re.M).group(1))
    file_rms = float(re.search(r"^x_pos\s+laser\s+\d+\s+value_um ([\d.]+)", out, re.M).group(1))
    np.testing.assert_allclose(file_rms, final, rtol=2e-3, atol=0)
    table = _table(out, "x_pos", "EXX")
    assert abs(table[:, 5].mean() - table[:, 6].mean()) < 0.5
    assert "EXX_b1" not in out
    assert main(args + ["--verbose"]) == 0
    assert re.search(r"^EXX_b1\s", capsys.readouterr().out, re.M)


def test_rotary_axis_components_match_the_fourier_series(tmp_path):
    """A 5-axis campaign (tracker points, laser runs, ball bar): the angular positioning range of A
    and C over the angles the data reached, against the documented series
    ECC(c) = ECC_0 + sum_k ECC_ck cos(k c) + ECC_sk sin(k c) (urad); error motions the model does not
    carry get no row; the location errors are the fitted values."""
    from mtcomp.identification.fit import identify
    from mtcomp.identification.report import GRID_POINTS, component_ranges
    from mtcomp.machine import load_machine
    from mtcomp.models import ErrorModel
    from mtcomp.sim import random_campaign, random_parameters, simulate

    machine = load_machine("cafxyz")
    model = ErrorModel(machine)
    rng = np.random.default_rng(5)
    truth = random_parameters(model, rng)
    camp = random_campaign(machine, rng, n_points=150, laser_offsets=1)
    res = identify(model, [simulate(model, d, truth, noise_um=0.3, noise_urad=0.5, rng=rng)
                           for d in camp.values()])
    ranges, values, _ = component_ranges(res.fitted_model)
    for axis in ("A", "C"):
        rows = [r for r in ranges if r.axis == axis]
        comp = f"E{axis}{axis}"
        assert [r.component for r in rows] == [comp] and rows[0].meaning == "angular positioning"
        lo, hi = res.fitted_model.support[axis]
        angle = np.linspace(lo, hi, GRID_POINTS)
        order = res.fitted_model.machine.axis(axis).fourier_order     # the harmonics the data chose
        e = res.value(f"{comp}_0")[0] + sum(res.value(f"{comp}_c{k}")[0] * np.cos(k * angle)
                                            + res.value(f"{comp}_s{k}")[0] * np.sin(k * angle)
                                            for k in range(1, order + 1))
        np.testing.assert_allclose(rows[0].range, np.ptp(e), rtol=1e-6, atol=1e-6)
        np.testing.assert_allclose([rows[0].lo, rows[0].hi], np.degrees([lo, hi]), rtol=0, atol=1e-9)
        assert rows[0].status == "fitted" and 0 < rows[0].sd < 0.1 * rows[0].range
    x0c = next(v for v in values if v.name == "X0C")
    np.testing.assert_allclose([x0c.value, x0c.sd], res.value("X0C"), rtol=1e-6, atol=1e-9)


def test_a_positioning_run_reports_the_positioning_error_and_what_was_not_measured(tmp_path, capsys):
    """One laser positioning run of Y (tool side of XFYZ, one tool length): the report gives EYY's
    range, which the readings' means per target show (the ISO 230-2 systematic deviation M), and
    says of the pitch and the rest that no file measured them (it printed 'not determined' for all,
    or half of EYY as a pitch)."""
    import re

    import numpy as np
    from mtcomp.cli import main
    targets = (-150, -100, -50, 0, 50, 100, 150)
    rng = np.random.default_rng(3)
    from laser_files import write_positioning
    path = write_positioning(tmp_path / "y.csv", "Y", targets, lambda t, d: 2e-4 * t ** 2 + 0.05 * t,
                             3, 0.2, rng)
    assert main(["identify", "xfyz", str(path), "-o", str(tmp_path / "m.json")]) == 0
    out = capsys.readouterr().out
    m = re.search(r"positioning\s+EYY\s+range\s+([\d.]+) \+- ([\d.]+) um", out)
    assert m, out
    t = np.array(targets, float)
    truth = 2e-4 * t ** 2 + 0.05 * t
    assert float(m.group(1)) == pytest.approx(np.ptp(truth), abs=max(3 * float(m.group(2)), 0.5))
    assert re.search(r"pitch\s+EAY\s+range not measured: held at zero", out), out

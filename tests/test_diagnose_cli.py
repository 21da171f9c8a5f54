"""`mtcomp diagnose` end to end: REPORT.json has the keys of SPEC 6, MODEL.json is the extended model
(checked by evaluating it independently, through load_model and the measurement models, on the
same files), bad input gives exit 2, one line, and no output file."""
import csv
import json
import re
from pathlib import Path

import numpy as np
import pytest

from mtcomp.cli import main
from sim_hidden import hidden_case
from mtcomp.measurement.readings import measurement_model
from mtcomp.measurement.drift import drift_context
from mtcomp.measurement.files import read_measurements
from mtcomp.machine import load_machine
from mtcomp.models import load_model


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    folder = tmp_path_factory.mktemp("campaign")
    case = hidden_case(41, ["backlash"], machine="xfyz")
    return case, [str(p) for p in case.write(folder)]


@pytest.fixture(scope="module")
def diagnosed(campaign, tmp_path_factory):
    """(REPORT.json, MODEL.json, standard output) of `diagnose xfyz` on the campaign, run once for
    the tests that read the same diagnosis."""
    import contextlib
    import io
    _, files = campaign
    folder = tmp_path_factory.mktemp("diagnosed")
    report, model = folder / "report.json", folder / "model.json"
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["diagnose", "xfyz", *files, "--json", str(report), "-o", str(model), "-q"]) == 0
    return report, model, out.getvalue()


def test_report_and_extended_model(campaign, diagnosed):
    case, files = campaign
    report, model, out = diagnosed
    assert "verdict: explained" in out and "evidence:" in out
    def no_nan(token):
        raise AssertionError(f"REPORT.json holds {token}")
    rep = json.loads(report.read_text(), parse_constant=no_nan)
    assert rep["verdict"] == "explained"
    for key in ("verdict", "noise_um", "base", "findings", "final"):
        assert key in rep
    for key in ("n_params", "rms_um", "heldout_rms_um"):
        assert key in rep["base"] and key in rep["final"]
    (f,) = rep["findings"]
    assert set(f) >= {"effect", "axis", "params", "evidence", "heldout_rms_before_um",
                      "heldout_rms_after_um"}
    h = case.effects[0]
    assert (f["effect"], f["axis"]) == (h["effect"], h["axis"])
    assert f["params"]["magnitude_um"] == pytest.approx(h["params"][f"BL_{h['axis']}"] * 1e3, rel=0.05)
    assert rep["noise_um"] == pytest.approx(case.noise_um, rel=0.1)
    assert rep["final"]["n_params"] == rep["base"]["n_params"] + 1

    # MODEL.json: the base model plus the backlash term, evaluated independently on every file;
    # its residual is the model written's rms of the report
    fitted = load_model(model, load_machine("xfyz"))
    assert [t.to_dict()["kind"] for t in fitted.model.terms] == ["backlash"]
    nuisance = fitted.info["nuisance"]
    resid = []
    for path in files:
        data = read_measurements(path)
        mm = measurement_model(fitted.model, data, fitted.context_defaults,
                               extra_context=drift_context(fitted.model, data))
        nu = np.array([nuisance[n] for n in mm.nuisance_names])
        r = (mm.observed - mm.predict(fitted.params.values, nu)) * mm.obs_unit_scale
        resid.append(r[np.asarray(mm.obs_column).astype(str) != "value_urad"])
    rms = float(np.sqrt(np.mean(np.concatenate(resid) ** 2)))
    assert rms == pytest.approx(rep["final"]["written"]["rms_um"], rel=1e-3)


def test_bad_inputs_exit_2_and_write_nothing(campaign, tmp_path, capsys):
    _, files = campaign
    report = tmp_path / "r.json"
    cases = [
        ["diagnose", "xfyz", str(tmp_path / "missing.csv"), "--json", str(report)],
        ["diagnose", "xfyz", *files[:2], "--json", str(tmp_path / "no" / "r.json")],
        ["diagnose", "xfyz", files[0], "--json", files[0]],
        ["diagnose", "nosuchmachine", files[0], "--json", str(report)],
        ["diagnose", "xfyz", files[0], "--json", str(report), "-o", str(report)],
    ]
    rotary = tmp_path / "rotary.csv"
    rotary.write_text("x_mm,y_mm,z_mm,c_deg,dx_um\n0,0,0,10,1.0\n1,0,0,20,1.5\n")
    cases.append(["diagnose", "xfyz", str(rotary), "--json", str(report)])
    # an output that is a folder (the report must not be written before the model's path is refused)
    folder = tmp_path / "folder"
    folder.mkdir()
    cases += [["diagnose", "xfyz", files[0], "--json", str(folder)],
              ["diagnose", "xfyz", files[0], "--json", str(report), "-o", str(folder)],
              ["identify", "xfyz", files[0], "-o", str(folder)]]
    for argv in cases:
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "Traceback" not in err, err
        assert not report.exists()
    # a file given twice (by its path, another spelling of it, a symlink, a hard link): its readings
    # would count twice and pass for repeats
    links = tmp_path / "links"
    links.mkdir()
    (links / "sym.csv").symlink_to(files[0])
    import os
    os.link(files[0], links / "hard.csv")
    spelt = str(links / ".." / "links" / "sym.csv")
    dotted = f"{Path(files[0]).parent}/./{Path(files[0]).name}"      # named as typed, ./ and all
    for other in (files[0], spelt, dotted, str(links / "sym.csv"), str(links / "hard.csv")):
        for cmd in (["diagnose", "xfyz", files[0], other, "--json", str(report)],
                    ["identify", "xfyz", files[0], other, "-o", str(report)]):
            assert main(cmd) == 2, cmd
            err = capsys.readouterr().err
            assert err.count("\n") == 1 and f"{other}: given twice (also as {files[0]})" in err, err
            assert not report.exists()
    # a copy under another name (a quality engineer's part saved twice): the same readings again
    import shutil
    copy = shutil.copy(files[0], links / "part4.csv")
    for cmd in (["diagnose", "xfyz", files[0], str(copy), "--json", str(report)],
                ["identify", "xfyz", files[0], str(copy), "-o", str(report)]):
        assert main(cmd) == 2, cmd
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and f"{copy}: the same bytes as {files[0]}" in err, err
        assert not report.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["folder", "links", "rotary.csv"]
    assert not any(folder.iterdir())


def test_angular_readings_alone_report_urad(tmp_path, capsys):
    """A laser file of yaw readings only: the held-out figures of findings are in urad and named so,
    and the summary's final line gives the angular rms (the um keys stay for data with positions)."""
    rng = np.random.default_rng(3)
    rows = ["axis,component,target_mm,dir,run,seq,value_urad,feed_mm_min"]
    k = 0
    for run in (1, 2, 3):
        for d in (1, -1):
            for x in np.linspace(-200, 200, 11)[::d]:
                k += 1
                v = 5.0 * np.sin(x / 100.0) + 2.0 * d + rng.normal(0, 0.2)
                rows.append(f"X,ECX,{x:g},{d},{run},{k},{v:.4f},1000")
    path = tmp_path / "yaw.csv"
    path.write_text("\n".join(rows) + "\n")
    report = tmp_path / "r.json"
    assert main(["diagnose", "xfyz", str(path), "--json", str(report)]) == 0
    out = capsys.readouterr().out
    r = json.loads(report.read_text())
    assert r["findings"]
    for f in r["findings"]:
        assert f["heldout_rms_before_urad"] > 0 and f["heldout_rms_before_um"] is None, f
    # the reversal of the yaw is no effect diagnose has: 'unexplained', on the axis whose approach
    # direction the residual follows, with the runs and a p-value like any unexplained finding
    un = [f for f in r["findings"] if f["effect"] == "unexplained"]
    assert un and un[0]["axis"] == "X" and un[0]["params"]["runs"] == [1, 2, 3]
    assert un[0]["params"]["p_value"] < 1e-6
    final = next(line for line in out.splitlines() if line.startswith("final model"))
    assert "urad" in final and f"{r['final']['heldout_rms_urad']:.4g}" in final
    # the noise floor is named by its unit: no um readings, no um noise
    assert r["noise_um"] is None and r["noise_urad"] == pytest.approx(0.2, rel=0.25)


def test_velocities_alone_report_um_per_min(tmp_path, capsys):
    """Velocity readings only (mm/min in the file): the noise and the rms figures are in um/min and
    named so (they had been printed as um)."""
    rng = np.random.default_rng(5)
    rows = ["axis,feed_mm_min,x_mm,m_x_mm,m_y_mm,m_vx_mm_min,m_vy_mm_min,n_x_mm,n_y_mm,n_vx_mm_min,"
            "n_vy_mm_min,dir_x,run"]
    for run in (1, 2, 3):
        for feed in (180.0, 300.0):
            for x in np.linspace(-100, 100, 21):
                w = 2e-7 * x / 100.0 * feed            # yaw rate of a yaw slope growing along X
                v = [feed - w * 150.0, w * 50.0, feed - w * 100.0, w * 250.0]
                v = [a + rng.normal(0, 1e-4) for a in v]
                rows.append(f"X,{feed:g},{x:g},50,150,{v[0]:.7f},{v[1]:.7f},250,100,{v[2]:.7f},{v[3]:.7f},1,{run}")
    path = tmp_path / "vel.csv"
    path.write_text("\n".join(rows) + "\n")
    report = tmp_path / "r.json"
    assert main(["diagnose", "xfyz", str(path), "--json", str(report), "-q"]) == 0
    out = capsys.readouterr().out
    r = json.loads(report.read_text())
    assert r["noise_um"] is None and r["noise_um_min"] == pytest.approx(0.1, rel=0.25)
    assert r["final"]["rms_um"] is None and r["final"]["heldout_rms_um_min"] == pytest.approx(0.1, rel=0.3)
    final = next(line for line in out.splitlines() if line.startswith("final model"))
    assert f"velocity rms {r['final']['rms_um_min']:.4g} um/min" in final
    # the same file in the bed's sense (every velocity negated): noted, fitted alike, and predicted in
    # its own sense
    bed = tmp_path / "bed.csv"
    head, *body = path.read_text().strip().split("\n")
    bed.write_text("\n".join([head] + [",".join(c if j not in (5, 6, 9, 10) else f"{-float(c):.7f}"
                                                  for j, c in enumerate(line.split(",")))
                                         for line in body]) + "\n")
    model = tmp_path / "m.json"
    assert main(["identify", "xfyz", str(path), "-o", str(model)]) == 0
    preds = []
    for f in (path, bed):
        assert main(["predict", "xfyz", str(model), str(f), "-o", str(tmp_path / f"p_{f.name}")]) == 0
        err = capsys.readouterr().err
        assert ("the bed's sense" in err) == (f == bed), err
        with open(tmp_path / f"p_{f.name}", newline="") as fh:
            preds.append(np.array([[float(r[c]) for c in ("pred_m_vx_mm_min", "pred_n_vy_mm_min")]
                                   for r in csv.DictReader(fh)]))
    np.testing.assert_allclose(preds[1], -preds[0], rtol=0, atol=1e-9)


def test_readings_outside_the_machine_travel_are_noted(tmp_path, capsys):
    """Readings beyond the machine file's travel are no error, but identify and diagnose say so on
    stderr (file, axis, how far), since the data may be of another machine."""
    toml = tmp_path / "small.toml"
    toml.write_text('name = "small"\ntopology = "XFYZ"\ntool_length_mm = 100.0\n' + "".join(
        f"[axes.{a}]\ntravel_mm = [-50.0, 50.0]\n" for a in "XYZ"))
    rows = ["axis,component,target_mm,dir,run,value_um"]
    rows += [f"X,EXX,{x:g},{d},{r},{0.01 * x + 0.3 * d:.3f}" for r in (1, 2) for d in (1, -1)
             for x in (-80, -40, 0, 40)]
    laser = tmp_path / "x.csv"
    laser.write_text("\n".join(rows) + "\n")
    assert main(["identify", str(toml), str(laser), "-o", str(tmp_path / "m.json")]) == 0
    assert main(["diagnose", str(toml), str(laser), "--json", str(tmp_path / "r.json"), "-q"]) == 0
    notes = [line for line in capsys.readouterr().err.splitlines() if "note:" in line]
    assert len(notes) == 2, notes
    for line in notes:
        assert "4 row(s) take X to -80..-80 mm, outside the machine's travel -50..50 mm" in line
    # inside the travel: no note
    assert main(["identify", "xfyz", str(laser), "-o", str(tmp_path / "m2.json")]) == 0
    assert "note:" not in capsys.readouterr().err
    # a static axis the file gives no column for is not the file's position (Y travel 100..600 mm,
    # the run has no y_mm): no note about Y; a y_mm column outside the travel is noted
    toml.write_text('name = "offset"\ntopology = "XFYZ"\ntool_length_mm = 100.0\n'
                    '[axes.X]\ntravel_mm = [-400.0, 400.0]\n[axes.Y]\ntravel_mm = [100.0, 600.0]\n'
                    '[axes.Z]\ntravel_mm = [-400.0, 400.0]\n')
    assert main(["identify", str(toml), str(laser), "-o", str(tmp_path / "m3.json")]) == 0
    assert "note:" not in capsys.readouterr().err
    with_y = tmp_path / "xy.csv"
    with_y.write_text("\n".join([rows[0] + ",y_mm"] + [r + ",50" for r in rows[1:]]) + "\n")
    assert main(["identify", str(toml), str(with_y), "-o", str(tmp_path / "m4.json")]) == 0
    err = capsys.readouterr().err
    assert "16 row(s) take Y to 50..50 mm, outside the machine's travel 100..600 mm" in err


def test_start_model_values_the_data_did_not_determine_are_not_taken(tmp_path, capsys):
    """A laser run of X alone, and a start model that holds a value its data did not determine (no
    standard error): a pitch of Z of 105 urad, which identify once put there. Started there, diagnose
    gave a tool-length error of 37 mm (the chain's products of small errors made its column at that
    point); such values are no start, so the model is the one diagnosed from identify's own model
    (the same knots: identify gives X's 11 targets 16 functions, diagnose's own base 11)."""
    from truth import TruthMachine
    from truth import campaigns as tc
    rng = np.random.default_rng(5)
    m = TruthMachine.random("xfyz", rng, effects=[], error_motions=False)
    laser = tc.laser(m, tmp_path / "x1.csv", rng, "X", components=("EXX",), targets=np.linspace(-200, 200, 11),
                     n_runs=3, feed_mm_min=[1000.0], noise_um=0.3, t0_s=0.0).path
    base = tmp_path / "b.json"
    assert main(["identify", "xfyz", str(laser), "-o", str(base)]) == 0
    doc = json.loads(base.read_text())
    assert "std_error" not in doc["parameters"]["EBZ_b1"]
    clean = tmp_path / "clean.json"
    clean.write_text(json.dumps(doc))
    doc["parameters"]["EBZ_b1"]["value"] = 104.85          # urad, held: not determined by the data
    base.write_text(json.dumps(doc))
    out = {}
    for name, extra in (("plain", ["--start", str(clean)]), ("started", ["--start", str(base)])):
        assert main(["diagnose", "xfyz", str(laser), "--json", str(tmp_path / f"{name}.r.json"), "-o",
                     str(tmp_path / f"{name}.json"), "-q", *extra]) == 0
        out[name] = json.loads((tmp_path / f"{name}.json").read_text())["parameters"]
    capsys.readouterr()
    for k, v in out["plain"].items():
        assert out["started"][k]["value"] == pytest.approx(v["value"], abs=1e-3), k
    assert abs(out["started"]["TOOL_dL"]["value"]) < 1e-3


def test_start_from_identify_model(campaign, diagnosed, tmp_path, capsys):
    """`--start MODEL.json`: identify's model is the base diagnosed (its knots, here fixed coarser by the
    machine file) and the start of the fit; the same effect is found as from the data's own base, and
    the start model is an input, never overwritten."""
    case, files = campaign
    # identify on a machine file that fixes coarser knots than the data choose: 8 intervals on X and Y,
    # 10 on Z: the 200 mm stylus puts the ram 100 mm above its tips, so Z's profiles are read over
    # 440 mm (-230 to 210) rather than 360; 10 intervals keep the 45 mm of 8 over 360 mm (8 over 440 mm,
    # 55 mm, leave Z's truth to the rival: 'unexplained Z' from the coarse start only)
    toml = tmp_path / "xfyz8.toml"
    toml.write_text('name = "xfyz8"\ntopology = "XFYZ"\ntool_length_mm = 100.0\n' + "".join(
        f'[axes.{a}]\ntravel_mm = [{lo}, {hi}]\nspline_intervals = {n}\n'
        for a, lo, hi, n in (("X", -400.0, 400.0, 8), ("Y", -300.0, 300.0, 8), ("Z", -250.0, 150.0, 10))))
    base = tmp_path / "base.json"
    assert main(["identify", str(toml), *files, "-o", str(base)]) == 0
    plain, started = diagnosed[0], tmp_path / "started.json"      # from the data's own base
    capsys.readouterr()
    assert main(["diagnose", "xfyz", *files, "--json", str(started), "-o", str(tmp_path / "ext.json"),
                 "--start", str(base)]) == 0
    err = capsys.readouterr().err
    start_line = next(line for line in err.splitlines() if "start:" in line)
    n_taken, n_base = (int(w) for w in re.findall(r"\d+", start_line)[:2])
    # the values identify's data determined (a standard error each); the rest start at zero
    determined = [v for v in json.loads(base.read_text())["parameters"].values()
                  if v.get("base") and "std_error" in v]
    assert 0 < n_taken == len(determined) < n_base
    a, b = json.loads(plain.read_text()), json.loads(started.read_text())
    assert [(f["effect"], f["axis"]) for f in a["findings"]] == [(f["effect"], f["axis"]) for f in b["findings"]]
    assert b["final"]["heldout_rms_um"] == pytest.approx(a["final"]["heldout_rms_um"], rel=0.05)
    assert b["base"]["n_params"] < a["base"]["n_params"]
    ext = load_model(tmp_path / "ext.json")
    assert [ax.spline_intervals for ax in ext.model.machine.linear_axes] == [8, 8, 10]
    # bad start models: not a model file; the report over the start model
    for argv in (["--start", files[0]], ["--start", str(base), "--json", str(base)]):
        report = tmp_path / "r.json"
        full = ["diagnose", "xfyz", *files, *([] if "--json" in argv else ["--json", str(report)]),
                *argv]
        assert main(full) == 2, argv
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "Traceback" not in err, err
        assert not report.exists()
    assert json.loads(base.read_text())["format"]

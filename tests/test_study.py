"""`mtcomp study`: the rows of a study run on a LocalCluster of 2 workers against direct `mtcomp
compensate` runs of the same settings; the judged error against an independent evaluation (the
model through mtcomp.kinematics.forward and mtcomp.models.deviation at the written positions of
BLOCKS.csv); draws against their covariance; a kill in the middle and a re-run; bad study files.
"""
import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from mtcomp import load_machine
from mtcomp.cli import main
from mtcomp.kinematics import forward
from mtcomp.models import ErrorModel, FittedModel, deviation, load_model, save_model

UNIT_SCALE = {"um": 10e-3, "urad": 20e-6, "mm": 50.0, "1": 0.05}

PROGRAM = """G21 G90 G17
G0 X-50 Y-40 Z20
G1 Z-5 F800
X60 Y-40
G2 X60 Y40 I0 J40 F600
G1 X-50 Y40
X-50 Y-38 Z-4.5
G0 Z30
G0 X120 Y100
G1 Z0 F300
X140 Y120 Z-2
M30
"""

#: a second program: a raster whose X reverses
RASTER = "G21 G90\nG0 X0 Y0 Z5\nG1 Z-1 F500\n" + "".join(
    f"G1 X{100 if k % 2 == 0 else 0} Y{k * 5}\nG1 Y{k * 5 + 5}\n" for k in range(8)) + "G0 Z20\nM30\n"


def _model(path, seed, rel_sd=0.05):
    """A polynomial xfyz model with random parameters of machine size and a diagonal covariance of
    ``rel_sd`` of that size per parameter."""
    machine = load_machine("xfyz").with_basis("polynomial")
    model = ErrorModel(machine)
    fitted = FittedModel.zero(model)
    rng = np.random.default_rng(seed)
    scale = np.array([UNIT_SCALE[s.unit] for s in model.param_specs])
    fitted.params.values[:] = rng.normal(size=model.n_params) * scale
    fitted.uncertainty = {"names": list(fitted.params.names),
                          "covariance": np.diag((rel_sd * scale) ** 2),
                          "undetermined": np.zeros((model.n_params, 0))}
    save_model(path, fitted)
    return fitted


def _write_study(tmp_path, text, models=(("MODEL.json", 3),)):
    for name, seed in models:
        _model(tmp_path / name, seed)
    (tmp_path / "progs").mkdir(exist_ok=True)
    (tmp_path / "progs" / "a.nc").write_text(PROGRAM)
    (tmp_path / "progs" / "b.nc").write_text(RASTER)
    study = tmp_path / "STUDY.toml"
    study.write_text(text)
    return study


STUDY = """machine = "xfyz"
programs = ["progs/*.nc"]
models = ["MODEL.json"]
draws = 2
seed = 7
[[bounds]]
name = "wide"
max_correction_um = 100
[[bounds]]
name = "tight"
max_correction_um = 4
max_step_um = 0.5
axis_max_correction = {Z = 1.0}
"""


def _rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def _blocks_judged(blocks_csv, fitted, machine):
    """(rms before, rms after) over the corrected rows of BLOCKS.csv under ``fitted``, evaluated
    independently: tip = forward(q) + deviation(q), nominal q = written minus correction, less the
    deviation at the part's datum (machine zero: the program has no work offset)."""
    rows = [r for r in _rows(blocks_csv) if r["corrected"] == "1"]
    q = np.array([[float(r[f"{a.lower()}_mm"]) for a in "XYZ"] for r in rows])
    dq = np.array([[float(r[f"c{a.lower()}_um"]) * 1e-3 for a in "XYZ"] for r in rows])
    nominal = q - dq
    p = fitted.params.values
    tip_after = forward(machine, q)[0] + deviation(fitted.model, q, p)[:, :3]
    tip_before = forward(machine, nominal)[0] + deviation(fitted.model, nominal, p)[:, :3]
    target = forward(machine, nominal)[0] + deviation(fitted.model, np.zeros_like(q), p)[:, :3]
    rms = lambda e: float(np.sqrt(np.mean(np.sum((e * 1e3) ** 2, axis=1))))   # noqa: E731
    return rms(tip_before - target), rms(tip_after - target)


def test_study_rows_match_direct_compensate_runs_and_an_independent_judge(tmp_path, capsys):
    study = _write_study(tmp_path, STUDY)
    out = tmp_path / "R"
    assert main(["study", str(study), "-o", str(out), "--workers", "2", "--quiet"]) == 0
    rows = _rows(out / "results.csv")
    assert len(rows) == 2 * 2 * 3          # programs x bounds x (model + 2 draws)
    assert {r["status"] for r in rows} == {"ok"}
    import pyarrow.parquet as pq
    table = pq.read_table(out / "results.parquet").to_pylist()
    assert [r["task"] for r in table] == [r["task"] for r in rows]
    for f in ("remaining_vs_bounds.png", "draws_spread.png", "pareto.png", "index.html"):
        assert (out / f).stat().st_size > 1000
    from mtcomp.study import draw_model
    from mtcomp.study.spec import _sha256
    machine = load_machine("xfyz")
    fitted = load_model(tmp_path / "MODEL.json", machine)
    checked = 0
    for r in rows:
        if r["draw"] == "2" and r["program"].endswith("b.nc"):
            continue                        # enough: the rest are the same path
        model_path = tmp_path / "MODEL.json"
        if r["draw"] != "0":
            drawn = draw_model(load_model(model_path, machine), int(r["draw"]), 7, _sha256(model_path))
            model_path = tmp_path / f"drawn{r['draw']}.json"
            save_model(model_path, drawn)
        flags = ["--max-correction-um", "100"] if r["bounds"] == "wide" else \
            ["--max-correction-um", "4", "--max-step-um", "0.5"]
        summary, blocks = tmp_path / "s.json", tmp_path / "b.csv"
        prog = tmp_path / r["program"]
        if r["bounds"] == "tight":
            continue                        # per-axis bounds have no flag: checked below by the row
        assert main(["compensate", "xfyz", str(model_path), str(prog), "-o", str(tmp_path / "o.nc"),
                     "--json", str(summary), "--report", str(blocks), "--quiet"] + flags) == 0
        s = json.loads(summary.read_text())
        assert int(r["blocks"]) == s["blocks"]
        assert int(r["corrected_blocks"]) == s["corrected"]["blocks"]
        assert float(r["plan_rms_after_um"]) == pytest.approx(s["corrected"]["rms_after_um"],
                                                              rel=1e-5, abs=1e-6)
        assert float(r["plan_max_after_um"]) == pytest.approx(s["corrected"]["max_after_um"],
                                                              rel=1e-5, abs=1e-6)
        # judged with the undrawn model, evaluated independently at the written positions
        before, after = _blocks_judged(blocks, fitted, machine)
        assert float(r["rms_before_um"]) == pytest.approx(before, rel=1e-4, abs=1e-5)
        assert float(r["rms_after_um"]) == pytest.approx(after, rel=1e-4, abs=1e-5)
        checked += 1
    assert checked == 5
    # a draw plans with another model: its own prediction and the judge's differ
    d1 = [r for r in rows if r["draw"] == "1" and r["bounds"] == "wide"][0]
    assert float(d1["rms_after_um"]) > float(d1["plan_rms_after_um"]) + 1e-3
    # the tight setting (4 um, Z 1 um per axis, 0.5 um a block) holds corrections back on every
    # program (by the size or the step bound: a block must also stay no worse than uncorrected)
    tight = [r for r in rows if r["bounds"] == "tight" and r["draw"] == "0"]
    assert all(float(r["share_max_correction"]) + float(r["share_max_step"]) > 0 for r in tight)
    assert all(float(r["rms_after_um"]) > float(w["rms_after_um"]) for r, w in
               zip(tight, [r for r in rows if r["bounds"] == "wide" and r["draw"] == "0"]))


def test_per_axis_bound_is_the_one_the_planner_uses(tmp_path):
    from mtcomp.compensation import CompensationSettings, build_problem
    machine = load_machine("xfyz").with_basis("polynomial")
    fitted = FittedModel.zero(ErrorModel(machine))
    s = CompensationSettings(max_correction_um=4, max_step_um=0.5, axis_max_correction={"Z": 1.0},
                             axis_max_step={"X": 0.25})
    p = build_problem(fitted, s, inch=False)
    np.testing.assert_allclose(p.max_correction, [4e-3, 4e-3, 1e-3], rtol=0, atol=1e-15)
    np.testing.assert_allclose(p.max_step, [0.25e-3, 0.5e-3, 0.5e-3], rtol=0, atol=1e-15)


def test_draws_follow_the_model_covariance(tmp_path):
    from mtcomp.study import draw_model
    fitted = _model(tmp_path / "m.json", 5)
    idx, F = fitted.covariance_factor()
    C = F @ F.T
    p0 = fitted.params.values.copy()
    d = np.array([draw_model(fitted, k, 1, "ab" * 32).params.values - p0 for k in range(1, 4001)])
    assert np.all(fitted.params.values == p0)               # the model itself is not changed
    sd = np.sqrt(np.diag(C))
    np.testing.assert_allclose(d.std(axis=0) / sd, 1.0, rtol=0, atol=0.06)
    np.testing.assert_allclose(d.mean(axis=0) / sd, 0.0, rtol=0, atol=0.06)
    # reproducible, and draw 0 is the model
    np.testing.assert_array_equal(draw_model(fitted, 3, 1, "ab" * 32).params.values,
                                  draw_model(fitted, 3, 1, "ab" * 32).params.values)
    assert draw_model(fitted, 0, 1, "ab" * 32) is fitted


def test_a_killed_study_resumes_without_computing_a_finished_task_twice(tmp_path):
    text = STUDY.replace("draws = 2", "draws = 9")
    study = _write_study(tmp_path, text)
    out = tmp_path / "R"
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    proc = subprocess.Popen([sys.executable, "-m", "mtcomp", "study", str(study), "-o", str(out),
                             "--workers", "2", "--quiet"], env=env, start_new_session=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    tasks = out / "tasks"
    deadline = time.monotonic() + 120
    try:
        while time.monotonic() < deadline:
            if tasks.is_dir() and len(list(tasks.glob("*.json"))) >= 6:
                break
            time.sleep(0.05)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    kept = {p.name: p.read_bytes() for p in tasks.glob("*.json")}
    assert 6 <= len(kept) < 40, "the study was not killed in the middle"
    assert not (out / "results.csv").exists()
    result = subprocess.run([sys.executable, "-m", "mtcomp", "study", str(study), "-o", str(out),
                             "--workers", "2", "--quiet"], capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    assert f"{40 - len(kept)} computed" in result.stdout
    assert f"{len(kept)} kept from before" in result.stdout
    # a kept row is the very file the first run wrote (a recomputed task rewrites it: its time differs)
    for name, data in kept.items():
        assert (tasks / name).read_bytes() == data
    rows = _rows(out / "results.csv")
    assert len(rows) == 40 and {r["status"] for r in rows} == {"ok"}
    assert len({r["task"] for r in rows}) == 40


def test_a_widened_grid_computes_only_what_is_new(tmp_path, capsys):
    study = _write_study(tmp_path, STUDY.replace("draws = 2", "draws = 0"))
    out = tmp_path / "R"
    assert main(["study", str(study), "-o", str(out), "--workers", "1", "--quiet"]) == 0
    first = _rows(out / "results.csv")
    study.write_text(STUDY.replace("draws = 2", "draws = 1"))
    capsys.readouterr()
    assert main(["study", str(study), "-o", str(out), "--workers", "1", "--quiet"]) == 0
    said = capsys.readouterr().out
    assert "4 computed" in said and "4 kept from before" in said
    again = {r["task"]: r for r in _rows(out / "results.csv")}
    for r in first:
        assert again[r["task"]] == r


def test_a_failing_task_records_its_error_and_the_study_goes_on(tmp_path, capsys):
    study = _write_study(tmp_path, STUDY.replace("draws = 2", "draws = 0"))
    (tmp_path / "progs" / "c.nc").write_text("G21 G90\nG1 X1 Y$ F100\n")     # a stray '$'
    out = tmp_path / "R"
    assert main(["study", str(study), "-o", str(out), "--workers", "1", "--quiet"]) == 0
    rows = _rows(out / "results.csv")
    bad = [r for r in rows if r["program"].endswith("c.nc")]
    assert len(bad) == 2 and all(r["status"] == "error" for r in bad)
    assert all("c.nc:2:" in r["error"] and "\n" not in r["error"] for r in bad)
    assert sum(r["status"] == "ok" for r in rows) == 4
    assert "failed: progs/c.nc" in capsys.readouterr().out
    # a failed task is not kept: fixed, it runs again, and only it
    (tmp_path / "progs" / "c.nc").write_text("G21 G90\nG0 X5 Y5 Z5\nG1 X20 F300\nM30\n")
    assert main(["study", str(study), "-o", str(out), "--workers", "1", "--quiet"]) == 0
    said = capsys.readouterr().out
    assert "2 computed" in said and "4 kept from before" in said and "0 failed" in said


@pytest.mark.parametrize("text, message", [
    ('machine = "xfyz"\nmodels = ["MODEL.json"]\n', "missing key 'programs'"),
    ('machine = "xfyz"\nprograms = ["none/*.nc"]\nmodels = ["MODEL.json"]\n', "matches no file"),
    ('machine = "xfyz"\nprograms = ["progs/a.nc"]\nmodels = ["MODEL.json"]\nfeeds = 3\n',
     "unknown key 'feeds'"),
    ('machine = "xfyz"\nprograms = ["progs/a.nc"]\nmodels = ["MODEL.json"]\n[[bounds]]\n'
     'max_correction_um = -1\n', "bounds[0] max_correction_um must be a positive number"),
    ('machine = "xfyz"\nprograms = ["progs/a.nc"]\nmodels = ["MODEL.json"]\n[[bounds]]\n'
     'axis_max_correction = {W = 1.0}\n', "has no W axis"),
    ('machine = "xfyz"\nprograms = ["progs/a.nc"]\nmodels = ["MODEL.json"]\nmethods = ["lp"]\n',
     "unknown method 'lp'"),
    ('machine = "xfyz"\nprograms = ["progs/a.nc"]\nmodels = ["MODEL.json"]\ndraws = 2\n',
     "no covariance to draw from"),
    ('machine = "xfyz"\nprograms = ["progs/a.nc"\n', "not valid TOML"),
])
def test_bad_study_files_get_one_line_and_nothing_written(tmp_path, capsys, text, message):
    study = _write_study(tmp_path, text)
    if "no covariance" in message:
        fitted = load_model(tmp_path / "MODEL.json", load_machine("xfyz"))
        fitted.uncertainty = None
        save_model(tmp_path / "MODEL.json", fitted)
    out = tmp_path / "R"
    assert main(["study", str(study), "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    named = "MODEL.json" if "no covariance" in message else study.name
    assert message in err and named in err and len(err.splitlines()) == 1
    assert not out.exists()


def test_scheduler_runs_the_study_on_an_existing_cluster(tmp_path, capsys):
    from dask.distributed import LocalCluster
    study = _write_study(tmp_path, STUDY.replace("draws = 2", "draws = 0"))
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None,
                      silence_logs=40) as cluster:
        out = tmp_path / "R"
        assert main(["study", str(study), "-o", str(out), "--scheduler", cluster.scheduler_address,
                     "--quiet"]) == 0
        assert f"4 computed on {cluster.scheduler_address}" in capsys.readouterr().out
        # the cluster is the caller's: still running
        assert cluster.status.name == "running"
    rows = _rows(out / "results.csv")
    assert len(rows) == 4 and {r["status"] for r in rows} == {"ok"}


def test_an_unreachable_scheduler_is_one_line(tmp_path, capsys, monkeypatch):
    """A refused connection (nothing listens on port 1) fails at once: Dask's Client alone tries it
    again until its timeout (20 s)."""
    from mtcomp.study import runner
    address = "tcp://127.0.0.1:1"
    monkeypatch.setattr(runner, "SCHEDULER_TIMEOUT_S", 60.0)
    study = _write_study(tmp_path, STUDY.replace("draws = 2", "draws = 0"))
    t0 = time.monotonic()
    assert main(["study", str(study), "-o", str(tmp_path / "R"), "--scheduler", address,
                 "--quiet"]) == 2
    assert time.monotonic() - t0 < 15.0                  # not the timeout waited out
    err = capsys.readouterr().err.strip()
    assert "cannot reach the Dask scheduler" in err and len(err.splitlines()) == 1
    assert address in err and "Connection refused" in err
    assert not (tmp_path / "R").exists()


def test_progress_shows_done_of_total_and_the_time_left():
    import io
    from mtcomp.study.runner import Progress
    stream = io.StringIO()
    bar = Progress(10, 4, stream=stream, every=0.0)
    bar.t0 -= 6.0                       # 6 s into the run (the cluster's start included)
    bar.update()
    bar.t_first -= 4.0                  # the first task finished 4 s ago
    bar.update(failed=True)
    lines = stream.getvalue().splitlines()
    assert "5/10 tasks (4 kept from before)" in lines[0] and "? left" in lines[0]
    assert "6/10 tasks (4 kept from before), 1 failed" in lines[1]
    # one task in the 4 s since the first finished, 4 to go: 16 s left (the start not counted)
    assert "0m06s elapsed, 0m16s left" in lines[1]


def test_a_judge_model_judges_every_compensation(tmp_path, capsys):
    """judge = a second model (a re-measurement): each row's before/after are that model's tip error
    at the nominal and at the written positions (independent evaluation on a direct compensate run),
    while plan_* stay the compensating model's."""
    text = STUDY.replace("draws = 2", 'draws = 0\njudge = "LATER.json"')
    study = _write_study(tmp_path, text, models=(("MODEL.json", 3), ("LATER.json", 4)))
    out = tmp_path / "R"
    assert main(["study", str(study), "-o", str(out), "--workers", "1", "--quiet"]) == 0
    rows = [r for r in _rows(out / "results.csv") if r["bounds"] == "wide"]
    assert rows and all(r["judge"] == "LATER.json" for r in rows)
    machine = load_machine("xfyz")
    later = load_model(tmp_path / "LATER.json", machine)
    for r in rows:
        blocks = tmp_path / "b.csv"
        assert main(["compensate", "xfyz", str(tmp_path / "MODEL.json"), str(tmp_path / r["program"]),
                     "-o", str(tmp_path / "o.nc"), "--max-correction-um", "100", "--report",
                     str(blocks), "--json", str(tmp_path / "s.json"), "--quiet"]) == 0
        before, after = _blocks_judged(blocks, later, machine)
        assert float(r["rms_before_um"]) == pytest.approx(before, rel=1e-4, abs=1e-5)
        assert float(r["rms_after_um"]) == pytest.approx(after, rel=1e-4, abs=1e-5)
        s = json.loads((tmp_path / "s.json").read_text())
        assert float(r["plan_rms_after_um"]) == pytest.approx(s["corrected"]["rms_after_um"],
                                                              rel=1e-5, abs=1e-6)
        assert float(r["rms_after_um"]) > 10 * float(r["plan_rms_after_um"])   # another machine


def test_a_program_with_no_corrected_block_has_no_remaining_error(tmp_path):
    study = _write_study(tmp_path, STUDY.replace("draws = 2", "draws = 0"))
    (tmp_path / "progs" / "x.nc").write_text("G21 G90\nG0 X10\nG1 X20 F100\nM30\n")  # Y, Z unknown
    out = tmp_path / "R"
    assert main(["study", str(study), "-o", str(out), "--workers", "1", "--quiet"]) == 0
    rows = [r for r in _rows(out / "results.csv") if r["program"].endswith("x.nc")]
    assert rows and all(r["status"] == "ok" and r["corrected_blocks"] == "0" for r in rows)
    assert all(r["rms_after_um"] == "" and r["plan_rms_after_um"] == "" for r in rows)


def test_plot_legends_name_programs_by_file_name_where_that_tells_them_apart():
    from mtcomp.study.plots import _case_label
    cases = [("/shop/jobs/a/PART.MPF", "m.json", "qp", ""), ("/shop/jobs/b/BRACKET.MPF", "m.json", "qp", "")]
    assert [_case_label(c, cases) for c in cases] == ["PART.MPF", "BRACKET.MPF"]
    same = [("/shop/a/PART.MPF", "m.json", "qp", ""), ("/shop/b/PART.MPF", "m.json", "qp", "")]
    assert [_case_label(c, same) for c in same] == ["/shop/a/PART.MPF", "/shop/b/PART.MPF"]
    methods = [("/shop/a/PART.MPF", "m.json", "qp", ""), ("/shop/a/PART.MPF", "m.json", "casadi", "")]
    assert [_case_label(c, methods) for c in methods] == ["PART.MPF, qp", "PART.MPF, casadi"]

"""`mtcomp identify`: fits files of several kinds, writes a MODEL.json that load_model reads back and
whose predictions match the fit; bad input exits 2 with one line and writes nothing."""
from __future__ import annotations

import json

import numpy as np
import pytest

from mtcomp.cli import main
from mtcomp.identification.fit import identify
from mtcomp.measurement.readings import measurement_model
from mtcomp.measurement.files import read_measurements
from mtcomp.machine import load_machine
from mtcomp.models import ErrorModel, load_model
from mtcomp.sim import random_campaign, random_parameters, simulate, write_measurements


POLY_XFYZ = """name = "xfyz-poly"
topology = "XFYZ"
tool_length_mm = 100.0
[axes.X]
travel_mm = [-400.0, 400.0]
basis = "polynomial"
[axes.Y]
travel_mm = [-300.0, 300.0]
basis = "polynomial"
[axes.Z]
travel_mm = [-250.0, 150.0]
basis = "polynomial"
"""


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """A campaign of mtcomp's own simulator on a machine file with the polynomial basis (these tests
    check the command against the API by parameter name)."""
    tmp = tmp_path_factory.mktemp("identify")
    (tmp / "poly.toml").write_text(POLY_XFYZ)
    machine = load_machine(tmp / "poly.toml")
    model = ErrorModel(machine)
    rng = np.random.default_rng(30)
    camp = random_campaign(machine, rng, n_points=150, laser_offsets=1)
    p = random_parameters(model, rng)
    paths = {}
    for kind, data in camp.items():
        path = tmp / f"{kind}.csv"
        write_measurements(path, simulate(model, data, p, noise_um=0.3, noise_urad=0.5, rng=rng))
        paths[kind] = path
    return tmp, paths, model


def test_identify_writes_model_that_reads_back_and_predicts(files, capsys):
    tmp, paths, model = files
    out = tmp / "model.json"
    args = ["identify", str(tmp / "poly.toml"), *map(str, paths.values()), "-o", str(out), "--hold",
            "EXY_2,EXZ_2", "--hold", "EYZ_2", "--known-setup", str(paths["points"])]
    assert main(args) == 0
    text = capsys.readouterr().out
    assert "rms residual" in text and "points" in text and "wrote" in text
    fitted = load_model(out, load_machine(tmp / "poly.toml"))
    raw = json.loads(out.read_text())
    assert raw["parameters"]["EXX_1"]["unit"] == "um" and "std_error" in raw["parameters"]["EXX_1"]
    assert raw["parameters"]["EXY_2"]["value"] == 0.0          # held
    # the squareness carries the straightness slope: no EXY_1 in the base model (ISO 230-1)
    assert "EXY_1" not in raw["parameters"] and "C0Y" in raw["parameters"]
    # the same fit through the Python API
    data = [read_measurements(p) for p in paths.values()]
    res = identify(model, data, hold=["EXY_2", "EXZ_2", "EYZ_2"], known_setup=[paths["points"]])
    np.testing.assert_allclose(fitted.params.values, res.values, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(fitted.params.std_errors[res.determined], res.std_errors[res.determined],
                               rtol=1e-9, atol=0)
    # the model's predictions reproduce observed minus residual of the fit (points file: no nuisance)
    mm = measurement_model(fitted.model, data[0])
    f = res.files[0]
    np.testing.assert_allclose(mm.predict(fitted.params.values, None) * 1e3,
                               mm.observed * 1e3 - f.residual, rtol=0, atol=1e-6)


def _one_line_error(capsys):
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "Traceback" not in err
    return err


def test_reader_errors_exit_2_with_one_line_and_write_nothing(files, capsys):
    tmp, paths, _ = files
    bad = tmp / "bad.csv"
    bad.write_text("x_mm,y_mm,z_mm,dx_um\n1,2,3,0.5\n1,2,abc,0.1\n")
    out = tmp / "never.json"
    assert main(["identify", "xfyz", str(paths["points"]), str(bad), "-o", str(out)]) == 2
    err = _one_line_error(capsys)
    assert "bad.csv" in err and "row 2" in err
    assert not out.exists()
    # an unknown machine, an unknown --hold name, overwriting an input
    assert main(["identify", "nosuchmachine", str(paths["points"]), "-o", str(out)]) == 2
    _one_line_error(capsys)
    assert main(["identify", "xfyz", str(paths["points"]), "-o", str(out), "--hold", "EXX_9"]) == 2
    assert "EXX_9" in _one_line_error(capsys)
    before = paths["points"].read_bytes()
    assert main(["identify", "xfyz", str(paths["points"]), "-o", str(paths["points"])]) == 2
    assert "overwrite" in _one_line_error(capsys)
    assert paths["points"].read_bytes() == before
    assert not out.exists()
    assert not list(tmp.glob(".*.part"))


def test_identify_refuses_file_whose_axes_the_machine_lacks(files, capsys):
    tmp, _, _ = files
    f = tmp / "rot.csv"
    f.write_text("x_mm,y_mm,z_mm,c_deg,dx_um\n0,0,0,10,1.0\n")
    assert main(["identify", "xfyz", str(f), "-o", str(tmp / "m.json")]) == 2
    err = _one_line_error(capsys)
    assert "rot.csv" in err and "no C axis" in err


def test_identify_options_noise_weights_and_rcond(files, capsys):
    tmp, paths, _ = files
    out = tmp / "model_noise.json"
    assert main(["identify", str(tmp / "poly.toml"), str(paths["points"]), str(paths["laser"]), "-o",
                 str(out), "--weights", "noise", "--rcond", "1e-5", "--known-setup", str(paths["points"])]) == 0
    text = capsys.readouterr().out
    assert "weighting 1/noise per file" in text
    # a rich points + laser campaign determines every base parameter
    assert "every fitted parameter is determined by the data" in text
    assert out.exists()
    assert main(["identify", "xfyz", str(paths["points"]), "-o", str(tmp / "x.json"), "--rcond", "2"]) == 2
    assert "--rcond" in _one_line_error(capsys)
    assert not (tmp / "x.json").exists()


def test_a_reader_that_goes_away_stops_the_command_quietly(tmp_path):
    """`mtcomp identify ... | head -1`: the summary's reader closes the pipe; the model is written
    whole, the command stops with 141 (as a shell reports SIGPIPE) and no traceback."""
    import subprocess
    import sys
    rows = ["axis,component,target_mm,dir,run,value_um"]
    rows += [f"X,EXX,{x},{d},{r},{0.01 * x + 0.1 * r}" for r in (1, 2) for d in (1, -1) for x in (0, 50, 100)]
    (tmp_path / "x.csv").write_text("\n".join(rows) + "\n")
    import os
    env = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}   # stdout buffered, as usual
    argv = [sys.executable, "-m", "mtcomp", "identify", "xfyz", str(tmp_path / "x.csv"), "-o", str(tmp_path / "m.json")]
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env)
    proc.stdout.close()                       # the reader is gone before a line is written
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=120) == 141, err
    assert "Traceback" not in err and "BrokenPipe" not in err, err
    assert json.loads((tmp_path / "m.json").read_text())["format"]
    # an error line into a closed pipe (`2>&1 | head`): no traceback either
    bad = [sys.executable, "-m", "mtcomp", "identify", "xfyz", str(tmp_path / "none.csv"), "-o",
           str(tmp_path / "n.json")]
    proc = subprocess.Popen(bad, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, env=env)
    proc.stdout.close()
    assert proc.wait(timeout=120) == 141


def test_component_ranges_match_the_polynomial_profiles(files):
    """Range over the data's travel and its standard error, against the documented polynomial
    E(s) = sum_k E_k (s / 1 m)^k (file units) and the fit's covariance of those coefficients;
    straightness about its least-squares line (numpy's polyfit)."""
    from mtcomp.identification.report import GRID_POINTS, component_ranges
    from mtcomp.models.chain import polynomial_orders
    tmp, paths, model = files
    res = identify(model, [read_measurements(p) for p in paths.values()])
    machine = res.fitted_model.machine          # the basis the data chose
    ranges, values, _ = component_ranges(res.fitted_model)
    index = {n: i for i, n in enumerate(res.unknown_names)}
    checked = 0
    for r in ranges:
        lo, hi = res.fitted_model.support[r.axis]
        s = np.linspace(lo, hi, GRID_POINTS)
        orders = polynomial_orders(machine, r.axis, r.component)
        names = [f"{r.component}_{k}" for k in orders]
        basis = np.column_stack([(s / 1000.0) ** k for k in orders])
        coef = np.array([res.value(n)[0] for n in names])
        e = basis @ coef
        if r.meaning.startswith("straightness"):
            line = np.polyval(np.polyfit(s, e, 1), s)
            e = e - line
            basis = basis - np.column_stack([np.polyval(np.polyfit(s, b, 1), s) for b in basis.T])
        assert r.status == "fitted"
        np.testing.assert_allclose(r.range, np.ptp(e), rtol=1e-6, atol=1e-9)
        j = basis[np.argmax(e)] - basis[np.argmin(e)]
        f = np.array([res.specs[res.param_names.index(n)].to_file for n in names])
        C = res.covariance[np.ix_([index[n] for n in names], [index[n] for n in names])] * np.outer(f, f)
        np.testing.assert_allclose(r.sd, np.sqrt(j @ C @ j), rtol=1e-6, atol=1e-9)
        checked += 1
    assert checked == 18
    c0y = next(v for v in values if v.name == "C0Y")
    np.testing.assert_allclose([c0y.value, c0y.sd], res.value("C0Y"), rtol=1e-6, atol=1e-9)


def test_an_axis_whose_errors_are_held_is_not_called_unmoved(files, capsys):
    """--hold X holds every error of X: the data moved X, so the report says its errors were held
    as given, not that the data did not move it (it said "axes the data did not move: X")."""
    tmp, paths, _model = files
    out = tmp / "held_x.json"
    assert main(["identify", str(tmp / "poly.toml"), str(paths["points"]), "-o", str(out),
                 "--hold", "X"]) == 0
    text = capsys.readouterr().out
    assert "axes whose errors were held as given (--hold): X:" in text
    assert "axes the data did not move" not in text


def test_sigterm_stops_the_command_like_ctrl_c(tmp_path, monkeypatch, capsys):
    """`kill` / `timeout` (SIGTERM) while a command writes its output: it stops with 143, one line,
    no traceback, and leaves neither the output nor its hidden temporary file (the default SIGTERM
    action killed the process inside its atomic write and left '.NAME.*.part' behind)."""
    import os
    import signal

    import mtcomp.commands.identify as identify
    from mtcomp.io.atomic import atomic_write
    out = tmp_path / "m.json"

    def run(args):
        with atomic_write(out) as f:
            f.write("{")
            os.kill(os.getpid(), signal.SIGTERM)
        return 0

    monkeypatch.setattr(identify, "run", run)
    before = signal.getsignal(signal.SIGTERM)
    assert main(["identify", "xfyz", str(tmp_path / "x.csv"), "-o", str(out)]) == 143
    assert capsys.readouterr().err == "mtcomp: terminated\n"
    assert list(tmp_path.iterdir()) == []
    assert signal.getsignal(signal.SIGTERM) is before          # the handler is the caller's again

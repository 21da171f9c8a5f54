"""The model `mtcomp diagnose` writes on a normal 5-axis campaign (a new user's finding): a
university lab's double turntable (CAFXYZ) read with ISO 230-2 laser runs of X, Y and Z, a ball-bar
circle both ways and an R-test (three nests on the table at A = 0, -30, -60 deg and C every 30 deg,
every axis approached from each side). Identify's model of these files predicted 200 poses the
campaign never read to 0.89 um of the truth; diagnose's model, identify's plus the backlash it found,
was 31.6 um off, with standard errors of 24 um that compensate could not use: judged with the
backlash's 8 um in the chain, one more combination of C's and A's location and angular errors
passed the rank test on second-order effects alone, and the fit moved it to 470 urad.

The oracle is the independent truth machine (tests/truth, no code shared with mtcomp), with the
errors the user gave their own simulator (squareness C0Y 50 urad, C's axis line 15 um off in X and
tilted 40 urad about X, X's scale 30 um/m, an 8 um backlash of X, 0.3 um noise) and the same readings:
the user's files are these to the digit."""
from __future__ import annotations

import numpy as np
import pytest

from mtcomp.diagnose import diagnose
from mtcomp.identification.fit import identify
from mtcomp.identification.predict import predict_readings
from mtcomp.machine import load_machine
from mtcomp.measurement.files import read_measurements
from truth import Backlash, Context, TruthMachine, campaigns
from truth import profiles as P

NOISE_MM = 0.3e-3
NESTS = np.array([[100.0, 0.0, 50.0], [0.0, 0.0, 150.0], [-80.0, 60.0, 30.0]])


def _lab_machine() -> TruthMachine:
    m = TruthMachine.zero("cafxyz")
    m.squareness["C0Y"] = 50e-6
    m.location["X0C"], m.location["A0C"] = 15e-3, 40e-6
    m.components["X"]["EXX"] = P.Linear(0.0, 30e-6)
    m.effects = (Backlash("X", 8.0),)
    return m


def _deviation(m, q, dir_x) -> np.ndarray:
    """(n, 3) mm: the truth's tip deviation at poses q (n, 5: mm and deg), X approached from dir_x."""
    q = np.atleast_2d(np.asarray(q, dtype=float)).copy()
    q[:, 3:] = np.radians(q[:, 3:])
    return m.true_deviation(q, None, Context(0.0, {"X": np.broadcast_to(dir_x, len(q)).astype(float)}))[0]


def _axes_of(m, Pw, a_deg, c_deg) -> np.ndarray:
    """(n, 5) the nominal axis positions (mm, deg) that put the tip at workpiece points Pw."""
    q = np.zeros((len(Pw), 5))
    q[:, 3], q[:, 4] = a_deg, c_deg
    W = m.wp2bed(np.column_stack([np.zeros((len(Pw), 3)), np.radians(q[:, 3:])]), errors=False)
    q[:, :3] = np.einsum("nij,nj->ni", W[:, :3, :3], Pw) + W[:, :3, 3]
    return q


def _laser(m, rng, folder, axis, targets):
    runs, dirs, tg = [], [], []
    for run in range(1, 6):
        for d in (1, -1):
            t = targets if d == 1 else targets[::-1]
            runs += [run] * len(t)
            dirs += [d] * len(t)
            tg += list(t)
    q = np.zeros((len(tg), 5))
    q[:, "XYZ".index(axis)] = tg
    dev = _deviation(m, q, np.array(dirs) if axis == "X" else 0.0)[:, "XYZ".index(axis)]
    value = (dev + rng.normal(0.0, NOISE_MM, len(tg))) * 1e3
    return campaigns.write_csv(folder / f"laser_{axis.lower()}.csv", {
        "axis": [axis] * len(tg), "component": [f"E{axis}{axis}"] * len(tg),
        "target_mm": np.round(tg, 3), "dir": dirs, "run": runs, "value_um": np.round(value, 3),
        "seq": np.arange(1, len(tg) + 1)})


def _ballbar(m, rng, folder):
    k = np.radians(np.arange(0, 360, 5))
    th = np.concatenate([k, -k])
    sense = np.repeat([1, -1], k.size)
    x, y = 100.0 * np.cos(th), 100.0 * np.sin(th)
    dx = np.where(np.abs(np.sin(th)) > 1e-9, -np.sign(np.sin(th)) * sense, 0.0)
    q = np.column_stack([x, y, np.zeros((th.size, 3))])
    length = np.linalg.norm(q[:, :3] + _deviation(m, q, dx), axis=1) + rng.normal(0.0, NOISE_MM, th.size)
    zero = np.zeros(th.size)
    return campaigns.write_csv(folder / "ballbar_xy.csv", {
        "x_mm": np.round(x, 4), "y_mm": np.round(y, 4), "z_mm": zero, "table_ball_x_mm": zero,
        "table_ball_y_mm": zero, "table_ball_z_mm": zero, "tool_ball_x_mm": zero, "tool_ball_y_mm": zero,
        "tool_ball_z_mm": zero, "length_mm": np.round(length, 6), "dir_x": np.where(dx == 0, np.nan, dx),
        "run": np.where(sense > 0, 1, 2)})


def _rtest(m, rng, folder):
    grid = [(run, p, a, c) for run in (1, 2) for p in NESTS for a in (0, -30, -60) for c in range(0, 360, 30)]
    Pw = np.array([p for _, p, _, _ in grid])
    q = _axes_of(m, Pw, np.array([g[2] for g in grid]), np.array([g[3] for g in grid]))
    dirs = np.array([1 if g[0] == 1 else -1 for g in grid])
    d = (_deviation(m, q, dirs) + rng.normal(0.0, NOISE_MM, (len(grid), 3))) * 1e3
    return campaigns.write_csv(folder / "rtest.csv", {
        "x_mm": np.round(q[:, 0], 4), "y_mm": np.round(q[:, 1], 4), "z_mm": np.round(q[:, 2], 4),
        "a_deg": q[:, 3], "c_deg": q[:, 4],
        "dx_um": np.round(d[:, 0], 3), "dy_um": np.round(d[:, 1], 3), "dz_um": np.round(d[:, 2], 3),
        "dir_x": dirs, "run": [g[0] for g in grid]})


def lab_campaign(folder):
    """(truth machine, paths): the lab's five files, written as the user's simulator wrote them."""
    m = _lab_machine()
    rng = np.random.default_rng(7)
    x_targets = np.linspace(-300, 300, 11) + np.array([0, 3.1, -2.2, 1.7, 0.9, 0, -1.3, 2.4, -0.8, 1.1, 0])
    paths = [_laser(m, rng, folder, "X", x_targets)]
    paths += [_laser(m, rng, folder, a, np.linspace(-250, 250, 11)) for a in "YZ"]
    return m, paths + [_ballbar(m, rng, folder), _rtest(m, rng, folder)]


def _check_points(m, folder):
    """(path, (200, 3) workpiece points, (200, 3) um true deviations): 200 poses the campaign never
    read (A also at -15 and -45 deg, C anywhere), as the user chose them."""
    rng = np.random.default_rng(3)
    Pw, a, c = np.zeros((200, 3)), np.zeros(200), np.zeros(200)
    for i in range(200):
        Pw[i] = [rng.uniform(-100, 100), rng.uniform(-100, 100), rng.uniform(0, 150)]
        a[i], c[i] = rng.choice([0, -30, -60, -15, -45]), rng.uniform(0, 330)
    q = _axes_of(m, Pw, a, c)
    true = _deviation(m, q, 0.0) * 1e3
    path = campaigns.write_csv(folder / "check.csv", {
        "x_mm": q[:, 0], "y_mm": q[:, 1], "z_mm": q[:, 2], "a_deg": a, "c_deg": c,
        "dx_um": true[:, 0], "dy_um": true[:, 1], "dz_um": true[:, 2]})
    return path, Pw, true


@pytest.fixture(scope="module")
def lab(tmp_path_factory):
    folder = tmp_path_factory.mktemp("lab")
    m, paths = lab_campaign(folder)
    data = [read_measurements(p) for p in paths]
    machine = load_machine("cafxyz")
    d = diagnose(machine, data)
    fit = identify(machine, data)
    check, Pw, true = _check_points(m, folder)
    out = {}
    for name, fm in (("diagnose", d.model), ("identify", fit.fitted_model)):
        cols = predict_readings(fm, read_measurements(check)).columns
        pred = np.column_stack([cols[f"pred_d{a}_um"] for a in "xyz"])
        sd = np.column_stack([cols[f"pred_d{a}_um_sd"] for a in "xyz"])
        out[name] = (pred - true, sd)
    return d, Pw, out


def _less_the_frame(Pw, e) -> np.ndarray:
    """``e`` (n, 3) less the best rigid motion of the check file's frame (a translation and a small
    turn w x p): its set-up, which predict takes as zero and says so."""
    n = len(Pw)
    A = np.zeros((3 * n, 6))
    for k in range(3):
        A[k::3, k] = 1.0
        unit = np.zeros(3)
        unit[k] = 1.0
        A[k::3, 3:] = -np.cross(Pw, unit)
    coef = np.linalg.lstsq(A, e.reshape(-1), rcond=None)[0]
    return (e.reshape(-1) - A @ coef).reshape(e.shape)


def test_the_truth_holds_the_lab_s_errors():
    """X at 300 mm approached from +, every other axis at 0: 30 um/m of scale and half the backlash
    (hand-derived), nothing across."""
    d = _deviation(_lab_machine(), [300.0, 0.0, 0.0, 0.0, 0.0], 1.0)[0] * 1e3
    np.testing.assert_allclose(d, [9.0 + 4.0, 0.0, 0.0], rtol=0, atol=1e-6)


def test_diagnose_s_model_predicts_unseen_poses_as_identify_s(lab):
    d, _, out = lab
    assert [(f.effect, f.axis) for f in d.findings] == [("backlash", "X")]
    rms = {k: float(np.sqrt(np.mean(e ** 2))) for k, (e, _) in out.items()}
    # identify 0.89 um; diagnose's model was 31.6 um off
    assert rms["diagnose"] <= 1.05 * rms["identify"] + 0.05, rms
    assert d.final["written"]["model"] == "penalised"


def test_its_standard_errors_say_how_far_off_it_is(lab):
    _, Pw, out = lab
    e, sd = out["diagnose"]
    # up to the check file's frame (its set-up, unknown to predict) the predictions are as good as
    # their standard errors say: 0.04 um rms against a median of 0.08 um (it was 24 um)
    rest = _less_the_frame(Pw, e)
    assert np.nanmedian(sd) < 0.5, np.nanmedian(sd)
    assert np.nanmean(np.abs(rest) > 2.0 * sd) < 0.05

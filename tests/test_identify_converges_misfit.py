"""`identify` converges in a few steps on a campaign with an effect its model lacks (a new user's
3-axis campaign: a 5 um X backlash, which only diagnose adds).

The model is linear in its parameters up to products of errors (1e-5 of the readings), so
Gauss-Newton converges in a few steps whatever the misfit. Its solver formed the penalty as a
square: at REML's weight at its bound (a straightness run with no curvature) the square's entries
were 1e14 with 1e-2 of round-off, a hundred times the data's curvature in the directions the penalty
does not see, and the steps crept: 40 iterations, not converged, and a warning.

Oracle: the independent truth machine (tests/truth): EXX = 15 um/m + 2 um sin(2 pi x / 25 mm) + a
5 um backlash, EYY = -6 um/m, EZZ = 10 um/m, pitch and yaw of Y; laser runs of X (also a fine
2.5 mm run), Y and Z, straightness of X and Z, pitch and yaw of Y, ball-bar circles in three
planes. The fitted Y positioning over the laser's stroke is the truth's -6 um/m, to the noise."""
from __future__ import annotations

import json

import numpy as np
import pytest

from mtcomp.cli import main
from mtcomp.identification.penalty import RHO_BOUND
from mtcomp.identification.predict import predict_readings
from mtcomp.measurement.files import read_measurements
from mtcomp.models import load_model
from truth import Backlash, TruthMachine
from truth import campaigns as tc
from truth import profiles as P

NOISE = 0.3
EYY_PER_MM = -6e-6          # mm of error per mm of travel: -6 um/m


def _campaign(folder, seed: int):
    rng = np.random.default_rng(seed)
    truth = TruthMachine.zero("xfyz").with_effects(Backlash("X", 5.0))
    truth.components["X"]["EXX"] = P.Sum((P.Linear(0.0, 15e-6), P.Sines((2e-3,), (25.0,), (0.0,))))
    truth.components["Y"]["EYY"] = P.Linear(0.0, EYY_PER_MM)
    truth.components["Z"]["EZZ"] = P.Linear(0.0, 10e-6)
    truth.components["Y"]["EAY"] = P.Linear(8e-6, 4e-8)
    truth.components["Y"]["ECY"] = P.Sines((10e-6,), (800.0,), (np.pi / 2,))
    runs = [tc.laser(truth, folder / f"laser_{a}.csv", rng, a, components=(f"E{a}{a}",), noise_um=NOISE)
            for a in "XYZ"]
    files = [r.path for r in runs]
    mid = 0.5 * sum(truth.travel["X"])
    files.append(tc.laser(truth, folder / "laser_x_fine.csv", rng, "X", components=("EXX",), noise_um=NOISE,
                          targets=np.arange(mid - 50.0, mid + 50.1, 2.5)).path)
    for name, axis, comps in (("straight_x", "X", ("EYX", "EZX")), ("straight_z", "Z", ("EXZ",)),
                              ("angular_y", "Y", ("EAY", "ECY"))):
        files.append(tc.laser(truth, folder / f"{name}.csv", rng, axis, components=comps, noise_um=NOISE,
                              noise_urad=NOISE, n_runs=2).path)
    files.append(tc.ballbar_circles(truth, folder / "ballbar.csv", rng).path)
    return truth, files, runs[1]


@pytest.mark.parametrize("seed", [1])
def test_a_campaign_with_a_backlash_the_model_lacks_converges_in_a_few_steps(tmp_path, capsys, seed):
    """Seed 1: the old solver took 40 iterations, not converged (and warned); now 6."""
    truth, files, laser_y = _campaign(tmp_path, seed)
    out = tmp_path / "m.json"
    assert main(["identify", "xfyz", *map(str, files), "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert "did not converge" not in err, err
    info = json.loads(out.read_text())["info"]["identify"]
    assert info["converged"] and info["iterations"] <= 8, info["iterations"]
    # this campaign no longer sends a weight to its bound (RHO_BOUND): with the turn of the machine
    # held by the convention (EYX's and EZX's slopes zero), REML's straightness weight stays at
    # e^19.2 to e^20.1 over seeds 1-6 (it was at e^30). The solver at the bound is tested by
    # test_identify_reml_bound; here: well inside the bound (seed 1: e^19.7)
    largest = max(np.log(v) for v in info["smoothing"]["weights"].values())
    assert largest < RHO_BOUND - 5.0, largest
    # and the fit is the truth's where the data are clean: Y positioning over the laser's stroke
    pred = predict_readings(load_model(out), read_measurements(laser_y.path)).columns["pred_value_um"]
    pred = np.asarray(pred, dtype=float)
    tg = np.asarray(laser_y.columns["target_mm"], dtype=float)
    stroke = pred[tg == tg.max()].mean() - pred[tg == tg.min()].mean()
    # the truth's noise-free reading: Y positioning and the Abbe arm of Y's pitch
    clean = tc.laser(truth, tmp_path / "clean_y.csv", np.random.default_rng(0), "Y", components=("EYY",),
                     noise_um=0.0, setup=False, n_runs=1).columns
    v, t = np.asarray(clean["value_um"], dtype=float), np.asarray(clean["target_mm"], dtype=float)
    tol = 4.0 * NOISE / np.sqrt(np.sum((tg - tg.mean()) ** 2)) * np.ptp(tg)
    np.testing.assert_allclose(stroke, v[t == t.max()].mean() - v[t == t.min()].mean(), rtol=0, atol=tol)


def test_a_fit_that_does_not_converge_says_what_did_not_settle(tmp_path, capsys, monkeypatch):
    """Gauss-Newton cut to one step on one clean positioning run of X (EXX = 15 um/m): the warning
    names the parameters the last step still moved, in their units and standard errors, and what a
    user can do. The old warning said only "check the data"."""
    from mtcomp.identification import fit

    gauss_newton = fit._Problem._gauss_newton
    monkeypatch.setattr(fit._Problem, "_gauss_newton",
                        lambda self, *a: gauss_newton(self, *a[:5], 1, *a[6:]))
    truth = TruthMachine.zero("xfyz")
    truth.components["X"]["EXX"] = P.Linear(0.0, 15e-6)
    run = tc.laser(truth, tmp_path / "laser_x.csv", np.random.default_rng(3), "X", components=("EXX",),
                   noise_um=NOISE)
    assert main(["identify", "xfyz", str(run.path), "-o", str(tmp_path / "m.json")]) == 0
    err = capsys.readouterr().err
    line = next(ln for ln in err.splitlines() if "did not converge" in ln)
    assert "its last step still moved EXX" in line and "standard errors" in line, line
    assert "mtcomp diagnose" in line and "--hold" in line, line

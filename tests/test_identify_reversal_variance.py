"""A reversal the base model does not hold is error it leaves, not noise: identify's posterior (and
REML's choice of smoothness) take it as one unpenalised nuisance term per target read from both
sides (mtcomp.identification.reversal.DirectionContrast).

Oracles: (1) a second formulation: the same runs with the reversal taken out of the readings by
hand give the same fitted values and the same covariance (with balanced runs the reversal is
orthogonal to everything a base model fits); (2) the truth the files were written with: the fitted
profile's departure from the true profile at the targets, over its standard error, has an rms near
1 (the old variance, which counted the reversal as noise, gave about 0.2)."""
import csv

import numpy as np
import pytest

from laser_files import write_x_positioning
from mtcomp.cli import main
from mtcomp.identification.fit import identify
from mtcomp.machine import load_machine
from mtcomp.measurement.files import read_measurements

TARGETS = tuple(range(-40, 41, 10))
NOISE_UM = 1.5


def _profile(t):
    return 12.0 * np.sin(t / 25.0) + 0.1 * t


def _half_reversal(t):
    return 0.5 * (-24.0 + 4.0 * np.cos(t / 7.0))


def _runs(tmp_path, name, with_reversal: bool, seed: int):
    half = _half_reversal if with_reversal else (lambda t: 0.0)
    return write_x_positioning(tmp_path / name, TARGETS, lambda t, d: _profile(t) + d * half(t),
                               5, NOISE_UM, np.random.default_rng(seed))


def test_the_reversal_taken_out_by_hand_gives_the_same_fit(tmp_path):
    machine = load_machine("xfyz")
    fits = [identify(machine, [read_measurements(_runs(tmp_path, f"{k}.csv", k == "with", seed=3))])
            for k in ("with", "without")]
    a, b = fits
    # the readings differ by +-half the reversal only; everything else (noise included) is the same
    # (to the tolerance of REML's search for the smoothness: 1e-5 of the values)
    np.testing.assert_allclose(a.values, b.values, rtol=0, atol=1e-4 * np.max(np.abs(b.values)))
    var = np.nanmax(np.diag(b.covariance))
    np.testing.assert_allclose(a.covariance, b.covariance, rtol=0, atol=1e-3 * var)


def _predicted(tmp_path, seed):
    data = _runs(tmp_path, f"runs{seed}.csv", True, seed)
    model = tmp_path / f"m{seed}.json"
    assert main(["identify", "xfyz", str(data), "-o", str(model)]) == 0
    out = tmp_path / f"p{seed}.csv"
    assert main(["predict", "xfyz", str(model), str(data), "-o", str(out)]) == 0
    rows = list(csv.DictReader(out.open()))
    first = {}
    for r in rows:                      # one row per target (the model is the same both ways)
        first.setdefault(float(r["target_mm"]), r)
    t = np.array(sorted(first))
    pred = np.array([float(first[k]["pred_value_um"]) for k in t])
    sd = np.array([float(first[k]["pred_value_um_sd"]) for k in t])
    return t, pred, sd


def test_standard_errors_match_the_truth_beside_a_reversal(tmp_path, capsys):
    z, sds = [], []
    for seed in (11, 12, 13, 14):
        t, pred, sd = _predicted(tmp_path, seed)
        capsys.readouterr()
        assert np.all(sd > 0)
        # a laser's zero is arbitrary: compare the profiles about their means over the targets
        truth = _profile(t)
        dep = (pred - pred.mean()) - (truth - truth.mean())
        z.append(dep / sd)
        sds.append(sd)
    # by hand: the mean of a target's 10 readings has standard error NOISE / sqrt(10) = 0.47 um; a
    # profile smoother than the targets has less. Counting the reversal (12 um half-size) as noise
    # made it 2.0 um
    of_a_mean = NOISE_UM / np.sqrt(10)
    assert 0.3 * of_a_mean < float(np.median(np.concatenate(sds))) < 1.3 * of_a_mean
    # and the standard errors say how far the fitted profile is from the truth: 36 departures of
    # 4 fits, rms(departure / sd) about 1
    rms = float(np.sqrt(np.mean(np.concatenate(z) ** 2)))
    assert 0.5 < rms < 1.7, rms

"""A penalised fit whose REML weight stands at its bound converges, and `identify` says nothing of
different machines: the penalty is evaluated as the squared norm of its factor, never below zero.

Oracle: the independent truth machine (tests/truth), EXX = 20 um/m and nothing else, one laser
positioning run of X (11 targets, 5 bidirectional runs, 0.2 um noise). A straight profile has no
curvature, so REML puts the positioning weight at its bound (e^30); the fitted X error over the
stroke is the truth's 20 um/m times the stroke, to the noise."""
from __future__ import annotations

import json

import numpy as np

from mtcomp.cli import main
from mtcomp.identification.predict import predict_readings
from mtcomp.measurement.files import read_measurements
from mtcomp.models import load_model
from mtcomp.identification.penalty import RHO_BOUND
from truth import TruthMachine
from truth import campaigns as tc
from truth import profiles as P

SLOPE_UM_PER_MM = 0.020
NOISE_UM = 0.2


def _laser_run(path, seed: int):
    """One positioning run of X on the truth machine with EXX = 20 um/m: (the run, its targets)."""
    truth = TruthMachine.zero("xfyz")
    truth.components["X"]["EXX"] = P.Linear(0.0, SLOPE_UM_PER_MM * 1e-3)
    run = tc.laser(truth, path, np.random.default_rng(seed), "X", components=("EXX",),
                   noise_um=NOISE_UM, n_targets=11)
    return run, np.unique(run.columns["target_mm"])


def test_a_clean_laser_run_at_the_weights_bound_converges_without_a_warning(tmp_path, capsys):
    """Seed 10: the old code evaluated the penalty as z^T S z, whose round-off (+-0.4 at a weight of
    e^30, against a residual sum of 4 um^2) kept Gauss-Newton from calling its step small: 20
    iterations, not converged, and `identify` warned "files of different machines fitted as one?"."""
    run, targets = _laser_run(tmp_path / "laser_x.csv", seed=10)
    out = tmp_path / "model.json"
    assert main(["identify", "xfyz", str(run.path), "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert "did not converge" not in err and "different machines" not in err, err
    info = json.loads(out.read_text())["info"]["identify"]
    assert info["converged"] and info["iterations"] < 10
    # the case this test is about: the weight at its bound
    assert np.log(info["smoothing"]["weights"]["positioning"]) >= RHO_BOUND - 1e-6
    # and the fit is the truth's: X error over the stroke, the laser's slope to its noise (the slope
    # of 110 readings of 0.2 um: 0.06 um over the stroke; four of those)
    pred = predict_readings(load_model(out), read_measurements(run.path)).columns["pred_value_um"]
    pred = np.asarray(pred, dtype=float)
    tg = np.asarray(run.columns["target_mm"], dtype=float)
    stroke = pred[tg == targets[-1]].mean() - pred[tg == targets[0]].mean()
    spread = np.sum((tg - tg.mean()) ** 2)
    tol = 4.0 * NOISE_UM / np.sqrt(spread) * np.ptp(targets)
    np.testing.assert_allclose(stroke, SLOPE_UM_PER_MM * np.ptp(targets), rtol=0, atol=tol)


def test_laser_runs_of_two_machines_fitted_as_one_are_told(tmp_path, capsys):
    """Two positioning runs of X from two truth machines with different errors (random profiles,
    seeds drawn from one generator): the fit of both leaves each run's means at its targets about
    1 um off where its repeats allow 0.06 um, and `identify` says the files do not agree. One
    machine's two runs (another set-up, the same errors) say nothing. The old code said nothing of
    either (it warned only when Gauss-Newton did not converge)."""
    rng = np.random.default_rng(0)
    a, b = TruthMachine.random("xfyz", rng), TruthMachine.random("xfyz", rng)
    runs = [tc.laser(m, tmp_path / f"{name}.csv", rng, "X", components=("EXX",), noise_um=NOISE_UM).path
            for m, name in ((a, "machine_a"), (b, "machine_b"), (a, "machine_a_again"))]
    for files, told in ((runs[:2], True), (runs[::2], False)):
        assert main(["identify", "xfyz", *map(str, files), "-o", str(tmp_path / "m.json")]) == 0
        err = capsys.readouterr().err
        assert ("the files do not agree" in err) == told, err
        if told:
            assert "machine_a" in err or "machine_b" in err


def test_reml_at_the_fit_restarts_from_its_grid_when_the_start_sent_it_to_the_bound(tmp_path, monkeypatch):
    """REML runs twice: on the problem linearised at the start, then at that fit, from the first
    round's weights. A start far from the fit (diagnose's model written starts its base terms at the
    base fit's start, every set-up at zero: 3e7 noise variances of misfit) sent the first round to the
    bound e^30, where the criterion is flat, and a second round started there stayed: profiles
    straight, the fit of the data lost (a rotary table's ball-bar campaign of tests/resolution_cases,
    pdge seed 2, did so before the penalty was a squared norm). The second round then starts from
    its grid. Here the first round is sent to the bound by hand (a laser run of a truth machine with
    curved profiles): the fit must be the one whose first round was left alone (the oracle: the
    same fit undisturbed); without the restart its weights stay at e^30 and its sum of squares is
    300 times as large."""
    import mtcomp.identification.penalty as penalty
    from mtcomp.identification.fit import RHO_SETTLED, identify
    from mtcomp.machine import load_machine
    rng = np.random.default_rng(0)
    run = tc.laser(TruthMachine.random("xfyz", rng), tmp_path / "laser_x.csv", rng, "X", n_targets=11)
    data = [read_measurements(run.path)]
    alone = identify(load_machine("xfyz"), data)
    assert max(alone.smoothing.rho.values()) < RHO_BOUND - 10       # the case: weights well inside
    reml, rounds = penalty.reml_weights, []

    def first_round_at_the_bound(*args, **kw):
        rho, edf = reml(*args, **kw)
        rounds.append(kw.get("start"))
        return (np.full(rho.shape, RHO_BOUND), edf) if len(rounds) == 1 else (rho, edf)

    monkeypatch.setattr(penalty, "reml_weights", first_round_at_the_bound)
    sent = identify(load_machine("xfyz"), data)
    # the first fit's second round from its grid (the run reads um and urad: a second fit, each
    # unit weighted by its own noise, runs its two rounds after these)
    assert len(rounds) >= 2 and rounds[1] is None
    for cls, rho in alone.smoothing.rho.items():
        assert abs(sent.smoothing.rho[cls] - rho) < RHO_SETTLED, (cls, sent.smoothing.rho, alone.smoothing.rho)
    np.testing.assert_allclose(sent.cost, alone.cost, rtol=1e-3, atol=0)

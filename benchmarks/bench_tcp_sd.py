"""Is compensate's standard error of a correction honest on a 5-axis TCP program? A Monte Carlo on
the independent truth machine (tests/truth, no code shared with mtcomp).

The campaign of ``independent_cases.clean_campaign`` (CAFXYZ, seed 11 by default: volumetric points,
laser runs of every axis, ball-bar circles, the three-sphere set-up of C), or with ``--campaign
tcp`` the 5-axis variant ``tcp_campaign``, is written ``--draws`` times: the same machine and poses,
the readings' noise drawn anew each time (draw 0 is the test's own). Each is identified (``mtcomp
identify``; the points file's first pass only, as tests/test_toolpaths_tcp.py does) and evaluated at
the moves of LinuxCNC's boat-xyzac M428 demo (tests/data/gcode_corpus), the part's datum its origin:
the correction compensate makes there is the model's tip deviation less that at the datum. Printed,
per tip component, over the blocks whose reported standard error is largest:

* ``sd``: compensate's standard error of the correction (the model's covariance, the combinations
  the fit held weakly included: ``correction_sd_um`` in BLOCKS.csv), its mean over the draws;
* ``sd no held``: the same without the held combinations' variance;
* ``spread``: the standard deviation of the correction over the draws (what noise moves);
* ``miss``: the rms over the draws of the correction less the truth's (the truth's tip deviation
  less its deviation at the datum): what a correction leaves.

An honest standard error has ``spread`` close to ``sd no held`` (the held values do not move with
the noise) and ``miss`` within about ``sd`` (the truth may lie off the held value by as much).
Then the share of the program's blocks whose reported standard error is over 5 um (compensate's
default limit), and of the components whose miss is within 1 and 2 of their ``sd``.

    PYTHONPATH=tests:. python benchmarks/bench_tcp_sd.py [--draws 12] [--seed 11] [--campaign clean|tcp]
"""
from __future__ import annotations

import argparse
import contextlib
import io
import tempfile
from pathlib import Path

import numpy as np

from mtcomp.cli import main
from mtcomp.models import evaluate, load_model
from mtcomp.planner import CompensationProblem, Planner, PlannerOptions


def _blocks(truth):
    """(q (n, 5), datum (1, 5)): the boat demo's move ends as the truth's axes, and its origin's."""
    from replay import replay
    from test_toolpaths_tcp import BOAT, _truth_axes
    moves = [m.end for m in replay(BOAT.read_bytes()).moves
             if all(m.end.get(k) is not None for k in "XYZAC")]
    return _truth_axes(truth, moves), _truth_axes(truth, [dict.fromkeys("XYZAC", 0.0)])


def _identify(paths, folder: Path):
    from test_toolpaths_tcp import _first_pass_only
    _first_pass_only(paths[0])
    model = folder / "model.json"
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        assert main(["identify", "cafxyz", *map(str, paths), "-o", str(model)]) == 0
    return load_model(model)


def _correction_and_sd(fitted, q, datum):
    """((n, 3) um the correction, (n, 3) um its standard error, (n, 3) um the same without the held
    combinations' variance), by compensate's own evaluator."""
    planner = Planner(CompensationProblem.from_machine(fitted), PlannerOptions(threads=1))
    ev, n = planner.ev, q.shape[0]
    ctx = planner._context(np.full(n, np.nan), np.zeros((n, q.shape[1])), n)
    d = np.repeat(datum, n, axis=0)
    J = evaluate(ev.model, "tip_pjacobian_function", q, ev.p, ctx)[0]
    J = J - ev._at_datum("tip_pjacobian_function", d, ctx)
    sd = fitted.tip_sd_um(J, fitted.covariance_factor(held=True), components=True)
    sd0 = fitted.tip_sd_um(J, fitted.covariance_factor(held=False), components=True)
    corr = (ev._deviation(q, ctx)[:, :3] - ev._at_datum("deviation_function", d, ctx)[:, :3]) * 1e3
    status_sd = planner.block_status(q, np.ones(q.shape, bool), np.full(n, np.nan), np.zeros(q.shape),
                                     datum=d)[2]
    assert np.allclose(status_sd, sd.max(axis=1), rtol=1e-6, atol=1e-9)   # what compensate gates
    return corr, sd, sd0


def _truth_correction(truth, q, datum):
    err = truth.true_pose(q)[0] - truth.nominal_pose(q)[0]
    return (err - (truth.true_pose(datum)[0] - truth.nominal_pose(datum)[0])) * 1e3


def run(draws: int, seed: int, campaign: str, worst: int) -> None:
    import independent_cases as ic
    make = ic.clean_campaign if campaign == "clean" else ic.tcp_campaign
    corr, sd, sd0, held = [], [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        for d in range(draws):
            folder = Path(tmp) / f"draw{d}"
            truth, paths = make("CAFXYZ", seed, folder, noise_seed=None if d == 0 else 1000 + d)
            fitted = _identify(paths, folder)
            if d == 0:
                q, datum = _blocks(truth)
                true = _truth_correction(truth, q, datum)
            c, s, s0 = _correction_and_sd(fitted, q, datum)
            corr.append(c), sd.append(s), sd0.append(s0)
            held.append(np.asarray((fitted.uncertainty or {}).get("held_sd_um", []), float))
            print(f"draw {d}: held combinations' sd (um) {np.round(np.sort(held[-1]), 2).tolist()}; "
                  f"blocks over 5 um {int(np.sum(s.max(axis=1) > 5.0))} of {q.shape[0]}", flush=True)
    corr, sd, sd0 = map(np.array, (corr, sd, sd0))        # (draws, n, 3)
    spread = corr.std(axis=0, ddof=1)
    miss = np.sqrt(np.mean((corr - true[None]) ** 2, axis=0))
    msd, msd0 = sd.mean(axis=0), sd0.mean(axis=0)
    order = np.argsort(-msd.max(axis=1))[:worst]
    print(f"\n{campaign} campaign, seed {seed}, {draws} draws, {q.shape[0]} blocks; "
          f"the {worst} blocks of largest sd (um; x y z):")
    print(" block | sd               | sd no held       | spread           | miss")
    f = lambda v: " ".join(f"{x:5.2f}" for x in v)   # noqa: E731
    for i in order:
        print(f" {i:5d} | {f(msd[i])} | {f(msd0[i])} | {f(spread[i])} | {f(miss[i])}")
    print(f"over the program: sd median {np.median(msd):.2f}, max {msd.max():.2f} um; "
          f"sd no held median {np.median(msd0):.2f}, max {msd0.max():.2f}; spread median "
          f"{np.median(spread):.2f}, max {spread.max():.2f}; miss median {np.median(miss):.2f}, "
          f"max {miss.max():.2f}")
    print(f"spread / sd-no-held median {np.median(spread / msd0):.2f}; "
          f"miss / sd median {np.median(miss / msd):.2f}, max {np.max(miss / msd):.2f}")
    i, k = np.unravel_index(np.argmax(miss / msd), msd.shape)
    print(f"largest miss / sd: block {i} ({'xyz'[k]}; A {np.degrees(q[i, 3]):.1f} C "
          f"{np.degrees(q[i, 4]):.1f} deg): miss {miss[i, k]:.2f} um, sd {msd[i, k]:.3f} um")
    z = np.abs(corr - true[None]) / sd
    print(f"blocks over 5 um per draw: {np.mean(np.sum(sd.max(axis=2) > 5.0, axis=1)):.0f} of "
          f"{q.shape[0]} (mean); components with |miss| within 1 sd {np.mean(z <= 1):.0%}, "
          f"within 2 sd {np.mean(z <= 2):.0%}")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=12)
    ap.add_argument("--seed", type=int, default=11)
    ap.add_argument("--campaign", choices=("clean", "tcp"), default="clean")
    ap.add_argument("--worst", type=int, default=8)
    a = ap.parse_args()
    run(a.draws, a.seed, a.campaign, a.worst)

"""Are identify's standard errors under ``--weights noise`` honest on a 5-axis trunnion whose files'
noise differs fivefold? A Monte Carlo over the readings' noise.

The campaign of ``tests/trunnion_case.py`` (a plain numpy truth sharing no code with mtcomp: laser
positioning runs of X, Y, Z, two R-test balls with B approached both ways and a B backlash no base
model has, a ball-bar circle) is written ``--draws`` times, the truth fixed and only the noise drawn
anew (seed 42 is the new user's files). Each is identified with ``weights="noise"``. Printed for the
squarenesses (urad): the mean reported standard error, the spread of the values over the draws, the
rms miss from the truth, and their ratios; then the least eigenvalue of each written correlation
matrix (a covariance that is positive semi-definite has none below zero but for round-off).

    PYTHONPATH=tests:. python benchmarks/bench_noise_weights_mc.py [--draws 8] [--first-seed 42]
"""
from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from mtcomp.identification.fit import identify
from mtcomp.machine import load_machine
from mtcomp.measurement.files import read_measurements
from trunnion_case import TRUTH_URAD, trunnion_campaign

NAMES = ("C0Y", "B0Z", "A0Z")


def _one(seed: int, folder: Path):
    toml, paths = trunnion_campaign(folder, seed)
    fit = identify(load_machine(str(toml)), [read_measurements(p) for p in paths], weights="noise")
    names = [s.name for s in fit.specs]
    idx = [names.index(n) for n in NAMES]
    C = fit.covariance
    sd = np.sqrt(np.clip(np.diag(C), 0.0, None))
    ok = np.isfinite(sd) & (sd > 0)
    corr = C[np.ix_(ok, ok)] / np.outer(sd[ok], sd[ok])
    return fit.values[idx] * 1e6, fit.std_errors[idx] * 1e6, float(np.linalg.eigvalsh(corr).min())


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=8)
    ap.add_argument("--first-seed", type=int, default=42)
    args = ap.parse_args()
    values, sds, least = [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(args.draws):
            (Path(tmp) / str(k)).mkdir()
            v, s, e = _one(args.first_seed + k, Path(tmp) / str(k))
            values.append(v), sds.append(s), least.append(e)
            print(f"draw {k}: " + ", ".join(f"{n} {a:.2f} +- {b:.2f}" for n, a, b in zip(NAMES, v, s))
                  + f"; correlation's least eigenvalue {e:.1e}", flush=True)
    values, sds = np.array(values), np.array(sds)
    truth = np.array([TRUTH_URAD[n] for n in NAMES])
    print("urad        sd (mean)  spread  miss (rms)  spread/sd  miss/sd")
    for j, n in enumerate(NAMES):
        sd, spread = sds[:, j].mean(), values[:, j].std(ddof=1)
        miss = np.sqrt(np.mean((values[:, j] - truth[j]) ** 2))
        print(f"{n:10s} {sd:10.2f} {spread:7.2f} {miss:11.2f} {spread / sd:10.2f} {miss / sd:8.2f}")
    print(f"least eigenvalue of the correlation matrices: {min(least):.1e}")


if __name__ == "__main__":
    main()

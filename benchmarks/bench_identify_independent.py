"""Identification on machines built independently of mtcomp (tests/truth): held-out error vs noise.

For each topology, N random machines (seeds 0..N-1) get a clean, rich campaign (volumetric points at
two tool lengths in two passes, five laser runs of every axis, ball-bar circles, the three-sphere
set-up with a C axis; tests/independent_cases.py); identify fits every file without its last run and
predicts that run. Printed per topology: the held-out rms over the noise (um readings and urad
readings), median and worst, how many machines are within 1.1 times the noise, and the held-out rms
over all the machines (each machine weighted alike). A model as fine
as the laser's targets leaves sqrt(1 + 1/8) = 1.06 times the noise on a held-out run of five, however
right it is (each target is fitted from 8 readings); so does the pitch table from the same runs
(the mean of the training runs per target and direction), whose held-out rms is printed beside
ours for the angular readings.

``--smoothing N``: would a smoother model do better on the angular readings? On N machines per
topology, each angular laser component alone: the held-out run predicted by the mean of the training
runs per target (one value per target, as fine as the targets) and by a cubic smoothing spline
through those means whose roughness penalty is chosen by leave-one-run-out cross-validation among
the training runs (scipy's make_smoothing_spline; no smoothing is among the choices). Printed: the
held-out rms over the noise of both, median and max, and how many machines each has within 1.1.

``--seed003 N``: seed 003 through the generic path on N independent CAFXYZ machines (identify on the
three-sphere ball-bar file, error motions of A and C in the machine file, the calibrated bar known,
the linear axes held), then the C-axis points against the truth: mean and max distance (um), and the
paper's 0.3 / 0.78 um beside them.

    PYTHONPATH=tests python benchmarks/bench_identify_independent.py [--machines 50] [--topologies XFYZ CAFXYZ CBFXYZ]
    PYTHONPATH=tests python benchmarks/bench_identify_independent.py --machines 0 --seed003 20

(The independent machine is test code: it lives in tests/, not in the mtcomp package, so tests/ goes
on PYTHONPATH, as for bench_diagnose.py.)
"""
from __future__ import annotations

import argparse
import math
import statistics
import tempfile
import time
from pathlib import Path

try:
    from independent_cases import (SEED003_HOLD, clean_campaign, heldout_by_run, seed003_case,
                                   seed003_errors_um)
except ImportError:
    raise SystemExit("bench_identify_independent: run it with tests/ on PYTHONPATH "
                     "(PYTHONPATH=tests python benchmarks/bench_identify_independent.py)") from None


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--machines", type=int, default=50)
    ap.add_argument("--topologies", nargs="+", default=["XFYZ", "CAFXYZ", "CBFXYZ"])
    ap.add_argument("--seed003", type=int, default=0, metavar="N")
    ap.add_argument("--smoothing", type=int, default=0, metavar="N")
    args = ap.parse_args()
    if args.seed003:
        seed003(args.seed003)
    if args.smoothing:
        for topo in args.topologies:
            smoothing(topo, args.smoothing)
    if args.machines > 0:
        print(f"{'topology':<8} {'n':>3} {'um med':>7} {'um max':>7} {'urad med':>8} {'urad max':>8} "
              f"{'<=1.1x':>7} {'s/fit':>6}")
    for topo in (args.topologies if args.machines > 0 else []):
        ratios_um, ratios_urad, vs_pitch, secs = [], [], [], []
        for seed in range(args.machines):
            with tempfile.TemporaryDirectory() as tmp:
                _, paths = clean_campaign(topo, seed, Path(tmp))
                t0 = time.perf_counter()
                h = heldout_by_run(topo, paths)
                secs.append(time.perf_counter() - t0)
            ratios_um.append(h.ratio_um)
            ratios_urad.append(h.ratio_urad)
            vs_pitch.append(h.rms_urad / h.pitch_urad)
            print(f"  {topo} seed {seed}: {h.ratio_um:.3f} x noise (um), {h.ratio_urad:.3f} x (urad; "
                  f"{vs_pitch[-1]:.3f} x the pitch table's), {secs[-1]:.1f} s", flush=True)
        within = sum(max(a, b) <= 1.1 for a, b in zip(ratios_um, ratios_urad))
        # the held-out rms over all machines (each machine's mean square weighted alike)
        pooled = [math.sqrt(statistics.fmean(r * r for r in x)) for x in (ratios_um, ratios_urad)]
        print(f"{topo:<8} {len(ratios_um):>3} {statistics.median(ratios_um):7.3f} {max(ratios_um):7.3f} "
              f"{statistics.median(ratios_urad):8.3f} {max(ratios_urad):8.3f} "
              f"{within:>3}/{len(ratios_um):<3} {statistics.median(secs):6.1f}   urad vs pitch table: "
              f"median {statistics.median(vs_pitch):.3f}, max {max(vs_pitch):.3f}; over all "
              f"{len(ratios_um)} machines: {pooled[0]:.3f} x noise (um), {pooled[1]:.3f} x (urad)",
              flush=True)
    return 0


def seed003(n: int) -> None:
    from mtcomp.identification.fit import identify
    from mtcomp.machine import load_machine
    from mtcomp.measurement.files import read_measurements
    means, maxes = [], []
    for seed in range(n):
        with tempfile.TemporaryDirectory() as tmp:
            truth, path, toml = seed003_case(seed, Path(tmp))
            res = identify(load_machine(str(toml)), [read_measurements(path)], known_setup=[str(path)],
                           hold=SEED003_HOLD)
        d = seed003_errors_um(res.fitted_model, truth)
        means.append(d.mean())
        maxes.append(d.max())
        print(f"  seed 003, machine {seed}: mean {d.mean():.3f} um, max {d.max():.3f} um", flush=True)
    print(f"seed 003 over {n} machines: mean of means {statistics.mean(means):.3f} um (worst "
          f"{max(means):.3f}), worst max {max(maxes):.3f} um; paper 0.3 / 0.78 um", flush=True)


def smoothing(topology: str, n: int) -> None:
    import numpy as np
    from scipy.interpolate import make_smoothing_spline

    from independent_cases import NOISE_URAD
    from mtcomp.measurement.files import read_measurements

    def fit(t, v, lam):
        """(targets, prediction function) from readings v at targets t of the given runs."""
        tt = np.unique(t)
        means = np.array([v[t == x].mean() for x in tt])
        if lam is None:
            return lambda s: np.interp(s, tt, means)
        return make_smoothing_spline(tt, means, lam=lam * (tt[-1] - tt[0]) ** 3)

    table, smooth = [], []
    for seed in range(n):
        res_t, res_s = [], []
        with tempfile.TemporaryDirectory() as tmp:
            _, paths = clean_campaign(topology, seed, Path(tmp))
            for p in paths:
                d = read_measurements(p)
                if d.kind != "laser":
                    continue
                run = d.context.run
                for comp in np.unique(d.component[d.angular]):
                    sel = (d.component == comp) & d.angular
                    t, v, r = d.target[sel], d.value[sel] * 1e6, run[sel]
                    train, test = r != r.max(), r == r.max()
                    best = None
                    for lam in [None] + list(10.0 ** np.arange(-12.0, -1.0)):
                        cv = 0.0
                        for k in np.unique(r[train]):
                            a, b = train & (r != k), train & (r == k)
                            cv += float(np.sum((v[b] - fit(t[a], v[a], lam)(t[b])) ** 2))
                        if best is None or cv < best[0]:
                            best = (cv, lam)
                    res_t.append(v[test] - fit(t[train], v[train], None)(t[test]))
                    res_s.append(v[test] - fit(t[train], v[train], best[1])(t[test]))
        table.append(float(np.sqrt(np.mean(np.concatenate(res_t) ** 2))) / NOISE_URAD)
        smooth.append(float(np.sqrt(np.mean(np.concatenate(res_s) ** 2))) / NOISE_URAD)
    for name, x in (("per-target mean", table), ("CV smoothing spline", smooth)):
        print(f"{topology} angular readings, {name:<20}: held-out / noise median {statistics.median(x):.3f}, "
              f"max {max(x):.3f}, within 1.1 on {sum(v <= 1.1 for v in x)}/{len(x)}", flush=True)


if __name__ == "__main__":
    raise SystemExit(main())

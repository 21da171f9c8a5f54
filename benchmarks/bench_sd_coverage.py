"""Are predict's standard errors honest? Coverage of 1 and 2 sd on held-out laser runs.

Every laser file is fitted without its last run (identify, ``--weights``: unit by default) and that
run is predicted (``predict_readings``: the same file, so with its fitted set-up). Per held-out
reading and unit (um, urad), the share within 1 sd and within 2 sd (68 % and 95 % for a calibrated
Gaussian) of three comparisons:

* ``truth``: the independent machine's noise-free reading of that run (its ideal reading plus the
  file's set-up, tests/truth) against the prediction's ``pred_*_sd``: what that standard error
  claims to cover;
* ``reading sd``: the noisy reading against ``pred_*_sd`` alone (which leaves out the reading's own
  noise);
* ``reading +noise``: the noisy reading against ``sqrt(sd^2 + s^2)``, s the fit's rms residual of
  that file's readings of the same unit (``FitResult.rms``, not corrected for the degrees of
  freedom the fit spends, so a little below the noise).

Campaigns on the independent machine (tests/truth, which shares no code with the model), random
xfyz machines, seeds ``--seeds``: ``laser`` (five bidirectional ISO 230-2 runs of X, Y and Z, all six
components, an optic offset, the other axes at random fixed positions, 0.2 um / 0.3 urad noise),
``rich`` (the same runs beside a volumetric points grid at two tool lengths and ball-bar circles).
Printed: each seed's coverage, then the median and range over the seeds. ``--real``: the real ISO
230-2 runs (MTCOMP_REAL_DATA/iso230_2): each run of a file held out in turn and predicted from the
others; readings only (no truth).

    PYTHONPATH=tests python benchmarks/bench_sd_coverage.py [--seeds 0 1 2 3 4] [--campaigns laser rich] [--weights noise]
    MTCOMP_REAL_DATA=... PYTHONPATH=tests python benchmarks/bench_sd_coverage.py --campaigns --real
"""
from __future__ import annotations

import argparse
import os
import statistics
import tempfile
from pathlib import Path

import numpy as np

try:
    import truth.campaigns as tc
    from truth.machine import TruthMachine
except ImportError:
    raise SystemExit("bench_sd_coverage: run it with tests/ on PYTHONPATH "
                     "(PYTHONPATH=tests python benchmarks/bench_sd_coverage.py)") from None

from mtcomp.identification.fit import identify
from mtcomp.identification.predict import predict_readings
from mtcomp.machine import load_machine
from mtcomp.measurement.files import read_measurements

NOISE_UM, NOISE_URAD = 0.2, 0.3


def _laser_truth(res: tc.CampaignResult) -> np.ndarray:
    """(n,) the noise-free reading of each row, file units: ideal + the component's set-up."""
    comp = np.array(res.columns["component"])
    tg = np.asarray(res.columns["target_mm"], float)
    ideal = np.where(np.isnan(res.ideal["value_um"]), res.ideal["value_urad"], res.ideal["value_um"])
    out = ideal.copy()
    for c, off in res.setup["offset"].items():
        sel = comp == c
        out[sel] += off + res.setup["slope_urad"][c] * tg[sel] / 1000.0
    return out


def campaign(kind: str, seed: int, folder: Path):
    """(paths, {path: noise-free readings}) of a campaign on a random xfyz machine."""
    rng = np.random.default_rng(seed)
    m = TruthMachine.random("xfyz", rng, error_motions=False)
    paths, truth = [], {}
    for a in "XYZ":
        static = {b: rng.uniform(*m.travel[b]) * 0.5 for b in "XYZ" if b != a}
        res = tc.laser(m, folder / f"laser_{a.lower()}.csv", rng, a, n_runs=5, static=static,
                       optic_mm=tuple(rng.uniform(-150, 150, 3)), noise_um=NOISE_UM, noise_urad=NOISE_URAD)
        paths.append(res.path)
        truth[str(res.path)] = _laser_truth(res)
    if kind == "rich":
        paths.append(tc.points(m, folder / "points.csv", rng, repeats=2, noise_um=NOISE_UM).path)
        paths.append(tc.ballbar_circles(m, folder / "ballbar.csv", rng, noise_mm=NOISE_UM * 1e-3).path)
    return paths, truth


def _noise_sd(result, tag: str, angular: bool) -> float:
    """The fit's residual sd of a file's readings of one unit (identify's per-file rms, um or urad)."""
    return float(result.rms()[tag].get("value_urad" if angular else "value_um", np.nan))


def heldout(paths, truth=None, weights="unit") -> dict:
    """{comparison unit: z}: every laser file fitted without its last run, that run predicted
    (identify's ``weights``: --weights)."""
    data = [read_measurements(p) for p in paths]
    train, test = [], []
    for d in data:
        if d.kind == "laser" and np.unique(d.context.run).size >= 2:
            last = d.context.run == d.context.run.max()
            train.append(d.subset(~last))
            test.append((d, last))
        else:
            train.append(d)
    res = identify(load_machine("xfyz"), train, weights=weights)
    z: dict = {}
    for d, last in test:
        t = None if truth is None else truth[str(d.path)][last]
        for k, v in _z(res, d.subset(last), t).items():
            z.setdefault(k, []).append(v)
    return {k: np.concatenate(v) for k, v in sorted(z.items())}


def _z(res, held, truth=None) -> dict:
    """{comparison unit: (k,) error over its standard error} of the readings of ``held`` (a run of a
    file the fit ``res`` saw, so predicted with its fitted set-up); ``truth``: their noise-free
    values (file units), None for real data."""
    pred = predict_readings(res.fitted_model, held)
    ang = held.angular
    value = np.where(ang, held.value * 1e6, held.value * 1e3)
    p = np.where(ang, pred.columns.get("pred_value_urad", np.nan), pred.columns.get("pred_value_um", np.nan))
    sd = np.where(ang, pred.columns.get("pred_value_urad_sd", np.nan),
                  pred.columns.get("pred_value_um_sd", np.nan))
    tag = Path(held.path).stem
    s = np.where(ang, _noise_sd(res, tag, True), _noise_sd(res, tag, False))
    ok = np.isfinite(p) & np.isfinite(sd) & (sd > 0)
    out = {}
    for unit, u in (("um", ~ang), ("urad", ang)):
        k = ok & u
        if not k.any():
            continue
        if truth is not None:
            out[f"truth {unit}"] = ((truth - p) / sd)[k]
        out[f"reading sd {unit}"] = ((value - p) / sd)[k]
        out[f"reading +noise {unit}"] = ((value - p) / np.hypot(sd, s))[k]
    return out


def _cover(zs) -> tuple[float, float]:
    a = np.abs(zs)
    return float(np.mean(a <= 1.0)), float(np.mean(a <= 2.0))


def _summary(name, per_seed: list[dict]) -> None:
    for comp in per_seed[0]:
        c1 = [_cover(z[comp])[0] for z in per_seed]
        c2 = [_cover(z[comp])[1] for z in per_seed]
        print(f"  {name:6s} {comp:15s} 1 sd {100 * statistics.median(c1):5.1f} % "
              f"({100 * min(c1):.0f}-{100 * max(c1):.0f}), 2 sd {100 * statistics.median(c2):5.1f} % "
              f"({100 * min(c2):.0f}-{100 * max(c2):.0f})   [median (range) over {len(per_seed)} seeds; "
              f"expected 68 / 95 %]")


def real(weights="unit") -> None:
    root = Path(os.environ.get("MTCOMP_REAL_DATA", ""))
    files = sorted(root.glob("iso230_2/*.csv"))
    if not files:
        print("real: MTCOMP_REAL_DATA has no laser runs")
        return
    for f in files:
        d = read_measurements(f)
        if d.kind != "laser" or np.unique(d.context.run).size < 3:
            continue
        per_run = [_heldout_run(d, r, weights) for r in np.unique(d.context.run)]
        z = {k: np.concatenate([p[k] for p in per_run if k in p]) for k in per_run[0]}
        for comp, v in z.items():
            c1, c2 = _cover(v)
            print(f"  real {f.name:24s} {comp:15s} 1 sd {100 * c1:5.1f} %, 2 sd {100 * c2:5.1f} %  "
                  f"({v.size} readings, each run held out in turn)")


def _heldout_run(d, r, weights) -> dict:
    """z of the readings of run r of a real laser file fitted on its other runs."""
    sel = d.context.run == r
    return _z(identify(load_machine("xfyz"), [d.subset(~sel)], weights=weights), d.subset(sel))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2, 3, 4])
    ap.add_argument("--campaigns", nargs="*", default=["laser", "rich"])
    ap.add_argument("--real", action="store_true")
    ap.add_argument("--weights", choices=("unit", "noise"), default="unit")
    args = ap.parse_args()
    for kind in args.campaigns:
        per_seed = []
        for seed in args.seeds:
            with tempfile.TemporaryDirectory() as tmp:
                paths, truth = campaign(kind, seed, Path(tmp))
                z = heldout(paths, truth, args.weights)
            per_seed.append(z)
            print(f"{kind} seed {seed}: " + ", ".join(
                f"{k} {100 * _cover(v)[0]:.0f}/{100 * _cover(v)[1]:.0f} %" for k, v in z.items()), flush=True)
        _summary(kind, per_seed)
    if args.real:
        real(args.weights)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

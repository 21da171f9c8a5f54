"""Benchmark: thermal drift predicted forward in time on the real spindle record (fl_thermal.csv).

The record (11,115 readings every 15 s, 46 h, 5 displacement channels, 16 temperatures, spindle 4 h
on / 4 h off) is split in time: the first part to fit, the rest to judge. For each split (60/40,
40/60, 80/20) the table gives the rms prediction error over the five channels, per channel about the
judged segment's mean (a file's zero belongs to its set-up) and absolute, of

* raw: no model (the drift itself),
* least squares: each channel on all 16 temperatures and an intercept,
* ridge: the same with a penalty on the standardised coefficients chosen by forward-chaining
  validation inside the fitted part (6 blocks in time, each of the last 5 predicted from the ones
  before it), penalties 1e-6 .. 1e2 per reading,
* mtcomp: `mtcomp diagnose xfyz TRAIN.csv --json R.json -o MODEL.json`, then
  `mtcomp predict xfyz MODEL.json TEST.csv -o PRED.csv`, run as commands on split files written to a
  temporary folder (the path a user takes).

A second table sets mtcomp's standard errors (`pred_<column>_sd`) against its errors on the judged
part: the rms error, the median standard error, their ratio, the rms of error / standard error over
every reading and channel (about 1 when the standard errors are honest) and the share of readings
within 2 standard errors; then the share of judged rows with a temperature or the spindle speed
beyond the fitted part's range (what `mtcomp predict` notes), and the last two figures on the rows
inside that range and on those beyond it.

The three baselines are computed here with plain numpy, independently of mtcomp's code.

With ``--truth N`` it also hides a drift (driven by a temperature, by spindle heat, settling or
steady in time, or none) in N 16 h records of the independent truth machine (tests/truth; run with
``PYTHONPATH=tests``), diagnoses the first 10 h and predicts the last 6 h, and prints how often the
driver is named right, the prediction rms over the noise of a reading, and the rms of error / standard
error with the share of readings within 2 standard errors.

    python benchmarks/bench_thermal.py [--data PATH/fl_thermal.csv]
    PYTHONPATH=tests python benchmarks/bench_thermal.py --truth 20
"""
from __future__ import annotations

import argparse
import csv
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

#: the real record is in the repository (tests/data/real/thermal, MIT licence; SOURCES.md there)
DEFAULT = Path(__file__).resolve().parents[1] / "tests" / "data" / "real" / "thermal" / "fl_thermal.csv"
SPLITS = (0.6, 0.4, 0.8)


def read_columns(path) -> dict:
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    head, body = rows[0], rows[1:]
    return {name: np.array([float(r[i]) if r[i] != "" else np.nan for r in body]) for i, name in enumerate(head)}


def scores(pred: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """(about the mean, absolute) rms over channels of pred - y (n, m), um."""
    about = ((pred - pred.mean(axis=0)) - (y - y.mean(axis=0)))
    return float(np.sqrt(np.mean(about ** 2))), float(np.sqrt(np.mean((pred - y) ** 2)))


def ridge(X, Y, lam):
    mx, my, sx = X.mean(0), Y.mean(0), X.std(0)
    sx[sx == 0] = 1.0
    Xs = (X - mx) / sx
    B = np.linalg.solve(Xs.T @ Xs + lam * len(X) * np.eye(X.shape[1]), Xs.T @ (Y - my))
    return lambda Xn: my + ((Xn - mx) / sx) @ B


def forward_ridge(X, Y, lams=np.logspace(-6, 2, 17), folds=5):
    edges = np.linspace(0, len(X), folds + 2).astype(int)
    errs = []
    for lam in lams:
        e = 0.0
        for k in range(1, folds + 1):
            f = ridge(X[:edges[k]], Y[:edges[k]], lam)
            e += np.sum((f(X[edges[k]:edges[k + 1]]) - Y[edges[k]:edges[k + 1]]) ** 2)
        errs.append(e)
    return ridge(X, Y, lams[int(np.argmin(errs))])


def mtcomp_prediction(header, rows, s, tmp: Path, chans) -> tuple[np.ndarray, np.ndarray, float]:
    """(predictions (n, m) um, their standard errors (n, m) um, seconds) of the readings after row s,
    by `mtcomp diagnose` on the readings before it and `mtcomp predict`."""
    train, test = tmp / f"train_{s}.csv", tmp / f"test_{s}.csv"
    for path, part in ((train, rows[:s]), (test, rows[s:])):
        path.write_text("\n".join([header] + part) + "\n")
    t0 = time.perf_counter()
    for cmd in (["diagnose", "xfyz", str(train), "--json", str(tmp / "r.json"), "-o", str(tmp / "m.json"),
                 "-q"],
                ["predict", "xfyz", str(tmp / "m.json"), str(test), "-o", str(tmp / "p.csv")]):
        subprocess.run([sys.executable, "-m", "mtcomp"] + cmd, check=True, stdout=subprocess.DEVNULL)
    seconds = time.perf_counter() - t0
    p = read_columns(tmp / "p.csv")
    return (np.column_stack([p["pred_" + k] for k in chans]),
            np.column_stack([p["pred_" + k + "_sd"] for k in chans]), seconds)


def sd_columns(pred: np.ndarray, sd: np.ndarray, y: np.ndarray, beyond: np.ndarray) -> str:
    """The standard errors against the errors (absolute, every channel and reading): rms error, median
    sd, their ratio, the rms of error / sd and the share of readings within 2 sd; then the last two
    for the rows inside the fitted part's range of every temperature and spindle speed and for the
    rows beyond it (``beyond`` (n,) bool)."""
    err = pred - y
    z = err / sd
    rms = float(np.sqrt(np.mean(err ** 2)))
    parts = [f"{rms:9.2f} {np.median(sd):9.2f} {rms / np.median(sd):7.2f} {np.sqrt(np.mean(z ** 2)):7.2f} "
             f"{np.mean(np.abs(z) <= 2.0):9.1%}"]
    for rows in (~beyond, beyond):
        zz = z[rows]
        parts.append(f"{np.sqrt(np.mean(zz ** 2)):7.2f} {np.mean(np.abs(zz) <= 2.0):9.1%}" if zz.size
                     else f"{'-':>7s} {'-':>9s}")
    return f"{parts[0]}  {np.mean(beyond):7.0%} {parts[1]} {parts[2]}"


def beyond_range(fit: np.ndarray, judged: np.ndarray) -> np.ndarray:
    """(n,) rows of ``judged`` (n, k) with a column outside the lowest and highest of ``fit`` (m, k)."""
    return np.any((judged < fit.min(axis=0)) | (judged > fit.max(axis=0)), axis=1)


def truth_sweep(n_seeds: int) -> None:
    """Hidden drifts on the truth machine (module docstring)."""
    from truth import SpindleSchedule, TruthMachine, campaigns, random_effect

    from mtcomp.thermal import diagnose_thermal
    from mtcomp.machine import load_machine
    from mtcomp.measurement.files import read_measurements
    from mtcomp.identification.predict import predict_readings
    noise = 0.1
    schedule = SpindleSchedule(((0.0, 0.0), (1800.0, 2000.0), (5400.0, 6000.0), (12600.0, 0.0),
                                (16200.0, 4000.0), (21600.0, 0.0), (43200.0, 5000.0), (50400.0, 0.0)))
    machine = load_machine("xfyz")
    print(f"truth machine, {n_seeds} records per driver: driver named right, later 6 h rms / noise")
    for driver, named in (("temperature", "temperature"), ("spindle", "spindle"), ("time", "time"),
                          ("linear", "time"), (None, None)):
        right, ratios, z = 0, [], []
        for seed in range(n_seeds):
            rng = np.random.default_rng(1000 + seed)
            effects = () if driver is None else (random_effect(
                "thermal_drift", TruthMachine("xfyz"), rng, driver=driver, schedule=schedule),)
            with tempfile.TemporaryDirectory(prefix="bench-thermal-") as tmp:
                tmp = Path(tmp)
                cols = campaigns.thermal(TruthMachine.random("xfyz", rng, effects=effects), tmp / "r.csv",
                                         rng, duration_h=16.0, interval_s=60.0, schedule=schedule,
                                         noise_um=noise).columns
                lines = (tmp / "r.csv").read_text().splitlines()
                s = int(np.searchsorted(cols["t_s"], 36000.0))
                (tmp / "f.csv").write_text("\n".join(lines[:1 + s]) + "\n")
                (tmp / "v.csv").write_text("\n".join([lines[0]] + lines[1 + s:]) + "\n")
                d = diagnose_thermal(machine, read_measurements(tmp / "f.csv"))
                val = read_measurements(tmp / "v.csv")
            right += [f.params["driver"] for f in d.findings if f.effect == "thermal_drift"] == \
                ([named] if named else [])
            pred = predict_readings(d.model, val).columns
            err = np.concatenate([pred[f"pred_disp_{c}_um"] - val.channels[c] * 1e3 for c in "xyz"])
            ratios.append(float(np.sqrt(np.mean(err ** 2))) / noise)
            if driver is not None:
                z.append(err / np.concatenate([pred[f"pred_disp_{c}_um_sd"] for c in "xyz"]))
        cover = (f"; error / sd rms {np.sqrt(np.mean(np.concatenate(z) ** 2)):.2f}, 2 sd cover "
                 f"{np.mean(np.abs(np.concatenate(z)) <= 2.0):.1%}") if z else ""
        print(f"  {str(driver):<12s} named {right}/{n_seeds}; rms/noise median {np.median(ratios):.3f}, "
              f"max {np.max(ratios):.3f}{cover}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=DEFAULT)
    ap.add_argument("--truth", type=int, default=0, metavar="N",
                    help="also N hidden-drift records per driver on the truth machine (PYTHONPATH=tests)")
    args = ap.parse_args(argv)
    if args.truth:
        truth_sweep(args.truth)
    d = read_columns(args.data)
    lines = args.data.read_text().splitlines()
    header, rows = lines[0], lines[1:]
    chans = [k for k in d if k.startswith("disp_")]
    temps = [k for k in d if k.startswith("temp_")]
    Y = np.column_stack([d[k] for k in chans])
    T = np.column_stack([d[k] for k in temps])
    n = len(Y)
    print(f"{args.data.name}: {n} readings, {len(chans)} channels, {len(temps)} temperatures; "
          "rms over the channels of the prediction error on the held-out part, um")
    print(f"{'split':>6s} {'model':<36s} {'about the mean':>14s} {'absolute':>9s}")
    sd_table = []
    with tempfile.TemporaryDirectory(prefix="bench-thermal-") as tmp:
        for frac in SPLITS:
            s = int(round(frac * n))
            yte = Y[s:]
            mt, sd, seconds = mtcomp_prediction(header, rows, s, Path(tmp), chans)
            state = np.column_stack([T, d["spindle_rpm"]])
            beyond = beyond_range(state[:s], state[s:])
            sd_table.append(f"{round(frac * 100):3d}/{round((1 - frac) * 100):<2d} "
                            f"{sd_columns(mt, sd, yte, beyond)}")
            table = [("raw (no model)", np.zeros_like(yte)),
                     ("least squares, 16 temperatures", ridge(T[:s], Y[:s], 0.0)(T[s:])),
                     ("ridge, forward-validated penalty", forward_ridge(T[:s], Y[:s])(T[s:])),
                     (f"mtcomp diagnose + predict ({seconds:.0f} s)", mt)]
            for name, pred in table:
                about, absolute = scores(pred, yte)
                print(f"{round(frac * 100):3d}/{round((1 - frac) * 100):<2d} {name:<36s} {about:14.2f} "
                      f"{absolute:9.2f}")
    print("mtcomp's standard errors (pred_..._sd) against its errors on the held-out part, absolute, um:")
    print("(then the rows beyond the fitted part's range of a temperature or the spindle speed, and rms z,")
    print(" 2 sd cover on the rows inside it and on those beyond it)")
    print(f"{'split':>6s} {'rms error':>9s} {'median sd':>9s} {'ratio':>7s} {'rms z':>7s} {'2 sd cover':>9s}"
          f"  {'beyond':>7s} {'in: z':>7s} {'cover':>9s} {'out: z':>7s} {'cover':>9s}")
    print("\n".join(sd_table))


if __name__ == "__main__":
    main()

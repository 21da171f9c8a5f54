"""Real ISO 230-2 runs: mtcomp's held-out prediction against the pitch table a controller would use.

For each real file (shared/data/real/iso230_2): runs 1-3 are written to one file and runs 4-5 to a
second (a new laser set-up), `mtcomp diagnose` (or `identify` with --command identify) fits the
first, `mtcomp predict` predicts the second. Judged like a user would: rms of (reading - prediction)
about its mean over the held-out file, since a new set-up's zero is unknown to any fit. The pitch
table is the mean of runs 1-3 per target and direction (bidirectional), computed here with plain
Python; "raw" is the held-out readings' own rms about their mean.

    python benchmarks/bench_identify_real.py [--command diagnose|identify] [--files ess_b02_x ...]
                                             [--data DIR]

Prints one row per file and the ratio mtcomp / pitch table (goal: <= 1.1). The real data are found
as bench_export_real.py finds them: ``--data DIR``, else ``$MTCOMP_REAL_DATA``, else
``shared/data/real`` beside the repository; without them the script says where it looked and exits
with status 1.
"""
from __future__ import annotations

import argparse
import csv
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from bench_export_real import FILES, iso230_2_folder_or_exit     # the script's own folder


def split_runs(src: Path, out_dir: Path, last_train_run: int = 3) -> tuple[Path, Path]:
    rows = list(csv.DictReader(open(src, newline="")))
    paths = []
    for part, keep in (("train", lambda r: int(r["run"]) <= last_train_run),
                       ("heldout", lambda r: int(r["run"]) > last_train_run)):
        path = out_dir / f"{src.stem}_{part}.csv"
        with open(path, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
            w.writeheader()
            w.writerows(r for r in rows if keep(r))
        paths.append(path)
    return paths[0], paths[1]


def rms_about_mean(x) -> float:
    x = np.asarray(x, dtype=float)
    return float(np.sqrt(np.mean((x - x.mean()) ** 2)))


def pitch_table_residual(train: Path, heldout: Path) -> np.ndarray:
    table: dict = {}
    for r in csv.DictReader(open(train, newline="")):
        table.setdefault((float(r["target_mm"]), int(r["dir"])), []).append(float(r["value_um"]))
    out = []
    for r in csv.DictReader(open(heldout, newline="")):
        out.append(float(r["value_um"]) - np.mean(table[(float(r["target_mm"]), int(r["dir"]))]))
    return np.array(out)


def mtcomp_residual(command: str, train: Path, heldout: Path, work: Path) -> np.ndarray:
    model, pred = work / f"{train.stem}_model.json", work / f"{heldout.stem}_pred.csv"
    fit = ["mtcomp", command, "xfyz", str(train), "-o", str(model)]
    if command == "diagnose":
        fit += ["--json", str(work / f"{train.stem}_report.json")]
    for cmd in (fit, ["mtcomp", "predict", "xfyz", str(model), str(heldout), "-o", str(pred)]):
        subprocess.run([sys.executable, "-m"] + cmd, check=True, capture_output=True, text=True)
    rows = list(csv.DictReader(open(pred, newline="")))
    return np.array([float(r["value_um"]) - float(r["pred_value_um"]) for r in rows])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--command", choices=("diagnose", "identify"), default="diagnose")
    ap.add_argument("--files", nargs="+", default=list(FILES))
    ap.add_argument("--data", type=Path, default=None,
                    help="the real-data folder (holding iso230_2/); default $MTCOMP_REAL_DATA, else "
                         "shared/data/real beside the repository")
    args = ap.parse_args()
    real = iso230_2_folder_or_exit(args.data)
    print(f"real data: {real}")
    print(f"held-out rms about the mean, um (fit runs 1-3, predict runs 4-5; mtcomp {args.command})")
    print(f"{'file':<16} {'raw':>7} {'pitch':>7} {'mtcomp':>7} {'ratio':>6}")
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        for name in args.files:
            train, heldout = split_runs(real / f"{name}.csv", work)
            raw = [float(r["value_um"]) for r in csv.DictReader(open(heldout, newline=""))]
            pitch = rms_about_mean(pitch_table_residual(train, heldout))
            ours = rms_about_mean(mtcomp_residual(args.command, train, heldout, work))
            print(f"{name:<16} {rms_about_mean(raw):7.2f} {pitch:7.2f} {ours:7.2f} {ours / pitch:6.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

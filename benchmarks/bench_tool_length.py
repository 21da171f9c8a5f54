"""A part cut with a tool length the campaign never measured, on the independent machine (tests/truth).

The tracker campaign: dense lines along X, Y and Z with a 100 mm stylus, a coarse 7 x 5 x 4 grid
with 50 and 200 mm styli (tests/independent_cases.py, ``tool_length_case``); the part, a 300 mm bowl,
is cut with tool length 0. For each seed: `mtcomp identify` on the campaign, `mtcomp compensate` of
the bowl, both programs "cut" on the independent machine. Printed per case: the bowl's form error
(rigid motion removed) before and after compensation, the share removed, how far the model's
predicted form is from the truth's, and the median and largest standard error of a correction
(BLOCKS.csv correction_sd_um: the largest of the three components' standard errors), and how often
the predicted form is off by more than twice that standard error: as the length of the 3-vector
misfit ("off > 2 sd": up to 26 % of blocks even when the standard error is calibrated, a
chi-square of 3 degrees of freedom above 4) and component by component ("per comp.", about 5 % when
calibrated, fewer where one component's standard error is the largest). ``--wave MM`` adds a sine
of that period to the angular profiles (structure finer than the grid, which the two styli cannot
follow between its nodes).

``--max-correction-sd-um SD`` is passed to compensate (0: every block corrected, whatever its
standard error).

    PYTHONPATH=tests python benchmarks/bench_tool_length.py [--seeds 1 2 3 4 5] [--wave 60]
                                                            [--max-correction-sd-um SD]
"""
from __future__ import annotations

import argparse
import csv
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

try:
    from independent_cases import tool_length_case
    from truth import Context, form_error
except ImportError:
    raise SystemExit("bench_tool_length: run it with tests/ on PYTHONPATH "
                     "(PYTHONPATH=tests python benchmarks/bench_tool_length.py)") from None


def run(seed: int, wave, folder: Path, max_sd=None) -> dict:
    case = tool_length_case(seed, folder, wave)
    model, out, rep = folder / "m.json", folder / "out.nc", folder / "b.csv"
    for cmd in (["identify", str(case.toml), *map(str, case.files), "-o", str(model)],
                ["compensate", str(case.toml), str(model), case.bowl.path, "-o", str(out), "--report",
                 str(rep), "--max-step-um", "50", "--max-correction-um", "200", "--quiet",
                 *(["--max-correction-sd-um", str(max_sd)] if max_sd is not None else [])]):
        done = subprocess.run([sys.executable, "-m", "mtcomp", *cmd], capture_output=True, text=True)
        if done.returncode:
            raise SystemExit(done.stderr)
    with open(rep, newline="") as f:
        rows = [r for r in csv.DictReader(f) if r["inserted"] == "0" and r["rapid"] == "0"]
    q = np.array([[float(r[f"{a}_mm"]) for a in "xyz"] for r in rows])
    corr = np.array([[float(r[f"c{a}_um"]) for a in "xyz"] for r in rows])
    pred = np.array([[float(r[f"e{a}_before_um"]) for a in "xyz"] for r in rows])
    sd = np.array([float(r["correction_sd_um"]) if r["correction_sd_um"] else np.nan for r in rows])
    nominal = q - corr * 1e-3
    ctx = Context(feed_mm_min=1200.0, dirs={a: 1.0 for a in "XYZ"})
    before = case.truth.true_pose(nominal, 0.0, ctx)[0]
    after = case.truth.true_pose(q, 0.0, ctx)[0]
    tip0 = case.truth.nominal_pose(nominal, 0.0)[0]
    misfit = form_error(tip0 + pred * 1e-3, before)
    off = np.linalg.norm(misfit.residual_um, axis=1)
    return {"before": form_error(before, tip0).rms_um, "after": form_error(after, tip0).rms_um,
            "misfit": misfit.rms_um, "beyond_2sd": float(np.mean(off > 2.0 * sd)),
            "component_beyond_2sd": float(np.mean(np.abs(misfit.residual_um) > 2.0 * sd[:, None])),
            # no standard errors at all with --max-correction-sd-um 0 (compensate then computes none)
            "sd_median": float(np.nanmedian(sd)) if np.isfinite(sd).any() else float("nan"),
            "sd_max": float(np.nanmax(sd)) if np.isfinite(sd).any() else float("nan"),
            "uncorrected": sum(r["corrected"] == "0" for r in rows), "blocks": len(rows)}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3, 4, 5])
    ap.add_argument("--wave", type=float, default=None, metavar="MM")
    ap.add_argument("--max-correction-sd-um", type=float, default=None, metavar="SD",
                    help="compensate's limit on a correction's standard error (default: its own; 0: none)")
    args = ap.parse_args()
    print(f"{'seed':>5} {'form before':>12} {'after':>8} {'removed':>8} {'predicted form off':>19} "
          f"{'sd median':>10} {'sd max':>8} {'off > 2 sd':>11} {'per comp.':>10} {'uncorrected':>12}   "
          f"(um; wave {args.wave or 'none'})")
    removed, off = [], []
    for seed in args.seeds:
        with tempfile.TemporaryDirectory() as tmp:
            r = run(seed, args.wave, Path(tmp), args.max_correction_sd_um)
        removed.append(1 - r["after"] / r["before"])
        off.append(r["misfit"])
        print(f"{seed:5d} {r['before']:12.3f} {r['after']:8.3f} {100 * removed[-1]:7.0f}% {r['misfit']:19.3f} "
              f"{r['sd_median']:10.3f} {r['sd_max']:8.3f} {100 * r['beyond_2sd']:10.0f}% "
              f"{100 * r['component_beyond_2sd']:9.0f}% "
              f"{r['uncorrected']:6d}/{r['blocks']}")
    print(f"median share removed {100 * float(np.median(removed)):.0f} %, smallest {100 * min(removed):.0f} %; "
          f"predicted form off: median {float(np.median(off)):.3f} um, largest {max(off):.3f} um, "
          f"over 0.3 um at {sum(v > 0.3 for v in off)} of {len(off)} seeds")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

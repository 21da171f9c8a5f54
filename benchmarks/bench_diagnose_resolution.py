"""Resolution of `mtcomp diagnose` on the independent machine (tests/truth, which shares no code with
mtcomp): four cases in which the base's resolution, not a missing effect, can be the limit.

* ``pdge``: a rotary table whose C error motions (radial, axial, tilt) carry harmonics 2, 3 and 4,
  seen by ball-bar circles and the three-sphere set-up (noise 0.3 um); the held-out rms over the noise
  (asked: 1.1 or less);
* ``seed003``: seed 003's three-sphere set-up on a C axis with error motions of harmonics 2-5, through
  the generic path (the built-in CAFXYZ machine, ``diagnose``): the distance between the model's and
  the truth's C-axis points, mean and max (the paper: 0.3 and 0.78 um);
* ``periodic_backlash``: a 20 mm screw period beside a backlash of the same axis, laser runs with a
  fine run: both must be named; ``pitch_line``: the same read as a pitch table (every 5 mm, no fine
  run);
* ``feed_abbe``: feed-dependent Abbe errors of the truth benchmark's laser, mixture and rich
  campaigns; ``feed_abbe_fine``: seed 000's set-up on a machine whose yaw has a 25 mm wave (finer
  than the base's 16 mm knot floor): the verdict (asked: ``explained``) and the held-out rms over the
  noise (0.2 um there).

    PYTHONPATH=tests python benchmarks/bench_diagnose_resolution.py            # every case
    PYTHONPATH=tests python benchmarks/bench_diagnose_resolution.py --case pdge --seeds 3
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path


try:
    from resolution_cases import (abbe_case, abbe_fine_case, pdge_case, periodic_backlash_case,
                                  pitch_line_case, seed003_diagnosed)
    from diagnose_truth import run, score
except ImportError:
    raise SystemExit("bench_diagnose_resolution: run it with tests/ on PYTHONPATH "
                     "(PYTHONPATH=tests python benchmarks/bench_diagnose_resolution.py)") from None

CASES = ("pdge", "seed003", "periodic_backlash", "pitch_line", "feed_abbe", "feed_abbe_fine")


def _named(d) -> list:
    return [f"{f.effect} {f.axis}".strip() for f in d.findings]


def _written(d) -> str:
    """The model diagnose wrote (REPORT.json's ``final.written``, docs/diagnose.md)."""
    return (d.final.get("written") or {}).get("model", "least squares (no weak combination)")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--case", choices=CASES, action="append", help="the cases to run (default: all)")
    ap.add_argument("--seeds", type=int, default=3, help="machines per case")
    ap.add_argument("--seed", type=int, default=0, help="first seed")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.case or CASES:
            for k in range(args.seeds):
                seed = args.seed + k
                folder = Path(tmp) / f"{name}{seed}"
                t0 = time.perf_counter()
                if name == "seed003":
                    d, err, turn = seed003_diagnosed(seed, folder)
                    print(f"seed003 {seed}: C-axis points over the turn (each point's offset removed) mean "
                          f"{turn.mean():.3f} um, max {turn.max():.3f} um (paper 0.3 / 0.78); with the offset "
                          f"the data leave open: mean {err.mean():.3f}, max {err.max():.3f}; named {_named(d)} "
                          f"{d.verdict}, model written: {_written(d)} {time.perf_counter() - t0:.1f} s", flush=True)
                    continue
                case = {"pdge": pdge_case, "periodic_backlash": periodic_backlash_case,
                        "pitch_line": pitch_line_case, "feed_abbe": abbe_case,
                        "feed_abbe_fine": abbe_fine_case}[name](seed, folder)
                d, dt = run(case)
                sc = score(case, d, noise_um=0.2 if name == "feed_abbe_fine" else 0.3)
                print(f"{name} {seed} {case.kind}: named {_named(d)} {d.verdict}, held-out/noise "
                      f"{sc.ratio:.3f}, model written: {_written(d)} {dt:.1f} s", flush=True)


if __name__ == "__main__":
    main()

"""Time of `mtcomp diagnose` on rich 5-axis campaigns of the independent machine (tests/truth), as a
user meets it: a fresh process and an empty compile cache (MTCOMP_CACHE_DIR), so that every CasADi
function is built and, past its threshold, compiled within the time shown.

    PYTHONPATH=tests python benchmarks/bench_diagnose_time.py            # 3 campaigns x 2 sizes
    PYTHONPATH=tests python benchmarks/bench_diagnose_time.py --runs 3   # median of 3 fresh runs each

Two sizes per campaign: the whole rich campaign (points grid, laser runs and fine runs of X, Y, Z,
rotary laser runs, ball-bar circles, three-sphere set-up: 10,496 rows) and the same without the
points grid (5,888 rows). The issue's goal: a 5,000-row campaign under 20 s.
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile

import numpy as np

CHILD = r'''
import sys, tempfile, time
from pathlib import Path
from mtcomp.diagnose import diagnose
from mtcomp.machine import load_machine
from mtcomp.measurement.files import read_measurements
from truth.hidden import hidden_case
seed, effect, topo, whole = int(sys.argv[1]), sys.argv[2], sys.argv[3], sys.argv[4] == "1"
with tempfile.TemporaryDirectory() as tmp:
    case = hidden_case(seed, effect, "rich", topo, Path(tmp))
    paths = [p for p in case.paths if whole or p.name != "points.csv"]
    data = [read_measurements(p) for p in paths]
    t0 = time.perf_counter()
    d = diagnose(load_machine(topo), data)
    print(sum(len(x) for x in data), time.perf_counter() - t0, d.verdict)
'''

CASES = ((9001, "rotary_backlash", "cafxyz"), (9002, "periodic_error", "cbfxyz"), (9063, "", "cafxyz"))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=1, help="fresh runs per campaign and size (median)")
    args = ap.parse_args(argv)
    here = os.path.dirname(os.path.abspath(__file__))
    tests = os.path.join(os.path.dirname(here), "tests")
    for seed, effect, topo in CASES:
        for whole in (False, True):
            times, rows, verdict = [], 0, ""
            for _ in range(args.runs):
                with tempfile.TemporaryDirectory() as cache:
                    env = dict(os.environ, MTCOMP_CACHE_DIR=cache,
                               PYTHONPATH=os.pathsep.join(p for p in (tests, os.environ.get("PYTHONPATH")) if p))
                    out = subprocess.run([sys.executable, "-c", CHILD, str(seed), effect, topo,
                                          "1" if whole else "0"], env=env, capture_output=True, text=True)
                    if out.returncode:
                        sys.exit((out.stderr.strip().splitlines() or [f"child exited {out.returncode}"])[-1])
                    r, t, verdict = out.stdout.split()
                    rows, times = int(r), times + [float(t)]
            print(f"seed {seed} {topo:7} {'whole campaign' if whole else 'without points '} {rows:6d} rows: "
                  f"first diagnosis median {np.median(times):.1f} s (runs {', '.join(f'{t:.1f}' for t in times)}), "
                  f"verdict {verdict}", flush=True)


if __name__ == "__main__":
    main()

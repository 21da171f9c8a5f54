"""How soon ``mtcomp compensate`` says what it does: seconds from its start to its first progress
line on stderr, on a long tool centre point program (which the reader reads line by line in
Python), with the model's compiled code in the cache or not (``--cold``: a fresh cache folder, so
the G-code scanner and the model's C code are compiled first, as on the first run with a model).

    python benchmarks/bench_compensate_first_progress.py [--blocks 100000] [--cold] [--repeat 3]
        [--model MODEL.json] [--program IN.ngc] [--checkout DIR]

The program (unless ``--program``) is LinuxCNC's ``M428`` ring of ``--blocks`` feed moves on the
built-in cafxyz machine: X Y on a circle of 40 mm, Z rising, A and C turning. The model (unless
``--model``, a cafxyz model: one with a covariance adds the standard-error check and its compiled
Jacobian) is a zero model. ``--checkout`` is the mtcomp checkout run (default: the one holding
this script), so two versions can be compared in turn. Prints, per run, the first line's time,
the run's time and the first line itself, then the medians.
"""
from __future__ import annotations

import argparse
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def write_program(path: Path, blocks: int) -> None:
    lines = ["G21 G90 G17 G94", "G54", "T1 M6", "G43 H1", "M428",
             "G0 X40.0 Y0.0 Z60.0 A-30.0 C0.0", "G1 Z20.0 F400."]
    for k in range(1, blocks + 1):
        t = 2 * math.pi * k / 2000
        lines.append(f"X{40 * math.cos(t):.4f} Y{40 * math.sin(t):.4f} Z{20 + 1e-4 * k:.4f} "
                     f"A{-30 - 10 * math.sin(t / 4):.4f} C{math.degrees(t) % 360:.4f}")
    path.write_text("\n".join(lines + ["G0 Z60.", "M429", "M2"]) + "\n")


def write_zero_model(path: Path, checkout: Path) -> None:
    code = ("import sys; from mtcomp import load_machine; "
            "from mtcomp.models import ErrorModel, FittedModel, save_model; "
            "save_model(sys.argv[1], FittedModel.zero(ErrorModel(load_machine('cafxyz'))))")
    subprocess.run([sys.executable, "-c", code, str(path)], check=True,
                   env={**os.environ, "PYTHONPATH": str(checkout)}, cwd=checkout)


def one_run(checkout: Path, model: Path, program: Path, out: Path, cache: Path | None):
    """(seconds to the first stderr line, seconds in all, that line)."""
    env = {**os.environ, "PYTHONPATH": str(checkout)}
    if cache is not None:
        env["MTCOMP_CACHE_DIR"] = str(cache)
    cmd = [sys.executable, "-m", "mtcomp", "compensate", "cafxyz", str(model), str(program),
           "-o", str(out), "--tool-length", "H1=100"]
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            env=env, cwd=checkout)
    first, first_s = "", math.nan
    for line in proc.stderr:
        if not first:
            first, first_s = line.strip(), time.perf_counter() - t0
    if proc.wait() != 0:
        raise SystemExit(f"compensate failed: {first}")
    return first_s, time.perf_counter() - t0, first


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--blocks", type=int, default=100_000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--cold", action="store_true", help="a fresh compiled-code cache each run")
    ap.add_argument("--model", type=Path, default=None)
    ap.add_argument("--program", type=Path, default=None)
    ap.add_argument("--checkout", type=Path, default=Path(__file__).resolve().parents[1])
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        program = args.program or tmp / "ring_tcp.ngc"
        if args.program is None:
            write_program(program, args.blocks)
        model = args.model or tmp / "zero.json"
        if args.model is None:
            write_zero_model(model, args.checkout)
        firsts, totals = [], []
        for k in range(args.repeat):
            cache = None
            if args.cold:
                cache = tmp / f"cache{k}"
                cache.mkdir(mode=0o700)
            first_s, total_s, line = one_run(args.checkout, model, program, tmp / "out.ngc",
                                             cache)
            firsts.append(first_s)
            totals.append(total_s)
            print(f"run {k + 1}: first line after {first_s:.1f} s, {total_s:.1f} s in all: {line}")
        print(f"median: first line after {statistics.median(firsts):.1f} s, "
              f"{statistics.median(totals):.1f} s in all ({args.checkout}, "
              f"{'cold' if args.cold else 'warm'} cache, load average "
              f"{os.getloadavg()[0]:.1f})")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""What saying what the corrections assume at zero costs `mtcomp compensate`: wall time of the same
run in two checkouts, on a model that holds components at zero and never moved Y.

The model: laser runs of X and Z alone (positioning and both straightnesses, on the lines Y = 0,
Z = 0 and X = 0, Y = 0) on the independent truth machine (tests/truth), identified. The program:
``--blocks`` G1 blocks of a Lissajous path over X +-350, Y +-250 mm, Z from -200 to 100 mm, so
that every block stands away from the data's lines. Each checkout runs ``python -m mtcomp
compensate ... --report`` in a subprocess from its own folder (one warm-up run, then ``--repeat``;
the median wall and CPU times are printed: on a loaded machine the CPU time is the figure), and
its summary's note on the assumptions, if any.

    PYTHONPATH=tests python benchmarks/bench_assumed.py /tmp/old CHECKOUT [--blocks 200000]
"""
from __future__ import annotations

import argparse
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def make_inputs(folder: Path, blocks: int) -> tuple[Path, Path]:
    from laser_files import xz_lasers
    paths = xz_lasers(folder)
    model = folder / "model.json"
    subprocess.run([sys.executable, "-m", "mtcomp", "identify", "xfyz", *paths, "-o", str(model)],
                   check=True, capture_output=True)
    t = np.linspace(0.0, 1.0, blocks)
    x, y, z = 350 * np.sin(40 * np.pi * t), 250 * np.cos(17 * np.pi * t), -200 + 300 * t
    lines = ["G21 G90 G17", "G54", "G0 X0 Y0 Z0", "G1 F1000"]
    lines += [f"X{a:.3f} Y{b:.3f} Z{c:.3f}" for a, b, c in zip(x, y, z)]
    prog = folder / "prog.nc"
    prog.write_text("\n".join(lines + ["M30"]) + "\n")
    return model, prog


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run(checkout: Path, model: Path, prog: Path, out: Path) -> tuple[float, float, str]:
    cmd = [sys.executable, "-m", "mtcomp", "compensate", "xfyz", str(model), str(prog), "-o",
           str(out / "out.nc"), "--report", str(out / "blocks.csv"), "--work-offset",
           "G54=X0,Y0,Z0", "--quiet"]
    t0, c0 = time.perf_counter(), _cpu()
    proc = subprocess.run(cmd, cwd=checkout, capture_output=True, text=True, check=True)
    note = next((line for line in proc.stdout.splitlines() if "assume zero" in line), "(no note)")
    return time.perf_counter() - t0, _cpu() - c0, note


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("checkouts", type=Path, nargs="+")
    ap.add_argument("--blocks", type=int, default=200_000)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        model, prog = make_inputs(folder, args.blocks)
        for checkout in args.checkouts:
            run(checkout, model, prog, folder)
            runs = [run(checkout, model, prog, folder) for _ in range(args.repeat)]
            print(f"{checkout}: {args.blocks} blocks, median {statistics.median(r[0] for r in runs):.2f} s "
                  f"wall, {statistics.median(r[1] for r in runs):.2f} s CPU (user + sys; "
                  f"{', '.join(f'{r[1]:.2f}' for r in runs)})")
            print(f"  {runs[0][2][:200]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

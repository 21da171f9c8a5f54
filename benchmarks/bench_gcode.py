"""G-code read + write throughput (blocks/s) and peak memory, on a generated program.

    python benchmarks/bench_gcode.py [--blocks 1000000] [--runs 3] [--python] [--corrected]

Each run is a fresh subprocess that streams the program through ``iter_segment_chunks`` and writes
it back with ``write_corrected`` (the corrections are the nominal end points, the shape of what the
planner hands over; with ``--corrected`` every position scaled by 1 + 3e-5, so that nearly every
number is written anew, as after a compensation); the figure is blocks / wall time of read + write,
and the peak resident memory (ru_maxrss) of that subprocess. Prints the median of the runs.
``--python`` forces the pure-Python reader and writer (no compiled fast path).
"""
from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

CHILD = r"""
import json, os, resource, sys, time
import numpy as np
if sys.argv[4] == "python":
    os.environ["MTCOMP_NO_FAST_GCODE"] = "1"
from mtcomp import load_machine
from mtcomp.toolpaths import iter_segment_chunks, write_corrected
from mtcomp.toolpaths import _fast
m = load_machine(sys.argv[3])
t0 = time.perf_counter()
scale = float(sys.argv[5])
def corr():
    for c in iter_segment_chunks(sys.argv[1], m):
        yield c, c.end if scale == 1.0 else c.end * scale, np.ones(len(c), np.int64)
rows = write_corrected(sys.argv[1], sys.argv[2], m, corr())
dt = time.perf_counter() - t0
print(json.dumps({"rows": rows, "seconds": dt, "maxrss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                  "fast": _fast.available()}))
"""


def make_program(path: Path, n_blocks: int, seed: int = 0) -> None:
    """A bowl-like finishing program: header, n_blocks 'X.. Y.. Z..' lines (every 50th with G1 and
    F, every 1000th a comment line), an arc every 5000 blocks, footer. Written in pieces."""
    rng = np.random.default_rng(seed)
    with open(path, "w") as f:
        f.write("%\nO0001 (BENCH)\nG21 G90 G17\nT1 M6\nS12000 M3\nG0 X0 Y0 Z10.\nG1 Z0 F1000\n")
        done = 0
        while done < n_blocks:
            k = min(100_000, n_blocks - done)
            xyz = np.cumsum(rng.normal(0, 0.2, (k, 3)), axis=0) + rng.uniform(-50, 50, 3)
            lines = [f"X{x:.4f} Y{y:.4f} Z{z:.4f}" for x, y, z in xyz]
            for i in range(0, k, 50):
                lines[i] = f"G1 {lines[i]} F{1000 + (i % 7) * 100}"
            for i in range(999, k, 1000):
                lines[i] = lines[i] + "\n(PASS)"
            for i in range(4999, k, 5000):
                x, y, z = xyz[i - 1]
                lines[i] = f"G2 X{x + 2:.4f} Y{y:.4f} I1. J0\nG1 X{xyz[i][0]:.4f} Y{xyz[i][1]:.4f} Z{xyz[i][2]:.4f}"
            f.write("\n".join(lines) + "\n")
            done += k
        f.write("G0 Z10.\nM5\nM30\n%\n")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--blocks", type=int, default=1_000_000)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--machine", default="xfyz")
    ap.add_argument("--python", action="store_true", help="force the pure-Python path")
    ap.add_argument("--corrected", action="store_true",
                    help="write every position scaled by 1 + 3e-5 (every number rewritten)")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as d:
        src = Path(d) / "bench.nc"
        t = time.perf_counter()
        make_program(src, args.blocks)
        size_mb = src.stat().st_size / 1e6
        print(f"program: {args.blocks} blocks, {size_mb:.1f} MB, generated in {time.perf_counter() - t:.1f} s")
        results = []
        for r in range(args.runs):
            out = Path(d) / f"out{r}.nc"
            p = subprocess.run([sys.executable, "-c", CHILD, str(src), str(out), args.machine,
                                "python" if args.python else "auto",
                                repr(1 + 3e-5 if args.corrected else 1.0)],
                               capture_output=True, text=True, check=True)
            res = json.loads(p.stdout.strip().splitlines()[-1])
            results.append(res)
            print(f"  run {r + 1}: {res['rows']} rows in {res['seconds']:.2f} s "
                  f"({args.blocks / res['seconds'] / 1e6:.3f} M blocks/s), peak RSS {res['maxrss_mb']:.0f} MB"
                  f", fast path {'on' if res['fast'] else 'off'}")
            out.unlink()
        secs = statistics.median(r["seconds"] for r in results)
        rss = statistics.median(r["maxrss_mb"] for r in results)
        print(f"median read+write: {args.blocks / secs / 1e6:.3f} M blocks/s "
              f"({size_mb / secs:.0f} MB/s of input), peak RSS {rss:.0f} MB")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""`mtcomp compensate` against a plain read-and-write of the same file: wall time and peak memory.

    python benchmarks/bench_compensate_copy.py [--blocks 1280000] [--repeat 5] [--report] [--bytecode]
        [--model MODEL.json]

The program (generated in a temporary folder, nothing is kept) is bench_gcode.py's: X Y Z lines with
4 decimals, a G1 with F every 50 blocks, a comment line every 1000, and a G2 arc every 5000 blocks
(so the arc path of the writer is exercised). The model is one as users have it: the one
``mtcomp demo`` compensates with, identified here once from the demo's simulated campaign
(bench_compensate.py's ``write_identified_model``: penalised B-splines, 274 parameters, a covariance,
so the correction standard-error gate runs, and a support region), or ``--model``'s. Every figure
is the median of ``--repeat`` fresh subprocesses after one warm-up (which compiles the model's and
the reader's C code into the cache):

* copy: the file read line by line and written to another file by a plain Python loop;
* compensate: ``python -m mtcomp compensate xfyz MODEL PROGRAM -o OUT --quiet`` (method qp);
* sd gate off: the same with ``--max-correction-sd-um 0`` (no standard error computed);
* synthetic: the same with bench_compensate.py's synthetic base model (polynomials, few
  parameters, no covariance, no support region: the gate does not run; a floor, no user's model);
* with ``--report``, also compensate with ``--report BLOCKS.csv`` (one row per block).

Peak memory is ru_maxrss of each subprocess (os.wait4). The ratio is compensate / copy of wall
times ("x copy"), and of CPU times, user and system ("cpu x": less sensitive to other work on the
machine, but blind to what threads gain). The subprocesses import mtcomp from the current folder first (``python -m`` and ``-c`` put
it at the head of sys.path), then from PYTHONPATH: run this from the checkout to be measured, with
``PYTHONPATH=.``; the folder they imported is printed. ``import`` is the floor of any compensation:
a process that imports what compensate imports (numpy, CasADi, the package) and exits; ``+ osqp``
adds OSQP and scipy.sparse, imported when a window of the program needs the bounded QP (this
program's do).

Python compiles each module it imports from source unless it finds the module's bytecode (a
``__pycache__`` file, written at the first import, or at installation); with
``PYTHONDONTWRITEBYTECODE`` set, as in some environments, it compiles the package's modules at
every start (about 0.2 s for compensate's). ``--bytecode`` runs every subprocess with a bytecode
cache in the temporary folder (``PYTHONPYCACHEPREFIX``; the warm-up writes it), as an installed
package runs.
"""
from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench_compensate import write_identified_model_apart, write_model
from bench_gcode import make_program

IMPORTS = "import mtcomp.commands.compensate, mtcomp.compensation, casadi"
COPY = ("import sys\n"
        "with open(sys.argv[1], 'rb') as f, open(sys.argv[2], 'wb') as g:\n"
        "    for line in f:\n"
        "        g.write(line)\n")


def run(cmd: list[str], env: dict | None = None) -> tuple[float, float, float]:
    """(wall s, peak rss MB, CPU s (user + system)) of one subprocess."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)
    _, status, ru = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    err = proc.stderr.read().decode()
    proc.stderr.close()
    if os.waitstatus_to_exitcode(status) != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed: {err}")
    return wall, ru.ru_maxrss / 1024.0, ru.ru_utime + ru.ru_stime


def measure(cmd, repeat, env=None):
    run(cmd, env)
    runs = [run(cmd, env) for _ in range(repeat)]
    return tuple(statistics.median(r[k] for r in runs) for k in range(3))


def bytecode_env(folder: Path) -> dict:
    """The environment with Python's bytecode cached in ``folder`` (written where missing)."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env["PYTHONPYCACHEPREFIX"] = str(folder)
    return env


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--blocks", type=int, default=1_280_000)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--report", action="store_true", help="also time compensate --report")
    ap.add_argument("--bytecode", action="store_true",
                    help="run every subprocess with a bytecode cache, as an installed package")
    ap.add_argument("--model", type=Path,
                    help="MODEL.json to compensate with (default: identified as mtcomp demo does)")
    args = ap.parse_args(argv)
    py = sys.executable
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        prog, synthetic, out = tmp / "p.nc", tmp / "synthetic.json", tmp / "out.nc"
        make_program(prog, args.blocks)
        write_model(synthetic, "xfyz")
        model = args.model
        if model is None:
            model = tmp / "m.json"
            write_identified_model_apart(model)
        size = prog.stat().st_size / 1e6
        env = bytecode_env(tmp / "pycache") if args.bytecode else None
        copy = measure([py, "-c", COPY, str(prog), str(tmp / "copy.nc")], args.repeat, env)
        floor = measure([py, "-c", IMPORTS], args.repeat, env)
        floor_qp = measure([py, "-c", IMPORTS + ", osqp, scipy.sparse"], args.repeat, env)
        cmd = [py, "-m", "mtcomp", "compensate", "xfyz", str(model), str(prog), "-o", str(out),
               "--quiet"]
        comp = measure(cmd, args.repeat, env)
        out_size = out.stat().st_size / 1e6
        rows = [("copy", copy), ("import", floor), ("+ osqp", floor_qp), ("compensate", comp),
                ("sd gate off", measure(cmd + ["--max-correction-sd-um", "0"], args.repeat, env))]
        cmd_synthetic = cmd[:5] + [str(synthetic)] + cmd[6:]
        rows.append(("synthetic", measure(cmd_synthetic, args.repeat, env)))
        if args.report:
            rows.append(("+ --report", measure(cmd + ["--report", str(tmp / "b.csv")],
                                               args.repeat, env)))
    where = subprocess.run([py, "-c", "import mtcomp; print(mtcomp.__file__)"], capture_output=True,
                           text=True, check=True).stdout.strip()
    print(f"mtcomp from {Path(where).parent}")
    print(f"program: {args.blocks} blocks, {size:.1f} MB (output {out_size:.1f} MB); model "
          f"{args.model or 'identified as mtcomp demo does'}")
    print(f"{'what':12s} {'wall s':>8s} {'peak MB':>8s} {'x copy':>7s} {'cpu s':>7s} {'cpu x':>6s}")
    for what, (wall, mb, cpu) in rows:
        print(f"{what:12s} {wall:8.2f} {mb:8.0f} {wall / copy[0]:7.1f} {cpu:7.2f} "
              f"{cpu / copy[2]:6.1f}")
    print(f"(median of {args.repeat} runs after a warm-up; {os.cpu_count()} cpus, load average "
          f"{os.getloadavg()[0]:.1f}; bytecode "
          f"{'cached' if args.bytecode or not sys.dont_write_bytecode else 'not written'})")
    return 0


if __name__ == "__main__":
    sys.exit(main())

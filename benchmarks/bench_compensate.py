"""Benchmark of `mtcomp compensate`: wall time, CPU time and peak memory, end to end, in subprocesses.

Programs (generated in a temporary folder, nothing is kept):

* xfyz: a 3-axis raster finishing pass over a wavy surface, ``--xfyz-blocks`` G1 blocks (1,000,000);
* cafxyz: a 5-axis pass with A tilting between 20 and 40 deg and C sweeping back and forth,
  ``--cafxyz-blocks`` G1 blocks (200,000).

The model is a synthetic base model of machine-tool size (about 10 um and 20 urad per parameter,
seeded). Each command runs ``--repeat`` times after one warm-up run (the warm-up compiles the model's
C code into the cache); the median is printed. The reference is the same program read and written
without correction (``write_corrected(..., None)`` in a subprocess), so the ratio is
compensate / (read + write) of wall times ("x r+w") and of CPU times ("cpu x"). ``qp 1 thread``
is qp with ``MTCOMP_THREADS=1`` (the planner does not use a second CPU). Peak memory is ru_maxrss
of each subprocess (os.wait4).

    python benchmarks/bench_compensate.py                      # full size
    python benchmarks/bench_compensate.py --xfyz-blocks 100000 --cafxyz-blocks 20000 --repeat 1
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

import numpy as np


def write_xfyz_program(path: Path, n: int) -> None:
    """Raster over a 200 x 200 mm wavy surface, 1001 points per row, rows 0.2 mm apart."""
    per_row = 1001
    x = np.linspace(-100.0, 100.0, per_row)
    k = np.arange(n)
    row = k // per_row
    col = k % per_row
    xs = np.where(row % 2 == 0, x[col], x[::-1][col])
    ys = -100.0 + 0.2 * (row % 1000)
    zs = 2.0 * np.sin(xs / 20.0) * np.cos(ys / 25.0) - 5.0
    body = "\n".join(f"X{a:.4f} Y{b:.4f} Z{c:.4f}" for a, b, c in zip(xs, ys, zs))
    path.write_text("%\nG21 G90 G17\nG0 X-100 Y-100 Z10\nG1 Z-5 F1500\n" + body + "\nG0 Z50\nM30\n%\n")


def write_cafxyz_program(path: Path, n: int) -> None:
    """5-axis: C sweeps -300..300 deg and back, A between 20 and 40 deg, tip on a slow spiral."""
    k = np.arange(n)
    s = k / max(n - 1, 1)
    c = 300.0 * np.sin(2 * math.pi * 3 * s)
    a = 30.0 + 10.0 * np.sin(2 * math.pi * 17 * s)
    r = 40.0 + 30.0 * s
    x = r * np.cos(2 * math.pi * 50 * s)
    y = r * np.sin(2 * math.pi * 50 * s)
    z = 20.0 + 5.0 * np.sin(2 * math.pi * 40 * s)
    body = "\n".join(f"X{p:.4f} Y{q:.4f} Z{w:.4f} A{u:.4f} C{v:.4f}"
                     for p, q, w, u, v in zip(x, y, z, a, c))
    path.write_text("%\nG21 G90\nG0 X40 Y0 Z60 A30 C0\nG1 F2000\n" + body + "\nG0 Z80\nM30\n%\n")


def write_model(path: Path, machine_name: str, seed: int = 7) -> None:
    from mtcomp import load_machine
    from mtcomp.models import ErrorModel, FittedModel, save_model
    unit_scale = {"um": 10e-3, "urad": 20e-6, "mm": 50.0, "1": 0.05}
    model = ErrorModel(load_machine(machine_name))
    fitted = FittedModel.zero(model)
    rng = np.random.default_rng(seed)
    fitted.params.values[:] = rng.normal(size=model.n_params) * np.array(
        [unit_scale[s.unit] for s in model.param_specs])
    save_model(path, fitted)


def write_identified_model(path: Path, seed: int = 2026) -> None:
    """MODEL.json as a user has it: the one ``mtcomp demo`` compensates with (its steps 1 and 3:
    a small simulated campaign on the xfyz machine with a hidden backlash of X, diagnosed into
    the extended model: penalised B-splines, 274 parameters, a covariance and a support region).
    About 10-20 s; the campaign's CSV files are written beside ``path``."""
    from mtcomp import load_machine
    from mtcomp.demo import DemoResult, _diagnose_campaign, _simulate
    folder = Path(path).parent / "identified"
    (folder / "campaign").mkdir(parents=True, exist_ok=True)
    machine = load_machine("xfyz")
    res = DemoResult(folder)
    _, datasets = _simulate(machine, np.random.default_rng(seed), folder / "campaign", res,
                            lambda *a: None)
    _diagnose_campaign(machine, datasets, folder, res, lambda *a: None)
    (folder / "MODEL.json").replace(path)


def write_identified_model_apart(path: Path) -> None:
    """:func:`write_identified_model` in a subprocess: the identification's memory (about 250 MB)
    then counts neither in this process's peak nor in its later subprocesses' (on Linux a child's
    ru_maxrss starts from its parent's size at the fork)."""
    here = str(Path(__file__).resolve().parent)
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (env.get("PYTHONPATH"), here) if p)
    subprocess.run([sys.executable, "-c", "import sys; from pathlib import Path; "
                    "from bench_compensate import write_identified_model; "
                    "write_identified_model(Path(sys.argv[1]))", str(path)], check=True, env=env)


def run(cmd: list[str], env=None) -> tuple[float, float, float, int]:
    """(wall s, cpu s, peak rss MB, exit code) of one subprocess."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            env=None if env is None else {**os.environ, **env})
    _, status, ru = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    err = proc.stderr.read().decode()
    proc.stderr.close()
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({proc.returncode}): {err}")
    return wall, ru.ru_utime + ru.ru_stime, ru.ru_maxrss / 1024.0, proc.returncode


def measure(cmd, repeat, env=None):
    run(cmd, env)                     # warm-up (compiles the model functions into the cache)
    runs = [run(cmd, env) for _ in range(repeat)]
    return (statistics.median(r[0] for r in runs), statistics.median(r[1] for r in runs),
            max(r[2] for r in runs))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--xfyz-blocks", type=int, default=1_000_000)
    ap.add_argument("--cafxyz-blocks", type=int, default=200_000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--methods", default="qp,pinv,newton")
    args = ap.parse_args(argv)
    py = sys.executable
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for name, n, writer in (("xfyz", args.xfyz_blocks, write_xfyz_program),
                                ("cafxyz", args.cafxyz_blocks, write_cafxyz_program)):
            if n <= 0:
                continue
            prog, model, out = tmp / f"{name}.nc", tmp / f"{name}.json", tmp / f"{name}_out.nc"
            writer(prog, n)
            write_model(model, name)
            rt = [py, "-c", "import sys; from mtcomp import load_machine; "
                  "from mtcomp.toolpaths import write_corrected; "
                  "write_corrected(sys.argv[1], sys.argv[2], load_machine(sys.argv[3]), None)",
                  str(prog), str(tmp / "rt.nc"), name]
            base = measure(rt, args.repeat)
            rows.append((name, n, "read+write", *base, 1.0, 1.0))
            runs = [(m, ["--method", m], None) for m in args.methods.split(",")]
            runs += [("qp 1 thread", ["--method", "qp"], {"MTCOMP_THREADS": "1"}),
                     ("qp+report", ["--report", str(tmp / "blocks.csv")], None)]
            for what, extra, env in runs:
                cmd = [py, "-m", "mtcomp", "compensate", name, str(model), str(prog), "-o", str(out),
                       "--quiet", *extra]
                res = measure(cmd, args.repeat, env)
                rows.append((name, n, what, *res, res[0] / base[0], res[1] / base[1]))
    print(f"{'machine':8s} {'blocks':>9s} {'what':12s} {'wall s':>8s} {'cpu s':>8s} {'peak MB':>8s} "
          f"{'x r+w':>6s} {'cpu x':>6s}")
    for name, n, what, wall, cpu, mb, ratio, cpu_ratio in rows:
        print(f"{name:8s} {n:9d} {what:12s} {wall:8.2f} {cpu:8.2f} {mb:8.0f} {ratio:6.1f} "
              f"{cpu_ratio:6.1f}")
    print(f"(median of {args.repeat} runs after a warm-up; cpu = user + sys of the subprocess; "
          f"{os.cpu_count()} cpus, load average {os.getloadavg()[0]:.1f})")


if __name__ == "__main__":
    main()

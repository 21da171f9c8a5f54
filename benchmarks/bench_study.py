"""`mtcomp study` on Dask: tasks per second with 1 and 2 local workers, and the scheduler's own cost
per task, from which the task size at which 100 workers stay busy.

    python benchmarks/bench_study.py [--tasks 16] [--blocks 50000] [--repeats 3]

1. A study of ``--tasks`` tasks (one raster program of about ``--blocks`` blocks, an xfyz model with a
   covariance, draws of it) is run by :func:`mtcomp.study.run_study` into a fresh folder, on a
   LocalCluster of 1 and of 2 worker processes, ``--repeats`` times each: the wall time of the whole
   run (cluster start and stop included) and the tasks per second after the first task of each
   worker (the steady state). Medians are printed, and the ratio 2 workers / 1 worker.
2. The scheduler's cost per task: 2,000 tasks that do nothing, mapped on a LocalCluster of 2
   workers; the wall time per task is what the scheduler and the transport cost. A cluster of W
   workers stays busy while each task takes longer than W times that cost (the scheduler hands out
   tasks one after the other); the figure printed for 100 workers is that bound, and ten times it
   for a margin.
"""
from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np


def _setup(folder: Path, n_tasks: int, blocks: int) -> Path:
    from mtcomp import load_machine
    from mtcomp.models import ErrorModel, FittedModel, save_model
    machine = load_machine("xfyz").with_basis("polynomial")
    model = ErrorModel(machine)
    fitted = FittedModel.zero(model)
    rng = np.random.default_rng(1)
    scale = np.array([{"um": 10e-3, "urad": 20e-6, "mm": 50.0, "1": 0.05}[s.unit]
                      for s in model.param_specs])
    fitted.params.values[:] = rng.normal(size=model.n_params) * scale
    fitted.uncertainty = {"names": list(fitted.params.names),
                          "covariance": np.diag((0.05 * scale) ** 2),
                          "undetermined": np.zeros((model.n_params, 0))}
    save_model(folder / "MODEL.json", fitted)
    passes = max(blocks // 2, 1)
    dy = 200.0 / passes                       # the raster covers 200 x 200 mm whatever its length
    lines = ["G21 G90", "G0 X0 Y0 Z5", "G1 Z-1 F800"]
    for k in range(passes):
        lines += [f"G1 X{200 if k % 2 == 0 else 0} Y{k * dy:.4f}", f"G1 Y{(k + 1) * dy:.4f}"]
    (folder / "raster.nc").write_text("\n".join(lines + ["G0 Z20", "M30"]) + "\n")
    (folder / "STUDY.toml").write_text(f'machine = "xfyz"\nprograms = ["raster.nc"]\n'
                                       f'models = ["MODEL.json"]\ndraws = {n_tasks - 1}\nseed = 1\n')
    return folder / "STUDY.toml"


def _run(study_path: Path, workers: int, out: Path) -> tuple[float, float]:
    """(wall time of the whole run, steady tasks per second after each worker's first task)."""
    from mtcomp.study import load_study, run_study
    study = load_study(study_path)
    t0 = time.perf_counter()
    result = run_study(study, out, workers=workers, progress=False)
    wall = time.perf_counter() - t0
    bad = [r["error"] for r in result.rows if r["status"] != "ok"]
    if bad or result.computed != len(result.rows):
        raise SystemExit(f"the study did not run as meant: {bad[:1] or 'tasks kept from before'}")
    # steady state: the tasks' own times, spread over the workers, after the first per worker
    seconds = sorted(r["seconds"] for r in result.rows)
    steady = seconds[:len(seconds) - workers] if len(seconds) > workers else seconds
    return wall, workers / statistics.median(steady)


def _scheduler_cost(n: int = 2000) -> float:
    from dask.distributed import Client, LocalCluster, wait
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                      silence_logs=40) as cluster, Client(cluster) as client:
        client.submit(int, 0).result()            # warm up
        best = []
        for _ in range(3):
            t0 = time.perf_counter()
            futures = client.map(int, range(n), pure=False)
            wait(futures)
            best.append((time.perf_counter() - t0) / n)
            del futures
        return statistics.median(best)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tasks", type=int, default=16)
    ap.add_argument("--blocks", type=int, default=50000)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        study = _setup(tmp, args.tasks, args.blocks)
        figures = {}
        for workers in (1, 2):
            walls, rates = [], []
            for k in range(args.repeats):
                wall, rate = _run(study, workers, tmp / f"R{workers}_{k}")
                walls.append(wall)
                rates.append(rate)
            figures[workers] = (statistics.median(walls), statistics.median(rates))
            print(f"{workers} worker{'s' if workers > 1 else ''}: {args.tasks} tasks in "
                  f"{figures[workers][0]:.1f} s (median of {args.repeats}, cluster start included): "
                  f"{args.tasks / figures[workers][0]:.2f} tasks/s; steady {figures[workers][1]:.2f} "
                  "tasks/s")
        print(f"2 workers / 1 worker: {figures[1][0] / figures[2][0]:.2f}x (whole run), "
              f"{figures[2][1] / figures[1][1]:.2f}x (steady)")
    cost = _scheduler_cost()
    print(f"scheduler cost per task (2,000 empty tasks, 2 workers): {cost * 1e3:.2f} ms")
    print(f"100 workers stay busy with tasks longer than {100 * cost:.2f} s "
          f"(with a tenfold margin: {1000 * cost:.1f} s)")


if __name__ == "__main__":
    main()

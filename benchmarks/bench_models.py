"""Poses per second of the error model: compiled C (mtcomp.models.compiled) against CasADi's map.

For the xfyz and cafxyz models, deviation + J_q (what the planner needs per block) and deviation +
J_q + J_p (what identification needs), at 1e4, 1e5 and 1e6 poses, median of --runs runs, one core.
Large batches are evaluated in chunks of --chunk poses so that J_p outputs fit in memory (the rate
includes the chunking). CasADi's map is slow; --map-max caps the largest N it is timed at (the
ratio is then taken at the largest N both were timed at).

    python benchmarks/bench_models.py [--runs 5] [--sizes 1e4 1e5 1e6] [--map-max 1e6]
"""
from __future__ import annotations

import argparse
import os
import time

import numpy as np

from mtcomp import load_machine
from mtcomp.models import ErrorModel, compiled
from mtcomp.models.evaluate import casadi_map_call

FUNCTIONS = {"dev+J_q": "deviation_qjacobian_function", "dev+J_q+J_p": "deviation_jacobian_function"}


def inputs(model, n, seed=0):
    rng = np.random.default_rng(seed)
    lo, hi = model.machine.travel_bounds()
    q = rng.uniform(lo, hi, size=(n, model.machine.n_axes))
    scale = np.array([{"um": 10e-3, "urad": 20e-6}.get(s.unit, 0.0) for s in model.param_specs])
    return q, rng.normal(size=model.n_params) * scale, model.default_context(n)


def rate(evaluate, q, p, c, runs, chunk, best=False):
    """Poses per second of CPU time of this process (median of runs), and of wall time; with
    ``best``, also the best run's CPU nanoseconds per pose.

    CPU time is the single-core figure even on a machine shared with other jobs; wall time shows
    what a user waits when the core is not shared. On a shared machine the CPU time still grows
    with a busy sibling core (shared caches), so the best run is closest to the quiet figure."""
    cpu, wall = [], []
    for _ in range(runs):
        t0, w0 = time.process_time(), time.perf_counter()
        for start in range(0, len(q), chunk):
            evaluate(q[start:start + chunk], p, c[start:start + chunk])
        cpu.append(time.process_time() - t0)
        wall.append(time.perf_counter() - w0)
    rates = len(q) / float(np.median(cpu)), len(q) / float(np.median(wall))
    return rates + (float(np.min(cpu)) / len(q) * 1e9,) if best else rates


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--sizes", type=float, nargs="+", default=[1e4, 1e5, 1e6])
    ap.add_argument("--machines", nargs="+", default=["xfyz", "cafxyz"])
    ap.add_argument("--map-max", type=float, default=1e6, help="largest N timed with CasADi's map")
    ap.add_argument("--map-max-jp", type=float, default=1e5,
                    help="largest N timed with CasADi's map for dev+J_q+J_p (it runs ~6e3 poses/s)")
    ap.add_argument("--chunk", type=int, default=100_000)
    args = ap.parse_args()
    print(f"CPU: {os.cpu_count()} logical cores; single-threaded evaluation; median of {args.runs} runs")
    print("rates in poses per second of CPU time (wall-clock rate in brackets)")
    print(f"{'machine':8s} {'outputs':12s} {'N':>9s} {'compiled/s':>22s} {'casadi map/s':>22s} {'ratio':>6s}"
          f" {'compiled ns/pose (best run)':>28s}")
    for mname in args.machines:
        model = ErrorModel(load_machine(mname))
        for label, fname in FUNCTIONS.items():
            function = getattr(model, fname)
            t0 = time.perf_counter()
            comp = compiled.get_compiled(model, fname, function)
            setup = time.perf_counter() - t0
            map_max = args.map_max_jp if "J_p" in label else args.map_max
            for size in args.sizes:
                n = int(size)
                q, p, c = inputs(model, n)
                comp(q[:10], p, c[:10])  # warm-up (page in the library)
                r_comp, w_comp, ns_best = rate(comp, q, p, c, args.runs, args.chunk, best=True)
                if n <= map_max:
                    r_map, w_map = rate(lambda a, b, d: casadi_map_call(function, a, b, d), q, p, c,
                                        args.runs, args.chunk)
                    text = f"{r_map:10.3e} ({w_map:9.3e}) {r_comp / r_map:6.1f}"
                else:
                    text = f"{'(skipped)':>22s} {'':>6s}"
                print(f"{mname:8s} {label:12s} {n:9d} {r_comp:10.3e} ({w_comp:9.3e}) {text} {ns_best:28.1f}",
                      flush=True)
            print(f"{mname:8s} {label:12s} code generation + compile (or cache load): {setup:.2f} s")


if __name__ == "__main__":
    main()

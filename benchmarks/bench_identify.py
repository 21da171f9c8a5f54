"""Benchmark of identify(): a 3-axis fit of 100,000 points and a 5-axis fit of 20,000 points.

Prints, per case, the wall time of one identify() call (median of 5 runs after one warm-up run that
also compiles the model's C code when a compiler is there), its processor time (all threads of the
process: on a shared machine the wall time also counts the waits for a core; the fit runs BLAS on
one thread), the Gauss-Newton iterations, the number of observations and unknowns, and the rms
residual against the simulated noise (0.5 um). The data
come from mtcomp's own simulator (a speed figure; accuracy is checked on the independent machine,
bench_identify_independent.py); the fitted model's knots are chosen from the data, as a user's are.
The first line names the package that ran (the one on the path).

    python benchmarks/bench_identify.py [--runs 5]
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

import mtcomp
from mtcomp.identification.fit import identify
from mtcomp.machine import load_machine
from mtcomp.models import ErrorModel
from mtcomp.sim import make_points, random_parameters, simulate


def case(machine_name: str, n_points: int, runs: int, rng) -> None:
    machine = load_machine(machine_name)
    model = ErrorModel(machine)
    lo, hi = machine.travel_bounds()
    lo = np.where(np.isin(list(machine.axis_names), list("ABC")), np.maximum(lo, -np.pi), lo)
    hi = np.where(np.isin(list(machine.axis_names), list("ABC")), np.minimum(hi, np.pi), hi)
    q = rng.uniform(lo, hi, (n_points, machine.n_axes))
    tool = rng.choice([0.0, 100.0, 200.0], n_points)
    # q's Z is the ram's machine position, inside its travel: a tool of length L stands its tip at
    # z = Z - (L - L0), L0 the machine's reference tool (docs/conventions.md, "Tool length")
    xyz = q[:, :3].copy()
    xyz[:, 2] -= tool - machine.tool_length
    abc = None
    if machine.n_axes > 3:
        abc = np.zeros((n_points, 3))
        for k, name in enumerate(machine.axis_names[3:]):
            abc[:, "ABC".index(name)] = q[:, 3 + k]
    free = model.base_mask.copy()
    p = random_parameters(model, rng, mask=free)
    data = simulate(model, make_points(xyz, abc, tool=tool), p, noise_um=0.5, rng=rng)
    t0 = time.perf_counter()
    identify(model, [data])
    first = time.perf_counter() - t0
    times, cpu = [], []
    for _ in range(runs):
        t0, c0 = time.perf_counter(), time.process_time()
        res = identify(model, [data])
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    rms = max(res.files[0].rms().values())
    print(f"{machine_name:8s} {n_points:7d} points  {res.n_obs:7d} obs  {res.n_params:3d} unknowns  "
          f"rank {res.rank:3d}  iterations {res.iterations}  median {np.median(times):.3f} s "
          f"(runs {', '.join(f'{t:.3f}' for t in times)}; first {first:.3f} s)  "
          f"processor median {np.median(cpu):.3f} s  "
          f"rms residual {rms:.3f} um (noise 0.5)")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5)
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    print(f"mtcomp from {Path(mtcomp.__file__).parent}")
    case("xfyz", 100_000, args.runs, rng)
    case("cafxyz", 20_000, args.runs, rng)


if __name__ == "__main__":
    main()

"""Hand-made laser files of positioning for tests (the measurement file format of docs/measurements.md)."""
from __future__ import annotations

from pathlib import Path


def write_positioning(path, axis: str, targets, error_um, n_runs: int, noise_um: float, rng) -> Path:
    """Write ``n_runs`` bidirectional runs of the positioning of ``axis`` (E<axis><axis>) at
    ``targets`` (mm): each reading is ``error_um(target, direction)`` plus Gaussian noise of
    ``noise_um``; returns the path."""
    rows = ["axis,component,target_mm,dir,run,value_um"]
    for run in range(1, n_runs + 1):
        for t in targets:
            for d in (1, -1):
                rows.append(f"{axis},E{axis}{axis},{t},{d},{run},"
                            f"{error_um(t, d) + rng.normal(0, noise_um):.4f}")
    Path(path).write_text("\n".join(rows) + "\n")
    return Path(path)


def write_x_positioning(path, targets, error_um, n_runs: int, noise_um: float, rng) -> Path:
    """:func:`write_positioning` of X."""
    return write_positioning(path, "X", targets, error_um, n_runs, noise_um, rng)


def xz_lasers(folder) -> list[str]:
    """Laser runs of X and Z alone on the independent truth machine (positioning and both
    straightnesses, one run of 9 targets, noise 0.1 um): X on the line Y = 0, Z = 0, Z on X = 0,
    Y = 0; Y never moved. X's positioning 20 um/m and pitch 30 urad over its travel. The paths."""
    import numpy as np
    from truth import TruthMachine
    from truth import campaigns as tc
    from truth import profiles as P
    rng = np.random.default_rng(4)
    truth = TruthMachine.zero("xfyz")
    truth.components["X"]["EXX"] = P.Linear(0.0, 20e-6)
    truth.components["X"]["EBX"] = P.Linear(0.0, 30e-6 / 400.0)
    return [str(tc.laser(truth, Path(folder) / f"laser_{a.lower()}.csv", rng, a,
                         components=[f"E{c}{a}" for c in "XYZ"], n_targets=9, n_runs=1,
                         static={b: 0.0 for b in "XYZ" if b != a}, noise_um=0.1).path)
            for a in "XZ"]

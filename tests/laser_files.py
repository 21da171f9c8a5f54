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

"""Real machined plates, one plate left out at a time: how much of a plate's hole position error a
model identified from the other plates predicts.

Data: 20 aluminium plates cut with one program on one Hurco vertical machining centre and measured
on a CMM (NIST Smart Manufacturing Systems Test Bed, tests/data/real/plates/, SOURCES.md there).
The holes' measured centres are in the part's datum frame (the CMM aligned to the part), so the
figure of merit is the error left after a rigid alignment in the plane (3 dof, least squares):

* rigid     the plate's own hole errors (measured - nominal), rigid-aligned: rms in um (of the
            error vector's length, over the plate's 17 holes)
* mtcomp    `mtcomp identify` on the other plates' points files (written from the QIF file by
            examples/qif_holes_to_points.py, each with its fitted set-up, i.e. its CMM alignment),
            `mtcomp predict` for the left-out plate; rigid-aligned rms of (predicted - measured),
            over rigid. With the machine file's travel (examples/hurco_vmx_plates.toml, a
            610 x 508 mm table) and, with ``--travel region``, the travel cut to the plate's region
            (the holes' extent plus 5 mm): the fit judges what the data fix only weakly over the
            region they cover, so the two give the same figures (they differed when it judged over
            the travel: a yaw profile fixed over a 120 mm plate is weak over a 610 mm table)
* cubic     the users' map: per component a full cubic polynomial in (x, y) (10 terms), least
            squares over every hole of the other plates pooled; the same ratio
* mean      the per-hole mean of the other plates' errors (no model: the batch's common pattern,
            hole by hole); the same ratio

and the repeatability of the batch: the rms over its plates of each plate's rigid-aligned error
about the batch's mean pattern, against that pattern's own rigid-aligned rms.

    python benchmarks/bench_plates.py [--batch short|long|operator|all]... [--machine TOML]
                                      [--travel machine|region]...

Default: the batch `short` (plates 1-9, one tool length), the machine's travel. Each left-out plate
costs one `mtcomp identify` and one `mtcomp predict` run per travel (a few seconds on this machine
when it is idle; `--batch short --batch long --batch all` about 2.5 minutes). The fit runs its
algebra on one BLAS thread. Before each plate's CMM frame was judged by the displacement it makes
over its plate (docs/identification.md, *Rank*), the penalty weight REML picked for the angular
profiles lay where its criterion is nearly flat on these data, and BLAS's threading moved a
plate's figure by up to 0.2 and the batch's median by about 0.02.
"""
from __future__ import annotations

import argparse
import csv
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "tests" / "data" / "real" / "plates"
QIF = DATA / "PlateResults_20_samples.QIF"
CONVERTER = ROOT / "examples" / "qif_holes_to_points.py"
MACHINE = ROOT / "examples" / "hurco_vmx_plates.toml"
#: a part point (x, y) is at program (123.175 - x, -2.412 - y) mm (SOURCES.md); top face at z 4.5
PART_TO_PROGRAM = "123.175,-2.412,180"
BATCHES = {"short": range(1, 10), "long": range(10, 19), "operator": range(19, 21),
           "all": range(1, 21)}


def run(args: list[str], cwd: Path) -> str:
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    res = subprocess.run([sys.executable, *args], cwd=cwd, env=env, capture_output=True, text=True)
    if res.returncode != 0:
        raise SystemExit(f"{' '.join(args)} failed:\n{res.stdout}{res.stderr}")
    return res.stdout


def read_points(path: Path, columns=("dx_um", "dy_um")):
    """(n, 2) hole positions in mm and (n, 2) of ``columns`` in um of a points (or PRED) file."""
    with open(path, newline="") as handle:
        rows = list(csv.DictReader(handle))
    xy = np.array([[float(r["x_mm"]), float(r["y_mm"])] for r in rows])
    return xy, np.array([[float(r[c]) for c in columns] for r in rows])


def rigid_aligned_rms(xy: np.ndarray, error_um: np.ndarray) -> float:
    """rms length (um) of ``error_um`` (n, 2) after the least-squares translation and rotation in
    the plane (small angle: the rotations of interest are microradians)."""
    d = xy - xy.mean(axis=0)
    design = np.zeros((2 * len(xy), 3))
    design[0::2, 0] = 1.0
    design[1::2, 1] = 1.0
    design[0::2, 2] = -d[:, 1]
    design[1::2, 2] = d[:, 0]
    b = error_um.reshape(-1)
    coef, *_ = np.linalg.lstsq(design, b, rcond=None)
    r = (b - design @ coef).reshape(-1, 2)
    return float(np.sqrt(np.mean(np.sum(r ** 2, axis=1))))


def cubic_design(xy: np.ndarray, centre: np.ndarray) -> np.ndarray:
    u, v = ((xy - centre) / 50.0).T
    return np.column_stack([u ** i * v ** j for i in range(4) for j in range(4 - i)])


def cubic_prediction(train_xy, train_err, xy):
    centre = train_xy.mean(axis=0)
    coef, *_ = np.linalg.lstsq(cubic_design(train_xy, centre), train_err, rcond=None)
    return cubic_design(xy, centre) @ coef


def mtcomp_prediction(machine: Path, files: dict[int, Path], left_out: int, work: Path):
    others = [str(files[p]) for p in sorted(files) if p != left_out]
    model, pred = work / f"model_{left_out:02d}.json", work / f"pred_{left_out:02d}.csv"
    run(["-m", "mtcomp", "identify", str(machine), *others, "-o", str(model)], work)
    run(["-m", "mtcomp", "predict", str(machine), str(model), str(files[left_out]), "-o", str(pred)],
        work)
    return read_points(pred, ("pred_dx_um", "pred_dy_um"))[1]


def region_machine(machine_toml: Path, xy: np.ndarray, target: Path) -> Path:
    """The machine file with its X and Y travel cut to the holes' extent plus 5 mm (Z to +-5 mm)."""
    lo, hi = xy.min(axis=0) - 5.0, xy.max(axis=0) + 5.0
    travel = {"X": (lo[0], hi[0]), "Y": (lo[1], hi[1]), "Z": (-5.0, 5.0)}
    lines, axis = [], None
    for line in machine_toml.read_text().splitlines():
        if line.startswith("[axes."):
            axis = line[6]
        elif line.startswith("travel_mm") and axis in travel:
            line = f"travel_mm = [{travel[axis][0]:.3f}, {travel[axis][1]:.3f}]"
        lines.append(line)
    target.write_text("\n".join(lines) + "\n")
    return target


def batch_figures(name, plates, files, machines, work):
    """Per left-out plate: the rigid-aligned error and the ratios of mtcomp on each of ``machines``,
    the cubic map and the per-hole mean; returns the medians of the ratios."""
    xy = {p: read_points(files[p])[0] for p in plates}
    err = {p: read_points(files[p])[1] for p in plates}
    if any(not np.array_equal(xy[p], xy[plates[0]]) for p in plates):
        raise SystemExit("the plates' holes differ; the per-hole mean needs the same holes")
    print(f"\nbatch {name}: plates {plates[0]}-{plates[-1]} ({len(plates)}), left out one at a time")
    print(f"{'plate':>6} {'rigid um':>9} " + " ".join(f"{m:>15}" for m in machines)
          + f" {'cubic':>7} {'mean':>7}")
    ratios = []
    for p in plates:
        others = [q for q in plates if q != p]
        rigid = rigid_aligned_rms(xy[p], err[p])
        train_xy = np.vstack([xy[q] for q in others])
        train_err = np.vstack([err[q] for q in others])
        predictions = [mtcomp_prediction(machines[m], {q: files[q] for q in plates}, p, work)
                       for m in machines]
        predictions += [cubic_prediction(train_xy, train_err, xy[p]),
                        np.mean([err[q] for q in others], axis=0)]
        row = [rigid_aligned_rms(xy[p], pred - err[p]) / rigid for pred in predictions]
        ratios.append(row)
        widths = [15] * len(machines) + [7, 7]
        print(f"{p:6d} {rigid:9.2f} " + " ".join(f"{r:{w}.2f}" for r, w in zip(row, widths)),
              flush=True)
    median = np.median(ratios, axis=0)
    print(f"{'median':>6} {np.median([rigid_aligned_rms(xy[p], err[p]) for p in plates]):9.2f} "
          + " ".join(f"{r:{w}.2f}" for r, w in zip(median, widths)))
    pattern = np.mean([err[p] for p in plates], axis=0)
    scatter = np.sqrt(np.mean([rigid_aligned_rms(xy[p], err[p] - pattern) ** 2 for p in plates]))
    common = rigid_aligned_rms(xy[plates[0]], pattern)
    print(f"common pattern (mean of the batch, rigid-aligned) {common:.2f} um; "
          f"plate-to-plate scatter about it {scatter:.2f} um rms")
    return median


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--batch", action="append", choices=sorted(BATCHES))
    parser.add_argument("--machine", type=Path, default=MACHINE, help="machine TOML file")
    parser.add_argument("--travel", action="append", choices=("machine", "region"),
                        help="mtcomp on the machine's travel (default), on the plate's region")
    args = parser.parse_args(argv)
    if not QIF.exists():
        print(f"skipped: {QIF} is absent (the NIST plate data, see tests/data/real/plates)")
        return 0
    with tempfile.TemporaryDirectory(prefix="bench_plates_") as tmp:
        work = Path(tmp)
        run([str(CONVERTER), str(QIF), str(work / "plates"), "--part-to-program", PART_TO_PROGRAM,
             "--top-z", "4.5"], work)
        files = {p: work / "plates" / f"part{p:02d}.csv" for p in range(1, 21)}
        region = region_machine(args.machine, read_points(files[1])[0], work / "region.toml")
        choices = {"machine": ("mtcomp travel", args.machine.resolve()),
                   "region": ("mtcomp region", region)}
        machines = dict(choices[t] for t in (args.travel or ["machine"]))
        medians = {name: batch_figures(name, list(BATCHES[name]), files, machines, work)
                   for name in args.batch or ["short"]}
    print("\nmedian remaining / rigid-aligned error (goal <= 0.75):")
    for name, median in medians.items():
        print(f"  {name:9s} " + "   ".join(f"{label} {r:.2f}" for label, r in
                                          zip([*machines, "cubic map", "per-hole mean"], median)))
    return 0


if __name__ == "__main__":
    sys.exit(main())

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
                                      [--travel machine|region]... [--without-diameter MM]
                                      [--explain]

``--without-diameter 4`` leaves the 4 mm holes out of every plate (with long tools they came out
oversized and their centres scatter from plate to plate). ``--explain`` runs no mtcomp fit and
says what explains the error from plate to plate (a second): each plate's error about the batch's
mean, rms by nominal hole diameter; held out one plate at a time, per-hole predictors that use only
what is known before a plate is measured (a line per hole in the cutting order or in the hours
since the first plate or the day's first plate was started, from the machine's logs; the mean of
the plates cut with the same tool length, speed or feed, plate_setups.csv), on every hole and
without the 4 mm holes; and, fitted on the plate itself and so no prediction, the batch's mean with
the plate among the plates averaged and an alignment extended by an isotropic scale (a thermal
expansion) or by every linear map.

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
from datetime import datetime
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


def alignment_design(xy: np.ndarray, kind: str = "rigid") -> np.ndarray:
    """(2n, k) columns of an alignment in the plane at the holes ``xy`` (n, 2) mm, rows x0, y0,
    x1, y1, ...: ``rigid`` a translation and a small rotation (k 3); ``scale`` those and an
    isotropic scale about the holes' centroid (k 4: a thermal expansion of the part or the
    machine); ``affine`` a translation and every linear map (k 6)."""
    d = xy - xy.mean(axis=0)
    columns = [np.tile([1.0, 0.0], len(xy)), np.tile([0.0, 1.0], len(xy))]
    if kind in ("rigid", "scale"):
        columns.append(np.column_stack([-d[:, 1], d[:, 0]]).reshape(-1))
    if kind == "scale":
        columns.append(d.reshape(-1))
    if kind == "affine":
        for reading, along in ((0, 0), (0, 1), (1, 0), (1, 1)):
            column = np.zeros_like(d)
            column[:, reading] = d[:, along]
            columns.append(column.reshape(-1))
    return np.column_stack(columns)


def aligned_residual(xy: np.ndarray, error_um: np.ndarray, kind: str = "rigid") -> np.ndarray:
    """(n, 2) what is left of ``error_um`` (n, 2) after the least-squares alignment ``kind``
    (:func:`alignment_design`; small angle: the rotations of interest are microradians)."""
    design = alignment_design(xy, kind)
    b = error_um.reshape(-1)
    coef, *_ = np.linalg.lstsq(design, b, rcond=None)
    return (b - design @ coef).reshape(-1, 2)


def aligned_rms(xy: np.ndarray, error_um: np.ndarray, kind: str = "rigid") -> float:
    """rms length (um) of ``error_um`` (n, 2) after the least-squares alignment ``kind``."""
    return float(np.sqrt(np.mean(np.sum(aligned_residual(xy, error_um, kind) ** 2, axis=1))))


def rigid_aligned_rms(xy: np.ndarray, error_um: np.ndarray) -> float:
    """rms length (um) of ``error_um`` (n, 2) after the least-squares translation and rotation in
    the plane."""
    return aligned_rms(xy, error_um, "rigid")


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


def drop_holes(path: Path, diameter_mm: float) -> None:
    """Rewrite the points file ``path`` without its holes of nominal diameter ``diameter_mm``."""
    with open(path, newline="") as handle:
        reader = csv.DictReader(handle)
        fields, rows = reader.fieldnames, list(reader)
    with open(path, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=fields)
        writer.writeheader()
        writer.writerows(r for r in rows if float(r["diameter_mm"]) != diameter_mm)


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


#: The plates' cutting order is their number, and these are the starts of their first operation
#: (UTC as logged): the part counter and the time stamps of the machine's MTConnect logs in the
#: NIST test bed's repository (tdp/mtc/PartData/Plate-Hurco04-01of20.txt ... 20of20.txt). The
#: back faces were cut on 2017-02-06 between 12:39 and 14:31, after every plate's first operation.
CUT_START = {1: "2017-02-01T13:59:35", 2: "2017-02-01T14:59:08", 3: "2017-02-01T15:49:42",
             4: "2017-02-01T16:31:27", 5: "2017-02-01T17:42:26", 6: "2017-02-01T18:22:07",
             7: "2017-02-01T18:42:15", 8: "2017-02-01T19:22:03", 9: "2017-02-01T19:41:37",
             10: "2017-02-02T16:30:58", 11: "2017-02-02T16:51:40", 12: "2017-02-02T17:58:54",
             13: "2017-02-02T18:26:37", 14: "2017-02-02T19:03:25", 15: "2017-02-02T19:24:23",
             16: "2017-02-06T10:02:36", 17: "2017-02-06T10:22:19", 18: "2017-02-06T10:48:37",
             19: "2017-02-06T11:16:48", 20: "2017-02-06T11:58:28"}
#: the holes milled with the 1/8 in end mill that came out oversized with long tools
OVERSIZED_DIAMETER_MM = 4.0


def plate_covariates(plates) -> dict[str, dict[int, float]]:
    """What is known of each plate before it is measured: its cutting order, the hours since the
    first plate and since the day's first plate were started (``CUT_START``)."""
    start = {p: datetime.fromisoformat(CUT_START[p]) for p in plates}
    first = min(start.values())
    day_first = {p: min(t for t in start.values() if t.date() == start[p].date()) for p in plates}
    return {"cutting order": {p: float(p) for p in plates},
            "hours since the first plate": {p: (start[p] - first).total_seconds() / 3600.0
                                            for p in plates},
            "hours since the day's first plate": {
                p: (start[p] - day_first[p]).total_seconds() / 3600.0 for p in plates}}


def plate_levels(path: Path = DATA / "plate_setups.csv") -> dict[str, dict[int, str]]:
    """The designed experiment's factors per plate (plate_setups.csv): tool length, cutting speed
    and feed."""
    with open(path, newline="") as handle:
        rows = list(csv.DictReader(handle))
    return {column.replace("_", " "): {int(r["part"]): r[column] for r in rows}
            for column in ("tool_length", "cutting_speed", "feed")}


def per_hole_mean(err, others, plate):
    """The per-hole mean of the ``others`` plates' errors (no model)."""
    return np.mean([err[q] for q in others], axis=0)


def per_hole_line(covariate: dict[int, float]):
    """A predictor: per hole and component, the least-squares line in ``covariate`` through the
    other plates' errors, at the left-out plate's value."""
    def predict(err, others, plate):
        design = np.column_stack([np.ones(len(others)), [covariate[q] for q in others]])
        targets = np.array([err[q].reshape(-1) for q in others])
        coef, *_ = np.linalg.lstsq(design, targets, rcond=None)
        return (np.array([1.0, covariate[plate]]) @ coef).reshape(err[plate].shape)
    return predict


def same_level_mean(level: dict[int, str]):
    """A predictor: the per-hole mean of the other plates cut at the left-out plate's level of a
    factor (of all the others when none was)."""
    def predict(err, others, plate):
        alike = [q for q in others if level[q] == level[plate]]
        return per_hole_mean(err, alike or others, plate)
    return predict


def held_out_median(xy, err, plates, predict, holes) -> float:
    """Median over ``plates``, each left out in turn, of the rigid-aligned rms of (predicted -
    measured) over its own, on the ``holes`` (index array) only."""
    ratios = []
    for p in plates:
        pred = predict(err, [q for q in plates if q != p], p)
        ratios.append(rigid_aligned_rms(xy[holes], (pred - err[p])[holes])
                      / rigid_aligned_rms(xy[holes], err[p][holes]))
    return float(np.median(ratios))


def _read_batch(plates, files):
    """The holes (n, 2) mm, their nominal diameters (n,) mm and each plate's errors (n, 2) um."""
    with open(files[plates[0]], newline="") as handle:
        diameter = np.array([float(r["diameter_mm"]) for r in csv.DictReader(handle)])
    xy = read_points(files[plates[0]])[0]
    return xy, diameter, {p: read_points(files[p])[1] for p in plates}


def _print_scatter(name, plates, xy, diameter, err):
    pattern = np.mean([err[p] for p in plates], axis=0)
    deviation = np.array([aligned_residual(xy, err[p] - pattern) for p in plates])
    print(f"\nbatch {name}: plates {plates[0]}-{plates[-1]}; each plate's error about the batch's "
          f"mean pattern, rigid-aligned, rms over the plates by nominal hole diameter:")
    for d in np.unique(diameter):
        sel = diameter == d
        rms = np.sqrt(np.mean(np.sum(deviation[:, sel] ** 2, axis=2)))
        print(f"  {d:5.1f} mm ({sel.sum():2d} holes) {rms:6.1f} um")
    return pattern


def explain_batch(name, plates, files):
    """What explains the plates' error from plate to plate: the scatter by hole diameter, the
    held-out figure of per-hole predictors that use only what is known before a plate is measured,
    and, not predictions, what fits on the plate itself leave."""
    xy, diameter, err = _read_batch(plates, files)
    pattern = _print_scatter(name, plates, xy, diameter, err)
    every, others = np.arange(len(xy)), np.flatnonzero(diameter != OVERSIZED_DIAMETER_MM)
    predictors = {"per-hole mean of the other plates": per_hole_mean}
    predictors |= {f"per-hole line in {k}": per_hole_line(v)
                   for k, v in plate_covariates(plates).items()}
    predictors |= {f"mean of the plates at the same {k}": same_level_mean(v)
                   for k, v in plate_levels().items()}
    print(f"held out, median remaining / rigid-aligned error {'all holes':>14} "
          f"{'without ' + f'{OVERSIZED_DIAMETER_MM:g}' + ' mm':>12}")
    for label, predict in predictors.items():
        figures = [held_out_median(xy, err, plates, predict, h) for h in (every, others)]
        print(f"  {label:50s} {figures[0]:9.2f} {figures[1]:12.2f}")
    rigid = {p: rigid_aligned_rms(xy, err[p]) for p in plates}
    fits = {"the batch's mean pattern, the plate among them":
            [rigid_aligned_rms(xy, err[p] - pattern) / rigid[p] for p in plates]}
    fits |= {f"an alignment with {label}":
             [aligned_rms(xy, err[p], kind) / rigid[p] for p in plates] for kind, label in (("scale", "an isotropic scale"), ("affine", "every linear map"))}
    print("fitted on the plate itself (no prediction), median remaining / rigid-aligned error:")
    for label, ratios in fits.items():
        print(f"  {label:50s} {np.median(ratios):9.2f}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--batch", action="append", choices=sorted(BATCHES))
    parser.add_argument("--machine", type=Path, default=MACHINE, help="machine TOML file")
    parser.add_argument("--travel", action="append", choices=("machine", "region"),
                        help="mtcomp on the machine's travel (default), on the plate's region")
    parser.add_argument("--explain", action="store_true",
                        help="what explains the error from plate to plate (no mtcomp runs)")
    parser.add_argument("--without-diameter", type=float, metavar="MM",
                        help="leave out the holes of this nominal diameter (e.g. 4)")
    args = parser.parse_args(argv)
    if not QIF.exists():
        print(f"skipped: {QIF} is absent (the NIST plate data, see tests/data/real/plates)")
        return 0
    with tempfile.TemporaryDirectory(prefix="bench_plates_") as tmp:
        work = Path(tmp)
        run([str(CONVERTER), str(QIF), str(work / "plates"), "--part-to-program", PART_TO_PROGRAM,
             "--top-z", "4.5"], work)
        files = {p: work / "plates" / f"part{p:02d}.csv" for p in range(1, 21)}
        for path in files.values() if args.without_diameter is not None else ():
            drop_holes(path, args.without_diameter)
        if args.explain:
            for name in args.batch or ["short"]:
                explain_batch(name, list(BATCHES[name]), files)
            return 0
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

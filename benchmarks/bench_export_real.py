"""Does a LinuxCNC table exported by mtcomp correct real ISO 230-2 runs it has not seen?

For each real laser file (shared/data/real/iso230_2: ess_b02_x, _y, _z, psi_mcu1025_x; 5 runs each)
runs 1-3 are the training data and runs 4-5 are held out. Three corrections are compared on the
held-out runs:

* raw: no correction;
* pitch table: the classical table built directly from runs 1-3, the mean reading per target and
  direction (what ISO 230-2 calls the mean unidirectional positional deviation), entered as trims;
* mtcomp: `mtcomp identify` (base model) or `mtcomp diagnose` (base model + what it finds, e.g.
  backlash) on a file holding runs 1-3, then `mtcomp export --format linuxcnc`.

A table is applied the way LinuxCNC does it: the trim is interpolated linearly between the table's
nominal positions, from the forward column when the target was approached moving + (dir +1) and the
reverse column otherwise, and added to the command; the corrected reading is reading + trim. The
figure is the rms of the corrected held-out readings about their mean: a new file is a new laser
set-up whose zero no fit can know. When the model file has no 'support' (the region of its data) the
export gets --range from the training targets. Each table is exported whatever its standard error
(``--max-correction-sd-um 0``); a second list gives each table's largest standard error and whether
export writes it at its default limit (the standard error under it, and the table's values told
from zero by it: compensate's rule for a correction).

    python benchmarks/bench_export_real.py [--data DIR]

The real data (a folder holding iso230_2/ess_b02_x.csv ...) are looked for where the tests look
(tests/real_data.py): ``--data DIR``, else ``$MTCOMP_REAL_DATA``, else ``shared/data/real`` beside
the repository. They are not part of the repository (no licence, or the GPL); without them the
script says where it looked and exits with status 1. docs/export.md quotes its output and
tests/test_export_real.py checks those figures against a run.
"""
from __future__ import annotations

import argparse
import contextlib
import csv
import io
import os
import tempfile
from pathlib import Path

import numpy as np

#: the environment variable naming the real-data folder
REAL_ENV = "MTCOMP_REAL_DATA"
#: the shared real-data folder beside the repository (absent on a plain clone)
REAL = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "real"
FILES = ("ess_b02_x", "ess_b02_y", "ess_b02_z", "psi_mcu1025_x")
TRAIN_RUNS = (1, 2, 3)
TEST_RUNS = (4, 5)


def real_data_folder(given: Path | None = None) -> Path:
    """The real-data folder: ``given`` (--data), else $MTCOMP_REAL_DATA, else :data:`REAL`."""
    if given is not None:
        return Path(given)
    return Path(os.environ[REAL_ENV]) if os.environ.get(REAL_ENV) else REAL


def iso230_2_folder_or_exit(given: Path | None = None) -> Path:
    """The folder of the real ISO 230-2 runs; SystemExit(1) saying where it looked when absent."""
    folder = real_data_folder(given) / "iso230_2"
    if not folder.is_dir():
        how = ("--data" if given is not None else f"${REAL_ENV}" if os.environ.get(REAL_ENV)
               else f"the default (neither --data nor ${REAL_ENV} given)")
        raise SystemExit(f"no real ISO 230-2 runs at {folder} (from {how}); the real data are not in "
                         f"the repository: give --data DIR or set {REAL_ENV}=DIR, DIR holding "
                         f"iso230_2/{FILES[0]}.csv ... (default: {REAL})")
    return folder


def read_rows(path: Path) -> list[dict]:
    with open(path, newline="", encoding="utf-8") as f:
        return list(csv.DictReader(f))


def write_rows(path: Path, rows: list[dict]) -> None:
    with open(path, "w", newline="", encoding="utf-8") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


def arrays(rows):
    """(target mm, dir, value um) of the rows."""
    return (np.array([float(r["target_mm"]) for r in rows]), np.array([int(r["dir"]) for r in rows]),
            np.array([float(r["value_um"]) for r in rows]))


def rms_about_mean(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean((x - x.mean()) ** 2)))


def pitch_table_residual(train, test) -> np.ndarray:
    """Corrected held-out readings (um) with the table of per-target, per-direction training means."""
    t_tr, d_tr, v_tr = arrays(train)
    t_te, d_te, v_te = arrays(test)
    out = np.empty_like(v_te)
    for i, (t, d) in enumerate(zip(t_te, d_te)):
        sel = (np.abs(t_tr - t) < 1e-9) & (d_tr == d)
        out[i] = v_te[i] - v_tr[sel].mean()
    return out


def read_comp_file(path: Path):
    """(nominal, forward trim, reverse trim) of a COMP_FILE_TYPE 1 file, read as LinuxCNC does
    (three numbers per line; stop at the first line that is not)."""
    rows = []
    for line in path.read_text().splitlines():
        try:
            vals = [float(v) for v in line.split()]
        except ValueError:
            break
        if len(vals) != 3:
            break
        rows.append(vals)
    a = np.array(rows)
    return a[:, 0], a[:, 1], a[:, 2]


def linuxcnc_residual(comp: Path, test) -> np.ndarray:
    """Corrected held-out readings (um): reading + interpolated trim (mm -> um)."""
    nom, fwd, rev = read_comp_file(comp)
    t, d, v = arrays(test)
    trim = np.where(d > 0, np.interp(t, nom, fwd), np.interp(t, nom, rev))
    return v + trim * 1e3


def mtcomp_table(train_csv: Path, axis: str, how: str, work: Path, grid_mm: float | None = None) -> Path:
    """Fit (identify or diagnose) on ``train_csv`` and export a LinuxCNC table; the comp file's path."""
    from mtcomp.cli import main
    from mtcomp.models.model_file import load_model
    model = work / f"model_{how}.json"
    sink = io.StringIO()
    with contextlib.redirect_stdout(sink), contextlib.redirect_stderr(sink):
        if how == "identify":
            rc = main(["identify", "xfyz", str(train_csv), "-o", str(model)])
        else:
            rc = main(["diagnose", "xfyz", str(train_csv), "--json", str(work / "report.json"),
                       "-o", str(model), "-q"])
        if rc != 0:
            raise RuntimeError(f"mtcomp {how} failed: {sink.getvalue()}")
        extra = []
        if load_model(model).support is None:
            t, _, _ = arrays(read_rows(train_csv))
            extra = ["--range", f"{axis}={t.min():g}:{t.max():g}"]
        if grid_mm is not None:
            extra += ["--grid-mm", f"{grid_mm:g}"]
        out = work / f"linuxcnc_{how}"
        # the table itself, whatever its standard error; and whether export's default limit writes
        # it (its standard error under the limit, and its values told from zero by it)
        rc = main(["export", "xfyz", str(model), "--format", "linuxcnc", "-o", str(out),
                   "--max-correction-sd-um", "0", *extra])
        if rc != 0:
            raise RuntimeError(f"mtcomp export failed: {sink.getvalue()}")
        gated = work / f"linuxcnc_{how}_gated"
        main(["export", "xfyz", str(model), "--format", "linuxcnc", "-o", str(gated), *extra])
    return out / f"{axis.lower()}.comp", (gated / f"{axis.lower()}.comp").exists()


def compare(path: Path, grid_mm: float | None = None) -> dict:
    """Held-out rms (um) of one file: raw, pitch table, mtcomp identify, mtcomp diagnose."""
    rows = read_rows(path)
    axis = rows[0]["axis"]
    train = [r for r in rows if int(r["run"]) in TRAIN_RUNS]
    test = [r for r in rows if int(r["run"]) in TEST_RUNS]
    out = {"file": path.stem, "axis": axis, "n_test": len(test),
           "raw_um": rms_about_mean(arrays(test)[2]),
           "pitch_um": rms_about_mean(pitch_table_residual(train, test))}
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        train_csv = work / f"{path.stem}_runs123.csv"
        write_rows(train_csv, train)
        for how in ("identify", "diagnose"):
            comp, out[f"{how}_written"] = mtcomp_table(train_csv, axis, how, work, grid_mm)
            out[f"{how}_um"] = rms_about_mean(linuxcnc_residual(comp, test))
            out[f"{how}_sd_um"] = largest_sd_um(work / f"model_{how}.json", axis)
    return out


def largest_sd_um(model_path: Path, axis: str) -> float:
    """The largest standard error (um) of the model's table of ``axis`` over the region of its
    data, either direction (what export checks against --max-correction-sd-um), on 201 points."""
    from mtcomp.export._tables import _evaluation_pose, axis_table_sd_um, table_region
    from mtcomp.models.model_file import load_model
    fitted = load_model(model_path)
    machine = fitted.machine
    region, _, _ = table_region(fitted)
    q_ref = _evaluation_pose(machine, region)
    lo, hi = region[axis]
    q = np.tile(q_ref, (201, 1))
    q[:, machine.index(axis)] = np.linspace(lo, hi, 201)
    sd = axis_table_sd_um(fitted, axis, q, q_ref)
    return float("nan") if sd is None else float(sd.max())


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=None,
                    help=f"the real-data folder (holding iso230_2/); default ${REAL_ENV}, else {REAL}")
    ap.add_argument("--grid-mm", type=float, default=None, help="grid step of the exported tables")
    args = ap.parse_args()
    folder = iso230_2_folder_or_exit(args.data)
    print(f"real data: {folder}")
    print("held-out rms (runs 4-5, about their mean), um; tables from runs 1-3")
    print(f"{'file':16s} {'raw':>8s} {'pitch table':>12s} {'mtcomp identify':>16s} "
          f"{'mtcomp diagnose':>16s} {'diagnose/pitch':>15s}")
    from mtcomp.planner.problem import DEFAULT_MAX_CORRECTION_SD_UM as limit
    sds = []
    for name in FILES:
        r = compare(folder / f"{name}.csv", args.grid_mm)
        print(f"{r['file']:16s} {r['raw_um']:8.2f} {r['pitch_um']:12.2f} {r['identify_um']:16.2f} "
              f"{r['diagnose_um']:16.2f} {r['diagnose_um'] / r['pitch_um']:15.2f}")
        sds.append((r["file"], *((r[f"{h}_sd_um"], r[f"{h}_written"]) for h in ("identify", "diagnose"))))
    print(f"largest standard error of each table, um, and whether export writes it at its default "
          f"limit ({limit:g} um; 'left out' over it, or where no value is told from zero by it)")
    for name, *sd in sds:
        print(f"{name:16s} " + "  ".join(f"{how} {v:5.2f} {'written' if w else 'left out'}"
                                         for how, (v, w) in zip(("identify", "diagnose"), sd)))


if __name__ == "__main__":
    main()

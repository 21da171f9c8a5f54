"""A correction study: how much accuracy each bound buys, and how far the compensation can be trusted.

On the virtual machine (an XFYZ machine with random geometric errors of machine-tool size), a
measurement campaign is identified into MODEL.json; a second campaign a while later (the same
machine, new noise: a re-measurement) into MODEL_remeasured.json. A study then compensates bowl
programs at several places on the table (Qi and Yang 2016's bowl) with MODEL.json under five bound
settings and draws of the model from its covariance, judges every compensation with the
re-measurement, and prints, per bound setting, the remaining error (median over programs) and its
spread over the draws. Files: the study's RESULTS/ folder (table, plots, index.html).

Run: python examples/study_bounds.py [--programs 3] [--draws 3] [--workers 2] [--out DIR]
     (the issue's size: --programs 20 --draws 20; default folder: a temporary one)
"""
from __future__ import annotations

import argparse
import contextlib
import csv
import io
import statistics
import tempfile
from pathlib import Path

import numpy as np

from mtcomp import load_machine
from mtcomp.cli import main as mtcomp_main
from mtcomp.identification.fit import identify
from mtcomp.models import save_model
from mtcomp.sim import VirtualMachine, campaign_plans, random_truth
from mtcomp.toolpaths.parts import write_bowl_program

#: bound settings, widest first: (name, max correction um, max step um)
BOUNDS = (("50 um", 50, 5), ("3 um", 3, 0.5), ("2 um", 2, 0.5), ("1 um", 1, 0.25),
          ("0.5 um", 0.5, 0.1))


def _measure(machine, truth, seed: int, out: Path) -> Path:
    """One campaign on the virtual machine, identified; returns the model file."""
    out.mkdir(parents=True, exist_ok=True)
    vm = VirtualMachine(machine, truth, noise_um=0.3, noise_urad=0.5, rng=np.random.default_rng(seed))
    data = vm.campaign(campaign_plans(machine, "small"), out)
    fit = identify(machine, list(data.values()),
                   known_setup=[d.path for d in data.values() if d.kind == "points"])
    path = out / "MODEL.json"
    save_model(path, fit.fitted_model)
    return path


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--programs", type=int, default=3)
    ap.add_argument("--draws", type=int, default=3)
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--out", help="folder for the files (default: a temporary one)")
    args = ap.parse_args(argv)
    machine = load_machine("xfyz").with_basis("polynomial")
    truth = random_truth(machine, np.random.default_rng(2026))
    with tempfile.TemporaryDirectory(prefix="mtcomp-study-") as tmp:
        out = Path(args.out) if args.out else Path(tmp)
        out.mkdir(parents=True, exist_ok=True)
        model = _measure(machine, truth, 1, out / "campaign")
        judge = _measure(machine, truth, 2, out / "remeasured")
        (out / "programs").mkdir(exist_ok=True)
        # bowls spread over the table (the errors change with position)
        rng = np.random.default_rng(7)
        for k in range(args.programs):
            origin = (rng.uniform(-250, 250), rng.uniform(-150, 150), -100.0)
            write_bowl_program(out / "programs" / f"bowl{k + 1:02d}.nc", stepover_mm=2.0,
                               step_mm=2.0, origin_mm=origin)
        bounds = "".join(f'\n[[bounds]]\nname = "{n}"\nmax_correction_um = {c}\nmax_step_um = {s}\n'
                         for n, c, s in BOUNDS)
        (out / "STUDY.toml").write_text(
            f'machine = "xfyz"\nprograms = ["programs/*.nc"]\nmodels = ["{model.relative_to(out)}"]\n'
            f'judge = "{judge.relative_to(out)}"\ndraws = {args.draws}\nseed = 1\n{bounds}')
        log = io.StringIO()
        argv = ["study", str(out / "STUDY.toml"), "-o", str(out / "RESULTS"), "--quiet"]
        if args.workers:
            argv += ["--workers", str(args.workers)]
        with contextlib.redirect_stdout(log), contextlib.redirect_stderr(log):
            rc = mtcomp_main(argv)
        if rc != 0:
            raise SystemExit(log.getvalue())
        print(log.getvalue().splitlines()[0])
        with open(out / "RESULTS" / "results.csv", newline="") as f:
            rows = [r for r in csv.DictReader(f) if r["status"] == "ok"]
        print(f"{len(rows)} tasks; judged with the re-measurement; files in {out}")
        print(f"{'bound setting':<14} {'before um':>10} {'after um':>9} {'draws: min..max um':>19} "
              f"{'bounded %':>10}")
        for name, _, _ in BOUNDS:
            mine = [r for r in rows if r["bounds"] == name]
            model_rows = [r for r in mine if r["draw"] == "0"]
            before = statistics.median(float(r["rms_before_um"]) for r in model_rows)
            after = statistics.median(float(r["rms_after_um"]) for r in model_rows)
            spread = [float(r["rms_after_um"]) for r in mine]
            bounded = 100 * statistics.median(float(r["share_max_correction"]) for r in model_rows)
            print(f"{name:<14} {before:10.3f} {after:9.3f} {min(spread):9.3f}..{max(spread):<9.3f} "
                  f"{bounded:10.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

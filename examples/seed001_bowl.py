"""Qi and Yang (2016): geometric error compensation of the bowl part by the pseudo-inverse (eqs. 27-30).

Replays the experiment of Qi Jibao and Yang Weimin, "Differential Change Construction Based Geometric
Error Compensation for Machine Tools" (2016; docs/references.md) on the virtual machine: an XFYZ machine
with the 21 geometric errors (the squareness errors the paper measured, S_xy = -57.78, S_yz = -29.28,
S_zx = 48.99 urad, and random component errors of machine-tool size) is measured (laser runs and a
volumetric grid), the 21-term model is identified, the bowl program (80 x 80 mm, 13.8 mm deep, ball end
of radius 3 mm) is compensated block by block with the paper's pseudo-inverse
(``mtcomp compensate --method pinv``), both programs are "cut" on the virtual machine and each part is
measured on a CMM at 100 evenly spread points of the bowl surface. The part's datum is the fixture's
zero at the machine origin (the program's coordinates are machine positions, no work offset), probed on
the machine before the cut: the machine's error there is in the probed datum, so both parts are
measured relative to it, and compensate references its corrections to it too. Prints the total error
of both parts, next to the paper's "about 30 % less" (a real cut also carries thermal, force and tool
errors that geometric compensation does not touch; the virtual machine has only geometric errors and
noise, so expect more).

Run: python examples/seed001_bowl.py [--out DIR]   (default: a temporary folder)
"""
from __future__ import annotations

import argparse
import contextlib
import io
import tempfile
from pathlib import Path

import numpy as np

from mtcomp import load_machine
from mtcomp.cli import main as mtcomp_main
from mtcomp.sim import campaign_plans
from mtcomp.identification.fit import identify
from mtcomp.models import save_model
from mtcomp.models.evaluate import deviation
from mtcomp.sim import VirtualMachine, cmm_plan, random_truth
from mtcomp.toolpaths.cutter import read_cut_program
from mtcomp.toolpaths.parts import bowl_normal, bowl_surface, write_bowl_program

BALL_RADIUS_MM = 3.0
#: the squareness Qi and Yang (2016) measured, in mtcomp's names
#: (docs/parameters.md: C0Y = -S_xy, A0Z = S_yz, B0Z = S_zx)
SQUARENESS_URAD = {"C0Y": 57.78, "A0Z": -29.28, "B0Z": 48.99}
#: where the part centre (rim level) sits on the table: off the axis zeros, where errors are larger
ORIGIN_MM = np.array([200.0, 150.0, -100.0])
RASTER_MM = 1.0


def cmm_points(n: int = 10, spacing: float = 8.0):
    """n x n evenly spread points of the bowl surface (workpiece frame, mm) and outward normals.
    They sit on vertices of the tool path, so the chords between path points do not enter."""
    g = (np.arange(n) - (n - 1) / 2) * spacing
    x, y = (a.ravel() for a in np.meshgrid(g, g))
    pts = np.column_stack([x, y, bowl_surface(x, y)]) + ORIGIN_MM
    return pts, bowl_normal(x, y)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", help="folder for the files (default: a temporary one)")
    args = ap.parse_args(argv)
    machine = load_machine("xfyz").with_basis("polynomial")  # the truth is set by polynomial name
    rng = np.random.default_rng(2016)
    truth = random_truth(machine, rng)
    for name, value in SQUARENESS_URAD.items():
        truth.params.set_file_value(name, value)
    vm = VirtualMachine(machine, truth, noise_um=0.3, noise_urad=0.5, rng=rng)
    with tempfile.TemporaryDirectory(prefix="mtcomp-seed001-") as tmp:
        out = Path(args.out) if args.out else Path(tmp)
        out.mkdir(parents=True, exist_ok=True)
        data = vm.campaign(campaign_plans(machine, "small"), out)           # the 21 errors, measured
        # the virtual machine's points are read in the workpiece frame: their set-up is known
        fit = identify(machine, list(data.values()),
                       known_setup=[d.path for d in data.values() if d.kind == "points"])
        save_model(out / "MODEL.json", fit.fitted_model)
        write_bowl_program(out / "bowl.nc", ball_radius_mm=BALL_RADIUS_MM, stepover_mm=RASTER_MM,
                           step_mm=RASTER_MM, origin_mm=ORIGIN_MM)
        log = io.StringIO()
        with contextlib.redirect_stdout(log), contextlib.redirect_stderr(log):
            rc = mtcomp_main(["compensate", "xfyz", str(out / "MODEL.json"), str(out / "bowl.nc"),
                              "-o", str(out / "bowl_pinv.nc"), "--method", "pinv", "--quiet"])
        if rc != 0:
            raise SystemExit(log.getvalue())
        pts, nrm = cmm_points()
        # the true tool-tip deviation at the datum, the machine origin (approach directions unknown)
        datum_error = deviation(truth.model, np.zeros((1, 3)), truth.params.values)[0, :3]
        parts = {}
        for label, program in (("uncompensated", "bowl.nc"), ("compensated", "bowl_pinv.nc")):
            # the CMM measures the part against the nominal surface: the corrections of the
            # compensated program are part of what it cut (include_path_offset)
            cut = read_cut_program(out / program, machine)        # the moves that cut the part
            plan = cmm_plan(pts, nrm, cut, BALL_RADIUS_MM, name=f"cmm_{label}", include_path_offset=True)
            # measured against the part's datum: the machine's error there is in it
            parts[label] = (vm.measure(plan, out / f"cmm_{label}.csv").normal_deviation
                            - nrm @ datum_error) * 1e3                               # um
        print(f"Qi and Yang (2016): bowl 80 x 80 x 13.8 mm, ball end R {BALL_RADIUS_MM:g} mm, "
              f"{len(pts)} CMM points; files in {out}")
        print(f"{'CMM, deviation along the normal':<34} {'uncompensated':>14} {'compensated':>12}")
        b, a = parts["uncompensated"], parts["compensated"]
        rows = (("total error, sum |dn| (um)", np.sum(np.abs(b)), np.sum(np.abs(a))),
                ("mean |dn| (um)", np.mean(np.abs(b)), np.mean(np.abs(a))),
                ("rms (um)", np.sqrt(np.mean(b ** 2)), np.sqrt(np.mean(a ** 2))),
                ("max |dn| (um)", np.max(np.abs(b)), np.max(np.abs(a))))
        for label, vb, va in rows:
            print(f"{label:<34} {vb:14.2f} {va:12.2f}")
        print(f"total error reduced by {100 * (1 - rows[0][2] / rows[0][1]):.0f} % "
              f"(paper: about 30 % on a real cut)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

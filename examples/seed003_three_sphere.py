"""Tan et al. (2026): the five position-dependent errors of a C axis by three-sphere intersection.

Replays the experiment of Tan Zhi, Wang Peilü, Liu Chunshi et al., "Geometric error identification
method for rotary axes based on three-sphere intersection positioning principle" (2026;
docs/references.md) on the virtual machine: a CAFXYZ double turntable whose C axis has radial,
axial and tilt error motions. A 100 mm ball bar runs from a table ball on the C axis, at 100 mm and
200 mm above the table, to a tool ball along X, Y and Z; only C moves (every 10 deg, both ways,
3 repeats). Per angle the three bar lengths locate the table ball (eqs. 10-14 after trilateration),
two heights give the actual axis line and the five errors EXC, EYC, EZC, EAC, EBC. As in the paper the
identified errors then predict where the centre of the C table face goes at each angle (eq. 9 and
eq. 15); the paper reports a prediction error of 0.3 um mean and 0.78 um max. On the virtual machine
the "measured" position is the truth's.

Run: python examples/seed003_three_sphere.py [--out DIR]   (default: a temporary folder)
"""
from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from mtcomp import load_machine
from mtcomp.identification.seed_methods import (predict_table_point, prediction_error,
                                                table_point_positions, three_sphere_errors,
                                                three_sphere_points)
from mtcomp.models import RotaryErrorMotion
from mtcomp.sim import VirtualMachine, random_truth, three_sphere_plan

H1, H2, BAR = 100.0, 200.0, 100.0   # mm
COMPONENTS = ("EXC", "EYC", "EZC", "EAC", "EBC")


def make_truth(machine, rng):
    """Random rotary-axis errors (C and A location, angular positioning) plus error motions of the C
    axis of the size the paper shows (radial ~ 10-40 um, tilt ~ 20-50 urad). The linear axes and the
    tool are error-free: the paper compensated the linear axes before measuring."""
    terms = tuple(RotaryErrorMotion(c, order=3) for c in COMPONENTS)
    truth = random_truth(machine, rng, terms=terms)
    for i, spec in enumerate(truth.params.specs):
        if spec.group.split(":")[0] in ("X", "Y", "Z", "squareness", "tool"):
            truth.params.values[i] = 0.0
    # random_truth draws the location and the first harmonic that turns against the table (EXC_c1,
    # EXC_s1 move EXC and EYC together; the one turning with it is the location); harmonics 2, 3 here
    for name, value in {"EXC_c2": 18.0, "EXC_s2": 6.0, "EYC_c2": -5.0, "EYC_s2": 15.0,
                        "EXC_c3": 3.0, "EYC_s3": -2.5, "EZC_c1": 1.5, "EZC_s2": 0.8,
                        "EAC_c2": 25.0, "EAC_s2": -10.0, "EBC_c2": 12.0, "EBC_s2": 30.0}.items():
        truth.params.set_file_value(name, value)
    return truth


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", help="folder for the simulated files (default: a temporary one)")
    args = ap.parse_args(argv)
    machine = load_machine("cafxyz")
    rng = np.random.default_rng(2025)
    truth = make_truth(machine, rng)
    vm = VirtualMachine(machine, truth, noise_um=0.3, rng=rng)   # ball-bar noise, um
    plan = three_sphere_plan(machine, bar_mm=BAR, heights_mm=(H1, H2), n_runs=3)
    with tempfile.TemporaryDirectory(prefix="mtcomp-seed003-") as tmp:
        out = Path(args.out) if args.out else Path(tmp)
        out.mkdir(parents=True, exist_ok=True)
        data = vm.measure(plan, out / "three_sphere.csv")
        pts = three_sphere_points(data, machine)              # trilateration per (height, angle)
        lo, hi = pts.height == H1, pts.height == H2
        angles = pts.angle[lo]
        if not np.allclose(angles, pts.angle[hi], rtol=0, atol=1e-12):
            raise SystemExit("the two heights were measured at different angles")
        errors = three_sphere_errors(pts.point[lo], pts.point[hi], H1, H2)   # eqs. 10-14
        centre = np.zeros(3)                                   # centre of the C table face
        predicted = predict_table_point(errors, angles, centre)              # eq. 9 (as eq. 5)
        actual = table_point_positions(truth, angles, centre)               # the truth
        d_um = 1e3 * prediction_error(predicted, actual)                    # eq. 15
        print(f"Tan et al. (2026): ball bar {BAR:g} mm at heights {H1:g} and {H2:g} mm, {angles.size} C "
              f"angles, {len(data)} readings; file in {out}")
        print(f"{'identified error':<18} {'min':>9} {'max':>9}  unit")
        for k in COMPONENTS:
            scale, unit = (1e3, "um") if k[1] in "XYZ" else (1e6, "urad")
            print(f"{k:<18} {errors[k].min() * scale:9.2f} {errors[k].max() * scale:9.2f}  {unit}")
        print()
        print(f"{'prediction error of the table centre (eq. 15)':<48} {'mtcomp':>8} {'paper':>7}")
        print(f"{'mean (um)':<48} {np.mean(d_um):8.3f} {0.3:7.2f}")
        print(f"{'max (um)':<48} {np.max(d_um):8.3f} {0.78:7.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

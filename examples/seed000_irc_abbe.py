"""Yang et al. (2020): Abbe positioning error about the worktable's instantaneous rotation centre (IRC).

Replays the experiment of Hong-Tao Yang, Li Li, Yong-Jun Pang and Bang-Shen Chen, "Abbe Positioning
Error Modeling and Compensation of CNC Machine Tools Based on Instantaneous Rotation Center" (2020;
docs/references.md) on the virtual machine: the X axis of an XFYZ machine moves 200 mm in 5 mm
steps, 3 runs at 180, 240 and 300 mm/min. A laser reads the positioning error at the point B (yaw Abbe
arm 210 mm, pitch arm 100 mm from the scale) and the yaw and pitch angles; two velocity sensors at M
and N give the IRC (eq. 1). The positioning error at B is compensated twice:

* traditionally, with the nominal arms (eq. 4 with Y_B = 210 mm, Z_B = 100 mm);
* about the IRC: the yaw arm is measured from O_p instead (eqs. 2-4).

The virtual machine's truth turns its table about a centre that moves with position and feed (the
:class:`~mtcomp.models.AbbeIRC` term) and its yaw grows with feed, as the paper observed.
Prints the positioning error (range of the mean error over the 200 mm, ISO 230-2 style) before and
after each compensation, and how much more the IRC compensation removes, next to the paper's
0.81, 1.12 and 1.18 um.

Run: python examples/seed000_irc_abbe.py [--out DIR]   (default: a temporary folder)
"""
from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from mtcomp import load_machine
from mtcomp.identification.seed_methods import irc_from_velocities
from mtcomp.models import AbbeIRC
from mtcomp.sim import VirtualMachine, iso230_2_plan, random_truth, velocity_plan

FEEDS = (180.0, 240.0, 300.0)              # mm/min
PAPER_GAIN_UM = {180.0: 0.81, 240.0: 1.12, 300.0: 1.18}
ARM_YAW_MM, ARM_PITCH_MM = 210.0, 100.0    # traditional Abbe offsets of the point B


def make_truth(machine, rng):
    """Random base errors, plus a yaw of the X table about a centre that moves with s and feed."""
    irc = AbbeIRC("X", angles="C", static=True, position=True, feed=True, angle_gain=True)
    truth = random_truth(machine, rng, terms=(irc,))
    for name, value in {"EXX_1": 1.0, "EXX_2": 0.0, "EXX_3": 0.0,       # um at 1 m: a small
                        "ECX_1": 45.0, "ECX_2": -60.0, "ECX_3": 30.0,   # scale error; yaw, urad
                        "IRC_CX_x0": 40.0, "IRC_CX_y0": 30.0,           # centre, mm
                        "IRC_CX_y_s": -50.0,                            # mm per m of travel
                        "IRC_CX_y_f": 120.0, "IRC_CX_x_f": 60.0,        # mm per m/min of feed
                        "AG_CX": 0.8}.items():                          # yaw gain per m/min
        truth.params.set_file_value(name, value)
    return truth


def mean_by_target(target, value, keep, average=np.mean):
    t = np.round(target[keep], 6)
    u = np.unique(t)
    return u, np.array([average(value[keep][t == k]) for k in u])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", help="folder for the simulated files (default: a temporary one)")
    args = ap.parse_args(argv)
    machine = load_machine("xfyz").with_basis("polynomial")  # the truth is set by polynomial name
    rng = np.random.default_rng(2020)
    vm = VirtualMachine(machine, make_truth(machine, rng), noise_um=0.05, noise_urad=0.1, rng=rng,
                        noise_velocity_mm_min=1e-5)
    start = -300.0
    targets = start + np.arange(0.0, 200.0 + 1e-9, 5.0)           # 41 positions
    plans = [iso230_2_plan(machine, "X", targets, n_runs=3, components=("EXX", "ECX", "EBX"),
                           optic_mm=(0.0, ARM_YAW_MM, ARM_PITCH_MM), feed_mm_min=f,
                           name=f"laser_x_{int(f)}") for f in FEEDS]
    plans.append(velocity_plan(machine, "X", start_mm=start, length_mm=200.0, step_mm=5.0, n_runs=3,
                               feeds_mm_min=FEEDS))
    with tempfile.TemporaryDirectory(prefix="mtcomp-seed000-") as tmp:
        out = Path(args.out) if args.out else Path(tmp)
        out.mkdir(parents=True, exist_ok=True)
        data = vm.campaign(plans, out)
        vel = data["velocity"]
        print(f"Yang et al. (2020): X axis, 200 mm in 5 mm steps, 3 runs per feed; files in {out}")
        print(f"{'feed':>8} {'IRC y_Op':>14} {'error':>8} {'trad.':>8} {'IRC':>8} "
              f"{'trad. gain':>11} {'IRC gain':>9} {'IRC - trad.':>12} {'paper':>6}")
        print(f"{'mm/min':>8} {'mm (min..max)':>14} {'um':>8} {'um':>8} {'um':>8} {'um':>11} "
              f"{'um':>9} {'um':>12} {'um':>6}")
        for f in FEEDS:
            las = data[f"laser_x_{int(f)}"]
            up = las.dir > 0                                       # the paper's forward runs
            s, e_b = mean_by_target(las.target, las.value, up & (las.component == "EXX"))
            _, eps_z = mean_by_target(las.target, las.value, up & (las.component == "ECX"))
            _, eps_y = mean_by_target(las.target, las.value, up & (las.component == "EBX"))
            rows = vel.feed == f
            irc = irc_from_velocities(vel.m_xy[rows], vel.m_v[rows], vel.n_xy[rows], vel.n_v[rows],
                                      vel.feed[rows])              # eq. 1, per reading
            pos, y_op = mean_by_target(vel.position[rows], irc[:, 1], np.isfinite(irc[:, 1]),
                                       np.median)  # robust where the yaw rate is near 0
            y_op = np.interp(s, pos, y_op)
            # eq. 4, first row: delta_x = -eps_z * Y_B + eps_y * Z_B, arms from the scale or from O_p
            delta_trad = -eps_z * ARM_YAW_MM + eps_y * ARM_PITCH_MM
            delta_irc = -eps_z * (ARM_YAW_MM - y_op) + eps_y * ARM_PITCH_MM
            rng_um = [1e3 * np.ptp(v) for v in (e_b, e_b - delta_trad, e_b - delta_irc)]
            print(f"{f:8.0f} {np.min(y_op):6.1f}..{np.max(y_op):<6.1f} {rng_um[0]:8.2f} "
                  f"{rng_um[1]:8.2f} {rng_um[2]:8.2f} {rng_um[0] - rng_um[1]:11.2f} "
                  f"{rng_um[0] - rng_um[2]:9.2f} {rng_um[1] - rng_um[2]:12.2f} {PAPER_GAIN_UM[f]:6.2f}")
        print("error: positioning error at B (range of the mean over the 200 mm); trad./IRC: after "
              "compensation;\ngain: how much each compensation removes; IRC - trad.: what the IRC "
              "removes beyond the traditional\nmodel (the paper's figure). Simulated, so the "
              "figures depend on the virtual machine's truth.")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Parts cut at several heights, each measured on a CMM in its own alignment, read their heights
only up to their own tilts: the top face's dz in one set-up does not give the tilt of the heights
across the part (the set-up's rx, ry take it, together with the walls' dx and dy along Z, which the
walls read over 8 mm only). Where no file reads heights at two positions of Z in one set-up, the
slopes of X's and Y's straightness in Z are not determined (as for a grid plate alone,
tests/test_plate_tilt_origin.py), and a Z correction away from the part's datum has no standard
error (compensate leaves it), where main gave it a finite one that the truth missed by several.

Oracle: a rigid-body machine in plain numpy (no mtcomp code): table X carrying the part, Y and Z
on the column, small-angle transforms; its heights fall along Y by 8 um/m (a slope of Y's
straightness in Z, which a convention would hold at zero), X pitches by up to 15 urad and bows in
Z, Z lengthens by 6 um/m and leans 20 urad towards +X. Three plates (holes dx, dy at 8 mm depth,
the top face's dz, walls' dx and dy 4 and 12 mm deep), two with their top at Z -200 mm and one at
Z -150 mm, each with a random CMM alignment (5 um, 20 urad) and 0.3 um noise."""
import csv
import re

import numpy as np
import pytest

from mtcomp.cli import main
from mtcomp.models.evaluate import evaluate
from mtcomp.models.model_file import load_model

MACHINE = ('name = "vmc"\ntopology = "XFYZ"\ntool_length_mm = 100.0\n[axes.X]\ntravel_mm = [-400.0, 400.0]\n'
           '[axes.Y]\ntravel_mm = [-250.0, 250.0]\n[axes.Z]\ntravel_mm = [-300.0, 100.0]\n')
PARTS = {"part1": (-300.0, -150.0, -200.0), "part2": (-50.0, -50.0, -200.0), "part3": (200.0, 60.0, -150.0)}


def truth_um(x, y, z):
    """(n, 3) the tool tip's deviation in the table's frame (um) at commanded x, y, z (mm)."""
    x, y, z = (np.asarray(v, dtype=float) for v in np.broadcast_arrays(x, y, z))
    u = x / 400.0
    e_x = np.stack([0 * x, 15e-6 * u, 0 * x], -1)                 # X's pitch (about Y)
    d_x = np.stack([0 * x, 0 * x, -0.003 * u ** 2], -1)          # X's straightness in Z
    tip = np.stack([20e-6 * z, y, z + 8e-6 * y + 6e-6 * z], -1)  # Z leaning, Y's slope, Z's scale
    rel = tip - (np.stack([-x, 0 * x, 0 * x], -1) + d_x)          # the tip less the table's position
    rel = rel - np.cross(e_x, rel)                                # in the turned table's frame
    return (rel - np.stack([x, y, z], -1)) * 1e3


def _part(path, off, rng):
    pts = [(xp, yp, -8.0, "xy") for xp in range(20, 181, 40) for yp in range(20, 141, 40)]
    pts += [(xp, yp, 0.0, "z") for xp in (10, 55, 100, 145, 190) for yp in (10, 80, 150)]
    pts += [(-6.0, yp, zp, "x") for yp in (15, 80, 145) for zp in (-4.0, -12.0)]
    pts += [(xp, -6.0, zp, "y") for xp in (15, 100, 185) for zp in (-4.0, -12.0)]
    P = np.array([p[:3] for p in pts]) + np.array(off)
    c = P.mean(axis=0)
    d = truth_um(*P.T) + rng.normal(0, 5, 3) + np.cross(rng.normal(0, 20e-6, 3), P - c) * 1e3
    d += rng.normal(0, 0.3, d.shape)
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["x_mm", "y_mm", "z_mm", "dx_um", "dy_um", "dz_um"])
        for (_, _, _, k), p, e in zip(pts, P, d):
            w.writerow([f"{v:.3f}" for v in p] + [f"{e[0]:.4f}" if k in ("xy", "x") else "",
                                                  f"{e[1]:.4f}" if k in ("xy", "y") else "",
                                                  f"{e[2]:.4f}" if k == "z" else ""])


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    d = tmp_path_factory.mktemp("parts")
    (d / "vmc.toml").write_text(MACHINE)
    rng = np.random.default_rng(5)
    files = []
    for name, off in PARTS.items():
        _part(d / f"{name}.csv", off, rng)
        files.append(str(d / f"{name}.csv"))
    return d, files


def test_the_slopes_of_the_heights_are_not_determined(fitted, capsys):
    d, files = fitted
    assert main(["identify", str(d / "vmc.toml"), *files, "-o", str(d / "m.json")]) == 0
    out = capsys.readouterr().out
    lines = {m.group(0): ln for ln in out.splitlines()
             for m in [re.search(r"\bE[XYZ]{2}\b", ln)] if m}
    for comp in ("EZX", "EZY"):
        assert "slope not determined by the data" in lines[comp], lines[comp]


def test_a_height_away_from_the_datum_has_no_standard_error(fitted):
    """compensate's standard error of a correction (relative to the part's datum, held combinations
    counted, infinite where it rests on what the data leave open) at 24 points over each part's top
    face: a Z correction there has none. On main they were 0.37 to 0.96 um (median per part) and
    the truth missed 80 % (part 2) and 88 % (part 3) of the corrections by more than two of them
    (up to 5.1 um)."""
    d, files = fitted
    if not (d / "m.json").exists():
        assert main(["identify", str(d / "vmc.toml"), *files, "-o", str(d / "m.json")]) == 0
    fm = load_model(d / "m.json")
    p = np.asarray(fm.params.values, dtype=float)
    xs, ys = np.meshgrid(np.linspace(0.0, 200.0, 5), np.linspace(0.0, 160.0, 5))
    grid = np.c_[xs.ravel(), ys.ravel(), np.zeros(xs.size)][1:]      # the datum itself left out
    for datum in map(np.array, PARTS.values()):
        q = np.vstack([datum, datum + grid])
        ctx = fm.model.default_context(len(q))
        dev = evaluate(fm.model, "deviation_function", fm.clamp(q)[0], p, ctx)[0][:, :3] * 1e3
        J = evaluate(fm.model, "tip_pjacobian_function", fm.clamp(q)[0], p, ctx)[0]
        sd = fm.tip_sd_um(J[1:] - J[:1], fm.covariance_factor(held=True), fm.undetermined_values(),
                          None, fm.choice_directions(), components=True)[:, 2]
        t = truth_um(*q.T)
        miss = np.abs((t[1:, 2] - t[0, 2]) - (dev[1:, 2] - dev[0, 2]))
        assert np.mean(miss > 2.0 * sd) <= 0.05, (datum, miss, sd)
        assert np.isinf(sd).all(), (datum, sd)

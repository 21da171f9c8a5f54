"""A part cut and measured on a CMM (docs/measurements.md), through the command line: the program
that cut it and the ball radius come with --cmm-program / --cmm-tool-radius. The part is cut on the
independent machine (tests/truth), whose Z straightness along X and Y the CMM reads on the floor of
the part."""
from __future__ import annotations

import csv

import numpy as np
import pytest

from mtcomp.cli import main
from truth import TruthMachine
from truth import profiles as P

RADIUS = 3.0
NOISE_UM = 0.1
ROWS = np.arange(-40.0, 40.1, 10.0)


def _cut_and_measure(folder):
    """A zig-zag floor at Z0 cut with a 3 mm ball on an XFYZ machine whose table sags along X and Y
    (EZX, EZY: sines of 4 and 3 um); CMM points on the cut rows, dn = the ball centre's Z error."""
    m = TruthMachine.zero("XFYZ")
    m.components["X"]["EZX"] = P.Sines((4e-3,), (150.0,), (0.3,))
    m.components["Y"]["EZY"] = P.Sines((3e-3,), (120.0,), (1.0,))
    lines = ["G21 G90", f"G0 X-60 Y{ROWS[0]:g} Z5", "G1 Z0 F800"]
    for k, y in enumerate(ROWS):
        if k:
            lines.append(f"G1 Y{y:g}")
        lines.append(f"G1 X{60 if k % 2 == 0 else -60}")
    lines += ["G0 Z5", "M30"]
    program = folder / "floor.nc"
    program.write_text("\n".join(lines) + "\n")
    x, y = (v.ravel() for v in np.meshgrid(np.arange(-55.0, 55.1, 5.0), ROWS))
    q = np.column_stack([x, y, np.zeros_like(x)])
    tip, axis = m.true_pose(q)
    centre = tip + RADIUS * axis
    dn = (centre[:, 2] - RADIUS) * 1e3 + np.random.default_rng(3).normal(0.0, NOISE_UM, x.size)
    part = folder / "floor_cmm.csv"
    with open(part, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["x_mm", "y_mm", "z_mm", "nx", "ny", "nz", "dn_um", "kind"])
        for row in zip(x, y, np.zeros_like(x), np.zeros_like(x), np.zeros_like(x), np.ones_like(x), dn):
            w.writerow([f"{v:.6f}" for v in row] + ["cmm"])
    return program, part, dn


def test_identify_and_predict_a_cut_part_from_the_command_line(tmp_path, capsys):
    program, part, dn = _cut_and_measure(tmp_path)
    model, pred = tmp_path / "model.json", tmp_path / "pred.csv"
    flags = ["--cmm-program", str(program), "--cmm-tool-radius", str(RADIUS)]
    assert main(["identify", "xfyz", str(part), "-o", str(model), *flags]) == 0, capsys.readouterr().err
    assert main(["predict", "xfyz", str(model), str(part), "-o", str(pred),
                 "--cmm-program", f"{part}={program}", "--cmm-tool-radius", f"{part}={RADIUS}"]) == 0
    with open(pred, newline="") as f:
        got = np.array([float(r["pred_dn_um"]) for r in csv.DictReader(f)])
    # the CMM is aligned to the part (a rotation and translation are fitted): the sag beyond a plane is
    # what the model must follow
    A = np.column_stack([np.ones(dn.size), *np.loadtxt(part, delimiter=",", skiprows=1,
                                                       usecols=(0, 1)).T])
    beyond_plane = dn - A @ np.linalg.lstsq(A, dn, rcond=None)[0]
    assert np.std(beyond_plane) > 10 * NOISE_UM
    assert np.sqrt(np.mean((dn - got) ** 2)) < 2 * NOISE_UM


@pytest.mark.parametrize("flags, message", [
    ([], "floor_cmm.csv: a cmm file is read with the G-code that cut the part and the radius of its "
         "ball-end tool: give --cmm-program and --cmm-tool-radius"),
    (["--cmm-program", "{d}/floor.nc"], "give --cmm-tool-radius"),
    (["--cmm-program", "{d}/none.nc", "--cmm-tool-radius", "3"], "--cmm-program {d}/none.nc: no such file"),
    (["--cmm-program", "{d}/floor.nc", "--cmm-tool-radius", "-3"], "the radius must be a positive number"),
    (["--cmm-program", "{d}/floor.nc", "--cmm-tool-radius", "{d}/floor.nc=3"], "is none of the data files"),
    (["--cmm-program", "{d}/floor.nc", "--cmm-tool-radius", "3", "-o", "{d}/floor.nc"],
     "output would overwrite an input file"),
    (["--cmm-program", "{d}/floor.nc", "--cmm-tool-radius", "3", "--cmm-tool-radius", "5"],
     "--cmm-tool-radius 5: {d}/floor_cmm.csv has its tool radius given twice"),
    (["--cmm-program", "{d}", "--cmm-tool-radius", "3"], "a folder, not a G-code file"),
    (["--cmm-program", "{d}/floor_cmm.csv=", "--cmm-tool-radius", "3"], "give the G-code file after '='"),
])
def test_cmm_flags_refused_with_one_line_and_nothing_written(tmp_path, capsys, flags, message):
    program, part, _ = _cut_and_measure(tmp_path)
    flags = [f.format(d=tmp_path) for f in flags]
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    args = ["identify", "xfyz", str(part), *flags]
    if "-o" not in flags:
        args += ["-o", str(tmp_path / "model.json")]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message.format(d=tmp_path) in err and "Traceback" not in err
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before


def test_diagnose_a_clean_cut_part_finds_nothing(tmp_path, capsys):
    """The part's errors are the machine's geometry alone: nothing to name. Held-out points are every
    fifth one of the part (a stretch of rows held out would leave its Y profile undetermined: 15 times
    the noise held out, read as structure)."""
    import json
    program, part, _ = _cut_and_measure(tmp_path)
    report = tmp_path / "report.json"
    assert main(["diagnose", "xfyz", str(part), "--cmm-program", str(program), "--cmm-tool-radius",
                 str(RADIUS), "--json", str(report), "-q"]) == 0, capsys.readouterr().err
    r = json.loads(report.read_text())
    assert r["verdict"] == "none" and r["findings"] == []
    assert r["final"]["heldout_rms_um"] < 1.5 * NOISE_UM


def test_a_wrong_tool_radius_is_noted(tmp_path, capsys):
    """A wall cut with a 3 mm ball at X3 (the wall at X0, normal +X), read with 4 mm: the points lie
    1 mm off the ball-centre path along their normals; identify says so (and fits: not an error)."""
    program = tmp_path / "wall.nc"
    program.write_text("G21 G90\nG0 X3 Y-50 Z5\nG1 Z-5 F400\nG1 Y50\nG0 Z5\nM30\n")
    part = tmp_path / "wall_cmm.csv"
    rows = [f"0,{y:g},-2,1,0,0,{0.05 * np.sin(y / 20):.4f},cmm" for y in np.arange(-45.0, 45.1, 5.0)]
    part.write_text("x_mm,y_mm,z_mm,nx,ny,nz,dn_um,kind\n" + "\n".join(rows) + "\n")
    for radius, noted in (("4", True), ("3", False)):
        assert main(["identify", "xfyz", str(part), "--cmm-program", str(program), "--cmm-tool-radius",
                     radius, "-o", str(tmp_path / f"m{radius}.json")]) == 0
        err = capsys.readouterr().err
        assert ("the points lie a median +1.000 mm off the ball-centre path" in err
                and "is the tool radius 4 mm right (it would be 3 mm)" in err) == noted, err


def test_the_cmm_frame_takes_a_misaligned_part_not_the_machine(tmp_path, capsys):
    """The same part read by a CMM tilted by (20, -15) urad about the points' centroid and shifted
    2 um along Z: the machine's parameters come out the same, the set-up's rotation by the tilt."""
    import json
    program, part, dn = _cut_and_measure(tmp_path)
    xyz = np.loadtxt(part, delimiter=",", skiprows=1, usecols=(0, 1, 2))
    arm = xyz - xyz.mean(axis=0)
    w = np.array([20e-6, -15e-6, 0.0])
    tilted = dn + (np.cross(w, arm)[:, 2] + 2e-3) * 1e3           # n = +z: dn += (w x arm)_z + tz
    moved = tmp_path / "moved" / part.name
    moved.parent.mkdir()
    text = part.read_text().splitlines()
    moved.write_text("\n".join([text[0]] + [",".join(r.split(",")[:6] + [f"{v:.6f}", "cmm"])
                                            for r, v in zip(text[1:], tilted)]) + "\n")
    fits = []
    for f in (part, moved):
        out = f.parent / "m.json"
        assert main(["identify", "xfyz", str(f), "--cmm-program", str(program), "--cmm-tool-radius",
                     str(RADIUS), "-o", str(out)]) == 0, capsys.readouterr().err
        fits.append(json.loads(out.read_text()))
    values = [{k: v["value"] for k, v in m["parameters"].items()} for m in fits]
    assert values[0].keys() == values[1].keys()
    # um, urad: to 1e-3, or to 2 % of its standard error for a profile the part barely sees (its
    # penalty weight, chosen by REML where the criterion is flat, moves it by a few 1e-3 urad)
    sd = {k: v.get("std_error") or 0.0 for k, v in fits[0]["parameters"].items()}
    worst = max(abs(values[0][k] - values[1][k]) / max(1e-3, 0.02 * sd[k]) for k in values[0])
    assert worst < 1.0, worst
    setup = [m["info"]["identify"]["nuisance"] for m in fits]
    d = {k.split(":", 1)[1]: setup[1][k]["value"] - setup[0][k]["value"] for k in setup[0]}
    assert d["setup:rx"] == pytest.approx(20.0, abs=1e-3) and d["setup:ry"] == pytest.approx(-15.0, abs=1e-3)
    assert d["setup:tz"] - d["radius_offset"] == pytest.approx(2.0, abs=1e-3)   # one along the normal


def _zigzag_part(folder, shape, backlash_um):
    """Rows along X cut both ways (zig-zag) with a 3 mm ball over a surface z = f(x) ('slope': 0.3 x,
    'trough': 0.005 x^2) on an XFYZ machine with a backlash of X; CMM points every 5 mm on every row,
    dn = the ball centre's error along the normal (directions as the program approached)."""
    from truth import Backlash, Context
    m = TruthMachine.zero("XFYZ").with_effects(Backlash("X", backlash_um))
    f, df = {"slope": (lambda x: 0.3 * x, lambda x: 0.3 + 0 * x),
             "trough": (lambda x: 0.005 * x * x, lambda x: 0.01 * x)}[shape]
    def normal(x):
        return np.array([-df(x), 0.0, 1.0]) / np.hypot(df(x), 1.0)
    def tip(x, y):
        return np.array([x, y, f(x)]) + RADIUS * normal(x) - [0.0, 0.0, RADIUS]
    rows, xs = np.arange(-40.0, 40.1, 4.0), np.arange(-60.0, 60.1, 2.0)
    lines = ["G21 G90", "G0 X-70 Y-40 Z20"]
    for i, y in enumerate(rows):
        for j, x in enumerate(xs if i % 2 == 0 else xs[::-1]):
            t = tip(x, y)
            lines.append(f"G1 X{t[0]:.4f} Y{t[1]:.4f} Z{t[2]:.4f}" + (" F600" if i == j == 0 else ""))
    program = folder / f"{shape}.nc"
    program.write_text("\n".join(lines + ["G0 Z30", "M30"]) + "\n")
    pts = [(x, y, 1.0 if i % 2 == 0 else -1.0) for i, y in enumerate(rows) for x in np.arange(-50.0, 50.1, 5.0)]
    q = np.array([tip(x, y) for x, y, _ in pts])
    d = np.array([p[2] for p in pts])
    dz = d * np.sign([df(x) for x, _, _ in pts])             # Z follows the surface up or down
    ctx = Context(np.full(len(pts), 600.0), {"X": d, "Y": np.ones(len(pts)), "Z": dz}, np.zeros(len(pts)))
    tip_a, ax_a = m.true_pose(q, None, ctx)
    tip_n, ax_n = m.nominal_pose(q)
    n = np.array([normal(x) for x, _, _ in pts])
    dn = np.einsum("ij,ij->i", (tip_a + RADIUS * ax_a) - (tip_n + RADIUS * ax_n), n) * 1e3
    dn += np.random.default_rng(8).normal(0.0, NOISE_UM, dn.size)
    part = folder / f"{shape}_cmm.csv"
    part.write_text("x_mm,y_mm,z_mm,nx,ny,nz,dn_um,kind\n" + "".join(
        f"{x:.4f},{y:.4f},{f(x):.4f},{nn[0]:.6f},0,{nn[2]:.6f},{v:.4f},cmm\n" for (x, y, _), nn, v in zip(pts, n, dn)))
    return program, part


@pytest.mark.parametrize("shape", ["trough", "slope"])
def test_a_backlash_read_on_a_cut_part(tmp_path, capsys, shape):
    """The reversal of X shows on a cut part where the surface slopes along X. On a trough the slope
    varies, and X's reversal reads otherwise than Z's (which follows the surface up and down): backlash
    on X is named, at its size. On a plane slope the two read alike everywhere: neither is named, the
    report says the data cannot tell X from Z, and the residual stays unexplained."""
    import json
    program, part = _zigzag_part(tmp_path, shape, 8.0)
    report = tmp_path / "r.json"
    assert main(["diagnose", "xfyz", str(part), "--cmm-program", str(program), "--cmm-tool-radius",
                 str(RADIUS), "--json", str(report), "-q"]) == 0, capsys.readouterr().err
    r = json.loads(report.read_text())
    named = [(f["effect"], f["axis"]) for f in r["findings"] if f["effect"] != "unexplained"]
    if shape == "trough":
        assert named == [("backlash", "X")], r["findings"]
        assert r["findings"][0]["params"]["magnitude_um"] == pytest.approx(8.0, abs=0.3)
    else:
        assert named == [] and r["verdict"] == "unexplained", r["findings"]
        assert any(x["axis"] == "X or Z" and "cannot tell which axis" in x["reason"] for x in r["rejected"])


def test_a_part_cut_by_a_compensated_program_is_predicted_with_its_path_offset(tmp_path, capsys):
    """The floor again, cut by a program whose Z carries the corrections (minus the machine's Z error
    at each point): the part comes out flat. With --cmm-path-offset the model fitted to the first part
    predicts that (the program's offset from the nominal surface is part of what it cut); without, it
    predicts the uncompensated error."""
    program, part, dn = _cut_and_measure(tmp_path)
    m = TruthMachine.zero("XFYZ")
    m.components["X"]["EZX"] = P.Sines((4e-3,), (150.0,), (0.3,))
    m.components["Y"]["EZY"] = P.Sines((3e-3,), (120.0,), (1.0,))
    xy = np.loadtxt(part, delimiter=",", skiprows=1, usecols=(0, 1))
    q = np.column_stack([xy, np.zeros(len(xy))])
    ez = m.true_pose(q)[0][:, 2] - q[:, 2]                    # Z error of the tip (mm)
    lines = ["G21 G90", f"G0 X-60 Y{ROWS[0]:g} Z5", "G1 Z0 F800"]
    for k, y in enumerate(ROWS):
        row = np.flatnonzero(xy[:, 1] == y)
        row = row[np.argsort(xy[row, 0])][::1 if k % 2 == 0 else -1]
        lines += [f"G1 X{xy[i, 0]:.4f} Y{y:.4f} Z{-ez[i]:.4f}" for i in row]
    comp = tmp_path / "floor_comp.nc"
    comp.write_text("\n".join(lines + ["G0 Z5", "M30"]) + "\n")
    tip, axis = m.true_pose(q - np.column_stack([0 * xy, ez]))
    flat = (tip + RADIUS * axis)[:, 2] - RADIUS                  # where the compensated cut lands
    assert np.abs(flat * 1e3).max() < 0.01                       # flat to 10 nm: a compensation
    cut = tmp_path / "flat" / part.name
    cut.parent.mkdir()
    text = part.read_text().splitlines()
    cut.write_text("\n".join([text[0]] + [",".join(r.split(",")[:6] + [f"{v * 1e3:.6f}", "cmm"])
                                          for r, v in zip(text[1:], flat)]) + "\n")
    model = tmp_path / "model.json"
    flags = ["--cmm-program", str(program), "--cmm-tool-radius", str(RADIUS)]
    assert main(["identify", "xfyz", str(part), "-o", str(model), "--known-setup", str(part), *flags]) == 0
    got = {}
    for extra in ([], ["--cmm-path-offset"]):
        out = tmp_path / f"pred{len(extra)}.csv"
        assert main(["predict", "xfyz", str(model), str(cut), "-o", str(out), "--cmm-program", str(comp),
                     "--cmm-tool-radius", str(RADIUS), *extra]) == 0, capsys.readouterr().err
        with open(out, newline="") as f:
            got[bool(extra)] = np.array([float(r["pred_dn_um"]) for r in csv.DictReader(f)])
    rms = lambda v: float(np.sqrt(np.mean(v ** 2)))  # noqa: E731
    assert rms(got[True]) < 2 * NOISE_UM < rms(dn) / 5        # the flat part, predicted flat
    assert rms(got[False] - dn) < 2 * NOISE_UM                # without: the uncompensated error

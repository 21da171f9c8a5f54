"""A part cut under a work offset and measured on a CMM in its own frame (the program's): identify,
diagnose and predict take the offset as compensate does (--work-offset, --offsets, G10 L2/L20 in the
program). The oracle is the same cut written without an offset: the program's coordinates and the
CMM's points moved by the offset. The part is cut on the independent machine (tests/truth), whose
table sags along X and Y."""
from __future__ import annotations

import csv

import numpy as np
import pytest

from mtcomp.cli import main
from truth import TruthMachine
from truth import profiles as P

RADIUS = 3.0
OFFSET = np.array([100.0, 50.0, 0.0])        # G54
ROWS = np.arange(-40.0, 40.1, 10.0)


def _floor(folder, name, shift, head=()):
    """The floor program (a zig-zag at Z0, 3 mm ball) with its coordinates moved by ``shift``."""
    dx, dy, _ = shift
    lines = ["G21 G90", *head, f"G0 X{-60 + dx:g} Y{ROWS[0] + dy:g} Z5", "G1 Z0 F800"]
    for k, y in enumerate(ROWS):
        if k:
            lines.append(f"G1 Y{y + dy:g}")
        lines.append(f"G1 X{(60 if k % 2 == 0 else -60) + dx:g}")
    lines += ["G0 Z5", "M30"]
    path = folder / name
    path.write_text("\n".join(lines) + "\n")
    return path


def _cmm(folder, name, dn, x, y, shift):
    path = folder / name
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["x_mm", "y_mm", "z_mm", "nx", "ny", "nz", "dn_um", "kind"])
        for row in zip(x + shift[0], y + shift[1], np.zeros_like(x), np.zeros_like(x), np.zeros_like(x),
                       np.ones_like(x), dn):
            w.writerow([f"{v:.6f}" for v in row] + ["cmm"])
    return path


@pytest.fixture(scope="module")
def cut(tmp_path_factory):
    """The part cut at G54 = (100, 50, 0) on the independent machine: its CMM file in the part's
    frame, and the same cut described at the machine's origin (program and points moved by G54)."""
    d = tmp_path_factory.mktemp("offset")
    m = TruthMachine.zero("XFYZ")
    m.components["X"]["EZX"] = P.Sines((4e-3,), (150.0,), (0.3,))
    m.components["Y"]["EZY"] = P.Sines((3e-3,), (120.0,), (1.0,))
    x, y = (v.ravel() for v in np.meshgrid(np.arange(-55.0, 55.1, 5.0), ROWS))
    q = np.column_stack([x, y, np.zeros_like(x)]) + OFFSET            # where the machine stood
    tip, axis = m.true_pose(q)
    centre = tip + RADIUS * axis
    dn = (centre[:, 2] - RADIUS) * 1e3 + np.random.default_rng(3).normal(0.0, 0.1, x.size)
    return {"dir": d,
            "part": _cmm(d, "part.csv", dn, x, y, np.zeros(3)),
            "g54": _floor(d, "g54.nc", np.zeros(3), head=("G54",)),
            "g10": _floor(d, "g10.nc", np.zeros(3), head=("G10 L2 P1 X100 Y50 Z0", "G54")),
            "moved_part": _cmm(d, "moved.csv", dn, x, y, OFFSET),
            "moved": _floor(d, "moved.nc", OFFSET)}


def _identify(folder, tag, part, program, *flags):
    model = folder / f"{tag}.json"
    assert main(["identify", "xfyz", str(part), "-o", str(model), "--cmm-program", str(program),
                 "--cmm-tool-radius", str(RADIUS), *flags]) == 0
    return model


def _predicted(model, data, column, *flags):
    out = model.with_name(f"{model.stem}_{data.stem}_{len(flags)}_pred.csv")
    assert main(["predict", "xfyz", str(model), str(data), "-o", str(out), *flags]) == 0
    with open(out, newline="") as f:
        return np.array([float(r[column]) for r in csv.DictReader(f)])


def _grid(folder):
    """Points over the region the cut reached on the machine (X 40..160, Y 10..90 mm)."""
    grid = folder / "grid.csv"
    gx, gy = (v.ravel() for v in np.meshgrid(np.arange(50.0, 150.1, 10.0), np.arange(15.0, 85.1, 10.0)))
    grid.write_text("x_mm,y_mm,z_mm,tool_mm,dx_um,dy_um,dz_um\n"
                    + "".join(f"{a:g},{b:g},0,100,0,0,0\n" for a, b in zip(gx, gy)))
    return grid


def test_identify_fits_a_part_cut_under_a_work_offset_as_the_same_cut_at_the_origin(cut):
    d = cut["dir"]
    want = _predicted(_identify(d, "moved", cut["moved_part"], cut["moved"]), _grid(d), "pred_dz_um")
    model = _identify(d, "g54", cut["part"], cut["g54"], "--work-offset", "G54=X100,Y50,Z0")
    got = _predicted(model, _grid(d), "pred_dz_um")
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-2)
    # the sag is there to be found: the prediction varies over the region by far more than 0.01 um
    assert np.ptp(want) > 1.0


def test_predict_places_the_part_by_the_flag_the_offsets_file_and_the_program_s_g10(cut):
    """The part's points predicted with the cut placed by --work-offset, by --offsets, and by the
    program's own G10 L2 P1 (G54): the same as the cut written at the origin. Neither file was
    part of the fit (their set-ups are taken as zero alike)."""
    d = cut["dir"]
    model = d / "moved.json"
    if not model.exists():
        _identify(d, "moved", cut["moved_part"], cut["moved"])
    copy = d / "moved_copy.csv"
    copy.write_text(cut["moved_part"].read_text())
    want = _predicted(model, copy, "pred_dn_um", "--cmm-program", str(cut["moved"]),
                      "--cmm-tool-radius", str(RADIUS))
    offsets = d / "offsets.toml"
    offsets.write_text("[work_offsets]\nG54 = {X = 100.0, Y = 50.0, Z = 0.0}\n")
    for program, flags in ((cut["g54"], ("--work-offset", "G54=X100,Y50,Z0")),
                           (cut["g54"], ("--offsets", str(offsets))), (cut["g10"], ())):
        got = _predicted(model, cut["part"], "pred_dn_um", "--cmm-program", str(program),
                         "--cmm-tool-radius", str(RADIUS), *flags)
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-2, err_msg=str(flags))
    assert np.ptp(want) > 1.0


@pytest.mark.parametrize("command", ["identify", "diagnose"])
@pytest.mark.parametrize("flags, message", [
    (["--work-offset", "G54=X100,Y50,Z0"], "--work-offset: the offsets are those of the program that cut a "
                                           "cmm part (--cmm-program), and no cmm file is among the data"),
    (["--work-offset", "G54=X100,Q5"], "--work-offset G54=X100,Q5:"),
])
def test_bad_offsets_fail_in_one_line_writing_nothing(tmp_path, capsys, command, flags, message):
    pts = tmp_path / "p.csv"
    pts.write_text("x_mm,y_mm,z_mm,dx_um\n0,0,0,1\n10,0,0,2\n")
    data = [str(pts)] if "no cmm" in message else []
    out = tmp_path / "m.json"
    if not data:
        part = tmp_path / "part.csv"
        part.write_text("x_mm,y_mm,z_mm,nx,ny,nz,dn_um,kind\n10,0,0,0,0,1,1.5,cmm\n")
        prog = tmp_path / "p.nc"
        prog.write_text("G21 G90 G54\nG0 X0 Y0 Z5\nG1 Z0 F500\nG1 X20\nM30\n")
        data = [str(part), "--cmm-program", str(prog), "--cmm-tool-radius", "3"]
    rc = main([command, "xfyz", *data, "-o", str(out), *flags]
              + (["--json", str(tmp_path / "r.json")] if command == "diagnose" else []))
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and not out.exists() and not (tmp_path / "r.json").exists()
    assert len(err) == 1 and message in err[0], err


def test_a_cut_program_in_two_work_offsets_is_refused(tmp_path):
    from mtcomp import load_machine
    from mtcomp.errors import InputError
    from mtcomp.toolpaths.cutter import read_cut_program
    from mtcomp.toolpaths.offsets import load_setup
    p = tmp_path / "p.nc"
    p.write_text("G21 G90 G54\nG0 X0 Y0 Z5\nG1 Z0 F500\nG55\nG1 X20\nM30\n")
    m = load_machine("xfyz")
    with pytest.raises(InputError) as exc:
        read_cut_program(p, m, load_setup(m, None, ["G55=X10"]))
    assert exc.value.line == 5 and "another work offset" in exc.value.message

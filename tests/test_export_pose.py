"""Where the other axes stand while an axis's table is read (`export --at`, and its default).

A machine-tool builder's VMC: the Y axis pitches (EAY), so the Y error at the tool tip carries the
pitch times the arm down to the tip, which changes with Z. Read at the reference position (Z at the
top of the data) the Y table carried an arm the machine never has at working height, and the Y error
over the volume was worse with mtcomp's table (1.24 um rms) than with none (0.94).

Hand-derived: the Y carriage carries Z and the spindle; a pitch a of Y turns the tip's arm (0, 0, h)
into (0, -a h, h), so dy = -a h, and lowering Z by 200 mm (h 200 mm shorter) changes dy by
+200 mm x a. With EAY = EAY_1 (y / 1 m), EAY_1 = 100 urad, at y = 300 mm that is 6 um. The model
is built by hand on the polynomial basis; its Z data reach -200 .. 0 mm, so the default pose is
Z = -100 (the middle).
"""
from __future__ import annotations

import csv

import numpy as np
from mtcomp.cli import main
from mtcomp.machine import load_machine
from mtcomp.models import ErrorModel, FittedModel, save_model

EAY_1 = 100.0        # urad per metre of Y


def _model(tmp_path):
    m = load_machine("xfyz")
    model = ErrorModel(m.with_basis("polynomial"), ())
    fitted = FittedModel.zero(model)
    fitted.params.set_file_value("EAY_1", EAY_1)
    fitted.support = {"X": (-400.0, 400.0), "Y": (-300.0, 300.0), "Z": (-200.0, 0.0)}
    path = tmp_path / "m.json"
    save_model(path, fitted)
    return path


def _y_trim(tmp_path, path, name, *at):
    """The LinuxCNC Y table (comp type 1: trims, -(error)), um, on its nominal positions."""
    out = tmp_path / name
    assert main(["export", "xfyz", str(path), "--format", "linuxcnc", "-o", str(out), *at]) == 0
    table = np.loadtxt(out / "y.comp")
    return table[:, 0], table[:, 1] * 1e3, (out / "README.txt").read_text()


def test_the_y_table_carries_the_arm_of_the_pose_it_is_read_at(tmp_path, capsys):
    path = _model(tmp_path)
    y, top, _ = _y_trim(tmp_path, path, "top", "--at", "Z=0")
    y2, low, readme = _y_trim(tmp_path, path, "low", "--at", "Z=-200")
    assert np.array_equal(y, y2)
    # error(Z=-200) - error(Z=0) = +200 mm * EAY(y); the trims are minus the error
    np.testing.assert_allclose(top - low, 200.0 * EAY_1 * 1e-6 * y / 1000.0 * 1e3, rtol=0, atol=0.01)
    assert "every other axis at X=0, Y=0, Z=-200" in readme
    y3, middle, readme = _y_trim(tmp_path, path, "default")
    np.testing.assert_allclose(middle, 0.5 * (top + low), rtol=0, atol=0.01)      # Z = -100
    assert "Z=-100" in readme


def test_at_names_a_bad_axis_in_one_line(tmp_path, capsys):
    path = _model(tmp_path)
    assert main(["export", "xfyz", str(path), "--format", "linuxcnc", "-o", str(tmp_path / "o"),
                 "--at", "Q=-200"]) == 2
    err = capsys.readouterr().err
    assert "--at 'Q=-200': the machine has no axis Q" in err and "Traceback" not in err
    assert not (tmp_path / "o").exists()


def test_a_pose_or_range_beyond_the_travel_is_refused_in_one_line(tmp_path, capsys):
    """xfyz's X travels -400 .. 400 mm: --at X=-1000 was read at the data's end without a word,
    and --range X=500:600 dropped X's table with only a note."""
    path = _model(tmp_path)
    for option, value in (("--at", "X=-1000"), ("--range", "X=500:600")):
        assert main(["export", "xfyz", str(path), "--format", "linuxcnc", "-o",
                     str(tmp_path / "o"), option, value]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and f"{option} '{value}': X beyond the machine's travel " \
            "-400 .. 400 mm" in err
        assert not (tmp_path / "o").exists()


def test_compensate_and_the_table_agree_along_a_line_through_its_pose(tmp_path, capsys):
    """Y moves at machine Z = -200 (no work offset: the datum is the machine zero). compensate's
    ey_before_um and the Y table read at --at Z=-200 differ by one constant to 0.01 um; the table
    read at the reference pose does not (6 um of arm between them)."""
    path = _model(tmp_path)
    ys = np.arange(-250.0, 251.0, 50.0)
    prog = tmp_path / "y.nc"
    prog.write_text("G21 G90\nG0 X0 Y0 Z0\nG0 Y-255 Z-200\n" + "".join(f"G1 Y{y:g} F1000\n" for y in ys)
                    + "M30\n")
    rep = tmp_path / "b.csv"
    assert main(["compensate", "xfyz", str(path), str(prog), "-o", str(tmp_path / "o.nc"), "--report",
                 str(rep), "--subdivide-tol-um", "0", "--max-step-um", "50"]) == 0
    rows = {int(r["line"]): r for r in csv.DictReader(open(rep, newline=""))}
    before = np.array([float(rows[4 + k]["ey_before_um"]) for k in range(ys.size)])
    assert np.ptp(before) > 5.0
    for at, agree in (("Z=-200", True), ("Z=0", False)):
        y, trim, _ = _y_trim(tmp_path, path, at.replace("=", ""), "--at", at)
        diff = before + np.interp(ys, y, trim)
        assert bool(np.ptp(diff) < 0.02) is agree, (at, diff)
    capsys.readouterr()

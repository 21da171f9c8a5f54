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
import pytest
from mtcomp.cli import main
from mtcomp.machine import load_machine
from mtcomp.models import ErrorModel, FittedModel, save_model

EAY_1 = 100.0        # urad per metre of Y


def _model(tmp_path, sd=None, held_share=0.0):
    """The model; with ``sd`` (urad per m) EAY_1's standard error, ``held_share`` of its variance
    along a combination the fit held weakly (MODEL.json uncertainty.held, held_sd_um 2 um)."""
    m = load_machine("xfyz")
    model = ErrorModel(m.with_basis("polynomial"), ())
    fitted = FittedModel.zero(model)
    fitted.params.set_file_value("EAY_1", EAY_1)
    fitted.support = {"X": (-400.0, 400.0), "Y": (-300.0, 300.0), "Z": (-200.0, 0.0)}
    if sd is not None:
        s = sd / fitted.params.specs[fitted.params.index("EAY_1")].to_file      # internal units
        fitted.uncertainty = {"names": ["EAY_1"], "covariance": np.array([[s ** 2]]),
                              "undetermined": np.zeros((1, 0)),
                              "held": np.array([[np.sqrt(held_share) * s / 2.0]]),
                              "held_sd_um": np.array([2.0])}
    path = tmp_path / f"m{'' if sd is None else f'_{sd:g}'}.json"
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


def _compensated_y(tmp_path, path, *extra, end=250.0):
    """compensate's report rows of the Y contour (Y moves from -``end`` to ``end`` mm at machine
    Z = -200; no work offset)."""
    ys = np.arange(-end, end + 1.0, 50.0)
    prog = tmp_path / "y.nc"
    prog.write_text(f"G21 G90\nG0 X0 Y0 Z0\nG0 Y{-end + 5:g} Z-200\n"
                    + "".join(f"G1 Y{y:g} F1000\n" for y in ys)
                    + "M30\n")
    rep = tmp_path / f"b_{path.stem}.csv"
    assert main(["compensate", "xfyz", str(path), str(prog), "-o", str(tmp_path / "o.nc"), "--report",
                 str(rep), "--subdivide-tol-um", "0", "--max-step-um", "50", *extra]) == 0
    rows = {int(r["line"]): r for r in csv.DictReader(open(rep, newline=""))}
    return ys, [rows[4 + k] for k in range(ys.size)]


def test_compensate_and_the_table_agree_along_a_line_through_its_pose(tmp_path, capsys):
    """Y moves at machine Z = -200 (no work offset: the datum is the machine zero). compensate's
    ey_before_um and the Y table read at --at Z=-200 differ by one constant to 0.01 um; the table
    read at the reference pose does not (6 um of arm between them)."""
    path = _model(tmp_path)
    ys, rows = _compensated_y(tmp_path, path)
    before = np.array([float(r["ey_before_um"]) for r in rows])
    assert np.ptp(before) > 5.0
    for at, agree in (("Z=-200", True), ("Z=0", False)):
        y, trim, _ = _y_trim(tmp_path, path, at.replace("=", ""), "--at", at)
        diff = before + np.interp(ys, y, trim)
        assert bool(np.ptp(diff) < 0.02) is agree, (at, diff)
    capsys.readouterr()


@pytest.mark.parametrize("sd, limit, written", [
    (EAY_1 / 1.5, 1000.0, False),    # every value 1.5 of its standard errors: not told from zero
    (EAY_1 / 3.0, 2.9, False),       # told (3 of them), but the largest standard error (3 um)
    (EAY_1 / 3.0, 3.1, True)],       # over 2.9 ... and under 3.1: written
    ids=["within_two_sd", "over_the_limit", "written"])
def test_the_table_is_written_exactly_where_compensate_corrects(tmp_path, capsys, sd, limit, written):
    """The same gate: where compensate leaves Y's motion through the table's points (Y's data reach
    -300 .. 300 mm) uncorrected, as one contour (its standard error over the limit, or no block told
    from zero), export writes no Y table; where it corrects, the table is written and its values
    are compensate's up to one constant. 90 % of EAY_1's variance lies along a combination the fit
    held weakly: both count it (sized without it, as export did, the largest standard error is
    sqrt(0.1) 3 = 0.95 um, under both limits). Hand-derived: the arm from Y's pitch to the tip is
    the tool length 100 mm plus 200 mm at Z = -200, so at Y = 300 mm (EAY = 30 urad) the
    correction is 9 um; every correction is EAY_1 / sd of its standard errors (one parameter),
    the largest standard error 9 sd / EAY_1 (3 um at sd = EAY_1 / 3)."""
    path = _model(tmp_path, sd=sd, held_share=0.9)
    ys, rows = _compensated_y(tmp_path, path, "--max-correction-sd-um", f"{limit:g}", end=300.0)
    corrected = {r["corrected"] for r in rows}
    assert corrected == {"1" if written else "0"}, corrected
    sds = np.array([float(r["correction_sd_um"]) for r in rows])
    before = np.array([float(r["ey_before_um"]) for r in rows])
    told = np.abs(before) > 0.01
    np.testing.assert_allclose(np.abs(before[told]) / sds[told], EAY_1 / sd, rtol=1e-3, atol=0)
    np.testing.assert_allclose(np.abs(before).max(), 9.0, rtol=0, atol=0.01)
    np.testing.assert_allclose(sds.max(), 9.0 * sd / EAY_1, rtol=1e-3, atol=0)
    out = tmp_path / "table"
    code = main(["export", "xfyz", str(path), "--format", "linuxcnc", "-o", str(out), "--at", "Z=-200",
                 "--max-correction-sd-um", f"{limit:g}"])
    err = capsys.readouterr().err
    assert code == (0 if written else 2)
    assert (out / "y.comp").exists() is written
    if not written:
        assert "axis Y: no table" in err and "as compensate leaves such blocks uncorrected" in err
        return
    table = np.loadtxt(out / "y.comp")
    diff = before + np.interp(ys, table[:, 0], table[:, 1] * 1e3)
    assert np.ptp(diff) < 0.02, diff


def test_a_straightness_over_the_limit_leaves_that_column_not_the_pitch_table(monkeypatch):
    """X's own error (its positioning) known to 0.5 um at every point, its straightness in Z to 8
    um only (over the 5 um limit; nothing measured it, as on a FANUC user's laser-and-ball-bar
    campaign, whose X got no pitch table at all): the table keeps X's own column and leaves EZX
    (set to zero), judged by the rules on the rest; the own column over the limit leaves the
    table."""
    from types import SimpleNamespace
    from mtcomp.export import _tables
    machine = load_machine("xfyz")
    n = 5
    q = np.zeros((n, 3))
    q[:, 0] = np.linspace(-100.0, 100.0, n)

    def run(own_sd):
        sd = np.tile([own_sd, 0.5, 8.0, 0.0, 0.0, 0.0], (n, 1))
        monkeypatch.setattr(_tables, "table_sd_um", lambda *a, **k: sd.copy())
        tips = {d: np.tile([0.02, 0.004, 0.01], (n, 1)) for d in (1.0, -1.0)}    # mm: 20, 4, 10 um
        fitted = SimpleNamespace(machine=machine)
        note, left = _tables._table_left(fitted, "X", q, q[0], tips, 5.0, SimpleNamespace(known=True))
        return note, left, tips
    note, left, tips = run(0.5)
    assert left == (2,) and "leaves its straightness in Z (EZX)" in note, note
    assert np.all(tips[1.0][:, 2] == 0.0) and np.all(tips[1.0][:, 0] == 0.02)
    note, left, _ = run(6.0)
    assert left == () and note.startswith("axis X: no table: its correction's standard error"), note

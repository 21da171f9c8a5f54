"""compensate gives a correction predict's standard error (the variance of the combinations the fit
held weakly included), and leaves a correction its standard error cannot tell from zero.

Oracles: the covariance applied by hand to central differences of the model's deviation (a second
formulation: not the planner's parameter Jacobian), hand-derived slopes (3 um per m over the
distance from the datum), and the hand-built machine's truth."""
import json

import numpy as np
import pytest

from mtcomp import load_machine
from mtcomp.cli import main
from mtcomp.models import ErrorModel, FittedModel, deviation, save_model
from mtcomp.planner import CompensationProblem, Planner, PlannerOptions

SIGMA = 3e-3             # standard error of EXX_1, internal units (3 um per m)


def _machine():
    return load_machine("xfyz").with_basis("polynomial")


def _sens(fitted, name, q):
    """(n, 3) mm per internal unit: the tip's change with parameter ``name``, central differences."""
    p = np.asarray(fitted.params.values, dtype=float)
    dp = np.zeros_like(p)
    dp[fitted.params.index(name)] = 1e-6
    return (deviation(fitted.model, q, p + dp)[:, :3] - deviation(fitted.model, q, p - dp)[:, :3]) / 2e-6


def _plan(fitted, q, datum=None, rapid=None, limit=5.0):
    planner = Planner(CompensationProblem.from_machine(fitted),
                      PlannerOptions(threads=1, max_correction_sd_um=limit))
    n = q.shape[0]
    nodes, lin = planner.nodes_from_arrays(q, np.full(n, 1000.0), None, rapid,
                                           datum=None if datum is None else np.asarray(datum, float))
    return planner.plan_nodes(nodes, lin, final=True)


def _q(x, z):
    x = np.asarray(x, dtype=float)
    return np.column_stack([x, np.zeros_like(x), np.broadcast_to(z, x.shape)])


# ------------------------------------------------------------------ the variance the fit held
def _held_model(exx_um_per_m, held_share):
    """EXX_1 at its file value with standard error SIGMA, ``held_share`` of its variance along a
    combination the fit held weakly (MODEL.json uncertainty.held, held_sd_um)."""
    m = _machine()
    fitted = FittedModel.zero(ErrorModel(m))
    fitted.params.set_file_value("EXX_1", exx_um_per_m)
    fitted.support = {"X": (-400.0, 400.0)}
    held_sd = np.sqrt(held_share) * SIGMA
    fitted.uncertainty = {"names": ["EXX_1"], "covariance": np.array([[SIGMA ** 2]]),
                          "undetermined": np.zeros((1, 0)),
                          "held": np.array([[held_sd / 2.0]]), "held_sd_um": np.array([2.0])}
    return m, fitted


def test_the_correction_standard_error_counts_the_held_variance_and_the_datum():
    m, fitted = _held_model(40.0, held_share=0.9)
    x = np.array([-150.0, 20.0, 100.0, 300.0])
    datum = np.array([[60.0, 0.0, 0.0]] * x.size)
    res = _plan(fitted, _q(x, 0.0), datum=datum, rapid=np.ones(x.size, bool), limit=50.0)
    # the correction's variance: that of the deviation less the datum's, the whole covariance
    # (held share included: the truth may differ from the held value by that much)
    d = _sens(fitted, "EXX_1", _q(x, 0.0)) - _sens(fitted, "EXX_1", datum)
    want = 1e3 * SIGMA * np.abs(d).max(axis=1)
    np.testing.assert_allclose(res.sd_um, want, rtol=1e-6, atol=1e-9)
    # by hand: 3 um per m over the distance from the datum
    np.testing.assert_allclose(res.sd_um, 3e-3 * np.abs(x - 60.0), rtol=1e-6, atol=1e-9)


# ------------------------------------------------------------------ not told from zero
@pytest.mark.parametrize("end", ["G0 Z10\n", ""], ids=["rapid_last", "contour_last"])
def test_a_correction_within_two_standard_errors_is_not_made(tmp_path, capsys, end):
    # the truth's X is exact; the fit read 4 um per m from noise, with a standard error of 3:
    # every correction is 1.33 standard errors (4 / 3), so nothing is corrected and the user told;
    # also where the program ends in the contour (no rapid closes it: it is judged at the end)
    m = _machine()
    fitted = FittedModel.zero(ErrorModel(m))
    fitted.params.set_file_value("EXX_1", 4.0)
    fitted.support = {"X": (-400.0, 400.0), "Y": (-300.0, 300.0)}
    fitted.uncertainty = {"names": ["EXX_1"], "covariance": np.array([[SIGMA ** 2]]),
                          "undetermined": np.zeros((1, 0))}
    path = tmp_path / "M.json"
    save_model(path, fitted)
    prog = tmp_path / "p.nc"
    prog.write_text("G21 G90\nG0 X20 Y0 Z0\nG1 X100 F1000\nG1 X200\nG1 X300\n" + end + "M30\n")
    capsys.readouterr()
    assert main(["compensate", "xfyz", str(path), str(prog), "-o", str(tmp_path / "o.nc"),
                 "--report", str(tmp_path / "B.csv"), "--json", str(tmp_path / "S.json"),
                 "--work-offset", "G54=X0,Y0,Z0", "--subdivide-tol-um", "0"]) == 0
    out = capsys.readouterr().out
    assert (tmp_path / "o.nc").read_text() == prog.read_text()
    rows = (tmp_path / "B.csv").read_text().splitlines()
    head = rows[0].split(",")
    body = [dict(zip(head, r.split(","))) for r in rows[1:]]
    moved = [r for r in body if float(r["x_mm"]) != 0.0]
    assert moved and all(r["uncertain"] == "1" and r["corrected"] == "0" for r in moved)
    for r in moved:                                   # 4 / 3 standard errors, by hand
        np.testing.assert_allclose(abs(float(r["ex_before_um"])) / float(r["correction_sd_um"]),
                                   4.0 / 3.0, rtol=1e-3, atol=0)
    assert f"{len(moved)} blocks not corrected: the correction is within two of its standard" in out
    summary = json.loads((tmp_path / "S.json").read_text())
    assert summary["uncorrected"]["indistinct_from_zero"] == len(moved)
    assert summary["uncorrected"]["uncertain"] == 0


def _x_quiet_y_told():
    """(machine, model): X's slope 4 +- 3 um per m (not told from zero), Y's 40 +- 3 (told)."""
    m = _machine()
    fitted = FittedModel.zero(ErrorModel(m))
    fitted.params.set_file_value("EXX_1", 4.0)
    fitted.params.set_file_value("EYY_1", 40.0)
    fitted.support = {"X": (-400.0, 400.0), "Y": (-300.0, 300.0)}
    fitted.uncertainty = {"names": ["EXX_1", "EYY_1"], "covariance": np.diag([SIGMA ** 2] * 2),
                          "undetermined": np.zeros((2, 0))}
    return m, fitted


def test_a_contour_with_one_correction_told_from_zero_is_corrected_whole():
    # X's slope 4 +- 3 um per m (not told from zero); Y's 40 +- 3 (told): a contour along X at
    # y = 0 is left, the same contour turning to y = 200 mm is corrected whole
    m, fitted = _x_quiet_y_told()
    xa = np.array([50.0, 100.0, 150.0, 200.0])
    qa = _q(xa, 0.0)
    qb = np.vstack([qa, [[200.0, 100.0, 0.0], [200.0, 200.0, 0.0]]])
    datum = np.zeros(3)
    res_a = _plan(fitted, qa, datum=np.tile(datum, (4, 1)))
    assert res_a.pinned.all() and res_a.indistinct.all()
    res_b = _plan(fitted, qb, datum=np.tile(datum, (6, 1)))
    assert not res_b.pinned.any()
    # X's part corrected too, 4 um per m (the tip lands where the program meant it on the model)
    np.testing.assert_allclose(res_b.correction[:4, 0], -4e-3 * xa / 1000.0, rtol=0, atol=2e-5)
    np.testing.assert_allclose(res_b.correction[4:, 1], -40e-3 * qb[4:, 1] / 1000.0, rtol=0, atol=2e-5)


@pytest.mark.parametrize("slope, made", [(5.7, False), (6.3, True), (7.5, True)])
def test_the_rule_is_two_standard_errors_from_both_sides(slope, made):
    # X's slope ``slope`` +- 3 um per m: every correction is slope / 3 of its standard errors (1.9,
    # 2.1, 2.5), so the contour is left under two and corrected whole over two
    m = _machine()
    fitted = FittedModel.zero(ErrorModel(m))
    fitted.params.set_file_value("EXX_1", slope)
    fitted.support = {"X": (-400.0, 400.0)}
    fitted.uncertainty = {"names": ["EXX_1"], "covariance": np.array([[SIGMA ** 2]]),
                          "undetermined": np.zeros((1, 0))}
    x = np.array([50.0, 100.0, 200.0, 300.0])
    res = _plan(fitted, _q(x, 0.0), datum=np.zeros((x.size, 3)), limit=50.0)
    np.testing.assert_allclose(res.sd_um, 1e3 * SIGMA * x / 1000.0, rtol=1e-6, atol=1e-9)
    assert not res.pinned.any() if made else (res.pinned.all() and res.indistinct.all())
    want = -slope * 1e-3 * x / 1000.0 if made else np.zeros(x.size)
    np.testing.assert_allclose(res.correction[:, 0], want, rtol=0, atol=2e-5)


def test_render_leaves_what_compensate_leaves_for_the_two_standard_error_rule(tmp_path):
    """render without a report marks uncertain (3) the blocks compensate leaves because their
    correction is not told from zero: X's slope 4 +- 3 um per m (a contour along X at y = 0 is
    left), Y's 40 +- 3 (a contour along Y is corrected); the oracle is compensate's BLOCKS.csv."""
    import csv
    from mtcomp.viz.surface import program_error_map
    m, fitted = _x_quiet_y_told()
    path = tmp_path / "M.json"
    save_model(path, fitted)
    xs, ys = (50.0, 100.0, 150.0, 200.0), (50.0, 100.0, 150.0, 200.0)
    prog = tmp_path / "p.nc"
    prog.write_text("G21 G90\nG0 X0 Y0 Z0\n" + "".join(f"G1 X{x:g} F1000\n" for x in xs)
                    + "G0 X0 Y0\n" + "".join(f"G1 Y{y:g}\n" for y in ys) + "M30\n")
    rep = tmp_path / "B.csv"
    assert main(["compensate", "xfyz", str(path), str(prog), "-o", str(tmp_path / "o.nc"),
                 "--report", str(rep), "--work-offset", "G54=X0,Y0,Z0", "--subdivide-tol-um", "0",
                 "--quiet"]) == 0
    with open(rep, newline="") as f:
        left = {(round(float(r["x_mm"]), 3), round(float(r["y_mm"]), 3)): r["uncertain"] == "1"
                for r in csv.DictReader(f) if r["rapid"] == "0"}
    assert sum(left.values()) == len(xs) and len(left) == len(xs) + len(ys)
    smap = program_error_map(m, fitted, prog, tool_radius_mm=0.0, normal="path")
    assert smap.status_source == "planner"
    for tip, status in zip(np.round(smap.tips, 3), smap.status):
        key = (float(tip[0]), float(tip[1]))
        if key in left:
            assert bool(status == 3) == left[key], (key, status)

"""What explains the NIST plates' hole errors from plate to plate (benchmarks/bench_plates.py,
``--explain``): the alignments in the plane, the held-out per-hole predictors, checked on synthetic
plates against hand-derived values, and the facts docs/identification.md states about the real
plates (tests/data/real/plates, public US government data, SOURCES.md there)."""
from __future__ import annotations

import csv
import runpy
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
bench = SimpleNamespace(**runpy.run_path(str(ROOT / "benchmarks" / "bench_plates.py"),
                                         run_name="bench_plates"))

#: a 5 x 5 grid of holes, 20 mm apart: symmetric about its centroid, so that sum dx^2 = sum dy^2
#: and sum dx dy = 0 and the alignments' figures have closed forms
_GRID = np.array([(10.0 + 20.0 * i, -40.0 + 20.0 * j) for i in range(5) for j in range(5)])


def _linear_error(matrix_um_per_mm, shift_um=(3.0, -2.0)):
    """(n, 2) um: the error matrix @ (hole - centroid) + a shift, at the grid's holes."""
    d = _GRID - _GRID.mean(axis=0)
    return d @ np.asarray(matrix_um_per_mm).T + np.asarray(shift_um)


def _rms_of_linear_map(matrix):
    """rms length of matrix @ d over the grid: trace(M^T M) * mean(dx^2) (sum dx dy = 0)."""
    d = _GRID - _GRID.mean(axis=0)
    return float(np.sqrt(np.trace(matrix.T @ matrix) * np.mean(d[:, 0] ** 2)))


def test_alignments_remove_what_they_should_and_leave_the_rest():
    # M = [[a, b], [c, e]]: a rigid alignment removes the shift and the turn (c - b) / 2, and
    # leaves the symmetric part; a scale removes (a + e) / 2 of it too; every linear map, all
    a, b, c, e = 0.05, -0.03, 0.11, -0.02
    matrix = np.array([[a, b], [c, e]])
    error = _linear_error(matrix)
    symmetric = np.array([[a, (b + c) / 2], [(b + c) / 2, e]])
    traceless = symmetric - (a + e) / 2 * np.eye(2)
    np.testing.assert_allclose(bench.rigid_aligned_rms(_GRID, error), _rms_of_linear_map(symmetric),
                               rtol=1e-12, atol=0)
    np.testing.assert_allclose(bench.aligned_rms(_GRID, error, "scale"),
                               _rms_of_linear_map(traceless), rtol=1e-12, atol=0)
    np.testing.assert_allclose(bench.aligned_rms(_GRID, error, "affine"), 0.0, rtol=0, atol=1e-12)
    # a pure turn and shift leave nothing after any of them
    turn = _linear_error([[0.0, -0.07], [0.07, 0.0]])
    for kind in ("rigid", "scale", "affine"):
        np.testing.assert_allclose(bench.aligned_residual(_GRID, turn, kind), 0.0, rtol=0, atol=1e-12)


def test_alignment_design_has_the_columns_of_its_kind():
    assert [bench.alignment_design(_GRID, k).shape for k in ("rigid", "scale", "affine")] == [
        (50, 3), (50, 4), (50, 6)]
    # the scale column is the hole's offset from the centroid, in x then y
    d = _GRID - _GRID.mean(axis=0)
    np.testing.assert_allclose(bench.alignment_design(_GRID, "scale")[:, 3], d.reshape(-1),
                               rtol=0, atol=0)


def _drifting_plates(order):
    """Errors (um) of plates whose holes drift along a fixed non-rigid pattern in proportion to
    ``order`` (plate -> value), about a common pattern."""
    rng = np.random.default_rng(7)
    common, drift = rng.normal(0.0, 3.0, (2, len(_GRID), 2))
    return {p: common + drift * t for p, t in order.items()}, common, drift


def test_a_per_hole_line_in_a_covariate_predicts_a_drift_the_mean_cannot():
    order = {1: 0.0, 2: 1.0, 3: 3.0, 4: 4.0, 5: 7.0}
    err, common, drift = _drifting_plates(order)
    plates, holes = list(order), np.arange(len(_GRID))
    assert bench.held_out_median(_GRID, err, plates, bench.per_hole_line(order), holes) == (
        pytest.approx(0.0, abs=1e-10))
    # the mean of the others misses by the drift times the plate's distance from their mean order
    expected = [abs(t - np.mean([order[q] for q in plates if q != p]))
                * bench.rigid_aligned_rms(_GRID, drift) / bench.rigid_aligned_rms(_GRID, err[p])
                for p, t in order.items()]
    np.testing.assert_allclose(
        bench.held_out_median(_GRID, err, plates, bench.per_hole_mean, holes), np.median(expected),
        rtol=1e-10, atol=0)


def test_same_level_mean_takes_the_plates_of_the_level_or_else_every_other():
    err = {p: np.full((3, 2), float(p)) for p in range(1, 6)}
    level = {1: "Low", 2: "High", 3: "Low", 4: "Low", 5: "Medium"}
    predict = bench.same_level_mean(level)
    np.testing.assert_allclose(predict(err, [2, 3, 4, 5], 1), 3.5, rtol=0, atol=0)   # plates 3, 4
    np.testing.assert_allclose(predict(err, [1, 3, 4, 5], 2), 3.25, rtol=0, atol=0)  # no High left


def test_plate_covariates_count_hours_from_the_first_plate_and_the_days_first():
    covariates = bench.plate_covariates(range(1, 21))
    # plate 12 was started 2017-02-02 17:58:54, plate 10 (that day's first) 16:30:58, plate 1
    # 2017-02-01 13:59:35
    np.testing.assert_allclose(covariates["hours since the day's first plate"][12],
                               1 + 27 / 60 + 56 / 3600, rtol=1e-12, atol=0)
    np.testing.assert_allclose(covariates["hours since the first plate"][12],
                               28 - 41 / 3600, rtol=1e-12, atol=0)
    assert covariates["hours since the day's first plate"][16] == 0.0
    assert covariates["cutting order"][7] == 7.0


def test_drop_holes_leaves_out_one_nominal_diameter(tmp_path):
    path = tmp_path / "part.csv"
    path.write_text("x_mm,y_mm,dx_um,diameter_mm\n1,2,3,4.0000\n5,6,7,4.5000\n8,9,1,4.0000\n")
    bench.drop_holes(path, 4.0)
    assert path.read_text().splitlines() == ["x_mm,y_mm,dx_um,diameter_mm", "5,6,7,4.5000"]


@pytest.fixture(scope="module")
def nist_plates(tmp_path_factory):
    """The 20 NIST plates' points files, written by the converter as the benchmark writes them."""
    out = tmp_path_factory.mktemp("plates")
    res = subprocess.run([sys.executable, str(bench.CONVERTER), str(bench.QIF), str(out),
                          "--part-to-program", bench.PART_TO_PROGRAM, "--top-z", "4.5"],
                         capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    return {p: out / f"part{p:02d}.csv" for p in range(1, 21)}


def _scatter_by_diameter(xy, diameter, err, plates):
    """rms over the plates of each plate's rigid-aligned error about the batch's mean, per nominal
    diameter: written out here with its own least squares, not the benchmark's."""
    d = xy - xy.mean(axis=0)
    design = np.zeros((2 * len(xy), 3))
    design[0::2, 0], design[1::2, 1] = 1.0, 1.0
    design[0::2, 2], design[1::2, 2] = -d[:, 1], d[:, 0]
    pattern = np.mean([err[p] for p in plates], axis=0)
    left = []
    for p in plates:
        b = (err[p] - pattern).reshape(-1)
        left.append((b - design @ np.linalg.lstsq(design, b, rcond=None)[0]).reshape(-1, 2))
    left = np.array(left)
    return {dia: float(np.sqrt(np.mean(np.sum(left[:, diameter == dia] ** 2, axis=2))))
            for dia in np.unique(diameter)}


def test_long_tool_plates_scatter_in_their_4_mm_holes_and_no_known_factor_predicts_it(nist_plates):
    plates = list(bench.BATCHES["long"])
    with open(nist_plates[10], newline="") as handle:
        rows = list(csv.DictReader(handle))
    xy = np.array([[float(r["x_mm"]), float(r["y_mm"])] for r in rows])
    diameter = np.array([float(r["diameter_mm"]) for r in rows])
    err = {p: bench.read_points(nist_plates[p])[1] for p in plates}
    scatter = _scatter_by_diameter(xy, diameter, err, plates)
    assert scatter[4.0] > 2.4 * max(v for k, v in scatter.items() if k != 4.0)
    every, others = np.arange(len(xy)), np.flatnonzero(diameter != 4.0)
    mean_all, mean_others = (bench.held_out_median(xy, err, plates, bench.per_hole_mean, h)
                             for h in (every, others))
    assert mean_all > 1.0 and mean_others < 0.6
    for covariate in bench.plate_covariates(plates).values():
        assert bench.held_out_median(xy, err, plates, bench.per_hole_line(covariate), every) > 1.0
    for level in bench.plate_levels().values():
        assert bench.held_out_median(xy, err, plates, bench.same_level_mean(level), every) > 1.0
    # not a prediction: the plate's own fitted scale (a thermal expansion) removes 1 % or less
    rigid = [bench.rigid_aligned_rms(xy, err[p]) for p in plates]
    scaled = [bench.aligned_rms(xy, err[p], "scale") for p in plates]
    assert np.median(np.divide(scaled, rigid)) > 0.98

"""What the data fix only weakly is judged over the region the data cover, not over the travel the
machine file states.

* ``data_region``: an axis the files move spans the positions they reached, an axis they hold at
  one position is that position, an axis none of whose errors are fitted its travel (hand-made
  files).
* The metric over a region is the mean squared tool-tip error there: a squareness C0Y moves the tip
  by ``-C0Y y`` in X, so its metric is the mean of y^2 over the region (hand-derived).
* Plates measured on a small region of a large machine (the independent truth machine, tests/truth,
  hole positions in X and Y only, each plate with its own CMM alignment): the model is the same
  whether the machine file states the machine's travel or only the plates' region (before, the fit
  held what the plates fix well on the plate but weakly over 610 mm, and the two differed by about
  1 um inside the region); inside the region it predicts the truth to within what the noise allows
  a smoother of its effective degrees of freedom; and its support is the region, so compensate and
  export apply it nowhere else.
"""
from __future__ import annotations

import csv

import numpy as np
import pytest

from mtcomp.identification.fit import identify
from mtcomp.identification.predict import predict_readings
from mtcomp.identification.problem import data_region, travel_metric
from mtcomp.machine import load_machine
from mtcomp.measurement.files import read_measurements
from mtcomp.models.chain import ErrorModel
from truth import TruthMachine
from truth import campaigns as tc

#: the plates' region (mm): 120 x 70 mm, holes at two depths 2 mm apart
REGION = {"X": (0.0, 120.0), "Y": (0.0, 70.0), "Z": (-2.0, 0.0)}
#: a vertical machining centre's travel (mm) around it
TRAVEL = {"X": (-300.0, 310.0), "Y": (-254.0, 254.0), "Z": (-400.0, 210.0)}
NOISE_UM = 2.5


def _machine_file(path, travel: dict):
    axes = "".join(f"[axes.{a}]\ntravel_mm = [{lo}, {hi}]\n" for a, (lo, hi) in travel.items())
    path.write_text(f'name = "vmc"\ntopology = "XYFZ"\ntool_length_mm = 0.0\n{axes}')
    return path


def _points_file(path, rows: list[tuple]):
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["x_mm", "y_mm", "z_mm", "dx_um", "dy_um"])
        w.writerows(rows)
    return path


def test_data_region_is_the_range_moved_and_the_position_held(tmp_path):
    machine = load_machine(_machine_file(tmp_path / "m.toml", TRAVEL))
    a = _points_file(tmp_path / "a.csv", [(10.0, -5.0, 3.0, 1.0, 1.0), (40.0, 20.0, 3.0, 1.0, 1.0)])
    b = _points_file(tmp_path / "b.csv", [(25.0, 60.0, 3.0, 1.0, 1.0)])
    lo, hi = data_region(machine, [read_measurements(a), read_measurements(b)])
    np.testing.assert_allclose(lo, [10.0, -5.0, 3.0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(hi, [40.0, 60.0, 3.0], rtol=0, atol=1e-12)
    # an axis none of whose errors are fitted keeps its travel: it does not bound the model
    lo, hi = data_region(machine, [read_measurements(a), read_measurements(b)], axes={"X"})
    np.testing.assert_allclose(lo, [10.0, TRAVEL["Y"][0], TRAVEL["Z"][0]], rtol=0, atol=1e-12)
    np.testing.assert_allclose(hi, [40.0, TRAVEL["Y"][1], TRAVEL["Z"][1]], rtol=0, atol=1e-12)


def test_region_metric_of_a_squareness_is_the_mean_square_arm(tmp_path):
    machine = load_machine(_machine_file(tmp_path / "m.toml", TRAVEL))
    model = ErrorModel(machine)
    i = np.array([model.param_names.index("C0Y")])
    lo, hi = np.array([0.0, 20.0, -2.0]), np.array([120.0, 90.0, 0.0])
    # dx = -C0Y y: mean of y^2 over y uniform in [a, b] is (a^2 + a b + b^2) / 3 (256 random poses:
    # the sample mean is within about 6 % of it; the travel's is 13 times larger)
    a, b = 20.0, 90.0
    np.testing.assert_allclose(travel_metric(model, i, 1, (lo, hi))[0, 0], (a * a + a * b + b * b) / 3,
                               rtol=0.15, atol=0)
    a, b = TRAVEL["Y"]
    np.testing.assert_allclose(travel_metric(model, i, 1)[0, 0], (a * a + a * b + b * b) / 3,
                               rtol=0.15, atol=0)


def _planar(path):
    """The file without its dz column: a hole's centre is read in X and Y only."""
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    keep = [k for k in rows[0] if k != "dz_um"]
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, keep, extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)
    return path


def _rigid_aligned_rms(xy, error_um):
    """rms length (um) of the (n, 2) error after the least-squares rigid motion in the plane (scipy's
    Kabsch rotation of the centred points)."""
    from scipy.spatial.transform import Rotation
    nominal = np.column_stack([xy - xy.mean(axis=0), np.zeros(len(xy))])
    actual = xy + error_um * 1e-3
    actual = np.column_stack([actual - actual.mean(axis=0), np.zeros(len(xy))])
    turn, _ = Rotation.align_vectors(nominal, actual)
    return float(np.sqrt(np.mean(np.sum((turn.apply(actual) - nominal) ** 2, axis=1)))) * 1e3


@pytest.mark.parametrize("seed", [1, 2])
def test_plates_on_a_large_machine_are_fitted_as_on_their_region(seed, tmp_path):
    rng = np.random.default_rng(seed)
    # a machine's errors drawn over its whole travel; the plates see the part of them on the region
    truth = TruthMachine.random(_machine_file(tmp_path / "truth.toml", TRAVEL), rng, error_motions=False)
    truth.travel = dict(REGION)                 # where the campaign writer puts the holes
    plates = [_planar(tc.points(truth, tmp_path / f"plate{k}.csv", rng, grid=(4, 3, 2), margin=0.0,
                                tool_lengths_mm=(0.0,), directions=(1,), noise_um=NOISE_UM).path)
              for k in range(8)]
    data = [read_measurements(p) for p in plates]
    test = tc.points(truth, tmp_path / "test.csv", rng, grid=(13, 9, 1), margin=0.0,
                     tool_lengths_mm=(0.0,), directions=(1,), noise_um=0.0, setup=False)
    fits, predictions = [], []
    for name, travel in (("travel", TRAVEL), ("region", REGION)):
        res = identify(load_machine(_machine_file(tmp_path / f"{name}.toml", travel)), data)
        pred = predict_readings(res.fitted_model, read_measurements(test.path)).columns
        fits.append(res)
        predictions.append(np.column_stack([pred["pred_dx_um"], pred["pred_dy_um"]]))
    # the machine file's travel changes nothing the data fix: the same parameters, the same predictions
    np.testing.assert_allclose(fits[0].fitted_model.params.values, fits[1].fitted_model.params.values,
                               rtol=0, atol=1e-12)
    np.testing.assert_allclose(predictions[0], predictions[1], rtol=0, atol=1e-6)
    # inside the region, the truth to the noise: a least-squares fit of p parameters to n readings of
    # noise sigma is off by sigma sqrt(p / n) rms over its design (a penalised one by less); p the
    # rank, set-ups included, and the test grid is not the design: a quarter more
    ideal = np.column_stack([test.ideal["dx_um"], test.ideal["dy_um"]])
    xy = test.q[:, :2]
    res = fits[0]
    expected = NOISE_UM * np.sqrt(res.rank / res.n_obs)
    misfit = _rigid_aligned_rms(xy, predictions[0] - ideal)
    print(f"truth {_rigid_aligned_rms(xy, ideal):.2f} um, misfit {misfit:.2f} um, expected {expected:.2f} um")
    assert misfit <= 1.25 * expected
    # the model applies where the data are: compensate and export use it nowhere else
    support = res.fitted_model.support
    for a, (lo, hi) in REGION.items():
        np.testing.assert_allclose(support[a], [lo, hi], rtol=0, atol=1e-9)

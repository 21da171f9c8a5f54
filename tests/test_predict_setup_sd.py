"""A prediction of a fitted file, made with its fitted set-up, has the standard error of that
prediction: the set-up was fitted with the parameters, so their joint covariance counts.

Oracle: ordinary least squares of a straight line, by hand. A laser positioning file of X whose
readings are a line plus noise that cancels per target (run 2 reads -noise where run 1 read +noise)
has per-target means exactly on the line, so REML puts the positioning weight at its bound and the
fit is the least-squares line: the file's zero (its set-up) and the profile's slope. The prediction
of reading i is ``c + b x_i`` with variance ``s^2 (1/n + (x_i - xbar)^2 / Sxx)``, ``s^2`` the
residual sum of squares over n - 2. The parameters' covariance alone (before) gave only the
slope's share about the profile's reference, not the zero's: 0 at the targets' centre, 0.84 of the
line's standard error at their ends."""
from __future__ import annotations

import numpy as np
import pytest

from mtcomp.identification.fit import identify
from mtcomp.identification.predict import predict_readings
from mtcomp.machine import load_machine
from mtcomp.measurement.files import read_measurements
from mtcomp.models.model_file import load_model, save_model

TARGETS_MM = np.linspace(-300.0, 100.0, 9)       # not centred on X's travel (-400 .. 400 mm)
OFFSET_UM, SLOPE_UM_PER_MM = 3.0, 0.015


def _line_file(path):
    eps = np.random.default_rng(7).normal(0.0, 0.3, TARGETS_MM.size)
    rows = ["axis,component,target_mm,dir,run,value_um"]
    for run, sign in ((1, 1.0), (2, -1.0)):
        for x, e in zip(TARGETS_MM, eps):
            rows.append(f"X,EXX,{x},1,{run},{OFFSET_UM + SLOPE_UM_PER_MM * x + sign * e:.6f}")
    path.write_text("\n".join(rows) + "\n")
    return path


def _by_hand(x, y):
    """(prediction, its standard error) of the least-squares line through (x, y), at x."""
    b, c = np.polyfit(x, y, 1)
    s2 = np.sum((y - (c + b * x)) ** 2) / (x.size - 2)
    sd = np.sqrt(s2 * (1.0 / x.size + (x - x.mean()) ** 2 / np.sum((x - x.mean()) ** 2)))
    return c + b * x, sd


def test_a_fitted_laser_file_is_predicted_with_the_standard_error_of_its_least_squares_line(tmp_path):
    d = read_measurements(_line_file(tmp_path / "line_x.csv"))
    res = identify(load_machine("xfyz"), [d])
    assert res.fitted_model.info["identify"]["smoothing"]["edf"] == pytest.approx(2.0, abs=1e-6)
    expected, expected_sd = _by_hand(d.target, d.value * 1e3)
    pred = predict_readings(res.fitted_model, d)
    np.testing.assert_allclose(pred.columns["pred_value_um"], expected, atol=1e-6)
    np.testing.assert_allclose(pred.columns["pred_value_um_sd"], expected_sd, rtol=1e-4)
    # MODEL.json carries the set-up's covariance: the model read back predicts the same
    save_model(tmp_path / "MODEL.json", res.fitted_model)
    again = predict_readings(load_model(tmp_path / "MODEL.json"), d)
    np.testing.assert_allclose(again.columns["pred_value_um_sd"], expected_sd, rtol=1e-4)


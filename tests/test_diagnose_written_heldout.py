"""The figures of the model diagnose writes when it fits clearly worse than the least squares: its
held-out rms (its own fit made once per fold, the fold's readings left out) and its rms per file
beside the least squares'. A service engineer's report printed only the least squares' held-out
figure (0.745 um) beside a model written that predicted fresh runs of X at 0.87 um.

The oracle is plain numpy: the fit a stand-in for identify's engine (weighted least squares with
the readings' standard deviations), the held-out residuals recomputed by np.linalg.lstsq on each
fold's kept readings, in an order of the readings other than the stack's."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from mtcomp.diagnose._open import _by_file, _heldout_rms_um, worse_files


def test_the_written_model_s_held_out_rms_is_its_own_fit_without_each_fold():
    rng = np.random.default_rng(4)
    n = 60
    X = np.column_stack([np.ones(n), np.linspace(-1.0, 1.0, n), rng.normal(size=n)])
    y = X @ [1.0, -2.0, 0.5] + rng.normal(0.0, 0.3, n)      # stack order
    folds = np.arange(n) % 5                                # stack order
    um = np.arange(n) % 4 != 0                              # a quarter of the readings in urad
    order = rng.permutation(n)                              # the fit's reading k is the stack's order^-1
    Xf, yf = np.empty_like(X), np.empty_like(y)
    Xf[order], yf[order] = X, y                             # the fit's order: stack reading i at order[i]

    def fit(sd):
        w = 1.0 / sd
        theta = np.linalg.lstsq(Xf * w[:, None], yf * w, rcond=None)[0]
        return SimpleNamespace(residual=(yf - Xf @ theta) * w)
    cv = np.empty(n)
    for k in range(5):
        keep = folds != k
        theta = np.linalg.lstsq(X[keep], y[keep], rcond=None)[0]
        cv[~keep] = y[~keep] - X[~keep] @ theta
    got = _heldout_rms_um(fit, np.full(n, 0.3), order, folds, um)
    assert got == pytest.approx(np.sqrt(np.mean(cv[um] ** 2)), rel=1e-9)
    # not the in-sample rms: the held-out residuals are larger
    assert got > np.sqrt(np.mean(((yf - Xf @ np.linalg.lstsq(Xf, yf, rcond=None)[0])[order][um]) ** 2))


def test_the_files_the_written_model_fits_worse_are_named_with_both_figures():
    st = SimpleNamespace(datasets=[SimpleNamespace(path="a/laser_X.csv"), SimpleNamespace(path="b/velocity_X.csv")],
                         file=np.array([0, 0, 0, 1, 1]), unit=np.array(["um", "um", "um", "um/min", "um/min"]))
    resid = np.array([0.8, -0.9, 0.85, 1.0, -1.0])
    lsq = np.array([0.3, -0.3, 0.3, 1.0, -0.9])
    by = _by_file(st, resid, lsq, 1.3)
    assert by["laser_X"] == {"unit": "um", "rms": pytest.approx(np.sqrt((0.64 + 0.81 + 0.7225) / 3), abs=1e-4),
                             "rms_least_squares": 0.3, "worse": True}
    assert by["velocity_X"]["worse"] is False
    assert by["velocity_X"]["rms"] == 1.0 and by["velocity_X"]["rms_least_squares"] == pytest.approx(
        np.sqrt((1.0 + 0.81) / 2), abs=1e-4)
    text = worse_files({"by_file": by, "heldout_rms_um": 0.7352})
    # laser_X 0.851 against 0.3: more than 1.3 times; velocity_X 1 against 0.951: not named
    assert text == "; laser_X 0.851 against 0.3 um; held-out 0.7352 um"

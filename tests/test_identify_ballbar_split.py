"""A ball-bar circle alone reads one radial deviation per angle: how X's deviation divides between X's
positioning and Y's straightness in X (and Y's between its positioning and X's straightness) is the
roughness penalty's choice where both carry curvature, and a prediction away from the circle rests on
that choice. Its standard error must say so.

The oracle is the independent truth machine (tests/truth, no code shared with mtcomp): an XFYZ
machine with curved positioning and straightness of X and Y, angular motions and a squareness (an
identifiability tester's machine), one circle of radius 150 mm in XY both ways (0.2 um noise), the
bar's length calibrated. By hand, EXX(x) = a (x^2 - r^2) with EXY(y) = a y^2 moves X's tip by
a (x^2 + y^2 - r^2), nothing on the circle: the circle cannot tell that split from none. The
straightness class carries a little curvature, so REML's weight for it rests on about one degree
of freedom. The program visits the corners of the square about the circle and the axis points.
"""
from __future__ import annotations

import contextlib
import csv
import io

import numpy as np
import pytest

from mtcomp.cli import main
from mtcomp.identification.predict import predict_readings
from mtcomp.measurement.files import read_measurements
from mtcomp.models import load_model
from truth import TruthMachine, campaigns

UM = 1e-3
URAD = 1e-6
CORNERS = [(-150, -150), (150, -150), (150, 150), (-150, 150), (-150, -150), (0, 150), (150, 0), (0, -150),
           (-150, 0), (0, 150)]


def _truth() -> TruthMachine:
    """Curved positioning and straightness of X and Y, angular motions no file names, a squareness."""
    t = TruthMachine("xfyz")
    X, Y = t.components["X"], t.components["Y"]
    X["EXX"] = lambda x: UM * (8.0 * np.sin(2 * np.pi * (x + 400) / 600) + 15 * x / 400)
    X["EYX"] = lambda x: UM * (6.0 * (x / 400) ** 2 + 0.2 * np.sin(np.pi * x / 150))
    X["EZX"] = lambda x: UM * 3.0 * np.sin(np.pi * x / 400)
    X["EAX"] = lambda x: URAD * 20.0 * np.cos(np.pi * x / 800)
    X["EBX"] = lambda x: URAD * 10.0 * np.sin(np.pi * x / 400)
    X["ECX"] = lambda x: URAD * 15.0 * x / 400
    Y["EXY"] = lambda y: UM * 4.0 * (y / 300) ** 2
    Y["EYY"] = lambda y: UM * (10 * y / 300 + 3 * np.sin(np.pi * y / 150))
    Y["EZY"] = lambda y: UM * 2.0 * np.cos(np.pi * y / 300)
    Y["EAY"] = lambda y: URAD * 12.0 * y / 300
    Y["ECY"] = lambda y: URAD * 8.0 * np.cos(np.pi * y / 300)
    t.squareness["C0Y"] = 40e-6
    return t


def run_circle(truth, tmp, corners, *, known: bool, setup: bool = False, seed: int = 10) -> str:
    """One circle of radius 150 mm about the origin in XY, both ways (``tmp / "circle.csv"``, the
    bar's length offset drawn with ``setup``), identified (``--known-setup`` when ``known``) into
    ``tmp / "m.json"``, and a program through ``corners`` (the first a rapid) compensated at G54 =
    0 (``tmp / "blocks.csv"``); identify's and compensate's printed output."""
    path = tmp / "circle.csv"
    campaigns.ballbar_circles(truth, path, np.random.default_rng(seed), planes=("XY",), radius_mm=150.0,
                              centre_mm=(0.0, 0.0, 0.0), n_points=72, setup=setup, noise_mm=0.0002)
    prog = tmp / "prog.nc"
    prog.write_text("%\nG21 G90 G17\nG54\n" + "".join(
        f"G{0 if i == 0 else 1} X{x:.3f} Y{y:.3f} Z0.000{'' if i == 0 else ' F1000'}\n"
        for i, (x, y) in enumerate(corners)) + "M30\n%\n")
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["identify", "xfyz", str(path), *(["--known-setup", str(path)] if known else []),
                     "-o", str(tmp / "m.json")]) == 0
        assert main(["compensate", "xfyz", str(tmp / "m.json"), str(prog), "-o", str(tmp / "out.nc"),
                     "--work-offset", "G54=X0,Y0,Z0", "--subdivide-tol-um", "0",
                     "--report", str(tmp / "blocks.csv")]) == 0
    return out.getvalue()


@pytest.fixture(scope="module")
def circle(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("split")
    truth = _truth()
    # a bar of calibrated length (--known-setup): without it the bar's length offset takes a scale
    # of X and Y alike, which the fit holds at zero, a set-up's trade and not the penalty's split
    # (tests/test_identify_ballbar_scale.py)
    run_circle(truth, tmp, CORNERS, known=True)
    return truth, tmp / "circle.csv", tmp


def _blocks(truth, tmp):
    """(miss (n,) um, the largest of x's and y's, sd (n,) um, rows) of compensate's report."""
    rows = list(csv.DictReader(open(tmp / "blocks.csv")))
    assert len(rows) == len(CORNERS)
    q = np.array([[float(r["x_mm"]), float(r["y_mm"]), float(r["z_mm"])] for r in rows])
    true = (truth.true_deviation(q)[0] - truth.true_deviation(np.zeros((1, 3)))[0]) / UM
    model = np.array([[float(r[f"e{a}_before_um"]) for a in "xy"] for r in rows])
    sd = np.array([float(r["correction_sd_um"] or "nan") for r in rows])
    # x and y: a circle in XY reads nothing of Z, held at zero and said so
    return np.abs(model - true[:, :2]).max(axis=1), sd, rows


def test_the_angular_motions_held_at_zero_leave_x_and_y_their_standard_errors(circle):
    # before: blank at every block (the angular class, which no file names and the assumption
    # holds at zero, counted as a class the data cannot bound, and through that assumption every
    # open combination of X's and Y's profiles was marked undetermined): nothing corrected
    _, sd, _ = _blocks(*circle[::2])
    assert np.all(np.isfinite(sd)), sd


def test_a_prediction_resting_on_the_penalty_s_split_carries_it_in_its_standard_error(circle):
    miss, sd, rows = _blocks(*circle[::2])
    # the fit misses by 0.9-2.8 um: the split is not the data's
    assert miss.max() > 2.0, miss
    # at the fitted weights alone sd 0.4-0.7 um, misses up to 4.3 sd; now 1.0-2.2 um, misses
    # within 1.6 sd, and every block still corrected
    assert np.all(miss <= 2.5 * sd), (miss, sd)
    assert all(r["corrected"] == "1" for r in rows)


def test_what_the_circle_reads_keeps_its_standard_error(circle):
    _, path, tmp = circle
    pred = predict_readings(load_model(tmp / "m.json"), read_measurements(path)).columns
    sd = np.asarray(pred["pred_length_mm_sd"], dtype=float) * 1e3
    # the bar's length on the circle, which the data read: 0.06 um, as before
    assert np.all(np.isfinite(sd)) and sd.max() < 0.15, sd

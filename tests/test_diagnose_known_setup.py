"""`mtcomp diagnose --known-setup` (a new user's finding: diagnose had no such option, so a campaign
read with a calibrated bar lost what the bar's known length measures on the route the README gives,
identify then diagnose): a calibrated bar's circle reads the machine's scale, which an unknown bar
length would take up.

The oracle is the independent truth machine (tests/truth, no code shared with mtcomp): an XFYZ
machine whose X and Y both grow 20 um/m from the origin, read with one circle of radius 100 mm
about the origin both ways with an exact bar (no calibration offset): every length is 2 um long.
A second circle the fit never saw, at the same place, is predicted to the truth's noise-free
lengths with the set-up known (the bar's 2 um growth is the machine's), and without it the 2 um is
taken by the bar's length offset and the model has none of it."""
from __future__ import annotations

import numpy as np
import pytest

from mtcomp.cli import main
from mtcomp.identification.predict import predict_readings
from mtcomp.measurement.files import read_measurements
from mtcomp.models import load_model
from truth import TruthMachine, campaigns
from truth import profiles as P

SCALE = 20e-6


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("known")
    truth = TruthMachine.zero("xfyz")
    truth.components["X"]["EXX"] = P.Linear(0.0, SCALE)
    truth.components["Y"]["EYY"] = P.Linear(0.0, SCALE)
    rng = np.random.default_rng(3)
    circle = campaigns.ballbar_circles(truth, tmp / "circle.csv", rng, planes=("XY",), setup=False,
                                       centre_mm=(0.0, 0.0, 0.0), noise_mm=0.0001)
    again = campaigns.ballbar_circles(truth, tmp / "again.csv", rng, planes=("XY",), setup=False,
                                      centre_mm=(0.0, 0.0, 0.0), noise_mm=0.0, n_points=40)
    return tmp, circle.path, again


def _diagnosed(tmp, name, *extra):
    assert main(["diagnose", "xfyz", *map(str, extra), "--json", str(tmp / f"{name}.json"),
                 "-o", str(tmp / f"{name}_model.json"), "-q"]) == 0
    return load_model(tmp / f"{name}_model.json")


def _offset_um(model, again) -> np.ndarray:
    pred = predict_readings(model, read_measurements(again.path)).columns
    return (np.asarray(pred["pred_length_mm"]) - again.columns["length_mm"]) * 1e3


def test_a_calibrated_bar_s_circle_reads_the_scale_with_known_setup(campaign, capsys):
    tmp, circle, again = campaign
    known = _offset_um(_diagnosed(tmp, "known", circle, "--known-setup", circle), again)
    free = _offset_um(_diagnosed(tmp, "free", circle), again)
    capsys.readouterr()
    # every true length is 100 mm + 2 um; known: predicted to 0.1 um, free: the 2 um is the bar's
    assert np.abs(known).max() < 0.1, known
    assert abs(np.mean(free) + 2.0) < 0.2, free


def test_the_start_model_s_known_setup_is_taken_and_said(campaign, capsys):
    tmp, circle, again = campaign
    assert main(["identify", "xfyz", str(circle), "--known-setup", str(circle), "-o",
                 str(tmp / "identified.json")]) == 0
    capsys.readouterr()
    started = _diagnosed(tmp, "started", circle, "--start", tmp / "identified.json")
    err = capsys.readouterr().err
    assert "note: the set-up of circle taken as known, as the start model was fitted" in err
    assert np.abs(_offset_um(started, again)).max() < 0.1


def test_known_setup_naming_no_data_file_is_refused(campaign, capsys):
    tmp, circle, _ = campaign
    assert main(["diagnose", "xfyz", str(circle), "--known-setup", "nothing.csv", "--json",
                 str(tmp / "x.json"), "-q"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--known-setup nothing.csv: names none of the data files" in err[0]
    assert not (tmp / "x.json").exists()

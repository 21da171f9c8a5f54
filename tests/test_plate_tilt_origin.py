"""A grid plate alone reads its heights only up to its own tilt: the slopes of X's and Y's
straightness in Z trade with the plate's set-up. Where the fit held those slopes at zero, the
heights it predicted hung on where the machine's zero is (X's roll acts on the tip over its distance
along Y from Y = 0): the same plate in negative machine coordinates gave other heights. The tilt is
among the combinations the data do not determine, and it is held where it predicts the least error
over the region, which is the same region whatever coordinates name it.

Oracle: the independent truth machine (tests/truth, no code shared with the model) with X rolling
by 0.4 urad per mm of X (a twist of the bed's heights, dz = EAX(x) y) and X's scale 400 um/m; one
noise-free 9 x 6 plate at Z -80 mm, written once in machine coordinates X 0..1000, Y 0..600 and once
shifted to X -1000..0, Y -600..0 (the same physical readings)."""
import csv

import numpy as np
import pytest

from mtcomp.cli import main
from mtcomp.identification.predict import Undetermined
from mtcomp.models.evaluate import evaluate
from mtcomp.models.model_file import load_model

ROLL, SCALE = 0.4e-6, 400e-6
SHIFT = np.array([1000.0, 600.0, 0.0])
MACHINE = ('name = "plate-{0}"\ntopology = "FXYZ"\ntool_length_mm = 0.0\n[axes.X]\ntravel_mm = [{1}, {2}]\n'
           '[axes.Y]\ntravel_mm = [{3}, {4}]\n[axes.Z]\ntravel_mm = [-100.0, 0.0]\n')


@pytest.fixture(scope="module")
def models(tmp_path_factory):
    from truth import TruthMachine
    from truth import campaigns as tc
    from truth import profiles as P
    d = tmp_path_factory.mktemp("tilt")
    (d / "pos.toml").write_text(MACHINE.format("pos", 0.0, 1000.0, 0.0, 600.0))
    (d / "neg.toml").write_text(MACHINE.format("neg", -1000.0, 0.0, -600.0, 0.0))
    truth = TruthMachine.zero(str(d / "pos.toml"))
    truth.components["X"]["EAX"] = P.Linear(0.0, ROLL)
    truth.components["X"]["EXX"] = P.Linear(0.0, SCALE)
    tc.points(truth, d / "plate.csv", np.random.default_rng(3), grid=(9, 6, 1), plane={"Z": -80.0},
              directions=(1,), setup=False, noise_um=0.0, tool_lengths_mm=(0.0,))
    with open(d / "plate.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    with open(d / "plate_neg.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        for r in rows:
            w.writerow({**r, "x_mm": float(r["x_mm"]) - SHIFT[0], "y_mm": float(r["y_mm"]) - SHIFT[1]})
    out = []
    for name, data in (("pos", "plate.csv"), ("neg", "plate_neg.csv")):
        assert main(["identify", str(d / f"{name}.toml"), str(d / data), "-o", str(d / f"{name}.json")]) == 0
        out.append(load_model(d / f"{name}.json"))
    return truth, out


def _points():
    xs, ys = np.meshgrid(np.linspace(150.0, 850.0, 8), np.linspace(100.0, 500.0, 5))
    P = np.c_[xs.ravel(), ys.ravel(), np.full(xs.size, -70.0)]
    return np.vstack([[150.0, 100.0, -70.0], P])             # the first: the part's datum


def _deviation(fitted, q):
    """(n, 3) um and (n, 3, n_params) the tip deviation's Jacobian at machine positions q."""
    p = np.asarray(fitted.params.values, dtype=float)
    ctx = fitted.model.default_context(len(q))
    qc = fitted.clamp(q)[0]
    d = evaluate(fitted.model, "deviation_function", qc, p, ctx)[0][:, :3] * 1e3
    J = evaluate(fitted.model, "tip_pjacobian_function", qc, p, ctx)[0]
    return d, J


def test_heights_do_not_depend_on_the_machine_zero(models):
    _, (pos, neg) = models
    P = _points()
    a, _ = _deviation(pos, P)
    b, _ = _deviation(neg, P - SHIFT)
    # the corrections compensate writes: relative to the part's datum (the first point)
    np.testing.assert_allclose((a - a[0])[:, 2], (b - b[0])[:, 2], rtol=0, atol=0.01)
    np.testing.assert_allclose((a - a[0])[:, :2], (b - b[0])[:, :2], rtol=0, atol=0.01)


def test_a_height_away_from_the_datum_is_not_determined(models):
    truth, (pos, neg) = models
    P = _points()
    for fitted, q in ((pos, P), (neg, P - SHIFT)):
        d, J = _deviation(fitted, q)
        und = Undetermined.of(fitted)
        rows = (J - J[:1])[1:]                          # (n, 3, n_params): relative to the datum
        sd_z = und.std(rows[:, 2, :] * 1e3)
        away = np.abs(q[1:, 0] - q[0, 0]) > 1.0
        assert np.all(np.isnan(sd_z[away])), sd_z
    # what the plate does determine is kept: the heights' shape, a plane apart, is the truth's
    d, _ = _deviation(pos, P)
    true = truth.true_deviation(np.vstack([truth.q_from(*p) for p in P]))[0] * 1e3
    A = np.c_[np.ones(len(P)), P[:, 0], P[:, 1]]
    shape = [e - A @ np.linalg.lstsq(A, e, rcond=None)[0] for e in (d[:, 2], true[:, 2])]
    np.testing.assert_allclose(shape[0], shape[1], rtol=0, atol=0.05)

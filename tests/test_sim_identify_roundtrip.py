"""Known truth through files: a standard campaign simulated from a random truth, written, read and
fitted with identify() gives back the truth's predictions (exactly without noise)."""
import numpy as np
import pytest

from mtcomp import load_machine, sim
from mtcomp.identification.fit import identify
from mtcomp.models import deviation


def fitted_vs_truth(name, noise_um, tmp_path, seed=0):
    # mtcomp's own simulator and the polynomial basis, whose every parameter the standard campaign
    # determines; the spline basis is checked on the independent machine (test_identify_independent)
    m = load_machine(name).with_basis("polynomial")
    truth = sim.random_truth(m, np.random.default_rng(seed))
    vm = sim.VirtualMachine(m, truth, noise_um=noise_um, noise_urad=noise_um, rng=np.random.default_rng(1))
    data = vm.campaign(sim.standard_campaign(m), tmp_path, noise=noise_um > 0)
    # mtcomp's simulator writes points in the workpiece frame: their set-up is known
    res = identify(m, list(data.values()), known_setup=[d.path for d in data.values() if d.kind == "points"])
    lo, hi = m.travel_bounds()
    q = np.random.default_rng(2).uniform(lo, hi, (60, m.n_axes))      # poses the campaign never saw
    true = deviation(truth.model, q, truth.params.values)[:, :3] * 1e3
    got = deviation(res.model, q, res.values)[:, :3] * 1e3
    return res, truth, true, got


@pytest.mark.parametrize("name", ["xfyz", "cafxyz"])
def test_noise_free_campaign_gives_back_the_truth(name, tmp_path):
    res, truth, true, got = fitted_vs_truth(name, 0.0, tmp_path)
    assert np.abs(true).max() > 5.0                                  # um: errors of machine size
    # the standard campaign determines the whole base model: on the turntable machine (its points
    # in the workpiece frame, the angular laser set-ups' zeros fitted) one rigid turn about Z
    # changes no reading, and the convention (X the reference axis) settles it
    assert [sorted(u.names) for u in res.undetermined] == []
    np.testing.assert_allclose(got, true, rtol=0, atol=1e-3)        # um; the CSV keeps 10 digits
    # every parameter is the truth's, the truth taken into the convention's gauge by hand: turning
    # the machine about Z by the slope of X's straightness in Y (EYX_1, um per m = urad) takes that
    # slope to zero and turns by as much the Y axis (C0Y), the A axis line (C0A) and the C zero (ECC_0)
    expected = dict(zip(truth.params.names, truth.params.file_values()))
    if name == "cafxyz":
        turn = expected["EYX_1"]
        assert abs(turn) > 0.1                                       # urad: the truth is off the gauge
        expected["EYX_1"] = 0.0
        for angle in ("C0Y", "C0A", "ECC_0"):
            expected[angle] -= turn
    fitted = dict(zip(res.params.names, res.params.file_values()))
    # um and urad per m^k: the cubic terms carry the readings' 10 digits as up to 2e-3 (1e-4 um at
    # 0.4 m); the turn is 0.31 urad
    for n, v in fitted.items():
        assert v == pytest.approx(expected[n], abs=1e-2), n


def test_noisy_campaign_predicts_within_the_noise(tmp_path):
    _, _, true, got = fitted_vs_truth("xfyz", 0.3, tmp_path)
    err = np.sqrt(np.mean((got - true) ** 2))
    assert 0.005 < err < 0.3                                        # um, below the reading noise

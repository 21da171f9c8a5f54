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
    return res, true, got


@pytest.mark.parametrize("name", ["xfyz", "cafxyz"])
def test_noise_free_campaign_gives_back_the_truth(name, tmp_path):
    res, true, got = fitted_vs_truth(name, 0.0, tmp_path)
    assert np.abs(true).max() > 5.0                                  # um: errors of machine size
    named = [sorted(u.names) for u in res.undetermined]
    if name == "xfyz":   # the standard campaign determines the whole base model
        assert named == []
    else:
        # on a turntable machine one rigid turn about Z stays free: the C zero (ECC_0) turns the part
        # as the tilt of X and Y (EYX_1, C0Y) and of the A axis (C0A) turn the machine, with the
        # angular laser set-ups' zero offsets
        assert {"ECC_0", "EYX_1", "C0Y", "C0A"} <= set().union(*named), named
    np.testing.assert_allclose(got, true, rtol=0, atol=1e-3)        # um; the CSV keeps 10 digits


def test_noisy_campaign_predicts_within_the_noise(tmp_path):
    res, true, got = fitted_vs_truth("xfyz", 0.3, tmp_path)
    err = np.sqrt(np.mean((got - true) ** 2))
    assert 0.005 < err < 0.3                                        # um, below the reading noise

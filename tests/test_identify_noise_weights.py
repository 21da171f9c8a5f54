"""identify's fit with each file weighted by its noise, on a 5-axis trunnion campaign whose files'
noise differs by a factor of five (tests/trunnion_case.py: a plain numpy truth sharing no code with
mtcomp; three laser runs, two R-test balls with a B backlash no base model has, a ball bar).

REML puts the angular errors' roughness weight at e^26..e^28 there, beside classes at e^-3. Before:
``--weights noise`` ended in a traceback (LinAlgError from a Cholesky factor of the summed
penalised matrix), and with the files' noise given per reading (as diagnose gives its noise floors)
the written covariance was not positive semi-definite and the squarenesses' standard errors were
several times what the data leave."""
from __future__ import annotations

import json

import numpy as np
import pytest

from mtcomp.cli import main
from mtcomp.identification._choice import bounded_split_variance
from mtcomp.identification._linalg import penalised_inverse
from trunnion_case import TRUTH_URAD, trunnion_campaign

SQUARENESS = ("C0Y", "B0Z", "A0Z")


#: the squarenesses' spread (urad) over 8 noise draws of the campaign (seeds 42..49; PYTHONPATH=tests:.
#: python benchmarks/bench_noise_weights_mc.py), the standard errors' Monte Carlo oracle
MC_SPREAD_URAD = {"C0Y": 3.05, "B0Z": 2.17, "A0Z": 1.24}


@pytest.fixture(scope="module", params=[42, 45])
def campaign(request, tmp_path_factory):
    # seed 42: the new user's files to the digit (before: a traceback); 45: the same truth, other
    # noise (before: squarenesses +-17 to 36 urad)
    return trunnion_campaign(tmp_path_factory.mktemp("trunnion"), request.param)


def _correlation(cov: np.ndarray) -> np.ndarray:
    sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    ok = np.isfinite(sd) & (sd > 0)
    return cov[np.ix_(ok, ok)] / np.outer(sd[ok], sd[ok])


def _assert_psd(cov: np.ndarray):
    corr = _correlation(cov)
    assert np.abs(corr).max() <= 1.0 + 1e-9
    assert np.linalg.eigvalsh(0.5 * (corr + corr.T)).min() >= -1e-9


def test_noise_weights_fit_without_traceback_and_write_a_psd_covariance(campaign, tmp_path, capsys):
    toml, paths = campaign
    out = tmp_path / "m.json"
    assert main(["identify", str(toml), *map(str, paths), "--weights", "noise", "-o", str(out)]) == 0
    model = json.loads(out.read_text())
    _assert_psd(np.array(model["uncertainty"]["covariance"], dtype=float))
    for name in SQUARENESS:
        p = model["parameters"][name]
        # each file's noise taken: the standard errors within a factor of 4 of what the noise moves
        # the value by over draws (conservative by 1.4 to 2.8: a held combination's variance is in)
        assert MC_SPREAD_URAD[name] / 4.0 < p["std_error"] < 4.0 * MC_SPREAD_URAD[name]
        assert abs(p["value"] - TRUTH_URAD[name]) < 3.0 * p["std_error"]


def _mixed(rng, n):
    """(n, n) a random orthonormal basis: every coordinate of the fit mixes every direction."""
    return np.linalg.qr(rng.standard_normal((n, n)))[0]


def test_a_light_penalty_beside_a_heavy_one_keeps_its_share_of_the_posterior():
    # a penalised matrix in a mixed basis U: 20 directions the data see (1), 20 that a class at
    # e^28 penalises (4e12), 20 the data see weakly (1e-3) with a light class on them (0.05), 10
    # that only the data see. Exact inverse: U diag(1 / (data + penalty)) U^T
    rng = np.random.default_rng(3)
    n = 70
    U = _mixed(rng, n)
    data = np.r_[np.ones(20), np.full(20, 1e-3), np.full(20, 1e-3), np.ones(10)]
    pen = np.r_[np.zeros(20), np.full(20, 4e12), np.full(20, 0.05), np.zeros(10)]
    AB = (U * data) @ U.T
    F = (U * np.sqrt(pen)).T                                   # F^T F = U diag(pen) U^T
    got = penalised_inverse(AB, factor=F)
    exact = (U / (data + pen)) @ U.T
    light = U[:, 40:60]
    # along the light class the posterior is 1 / (1e-3 + 0.05) = 18.9, not the data's 1000 (the cut
    # at the square's round-off took the light penalty for zero)
    np.testing.assert_allclose(light.T @ got @ light, light.T @ exact @ light, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(got, exact, rtol=0.0, atol=1e-6 * np.abs(exact).max())


def test_the_split_s_variance_is_the_posterior_at_the_lowered_weights_less_the_fit_s():
    # two classes that carry curvature (their penalty at the fit above s2): each weight lowered to
    # its REML bound, chi2_{nu, 0.05} / nu; the variance added on the splits' span is
    # s2 ((AB + sum c_k S_k)^-1 - (AB + sum S_k)^-1), a variance added, never taken
    from scipy.stats import chi2
    rng = np.random.default_rng(11)
    k = 12
    J = rng.standard_normal((30, k)) * np.r_[np.ones(8), np.full(4, 0.05)]
    AB = J.T @ J
    FB = [rng.standard_normal((5, k)) * 0.8, rng.standard_normal((4, k)) * 1.3]
    S = [G.T @ G for G in FB]
    Hinv = np.linalg.inv(AB + S[0] + S[1])
    s2, carried = 0.9, np.array([3.0, 2.0])
    splits = rng.standard_normal((k, 2))
    lowered = []
    for G, Sk in zip(FB, S):
        nu = max(np.linalg.matrix_rank(G) - np.trace(Hinv @ Sk), 1.0)
        lowered.append(Sk * chi2.ppf(0.05, nu) / nu)
    Q = np.linalg.qr(splits)[0]
    exact = s2 * Q @ Q.T @ (np.linalg.inv(AB + sum(lowered)) - Hinv) @ Q @ Q.T
    R = bounded_split_variance(AB, FB, Hinv, carried, s2, splits)
    np.testing.assert_allclose(R @ R.T, exact, rtol=0.0, atol=1e-9 * np.abs(exact).max())
    assert np.linalg.eigvalsh(exact).min() > -1e-12        # the oracle's: more variance, never less

"""The penalised fit's posterior beside a heavy penalty: a roughness weight of 1e14 (a profile the
data hardly bend) must not drop the directions the data fix and the penalty does not see (a
profile's offset and slope). Checked against the generalised eigenproblem P v = lambda G v, a
second formulation that never forms G + P: (G + P)^-1 = V diag(1 / (1 + lambda)) V^T and the
effective degrees of freedom sum(1 / (1 + lambda)). A pseudo-inverse of G + P cut relative to its
largest eigenvalue (1e15 here) dropped them: the fit's values, standard errors and degrees of
freedom came out wrong, and compensate's standard-error gate passed corrections it should hold."""
import numpy as np
import pytest
import scipy.linalg

from mtcomp.identification.linear import solve_linear
from mtcomp.models.params import ParamSpec


def _case(weight):
    rng = np.random.default_rng(3)
    n, k = 300, 16
    X = rng.normal(size=(n, k))
    y = X @ rng.normal(size=k) + rng.normal(0.0, 0.1, n)
    D = np.diff(np.eye(k), 2, axis=0)                 # second differences: offset and slope free
    specs = [ParamSpec(f"c{i}", "um", "g", False) for i in range(k)]
    return X, y, D, solve_linear(X, y, specs, weight * D.T @ D)


def _check(fit, X, y, b, Hinv, edf, rtol):
    n = len(y)
    s2 = float(np.sum((y - X @ b) ** 2)) / (n - edf)
    np.testing.assert_allclose(fit.values * 1e3, b, rtol=0, atol=rtol * np.abs(b).max())
    assert fit.dof == pytest.approx(n - edf, rel=0, abs=max(1e-6, rtol))
    np.testing.assert_allclose(fit.std_errors * 1e3, np.sqrt(s2 * np.diag(Hinv)), rtol=rtol, atol=0)


@pytest.mark.parametrize("weight", [1.0, 1e4])
def test_penalised_posterior_against_the_generalised_eigenproblem(weight):
    X, y, D, fit = _case(weight)
    G, P = X.T @ X, weight * D.T @ D
    lam, V = scipy.linalg.eigh(P, G)                  # V^T G V = I, V^T P V = diag(lam)
    lam = np.clip(lam, 0.0, None)
    Hinv = (V / (1.0 + lam)) @ V.T
    _check(fit, X, y, Hinv @ (X.T @ y), Hinv, float(np.sum(1.0 / (1.0 + lam))), rtol=1e-7)


@pytest.mark.parametrize("weight, rtol", [(1e12, 1e-5), (1e16, 2e-2)])
def test_a_heavy_penalty_leaves_the_least_squares_line(weight, rtol):
    """As the weight grows the profile tends to the least-squares fit within the penalty's null
    space (a line: offset and slope), to O(1/weight): the limit is the oracle. Forming G + S in
    double precision costs the data's share digits (at 1e16 the data's entries are 1e-14 of the
    penalty's): what is asked is that nothing the data fix is lost (before: at 1e16 the line's
    offset and slope were dropped, zero degrees of freedom, every value 0)."""
    X, y, D, fit = _case(weight)
    N = scipy.linalg.null_space(D)                    # (k, 2): offset and slope
    G = X.T @ X
    Hinv = N @ np.linalg.inv(N.T @ G @ N) @ N.T
    _check(fit, X, y, Hinv @ (X.T @ y), Hinv, 2.0, rtol=rtol)


def test_a_profile_seen_weakly_beside_one_seen_well_keeps_its_line_at_the_weights_bound():
    """Two profiles of 15 coefficients at REML's largest roughness weight (e^RHO_BOUND, where a
    clean campaign's straight profiles put it): the first read directly by 55 laser readings, the
    second only through a ball-bar circle, as a campaign sees a straightness beside a positioning.
    Oracle: the limit of the posterior as the weight grows, N (N^T G N)^-1 N^T with N the penalty's
    null space (each profile's offset and slope), to O(1/weight). Summed first, G + S lost the
    lines' digits to the penalty's round-off (values 0.01 um off, standard errors likewise); on a
    5-axis campaign's identify fit (301 unknowns, a condition number of 4e17 once summed) the
    inverse was wrong in every digit."""
    from mtcomp.identification.penalty import RHO_BOUND
    knots = np.linspace(-300.0, 300.0, 15)

    def hat(x):
        X = np.zeros((x.size, knots.size))
        j = np.clip(np.searchsorted(knots, x) - 1, 0, knots.size - 2)
        t = (x - knots[j]) / (knots[j + 1] - knots[j])
        X[np.arange(x.size), j], X[np.arange(x.size), j + 1] = 1.0 - t, t
        return X

    x = np.tile(np.linspace(-285.0, 285.0, 11), 5)
    th = np.linspace(0.0, 2.0 * np.pi, 72, endpoint=False)
    laser = np.hstack([hat(x), np.zeros((x.size, 15))])
    ballbar = np.hstack([hat(100.0 * np.cos(th)) * np.cos(th)[:, None],
                         hat(100.0 * np.cos(th)) * np.sin(th)[:, None]])
    X = np.vstack([laser, ballbar])
    rng = np.random.default_rng(5)
    y = X @ np.concatenate([0.03 * knots, 0.01 * knots + 2.0]) + rng.normal(0.0, 0.3, X.shape[0])
    D = np.kron(np.eye(2), np.diff(np.eye(15), 2, axis=0))
    G = X.T @ X
    S0 = D.T @ D * (np.median(np.diag(G)) / np.median(np.diag(D.T @ D)))
    specs = [ParamSpec(f"c{i}", "um", "g", False) for i in range(30)]
    fit = solve_linear(X, y, specs, np.exp(RHO_BOUND) * S0)
    N = scipy.linalg.null_space(D)                    # (30, 4): each profile's offset and slope
    Hinv = N @ np.linalg.inv(N.T @ G @ N) @ N.T
    _check(fit, X, y, Hinv @ (X.T @ y), Hinv, 4.0, rtol=1e-6)

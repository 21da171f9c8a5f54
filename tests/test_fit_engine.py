"""The one fit engine (mtcomp.identification.fit.solve on a FitProblem): its result type checked
against an independent formulation (numpy's lstsq on a design matrix written here from the model's
documented basis), and identify and diagnose giving the same base fit of the same data."""
from __future__ import annotations

import numpy as np
import pytest

from laser_files import write_x_positioning
from mtcomp.diagnose import diagnose
from mtcomp.identification.fit import identify, solve
from mtcomp.identification.problem import FitProblem, SolverOptions, unique_tags
from mtcomp.machine import load_machine
from mtcomp.measurement.files import read_measurements
from mtcomp.models import ErrorModel
from mtcomp.sim import random_campaign, random_parameters, simulate

EXX_TRUE_UM = (12.0, -7.0, 4.0)          # EXX_1..3: um at s = 1 m


def _positioning(tmp_path, rng):
    targets = np.linspace(-200.0, 200.0, 9)
    def error(t, d):
        s = t / 1000.0
        return sum(c * s ** (k + 1) for k, c in enumerate(EXX_TRUE_UM)) + 3.0   # + the laser's zero
    return write_x_positioning(tmp_path / "x.csv", targets, error, 3, 0.4, rng)


def test_result_type_against_lstsq_on_a_hand_built_design(tmp_path):
    """EXX(s) = sum_k EXX_k (s / 1 m)^k (um) plus the laser's zero offset: a linear model whose design
    is written by hand; the engine's values, standard errors, covariance, chi-square, degrees of
    freedom and AIC/BIC must be lstsq's to round-off."""
    rng = np.random.default_rng(3)
    path = _positioning(tmp_path, rng)
    machine = load_machine("xfyz").with_basis("polynomial")
    model = ErrorModel(machine)
    free = ["EXX_1", "EXX_2", "EXX_3"]
    problem = FitProblem.from_data(model, [read_measurements(path)], free=free, penalty=False,
                                   hold_weak=False)
    res = solve(problem, SolverOptions())
    # the oracle: columns (s/1m)^1..3 and 1, readings in um
    rows = np.loadtxt(path, delimiter=",", skiprows=1, usecols=(2, 3, 5))
    s, d, y = rows[:, 0] / 1000.0, rows[:, 1], rows[:, 2]
    X = np.column_stack([s, s ** 2, s ** 3, np.ones_like(s)])
    coef, sse, *_ = np.linalg.lstsq(X, y, rcond=None)
    n, p = X.shape
    s2 = float(sse[0]) / (n - p)
    # its standard errors: the residual variance of the same design with one reversal column per
    # target read from both sides (the approach direction there, 0 elsewhere), which the engine
    # counts as error a base model leaves, not noise (balanced runs: the coefficients are the same)
    R = np.column_stack([(rows[:, 0] == t) * d for t in np.unique(rows[:, 0])])
    full = np.column_stack([X, R])
    coef_full, sse_full, *_ = np.linalg.lstsq(full, y, rcond=None)
    np.testing.assert_allclose(coef_full[:p], coef, rtol=1e-9, atol=1e-9)
    s2_noise = float(sse_full[0]) / (n - p - R.shape[1])
    cov = s2_noise * np.linalg.inv(full.T @ full)[:p, :p]
    params = res.params
    got = np.array([params[nm] for nm in free]) * 1e3                 # internal mm -> um
    np.testing.assert_allclose(got, coef[:3], rtol=1e-8, atol=1e-9)
    assert res.nuisance_values[0] * 1e3 == pytest.approx(coef[3], rel=1e-8, abs=1e-9)
    se = np.array([params.stderr[params.index(nm)] for nm in free]) * 1e3
    np.testing.assert_allclose(se, np.sqrt(np.diag(cov))[:3], rtol=1e-7, atol=0)
    np.testing.assert_allclose(res.covar * 1e6, cov, rtol=1e-7, atol=1e-12 * np.abs(cov).max())
    assert list(params.vary) == [nm in free for nm in params.names]
    assert np.isnan(params.stderr[~params.vary]).all()
    assert res.ndata == n and res.nvarys == pytest.approx(p, abs=1e-9)
    assert res.nfree == pytest.approx(n - p, abs=1e-9)
    assert res.chisqr == pytest.approx(float(sse[0]), rel=1e-8, abs=0)
    assert res.redchi == pytest.approx(s2, rel=1e-8, abs=0)
    assert res.aic == pytest.approx(n * np.log(sse[0] / n) + 2 * p, rel=1e-9, abs=1e-9)
    assert res.bic == pytest.approx(n * np.log(sse[0] / n) + np.log(n) * p, rel=1e-9, abs=1e-9)
    assert res.directions.shape == (4, 4) and np.linalg.matrix_rank(res.directions) == 4
    np.testing.assert_allclose(res.residual, y - X @ coef, rtol=0, atol=1e-8)


def test_one_tag_rule():
    class F:
        def __init__(self, stem):
            from pathlib import Path
            self.path = Path(f"/d/{stem}.csv")
    from mtcomp.measurement.readings import file_tag
    files = [F("laser"), F("laser"), F("pts"), F("laser")]
    base = [file_tag(f) for f in files]
    assert unique_tags(files) == [base[0], base[0] + "#2", base[2], base[0] + "#3"]


def test_identify_and_diagnose_base_fit_give_the_same_parameters(tmp_path):
    """Points over the whole volume (um readings only) of a machine on the polynomial basis, noise
    only: diagnose adds no term, and the base parameters it reports are identify's."""
    machine = load_machine("xfyz").with_basis("polynomial")
    model = ErrorModel(machine)
    rng = np.random.default_rng(41)
    camp = random_campaign(machine, rng, n_points=400)
    p = random_parameters(model, rng, mask=model.base_mask)
    data = [simulate(model, camp["points"], p, noise_um=0.3, rng=rng)]
    res = identify(machine, data)
    diag = diagnose(machine, data)
    assert not [f for f in diag.findings if f.effect != "unexplained"], diag.summary()
    names = [s.name for s in model.param_specs if s.base]
    fm = diag.model.params
    ident = np.array([res.params[nm] for nm in names]) * 1e3
    diagnosed = np.array([fm[nm] for nm in names]) * 1e3
    assert np.abs(ident).max() > 1.0                       # something was fitted (um, urad)
    np.testing.assert_allclose(diagnosed, ident, rtol=0, atol=1e-6 * np.abs(ident).max())


def test_linear_engine_holds_what_the_data_leave_open_like_a_minimum_norm_lstsq():
    """A design with two equal columns: the engine determines their sum, holds the difference at zero
    (standard errors NaN) and otherwise agrees with numpy's minimum-norm lstsq; with a ridge on those
    two columns (the penalty sees the difference) both are determined and the values are the
    penalised normal equations' solution."""
    from mtcomp.identification.linear import solve_linear
    from mtcomp.models.params import ParamSpec
    rng = np.random.default_rng(8)
    n = 50
    a = rng.normal(size=n)
    X = np.column_stack([a, a, np.ones(n), rng.normal(size=n)])
    y = X @ [1.0, 2.0, 0.5, -1.0] + rng.normal(0, 0.1, n)
    specs = [ParamSpec(f"c{i}", "um", "g", False) for i in range(4)]
    res = solve_linear(X, y, specs)
    ref = np.linalg.lstsq(X, y, rcond=None)[0]
    np.testing.assert_allclose(res.values * 1e3, ref, rtol=1e-9, atol=1e-12)
    assert res.rank == 3 and list(res.determined) == [False, False, True, True]
    assert np.isnan(res.std_errors[:2]).all() and np.isfinite(res.std_errors[2:]).all()
    assert res.nfree == pytest.approx(n - 3, abs=1e-9)
    P = np.diag([0.7, 0.7, 0.0, 0.0])
    pen = solve_linear(X, y, specs, P)
    np.testing.assert_allclose(pen.values * 1e3, np.linalg.solve(X.T @ X + P, X.T @ y), rtol=1e-9, atol=1e-12)
    assert pen.determined.all() and pen.rank == 4


@pytest.mark.parametrize("given_um", [1.0, 0.1])
def test_known_noise_is_the_least_residual_variance_of_the_posterior(tmp_path, given_um):
    """Readings weighted by a noise the caller knows (diagnose's floors from repeats), ``known_noise``:
    the standard errors are at that noise when the residuals scatter less (given 1 um, the readings'
    0.4 um: sqrt(diag((X^T X)^-1)) times 1 um, the oracle written here), and at the residuals' own
    scatter when they scatter more (given 0.1 um: as without a given noise)."""
    rng = np.random.default_rng(3)
    path = _positioning(tmp_path, rng)
    model = ErrorModel(load_machine("xfyz").with_basis("polynomial"))
    free = ["EXX_1", "EXX_2", "EXX_3"]
    data = [read_measurements(path)]
    n = len(data[0])

    def se(**kw):
        problem = FitProblem.from_data(model, data, free=free, penalty=False, hold_weak=False, **kw)
        params = solve(problem, SolverOptions()).params
        return np.array([params.stderr[params.index(nm)] for nm in free]) * 1e3

    known = FitProblem.from_data(model, data, free=free, penalty=False, hold_weak=False,
                                 weights=np.full(n, given_um))
    known.known_noise = True
    params = solve(known, SolverOptions()).params
    got = np.array([params.stderr[params.index(nm)] for nm in free]) * 1e3
    s = np.loadtxt(path, delimiter=",", skiprows=1, usecols=(2,)) / 1000.0
    X = np.column_stack([s, s ** 2, s ** 3, np.ones_like(s)])
    at_given = given_um * np.sqrt(np.diag(np.linalg.inv(X.T @ X)))[:3]
    own = se()
    # the readings scatter by 0.4 um: the given 1 um is above it, the given 0.1 um below
    np.testing.assert_allclose(got, at_given if given_um > 0.5 else own, rtol=1e-7, atol=0)
    assert np.all(got >= own * (1 - 1e-9)) and (given_um < 0.5 or np.all(got > 1.5 * own))
    # without known_noise the given noise only weights: the residuals' own scatter sizes the errors
    np.testing.assert_allclose(se(weights=np.full(n, given_um)), own, rtol=1e-7, atol=0)

"""Drift models of thermal files that carry forward in time (ISO 230-3), validated forward in time.

Every candidate is a linear model of each displacement channel in a set of drift features (absolute
temperatures ``temp_<s>`` in degC, spindle heat ``spindle_lag_<tau>`` in 1000 rpm through a
first-order lag, time ``time_h`` or a settling ``time_exp_<tau>``), with an intercept, fitted by
ridge regression on standardised features (the intercept is not penalised). The penalty and the
choice among candidates come from forward-chaining validation: the rows, in time order, are cut into
``n_folds + 1`` equal blocks; fold k fits blocks 0..k-1 and predicts block k, so every score is a
prediction of the future from the past. docs/thermal.md explains it for a user.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import minimize_scalar

from ..diagnose._analysis import N_FOLDS, forward_folds
from ..errors import InputError
from ..measurement.drift import feature_value

#: time constants (s) of the spindle heat lags combined with the temperatures
DEFAULT_LAGS_S = (900.0, 3600.0)
#: ridge penalties tried (per reading, on standardised features); 0 is plain least squares
PENALTIES = (0.0, 1e-4, 3e-4, 1e-3, 3e-3, 1e-2, 3e-2, 1e-1, 3e-1, 1.0)
#: a more complex candidate must lower the forward-validated sum of squares by this share
PARSIMONY = 0.05
#: the residuals' lag-1 autocorrelation is taken no closer to 1 than this (an effective count of at
#: least n / 1999 independent readings)
RHO_MAX = 0.999
#: two drift models predict the record alike when the difference of their forward sums of squares is
#: within this many of its standard errors (:func:`alike_z`)
ALIKE_Z = 2.0
#: the drivers compensate follows (it is told temperatures and a spindle speed, not a time)
COMPENSABLE = ("temperature", "spindle")


# ------------------------------------------------------------------------------------ linear algebra
@dataclass(frozen=True)
class Ridge:
    """y = intercept + X @ coef (feature units): coef (k, m), intercept (m,), penalty."""

    coef: np.ndarray
    intercept: np.ndarray
    penalty: float

    def predict(self, X: np.ndarray) -> np.ndarray:
        return self.intercept + X @ self.coef


def fit_ridge(X: np.ndarray, Y: np.ndarray, penalty: float) -> Ridge:
    """Ridge regression of Y (n, m) on X (n, k) with an unpenalised intercept: minimises
    ``|Y - b - X C|^2 + penalty * n * |S C|^2`` with S the features' standard deviations (the
    penalty acts on standardised features, so it does not depend on their units)."""
    n, k = X.shape
    mx, my = X.mean(axis=0), Y.mean(axis=0)
    sx = X.std(axis=0)
    sx = np.where(sx > 0, sx, 1.0)
    Xs = (X - mx) / sx
    if k == 0:
        return Ridge(np.zeros((0, Y.shape[1])), my, penalty)
    G = Xs.T @ Xs + penalty * n * np.eye(k)
    B = np.linalg.lstsq(G, Xs.T @ (Y - my), rcond=None)[0]
    coef = B / sx[:, None]
    return Ridge(coef, my - mx @ coef, penalty)


def channel_fits(X: np.ndarray, Y: np.ndarray, penalty: float, channels=None) -> list:
    """The ridge of :func:`fit_ridge` solved by the package's fit engine
    (:func:`mtcomp.identification.linear.solve_linear`), one :class:`FitResult` per channel: in raw
    feature units with the intercept a column of ones, the penalty is ``penalty n sum_i s_i^2 c_i^2``
    (s_i the feature's standard deviation, the intercept free). Parameters ``TD_<channel>_<k>``
    (the k-th feature's coefficient, um per feature unit) and ``TD_<channel>_zero`` (um); the
    covariance is the Bayesian posterior (Wood 2006), s^2 (X1^T X1 + P)^-1 with s^2 the channel's
    residual variance over its effective degrees of freedom. It takes the residuals as independent;
    :func:`forward_covariance` makes it fit residuals correlated in time (docs/thermal.md)."""
    from ..identification.linear import solve_linear
    from ..models.params import ParamSpec
    n, k = X.shape
    channels = [str(j) for j in range(Y.shape[1])] if channels is None else list(channels)
    X1 = np.column_stack([X, np.ones(n)])
    P = np.diag(np.r_[penalty * n * (X.std(axis=0) ** 2 if k else np.zeros(0)), 0.0])
    out = []
    for j, ch in enumerate(channels):
        specs = [ParamSpec(f"TD_{ch}_{i}", "um", f"thermal:{ch}", False) for i in range(k)]
        specs.append(ParamSpec(f"TD_{ch}_zero", "um", f"thermal:{ch}", False))
        out.append(solve_linear(X1, Y[:, j], specs, P))
    return out


def ridge_covariance(X: np.ndarray, Y: np.ndarray, ridge: Ridge) -> np.ndarray:
    """(m, k + 1, k + 1) the posterior covariance of each channel's (coef..., intercept) (feature
    units; um^2 per feature unit^2) of :func:`fit_ridge`'s fit (:func:`channel_fits`)."""
    return np.array([r.covariance * 1e6 for r in channel_fits(X, Y, ridge.penalty)])


def residual_autocorrelation(resid: np.ndarray) -> np.ndarray:
    """(m,) lag-1 autocorrelation of each channel's residuals (n, m) in time order, clipped to
    [0, ``RHO_MAX``]: residuals that alternate in sign are not taken as worth more than independent
    ones, and a channel whose residual barely changes from reading to reading keeps a finite
    effective count."""
    r = resid - resid.mean(axis=0)
    num, den = np.sum(r[1:] * r[:-1], axis=0), np.sum(r * r, axis=0)
    rho = np.divide(num, den, out=np.zeros_like(num), where=den > 0)
    return np.clip(rho, 0.0, RHO_MAX)


def forward_covariance(covariance: np.ndarray, rho: np.ndarray, model_error_um: np.ndarray) -> np.ndarray:
    """(m, k + 1, k + 1) the covariance of each channel's (coefficients..., intercept) that a
    forward prediction's standard error is computed from, um^2 per feature unit^2.

    covariance : (m, k + 1, k + 1) the posterior of :func:`channel_fits` (independent residuals).
    rho : (m,) lag-1 autocorrelation of the residuals (:func:`residual_autocorrelation`): the
        readings are worth an effective count n (1 - rho) / (1 + rho) of independent ones (AR(1)),
        so the posterior is scaled by (1 + rho) / (1 - rho).
    model_error_um : (m,) the forward-validated rms of each channel: what the model misses at a
        reading it was not fitted on, correlated in time like the residuals, so at any one time an
        unknown offset. It is added to the intercept's variance (every prediction moves one to one
        with the intercept), so a prediction's variance is the parameters' share plus its square.
    """
    out = np.asarray(covariance, dtype=float) * ((1.0 + rho) / (1.0 - rho))[:, None, None]
    out[:, -1, -1] += np.asarray(model_error_um, dtype=float) ** 2
    return out


def forward_predictions(X: np.ndarray, Y: np.ndarray, penalty: float, folds) -> np.ndarray:
    """(n, m) each fold's test block predicted from its training blocks; NaN in the first block."""
    out = np.full(Y.shape, np.nan)
    for train, test in folds:
        out[test] = fit_ridge(X[train], Y[train], penalty).predict(X[test])
    return out


def forward_sse(X: np.ndarray, Y: np.ndarray, penalty: float, folds) -> np.ndarray:
    """(m,) forward-chained sum of squared prediction errors per channel."""
    return np.nansum((forward_predictions(X, Y, penalty, folds) - Y) ** 2, axis=0)


# ------------------------------------------------------------------------------------ candidates
@dataclass
class CandidateScore:
    """One drift model tried: ``driver`` (report name), ``drivers`` (every driver it uses),
    ``features``, penalty chosen, forward-validated rms per channel (um), time constants (s)."""

    label: str
    driver: str
    drivers: list
    features: list
    complexity: int
    penalty: float = 0.0
    forward_sse: np.ndarray | None = None
    forward_rms_um: np.ndarray | None = None
    time_constants_s: list = field(default_factory=list)
    #: (n, m) forward prediction minus reading (NaN in the first block, which is only fitted)
    forward_err: np.ndarray | None = None

    @property
    def total_sse(self) -> float:
        return float(np.sum(self.forward_sse))


def feature_matrix(context, names) -> np.ndarray:
    """(n, len(names)) drift features of a file's context (mtcomp.measurement.drift.feature_value)."""
    cols = [feature_value(nm, context) for nm in names]
    return np.column_stack(cols) if cols else np.zeros((len(context.t), 0))


def _fit_tau(context, Y, make_name, lo, hi) -> float:
    """Time constant (s) in [lo, hi] whose single feature fits Y best (least squares, 1-D search in
    log tau), rounded to whole seconds."""
    def sse(log_tau):
        X = feature_matrix(context, [make_name(float(np.exp(log_tau)))])
        r = fit_ridge(X, Y, 0.0).predict(X) - Y
        return float(np.sum(r ** 2))
    res = minimize_scalar(sse, bounds=(np.log(lo), np.log(hi)), method="bounded", options={"xatol": 0.01})
    return float(np.round(np.exp(res.x)))


def lag_name(tau_s: float) -> str:
    return f"spindle_lag_{round(tau_s):d}"


def usable_temperatures(context) -> list[str]:
    """Sensors with a reading in every row that is not constant (the others are left out)."""
    return [s for s, v in context.temperatures.items() if np.isfinite(v).all() and np.ptp(v) > 0]


def candidates(context, Y, lags_s=DEFAULT_LAGS_S) -> list[CandidateScore]:
    """The drift models a file supports (features not yet scored), simplest first."""
    t = np.asarray(context.t, dtype=float)
    span = float(np.ptp(t))
    out = [CandidateScore("no drift", "none", [], [], 0),
           CandidateScore("steady drift in time", "time", ["time"], ["time_h"], 1)]
    tau = _fit_tau(context, Y, lambda tau: f"time_exp_{round(tau):d}", span / 30.0, span * 3.0)
    out.append(CandidateScore("settling drift in time", "time", ["time"], [f"time_exp_{round(tau):d}"],
                              2, time_constants_s=[tau]))
    rpm = np.nan_to_num(np.asarray(context.spindle_rpm, dtype=float))
    spindle = np.ptp(rpm) > 0
    if spindle:
        tau = _fit_tau(context, Y, lag_name, 60.0, max(span, 120.0))
        out.append(CandidateScore("spindle heat", "spindle", ["spindle"], [lag_name(tau)], 3,
                                  time_constants_s=[tau]))
    temps = usable_temperatures(context)
    if temps:
        out.append(CandidateScore("temperatures", "temperature", ["temperature"],
                                  [f"temp_{s}" for s in temps], 4))
        if spindle:
            out.append(CandidateScore("temperatures and spindle heat", "temperature",
                                      ["temperature", "spindle"],
                                      [f"temp_{s}" for s in temps] + [lag_name(x) for x in lags_s], 5,
                                      time_constants_s=[float(x) for x in lags_s]))
    return out


# ------------------------------------------------------------------------------------ the fit
@dataclass
class ThermalFit:
    """The drift model chosen for a thermal file, and how it was chosen.

    channels : channel names (``disp_<name>_um``). chosen : the :class:`CandidateScore` kept.
    scores : every candidate tried. ridge : the chosen model refitted on every reading (um), by the
    package's fit engine: ``results``, one :class:`~mtcomp.identification.result.FitResult` per
    channel (:func:`channel_fits`; the ridge is its penalty).
    noise_um : robust noise of one reading (1.4826 MAD of successive differences / sqrt 2), pooled.
    max_drift_um : (m,) largest |reading - first reading| per channel (ISO 230-3 drift).
    fitted_um : (n, m) the model's readings at the file's rows; measured_um : (n, m) the readings.
    forward_um : (n, m) each block predicted from the blocks before it (NaN in the first block).
    t_s : (n,) time of the rows (in time order, as every array here); spindle_rpm : (n,).
    temperature_means, temperature_ranges : sensor -> mean, (lowest, highest) reading over the
        record (degC), for the sensors the chosen model reads.
    first_reading : feature -> its value at the record's first reading in time (``temp_<s>`` degC,
        a spindle heat at its start value), for the features the chosen model reads: the thermal
        state from which compensate corrects the drift by default (docs/thermal.md).
    """

    channels: list
    chosen: CandidateScore
    scores: list
    ridge: Ridge
    noise_um: float
    max_drift_um: np.ndarray
    fitted_um: np.ndarray
    measured_um: np.ndarray
    t_s: np.ndarray
    forward_um: np.ndarray
    spindle_rpm: np.ndarray
    n_folds: int = N_FOLDS
    temperature_means: dict = field(default_factory=dict)
    left_out: list = field(default_factory=list)
    #: (m, k + 1, k + 1) covariance of each channel's (coefficients, intercept) for forward
    #: predictions, um per feature unit (:func:`forward_covariance`: the posterior of
    #: :func:`channel_fits` for residuals correlated in time, the model error on the intercept)
    covariance: np.ndarray | None = None
    temperature_ranges: dict = field(default_factory=dict)
    results: list = field(default_factory=list)
    first_reading: dict = field(default_factory=dict)

    def summary(self) -> str:
        lines = [f"thermal drift ({len(self.t_s)} readings over {np.ptp(self.t_s) / 3600:.3g} h, "
                 f"noise {self.noise_um:.3g} um); forward-chained validation, {self.n_folds} folds "
                 "(fit the past, predict the next block):"]
        for s in self.scores:
            mark = "*" if s is self.chosen else " "
            lines.append(f" {mark} {s.label:<32s} rms {_rms(s.forward_rms_um):8.3f} um"
                         + (f"  (time constants {', '.join(f'{x:g}' for x in s.time_constants_s)} s)"
                            if s.time_constants_s else ""))
        if self.left_out:
            lines.append(f"   temperatures left out (blank or constant readings): {', '.join(self.left_out)}")
        lines.append("channel   max drift um  fitted rms um  forward rms um")
        resid = self.fitted_um - self.measured_um
        for j, ch in enumerate(self.channels):
            lines.append(f"{ch:<9s} {self.max_drift_um[j]:12.3f}  {_rms(resid[:, j]):13.3f}  "
                         f"{self.chosen.forward_rms_um[j]:14.3f}")
        return "\n".join(lines)


def _rms(v) -> float:
    v = np.asarray(v, dtype=float)
    return float(np.sqrt(np.mean(v ** 2))) if v.size else float("nan")


def robust_noise_um(Y: np.ndarray) -> float:
    """Noise of one reading (um): 1.4826 MAD of successive differences / sqrt 2, pooled over channels."""
    d = np.diff(Y, axis=0)
    if d.shape[0] == 0:
        return float("nan")
    mad = np.median(np.abs(d - np.median(d, axis=0)), axis=0) * 1.4826 / np.sqrt(2.0)
    return float(np.sqrt(np.mean(mad ** 2)))


def thermal_arrays(data):
    """(order, channels, Y (n, m) um) of a thermal file, rows in time order; InputError when a channel
    or the time is blank (a drift model needs complete readings)."""
    t = np.asarray(data.t, dtype=float)
    if not np.isfinite(t).all():
        bad = int(np.flatnonzero(~np.isfinite(t))[0])
        data.fail("blank t_s: every reading of a thermal file needs its time", bad)
    if np.ptp(t) <= 0:
        data.fail("t_s does not advance: a drift record needs readings spread in time")
    order = np.argsort(t, kind="stable")
    channels = list(data.channels)
    Y = np.column_stack([data.channels[ch] for ch in channels]) * 1e3
    if not np.isfinite(Y).all():
        r, c = np.argwhere(~np.isfinite(Y))[0]
        data.fail(f"blank disp_{channels[c]}_um: the drift fit needs every channel at every reading", r)
    return order, channels, Y[order]


def fit_thermal(data, lags_s=DEFAULT_LAGS_S, n_folds: int = N_FOLDS, penalties=PENALTIES) -> ThermalFit:
    """Choose and fit the drift model of a thermal file (measurement.files.ThermalData), validated
    forward in time (module docstring). Raises InputError when the file is too short."""
    order, channels, Y = thermal_arrays(data)
    ctx = data.context.subset(order)
    n = len(order)
    try:
        folds = forward_folds(n, n_folds)
    except ValueError as exc:
        raise InputError(f"thermal drift: {exc}", data.path) from None
    scores = candidates(ctx, Y, lags_s)
    for s in scores:
        X = feature_matrix(ctx, s.features)
        if not np.isfinite(X).all():
            s.forward_sse = np.full(Y.shape[1], np.inf)
            s.forward_rms_um = np.full(Y.shape[1], np.inf)
            continue
        options = penalties if X.shape[1] > 1 else (0.0,)
        err = [forward_predictions(X, Y, lam, folds) - Y for lam in options]
        sse = [np.nansum(e ** 2, axis=0) for e in err]
        best = int(np.argmin([np.sum(x) for x in sse]))
        s.penalty, s.forward_sse, s.forward_err = float(options[best]), sse[best], err[best]
        n_test = sum(te.stop - te.start for _, te in folds)
        s.forward_rms_um = np.sqrt(s.forward_sse / n_test)
    chosen = choose(scores)
    X = feature_matrix(ctx, chosen.features)
    results = channel_fits(X, Y, chosen.penalty, channels)
    ridge = Ridge(np.array([r.values[:-1] * 1e3 for r in results]).T.reshape(X.shape[1], len(channels)),
                  np.array([r.values[-1] * 1e3 for r in results]), chosen.penalty)
    temps = [(f[5:], X[:, i]) for i, f in enumerate(chosen.features) if f.startswith("temp_")]
    temp_means = {s: float(np.mean(v)) for s, v in temps}
    fitted = ridge.predict(X)
    rho = residual_autocorrelation(Y - fitted)
    covariance = forward_covariance(np.array([r.covariance * 1e6 for r in results]), rho,
                                    chosen.forward_rms_um)
    return ThermalFit(channels, chosen, scores, ridge, robust_noise_um(Y),
                      np.max(np.abs(Y - Y[0]), axis=0), fitted, Y,
                      np.asarray(ctx.t, dtype=float), forward_predictions(X, Y, chosen.penalty, folds),
                      np.asarray(ctx.spindle_rpm, dtype=float), n_folds, temp_means,
                      [s for s in ctx.temperatures if s not in usable_temperatures(ctx)], covariance,
                      {s: (float(np.min(v)), float(np.max(v))) for s, v in temps}, results,
                      {f: float(X[0, i]) for i, f in enumerate(chosen.features)})


def choose(scores: list[CandidateScore]) -> CandidateScore:
    """The candidate with the smallest forward-validated sum of squares, unless a simpler one comes
    within ``PARSIMONY`` of it (a more complex driver must earn its place on the future). A drift in
    time so chosen gives way to the best drift compensate can follow (:data:`COMPENSABLE`) when the
    two predict the record alike (:func:`alike`): a time since the record began is nothing
    compensate is told, so between two equals the one it can use is kept."""
    finite = [s for s in scores if np.isfinite(s.total_sse)]
    best = min(finite, key=lambda s: s.total_sse)
    simpler = [s for s in finite if s.complexity < best.complexity
               and s.total_sse <= (1.0 + PARSIMONY) * best.total_sse]
    pick = min(simpler, key=lambda s: s.complexity) if simpler else best
    other = best_of(scores, COMPENSABLE)
    if pick.driver == "time" and other is not None and alike(other, pick):
        return other
    return pick


def best_of(scores: list[CandidateScore], drivers) -> CandidateScore | None:
    """The candidate driven by one of ``drivers`` with the smallest forward-validated sum of
    squares (None: no such candidate was fitted)."""
    return min((s for s in scores if np.isfinite(s.total_sse) and s.driver in drivers),
               key=lambda s: s.total_sse, default=None)


def alike_z(a: CandidateScore, b: CandidateScore) -> float:
    """How much worse ``a`` predicts the record forward than ``b``, in standard errors: the
    difference of their forward sums of squares over its standard error, from the loss differential
    d_t = sum over channels of (a's error^2 - b's error^2) at each predicted reading t taken as
    independent (the asymptotic test of equal predictive accuracy of Diebold and Mariano 1995,
    "Comparing predictive accuracy", J. Business & Economic Statistics 13, with no autocorrelation
    of d_t). Two models that both follow the drift leave errors near the readings' own noise, whose
    d_t is near white: there the test is right. When one of them misses the drift, its error (and
    d_t) runs on from reading to reading, the standard error taken so is too small, and the two
    are told apart: the choice falls back on the parsimony rule, never on a tie that is not there.
    0 when either has no forward errors (or their errors are equal)."""
    if a.forward_err is None or b.forward_err is None:
        return 0.0
    d = np.nansum(a.forward_err ** 2 - b.forward_err ** 2, axis=1)[np.isfinite(a.forward_err).all(axis=1)]
    if d.size < 3 or np.ptp(d) == 0:
        return 0.0
    return float(np.sum(d) / np.sqrt(d.size * np.var(d, ddof=1)))


def alike(a: CandidateScore, b: CandidateScore) -> bool:
    """``a`` predicts the record forward no worse than ``b`` beyond noise: within ``ALIKE_Z``
    standard errors (:func:`alike_z`)."""
    return alike_z(a, b) < ALIKE_Z

"""Identification: one weighted least-squares fit of an error model to any mix of measurement files.

:func:`solve` is the one fit engine of the package: it solves a :class:`~.problem.FitProblem` (what
is fitted) with :class:`~.problem.SolverOptions` (how) and returns a :class:`~.result.FitResult`.
:func:`identify` builds the problem from files and fits the parameters of an
:class:`~mtcomp.models.ErrorModel` (by default its base parameters, ``model.base_mask``) and every
file's nuisance parameters (laser zero offsets and optic slopes, ball-bar length offsets ...) to all
observations at once; diagnose's base fit solves the problem of its probe model the same way.

Method (docs/identification.md):

* Residuals ``r = w (observed - predicted)`` with one weight per observation (:mod:`.weighting`).
  Default weighting ``"unit"``: every residual in um (translational, lengths) or urad (angular), i.e.
  ``w = 1e3`` per mm and ``1e6`` per rad, the same for every file, each unit then weighted by its own
  noise estimated from the residuals when the data hold more than one (generalised least squares
  with estimated weights), so that the covariance sizes each by its own residual variance. ``"noise"``: a first fit with unit weights estimates
  each file's noise (rms residual per file and unit, corrected for the degrees of freedom the file
  uses), then the fit is repeated with ``w = 1 / noise``. A dict ``{tag: noise}`` (um or urad) fixes
  the noise per file.
* Gauss-Newton on the unknowns x = (free parameters, nuisance parameters), with the exact CasADi
  Jacobian, columns scaled to unit norm (``D``), the normal equations of the scaled problem
  (accumulated file by file, a large one block by block: the stacked Jacobian is never formed; the
  dense algebra on one BLAS thread, :func:`._linalg.one_blas_thread`) solved in the subspace of
  well-determined directions. Each iteration recomputes the residuals exactly, which refines the
  normal-equation solution like iterative refinement. The model is nearly linear in p, so 2-3
  iterations converge; a step that increases the cost is halved (down to 1e-6).
* Rank: the singular values ``s`` of the scaled weighted Jacobian at the start point (the eigenvalues
  of its normal matrix). Directions with ``s / s_max <= rcond`` (default 1e-6) are the combinations the
  data cannot determine: they are named (the parameters with weight above 10 % of the largest in
  each direction, in file units, normalised on a pivot parameter) and held at their start values
  (zero by default) by solving only in a complement: the set-ups take what they trade with machine
  parameters, except a turn of a points or cmm file's frame that the machine makes with a clearly
  smaller displacement (:func:`.problem.frame_rule_complement`). The null space is fixed at the start point so that combinations that would be
  determined only by second-order effects of the errors themselves stay undetermined.
* Profiles carry a roughness penalty whose weights REML chooses (:mod:`.penalty`): what the data
  leave open between what they measured follows the smoothest curve.
* Covariance of the unknowns: the posterior ``s2 D B (B^T Js^T Js B + B^T S B)^-1 B^T D`` with B the
  directions fitted, S the penalty and ``s2 = sum r^2 / (n_obs - edf)`` (about 1 with weights
  1/noise), less the reversal at targets a laser file reads from both sides (one degree of freedom
  each: a reversal the model does not hold is error it leaves, not uncertainty of what it fits);
  standard errors are its diagonal. A parameter with weight in an undetermined direction gets std error NaN and
  ``determined = False``.

The pieces: :mod:`.problem` (what is fitted: free and held parameters, the files' measurement
models, the physical metric), :mod:`._linalg` (rank, null space, scaled solves), :mod:`.result` (the
result types), :mod:`.weighting` (the weights), :mod:`.predict` (predictions of a fitted model).
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from ..errors import InputError
from ..measurement.readings import MeasurementModel, data_held, data_support
from ..models.model_file import FittedModel, setup_uncertainty
from ..models.params import ParameterSet
from .reversal import DirectionContrast, data_reversal
from ._offsets import mark_unread_offsets
from ._traded import set_up_trades
from ._rotation import (least_error_along, plate_tilts, reference_rotation, undetermined_unknowns,
                        without)
from ._choice import beyond_posterior, bounded_split_variance, choice_directions, data_null
from .unmeasured import (assumption, leaving_held_alone, record_unmeasured, unmeasured_to_zero,
                         unmeasured_unknowns)
from ._linalg import (column_scale, _eliminate, _name_null_space,
                      _relative_singular_values, _seen_columns, _solver, _unseen_apart, _step, block_obs,
                      file_normal_equations, one_blas_thread, penalised_inverse, psd_factor)
from .problem import (DEFAULT_RCOND, FitProblem, SolverOptions, data_region, fitted_axes,
                      frame_rotations, frame_rule_complement)
from .problem import travel_metric  # noqa: F401
from .result import FileResiduals, FitResult, unsettled_parameters
from .weighting import fit_weights, group_noise, unit_weights
from ._weak import (WEAK_SD_UM, WEAK_SIGNIFICANT, held_variance, hold_weak, open_note,  # noqa: F401
                    open_undetermined, open_unknowns, sized_undetermined, weak_directions)
from ._sparse import sparse_note, unbounded_directions, without_unbounded


# ------------------------------------------------------------------------------------- identify
def identify(machine_or_model, datasets, *, free=None, hold=(), initial=None, weights="unit",
             rcond: float = DEFAULT_RCOND, max_iterations: int = 20, tol: float = 1e-10,
             context_defaults: dict | None = None, info: dict | None = None,
             known_setup=()) -> FitResult:
    """Fit an error model to measurement files (all at once): :meth:`FitProblem.from_data` solved by
    :func:`solve`, with what the data reached and held recorded in the fitted model.

    Parameters
    ----------
    machine_or_model : Machine (its base model is fitted), ErrorModel, or FittedModel (its values are
        the start point and the values of held parameters; its context defaults are used).
    datasets : MeasurementSet or MeasurementModel instances (any mix of kinds with a registered model).
    free : None (``model.base_mask``), a bool mask (n_params,), or parameter names.
    hold : what to hold at the start values even if ``free`` includes it: parameter names, components
        (EXX), axis letters (X) or groups (squareness, spindle, tool, C:location); see
        :func:`held_parameters`.
    initial : (n_params,) start values, internal units (default zeros, or the FittedModel's).
    weights : ``"unit"`` (residuals in um and urad), ``"noise"`` (iteratively reweighted, 1/noise
        per file and unit) or a dict tag -> noise (um for translational/length columns, urad for
        angular ones).
    rcond : relative singular-value threshold for undetermined directions.
    max_iterations, tol : Gauss-Newton stops when the scaled step is below tol (relative).
    context_defaults : values of context channels the files lack.
    known_setup : tags (file stems) or paths of files whose set-up is known: points files whose
        instrument frame is the workpiece frame (no set-up translation and rotation is fitted), ball-bar
        files of a calibrated bar (no length offset). Recorded in the model (``info["known_setup"]``)
        so that predict treats those files alike.
    Returns a :class:`FitResult`.

    Spline axes without fixed knots get them from the data first
    (:func:`mtcomp.models.basis.with_data_basis`): the fitted model's structure follows what was measured.
    """
    t0 = time.perf_counter()
    datasets = list(datasets)
    problem = FitProblem.from_data(machine_or_model, datasets, free=free, hold=hold, initial=initial,
                                   weights=weights, context_defaults=context_defaults,
                                   known_setup=known_setup)
    result = solve(problem, SolverOptions(rcond, max_iterations, tol), info=info, t0=t0)
    _record_data(result, problem.model, problem.free, problem.measurements, datasets)
    mark_unread_offsets(result)
    result.problem = problem        # what was fitted, for a linearised refit (.signflip)
    return result


def solve(problem: FitProblem, options: SolverOptions = SolverOptions(), info: dict | None = None,
          t0: float | None = None) -> FitResult:
    """Solve a :class:`FitProblem`: the one fit of the package (identify, diagnose's base fit).
    Returns a :class:`FitResult` (its ``directions`` the determined directions the fit moved in)."""
    t0 = time.perf_counter() if t0 is None else t0
    with one_blas_thread():
        return _solve(problem, options, info, t0)


def _solve(problem: FitProblem, options: SolverOptions, info: dict | None, t0: float) -> FitResult:
    mms = problem.measurements
    if not mms or sum(m.n_obs for m in mms) == 0:
        paths = [str(m.data.path) for m in mms if getattr(m.data, "path", None)]
        raise InputError("no observations to fit: every measured cell is blank"
                         + (f" in {', '.join(paths)}" if len(paths) > 1 else ""),
                         paths[0] if len(paths) == 1 else None)
    stacked = _Problem(problem.model, mms, np.asarray(problem.free, dtype=bool), problem.start)
    stacked.use_penalty, stacked.hold_weak = problem.penalty, problem.hold_weak
    stacked.rank_point, stacked.known_noise = problem.rank_point, problem.known_noise
    stacked.travel_metric = travel_metric(problem.model, stacked.free_idx, stacked.n_unknowns)
    # what the data fix only weakly is judged where the model is used: the data's region
    region = data_region(problem.model.machine, mms, fitted_axes(problem.model, problem.free))
    stacked.metric = travel_metric(problem.model, stacked.free_idx, stacked.n_unknowns, region)
    o = options
    w, label, sol = fit_weights(stacked, problem.weights, o.rcond, o.max_iterations, o.tol)
    if sol is None:
        sol = stacked.solve(w, o.rcond, o.max_iterations, o.tol)
    result = stacked.result(sol, w, label, problem.context_defaults, time.perf_counter() - t0, info)
    if stacked.weak_fallback:
        result.info["weak_directions"] = ("not held: holding them would have spoiled the fit of the "
                                          "data; the data's own least-squares fit is kept")
    result.info.update(open_note(stacked))
    result.info.update(sparse_note(stacked.unbounded_classes))
    if problem.removed:
        result.info["outliers"] = [str(o) for o in problem.removed]
    return result


def tool_lengths(machine, datasets) -> list[float] | None:
    """[shortest, longest] tool (mm) of the rows of the files that position an axis (a blank
    ``tool_mm`` the machine's); None when none does."""
    v = []
    for d in datasets:
        x = d.data if isinstance(d, MeasurementModel) else d
        if hasattr(x, "axis_positions") and len(x):
            t = getattr(x, "tool", None)
            v.append(np.nan_to_num(t if isinstance(t, np.ndarray) else np.full(len(x), np.nan),
                                   nan=machine.tool_length))
    return [float(min(t.min() for t in v)), float(max(t.max() for t in v))] if v else None


def _record_data(result, model, mask, mms, datasets) -> None:
    """:func:`record_data` of identify's fit."""
    known = [m.tag for m in mms if m.options.get("setup") == "known"]
    record_data(result.fitted_model, fitted_axes(model, mask), known, datasets)
    record_unmeasured(result.fitted_model, datasets)


def record_data(fitted_model, fitted: set, known: list, datasets) -> None:
    """Record in ``fitted_model`` where its data reached, what they held, the tools they were taken
    with, the files whose set-up is known (``known``, tags) and what the data show of a reversal:
    identify's and diagnose's models alike. ``fitted``: the axes some of whose own errors were
    fitted (:func:`~.problem.fitted_axes`)."""
    # an axis none of whose own errors were fitted (all held: the user says the controller already
    # compensates it) does not bound the model: what was fitted (a rotary table's motion) holds for
    # the rigid body wherever that axis stands
    machine = fitted_model.machine
    moved = data_support(machine, datasets)
    fitted_model.support = {a: r for a, r in moved.items() if a in fitted}
    held_axes = [a for a in moved if a not in fitted]
    if held_axes:
        fitted_model.info["held_axes"] = held_axes
    # the tools the data were taken with: compensate says when a program's go beyond them
    tools = tool_lengths(machine, datasets)
    if tools is not None:
        fitted_model.info["tool_length_mm"] = tools
    if known:
        fitted_model.info["known_setup"] = list(known)
    fitted_model.held = {a: v for a, v in data_held(machine, datasets).items() if a in fitted}
    # what the data show of a reversal, so that export can say when the model leaves it out
    fitted_model.info["reversal"] = data_reversal(datasets)


#: Gauss-Newton stops at a step that moves every combination of the unknowns by less than this
#: many of its standard errors (or by less than ``tol`` relative)
STEP_SE = 1e-3
#: log penalty weights that the REML at the fit moves by less than this are those the fit used (a
#: factor 1.05: the profiles move by far less than their standard errors), and the fit stands
RHO_SETTLED = 0.05
#: the widest range of penalty on one class's coefficients (column-scaled) that a fit keeps
PENALTY_RANGE = 1e6


def _refine_from(rho):
    """Where REML at the fit starts: the weights at the start's linearisation, unless one stands at
    the search's bound. A start far from the fit (every set-up at zero: 3e7 noise variances of misfit)
    sends them there, where the criterion is flat, and a search from there stayed (a rotary table's
    ball-bar campaign kept weights of e^30, its profiles straight, six times the least squares' sum of
    squares); then it starts from its grid again (:func:`.penalty.reml_weights`)."""
    from .penalty import RHO_BOUND
    if rho is None or np.any(np.abs(rho) >= RHO_BOUND - 1e-9):
        return None
    return rho


@dataclass
class _Solution:
    x: np.ndarray
    r: np.ndarray               # weighted residuals at x
    cov: np.ndarray             # covariance of the unknowns (internal units)
    null: np.ndarray            # (n_unknowns, n_null) null directions, scaled coordinates
    scale: np.ndarray           # column scaling D
    sv: np.ndarray              # relative singular values, descending
    rank: int
    cond: float
    iterations: int
    converged: bool
    leverage: np.ndarray        # (n_obs,) diagonal of the hat matrix (sums to the edf)
    edf: float = float("nan")   # effective degrees of freedom (the rank without a penalty)
    B: np.ndarray = None        # (n_unknowns, r) directions fitted, scaled coordinates
    held: np.ndarray = None     # (n_unknowns, k) directions held weak, internal units, each 1 um rms
    #                             tool-tip error over the data's region
    held_sd: np.ndarray = None  # (k,) their standard errors, um (their variance is in cov)
    unbounded: np.ndarray = None  # (n_unknowns, k) directions only a penalty the data cannot bound
    #                               fixes (._sparse), scaled coordinates: recorded as undetermined
    unsettled: tuple = None     # not converged: (the last step of the unknowns, internal units, the
    #                             share of the cost it took)


class _Problem:
    """The stacked least-squares problem of several measurement models."""

    #: profiles carry a roughness penalty (mtcomp.identification.penalty)
    use_penalty = True
    #: directions fixed only to worse than WEAK_SD_UM are held at the least error (second pass)
    hold_weak = True
    #: (n_params,) where what the data determine is judged (FitProblem.rank_point); None: the start
    rank_point = None
    #: the weights are the readings' known noise: s2 is at least 1 (FitProblem.known_noise)
    known_noise = False
    #: (step of the unknowns, share of the cost) of Gauss-Newton's last step, set by each step
    unsettled = None
    #: the residual variance of the last solve's posterior (weighted units)
    s2 = float("nan")

    def __init__(self, model, mms, mask, p0):
        self.model = model
        self.mms = mms
        self.mask = mask
        self.free_idx = np.flatnonzero(mask)
        self.p0 = p0
        self.n_free = self.free_idx.size
        self.nuis_slices = []
        k = self.n_free
        for m in mms:
            self.nuis_slices.append(slice(k, k + m.n_nuisance))
            k += m.n_nuisance
        self.n_unknowns = k
        self.obs_slices = []
        k = 0
        for m in mms:
            self.obs_slices.append(slice(k, k + m.n_obs))
            k += m.n_obs
        self.n_obs = k
        self.observed = np.concatenate([m.observed for m in mms])
        self.metric = None      # (n_unknowns, n_unknowns) mean squared tip error over the data's region, mm^2
        self.travel_metric = None   # the same over the machine's travel
        self.weak_fallback = False  # the weak-direction pass was refused (see solve)
        self.unbounded_classes = {}  # classes whose roughness the data cannot bound (._sparse)
        self.S = None               # the penalty in scaled coordinates at the chosen weights
        self.S_factor = None        # its factor: S = S_factor^T S_factor (the penalty's value)
        self.smoothing = None       # penalty.Smoothing of the last solve
        self.smoothing_rho = {}     # class -> log weight of the last solve
        self.gradient_stale = False  # the last Gauss-Newton pass stopped on a step it did not evaluate
        self.held = None            # (directions (n_unknowns, k) scaled, variances (k,)) of the held weak ones
        self.held_assumed = 0       # of those, how many the unmeasured components' assumption fixes
        self._contrast = None       # reversal.DirectionContrast of the files, made when first needed
        self.class_factors = []     # the weighted penalty factor of each class (the last fit's weights)
        self.choice = np.zeros((self.n_unknowns, 0))  # the penalty's alternative splits across classes (._choice)
        self._choice_cost = np.zeros((1, 1))  # each class's penalty at the fit and after each
        self._splits = np.zeros((0, 0))  # the alternative splits along the fit's directions B
        self.open_tilts = None      # a part's tilts no file reads (._rotation.plate_tilts), scaled

    # --------------------------------------------------------------- weights
    def unit_weights(self):
        """(n_obs,) the weights that put every residual in um, urad or um/min (:mod:`.weighting`)."""
        return unit_weights(self.mms)

    # --------------------------------------------------------------- evaluation
    def _unknowns(self, p) -> np.ndarray:
        """(n_unknowns,) the free parameters' values of ``p`` (n_params,), the set-ups at zero."""
        x = np.zeros(self.n_unknowns)
        x[:self.n_free] = np.asarray(p, dtype=float)[self.free_idx]
        return x

    def params(self, x):
        p = self.p0.copy()
        p[self.free_idx] = x[:self.n_free]
        return p

    def evaluate(self, x):
        """(n_obs,) unweighted predictions at the unknowns x."""
        p = self.params(x)
        pred = np.empty(self.n_obs)
        for m, so, sn in zip(self.mms, self.obs_slices, self.nuis_slices):
            if m.n_obs:
                pred[so] = m.predict(p, x[sn])
        return pred

    def normal_equations(self, x, w, gram: bool = True):
        """Predictions and the normal equations of the weighted problem at x, file by file (the
        stacked Jacobian is never formed): A = Jw^T Jw (n_unknowns, n_unknowns), g = Jw^T r_w with
        Jw = w J and r_w = w (observed - predicted). ``gram=False`` skips A (returned as None)."""
        p = self.params(x)
        n_u, nf, fi = self.n_unknowns, self.n_free, self.free_idx
        pred = np.empty(self.n_obs)
        A = np.zeros((n_u, n_u)) if gram else None
        g = np.zeros(n_u)
        for m, so, sn in zip(self.mms, self.obs_slices, self.nuis_slices):
            if m.n_obs == 0:
                continue
            if not gram and m.fast_gradient:
                ww = w[so]
                y = m.predict(p, x[sn])
                pred[so] = y
                gp, gn = m.gradient(p, x[sn], ww * ww * (self.observed[so] - y))
                g[:nf] += gp[fi]
                g[sn] += gn
                continue
            gp, App, Apn = file_normal_equations(m, p, x[sn], w[so], self.observed[so], pred[so], g[sn],
                                                  A[sn, sn] if gram else None)
            g[:nf] += gp[fi]
            if gram:
                A[:nf, :nf] += App[np.ix_(fi, fi)]
                A[:nf, sn] += Apn[fi]
                A[sn, :nf] += Apn[fi].T
        return pred, A, g

    def leverages(self, x, w, scale, B, R):
        """(n_obs,) diagonal of the hat matrix Js B Hinv B^T Js^T, R R^T = Hinv, the penalised fit's
        inverse (:func:`._linalg.psd_factor` of :func:`._linalg.penalised_inverse`)."""
        p = self.params(x)
        out = np.zeros(self.n_obs)
        for m, so, sn in zip(self.mms, self.obs_slices, self.nuis_slices):
            if m.n_obs == 0:
                continue
            lev, ww = out[so], w[so]
            for blk, _, Jp, Jn in m.jacobian_blocks(p, x[sn], block_obs(m.model.n_params)):
                Js = np.zeros((Jp.shape[0], self.n_unknowns))
                Js[:, :self.n_free] = Jp[:, self.free_idx]
                Js[:, sn] = Jn
                Js *= ww[blk][:, None] * scale[None, :]
                M = R.T @ (Js @ B).T
                lev[blk] = np.einsum("ij,ij->j", M, M)
        return out

    def _damped_step(self, x, cost, B, AB, scale, grad, w):
        """Levenberg-Marquardt steps ``(AB + mu I)^-1`` with growing mu from the smallest that helps:
        (x, r, cost) of the first that lowers the objective (penalty included), or (None, None, None)."""
        gs = B.T @ (scale * grad - self.penalty_gradient(x, scale))
        mu = 1e-8 * max(float(np.trace(AB)) / max(AB.shape[0], 1), 1e-300)
        for _ in range(12):
            dz = B @ np.linalg.solve(AB + mu * np.eye(AB.shape[0]), gs)
            x_new = x + scale * dz
            r_new = w * (self.observed - self.evaluate(x_new))
            cost_new = float(r_new @ r_new) + self.penalty(x_new, scale)
            if cost_new < cost * (1 - 1e-12):
                return x_new, r_new, cost_new
            mu *= 30.0
        return None, None, None

    # --------------------------------------------------------------- penalty
    def penalty(self, x, scale) -> float:
        """The roughness penalty ``z^T S z = |F z|^2`` at the unknowns x (z = x / scale), 0 without
        one: the squared norm of its factor F (:attr:`S_factor`), never below zero. As ``z @ S @ z``
        its round-off, about 1e-16 of ``|S| |z|^2``, made it -0.4 as often as +0.4 for a straight
        profile at a weight of e^28 (entries of S 4e12), where the fit of a noise-free laser run
        leaves a residual sum of 1e-9: the cost did not descend, Gauss-Newton never called its step
        small (its test scales with the cost, then negative) and stopped after 20 iterations."""
        if self.S is None:
            return 0.0
        f = self.S_factor @ (x / scale)
        return float(f @ f)

    def penalty_gradient(self, x, scale) -> np.ndarray:
        """``S z = F^T (F z)``: half the gradient of the penalty in scaled coordinates (zeros without
        one), through its factor as :meth:`penalty`: ``S @ z`` carried the same round-off (0.02 where
        it is 0), which the steps then followed."""
        if self.S is None:
            return np.zeros_like(x)
        return self.S_factor.T @ (self.S_factor @ (x / scale))

    def scaled_penalties(self, A, scale) -> dict:
        """{class: F_k}, the factors of the penalties ``S_k = F_k^T F_k``
        (:func:`.penalty.penalty_factors`) in scaled coordinates, each normalised so that a weight of 1 weighs a
        profile's curvature about as much as the data weigh one well-seen coefficient (the median
        penalty on the coefficients the data see). Classes none of whose coefficients the data see
        are left out, and so are the coefficients the data do not see at all (a rotary axis's
        positioning harmonics under balls on its axis): what no data touch stays at zero, held with
        the null space, never set by the penalty alone."""
        from .penalty import penalty_factors
        seen = _seen_columns(A)
        out = {}
        for cls, F in penalty_factors(self.model, self.free_idx, self.n_unknowns).items():
            Fs = F * scale[None, :]
            d = np.einsum("ij,ij->j", Fs, Fs)           # the diagonal of S_k, scaled
            on = d > 0
            typical = d[on & seen]
            if typical.size == 0:
                continue
            median = float(np.median(typical))
            # a coefficient the data see a million times more weakly than the class's typical one
            # (a wall's angular profile seen through a 0.1 mm arm) is as good as unseen: its penalty
            # would dwarf every other direction and the solve would lose them to round-off
            drop = on & (~seen | (d / median > PENALTY_RANGE))
            out[cls] = _eliminate(Fs / np.sqrt(median), drop)
        return {cls: F for cls, F in out.items() if F.any()}

    def penalised_null(self, null, penalties: dict) -> np.ndarray:
        """The directions among ``null`` (the data's, orthonormal, scaled) that no penalty sees either
        (a straight line of a profile the data do not reach, a constant against a laser zero ...)."""
        if not penalties or null.shape[1] == 0:
            return null
        # each penalty is normalised to about 1 on a well-seen coefficient (scaled_penalties): a
        # direction it weighs below DEFAULT_RCOND of that is as good as unseen
        M = sum((F @ null).T @ (F @ null) for F in penalties.values())
        ev, U = np.linalg.eigh(0.5 * (M + M.T))
        return null @ U[:, ev <= DEFAULT_RCOND]

    # --------------------------------------------------------------- weak directions
    def _weak_directions(self, AB, B, scale, sigma_w: float, y):
        """:func:`._weak.weak_directions` on this problem's metric over the data's region."""
        return weak_directions(self.metric, AB, B, scale, sigma_w, y)

    # --------------------------------------------------------------- Gauss-Newton
    def solve(self, w, rcond, max_iterations, tol, leverage=False) -> _Solution:
        """Penalised Gauss-Newton on the weighted residuals, in two passes.

        What the data determine (rank, the undetermined combinations, which parameters are
        determined) comes from the data alone: the eigen-decomposition of the column-scaled normal
        matrix at the start point. Of what they leave open, the profiles' roughness penalty
        (:mod:`mtcomp.identification.penalty`, weights by REML) fixes the curvature: between what
        was measured a profile follows the smoothest curve. What neither sees stays at its start
        values, set-ups taking what they trade with machine errors, except a frame's turn that the
        machine makes with a clearly smaller displacement (:func:`.problem.frame_rule_complement`). The
        first pass fits the data and the penalty. Knowing the residual scale, the directions whose
        rms tool-tip error over the data's region is fixed only to worse than :data:`WEAK_SD_UM` are
        held: the second pass holds them at the least predicted error (:mod:`._weak`), so that noise
        is never amplified into invented errors, and the posterior keeps their variance (they are
        fixed weakly, not undetermined).
        """
        from .penalty import Smoothing
        self.smoothing, self.smoothing_rho = None, {}
        x = self._unknowns(self.p0)
        pred, A, g = self.normal_equations(x, w)
        r = w * (self.observed - pred)
        A0 = A if self.rank_point is None else self.normal_equations(self._unknowns(self.rank_point), w)[1]
        scale = column_scale(A0)
        rel, V = _relative_singular_values(_unseen_apart(A0, scale))
        keep = rel > rcond
        penalties = self.scaled_penalties(A0, scale) if self.use_penalty else {}
        null = self.penalised_null(V[:, ~keep], penalties)
        frames = frame_rotations(self.mms, self.n_free)
        rotation, turns = reference_rotation(self, null, scale)   # X the reference
        tilts = plate_tilts(self, turns, scale)   # a plate's tilts: left open
        null = without(null, turns)
        self.by_convention = np.linalg.norm(rotation, axis=1) > 1.0 - 1e-9   # a slope's own parameter
        data_rank = int(keep.sum())
        cond = float(rel[0] / rel[keep][-1]) if data_rank else np.inf
        start = (x, r, A, g)
        assumed = assumption(self, without(V[:, ~keep], turns), scale)
        held_null = self.penalised_null(assumed.null, penalties) if assumed.fixed.shape[1] else null
        B1 = frame_rule_complement(held_null, scale, np.arange(self.n_unknowns) < self.n_free,
                                   unmeasured_unknowns(self), self.metric,
                                   frames, fixed=np.hstack([rotation, assumed.fixed]))
        first = self._penalised_fit(start, w, max_iterations, tol, B1, scale, penalties)
        first += (null, B1.shape[1])
        self.held = None
        x, r, A, g, B, AB, iterations, converged, null, rank = hold_weak(
            self, start, first, w, max_iterations, tol, B1, scale, data_rank) if self.hold_weak else first
        open_ = leaving_held_alone(self, B @ data_null(AB)) if len(self.class_factors) > 1 else B[:, :0]
        choice, self._choice_cost = choice_directions(x / scale, open_, self.class_factors)
        self.choice = scale[:, None] * choice
        self._splits = B.T @ choice                           # the same along B, for the posterior
        x, r, P = unmeasured_to_zero(self, x, r, w, assumed.move)
        self.open_tilts = tilts             # a correction that moves with one is not made
        if tilts.shape[1]:
            x = least_error_along(x, tilts, scale, self.metric)
            r = w * (self.observed - self.evaluate(x))
            null = np.hstack([null, tilts])
        lev, edf, L, held, held_sd = self._posterior(x, r, w, scale, B, AB, rank, leverage, P)
        unbounded, self.unbounded_classes = unbounded_directions(
            penalties if self.S is not None else {}, B, AB, scale, P, self.n_free)
        L = without_unbounded(L, unbounded, scale)
        cov = L @ L.T
        if self.S is not None:
            lam = {k: float(np.exp(v)) for k, v in self.smoothing_rho.items()}
            self.smoothing = Smoothing(lam, dict(self.smoothing_rho), edf)
        return _Solution(x, r, cov, null, scale, rel, rank, cond, iterations, converged, lev, edf, B,
                         held, held_sd, unbounded, None if converged else self.unsettled)

    def _penalised_fit(self, start, w, max_iterations, tol, B1, scale, penalties: dict) -> tuple:
        """The first pass of :meth:`solve`: Gauss-Newton from ``start`` (x, r, A, g) along B1, with
        the penalty's weights chosen by REML (sets ``S`` and ``smoothing_rho``). Returns (x, r, A, g,
        B, AB, iterations, converged) as :meth:`_gauss_newton`."""
        from .penalty import penalty_ranks, reml_weights
        x, r, A, g = start
        self.S = self.S_factor = None
        self.class_factors = []
        iterations = 0
        Fs = list(penalties.values())
        Ss = [F.T @ F for F in Fs]
        FB = [F @ B1 for F in Fs]
        SB = [G.T @ G for G in FB]                  # the same penalties in both REML rounds
        ranks = penalty_ranks(SB) if penalties else None
        # REML on the problem linearised at the start, then again at that fit: there the residuals
        # are small, so the criterion's residual sum of squares (the start's less what the step
        # explains) does not lose its digits to a large start misfit (a misaligned CMM frame)
        rho = None
        for k in range(2 if penalties else 1):
            if k and self.gradient_stale:
                # the gradient at the fit (Gauss-Newton stopped on a step whose gradient it did not
                # evaluate); the normal matrix is the start's (linear in p up to 1e-5)
                pred, _, g = self.normal_equations(x, w, gram=False)
                r = w * (self.observed - pred)
            if penalties:
                z0 = x / scale
                AB0 = B1.T @ (A * np.outer(scale, scale)) @ B1
                before = rho
                rss, n = self._noise_sum_of_squares(r)
                f0 = [F @ z0 for F in Fs]           # the penalties at z0 through their factors
                rho, _ = reml_weights(AB0, B1.T @ (scale * g), rss, SB, [G.T @ f for G, f in zip(FB, f0)],
                                      [float(f @ f) for f in f0], n, start=_refine_from(rho),
                                      ranks=ranks, with_edf=False)
                if before is not None and np.max(np.abs(rho - before)) < RHO_SETTLED:
                    # the weights at the fit are those the fit used: it stands
                    rho = before
                    break
                self.S = sum(np.exp(rk) * S for rk, S in zip(rho, Ss))
                self.S_factor = np.vstack([np.exp(0.5 * rk) * F for rk, F in zip(rho, Fs)])
                self.class_factors = [np.exp(0.5 * rk) * F for rk, F in zip(rho, Fs)]
                self.smoothing_rho = dict(zip(penalties, rho))
            x, r, A, g, B, AB, more, converged = self._gauss_newton(
                x, r, A, g, w, max_iterations, tol, B1, scale)
            iterations += more
        return x, r, A, g, B, AB, iterations, converged

    def _posterior(self, x, r, w, scale, B, AB, rank: int, leverage: bool, P=None):
        """((n_obs,) leverages (zeros unless ``leverage``), effective degrees of freedom, (n_unknowns,
        m) factor L of the covariance of the unknowns L L^T, NaN when nothing is fitted, (n_unknowns,
        k) held directions (internal units, each 1 um rms tool-tip error over the data's region) and
        (k,) their standard errors, um) of a fit along B. The covariance includes the variance the
        data leave along each held direction (:func:`._weak.held_variance`): held, not undetermined.
        It goes through ``P``, the move that took the components no laser file names to zero
        (:func:`.unmeasured.assumption_map`; None: none), as the values did. Each variance is added
        as a factor, so that the covariance is positive semi-definite by construction: summed and
        mapped as matrices, round-off gave parameters of variance 1e-19 correlations of 1.13 (and,
        with the split's variance taken off, -20)."""
        lev = np.zeros(self.n_obs)
        edf = float(rank)
        self.held_assumed = 0
        self.s2 = float("nan")
        if not B.shape[1]:
            return (lev, edf, np.full((self.n_unknowns, 1), np.nan),
                    np.zeros((self.n_unknowns, 0)), np.zeros(0))
        # the Bayesian posterior covariance of a penalised fit (Wood 2006): phi (AB + S)^-1, phi
        # the residual variance over the effective degrees of freedom tr((AB + S)^-1 AB); the
        # penalty through its factor (penalised_inverse: its square, formed, lost the classes at
        # small weights beside one at e^28, and the posterior 10 um of tool-tip error with them)
        Hinv = penalised_inverse(AB, factor=self._penalty_factor(B))
        edf = float(np.trace(Hinv @ AB)) if self.S is not None else float(rank)
        s2 = self.s2 = self._residual_variance(r, edf)
        _, held, held_sd, self.held_assumed = held_variance(self.held, scale, s2, P, self.metric)
        # the penalty's split of what the data cannot see across classes (._choice): between classes
        # that carry curvature, the posterior at the weights' REML bounds; into an empty class, more
        extra = bounded_split_variance(AB, [F @ B for F in self.class_factors], Hinv,
                                       self._choice_cost[0, :-1], s2, self._splits)
        R = psd_factor(Hinv)                    # one eigendecomposition: covariance and leverages
        L = scale[:, None] * (B @ np.hstack([np.sqrt(s2) * R, extra]))
        self.choice = beyond_posterior(self.choice, self._choice_cost, s2)
        if P is not None:
            L, self.choice = P @ L, P @ self.choice
        if leverage:
            # from the inverse the covariance takes: a Cholesky factor of AB + S itself failed at a
            # roughness weight of e^28 beside the data (condition 1e17: "not positive definite")
            lev = self.leverages(x, w, scale, B, R)
        return lev, edf, np.hstack([L, self.choice, held * held_sd[None, :]]), held, held_sd

    def _noise_sum_of_squares(self, r) -> tuple[float, int]:
        """(sum of squares, number) of the residuals ``r`` that noise makes: all of them, less what a
        reversal at the laser files' targets read from both sides explains, and one for each such
        target (:class:`.reversal.DirectionContrast`: a reversal the model does not hold is error it
        leaves, not noise; REML and the posterior's s2 take it as unpenalised nuisance terms)."""
        if self._contrast is None:
            self._contrast = DirectionContrast(self.mms, self.obs_slices, self.model)
        return float(r @ r) - self._contrast.sum_of_squares(r), self.n_obs - self._contrast.n_groups

    def _residual_variance(self, r, edf: float) -> float:
        """s2 of the posterior: the noise's sum of squares over its number less the edf
        (:meth:`_noise_sum_of_squares`); NaN without degrees of freedom. With the readings' noise
        known (weights 1 / noise), at least 1: a fit whose residuals scatter less than the readings'
        own repeats has taken some of their noise for information."""
        rss, n = self._noise_sum_of_squares(r)
        s2 = rss / (n - edf) if n - edf > 0 else np.nan
        return max(s2, 1.0) if self.known_noise and np.isfinite(s2) else s2

    def _reduced_penalty(self, B) -> np.ndarray:
        """B^T S B: the penalty in the directions B (zeros without one)."""
        FB = self._penalty_factor(B)
        return np.zeros((B.shape[1], B.shape[1])) if FB is None else FB.T @ FB

    def _penalty_factor(self, B):
        """F B: the penalty's factor (:attr:`S_factor`) in the directions B, None without one."""
        return None if self.S_factor is None else self.S_factor @ B

    def _gauss_newton(self, x, r, A, g, w, max_iterations, tol, B, scale):
        """Minimise ``|r|^2 + z^T S z`` (the penalty, when the problem has one) from x (with its
        residuals r and normal equations A, g) along the orthonormal directions B of the scaled
        unknowns (x = x0 + scale * B y, z = x / scale). Returns (x, r, A, g, B, reduced data matrix
        B^T As B, iterations, converged)."""
        def reduced(A_):
            return B.T @ (A_ * np.outer(scale, scale)) @ B

        FB, SB = self._penalty_factor(B), self._reduced_penalty(B)
        cost = float(r @ r) + self.penalty(x, scale)
        converged = False
        iterations = 0
        AB = reduced(A)
        solve = _solver(AB, FB)
        # The model is linear in p up to products of errors (1e-5 of the readings), so the Gram
        # matrix at the start serves every step (the chord method: the gradient is exact at each
        # step, so the minimum is the exact one). It is formed anew only when a step fails to
        # descend or convergence is slow: signs that the problem is not nearly linear.
        refresh = False
        self.gradient_stale = False
        for it in range(1, max_iterations + 1):
            iterations = it
            gs = scale * g - self.penalty_gradient(x, scale)
            dz = _step(B, solve, gs)
            # small: below tol of the unknowns, or so small against their uncertainty that no
            # reading could tell (the step's Mahalanobis length gs.dz under STEP_SE standard
            # errors: every combination of the unknowns moves less than that)
            small = (np.linalg.norm(dz) <= tol * (1.0 + np.linalg.norm(x / scale))
                     or float(gs @ dz) <= STEP_SE ** 2 * cost / max(self.n_obs - B.shape[1], 1))
            if small and it > 1:
                # converged: a step this small changes nothing a user can see (below tol of the
                # unknowns), so it is not taken and x keeps the residuals and gradient just evaluated;
                # the covariance uses the normal matrix the steps used (the start's unless refreshed;
                # the model is linear in p to 1e-5)
                converged = True
                break
            x_new = x + scale * dz
            if small:
                pred_new, A_new, g_new = self.evaluate(x_new), None, None
            else:
                refresh = refresh or it >= 4
                pred_new, A_new, g_new = self.normal_equations(x_new, w, gram=refresh)
                A_new = A if A_new is None else A_new
            r_new = w * (self.observed - pred_new)
            cost_new = float(r_new @ r_new) + self.penalty(x_new, scale)
            step = 1.0
            while cost_new > cost * (1 + 1e-12) + 1e-300 and step > 1e-6:
                # backtracking, rarely needed: the model is nearly linear in p
                step *= 0.5
                x_new = x + step * scale * dz
                pred_new = self.evaluate(x_new)
                r_new = w * (self.observed - pred_new)
                cost_new = float(r_new @ r_new) + self.penalty(x_new, scale)
                A_new = None
                refresh = True
            if cost_new > cost * (1 + 1e-12) + 1e-300:
                # no descent along the Gauss-Newton step: either at the minimum, or the step is
                # dominated by nearly singular directions; Levenberg-Marquardt damping tells them apart
                x_new, r_new, cost_new = self._damped_step(x, cost, B, AB + SB, scale, g, w)
                if x_new is None:
                    converged = True
                    break
                A_new = None
                refresh = True
                small = False
            self.unsettled = (x_new - x, (cost - cost_new) / max(cost, 1e-300))
            x, r, cost = x_new, r_new, cost_new
            if small or cost == 0.0:
                converged = True
                self.gradient_stale = True      # g is the last point's: the step was not evaluated
                break
            if A_new is None:
                _, A_new, g_new = self.normal_equations(x, w)
            if A_new is not A:
                AB = reduced(A_new)
                solve = _solver(AB, FB)
            A, g = A_new, g_new
        if A is None:
            _, A, g = self.normal_equations(x, w)
        return x, r, A, g, B, AB, iterations, converged

    # --------------------------------------------------------------- result
    def result(self, sol: _Solution, w, label, ctx_defaults, seconds, info) -> FitResult:
        model = self.model
        nuis_specs = [s for m in self.mms for s in m.nuisance_specs]
        unknown_specs = [model.param_specs[i] for i in self.free_idx] + nuis_specs
        unknown_names = tuple(s.name for s in unknown_specs)
        to_file = np.array([s.to_file for s in unknown_specs])
        in_null = undetermined_unknowns(self, sol.null) | open_unknowns(self, to_file)   # or too weak
        se = np.sqrt(np.clip(np.diag(sol.cov), 0.0, None))
        se[in_null] = np.nan
        cov = sol.cov.copy()
        cov[in_null, :] = np.nan
        cov[:, in_null] = np.nan
        combos = _name_null_space(sol.null, sol.scale, to_file, unknown_names, sol.sv[sol.rank:])

        values = self.params(sol.x)
        std = np.full(model.n_params, np.nan)
        std[self.free_idx] = se[:self.n_free]
        determined = np.zeros(model.n_params, dtype=bool)
        determined[self.free_idx] = ~in_null[:self.n_free]
        files = []
        pred = self.observed - sol.r / w
        for m, so in zip(self.mms, self.obs_slices):
            resid = (m.observed - pred[so]) * m.obs_unit_scale
            files.append(FileResiduals(m.tag, str(m.data.path), m.kind, m.obs_row.copy(),
                                       np.asarray(m.data.row)[m.obs_row], np.asarray(m.obs_column),
                                       resid, w[so]))
        # a penalised fit spends its effective degrees of freedom, not its rank
        dof = max(self.n_obs - (sol.edf if np.isfinite(sol.edf) else sol.rank), 0)
        cost = float(sol.r @ sol.r)
        res = FitResult(
            model=model, specs=model.param_specs, values=values, std_errors=std, free=self.mask.copy(),
            determined=determined, nuisance_specs=nuis_specs, nuisance_values=sol.x[self.n_free:].copy(),
            nuisance_std_errors=se[self.n_free:].copy(), unknown_names=unknown_names, covariance=cov,
            undetermined=combos, rank=sol.rank, condition_number=sol.cond, singular_values=sol.sv,
            files=files, n_obs=self.n_obs, n_params=self.n_unknowns, dof=dof,
            sigma=float(np.sqrt(cost / dof)) if dof else float("nan"), iterations=sol.iterations,
            converged=sol.converged, cost=cost, seconds=seconds, weighting=label, info=dict(info or {}),
            directions=sol.scale[:, None] * sol.B, residual=sol.r.copy(), held_sd_um=sol.held_sd,
            held_assumed=self.held_assumed, unsettled=unsettled_parameters(sol, se, unknown_specs),
            noise=group_noise(self, label, w, self.s2))
        if self.smoothing is not None:
            res.smoothing = self.smoothing
        params = ParameterSet(model.param_specs, values, std)
        nf = self.n_free
        traded, traded_why = set_up_trades(self, sol.null, sol.scale, res.info)
        # every combination the data leave open, by its machine part. One that trades machine errors
        # against a file's set-up (a constant against a laser zero, a turn of the table against an
        # R-test's frame) changes that file's readings only as its set-up would, and predict takes
        # out what a file's set-up absorbs; at other poses its machine part can change a prediction
        # beyond any set-up (recording only the combinations of machine parameters alone left the
        # predictions between an R-test's poses with standard errors of 0.07 um where they were off
        # by 1.6 um). Those of set-ups alone (no machine part) are left out.
        U, sv_m, _ = np.linalg.svd(sol.null[:nf], full_matrices=False)
        null_p = sol.scale[:nf, None] * U[:, sv_m > 1e-6]
        if self.travel_metric is not None:
            # each direction 1 um rms tool-tip error over the travel; one that moves the tip nowhere
            # (a turn about the tool axis) 1 um or urad of its parameters
            from .problem import undetermined_directions
            null_p = undetermined_directions(null_p, to_file[:nf], self.travel_metric[:nf, :nf])
        else:
            null_p = null_p[:, np.linalg.norm(null_p, axis=0) > 0]
        names = model.param_names           # a property that builds the tuple on each call
        # the covariance includes the held directions' variance; they are kept too, with their
        # standard errors, so that a reader of the model can tell that share
        uncertainty = {"names": tuple(names[i] for i in self.free_idx),
                       "covariance": np.nan_to_num(sol.cov[:nf, :nf]),
                       "undetermined": np.hstack([null_p, open_undetermined(self, sol.scale, to_file),
                                                  sized_undetermined(self, sol.unbounded, sol.scale, to_file)]),
                       "held": sol.held[:nf], "held_sd_um": np.asarray(sol.held_sd, dtype=float),
                       "choice": self.choice[:nf], "traded": traded,
                       "open": sized_undetermined(self, self.open_tilts, sol.scale, to_file),
                       "setup": setup_uncertainty(nuis_specs, sol.cov, nf)}
        res.fitted_model = FittedModel(model, params, dict(ctx_defaults),
                                       {"identify": res.to_dict(), **(info or {}),
                                        **({"traded": traded_why} if traded_why else {})},
                                       uncertainty=uncertainty)
        return res

"""What a fit fits, kept apart from how it is solved: :class:`FitProblem` (the model, the measurement
model of every file with one tag rule and the declared set-ups, the free and held parameters, the
start values, the weights, the outlier policy, the roughness penalty) and :class:`SolverOptions`
(rank threshold, iterations, tolerance); the model's knots from the data, and the physical metric
(tool-tip error over the travel, or over the region the data cover) in which what the data leave
open is measured."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.linalg

from ..errors import InputError
from ..io.atomic import same_file
from ..machine import Machine
from ..measurement.files import MeasurementSet
from ..measurement.readings import (MeasurementModel, data_held, data_positions, data_spline_sizes,
                                    data_support, measurement_model)
from ..models.basis import with_data_basis
from ..models.chain import ErrorModel
from ..models.model_file import FittedModel

#: relative singular value of the column-scaled weighted Jacobian at or below which a direction
#: counts as undetermined: the one rank rule of every fit (identify, diagnose, thermal)
DEFAULT_RCOND = 1e-6


@dataclass(frozen=True)
class SolverOptions:
    """How :func:`mtcomp.identification.fit.solve` solves a :class:`FitProblem`: ``rcond`` the
    rank threshold (relative singular value), Gauss-Newton's ``max_iterations`` and ``tol`` (relative
    step at which it stops)."""

    rcond: float = DEFAULT_RCOND
    max_iterations: int = 20
    tol: float = 1e-10


@dataclass
class FitProblem:
    """One weighted least-squares problem: a model, the files' measurement models and what is fitted.

    model : the error model. measurements : one MeasurementModel per file (unique tags:
    :func:`unique_tags`). free : (n_params,) bool, the parameters fitted (the rest held at ``start``).
    start : (n_params,) start values, internal units. weights : ``"unit"`` (residuals in um and urad),
    ``"noise"`` (1/noise per file and unit, re-estimated), {tag: noise} or an (n_obs,) array of each
    reading's noise (um, urad, um/min; the readings in the measurement models' order). penalty : the profiles
    carry a roughness penalty whose weights REML chooses (:mod:`.penalty`). hold_weak : directions the
    data fix only to worse than 1 um of tool-tip error over the region they cover are held at the
    least error.
    outliers : the policy the files were read with (``"keep"``, or ``"repeats"``: readings far off
    their repeats left out, :func:`without_outliers`); ``removed`` the readings it left out.
    context_defaults : values of context channels the files lack.
    rank_point : (n_params,) the values at which what the data determine is judged (the rank and the
    undetermined combinations), None: ``start``. diagnose starts its chosen terms at the selection's
    values but judges at zero: their products with the base's columns are no information.
    known_noise : the weights are each reading's known noise (diagnose's floors): the posterior's
    residual variance is not taken below 1, that noise.
    """

    model: ErrorModel
    measurements: list
    free: np.ndarray
    start: np.ndarray
    weights: object = "unit"
    penalty: bool = True
    hold_weak: bool = True
    outliers: str = "keep"
    removed: list = field(default_factory=list)
    context_defaults: dict = field(default_factory=dict)
    rank_point: np.ndarray | None = None
    known_noise: bool = False

    def __post_init__(self):
        # readings a fit cannot take (a ball bar's deviation in um under length_mm) are refused
        # before any fit, identify's and diagnose's alike
        for m in self.measurements:
            m.check_readings()

    @classmethod
    def from_data(cls, machine_or_model, datasets, *, free=None, hold=(), initial=None, weights="unit",
                  context_defaults=None, known_setup=(), outliers="keep", penalty=True,
                  hold_weak=True) -> "FitProblem":
        """The problem of fitting ``machine_or_model`` (Machine: its base model; ErrorModel; or
        FittedModel: its values are the start and the held values, its context defaults are used)
        to ``datasets`` (MeasurementSet or MeasurementModel), with the spline knots the data choose
        (:func:`model_for_data`); ``free``/``hold`` as :func:`_free_mask`, ``known_setup`` as
        :func:`build_measurement_models`."""
        datasets = list(datasets)
        datasets, removed = without_outliers(datasets, outliers)
        model, p0, ctx = _model_and_start(machine_or_model, datasets, initial, context_defaults)
        mask = _free_mask(model, free, hold)
        mms = build_measurement_models(model, datasets, ctx, known_setup=known_setup)
        return cls(model, mms, mask, p0, weights, penalty, hold_weak, outliers, removed, ctx)


def without_outliers(datasets: list, policy: str = "repeats") -> tuple[list, list]:
    """(datasets, readings left out) under an outlier ``policy``: ``"keep"`` every reading, or
    ``"repeats"``: readings more than :data:`mtcomp.measurement.outliers.OUTLIER_K` robust standard
    deviations off their repeats left out (measurement models are passed through)."""
    if policy == "keep":
        return list(datasets), []
    if policy != "repeats":
        raise ValueError(f"outlier policy must be 'keep' or 'repeats', not {policy!r}")
    from ..measurement.outliers import find_outliers
    cleaned, outliers = [], []
    for d in datasets:
        if isinstance(d, MeasurementSet):
            d, found = find_outliers(d)
            outliers += found
        cleaned.append(d)
    return cleaned, outliers


def _model_and_start(machine_or_model, datasets: list, initial, context_defaults):
    """(model fitted, its data's basis; (n_params,) start values, internal units; context defaults)
    of :meth:`FitProblem.from_data`'s arguments."""
    fitted_in = machine_or_model if isinstance(machine_or_model, FittedModel) else None
    if isinstance(machine_or_model, Machine):
        model = ErrorModel(machine_or_model)
    elif isinstance(machine_or_model, ErrorModel):
        model = machine_or_model
    elif fitted_in is not None:
        model = fitted_in.model
    else:
        raise TypeError("machine_or_model must be a Machine, ErrorModel or FittedModel")
    ctx_defaults = dict(fitted_in.context_defaults) if fitted_in is not None else {}
    ctx_defaults.update(context_defaults or {})
    model = model_for_data(model, datasets)
    p0 = np.zeros(model.n_params)
    if fitted_in is not None:
        p0 = fitted_in.params.reindexed(model.param_specs).values
    if initial is not None:
        p0 = np.asarray(initial, dtype=float).reshape(model.n_params).copy()
    return model, p0, ctx_defaults


def _free_mask(model: ErrorModel, free, hold) -> np.ndarray:
    names = model.param_names
    if free is None:
        mask = model.base_mask.copy()
    elif np.asarray(free).dtype == bool:
        mask = np.array(free, dtype=bool)
        if mask.shape != (model.n_params,):
            raise ValueError(f"free mask must have shape ({model.n_params},), got {mask.shape}")
    else:
        free = list(free)
        unknown = [n for n in free if n not in names]
        if unknown:
            raise InputError(f"unknown parameter(s) {', '.join(unknown)} (not in this model)")
        mask = np.isin(np.asarray(names), free)
    for name in hold or ():
        held = held_parameters(model, name)
        if not held.any():
            import difflib
            words = set(names) | _hold_groups(model) | {g.split(":")[0] for g in _hold_groups(model)}
            words |= {s.group.split(":", 1)[-1] for s in model.param_specs} | set(model.machine.axis_names)
            close = difflib.get_close_matches(name, sorted(words), n=1) or \
                difflib.get_close_matches(name.upper(), sorted(words), n=1)
            hint = f"did you mean {close[0]}? " if close else ""
            raise InputError(f"--hold {name}: no such parameter or group in this model ({hint}give a "
                             f"name such as EXX_b3, a component such as EXX, an axis letter such as X, "
                             f"or one of: {', '.join(sorted(_hold_groups(model)))})")
        mask[held] = False
    return mask


def _hold_groups(model: ErrorModel) -> set[str]:
    """Group names a hold may give besides parameter names: 'squareness', 'spindle', 'tool' and
    '<axis>:location' ... (the part of each parameter's group before any ':' is its axis)."""
    return {s.group for s in model.param_specs if ":" not in s.group or s.group.endswith(":location")}


def held_parameters(model: ErrorModel, name: str) -> np.ndarray:
    """(n_params,) bool: the parameters ``name`` stands for in a hold: a parameter name (EXX_b3), a
    component (EXX: all its terms), an axis letter (X: every component error of the axis; its
    location errors too for a rotary axis), or a group (squareness, spindle, tool, C:location)."""
    names = np.asarray(model.param_names)
    groups = np.array([s.group for s in model.param_specs])
    if name in model.param_names:
        return names == name
    axis = np.array([g.split(":", 1)[0] for g in groups])
    component = np.array([g.split(":", 1)[1] if ":" in g else "" for g in groups])
    return (groups == name) | (component == name) | ((axis == name) & (component != ""))


def unique_tags(datasets) -> list[str]:
    """The one tag rule of every fit: a file's tag is its stem (a measurement model's own tag), with
    ``#2``, ``#3`` ... appended on repeats."""
    from ..measurement.readings import file_tag
    tags, seen = [], {}
    for d in datasets:
        t = d.tag if isinstance(d, MeasurementModel) else file_tag(d)
        if t in seen:
            seen[t] += 1
            t = f"{t}#{seen[t]}"
        else:
            seen[t] = 1
        tags.append(t)
    return tags


def build_measurement_models(model: ErrorModel, datasets, context_defaults=None, machine=None,
                             known_setup=(), **options) -> list[MeasurementModel]:
    """A measurement model per data set (MeasurementModel instances are passed through), with unique
    tags (file stems, ``#2``... appended on repeats). ``known_setup``: tags or paths (as given, or
    any path to the same file) of files whose set-up is known: a points or cmm file whose instrument
    frame is the workpiece frame, a ball-bar file of a calibrated bar. One that names no data file, or a
    file of another kind, is an InputError."""
    out = []
    known = known_setup_tags(datasets, known_setup)
    for d, tag in zip(datasets, unique_tags(datasets)):
        if isinstance(d, MeasurementModel):
            out.append(d)
        elif isinstance(d, MeasurementSet):
            opts = dict(options)
            if machine is not None:
                opts["machine"] = machine
            if tag in known:
                opts["setup"] = "known"
            out.append(measurement_model(model, d, context_defaults, tag=tag, **opts))
        else:
            raise TypeError(f"not a measurement set: {type(d).__name__}")
    return out


def known_setup_tags(datasets, known_setup) -> set[str]:
    """The tags (:func:`unique_tags`) of the measurement sets among ``datasets`` that
    ``known_setup`` names (tags or paths, as given, or any path to the same file). One that names no
    data file, or a file of a kind without a set-up to declare, is an InputError."""
    known = [str(k) for k in known_setup]
    used: set[str] = set()
    tags = set()
    for d, tag in zip(datasets, unique_tags(datasets)):
        if not isinstance(d, MeasurementSet):
            continue
        hits = [k for k in known if k == tag or same_file(k, d.path)]
        if hits:
            if d.kind not in KNOWN_SETUP_KINDS:
                raise InputError(f"--known-setup {hits[0]}: a {d.kind} file has no set-up to declare "
                                 f"known (only {' and '.join(KNOWN_SETUP_KINDS)} files)")
            used.update(hits)
            tags.add(tag)
    for k in known:
        if k not in used:
            raise InputError(f"--known-setup {k}: names none of the data files")
    return tags


#: kinds whose set-up ``known_setup`` can declare known (points, cmm: the instrument frame; ballbar:
#: the bar's length)
KNOWN_SETUP_KINDS = ("points", "ballbar", "cmm")


def model_for_data(model: ErrorModel, datasets) -> ErrorModel:
    """``model`` with the knots of its spline axes chosen from the data where the machine leaves them
    open (the same terms)."""
    m = model.machine
    if not any(a.basis_from_data for a in m.linear_axes):
        return model
    return ErrorModel(with_data_basis(m, data_positions(m, datasets), sizes=data_spline_sizes(m, datasets)),
                      model.terms)


#: poses drawn over the travel for the physical metric of :func:`travel_metric`
METRIC_POSES = 256


def fitted_axes(model: ErrorModel, free) -> set[str]:
    """The axes some of whose own errors are among the ``free`` ((n_params,) bool) parameters."""
    return {model.param_specs[i].group.split(":", 1)[0] for i in np.flatnonzero(free)}


def data_region(machine, datasets, axes=None) -> tuple[np.ndarray, np.ndarray]:
    """(lower, upper), each (n_axes,), mm and rad: where the data put each axis, the region whose
    predictions the fitted model is used for. An axis the data moved spans the range they reached
    (the model's ``support``: compensate and export apply the model there and nowhere else unless
    asked); an axis they hold at one position is that position (the model is evaluated there,
    ``held``); an axis no file positions keeps its travel, and so does one not among ``axes`` (when
    given: the fitted axes, :func:`fitted_axes`): an axis none of whose errors were fitted does not
    bound the model (a rotary table's motion holds wherever the linear axes stand)."""
    lo, hi = machine.travel_bounds()
    lo, hi = lo.copy(), hi.copy()
    reached = {**data_support(machine, datasets),
               **{a: (v, v) for a, v in data_held(machine, datasets).items()}}
    for j, a in enumerate(machine.axis_names):
        if a in reached and (axes is None or a in axes):
            lo[j], hi[j] = reached[a]
    return lo, hi


def travel_metric(model: ErrorModel, free_idx: np.ndarray, n_unknowns: int,
                  region: tuple | None = None) -> np.ndarray:
    """(n_unknowns, n_unknowns) M with ``x^T M x`` the mean squared tool-tip error (mm^2) over the
    machine's travel (or over ``region``, (lower, upper) axis positions as :func:`data_region`
    gives) that the fitted parameters x predict (to first order); zero for nuisance parameters,
    which are not machine errors.

    The poses are drawn uniformly over the travel of every axis (fixed seed), at the machine's tool
    length and 100 mm longer, with random approach directions and feeds up to 5 m/min, so that
    every term that acts somewhere in normal use has its weight. What the data do not determine is
    resolved by the smallest ``x^T M x``: the smallest predicted error, in physical terms. Over the
    data's region it is the metric in which the fit judges what the data fix only weakly
    (:func:`mtcomp.identification.fit.solve`).
    """
    from ..measurement.readings import evaluate_chain
    m = model.machine
    rng = np.random.default_rng(20261123)
    lo, hi = m.travel_bounds() if region is None else region
    q = lo + (hi - lo) * rng.random((METRIC_POSES, m.n_axes))
    c = model.default_context(METRIC_POSES)
    names = model.context_names
    c[:, names.index("tool_length")] = m.tool_length + 100.0 * rng.integers(0, 2, METRIC_POSES)
    c[:, names.index("feed")] = 5000.0 * rng.random(METRIC_POSES)
    for a in m.axis_names:
        c[:, names.index(f"dir_{a}")] = rng.choice([-1.0, 1.0], METRIC_POSES)
    J = evaluate_chain(model, "tip_jac", q, np.zeros(model.n_params), c)[1]   # (N, n_params, 3)
    G = J.transpose(0, 2, 1).reshape(-1, model.n_params)[:, free_idx]
    M = np.zeros((n_unknowns, n_unknowns))
    M[:free_idx.size, :free_idx.size] = G.T @ G / METRIC_POSES
    return M



def undetermined_directions(null: np.ndarray, to_file: np.ndarray, metric: np.ndarray,
                            rcond: float = DEFAULT_RCOND) -> np.ndarray:
    """(n, j) a basis of span(``null``) (the combinations of the parameters the data leave open,
    internal units, any basis) sized as a prediction is judged against it: each direction that
    moves the tool tip scaled to 1 um rms tool-tip error over ``metric`` (mm^2 per internal unit^2,
    :func:`travel_metric`), those that move it nowhere (a turn about the tool axis) to 1 um or urad
    of their parameters (``to_file`` (n,): file unit per internal unit), tip-moving ones first.

    The span is decomposed in the metric (an eigenproblem in file units, where an um and an urad
    weigh alike), so that each direction either moves the tip or does not. A basis tested vector by
    vector mixes the two: on a 5-axis campaign a roll of Z about the tool axis, which moves no tool
    tip, carried 1e-10 of a weakly seen profile; scaled to 1 um rms it took 1e8 urad of roll, whose
    second-order effect at the fitted values (1e8 urad times a 15 um offset) moved every prediction,
    the fitted readings' too, by 1e8 um, and every standard error was blank. A direction moves the
    tip when its rms tool-tip error per unit of its parameters is above ``rcond`` (the fit's rank
    rule) of the largest that any combination of the parameters makes."""
    if null.shape[1] == 0:
        return np.zeros((null.shape[0], 0))
    U, s, _ = np.linalg.svd(to_file[:, None] * null, full_matrices=False)
    U = U[:, s > 1e-12 * s.max()]                          # orthonormal, file units
    Mf = metric * 1e6 / np.outer(to_file, to_file)         # um^2 per file unit^2
    top = float(np.linalg.eigvalsh(0.5 * (Mf + Mf.T))[-1])
    Q = U.T @ Mf @ U
    lam, E = np.linalg.eigh(0.5 * (Q + Q.T))
    moves = (lam > rcond ** 2 * top) & (top > 0)
    tip = (U @ E[:, moves]) / np.sqrt(lam[moves])[None, :]
    return np.hstack([tip, U @ E[:, ~moves]]) / to_file[:, None]

# ----------------------------------------------------------------- set-ups judged by displacement
#: a null direction of the fit whose frame rotations weigh less than this (orthonormal, scaled
#: coordinates) trades no frame rotation: it is held by the set-ups' rule alone
FRAME_SHARE = 1e-6
#: the machine takes a combination that turns a frame only where its displacement is at most this
#: share of the frames': clearly smaller. A turn of the region about an axis through it is the same
#: motion whether the machine or the frame makes it (a tracker's turn about Z against a squareness
#: with a straightness's slope); it stays the set-up's, and the 256 sampled poses of the machine's
#: metric tell displacements apart only to a few per cent
FRAME_MACHINE_SHARE = 0.5


def frame_rotations(mms, n_free: int) -> list[tuple[np.ndarray, np.ndarray, int]]:
    """Per file whose instrument frame is fitted (points and cmm files not declared known): (the
    indices of its rotation unknowns ``rx ry rz`` among the fit's unknowns (the ``n_free`` machine
    parameters, then each file's set-up in order), G (3, 3) in mm^2 per rad^2, the number of its
    measured rows).

    ``w^T G w`` is the mean squared displacement that a rotation w (rad) of the frame makes over the
    file's extent, the box its measured points span (the machine's errors are measured over the
    box of the data's region in the same way): the mean of ``|w x r|^2 = w^T (|r|^2 I - r r^T) w``
    over the box, r the arm (mm) from the box's centre, so G = tr(S) I - S with S = diag(L^2 / 12),
    L the box's sides. A turn about another centre is this turn and a translation, which is the
    set-up's anyway; over the points themselves, a grid's points at the box's faces would count a
    turn as larger than the same turn of the machine over the region it spans."""
    out, k = [], n_free
    for m in mms:
        names = [s.name for s in m.nuisance_specs]
        arm = getattr(m, "_setup_arm", None)
        wanted = [f"{m.tag}:setup:{a}" for a in ("rx", "ry", "rz")]
        if arm is not None and all(n in names for n in wanted) and m.n_obs:
            r = np.asarray(arm, dtype=float)[np.unique(m._rows)]
            S = np.diag(np.ptp(r, axis=0) ** 2 / 12.0)
            out.append((np.array([k + names.index(n) for n in wanted]), np.trace(S) * np.eye(3) - S,
                        len(r)))
        k += m.n_nuisance
    return out


def frame_rule_complement(null: np.ndarray, scale: np.ndarray, machine: np.ndarray,
                          unmeasured: np.ndarray | None, metric: np.ndarray | None,
                          rotations: list, fixed: np.ndarray | None = None) -> np.ndarray:
    """(n, n - k) orthonormal directions (column-scaled coordinates) a fit moves in, given the k
    orthonormal directions ``null`` the data do not determine: the rule of
    :func:`mtcomp.identification._linalg.held_complement` (the set-ups take what they trade with
    machine parameters), except where a combination turns an instrument's frame (``rotations``, from
    :func:`frame_rotations`). There it goes to whichever side makes the smaller displacement where
    it acts: the machine parameters by their rms tool-tip error over the data's region (``metric``,
    mm^2, :func:`travel_metric`; of the machine parts equivalent in the readings, the least), the
    frames' rotations by their rms displacement over their own files' extents. A machine's error is
    judged by the same measure everywhere else in the fit.

    In the null directions that turn a frame, both measures are made diagonal (a generalised
    eigenproblem), so each such direction is judged by itself: where the machine moves at most
    :data:`FRAME_MACHINE_SHARE` of what the frames move, the frames' rotations are held at their
    start along it and the machine takes it (the constraint is the frames' displacement form,
    orthogonal to every other null direction); elsewhere, the set-ups' rule holds. ``scale`` (n,) the column scaling D (unknown = D z);
    ``machine``, ``unmeasured`` as for ``held_complement``. ``fixed`` (n, c): orthonormal
    directions of machine parameters, independent of ``null``, that the fit does not move along
    either (:attr:`mtcomp.identification.unmeasured.Assumption.fixed`; None: none); then the
    result has n - k - c columns."""
    from ._linalg import held_complement as complement

    def held_complement(held, machine, unmeasured):
        return complement(held if fixed is None else np.hstack([fixed, held]), machine, unmeasured)

    n, k = null.shape
    if k == 0 or not rotations or metric is None:
        return held_complement(null, machine, unmeasured)
    idx = np.concatenate([i for i, _, _ in rotations])
    total = float(sum(c for _, _, c in rotations))
    G = np.zeros((n, n))
    for i, Gf, count in rotations:
        G[np.ix_(i, i)] = Gf * (count / total)         # rms over all the frames' points
    G = scale[:, None] * G * scale[None, :]             # mm^2 per scaled unit^2
    M = scale[:, None] * metric * scale[None, :]
    # the null directions that turn a frame (Nr), and those that do not (held as before)
    _, s, Vt = np.linalg.svd(null[idx], full_matrices=True)
    m_r = int(np.sum(s > FRAME_SHARE))
    if m_r == 0:
        return held_complement(null, machine, unmeasured)
    Nr, N0 = null @ Vt[:m_r].T, null @ Vt[m_r:].T
    Ps, Pm = Nr.T @ G @ Nr, Nr.T @ M @ Nr
    if N0.shape[1]:
        # the machine's part of a combination is any of its equivalents (adding what the machine
        # alone leaves open changes no reading): judged by the one that moves the tool tip least
        Mr0 = Nr.T @ M @ N0
        Pm = Pm - Mr0 @ scipy.linalg.pinvh(N0.T @ M @ N0) @ Mr0.T
    T = 0.5 * (Ps + Pm + (Ps + Pm).T)
    t, Q = np.linalg.eigh(T)
    on = t > 1e-12 * max(float(t.max()), 1e-300)
    C = Q[:, on] / np.sqrt(t[on])
    mu, E = np.linalg.eigh(0.5 * (C.T @ (Pm + Pm.T) @ C))   # machine's share d_m^2 / (d_m^2 + d_s^2)
    directions = Nr @ (C @ E)
    # mu = d_m^2 / (d_m^2 + d_s^2) < s^2 / (1 + s^2)  <=>  d_m < s d_s
    to_machine = mu < FRAME_MACHINE_SHARE ** 2 / (1.0 + FRAME_MACHINE_SHARE ** 2)
    held = np.hstack([N0, Nr @ Q[:, ~on], directions[:, ~to_machine]])
    B = held_complement(held, machine, unmeasured)
    if not to_machine.any():
        return B
    # the frames' rotations held along the directions the machine takes: (G n)^T z = 0
    K = (G @ directions[:, to_machine]).T @ B
    _, _, Wt = np.linalg.svd(K, full_matrices=True)
    return B @ Wt[int(to_machine.sum()):].T

"""`diagnose`: fit the base model, find what it gets wrong, extend it, measure the gain.

Steps (docs/diagnose.md explains them for a metrologist):

1. Stack every observation and fit the base model (two Gauss-Newton steps on the exact CasADi chain).
2. Noise floor from repeated readings (pooled standard deviation), or a robust estimate without them.
3. Held-out folds: whole runs (or whole passes / spindle-speed blocks) left out together.
4. Greedy forward selection: every candidate extension (``_candidates``) is fitted; it must lower the
   held-out residual by more than noise could (``CV_Z`` standard deviations of the held-out sum of
   squares under a useless extension), remove a material share of the held-out excess over the noise
   (``MIN_EXCESS_SHARE``) and lower the BIC (noise known) by ``BIC_MARGIN``; the strongest is added,
   and the search repeats until nothing more is significant or the held-out residual is at the noise.
   Rival explanations of one residual are compared by held-out gain, with a parsimony margin.
5. What structure remains (binned residual means against every context variable) becomes an
   ``unexplained`` finding that says where it sits and what it correlates with.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..machine import Machine
from ..models.chain import ErrorModel
from ..models.model_file import FittedModel
from ..models.params import ParameterSet
from . import _analysis as an
from ._analysis import cv_threshold
from ._candidates import Candidate, generate, temperature_regression
from ._headline import quote_standard_errors
from ._refusal import moved_axes, refusal
from ._linalg import Design, rms
from ._selection import (BIC_MARGIN, MIN_EXCESS_SHARE, _axis_ties, _backward,  # noqa: F401
                         _drop_undetermined_offsets, _forward_in_time, _joint_abbe, _parsimony)
from ._stack import Stack, build_stack
from ._covariance import _covariance, _uncertainty
from ._open import written_model
from .result import UNIT_KEYS, Diagnosis, Finding, _r

#: the held-out rms may exceed the noise floor by this factor (times the inflation expected of a right
#: model, sqrt(1 + parameters / readings fitted)) before the excess counts as structure
EXCESS_RATIO = 1.3
#: at most this many findings
MAX_FINDINGS = 6


# ------------------------------------------------------------------------------------------- fit
def _common_block(st: Stack) -> np.ndarray:
    base = np.flatnonzero(st.probe.base_mask)
    return np.hstack([st.J[:, base], st.D])


def _setup_columns(st: Stack) -> np.ndarray:
    """(m,) bool: the common block's set-up (nuisance) columns, which follow the base's."""
    return np.r_[np.zeros(int(st.probe.base_mask.sum()), dtype=bool), np.ones(st.D.shape[1], dtype=bool)]


def _theta0(st: Stack) -> np.ndarray:
    base = np.flatnonzero(st.probe.base_mask)
    return np.concatenate([st.p[base], st.nuisance])


def _linear_target(st: Stack) -> np.ndarray:
    return st.y - st.pred + _common_block(st) @ _theta0(st)


def _apply(st: Stack, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    base = np.flatnonzero(st.probe.base_mask)
    p = np.zeros(st.probe.n_params)
    p[base] = theta[:base.size]
    return p, theta[base.size:]


def _metrics(st: Stack, fit, n_params: int) -> dict:
    um = st.unit == "um"
    out = {"n_params": int(n_params), "n_determined": int(fit.rank) - len(st.nuisance_names),
           "n_nuisance": len(st.nuisance_names),
           "rms_um": _r(rms(fit.resid[um])) if um.any() else None,
           "heldout_rms_um": _r(rms(fit.cv_resid[um])) if um.any() else None}
    for unit in ("urad", "um/min"):
        sel = st.unit == unit
        if sel.any():
            out[f"rms_{UNIT_KEYS[unit]}"] = _r(rms(fit.resid[sel]))
            out[f"heldout_rms_{UNIT_KEYS[unit]}"] = _r(rms(fit.cv_resid[sel]))
    return out


#: report key suffix of each unit class: angular readings, velocities


#: the unit whose held-out rms the selection follows: the first of these the data hold
MAIN_UNITS = ("um", "urad", "um/min")


def _heldout_unit(st) -> str:
    """um, else urad (angular laser runs alone), else um/min (velocities alone)."""
    return next((u for u in MAIN_UNITS if np.any(st.unit == u)), MAIN_UNITS[0])


def _heldout(st, fit, judged: np.ndarray | None = None) -> float:
    """Held-out rms of the readings in :func:`_heldout_unit` (one unit, never a mixture), of those
    ``judged`` when given."""
    sel = st.unit == _heldout_unit(st)
    return rms(fit.cv_resid[sel if judged is None else sel & judged])


def _heldout_in_noise(st, design, fit, judged: np.ndarray | None = None,
                      spread: np.ndarray | None = None) -> float:
    """:func:`_heldout` in noise floors: each reading's held-out residual over the floor it is
    weighted by (``design.w``: its unit's, or its series' or file kind's own, :func:`.an.noise_floor`),
    so that a ball bar noisier than the laser beside it is judged by its own noise; over ``spread``
    (n,) as well when given (each reading's held-out rms under a right model, in noise floors)."""
    sel = st.unit == _heldout_unit(st)
    z = fit.cv_resid * design.w / (1.0 if spread is None else spread)
    return rms(z[sel if judged is None else sel & judged])


def diagnose(machine: Machine, datasets: list, progress=None, max_findings: int = MAX_FINDINGS,
             channel_axes: dict | None = None, start=None, known_setup=()) -> Diagnosis:
    """Diagnose the base model of ``machine`` on ``datasets`` (measurement sets, mtcomp.io).

    progress : callable(str) for progress lines, or None.
    channel_axes : refused (InputError), as thermal files with ``axis_<name>`` columns are: here
        channels x, y, z read the tip; another channel's axis is for one record (mtcomp.thermal).
    start : a FittedModel (MODEL.json of ``identify``) of this machine: its base (knots, Fourier
        orders) is the base diagnosed, and its values the point the base fit starts from; extension
        terms it carries are not taken (diagnose finds its own).
    known_setup : the files whose set-up is known (a calibrated bar, a tracker aligned to the
        machine), named as identify's ``known_setup`` names them: no set-up is fitted for them.
    A single thermal file is diagnosed by :func:`mtcomp.thermal.diagnose_thermal` (drift models
    validated forward in time, docs/thermal.md; ``mtcomp diagnose`` chooses it for such a file),
    one beside geometric files by :func:`mtcomp.thermal.diagnose_with_record`.
    Returns a :class:`Diagnosis`. Raises InputError when the data cannot be diagnosed.
    """
    from ._blas import single_threaded_blas
    if len(datasets) == 1 and datasets[0].kind == "thermal":
        raise InputError("a thermal file alone is diagnosed by mtcomp.thermal.diagnose_thermal (drift "
                         "models validated forward in time), not by the geometric diagnosis",
                         str(datasets[0].path))
    # the general search reads channels x, y, z as the tip; other axes are named for one record
    # (mtcomp.thermal: alone, or beside geometric files)
    join = "join the records of one set-up into one file in time order (docs/thermal.md)"
    if channel_axes:
        raise InputError(f"--channel-axis applies to one thermal record, alone or beside geometric "
                         f"files, not to several: {join}")
    for d in datasets:
        if d.kind != "thermal":
            continue
        named = [h.strip() for h in d.header if h.strip().lower().startswith("axis_")]
        if named:
            raise InputError(f"column {named[0]}: a channel's axis is read from one thermal record, "
                             f"alone or beside geometric files, not from several: {join}", str(d.path))
    from ._resolution import MAX_REFINEMENTS
    say = progress or (lambda s: None)
    refine: dict = {}
    with single_threaded_blas():
        diag, finer = _diagnose(machine, datasets, progress, max_findings, start, refine, may_refine=True,
                                known_setup=known_setup)
        # every run is scored with the first run's noise floor: a floor estimated from the
        # residual (no repeats) would move with the base
        sigma = {u: nz.sigma for u, nz in diag.noise.items()}
        for n_refined in range(1, MAX_REFINEMENTS + 1):
            if finer is None:
                break
            a, basis, text = finer
            say(f"{text}: diagnosed again with it")
            again, finer = _diagnose(machine, datasets, progress, max_findings, start, {**refine, a: basis},
                                     may_refine=n_refined < MAX_REFINEMENTS, known_setup=known_setup)
            # the finer base must hold on the diagnosis's own held-out data, once the extensions are
            # chosen again on it: no worse than noise could make it (2 sd of a chi-square with the
            # directions it adds)
            slack = 2.0 * np.sqrt(2.0 * max(abs(again.rank - diag.rank), 1))
            before, after = _heldout_sse(diag, sigma), _heldout_sse(again, sigma)
            if not after < before + slack:
                say(f"the finer base of {a} predicts held-out data worse ({after:.4g} against {before:.4g} "
                    "noise variances): kept the base before")
                diag.rejected.append({"effect": "finer base", "axis": a, "variant": f"{basis.n_basis} functions",
                                      "reason": f"the diagnosis with it predicts held-out readings worse "
                                                f"({after:.4g} against {before:.4g} noise variances)"})
                break
            diag, refine = again, {**refine, a: basis}
        return _written(diag)


def _written(diag: Diagnosis) -> Diagnosis:
    """``diag`` with its model the one written (:func:`._open.written_model`) and REPORT.json's
    ``final.written`` saying what that model did where the data leave directions open."""
    if getattr(diag, "written", None) is None:       # (a stand-in diagnosis made no final fit)
        return diag
    t0 = time.perf_counter()
    model, written = diag.written()
    if written:
        diag.final["written"] = written
    diag.model = model
    quote_standard_errors(diag.findings, model)
    diag.seconds += time.perf_counter() - t0
    model.info["diagnose"] = diag.to_dict()
    return diag


def _heldout_sse(diag, sigma: dict) -> float:
    """The final held-out sum of squares of a diagnosis in noise variances of ``sigma`` (unit ->
    standard deviation), all readings (um and urad alike); inf when there is none."""
    r = np.asarray(diag.heldout_resid, dtype=float)
    s = np.array([sigma.get(u, np.nan) for u in diag.units], dtype=float)
    ok = np.isfinite(r) & np.isfinite(s) & (s > 0)
    return float(np.sum((r[ok] / s[ok]) ** 2)) if ok.any() else float("inf")


def _start_point(machine, start):
    """(machine, {parameter name: value}) of a start model: its machine, checked against
    ``machine``, and its parameters' values (internal units).

    A model fitted by identify gives a standard error to every value its data determined; the others
    were held (weakly determined combinations at the least predicted error, which need not be zero).
    Those are not taken: at such a value the chain's products of small errors give columns to
    parameters nothing determines (a start model holding a pitch of Z of 105 urad made a tool-length
    error of 37 mm out of a laser run of X), so they start at zero, as without a start model. A model
    with no standard errors at all (written by hand) is taken whole."""
    m = start.model.machine
    if m.topology != machine.topology or m.axis_names != machine.axis_names:
        raise InputError(f"the start model is of a {m.topology} machine, not {machine.topology}",
                         start.info.get("path"))
    values = np.asarray(start.params.values, dtype=float)
    se = start.params.std_errors
    if se is not None and np.isfinite(se).any():
        return m, {n: v for n, v, e in zip(start.model.param_names, values, se) if np.isfinite(e)}
    return m, dict(zip(start.model.param_names, values))


def _diagnose(machine, datasets, progress, max_findings, start=None, refine=None, may_refine=False,
              known_setup=()):
    """(Diagnosis, None), or (Diagnosis, (axis, finer basis, sentence)) when ``may_refine`` and the
    final structure is the base's resolution along a linear axis (:func:`_resolution.finer_base`).
    ``refine``: axis -> SplineBasis that replaces the data-chosen base of that axis."""
    t0 = time.perf_counter()
    say = progress or (lambda s: None)
    if not datasets:
        raise InputError("no measurement files given")
    machine, roomy, values = _base_machines(machine, datasets, start, refine)
    datasets, outliers = _without_outliers(datasets, say)
    st = build_stack(machine, datasets, known_setup=known_setup)
    say(f"{len(st)} observations in {len(datasets)} file(s); probe model with {st.probe.n_params} "
        "parameters")
    T0 = _base_fit(st, values, start is not None, say)
    design, noise, folds, how = _weighted_design(st, T0, say)
    n_base = int(st.probe.base_mask.sum())
    current = design.fit()
    base_metrics = _metrics(st, current, n_base)
    if refine:
        base_metrics["refined"] = {a: b.n_basis for a, b in refine.items()}
    say(f"base model: rms {base_metrics['rms_um']} um, held-out {base_metrics['heldout_rms_um']} um")
    sel = _Selection(current, np.zeros((len(st), 0)), _not_tried(st, say))
    reference = _reference(st, design, n_base)
    noise_main = noise.get(_heldout_unit(st)) or next(iter(noise.values()))
    _forward_selection(st, design, sel, noise, noise_main, max_findings, say)
    if sel.chosen:
        design = _backward_selection(st, design, sel, say)
    chosen, findings, current = sel.chosen, sel.findings, sel.current
    final_metrics = _metrics(st, current, n_base + sum(c.columns.shape[1] for c in chosen))
    verdict, finer = _what_remains(st, design, sel, noise, noise_main, may_refine, say)
    _not_judged(st, sel, final_metrics, design.w)
    model, where = _fitted_model(st, design, chosen, current)
    diag = Diagnosis(verdict, noise, base_metrics, findings, final_metrics, model, how, len(st),
                     rejected=sel.rejected, reference=reference)
    diag.folds_of_observations = folds
    diag.heldout_resid, diag.units, diag.rank = current.cv_resid, st.unit, current.rank
    diag.outliers = outliers
    from ._untested import untested
    diag.untested = untested(st)
    if verdict == "unexplained":
        from ._signflip import reversed_sign_note
        extra = np.hstack([c.columns for c in chosen]) if chosen else np.zeros((len(st), 0))
        diag.sign_note = reversed_sign_note(st, design, extra)
    # where the data reached, what they held, their tools, known set-ups and reversal, as identify
    # records them (every axis's errors are diagnose's to fit)
    from ..identification.fit import record_data
    from ..identification.unmeasured import unmeasured_groups
    record_data(model, set(st.machine.axis_names), list(st.known_setup), datasets)
    unmeasured = unmeasured_groups([s for s in model.model.param_specs if s.base], datasets)
    if unmeasured:
        model.info["unmeasured"] = unmeasured
    diag.seconds = time.perf_counter() - t0
    model.info["diagnose"] = diag.to_dict()
    # the model written where the data leave directions open: made for the diagnosis kept only
    floor = (all(nz.source == "repeats" for nz in noise.values()), EXCESS_RATIO)
    diag.written = lambda: written_model(st, design, current, model, where, values, say, floor, roomy)
    return diag, finer


def _not_judged(st, sel: _Selection, final: dict, w: np.ndarray) -> None:
    """``final["not_judged"]``: the readings the verdict was not judged on (their held-out
    prediction rests on what only their own fold determines), how many, of which files, their
    held-out rms and, where it exceeds ``EXCESS_RATIO`` times the noise floor (``w``: 1 / the floor
    each reading is weighted by), that ratio
    (``times_noise``), when there are any: the held-out figures printed include them, the verdict
    does not."""
    out = ~sel.judged & (st.unit == _heldout_unit(st))
    if out.any():
        index, counts = np.unique(np.asarray(st.file)[out], return_counts=True)
        names = [Path(st.paths[int(i)]).name for i in index]
        final["not_judged"] = {"readings": int(out.sum()), "of": int((st.unit == _heldout_unit(st)).sum()),
                               "unit": _heldout_unit(st), "heldout_rms": round(rms(sel.current.cv_resid[out]), 4),
                               "files": {str(f): int(c) for f, c in zip(names, counts)}}
        # each reading over the floor it is weighted by (its file kind's own, where it has one)
        ratio = rms(sel.current.cv_resid[out] * w[out])
        if ratio > EXCESS_RATIO:
            final["not_judged"]["times_noise"] = round(ratio, 3)


def _base_machine(machine, datasets, start, refine):
    """(machine, {parameter name: start value}) of :func:`_base_machines`: the base diagnosed."""
    base, _, values = _base_machines(machine, datasets, start, refine)
    return base, values


def _base_machines(machine, datasets, start, refine):
    """(machine, the machine of the model written, {parameter name: start value}): the machine whose
    base is diagnosed (the start model's, its resolution chosen by the data as identify's is,
    ``refine``'s bases put in); the same with room between sparse positions for the model written
    (an axis read at 3 to 15 positions gets 16 functions, as in identify's penalised fit: with one
    function per position the positions fix the profile, and its posterior claims to know it between
    them); and the start values of its parameters (none without a start model)."""
    values = {}
    if start is not None:
        machine, values = _start_point(machine, start)
    # the base model's resolution follows the data, as identify's does
    from ..models.basis import with_data_basis
    from ..measurement.readings import data_positions, data_spline_sizes
    positions, sizes = data_positions(machine, datasets), data_spline_sizes(machine, datasets)
    # (the Fourier orders of rotary axes too, as identify chooses them: with identify's column-scale
    # rule and steps that must lower the misfit, the weak high harmonics no longer run away)
    # (no finer knots than 16 functions per axis by the data's spacing: the base fit is unpenalised)
    machines = [with_data_basis(machine, positions, fourier=True, sizes=sizes, penalised=False, room=room)
                for room in (False, True)]
    if refine:
        machines = [replace(m, axes=tuple(
            replace(ax, spline_range=(refine[ax.name].lo, refine[ax.name].hi),
                    spline_intervals=refine[ax.name].n_intervals, degree=refine[ax.name].degree)
            if ax.name in refine else ax for ax in m.axes)) for m in machines]
        # a start model's coefficients of a refined axis are of other functions
        if start is not None:
            other = {ps.name for ps in start.model.param_specs if ps.group.split(":")[0] in refine}
            values = {k: v for k, v in values.items() if k not in other}
    return machines[0], machines[1], values


def _without_outliers(datasets, say):
    """(datasets without their outlying readings, the outliers left out): the fit's ``"repeats"``
    outlier policy (:func:`mtcomp.identification.problem.without_outliers`)."""
    from ..identification.problem import without_outliers
    from ..measurement.outliers import OUTLIER_K
    cleaned, outliers = without_outliers(datasets, "repeats")
    if outliers:
        say(f"{len(outliers)} reading(s) more than {OUTLIER_K:g} robust standard deviations off their "
            f"repeats left out: " + "; ".join(str(o) for o in outliers[:5])
            + ("; ..." if len(outliers) > 5 else ""))
    return cleaned, outliers


def _base_fit(st: Stack, values: dict, from_start: bool, say) -> np.ndarray:
    """Fit the base model with the package's one fit (:func:`mtcomp.identification.fit.solve`, the
    probe's base parameters and the files' set-ups, from zero or from the start model's ``values``;
    without the roughness penalty and the weak-direction pass, so that the held-out comparison of
    extensions starts from the data's own least squares). Leaves ``st`` evaluated at the fit;
    returns the basis of the directions the data determine (the fit's ``directions``, fixed at the
    start point as identify fixes them)."""
    from ..identification.fit import solve
    from ..identification.problem import FitProblem, SolverOptions
    from ._linalg import RCOND
    p0 = np.zeros(st.probe.n_params)
    base_names = [nm for nm, b in zip(st.probe.param_names, st.probe.base_mask) if b]
    taken = [nm for nm in base_names if nm in values]
    for nm in taken:
        p0[st.probe.param_names.index(nm)] = values[nm]
    if from_start:
        say(f"start: {len(taken)} of the base's {len(base_names)} parameters from the start model")
    mms = [mm for mm, _, _ in st._models]
    # every reading in um or urad as it stands (a noise of 1 per reading, not identify's noise per
    # unit): the start of the held-out comparison, whose design weighs the units by their floors
    problem = FitProblem(st.probe, mms, st.probe.base_mask.copy(), p0,
                         weights=np.ones(sum(mm.n_obs for mm in mms)), penalty=False, hold_weak=False)
    fit = solve(problem, SolverOptions(rcond=RCOND))
    st.evaluate(fit.values, fit.nuisance_values)
    return fit.directions


def _weighted_design(st: Stack, T0: np.ndarray, say):
    """(design weighted by the noise floor of each unit with held-out folds, noise floors by unit,
    folds of the observations, how the folds were made), at the stack's current point."""
    A = _common_block(st)
    z = _linear_target(st)
    plain = Design(A, z, np.ones(len(st)), np.zeros(len(st), dtype=np.int64), T0)
    # runs of opposite approach: their reversal is error the base leaves, not noise (._reversal)
    from ._reversal import floor_reversals
    steps = floor_reversals(st)
    first = plain.fit(np.column_stack(steps) if steps else None, cv=False)
    noise = an.noise_floor(st, first.resid, first.rank, plain.leverage())
    w = np.ones(len(st))
    for u, nz in noise.items():
        say(f"noise floor ({u}): {nz.sigma:.4g} {u} from {nz.source}"
            + (f" ({nz.n_groups} repeat groups, {nz.dof} dof)" if nz.source == "repeats" else
               " (no repeated readings: robust estimate from successive differences)"))
        for name, sigma in nz.by_series.items():
            say(f"  {name}: its own noise floor {sigma:.4g} {u} (its readings weighted and judged by it)")
        rows = np.asarray(st.unit) == u
        w[rows] = 1.0 / nz.sigma_of(np.asarray(st.series)[rows])
    folds, how = an.make_folds(st)
    say(f"held-out evaluation: {how}")
    return Design(A, z, w, folds, T0), noise, folds, how


def _not_tried(st: Stack, say) -> list:
    """The report's ``rejected`` lines of what is not tried: extensions of axes the data do not move."""
    still = [a for a in st.machine.axis_names if a not in moved_axes(st)]
    if not still:
        return []
    say(f"not tried: any extension on {', '.join(still)} (the data do not move them)")
    return [{"effect": "every extension", "axis": ", ".join(still), "variant": "",
             "reason": "the data do not move " + ("this axis" if len(still) == 1 else "these axes")}]


def _reference(st: Stack, design: Design, n_base: int) -> dict:
    """The report's reference fits: a linear regression on every temperature, when there are any."""
    reference = {}
    treg = temperature_regression(st)
    if treg is not None:
        fit = design.fit(treg.columns)
        reference["linear_regression_all_temperatures"] = {
            **_metrics(st, fit, n_base + treg.columns.shape[1]), "temperatures": treg.info["temperatures"]}
    return reference


@dataclass
class _Selection:
    """The state of the greedy selection: the fit of the model so far and its extra columns, the
    report's rejected lines, the candidates chosen and their findings, the (effect, axis) the data
    cannot tell from another one, and the (finding, rejected line) of rivals the data do not tell
    apart (reported once the backward pass has kept the finding)."""

    current: object
    extra: np.ndarray
    rejected: list
    chosen: list = field(default_factory=list)
    findings: list = field(default_factory=list)
    undecided: set = field(default_factory=set)
    alike_entries: list = field(default_factory=list)
    judged: np.ndarray | None = None


def _forward_selection(st, design, sel: _Selection, noise, noise_main, max_findings, say) -> None:
    """Add the strongest significant extension until none is left, the held-out residual is at the
    noise floor or ``max_findings`` are chosen (module docstring, step 4)."""
    n = len(st)
    while len(sel.chosen) < max_findings:
        if _heldout_in_noise(st, design, sel.current) <= 1.0:
            say("held-out residual is at the noise floor: stop")
            break
        scored = _score_candidates(st, design, sel, n)
        good = [s for s in scored if s[5] and s[0].veto is None]
        for s in scored:
            if s[5] and s[0].veto is not None:
                entry = {"effect": s[0].effect, "axis": s[0].axis, "variant": s[0].variant,
                         "reason": s[0].veto}
                sel.rejected = [r for r in sel.rejected
                                if (r["effect"], r["axis"]) != (entry["effect"], entry["axis"])]
                sel.rejected.append(entry)
        if not good:
            say("no further candidate is significant on held-out data")
            break
        pool = _with_joint_abbe(st, design, sel, good, n)
        best, alike = _parsimony(max(pool, key=lambda s: s[3]), pool)
        tied = _axis_ties(design, sel.extra, best, good)
        if tied:
            _name_no_axis(sel, best, tied, say)
            continue
        _take(st, design, sel, best, alike, good, noise, say)


def _score_candidates(st, design, sel: _Selection, n: int) -> list:
    """Every candidate not yet chosen, scored against the model so far: (candidate, fit, dk, gain,
    dbic, ok), with a veto on those that pass the tests but are refused."""
    current = sel.current
    keys = {c.key for c in sel.chosen}
    used_terms = {t.key() for c in sel.chosen for t in c.terms}
    # one drift finding: its driver is chosen among the rivals, not added driver after driver
    drift_chosen = any(c.effect == "thermal_drift" for c in sel.chosen)
    cands = [c for c in generate(st, design, sel.extra, current.resid, keys)
             if not ({t.key() for t in c.terms} & used_terms)
             and not (drift_chosen and c.effect == "thermal_drift")
             and (c.effect, c.axis) not in sel.undecided]
    scored = []
    for c in cands:
        fit = design.fit(np.hstack([sel.extra, c.columns]))
        dk = fit.rank - current.rank
        if dk < c.columns.shape[1] or (c.effect == "thermal_drift" and c.columns.shape[1] > 1):
            c, fit = _drop_undetermined_offsets(design, sel.extra, current, c, fit)
            dk = fit.rank - current.rank
        gain = current.cv_sse - fit.cv_sse
        dbic = fit.bic(n) - current.bic(n)
        pen = c.info.get("search_penalty", 0.0)
        excess = max(current.cv_sse - n, 0.0)
        ok = (dk >= 1 and gain > cv_threshold(dk) + pen and dbic < -BIC_MARGIN - pen
              and gain >= MIN_EXCESS_SHARE * excess)
        scored.append((c, fit, dk, gain, dbic, ok))
    # a drift is judged forward in time as it would be chosen (its parts the data do not ask for
    # dropped), and only when it passes the other tests
    _forward_in_time(st, design, sel.extra, [s[0] for s in scored if s[5] and s[0].veto is None])
    for c, fit, dk, gain, dbic, ok in scored:
        if ok and c.veto is None:
            c.veto = refusal(st, c, fit.theta[-c.columns.shape[1]:], dk)
    return scored


def _with_joint_abbe(st, design, sel: _Selection, good: list, n: int) -> list:
    """``good`` and, for each axis, its best feed-dependent Abbe candidate completed with others."""
    # a feed-dependent Abbe effect can need several parts at once (see _joint_abbe): each axis's
    # best one is completed before the axes compete, else one part of one axis's effect may be
    # better explained by a single part of another axis (every reading carries the block's feed,
    # whichever axes move)
    abbe_axes = sorted({s[0].axis for s in good if s[0].effect == "feed_dependent_abbe"})
    pool = list(good)
    for a in abbe_axes:
        top = max((s for s in good if s[0].effect == "feed_dependent_abbe" and s[0].axis == a),
                  key=lambda s: s[3])
        joint = _joint_abbe(design, sel.extra, sel.current, top, good, n, st)
        if joint is not top:
            pool.append(joint)
    return pool


def _name_no_axis(sel: _Selection, best, tied: list, say) -> None:
    """The same effect on another axis explains the same residual exactly (a program that moves X and
    Z together on a slope): the data cannot say which axis it is; none is named."""
    axes = " or ".join(sorted({best[0].axis} | {t[0].axis for t in tied}))
    for s_ in [best] + tied:           # every variant of the effect on these axes
        sel.undecided.add((s_[0].effect, s_[0].axis))
    sel.rejected.append({"effect": best[0].effect, "axis": axes, "variant": "",
                         "reason": f"the data cannot tell which axis: their readings reverse (or "
                                   f"change) together, so {axes} explain the same residual alike"})
    say(f"not named: {best[0].effect} on {axes} (the data cannot tell which)")


def _take(st, design, sel: _Selection, best, alike, good, noise, say) -> None:
    """Add the scored candidate ``best`` to the model, with its finding."""
    current = sel.current
    c, fit, dk, gain, dbic, _ = best
    rivals = [s for s in good if s[0].rivals and s[0].rivals == c.rivals and s[0] is not c]
    before = _heldout(st, current)
    finding = _finding(st, c, current, fit, before, _heldout(st, fit), rivals, noise)
    if alike is not None:
        # held-out data and the BIC both lean to the more specific rival, only one decisively:
        # naming either would be a guess. The simpler term holds the residual (so that no third
        # candidate takes it); the report names neither (benchmark seed 9180: a moving centre times a
        # pitch no run measures reads almost as a feed offset)
        finding.rival_alike = f"{alike[0].effect} {alike[0].axis}"
        sel.undecided.add((alike[0].effect, alike[0].axis))
        sel.alike_entries.append((finding, _alike_entry(best, alike)))
        say(f"not named: {c.effect} {c.axis} or {finding.rival_alike} (only one selection test is decisive); "
            f"the model holds the first")
    else:
        say(f"found {finding.effect} {finding.axis}: held-out {before:.4g} -> "
            f"{finding.heldout_rms_after:.4g} {finding.unit} (Bayesian information criterion "
            f"{dbic:+.1f}: below 0 favours the term; {dk} parameter(s))")
    sel.findings.append(finding)
    sel.chosen.append(c)
    sel.extra = np.hstack([sel.extra, c.columns])
    sel.current = fit


def _backward_selection(st, design, sel: _Selection, say) -> Design:
    """Re-linearise the extended model at its own fit, drop what is no longer significant in it, and
    report the findings' parameters at the final fit. Returns the final design."""
    chosen, findings = sel.chosen, sel.findings
    design, current = _refine(st, design, chosen, sel.current)
    say(f"extended model re-linearised at its own fit: held-out {_heldout(st, current):.4g} um")
    dropped = _backward(design, chosen, findings, current, len(st))
    if dropped:
        for f in dropped:
            say(f"dropped {f.effect} {f.axis}: no longer significant in the re-linearised model")
        design, current = _refine(st, design, chosen, design.fit(np.hstack([c.columns for c in chosen])))
    _final_params(st, design, findings, current)
    # rivals told apart by neither test decisively: reported once the backward pass has kept them
    sel.rejected += [e for f, e in sel.alike_entries if f in findings]
    sel.findings = [_not_named(f) if f.rival_alike else f for f in findings]
    sel.current = current
    return design


def _what_remains(st, design, sel: _Selection, noise, noise_main, may_refine, say):
    """(verdict, finer base or None): the structure the final fit leaves, as an ``unexplained``
    finding appended to ``sel.findings`` when there is any."""
    current, chosen, findings = sel.current, sel.chosen, sel.findings
    sigma = {u: nz.sigma for u, nz in noise.items()}
    for nz in noise.values():
        sigma.update(nz.by_series)               # a series judged by its own floor
    structure = an.find_structure(st, current.resid, sigma)
    # a reading whose held-out prediction rests on what only its own fold determines shows what the
    # other folds cannot see, not what the model lacks: the excess is judged without it
    judged = sel.judged = ~design.extrapolated(current.theta)
    excess = _heldout_in_noise(st, design, current, judged)
    extra_all = np.hstack([c.columns for c in chosen]) if chosen else np.zeros((len(st), 0))
    # a right model predicts a held-out reading worse than its noise by the error of the fit that
    # predicts it: sqrt(1 + h), h the variance of the kept folds' prediction in noise variances
    # (large where the other folds fix a reading's prediction only loosely: a part's few points
    # that alone read a spline function): the excess is judged against that, reading by reading
    spread = np.sqrt(1.0 + design.heldout_variance(extra_all))
    beyond = _heldout_in_noise(st, design, current, judged, spread)
    verdict = "none" if not findings else ("unexplained" if any(f.rival_alike for f in findings) else "explained")
    finer = None
    if structure and may_refine:
        from ._resolution import finer_base
        finer = finer_base(st, design, extra_all, current, structure)
    if structure or beyond > EXCESS_RATIO:
        verdict = "unexplained"
        findings.append(_unexplained(st, current, structure, excess, beyond, noise_main, spread,
                                     judged))
        say(f"structure remains: {findings[-1].params['where']}")
    return verdict, finer


def _final_params(st, design, findings, fit):
    """Report the parameters of every finding, and the evidence that quotes them, at the final
    (re-linearised) fit."""
    from ._report import evidence_and_params
    k = design.A_original.shape[1]
    for f in findings:
        c = f.candidate
        w = c.columns.shape[1]
        before, after, rivals = f.step
        params, evidence = evidence_and_params(st, c, fit.theta[k:k + w], before, after, rivals, None)
        f.params, f.evidence = params, evidence or f.evidence
        k += w


def _refine(st: Stack, design: Design, chosen: list[Candidate], fit, iterations: int = 2):
    """Gauss-Newton steps of the extended model: re-evaluate the probe at the extended fit (so that
    bilinear terms, e.g. an angular error times a moving rotation centre, let every reading inform
    both factors) and refit the chosen model. Returns (design, fit)."""
    base_idx = np.flatnonzero(st.probe.base_mask)
    nb = base_idx.size
    m = design.A_original.shape[1]
    for _ in range(iterations):
        theta = fit.theta
        p = np.zeros(st.probe.n_params)
        p[base_idx] = theta[:nb]
        in_probe = []                                   # (name, value) evaluated by the probe itself
        k = m
        for c in chosen:
            for j, name in enumerate(c.params):
                if name in st.probe.param_names and not name.startswith(("BL_", "TD_")):
                    p[st.index(name)] = theta[k + j]
                    in_probe.append((name, theta[k + j]))
            k += c.columns.shape[1]
        st.evaluate(p, theta[nb:m])
        A = _common_block(st)
        z = st.y - st.pred + A @ theta[:m]
        for name, v in in_probe:
            z = z + st.J[:, st.index(name)] * v
        for c in chosen:
            c.columns = c.rebuild(st)
        design = design.__class__(A, z, design.w, design.folds, design.T)
        fit = design.fit(np.hstack([c.columns for c in chosen]))
    return design, fit


# --------------------------------------------------------------------------------------- findings
def _finding(st, c: Candidate, before_fit, after_fit, before, after, rivals, noise) -> Finding:
    from ._report import evidence_and_params
    theta = after_fit.theta[-c.columns.shape[1]:]
    params, evidence = evidence_and_params(st, c, theta, before_fit, after_fit, rivals, noise)
    axis = c.axis or params.get("direction", "")
    return Finding(c.effect, axis, params, evidence, before, after, c, (before_fit, after_fit, rivals),
                   _heldout_unit(st))


def _correlate(effect: str, axis: str) -> str:
    """What a residual that two rivals of ``effect`` explain alike varies with (the words of
    :func:`mtcomp.diagnose._analysis.correlations`)."""
    if effect.startswith("feed_dependent"):
        return "feed"
    if effect in ("backlash", "rotary_backlash"):
        return f"approach direction of {axis}"
    return "time" if effect == "thermal_drift" else effect


def _alike_entry(pick, alike) -> dict:
    """The report's ``rejected`` line for a rival the data do not tell from ``pick``."""
    p, s = pick[0], alike[0]
    gain, dbic = alike[3] - pick[3], pick[4] - alike[4]
    thr = cv_threshold(max(alike[2] - pick[2], 1))
    return {"effect": s.effect, "axis": s.axis, "variant": s.variant,
            "reason": f"the data cannot tell it from {p.effect} {p.axis}: it gains {gain:.1f} noise "
                      f"variances held out over that ({thr:.1f} needed), and its BIC differs from that one's "
                      f"by {-dbic:+.1f} ({-BIC_MARGIN:+g} needed): only one test is decisive; neither is "
                      f"named, the model holds {p.effect} {p.axis}"}


def _not_named(f: Finding) -> Finding:
    """A finding whose rival the data do not tell apart, as the report's ``unexplained`` entry: the
    model holds its term (its params as fitted), the cause is not named."""
    named = f"{f.effect} {f.axis}"
    var = _correlate(f.effect, f.axis)
    params = {"where": f"{f.axis}, with {var} ({named} or {f.rival_alike})", "correlates_with": [var],
              "runs": [], "p_value": None, "explained_alike_by": [named, f.rival_alike],
              "held_in_model": named, **f.params}
    evidence = (f"{named} and {f.rival_alike} explain this residual alike: held-out data and the BIC both "
                f"lean to the second, only one decisively; the model holds the first (held-out "
                f"{f.heldout_rms_before:.3g} -> {f.heldout_rms_after:.3g} {f.unit}); readings that "
                f"tell them apart would name the cause"
                + (" (the axis's angular errors at several feeds, or its positioning at two Abbe offsets)"
                   if var == "feed" else ""))
    return replace(f, effect="unexplained", params=params, evidence=evidence)


def _unexplained(st, fit, structure, excess, beyond, noise_main, spread,
                 judged: np.ndarray | None = None) -> Finding:
    from ._report import unexplained_params
    params, evidence, axis = unexplained_params(st, fit, structure, excess, beyond, noise_main, spread,
                                                judged)
    h = _heldout(st, fit)
    return Finding("unexplained", axis, params, evidence, h, h, None, unit=_heldout_unit(st))


def _fitted_model(st: Stack, design: Design, chosen: list[Candidate], fit) -> tuple:
    """(the final least squares as a model with its covariance, (the extras' columns, the machine
    parameters' names, their positions among the fit's coefficients)): :func:`._open.written_model`
    makes the model written from them."""
    terms = []
    for c in chosen:
        for t in c.terms:
            if t.key() not in {x.key() for x in terms}:
                terms.append(t)
    model = ErrorModel(st.machine, terms)
    params = ParameterSet(model.param_specs)
    base = [n for n, s in zip(st.probe.param_names, st.probe.param_specs) if s.base]
    m = design.A_original.shape[1]
    extra = np.hstack([c.columns for c in chosen]) if chosen else np.zeros((design.n, 0))
    names, theta_idx, k = list(base), list(range(len(base))), m
    for c in chosen:
        for j, name in enumerate(c.params):
            if name in params and name not in names:
                names.append(name)
                theta_idx.append(k + j)
        k += c.columns.shape[1]
    # standard errors from the weighted normal matrix (noise variance 1 after weighting)
    cov, determined = _covariance(design, extra)
    var = np.where(determined, np.diag(cov), np.nan)
    variances = np.full(model.n_params, np.nan)
    for name, i in zip(names, theta_idx):
        params[name] = fit.theta[i]
        variances[params.index(name)] = var[i]
    params.std_errors = np.sqrt(np.where(np.isfinite(variances), variances, np.nan))
    info = {"fitted_by": "mtcomp diagnose",
            "nuisance": {n: float(v) for n, v in zip(st.nuisance_names, fit.theta[len(base):m])}}
    feats = sorted({f for c in chosen for f in c.info.get("features", [])})
    if feats:
        info["drift_features"] = feats
    uncertainty = _uncertainty(model, design, extra, cov, names, theta_idx, ~_setup_columns(st))
    return FittedModel(model, params, {}, info, uncertainty=uncertainty), (extra, names, theta_idx)

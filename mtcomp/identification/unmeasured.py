"""What no file measured stays at zero error, also inside a combination the data do determine.

A laser positioning run of Y reads the tool tip's Y motion at one tool length: the positioning
error EYY plus the tool length times the pitch EAY. The data fix that sum, not its parts; a fit
that takes the smallest parameters along such an undetermined combination splits the reading
between the two (half into a pitch nobody measured, which a controller's table then "corrects"
at every other tool length). The physical reading of such a run is the positioning error with no
pitch: the component the file names carries it, the one no file names stays at zero.

Both fits (identify's and diagnose's base) hold an undetermined combination with the least weighted
machine part (:func:`mtcomp.identification._linalg.held_complement`); :func:`unmeasured_mask`
marks the parameters that weigh most there. The fitted readings are the same whichever way a
combination is held, and the combination stays undetermined: a prediction that depends on it (the
same reading at another tool length) keeps a blank standard error.
"""
from __future__ import annotations

import numpy as np


#: kinds of file that measure the tool tip's whole deviation, every component in combination: with
#: one of them among the data no component counts as unmeasured
VOLUMETRIC_KINDS = frozenset({"points", "ballbar", "cmm"})


def named_components(datasets) -> set[str]:
    """The error components the laser files name, as parameter groups ('Y:EYY', ...); empty when a
    file of a volumetric kind (points, ball bar, CMM) is among the data, since those see every
    component (in combination) and name none."""
    if any(getattr(d, "kind", None) in VOLUMETRIC_KINDS for d in datasets):
        return set()
    out = set()
    for d in datasets:
        if getattr(d, "kind", None) != "laser":
            continue
        for axis, comp in zip(np.asarray(d.axis).tolist(), np.asarray(d.component).tolist()):
            out.add(f"{axis}:{comp}")
    return out


def unmeasured_mask(specs, named: set) -> np.ndarray:
    """(len(specs),) bool: base-model parameters whose error component no laser file names
    (``named`` from :func:`named_components`); all False when no laser file names one (points,
    ball-bar and CMM data name no component)."""
    if not named:
        return np.zeros(len(specs), dtype=bool)
    return np.array([s.base and s.group not in named for s in specs], dtype=bool)


def unmeasured_groups(specs, datasets) -> list[str]:
    """The groups of the base parameters ``specs`` whose component no laser file among
    ``datasets`` names (what MODEL.json records as ``info["unmeasured"]``)."""
    mask = unmeasured_mask(specs, named_components(datasets))
    return sorted({s.group for s, m in zip(specs, mask) if m})


def record_unmeasured(fitted, datasets) -> None:
    """``fitted.info["unmeasured"]``: the components no laser file names, held at zero where the
    data leave them open; the report says so."""
    groups = unmeasured_groups(fitted.model.param_specs, datasets)
    if groups:
        fitted.info["unmeasured"] = groups


def unmeasured_unknowns(problem) -> np.ndarray:
    """(n_unknowns,) bool of identify's problem (``mtcomp.identification.fit._Problem``): the free
    base parameters whose component no laser file names; False for the set-ups."""
    named = named_components([m.data for m in problem.mms])
    specs = [problem.model.param_specs[i] for i in problem.free_idx]
    return np.concatenate([unmeasured_mask(specs, named),
                           np.zeros(problem.n_unknowns - problem.n_free, dtype=bool)])


def assumption_map(problem, data_null) -> np.ndarray | None:
    """(n_unknowns, n_unknowns) P, the linear move ``x -> P x`` along ``data_null`` (n_unknowns, k:
    directions the data do not see, unknowns' units) that takes the parameters of components no
    laser file names as near zero as those directions allow; None when there is nothing to move.

    It is what :func:`unmeasured_to_zero` does to the values, and what the fit's covariance goes
    through with them: the variance of a split between a named component and one no file names
    (only the roughness penalty saw it) is the assumption's, not the data's, and goes; what the
    data fix of the named component stays. Readings the fit saw do not change (J P = J), so their
    standard errors stay. Unlike conditioning the covariance on those parameters being zero, which
    also took the variance of the named component along with them (a combination of a positioning
    profile and a pitch the data see only in sum), this keeps it."""
    u = unmeasured_unknowns(problem)
    if not u.any() or data_null.shape[1] == 0:
        return None
    P = np.eye(data_null.shape[0])
    P[:, u] -= data_null @ np.linalg.pinv(data_null[u], rcond=1e-10)
    return P


def unmeasured_to_zero(problem, x, r, w, data_null) -> tuple:
    """(x, r, P) of identify's fit moved along ``data_null`` (n_unknowns, k): directions the data do
    not see (at the start point, in unknowns' units), so that the parameters of components no laser
    file names are as near zero as those directions allow (P the move, :func:`assumption_map`; None
    when nothing moved). The penalty had shared the curvature of such a combination (a positioning
    run's EYY + tool length x pitch EAY) between its parts; the readings do not change, to the
    chain's second order (kept only if the weighted sum of squares grows by less than 1e-5 of it:
    5e-7 on three real laser runs)."""
    P = assumption_map(problem, data_null)
    if P is None:
        return x, r, None
    moved = P @ x
    r_moved = w * (problem.observed - problem.evaluate(moved))
    if float(r_moved @ r_moved) > float(r @ r) * (1 + 1e-5) + 1e-300:
        return x, r, None
    return moved, r_moved, P

"""What no file measured stays at zero error, also inside a combination the data do determine.

A laser positioning run of Y reads the tool tip's Y motion at one tool length: the positioning
error EYY plus the tool length times the pitch EAY. The data fix that sum, not its parts; a fit
that takes the smallest parameters along such an undetermined combination splits the reading
between the two (half into a pitch nobody measured, which a controller's table then "corrects"
at every other tool length). The physical reading of such a run is the positioning error with no
pitch: the component the file names carries it, the one no file names stays at zero.

Points, ball-bar and CMM files name no component. With one of them among the data the rule holds
for the angular error motions of the linear axes that no laser names (:func:`unmeasured_mask`): a
laser run of X and a ball-bar circle at one height fix the X error there, not its split between
EXX and the pitch EBX (the split put half of a shop's 20 um/m into EBX, and the Siemens table built
at another height came out 12.5 um/m).

Both fits (identify's and diagnose's base) apply it. With laser files alone they hold an
undetermined combination with the least weighted machine part
(:func:`mtcomp.identification._linalg.held_complement`, :func:`unmeasured_unknowns` marks the
parameters that weigh most there) and move the values along the undetermined directions after
(:func:`assumption_map`). With volumetric data the fit moves only among the models that satisfy
the assumption (:func:`assumption`). The fitted readings are the same whichever way a combination
is held, and the combination stays undetermined: a prediction that depends on it (the same
reading at another tool length) keeps a blank standard error.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..machine import LINEAR, ROTARY
from ._linalg import NULL_WEIGHT


#: kinds of file that measure the tool tip's whole deviation, every component in combination: with
#: one of them among the data only the angular error motions no laser names count as unmeasured
VOLUMETRIC_KINDS = frozenset({"points", "ballbar", "cmm"})
#: with volumetric data, a direction of the components no laser names whose weight in the data's
#: undetermined directions (orthonormal, column-scaled) exceeds this is left open by the data (the
#: fit's rule for an undetermined unknown, :data:`mtcomp.identification._linalg.NULL_WEIGHT`)
OPEN_WEIGHT = NULL_WEIGHT
#: what a move of the files' set-ups and of the components no laser names costs in
#: :func:`assumption_map`, against 1 for the named components' (column-scaled): nearly nothing, so
#: that a point of an unnamed profile a run reads with its zero goes to that zero
SETUP_COST = 1e-6


def named_components(datasets) -> set[str]:
    """The error components the laser files name, as parameter groups ('Y:EYY', ...)."""
    out = set()
    for d in datasets:
        if getattr(d, "kind", None) != "laser":
            continue
        for axis, comp in zip(np.asarray(d.axis).tolist(), np.asarray(d.component).tolist()):
            out.add(f"{axis}:{comp}")
    return out


def volumetric(datasets) -> bool:
    """A file of a volumetric kind (points, ball bar, CMM) is among ``datasets``."""
    return any(getattr(d, "kind", None) in VOLUMETRIC_KINDS for d in datasets)


def angular_motion(group: str) -> bool:
    """'X:EBX' -> True: an angular error motion (pitch, yaw, roll) of a linear axis."""
    axis, _, comp = group.partition(":")
    return (axis in LINEAR and len(comp) == 3 and comp[0] == "E" and comp[1] in ROTARY
            and comp[2] == axis)


def unmeasured_mask(specs, named: set, volumetric_data: bool = False) -> np.ndarray:
    """(len(specs),) bool: base-model parameters whose error component no laser file names
    (``named`` from :func:`named_components`); all False when no laser file names one and no
    volumetric file is among the data. With a volumetric file among the data (``volumetric_data``:
    points, ball bar, CMM, which see every component in combination and name none) only the angular
    error motions of the linear axes that no laser names (:func:`angular_motion`), whether or not a
    laser file is there: a reading at one height or tool length cannot tell them from the
    translation they make there, and they are what changes it at another (a CMM's hole positions
    alone, dx and dy at one depth: a roll of X there is a turn of the plates in X and Y, and a Z
    error of the roll times Y that nothing read)."""
    if not named and not volumetric_data:
        return np.zeros(len(specs), dtype=bool)
    return np.array([s.base and s.group not in named and (not volumetric_data or angular_motion(s.group))
                     for s in specs], dtype=bool)


def unmeasured_groups(specs, datasets) -> list[str]:
    """The groups of the base parameters ``specs`` whose component no laser file among
    ``datasets`` names (what MODEL.json records as ``info["unmeasured"]``)."""
    mask = unmeasured_mask(specs, named_components(datasets), volumetric(datasets))
    return sorted({s.group for s, m in zip(specs, mask) if m})


def record_unmeasured(fitted, datasets) -> None:
    """``fitted.info["unmeasured"]``: the components no laser file names, held at zero where the
    data leave them open; the report says so."""
    groups = unmeasured_groups(fitted.model.param_specs, datasets)
    if groups:
        fitted.info["unmeasured"] = groups


def unmeasured_unknowns(problem, assumed: bool = False) -> np.ndarray:
    """(n_unknowns,) bool of identify's problem (``mtcomp.identification.fit._Problem``): the free
    base parameters whose component no laser file names (:func:`unmeasured_mask`); False for the
    set-ups. ``assumed=False``: those the first pass's complement weighs
    (:func:`mtcomp.identification._linalg.held_complement`), none when a volumetric file is among
    the data (:func:`assumption` holds those there)."""
    datasets = [m.data for m in problem.mms]
    vol = volumetric(datasets)
    specs = [problem.model.param_specs[i] for i in problem.free_idx]
    mask = (unmeasured_mask(specs, named_components(datasets), vol) if assumed or not vol
            else np.zeros(len(specs), dtype=bool))
    return np.concatenate([mask, np.zeros(problem.n_unknowns - problem.n_free, dtype=bool)])


#: a direction moves what the assumption holds by more than this (orthonormal, column-scaled
#: directions): it is not among those that leave it alone (round-off of one that does is ~1e-8)
MOVES_HELD = 1e-3


def leaving_held_alone(problem, null: np.ndarray) -> np.ndarray:
    """(n_unknowns, k') orthonormal: the part of ``null`` (orthonormal, column-scaled) that leaves
    alone the components the assumption holds (:func:`unmeasured_unknowns` ``assumed=True``). A
    direction of ``null`` that mixes such a component in is fixed by the assumption; an SVD basis of
    ``null`` can mix it into one that is open on its own (a ball bar at one height: B0Z with the
    rolls and pitches)."""
    u = unmeasured_unknowns(problem, assumed=True)
    if not null.shape[1] or not u.any():
        return null
    _, su, Vu = np.linalg.svd(null[u], full_matrices=True)
    return null @ Vu[int(np.sum(su > MOVES_HELD)):].T


@dataclass
class Assumption:
    """What the assumption that components no laser file names are zero does to a fit.

    fixed : (n_unknowns, c) orthonormal directions (column-scaled unknowns, non-zero only on those
        components) that the first pass holds at zero, so that the fit moves only among models
        that already carry none of what the data leave open of them.
    null : (n_unknowns, k) the data's undetermined directions that the first pass still holds by the
        other rules (all of them when ``fixed`` is empty).
    move : (n_unknowns, n_unknowns) P, internal units, the move along the undetermined directions
        that takes a fit to the assumption (:func:`assumption_map`; None: none). The covariance
        goes through it as the values do.
    """

    fixed: np.ndarray
    null: np.ndarray
    move: np.ndarray | None


def assumption(problem, null: np.ndarray, scale: np.ndarray) -> Assumption:
    """:class:`Assumption` of identify's problem, given ``null`` (n_unknowns, k) the orthonormal
    directions (column-scaled unknowns, scale (n_unknowns,)) the data do not determine.

    Laser files alone: nothing is fixed beforehand (the first pass's complement weighs the
    components no laser names, :func:`unmeasured_unknowns`) and the move is
    :func:`assumption_map`'s. With a volumetric file among the data: the angular error motions no
    laser names are held before the fit (:func:`_volumetric_split`)."""
    n = null.shape[0]
    u = unmeasured_unknowns(problem, assumed=True)
    if not u.any() or null.shape[1] == 0 or not volumetric([m.data for m in problem.mms]):
        return Assumption(np.zeros((n, 0)), null, assumption_map(problem, null, scale))
    return _volumetric_split(problem, u, null, scale)


def _volumetric_split(problem, u: np.ndarray, null: np.ndarray, scale: np.ndarray) -> Assumption:
    """The assumption with volumetric data. Of the undetermined directions ``null``, those whose
    weight on the components ``u`` exceeds OPEN_WEIGHT trade them against others (a pitch against
    the positioning error at a ball bar's height, a yaw beyond a circle's reach against the
    positioning at a laser's targets); the rest hold as before. Along the trading ones the
    components ``u`` take the least roughness penalty first, then, of what the penalty does not
    see, the least size in rad: the conditions this optimum satisfies (its gradient along those
    directions is zero) are held, so that between what the data read of an angle it follows the
    smoothest curve, beyond it the straight continuation. The move that takes any fit there goes
    along the trading directions."""
    from .penalty import penalty_matrices
    n = null.shape[0]
    K = null[u]
    _, sv, Vt = np.linalg.svd(K, full_matrices=True)
    c = int(np.sum(sv > OPEN_WEIGHT))
    if c == 0:
        return Assumption(np.zeros((n, 0)), null, None)
    Kb = K @ Vt[:c].T                                   # (n_u, c), full column rank
    d = scale[u]
    # an orthonormal basis (internal units: rad) of what those directions move of the components u:
    # a curvature per rad of move compares across components whatever their columns' scales
    W, _ = np.linalg.qr(d[:, None] * Kb)
    S = sum(penalty_matrices(problem.model, problem.free_idx, problem.n_unknowns).values(),
            np.zeros((n, n)))[np.ix_(u, u)]
    H = W.T @ S @ W
    ev, E = np.linalg.eigh(0.5 * (H + H.T))
    on = ev > 1e-9 * max(float(ev.max()), 1e-300)
    # the optimum's conditions on x_u = d z_u, as constraints on z_u
    Q, _ = np.linalg.qr(d[:, None] * np.hstack([S @ W @ E[:, on], W @ E[:, ~on]]))
    fixed = np.zeros((n, c))
    fixed[u] = Q
    Ps = np.eye(n)
    Ps[:, u] -= (null @ Vt[:c].T) @ np.linalg.pinv(Q.T @ Kb, rcond=1e-12) @ Q.T
    return Assumption(fixed, null @ Vt[c:].T, scale[:, None] * Ps / scale[None, :])


def assumption_map(problem, null: np.ndarray, scale: np.ndarray) -> np.ndarray | None:
    """(n_unknowns, n_unknowns) P, the linear move ``x -> P x`` along ``null`` (n_unknowns, k:
    orthonormal directions of the column-scaled unknowns, scale (n_unknowns,), that the data do not
    see) that takes the parameters of components no laser file names as near zero as those
    directions allow (internal units); None when there is nothing to move.

    Of the moves that do, it takes the one that changes the named components least (column-scaled),
    the files' set-ups costing nearly nothing (:data:`SETUP_COST`): X's positioning run at Y = 0
    reads the straightness of Y in X there with its laser zero, and that point goes to the zero. The
    least change of every unknown alike shared it between the zero and X's positioning profile
    between its targets (which the readings do not see), and the straightness's variance, which only
    the roughness penalty had sized, went there with it.

    It is what :func:`unmeasured_to_zero` does to the values, and what the fit's covariance goes
    through with them: the variance of a split between a named component and one no file names
    (only the roughness penalty saw it) is the assumption's, not the data's, and goes; what the
    data fix of the named component stays. Readings the fit saw do not change (J P = J), so their
    standard errors stay. Unlike conditioning the covariance on those parameters being zero, which
    also took the variance of the named component along with them (a combination of a positioning
    profile and a pitch the data see only in sum), this keeps it."""
    u = unmeasured_unknowns(problem)
    if not u.any() or null.shape[1] == 0:
        return None
    internal = scale[:, None] * null
    named = ~u
    named[problem.n_free:] = False
    G = null[named].T @ null[named] + SETUP_COST * np.eye(null.shape[1])
    w, E = np.linalg.eigh(0.5 * (G + G.T))
    R = E / np.sqrt(w)[None, :]                 # G^(-1/2): the least named change is the least norm
    P = np.eye(null.shape[0])
    P[:, u] -= internal @ (R @ np.linalg.pinv(internal[u] @ R, rcond=1e-10))
    return P


def unmeasured_to_zero(problem, x, r, w, P) -> tuple:
    """(x, r, P) of identify's fit moved by ``P`` (:attr:`Assumption.move`, None: no move) along
    the directions the data do not see (at the start point), so that the parameters of components no
    laser file names are as near zero as those directions allow. The penalty had shared the
    curvature of such a combination (a positioning run's EYY + tool length x pitch EAY) between its
    parts; the readings do not change, to the chain's second order (kept only if the weighted sum
    of squares grows by less than 1e-5 of it: 5e-7 on three real laser runs)."""
    if P is None:
        return x, r, None
    moved = P @ x
    r_moved = w * (problem.observed - problem.evaluate(moved))
    if float(r_moved @ r_moved) > float(r @ r) * (1 + 1e-5) + 1e-300:
        return x, r, None
    return moved, r_moved, P

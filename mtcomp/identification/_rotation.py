"""A rigid rotation of the machine the data leave open goes by the convention: X is the reference axis.

Where no file's frame is known, a turn of the whole machine against the workpiece frame changes no
reading: about Z it is the slope of X's straightness in Y (EYX) together with the squareness C0Y and
every instrument frame turned back (a tracker's or CMM's frame, a straightness run's optic slope).
The squareness itself (the angle between the two axes, as a ball bar reads it) is read; its split
between C0Y and EYX's slope is not. The convention (ISO 230-1's reference lines, X the reference)
puts it in C0Y: the slopes of EYX, EZX (with B0Z) and EZY (with A0Z) are zero wherever the data
leave them open, so that nothing turns the part. Where a file's frame is known (``--known-setup``,
a straightness run whose slope is not fitted), the data read those slopes and the fit keeps them.
A tilt about X or Y that a points or CMM file's frame takes (a grid plate's) is not settled by the
convention: it stays among the combinations the data do not determine (:func:`plate_tilts`)."""
from __future__ import annotations

import numpy as np

from ..models.basis import SLOPE_OF_RIGID_ROTATION, axis_spline
from ..models.chain import squareness_names
from ._linalg import NULL_WEIGHT
from .unmeasured import leaving_held_alone

#: the two axes whose angle each squareness is
SQUARENESS_AXES = {"C0Y": "XY", "B0Z": "XZ", "A0Z": "YZ"}

#: a slope moves along the data's null directions (orthonormal, scaled, each slope's row of unit
#: norm) by more than this: the data leave it open (round-off of a determined one is ~1e-8)
OPEN_SLOPE = 1e-3


def _slope_rows(problem, scale: np.ndarray, which=None) -> np.ndarray:
    """(r, n_unknowns) the least-squares slope over its range of each free straightness of
    :data:`SLOPE_OF_RIGID_ROTATION` (polynomials: the linear coefficient), in column-scaled unknowns,
    each row of unit norm; ``which``: a test of the component's name (None: all)."""
    model = problem.model
    machine = model.machine
    square = set(squareness_names(machine))
    rows = {}
    for k, i in enumerate(problem.free_idx):
        spec = model.param_specs[i]
        axis, _, comp = spec.group.partition(":")
        if SLOPE_OF_RIGID_ROTATION.get(comp) not in square or not spec.base or \
                (which is not None and not which(comp)):
            continue
        suffix = spec.name[len(comp) + 1:]
        ax = machine.axis(axis)
        if ax.basis == "bspline":
            weight = float(axis_spline(ax)._moments[1][int(suffix[1:])])
        else:
            weight = 1.0 if suffix == "1" else 0.0
        row = rows.setdefault(spec.group, np.zeros(problem.n_unknowns))
        row[k] = weight * spec.to_file * scale[k]
    out = [r / np.linalg.norm(r) for r in rows.values() if np.linalg.norm(r) > 0]
    return np.array(out).reshape(-1, problem.n_unknowns)


def reference_rotation(problem, null: np.ndarray, scale: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(fixed (n, c), turns (n, c)) in column-scaled unknowns (``scale`` (n,)): of ``null`` (n, k:
    orthonormal, what neither the data nor the roughness penalty see), the c combinations that move
    the slopes of :data:`SLOPE_OF_RIGID_ROTATION` (``turns``, orthonormal: the machine's turns with
    the frames turned back) and the constraints that hold those slopes at their start (``fixed``,
    orthonormal: the fit moves along none of them); c = 0 where the data read the slopes."""
    n = null.shape[0]
    L = _slope_rows(problem, scale)
    if L.shape[0] == 0 or null.shape[1] == 0:
        return np.zeros((n, 0)), np.zeros((n, 0))
    # a turn leaves alone what the assumption holds (angular motions no laser names): else the
    # slopes' SVD mixes them in (a laser run of X and a circle: a yaw of X of 20 +- 8e4 urad)
    null = leaving_held_alone(problem, null)
    U, sv, Vt = np.linalg.svd(L @ null, full_matrices=True)
    c = int(np.sum(sv > OPEN_SLOPE))
    fixed, _ = np.linalg.qr((U[:, :c].T @ L).T)
    return fixed, null @ Vt[:c].T


def without(basis: np.ndarray, turns: np.ndarray) -> np.ndarray:
    """An orthonormal basis of span(``basis``) less what lies along ``turns`` (orthonormal, inside
    the span when ``basis`` is the null space they came from)."""
    if not turns.shape[1] or not basis.shape[1]:
        return basis
    U, s, _ = np.linalg.svd(basis - turns @ (turns.T @ basis), full_matrices=False)
    return U[:, s > 0.5]


def _angle_read(problem, name: str) -> bool:
    """True when laser runs name the positioning of both axes of squareness ``name`` and a file
    moves both (a circle in their plane, points or a diagonal spread over both): it reads their
    angle from its shape, the lasers the axes' scales. A circle at one height reads B0Z and A0Z
    only as a shift of its centre, which rests on the centre the file states; a circle alone
    shares its angle with the straightnesses' shapes (C0Y 131 urad standard error)."""
    named = {str(c) for mm in problem.mms if mm.kind == "laser" for c in np.unique(mm.data.component)}
    if not all(f"E{a}{a}" in named for a in SQUARENESS_AXES[name]):
        return False
    for mm in problem.mms:
        try:
            q = mm.data.axis_positions(mm.machine)
        except (AttributeError, ValueError):
            continue
        names = mm.machine.axis_names
        if q.size and all(a in names and np.ptp(q[:, names.index(a)]) > 1e-6 for a in SQUARENESS_AXES[name]):
            return True
    return False


def undetermined_unknowns(problem, null: np.ndarray) -> np.ndarray:
    """(n_unknowns,) bool: the unknowns the fit leaves undetermined given its open directions
    ``null`` (orthonormal, column-scaled): those with weight in one, and the slopes the convention
    holds. A squareness whose only open directions move what the unmeasured-components rule holds
    (:func:`leaving_held_alone`) is determined on that rule, with its standard error, where the
    data read the angle (:func:`_angle_read`): lasers of X and Y and one XY circle leave C0Y open
    only with the rolls no laser names."""
    by_convention = getattr(problem, "by_convention", False)
    if not null.shape[1]:
        return np.zeros(problem.n_unknowns, dtype=bool) | by_convention
    in_null = (np.linalg.norm(null, axis=1) > NULL_WEIGHT) | by_convention
    open_alone = np.linalg.norm(leaving_held_alone(problem, null), axis=1) > NULL_WEIGHT
    specs = problem.model.param_specs
    for k, i in enumerate(problem.free_idx):
        name = specs[i].name
        if name in SQUARENESS_AXES and in_null[k] and not open_alone[k] and _angle_read(problem, name):
            in_null[k] = False
    return in_null


#: the straightnesses whose slope is a tilt of the machine about X or Y (with the squareness named)
TILT_SLOPES = {comp for comp, square in SLOPE_OF_RIGID_ROTATION.items() if square != "C0Y"}


def _heights_at_one_z(m) -> bool | None:
    """Of a points or CMM file whose frame is fitted: True when its readings along Z (dz, or a
    normal with a Z part) are all at one height of the tool tip (a part's top face read in its own
    set-up), which it reads only up to its frame's tilt; False when it reads heights at two; None
    when it reads none."""
    arm = np.asarray(m._setup_arm, dtype=float)
    if getattr(m, "_A", None) is not None:                      # points: a row per reading
        z = arm[m._rows, 2][np.abs(m._A[:, 2]) > 1e-9]
    else:                                                       # cmm: a reading per row, along its normal
        z = arm[np.abs(np.nan_to_num(np.asarray(m.data.normal, dtype=float))[:, 2]) > 1e-9, 2]
    return float(np.ptp(z)) <= 1e-6 if z.size else None


def _z_held(problem) -> bool:
    """No file reads heights at two positions of Z in one set-up: the data hold Z at one position
    (every file that positions the axes: nothing reads Z), or every points or CMM file whose frame
    is fitted reads its heights at one (:func:`_heights_at_one_z`: parts cut at several heights,
    each read in its own alignment on its top face) and every other file holds Z at one position."""
    z, heights = [], []
    for m in problem.mms:
        try:
            q = m.data.axis_positions(m.machine)
        except (AttributeError, ValueError):
            continue
        if "Z" not in m.machine.axis_names or not q.size:
            continue
        one = _heights_at_one_z(m) if getattr(m, "_setup_arm", None) is not None else None
        if one is None:                 # reads no height in a frame of its own: where it holds Z
            z.append(q[:, m.machine.axis_names.index("Z")])
        else:
            heights.append(one)
    held = not z or np.ptp(np.concatenate(z)) <= 1e-9
    return bool(z or heights) and held and all(heights)


def _plate_frames(problem) -> list[int]:
    """The unknowns' indices of the tilts ``rx``, ``ry`` of every points or CMM file whose frame is
    fitted, where no file reads heights at two positions of Z in one set-up (:func:`_z_held`):
    plates read on one plane, parts read each on its top face in its own alignment."""
    if not _z_held(problem):
        return []
    out, k = [], problem.n_free
    for m in problem.mms:
        names = [s.name for s in m.nuisance_specs]
        wanted = [f"{m.tag}:setup:{a}" for a in ("rx", "ry")]
        if getattr(m, "_setup_arm", None) is not None and all(w in names for w in wanted):
            out += [k + names.index(w) for w in wanted]
        k += m.n_nuisance
    return out


def plate_tilts(problem, turns: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """(n, t) orthonormal, column-scaled: the part of ``turns`` (:func:`reference_rotation`) that
    tilts the machine about X or Y against the frame of a plate (:func:`_plate_frames`: its ``rx``
    or ``ry``), moving no slope of X's straightness in Y. A plate reads its heights only up to its
    own tilt, and where nothing else reads the Z axis the slopes of X's and Y's straightness in Z
    trade with that tilt: what the model's convention makes of them depends on where the machine's
    zero is (a roll of X acts on the tip over its distance along Y from the machine's Y = 0, and
    the plate's tilt takes what the convention leaves). They stay among the combinations the data
    do not determine, held where they predict the least error (:func:`least_error_along`); the turn
    about Z (a part aligned to X) keeps the convention."""
    n = turns.shape[0]
    idx = _plate_frames(problem)
    if not turns.shape[1] or not idx:
        return np.zeros((n, 0))
    L = _slope_rows(problem, scale, lambda comp: comp not in TILT_SLOPES)
    basis = turns
    if L.shape[0]:
        _, s, Vt = np.linalg.svd(L @ turns, full_matrices=True)
        basis = turns @ Vt[int(np.sum(s > OPEN_SLOPE)):].T       # leaving the turn about Z alone
    if not basis.shape[1]:
        return np.zeros((n, 0))
    _, s, Vt = np.linalg.svd(basis[idx], full_matrices=True)
    return basis @ Vt[:int(np.sum(s > OPEN_SLOPE))].T


def least_error_along(x: np.ndarray, directions: np.ndarray, scale: np.ndarray,
                      metric: np.ndarray | None) -> np.ndarray:
    """x (internal units) moved along ``directions`` (column-scaled, combinations the data do not
    determine) to the least mean squared tool-tip error over ``metric``'s region
    (:func:`.problem.travel_metric`): a choice that does not depend on where the axes' zeros are,
    as the region is the same whatever coordinates name it."""
    if metric is None or not directions.shape[1]:
        return x
    d = scale[:, None] * directions
    Md = metric @ d
    t = -np.linalg.lstsq(d.T @ Md, Md.T @ x, rcond=1e-12)[0]
    return x + d @ t

"""Component-error tables of a fitted model, evaluated on a grid of each axis (the core of `export`).

The model is evaluated, never parsed: every number comes from the model's own prediction of the
tool-tip deviation (:func:`mtcomp.models.evaluate.deviation`) and of the tool's rotation relative to
the workpiece (the chain of :meth:`mtcomp.models.ErrorModel.symbolic`).

Definition. Every axis has a *reference position*: its machine coordinate 0 (the machine zero,
where the workpiece frame coincides with the machine frame; a controller's reference position), or
the nearest end of its travel when 0 lies outside the travel (a reference return has to reach it).
Every position is a machine coordinate. The model is used only inside the region its data reached:
a position beyond that region takes the value at the region's nearest end, and on a rotary axis
measured over part of its turn a table's grid points past the first one beyond each end are zero
(:mod:`mtcomp.export._ends`: its turn closes, and compensate corrects nothing beyond the data). The
component errors of axis L at position s, approached in direction dir, are what the model predicts
when only L moves:

    E(L, s, dir) = dev(q_ref with q_L = s, dir_L = dir) - dev(q_ref, all directions unknown)

with ``dev`` = (tip deviation dx, dy, dz in mm; rotation of the tool relative to the workpiece about
X, Y, Z in rad), the machine's tool length, every other axis at its reference position and its
approach direction unknown (0: the mean of both directions), each position taken into its axis's
region as above. So

* the positioning error of a linear axis L is the deviation along L: EXX = dx when X moves;
* its straightness errors are the other two translations (EYX = dy, EZX = dz when X moves); they
  contain the squareness (the slope of a straightness against the other axis is the squareness);
* its angular errors are the three rotations (EAX, EBX, ECX);
* the positioning error of a rotary axis is its rotation about its own direction, read the way a
  laser reads it: actual minus commanded angle of the axis (minus the tool's rotation for a rotary
  table, which turns the workpiece);
* forward (dir = +1) and reverse (dir = -1) differ by the backlash; their mean is zero at the
  reference position (and, when that lies outside the data's region, at the region's nearest end).

All arrays are in internal units (mm, rad).
"""
from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..models.evaluate import casadi_map_call, deviation
from ..models.model_file import UNDETERMINED_UM
from ..planner._contours import one_contour_left
from ..planner._uncertainty import SMALL_IN_SD, CorrectionUncertainty, in_sd
from ..planner.problem import unsure_advice
from ._ends import beyond_span, close_grid, open_ends
from ._reversal import reversal_note, unheld_reversals


#: how an axis table carries a component (``ExportResult.carried``)
FULL = "full"          # the table, forward and reverse
MEAN = "mean"          # the table without direction (mean of forward and reverse)
LINEAR = "linear"      # the least-squares line of the mean over the table


def fit_line(x: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """Least-squares line y ~ a + b x: (a, b)."""
    A = np.column_stack([np.ones_like(x), x])
    (a, b), *_ = np.linalg.lstsq(A, y, rcond=None)
    return float(a), float(b)

#: below this (mm, rad) everywhere an axis table is zero: the model holds that axis's errors at zero
ZERO = 1e-12

#: the six component errors of an axis L, in the order of the table columns: E X L, E Y L, E Z L,
#: E A L, E B L, E C L
COMPONENT_LETTERS = "XYZABC"


def component_names(axis: str) -> list[str]:
    """ISO 230-1 names of the six columns of an axis table: 'X' -> ['EXX', 'EYX', ... 'ECX']."""
    return [f"E{d}{axis}" for d in COMPONENT_LETTERS]


def own_column(machine, axis: str) -> int:
    """Column of the positioning error of ``axis`` (EXX: 0 ... ECC: 5)."""
    ax = machine.axis(axis)
    return ax.direction_index + (3 if ax.is_rotary else 0)


@dataclass(frozen=True)
class AxisTable:
    """The component errors of one axis on its grid (internal units: mm and rad).

    axis : axis letter. rotary : True for A, B, C.
    positions : (n,) grid positions, increasing, mm or rad.
    forward, reverse : (n, 6) component errors (columns :func:`component_names`) approaching each
        position in the + / - direction. angular_known : False when the model's rotations could not
        be evaluated (columns 3..5 are then NaN).
    reference : the reference position of every axis (dict axis -> mm or rad).
    region : (lo, hi) where the model's data reached along this axis (mm or rad); of the grid
        points beyond it the first at or past each end holds the value at that end, the others are
        zero (:mod:`mtcomp.export._ends`; default: the grid's ends).
    """

    axis: str
    rotary: bool
    positions: np.ndarray
    forward: np.ndarray
    reverse: np.ndarray
    reference: dict
    angular_known: bool = True
    region: tuple | None = None
    #: the tip columns the table leaves (zero in ``forward``, ``reverse``): their values rest on
    #: what the data did not determine or are over the standard-error limit (:func:`_table_left`)
    left: tuple = ()

    @property
    def data_region(self) -> tuple[float, float]:
        """(lo, hi): where the model's data reached (the grid's ends when not given)."""
        if self.region is None:
            return float(self.positions[0]), float(self.positions[-1])
        return float(self.region[0]), float(self.region[1])

    @property
    def held(self) -> np.ndarray:
        """(n,) bool: grid points outside the data's region (a linear axis's hold the end value;
        a rotary axis's measured over part of its turn: the first past an end holds it, the others
        are zero, :mod:`mtcomp.export._ends`)."""
        lo, hi = self.data_region
        tol = 1e-9 * max(1.0, abs(lo), abs(hi))
        return (self.positions < lo - tol) | (self.positions > hi + tol)

    @property
    def mean(self) -> np.ndarray:
        """(n, 6): the error without direction (mean of forward and reverse)."""
        return 0.5 * (self.forward + self.reverse)

    @property
    def reversal(self) -> np.ndarray:
        """(n, 6): forward minus reverse (the ISO 230-2 reversal value B_i of each component)."""
        return self.forward - self.reverse

    def column(self, name: str) -> int:
        return component_names(self.axis).index(name)


@dataclass
class ComponentTables:
    """Every axis table of a model, and the lines that say what has no table and why.

    machine : the Machine. tables : axis -> AxisTable (axes with a region only).
    notes : sentences for the user (axes without data, travel used for lack of a region ...).
    region_source : axis -> 'data' (the model's support), 'range' (--range alone), 'travel'.
    unheld_reversal : axis -> (mean, largest, unit) of the reversal the model's data show and the
        model does not hold (mtcomp.export._reversal.unheld_reversals), file units.
    fitted : the FittedModel. pose : (n_axes,) the pose every table is read at (each other axis
        there), mm and rad. volume : axis -> (lo, hi) where the data reached, rotary axes too (also
        those a format writes no table for): what is not carried is swept over it.
    """

    machine: object
    tables: dict
    notes: list = field(default_factory=list)
    region_source: dict = field(default_factory=dict)
    unheld_reversal: dict = field(default_factory=dict)
    fitted: object = None
    pose: np.ndarray | None = None
    volume: dict = field(default_factory=dict)

    def has_backlash(self, axis: str, tol: float = 1e-9) -> bool:
        """True when the positioning error of ``axis`` depends on the approach direction."""
        t = self.tables[axis]
        j = own_column(self.machine, axis)
        return bool(np.max(np.abs(t.reversal[:, j])) > tol)


# ------------------------------------------------------------------------------------ the region
def _axis_named(option: str, item: str, axis: str, machine) -> str:
    """``axis`` of the option's ``item`` upper-cased; InputError when the machine has no such axis."""
    axis = axis.strip().upper()
    if axis not in machine.axis_names:
        raise InputError(f"{option} {item!r}: the machine has no axis {axis} "
                         f"(axes: {' '.join(machine.axis_names)})")
    return axis


def parse_ranges(items, machine) -> dict:
    """``['X=0:400', 'C=-90:90']`` -> {'X': (0.0, 400.0), 'C': (-pi/2, pi/2)} (mm, rad)."""
    out = {}
    for item in items or ():
        axis, sep, rest = item.partition("=")
        lo_s, sep2, hi_s = rest.partition(":")
        if not sep or not sep2:
            raise InputError(f"--range {item!r}: expected AXIS=LO:HI, e.g. X=0:400")
        axis = _axis_named("--range", item, axis, machine)
        try:
            lo, hi = float(lo_s), float(hi_s)
        except ValueError:
            raise InputError(f"--range {item!r}: LO and HI must be numbers (mm, or deg for a rotary "
                             "axis)") from None
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise InputError(f"--range {item!r}: needs finite LO < HI")
        f = math.pi / 180.0 if machine.axis(axis).is_rotary else 1.0
        _within_travel("--range", item, machine, axis, (lo * f, hi * f))
        out[axis] = (lo * f, hi * f)
    return out


def _within_travel(option: str, item: str, machine, axis: str, values) -> None:
    """InputError when a linear axis's ``values`` (mm) lie beyond the machine's travel (a rotary
    axis's angle is any turn of one it reaches)."""
    ax = machine.axis(axis)
    lo, hi = ax.travel
    if ax.is_rotary or all(lo - 1e-9 <= v <= hi + 1e-9 for v in values):
        return
    raise InputError(f"{option} {item!r}: {axis} beyond the machine's travel {lo:g} .. {hi:g} mm")


def parse_pose(items, machine) -> dict:
    """``['Z=-200,X=-300']`` (``--at``, repeatable) -> {'Z': -200.0, 'X': -300.0} (mm, rad)."""
    out = {}
    for item in items or ():
        for part in str(item).split(","):
            axis, sep, value = part.partition("=")
            if not sep or not axis.strip():
                raise InputError(f"--at {item!r}: expected AXIS=VALUE[,AXIS=VALUE], e.g. Z=-200,X=-300")
            axis = _axis_named("--at", item, axis, machine)
            try:
                v = float(value)
            except ValueError:
                v = float("nan")
            if not math.isfinite(v):
                raise InputError(f"--at {item!r}: {axis}'s position must be a number (mm, or deg for "
                                 "a rotary axis)")
            out[axis] = v * (math.pi / 180.0 if machine.axis(axis).is_rotary else 1.0)
            _within_travel("--at", item, machine, axis, (out[axis],))
    return out


def table_pose(machine, volume: dict, at: dict | None = None) -> np.ndarray:
    """(n_axes,) the pose every axis's table is read at (each other axis there), mm and rad: an
    axis given in ``at`` (--at) there, taken into its region; else a linear axis at the middle of ``volume`` (where the
    data reached: for an angular error acting through an arm that grows linearly with another axis,
    the table read at the middle of that axis's data is the least-squares best 1-D table over
    them), a rotary axis, or an axis without data, at its reference position taken into its
    region (:func:`reference_positions`)."""
    ref = reference_positions(machine)
    pose = []
    for ax in machine.axes:
        a = ax.name
        if at and a in at:
            # beyond the data the model is held at the region's end, as everywhere in export
            pose.append(min(max(float(at[a]), volume[a][0]), volume[a][1]) if a in volume else float(at[a]))
        elif a in volume and not ax.is_rotary:
            pose.append(0.5 * (volume[a][0] + volume[a][1]))
        elif a in volume:
            pose.append(min(max(ref[a], volume[a][0]), volume[a][1]))
        else:
            pose.append(ref[a])
    return np.array(pose)


def table_region(fitted, ranges: dict | None = None) -> tuple[dict, dict, list]:
    """Where each axis gets a table: (region axis -> (lo, hi), source axis -> str, notes).

    The model's support (where its data reached), clipped by ``ranges``. An axis absent from the
    support moved in none of the fitted data: no table. Without a support (``None``: a model written
    by hand or by an older mtcomp) the ranges are used where given, else the travel, with a warning.
    """
    machine = fitted.machine
    ranges = dict(ranges or {})
    region, source, notes = {}, {}, []
    support = fitted.support
    unit = {a.name: ("deg", 180.0 / math.pi) if a.is_rotary else ("mm", 1.0) for a in machine.axes}
    if support is None:
        notes.append("WARNING: the model does not say where its data reached (no 'support' in "
                     "MODEL.json); tables span " + ("the --range given and otherwise " if ranges else "")
                     + "the machine's travel, where the model may be extrapolating. Refit with a "
                     "current mtcomp or give --range AXIS=LO:HI.")
    for ax in machine.axes:
        a = ax.name
        u, f = unit[a]
        if support is None:
            lo, hi = ranges.get(a, ax.travel)
            region[a], source[a] = (float(lo), float(hi)), ("range" if a in ranges else "travel")
            continue
        if a not in support:
            notes.append(f"axis {a}: no table: the axis did not move in the data the model was fitted "
                         "on, so its errors are unknown (the model holds them at zero)")
            continue
        lo, hi = support[a]
        if a in ranges:
            lo, hi = max(lo, ranges[a][0]), min(hi, ranges[a][1])
            given = f"--range {ranges[a][0] * f:g}:{ranges[a][1] * f:g} {u}"
            data = f"the region of the data {support[a][0] * f:g}:{support[a][1] * f:g} {u}"
            if not lo < hi:
                notes.append(f"axis {a}: no table: {given} does not overlap {data}")
                continue
            if ranges[a][0] < support[a][0] or ranges[a][1] > support[a][1]:
                notes.append(f"axis {a}: {given} reaches beyond {data}: the table covers "
                             f"{lo * f:g}:{hi * f:g} {u} (beyond the data the model is not known; "
                             "where a controller holds a table's end values beyond it, it holds "
                             "them there)")
        if not lo < hi:
            notes.append(f"axis {a}: no table: the data reached only one position ({lo * f:g} {u})")
            continue
        t_lo, t_hi = ax.travel
        if lo < t_lo or hi > t_hi:
            c_lo, c_hi = max(lo, t_lo), min(hi, t_hi)
            what = (f"axis {a}: the region of the data {lo * f:g}:{hi * f:g} {u} "
                    f"{'lies outside' if not c_lo < c_hi else 'reaches beyond'} the machine's travel "
                    f"{t_lo * f:g}:{t_hi * f:g} {u}")
            if not c_lo < c_hi:
                notes.append(f"{what}: no table (was the model made on another machine?)")
                continue
            notes.append(f"{what}: the table stops at the travel")
            lo, hi = c_lo, c_hi
        region[a], source[a] = (float(lo), float(hi)), "data"
    return region, source, notes


# ------------------------------------------------------------------------------------ the grid
_NICE = (1.0, 2.0, 2.5, 5.0)


def _nice_steps(smallest: float):
    k = math.floor(math.log10(smallest)) - 1
    while True:
        for m in _NICE:
            s = m * 10.0 ** k
            if s >= smallest * (1 - 1e-12):
                yield s
        k += 1


def grid_positions(lo: float, hi: float, step: float, include_end: bool,
                   anchor: float | None = None) -> np.ndarray:
    """lo, lo + step, ... up to hi (equidistant, inside [lo, hi]); with ``include_end`` also hi.
    With ``anchor``: the points anchor + k step inside [lo, hi] instead (a point sits on the anchor)."""
    if anchor is not None:
        k0 = math.ceil((lo - anchor) / step - 1e-9)
        k1 = math.floor((hi - anchor) / step + 1e-9)
        return anchor + step * np.arange(k0, k1 + 1)
    n = int(math.floor((hi - lo) / step + 1e-9)) + 1
    g = lo + step * np.arange(n)
    if include_end and hi - g[-1] > 1e-9 * max(1.0, abs(hi)):
        g = np.append(g, hi)
    return g


def plan_grids(machine, region: dict, max_points: int, step_mm: float | None = None,
               step_deg: float | None = None, include_end: bool = False,
               what: str = "the controller", anchors: dict | None = None) -> dict:
    """Grid of each axis of ``region`` (axis -> (n,) positions, mm or rad).

    An explicit step (``step_mm`` for linear axes, ``step_deg`` for rotary ones) is used as given and
    refused (InputError) when the grid would exceed ``max_points``; without one, the smallest of
    1, 2, 2.5, 5 x 10^k mm (deg) not below 1 mm (1 deg) whose grid fits ``max_points``.
    ``anchors`` (axis -> position): grids through that position (:func:`grid_positions`), reaching
    from it to the region when it lies outside the region. Where the axis can stand beyond its
    region, the grid reaches one step past it (:func:`mtcomp.export._ends.close_grid`: the table is
    zero there), and those points count towards ``max_points``.
    """
    grids = {}
    for a, (lo, hi) in region.items():
        anchor = None if anchors is None else anchors.get(a)
        ends = open_ends(machine, a, lo, hi)
        rotary = machine.axis(a).is_rotary
        f = math.pi / 180.0 if rotary else 1.0
        u = "deg" if rotary else "mm"
        given = step_deg if rotary else step_mm

        def grid(step, a_lo=min(lo, anchor) if anchor is not None else lo,
                 a_hi=max(hi, anchor) if anchor is not None else hi, anchor=anchor):
            g = grid_positions(a_lo, a_hi, step * f, include_end and anchor is None, anchor)
            return close_grid(g, lo, hi, step * f, ends)
        span = (hi - lo) / f
        if given is not None:
            if not (given > 0 and math.isfinite(given)):
                raise InputError(f"--grid-{u} must be a positive number, got {given:g}")
            n = len(grid(given))
            if n > max_points:
                extra = n - int(math.floor(span / given + 1e-9)) - 1
                raise InputError(f"--grid-{u} {given:g} gives {n} points on axis {a} ({span:g} {u}"
                                 + (", with the points beyond the data" if any(ends) else "")
                                 + f"); {what} holds at most {max_points}: use --grid-{u} >= "
                                 f"{span / max(1, max_points - 1 - extra):.4g}")
            grids[a] = grid(given)
        else:
            steps = _nice_steps(max(1.0, span / (max_points - 1 - (1 if include_end else 0))))
            grids[a] = next(g for g in map(grid, steps) if len(g) <= max_points)
    return grids


# ------------------------------------------------------------------------------------ evaluation
def _rotation_function(model):
    """CasADi function (q, p, c) -> (3,): rotation vector of the tool relative to the workpiece,
    actual times nominal transposed, vee((R - R^T) / 2) (exact to third order in the angle). Built
    once per model structure (:func:`mtcomp.models.function_cache.model_function`)."""
    from ..models.function_cache import model_function

    def build():
        import casadi as ca
        q = ca.SX.sym("q", model.machine.n_axes)
        p = ca.SX.sym("p", model.n_params)
        c = ca.SX.sym("c", model.n_context)
        _, _, R = model.symbolic(q, p, c, errors=True)
        _, _, R0 = model.symbolic(q, p, c, errors=False)
        Rr = ca.mtimes(R, R0.T)
        w = 0.5 * ca.vertcat(Rr[2, 1] - Rr[1, 2], Rr[0, 2] - Rr[2, 0], Rr[1, 0] - Rr[0, 1])
        return ca.Function("tool_rotation", [q, p, c], [w])
    return model_function(model, "tool_rotation", build)


def model_errors(fitted, q: np.ndarray, directions: dict | None = None) -> tuple[np.ndarray, bool]:
    """(N, 6) tip deviation (mm) and tool rotation (rad) the model predicts at poses ``q`` (N, n_axes),
    with context ``dir_<axis>`` from ``directions`` (axis -> (N,) or scalar), everything else at the
    model's defaults (tool length from the machine). Second value: False when the rotation could not
    be evaluated (then columns 3..5 are NaN)."""
    model = fitted.model
    n = q.shape[0]
    cols = {f"dir_{a}": np.broadcast_to(np.asarray(v, dtype=float), (n,))
            for a, v in (directions or {}).items()}
    c = fitted.context(n, cols)
    p = fitted.params.values
    q, _ = fitted.clamp(q)        # where the data held an axis, the model is evaluated there
    out = np.full((n, 6), np.nan)
    out[:, :3] = deviation(model, q, p, c)[:, :3]
    try:
        fn = _rotation_function(model)
    except Exception:  # a model without the symbolic chain: translations only
        return out, False
    out[:, 3:] = casadi_map_call(fn, np.ascontiguousarray(q), p, np.ascontiguousarray(c))[0]
    return out, True


def reference_positions(machine) -> dict:
    """Reference position of every axis (mm or rad): its machine coordinate 0, or the nearest end of
    its travel when 0 lies outside the travel (a reference return has to reach it)."""
    return {ax.name: float(min(max(0.0, ax.travel[0]), ax.travel[1])) for ax in machine.axes}


def _evaluation_pose(machine, region: dict) -> np.ndarray:
    """(n_axes,) the reference positions, each taken into its axis's region (axis -> (lo, hi)):
    the pose the model is evaluated at (beyond its data the model is held at the region's end)."""
    ref = reference_positions(machine)
    return np.array([min(max(ref[a], region[a][0]), region[a][1]) if a in region else ref[a]
                     for a in machine.axis_names])


#: the deviation at the reference position below which it goes unmentioned (um, urad)
CONSTANT_NOTE_MIN = 0.1


def undetermined_at(fitted, q: np.ndarray, base: np.ndarray) -> np.ndarray:
    """(6,) bool: which of the tip deviation's and the tool's turn's components at the pose ``q``
    (n_axes,), whose values there are ``base`` (1, 6) (:func:`model_errors`), move along a direction
    the data left undetermined (MODEL.json's ``uncertainty.undetermined``, each at the size of 1 um
    of tool-tip error) by more than :data:`~mtcomp.models.model_file.UNDETERMINED_UM` um or urad
    (predict's rule for a blank standard error): what the model holds there is the fit's choice
    among models that fit the data alike, not a measurement (a spindle tilt A0S that the data read
    only in combination with set-ups and rolls no laser named); or with a rotary axis's zero offset
    the data did not read apart from its positioning error
    (:func:`mtcomp.identification._offsets.unread_offsets`), taken to zero."""
    from ..identification._offsets import unread_offsets
    out = np.zeros(6, dtype=bool)
    names = unread_offsets(fitted)
    if names:
        out |= _moves(fitted, q, base, [fitted.params.index(n) for n in names], 0.0)
    u = fitted.uncertainty
    N = None if u is None else np.asarray(u.get("undetermined", ()), dtype=float)
    if N is None or not N.size or not len(u["names"]):
        return out
    N = N.reshape(len(u["names"]), -1)
    idx = np.array([fitted.params.index(n) for n in u["names"]], dtype=int)
    for k in range(N.shape[1]):
        out |= _moves(fitted, q, base, idx, fitted.params.values[idx] + N[:, k])
    return out


def _moves(fitted, q: np.ndarray, base: np.ndarray, idx, values) -> np.ndarray:
    """(6,) bool: the components at ``q`` that move from ``base`` (1, 6) by more than
    UNDETERMINED_UM um or urad when the parameters ``idx`` take ``values``."""
    moved = copy.copy(fitted)
    moved.params = fitted.params.copy()
    moved.params.values[idx] = values
    other, _ = model_errors(moved, q[None, :])
    d = np.abs(other[0] - base[0]) * np.r_[np.full(3, 1e3), np.full(3, 1e6)]
    return np.nan_to_num(d) > UNDETERMINED_UM


def _constant_note(zero: np.ndarray, rotary: bool = True, open_parts=None) -> list:
    """A note on what no table carries: the deviation ``zero`` (6,) (mm, rad) the model predicts with
    every axis at its reference position, from which every table is measured (none when each
    component is below CONSTANT_NOTE_MIN um or urad). ``rotary``: whether the machine has rotary
    axes (without them a turn is no axis's offset: the tool stands turned relative to the part).
    ``open_parts``: (6,) bool, the components the data do not determine (:func:`undetermined_at`)."""
    um, urad = zero[:3] * 1e3, zero[3:] * 1e6
    if not (np.nanmax(np.abs(um)) >= CONSTANT_NOTE_MIN or np.nanmax(np.abs(urad)) >= CONSTANT_NOTE_MIN):
        return []
    open_parts = np.zeros(6, dtype=bool) if open_parts is None else np.asarray(open_parts, dtype=bool)
    mark = [" (not determined by the data)" if o else "" for o in open_parts]
    parts = [f"d{c} {v:+.2f} um{mark[j]}" for j, (c, v) in enumerate(zip("xyz", um))
             if abs(v) >= CONSTANT_NOTE_MIN]
    parts += [f"a turn of {v:+.2f} urad about {c.upper()}{mark[3 + j]}"
              for j, (c, v) in enumerate(zip("xyz", urad)) if abs(v) >= CONSTANT_NOTE_MIN]
    shown = np.r_[np.abs(um) >= CONSTANT_NOTE_MIN, np.abs(urad) >= CONSTANT_NOTE_MIN]
    why = ("; what is marked not determined is the fit's choice among models that fit the data "
           "alike (the data read a spindle tilt or a squareness there only in combination with "
           "set-ups and angles no file measured, a rotary axis's zero offset only with its "
           "positioning error at the angles read; identify --verbose lists them), not a "
           "measurement, and any value there fits the data as well" if np.any(open_parts & shown) else "")
    turn = ("a turn is the machine's set-up there (a rotary axis's zero offset: its home offset), "
            "which compensate corrects and these tables do not" if rotary else
            "a turn is the tool standing tilted relative to the part (the spindle's tilt, a "
            "squareness): a machine without rotary axes has no axis that could turn it back, and at "
            "this tool length its effect at the tool tip is the translation; with another tool "
            "length the tip moves by the length's difference times the turn, which compensate "
            "corrects for the tool length it is given and these tables do not")
    return [f"with every axis at its reference position the model predicts {', '.join(parts)}: no "
            "table carries it (each table is zero there); a work offset taken on the part takes the "
            f"translation, and {turn}{why}"]


def reference_notes(machine, axes) -> list:
    """One line per axis of ``axes`` whose machine zero lies outside its travel: where its reference
    position is taken instead, and why."""
    notes = []
    for a in axes:
        ax = machine.axis(a)
        lo, hi = ax.travel
        if not lo <= 0.0 <= hi:
            u, f = ("deg", 180.0 / math.pi) if ax.is_rotary else ("mm", 1.0)
            end = lo if lo > 0 else hi
            notes.append(f"axis {a}: the machine zero lies outside its travel {lo * f:g}:{hi * f:g} {u}: "
                         f"its reference position is taken at the travel's nearest end, {end * f:g} {u} "
                         "(a reference return has to reach it); the tables are zero there")
    return notes


def table_sd_um(fitted, q: np.ndarray, q_ref: np.ndarray, directions: dict,
                uncertainty: CorrectionUncertainty | None = None,
                components: bool = False) -> np.ndarray | None:
    """(N,) the standard error (um) of the tip deviation at poses ``q`` (N, n_axes) less that at
    ``q_ref`` (the table's zero), with the context ``dir_<axis>`` of ``directions``: the largest of
    its three components' ((N, 3) each component's with ``components``), by compensate's rule for a
    correction's (:class:`~mtcomp.planner._uncertainty.CorrectionUncertainty`: predict's
    covariance, the weakly held combinations' variance included; infinite where the table moves
    with values the data left undetermined). None when the model carries no uncertainty.
    ``uncertainty``: the model's CorrectionUncertainty when already made."""
    from ..models.evaluate import evaluate
    unc = CorrectionUncertainty(fitted) if uncertainty is None else uncertainty
    if not unc.known:
        return None
    n = q.shape[0]
    cols = {f"dir_{a}": np.broadcast_to(np.asarray(v, dtype=float), (n,)) for a, v in directions.items()}
    p = fitted.params.values
    J = evaluate(fitted.model, "tip_pjacobian_function", fitted.clamp(q)[0], p, fitted.context(n, cols))[0]
    J0 = evaluate(fitted.model, "tip_pjacobian_function", fitted.clamp(q_ref[None, :])[0], p,
                  fitted.context(1, {}))[0]
    each = unc.components(J, J0)
    return each if components else each.max(axis=1)


def axis_table_sd_um(fitted, a: str, q: np.ndarray, q_ref: np.ndarray) -> np.ndarray | None:
    """(N,) :func:`table_sd_um` of axis ``a``'s table at poses ``q``, the larger of its two approach
    directions; None when the model carries no uncertainty."""
    unc = CorrectionUncertainty(fitted)
    if not unc.known:
        return None
    return np.maximum(*(table_sd_um(fitted, q, q_ref, {a: d}, unc) for d in (1.0, -1.0)))


def _table_left(fitted, a: str, q: np.ndarray, q_ref: np.ndarray, tips: dict,
                max_sd_um: float | None, unc: CorrectionUncertainty | None):
    """(note, left): the note saying why axis ``a``'s table is not written, or None (written):
    compensate's gate on the axis moving through the table's points, one contour
    (:func:`~mtcomp.planner._contours.one_contour_left`): some point's standard error exceeds
    ``max_sd_um``, or no point's value is told from zero by its standard errors. ``tips``: +-1 ->
    (N, 3) mm, the table's tip columns in that direction (the correction compensate makes there
    with its datum at the table's zero); ``unc`` the model's CorrectionUncertainty (None: no
    limit asked). As compensate corrects a block in the tip components it is sure of
    (:func:`~mtcomp.planner._uncertainty.components_left`), a linear axis whose own component
    (its positioning) is determined at every point keeps its table without the components the data
    do not determine (``left``, columns; their values are set to zero in ``tips``, views
    of the table's columns, and the note says so) and is judged on the rest."""
    if not max_sd_um or unc is None or not unc.known:
        return None, ()
    each = {d: table_sd_um(fitted, q, q_ref, {a: d}, unc, components=True) for d in (1.0, -1.0)}
    # a component another axis's straightness the data do not determine, or not to within the
    # limit: a table carries its own error without it (a pitch table without the straightness)
    over = np.any([(e[:, :3] > max_sd_um).any(axis=0) for e in each.values()], axis=0)
    own = own_column(fitted.machine, a)
    left = tuple(int(c) for c in np.flatnonzero(over)) if own < 3 and not over[own] else ()
    for d in each:
        each[d] = np.array(each[d][:, :3])
        each[d][:, list(left)] = 1.0           # a component left is judged by none of the rules
        tips[d][:, list(left)] = 0.0
    sd = np.concatenate([each[d].max(axis=1) for d in each])
    z = np.concatenate([in_sd(tips[d] * 1e3, each[d]) for d in each])
    why = one_contour_left(sd, z, max_sd_um)
    if why is None:
        return (None, ()) if not left else (
            f"axis {a}: its table carries its own error and leaves its "
            + " and ".join(f"straightness in {'XYZ'[c]} (E{'XYZ'[c]}{a})" for c in left)
            + ": the data do not determine it, or not to within --max-correction-sd-um (a "
            "controller's pitch table does not carry it anyway)", left)
    ax = fitted.machine.axis(a)
    u, f = ("deg", 180.0 / math.pi) if ax.is_rotary else ("mm", 1.0)
    if why == "indistinct":
        k = int(np.nanargmax(z))
        return (f"axis {a}: no table: no point's value is told from zero by its standard error (at "
                f"most {z[k]:.2g} of them, at {q[k % len(q), fitted.machine.index(a)] * f:g} {u}; "
                f"under {SMALL_IN_SD:g} everywhere), as compensate leaves such blocks uncorrected: "
                "measure more, or more often, to tell it"), ()
    top = float(sd.max())
    at = q[int(np.argmax(sd)) % len(q), fitted.machine.index(a)] * f
    if not np.isfinite(top):
        return (f"axis {a}: no table: it moves with values of the model its data did not determine "
                f"(at {at:g} {u}), as compensate leaves such blocks uncorrected; "
                + unsure_advice(top, max_sd_um, "writes the table")), ()
    return (f"axis {a}: no table: its correction's standard error reaches {top:.3g} um (at "
            f"{at:g} {u}), above the limit of {max_sd_um:g} um (--max-correction-sd-um), as "
            "compensate leaves such blocks uncorrected; "
            + unsure_advice(top, max_sd_um, "writes the table")), ()


#: a table whose points miss more than this (um, along its own axis) of the model's error between
#: them gets a note (a period shorter than a few grid steps: a screw's)
BETWEEN_NOTE_UM = 0.5


def _between_points(fitted, a: str, g: np.ndarray, pose: np.ndarray, region, own: np.ndarray):
    """The note when the table of axis ``a`` (points ``g``, its own error ``own`` there, forward)
    read by linear interpolation misses more than :data:`BETWEEN_NOTE_UM` of the model's own error
    of that axis at the quarter and half points between its points inside ``region``."""
    machine = fitted.machine
    if len(g) < 2 or machine.axis(a).is_rotary:
        return None
    mid = (g[:-1, None] + np.diff(g)[:, None] * np.array([0.25, 0.5, 0.75])).ravel()
    mid = mid[(mid >= region[0]) & (mid <= region[1])]
    if not mid.size:
        return None
    q = np.tile(pose, (mid.size, 1))
    q[:, machine.index(a)] = mid
    i = machine.index(a)
    q0 = pose.copy()
    q0[i] = np.clip(g[0], *region)
    at, _ = model_errors(fitted, np.vstack([q, q0]), {a: 1.0})       # the last row: q0
    col = own_column(machine, a)
    miss = np.abs((at[:-1, col] - at[-1, col]) - (np.interp(mid, g, own) - own[0])) * 1e3
    if miss.max() <= BETWEEN_NOTE_UM:
        return None
    k = int(np.argmax(miss))
    return (f"axis {a}: its table's points every {g[1] - g[0]:g} mm miss up to {miss[k]:.2g} um of "
            f"the model's error along {a} between them (at {a} {mid[k]:.6g} mm): an error of a "
            "shorter period than a few steps (a screw's); a finer --grid-mm carries it, as far as "
            "the controller's point limit allows")


def component_tables(fitted, grids: dict, region: dict | None = None,
                     notes: list | None = None, source: dict | None = None,
                     max_sd_um: float | None = None, volume: dict | None = None,
                     pose: np.ndarray | None = None) -> ComponentTables:
    """Evaluate the component errors of every axis of ``grids`` (module docstring).

    grids : axis -> (n,) positions, mm or rad (machine coordinates). region : axis -> (lo, hi) where
    the model's data reached (default: the grids' ends); grid points beyond it hold the end value,
    but on a rotary axis measured over part of its turn those past the first at or past each end
    are zero (:func:`mtcomp.export._ends.beyond_span`).
    volume : axis -> (lo, hi) where the data reached, rotary axes included (default ``region``):
        where what no table carries is swept (:mod:`._uncarried`).
    pose : (n_axes,) where every other axis stands while an axis's table is read (mm, rad;
        default: the reference positions, :func:`table_pose` gives the export's). Each table is
        zero at its own axis's reference position, the others at ``pose``: along a line through
        ``pose`` the tables correct what compensate corrects, up to one constant.
    max_sd_um : an axis gets no table, and a note says why, where compensate would leave its
    axis's motion through the table's points uncorrected as one contour (:func:`_table_left`): its
    standard error (:func:`table_sd_um`, either direction) exceeds this anywhere on its grid, or
    no point's value is told from zero by it (None or 0: no limit, and neither rule). The whole
    table, not the points over the limit: a controller interpolates between its points, and a table
    zero at some points and not at their neighbours would put steps into the axis's motion.
    The model is evaluated without its drift terms (:meth:`FittedModel.without_drift`): the
    tables hold the geometry, and a drift model's value at its reference temperatures is no error
    of an axis (its constant holds where the thermal record's probe was zeroed).
    """
    fitted = fitted.without_drift()
    machine = fitted.machine
    region = dict(region or {a: (float(g[0]), float(g[-1])) for a, g in grids.items()})
    ref = reference_positions(machine)
    q_ref = _evaluation_pose(machine, region)
    pose = q_ref if pose is None else np.asarray(pose, dtype=float)
    tables, dropped, uncertain = {}, [], []
    unc = CorrectionUncertainty(fitted) if max_sd_um else None
    for a, g in grids.items():
        g = np.asarray(g, dtype=float)
        lo, hi = region.get(a, (float(g[0]), float(g[-1])))
        i = machine.index(a)
        q0 = pose.copy()
        q0[i] = q_ref[i]                                # the table's zero: its axis's reference
        q = np.tile(pose, (len(g), 1))
        q[:, i] = np.clip(g, lo, hi)                    # beyond the data: the end value, held
        zero, _ = model_errors(fitted, q0[None, :])
        fwd, known = model_errors(fitted, q, {a: 1.0})
        rev, _ = model_errors(fitted, q, {a: -1.0})
        fwd, rev = fwd - zero, rev - zero
        why, left = _table_left(fitted, a, q, q0, {1.0: fwd[:, :3], -1.0: rev[:, :3]}, max_sd_um, unc)
        uncertain += [why] if why else []
        if why and not left:
            continue
        ax = machine.axis(a)
        if ax.is_rotary and ax.side == "workpiece":
            # a rotary table turns the workpiece: its own error is minus the tool's rotation
            j = own_column(machine, a)
            fwd[:, j], rev[:, j] = -fwd[:, j], -rev[:, j]
        missed = _between_points(fitted, a, g, q[0], (lo, hi), fwd[:, own_column(machine, a)])
        if missed:
            uncertain.append(missed)
        off = beyond_span(g, lo, hi, ax.is_rotary)    # past a rotary's ramp: no correction
        fwd[off], rev[off] = 0.0, 0.0
        if not (np.nanmax(np.abs(fwd)) > ZERO or np.nanmax(np.abs(rev)) > ZERO):
            dropped.append(a)
            continue
        tables[a] = AxisTable(a, ax.is_rotary, g, fwd, rev, ref, known, (float(lo), float(hi)), left)
    zero, _ = model_errors(fitted, q_ref[None, :])
    notes = list(notes or []) + reference_notes(machine, tables) + uncertain + \
        _constant_note(zero[0], bool(machine.rotary_axes), undetermined_at(fitted, q_ref, zero))
    if max_sd_um and fitted.uncertainty is None:
        notes.append("the model carries no covariance (identify, diagnose and a thermal diagnosis "
                     "write one; an older model file may not): no table could be checked against "
                     "--max-correction-sd-um")
    notes += [f"axis {a}: no table: the model predicts no error at all along it (its errors are held at "
              "zero: no data determined them)" for a in dropped]
    reversal = reversal_note(fitted)
    if reversal:
        notes.append(reversal)
    return ComponentTables(machine, tables, notes, dict(source or {}), unheld_reversals(fitted),
                           fitted, pose, dict(volume or region))

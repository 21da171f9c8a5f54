"""A fitted model in a metrologist's terms: what `mtcomp identify` and `mtcomp diagnose` print.

* :func:`component_ranges`: per axis the data moved, each ISO 230-1 component error (positioning,
  straightness, angular: roll, pitch, yaw; a rotary axis's angular positioning, radial, axial and
  tilt motions) as its range over the travel the data reached, with the range's standard error from
  the model's covariance; the squareness, spindle tilt and rotary-axis location errors as values.
  A component the data do not determine is said to be so, never printed as a number.
* :func:`laser_target_tables`: for every laser file, the mean reading of the runs per target and
  approach direction, the model's prediction there and the residual (an ISO 230-2 style table).
* :func:`file_rms_lines`: the rms residual of every file, from the model's predictions.
* :func:`parameter_lines`: the raw parameter rows (``--verbose``).

Everything is evaluated from the model (its CasADi chain, :mod:`mtcomp.models.evaluate`), never read
off the coefficients: a B-spline coefficient of -259 um can belong to a profile whose range is 2 um.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca
import numpy as np

from ..machine import AXIS_DIRECTION
from ..models.chain import SPINDLE_TILT, rotary_location_names, slope_carried, squareness_names
from ..models.evaluate import casadi_map_call
from ..models.model_file import FittedModel
from ..models.terms import ANGLE_LETTERS, TRANSLATION_LETTERS, positioning_component
from .penalty import RHO_BOUND, component_class
from .predict import Undetermined, predict_readings

#: positions along an axis at which a component's profile is evaluated
GRID_POINTS = 201

#: at most this many targets of a laser component are printed without --verbose
COMPACT_TARGETS = 30

#: without --verbose, per-target tables of the components other than positioning only when a file
#: has at most this many components
COMPACT_COMPONENTS = 3


def component_meaning(name: str, comp: str) -> str:
    """What component ``comp`` (e.g. 'EBX') of axis ``name`` is to a metrologist: 'positioning',
    'straightness in Y', 'roll', 'pitch', 'yaw' (X and Y: pitch about the other horizontal axis, yaw
    about Z), 'tilt about X' (Z); for a rotary axis 'angular positioning', 'radial in X', 'axial',
    'tilt about X'."""
    d = comp[1]
    if name in ANGLE_LETTERS:
        if comp == positioning_component(name):
            return "angular positioning"
        if d in TRANSLATION_LETTERS:
            return "axial" if TRANSLATION_LETTERS.index(d) == AXIS_DIRECTION[name] else f"radial in {d}"
        return f"tilt about {TRANSLATION_LETTERS[ANGLE_LETTERS.index(d)]}"
    if d == name:
        return "positioning"
    if d in TRANSLATION_LETTERS:
        return f"straightness in {d}"
    about = TRANSLATION_LETTERS[ANGLE_LETTERS.index(d)]
    if about == name:
        return "roll"
    if name == "Z":
        return f"tilt about {about}"
    return "yaw" if about == "Z" else "pitch"


@dataclass
class ComponentRange:
    """One component error of one axis over the travel the data reached.

    axis, component (ISO 230-1 name), meaning (:func:`component_meaning`), unit ('um' or 'urad').
    lo, hi : the travel the data reached, mm or deg.
    range : max minus min of the profile over [lo, hi] (straightness: about its least-squares line),
        file units; sd : its standard error (NaN without a covariance).
    largest_sd : the largest standard error of the profile along [lo, hi], relative to its value at
        the first position (straightness: about its least-squares line).
    status : 'fitted', 'undetermined' (the data do not determine the profile), 'flat' (the data
        determine it and show no variation above their noise: the roughness penalty, whose weight
        REML chose from them, holds the profile flat, or straight about its line, so its range is 0
        and its posterior variance none; :mod:`mtcomp.identification.penalty`), 'held' (none of its
        parameters was fitted: held at zero) or 'unmeasured' (no laser file names it and the data
        leave it open: held at zero, :mod:`mtcomp.identification.unmeasured`).
    """

    axis: str
    component: str
    meaning: str
    unit: str
    lo: float
    hi: float
    range: float
    sd: float
    largest_sd: float
    status: str
    #: straightness whose slope no squareness carries: the least-squares line's slope, urad (um/m)
    slope: float = float("nan")


@dataclass
class LocationValue:
    """A single-valued error (squareness, spindle tilt, rotary-axis location): value +- sd, file units;
    status as :class:`ComponentRange`."""

    name: str
    meaning: str
    unit: str
    value: float
    sd: float
    status: str


def _component_function(model, axis) -> ca.Function:
    """CasADi (s (1,), p, c) -> (E (6,), dE/dp (6, n_params)): the six component errors of ``axis`` at
    position s (mm or rad), internal units, with every extension term's contribution, in the order
    E X, E Y, E Z, E A, E B, E C of the axis."""
    s = ca.SX.sym("s")
    p = ca.SX.sym("p", model.n_params)
    c = ca.SX.sym("c", model.n_context)
    P = {n: p[i] for i, n in enumerate(model.param_names)}
    C = {n: c[i] for i, n in enumerate(model.context_names)}
    if axis.is_rotary:
        comps = model.rotary_components(axis.name, s, P, C)
    else:
        _, comps, _, _ = model.linear_parts(axis.name, s, P, C)
    order = [f"E{d}{axis.name}" for d in TRANSLATION_LETTERS + ANGLE_LETTERS]
    E = ca.vertcat(*[comps.get(n, ca.SX(0)) for n in order])
    return ca.Function(f"components_{axis.name}", [s, p, c], [E, ca.jacobian(E, p)])


def _fitted_mask(fitted: FittedModel) -> np.ndarray | None:
    """(n_params,) bool: the parameters the fit estimated (None: the model does not say)."""
    if fitted.uncertainty is None:
        return None
    mask = np.zeros(len(fitted.params), dtype=bool)
    mask[[fitted.params.index(n) for n in fitted.uncertainty["names"]]] = True
    return mask


def _status(J: np.ndarray, sd: np.ndarray, fitted_mask) -> str:
    """'held' when nothing fitted moves the rows J, 'undetermined' when one of them rests on what the
    data did not determine (sd NaN with a covariance), else 'fitted'."""
    if fitted_mask is not None and not np.any(J[:, fitted_mask]):
        return "held"
    if fitted_mask is not None and np.any(np.isnan(sd)):
        return "undetermined"
    return "fitted"


def component_ranges(fitted: FittedModel, undetermined: Undetermined | None = None):
    """(ranges, values, notes): :class:`ComponentRange` of every component of every axis the data
    moved (the model's ``support``), :class:`LocationValue` of the squareness, spindle tilt and
    rotary location errors, and sentences on the axes the data did not move.

    Profiles are evaluated at the model's reference context (approach direction unknown: the mean of
    both directions; feed 0; the reference conditions of drift terms). Straightness is taken about
    its least-squares line over [lo, hi] (ISO 230-1's reference line), so its slope, which is the
    squareness's, does not count in its range.
    """
    machine = fitted.machine
    unmeasured = _unmeasured(fitted)
    und = undetermined if undetermined is not None else _resolved(Undetermined.of(fitted), fitted,
                                                                   unmeasured)
    mask = _fitted_mask(fitted)
    ranges, notes = [], []
    support = fitted.support
    if support is None:
        notes.append("the model does not say where its data reached: component ranges are over the "
                     "machine's travel")
        support = {a.name: a.travel for a in machine.axes}
    for ax in machine.axes:
        if ax.name not in support or not support[ax.name][0] < support[ax.name][1]:
            continue
        ranges += _axis_ranges(fitted, ax, *support[ax.name], und, mask)
    moved = {r.axis for r in ranges}
    info = fitted.info if isinstance(fitted.info, dict) else {}
    given = [a for a in info.get("held_axes", ()) if a not in moved]
    if given:
        notes.append(f"axes whose errors were held as given (--hold): {', '.join(given)}: the data "
                     "moved them; their errors stay where the start model puts them (zero without "
                     "--start)")
    still = [a for a in machine.axis_names if a not in moved and a not in given]
    if still:
        held = fitted.held or {}
        at = [f"{a} at {held[a] * (180.0 / math.pi if machine.axis(a).is_rotary else 1.0):g} "
              f"{'deg' if machine.axis(a).is_rotary else 'mm'}" for a in still if a in held]
        notes.append(f"axes the data did not move: {', '.join(still)}"
                     + (f" (held {', '.join(at)})" if at else "")
                     + ": how their errors vary along them is not known")
    for r in ranges:
        # held at zero by the rule (a value the data gave it through another set-up stays fitted)
        if f"{r.axis}:{r.component}" in unmeasured and (r.status != "fitted" or abs(r.range) < 1e-3):
            r.status = "unmeasured"
    if unmeasured:
        notes.append("components no laser file measures are held at zero where the data leave "
                     "them open (a positioning run at one tool length is the positioning error, "
                     "with no pitch): the components they measure are given on that assumption")
    return ranges, _location_values(fitted, und, mask), notes


def _unmeasured(fitted: FittedModel) -> set:
    """The components no laser file measured, which the fit held at zero (MODEL.json's info)."""
    return set(fitted.info.get("unmeasured", ())) if isinstance(fitted.info, dict) else set()


def location_values(fitted: FittedModel) -> list:
    """:class:`LocationValue` of the squareness, spindle tilt and rotary location errors and zero
    offsets (value +- standard error, file units), as :func:`component_ranges` gives them, without
    evaluating the component ranges."""
    und = _resolved(Undetermined.of(fitted), fitted, _unmeasured(fitted))
    return _location_values(fitted, und, _fitted_mask(fitted))


def _resolved(und: Undetermined, fitted: FittedModel, unmeasured: set) -> Undetermined:
    """``und`` without the undetermined directions that move a component no laser file measures:
    the fit held those components at zero (:mod:`mtcomp.identification.unmeasured`), so what the
    others show is determined on that assumption. The covariance is already on it (the fit's
    :func:`mtcomp.identification.unmeasured.assumption_map`)."""
    if not unmeasured or und.directions is None or not und.directions.shape[1]:
        return und
    from dataclasses import replace
    D = und.directions
    um = np.array([fitted.params.specs[i].group in unmeasured for i in und.index])
    big = np.abs(D).max(axis=0)
    keep = ~(np.abs(D[um]).max(axis=0, initial=0.0) > 1e-6 * np.where(big > 0, big, 1.0))
    # a part's tilts no file reads (._rotation.plate_tilts) stay open whatever the assumption holds
    tilts = np.asarray((fitted.uncertainty or {}).get("open", np.zeros((D.shape[0], 0))), dtype=float)
    return replace(und, directions=np.hstack([D[:, keep], tilts.reshape(D.shape[0], -1)]))


def _axis_ranges(fitted: FittedModel, ax, lo: float, hi: float, und: Undetermined, mask) -> list:
    """:class:`ComponentRange` of every component of axis ``ax`` over [lo, hi] (mm or rad)."""
    model, p = fitted.model, fitted.params.values
    ranges = []
    s = np.linspace(lo, hi, GRID_POINTS)
    fn = _component_function(model, ax)
    E, dE = casadi_map_call(fn, s[:, None], p, fitted.context(s.size))
    dE = dE.reshape(s.size, model.n_params, 6).transpose(0, 2, 1)     # (n, 6, n_params)
    f_pos = 180.0 / math.pi if ax.is_rotary else 1.0
    names = [f"E{d}{ax.name}" for d in TRANSLATION_LETTERS + ANGLE_LETTERS]
    smoothed = _smoothed_classes(fitted)
    for j, comp in enumerate(names):
        if not np.any(dE[:, j, :]):
            continue            # not part of the model (a rotary axis's error motions of order 0)
        angular = comp[1] in ANGLE_LETTERS
        unit, scale = ("urad", 1e6) if angular else ("um", 1e3)
        e, J = E[:, j] * scale, dE[:, j, :] * scale
        slope = float("nan")
        if not ax.is_rotary and not angular and comp[1] != ax.name:
            # straightness about its least-squares line
            X = np.column_stack([np.ones_like(s), s - s.mean()])
            line = np.linalg.lstsq(X, e, rcond=None)[0]
            e = e - X @ line
            fit_J = np.linalg.lstsq(X, J, rcond=None)[0]
            if not slope_carried(fitted.machine, comp):
                # um per mm -> urad; infinite where the slope rests on what the data leave open
                # (a plate's tilt against it): the report says so
                slope = float(line[1]) * 1e3 if np.isfinite(und.std(fit_J[1:] * 1e3)[0]) or \
                    und.directions is None else float("inf")
            J = J - X @ fit_J
        D = J - J[0]
        sd_along, held = und.assess(D)
        i_max, i_min = int(np.argmax(e)), int(np.argmin(e))
        sd = float(und.std((J[i_max] - J[i_min])[None, :])[0])
        status = _status(D, sd_along, mask)
        if status != "held" and not abs(e[i_max] - e[i_min]) > sd and \
                component_class(fitted.machine, f"{ax.name}:{comp}") in smoothed and \
                np.all(held[np.isnan(sd_along)]):
            status = "flat"
        ranges.append(ComponentRange(ax.name, comp, component_meaning(ax.name, comp), unit, lo * f_pos,
                                     hi * f_pos, float(e[i_max] - e[i_min]), sd,
                                     float(np.nanmax(sd_along)) if np.any(np.isfinite(sd_along))
                                     else float("nan"), status, slope))
    return ranges


def _smoothed_classes(fitted: FittedModel) -> set:
    """The penalty classes whose roughness weight the fit (REML, :mod:`.penalty`) took far out, to
    the flat end of its criterion (above half its bound: the curvature then weighs millions of times
    what the data do): their profiles are held flat (straight about their line), and a range within
    its own standard error is the data showing none."""
    info = fitted.info if isinstance(fitted.info, dict) else {}
    smoothing = (info.get("identify") or {}).get("smoothing") or {}
    return {k for k, w in (smoothing.get("weights") or {}).items()
            if w is not None and float(w) >= math.exp(RHO_BOUND / 2.0)}


def _location_values(fitted: FittedModel, und: Undetermined, mask) -> list:
    """:class:`LocationValue` of the squareness, spindle tilt and rotary location errors."""
    from ._offsets import unread_offsets
    machine, p = fitted.machine, fitted.params.values
    unread = unread_offsets(fitted)
    values = []
    singles = [(n, f"squareness {n}") for n in squareness_names(machine)]
    singles += [(n, f"tilt of the tool axis about {about}") for n, about in zip(SPINDLE_TILT, "XY")]
    for ax in machine.rotary_axes:
        offsets, tilts = rotary_location_names(ax.name)
        singles += [(n, f"location of {ax.name}: offset") for n in offsets]
        singles += [(n, f"location of {ax.name}: tilt") for n in tilts]
        # the constant of its angular positioning: a range (largest minus smallest) never shows it
        singles.append((f"{positioning_component(ax.name)}_0", f"zero offset of {ax.name}"))
    for name, meaning in singles:
        if name not in fitted.params:
            continue
        i = fitted.params.index(name)
        spec = fitted.params.specs[i]
        J = np.zeros((1, len(fitted.params)))
        J[0, i] = spec.to_file
        sd = und.std(J)
        status = _status(J, sd, mask)
        std = fitted.params.std_errors
        if status == "fitted" and (std is not None and np.isfinite(std).any() and np.isnan(std[i])
                                   or name in unread):
            # the fit gave it no standard error: part of a held combination, or a rotary axis's
            # zero offset read only with its positioning error at the angles read (._offsets)
            status = "undetermined"
        values.append(LocationValue(name, meaning, spec.unit, float(p[i] * spec.to_file), float(sd[0]),
                                    status))
    return values


def _pm(value, sd, status, unit, width=9) -> str:
    if status == "undetermined":
        return "not determined by the data"
    if status == "flat":
        return f"0 {unit} (the data show none above their noise: smoothed flat)"
    if status == "unmeasured":
        return "not measured: held at zero (no laser file names it)"
    if status == "held":
        return "held at zero (not fitted)"
    err = f" +- {sd:.2g}" if np.isfinite(sd) else ""
    return f"{value:{width}.3g}{err} {unit}"


def component_lines(fitted: FittedModel, undetermined: Undetermined | None = None) -> list[str]:
    """The printed table of :func:`component_ranges`."""
    ranges, values, notes = component_ranges(fitted, undetermined)
    lines = ["error components over the travel the data reached (range: largest minus smallest value,",
             "straightness about its least-squares line; +- the standard error)"]
    for axis in dict.fromkeys(r.axis for r in ranges):
        rows = [r for r in ranges if r.axis == axis]
        unit = "deg" if fitted.machine.axis(axis).is_rotary else "mm"
        lines.append(f"  {axis} from {rows[0].lo:g} to {rows[0].hi:g} {unit}:")
        for r in rows:
            # a flat straightness (no bow above the noise) can still slope: that slope is a squareness
            slope = ("" if r.status not in ("fitted", "flat") or np.isnan(r.slope) else
                     f", slope {r.slope:.1f} urad" if np.isfinite(r.slope) else
                     ", slope not determined by the data")
            lines.append(f"    {r.meaning:<22} {r.component:<5} range {_pm(r.range, r.sd, r.status, r.unit)}"
                         + slope)
    fitted_values = [v for v in values if v.status != "held"]
    if fitted_values:
        lines.append("  squareness, tool axis and axis location:")
        for v in fitted_values:
            lines.append(f"    {v.meaning:<36} {v.name:<5} {_pm(v.value, v.sd, v.status, v.unit)}")
    lines += [f"  {n}" for n in notes]
    open_ = sum(r.status == "undetermined" for r in ranges) + \
        sum(v.status == "undetermined" for v in fitted_values)
    if open_:
        # each alone: the data may still fix a combination of them (a squareness with a
        # straightness, an axis's tilt with another's), which predictions use
        lines.append(f"  {open_} of these are not determined by the data alone; combinations of "
                     "them may be, and predictions use those (--verbose lists the parameters "
                     "and the combinations the data leave open)")
    hint = hold_hint(fitted, ranges, values)
    if hint:
        lines.append(f"  {hint}")
    return lines


#: singular values (of orthonormal bases of what the data leave open, file units) below this count
#: as none: the fit's own threshold for an undetermined combination (--rcond's default)
HINT_RANK = 1e-6
#: a component's range counts as left open when the data do not determine it, or fix it only to a
#: standard error at least its own size and above this (file units)
OPEN_SD = {"um": 1.0, "urad": 10.0}


def _left_open(r) -> bool:
    """Does the data leave the :class:`ComponentRange` or :class:`LocationValue` ``r`` open
    (:data:`OPEN_SD`)?"""
    size = abs(r.range if isinstance(r, ComponentRange) else r.value)
    return r.status == "undetermined" or (r.status == "fitted" and np.isfinite(r.sd)
                                          and r.sd >= max(size, OPEN_SD.get(r.unit, 0.0)))


def _holding_determines(D: np.ndarray, is_rotary: np.ndarray, is_held: np.ndarray) -> bool:
    """Would holding the parameters ``is_held`` at zero determine some combination of the rotary
    axes' parameters ``is_rotary`` that the data leave open? ``D`` (k, m): the combinations the data
    leave open (file units). The rotary part of what stays open once the held part is zero spans
    less than the rotary part of what is open now (an R-test's zero offset of C against the
    squareness of X and Y: yes; laser runs' zero offset of C against the C laser's own zero: no,
    whatever is held of the linear axes)."""
    U, sv, _ = np.linalg.svd(D, full_matrices=False)
    B = U[:, sv > HINT_RANK * sv.max(initial=0.0)]             # orthonormal: what is open
    _, sh, Vt = np.linalg.svd(B[is_held], full_matrices=True)
    kept = B @ Vt[int(np.sum(sh > HINT_RANK)):].T             # what is open with the held part zero

    def rank(M):
        return int(np.sum(np.linalg.svd(M, compute_uv=False) > HINT_RANK)) if M.size else 0
    return rank(kept[is_rotary]) < rank(B[is_rotary])


def hold_hint(fitted: FittedModel, ranges, values) -> str | None:
    """What to do when the data move a rotary axis and cannot tell its errors from the linear axes'
    (an R-test or three-sphere test alone: the linear axes move only with the rotary ones, at few
    positions): one sentence naming the ``--hold`` of the linear axes the data moved, the squareness
    and the spindle tilt (those not held already), when the data leave a component of those linear
    axes, or a squareness or spindle tilt, open (:func:`_left_open`) and holding them would determine
    some of the rotary axes' errors the data leave open (:func:`_holding_determines`). None
    otherwise (ranges and values of :func:`component_ranges`): laser runs of every axis determine
    the linear axes' components, whatever they leave open of the rotary axes' location."""
    machine = fitted.machine
    rotary = {a.name for a in machine.rotary_axes}
    if not any(r.axis in rotary for r in ranges):
        return None
    held = {r.axis for r in ranges if r.status == "held"} | {v.name for v in values if v.status == "held"}
    hold = [a.name for a in machine.linear_axes if any(r.axis == a.name for r in ranges) and a.name not in held]
    single = (("squareness", squareness_names(machine)), ("spindle", SPINDLE_TILT))
    hold += [g for g, names in single if any(v.name in names for v in values) and not held.intersection(names)]
    # the squareness and the spindle tilt count as the linear axes' components do: the angular
    # error motions held at zero where the data leave them open, what an R-test leaves open of the
    # linear axes is an angle between them (a straightness's slope, which is a squareness)
    names = {n for g, ns in single if g in hold for n in ns}
    if not any(_left_open(r) for r in [*(r for r in ranges if r.axis in hold),
                                       *(v for v in values if v.name in names)]):
        return None
    und = Undetermined.of(fitted)
    if und.directions is None or not und.directions.size:
        return None
    groups = [fitted.params.specs[i].group.split(":")[0] for i in und.index]
    if not _holding_determines(und.directions * und.to_file[:, None],
                               np.array([g in rotary for g in groups]), np.array([g in hold for g in groups])):
        return None
    return ("hint: the data cannot tell the rotary axes' errors from the linear axes' (a campaign "
            "that moves the linear axes only with the rotary ones): if the controller compensates "
            f"those, hold them and the data go to the rotary axes: --hold {','.join(hold)} "
            "(docs/identification.md, --hold)")


# ------------------------------------------------------------------------------ per file
def _measured(data, column: str) -> np.ndarray:
    """(n,) the file's own cells of ``column`` as numbers (NaN where blank), file units."""
    header = [h.strip().lower() for h in data.header]
    if column.lower() not in header:
        return np.full(len(data), np.nan)
    j = header.index(column.lower())
    out = np.full(len(data), np.nan)
    for i, cells in enumerate(data.rows):
        try:
            out[i] = float(cells[j])
        except (ValueError, IndexError):
            pass
    return out


def file_residuals(fitted: FittedModel, data, machine=None, prediction=None) -> dict:
    """column -> (n,) measured minus predicted (file units, NaN where blank or not predicted) of one
    file whose set-up the model carries (a file of the fit)."""
    pred = prediction if prediction is not None else predict_readings(fitted, data, machine)
    out = {}
    for name, values in pred.columns.items():
        if name.endswith("_sd") or not name.startswith("pred_"):
            continue
        column = name[len("pred_"):]
        out[column] = _measured(data, column) - np.asarray(values, dtype=float)
    return out


def file_rms_lines(fitted: FittedModel, datasets, machine=None, excluded=(), predictions=None) -> list[str]:
    """The rms residual of every file (measured minus the model's prediction, with the file's fitted
    set-up), per measured column; ``excluded``: (path, row, column) cells left out of the fit."""
    from .problem import unique_tags
    skip = {(str(p), int(r), str(c)) for p, r, c in excluded}
    lines = [f"{'file':<24} {'kind':<8} {'n_obs':>7}  rms residual"]
    for k, (tag, data) in enumerate(zip(unique_tags(datasets), datasets)):
        pred = predictions[k] if predictions is not None else None
        res = file_residuals(fitted, data, machine, pred)
        parts, n = [], 0
        for column, r in res.items():
            keep = np.isfinite(r) & np.array([(str(data.path), int(row), column) not in skip
                                              for row in data.row])
            if not keep.any():
                continue
            n += int(keep.sum())
            v = float(np.sqrt(np.mean(r[keep] ** 2)))
            um = f" ({v * 1e3:.4g} um)" if column.endswith("_mm") else ""
            parts.append(f"{column} {v:.4g}{um}")
        lines.append(f"{tag:<24} {data.kind:<8} {n:>7}  {', '.join(parts) or 'nothing predicted'}")
    return lines


def laser_target_tables(fitted: FittedModel, datasets, machine=None, verbose: bool = False,
                        predictions=None) -> list[str]:
    """Per laser file and component: target, the mean reading of the runs approaching it in + and in
    -, the model's prediction of each (with the file's fitted set-up: its zero, its slope) and the
    residual (mean reading minus prediction). Without ``verbose``: only components with at most
    :data:`COMPACT_TARGETS` targets, and of a file with more than :data:`COMPACT_COMPONENTS`
    components only the positioning ones (ISO 230-2), the others counted in one line."""
    from .problem import unique_tags
    lines = []
    for k, (tag, data) in enumerate(zip(unique_tags(datasets), datasets)):
        if data.kind != "laser":
            continue
        pred = predictions[k] if predictions is not None else predict_readings(fitted, data, machine)
        components = list(dict.fromkeys(data.component.tolist()))
        shown, more = components, []
        if not verbose and len(components) > COMPACT_COMPONENTS:
            shown = [c for c in components if c == positioning_component(c[2])]
            more = [f"laser {tag}: {len(components) - len(shown)} more component(s) "
                    f"({', '.join(c for c in components if c not in shown)}): --verbose prints their "
                    "per-target tables"]
        for comp in shown:
            sel = data.component == comp
            angular = bool(data.angular[sel][0])
            column = "value_urad" if angular else "value_um"
            unit = "urad" if angular else "um"
            measured = _measured(data, column)
            predicted = np.asarray(pred.columns.get(f"pred_{column}", np.full(len(data), np.nan)))
            ax = str(data.axis[sel][0])
            rotary = ax in ANGLE_LETTERS
            f_pos, pos_unit = (180.0 / math.pi, "deg") if rotary else (1.0, "mm")
            targets = np.unique(np.round(data.target[sel] * f_pos, 9))
            if targets.size > COMPACT_TARGETS and not verbose:
                lines.append(f"laser {tag}, {ax} {comp}: {targets.size} targets (--verbose prints the "
                             "per-target table)")
                continue
            lines.append(f"laser {tag}, {ax} {component_meaning(ax, comp)} ({comp}), {unit}: "
                         "mean of the runs per target and approach direction")
            lines.append(f"  {'target_' + pos_unit:>11} {'measured +':>11} {'measured -':>11} "
                         f"{'model +':>9} {'model -':>9} {'resid +':>9} {'resid -':>9}")
            for t in targets:
                at = sel & np.isclose(data.target * f_pos, t, rtol=0, atol=1e-9) & np.isfinite(measured)
                cells = []
                for what in ("m", "p"):
                    for d in (1, -1):
                        rows = at & (data.dir == d)
                        src = measured if what == "m" else predicted
                        cells.append(float(np.mean(src[rows])) if rows.any() else float("nan"))
                m_up, m_dn, p_up, p_dn = cells
                row = [m_up, m_dn, p_up, p_dn, m_up - p_up, m_dn - p_dn]
                widths = (11, 11, 9, 9, 9, 9)
                # + 0.0: no "-0.000" for a residual that rounds to zero
                text = " ".join(f"{round(v, 3) + 0.0:{w}.3f}" if np.isfinite(v) else " " * w
                                for v, w in zip(row, widths))
                lines.append(f"  {t:11.4f} {text}")
        lines += more
    return lines


# ------------------------------------------------------------------------------ raw parameters
def parameter_lines(fitted: FittedModel) -> list[str]:
    """Every fitted parameter of the model with its value and standard error (file units), and the
    names of those the data do not determine (held at zero error): the ``--verbose`` rows."""
    mask = _fitted_mask(fitted)
    std = fitted.params.std_errors
    lines = [f"{'parameter':<28} {'value':>12} {'std error':>11}  unit"]
    undetermined = []
    for i, s in enumerate(fitted.params.specs):
        if mask is not None and not mask[i]:
            continue
        v = fitted.params.values[i] * s.to_file
        if std is not None and np.isfinite(std[i]):
            e = f"{std[i] * s.to_file:11.4g}"
        else:
            e = f"{'undeterm.':>11}"
            undetermined.append(s.name)
        lines.append(f"{s.name:<28} {v:12.5g} {e}  {s.unit}")
    if undetermined:
        lines.append(f"{len(undetermined)} parameter(s) the data do not determine alone (their "
                     f"combinations are held where they predict the least error): {', '.join(undetermined)}")
    return lines

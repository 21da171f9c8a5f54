"""Measurement models: what an error model predicts for each reading of a measurement file.

A measurement model binds one :class:`~mtcomp.models.ErrorModel` to one measurement set
(:mod:`mtcomp.measurement.files`) and turns a parameter vector ``p`` (internal units, the model's
``param_names`` order) and the file's nuisance parameters into predicted readings, with exact
Jacobians from CasADi (never finite differences). Every model is vectorised: one call evaluates every
row of the file.

Observations are the measured scalars of a file: rows x measured columns, blank (NaN) cells dropped.
Each carries the data row it came from (``obs_row``, 0-based), its column (``obs_column``) and the
factor from internal units to its file unit (``obs_unit_scale``: 1e3 for um, 1e6 for urad, 1 for mm).

Kinds implemented here (formats: docs/measurements.md; equations: docs/identification.md):

* ``points``: tool-tip deviation d = tip(q, p, c) - tip0(q) in the workpiece frame;
  ``dx, dy, dz`` are its components, ``dn = n . d``. Per-row tool length (``tool_mm``).
* ``laser``: the measured point is the tool tip plus the optic offset o carried by the tool
  frame, so its deviation is ``d + (R_rel - I) o`` with ``R_rel = R R0^T`` the rotation of the tool
  relative to the workpiece (actual times nominal transposed). A translational component E<d><L> reads
  that deviation along direction d; an angular one the small-angle rotation of ``R_rel`` about d
  (``vee((R_rel - R_rel^T) / 2)``, exact to O(angle^3)). For a rotary axis that carries the workpiece
  the reading is the motion of the table relative to the tool, i.e. minus the above (so ECC is actual
  minus commanded angle, as ISO 230-2 reports it). Nuisance per (file, axis, component): a zero offset
  (interferometers are zeroed at the start of a set-up) and, for straightness components of linear
  axes, a slope (alignment of the straightness optic with the axis; one um/m = one urad).
* ``ballbar``: length ``| tip0 + d + R_rel b - T |`` with T the table-ball centre
  (workpiece frame) and b the tool-ball centre relative to the nominal tool tip; nuisance: one length
  offset per file (calibration of the bar).

Other kinds (cmm, thermal, velocity) register here from :mod:`.readings_extra`, imported with this
module by the package (every kind registered whichever module is imported first).
"""
from __future__ import annotations

from pathlib import Path
from typing import ClassVar

import casadi as ca
import numpy as np

from ..errors import InputError
from ._topology import refuse_other_topology
from .drift import feature_value
from .files import MeasurementSet
from ..models.chain import (ErrorModel, context_defaults as base_context_defaults,
                            guideway_positions)
from ..models.function_cache import model_function
from ..models.params import ParamSpec

#: kind -> measurement model class (filled by :func:`register`)
MEASUREMENT_MODELS: dict[str, type] = {}


def register(cls):
    """Class decorator: make ``cls`` the measurement model of files of kind ``cls.kind``."""
    if not getattr(cls, "kind", ""):
        raise TypeError(f"{cls.__name__} needs a class attribute 'kind'")
    MEASUREMENT_MODELS[cls.kind] = cls
    return cls


def model_class_for(kind: str, path=None) -> type:
    """The registered measurement model class of a kind; InputError when none is registered."""
    if kind not in MEASUREMENT_MODELS:
        raise InputError(f"no measurement model for {kind} files yet (available: "
                         f"{', '.join(sorted(MEASUREMENT_MODELS))})", path)
    return MEASUREMENT_MODELS[kind]


def measurement_model(model: ErrorModel, data: MeasurementSet, context_defaults: dict | None = None,
                      **options) -> "MeasurementModel":
    """Build the registered measurement model for ``data`` (its kind decides the class)."""
    return model_class_for(data.kind, data.path)(model, data, context_defaults, **options)


def data_positions(machine, datasets) -> dict[str, np.ndarray]:
    """Axis name -> every position that axis took on its guideway in the files' rows (mm, rad), where
    its error profiles were read: the commanded position, but for the ram that of a row's tool
    (``tool_mm``) longer than the machine's by d is q_Z + d (docs/conventions.md, "Tool length");
    files without axis positions (thermal) add nothing."""
    return _positions_by_axis(machine, datasets, guideway=True)


def _positions_by_axis(machine, datasets, guideway: bool) -> dict[str, np.ndarray]:
    out: dict[str, list] = {a: [] for a in machine.axis_names}
    for _, q in positions_by_file(machine, datasets, guideway):
        for j, a in enumerate(machine.axis_names):
            out[a].append(q[:, j])
    return {a: np.concatenate(v) for a, v in out.items() if v}


def positions_by_file(machine, datasets, guideway: bool = False):
    """(file's data, (n, n_axes) axis positions) of each file with axis positions and rows: the
    commanded ones, or with ``guideway`` the ram's at its machine position (:func:`data_positions`)."""
    for d in datasets:
        data = d.data if isinstance(d, MeasurementModel) else d
        if hasattr(data, "axis_positions") and len(data):
            q = np.asarray(data.axis_positions(machine), dtype=float)
            tool = getattr(data, "tool", None)
            if guideway and isinstance(tool, np.ndarray) and tool.shape == (len(q),):
                q = guideway_positions(machine, q, tool)
            yield data, q


def single_axis_lines(machine, datasets) -> dict[str, list]:
    """Linear axis name -> the measured lines of the laser files that move it: one (target mm,
    value, run) triple per (file, component, optic offset, static position, feed, approach direction
    of the axis), for :func:`mtcomp.models.basis.spline_size_by_cv`. Axes X, Y and Z only."""
    out: dict[str, list] = {}
    for d in datasets:
        data = d.data if isinstance(d, MeasurementModel) else d
        if getattr(data, "kind", "") != "laser" or len(data) == 0:
            continue
        feed = np.nan_to_num(np.asarray(data.context.feed, dtype=float), nan=-1.0)
        for a in machine.axis_names:
            if a not in "XYZ":
                continue
            static = np.round(np.nan_to_num(data.xyz), 3)
            static[:, "XYZ".index(a)] = 0.0                # the moving axis's own column
            # the approach direction too: a reversal error is not noise of a repeated reading
            key = np.column_stack([static, np.round(np.nan_to_num(data.abc), 9), np.round(data.optic, 3),
                                   np.round(feed, 3), data.context.dir_of(a)])
            for comp in np.unique(data.component[data.axis == a]):
                sel = (data.axis == a) & (data.component == comp) & np.isfinite(data.value)
                if not sel.any():
                    continue
                _, line = np.unique(key[sel], axis=0, return_inverse=True)
                ix = np.flatnonzero(sel)
                for g in np.unique(line):
                    j = ix[line.ravel() == g]
                    out.setdefault(a, []).append((data.target[j], data.value[j], data.run[j]))
    return out


def data_spline_sizes(machine, datasets) -> dict[str, int]:
    """Linear axis name -> the most spline functions the data's single-axis runs ask for
    (:func:`mtcomp.models.basis.spline_size_by_cv` over the axis's position range), for the axes
    whose knots the data choose; axes without such runs are absent (the default cap holds)."""
    from ..models.basis import spline_size_by_cv
    lines = single_axis_lines(machine, datasets)
    if not lines:
        return {}
    ranges = _position_ranges(machine, datasets, guideway=True)
    out = {}
    for a, ls in lines.items():
        ax = machine.axis(a)
        if not ax.basis_from_data or a not in ranges or not ranges[a][1] > ranges[a][0]:
            continue
        # over the range the knots will span: the machine file's when it fixes one
        n, _ = spline_size_by_cv(ls, *(ax.spline_range or ranges[a]))
        out[a] = n
    return out


def _position_ranges(machine, datasets, guideway: bool = False) -> dict[str, tuple[float, float]]:
    """Axis name -> (lowest, highest) finite position in the files' rows (internal units): commanded,
    or with ``guideway`` where each axis stood on its guideway (:func:`data_positions`)."""
    out = {}
    for a, v in _positions_by_axis(machine, datasets, guideway).items():
        v = v[np.isfinite(v)]
        if v.size:
            out[a] = (float(v.min()), float(v.max()))
    return out


def data_support(machine, datasets) -> dict[str, tuple[float, float]]:
    """The identified region: axis name -> (lowest, highest) position in the data, internal units,
    for every axis the data moved, each where it stood on its guideway (the ram where the rows' tools
    put it: :func:`data_positions`). An axis the data hold at one position (the static axes of a laser
    run) is absent, like one no file positions (see :func:`data_held`): it does not bound where the
    model applies (a laser run of X corrects X along the whole table, as the pitch table from the
    same run would; correcting it only on the laser's line would make the parts of a workpiece
    disagree)."""
    return {a: r for a, r in _position_ranges(machine, datasets, guideway=True).items() if r[1] - r[0] > 1e-9}


def data_held(machine, datasets) -> dict[str, float]:
    """Axis name -> position, for every axis that the files position but hold at one and the same
    position on its guideway (internal units; the ram where the rows' tools put it): how its errors
    vary along it, the data cannot say."""
    return {a: r[0] for a, r in _position_ranges(machine, datasets, guideway=True).items()
            if r[1] - r[0] <= 1e-9}


# ------------------------------------------------------------------------------------------ context
def context_matrix(model: ErrorModel, data: MeasurementSet, context_defaults: dict | None = None,
                   machine=None, extra: dict | None = None) -> np.ndarray:
    """(n_rows, model.n_context) block context of every row of ``data``.

    Channel by channel (``model.context_names``): ``feed`` (mm/min) from ``feed_mm_min``, ``t`` (s)
    from ``t_s``, ``spindle_rpm``, ``dir_<axis>`` from ``dir_<axis>`` (0 = unknown), ``tool_length``
    (mm) from the row's ``tool_mm`` (points files) else the machine's, ``temp_<name>`` (degC) from
    ``temp_<name>_c``. Blank cells and absent columns take ``context_defaults[name]`` when given, else
    the model's default (feed 0, t 0, dir 0, the machine's tool length). Drift features of a
    ThermalDrift term (``time_h``, ``dtemp_<s>``, ``spindle_heat_<tau>``) are computed from the file's
    ``t_s``, temperature and spindle columns (:func:`mtcomp.measurement.drift.feature_value`).
    ``extra``: name -> (n_rows,) arrays for channels computed elsewhere; they win over everything.
    """
    machine = machine if machine is not None else model.machine
    n = len(data)
    defaults = base_context_defaults(machine)
    defaults.update(context_defaults or {})
    ctx = data.context
    columns: dict[str, np.ndarray] = {"feed": ctx.feed, "t": ctx.t, "spindle_rpm": ctx.spindle_rpm}
    for a in machine.axis_names:
        d = ctx.dir_of(a).astype(float)
        columns[f"dir_{a}"] = np.where(d == 0, np.nan, d)
    tool = getattr(data, "tool", None)
    if isinstance(tool, np.ndarray) and tool.shape == (n,):
        columns["tool_length"] = tool
    for name, values in ctx.temperatures.items():
        columns[f"temp_{name}"] = values
    out = np.zeros((n, model.n_context))
    for i, name in enumerate(model.context_names):
        default = float(defaults.get(name, 0.0))
        col = columns.get(name)
        if extra is not None and name in extra:
            col = np.asarray(extra[name], dtype=float)
        if col is None:
            # drift features of a ThermalDrift term (time_h, dtemp_<s>, spindle_heat_<tau>) come
            # from the file's own time, temperature and spindle columns
            col = feature_value(name, ctx)
        if col is None:
            out[:, i] = default
        else:
            col = np.asarray(col, dtype=float)
            out[:, i] = np.where(np.isfinite(col), col, default)
    return out


# ------------------------------------------------------------------------- batched CasADi evaluation
#: what each chain function appends to the context: its length
_EXTRA_CONTEXT = {"tip": 0, "tip_jac": 0, "tip_vjp": 3, "laser": 9, "laser_jac": 9, "ballbar": 6,
                  "ballbar_jac": 6}


def chain_function(model: ErrorModel, name: str) -> ca.Function:
    """CasADi functions of (q, p, c) (``c`` may be extended per row), built once per model structure
    (:func:`mtcomp.models.function_cache.model_function`):

    * ``'tip'``: d (3,) tip deviation mm; ``'tip_jac'``: (d, J_d^T (n_params, 3)); ``'tip_vjp'``:
      c = [context, v (3)]: (d, J_d^T v (n_params, 1)), one reverse sweep instead of the Jacobian.
    * ``'laser'`` / ``'laser_jac'``: c = [context, o (3), s (6)]:
      v = s . [d + (R_rel - I) o ; vee((R_rel - R_rel^T) / 2)] (scalar) and its gradient
      (n_params, 1), with ``R_rel = R R0^T`` the tool's rotation relative to nominal.
    * ``'ballbar'`` / ``'ballbar_jac'``: c = [context, T (3), b (3)]:
      L = | tip0 + d + R_rel b - T | (scalar) and its gradient (n_params, 1).
    """
    if name not in _EXTRA_CONTEXT:
        raise KeyError(name)
    return model_function(model, f"mm_{name}", lambda: _build_chain_function(model, name))


def _build_chain_function(model: ErrorModel, name: str) -> ca.Function:
    nc = model.n_context
    q, p = ca.SX.sym("q", model.machine.n_axes), ca.SX.sym("p", model.n_params)
    cx = ca.SX.sym("c", nc + _EXTRA_CONTEXT[name])
    c = cx[:nc]
    tip, _, R = model.symbolic(q, p, c, errors=True)
    tip0, _, R0 = model.symbolic(q, p, c, errors=False)
    d = tip - tip0
    R_rel = ca.mtimes(R, R0.T)
    if name.startswith("tip"):
        outs = [d]
    elif name.startswith("laser"):
        o, sel = cx[nc:nc + 3], cx[nc + 3:nc + 9]
        point = d + ca.mtimes(R_rel, o) - o
        vee = 0.5 * ca.vertcat(R_rel[2, 1] - R_rel[1, 2], R_rel[0, 2] - R_rel[2, 0],
                               R_rel[1, 0] - R_rel[0, 1])
        outs = [ca.dot(sel, ca.vertcat(point, vee))]
    else:
        T, b = cx[nc:nc + 3], cx[nc + 3:nc + 6]
        outs = [ca.norm_2(tip0 + d + ca.mtimes(R_rel, b) - T)]
    if name.endswith("_jac"):
        # transposed (n_params, rows): column-major per pose = row-major (rows, n_params), so
        # the stacked Jacobian of N poses is a reshape, not a copy
        outs.append(ca.jacobian(outs[0], p).T)
    elif name.endswith("_vjp"):
        outs.append(ca.jtimes(outs[0], p, cx[nc:nc + 3], True))
    return ca.Function(f"mm_{name}", [q, p, cx], outs)


def evaluate_chain(model: ErrorModel, name: str, q: np.ndarray, p: np.ndarray, c: np.ndarray):
    """Evaluate :func:`chain_function` ``name`` on N poses at once.

    q (N, n_axes) mm and rad, p (n_params,), c (N, n_context). Returns a list with one array per
    output, shaped (N, rows, cols) (or (N, rows) for column outputs).
    """
    from ..models import compiled
    from ..models.evaluate import casadi_map_call
    f = chain_function(model, name)
    q = np.ascontiguousarray(q, dtype=float)
    c = np.ascontiguousarray(c, dtype=float)
    p = np.asarray(p, dtype=float)
    n = q.shape[0]
    if n == 0:
        return [np.zeros((0, *f.size_out(k))) if f.size_out(k)[1] > 1 else np.zeros((0, f.size_out(k)[0]))
                for k in range(f.n_out())]
    outs = compiled.call(model, f.name(), f, q, p, c, required=False)
    if outs is None:
        outs = casadi_map_call(f, q, p, c)
    result = []
    for k, flat in enumerate(outs):
        rows, cols = f.size_out(k)
        result.append(flat if cols == 1 else flat.reshape(n, cols, rows).transpose(0, 2, 1))
    return result


def compiled_ready(model: ErrorModel, name: str) -> bool:
    """True when :func:`chain_function` ``name`` of the model is compiled and loaded (or found in the
    cache): then evaluating its poses block by block costs no more than all at once. Until then a
    file is evaluated whole, so that its first evaluation decides compilation on all of its poses."""
    from ..models import compiled
    f = chain_function(model, name)
    try:
        return compiled.get_compiled(model, f.name(), f, compile_if_missing=False) is not None
    except compiled.CompileError:
        return False


# ------------------------------------------------------------------------------------- base class
def file_tag(data: MeasurementSet) -> str:
    """Short name of a file for nuisance parameter names: its stem."""
    return Path(str(data.path)).stem or data.kind


class MeasurementModel:
    """Prediction of the readings of one measurement file from an error model.

    Parameters
    ----------
    model : the error model (its ``param_names`` order the vector p).
    data : the measurement set (one file).
    context_defaults : values of context channels the file lacks (see :func:`context_matrix`).
    options : ``tag`` (prefix of nuisance names; default: the file's stem), ``machine`` (a machine that
        overrides the model's for tool length), ``extra_context`` (name -> (n_rows,) channels).

    Attributes (set by subclasses in ``_setup``)
    ----------
    n_obs : number of scalar observations.
    observed : (n_obs,) measured values, internal units (mm, rad).
    obs_row : (n_obs,) 0-based data row of each observation.
    obs_column : (n_obs,) name of the measured column ('dx_um', 'value_um', 'length_mm' ...).
    obs_unit_scale : (n_obs,) factor internal -> file unit of each observation.
    nuisance_specs : per-file nuisance parameters (names prefixed with ``<tag>:``).
    """

    kind: ClassVar[str] = ""

    def __init__(self, model: ErrorModel, data: MeasurementSet, context_defaults: dict | None = None,
                 **options):
        if data.kind != self.kind:
            raise ValueError(f"{type(self).__name__} models {self.kind} files, not {data.kind}")
        self.model = model
        self.data = data
        self.context_defaults = dict(context_defaults or {})
        self.options = dict(options)
        self.tag = str(options.get("tag") or file_tag(data))
        self.machine = options.get("machine") or model.machine
        self.nuisance_specs: list[ParamSpec] = []
        self.observed = np.zeros(0)
        self.obs_row = np.zeros(0, dtype=np.int64)
        self.obs_column = np.zeros(0, dtype=object)
        self.obs_unit_scale = np.zeros(0)
        self._setup()

    # -------------------------------------------------------------- to be provided by subclasses
    def _setup(self) -> None:
        raise NotImplementedError

    def predict(self, p: np.ndarray, nuisance: np.ndarray | None = None) -> np.ndarray:
        """(n_obs,) predicted observations, internal units (nuisance None: zeros)."""
        return self._evaluate(p, nuisance, jacobian=False)[0]

    def jacobian(self, p: np.ndarray, nuisance: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """((n_obs, n_params), (n_obs, n_nuisance)): d predict / d p and d predict / d nuisance."""
        _, J, Jn = self._evaluate(p, nuisance, jacobian=True)
        return J, Jn

    def predict_and_jacobian(self, p, nuisance):
        """(prediction (n_obs,), J_p (n_obs, n_params), J_nuisance (n_obs, n_nuisance)) in one pass."""
        return self._evaluate(p, nuisance, jacobian=True)

    def jacobian_blocks(self, p: np.ndarray, nuisance: np.ndarray, max_obs: int):
        """Yield (observations (a slice), prediction, J_p, J_nuisance) of blocks of the observations,
        each of about ``max_obs`` or fewer, together every observation once and
        :meth:`predict_and_jacobian`: the normal equations of a large file without its whole
        Jacobian in memory. One block unless a kind evaluates its rows in blocks; a block's arrays
        are the caller's to overwrite."""
        pred, J, Jn = self.predict_and_jacobian(p, nuisance)
        yield slice(0, self.n_obs), pred, J, Jn

    def _evaluate(self, p, nuisance, jacobian: bool):
        raise NotImplementedError

    #: :meth:`gradient` is cheaper than the Jacobian (a reverse sweep per row)
    fast_gradient: ClassVar[bool] = False

    def gradient(self, p: np.ndarray, nuisance: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(J_p^T v (n_params,), J_nuisance^T v (n_nuisance,)) for a seed v (n_obs,)."""
        J, Jn = self.jacobian(p, nuisance)
        return J.T @ v, Jn.T @ v

    def predict_columns(self, p: np.ndarray, nuisance: np.ndarray | None = None) -> dict[str, np.ndarray]:
        """'pred_<column>' -> (n_rows,) predicted readings in FILE units, for every row."""
        raise NotImplementedError

    def column_jacobians(self, p: np.ndarray) -> dict[str, np.ndarray]:
        """'pred_<column>' -> (n_rows, n_params): derivative of each row's predicted reading (FILE
        units) with respect to the model parameters (internal units); {} where not provided."""
        return {}

    # -------------------------------------------------------------- shared helpers
    @property
    def n_obs(self) -> int:
        return int(self.observed.shape[0])

    @property
    def n_nuisance(self) -> int:
        return len(self.nuisance_specs)

    @property
    def nuisance_names(self) -> tuple[str, ...]:
        return tuple(s.name for s in self.nuisance_specs)

    def zero_nuisance(self) -> np.ndarray:
        return np.zeros(self.n_nuisance)

    def residuals(self, p, nuisance) -> np.ndarray:
        """(n_obs,) observed minus predicted, internal units."""
        return self.observed - self.predict(p, nuisance)

    def check_readings(self) -> None:
        """InputError for readings a fit cannot take as they are (e.g. a ball bar's length that is
        no length); nothing for most kinds. Called before a fit, not for predictions."""

    def context(self) -> np.ndarray:
        """(n_rows, n_context) context of the file's rows."""
        return context_matrix(self.model, self.data, self.context_defaults, self.machine,
                              self.options.get("extra_context"))

    def _check_p(self, p, nuisance):
        p = np.asarray(p, dtype=float).reshape(-1)
        if p.shape != (self.model.n_params,):
            raise ValueError(f"p must have shape ({self.model.n_params},), got {p.shape}")
        nuisance = self.zero_nuisance() if nuisance is None else np.asarray(nuisance, dtype=float).reshape(-1)
        if nuisance.shape != (self.n_nuisance,):
            raise ValueError(f"nuisance must have shape ({self.n_nuisance},), got {nuisance.shape}")
        return p, nuisance

    def _set_observations(self, values: np.ndarray, columns: list[str], scales: list[float]):
        """From (n_rows, k) measured values (NaN = not measured): the flattened observation arrays,
        row-major (row 0 col 0, row 0 col 1, ...)."""
        values = np.asarray(values, dtype=float).reshape(len(self.data), len(columns))
        mask = np.isfinite(values)
        rows, cols = np.nonzero(mask)
        self._obs_mask = mask
        self.observed = values[mask]
        self.obs_row = rows.astype(np.int64)
        self.obs_column = np.asarray(columns, dtype=object)[cols]
        self.obs_unit_scale = np.asarray(scales, dtype=float)[cols]

    def __repr__(self):
        return f"<{type(self).__name__} {self.tag}: {len(self.data)} rows, {self.n_obs} observations>"


# ------------------------------------------------------------------------------------- points
def frame_setup_specs(tag: str, frame: str) -> list[ParamSpec]:
    """The set-up of an instrument aligned to the part (points, cmm): a translation ``<tag>:setup:tx``
    ``ty`` ``tz`` (um) and a small rotation ``rx`` ``ry`` ``rz`` (urad) of ``frame``."""
    return [ParamSpec(f"{tag}:setup:{name}", unit, f"nuisance:{tag}", False,
                      f"set-up of {tag}: {'translation' if name[0] == 't' else 'rotation'} {name[1]} of {frame}")
            for name, unit in (("tx", "um"), ("ty", "um"), ("tz", "um"),
                               ("rx", "urad"), ("ry", "urad"), ("rz", "urad"))]


@register
class PointsModel(MeasurementModel):
    """Points files: tip deviation d (workpiece frame), dn = n . d, as the file's instrument reads it.

    A tracker, probe or CMM is aligned to the part, not to the machine, so each file has its own
    set-up: a translation t and a small rotation w (about the centroid c of the file's nominal tips)
    of the frame its deviations are reported in. The reading is ``d + t + w x (tip0 - c)`` (and ``n .``
    of that for dn). Nuisance ``<tag>:setup:tx`` ``ty`` ``tz`` (um) and ``<tag>:setup:rx`` ``ry`` ``rz``
    (urad). Option ``setup="known"``: the instrument's frame is the workpiece frame (no nuisance).
    """

    kind = "points"
    COLUMNS = ("dx_um", "dy_um", "dz_um", "dn_um")

    def _setup(self):
        data = self.data
        self.q = data.axis_positions(self.machine)
        self.c = self.context()
        normal = np.where(np.isfinite(data.normal), data.normal, 0.0)
        self.normal = normal
        values = np.column_stack([data.deviation, data.normal_deviation])
        self._set_observations(values, list(self.COLUMNS), [1e3] * 4)
        # observation k = sum_j A[k, j] d[row_k, j]: unit vectors for dx..dz, the normal for dn
        basis = np.zeros((len(data), 4, 3))
        basis[:, 0, 0] = basis[:, 1, 1] = basis[:, 2, 2] = 1.0
        basis[:, 3, :] = normal
        self._rows, self._cols = np.nonzero(self._obs_mask)
        self._A = basis[self._rows, self._cols]          # (n_obs, 3)
        self._all_xyz = bool(self._obs_mask[:, :3].all() and not self._obs_mask[:, 3].any())
        self._setup_design = np.zeros((self.n_obs, 0))
        if self.options.get("setup", "free") != "known" and self.n_obs:
            from ..kinematics import forward
            tip0 = forward(self.machine, self.q)[0]
            self._setup_arm = tip0 - tip0[self._rows].mean(axis=0)    # (n_rows, 3): w x arm
            # d/dt = A; d/dw of A . (w x r) = r x A
            self._setup_design = np.hstack([self._A, np.cross(self._setup_arm[self._rows], self._A)])
            self.nuisance_specs += frame_setup_specs(self.tag, "the instrument's frame")

    def tip_deviation(self, p, jacobian: bool = False):
        """(n_rows, 3) tip deviation, mm (and (n_rows, 3, n_params) Jacobian when asked)."""
        p = np.asarray(p, dtype=float)
        if not jacobian:
            return evaluate_chain(self.model, "tip", self.q, p, self.c)[0]
        out = evaluate_chain(self.model, "tip_jac", self.q, p, self.c)
        return out[0], out[1].transpose(0, 2, 1)    # (n, 3, n_params), C-contiguous view

    def _evaluate(self, p, nuisance, jacobian):
        p, nuisance = self._check_p(p, nuisance)
        setup = self._setup_design @ nuisance if self.n_nuisance else 0.0
        if not jacobian:
            d = self.tip_deviation(p)
            return np.einsum("kj,kj->k", self._A, d[self._rows]) + setup, None, None
        d, Jd = self.tip_deviation(p, jacobian=True)
        pred = np.einsum("kj,kj->k", self._A, d[self._rows]) + setup
        n, n_p = len(self.data), self.model.n_params
        if self._all_xyz:
            J = Jd.reshape(n * 3, n_p)          # observations are rows x (dx, dy, dz), row-major
        else:
            J = np.empty((self.n_obs, n_p))
            for j in range(3):
                sel = self._cols == j
                J[sel] = Jd[self._rows[sel], j]
            sel = self._cols == 3
            if sel.any():
                J[sel] = np.einsum("kj,kjp->kp", self._A[sel], Jd[self._rows[sel]])
        return pred, J, self._setup_design

    def jacobian_blocks(self, p, nuisance, max_obs):
        # each block of rows yields its dx, dy and dz readings apart: each sees about a third of
        # the parameters (a straightness of X moves no dx), and the zero columns are skipped
        rows = max(1, max_obs // 3)
        n, n_p = len(self.data), self.model.n_params
        if not self._all_xyz or n <= rows or not compiled_ready(self.model, "tip_jac"):
            yield from super().jacobian_blocks(p, nuisance, max_obs)
            return
        p, nuisance = self._check_p(p, nuisance)
        setup = self._setup_design @ nuisance if self.n_nuisance else np.zeros(self.n_obs)
        for s in range(0, n, rows):
            e = min(n, s + rows)
            d, Jd = evaluate_chain(self.model, "tip_jac", self.q[s:e], p, self.c[s:e])
            Jd = Jd.transpose(0, 2, 1)                      # (rows, 3, n_params)
            for j in range(3):
                obs = slice(3 * s + j, 3 * e, 3)            # rows x (dx, dy, dz), row-major
                yield obs, d[:, j] + setup[obs], Jd[:, j], self._setup_design[obs]

    fast_gradient = True
    #: rows per evaluation of the gradient: each row's (n_params,) part is summed while in cache
    GRADIENT_ROWS = 4096

    def gradient(self, p, nuisance, v):
        p, nuisance = self._check_p(p, nuisance)
        v = np.asarray(v, dtype=float)
        n = len(self.data)
        # observation k = A_k . d[row_k]: the seed of each row's d is the sum of v_k A_k over its rows
        seeds = np.column_stack([np.bincount(self._rows, weights=v * self._A[:, j], minlength=n)
                                 for j in range(3)])
        c = np.hstack([self.c, seeds])
        blocks = n > self.GRADIENT_ROWS and compiled_ready(self.model, "tip_vjp")
        step = self.GRADIENT_ROWS if blocks else max(n, 1)
        g = sum(evaluate_chain(self.model, "tip_vjp", self.q[s:s + step], p, c[s:s + step])[1].sum(axis=0)
                for s in range(0, n, step))
        return g, self._setup_design.T @ v

    def column_jacobians(self, p):
        _, Jd = self.tip_deviation(np.asarray(p, dtype=float), jacobian=True)
        out = {f"pred_d{x}_um": Jd[:, j] * 1e3 for j, x in enumerate("xyz")}
        if "dn_um" in self.data.measured:
            out["pred_dn_um"] = np.einsum("ij,ijp->ip", self.normal, Jd) * 1e3
        return out

    def predict_columns(self, p, nuisance=None):
        p, nuisance = self._check_p(p, nuisance)
        d = self.tip_deviation(p)
        if self.n_nuisance:
            # the set-up acts on every row alike: t + w x (tip0 - c), c the centroid of the observations
            d = d + nuisance[:3] + np.cross(nuisance[3:], self._setup_arm)
        out = {"pred_dx_um": d[:, 0] * 1e3, "pred_dy_um": d[:, 1] * 1e3, "pred_dz_um": d[:, 2] * 1e3}
        if "dn_um" in self.data.measured:
            given = np.all(np.isfinite(self.data.normal), axis=1)
            out["pred_dn_um"] = np.where(given, np.einsum("ij,ij->i", self.normal, d) * 1e3, np.nan)
        return out


# ------------------------------------------------------------------------------------- laser
_LETTER_INDEX = {"X": 0, "Y": 1, "Z": 2, "A": 0, "B": 1, "C": 2}


@register
class LaserModel(MeasurementModel):
    """Laser interferometer files (docs/measurements.md): component readings of the measured point.

    Nuisance per (axis, component) of the file: ``<tag>:<axis>:<comp>:offset`` (um or urad) and, for
    straightness components of a linear axis (E<d><L> with d != L, translational),
    ``<tag>:<axis>:<comp>:slope`` (urad = um/m, times the target position).
    """

    kind = "laser"

    def _setup(self):
        data = self.data
        m = self.machine
        self.q = data.axis_positions(m)
        self.c = self.context()
        n = len(data)
        comps = data.component
        self.direction = np.array([_LETTER_INDEX[c[1]] for c in comps], dtype=np.int64)
        self.angular = np.asarray(data.angular, dtype=bool)
        # sign: readings of a rotary axis on the workpiece side are the table's motion (minus the
        # tool-relative deviation)
        sign = np.ones(n)
        for i, a in enumerate(data.axis):
            if a in "ABC" and m.axis(a).side == "workpiece":
                sign[i] = -1.0
        self.sign = sign
        self.value_column = np.where(self.angular, "value_urad", "value_um")
        mask = np.isfinite(data.value)
        self._rows = np.flatnonzero(mask)
        self.observed = data.value[mask]
        self.obs_row = self._rows.astype(np.int64)
        self.obs_column = self.value_column[mask].astype(object)
        self.obs_unit_scale = np.where(self.angular[mask], 1e6, 1e3)
        # nuisance: one offset per (axis, component), one slope per straightness (axis, component)
        specs = []
        self._offset_index = np.zeros(n, dtype=np.int64)
        self._slope_index = np.full(n, -1, dtype=np.int64)
        keys = sorted({(a, c) for a, c in zip(data.axis, comps)}, key=lambda k: (k[0], k[1]))
        for a, comp in keys:
            rows = (data.axis == a) & (comps == comp)
            angular = comp[1] in "ABC"
            self._offset_index[rows] = len(specs)
            specs.append(ParamSpec(f"{self.tag}:{a}:{comp}:offset", "urad" if angular else "um",
                                   f"nuisance:{self.tag}", False,
                                   f"zero offset of the {comp} reading of {self.tag}"))
            if not angular and a in "XYZ" and comp[1] != a:
                self._slope_index[rows] = len(specs)
                specs.append(ParamSpec(f"{self.tag}:{a}:{comp}:slope", "urad", f"nuisance:{self.tag}",
                                       False, f"optic misalignment slope of the {comp} reading of "
                                       f"{self.tag} (um/m)"))
        self.nuisance_specs = specs
        self.optic = np.asarray(data.optic, dtype=float)
        # per-row selector of the reading: [translation (3), rotation (3)] . s, sign included
        sel = np.zeros((n, 6))
        sel[np.arange(n), self.direction + 3 * self.angular] = self.sign
        self._cx = np.hstack([self.c, self.optic, sel])

    def _readings(self, p, jacobian):
        """(n_rows,) model readings without nuisance (and (n_rows, n_params) Jacobian)."""
        name = "laser_jac" if jacobian else "laser"
        out = evaluate_chain(self.model, name, self.q, p, self._cx)
        value = out[0].reshape(-1)
        return value, (out[1].reshape(len(value), -1) if jacobian else None)

    def _nuisance_part(self, nuisance):
        """(n_rows,) offset + slope * target, and the (n_rows, n_nuisance) design of it."""
        n = len(self.data)
        D = np.zeros((n, self.n_nuisance))
        D[np.arange(n), self._offset_index] = 1.0
        has = self._slope_index >= 0
        D[np.flatnonzero(has), self._slope_index[has]] = self.data.target[has]
        return D @ nuisance, D

    def _evaluate(self, p, nuisance, jacobian):
        p, nuisance = self._check_p(p, nuisance)
        value, J = self._readings(p, jacobian)
        extra, D = self._nuisance_part(nuisance)
        pred = (value + extra)[self._rows]
        if not jacobian:
            return pred, None, None
        return pred, J[self._rows], D[self._rows]

    def column_jacobians(self, p):
        _, J = self._readings(np.asarray(p, dtype=float), True)
        out = {}
        for col, scale, sel in (("value_um", 1e3, ~self.angular), ("value_urad", 1e6, self.angular)):
            if col in self.data.value_columns:
                out[f"pred_{col}"] = np.where(sel[:, None], J * scale, np.nan)
        return out

    def predict_columns(self, p, nuisance=None):
        p, nuisance = self._check_p(p, nuisance)
        value, _ = self._readings(p, False)
        value = value + self._nuisance_part(nuisance)[0]
        out = {}
        for col, scale, sel in (("value_um", 1e3, ~self.angular), ("value_urad", 1e6, self.angular)):
            if col in self.data.value_columns:
                out[f"pred_{col}"] = np.where(sel, value * scale, np.nan)
        return out


# ------------------------------------------------------------------------------------- ballbar
#: a ball-bar reading further than this from the distance of the balls at its nominal pose is no
#: bar length (a machine's errors and a bar's calibration are micrometres to a tenth of a millimetre)
BAR_LENGTH_TOLERANCE_MM = 1.0


@register
class BallbarModel(MeasurementModel):
    """Ball-bar files (docs/measurements.md): centre distance of table ball and tool ball, plus a
    per-file length offset ``<tag>:length_offset`` (um) for the calibration of the bar. Option
    ``setup="known"``: the bar is calibrated (its length is exact, no offset is fitted). A bar read from one side only (the
    three-sphere set-up: tool ball along +X, +Y, +Z) cannot tell its length offset from a shift of the
    table ball along (1, 1, 1): there the calibration decides where the axis is."""

    kind = "ballbar"

    def _setup(self):
        data = self.data
        self.q = data.axis_positions(self.machine)
        self.c = self.context()
        self._set_observations(data.length[:, None], ["length_mm"], [1.0])
        self._rows = self.obs_row
        self._cx = np.hstack([self.c, data.table_ball, data.tool_ball])
        self._calibrated = self.options.get("setup", "free") == "known"
        self.nuisance_specs = [] if self._calibrated else [
            ParamSpec(f"{self.tag}:length_offset", "um", f"nuisance:{self.tag}", False,
                      f"length calibration offset of the ball bar of {self.tag}")]

    def check_readings(self) -> None:
        """InputError for a reading that is no bar length: further than
        :data:`BAR_LENGTH_TOLERANCE_MM` from the distance of the balls at the row's nominal pose
        (a deviation in um entered under ``length_mm``, a length in inches). Called before a fit
        (predict takes any placeholder). Once per model: diagnose builds many problems of it."""
        if getattr(self, "_lengths_checked", False):
            return
        length = np.asarray(self.data.length, dtype=float)
        nominal = self._lengths(np.zeros(self.model.n_params), False)[0]
        with np.errstate(invalid="ignore"):
            far = np.flatnonzero(np.abs(length - nominal) > BAR_LENGTH_TOLERANCE_MM)
        if far.size:
            i = int(far[0])
            also = (" or the machine file's axis_point_mm (in mm)"
                    if any(a.is_rotary for a in self.model.machine.axes) else "")
            refuse_other_topology(self, length, i, BAR_LENGTH_TOLERANCE_MM)
            raise InputError(f"length_mm {length[i]:g} is {abs(length[i] - nominal[i]):.4g} mm from "
                             f"the distance of the balls there ({nominal[i]:.4f} mm): length_mm is "
                             "the bar's length in mm (its nominal length plus the reading, not the "
                             f"deviation in um); if it is, the row's ball positions{also} are off",
                             self.data.path, row=int(self.data.row[i]))
        self._lengths_checked = True

    def _offset(self, nuisance) -> float:
        return 0.0 if self._calibrated else nuisance[0]

    def _lengths(self, p, jacobian):
        name = "ballbar_jac" if jacobian else "ballbar"
        out = evaluate_chain(self.model, name, self.q, p, self._cx)
        length = out[0].reshape(-1)
        return length, (out[1].reshape(len(length), -1) if jacobian else None)

    def _evaluate(self, p, nuisance, jacobian):
        p, nuisance = self._check_p(p, nuisance)
        length, J = self._lengths(p, jacobian)
        pred = length[self._rows] + self._offset(nuisance)
        if not jacobian:
            return pred, None, None
        return pred, J[self._rows], np.ones((self.n_obs, len(self.nuisance_specs)))

    def column_jacobians(self, p):
        return {"pred_length_mm": self._lengths(np.asarray(p, dtype=float), True)[1]}

    def predict_columns(self, p, nuisance=None):
        p, nuisance = self._check_p(p, nuisance)
        return {"pred_length_mm": self._lengths(p, False)[0] + self._offset(nuisance)}


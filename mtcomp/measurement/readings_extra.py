"""Measurement models of the kinds cmm, thermal and velocity, and drift features.

These register into :data:`mtcomp.measurement.readings.MEASUREMENT_MODELS` like the
points, laser and ballbar models, with the same interface (``predict``, ``jacobian``,
``predict_columns``; internal units mm, rad, mm/min; exact CasADi Jacobians). docs/sim.md has the
equations, docs/measurements.md the file formats.

* ``cmm``: the normal deviation of a machined surface point is the deviation of the ball
  centre of the cutter that touched it, along the outward normal: ``dn = n . (d + r (R_rel - I) a0)``
  with d the tool-tip deviation, ``R_rel`` the tool's rotation relative to nominal, ``a0`` the nominal
  tool axis and r the ball radius (positive: tool displaced outward, material left outside). The
  cutter location is found on the G-code that cut the part: the ball centre nearest to ``x + r n``.
  Nuisance: ``<tag>:radius_offset`` (um), the tool radius error (``dn -= dr``), and the CMM frame's
  set-up, a translation and a rotation about the points' centroid (``dn += n . (t + w x (x - c))``).
* ``thermal``: channel ``disp_<name>_um`` drifts. Channels ``x``, ``y``, ``z``, and the
  channels a :class:`~mtcomp.models.ThermalDrift` term names, are tool-tip directions: they read the
  tip deviation at the set-up pose relative to the file's first row (so the ThermalDrift term acts).
  Other channels read ``sum_f TD_<name>_<f> (f - f0)`` from a :class:`~mtcomp.models.ChannelDrift`
  term (zero without one). A channel covered by an ``absolute`` drift term reads its value itself, not
  its change since the first row (docs/thermal.md). Nuisance: one zero offset per channel,
  ``<tag>:<name>:offset`` (um).
* ``velocity`` (Yang et al. (2020), eq. 1): the velocity of a table point P is the derivative of its
  displacement along the axis position s times ``V = dir * feed``:
  ``v = V d/ds [s u + delta(s) + E_C(s) e_z x (P - O(s))]`` with u the axis direction (squareness),
  delta its translational component errors, ``E_C<axis>`` its yaw (every extension term included)
  and O the carriage's reference point shifted by the :class:`~mtcomp.models.AbbeIRC` centre of its
  E_C rotation. No nuisance.

Drift features (:func:`thermal_features`, :func:`feature_value`): ``time_h`` (t / 3600),
``time_exp_<tau>`` (1 - exp(-t / tau), tau in s: a first-order warm-up),
``dtemp_<name>`` (K, temperature rise over the first reading of the file), ``spindle_heat_<tau>``
(spindle speed in 1000 rpm through a first-order lag of time constant tau seconds, from 0 at the
first reading). Any measurement model fills these context channels from its file.
"""
from __future__ import annotations

import math
import re
import weakref

import casadi as ca
import numpy as np

from ..errors import InputError
from .files import Context, MeasurementSet
from ..kinematics import forward
from ..models.chain import ErrorModel
from ..models.function_cache import model_function
from ..models.params import ParamSpec
from ..models.terms import ANGLE_LETTERS, TRANSLATION_LETTERS, ChannelDrift
from .readings import MeasurementModel, context_matrix, frame_setup_specs, register

#: default time constants (s) of the spindle heat features
DEFAULT_TIME_CONSTANTS_S = (900.0, 3600.0)
FEATURE_KINDS = ("time", "temperature", "spindle")
_HEAT = re.compile(r"^spindle_heat_(\d+(?:\.\d+)?)$")
_LAG = re.compile(r"^spindle_lag_(\d+(?:\.\d+)?)$")
_TEMP = re.compile(r"^temp_(.+)$")
_DTEMP = re.compile(r"^dtemp_(.+)$")
_TEXP = re.compile(r"^time_exp_(\d+(?:\.\d+)?)$")
#: tip-direction channels of thermal files
TIP_CHANNELS = {"x": 0, "y": 1, "z": 2}


# --------------------------------------------------------------------------------- drift features
def _time_order(t: np.ndarray) -> np.ndarray:
    """Indices of the rows with a finite time, in increasing time (stable)."""
    idx = np.flatnonzero(np.isfinite(t))
    return idx[np.argsort(t[idx], kind="stable")]


def spindle_heat(t: np.ndarray, rpm: np.ndarray, tau_s: float, steady_start: bool = False) -> np.ndarray:
    """(n,) spindle speed (1000 rpm) through a first-order lag of time constant ``tau_s`` (s).

    h' = (rpm/1000 - h) / tau, h = 0 at the first reading (``steady_start``: h = the first reading's
    speed, as if the spindle had run at it for long); the speed is held between readings (exact
    discretisation: h_k = h_{k-1} + (1 - exp(-dt/tau)) (u_{k-1} - h_{k-1})). Rows are processed in time
    order; rows without a time get NaN. A blank speed counts as 0.
    """
    t = np.asarray(t, dtype=float)
    u = np.nan_to_num(np.asarray(rpm, dtype=float)) / 1000.0
    out = np.full(t.shape, np.nan)
    order = _time_order(t)
    h = float(u[order[0]]) if steady_start and order.size else 0.0
    for k, i in enumerate(order):
        if k > 0:
            j = order[k - 1]
            h += (1.0 - math.exp(-(t[i] - t[j]) / tau_s)) * (u[j] - h)
        out[i] = h
    return out


def feature_value(name: str, context: Context, reference_temperatures: dict | None = None):
    """(n,) values of drift feature ``name`` for the rows of ``context``, or None if ``name`` is not a
    drift feature. ``time_h``: h; ``dtemp_<s>``: K above ``reference_temperatures[s]`` or else the
    first reading in time order; ``temp_<s>``: degC as read; ``spindle_heat_<tau>``: 1000 rpm (see
    :func:`spindle_heat`), ``spindle_lag_<tau>`` the same started at the first reading's speed."""
    t = np.asarray(context.t, dtype=float)
    if name == "time_h":
        return t / 3600.0
    m = _TEXP.match(name)
    if m:                                   # warm-up: 1 - exp(-t / tau), tau in s (diagnose)
        return 1.0 - np.exp(-t / float(m.group(1)))
    m = _DTEMP.match(name)
    if m:
        sensor = m.group(1)
        if sensor not in context.temperatures:
            return np.full(t.shape, np.nan)
        temp = np.asarray(context.temperatures[sensor], dtype=float)
        ref = (reference_temperatures or {}).get(sensor)
        if ref is None:
            order = _time_order(t)
            if order.size == 0:
                order = np.arange(len(temp))
            finite = order[np.isfinite(temp[order])]
            ref = temp[finite[0]] if finite.size else np.nan
        return temp - ref
    m = _HEAT.match(name) or _LAG.match(name)
    if m:
        return spindle_heat(t, context.spindle_rpm, float(m.group(1)), steady_start=m.re is _LAG)
    m = _TEMP.match(name)
    if m:
        temp = context.temperatures.get(m.group(1))
        return np.full(t.shape, np.nan) if temp is None else np.asarray(temp, dtype=float)
    return None


def feature_names(context: Context, kinds=FEATURE_KINDS,
                  time_constants_s=DEFAULT_TIME_CONSTANTS_S) -> list[str]:
    """Names of the drift features a file's context supports, for the given kinds."""
    names = []
    has_t = np.isfinite(context.t).any()
    if "time" in kinds and has_t:
        names.append("time_h")
    if "temperature" in kinds:
        names += [f"dtemp_{s}" for s in context.temperatures]
    if "spindle" in kinds and has_t and np.isfinite(context.spindle_rpm).any():
        names += [f"spindle_heat_{tau:g}" for tau in time_constants_s]
    return names


def thermal_features(context: Context, kinds=FEATURE_KINDS, time_constants_s=DEFAULT_TIME_CONSTANTS_S,
                     reference_temperatures: dict | None = None) -> dict[str, np.ndarray]:
    """Drift features of any file with ``t_s`` / ``temp_<name>_c`` / ``spindle_rpm``: name -> (n,).

    kinds : subset of ('time', 'temperature', 'spindle'). time_constants_s : lags of the spindle heat
    states (s). Units: time_h in h, dtemp_<name> in K, spindle_heat_<tau> in 1000 rpm.
    """
    return {name: feature_value(name, context, reference_temperatures)
            for name in feature_names(context, kinds, time_constants_s)}


def drift_context(model: ErrorModel, data: MeasurementSet, reference_temperatures: dict | None = None
                  ) -> dict[str, np.ndarray]:
    """The drift-feature channels among ``model.context_names`` computed from ``data`` (name -> (n,)),
    for ``context_matrix(..., extra=...)``. NaN where a file lacks the input (the default applies)."""
    out = {}
    for name in model.context_names:
        v = feature_value(name, data.context, reference_temperatures)
        if v is not None:
            out[name] = v
    return out


# --------------------------------------------------------------------------------- chain projections
def normal_deviation_function(model: ErrorModel) -> ca.Function:
    """CasADi (q, p, cx = [c, o (3), n (3)]) -> (v, dv/dp (1, n_params)) with
    ``v = n . (d + (R_rel - I) o)``: the deviation along n of the point carried by the tool at o from
    the nominal tip (workpiece frame; d tip deviation, R_rel the tool's rotation relative to nominal).
    Built once per model structure (:func:`mtcomp.models.function_cache.model_function`)."""
    def build():
        nc = model.n_context
        q, p = ca.SX.sym("q", model.machine.n_axes), ca.SX.sym("p", model.n_params)
        cx = ca.SX.sym("c", nc + 6)
        c, o, n = cx[:nc], cx[nc:nc + 3], cx[nc + 3:]
        tip, _, R = model.symbolic(q, p, c, errors=True)
        tip0, _, R0 = model.symbolic(q, p, c, errors=False)
        v = ca.dot(n, tip - tip0 + ca.mtimes(ca.mtimes(R, R0.T), o) - o)
        return ca.Function("normal_deviation", [q, p, cx], [v, ca.jacobian(v, p)])
    return model_function(model, "normal_deviation", build)


def normal_deviation(model: ErrorModel, q, p, c, offset, normal, jacobian: bool = False):
    """(N,) deviation along ``normal`` (N, 3) of the tool point at ``offset`` (N, 3) mm from the nominal
    tip, at poses q (N, na) with context c (N, n_context); with ``jacobian`` also (N, n_params)."""
    from ..models.evaluate import casadi_map_call
    q = np.ascontiguousarray(q, dtype=float)
    cx = np.ascontiguousarray(np.column_stack([c, offset, normal]), dtype=float)
    if q.shape[0] == 0:
        return (np.zeros(0), np.zeros((0, model.n_params))) if jacobian else np.zeros(0)
    v, J = casadi_map_call(normal_deviation_function(model), q, np.asarray(p, dtype=float), cx)
    v = v.reshape(-1)
    return (v, J.reshape(q.shape[0], model.n_params)) if jacobian else v


def tip_channels(model: ErrorModel) -> tuple[dict, set]:
    """(thermal channel -> tip direction index 0/1/2 it reads, channels read as absolute values):
    channels x, y, z, those the model's ThermalDrift terms name, and the channels of absolute terms."""
    from ..models.terms import ThermalDrift
    tip = dict(TIP_CHANNELS)
    absolute = set()
    for t in model.terms:
        if isinstance(t, ThermalDrift):
            tip.update(t.channel_directions())
            if t.absolute:
                absolute.update(t.channel_directions())
        elif isinstance(t, ChannelDrift) and t.absolute:
            absolute.update(t.channels)
    return tip, absolute


def _extra_context(mm: MeasurementModel) -> dict:
    """Drift features of the model's file, overridden by the ``extra_context`` option."""
    extra = drift_context(mm.model, mm.data, mm.options.get("reference_temperatures"))
    extra.update(mm.options.get("extra_context") or {})
    return extra


# --------------------------------------------------------------------------------- thermal
@register
class ThermalModel(MeasurementModel):
    """Thermal files (docs/measurements.md): drift of each ``disp_<name>_um`` channel (module docstring).

    Options: ``setup_q`` (n_axes,) axis positions of the set-up, mm and rad (default all zero),
    ``reference_temperatures`` (name -> degC) for the dtemp features.
    """

    kind = "thermal"

    def _setup(self):
        data = self.data
        m = self.machine
        n = len(data)
        self.channels = list(data.channels)
        q = np.asarray(self.options.get("setup_q", np.zeros(m.n_axes)), dtype=float)
        if q.shape != (m.n_axes,):
            raise ValueError(f"setup_q must have shape ({m.n_axes},)")
        self.q = np.tile(q, (n, 1))
        self.c = context_matrix(self.model, data, self.context_defaults, m, _extra_context(self))
        order = _time_order(data.t)
        self.first = int(order[0]) if order.size else 0
        values = np.column_stack([data.channels[ch] for ch in self.channels])
        self._set_observations(values, [f"disp_{ch}_um" for ch in self.channels],
                               [1e3] * len(self.channels))
        self._rows, self._cols = np.nonzero(self._obs_mask)
        self.nuisance_specs = [ParamSpec(f"{self.tag}:{ch}:offset", "um", f"nuisance:{self.tag}",
                                         False, f"zero offset of channel {ch} of {self.tag}")
                               for ch in self.channels]
        self._tip, self._absolute = tip_channels(self.model)
        # other channels: (feature index in context or -1 for the zero, parameter index) pairs
        ctx_index = {nm: i for i, nm in enumerate(self.model.context_names)}
        p_index = {nm: i for i, nm in enumerate(self.model.param_names)}
        self._channel_terms = {}
        for ch in self.channels:
            if ch in self._tip:
                continue
            pairs = []
            for t in self.model.terms:
                if isinstance(t, ChannelDrift) and ch in t.channels:
                    pairs += [(ctx_index[f], p_index[f"TD_{ch}_{f}"]) for f in t.features]
                    if t.absolute:
                        pairs.append((-1, p_index[f"TD_{ch}_zero"]))
            self._channel_terms[ch] = pairs

    def _channel_values(self, p, jacobian):
        """(n_rows, n_channels) drift readings without offsets, (and (n_rows, n_ch, n_params))."""
        n, k = len(self.data), len(self.channels)
        val = np.zeros((n, k))
        J = np.zeros((n, k, self.model.n_params)) if jacobian else None
        for ch, axis_index in self._tip.items():
            if ch not in self.channels:
                continue
            e = np.zeros((n, 3))
            e[:, axis_index] = 1.0
            v, Jv = normal_deviation(self.model, self.q, p, self.c, np.zeros((n, 3)), e, True)
            j = self.channels.index(ch)
            absolute = ch in self._absolute
            val[:, j] = v if absolute else v - v[self.first]
            if jacobian:
                J[:, j, :] = Jv if absolute else Jv - Jv[self.first]
        for j, ch in enumerate(self.channels):
            if ch in self._tip:
                continue
            dc = self.c if ch in self._absolute else self.c - self.c[self.first]
            for ci, pi in self._channel_terms[ch]:
                col = np.ones(n) if ci < 0 else dc[:, ci]
                val[:, j] += p[pi] * col
                if jacobian:
                    J[:, j, pi] += col
        return val, J

    def _evaluate(self, p, nuisance, jacobian):
        p, nuisance = self._check_p(p, nuisance)
        val, J = self._channel_values(p, jacobian)
        pred = val[self._rows, self._cols] + nuisance[self._cols]
        if not jacobian:
            return pred, None, None
        Jn = np.zeros((self.n_obs, self.n_nuisance))
        Jn[np.arange(self.n_obs), self._cols] = 1.0
        return pred, J[self._rows, self._cols], Jn

    def predict_columns(self, p, nuisance=None):
        p, nuisance = self._check_p(p, nuisance)
        val, _ = self._channel_values(p, False)
        return {f"pred_disp_{ch}_um": (val[:, j] + nuisance[j]) * 1e3
                for j, ch in enumerate(self.channels)}

    def column_jacobians(self, p):
        _, J = self._channel_values(np.asarray(p, dtype=float), True)
        return {f"pred_disp_{ch}_um": J[:, j, :] * 1e3 for j, ch in enumerate(self.channels)}


# --------------------------------------------------------------------------------- velocity
@register
class VelocityModel(MeasurementModel):
    """Velocity files (docs/measurements.md): the derivative of the points M and N's displacement
    along the axis times V (module docstring; Yang et al. (2020), eq. 1, find the point moving at
    exactly V e from two of them).
    Velocities in mm/min, in the axis's own sense: for a table axis the sign of the table's motion is
    reversed (ISO 841), which leaves O alone."""

    kind = "velocity"
    COLUMNS = ("m_vx_mm_min", "m_vy_mm_min", "n_vx_mm_min", "n_vy_mm_min")

    def _setup(self):
        data = self.data
        m = self.machine
        n = len(data)
        bad = np.flatnonzero(~np.isin(data.axis, [a for a in ("X", "Y") if a in m.axis_names]))
        if bad.size:
            data.fail(f"velocity rows must move axis X or Y of the machine (table plane XY), not "
                      f"{data.axis[bad[0]]}", bad[0])
        self.q = np.nan_to_num(data.axis_positions(m))    # the moving axis at its position, the others at 0
        self.c = context_matrix(self.model, data, self.context_defaults, m, _extra_context(self))
        self.speed = data.signed_speed()
        values = np.column_stack([data.m_v, data.n_v])
        self._set_observations(values, list(self.COLUMNS), [1.0] * 4)
        self._rows, self._cols = np.nonzero(self._obs_mask)
        self._functions = {a: velocity_function(self.model, a) for a in set(data.axis)}

    def _velocities(self, p, jacobian):
        n = len(self.data)
        v = np.zeros((n, 4))
        J = np.zeros((n, 4, self.model.n_params)) if jacobian else None
        for a, f in self._functions.items():
            rows = np.flatnonzero(self.data.axis == a)
            inp = np.column_stack([self.data.position[rows], self.speed[rows],
                                   self.data.m_xy[rows], self.data.n_xy[rows]])
            fm = f.map(len(rows))
            res = fm(inp.T, p, self.c[rows].T)
            v[rows] = np.asarray(res[0]).T
            if jacobian:
                # mapped jacobian: 4 x (n_params * len(rows)), block j holds row j
                Jm = np.asarray(res[1]).reshape(4, len(rows), self.model.n_params)
                J[rows] = Jm.transpose(1, 0, 2)
        return v, J

    def _evaluate(self, p, nuisance, jacobian):
        p, nuisance = self._check_p(p, nuisance)
        v, J = self._velocities(p, jacobian)
        pred = v[self._rows, self._cols]
        if not jacobian:
            return pred, None, None
        return pred, J[self._rows, self._cols], np.zeros((self.n_obs, 0))

    def predict_columns(self, p, nuisance=None):
        """In the file's own sense (a file in the bed's sense gets its predictions negated back)."""
        p, nuisance = self._check_p(p, nuisance)
        v, _ = self._velocities(p, False)
        sense = -1.0 if self.data.bed_sense else 1.0
        return {f"pred_{c}": sense * v[:, j] for j, c in enumerate(self.COLUMNS)}

    def column_jacobians(self, p):
        _, J = self._velocities(np.asarray(p, dtype=float), True)
        sense = -1.0 if self.data.bed_sense else 1.0
        return {f"pred_{c}": sense * J[:, j] for j, c in enumerate(self.COLUMNS)}

    def rotation_centre(self, p) -> np.ndarray:
        """(n_rows, 2) mm the instantaneous rotation centre of the model's velocity field at each row
        (carriage frame, XY): the point moving at exactly V0 along the axis, which Yang et al. (2020),
        eq. 1, find from two measured velocities (NaN without a yaw rate). The field is
        v(P) = a + Omega e_z x P, so the centre solves a + Omega e_z x O = V0 e; it is the AbbeIRC centre only when the axis has no
        translational error slope and the centre does not move along the axis."""
        out = np.full((len(self.data), 2), np.nan)
        for ax, f in self._functions.items():
            rows = np.flatnonzero(self.data.axis == ax)
            inp = np.column_stack([self.data.position[rows], self.speed[rows], np.zeros((rows.size, 2)),
                                   np.tile([1.0, 0.0], (rows.size, 1))])
            v = np.asarray(f.map(rows.size)(inp.T, p, self.c[rows].T)[0]).T     # v(0, 0), v(1, 0)
            omega = v[:, 3] - v[:, 1]
            g = -v[:, :2]
            g[:, "XY".index(ax)] += self.speed[rows]
            with np.errstate(divide="ignore", invalid="ignore"):
                out[rows] = np.column_stack([g[:, 1], -g[:, 0]]) / np.where(omega != 0, omega, np.nan)[:, None]
        return out

# --------------------------------------------------------------------------------- cmm
@register
class CmmModel(MeasurementModel):
    """CMM files (docs/measurements.md) with the program that cut the part (module docstring).

    Options: ``program`` (G-code path) and ``tool_radius_mm`` (ball radius), required here or as
    the data's fields of the same names,
    ``tool_mm`` (tool length, default the machine's), ``sample_mm`` (spacing of the sampled
    cutter locations, default 0.1), ``max_gap_mm`` (largest distance from ``x + r n`` to the
    nearest ball centre before the point counts as not cut by the program, default 2),
    ``include_path_offset`` (default the data's field, False: the program is taken to follow the
    nominal surface; True: add ``n . (c0 - (x + r n))``, where the commanded ball centre c0 sits off
    the nominal one along the normal -- the corrections of a compensated program, chordal error; for
    points on the passes: between passes of a curved surface the nearest centre is off the normal).
    """

    kind = "cmm"

    def _setup(self):
        data = self.data
        m = self.machine
        program = self.options.get("program", data.program)
        radius = self.options.get("tool_radius_mm", data.tool_radius_mm)
        if program is None or radius is None:
            raise InputError("a cmm file needs the G-code that cut the part and the radius of its "
                             "ball-end tool: give --cmm-program and --cmm-tool-radius", data.path)
        self.radius = radius = float(radius)
        q, k, loc = cut_poses(m, data, program, radius, float(self.options.get("sample_mm", 0.1)),
                              float(self.options.get("max_gap_mm", 2.0)))
        self.q = q
        self.segment = k
        self.line = loc.line[k]
        self.axis0 = forward(m, q)[1]
        self.path_offset = np.zeros(len(data))
        if self.options.get("include_path_offset", data.include_path_offset):
            self.path_offset = path_offsets(m, data, q, radius)
        extra = _extra_context(self)
        cols = {"feed": loc.feed[k]}
        for j, a in enumerate(m.axis_names):
            cols[f"dir_{a}"] = loc.dirs[k, j].astype(float)
        cols["tool_length"] = np.full(len(data), float(self.options.get("tool_mm", m.tool_length)))
        cols.update(extra)
        # the block context comes from the program, not from the CMM file's own columns
        base = self.model.default_context(len(data))
        for i, nm in enumerate(self.model.context_names):
            if nm in self.context_defaults:
                base[:, i] = self.context_defaults[nm]
            if nm in cols:
                col = np.asarray(cols[nm], dtype=float)
                base[:, i] = np.where(np.isfinite(col), col, base[:, i])
        self.c = base
        self._set_observations(data.normal_deviation[:, None], ["dn_um"], [1e3])
        self._rows = self.obs_row
        self.nuisance_specs = [ParamSpec(f"{self.tag}:radius_offset", "um", f"nuisance:{self.tag}",
                                         False, f"tool radius error of the cutter of {self.tag}")]
        # the CMM is aligned to the part, never to the machine: a translation t and a small rotation w
        # (about the centroid of the measured points) of its frame, dn += n . (t + w x (x - c))
        self._setup_arm = data.xyz - data.xyz[self._rows if self.n_obs else slice(None)].mean(axis=0)
        self._setup_design = np.zeros((len(data), 0))
        if self.options.get("setup", "free") != "known" and self.n_obs:
            self._setup_design = np.hstack([data.normal, np.cross(self._setup_arm, data.normal)])
            self.nuisance_specs += frame_setup_specs(self.tag, "the CMM's frame")

    def _dn(self, p, jacobian):
        """(n_rows,) n . (ball-centre deviation), mm (and (n_rows, n_params))."""
        out = normal_deviation(self.model, self.q, p, self.c, self.axis0 * self.radius,
                               self.data.normal, jacobian)
        return (out[0] + self.path_offset, out[1]) if jacobian else (out + self.path_offset, None)

    def _nuisance_design(self):
        """(n_rows, n_nuisance): radius offset (dn -= dr), then the set-up (when fitted)."""
        return np.hstack([-np.ones((len(self.data), 1)), self._setup_design])

    def _evaluate(self, p, nuisance, jacobian):
        p, nuisance = self._check_p(p, nuisance)
        dn, J = self._dn(p, jacobian)
        design = self._nuisance_design()[self._rows]
        pred = dn[self._rows] + design @ nuisance
        if not jacobian:
            return pred, None, None
        return pred, J[self._rows], design

    def predict_columns(self, p, nuisance=None):
        p, nuisance = self._check_p(p, nuisance)
        return {"pred_dn_um": (self._dn(p, False)[0] + self._nuisance_design() @ nuisance) * 1e3}

    def column_jacobians(self, p):
        return {"pred_dn_um": self._dn(np.asarray(p, dtype=float), True)[1] * 1e3}


# --------------------------------------------------------------------------------- velocity algebra
def _symbols(model: ErrorModel):
    p = ca.SX.sym("p", model.n_params)
    c = ca.SX.sym("c", model.n_context)
    P = {nm: p[i] for i, nm in enumerate(model.param_names)}
    C = {nm: c[i] for i, nm in enumerate(model.context_names)}
    return p, c, P, C


def velocity_function(model: ErrorModel, axis: str) -> ca.Function:
    """:func:`_build_velocity_function`, built once per model structure and axis
    (:func:`mtcomp.models.function_cache.model_function`)."""
    return model_function(model, f"velocity_{axis}", lambda: _build_velocity_function(model, axis))


def _build_velocity_function(model: ErrorModel, axis: str) -> ca.Function:
    """CasADi (inp (6,) = [s mm, V mm/min, Mx, My, Nx, Ny], p, c) -> (v (4,) = [vMx, vMy, vNx, vNy]
    mm/min, dv/dp (4, n_params)) for a table moving along ``axis`` (X or Y).

    The in-plane displacement of a carriage point P (in the plane of the carriage's reference point)
    at position s is, to first order, ``s u + delta(s) + E_C(s) e_z x (P - O(s))`` (the model's own
    carriage transform: u the axis direction with its squareness, delta its translational component
    errors, E_C its yaw about O); the velocity is its derivative along s times V."""
    inp = ca.SX.sym("inp", 6)
    p, c, P, C = _symbols(model)
    s, V = inp[0], inp[1]
    u, comps, centres, r = model.linear_parts(axis, s, P, C)
    delta = [comps[f"E{t}{axis}"] for t in TRANSLATION_LETTERS[:2]]
    yaw = comps[f"E{ANGLE_LETTERS[2]}{axis}"]
    o = r + centres["C"]                      # the yaw's centre: reference point + AbbeIRC shift
    out = []
    for base in (2, 4):
        rx, ry = inp[base] - o[0], inp[base + 1] - o[1]
        dx = s * u[0] + delta[0] - yaw * ry
        dy = s * u[1] + delta[1] + yaw * rx
        out += [ca.jacobian(dx, s) * V, ca.jacobian(dy, s) * V]
    v = ca.vertcat(*out)
    return ca.Function(f"velocity_{axis}", [inp, p, c], [v, ca.jacobian(v, p)])


# --------------------------------------------------------------------------------- cutter locations
class CutterLocations:
    """Densely sampled ball-centre path of a program (cutting moves only).

    start, end : (m, na) segment ends (mm, rad); line, feed, dirs : per segment.
    samples : (k, 3) mm ball centres (workpiece frame); seg : (k,) segment of each sample;
    u : (k,) position of the sample along its segment (0..1).
    """

    def __init__(self, machine, start, end, line, feed, dirs, radius, sample_mm):
        from scipy.spatial import cKDTree
        self.machine, self.start, self.end = machine, start, end
        self.line, self.feed, self.dirs, self.radius = line, feed, dirs, radius
        tip_s, ax_s = forward(machine, start)
        tip_e, ax_e = forward(machine, end)
        length = np.linalg.norm(tip_e - tip_s + radius * (ax_e - ax_s), axis=1)
        count = np.maximum(1, np.ceil(length / sample_mm).astype(int))
        seg = np.repeat(np.arange(len(start)), count + 1)
        first = np.repeat(np.cumsum(count + 1) - (count + 1), count + 1)
        u = (np.arange(seg.size) - first) / np.repeat(count, count + 1)
        self.seg, self.u = seg, u
        self.samples = self._centres(seg, u)
        self.tree = cKDTree(self.samples)

    def _q(self, seg, u):
        return self.start[seg] + u[:, None] * (self.end[seg] - self.start[seg])

    def _centres(self, seg, u):
        tip, axis = forward(self.machine, self._q(seg, u))
        return tip + self.radius * axis

    def nearest(self, target: np.ndarray):
        """For each (n, 3) target ball centre: (q (n, na) cutter location, segment (n,), distance (n,)
        mm from the target to that ball centre). The nearest sample is refined on its segment by
        projecting the target on the sampled centre polyline around it."""
        dist, idx = self.tree.query(target)
        seg = self.seg[idx]
        u = self.u[idx].copy()
        best = dist.copy()
        for nb in (-1, 1):
            j = np.clip(idx + nb, 0, len(self.seg) - 1)
            same = self.seg[j] == seg
            a, b = self.samples[idx], self.samples[j]
            ab = b - a
            den = np.einsum("ij,ij->i", ab, ab)
            lam = np.clip(np.einsum("ij,ij->i", target - a, ab) / np.where(den > 0, den, 1.0), 0, 1)
            pt = a + lam[:, None] * ab
            dd = np.linalg.norm(target - pt, axis=1)
            better = same & (den > 0) & (dd < best)
            u[better] = (self.u[idx] + lam * (self.u[j] - self.u[idx]))[better]
            best[better] = dd[better]
        return self._q(seg, u), seg, best


def path_offsets(machine, data, q, radius: float) -> np.ndarray:
    """(n,) mm how far the program's nominal ball centre at the cutter locations ``q`` sits from the
    cmm points' own ball centre ``x + r n``, along each normal: ``n . (c0 - (x + r n))``. Zero for a
    program that follows the nominal surface; a compensated program's corrections; a wrong radius or
    a misplaced part as a whole."""
    tip0, axis0 = forward(machine, q)
    return np.einsum("ij,ij->i", tip0 + radius * axis0 - (data.xyz + radius * data.normal), data.normal)


#: cmm data set -> (key, cut poses): the last poses found for it (the knots are placed from them
#: before the fit's measurement model finds them again)
_CUT_POSES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def cut_poses(machine, data, program, radius: float, sample_mm: float = 0.1, max_gap_mm: float = 2.0):
    """(q (n, na), segment (n,), CutterLocations) of the cmm file ``data``: for each surface point the
    cutter location of ``program`` whose ball centre is nearest to ``x + r n``. InputError naming the
    row of a point no cutter location comes within ``max_gap_mm`` of. Remembered for the same data,
    machine geometry, program and radius (:data:`_CUT_POSES`)."""
    geometry = tuple((a.name, tuple(getattr(a, "axis_point", None) or ())) for a in machine.axes)
    key = (machine.topology, geometry, str(program), float(radius), float(sample_mm), float(max_gap_mm))
    cached = _CUT_POSES.get(data)
    if cached is not None and cached[0] == key:
        return cached[1]
    if not radius > 0:
        raise InputError(f"tool radius must be positive, got {radius!r}", data.path)
    loc = cutter_locations(machine, program, radius, sample_mm)
    q, k, gap = loc.nearest(data.xyz + radius * data.normal)
    far = np.flatnonzero(gap > max_gap_mm)
    if far.size:
        data.fail(f"no cutter location of {program} within {max_gap_mm:g} mm of this point's "
                  f"ball centre (nearest {gap[far[0]]:.3g} mm): the program did not cut it", far[0])
    _CUT_POSES[data] = (key, (q, k, loc))
    return q, k, loc


def cutter_locations(machine, program, radius: float, sample_mm: float = 0.1) -> CutterLocations:
    """Sample the cutting moves (not G0) of ``program`` as ball centres every ``sample_mm`` mm."""
    from ..toolpaths import iter_segment_chunks
    chunks = list(iter_segment_chunks(program, machine))
    if not chunks:
        raise InputError("the program has no motion", str(program))
    start = np.concatenate([c.start for c in chunks])
    end = np.concatenate([c.end for c in chunks])
    keep = ~np.concatenate([c.rapid for c in chunks])
    if not keep.any():
        raise InputError("the program has no cutting moves (only G0)", str(program))
    cat = lambda f: np.concatenate([getattr(c, f) for c in chunks])[keep]  # noqa: E731
    return CutterLocations(machine, start[keep], end[keep], cat("line"), cat("feed"), cat("dirs"),
                           radius, sample_mm)


"""Measurement models of the kinds cmm, thermal and velocity.

These register into :data:`mtcomp.measurement.readings.MEASUREMENT_MODELS` like the
points, laser and ballbar models, with the same interface (``predict``, ``jacobian``,
``predict_columns``; internal units mm, rad, mm/min; exact CasADi Jacobians). docs/sim.md has the
equations, docs/measurements.md the file formats.

* ``cmm``: the normal deviation of a machined surface point is the deviation of the ball
  centre of the cutter that touched it, along the outward normal: ``dn = n . (d + r (R_rel - I) a0)``
  with d the tool-tip deviation, ``R_rel`` the tool's rotation relative to nominal, ``a0`` the nominal
  tool axis and r the ball radius (positive: tool displaced outward, material left outside). The
  cutter location is found on the cutting moves of the G-code that cut the part (a
  :class:`~mtcomp.measurement.cut.CutProgram`, read from the program by the caller): the ball centre
  nearest to ``x + r n``.
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

The drift features every model fills from its file are :mod:`.drift`'s; the cut poses of a cmm file
:mod:`.cut`'s.
"""
from __future__ import annotations

import weakref

import casadi as ca
import numpy as np

from ..errors import InputError
from ..kinematics import forward
from ..models.chain import ErrorModel
from ..models.function_cache import model_function
from ..models.params import ParamSpec
from ..models.terms import ANGLE_LETTERS, TRANSLATION_LETTERS, ChannelDrift
from .readings import MeasurementModel, context_matrix, frame_setup_specs, register
from .cut import cut_poses, path_offsets
from .drift import _time_order, drift_context

#: tip-direction channels of thermal files
TIP_CHANNELS = {"x": 0, "y": 1, "z": 2}


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


def model_channels(model: ErrorModel) -> set:
    """The thermal channels the model's drift terms name."""
    from ..models.terms import ThermalDrift
    out = set()
    for t in model.terms:
        if isinstance(t, ThermalDrift):
            out.update(t.channel_directions())
        elif isinstance(t, ChannelDrift):
            out.update(t.channels)
    return out


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

    Options: ``cut`` (the program's cutting moves, a :class:`~mtcomp.measurement.cut.CutProgram`:
    :func:`mtcomp.toolpaths.cutter.read_cut_program` reads them from the G-code) and
    ``tool_radius_mm`` (ball radius), required here or as the data's fields of the same names,
    ``tool_mm`` (tool length, default that of the program's move, else the machine's), ``sample_mm`` (spacing of the sampled
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
        cut = self.options.get("cut", data.cut)
        radius = self.options.get("tool_radius_mm", data.tool_radius_mm)
        if cut is None or radius is None:
            raise InputError("a cmm file needs the G-code that cut the part and the radius of its "
                             "ball-end tool: give --cmm-program and --cmm-tool-radius", data.path)
        self.radius = radius = float(radius)
        q, k, loc = cut_poses(m, data, cut, radius, float(self.options.get("sample_mm", 0.1)),
                              float(self.options.get("max_gap_mm", 2.0)))
        self.q = q
        self.segment = k
        self.line = loc.line[k]
        self.axis0 = forward(m, q)[1]
        self.path_offset = np.zeros(len(data))
        if self.options.get("include_path_offset", data.include_path_offset):
            self.path_offset = path_offsets(m, data, q, radius, cut)
        extra = _extra_context(self)
        cols = {"feed": loc.feed[k]}
        for j, a in enumerate(m.axis_names):
            cols[f"dir_{a}"] = loc.dirs[k, j].astype(float)
        # the tool of the move that cut each point (the program's G43 H, --tool-length), else tool_mm
        tool = np.full(len(data), float(self.options.get("tool_mm", m.tool_length)))
        if "tool_mm" not in self.options and cut.tool_length is not None:
            tool = np.where(np.isfinite(cut.tool_length[k]), cut.tool_length[k], tool)
        cols["tool_length"] = tool
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

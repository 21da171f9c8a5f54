"""The error model of a machine: the exact homogeneous-transform chain, built symbolically in CasADi.

Given a :class:`~mtcomp.machine.Machine` and optional extension terms, :class:`ErrorModel` builds

    tool2wp(q, p, c) = wp2bed(q, p, c)^-1 . tool2bed(q, p, c)

with CasADi SX symbols ``q`` (axis positions, mm and rad, in ``machine.axis_names`` order), ``p`` (the
parameter vector, internal units, in ``model.param_names`` order) and ``c`` (block context, in
``model.context_names`` order: feed, approach directions, time, spindle speed, tool length ...).

Each axis contributes one rigid transform of its carriage in its parent frame (all frames coincide
with the machine frame when every axis is at zero):

* linear axis L at position s, tool side (docs/conventions.md):

      Trans(s u_L) . Trans(delta) . prod_{a=A,B,C} [Trans(r + o_a) R_a(eps_a) Trans(-(r + o_a))]

  where u_L is the axis direction tilted by the squareness errors (u_Y = Rz(C0Y) e_y,
  u_Z = Ry(B0Z) Rx(A0Z) e_z), delta = (EXL, EYL, EZL)(s) and eps = (EAL, EBL, ECL)(s) are the
  component errors, r the carriage's reference point, a point fixed on the carriage (for tool-side
  axes the spindle gauge point at q = 0 with the machine's reference tool, (0, 0, L0), whatever tool
  is in the spindle; the workpiece origin for table axes) and o_a the shift of the centre of rotation a (zero in
  the base model, the IRC of Yang et al. (2020) with :class:`~mtcomp.models.terms.AbbeIRC`). Component errors
  are those a laser would read for the tool relative to the workpiece, so on the workpiece side the
  table's transform is the inverse of the one above (Qi and Yang (2016), eq. 17, do the same with
  signs).
* rotary axis R at angle theta: rotation about the *actual* axis line, not a nominal rotation plus an
  offset:

      Trans(P') . Trans(delta_m) . R(eps_m) . Rt Rot_d(theta + E_RR(theta)) Rt^T . Trans(-P')

  with P' the nominal axis point moved by the location errors (X0C, Y0C for C), Rt the tilt of the
  line (C: Ry(B0C) Rx(A0C)), E_RR the angular positioning error (ECC for C) and delta_m, eps_m the
  error motions (EXC, EYC, EZC, EAC, EBC for C) in the fixed frame at P'.

Tool length: the carriage frames are those of the reference tool (length L0, the machine file's
``tool_length_mm``): with every axis at zero its tip is at the origin. A tool of length L (context
``tool_length``) at commanded position q puts the ram (Z, :func:`ram_axis`) at its machine position
s = q_Z + (L - L0), where its nominal translation and error profiles are evaluated, and the tool tip
L - L0 further down the actual tool axis (:meth:`ErrorModel._axis_transform`). The tool tip is at
(0, 0, -TOOL_dL) in the last tool-side frame, the tool axis is its +Z. With L = L0 nothing moves.
Outputs: tool tip and tool axis in the workpiece frame, their deviations (actual minus nominal), and
Jacobians with respect to q and p.
"""
from __future__ import annotations

from functools import cached_property

import casadi as ca
import numpy as np

from .. import kinematics
from ..kinematics import CASADI
from ..machine import AXIS_DIRECTION, Machine
from .basis import SLOPE_CARRIED_BY_SQUARENESS, axis_spline
from .function_cache import model_function
from .params import ParamSpec
from .terms import (ANGLE_LETTERS, TRANSLATION_LETTERS, Term, motion_errors, motion_harmonics,
                    motion_pair, positioning_component)

#: context channels every model has; a term may add more (temperatures, drift features)
BASE_CONTEXT = ("feed", "t", "spindle_rpm", "tool_length")


def context_defaults(machine: Machine) -> dict[str, float]:
    """Value of each base context channel when a data set does not give it (dir 0: unknown)."""
    d = {"feed": 0.0, "t": 0.0, "spindle_rpm": 0.0, "tool_length": machine.tool_length}
    for a in machine.axis_names:
        d[f"dir_{a}"] = 0.0
    return d


# --------------------------------------------------------------------------------- rigid transforms
# A transform is a pair (R 3x3, t 3x1) of SX: x_parent = R x_child + t. The elementary rotation,
# composition and inverse are those of the nominal kinematics (mtcomp.kinematics, CasADi form).

rot = CASADI.rotation   # rot(axis_index, angle): elementary rotation about machine direction 0, 1 or 2


def compose(A, B):
    return kinematics.compose(A, B, CASADI)


def inverse(A):
    return kinematics.inverse(A, CASADI)


def trans(v):
    return (ca.SX.eye(3), ca.vertcat(*[v[i] for i in range(3)]) if not isinstance(v, ca.SX) else v)


def rot_about_point(R, point):
    """Rotation R about ``point`` (3-vector): Trans(p) R Trans(-p)."""
    return (R, point - ca.mtimes(R, point))


def unit(i: int):
    e = ca.SX.zeros(3)
    e[i] = 1
    return e


# --------------------------------------------------------------------------------- parameters
def linear_component_names(axis_name: str) -> list[str]:
    """The six ISO 230-1 component errors of a linear axis: EX?, EY?, EZ?, EA?, EB?, EC?."""
    return [f"E{d}{axis_name}" for d in TRANSLATION_LETTERS + ANGLE_LETTERS]


def rotary_motion_names(axis_name: str) -> list[str]:
    """The five error motions of a rotary axis (all components but its own angular positioning)."""
    own = positioning_component(axis_name)
    return [n for n in (f"E{d}{axis_name}" for d in TRANSLATION_LETTERS + ANGLE_LETTERS) if n != own]


def slope_carried(machine: Machine, comp: str) -> bool:
    """True when a squareness of the machine carries the slope of straightness ``comp`` (ISO 230-1
    defines straightness about a reference line whose slope against the other axis IS the squareness,
    so the base model keeps only one of the two: they act identically on every measurement)."""
    return SLOPE_CARRIED_BY_SQUARENESS.get(comp) in squareness_names(machine)


def polynomial_orders(machine: Machine, axis_name: str, comp: str) -> list[int]:
    """Powers k of the base polynomial of component ``comp`` (e.g. 'EXY') of linear axis ``axis_name``:
    1..degree, less k = 1 where the squareness carries the slope (:func:`slope_carried`)."""
    ax = machine.axis(axis_name)
    orders = list(range(1, ax.degree + 1))
    if slope_carried(machine, comp):
        orders.remove(1)
    return orders


def component_terms(machine: Machine, axis_name: str, comp: str) -> list[str]:
    """Suffixes of the parameters of component ``comp`` of linear axis ``axis_name``: ``b<j>`` for the
    kept B-spline functions, or the powers ``1``, ``2`` ... of a polynomial."""
    ax = machine.axis(axis_name)
    if ax.basis == "bspline":
        return [f"b{j}" for j in axis_spline(ax).kept(slope_carried(machine, comp))]
    return [str(k) for k in polynomial_orders(machine, axis_name, comp)]


def linear_components(machine: Machine, axis_name: str, s, value, zero=0) -> dict:
    """The six base component errors of linear axis ``axis_name`` at position s: {comp: E(s)}.

    Works on numpy arrays and CasADi expressions alike. ``value(name)`` gives the parameter of that
    name (e.g. 'EXX_b3'); ``zero`` starts each sum. The basis functions are evaluated once per axis
    and shared by its six components.
    """
    ax = machine.axis(axis_name)
    if ax.basis == "bspline":
        spline = axis_spline(ax)
        phis = spline.functions_by_reference(s)
    out = {}
    for comp in linear_component_names(axis_name):
        if ax.basis == "bspline":
            funcs = phis[slope_carried(machine, comp)]
        else:
            funcs = [(s / 1000.0) ** k for k in polynomial_orders(machine, axis_name, comp)]
        e = zero
        for k, phi in zip(component_terms(machine, axis_name, comp), funcs):
            e = e + value(f"{comp}_{k}") * phi
        out[comp] = e
    return out


#: the tilt of the spindle (tool) axis against its nominal direction: about X and about Y (urad)
SPINDLE_TILT = ("A0S", "B0S")


def squareness_names(machine: Machine) -> list[str]:
    names = set(machine.axis_names)
    out = []
    if {"X", "Y"} <= names:
        out.append("C0Y")
    if {"X", "Z"} <= names:
        out.append("B0Z")
    if {"Y", "Z"} <= names:
        out.append("A0Z")
    return out


def rotary_location_names(axis_name: str) -> tuple[list[str], list[str]]:
    """(offsets, tilts) of a rotary axis line: C -> (['X0C', 'Y0C'], ['A0C', 'B0C'])."""
    d = AXIS_DIRECTION[axis_name]
    others = [j for j in range(3) if j != d]
    return ([f"{TRANSLATION_LETTERS[j]}0{axis_name}" for j in others],
            [f"{ANGLE_LETTERS[j]}0{axis_name}" for j in others])


def base_param_specs(machine: Machine) -> list[ParamSpec]:
    """The base model (docs/identification.md), in a fixed order."""
    specs: list[ParamSpec] = []
    for ax in machine.linear_axes:
        for comp in linear_component_names(ax.name):
            angular = comp[1] in ANGLE_LETTERS
            for k in component_terms(machine, ax.name, comp):
                what = f"B-spline coefficient {k[1:]}" if k.startswith("b") else f"coefficient of (s/1 m)^{k}"
                specs.append(ParamSpec(f"{comp}_{k}", "urad" if angular else "um", f"{ax.name}:{comp}",
                                       True, f"{comp}: {what}"))
    for name in squareness_names(machine):
        specs.append(ParamSpec(name, "urad", "squareness", True, f"squareness {name}"))
    for ax in machine.rotary_axes:
        offsets, tilts = rotary_location_names(ax.name)
        for name in offsets:
            specs.append(ParamSpec(name, "um", f"{ax.name}:location", True, f"axis line offset {name}"))
        for name in tilts:
            specs.append(ParamSpec(name, "urad", f"{ax.name}:location", True, f"axis line tilt {name}"))
        own = positioning_component(ax.name)
        specs.append(ParamSpec(f"{own}_0", "urad", f"{ax.name}:{own}", True, f"zero offset of {ax.name}"))
        for k in range(1, ax.fourier_order + 1):
            for cs in "cs":
                specs.append(ParamSpec(f"{own}_{cs}{k}", "urad", f"{ax.name}:{own}", True,
                                       f"{own}: harmonic {k} ({'cos' if cs == 'c' else 'sin'})"))
        for comp in rotary_motion_names(ax.name):
            unit_ = "urad" if comp[1] in ANGLE_LETTERS else "um"
            for k in motion_harmonics(comp, ax.error_motion_order):
                for cs in "cs":
                    specs.append(ParamSpec(f"{comp}_{cs}{k}", unit_, f"{ax.name}:{comp}", True,
                                           f"{comp}: harmonic {k} ({'cos' if cs == 'c' else 'sin'})"
                                           + _against(comp, k)))
    for name, about in zip(SPINDLE_TILT, "XY"):
        specs.append(ParamSpec(name, "urad", "spindle", True,
                               f"tilt of the tool axis about {about}, about the spindle gauge point"))
    specs.append(ParamSpec("TOOL_dL", "um", "tool", True, "tool length error (tip lower when > 0)"))
    return specs


def _against(comp: str, k: int) -> str:
    """What a leader's first harmonic also moves (:func:`mtcomp.models.terms.motion_pair`)."""
    pair = motion_pair(comp) if k == 1 else None
    return f", turning against the axis with {pair[0]}" if pair else ""


def ram_axis(machine: Machine) -> str | None:
    """The ram: the axis that carries the spindle and that tool length compensation moves, Z when it is
    the last axis of the tool chain (XFYZ, CAFXYZ, CBFXYZ); None otherwise (a Z that moves the table
    or carries another axis: its errors stay functions of the commanded q_Z). A tool of length L puts
    the ram at its machine position q_Z + L - L0, L0 the machine file's tool length
    (docs/conventions.md)."""
    return "Z" if machine.tool_chain and machine.tool_chain[-1] == "Z" else None


def guideway_positions(machine: Machine, q, tool_length=None) -> np.ndarray:
    """(n, na) where each axis stood on its guideway at the commanded positions ``q`` ((n, na), mm and
    rad), where its error profiles are read: ``q`` itself, but the ram (:func:`ram_axis`) with a tool
    of length L (``tool_length``, (n,) mm or a scalar; None or NaN: the machine's L0) at its machine
    position q_Z + L - L0 (docs/conventions.md, "Tool length"). The one rule of the model's chain,
    of the region its data reached and of diagnose's structure analysis."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    ram = ram_axis(machine)
    if ram is None or tool_length is None:
        return q
    d = np.nan_to_num(np.broadcast_to(np.asarray(tool_length, dtype=float), q.shape[:1]) - machine.tool_length)
    if not d.any():
        return q
    out = q.copy()
    out[:, machine.index(ram)] += d
    return out


# --------------------------------------------------------------------------------- the model
class ErrorModel:
    """The symbolic error model of one machine with a given set of extension terms.

    The model is a frozen description; evaluation goes through its CasADi functions
    (``deviation_function``, ``deviation_jacobian_function``) or :mod:`mtcomp.models.evaluate`.

    Attributes
    ----------
    machine : the machine.
    terms : extension terms (beyond the base model), in order.
    param_specs : tuple of ParamSpec; ``param_names`` their names (the order of p).
    context_names : names of the context channels (the order of c).
    """

    def __init__(self, machine: Machine, terms: tuple[Term, ...] | list[Term] = ()):
        self.machine = machine
        self.terms = tuple(terms)
        keys = [t.key() for t in self.terms]
        if len(set(keys)) != len(keys):
            raise ValueError(f"a term is listed twice: {keys}")
        specs = base_param_specs(machine)
        for t in self.terms:
            specs.extend(t.param_specs(machine))
        names = [s.name for s in specs]
        dup = {n for n in names if names.count(n) > 1}
        if dup:
            raise ValueError(f"parameters defined twice (a term duplicates the base model?): {sorted(dup)}")
        self.param_specs = tuple(specs)
        ctx = list(BASE_CONTEXT) + [f"dir_{a}" for a in machine.axis_names]
        for t in self.terms:
            for name in t.context_names(machine):
                if name not in ctx:
                    ctx.append(name)
        self.context_names = tuple(ctx)
        self._q = ca.SX.sym("q", machine.n_axes)
        self._p = ca.SX.sym("p", len(specs))
        self._c = ca.SX.sym("c", len(ctx))

    # ----------------------------------------------------------------- sizes and names
    @property
    def param_names(self) -> tuple[str, ...]:
        return tuple(s.name for s in self.param_specs)

    @property
    def n_params(self) -> int:
        return len(self.param_specs)

    @property
    def n_context(self) -> int:
        return len(self.context_names)

    @property
    def base_mask(self) -> np.ndarray:
        return np.array([s.base for s in self.param_specs])

    def structure_key(self) -> str:
        """A string that identifies the model's structure (for the caches of its CasADi functions and
        compiled code); computed once (the model is a frozen description)."""
        key = self.__dict__.get("_structure_key")
        if key is None:
            import hashlib
            import json
            blob = json.dumps({"machine": self.machine.to_dict(), "terms": [t.to_dict() for t in self.terms],
                               "params": self.param_names, "ctx": self.context_names}, sort_keys=True)
            key = self._structure_key = hashlib.sha256(blob.encode()).hexdigest()[:16]
        return key

    def default_context(self, n: int = 1) -> np.ndarray:
        """(n, n_context) context with every channel at its default (feed 0, dir unknown ...)."""
        d = context_defaults(self.machine)
        out = np.empty((n, len(self.context_names)))
        for j, name in enumerate(self.context_names):   # column by column: a tile of the row
            out[:, j] = d.get(name, 0.0)                  # copies it row by row, ten times slower
        return out

    # ----------------------------------------------------------------- symbolic chain
    def direction_axes(self) -> np.ndarray:
        """(n_axes,) bool: the axes whose approach direction (context ``dir_<axis>``) the tool pose
        depends on, read from the symbolic chain (a backlash term, a signed feed lag); none for a
        base model."""
        m = self.machine
        names = list(self.context_names)
        out = np.zeros(m.n_axes, bool)
        wanted = [(j, names.index(f"dir_{a}")) for j, a in enumerate(m.axis_names)
                  if f"dir_{a}" in names]
        if not wanted or not self.terms:      # the base model has no dependence on direction
            return out
        q = ca.SX.sym("q", m.n_axes)
        p = ca.SX.sym("p", self.n_params)
        c = ca.SX.sym("c", self.n_context)
        tip, axis, _ = self.symbolic(q, p, c)
        expr = ca.vertcat(tip, axis)
        for j, k in wanted:
            out[j] = bool(ca.depends_on(expr, c[k]))
        return out

    def symbolic(self, q, p, c, errors: bool = True):
        """Tool-tip frame in the workpiece frame for SX inputs.

        Returns (tip (3,), axis (3,), R (3, 3)): tool tip position (mm), tool axis (unit), and the tool
        frame's rotation, all in the workpiece frame. ``errors=False`` gives the nominal chain, that of
        :func:`mtcomp.kinematics.symbolic_pose`.
        """
        m = self.machine
        if not errors:
            return kinematics.symbolic_pose(m, q)
        P = {name: p[i] for i, name in enumerate(self.param_names)}
        C = {name: c[i] for i, name in enumerate(self.context_names)}
        par = P.__getitem__
        # a tool longer than the reference tool by `shift` puts the ram `shift` higher for the same
        # tip (tool length compensation): its errors are those of its machine position q + shift
        ram = ram_axis(m)
        shift = C["tool_length"] - m.tool_length
        wp = (ca.SX.eye(3), ca.SX.zeros(3))
        for name in m.workpiece_chain:
            wp = compose(wp, self._axis_transform(name, q[m.index(name)], P, C))
        tl = (ca.SX.eye(3), ca.SX.zeros(3))
        for name in m.tool_chain:
            tl = compose(tl, self._axis_transform(name, q[m.index(name)], P, C,
                                                  shift if name == ram else None))
        # the tool axis tilted by the spindle tilt about the gauge point (0, 0, tool_length) above the
        # tip (fixed on the ram)
        tilt = ca.mtimes(rot(1, par("B0S")), rot(0, par("A0S")))
        tl = compose(tl, rot_about_point(tilt, ca.vertcat(0, 0, C["tool_length"])))
        tool2wp = compose(inverse(wp), tl)
        tip_local = ca.vertcat(0, 0, -par("TOOL_dL"))
        tip = ca.mtimes(tool2wp[0], tip_local) + tool2wp[1]
        for t in self.terms:
            off = t.tip_offset(m, q, C, P)
            if off is not None:
                tip = tip + off
        return tip, tool2wp[0][:, 2], tool2wp[0]

    def linear_parts(self, name, s, P, C):
        """The pieces of linear axis ``name``'s carriage transform at position s (SX), in the axis's own
        sense (tool relative to workpiece): (u, comps, centres, r) with u (3,) the axis direction tilted
        by the squareness errors, comps the six component errors (base plus every extension term's
        ``axis_errors``), centres {'A'|'B'|'C': (3,) shift of that rotation's centre (AbbeIRC)} and r
        (3,) the carriage's reference point. ``P``/``C`` map parameter/context names to symbols."""
        m = self.machine
        ax = m.axis(name)
        d = ax.direction_index
        par = P.__getitem__
        comps = linear_components(m, name, s, par, ca.SX(0))
        centres = {a: ca.SX.zeros(3) for a in ANGLE_LETTERS}
        for t in self.terms:
            for comp, e in t.axis_errors(m, ax, s, C, P, comps).items():
                comps[comp] = comps[comp] + e
            for a, o in t.abbe_centres(m, ax, s, C, P).items():
                centres[a] = centres[a] + o
        u = unit(d)
        if name == "Y":
            u = ca.mtimes(rot(2, par("C0Y")), u) if "C0Y" in P else u
        elif name == "Z":
            if "B0Z" in P or "A0Z" in P:
                u = ca.mtimes(ca.mtimes(rot(1, par("B0Z") if "B0Z" in P else 0),
                                        rot(0, par("A0Z") if "A0Z" in P else 0)), u)
        r = ca.vertcat(0, 0, m.tool_length) if ax.side == "tool" else ca.SX.zeros(3)
        return u, comps, centres, r

    def rotary_components(self, name, s, P, C) -> dict:
        """The component errors of rotary axis ``name`` at angle ``s`` (symbolic): the Fourier series
        of its positioning (``<comp>_0``, ``<comp>_c<k>`` cos(k s), ``<comp>_s<k>`` sin(k s);
        docs/parameters.md), its error motions' harmonics, and the extension terms' contributions
        (``P`` parameters and ``C`` context by name)."""
        ax = self.machine.axis(name)
        par = P.__getitem__
        own = positioning_component(name)
        e_pos = par(f"{own}_0")
        for k in range(1, ax.fourier_order + 1):
            e_pos = e_pos + par(f"{own}_c{k}") * ca.cos(k * s) + par(f"{own}_s{k}") * ca.sin(k * s)
        comps = {own: e_pos, **{comp: ca.SX(0) for comp in rotary_motion_names(name)}}
        if ax.error_motion_order > 0:
            for comp in rotary_motion_names(name):
                for c, e in motion_errors(comp, ax.error_motion_order, s, par).items():
                    comps[c] = comps[c] + e
        for t in self.terms:
            for comp, e in t.axis_errors(self.machine, ax, s, C, P, comps).items():
                comps[comp] = comps[comp] + e
        return comps

    def _axis_transform(self, name, s, P, C, shift=None):
        """One axis's carriage transform with its errors (the chain of the module notes); for the ram
        (:func:`ram_axis`) ``shift`` = L - L0, the tool's length less the reference tool's."""
        m = self.machine
        par = P.__getitem__
        ax = m.axis(name)
        d = ax.direction_index
        if ax.is_rotary:
            own = positioning_component(name)
            comps = self.rotary_components(name, s, P, C)
            offsets, tilts = rotary_location_names(name)
            point = ca.SX(np.asarray(ax.axis_point, dtype=float))
            others = [j for j in range(3) if j != d]
            for j, oname in zip(others, offsets):
                point[j] = point[j] + par(oname)
            # tilt of the line: about the first other direction, then the second (C: Ry(B0C) Rx(A0C))
            Rt = ca.mtimes(rot(others[1], par(tilts[1])), rot(others[0], par(tilts[0])))
            R_turn = ca.mtimes(ca.mtimes(Rt, rot(d, s + comps[own])), Rt.T)
            R_m = ca.SX.eye(3)
            for j in range(3):
                if j != d:
                    R_m = ca.mtimes(R_m, rot(j, comps[f"E{ANGLE_LETTERS[j]}{name}"]))
            delta_m = ca.vertcat(*[comps[f"E{TRANSLATION_LETTERS[j]}{name}"] for j in range(3)])
            R = ca.mtimes(R_m, R_turn)
            # Trans(P') Trans(delta_m) R Trans(-P')
            return (R, point + delta_m - ca.mtimes(R, point))

        # linear axis
        if shift is None:
            u, comps, centres, r = self.linear_parts(name, s, P, C)
            A = trans(s * u)
        else:
            # the ram at its machine position s + shift, then the tool's tip `shift` further down,
            # written in the frame of that tip so that the nominal chain is exact in floating point:
            # Trans(s u + shift (u - e_d)) and the angular errors about r + shift e_d
            u, comps, centres, r = self.linear_parts(name, s + shift, P, C)
            A = trans(s * u + shift * (u - unit(d)))
            r = r + shift * unit(d)
        A = compose(A, trans(ca.vertcat(*[comps[f"E{TRANSLATION_LETTERS[j]}{name}"] for j in range(3)])))
        for j, a in enumerate(ANGLE_LETTERS):
            A = compose(A, rot_about_point(rot(j, comps[f"E{a}{name}"]), r + centres[a]))
        if ax.side == "workpiece":
            A = inverse(A)
        return A

    # ----------------------------------------------------------------- CasADi functions
    @cached_property
    def _expressions(self):
        q, p, c = self._q, self._p, self._c
        tip, axis, _ = self.symbolic(q, p, c, errors=True)
        tip0, axis0, _ = self.symbolic(q, p, c, errors=False)
        dev = ca.vertcat(tip - tip0, axis - axis0)
        return {"tip": tip, "axis": axis, "tip0": tip0, "axis0": axis0, "dev": dev}

    def _function(self, name: str, outputs, out_names) -> ca.Function:
        """ca.Function ``name`` of (q, p, c) -> ``outputs(expressions)``, built once per model
        structure (:func:`mtcomp.models.function_cache.model_function`)."""
        def build():
            return ca.Function(name, [self._q, self._p, self._c], outputs(self._expressions),
                               ["q", "p", "c"], out_names)
        return model_function(self, name, build)

    @cached_property
    def pose_function(self) -> ca.Function:
        """(q, p, c) -> (tip (3,) mm, axis (3,)): actual tool tip and tool axis in the workpiece frame."""
        return self._function("pose", lambda e: [e["tip"], e["axis"]], ["tip", "axis"])

    @cached_property
    def nominal_function(self) -> ca.Function:
        """q -> (tip (3,) mm, axis (3,)): the nominal tool pose (:func:`mtcomp.kinematics.forward`)."""
        def build():
            e = self._expressions
            return ca.Function("nominal", [self._q], [e["tip0"], e["axis0"]], ["q"], ["tip", "axis"])
        return model_function(self, "nominal", build)

    @cached_property
    def deviation_function(self) -> ca.Function:
        """(q, p, c) -> dev (6,): tip deviation (mm) and tool-axis deviation (actual minus nominal)."""
        return self._function("deviation", lambda e: [e["dev"]], ["dev"])

    @cached_property
    def deviation_jacobian_function(self) -> ca.Function:
        """(q, p, c) -> (dev (6,), J_q (6, n_axes), J_p (6, n_params))."""
        return self._function("deviation_jac", lambda e: [e["dev"], ca.jacobian(e["dev"], self._q),
                                                          ca.jacobian(e["dev"], self._p)],
                              ["dev", "J_q", "J_p"])

    @cached_property
    def tip_pjacobian_function(self) -> ca.Function:
        """(q, p, c) -> J_p (3, n_params): the tip deviation's (mm) Jacobian with respect to the
        parameters, for the standard error of a correction."""
        return self._function("tip_pjac", lambda e: [ca.jacobian(e["dev"][:3], self._p)], ["J_p"])

    @cached_property
    def axis_pjacobian_function(self) -> ca.Function:
        """(q, p, c) -> J_p (3, n_params): the tool-axis deviation's Jacobian with respect to the
        parameters, for the standard error of an orientation correction (5-axis machines)."""
        return self._function("axis_pjac", lambda e: [ca.jacobian(e["dev"][3:], self._p)], ["J_p"])

    @cached_property
    def deviation_qjacobian_function(self) -> ca.Function:
        """(q, p, c) -> (dev (6,), J_q (6, n_axes)): what the planner needs per block."""
        return self._function("deviation_qjac", lambda e: [e["dev"], ca.jacobian(e["dev"], self._q)],
                              ["dev", "J_q"])

    def with_terms(self, *terms: Term) -> "ErrorModel":
        """A new model with extra terms appended (the base model is unchanged)."""
        return ErrorModel(self.machine, self.terms + tuple(terms))

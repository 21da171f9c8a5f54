"""The truth machine: an independent simulator of a CNC machine's actual tool pose (test-only).

See the package docstring (:mod:`truth`) for what is modelled, where each error acts and the signs.
Nothing here imports mtcomp; the machine TOML files are read with :mod:`tomllib`.
"""
from __future__ import annotations

import copy
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import profiles as P
from . import transforms as T
from .effects import UM, URAD, Effect

#: the built-in machine files of the repository (read as TOML, not through mtcomp)
MACHINES_DIR = Path(__file__).resolve().parents[2] / "mtcomp" / "machines"

AXIS_ORDER = "XYZABC"
UNIT = {"X": np.array([1.0, 0.0, 0.0]), "Y": np.array([0.0, 1.0, 0.0]), "Z": np.array([0.0, 0.0, 1.0])}
UNIT.update({"A": UNIT["X"], "B": UNIT["Y"], "C": UNIT["Z"]})

#: location errors of a rotary axis: (offset names, mm), (tilt names, rad), in the order used below
ROTARY_LOCATION = {
    "A": (("Y0A", "Z0A"), ("B0A", "C0A")),
    "B": (("X0B", "Z0B"), ("A0B", "C0B")),
    "C": (("X0C", "Y0C"), ("A0C", "B0C")),
}
SQUARENESS = ("C0Y", "B0Z", "A0Z")


def components_of(axis: str) -> tuple:
    """The six ISO 230-1 component errors of ``axis``: E<d><axis> for d in X Y Z A B C."""
    return tuple(f"E{d}{axis}" for d in AXIS_ORDER)


# ---------------------------------------------------------------------------------------- context
@dataclass
class Context:
    """Conditions of each row. Scalars or (N,) arrays; everything is broadcast to N rows.

    feed_mm_min : feed, mm/min (default 0: static reading, no feed effects).
    dirs : {axis letter: +1/-1} approach direction of each axis (absent axes: +1).
    t_s : time since the start of the campaign, s (default 0).
    temperatures : {name: degC} temperature channels (``temp_<name>_c`` in files).
    spindle_rpm : spindle speed, rpm (default 0; recorded only, thermal effects use their schedule).
    """

    feed_mm_min: object = 0.0
    dirs: dict = field(default_factory=dict)
    t_s: object = 0.0
    temperatures: dict = field(default_factory=dict)
    spindle_rpm: object = 0.0

    def resolve(self, n: int) -> "ResolvedContext":
        b = lambda v: np.broadcast_to(np.asarray(v, dtype=float), (n,)).copy()  # noqa: E731
        return ResolvedContext(n, b(self.feed_mm_min), {k.upper(): b(v) for k, v in self.dirs.items()},
                               b(self.t_s), {k: b(v) for k, v in self.temperatures.items()},
                               b(self.spindle_rpm))

    def subset(self, rows) -> "Context":
        """The context of ``rows`` (index array) of an N-row context."""
        pick = lambda v: v if np.ndim(v) == 0 else np.asarray(v)[rows]  # noqa: E731
        return Context(pick(self.feed_mm_min), {k: pick(v) for k, v in self.dirs.items()},
                       pick(self.t_s), {k: pick(v) for k, v in self.temperatures.items()},
                       pick(self.spindle_rpm))


@dataclass
class ResolvedContext:
    n: int
    feed: np.ndarray
    dirs: dict
    t_s: np.ndarray
    temperatures: dict
    spindle_rpm: np.ndarray

    def dir(self, axis: str) -> np.ndarray:
        return self.dirs.get(axis, np.ones(self.n))


def _as_context(context, n) -> ResolvedContext:
    if context is None:
        context = Context()
    if isinstance(context, dict):
        context = Context(**context)
    return context.resolve(n)


# ---------------------------------------------------------------------------------------- machine file
def read_machine_file(source) -> dict:
    """Topology, travel (linear mm, rotary deg), axis points and tool length from a machine TOML.

    ``source``: a TOML path, a built-in name (``xfyz``, ``cafxyz``, ``cbfxyz``) or a topology string
    (``XFYZ`` ...: the built-in file of that topology)."""
    src = str(source)
    path = Path(src)
    if not path.is_file():
        path = MACHINES_DIR / f"{src.lower()}.toml"
    if not path.is_file():
        raise FileNotFoundError(f"no machine file for {source!r} (looked in {MACHINES_DIR})")
    with open(path, "rb") as fh:
        return tomllib.load(fh)


def _parse_topology(topology: str):
    topology = topology.upper()
    if topology.count("F") != 1:
        raise ValueError(f"topology {topology!r} needs exactly one F")
    before, after = topology.split("F")
    workpiece_chain = tuple(reversed(before))      # bed -> workpiece
    tool_chain = tuple(after)                      # bed -> tool
    for a in tool_chain:
        if a in "ABC":
            raise NotImplementedError(f"rotary axis {a} on the tool side is not modelled")
    names = tuple(a for a in AXIS_ORDER if a in topology)
    return workpiece_chain, tool_chain, names


# ---------------------------------------------------------------------------------------- the machine
class TruthMachine:
    """An actual machine with known geometric errors and optional hidden effects.

    Internal units mm and rad everywhere: ``q`` (N, n_axes) lists the axes present in the order
    X Y Z A B C, linear in mm, rotary in **rad**. Errors are stored in mm and rad; the campaign
    writers convert to um, urad and deg.

    Attributes (plain data a test may set; see :mod:`truth` for their meaning):
    components : {axis: {component name: profile f(s) -> mm or rad}}
    pivots : {linear axis: (3,) mm} point about which the axis's angular errors act, fixed on its
        carriage: for a table axis in the table's frame; for a tool-side axis relative to the
        spindle gauge point at q = 0 with the reference tool (carriage coordinates
        ``pivot + (0, 0, reference_tool_mm)``), whatever tool is in the spindle.
    squareness : {"C0Y", "B0Z", "A0Z": rad}.
    location : {rotary location error name (X0C, Y0C, A0C, B0C ...): mm or rad}.
    spindle_tilt : (2,) rad, tilt of the tool axis about X then about Y of the Z carriage.
    effects : tuple of :class:`truth.effects.Effect`.
    reference_tool_mm : L0, the machine file's ``tool_length_mm``: the tool whose tip is at the
        origin with every axis at zero. Tool length compensation puts Z at its machine position
        ``z + L - L0`` for the tip of a tool of length L at z; the tip hangs ``L`` below the gauge
        point, fixed on the ram.
    """

    def __init__(self, source="xfyz", tool_length_mm: float | None = None):
        cfg = read_machine_file(source)
        self.name = cfg.get("name", str(source))
        self.topology = cfg["topology"].upper()
        self.workpiece_chain, self.tool_chain, self.axis_names = _parse_topology(self.topology)
        self.reference_tool_mm = float(cfg.get("tool_length_mm", 0.0))
        self.tool_length_mm = self.reference_tool_mm if tool_length_mm is None else float(tool_length_mm)
        axes = cfg.get("axes", {})
        self.travel = {}
        self.axis_point = {}
        for a in self.axis_names:
            spec = axes.get(a, {})
            if a in "XYZ":
                self.travel[a] = tuple(float(v) for v in spec.get("travel_mm", (-200.0, 200.0)))
            else:
                lo, hi = spec.get("travel_deg", (-360.0, 360.0))
                self.travel[a] = (np.radians(float(lo)), np.radians(float(hi)))
                self.axis_point[a] = np.asarray(spec.get("axis_point_mm", (0.0, 0.0, 0.0)), float)
        self.components = {a: {c: P.ZERO for c in components_of(a)} for a in self.axis_names}
        self.pivots = {a: np.zeros(3) for a in self.axis_names if a in "XYZ"}
        self.squareness = {k: 0.0 for k in SQUARENESS}
        self.location = {}
        for a in self.axis_names:
            if a in "ABC":
                for k in ROTARY_LOCATION[a][0] + ROTARY_LOCATION[a][1]:
                    self.location[k] = 0.0
        self.spindle_tilt = np.zeros(2)
        self.effects: tuple = ()

    # ---------------------------------------------------------------- construction
    @classmethod
    def zero(cls, source="xfyz", tool_length_mm=None) -> "TruthMachine":
        """A machine without any error (every profile zero, pivots at the carriage origins)."""
        return cls(source, tool_length_mm)

    @classmethod
    def random(cls, source, rng, *, effects=(), real_positioning: bool = True,
               error_motions: bool = True, scale: float = 1.0, tool_length_mm=None) -> "TruthMachine":
        """A machine with random, realistic geometric errors (all drawn from ``rng``).

        source : TOML path, built-in name or topology string. rng : ``np.random.Generator``.
        effects : hidden effects (:mod:`truth.effects`), default none.
        real_positioning : shape the positioning errors of X, Y, Z on the real ISO 230-2 runs
            ``ess_b02_<axis>.csv`` (mean per target, stretched over the travel) when present.
        error_motions : rotary error motions (radial, axial, tilt; harmonics 2..5) on/off.
        scale : multiplies every error magnitude.

        Magnitudes: positioning 5-30 um peak-to-peak over the travel plus a constant up to +-5 um,
        straightness 2-10 um p-p plus up to +-3 um, angular 5-30 urad p-p with a value of 3-20 urad
        (random sign) at s = 0 (a constant part; 0 clipped into the travel); squareness 10-60 urad;
        spindle tilt 3-30 urad per component; pivots as in :mod:`truth`; rotary offsets 5-40 um,
        tilts 10-60 urad, positioning error constant 5-30 urad and harmonics 1..5 of 3-15 urad,
        error motions 1-4 um and 2-8 urad.
        """
        m = cls(source, tool_length_mm)
        rnd = lambda lo, hi: float(rng.uniform(lo, hi) * rng.choice([-1.0, 1.0]))  # noqa: E731
        for a in m.axis_names:
            if a in "XYZ":
                lo, hi = m.travel[a]
                for c in components_of(a):
                    d = c[1]
                    if d == a:                     # positioning
                        rng_pp = rng.uniform(5.0, 30.0) * UM * scale
                        shape = P.real_positioning_shape(a, lo, hi) if real_positioning else None
                        if shape is not None:
                            base = P.normalised(P.Sum((P.Scaled(0.85, shape),
                                                       P.Scaled(0.15, P.random_shape(rng, lo, hi)))), lo, hi)
                        else:
                            base = P.random_shape(rng, lo, hi)
                        m.components[a][c] = P.Sum((P.Scaled(rng_pp, base),
                                                    P.Constant(rng.uniform(-5, 5) * UM * scale)))
                    elif d in "XYZ":               # straightness
                        m.components[a][c] = P.random_profile(rng, lo, hi, rng.uniform(2, 10) * UM * scale,
                                                              rng.uniform(-3, 3) * UM * scale)
                    else:                          # angular: 3-20 urad at s = 0, never through 0 there
                        shape = P.Scaled(rng.uniform(5, 30) * URAD * scale, P.random_shape(rng, lo, hi))
                        at0 = rnd(3, 20) * URAD * scale
                        shift = at0 - float(shape(np.array([0.0]))[0])
                        m.components[a][c] = P.Sum((shape, P.Constant(shift)))
                side = "workpiece" if a in m.workpiece_chain else "tool"
                if side == "workpiece":
                    # somewhere on the table, below or at its face, away from the workpiece origin
                    m.pivots[a] = np.array([rng.uniform(-250, 250), rng.uniform(-150, 150),
                                            rng.uniform(-120, -20)])
                elif a == m.tool_chain[-1]:        # relative to the gauge point, up the ram
                    m.pivots[a] = np.array([rng.uniform(-150, 150), rng.uniform(-150, 150),
                                            rng.uniform(20, 300)])
                else:
                    m.pivots[a] = np.array([rng.uniform(-150, 150), rng.uniform(-150, 150),
                                            rng.uniform(50, 400)])
            else:
                (o1, o2), (t1, t2) = ROTARY_LOCATION[a]
                m.location[o1] = rnd(5, 40) * UM * scale
                m.location[o2] = rnd(5, 40) * UM * scale
                m.location[t1] = rnd(10, 60) * URAD * scale
                m.location[t2] = rnd(10, 60) * URAD * scale
                pos = f"E{a}{a}"
                m.components[a][pos] = P.random_fourier(rng, rng.uniform(3, 15) * URAD * scale,
                                                        rnd(5, 30) * URAD * scale, orders=(1, 2, 3, 4, 5))
                if error_motions:
                    for c in components_of(a):
                        if c == pos:
                            continue
                        amp = (rng.uniform(1, 4) * UM if c[1] in "XYZ" else rng.uniform(2, 8) * URAD) * scale
                        m.components[a][c] = P.random_fourier(rng, amp, 0.0, orders=(2, 3, 4, 5))
        for k in SQUARENESS:
            if k == "C0Y" and not ("X" in m.axis_names and "Y" in m.axis_names):
                continue
            m.squareness[k] = rnd(10, 60) * URAD * scale
        m.spindle_tilt = np.array([rnd(3, 30), rnd(3, 30)]) * URAD * scale
        m.effects = tuple(effects)
        return m

    def copy(self) -> "TruthMachine":
        return copy.deepcopy(self)

    def with_effects(self, *effects: Effect) -> "TruthMachine":
        """A copy with ``effects`` added."""
        out = self.copy()
        out.effects = tuple(self.effects) + tuple(effects)
        return out

    # ---------------------------------------------------------------- helpers
    @property
    def n_axes(self) -> int:
        return len(self.axis_names)

    def index(self, axis: str) -> int:
        return self.axis_names.index(axis)

    def side(self, axis: str) -> str:
        return "workpiece" if axis in self.workpiece_chain else "tool"

    def q_from(self, x_mm=0.0, y_mm=0.0, z_mm=0.0, a_deg=0.0, b_deg=0.0, c_deg=0.0) -> np.ndarray:
        """(N, n_axes) or (n_axes,) q in mm and rad from file-unit positions (mm, deg; scalars or (N,)
        arrays); positions of axes the machine lacks must be 0."""
        given = {"X": x_mm, "Y": y_mm, "Z": z_mm, "A": a_deg, "B": b_deg, "C": c_deg}
        for a, v in given.items():
            if a not in self.axis_names and np.any(np.asarray(v) != 0):
                raise ValueError(f"machine {self.topology} has no axis {a}")
        cols = [np.asarray(given[a], float) if a in "XYZ" else np.radians(np.asarray(given[a], float))
                for a in self.axis_names]
        return np.stack(np.broadcast_arrays(*cols), axis=-1)

    def _q(self, q) -> np.ndarray:
        q = np.atleast_2d(np.asarray(q, dtype=float))
        if q.shape[1] != self.n_axes:
            raise ValueError(f"q has {q.shape[1]} columns; machine {self.topology} has axes "
                             f"{''.join(self.axis_names)}")
        return q

    def _tool(self, tool_length, n) -> np.ndarray:
        L = self.tool_length_mm if tool_length is None else tool_length
        return np.broadcast_to(np.asarray(L, dtype=float), (n,)).copy()

    def direction(self, axis: str) -> np.ndarray:
        """(3,) actual direction of travel of linear ``axis`` (squareness; X is the reference):
        u_Y = Rz(C0Y) e_y, u_Z = Ry(B0Z) Rx(A0Z) e_z."""
        if axis == "X":
            return UNIT["X"].copy()
        if axis == "Y":
            return T.rot_z(self.squareness["C0Y"])[0, :3, :3] @ UNIT["Y"]
        R = T.rot_y(self.squareness["B0Z"])[0, :3, :3] @ T.rot_x(self.squareness["A0Z"])[0, :3, :3]
        return R @ UNIT["Z"]

    def rotary_line(self, axis: str):
        """Actual line of rotary ``axis``: (point (3,) mm, unit direction (3,)).

        C: point = axis_point + (X0C, Y0C, 0), direction Ry(B0C) Rx(A0C) e_z;
        A: point = axis_point + (0, Y0A, Z0A), direction Rz(C0A) Ry(B0A) e_x;
        B: point = axis_point + (X0B, 0, Z0B), direction Rz(C0B) Rx(A0B) e_y.
        """
        (o1, o2), (t1, t2) = ROTARY_LOCATION[axis]
        point = self.axis_point[axis].copy()
        point["XYZ".index(o1[0])] += self.location[o1]
        point["XYZ".index(o2[0])] += self.location[o2]
        rot = {"A": T.rot_x, "B": T.rot_y, "C": T.rot_z}
        R = rot[t2[0]](self.location[t2])[0, :3, :3] @ rot[t1[0]](self.location[t1])[0, :3, :3]
        return point, R @ UNIT[axis]

    def component_values(self, axis, s, ctx: ResolvedContext) -> dict:
        """{component: (N,) mm or rad}: the profiles of ``axis`` at ``s`` plus every effect."""
        vals = {c: np.broadcast_to(f(s), s.shape).astype(float) for c, f in self.components[axis].items()}
        for e in self.effects:
            for c, v in e.component_delta(self, axis, s, ctx, dict(vals)).items():
                vals[c] = vals[c] + v
        return vals

    def _pivot(self, axis, s, ctx) -> np.ndarray:
        p = np.broadcast_to(self.pivots[axis], (len(s), 3)).copy()
        if self.side(axis) == "tool":
            # the carriage frames have their origin at the reference tool's tip at q = 0: a pivot
            # fixed on a slide is given relative to the gauge point there, L0 above that tip
            p[:, 2] += self.reference_tool_mm
        for e in self.effects:
            d = e.pivot_shift(self, axis, s, ctx)
            if d is not None:
                p = p + d
        return p

    # ---------------------------------------------------------------- one axis
    def _linear(self, axis, s, ctx, errors: bool) -> np.ndarray:
        """Carriage of linear ``axis`` in its parent frame (N, 4, 4).

        tool side :  Trans(s u) Trans(delta) [Trans(p) Rx(EA) Ry(EB) Rz(EC) Trans(-p)]
        table side:  Trans(-s u) [Trans(p) (Rx Ry Rz)^T Trans(-p)] Trans(-delta)
        with delta = (EX., EY., EZ.), p the pivot (carriage frame) and u the direction of travel.
        On the table side the table moves by -s u and the motion of the tool relative to the table
        is Trans(delta) [Trans(p) Rx Ry Rz Trans(-p)] Trans(s u): the component errors are those of the
        tool relative to the table, the angles turning about p fixed on the table.
        """
        table = self.side(axis) == "workpiece"
        if not errors:
            return T.translation((-s if table else s)[:, None] * UNIT[axis])
        u = self.direction(axis)
        v = self.component_values(axis, s, ctx)
        delta = np.stack([v[f"EX{axis}"], v[f"EY{axis}"], v[f"EZ{axis}"]], axis=1)
        R = T.rot_x(v[f"EA{axis}"]) @ T.rot_y(v[f"EB{axis}"]) @ T.rot_z(v[f"EC{axis}"])
        p = self._pivot(axis, s, ctx)
        if table:
            return (T.translation(-s[:, None] * u) @ T.about_point(p, np.transpose(R, (0, 2, 1)))
                    @ T.translation(-delta))
        return T.translation(s[:, None] * u) @ T.translation(delta) @ T.about_point(p, R)

    def _rotary(self, axis, theta, ctx, errors: bool) -> np.ndarray:
        """Table of rotary ``axis`` in its parent frame (N, 4, 4):
        Trans(m) [Trans(c) R_tilt Trans(-c)] [Trans(c) Rot(u, theta + E_pos) Trans(-c)]
        with (c, u) the actual line, m the translational error motions (along X, Y, Z of the parent)
        and R_tilt the two tilt error motions (for C: Rx(EAC) Ry(EBC); A: Ry(EBA) Rz(ECA);
        B: Rx(EAB) Rz(ECB)), both in the parent frame, not turning with the table."""
        if not errors:
            return T.about_point(self.axis_point[axis], T.rotation_about(UNIT[axis], theta))
        c, u = self.rotary_line(axis)
        v = self.component_values(axis, theta, ctx)
        m = np.stack([v[f"EX{axis}"], v[f"EY{axis}"], v[f"EZ{axis}"]], axis=1)
        rot = {"A": T.rot_x, "B": T.rot_y, "C": T.rot_z}
        tilt_letters = [d for d in "ABC" if d != axis]
        R_tilt = rot[tilt_letters[0]](v[f"E{tilt_letters[0]}{axis}"]) @ rot[tilt_letters[1]](
            v[f"E{tilt_letters[1]}{axis}"])
        turn = T.rotation_about(u, theta + v[f"E{axis}{axis}"])
        return T.translation(m) @ T.about_point(c, R_tilt) @ T.about_point(c, turn)

    def _spindle(self, q, L, ctx, errors: bool) -> np.ndarray:
        """Tool frame in the last tool-side carriage frame (the ram's, origin at the reference tool's
        tip at q = 0): Trans(d_thermal) Trans(g) Ry(tb) Rx(ta) Trans(-g) Trans(0, 0, L0 - L) with
        g = (0, 0, L0) the gauge point, fixed on the ram: the tool's tip hangs L below it, and the tool
        turns about it, so the tip moves by L times the tilt."""
        n = len(L)
        tip = np.zeros((n, 3))
        tip[:, 2] = self._ram_shift(L) * -1.0
        if not errors:
            return T.translation(tip)
        g = np.zeros((n, 3))
        g[:, 2] = self.reference_tool_mm if self._ram() else L
        Rt = T.rot_y(np.full(n, self.spindle_tilt[1])) @ T.rot_x(np.full(n, self.spindle_tilt[0]))
        out = T.about_point(g, Rt) @ T.translation(tip)
        for e in self.effects:
            d = e.spindle_offset(self, q, ctx)
            if d is not None:
                out = T.translation(d) @ out
        return out

    def _ram(self) -> bool:
        """True when Z carries the spindle (the last tool-side axis): the axis tool length
        compensation moves."""
        return bool(self.tool_chain) and self.tool_chain[-1] == "Z"

    def _ram_shift(self, L) -> np.ndarray:
        """(N,) mm: L - L0, how much higher the ram stands for the same tip (0 without a ram)."""
        return (L - self.reference_tool_mm) if self._ram() else np.zeros_like(L)

    def _axis_argument(self, axis, q, L):
        """The machine position of ``axis`` for the commanded ``q``: the ram's is z + L - L0."""
        s = q[:, self.index(axis)].copy()
        if axis == "Z" and self._ram():
            s = s + self._ram_shift(L)
        return s

    # ---------------------------------------------------------------- chains
    def wp2bed(self, q, context=None, errors: bool = True, tool_length=None) -> np.ndarray:
        """(N, 4, 4) pose of the workpiece frame in the bed frame."""
        q = self._q(q)
        n = len(q)
        ctx = _as_context(context, n)
        L = self._tool(tool_length, n)
        out = T.identity(n)
        for a in self.workpiece_chain:
            s = self._axis_argument(a, q, L)
            out = out @ (self._linear(a, s, ctx, errors) if a in "XYZ" else self._rotary(a, s, ctx, errors))
        return out

    def tool2bed(self, q, tool_length=None, context=None, errors: bool = True) -> np.ndarray:
        """(N, 4, 4) pose of the tool frame (origin at the tip, +Z towards the spindle) in the bed."""
        q = self._q(q)
        n = len(q)
        ctx = _as_context(context, n)
        L = self._tool(tool_length, n)
        out = T.identity(n)
        for a in self.tool_chain:
            out = out @ self._linear(a, self._axis_argument(a, q, L), ctx, errors)
        return out @ self._spindle(q, L, ctx, errors)

    def tool2wp(self, q, tool_length=None, context=None, errors: bool = True) -> np.ndarray:
        """(N, 4, 4) pose of the tool frame in the workpiece frame: wp2bed^-1 tool2bed."""
        return (T.inverse(self.wp2bed(q, context, errors, tool_length))
                @ self.tool2bed(q, tool_length, context, errors))

    # ---------------------------------------------------------------- core API
    def true_pose(self, q, tool_length=None, context=None):
        """Actual tool tip (N, 3) mm and tool axis (N, 3) unit, in the workpiece frame.

        q : (N, n_axes) or (n_axes,), mm and rad. tool_length : mm, scalar or (N,) (None: the
        machine's). context : :class:`Context`, a dict of its fields, or None."""
        M = self.tool2wp(q, tool_length, context, True)
        return M[:, :3, 3].copy(), M[:, :3, 2].copy()

    def nominal_pose(self, q, tool_length=None):
        """Nominal tool tip (N, 3) mm and tool axis (N, 3) in the workpiece frame."""
        M = self.tool2wp(q, tool_length, None, False)
        return M[:, :3, 3].copy(), M[:, :3, 2].copy()

    def true_deviation(self, q, tool_length=None, context=None):
        """Actual minus nominal, workpiece frame: tip (N, 3) mm and tool axis (N, 3) (unit vectors)."""
        tip, ax = self.true_pose(q, tool_length, context)
        tip0, ax0 = self.nominal_pose(q, tool_length)
        return tip - tip0, ax - ax0

    def point_deviation(self, q, offset_mm, tool_length=None, context=None):
        """Deviation (N, 3) mm, workpiece frame, of a point fixed to the tool at ``offset_mm`` (3,) or
        (N, 3) from the tool tip, the offset expressed in the workpiece frame at the nominal pose
        (the optic of a laser set-up, the tool ball of a ball bar)."""
        M = self.tool2wp(q, tool_length, context, True)
        M0 = self.tool2wp(q, tool_length, None, False)
        o = np.broadcast_to(np.asarray(offset_mm, float), (len(M), 3))
        o_tool = np.einsum("nji,nj->ni", M0[:, :3, :3], o)       # R0^T o
        return T.apply(M, o_tool) - (M0[:, :3, 3] + o)

    def point_position(self, q, offset_mm, tool_length=None, context=None, errors=True):
        """Position (N, 3) mm, workpiece frame, of the point fixed to the tool at ``offset_mm``
        (workpiece frame at the nominal pose) from the tip; nominal with ``errors=False``."""
        M = self.tool2wp(q, tool_length, context, errors)
        M0 = self.tool2wp(q, tool_length, None, False)
        o = np.broadcast_to(np.asarray(offset_mm, float), (len(M), 3))
        return T.apply(M, np.einsum("nji,nj->ni", M0[:, :3, :3], o))

    def relative_rotation(self, q, tool_length=None, context=None):
        """(N, 3) rad: rotation vector of R R0^T, the rotation of the tool relative to the workpiece
        (actual against nominal), components along the workpiece X, Y, Z."""
        M = self.tool2wp(q, tool_length, context, True)
        M0 = self.tool2wp(q, tool_length, None, False)
        return T.small_rotation_vector(M[:, :3, :3] @ np.transpose(M0[:, :3, :3], (0, 2, 1)))

    def laser_reading(self, axis, component, q, optic_mm=(0.0, 0.0, 0.0), tool_length=None, context=None):
        """(N,) ideal laser reading (mm or rad; no set-up, no noise) of ``component`` in a run of ``axis``.

        Translational E<d>.: the d-component of the deviation of the measured point (tool tip plus
        ``optic_mm``, see :meth:`point_deviation`). Angular E<d>.: the d-component of
        :meth:`relative_rotation` (tool relative to workpiece). In a run of a workpiece-side rotary
        ``axis`` both are negated: the reading is the motion of the table relative to the tool
        (ECC = actual minus commanded angle, EXC = the table's radial displacement), as ISO 230-2 and
        docs/measurements.md report it.
        """
        k = "XYZABC".index(component[1]) % 3
        if component[1] in "XYZ":
            v = self.point_deviation(q, optic_mm, tool_length, context)[:, k]
        else:
            v = self.relative_rotation(q, tool_length, context)[:, k]
        if axis in "ABC" and self.side(axis) == "workpiece":
            v = -v
        return v

    def ballbar_length(self, q, table_ball_mm, tool_ball_mm=(0.0, 0.0, 0.0), tool_length=None,
                       context=None) -> np.ndarray:
        """(N,) mm actual distance between the table ball (fixed in the workpiece frame at
        ``table_ball_mm``) and the tool ball (fixed to the tool at ``tool_ball_mm`` from the tip,
        workpiece frame at the nominal pose)."""
        p = self.point_position(q, tool_ball_mm, tool_length, context, True)
        return np.linalg.norm(p - np.asarray(table_ball_mm, float), axis=-1)

    def cut(self, q_commanded, tool_length=None, context=None):
        """Actual tool tip (N, 3) mm (workpiece frame) and tool axis (N, 3) for the commanded axis
        positions of a program (e.g. a compensated one): :meth:`true_pose` by another name."""
        return self.true_pose(q_commanded, tool_length, context)


# ---------------------------------------------------------------------------------------- form error
@dataclass(frozen=True)
class FormError:
    """Residual of actual against nominal points after the best rigid motion (least squares).

    residual_um : (N, 3); rms_um : sqrt(mean |r|^2); max_um : max |r|; rotation (3, 3) and
    translation_mm (3,) of the best fit (actual ~ R nominal + t)."""

    residual_um: np.ndarray
    rms_um: float
    max_um: float
    rotation: np.ndarray
    translation_mm: np.ndarray


def form_error(actual_points, nominal_points) -> FormError:
    """Form error of ``actual_points`` (N, 3) mm against ``nominal_points`` (N, 3) mm: Kabsch fit of a
    rigid motion nominal -> actual, residual actual - (R nominal + t) in um."""
    A = np.asarray(actual_points, float)
    B = np.asarray(nominal_points, float)
    ca, cb = A.mean(axis=0), B.mean(axis=0)
    H = (B - cb).T @ (A - ca)
    U, _, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(Vt.T @ U.T))
    R = Vt.T @ np.diag([1.0, 1.0, d]) @ U.T
    t = ca - R @ cb
    r = (A - (B @ R.T + t)) * 1e3
    norms = np.linalg.norm(r, axis=1)
    return FormError(r, float(np.sqrt(np.mean(norms ** 2))), float(norms.max()), R, t)

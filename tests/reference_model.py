"""A plain numpy reference of the error model: the test oracle for the CasADi model.

Written independently of :mod:`mtcomp.models.chain` (4x4 homogeneous matrices, scipy rotations,
parameters looked up by name, one pose at a time), like Pinocchio's numeric model is the oracle of
its CasADi model. It covers the base model and the extension terms Backlash, PeriodicError,
FeedOffset and AbbeIRC. Slow by design; use it only in tests.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy.integrate import quad
from scipy.interpolate import BSpline
from scipy.spatial.transform import Rotation

from mtcomp.machine import Machine

XYZ = "XYZ"
ABC = "ABC"


def _htm(R=None, t=None):
    T = np.eye(4)
    if R is not None:
        T[:3, :3] = R
    if t is not None:
        T[:3, 3] = t
    return T


def _rot(index, angle):
    v = np.zeros(3)
    v[index] = angle
    return Rotation.from_rotvec(v).as_matrix()


def reference_tool_pose(machine: Machine, params: dict, q, ctx: dict, terms=()):
    """Actual tool tip (3,) and tool axis (3,) in the workpiece frame for one pose.

    params : name -> internal value (missing names count as 0).
    ctx : context name -> value ('feed' mm/min, 'tool_length' mm, 'dir_X' ...).
    terms : extension term objects (Backlash, PeriodicError, FeedOffset, AbbeIRC are supported).
    """
    g = lambda name: float(params.get(name, 0.0))  # noqa: E731
    feed_m = ctx.get("feed", 0.0) / 1000.0
    # tool length compensation: with a tool dL longer than the machine's reference tool, the ram (Z,
    # when no rotary axis is on the tool side) stands dL higher for the same tip, and the tip hangs
    # dL below the reference tool's tip (the origin of the ram's frame); the ram is Z when it carries
    # the spindle (the last axis of the tool chain)
    ram = bool(machine.tool_chain) and machine.tool_chain[-1] == "Z"
    dL = ctx.get("tool_length", machine.tool_length) - machine.tool_length if ram else 0.0
    T_wp = np.eye(4)
    T_tool = np.eye(4)
    for chain, side in ((machine.workpiece_chain, "workpiece"), (machine.tool_chain, "tool")):
        for name in chain:
            ax = machine.axis(name)
            s = float(q[machine.index(name)]) + (dL if name == "Z" else 0.0)
            if ax.is_rotary:
                A = _rotary(machine, ax, s, g, ctx, terms)
            else:
                A = _linear(machine, ax, s, g, ctx, feed_m, terms)
            if side == "workpiece":
                T_wp = T_wp @ A
            else:
                T_tool = T_tool @ A
    # spindle tilt: the tool turns about the gauge point (fixed on the ram, the tool's length above its
    # tip), about X by A0S then about Y by B0S
    gauge = np.array([0.0, 0.0, ctx.get("tool_length", machine.tool_length) - dL])
    tilt = Rotation.from_euler("YX", [g("B0S"), g("A0S")]).as_matrix()
    T_tool = T_tool @ _htm(t=gauge) @ _htm(R=tilt) @ _htm(t=-gauge)
    T = np.linalg.inv(T_wp) @ T_tool
    tip = (T @ np.array([0.0, 0.0, -dL - g("TOOL_dL"), 1.0]))[:3]
    return tip, T[:3, 2]


@lru_cache(maxsize=64)
def _spline_pieces(lo, hi, n, k):
    """scipy B-spline basis elements on n equal intervals of [lo, hi] (degree k), with the mean and the
    least-squares slope of each over [lo, hi] from adaptive quadrature."""
    h = (hi - lo) / n
    knots = lo + h * np.arange(-k, n + k + 1)
    elems = [BSpline.basis_element(knots[j:j + k + 2], extrapolate=False) for j in range(n + k)]
    mid, length = 0.5 * (lo + hi), hi - lo
    brk = list(lo + h * np.arange(1, n))
    f = [lambda x, e=e: float(np.nan_to_num(e(x))) for e in elems]
    edges = [lo] + brk + [hi]

    def integral(g):
        # piece by piece: each piece of a B-spline is a polynomial, smooth for quad
        return sum(quad(g, a, b, epsabs=1e-14, epsrel=1e-12)[0] for a, b in zip(edges[:-1], edges[1:]))
    mean = [integral(fj) / length for fj in f]
    sxx = length ** 3 / 12.0
    slope = [integral(lambda x, fj=fj: fj(x) * (x - mid)) / sxx for fj in f]
    return f, mean, slope, mid


def _spline_component(machine, ax, comp, s, g):
    """E(s) of a B-spline component: sum over the parameters present of c_j (B_j - mean_j [- line_j]),
    at s clipped to the spline range. Which straightness drops its slope: the one whose squareness
    the machine has (EXY: C0Y, EXZ: B0Z, EYZ: A0Z)."""
    lo, hi = ax.spline_range if ax.spline_range is not None else ax.travel
    n = ax.spline_intervals or 8
    f, mean, slope, mid = _spline_pieces(float(lo), float(hi), int(n), int(ax.degree))
    sc = min(max(s, lo), hi)
    names = set(machine.axis_names)
    carried = {"EXY": {"X", "Y"}, "EXZ": {"X", "Z"}, "EYZ": {"Y", "Z"}}.get(comp, None)
    carried = carried is not None and carried <= names
    total = 0.0
    for j in range(len(f)):
        v = f[j](sc) - mean[j] - (slope[j] * (sc - mid) if carried else 0.0)
        total += g(f"{comp}_b{j}") * v
    return total


def _linear(machine, ax, s, g, ctx, feed_m, terms):
    L = ax.name
    sm = s / 1000.0
    err = {}
    for d in XYZ + ABC:
        comp = f"E{d}{L}"
        if ax.basis == "bspline":
            err[comp] = _spline_component(machine, ax, comp, s, g)
        else:
            err[comp] = sum(g(f"{comp}_{k}") * sm ** k for k in range(1, ax.degree + 1))
    centres = {a: np.zeros(3) for a in ABC}
    for t in terms:
        kind = type(t).__name__
        if getattr(t, "axis", None) != L:
            continue
        if kind == "Backlash":
            err[f"E{L}{L}"] += 0.5 * g(f"BL_{L}") * ctx.get(f"dir_{L}", 0.0)
        elif kind == "PeriodicError":
            w = 2 * np.pi / t.period_mm
            err[f"E{L}{L}"] += g(f"PER_{L}_c") * np.cos(w * s) + g(f"PER_{L}_s") * np.sin(w * s)
        elif kind == "FeedOffset":
            err[f"E{L}{L}"] += g(f"FOFF_{L}") * feed_m * (ctx.get(f"dir_{L}", 0.0) if t.signed else 1.0)
        elif kind == "AbbeIRC":
            for a in t.angles:
                for c in XYZ:
                    if c == XYZ[ABC.index(a)]:
                        continue
                    base = f"IRC_{a}{L}_{c.lower()}"
                    centres[a][XYZ.index(c)] += (g(base + "0") * t.static + g(base + "_s") * sm * t.position
                                                 + g(base + "_f") * feed_m * t.feed)
                if t.angle_gain:
                    err[f"E{a}{L}"] *= 1.0 + g(f"AG_{a}{L}") * feed_m
                if getattr(t, "angle_feed", False):
                    err[f"E{a}{L}"] += g(f"AF_{a}{L}") * feed_m
        else:
            raise NotImplementedError(kind)
    # axis direction with squareness
    u = np.zeros(3)
    u[ax.direction_index] = 1.0
    if L == "Y":
        u = _rot(2, g("C0Y")) @ u
    elif L == "Z":
        u = _rot(1, g("B0Z")) @ _rot(0, g("A0Z")) @ u
    # a tool-side carriage turns about a point fixed on it: the gauge point at q = 0 with the machine's
    # reference tool, whatever tool is in the spindle
    r = np.array([0.0, 0.0, machine.tool_length]) if ax.side == "tool" else np.zeros(3)
    A = _htm(t=s * u) @ _htm(t=[err[f"E{d}{L}"] for d in XYZ])
    for j, a in enumerate(ABC):
        c = r + centres[a]
        A = A @ _htm(t=c) @ _htm(R=_rot(j, err[f"E{a}{L}"])) @ _htm(t=-c)
    return np.linalg.inv(A) if ax.side == "workpiece" else A


def _counter_rotating_first_harmonic(motion, d, R_, theta, g):
    """The first harmonic of a radial (tilt) pair is a vector in the plane normal to the axis that turns
    by -theta while the axis turns by +theta: v(theta) = Rot_d(-theta) v0, whose first direction in
    X, Y, Z order (the leader) reads <leader>_c1 cos + <leader>_s1 sin; the leader's c1/s1 give v0 (the
    old model's partner _c1/_s1 are ignored: not parameters any more)."""
    others = [j for j in range(3) if j != d]
    for letters in (XYZ, ABC):
        lead, part = (f"E{letters[j]}{R_}" for j in others)
        for comp in (lead, part):
            motion[comp] -= g(f"{comp}_c1") * np.cos(theta) + g(f"{comp}_s1") * np.sin(theta)
        # v0 = c1 e_lead + x e_part, with the leader at theta = pi/2 equal to s1
        x = g(f"{lead}_s1") / _rot(d, -np.pi / 2)[others[0], others[1]]
        v = _rot(d, -theta) @ (g(f"{lead}_c1") * np.eye(3)[others[0]] + x * np.eye(3)[others[1]])
        motion[lead] += v[others[0]]
        motion[part] += v[others[1]]


def _rotary(machine, ax, theta, g, ctx, terms):
    R_ = ax.name
    d = ax.direction_index
    own = f"E{ABC[d]}{R_}"
    e_own = g(f"{own}_0") + sum(g(f"{own}_c{k}") * np.cos(k * theta) + g(f"{own}_s{k}") * np.sin(k * theta)
                                for k in range(1, ax.fourier_order + 1))
    motion = {}
    for comp in [f"E{x}{R_}" for x in XYZ + ABC if f"E{x}{R_}" != own]:
        motion[comp] = sum(g(f"{comp}_c{k}") * np.cos(k * theta) + g(f"{comp}_s{k}") * np.sin(k * theta)
                           for k in range(1, 9))
    _counter_rotating_first_harmonic(motion, d, R_, theta, g)
    for t in terms:
        if type(t).__name__ == "Backlash" and t.axis == R_:
            e_own += 0.5 * g(f"BL_{R_}") * ctx.get(f"dir_{R_}", 0.0)
    others = [j for j in range(3) if j != d]
    point = np.array(ax.axis_point, dtype=float)
    point[others[0]] += g(f"{XYZ[others[0]]}0{R_}")
    point[others[1]] += g(f"{XYZ[others[1]]}0{R_}")
    tilt = _rot(others[1], g(f"{ABC[others[1]]}0{R_}")) @ _rot(others[0], g(f"{ABC[others[0]]}0{R_}"))
    axis_line = tilt[:, d]
    turn = Rotation.from_rotvec(axis_line * (theta + e_own)).as_matrix()
    wobble = np.eye(3)
    for j in range(3):
        if j != d:
            wobble = wobble @ _rot(j, motion[f"E{ABC[j]}{R_}"])
    shift = np.array([motion.get(f"E{x}{R_}", 0.0) for x in XYZ])
    return _htm(t=point) @ _htm(t=shift) @ _htm(R=wobble @ turn) @ _htm(t=-point)


def reference_deviation(machine: Machine, params: dict, q, ctx: dict, terms=()) -> np.ndarray:
    """(6,): actual minus nominal tool tip (mm) and tool axis, workpiece frame."""
    tip, axis = reference_tool_pose(machine, params, q, ctx, terms)
    tip0, axis0 = reference_tool_pose(machine, {}, q, {"tool_length": ctx.get("tool_length",
                                                                               machine.tool_length)})
    return np.concatenate([tip - tip0, axis - axis0])

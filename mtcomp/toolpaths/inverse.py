"""Nominal inverse kinematics: tool-tip position and tool axis in the workpiece frame -> axis positions.

For any machine of :mod:`mtcomp.machine` whose rotary axes (at most two) all sit on the workpiece
side and whose tool side carries only linear axes, with X, Y and Z present (XFYZ, CAFXYZ, CBFXYZ,
...). The conventions are those of :mod:`mtcomp.kinematics` exactly; the tests check
``forward(inverse(p, k)) == (p, k)`` to 1e-9 mm.

Orientation. With the workpiece chain R = R1(t1) R2(t2) (R1 nearest the bed) and the tool fixed
along +Z of the bed, the tool axis in the workpiece frame is ``k = R^T e_z``. So ``R2(t2) k =
R1(-t1) e_z = z``: the vector z has ``u1.z = u1.e_z`` and ``u2.z = u2.k`` and unit length, which
for the perpendicular axis directions u1, u2 gives two solutions ``z = a u1 + b u2 +- g (u1 x u2)``
(Paden-Kahan subproblem 2); each angle then follows from a rotation of one vector onto another
about a known axis (subproblem 1).

Choices made explicit:

* branch : +1 takes, of the two solutions, the one with the larger angle of the bed-side rotary
  axis (for CAFXYZ/CBFXYZ: the positive tilt A or B), -1 the smaller one.
* singular poses : when the tool axis is parallel to the workpiece-side rotary axis (tilt 0 on
  CAFXYZ: k along C), that axis's angle is free; it keeps its previous value (the C table does not
  turn). The same holds for the bed-side axis if +Z is parallel to it.
* rotary wrap : each angle is taken as the value ``t + 2 pi m`` within travel closest to the
  previous pose's (the first pose: ``previous``, default all zero).

Units: mm and rad; shapes (N, 3) in, (N, n_axes) out in ``machine.axis_names`` order.
"""
from __future__ import annotations

import math

import numpy as np

from ..errors import InputError
from ..kinematics import forward
from ..machine import Machine

#: |sin| of the angle between a vector and a rotation axis below which the rotation is taken as free
SINGULAR_EPS = 1e-12
#: largest mismatch (of unit vectors) tolerated between a requested tool axis and a reachable one
ORIENTATION_TOL = 1e-9


def check_invertible(machine: Machine) -> None:
    """Raise InputError unless :func:`inverse_kinematics` handles this machine."""
    rot_tool = [n for n in machine.tool_chain if n in "ABC"]
    if rot_tool:
        raise InputError(f"machine {machine.name}: inverse kinematics needs every rotary axis on the "
                         f"workpiece side, {rot_tool[0]} is on the tool side")
    if len(machine.rotary_axes) > 2:
        raise InputError(f"machine {machine.name}: at most two rotary axes are supported")
    if any(c not in machine.axis_names for c in "XYZ"):
        raise InputError(f"machine {machine.name}: inverse kinematics needs X, Y and Z axes")


def _rotate_onto(u: np.ndarray, p: np.ndarray, q: np.ndarray):
    """Angle (N,) rotating p onto q about unit u (subproblem 1), and (N,) bool: free (p or q along u)."""
    pp = p - np.outer(p @ u, u)
    qq = q - np.outer(q @ u, u)
    s = np.einsum("j,ij->i", u, np.cross(pp, qq))
    c = np.einsum("ij,ij->i", pp, qq)
    free = (np.linalg.norm(pp, axis=1) < SINGULAR_EPS) | (np.linalg.norm(qq, axis=1) < SINGULAR_EPS)
    return np.arctan2(s, c), free


def rotary_angles(machine: Machine, tool_axis: np.ndarray, branch: int = 1):
    """Raw rotary angles for unit tool axes k (N, 3) in the workpiece frame.

    Returns (angles (N, n_rot) rad in (-pi, pi], free (N, n_rot) bool), the rotary axes listed
    bed-side first. Raises InputError for an orientation the machine cannot reach.
    """
    check_invertible(machine)
    k = np.atleast_2d(np.asarray(tool_axis, dtype=float))
    k = k / np.linalg.norm(k, axis=1, keepdims=True)
    n = k.shape[0]
    rot = [name for name in machine.workpiece_chain if name in "ABC"]
    ez = np.broadcast_to(np.array([0.0, 0.0, 1.0]), (n, 3))
    if not rot:
        bad = np.linalg.norm(k - ez, axis=1) > ORIENTATION_TOL
        if np.any(bad):
            raise InputError(f"pose {int(np.argmax(bad))}: a machine without rotary axes only "
                             "reaches the tool axis +Z")
        return np.zeros((n, 0)), np.zeros((n, 0), bool)
    if len(rot) == 1:
        u = machine.axis(rot[0]).direction
        t, free = _rotate_onto(u, k, ez)
        bad = np.abs(k @ u - u[2]) > ORIENTATION_TOL
        if np.any(bad):
            raise InputError(f"pose {int(np.argmax(bad))}: tool axis not reachable with the single "
                             f"rotary axis {rot[0]}")
        return t[:, None], free[:, None]
    u1, u2 = machine.axis(rot[0]).direction, machine.axis(rot[1]).direction
    u3 = np.cross(u1, u2)
    a = u1[2]
    b = k @ u2
    # 1 - a^2 - b^2, written without the cancellation of 1 - b^2 when k is nearly along u2
    k_perp = k - np.outer(b, u2)
    g2 = np.einsum("ij,ij->i", k_perp, k_perp) - a * a
    if np.any(g2 < -2 * ORIENTATION_TOL):
        i = int(np.argmin(g2))
        raise InputError(f"pose {i}: tool axis {np.round(k[i], 6).tolist()} not reachable with "
                         f"{rot[0]} and {rot[1]}")
    g = np.sqrt(np.clip(g2, 0.0, None))
    sols = []
    for sign in (1.0, -1.0):
        z = a * u1[None, :] + b[:, None] * u2[None, :] + (sign * g)[:, None] * u3[None, :]
        t1, free1 = _rotate_onto(u1, ez, z)
        t1 = -t1
        t2, free2 = _rotate_onto(u2, k, z)
        sols.append((t1, t2, free1, free2))
    pick_first = (sols[0][0] >= sols[1][0]) if branch >= 0 else (sols[0][0] <= sols[1][0])
    out = np.where(pick_first[:, None], np.stack(sols[0][:2], axis=1), np.stack(sols[1][:2], axis=1))
    free = np.where(pick_first[:, None], np.stack(sols[0][2:], axis=1), np.stack(sols[1][2:], axis=1))
    return out, free


def _wrap_near(t: float, prev: float, lo: float, hi: float, name: str, i: int) -> float:
    """t + 2 pi m within [lo, hi] closest to prev."""
    two_pi = 2.0 * math.pi
    m0 = round((prev - t) / two_pi)
    best = None
    for m in (m0 - 1, m0, m0 + 1):
        v = t + two_pi * m
        if lo - 1e-12 <= v <= hi + 1e-12 and (best is None or abs(v - prev) < abs(best - prev)):
            best = v
    if best is None:
        for m in range(-4, 5):   # nothing next to prev: any representative within travel
            v = t + two_pi * m
            if lo - 1e-12 <= v <= hi + 1e-12 and (best is None or abs(v - prev) < abs(best - prev)):
                best = v
    if best is None:
        raise InputError(f"pose {i}: axis {name} would need {math.degrees(t):.4f} deg, outside its "
                         f"travel {math.degrees(lo):g}..{math.degrees(hi):g} deg")
    return best


def inverse_kinematics(machine: Machine, tip: np.ndarray, tool_axis: np.ndarray, branch: int = 1,
                       previous: np.ndarray | None = None) -> np.ndarray:
    """Axis positions q (N, n_axes), mm and rad, that put the tool tip at ``tip`` (N, 3) mm with the
    tool axis ``tool_axis`` (N, 3) unit, tip towards spindle, both in the workpiece frame.

    Poses are solved in order: wrap and free angles follow the previous pose (see module notes);
    ``previous`` (n_axes,) is the pose before the first (default zeros). Linear travel is not
    checked here (the planner checks it); rotary travel is, since it decides the wrap.
    """
    check_invertible(machine)
    tip = np.atleast_2d(np.asarray(tip, dtype=float))
    n = tip.shape[0]
    angles, free = rotary_angles(machine, tool_axis, branch)
    rot = [name for name in machine.workpiece_chain if name in "ABC"]
    q = np.zeros((n, machine.n_axes))
    prev = np.zeros(machine.n_axes) if previous is None else np.asarray(previous, float).copy()
    for j, name in enumerate(rot):
        col = machine.index(name)
        lo, hi = machine.axis(name).travel
        p = prev[col]
        for i in range(n):
            p = p if free[i, j] else _wrap_near(angles[i, j], p, lo, hi, name, i)
            q[i, col] = p
    # with the rotary angles fixed, the tip is affine in the linear axes: p(s) = p0 + M s
    lin = [machine.index(c) for c in "XYZ"]
    probe = np.repeat(q[:, None, :], 4, axis=1)
    for j, col in enumerate(lin):
        probe[:, j + 1, col] = 1.0
    pts, _ = forward(machine, probe.reshape(-1, machine.n_axes))
    pts = pts.reshape(n, 4, 3)
    M = np.transpose(pts[:, 1:, :] - pts[:, :1, :], (0, 2, 1))
    s = np.linalg.solve(M, (tip - pts[:, 0, :])[:, :, None])[:, :, 0]
    q[:, lin] = s
    return q


def fit_rotary_travel(machine: Machine, q: np.ndarray) -> np.ndarray:
    """Make each rotary column of a pose sequence q (N, n_axes) continuous (no 360 deg jumps) and
    shift it by whole turns so that the whole sequence lies within travel, as near zero as possible.

    The pose-by-pose wrap of :func:`inverse_kinematics` may jump when the next value would leave the
    travel; a contour wants one continuous rotation planned as a whole. Raises InputError when the
    rotation spans more than the travel.
    """
    q = np.array(q, dtype=float)
    two_pi = 2.0 * math.pi
    for ax in machine.rotary_axes:
        j = machine.index(ax.name)
        col = np.unwrap(q[:, j])
        lo, hi = ax.travel
        m_lo = math.ceil((lo - col.min()) / two_pi - 1e-12)
        m_hi = math.floor((hi - col.max()) / two_pi + 1e-12)
        if m_lo > m_hi:
            raise InputError(f"axis {ax.name} would turn through {math.degrees(np.ptp(col)):.1f} deg, "
                             f"more than its travel {math.degrees(lo):g}..{math.degrees(hi):g} deg "
                             "allows in one piece")
        ms = np.arange(m_lo, m_hi + 1)
        m = ms[np.argmin(np.abs(col.mean() + two_pi * ms))]
        q[:, j] = col + two_pi * m
    return q

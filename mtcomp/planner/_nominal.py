"""Nominal (error-free) tool pose and its Jacobian with respect to the axis positions, in numpy.

The planner needs the Jacobian of the *actual* tool pose: the nominal Jacobian computed here plus the
error model's ``J_q`` (``deviation_qjacobian_function``). The nominal part is exact and vectorised
over poses; it follows the conventions of :mod:`mtcomp.kinematics` (one axis = one rigid motion
``A_j(q_j) = exp(G_j q_j)`` with a constant generator ``G_j``): a test checks it against
:func:`mtcomp.kinematics.forward` and finite differences.

With ``W = prod A_j`` (workpiece chain, bed -> workpiece) and ``T = prod A_j`` (tool chain, bed ->
tool), ``tool2wp = W^-1 T``. Writing a chain as ``P_k A_k S_k`` around axis k:

* tool-chain axis: ``d tool2wp / dq_k = W^-1 P_k A_k G_k S_k``;
* workpiece-chain axis: ``d tool2wp / dq_k = -S_k^-1 G_k S_k tool2wp``;

applied to the tip point and the tool axis. ``G_k`` moves a point y by ``sign * u`` (linear axis) or
``w x (y - p)`` (rotary axis about direction w through p). Transforms are kept as pairs (R, t) with
R = None for the identity, so that linear axes cost only vector additions.
"""
from __future__ import annotations

import numpy as np

from ..machine import Machine


def _matvec(R, v):
    return v if R is None else np.einsum("nij,nj->ni", R, v)


def _matmul(A, B):
    if A is None:
        return B
    if B is None:
        return A
    return np.matmul(A, B)


def _transpose(R):
    return None if R is None else np.swapaxes(R, 1, 2)


def _compose(a, b):
    """(R1, t1) . (R2, t2)."""
    R1, t1 = a
    R2, t2 = b
    return _matmul(R1, R2), _matvec(R1, t2) + t1


def _inverse(a):
    R, t = a
    Rt = _transpose(R)
    return Rt, -_matvec(Rt, t)


def _rotation(axis_index, angle):
    c, s = np.cos(angle), np.sin(angle)
    n = angle.shape[0]
    R = np.zeros((n, 3, 3))
    i, j, k = axis_index, (axis_index + 1) % 3, (axis_index + 2) % 3
    R[:, i, i] = 1.0
    R[:, j, j] = c
    R[:, k, k] = c
    R[:, k, j] = s
    R[:, j, k] = -s
    return R


def _axis_motion(machine: Machine, name: str, value: np.ndarray):
    """(R or None, t (n, 3)): the nominal motion of one axis (as kinematics.axis_transform)."""
    ax = machine.axis(name)
    n = value.shape[0]
    if ax.is_rotary:
        R = _rotation(ax.direction_index, value)
        p = np.asarray(ax.axis_point, dtype=float)
        return R, p[None, :] - R @ p
    t = np.zeros((n, 3))
    t[:, ax.direction_index] = (-1.0 if ax.side == "workpiece" else 1.0) * value
    return None, t


def _generate(machine: Machine, name: str, y: np.ndarray, point: bool) -> np.ndarray:
    """G_k applied to points (point=True) or directions y (n, 3)."""
    ax = machine.axis(name)
    if ax.is_rotary:
        w = ax.direction
        yy = y - np.asarray(ax.axis_point, dtype=float) if point else y
        return np.cross(np.broadcast_to(w, yy.shape), yy)
    if not point:
        return np.zeros_like(y)
    g = np.zeros_like(y)
    g[:, ax.direction_index] = -1.0 if ax.side == "workpiece" else 1.0
    return g


def _chain(machine, names, q, n):
    mats = [_axis_motion(machine, a, q[:, machine.index(a)]) for a in names]
    ident = (None, np.zeros((n, 3)))
    pre, acc = [], ident
    for A in mats:
        pre.append(acc)
        acc = _compose(acc, A)
    total = acc
    suf, acc = [None] * len(mats), ident
    for k in range(len(mats) - 1, -1, -1):
        suf[k] = acc
        acc = _compose(mats[k], acc)
    return mats, pre, suf, total


def _column(R, k):
    return R[:, :, k] if R is not None else None


def _linear_only(machine: Machine, q: np.ndarray):
    """Machines without rotary axes: every axis moves the tool by +s along its direction relative to
    the workpiece (mtcomp.machine conventions), so the tip is a fixed selection of q."""
    n = q.shape[0]
    tip = np.zeros((n, 3))
    J1 = np.zeros((6, machine.n_axes))
    for j, ax in enumerate(machine.axes):
        tip[:, ax.direction_index] += q[:, j]
        J1[ax.direction_index, j] = 1.0
    # constant: read-only broadcast views
    return tip, np.broadcast_to([0.0, 0.0, 1.0], (n, 3)), np.broadcast_to(J1, (n, 6, machine.n_axes))


def nominal_pose(machine: Machine, q: np.ndarray):
    """Nominal tip (N, 3) mm and tool axis (N, 3), workpiece frame (as kinematics.forward, faster)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    n = q.shape[0]
    if not machine.rotary_axes:
        return _linear_only(machine, q)[:2]
    _, _, _, W = _chain(machine, machine.workpiece_chain, q, n)
    _, _, _, T = _chain(machine, machine.tool_chain, q, n)
    R, t = _compose(_inverse(W), T)
    axis = np.broadcast_to([0.0, 0.0, 1.0], (n, 3)).copy() if R is None else R[:, :, 2].copy()
    return t, axis


def nominal_pose_jacobian(machine: Machine, q: np.ndarray):
    """Nominal tool pose and its Jacobian.

    q : (N, n_axes) axis positions, mm and rad (``machine.axis_names`` order).
    Returns (tip (N, 3) mm, axis (N, 3) unit vector, J (N, 6, n_axes)): rows 0-2 d tip / dq (mm per mm
    or mm per rad), rows 3-5 d axis / dq; all in the workpiece frame.
    """
    q = np.atleast_2d(np.asarray(q, dtype=float))
    n = q.shape[0]
    if not machine.rotary_axes:
        return _linear_only(machine, q)
    ez = np.broadcast_to([0.0, 0.0, 1.0], (n, 3))
    wp_mats, wp_pre, wp_suf, W = _chain(machine, machine.workpiece_chain, q, n)
    tl_mats, tl_pre, tl_suf, T = _chain(machine, machine.tool_chain, q, n)
    Winv = _inverse(W)
    R, tip = _compose(Winv, T)
    axis = ez.copy() if R is None else R[:, :, 2].copy()
    J = np.zeros((n, 6, machine.n_axes))
    for k, name in enumerate(machine.tool_chain):
        j = machine.index(name)
        RM = _matmul(_matmul(Winv[0], tl_pre[k][0]), tl_mats[k][0])
        RS, tS = tl_suf[k]
        J[:, 0:3, j] = _matvec(RM, _generate(machine, name, tS, True))
        if machine.axis(name).is_rotary:
            v = ez if RS is None else RS[:, :, 2]
            J[:, 3:6, j] = _matvec(RM, _generate(machine, name, v, False))
    for k, name in enumerate(machine.workpiece_chain):
        j = machine.index(name)
        RS, tS = wp_suf[k]
        RSt = _transpose(RS)
        y = _matvec(RS, tip) + tS
        J[:, 0:3, j] = -_matvec(RSt, _generate(machine, name, y, True))
        if machine.axis(name).is_rotary:
            J[:, 3:6, j] = -_matvec(RSt, _generate(machine, name, _matvec(RS, axis), False))
    return tip, axis, J

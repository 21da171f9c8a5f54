"""Nominal (error-free) tool pose and its Jacobian with respect to the axis positions, in numpy.

The planner needs the Jacobian of the *actual* tool pose: the nominal Jacobian computed here plus the
error model's ``J_q`` (``deviation_qjacobian_function``). The nominal part is exact and vectorised
over poses; it uses the conventions of :mod:`mtcomp.kinematics` (one axis = one rigid motion
``A_j(q_j) = exp(G_j q_j)`` with a constant generator ``G_j``).

With ``W = prod A_j`` (workpiece chain, bed -> workpiece) and ``T = prod A_j`` (tool chain, bed ->
tool), ``tool2wp = W^-1 T``. Writing a chain as ``P_k A_k S_k`` around axis k:

* tool-chain axis: ``d tool2wp / dq_k = W^-1 P_k A_k G_k S_k``;
* workpiece-chain axis: ``d tool2wp / dq_k = -S_k^-1 G_k S_k tool2wp``.

Applied to the tip point ``(0, 0, 0, 1)`` and to the tool axis ``(0, 0, 1, 0)``.
"""
from __future__ import annotations

import numpy as np

from ..kinematics import axis_transform
from ..machine import Machine


def _generator(machine: Machine, name: str) -> np.ndarray:
    """(4, 4) generator G of one axis: d A(q) / dq = A(q) G = G A(q)."""
    ax = machine.axis(name)
    G = np.zeros((4, 4))
    if ax.is_rotary:
        w = ax.direction
        W = np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])
        p = np.asarray(ax.axis_point, dtype=float)
        G[:3, :3] = W
        G[:3, 3] = -W @ p
    else:
        sign = -1.0 if ax.side == "workpiece" else 1.0
        G[:3, 3] = sign * ax.direction
    return G


def _rigid_inverse(T: np.ndarray) -> np.ndarray:
    Ti = np.zeros_like(T)
    Rt = np.swapaxes(T[..., :3, :3], -1, -2)
    Ti[..., :3, :3] = Rt
    Ti[..., :3, 3] = -np.einsum("nij,nj->ni", Rt, T[..., :3, 3])
    Ti[..., 3, 3] = 1.0
    return Ti


def _chain_products(mats: list[np.ndarray], n: int):
    """Prefix products P_k = A_0..A_{k-1} and suffix products S_k = A_{k+1}..A_end, each (n, 4, 4)."""
    eye = np.broadcast_to(np.eye(4), (n, 4, 4))
    pre, acc = [], eye
    for A in mats:
        pre.append(acc)
        acc = acc @ A
    total = acc
    suf, acc = [None] * len(mats), eye
    for k in range(len(mats) - 1, -1, -1):
        suf[k] = acc
        acc = mats[k] @ acc
    return pre, suf, total


def nominal_pose_jacobian(machine: Machine, q: np.ndarray):
    """Nominal tool pose and its Jacobian.

    q : (N, n_axes) axis positions, mm and rad (``machine.axis_names`` order).
    Returns (tip (N, 3) mm, axis (N, 3) unit vector, J (N, 6, n_axes)): rows 0-2 d tip / dq (mm per mm
    or mm per rad), rows 3-5 d axis / dq; all in the workpiece frame.
    """
    q = np.atleast_2d(np.asarray(q, dtype=float))
    n = q.shape[0]
    wp_mats = [axis_transform(machine, a, q[:, machine.index(a)]) for a in machine.workpiece_chain]
    tl_mats = [axis_transform(machine, a, q[:, machine.index(a)]) for a in machine.tool_chain]
    wp_pre, wp_suf, W = _chain_products(wp_mats, n)
    tl_pre, tl_suf, T = _chain_products(tl_mats, n)
    Winv = _rigid_inverse(W)
    tool2wp = Winv @ T
    tip = tool2wp[:, :3, 3]
    axis = tool2wp[:, :3, 2]
    J = np.zeros((n, 6, machine.n_axes))
    tip_h = np.concatenate([tip, np.ones((n, 1))], axis=1)
    axis_h = np.concatenate([axis, np.zeros((n, 1))], axis=1)
    for k, name in enumerate(machine.tool_chain):
        G = _generator(machine, name)
        S = tl_suf[k]
        M = Winv @ tl_pre[k] @ tl_mats[k]
        # S v for v = tip (point) and tool axis (direction) in the frame after axis k
        v_tip = S[:, :, 3]
        v_axis = S[:, :, 2]
        j = machine.index(name)
        J[:, 0:3, j] = np.einsum("nij,nj->ni", M[:, :3, :], np.einsum("ij,nj->ni", G, v_tip))
        J[:, 3:6, j] = np.einsum("nij,nj->ni", M[:, :3, :], np.einsum("ij,nj->ni", G, v_axis))
    for k, name in enumerate(machine.workpiece_chain):
        G = _generator(machine, name)
        S = wp_suf[k]
        Sinv = _rigid_inverse(S)
        j = machine.index(name)
        for rows, v in ((slice(0, 3), tip_h), (slice(3, 6), axis_h)):
            y = np.einsum("nij,nj->ni", S, v)
            gy = np.einsum("ij,nj->ni", G, y)
            J[:, rows, j] = -np.einsum("nij,nj->ni", Sinv[:, :3, :], gy)
    return tip, axis, J

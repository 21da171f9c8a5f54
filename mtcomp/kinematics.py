"""Nominal (error-free) forward kinematics of any machine, in numpy, vectorised over poses.

Frames: ``bed`` (the machine frame), ``wp`` (workpiece frame, fixed to the table), ``tool`` (the tool
tip frame: origin at the tip, +Z along the tool axis from the tip towards the spindle). Transforms
are named ``A2B``: the pose of frame A expressed in frame B (a 4x4 that maps A coordinates to B).
Conventions are those of :mod:`mtcomp.machine` and docs/conventions.md.

The error model (:mod:`mtcomp.models`) builds the same chain with every axis's errors; with all
errors zero it reduces to this module, which tests check.
"""
from __future__ import annotations

import numpy as np

from .machine import Machine


def rotation_about(axis_index: int, angle: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotations by ``angle`` (N,) rad about machine direction 0 (X), 1 (Y) or 2 (Z)."""
    angle = np.asarray(angle, dtype=float)
    c, s = np.cos(angle), np.sin(angle)
    R = np.zeros(angle.shape + (3, 3))
    i, j, k = axis_index, (axis_index + 1) % 3, (axis_index + 2) % 3
    R[..., i, i] = 1.0
    R[..., j, j] = c
    R[..., k, k] = c
    R[..., k, j] = s
    R[..., j, k] = -s
    return R


def _homogeneous(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    n = R.shape[0]
    T = np.zeros((n, 4, 4))
    T[:, :3, :3] = R
    T[:, :3, 3] = t
    T[:, 3, 3] = 1.0
    return T


def axis_transform(machine: Machine, name: str, value: np.ndarray) -> np.ndarray:
    """(N, 4, 4) nominal motion of one axis: child carriage frame in its parent frame.

    Linear axis on the tool side: translation by ``+s`` along its direction; on the workpiece side:
    by ``-s`` (the table moves the other way, so that the tool moves ``+s`` relative to the part).
    Rotary axis: rotation by ``+theta`` about its nominal line through ``axis_point``.
    """
    ax = machine.axis(name)
    value = np.asarray(value, dtype=float)
    n = value.shape[0]
    if ax.is_rotary:
        R = rotation_about(ax.direction_index, value)
        p = np.asarray(ax.axis_point, dtype=float)
        t = p - R @ p
        return _homogeneous(R, t)
    sign = -1.0 if ax.side == "workpiece" else 1.0
    t = np.zeros((n, 3))
    t[:, ax.direction_index] = sign * value
    return _homogeneous(np.broadcast_to(np.eye(3), (n, 3, 3)).copy(), t)


def wp2bed(machine: Machine, q: np.ndarray) -> np.ndarray:
    """(N, 4, 4) workpiece frame in the bed frame; q (N, n_axes) mm and rad."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    T = np.broadcast_to(np.eye(4), (q.shape[0], 4, 4)).copy()
    for name in machine.workpiece_chain:
        T = T @ axis_transform(machine, name, q[:, machine.index(name)])
    return T


def tool2bed(machine: Machine, q: np.ndarray) -> np.ndarray:
    """(N, 4, 4) tool-tip frame in the bed frame."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    T = np.broadcast_to(np.eye(4), (q.shape[0], 4, 4)).copy()
    for name in machine.tool_chain:
        T = T @ axis_transform(machine, name, q[:, machine.index(name)])
    return T


def rigid_inverse(T: np.ndarray) -> np.ndarray:
    """(N, 4, 4) inverses of rigid transforms: [R^T, -R^T t]."""
    R = T[:, :3, :3]
    Ti = np.zeros_like(T)
    Ti[:, :3, :3] = R.transpose(0, 2, 1)
    Ti[:, :3, 3] = -np.einsum("nji,nj->ni", R, T[:, :3, 3])
    Ti[:, 3, 3] = 1.0
    return Ti


def tool2wp(machine: Machine, q: np.ndarray) -> np.ndarray:
    """(N, 4, 4) tool-tip frame in the workpiece frame (nominal)."""
    return rigid_inverse(wp2bed(machine, q)) @ tool2bed(machine, q)


def forward(machine: Machine, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Nominal tool tip (N, 3) mm and tool axis (N, 3) unit vector, both in the workpiece frame."""
    T = tool2wp(machine, q)
    return T[:, :3, 3], T[:, :3, 2]

"""4x4 homogeneous transforms, vectorised over N rows (test-only; independent of mtcomp).

Every function takes arrays of shape (N,) (angles, rad) or (N, 3) (vectors, mm) and returns (N, 4, 4).
Rotations are right-handed active rotations: ``rot_z(a)`` turns a vector by ``+a`` about +Z.
"""
from __future__ import annotations

import numpy as np


def _n(*arrays) -> int:
    return max(np.atleast_1d(a).shape[0] for a in arrays)


def identity(n: int) -> np.ndarray:
    """(n, 4, 4) identity."""
    return np.broadcast_to(np.eye(4), (n, 4, 4)).copy()


def translation(v) -> np.ndarray:
    """(N, 4, 4) pure translation by v (N, 3) or (3,) mm."""
    v = np.atleast_2d(np.asarray(v, dtype=float))
    T = identity(v.shape[0])
    T[:, :3, 3] = v
    return T


def rotation_about(u, angle) -> np.ndarray:
    """(N, 4, 4) rotation by ``angle`` (N,) rad about the unit direction ``u`` (3,) or (N, 3), through
    the origin (Rodrigues' formula, exact for any angle)."""
    angle = np.atleast_1d(np.asarray(angle, dtype=float))
    u = np.atleast_2d(np.asarray(u, dtype=float))
    n = _n(angle, u)
    angle = np.broadcast_to(angle, (n,))
    u = np.broadcast_to(u, (n, 3))
    u = u / np.linalg.norm(u, axis=1, keepdims=True)
    K = np.zeros((n, 3, 3))
    K[:, 0, 1], K[:, 0, 2] = -u[:, 2], u[:, 1]
    K[:, 1, 0], K[:, 1, 2] = u[:, 2], -u[:, 0]
    K[:, 2, 0], K[:, 2, 1] = -u[:, 1], u[:, 0]
    s = np.sin(angle)[:, None, None]
    c = np.cos(angle)[:, None, None]
    T = identity(n)
    T[:, :3, :3] = np.eye(3) + s * K + (1.0 - c) * (K @ K)
    return T


def rot_x(a) -> np.ndarray:
    return rotation_about([1.0, 0.0, 0.0], a)


def rot_y(a) -> np.ndarray:
    return rotation_about([0.0, 1.0, 0.0], a)


def rot_z(a) -> np.ndarray:
    return rotation_about([0.0, 0.0, 1.0], a)


def about_point(point, T) -> np.ndarray:
    """(N, 4, 4) the transform T (a rotation) applied about ``point`` (N, 3) or (3,):
    ``Trans(p) T Trans(-p)``."""
    p = np.atleast_2d(np.asarray(point, dtype=float))
    return translation(p) @ T @ translation(-p)


def inverse(T) -> np.ndarray:
    """(N, 4, 4) inverse of rigid transforms."""
    R = T[:, :3, :3]
    Rt = np.transpose(R, (0, 2, 1))
    out = identity(T.shape[0])
    out[:, :3, :3] = Rt
    out[:, :3, 3] = -np.einsum("nij,nj->ni", Rt, T[:, :3, 3])
    return out


def apply(T, points) -> np.ndarray:
    """(N, 3): T (N, 4, 4) applied to points (N, 3) or (3,)."""
    p = np.broadcast_to(np.asarray(points, dtype=float), (T.shape[0], 3))
    return np.einsum("nij,nj->ni", T[:, :3, :3], p) + T[:, :3, 3]


def rotate(T, vectors) -> np.ndarray:
    """(N, 3): the rotation part of T applied to direction vectors (N, 3) or (3,)."""
    v = np.broadcast_to(np.asarray(vectors, dtype=float), (T.shape[0], 3))
    return np.einsum("nij,nj->ni", T[:, :3, :3], v)


def small_rotation_vector(R) -> np.ndarray:
    """(N, 3) rotation vector (rad) of rotation matrices R (N, 3, 3), exact for any angle < pi."""
    w = 0.5 * np.stack([R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0], R[:, 1, 0] - R[:, 0, 1]], axis=1)
    s = np.linalg.norm(w, axis=1)
    c = 0.5 * (np.trace(R, axis1=1, axis2=2) - 1.0)
    angle = np.arctan2(s, c)
    scale = np.where(s > 1e-300, angle / np.where(s > 1e-300, s, 1.0), 1.0)
    return w * scale[:, None]

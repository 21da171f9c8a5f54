"""Nominal (error-free) kinematics of any machine: the one implementation in mtcomp.

Frames: ``bed`` (the machine frame), ``wp`` (workpiece frame, fixed to the table), ``tool`` (the tool
tip frame: origin at the tip, +Z along the tool axis from the tip towards the spindle). Transforms
are named ``A2B``: the pose of frame A expressed in frame B (a 4x4 that maps A coordinates to B).
Conventions are those of :mod:`mtcomp.machine` and docs/conventions.md.

Each axis is one rigid motion ``A_j(q_j) = exp(G_j q_j)`` with a constant generator ``G_j``
(:func:`axis_motion`): a linear axis on the tool side translates by ``+s`` along its direction, on
the workpiece side by ``-s`` (the table moves the other way, so that the tool moves ``+s`` relative
to the part); a rotary axis turns by ``+theta`` about its nominal line through ``axis_point``. With
``W = prod A_j`` (workpiece chain, bed -> workpiece) and ``T = prod A_j`` (tool chain, bed -> tool),
``tool2wp = W^-1 T``.

A transform is a pair (R, t), ``x_parent = R x_child + t``, with R None for the identity, so that
linear axes cost only vector additions. The formulas are written once, against a small namespace of
operations, and serve two kinds of numbers:

* :data:`NUMPY`: N poses at once, R (N, 3, 3), t (N, 3): :func:`forward`, :func:`tool2wp` ... and
  :func:`pose_jacobian`, the exact Jacobian the planner uses;
* :data:`CASADI`: one symbolic pose, R an SX 3x3, t an SX 3-vector: :func:`symbolic_pose`, the nominal
  chain of the error model (:mod:`mtcomp.models.chain`), whose deviations are actual minus this.

Jacobian (:func:`pose_jacobian`). Writing a chain as ``P_k A_k S_k`` around axis k:

* tool-chain axis: ``d tool2wp / dq_k = W^-1 P_k A_k G_k S_k``;
* workpiece-chain axis: ``d tool2wp / dq_k = -S_k^-1 G_k S_k tool2wp``;

applied to the tip point and the tool axis. ``G_k`` moves a point y by ``sign * u`` (linear axis) or
``w x (y - p)`` (rotary axis about direction w through p).

Inverse kinematics (tool pose -> axis positions) is :func:`mtcomp.toolpaths.inverse_kinematics`,
checked against :func:`forward`.
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


# ----------------------------------------------------------------------- the two kinds of numbers
class _Numpy:
    """N poses at once: q (N, n_axes), R (N, 3, 3), t (N, 3)."""

    rotation = staticmethod(rotation_about)

    @staticmethod
    def matmul(A, B):
        return np.matmul(A, B)

    @staticmethod
    def matvec(R, v):
        return np.einsum("nij,nj->ni", R, v)

    @staticmethod
    def transpose(R):
        return np.swapaxes(R, 1, 2)

    @staticmethod
    def about_point(R, point):
        """t of the rotation R about ``point`` (3,): p - R p."""
        p = np.asarray(point, dtype=float)
        return p[None, :] - R @ p

    @staticmethod
    def along(like, axis_index: int, value):
        """t of a translation by ``value`` (N,) along machine direction ``axis_index``."""
        t = np.zeros((like.shape[0], 3))
        t[:, axis_index] = value
        return t

    @staticmethod
    def zeros(q):
        return np.zeros((q.shape[0], 3))

    @staticmethod
    def coordinate(q, j: int):
        return q[:, j]


class _CasADi:
    """One symbolic pose: q an SX n_axes-vector, R an SX 3x3, t an SX 3-vector (casadi is imported
    on first use, so that numpy users of this module do not load it)."""

    @staticmethod
    def rotation(axis_index: int, angle):
        import casadi as ca
        c, s = ca.cos(angle), ca.sin(angle)
        R = ca.SX.eye(3)
        j, k = (axis_index + 1) % 3, (axis_index + 2) % 3
        R[j, j] = c
        R[k, k] = c
        R[k, j] = s
        R[j, k] = -s
        return R

    @staticmethod
    def matmul(A, B):
        import casadi as ca
        return ca.mtimes(A, B)

    matvec = matmul

    @staticmethod
    def transpose(R):
        return R.T

    @staticmethod
    def about_point(R, point):
        import casadi as ca
        p = ca.SX(np.asarray(point, dtype=float))
        return p - ca.mtimes(R, p)

    @staticmethod
    def along(like, axis_index: int, value):
        import casadi as ca
        t = ca.SX.zeros(3)
        t[axis_index] = value
        return t

    @staticmethod
    def zeros(q):
        import casadi as ca
        return ca.SX.zeros(3)

    @staticmethod
    def coordinate(q, j: int):
        return q[j]


#: numpy, vectorised over poses
NUMPY = _Numpy()
#: CasADi SX, one symbolic pose
CASADI = _CasADi()


# ----------------------------------------------------------------------- rigid transforms (R, t)
def _matmul(A, B, ops=NUMPY):
    if A is None:
        return B
    if B is None:
        return A
    return ops.matmul(A, B)


def _matvec(R, v, ops=NUMPY):
    return v if R is None else ops.matvec(R, v)


def _transpose(R, ops=NUMPY):
    return None if R is None else ops.transpose(R)


def compose(a, b, ops=NUMPY):
    """(R1, t1) . (R2, t2) = (R1 R2, R1 t2 + t1)."""
    R1, t1 = a
    R2, t2 = b
    return _matmul(R1, R2, ops), _matvec(R1, t2, ops) + t1


def inverse(a, ops=NUMPY):
    """(R, t)^-1 = (R^T, -R^T t)."""
    R, t = a
    Rt = _transpose(R, ops)
    return Rt, -_matvec(Rt, t, ops)


def axis_motion(machine: Machine, name: str, value, ops=NUMPY):
    """(R or None, t): the nominal motion of one axis at ``value`` (mm or rad), its carriage frame in
    its parent frame."""
    ax = machine.axis(name)
    if ax.is_rotary:
        R = ops.rotation(ax.direction_index, value)
        return R, ops.about_point(R, ax.axis_point)
    sign = -1.0 if ax.side == "workpiece" else 1.0
    return None, ops.along(value, ax.direction_index, sign * value)


def chain_motions(machine: Machine, names, q, ops=NUMPY):
    """(motions, prefixes, suffixes, total) of the chain of axes ``names`` at q: ``prefixes[k]`` is
    the product of the motions before axis k, ``suffixes[k]`` of those after it, ``total`` of all."""
    mats = [axis_motion(machine, a, ops.coordinate(q, machine.index(a)), ops) for a in names]
    ident = (None, ops.zeros(q))
    pre, acc = [], ident
    for A in mats:
        pre.append(acc)
        acc = compose(acc, A, ops)
    total = acc
    suf, acc = [None] * len(mats), ident
    for k in range(len(mats) - 1, -1, -1):
        suf[k] = acc
        acc = compose(mats[k], acc, ops)
    return mats, pre, suf, total


def _chain(machine: Machine, names, q, ops=NUMPY):
    acc = (None, ops.zeros(q))
    for a in names:
        acc = compose(acc, axis_motion(machine, a, ops.coordinate(q, machine.index(a)), ops), ops)
    return acc


def tool2wp_pair(machine: Machine, q, ops=NUMPY):
    """(R or None, t): the tool-tip frame in the workpiece frame, ``W^-1 T``."""
    W = _chain(machine, machine.workpiece_chain, q, ops)
    T = _chain(machine, machine.tool_chain, q, ops)
    return compose(inverse(W, ops), T, ops)


def symbolic_pose(machine: Machine, q):
    """Nominal (tip (3,), tool axis (3,), R (3, 3)) of the SX axis positions q, workpiece frame: the
    error model's nominal chain (:meth:`mtcomp.models.ErrorModel.symbolic` with ``errors=False``)."""
    import casadi as ca
    R, t = tool2wp_pair(machine, q, CASADI)
    if R is None:
        R = ca.SX.eye(3)
    return t, R[:, 2], R


# ----------------------------------------------------------------------- numpy, over N poses
def _homogeneous(pair, n: int) -> np.ndarray:
    R, t = pair
    T = np.zeros((n, 4, 4))
    T[:, :3, :3] = np.eye(3) if R is None else R
    T[:, :3, 3] = t
    T[:, 3, 3] = 1.0
    return T


def axis_transform(machine: Machine, name: str, value: np.ndarray) -> np.ndarray:
    """(N, 4, 4) nominal motion of one axis (:func:`axis_motion`): child carriage frame in its parent
    frame."""
    value = np.asarray(value, dtype=float)
    return _homogeneous(axis_motion(machine, name, value), value.shape[0])


def wp2bed(machine: Machine, q: np.ndarray) -> np.ndarray:
    """(N, 4, 4) workpiece frame in the bed frame; q (N, n_axes) mm and rad."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    return _homogeneous(_chain(machine, machine.workpiece_chain, q), q.shape[0])


def tool2bed(machine: Machine, q: np.ndarray) -> np.ndarray:
    """(N, 4, 4) tool-tip frame in the bed frame."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    return _homogeneous(_chain(machine, machine.tool_chain, q), q.shape[0])


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
    q = np.atleast_2d(np.asarray(q, dtype=float))
    return _homogeneous(tool2wp_pair(machine, q), q.shape[0])


def _linear_only(machine: Machine, q: np.ndarray):
    """Machines without rotary axes: every axis moves the tool by +s along its direction relative to
    the workpiece, so the tip is a fixed selection of q (read-only tool axis and Jacobian)."""
    n = q.shape[0]
    tip = np.zeros((n, 3))
    J1 = np.zeros((6, machine.n_axes))
    for j, ax in enumerate(machine.axes):
        tip[:, ax.direction_index] += q[:, j]
        J1[ax.direction_index, j] = 1.0
    return tip, np.broadcast_to([0.0, 0.0, 1.0], (n, 3)), np.broadcast_to(J1, (n, 6, machine.n_axes))


def forward(machine: Machine, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Nominal tool tip (N, 3) mm and tool axis (N, 3) unit vector, both in the workpiece frame;
    q (N, n_axes) mm and rad, ``machine.axis_names`` order."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    if not machine.rotary_axes:
        tip, axis, _ = _linear_only(machine, q)
        return tip, axis.copy()
    R, t = tool2wp_pair(machine, q)
    axis = np.broadcast_to([0.0, 0.0, 1.0], t.shape).copy() if R is None else R[:, :, 2].copy()
    return t, axis


def _generate(machine: Machine, name: str, y: np.ndarray, point: bool) -> np.ndarray:
    """G_k applied to points (point=True) or directions y (n, 3)."""
    ax = machine.axis(name)
    if ax.is_rotary:
        yy = y - np.asarray(ax.axis_point, dtype=float) if point else y
        return np.cross(np.broadcast_to(ax.direction, yy.shape), yy)
    if not point:
        return np.zeros_like(y)
    g = np.zeros_like(y)
    g[:, ax.direction_index] = -1.0 if ax.side == "workpiece" else 1.0
    return g


def pose_jacobian(machine: Machine, q: np.ndarray):
    """Nominal tool pose and its exact Jacobian.

    q : (N, n_axes) axis positions, mm and rad (``machine.axis_names`` order).
    Returns (tip (N, 3) mm, axis (N, 3) unit vector, J (N, 6, n_axes)): rows 0-2 d tip / dq (mm per mm
    or mm per rad), rows 3-5 d axis / dq; all in the workpiece frame. On a machine without rotary
    axes the tool axis and J are read-only (constant).
    """
    q = np.atleast_2d(np.asarray(q, dtype=float))
    n = q.shape[0]
    if not machine.rotary_axes:
        return _linear_only(machine, q)
    ez = np.broadcast_to([0.0, 0.0, 1.0], (n, 3))
    _, _, wp_suf, W = chain_motions(machine, machine.workpiece_chain, q)
    tl_mats, tl_pre, tl_suf, T = chain_motions(machine, machine.tool_chain, q)
    Winv = inverse(W)
    R, tip = compose(Winv, T)
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

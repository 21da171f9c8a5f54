"""The differential change construction (Qi and Yang 2016): a first-order error model and the machine
Jacobian built from the same differential change matrices, for any topology, in numpy.

Frames (docs/conventions.md): every axis carriage has a frame that coincides with the bed frame when
all axes are at zero; ``tool2i`` is the nominal pose of the tool-tip frame in the frame of axis i:

* tool-side axis i (chain bed -> tool ``A_1 ... A_n``): ``tool2i = A_{i+1} ... A_n`` (eq. 11);
* workpiece-side axis j (chain bed -> workpiece ``W_1 ... W_m``): frame j is the part side of the
  axis (the carriage it moves), ``tool2j = W_j^-1 ... W_1^-1 A_1 ... A_n`` (eq. 10, 11: the chain from
  the workpiece to the tool runs through the inverse table motions).

The differential change matrix of eq. 4, ``C = [[R^T, -R^T hat(p)], [0, R^T]]`` for a transform
(R, p), maps a differential motion vector D = (delta, eps) of frame i (expressed in frame i) to the
tool frame (eq. 5). The model:

1. each axis's differential motion vector D_i, first order in its errors (eqs. 15-17): for a
   tool-side linear axis ``(delta + s (u - e) + r x eps, eps)`` (translation errors, squareness as the
   tilt of the direction of travel, angular errors turning about the carriage reference point r,
   fixed on the carriage: the gauge point with the machine's reference tool, (0, 0, L0); the ram at
   its machine position q_Z + L - L0 for a tool of length L);
   for a workpiece-side axis the differential motion of the bed seen from the carriage, the *negated*
   body error (the sign flip of eq. 17); for a rotary axis the location errors, angular positioning
   error and error motions moved into the carriage frame;
2. the tool-frame error ``D_t = sum_i C(tool2i) D_i + D_tool`` (eq. 22), with ``D_tool`` the tool
   length error;
3. to the workpiece frame (eqs. 23-25): ``dT = T . hat(D_t)``, so the tip error is ``R delta_t`` and
   the tool-axis error ``R (eps_t x e_z)``.

The Jacobian (eqs. 27, 28) takes from each axis's matrix the column of its own motion: ``J_i =
C(tool2i) xi_i`` with xi_i the unit twist of axis i (``(e_d, 0)`` linear, ``(-e_d x P, e_d)``
rotary), negated for workpiece-side axes. ``D_t = J dq``: tool-frame differential motion per unit
axis motion. :func:`pinv_correction` solves eq. 29 per pose; the corrected command is
``q - dq`` (eq. 30).

This model is first order in the errors: it equals the exact chain's first-order term ``J_p(p=0) p``
(tests check it to 1e-12), and exact minus DCM is O(|p|^2). Base model only (no extension terms);
:func:`pinv_correction` accepts extended models by taking the error from the exact chain.
Units: mm, rad; q (N, n_axes) in ``machine.axis_names`` order; p in ``model.param_names`` order.
"""
from __future__ import annotations

import numpy as np

from mtcomp.kinematics import axis_transform, tool2wp
from mtcomp.models.chain import ErrorModel
from mtcomp.models.evaluate import deviation
from mtcomp.models.terms import ANGLE_LETTERS, TRANSLATION_LETTERS, positioning_component

from .poe import (adjoint, machine_positions, prepare_inputs, rotary_line_errors, rotation_twist, skew,
                  tool_shift)

__all__ = ["differential_change_matrix", "tool_in_axis_frames", "axis_differential_motions",
           "tool_differential", "dcm_deviation", "machine_jacobian", "pinv_correction",
           "exact_tool_differential"]


def differential_change_matrix(T: np.ndarray) -> np.ndarray:
    """(..., 6, 6) C of eq. 4 for the transform T (..., 4, 4) of frame b in frame a: maps a
    differential motion vector of frame a (in a) to frame b. Equal to the adjoint of T^-1."""
    T = np.asarray(T, dtype=float)
    R, p = T[..., :3, :3], T[..., :3, 3]
    Rt = np.swapaxes(R, -1, -2)
    C = np.zeros(T.shape[:-2] + (6, 6))
    C[..., :3, :3] = Rt
    C[..., 3:, 3:] = Rt
    C[..., :3, 3:] = -Rt @ skew(p)
    return C


def _nominal_chain(model: ErrorModel, q: np.ndarray):
    m = model.machine
    A = {name: axis_transform(m, name, q[:, m.index(name)]) for name in m.axis_names}
    return A


def tool_in_axis_frames(model: ErrorModel, q, c=None) -> dict[str, np.ndarray]:
    """{axis: (N, 4, 4)} nominal pose of the tool-tip frame in each axis's frame (eqs. 10, 11), with
    the ram at its machine position and the tip of a tool longer than the reference tool by ``shift``
    that much below the ram frame's origin (:func:`oracles.poe.tool_shift`)."""
    m = model.machine
    q = np.atleast_2d(np.asarray(q, dtype=float))
    n = q.shape[0]
    A = _nominal_chain(model, machine_positions(model, q, c))
    eye = np.broadcast_to(np.eye(4), (n, 4, 4))
    out = {}
    tail = eye.copy()  # A_{i+1} ... A_n Trans(0, 0, -shift)
    tail[:, 2, 3] = -tool_shift(model, q, c)
    for name in reversed(m.tool_chain):
        out[name] = tail.copy()
        tail = A[name] @ tail
    bed2tool = tail  # tool frame in the bed frame (A_1 ... A_n)
    head = eye.copy()  # W_{j-1}^-1 ... W_1^-1
    for name in m.workpiece_chain:
        head = np.linalg.inv(A[name]) @ head
        out[name] = head @ bed2tool
    return out


def axis_differential_motions(model: ErrorModel, p, q, c=None) -> dict[str, np.ndarray]:
    """{axis: (N, 6)} differential motion vector D_i of each axis in its own frame (eqs. 15-17),
    first order in the errors; workpiece-side axes carry the sign flip of eq. 17."""
    m = model.machine
    q, c, P, E = prepare_inputs(model, p, q, c)
    n = q.shape[0]
    out = {}
    for ax in m.axes:
        s = q[:, m.index(ax.name)]
        e_d = np.eye(3)[ax.direction_index]
        comps = E[ax.name]
        if ax.is_rotary:
            point, others, shift, tilt = rotary_line_errors(P, ax)
            xi0 = rotation_twist(e_d, point)
            g = np.concatenate([shift + np.cross(point, tilt), tilt])  # location error twist
            eps_m = np.zeros((n, 3))
            for j in others:
                eps_m[:, j] = comps[f"E{ANGLE_LETTERS[j]}{ax.name}"]
            delta_m = np.stack([comps[f"E{x}{ax.name}"] for x in TRANSLATION_LETTERS], axis=1)
            A0 = axis_transform(m, ax.name, s)
            AdA = adjoint(A0)
            # left (fixed-frame) differential: error motions about P, positioning error along xi0,
            # and the location errors: G exp(xi0 t) G^-1 exp(-xi0 t) - I = g - Ad_A0 g
            left = np.concatenate([delta_m + np.cross(point, eps_m), eps_m], axis=1)
            left += xi0[None, :] * comps[positioning_component(ax.name)][:, None]
            left += g[None, :] - AdA @ g
            body = np.einsum("nij,nj->ni", adjoint(np.linalg.inv(A0)), left)
            out[ax.name] = -body if ax.side == "workpiece" else body
            continue
        delta = np.stack([comps[f"E{x}{ax.name}"] for x in TRANSLATION_LETTERS], axis=1)
        eps = np.stack([comps[f"E{a}{ax.name}"] for a in ANGLE_LETTERS], axis=1)
        sq = np.zeros(3)  # first-order tilt u - e_d of the direction of travel
        if ax.name == "Y" and "C0Y" in P:
            sq = np.array([-P["C0Y"], 0.0, 0.0])
        elif ax.name == "Z":
            sq = np.array([P.get("B0Z", 0.0), -P.get("A0Z", 0.0), 0.0])
        if ax.side == "tool":
            r = np.zeros((n, 3))      # fixed on the carriage: the gauge point with the reference tool
            r[:, 2] = m.tool_length
            out[ax.name] = np.concatenate([delta + s[:, None] * sq + np.cross(r, eps), eps], axis=1)
        else:
            # table = (Trans(s u) E)^-1: the bed seen from the carriage moves by the error of the
            # tool-relative motion, at the moved point s e_d (eq. 17's sign flip, and its arm)
            arm = s[:, None] * e_d[None, :]
            out[ax.name] = np.concatenate([delta + s[:, None] * sq + np.cross(arm, eps), eps], axis=1)
    return out


def tool_differential(model: ErrorModel, p, q, c=None) -> np.ndarray:
    """(N, 6) D_t: the combined differential motion of the tool frame, in the tool frame (eq. 22)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    frames = tool_in_axis_frames(model, q, c)
    D = axis_differential_motions(model, p, q, c)
    Dt = np.zeros((q.shape[0], 6))
    for name, T in frames.items():
        Dt += np.einsum("nij,nj->ni", differential_change_matrix(T), D[name])
    P = dict(zip(model.param_names, np.asarray(p, dtype=float)))
    Dt[:, 2] -= P["TOOL_dL"]
    # spindle tilt eps = (A0S, B0S, 0) about the gauge point r = (0, 0, L) of the tool frame: the tip
    # (origin) moves by r x eps
    L = (model.default_context(q.shape[0]) if c is None else np.atleast_2d(c))[:, model.context_names.index("tool_length")]
    Dt[:, 0] += -L * P.get("B0S", 0.0)
    Dt[:, 1] += L * P.get("A0S", 0.0)
    Dt[:, 3] += P.get("A0S", 0.0)
    Dt[:, 4] += P.get("B0S", 0.0)
    return Dt


def _to_workpiece(model: ErrorModel, q, Dt):
    """Eqs. 23-25: tip error R delta_t and tool-axis error R (eps_t x e_z), workpiece frame."""
    T = tool2wp(model.machine, q)
    R = T[:, :3, :3]
    tip = np.einsum("nij,nj->ni", R, Dt[:, :3])
    axis = np.einsum("nij,nj->ni", R, np.cross(Dt[:, 3:], np.array([0.0, 0.0, 1.0])))
    return np.concatenate([tip, axis], axis=1)


def dcm_deviation(model: ErrorModel, p, q, c=None) -> np.ndarray:
    """(N, 6): first-order tool tip (mm) and tool-axis deviation, workpiece frame (eqs. 22-25)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    return _to_workpiece(model, q, tool_differential(model, p, q, c))


def machine_jacobian(model: ErrorModel, q) -> np.ndarray:
    """(N, 6, n_axes) J of eqs. 27, 28 in the tool frame: D_t = J dq (mm and rad per mm or rad)."""
    m = model.machine
    q = np.atleast_2d(np.asarray(q, dtype=float))
    frames = tool_in_axis_frames(model, q)
    J = np.zeros((q.shape[0], 6, m.n_axes))
    for name, T in frames.items():
        ax = m.axis(name)
        e_d = np.eye(3)[ax.direction_index]
        if ax.is_rotary:
            xi = rotation_twist(e_d, ax.axis_point)
        else:
            xi = np.concatenate([(-1.0 if ax.side == "workpiece" else 1.0) * e_d, np.zeros(3)])
        col = differential_change_matrix(T) @ xi
        J[:, :, m.index(name)] = -col if ax.side == "workpiece" else col
    return J


def exact_tool_differential(model: ErrorModel, p, q, c=None) -> np.ndarray:
    """(N, 6) tool-frame differential motion from the exact chain (any model, extension terms too):
    tip deviation and the tilt of the tool axis in the tool frame; rotation about the tool axis 0."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    dev = deviation(model, q, p, c)
    R = tool2wp(model.machine, q)[:, :3, :3]
    Rt = np.swapaxes(R, 1, 2)
    axis0 = R[:, :, 2]
    tilt = np.cross(axis0, axis0 + dev[:, 3:])
    return np.concatenate([np.einsum("nij,nj->ni", Rt, dev[:, :3]),
                           np.einsum("nij,nj->ni", Rt, tilt)], axis=1)


def pinv_correction(model: ErrorModel, p, q, c=None, errors: str = "auto",
                    orientation_weight_mm: float = 100.0, rcond: float = 1e-10) -> np.ndarray:
    """(N, n_axes) axis corrections dq of one step of Qi and Yang (2016) (eq. 29); command ``q - dq`` (eq. 30).

    Least squares of ``J dq = D_t`` per pose over the tool-frame translation (mm) and the two tilts
    of the tool axis (rad, scaled by ``orientation_weight_mm`` to be comparable with mm); the
    rotation about the tool's own axis is left out (it does not move a rotating tool). A 3-axis
    machine has no orientation columns, so this is eq. 29 on the position rows.

    At a singular pose (5-axis: tilt axis at zero, where the turn of the table cannot tilt the
    tool) the unreachable tilt is left as it is (singular values below ``rcond`` times the largest
    are dropped).

    errors : 'dcm' (the first-order model of this module; base model only), 'exact' (the error of
        the exact chain, any extension terms) or 'auto' (dcm for the base model, exact otherwise).
    q : (N, n_axes) commanded axis positions, mm and rad. c : (N, n_context) or None.
    """
    q = np.atleast_2d(np.asarray(q, dtype=float))
    if errors == "auto":
        errors = "exact" if model.terms else "dcm"
    if errors == "dcm":
        Dt = tool_differential(model, p, q, c)
    elif errors == "exact":
        Dt = exact_tool_differential(model, p, q, c)
    else:
        raise ValueError(f"errors must be 'auto', 'dcm' or 'exact', got {errors!r}")
    J = machine_jacobian(model, q)
    w = np.array([1.0, 1.0, 1.0, orientation_weight_mm, orientation_weight_mm])
    A = J[:, :5, :] * w[None, :, None]
    b = Dt[:, :5] * w[None, :]
    return np.einsum("nij,nj->ni", np.linalg.pinv(A, rcond=rcond), b)

"""The error model as a product of exponentials (Tan et al. 2026, eqs. 1-9), in numpy.

A second, independent formulation of the exact chain of :mod:`mtcomp.models.chain`, with the same
parameter vector and the same meaning of every parameter. Every motion is the exponential of a
twist ``xi = (v, w)`` (v: mm, w: unit or zero; a 6-vector, translation part first) defined in the bed
frame with every axis at zero (all frames coincide there, docs/conventions.md):

    g_ft = prod_{tool chain} exp(xi_i^e) exp(xi_i^r theta_i) . g_ft(0)          (eq. 2, 5)
    g_fw = prod_{workpiece chain} exp(xi_i^e) exp(xi_i^r theta_i) . g_fw(0)     (eq. 1, 5)
    g_wt = g_fw^-1 g_ft                                                          (eq. 3, 5)

with the error exponential on the *left* of the ideal one, as in eq. 4 (the actual motion is the
ideal motion followed by an error motion expressed in the fixed frame). Eq. 9 prints the product in
the opposite order (ideal . error), which would express the error motion in the moving carriage
frame; that contradicts eq. 7 and the identification of eqs. 10-14, which measure the error motions
in the fixed frame. docs/models.md discusses it.

How the errors of chain.py become exponentials:

* linear axis, tool side: the ideal twist is ``(u, 0)`` with u the direction tilted by the squareness
  errors, i.e. ``Ad_{G_sq} (e_d, 0)`` with G_sq the squareness rotation (C0Y for Y; B0Z, A0Z for Z).
  The component errors are, in the carriage frame, a translation ``(EX, EY, EZ)`` followed by
  rotations EA, EB, EC about the carriage reference point r, fixed on the carriage (the spindle gauge
  point with the machine's reference tool: (0, 0, L0)). Moved to the left of the ideal exponential they become ``Ad_{exp(xi s)}`` of those twists:
  rotations about the moved point ``r + s u``.
* linear axis, workpiece side: the table transform is the inverse of the tool-relative motion, so
  the ideal twist is ``-(u, 0)`` and the error exponentials are the inverses, in reverse order, of
  those above with r = 0 (the workpiece origin); they are already on the left. This is the sign
  flip of Qi and Yang (2016), eq. 17.
* rotary axis: the ideal twist of the *actual* line, ``Ad_{G_loc} (-e_d x P, e_d)``, with G_loc the
  location errors (offset of the axis point, tilt of the line about P), turned by ``theta + E_own``;
  the error motions are a translation and rotations about the actual axis point, in the fixed frame
  (Tan et al. 2026, eq. 7), on the left.
* the tool frame at zero: ``g_ft(0) = exp((0, 0, -(L - L0) - TOOL_dL, 0, 0, 0))``: a tool of length
  L hangs L - L0 below the reference tool's tip (the ram, Z, stands that much higher: its ideal
  motion and component errors are those of its machine position q_Z + L - L0) and the tool length
  error lowers it further.

Only the base model (docs/models.md) is covered; extension terms raise NotImplementedError.
Units: mm and rad; q (N, n_axes) in ``machine.axis_names`` order; p in ``model.param_names`` order.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from mtcomp.models.chain import (ErrorModel, linear_components, rotary_location_names,
                    rotary_motion_names)
from mtcomp.models.terms import ANGLE_LETTERS, TRANSLATION_LETTERS, positioning_component

__all__ = ["hat", "exp_twist", "adjoint", "component_errors", "poe_transforms", "poe_tool_pose",
           "poe_deviation", "rotation_twist"]


# --------------------------------------------------------------------------------- se(3) algebra
def skew(w: np.ndarray) -> np.ndarray:
    """(..., 3, 3) cross-product matrix of w (..., 3)."""
    w = np.asarray(w, dtype=float)
    S = np.zeros(w.shape[:-1] + (3, 3))
    S[..., 0, 1], S[..., 0, 2] = -w[..., 2], w[..., 1]
    S[..., 1, 0], S[..., 1, 2] = w[..., 2], -w[..., 0]
    S[..., 2, 0], S[..., 2, 1] = -w[..., 1], w[..., 0]
    return S


def hat(xi: np.ndarray) -> np.ndarray:
    """(..., 4, 4) matrix form of the twist xi = (v, w), (..., 6)."""
    xi = np.asarray(xi, dtype=float)
    X = np.zeros(xi.shape[:-1] + (4, 4))
    X[..., :3, :3] = skew(xi[..., 3:])
    X[..., :3, 3] = xi[..., :3]
    return X


def rotation_twist(direction, point) -> np.ndarray:
    """(6,) unit twist of a rotation about the line through ``point`` (mm) along ``direction``."""
    w = np.asarray(direction, dtype=float)
    return np.concatenate([-np.cross(w, np.asarray(point, dtype=float)), w])


def exp_twist(xi: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """(N, 4, 4) exp(hat(xi) * theta) in closed form (Rodrigues; Murray, Li, Sastry eq. 2.36).

    xi : (6,) or (N, 6) twist; |w| is 0 (translation, theta in mm per unit v) or any positive value
    (the rotation angle is |w| theta). theta : (N,).
    """
    theta = np.asarray(theta, dtype=float).reshape(-1)
    n = theta.shape[0]
    xi = np.broadcast_to(np.asarray(xi, dtype=float), (n, 6))
    v, w = xi[:, :3], xi[:, 3:]
    nw = np.linalg.norm(w, axis=1)
    T = np.zeros((n, 4, 4))
    T[:, 3, 3] = 1.0
    T[:, :3, :3] = np.eye(3)
    T[:, :3, 3] = v * theta[:, None]
    rot = nw > 0
    if np.any(rot):
        wn = w[rot] / nw[rot, None]
        vn = v[rot] / nw[rot, None]
        th = theta[rot] * nw[rot]
        K = skew(wn)
        s, c = np.sin(th)[:, None, None], np.cos(th)[:, None, None]
        R = np.eye(3) + s * K + (1.0 - c) * (K @ K)
        wxv = np.cross(wn, vn)
        t = np.einsum("nij,nj->ni", np.eye(3) - R, wxv) + wn * np.sum(wn * vn, axis=1)[:, None] * th[:, None]
        T[rot, :3, :3] = R
        T[rot, :3, 3] = t
    return T


def adjoint(g: np.ndarray) -> np.ndarray:
    """(..., 6, 6) adjoint of the transform g (..., 4, 4) acting on twists (v, w):
    Ad_g = [[R, hat(p) R], [0, R]], so that hat(Ad_g xi) = g hat(xi) g^-1."""
    g = np.asarray(g, dtype=float)
    R, p = g[..., :3, :3], g[..., :3, 3]
    A = np.zeros(g.shape[:-2] + (6, 6))
    A[..., :3, :3] = R
    A[..., 3:, 3:] = R
    A[..., :3, 3:] = skew(p) @ R
    return A


def _exp_product(twists, thetas, n):
    """(N, 4, 4) product of exp(xi_k theta_k) in the given order."""
    T = np.broadcast_to(np.eye(4), (n, 4, 4)).copy()
    for xi, th in zip(twists, thetas):
        T = T @ exp_twist(xi, th)
    return T


def _elementary_rotation(j: int, angle: float) -> np.ndarray:
    return exp_twist(rotation_twist(np.eye(3)[j], np.zeros(3)), np.array([angle]))[0]


# --------------------------------------------------------------------------------- errors of each axis
def _check_base(model: ErrorModel):
    if model.terms:
        raise NotImplementedError("the product-of-exponentials and differential-change formulations "
                                  "cover the base model only (no extension terms)")


def component_errors(model: ErrorModel, p: np.ndarray, q: np.ndarray) -> dict[str, dict[str, np.ndarray]]:
    """Values of every axis's component errors at the poses, internal units.

    Returns {axis: {component: (N,)}}: for a linear axis L its six ``E<d>L`` (mm, rad); for a rotary
    axis its angular positioning error (e.g. ECC) and its five error motions. Base model only.
    """
    _check_base(model)
    m = model.machine
    P = dict(zip(model.param_names, np.asarray(p, dtype=float)))
    q = np.atleast_2d(np.asarray(q, dtype=float))
    out = {}
    for ax in m.axes:
        s = q[:, m.index(ax.name)]
        comps = {}
        if ax.is_rotary:
            own = positioning_component(ax.name)
            e = np.full_like(s, P[f"{own}_0"])
            for k in range(1, ax.fourier_order + 1):
                e = e + P[f"{own}_c{k}"] * np.cos(k * s) + P[f"{own}_s{k}"] * np.sin(k * s)
            comps[own] = e
            for comp in rotary_motion_names(ax.name):
                e = np.zeros_like(s)
                # the axial motion from harmonic 1, the radial and tilt pairs from 2 (their first
                # harmonic is the axis line's location: ISO 230-7 removes it as centring)
                axial = comp[1] == "XYZ"["ABC".index(ax.name)]
                for k in range(1 if axial else 2, ax.error_motion_order + 1):
                    e = e + P[f"{comp}_c{k}"] * np.cos(k * s) + P[f"{comp}_s{k}"] * np.sin(k * s)
                comps[comp] = e
        else:
            comps = linear_components(model.machine, ax.name, s, P.__getitem__, np.zeros_like(s))
        out[ax.name] = comps
    return out


def tool_shift(model: ErrorModel, q, c) -> np.ndarray:
    """(N,) mm: how much longer each row's tool is than the machine's reference tool, the distance
    tool length compensation moves the ram (Z, when it carries the spindle: the last axis of the tool
    chain) for the same tip; zeros on a machine without such a ram."""
    m = model.machine
    q = np.atleast_2d(np.asarray(q, dtype=float))
    if not m.tool_chain or m.tool_chain[-1] != "Z":
        return np.zeros(q.shape[0])
    c = model.default_context(q.shape[0]) if c is None else np.atleast_2d(np.asarray(c, dtype=float))
    return c[:, model.context_names.index("tool_length")] - m.tool_length


def machine_positions(model: ErrorModel, q, c) -> np.ndarray:
    """(N, n_axes): the commanded positions q with the ram at its machine position q_Z + shift."""
    q = np.atleast_2d(np.asarray(q, dtype=float)).copy()
    shift = tool_shift(model, q, c)
    if shift.any():
        q[:, model.machine.index("Z")] += shift
    return q


def prepare_inputs(model: ErrorModel, p, q, c):
    """Common set-up: (machine positions (N, n_axes) (:func:`machine_positions`), c (N, n_context),
    {name: value}, component errors at the machine positions)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    c = model.default_context(q.shape[0]) if c is None else np.atleast_2d(np.asarray(c, dtype=float))
    p = np.asarray(p, dtype=float)
    qm = machine_positions(model, q, c)
    return qm, c, dict(zip(model.param_names, p)), component_errors(model, p, qm)


def rotary_line_errors(P: dict, ax) -> tuple[np.ndarray, list[int], np.ndarray, np.ndarray]:
    """Location errors of a rotary axis line: (nominal axis point (3,) mm, the two other directions,
    offset of the point (3,) mm, tilt angles (3,) rad: about others[0] then others[1])."""
    d = ax.direction_index
    offsets, tilts = rotary_location_names(ax.name)
    others = [j for j in range(3) if j != d]
    shift, tilt = np.zeros(3), np.zeros(3)
    for j, on, tn in zip(others, offsets, tilts):
        shift[j], tilt[j] = P[on], P[tn]
    return np.asarray(ax.axis_point, dtype=float), others, shift, tilt


def squareness_rotation(model: ErrorModel, p: np.ndarray, axis_name: str) -> np.ndarray:
    """(4, 4) the rotation that tilts the direction of linear axis Y (C0Y) or Z (B0Z, A0Z)."""
    P = dict(zip(model.param_names, np.asarray(p, dtype=float)))
    G = np.eye(4)
    if axis_name == "Y":
        G = _elementary_rotation(2, P.get("C0Y", 0.0))
    elif axis_name == "Z":
        G = _elementary_rotation(1, P.get("B0Z", 0.0)) @ _elementary_rotation(0, P.get("A0Z", 0.0))
    return G


def _reference_point(model: ErrorModel, side: str, c_row: np.ndarray) -> np.ndarray:
    """(N, 3) carriage reference point r, fixed on the carriage: the spindle gauge point at q = 0
    with the machine's reference tool (tool side, whatever the row's tool) or the workpiece origin."""
    n = c_row.shape[0]
    r = np.zeros((n, 3))
    if side == "tool":
        r[:, 2] = model.machine.tool_length
    return r


def poe_transforms(model: ErrorModel, p, q, c=None, errors: bool = True,
                   error_side: str = "left") -> dict[str, np.ndarray]:
    """(N, 4, 4) actual motion of each axis, ``exp(xi^e) exp(xi^r theta)`` (eq. 4), keyed by axis.

    With ``errors=False`` the ideal motions ``exp(xi theta)`` (eqs. 1, 2). ``error_side='right'``
    multiplies the same error exponentials on the right, ``exp(xi^r theta) exp(xi^e)``, as Tan et al. (2026)
    eq. 9 prints it: this is *not* the model (tests use it to show that eq. 9's order contradicts the
    fixed-frame error definitions).
    """
    if error_side not in ("left", "right"):
        raise ValueError(f"error_side must be 'left' or 'right', got {error_side!r}")
    _check_base(model)
    m = model.machine
    p = np.asarray(p, dtype=float) if errors else np.zeros(model.n_params)
    q, c, P, E = prepare_inputs(model, p, q, c)
    n = q.shape[0]
    out = {}
    for ax in m.axes:
        s = q[:, m.index(ax.name)]
        d = ax.direction_index
        e_d = np.eye(3)[d]
        comps = E[ax.name]
        if ax.is_rotary:
            point, others, shift, tilt_angles = rotary_line_errors(P, ax)
            xi0 = rotation_twist(e_d, point)
            # G_loc: tilt of the line about the nominal axis point, then its offset
            tilt = _elementary_rotation(others[1], tilt_angles[others[1]]) @ \
                _elementary_rotation(others[0], tilt_angles[others[0]])
            G_loc = exp_twist(np.concatenate([shift, np.zeros(3)]), np.ones(1))[0] @ \
                _translate(point) @ tilt @ _translate(-point)
            xi_actual = adjoint(G_loc) @ xi0
            ideal = exp_twist(xi_actual, s + comps[positioning_component(ax.name)])
            p_actual = point + shift
            error = exp_twist(np.concatenate([[1.0, 0.0, 0.0], np.zeros(3)]),
                              comps[f"EX{ax.name}"])
            error = error @ exp_twist(np.array([0, 1.0, 0, 0, 0, 0]), comps[f"EY{ax.name}"])
            error = error @ exp_twist(np.array([0, 0, 1.0, 0, 0, 0]), comps[f"EZ{ax.name}"])
            for j in range(3):
                if j != d:
                    error = error @ exp_twist(rotation_twist(np.eye(3)[j], p_actual),
                                              comps[f"E{ANGLE_LETTERS[j]}{ax.name}"])
            out[ax.name] = error @ ideal if error_side == "left" else ideal @ error
            continue
        xi = adjoint(squareness_rotation(model, p, ax.name)) @ np.concatenate([e_d, np.zeros(3)])
        r = _reference_point(model, ax.side, c)
        trans_twists = [np.concatenate([np.eye(3)[j], np.zeros(3)]) for j in range(3)]
        delta = [comps[f"E{TRANSLATION_LETTERS[j]}{ax.name}"] for j in range(3)]
        eps = [comps[f"E{ANGLE_LETTERS[j]}{ax.name}"] for j in range(3)]
        rot_twists = [np.stack([rotation_twist(np.eye(3)[j], r[i]) for i in range(n)]) for j in range(3)]
        if ax.side == "tool":
            ideal = exp_twist(xi, s)
            # error twists of the carriage frame, moved to the fixed frame: Ad_{exp(xi s)}
            Ad = adjoint(ideal)
            twists = trans_twists + [np.einsum("nij,nj->ni", Ad, t) for t in rot_twists]
            error = _exp_product(twists, delta + eps, n)
        else:
            ideal = exp_twist(-xi, s)
            # inverse of (translation . rotations), r = workpiece origin: already in the fixed frame
            twists = [rot_twists[2], rot_twists[1], rot_twists[0]] + trans_twists[::-1]
            error = _exp_product(twists, [-eps[2], -eps[1], -eps[0], -delta[2], -delta[1], -delta[0]], n)
        out[ax.name] = error @ ideal if error_side == "left" else ideal @ error
    return out


def _translate(v):
    T = np.eye(4)
    T[:3, 3] = v
    return T


def poe_tool_pose(model: ErrorModel, p, q, c=None, errors: bool = True,
                  error_side: str = "left") -> tuple[np.ndarray, np.ndarray]:
    """Tool tip (N, 3) mm and tool axis (N, 3) in the workpiece frame: g_wt = g_fw^-1 g_ft (eq. 5).

    p (n_params,) internal units; q (N, n_axes) mm and rad; c (N, n_context) or None (defaults).
    """
    m = model.machine
    q = np.atleast_2d(np.asarray(q, dtype=float))
    n = q.shape[0]
    A = poe_transforms(model, p, q, c, errors, error_side)
    g_fw = np.broadcast_to(np.eye(4), (n, 4, 4)).copy()
    for name in m.workpiece_chain:
        g_fw = g_fw @ A[name]
    g_ft = np.broadcast_to(np.eye(4), (n, 4, 4)).copy()
    for name in m.tool_chain:
        g_ft = g_ft @ A[name]
    P = dict(zip(model.param_names, p))
    shift = tool_shift(model, q, c)
    dL = (float(P["TOOL_dL"]) if errors else 0.0) + shift
    if errors and (P.get("A0S", 0.0) or P.get("B0S", 0.0)):
        # spindle tilt: exp of two rotation twists about the gauge point r = (0, 0, L - shift) of the
        # ram's frame, the tool's length above its tip (Y after X)
        L = (model.default_context(n) if c is None else np.atleast_2d(c))[:, model.context_names.index("tool_length")]
        R = Rotation.from_rotvec([0.0, P["B0S"], 0.0]).as_matrix() @ Rotation.from_rotvec([P["A0S"], 0.0, 0.0]).as_matrix()
        r = np.zeros((n, 3))
        r[:, 2] = L - shift
        tilt = np.broadcast_to(np.eye(4), (n, 4, 4)).copy()
        tilt[:, :3, :3] = R
        tilt[:, :3, 3] = r - r @ R.T
        g_ft = g_ft @ tilt
    g_ft = g_ft @ exp_twist(np.array([0, 0, -1.0, 0, 0, 0]), dL)  # g_ft(0)
    g_wt = np.linalg.solve(g_fw, g_ft)
    return g_wt[:, :3, 3].copy(), g_wt[:, :3, 2].copy()


def poe_deviation(model: ErrorModel, p, q, c=None) -> np.ndarray:
    """(N, 6): actual minus nominal tool tip (mm) and tool axis, workpiece frame (eq. 6)."""
    tip, axis = poe_tool_pose(model, p, q, c, errors=True)
    tip0, axis0 = poe_tool_pose(model, p, q, c, errors=False)
    return np.concatenate([tip - tip0, axis - axis0], axis=1)

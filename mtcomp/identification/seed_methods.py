"""The direct (closed-form) methods of the papers mtcomp builds on (docs/references.md), as plain
computations.

* Yang et al. (2020), eq. 1: the instantaneous rotation centre (IRC) of a table from the velocities of
  two of its points (:func:`irc_from_velocities`), the yaw rate about it
  (:func:`yaw_rate_from_velocities`), and eq. 3, the yaw Abbe error about it (:func:`abbe_error_about_irc`).
* Tan et al. (2026), eqs. 10-15: three-sphere intersection (trilateration) of ball-bar lengths
  (:func:`trilaterate`, :func:`three_sphere_points`), the five position-dependent errors of the C
  axis from two axis points per angle (:func:`three_sphere_errors`), the prediction of table points
  with them (eq. 9 in the order of eq. 5, :func:`predict_table_point`) and the prediction error
  (eq. 15, :func:`prediction_error`).
* Pi et al. (2017): positioning error, backlash and compensation table of a rotary axis from laser
  readings in both approach directions (:func:`rotary_positioning`).

docs/seed_methods.md checks every printed equation and says where the print is wrong.
Units: mm, rad, mm/min inside; the result objects say when they convert.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..measurement.files import BallbarData, LaserData
from ..kinematics import forward, wp2bed
from ..machine import Machine


# --------------------------------------------------------------------------- Yang et al. (2020)
def irc_from_velocities(m_xy, m_v, n_xy, n_v, v0) -> np.ndarray:
    """(n, 2) mm instantaneous rotation centre O_p of a table moving along X (Yang et al. (2020), eq. 1).

    m_xy, n_xy : (n, 2) mm coordinates of the points M and N (table frame).
    m_v, n_v : (n, 2) mm/min their measured velocities (V_Mx, V_My), (V_Nx, V_Ny).
    v0 : (n,) or scalar mm/min the table's translation speed along X (signed).

    Eq. 1 as printed: the two lines ``y - y_M = -(V_Mx - V0)/V_My (x - x_M)`` and
    ``y - y_N = -(V_Nx - V0)/V_Ny (x - x_N)`` intersect at O_p. Each is the line through the point
    perpendicular to its velocity relative to the translation; rigid motion ``v = V0 e_x + w e_z x
    (P - O)`` gives exactly that, so the equation is right (docs/seed_methods.md). The slopes are
    infinite when a V_y is 0 (no yaw rate): NaN then, and where the lines are parallel.
    """
    m_xy, n_xy = np.atleast_2d(m_xy).astype(float), np.atleast_2d(n_xy).astype(float)
    m_v, n_v = np.atleast_2d(m_v).astype(float), np.atleast_2d(n_v).astype(float)
    v0 = np.broadcast_to(np.asarray(v0, dtype=float), (m_xy.shape[0],))
    with np.errstate(divide="ignore", invalid="ignore"):
        k_m = -(m_v[:, 0] - v0) / m_v[:, 1]
        k_n = -(n_v[:, 0] - v0) / n_v[:, 1]
        x = (n_xy[:, 1] - m_xy[:, 1] + k_m * m_xy[:, 0] - k_n * n_xy[:, 0]) / (k_m - k_n)
        y = m_xy[:, 1] + k_m * (x - m_xy[:, 0])
    out = np.column_stack([x, y])
    out[~np.all(np.isfinite(out), axis=1)] = np.nan
    return out


def yaw_rate_from_velocities(xy, v, irc_xy, v0) -> np.ndarray:
    """(n,) rad/min the yaw rate w of a table moving along X, from the velocity v (n, 2) mm/min of its
    point xy (n, 2) mm and the rotation centre irc_xy (n, 2) mm (Yang et al. (2020), eq. 1 solved for O
    first): ``w = ((P - O) x (v - V0 e_x))_z / |P - O|^2``. Divided by the signed speed v0 it is the slope
    d eps_z / ds of the yaw error (rad/mm)."""
    r = np.atleast_2d(xy) - np.atleast_2d(irc_xy)
    u = np.atleast_2d(v).astype(float).copy()
    u[:, 0] -= np.asarray(v0, dtype=float)
    return (r[:, 0] * u[:, 1] - r[:, 1] * u[:, 0]) / np.einsum("ij,ij->i", r, r)


def abbe_error_about_irc(eps_z, point_xy, irc_xy) -> np.ndarray:
    """(n, 2) mm yaw Abbe positioning error of table point B about the rotation centre O_p (Yang et al.
    (2020), eq. 3): ``delta = (-eps_z (y_B - y_O), eps_z (x_B - x_O))``. eps_z : (n,) rad yaw angle."""
    eps_z = np.asarray(eps_z, dtype=float)
    r = np.atleast_2d(point_xy) - np.atleast_2d(irc_xy)
    return np.column_stack([-eps_z * r[:, 1], eps_z * r[:, 0]])


# ---------------------------------------------------------------------------- Tan et al. (2026)
def trilaterate(centres, radii, near) -> np.ndarray:
    """(n, 3) mm the intersection of three spheres nearest to ``near`` (Tan et al. (2026), Fig. 4).

    centres : (n, 3, 3) mm sphere centres (three per problem). radii : (n, 3) mm. near : (n, 3) mm a
    point near the wanted root (three spheres meet in two points D and D', mirror images through the
    plane of the centres; Tan et al. take the one near the rotary axis). Where noise makes the spheres
    miss each other, the point of the centres' plane closest to all three is returned.
    """
    P = np.asarray(centres, dtype=float).reshape(-1, 3, 3)
    r = np.asarray(radii, dtype=float).reshape(-1, 3)
    near = np.asarray(near, dtype=float).reshape(-1, 3)
    p1 = P[:, 0]
    d21, d31 = P[:, 1] - p1, P[:, 2] - p1
    d = np.linalg.norm(d21, axis=1)
    ex = d21 / d[:, None]
    i = np.einsum("ij,ij->i", ex, d31)
    ey = d31 - i[:, None] * ex
    ey /= np.linalg.norm(ey, axis=1)[:, None]
    ez = np.cross(ex, ey)
    j = np.einsum("ij,ij->i", ey, d31)
    x = (r[:, 0] ** 2 - r[:, 1] ** 2 + d ** 2) / (2 * d)
    y = (r[:, 0] ** 2 - r[:, 2] ** 2 + i ** 2 + j ** 2) / (2 * j) - i / j * x
    z = np.sqrt(np.maximum(r[:, 0] ** 2 - x ** 2 - y ** 2, 0.0))
    base = p1 + x[:, None] * ex + y[:, None] * ey
    side = np.sign(np.einsum("ij,ij->i", near - base, ez))
    side[side == 0] = 1.0
    return base + (side * z)[:, None] * ez


@dataclass(frozen=True)
class ThreeSpherePoints:
    """Table-ball positions found by trilateration, one per (set-up height, C angle).

    angle : (m,) rad C angle. height : (m,) mm nominal height of the table ball above the C axis point.
    point : (m, 3) mm actual table-ball centre, machine frame (D of Tan et al. (2026)).
    nominal : (m, 3) mm its nominal position. lengths : (m, 3) mm mean bar lengths (repeats averaged).
    n_readings : (m,) readings averaged.
    """

    angle: np.ndarray
    height: np.ndarray
    point: np.ndarray
    nominal: np.ndarray
    lengths: np.ndarray
    n_readings: np.ndarray


def three_sphere_points(data: BallbarData, machine: Machine, decimals: int = 6) -> ThreeSpherePoints:
    """Tan et al. (2026), section 2.1: average the repeats, then trilaterate each (height, C angle).

    Rows are grouped by C angle (rounded to ``decimals`` deg) and table ball; within a group the
    distinct tool-ball positions (machine frame: nominal tip plus the tool-ball offset) are the three
    sphere centres and the mean lengths their radii. InputError when a group has not exactly three
    bar directions.
    """
    if "C" not in machine.axis_names:
        raise InputError(f"three-sphere evaluation needs a C axis; machine {machine.name!r} has none",
                         data.path)
    q = data.axis_positions(machine)
    T = wp2bed(machine, q)
    tip, _ = forward(machine, q)
    tool_bed = np.einsum("nij,nj->ni", T[:, :3, :3], tip + data.tool_ball) + T[:, :3, 3]
    table_bed = np.einsum("nij,nj->ni", T[:, :3, :3], data.table_ball) + T[:, :3, 3]
    ok = np.isfinite(data.length)
    angle_deg = np.round(np.degrees(q[:, machine.index("C")]), decimals)
    key_table = np.round(table_bed, 4)
    key_tool = np.round(tool_bed, 4)
    groups: dict = {}
    for i in np.flatnonzero(ok):
        groups.setdefault((angle_deg[i], *key_table[i]), {}).setdefault(tuple(key_tool[i]), []).append(i)
    keys = sorted(groups, key=lambda k: (k[3], k[0]))
    centres, radii, near, angle, height, counts = [], [], [], [], [], []
    ap = np.asarray(machine.axis("C").axis_point, dtype=float)
    for key in keys:
        sub = groups[key]
        if len(sub) != 3:
            first = next(iter(sub.values()))[0]
            same_angle = sum(k[0] == key[0] for k in keys)
            why = ("; the table ball stands elsewhere on the bed in the other rows of this angle (the "
                   "table moved with a linear axis between the bar directions: the method takes the "
                   "three directions with the table still, by moving the tool ball)"
                   if len(sub) < 3 and same_angle > 1 else "")
            data.fail(f"three-sphere evaluation: C = {key[0]:g} deg with table ball at "
                      f"{key[1]:g}, {key[2]:g}, {key[3]:g} (bed frame) has {len(sub)} bar "
                      f"directions, not 3{why}", first)
        cen = np.array([tool_bed[v[0]] for v in sub.values()])
        rad = np.array([np.mean(data.length[v]) for v in sub.values()])
        centres.append(cen)
        radii.append(rad)
        near.append(table_bed[next(iter(sub.values()))[0]])
        angle.append(math.radians(key[0]))
        height.append(key[3] - ap[2])
        counts.append(sum(len(v) for v in sub.values()))
    centres, radii, near = np.array(centres), np.array(radii), np.array(near)
    return ThreeSpherePoints(np.array(angle), np.array(height), trilaterate(centres, radii, near),
                             near, radii, np.array(counts))


def three_sphere_errors(D1, D2, h1: float, h2: float, exact: bool = False) -> dict[str, np.ndarray]:
    """The five position-dependent errors of the C axis per angle from two axis points (Tan et al. (2026)).

    D1, D2 : (m, 3) mm actual positions of the table balls set at heights h1 and h2 (mm) on the axis,
    machine frame with the origin at the C table's centre (the points of :func:`three_sphere_points`).
    Returns 'EXC', 'EYC', 'EZC' (mm) and 'EAC', 'EBC' (rad) of each angle (the paper's delta_xc, delta_yc,
    delta_zc, epsilon_xc, epsilon_yc):

    * eq. 10: ``delta_zc = (z1 + z2)/2 - (h1 + h2)/2``
    * eq. 11, 12: ``delta_xc = z1 (x1 - x2)/(z2 - z1) + x1`` (the line D1 D2 at z = 0), same for y
    * eq. 13: ``eps_xc = arcsin((y1 - y2) / sqrt((y2 - y1)^2 + (z2 - z1)^2))``
    * eq. 14: ``eps_yc = arcsin((x2 - x1) / sqrt((x2 - x1)^2 + (z2 - z1)^2))``

    These are right, signs included, for the error matrix of eq. 7 applied as in eq. 5 (error times
    ideal motion): a table point (0, 0, h) goes to (dx + ey h, dy - ex h, h + dz). ``exact=True``
    interpolates at the nominal height 0 instead of at z = 0 (a second-order difference:
    eps * delta_zc) and gives the angles of the exact rotation (same to O(eps^3)).
    """
    D1, D2 = np.atleast_2d(D1).astype(float), np.atleast_2d(D2).astype(float)
    x1, y1, z1 = D1.T
    x2, y2, z2 = D2.T
    dzc = (z1 + z2) / 2 - (h1 + h2) / 2
    if exact:
        lam = -h1 / (h2 - h1)
        dxc = x1 + lam * (x2 - x1)
        dyc = y1 + lam * (y2 - y1)
        dzc = z1 + lam * (z2 - z1)
    else:
        dxc = z1 * (x1 - x2) / (z2 - z1) + x1
        dyc = z1 * (y1 - y2) / (z2 - z1) + y1
    exc = np.arcsin((y1 - y2) / np.hypot(y2 - y1, z2 - z1))
    eyc = np.arcsin((x2 - x1) / np.hypot(x2 - x1, z2 - z1))
    return {"EXC": dxc, "EYC": dyc, "EZC": dzc, "EAC": exc, "EBC": eyc}


def error_matrix(errors: dict, index=slice(None)) -> np.ndarray:
    """(m, 4, 4) the C axis error matrix of Tan et al. (2026), eq. 7 (small angles, eps_zc = 0 when
    absent)."""
    dx, dy, dz = (np.atleast_1d(errors[k])[index] for k in ("EXC", "EYC", "EZC"))
    ex, ey = (np.atleast_1d(errors[k])[index] for k in ("EAC", "EBC"))
    ez = np.atleast_1d(errors.get("ECC", np.zeros_like(dx)))[index]
    E = np.zeros((dx.shape[0], 4, 4))
    E[:, 0] = np.column_stack([np.ones_like(dx), -ez, ey, dx])
    E[:, 1] = np.column_stack([ez, np.ones_like(dx), -ex, dy])
    E[:, 2] = np.column_stack([-ey, ex, np.ones_like(dx), dz])
    E[:, 3, 3] = 1.0
    return E


def predict_table_point(errors: dict, angle, point, order: str = "error_first") -> np.ndarray:
    """(m, 3) mm where a table point (3,) (table frame, origin at the C table centre) is at each C
    angle (m,) rad, from the identified errors (Tan et al. (2026), eq. 9, used as eq. 5 writes it:
    actual = error matrix . ideal rotation). ``order='ideal_first'`` applies eq. 9 as printed (ideal . error),
    which rotates the error motion with the table: wrong for errors identified by eqs. 10-14."""
    angle = np.atleast_1d(np.asarray(angle, dtype=float))
    E = error_matrix(errors)
    c, s = np.cos(angle), np.sin(angle)
    R = np.zeros((angle.size, 4, 4))
    R[:, 0, 0], R[:, 0, 1], R[:, 1, 0], R[:, 1, 1] = c, -s, s, c
    R[:, 2, 2] = R[:, 3, 3] = 1.0
    M = E @ R if order == "error_first" else R @ E
    p = np.append(np.asarray(point, dtype=float), 1.0)
    return (M @ p)[:, :3]


def prediction_error(predicted, actual) -> np.ndarray:
    """(m,) mm distance between predicted and actual points (Tan et al. (2026), eq. 15)."""
    return np.linalg.norm(np.atleast_2d(predicted) - np.atleast_2d(actual), axis=1)


def table_point_positions(fitted, angles, point, axis: str = "C") -> np.ndarray:
    """(m, 3) mm where an error model puts a table point (workpiece frame, (3,) mm) in the machine
    frame when rotary ``axis`` is at each angle (m,) rad and every other axis at 0.

    Uses the workpiece-side chain only: the parameters of the linear axes and the tool are set to zero
    so that the tool tip sits exactly at the commanded linear positions x; then x is found with
    ``tip_wp(x) = point`` (Newton; the Jacobian is the nominal rotation R0^T to first order).
    """
    model = fitted.model
    m = model.machine
    p = fitted.params.values.copy()
    for i, spec in enumerate(model.param_specs):
        g = spec.group.split(":")[0]
        if g in ("X", "Y", "Z", "squareness", "tool") or spec.name == "TOOL_dL":
            p[i] = 0.0
    angles = np.atleast_1d(np.asarray(angles, dtype=float))
    point = np.asarray(point, dtype=float)
    lin = [m.index(a) for a in "XYZ"]
    q = np.zeros((angles.size, m.n_axes))
    q[:, m.index(axis)] = angles
    c = fitted.context(angles.size)
    T0 = wp2bed(m, q)                          # nominal: x = R0 point + t0, and d tip / d x ~ R0^T
    x = np.einsum("nij,j->ni", T0[:, :3, :3], point) + T0[:, :3, 3]
    for _ in range(4):
        q[:, lin] = x
        tip = np.array([np.asarray(model.pose_function(q[k], p, c[k])[0]).ravel()
                        for k in range(angles.size)])
        x = x - np.einsum("nij,nj->ni", T0[:, :3, :3], tip - point)
    return x


# ----------------------------------------------------------------------------- Pi et al. (2017)
@dataclass(frozen=True)
class RotaryPositioning:
    """Positioning error, backlash and compensation table of a rotary axis (Pi et al. (2017)), rad.

    axis : 'A', 'B' or 'C'. targets : (m,) rad. mean_up, mean_down : (m,) mean angular positioning
    error (actual minus commanded) approaching up (+1) and down (-1). mean : (m,) bidirectional mean.
    backlash : (m,) mean up minus mean down (ISO 230-2 B_i). backlash_mean : mean over targets.
    compensation : (m,) pitch-error compensation table: the correction to add to the commanded angle,
    ``-mean`` (the backlash is compensated separately, by ``backlash_mean``: half of it added when
    approaching down, half subtracted up, so that both directions meet ``mean``).
    residual_up, residual_down : (m,) what remains after both compensations, per direction.
    """

    axis: str
    targets: np.ndarray
    mean_up: np.ndarray
    mean_down: np.ndarray
    mean: np.ndarray
    backlash: np.ndarray
    backlash_mean: float
    compensation: np.ndarray
    residual_up: np.ndarray
    residual_down: np.ndarray

    def table(self) -> str:
        """The compensation table in arcsec and urad, one line per target."""
        k = 180.0 / math.pi * 3600.0
        lines = [f"{'target_deg':>10} {'mean_up_urad':>13} {'mean_down_urad':>15} {'backlash_urad':>14} "
                 f"{'comp_urad':>10} {'comp_arcsec':>11}"]
        for i, t in enumerate(self.targets):
            lines.append(f"{math.degrees(t):10.3f} {self.mean_up[i] * 1e6:13.2f} "
                         f"{self.mean_down[i] * 1e6:15.2f} "
                         f"{self.backlash[i] * 1e6:14.2f} {self.compensation[i] * 1e6:10.2f} "
                         f"{self.compensation[i] * k:11.3f}")
        lines.append(f"backlash compensation: {self.backlash_mean * 1e6:.2f} urad "
                     f"({self.backlash_mean * k:.3f} arcsec)")
        return "\n".join(lines)


def rotary_positioning(data: LaserData, axis: str = "C") -> RotaryPositioning:
    """Pi et al. (2017): from angular positioning readings (E<axis><axis>, e.g. ECC, value_urad) of a rotary
    axis in both approach directions: the positioning error curve per direction, the backlash per
    target (mean up minus mean down, as ISO 230-2's B_i), and the compensation tables.

    The compensation removes the bidirectional mean (pitch table ``-mean``) and the mean backlash
    (``+-backlash_mean/2`` by direction); the residuals are what is left (before/after figures).
    """
    comp = f"E{axis}{axis}"
    sel = (data.axis == axis) & (data.component == comp) & np.isfinite(data.value)
    if not sel.any():
        raise InputError(f"no {comp} readings of axis {axis} in this laser file", data.path)
    tgt = np.round(data.target[sel], 12)
    val = data.value[sel]
    d = data.dir[sel]
    targets = np.unique(tgt)
    up = np.full(targets.size, np.nan)
    down = np.full(targets.size, np.nan)
    for i, t in enumerate(targets):
        at = tgt == t
        if (at & (d > 0)).any():
            up[i] = val[at & (d > 0)].mean()
        if (at & (d < 0)).any():
            down[i] = val[at & (d < 0)].mean()
    if np.isnan(up).all() or np.isnan(down).all():
        raise InputError(f"{comp} readings need both approach directions (dir +1 and -1)", data.path)
    mean = np.nanmean(np.vstack([up, down]), axis=0)
    backlash = up - down
    bl = float(np.nanmean(backlash))
    compensation = -mean
    return RotaryPositioning(axis, targets, up, down, mean, backlash, bl, compensation,
                             up + compensation - bl / 2, down + compensation + bl / 2)

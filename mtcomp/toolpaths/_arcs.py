"""Circular and helical arcs of G2/G3 blocks, and their split into chords.

Internal units: mm and rad. An arc is described in its plane by the two in-plane coordinates
``(first, second)`` chosen so that ``(first, second, normal)`` is right-handed: G17 (X, Y | Z),
G18 (Z, X | Y), G19 (Y, Z | X). Counter-clockwise (G3) is then the positive sense seen from the
positive end of the normal axis, as RS-274 prescribes for all three planes.
"""
from __future__ import annotations

import math

import numpy as np

#: plane G code -> (first in-plane XYZ index, second in-plane index, normal index)
PLANE_AXES = {17: (0, 1, 2), 18: (2, 0, 1), 19: (1, 2, 0)}
#: plane G code -> (offset letter of the first in-plane axis, of the second)
PLANE_OFFSET_LETTERS = {17: ("I", "J"), 18: ("K", "I"), 19: ("J", "K")}

#: an arc whose end radius differs from its start radius by more than this is refused (mm; a
#: 4-decimal inch program is off by up to 4 um through rounding alone) ...
ARC_RADIUS_TOL_MM = 1e-2
#: ... or by more than this fraction of the radius, whichever is larger
ARC_RADIUS_TOL_REL = 1e-4
#: start and end closer than this (mm) make an I/J/K arc a full circle
FULL_CIRCLE_TOL_MM = 1e-9
#: at most this many chords per arc (a guard against absurd radii and tolerances)
MAX_CHORDS = 1_000_000


class ArcError(ValueError):
    """The arc cannot be interpolated; the message says why (the reader adds file and line)."""


def centre_from_radius(s: np.ndarray, e: np.ndarray, radius: float, ccw: bool) -> np.ndarray:
    """Centre (2,) mm of the arc from ``s`` (2,) to ``e`` (2,) with signed radius (R word, mm).

    R > 0 selects the arc of at most 180 deg, R < 0 the larger one (RS-274). A chord up to
    ``ARC_RADIUS_TOL_MM`` longer than the diameter is taken as a half circle; a longer one is refused.
    """
    d = float(math.hypot(e[0] - s[0], e[1] - s[1]))
    r = abs(radius)
    if d == 0.0:
        raise ArcError("R arc with start = end is undefined (use I/J/K for a full circle)")
    if r == 0.0:
        raise ArcError("R arc with zero radius")
    h2 = r * r - 0.25 * d * d
    if h2 < 0.0:
        if 0.5 * d - r > max(ARC_RADIUS_TOL_MM, ARC_RADIUS_TOL_REL * r):
            raise ArcError(f"R arc impossible: the end point is {d:.6g} mm from the start, more than "
                           f"the diameter {2 * r:.6g} mm")
        h2 = 0.0
    h = math.sqrt(h2)
    ux, uy = (e[0] - s[0]) / d, (e[1] - s[1]) / d
    left = np.array([-uy, ux])
    side = 1.0 if ccw else -1.0          # the minor arc's centre lies left of the chord when CCW
    if radius < 0:
        side = -side
    return 0.5 * (s + e) + side * h * left


def arc_chords(start: np.ndarray, end: np.ndarray, centre2: np.ndarray, plane: int, ccw: bool,
               chord_tol: float, xyz_index: tuple[int, int, int]) -> np.ndarray:
    """End points (k, n_axes) of the chords of an arc, the last one exactly ``end``.

    start, end : (n_axes,) axis positions, mm and rad. centre2 : (2,) centre in the plane, mm.
    plane : 17, 18 or 19. xyz_index : where X, Y and Z sit in the axis vector.
    Every axis outside the plane (the helix axis, rotary axes) moves linearly with the swept angle.
    The radius may change slightly from start to end (a spiral, within the reader's tolerance): the
    chords follow the spiral, so both end points are exact. Sagitta of every chord <= chord_tol (mm).
    """
    i0, i1, _ = PLANE_AXES[plane]
    a, b = xyz_index[i0], xyz_index[i1]
    s = np.array([start[a], start[b]])
    e = np.array([end[a], end[b]])
    r0 = float(math.hypot(*(s - centre2)))
    r1 = float(math.hypot(*(e - centre2)))
    if r0 == 0.0 or r1 == 0.0:
        raise ArcError("arc with zero radius (start or end at the centre)")
    if abs(r1 - r0) > max(ARC_RADIUS_TOL_MM, ARC_RADIUS_TOL_REL * max(r0, r1)):
        raise ArcError(f"arc radius inconsistent: {r0:.6g} mm at the start, {r1:.6g} mm at the end")
    a0 = math.atan2(s[1] - centre2[1], s[0] - centre2[0])
    a1 = math.atan2(e[1] - centre2[1], e[0] - centre2[0])
    if math.hypot(*(e - s)) <= FULL_CIRCLE_TOL_MM:
        sweep = 2.0 * math.pi
    else:
        sweep = (a1 - a0) % (2.0 * math.pi) if ccw else (a0 - a1) % (2.0 * math.pi)
        if sweep == 0.0:
            sweep = 2.0 * math.pi
    rmax = max(r0, r1)
    if chord_tol >= rmax:
        max_step = math.pi / 2
    else:
        max_step = min(2.0 * math.acos(1.0 - chord_tol / rmax), math.pi / 2)
    n = max(1, math.ceil(sweep / max_step - 1e-12))
    if n > MAX_CHORDS:
        raise ArcError(f"arc would need {n} chords (radius {rmax:.6g} mm, chord tolerance "
                       f"{chord_tol:.3g} mm)")
    t = np.arange(1, n + 1) / n
    ang = a0 + (sweep if ccw else -sweep) * t
    rad = r0 + (r1 - r0) * t
    pts = start[None, :] + (end - start)[None, :] * t[:, None]
    pts[:, a] = centre2[0] + rad * np.cos(ang)
    pts[:, b] = centre2[1] + rad * np.sin(ang)
    pts[-1] = end
    return pts

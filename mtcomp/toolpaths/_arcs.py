"""Circular and helical arcs of G2/G3 blocks, and their split into chords.

Internal units: mm and rad. An arc is described in its plane by the two in-plane coordinates
``(first, second)`` chosen so that ``(first, second, normal)`` is right-handed: G17 (X, Y | Z),
G18 (Z, X | Y), G19 (Y, Z | X). Counter-clockwise (G3) is then the positive sense seen from the
positive end of the normal axis, as RS-274 prescribes for all three planes.
"""
from __future__ import annotations

import math

import numpy as np

from .passed import passed_end

#: plane G code -> (first in-plane XYZ index, second in-plane index, normal index)
PLANE_AXES = {17: (0, 1, 2), 18: (2, 0, 1), 19: (1, 2, 0)}
#: plane G code -> (offset letter of the first in-plane axis, of the second)
PLANE_OFFSET_LETTERS = {17: ("I", "J"), 18: ("K", "I"), 19: ("J", "K")}

#: an R arc whose chord is longer than its diameter by more than this (mm) ...
ARC_RADIUS_TOL_MM = 1e-2
#: ... or by more than this fraction of the radius, whichever is larger, is refused
ARC_RADIUS_TOL_REL = 1e-4
#: an I J K arc whose radius to the end differs from its radius to the start is followed as the
#: controller does (a spiral: the radius changes linearly with the angle) unless LinuxCNC would
#: refuse it (interp_arc.cc, arc_data_ijk; constants of interp_internal.hh): a difference over 100
#: times the absolute tolerance, or over both the absolute tolerance and 0.1 % of the radius. The
#: absolute tolerance is in the program's units: 2 * sqrt(2) * 0.001 in, or 2 * sqrt(2) * 0.01 mm
#: (any end point and centre rounded to 0.001 in or 0.01 mm passes)
SPIRAL_ABS_TOL_INCH = 2 * 0.001 * math.sqrt(2)
SPIRAL_ABS_TOL_MM = 2 * 0.01 * math.sqrt(2)
SPIRAL_REL_TOL = 0.001
#: start and end closer than this (mm) make an I/J/K arc a full circle
FULL_CIRCLE_TOL_MM = 1e-9
#: at most this many chords per arc (a guard against absurd radii and tolerances)
MAX_CHORDS = 1_000_000


class ArcError(ValueError):
    """The arc cannot be interpolated; the message says why (the reader adds file and line)."""


def is_point_circle(start: np.ndarray, end: np.ndarray, centre2: np.ndarray,
                    cols: tuple[int, int]) -> bool:
    """Whether an I/J/K arc from ``start`` to ``end`` (na,) about ``centre2`` (2,) is a full circle
    of zero radius that does not move the tool: the end is the start on every axis and the centre
    is the start, each within ``FULL_CIRCLE_TOL_MM`` (the same numbers as written; a program's
    resolution is 1e-4 mm at the finest). ``cols``: the two in-plane columns."""
    a, b = cols
    return (float(np.max(np.abs(end - start), initial=0.0)) <= FULL_CIRCLE_TOL_MM
            and math.hypot(start[a] - centre2[0], start[b] - centre2[1]) <= FULL_CIRCLE_TOL_MM)


def point_circle(start: np.ndarray, dialect: str) -> np.ndarray:
    """The one end point (1, na) of a full circle of zero radius (:func:`is_point_circle`): the
    start, so the block does not move and keeps the approach directions of the motion before it.
    grbl runs such a block without motion (gcode.c accepts it, both radii being 0; the planner
    drops its zero-length pieces); LinuxCNC refuses it (interp_arc.cc, arc_data_ijk: "Zero-radius
    arc"), so does the reader under its dialect."""
    if dialect == "linuxcnc":
        raise ArcError("arc with zero radius (a full circle about its own start): LinuxCNC refuses "
                       "it (\"Zero-radius arc\"); grbl runs it as a block that does not move (give "
                       "--dialect grbl if grbl runs it)")
    return np.asarray(start, dtype=float).copy()[None, :]


def radius_refused(r0: float, r1: float, inch: bool) -> bool:
    """Whether an arc of start radius r0 and end radius r1 (mm) is refused (the rule above)."""
    abs_tol = SPIRAL_ABS_TOL_INCH * 25.4 if inch else SPIRAL_ABS_TOL_MM
    err = abs(r1 - r0)
    return err > 100.0 * abs_tol or (err > abs_tol and err > SPIRAL_REL_TOL * max(r0, r1))


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
               chord_tol: float, xyz_index: tuple[int, int, int], inch: bool = False) -> np.ndarray:
    """End points (k, n_axes) of the chords of an arc, the last one exactly ``end``.

    start, end : (n_axes,) axis positions, mm and rad. centre2 : (2,) centre in the plane, mm.
    plane : 17, 18 or 19. xyz_index : where X, Y and Z sit in the axis vector.
    Every axis outside the plane (the helix axis, rotary axes) moves linearly with the swept angle.
    The radius may change from start to end (a spiral, within the controller's tolerance,
    :func:`radius_refused`; ``inch``: the program's units, which the tolerance is in): the chords
    follow the spiral, so both end points are exact. Sagitta of every chord <= chord_tol (mm).
    """
    i0, i1, _ = PLANE_AXES[plane]
    a, b = xyz_index[i0], xyz_index[i1]
    s = np.array([start[a], start[b]])
    e = np.array([end[a], end[b]])
    r0 = float(math.hypot(*(s - centre2)))
    r1 = float(math.hypot(*(e - centre2)))
    if r0 == 0.0 or r1 == 0.0:
        raise ArcError("arc with zero radius (start or end at the centre)")
    if radius_refused(r0, r1, inch):
        raise ArcError(f"arc radius inconsistent: {r0:.6g} mm at the start, {r1:.6g} mm at the end "
                       "(more than a controller accepts)")
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


# ------------------------------------------------------------------------ arcs of corrected points
def arc_sweep(s2, e2, centre2, ccw: bool, full: bool) -> tuple[float, float]:
    """(start angle, swept angle > 0) rad of the arc from s2 to e2 (2,) about centre2 (2,)."""
    a0 = math.atan2(s2[1] - centre2[1], s2[0] - centre2[0])
    if full:
        return a0, 2.0 * math.pi
    a1 = math.atan2(e2[1] - centre2[1], e2[0] - centre2[0])
    sweep = (a1 - a0) % (2.0 * math.pi) if ccw else (a0 - a1) % (2.0 * math.pi)
    return a0, (2.0 * math.pi if sweep == 0.0 else sweep)


def arc_points_at(start, end, centre2, cols, ccw: bool, full: bool, u) -> np.ndarray:
    """(m, na) points of the arc from start to end (na,) about centre2 at swept fractions u (m,):
    in the plane the radius goes linearly from its start value to its end value, every other axis
    moves linearly with the angle (as :func:`arc_chords`). cols : the two in-plane columns."""
    a, b = cols
    s2, e2 = np.array([start[a], start[b]]), np.array([end[a], end[b]])
    a0, sweep = arc_sweep(s2, e2, centre2, ccw, full)
    r0, r1 = float(np.hypot(*(s2 - centre2))), float(np.hypot(*(e2 - centre2)))
    u = np.asarray(u, dtype=float)
    ang = a0 + (sweep if ccw else -sweep) * u
    rad = r0 + (r1 - r0) * u
    pts = start[None, :] + (end - start)[None, :] * u[:, None]
    pts[:, a] = centre2[0] + rad * np.cos(ang)
    pts[:, b] = centre2[1] + rad * np.sin(ang)
    return pts


def fit_arc_centre(s2, e2, inner, ccw: bool, full: bool, hint, radius: float):
    """Centre (2,) of the circle through s2 and e2 (2,) closest to the points ``inner`` (m, 2)
    (algebraic least squares: the centre on the perpendicular bisector of s2 e2, or anywhere for a
    full circle through s2). Without inner points: the circle of ``radius`` through s2 and e2 whose
    centre lies on the side of ``hint`` (2,), or ``hint`` for a full circle. None when there is no
    such circle."""
    q = np.asarray(inner, dtype=float).reshape(-1, 2) - s2
    if full:
        if q.shape[0] < 2:
            return np.asarray(hint, dtype=float) if q.shape[0] == 0 else None
        c, *_ = np.linalg.lstsq(q, 0.5 * np.sum(q * q, axis=1), rcond=None)
        return s2 + c
    d = e2 - s2
    length = float(np.hypot(*d))
    if length == 0.0:
        return None
    mid = 0.5 * d
    nperp = np.array([-d[1], d[0]]) / length
    if q.shape[0] == 0:
        h2 = radius * radius - 0.25 * length * length
        if h2 < 0.0:
            return None
        side = 1.0 if float(np.dot(np.asarray(hint) - s2 - mid, nperp)) >= 0.0 else -1.0
        return s2 + mid + side * math.sqrt(h2) * nperp
    a = -2.0 * (q @ nperp)
    bb = -np.sum(q * q, axis=1) + 2.0 * (q @ mid)
    aa = float(a @ a)
    if aa == 0.0:
        return None
    return s2 + mid + (float(a @ bb) / aa) * nperp


def arc_misses(start, end, centre2, cols, ccw: bool, full: bool, samples, linear) -> tuple:
    """(largest distance mm over the linear axes, largest deviation rad over the rotary axes) of the
    points ``samples`` (m, na) from the arc start -> end (na,) about centre2: each point against
    the arc's point at its own angle (clamped to the arc's ends). linear : (na,) bool."""
    a, b = cols
    samples = np.asarray(samples, dtype=float)
    if samples.shape[0] == 0:
        return 0.0, 0.0
    s2, e2 = np.array([start[a], start[b]]), np.array([end[a], end[b]])
    a0, sweep = arc_sweep(s2, e2, centre2, ccw, full)
    phi = np.arctan2(samples[:, b] - centre2[1], samples[:, a] - centre2[0])
    turn = (phi - a0) if ccw else (a0 - phi)
    frac = np.mod(turn, 2.0 * math.pi) / sweep
    # just before the start reads as almost a full turn: take whichever end is nearer
    back = frac - 2.0 * math.pi / sweep
    frac = np.where((frac > 1.0) & (np.abs(back) < frac - 1.0), back, frac)
    expect = arc_points_at(start, end, centre2, cols, ccw, full, np.clip(frac, 0.0, 1.0))
    dev = samples - expect
    lin = np.asarray(linear, bool)
    dist = float(np.max(np.sqrt(np.sum(dev[:, lin] ** 2, axis=1)))) if lin.any() else 0.0
    rot = float(np.max(np.abs(dev[:, ~lin]))) if (~lin).any() else 0.0
    return dist, rot


def arc_samples(start, end, chord_ends, points, counts, centre2, cols, ccw: bool, full: bool):
    """The corrected path of an arc block as points along the arc.

    start, end : (na,) the block's nominal start and end. chord_ends : (n, na) its nominal chord
    ends. points : (M, na) the corrected points, counts (n,) of them per chord (None: one each),
    the last of each chord its corrected end; the others lie on the chord (nodes the planner
    inserted) and are moved by the chord's distance from the arc there, so that every point is
    the nominal arc's point plus its correction. Returns (intended points (M, na), their nominal
    places on the arc (M, na), their swept fractions (M,) in (0, 1]), or None when counts do not
    match."""
    n = chord_ends.shape[0]
    points = np.asarray(points, dtype=float)
    counts = np.ones(n, np.int64) if counts is None else np.asarray(counts, dtype=np.int64)
    if counts.shape[0] != n or int(counts.sum()) != points.shape[0]:
        return None
    row = np.repeat(np.arange(n), counts)
    is_end = np.zeros(points.shape[0], bool)
    is_end[np.cumsum(counts) - 1] = True
    s = np.vstack([start[None, :], chord_ends[:-1]])[row]
    d = chord_ends[row] - s
    c = list(cols)
    dd = np.sum(d[:, c] ** 2, axis=1)
    t = np.where(dd > 0, np.sum((points - s)[:, c] * d[:, c], axis=1) / np.where(dd > 0, dd, 1.0), 1.0)
    t = np.clip(t, 0.0, 1.0)
    t[is_end] = 1.0
    u = (row + t) / n
    on_arc = arc_points_at(start, end, centre2, cols, ccw, full, u)
    on_arc[is_end] = chord_ends[row[is_end]]
    intended = points + (on_arc - (s + t[:, None] * d))
    intended[is_end] = points[is_end]
    return intended, on_arc, u


# ------------------------------------------------------------------------ pieces of a split arc
#: steps from the circle nearest the source's towards the fitted one before the bisection
BISECTOR_STEPS = 4


def min_piece_length(radius: float, chord_tol: float) -> float:
    """The shortest piece (mm) a split arc of ``radius`` (mm) is cut into where a longer one holds:
    half the chord whose sagitta is ``chord_tol`` (mm), sqrt(tol (2 r - tol)). A piece shorter than
    the whole chord lies within the tolerance of its own chord, so its path no longer says its
    radius (any from r to a straight line fits), and half of it is a few interpolation cycles of
    the controller at a cutting feed rather than a fraction of one."""
    tol = min(chord_tol, radius)
    return math.sqrt(tol * (2.0 * radius - tol))


def piece_ends(length: np.ndarray, a: int, b: int, min_piece: float) -> list[int]:
    """The samples a piece from sample a may end at, in order, the last one b: at least
    ``min_piece`` (mm) along the path ``length`` (m,) from a, and leaving at least that much to b
    (or b itself, which ends the block however short the rest is)."""
    j = np.arange(a + 1, b)
    keep = (length[j] - length[a] >= min_piece) & (length[b] - length[j] >= min_piece)
    return [int(k) for k in j[keep]] + [b]


def near_bound(samples, nominal, cols, tol: float) -> float:
    """How far (mm) a split arc's piece's centre may lie from the source's for a machinist to
    recognise the source's circle: the largest in-plane correction along the arc (``samples`` less
    ``nominal``, (m, na)) and the tolerance ``tol`` (mm)."""
    c = (np.asarray(samples) - np.asarray(nominal))[:, list(cols)]
    return float(np.max(np.hypot(c[:, 0], c[:, 1]), initial=0.0)) + tol


def piece_centre(holds, s2, e2, shifted, fitted, resolution: float, source=None,
                 bound: float = math.inf):
    """The centre of a piece of a split arc from s2 to e2 (2,), as ``holds(centre)`` (2,) -> the
    piece about it, or None where it does not hold: the source's centre moved by the correction
    (``shifted`` (2,)) where its circle passes through the piece's corrected ends within the
    tolerance and holds the path; otherwise the circle through both ends whose centre is nearest
    to ``shifted`` (least change of centre: on the perpendicular bisector of s2 e2, from the foot
    of ``shifted`` on it towards ``fitted`` (2,), the one closest to the corrected points, or None)
    that holds, found to ``resolution`` (mm) by bisection. A short piece's path says little of its
    radius (any from the source's to a straight line fits within a micrometre), so the circle a
    machinist reads it on is the source's moved as little as the path allows. A centre farther
    than ``bound`` (mm) from ``source`` (2,) does not hold. None where none holds."""
    def ok(centre):
        if bound < math.inf and math.hypot(*(np.asarray(centre) - source)) > bound:
            return None
        return holds(centre)

    piece = ok(shifted)
    d = np.asarray(e2, float) - np.asarray(s2, float)
    if piece is not None or not np.any(d):
        return piece
    mid = 0.5 * (np.asarray(s2, float) + np.asarray(e2, float))
    along = np.array([-d[1], d[0]]) / math.hypot(*d)
    foot = mid + float(np.dot(np.asarray(shifted) - mid, along)) * along
    piece = ok(foot)
    if piece is not None or fitted is None:
        return piece
    step = float(np.dot(np.asarray(fitted) - foot, along))
    lo, hi = 0.0, None
    for t in np.arange(1, BISECTOR_STEPS + 1) / BISECTOR_STEPS:
        piece = ok(foot + t * step * along)
        if piece is not None:
            hi = t
            break
        lo = t
    if hi is None:
        return None
    while (hi - lo) * abs(step) > resolution:
        t = 0.5 * (lo + hi)
        nearer = ok(foot + t * step * along)
        if nearer is None:
            lo = t
        else:
            hi, piece = t, nearer
    return piece


def plan_pieces(arc_piece, straight_piece, points: np.ndarray, length: np.ndarray,
                min_piece: float, a: int, b: int, start_w: np.ndarray) -> list:
    """The pieces an arc is written as, from sample a (where the machine stands: ``start_w``
    (na,)) to sample b of ``points`` (m, na). ``arc_piece(a, k, start_w, near)``: the piece from
    sample a to sample k about the centre :func:`piece_centre` chooses, with its written ``end``
    (na,), or None where none holds; ``near``: only a centre within the correction (its largest
    size along the arc) and the tolerance of the source's, where a machinist recognises the
    source's circle. Each piece is the longest such near arc from where the last one ended;
    where none holds a piece's length (a ramp of the correction: a backlash's reversal), the
    longest arc about any centre, ending where a near arc holds again; a straight piece
    (``straight_piece(a, start_w)``, to sample a + 1) only where no arc reaches the next sample.
    The longest arcs are found by bisection over the samples they may end at (an arc that holds
    over a stretch holds over a shorter one from the same start), none shorter than
    ``min_piece`` (mm along ``length`` (m,)) where an arc that long holds (:func:`piece_ends`).
    The G-code, Heidenhain and Sinumerik writers plan their split arcs with it."""
    pieces = []
    while a < b:
        piece, end = _longest_piece(arc_piece, points, length, min_piece, a, b, start_w)
        if piece is None:
            end = a + 1
            piece = straight_piece(a, start_w)
        pieces.append(piece)
        a, start_w = end, piece.end
    return pieces


def _longest_piece(arc_piece, points, length, min_piece, a: int, b: int, start_w):
    """(the arc piece from sample a to the farthest sample one arc reaches, that sample), or
    (None, None) when no arc reaches even the next sample (:func:`plan_pieces`)."""
    ends = piece_ends(length, a, b, min_piece)

    def near(i, k, s):
        return arc_piece(i, k, s, True)

    best = _farthest(near, a, ends, start_w)
    if best[0] is not None:
        return best
    best = _farthest(arc_piece, a, ends, start_w)
    if best[0] is None:
        # a shorter piece only where the corrected path turns within less (a correction that
        # changes fast): the longest arc that holds there
        return _farthest(arc_piece, a, list(range(a + 1, ends[0])), start_w)
    for j in range(a + 1, best[1]):
        if near(j, piece_ends(length, j, b, min_piece)[0], points[j]) is not None:
            shorter = arc_piece(a, j, start_w)
            return best if shorter is None else (shorter, j)
    return best


def _farthest(arc_piece, a: int, ends: list, start_w):
    """(piece, end) of the farthest of ``ends`` (increasing sample indices) an arc from sample a
    reaches (the last first, then by bisection); (None, None) when it reaches none."""
    if not ends:
        return None, None
    piece = arc_piece(a, ends[-1], start_w)
    if piece is not None:
        return piece, ends[-1]
    lo, hi, best = 0, len(ends) - 2, (None, None)
    while lo <= hi:
        mid = (lo + hi) // 2
        piece = arc_piece(a, ends[mid], start_w)
        if piece is None:
            hi = mid - 1
        else:
            best, lo = (piece, ends[mid]), mid + 1
    return best


def arc_path(state, start, end, values, line: int):
    """(chord ends (k, na), centre (3,) mm) of the G2/G3 block read by ``state`` (a
    :class:`~.modal.ModalState`) from ``start`` to ``end`` (na,), its words ``values``: the centre
    from R or from the I J K offsets (absolute under G90.1), the chords within the chord tolerance
    (of the machine's arc under scaling); an arc the words do not make is refused naming the
    line."""
    from .words import MM_PER_INCH
    plane = state.plane
    i0, i1, _ = PLANE_AXES[plane]
    if min(state.xyz_index) < 0:
        raise state._err("arc on a machine without X, Y and Z axes", line)
    a, b = state.xyz_index[i0], state.xyz_index[i1]
    scale = MM_PER_INCH if state.inch else 1.0
    ccw = state.motion == 3
    l0, l1 = PLANE_OFFSET_LETTERS[plane]
    s2 = np.array([start[a], start[b]])
    try:
        if "R" in values:
            if any(c in values for c in "IJK"):
                raise ArcError("both R and I/J/K in one arc block")
            centre2 = centre_from_radius(s2, np.array([end[a], end[b]]), values["R"] * scale, ccw)
        else:
            other = set("IJK") - {l0, l1}
            bad = [c for c in other if values.get(c, 0.0) != 0.0]   # K0 in G17: harmless
            if bad:
                raise ArcError(f"{bad[0]} word is not an offset in plane G{plane}")
            if l0 not in values and l1 not in values:
                raise ArcError(f"arc without centre: give {l0}/{l1} or R in plane G{plane}")
            offset = scale * np.array([values.get(l0, 0.0), values.get(l1, 0.0)])
            if state.arc_absolute and not (l0 in values and l1 in values):
                raise ArcError(f"arc in G90.1 (absolute centre) without both {l0} and {l1}")
            centre2 = offset if state.arc_absolute else s2 + offset
        if "R" not in values and is_point_circle(start, end, centre2, (a, b)):
            pts = point_circle(start, state.dialect.name)
        else:
            # under scaling the chords are cut for the machine's arc (the tolerance on it)
            tol = state.chord_tol / state.local.scales().max()
            pts = arc_chords(start, end, centre2, plane, ccw, tol, state.xyz_index, state.inch)
    except ArcError as exc:
        raise state._err(str(exc), line) from None
    centre = np.zeros(3)
    xyz = [start[i] for i in state.xyz_index]
    centre[:] = xyz
    centre[i0], centre[i1] = centre2
    return pts, centre


def blind_arc(state, values, axes_given) -> bool:
    """A G2/G3 block that moves an axis whose position the program has not given (a program that
    starts with an arc, an arc right after a home move, a helix from a height nobody gave, an
    incremental arc from wherever the tool stands), or that starts from such a position in its
    plane: the controller runs it from wherever the machine stands, so nothing of its path is
    known and it is passed through as written, uncorrected (its source line, as the controller
    would run it without mtcomp). After it each axis it names stands, in G90, at its written value,
    known, in the program and in the output alike (``declared``); in G91 it moves by its increment
    from where it stood (an axis not known stays unknown; the output moves from where it stands,
    ``distance_sensitive``) (:func:`.passed.passed_end`). An absolute one must start where the
    output stands uncorrected in its plane (:func:`.passed.check_passed_start`, the writer's
    check). True when the block is such an arc; False for an arc whose every axis is known. The
    reader refuses an arc under unequal scales before it (:func:`.frames.check_arc`)."""
    i0, i1, _ = PLANE_AXES[state.plane]
    if min(state.xyz_index) < 0:
        return False
    state.passed_plane = [state.xyz_index[i0], state.xyz_index[i1]]
    if all(state.known[i] for i in state.passed_plane + [state.names.index(c) for c in axes_given]):
        return False
    passed_end(state, values, axes_given, "increment" if state.incremental else "arc", state._line)
    return True


#: the dialects whose G5 and G5.1 with coordinates are splines (LinuxCNC G-code reference, G5 cubic
#: spline, G5.1 quadratic spline; BeagleG's G-code.md, "G5 syntax"); generic reads as LinuxCNC. On
#: Fanuc and Haas G05 is a contour-control mode, and grbl, RepRapFirmware have no G5
SPLINE_DIALECTS = ("linuxcnc", "beagleg", "generic")


def spline_code(state, g: float, name: str, line: int) -> None:
    """A G5/G5.1 block with coordinates: a spline where the dialect has them (``state.spline``,
    read by :func:`passed_spline`), else refused."""
    if state.dialect.name not in SPLINE_DIALECTS:
        raise state._err(f"{name} is not supported", line)
    state.spline = g


def passed_spline(state, values, tokens, motion, line: int) -> None:
    """A G5 (cubic) or G5.1 (quadratic) spline in G17, X and Y its only axes: passed through as
    written, uncorrected (its control points, offsets from its ends, are not corrected), its end
    known where its start was or the block names the axis (in G90 ``declared``, as for an arc from
    a position not given, :func:`blind_arc`; in G91 the output moves by the increments from where
    it stands, ``distance_sensitive``). Refused as LinuxCNC refuses it: another plane, another
    axis, G5 without both P and Q or with one of I J, G5.1 without I or J; and under cutter radius
    compensation, a frame change or a motion code in the block. After it no motion mode is in force
    (LinuxCNC: G5 is a motion mode of its own, which axis words alone would continue without P Q),
    on BeagleG the last G0/G1 (the spline holds for its block only)."""
    name = "G5 (cubic spline)" if state.spline == 5 else "G5.1 (quadratic spline)"
    axes = state._axis_words(values, line)
    others = [c for c in axes if c not in "XY"] + [c for c in "UVW" if c in values]
    given = {letter for letter, _num, _raw in tokens}
    problem = ("not in G17 (its plane is X Y)" if state.plane != 17 else
               f"with {others[0]}: its axes are X and Y only" if others else
               f"with motion G{motion}" if motion is not None else
               "under cutter radius compensation" if state.cutter_comp else
               "under a frame change (G68, mirror image, scaling)" if state.local.kind else
               "without both P and Q" if state.spline == 5 and not {"P", "Q"} <= given else
               "with only one of I and J" if state.spline == 5 and len({"I", "J"} & given) == 1 else
               "without I or J" if state.spline == 5.1 and not {"I", "J"} & given else "")
    if problem:
        raise state._err(f"{name} {problem}", line)
    state._set_feed(values, line)
    passed_end(state, values, axes, "spline", line)
    state.motion = getattr(state, "linear_motion", None) if not state.dialect.arcs_modal else None
    state.cycle = None

"""The in-plane map of a planar program (a 2-D contour, a profile cut in step-downs): whether a
program is planar (:func:`planar_levels`), and its contour as wall segments whose normals lie in the
plane (:func:`inplane_geometry`), the moves that clear material inside a pocket left out."""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..kinematics import forward
from ..machine import Machine
from .geometry import SurfaceGeometry
from .program import ProgramPoints, drawn_q


#: a program is planar (a 2-D contour) when this share of its cutting path runs across a constant
#: tool axis and of its cutting points lies on at most PLANAR_MAX_LEVELS heights (to PLANAR_TOL_MM)
PLANAR_SHARE = 0.95
PLANAR_MAX_LEVELS = 10
PLANAR_TOL_MM = 1e-3
#: height of the band a contour of one level is drawn as, as a share of its extent (display only)
BAND_SHARE = 0.015
#: an in-plane map draws the contour with segments no shorter than this share of its extent (the
#: chords of arcs merged): the deviation is smooth on that scale, and 10k arcs stay a few seconds
MIN_SEGMENT_SHARE = 1.0 / 1000
#: a move with cut path on both sides, at about the same distance and within this share of the
#: contour's extent, clears material (a raster or offset pass inside a pocket): no wall, left out
#: of an in-plane map
CLEARING_SHARE = 0.05


def planar_levels(orig: ProgramPoints, machine: Machine) -> int:
    """The number of planes across the tool axis the program cuts in (0: not planar).

    Planar (a 2-D contour, engraving, a profile cut in a few step-downs): the tool axis is the same
    at every cutting point, at least ``PLANAR_SHARE`` of the cutting path's length runs across it
    (moves whose height along it changes by at most ``PLANAR_TOL_MM``), and at least that share of
    the cutting points lies on at most ``PLANAR_MAX_LEVELS`` heights (ramps and plunges may lie
    between), or on more heights of which each repeats, for at least half the length, the contour
    of the one below (a profile or a pocket cut in many step-downs). A sloped or curved surface,
    or waterline finishing over a form (each level's contour beside the one below), is not planar.

    The shares are of path length across the tool axis, not of points: a helical entry or a ramp
    written as an arc puts hundreds of chord ends between two levels on a few mm of path."""
    feed = np.flatnonzero(~orig.rapid)
    feed = feed[feed > 0]
    if feed.size < 2:
        return 0
    tips, axes = forward(machine, drawn_q(orig))
    axis = axes[feed[0]]
    if np.max(np.abs(axes[feed] - axis)) > 1e-9:
        return 0
    step = tips[feed] - tips[feed - 1]
    dh = step @ axis
    across = np.linalg.norm(step - dh[:, None] * axis, axis=1)
    flat = np.abs(dh) <= PLANAR_TOL_MM
    total = across.sum()
    if total <= 0 or across[flat].sum() < PLANAR_SHARE * total:
        return 0
    h = np.round(tips[feed[flat]] @ axis / PLANAR_TOL_MM).astype(np.int64)
    names, where = np.unique(h, return_inverse=True)
    length = np.bincount(where.ravel(), weights=across[flat])
    top = np.sort(length[length > 0])[::-1][:PLANAR_MAX_LEVELS]
    if top.sum() >= PLANAR_SHARE * total:
        return int(top.size)
    # more levels: a profile or a pocket cut in many step-downs (each level's contour on the one
    # below: walls) is planar; waterline passes over a form (each level's contour beside the one
    # below, as the form slopes) are a surface
    if _stacked_share(tips[feed[flat] - 1], tips[feed[flat]], where.ravel(), names * PLANAR_TOL_MM,
                      axis) >= 0.5:
        return int(np.count_nonzero(length > 0))
    return 0


def _samples(start, end, spacing):
    """Points along the moves ``start`` -> ``end`` (m, 3), at most ``spacing`` apart (ends
    included), and the length each stands for."""
    seg_len = np.linalg.norm(end - start, axis=1)
    count = np.maximum(np.ceil(seg_len / spacing).astype(np.int64), 1) + 1
    owner = np.repeat(np.arange(start.shape[0]), count)
    frac = (np.arange(owner.size) - np.repeat(np.cumsum(count) - count, count)) / (count[owner] - 1)
    return start[owner] + frac[:, None] * (end[owner] - start[owner]), seg_len[owner] / count[owner]


def _stacked_share(start, end, level, heights, axis) -> float:
    """Share of the length of flat moves (``start`` -> ``end`` (m, 3) mm, on level index ``level``
    of ``heights`` (mm along ``axis``)) that lies on the path of the next level below, to within
    tan(10 deg) of the step between them: the levels of a wall steeper than 80 deg."""
    from scipy.spatial import cKDTree
    flat_start = start - (start @ axis)[:, None] * axis
    flat_end = end - (end @ axis)[:, None] * axis
    order = np.argsort(heights)
    total = float(np.linalg.norm(end - start, axis=1).sum())
    extent = float(np.ptp(np.vstack([flat_start, flat_end]), axis=0).max())
    stacked = 0.0
    for k in range(1, order.size):
        above = level == order[k]
        hit = None
        # the three levels below: small features may be cut on levels between a contour's
        for lower in order[max(k - 3, 0):k]:
            below = level == lower
            tol = np.tan(np.radians(10.0)) * abs(float(heights[order[k]] - heights[lower]))
            # the path below to within a third of the tolerance (at most 200k points per level)
            spacing = max(tol / 3.0, np.linalg.norm(end[below] - start[below], axis=1).sum() / 2e5,
                          1e-6 * max(extent, 1.0))
            upper_pts, weight = _samples(flat_start[above], flat_end[above], extent / 500.0)
            lower_pts, _ = _samples(flat_start[below], flat_end[below], spacing)
            d, _ = cKDTree(lower_pts).query(upper_pts, distance_upper_bound=tol + 0.5 * spacing)
            hit = np.isfinite(d) if hit is None else hit | np.isfinite(d)
        stacked += float(weight[hit].sum())
    return stacked / max(total, 1e-300)


def inplane_geometry(orig: ProgramPoints, machine: Machine, radius: float, side: str):
    """A planar program's contour: the feed moves with a length across the tool axis, as wall
    segments whose normal lies in the plane (perpendicular to the move and the tool axis), pointing
    away from the middle of its pass (``side`` 'outer', a boss) or towards it ('inner', a pocket).

    * Runs of moves shorter than ``MIN_SEGMENT_SHARE`` of the contour's extent (the chords of an
      arc) are merged into one segment, up to a turn of 20 deg: the deviation is evaluated at the
      ends of the merged segments, which are segment ends of the program.
    * A move with cut path on both sides (:func:`_clearing_segments`: a raster or an offset pass
      inside a pocket, a face's raster) leaves no wall: it is left out (all are kept when every
      move is such).
    * The deviation is the tip's (or the tool axis point's, for a cutter of ``radius``: the same for
      a tool that does not tilt); each segment is drawn as a band up the tool axis from its contact
      line (to the next level above, for a wall cut in step-downs, else ``BAND_SHARE`` of the extent)
      with the deviation of its own two end points, so a corner keeps the normals of both walls.

    Returns (geometry, segments (S, 2) point indices of the contour, info dict)."""
    tips, axes = forward(machine, drawn_q(orig))
    j, unit, length, extent = _moves_across(orig, tips, axes)
    first, ends, new_pass = _merged_segments(j, unit, length, extent)
    a_idx, b_idx = j[first] - 1, j[ends]                    # program rows of each segment's ends
    t = tips[b_idx] - tips[a_idx]
    ax = axes[b_idx]
    t -= np.einsum("ij,ij->i", t, ax)[:, None] * ax
    seg_len = np.linalg.norm(t, axis=1)
    t /= np.maximum(seg_len, 1e-300)[:, None]
    n = np.cross(t, ax)
    mid = 0.5 * (tips[a_idx] + tips[b_idx])
    pass_id = np.cumsum(new_pass)[ends] - 1
    wall = ~_clearing_segments(tips[j - 1], tips[j], tips[a_idx], tips[b_idx], n, axes[j[0]],
                               extent)
    info = {"levels": 0, "clearing_moves": 0}
    if wall.any() and not wall.all():
        info["clearing_moves"] = int(np.count_nonzero(~wall))
        a_idx, b_idx, n, mid, seg_len, pass_id = (v[wall] for v in (a_idx, b_idx, n, mid, seg_len,
                                                                     pass_id))
    _, pass_id = np.unique(pass_id, return_inverse=True)
    n *= _outward(n, mid, seg_len, pass_id, side)[:, None]
    geometry, segments = _bands(tips, axes, a_idx, b_idx, n, mid, extent, radius, info)
    return geometry, segments, info


def _moves_across(orig: ProgramPoints, tips: np.ndarray, axes: np.ndarray):
    """(j, unit, length, extent) of the feed moves with a length across the tool axis: their rows in
    the program (each move from row j - 1 to row j), (m, 3) unit directions across the axis, (m,)
    lengths mm, and the contour's extent mm. InputError when there is none."""
    j = np.flatnonzero(~orig.rapid)
    j = j[j > 0]
    d = tips[j] - tips[j - 1]
    d -= np.einsum("ij,ij->i", d, axes[j])[:, None] * axes[j]
    length = np.linalg.norm(d, axis=1)
    keep = length > 1e-6
    j, d, length = j[keep], d[keep], length[keep]
    if j.size == 0:
        raise InputError("in-plane map: the program has no feed move across the tool axis",
                         orig.path)
    extent = max(float(np.max(np.ptp(tips[np.concatenate([j - 1, j])], axis=0))), 1e-3)
    return j, d / length[:, None], length, extent


def _merged_segments(j: np.ndarray, unit: np.ndarray, length: np.ndarray, extent: float):
    """(first, ends, new_pass): of each segment (runs of moves merged up to ``MIN_SEGMENT_SHARE`` of
    ``extent`` and a turn of 20 deg, never across passes) its first and last move (indices into
    ``j``), and (m,) bool, the move starts a pass (no rapid or move along the axis before it)."""
    new_pass = np.ones(j.size, bool)
    new_pass[1:] = j[1:] != j[:-1] + 1
    last = np.ones(j.size, bool)
    last[:-1] = new_pass[1:]
    turn = np.zeros(j.size, bool)
    turn[:-1] = np.einsum("ij,ij->i", unit[:-1], unit[1:]) < np.cos(np.radians(20.0))
    cum = np.cumsum(length)
    bucket = np.floor(cum / (MIN_SEGMENT_SHARE * extent)).astype(np.int64)
    crossed = bucket != np.concatenate([[0], bucket[:-1]])
    ends = np.flatnonzero(last | turn | crossed)          # moves whose end closes a segment
    first = np.empty_like(ends)      # the first move of each segment (a pass's last move is an end)
    first[0] = 0
    first[1:] = ends[:-1] + 1
    return first, ends, new_pass


def _outward(n: np.ndarray, mid: np.ndarray, seg_len: np.ndarray, pass_id: np.ndarray,
             side: str) -> np.ndarray:
    """(S,) +-1 per segment: its normal ``n`` turned away from the middle of its pass ('outer') or
    towards it ('inner'); the middle weighted by the segments' lengths."""
    w = seg_len + 1e-12
    total = np.bincount(pass_id, weights=w)
    centre = np.column_stack([np.bincount(pass_id, weights=w * mid[:, i]) for i in range(3)])
    centre /= total[:, None]
    sign = np.sign(np.bincount(pass_id, weights=w * np.einsum("ij,ij->i", mid - centre[pass_id], n)))
    sign[sign == 0] = 1.0
    return (sign if side == "outer" else -sign)[pass_id]


def _bands(tips, axes, a_idx, b_idx, n, mid, extent: float, radius: float, info: dict):
    """(geometry, segments (S, 2)) of the contour's segments drawn as bands up the tool axis; the
    levels found go into ``info``."""
    # the band's height: up to the next level above (a wall cut in step-downs reads as one wall)
    axis = axes[b_idx[0]]
    height = mid @ axis
    flat_seg = np.abs((tips[b_idx] - tips[a_idx]) @ axis) <= PLANAR_TOL_MM
    levels = np.unique(np.round(height[flat_seg] / PLANAR_TOL_MM)) * PLANAR_TOL_MM
    info["levels"] = int(levels.size)
    info["level_range_mm"] = ((float(levels[0]), float(levels[-1])) if levels.size else None)
    band = BAND_SHARE * extent
    above = np.searchsorted(levels, height + 0.5 * PLANAR_TOL_MM)
    gap = np.where(above < levels.size, levels[np.minimum(above, max(levels.size - 1, 0))] - height
                   if levels.size else np.inf, np.inf)
    up = np.where(flat_seg & (gap <= 4 * band), gap, band)
    s = a_idx.size
    index = np.concatenate([a_idx, b_idx, a_idx, b_idx])
    normals = np.tile(n, (4, 1))
    contact = tips[index] - radius * normals
    lift = np.concatenate([np.zeros(2 * s), up, up])
    draw = contact + lift[:, None] * axes[index]
    a, b = np.arange(s), np.arange(s) + s                   # start, end on the contour
    c, e = a + 2 * s, b + 2 * s                              # start, end at the band's top
    tris = np.vstack([np.column_stack([a, b, e]), np.column_stack([a, e, c])])
    return SurfaceGeometry(index, draw, radius * axes[index], normals, tris), np.column_stack([a, b])


def _clearing_segments(start: np.ndarray, end: np.ndarray, seg_start: np.ndarray,
                       seg_end: np.ndarray, normal: np.ndarray, axis: np.ndarray,
                       extent: float) -> np.ndarray:
    """(S,) bool: the segments (``seg_start`` -> ``seg_end`` (S, 3) mm, in-plane normals
    ``normal``) of a contour that clear material: cut path on both sides, at about the same
    distance (within a factor of 2.5) and within ``CLEARING_SHARE`` of the extent, as a raster or
    an offset pass inside a pocket has, at 3 or more of 5 places along the segment.

    The cutting moves (``start`` -> ``end``, (m, 3) mm) are drawn into a grid of extent/1000 per
    cell on each of the (at most ``PLANAR_MAX_LEVELS``) main levels; the distance to the path
    (scipy's Euclidean distance transform) is read at probes 8, 16, ... cells out along each
    normal: a probe at distance d closer than 0.75 d to the path has found path beyond the
    segment's own (between 0.25 d and 1.75 d from it). Segments on other heights (ramps,
    helices) count as walls."""
    from scipy.ndimage import distance_transform_edt
    u = np.cross(axis, [1.0, 0.0, 0.0])
    if np.linalg.norm(u) < 0.5:
        u = np.cross(axis, [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    basis = np.column_stack([u, np.cross(axis, u)])           # (3, 2): the plane across the axis
    cell = extent / 1000.0
    # from 8 cells out: the grid's rounding (a cell) never makes the segment's own path look near
    probes = cell * 2.0 ** np.arange(3, 10)
    probes = probes[probes <= max(CLEARING_SHARE * extent, 8 * cell)]
    margin = probes[-1] + 2 * cell
    level = np.round(0.5 * (seg_start + seg_end) @ axis / PLANAR_TOL_MM).astype(np.int64)
    move_level = np.round(0.5 * (start + end) @ axis / PLANAR_TOL_MM).astype(np.int64)
    move_len = np.linalg.norm(end - start, axis=1)
    flat = np.abs((end - start) @ axis) <= PLANAR_TOL_MM
    names, where = np.unique(move_level[flat], return_inverse=True)
    weight = np.bincount(where.ravel(), weights=move_len[flat])
    clearing = np.zeros(seg_start.shape[0], bool)
    for lev in names[np.argsort(weight)[::-1][:PLANAR_MAX_LEVELS]]:
        moves = np.flatnonzero(flat & (move_level == lev))
        segs = np.flatnonzero(level == lev)
        if segs.size == 0:
            continue
        a2, b2 = start[moves] @ basis, end[moves] @ basis
        lo = np.minimum(a2.min(axis=0), b2.min(axis=0)) - margin
        shape = (np.ceil((np.maximum(a2.max(axis=0), b2.max(axis=0)) + margin - lo) / cell)
                 .astype(np.int64) + 1)
        count = np.maximum(np.ceil(move_len[moves] / (0.5 * cell)).astype(np.int64), 1) + 1
        owner = np.repeat(np.arange(moves.size), count)
        frac = (np.arange(owner.size) - np.repeat(np.cumsum(count) - count, count)) / (count[owner] - 1)
        pts = a2[owner] + frac[:, None] * (b2[owner] - a2[owner])
        cells = np.floor((pts - lo) / cell).astype(np.int64)
        free = np.ones(tuple(shape), bool)
        free[cells[:, 0], cells[:, 1]] = False
        dist = distance_transform_edt(free) * cell
        n2 = normal[segs] @ basis
        votes = np.zeros(segs.size)
        for at in (0.1, 0.3, 0.5, 0.7, 0.9):            # along the segment: a majority decides
            m2 = ((1.0 - at) * seg_start[segs] + at * seg_end[segs]) @ basis
            found = []
            for sgn in (1.0, -1.0):
                first = np.full(segs.size, np.inf)
                for d in probes[::-1]:                  # the nearest probe that finds path wins
                    c = np.floor((m2 + sgn * d * n2 - lo) / cell).astype(np.int64)
                    inside = np.all((c >= 0) & (c < shape), axis=1)
                    hit = np.zeros(segs.size, bool)
                    hit[inside] = dist[c[inside, 0], c[inside, 1]] < 0.75 * d
                    first[hit] = d
                found.append(first)
            near, far = np.minimum(*found), np.maximum(*found)
            votes += np.isfinite(far) & (far <= 2.5 * near)
        clearing[segs] = votes >= 3
    return clearing

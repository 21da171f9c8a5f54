"""The surfaces an error map is drawn on (:func:`mtcomp.viz.surface.program_error_map`): the tool-tip
surface triangulated as seen along Z, the path itself when it is no such surface (or its points,
when it does not cut), the flank of a tool in 5-axis side milling, and the holes of a drilling
program. The in-plane contour
of a planar program is :mod:`mtcomp.viz.inplane`'s."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..kinematics import forward
from ..machine import Machine
from .program import ProgramPoints, drawn_q


#: points closer than this in XY (mm) count as the same surface point
XY_MERGE_TOL_MM = 1e-3
#: triangles with an edge longer than this times the median edge length are dropped
MAX_EDGE_FACTOR = 5.0
#: triangles of a tool-tip surface steeper than this (deg from the plane across the tool axis) are
#: walls seen edge-on: slivers between the levels of a wall, left out
MAX_SURFACE_SLOPE_DEG = 80.0


@dataclass
class SurfaceGeometry:
    """Surface points of a program: ``index`` (N,) into the program's segment ends, ``draw`` (N, 3)
    where the point is drawn, ``offset`` (N, 3) the tool point (relative to the tip, workpiece frame,
    nominal orientation) whose deviation along the normal is the part's, ``normals`` (N, 3),
    ``triangles`` (M, 3)."""

    index: np.ndarray
    draw: np.ndarray
    offset: np.ndarray
    normals: np.ndarray
    triangles: np.ndarray


def select_surface_points(tips: np.ndarray, tol_mm: float = XY_MERGE_TOL_MM) -> np.ndarray:
    """Indices of the points that form the surface seen from +Z: one per XY cell of size ``tol_mm``,
    the lowest (first in program order among equals). tips (n, 3) mm. Returns sorted indices."""
    if tips.shape[0] == 0:
        return np.zeros(0, np.int64)
    key = np.round(tips[:, :2] / tol_mm).astype(np.int64)
    order = np.lexsort((np.arange(tips.shape[0]), tips[:, 2], key[:, 1], key[:, 0]))
    k = key[order]
    first = np.ones(order.shape[0], bool)
    first[1:] = np.any(k[1:] != k[:-1], axis=1)
    return np.sort(order[first])


def triangulate_xy(points: np.ndarray, max_edge_factor: float = MAX_EDGE_FACTOR) -> np.ndarray:
    """Delaunay triangles (M, 3) of ``points`` (N, 3) projected on XY, without over-long triangles.

    Raises InputError when fewer than 3 points or all points lie on a line in XY.
    """
    from scipy.spatial import Delaunay, QhullError
    if points.shape[0] < 3:
        raise InputError(f"the program has {points.shape[0]} distinct cutting points in XY; a surface "
                         "needs at least 3")
    try:
        tri = Delaunay(points[:, :2]).simplices.astype(np.int64)
    except QhullError:
        raise InputError("the program's cutting points lie on a line in XY: no surface to map "
                         "(render maps surfaces seen along Z)") from None
    xy = points[:, :2]
    edges = np.stack([np.linalg.norm(xy[tri[:, i]] - xy[tri[:, (i + 1) % 3]], axis=1)
                      for i in range(3)], axis=1)
    longest = edges.max(axis=1)
    limit = max_edge_factor * np.median(edges)
    keep = longest <= limit
    if not np.any(keep):
        keep = np.ones(tri.shape[0], bool)
    return tri[keep]


def vertex_normals(points: np.ndarray, triangles: np.ndarray, towards: np.ndarray) -> np.ndarray:
    """(N, 3) unit normals: area-weighted mean of the triangle normals at each vertex, each turned to
    have a positive component along ``towards`` (N, 3), e.g. the tool axis. Vertices in no triangle
    get ``towards`` itself."""
    a, b, c = (points[triangles[:, i]] for i in range(3))
    fn = np.cross(b - a, c - a)  # length = 2 * area: area weighting for free
    flip = np.einsum("ij,ij->i", fn, towards[triangles[:, 0]]) < 0
    fn[flip] *= -1.0
    acc = np.zeros_like(points)
    for i in range(3):
        np.add.at(acc, triangles[:, i], fn)
    norm = np.linalg.norm(acc, axis=1)
    n = np.where(norm[:, None] > 0, acc / np.where(norm > 0, norm, 1.0)[:, None], towards)
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def steep_triangles(points: np.ndarray, triangles: np.ndarray, axis: np.ndarray,
                    max_slope_deg: float = MAX_SURFACE_SLOPE_DEG) -> np.ndarray:
    """(M,) bool: triangles steeper than ``max_slope_deg`` against the plane across the tool axis
    ``axis`` (N, 3), and degenerate ones. On a surface triangulated as seen along the tool axis
    these join the levels of a wall: slivers, not a surface."""
    a, b, c = (points[triangles[:, i]] for i in range(3))
    fn = np.cross(b - a, c - a)
    size = np.linalg.norm(fn, axis=1)
    along = np.abs(np.einsum("ij,ij->i", fn, axis[triangles[:, 0]]))
    return along <= np.cos(np.radians(max_slope_deg)) * size


def path_geometry(orig: ProgramPoints, machine: Machine) -> SurfaceGeometry:
    """The points of the feed moves (of every move, if none cuts) with no surface: the deviation
    along the tool axis at each, drawn as points."""
    idx = np.flatnonzero(~orig.rapid)
    if idx.size == 0:
        idx = np.arange(len(orig))
    tips, axes = forward(machine, drawn_q(orig)[idx])
    return SurfaceGeometry(idx, tips, np.zeros_like(tips), axes, np.zeros((0, 3), np.int64))


def hole_rows(orig: ProgramPoints, machine: Machine) -> np.ndarray:
    """Indices of the segment ends that are the bottoms of drilled holes: the holes of drilling cycles
    (G73, G81-G89); in a program without cycles whose every feed move runs along the tool axis (holes
    plunged with G1), the ends of the plunges into the part, one per hole: consecutive plunges at the
    same place across the tool axis (within 1 um: the pecks of a hole drilled in steps, as a
    controller without canned cycles, grbl, is given them) are one hole, its deepest plunge. Empty
    when the program is no drilling program (a feed move across the tool axis cuts, so its map is a
    surface or a contour)."""
    cycle = np.zeros(len(orig), bool) if orig.cycle is None else np.asarray(orig.cycle, bool)
    if cycle.any():
        return np.flatnonzero(cycle)
    idx = np.flatnonzero(~orig.rapid)
    if idx.size == 0 or cutting_rows(orig, machine).size:
        return np.zeros(0, np.int64)
    tips, axes = forward(machine, drawn_q(orig))
    step = tips[idx] - tips[np.maximum(idx - 1, 0)]
    step[idx == 0] = 0.0
    return _one_per_hole(idx[np.einsum("ij,ij->i", step, axes[idx]) < -1e-3], tips, axes)


def _one_per_hole(rows: np.ndarray, tips: np.ndarray, axes: np.ndarray) -> np.ndarray:
    """Of the plunges' ends ``rows``, the deepest (along the tool axis) of each run of consecutive
    ones at the same place across the tool axis (within 1 um)."""
    if rows.size < 2:
        return rows
    step = tips[rows[1:]] - tips[rows[:-1]]
    along = np.einsum("ij,ij->i", step, axes[rows[1:]])
    new = np.linalg.norm(step - along[:, None] * axes[rows[1:]], axis=1) > 1e-3
    hole = np.concatenate([[0], np.cumsum(new)])
    depth = np.einsum("ij,ij->i", tips[rows], axes[rows])       # deeper: smaller along the axis
    order = np.lexsort((depth, hole))
    first = np.concatenate([[True], hole[order][1:] != hole[order][:-1]])
    return np.sort(rows[order[first]])


def cutting_rows(orig: ProgramPoints, machine: Machine) -> np.ndarray:
    """Indices of the feed moves, drilling cycles' holes aside, that move across the tool axis
    (by more than 1 um): the moves that cut a surface or a contour."""
    cycle = np.zeros(len(orig), bool) if orig.cycle is None else np.asarray(orig.cycle, bool)
    idx = np.flatnonzero(~orig.rapid & ~cycle)
    idx = idx[idx > 0]
    if idx.size == 0:
        return idx
    tips, axes = forward(machine, drawn_q(orig)[np.concatenate([idx - 1, idx])])
    step = tips[idx.size:] - tips[:idx.size]
    along = np.einsum("ij,ij->i", step, axes[idx.size:])
    across = np.linalg.norm(step - along[:, None] * axes[idx.size:], axis=1)
    return idx[across > 1e-3]


def hole_geometry(orig: ProgramPoints, machine: Machine, rows: np.ndarray) -> SurfaceGeometry:
    """The holes' bottoms (``rows`` from :func:`hole_rows`), drawn where they are, with the tool
    axis as their 'normal': a hole map shows each hole's position error across the tool axis."""
    tips, axes = forward(machine, drawn_q(orig)[rows])
    return SurfaceGeometry(rows, tips, np.zeros_like(tips), axes, np.zeros((0, 3), np.int64))


def path_line_geometry(orig: ProgramPoints, machine: Machine):
    """(geometry, segments (S, 2)) of a 3-D path that is no surface seen along the tool axis (steep
    walls, a path wandering in space): the feed moves as lines between their end points, each point
    with the direction of the move that reaches it (of the move that leaves it, for a move's start)
    as its 'normal'; a path map shows the size of the deviation across that direction (the error of
    the path's shape, not of its timing along it)."""
    tips, _ = forward(machine, drawn_q(orig))
    feed = np.flatnonzero(~orig.rapid)
    feed = feed[feed > 0]
    rows = np.unique(np.concatenate([feed - 1, feed]))
    pos = np.full(len(orig), -1, np.int64)
    pos[rows] = np.arange(rows.size)
    segments = np.column_stack([pos[feed - 1], pos[feed]])
    step = tips[feed] - tips[feed - 1]
    length = np.linalg.norm(step, axis=1)
    unit = np.divide(step, length[:, None], out=np.zeros_like(step), where=length[:, None] > 0)
    tangent = np.zeros((rows.size, 3))
    tangent[pos[feed - 1]] = unit          # a move's start: the move that leaves it ...
    tangent[pos[feed]] = unit              # ... unless a move ends there
    return (SurfaceGeometry(rows, tips[rows], np.zeros((rows.size, 3)), tangent,
                            np.zeros((0, 3), np.int64)), segments)


def tip_geometry(orig: ProgramPoints, machine: Machine, radius: float, max_edge_factor: float):
    cut = np.flatnonzero(~orig.rapid)
    tips_all, axes_all = forward(machine, drawn_q(orig)[cut])
    keep = select_surface_points(tips_all)
    tips, axis = tips_all[keep], axes_all[keep]
    tri = triangulate_xy(tips, max_edge_factor)
    steep = steep_triangles(tips, tri, axis)
    if steep.any() and not steep.all():
        tri = tri[~steep]
    normals = vertex_normals(tips, tri, axis)
    # a ball end cuts with its surface: the contact point's deviation along n is the ball centre's
    draw = tips + radius * (axis - normals) if radius > 0 else tips.copy()
    return SurfaceGeometry(cut[keep], draw, radius * axis, normals, tri), int(np.count_nonzero(steep))


def cutting_runs(tips: np.ndarray, gap_factor: float = 5.0, corner_deg: float = 60.0
                 ) -> list[np.ndarray]:
    """Split consecutive cutting points (n, 3) into runs: at steps longer than ``gap_factor`` times
    the median step (linking moves), and where the path turns by more than ``corner_deg`` (a corner,
    or an approach or leave move along the normal; the corner point belongs to both runs). Runs of at
    least 3 points, as index arrays."""
    n = tips.shape[0]
    if n < 3:
        return []
    steps = np.diff(tips, axis=0)
    length = np.linalg.norm(steps, axis=1)
    long = length > gap_factor * max(float(np.median(length)), 1e-9)
    unit = steps / np.maximum(length, 1e-300)[:, None]
    turn = np.einsum("ij,ij->i", unit[:-1], unit[1:]) < np.cos(np.radians(corner_deg))
    runs, start = [], 0
    for i in range(1, n):                      # step i-1 goes from point i-1 to point i
        if long[i - 1]:
            runs.append(np.arange(start, i))
            start = i
        elif i < n - 1 and turn[i - 1]:        # the path turns at point i
            runs.append(np.arange(start, i + 1))
            start = i
    runs.append(np.arange(start, n))
    return [r for r in runs if r.size >= 3]


def flank_geometry(orig: ProgramPoints, machine: Machine, radius: float, length: float,
                    side: str, n_levels: int | None):
    cut = np.flatnonzero(~orig.rapid)
    tips_all, axes_all = forward(machine, drawn_q(orig)[cut])
    idx, draw, offset, normals, tris = [], [], [], [], []
    base = 0
    for run in cutting_runs(tips_all):
        tips, axis = tips_all[run], axes_all[run]
        t = np.gradient(tips, axis=0)
        step = float(np.median(np.linalg.norm(np.diff(tips, axis=0), axis=1)))
        if np.linalg.norm(tips[-1] - tips[0]) < 1e-3 * step:   # closed contour: no ends
            t[0] = t[-1] = tips[1] - tips[-2]
        nrm = np.cross(t, axis)
        nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-300)
        # outer wall: the normal points away from the middle of the run (inner: towards it)
        out = tips - tips.mean(axis=0)
        out -= np.einsum("ij,ij->i", out, axis)[:, None] * axis
        sign = np.sign(np.einsum("ij,ij->i", nrm, out).sum()) or 1.0
        nrm *= sign if side == "outer" else -sign
        k = n_levels or int(np.clip(np.ceil(length / max(step, 1e-9)) + 1, 2, 41))
        h = np.linspace(0.0, length, k)
        m = run.size
        # grid point (i, j): pose i, height h_j along the tool axis; the contact line on the flank
        off = axis[:, None, :] * h[None, :, None]
        idx.append(np.repeat(cut[run], k))
        offset.append(off.reshape(-1, 3))
        draw.append((tips[:, None, :] + off - radius * nrm[:, None, :]).reshape(-1, 3))
        normals.append(np.repeat(nrm, k, axis=0))
        ii, jj = np.meshgrid(np.arange(m - 1), np.arange(k - 1), indexing="ij")
        v00 = (ii * k + jj).ravel() + base
        v01, v10, v11 = v00 + 1, v00 + k, v00 + k + 1
        tris.append(np.vstack([np.column_stack([v00, v10, v11]), np.column_stack([v00, v11, v01])]))
        base += m * k
    if not idx:
        raise InputError("flank map: the program has no run of 3 or more cutting points", orig.path)
    return SurfaceGeometry(np.concatenate(idx), np.vstack(draw), np.vstack(offset), np.vstack(normals),
                     np.vstack(tris))

"""The workpiece surface a program cuts, and the model's predicted deviation along its normal.

No plotting here (numpy, scipy, CasADi): :func:`program_error_map` turns a machine, a fitted model and
an NC program (optionally with its compensated version) into a :class:`SurfaceMap`, which
:mod:`mtcomp.viz.render` draws and writes to .vtp. docs/render.md says it for users.

Surfaces (a program whose cut is not a surface seen along Z -- a lathe profile in XZ, a single
point, only rapids -- is mapped as the points of its path, the deviation along the tool axis):

* tool-tip surface (default): the end points of the feed moves (G1, chords of G2/G3; rapids left
  out), nominal tool tips in the workpiece frame, triangulated in XY (Delaunay; the lowest point per
  1 um XY cell; over-long triangles dropped so holes are not bridged); normals are the area-weighted
  triangle normals turned towards the tool. A ball end of radius R is drawn at the contact points
  ``tip + R (axis - n)`` (the tip surface is the ball-centre surface moved by -R z: same normals).
* flank surface (``flank_length_mm``, 5-axis side milling): per run of cutting points, contact lines
  along the tool axis over the flank length, offset by the cutter radius; normals perpendicular to
  the path and the tool axis.

The deviation at a point is that of the tool point that cuts there -- the tip, the ball centre, or
the axis point at the contact height on a flank -- actual minus nominal, in the workpiece frame , from the model's tool frame (tip and rotation); ``dn`` is its component along the normal
(positive: the tool stays off the surface, material is left outside, the sign a CMM reports). For a
compensated program the same tool point is taken at the corrected axis positions and compared with
its ORIGINAL nominal position; original and compensated blocks are paired through the programs'
line structure or the compensation report's source lines.
"""
from __future__ import annotations

import math
import os
import re
import weakref
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..kinematics import forward, tool2wp
from ..machine import Machine

#: points closer than this in XY (mm) count as the same surface point
XY_MERGE_TOL_MM = 1e-3
#: triangles with an edge longer than this times the median edge length are dropped
MAX_EDGE_FACTOR = 5.0
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
#: triangles of a tool-tip surface steeper than this (deg from the plane across the tool axis) are
#: walls seen edge-on: slivers between the levels of a wall, left out
MAX_SURFACE_SLOPE_DEG = 80.0
#: why a block is left uncorrected (SurfaceMap.status)
STATUS_REASONS = {1: "an axis position the program has not given",
                  2: "outside the region the model's data reached",
                  3: "the model unsure (correction's standard error over the limit)"}


@dataclass
class ProgramPoints:
    """The segment end points of a program, in program order (all motion, rapids included).

    q : (n, na) axis positions, mm and rad. line : (n,) 1-based source lines. feed : (n,) mm/min
    (nan for rapids). dirs : (n, na) approach directions. rapid : (n,) bool. known : (n, na) bool, the
    program has given that axis's position (None: all).
    """

    path: str
    q: np.ndarray
    line: np.ndarray
    feed: np.ndarray
    dirs: np.ndarray
    rapid: np.ndarray
    known: np.ndarray | None = None

    def __len__(self):
        return int(self.line.shape[0])


def read_program_points(path, machine: Machine) -> ProgramPoints:
    """Every segment end of the program at ``path`` (arcs as chords). Raises InputError."""
    from ..toolpaths import SegmentChunk, iter_segment_chunks
    chunks = list(iter_segment_chunks(path, machine))
    seg = SegmentChunk.concatenate(chunks, machine.n_axes)
    if len(seg.end) == 0:
        from ..errors import InputError
        raise InputError("no motion block in the program: nothing to draw", path)
    return ProgramPoints(os.fspath(path), seg.end.copy(), seg.line.copy(), seg.feed.copy(),
                         seg.dirs.copy(), seg.rapid.copy(), seg.known.copy())


@dataclass
class SurfaceMap:
    """A triangulated workpiece surface with the predicted deviation at its vertices.

    points : (N, 3) mm, where the map is drawn (tool tips, or contact points for a ball-end tool).
    tips : (N, 3) mm, nominal tool tips of the original program, workpiece frame.
    normals : (N, 3) unit surface normals, pointing towards the tool.
    triangles : (M, 3) int, vertex indices.
    line : (N,) int, source line of each point in the original program.
    dev_before : (N, 3) mm, actual minus nominal position of the tool point at ``offsets``, less the
        deviation at the part's datum (the program's origin: FittedModel.datum_deviation).
    dev_after : (N, 3) mm or None, at the corrected axes minus the ORIGINAL nominal position (less
        the same).
    source : the program's path, compensated : the compensated program's path or None.
    offsets : (N, 3) mm, the tool point whose deviation is mapped, relative to the nominal tip
        (workpiece frame): zero for the tip, the ball centre for a ball end, the axis point at the
        contact height on a flank. dev_before/dev_after are the deviations of that point.
    normal_kind : 'surface' (the normal of the cut surface, or of the flank) or 'in-plane' (the
        normal of a planar contour in its plane, across the tool axis).
    status : (N,) int8 or None, why the point's block is left uncorrected (:data:`STATUS_REASONS`:
        0 corrected, 1 an axis position the program has not given, 2 outside the region the model's
        data reached, 3 the model unsure of the correction). status_source : 'report' (the
        compensation report's columns) or 'planner' (the planner's rules, default bounds).
    notes : sentences the map must show (warnings), info : counts the command prints (levels,
        clearing moves and steep triangles left out, ...). segments : (S, 2) int or None, an
        in-plane map's contour: the point indices of each segment's two ends.
    """

    points: np.ndarray
    tips: np.ndarray
    normals: np.ndarray
    triangles: np.ndarray
    line: np.ndarray
    dev_before: np.ndarray
    dev_after: np.ndarray | None = None
    source: str = ""
    compensated: str | None = None
    offsets: np.ndarray | None = None
    normal_kind: str = "surface"
    status: np.ndarray | None = None
    status_source: str = ""
    notes: list = field(default_factory=list)
    info: dict = field(default_factory=dict)
    segments: np.ndarray | None = None

    @property
    def uncorrected(self) -> np.ndarray:
        """(N,) bool: the point's block is left uncorrected (``status`` > 0)."""
        if self.status is None:
            return np.zeros(self.points.shape[0], bool)
        return self.status > 0

    @property
    def dn_before_um(self) -> np.ndarray:
        """(N,) um, deviation along the normal before compensation."""
        return 1e3 * np.einsum("ij,ij->i", self.dev_before, self.normals)

    @property
    def dn_after_um(self) -> np.ndarray | None:
        """(N,) um, deviation along the normal of the compensated program, or None."""
        if self.dev_after is None:
            return None
        return 1e3 * np.einsum("ij,ij->i", self.dev_after, self.normals)

    def stats(self) -> dict:
        """RMS and largest magnitude of dn (um), before and (if present) after."""
        out = {"n_points": int(self.points.shape[0]), "n_triangles": int(self.triangles.shape[0])}
        for key, dn in (("before", self.dn_before_um), ("after", self.dn_after_um)):
            if dn is not None:
                out[f"rms_{key}_um"] = float(np.sqrt(np.mean(dn ** 2))) if dn.size else 0.0
                out[f"max_{key}_um"] = float(np.max(np.abs(dn))) if dn.size else 0.0
        return out


# ------------------------------------------------------------------------------------ geometry
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


# ----------------------------------------------------------------------------------- deviations
def _context(fitted, q_count, feed, dirs):
    machine = fitted.machine
    cols = {"feed": feed}
    for j, a in enumerate(machine.axis_names):
        cols[f"dir_{a}"] = dirs[:, j].astype(float)
    return fitted.context(q_count, cols)


_FRAME_FUNCTIONS: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def _frame_function(model):
    """CasADi (q, p, c) -> (tip (3,), R (9,) column-major): the actual tool frame in the workpiece
    frame, from the model's symbolic chain. Built once per model."""
    f = _FRAME_FUNCTIONS.get(model)
    if f is None:
        import casadi as ca
        q = ca.SX.sym("q", model.machine.n_axes)
        p = ca.SX.sym("p", model.n_params)
        c = ca.SX.sym("c", model.n_context)
        tip, _, R = model.symbolic(q, p, c, errors=True)
        f = ca.Function("viz_tool_frame", [q, p, c], [tip, ca.reshape(R, 9, 1)])
        _FRAME_FUNCTIONS[model] = f
    return f


def predicted_points(fitted, q: np.ndarray, feed: np.ndarray, dirs: np.ndarray,
                     offset_tool: np.ndarray | None = None) -> np.ndarray:
    """(n, 3) mm: where the tool point at ``offset_tool`` (n, 3) mm, tool frame (None: the tip) really
    is in the workpiece frame at axis positions q (n, na), as the model ``fitted`` predicts it (its
    tool tip and tool rotation, every term included; feed mm/min and approach directions as context).
    """
    from ..models.evaluate import casadi_map_call
    n = q.shape[0]
    if n == 0:
        return np.zeros((0, 3))
    c = np.ascontiguousarray(_context(fitted, n, feed, dirs), dtype=float)
    f = _frame_function(fitted.model)
    p = np.asarray(fitted.params.values, dtype=float)
    q = np.ascontiguousarray(q, dtype=float)

    def frame(q_, p_):
        tip_, rflat_ = casadi_map_call(f, q_, p_, c)
        return tip_, rflat_.reshape(n, 3, 3).transpose(0, 2, 1)

    qc, held = fitted.clamp(q)
    tip, R = frame(q, p)
    if held:
        # the model's error is evaluated where the data held those axes (as compensate does): the
        # deviation at the clamped pose, carried to the block's own nominal pose
        tip_c, R_c = frame(qc, p)
        tip0_c, R0_c = frame(qc, np.zeros_like(p))
        tip0, R0 = frame(q, np.zeros_like(p))
        tip = tip0 + (tip_c - tip0_c)
        R = np.einsum("nij,nkj,nkl->nil", R_c, R0_c, R0)
    if offset_tool is None:
        return tip
    return tip + np.einsum("nij,nj->ni", R, offset_tool)


def _motion_runs(original: ProgramPoints, compensated: ProgramPoints) -> tuple[np.ndarray, np.ndarray]:
    """Run number of every segment end of both programs, from their line structure.

    The compensated program keeps every non-motion line of the original byte for byte and in order
    (mtcomp compensate writes it so); the motion lines between two such kept lines form a run, and
    a run of the original and the same run of the compensated program hold the same blocks, in the
    same order. Raises InputError where a kept line is missing."""
    def lines(path):
        with open(path, "rb") as f:
            return f.read().split(b"\n")
    a, b = lines(original.path), lines(compensated.path)
    a_motion, b_motion = set(original.line.tolist()), set(compensated.line.tolist())
    run_a = np.zeros(len(a) + 2, np.int64)
    run_b = np.zeros(len(b) + 2, np.int64)
    j, run = 0, 0
    for k, raw in enumerate(a, 1):
        if k in a_motion:
            run_a[k] = run
            continue
        start = j
        while j < len(b) and ((j + 1) in b_motion or b[j] != raw):
            j += 1
        if j >= len(b):
            raise InputError(f"line {k} of {original.path} is not in the compensated program (is it "
                             "compensated from that program?)", compensated.path)
        run_b[start + 1:j + 1] = run
        run += 1
        j += 1
    run_b[j + 1:] = run
    return run_a[original.line], run_b[compensated.line]


def pair_compensated(original: ProgramPoints, compensated: ProgramPoints, machine: Machine,
                     tol_mm: float | None = None, tol_rad: float | None = None) -> np.ndarray:
    """For each segment end of ``original``, the index of its corrected counterpart in ``compensated``.

    Blocks are paired through the programs' line structure (:func:`_motion_runs`): within a run of
    motion lines, one to one when both have as many segment ends; else (the compensated program
    may split a move, or write an arc as chords or a piece that changes nothing not at all) each
    original end is paired with the nearest compensated end of the same run after the one paired
    before it, no further ahead than the run's surplus of compensated ends allows. The pair must agree within a tolerance (default: four times the machine's
    largest correction, at least 0.05 mm / 50 urad). Raises InputError when the programs do not
    correspond.
    """
    comp = machine.compensation
    tol_mm = max(4e-3 * comp.get("max_correction_um", 50.0), 0.05) if tol_mm is None else tol_mm
    tol_rad = max(4e-6 * comp.get("max_correction_urad", 500.0), 5e-5) if tol_rad is None else tol_rad
    rotary = np.array([a.is_rotary for a in machine.axes])
    tol = np.where(rotary, tol_rad, tol_mm)
    n, m = len(original), len(compensated)
    idx = np.empty(n, np.int64)
    run_a, run_b = _motion_runs(original, compensated)
    for r in np.unique(run_a):
        ia = np.flatnonzero(run_a == r)
        ib = np.flatnonzero(run_b == r)
        if ib.size == 0:
            raise InputError(f"the compensated program has no motion where line "
                             f"{int(original.line[ia[0]])} of {original.path} moves",
                             compensated.path)
        if ia.size == ib.size:
            idx[ia] = ib
            continue
        # the compensated run has `slack` more ends than the original one: an original end lies
        # at most that many ends ahead of the place the ends before it left off
        slack = max(ib.size - ia.size, 0) + 1
        j = 0
        for i in ia:
            window = compensated.q[ib[j:j + slack + 1]]
            dist = np.max(np.abs(window - original.q[i]) / tol, axis=1)
            step = int(np.argmin(dist))
            idx[i] = ib[j + step]
            slack -= step
            j = min(j + step + 1, ib.size - 1)
    if n and m:
        diff = np.abs(compensated.q[idx] - original.q) > tol
        bad = np.flatnonzero(np.any(diff, axis=1))
        if bad.size:
            i = int(bad[0])
            d = np.abs(compensated.q[idx[i]] - original.q[i])
            what = ", ".join(f"{a} by {d[k] * (1e6 if rotary[k] else 1e3):.4g} "
                             f"{'urad' if rotary[k] else 'um'}"
                             for k, a in enumerate(machine.axis_names) if d[k] > tol[k])
            raise InputError(f"line {int(compensated.line[idx[i]])} differs from line "
                             f"{int(original.line[i])} of {original.path} ({what}): not a compensated "
                             "version of that program", compensated.path)
    return idx


def report_points(original: ProgramPoints, report, machine: Machine) -> ProgramPoints:
    """The corrected positions of the original's segment ends, from the BLOCKS.csv of
    ``mtcomp compensate`` (its rows that are not inserted nodes, in order, by source line)."""
    import csv
    path = os.fspath(report)
    cols = [f"{a.lower()}_deg" if a in "ABC" else f"{a.lower()}_mm" for a in machine.axis_names]
    try:
        with open(path, newline="") as f:
            rows = [r for r in csv.DictReader(f) if r.get("inserted", "0") == "0"]
    except FileNotFoundError:
        raise InputError("no such report file", path) from None
    if len(rows) != len(original):
        raise InputError(f"the report has {len(rows)} blocks, the program {len(original)} segment "
                         "ends: not the report of that program", path)
    try:
        # a blank cell: an axis the program had not positioned there, which the block leaves alone
        q = np.array([[float(r[c]) if r[c] != "" else np.nan for c in cols] for r in rows])
        q = np.where(np.isnan(q), original.q, q)
        line = np.array([int(r["line"]) for r in rows])
    except (KeyError, ValueError, TypeError):
        raise InputError(f"not a report of mtcomp compensate (columns line, inserted, "
                         f"{', '.join(cols)})", path) from None
    q[:, [a.is_rotary for a in machine.axes]] = np.radians(q[:, [a.is_rotary for a in machine.axes]])
    bad = np.flatnonzero(line != original.line)
    if bad.size:
        raise InputError(f"row {int(bad[0]) + 2} is for line {int(line[bad[0]])}, the program's "
                         f"segment end there is on line {int(original.line[bad[0]])}", path)
    return ProgramPoints(path, q, line, original.feed, original.dirs, original.rapid)


@dataclass
class _Geometry:
    """Surface points of a program: ``index`` (N,) into the program's segment ends, ``draw`` (N, 3)
    where the point is drawn, ``offset`` (N, 3) the tool point (relative to the tip, workpiece frame,
    nominal orientation) whose deviation along the normal is the part's, ``normals`` (N, 3),
    ``triangles`` (M, 3)."""

    index: np.ndarray
    draw: np.ndarray
    offset: np.ndarray
    normals: np.ndarray
    triangles: np.ndarray


def _path_geometry(orig: ProgramPoints, machine: Machine) -> _Geometry:
    """The points of the feed moves (of every move, if none cuts) with no surface: the deviation
    along the tool axis at each, drawn as points."""
    idx = np.flatnonzero(~orig.rapid)
    if idx.size == 0:
        idx = np.arange(len(orig))
    tips, axes = forward(machine, orig.q[idx])
    return _Geometry(idx, tips, np.zeros_like(tips), axes, np.zeros((0, 3), np.int64))


def _tip_geometry(orig: ProgramPoints, machine: Machine, radius: float, max_edge_factor: float):
    cut = np.flatnonzero(~orig.rapid)
    tips_all, axes_all = forward(machine, orig.q[cut])
    keep = select_surface_points(tips_all)
    tips, axis = tips_all[keep], axes_all[keep]
    tri = triangulate_xy(tips, max_edge_factor)
    steep = steep_triangles(tips, tri, axis)
    if steep.any() and not steep.all():
        tri = tri[~steep]
    normals = vertex_normals(tips, tri, axis)
    # a ball end cuts with its surface: the contact point's deviation along n is the ball centre's
    draw = tips + radius * (axis - normals) if radius > 0 else tips.copy()
    return _Geometry(cut[keep], draw, radius * axis, normals, tri), int(np.count_nonzero(steep))


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
    tips, axes = forward(machine, orig.q)
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


def _inplane_geometry(orig: ProgramPoints, machine: Machine, radius: float, side: str):
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
    tips, axes = forward(machine, orig.q)
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
    unit = d / length[:, None]
    # passes: moves that follow each other without a rapid or a move along the axis between
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
    w = seg_len + 1e-12
    total = np.bincount(pass_id, weights=w)
    centre = np.column_stack([np.bincount(pass_id, weights=w * mid[:, i]) for i in range(3)])
    centre /= total[:, None]
    sign = np.sign(np.bincount(pass_id, weights=w * np.einsum("ij,ij->i", mid - centre[pass_id], n)))
    sign[sign == 0] = 1.0
    n *= (sign if side == "outer" else -sign)[pass_id][:, None]
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
    return (_Geometry(index, draw, radius * axes[index], normals, tris), np.column_stack([a, b]),
            info)


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


def _flank_geometry(orig: ProgramPoints, machine: Machine, radius: float, length: float,
                    side: str, n_levels: int | None):
    cut = np.flatnonzero(~orig.rapid)
    tips_all, axes_all = forward(machine, orig.q[cut])
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
    return _Geometry(np.concatenate(idx), np.vstack(draw), np.vstack(offset), np.vstack(normals),
                     np.vstack(tris))


#: the bowl's header; programs written by earlier versions of mtcomp name it "SEED 001 BOWL"
_BOWL_HEADER = re.compile(r"(?:QI-YANG 2016|SEED 001) BOWL .*BALL R\s*([0-9.]+)", re.I)
_CONE_HEADER = re.compile(r"CONE FRUSTUM D([0-9.]+)/D([0-9.]+) HALF-ANGLE ([0-9.]+).*END MILL R\s*"
                          r"([0-9.]+)", re.I)


def program_hints(path) -> dict:
    """Tool and surface of the built-in test parts (mtcomp.toolpaths.parts), from the header comment
    in the first 30 lines: the bowl of Qi and Yang (2016) gives ``tool_radius_mm``; the cone frustum
    gives ``tool_radius_mm`` and ``flank_length_mm`` (its slant height). {} for any other program."""
    try:
        with open(path, encoding="latin-1") as f:
            head = "".join(f.readline() for _ in range(30))
    except OSError:
        return {}
    m = _BOWL_HEADER.search(head)
    if m:
        return {"tool_radius_mm": float(m.group(1)), "part": "bowl of Qi and Yang (2016)"}
    m = _CONE_HEADER.search(head)
    if m:
        big, small, half, r = (float(g) for g in m.groups())
        return {"tool_radius_mm": r, "flank_length_mm": 0.5 * (big - small) / math.sin(math.radians(half)),
                "part": "cone frustum"}
    return {}


def program_error_map(machine: Machine, fitted, program, compensated=None,
                      tool_radius_mm: float | None = None, flank_length_mm: float | None = None,
                      flank_side: str = "outer", max_edge_factor: float = MAX_EDGE_FACTOR,
                      flank_levels: int | None = None, report=None,
                      normal: str = "surface", uncorrected: bool = True,
                      progress=None) -> SurfaceMap:
    """The surface ``program`` cuts, with the deviation predicted by ``fitted`` (a FittedModel).

    program, compensated : paths of NC files (or :class:`ProgramPoints`); the compensated program
        is paired with the original through their line structure (:func:`pair_compensated`).
    report : the BLOCKS.csv of the compensation (path) or None: the corrected positions are then
        taken from it, paired by source line (:func:`report_points`).
    tool_radius_mm : ball-end radius (tip surface) or cylinder radius (flank), mm; None: from the
        header of a built-in test part (:func:`program_hints`), else 0 (the map at the tool tips).
    flank_length_mm : > 0 maps the flank of the tool instead (5-axis side milling): contact lines
        along the tool axis from the tip over this length, offset by the tool radius; None: from the
        header of a built-in part, else the tip surface. flank_side : 'outer' (the tool works
        outside the contour, e.g. a boss) or 'inner' (a pocket); also the side of an in-plane map.
    normal : 'surface' (the cut surface's normal), 'in-plane' (a planar contour's normal in its
        plane: :func:`_inplane_geometry`) or 'auto' (in-plane for a program :func:`planar_levels`
        finds planar, else surface). A flank length > 0 maps the flank whatever this says.
    uncorrected : mark the blocks left uncorrected (``SurfaceMap.status``): from the report's
        columns when a report is given, else by the planner's rules (:func:`planner_status`).
    progress : callable(stage text) told at each stage, or None.
    Raises InputError for programs without a surface or a compensated program that does not match.
    """
    hints = program_hints(program) if not isinstance(program, ProgramPoints) else {}
    radius = hints.get("tool_radius_mm", 0.0) if tool_radius_mm is None else float(tool_radius_mm)
    length = hints.get("flank_length_mm", 0.0) if flank_length_mm is None else float(flank_length_mm)
    if not radius >= 0:
        raise InputError(f"tool radius must be >= 0 mm, got {tool_radius_mm}")
    if not length >= 0:
        raise InputError(f"flank length must be >= 0 mm, got {flank_length_mm}")
    if flank_side not in ("outer", "inner"):
        raise InputError(f"flank side must be 'outer' or 'inner', not {flank_side!r}")
    if normal not in ("surface", "in-plane", "auto"):
        raise InputError(f"normal must be 'surface', 'in-plane' or 'auto', not {normal!r}")
    orig = program if isinstance(program, ProgramPoints) else read_program_points(program, machine)
    comp = None
    if report is not None:
        comp = report_points(orig, report, machine)
        pair = np.arange(len(orig))
    elif compensated is not None:
        comp = (compensated if isinstance(compensated, ProgramPoints)
                else read_program_points(compensated, machine))
        pair = pair_compensated(orig, comp, machine)
    say = progress or (lambda _stage: None)
    kind = "surface"
    g, segments, info = None, None, {}
    if length > 0:
        g = _flank_geometry(orig, machine, radius, length, flank_side, flank_levels)
    else:
        levels = planar_levels(orig, machine) if normal != "in-plane" else 0
        info["planar_levels"] = levels
        if normal == "in-plane" or (normal == "auto" and levels):
            say(f"contour of {len(orig)} segment ends")
            try:
                g, segments, more = _inplane_geometry(orig, machine, radius, flank_side)
                info.update(more)
                kind = "in-plane"
            except InputError:
                if normal == "in-plane":
                    raise
    if g is None:
        try:
            g, info["steep_triangles"] = _tip_geometry(orig, machine, radius, max_edge_factor)
        except InputError:      # no surface seen along Z (a lathe profile, one point, no cutting)
            g = _path_geometry(orig, machine)
    # each distinct tool point once (a contour's band repeats its ends four times)
    key = np.column_stack([g.index.astype(float), g.offset])
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.ravel()
    sel = g.index[first]
    T0 = tool2wp(machine, orig.q[sel])
    tips = T0[:, :3, 3]
    offset_tool = np.einsum("nji,nj->ni", T0[:, :3, :3], g.offset[first])   # R0^T offset: tool frame
    # referenced to the part's datum, as compensate references its corrections: the program's
    # origin (the machine zero: the map knows no work offsets), where the machinist probed the part
    nominal = tips + g.offset[first] + fitted.datum_deviation(np.zeros((1, machine.n_axes)),
                                                              machine.tool_length)
    say(f"deviation at {sel.size} points")
    dev_before = predicted_points(fitted, orig.q[sel], orig.feed[sel], orig.dirs[sel],
                                  offset_tool) - nominal
    dev_after = None
    if comp is not None:
        say(f"deviation after compensation at {sel.size} points")
        j = pair[sel]
        dev_after = predicted_points(fitted, comp.q[j], comp.feed[j], comp.dirs[j],
                                     offset_tool) - nominal
    status, source = None, ""
    if report is not None:
        status, source = report_status(report, len(orig))[sel], "report"
    elif uncorrected and hasattr(fitted, "support"):
        say(f"finding the blocks the planner leaves uncorrected ({sel.size} points)")
        status, source = planner_status(fitted, orig, sel), "planner"
    notes = []
    normals = g.normals
    if kind == "surface" and length == 0 and normals.size:
        tip_axes = forward(machine, orig.q[g.index])[1]
        along = np.abs(np.einsum("ij,ij->i", normals, tip_axes)) >= np.cos(np.radians(1.0))
        if along.all() or info.get("planar_levels"):
            notes.append("the normals all lie along the tool axis (a flat or 2-D program): the map "
                         "shows the deviation along the tool axis only, not the error across it "
                         "(--normal in-plane maps contours)")
    smap = SurfaceMap(g.draw, tips[inverse], normals, g.triangles, orig.line[g.index].copy(),
                      dev_before[inverse], None if dev_after is None else dev_after[inverse],
                      orig.path, None if comp is None else comp.path, g.offset, kind,
                      None if status is None else status[inverse], source, notes, info)
    smap.segments = segments
    return smap


def report_status(report, n: int) -> np.ndarray:
    """(n,) int8 :data:`STATUS_REASONS` of the program's segment ends from the compensation report's
    columns ``unknown_axes``, ``outside_support``, ``uncertain`` and ``corrected`` (its rows that are
    not inserted nodes, checked against the program by :func:`report_points` before)."""
    import csv
    with open(os.fspath(report), newline="") as f:
        rows = [r for r in csv.DictReader(f) if r.get("inserted", "0") == "0"]
    status = np.zeros(n, np.int8)
    for i, r in enumerate(rows[:n]):
        if r.get("corrected", "1") not in ("0", "0.0"):
            continue
        status[i] = (1 if r.get("unknown_axes") else 3 if r.get("uncertain") in ("1", "1.0")
                     else 2)
    return status


def planner_status(fitted, orig: ProgramPoints, sel: np.ndarray) -> np.ndarray:
    """(len(sel),) int8 :data:`STATUS_REASONS`: which of the blocks ``sel`` the planner would leave
    uncorrected under the model's and the machine's defaults (no --extrapolate, the default limit on
    a correction's standard error), by the planner's own rules, the part's datum at the program's
    origin as render takes it."""
    from ..planner import CompensationProblem, Planner, PlannerOptions
    planner = Planner(CompensationProblem.from_machine(fitted), PlannerOptions(threads=1))
    q = orig.q[sel]
    known = np.ones(q.shape, bool) if orig.known is None else np.asarray(orig.known[sel], bool)
    unknown = ~known
    outside = planner._outside(q, known)
    # the standard error changes slowly with position: evaluated once per cell of 1/100 of the
    # part's extent (0.1 deg for rotary axes) and approach direction, at the cell's first block
    rotary = np.array([a.is_rotary for a in fitted.machine.axes])
    extent = max(float(np.max(np.ptp(q[:, ~rotary], axis=0))) if q.size and (~rotary).any() else 0.0,
                 1e-3)
    step = np.where(rotary, np.radians(0.1), extent / 100.0)
    key = np.column_stack([np.round(q / step), orig.dirs[sel], known])
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    ctx = planner._context(orig.feed[sel][first], orig.dirs[sel][first], first.size)
    sd = planner._sd_um(q[first], ctx, unknown[first], outside[first],
                        np.zeros_like(q[first]))[inverse.ravel()]
    status = np.zeros(q.shape[0], np.int8)
    limit = planner.options.max_correction_sd_um
    if limit:
        with np.errstate(invalid="ignore"):
            status[sd > limit] = 3
    status[outside.any(axis=1)] = 2
    status[unknown.any(axis=1)] = 1
    return status

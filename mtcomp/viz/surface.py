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
from dataclasses import dataclass

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
#: width of the band an in-plane map is drawn as, as a share of the contour's extent (display only)
BAND_SHARE = 0.015


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
    normals = vertex_normals(tips, tri, axis)
    # a ball end cuts with its surface: the contact point's deviation along n is the ball centre's
    draw = tips + radius * (axis - normals) if radius > 0 else tips.copy()
    return _Geometry(cut[keep], draw, radius * axis, normals, tri)


def planar_levels(orig: ProgramPoints, machine: Machine) -> int:
    """The number of planes across the tool axis the program cuts in (0: not planar).

    Planar (a 2-D contour, engraving, a profile cut in a few step-downs): the tool axis is the same
    at every cutting point, at least ``PLANAR_SHARE`` of the cutting path's length runs across it
    (moves whose height along it changes by at most ``PLANAR_TOL_MM``), and at least that share of
    the cutting points lies on at most ``PLANAR_MAX_LEVELS`` heights (ramps and plunges may lie
    between). A sloped or curved surface, or waterline finishing on many levels, is not planar."""
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
    if across.sum() <= 0 or across[flat].sum() < PLANAR_SHARE * across.sum():
        return 0
    h = np.round(tips[feed] @ axis / PLANAR_TOL_MM).astype(np.int64)
    _, counts = np.unique(h, return_counts=True)
    top = np.sort(counts)[::-1][:PLANAR_MAX_LEVELS]
    return int(top.size) if top.sum() >= PLANAR_SHARE * feed.size else 0


def _inplane_geometry(orig: ProgramPoints, machine: Machine, radius: float, side: str):
    """A planar program's contour: every feed move with a length across the tool axis is a wall
    segment whose normal lies in the plane (perpendicular to the move and the tool axis), pointing
    away from the middle of its pass (``side`` 'outer', a boss) or towards it ('inner', a pocket).
    The deviation is the tip's (or the tool axis point's, for a cutter of ``radius``: the same for
    a tool that does not tilt); each segment is drawn as a band of its own two end points, so a
    corner keeps the normals of both walls."""
    tips, axes = forward(machine, orig.q)
    feed = ~orig.rapid
    seg = []                                  # row j: the move from point j-1 to point j
    for j in np.flatnonzero(feed):
        if j == 0:
            continue
        d = tips[j] - tips[j - 1]
        d = d - (d @ axes[j]) * axes[j]
        length = float(np.linalg.norm(d))
        if length > 1e-6:
            seg.append((j, d / length, length))
    if not seg:
        raise InputError("in-plane map: the program has no feed move across the tool axis",
                         orig.path)
    rows = np.array([j for j, _t, _l in seg])
    t = np.array([t for _j, t, _l in seg])
    n = np.cross(t, axes[rows])
    mid = 0.5 * (tips[rows] + tips[rows - 1])
    # passes: segments that follow each other without a rapid or a move along the axis between
    new_pass = np.ones(rows.size, bool)
    new_pass[1:] = rows[1:] != rows[:-1] + 1
    pass_id = np.cumsum(new_pass) - 1
    lengths = np.array([l for _j, _t, l in seg])
    for k in range(int(pass_id[-1]) + 1):
        m = pass_id == k
        centre = np.average(mid[m], axis=0, weights=lengths[m])
        sign = np.sign(np.sum(lengths[m] * np.einsum("ij,ij->i", mid[m] - centre, n[m]))) or 1.0
        n[m] *= sign if side == "outer" else -sign
    span = np.ptp(tips[np.concatenate([rows, rows - 1])], axis=0)
    width = BAND_SHARE * max(float(np.max(span)), 1e-3)
    s = rows.size
    index = np.concatenate([rows - 1, rows, rows - 1, rows])
    normals = np.tile(n, (4, 1))
    contact = tips[index] - radius * normals
    draw = contact + np.concatenate([np.zeros((2 * s, 1)), np.full((2 * s, 1), width)]) * normals
    a, b = np.arange(s), np.arange(s) + s                   # start, end on the contour
    c, e = a + 2 * s, b + 2 * s                              # start, end on the band's far edge
    tris = np.vstack([np.column_stack([a, b, e]), np.column_stack([a, e, c])])
    return _Geometry(index, draw, radius * axes[index], normals, tris)


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
                      normal: str = "surface") -> SurfaceMap:
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
    kind = "surface"
    g = None
    if length > 0:
        g = _flank_geometry(orig, machine, radius, length, flank_side, flank_levels)
    elif normal == "in-plane" or (normal == "auto" and planar_levels(orig, machine)):
        try:
            g = _inplane_geometry(orig, machine, radius, flank_side)
            kind = "in-plane"
        except InputError:
            if normal == "in-plane":
                raise
    if g is None:
        try:
            g = _tip_geometry(orig, machine, radius, max_edge_factor)
        except InputError:      # no surface seen along Z (a lathe profile, one point, no cutting)
            g = _path_geometry(orig, machine)
    sel = g.index
    T0 = tool2wp(machine, orig.q[sel])
    tips = T0[:, :3, 3]
    offset_tool = np.einsum("nji,nj->ni", T0[:, :3, :3], g.offset)   # R0^T offset: tool frame
    # referenced to the part's datum, as compensate references its corrections: the program's
    # origin (the machine zero: the map knows no work offsets), where the machinist probed the part
    nominal = tips + g.offset + fitted.datum_deviation(np.zeros((1, machine.n_axes)), machine.tool_length)
    dev_before = predicted_points(fitted, orig.q[sel], orig.feed[sel], orig.dirs[sel],
                                  offset_tool) - nominal
    dev_after = None
    if comp is not None:
        j = pair[sel]
        dev_after = predicted_points(fitted, comp.q[j], comp.feed[j], comp.dirs[j],
                                     offset_tool) - nominal
    return SurfaceMap(g.draw, tips, g.normals, g.triangles, orig.line[sel].copy(), dev_before,
                      dev_after, orig.path, None if comp is None else comp.path, g.offset, kind)

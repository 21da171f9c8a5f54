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
* holes (a drilling program: canned cycles, or only plunges along the tool axis): each hole's bottom,
  where it is; the map shows the size of its deviation across the tool axis (its position error),
  ``SurfaceMap.depth_um`` the deviation along it.

The deviation at a point is that of the tool point that cuts there -- the tip, the ball centre, or
the axis point at the contact height on a flank -- actual minus nominal, in the workpiece frame, by
compensate's evaluator (the model's tip and tool-axis deviation, at the blocks placed on the machine
as compensate places them); ``dn`` is its component along the normal
(positive: the tool stays off the surface, material is left outside, the sign a CMM reports). For a
compensated program the same tool point is taken at the corrected axis positions and compared with
its ORIGINAL nominal position; original and compensated blocks are paired through the programs'
line structure or the compensation report's source lines.
"""
from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..kinematics import forward, tool2wp
from ..machine import Machine
from .geometry import (MAX_EDGE_FACTOR, cutting_rows, cutting_runs, flank_geometry, hole_geometry, hole_rows,
                       path_geometry, path_line_geometry, select_surface_points, steep_triangles,
                       tip_geometry, triangulate_xy, vertex_normals)
from .inplane import inplane_geometry, planar_levels
from .program import (ProgramPoints, drawn_q, pair_compensated, read_program_points,
                      report_points)

#: the public face of the error maps (the surfaces and the program's points from their modules too)
__all__ = ["STATUS_REASONS", "SurfaceMap", "ProgramPoints", "read_program_points", "pair_compensated",
           "report_points", "predicted_points", "program_hints", "program_error_map", "report_status",
           "planner_status", "planar_levels", "select_surface_points", "triangulate_xy", "vertex_normals",
           "steep_triangles", "cutting_runs"]

#: why a block is left uncorrected (SurfaceMap.status)
STATUS_REASONS = {1: "an axis position the program has not given",
                  2: "outside the region the model's data reached",
                  3: "the model unsure (correction's standard error over the limit, the "
                     "correction within two of them of zero, or an approach its data never read)",
                  4: "a bound held an axis's whole correction"}


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
    normal_kind : 'surface' (the normal of the cut surface, or of the flank), 'in-plane' (the
        normal of a planar contour in its plane, across the tool axis), 'holes' (the bottoms of
        drilled holes; ``normals`` holds the tool axis, and ``dn`` is the size of a hole's position
        error across it, ``depth`` the error along it) or 'path' (a 3-D path that is no surface,
        drawn as its lines ``segments``; ``normals`` holds the path's direction, and ``dn`` is the
        size of the deviation across it).
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

    def _shown_um(self, dev: np.ndarray) -> np.ndarray:
        """(N,) um, what the map shows of the deviations ``dev`` (N, 3) mm: the component along
        the normal; for a hole or path map the size of the component across the tool axis or the
        path (>= 0)."""
        along = np.einsum("ij,ij->i", dev, self.normals)
        if self.normal_kind in ("holes", "path"):
            return 1e3 * np.linalg.norm(dev - along[:, None] * self.normals, axis=1)
        return 1e3 * along

    @property
    def dn_before_um(self) -> np.ndarray:
        """(N,) um, deviation along the normal before compensation (a hole map: the size of each
        hole's position error across the tool axis)."""
        return self._shown_um(self.dev_before)

    @property
    def dn_after_um(self) -> np.ndarray | None:
        """(N,) um, as :attr:`dn_before_um` for the compensated program, or None."""
        if self.dev_after is None:
            return None
        return self._shown_um(self.dev_after)

    def depth_um(self, dev: np.ndarray) -> np.ndarray:
        """(N,) um, a hole map's depth error: the deviation along the tool axis (positive: the tool
        stops short, the hole is too shallow)."""
        return 1e3 * np.einsum("ij,ij->i", dev, self.normals)

    def stats(self) -> dict:
        """RMS and largest magnitude of dn (um), before and (if present) after."""
        out = {"n_points": int(self.points.shape[0]), "n_triangles": int(self.triangles.shape[0])}
        for key, dev in (("before", self.dev_before), ("after", self.dev_after)):
            if dev is None:
                continue
            dn = self._shown_um(dev)
            out[f"rms_{key}_um"] = float(np.sqrt(np.mean(dn ** 2))) if dn.size else 0.0
            out[f"max_{key}_um"] = float(np.max(np.abs(dn))) if dn.size else 0.0
            if self.normal_kind == "holes":
                depth = self.depth_um(dev)
                out[f"depth_rms_{key}_um"] = float(np.sqrt(np.mean(depth ** 2))) if depth.size else 0.0
                out[f"depth_max_{key}_um"] = float(np.max(np.abs(depth))) if depth.size else 0.0
        return out


# ------------------------------------------------------------------------------------ geometry


# ----------------------------------------------------------------------------------- deviations
def _context(fitted, q_count, feed, dirs, tool_length=None):
    machine = fitted.machine
    cols = {"feed": feed}
    for j, a in enumerate(machine.axis_names):
        cols[f"dir_{a}"] = dirs[:, j].astype(float)
    if tool_length is not None and "tool_length" in fitted.model.context_names:
        cols["tool_length"] = np.asarray(tool_length, dtype=float)
    return fitted.context(q_count, cols)


def tool_lengths_of(orig: "ProgramPoints", machine: Machine, lengths: dict) -> np.ndarray:
    """(n,) mm: the tool length of each segment end, as compensate takes it: the length ``lengths``
    (H number -> mm) gives the ``G43 H`` number in force, else the machine's. It sets the model's
    Abbe arm only: the controller's own tool length offset puts the tip where the program says."""
    out = np.full(len(orig), float(machine.tool_length))
    if orig.tool is not None:
        for h, length in lengths.items():
            out[np.asarray(orig.tool) == h] = float(length)
    return out


def tools_assumed(orig: "ProgramPoints", sel: np.ndarray, lengths: dict) -> list[str]:
    """The tools in force at the segment ends ``sel`` whose length ``lengths`` (H number -> mm)
    does not give, as the program names them (``H1``, ``"DRILL 8.5"``)."""
    used = set(np.unique(np.asarray(orig.tool)[sel]).tolist()) - {0} - set(lengths)
    by_number = {h: name for name, h in (orig.tool_names or {}).items()}
    return [f'"{by_number[h]}"' if h in by_number else f"H{h}" for h in sorted(used)]


def tool_point_evaluator(fitted):
    """Compensate's evaluator of ``fitted`` (:class:`mtcomp.planner._evaluate.Evaluator`): the one
    way the model's deviation at a pose is computed, for the planner's residuals, the judges' and
    the error maps."""
    from ..planner import CompensationProblem
    from ..planner._evaluate import Evaluator
    return Evaluator(CompensationProblem.from_machine(fitted))


def predicted_points(fitted, q: np.ndarray, feed: np.ndarray, dirs: np.ndarray,
                     along: np.ndarray | None = None, tool_length=None, evaluator=None) -> np.ndarray:
    """(n, 3) mm: where the tool point ``along`` (n,) mm up the tool axis from the tip (None: the
    tip) really is in the workpiece frame at axis positions q (n, na), as the model ``fitted``
    predicts it (its tool tip and tool axis, every term included, evaluated where the model's data
    held an axis as compensate evaluates it; feed mm/min, approach directions and ``tool_length``
    (n,) mm (None: the machine's) as context), by compensate's evaluator (``evaluator``: one from
    :func:`tool_point_evaluator`, made here when None).
    """
    n = q.shape[0]
    if n == 0:
        return np.zeros((0, 3))
    ev = tool_point_evaluator(fitted) if evaluator is None else evaluator
    c = np.ascontiguousarray(_context(fitted, n, feed, dirs, tool_length), dtype=float)
    return ev.tool_point(np.ascontiguousarray(q, dtype=float), c, along)


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
                      progress=None, work_offset=None, setup=None) -> SurfaceMap:
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
    normal : 'surface', 'in-plane', 'holes', 'path' (:attr:`SurfaceMap.normal_kind`) or 'auto'
        (as :func:`_map_geometry` finds). A flank length > 0 maps the flank.
    uncorrected : mark the blocks left uncorrected (``SurfaceMap.status``): from the report's
        columns when a report is given, else by the planner's rules (:func:`planner_status`).
    progress : callable(stage text) told at each stage, or None.
    work_offset : (na,) mm (linear axes only) where the program's origin (G54) sits in machine
        axis positions, as compensate was given it, when no ``setup`` is given.
    setup : the :class:`mtcomp.toolpaths.offsets.ProgramSetup` compensate was given: the blocks
        (and the corrected ones) are placed on the machine by it as compensate places them, the
        model evaluated there, the map referenced to the part's datum; its tool lengths are the
        model's Abbe arm (a tool it does not list: the machine's, as compensate assumes, listed in
        ``info["tools_assumed"]``). None: the one ``program`` was read with, else no offsets.
    Raises InputError for programs without a surface or a compensated program that does not match.
    """
    radius, length = _tool(program, tool_radius_mm, flank_length_mm)
    if flank_side not in ("outer", "inner"):
        raise InputError(f"flank side must be 'outer' or 'inner', not {flank_side!r}")
    if normal not in ("surface", "in-plane", "holes", "path", "auto"):
        raise InputError(f"normal must be 'surface', 'in-plane', 'holes', 'path' or 'auto', not "
                         f"{normal!r}")
    orig, setup = _placed_program(machine, program, work_offset, setup)
    comp, pair = _compensated_points(orig, compensated, report, machine)
    say = progress or (lambda _stage: None)
    g, segments, info, kind = _map_geometry(orig, machine, radius, length, normal, flank_side,
                                            flank_levels, max_edge_factor, say)
    # each distinct tool point once (a contour's band repeats its ends four times)
    key = np.column_stack([g.index.astype(float), g.offset])
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.ravel()
    sel = g.index[first]
    tips = tool2wp(machine, drawn_q(orig)[sel])[:, :3, 3]
    lengths = setup.lengths_by_number(orig.tool_names or {})
    length_of = tool_lengths_of(orig, machine, lengths)
    if orig.tool is not None:
        info["tools_assumed"] = tools_assumed(orig, sel, lengths)
    dev_before, dev_after = _deviations(machine, fitted, orig, comp, pair, sel, g.offset[first],
                                        length_of[sel], say)
    status, source = None, ""
    if report is not None:
        status, source = report_status(report, len(orig))[sel], "report"
    elif uncorrected and hasattr(fitted, "support"):
        say(f"finding the blocks the planner leaves uncorrected ({sel.size} points)")
        status, source = planner_status(fitted, orig, sel, length_of), "planner"
    notes = [info.pop("left_out")] if "left_out" in info else []
    if kind == "surface" and length == 0 and g.normals.size and _along_tool_axis(machine, orig, g, info):
        notes.append("the normals all lie along the tool axis (a flat or 2-D program): the map "
                     "shows the deviation along the tool axis only, not the error across it "
                     "(--normal in-plane maps contours)")
    elif kind == "surface" and length == 0 and g.normals.size and _one_plane(g.normals):
        notes.append("the normals are all one (a flat face) and the tool is tilted to them: if the "
                     "program cuts a contour in that plane (at a lead angle) rather than the face, "
                     "the map fills the contour's inside and shows the deviation along the face's "
                     "normal only, not the contour's position (--normal in-plane maps its walls)")
    smap = SurfaceMap(g.draw, tips[inverse], g.normals, g.triangles, orig.line[g.index].copy(),
                      dev_before[inverse], None if dev_after is None else dev_after[inverse],
                      orig.path, None if comp is None else comp.path, g.offset, kind,
                      None if status is None else status[inverse], source, notes, info)
    smap.segments = segments
    return smap


def _deviations(machine, fitted, orig: ProgramPoints, comp, pair, sel, offset, lengths, say):
    """(before (n, 3), after (n, 3) or None) mm: the deviation the model predicts of the tool point
    ``offset`` (n, 3) mm, workpiece frame (a point of the tool axis), carried by the tool at the
    segment ends ``sel`` of the program (and at their corrected counterparts ``pair[sel]`` in
    ``comp``), tools of ``lengths`` (n,) mm: compensate's residual (:func:`predicted_points`). The
    model is evaluated where compensate places the blocks on the machine (``machine_q``: the work
    offset in force, under G254 turned with the table, a tool centre point row's tip turned into
    axes), and the deviation referenced to the part's datum as compensate references its
    corrections (``datum``: the program's origin as probed)."""
    ev = tool_point_evaluator(fitted)
    q0 = orig.machine_q[sel]
    along = np.einsum("ij,ij->i", offset, forward(machine, drawn_q(orig)[sel])[1])
    ctx = _context(fitted, sel.size, orig.feed[sel], orig.dirs[sel], lengths)
    nominal = tool2wp(machine, q0)[:, :3, 3] + offset \
        + ev.datum_reference(orig.datum[sel], ctx)[:, :3]
    say(f"deviation at {sel.size} points")
    before = predicted_points(fitted, q0, orig.feed[sel], orig.dirs[sel], along, lengths, ev) \
        - nominal
    if comp is None:
        return before, None
    say(f"deviation after compensation at {sel.size} points")
    j = pair[sel]
    return before, predicted_points(fitted, comp.machine_q[j], comp.feed[j], comp.dirs[j], along,
                                    lengths, ev) - nominal


def _placed_program(machine: Machine, program, work_offset, setup):
    """(the program's ProgramPoints, the set-up that placed them on the machine): ``program`` (a
    path, or ProgramPoints) placed by the set-up compensate was given (:func:`_program_setup`; one
    placement, compensate's), read again when it was read with another."""
    setup = _program_setup(machine, program, work_offset, setup)
    if isinstance(program, ProgramPoints) and program.setup is setup:
        return program, setup
    path = program.path if isinstance(program, ProgramPoints) else program
    return read_program_points(path, machine, setup=setup), setup


def _program_setup(machine: Machine, program, work_offset, setup):
    """The :class:`~mtcomp.toolpaths.offsets.ProgramSetup` the program is placed by: ``setup``, else
    one whose G54 is ``work_offset`` (na,), else the one ``program`` (ProgramPoints) was read with
    (else no offset); InputError for a rotary work offset
    (a map drawn in a turned frame is not what the program cut: not supported)."""
    from ..toolpaths.offsets import ProgramSetup
    if setup is None and work_offset is None and isinstance(program, ProgramPoints):
        setup = program.setup       # as it was read
    if setup is None:
        setup = ProgramSetup(machine, work_offsets={} if work_offset is None else
                             {0: np.asarray(work_offset, dtype=float)})
    for off in setup.work_offsets.values():
        turned = [a.name for a, v in zip(machine.axes, off) if a.is_rotary and v != 0.0]
        if turned:
            raise InputError(f"a work offset of rotary axis {turned[0]} is not supported by render "
                             "(linear axes only)")
    return setup


def _tool(program, tool_radius_mm, flank_length_mm) -> tuple[float, float]:
    """(tool radius, flank length), mm: as given, else from the header of a built-in test part."""
    hints = program_hints(program) if not isinstance(program, ProgramPoints) else {}
    radius = hints.get("tool_radius_mm", 0.0) if tool_radius_mm is None else float(tool_radius_mm)
    length = hints.get("flank_length_mm", 0.0) if flank_length_mm is None else float(flank_length_mm)
    if not radius >= 0:
        raise InputError(f"tool radius must be >= 0 mm, got {tool_radius_mm}")
    if not length >= 0:
        raise InputError(f"flank length must be >= 0 mm, got {flank_length_mm}")
    return radius, length


def _compensated_points(orig: ProgramPoints, compensated, report, machine: Machine):
    """(compensated ProgramPoints or None, (len(orig),) index of each segment end's counterpart in
    it or None): from the compensation report when given, else from the compensated program."""
    if report is not None:
        return report_points(orig, report, machine), np.arange(len(orig))
    if compensated is not None:
        comp = (compensated if isinstance(compensated, ProgramPoints)
                else read_program_points(compensated, machine, orig.dialect, orig.chord_tol_mm,
                                         orig.setup))
        if comp.setup is not orig.setup:        # placed as the program is
            comp = read_program_points(comp.path, machine, orig.dialect, orig.chord_tol_mm,
                                       orig.setup)
        return comp, pair_compensated(orig, comp, machine)
    return None, None


def _map_geometry(orig: ProgramPoints, machine: Machine, radius: float, length: float, normal: str,
                  flank_side: str, flank_levels, max_edge_factor: float, say):
    """(geometry, in-plane segments or None, info dict, normal kind 'surface', 'in-plane' or
    'holes' or 'path') of the surface :func:`program_error_map` draws: the holes of a drilling
    program (:func:`mtcomp.viz.geometry.hole_rows`), the flank, the in-plane contour of a program
    :func:`planar_levels` finds planar (:func:`mtcomp.viz.inplane.inplane_geometry`), the tool-tip
    surface, or, when most of that surface would be walls seen edge-on, the path's lines
    (:func:`mtcomp.viz.geometry.path_line_geometry`); the points of the path when there is no
    surface seen along Z."""
    holes = hole_rows(orig, machine) if length == 0 and normal in ("holes", "auto") else None
    if normal == "holes" and not holes.size:
        raise InputError("the program drills no hole (no drilling cycle, and feed moves across the "
                         "tool axis): --normal holes maps drilling programs", orig.path)
    cycle = np.zeros(len(orig), bool) if orig.cycle is None else np.asarray(orig.cycle, bool)
    cuts = cutting_rows(orig, machine) if cycle.any() else np.zeros(0, np.int64)
    if holes is not None and holes.size and (normal == "holes" or not cuts.size):
        say(f"{holes.size} holes")
        info = {"holes": int(holes.size), "drilling_cycles": bool(cycle.any())}
        # without cycles every feed move runs along the tool axis: a hole's pecks and retracts
        left = (np.setdiff1d(np.flatnonzero(~orig.rapid), holes) if cycle.any()
                else np.zeros(0, np.int64))
        if left.size:       # the feed moves that drill no hole (a milled slot beside the holes)
            info["left_out"] = (f"{left.size} feed move{'s' if left.size > 1 else ''} "
                                f"({_lines_text(orig.line[left])}) not drawn: the map shows the "
                                "holes only; --normal auto, in-plane, surface or path maps the "
                                "moves that cut")
        return hole_geometry(orig, machine, holes), None, info, "holes"
    if not cuts.size:
        return _cut_geometry(orig, machine, radius, length, normal, flank_side, flank_levels,
                             max_edge_factor, say)
    # drilling cycles beside moves that cut: the map shows the cut, the holes are said
    keep = np.flatnonzero(~cycle)
    g, segments, info, kind = _cut_geometry(_rows(orig, keep), machine, radius, length, normal,
                                            flank_side, flank_levels, max_edge_factor, say)
    g.index = keep[g.index]
    k = int(cycle.sum())
    info["left_out"] = (f"{k} hole{'s' if k > 1 else ''} of drilling cycles "
                        f"({_lines_text(orig.line[cycle])}) not drawn: the map shows the moves "
                        "that cut; --normal holes maps the holes")
    return g, segments, info, kind


def _cut_geometry(orig: ProgramPoints, machine: Machine, radius: float, length: float, normal: str,
                  flank_side: str, flank_levels, max_edge_factor: float, say):
    """:func:`_map_geometry` of a program's moves that cut (no hole map)."""
    kind = "surface"
    g, segments, info = None, None, {}
    if length > 0:
        g = flank_geometry(orig, machine, radius, length, flank_side, flank_levels)
    else:
        levels = planar_levels(orig, machine) if normal != "in-plane" else 0
        info["planar_levels"] = levels
        if normal == "in-plane" or (normal == "auto" and levels):
            say(f"contour of {len(orig)} segment ends")
            try:
                g, segments, more = inplane_geometry(orig, machine, radius, flank_side)
                info.update(more)
                kind = "in-plane"
            except InputError:
                if normal == "in-plane":
                    raise
    if normal == "path":
        g, segments = path_line_geometry(orig, machine)
        return g, segments, info, "path"
    if g is None and normal == "auto" and _tool_axis_turns(orig, machine):
        # a tool that tilts against the part (5-axis) cuts no surface seen along one axis: a
        # triangulation of its tips across Z would map a deviation along Z that nothing cuts
        info["path_segments"] = "tool axis"
        g, segments = path_line_geometry(orig, machine)
        return g, segments, info, "path"
    if g is None:
        try:
            g, info["steep_triangles"] = tip_geometry(orig, machine, radius, max_edge_factor)
        except InputError:      # no surface seen along Z (a lathe profile, one point, no cutting)
            g = path_geometry(orig, machine)
        steep = info.get("steep_triangles", 0)
        if normal == "auto" and steep and steep >= g.triangles.shape[0]:
            # most of the "surface" would be walls seen edge-on: the path is no surface
            info["path_segments"] = True
            g, segments = path_line_geometry(orig, machine)
            return g, segments, info, "path"
    return g, segments, info, kind


def _tool_axis_turns(orig: ProgramPoints, machine: Machine, limit_deg: float = 1.0) -> bool:
    """Whether the tool axis, seen from the workpiece, turns while the tool cuts: on at least a
    tenth of the feed moves, by more than ``limit_deg`` over them all (simultaneous 5-axis). A 3+2
    program, whose rotary axes index between faces, keeps it fixed while it cuts each face."""
    feed = np.flatnonzero(~orig.rapid)
    feed = feed[feed > 0]
    if feed.size < 2:
        return False
    start = forward(machine, drawn_q(orig)[feed - 1])[1]
    end = forward(machine, drawn_q(orig)[feed])[1]
    turn = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", start, end), -1.0, 1.0)))
    spread = np.degrees(np.arccos(np.clip(end @ end[0], -1.0, 1.0))).max()
    return bool(np.mean(turn > 1e-3) >= 0.1 and spread > limit_deg)


def _rows(orig: ProgramPoints, rows: np.ndarray) -> ProgramPoints:
    """The program's segment ends ``rows`` only (in order), as a program of their own."""
    def take(a):
        return None if a is None else np.asarray(a)[rows]
    return ProgramPoints(orig.path, orig.q[rows], orig.line[rows], orig.feed[rows], orig.dirs[rows],
                         orig.rapid[rows], take(orig.known), take(orig.cycle), take(orig.tcp),
                         orig.dialect, orig.chord_tol_mm, tool=take(orig.tool),
                         tool_names=orig.tool_names, machine_q=take(orig.machine_q),
                         datum=take(orig.datum), offsets=take(orig.offsets), setup=orig.setup,
                         drawn=take(orig.drawn))


def _lines_text(lines) -> str:
    """'line 8' or 'lines 8 to 21' (the first and the last of the lines given)."""
    lines = np.asarray(lines)
    lo, hi = int(lines.min()), int(lines.max())
    return f"line {lo}" if lo == hi else f"lines {lo} to {hi}"


def _along_tool_axis(machine: Machine, orig: ProgramPoints, g, info: dict) -> bool:
    """Whether a surface map's normals all lie along the tool axis (to 1 deg), or the program is
    planar: the map then shows the deviation along the tool axis only."""
    tip_axes = forward(machine, drawn_q(orig)[g.index])[1]
    along = np.abs(np.einsum("ij,ij->i", g.normals, tip_axes)) >= np.cos(np.radians(1.0))
    return bool(along.all() or info.get("planar_levels"))

def _one_plane(normals: np.ndarray) -> bool:
    """Whether a surface map's normals all lie along one direction (to 1 deg): a flat face."""
    return bool(np.all(np.abs(normals @ normals[0]) >= np.cos(np.radians(1.0))))


def report_status(report, n: int) -> np.ndarray:
    """(n,) int8 :data:`STATUS_REASONS` of the program's segment ends from the compensation report's
    columns ``unknown_axes``, ``outside_support``, ``uncertain``, ``active_bounds`` and
    ``corrected`` (its rows that are not inserted nodes, checked against the program by
    :func:`report_points` before)."""
    import csv
    with open(os.fspath(report), newline="") as f:
        rows = [r for r in csv.DictReader(f) if r.get("inserted", "0") == "0"]
    status = np.zeros(n, np.int8)
    for i, r in enumerate(rows[:n]):
        if r.get("corrected", "1") not in ("0", "0.0"):
            continue
        status[i] = (1 if r.get("unknown_axes") else 3 if r.get("uncertain") in ("1", "1.0")
                     else 4 if r.get("active_bounds") else 2)
    return status


def planner_status(fitted, orig: ProgramPoints, sel: np.ndarray, tool_length=None) -> np.ndarray:
    """(len(sel),) int8 :data:`STATUS_REASONS`: which of the blocks ``sel`` the planner would leave
    uncorrected under the model's and the machine's defaults (no --extrapolate, the default limit on
    a correction's standard error), by the planner's own rules, at the machine positions and the
    part's datum compensate places the blocks at (``orig.machine_q``, ``orig.datum``),
    ``tool_length`` (len(orig),) mm per segment end (None: the machine's)."""
    from ..planner import CompensationProblem, Planner, PlannerOptions
    planner = Planner(CompensationProblem.from_machine(fitted), PlannerOptions(threads=1))
    q = orig.machine_q[sel]
    datum = orig.datum[sel]
    known = np.ones(q.shape, bool) if orig.known is None else np.asarray(orig.known[sel], bool)
    unknown = ~known
    lengths = (np.full(len(orig), float(fitted.machine.tool_length)) if tool_length is None
               else np.asarray(tool_length, dtype=float))[sel]
    outside = planner.outside_support(q, known, lengths)
    # the standard error changes slowly with position: evaluated once per cell of 1/100 of the
    # part's extent (0.1 deg for rotary axes) and approach direction, at the cell's first block
    rotary = np.array([a.is_rotary for a in fitted.machine.axes])
    extent = max(float(np.max(np.ptp(q[:, ~rotary], axis=0))) if q.size and (~rotary).any() else 0.0,
                 1e-3)
    step = np.where(rotary, np.radians(0.1), extent / 100.0)
    key = np.column_stack([np.round(q / step), orig.dirs[sel], known, lengths])
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    _, _, sd, z = planner.block_status(q[first], known[first], orig.feed[sel][first],
                                       orig.dirs[sel][first], datum=datum[first],
                                       tool_length=lengths[first])
    sd = sd[inverse.ravel()]
    status = np.zeros(q.shape[0], np.int8)
    if planner.options.max_correction_sd_um:
        z = None if z is None else z[inverse.ravel()]
        status[_gated(orig, sel, sd, z, planner.options.max_correction_sd_um)] = 3
    status[planner.ram.whole_outside(outside)] = 2      # the ram alone: corrected but for it
    status[unknown.any(axis=1)] = 1
    return status


def _gated(orig: ProgramPoints, sel: np.ndarray, sd: np.ndarray, z: np.ndarray, limit: float):
    """(len(sel),) bool: the blocks ``sel`` the planner's gate leaves as compensate's does
    (:mod:`mtcomp.planner._contours`): a contour (feed moves cut one after the other; a hole is one
    of its own), found on the whole program (sel may repeat or skip blocks), is left whole when a
    block's standard error ``sd`` is over ``limit`` and when no block's correction is told from
    zero by its standard errors (``z``, :func:`mtcomp.planner._uncertainty.in_sd`; None: none
    judged)."""
    from ..planner._contours import gated_contours, quiet_contours
    with np.errstate(invalid="ignore"):
        over = sd > limit
    over_all = np.zeros(len(orig), bool)
    np.logical_or.at(over_all, sel, over)
    # a block's in_sd as the program has it (the last of a repeated one: they are the same block);
    # None: a model without a covariance, nothing judged
    z_all = np.full(len(orig), np.nan)
    if z is not None:
        z_all[sel] = z
    member = ~np.asarray(orig.rapid, bool)
    if orig.known is not None:
        member &= np.asarray(orig.known, bool).all(axis=1)
    cyc = np.zeros(len(orig), bool) if orig.cycle is None else np.asarray(orig.cycle, bool)
    start = cyc | np.r_[False, cyc[:-1]]
    return over | gated_contours(member, start, over_all)[0][sel] | \
        quiet_contours(member, start, z_all)[sel]

"""Where a program cut a measured part: the cutting moves of the G-code program that cut a CMM part
(:class:`CutProgram`, read from the G-code by the caller: :func:`mtcomp.toolpaths.cutter.read_cut_program`),
their cutter locations (ball centres sampled along the moves) and, for each point of a CMM file, the
pose of the program that cut it (:func:`cut_poses`). The CMM measurement model and the knot
placement of a fit use them. Nothing here reads G-code: the program is handed in already read."""
from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..kinematics import forward


@dataclass(frozen=True, eq=False)
class CutProgram:
    """The cutting moves (G0 left out) of the program that cut a part, in program order.

    path : the program's file as the user named it (for messages).
    start, end : (m, na) machine axis positions at each move's ends (the program's plus its work
    offset), ``machine.axis_names`` order, mm and rad.
    line : (m,) int, 1-based source line of each move's block.
    feed : (m,) mm/min commanded feed. dirs : (m, na) +1/-1 approach direction of each axis.
    tool_length : (m,) mm, the length of the tool in force (NaN or None: the machine's).
    datum : (na,) the machine position of the program's zero, its work offset (None: machine zero):
    the CMM measures the part in the program's frame, which sits there.
    Compared and hashed by identity: a cut program read once is one key of the cut poses' memory.
    """

    path: str
    start: np.ndarray
    end: np.ndarray
    line: np.ndarray
    feed: np.ndarray
    dirs: np.ndarray
    tool_length: np.ndarray | None = None
    datum: np.ndarray | None = None

    def __str__(self) -> str:
        return self.path

    def part_origin(self, machine) -> np.ndarray:
        """(3,) mm the program's zero in the workpiece frame: a cmm file's points (in the program's
        frame) are there plus their coordinates. Zero without a work offset."""
        if self.datum is None or not np.any(self.datum):
            return np.zeros(3)
        tip = forward(machine, np.vstack([np.zeros(machine.n_axes), self.datum]))[0]
        return tip[1] - tip[0]


class CutterLocations:
    """Densely sampled ball-centre path of a program's cutting moves (:class:`CutProgram`).

    start, end : (m, na) segment ends (mm, rad); line, feed, dirs : per segment.
    samples : (k, 3) mm ball centres (workpiece frame); seg : (k,) segment of each sample;
    u : (k,) position of the sample along its segment (0..1).
    """

    def __init__(self, machine, cut: CutProgram, radius: float, sample_mm: float = 0.1):
        from scipy.spatial import cKDTree
        if cut.start.shape[1] != len(machine.axes):
            raise ValueError(f"the cut program {cut.path} has {cut.start.shape[1]} axes, the machine "
                             f"{len(machine.axes)}")
        self.machine, self.start, self.end = machine, cut.start, cut.end
        self.line, self.feed, self.dirs, self.radius = cut.line, cut.feed, cut.dirs, radius
        start, end = cut.start, cut.end
        tip_s, ax_s = forward(machine, start)
        tip_e, ax_e = forward(machine, end)
        length = np.linalg.norm(tip_e - tip_s + radius * (ax_e - ax_s), axis=1)
        count = np.maximum(1, np.ceil(length / sample_mm).astype(int))
        seg = np.repeat(np.arange(len(start)), count + 1)
        first = np.repeat(np.cumsum(count + 1) - (count + 1), count + 1)
        u = (np.arange(seg.size) - first) / np.repeat(count, count + 1)
        self.seg, self.u = seg, u
        self.samples = self._centres(seg, u)
        self.tree = cKDTree(self.samples)

    def _q(self, seg, u):
        return self.start[seg] + u[:, None] * (self.end[seg] - self.start[seg])

    def _centres(self, seg, u):
        tip, axis = forward(self.machine, self._q(seg, u))
        return tip + self.radius * axis

    def nearest(self, target: np.ndarray):
        """For each (n, 3) target ball centre: (q (n, na) cutter location, segment (n,), distance (n,)
        mm from the target to that ball centre). The nearest sample is refined on its segment by
        projecting the target on the sampled centre polyline around it."""
        dist, idx = self.tree.query(target)
        seg = self.seg[idx]
        u = self.u[idx].copy()
        best = dist.copy()
        for nb in (-1, 1):
            j = np.clip(idx + nb, 0, len(self.seg) - 1)
            same = self.seg[j] == seg
            a, b = self.samples[idx], self.samples[j]
            ab = b - a
            den = np.einsum("ij,ij->i", ab, ab)
            lam = np.clip(np.einsum("ij,ij->i", target - a, ab) / np.where(den > 0, den, 1.0), 0, 1)
            pt = a + lam[:, None] * ab
            dd = np.linalg.norm(target - pt, axis=1)
            better = same & (den > 0) & (dd < best)
            u[better] = (self.u[idx] + lam * (self.u[j] - self.u[idx]))[better]
            best[better] = dd[better]
        return self._q(seg, u), seg, best


def path_offsets(machine, data, q, radius: float, cut: CutProgram | None = None) -> np.ndarray:
    """(n,) mm how far the program's nominal ball centre at the cutter locations ``q`` sits from the
    cmm points' own ball centre ``x + r n``, along each normal: ``n . (c0 - (x + r n))``. Zero for a
    program that follows the nominal surface; a compensated program's corrections; a wrong radius or
    a misplaced part as a whole. ``cut``: the program (default the data's), whose zero the points'
    coordinates are from."""
    cut = data.cut if cut is None else cut
    tip0, axis0 = forward(machine, q)
    centre = data.xyz + (np.zeros(3) if cut is None else cut.part_origin(machine)) + radius * data.normal
    return np.einsum("ij,ij->i", tip0 + radius * axis0 - centre, data.normal)


#: cmm data set -> (key, cut poses): the last poses found for it (the knots are placed from them
#: before the fit's measurement model finds them again)
_CUT_POSES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def cut_poses(machine, data, cut: CutProgram, radius: float, sample_mm: float = 0.1,
              max_gap_mm: float = 2.0):
    """(q (n, na), segment (n,), CutterLocations) of the cmm file ``data``: for each surface point the
    cutter location of the program's moves ``cut`` whose ball centre is nearest to ``x + r n``.
    InputError naming the row of a point no cutter location comes within ``max_gap_mm`` of.
    Remembered for the same data, machine geometry, cut program and radius (:data:`_CUT_POSES`)."""
    geometry = tuple((a.name, tuple(getattr(a, "axis_point", None) or ())) for a in machine.axes)
    key = (machine.topology, geometry, cut, float(radius), float(sample_mm), float(max_gap_mm))
    cached = _CUT_POSES.get(data)
    if cached is not None and cached[0] == key:
        return cached[1]
    if not radius > 0:
        raise InputError(f"tool radius must be positive, got {radius!r}", data.path)
    loc = CutterLocations(machine, cut, radius, sample_mm)
    q, k, gap = loc.nearest(data.xyz + cut.part_origin(machine) + radius * data.normal)
    far = np.flatnonzero(gap > max_gap_mm)
    if far.size:
        data.fail(f"no cutter location of {cut.path} within {max_gap_mm:g} mm of this point's "
                  f"ball centre (nearest {gap[far[0]]:.3g} mm): the program did not cut it", far[0])
    _CUT_POSES[data] = (key, (q, k, loc))
    return q, k, loc

"""G-code blocks and programs: the data the reader hands out and the writer takes.

One line of a program that moves the machine becomes a :class:`MotionBlock` (a drilling cycle kept
as a cycle adds its :class:`CycleBlock`); a whole program in memory is a :class:`Program`; the
streaming reader hands out its straight segments in :class:`SegmentChunk` rows. These are plain
data: :mod:`.modal` makes the blocks, :mod:`.reader` the chunks, :mod:`.writer` writes them back.

Units: mm, rad and mm/min; positions are axis positions in ``machine.axis_names`` order.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np


@dataclass
class SegmentChunk:
    """Straight segments in program order (arcs already split into chords); n rows, na axes.

    line : (n,) int, 1-based source line of the block the segment comes from.
    start, end : (n, na) float, axis positions in ``machine.axis_names`` order, mm and rad, in the
        program's own frame (work offsets and tool lengths not applied). An axis whose position the
        program has not given holds a placeholder (the last value, 0 at the start): see ``known``.
    feed : (n,) float, mm/min (inch programs converted); nan for rapids and before any F word.
    dirs : (n, na) int8, +1/-1 approach direction of each axis at the end of the segment: the sign
        of its last motion, carried over while it does not move (+1 before its first motion).
    rapid : (n,) bool, G0. from_arc : (n,) bool, a chord of a G2/G3 block.
    known : (n, na) bool, the program has given the axis's position (in its frame) at this segment:
        False at the start, after a G28/G30/G53 move of the axis, a tool change or tool length
        change (the tool axis), a change of work coordinate system (every axis), until the program
        names the axis again. Unknown axes are never written and never corrected.
    frame : (n,) int32, active work coordinate system and tool length number
        (:func:`~.words.frame_code`).
    cycle : (n,) bool, the row is the bottom of a hole of a drilling cycle (G73, G81-G89) that is
        kept as a cycle: one output block, reached by rapids, corrected as a whole.
    jump : (n,) bool, the row's start is not a position the program has given on every axis (an
        axis was unknown before its block: at the start, after a home move, a tool change ...):
        the machine does not come from ``start`` along a known line.
    tool_length : (n,) float, mm, tool length of the block for the error model (nan: the machine's),
        or None; set by the caller that knows the tool lengths (not read from the program).
    datum : (n, na) float, the machine axis positions of the program's origin (its work offset) at
        the row, or None (the machine zero); set by the caller that knows the work offsets. The
        corrections are referenced to it (mtcomp.planner: what the machinist's probing of the
        part's datum already removes is not corrected again).
    context : dict or None, more of the model's context per row, name -> (n,) float (e.g.
        ``temp_t1``: the temperatures along the program's run time); set by the caller.
    tcp : (n,) bool or None, the row is in tool centre point mode (set by
        :meth:`mtcomp.toolpaths.offsets.ProgramSetup.apply`, which turns such rows into axis
        positions; None: not known, none is).
    cutter_comp : (n,) int8, 0 where the row's block runs without cutter radius compensation, else
        the offset plane it runs under (17, 18, 19 for G17, G18, G19; :func:`crc_code`): G41/G42 in
        force, or its line switches it on or off. The controller offsets such a block as written,
        so an arc under it is written as one arc (:attr:`MotionBlock.cutter_comp`), and the planner
        ties the correction of the plane's axes where the block does not move in it.
    """

    line: np.ndarray
    start: np.ndarray
    end: np.ndarray
    feed: np.ndarray
    dirs: np.ndarray
    rapid: np.ndarray
    from_arc: np.ndarray
    known: np.ndarray | None = None
    frame: np.ndarray | None = None
    cycle: np.ndarray | None = None
    jump: np.ndarray | None = None
    tool_length: np.ndarray | None = None
    datum: np.ndarray | None = None
    context: dict | None = None
    cutter_comp: np.ndarray | None = None
    tcp: np.ndarray | None = None

    FIELDS = ("line", "start", "end", "feed", "dirs", "rapid", "from_arc", "known", "frame", "cycle",
              "jump")
    #: set by the caller, None until then
    OPTIONAL = ("tool_length", "datum", "tcp")

    def __post_init__(self):
        n, na = self.start.shape
        if self.known is None:
            self.known = np.ones((n, na), bool)
        if self.frame is None:
            self.frame = np.zeros(n, np.int32)
        if self.cycle is None:
            self.cycle = np.zeros(n, bool)
        if self.jump is None:
            self.jump = np.zeros(n, bool)
        if self.cutter_comp is None:
            self.cutter_comp = np.zeros(n, np.int8)

    def __len__(self) -> int:
        return int(self.line.shape[0])

    @staticmethod
    def concatenate(chunks: list["SegmentChunk"], n_axes: int) -> "SegmentChunk":
        if not chunks:
            return _empty_chunk(n_axes)
        # what the caller set (tool lengths, the datum) is kept when every chunk has it
        optional = {f: np.concatenate([getattr(c, f) for c in chunks]) for f in SegmentChunk.OPTIONAL
                    if all(getattr(c, f) is not None for c in chunks)}
        if all(c.context is not None for c in chunks) and \
                len({tuple(sorted(c.context)) for c in chunks}) == 1:
            optional["context"] = {k: np.concatenate([c.context[k] for c in chunks])
                                   for k in chunks[0].context}
        optional["cutter_comp"] = np.concatenate([c.cutter_comp for c in chunks])
        return SegmentChunk(*(np.concatenate([getattr(c, f) for c in chunks])
                              for f in SegmentChunk.FIELDS), **optional)


def crc_code(cutter_comp: bool, plane: int) -> int:
    """A row's :attr:`SegmentChunk.cutter_comp` code: 0 without cutter radius compensation, else
    the offset plane (17, 18, 19) the controller offsets its block in."""
    return int(plane) if cutter_comp else 0


def _empty_chunk(na: int) -> SegmentChunk:
    return SegmentChunk(np.zeros(0, np.int64), np.zeros((0, na)), np.zeros((0, na)), np.zeros(0),
                        np.zeros((0, na), np.int8), np.zeros(0, bool), np.zeros(0, bool),
                        np.zeros((0, na), bool), np.zeros(0, np.int32), np.zeros(0, bool),
                        np.zeros(0, bool))


@dataclass
class MotionBlock:
    """One motion line of the program (G0/G1/G2/G3 or a modal continuation).

    line : 1-based source line. motion : 0, 1, 2 or 3.
    start, end : (na,) nominal axis positions, mm and rad. feed : mm/min (nan: rapid / unknown).
    points : (k, na) ends of the straight segments (k = 1 for G0/G1; the chords of an arc).
    dirs : (k, na) int8 approach directions at the end of each segment.
    centre : (3,) arc centre in X Y Z (mm) for G2/G3, else None. plane : 17, 18 or 19.
    inch : the block was written in inches (G20).
    words : the tokens kept when the line is rewritten, in their original order and spelling
        (every word except N, G0-G3, G90/G91, X Y Z A B C, I J K R, and every comment).
    number : the N word as written ('' if none).
    known : (na,) bool, axes whose position the program has given (after this block).
    given : (na,) bool, axes named in this block. raw : axis letter -> its word as written.
    motion_word : the line carries its G0/G1/G2/G3. incremental : G91 was in force.
    inverse_time : G93 was in force (then ``f_word`` is the block's F value, 1/min).
    frame : :func:`~.words.frame_code` of the block.
    cycle : a drilling cycle line kept as a cycle (:class:`CycleBlock`), else None; its ``points``
        are then the bottoms of its holes (one per hole) and ``end`` where the cycle leaves the tool.
    start_known : every axis's position was known before the block (``start`` is where the machine
        stands, not a placeholder).
    absolute_centre : an arc written in G90.1 (its I J K are the centre's position in the program's
        frame, not offsets from the start); the writer writes its centre words the same way.
    cutter_comp : cutter radius compensation (G41/G42) is in force at the block, or its line
        switches it on or off (G40-G42: the entry and exit moves); the controller offsets the block
        as written, so the writer keeps such an arc one arc.
    """

    line: int
    motion: int
    start: np.ndarray
    end: np.ndarray
    feed: float
    points: np.ndarray
    dirs: np.ndarray
    centre: np.ndarray | None = None
    plane: int = 17
    inch: bool = False
    words: list[str] = field(default_factory=list)
    number: str = ""
    known: np.ndarray | None = None
    given: np.ndarray | None = None
    raw: dict = field(default_factory=dict)
    motion_word: bool = True
    incremental: bool = False
    inverse_time: bool = False
    f_word: float = math.nan
    frame: int = 0
    cycle: "CycleBlock | None" = None
    start_known: bool = True
    absolute_centre: bool = False
    cutter_comp: bool = False

    def __post_init__(self):
        if self.known is None:
            self.known = np.ones(self.start.shape[0], bool)
        if self.given is None:
            self.given = np.ones(self.start.shape[0], bool)

    @property
    def rapid(self) -> bool:
        return self.motion == 0

    @property
    def crc_code(self) -> int:
        """The block's :attr:`SegmentChunk.cutter_comp` code (:func:`crc_code`)."""
        return crc_code(self.cutter_comp, self.plane)

    @property
    def from_arc(self) -> bool:
        return self.motion in (2, 3)

    def segment_starts(self) -> np.ndarray:
        """(k, na) start of each segment of this block."""
        return np.vstack([self.start[None, :], self.points[:-1]])


@dataclass
class CycleBlock:
    """A drilling cycle line (G73, G81-G89) kept as a cycle: what the writer needs to restate it.

    code : 73, 81 ... r_level, z_bottom : mm, absolute levels of the R plane and the hole bottom in
    the program's frame. retract : 98 / 99, or None when the program has stated neither.
    starting : the line begins a series of cycles (the initial level is the Z before it).
    incremental : the line was written in G91 (its repeats become one absolute line each).
    tokens : the line's words and comments (letter, number, raw), without its N word.
    named : the letters among X Y Z R that the line gives.
    z_after_known : the program knows Z after the line (where the cycle leaves the tool).
    count_letter : the word that gave the repeat count ("L" or "K"), None when the line gives none.
    """

    code: int
    r_level: float
    z_bottom: float
    retract: int | None
    starting: bool
    incremental: bool
    tokens: list
    named: frozenset
    z_after_known: bool = False
    count_letter: str | None = None


@dataclass
class Program:
    """A whole program in memory (small programs and tests; use the streaming API for big ones)."""

    path: str
    axis_names: tuple[str, ...]
    blocks: list[MotionBlock]
    n_lines: int

    def segments(self) -> SegmentChunk:
        """Every segment of the program as one :class:`SegmentChunk`."""
        return SegmentChunk.concatenate([_block_rows(b) for b in self.blocks], len(self.axis_names))


def _block_rows(b: MotionBlock) -> SegmentChunk:
    k = b.points.shape[0]
    return SegmentChunk(np.full(k, b.line, np.int64), b.segment_starts(), b.points.copy(),
                        np.full(k, b.feed), b.dirs.copy(), np.full(k, b.rapid), np.full(k, b.from_arc),
                        np.repeat(b.known[None, :], k, axis=0), np.full(k, b.frame, np.int32),
                        np.full(k, b.cycle is not None), np.arange(k) == 0 if not b.start_known
                        else np.zeros(k, bool), cutter_comp=np.full(k, b.crc_code, np.int8))

"""G-code (ISO 6983 / RS-274, the subset in docs/toolpaths.md): reader, segment stream and writer.

Layers (after pygcode): a line is cut into *tokens* (words ``X-1.5`` and comments), the tokens of a
line form a *block*, and :class:`ModalState` -- the one place that holds the machine's modal state
(motion mode, plane, units, distance mode, feed, position, approach directions) -- turns each block
into motion or leaves it as a pass-through line.

Units: the file holds mm or inch (G21/G20) and deg for A, B, C; everything returned is mm, rad and
mm/min. Positions are axis positions in ``machine.axis_names`` order (tool-tip positions).

Public functions: :func:`iter_segment_chunks`, :func:`write_corrected`, :func:`read_program`
(see docs/toolpaths.md for the rules of what is rewritten and what passes through).
"""
from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass, field
from typing import Iterable, Iterator

import numpy as np

from ..errors import InputError
from ..io.atomic import atomic_write, check_output_path
from ..machine import Machine
from ._arcs import (FULL_CIRCLE_TOL_MM, PLANE_AXES, PLANE_OFFSET_LETTERS, ArcError, arc_chords,
                    centre_from_radius)

MM_PER_INCH = 25.4
#: an axis moving less than this (mm or rad) in a segment keeps its previous approach direction
DIR_EPS = 1e-9
DEFAULT_CHORD_TOL_MM = 1e-3
DEFAULT_CHUNK_SIZE = 65536
#: an arc stays one G2/G3 line when its corrections agree along it within this (mm; or within the
#: chord tolerance, if that is smaller): the shifted arc then misses no planned point by more
ARC_KEEP_TOL_MM = 1e-4
#: the axis along the tool: a tool change or a tool length change leaves its position unknown
TOOL_AXIS = "Z"

_NUM = r"[+-]?(?:\d+\.?\d*|\.\d+)"
_TOKEN_RE = re.compile(r"[ \t]+|\([^()]*\)|;.*|([A-Za-z])(" + _NUM + r")|(.)", re.S)
_AXIS_LETTERS = "XYZABC"
_UNIQUE_LETTERS = frozenset("XYZABCIJKRFNUVW")
#: G codes that would change geometry in a way mtcomp does not follow: refused, never guessed
_REFUSED_G = {
    10: "G10 (programmable data input)", 52: "G52 (local coordinate system)",
    92: "G92 (coordinate system offset set by the program; give the offset as a work offset G54-G59 "
        "instead)",
    92.3: "G92.3 (restored coordinate system offset)",
    68: "G68 (coordinate rotation)", 51: "G51 (scaling)",
    51.1: "G51.1 (mirroring)", 95: "G95 (feed per revolution)",
    74: "canned cycle G74 (left-hand tapping)", 76: "canned cycle G76 (threading)",
    90.1: "G90.1 (absolute arc centres)",
    43.4: "G43.4 (tool centre point control: the program gives tool-tip positions, not axis "
          "positions)",
    43.5: "G43.5 (tool centre point control: the program gives tool-tip positions, not axis "
          "positions)",
    68.2: "G68.2 (tilted working plane)", 68.3: "G68.3 (tilted working plane)",
    53.1: "G53.1 (tool axis direction control)",
    65: "G65 (macro call)", 66: "G66 (modal macro call)",
    # moves that stop where a signal comes (the position after them is not the program's), and
    # coordinates that are not axis positions
    31: "G31 (skip function: the move stops where the signal comes, and later positions are unknown)",
    31.1: "G31.1 (multi-step skip: the move stops where the signal comes)",
    31.2: "G31.2 (multi-step skip: the move stops where the signal comes)",
    31.3: "G31.3 (multi-step skip: the move stops where the signal comes)",
    31.4: "G31.4 (multi-step skip: the move stops where the signal comes)",
    37: "G37 (automatic tool length measurement: the move stops at the sensor and sets the offset)",
    38.2: "G38.2 (probing move: it stops where the probe touches, and later positions are unknown)",
    38.3: "G38.3 (probing move: it stops where the probe touches, and later positions are unknown)",
    38.4: "G38.4 (probing move: it stops where the probe leaves, and later positions are unknown)",
    38.5: "G38.5 (probing move: it stops where the probe leaves, and later positions are unknown)",
    16: "G16 (polar coordinates: X and Y are a radius and an angle)",
    12.1: "G12.1 (polar coordinate interpolation)", 112: "G112 (polar coordinate interpolation)",
    7.1: "G7.1 (cylindrical interpolation)", 107: "G107 (cylindrical interpolation)",
    5.2: "G5.2 (NURBS)", 6.2: "G6.2 (NURBS)",
}
#: codes that are a curve when the block has coordinates, and a mode switch without them (Fanuc's
#: G05 P10000 high-precision contour control, G05.1 Q1 AI contour control pass through)
_CURVE_WITH_COORDINATES = {5: ("G5 (cubic spline)", frozenset("XYZABCIJKR")),
                           5.1: ("G5.1 (quadratic spline)", frozenset("XYZABCIJK"))}
#: M codes refused (subprograms, tool centre point control)
_REFUSED_M = {98: "M98 (subprogram call)", 99: "M99 (subprogram end)",
              128: "M128 (tool centre point control: the program gives tool-tip positions, not axis "
                   "positions)",
              428: "M428 (LinuxCNC switchable kinematics to tool centre point: the program gives "
                   "tool-tip positions, not axis positions)",
              430: "M430 (LinuxCNC switchable kinematics: the program does not give axis positions)"}
#: drilling cycles: their lines pass through unchanged (not corrected), see docs/toolpaths.md
_CANNED_CYCLES = frozenset({73, 81, 82, 83, 84, 85, 86, 87, 88, 89})
#: work coordinate systems, in the order of their index in ``frame`` codes
WORK_SYSTEMS = ("G54", "G55", "G56", "G57", "G58", "G59", "G59.1", "G59.2", "G59.3")
_WCS_INDEX = {54: 0, 55: 1, 56: 2, 57: 3, 58: 4, 59: 5, 59.1: 6, 59.2: 7, 59.3: 8}
_NEG_ZERO_RE = re.compile(r"-(0\.0+)(?![0-9])")
#: a program number written with ':' (the ISO code's O), alone or with comments
_COLON_PROGRAM_RE = re.compile(r":\s*\d+\s*(?:\([^()]*\)\s*)*(?:;.*)?$")
#: features of other languages, refused with their name (checked on lines that do not tokenize)
_O_WORD_RE = re.compile(r"^\s*(?:[Nn]\s*\d+\s*)?[Oo]\s*(?:\d+|<[^>]*>)\s*([A-Za-z]+)")
_KEYWORDS = {
    "TRAORI": "TRAORI (Siemens 5-axis transformation: tool centre point control)",
    "TRAFOOF": "TRAFOOF (Siemens transformation off)", "CYCLE": "Siemens cycle calls",
    "IF": "macro statement IF", "GOTO": "macro statement GOTO", "WHILE": "macro statement WHILE",
    "END": "macro statement END", "DO": "macro statement DO", "CALL": "subprogram CALL",
    "TOOL": "Heidenhain TOOL CALL",
    "BEGIN": "Heidenhain conversational program (BEGIN PGM)",
}


def frame_code(wcs: int, tool: int) -> int:
    """Pack the work coordinate system index (0 = G54 .. 8 = G59.3) and the active tool length
    number H (0: none, G49) into one int: ``wcs + 16 * tool``."""
    return int(wcs) + 16 * int(tool)


def frame_wcs(code):
    """Work coordinate system index (0 = G54 ...) of frame codes (int or array)."""
    return np.asarray(code) % 16


def frame_tool(code):
    """Active tool length number H (0: none) of frame codes (int or array)."""
    return np.asarray(code) // 16


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
    frame : (n,) int32, active work coordinate system and tool length number (:func:`frame_code`).
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

    FIELDS = ("line", "start", "end", "feed", "dirs", "rapid", "from_arc", "known", "frame", "cycle",
              "jump")
    #: set by the caller, None until then
    OPTIONAL = ("tool_length", "datum")

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

    def __len__(self) -> int:
        return int(self.line.shape[0])

    @staticmethod
    def concatenate(chunks: list["SegmentChunk"], n_axes: int) -> "SegmentChunk":
        if not chunks:
            return _empty_chunk(n_axes)
        # what the caller set (tool lengths, the datum) is kept when every chunk has it
        optional = {f: np.concatenate([getattr(c, f) for c in chunks]) for f in SegmentChunk.OPTIONAL
                    if all(getattr(c, f) is not None for c in chunks)}
        return SegmentChunk(*(np.concatenate([getattr(c, f) for c in chunks])
                              for f in SegmentChunk.FIELDS), **optional)


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
    frame : :func:`frame_code` of the block.
    cycle : a drilling cycle line kept as a cycle (:class:`CycleBlock`), else None; its ``points``
        are then the bottoms of its holes (one per hole) and ``end`` where the cycle leaves the tool.
    start_known : every axis's position was known before the block (``start`` is where the machine
        stands, not a placeholder).
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

    def __post_init__(self):
        if self.known is None:
            self.known = np.ones(self.start.shape[0], bool)
        if self.given is None:
            self.given = np.ones(self.start.shape[0], bool)

    @property
    def rapid(self) -> bool:
        return self.motion == 0

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
                        else np.zeros(k, bool))


# --------------------------------------------------------------------------------------- tokens
def _strip_blanks(text: str) -> str:
    """The line without blanks outside comments: RS-274 ignores them (``Z 10`` is ``Z10``)."""
    if " " not in text and "\t" not in text:
        return text
    out = []
    pos, n = 0, len(text)
    while pos < n:
        ch = text[pos]
        if ch == "(":
            e = text.find(")", pos)
            e = n if e < 0 else e + 1
            out.append(text[pos:e])
            pos = e
        elif ch == ";":
            out.append(text[pos:])
            break
        else:
            if ch not in " \t":
                out.append(ch)
            pos += 1
    return "".join(out)


def _foreign_feature(text: str) -> str | None:
    """Name of a language feature mtcomp does not interpret, if the line uses one."""
    m = _O_WORD_RE.match(text)
    if m:
        return f"O-word {m.group(1).lower()} (subroutines and control flow)"
    code = text.split(";", 1)[0]
    code = re.sub(r"\([^()]*\)", "", code)
    if "#" in code:
        return "#-parameters"
    if "[" in code:
        return "expressions in [ ]"
    for word in re.findall(r"[A-Za-z]{2,}", code):
        key = word.upper()
        for k, name in _KEYWORDS.items():
            if len(k) >= 2 and key.startswith(k):
                return name
    return None


def tokenize(text: str, path=None, line: int | None = None) -> list[tuple[str, str, str]]:
    """Cut one line (without its line ending) into tokens ``(letter, number, raw)``.

    letter is the upper-case word letter, or '(' / ';' for a comment (number '' then). Blanks
    inside words are ignored, as RS-274 prescribes (``Z 10`` is ``Z10``; raw is then ``Z10``).
    Raises InputError for anything that is not a word, a comment or blank; a line in a language
    mtcomp does not interpret (O-word subroutines, #-parameters, macro statements) is refused with
    the feature's name.
    """
    out = []
    pos, n = 0, len(text)
    compact = None
    while pos < n:
        m = _TOKEN_RE.match(text, pos)
        raw = m.group(0)
        if m.group(3) is not None:
            if compact is None:
                feature = _foreign_feature(text)
                if feature is not None:
                    raise InputError(f"{feature} not supported: {text.strip()[:40]!r}", path, line)
                compact = _strip_blanks(text)
                if compact != text:          # blanks inside words: read the line without them
                    return tokenize(compact, path, line)
            ch = m.group(3)
            if ch == "(":
                raise InputError("comment '(' is not closed on this line (or is nested)", path, line)
            if ch.isalpha() and ch.isascii():
                raise InputError(f"word {ch.upper()} without a valid number: "
                                 f"{text[pos:pos + 12].strip()!r}", path, line)
            raise InputError(f"unexpected character {ch!r} at column {pos + 1}", path, line)
        if m.group(1) is not None:
            out.append((m.group(1).upper(), m.group(2), raw))
        elif raw[0] in "(;":
            out.append((raw[0], "", raw))
        pos = m.end()
    return out


# ---------------------------------------------------------------------------------- modal state
class ModalState:
    """The machine's modal state while a program is read, and the interpreter of one block.

    motion : None (none yet / G80), 0, 1, 2 or 3. plane : 17, 18, 19. inch : G20 active.
    incremental : G91 active. feed : mm/min (nan until the first F). position : (na,) mm and rad.
    dirs : (na,) int8 approach directions. known : (na,) bool, the program has given the axis's
    position in its frame (see :class:`SegmentChunk`). wcs : active work coordinate system index
    (0 = G54). tool : active tool length number (G43 H; 0 = none). cycle : the drilling cycle in
    force (G81 ...) or None. inverse_time : G93 in force.
    """

    def __init__(self, machine: Machine, path=None, chord_tol: float = DEFAULT_CHORD_TOL_MM,
                 initial_position: np.ndarray | None = None, inch: bool = False,
                 initial_known=None):
        self.machine = machine
        self.path = None if path is None else os.fspath(path)
        self.chord_tol = float(chord_tol)
        if not self.chord_tol > 0:
            raise ValueError("chord_tol_mm must be positive")
        self.names = machine.axis_names
        self.na = len(self.names)
        self.rotary = [n in "ABC" for n in self.names]
        self.home = (np.zeros(self.na) if initial_position is None
                     else np.asarray(initial_position, dtype=float).reshape(self.na).copy())
        self.position = self.home.copy()
        if initial_known is None:
            initial_known = initial_position is not None
        self.known = np.broadcast_to(np.asarray(initial_known, bool), (self.na,)).copy()
        self.dirs = np.ones(self.na, np.int8)
        self.motion: int | None = None
        self.plane = 17
        self.inch = bool(inch)
        self.incremental = False
        self.feed = math.nan
        self.wcs = 0
        self.tool = 0
        self.selected_tool = 0
        self.cycle: int | None = None
        #: drilling cycles: G98/G99 in force (None: neither stated), the sticky R and Z words
        #: (mm, given in G91), the initial level of the series (mm, known)
        self.retract: int | None = None
        self.cycle_r: tuple[float, bool] | None = None
        self.cycle_z: tuple[float, bool] | None = None
        self.cycle_init: tuple[float, bool] = (math.nan, False)
        #: the last block began a series of drilling cycles
        self.cycle_start = False
        self.inverse_time = False
        self.f_word = math.nan
        self.tool_axis = self.names.index(TOOL_AXIS) if TOOL_AXIS in self.names else -1
        self.xyz_index = tuple(machine.index(c) if c in self.names else -1 for c in "XYZ")
        #: 90 / 91 if the last block interpreted carried G90 / G91, else None
        self.distance_word: int | None = None
        #: the last block was a G28/G30 with axis words (read in the distance mode in force)
        self.distance_sensitive = False
        #: the last block carried a G word (the output's motion mode is then re-stated)
        self.had_g = False
        #: the last block was a drilling cycle line (passed through)
        self.cycle_line = False

    @property
    def frame(self) -> int:
        return frame_code(self.wcs, self.tool)

    @property
    def python_only(self) -> bool:
        """Lines the compiled scanner must not take (cycle or inverse-time mode in force)."""
        return self.cycle is not None or self.inverse_time

    def _err(self, msg, line):
        return InputError(msg, self.path, line)

    def _forget(self, idx=None):
        """The program's position of these axes (all by default) is unknown from here on."""
        if idx is None:
            self.known[:] = False
        elif idx >= 0:
            self.known[idx] = False

    def block(self, line: int, text: str) -> MotionBlock | None:
        """Interpret one line (text without line ending). Returns its motion, or None."""
        self.distance_word = None
        self.distance_sensitive = False
        self.had_g = False
        self.cycle_line = False
        self.cycle_start = False
        if line == 1 and text.startswith("\xef\xbb\xbf"):      # a UTF-8 byte order mark
            text = text[3:]
        s = text.lstrip(" \t")
        if not s or s[0] == "%":
            return None
        if s[0] == ":" and _COLON_PROGRAM_RE.match(s):    # ':0097': ISO's O, a program number
            return None
        if not s.strip("\x1a \t"):        # DOS end-of-file mark (Ctrl-Z) after the program
            return None
        if s[0] == "$":               # grbl system command: passes through; $H homes every axis
            if s[1:2].upper() in ("H", "J"):
                self._forget()
            return None
        if s[0] == "/":
            raise self._err("block delete '/' is not supported", line)
        tokens = tokenize(text, self.path, line)
        if not tokens:
            return None
        values: dict[str, float] = {}
        gcodes: list[float] = []
        mcodes: list[float] = []
        number = ""
        for letter, num, raw in tokens:
            if letter in "(;":
                continue
            try:
                v = float(num)
            except ValueError:  # pragma: no cover - the token pattern only lets numbers through
                raise self._err(f"garbled number in {raw!r}", line) from None
            if letter == "G":
                gcodes.append(v)
                continue
            if letter == "M":
                mcodes.append(v)
                continue
            if letter == "T":
                self.selected_tool = int(v)
            if letter in _UNIQUE_LETTERS:
                if letter in values:
                    raise self._err(f"word {letter} appears twice", line)
                values[letter] = v
                if letter == "N":
                    number = raw
            elif letter in "HL":
                values[letter] = v
        for m in mcodes:
            if m in _REFUSED_M:
                raise self._err(f"{_REFUSED_M[m]} is not supported", line)
        motion = None
        nonmotion_axes = False     # G4 dwell (X/P is time), G28/G30/G53: axis words are no motion
        home_move = None
        cycle = None
        tool_change = any(m == 6 for m in mcodes)
        self.had_g = bool(gcodes)
        for g in gcodes:
            gi = round(g)
            if g in _REFUSED_G:
                raise self._err(f"{_REFUSED_G[g]} is not supported", line)
            if g in _CURVE_WITH_COORDINATES:
                name, words = _CURVE_WITH_COORDINATES[g]
                if any(letter in words for letter, _num, _raw in tokens):
                    raise self._err(f"{name} is not supported", line)
            if g != gi:
                if g in _WCS_INDEX:
                    self._set_wcs(_WCS_INDEX[g])
                elif round(g, 1) in (28.1, 30.1, 92.1, 92.2, 43.1, 54.1):
                    if round(g, 1) in (92.1, 92.2, 43.1, 54.1):
                        self._forget()
                continue
            if gi in (0, 1, 2, 3):
                if motion is not None:
                    raise self._err(f"two motion codes G{motion} and G{gi} in one block", line)
                motion = gi
            elif gi in (17, 18, 19):
                self.plane = gi
            elif gi == 20:
                self.inch = True
            elif gi == 21:
                self.inch = False
            elif gi == 90:
                self.incremental = False
                self.distance_word = 90
            elif gi == 91:
                self.incremental = True
                self.distance_word = 91
            elif gi == 93:
                self.inverse_time = True
            elif gi == 94:
                self.inverse_time = False
            elif gi == 4:
                nonmotion_axes = True
            elif gi in (28, 30, 53):
                nonmotion_axes = True
                home_move = gi
            elif gi in (98, 99):
                self.retract = gi
            elif gi == 80:
                self.motion = None
                self.cycle = None
            elif gi in _CANNED_CYCLES:
                cycle = gi
            elif gi in _WCS_INDEX:
                self._set_wcs(_WCS_INDEX[gi])
            elif gi in (43, 44):
                self.tool = int(values.get("H", self.selected_tool))
                self._forget(self.tool_axis)
            elif gi == 49:
                self.tool = 0
                self._forget(self.tool_axis)
        if tool_change:
            self._forget(self.tool_axis)
        for letter in "UVW":
            if letter in values:
                raise self._err(f"axis word {letter}: machine {self.machine.name} has no {letter} axis",
                                line)
        axes_given = [c for c in _AXIS_LETTERS if c in values]
        for c in axes_given:
            if c not in self.names:
                raise self._err(f"axis word {c}: machine {self.machine.name} has no {c} axis "
                                f"(axes: {' '.join(self.names)})", line)
        if home_move is not None and motion is not None and not (home_move == 53 and motion < 2):
            raise self._err(f"G{home_move} and motion G{motion} in one block", line)
        if "F" in values:
            if self.inverse_time:
                if not values["F"] > 0:
                    raise self._err(f"feed F must be positive, got {values['F']:g}", line)
                self.f_word = values["F"]
            else:
                f = values["F"] * (MM_PER_INCH if self.inch else 1.0)
                if not f > 0:
                    raise self._err(f"feed F must be positive, got {values['F']:g}", line)
                self.feed = f
        if nonmotion_axes:
            self.distance_sensitive = home_move in (28, 30) and bool(axes_given)
            if home_move is not None:
                if motion is not None:      # G53 G0 Z0: a move in machine coordinates
                    self.motion = motion
                    self.cycle = None
                self._home_move(home_move, values, axes_given, line)
            return None
        if motion is not None:
            self.motion = motion
            self.cycle = None
        if cycle is not None:
            if self.cycle is None:
                self.cycle_start = True
                z = self.tool_axis
                self.cycle_init = (float(self.position[z]), bool(self.known[z])) if z >= 0 \
                    else (math.nan, False)
            self.cycle = cycle
            self.motion = None
        if self.cycle is not None:
            scale = MM_PER_INCH if self.inch else 1.0
            if "R" in values:
                self.cycle_r = (values["R"] * scale, self.incremental)
            if "Z" in values:
                self.cycle_z = (values["Z"] * scale, self.incremental)
        if self.cycle is not None and axes_given:
            return self._cycle_block(line, values, axes_given, tokens, number)
        arc_words = [c for c in "IJKR" if c in values]
        is_motion = bool(axes_given) or (self.motion in (2, 3) and bool(arc_words))
        if not is_motion:
            if arc_words and self.cycle is None:
                raise self._err(f"{arc_words[0]} word outside an arc block", line)
            return None
        if self.motion is None:
            raise self._err("coordinates without a motion mode (no G0/G1/G2/G3 in force; a controller's "
                            "power-on mode is not assumed: write G0 or G1 in this block)", line)
        if self.motion in (0, 1) and arc_words:
            raise self._err(f"{arc_words[0]} word in a G{self.motion} block (only G2/G3 take I J K R)",
                            line)
        if self.inverse_time and self.motion != 0 and "F" not in values:
            raise self._err(f"G93 (inverse time feed): the G{self.motion} block has no F word", line)
        start = self.position.copy()
        end = start.copy()
        scale = MM_PER_INCH if self.inch else 1.0
        given = np.zeros(self.na, bool)
        raw_axes = {}
        for c in axes_given:
            i = self.names.index(c)
            if self.incremental and not self.known[i]:
                raise self._err(f"incremental (G91) move of axis {c}, whose position the program "
                                "has not given (at the start, or after a home move, tool change "
                                "or offset change)", line)
            v = math.radians(values[c]) if c in "ABC" else values[c] * scale
            end[i] = start[i] + v if self.incremental else v
            given[i] = True
        if not self.incremental:
            raw_axes = {letter: raw for letter, _num, raw in tokens if letter in _AXIS_LETTERS}
        centre = None
        if self.motion in (2, 3):
            # LinuxCNC's P turns: even P1 (the plain arc) is refused, since a corrected arc is written
            # as straight G1 chords, which may not carry a P word
            if any(letter == "P" for letter, _num, _raw in tokens):
                raise self._err(f"arc G{self.motion} with a P word (a number of turns) is not supported",
                                line)
            i0, i1, _ = PLANE_AXES[self.plane]
            plane_idx = [self.xyz_index[i0], self.xyz_index[i1]]
            if min(self.xyz_index) >= 0 and not all(self.known[i] for i in plane_idx):
                raise self._err(f"arc G{self.motion} from a position the program has not given "
                                f"(axes {self.names[plane_idx[0]]} {self.names[plane_idx[1]]})",
                                line)
            pts, centre = self._arc(start, end, values, line)
        else:
            pts = end[None, :]
        start_known = bool(self.known.all())
        self.known |= given
        dirs = self._directions(start, pts)
        if self.motion == 0:
            feed = math.nan
        elif self.inverse_time:
            length = float(np.sum(np.linalg.norm(np.diff(
                np.vstack([start, pts])[:, [i for i in self.xyz_index if i >= 0]], axis=0), axis=1)))
            feed = length * self.f_word if length > 0 else math.nan
        else:
            feed = self.feed
        self.position = end
        words = [raw for letter, num, raw in tokens
                 if not (letter == "N" or letter in _AXIS_LETTERS or letter in "IJKR"
                         or (letter == "G" and float(num) in (0, 1, 2, 3, 90, 91)))]
        motion_word = any(letter == "G" and float(num) in (0, 1, 2, 3) for letter, num, _r in tokens)
        return MotionBlock(line, self.motion, start, end, feed, pts, dirs, centre, self.plane,
                           self.inch, words, number, self.known.copy(), given, raw_axes,
                           motion_word, self.incremental, self.inverse_time and self.motion != 0,
                           self.f_word, self.frame, start_known=start_known)

    def _set_wcs(self, index: int):
        if index != self.wcs:
            self.wcs = index
            self._forget()

    def _cycle_unclear(self, inc: bool) -> str | None:
        """Why a drilling cycle line cannot be kept as a corrected cycle (None: it can)."""
        if min(self.xyz_index) < 0:
            return "a machine without X, Y and Z"
        if self.plane != 17:
            return f"drilling along another axis than Z (G{self.plane})"
        if self.cycle == 87:
            return "back boring G87"
        if self.inverse_time:
            return "inverse time feed G93"
        if self.cycle_r is None or self.cycle_z is None:
            return "no R or Z word given for the cycle"
        if self.cycle_r[1] != inc or self.cycle_z[1] != inc:
            return "its R or Z was given in the other distance mode (G90/G91)"
        return None

    def _cycle_block(self, line, values, axes_given, tokens, number) -> MotionBlock | None:
        """A drilling cycle line. Where the hole is clear (X, Y, the R plane and the bottom known,
        plane G17) it becomes a :class:`CycleBlock` whose points are the bottoms of its holes;
        otherwise it passes through uncorrected (G90) or is refused (G91: an incremental cycle
        passed through would be read against an absolute output)."""
        rot = [c for c in axes_given if c in "ABC"]
        if rot:
            raise self._err(f"drilling cycle G{self.cycle} with a rotary axis word {rot[0]} is not "
                            "supported", line)
        inc = self.incremental
        reason = self._cycle_unclear(inc)
        xi, yi, zi = self.xyz_index
        if reason is None and not inc and not all(self.known[i] or c in values
                                                  for i, c in ((xi, "X"), (yi, "Y"))):
            reason = "its X or Y position is not known"
        if reason is not None:
            if inc:
                raise self._err(f"incremental (G91) drilling cycle G{self.cycle}: {reason}", line)
            self._cycle_move(values, axes_given)
            return None
        scale = MM_PER_INCH if self.inch else 1.0
        # the repeat count: L (LinuxCNC, Haas, Siemens ISO mode); K on Fanuc, but only where the
        # line has no L and no I/J (Haas G73/G83 write I J K as first peck, peck reduction and
        # minimum peck)
        count_letter = "L" if "L" in values else (
            "K" if "K" in values and "I" not in values and "J" not in values else None)
        reps = values.get(count_letter, 1.0) if count_letter else 1.0
        if reps != int(reps) or reps < 1:
            raise self._err(f"drilling cycle repeat count {reps:g} is not supported (a whole number "
                            ">= 1)", line)
        reps = int(reps)
        start = self.position.copy()
        start_known = bool(self.known.all())
        init_z, init_known = self.cycle_init
        if inc:
            if not (self.known[xi] and self.known[yi] and self.known[zi]):
                raise self._err(f"incremental (G91) drilling cycle G{self.cycle} from a position the "
                                "program has not given", line)
            if not self.cycle_start and self.retract != 98:
                raise self._err(f"incremental (G91) drilling cycle G{self.cycle} continued without "
                                "G98: where its R plane lies differs between controllers", line)
            r_level = start[zi] + self.cycle_r[0]
            z_bottom = r_level + self.cycle_z[0]
            steps = np.arange(1, reps + 1)
            xs = start[xi] + steps * values.get("X", 0.0) * scale
            ys = start[yi] + steps * values.get("Y", 0.0) * scale
        else:
            r_level, z_bottom = self.cycle_r[0], self.cycle_z[0]
            xs = np.array([values["X"] * scale if "X" in values else start[xi]])
            ys = np.array([values["Y"] * scale if "Y" in values else start[yi]])
        pts = np.repeat(start[None, :], xs.shape[0], axis=0)
        pts[:, xi], pts[:, yi], pts[:, zi] = xs, ys, z_bottom
        given = np.zeros(self.na, bool)
        given[[xi, yi, zi]] = True
        known = self.known | given
        dirs = self._directions(start, pts)
        # where the cycle leaves the tool: the R plane (G99) or the initial level (G98; controllers
        # differ when the R plane lies above it, and neither stated leaves it open)
        if self.retract == 99:
            z_after, z_known = r_level, True
        elif self.retract == 98 and init_known and r_level <= init_z + 1e-9:
            z_after, z_known = init_z, True
        else:
            z_after, z_known = r_level, False
        end = pts[-1].copy()
        end[zi] = z_after
        self.dirs[zi] = 1                  # the retract moves Z up last
        self.position = end
        self.known = known.copy()
        self.known[zi] = z_known
        feed = self.feed
        info = CycleBlock(self.cycle, r_level, z_bottom, self.retract, self.cycle_start, inc,
                          [t for t in tokens if t[0] != "N"],
                          frozenset(c for c in "XYZR" if c in values), z_known, count_letter)
        return MotionBlock(line, self.cycle, start, end, feed, pts, dirs, None, self.plane,
                           self.inch, [], number, known, given, {}, True, inc, False, self.f_word,
                           self.frame, info, start_known)

    def _cycle_move(self, values, axes_given):
        """A drilling cycle line passed through: X/Y go where it says (absolute) or stay unknown; the
        tool axis ends at the R plane or the start height: unknown."""
        scale = MM_PER_INCH if self.inch else 1.0
        self.cycle_line = True
        for c in axes_given:
            i = self.names.index(c)
            if c == TOOL_AXIS:
                continue
            v = math.radians(values[c]) if c in "ABC" else values[c] * scale
            if self.incremental:
                self.position[i] += v
            else:
                self.position[i] = v
                self.known[i] = True
        self._forget(self.tool_axis)

    def _home_move(self, g, values, axes_given, line):
        """G28/G30: named axes (all without any) go home; G53: named axes go to a machine position.
        Either way the program's frame no longer knows where they are."""
        new = self.position.copy()
        idx = [self.names.index(c) for c in axes_given]
        for i in idx:
            if g != 53:
                new[i] = self.home[i]
            self.known[i] = False
        if g != 53 and not axes_given:      # G28 / G30 alone: every axis goes home
            new = self.home.copy()
            self._forget()
        self.dirs = self._directions(self.position, new[None, :])[-1]
        self.position = new

    def _arc(self, start, end, values, line):
        plane = self.plane
        i0, i1, _ = PLANE_AXES[plane]
        if min(self.xyz_index) < 0:
            raise self._err("arc on a machine without X, Y and Z axes", line)
        a, b = self.xyz_index[i0], self.xyz_index[i1]
        scale = MM_PER_INCH if self.inch else 1.0
        ccw = self.motion == 3
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
                centre2 = s2 + scale * np.array([values.get(l0, 0.0), values.get(l1, 0.0)])
            pts = arc_chords(start, end, centre2, plane, ccw, self.chord_tol, self.xyz_index)
        except ArcError as exc:
            raise self._err(str(exc), line) from None
        centre = np.zeros(3)
        xyz = [start[i] for i in self.xyz_index]
        centre[:] = xyz
        centre[i0], centre[i1] = centre2
        return pts, centre

    def _directions(self, start: np.ndarray, pts: np.ndarray) -> np.ndarray:
        """(k, na) int8 approach directions at the end of each segment; updates self.dirs."""
        if pts.shape[0] == 1:                 # the common straight move, without array arithmetic
            cur = self.dirs
            for j, (a, b) in enumerate(zip(start.tolist(), pts[0].tolist())):
                step = b - a
                if step > DIR_EPS:
                    cur[j] = 1
                elif step < -DIR_EPS:
                    cur[j] = -1
            return cur[None, :].copy()
        prev = np.vstack([start[None, :], pts[:-1]])
        step = pts - prev
        sign = np.where(step > DIR_EPS, 1, np.where(step < -DIR_EPS, -1, 0)).astype(np.int8)
        out = np.empty_like(sign)
        cur = self.dirs.copy()
        for r in range(sign.shape[0]):
            moving = sign[r] != 0
            cur[moving] = sign[r][moving]
            out[r] = cur
        self.dirs = cur.copy()
        return out


# ---------------------------------------------------------------------------------- line reading
def _open_lines(path) -> Iterator[tuple[int, bytes, str]]:
    """(1-based line number, raw bytes with line ending, text without line ending, latin-1)."""
    p = os.fspath(path)
    try:
        f = open(p, "rb")
    except FileNotFoundError:
        raise InputError("no such file", p) from None
    except IsADirectoryError:
        raise InputError("is a folder, not a G-code file", p) from None
    except OSError as exc:
        raise InputError(f"cannot open: {exc.strerror}", p) from None
    with f:
        for k, raw in enumerate(f, 1):
            yield k, raw, raw.decode("latin-1").rstrip("\r\n")


def new_state(machine: Machine, path, chord_tol_mm=DEFAULT_CHORD_TOL_MM, initial_position=None,
              inch: bool = False, initial_known=None) -> ModalState:
    """The reader's state before the first line (see :class:`ModalState`)."""
    return ModalState(machine, path, chord_tol_mm, initial_position, inch, initial_known)


def iter_blocks(path, machine: Machine, chord_tol_mm: float = DEFAULT_CHORD_TOL_MM,
                initial_position=None, *, inch: bool = False, initial_known=None
                ) -> Iterator[tuple[int, bytes, MotionBlock | None, ModalState]]:
    """Every line of a program: (line number, raw bytes, its motion block or None, the state after it).

    The state is the same object throughout (it is the reader's modal state, updated in place).
    inch : the units before any G20/G21 (False: mm). initial_known : (na,) bool or bool, axes whose
    position is known before the first line (default: known if initial_position is given).
    """
    state = new_state(machine, path, chord_tol_mm, initial_position, inch, initial_known)
    for k, raw, text in _open_lines(path):
        yield k, raw, state.block(k, text), state


def read_program(path, machine: Machine, chord_tol_mm: float = DEFAULT_CHORD_TOL_MM,
                 initial_position=None, *, inch: bool = False, initial_known=None) -> Program:
    """All motion blocks of a program, in memory. Raises InputError naming file and line."""
    blocks = []
    n = 0
    for n, _raw, b, _state in iter_blocks(path, machine, chord_tol_mm, initial_position, inch=inch,
                                          initial_known=initial_known):
        if b is not None:
            blocks.append(b)
    return Program(os.fspath(path), machine.axis_names, blocks, n)


class _ChunkBuilder:
    """Collects segment rows and hands out SegmentChunks of at most ``size`` rows."""

    def __init__(self, na: int, size: int):
        self.na, self.size = na, int(size)
        if self.size < 1:
            raise ValueError("chunk_size must be >= 1")
        self._reset()

    def _reset(self):
        self.rows: list[tuple] = []   # (line, start, end, feed, dirs, rapid, arc, known, frame,
        #                                cycle, jump)
        self.n = 0

    def add(self, b: MotionBlock) -> Iterator[SegmentChunk]:
        k = b.points.shape[0]
        starts = b.segment_starts() if k > 1 else b.start[None, :]
        for r in range(k):
            self.rows.append((b.line, starts[r], b.points[r], b.feed, b.dirs[r], b.rapid, b.from_arc,
                              b.known, b.frame, b.cycle is not None, r == 0 and not b.start_known))
            self.n += 1
            if self.n == self.size:
                yield self.flush()

    def flush(self) -> SegmentChunk:
        if self.n == 0:
            return _empty_chunk(self.na)
        line, start, end, feed, dirs, rapid, arc, known, frame, cycle, jump = zip(*self.rows)
        c = SegmentChunk(np.array(line, np.int64), np.array(start, float).reshape(-1, self.na),
                         np.array(end, float).reshape(-1, self.na), np.array(feed, float),
                         np.array(dirs, np.int8).reshape(-1, self.na), np.array(rapid, bool),
                         np.array(arc, bool), np.array(known, bool).reshape(-1, self.na),
                         np.array(frame, np.int32), np.array(cycle, bool), np.array(jump, bool))
        self._reset()
        return c


def iter_segment_chunks(path, machine: Machine, chord_tol_mm: float = DEFAULT_CHORD_TOL_MM,
                        chunk_size: int = DEFAULT_CHUNK_SIZE,
                        initial_position=None, *, inch: bool = False,
                        initial_known=None) -> Iterator[SegmentChunk]:
    """Stream a program as :class:`SegmentChunk` objects of at most ``chunk_size`` rows.

    initial_position : (na,) axis positions before the first block, also where G28/G30 send the
    axes (mm, rad; default all zero). chord_tol_mm : largest sagitta of an arc's chords (mm).
    inch, initial_known : see :func:`iter_blocks`.
    Memory stays flat for any program length: one chunk (and one arc) is held at a time. A block
    split into many chords may continue in the next chunk. Raises InputError naming file and line
    (rows of earlier chunks have been yielded by then: consumers must not write output before the
    stream is exhausted, which :func:`write_corrected` guarantees through atomic_write).
    """
    from . import _fast
    kw = dict(inch=inch, initial_known=initial_known)
    if _fast.available():
        yield from _fast.iter_segment_chunks(path, machine, chord_tol_mm, chunk_size,
                                             initial_position, **kw)
        return
    builder = _ChunkBuilder(machine.n_axes, chunk_size)
    for _k, _raw, b, _state in iter_blocks(path, machine, chord_tol_mm, initial_position, **kw):
        if b is not None:
            yield from builder.add(b)
    if builder.n:
        yield builder.flush()


# ------------------------------------------------------------------------------------- writing
class OutputState:
    """What the written program has said so far (shared with the compiled writer).

    absolute : the output is in G90. motion : the motion word in force in the output (0, 1, 2, 3;
    -1 when not known: before the first, after a line that changed it in another way). values :
    (na,) float64, per axis the position last written (mm, rad, as read back from its text; nan:
    none yet). A coordinate is written when its text differs from that of the last value.
    """

    def __init__(self, na: int, state: ModalState | None = None):
        self.absolute = True        # the reader takes a program without G90/G91 as absolute too
        self.motion = -1
        self.cycle_lines = 0        # drilling cycle lines passed through (not corrected)
        self.cycle_blocks = 0       # drilling cycle lines kept as cycles (holes corrected where given)
        #: drilling cycles: the R and Z the output's cycle holds ('' : not known), and the Z where
        #: its current series began (mm; nan: not known)
        self.cycle_r = ""
        self.cycle_z = ""
        self.cycle_init_z = math.nan
        self.values = np.full(na, np.nan)
        self.rotary = [False] * na if state is None else state.rotary
        if state is not None:       # axes known before the first line stand where the reader says
            self.values[state.known] = state.position[state.known]

    def last(self, j: int, inch: bool) -> str:
        """The text of the last written position of axis j in the given units ('' if none)."""
        v = self.values[j]
        return "" if v != v else _format_value(v, self.rotary[j], inch)

    def set_last(self, j: int, text: str, inch: bool) -> None:
        v = float(text)
        self.values[j] = math.radians(v) if self.rotary[j] else v * (MM_PER_INCH if inch else 1.0)


def _format_value(v: float, rot: bool, inch: bool) -> str:
    if rot:
        s = f"{math.degrees(v):.4f}"
    elif inch:
        s = f"{v / MM_PER_INCH:.5f}"
    else:
        s = f"{v:.4f}"
    if s.startswith("-0.") and _NEG_ZERO_RE.fullmatch(s):
        s = s[1:]
    return s


def _piece_feeds(block: MotionBlock, points: np.ndarray, xyz: list[int]) -> np.ndarray:
    """G93: the F (1/min) of each of the k pieces a block is written as, so that the block keeps its
    time: F / (share of the piece in the block's path length; equal shares without motion in XYZ)."""
    prev = np.vstack([block.start[None, :], points[:-1]])
    seg = np.linalg.norm((points - prev)[:, xyz], axis=1) if xyz else np.zeros(len(points))
    total = float(seg.sum())
    share = seg / total if total > 0 else np.full(len(points), 1.0 / len(points))
    return share


def format_motion_lines(block: MotionBlock, points: np.ndarray, letters: str, rotary: list[bool],
                        out: OutputState, ending: str, separator: str = "\n",
                        source: str | None = None, chord_tol: float = DEFAULT_CHORD_TOL_MM) -> str:
    """The rewritten text of one motion line: ``points`` (m, na) become up to m lines G0/G1 (or one
    arc), absolute. Updates ``out``.

    Only the words a line needs are written: the N word, G90 when the output is not yet absolute,
    the motion word where the source line had one or the output's motion mode differs, the axes the
    source line named and any other axis whose written value changes (never an axis whose position
    the program has not given), then the kept words and comments in their original order (on the
    first line). A coordinate that keeps its source value keeps its source spelling, and a line
    that would be written with the very words of its source is written as the source (``source``:
    the line's text without its ending). A piece of a split block that changes no coordinate is left
    out. Under G93 each piece gets its own F. An arc whose correction is the same along it within
    ``ARC_KEEP_TOL_MM`` (or ``chord_tol``, mm, if smaller) stays one G2/G3 line (the arc shifted by
    its correction); otherwise it is written as its chords. ``ending`` is the line's own ending (kept, '' for a last line without
    one); ``separator`` goes between the lines of a split block.
    """
    if block.cycle is not None:
        return _cycle_text(block, points, letters, out, ending, separator, source)
    if block.from_arc:
        text = _arc_text(block, points, letters, rotary, out, source, min(chord_tol, ARC_KEEP_TOL_MM))
        if text is not None:
            return text + ending
    code = 0 if block.rapid else 1
    word = "G0" if code == 0 else "G1"
    k = points.shape[0]
    na = len(letters)
    out_lines = []
    g93 = block.inverse_time and k > 1
    if g93:
        share = _piece_feeds(block, points, [i for i, c in enumerate(letters) if c in "XYZ"])
        carried = 0.0
    verbatim = k == 1 and source is not None and out.absolute and not block.from_arc \
        and (block.motion_word or out.motion == code)
    for j in range(k):
        first = j == 0
        parts = []
        for i in range(na):
            if not block.known[i]:
                continue
            t = _format_value(points[j, i], rotary[i], block.inch)
            named = first and block.given[i]
            if named or t != out.last(i, block.inch):
                raw = block.raw.get(letters[i]) if (k == 1 and named) else None
                if raw is not None and t == _format_value(block.end[i], rotary[i], block.inch):
                    parts.append(raw)
                    t = raw[1:]         # the machine goes where the source spelling says
                else:
                    parts.append(letters[i] + t)
                    verbatim = False
                out.set_last(i, t, block.inch)
        if g93:
            carried += share[j]
        if not first and not parts:
            continue
        if verbatim and len(parts) == int(block.given.sum()):
            out.motion = code
            return source + ending
        head = []
        if first:
            if block.number:
                head.append(block.number)
            if not out.absolute:
                head.append("G90")
                out.absolute = True
        if (first and block.motion_word) or out.motion != code:
            head.append(word)
            out.motion = code
        tail = []
        if first:
            tail = [w for w in block.words if not (g93 and w[:1] in "Ff")]
        if g93:
            tail.append(f"F{block.f_word / carried:.6g}")
            carried = 0.0
        out_lines.append(" ".join(head + parts + tail))
    return (ending or separator).join(out_lines) + ending


def _cycle_text(block: MotionBlock, points: np.ndarray, letters: str, out: OutputState, ending: str,
                separator: str, source: str | None) -> str:
    """A drilling cycle line restated with corrected hole positions: points (k, na) are the
    corrected bottoms of its k holes. X, Y and Z take the corrected bottom; R moves with Z (the
    depth below the R plane is kept). The line keeps its words in their order, X Y Z R in their
    places; each is written when the source names it or the output's value differs (those the
    source does not name after its last one). An incremental line becomes absolute, one line per
    repeat (L dropped)."""
    info = block.cycle
    xi, yi, zi = (letters.index(c) for c in "XYZ")
    inch = block.inch
    scale = MM_PER_INCH if inch else 1.0
    if info.starting:
        out.cycle_init_z = out.values[zi]
    out.cycle_blocks += 1
    raw = {} if info.incremental else {t[0]: t[2] for t in info.tokens if t[0] in "XYZR"}
    nominal = {"X": block.points[0, xi], "Y": block.points[0, yi], "Z": info.z_bottom,
               "R": info.r_level}
    nominal = {c: _format_value(v, False, inch) for c, v in nominal.items()}
    lines = []
    for j in range(points.shape[0]):
        p = points[j]
        r = info.r_level + (p[zi] - block.points[j, zi])
        text = {c: _format_value(v, False, inch) for c, v in zip("XYZR", (p[xi], p[yi], p[zi], r))}
        current = {"X": out.last(xi, inch), "Y": out.last(yi, inch), "Z": out.cycle_z,
                   "R": out.cycle_r}
        named = info.named if j == 0 else frozenset("XY")
        need = [c for c in "XYZR" if c in named or text[c] != current[c]]
        # a coordinate that keeps its source value keeps its source spelling: the machine goes
        # where that spelling says
        spelled = {c: raw[c][1:] for c in need if c in raw and text[c] == nominal[c]}
        if j == 0 and points.shape[0] == 1 and source is not None and out.absolute \
                and not info.incremental and all(text[c] == nominal[c] for c in "XYZR") \
                and all(current[c] == nominal[c] for c in "XYZR" if c not in named):
            lines.append(source)
        else:
            words = [raw[c] if c in spelled else f"{c}{text[c]}" for c in need]
            head = []
            if j == 0:
                if block.number:
                    head.append(block.number)
                if not out.absolute:
                    head.append("G90")
                    out.absolute = True
                word_of = dict(zip(need, words))
                in_source = [t[0] for t in info.tokens if t[0] in "XYZR"]
                extra = [word_of[c] for c in need if c not in in_source]
                body = []
                for letter, num, rw in info.tokens:
                    if letter == "G" and float(num) in (90, 91):
                        continue
                    if letter == info.count_letter and info.incremental:
                        continue
                    if letter in "XYZR":
                        if letter in word_of:
                            body.append(word_of[letter])
                        in_source.remove(letter)
                        if not in_source:      # after the source's last X Y Z R: the others
                            body += extra
                            extra = []
                        continue
                    body.append(rw)
                body += extra
                lines.append(" ".join(head + body))
            else:
                lines.append(" ".join(words))
        out.set_last(xi, spelled.get("X", text["X"]), inch)
        out.set_last(yi, spelled.get("Y", text["Y"]), inch)
        out.cycle_z, out.cycle_r = (_format_value(float(spelled[c]) * scale, False, inch)
                                    if c in spelled else text[c] for c in "ZR")
    r_out = float(out.cycle_r) * scale
    init = out.cycle_init_z
    if info.retract == 99:
        out.values[zi] = r_out
    elif info.retract == 98 and info.z_after_known and init == init and r_out <= init + 1e-9:
        out.values[zi] = init
    else:
        out.values[zi] = math.nan
    out.motion = -1
    return (ending or separator).join(lines) + ending


def _arc_text(block, points, letters, rotary, out, source, chord_tol) -> str | None:
    """One G2/G3 line for an arc block whose corrections (points minus the chord ends) agree within
    chord_tol along the arc and with the correction of the written start; None otherwise."""
    k = points.shape[0]
    if k != block.points.shape[0] or block.centre is None or block.inverse_time:
        return None
    na = len(letters)
    scale = MM_PER_INCH if block.inch else 1.0
    start = np.empty(na)
    for i in range(na):
        if not block.known[i]:
            start[i] = block.start[i]
            continue
        start[i] = block.start[i] if np.isnan(out.values[i]) else out.values[i]
    d = points - block.points
    d_end = d[-1]
    lin = np.array([not r for r in rotary])
    known = np.asarray(block.known, bool)
    spread = np.abs(d - d_end)
    d_start = start - block.start
    if np.any(spread[:, lin & known] > chord_tol) or np.any(spread[:, ~lin & known] > 1e-9):
        return None
    # the written start is rounded to the output's resolution (and re-told after G20/G21)
    slack = chord_tol + (MM_PER_INCH * 1e-5 if block.inch else 1e-4)
    if np.any(np.abs(d_start - d_end)[lin & known] > slack) \
            or np.any(np.abs(d_start - d_end)[~lin & known] > math.radians(1e-4)):
        return None
    code = block.motion
    texts = [_format_value(points[-1, i], rotary[i], block.inch) for i in range(na)]
    # a full circle (end = start in the plane) must stay one, and an arc must not become one
    xyz = [letters.index(c) for c in "XYZ"]
    pa, pb = xyz[PLANE_AXES[block.plane][0]], xyz[PLANE_AXES[block.plane][1]]
    full = math.hypot(block.end[pa] - block.start[pa], block.end[pb] - block.start[pb]) \
        <= FULL_CIRCLE_TOL_MM
    if full:
        for i in (pa, pb):
            texts[i] = _format_value(start[i], False, block.inch)
            if abs(float(texts[i]) * scale - start[i]) > FULL_CIRCLE_TOL_MM:
                return None             # the start was written in a spelling this cannot repeat
    elif math.hypot(float(texts[pa]) * scale - start[pa], float(texts[pb]) * scale - start[pb]) \
            <= FULL_CIRCLE_TOL_MM:
        return None
    unchanged = all(texts[i] == _format_value(block.end[i], rotary[i], block.inch)
                    and (out.last(i, block.inch) or _format_value(block.start[i], rotary[i], block.inch))
                    == _format_value(block.start[i], rotary[i], block.inch)
                    for i in range(na) if known[i])
    if unchanged and source is not None and out.absolute and not block.incremental \
            and (block.motion_word or out.motion == code):
        out.values[known] = block.end[known]     # where the source's own spelling goes
        out.motion = code
        return source
    head = []
    if block.number:
        head.append(block.number)
    if not out.absolute:
        head.append("G90")
        out.absolute = True
    if block.motion_word or out.motion != code:
        head.append(f"G{code}")
        out.motion = code
    i0, i1, _ = PLANE_AXES[block.plane]
    plane_cols = (pa, pb)
    parts = []
    for i in range(na):
        if not known[i]:
            continue
        if i in plane_cols or block.given[i] or texts[i] != out.last(i, block.inch):
            parts.append(letters[i] + texts[i])
            out.set_last(i, texts[i], block.inch)
    centre = np.asarray(block.centre) + d_end[xyz]
    offsets = {}
    for axis_i, letter in zip((i0, i1), PLANE_OFFSET_LETTERS[block.plane]):
        col = xyz[axis_i]
        offsets[letter] = (centre[axis_i] - start[col]) / scale
    fmt = "{:.5f}" if block.inch else "{:.4f}"
    for letter in sorted(offsets):
        t = fmt.format(offsets[letter])
        if _NEG_ZERO_RE.fullmatch(t):
            t = t[1:]
        parts.append(letter + t)
    return " ".join(head + parts + block.words)


def _line_ending(raw: bytes) -> str:
    if raw.endswith(b"\r\n"):
        return "\r\n"
    if raw.endswith(b"\n"):
        return "\n"
    return ""


def write_pass_through(f, raw: bytes, state: ModalState, out: OutputState, separator: str) -> None:
    """Write a non-motion line as it is; updates ``out``.

    The output is absolute while the input may be incremental (a G91 on a motion line is dropped).
    A G28/G30 whose axis words rely on that G91 gets a line ``G91`` inserted before it.
    """
    if state.distance_sensitive and state.distance_word is None and state.incremental \
            and out.absolute:
        f.write(("G91" + (_line_ending(raw) or separator)).encode("latin-1"))
        out.absolute = False
    f.write(raw)
    if state.distance_word == 91:
        out.absolute = False
    elif state.distance_word == 90:
        out.absolute = True
    if state.had_g:
        out.motion = state.motion if state.motion in (0, 1) and state.cycle is None else -1
    if state.cycle_line:
        out.cycle_lines += 1
        xi, yi, zi = state.xyz_index
        if state.cycle_start:
            out.cycle_init_z = out.values[zi]
        for i in (xi, yi):
            out.values[i] = state.position[i] if state.known[i] else math.nan
        out.values[zi] = math.nan
        for attr in ("cycle_r", "cycle_z"):
            v = getattr(state, attr)
            setattr(out, attr, "" if v is None or v[1] else _format_value(v[0], False, state.inch))


def _uncorrected(path, machine, chord_tol_mm, chunk_size, initial_position, **kw):
    for chunk in iter_segment_chunks(path, machine, chord_tol_mm, chunk_size, initial_position, **kw):
        yield chunk, chunk.end, np.ones(len(chunk), np.int64)


class CorrectionCursor:
    """Walks the ``(chunk, points, counts)`` stream of :func:`write_corrected` row by row.

    line (n,) int64, offsets (n+1,) int64 and points (M, na) float64 of the current chunk are
    contiguous arrays (the compiled writer reads them directly); ``row`` is the next row to write.
    """

    def __init__(self, corrections, n_axes: int, in_path):
        self._it = iter(corrections)
        self.na = n_axes
        self.in_path = in_path
        self.line = np.zeros(0, np.int64)
        self.offsets = np.zeros(1, np.int64)
        self.points = np.zeros((0, n_axes))
        self.row = 0
        self.n = 0

    def advance(self, line_no: int) -> None:
        """Load the next chunk (the current one is used up)."""
        try:
            chunk, points, counts = next(self._it)
        except StopIteration:
            raise ValueError(f"corrections ended before line {line_no} of {self.in_path}") from None
        counts = np.asarray(counts, dtype=np.int64).reshape(-1)
        if counts.shape[0] != len(chunk) or np.any(counts < 1):
            raise ValueError("counts must have one entry >= 1 per segment row")
        offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        points = np.ascontiguousarray(points, dtype=np.float64)
        if points.shape != (offsets[-1], self.na):
            raise ValueError(f"points must be ({offsets[-1]}, {self.na}), got {points.shape}")
        if not np.all(np.isfinite(points)):
            bad = int(np.searchsorted(offsets, np.argmax(~np.isfinite(points).all(axis=1)), "right")) - 1
            raise ValueError(f"corrections hold a non-finite point for line {int(chunk.line[bad])}")
        self.line = np.ascontiguousarray(chunk.line, dtype=np.int64)
        self.offsets, self.points, self.row, self.n = offsets, points, 0, len(chunk)

    def take(self, line_no: int, k: int) -> np.ndarray:
        """The corrected points of the next k segment rows, which must belong to line_no."""
        parts = []
        while k > 0:
            if self.row >= self.n:
                self.advance(line_no)
                continue
            r = self.row
            take = min(k, self.n - r)
            if np.any(self.line[r:r + take] != line_no):
                self.mismatch(line_no)
            parts.append(self.points[self.offsets[r]:self.offsets[r + take]])
            self.row = r + take
            k -= take
        return parts[0] if len(parts) == 1 else np.vstack(parts)

    def mismatch(self, line_no: int):
        raise ValueError(f"corrections do not match the program at line {line_no}: the segment row "
                         f"says line {int(self.line[self.row])}")

    def finish(self) -> None:
        if self.row < self.n:
            raise ValueError("corrections have more segment rows than the program")
        for extra in self._it:
            if len(extra[0]):
                raise ValueError("corrections have more segment rows than the program")


def write_corrected(in_path, out_path, machine: Machine,
                    corrections: Iterable[tuple[SegmentChunk, np.ndarray, np.ndarray]] | None,
                    chord_tol_mm: float = DEFAULT_CHORD_TOL_MM, initial_position=None, *,
                    inch: bool = False, initial_known=None, stats: dict | None = None) -> int:
    """Write ``in_path`` to ``out_path`` with corrected motion lines; returns the number of segment
    rows written.

    corrections : iterator of ``(chunk, points, counts)`` per SegmentChunk of
        :func:`iter_segment_chunks` (same order): points (M, na) corrected axis positions (mm, rad)
        to emit as G0/G1 moves, counts (n,) int >= 1: how many of ``points`` belong to each segment
        row, the last being the segment's corrected end. None writes the nominal program (arcs as
        chords): the round trip.
    Every line that is not a motion line is written byte for byte and in place. Motion lines carry
    only the words they need (see :func:`format_motion_lines`); an axis whose position the program
    has not given is never written. Output is absolute (G90), in the units of the input at that
    line, 4 decimals for mm and deg, 5 for inch. The file is written atomically: nothing is left on
    failure and the input is never overwritten. inch, initial_known : see :func:`iter_blocks`.
    stats : a dict that receives ``cycle_lines``, the drilling cycle lines passed through unchanged
    (their positions are not corrected), and ``cycle_blocks``, those kept as cycles (with the corrections given),
    or None.
    Raises InputError for a bad program or output path, ValueError for corrections that do not
    match the program's segment rows (or hold a non-finite point).
    """
    check_output_path(out_path, [in_path])
    kw = dict(inch=inch, initial_known=initial_known)
    if corrections is None:
        corrections = _uncorrected(in_path, machine, chord_tol_mm, DEFAULT_CHUNK_SIZE,
                                   initial_position, **kw)
    cursor = CorrectionCursor(corrections, machine.n_axes, in_path)
    from . import _fast
    if _fast.available():
        return _fast.write_corrected(in_path, out_path, machine, cursor, chord_tol_mm,
                                     initial_position, stats=stats, **kw)
    letters = "".join(machine.axis_names)
    rotary = [c in "ABC" for c in letters]
    rows_written = 0
    out = None
    separator = "\n"
    with atomic_write(out_path, "wb") as f:
        for k, raw, block, state in iter_blocks(in_path, machine, chord_tol_mm, initial_position,
                                                **kw):
            if out is None:
                out = OutputState(machine.n_axes, new_state(machine, in_path, chord_tol_mm,
                                                            initial_position, **kw))
            if block is None:
                write_pass_through(f, raw, state, out, separator)
                continue
            pts = cursor.take(k, block.points.shape[0])
            ending = _line_ending(raw)
            separator = ending or separator
            text = format_motion_lines(block, pts, letters, rotary, out, ending, separator,
                                       raw.decode("latin-1").rstrip("\r\n"), chord_tol_mm)
            rows_written += block.points.shape[0]
            f.write(text.encode("latin-1"))
        cursor.finish()
    if stats is not None:
        stats["cycle_lines"] = 0 if out is None else out.cycle_lines
        stats["cycle_blocks"] = 0 if out is None else out.cycle_blocks
    return rows_written

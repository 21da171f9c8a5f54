"""G-code (ISO 6983 / RS-274 subset of SPEC section 4): reader, segment stream and writer.

Layers (after pygcode): a line is cut into *tokens* (words ``X-1.5`` and comments), the tokens of a
line form a *block*, and :class:`ModalState` -- the one place that holds the machine's modal state
(motion mode, plane, units, distance mode, feed, position, approach directions) -- turns each block
into motion or leaves it as a pass-through line.

Units: the file holds mm or inch (G21/G20) and deg for A, B, C; everything returned is mm, rad and
mm/min. Positions are axis positions in ``machine.axis_names`` order (tool-tip positions, SPEC 2).

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
from ._arcs import PLANE_AXES, PLANE_OFFSET_LETTERS, ArcError, arc_chords, centre_from_radius

MM_PER_INCH = 25.4
#: an axis moving less than this (mm or rad) in a segment keeps its previous approach direction
DIR_EPS = 1e-9
DEFAULT_CHORD_TOL_MM = 1e-3
DEFAULT_CHUNK_SIZE = 65536

_NUM = r"[+-]?(?:\d+\.?\d*|\.\d+)"
_TOKEN_RE = re.compile(r"[ \t]+|\([^()]*\)|;.*|([A-Za-z])(" + _NUM + r")|(.)", re.S)
_AXIS_LETTERS = "XYZABC"
_UNIQUE_LETTERS = frozenset("XYZABCIJKRFNUVW")
#: G codes that would change geometry in a way mtcomp does not follow: refused, never guessed
_REFUSED_G = {
    10: "G10 (programmable data input)", 52: "G52 (local coordinate system)",
    92: "G92 (coordinate system offset)", 68: "G68 (coordinate rotation)", 51: "G51 (scaling)",
    93: "G93 (inverse time feed)", 95: "G95 (feed per revolution)",
    73: "canned cycle G73", 74: "canned cycle G74", 76: "canned cycle G76",
    81: "canned cycle G81", 82: "canned cycle G82", 83: "canned cycle G83", 84: "canned cycle G84",
    85: "canned cycle G85", 86: "canned cycle G86", 87: "canned cycle G87", 88: "canned cycle G88",
    89: "canned cycle G89", 90.1: "G90.1 (absolute arc centres)",
}
_NEG_ZERO_RE = re.compile(r"-(0\.0+)(?![0-9])")


@dataclass
class SegmentChunk:
    """Straight segments in program order (arcs already split into chords); n rows, na axes.

    line : (n,) int, 1-based source line of the block the segment comes from.
    start, end : (n, na) float, axis positions in ``machine.axis_names`` order, mm and rad.
    feed : (n,) float, mm/min (inch programs converted); nan for rapids and before any F word.
    dirs : (n, na) int8, +1/-1 approach direction of each axis at the end of the segment: the sign
        of its last motion, carried over while it does not move (+1 before its first motion).
    rapid : (n,) bool, G0. from_arc : (n,) bool, a chord of a G2/G3 block.
    """

    line: np.ndarray
    start: np.ndarray
    end: np.ndarray
    feed: np.ndarray
    dirs: np.ndarray
    rapid: np.ndarray
    from_arc: np.ndarray

    def __len__(self) -> int:
        return int(self.line.shape[0])

    @staticmethod
    def concatenate(chunks: list["SegmentChunk"], n_axes: int) -> "SegmentChunk":
        if not chunks:
            return _empty_chunk(n_axes)
        return SegmentChunk(*(np.concatenate([getattr(c, f) for c in chunks])
                              for f in ("line", "start", "end", "feed", "dirs", "rapid", "from_arc")))


def _empty_chunk(na: int) -> SegmentChunk:
    return SegmentChunk(np.zeros(0, np.int64), np.zeros((0, na)), np.zeros((0, na)), np.zeros(0),
                        np.zeros((0, na), np.int8), np.zeros(0, bool), np.zeros(0, bool))


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
                        np.full(k, b.feed), b.dirs.copy(), np.full(k, b.rapid), np.full(k, b.from_arc))


# --------------------------------------------------------------------------------------- tokens
def tokenize(text: str, path=None, line: int | None = None) -> list[tuple[str, str, str]]:
    """Cut one line (without its line ending) into tokens ``(letter, number, raw)``.

    letter is the upper-case word letter, or '(' / ';' for a comment (number '' then). Raises
    InputError for anything that is not a word, a comment or blank.
    """
    out = []
    pos, n = 0, len(text)
    while pos < n:
        m = _TOKEN_RE.match(text, pos)
        raw = m.group(0)
        if m.group(3) is not None:
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
    dirs : (na,) int8 approach directions. home : (na,) where G28/G30 send the named axes.
    """

    def __init__(self, machine: Machine, path=None, chord_tol: float = DEFAULT_CHORD_TOL_MM,
                 initial_position: np.ndarray | None = None):
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
        self.dirs = np.ones(self.na, np.int8)
        self.motion: int | None = None
        self.plane = 17
        self.inch = False
        self.incremental = False
        self.feed = math.nan
        self.xyz_index = tuple(machine.index(c) if c in self.names else -1 for c in "XYZ")
        #: 90 / 91 if the last block interpreted carried G90 / G91, else None
        self.distance_word: int | None = None
        #: the last block was a G28/G30 with axis words (read in the distance mode in force)
        self.distance_sensitive = False

    def _err(self, msg, line):
        return InputError(msg, self.path, line)

    def block(self, line: int, text: str) -> MotionBlock | None:
        """Interpret one line (text without line ending). Returns its motion, or None."""
        self.distance_word = None
        self.distance_sensitive = False
        s = text.lstrip(" \t")
        if not s or s[0] == "%":
            return None
        if s[0] == "/":
            raise self._err("block delete '/' is not supported", line)
        tokens = tokenize(text, self.path, line)
        if not tokens:
            return None
        values: dict[str, float] = {}
        gcodes: list[float] = []
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
            if letter in _UNIQUE_LETTERS:
                if letter in values:
                    raise self._err(f"word {letter} appears twice", line)
                values[letter] = v
                if letter == "N":
                    number = raw
        motion = None
        nonmotion_axes = False     # G4 dwell (X/P is time), G28/G30/G53: axis words are no motion
        home_move = None
        for g in gcodes:
            gi = round(g)
            if g != gi:
                if g in _REFUSED_G:
                    raise self._err(f"{_REFUSED_G[g]} is not supported", line)
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
            elif gi == 4:
                nonmotion_axes = True
            elif gi in (28, 30, 53):
                nonmotion_axes = True
                home_move = gi
            elif gi == 80:
                self.motion = None
            elif gi in _REFUSED_G:
                raise self._err(f"{_REFUSED_G[gi]} is not supported", line)
        for letter in "UVW":
            if letter in values:
                raise self._err(f"axis word {letter}: machine {self.machine.name} has no {letter} axis",
                                line)
        axes_given = [c for c in _AXIS_LETTERS if c in values]
        if home_move is not None and motion is not None:
            raise self._err(f"G{home_move} and motion G{motion} in one block", line)
        if nonmotion_axes:
            self.distance_sensitive = home_move in (28, 30) and bool(axes_given)
            if home_move is not None:
                self._home_move(home_move, values, axes_given, line)
            return None
        for c in axes_given:
            if c not in self.names:
                raise self._err(f"axis word {c}: machine {self.machine.name} has no {c} axis "
                                f"(axes: {' '.join(self.names)})", line)
        if "F" in values:
            f = values["F"] * (MM_PER_INCH if self.inch else 1.0)
            if not f > 0:
                raise self._err(f"feed F must be positive, got {values['F']:g}", line)
            self.feed = f
        if motion is not None:
            self.motion = motion
        arc_words = [c for c in "IJKR" if c in values]
        is_motion = bool(axes_given) or (self.motion in (2, 3) and bool(arc_words))
        if not is_motion:
            if arc_words:
                raise self._err(f"{arc_words[0]} word outside an arc block", line)
            return None
        if self.motion is None:
            raise self._err("coordinates without a motion mode (no G0/G1/G2/G3 in force)", line)
        if self.motion in (0, 1) and arc_words:
            raise self._err(f"{arc_words[0]} word in a G{self.motion} block (only G2/G3 take I J K R)",
                            line)
        start = self.position.copy()
        end = start.copy()
        scale = MM_PER_INCH if self.inch else 1.0
        for c in axes_given:
            i = self.names.index(c)
            v = math.radians(values[c]) if c in "ABC" else values[c] * scale
            end[i] = start[i] + v if self.incremental else v
        centre = None
        if self.motion in (2, 3):
            pts, centre = self._arc(start, end, values, line)
        else:
            pts = end[None, :]
        dirs = self._directions(start, pts)
        feed = math.nan if self.motion == 0 else self.feed
        self.position = end
        words = [raw for letter, num, raw in tokens
                 if not (letter == "N" or letter in _AXIS_LETTERS or letter in "IJKR"
                         or (letter == "G" and float(num) in (0, 1, 2, 3, 90, 91)))]
        return MotionBlock(line, self.motion, start, end, feed, pts, dirs, centre, self.plane,
                           self.inch, words, number)

    def _home_move(self, g, values, axes_given, line):
        """G28/G30: named axes go home; G53: named axes go to the value (no work offset modelled)."""
        scale = MM_PER_INCH if self.inch else 1.0
        new = self.position.copy()
        for c in axes_given:
            if c not in self.names:
                raise self._err(f"axis word {c}: machine {self.machine.name} has no {c} axis", line)
            i = self.names.index(c)
            if g == 53:
                new[i] = math.radians(values[c]) if c in "ABC" else values[c] * scale
            else:
                new[i] = self.home[i]
        if g != 53 and not axes_given:      # G28 / G30 alone: every axis goes home
            new = self.home.copy()
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
                bad = [c for c in other if c in values]
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


def iter_blocks(path, machine: Machine, chord_tol_mm: float = DEFAULT_CHORD_TOL_MM,
                initial_position=None) -> Iterator[tuple[int, bytes, MotionBlock | None, ModalState]]:
    """Every line of a program: (line number, raw bytes, its motion block or None, the state after it).

    The state is the same object throughout (it is the reader's modal state, updated in place).
    """
    state = ModalState(machine, path, chord_tol_mm, initial_position)
    for k, raw, text in _open_lines(path):
        yield k, raw, state.block(k, text), state


def read_program(path, machine: Machine, chord_tol_mm: float = DEFAULT_CHORD_TOL_MM,
                 initial_position=None) -> Program:
    """All motion blocks of a program, in memory. Raises InputError naming file and line."""
    blocks = []
    n = 0
    for n, _raw, b, _state in iter_blocks(path, machine, chord_tol_mm, initial_position):
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
        self.rows: list[tuple] = []          # (line, start, end, feed, dirs, rapid, arc) per row
        self.n = 0

    def add(self, b: MotionBlock) -> Iterator[SegmentChunk]:
        k = b.points.shape[0]
        if k == 1 and self.n < self.size:
            self.rows.append((b.line, b.start, b.points[0], b.feed, b.dirs[0], b.rapid, b.from_arc))
            self.n += 1
            if self.n == self.size:
                yield self.flush()
            return
        starts = b.segment_starts()
        for r in range(k):
            self.rows.append((b.line, starts[r], b.points[r], b.feed, b.dirs[r], b.rapid, b.from_arc))
            self.n += 1
            if self.n == self.size:
                yield self.flush()

    def flush(self) -> SegmentChunk:
        if self.n == 0:
            return _empty_chunk(self.na)
        line, start, end, feed, dirs, rapid, arc = zip(*self.rows)
        c = SegmentChunk(np.array(line, np.int64), np.array(start, float).reshape(-1, self.na),
                         np.array(end, float).reshape(-1, self.na), np.array(feed, float),
                         np.array(dirs, np.int8).reshape(-1, self.na), np.array(rapid, bool),
                         np.array(arc, bool))
        self._reset()
        return c


def iter_segment_chunks(path, machine: Machine, chord_tol_mm: float = DEFAULT_CHORD_TOL_MM,
                        chunk_size: int = DEFAULT_CHUNK_SIZE,
                        initial_position=None) -> Iterator[SegmentChunk]:
    """Stream a program as :class:`SegmentChunk` objects of at most ``chunk_size`` rows.

    initial_position : (na,) axis positions before the first block, also where G28/G30 send the
    axes (mm, rad; default all zero). chord_tol_mm : largest sagitta of an arc's chords (mm).
    Memory stays flat for any program length: one chunk (and one arc) is held at a time. A block
    split into many chords may continue in the next chunk. Raises InputError naming file and line
    (rows of earlier chunks have been yielded by then: consumers must not write output before the
    stream is exhausted, which :func:`write_corrected` guarantees through atomic_write).
    """
    from . import _fast
    if _fast.available():
        yield from _fast.iter_segment_chunks(path, machine, chord_tol_mm, chunk_size,
                                             initial_position)
        return
    builder = _ChunkBuilder(machine.n_axes, chunk_size)
    for _k, _raw, b, _state in iter_blocks(path, machine, chord_tol_mm, initial_position):
        if b is not None:
            yield from builder.add(b)
    if builder.n:
        yield builder.flush()


# ------------------------------------------------------------------------------------- writing
def _format_point(values: np.ndarray, letters: str, rotary: list[bool], inch: bool) -> str:
    parts = []
    for c, rot, v in zip(letters, rotary, values):
        if rot:
            parts.append(f"{c}{math.degrees(v):.4f}")
        elif inch:
            parts.append(f"{c}{v / MM_PER_INCH:.5f}")
        else:
            parts.append(f"{c}{v:.4f}")
    s = " ".join(parts)
    if "-0.0" in s:
        s = _NEG_ZERO_RE.sub(r"\1", s)
    return s


def format_motion_lines(block: MotionBlock, points: np.ndarray, letters: str, rotary: list[bool],
                        need_g90: bool, ending: str, separator: str = "\n") -> str:
    """The rewritten text of one motion line: ``points`` (m, na) become m lines G0/G1, absolute.

    The first line carries the N word, a G90 when the output is not yet absolute, the motion word,
    every axis, then the kept words and comments in their original order; the others only G0/G1
    and the axes. ``ending`` is the line's own ending (kept, '' for a last line without one);
    ``separator`` goes between the lines of a split block.
    """
    word = "G0" if block.rapid else "G1"
    out = []
    for j in range(points.shape[0]):
        coords = _format_point(points[j], letters, rotary, block.inch)
        if j == 0:
            head = [block.number] if block.number else []
            if need_g90:
                head.append("G90")
            head.append(word)
            head.append(coords)
            head.extend(block.words)
            out.append(" ".join(head))
        else:
            out.append(f"{word} {coords}")
    return (ending or separator).join(out) + ending


def _line_ending(raw: bytes) -> str:
    if raw.endswith(b"\r\n"):
        return "\r\n"
    if raw.endswith(b"\n"):
        return "\n"
    return ""


def write_pass_through(f, raw: bytes, state: ModalState, out_absolute: bool, separator: str) -> bool:
    """Write a non-motion line as it is; returns whether the output is absolute after it.

    The output is absolute while the input may be incremental (a G91 on a motion line is dropped).
    A G28/G30 whose axis words rely on that G91 gets a line ``G91`` inserted before it.
    """
    if state.distance_sensitive and state.distance_word is None and state.incremental \
            and out_absolute:
        f.write(("G91" + (_line_ending(raw) or separator)).encode("latin-1"))
        out_absolute = False
    f.write(raw)
    if state.distance_word == 91:
        return False
    if state.distance_word == 90:
        return True
    return out_absolute


def _uncorrected(path, machine, chord_tol_mm, chunk_size, initial_position):
    for chunk in iter_segment_chunks(path, machine, chord_tol_mm, chunk_size, initial_position):
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
                    chord_tol_mm: float = DEFAULT_CHORD_TOL_MM, initial_position=None) -> int:
    """Write ``in_path`` to ``out_path`` with corrected motion lines; returns the number of segment
    rows written.

    corrections : iterator of ``(chunk, points, counts)`` per SegmentChunk of
        :func:`iter_segment_chunks` (same order): points (M, na) corrected axis positions (mm, rad)
        to emit as G0/G1 moves, counts (n,) int >= 1: how many of ``points`` belong to each segment
        row, the last being the segment's corrected end. None writes the nominal program (arcs as
        chords): the round trip.
    Every line that is not a motion line is written byte for byte and in place. Output is absolute
    (G90), in the units of the input at that line, 4 decimals for mm and deg, 5 for inch. The file
    is written atomically: nothing is left on failure and the input is never overwritten.
    Raises InputError for a bad program or output path, ValueError for corrections that do not
    match the program's segment rows (or hold a non-finite point).
    """
    check_output_path(out_path, [in_path])
    if corrections is None:
        corrections = _uncorrected(in_path, machine, chord_tol_mm, DEFAULT_CHUNK_SIZE,
                                   initial_position)
    cursor = CorrectionCursor(corrections, machine.n_axes, in_path)
    from . import _fast
    if _fast.available():
        return _fast.write_corrected(in_path, out_path, machine, cursor, chord_tol_mm,
                                     initial_position)
    letters = "".join(machine.axis_names)
    rotary = [c in "ABC" for c in letters]
    rows_written = 0
    out_absolute = False
    separator = "\n"
    with atomic_write(out_path, "wb") as f:
        for k, raw, block, state in iter_blocks(in_path, machine, chord_tol_mm, initial_position):
            if block is None:
                out_absolute = write_pass_through(f, raw, state, out_absolute, separator)
                continue
            pts = cursor.take(k, block.points.shape[0])
            ending = _line_ending(raw)
            separator = ending or separator
            text = format_motion_lines(block, pts, letters, rotary, not out_absolute, ending,
                                       separator)
            out_absolute = True
            rows_written += block.points.shape[0]
            f.write(text.encode("latin-1"))
        cursor.finish()
    return rows_written

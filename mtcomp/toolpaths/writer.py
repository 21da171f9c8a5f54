"""Writing a G-code program back with corrected coordinates: the writer's layer.

:class:`OutputState` keeps what the written program has said so far (distance mode, motion mode,
the last value written per axis); :func:`format_motion_lines` writes one motion line with its
corrected points (G0/G1 pieces, one shifted G2/G3 arc, or a restated drilling cycle), and
:func:`write_pass_through` copies every other line byte for byte. :class:`CorrectionCursor` walks
the corrections the planner hands over, row by row, and :func:`write_corrected` here is the
pure-Python writer (the public :func:`mtcomp.toolpaths.gcode.write_corrected` prepares the cursor
and runs the compiled writer when it can, with the same bytes).

Output: absolute (G90), in the units of the input at each line, 4 decimals for mm and deg, 5 for
inch; see docs/toolpaths.md for what is rewritten and what passes through.
"""
from __future__ import annotations

import math

import numpy as np

from ..io.atomic import atomic_write
from ..machine import Machine
from ._arcs import FULL_CIRCLE_TOL_MM, PLANE_AXES, PLANE_OFFSET_LETTERS
from .blocks import MotionBlock
from .modal import ModalState
from .reader import iter_blocks, new_state
from .words import _NEG_ZERO_RE, ARC_KEEP_TOL_MM, DEFAULT_CHORD_TOL_MM, MM_PER_INCH


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
    its correction); otherwise it is written as its chords. ``ending`` is the line's own ending
    (kept, '' for a last line without one); ``separator`` goes between the lines of a split block.
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


def _arc_shift(block, points, rotary, out, chord_tol):
    """(written start (na,), correction d_end (na,)) when the arc block's corrections (points minus
    the chord ends) agree within chord_tol along the arc and with the correction of the written
    start, so that the corrected arc is the arc shifted by d_end; None otherwise."""
    na = len(rotary)
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
    return start, d_end


def _arc_text(block, points, letters, rotary, out, source, chord_tol) -> str | None:
    """One G2/G3 line for an arc block whose corrections agree along it (:func:`_arc_shift`);
    None otherwise."""
    k = points.shape[0]
    if k != block.points.shape[0] or block.centre is None or block.inverse_time:
        return None
    shift = _arc_shift(block, points, rotary, out, chord_tol)
    if shift is None:
        return None
    start, d_end = shift
    na = len(letters)
    scale = MM_PER_INCH if block.inch else 1.0
    known = np.asarray(block.known, bool)
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


class CorrectionCursor:
    """Walks the ``(chunk, points, counts)`` stream of corrections row by row (see
    :func:`mtcomp.toolpaths.gcode.write_corrected`).

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


def write_corrected(in_path, out_path, machine: Machine, cursor: CorrectionCursor,
                    chord_tol_mm: float = DEFAULT_CHORD_TOL_MM, initial_position=None, *,
                    inch: bool = False, initial_known=None, stats: dict | None = None) -> int:
    """Pure-Python path of :func:`mtcomp.toolpaths.gcode.write_corrected`, which checks the output
    path and prepares the cursor over the corrections; returns the number of segment rows written."""
    kw = dict(inch=inch, initial_known=initial_known)
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

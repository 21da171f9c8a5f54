"""A Heidenhain conversational program written back with corrected coordinates.

The program is read through its G-code equivalent (:mod:`.heidenhain`), planned as any program,
and written here in its own form: every line is the source line, byte for byte, except the
numbers that carry a correction. In an ``L`` block the axis words are replaced in place (an
incremental ``IX`` word gets the corrected end less the corrected start), an axis the block does
not name is added after its last axis word where its written value changes (never an axis whose
position the program has not given); a drilling call (``L ... M99``, ``CYCL CALL``) gets the hole's
corrected X Y and its start level moved by the correction at the bottom (the cycle's depth below
it is kept, as G-code cycles keep the depth below R). An arc ``C`` gets its corrected end point
and its circle centre ``CC`` is moved: one centre for the arcs that use it, taken as the nominal
centre shifted by the mean correction at their ends (or, for one arc, the circle through its
corrected ends closest to its corrected path), kept only when every one of those arcs lies within
the chord tolerance of its corrected path; an arc no one centre holds is written in pieces, a CC
and a C block for each after the first, the blocks after them renumbered
(:mod:`.heidenhain_pieces`), and a full circle that none holds is refused (one line naming it).
Under radius compensation (RL/RR, read as G41/G42) the planner gives all of an arc's nodes one
correction, a translation, so the arc's moved centre carries it exactly and the C stays whole.
Numbers are written in Heidenhain's signed form (``X+107.5032``), with at least the source word's
decimals and at least 4 in mm and degrees, 5 in inch. Internal nodes of the planner are not
written (compensate plans such programs without them): only an arc is cut, at its corrected
points.
"""
from __future__ import annotations

import math
import re

import numpy as np

from ..errors import InputError
from ..io.atomic import atomic_write
from ._arcs import arc_misses, arc_samples, arc_sweep, fit_arc_centre, radius_refused
from .heidenhain import CR_RADIUS, WORD, read_lines, signed
from .heidenhain_pieces import ROTARY_ARC_TOL_RAD, ArcPieces, renumbered
from .reader import iter_blocks
from .sinumerik_paths import RadiusError, radius_centre, signed_radius
from .words import MM_PER_INCH, number_decimals



#: the end of a motion block's keyword, after its block number
_KEY_END = re.compile(r"^\s*\d+\s*(?:L|C)(?![A-Z])")
#: a block's number and the blanks after it
_KEY_START = re.compile(r"^\s*\d+\s*")


def _code_end(text: str) -> int:
    """Where a line's comment starts (its length when it has none)."""
    pos = text.find(";")
    return len(text) if pos < 0 else pos


class _Arc:
    """One C block as written: its line, written start and end (na,), the samples of its
    corrected path (m, na), its nominal start and end, centre (2,), direction, full circle; the
    samples' nominal places (m, na) and swept fractions (m,) (None where not known)."""

    def __init__(self, line, start_w, end_w, samples, block, centre2, full, nominal=None, u=None):
        self.line, self.start_w, self.end_w, self.samples = line, start_w, end_w, samples
        self.block, self.centre2, self.full = block, centre2, full
        self.nominal, self.u = nominal, u
        self.ccw = block.motion == 3


class HeidenhainWriter:
    """Writes one conversational program (see the module docstring)."""

    #: how a refused arc is named: the arc, its centre, what would let it through
    ARC, CENTRE, HINT = "arc C", "CC", "a larger --chord-tol-um"
    #: an arc that no one centre holds is written in pieces (:mod:`.heidenhain_pieces`)
    SPLITS = True
    #: the words of a circle centre, and the letters of its X and Y
    CENTRE_WORD, CENTRE_LETTERS = WORD, "XY"

    def __init__(self, src, machine, chord_tol_mm: float, translation=None):
        self.src = src
        self.tr = src.heidenhain if translation is None else translation
        self.letters = "".join(machine.axis_names)
        self.rotary = [c in "ABC" for c in self.letters]
        self.linear = np.array([not r for r in self.rotary])
        self.na = machine.n_axes
        self.tol = chord_tol_mm
        #: the largest distance of a written arc from its corrected path (mm)
        self.arc_miss = 0.0
        self.scale = MM_PER_INCH if self.tr.inch else 1.0
        self.base = 5 if self.tr.inch else 4
        self.raws = read_lines(src.source)
        self.texts = [r.decode("latin-1") for r in self.raws]
        self.written = np.full(self.na, np.nan)       # the G-code frame: mm, rad
        self.arcs: dict[int, list] = {}
        self.holes = 0
        self.dropped = 0
        #: blocks put in before / after a source line (texts without their block numbers), the
        #: arcs written in pieces and the blocks added for them
        self.before: dict[int, list] = {}
        self.after: dict[int, list] = {}
        self.split_arcs = self.added_blocks = 0
        #: lines written with axis words they did not name, and the first of them (1-based, a line
        #: of the program read: its G-code equivalent, line for line here), the lines counted
        self.added_lines, self.added_line, self._counted = 0, 0, set()
        #: the line of the program read (1-based) of the block being written
        self.line_read = 0
        self.cols = [self.letters.index(c) for c in "XY"]

    # ------------------------------------------------------------------ numbers and words
    def _units(self, j: int, v: float, shift) -> float:
        """An axis value (mm, rad; G-code frame) in the program's units and frame."""
        if self.rotary[j]:
            return math.degrees(v)
        k = "XYZ".find(self.letters[j])
        return v / self.scale - (shift[k] if k >= 0 else 0.0)

    def _internal(self, j: int, u: float, shift) -> float:
        if self.rotary[j]:
            return math.radians(u)
        k = "XYZ".find(self.letters[j])
        return (u + (shift[k] if k >= 0 else 0.0)) * self.scale

    def _rewrite(self, i: int, block, end, info, write=None) -> str:
        """The text of line i with the axis words of ``end`` (na,) written (see the module
        docstring); ``write`` : (na,) bool, the axes that may be written (default: known)."""
        text = self.texts[i].rstrip("\r\n")
        ending = self.texts[i][len(text):]
        code = _code_end(text)
        named = {m.group(2): m for m in WORD.finditer(text, 0, code)}
        most = max([number_decimals(m.group(4).replace(" ", "")) for m in named.values()] + [0])
        edits, added = [], []
        for j, letter in enumerate(self.letters):
            if not block.known[j] or (write is not None and not write[j]):
                continue
            u = self._units(j, end[j], info.shift)
            m = named.get(letter)
            if m is None:
                last = self.written[j]
                if last == last and signed(self._units(j, last, info.shift), self.base) == \
                        signed(u, self.base):
                    continue
                # in an incremental block (ISO's G91) the word added is an increment too
                start = self._units(j, last, info.shift) if letter in info.incremental else 0.0
                t = signed(u - start, max(self.base, most))
                added.append(letter + t)
                self.written[j] = self._internal(j, start + float(t), info.shift)
                continue
            number = m.group(4).replace(" ", "")
            dec = max(self.base, number_decimals(number))
            sign = number[0] in "+-"
            inc = letter in info.incremental
            if inc:                  # incremental: the corrected end less the written start
                start = self._units(j, self.written[j], info.shift)
                t = signed(u - start, dec, sign)
                value = start + float(t)
            else:
                t = signed(u, dec, sign)
                value = float(t)
            if t == signed(float(number), dec, sign):
                # the source's spelling: the machine goes where it says
                self.written[j] = self._internal(j, value, info.shift) if inc \
                    else block.end[j]
                continue
            edits.append((m.start(4), m.end(4), t))
            self.written[j] = self._internal(j, value, info.shift)
        if added:
            self.count_added(i)
            pos = max([m.end() for m in named.values()], default=None)
            if pos is None:
                pos = self.insert_at(text, code)
            edits.append((pos, pos, " " + " ".join(added)))
        for a, b, t in sorted(edits, reverse=True):
            text = text[:a] + t + text[b:]
        return text + ending

    @staticmethod
    def insert_at(text: str, code: int) -> int:
        """Where an axis word goes in a block that names none: after its keyword."""
        return _KEY_END.match(text).end()

    def count_added(self, i: int) -> None:
        """Count line i (0-based), written with an axis word it did not name, once (the summary's
        ``added_axis_words``: the lines, and the first as a line of the program read,
        ``line_read``)."""
        if i not in self._counted:
            self._counted.add(i)
            self.added_lines += 1
            self.added_line = self.added_line or self.line_read

    # ------------------------------------------------------------------ blocks
    def block(self, i: int, block, pts: np.ndarray, counts) -> None:
        """A motion block of line i (0-based) and its corrected points."""
        self.line_read = i + 1
        info = self.tr.lines[i]
        if info.kind == "C":
            self._arc(i, block, pts, counts, info)
            return
        if pts.shape[0] > 1:
            self.dropped += pts.shape[0] - 1
        end = pts[-1].copy()
        if info.kind == "hole":
            z = self.letters.index("Z")
            end[z] = block.cycle.r_level + (pts[-1, z] - block.points[-1, z])
            self.holes += 1
        self.texts[i] = self._rewrite(i, block, end, info)

    def _arc(self, i, block, pts, counts, info) -> None:
        cols = self.cols
        start_w = np.where(np.isnan(self.written), block.start, self.written)
        if np.isnan(self.written[cols]).any():
            raise InputError("an arc C from a position the output has not written", self.src.source,
                             line=i + 1)
        centre2 = np.asarray(block.centre, float)[:2]
        full = math.hypot(*(block.end[cols] - block.start[cols])) <= 1e-9
        plane = np.zeros(self.na, bool)
        plane[cols] = True
        if full:
            # a full circle ends where it starts as written (the TNC runs a C whose end point is
            # its start as the full circle): its X Y words, where it has them, say that start
            end_w = start_w.copy()
            self.texts[i] = self._rewrite(i, block, end_w, info, write=plane)
        else:
            self.texts[i] = self._rewrite(i, block, pts[-1], info, write=plane)
            end_w = start_w.copy()
            end_w[cols] = self.written[cols]
        self.written = np.where(plane, end_w, self.written)
        got = arc_samples(block.start, block.end, block.points, pts, counts, centre2, tuple(cols),
                          block.motion == 3, full)
        samples, nominal, u = (pts, None, None) if got is None else got
        self.arcs.setdefault(info.cc_line, []).append(
            _Arc(i, start_w, end_w, samples, block, centre2, full, nominal, u))

    # ------------------------------------------------------------------ circle centres
    def centres(self) -> None:
        """Every CC line that arcs use, written with one centre that holds for all of them; where
        none does, the arcs it cannot hold are written in pieces (:mod:`.heidenhain_pieces`), or
        refused in one line where they cannot be (a full circle, an arc under radius
        compensation)."""
        for cc, arcs in self.arcs.items():
            worst = self._one_centre(cc, arcs)
            if worst is not None and not (self.SPLITS and self._in_pieces(cc, arcs)):
                arc, centre = (self.ARC, f"{self.CENTRE} of line {cc + 1}")
                if self._by_radius(cc):
                    arc, centre = "arc CR", "its radius R"
                raise InputError(
                    f"the corrected {arc} of line {worst[1] + 1} is not within the chord "
                    f"tolerance ({self.tol * 1e3:g} um) of an arc about one circle centre "
                    f"({centre}): it misses its corrected path by "
                    f"{worst[2] * 1e3:.2f} um ({self.HINT})", self.src.source, line=worst[1] + 1)

    def _by_radius(self, cc: int) -> bool:
        """Whether the arcs of CC line ``cc`` (a line of the translation) are given by a radius
        (`CR`), not about a circle centre."""
        return self.tr.lines[cc].radius is not None

    def _candidates(self, arcs) -> list:
        """The centres (2,) tried for the arcs of one CC: the nominal centre shifted by the mean
        correction at their ends, and for one arc the circle through its corrected ends closest to
        its corrected path."""
        shifts = [0.5 * ((a.start_w - a.block.start) + (a.end_w - a.block.end))[self.cols]
                  for a in arcs]
        nominal = arcs[0].centre2
        candidates = [nominal + np.mean(shifts, axis=0)]
        if len(arcs) == 1:
            a = arcs[0]
            s2, e2 = a.start_w[self.cols], a.end_w[self.cols]
            r = math.hypot(*(a.block.start[self.cols] - nominal))
            fitted = fit_arc_centre(s2, e2, a.samples[:-1, self.cols], a.ccw, a.full,
                                    candidates[0], r)
            if fitted is not None:
                candidates.append(fitted)
        return candidates

    def _one_centre(self, cc: int, arcs) -> tuple | None:
        """Write the CC line with the first candidate centre that holds every one of ``arcs``:
        None, or the least bad miss (excess, line, distance) where none does."""
        worst = None
        for c in self._candidates(arcs):
            text, said = self._centre_text(cc, c)
            misses = [self._miss(a, said) for a in arcs]
            miss = max(misses)
            if miss[0] <= 0.0:
                self.texts[cc] = text
                self.arc_miss = max(self.arc_miss, *(m[2] for m in misses))
                return None
            worst = miss if worst is None or miss[0] < worst[0] else worst
        return worst

    def _in_pieces(self, cc: int, arcs) -> bool:
        """Write the arcs of one CC that no one centre holds in pieces, the others about the CC
        line's centre (those one candidate holds most of); False where that cannot be done."""
        keep = []
        if len(arcs) > 1:
            tried = self._candidates(arcs) + [c for a in arcs for c in self._candidates([a])]
            for c in tried:
                said = self._centre_text(cc, c)[1]
                held = [a for a in arcs if self._miss(a, said)[0] <= 0.0]
                keep = held if len(held) > len(keep) else keep
            if keep and self._one_centre(cc, keep) is not None:
                keep = []
        split = [a for a in arcs if a not in keep]
        if any(a.full or a.block.cutter_comp or a.nominal is None
               or self.tr.lines[a.line].radius is not None for a in split):   # a CR: not cut
            return False
        for a in split:
            later = any(b.line > a.line for b in keep)
            if not self._write_in_pieces(cc, a, not keep and a is split[0], later):
                return False
        return True

    def _write_in_pieces(self, cc: int, a: _Arc, own_cc: bool, restate: bool) -> bool:
        """The arc ``a`` written as pieces (:class:`~.heidenhain_pieces.ArcPieces`): its line the
        first, about the CC line's centre where ``own_cc`` (else a CC block before it), the
        others after it, and the CC line restated after them where later arcs use it
        (``restate``). False where the first piece would be no arc."""
        info = self.tr.lines[a.line]
        text = self.raws[a.line].decode("latin-1")
        words = [m.group(4) for m in WORD.finditer(text, 0, _code_end(text))]
        cc_text = self.texts[cc].rstrip("\r\n")
        cc_words = [m.group(4) for m in WORD.finditer(cc_text, 0, _code_end(cc_text))]
        dec = max([self.base] + [number_decimals(t.replace(" ", "")) for t in words + cc_words])
        fit = ArcPieces(self, a, dec)
        pieces = fit.plan()
        if pieces[0].centre is None:
            return False
        # the source line: the first piece's end, from where the arc starts as written
        written, self.written = self.written, a.start_w.copy()
        self.texts[a.line], self.line_read = text, a.line + 1
        self.texts[a.line] = self._rewrite(a.line, a.block, pieces[0].end, info,
                                           write=np.isin(np.arange(self.na), self.cols))
        self.written = written
        if own_cc:
            self.texts[cc] = self._centre_text(cc, pieces[0].centre, dec)[0]
        else:
            self.before.setdefault(a.line, []).append(f"CC {fit.words(pieces[0].centre)}")
        lines = fit.later_lines(pieces)
        if restate:
            lines.append(_KEY_START.sub("", cc_text).strip())
        self.after.setdefault(a.line, []).extend(lines)
        self.arc_miss = max(self.arc_miss, *(p.miss for p in pieces))
        self.split_arcs += len(pieces) > 1
        self.added_blocks += len(lines) + (not own_cc)
        return True

    def output(self) -> str:
        """The program's text, with the blocks added for arcs in pieces (renumbered after them)."""
        return renumbered(self.texts, self.before, self.after)

    def _centre_text(self, cc: int, centre, least: int = 0) -> tuple[str, np.ndarray]:
        """(the CC line with the centre (2,) G-code frame, mm) written with at least ``least``
        decimals, the centre it says); for a CR line, its radius (:meth:`_cr_text`)."""
        info = self.tr.lines[cc]
        if info.radius is not None:
            return self._cr_text(cc, centre, least)
        text = self.texts[cc].rstrip("\r\n")
        ending = self.texts[cc][len(text):]
        said = np.zeros(2)
        edits = []
        for m in self.CENTRE_WORD.finditer(text, 0, _code_end(text)):
            k = self.CENTRE_LETTERS.index(m.group(2))
            number = m.group(4).replace(" ", "")
            dec = max(self.base, number_decimals(number), least)
            sign = number[0] in "+-"
            t = signed(centre[k] / self.scale - info.shift[k], dec, sign)
            if t == signed(float(number), dec, sign):
                t = number
            else:
                edits.append((m.start(4), m.end(4), t))
            said[k] = (float(t) + info.shift[k]) * self.scale
        for a, b, t in sorted(edits, reverse=True):
            text = text[:a] + t + text[b:]
        return text + ending, said

    def _cr_text(self, cc: int, centre, least: int = 0) -> tuple[str, np.ndarray]:
        """(the CR line ``cc`` with the R of the circle through its written ends whose centre is
        the nearest to ``centre`` (2,) on the chord's bisector, the centre the TNC makes of the R
        written); a radius that rounds below half the chord says no centre (far away)."""
        a, info = self.arcs[cc][0], self.tr.lines[cc]
        s2, e2 = a.start_w[self.cols], a.end_w[self.cols]
        text = self.texts[cc].rstrip("\r\n")
        ending = self.texts[cc][len(text):]
        m = CR_RADIUS.search(text, 0, _code_end(text))
        number = m.group(1).replace(" ", "")
        dec = max(self.base, number_decimals(number), least)
        r = signed_radius(s2, e2, centre, a.ccw) / self.scale
        half = 0.5 * math.hypot(*(e2 - s2)) / self.scale
        if abs(r) - half < 10.0 ** -dec:
            # a half circle: either sign turns the same within the written decimals (the
            # source's kept), and a radius written below half the chord makes no circle
            r = math.copysign(abs(r), info.radius)
        said = None
        for step in (0.0, 10.0 ** -dec):        # up by one digit where it rounds below the chord
            t = signed(math.copysign(abs(r) + step, r), dec, number[0] in "+-")
            t = number if t == signed(float(number), dec, number[0] in "+-") else t
            try:
                said = np.array(radius_centre(s2, e2, float(t) * self.scale, a.ccw))
                break
            except RadiusError:
                said = np.full(2, 1e9)
        return text[:m.start(1)] + t + text[m.end(1):] + ending, said

    def _miss(self, a: _Arc, centre) -> tuple:
        """(excess over the tolerance (<= 0: holds), line, distance mm) of an arc about centre."""
        s2, e2 = a.start_w[self.cols], a.end_w[self.cols]
        r0, r1 = math.hypot(*(s2 - centre)), math.hypot(*(e2 - centre))
        if radius_refused(r0, r1, self.tr.inch):
            return abs(r1 - r0), a.line, abs(r1 - r0)
        _a, sweep = arc_sweep(s2, e2, centre, a.ccw, a.full)
        _a, span = arc_sweep(a.block.start[self.cols], a.block.end[self.cols], a.centre2, a.ccw,
                             a.full)
        if abs(sweep - span) > 0.25 * math.pi:
            return math.inf, a.line, math.inf
        dist, rot = arc_misses(a.start_w, a.end_w, centre, tuple(self.cols), a.ccw, a.full,
                               a.samples, self.linear)
        excess = max(dist - self.tol, (rot - ROTARY_ARC_TOL_RAD) if rot > ROTARY_ARC_TOL_RAD else -1)
        return excess, a.line, dist


class IsoWriter(HeidenhainWriter):
    """Writes one DIN/ISO program (:mod:`.heidenhain_iso`): as a conversational one
    (:class:`HeidenhainWriter`), the circle centre in its I J words; an arc that no one centre
    holds is refused (not written in pieces)."""

    ARC, CENTRE = "arc G02/G03", "I J"
    SPLITS = False
    CENTRE_WORD = re.compile(r"(?<![A-Z])()([IJ])(\s*)([+-]?\s*(?:\d+\.?\d*|\.\d+))")
    CENTRE_LETTERS = "IJ"

    @staticmethod
    def insert_at(text: str, code: int) -> int:
        """Where an axis word goes in a block that names none: before its closing ``*``."""
        return len(text[:code].rstrip().rstrip("*").rstrip())


def plan_blocks(w, src, machine, cursor, chord_tol_mm, initial_position, inch, initial_known):
    """Hand every block of the program read through its G-code equivalent, with its corrected
    points, to the writer ``w`` (its ``block``), then the circle centres (``centres``); returns
    the segment rows written."""
    rows = 0
    for k, _raw, block, state in iter_blocks(src, machine, chord_tol_mm, initial_position,
                                             inch=inch, initial_known=initial_known):
        if block is None:
            # an axis the reader forgets (M91/M92, TOOL CALL, a subprogram) is not where the
            # output wrote it
            w.written[~state.known] = np.nan
            continue
        pts = np.array(cursor.take(k, block.points.shape[0]))
        w.block(k - 1, block, pts, cursor.counts.copy())
        rows += block.points.shape[0]
    cursor.finish()
    w.centres()
    return rows


def write_corrected(src, out_path, machine, cursor, chord_tol_mm: float, initial_position=None,
                    *, inch: bool = False, initial_known=None, stats: dict | None = None) -> int:
    """Write the conversational program of ``src`` (a :class:`~.source.ProgramSource` with its
    ``heidenhain`` translation) with the corrections of ``cursor`` (see
    :func:`mtcomp.toolpaths.gcode.write_corrected`); returns the segment rows written."""
    w = (IsoWriter if src.heidenhain.iso else HeidenhainWriter)(src, machine, chord_tol_mm)
    rows = plan_blocks(w, src, machine, cursor, chord_tol_mm, initial_position, inch,
                       initial_known)
    with atomic_write(out_path, "wb") as f:
        f.write(w.output().encode("latin-1"))
    if w.dropped:
        src.notes.append(f"note: {w.dropped} internal node{'s' if w.dropped != 1 else ''} of the "
                         "plan not written: a Heidenhain program's blocks stay one to one (only "
                         "the blocks' ends are corrected)")
    if w.arc_miss >= 1e-4:
        src.notes.append(f"note: the arcs written (one circle centre {w.CENTRE} each) miss their "
                         f"corrected path by up to {w.arc_miss * 1e3:.2f} um (within --chord-tol-um "
                         f"{w.tol * 1e3:g}): the deviation after compensation and BLOCKS.csv are "
                         "the corrected path's, the arcs as written leave up to that much more")
    if w.added_blocks:
        src.notes.append(f"{w.split_arcs} arc{'s' if w.split_arcs != 1 else ''} C that no one "
                         f"circle centre holds within --chord-tol-um {w.tol * 1e3:g} (a reversal "
                         "of an axis with play, a correction that changes along the arc) written in "
                         f"pieces: {w.added_blocks} block{'s' if w.added_blocks != 1 else ''} "
                         "added (a CC and a C for each piece after the first; a CC of its own for "
                         "an arc whose CC other arcs keep), the blocks after them renumbered (the "
                         "TNC numbers a program's blocks in ascending order)")
    if w.holes:
        src.notes.append(f"{w.holes} drilling call{'s' if w.holes != 1 else ''} (L ... M99 of a "
                         "pecking cycle) corrected at the hole's bottom: X Y of the hole, the "
                         "start level moved by the Z correction (the depth below it kept)")
    if stats is not None:
        stats["cycle_lines"] = 0
        stats["cycle_blocks"] = 0
        stats["heidenhain_holes"] = w.holes
        if w.added_lines:
            stats["added_axis_words"] = (w.added_lines, w.added_line)
    return rows

"""A Siemens Sinumerik program written back with corrected coordinates.

The program is read through its G-code equivalent (:mod:`.sinumerik`), planned as any program, and
written here in its own form: every line is the source line, byte for byte, except the values
that carry a correction. An axis word given as a number (``X57``) gets the corrected number, with
at least the source's decimals and at least 4 (5 in inch: G70/G700 in force; every value is written
in the units of its block); an axis word given as an expression
(``Z=WYSSRU+60``) keeps its expression and gets the correction appended (``Z=WYSSRU+60+0.0012``),
so the variables the programmer wrote stay visible (the controller computes in double precision:
the written value is exact to far below a micrometre). An axis the block does not name is added
after its last axis word where its written value changes (never one the program has not
positioned). A circle's centre ``I=AC(..) J=AC(..)`` (or incremental ``I J``) is moved as a
Heidenhain ``CC`` is (:mod:`.heidenhain_out`): one centre per circle, kept when the circle lies
within the chord tolerance of its corrected path, otherwise refused in one line. A circle by its
radius ``CR=`` gets the radius of the circle through its written ends whose centre is the moved
centre's nearest on the chord's bisector (of the radii its decimals give next to it, the one whose
centre the controller makes nearest; that centre is the one checked against the corrected path),
written to its corrected Z with that ``CR=`` where one circle then holds it; where none holds, it
is written in pieces about ``I=AC J=AC`` centres.
Under a programmable offset ``TRANS``/``ATRANS`` the positions are written in the program's
coordinates (the offset taken off); the offset's lines, and blocks in machine coordinates
(``SUPA``, ``G53``), are kept as written.

A drilling cycle's hole is corrected at its bottom: X Y on the positioning block under ``MCALL``;
the cycle's reference plane RFP (and an absolute depth DP) moved by the Z correction, in the call's
line when every hole of the call gets the same; otherwise the call is repeated (``MCALL
CYCLE81(...)`` with that hole's levels) before each hole whose levels differ. A single call's hole
(at the position the block before left) gets a positioning block ``X.. Y..`` before the call where
its corrected position differs from the written one. A hole pattern (``HOLES1`` row, ``HOLES2``
circle) whose holes share one correction gets its reference point moved; otherwise it is written as
explicit positions, one block each. The retract plane RTP is kept as written (a clearance, not a cut). Where lines are added the
output's first line after the file header says so.

The program is planned one output block per source block, but for the nodes of the step bound's
ramp along a straight feed move after a block left uncorrected (mtcomp.planner): they are written
as ``G1`` blocks before the move's line, every axis the program has given, with the line's feed.
"""
from __future__ import annotations

import copy
import math

import numpy as np

from ..errors import InputError
from ..io.atomic import atomic_write
from .heidenhain_pieces import ArcPieces
from .heidenhain_out import ROTARY_ARC_TOL_RAD, HeidenhainWriter, plan_blocks
from .sinumerik import AXES, BLOCK_START
from .sinumerik_lang import code_end, corrected_text, split_words
from .sinumerik_lang import edit_text as _edit
from .sinumerik_lang import number_text as _number
from .sinumerik_paths import RadiusError, radius_centre, signed_radius
from .sinumerik_turn import HelixTurns, turn_notes
from .words import MM_PER_INCH

__all__ = ["SinumerikWriter", "corrected_text", "write_corrected"]



class SinumerikWriter(HelixTurns, HeidenhainWriter):
    """Writes one Sinumerik program (see the module docstring)."""

    ARC, CENTRE, HINT = "circle G2/G3", "its I J", "a larger --chord-tol-um"
    SPLITS = False          # a circle no centre holds is written in pieces by _split

    def __init__(self, src, machine, chord_tol_mm: float):
        super().__init__(src, machine, chord_tol_mm, translation=src.sinumerik)
        self.orig = list(self.texts)             # the source's lines (the calls' spans)
        self.restate: dict[int, str] = {}       # a HOLES2 hole -> the call restated before it
        self.before: dict[int, list] = {}       # source line -> lines inserted before it
        self.replaced: dict[int, list] = {}     # source line -> the lines written instead
        self.dz: dict[int, float] = {}          # hole (G-code line index) -> Z correction, mm
        self.xy: dict[int, np.ndarray] = {}     # hole -> its corrected X Y as written
        self.dxy: dict[int, np.ndarray] = {}    # a HOLES2 hole -> its X Y correction, mm
        self.retracts = 0
        self.added = 0
        self.ramp_blocks = 0                    # internal nodes written as blocks (_nodes)
        self.split_circles = 0
        self.arc_info: dict = {}                # a circle's line -> its GInfo
        self.zi = self.letters.index("Z")

    # ------------------------------------------------------------------ words
    def _units_of(self, info) -> None:
        """The units of the line of ``info`` (a :class:`~.sinumerik.GInfo`): G70/G700 inch (mm per
        unit and at least 5 decimals) or mm (4 decimals)."""
        self.scale = MM_PER_INCH if info.inch else 1.0
        self.base = 5 if info.inch else 4

    def _places(self, j: int) -> int:
        """The fewest decimals of axis j's words: 4 in degrees, else the line's."""
        return 4 if self.rotary[j] else self.base

    def _words(self, text: str):
        end = code_end(text)
        start = BLOCK_START.match(text).end()
        try:
            return split_words(text, start, end)
        except ValueError:
            return []

    def _rewrite(self, i: int, block, end, info, write=None, nominal=None) -> str:
        """Line i with the axis words of ``end`` (na,) written (see the module docstring);
        ``write`` (na,) bool: the axes that may be written (default: known); ``nominal`` (na,) the
        positions the line's words say (default: the block's end)."""
        nominal = block.end if nominal is None else nominal
        text = self.texts[i].rstrip("\r\n")
        ending = self.texts[i][len(text):]
        words = self._words(text)
        named = {w.name: w for w in words if w.name in AXES and w.kind in ("address", "assign")}
        edits, added = [], []
        for j, letter in enumerate(self.letters):
            if not block.known[j] or (write is not None and not write[j]):
                continue
            u = self._units(j, end[j], info.shift)
            w = named.get(letter)
            if w is None:
                last = self.written[j]
                t = _number(u, self._places(j))
                if last == last and _number(self._units(j, last, info.shift), self._places(j)) == t:
                    continue
                added.append(letter + t)
                self.written[j] = self._internal(j, float(t), info.shift)
                continue
            t, said = corrected_text(w.text, self._units(j, nominal[j], info.shift), u,
                                     self._places(j))
            if t != w.text:
                edits.append((w.start, w.end, t))
            self.written[j] = self._internal(j, said, info.shift)
        if added:
            self.count_added(i)
            last = max([w.end for w in named.values()], default=None)
            if last is None:
                last = len(text[:code_end(text)].rstrip())
            edits.append((last, last, " " + " ".join(added)))
        return _edit(text, edits) + ending

    def _centre_text(self, cc: int, centre) -> tuple[str, np.ndarray]:
        """(line cc with its circle centre (2,) G-code frame, mm, written; the centre it says)."""
        arc = self.arcs[cc][0]
        text = self.texts[cc].rstrip("\r\n")
        ending = self.texts[cc][len(text):]
        said = np.zeros(2)
        edits = []
        info = self.arc_info[cc]
        if info.radius is not None:
            return self._radius_text(cc, centre, info)
        named = {w.name: w for w in self._words(text) if w.name in "IJ"}
        for k, letter in enumerate("IJ"):
            w = named[letter]
            head = w.text.strip().upper()[:2] if w.kind == "assign" else ""
            a, b = w.start, w.end
            if head in ("AC", "IC"):
                a, b = w.start + w.text.find("(") + 1, w.start + w.text.rfind(")")
            col = self.cols[k]
            # the word's value: the centre in the program's frame (AC) or from the start (mm,
            # the G-code frame: the nominal start for the nominal centre, the written one else)
            f = self.scale
            start, base = ((info.shift[k] * f, info.shift[k] * f) if head == "AC" else
                           (arc.block.start[col], arc.start_w[col]))
            t, value_said = corrected_text(text[a:b], (arc.centre2[k] - start) / f,
                                           (centre[k] - base) / f, self.base)
            if t != text[a:b]:
                edits.append((a, b, t))
            said[k] = value_said * f + base
        return _edit(text, edits) + ending, said

    def _radius_text(self, cc: int, centre, info) -> tuple[str, np.ndarray]:
        """(line cc with the CR= of the circle through its written start and end whose centre is
        the nearest to ``centre`` (2,) on the chord's bisector; the centre the controller makes of
        the CR= written). Of the radii the written decimals give next to it (rounded, one digit
        below, one above), the one whose centre is nearest ``centre``: near a half circle a radius
        a tenth of a micrometre above half the chord moves the centre off the chord by the root of
        the chord times that (30 um on a 20 mm chord), while one below it by less than the
        controller's tolerance makes the half circle itself (:func:`radius_centre`)."""
        a = self.arcs[cc][0]
        f = self.scale                      # in the program's units here
        s2, e2 = a.start_w[self.cols] / f, a.end_w[self.cols] / f
        text = self.texts[cc].rstrip("\r\n")
        ending = self.texts[cc][len(text):]
        w = next(w for w in self._words(text) if w.kind == "assign" and w.name == "CR")
        r = signed_radius(s2, e2, np.asarray(centre) / f, a.ccw)
        half = 0.5 * math.hypot(*(e2 - s2))
        if abs(r) - half < 10.0 ** -self.base:
            # a half circle: either sign turns the same within the written decimals (the
            # source's kept)
            r = math.copysign(abs(r), info.radius)
        best = None
        for step in (0.0, -1.0, 1.0):
            t, said_r = corrected_text(w.text, info.radius,
                                       math.copysign(abs(r) + step * 10.0 ** -self.base, r),
                                       self.base)
            try:
                said = np.array(radius_centre(s2, e2, said_r, a.ccw, f)) * f
            except RadiusError:
                said = np.full(2, 1e9)
            miss = math.hypot(*(said - np.asarray(centre)))
            if best is None or miss < best[0] - 1e-12:
                best = (miss, t, said)
        _miss, t, said = best
        return _edit(text, [(w.start, w.end, t)] if t != w.text else []) + ending, said

    def _arc(self, i, block, pts, counts, info) -> None:
        """A circle (:meth:`HeidenhainWriter._arc`) and at once its centre: each circle has its own
        centre words, so it is settled here, before the blocks after it are written (a circle
        written in pieces may leave Z where the corrected path has it)."""
        self.arc_info[info.cc_line] = info
        self.CENTRE = "its I J" if info.radius is None else "its radius CR="
        super()._arc(i, block, pts, counts, info)
        self._helix_end(i, block, pts[-1], info)
        arcs = self.arcs.pop(info.cc_line)
        every, self.arcs = self.arcs, {info.cc_line: arcs}
        try:
            super().centres()
        except InputError as exc:
            cause = self._rotary_cause(exc.line - 1) if exc.line is not None else None
            if cause is not None:
                raise InputError(cause, self.src.source, line=exc.line) from None
            if len(arcs) != 1 or not self._split(arcs[0], info):
                raise
        finally:
            self.arcs = every

    def _helix_end(self, i: int, block, end, info) -> None:
        """A helix (a circle whose Z, a linear axis off the plane, changes; Fundamentals, helical
        interpolation): its Z word gets the corrected end, and the circle is checked against its
        corrected path as the helix it is (the off-plane axes going linearly with the angle)."""
        off = self.linear & block.known
        off[self.cols] = False
        if not np.any(np.abs(block.end - block.start)[off] > 1e-9):
            return
        if math.hypot(*(block.end - block.start)[self.cols]) <= 1e-9:
            raise InputError("a helix of a whole turn (a circle G2/G3 back to its start in the "
                             "plane, Z changing) is not written by mtcomp (a circle's corrected "
                             "path is matched by its angle, which a whole turn repeats)",
                             self.src.source, line=i + 1)
        self.texts[i] = self._rewrite(i, block, end, info, write=off)
        self.arcs[info.cc_line][-1].end_w[off] = self.written[off]

    def _split(self, a, info) -> bool:
        """The circle ``a`` (a :class:`~.heidenhain_out._Arc`) written as circle pieces, each
        within the chord tolerance of its part of the corrected path, Z (a linear axis off the
        plane) written where the corrected path moves it: the first on the source line (its other
        words kept), the others after it. The pieces as the G-code and Heidenhain writers plan them
        (:class:`_CirclePieces`). False (nothing written) when the circle is a helix or a piece
        would be a straight line."""
        off = self.linear & a.block.known
        off[self.cols] = False
        if np.any(np.abs(a.block.end - a.block.start)[off] > 1e-9) or a.nominal is None:
            return False
        planned = _CirclePieces(self, a, off, info).plan()
        if any(p.centre is None for p in planned):
            return False
        self.arc_miss = max(self.arc_miss, *(p.miss for p in planned))
        starts = [a.start_w] + [p.end for p in planned[:-1]]
        pieces = [(s, p.end, p.centre) for s, p in zip(starts, planned)]
        one = (None if len(planned) > 1 or info.radius is None
               else self._radius_piece(a, planned[0], off, info))
        lines = [one] if one is not None else self._piece_lines(a, pieces, off, info)
        if len(lines) == 1:
            self.texts[a.line] = self._with_ending(a.line, lines[0])
        else:
            self.replaced[a.line] = lines
        self.written[off] = planned[-1].end[off]
        self.added += len(pieces) - 1
        self.split_circles += 1
        return True

    def _radius_piece(self, a, piece, off, info) -> str | None:
        """A circle by its radius written as one piece (to its corrected Z): its source line with
        the CR= of the piece's centre (:meth:`_radius_text`) and the Z word of the piece's end, the
        form it was written in; None where the circle that CR= makes misses the corrected path by
        more than the chord tolerance (it is then written about ``I=AC J=AC``)."""
        text, said = self._radius_text(a.line, piece.centre, info)
        whole = copy.copy(a)
        whole.end_w = piece.end
        excess, _line, miss = self._miss(whole, said)
        if excess > 0.0:
            return None
        self.arc_miss = max(self.arc_miss, miss)
        text = text.rstrip("\r\n")
        named = {w.name: w for w in self._words(text) if w.kind in ("address", "assign")}
        words = {self.letters[j]: _number(self._units(j, piece.end[j], info.shift), self._places(j))
                 for j in np.flatnonzero(off)
                 if _number(self._units(j, piece.end[j], info.shift), self._places(j))
                 != _number(self._units(j, a.start_w[j], info.shift), self._places(j))}
        return self._first_piece(text, named, words, None)

    def _rounded(self, point, like, off, info, last: bool) -> np.ndarray:
        """A piece's end: ``like`` (na,) with the corrected point's (na,) X Y (unless ``last``:
        the circle's end as written) and its axes ``off`` (na,) bool as written (4 decimals)."""
        out = like.copy()
        for j in np.flatnonzero(off) if last else list(self.cols) + list(np.flatnonzero(off)):
            out[j] = self._internal(j, float(_number(self._units(j, point[j], info.shift),
                                                     self._places(j))),
                                    info.shift)
        return out

    def _piece_lines(self, a, pieces, off, info) -> list[str]:
        """The pieces' lines: the first is the source line with its end point and centre words
        replaced (an end point added before I where it had none), the others ``X.. Y.. I=AC(..)
        J=AC(..)`` (incremental ``I.. J..`` where the source's centre was), the last ending at
        the circle's end as the source line's words wrote it; Z (the axes ``off``) on a piece
        whose written value it changes. A circle by its radius CR= becomes pieces about absolute
        centres, its CR= word the first piece's I=AC(..) J=AC(..)."""
        text = self.texts[a.line].rstrip("\r\n")
        named = {w.name: w for w in self._words(text) if w.kind in ("address", "assign")}
        radius = "I" not in named
        absolute = [radius or named[c].kind == "assign" and
                    named[c].text.strip().upper().startswith("AC") for c in "IJ"]
        lines = []
        for n, (start, end, centre) in enumerate(pieces):
            u = {self.letters[j]: _number(self._units(j, end[j], info.shift), self._places(j))
                 for j in list(self.cols) + list(np.flatnonzero(off))}
            for j in np.flatnonzero(off):
                if u[self.letters[j]] == _number(self._units(j, start[j], info.shift),
                                                 self._places(j)):
                    del u[self.letters[j]]
            b = self.base
            ij = [f"{c}=AC({_number(self._units(j, v, info.shift), b)})" if ab else
                  f"{c}{_number(self._units(j, v, info.shift) - self._units(j, s, info.shift), b)}"
                  for c, j, v, s, ab in zip("IJ", self.cols, centre, start[self.cols], absolute)]
            if n == len(pieces) - 1 == 0 and not radius:    # one piece: its words, with Z
                text = self._centre_text(a.line, centre)[0].rstrip("\r\n")
                u = {c: v for c, v in u.items() if c not in "XY"}
                named = {w.name: w for w in self._words(text) if w.kind in ("address", "assign")}
                ij = [text[self._word_start(text, named[c]):named[c].end] for c in "IJ"]
            if n == 0:
                lines.append(self._first_piece(text, named, u, ij))
                continue
            if n == len(pieces) - 1:         # the circle's end as the source line wrote it
                u.update({c: text[self._word_start(text, named[c]):named[c].end]
                          for c in "XY" if c in named})
            lines.append(" ".join([v if v[:1].isalpha() else f"{c}{v}" for c, v in u.items()]
                                  + ij))
        return lines

    @staticmethod
    def _word_start(text: str, w) -> int:
        """Where word ``w``'s letter stands (before its ``=`` for an assign word)."""
        return text.upper().rfind(w.name, 0, w.start)

    def _first_piece(self, text, named, words, ij) -> str:
        """The source line with the first piece's end point (``words``: letter -> value text)
        and centre ``ij`` written (None: the line's centre words kept)."""
        if ij is None:
            edits = []
        elif "I" in named:
            edits = [(self._word_start(text, named[c]), named[c].end, t) for c, t in zip("IJ", ij)]
        else:                       # CR=: the pieces' centres are absolute
            edits = [(self._word_start(text, named["CR"]), named["CR"].end, " ".join(ij))]
        missing = []
        for c, v in words.items():
            if c in named:
                edits.append((self._word_start(text, named[c]), named[c].end, f"{c}{v}"))
            else:
                missing.append(f"{c}{v}")
        if missing:
            at = self._word_start(text, named["I" if "I" in named else "CR"])
            edits.append((at, at, " ".join(missing) + " "))
        return _edit(text, edits)

    def _by_radius(self, cc: int) -> bool:
        """False: a circle's ``cc`` is its source line, not a line of the translation, and
        :attr:`CENTRE` already names its centre words (`I J` or `CR=`: :meth:`_arc`)."""
        return False

    def _rotary_cause(self, line: int) -> str | None:
        """Why the circle of ``line`` (0-based) is refused when its rotary axes are: the rotary
        axis whose corrected path leaves the value the circle holds, and by how much; None when
        every rotary axis stays within ROTARY_ARC_TOL_RAD of it."""
        for arcs in self.arcs.values():
            for a in arcs:
                if a.line != line:
                    continue
                for j in np.flatnonzero(~self.linear):
                    span = np.abs(a.samples[:, j] - a.start_w[j])
                    if span.max() <= ROTARY_ARC_TOL_RAD:
                        continue
                    change = np.degrees(np.ptp(np.append(a.samples[:, j], a.start_w[j])))
                    # corrections within +-bound differ by 2 bound along the circle, and the
                    # written start (4 decimals of a degree) by up to half a step more
                    bound = math.floor(0.25 * ROTARY_ARC_TOL_RAD * 1e7) / 10      # urad
                    return (f"the correction of {self.letters[j]} varies along the circle G2/G3 of "
                            f"line {line + 1} by {change:.5f} deg, and a circle holds "
                            f"{self.letters[j]} at its written value (within "
                            f"{np.degrees(ROTARY_ARC_TOL_RAD):g} deg): a larger --chord-tol-um does "
                            f"not help; bound the rotary corrections with --max-correction-urad "
                            f"{bound:.1f} (or less), which a circle holds")
        return None

    # ------------------------------------------------------------------ blocks
    def block(self, g: int, block, pts: np.ndarray, _counts=None) -> None:
        """A motion block of G-code line g (0-based) and its corrected points."""
        self.line_read = g + 1
        info = self.tr.lines[g]
        i = info.source
        self._units_of(info)
        if pts.shape[0] > 1 and info.kind == "move" and block.motion == 1:
            self._nodes(i, block, pts[:-1], info)
        elif pts.shape[0] > 1 and info.kind != "arc":
            self.dropped += pts.shape[0] - 1
        if info.kind == "arc" and info.turn is not None:
            self._turn_piece(i, block, pts, info)
        elif info.kind == "arc":
            self._arc(i, block, pts, None, info)
        elif info.kind == "hole":
            self._hole(g, i, block, pts[-1], info)
        elif info.kind == "retract":
            self.retracts += 1
            self.written[self.zi] = block.end[self.zi]
        elif info.kind == "approach":
            write = np.ones(self.na, bool)
            write[self.cols] = False
            self.texts[i] = self._rewrite(i, block, pts[-1], info, write=write)
        else:
            self.texts[i] = self._rewrite(i, block, pts[-1], info)

    def _nodes(self, i: int, block, nodes: np.ndarray, info) -> None:
        """The internal nodes (k, na) of a straight feed move (the step bound's ramp into it after
        a block left uncorrected: mtcomp.planner) written as ``G1`` blocks before its line, every
        axis the program has given, with the line's feed word (the feed it moves at)."""
        text = self.texts[i].rstrip("\r\n")
        feed = [text[self._word_start(text, w):w.end] for w in self._words(text) if w.name == "F"]
        for p in nodes:
            words = ["G1"]
            for j in np.flatnonzero(block.known):
                t = _number(self._units(j, p[j], info.shift), self._places(j))
                words.append(self.letters[j] + t)
                self.written[j] = self._internal(j, float(t), info.shift)
            self.before.setdefault(i, []).append(" ".join(words + feed[-1:]))
        self.added += len(nodes)
        self.ramp_blocks += len(nodes)

    def _hole(self, g, i, block, end, info) -> None:
        nominal = block.points[-1]
        # dz, dxy: in the program's units
        self.dz[g] = float(_number((end[self.zi] - nominal[self.zi]) / self.scale, self.base))
        xy = np.array([float(_number(self._units(j, end[j], info.shift), self.base))
                       for j in self.cols])
        self.xy[g] = xy
        self.dxy[g] = (end - nominal)[self.cols] / self.scale
        if info.pattern is None and info.call.line != i:      # a positioning block under MCALL
            write = np.zeros(self.na, bool)
            write[self.cols] = True
            self.texts[i] = self._rewrite(i, block, end, info, write=write, nominal=nominal)
        elif info.pattern is None:                             # a single call at the position
            # written: the G-code frame; xy: the program's (TRANS/ATRANS taken off)
            now = np.array([self._units(j, v, info.shift) for j, v in zip(self.cols, self.written[self.cols])])
            if np.isnan(now).any() or not np.allclose(now, xy, rtol=0, atol=1e-9):
                words = " ".join(f"{a}{_number(v, self.base)}" for a, v in zip("XY", xy))
                self.before.setdefault(i, []).append(words)
                self.added += 1
        self.written[self.cols] = [self._internal(j, float(v), info.shift) for j, v in zip(self.cols, xy)]
        self.written[self.zi] = self._internal(self.zi, info.call.rtp, info.shift)

    # ------------------------------------------------------------------ cycle calls and patterns
    def _call_edits(self, call, dz: float) -> dict:
        """Argument index -> its text with RFP (and DP when the depth is DP's) moved by dz."""
        edits = {}
        which = [1] if len(call.args) > 4 and call.args[4] else [1, 3]
        for n in which:
            if dz == 0.0 or n >= len(call.args) or not call.args[n] or not call.spans:
                continue
            a, b = call.spans[n]
            nominal = call.rfp if n == 1 else call.bottom
            edits[n] = corrected_text(self.orig[call.line][a:b], nominal, nominal + dz,
                                      self.base)[0]
        return edits

    def _call_line(self, call, dz: float) -> str:
        """The modal call restated with the levels of a hole corrected by dz."""
        edits = self._call_edits(call, dz)
        args = [edits.get(n, self.orig[call.line][a:b]) for n, (a, b) in enumerate(call.spans)]
        return f"MCALL {call.name}({','.join(args)})"

    def finish(self) -> None:
        """The cycle calls' levels and the HOLES2 circles, once every hole is planned."""
        for call in self.tr.calls:
            holes = [h for h in call.holes if h in self.dz]
            if not holes:
                continue
            self._units_of(self.tr.lines[holes[0]])     # no change of units under a modal call
            if call.modal and len({self.dz[h] for h in holes}) > 1 and not call.spans:
                raise InputError(f"the holes of {call.name} need different corrections of its "
                                 "levels, and its arguments cannot be restated", self.src.source,
                                 line=call.line + 1)
            force = self.dz[holes[0]]
            for h in holes[1:]:
                if call.modal and self.dz[h] != force:
                    force = self.dz[h]
                    if self.tr.lines[h].pattern is not None:
                        self.restate[h] = self._call_line(call, force)
                    else:
                        self.before.setdefault(self.tr.lines[h].source, []).append(
                            self._call_line(call, force))
                        self.added += 1
            edits = self._call_edits(call, self.dz[holes[0]])
            self.texts[call.line] = self._with_ending(call.line, _edit(
                self.texts[call.line].rstrip("\r\n"),
                [(*call.spans[n], t) for n, t in edits.items()]))
        for p in self.tr.patterns:
            self._units_of(self.tr.lines[p.holes[0]])
            if self._pattern_expands(p):
                self._expand(p)
            else:
                self._shift_centre(p)

    def _pattern_expands(self, p) -> bool:
        """Whether a HOLES2 circle must be written as explicit positions: its holes' corrections
        differ (X Y, or Z)."""
        d = {tuple(_number(v, self.base) for v in self.dxy[h]) for h in p.holes}
        same_xy = len(d) == 1
        dz = [self.dz[h] for h in p.holes if h in self.dz]
        return not same_xy or len(set(dz)) > 1 or any(h in self.restate for h in p.holes)

    def _shift_centre(self, p) -> None:
        """A HOLES2 circle whose holes share one correction: its centre CPA CPO moved by it."""
        d = [float(_number(v, self.base)) for v in self.dxy[p.holes[0]]]
        text = self.texts[p.line].rstrip("\r\n")
        edits = []
        for k in (0, 1):
            a, b = p.spans[k]
            t, _said = corrected_text(text[a:b], p.centre[k], p.centre[k] + float(d[k]), self.base)
            if t != text[a:b]:
                edits.append((a, b, t))
        self.texts[p.line] = self._with_ending(p.line, _edit(text, edits))

    def _expand(self, p) -> None:
        text = self.texts[p.line].rstrip("\r\n")
        call_start = text.upper().rfind(p.name, 0, p.spans[0][0])
        lines = []
        for n, h in enumerate(p.holes):
            if h in self.restate:
                lines.append(self.restate[h])
            words = " ".join(f"{a}{_number(v, self.base)}" for a, v in zip("XY", self.xy[h]))
            if n == 0 and p.motion not in (0, None):
                words = "G0 " + words
            if n == 0:
                lines.append(text[:call_start] + words + text[p.spans[-1][1] + 1:])
            else:
                lines.append(words)
        if p.motion not in (0, None):
            lines.append(f"G{p.motion}")
        self.added += len(lines) - 1
        self.replaced[p.line] = lines

    def _with_ending(self, i: int, text: str) -> str:
        return text + self.texts[i][len(self.texts[i].rstrip("\r\n")):]

    def output(self) -> str:
        """The program's text, with the lines added and a comment saying so."""
        out = []
        ending = "\r\n" if self.texts and self.texts[0].endswith("\r\n") else "\n"
        head = 0
        while head < len(self.texts) and (self.texts[head].lstrip().startswith("%") or
                                          self.texts[head].lstrip().upper().startswith(";$PATH")):
            head += 1
        for i, text in enumerate(self.texts):
            if i == head and (self.added or self.replaced):
                out.append(f"; mtcomp: {self.added} block{'s' if self.added != 1 else ''} added to "
                           "write corrected holes and circles (a cycle call restated, a hole's "
                           "position, a hole pattern HOLES1 or HOLES2 written as explicit "
                           "positions, a circle written in pieces, a helix with TURN= written as "
                           "pieces" + (", a feed move's ramp of the correction written at its "
                                       "nodes" if self.ramp_blocks else "") + ")"
                           + ending)
            own = text[len(text.rstrip("\r\n")):] or ending
            out.extend(t + own for t in self.before.get(i, []))
            if i in self.replaced:
                out.extend(t + own for t in self.replaced[i])
            else:
                out.append(text)
        return "".join(out)


def write_corrected(src, out_path, machine, cursor, chord_tol_mm: float, initial_position=None,
                    *, inch: bool = False, initial_known=None, stats: dict | None = None) -> int:
    """Write the Sinumerik program of ``src`` (a :class:`~.source.ProgramSource` with its
    ``sinumerik`` translation) with the corrections of ``cursor`` (see
    :func:`mtcomp.toolpaths.gcode.write_corrected`); returns the segment rows written."""
    w = SinumerikWriter(src, machine, chord_tol_mm)
    rows = plan_blocks(w, src, machine, cursor, chord_tol_mm, initial_position, inch,
                       initial_known)
    w.finish()
    with atomic_write(out_path, "wb") as f:
        f.write(w.output().encode("latin-1"))
    _notes(src, w, stats)
    return rows


def _notes(src, w: SinumerikWriter, stats) -> None:
    subs = src.sinumerik.subprograms
    if subs:
        named = ", ".join(f"{name} at line {k + 1}" for k, name in subs[:6])
        src.notes.append(
            f"warning: {len(subs)} call{'s' if len(subs) != 1 else ''} of subprograms or cycles "
            f"not in the file ({named}{', ...' if len(subs) > 6 else ''}): passed through "
            "uncorrected, every axis unknown after each until the program names it again; the "
            "modes are taken as before the call (a Siemens subprogram with SAVE restores them)")
    holes = len(w.dz)
    if holes:
        names = ", ".join(sorted({call.name for call in src.sinumerik.calls if call.holes}))
        src.notes.append(
            f"{holes} hole{'s' if holes != 1 else ''} of drilling cycles ({names}) "
            "corrected at the bottom: X Y of the hole, the reference plane RFP moved by the Z "
            f"correction (the depth below it kept); the retract plane RTP kept as written "
            f"({w.retracts} retract{'s' if w.retracts != 1 else ''}: BLOCKS.csv gives their "
            "planned correction, not written)")
    src.notes.extend(turn_notes(w))
    if w.split_circles:
        src.notes.append(
            f"{w.split_circles} circle{'s' if w.split_circles != 1 else ''} G2/G3 that one centre "
            f"does not hold within --chord-tol-um {w.tol * 1e3:g}: written to the corrected Z (a "
            "helix where Z's correction changes along it) and, where needed, in pieces (G2/G3 each, "
            "with its own end point and centre)")
    if w.arc_miss >= 1e-4:
        src.notes.append(f"note: the circles written miss their corrected path by up to "
                         f"{w.arc_miss * 1e3:.2f} um (within --chord-tol-um {w.tol * 1e3:g})")
    if stats is not None:
        stats["cycle_lines"] = 0
        stats["cycle_blocks"] = 0
        if w.added_lines:
            stats["added_axis_words"] = (w.added_lines, w.added_line)
        if subs:
            first = next(n for n, info in enumerate(src.sinumerik.lines)
                         if info.source == subs[0][0]) + 1
            stats["passed_moves"] = {"subprogram": [len(subs), first]}


class _CirclePieces(ArcPieces):
    """The pieces of a circle G2/G3 that no one centre holds, planned as a Heidenhain arc's
    (:class:`~.heidenhain_pieces.ArcPieces`: the shared splitter of the G-code and Heidenhain
    writers), with this dialect's words: a piece's end has the corrected X Y (and Z where it
    changes) as written, its centre ``I=AC(..) J=AC(..)`` as written."""

    def __init__(self, w, a, off, info):
        super().__init__(w, a, w.base)
        self.off, self.info = off, info

    def _end(self, b: int, start_w: np.ndarray) -> np.ndarray:
        last = b == self.samples.shape[0] - 1
        return self.w._rounded(self.samples[b], self.a.end_w if last else start_w, self.off,
                               self.info, last)

    def _centre(self, centre) -> np.ndarray:
        w, shift = self.w, self.info.shift
        return np.array([w._internal(j, float(_number(w._units(j, v, shift), w.base)), shift)
                         for j, v in zip(w.cols, centre)])

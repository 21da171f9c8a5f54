"""A Heidenhain arc ``C`` that no one circle centre holds, written in pieces.

Where the corrected path of an arc leaves every circle about one centre by more than the chord
tolerance (a backlash's reversal at its start: the correction steps by the play there; a
correction that changes along it), the arc is cut into pieces as the G-code writer cuts a
G2/G3 block (:func:`~._arcs.plan_pieces`: from where the last piece ended, the longest arc that
holds, no micro-arcs where a longer one holds, a straight ``L`` only where no arc reaches the
next point). The source's ``C`` line is the first piece (its block number, feed and M functions
kept, its end point that of the piece); each later piece is a ``CC`` block with its centre and a
``C`` block with its end, the last ending where the source's arc ends as written. A piece's centre
is its own: the source's ``CC`` line takes the first piece's where that arc is the only one about
it; otherwise the first piece gets a ``CC`` block before it, and where later arcs use the source's
centre, a ``CC`` block restating it follows the pieces.

The blocks after an added one are renumbered: the TNC numbers a program's blocks in ascending
order (HEIDENHAIN, TNC 620 User's Manual, Klartext programming, 2017: "The control numbers the
blocks of a part program in ascending order"; TNC 320 User's Manual, 2014, "Opening programs and
entering"). A block keeps its number where it is still larger than the one before it (a program
numbered in steps of 10 takes the new blocks in its gaps), else it gets the next free one, with the
digits of its source number (leading zeros kept).
"""
from __future__ import annotations

import math
import re

import numpy as np

from ._arcs import (FULL_CIRCLE_TOL_MM, arc_misses, arc_sweep, fit_arc_centre, min_piece_length,
                    near_bound, piece_centre, plan_pieces, radius_refused)
from .heidenhain import signed

#: a rotary axis on an arc must stay within this of its written value (rad: 1e-4 deg)
ROTARY_ARC_TOL_RAD = math.radians(1e-4)
#: a Heidenhain block's number at the start of its line
_BLOCK_NUMBER = re.compile(r"^(\s*)(\d+)")


class _Piece:
    """A written piece: its end (na,) in the G-code frame (mm, rad), its centre (2,) or None for a
    straight piece, how far it misses the corrected path (mm)."""

    def __init__(self, end, centre, miss=0.0):
        self.end, self.centre, self.miss = end, centre, miss


class ArcPieces:
    """The pieces of one arc (``a``: a :class:`~.heidenhain_out._Arc`) written by ``w`` (a
    :class:`~.heidenhain_out.HeidenhainWriter`): :meth:`plan`, then :meth:`lines`."""

    def __init__(self, w, a, decimals: int):
        self.w, self.a, self.dec = w, a, decimals
        cols = list(w.cols)
        #: the written start, then the corrected points along the arc, and their nominal places
        self.samples = np.vstack([a.start_w[None, :], a.samples])
        self.nominal = np.vstack([a.block.start[None, :], a.nominal])
        self.u = np.concatenate([[0.0], a.u])
        step = np.diff(self.samples[:, w.linear], axis=0)
        self.length = np.concatenate([[0.0], np.cumsum(np.sqrt(np.sum(step * step, axis=1)))])
        self.radius = math.hypot(*(a.block.start[cols] - a.centre2))
        self.min_piece = min_piece_length(self.radius, w.tol)
        self.near = near_bound(self.samples, self.nominal, cols, w.tol)
        _a0, self.sweep = arc_sweep(a.block.start[cols], a.block.end[cols], a.centre2, a.ccw, False)

    def plan(self) -> list:
        return plan_pieces(self.arc_piece, self.straight, self.samples, self.length,
                           self.min_piece, 0, self.samples.shape[0] - 1, self.a.start_w)

    def _end(self, b: int, start_w: np.ndarray) -> np.ndarray:
        """Where a piece ending at sample b ends as written: the arc's written end for the last,
        else the sample's X Y rounded to the decimals written (the other axes as at its start)."""
        if b == self.samples.shape[0] - 1:
            return self.a.end_w.copy()
        w, info = self.w, self.w.tr.lines[self.a.line]
        end = start_w.copy()
        for j in w.cols:
            end[j] = w._internal(j, float(signed(w._units(j, self.samples[b, j], info.shift),
                                                 self.dec)), info.shift)
        return end

    def _centre(self, centre) -> np.ndarray:
        """A centre (2,) as a CC block writes it (rounded in the program's units)."""
        w, info = self.w, self.w.tr.lines[self.a.line]
        return np.array([w._internal(j, float(signed(w._units(j, v, info.shift), self.dec)),
                                     info.shift) for j, v in zip(w.cols, centre)])

    def straight(self, a: int, start_w: np.ndarray) -> _Piece:
        return _Piece(self._end(a + 1, start_w), None)

    def arc_piece(self, a: int, b: int, start_w: np.ndarray, near: bool = False):
        """The arc from start_w through samples a+1 .. b about one centre within the tolerance, or
        None (its centre as :func:`~._arcs.piece_centre` chooses it: the source's moved by the
        mean correction at the piece's ends, else the one nearest it that holds; within
        ``self.near`` of the source's where ``near``)."""
        cols = list(self.w.cols)
        end = self._end(b, start_w)
        s2, e2 = start_w[cols], end[cols]
        if math.hypot(*(e2 - s2)) <= FULL_CIRCLE_TOL_MM:
            return None
        # the source's centre moved by the mean correction of the points the piece goes through
        shift = np.mean(self.samples[a + 1:b + 1] - self.nominal[a + 1:b + 1], axis=0)
        shifted = self.a.centre2 + shift[cols]
        ra, rb = (math.hypot(*(self.nominal[k][cols] - self.a.centre2)) for k in (a, b))
        radius = 0.5 * (ra + rb)
        inner = self.samples[a + 1:b]
        fitted = fit_arc_centre(s2, e2, inner[:, cols], self.a.ccw, False, shifted, radius)
        span = (self.u[b] - self.u[a]) * self.sweep
        spiral = abs(rb - ra) + self.w.tol + 2.0 * 10.0 ** -self.dec * self.w.scale

        def holds(centre):
            c = self._centre(centre)
            miss = self._miss(start_w, end, c, inner, span, spiral)
            return None if miss is None else _Piece(end, c, miss)

        return piece_centre(holds, s2, e2, shifted, fitted,
                            max(self.w.tol, 10.0 ** -self.dec * self.w.scale), self.a.centre2,
                            self.near if near else math.inf)

    def _miss(self, start_w, end, centre, inner, span, spiral):
        """How far (mm) the arc start_w -> end about centre misses the corrected points inner, or
        None where that is more than the tolerance, a controller would refuse its radii, or it
        turns otherwise than the source's part it stands for (span, rad)."""
        a, cols = self.a, list(self.w.cols)
        r0, r1 = math.hypot(*(start_w[cols] - centre)), math.hypot(*(end[cols] - centre))
        if abs(r1 - r0) > spiral or radius_refused(r0, r1, self.w.scale != 1.0):
            return None
        _a0, sweep = arc_sweep(start_w[cols], end[cols], centre, a.ccw, False)
        if abs(sweep - span) > 0.25 * math.pi:
            return None
        dist, rot = arc_misses(start_w, end, centre, tuple(cols), a.ccw, False, inner,
                               self.w.linear)
        return dist if dist <= self.w.tol and rot <= ROTARY_ARC_TOL_RAD else None

    def words(self, p: np.ndarray) -> str:
        """``X.. Y..`` of a point (2,) or (na,) in the G-code frame, as this arc's blocks write
        them."""
        w, info = self.w, self.w.tr.lines[self.a.line]
        v = p[list(w.cols)] if p.shape[0] == w.na else p
        return " ".join(f"{c}{signed(w._units(j, x, info.shift), self.dec)}"
                        for c, j, x in zip("XY", w.cols, v))

    def later_lines(self, pieces: list) -> list[str]:
        """The blocks (without their numbers) of the pieces after the first."""
        out = []
        direction = "DR+" if self.a.ccw else "DR-"
        for p in pieces[1:]:
            if p.centre is None:
                out.append(f"L {self.words(p.end)}")
            else:
                out += [f"CC {self.words(p.centre)}", f"C {self.words(p.end)} {direction}"]
        return out


def renumbered(texts: list[str], before: dict, after: dict) -> str:
    """The program's lines ``texts`` (with their endings) with the blocks ``before`` / ``after``
    each line index (lists of block texts without number) put in, numbered (see the module
    docstring)."""
    out, last, moved = [], -1, False
    for i, text in enumerate(texts):
        ending = text[len(text.rstrip("\r\n")):] or "\n"
        for body in before.get(i, []):
            last, moved = last + 1, True
            out.append(f"{last} {body}{ending}")
        m = _BLOCK_NUMBER.match(text)
        if m is not None:
            n = int(m.group(2))
            if moved and n <= last:
                digits = m.group(2)
                n = last + 1
                new = str(n).zfill(len(digits)) if digits.startswith("0") and len(digits) > 1 \
                    else str(n)
                text = m.group(1) + new + text[m.end():]
            last = n
        out.append(text)
        for body in after.get(i, []):
            last, moved = last + 1, True
            out.append(f"{last} {body}{ending}")
    return "".join(out)

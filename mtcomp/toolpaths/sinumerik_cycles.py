"""The drilling cycles and hole patterns of a Siemens Sinumerik program, and the calls of
subprograms mtcomp cannot see: the part of :mod:`.sinumerik`'s reader that turns a call into the
moves the controller makes for it.

The rules are those of Siemens AG, SINUMERIK 840D sl / 828D Cycles, Programming Manual (2013) for
CYCLE81 to CYCLE89 and the hole patterns HOLES1 and HOLES2, and of the SINUMERIK 840D sl
Programming Manual, Job planning (2013) for subprograms (the SAVE mechanism).
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

from .sinumerik_lang import AXES, Word, fmt, split_arguments

#: the drilling cycles read: their moves are a hole from RFP+SDIS to the depth, back to RTP. They
#: share CYCLE81's first five parameters (RTP, RFP, SDIS, DP, DPR) and its hole; what else they do
#: (pecks, dwells, the spindle stopped, a lift-off at the bottom, the way out) keeps the hole where
#: it is (Cycles manual, 2013)
_DRILLING = {f"CYCLE8{n}" for n in range(1, 10)}
#: the hole patterns read under a modal call: their arguments
_PATTERNS = {"HOLES1": ("SPCA", "SPCO", "STA1", "FDIS", "DBH", "NUM"),
             "HOLES2": ("CPA", "CPO", "RAD", "STA1", "INDA", "NUM")}


@dataclass
class Call:
    """A drilling cycle call: its line (0-based), name, argument texts and where they stand in
    the line (start, end), whether modal (MCALL), the levels RTP, RFP, SDIS and the hole's
    bottom (mm), and its holes (G-code line indices)."""

    line: int
    name: str
    args: list
    spans: list
    modal: bool
    rtp: float
    rfp: float
    sdis: float
    bottom: float
    holes: list = field(default_factory=list)


@dataclass
class Pattern:
    """A hole pattern (HOLES1 a row, HOLES2 a circle): its line, the argument texts and spans, its
    holes' positions, its reference point (the first two arguments)."""

    line: int
    name: str
    args: list
    spans: list
    positions: list
    centre: tuple = (0.0, 0.0)
    motion: int | None = 0
    holes: list = field(default_factory=list)


class CycleCalls:
    """The calls of :class:`~.sinumerik._Reader` (a mixin: the reader's state, ``err``, ``value``
    and ``emit`` are its own)."""

    def _call(self, w: Word) -> None:
        if w.kind == "address":                 # L54: a subprogram not in the file
            self._unknown(f"L{w.text}")
        elif w.name in _DRILLING:
            call = self._drilling(w, modal=False)
            self._hole(call, self.pos["X"], self.pos["Y"], None)
        elif w.name in _PATTERNS:
            self._pattern(w)
        else:
            if w.name == "CYCLE800":
                self._swivel(w)
            self._unknown(w.name)

    def _swivel(self, w: Word) -> None:
        """CYCLE800 (_FR, _TC, _ST, _MODE, _X0, _Y0, _Z0, _A, _B, _C, _X1, _Y1, _Z1, _DIR, ...):
        the swivel cycle leaves a frame turned by its angles and shifted by its offsets (SINUMERIK
        840D sl Cycles programming manual, CYCLE800), in which the program's next positions are
        given; mtcomp does not follow that frame, so a CYCLE800 with any angle or offset other
        than 0 is refused. ``CYCLE800()`` and one whose offsets and angles are all 0 cancel the
        swivel: the positions after it are unknown until named, as after any cycle."""
        args = split_arguments(w.text)
        for i, a in enumerate(args[4:13], 4):
            if a.strip() and self.value(a) != 0.0:
                raise self.err("CYCLE800 with a rotation or an offset (a swivelled frame) is not "
                               "read by mtcomp")

    def _unknown(self, name: str) -> None:
        """A subprogram the program does not hold: the controller runs it, mtcomp cannot see its
        moves: every position and every R parameter is unknown after it (the modes are taken as
        the subprogram leaves them, restored: SAVE)."""
        self.out.subprograms.append((self.k, name))
        self.pos = dict.fromkeys(AXES)
        for key in list(self.vars):
            if re.fullmatch(r"R\d+", key):
                self.vars[key] = None
        self.r_lost = True
        self.emit("G43.1")

    def _mcall(self, calls, axes) -> None:
        if axes or len(calls) > 1:
            raise self.err("MCALL with a move or more than one call is not read by mtcomp")
        if not calls:
            self.modal_call = None
            return
        w = calls[0]
        if w.kind == "address" or w.name not in _DRILLING:
            self.modal_call = w.name if w.kind == "call" else f"L{w.text}"
            return
        self.modal_call = self._drilling(w, modal=True)

    def _drilling(self, w: Word, modal: bool) -> Call:
        """CYCLE81 ... CYCLE89 (RTP, RFP, SDIS, DP, DPR, ...): the levels of its holes."""
        args = split_arguments(w.text)
        spans = _spans(w, args)
        names = ("RTP", "RFP", "SDIS", "DP", "DPR")
        vals = [self.value(a) if i < len(args) and args[i] else None for i, a in
                enumerate(args[:5] + [""] * (5 - len(args[:5])))]
        rtp, rfp, sdis, dp, dpr = vals
        missing = [n for n, v in zip(names[:2], (rtp, rfp)) if v is None]
        if missing or (dp is None and dpr is None):
            raise self.err(f"{w.name} without {', '.join(missing) or 'DP or DPR'}")
        bottom = rfp - abs(dpr) if dpr is not None else dp
        sdis = abs(sdis or 0.0)
        if not rtp >= rfp + sdis > bottom:
            raise self.err(f"{w.name} whose levels are not RTP >= RFP+SDIS > depth (drilling "
                           "down along Z) is not read by mtcomp")
        if self.plane != 17:
            raise self.err(f"{w.name} outside the G17 plane is not read by mtcomp")
        if w.name == "CYCLE83" and len(args) > 12 and args[12] \
                and self.value(args[12]) in (1.0, 2.0):
            raise self.err("CYCLE83 drilling along another axis than Z (_AXN) is not read by mtcomp")
        call = Call(self.k, w.name, args, spans, modal, rtp, rfp, sdis, bottom)
        self.out.calls.append(call)
        return call

    def _modal_hole(self, line: str, axes: dict) -> None:
        """A positioning block under MCALL of a drilling cycle: its move, then the hole."""
        call = self.modal_call
        if set(axes) - {"X", "Y"}:
            self.emit(line, "approach")
        self._hole(call, self.pos["X"], self.pos["Y"], None)

    def _hole(self, call: Call, x, y, pattern) -> None:
        if x is None or y is None:
            raise self.err(f"a hole of {call.name} at a position the program has not given")
        dx, dy, dz = self.shift
        g = (f"G99 G81 X{fmt(x + dx)} Y{fmt(y + dy)} R{fmt(call.rfp + call.sdis + dz)} "
             f"Z{fmt(call.bottom + dz)}")
        self.emit(g, "hole", call=call, pattern=pattern)
        call.holes.append(len(self.out.gcode) - 1)
        if pattern is not None:
            pattern.holes.append(len(self.out.gcode) - 1)
        self.emit("G80")
        self.emit(f"G0 Z{fmt(call.rtp + dz)}", "retract")
        if self.motion not in (0, None):
            self.emit(f"G{self.motion}")
        self.pos.update({"X": x, "Y": y, "Z": call.rtp})

    def _pattern(self, w: Word) -> None:
        """HOLES1(SPCA, SPCO, STA1, FDIS, DBH, NUM): NUM holes on a line from (SPCA, SPCO) at the
        angle STA1 from X, the first FDIS from it, the next DBH further; HOLES2(CPA, CPO, RAD,
        STA1, INDA, NUM): NUM holes on a circle about (CPA, CPO) of radius RAD, the first at the
        angle STA1 from X, the next INDA further (0: evenly). The modal call runs at each."""
        names = _PATTERNS[w.name]
        if self.modal_call is None:
            raise self.err(f"{w.name} without a modal call (MCALL) is not read by mtcomp")
        args = split_arguments(w.text)
        if len(args) != 6 or not all(args):
            raise self.err(f"{w.name} needs its six values {', '.join(names)}")
        x0, y0, a, b, c, num = (self.value(t) for t in args)
        n = int(round(num))
        if n < 1 or n != num:
            raise self.err(f"{w.name} with a number of holes NUM that is not a positive integer")
        if not isinstance(self.modal_call, Call):
            # a cycle mtcomp does not read runs at each position: passed through uncorrected
            self._unknown(self.modal_call)
            return
        if w.name == "HOLES1":          # a, b, c: STA1, FDIS, DBH
            d = [b + i * c for i in range(n)]
            positions = [(x0 + t * math.cos(math.radians(a)), y0 + t * math.sin(math.radians(a)))
                         for t in d]
        else:                           # a, b, c: RAD, STA1, INDA
            step = 360.0 / n if c == 0 else c
            positions = [(x0 + a * math.cos(math.radians(b + i * step)),
                          y0 + a * math.sin(math.radians(b + i * step))) for i in range(n)]
        spans = _spans(w, args)
        if not spans:
            raise self.err(f"{w.name} with a comma inside an argument's parentheses is not read by "
                           "mtcomp (give the value as a variable or a number)")
        pattern = Pattern(self.k, w.name, args, spans, positions, (x0, y0), self.motion)
        self.out.patterns.append(pattern)
        for x, y in positions:
            self._hole(self.modal_call, x, y, pattern)


def _spans(w: Word, args: list) -> list:
    """[(start, end)] of each argument's text of the call ``w`` on its line, [] when a comma sits
    inside an argument's parentheses (its arguments cannot be edited in place)."""
    spans, pos = [], w.start
    for part in w.text.split(","):
        spans.append((pos, pos + len(part)))
        pos += len(part) + 1
    return spans if len(spans) == len(args) else []

"""A Sinumerik helix with additional full turns (``G2/G3 ... TURN=n``) written back corrected.

The reader (:mod:`.sinumerik`) gives such a circle to the planner as pieces of half a turn from its
start's angle (the last one the circle's own part). Each piece is corrected as any circle of
:mod:`.sinumerik_out` is (its end point, its Z, its centre, within the chord tolerance of its
corrected path; in pieces of its own where one centre does not hold), written here first as
``X.. Y.. Z.. I=AC(..) J=AC(..)``. Where every piece (and the helix's start as written before it)
comes out as the nominal one moved by one same translation, the source line is kept with
``TURN=`` and its end point and absolute centre moved by it: that helix is exactly the pieces'.
Otherwise (the correction changes along the turns, as it does over a thread's depth) the line is
written as the pieces: the first on the source line (its other words kept, ``TURN=`` taken out),
the others after it, and the line after the file header counts them among the blocks added.
"""
from __future__ import annotations

import dataclasses
import re

import numpy as np

from .sinumerik_lang import corrected_text, edit_text, number_text

_VALUE = re.compile(r"([XYZ])(-?\d+\.?\d*)|([IJ])=AC\((-?\d+\.?\d*)\)")


@dataclasses.dataclass
class _Helix:
    """The helix being written: its source line's text, the output's position before it (na,) and
    the nominal one (na,), and per piece (the piece's text as planned, its written lines)."""

    source: str
    start: np.ndarray
    nominal: np.ndarray
    pieces: list = dataclasses.field(default_factory=list)


def _values(text: str) -> dict:
    """The numbers of a piece's line: X Y Z and the absolute centre I J."""
    out = {}
    for m in _VALUE.finditer(text):
        out[m.group(1) or m.group(3)] = float(m.group(2) or m.group(4))
    return out


class HelixTurns:
    """The helices with TURN= of :class:`~.sinumerik_out.SinumerikWriter` (a mixin: the
    writer's words, units and circles are its own)."""

    helix: _Helix | None = None
    turn_split = 0

    def _turn_piece(self, i: int, block, pts, info) -> None:
        """Piece ``info.turn`` of the helix of source line i: corrected as a circle about an
        absolute centre; the last one settles the line (see the module docstring)."""
        k, m = info.turn
        if k == 0:
            self.helix = _Helix(self.texts[i], self.written.copy(), block.start.copy())
        h = self.helix
        ending = h.source[len(h.source.rstrip("\r\n")):]
        planned = self._piece_text(block, info)
        self.texts[i] = planned + ending
        self._arc(i, block, pts, None, dataclasses.replace(info, radius=None))
        lines = self.replaced.pop(i, None) or [self.texts[i].rstrip("\r\n")]
        h.pieces.append((planned, lines))
        self.texts[i] = h.source
        if k == m - 1:
            self._settle_helix(i, block, info)

    def _piece_text(self, block, info) -> str:
        """``X.. Y.. [Z..] I=AC(..) J=AC(..)``: the nominal piece in the program's units and frame
        (Z where the helix moves it)."""
        words = []
        for a in "XYZ":
            j = self.letters.index(a)
            if a != "Z" or abs(block.end[j] - block.start[j]) > 1e-9:
                words.append(f"{a}{self._text(self._units(j, block.end[j], info.shift))}")
        for k, c in enumerate("IJ"):
            v = block.centre[k] / self.scale - info.shift[k]
            words.append(f"{c}=AC({self._text(v)})")
        return " ".join(words)

    def _shift(self, planned: str, written: str) -> dict | None:
        """Letter -> how far (program units, at the written decimals) the written piece stands
        from the planned one (the centre's I J as 'Xc', 'Yc'); None where the written piece names
        other axes (a Z its corrected path moves on a flat circle)."""
        a, b = _values(planned), _values(written)
        if a.keys() != b.keys():
            return None
        return {{"I": "Xc", "J": "Yc"}.get(c, c): round(b[c] - a[c], self.base + 1) for c in a}

    def _settle_helix(self, i: int, block, info) -> None:
        h = self.helix
        shifts = [self._shift(p, lines[0]) for p, lines in h.pieces]
        # how far the helix's start as written stands from the nominal one
        first = {a: round(self._units(j, h.start[j], info.shift)
                          - self._units(j, h.nominal[j], info.shift), self.base + 1)
                 for a, j in ((a, self.letters.index(a)) for a in "XYZ") if h.start[j] == h.start[j]}
        d = shifts[0]
        one = d is not None and all(len(lines) == 1 for _p, lines in h.pieces) and \
            all(s == d for s in shifts)
        if one and "Z" not in d:              # a flat circle: Z stays where it was written
            d = dict(d, Z=first.get("Z", 0.0))
        if one and d["Xc"] == d["X"] and d["Yc"] == d["Y"] and first == {a: d[a] for a in first}:
            self.texts[i] = self._moved_helix(i, block, info, d)
            return
        lines = [line for _p, piece in h.pieces for line in piece]
        z = self.letters.index("Z")
        start_z = self._text(self._units(z, h.start[z], info.shift)) if "Z" in first else None
        lines[0] = self._first_of_helix(h.source.rstrip("\r\n"), lines[0], start_z)
        self.replaced[i] = lines
        self.added += len(lines) - 1
        self.turn_split += 1

    def _moved_helix(self, i: int, block, info, d: dict) -> str:
        """The source line with its end point and absolute centre moved by ``d`` (letter ->
        program units); an incremental centre and a radius CR= stay as written."""
        text = self.helix.source.rstrip("\r\n")
        edits = []
        for w in self._words(text):
            if w.kind not in ("address", "assign") or w.name not in ("X", "Y", "Z", "I", "J"):
                continue
            a, b = w.start, w.end
            if w.name in "IJ":
                if not (w.kind == "assign" and w.text.strip().upper().startswith("AC")):
                    continue
                a, b = w.start + w.text.find("(") + 1, w.start + w.text.rfind(")")
                k = "IJ".index(w.name)
                nominal = block.centre[k] / self.scale - info.shift[k]
                delta = d["X" if w.name == "I" else "Y"]
            else:
                j = self.letters.index(w.name)
                nominal, delta = self._units(j, block.end[j], info.shift), d.get(w.name, 0.0)
            t = corrected_text(text[a:b], nominal, nominal + delta, self.base)[0]
            if t != text[a:b]:
                edits.append((a, b, t))
        return edit_text(text, edits) + self.helix.source[len(text):]

    def _first_of_helix(self, text: str, piece: str, start_z: str | None) -> str:
        """The source line (``TURN=`` taken out) with the first piece's end point and centre; a
        Z word of a flat circle (the piece names none) says the Z written before it,
        ``start_z``."""
        turn = next(w for w in self._words(text) if w.kind == "assign" and w.name == "TURN")
        at = self._word_start(text, turn)
        text = text[:at].rstrip(" \t") + text[turn.end:] if text[:at].strip() else \
            text[:at] + text[turn.end:].lstrip(" \t")
        named = {w.name: w for w in self._words(text) if w.kind in ("address", "assign")}
        words = {m.group(1): m.group(2) for m in re.finditer(r"([XYZ])(-?\d+\.?\d*)", piece)}
        if "Z" in named and "Z" not in words and start_z is not None:
            words["Z"] = start_z
        ij = re.findall(r"[IJ]=AC\([^)]*\)", piece)
        return self._first_piece(text, named, words, ij)

    def _text(self, v: float) -> str:
        return number_text(v, self.base)


def turn_notes(w) -> list[str]:
    """What the summary says of the helices with TURN= written as pieces."""
    if not w.turn_split:
        return []
    n = w.turn_split
    return [f"{n} helix{'es' if n != 1 else ''} with additional turns (TURN=) written as pieces "
            "of half a turn at most (G2/G3 each, I=AC J=AC): the correction changes along the "
            "turns, which one helix with TURN= cannot follow"]


"""Heidenhain TNC programs in DIN/ISO (``.i``): read as the motion mtcomp knows.

The TNC's second programming language (HEIDENHAIN, iTNC 530 User's Manual, ISO programming,
2004-2010; TNC 640 User's Manual, DIN/ISO programming) is read as the conversational one is
(:mod:`.heidenhain`): line for line into G-code, the state carried by the same reader, and the
corrected program written back in its own form by :mod:`.heidenhain_out` (the numbers that carry a
correction changed, every other byte kept). The rules followed:

* the first block ``%NAME G71 *`` (``G70``: inch), the last ``N99999999 %NAME G71 *``; every
  block ends in ``*`` (a blank before it or not), ``;`` starts a comment;
* ``G00`` rapid, ``G01`` straight line, ``G02`` / ``G03`` clockwise / counter-clockwise arc about
  the circle centre in force (all modal); ``G90`` / ``G91`` absolute / incremental coordinates
  (modal); ``G40`` / ``G41`` / ``G42`` radius compensation, switched on a straight line;
* ``I J``: the circle centre (absolute, modal: as conversational ``CC``; "Circle center I, J", the
  only effect of I and J is to define a position as a circle centre: the tool does not move);
* ``T n G17 S..``: a tool call (tool axis Z); ``G99 T.. L.. R..`` tool definition, ``G30`` /
  ``G31`` blank form, ``G38`` stop, ``S``, ``F`` (modal) and M functions make no move;
  ``M91`` / ``M92`` machine positions as in conversational programs.

Everything else is refused in one line naming it: other G functions (polar coordinates, ``G05``,
``G06``, ``G24``/``G25``, approach and departure, ``G29``, cycles, coordinate transformations,
labels ``G98 L``), ``K`` and incremental circle centres, Q parameters and ``D`` functions, ``M99``
and the TNC's other path functions ``M89``, ``M90`` and up. ``M128`` ... ``M129``, the tool centre
point mode, is read as in a conversational program (:mod:`.heidenhain_tcp`; TNC 620 User's Manual
for DIN/ISO programming, 2013, "Maintaining the position of the tool tip when positioning with
tilted axes (TCPM): M128"): a ``T`` block is its TOOL CALL, ``G02``/``G03`` and ``I J`` its arcs
and circle centre, ``G41``/``G42`` its radius compensation RL/RR, refused in the mode.
"""
from __future__ import annotations

import re

from .heidenhain import AXES, ISO_BEGIN, LineInfo, Translation, _fmt, _num, _Reader, read_lines
from .heidenhain import translate as translate_conversational

#: an address word of a block: its letter and a signed number
_TOKEN = re.compile(r"([A-Z])\s*([+-]?\s*(?:\d+\.?\d*|\.\d+))")
_NUMBERED = re.compile(r"^N\s*(\d+)\s*")
#: the G functions read: motion, plane, radius compensation, absolute / incremental, and those
#: that make no move (blank form, stop, tool definition)
_READ_G = {0, 1, 2, 3, 17, 30, 31, 38, 40, 41, 42, 90, 91, 99}
_NAMED_G = {5: "a circle without a direction of rotation (G05)",
            6: "a circle with tangential connection (G06)", 7: "a paraxial positioning block (G07)",
            10: "polar coordinates", 11: "polar coordinates", 12: "polar coordinates",
            13: "polar coordinates", 15: "polar coordinates", 16: "polar coordinates",
            18: "a working plane other than XY (G18)", 19: "a working plane other than XY (G19)",
            24: "a chamfer (G24)", 25: "a rounding (G25)", 26: "a tangential approach (G26)",
            27: "a tangential departure (G27)", 28: "a mirror image (G28)",
            29: "the last position as the circle centre (G29)", 53: "a datum shift (G53)",
            54: "a datum shift (G54)", 70: "a change of units (G70)", 71: "a change of units (G71)",
            72: "a scaling factor (G72)", 73: "a rotation (G73)", 79: "a cycle call (G79)",
            80: "a tilted working plane (G80)", 98: "a label (G98)"}
_NAMED_LETTERS = {"Q": "Q parameters", "D": "a Q parameter function (D)",
                  "L": "a label or call (L)", "R": "a radius (R)", "P": "a P word",
                  "K": "a circle centre K (only I J in the XY plane are read)",
                  "H": "an H word", "U": "the parallel axis U", "V": "the parallel axis V",
                  "W": "the parallel axis W"}
_COMP = {40: "R0", 41: "RL", 42: "RR"}


class IsoReader(_Reader):
    """The state a DIN/ISO program carries from line to line (see the module docstring)."""

    LANGUAGE, ARC, CENTRE = "Heidenhain DIN/ISO", "G02/G03", "I J"
    TOOL = "tool call T"

    def __init__(self, path):
        super().__init__(path)
        self.motion = None                       # G00 ... G03 in force
        self.incremental = False                 # G91 in force
        self.ended = False

    def refuse(self, what: str, k: int):
        return self.err(f"{what} is not read by mtcomp ({self.LANGUAGE})", k)

    def _line(self, k: int, text: str) -> tuple[str, LineInfo]:
        """(G-code, info) of source line k (0-based), before the mode's M129 is carried
        (:meth:`_Reader.line`)."""
        info = LineInfo()
        body = text.split(";", 1)[0].strip().upper()
        numbered = _NUMBERED.match(body)
        self.current = (k, f"N{numbered.group(1)}" if numbered else "")
        if not body:
            return "", info
        if self.ended:
            raise self.err("a block after the program's end block (N99999999 %NAME G71 *)", k)
        begin = ISO_BEGIN.match(body)
        if not self.started:
            if begin is None:
                raise self.err("a Heidenhain DIN/ISO program starts with %NAME G71 * (G70: "
                               f"inch), not {body[:40]!r}", k)
            self.started, self.out.inch = True, begin.group(2) == "0"
            return ("G20" if self.out.inch else "G21"), info
        if begin is not None:
            if (begin.group(2) == "0") != self.out.inch:
                raise self.err("the end block's units (G70/G71) are not the first block's", k)
            self.ended = True
            return "", info
        code = body[numbered.end():] if numbered else body
        code = code[:-1].rstrip() if code.endswith("*") else code
        return self._block(self._tokens(code, k), k, info)

    def _tokens(self, code: str, k: int) -> list:
        if re.search(r"Q\s*\d", code):
            raise self.refuse("Q parameters", k)
        left = _TOKEN.sub(" ", code).strip()
        if left:
            raise self.refuse(repr(left[:30]), k)
        return [(m.group(1), m.group(2)) for m in _TOKEN.finditer(code)]

    def _g_codes(self, tokens: list, k: int) -> set:
        """The block's G functions, each checked (see the module docstring)."""
        out = set()
        for letter, value in tokens:
            if letter != "G":
                continue
            g = _num(value)
            if g != int(g) or int(g) not in _READ_G:
                what = _NAMED_G.get(int(g)) if g == int(g) else None
                raise self.refuse(what or (f"G{value}" if g < 200 else f"the cycle G{value}"), k)
            out.add(int(g))
        for group in ((0, 1, 2, 3), (40, 41, 42), (90, 91)):
            if len(out.intersection(group)) > 1:
                raise self.err(f"two G functions of one group ({sorted(out.intersection(group))}) "
                               "in one block", k)
        return out

    def _block(self, tokens: list, k: int, info: LineInfo) -> tuple[str, LineInfo]:
        g = self._g_codes(tokens, k)
        if g & {30, 31, 38, 99}:               # blank form, stop, tool definition: no move
            return "", info
        letters = {letter for letter, _v in tokens}
        for letter in sorted(letters - set("GMXYZABCIJFST")):
            raise self.refuse(_NAMED_LETTERS.get(letter, f"the word {letter}"), k)
        self.incremental = (self.incremental or 91 in g) and 90 not in g
        words, centre = {}, {}
        for letter, value in tokens:
            into = centre if letter in "IJ" else words if letter in "XYZABC" else None
            if into is not None:
                if letter in into:
                    raise self.err(f"{letter} twice in one block", k)
                into[letter] = (_num(value), self.incremental)
        mcodes = self._mcodes(" ".join("M" + v for letter, v in tokens if letter == "M"), k)
        if 99 in mcodes:
            raise self.refuse("M99", k)
        self.motion = next((c for c in (0, 1, 2, 3) if c in g), self.motion)
        switch = self._tcp(letters, g, words, centre, mcodes, k)
        if "T" in letters:
            return self._tool_call(tokens, g, words or centre, k), info
        feed = next((_num(v) for letter, v in tokens if letter == "F"), None)
        if centre:
            return self._centre(centre, words, k, info)
        arc = self.motion in (2, 3)
        comp = self._comp(g, k, arc and bool(words))
        if not words:
            if 91 in mcodes or 92 in mcodes:
                raise self.err("M91 or M92 without a straight move G00/G01", k)
            return (comp + ("" if feed is None else f"F{_fmt(feed)}")).strip(), info
        machine = 91 in mcodes or 92 in mcodes
        if self.motion is None and not machine:
            raise self.err("axis words without G00, G01, G02 or G03 in force", k)
        if not arc:
            # M91/M92 before any path function (`N70 G90 Z-25. M91 *`, a post's first block): a
            # straight move to machine positions whether the TNC takes it at rapid or at the feed,
            # passed through as G53 moves are, the path function still not in force after it
            gcode, info = self.move_gcode(words, self.motion in (0, None), feed, mcodes, k, info)
        elif set(words) - set("XY") or 91 in mcodes or 92 in mcodes:
            raise self.refuse("an arc G02/G03 with other axes than X Y (a helix) or M91/M92", k)
        else:
            gcode, info = self.arc_gcode(words, self.motion == 3, feed, k, info)
        if self.incremental:                  # every word of a G91 block, added ones too
            info.incremental = frozenset(AXES)
        return (switch + comp + gcode).strip(), info

    def _tcp(self, letters: set, g: set, words: dict, centre: dict, mcodes: list, k: int) -> str:
        """The block read by the tool centre point mode's rules (M128 ... M129, as in a
        conversational program: :class:`~.heidenhain_tcp.TcpMode`): a T block is a TOOL CALL, an
        arc G02/G03 or a centre I J the conversational C or CC, G41/G42 radius compensation RL/RR;
        the G-code word that switches the mode, followed by a blank, or ''."""
        name = ("TOOL CALL" if "T" in letters else "CC" if centre else
                "C" if words and self.motion in (2, 3) else "L" if words else "M")
        rest = " ".join(f"M{c}" for c in mcodes) + (" RL" if g & {41, 42} else "")
        return self.tcp_block(name, rest, k)

    def _comp(self, g: set, k: int, arc: bool) -> str:
        """The G-code word of the block's radius compensation where it changes the one in force,
        followed by a blank, else ''; an arc may only repeat it."""
        code = next((c for c in (40, 41, 42) if c in g), None)
        if code is None or _COMP[code] == self.radius_comp:
            return ""
        if arc:
            raise self.err(f"radius compensation G{code} switched on an arc G02/G03 is not read "
                           "by mtcomp (switch it on a straight line G01)", k)
        self.radius_comp = _COMP[code]
        return f"G{code} "

    def _centre(self, centre: dict, words: dict, k: int, info: LineInfo) -> tuple[str, LineInfo]:
        if words or set(centre) != {"I", "J"} or self.incremental:
            raise self.err("a circle centre needs absolute I and J in a block of its own (an "
                           "incremental centre, one with a move or without both is not read)", k)
        self.cc = (centre["I"][0], centre["J"][0], k)
        info.kind, info.centre = "CC", self.cc[:2]
        return "", info

    def _tool_call(self, tokens: list, g: set, moves: dict, k: int) -> str:
        value = next(v for letter, v in tokens if letter == "T")
        if moves or _num(value) != int(_num(value)) or g - {17, 40, 90, 91}:
            raise self.err("a tool call T with a move or other G functions than G17 is not "
                           "read", k)
        n = int(_num(value))
        self.pos["Z"] = None
        return f"T{n} M6 G43 H{n}"



def translate(path) -> Translation:
    """A Heidenhain program at ``path`` as G-code: DIN/ISO where its first block is ``%NAME G71 *``
    (:class:`IsoReader`), else conversational (:func:`.heidenhain.translate`)."""
    first = next((r for r in read_lines(path) if r.strip()), b"")
    if not ISO_BEGIN.match(first.decode("latin-1").lstrip("\ufeff")):
        return translate_conversational(path)
    reader = IsoReader(path)
    reader.out.iso = True
    return translate_conversational(path, reader)

"""Heidenhain TNC conversational programs (Klartext, ``.h``): read as the motion mtcomp knows.

A conversational program is turned, line for line, into equivalent G-code that mtcomp's reader
reads (one G-code line per source line, so every line keeps its number); the corrected program
is written back in the conversational form by :mod:`.heidenhain_out`. The rules followed are those
of HEIDENHAIN's user's manuals for conversational programming (iTNC 530, HEIDENHAIN 2004-2010;
TNC 640, HEIDENHAIN 2015-2022; TNC 370, HEIDENHAIN 1995 for the direction of rotation):

* ``BEGIN PGM name MM|INCH``: the program's units; ``END PGM``, ``BLK FORM``, ``TOOL DEF``, ``;``
  and ``*`` comments, ``STOP`` and lines of M functions alone make no move. A line that starts
  with ``;`` is a comment with or without its block number (the TNC numbers the blocks itself).
* ``L``: a straight move to the given coordinates (``IX`` ... incremental from the last
  programmed position); ``FMAX`` rapid in that block only, ``F..`` a feed that stays.
  ``M91``/``M92``: the coordinates are machine positions (as G53: passed through, those axes
  unknown afterwards).
* ``RL`` / ``RR`` on an ``L`` block: tool radius compensation, the tool left / right of the
  contour in the direction of travel, in force from that block until an ``L`` block with ``R0``
  (TNC 640 User's Manual, "Tool radius compensation"); read as G41 / G42 and G40, so the blocks
  carry it as G-code's do. A ``C`` block may repeat the compensation in force; one that changes it
  is refused (switch it on a straight line ``L``).
* ``CC X Y``: the circle centre (modal); ``C X Y DR+`` / ``DR-``: an arc about it to the end point,
  counter-clockwise / clockwise (``C DR-`` without coordinates, or ending at its start: a full
  circle). ``CR X Y R.. DR+``: an arc by its radius (R > 0 at most 180 degrees, R < 0 more),
  about the centre that makes; one ending at its start is refused (no radius places its centre).
* ``TOOL CALL n Z``: a tool change (as ``T n M6 G43 H n``: the tool length of H n, Z unknown).
* ``CYCL DEF 7`` datum shift: the program's coordinates are shifted by it from then on (relative
  to the workpiece datum, ``IX`` relative to the last shift); read here as positions in the
  workpiece datum's frame (the G-code gets coordinate plus shift).
* ``CYCL DEF 1`` pecking, called by ``M99`` on an ``L FMAX`` line: a hole from the
  tool's position (its set-up clearance above the surface) to the depth, back to that position
  (as a G99 G81 cycle with R at the start level and Z at the bottom). ``CYCL DEF 9`` dwell.

A program whose first block is ``%NAME G71 *`` is the TNC's DIN/ISO language, read by this
reader's :class:`~.heidenhain_iso.IsoReader` (:func:`.heidenhain_iso.translate` reads either).

Everything else is refused in one line naming the construct: other cycles, ``CT``/polar and FK contours, ``RND``/``CHF``, ``APPR``/``DEP``, ``LBL`` and
``CALL``, ``CYCL CALL``, ``FN`` and Q parameters, ``PLANE``, incremental or empty ``CC``, the TNC's path functions
``M89`` and ``M90`` and up (but M91, M92, M99), tools by name, ``DL`` deltas, other tool axes.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field

from ..errors import InputError
from .heidenhain_tcp import TcpMode
from .sinumerik_paths import RadiusError, radius_centre
from .words import MM_PER_INCH

AXES = "XYZABC"
_BLOCK = re.compile(r"^\s*(\d+)\s*(.*?)\s*$")
#: an axis word of a block: optional I (incremental), the letter, blanks, a signed number
WORD = re.compile(r"(?<![A-Z])(I?)([XYZABC])(\s*)([+-]?\s*(?:\d+\.?\d*|\.\d+))")
_NUMBER = r"[+-]?\s*(?:\d+\.?\d*|\.\d+)"
_KEYWORD = re.compile(r"^(BEGIN PGM|END PGM|BLK FORM|TOOL DEF|TOOL CALL|CYCLE? DEF|CYCL CALL|"
                      r"CC|CR|CTP|CT|CP|C|LP|LN|L|STOP|M)(?![A-Z])")
#: keywords of constructs refused by name, and what they are
_REFUSED = {"CT": "a tangential arc (CT)",
            "CP": "a polar arc (CP)", "CTP": "a polar tangential arc (CTP)",
            "LP": "a polar straight line (LP)", "LN": "a straight line with a normal vector (LN)",
            "RND": "a rounding (RND)", "CHF": "a chamfer (CHF)", "APPR": "an approach (APPR)",
            "DEP": "a departure (DEP)", "FL": "an FK free contour", "FLT": "an FK free contour",
            "FC": "an FK free contour", "FCT": "an FK free contour", "FPOL": "an FK pole (FPOL)",
            "LBL": "a label (LBL)", "CALL": "a subprogram or program call (CALL)",
            "FN": "a Q parameter function (FN)", "PLANE": "a tilted working plane (PLANE)",
            "TCH": "a touch probe cycle (TCH PROBE)", "TRANS": "a coordinate transformation",
            "SEL": "a program selection (SEL)", "Q": "Q parameters", "SPL": "a spline (SPL)",
            "CYCL CALL": "CYCL CALL (the hole's position is not in the block: call the cycle "
                         "with M99 on its positioning block L)"}
_CYCLES = {1: "PECKING", 7: "DATUM SHIFT", 9: "DWELL TIME"}
#: the first block of a TNC DIN/ISO program: ``%NAME G71 *`` (G70: inch), also numbered
ISO_BEGIN = re.compile(r"(?i)^\s*(?:N\s*\d+\s*)?%\s*(\S+)\s+G\s*7([01])\s*\*?\s*(?:;.*)?$")
#: the radius R of a CR block (signed; not the radius compensation R0)
CR_RADIUS = re.compile(r"(?<![A-Z])R\s*([+-]\s*(?:\d+\.?\d*|\.\d+)|\d*\.\d+|\d+\.|[1-9]\d*)"
                       r"(?![\dA-Z])")
#: radius compensation word -> the G code that says the same (G40 off, G41 left, G42 right)
_RADIUS_COMP = {"R0": 40, "RL": 41, "RR": 42}


@dataclass
class LineInfo:
    """What a source line is, for the writer: ``kind`` (None: no motion and nothing rewritten;
    'L', 'C', 'CC', 'hole' (an L that calls a pecking cycle with M99)), the datum shift in force (3,) in
    program units, the axes given incrementally, the circle centre (CC: absolute, program
    frame) and for a C the index of its CC line."""

    kind: str | None = None
    shift: tuple = (0.0, 0.0, 0.0)
    incremental: frozenset = frozenset()
    centre: tuple | None = None
    cc_line: int | None = None
    #: a CR's radius R (signed, program units); None for every other line
    radius: float | None = None


@dataclass
class Translation:
    """A conversational program as G-code: ``gcode`` (one line per source line), ``lines`` (a
    :class:`LineInfo` per source line), ``inch``."""

    gcode: list = field(default_factory=list)
    lines: list = field(default_factory=list)
    inch: bool = False
    #: a DIN/ISO program (:mod:`.heidenhain_iso`), not a conversational one
    iso: bool = False


def _num(text: str) -> float:
    return float(text.replace(" ", ""))


def _fmt(v: float) -> str:
    s = f"{v:.10f}".rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


@dataclass
class _Cycle:
    dist: float
    depth: float
    feed: float | None


class _Reader(TcpMode):
    """The state a conversational program carries from line to line (see the module docstring;
    the tool centre point mode: :class:`~.heidenhain_tcp.TcpMode`)."""

    #: the language named in a refusal, an arc and its centre as the language writes them
    LANGUAGE, ARC, CENTRE = "Heidenhain conversational", "C", "CC"

    def __init__(self, path):
        self.path = path
        self.out = Translation()
        self.pos = dict.fromkeys(AXES)          # program frame, program units; None: unknown
        self.shift = [0.0, 0.0, 0.0]
        self.cc = None                           # (x, y, line index)
        self.radius_comp = "R0"                  # RL, RR or R0 in force
        self.cycle_def: dict = {}                # the CYCL DEF 1 being read
        self.cycle: _Cycle | None = None
        self.started = False
        self.current = (-1, "")                  # (line index, its block number) being read

    def err(self, message: str, k: int) -> InputError:
        """InputError at source line k (0-based), naming the TNC's block number too (the number a
        TNC user searches by)."""
        block = f" (block {self.current[1]})" if self.current[0] == k and self.current[1] else ""
        return InputError(message + block, self.path, line=k + 1)

    def line(self, k: int, text: str) -> tuple[str, LineInfo]:
        """(G-code, info) of source line k (0-based)."""
        g, info = self._line(k, text)
        return self.tcp_after(g), info

    def _line(self, k: int, text: str) -> tuple[str, LineInfo]:
        info = LineInfo(shift=tuple(self.shift))
        body = text.strip()
        first = body.split(maxsplit=1)[0] if body else ""
        self.current = (k, first if first.isdigit() else "")
        if not body or body.startswith(";"):
            # a comment line without a block number (added by hand): the TNC numbers its blocks
            # itself (docs/toolpaths.md, "Heidenhain conversational"); kept as written
            return "", info
        m = _BLOCK.match(body)
        if not m:
            raise self.err(f"a Heidenhain block without its block number: {body[:40]!r}", k)
        body = m.group(2)
        code = body.split(";", 1)[0].strip().upper()
        if not code or code.startswith("*"):
            return "", info
        if not self.started:
            return self._begin(code, k), info
        tcp = self.tcp_function(code, k)
        if tcp is not None:
            return tcp, info
        key = _KEYWORD.match(code)
        if key is None:
            word = re.match(r"[A-Z]+", code)
            what = _REFUSED.get(word.group(0)) if word else None
            if what is None and word and word.group(0).startswith("Q"):
                what = "Q parameters"
            raise self.err(f"{what or repr(code)} is not read by mtcomp (Heidenhain "
                           "conversational)", k)
        name, rest = key.group(1), code[key.end():].strip()
        if name == "CR" and self._ends_at_start(rest, k):
            raise self.err("a CR ending at its start (a full circle) is not read by mtcomp: no "
                           "radius places its centre, and the TNC's manual programs a full circle "
                           "as two CR semicircles (or as C about a CC)", k)
        if name in _REFUSED:
            raise self.err(f"{_REFUSED[name]} is not read by mtcomp (Heidenhain conversational)", k)
        if re.search(r"\bQ\d|\bFN\b", rest):
            raise self.err("Q parameters are not read by mtcomp (Heidenhain conversational)", k)
        switch = self.tcp_block(name, rest, k)       # M128 / M129
        handler = {"L": self._l, "C": self._c, "CR": self._cr, "CC": self._cc,
                   "TOOL CALL": self._tool_call,
                   "CYCL DEF": self._cycl_def, "CYCLE DEF": self._cycl_def,
                   "M": self._m_only}.get(name)
        if handler is None:         # END PGM, BLK FORM, TOOL DEF, STOP
            return "", info
        g, info = handler(rest, k, info)
        return switch + g, info

    def _ends_at_start(self, rest: str, k: int) -> bool:
        """Whether a block's X Y (absolute or incremental; those it does not give: the last
        programmed) are the position it starts from (False where that is not known)."""
        if self.pos["X"] is None or self.pos["Y"] is None:
            return False
        end = self._absolute({a: v for a, v in self._words(rest, k, AXES).items() if a in "XY"}, k)
        return all(abs(end.get(a, self.pos[a]) - self.pos[a]) <= 1e-9 for a in "XY")

    def _begin(self, code: str, k: int) -> str:
        m = re.fullmatch(r"BEGIN PGM\s+\S+\s+(MM|INCH)", code)
        if not m:
            raise self.err("a Heidenhain conversational program starts with BEGIN PGM name MM "
                           f"(or INCH), not {code[:40]!r}", k)
        self.started = True
        self.out.inch = m.group(1) == "INCH"
        return "G20" if self.out.inch else "G21"

    def _mcodes(self, rest: str, k: int) -> list[int]:
        codes = [int(v) for v in re.findall(r"(?<![A-Z])M\s*(\d+)", rest)]
        for c in codes:
            if c == 89 or (c >= 90 and c not in (91, 92, 99, 128, 129)):
                raise self.err(f"M{c} (a TNC path or cycle function) is not read by mtcomp "
                               f"({self.LANGUAGE})", k)
        return codes

    def _m_only(self, rest: str, k: int, info: LineInfo) -> tuple[str, LineInfo]:
        codes = self._mcodes("M" + rest, k)
        if 99 in codes or 91 in codes or 92 in codes:
            raise self.err("M91, M92 or M99 without a positioning block L", k)
        return "", info

    def _words(self, rest: str, k: int, allowed: str) -> dict:
        """letter -> (value, incremental) of the axis words; refuses other axes and repeats."""
        out = {}
        for m in WORD.finditer(rest):
            letter = m.group(2)
            if letter not in allowed:
                raise self.err(f"axis word {m.group(1)}{letter} is not read in this block", k)
            if letter in out:
                raise self.err(f"axis {letter} twice in one block", k)
            out[letter] = (_num(m.group(4)), bool(m.group(1)))
        return out

    def _leftover(self, rest: str, k: int, extra: str) -> None:
        """Refuse what a block holds besides axis words and the ``extra`` words (a regex)."""
        left = WORD.sub(" ", rest)
        left = re.sub(extra, " ", left).strip()
        if left:
            word = re.match(r"[A-Z]+", left)
            what = _REFUSED.get(word.group(0)) if word else None
            if word and word.group(0) in ("RL", "RR"):
                what = f"radius compensation {word.group(0)}"
            raise self.err(f"{what or repr(left[:30])} is not read by mtcomp (Heidenhain "
                           "conversational)", k)

    def _absolute(self, words: dict, k: int) -> dict:
        """letter -> absolute value (program frame), from absolute or incremental words."""
        out = {}
        for letter, (v, inc) in words.items():
            if inc:
                if self.pos[letter] is None:
                    raise self.err(f"incremental I{letter} from a position the program has not "
                                   "given", k)
                v = self.pos[letter] + v
            out[letter] = v
        return out

    def _coords(self, target: dict) -> str:
        return " ".join(f"{a}{_fmt(v + (self.shift['XYZ'.index(a)] if a in 'XYZ' else 0.0))}"
                        for a, v in target.items())

    def _feed(self, rest: str, k: int):
        """(rapid, feed or None) of a block: FMAX, F number, or neither."""
        if re.search(r"\bF\s*(?:AUTO|U|Z)", rest):
            raise self.err("FAUTO and feeds per revolution or tooth (FU, FZ) are not read", k)
        if re.search(r"\bFMAX\b", rest):
            return True, None
        m = re.search(r"(?<![A-Z])F\s*(" + _NUMBER + ")", rest)
        return False, (None if m is None else _num(m.group(1)))

    def _radius_comp(self, rest: str, k: int, arc: bool) -> str:
        """The G-code word of a block's radius compensation word where it changes the one in force
        (RL G41, RR G42, R0 G40) followed by a blank, else ''; an arc C may only repeat it."""
        words = re.findall(r"\b(R0|RL|RR)\b", rest)
        if len(words) > 1:
            raise self.err("two radius compensation words in one block", k)
        if not words or words[0] == self.radius_comp:
            return ""
        if arc:
            raise self.err(f"radius compensation {words[0]} switched on an arc C is not read by "
                           "mtcomp (switch it on a straight line L)", k)
        self.radius_comp = words[0]
        return f"G{_RADIUS_COMP[words[0]]} "

    def _l(self, rest: str, k: int, info: LineInfo) -> tuple[str, LineInfo]:
        words = self._words(rest, k, AXES)
        self._leftover(rest, k, r"\bFMAX\b|\bR[0LR]\b|(?<![A-Z])F\s*" + _NUMBER
                       + r"|(?<![A-Z])M\s*\d+")
        comp = self._radius_comp(rest, k, False)
        g, info = self._l_gcode(rest, k, info, words)
        return (comp + g).strip(), info

    def _l_gcode(self, rest: str, k: int, info: LineInfo, words: dict) -> tuple[str, LineInfo]:
        """The G-code of an L block, its radius compensation left out."""
        mcodes = self._mcodes(rest, k)
        rapid, feed = self._feed(rest, k)
        return self.move_gcode(words, rapid, feed, mcodes, k, info)

    def move_gcode(self, words: dict, rapid: bool, feed, mcodes: list, k: int,
                   info: LineInfo) -> tuple[str, LineInfo]:
        """The G-code of a straight move to ``words`` (letter -> (value, incremental)): rapid or
        at the feed, M91/M92 machine positions, M99 a cycle call."""
        f_word = "" if feed is None else f" F{_fmt(feed)}"
        if 91 in mcodes or 92 in mcodes:
            if any(inc for _v, inc in words.values()) or 99 in mcodes:
                raise self.err("an incremental or drilling block with M91/M92 is not read", k)
            for a in words:
                self.pos[a] = None
            axes = " ".join(f"{a}{_fmt(v)}" for a, (v, _i) in words.items())
            return (f"G53 G{0 if rapid else 1} {axes}{f_word}" if words else ""), info
        target = self._absolute(words, k)
        info.incremental = frozenset(a for a, (_v, inc) in words.items() if inc)
        if 99 in mcodes:
            if words and not rapid:
                raise self.err("a cycle call M99 on a feed move (the cycle is reached at FMAX)", k)
            self.pos.update(target)
            info.kind = "hole"
            return self._hole(k, feed), info
        self.pos.update(target)
        if not words:
            return (f"F{_fmt(feed)}" if feed is not None else ""), info
        info.kind = "L"
        return f"G{0 if rapid else 1} {self._coords(target)}{f_word}", info

    def _cc(self, rest: str, k: int, info: LineInfo) -> tuple[str, LineInfo]:
        words = self._words(rest, k, "XY")
        self._leftover(rest, k, r"$^")
        if len(words) != 2 or any(inc for _v, inc in words.values()):
            raise self.err("a circle centre CC needs absolute X and Y (CC alone or incremental "
                           "IX IY is not read)", k)
        self.cc = (words["X"][0], words["Y"][0], k)
        info.kind, info.centre = "CC", self.cc[:2]
        return "", info

    def _c(self, rest: str, k: int, info: LineInfo) -> tuple[str, LineInfo]:
        words, ccw, feed = self._arc_block("C", rest, k, "")
        return self.arc_gcode(words, ccw, feed, k, info)

    def _cr(self, rest: str, k: int, info: LineInfo) -> tuple[str, LineInfo]:
        """An arc by its end point and radius (HEIDENHAIN, iTNC 530 User's Manual, "Circular path
        CR with defined radius": R > 0 the arc of at most 180 degrees, R < 0 the larger one),
        read as an arc about the centre that makes (its own, not the CC in force)."""
        radius = CR_RADIUS.search(rest)
        words, ccw, feed = self._arc_block("CR", rest, k, "|" + CR_RADIUS.pattern)
        if radius is None:
            raise self.err("an arc CR needs its radius R", k)
        if self.pos["X"] is None or self.pos["Y"] is None:
            raise self.err("an arc CR from a position the program has not given", k)
        end = {"X": self.pos["X"], "Y": self.pos["Y"], **self._absolute(words, k)}
        info.radius = _num(radius.group(1))
        try:
            c = radius_centre((self.pos["X"], self.pos["Y"]), (end["X"], end["Y"]), info.radius,
                              ccw, MM_PER_INCH if self.out.inch else 1.0)
        except RadiusError:
            raise self.err(f"the radius R{radius.group(1)} of a CR is smaller than half the "
                           "chord to its end point", k) from None
        return self.arc_gcode(words, ccw, feed, k, info, centre=(c[0], c[1], k))

    def _arc_block(self, name: str, rest: str, k: int, extra: str) -> tuple[dict, bool, object]:
        """(the axis words, counter-clockwise, the feed) of an arc block ``name`` (C, CR), its
        words checked (``extra``: a regex of words it holds besides those of a C)."""
        direction = re.search(r"\bDR\s*([+-])", rest)
        words = self._words(rest.replace("DR", "  "), k, "XY")
        self._leftover(rest, k, r"\bDR\s*[+-]|\bR[0LR]\b|(?<![A-Z])F\s*" + _NUMBER
                       + r"|(?<![A-Z])M\s*\d+" + extra)
        self._radius_comp(rest, k, True)
        self._mcodes(rest, k)
        rapid, feed = self._feed(rest, k)
        if direction is None or rapid:
            raise self.err(f"an arc {name} needs its direction DR+ or DR- (and no FMAX)", k)
        return words, direction.group(1) == "+", feed

    def arc_gcode(self, words: dict, ccw: bool, feed, k: int, info: LineInfo,
                  centre: tuple | None = None) -> tuple[str, LineInfo]:
        """The G-code of an arc about ``centre`` (x, y, the line that gives it; None: the circle
        centre in force) to ``words`` (letter -> (value, incremental); a coordinate not given is
        the last programmed one)."""
        centre = self.cc if centre is None else centre
        if centre is None:
            raise self.err(f"an arc {self.ARC} before any circle centre {self.CENTRE}", k)
        if self.pos["X"] is None or self.pos["Y"] is None:
            raise self.err(f"an arc {self.ARC} from a position the program has not given", k)
        target = {"X": self.pos["X"], "Y": self.pos["Y"], **self._absolute(words, k)}
        sx, sy = self.pos["X"], self.pos["Y"]
        info.kind, info.cc_line, info.centre = "C", centre[2], centre[:2]
        info.incremental = frozenset(a for a, (_v, inc) in words.items() if inc)
        self.pos.update(target)
        f_word = "" if feed is None else f" F{_fmt(feed)}"
        g = 3 if ccw else 2
        return (f"G{g} {self._coords(target)} I{_fmt(centre[0] - sx)} J{_fmt(centre[1] - sy)}"
                f"{f_word}"), info

    def _tool_call(self, rest: str, k: int, info: LineInfo) -> tuple[str, LineInfo]:
        m = re.match(r"(\d+)\s*(?:([XYZ])(?![A-Z]))?", rest)
        if m is None:
            raise self.err("TOOL CALL by tool name (not number) is not read", k)
        if m.group(2) not in (None, "Z"):
            raise self.err(f"TOOL CALL with tool axis {m.group(2)} (only Z is read)", k)
        for word in ("DL", "DR"):
            d = re.search(r"\b" + word + r"\s*(" + _NUMBER + ")", rest)
            if d and _num(d.group(1)) != 0.0:
                raise self.err(f"TOOL CALL with a delta {word} is not read", k)
        n = int(m.group(1))
        self.pos["Z"] = None
        return f"T{n} M6 G43 H{n}", info

    def _cycl_def(self, rest: str, k: int, info: LineInfo) -> tuple[str, LineInfo]:
        m = re.match(r"(\d+)(?:\.(\d+))?\s*(.*)$", rest)
        if m is None:
            raise self.err(f"a cycle definition {rest[:30]!r} is not read", k)
        number, part, tail = int(m.group(1)), int(m.group(2) or 0), m.group(3)
        if number not in _CYCLES:
            raise self.err(f"CYCL DEF {number} is not read by mtcomp (of the cycles only 1 "
                           "pecking, 7 datum shift and 9 dwell are)", k)
        if number == 7 and part > 0:
            self._datum_shift(tail, k)
            info.shift = tuple(self.shift)
        elif number == 1:
            self._pecking(part, tail, k)
        return "", info

    def _datum_shift(self, tail: str, k: int) -> None:
        if "#" in tail:
            raise self.err("a datum shift from a datum table (#) is not read", k)
        words = self._words(tail, k, "XYZ")
        self._leftover(tail, k, r"$^")
        for a, (v, inc) in words.items():
            i = "XYZ".index(a)
            self.shift[i] = self.shift[i] + v if inc else v

    def _pecking(self, part: int, tail: str, k: int) -> None:
        # the words of each part: the TNC's English dialogue (SET UP, PECKG: HEIDENHAIN TNC 426
        # User's Manual, Cycle 1 PECKING) and the shorter forms of other posts (DIST, PLNGNG)
        names = {1: ("DIST", "SET UP"), 2: ("DEPTH",), 3: ("PLNGNG", "PECKG"), 4: ("DWELL",),
                 5: ("F",)}
        if part == 0:
            self.cycle_def, self.cycle = {}, None
            return
        words = names.get(part)
        name = words[0] if words else None
        m = re.fullmatch("(?:" + "|".join(words) + r")\s*(" + _NUMBER + ")", tail) if words else None
        if m is None:
            raise self.err(f"CYCL DEF 1.{part} {tail[:30]!r} is not read", k)
        self.cycle_def[name] = _num(m.group(1))
        if part == 5 or {"DIST", "DEPTH"} <= set(self.cycle_def):
            if self.cycle_def.get("DEPTH", 0.0) >= 0.0:
                raise self.err("a pecking cycle with a depth that is not negative is not read", k)
            self.cycle = _Cycle(self.cycle_def["DIST"], self.cycle_def["DEPTH"],
                                self.cycle_def.get("F"))

    def _hole(self, k: int, feed) -> str:
        """The G-code of a cycle call at the current position: G99 G81 from the start level."""
        if self.cycle is None:
            raise self.err("a cycle call without a pecking cycle CYCL DEF 1 defined", k)
        if any(self.pos[a] is None for a in "XYZ"):
            raise self.err("a cycle call at a position the program has not given", k)
        start = self.pos["Z"]
        bottom = start - self.cycle.dist + self.cycle.depth
        f = self.cycle.feed if self.cycle.feed is not None else feed
        xy = self._coords({"X": self.pos["X"], "Y": self.pos["Y"]})
        return (f"G99 G81 {xy} R{_fmt(start + self.shift[2])} Z{_fmt(bottom + self.shift[2])}"
                + ("" if f is None else f" F{_fmt(f)}"))


def read_lines(path) -> list[bytes]:
    """The source's lines as the reader counts them ('\\n' ends one), each with its ending."""
    with open(path, "rb") as f:
        raws = f.read().split(b"\n")
    return [r + b"\n" for r in raws[:-1]] + ([raws[-1]] if raws[-1] else [])


def translate(path, reader: _Reader | None = None) -> Translation:
    """The conversational program at ``path`` as G-code (see the module docstring), read by
    ``reader`` (None: a conversational one; :func:`.heidenhain_iso.translate` hands its DIN/ISO
    reader). Raises InputError naming the line and the construct for what is not read."""
    raws = read_lines(path)
    reader = _Reader(path) if reader is None else reader
    for k, raw in enumerate(raws):
        text = raw.decode("latin-1").rstrip("\r\n")
        if k == 0 and text.startswith("\ufeff"):
            text = text[1:]
        g, info = reader.line(k, text)
        reader.out.gcode.append(g)
        reader.out.lines.append(info)
    if not reader.started:
        raise InputError("no BEGIN PGM line: not a Heidenhain conversational program (nor a "
                         "%NAME G71 line: nor a DIN/ISO one)", path)
    return reader.out


def signed(value: float, decimals: int, sign: bool = True) -> str:
    """A coordinate in Heidenhain's form: ``+107.5032``, ``-0.0100`` (``+0.0000``, never -0)."""
    s = f"{value:.{decimals}f}"
    if float(s) == 0.0:
        s = s.lstrip("-")
    if sign and not s.startswith("-"):
        s = "+" + s
    return s



"""Siemens Sinumerik programs (840D, ``%_N_NAME_MPF``): read as the motion mtcomp knows.

A Sinumerik program is turned into equivalent G-code that mtcomp's reader reads, each source line
into the G-code lines of the moves the controller makes for it (a hole of a drilling cycle is
three: the cycle, its cancel and the retract to the cycle's retract plane); the map from G-code
lines to source lines names the source in every message and report. The corrected program is
written back in its own form by :mod:`.sinumerik_out`. The rules are those of Siemens AG, SINUMERIK
840D sl Programming Manual, Fundamentals (2013) and Job planning (2013), and of its Cycles manual
(SINUMERIK 840D sl / 828D Cycles, Programming Manual, 2013) for the drilling cycles CYCLE81 to
CYCLE89 and the hole patterns HOLES1 and HOLES2;
docs/toolpaths.md, "Siemens Sinumerik", lists them with what is refused.
"""
from __future__ import annotations

import math
import re
from array import array
from dataclasses import dataclass, field

from ..errors import InputError
from .heidenhain import read_lines
from .words import MM_PER_INCH, NO_LENGTH
from .sinumerik_cycles import Call, CycleCalls
from .sinumerik_lang import (AXES, ExpressionError, Word, code_end, evaluate, fmt,
                             split_arguments, split_words)
from .sinumerik_paths import (CORNER_G, FRAME_WORDS, MACHINE_G, SETTING_CALLS, SETTING_VALUES,
                              SETTING_WORDS, SMOOTHING_G, RadiusError, radius_centre)

_HEADER = re.compile(r"^\s*%")
#: what stands before a block's words: a block skip, its number, a label
BLOCK_START = re.compile(r"\s*/?\s*(?:(?:N\d+|:\d+)\s*)?(?:[A-Za-z_][A-Za-z0-9_]*:(?!=)\s*)?")
_BLOCK_NUMBER = re.compile(r"\s*(?:N\d+|:\d+)\s*")
_LABEL = re.compile(r"\s*[A-Za-z_][A-Za-z0-9_]*:(?!=)\s*")
_DEF = re.compile(r"(?i)\s*DEF\s+(REAL|INT|BOOL)\s+(.*)$")
#: G codes read (others refused by name): motion, plane, distance, units, work offsets, path
#: control (exact stop, continuous path and its smoothing: within a tolerance of the path as
#: programmed), feed per minute, cutter radius compensation
_MOTION_G = {0, 1, 2, 3}
_PASSED_G = {17, 18, 19, 40, 41, 42, 90, 94, 70, 700, 71, 710}
#: the units: G70 inch for the geometry (positions, centres, radii, TRANS), the feed in the basic
#: system; G700 inch for the feed F too; G71, G710 metric (Fundamentals, "Dimensions in metric
#: units and inches")
_INCH_G = {70: (True, False), 700: (True, True), 71: (False, False), 710: (False, False)}
_IGNORED_G = {9, 60, 64, 601, 602, 603} | SMOOTHING_G | CORNER_G
_REFUSED_WORDS = {
    "GOTO": "program jumps (GOTO)", "GOTOF": "program jumps (GOTOF)",
    "GOTOB": "program jumps (GOTOB)", "GOTOC": "program jumps (GOTOC)",
    "IF": "IF control structures", "WHILE": "WHILE loops", "FOR": "FOR loops",
    "REPEAT": "REPEAT loops", "LOOP": "LOOP loops", "CASE": "CASE jumps",
    "PROC": "a subprogram definition (PROC)", "ROT": "a programmable frame (ROT)",
    "AROT": "a programmable frame (AROT)", "SCALE": "a programmable frame (SCALE)",
    "ASCALE": "a programmable frame (ASCALE)", "MIRROR": "a programmable frame (MIRROR)",
    "AMIRROR": "a programmable frame (AMIRROR)",
    "TRANSMIT": "a transformation (TRANSMIT)", "TRACYL": "a transformation (TRACYL)",
    "CIP": "a circle through an intermediate point (CIP)", "CT": "a tangential circle (CT)",
    "AR": "a circle by its opening angle (AR=)",
    "AP": "polar coordinates (AP=)", "RP": "polar coordinates (RP=)",
    "RND": "a rounding (RND)", "CHF": "a chamfer (CHF)", "CHR": "a chamfer (CHR)",
    "SPOS": "spindle positioning (SPOS)",
}
#: the words refused where they are given a value (``AR=...``)
_REFUSED_VALUES = {"AR", "AP", "RP", "RND", "CHF", "CHR"}
#: the tool orientation given otherwise than by the rotary axes' positions (Job planning,
#: orientation programming; 5-axis machining): refused by name under TRAORI and elsewhere
_ORIENTATION = {"2": "its Euler or RPY angles (A2= B2= C2=)",
                "3": "its direction vector (A3= B3= C3=)",
                "4": "the surface normal at the block's start (A4= B4= C4=)",
                "5": "the surface normal at the block's end (A5= B5= C5=)",
                "6": "the axis of a cone of orientations (A6= B6= C6=)",
                "7": "an intermediate orientation (A7= B7= C7=)",
                "LEAD": "its lead angle (LEAD=)", "TILT": "its tilt angle (TILT=)",
                "THETA": "its rotation angle (THETA=)"}
#: the largest number of additional full turns TURN= of a helix (Fundamentals, helical
#: interpolation: 0 to 999)
MAX_TURNS = 999
@dataclass
class GInfo:
    """What a G-code line of the translation is, for the writer: ``source`` its source line
    (0-based); ``kind`` None (no move), 'move' (a straight move of the line's axis words), 'arc',
    'hole' (a hole of a drilling cycle, at its bottom), 'retract' (to the cycle's RTP: kept as
    written), 'approach' (a call's own move, kept); ``shift`` the programmable frame's translation
    (X Y Z, the program's units) in force; for an arc its ``centre``, ``cc_line`` (its own line)
    and, for a circle given by its radius, ``radius`` (the CR= value); for a piece of a helix with
    additional turns ``turn`` (its index, the number of pieces); for a hole its ``call``
    (:class:`Call`) and ``pattern`` (:class:`Pattern` or None); ``inch``: G70/G700 in force."""

    source: int
    kind: str | None = None
    shift: tuple = (0.0, 0.0, 0.0)
    centre: tuple | None = None
    cc_line: int | None = None
    radius: float | None = None
    turn: tuple | None = None
    call: object = None
    pattern: object = None
    inch: bool = False


@dataclass
class Translation:
    """A Sinumerik program as G-code: ``gcode`` lines, ``lines`` a :class:`GInfo` per G-code line,
    ``line_map`` (the source line, 1-based, of each G-code line), ``calls``, ``patterns``,
    ``subprograms``: (line, text) of the calls whose moves mtcomp cannot see, ``inch``: whether
    the program gives lengths in inch anywhere (G70, G700), ``tool_names``: see below."""

    gcode: list = field(default_factory=list)
    lines: list = field(default_factory=list)
    line_map: array = field(default_factory=lambda: array("l"))
    calls: list = field(default_factory=list)
    patterns: list = field(default_factory=list)
    subprograms: list = field(default_factory=list)
    inch: bool = False
    #: the tools called by name (``T="DRILL 8.5"``) -> the tool length number H that stands for
    #: each in the G-code equivalent (its length: ``--tool-length "DRILL 8.5=L"``)
    tool_names: dict = field(default_factory=dict)


class _Reader(CycleCalls):
    """The state a Sinumerik program carries from line to line."""

    def __init__(self, path):
        self.path = path
        self.out = Translation()
        self.vars: dict = {}                    # DEF variables and R parameters: value or None
        self.pos = dict.fromkeys(AXES)          # program frame (mm, deg); None: unknown
        self.motion: int | None = None
        self.plane = 17
        self.tool: int | str = 0                # the tool T selects: a number or a name
        self.active: int | str | None = None    # the tool M6 changed in (None: no M6 yet)
        self.edge = 1                           # the tool's cutting edge D in force (0: D0)
        self.wcs = 500                          # the basic setting: no settable work offset
        #: the G-code equivalent is in the basic frame (G500 named; before any work system is
        #: named it reads the G-code default G54: the reset setting is a machine datum)
        self.basic = False
        self.modal_call: Call | str | None = None   # a drilling Call, or the name of another
        self.ended = False
        self.r_lost = False                     # a subprogram may have set any R parameter
        #: the programmable frame's translation TRANS/ATRANS (mm, X Y Z): the G-code equivalent's
        #: coordinates are the program's plus this shift
        self.shift = [0.0, 0.0, 0.0]
        #: the units in force (G70/G700 inch, G71/G710 mm): of the geometry, of the feed F
        self.inch = False
        self.feed_inch = False
        self.tcp = False                        # TRAORI in force
        self.k = 0

    def err(self, message: str) -> InputError:
        return InputError(message + " (Sinumerik)", self.path, line=self.k + 1)

    def emit(self, text: str, kind=None, **kw) -> GInfo:
        info = GInfo(self.k, kind, shift=tuple(self.shift), inch=self.inch, **kw)
        self.out.gcode.append(text)
        self.out.lines.append(info)
        self.out.line_map.append(self.k + 1)
        return info

    # ------------------------------------------------------------------ values
    def lookup(self, name: str) -> float:
        if name not in self.vars:
            if re.fullmatch(r"R\d+", name):
                if self.r_lost:
                    raise ExpressionError(f"{name} may hold a value a subprogram set, which mtcomp "
                                          "cannot see")
                raise ExpressionError(f"the R parameter {name} is read before the program sets it")
            raise KeyError(name)
        v = self.vars[name]
        if v is None:
            raise ExpressionError(f"{name} may hold a value a subprogram set, which mtcomp cannot "
                                  "see")
        return v

    def value(self, text: str) -> float:
        try:
            return evaluate(text, self.lookup)
        except ExpressionError as exc:
            raise self.err(str(exc)) from None

    def assign(self, name: str, text: str) -> None:
        """A variable or R parameter set; a value that cannot be computed now is None (refused
        where a move uses it)."""
        try:
            self.vars[name] = evaluate(text, self.lookup)
        except ExpressionError:
            self.vars[name] = None

    # ------------------------------------------------------------------ lines
    def line(self, k: int, text: str) -> None:
        self.k = k
        if self.ended or _HEADER.match(text):
            return
        end = code_end(text)
        start = len(text) - len(text.lstrip())
        if start < end and text[start] == "/":
            self._block_skip(text, start + 1, end)
            return
        m = _BLOCK_NUMBER.match(text, start)
        start = m.end() if m else start
        m = _LABEL.match(text, start)
        start = m.end() if m else start
        if "@" in text[start:end]:
            code = re.search(r"@\d*", text[start:end]).group(0)
            raise self.err(f"the computation instruction {code} (Sinumerik 8xx) is not read by "
                           "mtcomp")
        d = _DEF.match(text[start:end])
        if d:
            self._define(d.group(2))
            return
        if re.match(r"(?i)\s*DEF\b", text[start:end]):
            raise self.err("a DEF of a type other than REAL, INT or BOOL is not read by mtcomp")
        try:
            words = split_words(text, start, end)
        except ValueError as exc:
            raise self.err(f"{exc}") from None
        if words:
            self._block(words)

    def _block_skip(self, text: str, start: int, end: int) -> None:
        """A skippable block '/': passed through when it moves nothing and changes no mode the
        moves depend on (it runs or not: the same motion either way); refused otherwise."""
        m = _BLOCK_NUMBER.match(text, start)
        try:
            words = split_words(text, m.end() if m else start, end)
        except ValueError as exc:
            raise self.err(f"{exc}") from None
        if any(w.kind != "address" or w.name not in "MSH" or
               (w.name == "M" and w.text.strip() in ("2", "02", "30", "6", "06", "17"))
               for w in words):
            raise self.err("a skippable block '/' that moves or changes a mode is not read by "
                           "mtcomp (the operator's block-skip switch decides whether it runs)")

    def _define(self, rest: str) -> None:
        for item in split_arguments(rest):
            name, _eq, expr = item.partition("=")
            name = name.strip().upper()
            if not re.fullmatch(r"[A-Z_][A-Z0-9_]*", name):
                raise self.err(f"DEF {item!r} is not read by mtcomp")
            if expr.strip():
                self.assign(name, expr)
            else:
                self.vars[name] = 0.0

    def _block(self, words: list[Word]) -> None:
        if any(w.kind == "keyword" and w.name in FRAME_WORDS for w in words):
            self._frame(words)
            return
        for w in words:
            if w.name in _REFUSED_WORDS and (w.kind in ("keyword", "call")
                                             or (w.kind == "assign" and w.name in _REFUSED_VALUES)):
                raise self.err(f"{_REFUSED_WORDS[w.name]} is not read by mtcomp")
            self._orientation(w)
        switch = self._switch(words)
        g, axes, centre, other = self._classify(words)
        calls = [w for w in words if (w.kind == "call" and w.name not in SETTING_CALLS
                                      and w.name != "TRAORI")
                 or (w.kind == "address" and w.name == "L")]
        mcall = any(w.kind == "keyword" and w.name == "MCALL" for w in words)
        self._modes(g, other)
        if switch is not None:
            if axes or centre or calls or mcall:
                raise self.err(f"{'TRAORI' if switch else 'TRAFOOF'} and a move or a call in one "
                               "block is not read by mtcomp")
            if switch != self.tcp:
                self.tcp = switch
                self.pos = dict.fromkeys(AXES)
                self.emit("M428" if switch else "M429")
        if mcall:
            self._mcall(calls, axes)
            return
        if calls:
            if axes or centre:
                raise self.err("a call and a move in one block are not read by mtcomp")
            self._call(calls[0])
            return
        if "machine" in other or MACHINE_G & set(g):
            self._machine_block(g, axes, centre, other)
        elif 4 in g:
            self._dwell(axes, centre, other)
        else:
            self._move(g, axes, centre, other)
        if "M6" in other:
            # the machine maker's tool change cycle moves the axes it needs (on a horizontal
            # machine Y and Z, often X): every position is unknown until the program names it
            self.pos = dict.fromkeys(AXES)
            self.edge = 1                       # a new tool starts on its edge D1
            self.active = self.tool
            h = self._length_number()
            self.emit(f"T{h} M6 {self._length_code(h)}")
            self.emit("G43.1")
        if "END" in other:
            self.ended = True
            self.emit("M30")

    def _orientation(self, w: Word) -> None:
        """Refuses the tool orientation given otherwise than by the rotary axes, by name (Job
        planning, "Variants of orientation programming")."""
        key = w.name if w.name in _ORIENTATION else w.name[1:] if re.fullmatch(r"[ABC][2-7]",
                                                                                  w.name) else ""
        if w.kind == "assign" and key:
            raise self.err(f"the tool orientation by {_ORIENTATION[key]} is not read by mtcomp "
                           "(give the rotary axes' positions)")
        if w.kind in ("keyword", "call") and w.name.startswith("ORI"):
            raise self.err(f"{w.name} (orientation programming: how the tool orientation is given "
                           "or interpolated) is not read by mtcomp (give the rotary axes' "
                           "positions)")

    def _switch(self, words: list[Word]) -> bool | None:
        """TRAORI (True: the 5-axis transformation, X Y Z the tool tip in the workpiece frame,
        the rotary axes their machine positions; Job planning, "Three, four and five axis
        transformation (TRAORI)"), TRAFOOF (False: off) or neither (None). Read as G-code's tool centre point mode, M428 and
        M429 (docs/toolpaths.md, "Tool centre point programs"), in a block without a move; a
        switch makes every position unknown (the words change meaning). ``TRAORI`` and
        ``TRAORI(1)`` select the machine's first transformation, the machine file's kinematics;
        another one, or one given an orientation or offsets in the call, is refused."""
        switch = None
        for w in words:
            if w.name == "TRAORI" and w.kind in ("keyword", "call"):
                if w.kind == "call" and w.text.strip() and split_arguments(w.text) != ["1"]:
                    raise self.err(f"TRAORI({w.text.strip()}) is not read by mtcomp (TRAORI or "
                                   "TRAORI(1): the machine's first transformation, which the "
                                   "machine file describes)")
                switch = True
            elif w.name == "TRAFOOF" and w.kind == "keyword":
                switch = False
        return switch

    def _frame(self, words: list[Word]) -> None:
        """TRANS X.. Y.. Z.. (the programmable frame's translation replaced, its other parts
        cleared), ATRANS X.. Y.. Z.. (added to it), and TRANS, ROT, SCALE or MIRROR without values
        (the programmable frame cleared): in a block of their own (Fundamentals, frames). The
        program's coordinates are shifted from here on; the positions stay where they are."""
        name = next(w.name for w in words if w.kind == "keyword" and w.name in FRAME_WORDS)
        values = [w for w in words if not (w.kind == "keyword" and w.name == name)]
        if values and name not in ("TRANS", "ATRANS"):
            raise self.err(f"a programmable frame ({name} with values) is not read by mtcomp")
        if any(w.kind not in ("address", "assign") or w.name not in AXES for w in values):
            raise self.err(f"{name} with other words than its axis values in its block is not read "
                           "by mtcomp (the manual gives it a block of its own)")
        if any(w.name not in "XYZ" for w in values):
            raise self.err(f"{name} of a rotary axis is not read by mtcomp")
        self._check_axis_words({w.name: w for w in values})
        given = {w.name: self.value(w.text) for w in values}
        new = [0.0, 0.0, 0.0] if name != "ATRANS" else list(self.shift)
        for k, a in enumerate("XYZ"):
            new[k] += given.get(a, 0.0)
            if self.pos[a] is not None:
                self.pos[a] -= new[k] - self.shift[k]
        self.shift = new

    def _classify(self, words):
        """(G codes, axis words {letter: Word}, centre words (I J K, CR), other: a set of 'M6',
        'END', 'F..', 'D..', 'machine' (SUPA), 'dwell F..' ...)."""
        g, axes, centre, other = [], {}, {}, set()
        dwell = any(w.kind == "address" and w.name == "G" and float(w.text) == 4 for w in words)
        for w in words:
            if w.kind == "address" and w.name == "G":
                g.append(int(float(w.text)))
            elif w.kind in ("address", "assign") and w.name in AXES:
                if w.name in axes:
                    raise self.err(f"axis {w.name} twice in one block")
                axes[w.name] = w
            elif w.kind in ("address", "assign") and w.name in "IJK" or \
                    (w.kind == "assign" and w.name in ("CR", "TURN")):
                centre[w.name] = w
            elif w.kind == "address" and w.name == "M":
                m = int(float(w.text))
                other.add({6: "M6", 2: "END", 30: "END", 17: "END"}.get(m, f"M{m}"))
            elif w.kind in ("address", "assign") and w.name == "T":
                self.tool = self._tool(w)
            elif w.kind == "address" and w.name == "D":
                other.add(f"D{int(float(w.text))}")
            elif dwell and w.kind in ("address", "assign") and w.name in "FS":
                other.add(f"dwell {w.name}{fmt(self.value(w.text))}")
            elif w.kind in ("address", "assign") and w.name == "F":
                other.add(f"F{fmt(self.value(w.text))}")
            elif w.kind == "assign" and w.name in SETTING_VALUES:
                self.value(w.text)              # a smoothing distance: set, moves nothing
            elif w.kind == "assign" and w.name.startswith("$"):
                raise self.err(f"the system variable {w.name} is not read by mtcomp (a frame, "
                               "an offset or a tool's data: the positions' meaning changes)")
            elif w.kind == "assign" and w.name not in ("S", "M", "H"):
                self.assign(w.name, w.text)
            elif w.kind == "keyword" and w.name == "SUPA":
                other.add("machine")
            elif w.kind == "keyword" and w.name not in ("MCALL", "TRAORI") \
                    and w.name not in SETTING_WORDS:
                raise self.err(f"{w.name} is not read by mtcomp")
            elif w.kind == "address" and w.name not in "SHNLP":
                raise self.err(f"the word {w.name}{w.text} is not read by mtcomp")
        return g, axes, centre, other

    def _modes(self, g: list[int], other: set) -> None:
        for code in g:
            if code in _MOTION_G:
                self.motion = code
            elif code in (17, 18, 19):
                self.plane = code
            elif code in (54, 55, 56, 57):
                if code != self.wcs:
                    # every position in the new frame is unknown (the G-code reader is told so)
                    self.wcs = code
                    self.basic = False
                    self.pos = dict.fromkeys(AXES)
                    self.emit(f"G{code} G43.1")
            elif code == 500:
                if not self.basic:
                    self.wcs = code
                    self.pos = dict.fromkeys(AXES)
                    self._basic_frame()
            elif code in _INCH_G:
                self._units(*_INCH_G[code])
            elif code == 91:
                raise self.err("incremental dimensions G91 are not read by mtcomp's Sinumerik "
                               "dialect")
            elif code not in _PASSED_G and code not in _IGNORED_G and code != 4 \
                    and code not in MACHINE_G:
                raise self.err(f"G{code} is not read by mtcomp")
        edges = [int(o[1:]) for o in other if o[0] == "D" and o[1:].isdigit()]
        if edges and edges[-1] != self.edge:
            # another cutting edge (D0: none) is another tool length: Z unknown until named
            self.edge = edges[-1]
            self.pos["Z"] = None
            self.emit(self._length_code(self._length_number() if self.edge else 0))

    def _length_code(self, h: int) -> str:
        """The tool length of H number h (0: none) in the G-code equivalent: G43 H.., G49 for
        none (G43 H0 under TRAORI: G49 would end G-code's tool centre point mode)."""
        return f"G43 H{h}" if h or self.tcp else "G49"

    def _tool(self, w: Word) -> int | str:
        """The tool a T word selects: ``T5``, ``T=5`` (a number) or ``T="DRILL 8.5"`` (a name, the
        string's text; Fundamentals, tool change: tool selection by name or number)."""
        text = w.text.strip()
        if w.kind == "assign" and text.startswith('"'):
            if len(text) < 3 or not text.endswith('"') or '"' in text[1:-1]:
                raise self.err(f"the tool name T={text} is not read by mtcomp")
            return text[1:-1]
        number = self.value(text)
        if number != int(number) or number < 0:
            raise self.err(f"the tool number T{fmt(number)} is not a whole number")
        return int(number)

    def _length_number(self) -> int:
        """The tool length number H of the G-code equivalent for the tool in the spindle (the
        one M6 changed in; the one T selected before any M6): its number, or for a tool called
        by name a number of its own (``Translation.tool_names``), counted down from the largest
        below NO_LENGTH (a program's numbered tools stay below them)."""
        tool = self.tool if self.active is None else self.active
        if isinstance(tool, int):
            return tool
        names = self.out.tool_names
        if tool not in names:
            names[tool] = NO_LENGTH - 1 - len(names)
        return names[tool]

    def _basic_frame(self) -> None:
        """The basic frame G500 (no settable work offset) in the G-code equivalent: the work system
        G59.3, which no Sinumerik program names, with its offset 0 unless one is given (a change
        of work system: every position unknown)."""
        self.basic = True
        self.emit("G59.3")

    def _g_codes(self, g: list[int]) -> str:
        return " ".join("G20" if c in (70, 700) else "G21" if c in (71, 710) else f"G{c}"
                        for c in g if c in _PASSED_G)

    def _units(self, inch: bool, feed_inch: bool) -> None:
        """G70, G700, G71, G710: the G-code equivalent says G20 or G21 and keeps the program's
        numbers; the positions and the programmable offset carried here are turned into the new
        units (the tool stays where it is). Under G70 the feed is the basic system's, taken as
        metric (the manual's setting): written in inch/min for the G-code equivalent."""
        if inch != self.inch:
            if self.modal_call is not None:
                raise self.err("a change of units (G70, G71, G700, G710) under a modal call "
                               "(MCALL) is not read by mtcomp")
            f = 1.0 / MM_PER_INCH if inch else MM_PER_INCH
            for a in "XYZ":
                if self.pos[a] is not None:
                    self.pos[a] *= f
            self.shift = [v * f for v in self.shift]
            self.inch = inch
            self.out.inch = self.out.inch or inch
        self.feed_inch = feed_inch

    def _feed(self, other: set) -> str:
        """The block's feed word for the G-code equivalent (mm/min, or inch/min under G20)."""
        feed = [o for o in sorted(other) if o.startswith("F")]
        if feed and self.inch and not self.feed_inch:
            return f"F{float(feed[0][1:]) / MM_PER_INCH:.15g}"
        return " ".join(feed)

    def _target(self, axes: dict) -> dict:
        return {a: self.value(w.text) for a, w in axes.items()}

    def _words(self, values: dict) -> str:
        """Axis words of the G-code equivalent for positions in the program's frame."""
        return " ".join(f"{a}{fmt(v + (self.shift['XYZ'.index(a)] if a in 'XYZ' else 0.0))}"
                        for a, v in values.items())

    def _check_axis_words(self, axes: dict) -> None:
        for a, w in axes.items():
            if w.kind == "assign" and re.match(r"(?i)\s*(AC|IC|DC|ACP|ACN|CAC|CIC)\s*\(", w.text):
                raise self.err(f"{a}={w.text.split('(')[0].strip().upper()}(...) is not read by "
                               "mtcomp (give the position as a value or an expression)")

    def _move(self, g, axes, centre, other) -> None:
        self._check_axis_words(axes)
        codes = self._g_codes(g)
        feed = self._feed(other)
        if self.motion in (2, 3) and (axes or centre):
            self._arc(axes, centre, codes, feed)
            return
        if centre:
            word = next((f"{n}=" for n in ("CR", "TURN") if n in centre), "I, J or K")
            raise self.err(f"{word} outside a circle G2/G3")
        if not axes:
            text = " ".join(t for t in (codes, feed) if t)
            if text.strip():
                self.emit(text.strip())
            return
        if self.motion is None:
            raise self.err("a move before any G0/G1/G2/G3")
        target = self._target(axes)
        line = " ".join(t for t in (codes, f"G{self.motion}", self._words(target), feed) if t)
        self.pos.update(target)
        if self.modal_call is not None and not isinstance(self.modal_call, Call):
            # a cycle mtcomp does not read runs at the position: the block passes uncorrected
            self.emit(" ".join(t for t in (codes, f"G{self.motion}", feed) if t))
            self._unknown(self.modal_call)
            return
        if self.modal_call is not None:
            self._modal_hole(line, axes)
            return
        self.emit(line, "move")

    def _machine_block(self, g, axes, centre, other) -> None:
        """A block with SUPA, G53 or G153: its positions are machine positions, every frame
        suppressed in this block alone (Fundamentals, suppression of frames); as G53 of G-code:
        passed through uncorrected, the axes it names unknown afterwards."""
        self._check_axis_words(axes)
        if centre or self.motion in (2, 3) and axes:
            raise self.err("a circle in machine coordinates (SUPA, G53, G153) is not read by "
                           "mtcomp")
        if self.modal_call is not None and axes:
            raise self.err("a block in machine coordinates (SUPA, G53, G153) under a modal call "
                           "(MCALL) is not read by mtcomp")
        codes = self._g_codes(g)
        feed = self._feed(other)
        if not axes:
            text = " ".join(t for t in (codes, feed) if t)
            if text:
                self.emit(text)
            return
        if self.motion is None:
            raise self.err("a move before any G0/G1/G2/G3")
        target = self._target(axes)
        words = " ".join(f"{a}{fmt(v)}" for a, v in target.items())
        self.emit(" ".join(t for t in (codes, f"G53 G{self.motion}", words, feed) if t))
        for a in axes:
            self.pos[a] = None

    def _dwell(self, axes, centre, other) -> None:
        """G4 F.. (seconds) or G4 S.. (spindle revolutions), in a block of its own: the F or S is
        the dwell's, the feed and the spindle speed in force stay (Fundamentals, dwell time)."""
        if axes or centre:
            raise self.err("a dwell G4 with axis words is not read by mtcomp (the manual gives "
                           "it a block of its own)")
        seconds = [o.split("F")[1] for o in other if o.startswith("dwell F")]
        if seconds:
            self.emit(f"G4 P{seconds[0]}")

    def _arc(self, axes, centre, codes, feed) -> None:
        if self.plane != 17:
            raise self.err("a circle outside the G17 plane is not read by mtcomp's Sinumerik "
                           "dialect")
        if self.pos["X"] is None or self.pos["Y"] is None:
            raise self.err("a circle from a position the program has not given")
        target = self._target(axes)
        if set(target) - {"X", "Y", "Z"}:
            raise self.err("a circle with a rotary axis word is not read by mtcomp")
        sx, sy = self.pos["X"], self.pos["Y"]
        end = {"X": sx, "Y": sy, **target}
        radius = None
        turns = self._turns(centre.pop("TURN", None))
        if "CR" in centre:
            if set(centre) != {"CR"}:
                raise self.err("a circle with both its radius CR= and its centre I J K is not read "
                               "by mtcomp")
            radius = self.value(centre["CR"].text)
            try:
                c = radius_centre((sx, sy), (end["X"], end["Y"]), radius, self.motion == 3,
                                  MM_PER_INCH if self.inch else 1.0)
            except RadiusError as exc:
                raise self.err(str(exc)) from None
        else:
            c = self._centre(centre, sx, sy)
        if turns:
            self._helix_turns(end, c, turns, codes, feed, radius)
            return
        self.pos.update(end)
        words = self._words({a: end[a] for a in ("X", "Y", "Z") if a in end})
        text = " ".join(t for t in (codes, f"G{self.motion}", words,
                                    f"I{fmt(c[0] - sx)} J{fmt(c[1] - sy)}", feed) if t)
        self.emit(text, "arc", centre=(c[0], c[1]), cc_line=self.k, radius=radius)

    def _turns(self, w: Word | None) -> int:
        """The additional full turns of ``TURN=`` (0 without it): a whole number, 0 to 999."""
        if w is None:
            return 0
        n = self.value(w.text)
        if n != int(n) or not 0 <= n <= MAX_TURNS:
            raise self.err(f"TURN={w.text.strip()} is not a whole number of additional turns "
                           f"(0 to {MAX_TURNS})")
        return int(n)

    def _helix_turns(self, end: dict, c, turns: int, codes: str, feed: str, radius) -> None:
        """A circle with ``turns`` additional full turns (Fundamentals, helical interpolation:
        from the start the full turns, then the circle to its end point; a circle whose end is its
        start is itself a full turn), Z (and the radius, where the ends' radii differ) going
        linearly with the angle over all of them: in the G-code equivalent as pieces of half a
        turn from the start's angle (the last one the circle's own part, two halves for a full
        circle), each a circle G2/G3 with ``turn`` (its index, the pieces' number)."""
        sx, sy, sz = self.pos["X"], self.pos["Y"], self.pos["Z"]
        if "Z" in end and sz is None:
            raise self.err("a helix with TURN= from a Z the program has not given")
        ccw = self.motion == 3
        a0 = math.atan2(sy - c[1], sx - c[0])
        r0, r1 = math.hypot(sx - c[0], sy - c[1]), math.hypot(end["X"] - c[0], end["Y"] - c[1])
        if math.hypot(end["X"] - sx, end["Y"] - sy) <= 1e-9:
            own = [math.pi, 2.0 * math.pi]
        else:
            a1 = math.atan2(end["Y"] - c[1], end["X"] - c[0])
            own = [(a1 - a0) % (2.0 * math.pi) if ccw else (a0 - a1) % (2.0 * math.pi)]
        turned = [k * math.pi for k in range(1, 2 * turns + 1)] + [2 * math.pi * turns + t
                                                                   for t in own]
        total = turned[-1]
        sign = 1.0 if ccw else -1.0
        start = (sx, sy)
        for k, t in enumerate(turned):
            u = t / total
            r = r0 + (r1 - r0) * u
            at = {"X": c[0] + r * math.cos(a0 + sign * t), "Y": c[1] + r * math.sin(a0 + sign * t)}
            if k == len(turned) - 1:
                at = {"X": end["X"], "Y": end["Y"]}
            if "Z" in end:
                at["Z"] = end["Z"] if k == len(turned) - 1 else sz + (end["Z"] - sz) * u
            first = (codes, f"G{self.motion}") if k == 0 else ("", f"G{self.motion}")
            text = " ".join(t for t in (*first, self._words(at),
                                        f"I{fmt(c[0] - start[0])} J{fmt(c[1] - start[1])}",
                                        feed if k == 0 else "") if t)
            self.emit(text, "arc", centre=(c[0], c[1]), cc_line=self.k, radius=radius,
                      turn=(k, len(turned)))
            start = (at["X"], at["Y"])
        self.pos.update(end)

    def _centre(self, centre, sx: float, sy: float) -> list:
        """The centre (x, y) of a circle given by I J (from the start, IC(..)) or I=AC(..)
        J=AC(..) (absolute), in the program's frame."""
        if "K" in centre or set(centre) != {"I", "J"}:
            raise self.err("a circle needs its centre I and J (in the G17 plane)")
        c = []
        for letter, s in (("I", sx), ("J", sy)):
            w = centre[letter]
            m = re.fullmatch(r"(?i)\s*AC\s*\((.*)\)\s*", w.text) if w.kind == "assign" else None
            if w.kind == "assign" and m is None and re.match(r"(?i)\s*[A-Z]+\s*\(", w.text) \
                    and not re.match(r"(?i)\s*IC\s*\(", w.text):
                raise self.err(f"{letter}={w.text[:20]} is not read by mtcomp")
            if m is not None:
                c.append(self.value(m.group(1)))
            else:
                inner = re.fullmatch(r"(?i)\s*IC\s*\((.*)\)\s*", w.text)
                c.append(s + self.value(inner.group(1) if inner else w.text))
        return c


def translate(path) -> Translation:
    """The program at ``path`` as G-code (see the module docstring). Raises InputError naming the
    line and the construct for what is not read."""
    reader = _Reader(path)
    texts = [raw.decode("latin-1").rstrip("\r\n") for raw in read_lines(path)]
    if texts and texts[0].startswith("\ufeff"):
        texts[0] = texts[0][1:]
    for k, text in enumerate(texts):
        reader.line(k, text)
    if not reader.out.gcode:
        raise InputError("no move in the program (Sinumerik)", path)
    return reader.out

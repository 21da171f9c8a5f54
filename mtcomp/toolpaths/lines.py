"""One line of a program with parameters and expressions: its values computed, its text rewritten.

Shared by the LinuxCNC front end (:mod:`.ngc`) and Fanuc macro B (:mod:`.macro`). A line's code (the
text outside comments, lower case and without blanks, as both controllers read it) is parsed once;
every word whose value is a parameter or an expression gets the computed number, parameter
assignments are taken out (they take effect after the line is read: LinuxCNC G-code reference,
Numbered Parameters), and LinuxCNC's polar words ``@`` (distance) and ``^`` (angle) become X and Y
words. Everything else of the line (letters, case, blanks, comments, plain numbers) is kept as
written.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

from .expr import FUNCTIONS, Evaluator, ExprError, Number, decimals_of, format_value, is_unknown
from .words import comment_end, number_decimals

_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)")

#: the letters of dimension words: in a Fanuc-style program a computed one is written with a
#: decimal point (a whole number without one is read in the least input increment by Fanuc and
#: Haas, as they read a program's own 'X6': FANUC Series 0i-MODEL F operator's manual,
#: B-64604EN, decimal point programming; a macro variable's value in a word is the value itself)
_DIMENSION = frozenset("XYZABCUVWIJKRQ")


#: a Fanuc drilling cycle's code, whose K is a repeat count, not a dimension
_FANUC_CYCLE = re.compile(r"(?i)g0*(?:7[346]|8\d)(?![\d.])")


def dimension_text(v: float, decimals: int | None = None) -> str:
    """A computed dimension word's value in a Fanuc-style program (:func:`~.expr.format_value`),
    with a point when whole."""
    text = format_value(v, decimals)
    return text if "." in text else text + "."


def _word_value(letter: str, v, code: str, fanuc: bool) -> str:
    """A computed word's value as written: a dimension word or a feed with the decimals of what it
    was computed from (with a point when whole in a Fanuc-style program, except K, a drilling
    cycle's repeat count, on a cycle's line); a code, a number or a count (G M T H D S P L ...) as
    a plain number, '3' not '3.0' (Fanuc alarms on a point in T M H D; Haas reads G04 P500. as
    seconds and P500 as milliseconds)."""
    count = fanuc and letter == "K" and _FANUC_CYCLE.search(code) is not None
    if count or (letter not in _DIMENSION and letter != "F"):
        return format_value(v, 0)
    return dimension_text(v) if fanuc and letter in _DIMENSION else format_value(v)


@dataclass
class Code:
    """The code of a line: ``text`` (lower case, no blanks, no comments) and for each of its
    characters the column in the original line."""

    text: str
    cols: list = field(default_factory=list)


def line_code(line: str) -> Code:
    """The code of a line outside ``( )`` and ``;`` comments."""
    chars, cols = [], []
    pos, n = 0, len(line)
    while pos < n:
        ch = line[pos]
        if ch == "(":
            e = comment_end(line, pos)        # a comment holding parentheses: to where they balance
            pos = n if e < 0 else e
            continue
        if ch == ";":
            break
        if ch not in " \t":
            chars.append(ch.lower())
            cols.append(pos)
        pos += 1
    return Code("".join(chars), cols)


@dataclass
class Rewritten:
    """A line after its values were computed: ``text`` (None: unchanged), the assignments to make
    after it (key -> value), the words it names (letter -> value), its polar words. ``unknown``: the
    letters of the words whose value the controller holds (:data:`~.expr.UNKNOWN`); such a line
    is written with those words and its assignments of such values as written (the parameters
    whose values are known put in as numbers), and ``reading`` is its text for the reader: those
    words given 0 and those assignments taken out (the reader passes the line through)."""

    text: str | None
    assignments: list
    words: dict
    polar: dict
    unknown: set = field(default_factory=set)
    reading: str | None = None


class ControllerLine(str):
    """An expanded line written as the controller computes it (a value it holds in its words or
    assignments: :class:`Rewritten`), with ``reading``, its text for the reader, and ``unknown``,
    the letters of its words of such values."""

    reading: str = ""
    unknown: frozenset = frozenset()

    @classmethod
    def of(cls, r: Rewritten) -> "ControllerLine":
        line = cls(r.text)
        line.reading, line.unknown = r.reading, frozenset(r.unknown)
        return line


def _is_computed(s: str, p: int, fanuc: bool = False) -> bool:
    """Whether the word value at s[p] is computed: an expression, a parameter, either after a sign,
    or (RS274/NGC) a function applied to a value in brackets, ``X SIN[30]``: LinuxCNC reads a real
    value that starts with a letter as a unary operation (LinuxCNC G-code reference, Unary
    Operation Value). Not read so in Fanuc macro B (``fanuc``), whose programs here give an
    address's expression in brackets (``X[SIN[30]]``): such a word stays refused there."""
    if p >= len(s):
        return False
    if s[p] in "[#":
        return True
    if not fanuc and s[p].isalpha():
        return any(s.startswith(name + "[", p) for name in FUNCTIONS)
    return s[p] in "+-" and p + 1 < len(s) and (s[p + 1] in "[#" or s[p + 1].isalpha())


def rewrite(line: str, code: Code, ev: Evaluator, *, fanuc: bool = False) -> Rewritten:
    """Compute a line's word values and take out its assignments (see the module docstring).
    Raises ExprError."""
    s = code.text
    spans, reads = [], []      # (start, end) in code positions, replacement: written, read
    assignments, words, polar, unknown = [], {}, {}, set()
    pos = 0
    while pos < len(s):
        ch = s[pos]
        if ch == "#":
            key, p = ev.parameter_key(s, pos)
            if p >= len(s) or s[p] != "=":
                raise ExprError("a parameter outside a word must be assigned: #1=...")
            v, p2 = ev.counted(ev.expression if fanuc else ev.value, s, p + 1)
            assignments.append((key, v))
            if is_unknown(v):           # the controller computes it: kept, as the words using it
                spans += _with_known(s, p + 1, p2, ev)
                unknown.add("#")
            else:
                spans.append((pos, p2, ""))
            reads.append((pos, p2, ""))
            pos = p2
        elif ch in "@^" or ch.isalpha():
            p = pos + 1
            if _is_computed(s, p, fanuc):
                v, p2 = ev.counted(ev.value, s, p)
                if is_unknown(v):
                    if ch in "@^":
                        raise ExprError(f"polar word {ch} of a value the controller holds (its "
                                        "position, a probe's result, a setting)")
                    unknown.add(ch.upper())
                    spans += _with_known(s, p, p2, ev)
                    # read as 0 (a feed, a speed, FluidNC's D print: not read, the feed kept)
                    reads.append((pos, p2, "") if ch in "fsd" else (p, p2, "0"))
                elif ch not in "@^":    # a polar word is replaced whole, by X and Y, below
                    text = _word_value(ch.upper(), v, s, fanuc)
                    spans.append((p, p2, text))
                    reads.append((p, p2, text))
            else:
                m = _NUMBER.match(s, p)
                if not m:
                    pos = p
                    continue        # left for the tokenizer to name
                v, p2 = Number(float(m.group(0)), number_decimals(m.group(0))), m.end()
            if ch in "@^":
                polar[ch] = v
                spans.append((pos, p2, None))
                reads.append((pos, p2, None))
            else:
                words.setdefault(ch, v)
            pos = p2
        else:
            pos += 1
    if unknown:
        return Rewritten(_apply(line, code, spans), assignments, words, polar,
                         unknown - {"#"}, _apply(line, code, reads))
    if not spans:
        return Rewritten(None, assignments, words, polar)
    return Rewritten(_apply(line, code, spans), assignments, words, polar)


def _with_known(s: str, start: int, end: int, ev: Evaluator) -> list:
    """The span s[start:end] (a value computed from one the controller holds) to write: [] where it
    reads no parameter whose value is known (kept as written), else the span with each of those
    put in as its number (the expansion leaves out their assignments)."""
    out, pos, changed = [], start, False
    while pos < end:
        if s[pos] != "#":
            out.append(s[pos])
            pos += 1
            continue
        key, after = ev.parameter_key(s, pos)
        v = ev.params.get(key)
        if is_unknown(v):
            out.append(s[pos:after])
        else:
            text = format_value(v)
            out.append(f"[{text}]" if text.startswith("-") else text)
            changed = True
        pos = after
    return [(start, end, "".join(out))] if changed else []


def _apply(line: str, code: Code, spans) -> str:
    """The line with each span of code replaced (None: the polar placeholder, kept as '\\0')."""
    out, last = [], 0
    for start, end, text in spans:
        a = code.cols[start]
        b = code.cols[end - 1] + 1
        out.append(line[last:a])
        out.append("\0" if text is None else text)
        last = b
        if text == "":                  # a removed assignment takes its blanks with it
            while last < len(line) and line[last] in " \t":
                last += 1
    out.append(line[last:])
    return "".join(out)


def place_polar(text: str, xy: tuple[float, float], upper: bool, polar: dict | None = None) -> str:
    """The rewritten line with its polar words replaced by X and Y words (at the first one), with
    the decimals of the polar words (``polar``: their values, :class:`~.expr.Number` s)."""
    decimals = max((decimals_of(v) for v in (polar or {}).values()), default=0)
    x, y = (format_value(v, decimals) for v in xy)
    words = f"{'X' if upper else 'x'}{x} {'Y' if upper else 'y'}{y}"
    first = text.index("\0")
    rest = re.sub("\0[ \t]*", "", text[first + 1:])
    return text[:first] + words + rest


def polar_target(polar: dict, words: dict, xy, incremental: bool) -> tuple[float, float]:
    """Where LinuxCNC's polar words send X and Y (LinuxCNC G-code reference, Polar Coordinates):
    from the XY zero of the program, the angle in degrees counter-clockwise from +X; in G91 the
    distance and the angle are added to those of the current position. xy : the current X Y in
    the program's frame (None: not known)."""
    if "x" in words or "y" in words:
        raise ExprError("polar words @ ^ and X or Y words in one line")
    if not incremental and "@" in polar and "^" in polar:
        r, t = polar["@"], math.radians(polar["^"])
        return r * math.cos(t), r * math.sin(t)
    if xy is None:
        raise ExprError("polar word from an X Y position the program has not given")
    if xy[0] == 0.0 and xy[1] == 0.0:
        raise ExprError("polar word with a missing distance or angle, or in G91, at the origin")
    r, t = math.hypot(xy[1], xy[0]), math.atan2(xy[1], xy[0])
    if incremental:
        r += polar.get("@", 0.0)
        t += math.radians(polar.get("^", 0.0))
    else:
        r = polar.get("@", r)
        t = math.radians(polar["^"]) if "^" in polar else t
    return r * math.cos(t), r * math.sin(t)


class XYTracker:
    """The X Y position in the program's frame along the expanded lines, for polar words: G90/G91,
    G20/G21, and the X Y words of moves; unknown after G28, G30, G53, G92, G10 and the like."""

    def __init__(self):
        self.xy = None            # (x, y) or None
        self.incremental = False

    def follow(self, words: dict, gcodes: list) -> None:
        for g in gcodes:
            if g == 90:
                self.incremental = False
            elif g == 91:
                self.incremental = True
            elif g in (20, 21) and self.xy is not None:
                f = 1 / 25.4 if g == 20 else 25.4
                self.xy = (self.xy[0] * f, self.xy[1] * f)
        if any(round(g) in (10, 28, 30, 52, 53, 92) for g in gcodes):
            self.xy = None
            return
        if any(round(g, 1) == 4.0 for g in gcodes):
            return
        if is_unknown(words.get("x", 0.0)) or is_unknown(words.get("y", 0.0)):
            self.xy = None                  # a value the controller holds
            return
        if "x" in words or "y" in words:
            if self.incremental:
                if self.xy is not None:
                    self.xy = (self.xy[0] + words.get("x", 0.0), self.xy[1] + words.get("y", 0.0))
            elif "x" in words and "y" in words:
                self.xy = (words["x"], words["y"])
            elif self.xy is not None:
                self.xy = (words.get("x", self.xy[0]), words.get("y", self.xy[1]))

    def set(self, xy) -> None:
        self.xy = xy


def gcodes_of(code: str) -> list[float]:
    """The G codes of a line's code (numbers only; computed ones are in the rewritten text)."""
    return [float(m.group(1)) for m in re.finditer(r"g([+-]?(?:\d+\.?\d*|\.\d+))", code)]

"""G-code words: the lowest layer of the reader (after pygcode: word -> block -> program).

A line of a program (ISO 6983 / RS-274, the subset in docs/toolpaths.md) is cut here into *tokens*:
words such as ``X-1.5`` and comments. This module also holds what the layers above share about
words: the units and tolerances, the tables of features refused by name (G and M codes, the
keywords of other languages), the drilling cycle codes, the *frame code* that packs the active
work coordinate system and tool length number into one int (:func:`frame_code`), and the text of a
written coordinate (:func:`position_text`, :func:`increment_text`).

Nothing here keeps state: :mod:`.modal` turns the tokens of a line into motion.
"""
from __future__ import annotations

import math
import re
from decimal import Decimal

import numpy as np

from ..errors import InputError

MM_PER_INCH = 25.4
#: an axis moving less than this (mm or rad) in a segment keeps its previous approach direction
DIR_EPS = 1e-9
DEFAULT_CHORD_TOL_MM = 1e-3
DEFAULT_CHUNK_SIZE = 65536
#: a reader's ``progress`` is told the lines read after every this many lines it interprets in
#: Python (and the compiled scanner after every block of the file it reads)
PROGRESS_LINES = 1024
#: the axis along the tool: a tool change or a tool length change leaves its position unknown
TOOL_AXIS = "Z"

_NUM = r"[+-]?(?:\d+\.?\d*|\.\d+)"
#: the control characters grbl drops as it reads a line (grbl 1.1, protocol.c: every byte up to
#: the blank but CR and LF, which end the line; tab is a blank, Ctrl-X its soft reset, taken out
#: of the stream before): :mod:`.linetext` drops them on grbl, other dialects refuse them
GRBL_DROPPED = re.compile(r"[\x00-\x08\x0b\x0c\x0e-\x17\x19-\x1f]")
_TOKEN_RE = re.compile(r"[ \t]+|\([^()]*\)|;.*|([A-Za-z])(" + _NUM + r")|(.)", re.S)
_AXIS_LETTERS = "XYZABC"
_UNIQUE_LETTERS = frozenset("XYZABCIJKRFNUVW")
#: whole G codes that change a mode mtcomp need not follow (nothing moves, the frame stays): G05
#: P10000 / G08 high-speed and look-ahead modes (LinuxCNC's G8: radius mode), G09 exact stop, G11
#: data setting off, G15 polar coordinates off, G40-G42 cutter compensation (G41/G42 noted where
#: the program is read), G61-G64 path control, G67 modal macro off, G96/G97 spindle speed modes,
#: G103 look-ahead, G187 smoothness, G113 polar interpolation off. Any whole G code that is
#: neither this nor one the reader follows (motion, planes, units, distance and feed modes, work
#: systems, tool length, cycles, dwell, home moves) is refused: its motion cannot be known.
MODE_ONLY_G = frozenset({5, 8, 9, 11, 15, 40, 41, 42, 61, 62, 63, 64, 67, 96, 97, 103, 113,
                         187})
#: G codes with a decimal part the reader follows or that change nothing it follows
KNOWN_DECIMAL_G = frozenset({5.1, 28.1, 30.1, 33.1, 43.1, 43.4, 54.1, 59.1, 59.2, 59.3,
                             61.1, 90.1, 91.1, 92.1, 92.2})
#: Haas' additional work coordinate systems (G154 P1-P99, G110-G129): positions are unknown after
#: a change to one, as after Fanuc's G54.1
OTHER_WCS_G = frozenset({154, *range(110, 130)})
#: whole G codes of modes the reader follows (planes, units, tool length, cycle cancel, distance
#: and feed modes, retract levels; the work systems apart)
FOLLOWED_MODE_G = frozenset({17, 18, 19, 20, 21, 43, 44, 49, 80, 90, 91, 93, 94, 98, 99})


def mode_followed(gi: int, letters) -> bool:
    """Whether the whole G code ``gi`` of a block whose word letters are ``letters`` is a mode the
    reader follows or one that changes no motion (the frame changes G50-G52, G68/G69, G100/G101
    are :mod:`.frames`')."""
    if gi in FOLLOWED_MODE_G or gi in _WCS_INDEX or gi in OTHER_WCS_G:
        return True
    return gi in MODE_ONLY_G
#: G codes that would change geometry in a way mtcomp does not follow: refused, never guessed
_REFUSED_G = {
    92.3: "G92.3 (the G92 offset restored from the controller's parameters, which may come from "
          "outside the program)",
    95: "G95 (feed per revolution)",
    74: "canned cycle G74 (left-hand tapping)", 76: "canned cycle G76 (threading)",
    33: "G33 (spindle-synchronised motion)",
    43.5: "G43.5 (tool centre point control with a tool axis vector I J K: only G43.4, with the "
          "rotary axes' angles, is followed)",
    68.2: "G68.2 (tilted working plane)", 68.3: "G68.3 (tilted working plane)",
    53.1: "G53.1 (tool axis direction control)",
    65: "G65 (macro call; in a Fanuc or Haas program whose macro is in the file, give "
        "--dialect fanuc or haas)",
    66: "G66 (modal macro call)",
    # moves that stop where a signal comes (the position after them is not the program's), and
    # coordinates that are not axis positions
    31: "G31 (skip function: the move stops where the signal comes, and later positions are unknown)",
    31.1: "G31.1 (multi-step skip: the move stops where the signal comes)",
    31.2: "G31.2 (multi-step skip: the move stops where the signal comes)",
    31.3: "G31.3 (multi-step skip: the move stops where the signal comes)",
    31.4: "G31.4 (multi-step skip: the move stops where the signal comes)",
    37: "G37 (automatic tool length measurement: the move stops at the sensor and sets the offset)",
    38.2: "G38.2 (probing move: it stops where the probe touches, and later positions are unknown)",
    38.3: "G38.3 (probing move: it stops where the probe touches, and later positions are unknown)",
    38.4: "G38.4 (probing move: it stops where the probe leaves, and later positions are unknown)",
    38.5: "G38.5 (probing move: it stops where the probe leaves, and later positions are unknown)",
    16: "G16 (polar coordinates: X and Y are a radius and an angle)",
    12.1: "G12.1 (polar coordinate interpolation)", 112: "G112 (polar coordinate interpolation)",
    7.1: "G7.1 (cylindrical interpolation)", 107: "G107 (cylindrical interpolation)",
    5.2: "G5.2 (NURBS)", 6.2: "G6.2 (NURBS)",
}
#: codes that are a curve when the block has coordinates, and a mode switch without them (Fanuc's
#: G05 P10000 high-precision contour control, G05.1 Q1 AI contour control pass through)
_CURVE_WITH_COORDINATES = {5: ("G5 (cubic spline)", frozenset("XYZABCIJKR")),
                           5.1: ("G5.1 (quadratic spline)", frozenset("XYZABCIJK"))}
#: M codes refused (subprograms, tool centre point control)
_REFUSED_M = {98: "M98 (subprogram call; in a Fanuc or Haas program whose subprogram is in the "
                  "file, give --dialect fanuc or haas)",
              97: "M97 (Haas' local subprogram call; give --dialect haas if a Haas runs it)",
              430: "M430 (LinuxCNC switchable kinematics: the program does not give axis positions)"}
#: M codes that switch tool centre point mode on (LinuxCNC's switchable kinematics M428, Heidenhain's
#: M128 in ISO programs) and off (M429: LinuxCNC's identity kinematics again; M129)
TCP_ON_M = frozenset({428, 128})
TCP_OFF_M = frozenset({429, 129})
#: drilling cycles: their lines pass through unchanged (not corrected), see docs/toolpaths.md
_CANNED_CYCLES = frozenset({73, 81, 82, 83, 84, 85, 86, 87, 88, 89})
#: the drilling cycles of Fanuc and Haas mills beyond RS274's: G74 left-hand (reverse) tapping and
#: G76 fine boring, a hole from R to Z at X Y like G84 and G86 (G76's shift Q at the bottom moves
#: the tool off the wall and back, the hole stays: Fanuc Series 0i-MF operator's manual, canned
#: cycles; Haas mill operator's manual, G74 Reverse Tap, G76 Fine Boring). Elsewhere G74 and G76
#: are other things (LinuxCNC's G76 is a lathe's threading cycle): refused
FANUC_CYCLES = frozenset({74, 76})
FANUC_DIALECTS = ("fanuc", "haas")
#: work coordinate systems, in the order of their index in ``frame`` codes
WORK_SYSTEMS = ("G54", "G55", "G56", "G57", "G58", "G59", "G59.1", "G59.2", "G59.3")
_WCS_INDEX = {54: 0, 55: 1, 56: 2, 57: 3, 58: 4, 59: 5, 59.1: 6, 59.2: 7, 59.3: 8}
_NEG_ZERO_RE = re.compile(r"-(0\.0+)(?![0-9])")
#: a program number written with ':' (the ISO code's O), alone or with comments
_COLON_PROGRAM_RE = re.compile(r":\s*\d+\s*(?:\([^()]*\)\s*)*(?:;.*)?$")
#: a block number before the end-of-tape mark ('N194 %', as some posts number every line)
_NUMBERED_PERCENT_RE = re.compile(r"[Nn]\s*\d+\s*%\s*$")
#: features of other languages, refused with their name (checked on lines that do not tokenize)
_O_WORD_RE = re.compile(r"^\s*(?:[Nn]\s*\d+\s*)?[Oo]\s*(?:\d+|<[^>]*>)\s*([A-Za-z]+)")
_KEYWORDS = {
    "TRAORI": "TRAORI (Siemens 5-axis transformation: tool centre point control)",
    "TRAFOOF": "TRAFOOF (Siemens transformation off)", "CYCLE": "Siemens cycle calls",
    "IF": "macro statement IF", "GOTO": "macro statement GOTO", "WHILE": "macro statement WHILE",
    "END": "macro statement END", "DO": "macro statement DO", "CALL": "subprogram CALL",
    "TOOL": "Heidenhain TOOL CALL", "DEF": "Siemens variable definition DEF",
    "BEGIN": "Heidenhain conversational program (BEGIN PGM)",
}


#: the bit of a frame code set where the program's frame is moved on the work system by the
#: program itself (G52, G68, a mirror image, scaling: :mod:`.frames`); the tool length number
#: stays below it
LOCAL_FRAME = 1 << 23
#: the bit of a frame code set in tool centre point mode (the words are the tool tip in the
#: workpiece frame and the rotary axes' angles, not axis positions: :mod:`.tcp`)
TCP_FRAME = 1 << 24
#: the lowest bit of the work offsets the program set itself (G10 L2/L20) in a frame code: the
#: index + 1 of the set in force (0: none), at most MAX_OFFSET_SETS distinct sets
OFFSET_SET_FRAME = 1 << 25
MAX_OFFSET_SETS = 31
#: the bit of a frame code set under Haas' dynamic work offset G254 (the work offset turned with
#: the rotary axes: :mod:`.haas5`); the highest of the int32 frame codes
DWO_FRAME = OFFSET_SET_FRAME * (MAX_OFFSET_SETS + 1)
#: the frame code's fields are bits (every constant above a power of two): the functions below
#: read them with bit operations, which numpy does some twenty times faster than // and %
#: (the same numbers for every integer, negative ones too)
OFFSET_SET_SHIFT = OFFSET_SET_FRAME.bit_length() - 1


#: tool length numbers H below this fit in a frame code
MAX_TOOL = LOCAL_FRAME // 16
#: the tool length "number" of a block after the program cancelled the tool length offset (G49)
#: or chose offset number 0 where its value is 0 (Fanuc's H00: :mod:`.lengths`): the spindle's
#: gauge point is the point programmed, tool length 0; H numbers stay below it
NO_LENGTH = MAX_TOOL - 1


def frame_code(wcs: int, tool: int, tcp: bool = False, offset_set: int = 0,
               local: bool = False, dwo: bool = False) -> int:
    """Pack the work coordinate system index (0 = G54 .. 8 = G59.3), the active tool length number H
    (0: none stated; NO_LENGTH: an offset of 0, G49; below MAX_TOOL), the tool centre point mode,
    the set of work offsets the program gave itself (0: none; k: the k-th distinct set,
    :mod:`.programmed`) and whether the program moved its frame (G52, G68, mirror, scaling) into
    one int, and whether Haas' dynamic work offset (G254) is in force:
    ``wcs + 16 * tool (+ LOCAL_FRAME) (+ TCP_FRAME) + OFFSET_SET_FRAME * offset_set (+ DWO_FRAME)``."""
    return (int(wcs) + 16 * int(tool) + (LOCAL_FRAME if local else 0) + (TCP_FRAME if tcp else 0)
            + OFFSET_SET_FRAME * int(offset_set) + (DWO_FRAME if dwo else 0))


def frame_wcs(code):
    """Work coordinate system index (0 = G54 ...) of frame codes (int or array)."""
    return np.asarray(code) & 15


def frame_tool(code):
    """Active tool length number H (0: none stated, NO_LENGTH: an offset of 0) of frame codes (int
    or array)."""
    return (np.asarray(code) & (LOCAL_FRAME - 1)) >> 4


def frame_local(code):
    """Whether frame codes (int or array) are under a frame the program moved (:mod:`.frames`)."""
    return (np.asarray(code) & LOCAL_FRAME) != 0


def frame_tcp(code):
    """Whether frame codes (int or array) are in tool centre point mode."""
    return (np.asarray(code) & TCP_FRAME) != 0


def frame_offset_set(code):
    """The set of programmed work offsets (0: none, k: the k-th) of frame codes (int or array)."""
    return (np.asarray(code) & (DWO_FRAME - 1)) >> OFFSET_SET_SHIFT


def frame_dwo(code):
    """Whether frame codes (int or array) are under Haas' dynamic work offset G254."""
    return (np.asarray(code) & DWO_FRAME) != 0


# --------------------------------------------------------------------------------------- tokens
def comment_end(text: str, pos: int) -> int:
    """Where the '(' comment that opens at ``pos`` ends (the index after its ')'), or -1 where it
    is not closed on the line. A comment is closed by its first ')' (RS-274); one that holds a
    '(' before that (a comment holding parentheses, ``(HSS Twist Drill, 3mm (R))``) is taken to
    where its parentheses balance (see :func:`nested_comment_problem`)."""
    e = text.find(")", pos)
    if e < 0:
        return -1
    if text.find("(", pos + 1, e) < 0:
        return e + 1
    depth = 0
    for i in range(pos, len(text)):
        c = text[i]
        if c == "(":
            depth += 1
        elif c == ")":
            depth -= 1
            if depth == 0:
                return i + 1
    return -1


#: what a control that ends a comment at its first ')' reads as further comments (a '(' opens
#: one, and the next ')' closes it whatever '(' come between)
_FIRST_CLOSE_COMMENT_RE = re.compile(r"\([^)]*\)")
#: a comment that holds a '(' before its first ')'
NESTED_COMMENT_RE = re.compile(r"\([^()]*\(")


def nested_comment_problem(text: str, pos: int, end: int) -> str | None:
    """Why the comment ``text[pos:end]``, whose parentheses nest and balance, cannot be read as one
    comment whatever the controller's rule, or None when it can. A control that nests parentheses
    reads it as one comment; a control that ends it at its first ')' reads what follows as code:
    the two agree when that is only ')', blanks and further comments (``(2D Contour (cutout))``
    leaves one ')', and no word either way)."""
    first = text.index(")", pos) + 1
    rest = _FIRST_CLOSE_COMMENT_RE.sub("", text[first:end])
    left = rest.replace(")", "").strip(" \t")
    if not left:
        return None
    return (f"comment '(' holds parentheses, and a control that ends it at its first ')' reads "
            f"{left[:20]!r} after it as code: {text[pos:end][:50]!r}")


def _strip_blanks(text: str) -> str:
    """The line without blanks outside comments: RS-274 ignores them (``Z 10`` is ``Z10``)."""
    if " " not in text and "\t" not in text:
        return text
    out = []
    pos, n = 0, len(text)
    while pos < n:
        ch = text[pos]
        if ch == "(":
            e = comment_end(text, pos)
            e = n if e < 0 else e
            out.append(text[pos:e])
            pos = e
        elif ch == ";":
            out.append(text[pos:])
            break
        else:
            if ch not in " \t":
                out.append(ch)
            pos += 1
    return "".join(out)


def _foreign_feature(text: str) -> str | None:
    """Name of a language feature mtcomp does not interpret, if the line uses one."""
    m = _O_WORD_RE.match(text)
    if m:
        return f"O-word {m.group(1).lower()} (subroutines and control flow)"
    code = strip_comments(text)
    if "#" in code:
        return "#-parameters"
    if "[" in code:
        return "expressions in [ ]"
    for word in re.findall(r"[A-Za-z]{2,}", code):
        key = word.upper()
        for k, name in _KEYWORDS.items():
            if len(k) >= 2 and key.startswith(k):
                return name
    return None


#: a feed word F without a number, followed by a blank, a comment or the line's end (not a letter
#: of a keyword: ``ENDIF``): Estlcam 11 writes one on every rapid (``G00 Z8.0000 F``) for Marlin,
#: which reads it as F seen without a value and keeps the feed in force (:mod:`.linetext`)
_EMPTY_F_RE = re.compile(r"(?<![A-Za-z])[Ff](?=[ \t]*(?:[(;]|$)|[ \t]+[A-Za-z])")


def empty_feed_at(text: str, pos: int) -> bool:
    """Whether the character at ``pos`` (in the line's code) is an F word without a number."""
    return _EMPTY_F_RE.match(text, pos) is not None


def empty_feeds(text: str) -> list[int]:
    """Where a line's F words without a number are (comments left out)."""
    if _EMPTY_F_RE.search(text) is None:
        return []
    return [m.start() for s, e in _code_parts(text) for m in _EMPTY_F_RE.finditer(text, s, e)]


def tokenize(text: str, path=None, line: int | None = None) -> list[tuple[str, str, str]]:
    """Cut one line (without its line ending) into tokens ``(letter, number, raw)``.

    letter is the upper-case word letter, or '(' / ';' for a comment (number '' then). Blanks
    inside words are ignored, as RS-274 prescribes (``Z 10`` is ``Z10``; raw is then ``Z10``).
    Raises InputError for anything that is not a word, a comment or blank; a line in a language
    mtcomp does not interpret (O-word subroutines, #-parameters, macro statements) is refused with
    the feature's name.
    """
    out = []
    pos, n = 0, len(text)
    compact = None
    while pos < n:
        m = _TOKEN_RE.match(text, pos)
        raw = m.group(0)
        if m.group(3) is not None:
            if compact is None:
                feature = _foreign_feature(text)
                if feature is not None:
                    raise InputError(f"{feature} not supported: {text.strip()[:40]!r}", path, line)
                compact = _strip_blanks(text)
                if compact != text:          # blanks inside words: read the line without them
                    return tokenize(compact, path, line)
            ch = m.group(3)
            if ch == "(":
                out.append(("(", "", _nested_comment(text, pos, path, line)))
                pos += len(out[-1][2])
                continue
            if ch.isalpha() and ch.isascii():
                raise InputError(f"word {ch.upper()} without a valid number: "
                                 f"{text[pos:pos + 12].strip()!r}", path, line)
            if ch < " " or ch == "\x7f":
                hint = (" (grbl drops it as it reads the line; give --dialect grbl if a grbl runs "
                        "the program)") if GRBL_DROPPED.match(ch) else ""
                raise InputError(f"control character 0x{ord(ch):02X}{hint}", path, line)
            raise InputError(f"unexpected character {ch!r} at column {pos + 1}", path, line)
        if m.group(1) is not None:
            out.append((m.group(1).upper(), m.group(2), raw))
        elif raw[0] in "(;":
            out.append((raw[0], "", raw))
        pos = m.end()
    return out


def _nested_comment(text: str, pos: int, path, line) -> str:
    """The comment holding parentheses that opens at ``pos``, where every reading of it agrees
    (:func:`nested_comment_problem`); InputError where it is not closed or where they differ."""
    end = comment_end(text, pos)
    if end < 0:
        raise InputError("comment '(' is not closed on this line", path, line)
    problem = nested_comment_problem(text, pos, end)
    if problem is not None:
        raise InputError(problem, path, line)
    return text[pos:end]


# ------------------------------------------------------------------- the source line, rewritten
#: a word with blanks anywhere in it (RS-274 ignores them: ``Z - 1`` is ``Z-1``); a quoted string
#: parameter (RepRapFirmware's ``S"..."``, ``""`` one quote inside: :mod:`.rrf`) is kept as written,
#: and so are the control characters grbl drops between words
_SPAN_RE = re.compile(r"[ \t\x00-\x08\x0b\x0c\x0e-\x17\x19-\x1f]+|\([^()]*\)|;.*|"
                      r"([A-Za-z])[ \t]*"
                      r"([+-]?[ \t]*(?:\d[\d \t]*\.?[\d \t]*|\.[ \t]*\d[\d \t]*))|"
                      r'[A-Za-z]?"(?:[^"]|"")*"|(.)', re.S)
_BOM = "\xef\xbb\xbf"


def number_decimals(number: str) -> int:
    """Digits after the decimal point of a number as written (``'10.'`` -> 0, ``'1.25'`` -> 2)."""
    dot = number.find(".")
    return 0 if dot < 0 else len(number) - dot - 1


def format_number(value: float, decimals: int) -> str:
    """``value`` with ``decimals`` digits after the point; ``-0.000`` is written ``0.000``."""
    s = f"{value:.{decimals}f}"
    if s.startswith("-0") and _NEG_ZERO_RE.fullmatch(s):
        s = s[1:]
    return s


def base_decimals(rot: bool, inch: bool) -> int:
    """The fewest decimals a corrected coordinate is written with: 4 in mm and deg, 5 in inch."""
    return 5 if inch and not rot else 4


def program_units(v: float, rot: bool, inch: bool) -> float:
    """An axis value v (mm, rad) in the program's units (mm, inch, deg)."""
    return math.degrees(v) if rot else (v / MM_PER_INCH if inch else v)


def machine_units(x: float, rot: bool, inch: bool) -> float:
    """A value x written in the program's units (mm, inch, deg) in mm and rad, as the reader
    takes it."""
    return math.radians(x) if rot else x * (MM_PER_INCH if inch else 1.0)


def position_text(v: float, rot: bool, inch: bool, decimals: int) -> str:
    """The text of an axis position v (mm, rad) in the program's units (mm, inch, deg)."""
    return format_number(program_units(v, rot, inch), decimals)


def grid_text(v: float, rot: bool, inch: bool) -> str:
    """The text of an axis position v (mm, rad) at the fewest decimals of a corrected word (what
    tells whether a written coordinate changes)."""
    return position_text(v, rot, inch, base_decimals(rot, inch))


def increment_text(step: float, change: float, rot: bool, inch: bool, decimals: int) -> str:
    """The G91 word of an axis: the input's increment ``step`` plus the change of the written
    correction ``change`` (both mm or rad), each taken on the word's grid (``decimals`` in the
    program's units). A change that rounds to zero gives back the input's increment exactly,
    whatever the units the program stood in before; the output never drifts from the corrected
    path by more than the rounding of one word, since ``change`` is taken from where the output
    stands."""
    total = Decimal(position_text(step, rot, inch, decimals)) + \
        Decimal(position_text(change, rot, inch, decimals))
    return f"{abs(total) if total == 0 else total:.{decimals}f}"


def _line_words(text: str, pos: int) -> list | None:
    out = []
    n = len(text)
    while pos < n:
        m = _SPAN_RE.match(text, pos)
        if m.group(3) is not None:
            if empty_feed_at(text, pos):          # kept as written (read only where accepted)
                pos += 1
                continue
            end = comment_end(text, pos) if text[pos] == "(" else -1
            if end < 0:
                return None
            out.append(("(", pos, pos, end))          # a comment holding parentheses
            pos = end
            continue
        if m.group(1) is not None:
            end = m.start(2) + len(m.group(2).rstrip(" \t"))
            out.append((m.group(1).upper(), m.start(), m.start(2), end))
            pos = end
            continue
        if text[pos] in "(;":
            out.append((text[pos], pos, pos, m.end()))
        pos = m.end()
    return out


class SourceLine:
    """A source line to be rewritten in place: its words with their places, and the edits to it.

    words : ``(letter, letter position, number start, number end)`` per word in line order (the
    letter upper-case; comments as ``('(' or ';', start, start, end)``). The edits replace the
    number of a word, a whole word, or insert words at a place; :meth:`render` applies them and
    leaves every other character as written. A line with blanks inside a number (``X1 0``) is
    taken without its blanks (RS-274 ignores them). ``sep`` is the blank put between inserted words
    (none when the line writes two words or more and no blank); ``lower``: the line writes its letters in lower case
    (judged by its first axis word, else its first word).
    """

    def __init__(self, text: str):
        start = 3 if text.startswith(_BOM) else 0
        words = _line_words(text, start)
        if words is None and GRBL_DROPPED.search(text):     # one inside a word (grbl drops it)
            text = text[:start] + GRBL_DROPPED.sub("", text[start:])
            words = _line_words(text, start)
        if words is None:
            text = text[:start] + _strip_blanks(text[start:])
            words = _line_words(text, start) or []
        self.text = text
        self.words = words
        self.start = start
        letters = sum(w[0] not in "(;" for w in words)
        self.sep = " " if (" " in text or "\t" in text or letters < 2) else ""
        first = next((w for w in words if w[0] in _AXIS_LETTERS), None) or \
            next((w for w in words if w[0] not in "(;"), None)
        self.lower = first is not None and text[first[1]].islower()
        self.edits: list[tuple[int, int, int, str]] = []

    def letter(self, c: str) -> str:
        """A letter in the line's case."""
        return c.lower() if self.lower else c

    def find(self, letter: str):
        """The first word with this letter (upper case), or None."""
        for w in self.words:
            if w[0] == letter:
                return w
        return None

    def number(self, w) -> str:
        """The number of a word as written, without blanks."""
        return self.text[w[2]:w[3]].replace(" ", "").replace("\t", "")

    def replace_number(self, w, number: str) -> None:
        self.edits.append((w[2], w[3], 1, number))

    def replace_word(self, w, text: str) -> None:
        self.edits.append((w[1], w[3], 1, text))

    def delete(self, w) -> None:
        """Remove a word and the blanks after it (or before it, at the end of the line)."""
        s, e = w[1], w[3]
        t = self.text
        while e < len(t) and t[e] in " \t":
            e += 1
        if e == len(t):
            e = w[3]
            while s > self.start and t[s - 1] in " \t":
                s -= 1
        self.edits.append((s, e, 1, ""))

    def insert_head(self, words: list[str]) -> None:
        """Words at the start of the line's block: after its N word, else before its first word."""
        if not words:
            return
        n = self.find("N")
        if n is not None:
            self.edits.append((n[3], n[3], 0, self.sep + self.sep.join(words)))
            return
        pos = self.words[0][1] if self.words else len(self.text)
        self.edits.append((pos, pos, 0, self.sep.join(words) + self.sep))

    def append_pos(self, letters: str = _AXIS_LETTERS) -> int:
        """Where appended words go: after the line's last word with one of these letters (its
        axis words), else after its motion word, else before its first comment, else at the end
        (as a negative position: words go before a comment, ``-1 - pos``)."""
        last = [w for w in self.words if w[0] in letters]
        if last:
            return last[-1][3]
        motion = [w for w in self.words if w[0] == "G" and float(self.number(w)) in (0, 1, 2, 3)]
        if motion:
            return motion[0][3]
        comment = [w for w in self.words if w[0] in "(;"]
        if comment:
            return -1 - comment[0][1]
        return len(self.text.rstrip(" \t"))

    def insert_at(self, pos: int, words: list[str]) -> None:
        if not words:
            return
        if pos < 0:
            self.edits.append((-1 - pos, -1 - pos, 2, self.sep.join(words) + self.sep))
        else:
            self.edits.append((pos, pos, 2, self.sep + self.sep.join(words)))

    def render(self) -> str:
        if not self.edits:
            return self.text
        out = []
        pos = 0
        for s, e, _kind, new in sorted(self.edits, key=lambda x: (x[0], x[2])):
            out.append(self.text[pos:s])
            out.append(new)
            pos = max(pos, e)
        out.append(self.text[pos:])
        text = "".join(out)
        # two words deleted at the line's end leave the blank between them: a line that ended
        # without blanks still does
        return text.rstrip(" \t") if self.text == self.text.rstrip(" \t") else text


_CUTTER_COMP_RE = re.compile(r"(?i)g0*4([012])(?![\d.])")
_COMMENT_TEXT_RE = re.compile(r"\([^()]*\)|;.*")


def strip_comments(line: str) -> str:
    """A line's text without its comments ('( )' and ';' to the end; a comment holding
    parentheses to where they balance, :func:`comment_end`; one not closed is kept)."""
    if "(" not in line or not NESTED_COMMENT_RE.search(line):
        return _COMMENT_TEXT_RE.sub("", line)
    return "".join(line[s:e] for s, e in _code_parts(line))


def _code_parts(line: str) -> list[tuple[int, int]]:
    """The (start, end) places of a line's code between its comments (see :func:`strip_comments`)."""
    parts = []
    pos = start = 0
    n = len(line)
    while pos < n:
        ch = line[pos]
        if ch == ";":
            break
        end = comment_end(line, pos) if ch == "(" else -1
        if ch == "(" and end > 0:
            parts.append((start, pos))
            pos = start = end
            continue
        pos += 1
    parts.append((start, pos))
    return parts


def cutter_comp_code(text: str) -> int | None:
    """The last of G40, G41, G42 a line's words give (comments left out), or None."""
    codes = _CUTTER_COMP_RE.findall(strip_comments(text))
    return 40 + int(codes[-1]) if codes else None

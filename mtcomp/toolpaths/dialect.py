"""Controller dialects: the rules that differ between controllers, and how a program shows its own.

A :class:`Dialect` holds what the reader needs to know of the controller that runs the program
(docs/toolpaths.md, "Dialects", cites each controller's manual):

* ``g80_keeps_motion``: after G80 the group-01 motion mode in force before the drilling cycle is in
  force again (Fanuc, Haas: the cycles are a modal group of their own), or no motion mode is
  (LinuxCNC: G80 is in the motion group; grbl: G80 is "motion mode cancel").
* ``g98_to_higher``: G98 retracts to the higher of the initial level and the R plane (LinuxCNC);
  elsewhere the Z after a G98 cycle is known only where the R plane lies below the initial level.
* ``incremental_r_from_initial``: in G91 the R of every hole of a series is measured from the
  series' initial level (LinuxCNC), so a series may continue under G99.
* ``cycle_words_as_numbers``: a drilling cycle keeps its R and Z as the numbers last written and
  reads them in the distance mode in force at each line (LinuxCNC's ``interp_cycles.cc``,
  ``convert_cycle_xy``); elsewhere a cycle line whose R or Z was given in the other distance mode
  is not read.
* ``local_shift``: G52 is a local shift of the work system (LinuxCNC, Fanuc; on a Haas its meaning
  follows Setting 33). ``rotation``: G68/G69 coordinate rotation (Fanuc, Haas). ``mirror``: the
  mirror image code ('G51.1': Fanuc's G51.1/G50.1; 'G101': Haas' G101/G100). ``scale_words``: the
  words of G51 scaling ('PIJK' Fanuc, 'P' Haas, '' none): :mod:`.frames`.
* ``arcs_modal``: G2/G3 stay in force for the blocks after them (RS274); False on BeagleG, whose
  blocks of axis words alone after an arc move in the last G0/G1 mode.
* ``language``: 'ngc' (LinuxCNC's O-words and parameters, :mod:`.ngc`), 'macro' (Fanuc macro B,
  :mod:`.macro`), 'heidenhain' (a conversational program, read through its G-code equivalent:
  :mod:`.heidenhain`), 'sinumerik' (a Siemens Sinumerik program, likewise: :mod:`.sinumerik`) or
  None (nothing is expanded), 'beagleg' (BeagleG's parameters and loops, written in LinuxCNC's
  form by :mod:`.beagleg` and run by :mod:`.ngc`). RepRapFirmware's rules (quoted strings, the
  codes it runs as macro files) are :mod:`.rrf`'s, for the dialect named 'rrf'.

:func:`detect` reads the start of a program (and :func:`needs_expansion` all of it, in blocks).
"""
from __future__ import annotations

import os
import re
from dataclasses import dataclass

from ..errors import InputError
from .words import _WCS_INDEX, strip_comments


@dataclass(frozen=True)
class Dialect:
    name: str
    g80_keeps_motion: bool = False
    g98_to_higher: bool = False
    incremental_r_from_initial: bool = False
    cycle_words_as_numbers: bool = False
    language: str | None = None
    local_shift: bool = False
    rotation: bool = False
    mirror: str | None = None
    scale_words: str = ""
    arcs_modal: bool = True


DIALECTS = {
    "linuxcnc": Dialect("linuxcnc", g98_to_higher=True, incremental_r_from_initial=True,
                        cycle_words_as_numbers=True, language="ngc", local_shift=True),
    "fanuc": Dialect("fanuc", g80_keeps_motion=True, language="macro", local_shift=True,
                     rotation=True, mirror="G51.1", scale_words="PIJK"),
    "haas": Dialect("haas", g80_keeps_motion=True, language="macro", rotation=True,
                    mirror="G101", scale_words="P"),
    "grbl": Dialect("grbl"),
    # RepRapFirmware (Duet3D): quoted string parameters, codes it runs as macro files (.rrf)
    "rrf": Dialect("rrf"),
    # Heidenhain TNC conversational (Klartext): read through its G-code equivalent (.heidenhain)
    "heidenhain": Dialect("heidenhain", language="heidenhain"),
    # Siemens Sinumerik 840D: read through its G-code equivalent (.sinumerik)
    "sinumerik": Dialect("sinumerik", language="sinumerik"),
    # BeagleG (BeagleBone CNC): its parameters and loops read through LinuxCNC's (.beagleg)
    "beagleg": Dialect("beagleg", language="beagleg", arcs_modal=False),
    "generic": Dialect("generic", language="ngc"),
}
GENERIC = DIALECTS["generic"]

_OWORD_KEYWORD = (r"o[ \t]*(?:<[^>\n]*>|\[[^\n]*?\]|\d+)[ \t]*(?:endsub|sub|call|return|elseif|"
                  r"else|endif|if|endwhile|while|do|endrepeat|repeat|break|continue)")
_MACRO_STATEMENT = r"if[ \t]*\[|goto[ \t]*[#\d]|while[ \t]*\[|end[ \t]*\d[ \t]*(?:[(;\r]|$)"
_STATEMENT_LINE = re.compile(
    rb"(?im)^[ \t]*(?:n[ \t]*\d+[ \t]*)?(?:" + _OWORD_KEYWORD.encode() + rb"|"
    + _MACRO_STATEMENT.encode() + rb")")
#: a subprogram call: M98, or Haas' M97
_CALL = re.compile(rb"(?i)m[ \t]*0*9[78](?![\d.])")
#: a macro call: G65
_MACRO_CALL = re.compile(rb"(?i)(?<![a-z])g[ \t]*0*65(?![\d.])")
#: a '65' that a G comes before with only zeros and blanks between (the places _MACRO_CALL is
#: tried): one pattern per case of the letter, so that each starts with a literal
_G_65 = (re.compile(rb"G[0 \t]*65"), re.compile(rb"g[0 \t]*65"))
_CLUES = [
    ("linuxcnc", re.compile(r"(?i)^\s*(?:n\s*\d+\s*)?" + _OWORD_KEYWORD + r"|o\s*<|#\s*<")),
    ("linuxcnc", re.compile(r"\^\s*[-+.\d\[#]")),         # a polar angle word: LinuxCNC's alone
    # its switchable kinematics (M428 tool centre point on, M429 off, M430): LinuxCNC's own codes
    ("linuxcnc", re.compile(r"(?i)(?<![a-z_])m\s*0*4(?:2[89]|30)(?![\d.])")),
    ("fanuc", re.compile(r"(?i)^\s*(?:n\s*\d+\s*)?(?:" + _MACRO_STATEMENT + r")")),
    ("fanuc", re.compile(r"^\s*[Oo:]\s*\d+\s*(?:\([^()]*\)\s*)*$")),   # a program number O1234
    ("grbl", re.compile(r"^\s*(?:\$[A-Za-z$#]|[?~!]\s*$)")),
    # a TNC conversational program's BEGIN PGM, a DIN/ISO program's first block %NAME G71 *
    ("heidenhain", re.compile(r"(?i)^\s*\d+\s+BEGIN\s+PGM\b|"
                              r"^\s*(?:N\s*\d+\s*)?%\s*\S+\s+G\s*7[01]\s*\*?\s*(?:;.*)?$")),
    # Sinumerik: its file header, its path line, a DEF of a variable, a standard cycle call, a
    # message to the operator MSG("..."), an arithmetic parameter set at a block's start (`R1=0`;
    # SINUMERIK 840D sl Programming Manual, Fundamentals, "Arithmetic parameters (R)": Fanuc and
    # LinuxCNC number theirs #1, a TNC's are Q parameters)
    ("sinumerik", re.compile(r"(?i)^\s*%(?:_N_\w+_(?:MPF|SPF)|MPF|SPF)\b|^\s*;\s*\$PATH=|"
                             r"^\s*(?:N\d+\s*)?DEF\s+(?:REAL|INT|BOOL)\b|"
                             r"^\s*(?:N\d+\s*)?(?:MCALL\s+)?CYCLE\d+\s*\(|"
                             r"^\s*(?:N\d+\s*)?MSG\s*\(\s*\"|"
                             r"^\s*(?:N\d+\s*)?R\d+\s*=")),
    # a parameter named without brackets (`#r=50`, `#i++`): BeagleG's alone (LinuxCNC names one
    # #<r>, Fanuc numbers them)
    ("beagleg", re.compile(r"(?i)(?<![\w<])#[ \t]*[a-z_][a-z0-9_]*[ \t]*(?:=|\+\+|--|[-+*/]=)")),
    # a quoted string parameter (M98 P"file.g", M4000 S"name"): RepRapFirmware's alone
    ("rrf", re.compile(r'(?i)^\s*(?:n\s*\d+\s*)?[gmt]\s*\d[^"]*"')),
]
#: controllers whose own language mtcomp does not read, known from a program's first lines:
#: (pattern, the language's name, what in it differs from RS274 / ISO G-code)
_FOREIGN = [
    (re.compile(r"(?i)^\s*\$[\w.-]+\.(?:MIN|SSB|SDF)%?\s*$"), "Okuma OSP",
     "named programs and labels, VC variables, IF/GOTO"),
]
_FOREIGN_LINES = 3      # the first lines looked at for them
_HAAS = re.compile(r"(?i)haas")
#: codes of the Haas mill control that a Fanuc does not have (Haas mill operator's manual, G and M
#: codes): G187 smoothness, G154 P work offsets, G103 look-ahead, M97 local subprogram call, G234
#: tool centre point control, G254/G255 dynamic work offset
_HAAS_CODES = re.compile(r"(?i)(?<![A-Z])(?:G\s*187(?![\d.])|G\s*154\s*P|G\s*103(?![\d.])|M\s*97\s*P"
                         r"|G\s*2(?:34|54|55)(?![\d.]))")
#: a comment that names the controller
_NAMED = re.compile(r"(?i)[(;][^)]*\b(fanuc|haas|linuxcnc|grbl|rrf|reprapfirmware|millenniumos|"
                    r"beagleg)\b")
#: names of a controller in a comment -> its dialect
_NAME_DIALECT = {"reprapfirmware": "rrf", "millenniumos": "rrf"}
_HEAD = 1 << 16          # bytes of the program's start read for its dialect


def _haas_codes(lines) -> bool:
    """Whether the lines use a code only the Haas control has (:data:`_HAAS_CODES`), outside
    comments."""
    return any(_HAAS_CODES.search(strip_comments(line)) for line in lines)


def detect(path) -> tuple[Dialect, str]:
    """(the program's dialect, why: 'detected from line N: ...' or what was taken). The first
    clue in the first 64 kB wins: LinuxCNC's O-words, named parameters, polar angle word or
    switchable kinematics codes (M428, M429, M430), a Fanuc macro statement
    or program number (Haas where the program names Haas or uses a code only Haas has), grbl's '$' commands or real-time
    characters, RepRapFirmware's quoted string parameters, Sinumerik's file header
    ``%_N_NAME_MPF``, ``;$PATH=``, a DEF, a CYCLE call, ``MSG("...")`` or ``R1=`` at a block's
    start, a comment naming the controller (rrf
    for RepRapFirmware, RRF or MillenniumOS); nothing: generic."""
    try:
        with open(os.fspath(path), "rb") as f:
            head = f.read(_HEAD)
    except OSError:
        return GENERIC, "nothing in the program names a controller"
    text = head.decode("latin-1")
    lines = text.splitlines()
    if len(head) == _HEAD:
        lines = lines[:-1]
    for k, line in enumerate(lines, 1):
        code = strip_comments(line) if not line.lstrip().startswith(("$", "?", "~", "!")) else line
        named = _NAMED.search(line)
        by_name = _NAME_DIALECT.get(named.group(1).lower(), named.group(1).lower()) if named else ""
        for name, clue in _CLUES + ([(by_name, re.compile(""))] if named else []):
            if clue.search(line if name == "sinumerik" else code):
                if name == "fanuc" and (_HAAS.search(text) or _haas_codes(lines)):
                    name = "haas"
                shown = line.strip()
                shown = shown if len(shown) <= 40 else shown[:37] + "..."
                return DIALECTS[name], f"detected from line {k}: {shown}"
    return GENERIC, "nothing in the program names a controller"


def foreign_language(path) -> tuple[int, str, str, str] | None:
    """(line, the line, the language's name, what differs) when one of a program's first lines
    shows a controller language mtcomp does not read (Okuma ``$NAME.MIN%``), else None."""
    try:
        with open(os.fspath(path), "rb") as f:
            head = [f.readline().decode("latin-1") for _ in range(_FOREIGN_LINES)]
    except OSError:
        return None
    for k, line in enumerate(head, 1):
        for pattern, name, what in _FOREIGN:
            if pattern.search(line):
                return k, line.strip(), name, what
    return None


def dialect_named(name: str | None, path) -> tuple[Dialect, str]:
    """The dialect given by name (``--dialect``), or detected when None."""
    if name is None:
        return detect(path)
    key = name.lower()
    if key not in DIALECTS:
        raise InputError(f"unknown dialect {name!r} (one of: {', '.join(DIALECTS)})")
    return DIALECTS[key], "given"


def needs_expansion(path, block: int = 1 << 16, macro_calls: bool = False) -> bool:
    """True if the program has code to compute: an O-word or macro statement at a line's start, or
    '#', '[', '@', '^' outside comments, a subprogram call, and with ``macro_calls`` (a Fanuc or
    Haas program) a G65. Reads the file in blocks (memory stays flat)."""
    try:
        f = open(os.fspath(path), "rb")
    except OSError:
        return False              # the reader names the problem
    tail = b""
    with f:
        while True:
            data = f.read(block)
            chunk = tail + data
            if not data:
                return _has_code(chunk, macro_calls)
            cut = chunk.rfind(b"\n") + 1
            if _has_code(chunk[:cut], macro_calls):
                return True
            tail = chunk[cut:]




def _has_code(chunk: bytes, macro_calls: bool = False) -> bool:
    """Whether a block of whole lines has code to compute. Cheap searches find the lines that may
    (a '#', '[', '@', '^', an 'O' before a number or label); only those lines are read. A GOTO
    without any of these is left to the reader, which refuses it by name. A subprogram call (M98,
    Haas' M97) counts too, and with ``macro_calls`` (a Fanuc or Haas program) a macro call G65:
    the macro runner expands them."""
    # an M is rare in a program (a regular expression over the whole block took 1.5 ms per 64 kB);
    # a '65' is not rare in coordinates: only those that a G (zeros and blanks between) comes
    # before are read, found by a pattern that starts with its letter (the regular expression
    # engine skips to each G at memchr speed; a G is rarer than a '65' in coordinates)
    calls = [(p, _CALL) for ch in (b"M", b"m") for p in _finds(chunk, ch) if _CALL.match(chunk, p)]
    if macro_calls:
        calls += [(m.end() - 2, _MACRO_CALL) for g in _G_65 for m in g.finditer(chunk)]
    for pos, pattern in calls:
        start = chunk.rfind(b"\n", 0, pos) + 1
        end = chunk.find(b"\n", pos)
        line = chunk[start:len(chunk) if end < 0 else end].decode("latin-1")
        if pattern.search(strip_comments(line).encode("latin-1")):
            return True
    for ch in (b"#", b"[", b"@", b"^", b"o", b"O"):
        for pos in _finds(chunk, ch):
            if ch in b"oO" and chunk[pos + 1:pos + 3].lstrip(b" \t")[:1] not in b"0123456789<[":
                continue
            start = chunk.rfind(b"\n", 0, pos) + 1
            end = chunk.find(b"\n", pos)
            line = chunk[start:len(chunk) if end < 0 else end]
            if _STATEMENT_LINE.match(line):
                return True
            if ch in (b"#", b"[", b"@", b"^") and ch.decode() in strip_comments(line.decode("latin-1")):
                return True
    return False


def _finds(chunk: bytes, what: bytes):
    """Positions of ``what`` in ``chunk`` (bytes.find: memchr speed)."""
    pos = chunk.find(what)
    while pos >= 0:
        yield pos
        pos = chunk.find(what, pos + 1)


def grbl_program_end(state) -> None:
    """grbl after M2/M30 (grbl 1.1, gcode.c, program flow): it goes on with the lines a sender
    streams after it, its modes reset to G1 G17 G90 G94 G54 (positions kept, G92 kept); uCNC's
    reset turns its height map off too (parser.c, parser_reset)."""
    state.ended = False
    state.height_map = False
    state.motion, state.incremental, state.inverse_time = 1, False, False
    state._apply_modal_code(17, {})
    state._set_wcs(_WCS_INDEX[54])


#: BeagleG's G codes (its G-code.md, "G Codes"; src/gcode-parser/gcode-parser.cc, ParseBlock). It
#: hands any other to the machine control, which acts on M codes only
#: (src/gcode-machine-control.cc, special_commands) and then reads the block's axis words as a move.
#: G70/G71 are its inch/mm, as G20/G21 (ParseBlock, lines 1913-1914)
_BEAGLEG_G = frozenset([0, 1, 2, 3, 4, 5, 5.1, 10, 17, 18, 19, 20, 21, 28, 50, 51, 54, 55, 56, 57,
                        58, 59, 59.1, 59.2, 59.3, 70, 71, 90, 91, 92, 92.1, 92.2, 92.3])
#: BeagleG's axis letters (gcode-parser.cc, gcodep_letter2axis), and the other words a move, an arc
#: or a spline reads after its G code (handle_move, handle_arc, handle_spline); with F, S and G10's
#: L they do not end a move
_BEAGLEG_AXES = "XYZABCUVWE"
_BEAGLEG_ARGS = "IJKRPQ"
_BEAGLEG_UNITS_G = ("20", "21", "70", "71")


def beagleg_word_order(state, tokens, line: int) -> None:
    """Refuse a line BeagleG does not read as one block. Its ParseBlock (gcode-parser.cc, lines
    1860-1982) acts on each word in turn: axis words move at once, in the modes set by the words
    before them, and a move ends at the first word that is not an axis word, F or S (handle_move,
    lines 1444-1459: an M, N or T word ends it). So a G word after an axis word (or after I J K R
    P Q, which an earlier G code reads in the units then in force) applies after that move, an F
    before G20/G21/G70/G71 is read in the units before them, and axis words after a word that
    ended a move make a second move; mtcomp reads a line as one block, and would correct it so."""
    first = ended = feed = None     # the first axis (or arc) word; the word that ended its move
    last_g = None
    for letter, number, raw in tokens:
        if letter in "(;" or (letter == "P" and last_g == "4"):
            continue                # a dwell's time (set_param: no units), done before what follows
        last_g = (number.lstrip("0") or "0") if letter == "G" else last_g
        before = feed if letter == "G" and number.lstrip("0") in _BEAGLEG_UNITS_G else None
        before = first if first is not None and letter == "G" else before
        if before is not None:
            raise state._err(f"{before} comes before {raw} on this line: BeagleG reads a line's "
                             f"words in turn and acts on {before} before {raw} applies (mtcomp "
                             f"reads the line as one block): put {raw} first", line)
        if letter in _BEAGLEG_AXES + "F" and ended is not None:
            raise state._err(f"{raw} comes after {ended}, which ends the move of {first} on this "
                             f"line: BeagleG reads a line's words in turn and makes a second move "
                             f"(mtcomp reads the line as one block): put {ended} last", line)
        if letter in _BEAGLEG_AXES + _BEAGLEG_ARGS:
            first = raw if first is None else first
        elif letter == "F":
            feed = raw if feed is None else feed
        elif first is not None and letter not in "SL" and ended is None:
            ended = raw


def beagleg_block(state, gcodes, line: int) -> None:
    """BeagleG's rules for a block, before its codes apply (docs/toolpaths.md, "BeagleG"): G2/G3 do
    not stay in force (gcode-parser.cc, ParseBlock: axis words alone move in the last G0/G1 mode,
    G0 at the start), G70/G71 are read as G20/G21 (``gcodes`` changed in place), a G code it does
    not have is refused (it would ignore it and move). Its G30, a Z probe, is :mod:`.probe`'s,
    taken out of ``gcodes`` before this."""
    if not hasattr(state, "linear_motion"):
        state.linear_motion = 0 if state.motion is None else state.motion
        state.motion = state.linear_motion
    if state.motion in (2, 3):
        state.motion = state.linear_motion
    gcodes[:] = [{70: 20, 71: 21}.get(g, g) for g in gcodes]
    for g in gcodes:
        if g not in _BEAGLEG_G:
            raise state._err(f"G{g:g} is not a BeagleG code (BeagleG ignores it and moves to the "
                             "block's axis words)", line)
        if g in (0, 1):
            state.linear_motion = int(g)

"""RepRapFirmware (RRF): quoted string parameters, and the codes the firmware runs as macro files.

RepRapFirmware reads a parameter's value in double quotes as a string (``M4000 P11 S"Face Mill"``:
Duet3D, RepRapFirmware G-code dictionary, docs.duet3d.com; RepRapFirmware 3.5, StringParser.cpp: a
doubled quote ``""`` inside is one quote character, and a ``;`` or ``(`` inside is part of the
string). Such a parameter moves nothing: :func:`without_strings` takes it out of the text the
reader tokenizes; the line is written as it is (in a move only the corrected words change).

A G or M code the firmware does not implement itself is a call of the macro file ``/sys/G<n>.g``
or ``/sys/M<n>.g`` (``G<n>.<f>.g`` with a decimal part), and a T word is a tool change that runs the
tool change macros ``tfree``, ``tpre`` and ``tpost`` (Duet3D, RepRapFirmware G-code dictionary, T;
RepRapFirmware 3.5 ``GCodes2.cpp``: ``TryMacroFile`` for every code its ``HandleGcode`` and
``HandleMcode`` do not list). The macros live on the controller, not in
the program: after one, every axis's position is unknown until the program names it again (as
after a subprogram not in the file), and a work offset the macro sets (MillenniumOS's ``G6600``
probes the work system's origin) is the controller's, taken from the work offsets given on the
command line. :func:`macro_codes` takes those codes out of a line's codes and applies that.
"""
from __future__ import annotations

import math
import re

from ..errors import InputError
from .words import strip_comments

#: G codes RepRapFirmware implements itself (G-code dictionary; GCodes2.cpp, HandleGcode);
#: decimal parts only on G38 and G59
NATIVE_G = frozenset({0, 1, 2, 3, 4, 10, 11, 17, 18, 19, 20, 21, 28, 29, 30, 31, 32, 38, 53, 54,
                      55, 56, 57, 58, 59, 60, 68, 69, 90, 91, 92, 93, 94})
_DECIMAL_G = frozenset({38, 59})
#: native G codes whose moves the program does not hold: G29 mesh probing (mesh.g), G30 single
#: Z probe (it may set Z), G32 bed probing (bed.g)
_PROBING_G = frozenset({29, 30, 32})
#: native G codes that change nothing the reader follows: G31 sets or reports the Z probe's
#: trigger height and offsets, G60 saves the position in a memory slot
_NO_MOTION_G = frozenset({31, 60})
#: M codes RepRapFirmware implements itself (RepRapFirmware 3.5, GCodes2.cpp, HandleMcode)
NATIVE_M = frozenset({
    0, 1, 2, 3, 4, 5, 17, 18, 20, 21, 22, 23, 24, 25, 26, 27, 28, 29, 30, 32, 36, 37, 38, 39, 42,
    73, 80, 81, 82, 83, 84, 85, 92, 98, 99, 101, 102, 103, 104, 105, 106, 107, 108, 109, 110, 111,
    112, 114, 115, 116, 117, 118, 119, 120, 121, 122, 140, 141, 143, 144, 150, 190, 191, 200, 201,
    203, 204, 205, 206, 207, 208, 220, 221, 226, 260, 261, 280, 290, 291, 292, 300, 301, 302, 303,
    304, 305, 307, 308, 309, 350, 374, 375, 376, 400, 401, 402, 404, 407, 408, 409, 425, 450, 451,
    452, 453, 470, 471, 472, 486, 500, 501, 502, 503, 505, 540, 550, 551, 552, 553, 554, 555, 556,
    557, 558, 559, 560, 561, 562, 563, 564, 566, 567, 568, 569, 570, 571, 572, 574, 575, 576, 577,
    579, 581, 582, 584, 585, 586, 587, 588, 589, 591, 592, 593, 594, 595, 596, 597, 598, 599, 600,
    601, 606, 665, 666, 667, 669, 670, 671, 672, 673, 674, 675, 701, 702, 703, 750, 751, 752, 753,
    754, 755, 756, 851, 905, 906, 911, 912, 913, 915, 916, 917, 918, 929, 950, 951, 952, 953, 954,
    955, 956, 957, 997, 998, 999})
_DECIMAL_M = frozenset({36, 201, 558, 569, 586, 587})
#: a comment, or a quoted string with the letter of its parameter (RepRapFirmware reads left to
#: right: a quote inside a comment is the comment's, a ';' or '(' inside a string the string's)
_STRING_OR_COMMENT = re.compile(r'\([^)]*\)?|;.*|[A-Za-z]?"(?:[^"]|"")*"')
#: MillenniumOS's rotation compensation (macro/machine/M5011.g): G68 about the work system's
#: origin by the angle its probing measured
ROTATION_M = 5011


def without_strings(text: str, path=None, line: int | None = None) -> str:
    """The line with each quoted string parameter (a letter and ``"..."``, or ``"..."`` alone)
    blanked out, comments kept; a ``;`` or ``(`` inside a string is part of it, ``""`` is one
    quote. Raises InputError for a string not closed on its line."""
    if '"' not in text:
        return text
    out = _STRING_OR_COMMENT.sub(_blank_string, text)
    if '"' in strip_comments(out):
        raise InputError(f"quoted string not closed on this line: {text.strip()[:40]!r}", path, line)
    return out


def _blank_string(m: re.Match) -> str:
    s = m.group(0)
    return s if s[0] in "(;" else " " * len(s)


def is_macro_g(g: float) -> bool:
    """Whether RepRapFirmware runs G code ``g`` from a macro file (or probes: its moves are not in
    the program)."""
    gi = round(g)
    if g != gi:
        return gi not in _DECIMAL_G
    return gi not in NATIVE_G or gi in _PROBING_G


def is_macro_m(m: float) -> bool:
    """Whether RepRapFirmware runs M code ``m`` from a macro file; M98 calls one by name."""
    mi = round(m)
    if m != mi:
        return mi not in _DECIMAL_M
    return mi not in NATIVE_M or mi == 98


def macro_codes(state, gcodes: list, mcodes: list, values: dict, tokens, line: int) -> bool:
    """Take out of a line's G and M codes those RepRapFirmware runs as macro files, and the native
    codes that change nothing followed (G31, G60); True when the line holds one of them or a T
    word: its words are parameters (``values`` emptied), and after a macro or a tool change every
    axis is unknown and the work offsets are the controller's. Refused with a move in the same
    block."""
    macros = [f"G{g:g}" for g in gcodes if is_macro_g(g)]
    macros += [f"M{m:g}" for m in mcodes if is_macro_m(m)]
    own = [f"G{g:g}" for g in gcodes if g in _NO_MOTION_G]
    gcodes[:] = [g for g in gcodes if not is_macro_g(g) and g not in _NO_MOTION_G]
    tool = any(t[0] == "T" for t in tokens)
    if not macros and not tool and not own:
        return False
    if any(round(g) in (0, 1, 2, 3) for g in gcodes):
        raise state._err(f"{(macros + own or ['T'])[0]} (a RepRapFirmware macro, tool change or "
                         "setting, whose words are no move) and a move in one block is not "
                         "supported", line)
    values.clear()
    if not macros and not tool:
        return True
    mcodes[:] = [m for m in mcodes if not is_macro_m(m)]
    state._forget()
    _offsets_from_outside(state)
    notes = getattr(state._source, "notes", None)
    if notes is not None:
        _note(state, notes, macros[0] if macros else "T", line)
        if f"M{ROTATION_M}" in macros:
            _note_rotation(state, notes, line)
    return True


def _offsets_from_outside(state) -> None:
    """Every work offset the program set itself (G10 L2/L20) is the controller's from here on."""
    offsets = state.offsets
    for wcs in list(offsets.current):
        if not offsets.assign(wcs, {i: math.nan for i in range(state.na)}):
            raise state._err("too many distinct sets of work offsets set by the program",
                             state._line)


def _note(state, notes: list, code: str, line: int) -> None:
    where = state._where(line)[1]
    note = (f"note: RepRapFirmware runs macro codes and tool changes (first: {code} at line "
            f"{where}) from the controller's own macro files, whose moves the program does not "
            "hold: every axis is unknown after one until the program names it again, and a work "
            "offset one sets (a probed origin) is taken as given on the command line")
    if not any(n.startswith("note: RepRapFirmware runs macro codes") for n in notes):
        notes.append(note)


def _note_rotation(state, notes: list, line: int) -> None:
    t = math.radians(1.0)
    note = (f"note: M{ROTATION_M} at line {state._where(line)[1]} (MillenniumOS rotation "
            "compensation) turns the work frame about its origin by the angle the probing "
            "measured, which the program does not state: the corrections are written in the "
            "program's frame taking the turn as 0; a turn of t rad turns each correction by t "
            f"(1 degree: {100 * t:.2f} % of its size across it) and moves the point where the "
            f"model is read by t times its distance from the origin (1 degree: {100 * t:.2f} mm at "
            "100 mm)")
    if not any(n.startswith(f"note: M{ROTATION_M}") for n in notes):
        notes.append(note)


#: RepRapFirmware's restore points (G60 S0-S5: RepRapFirmware 3.5, ``NumRestorePoints``; the
#: firmware saves 1 on a pause and 2 at a tool change)
RESTORE_POINTS = 6


def restore_move(state, values, axes_given, line: int) -> None:
    """A ``G0``/``G1`` with an R parameter on RepRapFirmware: a move relative to restore point R
    (RepRapFirmware 3.5, ``GCodes.cpp``, ``DoStraightMove``: each axis named goes to its value plus
    the restore point's coordinate, G90 or G91 alike; the axes not named stay; R above 5 is "bad
    restore point number"). The point was saved by a ``G60 S<R>``, a pause or a tool change, where
    the compensated program's tool stood off by its correction, or outside the program: the line
    passes through as written, uncorrected, and the axes it names are unknown afterwards (their
    direction too), until the program names them again."""
    r = values["R"]
    if r != int(r) or not 0 <= r < RESTORE_POINTS:
        raise state._err(f"G{state.motion} R{r:g}: RepRapFirmware's restore points are 0 to "
                         f"{RESTORE_POINTS - 1} (G60 S0-S{RESTORE_POINTS - 1}; the firmware "
                         "answers \"bad restore point number\"; R is no radius on a G0/G1)", line)
    for c in axes_given:
        i = state.names.index(c)
        state.known[i] = False
        state.dirs[i] = 0
    if axes_given:
        state.passed_move = ("restore", line)


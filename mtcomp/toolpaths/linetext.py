"""Lines that hold no words for the reader, and the text of the others that it tokenizes.

Split from :mod:`.modal`: :func:`text_with_words` says which lines pass through without being read
(empty lines, tape marks, program numbers, grbl's commands, a Fanuc alarm-only IF, a line
RepRapFirmware answers "Bad command") and gives the others' text as the tokenizer is to see it (on
RepRapFirmware without its quoted string parameters: :mod:`.rrf`). A comment holding parentheses
(``(HSS Twist Drill, 3mm (R))``) is refused where the controller stops on it (LinuxCNC, grbl) and
said once elsewhere, where the tokenizer reads it as one comment (:func:`.words.comment_end`).
"""
from __future__ import annotations

import re

from ..errors import InputError
from .rrf import without_strings
from .words import (_COLON_PROGRAM_RE, _NUMBERED_PERCENT_RE, GRBL_DROPPED, NESTED_COMMENT_RE,
                    comment_end, empty_feeds, nested_comment_problem, strip_comments)

#: a CSV header line (names separated by commas), given where G-code was meant
_CSV_HEADER = re.compile(r"^[A-Za-z_][\w ]*(?:,[\w ]*){2,}$")
#: grbl's real-time commands (status query, cycle start/resume, feed hold, soft reset): sent as
#: single characters, they have no effect on the program's geometry (grbl v1.1 interface docs)
_REALTIME = frozenset({"?", "~", "!", "\x18"})
#: a Fanuc / Haas alarm-only IF (``IF [#5405 GE 6000] THEN #3000=15``): left in the program by
#: the macro run only where its condition reads system variables (:mod:`.macro`); no motion
_ALARM_IF = re.compile(r"(?i)^\s*(?:n\s*\d+\s*)?if\s*\[.*\]\s*then\s*#\s*3000\s*=")


def text_with_words(state, line: int, text: str) -> str | None:
    """The line's text to tokenize, or None for a line without words, which passes through (an
    empty line, '%', a ':' program number, the DOS end-of-file mark, a grbl '$' command or
    real-time command: '?' status, '~' resume, '!' feed hold, Ctrl-X reset). state : the
    :class:`~.modal.ModalState` reading the line."""
    if line == 1 and text.startswith("\xef\xbb\xbf"):      # a UTF-8 byte order mark
        text = text[3:]
    s = text.lstrip(" \t")
    if not s or s[0] == "%":
        return None
    if s[0] == ":" and _COLON_PROGRAM_RE.match(s):    # ':0097': ISO's O, a program number
        return None
    if _NUMBERED_PERCENT_RE.match(s):                  # 'N194 %': the end-of-tape mark
        return None
    if not s.strip("\x1a \t"):        # DOS end-of-file mark (Ctrl-Z) after the program
        return None
    if s[0] == "$":               # grbl system command: passes through; $H homes every axis
        if s[1:2].upper() in ("H", "J"):
            state._forget()
            state.passed_move = ("home" if s[1:2].upper() == "H" else "jog", line)
        return None
    if s.rstrip(" \t") in _REALTIME:     # a grbl real-time command alone on its line
        return None
    if s[0] == "/":
        raise state._err("block delete '/' is not supported", line)
    if state.dialect.language == "macro" and _ALARM_IF.match(s):
        return None
    if line == 1 and _CSV_HEADER.match(s):
        raise state._err("this looks like a CSV file (a header of comma-separated names), not "
                         "G-code: give the NC program here", line)
    if "(" in text and NESTED_COMMENT_RE.search(text):
        _comment_with_parentheses(state, line, text)
    if state.dialect.name == "generic" and ("F" in text or "f" in text):
        text = _without_empty_feeds(state, line, text)
    if state.dialect.name == "grbl":
        return _grbl_without_controls(state, line, text)
    if state.dialect.name == "rrf":
        try:
            text = without_strings(text, state.path, line)
        except InputError as exc:
            raise state._err(exc.message, line) from None
        return None if _bad_command(state, line, text) else text
    return text


def _without_empty_feeds(state, line: int, text: str) -> str:
    """The line without its F words that have no number (``G00 Z8.0000 F``, as Estlcam 11 writes
    every rapid for a Marlin router), on the generic dialect only: Marlin reads a parameter letter
    without a value as seen without one (src/gcode/parser.cpp, GCodeParser::parse) and G0/G1 set
    the feed only from an F with a value (src/gcode/gcode.cpp, get_destination_from_command), so
    the feed in force stays. The written line keeps the F; said once. LinuxCNC and grbl refuse it
    (the tokenizer then names the word)."""
    places = empty_feeds(text)
    if not places:
        return text
    code = strip_comments(text)
    if len(re.findall(r"(?<![A-Za-z])[Ff]", code)) > len(places):
        raise state._err("an F without a number and an F with one in one block (which one "
                         "counts depends on the controller: Marlin's fast parser takes the last, "
                         "its plain one and other readers the first)", line)
    first = state._where(line)[1]
    _note_once(state, f"note: an F word without a number (first at line {first}: "
                      f"{text.strip()[:40]!r}) is kept as written and leaves the feed in force, "
                      "as Marlin reads it; LinuxCNC and grbl refuse it (give --dialect linuxcnc "
                      "or grbl to have it refused)")
    chars = list(text)
    for pos in places:
        chars[pos] = " "
    return "".join(chars)


#: the control characters grbl does not drop: Ctrl-X, its soft reset, and DEL
_GRBL_KEPT_CONTROL = re.compile(r"[\x18\x7f]")


def _grbl_without_controls(state, line: int, text: str) -> str:
    """The line as grbl reads it: without the control characters it drops (grbl 1.1, protocol.c:
    every byte up to the blank is thrown away as the line is read; CR and LF end it). The written
    line keeps them (the controller drops them again). Ctrl-X (0x18) in a line is grbl's soft reset
    (serial.c takes it from the stream: the motion not yet run is lost), and DEL (0x7F) is not
    dropped: outside a comment grbl's parser answers it with an error (gcode.c, a word letter or
    number expected); both are refused, naming the byte."""
    if not GRBL_DROPPED.search(text) and not _GRBL_KEPT_CONTROL.search(text):
        return text
    if "\x18" in text:
        raise state._err("control character 0x18 (Ctrl-X) in a line: grbl takes it as its soft "
                         "reset (serial.c) and throws away the motion it has not run", line)
    if "\x7f" in strip_comments(text):
        raise state._err("control character 0x7F (DEL) outside a comment: grbl drops only the "
                         "bytes up to the blank (protocol.c) and answers this one with an error",
                         line)
    return GRBL_DROPPED.sub("", text)


def _bad_command(state, line: int, text: str) -> bool:
    """A line whose code holds no letter and no digit ('...'): RepRapFirmware answers it "Bad
    command", moves nothing and runs on (RepRapFirmware 3.5, StringParser.cpp, DecodeCommand;
    GCodes.cpp reports the error and goes on with the file): it passes through, said once."""
    code = strip_comments(text).strip(" \t")
    if not code or any(c.isalnum() for c in code):
        return False
    _note_once(state, f"note: RepRapFirmware answers line {state._where(line)[1]} "
                      f"({code[:20]!r}: no command) 'Bad command', moves nothing and runs on: it "
                      "passes through as written")
    return True


#: controllers that stop on a comment holding parentheses, and their rule
_REFUSE_NESTED = {
    "linuxcnc": "LinuxCNC stops on a '(' inside a comment ('Nested comment found': comments do "
                "not nest in RS274/NGC)",
    "grbl": "grbl ends the comment at its first ')' and answers the ')' left after it with error 1 "
            "(a word letter expected)",
}


def _comment_with_parentheses(state, line: int, text: str) -> None:
    """A comment that holds parentheses (``(HSS Twist Drill, 3mm (R))``): refused on a controller
    that stops on it (LinuxCNC, grbl); elsewhere read as one comment where every reading agrees
    that it holds no word (:func:`~.words.nested_comment_problem`), said once in the notes."""
    pos = _first_nested(text)
    if pos < 0:
        return
    end = comment_end(text, pos)
    shown = text[pos:end if end > 0 else len(text)][:50]
    rule = _REFUSE_NESTED.get(state.dialect.name)
    if rule is not None and end > 0:
        raise state._err(f"comment '(' holds parentheses, {shown!r}: {rule}", line)
    if end < 0 or nested_comment_problem(text, pos, end) is not None:
        return                          # the tokenizer names the problem
    first = state._where(line)[1]
    _note_once(state, f"note: a comment holding parentheses (first at line {first}: {shown!r}) "
                      "is read as one comment: a control that nests parentheses reads it so, and "
                      "one that ends it at its first ')' finds only ')' after it; no word either "
                      "way, and the line passes as written")


def _first_nested(text: str) -> int:
    """Where the line's first comment holding parentheses opens (-1: none; ';' ends the code)."""
    pos, n = 0, len(text)
    while pos < n:
        ch = text[pos]
        if ch == ";":
            return -1
        if ch == "(":
            e = text.find(")", pos)
            if e < 0 or text.find("(", pos + 1, e) >= 0:
                return pos
            pos = e
        pos += 1
    return -1


def _note_once(state, note: str) -> None:
    """Add a note to the program's notes unless one of its kind (its first 24 characters) is
    there: said once, naming the first line."""
    notes = getattr(state._source, "notes", None)
    if notes is not None and not any(n.startswith(note[:24]) for n in notes):
        notes.append(note)

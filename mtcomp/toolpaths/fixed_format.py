"""Fixed-format numbers: a program whose words have no decimal point, read in the format its
controller is set to, and written back in it.

Older controls place the decimal point of a word by a format (EIA RS-274-D, "Interchangeable
variable block data format for positioning, contouring, and contouring/positioning numerically
controlled machines", 1979: the format detail gives the digits before and after the point). In a
leading-zero format every digit before the point is written, leading zeros too, and the point lies
after that many digits: in a 3.4 format ``X0019685`` is 1.9685, ``R-0005`` is -0.5 (trailing zeros
left off), ``F0098`` is 9.8 and ``F600`` 600 (the feed's own format, 3.1 in Siemens NX's post for a
Monarch with a GE 1050 control, also has three digits before the point). The format is not in the
program: the user says it in the machine file (``fixed_format = "3.4"``, docs/machines.md).

:func:`translate` writes the program as plain G-code, each word of :data:`LETTERS` with its point
(``X001.9685``: the leading zeros kept, so that the text tells the word it came from), one line
for each line; :func:`written_back` turns a line the writer wrote back into the format: a number
the program had is written as the program wrote it (by its text, or by its value at the format's
resolution), a new one with the format's digits before the point, the program's sign style and
the program's trailing zeros (all of them where every word of the program writes them, else left
off, as the program does). A word of those letters with a decimal point, a rotary word (A B C:
the format given is that of the lengths), a word with more digits than the format has and one with
fewer than the digits before its point (not written in a leading-zero format) are refused at
their line.
"""
from __future__ import annotations

import os
import re
import tempfile
from dataclasses import dataclass, field
from decimal import ROUND_HALF_EVEN, Decimal
from pathlib import Path

from ..errors import InputError
from ..io.atomic import atomic_write
from .heidenhain import read_lines
from .lines import line_code

#: the words read in the format: the linear axes, an arc's centre and radius, a cycle's R, its
#: peck or dwell (Q, K) and the feed F
LETTERS = frozenset("XYZUVWIJKRQF")
_ROTARY = frozenset("ABC")
#: a word of a line's code (lower case, without blanks: :func:`~.lines.line_code`)
_WORD = re.compile(r"([a-z])([+-]?(?:\d+\.?\d*|\.\d+))")
#: G codes that controls reading a fixed format use for moves of their own: the GE 1050's G86 and
#: G87 as Siemens NX's post for a Monarch VMC 150 writes them, `G87 R-0003937 Z-0003937 F600` (R
#: and Z the same level: a move along the spindle), `G86 R-0001181 Z0 F0098` (from R to Z at the
#: feed), and G87 for a boring cycle too; not RS274/NGC's boring cycles, and no manual we found
#: gives their motion
_GE = ("the GE 1050 control's own code (Siemens NX's post for a Monarch VMC 150 writes {} for "
       "a move along the spindle, not RS274/NGC's boring cycle), whose motion mtcomp does not know")
_OWN_CODES = {"86": _GE.format("G86 R.. Z.. F.."), "87": _GE.format("G87 R.. Z.. F..")}


@dataclass
class FixedFormat:
    """How a program writes its numbers: ``digits`` (before, after the point), ``plus`` (a '+'
    before positive numbers), ``full`` (every word has all the format's digits), ``texts`` (the
    text the G-code holds -> the program's word text) and ``values`` (value -> the first text the
    program wrote it with)."""

    digits: tuple
    plus: bool = False
    full: bool = True
    texts: dict = field(default_factory=dict)
    values: dict = field(default_factory=dict)

    def name(self) -> str:
        return f"{self.digits[0]}.{self.digits[1]}"

    def read(self, number: str) -> str:
        """The G-code text of a word's number written in the format (``0019685`` -> ``001.9685``;
        ``0`` stays ``0``)."""
        sign = number[0] if number[0] in "+-" else ""
        body = number[len(sign):]
        before = self.digits[0]
        text = body if int(body) == 0 else (sign + body[:before].ljust(before, "0") + "."
                                            + body[before:])
        self.texts.setdefault(text, number)
        self.values.setdefault(Decimal(text), number)
        self.plus = self.plus or sign == "+"
        self.full = self.full and (int(body) == 0 or len(body) == sum(self.digits))
        return text

    def write(self, text: str) -> str | None:
        """The format's text of the number the writer wrote (``1.96843`` -> ``0019684``); None
        where it does not fit the format."""
        if text in self.texts:
            return self.texts[text]
        before, after = self.digits
        value = Decimal(text).quantize(Decimal(1).scaleb(-after), rounding=ROUND_HALF_EVEN)
        if value in self.values:
            return self.values[value]
        if value == 0:
            return "0"
        whole, _point, frac = f"{abs(value):.{after}f}".partition(".")
        if len(whole) > before:
            return None
        sign = "-" if value < 0 else "+" if self.plus else ""
        return sign + whole.zfill(before) + (frac if self.full else frac.rstrip("0"))


def _words(text: str):
    """(start, end, letter, number) of the words of a line outside its comments (blanks inside a
    word, ``X 0019685``, are taken with it)."""
    code = line_code(text)
    for m in _WORD.finditer(code.text):
        yield code.cols[m.start(2)], code.cols[m.end(2) - 1] + 1, m.group(1).upper(), m.group(2)


def _replace(text: str, spans) -> str:
    for start, end, new in reversed(spans):
        text = text[:start] + new + text[end:]
    return text


def translate(lines: list, fmt: FixedFormat, path) -> list:
    """The lines (texts without their endings) as G-code with points (see the module docstring).
    Raises InputError at the first word the format does not read."""
    out = []
    for k, text in enumerate(lines, 1):
        spans = []
        for start, end, letter, number in _words(text):
            word = f"{letter}{number}"
            if letter == "G" and number.lstrip("+0") in _OWN_CODES:
                raise InputError(f"{word} in a program read in the fixed format {fmt.name()}: "
                                 f"{_OWN_CODES[number.lstrip('+0')]}", path, line=k)
            if letter in _ROTARY and "." not in number and int(number.lstrip("+-")) != 0:
                raise InputError(f"{word} has no decimal point: the fixed format {fmt.name()} of "
                                 "the machine file is that of the lengths, and a rotary word's is "
                                 "not given; write it with its point", path, line=k)
            if letter not in LETTERS:
                continue
            if "." in number:
                raise InputError(f"{word} has a decimal point in a program read in the fixed "
                                 f"format {fmt.name()} (the machine file's fixed_format): write "
                                 "every word in the format, or take fixed_format out", path, line=k)
            digits = number.lstrip("+-")
            if len(digits) > sum(fmt.digits):
                raise InputError(f"{word} has more digits than the fixed format {fmt.name()} of "
                                 "the machine file", path, line=k)
            if len(digits) < fmt.digits[0] and int(digits) != 0:
                # a leading-zero format writes every digit before the point; a word without them
                # is of another format (one that leaves leading zeros off counts from the right)
                raise InputError(f"{word} has fewer digits than the {fmt.digits[0]} before the "
                                 f"point of the fixed format {fmt.name()} of the machine file, "
                                 "which writes them all with their leading zeros", path, line=k)
            spans.append((start, end, fmt.read(number)))
        out.append(_replace(text, spans))
    return out


def written_back(text: str, fmt: FixedFormat, path, line: int) -> str:
    """A line the writer wrote (G-code with points) in the program's fixed format."""
    spans = []
    for start, end, letter, number in _words(text):
        if letter not in LETTERS:
            continue
        new = fmt.write(number)
        if new is None:
            raise InputError(f"the corrected {letter}{number} does not fit the fixed format "
                             f"{fmt.name()}", path, line=line)
        spans.append((start, end, new))
    return _replace(text, spans)


def write_corrected(write, src, out_path, *args, **kw) -> int:
    """Write the program ``src`` (a ProgramSource with ``fixed``) to ``out_path`` by the G-code
    writer ``write`` into a temporary file beside it, then its lines with their words in the
    program's fixed format (:func:`written_back`); returns what ``write`` returns. Nothing is left
    at ``out_path`` on failure."""
    out = Path(out_path)
    fd, tmp = tempfile.mkstemp(prefix=f".{out.name}.", suffix=".nc", dir=out.resolve().parent)
    os.close(fd)
    try:
        rows = write(src, tmp, *args, **kw)
        with atomic_write(out, "wb") as f:
            for k, raw in enumerate(read_lines(tmp), 1):
                body = raw.rstrip(b"\r\n")
                text = written_back(body.decode("latin-1"), src.fixed, src.source, k)
                f.write(text.encode("latin-1") + raw[len(body):])
        return rows
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)

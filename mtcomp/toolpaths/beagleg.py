"""BeagleG's G-code language, read as LinuxCNC's: each line rewritten in RS274/NGC, line for line.

BeagleG (a CNC controller for the BeagleBone, github hzeller/beagleg) reads RS274/NGC parameters
and expressions with extensions of its own (its G-code.md, "Parameters / Variables" and
"Expressions"; its parser src/gcode-parser/gcode-parser.cc). :func:`to_ngc` writes each line in
the RS274/NGC that LinuxCNC's interpreter reads (:mod:`.ngc` then runs it), keeping the line count
so that errors name the source's lines:

* a parameter named without brackets, ``#faces=24``, ``X#r`` (letters, digits, '_'; case does not
  matter) is the named parameter ``#<faces>``; ``#<name>`` is read as it is, a numbered ``#1``
  too;
* ``#i++``, ``#i--`` and ``#a+=v`` (``-=``, ``*=``, ``/=``) are assignments ``#<i>=[#<i>+1]``, ...;
* the comparison operators ``<=`` ``>=`` ``==`` ``!=`` ``<`` ``>`` and ``&&`` ``||`` are LE GE EQ NE
  LT GT AND OR;
* ``WHILE [condition] DO`` ... ``END`` is an O-word loop (BeagleG does not nest them: the first line
  starting with END closes the loop, so a WHILE inside one is refused).

Refused by name: the one-line ``IF [...] THEN #a=... ELSE ...``, the ternary ``#a=[c] ? x : y``,
an update inside a value (``X#i++``: BeagleG reads ``#i`` as the value, the ``++`` is no update),
and an assignment whose parameter its own line reads after it (BeagleG sets a parameter at once,
within its line; LinuxCNC after the line: the two would differ).
"""
from __future__ import annotations

import re

from ..errors import InputError
from .words import comment_end

_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_NUMBERED = re.compile(r"\d+(?:\.\d*)?")
_OPERATORS = [("<=", " LE "), (">=", " GE "), ("==", " EQ "), ("!=", " NE "), ("&&", " AND "),
              ("||", " OR "), ("<", " LT "), (">", " GT ")]
_UPDATE = re.compile(r"[ \t]*(\+\+|--|[-+*/]=)")
_WHILE = re.compile(r"(?i)^\s*while\s*(\[.*\])\s*do\s*$")
_END = re.compile(r"(?i)^\s*end(?![a-z0-9_])")
_IF = re.compile(r"(?i)^\s*if\s*\[")
#: an assignment in NGC form: '#<name>=' or '#12='
_SET = re.compile(r"#(<[^>]*>|\d+)\s*=")


def _param(code: str, pos: int) -> tuple[str, int]:
    """(the parameter at ``code[pos]`` == '#' in NGC form, the position after it)."""
    p = pos + 1
    while p < len(code) and code[p] in " \t":
        p += 1
    if code.startswith("<", p):
        end = code.find(">", p)
        if end < 0:
            return "#", pos + 1            # left for the NGC reader to name
        return "#<" + code[p + 1:end].replace(" ", "").lower() + ">", end + 1
    m = _NAME.match(code, p)
    if m:
        return f"#<{m.group(0).lower()}>", m.end()
    return "#", pos + 1


def _code_part(code: str, path, line: int) -> str:
    """A stretch of code (no comments) in NGC form."""
    out, pos = [], 0
    while pos < len(code):
        ch = code[pos]
        if ch == "#":
            start = pos
            name, pos = _param(code, pos)
            update = _UPDATE.match(code, pos) if name != "#" else None
            if update and _in_value(code, start):
                op, shown = update.group(1), code[start:update.end()].strip()
                raise InputError(f"'{shown}' updates a parameter inside a value: BeagleG reads "
                                 f"{code[start:pos].strip()} as the value and does not take the "
                                 f"'{op}' after it as an update; put the update apart, as a word "
                                 "of its own", path, line)
            if update:
                op = update.group(1)
                if op in ("++", "--"):
                    out.append(f"{name}=[{name}{op[0]}1]")
                    pos = update.end()
                    continue
                value, pos = _value_to_end(code, update.end())
                out.append(f"{name}=[{name}{op[0]}[{value}]]")
                continue
            out.append(name)
            continue
        for op, ngc in _OPERATORS:
            if code.startswith(op, pos):
                out.append(ngc)
                pos += len(op)
                break
        else:
            if ch == "?":
                raise InputError("the ternary assignment '#a=[c] ? x : y' of BeagleG is not read",
                                 path, line)
            out.append(ch)
            pos += 1
    return "".join(out)


def _in_value(code: str, pos: int) -> bool:
    """Whether the '#' at ``code[pos]`` is (part of) a word's value or an expression: what comes
    before it is a word's letter, '[', an operator or '='."""
    before = code[:pos].rstrip()
    if re.search(r"#\s*(?:<[^>]*>|\w+)$", before):
        return False                # a parameter before it: the value it belongs to ends there
    return bool(before) and (before[-1].isalpha() or before[-1] in "[+-*/=<>!&|")


def _value_end(code: str, pos: int) -> int:
    """Where the value that starts at or after ``code[pos]`` ends: a bracketed expression, a
    parameter or a number."""
    rest = code[pos:].lstrip()
    start = len(code) - len(rest)
    if rest.startswith("["):
        depth = 0
        for k, ch in enumerate(rest):
            depth += (ch == "[") - (ch == "]")
            if depth == 0:
                return start + k + 1
        return len(code)
    m = re.match(r"#\s*(?:<[^>]*>|[A-Za-z_]\w*|\d+)|[-+]?(?:\d+\.?\d*|\.\d+)", rest)
    return start + (m.end() if m else len(rest))


def _value_to_end(code: str, pos: int) -> tuple[str, int]:
    """The value of an update ``#a+=v`` in NGC form, and where it ends."""
    end = _value_end(code, pos)
    return _code_part(code[pos:end].strip(), None, 0), end


def _line(text: str, path, line: int) -> str:
    """One line in NGC form: its code translated, its comments as they are."""
    out, start, pos, n = [], 0, 0, len(text)
    while pos < n:
        ch = text[pos]
        if ch in "(;":
            out.append(_code_part(text[start:pos], path, line))
            end = n if ch == ";" else comment_end(text, pos)
            end = n if end < 0 else end
            out.append(text[pos:end])
            start = pos = end
            continue
        pos += 1
    out.append(_code_part(text[start:], path, line))
    result = "".join(out)
    for m in _SET.finditer(result):
        name = m.group(1)
        again = re.compile(r"#" + re.escape(name) + r"(?!\s*=)(?![\d>])")
        if again.search(result, _value_end(result, m.end())):
            raise InputError(f"#{name.strip('<>')} is set and read in one line (BeagleG sets it at "
                             "once, LinuxCNC after the line): put the assignment on a line of its "
                             "own", path, line)
    return result


def _code_only(text: str) -> str:
    """A line's text before its first comment."""
    cut = [k for k in (text.find("("), text.find(";")) if k >= 0]
    return text[:min(cut)] if cut else text


def to_ngc(texts: list[str], path) -> list[str]:
    """The lines of a BeagleG program in LinuxCNC's RS274/NGC, one for each (see the module)."""
    out, loop = [], None            # loop: the line (1-based) of the WHILE open, or None
    for k, text in enumerate(texts, 1):
        code = _code_only(text)
        if _IF.match(code):
            raise InputError("BeagleG's one-line IF [...] THEN #a=... is not read", path, k)
        if loop is not None and _END.match(code):
            out.append(f"o<beagleg_while_{loop}> endwhile")
            loop = None
            continue
        m = re.match(r"(?i)^\s*while\b", code)
        if m:
            w = _WHILE.match(code)
            if loop is not None:
                raise InputError(f"WHILE inside the WHILE of line {loop} (BeagleG's first END "
                                 "closes the outer loop: loops do not nest)", path, k)
            if w is None:
                raise InputError("WHILE without '[condition] DO'", path, k)
            loop = k
            out.append(f"o<beagleg_while_{k}> while {_code_part(w.group(1), path, k)}")
            continue
        out.append(_line(text, path, k))
    if loop is not None:
        raise InputError("WHILE without its END", path, loop)
    return out

"""The words of a Siemens Sinumerik block and the arithmetic of its expressions.

A block (Siemens AG, SINUMERIK 840D sl Programming Manual, Fundamentals, 2013, "Structure and
contents of an NC program" and "Arithmetic parameters") is cut here into :class:`Word` objects:
an address with a number (``X57``, ``G0``, ``L54``), an address or variable with ``=`` and an
expression (``Z=WYSSRU+60``, ``R1=0+R102``, ``I=AC(0)``), a call with arguments in parentheses
(``CYCLE81(...)``) or a keyword (``MCALL``). Each word keeps where its value stands in the line, so
the writer can replace that text alone. :func:`evaluate` computes an expression with the four
operations, parentheses and the manual's functions (``SIN``, ``COS`` ... in degrees), from the
values of the program's variables; Python's own parser reads it (the grammar is the same for these).
:func:`corrected_text` gives a value's text with a correction, as the writer writes it.
"""
from __future__ import annotations

import ast
import math
import re
from dataclasses import dataclass

from .heidenhain import signed
from .words import number_decimals

_NAME = re.compile(r"[A-Za-z_$][A-Za-z0-9_]*")
_ADDRESS = re.compile(r"([A-Za-z])\s*([+-]?\s*(?:\d+\.?\d*|\.\d+))(?![A-Za-z0-9_.])")
#: a number inside an expression (Python would read 007 as an error, and 14. is fine)
_NUMBER = re.compile(r"(?<![A-Za-z0-9_.$])(\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")
#: the manual's arithmetic functions (angles in degrees)
_FUNCTIONS = {
    "SIN": lambda a: math.sin(math.radians(a)), "COS": lambda a: math.cos(math.radians(a)),
    "TAN": lambda a: math.tan(math.radians(a)), "ASIN": lambda a: math.degrees(math.asin(a)),
    "ACOS": lambda a: math.degrees(math.acos(a)), "ATAN2": lambda a, b: math.degrees(math.atan2(a, b)),
    "SQRT": math.sqrt, "ABS": abs, "POT": lambda a: a * a, "TRUNC": math.trunc,
    "ROUND": lambda a: float(math.floor(a + 0.5)), "LN": math.log, "EXP": math.exp,
    "MINVAL": min, "MAXVAL": max,
}
_BINARY = {ast.Add: lambda a, b: a + b, ast.Sub: lambda a, b: a - b,
           ast.Mult: lambda a, b: a * b, ast.Div: lambda a, b: a / b}


#: the axis letters of a Sinumerik program mtcomp reads
AXES = "XYZABC"


def fmt(v: float) -> str:
    """A number of the G-code equivalent: up to 10 decimals, no trailing zeros (never -0)."""
    s = f"{v:.10f}".rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


class ExpressionError(ValueError):
    """An expression that cannot be computed (the message says why)."""


@dataclass
class Word:
    """One word of a block. kind: 'address' (``X57``: name 'X', text '57'), 'assign' (``X=...``,
    ``R1=...``, ``NAME=...``: text the expression), 'call' (``NAME(...)``: text what the
    parentheses hold), 'keyword' (``MCALL``). start, end: where ``text`` stands in the line."""

    kind: str
    name: str
    text: str
    start: int
    end: int


def code_end(text: str) -> int:
    """Where a line's ';' comment starts (its length when it has none); a ';' inside a string
    ``"..."`` (``MSG("ROUGH; SIDE")``) is the string's."""
    quoted = False
    for i, ch in enumerate(text):
        if ch == '"':
            quoted = not quoted
        elif ch == ";" and not quoted:
            return i
    return len(text)


def _closing(text: str, pos: int, end: int) -> int:
    """The index after the parenthesis that closes the one at ``pos`` (-1 when none does); the
    parentheses of a string ``"..."`` are the string's."""
    depth = 0
    quoted = False
    for i in range(pos, end):
        if text[i] == '"':
            quoted = not quoted
        elif quoted:
            continue
        elif text[i] == "(":
            depth += 1
        elif text[i] == ")":
            depth -= 1
            if depth == 0:
                return i + 1
    return -1


def _expression_end(text: str, pos: int, end: int) -> int:
    """The end of an expression starting at ``pos``: a blank outside parentheses and strings
    ``"..."`` ends it."""
    i = pos
    while i < end and text[i] not in " \t":
        if text[i] == '"':                  # a string: its blanks are its own
            close = text.find('"', i + 1, end)
            if close < 0:
                return -1
            i = close + 1
        elif text[i] == "(":
            close = _closing(text, i, end)
            if close < 0:
                return -1
            i = close
        else:
            i += 1
    return i


def split_words(text: str, start: int, end: int) -> list[Word]:
    """The words of ``text[start:end]`` (see the module docstring). A parenthesised text where a
    word would start is a comment (the Sinumerik 8xx form). Raises ValueError naming what cannot
    be read."""
    words = []
    p = start
    while p < end:
        while p < end and text[p] in " \t":
            p += 1
        if p >= end:
            break
        if text[p] == "(":
            close = _closing(text, p, end)
            if close < 0:
                raise ValueError("an unclosed parenthesis")
            p = close
            continue
        m = _NAME.match(text, p)
        if m is None:
            raise ValueError(f"{text[p:p + 12]!r} is not a word")
        after = m.end()
        q = after
        while q < end and text[q] in " \t":
            q += 1
        if q < end and text[q] == "(" and len(m.group(0)) > 1:
            close = _closing(text, q, end)
            if close < 0:
                raise ValueError(f"the call {m.group(0)} has no closing parenthesis")
            words.append(Word("call", m.group(0).upper(), text[q + 1:close - 1], q + 1, close - 1))
            p = close
            continue
        if q < end and text[q] == "=":
            e0 = q + 1
            while e0 < end and text[e0] in " \t":
                e0 += 1
            e1 = _expression_end(text, e0, end)
            if e1 < 0 or e1 == e0:
                raise ValueError(f"{m.group(0)}= without a value")
            words.append(Word("assign", m.group(0).upper(), text[e0:e1], e0, e1))
            p = e1
            continue
        a = _ADDRESS.match(text, p)
        if a is not None:
            words.append(Word("address", a.group(1).upper(), a.group(2), a.start(2), a.end(2)))
            p = a.end()
            continue
        words.append(Word("keyword", m.group(0).upper(), "", p, after))
        p = after
    return words


def split_arguments(text: str) -> list[str]:
    """The comma-separated arguments of a call (an empty one is ''), commas inside parentheses
    kept."""
    out, depth, cur = [], 0, []
    for ch in text:
        if ch == "," and depth == 0:
            out.append("".join(cur).strip())
            cur = []
            continue
        depth += (ch == "(") - (ch == ")")
        cur.append(ch)
    out.append("".join(cur).strip())
    return out


def evaluate(expr: str, lookup) -> float:
    """The value of an expression. ``lookup(name)`` gives a variable's value (raises KeyError for
    an unknown one, ExpressionError for a value that is not known)."""
    source = _NUMBER.sub(lambda m: repr(float(m.group(0))), expr.strip())
    if "$" in source:
        raise ExpressionError(f"a system variable in {expr!r}")
    try:
        tree = ast.parse(source.upper(), mode="eval")
    except SyntaxError:
        raise ExpressionError(f"{expr!r} is not an expression mtcomp reads") from None
    return float(_value(tree.body, lookup, expr))


def _value(node, lookup, expr):
    if isinstance(node, ast.Constant) and isinstance(node.value, float):
        return node.value
    if isinstance(node, ast.Name):
        try:
            return lookup(node.id)
        except KeyError:
            raise ExpressionError(f"the variable {node.id} is not defined") from None
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
        v = _value(node.operand, lookup, expr)
        return -v if isinstance(node.op, ast.USub) else v
    if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
        a, b = _value(node.left, lookup, expr), _value(node.right, lookup, expr)
        if isinstance(node.op, ast.Div) and b == 0:
            raise ExpressionError(f"a division by zero in {expr!r}")
        return _BINARY[type(node.op)](a, b)
    if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) \
            and node.func.id in _FUNCTIONS and not node.keywords:
        args = [_value(a, lookup, expr) for a in node.args]
        try:
            return float(_FUNCTIONS[node.func.id](*args))
        except (TypeError, ValueError):
            raise ExpressionError(f"{node.func.id} with these arguments in {expr!r}") from None
    raise ExpressionError(f"{expr!r} is not an expression mtcomp reads (the four operations, "
                          "parentheses, variables and SIN, COS, SQRT ...)")


# ---------------------------------------------------------------------------- written values
_PLAIN = "0123456789+-. "


def _plain(text: str) -> bool:
    return bool(text.strip()) and all(c in _PLAIN for c in text)


def number_text(value: float, decimals: int) -> str:
    """A plain number at ``decimals`` (never -0), unsigned where positive."""
    return signed(value, decimals, sign=False)


def corrected_text(text: str, nominal: float, corrected: float, base: int = 4) -> tuple[str, float]:
    """(the value's new text, the value it says): a plain number is rewritten with at least its
    decimals and at least ``base`` (4 in mm and degrees, 5 in inch); an expression gets the
    correction appended (``A+60`` -> ``A+60+0.0012``); the text stays as it is when the
    correction rounds to zero."""
    if _plain(text):
        number = text.replace(" ", "")
        dec = max(base, number_decimals(number))
        t = number_text(corrected, dec)
        if t == number_text(float(number), dec):
            return text, nominal
        if number.startswith("+") and not t.startswith("-"):
            t = "+" + t
        return t, float(t)
    c = number_text(corrected - nominal, base)
    if float(c) == 0.0:
        return text, nominal
    c = c if c.startswith("-") else "+" + c
    return text + c, nominal + float(c)


def edit_text(text: str, edits) -> str:
    """``text`` with each (start, end, new text) of ``edits`` put in (spans of the text as given)."""
    for a, b, t in sorted(edits, reverse=True):
        text = text[:a] + t + text[b:]
    return text

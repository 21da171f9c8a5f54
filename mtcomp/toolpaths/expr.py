"""Expressions and parameters of RS274/NGC (LinuxCNC) and Fanuc macro B: the values in ``[ ]``.

One evaluator for both languages (LinuxCNC G-code reference, Expressions, Binary Operators,
Functions, Numbered and Named Parameters; Fanuc custom macro B): numbers, parameters ``#1``,
``#<name>``, ``#<_global>``, ``##2`` and ``#[1+2]``, the binary operators ``** * / MOD + - EQ NE GT
GE LT LE AND OR XOR`` in LinuxCNC's five precedence groups (left to right inside a group), unary
``+ -`` and the functions ``ABS ACOS ASIN ATAN[a]/[b] COS EXP FIX FUP ROUND LN SIN SQRT TAN EXISTS``
(angles in degrees). Equality is within 1e-6, as in LinuxCNC (``TOLERANCE_EQUAL``); ``MOD`` is
never negative; ``ROUND`` rounds half away from zero; ``FIX`` and ``FUP`` are floor and ceiling.

The text handed here is lower case without blanks (both controllers read a line that way outside
comments). Errors are :class:`ExprError` (a message without file or line; the caller adds them).
"""
from __future__ import annotations

import math
import re

from .words import number_decimals

#: two values are equal within this (LinuxCNC's TOLERANCE_EQUAL)
TOLERANCE_EQUAL = 1e-6
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)")
#: the functions, by name (``atan`` takes two bracketed arguments, ``exists`` a named parameter)
FUNCTIONS = ("abs", "acos", "asin", "atan", "cos", "exp", "exists", "fix", "fup", "ln", "round",
              "sin", "sqrt", "tan")
#: binary operators by precedence group, lowest first (LinuxCNC G-code reference, Binary Operators)
_GROUPS = (("and", "or", "xor"), ("eq", "ne", "gt", "ge", "lt", "le"), ("+", "-"),
           ("*", "/", "mod"), ("**",))
_OPERATORS = sorted({op for g in _GROUPS for op in g}, key=len, reverse=True)
_RANK = {op: r for r, g in enumerate(_GROUPS) for op in g}


class ExprError(ValueError):
    """A bad expression or parameter use (message only: the caller names file and line)."""


#: the value of a parameter the controller holds when it runs the program (its position, a probe's
#: result, a setting): not known here. Anything computed from it is unknown too (NaN carries
#: through arithmetic and functions; a comparison or logical operator on it is made unknown here)
UNKNOWN = math.nan


def is_unknown(v) -> bool:
    """Whether a computed value is :data:`UNKNOWN` (computed from a value the controller holds)."""
    return v != v


class Number(float):
    """A computed value that remembers ``decimals``: the most digits after the point of the numbers
    it was computed from (literals, and the parameters read, each with its own). A word written
    from it in the expanded program keeps them (``#<_depth> = -0.062500`` ... ``Z#<_depth>`` is
    written ``Z-0.062500``, as the program writes its numbers)."""

    def __new__(cls, value: float, decimals: int = 0):
        self = super().__new__(cls, value)
        self.decimals = int(decimals)
        return self


def decimals_of(v) -> int:
    """The decimals a value carries (0 for a plain float)."""
    return getattr(v, "decimals", 0)


def _deg(f):
    return lambda x: f(math.radians(x))


def _domain(name, f, ok):
    def g(x):
        if not ok(x):
            raise ExprError(f"{name.upper()} of {x:g} is not defined")
        return f(x)
    return g


_UNARY = {
    "abs": abs, "cos": _deg(math.cos), "sin": _deg(math.sin), "tan": _deg(math.tan),
    "acos": _domain("acos", lambda x: math.degrees(math.acos(x)), lambda x: -1.0 <= x <= 1.0),
    "asin": _domain("asin", lambda x: math.degrees(math.asin(x)), lambda x: -1.0 <= x <= 1.0),
    "exp": math.exp, "fix": lambda x: float(math.floor(x)), "fup": lambda x: float(math.ceil(x)),
    "ln": _domain("ln", math.log, lambda x: x > 0.0),
    "sqrt": _domain("sqrt", math.sqrt, lambda x: x >= 0.0),
    "round": lambda x: float(math.trunc(x + (-0.5 if x < 0.0 else 0.5))),
}


def _binary(op: str, a: float, b: float) -> float:
    if is_unknown(a) or is_unknown(b):
        return UNKNOWN
    if op == "+":
        return a + b
    if op == "-":
        return a - b
    if op == "*":
        return a * b
    if op == "/":
        if b == 0.0:
            raise ExprError("division by zero")
        return a / b
    if op == "mod":
        if b == 0.0:
            raise ExprError("MOD by zero")
        r = math.fmod(a, b)
        return r + abs(b) if r < 0.0 else r
    if op == "**":
        if a < 0.0 and math.floor(b) != b:
            raise ExprError(f"{a:g} ** {b:g}: a negative number to a non-integer power")
        return float(a ** b)
    if op == "and":
        return 0.0 if a == 0.0 or b == 0.0 else 1.0
    if op == "or":
        return 1.0 if a != 0.0 or b != 0.0 else 0.0
    if op == "xor":
        return 1.0 if (a != 0.0) != (b != 0.0) else 0.0
    d = abs(a - b)
    return float({"eq": d < TOLERANCE_EQUAL, "ne": d >= TOLERANCE_EQUAL,
                  "le": d < TOLERANCE_EQUAL or a <= b, "ge": d < TOLERANCE_EQUAL or a >= b,
                  "gt": a > b, "lt": a < b}[op])


class Evaluator:
    """Reads values from a text at a position; parameters come from ``params`` (an object with
    ``get(key) -> float`` and ``exists(name) -> bool``; keys are ints or lower-case names)."""

    def __init__(self, params, logical_only: bool = False):
        self.params = params
        #: AND / OR / XOR only on 0 and 1 (a Fanuc computes them bitwise on other values)
        self.logical_only = logical_only
        #: the most decimals of the numbers and parameters read since :meth:`counted` started
        self.decimals = 0

    def counted(self, read, *args) -> tuple[Number, int]:
        """``read(*args)`` (one of the readers below: ``value``, ``bracket``, ``expression``) with
        its value as a :class:`Number` carrying the decimals of what it read."""
        outer, self.decimals = self.decimals, 0
        try:
            v, pos = read(*args)
            return Number(v, self.decimals), pos
        finally:
            self.decimals = max(outer, self.decimals)

    # ------------------------------------------------------------------ values
    def value(self, s: str, pos: int) -> tuple[float, int]:
        """(the real value starting at s[pos], the position after it): a number, an expression
        in brackets, a parameter, a function, or one of these after a sign."""
        if pos >= len(s):
            raise ExprError("a value is missing at the end")
        c = s[pos]
        if c == "[":
            return self.bracket(s, pos)
        if c == "#":
            key, pos = self.parameter_key(s, pos)
            v = self.params.get(key)
            self.decimals = max(self.decimals, decimals_of(v))
            return v, pos
        if c in "+-" and pos + 1 < len(s) and not (s[pos + 1].isdigit() or s[pos + 1] == "."):
            v, pos = self.value(s, pos + 1)
            return (-v if c == "-" else v), pos
        if c.isalpha():
            return self.function(s, pos)
        m = _NUMBER.match(s, pos)
        if not m:
            raise ExprError(f"a number is expected at {s[pos:pos + 12]!r}")
        self.decimals = max(self.decimals, number_decimals(m.group(0)))
        return float(m.group(0)), m.end()

    def parameter_key(self, s: str, pos: int) -> tuple[int | str, int]:
        """The parameter named at s[pos] ('#'): an int for ``#31``, ``##2``, ``#[1+2]``, a name
        (lower case, blanks removed) for ``#<name>``."""
        pos += 1
        if pos < len(s) and s[pos] == "<":
            end = s.find(">", pos)
            if end < 0:
                raise ExprError("named parameter without its closing '>'")
            name = s[pos + 1:end].replace(" ", "").replace("\t", "")
            if not name:
                raise ExprError("named parameter without a name")
            return name, end + 1
        v, pos = self.value(s, pos)
        if is_unknown(v):
            raise ExprError("a parameter number computed from a value the controller holds (its "
                            "position, a probe's result, a setting): which parameter is read "
                            "cannot be known")
        k = round(v)
        if abs(v - k) > 1e-4 or k < 0:
            raise ExprError(f"parameter number {v:g} is not a whole number")
        return int(k), pos

    def bracket(self, s: str, pos: int) -> tuple[float, int]:
        """The expression in brackets at s[pos] ('[')."""
        v, pos = self._expression(s, pos + 1)
        if pos >= len(s) or s[pos] != "]":
            raise ExprError("expression without its closing ']'")
        return v, pos + 1

    def function(self, s: str, pos: int) -> tuple[float, int]:
        for name in FUNCTIONS:
            if s.startswith(name, pos):
                break
        else:
            raise ExprError(f"unknown function or word {s[pos:pos + 8]!r} in an expression")
        pos += len(name)
        if pos >= len(s) or s[pos] != "[":
            raise ExprError(f"function {name.upper()} without its argument in [ ]")
        if name == "exists":
            if not s.startswith("#<", pos + 1):
                raise ExprError("EXISTS takes one named parameter, e.g. EXISTS[#<name>]")
            key, end = self.parameter_key(s, pos + 1)
            if end >= len(s) or s[end] != "]":
                raise ExprError("EXISTS takes one named parameter, e.g. EXISTS[#<name>]")
            return float(self.params.exists(key)), end + 1
        a, pos = self.bracket(s, pos)
        if name == "atan":
            if not s.startswith("/[", pos):
                raise ExprError("ATAN takes two arguments: ATAN[y]/[x]")
            b, pos = self.bracket(s, pos + 1)
            return math.degrees(math.atan2(a, b)), pos
        if is_unknown(a):
            return UNKNOWN, pos
        return _UNARY[name](a), pos

    # ------------------------------------------------------------------ expressions
    def _binary(self, op: str, a: float, b: float) -> float:
        if self.logical_only and op in ("and", "or", "xor") and not {a, b} <= {0.0, 1.0}:
            raise ExprError(f"{op.upper()} of {a:g} and {b:g}: bitwise on a Fanuc, not supported "
                            "(only on 0 and 1, as comparisons give)")
        return _binary(op, a, b)

    def _operator(self, s: str, pos: int) -> str | None:
        for op in _OPERATORS:
            if s.startswith(op, pos):
                return op
        return None

    def expression(self, s: str, pos: int) -> tuple[float, int]:
        """An expression without brackets around it (Fanuc's ``#1=#2+1``), up to the end or a ']'."""
        return self._expression(s, pos)

    def _expression(self, s: str, pos: int) -> tuple[float, int]:
        """Operator precedence parsing of the inside of a bracket (up to the ']')."""
        values = []
        ops: list[str] = []
        v, pos = self.value(s, pos)
        values.append(v)
        while pos < len(s) and s[pos] != "]":
            op = self._operator(s, pos)
            if op is None:
                raise ExprError(f"an operator is expected at {s[pos:pos + 12]!r}")
            pos += len(op)
            while ops and _RANK[ops[-1]] >= _RANK[op]:
                b = values.pop()
                values[-1] = self._binary(ops.pop(), values[-1], b)
            ops.append(op)
            v, pos = self.value(s, pos)
            values.append(v)
        while ops:
            b = values.pop()
            values[-1] = self._binary(ops.pop(), values[-1], b)
        if not math.isfinite(values[0]) and not is_unknown(values[0]):
            raise ExprError("the expression is not a finite number")
        return values[0], pos


def compact(code: str) -> str:
    """The code of a line as the controllers read it: lower case, without blanks."""
    return code.lower().replace(" ", "").replace("\t", "")


def format_value(v: float, decimals: int | None = None) -> str:
    """A computed word value as written into the expanded program: ``decimals`` digits after the
    point (None: those ``v`` carries, :func:`decimals_of`), more where the value has more, up to 6
    (or ``decimals`` when more); no '-0'."""
    keep = decimals_of(v) if decimals is None else decimals
    whole, _dot, frac = f"{v:.{max(6, keep)}f}".partition(".")
    frac = frac.rstrip("0").ljust(keep, "0")
    if whole == "-0" and not frac.strip("0"):
        whole = "0"
    return whole + ("." + frac if frac else "")

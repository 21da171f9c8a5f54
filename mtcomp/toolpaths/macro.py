"""Fanuc custom macro B (also run by Haas): variables, IF / GOTO / WHILE expanded into flat lines.

What is followed (Fanuc Series 0i-MODEL F operator's manual, custom macro; Haas mill operator's
manual, macros): variables ``#1``-``#33`` (local), ``#100``-``#199`` and ``#500``-``#999`` (common),
assignments ``#100=#101+1`` (an expression without brackets), the same operators and functions as
LinuxCNC's (:mod:`.expr`), ``IF [cond] GOTO n``, ``IF [cond] THEN #i=...``, ``GOTO n`` (to the
line with sequence number N n), ``WHILE [cond] DOm`` ... ``ENDm``. The lines the control executes
come out, in order, as in :mod:`.ngc`.

Refused, each by name: a variable read before it is set (a Fanuc's *vacant* variable, which leaves
out the word that uses it), system variables #1000 and above (signals, tool offsets, modal
information, positions), and AND / OR / XOR on values other than 0 and 1 (bitwise on a Fanuc).
One use of system variables passes: ``IF [cond] THEN #3000=n`` whose condition reads them (Haas'
tool life check ``IF [#5405 GE 6000] THEN #3000=15``). #3000 raises an alarm that stops the
program (Fanuc 0i-MF, custom macro, alarm #3000; Haas, macros, #3000 programmable alarm): either
way the motion that is executed is the program's own, up to where it stops, so the line is written
unchanged (the reader passes it through) and nothing else of the run depends on it. A condition
that holds without system variables stops the program there, and is refused as such.
Subprogram and macro calls (M98, M99, G65, G66) are refused by the reader.
"""
from __future__ import annotations

import re

from ..errors import InputError
from .expr import Evaluator, ExprError
from .lines import line_code, rewrite
from .ngc import _END, MAX_LINES, MAX_STEPS, check_steps, check_written

_STATEMENT = re.compile(r"(?:n(\d+))?(if\[|goto|while\[|end(\d))")
_SEQUENCE = re.compile(r"n(\d+)")
#: the action of an alarm-only IF: an assignment to #3000 (the programmable alarm), which stops
#: the program
_ALARM = re.compile(r"#3000=")


class SystemVariable(ExprError):
    """A system variable (#1000 and above) was read: controller state the program does not hold."""


class MacroParams:
    """Fanuc macro variables: every one vacant until it is set."""

    def __init__(self):
        self.values: dict[int, float] = {}

    def get(self, key):
        if isinstance(key, str):
            raise ExprError(f"named parameter #<{key}> is LinuxCNC's, not a Fanuc macro variable")
        if key >= 1000:
            raise SystemVariable(f"system variable #{key} (signals, offsets, modal state or positions) "
                            "is not known here")
        if key not in self.values:
            raise ExprError(f"variable #{key} is read before it is set (vacant: a Fanuc leaves "
                            "out the word that uses it, which mtcomp does not follow)")
        return self.values[key]

    def exists(self, key) -> bool:
        return False

    def set(self, key, value: float) -> None:
        if isinstance(key, str) or key == 0 or key >= 1000:
            raise ExprError(f"assignment to #{key}: not a local or common macro variable")
        self.values[key] = value


def _bracket_end(s: str, pos: int) -> int:
    depth = 0
    for p in range(pos, len(s)):
        depth += {"[": 1, "]": -1}.get(s[p], 0)
        if depth == 0:
            return p + 1
    raise ExprError("a condition without its closing ']'")


class MacroRun:
    """Runs a Fanuc macro program's lines; yields ``(line index, new text or None)`` like
    :class:`~.ngc.NgcRun`."""

    def __init__(self, texts: list[str], path, max_steps: int = MAX_STEPS,
                 max_lines: int = MAX_LINES):
        self.texts, self.path = texts, path
        self.max_steps, self.max_lines = max_steps, max_lines
        self.ev = Evaluator(MacroParams(), logical_only=True)
        self.codes = [line_code(t) for t in texts]
        self.sequence: dict[int, list[int]] = {}
        self.statements: dict[int, tuple] = {}
        loops: list[tuple[int, int]] = []
        self.partner: dict[int, int] = {}
        for i, c in enumerate(self.codes):
            m = _SEQUENCE.match(c.text)
            if m:
                self.sequence.setdefault(int(m.group(1)), []).append(i)
            st = _STATEMENT.match(c.text)
            if not st:
                continue
            self.statements[i] = self._parse(c.text, st, i)
            kind = self.statements[i][0]
            if kind == "while":
                loops.append((self.statements[i][3], i))
            elif kind == "end":
                if not loops or loops[-1][0] != self.statements[i][1]:
                    raise self.error(f"END{self.statements[i][1]} without its WHILE ... "
                                     f"DO{self.statements[i][1]}", i)
                _m, j = loops.pop()
                self.partner[i], self.partner[j] = j, i
        if loops:
            raise self.error(f"WHILE ... DO{loops[-1][0]} without its END{loops[-1][0]}",
                             loops[-1][1])

    def error(self, message: str, index: int) -> InputError:
        return InputError(message, self.path, index + 1)

    def _parse(self, code: str, m, i: int) -> tuple:
        """(kind, ...) of a macro statement: ('if', condition, action, target text), ('goto', target),
        ('while', condition, '', m), ('end', m)."""
        word, pos = m.group(2), m.end()
        try:
            if word.startswith("end"):
                if pos != len(code):
                    raise ExprError(f"text after END{m.group(3)}")
                return ("end", int(m.group(3)))
            if word == "goto":
                return ("goto", code[pos:])
            end = _bracket_end(code, pos - 1)
            cond, rest = code[pos - 1:end], code[end:]
            if word == "while[":
                dm = re.fullmatch(r"do(\d)", rest)
                if not dm:
                    raise ExprError("WHILE [...] without DOm after it")
                return ("while", cond, "", int(dm.group(1)))
            if rest.startswith("goto"):
                return ("if", cond, "goto", rest[4:])
            if rest.startswith("then"):
                return ("if", cond, "then", rest[4:])
            raise ExprError("IF [...] without GOTO or THEN after it")
        except ExprError as exc:
            raise self.error(str(exc), i) from None

    def _value(self, text: str, i: int, what: str) -> float:
        try:
            v, end = (self.ev.bracket(text, 0) if text.startswith("[") else self.ev.value(text, 0))
            if end != len(text):
                raise ExprError(f"text after the value: {text[end:end + 12]!r}")
        except ExprError as exc:
            raise self.error(f"{what}: {exc}", i) from None
        return v

    def _goto(self, target: str, i: int) -> int:
        n = self._value(target, i, "GOTO")
        lines = self.sequence.get(int(round(n)), [])
        if not lines:
            raise self.error(f"GOTO {n:g}: no line with sequence number N{n:g}", i)
        after = [j for j in lines if j > i]         # searched forward first, then from the start
        return after[0] if after else lines[0]

    def run(self):
        pc, steps, written = 0, 0, 0
        while pc < len(self.texts):
            steps += 1
            check_steps(self, steps, pc)
            st = self.statements.get(pc)
            if st is None:
                text = self._code_line(pc)
                if text is not False:
                    written += 1
                    check_written(self, written, pc)
                    yield pc, text
                if _END.search(self.codes[pc].text):
                    return
                pc += 1
                continue
            nxt = self._statement(pc, st)
            if nxt is None:               # an alarm-only IF on system variables: written as it is
                written += 1
                check_written(self, written, pc)
                yield pc, None
                nxt = pc + 1
            pc = nxt

    def _statement(self, i: int, st: tuple) -> int:
        kind = st[0]
        if kind == "goto":
            return self._goto(st[1], i)
        if kind == "end":
            return self.partner[i]
        if kind == "if" and st[2] == "then" and _ALARM.match(st[3]):
            return self._alarm(st, i)
        true = self._value(st[1], i, kind.upper()) != 0.0
        if kind == "while":
            return i + 1 if true else self.partner[i] + 1
        if not true:
            return i + 1
        if st[2] == "goto":
            return self._goto(st[3], i)
        self._assign(st[3], i)
        return i + 1

    def _alarm(self, st: tuple, i: int) -> int | None:
        """``IF [cond] THEN #3000=n``: None (pass the line through) when the condition reads system
        variables, the next line when it does not hold; refused when it holds (the program stops)."""
        try:
            v, _end = self.ev.bracket(st[1], 0)
        except SystemVariable:
            return None
        except ExprError as exc:
            raise self.error(f"IF: {exc}", i) from None
        if v != 0.0:
            raise self.error("IF ... THEN #3000: the condition holds, so the program stops here with "
                             "its alarm (nothing after this line runs)", i)
        return i + 1

    def _assign(self, code: str, i: int) -> None:
        try:
            r = rewrite(code, line_code(code), self.ev, fanuc=True)
            if not r.assignments or (r.text or "").strip():
                raise ExprError("THEN takes one assignment, e.g. THEN #1=2")
            for key, v in r.assignments:
                self.ev.params.set(key, v)
        except ExprError as exc:
            raise self.error(str(exc), i) from None

    def _code_line(self, i: int):
        try:
            r = rewrite(self.texts[i], self.codes[i], self.ev, fanuc=True)
            if r.polar:
                raise ExprError("polar words @ ^ are LinuxCNC's")
            for key, v in r.assignments:
                self.ev.params.set(key, v)
        except ExprError as exc:
            raise self.error(str(exc), i) from None
        if r.text is not None and not r.text.strip(" \t"):
            return False
        return r.text

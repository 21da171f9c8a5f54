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
Subprograms in the same file are expanded where they are called (Fanuc 0i-MF, "Subprogram";
Haas mill operator's manual, M97 local subprogram call, M98 subprogram call, M99 return):
``M98 P1000`` runs the program ``O1000`` of the file from the line after its O line, ``M98 P1000
L3`` (or Fanuc's ``M98 P00031000``: the repetitions in front of the 4-digit number) three times,
and Haas' ``M97 P100`` the lines from the block ``N100`` of this program on; ``M99`` returns to
the line after the call. A subprogram called at two places comes out twice, each with its own
correction; the call and return lines are not written (the flat program holds what they did).
Refused by name: a program number the file does not hold (a subprogram in the controller's memory),
``M99 P`` (a return to a sequence number), a call or return with other words on its line, calls
nested more than 10 deep. An ``M99`` in the main program (no call to return from: the controller
runs the program again from its start) passes through; one pass is what is corrected.
Macro calls ``G65 P1000 L2 A1. X5.`` are expanded as subprogram calls are, with a new level of
local variables set from the arguments (A -> #1, B -> #2, ... Z -> #26: argument specification I)
that the macro's M99 takes away again (FANUC 16i/18i-PB operator's manual B-63684EN, custom
macro, simple call G65, local variable levels; Haas mill operator's manual, macros, G65). Refused
by name: a macro the file does not hold (a probing or measuring cycle in the controller's memory),
an argument given twice (argument specification II), macro calls nested more than four deep. The
modal macro call G66 is refused by the reader.
"""
from __future__ import annotations

import re

from ..errors import InputError
from .expr import Evaluator, ExprError
from .lines import line_code, rewrite
from .ngc import _END, MAX_DEPTH, MAX_LINES, MAX_STEPS, check_steps, check_written

_STATEMENT = re.compile(r"(?:n(\d+))?(if\[|goto|while\[|end(\d))")
_SEQUENCE = re.compile(r"n(\d+)")
#: the action of an alarm-only IF: an assignment to #3000 (the programmable alarm), which stops
#: the program
_ALARM = re.compile(r"#3000=")
#: a subprogram call (M98; Haas' local call M97) or return (M99)
_SUBPROGRAM = re.compile(r"m0*(9[789])(?![\d.])")
#: the line that starts program O<n> (its number, at the start of the line's code)
_PROGRAM = re.compile(r"o0*(\d+)$")
#: a macro call G65 (simple call), anywhere in the line's code
_MACRO_CALL = re.compile(r"(?<![a-z])g0*65(?![\d.])")
#: the local variables #1-#33
LOCALS = 33
#: macro calls (G65) nest at most four levels deep (FANUC Series 16i/18i-PB operator's manual
#: B-63684EN, 16. custom macro, call nesting: four levels, M98 subprogram calls not counted)
MAX_MACRO_DEPTH = 4
#: argument specification I of a macro call: address -> local variable (FANUC 16i/18i-PB
#: operator's manual B-63684EN, custom macro, argument specification; Haas mill operator's manual,
#: macros, G65); G L N O P are not arguments
ARGUMENTS = {"a": 1, "b": 2, "c": 3, "i": 4, "j": 5, "k": 6, "d": 7, "e": 8, "f": 9, "h": 11,
             "m": 13, "q": 17, "r": 18, "s": 19, "t": 20, "u": 21, "v": 22, "w": 23, "x": 24,
             "y": 25, "z": 26}
#: a word's letter in a line's code once its bracketed expressions are taken out
_LETTER = re.compile(r"([a-z])(?=[-+]?[\d.#\[])")


class SystemVariable(ExprError):
    """A system variable (#1000 and above) was read: controller state the program does not hold."""


class MacroParams:
    """Fanuc macro variables: every one vacant until it is set. The local variables #1-#33 have a
    set per macro call level (``frames``: the main program's first; a G65 call pushes a new one
    and its M99 pops it, restoring the caller's)."""

    def __init__(self):
        self.values: dict[int, float] = {}
        self.frames: list[dict[int, float]] = [{}]

    def _store(self, key) -> dict:
        return self.frames[-1] if 1 <= key <= LOCALS else self.values

    def get(self, key):
        if isinstance(key, str):
            raise ExprError(f"named parameter #<{key}> is LinuxCNC's, not a Fanuc macro variable")
        if key >= 1000:
            raise SystemVariable(f"system variable #{key} (signals, offsets, modal state or positions) "
                            "is not known here")
        store = self._store(key)
        if key not in store:
            raise ExprError(f"variable #{key} is read before it is set (vacant: a Fanuc leaves "
                            "out the word that uses it, which mtcomp does not follow)")
        return store[key]

    def exists(self, key) -> bool:
        return False

    def set(self, key, value: float) -> None:
        if isinstance(key, str) or key == 0 or key >= 1000:
            raise ExprError(f"assignment to #{key}: not a local or common macro variable")
        self._store(key)[key] = value


def _bracket_end(s: str, pos: int) -> int:
    depth = 0
    for p in range(pos, len(s)):
        depth += {"[": 1, "]": -1}.get(s[p], 0)
        if depth == 0:
            return p + 1
    raise ExprError("a condition without its closing ']'")


def _without_brackets(s: str) -> str:
    """A line's code with each bracketed expression replaced by 0 (its words' letters stay)."""
    out, pos = [], 0
    while pos < len(s):
        if s[pos] == "[":
            end = _bracket_end(s, pos)
            out.append("0")
            pos = end
        else:
            out.append(s[pos])
            pos += 1
    return "".join(out)


class MacroRun:
    """Runs a Fanuc macro program's lines; yields ``(line index, new text or None)`` like
    :class:`~.ngc.NgcRun`."""

    def __init__(self, texts: list[str], path, max_steps: int = MAX_STEPS,
                 max_lines: int = MAX_LINES, dialect: str = "fanuc"):
        self.texts, self.path = texts, path
        #: Haas' M97 calls a subprogram at a sequence number of this program
        self.local_calls = dialect == "haas"
        #: subprogram calls in progress: (the line to return to, the subprogram's first line,
        #: repetitions left)
        self.calls: list[list[int]] = []
        self.programs: dict[int, int] = {}
        self.max_steps, self.max_lines = max_steps, max_lines
        self.ev = Evaluator(MacroParams(), logical_only=True)
        self.codes = [line_code(t) for t in texts]
        self.sequence: dict[int, list[int]] = {}
        self.statements: dict[int, tuple] = {}
        loops: list[tuple[int, int]] = []
        self.partner: dict[int, int] = {}
        for i, c in enumerate(self.codes):
            p = _PROGRAM.match(c.text)
            if p:
                self.programs.setdefault(int(p.group(1)), i)
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
        #: the lines that start a program (O<n>); the first is the main program's, which ends
        #: where the next one starts (the controller keeps the file's programs apart)
        self.starts = frozenset(self.programs.values())
        self.first = min(self.starts, default=-1)

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
            if pc in self.starts and pc != self.first:    # the next program of the file
                if self.calls:
                    raise self.error("a subprogram runs into the next program without its M99 "
                                     f"(called at line {self.calls[-1][0]})", pc)
                return
            jump = self._subprogram(pc) if st is None else None
            if jump is not None:
                pc = jump
                continue
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

    def _subprogram(self, i: int) -> int | None:
        """The line to run next when line ``i`` calls a subprogram (M98, Haas' M97) or returns from
        one (M99); None for any other line (an M99 of the main program included)."""
        if _MACRO_CALL.search(self.codes[i].text):
            return self._macro_call(i)
        m = _SUBPROGRAM.search(self.codes[i].text)
        kind = int(m.group(1)) if m else 0
        if kind == 0 or (kind == 97 and not self.local_calls) or (kind == 99 and not self.calls):
            return None
        try:
            r = rewrite(self.texts[i], self.codes[i], self.ev, fanuc=True)
        except ExprError as exc:
            raise self.error(str(exc), i) from None
        others = sorted(set(r.words) - {"n", "m", "p", "l"})
        if r.assignments or others or len(_SUBPROGRAM.findall(self.codes[i].text)) > 1:
            raise self.error(f"M{kind} with other words on its line "
                             f"({', '.join(others).upper() or 'M'}): "
                             "put the call or return on a line of its own", i)
        if kind == 99:
            if "p" in r.words:
                raise self.error("M99 P (a return to a sequence number of the calling program) is "
                                 "not followed", i)
            call = self.calls[-1]
            call[2] -= 1
            if call[2] > 0:              # a G65 L repetition keeps its local variables
                return call[1]
            self.calls.pop()
            if call[3]:                  # the end of a macro call: the caller's locals again
                self.ev.params.frames.pop()
            return call[0]
        return self._call(kind, r.words, i)

    def _call(self, kind: int, words: dict, i: int) -> int:
        """The first line of the subprogram that line ``i`` calls (M98 P.. [L..], M97 P.. [L..])."""
        if "p" not in words:
            raise self.error(f"M{kind} without P (the subprogram to call)", i)
        number, reps = words["p"], words.get("l", 1.0)
        if kind == 98 and "l" not in words and number > 9999:      # Fanuc's P<reps><4 digits>
            reps, number = divmod(number, 10000)
        if number != int(number) or reps != int(reps) or reps < 1:
            raise self.error(f"M{kind} P{number:g} L{reps:g}: the number and the repetitions must be "
                             "whole, the repetitions at least 1", i)
        if kind == 98:
            if int(number) not in self.programs:
                raise self.error(f"M98 P{number:g}: no program O{number:g} in this file (a subprogram "
                                 "in the controller's memory: its motion is not in the file)", i)
            start = self.programs[int(number)] + 1
        else:
            first, end = self._program_of(i)
            lines = [j for j in self.sequence.get(int(number), []) if first <= j < end]
            if not lines:
                raise self.error(f"M97 P{number:g}: no block N{number:g} in this program", i)
            start = lines[0]
        if len(self.calls) >= MAX_DEPTH:
            raise self.error(f"M{kind}: subprograms nested more than {MAX_DEPTH} deep", i)
        self.calls.append([i + 1, start, int(reps), False])
        return start

    def _macro_call(self, i: int) -> int:
        """The first line of the macro program that line ``i`` calls (``G65 P.. [L..]`` and its
        arguments): a new level of local variables, set from the arguments (argument specification
        I), is pushed; its M99 pops it. The repetitions of ``L`` keep the level (Haas mill
        operator's manual, macros, G65: the arguments are set on the first repetition only)."""
        code = self.codes[i].text
        try:
            r = rewrite(self.texts[i], self.codes[i], self.ev, fanuc=True)
            letters = _LETTER.findall(_without_brackets(code))
        except ExprError as exc:
            raise self.error(f"G65: {exc}", i) from None
        twice = sorted({c.upper() for c in letters if letters.count(c) > 1})
        if twice:
            raise self.error(f"G65 with {', '.join(twice)} more than once (argument specification "
                             "II, or a second code) is not followed", i)
        others = sorted(c.upper() for c in set(letters) - set(ARGUMENTS) - {"g", "l", "n", "p"})
        if r.assignments or others:
            raise self.error(f"G65 with {', '.join(others) or 'an assignment'} on its line: put "
                             "the call on a line of its own", i)
        if "p" not in r.words:
            raise self.error("G65 without P (the macro program to call)", i)
        number, reps = r.words["p"], r.words.get("l", 1.0)
        if number != int(number) or reps != int(reps) or reps < 1:
            raise self.error(f"G65 P{number:g} L{reps:g}: the number and the repetitions must be "
                             "whole, the repetitions at least 1", i)
        if int(number) not in self.programs:
            raise self.error(f"G65 P{number:g}: no program O{number:g} in this file (a macro in the "
                             "controller's memory, e.g. a probing or measuring cycle: its motion "
                             "is not in the file)", i)
        if sum(c[3] for c in self.calls) >= MAX_MACRO_DEPTH or len(self.calls) >= MAX_DEPTH:
            raise self.error(f"G65: macro calls nested more than {MAX_MACRO_DEPTH} deep (or calls "
                             f"more than {MAX_DEPTH})", i)
        start = self.programs[int(number)] + 1
        self.ev.params.frames.append({ARGUMENTS[c]: float(v) for c, v in r.words.items()
                                      if c in ARGUMENTS})
        self.calls.append([i + 1, start, int(reps), True])
        return start

    def _program_of(self, i: int) -> tuple[int, int]:
        """(first line, line after the last) of the program of the file that holds line ``i``."""
        first = max((s for s in self.starts if s <= i), default=0)
        end = min((s for s in self.starts if s > i), default=len(self.texts))
        return first, end

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

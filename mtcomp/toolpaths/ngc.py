"""LinuxCNC's RS274/NGC front end: O-word control flow and parameters expanded into flat lines.

The program is run the way LinuxCNC's interpreter reads it (LinuxCNC G-code reference, O codes /
Numbered parameters / Expressions): ``oN sub`` / ``endsub`` / ``call [a] [b]`` / ``return``,
``if`` / ``elseif`` / ``else`` / ``endif``, ``while`` / ``endwhile``, ``do`` / ``while``, ``repeat`` /
``endrepeat``, ``break`` / ``continue``; numbered parameters (``#1``-``#30`` local to a call,
``#31`` and above global, unset ones 0), local named ``#<name>`` and global ``#<_name>`` (unset ones
an error), assignments that take effect after their line, polar words. What comes out is the
sequence of lines the controller executes: a subroutine called at two places appears twice, a loop
once per pass. A line that needs nothing computed keeps its bytes; O-word lines and lines of
assignments alone are left out; a line with computed values is written with the numbers.

A value the controller holds as it runs (its position ``#<_x>``, a probe's result ``#5063``, FluidNC's
``#</...>`` settings: :func:`controller_value`) is read as unknown, and the line using it written as
the controller computes it (:mod:`.controller_values`); control flow on it is refused. Other
controller state that the program's file does not hold is refused by name: parameters #5000 and
above (offsets, tool data), LinuxCNC's other predefined named parameters, and subroutines in other
files.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field

from ..errors import InputError
from .expr import UNKNOWN, Evaluator, ExprError, is_unknown
from .lines import (ControllerLine, XYTracker, gcodes_of, line_code, place_polar, polar_target,
                    rewrite)

#: at most this many lines executed (a loop that never ends is refused, not followed forever)
MAX_STEPS = 5_000_000
#: at most this many lines written
MAX_LINES = 2_000_000
#: LinuxCNC's deepest subroutine nesting (O codes: "The maximum subroutine nesting level is 10")
MAX_DEPTH = 10
_KEYWORDS = ("endsub", "sub", "call", "return", "elseif", "else", "endif", "if", "endwhile",
             "while", "do", "endrepeat", "repeat", "break", "continue")
_OWORD = re.compile(r"(?:n\d+(?:\.\d*)?)?o(<[^>]*>|\d+|\[)")
_END = re.compile(r"m0*(?:2|30)(?![\d.])")


@dataclass
class Statement:
    """An O-word line: its keyword, label ('100', '<name>' or '' for a computed one), the code after
    the keyword (conditions, arguments), where it matches (filled by :func:`structure`)."""

    kind: str
    label: str
    rest: str
    label_expr: str = ""
    partner: int = -1            # closing line of sub/if/while/do/repeat; opening of break/...
    branches: list = field(default_factory=list)


def parse_oword(code: str) -> Statement | None:
    """The O-word statement of a line's code, or None for a line without one."""
    m = _OWORD.match(code)
    if not m:
        return None
    pos = m.end()
    label, label_expr = m.group(1), ""
    if label == "[":
        depth, p = 1, pos
        while p < len(code) and depth:
            depth += {"[": 1, "]": -1}.get(code[p], 0)
            p += 1
        label_expr, label, pos = code[pos - 1:p], "", p
    elif label.isdigit():
        label = str(int(label))
    else:
        label = label.replace(" ", "")
    for kind in _KEYWORDS:
        if code.startswith(kind, pos):
            return Statement(kind, label, code[pos + len(kind):], label_expr)
    return Statement("", label, code[pos:], label_expr)


#: the numbered parameters that hold what the controller measured as it runs the program: the last
#: probe's end #5061-#5069 and whether it touched #5070, the current position #5420-#5428
#: (LinuxCNC G-code reference, Numbered Parameters; FluidNC src/Parameters.cpp, get_numbered_param)
CONTROLLER_NUMBERED = frozenset(range(5061, 5071)) | frozenset(range(5420, 5429))
#: the predefined named parameters of the current position, in the work frame and the machine's
#: (LinuxCNC G-code reference, Predefined Named Parameters; FluidNC src/Parameters.cpp,
#: get_system_param); FluidNC's ``#</axes/z/...>`` (a ``/`` first) reads its configuration
CONTROLLER_NAMED = frozenset(f"_{a}" for a in "xyzabcuvw") | frozenset(
    f"_abs_{a}" for a in "xyzabcuvw")


def controller_value(key) -> bool:
    """Whether parameter ``key`` holds a value the controller has when it runs the program and the
    file does not give (:data:`CONTROLLER_NUMBERED`, :data:`CONTROLLER_NAMED`, a configuration
    item ``/...``): read as :data:`~.expr.UNKNOWN`."""
    if isinstance(key, int):
        return key in CONTROLLER_NUMBERED
    return key in CONTROLLER_NAMED or key.startswith("/")


class NgcParams:
    """LinuxCNC's parameters: numbered (#1-#30 saved and restored around a call), global named
    (``_`` first) and local named ones (one table per call). A value the controller holds
    (:func:`controller_value`) reads as :data:`~.expr.UNKNOWN`, and so does a parameter assigned one."""

    def __init__(self):
        self.numbered: dict[int, float] = {}
        self.globals: dict[str, float] = {}
        self.frames: list[dict] = [{}]

    @property
    def in_call(self) -> bool:
        """A subroutine call is in progress (a value the controller holds is not assigned there:
        the expansion writes its assignment where the main program's parameters are)."""
        return len(self.frames) > 1

    def get(self, key):
        if controller_value(key):
            return UNKNOWN
        if isinstance(key, int):
            if key >= 5000:
                raise ExprError(f"parameter #{key} holds controller state (offsets, positions, tool "
                                "data) that the program's file does not give")
            return self.numbered.get(key, 0.0)
        table = self.globals if key.startswith("_") else self.frames[-1]
        if key not in table:
            what = ("a global parameter used before the program sets it (or one of the "
                    "controller's predefined ones, whose state the file does not give)"
                    if key.startswith("_") else "used before it is set")
            raise ExprError(f"named parameter #<{key}>: {what}")
        return table[key]

    def exists(self, key) -> bool:
        return key in (self.globals if key.startswith("_") else self.frames[-1])

    def set(self, key, value: float) -> None:
        name = f"#<{key}>" if isinstance(key, str) else f"#{key}"
        if is_unknown(value) and self.in_call:
            raise ExprError(f"a value the controller holds assigned to {name} inside a subroutine "
                            "call: not followed (assign it in the main program)")
        if controller_value(key):
            raise ExprError(f"assignment to {name}: a value the controller holds")
        if isinstance(key, int):
            if key >= 5000 or key == 0:
                raise ExprError(f"assignment to parameter #{key}: it changes controller state "
                                "(offsets, tool data) that mtcomp does not follow")
            self.numbered[key] = value
        elif key.startswith("_"):
            self.globals[key] = value
        else:
            self.frames[-1][key] = value


#: the refusal of control flow that depends on a value the controller holds
_UNKNOWN_FLOW = ("{what} reads a value the controller holds (its position, a probe's result, a "
                 "setting): which lines run, and so the flat sequence of moves, cannot be known")

_OPENERS = {"endsub": "sub", "endif": "if", "endwhile": "while", "endrepeat": "repeat"}


def structure(statements: dict, err) -> dict:
    """Match every O-word statement with its partners (LinuxCNC's O codes: labels match within
    the subroutine or main program). statements : line index -> Statement, in order. Returns
    subroutine label -> index of its ``sub`` line. err(message, index) -> InputError."""
    subs, stack = {}, []
    for i, st in statements.items():
        k, lab = st.kind, st.label
        if st.label_expr and k != "call":
            raise err(f"o[...] {k}: a computed O-word label is supported on call only", i)
        if k == "sub":
            if any(s.kind == "sub" for _j, s in stack):
                raise err(f"o{lab} sub inside another subroutine's definition", i)
            stack.append((i, st))
        elif k in ("if", "do", "repeat") or (k == "while" and not (
                stack and stack[-1][1].kind == "do" and stack[-1][1].label == lab)):
            stack.append((i, st))
            st.branches = [i]
        elif k in ("elseif", "else"):
            if not stack or stack[-1][1].kind != "if" or stack[-1][1].label != lab:
                raise err(f"o{lab} {k} without its o{lab} if", i)
            stack[-1][1].branches.append(i)
            st.partner = stack[-1][0]
        elif k in _OPENERS or k == "while":
            want = "do" if k == "while" else _OPENERS[k]
            if not stack or stack[-1][1].kind != want or stack[-1][1].label != lab:
                raise err(f"o{lab} {k} without its o{lab} {want}", i)
            j, opener = stack.pop()
            opener.partner = i
            st.partner = j
            opener.branches.append(i)
            if k == "endsub":
                if lab in subs:
                    raise err(f"o{lab} sub is defined twice", i)
                subs[lab] = j
            if k == "while":
                st.kind = "do-while"
        elif k in ("break", "continue", "return"):
            kinds = ("sub",) if k == "return" else ("while", "do", "repeat")
            found = [j for j, s in stack if s.kind in kinds and s.label == lab]
            if not found:
                raise err(f"o{lab} {k} outside its o{lab} {'sub' if k == 'return' else 'loop'}", i)
            st.partner = found[-1]
        elif k != "call":
            raise err(f"o-word {st.kind or st.rest[:12]!r} is not a LinuxCNC O-word statement", i)
    if stack:
        j, st = stack[-1]
        closing = {"sub": "endsub", "if": "endif", "while": "endwhile", "do": "while",
                   "repeat": "endrepeat"}[st.kind]
        raise err(f"o{st.label} {st.kind} without its o{st.label} {closing}", j)
    return subs


def check_steps(run, steps: int, pc: int, loop_line: int | None = None) -> None:
    """The runaway guard of a program run (LinuxCNC's or Fanuc macro B's): ``run.error`` when more
    than ``run.max_steps`` lines were executed (naming the loop at ``loop_line``, 0-based)."""
    if steps > run.max_steps:
        where = f" (the loop at line {loop_line + 1})" if loop_line is not None else ""
        raise _runaway(run.error(f"more than {run.max_steps} lines executed{where}: a loop that "
                                 "does not end? (mtcomp expands at most that many)", pc))


def check_written(run, written: int, pc: int) -> None:
    """The size guard of a program run: ``run.error`` past ``run.max_lines`` lines written."""
    if written > run.max_lines:
        raise _runaway(run.error(f"the expanded program passes {run.max_lines} lines: a loop "
                                 "that does not end?", pc))


def _runaway(err: InputError) -> InputError:
    """``err`` marked as a fault of the whole run (a loop that does not end), which the expansion
    raises at once rather than after reading the lines before it (:mod:`.source`)."""
    err.runaway = True
    return err


@dataclass
class _Frame:
    return_to: int
    saved: dict
    repeats: dict = field(default_factory=dict)


class NgcRun:
    """Runs a program's lines (text without line endings) and yields ``(line index, new text or
    None for the line as written)`` for every line the controller executes."""

    def __init__(self, texts: list[str], path, max_steps: int = MAX_STEPS,
                 max_lines: int = MAX_LINES):
        self.texts, self.path = texts, path
        self.max_steps, self.max_lines = max_steps, max_lines
        self.params = NgcParams()
        self.ev = Evaluator(self.params)
        self.codes = [line_code(t) for t in texts]
        self.statements = {}
        for i, c in enumerate(self.codes):
            st = parse_oword(c.text)
            if st is not None and st.kind:
                self.statements[i] = st       # ('o1234' without a keyword: a program number)
        self.subs = structure(self.statements, self.error)
        self.frames: list[_Frame] = []
        self.xy = XYTracker()
        self.loop_line = None
        self.main_repeats: dict = {}
        #: a line with words was executed (a file of subroutine definitions only runs none)
        self.ran_code = False

    def error(self, message: str, index: int) -> InputError:
        return InputError(message, self.path, index + 1)

    def check_ran(self) -> str | None:
        """The note for a file of subroutine definitions that nothing in it calls (None for any
        other): no line of words runs (an ngcgui subroutine file runs when another program calls
        it, with that program's arguments, which this file does not give), so nothing in it moves
        and nothing is corrected."""
        if self.ran_code or not self.subs:
            return None
        label, first = min(self.subs.items(), key=lambda item: item[1])
        return (f"note: a file of subroutines only (o{label} sub ... endsub at line {first + 1}, "
                "called by no line of it): nothing in it runs, so nothing in it is corrected; "
                "compensate the program that calls it, with the subroutine in it")

    def _eval(self, text: str, index: int, what: str) -> float:
        try:
            if not text.startswith("["):
                raise ExprError(f"{what}: a value in [ ] is expected")
            v, end = self.ev.counted(self.ev.bracket, text, 0)
            if end != len(text):
                raise ExprError(f"{what}: text after the value: {text[end:end + 12]!r}")
            if is_unknown(v):
                raise ExprError(_UNKNOWN_FLOW.format(what=what))
            return v
        except ExprError as exc:
            raise self.error(str(exc), index) from None

    def run(self):
        pc, steps, written = 0, 0, 0
        n = len(self.texts)
        while pc < n:
            steps += 1
            check_steps(self, steps, pc, self.loop_line)
            st = self.statements.get(pc)
            if st is None:
                text = self._code_line(pc)
                for t in (text if isinstance(text, list) else [text]):
                    if t is not False:
                        self.ran_code = self.ran_code or bool(self.codes[pc].text)
                        written += 1
                        check_written(self, written, pc)
                        yield pc, t
                if not self.frames and _END.search(self.codes[pc].text):
                    return                     # M2 / M30 ends the program
                pc += 1
                continue
            pc = self._statement(pc, st)

    def _code_line(self, i: int):
        """A line of words: its values computed (None: unchanged; False: nothing left to write)."""
        code = self.codes[i]
        try:
            r = rewrite(self.texts[i], code, self.ev)
            text = r.text
            if r.polar:
                self.xy.follow({}, gcodes_of(line_code(text).text))      # G90/G91 of the line first
                if "l" in r.words:
                    return self._polar_repeats(text, r)
                xy = polar_target(r.polar, r.words, self.xy.xy, self.xy.incremental)
                written = xy                # in G91 the words are the increments
                if self.xy.incremental:
                    written = (xy[0] - self.xy.xy[0], xy[1] - self.xy.xy[1])
                upper = any(ch.isupper() for ch in self.texts[i])
                text = place_polar(text, written, upper, r.polar)
                self.xy.set(xy)
            else:
                self.xy.follow(r.words, gcodes_of(line_code(text).text if text else code.text))
            for key, v in r.assignments:
                self.params.set(key, v)
        except ExprError as exc:
            raise self.error(str(exc), i) from None
        if r.reading is not None:           # a value the controller holds: as it computes it
            return ControllerLine.of(r)
        if text is not None and not text.strip(" \t"):
            return False
        return text

    def _polar_repeats(self, text: str, r) -> list[str]:
        """A drilling cycle in G91 with polar words and a repeat count L (``G91 G81 R.1 Z-.5 ^60
        L6``): LinuxCNC repeats the cycle L times, each time applying the incremental polar move
        (LinuxCNC G-code reference, Polar Coordinates and G81; its R measured from the series'
        initial level each time). Written as L lines without L, one hole each, their X Y the
        increments, each marked with a comment."""
        count = r.words["l"]
        code = text.split("(", 1)[0].split(";", 1)[0]
        words = re.findall(r"(?i)l[ \t]*\+?\d+\.?\d*", code)
        if not self.xy.incremental or count != int(count) or count < 1 or len(words) != 1 \
                or not any(round(g) in range(73, 90) for g in gcodes_of(line_code(text).text)):
            raise ExprError("polar words @ ^ with a repeat count L are followed in an incremental "
                            "(G91) drilling cycle only")
        text = text.replace(words[0], "", 1).replace("\0 ", "\0").rstrip(" \t")
        upper = any(ch.isupper() for ch in text)
        out = []
        for k in range(1, int(count) + 1):
            xy = polar_target(r.polar, {}, self.xy.xy, True)
            step = (xy[0] - self.xy.xy[0], xy[1] - self.xy.xy[1])
            out.append(place_polar(text, step, upper, r.polar) + f" (repeat {k} of {int(count)})")
            self.xy.set(xy)
        return out

    def _statement(self, i: int, st: Statement) -> int:
        """Execute an O-word line; returns the next line index."""
        k = st.kind
        if k == "sub":
            return st.partner + 1                       # a definition is skipped
        if k == "call":
            return self._call(i, st)
        if k in ("endsub", "return"):
            return self._return(i, st)
        if k == "if":
            for b in st.branches[:-1]:
                bst = self.statements[b]
                if bst.kind == "else" or self._eval(bst.rest, b, f"o{st.label} {bst.kind}"):
                    return b + 1
            return st.branches[-1] + 1
        if k in ("elseif", "else"):                    # the end of a branch that was taken
            return self.statements[st.partner].branches[-1] + 1
        if k == "endif":
            return i + 1
        if k == "while":
            self.loop_line = i
            return i + 1 if self._eval(st.rest, i, f"o{st.label} while") else st.partner + 1
        if k == "endwhile":
            return st.partner
        if k == "do":
            return i + 1
        if k == "do-while":
            self.loop_line = st.partner
            return st.partner + 1 if self._eval(st.rest, i, f"o{st.label} while") else i + 1
        if k == "repeat":
            count = self._eval(st.rest, i, f"o{st.label} repeat")
            if round(count) <= 0:
                return st.partner + 1
            self._repeats()[i] = int(round(count))
            return i + 1
        if k == "endrepeat":
            self.loop_line = st.partner
            left = self._repeats()
            left[st.partner] -= 1
            if left[st.partner] > 0:
                return st.partner + 1
            del left[st.partner]
            return i + 1
        loop = self.statements[st.partner]
        if k == "break":
            self._repeats().pop(st.partner, None)
            return loop.partner + 1
        # continue: to the test of a while loop, the closing test of a do loop, the count of a repeat
        return st.partner if loop.kind == "while" else loop.partner

    def _repeats(self) -> dict:
        return self.frames[-1].repeats if self.frames else self.main_repeats

    def _call(self, i: int, st: Statement) -> int:
        label = st.label
        if st.label_expr:
            v = self._eval(st.label_expr, i, "o[...] call")
            label = str(int(round(v)))
        if label not in self.subs:
            where = (f" (LinuxCNC would look for the file {label[1:-1]}.ngc on its subroutine path; "
                     "mtcomp reads the one program)") if label.startswith("<") else ""
            raise self.error(f"o{label} call: no subroutine o{label} in this program{where}", i)
        if len(self.frames) >= MAX_DEPTH:
            raise self.error(f"o{label} call: subroutines nested more than {MAX_DEPTH} deep", i)
        args, rest = [], st.rest
        pos = 0
        try:
            while pos < len(rest):
                if rest[pos] != "[":
                    raise ExprError(f"call arguments must each be in [ ], got {rest[pos:pos + 12]!r}")
                v, pos = self.ev.counted(self.ev.bracket, rest, pos)
                if is_unknown(v):
                    raise ExprError(_UNKNOWN_FLOW.format(what=f"o{label} call argument"))
                args.append(v)
        except ExprError as exc:
            raise self.error(str(exc), i) from None
        if len(args) > 30:
            raise self.error(f"o{label} call with {len(args)} arguments (at most 30)", i)
        p = self.params
        saved = {k: p.numbered.get(k) for k in range(1, 31)}
        for k, v in enumerate(args, 1):
            p.numbered[k] = v
        p.globals["_value"] = 0.0
        p.globals["_value_returned"] = 0.0
        p.frames.append({})
        self.frames.append(_Frame(i, saved))
        return self.subs[label] + 1

    def _return(self, i: int, st: Statement) -> int:
        if st.rest:
            self.params.globals["_value"] = self._eval(st.rest, i, f"o{st.label} {st.kind}")
            self.params.globals["_value_returned"] = 1.0
        if not self.frames:                 # pragma: no cover - structure() keeps them in a sub
            raise self.error(f"o{st.label} {st.kind} outside a subroutine call", i)
        frame = self.frames.pop()
        self.params.frames.pop()
        for k, v in frame.saved.items():
            if v is None:
                self.params.numbered.pop(k, None)
            else:
                self.params.numbered[k] = v
        return frame.return_to + 1

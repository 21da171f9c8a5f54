"""A controller-style replay of a Siemens Sinumerik 840D program, written for the tests from the
SINUMERIK 840D sl Programming Manual (Fundamentals, Job planning; Siemens AG 2013) and the Cycles
manual (Siemens AG 2013), independently of mtcomp's reader: the program becomes the moves the
controller makes (tests/replay.py's Move and Replay) and the lines that make none.

Rules: `;` comments; `N` numbers and `NAME:` labels; `%_N_..._MPF` header; `/` skippable blocks run
(the block-skip switch off: the only ones the corpus has move nothing); `DEF REAL|INT name=value`
and `R<n>=` parameters, `X=expr` (the four operations and parentheses); G0 G1 straight moves, G2 G3
circles in G17 about `I=AC(..) J=AC(..)` (absolute) or `I J` (from the start), without an end
point the full circle; a work offset change (G54 ..., and back to the basic frame G500) and a
subprogram or cycle whose moves are not in the file (`L54`, `NAME(...)`, `MCALL NAME(...)` after
each positioning block) leave every axis unknown, as does a tool change M6 (the machine maker's
cycle). CYCLE81 ... CYCLE89 (RTP, RFP, SDIS, DP, DPR, ...): from the position, rapid to RFP+SDIS,
feed to the depth (RFP-DPR when DPR is given, else DP), rapid to RTP; called once by
`CYCLE81(...)` or after each positioning block of `MCALL CYCLE81(...)` until `MCALL`;
`HOLES2(CPA, CPO, RAD, STA1, INDA, NUM)` positions at rapid on the circle, `HOLES1(SPCA, SPCO,
STA1, FDIS, DBH, NUM)` on the line from (SPCA, SPCO) at STA1 degrees, FDIS to the first, DBH apart,
the modal call at each.
A line that holds a call, an `MCALL` or a circle's centre is a state line (its numbers move with
the correction), so it is not among the lines without motion; nor is the output's note line
`; mtcomp: ...`. `positioned_per_line` gives, per line, whether it may be rewritten and which
axes the program has positioned after it (the corpus test's safety oracle)."""
import math
import re

from replay import AXES, Move, Replay, _align, _runs
from replay_heidenhain import arc_move

_START = re.compile(r"^\s*/?\s*(?:N\d+\s*)?(?:[A-Z_][A-Z0-9_]*:(?!=)\s*)?")
_CALL = re.compile(r"([A-Z_][A-Z0-9_]*)\s*\((.*)\)")
_AXIS = re.compile(r"(?<![A-Z0-9_])([XYZABCIJ])\s*(=\s*\S+|[-+]?(?:\d+\.?\d*|\.\d+))")
_G = re.compile(r"(?<![A-Z0-9_])G(\d+)")
_ASSIGN = re.compile(r"(?<![A-Z0-9_])(R\d+|[A-Z_][A-Z0-9_]{2,})\s*=\s*(\S+)")


def _code(raw: bytes) -> str:
    text = raw.decode("latin-1").replace("\r", "").split(";")[0].upper()
    if text.lstrip().startswith("%"):
        return ""
    return text[_START.match(text).end():].strip()


class _Controller:
    def __init__(self):
        self.pos = {a: None for a in AXES}
        self.vars = {}
        self.motion = None
        self.modal = None           # the modal call: (name, argument texts)
        self.wcs = None             # no work system named yet

    def value(self, text):
        text = text.strip()
        if text.startswith("="):
            text = text[1:]
        return float(eval(re.sub(r"(?<![\w.])0+(\d)", r"\1", text), {"__builtins__": {}},
                          dict(self.vars)))

    def unknown(self):
        self.pos = {a: None for a in AXES}


def replay(data: bytes) -> Replay:
    """The moves of a Sinumerik program (its bytes) and its lines without motion."""
    c = _Controller()
    out = Replay()
    for index, raw in enumerate(data.split(b"\n")):
        code = _code(raw)
        state, moves = _block(c, index, code) if code else (False, [])
        out.moves.extend(moves)
        if not moves and not state and not raw.startswith(b"; mtcomp:"):
            out.still.append((index, raw))
    return out


def _block(c, index, code):
    """(is a state line, the moves) of one block."""
    if code.startswith("DEF "):
        for name, expr in re.findall(r"([A-Z_][A-Z0-9_]*)\s*=\s*([^,]+)", code[8:]):
            c.vars[name] = c.value(expr)
        return False, []
    for name, expr in _ASSIGN.findall(code):
        try:
            c.vars[name] = c.value(expr)
        except NameError:                      # a parameter a subprogram set
            c.vars[name] = math.nan
    g = [int(v) for v in _G.findall(code)]
    for v in g:
        if v in (54, 55, 56, 57, 500) and v != c.wcs:
            c.wcs = v
            c.unknown()
    c.motion = next((v for v in g if v in (0, 1, 2, 3)), c.motion)
    if re.search(r"(?<![A-Z0-9_])M0*6(?!\d)", code):
        c.unknown()
    if code.startswith("MCALL"):
        m = _CALL.search(code)
        c.modal = (m.group(1), m.group(2).split(",")) if m else None
        return True, []
    call = _CALL.search(code)
    if call and call.group(1) != "AC":
        return True, _call(c, index, call.group(1), call.group(2).split(","))
    if re.match(r"L\d+", code):
        c.unknown()
        return True, []
    words = {a: v for a, v in _AXIS.findall(code)}
    if c.motion in (2, 3) and ("I" in words or "J" in words):
        return True, [_arc(c, index, words)]
    target = dict(c.pos)
    for a, v in words.items():
        target[a] = c.value(v)
    if target == c.pos and not words:
        return False, []
    move = Move(index, "rapid" if c.motion == 0 else "feed", dict(c.pos), target)
    c.pos = target
    moves = [move]
    if c.modal is not None:
        moves += _cycle(c, index, *c.modal)
    return False, moves


def _cycle(c, index, name, args):
    if not re.fullmatch(r"CYCLE8[1-9]", name):
        c.unknown()
        return []
    rtp, rfp, sdis = (c.value(a) for a in args[:3])
    bottom = rfp - c.value(args[4]) if len(args) > 4 and args[4].strip() else c.value(args[3])
    moves = []
    for kind, z in (("rapid", rfp + sdis), ("feed", bottom), ("rapid", rtp)):
        end = dict(c.pos, Z=z)
        moves.append(Move(index, kind, dict(c.pos), end))
        c.pos = end
    return moves


def _call(c, index, name, args):
    if name in ("HOLES1", "HOLES2"):
        x0, y0, p, q, r, num = (c.value(a) for a in args)
        if name == "HOLES1":        # p: the line's angle, q: to the first hole, r: between holes
            at = [(q + i * r, math.radians(p)) for i in range(int(num))]
        else:                       # p: the radius, q: the first angle, r: the step (0: evenly)
            at = [(p, math.radians(q + i * (r if r else 360.0 / num))) for i in range(int(num))]
        moves = []
        for d, a in at:
            end = dict(c.pos, X=x0 + d * math.cos(a), Y=y0 + d * math.sin(a))
            moves.append(Move(index, "rapid", dict(c.pos), end))
            c.pos = end
            moves += _cycle(c, index, *c.modal)
        return moves
    return _cycle(c, index, name, args)


def _arc(c, index, words):
    start = dict(c.pos)
    end = dict(start)
    for a in "XYZ":
        if a in words:
            end[a] = c.value(words[a])
    centre = []
    for letter, s in (("I", start["X"]), ("J", start["Y"])):
        v = words[letter]
        m = re.match(r"=\s*AC\((.*)\)$", v)
        centre.append(c.value(m.group(1)) if m else s + c.value(v))
    c.pos = end
    return arc_move(index, start, end, centre, c.motion == 3)


def compare(src: bytes, out: bytes, tol, name: str = ""):
    """As replay.compare, for Sinumerik programs: lines without motion byte for byte and in
    order, the motion between them the same up to the correction."""
    a, b = replay(src), replay(out)
    if [r for _, r in a.still] != [r for _, r in b.still]:
        bad = next((i for i, (x, y) in enumerate(zip(a.still, b.still)) if x[1] != y[1]), -1)
        raise AssertionError(f"{name}: the lines without motion differ (at {bad})")
    for src_run, dst_run in zip(_runs(a), _runs(b)):
        _align(src_run, dst_run, tol, name)
    return a.moves, b.moves


def positioned_per_line(text: str):
    """Per line: (may be rewritten: a move or a state line, axes positioned after it)."""
    c = _Controller()
    out = []
    for index, raw in enumerate(text.split("\n")):
        code = _code(raw.encode("latin-1"))
        state, moves = _block(c, index, code) if code else (False, [])
        out.append((state or bool(moves), {a for a in AXES if c.pos[a] is not None}))
    return out

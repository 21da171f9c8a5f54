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
Path control and settings move nothing: `G64`, `G641`-`G645` with `ADIS=`, `SOFT`, `FFWON`,
`COMPCAD`, `CYCLE832(...)`, `MSG("...")`, `G4 F..` are lines without motion. A circle with
`TURN=n` makes n full turns from its start, then the circle to its end point, Z going linearly with
the angle over all of them (Fundamentals, helical interpolation). A circle by its radius
`G2/G3 X.. Y.. CR=r` turns about the centre at distance |r| from both ends, on the left of the chord
for G3 and r > 0 (the right for G2), on the other side for a negative r (more than 180 degrees).
`TRANS X.. Y.. Z..` sets the programmable offset (the axes not given 0), `ATRANS` adds to it,
`TRANS` alone (or `ROT`, `SCALE`, `MIRROR` alone) clears it: the positions the program gives from
then on are its own plus the offset (the moves here are in the work offset's frame). A block with
`SUPA`, `G53` or `G153` moves in machine coordinates: a line without motion (kept as written), and
the axes it names unknown afterwards.
Units: G70 and G700 give the lengths in inch (positions, centres, CR=, TRANS, the cycles' levels
and the hole patterns' distances), G71 and G710 in mm, from their own block on; the moves are in mm.
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


#: a Sinumerik program, known from its file header, its path line, or a DEF, a standard cycle call,
#: a message MSG("...") or an arithmetic parameter set (`R1=0`: Fundamentals, "Arithmetic
#: parameters (R)"; no other controller here names a parameter R<n>) at a block's start
_SIEMENS = re.compile(rb'(?im)^\s*%(?:_N_\w+_MPF|MPF)|^\s*;\s*\$PATH=|'
                      rb'^\s*(?:N\d+\s*)?(?:DEF\s+(?:REAL|INT|BOOL)\b|(?:MCALL\s+)?CYCLE\d+\s*\(|'
                      rb'MSG\s*\(\s*"|R\d+\s*=)')


def is_sinumerik(data: bytes) -> bool:
    """Whether a program (its bytes) is a Sinumerik program (see _SIEMENS)."""
    return _SIEMENS.search(data) is not None


def _code(raw: bytes) -> str:
    # a ';' starts the comment, but not inside a string "..." (MSG("A;B"))
    text = re.match(r'(?:[^;"]|"[^"]*")*', raw.decode("latin-1").replace("\r", "")).group(0).upper()
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
        self.shift = {"X": 0.0, "Y": 0.0, "Z": 0.0}     # TRANS / ATRANS, mm
        self.scale = 1.0            # mm per unit of length: G70/G700 inch, G71/G710 mm

    def at(self, axis, text):
        """The position (work offset's frame, mm or deg) of an axis word's value."""
        if axis in "ABC":
            return self.value(text)
        return self.length(text) + self.shift.get(axis, 0.0)

    def length(self, text):
        """A length (mm) the program gives in its units."""
        return self.value(text) * self.scale

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
    frame = re.match(r"(A?TRANS|ROT|SCALE|MIRROR)\b(.*)", code)
    if frame:
        given = {a: c.length(v) for a, v in _AXIS.findall(frame.group(2))}
        for a in "XYZ":         # the tool stays where it is (positions are the work frame's)
            c.shift[a] = given.get(a, 0.0) + (c.shift[a] if frame.group(1) == "ATRANS" else 0.0)
        return False, []
    g = [int(v) for v in _G.findall(code)]
    for v in g:
        if v in (70, 700, 71, 710):
            c.scale = 25.4 if v in (70, 700) else 1.0
    if re.search(r"(?<![A-Z0-9_])SUPA(?![A-Z0-9_])", code) or 53 in g or 153 in g:
        c.pos = dict(c.pos, **{a: None for a, _v in _AXIS.findall(code)})
        return False, []
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
    if call and call.group(1) in ("MSG", "CYCLE832"):
        return False, []
    if call and call.group(1) != "AC":
        return True, _call(c, index, call.group(1), call.group(2).split(","))
    if re.match(r"L\d+", code):
        c.unknown()
        return True, []
    words = {a: v for a, v in _AXIS.findall(code)}
    radius = re.search(r"(?<![A-Z0-9_])CR\s*=\s*(\S+)", code)
    turns = re.search(r"(?<![A-Z0-9_])TURN\s*=\s*(\S+)", code)
    if c.motion in (2, 3) and (radius or "I" in words or "J" in words):
        move = (_radius_arc(c, index, words, c.length(radius.group(1))) if radius
                else _arc(c, index, words))
        return True, _turns(move, int(c.value(turns.group(1)))) if turns else [move]
    target = dict(c.pos)
    for a, v in words.items():
        target[a] = c.at(a, v)
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
    rtp, rfp = (c.at("Z", a) for a in args[:2])
    sdis = c.length(args[2])
    bottom = rfp - c.length(args[4]) if len(args) > 4 and args[4].strip() else c.at("Z", args[3])
    moves = []
    for kind, z in (("rapid", rfp + sdis), ("feed", bottom), ("rapid", rtp)):
        end = dict(c.pos, Z=z)
        moves.append(Move(index, kind, dict(c.pos), end))
        c.pos = end
    return moves


def _call(c, index, name, args):
    if name in ("HOLES1", "HOLES2"):
        x0, y0, p, q, r, num = (c.value(a) for a in args)
        x0, y0 = c.at("X", args[0]), c.at("Y", args[1])
        if name == "HOLES1":        # p: the line's angle, q: to the first hole, r: between holes
            at = [((q + i * r) * c.scale, math.radians(p)) for i in range(int(num))]
        else:                       # p: the radius, q: the first angle, r: the step (0: evenly)
            at = [(p * c.scale, math.radians(q + i * (r if r else 360.0 / num)))
                  for i in range(int(num))]
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
            end[a] = c.at(a, words[a])
    centre = []
    for letter, a, s in (("I", "X", start["X"]), ("J", "Y", start["Y"])):
        v = words[letter]
        m = re.match(r"=\s*AC\((.*)\)$", v)
        centre.append(c.at(a, m.group(1)) if m else s + c.length(v))
    c.pos = end
    return arc_move(index, start, end, centre, c.motion == 3)


def _turns(move, n):
    """A circle with n additional full turns (TURN=n): from its start n full turns, then the
    circle to its end point, the axis off the plane and the radius going linearly with the angle
    over all of them. n + 1 moves: each full turn one (its sweep 2 pi), then the circle's own."""
    cx, cy = move.centre
    r0 = math.hypot(move.start["X"] - cx, move.start["Y"] - cy)
    r1 = math.hypot(move.end["X"] - cx, move.end["Y"] - cy)
    a0 = math.atan2(move.start["Y"] - cy, move.start["X"] - cx)
    total = abs(move.sweep) + 2 * math.pi * n
    out, start = [], move.start
    for k in range(1, n + 1):
        u = 2 * math.pi * k / total
        r = r0 + (r1 - r0) * u
        end = dict(start, X=cx + r * math.cos(a0), Y=cy + r * math.sin(a0))
        if move.start["Z"] is not None and move.end["Z"] is not None:
            end["Z"] = move.start["Z"] + (move.end["Z"] - move.start["Z"]) * u
        out.append(Move(move.line, "arc", start, end, 17, (cx, cy), math.copysign(2 * math.pi,
                                                                                   move.sweep)))
        start = end
    return out + [arc_move(move.line, start, move.end, (cx, cy), move.sweep > 0)]


def _radius_arc(c, index, words, r):
    """A circle G2/G3 to its end point with the radius CR= r: its centre found with complex
    numbers, on the chord's bisector, |r| from both ends."""
    start = dict(c.pos)
    end = dict(start)
    for a in "XYZ":
        if a in words:
            end[a] = c.at(a, words[a])
    s, e = complex(start["X"], start["Y"]), complex(end["X"], end["Y"])
    half = abs(e - s) / 2
    left = 1j * (e - s) / abs(e - s)
    towards = 1 if (c.motion == 3) == (r > 0) else -1
    centre = (s + e) / 2 + towards * left * math.sqrt(max(r * r - half * half, 0.0))
    c.pos = end
    return arc_move(index, start, end, (centre.real, centre.imag), c.motion == 3)


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

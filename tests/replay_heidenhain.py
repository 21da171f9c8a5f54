"""A controller-style replay of a Heidenhain conversational program, written for the tests from
HEIDENHAIN's conversational programming manuals (iTNC 530, TNC 640) and independently of mtcomp's
reader: the program becomes the moves the TNC makes (tests/replay.py's Move and Replay) and the
lines that make none.

Rules: `BEGIN PGM name MM|INCH` units; `L` straight moves (`IX` incremental, `FMAX` rapid, else a
feed move), `M91`/`M92` machine positions (the axes are then unknown in the program's frame);
`CC X Y` the circle centre, `C X Y DR+` counter-clockwise / `DR-` clockwise about it (no coordinates:
the full circle); `CR X Y R.. DR+` the arc of radius |R| (R > 0: at most 180 degrees);
`TOOL CALL` (Z unknown); `CYCL DEF 7` datum shift (positions are given in the
shifted frame: the machine goes to value + shift); `CYCL DEF 1` pecking called by `M99` after the
block's move: down to start - set-up clearance + depth and back to the start. A `CC` line is a
state line (no move; its numbers move with the correction), so it is not among the lines without
motion. `positioned_per_line` gives, per line, whether it may be rewritten and which axes the
program has positioned after it (the corpus test's safety oracle)."""
import math
import re

from replay import AXES, Move, Replay, _align, _runs

_BLOCK = re.compile(r"^\s*\d+\s*(.*)$")
_AXIS = re.compile(r"(?<![A-Z])(I?)([XYZABC])\s*([-+]?\s*(?:\d+\.?\d*|\.\d+))")


def _code(raw: bytes) -> str:
    text = raw.decode("latin-1").replace("\r", " ")
    m = _BLOCK.match(text)
    return "" if m is None else m.group(1).split(";")[0].strip().upper()


class _TNC:
    def __init__(self):
        self.pos = {a: None for a in AXES}      # machine frame less the preset (mm, deg)
        self.shift = {"X": 0.0, "Y": 0.0, "Z": 0.0}
        self.scale = 1.0
        self.cc = None
        self.cycle = {}

    def target(self, code):
        end = dict(self.pos)
        for inc, a, v in _AXIS.findall(code):
            v = float(v.replace(" ", "")) * (self.scale if a in "XYZ" else 1.0)
            if inc:
                end[a] = None if end[a] is None else end[a] + v
            else:
                end[a] = v + self.shift.get(a, 0.0) * self.scale
        return end


def replay(data: bytes) -> Replay:
    """The moves of a conversational program (its bytes) and its lines without motion."""
    tnc = _TNC()
    out = Replay()
    for index, raw in enumerate(data.split(b"\n")):
        code = _code(raw)
        moves = _block(tnc, index, code) if code else []
        if moves:
            out.moves.extend(moves)
        elif not code.startswith("CC"):
            out.still.append((index, raw))
    return out


def _block(tnc, index, code):
    if code.startswith("BEGIN PGM"):
        tnc.scale = 25.4 if code.endswith("INCH") else 1.0
    elif code.startswith("TOOL CALL"):
        tnc.pos = dict(tnc.pos, Z=None)         # a new dict: the last move's end keeps its Z
    elif code.startswith("CYCL DEF 7."):
        for inc, a, v in _AXIS.findall(code[len("CYCL DEF 7.1"):]):
            tnc.shift[a] = float(v.replace(" ", ""))
    elif code.startswith("CYCL DEF 1."):
        m = re.match(r"CYCL DEF 1\.\d\s*([A-Z]+)\s*([-+]?[\d.]+)", code)
        if m:
            tnc.cycle[m.group(1)] = float(m.group(2)) * tnc.scale
    elif code.startswith("CC"):
        end = tnc.target(code[2:])
        tnc.cc = (end["X"], end["Y"])
    elif re.match(r"CR(?![A-Z])", code):
        return [_radius_arc(tnc, index, code[2:])]
    elif re.match(r"C(?![A-Z])", code):
        return [_arc(tnc, index, code[1:])]
    elif re.match(r"L(?![A-Z])", code):
        return _line(tnc, index, code[1:])
    return []


def _line(tnc, index, code):
    if re.search(r"\bM9[12]\b", code):
        tnc.pos = dict(tnc.pos)
        for _inc, a, _v in _AXIS.findall(code):
            tnc.pos[a] = None
        return []
    end = tnc.target(code)
    moves = []
    if end != tnc.pos:
        moves.append(Move(index, "rapid" if "FMAX" in code else "feed", dict(tnc.pos), end))
        tnc.pos = end
    if re.search(r"\bM99\b", code):
        start = dict(tnc.pos)
        bottom = dict(start, Z=start["Z"] - tnc.cycle["DIST"] + tnc.cycle["DEPTH"])
        moves += [Move(index, "feed", start, bottom), Move(index, "rapid", bottom, dict(start))]
    return moves


def _arc(tnc, index, code):
    start = dict(tnc.pos)
    end = tnc.target(code)
    tnc.pos = end
    return arc_move(index, start, end, tnc.cc, "DR+" in code)


def _radius_arc(tnc, index, code):
    """CR X Y R.. DR+/-: the centre on the chord's perpendicular bisector, |R| from both ends, left
    of the chord (seen from the start) for a counter-clockwise arc of at most 180 degrees (R > 0),
    right for a clockwise one, the other side for R < 0 (the larger arc)."""
    start = dict(tnc.pos)
    end = tnc.target(code)
    tnc.pos = end
    r = float(re.search(r"(?<![A-Z])R\s*([-+]?[\d.]+)", code).group(1)) * tnc.scale
    ccw = "DR+" in code
    dx, dy = end["X"] - start["X"], end["Y"] - start["Y"]
    chord = math.hypot(dx, dy)
    h = math.sqrt(max(r * r - 0.25 * chord * chord, 0.0))
    side = 1.0 if ccw == (r > 0) else -1.0
    centre = (start["X"] + 0.5 * dx - side * h * dy / chord,
              start["Y"] + 0.5 * dy + side * h * dx / chord)
    return arc_move(index, start, end, centre, ccw)


def arc_move(index, start, end, centre, ccw):
    """The move of an arc in G17 about centre (x, y) from start to end (the same: the full
    circle), counter-clockwise or not."""
    cx, cy = centre
    a0 = math.atan2(start["Y"] - cy, start["X"] - cx)
    a1 = math.atan2(end["Y"] - cy, end["X"] - cx)
    full = math.hypot(end["X"] - start["X"], end["Y"] - start["Y"]) < 1e-9
    sweep = 2 * math.pi if full else ((a1 - a0) % (2 * math.pi) if ccw else (a0 - a1) % (2 * math.pi))
    return Move(index, "arc", start, end, 17, (cx, cy), sweep if ccw else -sweep)


def compare(src: bytes, out: bytes, tol, name: str = ""):
    """As replay.compare, for conversational programs: lines without motion byte for byte and in
    order, the motion between them the same up to the correction."""
    a, b = replay(src), replay(out)
    if [r for _, r in a.still] != [r for _, r in b.still]:
        bad = next(i for i, (x, y) in enumerate(zip(a.still, b.still)) if x[1] != y[1]) \
            if len(a.still) == len(b.still) else -1
        raise AssertionError(f"{name}: the lines without motion differ (at {bad})")
    for src_run, dst_run in zip(_runs(a), _runs(b)):
        _align(src_run, dst_run, tol, name)
    return a.moves, b.moves


def positioned_per_line(text: str):
    """Per line: (may be rewritten: a move or a CC line, axes positioned after it)."""
    known: set = set()
    out = []
    for raw in text.split("\n"):
        code = _code(raw.encode("latin-1"))
        axes = {a for _i, a, _v in _AXIS.findall(code)}
        moved = False
        if code.startswith("TOOL CALL"):
            known.discard("Z")
        elif re.match(r"L(?![A-Z])", code) and re.search(r"\bM9[12]\b", code):
            known -= axes
        elif re.match(r"L(?![A-Z])", code):
            known |= axes
            moved = bool(axes) or "M99" in code
        elif re.match(r"C[CR]?(?![A-Z])", code):
            moved = True
        out.append((moved, set(known)))
    return out

"""A controller-style replay of an NC program, written for the tests from the RS-274 rules and
independently of mtcomp's reader: a program becomes the moves a controller makes and the lines
that make none. Then `compare` checks that a compensated program moves like its source up to the
correction.

Replay: modal G0/G1/G2/G3 (I J K or R), G90/G91, G20/G21 (everything in mm and degrees), G17/G18/
G19, G90.1/G91.1 (absolute or incremental arc centres), G33.1 rigid tapping (to the point and
back), drilling cycles G73 and G81-G89 expanded into their moves (to X Y at the current level, to
the R plane, to the bottom, back to R with G99 or to the higher of R and the initial level with
G98; along Z in G17, Y in G18, X in G19; R and Z kept as the numbers written and read in each
block's distance mode, under G91 R from the series' initial level and Z from R; L repeats), G28/G30 and G53 moves
leave the axes they move (G28/G30 without axis words: every axis) at an unknown position, so do a
tool change or tool length change (Z) and a change of work coordinate system (every axis); G92
declares the named axes' positions by an offset of every work system (the old position less the
value where the position is known, 0 where it is not: the same unknown in a program and its
compensated version), G92.1/G92.2 set the offsets to 0 (the positions then read the work
system's), and the moves are given in the work system (program position plus that offset); G10
L2/L20 set a work system's origin (the active system's position moves by the
change where the old origin is known, else becomes unknown; after L20 the named axes read the
given values, and where their position was unknown, as after grbl's homing `$H`, the new origin
is the operator's, from outside the program); G4 dwells and moves too when the block has axis
words; a full circle of zero radius about its start (I J K 0, the end at the start) is a move of
kind 'none': grbl runs it without motion. Comments `( )` and `;` (a comment holding parentheses:
see `without_comments`), `%`, `:` program numbers, `$`
lines (`$H` homing and `$J=` jogging leave every axis unknown) and a DOS end-of-file mark make no
move. A RepRapFirmware program (see `is_rrf`) is read without its quoted strings, and a block that
runs the controller's macro files (see `rrf_runs_macro`) leaves every axis unknown. On BeagleG (see
`is_beagleg`) a line is read word by word, as BeagleG's parser does (`beagleg_commands`: `X5 G91`
moves to X5 before G91 applies), G70/G71 are G20/G21, and G2/G3 hold for their own block only: axis
words alone move in the last G0/G1 mode, G0 at the start (BeagleG's
src/gcode-parser/gcode-parser.cc, ParseBlock), and G30 probes Z (handle_z_probe: Z unknown after
it, its own Z word the probe's thickness). uCNC's G39 probes a height map and leaves Z unknown, X Y
where it names them (motion_control.c, mc_build_hmap). A G5 cubic spline (X Y
its end; the first control point the start plus I J, or without I J minus the previous G5's P Q;
the second the end plus P Q) and a G5.1 quadratic one (its control point the start plus I J) are
moves along their Bezier curve (LinuxCNC G-code reference, G5 and G5.1); after one no motion mode
is in force (BeagleG: the last G0/G1). A G5 without coordinates (Fanuc's G05 P10000 contour control
mode) moves nothing.
W, the quill of a horizontal boring mill (ISO 841's secondary axis parallel to Z), is an axis of
the replay like X Y Z: mtcomp never corrects it, so its positions in the output must be the
source's exactly.

A position is a dict axis -> value (mm or deg) or None where the controller's position in the
program's frame is unknown."""
import math
import re
from dataclasses import dataclass, field

AXES = "XYZABCW"
LINEAR = "XYZ"
#: the axes of lengths (scaled by G20): X Y Z and the quill W, a secondary axis parallel to Z
#: (ISO 841) that mtcomp never corrects: its positions must be the source's exactly
LENGTHS = "XYZW"
#: a comment as a control that ends it at its first ')' reads it ('(' inside is its text)
_COMMENT = re.compile(r"\([^)]*\)|;.*")
#: a comment that holds no parenthesis: the innermost of nested ones
_INNERMOST = re.compile(r"\([^()]*\)")
_WORD = re.compile(r"([A-Z])\s*([-+]?\s*(?:\d+\.?\d*|\.\d+))")
#: drilling cycles; G74 (left-hand tapping) and G76 (fine boring) are Fanuc's and Haas' (mtcomp
#: refuses them on other controllers, so no other program reaches this replay with them)
_CYCLES = {73, 74, 76, 81, 82, 83, 84, 85, 86, 87, 88, 89}
#: the axis a drilling cycle drills along in each plane (LinuxCNC's interp_cycles.cc: aa, bb the
#: plane's axes, cc the one drilled along: Z in convert_cycle_xy, Y in _zx, X in _yz)
_DRILL = {17: "Z", 18: "Y", 19: "X"}
#: RepRapFirmware (Duet3D, G-code dictionary): a parameter's value may be a string in double quotes
#: ("" inside is one quote character; ; and ( inside belong to it); a program for it is known by
#: such a string outside comments or by a comment naming the firmware or MillenniumOS
RRF_STRING = re.compile(r'[A-Za-z]?"(?:[^"]|"")*"')
_RRF_CLUE = re.compile(rb'(?im)^[^(;\n]*"|reprapfirmware|\brrf\b|millenniumos')
#: BeagleG: a parameter named without brackets (`#r=50`, `#i++`), or the controller named (the
#: first line of a program mtcomp expanded for it says "for beagleg")
_BEAGLEG_CLUE = re.compile(rb"(?im)^[ \t]*#[ \t]*[a-z_]\w*[ \t]*(?:=|\+\+|--|[-+*/]=)|\bbeagleg\b")
#: the G codes RepRapFirmware carries out itself; any other runs the controller's macro file
#: /sys/G<n>.g, and G29, G30, G32 probe: the moves are not in the program
_RRF_OWN_G = {0, 1, 2, 3, 4, 10, 11, 17, 18, 19, 20, 21, 28, 31, 53, 54, 55, 56, 57, 58, 59, 60,
              68, 69, 90, 91, 92, 93, 94}
#: plane -> (first, second, normal axis) of a right-handed frame, and the centre offset letters
_PLANES = {17: ("X", "Y", "Z", "I", "J"), 18: ("Z", "X", "Y", "K", "I"),
           19: ("Y", "Z", "X", "J", "K")}


@dataclass
class Move:
    """One move of the controller: `line` (0-based source line), `kind` ('rapid', 'feed', 'arc',
    'home', or 'none': a block that names a position and does not move), `start` and `end`
    positions (mm, deg; None = unknown), and for an arc its plane,
    centre (first, second; mm) and signed sweep (rad, counter-clockwise positive)."""
    line: int
    kind: str
    start: dict
    end: dict
    plane: int = 17
    centre: tuple = None
    sweep: float = 0.0
    controls: tuple = None      # a spline's four Bezier points (x, y), start to end


@dataclass
class Replay:
    """The moves of a program and its lines without motion (index, bytes as written)."""
    moves: list = field(default_factory=list)
    still: list = field(default_factory=list)


@dataclass
class _State:
    pos: dict = field(default_factory=lambda: {a: None for a in AXES})
    scale: float = 1.0          # mm per program unit (linear axes)
    absolute: bool = True
    plane: int = 17
    motion: int = None          # 0, 1, 2, 3 or a cycle number
    before_cycle: int = None    # the group-01 motion in force when a cycle started
    retract: int = 98
    init_z: float = None
    cycle_r: float = None
    cycle_z: float = None
    wcs: str = "G54"
    arc_absolute: bool = False   # G90.1: I J K are the centre's position
    offsets: dict = field(default_factory=dict)   # (wcs, axis) -> offset set by G10 L2/L20
    g92: dict = field(default_factory=lambda: {a: 0.0 for a in LENGTHS})  # G92 offsets, mm
    rrf: bool = False            # a RepRapFirmware program: its strings and macro codes
    beagleg: bool = False        # a BeagleG program: G2/G3 not modal
    linear: int = 0              # BeagleG: the G0/G1 mode axis words alone move in
    last_pq: tuple = (0.0, 0.0)  # the last G5's P Q (mm)


def _words(code):
    return [(m.group(1), float(m.group(2).replace(" ", ""))) for m in _WORD.finditer(code)]


def without_comments(text: str) -> str:
    """A line without its comments. A comment that holds parentheses (`(Drill, 3mm (R))`) has two
    readings: a control that nests them takes it whole (innermost comments removed until none is
    left), one that ends it at its first ')' reads what follows as code (lone ')' skipped). Where
    the two give different words the program is not one to compensate: ValueError."""
    first_close = _COMMENT.sub("", text)
    if not re.search(r"\([^()]*\(", text):      # no '(' inside a comment: one reading
        return first_close
    nested = text.split(";", 1)[0] if text.find(";") < text.find("(") else text
    while True:
        fewer = _INNERMOST.sub("", nested)
        if fewer == nested:
            break
        nested = fewer
    nested = re.sub(";.*", "", nested)
    rest = first_close.replace(")", "")
    if re.sub(r"[ \t]", "", rest.upper()) != re.sub(r"[ \t]", "", nested.upper()):
        raise ValueError(f"the readings of a comment holding parentheses differ: {text!r}")
    return rest


def _code(raw: bytes, rrf: bool = False) -> str:
    text = raw.decode("latin-1").replace("\r", "").replace("\x1a", "")
    if rrf:
        text = RRF_STRING.sub(" ", text)
    return without_comments(text).upper().strip()


def is_rrf(data: bytes) -> bool:
    """Whether a program is one for RepRapFirmware (see RRF_STRING)."""
    return _RRF_CLUE.search(data) is not None


def rrf_runs_macro(words) -> bool:
    """Whether a RepRapFirmware block runs moves the program does not hold: a G code the firmware
    does not carry out itself (a macro file) or one that probes; of the M codes, at least those
    with a decimal part (M3.9: a macro file), M6 to M9 and M1000 up (macro files: the firmware has
    none of them), M98 (a named macro); a T word (the tool change macros tfree, tpre, tpost)."""
    for c, v in words:
        if c == "T":
            return True
        if c == "G" and (int(v) not in _RRF_OWN_G or (v != int(v) and int(v) not in (38, 59))):
            return True
        if c == "M" and (v != int(v) or 6 <= v <= 9 or v >= 1000 or v == 98):
            return True
    return False


def is_beagleg(data: bytes) -> bool:
    """Whether a program is one for BeagleG (see _BEAGLEG_CLUE)."""
    return _BEAGLEG_CLUE.search(data) is not None


def beagleg_commands(words):
    """A line's words as BeagleG runs them, in turn (its src/gcode-parser/gcode-parser.cc,
    ParseBlock and handle_move): each G word with the words it reads after it (axis words, F S I J
    K R P Q L), and each run of those without a G word before it, as a move of its own, ended by
    any other word (an M, N, T word: on a line of its own here). Each part is a block."""
    parts, reading = [], False
    for c, v in words:
        arg = c in AXES + "UVE" + "FSIJKRPQL"
        if c == "G" or not (reading and arg):
            parts.append([])
        parts[-1].append((c, v))
        reading = c == "G" or arg
    return parts


def replay(data: bytes, units_mm: bool = True, placed: bool = False,
           beagleg: bool | None = None) -> Replay:
    """The moves and motionless lines of a program (its bytes); `units_mm`: what a program
    without G20/G21 is in. `placed`: the positions on the machine, plus the work offset the program
    set for the system in force (G10 L2/L20; None where that offset is not the program's).
    `beagleg`: BeagleG's rules (None: known from the program, `is_beagleg`)."""
    st = _State(scale=1.0 if units_mm else 25.4, rrf=is_rrf(data),
                beagleg=is_beagleg(data) if beagleg is None else beagleg)
    out = Replay()
    for index, raw in enumerate(data.split(b"\n")):
        code = _code(raw, st.rrf)
        if code[:2] in ("$H", "$J"):
            # grbl homing ($H) or jogging ($J=): the machine moves where the program does not say
            st.pos = {a: None for a in AXES}
        words = [] if (not code or code[0] in "%:$") else _words(code)
        moves = [m for part in (beagleg_commands(words) if st.beagleg else [words])
                 for m in (_block(st, index, part) if part else [])]
        if moves:
            out.moves.extend(_in_work_system(m, _offsets(st, placed)) for m in moves)
        else:
            out.still.append((index, raw))
    return out


def _offsets(st, placed):
    """axis -> what a program position is shifted by: the G92 offset, and with `placed` the work
    offset the program set for the system in force (None where it did not)."""
    out = {a: st.g92.get(a, 0.0) for a in AXES}
    if placed:
        for a in AXES:
            off = st.offsets.get((st.wcs, a))
            out[a] = None if off is None else out[a] + off
    return out


def _in_work_system(move, shift):
    """A move with its positions (and arc centre, spline control points) shifted by `shift` (axis ->
    mm or deg, None: the position is not known)."""
    def placed(pos):
        return {a: None if v is None or shift[a] is None else v + shift[a] for a, v in pos.items()}
    centre = move.centre
    if centre is not None:
        first, second = _PLANES[move.plane][:2]
        centre = None if shift[first] is None or shift[second] is None else (
            centre[0] + shift[first], centre[1] + shift[second])
    controls = move.controls
    if controls is not None:
        controls = None if shift["X"] is None or shift["Y"] is None else tuple(
            (x + shift["X"], y + shift["Y"]) for x, y in controls)
    return Move(move.line, move.kind, placed(move.start), placed(move.end), move.plane, centre,
                move.sweep, controls)


def _value(st, letter, v):
    return v * st.scale if letter in LENGTHS else v


def _target(st, words):
    """The end position of the axis words (absolute or incremental), None where unknown."""
    end = dict(st.pos)
    for letter, v in words:
        if letter in AXES:
            v = _value(st, letter, v)
            if st.absolute:
                end[letter] = v
            else:
                end[letter] = None if st.pos[letter] is None else st.pos[letter] + v
    return end


def _modal(st, gs, words):
    """Apply the modal words of a block; True when the block changes the tool length (Z)."""
    for g in gs:
        if g in (20, 21) or (st.beagleg and g in (70, 71)):     # BeagleG: G70/G71 inch/mm
            st.scale = 25.4 if g in (20, 70) else 1.0
        elif g in (90, 91):
            st.absolute = g == 90
        elif g in (90.1, 91.1):
            st.arc_absolute = g == 90.1
        elif g in (17, 18, 19):
            st.plane = int(g)
        elif g in (98, 99):
            st.retract = int(g)
        elif g in (54, 55, 56, 57, 58, 59) and f"G{g:g}" != st.wcs:
            st.wcs = f"G{g:g}"
            st.pos = {a: None for a in AXES}
    tool = any(c == "M" and v == 6 for c, v in words) or any(g in (43, 49) for g in gs)
    if tool:
        st.pos["Z"] = None
    return tool


def _block(st, index, words):
    """The moves of one block, the machine state updated."""
    gs = [v for c, v in words if c == "G"]
    if st.rrf and rrf_runs_macro(words):
        # the controller's macro (its words are the macro's parameters): every axis unknown
        st.pos = {a: None for a in AXES}
        return []
    _modal(st, gs, words)
    axes = [c for c, _ in words if c in AXES]
    if st.beagleg and st.motion in (2, 3):
        st.motion = st.linear            # BeagleG: an arc holds for its own block only
    _motion_mode(st, gs)
    if 39 in gs:
        # uCNC's height map (motion_control.c, mc_build_hmap): it probes a grid from the X Y it
        # names, then stands at the first point at the height probed there; G39 stays in force
        end = _target(st, [(c, v) for c, v in words if c in "XY"])
        end["Z"] = None
        st.motion = None
        return _go(st, Move(index, "home", dict(st.pos), end))
    if any(g in (28, 30) for g in gs):
        end = dict(st.pos)
        # BeagleG's G30 probes Z (gcode-parser.cc, handle_z_probe: its Z word is the thickness)
        for a in ("Z" if st.beagleg and 30 in gs else axes or AXES):
            end[a] = None
        return _go(st, Move(index, "home", dict(st.pos), end))
    if 53 in gs:
        end = dict(st.pos)
        for a in axes:
            end[a] = None
        return _go(st, Move(index, "home", dict(st.pos), end)) if axes else []
    if 92 in gs:
        for letter, v in words:
            if letter in AXES:
                v = _value(st, letter, v)
                old = st.pos[letter]
                st.g92[letter] = 0.0 if old is None else st.g92[letter] + old - v
                st.pos[letter] = v
        return []
    if 92.1 in gs or 92.2 in gs:
        for a in LENGTHS:
            if st.pos[a] is not None:
                st.pos[a] += st.g92[a]
            st.g92[a] = 0.0
        return []
    if 10 in gs:            # G10 L..: the axis words are data, not a move (G4 is a dwell only)
        _g10(st, words)
        return []
    if st.motion == 33.1:       # rigid tapping: to the point and back to where it started
        if not axes:
            return []
        there = _target(st, words)
        return [Move(index, "feed", dict(st.pos), there), Move(index, "feed", there, dict(st.pos))]
    if (5 in gs or 5.1 in gs) and any(c in AXES + "IJKR" for c, _ in words):
        return _go(st, _spline(st, index, words, 5 in gs))
    if st.motion in _CYCLES:
        return _cycle(st, index, words) if (axes or "L" in dict(words)) else []
    arc_words = any(c in "IJKR" for c, _ in words)
    if st.motion in (2, 3) and (axes or arc_words):
        return _go(st, _arc(st, index, words))
    if axes and st.motion in (0, 1):
        kind = "rapid" if st.motion == 0 else "feed"
        return _go(st, Move(index, kind, dict(st.pos), _target(st, words)))
    return []


def _g10(st, words):
    """G10 L2 / L20 P: set the origin of a work system (P0: the active one). The active system's
    position changes with it: by the change where the old offset is known, to the given value
    under L20, unknown otherwise. L20 sets the origin so that the current position reads the value
    (LinuxCNC G-code reference, G10 L20; grbl 1.1 gcode.c: WCS = MPos - G92 - TLO - WPos): the
    machine position (the position plus G92's offset plus the active system's origin) less G92's
    offset less the value, in system P whichever is active. An L20 where the position is unknown
    (after homing) sets an origin from outside the program (None), as the operator's touch-off at
    the panel would."""
    value = dict(words)
    p = int(value.get("P", -1))
    wcs = st.wcs if p == 0 else f"G{53 + p}" if 1 <= p <= 6 else f"P{p}"
    for letter, v in words:
        if letter not in AXES:
            continue
        v = _value(st, letter, v)
        old = st.offsets.get((wcs, letter))
        pos = st.pos[letter]
        if value.get("L") == 20:
            active = st.offsets.get((st.wcs, letter))
            new = None if active is None or pos is None else pos + active - v
            if wcs == st.wcs:
                st.pos[letter] = v
        else:
            new = v
            if wcs == st.wcs:
                st.pos[letter] = None if old is None or pos is None else pos + old - new
        st.offsets[(wcs, letter)] = new


def _motion_mode(st, gs):
    for g in gs:
        if g in (0, 1, 2, 3):
            st.motion = int(g)
            st.linear = int(g) if g in (0, 1) else st.linear
        elif g == 33.1:
            st.motion = g
        elif g in _CYCLES:
            if st.motion not in _CYCLES:
                st.before_cycle, st.init_z = st.motion, st.pos[_DRILL[st.plane]]
            st.motion = int(g)
        elif g == 80:
            # Fanuc and Haas keep the motion in force before the cycle; LinuxCNC refuses axis words
            st.motion = st.before_cycle if st.motion in _CYCLES else st.motion


def _spline(st, index, words, cubic):
    """A G5 or G5.1 block's move (see the module's docstring)."""
    value = {c: v * st.scale for c, v in words if c in "IJPQ"}
    start, end = dict(st.pos), _target(st, words)
    st.motion = st.linear if st.beagleg else None
    if None in (start["X"], start["Y"], end["X"], end["Y"]):
        return Move(index, "spline", start, end)
    p0, p3 = (start["X"], start["Y"]), (end["X"], end["Y"])
    if cubic:
        d1 = (value["I"], value["J"]) if "I" in value else (-st.last_pq[0], -st.last_pq[1])
        st.last_pq = (value["P"], value["Q"])
        p1 = (p0[0] + d1[0], p0[1] + d1[1])
        p2 = (p3[0] + value["P"], p3[1] + value["Q"])
    else:
        q = (p0[0] + value.get("I", 0.0), p0[1] + value.get("J", 0.0))
        p1 = tuple(a + 2 / 3 * (b - a) for a, b in zip(p0, q))
        p2 = tuple(a + 2 / 3 * (b - a) for a, b in zip(p3, q))
    return Move(index, "spline", start, end, controls=(p0, p1, p2, p3))


def _bezier(controls, t):
    """The point (x, y) of a cubic Bezier curve at t."""
    w = ((1 - t) ** 3, 3 * t * (1 - t) ** 2, 3 * t * t * (1 - t), t ** 3)
    return tuple(sum(wi * c[k] for wi, c in zip(w, controls)) for k in (0, 1))


def _go(st, move):
    st.pos = dict(move.end)
    return [move]


def _arc(st, index, words):
    first, second, _normal, off1, off2 = _PLANES[st.plane]
    end = _target(st, words)
    value = dict(words)
    start = st.pos
    known = all(p[a] is not None for p in (start, end) for a in (first, second))
    if known and "R" not in value and end == start and not st.arc_absolute \
            and value.get(off1, 0.0) == 0.0 and value.get(off2, 0.0) == 0.0:
        # a full circle of zero radius about its own start: grbl runs it without moving (its
        # planner drops zero-length pieces); a move of kind 'none', so its words still compare
        return Move(index, "none", dict(start), end, plane=st.plane)
    move = Move(index, "arc", dict(start), end, plane=st.plane)
    if not known:
        return move
    x0, y0, x1, y1 = start[first], start[second], end[first], end[second]
    ccw = st.motion == 3
    if "R" in value:
        r = value["R"] * st.scale
        d = math.hypot(x1 - x0, y1 - y0)
        h = math.sqrt(max(r * r - d * d / 4.0, 0.0))
        # the centre on the left of the chord for a short CCW arc (R > 0), on the right for CW
        side = (1.0 if ccw else -1.0) * (1.0 if r > 0 else -1.0)
        mx, my = (x0 + x1) / 2.0, (y0 + y1) / 2.0
        cx, cy = mx - side * h * (y1 - y0) / d, my + side * h * (x1 - x0) / d
    else:
        base = (0.0, 0.0) if st.arc_absolute else (x0, y0)
        cx = base[0] + value.get(off1, 0.0) * st.scale
        cy = base[1] + value.get(off2, 0.0) * st.scale
    a0 = math.atan2(y0 - cy, x0 - cx)
    a1 = math.atan2(y1 - cy, x1 - cx)
    sweep = (a1 - a0) % (2 * math.pi) if ccw else -((a0 - a1) % (2 * math.pi))
    if abs(sweep) < 1e-12:
        sweep = 2 * math.pi if ccw else -2 * math.pi     # a full circle
    move.centre, move.sweep = (cx, cy), sweep
    return move


def _cycle(st, index, words):
    """The moves of one drilling cycle block: per hole to X Y, to R, to the bottom, and back.

    R and Z are kept as the numbers last written and read in the distance mode of the block
    (LinuxCNC's interp_cycles.cc, convert_cycle_xy: `block->z_number = block->z_flag ?
    block->z_number : settings->cycle_cc`, R likewise from `settings->cycle_r` in convert_cycle):
    in G90 they are the levels; in G91 R is measured from the series' initial level (`cycle_il`,
    the Z where the cycles began) and Z from R (`r = block->r_number + old_cc; cc = r +
    block->z_number`). mtcomp refuses a G91 series continued under G99 where other controllers
    differ, and R or Z given in the other distance mode on them."""
    value = dict(words)
    drill = _DRILL[st.plane]          # its word is the depth (Z in G17, Y in G18, X in G19)
    if "R" in value:
        st.cycle_r = value["R"] * st.scale
    if drill in value:
        st.cycle_z = value[drill] * st.scale
    if st.absolute:
        r, bottom = st.cycle_r, st.cycle_z
    else:
        r = None if st.init_z is None or st.cycle_r is None else st.init_z + st.cycle_r
        bottom = None if r is None or st.cycle_z is None else r + st.cycle_z
    moves = []
    xy = [(c, v) for c, v in words if c in AXES and c != drill]
    for _ in range(max(int(value.get("L", 1)), 1)):
        moves += _hole(st, index, xy, r, bottom, drill)
    return moves


def _hole(st, index, xy, r, bottom, drill):
    """One hole: to its place in the plane, along the axis ``drill`` to R, to the bottom, back."""
    moves = []
    if st.pos[drill] is not None and r is not None and st.pos[drill] < r:
        moves += _go(st, Move(index, "rapid", dict(st.pos), {**st.pos, drill: r}))
    if xy:
        moves += _go(st, Move(index, "rapid", dict(st.pos), _target(st, xy)))
    moves += _go(st, Move(index, "rapid", dict(st.pos), {**st.pos, drill: r}))
    moves += _go(st, Move(index, "feed", dict(st.pos), {**st.pos, drill: bottom}))
    if st.retract == 99 or r is None:
        up = r
    else:
        up = None if st.init_z is None else max(st.init_z, r)
    moves += _go(st, Move(index, "rapid", dict(st.pos), {**st.pos, drill: up}))
    return moves


# ---------------------------------------------------------------------------------------------
# comparison of a program and its compensated version

@dataclass
class Tolerance:
    """What the output may differ by: `axis_mm` per linear axis and `axis_deg` per rotary axis at
    a corresponding end point (the correction bound plus rounding), `path_mm` for a piece of a
    split block off the source block's path (chord tolerance plus the correction)."""
    axis_mm: float
    axis_deg: float
    path_mm: float


def _known_same(a: dict, b: dict):
    return all((a[x] is None) == (b[x] is None) for x in AXES)


def _near_end(piece: Move, move: Move, tol: Tolerance):
    if not _known_same(piece.end, move.end):
        return False
    for x in AXES:
        if move.end[x] is not None:
            limit = 1e-9 if x == "W" else tol.axis_mm if x in LINEAR else tol.axis_deg
            if abs(piece.end[x] - move.end[x]) > limit:
                return False
    return True


def _point_to_segment(p, a, b):
    d = [bi - ai for ai, bi in zip(a, b)]
    dd = sum(v * v for v in d)
    along = sum((pi - ai) * v for pi, ai, v in zip(p, a, d))
    t = 0.0 if dd == 0 else max(0.0, min(1.0, along / dd))
    return math.dist(p, [ai + t * v for ai, v in zip(a, d)])


def _point_to_arc(p: dict, move: Move):
    """Distance (mm) of a point to an arc's helix, over the linear axes."""
    first, second, normal = _PLANES[move.plane][:3]
    cx, cy = move.centre
    r = math.hypot(move.start[first] - cx, move.start[second] - cy)
    r_end = math.hypot(move.end[first] - cx, move.end[second] - cy)
    angle = math.atan2(p[second] - cy, p[first] - cx)
    a0 = math.atan2(move.start[second] - cy, move.start[first] - cx)
    turn = (angle - a0) % (2 * math.pi) if move.sweep > 0 else -((a0 - angle) % (2 * math.pi))
    frac = turn / move.sweep if move.sweep else 0.0
    if not 0.0 <= frac <= 1.0:
        return min(_dist(p, m) for m in (move.start, move.end))
    radial = math.hypot(p[first] - cx, p[second] - cy) - (r + frac * (r_end - r))
    w0, w1 = move.start[normal], move.end[normal]
    axial = 0.0 if None in (w0, w1, p[normal]) else p[normal] - (w0 + frac * (w1 - w0))
    same_angle = math.hypot(radial, axial)
    # on a helix the distance at the point's own angle is only an upper bound: on a steep one a
    # small step along the arc is a large one in the normal axis. Where it may be off by more than
    # 1 um (the helix rises more than a tenth of its arc's length), the nearest point of the helix
    if same_angle <= 1e-3 or abs(axial) <= 0.1 * abs(radial) \
            or abs(w1 - w0) <= 0.1 * max(r, r_end) * abs(move.sweep):
        return same_angle
    return min(same_angle, _nearest_on_helix(p, move, r, r_end, a0))


def _nearest_on_helix(p: dict, move: Move, r: float, r_end: float, a0: float) -> float:
    """The distance of a point to the nearest point of an arc's helix (over the plane's axes and
    its normal): the helix sampled at 33 fractions, then a golden-section search next to the
    nearest sample."""
    first, second, normal = _PLANES[move.plane][:3]
    cx, cy = move.centre
    w0, w1 = move.start[normal], move.end[normal]

    def dist(t):
        rt, at = r + t * (r_end - r), a0 + t * move.sweep
        return math.hypot(p[first] - cx - rt * math.cos(at), p[second] - cy - rt * math.sin(at),
                          p[normal] - w0 - t * (w1 - w0))

    n = 32
    k = min(range(n + 1), key=lambda i: dist(i / n))
    lo, hi = max(0.0, (k - 1) / n), min(1.0, (k + 1) / n)
    g = (math.sqrt(5) - 1) / 2
    for _ in range(40):
        a, b = hi - g * (hi - lo), lo + g * (hi - lo)
        if dist(a) < dist(b):
            hi = b
        else:
            lo = a
    return min(dist(k / n), dist((lo + hi) / 2))


def _dist(p: dict, q: dict):
    """Distance (mm) over the linear axes known in both."""
    return math.dist(*zip(*[(p[x], q[x]) for x in LINEAR if None not in (p[x], q[x])] or [(0, 0)]))


def _off_path(point: dict, move: Move):
    """Distance (mm) of a point to a source move's path, over the linear axes known on both."""
    axes = [x for x in LINEAR if None not in (move.start[x], move.end[x], point[x])]
    first, second = _PLANES[move.plane][:2]
    if move.kind == "arc" and move.centre is not None and None not in (point[first],
                                                                       point[second]):
        return _point_to_arc(point, move)
    if move.controls is not None and None not in (point["X"], point["Y"]):
        poly = [_bezier(move.controls, k / 64) for k in range(65)]
        return min(_point_to_segment((point["X"], point["Y"]), a, b)
                   for a, b in zip(poly, poly[1:]))
    return _point_to_segment([point[x] for x in axes], [move.start[x] for x in axes],
                             [move.end[x] for x in axes])


def _midpoint(piece: Move):
    if piece.controls is not None:
        mid = {x: None if piece.start[x] is None or piece.end[x] is None
               else (piece.start[x] + piece.end[x]) / 2 for x in AXES}
        mid["X"], mid["Y"] = _bezier(piece.controls, 0.5)
        return mid
    if piece.kind == "arc" and piece.centre is not None:
        first, second, normal = _PLANES[piece.plane][:3]
        cx, cy = piece.centre
        a0 = math.atan2(piece.start[second] - cy, piece.start[first] - cx) + piece.sweep / 2
        r0 = math.hypot(piece.start[first] - cx, piece.start[second] - cy)
        r1 = math.hypot(piece.end[first] - cx, piece.end[second] - cy)
        mid = {x: None if piece.start[x] is None or piece.end[x] is None
               else (piece.start[x] + piece.end[x]) / 2 for x in AXES}
        mid[first] = cx + (r0 + r1) / 2 * math.cos(a0)
        mid[second] = cy + (r0 + r1) / 2 * math.sin(a0)
        return mid
    return {x: None if piece.start[x] is None or piece.end[x] is None
            else (piece.start[x] + piece.end[x]) / 2 for x in AXES}


def _on_path(piece: Move, move: Move, tol: Tolerance):
    """A piece of the output lies along a source move: its end and its middle."""
    if not _known_same(piece.end, move.end) and not _known_same(piece.end, move.start):
        return False
    return all(_off_path(p, move) <= tol.path_mm for p in (piece.end, _midpoint(piece)))


def _align(src: list, dst: list, tol: Tolerance, where: str):
    """Each source move matched by one or more consecutive output moves, the last ending at the
    source move's end up to the correction, the others along its path (a split block)."""
    reach = {0}
    for move in src:
        nxt = set()
        for j in sorted(reach):
            for k in range(j, len(dst)):
                if _near_end(dst[k], move, tol) and _off_path(_midpoint(dst[k]), move) \
                        <= tol.path_mm:
                    nxt.add(k + 1)
                if not _on_path(dst[k], move, tol):
                    break
        if not nxt:
            j = min(reach)
            got = f"output line {dst[j].line + 1}" if j < len(dst) else "no output move"
            raise AssertionError(f"{where}: source line {move.line + 1} ({move.kind} to "
                                 f"{_show(move.end)}) has no matching output motion; {got}: "
                                 f"{_show(dst[j].end) if j < len(dst) else ''}")
        reach = nxt
    if len(dst) not in reach:
        extra = dst[max(reach)] if max(reach) < len(dst) else dst[-1]
        raise AssertionError(f"{where}: output line {extra.line + 1} moves where the source "
                             f"does not ({_show(extra.end)})")


def _show(pos):
    return " ".join(f"{a}{'?' if v is None else f'{v:.4f}'}" for a, v in pos.items()
                    if v is not None or a in LINEAR)


def compare(src: bytes, out: bytes, tol: Tolerance, units_mm: bool = True, name: str = "",
            beagleg: bool | None = None):
    """Raise AssertionError unless `out` moves like `src` up to the correction and keeps every
    line without motion byte for byte and in order. Returns (source moves, output moves).
    `beagleg`: both replayed with BeagleG's rules (None: as each program shows, `is_beagleg`)."""
    a, b = replay(src, units_mm, beagleg=beagleg), replay(out, units_mm, beagleg=beagleg)
    a_still = [raw for _, raw in a.still]
    b_still = [raw for _, raw in b.still]
    for i, (x, y) in enumerate(zip(a_still, b_still)):
        if x != y:
            raise AssertionError(f"{name}: line without motion {a.still[i][0] + 1} is "
                                 f"{x[:60]!r} in the source, output line {b.still[i][0] + 1} "
                                 f"is {y[:60]!r}")
    if len(a_still) != len(b_still):
        raise AssertionError(f"{name}: {len(a_still)} lines without motion in the source, "
                             f"{len(b_still)} in the output")
    # motion between the same two motionless lines corresponds
    for run, (src_run, dst_run) in enumerate(zip(_runs(a), _runs(b))):
        _align(src_run, dst_run, tol, name)
    return a.moves, b.moves


def _runs(rep: Replay):
    """The moves grouped by the motionless lines between them."""
    runs = [[] for _ in range(len(rep.still) + 1)]
    stills = [i for i, _ in rep.still]
    k = 0
    for move in rep.moves:
        while k < len(stills) and stills[k] < move.line:
            k += 1
        runs[k].append(move)
    return runs

"""The drilling cycle rules of the reader's modal state that depend on the controller: whether a
cycle line is clear enough to be kept as a corrected cycle, where the tool is left after it, where
an incremental cycle's R plane lies, a cycle line passed through (docs/toolpaths.md, "Drilling
cycles"), and a G33.1 rigid tapping line. Functions of a :class:`~.modal.ModalState` (``state``), kept apart from it for size."""
from __future__ import annotations

import math

import numpy as np

from .directions import step_directions
from .words import MM_PER_INCH, TOOL_AXIS


def cycle_unclear(state, inc: bool) -> str | None:
    """Why a drilling cycle line cannot be kept as a corrected cycle (None: it can)."""
    if min(state.xyz_index) < 0:
        return "a machine without X, Y and Z"
    if state.plane != 17:
        return f"drilling along another axis than Z (G{state.plane})"
    if state.cycle == 87:
        return "back boring G87"
    if state.inverse_time:
        return "inverse time feed G93"
    if state.cycle_r is None or state.cycle_z is None:
        return "no R or Z word given for the cycle"
    if not state.dialect.cycle_words_as_numbers and (state.cycle_r[1] != inc
                                                     or state.cycle_z[1] != inc):
        return "its R or Z was given in the other distance mode (G90/G91)"
    return None


def rotary_cycle(state, axes_given) -> str | None:
    """Why a drilling cycle line that turns a rotary axis, or follows one in its series, cannot be
    kept as a corrected cycle (None: no rotary word in the series so far). Where the control turns
    the rotary axes and along which axis it then drills is its own rule: a Fanuc's G81 drills along
    the plane's normal, Z in G17 (Fanuc Series 0i-MF operator's manual, canned cycles), while a
    5-axis router's control (Thermwood's) drills along the tilted tool. So the line passes through
    as written (in G91 it is refused), its rotary axes stand at their words afterwards and X, Y
    and Z are not known; the rest of the series (to G80 or another motion code) passes through
    too, its holes drilled at that pose by the same rule."""
    rot = [c for c in axes_given if c in "ABC"]
    if rot and state.cycle_rotary is None:
        state.cycle_rotary = rot[0]
    if state.cycle_rotary is None:
        return None
    return (f"a rotary axis word {rot[0]} on the line" if rot else
            f"a rotary axis word {state.cycle_rotary} earlier in its series of cycles")


def check_held_numbers(state, values, reason: str, line: int) -> None:
    """A G90 cycle line passed through (``reason``) on LinuxCNC, which reads the R and Z its line
    does not name as the numbers last written: refused where one was written in G91, since the
    output writes that line absolute and so holds other numbers."""
    held = [c for c, v in (("R", state.cycle_r), ("Z", state.cycle_z))
            if v is not None and v[1] and c not in values]
    if state.dialect.cycle_words_as_numbers and held:
        raise state._err(f"drilling cycle G{state.cycle} passed through uncorrected ({reason}) "
                         f"with the {held[0]} of an incremental (G91) cycle line, which the output "
                         "writes absolute", line)


def retract_level(state, r_level: float) -> tuple[float, bool]:
    """(Z where the cycle leaves the tool, mm; whether that is known): the R plane (G99) or
    the initial level (G98; controllers differ when the R plane lies above it, LinuxCNC takes
    the higher of the two). Neither stated leaves it open, except on LinuxCNC with the R plane
    at or above the initial level, where either leaves the tool at the R plane."""
    init_z, init_known = state.cycle_init
    if state.retract == 99:
        return r_level, True
    if state.retract == 98 and init_known and (r_level <= init_z + 1e-9
                                              or state.dialect.g98_to_higher):
        return max(init_z, r_level), True
    if state.retract is None and init_known and state.dialect.g98_to_higher \
            and r_level >= init_z - 1e-9:
        return r_level, True
    return r_level, False


def incremental_r_level(state, z: float, line: int) -> float:
    """The R plane (mm) of a G91 cycle line started at height z: LinuxCNC measures every hole's
    R from the series' initial level (the Z where the series began: only that and X, Y need be
    known); elsewhere the controllers differ once the tool stands at the R plane (G99), so a
    series continued without G98 is refused, and X, Y and Z must be known."""
    init_z, init_known = state.cycle_init
    xi, yi, zi = state.xyz_index
    from_initial = state.dialect.incremental_r_from_initial
    if not (state.known[xi] and state.known[yi] and (state.known[zi] or from_initial)):
        raise state._err(f"incremental (G91) drilling cycle G{state.cycle} from a position the "
                         "program has not given", line)
    if from_initial:
        if not init_known:
            raise state._err(f"incremental (G91) drilling cycle G{state.cycle}: its R is measured "
                             "from the initial level, the Z where the cycles began, which the "
                             "program has not given", line)
        return init_z + state.cycle_r[0]
    if not state.cycle_start and state.retract != 98:
        raise state._err(f"incremental (G91) drilling cycle G{state.cycle} continued without "
                        "G98: where its R plane lies differs between controllers (give "
                        "--dialect linuxcnc if LinuxCNC runs it)", line)
    return z + state.cycle_r[0]


#: the axis a drilling cycle drills along in each plane (LinuxCNC's interp_cycles.cc:
#: convert_cycle_zx drills along Y, convert_cycle_yz along X; the other two are the hole's place)
DRILL_AXIS = {17: "Z", 18: "Y", 19: "X"}


def cycle_move(state, values, axes_given):
    """A drilling cycle line passed through: the axes of its plane go where it says (absolute) or
    stay unknown; the axis it drills along (Z in G17, Y in G18, X in G19) ends at the R plane or
    the start height: unknown."""
    scale = MM_PER_INCH if state.inch else 1.0
    depth = DRILL_AXIS.get(state.plane, TOOL_AXIS)
    state.cycle_line = True
    # new arrays: the block before holds the old ones as its end (changed in place, a passed-through
    # back boring G87 moved the block before it to the next hole in the pure-Python reader)
    state.position, state.known = state.position.copy(), state.known.copy()
    for c in axes_given:
        i = state.names.index(c)
        if c == depth:
            continue
        v = math.radians(values[c]) if c in "ABC" else values[c] * scale
        if state.incremental:
            state.position[i] += v
        else:
            state.position[i] = v
            state.known[i] = True
    state._forget(state.names.index(depth) if depth in state.names else -1)
    if state.cycle_rotary is not None:      # drilled along a tilted tool: X Y Z end by its rule
        for i in state.xyz_index:
            state._forget(i)
    # what the writer's output holds after it: the rotary axes the line names, and the R and Z
    # the line leaves to the cycle's held values
    state.cycle_rotaries = [state.names.index(c) for c in axes_given if c in "ABC"]
    state.cycle_held = [c for c in "RZ" if c not in values]


def home_with_motion(dialect: str, home_move: int, motion: int) -> bool:
    """Whether a home move (G28/G30) or a move in machine coordinates (G53) may share its block with
    the motion code ``motion`` (read as setting the motion mode for the blocks after it).

    G53 with G0 or G1 on every dialect (``G53 G0 Z0``: the move itself, in machine coordinates).
    G28/G30 with G0 or G1 on Fanuc and Haas (``G00 G91 G28 Z0``, written by many posts): their G
    codes come in groups, group 00 one-shot (G28, G30) and group 01 the motion mode (G00-G03), and
    codes of different groups may share a block (M. Lynch, "Taking advantage of G-code grouping",
    Modern Machine Shop); the home move runs at rapid whatever the mode (M. Lynch, CNC Concepts, "How
    the heck does G28 work?"), and the mode holds for the blocks after it. RS274/NGC (LinuxCNC and
    grbl) makes it an error: two codes that use the axis words."""
    if motion >= 2:
        return False
    return home_move == 53 or (home_move in (28, 30) and dialect in ("fanuc", "haas"))


def codes_with_motion(state, motion: int, dwell: bool, gcodes, tokens, line: int) -> bool:
    """A block with a motion code and a code whose axis words are no motion: whether its axis words
    are motion (False) or not (True). A G4 dwell with a motion code (``G04 P.001 G0 X1 Y1``):
    LinuxCNC and grbl take the dwell time from P and move to the axis words; Fanuc and Haas read X
    as the dwell time, so such a block is refused. G43.1 with a motion code and axis words
    (``G0 G43.1 Z5``): both codes use the axis words, which LinuxCNC refuses ("Cannot use two G
    codes that both use axis values"), and so does mtcomp. A frame code or G10 with a motion code
    is checked where those are applied."""
    axis_words = any(letter.upper() in "XYZABCUVW" for letter, _num, _raw in tokens)
    if not dwell:
        if axis_words and any(round(g, 1) == 43.1 for g in gcodes):
            raise state._err(f"G43.1 and motion G{motion} in one block: both use the axis words "
                             "(G43.1's are the tool's offsets)", line)
        return True
    if state.dialect.name in ("fanuc", "haas") and axis_words:
        raise state._err(f"G4 with G{motion} and axis words in one block ({state.dialect.name} "
                         "reads X as the dwell time): write the dwell on a line of its own", line)
    return False


def has_axis_words(values: dict) -> bool:
    """Whether a block's words (letter -> value) name an axis."""
    return any(letter in values for letter in "XYZABCUVW")


def rigid_tap(state, values, axes_given) -> None:
    """A G33.1 rigid tapping line (or an axis line in its mode): the spindle-synchronised move
    to the given point and back; the line passes through unchanged and uncorrected (its
    overshoot past both ends follows the spindle's reversal, which the program does not give),
    and every axis ends where it started (LinuxCNC G-code reference, G33.1: the moves end at
    the original coordinate), approached in the direction of the tap's last move. In G91 the
    writer keeps the line incremental (``distance_sensitive``)."""
    state.tapping = True
    state.motion = None
    state.cycle = None
    state.passed_move = ("tap", state._line) if axes_given else None
    scale = MM_PER_INCH if state.inch else 1.0
    step = np.zeros(state.na)
    for c in axes_given:
        i = state.names.index(c)
        v = math.radians(values[c]) if c in "ABC" else values[c] * scale
        step[i] = v if state.incremental else (v - state.position[i] if state.known[i] else 0.0)
    state.dirs = step_directions(state.dirs, np.zeros(state.na), step[None, :])[0].copy()
    state.distance_sensitive = state.incremental and bool(axes_given)
    return None

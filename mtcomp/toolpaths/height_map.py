"""uCNC's height map: G39 probes a grid and applies it to Z, G39.1 and G39.2 turn it off and on
(docs/toolpaths.md, "Height maps (uCNC's G39)").

uCNC (github Paciente8159/uCNC; src/core/parser.c and src/core/motion_control.c, ``mc_build_hmap``)
reads ``G39 X Y Z I J R`` in G17, with I J Z R given and I J not negative: from X Y (where the tool
stands without them) it probes a grid of I by J mm towards Z, retracting by R between the points,
then returns to the grid's first point, at the height probed there, and applies the map: while it
is on, every move's Z is the program's plus the map's offset at the move's X Y (the heights probed,
less the first point's; 0 outside the grid). ``G39.1`` turns it off, ``G39.2`` on again (the map
kept). G39 is a motion code of its own: it stays in force for the blocks after it.

mtcomp follows it as a move it cannot correct but whose end the program gives: the G39 line passes
through as written, X and Y stand where it names them (or where they stood), Z is unknown until a
block names it (:func:`.passed.passed_end`), and no motion mode is in force after it (a block of axis
words alone would probe again: refused, naming the missing G0/G1). While the map is on, the Z
positions are placed on the machine with the map's offsets taken as 0: the map is a Z offset of
the machine from the program, not in the program, as an unstated work offset is, and the notes say
so once. An arc in G18 or G19 while the map is on is refused, as uCNC refuses it.

Read on the generic and grbl dialects (uCNC is a grbl-compatible firmware); on Fanuc and Haas G39
is corner rounding under cutter compensation, refused.
"""
from __future__ import annotations

from .passed import passed_end

__all__ = ["height_map_code", "passed_height_map", "check_map_plane"]

#: the dialects on which G39 is uCNC's height map
MAP_DIALECTS = ("generic", "grbl")


def height_map_code(state, g: float, values: dict, line: int) -> bool:
    """Apply G39, G39.1 or G39.2 of a line to ``state``; True for G39 (its axis words are no move
    of the line's motion mode: :func:`passed_height_map` passes the line through)."""
    if state.dialect.name not in MAP_DIALECTS:
        raise state._err(f"G{g:g} is not a code mtcomp follows on {state.dialect.name} (uCNC's "
                         "height map on the generic and grbl dialects)", line)
    code = round(g, 1)
    if code in (39.1, 39.2):
        state.height_map = code == 39.2
        if state.height_map:
            _note_map(state, line, "G39.2")
        return False
    missing = [c for c in "IJZR" if c not in values]
    problem = ("not in G17" if state.plane != 17 else
               f"without {' '.join(missing)}" if missing else
               "with a negative I or J" if min(values["I"], values["J"]) < 0 else
               "under cutter radius compensation" if state.cutter_comp else "")
    if problem:
        raise state._err(f"G39 (uCNC's height map) {problem}", line)
    state.map_line = line
    return True


def passed_height_map(state, values: dict, axes_given, motion, line: int) -> None:
    """The G39 line: passed through as written; X and Y stand where it names them (G90) or moved by
    its increments (G91), Z is unknown, the map on, no motion mode in force."""
    if motion is not None:
        raise state._err(f"G39 (uCNC's height map) and motion G{motion} in one block", line)
    passed_end(state, values, [c for c in axes_given if c in "XY"], "height map", line)
    zi = state.xyz_index[2]
    if zi >= 0:
        state.known[zi] = False
        state.dirs[zi] = 0
    state.motion = None
    state.height_map = True
    state.map_line = None
    _note_map(state, line, "G39")


def check_map_plane(state, line: int) -> None:
    """An arc in G18 or G19 while the map is on: refused, as uCNC refuses it (parser.c: invalid
    plane selected)."""
    if getattr(state, "height_map", False) and state.plane != 17:
        raise state._err(f"arc G{state.motion} in G{state.plane} while uCNC's height map (G39) is "
                         "on: uCNC refuses it (invalid plane selected)", line)


def _note_map(state, line: int, code: str) -> None:
    """Say once, in the program's notes, how the Z positions under the map are placed."""
    notes = getattr(state._source, "notes", None)
    if notes is None or any("(uCNC's height map)" in n for n in notes):
        return
    notes.append(f"assumed: {code} at line {state._where(line)[1]} (uCNC's height map) offsets every "
                 "move's Z by the heights it probed, which the program does not give: Z is not "
                 "written after the probing until the program names it, and the Z positions under "
                 "the map are placed with its offsets taken as 0 (as an unstated work offset)")

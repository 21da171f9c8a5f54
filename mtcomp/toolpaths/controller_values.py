"""Lines that move to a place only the controller knows: values it holds, and probing moves
(docs/toolpaths.md, "Values the controller holds").

A program may take a position from the controller as it runs: the current position ``#<_x>`` ...
``#<_c>``, ``#<_abs_x>`` ... and ``#5420``-``#5428``, the last probe's end ``#5061``-``#5069`` and
its success ``#5070`` (LinuxCNC G-code reference, Numbered Parameters and Predefined Named
Parameters; FluidNC, src/Parameters.cpp, get_numbered_param and get_system_param), or one of
FluidNC's configuration items ``#</axes/z/max_travel_mm>`` (Parameters.cpp, get_config_item). The
expansion (:mod:`.ngc`) reads such a value as unknown, and anything computed from it too; a line
with a word of such a value is written as the controller computes it (:class:`~.lines.ControllerLine`)
and read here from its ``reading`` text, where those words are 0 (a feed, a speed or FluidNC's D
left out):

* it passes through as written, uncorrected; each axis whose word is such a value is unknown after
  it (no word is written for it until the program positions it again), each axis of a known word
  stands at it as after any move passed through (:func:`.passed.passed_end`);
* a tool length offset ``G43.1 Z`` of such a value makes the tool length unknown, so the tip: no
  block is corrected while it is in force (until G49, G43, or a G43.1 of a known value);
* a work offset (G10, G92, G52) of such a value is refused: the program's frame is then unknown.

The probing moves G38.2-G38.5 (LinuxCNC G-code reference, G38.x; FluidNC follows them, its
GCode.cpp) stop where the probe touches or leaves: the line passes through as written and the axes
it names are unknown after it. G38.x is a motion mode of its own: no motion mode is in force after
it here, so a block of axis words alone (another probe) is refused, naming the missing G0/G1. On a
Fanuc or Haas G38 is no probing move (refused, :mod:`.modal`).
"""
from __future__ import annotations

from .passed import passed_end
from .words import _CANNED_CYCLES, FANUC_CYCLES

__all__ = ["PROBE_G", "probe_code", "held_block"]

#: the probing moves
PROBE_G = (38.2, 38.3, 38.4, 38.5)
#: the drilling cycles
_CYCLE_G = _CANNED_CYCLES | FANUC_CYCLES
#: the codes whose axis words set an offset of the program's frame
_OFFSET_G = (10.0, 52.0, 92.0)


def probe_code(state, g: float, line: int) -> bool:
    """A G38.x of a line: its axis words are the probe's target, no move of the motion mode."""
    state.probing = round(g, 1)
    return True


def held_block(state, gcodes, values: dict, axes_given, motion, nonmotion_axes, line: int) -> bool:
    """Follow a line read from a value the controller holds (``state.held``: the letters of those
    words), a probing move, or a move while the tool length is unknown. True where the line passes
    through here (the reader returns no block); False where the usual path goes on."""
    held = state.held or frozenset()
    if any(round(g, 1) in (43.0, 49.0) for g in gcodes) or (
            43.1 in gcodes and "Z" not in held):
        state.length_unknown = False
    if nonmotion_axes and state.probing is None:
        if held & set(axes_given) and any(g in _OFFSET_G for g in gcodes):
            raise state._err("an offset (G10, G52, G92) set from a value the controller holds (its "
                             "position, a probe's result, a setting): the program's frame is not "
                             "known", line)
        if 43.1 in gcodes and "Z" in held:
            state.length_unknown = True
            _note(state, line, "G43.1 sets the tool length offset from a value the controller "
                               "holds: the tip is not known, no block is corrected until G49 or "
                               "G43")
        return False
    if state.probing is not None:
        return _probing(state, axes_given, motion, line)
    if not axes_given or (state.held is None and not state.length_unknown):
        return False                # nothing moves (a D, F or S word of such a value)
    cycle = state.cycle is not None or any(round(g) in _CYCLE_G for g in gcodes)
    if cycle or motion is None and state.motion is None:
        what = "a drilling cycle" if cycle else "axis words without a motion mode"
        why = "given a value" if state.held is not None else "under a tool length"
        raise state._err(f"{what} {why} the controller holds (its position, a probe's result, a "
                         "setting): not followed", line)
    if motion is not None:
        state.motion = motion
    passed_end(state, values, [c for c in axes_given if c not in held], "controller", line)
    for c in held & set(axes_given):
        _lose(state, c)
    return True


def _probing(state, axes_given, motion, line: int) -> bool:
    """A G38.x line: passed through as written, its axes unknown, no motion mode after it."""
    if motion is not None:
        raise state._err(f"G{state.probing:g} (probing move) and motion G{motion} in one block",
                         line)
    if not axes_given:
        raise state._err(f"G{state.probing:g} (probing move) without axis words", line)
    for c in axes_given:
        _lose(state, c)
    state.motion = None
    state.passed_move = ("probing", line)
    return True


def _lose(state, c: str) -> None:
    """Axis ``c`` is at a place the controller knows, the program not."""
    i = state.names.index(c)
    state.known[i] = False
    state.dirs[i] = 0


def _note(state, line: int, text: str) -> None:
    """Say once, in the program's notes, naming the first line."""
    notes = getattr(state._source, "notes", None)
    if notes is not None and not any(n.startswith(f"note: {text[:20]}") for n in notes):
        notes.append(f"note: {text} (first at line {state._where(line)[1]})")

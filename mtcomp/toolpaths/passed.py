"""Where a move passed through as written leaves the axes: the one rule for the moves mtcomp
cannot correct but whose end the program gives (docs/toolpaths.md): an absolute arc from a position
the program has not given in its plane (:func:`._arcs.blind_arc`), a G5/G5.1 spline
(:func:`._arcs.passed_spline`) and Fanuc's G60 single-direction positioning
(:func:`.single_direction.single_direction`)."""
from __future__ import annotations

import math

from .words import MM_PER_INCH, grid_text

__all__ = ["passed_end", "check_passed_start", "passed_cycle"]

#: an axis of the output within this (mm, rad) of the program's position stands uncorrected there
_SAME_START = 1e-6


def passed_end(state, values: dict, axes, why: str, line: int) -> None:
    """The line (read by ``state``, a :class:`~.modal.ModalState`; its words ``values``) passes
    through as written, uncorrected (``passed_move`` = (``why``, ``line``)). Each axis it names
    (``axes``) stands after it at its written value in G90, known, in the program and in the output
    alike (``declared``), or in G91 moves by its increment from where it stood, in the output from
    where the output stands (``distance_sensitive``; an axis not known stays unknown). The
    direction each of them last moved in is not known (0): the controller's path there is not the
    program's straight line. The next block starts from this end, not from the last block's: its
    first row is a ``jump`` (``off_path``), so the planner puts no node on a line from the last
    block's end and takes no step bound from its correction (the output stands here uncorrected)."""
    scale = MM_PER_INCH if state.inch else 1.0
    state.passed_start = state.position.copy()  # where the program stood before it
    state.position = state.position.copy()      # the last block's end is that array
    for c in axes:
        i = state.names.index(c)
        v = math.radians(values[c]) if c in "ABC" else values[c] * scale
        if state.incremental:
            state.position[i] += v
        else:
            state.position[i], state.known[i] = v, True
            state.declared.append(i)
        state.dirs[i] = 0
    state.distance_sensitive = state.incremental
    state.passed_move = (why, line)
    state.off_path = True


def check_passed_start(state, out_values) -> None:
    """An absolute arc passed through (``passed_move`` 'arc', :func:`._arcs.blind_arc`) must start,
    on the axes of its plane whose position is known, where the output stands uncorrected
    (``out_values``, the writer's, equal to the program's): the controller takes its centre from
    where the tool stands (I J K offsets, or R from there to the written end), so from a corrected
    start its centre would move and its end stay (a full circle shrunk to a sliver, an end off its
    circle). ``state.passed_plane``: the columns of the arc's plane (set by ``blind_arc``).
    InputError naming the line otherwise (the output is not written)."""
    if state.passed_move is None or state.passed_move[0] != "arc" or state.incremental:
        return
    off = [state.names[i] for i in state.passed_plane
           if abs(out_values[i] - state.passed_start[i]) > _SAME_START]    # nan: not known, passes
    if off:
        raise state._err(f"arc G{state.motion} from a position the program has not given "
                         f"starts where the output stands corrected on {' '.join(off)} (a move "
                         "before it was corrected, and the controller would take the arc's centre "
                         f"from there): position {' '.join(off)} again before the arc",
                         state.passed_move[1])


def passed_cycle(state, out) -> None:
    """A drilling cycle line passed through as written (:func:`.cycle_rules.cycle_move`), seen by the
    writer (``out``, its :class:`~.writer.OutputState`): the rotary axes the line names stand at
    their words in the output too. An R or Z the line does not name is the one the output's cycle
    holds, which a cycle line corrected before it may have moved: where that differs from the
    program's, the controller would drill the passed line's holes at a corrected depth without
    their correction, so the line is refused (InputError naming it; the output is not written)."""
    for i in state.cycle_rotaries:
        out.values[i] = state.position[i]
    for c in state.cycle_held:
        v = state.cycle_r if c == "R" else state.cycle_z
        held = out.cycle_r if c == "R" else out.cycle_z
        if held and v is not None and not v[1] and held != grid_text(v[0], False, state.inch):
            raise state._err(f"drilling cycle G{state.cycle} passed through uncorrected without "
                             f"its own {c}: the output's cycle holds the corrected {c}{held} of a "
                             "line before it (give the line its " + c + ")", state._line)

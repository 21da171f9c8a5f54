"""The W quill of horizontal boring mills: an axis parallel to Z that the machine model does not
have (docs/toolpaths.md, "The W quill").

A W word is never corrected and never written where the program did not write it; its travel adds
to the tool tip's position along Z: the tip stands at ``Z + W`` in the program's frame (ISO 841:
W is the secondary linear axis parallel to Z, of the same sense; the Siemens NX posts for the
Nomura BN-130 and Kuraki KBT horizontal boring mills write ``W = tip - Z``). The quill extends the
tool out of the ram, so the model sees the tip at ``Z + W`` with a tool longer by ``-W``: the ram
stands where the Z word puts it, the Abbe arm of its angular errors is the tool's length plus the
quill's reach (docs/conventions.md, "Tool length").

The reader records, per line that changes it, the quill's position before and after the line
(``source.quill_moves``: line -> (before, after), mm, NaN where not known); :func:`quill_of_rows`
gives each segment row its W. Only a machine whose file declares its quill (``quill = true`` in
[axes.Z]: ``Machine.quill``) has one: elsewhere W is not followed (on Fanuc and Haas, whose lathes
read W as Z given incrementally, it is refused by the reader). Before the program's first W word
the quill stands where the set-up left it (0: as in a program that never names W, its place is
part of the Z work offset), until a home move of every axis, which homes the quill too, or a tool
change (the builder's macro may move it). After a home move of W or of every axis, a G53 move of
W, a tool change, a change of work system or of the tool centre point mode (the last two once the
program has named W), its position is not known until the program names W again: the tip's Z is
not known there, so those blocks are not corrected, and get no Z word they do not name
(:func:`tip_known`). A block that moves W and the model's axes
together is not corrected either (its tip moves along a line the controller runs with an axis the
model does not have).
"""
from __future__ import annotations

import numpy as np

from .words import MM_PER_INCH


def init_quill(state, path) -> None:
    """The quill's state at the program's start: ``quill`` (mm, NaN: not known), ``quill_named``
    (a W word was read) and ``quill_moves``, shared by the passes over one ProgramSource
    (``path``)."""
    state.quill, state.quill_named = 0.0, False
    table = getattr(path, "quill_moves", None)
    state.quill_moves = table if table is not None else {}


def tip_known(state, known: np.ndarray) -> np.ndarray:
    """``known`` (na,) of a block read by ``state``, with Z not known where the quill's position
    is not: the tip's Z is not known there, so the writer adds no Z word to the block (one the
    block names is written as named)."""
    z = state.xyz_index[2]
    if z < 0 or not quill_lost(state):
        return known
    known = known.copy()
    known[z] = False
    return known


def quill_lost(state) -> bool:
    """The quill of the machine read by ``state`` stands where the program has not said (the
    compiled scanner hands such lines to Python, which knows the tip's Z is not known)."""
    return np.isnan(state.quill) and has_quill(state)


def has_quill(state) -> bool:
    """The W words of the program read by ``state`` (a ModalState) move a quill along Z: the
    machine file declares one, and the dialect is not Haas (a Haas mill has no W; on its lathes W
    is Z given incrementally)."""
    return state.machine.quill and state.dialect.name != "haas"


def follow_quill(state, values: dict, codes: tuple, nonmotion_axes: bool, line: int) -> None:
    """Follow the line's W word (``values``: its words), after its codes were applied (``codes``:
    the line's motion code, drilling cycle code and home move, each None where it has none); on a
    machine without a quill, nothing."""
    if not has_quill(state):
        return
    motion, cycle, home_move = codes
    motion = state.motion if motion is None else motion
    before = state.quill
    if "W" in values:
        if state.tcp or state.dwo:
            raise state._err("axis word W in tool centre point mode is not supported (the quill "
                             "moves along the tilted tool, not along Z)", line)
        if any(state.machine.axes[state.names.index(a)].is_rotary
               for a in state.machine.tool_chain):
            raise state._err(f"axis word W on machine {state.machine.name}, whose rotary axes "
                             "carry the tool, is not supported (the quill moves along the tool)",
                             line)
        if (cycle or state.cycle) is not None or (motion in (2, 3) and not nonmotion_axes):
            raise state._err("axis word W in a drilling cycle or arc block is not supported (the "
                             "quill's travel there is the controller's own rule)", line)
        if nonmotion_axes:            # G28/G30 W (home), G53 W, G92/G52/G10 W: not known after
            state.quill = np.nan
        else:
            w = values["W"] * (MM_PER_INCH if state.inch else 1.0)
            state.quill = state.quill + w if state.incremental else w
        state.quill_named = True
    elif home_move in (28, 30) and not any(c in values for c in state.names):
        state.quill = np.nan          # G28 / G30 alone: every axis goes home, W too
    if not _same(before, state.quill):
        state.quill_moves[line] = (before, state.quill)


def forget_quill(state, tool_change: bool = False) -> None:
    """The quill's position is not known from the line being read on: after a tool change (the
    machine builder's macro, which may move the quill to change tools: before the program's first
    W word as after it), or a change of work system or of the tool centre point mode once the
    program has named W (before, the quill stands where the set-up left it: a program that never
    names W does not move it). On a machine without a quill, nothing."""
    if not has_quill(state):
        return
    if (state.quill_named or tool_change) and not np.isnan(state.quill):
        state.quill_moves[state._line] = (state.quill, np.nan)
        state.quill = np.nan


def _same(a: float, b: float) -> bool:
    return a == b or (np.isnan(a) and np.isnan(b))


def quill_of_rows(moves: dict, lines: np.ndarray, last: int = -1):
    """(w, known, moved, i) per row of source ``lines``: the quill's position at the row's end
    (mm; 0 before the program's first W word); whether it is known and stands still along the row
    (False: the row's tip along Z is not known, or moves with the quill); whether the quill moved
    since the row before (``last``: the number of changes before the previous chunk's last row,
    -1 at the start), so the tip does not come from that row's end along a line; and the number of
    changes up to the last row, the next chunk's ``last``."""
    keys = np.array(sorted(moves), dtype=np.int64)
    lines = np.asarray(lines, dtype=np.int64)
    if keys.size == 0 or lines.size == 0:
        return np.zeros(lines.shape), np.ones(lines.shape, bool), np.zeros(lines.shape, bool), last
    after = np.array([moves[k][1] for k in keys.tolist()])
    upto = np.searchsorted(keys, lines, side="right")       # changes at or before the row's line
    w = np.where(upto > 0, after[np.maximum(upto - 1, 0)], 0.0)
    own = upto > np.searchsorted(keys, lines, side="left")  # the row's own line moved the quill
    moved = np.empty(lines.shape, bool)
    moved[0] = upto[0] - own[0] != last if last >= 0 else upto[0] - own[0] > 0
    moved[1:] = upto[1:] - own[1:] != upto[:-1]
    known = ~np.isnan(w) & ~own
    return np.nan_to_num(w, nan=0.0), known, moved, int(upto[-1])

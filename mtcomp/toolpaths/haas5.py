"""Haas 5-axis modes: tool centre point control ``G234`` ... ``G49`` and the dynamic work offset
``G254`` ... ``G255`` (Haas mill operator's manual, Next Generation Control: "G234 Tool Center
Point Control (TCPC)" and "G254 Dynamic Work Offset (DWO)").

* ``G234 H..``: the program's X Y Z are the tool tip in the work coordinate system, which the
  control keeps fixed to the table (it combines the table's centres of rotation, the machine rotary
  zero point MRZP of settings 255-257, with the active work offset; "when the rotary axes rotate,
  the linear coordinate system rotates with them"). That is the tool centre point mode of Fanuc's
  ``G43.4`` and is read by the same machinery (:mod:`.tcp`); ``G49`` cancels it.
* ``G254``: for 3+1 and 3+2 positioning. The work offset follows the rotary axes' position: the
  part origin (the active work offset, set with the rotary axes at zero) turned with the table
  about its axes, the program's X Y Z along the machine's axes from there (the CAM post writes the
  positions of the turned part in the machine's directions, as a 3+2 program without it does, and
  the control moves its origin: "DWO applies the appropriate offsets to account for the
  differences between the programmed workpiece location and the actual workpiece location"). So a
  row under it is a row with a work offset of its own (:func:`dwo_offsets`): ``G255`` cancels it.

The MRZP is the machine file's: its rotary axes' lines (``axis_point_mm``). What the manual asks
for and what is not sure here is refused in one line naming it (never guessed).
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from .lengths import length_number
from .tcp import axes_of_tcp

#: the Haas codes this module follows
HAAS_5AXIS_G = frozenset({234, 254, 255})
#: work system codes (their change under G254 is refused)
_WCS_G = frozenset({54.0, 55.0, 56.0, 57.0, 58.0, 59.0, 59.1, 59.2, 59.3, 154.0,
                    *(float(g) for g in range(110, 130))})


def haas_code(state, gi: int, values, line: int) -> None:
    """Follow ``G234``, ``G254`` or ``G255`` of a block (``values``: its words)."""
    if state.dialect.name != "haas":
        what = "tool centre point control" if gi == 234 else "dynamic work offset"
        raise state._err(f"G{gi} (Haas' {what}) is not a code mtcomp follows on "
                         f"{state.dialect.name} (give --dialect haas for a Haas program)", line)
    if gi == 234:
        if state.dwo:
            raise state._err("G234 while G254 (dynamic work offset) is in force is not supported: "
                             "cancel it with G255 first", line)
        if state.cutter_comp:
            raise state._err("G234 under cutter radius compensation (G41/G42) is not supported",
                             line)
        state.tool, state.length_on = length_number(state, values), True
        state._set_tcp(True, "G234")
        state.g234 = True
        return
    if any(c in values for c in state.names):
        raise state._err(f"G{gi} with axis words in its block is not supported (give the axes "
                         "on a line of their own)", line)
    if gi == 254:
        _dwo_on(state, line)
    elif state.dwo:
        state.dwo = False
        _forget_xyz(state)


def _dwo_on(state, line: int) -> None:
    """G254: the dynamic work offset from here on, at the rotary axes' positions the program gave."""
    if state.tcp:
        raise state._err("G254 in tool centre point mode is not supported: cancel G234 with G49 "
                         "first", line)
    if not state.local.identity:
        raise state._err("G254 while G52, G68, a mirror image or scaling is in force is not "
                         "supported", line)
    rotary = [c for c in state.names if c in "ABC"]
    if not rotary:
        raise state._err("G254 (dynamic work offset) on a machine without rotary axes is not "
                         "supported", line)
    unknown = [c for c in rotary if not state.known[state.names.index(c)]]
    if unknown:
        raise state._err(f"G254 before the program positioned {', '.join(unknown)} is not "
                         "supported (the offset turns with the rotary axes' positions; the Haas manual "
                         "asks for all rotary motion before G254)", line)
    if not state.dwo:
        state.dwo = True
        state.tcp_switches[line] = "G254"
        _forget_xyz(state)


def _forget_xyz(state) -> None:
    """X Y Z change meaning: unknown until the program names them (the manual asks for them after
    G254)."""
    for j in state.xyz_index:
        state._forget(j)


def haas_block(state, gcodes, motion, home_move, values, line: int) -> None:
    """Refuse in one line what a block does under G234 or G254 that is not followed here."""
    if not state.tcp:
        state.g234 = False
    named = any(c in values for c in "XYZ")
    if state.tcp and state.g234:
        arc = motion in (2, 3) or (motion is None and state.motion in (2, 3) and named)
        bad = ("an arc (G02/G03)" if arc else
               "cutter radius compensation (G41/G42)" if state.cutter_comp else
               "G91 (incremental positions)" if state.incremental and named and home_move is None else
               "G43/G44" if any(g in (43.0, 44.0) for g in gcodes) else None)
        if bad:
            raise state._err(f"{bad} in tool centre point mode (G234) is not supported", line)
    if state.dwo:
        turned = [c for c in "ABC" if c in values]
        bad = (f"rotary motion ({turned[0]})" if turned else
               f"G{home_move}" if home_move in (28, 30) else
               "a change of work system" if any(g in _WCS_G for g in gcodes) else None)
        if bad:
            raise state._err(f"{bad} under G254 (dynamic work offset) is not supported: the Haas "
                             "manual asks for G255 before it", line)


def dwo_offsets(machine, chunk, off: np.ndarray, rows: np.ndarray, path) -> np.ndarray:
    """(n, na) the rows' work offsets with those of ``rows`` (n,) bool, under G254, turned with the
    table: the linear axes' position of the part origin (the work offset's X Y Z, a tip position at
    the rotary axes' zero) at the row's rotary angles, by the machine file's kinematics (the inverse
    of :mod:`.tcp`); the program's X Y Z add to it along the machine's axes. ``off``: the rows'
    offsets as set up; ``chunk``: the rows as read (program positions)."""
    rot = np.array([a.is_rotary for a in machine.axes])
    turned = rows & np.any(off[:, rot] != 0.0, axis=1)
    if turned.any():
        raise InputError("G254 (dynamic work offset) with a work offset that turns a rotary axis is "
                         "not supported", path, line=int(chunk.line[np.argmax(turned)]))
    lin = [machine.index(c) for c in "XYZ"]
    q = np.array(off[rows], dtype=float)
    q[:, rot] = np.asarray(chunk.end, float)[rows][:, rot]
    out = np.array(off, dtype=float)
    out[np.ix_(np.flatnonzero(rows), lin)] = axes_of_tcp(machine, q)[:, lin]
    return out


def mrzp_text(machine) -> str:
    """The machine rotary zero point as the machine file gives it: each rotary axis's line."""
    return ", ".join(f"{a.name} through ({', '.join(f'{v:g}' for v in a.axis_point)}) mm"
                     for a in machine.axes if a.is_rotary)

"""Tool length offsets: the tool length number in force after ``G43``/``G44 H``, ``G49`` and an
``H`` on its own, as each controller takes them (docs/toolpaths.md, "Tool length offsets").

The number in force is recorded per block (its frame code, :func:`~.words.frame_code`): an H
number, 0 where no offset has been stated (the program's start: the machine file's tool length is
assumed), or :data:`~.words.NO_LENGTH` where the program cancelled the offset or chose offset
number 0, whose value is 0: the point the program steers is then the spindle's gauge point (tool
length 0 for the error model's Abbe arm). Where that is so:

* ``G49`` cancels the offset the program applied: LinuxCNC, Fanuc, Haas and RS274/NGC (LinuxCNC
  G-code reference, G49; Fanuc Series 0i-MF operator's manual, tool length compensation cancel;
  Haas mill operator's manual, G49; Kramer, Proctor and Messina 2000, NIST RS274/NGC interpreter
  version 3, section 3.5.13). A ``G49`` before the program applies any (the safe-start line of
  many posts, ``G17 G21 G40 G49 G80 G90``) leaves none stated: a program that moves Z without ever
  applying an offset has Z touched off with its tool in the spindle, the tip (the machine file's
  tool length). grbl's G49 cancels its dynamic offset ``G43.1`` (grbl v1.1 commands), whose values
  are relative to the tool the machine was zeroed with, not lengths from the gauge point:
  unchanged there.
* ``H0`` (``H00``) is an offset of 0 on Fanuc and Haas (Haas mill operator's manual, G49 and G143:
  "a G49 or H00 command will cancel" the compensation; Centroid M-series operator's manual, H: "H00
  is always a 0.0 length offset") and in RS274/NGC ("It is OK for the H number to be zero; an
  offset value of zero will be used", section 3.5.13). LinuxCNC's ``G43 H0`` is the tool in the
  spindle's offset on a non-random tool changer (T0's on a random one: LinuxCNC G-code reference,
  G43), read as ``G43`` without H: the tool the program's T word selected.
* An ``H`` on its own changes the offset number while ``G43``/``G44`` is in force on Fanuc and Haas
  (Fanuc: the new offset number's value replaces the old one; Milltronics' Fanuc-style manual: "The
  H offsets can be changed throughout the program without canceling the previous offset with a G49
  or H00"): the same change as ``G43 H..`` (Z unknown until the program names it again, since the
  controller's Z position in the program's frame moves by the difference), an ``H0`` on a Haas also
  cancelling the compensation (its G49). Under ``G49`` it changes nothing. LinuxCNC, grbl and
  RS274/NGC refuse it (:mod:`.word_use`).
"""
from __future__ import annotations

from .words import NO_LENGTH

#: dialects whose G49 cancels the tool length offset (the gauge point steered: tool length 0)
G49_NO_LENGTH = frozenset({"linuxcnc", "fanuc", "haas", "generic"})
#: dialects whose offset number 0 is an offset of 0
H0_NO_LENGTH = frozenset({"fanuc", "haas", "generic"})
#: dialects on which an H word on its own changes the offset number under G43/G44
LONE_H = frozenset({"fanuc", "haas"})
#: the G codes that take an H word (tool length offsets; G43.4: Fanuc's tool centre point control)
H_CODES = (43.0, 44.0, 43.4, 49.0)


def length_number(state, values) -> int:
    """The tool length number a ``G43``/``G44``/``G43.4`` of the block puts in force (``values``:
    its words): its H (0 read per dialect), or without H the tool its T word selected."""
    if "H" not in values:
        return state.selected_tool
    h = int(values["H"])
    if h == 0:
        if state.dialect.name in H0_NO_LENGTH:
            return NO_LENGTH
        if state.dialect.name == "linuxcnc":
            return state.selected_tool
    if not 0 <= h < NO_LENGTH:
        raise state._err(f"tool length number H{h} is not supported (0 to {NO_LENGTH - 1})",
                         state._line)
    return h


def set_length(state, code: float, values) -> None:
    """Follow a ``G43``, ``G44`` or ``G49`` of the block: the number in force, the offset's mode;
    the tool axis is unknown after it (its position in the program's frame moves by the change)."""
    if code == 49.0:
        # a G49 before any offset (the safe-start line of many posts) leaves none stated: the
        # machine's tool length, the program's Z touched off with the tool in the spindle
        cancels = state.tool != 0 and state.dialect.name in G49_NO_LENGTH
        state.tool = NO_LENGTH if cancels else 0
        state.length_on = False
    else:
        state.tool = length_number(state, values)
        state.length_on = True
    state._forget(state.tool_axis)


def lone_h(state, gcodes, values) -> None:
    """An H word no tool length code of its block takes: on Fanuc and Haas, under G43/G44, the new
    offset number (see the module docstring)."""
    if "H" not in values or state.dialect.name not in LONE_H or not state.length_on:
        return
    if any(g in H_CODES for g in gcodes):
        return
    state.tool = length_number(state, values)
    if state.tool == NO_LENGTH and state.dialect.name == "haas":
        state.length_on = False          # Haas: H00 cancels the compensation, as G49 does
    state._forget(state.tool_axis)


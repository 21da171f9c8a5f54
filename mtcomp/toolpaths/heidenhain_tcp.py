"""The TNC's tool centre point mode in a conversational program: ``M128`` ... ``M129`` and
``FUNCTION TCPM ...`` ... ``FUNCTION RESET TCPM``.

In the mode an ``L`` block's X Y Z are the tool tip in the workpiece frame and its A B C the rotary
axes' positions; the TNC moves the linear axes so that the tip stays where the words put it as the
rotary axes turn (HEIDENHAIN, TNC 620 User's Manual for DIN/ISO programming, 2013, "Maintaining the
position of the tool tip when positioning with tilted axes (TCPM): M128"; iTNC 530 User's Manual,
"TCPM FUNCTION"). The G-code equivalent says so as a G-code program does: ``M128`` where the mode
goes on and ``M129`` where it goes off (:mod:`.tcp` turns the words into the axes the controller
reaches, and back). The TNC's rules followed:

* ``M128`` is effective at the start of its block, ``M129`` at its end (TNC 410/426/430 User's
  Manual, ISO programming, "Effect": "M128 becomes effective at the start of block, M129 at the end
  of block"), so the block with ``M129`` still moves in the mode: its ``M129`` goes on the next
  line of the G-code equivalent;
* ``FUNCTION TCPM`` with ``AXIS POS`` (the rotary coordinates are the axes' positions), with or
  without ``F TCP`` / ``F CONT`` (how the feed is meant), ``PATHCTRL AXIS`` (the tip on a straight
  line, the rotary axes interpolated linearly: what mtcomp plans) and ``REFPNT TIP-TIP``; ``AXIS
  SPAT``, ``PATHCTRL VECTOR`` and other reference points are refused;
* a switch of the mode makes every axis unknown until a block names it (the words change
  meaning);
* "Before positioning with M91 or M92 and before a TOOL CALL, reset M128": those are refused in
  the mode, as are arcs (``C``, ``CC``), cycles, datum shifts and radius compensation ``RL``/``RR``
  (the TNC's 3-D compensation), and the mode under a datum shift.
"""
from __future__ import annotations

import re

#: the options of FUNCTION TCPM read: AXIS POS, with the feed's meaning, PATHCTRL AXIS and
#: REFPNT TIP-TIP
_TCPM_READ = re.compile(r"(?:F (?:TCP|CONT) )?AXIS POS(?: PATHCTRL AXIS)?(?: REFPNT TIP-TIP)?")
#: blocks refused in the mode, and why
_UNDER_TCP = {"C": "an arc C", "CC": "a circle centre CC",
              "TOOL CALL": "a TOOL CALL (the TNC asks for the mode reset before it)",
              "CYCL DEF": "a cycle definition", "CYCLE DEF": "a cycle definition"}


class TcpMode:
    """The tool centre point mode of a conversational program's reader (see the module
    docstring): its ``pos``, ``shift``, ``radius_comp`` and ``err`` are the reader's."""

    tcp = False                 # in force
    tcp_ending = False          # M129 in the block being read: off after it
    tcp_carry = ""              # the M129 the next line of the G-code equivalent starts with

    def _tcp_set(self, on: bool, k: int, code: str) -> str:
        """Switch the mode; the G-code word that says so ('' where it does not change)."""
        if on == self.tcp:
            return ""
        if on and (any(self.shift) or self.radius_comp != "R0"):
            raise self.err("tool centre point mode (M128, FUNCTION TCPM) under a datum shift "
                           "CYCL DEF 7 or radius compensation RL/RR is not read by mtcomp", k)
        self.tcp = on
        self.pos = dict.fromkeys(self.pos)
        return code

    def tcp_function(self, code: str, k: int) -> str | None:
        """The G-code of a FUNCTION TCPM or FUNCTION RESET TCPM block; None for another block."""
        words = code.split()
        if words[:3] == ["FUNCTION", "RESET", "TCPM"] and len(words) == 3:
            return self._tcp_set(False, k, "M129")
        if words[:2] != ["FUNCTION", "TCPM"]:
            return None
        if not _TCPM_READ.fullmatch(" ".join(words[2:])):
            raise self.err(f"{code!r} is not read by mtcomp (Heidenhain conversational): of "
                           "FUNCTION TCPM, AXIS POS (the rotary axes' positions) is, with F TCP or "
                           "F CONT, PATHCTRL AXIS and REFPNT TIP-TIP", k)
        return self._tcp_set(True, k, "M128")

    def tcp_block(self, name: str, rest: str, k: int) -> str:
        """Refuse what the mode does not take in a block (keyword ``name``, the words after it
        ``rest``); switch it where the block says M128 or M129 (the G-code word that goes on this
        block's line, followed by a blank, or '')."""
        codes = {int(v) for v in re.findall(r"(?<![A-Z])M\s*(\d+)", ("M" if name == "M" else "")
                                            + rest)}
        on, off = 128 in codes, 129 in codes
        if on and off:
            raise self.err("M128 and M129 in one block", k)
        if (on or off) and name not in ("L", "M"):
            raise self.err(f"M{128 if on else 129} in a block other than L or M", k)
        if self.tcp or on:
            if name in _UNDER_TCP:
                what = {"C": f"an arc {self.ARC}", "CC": f"a circle centre {self.CENTRE}",
                        "TOOL CALL": f"a {getattr(self, 'TOOL', 'TOOL CALL')} (the TNC asks for "
                                     "the mode reset before it)"}
                raise self.err(f"{what.get(name, _UNDER_TCP[name])} in tool centre point mode "
                               "(M128, FUNCTION TCPM) is not read by mtcomp", k)
            if codes & {91, 92, 99} or re.search(r"\bR[LR]\b", rest):
                raise self.err("M91, M92, M99 or radius compensation RL/RR in tool centre point "
                               "mode (M128, FUNCTION TCPM) is not read by mtcomp (the TNC asks "
                               "for the mode reset before M91 and M92)", k)
        if on:
            return (self._tcp_set(True, k, "M128") + " ").lstrip()
        if off and name == "M":
            return (self._tcp_set(False, k, "M129") + " ").lstrip()
        self.tcp_ending = off and self.tcp
        return ""

    def tcp_after(self, gcode: str) -> str:
        """The G-code of a line with the M129 of the line before it, if any; where this line's
        block ends the mode (M129 on a move), the mode goes off after it."""
        gcode, self.tcp_carry = (self.tcp_carry + gcode).strip(), ""
        if self.tcp_ending:
            self.tcp_ending = False
            self._tcp_set(False, -1, "")
            self.tcp_carry = "M129 "
        return gcode

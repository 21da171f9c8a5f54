"""The modal state of the machine while a program is read: the one place that holds it.

The middle layer of the reader (after pygcode: word -> block -> program). :class:`ModalState`
takes the tokens of one line (:func:`~.words.tokenize`), updates the modes the line changes
(motion mode, plane, units, distance mode, feed and feed mode, work coordinate system, tool length,
drilling cycle) and the position and approach directions of the axes, and returns the line's
motion as a :class:`~.blocks.MotionBlock`, or None for a line that passes through.

Units: the file holds mm or inch (G20/G21) and deg for A, B, C; the state holds mm, rad and mm/min.
"""
from __future__ import annotations

import math
import os

import numpy as np

from ..errors import InputError
from ..machine import Machine
from ._arcs import arc_path, blind_arc, passed_spline, spline_code
from .blocks import CycleBlock, MotionBlock
from .controller_values import PROBE_G, held_block, probe_code
from .cycle_rules import (check_held_numbers, codes_with_motion, cycle_move, cycle_unclear,
                          has_axis_words, home_with_motion, incremental_r_level, retract_level,
                          rigid_tap, rotary_cycle)
from .dialect import GENERIC, beagleg_block, beagleg_word_order, grbl_program_end
from .directions import step_directions
from .frames import (FRAME_G, IDENTITY, apply_frame_code, check_arc, check_cycle, follow_given,
                     mode_change)
from .haas5 import HAAS_5AXIS_G, haas_block, haas_code
from .lengths import length_number, lone_h, set_length
from .linetext import text_with_words
from .height_map import height_map_code, passed_height_map
from .probe import beagleg_probe, passed_probe
from .programmed import ProgrammedOffsets, apply_g10
from .quill import follow_quill, forget_quill, has_quill, init_quill, quill_lost, tip_known
from .rrf import macro_codes, restore_move
from .single_direction import single_direction
from .word_use import check_motion_mode, check_point_words, check_value_words
from .words import (_AXIS_LETTERS, _CANNED_CYCLES, _CURVE_WITH_COORDINATES, KNOWN_DECIMAL_G, FANUC_CYCLES, FANUC_DIALECTS,
                    OTHER_WCS_G, mode_followed, _REFUSED_G, _REFUSED_M, _UNIQUE_LETTERS, _WCS_INDEX, DEFAULT_CHORD_TOL_MM,
                    MM_PER_INCH, TCP_OFF_M, TCP_ON_M, TOOL_AXIS, frame_code,
                    tokenize)

#: the codes whose axis words probe: uCNC's height map G39 (G39.1, G39.2 switch it), G38.2-G38.5
_PROBING_G = (39.0, 39.1, 39.2) + PROBE_G


class ModalState:
    """The machine's modal state while a program is read, and the interpreter of one block.

    motion : None (none yet / G80), 0, 1, 2 or 3. plane : 17, 18, 19. inch : G20 active.
    incremental : G91 active. feed : mm/min (nan until the first F). position : (na,) mm and rad.
    dirs : (na,) int8 approach directions. known : (na,) bool, the program has given the axis's
    position in its frame (see :class:`~.blocks.SegmentChunk`). wcs : active work coordinate system index
    (0 = G54). tool : active tool length number (G43 H; 0 = none). cycle : the drilling cycle in
    force (G81 ...) or None. inverse_time : G93 in force. dialect : the controller's rules
    (:class:`~.dialect.Dialect`), taken from ``path`` when it is a :class:`~.source.ProgramSource`
    (generic otherwise), which also names the source's lines in errors.
    """

    #: a move passed through with its end known (:mod:`.passed`) stands between the last block and
    #: the next: the next does not start where the last ended (its first row is a ``jump``)
    off_path = False
    #: a G43.1 of a value the controller holds is in force: the tool length, so the tip, is unknown
    #: and no block is corrected (:mod:`.controller_values`)
    length_unknown = False

    def __init__(self, machine: Machine, path=None, chord_tol: float = DEFAULT_CHORD_TOL_MM,
                 initial_position: np.ndarray | None = None, inch: bool = False,
                 initial_known=None):
        self.machine = machine
        self.path = None if path is None else os.fspath(path)
        self.dialect = getattr(path, "dialect", None) or GENERIC
        self._source = path
        self._locate = getattr(path, "locate", None)
        self.chord_tol = float(chord_tol)
        if not self.chord_tol > 0:
            raise ValueError("chord_tol_mm must be positive")
        self.names = machine.axis_names
        self.na = len(self.names)
        self.rotary = [n in "ABC" for n in self.names]
        self.home = (np.zeros(self.na) if initial_position is None
                     else np.asarray(initial_position, dtype=float).reshape(self.na).copy())
        self.position = self.home.copy()
        if initial_known is None:
            initial_known = initial_position is not None
        self.known = np.broadcast_to(np.asarray(initial_known, bool), (self.na,)).copy()
        #: approach direction per axis: +1, -1, 0 (not known before a move from a known position)
        self.dirs = np.zeros(self.na, np.int8)
        self.motion: int | None = None
        self.plane = 17
        #: G90.1 in force: arc centre words I J K are positions, not offsets from the start
        self.arc_absolute = False
        self.inch = bool(inch)
        self.incremental = False
        self.feed = math.nan
        #: the feed of the last G0-G3 move (mm/min, nan for a rapid)
        self.last_feed = math.nan
        self.wcs = 0
        self.tool = 0
        self.selected_tool = 0
        self.length_on = False          # G43/G44 in force (:mod:`.lengths`)
        self._init_cycles()
        self.inverse_time = False
        #: tool centre point mode (M428, G43.4, M128): the words are the tool tip in the workpiece
        #: frame and the rotary axes' angles (:mod:`.tcp`)
        self.tcp = False
        self.g234 = self.dwo = False        # Haas' G234 made the mode, G254 in force: .haas5
        self.f_word = math.nan
        self.tool_axis = self.names.index(TOOL_AXIS) if TOOL_AXIS in self.names else -1
        self.xyz_index = tuple(machine.index(c) if c in self.names else -1 for c in "XYZ")
        #: 90 / 91 if the last block interpreted carried G90 / G91, else None
        self.distance_word: int | None = None
        #: the last block was a G28/G30 with axis words (read in the distance mode in force)
        self.distance_sensitive = False
        #: the last block carried a G word (the output's motion mode is then re-stated)
        self.had_g = False
        #: the last block was a drilling cycle line (passed through)
        self.cycle_line = False
        #: G33.1 (rigid tapping) is the motion mode in force (``motion`` is then None); the line
        #: read carries G33.1
        self.tapping = False
        self.tap_line = False
        #: (why, line) when the line read moves the machine and passes through uncorrected: why
        #: 'increment' (G91 of an axis not known), 'home' (G28/G30, grbl's $H), 'machine' (G53),
        #: 'tap' (G33.1), 'jog' (grbl's $J=); else None
        self.passed_move = None
        #: cutter radius compensation (G41/G42) is in force; the line read switches it (G40-G42)
        self.cutter_comp = False
        self.cutter_comp_line = False
        #: work offsets the program sets itself (G10 L2/L20); their sets are numbered alike in
        #: every pass over one ProgramSource
        self.offsets = ProgrammedOffsets(self.na, path)
        self.ended = False      # an M2/M30 was read: no later line runs (docs/toolpaths.md)
        #: the frame the program moved itself (G52, G68, mirror, scaling: :mod:`.frames`), its changes
        #: by line (shared by the passes over one ProgramSource); none is left open after M2/M30
        self.local = IDENTITY
        table = getattr(path, "local_frames", None)
        self.local_frames = table if table is not None else []
        #: G92 (.frames): axes given since their last home move, 'G52'/'G92' shift, axes declared
        self.was_known = self.known.copy()
        self.shift_by, self.declared = "", []
        #: where TCP mode went on: line read -> code ('M428', 'G43.4', 'M128'), shared like these
        table = getattr(path, "tcp_switches", None)
        self.tcp_switches = table if table is not None else {}
        init_quill(self, path)          # the W quill's position (:mod:`.quill`)
        self._line = 0

    def _init_cycles(self) -> None:
        """The drilling cycles' state at the program's start."""
        self.cycle: int | None = None
        #: drilling cycles: G98/G99 in force (None: neither stated), the sticky R and Z words
        #: (mm, given in G91), the initial level of the series (mm, known)
        self.retract: int | None = None
        self.cycle_r: tuple[float, bool] | None = None
        self.cycle_z: tuple[float, bool] | None = None
        self.cycle_init: tuple[float, bool] = (math.nan, False)
        #: the last block began a series of drilling cycles
        self.cycle_start = False
        #: the group-01 motion mode in force when the drilling cycles began (G80 restores it
        #: where the dialect says so)
        self.cycle_motion: int | None = None
        #: the first rotary axis word of the series of cycles in force (None: none yet)
        self.cycle_rotary: str | None = None

    @property
    def frame(self) -> int:
        return frame_code(self.wcs, self.tool, self.tcp, self.offsets.index, not self.local.identity,
                          self.dwo)

    @property
    def python_only(self) -> bool:
        """Lines the compiled scanner must not take (cycle, inverse-time or tool centre point mode
        in force, the next block starts off the last one's path, the quill's place is lost, or the
        tool length is one the controller holds)."""
        return (self.cycle is not None or self.inverse_time or self.tcp or self.dwo or self.ended
                or bool(self.local.kind) or self.off_path or quill_lost(self) or self.length_unknown)

    def _err(self, msg, line):
        path, line, suffix = self._where(line)
        return InputError(msg + suffix, path, line)

    def _where(self, line):
        """(file, line, message suffix) naming a line: the source's for an expanded program."""
        if self._locate is None:
            return self.path, line, ""
        return self._locate(line)

    def _forget(self, idx=None):
        """The program's position of these axes (all by default) is unknown from here on."""
        if idx is None:
            self.known[:] = False
            forget_quill(self)
        elif idx >= 0:
            self.known[idx] = False

    def block(self, line: int, text: str) -> MotionBlock | None:
        """Interpret one line (text without line ending): its motion, or None. In the order errors
        are found: flags cleared, lines without words (all after M2/M30 but on grbl, which resets
        its modes and runs on) pass, words read, G/M codes change modes, axis words checked, feed
        set; then a home move, a drilling cycle or a motion block."""
        follow_given(self)
        self._clear_line_flags()
        self._line = line
        if self.ended and self.dialect.name == "grbl":
            grbl_program_end(self)
        held = getattr(self._source, "controller_lines", None)
        if held and line in held:       # read from its text with those words given 0
            text, self.held = held[line]
        text = None if self.ended else text_with_words(self, line, text)
        if text is None:
            return None
        try:
            tokens = tokenize(text, self.path, line)
        except InputError as exc:
            raise self._err(exc.message, line) from None
        if not tokens:
            return None
        values, gcodes, mcodes, number = self._read_words(tokens, line)
        if self.dialect.name == "beagleg":     # its words act in turn (dialect.py)
            beagleg_word_order(self, tokens, line)
            if 30.0 in gcodes:              # its Z probe (.probe)
                beagleg_probe(self, tokens, values, gcodes, line)
            beagleg_block(self, gcodes, line)
        self._cutter_comp_codes(gcodes)
        self.g60 = self.dialect.name == "fanuc" and 60.0 in gcodes  # single-direction positioning
        motion, nonmotion_axes, home_move, cycle = self._apply_codes(
            [g for g in gcodes if not (self.g60 and g == 60.0)], mcodes, values, tokens, line)
        if self.spline is not None:
            return passed_spline(self, values, tokens, motion, line)
        if self.tcp or self.dwo:
            haas_block(self, gcodes, motion, home_move, values, line)
        axes_given = self._axis_words(values, line)
        follow_quill(self, values, (motion, cycle, home_move), nonmotion_axes, line)
        check_value_words(self, tokens, gcodes, mcodes, motion, cycle, axes_given,
                          nonmotion_axes and home_move != 53, line)
        check_point_words(self, tokens, motion, cycle, axes_given, nonmotion_axes and home_move != 53, line)
        if home_move is not None and motion is not None and not home_with_motion(self.dialect.name, home_move, motion):
            raise self._err(f"G{home_move} and motion G{motion} in one block", line)
        self._set_feed(values, line)
        if held_block(self, gcodes, values, axes_given, motion, nonmotion_axes, line):
            return None
        if self.probe_line == line:         # BeagleG's G30 (.probe)
            return passed_probe(self, values, axes_given, motion, line)
        if self.map_line == line:           # uCNC's G39 (.height_map)
            return passed_height_map(self, values, axes_given, motion, line)
        if self.g60:
            return single_direction(self, values, axes_given, gcodes,
                                    (motion, cycle, home_move, nonmotion_axes), line)
        if nonmotion_axes:
            self.distance_sensitive = home_move in (28, 30) and bool(axes_given)
            if motion is not None:          # G53 G0 Z0 (a move in machine coordinates), G0 G50
                self.motion = motion        # (nothing moves): the mode holds for the blocks after
                self.cycle = None
            if home_move is not None:
                self._home_move(home_move, values, axes_given, line)
                if home_move != 53 or axes_given:
                    self.passed_move = ("machine" if home_move == 53 else "home", line)
            return None
        if motion is not None:
            self.motion = motion
            self.cycle = None
            self.tapping = False
        if self.tap_line or (self.tapping and self.motion is None and cycle is None
                             and self.cycle is None and axes_given):
            return rigid_tap(self, values, axes_given)
        self._set_cycle_mode(cycle, values)
        if self.cycle is not None and axes_given:
            b = self._cycle_block(line, values, axes_given, tokens, number)
        else:
            b = self._motion_block(line, values, axes_given, tokens, number)
        if b is not None:
            # as the writer keeps it whole: in force, or the line's own entry or exit move
            b.cutter_comp = self.cutter_comp or self.cutter_comp_line
        return b

    def _cutter_comp_codes(self, gcodes) -> None:
        """Follow G40 (off), G41/G42 (on; the last of them on the line counts)."""
        codes = [g for g in gcodes if g in (40.0, 41.0, 42.0)]
        self.cutter_comp_line = bool(codes)
        if codes:
            self.cutter_comp = codes[-1] != 40.0

    def _clear_line_flags(self) -> None:
        """Forget what the previous line said about itself (the flags the writer reads)."""
        self.distance_word = None
        self.distance_sensitive = False
        self.spline = None           # G5/G5.1 with coordinates on this line (._arcs.passed_spline)
        self.had_g = False
        self.cycle_line = False
        self.cycle_start = False
        self.tap_line = False
        self.passed_move = None
        self.g60 = False             # G60 on this line (.single_direction)
        self.probe_line = None       # BeagleG's G30 on this line (.probe)
        self.map_line = None         # uCNC's G39 on this line (.height_map)
        self.held = self.probing = None  # held words' letters, G38.x (.controller_values)
        #: how far G52 or a G10 moved the program's coordinates on this line (the writer follows)
        self.frame_shift = None
        self.declared = []

    def shift_frame(self, i: int, delta: float) -> None:
        """The program's coordinate of axis i moved by ``delta`` on this line, the machine still."""
        if self.frame_shift is None:
            self.frame_shift = np.zeros(self.na)
        self.frame_shift[i] += delta

    def _read_words(self, tokens, line: int) -> tuple[dict, list, list, str]:
        """(values, G codes, M codes, N word as written) of a line's tokens; a T word selects the
        tool. values : letter -> number of the words that may appear once (and H, L)."""
        values: dict[str, float] = {}
        gcodes: list[float] = []
        mcodes: list[float] = []
        number = ""
        for k, (letter, num, raw) in enumerate(tokens):
            if letter in "(;":
                continue
            if letter == "O" and any(t[0] not in "(;" for t in tokens[:k]):
                after = next((t[2] for t in reversed(tokens[:k]) if t[0] not in "(;"), "")
                why = (f"after the tool word {after}, a tool offset number on some controls, whose "
                       "rule mtcomp does not know" if after[:1] == "T" else "a letter O typed for a zero?")
                raise self._err(f"word {raw} inside a line (a program number O opens its line; "
                                f"{why})", line)
            try:
                v = float(num)
            except ValueError:  # pragma: no cover - the token pattern only lets numbers through
                raise self._err(f"garbled number in {raw!r}", line) from None
            if letter == "G":
                gcodes.append(v)
                continue
            if letter == "M":
                mcodes.append(v)
                continue
            if letter == "T":
                self.selected_tool = int(v)
            if letter in _UNIQUE_LETTERS:
                if letter in values:
                    raise self._err(f"word {letter} appears twice", line)
                values[letter] = v
                if letter == "N":
                    number = raw
            elif letter in "HL":
                values[letter] = v
        return values, gcodes, mcodes, number

    def _apply_codes(self, gcodes, mcodes, values, tokens, line: int):
        """Refuse the G and M codes mtcomp does not follow and set the modes the others change.

        Returns (motion code of the line or None, the axis words are no motion (G4, G28, G30,
        G53), the home move G28/G30/G53 or None, the drilling cycle code of the line or None).
        """
        # RepRapFirmware's macro codes and tool changes: their words are the macro's parameters
        macro = self.dialect.name == "rrf" and macro_codes(self, gcodes, mcodes, values, tokens, line)
        for m in mcodes:
            if m in _REFUSED_M:
                raise self._err(f"{_REFUSED_M[m]} is not supported", line)
            if m in TCP_ON_M or m in TCP_OFF_M:
                self._set_tcp(m in TCP_ON_M, f"M{m:g}")
        motion = home_move = cycle = None
        nonmotion_axes = macro     # G4 dwell (X/P is time), G28/G30/G53: axis words are no motion
        dwell = g10 = False
        frame_codes = []
        tool_change = any(m == 6 for m in mcodes)
        self.ended = any(m in (2, 30) for m in mcodes)
        self.had_g = bool(gcodes)
        for g in gcodes:
            gi = round(g)
            if g in FRAME_G:       # G52, G68/G69, mirror, scaling: their axis words are no motion
                frame_codes.append(g)
                nonmotion_axes = True
                continue
            if round(g, 1) in _PROBING_G:       # uCNC's height map, a probing move G38.x
                nonmotion_axes = self._probing_code(g, values, line) or nonmotion_axes
                continue
            if g in _REFUSED_G and not (g in FANUC_CYCLES and self.dialect.name in FANUC_DIALECTS):
                raise self._err(f"{_REFUSED_G[g]} is not supported", line)
            if g in _CURVE_WITH_COORDINATES:
                name, words = _CURVE_WITH_COORDINATES[g]
                if any(letter in words for letter, _num, _raw in tokens):
                    spline_code(self, g, name, line)
                    continue
            if g != gi:
                if round(g, 1) not in KNOWN_DECIMAL_G:
                    raise self._err(f"G{g:g} is not a code mtcomp follows (its effect on the motion "
                                    "cannot be known)", line)
                nonmotion_axes = self._apply_decimal_code(g, values, line) or nonmotion_axes
                continue
            if gi in (0, 1, 2, 3):
                if motion is not None:
                    raise self._err(f"two motion codes G{motion} and G{gi} in one block", line)
                motion = gi
            elif gi == 4:
                nonmotion_axes = dwell = True
            elif gi in (28, 30, 53):
                nonmotion_axes = True
                home_move = gi
            elif gi in _CANNED_CYCLES or gi in FANUC_CYCLES:
                cycle = gi
            elif gi == 10:
                nonmotion_axes = g10 = True          # the axis words are offsets
            else:
                if gi in OTHER_WCS_G and self.dialect.name != "haas":
                    raise self._err(f"G{gi} is not a code mtcomp follows on {self.dialect.name} "
                                    "(G110-G129 and G154 select Haas' additional work systems: "
                                    "give --dialect haas for a Haas program)", line)
                if gi in HAAS_5AXIS_G:
                    haas_code(self, gi, values, line)
                    continue
                if not mode_followed(gi, [t[0] for t in tokens]):
                    raise self._err(f"G{gi} is not a code mtcomp follows (its effect on the motion "
                                    "cannot be known)", line)
                self._apply_modal_code(gi, values)
        lone_h(self, gcodes, values)
        if nonmotion_axes and motion is not None and home_move is None:
            nonmotion_axes = codes_with_motion(self, motion, dwell, gcodes, tokens, line)
        if tool_change:
            self._forget(self.tool_axis)
            forget_quill(self, tool_change=True)
        if g10:
            apply_g10(self, values, tokens, line)
        for g in frame_codes:
            if (motion is not None and has_axis_words(values)) or home_move is not None or cycle is not None:
                raise self._err(f"G{g:g} and a move in one block is not supported", line)
            apply_frame_code(self, g, values, tokens, line)
        return motion, nonmotion_axes, home_move, cycle

    def _probing_code(self, g: float, values, line: int) -> bool:
        """uCNC's height map G39 (:mod:`.height_map`) or a probing move G38.x
        (:mod:`.controller_values`; on a Fanuc or Haas G38.x is no probe: refused)."""
        if round(g, 1) in PROBE_G:
            if self.dialect.name in FANUC_DIALECTS:
                raise self._err(f"{_REFUSED_G[g]} is not supported", line)
            return probe_code(self, g, line)
        return height_map_code(self, g, values, line)

    def _set_tcp(self, on: bool, code: str = "") -> None:
        """Tool centre point mode on or off (by the G or M ``code``): the words change meaning
        (tool tip against axis positions), so no position is known until the program names it
        again. Where it goes on, the line and the code are recorded (``tcp_switches``)."""
        if on != self.tcp:
            if on:
                mode_change(self, "tcp", self._line)
                self.tcp_switches[self._line] = code
            self.tcp = on
            self._forget()

    def _apply_decimal_code(self, g: float, values, line: int) -> bool:
        """A G code with a decimal part that is not refused: a work coordinate system G59.1-G59.3,
        or one that changes offsets the program's positions are given in (G92.1, G92.2, G43.1,
        G54.1: every axis unknown); the others (G28.1, G30.1 ...) change nothing followed here.
        True where the block's axis words are no motion: G43.1's are the tool's offsets."""
        if g in _WCS_INDEX:
            self._set_wcs(_WCS_INDEX[g])
        elif round(g, 1) == 33.1:
            self.tap_line = True
        elif round(g, 1) in (90.1, 91.1):          # arc centres absolute / incremental
            self.arc_absolute = round(g, 1) == 90.1
        elif round(g, 1) == 43.4:                # Fanuc's tool centre point control with H
            self.tool, self.length_on = length_number(self, values), True
            self._set_tcp(True, "G43.4")
        elif round(g, 1) in (28.1, 30.1, 92.1, 92.2, 43.1, 54.1):
            if round(g, 1) in (92.1, 92.2, 43.1, 54.1):
                if round(g, 1) != 43.1:
                    mode_change(self, "g92" if round(g) == 92 else "wcs", self._line)
                self._forget()
        return round(g, 1) == 43.1

    def _apply_modal_code(self, gi: int, values) -> None:
        """A whole G code that only changes a mode: plane, units, distance mode, feed mode, retract
        level, cycle cancel, work coordinate system, tool length (others change nothing here)."""
        if gi in (17, 18, 19):
            if gi != self.plane:
                mode_change(self, "plane", self._line)
            self.plane = gi
        elif gi == 20:
            self.inch = True
        elif gi == 21:
            self.inch = False
        elif gi == 90:
            self.incremental = False
            self.distance_word = 90
        elif gi == 91:
            self.incremental = True
            self.distance_word = 91
        elif gi == 93:
            self.inverse_time = True
        elif gi == 94:
            self.inverse_time = False
        elif gi in (98, 99):
            self.retract = gi
        elif gi == 80:
            self.tapping = False
            if not self.dialect.g80_keeps_motion:
                self.motion = None
            elif self.cycle is not None:
                self.motion = self.cycle_motion
            self.cycle = None
        elif gi in _WCS_INDEX:
            self._set_wcs(_WCS_INDEX[gi])
        elif gi in OTHER_WCS_G:
            mode_change(self, "wcs", self._line)
            self._forget()
        elif gi in (43, 44, 49):
            set_length(self, float(gi), values)
            if gi == 49:
                self._set_tcp(False)

    def _axis_words(self, values, line: int) -> list[str]:
        """The axis letters the line names (X Y Z A B C order); refuses axes the machine has not."""
        foreign = [c for c in "UVW" if c in values]
        refused = [c for c in foreign if c != "W" or not has_quill(self)]
        if refused and self.dialect.name in ("fanuc", "haas"):
            # on Fanuc and Haas lathes U and W are X and Z given incrementally, not other axes; a
            # W is a quill only where the machine file declares one (:mod:`.quill`)
            hint = ("; a boring mill's W quill: quill = true in the machine file's [axes.Z]"
                    if refused[0] == "W" and self.dialect.name == "fanuc" else "")
            raise self._err(f"axis word {refused[0]} on {self.dialect.name} (on its lathes U and "
                            f"W are incremental X and Z) is not supported{hint}", line)
        if foreign:
            self._note_foreign()
        axes_given = [c for c in _AXIS_LETTERS if c in values]
        for c in axes_given:
            if c not in self.names:
                raise self._err(f"axis word {c}: machine {self.machine.name} has no {c} axis "
                                f"(axes: {' '.join(self.names)})", line)
        return axes_given

    def _note_foreign(self) -> None:
        """U V W words (axes parallel to X Y Z that the machine model does not have, e.g. a quill
        W) pass through as written and uncorrected: said once, in the program's notes."""
        note = ("note: axis words U, V, W (axes the machine model does not have) pass through "
                "unchanged and uncorrected; " + (
                    "the model is evaluated with the tool tip at Z + W (a quill along Z) and at "
                    "the other axes' positions" if has_quill(self) else
                    "the other axes' corrections are those at their positions"))
        notes = getattr(self._source, "notes", None)
        if notes is not None and note not in notes:
            notes.append(note)

    def _set_feed(self, values, line: int) -> None:
        """An F word: the feed (mm/min), or under G93 the inverse time (1/min) of the block."""
        if "F" in values:
            if self.inverse_time:
                if not values["F"] > 0:
                    raise self._err(f"feed F must be positive, got {values['F']:g}", line)
                self.f_word = values["F"]
            else:
                f = values["F"] * (MM_PER_INCH if self.inch else 1.0)
                if not f > 0:
                    raise self._err(f"feed F must be positive, got {values['F']:g}", line)
                self.feed = f

    def _set_cycle_mode(self, cycle: int | None, values) -> None:
        """A drilling cycle code starts (or continues) the cycle mode; in it, R and Z are sticky."""
        if cycle is not None:
            if self.cycle is None:
                self.cycle_motion = self.motion
                self.cycle_start = True
                self.cycle_rotary = None
                z = self.tool_axis
                self.cycle_init = (float(self.position[z]), bool(self.known[z])) if z >= 0 \
                    else (math.nan, False)
            self.cycle = cycle
            self.motion = None
        if self.cycle is not None:
            scale = MM_PER_INCH if self.inch else 1.0
            if "R" in values:
                self.cycle_r = (values["R"] * scale, self.incremental)
            if "Z" in values:
                self.cycle_z = (values["Z"] * scale, self.incremental)

    def _motion_block(self, line, values, axes_given, tokens, number) -> MotionBlock | None:
        """The line's move in the motion mode in force (G0 to G3), or None when it does not move."""
        arc_words = [c for c in "IJKR" if c in values]
        is_motion = bool(axes_given) or (self.motion in (2, 3) and bool(arc_words))
        if self.dialect.name == "rrf" and self.motion in (0, 1) and "R" in values:
            return restore_move(self, values, axes_given, line)
        if not is_motion:
            if arc_words and self.cycle is None:
                raise self._err(f"{arc_words[0]} word outside an arc block", line)
            return None
        check_motion_mode(self, values, arc_words, line)
        if self.motion in (2, 3):
            check_arc(self, line)   # under unequal scales no circle on the machine: refused
            if blind_arc(self, values, axes_given):
                return None
        if self.incremental and self.motion in (0, 1) and \
                any(not self.known[self.names.index(c)] for c in axes_given):
            return self._blind_increment(values, axes_given)
        start = self.position.copy()
        end, given = self._targets(start, axes_given, values, line)
        raw_axes = {}
        if not self.incremental:
            raw_axes = {letter: raw for letter, _num, raw in tokens if letter in _AXIS_LETTERS}
        centre = None
        if self.motion in (2, 3):
            pts, centre = self._arc_block(start, end, values, tokens, line)
        else:
            pts = end[None, :]
        start_known = bool(self.known.all()) and not self.off_path
        self.off_path = False
        fresh = given & ~self.known
        self.known |= given
        dirs = self._directions(start, pts, fresh)
        # a circle of zero radius does not move: the tool stands as the last move left it
        still = centre is not None and pts.shape[0] == 1 and not np.any(pts[0] != start)
        feed = self.last_feed if still else self._block_feed(start, pts)
        self.last_feed = feed
        self.position = end
        words = [raw for letter, num, raw in tokens
                 if not (letter == "N" or letter in _AXIS_LETTERS or letter in "IJKR"
                         or (letter == "G" and float(num) in (0, 1, 2, 3, 90, 91)))]
        motion_word = any(letter == "G" and float(num) in (0, 1, 2, 3) for letter, num, _r in tokens)
        known = tip_known(self, self.known.copy())      # Z not known where the quill is lost
        return MotionBlock(line, self.motion, start, end, feed, pts, dirs, centre, self.plane,
                           self.inch, words, number, known, given, raw_axes, motion_word,
                           self.incremental, self.inverse_time and self.motion != 0, self.f_word,
                           self.frame, start_known=start_known,
                           absolute_centre=self.arc_absolute and centre is not None)

    def _blind_increment(self, values, axes_given) -> None:
        """An incremental G0/G1 move of an axis whose position the program has not given (a Haas
        ``G91 G0 Z-10.`` after ``G43 H01``, before any Z): the controller moves it from wherever
        it stands, so the line passes through uncorrected and that axis stays unknown; the known
        axes it names move by their increments, and every named axis's approach direction is the
        sign of its increment. The writer keeps the line incremental (``distance_sensitive``)."""
        scale = MM_PER_INCH if self.inch else 1.0
        start = self.position.copy()
        end = start.copy()
        for c in axes_given:
            i = self.names.index(c)
            end[i] += math.radians(values[c]) if c in "ABC" else values[c] * scale
        self._directions(start, end[None, :])
        self.position = end
        self.distance_sensitive = True
        self.passed_move = ("increment", self._line)
        return None

    def _targets(self, start, axes_given, values, line: int) -> tuple[np.ndarray, np.ndarray]:
        """(end (na,) mm and rad, given (na,) bool): where the named axes go (G90 or G91)."""
        end = start.copy()
        scale = MM_PER_INCH if self.inch else 1.0
        given = np.zeros(self.na, bool)
        for c in axes_given:
            i = self.names.index(c)
            if self.incremental and not self.known[i]:
                raise self._err(f"incremental (G91) move of axis {c}, whose position the program "
                                "has not given (at the start, or after a home move, tool change "
                                "or offset change)", line)
            v = math.radians(values[c]) if c in "ABC" else values[c] * scale
            end[i] = start[i] + v if self.incremental else v
            given[i] = True
        return end, given

    def _arc_block(self, start, end, values, tokens, line: int):
        """(chord ends (k, na), centre (3,) mm) of a G2/G3 move from a known position in its plane
        (one from a position not given passed through before it: :func:`._arcs.blind_arc`)."""
        # LinuxCNC's P turns: even P1 (the plain arc) is refused, since a corrected arc is written
        # as straight G1 chords, which may not carry a P word
        if any(letter == "P" for letter, _num, _raw in tokens):
            raise self._err(f"arc G{self.motion} with a P word (a number of turns) is not supported",
                            line)
        check_arc(self, line)
        return arc_path(self, start, end, values, line)

    def _block_feed(self, start, pts) -> float:
        """The block's feed, mm/min: nan for a rapid; under G93 its path length in X Y Z times the
        block's F (nan without motion in X Y Z)."""
        if self.motion == 0:
            return math.nan
        if self.inverse_time:
            path = np.vstack([start, pts])
            if self.local.kind:        # scaling: the machine's path is longer than the program's
                path = self.local.to_machine(path, self.xyz_index)
            length = float(np.sum(np.linalg.norm(np.diff(
                path[:, [i for i in self.xyz_index if i >= 0]], axis=0), axis=1)))
            return length * self.f_word if length > 0 else math.nan
        return self.feed

    def _set_wcs(self, index: int):
        if index != self.wcs:
            mode_change(self, "wcs", self._line)
            self.wcs = index
            self._forget()

    def _cycle_block(self, line, values, axes_given, tokens, number) -> MotionBlock | None:
        """A drilling cycle line. Where the hole is clear (X, Y, the R plane and the bottom known,
        plane G17) it becomes a :class:`CycleBlock` whose points are the bottoms of its holes;
        otherwise it passes through uncorrected (G90) or is refused (G91: an incremental cycle
        passed through would be read against an absolute output)."""
        check_cycle(self, line)
        inc = self.incremental
        reason = rotary_cycle(self, axes_given) or cycle_unclear(self, inc)
        xi, yi, zi = self.xyz_index
        if reason is None and not inc and not all(self.known[i] or c in values
                                                  for i, c in ((xi, "X"), (yi, "Y"))):
            reason = "its X or Y position is not known"
        if reason is not None:
            if inc:
                raise self._err(f"incremental (G91) drilling cycle G{self.cycle}: {reason}", line)
            check_held_numbers(self, values, reason, line)
            cycle_move(self, values, axes_given)
            return None
        scale = MM_PER_INCH if self.inch else 1.0
        # the repeat count: L (LinuxCNC, Haas, Siemens ISO mode); K on Fanuc, but only where the
        # line has no L and no I/J (Haas G73/G83 write I J K as first peck, peck reduction and
        # minimum peck)
        count_letter = "L" if "L" in values else (
            "K" if "K" in values and "I" not in values and "J" not in values else None)
        reps = values.get(count_letter, 1.0) if count_letter else 1.0
        if reps != int(reps) or reps < 1:
            raise self._err(f"drilling cycle repeat count {reps:g} is not supported (a whole number "
                            ">= 1)", line)
        reps = int(reps)
        start = self.position.copy()
        start_known = bool(self.known.all()) and not self.off_path
        self.off_path = False
        if inc:
            r_level = incremental_r_level(self, start[zi], line)
            z_bottom = r_level + self.cycle_z[0]
            steps = np.arange(1, reps + 1)
            xs = start[xi] + steps * values.get("X", 0.0) * scale
            ys = start[yi] + steps * values.get("Y", 0.0) * scale
        else:
            r_level, z_bottom = self.cycle_r[0], self.cycle_z[0]
            xs = np.array([values["X"] * scale if "X" in values else start[xi]])
            ys = np.array([values["Y"] * scale if "Y" in values else start[yi]])
        pts = np.repeat(start[None, :], xs.shape[0], axis=0)
        pts[:, xi], pts[:, yi], pts[:, zi] = xs, ys, z_bottom
        given = np.zeros(self.na, bool)
        given[[xi, yi, zi]] = True
        known = self.known | given
        dirs = self._directions(start, pts, given & ~self.known)
        z_after, z_known = retract_level(self, r_level)
        end = pts[-1].copy()
        end[zi] = z_after
        self.dirs[zi] = 1                  # the retract moves Z up last
        self.position = end
        self.known = known.copy()
        self.known[zi] = z_known
        feed = self.feed
        info = CycleBlock(self.cycle, r_level, z_bottom, self.retract, self.cycle_start, inc,
                          [t for t in tokens if t[0] != "N"],
                          frozenset(c for c in "XYZR" if c in values), z_known, count_letter)
        return MotionBlock(line, self.cycle, start, end, feed, pts, dirs, None, self.plane,
                           self.inch, [], number, known, given, {}, True, inc, False, self.f_word,
                           self.frame, info, start_known)

    def _home_move(self, g, values, axes_given, line):
        """G28/G30: named axes (all without any) go home; G53: named axes go to a machine position.
        Either way the program's frame no longer knows where they are. In Fanuc's tool centre
        point mode (G43.4) refused: what the mode does at the home move is not determined here."""
        code = "G234" if self.g234 else list(self.tcp_switches.values())[-1:] == ["G43.4"] and "G43.4"
        if self.tcp and (g != 53 or axes_given) and code:
            raise self._err(f"G{g:g} in tool centre point mode ({code}) is not supported: cancel the "
                            "mode with G49 before the move (the mode's axes at a reference "
                            "position or machine position are not determined here)", line)
        new = self.position.copy()
        idx = [self.names.index(c) for c in axes_given]
        for i in idx:
            if g != 53:
                new[i] = self.home[i]
            self.known[i] = False
        if g != 53 and not axes_given and "W" not in values:    # alone: every axis goes home
            new = self.home.copy()
            self._forget()
        self.dirs = self._directions(self.position, new[None, :])[-1]
        self.position = new

    def _directions(self, start: np.ndarray, pts: np.ndarray, fresh=None) -> np.ndarray:
        """(k, na) int8 approach directions at the end of each segment, of the machine's axes (under
        G68 or a mirror image the program's steps turned onto them: :func:`~.directions.step_directions`);
        updates self.dirs. ``fresh``: axes moving from a position not given, whose direction is not
        known (0) until their next."""
        if self.local.kind:
            start = self.local.to_machine(start[None, :], self.xyz_index)[0]
            pts = self.local.to_machine(pts, self.xyz_index)
        out = step_directions(self.dirs, start, pts, fresh)
        self.dirs = out[-1].copy()
        return out

"""Work offsets a program sets itself: G10 L2 and G10 L20 (programmable data input).

``G10 L2 P- X- Y- ...`` sets the origin of work coordinate system P (1 = G54 ... 9 = G59.3) to the
given machine positions, axis by axis (axes not named keep their offset); ``G10 L20 P- X- ...``
sets it so that the current position reads the given values in that system (LinuxCNC G-code
reference, G10 L2 and G10 L20; Fanuc Series 0i-MF operator's manual, "Changing workpiece
coordinate system" by G10 L2; Haas mill operator's manual, G10 Set Offsets). The values are in the
program's units (G20/G21), degrees for rotary axes. Where the controllers differ, the line is
refused unless the program's dialect is LinuxCNC or grbl (grbl follows LinuxCNC here: P0 is the
active system, the values are set whatever the distance mode, L20 as above; grbl 1.1 source,
gcode.c, "L20: Update coordinate system axis at current position"):

* ``P0``: LinuxCNC's active system; on Fanuc the external work offset that shifts every system.
* under G91: LinuxCNC ignores G91 for G10; Fanuc adds the values to the offsets in force.
* ``L20``: LinuxCNC as above; on Fanuc the additional work offsets G54.1 P1-P48.

The line itself moves nothing and passes through unchanged. From it on, the blocks of that system
are placed on the machine with the offsets the program set (:class:`~.offsets.ProgramSetup`
applies them where the command line's work offsets would apply), so the corrections stay
referenced to the program's own work-offset origin. The program's position in the active system
changes with its offset: an axis whose old offset the program had set moves by the difference, an
axis whose old offset came from outside the program becomes unknown (never written until the
program names it again); after L20 the named axes read the given values. An L20 where the program
has not given the position (after homing) is a touch-off: its offset comes from outside the program
(the command line's, as for an offset the program never set), said once in a note; one where the
program has lost a position it had given (a tool change, another work system) is refused, as G92
there (the compensated program stands off by a correction the controller may or may not have
moved away from).

The compensated program's G10 L20 line is the source's, read where the *corrected* tool stands:
at a known position its offset differs from the source's by the correction there, and every later
block of that system would be placed off by it. So each G10 line is recorded (``offset_writes``:
the system and, per axis, 1 set where the tool stands, 2 set to a given value) and
:meth:`~.offsets.ProgramSetup.written` takes that correction back from the words written in that
system, as for G92 (:mod:`.frames`).
"""
from __future__ import annotations

import math
import threading

import numpy as np

from .frames import record
from .words import MAX_OFFSET_SETS, MM_PER_INCH, WORK_SYSTEMS


_SETS_LOCK = threading.Lock()


class ProgrammedOffsets:
    """The work offsets the program has set so far, and the distinct sets of them in order.

    current : wcs index (0 = G54) -> (na,) offset, mm and rad, nan where the program has not set
    that axis. sets : the distinct states of ``current`` met so far (shared by every reader of one
    :class:`~.source.ProgramSource`, so that a frame code names the same set in each pass).
    index : the set in force (0: the program has set none; k: ``sets[k - 1]``). writes : what
    each G10 line did, ``(line, (wcs, codes))`` with codes (na,) per axis 0 (not named), 1 (L20 at
    a known position: set where the tool stands), 2 (L2, or a touch-off: set to a value given);
    shared like ``sets`` (``source.offset_writes``). at_tool : wcs -> (na,) bool, the axes whose
    offset an L20 at a known position set last.
    """

    def __init__(self, na: int, source=None):
        self.na = na
        self.current: dict[int, np.ndarray] = {}
        sets = getattr(source, "work_offset_sets", None)
        self.sets = sets if sets is not None else []
        writes = getattr(source, "offset_writes", None)
        self.writes = writes if writes is not None else []
        self.at_tool: dict[int, np.ndarray] = {}
        self.index = 0

    def offset(self, wcs: int, axis: int) -> float:
        """The offset of one axis of one system as the program set it (nan: not set)."""
        v = self.current.get(wcs)
        return math.nan if v is None else float(v[axis])

    def assign(self, wcs: int, values: dict) -> bool:
        """Set axes (index -> mm or rad) of system ``wcs``; False when more than MAX_OFFSET_SETS
        distinct sets would be needed."""
        vec = self.current.get(wcs, np.full(self.na, np.nan)).copy()
        for i, v in values.items():
            vec[i] = v
        self.current[wcs] = vec
        key = _key(self.current)
        # the sets are shared by the passes over one program (compensate reads it in one thread
        # and writes it in another): find-or-append at once, so both number a set alike
        with _SETS_LOCK:
            for k, known in enumerate(self.sets):
                if _key(known) == key:
                    self.index = k + 1
                    return True
            if len(self.sets) >= MAX_OFFSET_SETS:
                return False
            self.sets.append({w: v.copy() for w, v in self.current.items()})
            self.index = len(self.sets)
        return True


def _key(table: dict) -> tuple:
    return tuple(sorted((w, tuple(None if math.isnan(x) else round(x, 12) for x in v))
                        for w, v in table.items()))


def apply_g10(state, values: dict, tokens, line: int) -> None:
    """Interpret a G10 line on ``state`` (a :class:`~.modal.ModalState`): L2 and L20 set work
    offsets (see the module docstring); every other G10 (tool table, parameters) is refused."""
    dialect = state.dialect.name
    level = values.get("L")
    if level not in (2.0, 20.0):
        what = "no L word" if level is None else f"L{level:g}"
        raise state._err(f"G10 {what} (programmable data input other than work offsets L2/L20: "
                         "tool table or parameters) is not supported", line)
    level = int(level)
    p_words = [float(num) for letter, num, _raw in tokens if letter == "P"]
    if len(p_words) != 1 or p_words[0] != int(p_words[0]) or not 0 <= p_words[0] <= 9:
        raise state._err(f"G10 L{level} needs one P word 0-9 (the work coordinate system)", line)
    p = int(p_words[0])
    if values.get("R", 0.0) != 0.0:
        raise state._err(f"G10 L{level} with R (a rotation of the work coordinate system) is not "
                         "supported", line)
    if dialect not in ("linuxcnc", "grbl"):
        if p == 0:
            raise state._err(f"G10 L{level} P0: the active system on LinuxCNC, the external work "
                             f"offset on Fanuc (dialect {dialect}; give --dialect linuxcnc if "
                             "LinuxCNC runs it)", line)
        if state.incremental:
            raise state._err(f"G10 L{level} under G91: LinuxCNC sets the offsets, Fanuc adds to them "
                             f"(dialect {dialect}; give --dialect linuxcnc if LinuxCNC runs it)", line)
        if level == 20:
            raise state._err("G10 L20: LinuxCNC's offset set from the current position, Fanuc's "
                             f"additional work offsets G54.1 (dialect {dialect}; give --dialect "
                             "linuxcnc if LinuxCNC runs it)", line)
    wcs = state.wcs if p == 0 else p - 1
    scale = MM_PER_INCH if state.inch else 1.0
    given = {state.names.index(c): (math.radians(values[c]) if c in "ABC" else values[c] * scale)
             for c in "XYZABC" if c in values and c in state.names}
    new = dict(given) if level == 2 else _l20_offsets(state, given, wcs, line)
    codes = _record_write(state, wcs, [1 if level == 20 and state.known[i] else 2 for i in given],
                          list(given), line)
    if wcs == state.wcs:
        state.position = state.position.copy()        # the last block holds the old array
        for i, v in new.items():
            old = state.offsets.offset(wcs, i)
            if level == 20:
                if state.known[i]:
                    state.shift_frame(i, given[i] - state.position[i])
                    state.declared.append(i)      # the output's axis reads the value too
                state.position[i] = given[i]
                state.known[i] = True
            elif math.isnan(old) or codes[1][i]:
                # an offset from outside, or one an L20 set where the tool stood: the output's
                # position in the system is not the source's plus a correction the writer knows
                state.known[i] = False
            else:
                state.position[i] += old - v
                state.shift_frame(i, old - v)
    if not state.offsets.assign(wcs, new):
        raise state._err(f"G10: the program sets more than {MAX_OFFSET_SETS} different sets of work "
                         "offsets (not followed)", line)


def _record_write(state, wcs: int, codes: list, axes: list, line: int) -> tuple:
    """Record what a G10 line does to system ``wcs`` (``codes`` of the ``axes`` named: 1 set where
    the tool stands, 2 set to a value given); returns (the recorded codes (na,), the axes whose
    old offset an L20 at a known position had set)."""
    offsets = state.offsets
    full = np.zeros(offsets.na, np.int8)
    full[axes] = codes
    at_tool = offsets.at_tool.setdefault(wcs, np.zeros(offsets.na, bool))
    before = at_tool.copy()
    at_tool[axes] = full[axes] == 1
    if axes:
        record(offsets.writes, line, (wcs, tuple(full.tolist())))
    return full, before


def _l20_offsets(state, given: dict, wcs: int, line: int) -> dict:
    """The offsets (axis index -> mm or rad, nan: from outside the program) G10 L20 sets in system
    ``wcs``: the machine position less the value (grbl 1.1 gcode.c: the current position in machine
    coordinates less the programmed value; LinuxCNC likewise). Where the program has not given the
    axis's position (after homing, a home move or a tool change) the controller's offset there is
    a touch-off, as an operator's at the panel: it comes from outside the program, as an offset the
    program never set (the command line's, said once in a note). A known position in a system
    whose offset came from outside would give that outside offset shifted: refused."""
    new, touched = {}, []
    for i, v in given.items():
        old = state.offsets.offset(state.wcs, i)
        if not state.known[i]:
            if state.was_known[i]:
                raise state._err(f"G10 L20 {state.names[i]} where the program has lost the position "
                                 f"of {state.names[i]} after giving it (a tool change, a change of "
                                 "work system or offset: the compensated program stands off there "
                                 "by a correction not known) is not supported (move "
                                 f"{state.names[i]} first, or home it)", line)
            new[i] = math.nan
            touched.append(state.names[i])
            continue
        if math.isnan(old):
            raise state._err(f"G10 L20 on axis {state.names[i]}: the active system's offset "
                             f"({WORK_SYSTEMS[state.wcs]}) comes from outside the program (the "
                             "command line's), and the new one would be that offset shifted by "
                             f"{state.position[i] - v:.6g} mm (not followed: set the offset with G10 L2 "
                             "or give the position after homing)", line)
        new[i] = state.position[i] + old - v          # the machine position less the value
    if touched:
        _note_touch_off(state, wcs, touched, line)
    return new


def _note_touch_off(state, wcs: int, axes: list, line: int) -> None:
    """Say once, in the program's notes, that a G10 L20 offset is taken from the command line."""
    notes = getattr(state._source, "notes", None)
    if notes is None:
        return
    name = WORK_SYSTEMS[wcs]
    where = state._where(line)[1]
    note = (f"note: G10 L20 at line {where} sets {name} {' '.join(axes)} where the program has not "
            "given the position (a touch-off, as after homing): that offset is taken as given on "
            f"the command line (--work-offset {name}=..., or --offsets)")
    if note not in notes:
        notes.append(note)

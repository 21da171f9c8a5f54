"""Frame changes a program makes itself: G52 local shift, G68 rotation, mirror images, scaling.

A program's X Y Z are positions in its own frame; under these codes the controller places them on
the machine through a map of its own (docs/toolpaths.md, "Frame changes", cites each controller's
manual):

* ``G52 X Y Z`` (LinuxCNC, Fanuc): the local coordinate system, shifted by the given amounts from
  the work system's origin; ``G52 X0 Y0 Z0`` cancels it. Nothing moves: the program's position of
  the named axes changes by the shift, and stays known.
* ``G92 X Y Z`` (every dialect): the named axes' current positions declared to have the given
  coordinates, by an offset of every work system; ``G92.1``/``G92.2`` cancel it. A known position
  gives the offset exactly (the old position less the value: the same shift as a G52 of that
  amount, and on LinuxCNC the same offset); at a position the program has not given, the offset is
  assumed 0 (as an unstated work offset), said once in the notes. The compensated program's
  G92 line is the source's, so its offset is set where the *corrected* tool stands: off by the
  correction there, which the written words after it take back
  (:class:`~.offsets.OutputShifts`).
* ``G68 X Y R`` (Fanuc, Haas; G17 only): the program's X Y turned by R degrees counter-clockwise
  about the centre X Y (the current position where the block gives none); ``G69`` cancels it.
* ``G51.1 X Y Z`` / ``G50.1`` (Fanuc) and ``G101`` / ``G100`` (Haas): the named axes mirrored about
  the given position (Haas: about the work zero).
* ``G51 X Y Z P`` (Fanuc, Haas) or ``G51 X Y Z I J K`` (Fanuc): X Y Z scaled about the centre X Y Z
  by P (each axis by its own I J K); ``G50`` cancels it.

The map is affine on X Y Z: ``machine = M (p - centre) + centre + shift`` (:class:`LocalFrame`), M
a rotation, a diagonal of signs or of scales. The correction the model gives in the machine's frame
(c) is written in the program's frame as ``M^-1 c``: turned back, of opposite sign on a mirrored
axis, divided by the scale. At most one of rotation, mirror and scaling is in force at a time (their
order of composition differs between controllers), with or under a G52 shift.

Which frame is in force at a row of a :class:`~.blocks.SegmentChunk` is told by its frame code (the
bit :data:`~.words.LOCAL_FRAME`) and, for the map itself, by the line: the reader records each
change with its line in a table shared by every pass over one program
(``ProgramSource.local_frames``), and :func:`frames_of_rows` looks the rows' lines up in it.
"""
from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field

import numpy as np

from .words import MM_PER_INCH, number_decimals

_LOCK = threading.Lock()


@dataclass(frozen=True)
class LocalFrame:
    """The map of the program's frame onto the work system: X Y Z only (rotary axes untouched).

    shift : (3,) mm, the G52 shift of X Y Z. kind : '' (a shift alone), 'rotation', 'mirror' or
    'scale'. matrix : (3, 3) the linear part M. centre : (3,) mm, its fixed point (program frame).
    """

    shift: tuple = (0.0, 0.0, 0.0)
    kind: str = ""
    matrix: tuple = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
    centre: tuple = (0.0, 0.0, 0.0)
    mirrored: tuple = (False, False, False)
    #: what the line that set this frame did to the shared offset of X Y Z in the *output*, where
    #: it differs from the program's (G92 at a known position): 0 nothing, 1 set from where the
    #: tool stands (the output stands off by the correction there), 2 set to a given value (G52,
    #: G92 at a position not given, G92.1/G92.2: the output's offset is the program's)
    g92: tuple = (0, 0, 0)
    _m: np.ndarray = field(default=None, repr=False, compare=False)

    def __post_init__(self):
        object.__setattr__(self, "_m", np.array(self.matrix, dtype=float))

    @property
    def identity(self) -> bool:
        return self.kind == "" and not any(self.shift)

    def to_machine(self, pts: np.ndarray, xyz) -> np.ndarray:
        """(m, na) program-frame positions -> work-system positions (mm, rad; X Y Z at ``xyz``)."""
        out = np.array(pts, dtype=float)
        idx = list(xyz)
        p = out[:, idx]
        if self.kind:
            c = np.asarray(self.centre)
            p = (p - c) @ self._m.T + c
        out[:, idx] = p + np.asarray(self.shift)
        return out

    def to_program(self, pts: np.ndarray, xyz) -> np.ndarray:
        """The inverse of :meth:`to_machine`: a machine correction c comes back as ``M^-1 c``."""
        out = np.array(pts, dtype=float)
        idx = list(xyz)
        p = out[:, idx] - np.asarray(self.shift)
        if self.kind:
            c = np.asarray(self.centre)
            p = np.linalg.solve(self._m, (p - c).T).T + c
        out[:, idx] = p
        return out

    def scales(self) -> np.ndarray:
        """(3,) the scale of each of X Y Z (1 without scaling)."""
        return np.abs(np.diag(self._m)) if self.kind == "scale" else np.ones(3)


IDENTITY = LocalFrame()


def record(table: list, line: int, frame: LocalFrame) -> None:
    """Record that ``frame`` is in force from ``line`` on (lines of the file read). Every pass over
    one program records the same changes at the same lines: a line at or before the last one
    recorded is there already (compensate reads the program in one thread and writes it in
    another)."""
    with _LOCK:
        if not table or line > table[-1][0]:
            table.append((line, frame))


def frames_of_rows(table: list, lines: np.ndarray) -> list[tuple[LocalFrame, np.ndarray]]:
    """[(frame, rows)]: the frame in force at each row, by the row's line (rows before any change:
    none listed)."""
    snapshot = list(table)
    if not snapshot:
        return []
    starts = np.array([entry[0] for entry in snapshot], np.int64)
    which = np.searchsorted(starts, np.asarray(lines, np.int64), side="right") - 1
    out = []
    for k in np.unique(which[which >= 0]).tolist():
        frame = snapshot[k][1]
        if not frame.identity:
            out.append((frame, which == k))
    return out


def placed_by_frames(table: list, local: np.ndarray, lines: np.ndarray, pts: np.ndarray,
                     xyz: list) -> np.ndarray:
    """(n, na) the rows' program positions ``pts`` placed by the frame in force at each (the rows
    ``local`` marks, looked up by their ``lines`` in ``table``: :func:`frames_of_rows`), in the work
    system; ``xyz`` the columns of X, Y, Z."""
    out = np.array(pts, dtype=float)
    for frame, rows in frames_of_rows(table, lines):
        rows = rows & local
        out[rows] = frame.to_machine(out[rows], xyz)
    return out


# ------------------------------------------------------------------------- the reader's side
class FrameCodes:
    """The frame codes of one line, read for one :class:`~.modal.ModalState` (``state``): what the
    dialect has, what the manuals leave open (refused), and the new frame."""

    def __init__(self, state, values: dict, tokens, line: int):
        self.s = state
        self.values = dict(values)
        for letter, num, _raw in tokens:       # P (G51's scale) is not among the block's values
            if letter == "P":
                self.values["P"] = float(num)
        self.tokens = tokens
        self.line = line
        self.scale = MM_PER_INCH if state.inch else 1.0
        self.axes = [c for c in "XYZABC" if c in values]

    def err(self, msg: str):
        return self.s._err(msg, self.line)

    def refuse_other_axes(self, name: str, allowed: str = "XYZ") -> None:
        bad = [c for c in self.axes if c not in allowed]
        if bad:
            raise self.err(f"{name} with a word {bad[0]} is not supported")

    def check_common(self, name: str) -> None:
        """Refused everywhere: a frame change in tool centre point mode, in a drilling cycle's
        mode, or on a machine without X, Y and Z (each code checks the frame in force itself)."""
        if self.s.tcp or getattr(self.s, "dwo", False):
            raise self.err(f"{name} in tool centre point mode is not supported" if self.s.tcp else
                           f"{name} under G254 (dynamic work offset) is not supported")
        if self.s.cycle is not None:
            raise self.err(f"{name} while a drilling cycle is in force (give G80 first) is not "
                           "supported")
        if min(self.s.xyz_index) < 0:
            raise self.err(f"{name} on a machine without X, Y and Z is not supported")

    def g52(self, cur: LocalFrame) -> LocalFrame:
        d = self.s.dialect
        if not d.local_shift:
            hint = (" (its meaning follows Setting 33: a work system of its own in HAAS mode, a "
                    "local shift in FANUC mode; give --dialect fanuc if Setting 33 is FANUC)"
                    if d.name == "haas" else
                    " (give --dialect linuxcnc or fanuc if one of them runs the program)")
            raise self.err(f"G52 (local coordinate system) is not supported on {d.name}{hint}")
        self.check_common("G52")
        if cur.kind:
            raise self.err("G52 while G68, a mirror image or scaling is in force (the order of the "
                           "two is not followed) is not supported")
        if self.s.incremental:
            raise self.err("G52 under G91 (whether its values add to the shift differs between "
                           "controllers) is not supported")
        self.refuse_other_axes("G52")
        if not self.axes:
            raise self.err("G52 without axis words is not supported")
        if self.s.shift_by == "G92" and d.name != "linuxcnc":
            raise self.err("G52 while a G92 offset is in force (LinuxCNC shares their offsets; "
                           f"how {d.name} composes them is not followed) is not supported")
        shift, codes = list(cur.shift), [0, 0, 0]
        self.s.position = self.s.position.copy()     # the last block's end is not moved with it
        for k, c in enumerate("XYZ"):
            if c in self.values:
                new = self.values[c] * self.scale
                i = self.s.xyz_index[k]
                # nothing moves: the program's position of the axis changes by the shift
                self.s.position[i] -= new - shift[k]
                self.s.shift_frame(i, shift[k] - new)
                shift[k] = new
                codes[k] = 2
        self.s.shift_by = "G52" if any(shift) else ""
        return LocalFrame(tuple(shift), g92=tuple(codes))

    def g92(self, cur: LocalFrame) -> LocalFrame:
        """G92: the named axes' positions declared (nothing moves). A known position moves the
        offset by the old position less the value; one the program has not given is assumed to
        have offset 0 (its program coordinate taken as the machine's, plus the work offset)."""
        s = self.s
        self.check_common("G92")
        if cur.kind:
            raise self.err("G92 while G68, a mirror image or scaling is in force (the order of the "
                           "two is not followed) is not supported")
        if s.incremental:
            raise self.err("G92 under G91 (whether its values are increments differs between "
                           "controllers) is not supported")
        self.refuse_other_axes("G92")
        if not self.axes:
            raise self.err("G92 without axis words is not supported")
        if s.shift_by == "G52" and s.dialect.name != "linuxcnc":
            raise self.err(f"G92 while G52 is in force (LinuxCNC shares their offsets; how "
                           f"{s.dialect.name} composes them is not followed) is not supported")
        shift, codes, assumed = list(cur.shift), [0, 0, 0], []
        s.position = s.position.copy()     # the last block's end is not moved with it
        for k, c in enumerate("XYZ"):
            if c not in self.values:
                continue
            i, new = s.xyz_index[k], self.values[c] * self.scale
            if s.known[i]:
                s.shift_frame(i, new - s.position[i])
                shift[k] += s.position[i] - new
                codes[k] = 1
            elif s.was_known[i]:
                raise self.err(f"G92 {c} where the program has lost the position of {c} after "
                               "giving it (a tool change, a change of work system or offset: the "
                               "compensated program stands off there by a correction not known) "
                               f"is not supported (move {c} first, or home it)")
            else:
                shift[k], codes[k] = 0.0, 2
                s.known[i] = True
                assumed.append(c)
            s.position[i] = new
            s.declared.append(i)
        if assumed:
            _note_assumed(s, assumed, self.line)
        s.shift_by = "G92"
        return LocalFrame(tuple(shift), g92=tuple(codes))

    def g68(self, cur: LocalFrame) -> LocalFrame:
        s = self.s
        if not s.dialect.rotation:
            raise self.err(f"G68 (coordinate rotation) is not supported on {s.dialect.name} (give "
                           "--dialect fanuc or haas if one of them runs the program)")
        self.check_common("G68")
        if cur.kind == "rotation":
            raise self.err("G68 while a rotation is in force (give G69 first) is not supported")
        if cur.kind:
            raise self.err(f"G68 while {'a mirror image' if cur.kind == 'mirror' else 'scaling'} "
                           "is in force (the order of the two differs between controllers) is not "
                           "supported")
        if any(c in self.values for c in "IJK"):
            raise self.err("G68 with I J K (three-dimensional coordinate conversion) is not "
                           "supported")
        if s.plane != 17:
            raise self.err(f"G68 in plane G{s.plane} (only G17 is followed) is not supported")
        if s.incremental:
            raise self.err("G68 under G91 (whether R adds to the rotation is a controller setting: "
                           "Fanuc parameter 5400, Haas Setting 73) is not supported")
        if "R" not in self.values:
            raise self.err("G68 without R (the angle is then a controller setting) is not "
                           "supported")
        self.refuse_other_axes("G68", "XY")
        centre = self._centre("G68", "XY")
        c, sn = _cos_sin(self.values["R"])
        m = ((c, -sn, 0.0), (sn, c, 0.0), (0.0, 0.0, 1.0))
        self._forget("XY")
        return LocalFrame(cur.shift, "rotation", m, (centre[0], centre[1], 0.0))

    def _centre(self, name: str, letters: str) -> list[float]:
        """The centre words (mm) of X Y (Z), the current position where the block gives none
        (it must be known then); a centre given on some axes only is refused."""
        s = self.s
        given = [c for c in letters if c in self.values]
        if given and len(given) != len(letters):
            raise self.err(f"{name} with a centre on {' '.join(given)} only (give "
                           f"{' '.join(letters)} or none) is not supported")
        out = []
        for c in letters:
            i = s.xyz_index["XYZ".index(c)]
            if c in self.values:
                out.append(self.values[c] * self.scale)
            elif not s.known[i]:
                raise self.err(f"{name} without a centre, at a position the program has not given "
                               f"(axis {c}) is not supported")
            else:
                out.append(float(s.position[i]))
        return out

    def _forget(self, letters: str) -> None:
        """The axes the frame change acts on are unknown until the program names them: the
        controller's current position in the new frame is not the program's (Fanuc: an incremental
        move after G68 turns about the position G68 was given at)."""
        for c in letters:
            self.s._forget(self.s.xyz_index["XYZ".index(c)])

    def g69(self, cur: LocalFrame) -> LocalFrame:
        if cur.kind != "rotation":
            return cur
        if self.axes:
            raise self.err("G69 with axis words in its block is not supported")
        self._forget("XY")
        return LocalFrame(cur.shift)

    def mirror(self, g: float, cur: LocalFrame) -> LocalFrame:
        s = self.s
        name = "G51.1" if g == 51.1 else "G101"
        if s.dialect.mirror != name:
            raise self.err(f"{name} (mirror image) is not supported on {s.dialect.name} (give "
                           f"--dialect {'fanuc' if g == 51.1 else 'haas'} if "
                           f"{'a Fanuc' if g == 51.1 else 'a Haas'} runs the program)")
        self.check_common(name)
        if cur.kind in ("rotation", "scale"):
            raise self.err(f"{name} while {'G68' if cur.kind == 'rotation' else 'scaling'} is in "
                           "force (the order of the two differs between controllers) is not "
                           "supported")
        self.refuse_other_axes(name)
        if not self.axes:
            raise self.err(f"{name} without axis words is not supported")
        if s.incremental and g == 51.1:
            raise self.err("G51.1 under G91 is not supported")
        signs = list(cur.mirrored)
        centre = list(cur.centre)
        for k, c in enumerate("XYZ"):
            if c in self.values:
                v = self.values[c] * self.scale
                if name == "G101" and v != 0.0:
                    raise self.err(f"G101 {c}{self._raw(c)} (Haas mirrors about the work zero; a "
                                   "mirror line elsewhere is not supported)")
                signs[k], centre[k] = True, v
        self._forget("".join(self.axes))
        return _mirror_frame(cur.shift, signs, centre)

    def unmirror(self, g: float, cur: LocalFrame) -> LocalFrame:
        name = "G50.1" if g == 50.1 else "G100"
        if cur.kind != "mirror":
            return cur
        self.refuse_other_axes(name)
        if not self.axes:
            raise self.err(f"{name} without axis words while a mirror image is in force is not "
                           "supported (name the axes to cancel)")
        signs, centre = list(cur.mirrored), list(cur.centre)
        for k, c in enumerate("XYZ"):
            if c in self.values and signs[k]:
                signs[k], centre[k] = False, 0.0
                self._forget(c)
        return _mirror_frame(cur.shift, signs, centre)

    def _raw(self, letter: str) -> str:
        return next((num for c, num, _raw in self.tokens if c == letter), "")

    def g51(self, cur: LocalFrame) -> LocalFrame:
        s = self.s
        words = s.dialect.scale_words
        if not words:
            raise self.err(f"G51 (scaling) is not supported on {s.dialect.name} (give --dialect "
                           "fanuc or haas if one of them runs the program)")
        self.check_common("G51")
        if cur.kind:
            raise self.err(f"G51 while {'G68' if cur.kind == 'rotation' else 'a mirror image'} or "
                           "scaling is in force (the order of the two differs between controllers) "
                           "is not supported")
        if s.incremental:
            raise self.err("G51 under G91 is not supported")
        self.refuse_other_axes("G51")
        factors = self._factors(words)
        centre = self._centre("G51", "XYZ") if self.axes else None
        if centre is None:
            raise self.err("G51 without its centre X Y Z (the centre is then where the tool "
                           "stands, which controllers take differently) is not supported")
        self._forget("XYZ")
        m = ((factors[0], 0.0, 0.0), (0.0, factors[1], 0.0), (0.0, 0.0, factors[2]))
        return LocalFrame(cur.shift, "scale", m, tuple(centre))

    def _factors(self, words: str) -> list[float]:
        """(3,) the scale of X Y Z: P for all three, or I J K each (Fanuc). A value without a
        decimal point is refused: its unit (0.001 or 0.00001) is a controller setting."""
        given = [c for c in "PIJK" if c in self.values and c in words]
        other = [c for c in "IJK" if c in self.values and c not in words]
        if other:
            raise self.err(f"G51 with {other[0]} on {self.s.dialect.name} is not supported")
        if "P" in given and len(given) > 1:
            raise self.err("G51 with both P and I J K is not supported")
        if not given or (given != ["P"] and len(given) != 3):
            raise self.err("G51 without P (or I J K for every axis): the scale is then a "
                           "controller setting, not supported")
        for c in given:
            raw = self._raw(c)
            if number_decimals(raw) == 0 and "." not in raw:
                raise self.err(f"G51 {c}{raw} without a decimal point (its unit is a controller "
                               "setting) is not supported")
            if not self.values[c] > 0:
                raise self.err(f"G51 {c}{raw}: a scale that is not positive (a mirror image by "
                               "scaling) is not supported")
        return [self.values["P"]] * 3 if given == ["P"] else [self.values[c] for c in "IJK"]

    def g50(self, cur: LocalFrame) -> LocalFrame:
        if self.axes:
            raise self.err("G50 with axis words is not a code mtcomp follows (a lathe's coordinate "
                           "setting: its effect on the motion cannot be known)")
        if cur.kind != "scale":
            return cur
        self._forget("XYZ")
        return LocalFrame(cur.shift)


def _cos_sin(deg: float) -> tuple[float, float]:
    """cos and sin of an angle in degrees, exact at multiples of 90 deg (G68 R90.)."""
    quarter = deg / 90.0
    if quarter == round(quarter):
        return ((1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0))[int(round(quarter)) % 4]
    a = math.radians(deg)
    return math.cos(a), math.sin(a)


def _mirror_frame(shift, signs, centre) -> LocalFrame:
    if not any(signs):
        return LocalFrame(shift)
    m = tuple(tuple((-1.0 if signs[r] else 1.0) if r == k else 0.0 for k in range(3))
              for r in range(3))
    return LocalFrame(shift, "mirror", m, tuple(centre), tuple(signs))


#: the G codes of frame changes the reader follows where the dialect has them
FRAME_G = frozenset({52, 92, 68, 69, 51, 50, 51.1, 50.1, 101, 100})


def apply_frame_code(state, g: float, values: dict, tokens, line: int) -> None:
    """Apply one frame code of a line to ``state`` (its ``local`` frame, its known axes), and
    record the change with its line."""
    fc = FrameCodes(state, values, tokens, line)
    cur = state.local
    if g == 52:
        new = fc.g52(cur)
    elif g == 92:
        # recorded even where the program's offset stays: the output's is set where it stands
        state.local = fc.g92(cur)
        record(state.local_frames, line, state.local)
        return
    elif g == 68:
        new = fc.g68(cur)
    elif g == 69:
        new = fc.g69(cur)
    elif g in (51.1, 101):
        new = fc.mirror(g, cur)
    elif g in (50.1, 100):
        new = fc.unmirror(g, cur)
    elif g == 51:
        new = fc.g51(cur)
    else:
        new = fc.g50(cur)
    set_frame(state, new, line)


def set_frame(state, new: LocalFrame, line: int) -> None:
    if new == state.local:
        return
    state.local = new
    record(state.local_frames, line, new)


def check_arc(state, line: int) -> None:
    """An arc under unequal scales of its plane's axes is not a circle on the machine: refused."""
    f = state.local
    if f.kind != "scale":
        return
    from ._arcs import PLANE_AXES
    i0, i1, _ = PLANE_AXES[state.plane]
    sc = f.scales()
    if sc[i0] != sc[i1]:
        raise state._err(f"arc G{state.motion} under scaling with unequal scales of its plane's "
                         f"axes ({sc[i0]:g} and {sc[i1]:g}: not a circle on the machine) is not "
                         "supported", line)


def check_cycle(state, line: int) -> None:
    """A drilling cycle under scaling (controllers differ on the depth) or a mirrored Z: refused."""
    f = state.local
    if f.kind == "scale" or (f.kind == "mirror" and f.mirrored[2]):
        what = "scaling" if f.kind == "scale" else "a mirror image of Z"
        raise state._err(f"drilling cycle G{state.cycle} under {what} is not supported", line)


def mode_change(state, what: str, line: int) -> None:
    """A mode change that meets a frame the program moved: ``what`` 'wcs' (another work system),
    'g92' (G92.1/G92.2: the G92 offset cancelled, and LinuxCNC's G52, which shares it), 'tcp'
    (tool centre point mode on) or 'plane' (G17/G18/G19 under G68, which the Fanuc manual
    forbids)."""
    f = state.local
    if what == "g92" and not f.kind and (state.shift_by != "G52"
                                         or state.dialect.name == "linuxcnc"):
        # the offsets are 0 in the output too (recorded even where the program's were)
        record(state.local_frames, line, LocalFrame(g92=(2, 2, 2)))
        state.local, state.shift_by = IDENTITY, ""
        return
    if f.identity:
        return
    if what == "plane":
        if f.kind == "rotation":
            raise state._err("a plane change (G17/G18/G19) while G68 is in force is not "
                             "supported", line)
        return
    if what == "tcp":
        raise state._err("tool centre point mode while G52, G68, a mirror image or scaling is in "
                         "force is not supported", line)
    if what == "wcs" and not f.kind and (state.dialect.name == "linuxcnc"
                                         or state.shift_by == "G92"):
        return        # LinuxCNC's G52 and every controller's G92 offset apply in every system
    name = "G92.1/G92.2" if what == "g92" else "a change of work system"
    raise state._err(f"{name} while G52, G68, a mirror image or scaling is in force "
                     "(controllers differ whether it keeps, moves or cancels it) is not "
                     "supported", line)


def follow_given(state) -> None:
    """Before a line: which axes the program has given since the start or since their last home
    or machine-coordinate move (``state.was_known``). Where such an axis is lost again (a tool
    change, another work system), the compensated program stands there off by the last
    correction, so a G92 of it cannot be followed."""
    if state.passed_move is not None and state.passed_move[0] in ("home", "machine"):
        state.was_known &= state.known
    state.was_known |= state.known


def _note_assumed(state, axes: list, line: int) -> None:
    """Say once, in the program's notes, that a G92 at positions not given is taken with offset 0."""
    notes = getattr(state._source, "notes", None)
    if notes is None:
        return
    names = " ".join(axes)
    note = (f"assumed: G92 at line {state._where(line)[1]} sets {names} where the program has not "
            f"given the position: its offset of {names} = 0 (the program's coordinates after it "
            "taken as machine axis positions, plus the work offset); where the machine stands "
            "elsewhere, add the offset to --work-offset")
    if note not in notes:
        notes.append(note)

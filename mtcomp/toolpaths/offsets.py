"""Where a program's coordinates sit on the machine: work offsets and tool lengths.

A program's X Y Z ... are positions in its work coordinate system (G54 ... G59.3). The error model
wants machine axis positions: the tool-tip position of the machine (the convention of the machine
file: with every axis at zero the tip of a tool of ``tool_length_mm`` sits at the machine origin).
So a block's machine positions are its program positions plus the work offset in force, and the
tool length of the ``G43 H`` number in force sets the model's Abbe arm (context ``tool_length``).

Offsets come from a small TOML file (``--offsets``) and/or flags (``--work-offset``,
``--tool-length``); flags win. File format (mm for linear axes, deg for rotary axes; axes left out
are 0)::

    [work_offsets]
    G54 = {X = 250.0, Y = 120.0, Z = -310.5}
    G55 = {X = 400.0, Y = 120.0, Z = -310.5, C = 90.0}

    [tool_lengths]            # mm, spindle gauge point to tool tip
    H1 = 82.35
    H2 = 104.0
    "DRILL 8.5" = 123.4       # a tool a Sinumerik program calls by name (T="DRILL 8.5")

Flags: ``--work-offset G54=X250,Y120,Z-310.5`` and ``--tool-length H1=82.35`` (or by name:
``--tool-length "DRILL 8.5=123.4"``; each may be repeated).
"""
from __future__ import annotations

import math
import os
import re
import tomllib
from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import InputError
from ..machine import Machine
from .blocks import SegmentChunk
from .directions import AxisDirections
from .frames import frames_of_rows, placed_by_frames
from .haas5 import dwo_offsets
from .quill import quill_of_rows
from .tcp import axes_of_tcp, tcp_of_axes
from .words import (NO_LENGTH, WORK_SYSTEMS, frame_dwo, frame_local, frame_offset_set, frame_tcp,
                    frame_tool, frame_wcs)

_WCS_NAME = {name: i for i, name in enumerate(WORK_SYSTEMS)}
_AXIS_VALUE_RE = re.compile(r"^\s*([A-Za-z])\s*=?\s*([+-]?(?:\d+\.?\d*|\.\d+))\s*$")



def _distinct(a: np.ndarray) -> list:
    """``np.unique(a).tolist()`` of a chunk's rows (1-D), sorting only the first row of each run of
    equal ones: a program changes its work system and tool a few times in thousands of blocks
    (sorting every row took about 1 ms a chunk, three times a chunk)."""
    if a.size == 0:
        return []
    first = np.ones(a.size, bool)
    first[1:] = a[1:] != a[:-1]
    return np.unique(a[first]).tolist()

@dataclass
class ProgramSetup:
    """Work offsets and tool lengths of one program on one machine.

    work_offsets : wcs index (0 = G54 ... 8 = G59.3) -> (na,) offset, mm and rad (machine order).
    tool_lengths : H number -> tool length, mm; named_lengths : the same for the tools a program
    calls by name (Sinumerik ``T="DRILL 8.5"``): name -> tool length, mm.
    used_wcs, used_tools : the work systems and H numbers the program used (filled by :meth:`apply`;
    a system whose every axis the program set itself with G10 is in ``programmed_wcs`` instead).
    tool_names : the H numbers that stand for tools called by name in the program last applied
    -> their names.
    """

    machine: Machine
    work_offsets: dict = field(default_factory=dict)
    tool_lengths: dict = field(default_factory=dict)
    named_lengths: dict = field(default_factory=dict)
    tool_names: dict = field(default_factory=dict)
    used_wcs: set = field(default_factory=set)
    used_tools: set = field(default_factory=set)
    programmed_wcs: set = field(default_factory=set)
    #: wcs index -> the axis letters the user gave for that work offset (the others are 0)
    given_axes: dict = field(default_factory=dict)
    #: wcs index -> (na,) bool, the axes the program positioned under that work offset (filled by
    #: :meth:`apply` for the offsets given in part only: :meth:`left_out`)
    positioned: dict = field(default_factory=dict)
    #: the frame changes of the program last applied (``source.local_frames``, :mod:`.frames`)
    local_frames: list = field(default_factory=list, repr=False)
    #: the G10 lines of the program last applied (``source.offset_writes``, :mod:`.programmed`)
    offset_writes: list = field(default_factory=list, repr=False)
    #: how far the compensated program's offsets stand from the source's (:meth:`written`)
    _shifts: object = field(default=None, repr=False)
    #: (the program applied, the approach directions of its axes so far: :meth:`apply`)
    _directions: tuple = field(default=None, repr=False)
    #: (the quill moves of the program applied, how many of them came before its last row so far)
    _quill_last: tuple = field(default=(None, -1), repr=False)

    def _offset_table(self) -> np.ndarray:
        table = np.zeros((len(WORK_SYSTEMS), self.machine.n_axes))
        for i, v in self.work_offsets.items():
            table[i] = v
        return table

    def _row_offsets(self, chunk: SegmentChunk, wcs: np.ndarray, source) -> np.ndarray:
        """(n, na) the work offset of each row: this setup's, where the program set an axis of
        its system itself (G10 L2/L20, the sets ``source.work_offset_sets``) the program's."""
        table = self._offset_table()
        off = np.empty((len(wcs), table.shape[1]))
        for j in range(table.shape[1]):     # a column at a time: numpy takes rows one by one
            off[:, j] = table[wcs, j]
        sets = getattr(source, "work_offset_sets", None) or []
        which = frame_offset_set(chunk.frame)
        full = np.zeros(len(chunk), bool)
        for k in np.unique(which[which > 0]).tolist():
            if k > len(sets):
                raise ValueError("the chunk's rows carry work offsets the program set itself (G10): "
                                 "apply(chunk, source) needs the ProgramSource that read them")
            for w, vec in sets[k - 1].items():
                rows = (which == k) & (wcs == w)
                given = ~np.isnan(vec)
                off[np.ix_(rows, given)] = vec[given]
                if given.all():
                    full |= rows
        self.programmed_wcs.update(_distinct(wcs[full]))
        used = _distinct(wcs[~full])
        self.used_wcs.update(used)
        for w in used:
            if w in self.given_axes and len(self.given_axes[w]) < table.shape[1]:
                rows = (wcs == w) & ~full
                seen = self.positioned.get(w, np.zeros(table.shape[1], bool))
                self.positioned[w] = seen | np.asarray(chunk.known, bool)[rows].any(axis=0)
        return off

    def left_out(self) -> dict:
        """wcs index -> the letters of the axes the program positioned under a work offset given
        without them (taken as 0), for the offsets the program used."""
        names = self.machine.axis_names
        out = {}
        for w, seen in sorted(self.positioned.items()):
            left = [names[j] for j in np.flatnonzero(seen) if names[j] not in self.given_axes[w]]
            if left and w in self.used_wcs:
                out[w] = left
        return out

    def apply(self, chunk: SegmentChunk, source=None) -> tuple[SegmentChunk, np.ndarray]:
        """The chunk in machine axis positions, and the (n, na) offsets added to each row.
        ``source``: the :class:`~.source.ProgramSource` read, whose program may set its own work
        offsets (G10 L2/L20: they replace this setup's from their line on).

        The returned chunk carries ``tool_length`` (mm per row; nan: the machine's tool length) and
        ``datum`` (the machine position of the program's origin per row: its work offset). Tool
        centre point rows (:mod:`.tcp`) are turned into the axes the controller reaches, and marked
        ``jump``: between two of them the axes do not move along a straight line; their approach
        directions (``dirs``) are the axes', not the tip words' (:mod:`.directions`), and so are
        those of the rows after them until an axis moves again. A program's W quill (:mod:`.quill`)
        moves the tip along Z and lengthens the tool. Chunks of one program are applied in
        order."""
        wcs = frame_wcs(chunk.frame)
        tool = frame_tool(chunk.frame)
        self.used_tools.update(t for t in _distinct(tool) if 0 < t != NO_LENGTH)
        off = probed = self._row_offsets(chunk, wcs, source)
        dwo = frame_dwo(chunk.frame)
        if dwo.any():
            # Haas' G254: the work offset turned with the rotary axes; the part's datum stays the
            # origin as probed, the rotary axes at zero (as in tool centre point mode)
            off = dwo_offsets(self.machine, chunk, off, dwo, getattr(source, "path", None))
        table = getattr(source, "local_frames", None)
        if table is not None:
            self.local_frames = table
        writes = getattr(source, "offset_writes", None)
        if writes is not None:
            self.offset_writes = writes
        lengths = np.full(len(chunk), np.nan)
        for h, length in self._lengths(source).items():
            lengths[tool == h] = length
        start, end = self._local(chunk, chunk.start, source), self._local(chunk, chunk.end, source)
        known = chunk.known
        moves = getattr(source, "quill_moves", None)
        jump = chunk.jump
        if moves and "Z" in self.machine.axis_names:
            off, lengths, known, jump = self._quill(chunk, moves, off, lengths)
        tcp = frame_tcp(chunk.frame)
        rows = tcp & chunk.known.all(axis=1)
        start, end, datum = start + off, self.on_machine(end, off, rows), probed
        from_known = tcp
        if tcp.any():
            datum = datum.copy()
            datum[tcp] = axes_of_tcp(self.machine, datum[tcp])
            from_known = rows & ~chunk.jump
            start = start.copy()
            start[from_known] = axes_of_tcp(self.machine, start[from_known])
            # the controller moves the tip straight, not the axes: no point of the axes' straight
            # line between two blocks is on the path (the planner puts no node on it)
            jump = jump | tcp
        # the approach directions of the axes, not of the tip words (the backlash's side)
        dirs = self._held_directions(source).chunk(chunk.dirs, start, end, tcp, from_known)
        return replace(chunk, start=start, end=end, dirs=dirs, tool_length=lengths, datum=datum,
                       jump=jump, tcp=tcp, known=known), off

    def on_machine(self, placed: np.ndarray, off: np.ndarray, tcp: np.ndarray) -> np.ndarray:
        """(n, na) machine axis positions of program positions ``placed`` (n, na; in the work
        system, placed by any frame the program moved itself) with the rows' work offsets ``off``
        (from :meth:`apply`; under Haas' G254 the part origin turned with the table): the offset
        added, and in tool centre point rows ``tcp`` (n,) bool (the words (plus the offset) the tip
        in the workpiece frame and the angles; rows whose every axis the program has given) the
        axes where the controller's kinematics puts them. How :meth:`apply` places a row's end, and
        how the error maps place the positions of a compensation's report."""
        out = placed + off
        if tcp.any():
            out[tcp] = axes_of_tcp(self.machine, out[tcp])
        return out

    def _quill(self, chunk: SegmentChunk, moves: dict, off: np.ndarray, lengths: np.ndarray):
        """(offsets, tool lengths, known) of the rows with the W quill's travel (:mod:`.quill`):
        the tip at Z + W (W added to Z's offset, so the written Z is the program's plus its
        correction), the tool longer by -W (the ram where the Z word puts it), and Z not known
        where W is not (the block is not corrected); a row after a move of W alone is marked
        ``jump`` (its tip does not come from the row before's end: no node is put on it)."""
        last = self._quill_last if self._quill_last[0] is moves else (moves, -1)
        w, w_known, moved, upto = quill_of_rows(moves, chunk.line, last[1])
        self._quill_last = (moves, upto)
        z = self.machine.index("Z")
        off = off.copy()
        off[:, z] += w
        lengths = np.where(np.isnan(lengths), self.machine.tool_length, lengths) - w
        known = chunk.known.copy()
        known[:, z] &= w_known
        return off, lengths, known, chunk.jump | moved

    def _held_directions(self, source) -> AxisDirections:
        """The axes' approach directions along the program ``source`` (:mod:`.directions`), new for
        each program."""
        if self._directions is None or self._directions[0] is not source:
            linear = np.array([not a.is_rotary for a in self.machine.axes])
            self._directions = (source, AxisDirections(linear))
        return self._directions[1]

    def _lengths(self, source) -> dict:
        """H number -> tool length (mm): the numbered tools', and those of the tools the program
        calls by name, under the H numbers its translation gave them."""
        names = getattr(getattr(source, "sinumerik", None), "tool_names", None) or {}
        self.tool_names = {h: name for name, h in names.items()}
        return self.lengths_by_number(names)

    def lengths_by_number(self, names: dict) -> dict:
        """H number -> tool length (mm): the numbered tools', those given by name for the tools
        a program calls by name (``names``: name -> the H number its reading gave the tool), and
        0 for NO_LENGTH (the offset cancelled or of value 0: the gauge point steered)."""
        out = dict(self.tool_lengths)
        out[NO_LENGTH] = 0.0
        out.update({h: self.named_lengths[name] for name, h in names.items()
                    if name in self.named_lengths})
        return out

    def _local(self, chunk: SegmentChunk, pts: np.ndarray, source) -> np.ndarray:
        """(n, na) the rows' program positions placed by the frame the program moved itself (G52,
        G68, mirror, scaling: :mod:`.frames`), in the work system; ``pts`` itself without one."""
        local = frame_local(chunk.frame)
        if not local.any():
            return pts
        if getattr(source, "local_frames", None) is None:
            raise ValueError("the chunk's rows carry frame changes the program made (G52, G68, "
                             "mirror, scaling): apply(chunk, source) needs the ProgramSource")
        return placed_by_frames(self.local_frames, local, chunk.line, pts,
                                [self.machine.index(c) for c in "XYZ"])

    def to_program(self, chunk: SegmentChunk, points: np.ndarray, counts: np.ndarray,
                   off: np.ndarray) -> np.ndarray:
        """Machine axis positions ``points`` (the rows of ``chunk``, ``counts`` points each) back to
        the program's words: the offsets ``off`` (from :meth:`apply`) taken off, in tool centre
        point rows the axes turned into the tip and angles the controller turns into them, and
        under a frame the program moved itself (:mod:`.frames`) the positions turned back into the
        program's frame (a machine correction c is written as ``M^-1 c``: turned back under G68,
        of opposite sign on a mirrored axis, divided by the scale)."""
        tcp = frame_tcp(chunk.frame)
        out = np.array(points, dtype=float)
        one = out.shape[0] == len(counts)           # one point a row: no repeats
        if tcp.any():
            tcp = tcp & chunk.known.all(axis=1)
            tcp = tcp if one else np.repeat(tcp, counts)
            out[tcp] = tcp_of_axes(self.machine, out[tcp])
        out -= off if one else np.repeat(off, counts, axis=0)
        local = frame_local(chunk.frame)
        if local.any():
            xyz = [self.machine.index(c) for c in "XYZ"]
            for frame, rows in frames_of_rows(self.local_frames, chunk.line):
                rows = rows & local
                rows = rows if one else np.repeat(rows, counts)
                out[rows] = frame.to_program(out[rows], xyz)
        return out

    def written(self, chunk: SegmentChunk, corrected: np.ndarray, nominal: np.ndarray,
                counts: np.ndarray) -> np.ndarray:
        """The corrected program positions (:meth:`to_program`'s, ``counts`` a row) as the words
        to write. A G92 or a G10 L20 at a known position sets an offset where the tool stands; the
        compensated program's line is the source's, read where the *corrected* tool stands, so
        its offset stands off by the correction there, and that is taken off every later word
        of the axis (in the work system the L20 set, in every system for G92:
        :class:`OutputShifts`). Called once a chunk, in program order."""
        frames, writes = self.local_frames, self.offset_writes
        if not frames and not writes:
            return corrected
        shifts = self._shifts
        if shifts is None or shifts.frames is not frames or shifts.writes is not writes:
            shifts = self._shifts = OutputShifts(frames, writes, self.machine.n_axes,
                                                 [self.machine.index(c) for c in "XYZ"])
        ends = np.cumsum(counts) - 1
        rows = shifts.rows(chunk.line, frame_wcs(chunk.frame), corrected[ends] - nominal[ends])
        if not rows.any():
            return corrected
        return corrected - (rows if len(ends) == corrected.shape[0]
                            else np.repeat(rows, counts, axis=0))

    def notes(self) -> list[str]:
        """What was assumed for what the program used and nobody said (one line each)."""
        out = []
        if self.programmed_wcs:
            names = ", ".join(WORK_SYSTEMS[w] for w in sorted(self.programmed_wcs))
            out.append(f"work offset {names} as the program sets it (G10 L2/L20): the corrections "
                       "are referenced to that origin")
        missing = sorted(w for w in self.used_wcs if w not in self.work_offsets)
        if missing:
            names = ", ".join(WORK_SYSTEMS[w] for w in missing)
            out.append(f"assumed: work offset {names} = 0 (the program's coordinates taken as machine "
                       "axis positions); give --work-offset or --offsets")
        for w, left in self.left_out().items():
            given = [a for a in self.machine.axis_names if a in self.given_axes[w]]
            every = ",".join(f"{a}.." for a in self.machine.axis_names if a in given or a in left)
            out.append(f"assumed: {', '.join(left)} of work offset {WORK_SYSTEMS[w]} = 0 (given "
                       f"with {', '.join(given) or 'no axis'} only; the program positions "
                       f"{', '.join(left)} too): give every axis it positions, e.g. --work-offset "
                       f"{WORK_SYSTEMS[w]}={every}")
        unused = sorted(n for n in self.named_lengths if n not in self.tool_names.values())
        if unused:
            names = ", ".join(f'"{n}"' for n in unused)
            out.append(f"tool length given for {names}, but the program calls no tool by that name: "
                       "not used")
        given = {h for h, name in self.tool_names.items() if name in self.named_lengths}
        tools = sorted(t for t in self.used_tools if t not in self.tool_lengths and t not in given)
        if tools:
            names = ", ".join(f'"{self.tool_names[t]}"' if t in self.tool_names else f"H{t}"
                              for t in tools)
            out.append(f"assumed: tool length of {names} = the machine's tool_length_mm "
                       f"({self.machine.tool_length:g} mm); give --tool-length or --offsets")
        return out


class OutputShifts:
    """How far the compensated program's offsets stand from the source's, walked through the rows
    of one program in order.

    A G92 or a G10 L20 at a known position sets an offset where the tool stands (the position less
    the value, on LinuxCNC and grbl the G92 offset taken into account: grbl 1.1 ``gcode.c``,
    ``WCS = MPos - G92 - TLO - WPos``); in the output the tool stands there off by the correction
    of the block that brought it (c, in the program's frame and units), so the output's total
    offset (G92 plus the work system's) differs from the source's by c there: the G92 one by c
    less the system's, the L20 one by c less G92's. A G52, a G92 or L20 at a position not given,
    a G10 L2 and G92.1/G92.2 set the same offset in both. ``frames``: the program's
    ``local_frames`` (the G92 codes of :class:`~.frames.LocalFrame`), ``writes``: its
    ``offset_writes`` (:mod:`.programmed`); an entry after the last row waits for the next rows.
    """

    def __init__(self, frames: list, writes: list, na: int, xyz: list):
        self.frames, self.writes, self.xyz = frames, writes, xyz
        self.g92 = np.zeros(na)                        # X Y Z columns only
        self.wcs = np.zeros((len(WORK_SYSTEMS), na))   # each system's, G10 L20
        self.done = [0, 0]                             # entries of writes, frames applied
        self.last = np.zeros(na)                       # the correction of the last row
        self.last_wcs = 0

    def _pending(self) -> list:
        """(line, 0 for a G10 line (read before a frame code of the same line) or 1, entry)."""
        out = []
        for kind, table in enumerate((self.writes, self.frames)):
            stop = len(table)           # the reader may append while this runs: entries never move
            out += [(table[k][0], kind, table[k][1]) for k in range(self.done[kind], stop)]
        out.sort(key=lambda e: (e[0], e[1]))
        return out

    def rows(self, lines: np.ndarray, wcs: np.ndarray, correction: np.ndarray) -> np.ndarray:
        """(n, na) the output's offset less the source's at each row (mm, rad; to be taken off the
        words). lines, wcs : (n,) the rows' lines and work systems; correction : (n, na) the
        corrections of the rows' ends in the program's frame."""
        n = len(lines)
        out = np.empty((n, len(self.last)))
        pos = 0
        for line, kind, entry in self._pending():
            r = int(np.searchsorted(lines, line, side="right"))
            if r == n:
                break
            out[pos:r] = self.g92 + self.wcs[wcs[pos:r]]
            if r > pos:
                self.last, self.last_wcs = correction[r - 1], int(wcs[r - 1])
            if kind == 0:
                self._g10(*entry)
            else:
                self._g92(entry.g92)
            self.done[kind] += 1
            pos = r
        out[pos:] = self.g92 + self.wcs[wcs[pos:]]
        if pos < n:
            self.last, self.last_wcs = correction[-1].copy(), int(wcs[-1])
        return out

    def _g10(self, system: int, codes: tuple) -> None:
        for i, code in enumerate(codes):
            if code:
                self.wcs[system, i] = self.last[i] - self.g92[i] if code == 1 else 0.0

    def _g92(self, codes: tuple) -> None:
        for k, code in enumerate(codes):
            i = self.xyz[k]
            if code:
                self.g92[i] = self.last[i] - self.wcs[self.last_wcs, i] if code == 1 else 0.0


def _axis_vector(machine: Machine, values: dict, where: str, path) -> np.ndarray:
    v = np.zeros(machine.n_axes)
    for letter, x in values.items():
        a = letter.upper()
        if a not in machine.axis_names:
            raise InputError(f"{where}: machine {machine.name} has no {a} axis", path)
        if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x):
            raise InputError(f"{where}: {a} must be a number, got {x!r}", path)
        i = machine.index(a)
        v[i] = math.radians(x) if machine.axes[i].is_rotary else float(x)
    return v


def _wcs_index(name: str, where: str, path) -> int:
    key = name.strip().upper()
    if key not in _WCS_NAME:
        raise InputError(f"{where}: {name!r} is not a work coordinate system "
                         f"({', '.join(WORK_SYSTEMS)})", path)
    return _WCS_NAME[key]


def _tool_number(name: str, where: str, path) -> int:
    m = re.fullmatch(r"\s*[Hh]?(\d+)\s*", name)
    if not m or int(m.group(1)) < 1:
        raise InputError(f"{where}: {name!r} is not a tool length number (H1, H2 ...)", path)
    return int(m.group(1))


def _length(x, where, path) -> float:
    if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x) or x < 0:
        raise InputError(f"{where}: tool length must be a number >= 0 (mm), got {x!r}", path)
    return float(x)


def load_setup(machine: Machine, path=None, work_offset_flags=(), tool_length_flags=()) -> ProgramSetup:
    """The program setup from an offsets file (or None) and the command-line flags (which win).

    work_offset_flags : strings ``G54=X250,Y120,Z-310.5``. tool_length_flags : strings ``H1=82.35``.
    Raises InputError naming the file or the flag and what is wrong.
    """
    setup = ProgramSetup(machine)
    if path is not None:
        p = os.fspath(path)
        try:
            with open(p, "rb") as f:
                data = tomllib.load(f)
        except FileNotFoundError:
            raise InputError("no such offsets file", p) from None
        except tomllib.TOMLDecodeError as exc:
            raise InputError(f"not valid TOML: {exc}", p) from None
        for key in data:
            if key not in ("work_offsets", "tool_lengths"):
                raise InputError(f"unknown table {key!r} (known: work_offsets, tool_lengths)", p)
        for name, values in data.get("work_offsets", {}).items():
            where = f"[work_offsets] {name}"
            if not isinstance(values, dict):
                raise InputError(f"{where} must be a table such as {{X = 250.0, Y = 120.0}}", p)
            w = _wcs_index(name, where, p)
            setup.work_offsets[w] = _axis_vector(machine, values, where, p)
            setup.given_axes[w] = {a.upper() for a in values}
        for name, x in data.get("tool_lengths", {}).items():
            _set_length(setup, name, x, f"[tool_lengths] {name}", p)
    for flag in work_offset_flags:
        where = f"--work-offset {flag}"
        name, sep, rest = flag.partition("=")
        if not sep:
            raise InputError(f"{where}: write it as G54=X250,Y120,Z-310.5")
        values = {}
        for item in filter(None, (t.strip() for t in rest.split(","))):
            m = _AXIS_VALUE_RE.match(item)
            if not m:
                raise InputError(f"{where}: {item!r} is not an axis value such as X250")
            values[m.group(1)] = float(m.group(2))
        w = _wcs_index(name, where, None)
        setup.work_offsets[w] = _axis_vector(machine, values, where, None)
        setup.given_axes[w] = {a.upper() for a in values}
    for flag in tool_length_flags:
        where = f"--tool-length {flag}"
        name, sep, rest = flag.rpartition("=")
        try:
            x = float(rest) if sep and name.strip() else None
        except ValueError:
            x = None
        if x is None:
            raise InputError(f"{where}: write it as H1=82.35 (mm), or NAME=82.35 for a tool "
                             "called by name")
        _set_length(setup, name, x, where, None)
    return setup


def _set_length(setup: ProgramSetup, name: str, x, where: str, path) -> None:
    """The length ``x`` (mm) of the tool ``name``: ``H1`` (or ``1``) a tool length number, any
    other text the name of a tool a program calls by name (``DRILL 8.5``, as between the quotes
    of ``T="DRILL 8.5"``)."""
    if re.fullmatch(r"\s*[Hh]?\d+\s*", name):
        setup.tool_lengths[_tool_number(name, where, path)] = _length(x, where, path)
    elif re.fullmatch(r"\s*[A-Za-z]\s*\d+\s*", name):
        # T1, D1, H 1: a slip for a tool length number, not a tool's name
        raise InputError(f"{where}: {name.strip()!r} is not a tool length number (H1, H2 ...); a "
                         "tool a Sinumerik program calls by name is given by that name", path)
    else:
        setup.named_lengths[name.strip()] = _length(x, where, path)

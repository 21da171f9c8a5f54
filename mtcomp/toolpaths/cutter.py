"""The cutting moves of the program that cut a measured part, read from its G-code and handed to the
CMM measurement model (:class:`mtcomp.measurement.cut.CutProgram`): the measurement level holds no
G-code reader.

A program in the controller's tool centre point mode (:mod:`.tcp`) gives the tool tip in the
workpiece frame, the part's surface point: its moves are turned into the axes the controller
reaches, as compensate turns them (:class:`~.offsets.ProgramSetup`, with the work offset the part
was cut at), and each is cut into pieces short enough that the axes' straight line
between their ends keeps the tip within :data:`TCP_TOL_MM` of the program's straight line (the
controller moves the tip straight, not the axes)."""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..kinematics import forward
from ..measurement.cut import CutProgram
from .gcode import iter_segment_chunks
from .offsets import ProgramSetup
from .source import open_program
from .tcp import axes_of_tcp
from .words import DEFAULT_CHORD_TOL_MM, frame_local, frame_tcp

#: how far (mm) the tip of a tool centre point move's pieces may stand from its straight line: the
#: reader's chord tolerance of an arc
TCP_TOL_MM = DEFAULT_CHORD_TOL_MM


def read_cut_program(path, machine, setup=None) -> CutProgram:
    """The cutting moves (not G0) of the G-code program ``path`` on ``machine``: segment ends in
    machine axis positions (mm, rad), source lines, feeds, approach directions and tool lengths (arcs
    split into chords as the reader does; tool centre point moves in axis positions, in pieces:
    module docstring), and the part's datum. ``setup``: the program's work offsets and tool lengths
    (:func:`mtcomp.toolpaths.offsets.load_setup`, as compensate takes them; None: none, the
    program's zero at the machine's), applied as compensate applies them, with the offsets the
    program sets itself (G10 L2/L20) from their line on.
    InputError naming the program (and line) when it has no motion or only rapids, where its G-code
    is bad or moves its own frame, and where its cutting moves lie in more than one work offset or
    in one that turns a rotary axis (:func:`_part_datum`)."""
    setup = ProgramSetup(machine) if setup is None else setup
    with open_program(path, fixed_format=machine.fixed_format) as src:
        raw = list(iter_segment_chunks(src, machine))
        for c in raw:
            _refuse_local_frame(c, path)
        chunks = [(c, *setup.apply(c, src)) for c in raw]
        notes = list(src.notes)
    if any("U, V, W" in n for n in notes):
        raise InputError("a cut program with U, V or W axis words is not supported (the ball "
                         "centres would miss those axes' moves)", str(path))
    if not chunks:
        raise InputError("the program has no motion", str(path))
    keep = ~np.concatenate([c.rapid for c, _, _ in chunks])
    if not keep.any():
        raise InputError("the program has no cutting moves (only G0)", str(path))
    parts = [_cutting_rows(machine, c, m, off, path) for c, m, off in chunks]
    start, end, line, feed, dirs, tool_length, offsets = (np.concatenate([p[k] for p in parts])
                                                          for k in range(7))
    datum = _part_datum(machine, offsets, line, path)
    return CutProgram(str(path), start, end, line, feed, dirs, tool_length, datum)


def _cutting_rows(machine, chunk, placed, off, path):
    """(start, end, line, feed, dirs, tool_length, work offset) of the chunk's cutting rows:
    ``placed`` the chunk in axis positions and ``off`` (n, na) its rows' work offsets
    (:meth:`ProgramSetup.apply`); a tool centre point row cut into pieces."""
    keep = ~np.asarray(chunk.rapid, bool)
    tcp = frame_tcp(chunk.frame) & keep
    rows = (placed.start, placed.end, chunk.line, chunk.feed, placed.dirs, placed.tool_length, off)
    if not tcp.any():
        return tuple(np.asarray(a)[keep] for a in rows)
    unknown = tcp & ~np.asarray(chunk.known, bool).all(axis=1)
    if unknown.any():
        raise InputError("a cutting move in tool centre point mode with an axis the program has not "
                         "given: its tip's axes are not known", str(path),
                         line=int(chunk.line[np.argmax(unknown)]))
    starts, ends, index = [], [], []
    for i in np.flatnonzero(keep):
        if not tcp[i]:
            s, e = placed.start[i][None], placed.end[i][None]
        else:
            # a move from a position the program has not given: no path, its end only
            # the words in the frame the offset places them in, as ProgramSetup.apply reads them
            s, e = _tcp_pieces(machine, (chunk.end[i] if chunk.jump[i] else chunk.start[i]) + off[i],
                               chunk.end[i] + off[i])
        starts.append(s)
        ends.append(e)
        index.append(np.full(len(s), i))
    index = np.concatenate(index)
    return (np.concatenate(starts), np.concatenate(ends),
            *(np.asarray(r)[index] for r in rows[2:]))


def _tcp_pieces(machine, start, end):
    """(starts (k, na), ends (k, na)) axis positions of k pieces of the tool centre point move from
    the words ``start`` to ``end`` (na,): the words' straight line cut in k equal parts, k doubled
    until the tip at the axes' midpoint of each piece is within TCP_TOL_MM of the words' midpoint."""
    lin = [machine.index(a) for a in "XYZ"]
    for k in (2 ** n for n in range(12)):
        t = np.linspace(0.0, 1.0, 2 * k + 1)[:, None]
        q = axes_of_tcp(machine, start + t * (end - start))
        mid = 0.5 * (q[:-2:2] + q[2::2])
        off = np.linalg.norm(forward(machine, mid)[0] - (start + t[1::2] * (end - start))[:, lin],
                             axis=1)
        if off.max() <= TCP_TOL_MM:
            break
    return q[:-2:2], q[2::2]


def _refuse_local_frame(chunk, path) -> None:
    """InputError at the first move under a frame the program moves itself (G52, G68, mirror,
    scaling): the CMM's part frame would not be the program's."""
    moved = frame_local(chunk.frame)
    if moved.any():
        raise InputError("a move under G52, G68, a mirror image or scaling: a cut program that "
                         "moves its own frame is not supported", str(path),
                         line=int(chunk.line[np.argmax(moved)]))


def _part_datum(machine, offsets, line, path) -> np.ndarray:
    """(na,) the one work offset (mm, rad) of every cutting move (``offsets`` (m, na), ``line`` their
    source lines): the CMM measures the part in one frame, the program's, which sits there on the
    machine. InputError at the first move in another offset, or when the offset turns a rotary axis
    (the part's frame would turn with it)."""
    if not len(offsets):
        return np.zeros(machine.n_axes)
    datum = offsets[0]
    other = np.flatnonzero(np.any(np.abs(offsets - datum) > 1e-9, axis=1))
    if other.size:
        raise InputError("a cutting move in another work offset than the first's: the CMM measures "
                         "the part in one frame; give each part's program apart", str(path),
                         line=int(line[other[0]]))
    turned = [a.name for a, v in zip(machine.axes, datum) if a.is_rotary and v != 0.0]
    if turned:
        raise InputError(f"the cutting moves' work offset turns {', '.join(turned)}: a cut program "
                         "whose part frame turns with a rotary axis is not supported", str(path),
                         line=int(line[0]))
    return datum.copy()

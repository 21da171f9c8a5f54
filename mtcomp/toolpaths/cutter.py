"""The cutting moves of the program that cut a measured part, read from its G-code and handed to the
CMM measurement model (:class:`mtcomp.measurement.cut.CutProgram`): the measurement level holds no
G-code reader.

A program in the controller's tool centre point mode (:mod:`.tcp`) gives the tool tip in the
workpiece frame, the part's surface point: its moves are turned into the axes the controller
reaches, as compensate turns them (:class:`~.offsets.ProgramSetup` with no work offset: the moves
are taken as written), and each is cut into pieces short enough that the axes' straight line
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
from .words import DEFAULT_CHORD_TOL_MM, frame_local, frame_offset_set, frame_tcp

#: how far (mm) the tip of a tool centre point move's pieces may stand from its straight line: the
#: reader's chord tolerance of an arc
TCP_TOL_MM = DEFAULT_CHORD_TOL_MM


def read_cut_program(path, machine) -> CutProgram:
    """The cutting moves (not G0) of the G-code program ``path`` on ``machine``: segment ends (mm,
    rad), source lines, feeds and approach directions (arcs split into chords as the reader does;
    tool centre point moves in axis positions, in pieces: module docstring).
    InputError naming the program when it has no motion or only rapids, or where its G-code is bad."""
    setup = ProgramSetup(machine)
    with open_program(path) as src:
        chunks = [(c, setup.apply(c, src)[0]) for c in iter_segment_chunks(src, machine)]
        notes = list(src.notes)
    # the moves are taken as written (no work offset is applied: the CMM's alignment is the
    # part's), so a program that moves its own origin or a quill mtcomp does not model is refused
    for c, _ in chunks:
        moved = frame_offset_set(c.frame) > 0
        if moved.any():
            raise InputError("a move placed by work offsets the program sets itself (G10 L2/L20): "
                             "a cut program that does so is not supported", str(path),
                             line=int(c.line[np.argmax(moved)]))
        moved = frame_local(c.frame)
        if moved.any():
            raise InputError("a move under G52, G68, a mirror image or scaling: a cut program that "
                             "moves its own frame is not supported", str(path),
                             line=int(c.line[np.argmax(moved)]))
    if any("U, V, W" in n for n in notes):
        raise InputError("a cut program with U, V or W axis words is not supported (the ball "
                         "centres would miss those axes' moves)", str(path))
    if not chunks:
        raise InputError("the program has no motion", str(path))
    keep = ~np.concatenate([c.rapid for c, _ in chunks])
    if not keep.any():
        raise InputError("the program has no cutting moves (only G0)", str(path))
    parts = [_cutting_rows(machine, c, m, path) for c, m in chunks]
    return CutProgram(str(path), *(np.concatenate([p[k] for p in parts]) for k in range(5)))


def _cutting_rows(machine, chunk, placed, path):
    """(start, end, line, feed, dirs) of the chunk's cutting rows: ``placed`` the chunk in axis
    positions (:meth:`ProgramSetup.apply`); a tool centre point row cut into pieces."""
    keep = ~np.asarray(chunk.rapid, bool)
    tcp = frame_tcp(chunk.frame) & keep
    rows = (placed.start, placed.end, chunk.line, chunk.feed, placed.dirs)
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
            s, e = _tcp_pieces(machine, chunk.end[i] if chunk.jump[i] else chunk.start[i],
                               chunk.end[i])
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

"""The cutting moves of the program that cut a measured part, read from its G-code and handed to the
CMM measurement model (:class:`mtcomp.measurement.cut.CutProgram`): the measurement level holds no
G-code reader."""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..measurement.cut import CutProgram
from .gcode import iter_segment_chunks
from .source import open_program
from .words import frame_local


def read_cut_program(path, machine, setup=None) -> CutProgram:
    """The cutting moves (not G0) of the G-code program ``path`` on ``machine``: segment ends in
    machine axis positions (mm, rad), source lines, feeds, approach directions and tool lengths (arcs
    split into chords as the reader does), and the part's datum. ``setup``: the program's work
    offsets and tool lengths (:func:`mtcomp.toolpaths.offsets.load_setup`, as compensate takes them;
    None: none, the program's zero at the machine's), applied as compensate applies them, with the
    offsets the program sets itself (G10 L2/L20) from their line on.
    InputError naming the program (and line) when it has no motion or only rapids, where its G-code
    is bad or moves its own frame, and where its cutting moves lie in more than one work offset or
    in one that turns a rotary axis (:func:`_part_datum`)."""
    from .offsets import ProgramSetup
    setup = ProgramSetup(machine) if setup is None else setup
    with open_program(path) as src:
        chunks = list(iter_segment_chunks(src, machine))
        for c in chunks:
            _refuse_local_frame(c, path)
        placed = [setup.apply(c, src) for c in chunks]
        notes = list(src.notes)
    if any("U, V, W" in n for n in notes):
        raise InputError("a cut program with U, V or W axis words is not supported (the ball "
                         "centres would miss those axes' moves)", str(path))
    if not chunks:
        raise InputError("the program has no motion", str(path))
    keep = ~np.concatenate([c.rapid for c in chunks])
    if not keep.any():
        raise InputError("the program has no cutting moves (only G0)", str(path))

    def cat(field):
        return np.concatenate([getattr(c, field) for c, _ in placed])[keep]

    datum = _part_datum(machine, np.concatenate([off for _, off in placed])[keep], cat("line"), path)
    return CutProgram(str(path), cat("start"), cat("end"), cat("line"), cat("feed"), cat("dirs"),
                      cat("tool_length"), datum)


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

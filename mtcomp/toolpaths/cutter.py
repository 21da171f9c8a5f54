"""The cutting moves of the program that cut a measured part, read from its G-code and handed to the
CMM measurement model (:class:`mtcomp.measurement.cut.CutProgram`): the measurement level holds no
G-code reader."""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..measurement.cut import CutProgram
from .gcode import iter_segment_chunks
from .source import open_program
from .words import frame_local, frame_offset_set


def read_cut_program(path, machine) -> CutProgram:
    """The cutting moves (not G0) of the G-code program ``path`` on ``machine``: segment ends (mm,
    rad), source lines, feeds and approach directions (arcs split into chords as the reader does).
    InputError naming the program when it has no motion or only rapids, or where its G-code is bad."""
    with open_program(path) as src:
        chunks = list(iter_segment_chunks(src, machine))
        notes = list(src.notes)
    # the moves are taken as written (no work offset is applied: the CMM's alignment is the
    # part's), so a program that moves its own origin or a quill mtcomp does not model is refused
    for c in chunks:
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
    keep = ~np.concatenate([c.rapid for c in chunks])
    if not keep.any():
        raise InputError("the program has no cutting moves (only G0)", str(path))

    def cat(field):
        return np.concatenate([getattr(c, field) for c in chunks])[keep]

    return CutProgram(str(path), cat("start"), cat("end"), cat("line"), cat("feed"), cat("dirs"))

"""The cutting moves of the program that cut a measured part, read from its G-code and handed to the
CMM measurement model (:class:`mtcomp.measurement.cut.CutProgram`): the measurement level holds no
G-code reader."""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..measurement.cut import CutProgram
from .gcode import iter_segment_chunks


def read_cut_program(path, machine) -> CutProgram:
    """The cutting moves (not G0) of the G-code program ``path`` on ``machine``: segment ends (mm,
    rad), source lines, feeds and approach directions (arcs split into chords as the reader does).
    InputError naming the program when it has no motion or only rapids, or where its G-code is bad."""
    chunks = list(iter_segment_chunks(path, machine))
    if not chunks:
        raise InputError("the program has no motion", str(path))
    keep = ~np.concatenate([c.rapid for c in chunks])
    if not keep.any():
        raise InputError("the program has no cutting moves (only G0)", str(path))

    def cat(field):
        return np.concatenate([getattr(c, field) for c in chunks])[keep]

    return CutProgram(str(path), cat("start"), cat("end"), cat("line"), cat("feed"), cat("dirs"))

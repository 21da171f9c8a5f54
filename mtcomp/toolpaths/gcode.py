"""G-code (ISO 6983 / RS-274, the subset in docs/toolpaths.md): reader, segment stream and writer.

This module is the public face of the G-code layers, which live in their own modules (after
pygcode: word -> block -> program, with the modal state of the machine in one place):

* :mod:`.words`: a line cut into tokens (words ``X-1.5`` and comments, :func:`tokenize`), the
  units and tolerances, the tables of refused features, the frame codes (:func:`frame_code`,
  :func:`frame_wcs`, :func:`frame_tool`, :data:`WORK_SYSTEMS`);
* :mod:`.blocks`: the data handed out (:class:`SegmentChunk`, :class:`MotionBlock`,
  :class:`CycleBlock`, :class:`Program`);
* :mod:`.modal`: :class:`ModalState`, the machine's modal state (motion mode, plane, units,
  distance mode, feed, position, approach directions ...), which turns each line into motion or
  leaves it as a pass-through line;
* :mod:`.dialect`, :mod:`.expr`, :mod:`.lines`, :mod:`.ngc`, :mod:`.macro`, :mod:`.source`: the
  program's dialect, and the LinuxCNC and Fanuc macro code run into the flat lines the controller
  executes (:func:`open_program`, :class:`ProgramSource`), which every reader goes through;
* :mod:`.reader`: lines -> blocks -> program (:func:`iter_blocks`, :func:`read_program`) and the
  pure-Python segment stream;
* :mod:`.writer`: the corrected program written back (:class:`OutputState`,
  :func:`format_motion_lines`, :func:`write_pass_through`, :class:`CorrectionCursor`) and the
  pure-Python writer;
* :mod:`._fast`: the compiled reader and writer (same chunks and bytes), built on the layers above.

Here are the two entry points that choose between the compiled path (when it is available and
``MTCOMP_NO_FAST_GCODE`` is not set) and the pure-Python one: :func:`iter_segment_chunks` and
:func:`write_corrected`. Every name above is importable from here.

Units: the file holds mm or inch (G21/G20) and deg for A, B, C; everything returned is mm, rad and
mm/min. Positions are axis positions in ``machine.axis_names`` order (tool-tip positions).
"""
from __future__ import annotations

from dataclasses import replace
from typing import Iterable, Iterator

import numpy as np

from ..io.atomic import check_output_path
from ..machine import Machine
from . import _fast, reader, writer
from .blocks import CycleBlock, MotionBlock, Program, SegmentChunk
from .modal import ModalState
from .reader import iter_blocks, new_state, read_program
from .source import ProgramSource, open_program
from .words import (DEFAULT_CHORD_TOL_MM, DEFAULT_CHUNK_SIZE, DIR_EPS, MM_PER_INCH, TOOL_AXIS,
                    WORK_SYSTEMS, frame_code, frame_tool, frame_wcs, tokenize)
from .writer import CorrectionCursor, OutputState, format_motion_lines, write_pass_through

__all__ = ["DEFAULT_CHORD_TOL_MM", "DEFAULT_CHUNK_SIZE", "DIR_EPS", "MM_PER_INCH",
           "TOOL_AXIS", "WORK_SYSTEMS", "frame_code", "frame_tool", "frame_wcs", "tokenize",
           "CycleBlock", "MotionBlock", "Program", "SegmentChunk", "ModalState", "iter_blocks",
           "new_state", "read_program", "iter_segment_chunks", "CorrectionCursor", "OutputState",
           "format_motion_lines", "write_pass_through", "write_corrected", "ProgramSource",
           "open_program"]


def _compiled(src) -> bool:
    """Whether the compiled scanner reads and writes the program: when it is built, and not for a
    RepRapFirmware program (the scanner takes M codes and T words as codes that move nothing, where
    the firmware may run a macro file for them: :mod:`.rrf`) or a BeagleG one (the scanner keeps a
    G2/G3 in force, and reads G codes BeagleG does not have), which the Python reader and writer
    read and write throughout."""
    return _fast.available() and src.dialect.name not in ("rrf", "beagleg")


def iter_segment_chunks(path, machine: Machine, chord_tol_mm: float = DEFAULT_CHORD_TOL_MM,
                        chunk_size: int = DEFAULT_CHUNK_SIZE,
                        initial_position=None, *, inch: bool = False,
                        initial_known=None, dialect: str | None = None,
                        progress=None) -> Iterator[SegmentChunk]:
    """Stream a program as :class:`SegmentChunk` objects of at most ``chunk_size`` rows.

    path : the program's file, or a :class:`ProgramSource` from :func:`open_program` (its
    expansion is then read as it is). dialect : see :func:`open_program` (None: detected).
    initial_position : (na,) axis positions before the first block, also where G28/G30 send the
    axes (mm, rad; default all zero). chord_tol_mm : largest sagitta of an arc's chords (mm).
    inch, initial_known : see :func:`iter_blocks`. progress : callable(lines read), told after
    every :data:`~.words.PROGRESS_LINES` lines interpreted in Python (a tool centre point program
    is read so throughout) and every block of the file the compiled scanner reads, or None.
    Memory stays flat for any program length: one chunk (and one arc) is held at a time. A block
    split into many chords may continue in the next chunk. Raises InputError naming file and line
    (rows of earlier chunks have been yielded by then, and the rows before the bad line, as a
    chunk of their own, so that a consumer's check of them names an earlier line first: consumers
    must not write output before the stream is exhausted, which :func:`write_corrected`
    guarantees through atomic_write).
    """
    kw = dict(inch=inch, initial_known=initial_known)
    with open_program(path, dialect, fixed_format=machine.fixed_format) as src:
        if _compiled(src):
            chunks = _fast.iter_segment_chunks(src, machine, chord_tol_mm, chunk_size,
                                               initial_position, progress, **kw)
        else:
            chunks = reader.iter_segment_chunks(src, machine, chord_tol_mm, chunk_size,
                                                initial_position, progress, **kw)
        yield from _still_arcs_at_the_last_feed(chunks)
        # an error in the program's code that stopped its expansion comes after the rows of the
        # lines executed before it (the first error in program order is the one told)
        src.raise_error()


def _still_arcs_at_the_last_feed(chunks: Iterable[SegmentChunk]) -> Iterator[SegmentChunk]:
    """The chunks, the rows of arc blocks that do not move (a full circle of zero radius about its
    start, :func:`~._arcs.is_point_circle`) at the feed of the row before: the tool stands as the
    last move left it (the compiled scanner does not follow the feed of the moves it reads)."""
    last = np.nan
    for chunk in chunks:
        if len(chunk):
            arc = np.flatnonzero(chunk.from_arc)        # the few arc rows only
            still = arc[~np.any(chunk.end[arc] != chunk.start[arc], axis=1)]
            if still.size:
                feed = np.array(chunk.feed, dtype=float)
                for r in still.tolist():
                    feed[r] = feed[r - 1] if r else last
                chunk = replace(chunk, feed=feed)
            last = float(chunk.feed[-1])
        yield chunk


def _uncorrected(path, machine, chord_tol_mm, chunk_size, initial_position, **kw):
    for chunk in iter_segment_chunks(path, machine, chord_tol_mm, chunk_size, initial_position, **kw):
        yield chunk, chunk.end, np.ones(len(chunk), np.int64)


def write_corrected(in_path, out_path, machine: Machine,
                    corrections: Iterable[tuple[SegmentChunk, np.ndarray, np.ndarray]] | None,
                    chord_tol_mm: float = DEFAULT_CHORD_TOL_MM, initial_position=None, *,
                    inch: bool = False, initial_known=None, stats: dict | None = None,
                    dialect: str | None = None) -> int:
    """Write ``in_path`` to ``out_path`` with corrected motion lines; returns the number of segment
    rows written.

    in_path : the program's file, or a :class:`ProgramSource` (an expanded program is written as
    its expansion, first line the comment that says so). dialect : see :func:`open_program`.
    corrections : iterator of ``(chunk, points, counts)`` per SegmentChunk of
        :func:`iter_segment_chunks` (same order): points (M, na) corrected axis positions (mm, rad)
        to emit, counts (n,) int >= 1: how many of ``points`` belong to each segment row, the last
        being the segment's corrected end. None writes the nominal program: the round trip.
    Every line that is not a motion line is written byte for byte and in place. In a motion line
    only the numbers that carry a correction change, in place (see :func:`format_motion_lines`); an
    axis whose position the program has not given is never written. Output is in the distance
    mode (G90/G91: an incremental word is the source's increment plus the change of correction)
    and the units of the input at that line, a corrected number with at least its source word's decimals
    (and 4 for mm and deg, 5 for inch); lines after M2/M30 are written as they are. The file is written atomically: nothing is left on
    failure and the input is never overwritten. inch, initial_known : see :func:`iter_blocks`.
    stats : a dict that receives ``cycle_lines``, the drilling cycle lines passed through unchanged
    (their positions are not corrected), and ``cycle_blocks``, those kept as cycles (with the
    corrections given), or None.
    Raises InputError for a bad program or output path, ValueError for corrections that do not
    match the program's segment rows (or hold a non-finite point).
    """
    check_output_path(out_path, [getattr(in_path, "source", in_path)])
    kw = dict(inch=inch, initial_known=initial_known)
    with open_program(in_path, dialect, fixed_format=machine.fixed_format) as src:
        if corrections is None:
            corrections = _uncorrected(src, machine, chord_tol_mm, DEFAULT_CHUNK_SIZE,
                                       initial_position, **kw)
        cursor = CorrectionCursor(corrections, machine.n_axes, src.source)
        write = _fast.write_corrected if _compiled(src) else writer.write_corrected
        if src.heidenhain is not None:          # written back in its conversational form
            from .heidenhain_out import write_corrected as write
        if src.sinumerik is not None:           # written back in its own form
            from .sinumerik_out import write_corrected as write
        if src.fixed is not None:               # its words written back in the format
            from .fixed_format import write_corrected as fixed_write
            return fixed_write(write, src, out_path, machine, cursor, chord_tol_mm,
                               initial_position, stats=stats, **kw)
        return write(src, out_path, machine, cursor, chord_tol_mm, initial_position, stats=stats,
                     **kw)

"""Reading a G-code program: lines -> blocks (through the modal state) -> program or segment stream.

The top layer of the reader (after pygcode: word -> block -> program). Every program is first
opened by :func:`~.source.open_program` (its dialect, and the expansion of LinuxCNC O-words and
parameters or Fanuc macro B into the lines the controller executes). :func:`iter_blocks` feeds
the lines of a file one by one to one :class:`~.modal.ModalState`; :func:`read_program` keeps the
blocks in memory; :func:`iter_segment_chunks` here is the pure-Python segment stream (the public
:func:`mtcomp.toolpaths.gcode.iter_segment_chunks` runs the compiled one when it can, with the same
results).
"""
from __future__ import annotations

import os
from typing import Iterator

import numpy as np

from ..errors import InputError
from ..machine import Machine
from .blocks import MotionBlock, Program, SegmentChunk, _empty_chunk
from .modal import ModalState
from .source import open_program
from .words import DEFAULT_CHORD_TOL_MM, DEFAULT_CHUNK_SIZE, PROGRESS_LINES


def _open_lines(path) -> Iterator[tuple[int, bytes, str]]:
    """(1-based line number, raw bytes with line ending, text without line ending, latin-1)."""
    p = os.fspath(path)
    try:
        f = open(p, "rb")
    except FileNotFoundError:
        raise InputError("no such file", p) from None
    except IsADirectoryError:
        raise InputError("is a folder, not a G-code file", p) from None
    except OSError as exc:
        raise InputError(f"cannot open: {exc.strerror}", p) from None
    with f:
        for k, raw in enumerate(f, 1):
            yield k, raw, raw.decode("latin-1").rstrip("\r\n")


def new_state(machine: Machine, path, chord_tol_mm=DEFAULT_CHORD_TOL_MM, initial_position=None,
              inch: bool = False, initial_known=None) -> ModalState:
    """The reader's state before the first line (see :class:`ModalState`). path : a file name, or
    the :class:`~.source.ProgramSource` whose dialect and line map the state follows."""
    return ModalState(machine, path, chord_tol_mm, initial_position, inch, initial_known)


def iter_blocks(path, machine: Machine, chord_tol_mm: float = DEFAULT_CHORD_TOL_MM,
                initial_position=None, *, inch: bool = False, initial_known=None,
                dialect: str | None = None
                ) -> Iterator[tuple[int, bytes, MotionBlock | None, ModalState]]:
    """Every line of a program: (line number, raw bytes, its motion block or None, the state after it).

    The state is the same object throughout (it is the reader's modal state, updated in place).
    inch : the units before any G20/G21 (False: mm). initial_known : (na,) bool or bool, axes whose
    position is known before the first line (default: known if initial_position is given).
    dialect : the controller's dialect (None: detected; see :mod:`.dialect`). For an expanded
    program the lines are those of the expansion (see :mod:`.source`); where an error in its code
    stopped the expansion, that error is raised after the lines executed before it.
    """
    with open_program(path, dialect, fixed_format=machine.fixed_format) as src:
        state = new_state(machine, src, chord_tol_mm, initial_position, inch, initial_known)
        for k, raw, text in _open_lines(src):
            yield k, raw, state.block(k, text), state
        src.raise_error()


def read_program(path, machine: Machine, chord_tol_mm: float = DEFAULT_CHORD_TOL_MM,
                 initial_position=None, *, inch: bool = False, initial_known=None,
                 dialect: str | None = None) -> Program:
    """All motion blocks of a program, in memory. Raises InputError naming file and line."""
    blocks = []
    n = 0
    for n, _raw, b, _state in iter_blocks(path, machine, chord_tol_mm, initial_position, inch=inch,
                                          initial_known=initial_known, dialect=dialect):
        if b is not None:
            blocks.append(b)
    return Program(getattr(path, "source", None) or os.fspath(path), machine.axis_names, blocks, n)


class _ChunkBuilder:
    """Collects segment rows and hands out SegmentChunks of at most ``size`` rows."""

    def __init__(self, na: int, size: int):
        self.na, self.size = na, int(size)
        if self.size < 1:
            raise ValueError("chunk_size must be >= 1")
        self._reset()

    def _reset(self):
        self.rows: list[tuple] = []   # (line, start, end, feed, dirs, rapid, arc, known, frame,
        #                                cycle, jump, cutter_comp code)
        self.n = 0

    def add(self, b: MotionBlock) -> Iterator[SegmentChunk]:
        k = b.points.shape[0]
        starts = b.segment_starts() if k > 1 else b.start[None, :]
        for r in range(k):
            self.rows.append((b.line, starts[r], b.points[r], b.feed, b.dirs[r], b.rapid, b.from_arc,
                              b.known, b.frame, b.cycle is not None, r == 0 and not b.start_known,
                              b.crc_code))
            self.n += 1
            if self.n == self.size:
                yield self.flush()

    def flush(self) -> SegmentChunk:
        if self.n == 0:
            return _empty_chunk(self.na)
        line, start, end, feed, dirs, rapid, arc, known, frame, cycle, jump, crc = zip(*self.rows)
        c = SegmentChunk(np.array(line, np.int64), np.array(start, float).reshape(-1, self.na),
                         np.array(end, float).reshape(-1, self.na), np.array(feed, float),
                         np.array(dirs, np.int8).reshape(-1, self.na), np.array(rapid, bool),
                         np.array(arc, bool), np.array(known, bool).reshape(-1, self.na),
                         np.array(frame, np.int32), np.array(cycle, bool), np.array(jump, bool),
                         cutter_comp=np.array(crc, np.int8))
        self._reset()
        return c


def iter_segment_chunks(path, machine: Machine, chord_tol_mm: float = DEFAULT_CHORD_TOL_MM,
                        chunk_size: int = DEFAULT_CHUNK_SIZE,
                        initial_position=None, progress=None, *, inch: bool = False,
                        initial_known=None, dialect: str | None = None) -> Iterator[SegmentChunk]:
    """Pure-Python path of :func:`mtcomp.toolpaths.gcode.iter_segment_chunks` (same arguments and
    chunks): the program's blocks from :func:`iter_blocks`, cut into rows. On a bad line the rows
    before it come out (a chunk of their own) before its InputError."""
    builder = _ChunkBuilder(machine.n_axes, chunk_size)
    try:
        for k, _raw, b, _state in iter_blocks(path, machine, chord_tol_mm, initial_position,
                                              inch=inch, initial_known=initial_known,
                                              dialect=dialect):
            if progress is not None and not k % PROGRESS_LINES:
                progress(k)
            if b is not None:
                yield from builder.add(b)
    except InputError:
        # the rows read before the bad line are handed out first: a consumer's own check of them
        # (the machine's travel) names an earlier line, and the first error in program order is
        # the one to tell
        if builder.n:
            yield builder.flush()
        raise
    if builder.n:
        yield builder.flush()

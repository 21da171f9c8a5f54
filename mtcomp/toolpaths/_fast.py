"""Compiled fast path of the G-code reader and writer (optional, same results as the Python path).

The C source ``_fast_gcode.c`` handles the common lines (``N.. G0/G1 X.. Y.. Z.. F..``, with
comments and words such as M, S, T that do not touch the geometry) and hands every other line back
to :class:`~mtcomp.toolpaths.modal.ModalState`, which is kept in step through a small state vector;
the writer hands those lines to :mod:`.writer`'s formatting. A line with any G code but G0/G1
(``G52``, ``G92`` ...) goes back to Python, which follows the frame it sets; the rows after it are
read here again, carrying the frame code the state vector holds (the offsets themselves are looked
up by line, :mod:`.frames`). It is compiled once with the system C
compiler (``$CC`` or ``gcc``) into a per-user cache folder (``$XDG_CACHE_HOME/mtcomp`` or
``~/.cache/mtcomp``) and loaded with ctypes. Without a compiler, or with ``MTCOMP_NO_FAST_GCODE=1``
in the environment, the pure-Python path runs instead (:mod:`.gcode` chooses). The tests check
both paths give identical chunks and bytes.

This module builds on the lower layers only (:mod:`.blocks`, :mod:`.reader`, :mod:`.writer`),
never on :mod:`.gcode`, which imports it.
"""
from __future__ import annotations

import ctypes
import hashlib
import math
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..io.atomic import atomic_write
from .blocks import SegmentChunk, crc_code
from .reader import new_state
from .word_use import POINT_DIALECTS
from .words import PROGRESS_LINES
from .writer import (OutputState, _line_ending, format_motion_lines, write_pass_through,
                     writer_stats)

_SRC = Path(__file__).with_name("_fast_gcode.c")
_BLOCK = 4 << 20           # bytes read from the input at a time
_OUT = 8 << 20             # bytes of output gathered before a write
NEED_INPUT, FALLBACK, ROWS_FULL, NEED_CORR, OUT_FULL, MISMATCH = range(6)
#: bit of a row's known mask (uint8) set by the compiled reader when the row's start is not known
START_UNKNOWN = 128

_lib = None
_tried = False


def _cache_dirs():
    """mtcomp's one cache folder (:func:`mtcomp.io.cache.private_cache_dir`: ``$MTCOMP_CACHE_DIR``,
    else ``$XDG_CACHE_HOME/mtcomp`` or ``~/.cache/mtcomp``, else a temporary folder), or none."""
    from ..io.cache import CacheDirError, private_cache_dir
    try:
        return [private_cache_dir()]
    except CacheDirError:
        return []


def _private(d: Path) -> bool:
    """The folder belongs to this user and nobody else can write to it (we load code from it)."""
    if not hasattr(os, "getuid"):
        return True
    st = d.stat()
    return st.st_uid == os.getuid() and not (st.st_mode & 0o022)


def _compile() -> Path | None:
    src = _SRC.read_bytes()
    tag = hashlib.sha256(src + sys.platform.encode() + str(ctypes.sizeof(ctypes.c_void_p)).encode())
    name = f"gcode_{tag.hexdigest()[:16]}.so"
    cc = os.environ.get("CC", "gcc")
    for d in _cache_dirs():
        so = d / name
        try:
            d.mkdir(parents=True, exist_ok=True, mode=0o700)
            if not _private(d):
                continue
            if so.exists():
                return so
            fd, tmp = tempfile.mkstemp(prefix=".gcode_", suffix=".so", dir=d)
            os.close(fd)
            r = subprocess.run([cc, "-O2", "-shared", "-fPIC", "-o", tmp, str(_SRC), "-lm"],
                               capture_output=True, timeout=120)
            if r.returncode != 0:
                os.unlink(tmp)
                return None
            os.replace(tmp, so)
            return so
        except (OSError, subprocess.SubprocessError):
            continue
    return None


def _load():
    global _lib, _tried
    if _tried:
        return _lib
    _tried = True
    try:
        so = _compile()
        if so is None:
            return None
        lib = ctypes.CDLL(str(so))
    except OSError:
        return None
    P = ctypes.c_void_p
    LL = ctypes.c_longlong
    lib.mt_process.restype = LL
    lib.mt_process.argtypes = [ctypes.c_char_p, LL, ctypes.c_int, P, P, ctypes.c_int, P, P,
                               ctypes.c_char_p, P, P, P, P, P, P, P, P, LL, P, P, P, P, LL, P, P, LL,
                               P, P]
    lib.mt_format_table.restype = LL
    lib.mt_format_table.argtypes = [P, LL, ctypes.c_int, P, P, P, LL]
    lib.mt_g_codes.restype = ctypes.c_int
    lib.mt_g_codes.argtypes = [P, LL, ctypes.c_char_p, ctypes.c_int, P]
    _lib = lib
    return _lib


def available() -> bool:
    """True if the compiled path can be used (compiles it on first call)."""
    if os.environ.get("MTCOMP_NO_FAST_GCODE"):
        return False
    return _load() is not None


def format_table(values: np.ndarray, decimals, blank) -> str | None:
    """The rows of a CSV table as text, each ending with a newline, or None without the compiled
    path. values : (n, k) floats; decimals : (k,) per column, >= 0 writes ``"%.{d}f" % v`` (at most
    6), < 0 an empty field; blank : (k,) bool, an empty field for NaN or an infinity in that column.
    The text is the one Python's ``%`` writes (tests compare them)."""
    if not available():
        return None
    values = np.ascontiguousarray(values, dtype=np.float64)
    n, k = values.shape
    dec = np.ascontiguousarray(decimals, dtype=np.int32)
    if dec.shape != (k,) or np.any(dec > 6):
        raise ValueError("format_table: one decimals entry per column, at most 6")
    blank = np.ascontiguousarray(blank, dtype=np.int32)
    cap = n * (k * 24 + 2) + 1024
    while True:
        out = np.empty(cap, np.uint8)
        size = _lib.mt_format_table(values.ctypes.data, n, k, dec.ctypes.data, blank.ctypes.data,
                                    out.ctypes.data, cap)
        if size >= 0:
            return str(memoryview(out)[:size], "ascii")     # decoded in place: no bytes copy
        cap *= 4                                  # values too large for 24 characters: room for more


def g_codes(text, n: int, codes) -> set | None:
    """The ``codes`` (two-digit bytes, e.g. b"20") that :func:`mtcomp.compensation._g_codes` finds in
    the first ``n`` bytes of ``text`` (bytes or bytearray), in one compiled pass (numpy's took
    60 ms for 37 MB), or None without the compiled path."""
    if not available():
        return None
    found = np.zeros(len(codes), np.int32)
    _lib.mt_g_codes(np.frombuffer(text, np.uint8).ctypes.data, n, b"".join(codes), len(codes),
                    found.ctypes.data)
    return {c for c, f in zip(codes, found.tolist()) if f}


def _ptr(a: np.ndarray | None):
    return None if a is None else a.ctypes.data


class _Pointers:
    """The data pointers of a few arrays, taken anew only when one of them is another array: the
    scanner is called once per line Python reads (every arc), and a pointer costs 1-2 us. The
    arrays are held, so their pointers stay valid."""

    def __init__(self):
        self.arrays, self.ptrs = (), ()

    def __call__(self, *arrays) -> tuple:
        if len(arrays) != len(self.arrays) or any(a is not b for a, b in zip(arrays, self.arrays)):
            self.arrays, self.ptrs = arrays, tuple(_ptr(a) for a in arrays)
        return self.ptrs


class _Driver:
    """Feeds the input to the compiled scanner and interprets its fallback lines in Python."""

    def __init__(self, path, machine, chord_tol_mm, initial_position=None, **kw):
        self.lib = _load()
        self.path = os.fspath(path)
        self.state = new_state(machine, path, chord_tol_mm, initial_position, **kw)
        self.na = machine.n_axes
        self.out = OutputState(self.na, self.state)
        self.bits = 1 << np.arange(self.na)
        st = np.zeros(26)
        st[:self.na] = self.state.position
        st[6:6 + self.na] = self.state.dirs      # approach directions: the reader's (not known yet)
        st[12] = math.nan
        st[13] = -1.0
        st[14] = float(self.state.inch)
        st[20] = float(self._mask(self.state.known))
        st[21] = float(self.state.frame)
        st[17] = float(self.out.absolute)
        st[22] = -1.0
        # 1: a word without a point goes to Python (fanuc), 2: an F without one too (haas)
        name = self.state.dialect.name
        st[25] = float(name in POINT_DIALECTS) + float(name == "haas")
        self.st = st
        self.letter_col = np.full(26, -1, np.int32)
        for j, c in enumerate(machine.axis_names):
            self.letter_col[ord(c) - 65] = j
        self.is_rot = np.array([c in "ABC" for c in machine.axis_names], np.int32)
        self.letters = "".join(machine.axis_names).encode()
        try:
            self.f = open(self.path, "rb")
        except FileNotFoundError:
            raise InputError("no such file", self.path) from None
        except IsADirectoryError:
            raise InputError("is a folder, not a G-code file", self.path) from None
        except OSError as exc:
            raise InputError(f"cannot open: {exc.strerror}", self.path) from None
        self.buf = b""
        self.consumed = ctypes.c_longlong(0)
        self.eof = False
        self._state_ptrs, self._row_ptrs, self._cursor_ptrs = _Pointers(), _Pointers(), _Pointers()

    def close(self):
        self.f.close()

    def fill(self):
        """Append the next block of input (keeps the unprocessed tail)."""
        data = self.f.read(_BLOCK)
        if not data:
            self.eof = True
        self.buf = self.buf[self.consumed.value:] + data
        self.consumed.value = 0

    def _mask(self, known) -> int:
        return int(np.sum(self.bits[np.asarray(known, bool)]))

    def call(self, rows=None, cap=0, r_n=None, cursor=None, crow=None, out=None, out_n=None):
        st, letter_col, is_rot, out_ptr, values = self._state_ptrs(
            self.st, self.letter_col, self.is_rot, out, self.out.values)
        line, start, end, feed, dirs, rapid, known, frame = self._row_ptrs(
            *(rows if rows is not None else (None,) * 8))
        cur = cursor
        c_line, c_off, c_pts = self._cursor_ptrs(
            *((cur.line, cur.offsets, cur.points) if cur is not None else (None,) * 3))
        return self.lib.mt_process(
            self.buf, len(self.buf), int(self.eof), ctypes.byref(self.consumed), st,
            self.na, letter_col, is_rot, self.letters,
            line, start, end, feed, dirs, rapid, known, frame, cap,
            None if r_n is None else ctypes.byref(r_n),
            c_line, c_off, c_pts, 0 if cur is None else cur.n,
            None if crow is None else ctypes.byref(crow),
            out_ptr, 0 if out is None else out.shape[0],
            None if out_n is None else ctypes.byref(out_n), values)

    def fallback(self):
        """Interpret the line at the current position in Python: (line number, raw bytes, block)."""
        pos = self.consumed.value
        nl = self.buf.find(b"\n", pos)
        while nl < 0 and not self.eof:       # the line runs past the block read (the scanner
            self.fill()                       # hands lines over unread in Python-only modes)
            pos = self.consumed.value
            nl = self.buf.find(b"\n", pos)
        end = len(self.buf) if nl < 0 else nl + 1
        raw = self.buf[pos:end]
        k = int(self.st[16]) + 1
        s, st, na = self.state, self.st, self.na
        s.position = st[:na].copy()
        s.dirs = st[6:6 + na].astype(np.int8)
        s.feed = float(st[12])
        s.motion = None if st[13] < 0 else int(st[13])
        s.inch = bool(st[14])
        s.incremental = bool(st[15])
        s.known = (int(st[20]) & self.bits) != 0
        block = s.block(k, raw.decode("latin-1").rstrip("\r\n"))
        st[19] = float(s.python_only)
        st[20] = float(self._mask(s.known))
        st[21] = float(s.frame)
        st[:na] = s.position
        st[6:6 + na] = s.dirs
        st[12] = s.feed
        st[13] = -1.0 if s.motion is None else s.motion
        st[14] = float(s.inch)
        st[15] = float(s.incremental)
        st[16] = k
        self.consumed.value = end
        return k, raw, block


def _new_rows(cap, na):
    return (np.empty(cap, np.int64), np.empty((cap, na)), np.empty((cap, na)), np.empty(cap),
            np.empty((cap, na), np.int8), np.empty(cap, np.uint8), np.empty(cap, np.uint8),
            np.empty(cap, np.int32), np.zeros(cap, bool), np.zeros(cap, bool),
            np.zeros(cap, np.int8))


def iter_segment_chunks(path, machine, chord_tol_mm, chunk_size, initial_position=None,
                        progress=None, **kw):
    """Compiled counterpart of :func:`mtcomp.toolpaths.gcode.iter_segment_chunks`."""
    cap = int(chunk_size)
    if cap < 1:
        raise ValueError("chunk_size must be >= 1")
    na = machine.n_axes
    d = _Driver(path, machine, chord_tol_mm, initial_position, **kw)
    rows = _new_rows(cap, na)
    n = ctypes.c_longlong(0)

    def chunk():
        k = n.value
        line, start, end, feed, dirs, rapid, known, frame, arc, cycle, crc = rows
        jump = (known[:k] & START_UNKNOWN) != 0
        mask, known = known[:k], np.empty((k, na), bool)
        for j in range(na):     # column by column: the bits broadcast over the rows go row by row
            known[:, j] = (mask & (1 << j)) != 0
        return SegmentChunk(line[:k], start[:k], end[:k], feed[:k], dirs[:k], rapid[:k].view(bool),
                            arc[:k], known, frame[:k], cycle[:k], jump, cutter_comp=crc[:k])
    try:
        while True:
            before = n.value
            status = d.call(rows[:8], cap, n)
            # the scanner's rows: every line that switches G40-G42 is Python's, so the state holds
            rows[10][before:n.value] = crc_code(d.state.cutter_comp, d.state.plane)
            if status == NEED_INPUT:
                if d.eof:
                    break
                if progress is not None:
                    progress(int(d.st[16]))
                d.fill()
            elif status == ROWS_FULL:
                yield chunk()
                rows = _new_rows(cap, na)
                n.value = 0
            elif status == FALLBACK:
                try:
                    k, _raw, b = d.fallback()
                except InputError:
                    if n.value:         # the rows before the bad line first, as reader.py does
                        yield chunk()
                    raise
                if progress is not None and not k % PROGRESS_LINES:
                    progress(k)
                if b is None:
                    continue
                kb = b.points.shape[0]
                starts = b.segment_starts() if kb > 1 else b.start[None, :]
                done = 0
                while done < kb:
                    if n.value == cap:
                        yield chunk()
                        rows = _new_rows(cap, na)
                        n.value = 0
                    take = min(kb - done, cap - n.value)
                    _put_rows(rows, n.value, b, starts, slice(done, done + take), d._mask(b.known))
                    n.value += take
                    done += take
            else:  # pragma: no cover - the reader asks for nothing else
                raise RuntimeError(f"fast G-code reader: unexpected status {status}")
    finally:
        d.close()
    if n.value:
        yield chunk()


def _put_rows(rows, r, b, starts, sl, mask) -> None:
    """Rows ``r``... of ``rows`` from the segments ``sl`` of the block ``b`` (segment starts
    ``starts``, known axes as the bit ``mask``)."""
    line, start, end, feed, dirs, rapid, known, frame, arc, cycle, crc = rows
    take = sl.stop - sl.start
    crc[r:r + take] = b.crc_code
    known[r:r + take] = mask
    if sl.start == 0 and not b.start_known:
        known[r] |= START_UNKNOWN
    frame[r:r + take] = b.frame
    line[r:r + take] = b.line
    start[r:r + take] = starts[sl]
    end[r:r + take] = b.points[sl]
    feed[r:r + take] = b.feed
    dirs[r:r + take] = b.dirs[sl]
    rapid[r:r + take] = b.rapid
    arc[r:r + take] = b.from_arc
    cycle[r:r + take] = b.cycle is not None


def write_corrected(in_path, out_path, machine, cursor, chord_tol_mm, initial_position=None,
                    stats=None, **kw):
    """Compiled counterpart of :func:`mtcomp.toolpaths.gcode.write_corrected` (cursor prepared)."""
    letters = "".join(machine.axis_names)
    rotary = [c in "ABC" for c in letters]
    d = _Driver(in_path, machine, chord_tol_mm, initial_position, **kw)
    ostate = d.out
    out = np.empty(_OUT, np.uint8)
    out_n = ctypes.c_longlong(0)
    crow = ctypes.c_longlong(0)
    rows_done = 0

    def flush(f):
        if out_n.value:
            f.write(out[:out_n.value])
            out_n.value = 0
    try:
        with atomic_write(out_path, "wb") as f:
            while True:
                crow.value = cursor.row
                status = d.call(cursor=cursor, crow=crow, out=out, out_n=out_n)
                rows_done += crow.value - cursor.row
                cursor.row = crow.value
                if status == NEED_INPUT:
                    if d.eof:
                        break
                    d.fill()
                elif status == OUT_FULL:
                    flush(f)
                elif status == NEED_CORR:
                    cursor.advance(int(d.st[16]) + 1)
                elif status == MISMATCH:
                    cursor.mismatch(int(d.st[16]) + 1)
                elif status == FALLBACK:
                    flush(f)
                    k, raw, block = d.fallback()
                    ostate.absolute = d.st[17] != 0.0
                    ostate.motion = int(d.st[22])
                    if block is None:
                        sep = "\r\n" if d.st[18] else "\n"
                        write_pass_through(f, raw, d.state, ostate, sep)
                        d.st[17] = float(ostate.absolute)
                        d.st[22] = float(ostate.motion)
                        continue
                    pts = cursor.take(k, block.points.shape[0])
                    rows_done += block.points.shape[0]
                    ending = _line_ending(raw)
                    separator = ending or ("\r\n" if d.st[18] else "\n")
                    text = format_motion_lines(block, pts, letters, rotary, ostate, ending, separator,
                                               raw.decode("latin-1").rstrip("\r\n"), chord_tol_mm,
                                               cursor.counts)
                    d.st[17] = float(ostate.absolute)
                    d.st[22] = float(ostate.motion)
                    if ending:
                        d.st[18] = float(ending == "\r\n")
                    f.write(text.encode("latin-1"))
                else:  # pragma: no cover
                    raise RuntimeError(f"fast G-code writer: unexpected status {status}")
            flush(f)
            cursor.finish()
    finally:
        d.close()
    if d.st[23]:            # lines the compiled writer gave axis words they did not name
        ostate.added_lines += int(d.st[23])
        first = int(d.st[24])
        ostate.added_line = min(ostate.added_line, first) if ostate.added_line else first
    if stats is not None:
        stats.update(writer_stats(ostate))
    return rows_done

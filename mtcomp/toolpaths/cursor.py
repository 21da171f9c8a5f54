"""The corrections the planner hands the writer, walked row by row: :class:`CorrectionCursor`
(shared by the pure-Python writer, :mod:`.writer`, and the compiled one, :mod:`._fast`)."""
from __future__ import annotations

import numpy as np


class CorrectionCursor:
    """Walks the ``(chunk, points, counts)`` stream of corrections row by row (see
    :func:`mtcomp.toolpaths.gcode.write_corrected`).

    line (n,) int64, offsets (n+1,) int64 and points (M, na) float64 of the current chunk are
    contiguous arrays (the compiled writer reads them directly); ``row`` is the next row to write.
    """

    def __init__(self, corrections, n_axes: int, in_path):
        self._it = iter(corrections)
        self.na = n_axes
        self.in_path = in_path
        self.line = np.zeros(0, np.int64)
        self.offsets = np.zeros(1, np.int64)
        self.points = np.zeros((0, n_axes))
        self.row = 0
        self.n = 0
        #: corrected points per segment row of the last :meth:`take`
        self.counts = np.zeros(0, np.int64)

    def advance(self, line_no: int) -> None:
        """Load the next chunk (the current one is used up)."""
        try:
            chunk, points, counts = next(self._it)
        except StopIteration:
            raise ValueError(f"corrections ended before line {line_no} of {self.in_path}") from None
        counts = np.asarray(counts, dtype=np.int64).reshape(-1)
        if counts.shape[0] != len(chunk) or np.any(counts < 1):
            raise ValueError("counts must have one entry >= 1 per segment row")
        offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        points = np.ascontiguousarray(points, dtype=np.float64)
        if points.shape != (offsets[-1], self.na):
            raise ValueError(f"points must be ({offsets[-1]}, {self.na}), got {points.shape}")
        if not np.all(np.isfinite(points)):
            bad = int(np.searchsorted(offsets, np.argmax(~np.isfinite(points).all(axis=1)), "right")) - 1
            raise ValueError(f"corrections hold a non-finite point for line {int(chunk.line[bad])}")
        self.line = np.ascontiguousarray(chunk.line, dtype=np.int64)
        self.offsets, self.points, self.row, self.n = offsets, points, 0, len(chunk)

    def take(self, line_no: int, k: int) -> np.ndarray:
        """The corrected points of the next k segment rows, which must belong to line_no (how many
        per row: ``counts``)."""
        parts = []
        counts = []
        while k > 0:
            if self.row >= self.n:
                self.advance(line_no)
                continue
            r = self.row
            take = min(k, self.n - r)
            if np.any(self.line[r:r + take] != line_no):
                self.mismatch(line_no)
            parts.append(self.points[self.offsets[r]:self.offsets[r + take]])
            counts.append(np.diff(self.offsets[r:r + take + 1]))
            self.row = r + take
            k -= take
        self.counts = counts[0] if len(counts) == 1 else np.concatenate(counts)
        return parts[0] if len(parts) == 1 else np.vstack(parts)

    def mismatch(self, line_no: int):
        raise ValueError(f"corrections do not match the program at line {line_no}: the segment row "
                         f"says line {int(self.line[self.row])}")

    def finish(self) -> None:
        if self.row < self.n:
            raise ValueError("corrections have more segment rows than the program")
        for extra in self._it:
            if len(extra[0]):
                raise ValueError("corrections have more segment rows than the program")

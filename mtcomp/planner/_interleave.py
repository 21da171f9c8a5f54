"""Where a chunk's internal nodes go among its segment ends: each row's inserted nodes in the order
of their parameter along the move, then the row's end (a scatter into place, not a sort of every
node of the chunk)."""
from __future__ import annotations

import numpy as np


def positions(counts: np.ndarray, rows: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(pos_end (n_rows,), pos_inner (m,)): the index among all nodes of each row's end and of each
    inserted node. counts (n_rows,): nodes per row (its inserted ones and its end); rows, t (m,):
    the row of each inserted node and its parameter along the move (0 < t < 1, distinct in a row)."""
    first = np.cumsum(counts) - counts
    pos_end = first + counts - 1
    order = np.lexsort((t, rows))
    r = rows[order]
    m = r.size
    run_start = np.ones(m, bool)
    run_start[1:] = r[1:] != r[:-1]
    rank = np.arange(m) - np.maximum.accumulate(np.where(run_start, np.arange(m), 0))
    pos_inner = np.empty(m, np.int64)
    pos_inner[order] = first[r] + rank
    return pos_end, pos_inner


def placed(ends: np.ndarray, inner: np.ndarray, pos_end: np.ndarray, pos_inner: np.ndarray):
    """The rows of ``ends`` and ``inner`` (same trailing shape) at their positions in one array
    (``pos_end`` increasing, the positions ``pos_inner`` leaves: :func:`positions`)."""
    out = np.empty((pos_end.size + pos_inner.size,) + ends.shape[1:], dtype=np.result_type(ends, inner))
    out[pos_inner] = inner
    m = pos_inner.size
    if m * 64 > pos_end.size:
        out[pos_end] = ends
        return out
    # few inserted nodes (the usual case): the ends between two of them are one slice each, copied
    # whole (a scatter copies the rows one at a time: ten to thirty times slower)
    start = 0
    for k, p in enumerate(np.sort(pos_inner).tolist()):
        out[start:p] = ends[start - k:p - k]
        start = p + 1
    out[start:] = ends[start - m:]
    return out

"""Readings of an axis approached from both sides: a reversal (backlash) to test, not repeats.

An R-test of a trunnion read once with B approached from below (run 1) and once from above (run 2)
holds each pose twice, in opposite approach directions of B. Those two runs are not repeats of each
other: a rotary backlash of 30 urad moves the ball 4.5 um between them. Two things follow:

* The held-out folds do not hold out such a run whole (:func:`run_blocks`): with run r of every file
  in fold r, the fold of run 2 holds out every reading approached from above, the fit without it
  cannot see the reversal, and the backlash candidate predicts the held-out run worse than the model
  without it (a gain of -6400 noise variances on the trunnion's two R-test files). A file whose runs
  approach from opposite sides holds out the k-th run of each direction together, when each
  direction has two runs or more, else its readings are dealt to the folds as a points file's are.
* The noise floor of such a file is judged on the base fit's residual less the reversal of that
  axis (:func:`floor_reversals`), as identify's posterior takes a reversal the model does not hold
  as error it leaves, not noise: the R-test files have no repeated pose, and their floor from the
  successive differences of the base residual was 1.24 um (true noise 0.5 um; 0.52 um without the
  backlash), which weighted them down so far that no candidate could show the backlash. Only
  there: a ball-bar circle, whose runs each turn X and Y both ways, keeps its floor (judged
  without the reversal, a circle's 0.39 um fell to 0.25 um against its 0.3 um noise, and the
  model written from it lost the weak straightness of Y it had held to 2 um).
"""
from __future__ import annotations

import numpy as np

#: a reading is one of an axis's own where that axis's error reaches this share of its largest
READS_SHARE = 0.3


def axis_reads(st, a: str) -> np.ndarray | None:
    """(n,) bool: the readings of axis ``a``'s error (where its share of the reading is
    :data:`READS_SHARE` of its largest or more), None where the data do not read it at all."""
    g = st.g.get(a)
    if g is None or not g.size or not float(np.max(np.abs(g))) > 0.0:
        return None
    return np.abs(g) > READS_SHARE * float(np.max(np.abs(g)))


def reversal_columns(st) -> dict:
    """axis -> (n,) the column of a constant reversal of that axis (``BL_<axis>``: its positioning
    error steps by half of it with the approach direction, :class:`mtcomp.models.terms.Backlash`), for
    every axis the data move whose own readings (:func:`axis_reads`) state both approach
    directions, linear and rotary alike."""
    from ._refusal import moved_axes
    moved = moved_axes(st)
    out = {}
    for k, a in enumerate(st.machine.axis_names):
        if a not in moved:
            continue
        reads = axis_reads(st, a)
        if reads is None:
            continue
        d = st.dirs[reads, k]
        if np.any(d > 0) and np.any(d < 0):
            out[a] = 0.5 * st.dirs[:, k] * st.g[a]
    return out


def _one_way_axes(dirs: np.ndarray, runs: np.ndarray, known: np.ndarray) -> dict:
    """axis index -> (per run ``known``, the side it approaches that axis from) over the axes that the
    file ``dirs`` (n, n_axes) approaches from both sides and each of its runs from one side only
    (runs that approach from both sides, or state no direction, are repeats)."""
    out = {}
    for k in range(dirs.shape[1]):
        d = dirs[:, k]
        if not (np.any(d > 0) and np.any(d < 0)):
            continue
        sides = [np.unique(np.sign(d[(runs == r) & (d != 0)])) for r in known]
        if all(s.size == 1 for s in sides):
            out[k] = [int(s[0]) for s in sides]
    return out


def _files_with_runs(st):
    """(readings of the file, their run numbers, the file's known run numbers) of every file with
    two runs or more."""
    for fi in np.unique(st.file):
        ix = np.flatnonzero(st.file == fi)
        runs = st.run[ix]
        known = np.unique(runs[runs >= 0])
        if known.size >= 2:
            yield ix, runs, known


def floor_reversals(st) -> list:
    """(n,) columns of the reversal of each axis (:func:`reversal_columns`) on the readings of the
    files whose runs approach it from opposite sides, one side each (zero elsewhere): what the noise
    floor is judged without. Elsewhere the floor stands as before: repeats are matched by approach
    direction, and a ball-bar circle, whose runs each turn X and Y both ways, keeps its floor."""
    steps = reversal_columns(st)
    rows = {a: np.zeros(len(st.file), dtype=bool) for a in steps}
    for ix, runs, known in _files_with_runs(st):
        for k in _one_way_axes(st.dirs[ix], runs, known):
            a = st.machine.axis_names[k]
            if a in rows:
                rows[a][ix] = True
    return [np.where(rows[a], steps[a], 0.0) for a in steps if rows[a].any()]


def run_blocks(st, ix: np.ndarray, runs: np.ndarray, known: np.ndarray):
    """(blocks, how) for :func:`._analysis.make_folds` of one file's readings ``ix`` with two or more
    ``known`` run numbers (``runs``: each reading's), when its runs approach an axis from opposite
    sides: blocks (the k-th run of each direction in block k) when every direction has two runs or
    more, else None (the caller deals the readings to the folds), and the sentence that says so.
    None when the runs are repeats (the caller holds out whole runs)."""
    sides = _one_way_axes(st.dirs[ix], runs, known)
    if not sides:
        return None
    keys = [tuple(v) for v in np.array(list(sides.values())).T.tolist()]
    count: dict = {}
    rank_of_run = {}
    for r, key in zip(known.tolist(), keys):
        rank_of_run[r] = count.get(key, 0)
        count[key] = rank_of_run[r] + 1
    if min(count.values()) >= 2:
        blocks = np.array([rank_of_run.get(int(r), 0) for r in runs], dtype=np.int64)
        return blocks, "runs of opposite approach directions in pairs (a reversal, not repeats)"
    return None, ("the readings of a file whose runs approach from opposite sides (a reversal, not "
                  "repeats) dealt to the folds in a shuffled order")

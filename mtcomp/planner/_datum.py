"""A part's datum outside the region the model's data reached (docs/planner.md, *One datum*).

Every block's correction is its deviation less the model's deviation at the part's datum. Where the
datum lies outside the region the data reached, along an axis that limits it, that deviation is the
model carried past its data, with no standard error: so every correction referenced to it is not
determined (its standard error infinite) and the standard-error gate leaves it uncorrected, as it
would a block standing there. An axis the data held still does not limit the region (the model is
evaluated at the held position); a datum outside along the ram alone follows the ram's rule
(:mod:`._ram`: the X Y references hold the ram's profiles at the data's edge, as at a block). With
``--extrapolate`` the corrections are referenced to the model's continuation, as before."""
from __future__ import annotations

import numpy as np

from ._evaluate import _run_starts as run_starts


class DatumRule:
    """The rule for one plan, and what it saw: :attr:`gated`, datum (machine positions, a tuple)
    -> [blocks, first line], the blocks left uncorrected for their datum."""

    def __init__(self, planner):
        self.planner = planner
        self.gated: dict = {}

    def outside(self, datum, tool_length=None) -> np.ndarray | None:
        """(n,) bool: the blocks whose part's datum (``datum`` (n, na) machine positions; the ram
        where ``tool_length`` (n,) mm puts it) lies outside the support on an axis other than the
        ram alone; None when no block's does (or the options extrapolate, or the model does not
        say where its data reached). Tested once per run of equal datums and tools."""
        p = self.planner
        if datum is None or p.support is None or p.options.extrapolate:
            return None
        datum = np.atleast_2d(np.asarray(datum, dtype=float))
        tools = None if tool_length is None else np.asarray(tool_length, dtype=float)
        new_run = run_starts(datum)
        if tools is not None:
            new_run |= run_starts(tools)
        firsts = np.flatnonzero(new_run)
        d = datum[firsts]
        out = p.outside_support(d, np.ones(d.shape, bool), None if tools is None else tools[firsts])
        whole = p.ram.whole_outside(out)
        if not whole.any():
            return None
        return whole[np.cumsum(new_run) - 1]

    def note(self, datum, gated, line) -> None:
        """Count in :attr:`gated` the blocks ``gated`` ((n,) bool or None: those whose standard
        error the datum made infinite, not those left uncorrected for another reason first), each
        datum's first ``line``."""
        if gated is None:
            return
        rows = np.flatnonzero(gated)
        if not rows.size:
            return
        datum = np.atleast_2d(np.asarray(datum, dtype=float))[rows]
        starts = np.flatnonzero(run_starts(datum))
        for r, k in zip(starts, np.diff(np.append(starts, rows.size))):
            entry = self.gated.setdefault(tuple(float(v) for v in datum[r]),
                                          [0, int(np.asarray(line)[rows[r]])])
            entry[0] += int(k)

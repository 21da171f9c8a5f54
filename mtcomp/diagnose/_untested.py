"""What the data could not test, per axis (docs/diagnose.md, REPORT.json ``untested``).

The candidates of :mod:`._candidates` need something of the data to exist at all: a reversal both
approach directions among an axis's readings, a feed dependence two feeds, a drift readings at
different times. Where the data lack it, no candidate is made, so nothing is found and nothing
refused: a verdict ``none`` would read as "no backlash" where no backlash could be seen. This
module names, per axis the data move, each effect the data could not test and why, with the same
tests the candidates use (the readings of an axis's error: where its share of the reading is 30 %
of its largest or more).
"""
from __future__ import annotations

import numpy as np

from ._candidates import _drives, _feeds
from ._reversal import axis_reads
from ._refusal import moved_axes


def _reversal(st, k: int, reads) -> str | None:
    dirs = st.dirs[reads, k]
    if np.any(dirs > 0) and np.any(dirs < 0):
        return None
    if not np.any(dirs != 0):
        return "no approach direction given (dir, dir_<axis>)"
    return f"every reading approached in {'+' if np.any(dirs > 0) else '-'} only"


def _feed(st, reads) -> str | None:
    feeds = _feeds(st, reads)
    if feeds.size >= 2:
        return None
    return f"one feed only ({feeds[0]:g} mm/min)" if feeds.size else "no feed given (feed_mm_min)"


def _drift(st, reads) -> str | None:
    if _drives(st, st.t):
        t = st.t[reads]
        t = t[np.isfinite(t)]
        if t.size >= 2 and np.ptp(t) > 0:
            return None
        return "its readings carry no time (t_s)" if not t.size else "its readings are all at one time"
    return "no times given (t_s)" if not np.isfinite(st.t).any() else "every reading at one time"


def untested(st) -> dict:
    """{axis: [{"effect", "reason"}]}: per axis the data move, the effects they could not test
    (reversal: ``backlash``/``rotary_backlash``; ``feed_dependence`` of a linear axis; drift in time:
    ``thermal_drift``); axes with none are left out."""
    out = {}
    m = st.machine
    moved = moved_axes(st)
    for k, a in enumerate(m.axis_names):
        reads = axis_reads(st, a) if a in moved else None
        if reads is None:
            continue
        rotary = m.axis(a).is_rotary
        checks = [("rotary_backlash" if rotary else "backlash", _reversal(st, k, reads))]
        if not rotary:
            checks.append(("feed_dependence", _feed(st, reads)))
        checks.append(("thermal_drift", _drift(st, reads)))
        lines = [{"effect": e, "reason": r} for e, r in checks if r is not None]
        if lines:
            out[a] = lines
    return out


#: the words of each effect in the printed line
_WORDS = {"backlash": "reversal (backlash)", "rotary_backlash": "reversal (backlash)",
          "feed_dependence": "feed dependence", "thermal_drift": "drift in time"}


def untested_lines(untested_by_axis: dict) -> list[str]:
    """The printed report's lines: one per axis with what its data could not test."""
    return [f"not testable on {a} with these data: "
            + "; ".join(f"{_WORDS.get(u['effect'], u['effect'])}: {u['reason']}" for u in items)
            for a, items in untested_by_axis.items()]

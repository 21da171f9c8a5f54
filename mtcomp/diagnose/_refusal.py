"""Why a candidate extension is refused even when it lowers the held-out residual.

A candidate that fits the data can still be no cause: its parameters may not be determined by the
data, it may act only where the data do not reach (an axis they hold still, a single feed), or its
fitted values may be physically absurd (a rotation centre further away than the machine is large, a
drift larger than the range of the readings it explains). Each rule returns one sentence, printed in
the report as ``refused: ...``, or None.
"""
from __future__ import annotations

import numpy as np

#: positions of an axis closer than this count as one (mm for linear axes, rad for rotary axes)
SAME_POSITION_MM = 1e-3
SAME_POSITION_RAD = 1e-6
#: a row counts as one where a candidate acts when its column reaches this share of the largest
ACTS_SHARE = 0.05
#: a fitted contribution whose peak-to-peak exceeds this multiple of the readings' own is absurd
MAX_RANGE_RATIO = 1.5
#: an angular error that grows by more than this multiple of itself over the data's feeds is absurd
MAX_ANGLE_GAIN = 3.0
#: a candidate's column whose largest entry is below this share of its largest column's is round-off:
#: its parameter moves no reading (a gain or a moving centre of an angle the model holds at zero)
ROUNDOFF_SHARE = 1e-9


def distinct_positions(st, axis: str, rows=None) -> np.ndarray:
    """Sorted distinct positions (mm or rad) that ``axis`` takes in the rows ``rows`` (bool mask,
    default all) of the stack."""
    k = st.machine.axis_names.index(axis)
    x = st.stood[:, k] if rows is None else st.stood[rows, k]
    tol = SAME_POSITION_RAD if st.machine.axis(axis).is_rotary else SAME_POSITION_MM
    return np.unique(np.round(x / tol)) * tol


def moved_axes(st) -> list[str]:
    """The axes the data move: two or more distinct positions among all readings."""
    return [a for a in st.machine.axis_names if distinct_positions(st, a).size >= 2]


def machine_size_mm(machine) -> float:
    """Diagonal of the linear travel (mm): nothing about the machine is further away than this."""
    spans = [ax.travel[1] - ax.travel[0] for ax in machine.linear_axes]
    return float(np.sqrt(np.sum(np.square(spans)))) if spans else 1000.0


def _acting_rows(columns: np.ndarray) -> np.ndarray:
    size = np.max(np.abs(columns), axis=1)
    top = float(size.max()) if size.size else 0.0
    return size > ACTS_SHARE * top if top > 0 else np.zeros(size.shape, dtype=bool)


def undetermined(c, dk: int) -> str | None:
    """Some of the candidate's parameters are not determined: the data fix fewer combinations of them
    than it has (beyond what the current model already explains)."""
    k = c.columns.shape[1]
    if dk < k:
        return (f"the data determine only {max(dk, 0)} of its {k} parameters (the others move nothing "
                "the current model does not already explain)")
    return None


def out_of_reach(st, c) -> str | None:
    """The candidate acts only where the data do not reach: where its columns act, its axis stands at
    one position (or, for a feed term, the feed takes one value; for a drift, time stands still)."""
    rows = _acting_rows(c.columns)
    if not rows.any():
        return "it changes no reading"
    if c.axis and c.axis in st.machine.axis_names:
        pos = distinct_positions(st, c.axis, rows)
        if pos.size < 2:
            unit, v = ("deg", np.degrees(pos[0])) if st.machine.axis(c.axis).is_rotary else ("mm", pos[0])
            return (f"it acts only on readings taken with {c.axis} at {v:.6g} {unit}: the data do not "
                    f"move {c.axis} where it acts")
    if c.effect.startswith("feed_dependent"):
        f = st.feed[rows]
        f = np.unique(np.round(f[np.isfinite(f)], 6))
        if f.size < 2:
            return "it acts only on readings taken at one feed"
    if c.effect == "thermal_drift":
        t = st.t[rows]
        t = t[np.isfinite(t)]
        if t.size < 2 or np.ptp(t) <= 0:
            return "it acts only on readings taken at one time"
    return None


def absurd(st, c, theta: np.ndarray) -> str | None:
    """The fitted values are physically absurd: a rotation centre moved further than the machine is
    large over the data's feeds, an angular error multiplied over them, or a contribution whose range
    exceeds the range of the readings it acts on (per unit)."""
    theta = np.asarray(theta, float)
    if c.effect == "feed_dependent_abbe":
        rows = _acting_rows(c.columns)
        f = st.feed[rows]
        fmax = float(np.nanmax(np.abs(f))) / 1000.0 if np.isfinite(f).any() else 0.0
        size = machine_size_mm(st.machine)
        reach = np.max(np.abs(c.columns), axis=0)
        for name, r in zip(c.params, reach):
            if name.startswith(("IRC_", "AG_")) and r <= ROUNDOFF_SHARE * reach.max():
                # its fitted value is round-off over round-off: a ratio to an angle held at zero
                comp = "E" + name.split("_")[1]
                return (f"{name} is not determined: it acts through {comp}, which the model holds at "
                        f"zero where the data reach (nothing measured it), so no reading tells how "
                        f"{comp} changes with feed")
        for name, v in zip(c.params, theta):
            if name.startswith("IRC_") and abs(v) * fmax > size:
                return (f"its rotation centre ({name}) would move {abs(v) * fmax:.3g} mm at "
                        f"{fmax * 1000:.4g} mm/min, further than the machine is large ({size:.4g} mm)")
            if name.startswith("AG_") and abs(v) * fmax > MAX_ANGLE_GAIN:
                return (f"its angular error ({name}) would grow by {abs(v) * fmax * 100:.3g} % of itself "
                        f"at {fmax * 1000:.4g} mm/min")
    contrib = c.columns @ theta
    rows = _acting_rows(c.columns)
    for u in np.unique(st.unit[rows]):
        sel = rows & (st.unit == u)
        if sel.sum() < 2:
            continue
        span_c = float(np.ptp(contrib[sel]))
        span_y = float(np.ptp(st.y[sel]))
        if span_c > MAX_RANGE_RATIO * span_y:
            return (f"its fitted contribution spans {span_c:.3g} {u}, more than the {span_y:.3g} {u} "
                    "the readings it acts on span")
    return None


def refusal(st, c, theta, dk: int) -> str | None:
    """The first reason to refuse candidate ``c`` fitted with coefficients ``theta`` adding ``dk``
    determined directions, or None."""
    return undetermined(c, dk) or out_of_reach(st, c) or absurd(st, c, theta)

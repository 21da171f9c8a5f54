"""The base's resolution along a linear axis, checked by the diagnosis on its own held-out data.

The number of spline functions per axis is chosen before the fit from the laser lines that move one
axis alone (:func:`mtcomp.models.basis.spline_size_by_cv`). A campaign can see finer shape than any
such line tells: a straightness read at eleven laser targets whose ball-bar circles pass between
them, a volumetric grid read with several set-ups. Structure then stays in the residual along that
axis, and it is the base's resolution, not an effect. So, when the diagnosis ends with structure
along a linear axis, each component of the axis at twice the resolution (knots at least
``MIN_KNOT_MM`` apart) is fitted beside the chosen model. When the one that gains most earns its
parameters on held-out data, as an extension must (BIC is not asked: most of the finer functions are
only weakly determined, and BIC counts each direction at the full log n), and a window of its
functions about the structure's peak does not explain the gain as well, there (that is a local
defect, which the diagnosis must report, and no axis is refined), the axis asks for the finer base and the
diagnosis is run again with it. The other linear axes the structure's series moves are tried the
same way, about where they stand at the structure's peak; of the axes that ask for a finer base, the
one whose component gains most is refined (a circle's structure in Z's profiles, read along Y, is
followed in part by Y's straightness on finer knots, in full by Z's). Structure along time, feed,
temperature or a rotary axis asks nothing of the base.

The finer columns are the derivative of each reading with respect to a component's value where the
axis stood (the ram: its commanded position plus the tool's length less the machine's,
docs/conventions.md "Tool length") (recovered from the base's own Jacobian columns: d reading / d c_j = d reading / d E
* phi_j(s)) times the finer functions. A reading that depends on one component at two positions (a
two-point velocity) is not of that form and gets no finer column.
"""
from __future__ import annotations

import numpy as np

from ..models.basis import LOCAL_WINDOW, RIVAL_SHARE, axis_spline, max_intervals, spline_basis
from ..models.chain import component_terms, linear_component_names, slope_carried
from ..identification._linalg import SEEN_SHARE
from ._analysis import cv_threshold

#: at most this many refinements of the base in one diagnosis
MAX_REFINEMENTS = 2
#: the structure's peak must span this many positions read for a window to be its rival (a defect)
MIN_DEFECT_POSITIONS = 4
#: ... and the window's functions must gain at least this share of their held-out gain on the
#: readings inside the window (a defect's bump about 0.8, with the base's overshoot beside it; a
#: wave two knot intervals long, which a few finer functions anywhere let the coarse ones follow
#: everywhere, about 0.4)
LOCAL_SHARE = 2.0 / 3.0


#: a component other than the positioning error may be refined below ``MIN_KNOT_MM``, to knots this
#: many times the spacing of the positions read (a screw's period shows in positioning, which keeps
#: the floor, so that diagnose names it; an angular or straightness profile has no such rival)
DATA_SPACING_KNOTS = 1.0


def data_spacing_mm(st, a: str) -> float:
    """The median spacing (mm) of the distinct positions of linear axis ``a`` that are read again
    (a repeat: the same series, pose, directions, feed and arm, in another run or pass) by readings
    that depend on its errors; inf when fewer than two. Only repeated positions count: a profile as
    fine as the positions can be checked, held out, only against other readings at the same
    positions. Read once (a CMM part's rows, each cut in one direction), a profile that fine would
    follow whatever alternates from row to row, a reversal included, and nothing could tell."""
    from ._analysis import POSITION_DECIMALS, _pose_keys
    reads = np.flatnonzero(np.abs(st.g[a]) > 0 if a in st.g else np.ones(len(st), dtype=bool))
    if reads.size < 2:
        return float("inf")
    inv = _pose_keys(st, reads)
    repeated = reads[np.bincount(inv)[inv] >= 2]
    x = np.unique(np.round(st.guideway(a)[repeated], POSITION_DECIMALS))
    return float(np.median(np.diff(x))) if x.size >= 2 else float("inf")


def finer_base_columns(st, a: str, beyond_floor: bool = False):
    """({component: ((n, m) columns, (m,) centre of each column's function, mm)}, the finer
    SplineBasis) of linear axis ``a`` at twice the base's intervals (fewer when knots would come
    closer than ``MIN_KNOT_MM``); components the data do not read are absent. None when the axis has
    no B-spline base or none finer is allowed. ``beyond_floor``: knots as close as
    ``DATA_SPACING_KNOTS`` times the data's spacing instead, for every component but the positioning
    error."""
    ax = st.machine.axis(a)
    if ax.is_rotary or ax.basis != "bspline":
        return None
    base = axis_spline(ax)
    if beyond_floor:
        h_min = DATA_SPACING_KNOTS * data_spacing_mm(st, a)
        most = int((base.hi - base.lo) // h_min) if np.isfinite(h_min) and h_min > 0 else 0
    else:
        most = max_intervals(base.lo, base.hi)
    n_int = min(2 * base.n_intervals, most)
    if n_int <= base.n_intervals:
        return None
    fine = spline_basis(base.lo, base.hi, n_int, base.degree)
    s = st.guideway(a)                  # the ram's profiles are read where it stood
    # identify's round-off rule (a component no reading sees but through the rounding of the
    # chain, an angle with no arm: its finer columns, scaled up in the held-out fits, would pass
    # their round-off for information and "gain" hundreds of noise variances)
    seen = SEEN_SHARE * max(float(np.linalg.norm(st.J, axis=0).max(initial=0.0)), 1e-300)
    out = {}
    for comp in linear_component_names(a):
        if beyond_floor and comp == f"E{a}{a}":
            continue
        carried = slope_carried(st.machine, comp)
        names = [f"{comp}_{t}" for t in component_terms(st.machine, a, comp)]
        if not names:
            continue
        Jc = st.columns(names)
        if np.linalg.norm(Jc, axis=0).max(initial=0.0) <= seen:
            continue
        phi = np.column_stack(base.functions(s, carried))
        norm = np.sum(phi * phi, axis=1)
        sens = np.sum(Jc * phi, axis=1) / np.where(norm > 0, norm, 1.0)
        # rows not of the form sens * phi (one component read at two positions) get no column
        off = np.abs(Jc - sens[:, None] * phi).max(axis=1) > 1e-6 * (np.abs(Jc).max(axis=1) + 1e-300)
        sens[off] = 0.0
        if not np.any(sens):
            continue
        # centre of B_j's support [j - degree, j + 1] knot intervals from lo
        kept = np.asarray(fine.kept(carried), dtype=float)
        out[comp] = (sens[:, None] * np.column_stack(fine.functions(s, carried)),
                     fine.lo + fine.h * (kept - 0.5 * (fine.degree - 1)))
    if not out:
        return None
    return out, fine


def finer_base(st, design, extra, current, structure):
    """(axis, finer SplineBasis, sentence) when the base at a finer resolution along a linear axis
    the final ``structure`` names takes that structure (see the module docstring), else None.
    ``extra``: the chosen extensions' columns; ``current``: their fit."""
    names = st.machine.axis_names
    linear = [a for a in names if not st.machine.axis(a).is_rotary]
    # (axis, series, lo, hi): where the structure peaks along a linear axis; then, for the other
    # linear axes its series moves, where they stand at that peak (a ball-bar circle's extreme in Y
    # is where Z turns too). Structure along time, feed or a rotary axis asks nothing of the base.
    peaks = [(s.variable.split(" ")[0], s.series, s.lo, s.hi) for s in structure
             if s.variable.endswith(" position") and s.variable.split(" ")[0] in linear]
    for a0, series, lo, hi in list(peaks):
        rows = st.series == series
        at = rows & (st.stood[:, names.index(a0)] >= lo) & (st.stood[:, names.index(a0)] <= hi)
        for b in linear:
            k = names.index(b)
            if b != a0 and np.ptp(st.stood[rows, k]) > 0 and at.any():
                peaks.append((b, series, float(st.stood[at, k].min()), float(st.stood[at, k].max())))
    # every axis the structure names is tried; of those whose finer base earns its parameters the one
    # that gains most takes the structure (a ball-bar circle's structure in Z read along Y: Y's
    # straightness on finer knots follows part of it, Z's own profiles all of it); a defect found on
    # an axis before any is refined stops the search (no other axis is refined to take its leak)
    best, seen = None, set()
    for a, series, lo, hi in peaks:
        if a in seen:
            continue
        seen.add(a)
        got = _axis_refinement(st, design, extra, current, a, series, lo, hi)
        if got == "defect":
            return None if best is None else best[1:]
        if got is not None and (best is None or got[0] > best[0]):
            best = got
    return None if best is None else best[1:]


def _axis_refinement(st, design, extra, current, a, series, lo, hi):
    """(gain, axis, finer SplineBasis, sentence) when the base of linear axis ``a`` at a finer
    resolution earns its parameters on held-out data, "defect" when a window of its finer functions
    about the structure's peak (``series`` between ``lo`` and ``hi`` along ``a``) takes that gain
    there, else None (:func:`finer_base`)."""
    from ._analysis import POSITION_DECIMALS
    got = finer_base_columns(st, a)
    if got is None:
        got = finer_base_columns(st, a, beyond_floor=True)
    if got is None:
        return None
    by_comp, basis = got
    # each component on its own (one finer than the others must not be diluted by them); the
    # one that gains most speaks for the axis: when a window takes its gain, the structure is a
    # defect in one place, and what the others gain is the defect's leak into them
    tried = []
    for comp, (fine, centres) in by_comp.items():
        fit = design.fit(np.hstack([extra, fine]))
        tried.append((current.cv_sse - fit.cv_sse, fit.rank - current.rank, comp, fine, centres))
    gain, dk, comp, fine, centres = max(tried, key=lambda t: t[0])
    if not (dk >= 1 and gain > cv_threshold(dk)):
        return None
    # the rival: the finer functions of one window about where the structure peaks
    c = 0.5 * (lo + hi)
    half = 0.5 * max(hi - lo, LOCAL_WINDOW * (basis.hi - basis.lo)) + basis.h
    window = np.abs(centres - c) <= half
    # a defect is a shape read at several positions; a peak at one or two targets of a coarse
    # line is the profile between them, not a place
    k = st.machine.axis_names.index(a)
    x = st.stood[st.series == series, k]
    resolved = np.unique(np.round(x[(x >= lo) & (x <= hi)], POSITION_DECIMALS)).size >= MIN_DEFECT_POSITIONS
    if window.any() and resolved:
        rival = design.fit(np.hstack([extra, fine[:, window]]))
        # ... and a rival in one place gains there: a wave at the knots' own scale is also
        # taken by a few finer functions anywhere, which free the coarse ones everywhere
        each = np.nan_to_num((current.cv_resid ** 2 - rival.cv_resid ** 2) * design.w ** 2)
        inside = np.abs(st.stood[:, k] - c) <= half
        local = each[inside].sum() >= LOCAL_SHARE * each.sum()
        if (local and rival.rank - current.rank <= 0.5 * dk
                and current.cv_sse - rival.cv_sse >= RIVAL_SHARE * gain):
            return "defect"
    where = "not in one place" if resolved else "at a peak too narrow to be a place"
    text = (f"the base of {a} at {basis.n_basis} spline functions (knots {basis.h:.3g} mm apart) "
            f"takes the structure along {a}: {comp} alone on them lowers the held-out sum of "
            f"squares by {gain:.3g} noise variances for {dk} parameters, {where}")
    return gain, a, basis, text

"""The tests of diagnose's greedy selection: a candidate against the model without it, rivals
against each other (parsimony, ties between axes), drifts forward in time, and the backward pass
after re-linearisation. The loop that runs them is :func:`mtcomp.diagnose._diagnose._diagnose`.

A scored candidate is a tuple ``(candidate, fit, dk, gain, dbic, ok)``: its fit with the model so
far, the directions it adds, the held-out gain and the BIC change (both in noise variances), and
whether it passes the selection tests.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ._analysis import cv_threshold
from ._candidates import Candidate, _drift_names, without_params
from ._linalg import solve_normal
from ._refusal import refusal

#: a candidate must lower the BIC by at least this much
BIC_MARGIN = 10.0
#: ... and remove at least this share of the held-out excess over the noise (a cause must be material:
#: with large unexplained structure, a column that merely leans on it gains a little everywhere)
MIN_EXCESS_SHARE = 0.05


def _forward_in_time(st, design, extra, cands) -> None:
    """A drift (in time, temperature or spindle history) must predict later readings from earlier
    ones: the model with each thermal_drift candidate and the model without it are fitted on the
    past and scored on the future; a candidate that does not lower the future's weighted sum of
    squares by more than noise could gets a veto saying so.

    The future is cut file by file: each file that carries the drift's readings (its columns are not
    zero there) is cut into forward-chained blocks of its own readings in time
    (:func:`mtcomp.diagnose._analysis.forward_folds`), and each block is predicted from every reading
    of the campaign taken before the block begins (:func:`_forward_cuts`). Cut over the whole
    campaign instead, a file read first (a warm-up laser run of Z before the other files) fell whole
    into the first block, which is only ever fitted: the drift was scored only on the later files,
    where it had settled, and refused.

    Only future readings that repeat a past one are scored (same series, same row of the model's
    columns: same axis positions, optic arm, tool, balls): there the past has fixed the geometry and
    the file's set-up, and what the future adds is the change in time, which is the drift's to
    predict. A reading at a position or of a file the past has not seen would be predicted by
    extrapolating the geometry, with or without a drift (a laser run of X cannot predict a later run
    of Y)."""
    drift = [c for c in cands if c.effect == "thermal_drift"]
    if not drift:
        return
    Bw = np.hstack([design.Aw, extra * design.w[:, None]])
    carried = np.zeros(Bw.shape[0], dtype=bool)
    for c in drift:
        carried |= np.any(c.columns != 0, axis=1)
    cuts = _forward_cuts(st, Bw, carried)
    if not cuts:
        return
    without = _forward_sse(Bw, design.zw, cuts)
    for c in drift:
        with_c = _forward_sse(np.hstack([Bw, c.columns * design.w[:, None]]), design.zw, cuts)
        if not without - with_c > cv_threshold(c.columns.shape[1]):
            c.veto = (f"predicted forward in time (fitted on earlier readings, scored on later ones "
                      f"that repeat them) it does not beat the model without it (weighted sum of "
                      f"squares {with_c:.4g} against {without:.4g})")


def _forward_cuts(st, Bw, carried) -> list:
    """[(order, n_past, scored)]: the timed readings in time order, and per cut the number of them
    in the past and the readings scored there (sorted by ``n_past``). Each file with timed readings
    ``carried`` (the drift's columns not zero) is cut into the forward folds of its own timed
    readings; a fold's block is predicted from every timed reading earlier than its first, and only
    its readings that repeat a past one (same series and row of ``Bw``, to 1e-6 of each column's
    largest entry) are scored."""
    from ._analysis import N_FOLDS, forward_folds
    timed = np.flatnonzero(np.isfinite(st.t))
    if timed.size < 2 * (N_FOLDS + 1) or np.ptp(st.t[timed]) <= 0:
        return []
    order = timed[np.argsort(st.t[timed], kind="stable")]
    t_sorted = st.t[order]
    _, series = np.unique(st.series.astype(str), return_inverse=True)
    scale = np.max(np.abs(Bw), axis=0)
    rows = np.round(Bw / np.where(scale > 0, scale, 1.0), 6)
    _, key = np.unique(np.column_stack([series, rows]), axis=0, return_inverse=True)
    key = key.ravel()
    scored_at: dict = {}
    for fi in np.unique(st.file[timed]):
        own = order[st.file[order] == fi]
        if own.size < 2 * (N_FOLDS + 1) or np.ptp(st.t[own]) <= 0 or not carried[own].any():
            continue
        for _, te in forward_folds(own.size, N_FOLDS):
            block = own[te]
            n_past = int(np.searchsorted(t_sorted, st.t[block[0]], side="left"))
            scored = block[np.isin(key[block], key[order[:n_past]])]
            if n_past and scored.size:
                scored_at.setdefault(n_past, []).append(scored)
    return [(order, n, np.concatenate(scored_at[n])) for n in sorted(scored_at)]


def _forward_sse(M, zw, cuts) -> float:
    """Weighted sum of squares of the scored readings of ``cuts`` (:func:`_forward_cuts`), each
    predicted by the least squares of ``M`` on the readings before its cut (normal equations summed
    forward in time, one solve per cut)."""
    out, G, b, done = 0.0, np.zeros((M.shape[1], M.shape[1])), np.zeros(M.shape[1]), 0
    for order, n_past, scored in cuts:
        new = order[done:n_past]
        G += M[new].T @ M[new]
        b += M[new].T @ zw[new]
        done = n_past
        theta, _ = solve_normal(G, b)
        out += float(np.sum((zw[scored] - M[scored] @ theta) ** 2))
    return out


def _backward(design, chosen, findings, fit, n) -> list:
    """One backward pass after re-linearisation: a term chosen earlier that no longer passes the
    selection tests against the model without it (a later, better-placed term or the refined
    profiles now explain its share) is removed from ``chosen`` and ``findings``. Returns the
    removed findings."""
    dropped = []
    for c in list(chosen)[::-1]:
        if len(chosen) < 2:
            break
        rest = [x for x in chosen if x is not c]
        without = design.fit(np.hstack([x.columns for x in rest]))
        dk = fit.rank - without.rank
        gain = without.cv_sse - fit.cv_sse
        dbic = fit.bic(n) - without.bic(n)
        excess = max(without.cv_sse - n, 0.0)
        if not (dk >= 1 and gain > cv_threshold(dk) and dbic < -BIC_MARGIN
                and gain >= MIN_EXCESS_SHARE * excess):
            chosen.remove(c)
            f = next(f for f in findings if f.candidate is c)
            findings.remove(f)
            dropped.append(f)
            fit = without
    return dropped


def _drop_undetermined_offsets(design, extra, current, c: Candidate, fit):
    """An Abbe candidate brings feed offsets along the directions its moved centre or its scaled
    constant angle translates (see ``_abbe_candidates``); where the data cannot tell such an offset
    from the rest of the model (a direction read at one feed only, or read only where another column
    already moves it), the offset is dropped rather than the cause refused for it. A drift acts along
    every direction (and channel) the data read; where the data cannot tell its part along one from
    the files' set-ups (a warm-up that has settled before a file of that direction begins: the
    drift's feature is constant over that file), that part is dropped alike, and so is a part the
    rank test keeps but held-out data do not ask for (:func:`_drift_parts_that_earn`). (A rotary error
    motion has no harmonic that trades with the axis's location errors to drop:
    :func:`mtcomp.models.terms.motion_harmonics`; the harmonics it names are those it writes.)
    Returns the candidate and its fit; unchanged when nothing is undetermined."""
    if c.effect == "feed_dependent_abbe":
        groups = [[p] for p in c.params if p.startswith("FOFF_")]
    elif c.effect == "thermal_drift":
        groups = _drift_parts(c)
    else:
        return c, fit
    dropped = False
    for names in groups:
        if fit.rank - current.rank >= c.columns.shape[1] or not names or len(names) == len(c.params):
            break
        trial = without_params(c, names)
        f = design.fit(np.hstack([extra, trial.columns]), cv=False)
        if f.rank - current.rank >= fit.rank - current.rank - (len(names) - 1) and f.rank <= fit.rank:
            c, fit, dropped = trial, f, True
    if dropped:
        fit = design.fit(np.hstack([extra, c.columns]))
    if c.effect == "thermal_drift":
        c, fit = _drift_parts_that_earn(design, extra, c, fit)
    return c, fit


def _drift_parts_that_earn(design, extra, c: Candidate, fit):
    """A drift's part along a direction (or channel) that the data determine only barely (a warm-up
    that has all but settled before the first file of that direction begins: a laser run of X an hour
    after the start sees 1 % of a 15-minute settling) is fitted from that sliver of its feature and
    trades with the file's set-up: 0.63 +- 2.7 um of drift along X beside a warm-up of Z, which
    predicted without the drift (as `predict` does a file without the drift's context) moved
    unseen readings of X by 0.6 um. Each part is kept only where held-out data ask for it: dropping
    it must raise the held-out sum of squares by more than noise could (``cv_threshold`` of its
    parameters). The last part always stays (the candidate as a whole is judged by the selection)."""
    for names in _drift_parts(c):
        if len(_drift_parts(c)) < 2:
            break
        trial = without_params(c, names)
        f = design.fit(np.hstack([extra, trial.columns]))
        if not f.cv_sse - fit.cv_sse > cv_threshold(len(names)):
            c, fit = trial, f
    return c, fit


def _drift_parts(c: Candidate) -> list:
    """A drift's parameters per direction or channel it acts along (``TD_<d>_<feature>``): a part
    goes whole, every feature of it (:func:`without_params` rebuilds the drift per direction, so a
    direction kept with one feature dropped would keep that feature's term)."""
    parts = [[p for p in c.params if p.startswith(f"TD_{d}_")] for d in _drift_names(c)]
    return [p for p in parts if p]


def _joint_abbe(design, extra, current, best, good, n, st, max_parts: int = 4):
    """A carriage's angular errors can depend on feed in more than one way at once (its rotation
    centre moves, shifting every angular error's centre, while one angle also grows with feed), and two
    angular errors can have profiles so alike that either alone explains most of the residual. So the
    other significant feed-dependent Abbe candidates of the same axis are added to the best one, one
    at a time (the one that gains most first, up to ``max_parts``), each kept only when it earns its
    extra parameters on held-out data and in BIC and is not refused."""
    from ._candidates import joint_abbe
    c = best[0]
    if c.effect != "feed_dependent_abbe":
        return best
    others = [s[0] for s in good if s[0].effect == c.effect and s[0].axis == c.axis and s[0] is not c]
    parts = 1
    while others and parts < max_parts:
        tried = []
        for o in others:
            pair = joint_abbe(best[0], o)
            if len(pair.params) == len(best[0].params):
                continue
            fit = design.fit(np.hstack([extra, pair.columns]))
            dk = fit.rank - current.rank
            gain = current.cv_sse - fit.cv_sse
            dbic = fit.bic(n) - current.bic(n)
            if (dk > best[2] and gain - best[3] > cv_threshold(dk - best[2]) and dbic < best[4] - BIC_MARGIN
                    and refusal(st, pair, fit.theta[-pair.columns.shape[1]:], dk) is None):
                tried.append(((pair, fit, dk, gain, dbic, True), o))
        if not tried:
            break
        (step, o) = max(tried, key=lambda t: t[0][3])
        best = step
        others = [x for x in others if x is not o]
        parts += 1
    return best


def _complexity(c: Candidate, dk: int) -> float:
    return dk + 0.1 * c.info.get("complexity", 0)


def _axis_ties(design, extra, best, good) -> list:
    """The scored candidates of ``best``'s effect on other axes that the data cannot tell from it:
    columns that add no direction to its own (to the design's rank tolerance), and a held-out gain
    that noise alone could make up (within the threshold one parameter must pass)."""
    c, fit = best[0], best[1]
    out = []
    for s in good:
        if s[0].effect != c.effect or s[0].axis == c.axis or not s[0].axis:
            continue
        if best[3] - s[3] > cv_threshold(1):
            continue
        if design.fit(np.hstack([extra, c.columns, s[0].columns])).rank == fit.rank:
            out.append(s)
    return out


class Choice(NamedTuple):
    """What :func:`_parsimony` picks among rivals: the scored candidate to add, and the more specific
    rival the data do not tell from it (None when they do)."""

    pick: tuple
    rival_alike: tuple | None


def _orders_of_one_series(a: Candidate, b: Candidate) -> bool:
    """``a`` and ``b`` are two orders of one component's Fourier series (a rotary error motion's
    ladder, ``_candidates.PDGE_LADDER``)."""
    comp = a.info.get("component")
    return (a.effect == b.effect and comp is not None and comp == b.info.get("component")
            and "order" in a.info and "order" in b.info)


def _lowest_order(best, good):
    """The scored candidate of ``best``'s series (:func:`_orders_of_one_series`) of the lowest order
    whose held-out gain no higher order of it beats by more than noise could (``cv_threshold`` of
    the directions the higher one adds).

    A higher order names no other cause, only a finer resolution of the same error motion, so it is
    chosen by held-out data alone, as the base's resolution is
    (:func:`mtcomp.models.basis.spline_size_by_cv`). Two rules it replaces dropped harmonics the
    truth has (tests/truth, harmonics 2-4 of every C error motion): the BIC's margin, whose ln n per
    coefficient (7.7 at 2,160 readings) asked a 2.2 urad fourth harmonic of a tilt motion for 25
    noise variances where held-out data gained 17 (10 asked); and a comparison with the best order
    alone, with the threshold of all the directions between them: order 3 of a tilt motion stood
    against order 5 (13.4 short of it, 15.3 asked for 4 directions) though order 4 beat it by 12.7
    (10 asked for its 2) and order 5 beat order 4 by 0.6."""
    by_order = {s[0].info["order"]: s for s in good if _orders_of_one_series(s[0], best[0])}
    by_order[best[0].info["order"]] = best
    ladder = [by_order[o] for o in sorted(by_order)]
    for k, s in enumerate(ladder):
        if all(h[3] - s[3] <= cv_threshold(max(h[2] - s[2], 1)) for h in ladder[k + 1:]):
            return s
    return best


def _parsimony(best, good) -> Choice:
    """Among rivals of ``best`` (explanations of the same residual), prefer the simplest one (fewer
    parameters; then uniform offset before direction lag before an Abbe term) whose held-out gain is
    not significantly smaller, or whose BIC is not worse by ``BIC_MARGIN``: a more specific cause must
    be earned by a margin in the data. ``rival_alike`` of the result is ``best`` when both tests lean
    to it against the simpler pick of another name (effect or axis), a larger held-out gain and a
    lower BIC, but only one by its margin: the data then do not tell the two names apart. Only the
    final pick is compared with ``best`` so. The orders of one error motion's series are no rivals
    of each other: :func:`_lowest_order` chooses among them."""
    c = best[0]
    pick, alike = best, None
    for s in good:
        # rivals: the same residual's explanations, or a candidate made of part of this one's terms
        # (a feed offset beside an IRC shift that carries that offset)
        related = (c.rivals and s[0].rivals == c.rivals) or set(s[0].params) < set(c.params)
        if (not related or _orders_of_one_series(s[0], c)
                or _complexity(s[0], s[2]) >= _complexity(pick[0], pick[2])):
            continue
        # the more specific cause must pass both selection tests against the simpler one: its extra
        # parameters must gain more than noise could held out, and lower the BIC by the margin
        gain_earned = s[3] < best[3] - cv_threshold(max(best[2] - s[2], 1))
        bic_earned = s[4] > best[4] + BIC_MARGIN
        if not (gain_earned and bic_earned):
            pick = s
            lean = s[3] < best[3] and s[4] > best[4]
            other_name = (s[0].effect, s[0].axis) != (c.effect, c.axis)
            alike = best if lean and gain_earned != bic_earned and other_name else None
    if pick is best and "order" in c.info:
        pick = _lowest_order(best, good)
    return Choice(pick, alike)

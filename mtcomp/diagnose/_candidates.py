"""The library of candidate extensions, one per effect a diagnosis reports (docs/diagnose.md).

Each candidate is a symbolic extension term of the error model (mtcomp.models.terms) together with
its Jacobian columns at the current fit (from the probe model, see ``_stack``), so that selection is
linear algebra and the chosen terms go straight into MODEL.json.

Candidates that compete for the same residual share a ``rivals`` key ('feed:X', 'thermal'); the
selection picks among rivals by held-out gain (with a parsimony margin), never by the order in which
they are listed.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import minimize_scalar

from ..models.terms import (AbbeIRC, Backlash, ChannelDrift, FeedOffset, PeriodicError,
                            RotaryErrorMotion, ThermalDrift, motion_harmonics,
                            positioning_component)
from ..models.basis import axis_spline
from . import _analysis as an
from ._analysis import cv_threshold
from ._reversal import axis_reads, reversal_columns
from ._stack import MOTION_LETTERS

#: false-alarm probability below which a spectral line makes a periodic candidate
LINE_FAP = 1e-3


@dataclass(eq=False)
class Candidate:
    """One extension of the current model.

    effect : the report's effect name; axis : machine axis ('' for campaign-wide drift); variant : which form.
    columns : (n, k) Jacobian columns (file units per internal parameter unit).
    terms : extension terms (mtcomp.models.terms) that implement it.
    params : (k,) parameter names of ``terms``, one per column.
    rivals : key shared by candidates that explain the same residual.
    info : what the report needs (period, time constant, spectral line ...).
    veto : a reason the data refuse this candidate (it is then never chosen), or None.
    build : callable(stack) -> columns, to rebuild them after the stack is re-linearised.
    """

    effect: str
    axis: str
    variant: str
    columns: np.ndarray
    terms: list
    params: list
    rivals: str = ""
    info: dict = field(default_factory=dict)
    veto: str | None = None
    build: object = None

    def rebuild(self, st) -> np.ndarray:
        """The candidate's columns for the stack's current linearisation point."""
        return self.build(st) if self.build is not None else self.columns

    @property
    def key(self) -> str:
        return f"{self.effect}:{self.axis}:{self.variant}"


def _significant(col: np.ndarray, ref: float) -> bool:
    return bool(np.any(np.abs(col) > 1e-9 * max(ref, 1e-300)))


def _feeds(st, sel):
    f = st.feed[sel]
    f = f[np.isfinite(f)]
    return np.unique(np.round(f, 6))


def generate(st, design, extra: np.ndarray, resid: np.ndarray, chosen_keys: set[str]) -> list[Candidate]:
    """Every candidate that the data could support, given the current model (``extra`` columns beyond
    the common block, ``resid`` its full-data residual)."""
    from ._refusal import moved_axes
    m = st.machine
    out: list[Candidate] = []
    moved = moved_axes(st)
    both_ways = reversal_columns(st)
    for k, a in enumerate(m.axis_names):
        if a not in moved:
            continue                        # no term is named on an axis the data do not move
        reads = axis_reads(st, a)
        if reads is None:
            continue
        rotary = m.axis(a).is_rotary
        dirs = st.dirs[reads, k]
        # backlash: both approach directions must be present among readings of this axis's error
        if a in both_ways:
            def bl(s, k=k, a=a):
                return (0.5 * s.dirs[:, k] * s.g[a])[:, None]
            out.append(Candidate("rotary_backlash" if rotary else "backlash", a, "step", bl(st),
                                 [Backlash(a)], [f"BL_{a}"], rivals=f"backlash:{a}",
                                 info={"complexity": 0}, build=bl))
            profile = _backlash_profile_candidate(st, a, k, reads)
            if profile is not None:
                out.append(profile)
        if not rotary:
            feeds = _feeds(st, reads)
            if feeds.size >= 2:
                def fo(s, a=a, k=k, signed=False):
                    col = s.g[a] * np.nan_to_num(s.feed, nan=0.0) / 1000.0
                    return (col * s.dirs[:, k] if signed else col)[:, None]
                out.append(Candidate("feed_dependent_offset", a, "uniform", fo(st),
                                     [FeedOffset(a)], [f"FOFF_{a}"], rivals=f"feed:{a}",
                                     info={"complexity": 0}, build=fo))
                if np.any(dirs > 0) and np.any(dirs < 0):
                    def fl(s, a=a, k=k):
                        return fo(s, a, k, True)
                    out.append(Candidate("feed_dependent_offset", a, "lag", fl(st),
                                         [FeedOffset(a, signed=True)], [f"FOFF_{a}"], rivals=f"feed:{a}",
                                         info={"complexity": 1}, build=fl))
                out.extend(_abbe_candidates(st, a))
            out.extend(_periodic_candidates(st, design, extra, resid, a))
        else:
            out.extend(_pdge_candidates(st, a))
    out.extend(_thermal_candidates(st, design, extra))
    return [c for c in out if c.key not in chosen_keys and _significant(c.columns, 1.0)]


def _backlash_profile_candidate(st, a: str, k: int, reads) -> Candidate | None:
    """Backlash whose reversal varies along a linear axis (a bidirectional pitch table's shape), on
    the axis's own spline basis: the step's column plus one per zero-mean spline function. Offered
    only where both directions are read at three or more distinct positions; the selection takes it
    over the constant step only when held-out data earn the extra parameters."""
    ax = st.machine.axis(a)
    if ax.is_rotary or ax.basis != "bspline":
        return None
    x = st.q[reads, k]
    both = [v for v in np.unique(np.round(x, 3))
            if np.any((np.abs(x - v) < 1e-3) & (st.dirs[reads, k] > 0))
            and np.any((np.abs(x - v) < 1e-3) & (st.dirs[reads, k] < 0))]
    if len(both) < 3:
        return None
    term = Backlash(a, profile=True)
    names = [s.name for s in term.param_specs(st.machine)]

    def cols(s, k=k, a=a):
        step = 0.5 * s.dirs[:, k] * s.g[a]
        phis = axis_spline(s.machine.axis(a)).functions(s.guideway(a), False)
        return np.column_stack([step] + [step * phi for phi in phis])
    return Candidate("backlash", a, "profile", cols(st), [term], names, rivals=f"backlash:{a}",
                     info={"complexity": 1}, build=cols)


def _abbe_candidates(st, a: str) -> list[Candidate]:
    """Yang et al. (2020): one candidate per way the Abbe error of axis ``a`` can depend on feed: the
    centre of one angular error (E<b><a>, b = A, B, C) shifted along one coordinate in proportion to feed
    (``IRC_<b><a>_<c>_f``), or that angular error scaled by feed (``AG_<b><a>``). One parameter each,
    so that the report can say what moves."""
    cands = []
    for b in "ABC":
        for c in [x for i, x in enumerate("XYZ") if i != "ABC".index(b)]:
            name = f"IRC_{b}{a}_{c.lower()}_f"
            if name not in st.probe.param_names:
                continue
            # the constant part of an angular error is not in the base model (laser zero offsets and
            # set-ups take it), yet a centre that moves with feed turns it into a uniform feed offset,
            # perpendicular to the rotation and to the shift: it comes with the IRC shift, so that one
            # cause is not split into an Abbe finding and an offset finding (on this or another axis)
            d = next(x for x in "XYZ" if x not in (c, "XYZ"["ABC".index(b)]))
            if d in st.g and np.max(np.abs(st.g[d])) > 1.0:     # d is read (not round-off)
                build = _irc_with_offset(name, d)
                cands.append(Candidate("feed_dependent_abbe", a, f"irc:{name}", build(st),
                                       [AbbeIRC(a, angles=b, feed=True), FeedOffset(d)], [name, f"FOFF_{d}"],
                                       rivals=f"feed:{a}", info={"complexity": 2}, build=build))
            else:
                cands.append(Candidate("feed_dependent_abbe", a, f"irc:{name}", st.columns([name]),
                                       [AbbeIRC(a, angles=b, feed=True)], [name], rivals=f"feed:{a}",
                                       info={"complexity": 2}, build=_probe_columns([name])))
        name = f"AG_{b}{a}"
        if name in st.probe.param_names:
            cands.append(Candidate("feed_dependent_abbe", a, f"gain:{name}", st.columns([name]),
                                   [AbbeIRC(a, angles=b, feed=False, angle_gain=True)], [name],
                                   rivals=f"feed:{a}", info={"complexity": 2}, build=_probe_columns([name])))
            # an angle that scales as a whole scales its constant part too, which the base model does
            # not hold (set-ups take it): without its own column that part, an angle uniform along the
            # axis that grows with feed, is left to terms of other axes and named there
            # that part turns about the carriage's true centre, which is not the model's reference
            # point: about the model's, it comes with a translation perpendicular to the rotation,
            # uniform and in proportion to feed (as the IRC shift's offset above)
            both = [name, f"AF_{b}{a}"]
            perp = [x for x in "XYZ" if x != "XYZ"["ABC".index(b)]
                    and x in st.g and np.max(np.abs(st.g[x])) > 1.0]
            if both[1] in st.probe.param_names:
                build = _with_offsets(both, perp)
                cands.append(Candidate("feed_dependent_abbe", a, f"gain+constant:{name}", build(st),
                                       [AbbeIRC(a, angles=b, feed=False, angle_gain=True, angle_feed=True)]
                                       + [FeedOffset(d) for d in perp],
                                       both + [f"FOFF_{d}" for d in perp], rivals=f"feed:{a}",
                                       info={"complexity": 2}, build=build))
    return cands


def without_params(c: Candidate, names) -> Candidate:
    """``c`` without the accompanying parameters ``names``: the feed offsets (``FOFF_<d>``) of an
    Abbe candidate (their columns and their FeedOffset terms go, the cause's own parameters stay), or
    the directions and channels (``TD_<d>_<feature>``) of a drift (:func:`_drift_candidate`)."""
    keep = [i for i, n in enumerate(c.params) if n not in names]
    if c.effect == "thermal_drift":
        only = {d for d in _drift_names(c) if any(c.params[i].startswith(f"TD_{d}_") for i in keep)}
        out = _drift_candidate(None, c.info["driver"], c.variant, c.info["features"], c.info, only,
                               (c.columns[:, keep], [c.params[i] for i in keep]))
        out.veto = c.veto
        return out
    gone = {n[len("FOFF_"):] for n in names}
    terms = [t for t in c.terms if not (isinstance(t, FeedOffset) and t.axis in gone)]

    def build(st):
        return c.rebuild(st)[:, keep]
    return Candidate(c.effect, c.axis, c.variant, c.columns[:, keep], terms, [c.params[i] for i in keep],
                     rivals=c.rivals, info=dict(c.info), veto=c.veto, build=build)


def _with_offsets(names, dirs):
    def build(st):
        f = np.nan_to_num(st.feed, nan=0.0) / 1000.0
        return np.column_stack([st.columns(names)] + [st.g[d] * f for d in dirs])
    return build


def _irc_with_offset(name, a):
    def build(st):
        return np.column_stack([st.columns([name])[:, 0],
                                st.g[a] * np.nan_to_num(st.feed, nan=0.0) / 1000.0])
    return build


def _probe_columns(names):
    def build(st):
        return st.columns(names)
    return build


def joint_abbe(c1: Candidate, c2: Candidate) -> Candidate:
    """One feed-dependent Abbe candidate made of two one-parameter ones of the same axis."""
    keep = [i for i, n in enumerate(c2.params) if n not in c1.params]
    params = c1.params + [c2.params[i] for i in keep]
    abbe = [n for n in params if n.startswith(("IRC_", "AG_", "AF_"))]
    letters = "".join(sorted({n.split("_")[1][0] for n in abbe}))
    terms = [AbbeIRC(c1.axis, angles=letters, feed=any(n.startswith("IRC_") for n in abbe),
                     angle_gain=any(n.startswith("AG_") for n in abbe),
                     angle_feed=any(n.startswith("AF_") for n in abbe))]
    terms += list({t.key(): t for t in c1.terms + c2.terms if isinstance(t, FeedOffset)}.values())

    def build(st):
        return np.hstack([c1.rebuild(st), c2.rebuild(st)[:, keep]])
    return Candidate("feed_dependent_abbe", c1.axis, f"{c1.variant}+{c2.variant}",
                     np.hstack([c1.columns, c2.columns[:, keep]]), terms, params, rivals=c1.rivals,
                     info={"complexity": 3}, build=build)


def _periodic_candidates(st, design, extra, resid, a: str) -> list[Candidate]:
    lines = [ln for ln in an.spectral_lines(st, resid, a) if ln.fap < LINE_FAP]
    out = []
    for ln in lines[:2]:
        def cols(period, s=st):
            w = 2 * np.pi * s.guideway(a) / period
            return np.column_stack([s.g[a] * np.cos(w), s.g[a] * np.sin(w)])

        def sse(period):
            return design.fit(np.hstack([extra, cols(period)]), cv=False).sse

        def refined(span):
            half = ln.period ** 2 / max(span, ln.period) * 0.75
            lo, hi = max(ln.period - half, ln.period * 0.5), ln.period + half
            return float(minimize_scalar(sse, bounds=(lo, hi), method="bounded",
                                         options={"xatol": 1e-4 * ln.period}).x)

        ser = an.axis_series(st, resid, a)
        span = float(np.ptp(ser[0])) if ser is not None else 0.0
        period = refined(span)
        agree, text = an.parts_agree(st, resid, a, period)
        narrow = an.resolved_span(st, resid, a, ln.period)
        if not agree and narrow < span:
            # where only part of the travel resolves the line (a fine run among sparse targets,
            # which alias it), its period is known only to the width that part gives
            wide = refined(narrow)
            agree_w, text_w = an.parts_agree(st, resid, a, wide)
            if agree_w:
                period, agree, text = wide, agree_w, text_w
        cand = Candidate("periodic_error", a, f"{period:.6g}mm", cols(period), [PeriodicError(a, period)],
                         [f"PER_{a}_c", f"PER_{a}_s"], rivals=f"periodic:{a}",
                         build=lambda s, period=period, cols=cols: cols(period, s),
                         info={"line": ln, "period_mm": period, "parts": text,
                               # the period was searched: the best of M frequencies needs 2 ln M more
                               "search_penalty": 2.0 * np.log(max(ln.n_independent, 1.0))})
        if not agree:
            cand.veto = f"the line does not replicate along the travel ({text})"
        else:
            cand.veto = _finer_profile_veto(st, design, extra, a, cand)
        out.append(cand)
    return out


#: the rival of a periodic error is the axis's positioning profile on knots this many times closer
#: than the line's period: a cubic spline on such knots follows at most about 12 % of a sine of that
#: period (and all of a sine 2.5 knot spacings long), so it takes what the base's knots missed of
#: slower structure, not the line itself
RIVAL_KNOTS_PER_PERIOD = 1.5
#: a line slower than that (the base's knots already follow part of it: a shape on the base's own
#: scale) has as rival the profile on this many times the base's knot intervals, which follows it
FINER_PROFILE = 2
#: ... the rival has at most this many times the base's spline functions
FINER_PROFILE_MAX = 4


def finer_profile_columns(st, a: str, period_mm: float) -> tuple[np.ndarray, float]:
    """(n, m) columns of the positioning error of linear axis ``a`` on a finer spline over the base's
    range (zero-mean functions, as the base's): the base model at a finer resolution, for that one
    component. Knots ``period_mm / RIVAL_KNOTS_PER_PERIOD`` apart when that is closer than the base's
    (the rival cannot follow a sine of ``period_mm``), else ``FINER_PROFILE`` times the base's
    intervals (the line is on the base's own scale), and never closer than ``MIN_KNOT_MM`` (the
    base's own limit); and the knot spacing (mm). (n, 0) columns when the data hold no more
    positions than the base has functions, or the rival would be no finer than the base."""
    from ..models.basis import max_intervals, spline_basis
    ax = st.machine.axis(a)
    if ax.is_rotary or ax.basis != "bspline":
        return np.zeros((len(st), 0)), 0.0
    base = axis_spline(ax)
    reads = np.abs(st.g[a]) > 0
    distinct = np.unique(np.round(st.guideway(a)[reads], 3)).size
    if period_mm / RIVAL_KNOTS_PER_PERIOD < base.h:
        n_intervals = int(np.ceil((base.hi - base.lo) * RIVAL_KNOTS_PER_PERIOD / period_mm))
    else:
        n_intervals = FINER_PROFILE * base.n_intervals
    # never finer than the base itself may become (docs/identification.md): a sine two or three
    # of those knot spacings long is what diagnose names, not a profile the base could follow
    n_intervals = min(n_intervals, max_intervals(base.lo, base.hi))
    n_basis = min(n_intervals + 3, FINER_PROFILE_MAX * base.n_basis, distinct)
    if n_basis <= base.n_basis:
        return np.zeros((len(st), 0)), 0.0
    fine = spline_basis(base.lo, base.hi, n_basis - 3, 3)
    return np.column_stack([st.g[a] * phi for phi in fine.functions(st.guideway(a), False)]), fine.h


def _finer_profile_veto(st, design, extra, a: str, cand: Candidate) -> str | None:
    """A line in the residual along an axis may be a smooth part of the positioning profile that the
    base's spline is too coarse to follow (a profile with wiggles a few centimetres apart), not a
    periodic error. The rival is the base at a finer resolution (see :func:`finer_profile_columns`):
    the sine must still lower the held-out sum of squares by more than noise could beyond that finer
    profile, else it is refused. The rival counts only when it predicts held-out readings better than
    the current model: where held-out data are whole stretches of the travel, a finer profile cannot
    predict what it was not fitted to (and a sine can), so there it is no rival."""
    fine, spacing = finer_profile_columns(st, a, cand.info["period_mm"])
    if fine.shape[1] == 0:
        return None
    rival = design.fit(np.hstack([extra, fine]))
    if rival.cv_sse > design.fit(extra).cv_sse:
        return None
    both = design.fit(np.hstack([extra, fine, cand.columns]))
    gain = rival.cv_sse - both.cv_sse
    need = cv_threshold(max(both.rank - rival.rank, 1)) + cand.info.get("search_penalty", 0.0)
    if gain > need:
        return None
    return (f"a positioning profile of {a} on {fine.shape[1]} spline functions (knots "
            f"{spacing:.3g} mm apart) explains the line as well: beyond it the sine lowers the held-out "
            f"sum of squares by {gain:.3g} noise variances, not more than the {need:.3g} noise could; "
            "a smooth profile the base's resolution does not follow, not a periodic error")


#: the orders (highest harmonic) of the error-motion candidates offered per component, up to the
#: probe's; held-out data choose among them (the simplest whose gain the others do not beat by more
#: than noise could, ``_selection._parsimony``)
PDGE_LADDER = (1, 2, 3, 4, 5, 6, 8)


def _pdge_candidates(st, a: str) -> list[Candidate]:
    """Error motions of rotary axis ``a`` beyond its location errors, one candidate per component and
    order: Fourier series of the angle up to each order of ``PDGE_LADDER`` that the probe holds and
    the data's distinct angles determine (2 order + 1 of them)."""
    k = st.machine.axis_names.index(a)
    angles = np.unique(np.round(np.mod(st.q[:, k], 2 * np.pi), 4))
    out = []
    for letters in MOTION_LETTERS:
        comp = f"{letters}{a}"
        if comp == positioning_component(a):
            continue
        top = max((t.order for t in st.probe.terms
                   if isinstance(t, RotaryErrorMotion) and t.component == comp), default=0)
        for order in [o for o in PDGE_LADDER if o <= top and angles.size >= 2 * o + 1]:
            names = [f"{comp}_{cs}{h}" for h in motion_harmonics(comp, order) for cs in "cs"]
            if not names:
                continue
            out.append(Candidate("rotary_pdge", a, f"{comp}:{order}", st.columns(names),
                                 [RotaryErrorMotion(comp, order=order)], names, rivals=f"pdge:{a}",
                                 info={"component": comp, "order": order}, build=_probe_columns(names)))
    return out


# ------------------------------------------------------------------------------------ thermal
def _drift_columns(st, feature_names, only=None):
    """Columns and parameter names of tip drift (X, Y, Z) and channel drift for the features (of the
    directions and channels in ``only``, when given)."""
    cols, params, dirs, chans = [], [], [], []
    for d in "XYZ":
        if np.any(st.h[d]) and (only is None or d in only):
            dirs.append(d)
    chans = [c for c, v in st.hc.items() if np.any(v) and (only is None or c in only)]
    for f in feature_names:
        v = st.feature(f)
        # a direction or channel none of whose readings has the feature (e.g. laser files without
        # temperatures) gets no column: its parameter stays at zero, it is not 'undetermined'
        for name, h in [(d, st.h[d]) for d in dirs] + [(c, st.hc[c]) for c in chans]:
            col = h * v
            if np.any(col):
                cols.append(col)
                params.append(f"TD_{name}_{f}")
    return (np.column_stack(cols) if cols else np.zeros((len(st), 0))), params, dirs, chans


def _drift_terms(driver, feature_names, dirs, chans):
    terms = []
    if dirs:
        terms.append(ThermalDrift(driver, tuple(feature_names), "".join(dirs)))
    if chans:
        terms.append(ChannelDrift(driver, tuple(feature_names), tuple(chans)))
    return terms


def _drift_names(c: Candidate) -> list:
    """The directions (X, Y, Z) and channels a drift candidate's terms act along."""
    out = []
    for t in c.terms:
        out += list(t.channels) if isinstance(t, ChannelDrift) else list(t.directions)
    return out


def _drift_candidate(st, driver, variant, names, info=None, only=None, made=None):
    """A drift of ``driver`` on the features ``names``, along every direction and channel the data
    read (or those in ``only``); ``made``: its (columns, parameter names) when already built."""
    if made is None:
        cols, params, dirs, chans = _drift_columns(st, names, only)
    else:
        cols, params = made
        dirs = [d for d in "XYZ" if d in only]
        chans = sorted(only - set("XYZ"))
    if cols.shape[1] == 0:
        return None

    def build(s):
        c, p, *_ = _drift_columns(s, names, only)
        return c[:, [p.index(n) for n in params]]
    return Candidate("thermal_drift", "", variant, cols, _drift_terms(driver, names, dirs, chans), params,
                     rivals="thermal", info={**(info or {}), "driver": driver, "features": list(names)},
                     build=build)


def spindle_heat_name(tau_s: float) -> str:
    """Feature name of the spindle heat state with time constant tau (s), whole seconds."""
    return f"spindle_heat_{round(tau_s):d}"


def _best_tau(st, design, extra, make_names, lo, hi):
    """Time constant (s) in [lo, hi] minimising the fit's SSE (1-D search in log tau)."""
    def sse(log_tau):
        cols, *_ = _drift_columns(st, make_names(float(np.exp(log_tau))))
        return design.fit(np.hstack([extra, cols]), cv=False).sse
    res = minimize_scalar(sse, bounds=(np.log(lo), np.log(hi)), method="bounded",
                          options={"xatol": 0.02})
    return float(np.round(np.exp(res.x)))


def _drives(st, v) -> bool:
    """Whether a context column ``v`` (time, speed, a temperature; NaN unknown) can drive a drift:
    known at half or more of the readings of at least one file, and varying. A file without it (a
    ball bar without times) leaves the other files' drift to be found: the drift's columns are zero
    on its readings."""
    known = np.isfinite(v)
    if not known.any() or np.ptp(v[known]) <= 0:
        return False
    return any(known[st.file == fi].mean() >= 0.5 for fi in np.unique(st.file))


def _thermal_candidates(st, design, extra) -> list[Candidate]:
    t = st.t
    known = np.isfinite(t)
    if not _drives(st, t):
        return []
    span = float(np.ptp(t[known]))
    out = []
    c = _drift_candidate(st, "time", "time", ["time_h"], {"complexity": 0})
    if c is not None:
        out.append(c)
    # a warm-up that settles: 1 - exp(-t / tau), tau by a 1-D search (one more effective parameter)
    tau = _best_tau(st, design, extra, lambda tau: [f"time_exp_{round(tau):d}"], span / 30.0, span * 3.0)
    c = _drift_candidate(st, "time", "time (exponential)", [f"time_exp_{round(tau):d}"],
                         {"tau_s": tau, "complexity": 1, "search_penalty": 2.0})
    if c is not None:
        out.append(c)
    sp = st.spindle
    if _drives(st, sp):
        tau = _best_tau(st, design, extra, lambda tau: [spindle_heat_name(tau)], 60.0, span)
        c = _drift_candidate(st, "spindle", "spindle", [spindle_heat_name(tau)],
                             {"tau_s": tau, "complexity": 2, "search_penalty": 2.0})
        if c is not None:
            out.append(c)
    temps = [n for n, v in st.temps.items() if _drives(st, v)]
    for n in temps:
        c = _drift_candidate(st, "temperature", f"temp_{n}", [f"dtemp_{n}"],
                             {"temperatures": [n], "complexity": 2})
        if c is not None:
            out.append(c)
    if len(temps) > 1:
        c = _drift_candidate(st, "temperature", "all temperatures", [f"dtemp_{n}" for n in temps],
                             {"temperatures": temps})
        if c is not None:
            out.append(c)
    return out


def temperature_regression(st) -> Candidate | None:
    """The plain linear regression of every reading on every temperature (rise over its first
    reading), as a candidate: the usual thermal model, reported beside the diagnosis as a reference."""
    temps = [n for n, v in st.temps.items() if _drives(st, v)]
    if not temps:
        return None
    return _drift_candidate(st, "temperature", "all temperatures", [f"dtemp_{n}" for n in temps],
                            {"temperatures": temps})

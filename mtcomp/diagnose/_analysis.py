"""Residual analysis: noise floor, held-out folds, step test, spectrum, and the search for structure.

Everything here works on a :class:`~mtcomp.diagnose._stack.Stack` and a residual vector (file units:
um for lengths, urad for angles).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import signal, stats

#: the largest number of folds of the K-fold held-out evaluation
MAX_FOLDS = 5
#: positions (mm or rad) closer than this count as the same target when matching repeats
POSITION_DECIMALS = 4
#: the repeats must give at least this many degrees of freedom for their noise floor (with 12, a
#: standard deviation is off by a third one time in ten: a few poses two circles share are no floor)
MIN_REPEAT_DOF = 30
#: a series (file, axis, component) whose own repeats give a noise floor off the pooled one by more
#: than this factor is weighted by its own (a laser run of Z at 0.36 um beside X and Y at 2-3 um)
SERIES_NOISE_FACTOR = 2.0


# ------------------------------------------------------------------------------------ noise floor
@dataclass
class Noise:
    """Noise floor of one unit class ('um' or 'urad').

    sigma : standard deviation of one reading, file units. dof : degrees of freedom behind it.
    source : 'repeats' (pooled standard deviation of repeated readings at the same pose, direction
        and conditions) or 'robust' (no repeats: 1.4826 MAD of successive differences / sqrt 2).
    n_groups : number of repeat groups used. by_series : series -> its own floor (file units), for
        the series whose repeats give one (at least ``MIN_REPEAT_DOF`` dof) off the pooled one by
        more than ``SERIES_NOISE_FACTOR``: those readings are weighted by their own floor.
    """

    unit: str
    sigma: float
    dof: int
    source: str
    n_groups: int = 0
    by_series: dict = field(default_factory=dict)

    def sigma_of(self, series) -> np.ndarray:
        """(n,) the floor each reading of ``series`` (n,) is weighted by."""
        out = np.full(len(series), self.sigma)
        for name, sigma in self.by_series.items():
            out[np.asarray(series) == name] = sigma
        return out


def _pose_keys(st, sel):
    """Integer key per observation in ``sel``: same series, pose, set-up (tool, balls), directions,
    feed and arm."""
    cols = [st.series[sel].astype(str)]
    setup = getattr(st, "setup", None)
    setup = np.zeros((sel.size, 1)) if setup is None else np.round(setup[sel], 3)
    parts = [np.round(st.q[sel], POSITION_DECIMALS), setup, st.dirs[sel],
             np.round(np.nan_to_num(st.feed[sel], nan=-1.0), 3)[:, None], np.round(st.arm[sel], 3),
             np.round(np.nan_to_num(st.spindle[sel], nan=-1.0), 1)[:, None]]
    num = np.hstack(parts)
    _, inv_s = np.unique(cols[0], return_inverse=True)
    key = np.column_stack([inv_s, num])
    _, inv = np.unique(key, axis=0, return_inverse=True)
    return inv.reshape(-1)


def _detrend_runs(st, resid, sel):
    """Remove from ``resid[sel]`` a mean (and a slope in time, when t varies) per (series, run): slow
    drift between and within runs must not count as noise of a repeated reading."""
    r = resid[sel].copy()
    keys = np.array([f"{s}|{k}" for s, k in zip(st.series[sel], st.run[sel])])
    t = st.t[sel]
    for key in np.unique(keys):
        ix = np.flatnonzero(keys == key)
        tt = t[ix]
        if ix.size >= 6 and np.all(np.isfinite(tt)) and np.ptp(tt) > 0:
            X = np.column_stack([np.ones(ix.size), (tt - tt.mean()) / np.ptp(tt)])
            coef, *_ = np.linalg.lstsq(X, r[ix], rcond=None)
            r[ix] -= X @ coef
        elif ix.size >= 2:
            r[ix] -= r[ix].mean()
    return r


def noise_floor(st, resid: np.ndarray, n_params: int = 0,
                leverage: np.ndarray | None = None) -> dict[str, Noise]:
    """Noise floor per unit class from repeated readings of the base-fit residual ``resid``.

    Repeats: same series, pose, approach directions, feed, arm and spindle speed, in different runs
    (or repeated within one), when they give at least ``MIN_REPEAT_DOF`` degrees of freedom. The
    residual is first freed of a per-(series, run) offset and time trend (readings that disagree
    with their repeats were left out before, mtcomp.measurement.outliers).
    Classes without repeats fall back to a robust estimate (Noise.source says which), scaled
    by sqrt(n / (n - p)) for the degrees of freedom p the fit took from the class's residual: the
    sum of its readings' ``leverage`` (n,) (the hat matrix's diagonal of the fit that left
    ``resid``) when given, else its share of ``n_params``. A file kind of a class without repeats
    whose own robust floor exceeds the pooled one is judged by its own, as beside repeats
    (:func:`_kind_floors`): three CMM parts at 0.8 um beside a ball bar at 0.3 um were weighted
    and judged by the 0.36 um pooled over both, the ball bar's 720 readings against their 201.
    """
    out = {}
    posed = np.array([k != "thermal" for k in st.kinds])[st.file]
    for unit in ("um", "urad", "um/min"):
        sel = np.flatnonzero((st.unit == unit) & np.isfinite(resid))
        if sel.size == 0:
            continue
        ps = sel[posed[sel]]
        sigma, dof, groups = np.nan, 0, 0
        if ps.size:
            r = _detrend_runs(st, resid, ps)
            inv = _pose_keys(st, ps)
            counts = np.bincount(inv)
            means = np.bincount(inv, weights=r) / counts
            dev = r - means[inv]
            rep = counts[inv] >= 2
            groups = int(np.sum(counts >= 2))
            dof = int(np.sum(counts[counts >= 2] - 1))
            if dof >= MIN_REPEAT_DOF:
                sigma = float(np.sqrt(np.sum(dev[rep] ** 2) / dof))
        if np.isfinite(sigma) and sigma > 0:
            own = _series_floors(st.series[ps], inv, dev, rep, sigma)
            own.update(_kind_floors(st, resid, sel, ps[rep], sigma, n_params, leverage))
            out[unit] = Noise(unit, sigma, dof, "repeats", groups, own)
        else:
            dof = _class_dof(sel, len(resid), n_params, leverage)
            sigma = robust_sigma(st, resid, sel) * np.sqrt(sel.size / dof)
            own = _kind_floors(st, resid, sel, sel[:0], sigma, n_params, leverage)
            out[unit] = Noise(unit, sigma, int(dof), "robust", by_series=own)
    return out


def _class_dof(rows: np.ndarray, n: int, n_params: int, leverage: np.ndarray | None) -> float:
    """The degrees of freedom the residual of ``rows`` keeps: their number less the sum of their
    ``leverage`` (the parameters the fit spent on them), or less their share of ``n_params``."""
    spent = float(np.sum(leverage[rows])) if leverage is not None else n_params * rows.size / max(n, 1)
    return max(rows.size - spent, 1.0)


def _series_floors(series, inv, dev, rep, pooled: float) -> dict:
    """series -> its own noise floor from its repeats (deviations ``dev`` from their group means,
    groups ``inv``, repeated ``rep``), for the series with at least MIN_REPEAT_DOF degrees of freedom
    whose floor is off ``pooled`` by more than SERIES_NOISE_FACTOR."""
    out = {}
    for name in np.unique(series[rep]):
        m = rep & (series == name)
        dof = int(m.sum()) - np.unique(inv[m]).size
        if dof < MIN_REPEAT_DOF:
            continue
        sigma = float(np.sqrt(np.sum(dev[m] ** 2) / dof))
        if sigma > 0 and not 1.0 / SERIES_NOISE_FACTOR <= sigma / pooled <= SERIES_NOISE_FACTOR:
            out[str(name)] = sigma
    return out


def _kind_floors(st, resid, sel, repeated, pooled: float, n_params: int,
                 leverage: np.ndarray | None = None) -> dict:
    """series -> the noise floor of its file kind, for the series of the kinds among ``sel`` none of
    whose readings are repeated (``repeated``: the readings that are) and whose robust floor
    (:func:`robust_sigma` over the kind's readings, corrected for the parameters the fit spent on
    them as the unit's own fallback is) exceeds the floor ``pooled`` that other kinds' repeats give
    (or, in a class without repeats, the robust floor pooled over every kind). A ball bar
    read once per angle is judged by its own noise, not by the laser's repeats beside it: at 0.3 um
    against the laser's 0.2 um the base model's held-out residual stood 1.5 times above the pooled
    floor, and diagnose called all the data unexplained. Never below the pooled floor: a kind is not
    judged more strictly than before."""
    kinds = np.asarray(st.kinds, dtype=object)[st.file[sel]]
    has_repeats = set(np.asarray(st.kinds, dtype=object)[st.file[repeated]].tolist())
    out = {}
    for kind in dict.fromkeys(kinds.tolist()):
        if kind in has_repeats:
            continue
        rows = sel[kinds == kind]
        dof = _class_dof(rows, len(resid), n_params, leverage)
        sigma = robust_sigma(st, resid, rows) * np.sqrt(rows.size / dof)
        if sigma > pooled:
            out.update({str(s): float(sigma) for s in np.unique(st.series[rows])})
    return out


def robust_sigma(st, resid, sel) -> float:
    """1.4826 MAD of successive differences / sqrt(2), within each series in reading order (or along
    the position of its moving axis when it has one)."""
    diffs = []
    for s in np.unique(st.series[sel]):
        ix = sel[st.series[sel] == s]
        order = np.lexsort((st.row[ix],))
        diffs.append(np.diff(resid[ix][order]))
    d = np.concatenate(diffs) if diffs else np.zeros(0)
    if d.size < 3:
        return float(np.std(resid[sel])) if sel.size > 1 else 1.0
    mad = np.median(np.abs(d - np.median(d)))
    return float(max(1.4826 * mad / np.sqrt(2.0), 1e-9))


# ------------------------------------------------------------------------------------ folds
def make_folds(st, max_folds: int = MAX_FOLDS) -> tuple[np.ndarray, str]:
    """Fold of each observation for K-fold held-out evaluation, and a sentence saying how.

    Whole runs are held out together (run r of every file in fold r mod K, by rank of its run number
    in the file), but for runs that approach an axis from opposite sides: a reversal, not repeats
    (:func:`._reversal.run_blocks`). Files without runs are cut into blocks: by spindle-speed block (a speed step and the
    time until the next one) when the spindle speed changes at least four times, else into K
    contiguous stretches of reading order; a cmm file (a cut part) and a points file without runs or
    spindle-speed blocks (a plate measured on a CMM) have their points dealt to the folds in a fixed
    shuffled order.
    """
    n = len(st.file)
    how = set()
    block_of = np.zeros(n, dtype=np.int64)
    for fi in np.unique(st.file):
        ix = np.flatnonzero(st.file == fi)
        runs = st.run[ix]
        known = np.unique(runs[runs >= 0])
        if known.size >= 2:
            from ._reversal import run_blocks
            reversal = run_blocks(st, ix, runs, known)
            if reversal is None:
                rank = np.searchsorted(known, runs)
                rank[runs < 0] = 0
                block_of[ix] = rank
                how.add("whole runs")
                continue
            blocks, said = reversal
            block_of[ix] = _dealt(st.row[ix], fi, max_folds) if blocks is None else blocks
            how.add(said)
            continue
        rows = st.row[ix]
        if st.kinds[fi] == "cmm":
            # a cut part: the order of its points is a path over the part, not the machine's time, and
            # a stretch of it held out is a region of the part the rest does not reach (its errors are
            # undetermined there): the points are dealt to the folds in a fixed shuffled order (every
            # K-th point in reading order would hold out whole columns of a grid whose rows have a
            # multiple of K points)
            block_of[ix] = _dealt(rows, fi, max_folds)
            how.add("the points of a cut part dealt to the folds in a shuffled order")
            continue
        sp = st.spindle[ix]
        order = np.argsort(rows, kind="stable")
        blocks = None
        if np.isfinite(sp).all() and sp.size:
            sps = sp[order]
            steps = np.flatnonzero(np.abs(np.diff(sps)) > 1e-6) + 1
            on_steps = [s for s in steps if sps[s] > 0 and sps[s - 1] != sps[s]]
            if len(on_steps) >= 4:
                b = np.zeros(ix.size, dtype=np.int64)
                for k, s in enumerate(on_steps):
                    b[order[s:]] = k + 1
                blocks = b
                how.add("whole spindle-speed blocks")
        if blocks is None and st.kinds[fi] == "points":
            # a points file without runs (a plate's holes, measured on a CMM in its own frame): a
            # stretch of its reading order is a band of the travel (a row of the grid), and every
            # file on the same grid leaves out the same band in that fold, so the fold's fit has
            # nothing to fix the errors there but the directions the rest determines (a CMM-only
            # campaign of two plates: the held-out points off by 16 to 20 um against 1 um of noise)
            blocks = _dealt(rows, fi, max_folds)
            how.add("the points of a points file dealt to the folds in a shuffled order")
        if blocks is None:
            urows = np.unique(rows)
            edges = np.quantile(urows, np.linspace(0, 1, max_folds + 1)[1:-1]) if urows.size else []
            blocks = np.searchsorted(edges, rows, side="right")
            how.add("contiguous stretches of each file")
        block_of[ix] = blocks
    nb = int(block_of.max()) + 1
    K = min(max_folds, nb)
    if K < 2:
        return np.zeros(n, dtype=np.int64), "no held-out split possible (one run, one block)"
    folds = block_of % K
    return folds, f"{K}-fold, holding out " + " and ".join(sorted(how))


def _dealt(rows: np.ndarray, fi, max_folds: int) -> np.ndarray:
    """Block of each reading of file ``fi`` (data rows ``rows``): its rows dealt to ``max_folds``
    folds in a fixed shuffled order (seeded by the file's index, so that files on the same grid hold
    out different points), the readings of one row together."""
    urows, rank = np.unique(rows, return_inverse=True)
    order = np.random.default_rng(int(fi)).permutation(urows.size)
    return order[rank] % max_folds


# ------------------------------------------------------------------------------------ step test
@dataclass
class Step:
    """Mean residual difference between approach directions at matched positions.

    step : mean(+) - mean(-) at matched positions (file units); se : its standard error;
    n_pairs : matched position groups; t : step / se.
    """

    step: float
    se: float
    n_pairs: int

    @property
    def t(self) -> float:
        return self.step / self.se if self.se > 0 else 0.0


def step_test(st, resid, axis: str, sel=None) -> Step | None:
    """Mean of (residual approached in +) minus (in -) at the same pose, for ``axis`` (the backlash
    of Pi et al. (2017) / ISO 230-2 reversal), in the axis's own unit (um, urad for a rotary axis).

    Each reading's residual is divided by its derivative with respect to the axis's positioning
    error (a laser run of the axis reads it whole, a ball-bar length at an angle theta to the axis
    only cos theta of it), so that every matched pair estimates the same reversal; the pairs are
    averaged weighted by the square of that derivative (the information each carries)."""
    k = st.machine.axis_names.index(axis)
    g = st.g[axis]
    use = (np.abs(g) > 0.3 * np.max(np.abs(g))) & (st.dirs[:, k] != 0) & np.isfinite(resid)
    if sel is not None:
        use &= sel
    ix = np.flatnonzero(use)
    if ix.size < 4:
        return None
    scale = 1e6 if st.machine.axis(axis).is_rotary else 1e3
    r = resid[ix] / g[ix] * scale
    d = st.dirs[ix, k]
    setup = getattr(st, "setup", None)
    key_parts = np.column_stack([np.unique(st.series[ix].astype(str), return_inverse=True)[1],
                                 np.round(st.q[ix], POSITION_DECIMALS),
                                 np.zeros((ix.size, 1)) if setup is None else np.round(setup[ix], 3),
                                 np.round(np.nan_to_num(st.feed[ix], nan=-1), 3), np.round(st.arm[ix], 3)])
    _, inv = np.unique(key_parts, axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    steps, weights, vars_ = [], [], []
    for gk in np.unique(inv):
        m = inv == gk
        up, dn = r[m & (d > 0)], r[m & (d < 0)]
        if up.size and dn.size:
            steps.append(up.mean() - dn.mean())
            weights.append(np.mean((g[ix][m] / scale) ** 2))
            vars_.append((up.var(ddof=1) / up.size if up.size > 1 else np.nan)
                         + (dn.var(ddof=1) / dn.size if dn.size > 1 else np.nan))
    if not steps:
        return None
    steps, w = np.array(steps), np.array(weights) / np.sum(weights)
    mean = float(w @ steps)
    n = len(steps)
    # inverse-variance weights, variance c / w_i: c from the pairs' scatter, and the mean's is c
    se = float(np.sqrt(w @ (steps - mean) ** 2 / (n - 1))) if n > 1 else np.nan
    if not np.isfinite(se) or se == 0:
        v = np.array(vars_)
        se = float(np.sqrt(np.nansum(w ** 2 * v))) if np.isfinite(v).any() else float("nan")
    return Step(mean, se, n)


# ------------------------------------------------------------------------------------ spectrum
@dataclass
class Line:
    """A spectral line of the residual along an axis (Lomb-Scargle, uneven sampling).

    period : mm (linear axis) or rad; power : normalised generalised LS power (0..1, share of the
    variance a sinusoid at that period explains); fap : false-alarm probability over the searched band
    (Zechmeister-Kuerster tail, times the number of independent frequencies); n : readings used;
    n_independent : number of independent frequencies searched.
    """

    period: float
    power: float
    fap: float
    n: int
    n_independent: float = 1.0


def axis_series(st, resid, axis: str, sel=None):
    """(positions, mean residual along the axis's positioning direction at each position, index of
    the observations used) for the spectrum of ``axis``.

    Readings of scans that move the axis (laser rows with ``axis`` moving) are used when there are
    enough of them, else every reading of the axis's positioning error. Readings at the same position
    are averaged first, so that heavily repeated coarse targets do not dominate the spectrum (their
    sparse grid aliases any structure into false lines)."""
    k = st.machine.axis_names.index(axis)
    g = st.g[axis]
    if not np.any(g):
        return None
    use = (np.abs(g) > 0.3 * np.max(np.abs(g))) & np.isfinite(resid)
    if sel is not None:
        use &= sel
    scans = use & (st.moving == axis)
    s = st.stood[:, k]                  # where the axis stood: its profiles are read there
    if np.unique(np.round(s[scans], POSITION_DECIMALS)).size >= 12:
        use = scans
    ix = np.flatnonzero(use)
    if ix.size < 12 or np.ptp(s[ix]) <= 0:
        return None
    x = np.round(s[ix], POSITION_DECIMALS)
    r = resid[ix] * np.sign(g[ix])
    ux, inv = np.unique(x, return_inverse=True)
    means = np.bincount(inv, weights=r) / np.bincount(inv)
    return ux, means, ix


def spectral_lines(st, resid, axis: str, min_cycles: float = 4.0, n_freq: int = 2000,
                   max_lines: int = 3) -> list[Line]:
    """Strongest lines of the residual of ``axis`` versus its position, periods between twice the
    finest target spacing and travel/``min_cycles``; sorted by false-alarm probability."""
    ser = axis_series(st, resid, axis)
    if ser is None:
        return []
    x, r, _ = ser
    span = np.ptp(x)
    ux = np.unique(np.round(x, POSITION_DECIMALS))
    if ux.size < 8:
        return []
    # shortest period: three median target spacings (jittered grids alias near their Nyquist period);
    # the median of the actual spacings, so that a fine run over part of the travel counts as fine
    pmin = 3.0 * min(float(np.median(np.diff(ux))), span / (ux.size - 1))
    pmax = span / min_cycles
    if pmax <= pmin:
        return []
    m_band = (1.0 / pmin - 1.0 / pmax) * span
    w = np.linspace(2 * np.pi / pmax, 2 * np.pi / pmin, int(min(n_freq, max(50, 5 * m_band))))
    y = r - r.mean()
    if not np.any(y):
        return []
    p = signal.lombscargle(x, y, w, normalize=True, floating_mean=True)
    p = np.clip(p, 0.0, 1.0 - 1e-15)
    m_indep = max(1.0, (w[-1] - w[0]) * span / (2 * np.pi))
    n = x.size
    lines = []
    peaks, _ = signal.find_peaks(p)
    for i in peaks[np.argsort(p[peaks])[::-1]][:max_lines]:
        single = (1.0 - p[i]) ** ((n - 3) / 2.0)
        fap = float(min(1.0, m_indep * single))
        lines.append(Line(float(2 * np.pi / w[i]), float(p[i]), fap, n, m_indep))
    return sorted(lines, key=lambda ln: ln.fap)


def sinusoid_fit(x, r, period):
    """Least-squares a cos + b sin + c of r(x) at ``period``: (amplitude, phase, amplitude se)."""
    wx = 2 * np.pi * x / period
    X = np.column_stack([np.cos(wx), np.sin(wx), np.ones_like(x)])
    coef, *_ = np.linalg.lstsq(X, r, rcond=None)
    res = r - X @ coef
    dof = max(1, x.size - 3)
    s2 = float(res @ res / dof)
    cov = s2 * np.linalg.pinv(X.T @ X)
    amp = float(np.hypot(coef[0], coef[1]))
    se = float(np.sqrt(max((cov[0, 0] + cov[1, 1]) / 2.0, 0.0)))
    return amp, float(np.arctan2(coef[1], coef[0])), se


def _profile_columns(st, axis: str, x):
    """(n, k) the base's positioning-profile functions of linear ``axis`` at positions ``x``, or
    None (a rotary axis or another basis)."""
    ax = st.machine.axis(axis)
    if ax.is_rotary or ax.basis != "bspline":
        return None
    from ..models.basis import axis_spline
    return np.column_stack(axis_spline(ax).functions(x, False))


#: the largest ratio of the sine's amplitudes in the parts of the travel (thirds: 3, halves: 1.5)
AMPLITUDE_RATIO = {3: 3.0, 2: 1.5}


#: neighbouring positions further apart than this share of the period break a resolving stretch
RESOLVE_MAX_GAP = 0.5
#: a resolving stretch's median spacing is at most this share of the period
RESOLVE_MEDIAN_GAP = 1.0 / 3.0


def resolving_stretches(x, period: float) -> list[tuple[int, int]]:
    """[(i0, i1), ...]: slices of the sorted positions ``x`` whose readings resolve a sine of
    ``period``. A stretch is cut where neighbouring positions are more than
    :data:`RESOLVE_MAX_GAP` periods apart (half a cycle unread); it resolves the period when it
    spans at least one period and its median spacing is at most :data:`RESOLVE_MEDIAN_GAP` of it
    (the spectrum's own shortest period is three median spacings). Sparser readings, such as
    ISO 230-2 targets a period or more apart, sample the sine aliased: the base's profile through
    them takes it, so they can neither confirm nor refute a line of that period."""
    cuts = np.flatnonzero(np.diff(x) > RESOLVE_MAX_GAP * period) + 1
    out = []
    for i0, i1 in zip(np.r_[0, cuts], np.r_[cuts, x.size]):
        if i1 - i0 >= 2 and x[i1 - 1] - x[i0] >= period \
                and np.median(np.diff(x[i0:i1])) <= RESOLVE_MEDIAN_GAP * period:
            out.append((int(i0), int(i1)))
    return out


def resolved_span(st, resid, axis: str, period: float) -> float:
    """mm over which the readings of ``axis`` resolve ``period`` (first to last position of its
    resolving stretches; the whole span when none does): a line's period is known to about
    period**2 over it, however far sparser readings reach."""
    ser = axis_series(st, resid, axis)
    if ser is None:
        return 0.0
    x = ser[0]
    stretches = resolving_stretches(x, period)
    if not stretches:
        return float(np.ptp(x))
    return float(x[stretches[-1][1] - 1] - x[stretches[0][0]])


def _cut_parts(x, period: float):
    """(number of parts, boolean masks) of ``x`` cut into thirds of equal count, else halves; each
    part must hold 8 positions over at least one period. (0, []) when not even halves do."""
    for n_parts in (3, 2):
        edges = np.quantile(x, np.linspace(0.0, 1.0, n_parts + 1))
        # half-open parts (the last one closed): a reading on an edge counts once
        parts = [(x >= lo) & ((x < hi) if k < n_parts - 1 else (x <= hi))
                 for k, (lo, hi) in enumerate(zip(edges[:-1], edges[1:]))]
        if all(p.sum() >= 8 and np.ptp(x[p]) >= period for p in parts):
            return n_parts, parts
    return 0, []


def _where_resolved(x, period: float, keep) -> str:
    """'' when every position resolves the period, else the clause saying where the line is seen
    and that the other readings (their spacing) cannot tell."""
    if keep.all():
        return ""
    gaps = np.diff(x)
    sparse = gaps[~(keep[1:] & keep[:-1])]
    seen = "; ".join(f"{lo:.4g}..{hi:.4g}" for lo, hi in _runs(x, keep))
    return (f"seen over {seen} mm only (the other {int((~keep).sum())} positions, "
            f"{np.min(sparse):.3g} to {np.max(sparse):.3g} mm apart, cannot resolve a {period:.4g} mm "
            f"period: they neither confirm nor refute it); ")


def _runs(x, keep):
    """(first, last) position of each run of ``keep``."""
    edges = np.flatnonzero(np.diff(np.r_[0, keep.astype(int), 0]))
    return [(x[i0], x[i1 - 1]) for i0, i1 in zip(edges[::2], edges[1::2])]


def _part_sines(x, r, period, parts, prof):
    """[(amplitude, phase, se)] of one sine per part, fitted together beside a constant and the
    base's profile functions ``prof`` that act over the parts. The base fit took what its knots
    could follow of a line, more where they fall in step with the period than where they do not
    (a beat along the travel): the residual's own sine varies from part to part by that alone.
    Beside the profile, each part's sine is the line's there."""
    w = 2 * np.pi * x / period
    prof = prof[:, np.ptp(prof, axis=0) > 1e-9]
    cols = [np.ones_like(x)] + list(prof.T)
    for p in parts:
        cols += [np.where(p, np.cos(w), 0.0), np.where(p, np.sin(w), 0.0)]
    X = np.column_stack(cols)
    k0 = X.shape[1] - 2 * len(parts)
    coef, *_ = np.linalg.lstsq(X, r, rcond=None)
    res = r - X @ coef
    rank = np.linalg.matrix_rank(X)
    # the profile's functions sum to the constant over the parts (a partition of unity): judge the
    # sines by the rank they add, not the whole design's
    told = rank == np.linalg.matrix_rank(X[:, :k0]) + 2 * len(parts)
    s2 = float(res @ res / max(1, x.size - rank))
    cov = s2 * np.linalg.pinv(X.T @ X)
    out = []
    for j in range(len(parts)):
        i = k0 + 2 * j
        se = float(np.sqrt(max((cov[i, i] + cov[i + 1, i + 1]) / 2.0, 0.0))) if told else float("inf")
        out.append((float(np.hypot(coef[i], coef[i + 1])), float(np.arctan2(coef[i + 1], coef[i])), se))
    return out


def parts_agree(st, resid, axis: str, period: float) -> tuple[bool, str]:
    """Does a line at ``period`` replicate along the axis travel (a cyclic error does, a local defect
    does not)? The readings are cut into thirds of equal count (halves when a third is shorter
    than one period; a bump in the middle of a run fits a sine in each half, mirrored, but not in
    the outer thirds). Needs the sine significant (amplitude > 5 se) in each part, its amplitudes
    within :data:`AMPLITUDE_RATIO`, and each part's phase within 45 deg of the lower part's.
    When that fails and some readings cannot resolve the period (:func:`resolving_stretches`),
    those neither confirm nor refute it: the test is made again on the others alone, each part's
    sine fitted beside the base's profile functions (:func:`_part_sines`), and the sentence says
    where the line is seen. Returns (agree, sentence)."""
    ser = axis_series(st, resid, axis)
    if ser is None:
        return False, "too few readings"
    x, r, _ = ser
    ok, text = _parts_test(x, r, period, None, "")
    keep = np.zeros(x.size, bool)
    for i0, i1 in resolving_stretches(x, period):
        keep[i0:i1] = True
    if ok or keep.all():
        return ok, text
    if not keep.any():
        return False, (text + f"; no stretch of the readings resolves it (neighbouring positions "
                       f"{np.min(np.diff(x)):.3g} mm apart or more over less than one period)")
    where = _where_resolved(x, period, keep)
    return _parts_test(x[keep], r[keep], period, _profile_columns(st, axis, x[keep]), where)


def _parts_test(x, r, period, prof, where: str) -> tuple[bool, str]:
    """(agree, sentence) of the parts test of :func:`parts_agree` on positions ``x`` (residual
    ``r``), the parts' sines fitted beside ``prof`` (None: a constant); ``where``: the clause
    saying where the line is seen ('' for the whole travel)."""
    of = "of it" if where else "of the travel"
    n_parts, parts = _cut_parts(x, period)
    if not n_parts:
        tail = ": a local defect there fits a sine as well" if where else ""
        return False, where + f"a half {of} is shorter than one period ({period:.4g}){tail}"
    names = {3: ("lower", "middle", "upper"), 2: ("lower", "upper")}
    if prof is None:
        fits = [sinusoid_fit(x[p], r[p], period) for p in parts]
    else:
        fits = _part_sines(x, r, period, parts, prof)
    amps = [f[0] for f in fits]
    dphi = max(abs((f[1] - fits[0][1] + np.pi) % (2 * np.pi) - np.pi) for f in fits)
    # each third mixes the travel's lines in its own proportions (a fine run fills the middle one),
    # which dilutes the sine more in some than in others: amplitudes within a factor 3 there (1.5
    # between the halves of one line); a bump's leak into the outer thirds is far smaller
    ratio = AMPLITUDE_RATIO[n_parts]
    ok = all(f[0] > 5 * f[2] for f in fits) and max(amps) < ratio * min(amps) and dphi < np.radians(45)
    which = "third" if n_parts == 3 else "half"
    text = (where + "amplitude " + ", ".join(f"{a_:.3g}" for a_ in amps) + " in the "
            + ", ".join(names[n_parts]) + f" {which} {of}, phases within {np.degrees(dphi):.0f} deg of the lower one")
    return bool(ok), text


# ------------------------------------------------------------------------------------ structure
@dataclass
class Structure:
    """Where a residual is systematic: the strongest binned-mean departure from zero.

    p : Bonferroni-corrected p-value of the chi-square test of bin means (noise known);
    series : the series; variable : what the bins run along ('X position', 'time' ...);
    lo, hi : range of the variable around the bin furthest from zero, extended over neighbouring bins
        of the same sign beyond 3 standard errors;
    unit : unit of lo/hi; peak : largest bin mean (file units); chi2, dof (bins);
    n_departing : bins whose mean departs from zero by more than 3 standard errors.
    """

    p: float
    series: str
    variable: str
    lo: float
    hi: float
    unit: str
    peak: float
    chi2: float
    dof: int
    n_departing: int = 0


def _bins(x, n_bins):
    ux = np.unique(x)
    if ux.size <= n_bins:
        return np.searchsorted(ux, x), ux, ux
    edges = np.quantile(x, np.linspace(0, 1, n_bins + 1))
    b = np.clip(np.searchsorted(edges[1:-1], x, side="right"), 0, n_bins - 1)
    return b, edges[:-1], edges[1:]


def find_structure(st, resid, sigma: dict, n_tests_extra: int = 0) -> list[Structure]:
    """Chi-square tests of binned residual means along every variable of every series (positions of
    moving axes, time, feed, temperatures), noise known from ``sigma`` (unit -> sigma, and series ->
    its own floor where it has one, :attr:`Noise.by_series`). Returns the
    tests with corrected p < 1e-3, strongest first."""
    tests = []
    names = st.machine.axis_names
    for s in np.unique(st.series):
        ix = np.flatnonzero((st.series == s) & np.isfinite(resid))
        if ix.size < 10:
            continue
        unit = st.unit[ix[0]]
        sg = sigma.get(str(s), sigma.get(unit))     # its own floor, else its unit's
        if sg is None or sg <= 0:
            continue
        r = resid[ix]
        variables = []
        for k, a in enumerate(names):
            x = st.stood[ix, k]            # where it stood (the ram: where the tool put it)
            if np.unique(np.round(x, POSITION_DECIMALS)).size >= 3:
                rot = st.machine.axis(a).is_rotary
                variables.append((f"{a} position", np.degrees(x) if rot else x, "deg" if rot else "mm"))
        if np.isfinite(st.t[ix]).all() and np.ptp(st.t[ix]) > 0:
            variables.append(("time", st.t[ix], "s"))
        f = st.feed[ix]
        if np.isfinite(f).all() and np.unique(f).size >= 2:
            variables.append(("feed", f, "mm/min"))
        for name, v in st.temps.items():
            if np.isfinite(v[ix]).all() and np.ptp(v[ix]) > 0:
                variables.append((f"temperature {name}", v[ix], "degC"))
        if np.unique(st.run[ix]).size >= 3 and np.all(st.run[ix] >= 0):
            variables.append(("run", st.run[ix].astype(float), ""))
        for label, x, u in variables:
            n_bins = int(min(12, max(3, ix.size // 8)))
            b, lo, hi = _bins(x, n_bins)
            if label.endswith("position"):
                # a fine run read more than once at each of many positions: every position its own
                # bin (the pure-error test of lack of fit), else a narrow defect's core and the
                # smooth profile's overshoot beside it cancel within a coarse bin
                ux, inv, cnt = np.unique(np.round(x, POSITION_DECIMALS), return_inverse=True,
                                         return_counts=True)
                if ux.size > n_bins and cnt.min() >= 2:
                    b, lo, hi = inv, ux, ux
            cnt = np.bincount(b, minlength=len(lo)).astype(float)
            ok = cnt > 0
            mean = np.bincount(b, weights=r, minlength=len(lo))[ok] / cnt[ok]
            zb = mean * np.sqrt(cnt[ok]) / sg
            chi2 = float(np.sum(zb ** 2))
            dof = int(ok.sum())
            p = float(stats.chi2.sf(chi2, dof))
            lo_ok, hi_ok = lo[ok], hi[ok]
            # where: the bin furthest from zero and its neighbours of the same sign beyond 3 se
            a, b_ = _peak_run(zb)
            rng = (float(lo_ok[a]), float(hi_ok[b_]))
            if label.endswith("position"):
                rng = _peak_positions(x, r, sg) or rng
            tests.append([p, str(s), label, rng[0], rng[1], u, float(mean[np.argmax(np.abs(mean))]),
                          chi2, dof, int(np.sum(np.abs(zb) > 3))])
    m = len(tests) + n_tests_extra
    out = [Structure(min(1.0, t[0] * m), *t[1:]) for t in tests]
    out = [s for s in out if s.p < 1e-3]
    return sorted(out, key=lambda s: (s.p, -s.chi2 / max(s.dof, 1)))


def _peak_run(z):
    """(first, last) index of the run around the entry of ``z`` furthest from zero: its neighbours of
    the same sign beyond 3 (standard errors)."""
    k0 = int(np.argmax(np.abs(z)))
    a = b = k0
    while a > 0 and abs(z[a - 1]) > 3 and np.sign(z[a - 1]) == np.sign(z[k0]):
        a -= 1
    while b < z.size - 1 and abs(z[b + 1]) > 3 and np.sign(z[b + 1]) == np.sign(z[k0]):
        b += 1
    return a, b


def _peak_positions(x, r, sg):
    """Where along a position the residual peaks, at the resolution of the positions read: the
    position whose mean residual is furthest from zero (in standard errors) and its neighbours of the
    same sign beyond 3 standard errors, as (lo, hi) halfway to the next positions read. A bin of a
    coarse grid can average a narrow defect away against the smooth profile's overshoot beside it;
    the positions themselves do not. None when positions are not repeated (no per-position mean)."""
    xs, inv, cnt = np.unique(np.round(x, POSITION_DECIMALS), return_inverse=True, return_counts=True)
    if xs.size < 3 or cnt.min() < 2:
        return None
    z = np.bincount(inv, weights=r) / cnt * np.sqrt(cnt) / sg
    a, b = _peak_run(z)
    lo = xs[a] - 0.5 * (xs[a] - xs[a - 1]) if a > 0 else xs[a]
    hi = xs[b] + 0.5 * (xs[b + 1] - xs[b]) if b < xs.size - 1 else xs[b]
    return float(lo), float(hi)


def correlations(st, resid, sel) -> list[tuple[str, float]]:
    """Correlation of the residual with each context variable over ``sel``: [(name, r)], strongest
    first (feed, time, spindle speed, temperatures, approach directions, axis positions)."""
    out = []
    r = resid[sel]
    cand = [("feed", st.feed), ("time", st.t), ("spindle speed", st.spindle),
            ("run", np.where(st.run >= 0, st.run, np.nan).astype(float)), ("reading order", st.row.astype(float))]
    cand += [(f"temperature {n}", v) for n, v in st.temps.items()]
    cand += [(f"approach direction of {a}", st.dirs[:, k]) for k, a in enumerate(st.machine.axis_names)]
    cand += [(f"{a} position", st.stood[:, k]) for k, a in enumerate(st.machine.axis_names)]
    for name, v in cand:
        x = v[sel]
        ok = np.isfinite(x) & np.isfinite(r)
        if ok.sum() >= 5 and np.std(x[ok]) > 0 and np.std(r[ok]) > 0:
            out.append((name, float(np.corrcoef(x[ok], r[ok])[0, 1])))
    return sorted(out, key=lambda t: -abs(t[1]))


# ------------------------------------------------------------------ forward-chained folds in time
#: blocks of readings predicted forward in time (thermal drift: docs/thermal.md)
N_FOLDS = 5


def forward_folds(n_rows: int, n_folds: int = N_FOLDS) -> list[tuple[slice, slice]]:
    """(train, test) slices of rows in time order: n_folds + 1 equal blocks, fold k trains on the
    blocks before block k and tests on block k (k = 1..n_folds)."""
    if n_rows < 2 * (n_folds + 1):
        raise ValueError(f"{n_rows} readings are too few for {n_folds} forward folds")
    edges = np.linspace(0, n_rows, n_folds + 2).round().astype(int)
    return [(slice(0, edges[k]), slice(edges[k], edges[k + 1])) for k in range(1, n_folds + 1)]


# ------------------------------------------------------------------ what a candidate must gain
#: a candidate must lower the held-out weighted sum of squares by CV_Z sqrt(2 k) + k (k: the
#: parameters it adds; besides a lower BIC, mtcomp.diagnose._selection.BIC_MARGIN)
CV_Z = 4.0


def cv_threshold(dk: int) -> float:
    """Held-out sum-of-squares reduction (in noise variances) an extension of dk parameters must beat."""
    dk = max(int(dk), 1)
    return CV_Z * np.sqrt(2.0 * dk) + dk

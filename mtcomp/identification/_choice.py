"""The penalty's choice of split (:func:`mtcomp.identification.fit.solve`): a combination of profiles of
different penalty classes that the data cannot see at all, which the roughness penalty alone
divides between them.

Where the data leave such a combination open, the fit's value along it is the one the penalty
prefers, and the penalty's preference between two classes is the ratio of their weights. REML
chooses those weights from how rough each class's fitted profiles are, and that is not a
measurement of the split: a rotary table's second-order radial error motion and its positioning
error read by a ball bar at one radius make the same readings, REML weighs the radial class that
carries nothing at its bound, and the posterior gives the radial motion the prior's standard error
at that weight (7.5e-4 um) where the truth's was 2 um.

So the fit's value along such a combination is given a variance that covers the other splits the
weights could have made: for each class k, the split that the penalty of class k alone would
choose (the combination moved so that class k carries the least curvature it can, the other
classes settling the rest as the fit's weights do) is one standard error from the fit's, where it
fills a class the fit left empty (:func:`beyond_posterior`); between classes that both carry
curvature it adds the posterior at the classes' weights lowered to their REML bounds
(:func:`bounded_split_variance`). A combination within one class (a profile
smoothed between what was measured) is the same at every weight of that class and gets none; a
combination along which the fit carries nothing gets none either, whatever its classes.

Between classes that both carry curvature the posterior's variance along such a combination is the
prior's at the fitted weights (Wahba 1983; Wood 2017, section 5.8: the posterior covariance
``phi (A + sum_k l_k S_k)^-1``), and a weight is as good as the curvature REML read to estimate
it: a class the penalty has squeezed to a curvature direction or two (a ball bar's straightness,
nu = 1, beside its positioning) has a weight that could have been hundreds of times smaller.
:func:`bounded_split_variance` gives those combinations, and only those, the posterior at each
carrying class's weight lowered to its REML variance's one-sided 95 % upper bound: the class's
variance estimated from nu degrees of freedom (nu the class's effective degrees of freedom,
its penalised rank less ``tr((A + S)^-1 l_k S_k)``) is below ``nu / chi2_{nu, 0.05}`` times the
estimate with 95 % confidence (as :mod:`._sparse` bounds a class within itself). A prediction
resting on the penalty's split carries that variance as a finite standard error; what the data
determine keeps its own.
"""
from __future__ import annotations

import numpy as np

from ._linalg import penalised_inverse, psd_factor

#: relative singular values of the fit's data matrix (on the directions it moves in) at or below
#: this share of the largest are directions the data do not see: the penalty alone sets them
CHOICE_RCOND = 1e-6
#: an alternative split must take at least this share of a class's fitted curvature off it: a class
#: whose least curvature along the open combinations is nearly its fitted one has nothing to give
#: away there (a move that buys a fraction of a per cent of it drifts far along what the penalty
#: barely weighs, and is no split)
SPLIT_SHARE = 0.1
#: an alternative split within this many of the posterior's standard errors of the fit's is covered
#: by them already
COVERED_SD = 2.0
#: a class's weight is estimated from at least this many degrees of freedom in the upper bound of
#: :func:`bounded_split_variance` (nu / chi2_{nu, 0.05}: 254 at 1; it grows without limit below)
MIN_WEIGHT_DOF = 1.0
#: the one-sided confidence of the upper bound on a class's prior variance
WEIGHT_BOUND_P = 0.05
#: a direction a class's penalty weighs below this share of its strongest (on the open combinations)
#: is one that class does not decide: the others settle it
SEEN_BY_CLASS = 1e-3


def data_null(AB: np.ndarray, rcond: float = CHOICE_RCOND) -> np.ndarray:
    """(n_B, k) orthonormal directions of the fit's directions B that the data's normal matrix AB
    (B^T As B, the penalty not included) does not see: relative singular values at most rcond."""
    if AB.shape[0] == 0:
        return np.zeros((0, 0))
    ev, V = np.linalg.eigh(0.5 * (AB + AB.T))
    top = max(float(ev.max()), 1e-300)
    return V[:, np.sqrt(np.clip(ev, 0.0, None) / top) <= rcond]


def _least_then(G_first, f_first, G_rest, f_rest) -> np.ndarray:
    """t minimising |f_first + G_first t|^2, then, among those minimisers, |f_rest + G_rest t|^2,
    then |t|: the move from the fit (t = 0) that lets one class carry the least curvature it can."""
    U, s, Vt = np.linalg.svd(G_first, full_matrices=True)
    on = s > SEEN_BY_CLASS * max(float(s.max()) if s.size else 0.0, 1e-300)
    r = int(on.sum())
    t0 = Vt[:r].T @ ((U[:, :r].T @ -f_first) / s[:r])
    N = Vt[r:].T
    if not N.shape[1] or not G_rest.shape[0]:
        return t0
    GN = G_rest @ N
    s_opt = np.linalg.lstsq(GN, -(f_rest + G_rest @ t0), rcond=SEEN_BY_CLASS)[0]
    return t0 + N @ s_opt


def choice_directions(z: np.ndarray, BZ: np.ndarray, factors: list) -> tuple[np.ndarray, np.ndarray]:
    """((n_unknowns, c) D, (1 + c, n_classes + 1) penalties): the penalty's alternative splits of what
    the data leave open, in the scaled unknowns (D D^T their covariance, each column one standard
    error; zero columns dropped), each class's penalty at the fit and after each alternative, and
    the class each takes curvature from (:func:`beyond_posterior` keeps those that move curvature
    from a class that carries some into one the fit left empty).

    z : (n_unknowns,) the fitted scaled unknowns (x / scale), where the penalty is evaluated.
    BZ : (n_unknowns, k) orthonormal combinations among the fit's directions that the data do not
    see (:func:`data_null` on the fit's directions B), less those that move what the assumption
    that components no laser file names are zero holds (that split is the assumption's, not the
    penalty's). factors : [(m_k, n_unknowns) sqrt(l_k) F_k], one weighted penalty factor per
    class (l_k the class's weight), so that the fit's penalty is ``sum_k |F_k z|^2``. The fit sits
    at t = 0 of ``z + BZ t``: the least penalty there. For each class k, t_k is the move that
    makes class k's penalty least, the others weighed as in the fit; the columns of D are
    ``BZ t_k``, so that the covariance is ``sum_k (BZ t_k)(BZ t_k)^T``: each split one class alone
    would choose lies one standard error from the fit's."""
    if len(factors) < 2 or not BZ.shape[1]:
        return np.zeros((z.shape[0], 0)), np.zeros((1, len(factors) + 1))
    G = [F @ BZ for F in factors]
    f = [F @ z for F in factors]
    T = []
    for k in range(len(factors)):
        rest = [j for j in range(len(factors)) if j != k]
        t = _least_then(G[k], f[k], np.vstack([G[j] for j in rest]), np.concatenate([f[j] for j in rest]))
        before = float(f[k] @ f[k])
        after = float(np.sum((f[k] + G[k] @ t) ** 2))
        T.append(t if before - after >= SPLIT_SHARE * before else 0.0 * t)
    # an alternative split moves at most what the fit carries along the open combinations: a
    # class's least curvature reached by moving far more than that invents a combination
    carried = float(np.linalg.norm(BZ.T @ z))
    T = [t * min(1.0, carried / max(float(np.linalg.norm(t)), 1e-300)) for t in T]
    # each class's penalty after each move
    cost = [[float(np.sum((fj + Gj @ t) ** 2)) for fj, Gj in zip(f, G)] for t in T]
    D = BZ @ np.array(T).T                                # (n_unknowns, n_classes)
    on = np.abs(D).max(axis=0) > 0.0
    # the last column: the class each alternative takes curvature from
    pens = np.vstack([[float(fj @ fj) for fj in f], np.array(cost)[on]])
    return D[:, on], np.hstack([pens, np.concatenate([[-1.0], np.flatnonzero(on)])[:, None]])


def beyond_posterior(D: np.ndarray, pens: np.ndarray, s2: float) -> np.ndarray:
    """The alternative splits ``D`` (:func:`choice_directions`) that fill a class the fit left empty:
    ``pens`` (1 + c, n_classes + 1), each class's penalty at the fit (first row) and after each
    alternative, in the weighted residuals' units, and (last column) the class each alternative
    takes curvature from, which must carry some: a class with none has nothing to give away. A class whose penalty at the fit is at most the
    residual variance s2 carries no curvature the data show, and REML weighs it at or near its
    bound: the posterior gives it the prior's variance at that weight, next to nothing, whatever
    the open combinations could put there. An alternative that puts more than :data:`COVERED_SD`
    squared times s2 into such a class is one the posterior cannot represent: kept. One that moves
    curvature between classes that both carry some is the prior's to weigh, at weights known to
    REML's precision (:func:`bounded_split_variance`)."""
    if not D.shape[1] or not np.isfinite(s2):
        return D[:, :0]
    source = pens[1:, -1].astype(int)
    pens = pens[:, :-1]
    empty = pens[0] <= s2
    filled = ((pens[1:] - pens[0][None, :]) > COVERED_SD ** 2 * s2) & empty[None, :]
    return D[:, filled.any(axis=1) & ~empty[source]]


def bounded_split_variance(AB: np.ndarray, FB: list, Hinv: np.ndarray, carried: np.ndarray, s2: float,
                           splits: np.ndarray) -> np.ndarray:
    """(k, m) R, R R^T the variance, in the fit's directions B, that the penalty's alternative
    splits add to the posterior ``s2 Hinv`` when each class's weight is only known to REML's
    precision.

    AB : the data's normal matrix along B. FB : [(m_k, k) sqrt(l_k) F_k B], each class's weighted
    penalty factor along B. Hinv : ``(AB + sum_k FB_k^T FB_k)^-1``. carried : (n_classes,) each
    class's weighted penalty at the fit (:func:`choice_directions`' first row). splits : (k, c)
    the alternative splits (:func:`choice_directions`) along B.

    Each class that carries curvature beyond the residual variance (``carried > s2``; an empty
    one is :func:`beyond_posterior`'s) has its weight multiplied by ``chi2_{nu, 0.05} / nu``, nu
    its effective degrees of freedom (its penalised rank less ``tr(Hinv FB_k^T FB_k)``, at least
    :data:`MIN_WEIGHT_DOF`): the lower bound of the weight, the upper of the prior variance. The
    posterior at those weights less the fit's, on the span of the splits only (a profile smoothed
    within one class between what was measured is no split and keeps its variance), is returned
    as its factor R; none (k, 0) where there is no split."""
    from scipy.special import gammaincinv    # chi2_{nu, p} = 2 gammaincinv(nu / 2, p): no scipy.stats
    k = AB.shape[0]
    if not splits.shape[1] or len(FB) < 2 or not np.isfinite(s2) or not np.any(np.asarray(carried) > s2):
        return np.zeros((k, 0))
    lowered = []
    for G, pen in zip(FB, carried):
        Sk = G.T @ G
        sv = np.linalg.svd(G, compute_uv=False)
        rank = int(np.sum(sv > 1e-9 * max(float(sv.max()) if sv.size else 0.0, 1e-300)))
        nu = max(rank - float(np.trace(Hinv @ Sk)), MIN_WEIGHT_DOF)
        lowered.append(G * np.sqrt(2.0 * float(gammaincinv(0.5 * nu, WEIGHT_BOUND_P)) / nu if pen > s2 else 1.0))
    # (AB + lowered)^-1, the penalty given once and through its factor, as the fit's Hinv (given
    # both as part of H and as S it counted twice: a class at its weight doubled took 2.9e6 of
    # variance off a 5-axis campaign's split, the covariance not positive semi-definite)
    extra = s2 * (penalised_inverse(AB, factor=np.vstack(lowered)) - Hinv)
    U, sv, _ = np.linalg.svd(splits, full_matrices=False)
    Q = U[:, sv > 1e-9 * max(float(sv.max()), 1e-300)]
    return Q @ psd_factor(Q.T @ extra @ Q)    # a variance added, never taken: its round-off cut

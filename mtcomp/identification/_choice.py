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
classes settling the rest as the fit's weights do) is one standard error from the fit's. A
combination within one class (a profile smoothed between what was measured) is the same at every
weight of that class and gets none; a combination along which the fit carries nothing gets none
either, whatever its classes.
"""
from __future__ import annotations

import numpy as np

#: relative singular values of the fit's data matrix (on the directions it moves in) at or below
#: this share of the largest are directions the data do not see: the penalty alone sets them
CHOICE_RCOND = 1e-6
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


def choice_directions(z: np.ndarray, B: np.ndarray, AB: np.ndarray, factors: list,
                      rcond: float = CHOICE_RCOND) -> np.ndarray:
    """(n_unknowns, c) D, the penalty's alternative splits of what the data leave open among the
    fit's directions B, in the scaled unknowns: D D^T is their covariance, each column one
    standard error (zero columns dropped).

    z : (n_unknowns,) the fitted scaled unknowns (x / scale), where the penalty is evaluated.
    AB : B^T As B, the data's normal matrix on B. factors : [(m_k, n_unknowns) sqrt(l_k) F_k], one
    weighted penalty factor per class (l_k the class's weight), so that the fit's penalty is
    ``sum_k |F_k z|^2``. The fit sits at t = 0 of ``z + B Z t`` (Z :func:`data_null`): the least
    penalty there. For each class k, t_k is the move that makes class k's penalty least, the
    others weighed as in the fit; the columns of D are ``B Z t_k``, so that the covariance is
    ``sum_k (B Z t_k)(B Z t_k)^T``: each split one class alone would choose lies one standard
    error from the fit's."""
    n = z.shape[0]
    Z = data_null(AB, rcond)
    if len(factors) < 2 or not Z.shape[1]:
        return np.zeros((n, 0))
    BZ = B @ Z
    G = [F @ BZ for F in factors]
    f = [F @ z for F in factors]
    T = []
    for k in range(len(factors)):
        rest = [j for j in range(len(factors)) if j != k]
        t = _least_then(G[k], f[k], np.vstack([G[j] for j in rest]), np.concatenate([f[j] for j in rest]))
        T.append(t)
    # an alternative split moves at most what the fit carries along the open combinations: a
    # class's least curvature reached by moving far more than that invents a combination
    carried = float(np.linalg.norm(Z.T @ (B.T @ z)))
    T = [t * min(1.0, carried / max(float(np.linalg.norm(t)), 1e-300)) for t in T]
    D = BZ @ np.array(T).T                                # (n_unknowns, n_classes)
    return D[:, np.abs(D).max(axis=0) > 0.0]

"""Profiles whose roughness the data cannot bound: sparse measurements (a laser run of three targets).

Between what was measured a profile follows the smoothest curve, and the posterior covariance of the
penalised fit, ``phi (J^T W J + S)^-1`` (Wood 2006; Wahba 1983's Bayesian intervals for smoothing
splines), gives that curve the standard error the roughness leaves there: the penalty's weight is
the inverse of the roughness's prior variance, in units of the residual variance. REML estimates
that variance from the curvature the data read, and a class of components whose curvature the data
read in fewer than :data:`MIN_CURVATURE_DOF` directions (nu: the data's rank with the other classes'
profiles held straight, less their rank with every profile straight; three targets of one laser
run: one, the middle target's departure from the line through the ends) cannot bound it: a
variance estimated from nu degrees of freedom has a one-sided 95 % upper bound of
``nu / chi2_{nu, 0.05}`` times the estimate, 254 at nu = 1, 19.5 at nu = 2, 8.5 at nu = 3. Below
that the directions the penalty alone fixes (what the profile does between the targets) are
recorded as undetermined: a prediction that moves with them gets a blank standard error, compensate
leaves such blocks uncorrected and export writes no table from them. The values keep the smoothest
curve; only their claim to be known goes.
"""
from __future__ import annotations

import numpy as np

#: a class of components whose penalised directions the data read in fewer than this many
#: dimensions cannot bound its roughness (nu / chi2_{nu, 0.05}: 254 at 1, 19.5 at 2, 8.5 at 3)
MIN_CURVATURE_DOF = 3
#: eigenvalues of the data's normal matrix (scaled coordinates) below this share of the largest are
#: directions the data do not see
UNSEEN_EV = 1e-12
#: a class whose penalty on the fit's directions the assumption map shrinks below this share has
#: every component held at zero by it (what is left is the map's round-off, 1e-13 to 1e-8)
TAKEN_AWAY = 1e-6


def unbounded_directions(penalties: dict, B: np.ndarray, AB: np.ndarray, scale: np.ndarray,
                         P: np.ndarray | None = None, n_free: int | None = None) -> tuple[np.ndarray, dict]:
    """((n_unknowns, k) orthonormal directions in scaled coordinates, {class: nu}): the directions
    along B (the fit's, orthonormal, scaled) that only the penalty of a class the data read in fewer
    than :data:`MIN_CURVATURE_DOF` of its directions fixes, and those classes with their nu.

    penalties : {class: F_k}, the factors of the penalties in scaled coordinates (unweighted).
    AB : the data's normal matrix along B (no penalty).
    P : the move that took the components no laser file names to zero
    (:func:`.unmeasured.assumption_map`, internal units; None: none). The fit's directions are taken
    as that move leaves them (``P B``), both where the curvatures are counted and for the directions
    returned: what the assumption holds at zero has no curvature to bound, a class it takes away
    whole (the straightnesses beside positioning runs alone) is not counted, and a count is not
    lowered by a line of another profile that B carries only with a curvature of a component the
    assumption holds (with X and Y positioning runs B had X's slope only with a little of the
    straightness of Y in X, read at Y 0 against X's laser zero: with that straightness held straight
    the slopes went, and the straightnesses counted 2 curvatures that were the positioning's).
    n_free : the machine parameters come first, the files' set-ups after: only the directions that
    leave the set-ups alone are counted (one that shifts a profile at every target and the laser's
    zero against it is a set-up's, whose variance stays in the covariance)."""
    n = B.shape[0]
    if not penalties or not B.shape[1]:
        return np.zeros((n, 0)), {}
    ev, V = np.linalg.eigh(0.5 * (AB + AB.T))
    seen = ev > UNSEEN_EV * max(float(ev.max()), 1e-300)
    N = V[:, ~seen]
    # the fit's directions as the assumption leaves them; the data read them as B's (J P = J)
    M = B if P is None else (P @ (scale[:, None] * B)) / scale[:, None]
    if n_free is not None and N.shape[1] and n_free < B.shape[0]:
        _, sk, Vk = np.linalg.svd(M[n_free:] @ N, full_matrices=True)
        N = N @ Vk[int(np.sum(sk > 1e-9)):].T
    FBs = []                                    # (class, its penalty on M)
    for cls, F in penalties.items():
        FM = F @ M
        if np.linalg.norm(FM, 2) > TAKEN_AWAY * np.linalg.norm(F @ B, 2):
            FBs.append((cls, FM))
    tol = UNSEEN_EV * max(float(ev.max()), 1e-300)

    def rank_on_null(blocks):
        """The data's rank on the null space of the penalties ``blocks`` (all of B without any)."""
        if not blocks:
            return int(seen.sum())
        X = np.vstack(blocks)
        _, sf, Vt = np.linalg.svd(X, full_matrices=True)
        Z = Vt[int(np.sum(sf > 1e-9 * max(float(sf.max()) if sf.size else 0.0, 1e-300))):].T
        return int(np.sum(np.linalg.eigvalsh(Z.T @ AB @ Z) > tol)) if Z.shape[1] else 0

    straight = rank_on_null([G for _, G in FBs])
    out, classes = [], {}
    for i, (cls, FB) in enumerate(FBs):
        top = np.linalg.norm(FB, 2) if FB.size else 0.0
        if not top > 0:
            continue
        # nu: the curvature of this class the data read, the other classes held straight: the
        # degrees of freedom REML has for its weight
        nu = rank_on_null([G for j, (_, G) in enumerate(FBs) if j != i]) - straight
        if nu >= MIN_CURVATURE_DOF or not N.shape[1]:
            continue
        G = FB @ N
        w, U = np.linalg.eigh(G.T @ G)
        U = U[:, w > 1e-12 * top ** 2]
        D = M @ (N @ U)
        # what the assumption leaves of the class's own part: a direction whose part in this class
        # the move takes to zero (an angular profile no laser names) is the assumption's; what it
        # leaves in the other classes (the split of a ball bar's radial reading between positioning
        # and straightness, which the move trades the angular part against) is theirs to weigh,
        # not this class's
        own = np.abs(penalties[cls]).sum(axis=0) > 0
        D = D[:, np.linalg.norm(D[own], axis=0) > 1e-6]
        if D.shape[1]:
            out.append(D)
            classes[cls] = nu
    if not out:
        return np.zeros((n, 0)), {}
    Q, s, _ = np.linalg.svd(np.hstack(out), full_matrices=False)
    return Q[:, s > 1e-9 * s.max()], classes


def without_unbounded(L: np.ndarray, D: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """The factor L of a covariance L L^T (internal units) with the directions D (scaled
    coordinates, orthonormal) projected out: what is left is the variance of what the data bound;
    the values along D are then the model's part along undetermined directions (``FittedModel.
    undetermined_values``), as for any direction recorded so."""
    if not D.shape[1]:
        return L
    Ls = L / scale[:, None]
    return scale[:, None] * (Ls - D @ (D.T @ Ls))


def sparse_note(classes: dict) -> dict:
    """{"sparse": the summary's one line} on the classes :func:`unbounded_directions` found; {}
    when there are none."""
    if not classes:
        return {}
    names = ", ".join(f"{c} ({nu} curvature direction{'s' if nu != 1 else ''} read)" for c, nu in classes.items())
    return {"sparse": f"too few measured positions to bound how the profiles vary between them: {names}, "
                      f"fewer than {MIN_CURVATURE_DOF}: a prediction between the measured positions has a blank "
                      "standard error (not determined), compensate leaves it uncorrected and export writes no "
                      "table from it; measure more positions along the axis"}

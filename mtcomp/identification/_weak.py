"""The weak-direction pass of the fit (:func:`mtcomp.identification.fit.solve`): the combinations of
the unknowns that the data fix only weakly over the region they cover are held at the least
predicted error, and the fit keeps what the data say of each as a standard error.

A held direction is not undetermined: the data do fix it, to worse than :data:`WEAK_SD_UM` of rms
tool-tip error over their region. Holding it at zero keeps noise from being amplified into invented
errors; its standard error stays in the fit's covariance (:func:`held_variance`), so a prediction
that moves along it gets that variance rather than a blank. One the data barely see (a standard
error above :data:`OPEN_SD_UM`) is held at zero as not determined instead, with no variance
(:func:`open_unknowns`, :func:`open_undetermined`).
"""
from __future__ import annotations

import numpy as np

from ._linalg import penalised_inverse

#: a combination of parameters whose rms tool-tip error over the data's region they fix only to worse
#: than this standard error (um) is held at the least error
WEAK_SD_UM = 1.0
#: ... unless the first fit puts it further from the start than this many of its standard errors:
#: then the data do see it (a real error of 28 um fixed to 1.2 um is fitted, not held at zero)
WEAK_SIGNIFICANT = 3.0
#: a weak direction whose standard error (um of rms tool-tip error over the data's region) exceeds
#: this is open, not held: no machine error a model linear in its errors describes is that large, so
#: the data say nothing of it. It is held at zero with the undetermined combinations (its parameters
#: "not determined", a prediction resting on it blank), never given its variance: held with it, a
#: CMM dome beside laser runs of X and Y left six such combinations of 7.9e5 um, and the variance
#: they carried into the laser-measured X positioning printed it 6.71 +- 1.9e3 um
OPEN_SD_UM = 1e3
#: a held direction of which the assumption that components no laser file names are zero leaves
#: less than this share of its rms tool-tip error over the data's region is the assumption's alone
#: (a split of readings between a named component and an unnamed one): it is counted, not kept. The
#: others keep the variance of what is left, however small (on two real laser runs of X and Y,
#: between 6e-7 and 0.17 of it is left, standard errors 0.07 to 1 um)
ASSUMED_SHARE = 1e-6


def weak_directions(metric, AB, B, scale, sigma_w: float, y, F=None):
    """((n_seen, k) W, Q): the weak directions among those the data see, as coordinates on B: what
    the data barely see, to be held at the least predicted error.

    The search space is x = x0 + scale * B y (B: the directions the data see, orthonormal in the
    scaled unknowns; AB = B^T As B, the data's normal matrix there; F the penalty's factor there,
    F^T F its part of the matrix, None for none). ``metric``
    (n_unknowns, n_unknowns, mm^2) gives ``Q = B^T D M D B``, a step's mean squared tool-tip error
    over the data's region (um^2); steps it does not see (the files' set-ups, a thermal channel's
    drift ...) have no physical size and are marginalised out (the block of the posterior's
    inverse on the rest). In the
    rest, whitened by Q, a direction whose standard error ``sigma_w / s`` (sigma_w the rms weighted
    residual, s^2 the data's information per um^2) exceeds :data:`WEAK_SD_UM` is weak: the data would
    fix its error over the region only to worse than that; unless the first fit ``y`` moved it by
    more than :data:`WEAK_SIGNIFICANT` of those standard errors (then the data see it after all).
    Weak and strong directions are orthogonal in the metric and uncorrelated in the data, so the
    result is the least-error completion of what the data determine.

    W has the constraint ``W^T Q y = 0`` holding them and is Q-orthonormal: a unit step along a
    column is 1 um rms tool-tip error over the region.
    """
    k = B.shape[1]
    if metric is None or k == 0:
        return np.zeros((k, 0)), None
    SB = scale[:, None] * B
    Q = SB.T @ (metric * 1e6) @ SB                      # um^2 of mean squared tip error per y^2
    Q = 0.5 * (Q + Q.T)
    m, V = np.linalg.eigh(Q)
    phys = m > 1e-9 * max(float(m.max()), 1e-300)
    if not phys.any():
        return np.zeros((k, 0)), Q
    R = V[:, phys]
    # the inverse the posterior takes (fit._posterior), so that what is weak here is what the
    # covariance written says: the two inverted the penalty differently, and on a 5-axis campaign
    # weighted by its files' noise the posterior had a combination of 10.5 um that this saw at 0.8
    C = R.T @ penalised_inverse(AB, factor=F) @ R
    d = 1.0 / np.sqrt(m[phys])
    Cw = C / (d[:, None] * d[None, :])
    var, U = np.linalg.eigh(0.5 * (Cw + Cw.T))
    sd = sigma_w * np.sqrt(np.clip(var, 0.0, None))
    c = U.T @ (np.sqrt(m[phys]) * (R.T @ y))            # each direction's size in the fit, um
    is_weak = (sd > WEAK_SD_UM) & (np.abs(c) < WEAK_SIGNIFICANT * sd)
    return R @ (d[:, None] * U[:, is_weak]), Q


def held_directions(H, W, Q, F=None) -> tuple[np.ndarray, np.ndarray]:
    """((n_seen, k) G, (k,) v): how the unknowns move with each held direction, and its variance per
    unit residual variance, from the first pass's matrix H (the data's, on B; F the penalty's
    factor there, F^T F its part, None: none) and the weak directions W (Q-orthonormal,
    :func:`weak_directions`).

    The held coordinates are u = W^T Q y. In the first pass's posterior (covariance s2 H^-1) each
    has variance s2 v_k, ``v_k = W_k^T Q H^-1 Q W_k`` (they are uncorrelated: W diagonalises the
    data's information in the metric), and the unknowns follow it along its regression direction
    ``G_k = H^-1 Q W_k / v_k`` (one unit of u_k: 1 um rms tip error over the region; the set-ups and
    what the metric does not see come along as the data tie them to it). Held at zero, the second
    pass's posterior is the first's conditioned on u = 0; adding s2 v_k G_k G_k^T for every k gives
    the first's back: what holding took out of the fit's uncertainty, and no more.
    """
    if not W.shape[1]:
        return np.zeros((W.shape[0], 0)), np.zeros(0)
    P = penalised_inverse(H, factor=F) @ (Q @ W)
    v = np.einsum("ik,ik->k", Q @ W, P)
    ok = v > 0                      # always, but for round-off at the edge of the rank
    v = np.where(ok, v, 0.0)
    return np.where(ok[None, :], P / np.where(ok, v, 1.0)[None, :], 0.0), v


def held_variance(held, scale, s2: float, P=None, metric=None) -> tuple:
    """((n_unknowns, n_unknowns) covariance, (n_unknowns, k) directions, (k,) standard errors (um),
    number left to the assumption) of the held directions ``held`` = (directions in scaled
    unknowns (n_unknowns, h), variance per unit residual variance (h,)) at the residual variance s2.

    Each goes through ``P`` (:func:`mtcomp.identification.unmeasured.assumption_map`, None: no
    move) as the values do: the part of a held direction that only splits a reading between a
    named component and one no laser file names is the assumption's, held at zero with no variance.
    What is left is given as a direction of 1 um rms tool-tip error over the data's region
    (``metric``, mm^2; without one, as it is) and its standard error in um; a direction with less
    than :data:`ASSUMED_SHARE` of its error left is the assumption's entirely (counted, not kept).
    Zeros when nothing is held."""
    n = scale.shape[0]
    if held is None or not held[0].shape[1]:
        return np.zeros((n, n)), np.zeros((n, 0)), np.zeros(0), 0
    G, v = held
    Gi = scale[:, None] * G
    mapped = Gi if P is None else P @ Gi
    if metric is None:
        size_before = size = np.ones(G.shape[1])
    else:
        M = metric * 1e6                                  # um^2 per internal unit^2
        size_before = np.sqrt(np.clip(np.einsum("ik,ij,jk->k", Gi, M, Gi), 0.0, None))
        size = np.sqrt(np.clip(np.einsum("ik,ij,jk->k", mapped, M, mapped), 0.0, None))
    keep = size > ASSUMED_SHARE * size_before
    sd = np.sqrt(s2 * v[keep]) * size[keep]
    D = mapped[:, keep] / size[keep][None, :]
    return (D * (sd ** 2)[None, :]) @ D.T, D, sd, int(np.sum(~keep))


def repeat_scale(problem, r, rank) -> float:
    """The scale of ``problem``'s weighted residuals r that noise alone makes: pooled over repeat groups
    (the same reading of the same set-up in several runs, mtcomp.measurement.outliers) when the
    files have at least 5 degrees of freedom of repeats, so that a model's misfit (an effect it
    lacks) is not taken for noise; else the rms residual."""
    from ..measurement.outliers import setup_keys
    ss, dof = 0.0, 0
    for m, so in zip(problem.mms, problem.obs_slices):
        keys = setup_keys(m.data)
        if keys is None or m.n_obs == 0:
            continue
        names, cols = np.unique(np.asarray(m.obs_column, dtype=str), return_inverse=True)
        group = keys[m.obs_row] * names.size + cols
        rr = r[so]
        counts = np.bincount(group)
        means = np.bincount(group, weights=rr) / np.maximum(counts, 1)
        rep = counts[group] >= 2
        ss += float(np.sum((rr[rep] - means[group[rep]]) ** 2))
        dof += int(np.sum(counts[counts >= 2] - 1))
    if dof >= 5:
        return float(np.sqrt(ss / dof))
    dof0 = max(problem.n_obs - rank, 0)
    return float(np.sqrt(float(r @ r) / dof0)) if dof0 > 0 else 0.0


def hold_weak(problem, start, first, w, max_iterations, tol, B1, scale, data_rank: int) -> tuple:
    """The second pass of the fit: the weak directions of the first pass's fit ``first`` (x, r, A,
    g, B, AB, iterations, converged, null, rank) held at the least predicted error, fitted again from
    ``start`` by ``problem`` (:class:`mtcomp.identification.fit._Problem`). Returns the same tuple:
    the second pass's, or ``first`` when there is no weak direction or holding them spoils the fit
    (then ``problem.weak_fallback``). Sets ``problem.held``: (the held directions in scaled unknowns
    (n_unknowns, k), their variance per unit residual variance (k,)), None when nothing is held.
    The rank counts only the directions fitted; the null space stays the data's."""
    x, r, A, g, B, AB, iterations, converged, null, rank = first
    problem.held = problem.open = problem.open_sd = None
    sigma_w = repeat_scale(problem, r, min(rank, data_rank))
    AB1, F1 = AB, problem._penalty_factor(B)       # the first pass's, data and penalty apart
    y1 = B1.T @ ((x - start[0]) / scale)
    weak, Q = weak_directions(problem.metric, AB1, B1, scale, sigma_w, y1, F1)
    if not weak.shape[1]:
        return first
    # from the start again (the data-only pass may have wandered far along the weak
    # directions), in the directions the data see less the weak ones: W^T Q y = 0
    C = weak.T @ Q
    _, sv_c, Vt = np.linalg.svd(C, full_matrices=True)
    k_c = int(np.sum(sv_c > 1e-9 * max(float(sv_c.max()), 1e-300)))
    B2 = B1 @ Vt[k_c:].T
    x, r, A, g, B, AB, more, converged = problem._gauss_newton(
        *start, w, max_iterations, tol, B2, scale)
    iterations += more
    # holding weak directions may cost the data fit about one noise variance each; much more
    # means the split into weak and strong went wrong numerically: keep the data's own fit
    allowed = float(first[1] @ first[1]) + 4.0 * weak.shape[1] * sigma_w ** 2 + 1e-300
    if not converged or float(r @ r) > 1.01 * allowed:
        problem.weak_fallback = True
        return first
    G, v = held_directions(AB1, weak, Q, F1)
    held = open_sd(problem.metric, scale[:, None] * (B1 @ G), sigma_w, v) <= OPEN_SD_UM
    problem.held = (B1 @ G[:, held], v[held])
    problem.open = B1 @ G[:, ~held]
    # what each unknown's standard error would be from them (internal units)
    problem.open_sd = sigma_w * np.sqrt((scale[:, None] * problem.open) ** 2 @ v[~held])
    return x, r, A, g, B, AB, iterations, converged, null, rank - weak.shape[1]


def open_sd(metric, Gi, sigma_w: float, v) -> np.ndarray:
    """(k,) standard errors (um of rms tool-tip error over the data's region, ``metric`` mm^2) of the
    held directions whose unknowns move by ``Gi`` (internal units) per unit, of variance
    ``sigma_w^2 v``: as :func:`held_variance` gives them before the assumption's move."""
    size = np.sqrt(np.clip(np.einsum("ik,ij,jk->k", Gi, metric * 1e6, Gi), 0.0, None))
    return sigma_w * np.sqrt(v) * size


def open_unknowns(problem, to_file) -> np.ndarray:
    """(n_unknowns,) bool: the unknowns the weak directions too open to hold with a variance
    (``problem.open``, :data:`OPEN_SD_UM`) leave not determined: those to which they would give a
    standard error above :data:`WEAK_SD_UM` (um or urad; ``to_file`` (n_unknowns,) file unit per
    internal unit). A parameter they barely move keeps its standard error (a laser-measured
    positioning beside a CMM dome whose set-up trades with the table's zero angle)."""
    sd = getattr(problem, "open_sd", None)
    if sd is None:
        return np.zeros(problem.n_unknowns, dtype=bool)
    return sd * np.abs(np.asarray(to_file, dtype=float)) > WEAK_SD_UM


def open_note(problem) -> dict:
    """{"open_weak": the summary's sentence} on the weak directions ``problem`` found too open to
    hold with a variance; {} when there are none."""
    directions = getattr(problem, "open", None)
    if directions is None or not directions.shape[1]:
        return {}
    return {"open_weak": f"{directions.shape[1]} combination(s) the data see too weakly to hold with a "
                         f"variance (standard error above {OPEN_SD_UM:.0f} um of rms tool-tip error over the "
                         "region) are held at zero as not determined: their parameters are not determined, "
                         "and a prediction that rests on one has a blank standard error"}


def open_undetermined(problem, scale, to_file) -> np.ndarray:
    """(n_free, k) the weak directions too open to hold with a variance (``problem.open``) as
    predict judges an undetermined combination: the machine parameters' part, internal units, each
    by itself sized to 1 um rms tool-tip error over the travel (``problem.travel_metric``), one that
    moves no tool tip to 1 um or urad of its parameters. Kept apart from the data's undetermined
    span: mixed into it, a combination of the two that moves the tip little over the travel, scaled
    up, moved the fitted readings (a laser run of X beside a CMM dome lost 120 of its 130 standard
    errors)."""
    return sized_undetermined(problem, getattr(problem, "open", None), scale, to_file)


def sized_undetermined(problem, directions, scale, to_file) -> np.ndarray:
    """(n_free, k) the machine parameters' part of ``directions`` (scaled coordinates; None: none)
    as predict judges an undetermined combination: internal units, each sized to 1 um rms tool-tip
    error over the travel, or to 1 um or urad of its parameters where it moves no tool tip."""
    nf = problem.n_free
    if directions is None or not directions.shape[1]:
        return np.zeros((nf, 0))
    D = scale[:nf, None] * directions[:nf]
    M = problem.travel_metric
    size = (np.sqrt(np.clip(np.einsum("ik,ij,jk->k", D, M[:nf, :nf] * 1e6, D), 0.0, None))
            if M is not None else np.zeros(D.shape[1]))
    own = np.abs(D * np.asarray(to_file[:nf], dtype=float)[:, None]).max(axis=0)
    size = np.where(size > 1e-12 * np.maximum(own, 1e-300), size, own)
    keep = size > 0
    return D[:, keep] / size[keep][None, :]

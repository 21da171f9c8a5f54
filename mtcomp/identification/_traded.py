"""What a ball bar's uncalibrated length trades with (:func:`mtcomp.identification.fit.solve`).

A bar whose length is not calibrated (no ``--known-setup``) reads each radius only up to its length
offset, and a common scale of the axes in the circle's plane changes every radius alike: on a
circle of radius r, X and Y scaled by s lengthen the bar by s r at every angle. The data cannot
tell the two apart; the fit gives the reading to the bar's offset (the set-up takes what it trades
with machine errors) and holds the machine's scale at zero. That is a choice, not a finding: a
machine whose true scale is 20 um/m is predicted without it, and a correction relative to the
part's datum misses by that scale times the distance from the datum. Its standard error from the
covariance knows nothing of it (the scale has no variance at all), so the choice is recorded as
directions (the machine's part of each such combination) along which a correction that moves
rests on the held scale: ``compensate`` and ``export`` give it an infinite standard error
(:meth:`mtcomp.models.model_file.FittedModel.undetermined_values`), as ``predict`` blanks its.
"""
from __future__ import annotations

import numpy as np

from ._choice import _least_then
from .unmeasured import unmeasured_unknowns

#: a null direction's share on the bars' offsets (orthonormal, scaled coordinates) below this
#: trades no bar length
LENGTH_SHARE = 1e-6


def bar_length_unknowns(problem) -> np.ndarray:
    """(j,) indices among ``problem``'s unknowns of the ball bars' fitted length offsets."""
    out = []
    for m, sl in zip(problem.mms, problem.nuis_slices):
        if m.kind == "ballbar":
            out += [sl.start + k for k, s in enumerate(m.nuisance_specs) if s.name.endswith(":length_offset")]
    return np.asarray(out, dtype=int)


def bar_length_trades(problem, null: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """(n_free, c) the machine's part of the combinations the data leave open that move a bar's
    length offset (``null`` (n_unknowns, k): the fit's undetermined combinations, orthonormal in
    the scaled unknowns), internal units, each scaled to 1 um rms tool-tip error over the travel;
    (n_free, 0) when no bar's length trades with the machine.

    Of the machine parts that go with a change of the offsets (the other open combinations free to
    settle the rest), each is the one that leaves the components the fit holds at zero by assumption
    (the angular motions no laser names, :func:`.unmeasured.unmeasured_unknowns`) as near zero as
    it can, then makes the least rms tool-tip error over the travel: a common scale of the axes,
    not a pitch that makes the same readings at the circle's height."""
    nf = problem.n_free
    L = bar_length_unknowns(problem)
    M = problem.travel_metric
    if not L.size or not null.shape[1] or M is None:
        return np.zeros((nf, 0))
    _, s, Vt = np.linalg.svd(null[L], full_matrices=True)
    k = int(np.sum(s > LENGTH_SHARE))
    if not k:
        return np.zeros((nf, 0))
    A, B = null @ Vt[:k].T, null @ Vt[k:].T                 # offsets' moves; what moves none
    ev, E = np.linalg.eigh(0.5 * (M[:nf, :nf] + M[:nf, :nf].T) * 1e6)
    R = (np.sqrt(np.clip(ev, 0.0, None))[:, None] * E.T) * scale[None, :nf]  # |R z|: um rms tip error
    held = unmeasured_unknowns(problem, assumed=True)
    out = []
    for a in A.T:
        t = _least_then(B[held], a[held], R @ B[:nf], R @ a[:nf]) if B.shape[1] else np.zeros(0)
        out.append(scale[:nf] * (a[:nf] + B[:nf] @ t))
    D = np.array(out).T
    size = np.sqrt(np.clip(np.einsum("ik,ij,jk->k", D, M[:nf, :nf] * 1e6, D), 0.0, None))
    keep = size > 1e-9 * max(float(size.max()), 1e-300)
    return D[:, keep] / size[keep][None, :]


def bar_scale_note(problem, traded: np.ndarray) -> dict:
    """{"bar_scale": the summary's sentence} when a ball bar's uncalibrated length trades with the
    machine (``traded``: :func:`bar_length_trades`); {} otherwise."""
    if not traded.shape[1]:
        return {}
    tags = ", ".join(m.tag for m in problem.mms if m.kind == "ballbar" and m.nuisance_specs)
    return {"bar_scale": f"the ball bar's length is not calibrated ({tags}; no --known-setup): a common "
                         "scale of the axes in its circle's plane reads as the bar's length offset, which "
                         "takes it; the scale is held at zero, so predict leaves the standard error blank, "
                         "and compensate and export give no correction, where a prediction moves with it "
                         "(--known-setup for a calibrated bar, or a laser run of one of those axes, "
                         "determines it)"}

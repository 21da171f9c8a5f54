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
#: a parameter's share of a traded combination (file units, of the combination's largest) above
#: which it takes a part in it (the note names it)
NAMED_SHARE = 0.05


def bar_length_unknowns(problem) -> np.ndarray:
    """(j,) indices among ``problem``'s unknowns of the ball bars' fitted length offsets."""
    out = []
    for m, sl in zip(problem.mms, problem.nuis_slices):
        if m.kind == "ballbar":
            out += [sl.start + k for k, s in enumerate(m.nuisance_specs) if s.name.endswith(":length_offset")]
    return np.asarray(out, dtype=int)


def frame_shift_unknowns(problem) -> np.ndarray:
    """(j,) indices among ``problem``'s unknowns of the fitted translations of the frames of
    instruments aligned to the part (points and cmm files without ``--known-setup``)."""
    out = []
    for m, sl in zip(problem.mms, problem.nuis_slices):
        if m.kind in ("points", "cmm"):
            out += [sl.start + k for k, s in enumerate(m.nuisance_specs)
                    if s.name.rpartition(":")[2] in ("tx", "ty", "tz")]
    return np.asarray(out, dtype=int)


def bar_length_trades(problem, null: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """:func:`setup_trades` of the ball bars' length offsets (:func:`bar_length_unknowns`)."""
    return setup_trades(problem, null, scale, bar_length_unknowns(problem))


def frame_shift_trades(problem, null: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """:func:`setup_trades` of the frame translations of points and cmm files
    (:func:`frame_shift_unknowns`): a machine error that moves every reading of such a file alike
    (an R-test's ball: the zero offset of the table it stands on, the location of the table's lines
    at one ball) reads as the frame's shift, which takes it, while it moves the tip elsewhere on the
    part by other amounts. A turn that a frame takes is not among them: that is the part's
    alignment (nothing turns the part: :mod:`._rotation`). Only the combinations in which a rotary
    axis's own parameters (its location, zero offset, positioning) take a part are kept: the balls
    turn with the table, so a frame fitted to them takes the table's errors there, which act
    elsewhere on the part as no shift does. What the linear axes trade with a plate's position
    (a squareness times the one height the plates were measured at) is bounded by the region rule
    for the tip's height and said by the note on what the corrections assume at zero."""
    D = setup_trades(problem, null, scale, frame_shift_unknowns(problem))
    machine = problem.model.machine
    specs = [problem.model.param_specs[i] for i in problem.free_idx]
    rotary = np.array([s.group.partition(":")[0] in machine.axis_names
                       and machine.axis(s.group.partition(":")[0]).is_rotary for s in specs], dtype=bool)
    if not D.shape[1] or not rotary.any():
        return D[:, :0]
    f = np.abs(D * np.array([s.to_file for s in specs])[:, None])
    return D[:, (f[rotary] >= NAMED_SHARE * f.max(axis=0)[None, :]).any(axis=0)]


def setup_trades(problem, null: np.ndarray, scale: np.ndarray, L: np.ndarray) -> np.ndarray:
    """(n_free, c) the machine's part of the combinations the data leave open that move the set-up
    unknowns ``L`` (``null`` (n_unknowns, k): the fit's undetermined combinations, orthonormal in
    the scaled unknowns), internal units, each scaled to 1 um rms tool-tip error over the travel;
    (n_free, 0) when no such set-up trades with the machine.

    Of the machine parts that go with a change of those set-ups (the other open combinations free to
    settle the rest), each is the one that leaves the components the fit holds at zero by assumption
    (the angular motions no laser names, :func:`.unmeasured.unmeasured_unknowns`) as near zero as
    it can, then makes the least rms tool-tip error over the travel: a common scale of the axes,
    not a pitch that makes the same readings at the circle's height."""
    nf = problem.n_free
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


def frame_shift_note(problem, traded: np.ndarray) -> dict:
    """{"frame_shift": the summary's sentence} when a points or cmm file's fitted frame translation
    takes a machine error (``traded``: :func:`frame_shift_trades`), naming the parameters the
    combinations move most; {} otherwise."""
    if not traded.shape[1]:
        return {}
    specs = [problem.model.param_specs[i] for i in problem.free_idx]
    f = np.array([s.to_file for s in specs])
    part = np.abs(traded * f[:, None])
    big = part >= NAMED_SHARE * part.max(axis=0)[None, :]
    names = ", ".join(s.name for s, row in zip(specs, big) if row.any())
    tags = ", ".join(m.tag for m in problem.mms if m.kind in ("points", "cmm") and m.nuisance_specs)
    return {"frame_shift": f"the frame of {tags} is fitted (no --known-setup) and takes, as its "
                           f"shift, what {names} make alike at every reading (what it measured "
                           "stands on the table); elsewhere on the part they move the tip by other "
                           "amounts, which no reading tells: predict leaves the standard error "
                           "blank, and compensate and export give no correction, where a prediction "
                           "moves with them (--known-setup, the places of what was measured on the "
                           "part known, determines them)"}


def set_up_trades(problem, null: np.ndarray, scale: np.ndarray,
                  info: dict) -> tuple[np.ndarray, list]:
    """((n_free, c) the machine's part of every combination a file's set-up takes from the machine,
    a bar's length (:func:`bar_length_trades`) and a frame's shift (:func:`frame_shift_trades`),
    MODEL.json ``uncertainty.traded``; the summary's sentences on them, also added to ``info``):
    compensate says them again where a correction rests on one."""
    bar = bar_length_trades(problem, null, scale)
    shift = frame_shift_trades(problem, null, scale)
    notes = {**bar_scale_note(problem, bar), **frame_shift_note(problem, shift)}
    info.update(notes)
    return np.hstack([bar, shift]), list(notes.values())


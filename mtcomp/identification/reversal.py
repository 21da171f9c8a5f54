"""What the fitted data show of the reversal of each axis (ISO 230-2), for MODEL.json ``info``.

A base model (``mtcomp identify``) has no dependence on the approach direction; when its laser data
show a reversal, the tables and corrections made from it drop that reversal. So that ``export`` and
``compensate`` can say so, a model records what its data showed: for each axis with bidirectional
positioning readings (laser files, component EXX, EYY, ... ECC),

* at every target (and static position of the other axes) of every file, the reversal value
  ``B_i = mean up - mean down`` (ISO 230-2; up: dir +1);
* ``B``: the ``B_i`` of largest magnitude, with its sign; ``B_mean``: their mean;
* ``p_value``: how likely reversal values this far from zero are when the axis has no reversal:
  ``F = sum_i B_i^2 / (s^2 (1/n_up_i + 1/n_down_i)) / m`` against Fisher's F(m, dof), with ``s^2``
  the repeatability variance pooled over every target and direction (dof = readings - groups) and m
  the number of targets. It tests the whole profile, so a reversal that changes sign along the axis
  counts as well as a constant step. None when no target has repeated readings (nothing to judge
  the reversal values against).

Ball-bar files read a position from both sides too (an ISO 230-4 circle run both ways): at every
position read in two patterns of approach directions (rotary axes at 0) the length read one way
less the other is, to first order, the sum over the linear axes whose direction changes of that
axis's reversal B (up minus down) times the bar's direction cosine along it; a model the same in
both directions predicts zero. The B of every such axis is the least-squares solution over all the
pairs of the ball-bar files; its p-value the F test of B against the scatter the pairs leave
(dof: pairs less the axes fitted). An axis that a laser file reads from both sides keeps the laser's.

:data:`REVERSAL_P` is the level below which the data are said to show a reversal.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..machine import AXIS_ORDER, ROTARY
from .iso230_2 import positioning_component

#: the data show a reversal when its p-value (module docstring) is below this
REVERSAL_P = 1e-3
#: positions (mm, rad) closer than this are the same target
_DECIMALS = 9


def _laser_sets(datasets):
    for d in datasets:
        d = getattr(d, "data", d)       # a measurement model holds its file as ``data``
        if getattr(d, "kind", None) == "laser":
            yield d


def _groups(d, sel):
    """(reversal B_i, n_up, n_down, within sum of squares, within dof) per target of rows ``sel``
    of laser data ``d``, internal units; targets read in one direction only are skipped."""
    key = np.column_stack([d.target[sel], np.nan_to_num(d.xyz[sel]), np.nan_to_num(d.abc[sel])])
    _, label = np.unique(np.round(key, _DECIMALS), axis=0, return_inverse=True)
    label = label.reshape(-1)
    value, direction = d.value[sel], d.dir[sel]
    out = []
    for k in range(label.max() + 1):
        up = value[(label == k) & (direction > 0)]
        down = value[(label == k) & (direction < 0)]
        if up.size and down.size:
            ss = float(((up - up.mean()) ** 2).sum() + ((down - down.mean()) ** 2).sum())
            out.append((float(up.mean() - down.mean()), up.size, down.size, ss, up.size + down.size - 2))
    return out


def reversal_p_value(B, n_up, n_down, ss: float, dof: int) -> float | None:
    """p-value of reversal values ``B`` (m,) at targets read n_up, n_down (m,) times, against a
    pooled within-group sum of squares ``ss`` with ``dof`` degrees of freedom (module docstring).
    None without repeated readings (dof 0)."""
    from scipy.stats import f as fisher_f
    B = np.asarray(B, dtype=float)
    if dof <= 0 or B.size == 0:
        return None
    s2 = ss / dof
    if not s2 > 0:
        return 0.0 if np.any(B != 0) else 1.0      # noise-free readings: any step is a step
    F = float(np.sum(B ** 2 / (s2 * (1.0 / np.asarray(n_up) + 1.0 / np.asarray(n_down))))) / B.size
    return float(fisher_f.sf(F, B.size, dof))


def data_reversal(datasets) -> dict:
    """What the laser and ball-bar files among ``datasets`` (MeasurementSet or measurement models)
    show of each axis's reversal, in file units (module docstring)::

        {"X": {"B_um": -36.0, "B_mean_um": -26.0, "p_value": 3e-27, "n_targets": 9,
               "files": ["ess_b02_x"]}}

    (``_urad`` for rotary axes; from ball-bar files ``B`` and ``B_mean`` are the one fitted value and
    ``n_targets`` the positions read both ways). An axis, linear or rotary, whose readings state
    their approach direction (:func:`_stated_directions`: laser files, and points, ball-bar and CMM
    files with ``dir_<axis>`` columns) and all state the same one (every direction +1, or every one
    -1) is ``{"one_direction": "+", "files": [...]}``: its reversal is not measured, and compensate
    leaves the blocks approaching it the other way uncorrected. Other axes without a target read in
    both directions are absent."""
    found: dict = {}
    signs: dict = {}                    # axis -> (approach directions read, files), every file
    for a, read, tag in _stated_directions(datasets):
        entry = signs.setdefault(a, (set(), []))
        entry[0].update(read)
        entry[1].append(tag)
    for d in _laser_sets(datasets):
        tag = _tag(d, "laser")
        for a in dict.fromkeys(d.axis.tolist()):
            sel = np.flatnonzero((d.axis == a) & (d.component == positioning_component(a))
                                 & np.isfinite(d.value))
            if not sel.size:
                continue
            groups = _groups(d, sel)
            if groups:
                entry = found.setdefault(a, {"groups": [], "files": []})
                entry["groups"] += groups
                entry["files"].append(tag)
    out = _ballbar_reversal(datasets)
    for a, (read, files) in signs.items():
        if a not in found and a not in out and read in ({1}, {-1}):
            out[a] = {"one_direction": "+" if read == {1} else "-", "files": list(dict.fromkeys(files))}
    for a, entry in found.items():
        B, n_up, n_down, ss, dof = (np.array(c) for c in zip(*entry["groups"]))
        unit, scale = ("urad", 1e6) if a in ROTARY else ("um", 1e3)
        out[a] = {f"B_{unit}": float(B[np.argmax(np.abs(B))] * scale), f"B_mean_{unit}": float(B.mean() * scale),
                  "p_value": reversal_p_value(B, n_up, n_down, float(ss.sum()), int(dof.sum())),
                  "n_targets": int(B.size), "files": list(dict.fromkeys(entry["files"]))}
    return out


def _tag(d, kind: str) -> str:
    """The name a file goes by in ``info["reversal"]``: its stem."""
    return Path(str(d.path)).stem if getattr(d, "path", None) else kind


def _stated_directions(datasets):
    """(axis letter, the approach directions its readings state (a set of +1/-1), file name) per
    axis and file whose readings state the axis's approach direction: a laser file's moving axis
    (column ``dir``, every component read), and in a points (R-test, three-sphere, grid) or
    ball-bar file every axis that moves in the file and has a ``dir_<axis>`` cell that is not blank
    (a blank cell or an absent column states nothing). An axis the file holds at one position is
    not approached from anywhere the readings tell; a CMM file's points are where a program cut
    (its moves' directions are the program's), and thermal and velocity files read no position:
    they state nothing."""
    for d in datasets:
        d = getattr(d, "data", d)
        kind = getattr(d, "kind", None)
        if kind == "laser":
            for a in dict.fromkeys(d.axis.tolist()):
                sel = (d.axis == a) & np.isfinite(d.value) & (d.dir != 0)
                if sel.any():
                    yield a, set(np.sign(d.dir[sel]).astype(int).tolist()), _tag(d, kind)
            continue
        xyz, abc = getattr(d, "xyz", None), getattr(d, "abc", None)
        if kind not in ("points", "ballbar") or xyz is None:
            continue
        pos = np.column_stack([xyz, abc if abc is not None else np.zeros_like(xyz)])
        for k, a in enumerate(AXIS_ORDER):
            stated = d.context.dirs[:, k] != 0
            column = pos[stated, k]
            column = column[np.isfinite(column)]
            if column.size and float(column.max() - column.min()) > 1e-9:
                yield a, set(np.sign(d.context.dirs[stated, k]).astype(int).tolist()), _tag(d, kind)


def _ballbar_pairs(d):
    """(differences (m,) mm, directions (m, 3)) of ball-bar data ``d``: at every position (axis
    positions, both balls; rotary axes at 0) read in exactly two patterns of the linear axes'
    approach directions, the mean length of the first less the second's, and for each linear axis
    its direction cosine along the bar times half the change of its direction (module docstring)."""
    dirs = d.context.dirs[:, :3]
    ok = np.isfinite(d.length) & np.all(d.abc == 0, axis=1) & np.all(dirs != 0, axis=1)
    if not ok.any():
        return np.zeros(0), np.zeros((0, 3))
    key = np.round(np.column_stack([d.xyz, d.table_ball, d.tool_ball])[ok], 6)
    _, label = np.unique(key, axis=0, return_inverse=True)
    label = label.reshape(-1)
    length, dirs = d.length[ok], dirs[ok]
    arm = (d.xyz + d.tool_ball - d.table_ball)[ok]
    diffs, cols = [], []
    for k in range(label.max() + 1):
        rows = np.flatnonzero(label == k)
        patterns, which = np.unique(dirs[rows], axis=0, return_inverse=True)
        which = which.reshape(-1)
        norm = float(np.linalg.norm(arm[rows[0]]))
        if len(patterns) != 2 or norm == 0.0:
            continue
        diffs.append(length[rows[which == 0]].mean() - length[rows[which == 1]].mean())
        cols.append(arm[rows[0]] / norm * (patterns[0] - patterns[1]) / 2.0)
    return np.array(diffs), np.array(cols).reshape(-1, 3)


def _ballbar_reversal(datasets) -> dict:
    """What the ball-bar files among ``datasets`` show of the linear axes' reversals, as
    :func:`data_reversal` gives it (module docstring)."""
    from scipy.stats import f as fisher_f
    diffs, cols, files = [], [], []
    for d in datasets:
        d = getattr(d, "data", d)
        if getattr(d, "kind", None) != "ballbar":
            continue
        dz, h = _ballbar_pairs(d)
        if dz.size:
            diffs.append(dz)
            cols.append(h)
            files.append(_tag(d, "ballbar"))
    if not diffs:
        return {}
    dz, h = np.concatenate(diffs), np.vstack(cols)
    on = np.flatnonzero(np.abs(h).max(axis=0) > 1e-9)
    dof = dz.size - on.size
    if on.size == 0 or dof <= 0:
        return {}
    B, *_ = np.linalg.lstsq(h[:, on], dz, rcond=None)
    s2 = float(np.sum((dz - h[:, on] @ B) ** 2)) / dof
    var = s2 * np.diag(np.linalg.pinv(h[:, on].T @ h[:, on]))
    out = {}
    for j, b in zip(on, B):
        p = float(fisher_f.sf(b * b / var[list(on).index(j)], 1, dof)) if s2 > 0 else float(b != 0)
        out["XYZ"[j]] = {"B_um": float(b * 1e3), "B_mean_um": float(b * 1e3), "p_value": p,
                         "n_targets": int(dz.size), "files": files}
    return out


class DirectionContrast:
    """The reversal a base model does not hold, taken out of its residual variance.

    A base model is the same in both approach directions; where a laser file reads a target from
    both sides, the readings' mean up minus mean down (the reversal, ISO 230-2) is error the model
    leaves, not noise: as noise it would make the fitted profile look as uncertain as the reversal
    is large, though balanced runs fix the profile's mean as well as their repeats allow. Each such
    target contributes one centred contrast ``c = dir - mean(dir)`` over its readings (the group:
    one file, column, target and static position of the other axes, every approach direction and
    run); :meth:`sum_of_squares` is the part of residuals ``r`` those contrasts explain,
    ``sum_g (c_g . r_g)^2 / (c_g . c_g)``, and :attr:`n_groups` the degrees of freedom it takes. A
    model's noise then stays ``(r.r - sum_of_squares) / (dof - n_groups)``. Files of an axis the
    model does make depend on direction (``model.direction_axes()``: a backlash term) are left
    out: what such a model leaves of the reversal is its misfit, counted like any other (on the
    real runs of ess_b02_y a penalised fit that left it out predicted a new set-up 1.12 times
    worse than the pitch table, against 1.00)."""

    def __init__(self, mms, obs_slices, model):
        from ..measurement.files import LaserData
        from ..measurement.outliers import setup_keys
        idx, contrast, group, n = [], [], [], 0
        held_axes = None
        for m, so in zip(mms, obs_slices):
            d = getattr(m, "data", None)
            if not isinstance(d, LaserData) or m.n_obs == 0:
                continue
            if held_axes is None:       # (a symbolic look at the model: only when laser files come)
                held_axes = [a for a, h in zip(model.machine.axis_names, model.direction_axes()) if h]
            own = ~np.isin(d.axis[m.obs_row], held_axes)
            _, cols = np.unique(np.asarray(m.obs_column, dtype=str), return_inverse=True)
            keys = setup_keys(d, directions=False)[m.obs_row] * (cols.max() + 1) + cols
            _, g = np.unique(keys, return_inverse=True)
            direction = d.dir[m.obs_row].astype(float)
            both = (np.bincount(g, weights=direction > 0) > 0) & (np.bincount(g, weights=direction < 0) > 0)
            keep = both[g] & own
            if not keep.any():
                continue
            _, g = np.unique(g[keep], return_inverse=True)
            direction = direction[keep]
            mean = np.bincount(g, weights=direction) / np.bincount(g)
            idx.append(np.arange(so.start, so.stop)[keep])
            contrast.append(direction - mean[g])
            group.append(g + n)
            n += int(g.max()) + 1
        self.n_groups = n
        self._idx = np.concatenate(idx) if idx else np.zeros(0, dtype=int)
        self._c = np.concatenate(contrast) if contrast else np.zeros(0)
        self._g = np.concatenate(group) if group else np.zeros(0, dtype=int)

    def sum_of_squares(self, r: np.ndarray) -> float:
        """The part of the sum of squares of ``r`` (n_obs,) the groups' contrasts explain."""
        if not self.n_groups:
            return 0.0
        num = np.bincount(self._g, weights=self._c * r[self._idx], minlength=self.n_groups)
        den = np.bincount(self._g, weights=self._c ** 2, minlength=self.n_groups)
        return float(np.sum(num ** 2 / den))


def unheld_records(fitted) -> dict:
    """axis -> its record in ``info["reversal"]`` for every axis on which the model holds no
    backlash term (a record absent or not understood, a hand-edited file, says nothing)."""
    record = fitted.info.get("reversal") if isinstance(fitted.info, dict) else None
    if not isinstance(record, dict):
        return {}
    held = {getattr(t, "axis", None) for t in fitted.model.terms if t.kind == "backlash"}
    return {a: r for a in fitted.machine.axis_names
            if a not in held and isinstance(r := record.get(a), dict)}


def one_direction_axes(fitted) -> dict:
    """axis -> '+' or '-': the axes whose readings in the model's data all state the one approach
    direction (``info["reversal"]``'s ``one_direction``: laser files, and points and ball-bar
    files with ``dir_<axis>`` columns) and on which the model holds no backlash term: their
    reversal is not measured, so the model's correction is the one read from that side."""
    return {a: r["one_direction"] for a, r in unheld_records(fitted).items()
            if r.get("one_direction") in ("+", "-")}

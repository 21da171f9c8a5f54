"""What a model's corrections and predictions assume at zero (:class:`Assumed`).

Two of the model's rules correct with errors nobody measured, taken as zero:

* an axis the data never moved (the static axis of a laser run, the Z of points on one plane) does
  not limit the region: the model is evaluated at the position the data held it at (MODEL.json
  ``held``), so a block away from it is corrected with that axis's errors at zero;
* what the data leave open (MODEL.json ``info.unmeasured``: the components no laser file names,
  with points, ball-bar or CMM data the angular motions) is held at zero.

Neither has a variance: the correction does not move with them, so its standard error leaves them
out. Where they act on a block, compensate says so (:mod:`mtcomp.planner._assumed`), with the arm
they act over; predict and render say it of the model in one note (:func:`model_note`).

A held component acts on a block when a combination of the machine's errors the data leave open
(MODEL.json ``uncertainty.undetermined``, each at the size that makes 1 um rms error over the
region) moves the block's correction, as compensate writes it (relative to the part's datum), by
more than :data:`~mtcomp.models.model_file.UNDETERMINED_UM` and its part of that combination does
too (predict's rule for a blank standard error). Its arm at the block is the motion the
combination's angles (angular motions, a squareness, a tilt of the tool axis) make there, per unit of
the largest of them:
0 at the data's own positions, the height above the laser's line elsewhere. An axis never moved
acts where the block stands away from its held position, over that distance; the held angular
motions of the other axes act over it too (the model, evaluated at the held position, cannot).
"""
from __future__ import annotations

import numpy as np

from .model_file import UNDETERMINED_UM

#: the rotation about each linear axis (its angular motions' second letter: EBX turns about Y)
_ABOUT = {"X": "A", "Y": "B", "Z": "C"}
#: the most items (never-moved axes and held groups) a block's mask names: a float64 holds 52 bits
#: (integers up to 2**53) exactly
MAX_ITEMS = 52
#: a block stands away from a never-moved axis's held position beyond this (mm: the output grid)
AWAY_MM = 1e-3


#: a parameter held at zero is below this (internal units: mm, rad)
_ZERO = 1e-9
#: a group has a part in a combination the data leave open when its parameters' largest entry is
#: above this fraction of the combination's largest (the identification report's rule)
_PART = 1e-6


def _open_groups(specs, N: np.ndarray) -> set:
    """The groups of ``specs`` with a part in some combination of ``N`` (k, m) (columns: the
    combinations the data leave open; rows: ``specs``'s parameters)."""
    if not N.size:
        return set()
    big = np.abs(N).max(axis=0)
    part = np.abs(N) > _PART * np.where(big > 0, big, 1.0)
    return {s.group for s, row in zip(specs, part) if row.any()}


def never_words(name: str, pos, more: str = "") -> str:
    """'Z's errors (never measured: ...)': an axis the data never moved, held at ``pos`` mm."""
    if pos is None:
        return f"{name}'s errors (never measured{more})"
    return f"{name}'s errors (never measured: the data held {name} at {pos:g} mm{more})"


class Assumed:
    """The components a model holds at zero and the axes its data never moved.

    ``items``: the names, the never-moved axes first ('Y'), then the held groups ('X:EBX',
    'squareness'); bit k of a block's mask is ``items[k]``. Rows of :meth:`blocks`: (mask, arm mm,
    the distance from each never-moved axis's held position, mm)."""

    def __init__(self, fitted, machine):
        u = fitted.uncertainty
        idx = np.array([fitted.params.index(n) for n in u["names"]], dtype=int)
        specs = [fitted.params.specs[i] for i in idx]
        free_axes = {s.group.partition(":")[0] for s in specs}
        held = fitted.held or {}
        # (name, column, held position or None); an axis whose errors were all held (--hold,
        # the controller compensates it) is no assumption of the data
        self.never = [(a.name, j, held.get(a.name)) for j, a in enumerate(machine.axes)
                      if not a.is_rotary and a.name not in fitted.support and a.name in free_axes]
        never = {n for n, _, _ in self.never}
        info = fitted.info if isinstance(fitted.info, dict) else {}
        N = (np.asarray(u["undetermined"], dtype=float).reshape(idx.size, -1) if idx.size
             else np.zeros((0, 0)))
        # the groups the rule names (info.unmeasured) that have a part in what the data leave open:
        # one the data determine (a roll the twist of a plate shows) is fitted, not held
        open_ = _open_groups(specs, N)
        # a block's mask is kept in a float64 column: at most MAX_ITEMS bits, exact
        self.groups = [g for g in info.get("unmeasured", ())
                       if g.partition(":")[0] not in never and g in open_][:MAX_ITEMS - len(self.never)]
        #: of those, the ones the data determine in part (a parameter of theirs is not zero)
        self.partly = {g for g in self.groups
                       if np.any(np.abs(fitted.params.values[[i for i, s in zip(idx, specs)
                                                               if s.group == g]]) > _ZERO)}
        self.items = [n for n, _, _ in self.never] + self.groups
        self._idx, self._N = idx, N
        # N over every parameter: J's columns are used as they come (no copy of the fitted ones)
        self._full = np.zeros((fitted.params.values.size, N.shape[1]))
        self._full[idx] = N
        # per held group its parameters and the combinations it has a part in
        self._cols = [np.array([k for k, s in enumerate(specs) if s.group == g], dtype=int)
                      for g in self.groups]
        self._dirs = [np.flatnonzero(np.any(N[c] != 0.0, axis=0)) for c in self._cols]
        # of those, the few where the group's part is largest: tried first at every block
        self._top = [ks[np.argsort(-np.abs(N[np.ix_(c, ks)]).sum(axis=0))[:3]]
                     for c, ks in zip(self._cols, self._dirs)]
        linear = {a.name for a in machine.axes if not a.is_rotary}
        #: the held groups that are angular motions of a linear axis (pitch, roll, yaw: in urad)
        self.angular = {s.group for s in specs if s.unit == "urad"
                        and s.group.partition(":")[0] in linear and s.group in self.groups}
        angle = np.array([s.unit == "urad" for s in specs], dtype=bool)
        # the largest angle (rad) of each combination: its arm is its motion per unit of that
        self._theta = np.abs(N[angle]).max(axis=0) if angle.any() and N.shape[1] else np.zeros(N.shape[1])
        # the angles' own rows: the arm is the motion *they* make (a combination of straightness
        # profiles with a trace of an angle would otherwise get an arm of kilometres)
        self._angle_rows = np.flatnonzero(angle)
        # per never-moved axis the held angular motions with an arm along it (not those about it)
        self._angular = [sum(1 << (len(self.never) + b) for b, g in enumerate(self.groups)
                             if g in self.angular and g[3] != _ABOUT.get(name))
                         for name, _, _ in self.never]

    @staticmethod
    def of(fitted, machine) -> "Assumed | None":
        """The model's assumptions, or None when it makes none (no covariance, no region stated,
        nothing held at zero and every linear axis moved)."""
        if fitted.uncertainty is None or fitted.support is None:
            return None
        a = Assumed(fitted, machine)
        return a if a.items else None

    @property
    def width(self) -> int:
        return 2 + len(self.never)

    def _part_over(self, Jc, cols, ks, top, keep, some, tol) -> np.ndarray:
        """(n,) bool: the group's part (its parameters ``cols``) of a combination that moves the
        block (``keep`` (n, 1, k), None: all do; ``some`` (n,): any does) moves it by more than
        ``tol`` mm. Tried on the group's ``top`` combinations first, at every block; on all its
        combinations ``ks`` only where those do not (a ninth of the work on a program away from the
        data's lines). Jc : (n, 3, len(cols)) its columns of the Jacobian."""
        def over(rows, dirs):
            P = np.abs(Jc[rows] @ self._N[np.ix_(cols, dirs)])              # (m, 3, len(dirs))
            if keep is not None:
                P *= keep[rows][:, :, dirs]
            return P.max(axis=(1, 2)) > tol
        hit = over(slice(None), top)
        rest = some & ~hit
        if rest.any() and ks.size > top.size:
            hit[rest] = over(rest, ks)
        return hit

    def blocks(self, q: np.ndarray, J: np.ndarray) -> np.ndarray:
        """(n, width): per block the mask of the items that act on its correction, the largest arm
        they act over (mm) and the distance from each never-moved axis's held position (mm).
        q : (n, na) machine positions (mm, rad), not clamped. J : (n, 3, n_params) the Jacobian of
        the correction (the tip deviation less the datum's), mm per internal unit."""
        n = q.shape[0]
        out = np.zeros((n, self.width))
        mask = np.zeros(n, np.int64)
        if self._N.shape[1]:
            # products of each block's (3, p): small enough that BLAS runs them on this thread (one
            # (3 n, p) product took BLAS's threads, which spun against the planner's own: twice
            # the processor time)
            tol = UNDETERMINED_UM * 1e-3                                            # mm
            tot = np.abs(J @ self._full).max(axis=1)                                # (n, k) mm
            moved = tot > tol
            keep = None if moved.all() else moved[:, None, :]
            some = moved.any(axis=1)
            for b, (cols, ks, top) in enumerate(zip(self._cols, self._dirs, self._top)):
                if ks.size:
                    hit = self._part_over(J[:, :, self._idx[cols]], cols, ks, top, keep, some, tol)
                    mask |= hit.astype(np.int64) << (len(self.never) + b)
            rows = self._angle_rows
            turned = (np.abs(J[:, :, self._idx[rows]] @ self._N[rows]).max(axis=1) if rows.size
                      else np.zeros_like(tot))                                   # (n, k) mm
            ratio = np.divide(turned, self._theta, out=np.zeros_like(tot), where=self._theta > 0)
            out[:, 1] = np.where(moved, ratio, 0.0).max(axis=1)
        for k, (_, j, pos) in enumerate(self.never):
            if pos is None:
                continue
            d = np.abs(q[:, j] - pos)
            away = d > AWAY_MM
            out[:, 2 + k] = np.where(away, d, 0.0)
            mask |= away.astype(np.int64) << k
            if self._angular[k]:
                # the held angular motions act over the distance too, where the model cannot see
                mask |= np.where(away, self._angular[k], 0)
                out[:, 1] = np.where(away, np.maximum(out[:, 1], d), out[:, 1])
        out[:, 0] = mask
        out[mask == 0, 1] = 0.0
        return out


#: words for the groups that are no axis's own component
_GROUP_WORDS = {"squareness": "the squareness", "spindle": "the tool axis's tilt",
                "tool": "the tool length's offset"}


def held_words(groups, angular, partly=()) -> str:
    """'X's angular motions (EAX, EBX), Z's errors (EXZ) and the squareness': the held groups
    ('X:EAX', 'squareness'; ``angular``: those that are angular motions, ``partly``: those the data
    determine in part: 'EBX in part'), an axis's together."""
    per: dict = {}
    other = []
    for g in groups:
        axis, _, comp = g.partition(":")
        part = " in part" if g in partly else ""
        if comp:
            kind = "angular motions" if g in angular else "errors"
            per.setdefault((axis, kind), []).append(comp + part)
        else:
            other.append(_GROUP_WORDS.get(g, g) + part)
    parts = [f"{a}'s {kind} ({', '.join(c)})" for (a, kind), c in per.items()] + other
    return parts[0] if len(parts) == 1 else ", ".join(parts[:-1]) + " and " + parts[-1]


def model_note(fitted, machine, what: str, q: np.ndarray | None = None, acting: bool = True) -> str:
    """The note predict and render print of the model as a whole (``what``: 'the predictions'):
    the axes its data never moved (with ``q`` (n, na) machine positions, those some row stands away
    from) and every component it holds at zero; '' when it assumes nothing, or when nothing is
    ``acting`` (predict: no prediction rests on what the data left open) and no row stands away."""
    a = Assumed.of(fitted, machine)
    if a is None:
        return ""
    never = [(n, pos) for n, j, pos in a.never
             if q is None or pos is None or bool(np.any(np.abs(q[:, j] - pos) > AWAY_MM))]
    if not (acting or never):
        return ""
    said = [never_words(n, pos) for n, pos in never]
    if a.groups:
        said.append(f"{held_words(a.groups, a.angular, a.partly)} (held at zero where the data "
                    "leave them open)")
    return (f"note: {what} assume zero for {' and for '.join(said)}: where these act (away from "
            "the positions the data were taken at, over an Abbe arm) the figures are the model's on "
            "that assumption, not a measurement, and no standard error counts it")

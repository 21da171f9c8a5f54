"""What the data behind a fitted model left undetermined, and the standard error of a prediction
from its covariance (:class:`Undetermined`): predict's rule for a blank standard error, which
compensate applies to its corrections (:mod:`mtcomp.planner._evaluate`).

A standard error comes from the model's covariance, which includes the variance the data leave
along the directions the fit held because the data fix them only weakly (the model file's
``uncertainty.held``, with ``held_sd_um``). Only the directions the data do not determine at all
(``uncertainty.undetermined``) blank a prediction."""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .._threads import one_blas_thread
from .model_file import UNDETERMINED_UM, FittedModel

#: a parameter whose standard error is below this share of the model's largest (file units) has
#: none: the data see nothing of it (:meth:`Undetermined.splits`); the fit's unseen components sit at
#: 1e-8 to 1e-12 of it, the least seen ones at 1e-3
UNSEEN = 1e-6


@dataclass
class Undetermined:
    """What the data behind a model left undetermined, to blank predictions that rest on it, and the
    covariance that gives the others their standard errors.

    index : (k,) positions in the model's parameters of the fitted ones (the covariance's order).
    directions : (k, m) directions of those parameters the data did not determine (the model
        file's ``uncertainty.undetermined``), internal units, each scaled to 1 um rms tool-tip error
        over the machine's travel. None: the model carries no uncertainty. The directions the fit
        held because the data fix them only weakly are not among them: their variance is in the
        covariance (``factor``).
    to_file : (k,) file unit per internal unit of each fitted parameter.
    largest_sd : the largest standard error of any combination of unit size of the fitted
        parameters in file units (um, urad): below :attr:`ROUNDING` of it a standard error counts
        as none at all (parameters held with no variance).
    """

    index: np.ndarray | None
    directions: np.ndarray | None
    to_file: np.ndarray | None = None
    largest_sd: float = 0.0
    #: (indices, F) with F F^T the covariance (:meth:`FittedModel.covariance_factor`), computed once
    factor: tuple | None = None
    #: (k,) each fitted parameter's standard error (internal units; the factor's order)
    parameter_sd: np.ndarray | None = None

    #: a prediction whose standard error is below this share of what its own parameters' standard
    #: errors could give it (all moving together) has none: the fit held what it rests on (a held
    #: combination has no variance at all, to rounding), it did not measure it
    NO_VARIANCE = 1e-9
    #: nor one below this share of the model's largest standard error (per unit of its Jacobian):
    #: parameters held with no variance at all, to rounding. A model of the real ISO 230-2 run of
    #: X (ess_b02_x) predicts its own readings at 0.018 to 0.022 of it, the Y run (held) at 1e-26;
    #: a laser-measured positioning profile beside a spline function of 2e7 um, 1.3e-9
    ROUNDING = 1e-13

    @classmethod
    def of(cls, fitted: FittedModel) -> "Undetermined":
        u = fitted.uncertainty
        if u is None:
            return cls(None, None)
        idx = np.array([fitted.params.index(n) for n in u["names"]], dtype=int)
        f = np.array([fitted.params.specs[i].to_file for i in idx])
        factor = fitted.covariance_factor()
        scaled = factor[1] * f[:, None]          # the same parameters, in the same order
        with one_blas_thread():
            top = float(np.linalg.norm(scaled, 2)) if scaled.size else 0.0
        # (no parameter free: no direction left open either)
        undetermined = np.asarray(u["undetermined"], dtype=float).reshape(idx.size, -1) if idx.size \
            else np.zeros((0, 0))
        return cls(idx, undetermined, f, top, factor, np.linalg.norm(factor[1], axis=1))

    def rests_on_open(self, J_first: np.ndarray, setup: np.ndarray | None = None) -> np.ndarray:
        """(n,) bool: the predictions whose Jacobian at zero errors is ``J_first`` (n, n_params; file
        units per internal unit) move by more than 0.01 (um, urad) along some combination the data
        left undetermined (:attr:`directions`), after what the ``setup`` absorbs (:meth:`assess`):
        predict's rule for a blank standard error."""
        J_first = np.atleast_2d(J_first)
        if self.directions is None or not self.directions.shape[1]:
            return np.zeros(J_first.shape[0], dtype=bool)
        moved = J_first[:, self.index] @ self.directions
        if setup is not None and setup.shape[1]:
            rows = np.all(np.isfinite(setup), axis=1)
            D = setup[rows]
            moved[rows] -= D @ np.linalg.lstsq(D, moved[rows], rcond=None)[0]
        return np.abs(moved).max(axis=1) > UNDETERMINED_UM

    def splits(self, fitted: FittedModel) -> "Undetermined":
        """The same, with :attr:`directions` only the combinations that split what the data see
        between components (compensate's rule, docs/planner.md): what is left of the undetermined
        span with every component the model holds at zero by rule taken out, the components no
        laser file names (MODEL.json ``info.unmeasured``, held at zero where the data leave them
        open: docs/identification.md) and those the data see nothing of at all (no parameter of the
        component has a variance: C's positioning read by balls on C's axis, the z straightness of
        plates read in x and y). A correction resting on those corrects nothing of them (they stay
        at zero); one resting on a split takes the fit's choice of it for a measurement."""
        N = self.directions
        if N is None or not N.shape[1]:
            return self
        groups = np.array([fitted.params.specs[i].group for i in self.index])
        info = fitted.info if isinstance(fitted.info, dict) else {}
        held = set(info.get("unmeasured", ()))
        sd = self.parameter_sd * self.to_file                   # file units: um and urad alike
        unseen = sd <= UNSEEN * max(float(sd.max()) if sd.size else 0.0, 1e-300)
        held |= {g for g in set(groups.tolist()) if np.all(unseen[groups == g])}
        rows = np.isin(groups, list(held))
        if not rows.any():
            return self
        Nf = N * self.to_file[:, None]
        with one_blas_thread():
            _, s, Vt = np.linalg.svd(Nf[rows], full_matrices=True)
        rank = int(np.sum(s > 1e-9 * float(np.abs(Nf).max())))
        return replace(self, directions=N @ Vt[rank:].T)

    def std(self, J: np.ndarray, setup: np.ndarray | None = None,
            J_first: np.ndarray | None = None) -> np.ndarray:
        """(n,) standard error of n predictions whose Jacobian with respect to the model's parameters
        is J (n, n_params; file units per internal unit), from the model's covariance; NaN where the
        data behind the model do not determine a prediction (:meth:`assess`), or where the model
        carries no uncertainty."""
        return self.assess(J, setup, J_first)[0]

    def assess(self, J: np.ndarray, setup: np.ndarray | None = None,
               J_first: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(sd (n,), unknown (n,) bool) of n predictions whose Jacobian is J (:meth:`std`).

        sd is NaN where a prediction moves by more than 0.01 (um, urad) along an undetermined
        direction (judged with the Jacobian ``J_first`` when given: at zero errors, see
        :func:`predict_readings`), or where it is unknown. unknown: the prediction rests only on
        what the fit held (its standard error is no more than :attr:`NO_VARIANCE` of the model's
        largest while it moves with the fitted parameters): the model knows nothing of it, and the
        number it holds there (zero, or 1e-9) is no prediction. False everywhere for a model
        without uncertainty.

        setup : (n, k) the predictions' derivatives with respect to their file's set-up (a laser's
            zero, a tracker's frame). Readings are compared up to their set-up: what a set-up would
            absorb (a constant on every reading of a laser component) is taken out of each
            direction's effect before the 0.01 test; and the rows of one set-up parameter are
            unknown together when none of them with any content is known (the reading of a Y laser
            run at Y = 0, where a profile is zero by its reference, is no better known than the
            others); a row that shares no set-up parameter is judged on its own.
        """
        J = np.atleast_2d(np.asarray(J, dtype=float))
        if self.factor is None:
            return np.full(J.shape[0], np.nan), np.zeros(J.shape[0], dtype=bool)
        idx, F = self.factor
        sd = np.linalg.norm(J[:, idx] @ F, axis=1)
        open_ = self.rests_on_open(J if J_first is None else J_first, setup)
        # what the prediction's own parameters could give it at most (all of them moving together,
        # each by its standard error): a held combination of them leaves only rounding of that; and
        # ROUNDING of the model's largest standard error (parameters held with no variance at all).
        # Judged against the largest alone, one spline coefficient of 2e7 um at the data's edge
        # blanked every range of a laser-measured profile
        content = np.any(J[:, self.index] != 0, axis=1)
        size = np.abs(J[:, idx]) @ self.parameter_sd
        largest = np.linalg.norm(J[:, self.index] / self.to_file, axis=1) * self.largest_sd
        held_only = content & (sd <= self.NO_VARIANCE * size + self.ROUNDING * largest)
        if setup is None or not setup.shape[1]:
            unknown = held_only
        else:
            acts = np.abs(np.nan_to_num(setup)) > 1e-6 * np.abs(np.nan_to_num(setup)).max(axis=0)
            unknown = held_only & ~acts.any(axis=1)
            for k in range(acts.shape[1]):
                group = acts[:, k]
                if np.any(group & content) and np.all(held_only[group & content]):
                    unknown |= group
        return np.where(open_ | unknown, np.nan, sd), unknown


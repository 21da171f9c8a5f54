"""A correction's standard error and the rule that leaves it unmade: the one source of both for
compensate's blocks, export's table nodes and render's map of what compensate would leave.

A correction at a pose is the model's tool-tip deviation there less the deviation at its reference
(the part's datum for compensate, the table's zero for export). Its standard error, per tip
component, is that of the difference under the model's covariance as predict takes it: the
variance of the combinations the fit held because the data fix them only weakly is counted (the
correction does not move along them, but the truth may differ from the held value by that much),
and a drift model's model error once (:meth:`FittedModel.model_error_variance`); it is infinite
where the correction moves with values the data left undetermined or rests on how the roughness
penalty split what the data cannot tell apart (:meth:`FittedModel.tip_sd_um`). A correction is
not made where the largest component's standard error exceeds the limit
(``--max-correction-sd-um``), nor where it is within :data:`SMALL_IN_SD` of its standard errors of
zero in every component (docs/planner.md, *Blocks where the model is unsure*); how those decisions
spread over a contour, or over an export table, is :mod:`._contours`'s.
"""
from __future__ import annotations

import numpy as np

from ..models.model_file import UNDETERMINED_UM

#: a correction within this many of its standard errors of zero (in every component of the tip) is
#: not told from none (docs/planner.md, *Blocks where the model is unsure*)
SMALL_IN_SD = 2.0


class CorrectionUncertainty:
    """What a fitted model says of its corrections' standard errors, taken from it once."""

    def __init__(self, fitted):
        self.fitted = fitted
        #: predict's covariance, the combinations the fit held weakly included
        self.factor = fitted.covariance_factor(held=True)
        known = self.factor is not None
        #: the part of the values along what the data left undetermined (a correction moving with
        #: it is unsure), and the penalty's split of what the data cannot tell apart
        self.open = fitted.undetermined_values() if known else None
        self.choice = fitted.choice_directions() if known else None
        #: (indices into the parameters, (k, m) the directions the data left undetermined, each
        #: at 1 um rms over the region), or None: where a tool-axis deviation moves along one, the
        #: data do not determine it (predict's rule for a blank standard error)
        u = fitted.uncertainty if known else None
        N = None if u is None else np.asarray(u["undetermined"], dtype=float)
        self.undetermined = None if N is None or not N.size else (
            np.array([fitted.params.index(n) for n in u["names"]], dtype=int),
            N.reshape(len(u["names"]), -1))

    @property
    def known(self) -> bool:
        """The model carries a covariance (without one no standard error is known)."""
        return self.factor is not None

    def components(self, J: np.ndarray, J_reference: np.ndarray | None = None) -> np.ndarray:
        """(n, 3) um: each tip component's standard error of the corrections whose Jacobians with
        respect to the parameters are J (n, 3, n_params) at the pose and ``J_reference`` (n or 1,
        3, n_params) at their reference (None: the raw deviation), mm (module docstring)."""
        extra = None
        if J_reference is not None:
            # the drift since the reference's state: the model error it misses there counted once
            extra = self.fitted.model_error_variance(J)
            J = J - J_reference
        return self.fitted.tip_sd_um(J, self.factor, self.open, extra, self.choice, components=True)

    def orientation(self, J: np.ndarray) -> np.ndarray:
        """(n, 3) urad: each component's standard error of the tool-axis deviations whose
        Jacobians with respect to the parameters are J (n, 3, n_params), rad, under the same
        covariance as :meth:`components` (a tool-axis deviation is corrected as it stands: probing
        a datum removes none); infinite where it moves with values the data left undetermined or
        along a direction they leave open by more than :data:`UNDETERMINED_UM` urad (a spindle's
        tilt that no measurement with one stylus length tells from a table's: predict leaves its
        standard error blank there)."""
        J = np.asarray(J, dtype=float) * 1e3        # rad as the mm tip_sd_um takes: its um are urad
        sd = self.fitted.tip_sd_um(J, self.factor, self.open, None, self.choice, components=True)
        if self.undetermined is not None:
            idx, N = self.undetermined
            moved = np.abs(J[:, :, idx] @ N).max(axis=(1, 2)) * 1e3
            sd[moved > UNDETERMINED_UM] = np.inf
        return sd


def orientation_left(axis_urad: np.ndarray, each: np.ndarray, limit_urad: float) -> np.ndarray:
    """(n,) bool: the blocks whose tool-axis correction (``axis_urad`` (n, 3), the deviation it
    removes) is not made: its standard error ``each`` (n, 3) (:meth:`CorrectionUncertainty
    .orientation`) exceeds ``limit_urad`` in some component (infinite: the data do not determine
    it), or it is within :data:`SMALL_IN_SD` of its standard errors of zero in every component
    (as :func:`in_sd` judges a tip correction)."""
    each = np.asarray(each, dtype=float)
    with np.errstate(invalid="ignore"):
        over = (each > limit_urad).any(axis=1)
        z = in_sd(axis_urad, each)
        return over | (z < SMALL_IN_SD)


def in_sd(correction_um: np.ndarray, each: np.ndarray) -> np.ndarray:
    """(n,) the corrections ``correction_um`` (n, 3) (tip deviation less its reference's, um) in
    their own standard errors ``each`` (n, 3) (:meth:`CorrectionUncertainty.components`): the
    largest over the tip's components of |its correction| / its standard error; NaN (not judged)
    where some standard error is infinite (the correction is over any limit) or the correction is
    under :data:`UNDETERMINED_UM` in every component (written or not, the pose is the same)."""
    size = np.abs(np.asarray(correction_um, dtype=float))
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(size > 0, size / each, 0.0).max(axis=1)
    z[np.isinf(each).any(axis=1) | (size.max(axis=1) < UNDETERMINED_UM)] = np.nan
    return z

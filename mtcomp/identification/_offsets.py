"""A rotary axis's zero offset the data do not read apart from its positioning error.

The zero offset (``EAA_0``, ``EBB_0``, ``ECC_0``) is the constant of the axis's angular positioning
error, a Fourier series over the turn: its mean over the whole turn. Data that hold the axis at one
angle (an R-test at one tilt of A) read the offset and the series' value there as one number; data
that read it over part of a turn (C from 0 to 90 deg) read the series there, and the constant comes
only with how the fitted harmonics continue beyond them. Either way the split is not the data's:
the fit keeps the sum (its predictions at the angles read use it, with its standard error), and the
offset itself is reported as not determined (no standard error), in identify's table and export's
notes alike. The data read the offset where they read the axis round its turn: at three angles or
more (a Fourier series of order 1 at least, :func:`mtcomp.models.basis.auto_fourier_order`) spread
over half a turn or more.

A linear axis has no offset parameter: each of its component errors is zero in the mean over the
range its knots span (:mod:`mtcomp.models.basis`), which is a reference, not a reading.
"""
from __future__ import annotations

import math

import numpy as np

from ..models.chain import positioning_component

#: the data read a rotary axis round its turn when their angles span this much at least (rad): a tilting
#: axis read from -90 to 90 deg is read so
HALF_TURN = math.pi


def unread_offsets(fitted) -> dict:
    """{parameter name: why} of the zero offsets of the rotary axes that ``fitted`` (a FittedModel
    with its ``support`` and ``held`` recorded) has but whose data did not read the axis round its
    turn."""
    out = {}
    support, held = fitted.support or {}, fitted.held or {}
    for ax in fitted.machine.rotary_axes:
        name = f"{positioning_component(ax.name)}_0"
        if name not in fitted.params:
            continue
        if ax.name in held:
            out[name] = f"the data held {ax.name} at {math.degrees(held[ax.name]):g} deg"
        elif ax.name in support:
            lo, hi = support[ax.name]
            if hi - lo < HALF_TURN * (1.0 - 1e-9) or ax.fourier_order < 1:
                out[name] = (f"the data read {ax.name} from {math.degrees(lo):g} to "
                             f"{math.degrees(hi):g} deg only")
    return out


def mark_unread_offsets(result) -> None:
    """The zero offsets of :func:`unread_offsets` in ``result`` (a FitResult with its fitted model)
    get no standard error and ``determined`` False, and the summary a sentence on them; the
    covariance stays, so that predictions at the angles read keep theirs."""
    fitted = result.fitted_model
    unread = unread_offsets(fitted)
    if not unread:
        return
    for name in unread:
        i = fitted.params.index(name)
        result.std_errors[i] = np.nan
        result.determined[i] = False
        if fitted.params.std_errors is not None:
            fitted.params.std_errors[i] = np.nan
    result.info["unread_offsets"] = (
        "; ".join(f"{name}: {why}" for name, why in unread.items())
        + ": a zero offset, the mean of the axis's angular positioning error over its turn, is not "
        "told from the error at the angles read (the model holds their sum, and predicts those "
        "angles with it): not determined by the data")

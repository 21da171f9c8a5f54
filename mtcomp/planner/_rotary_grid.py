"""Rotary corrections on the output grid, and the linear corrections re-solved for the rounded turn.

A rotary axis is written to 1e-4 deg (1.75 urad). One step of it moves the tool tip by r * 1.75 urad
(0.17 um at r = 100 mm from the table's axis), much more than a step of a linear axis (0.1 um, 0.05 um
at most by rounding). The planner's corrections pair rotary and linear moves: a turn of the table
that holds the tip while X or Y ramp in under the step bound, or a turn against a tool-axis error
with the X/Y/Z moves that bring the tip back. Rounding the turn on its own breaks the pair: a
correction of -0.7 urad of A rounds to 0 while the 0.16 um of Y that went with it stays, and the
block ends 0.2 um worse than uncorrected. So the rotary columns are rounded first and the linear
columns re-solved for the rounded turn:

    x_L' = x_L - (A_L^T A_L + diag(lam_L))^-1 A_L^T A_R (round(x_R) - x_R)

per block (first order; A the objective's Jacobian, lam the regularisation), the least change of
the linear corrections that gives back the objective's residual the unrounded pair had. In a
window the bounds made OSQP solve, the linear corrections are solved again with the rotary ones
fixed at their rounded values (:func:`solve_with_rotary_fixed`), so the step and never-worse bounds
hold for them too: each block's own best X/Y/Z, clipped to the box, where that keeps every bound
(:func:`box_optimum`, the usual case), OSQP over the window otherwise. The linear corrections are
then rounded as before (0.05 um at most per axis).
"""
from __future__ import annotations

import numpy as np

from ._evaluate import objective_jacobian, objective_residual
from ._qp import never_worse_rows
from ._small import NormalFactor, a_x, at_b, gram, row_max_abs


def rotary_columns(machine) -> np.ndarray:
    """(na,) bool: the machine's rotary axes."""
    return np.array([a.is_rotary for a in machine.axes], bool)


def round_rotary(bounds, lin, x: np.ndarray, rotary: np.ndarray, lam) -> np.ndarray:
    """x (n, na, um and urad) with its rotary columns rounded to the output grid and its linear
    columns re-solved for the rounded turn (module docstring), to first order around ``lin``
    (:class:`~mtcomp.planner._pointwise.Linearization`); x itself (a copy) without a grid or a
    rotary axis. lam : (na,) the regularisation weights."""
    x = np.array(x, dtype=float, copy=True)
    if bounds.grid is None or not rotary.any() or x.shape[0] == 0:
        return x
    return set_turn(lin, x, bounds.quantize(x)[:, rotary], rotary, lam)


def set_turn(lin, x: np.ndarray, xr: np.ndarray, rotary: np.ndarray, lam) -> np.ndarray:
    """x (n, na), changed in place and returned, with its rotary columns set to ``xr`` (n, k) and
    its linear columns re-solved for that turn (module docstring: the least change of the linear
    corrections that gives back the objective's residual, to first order around ``lin``)."""
    d_r = xr - x[:, rotary]
    x[:, rotary] = xr
    rows = np.flatnonzero(row_max_abs(d_r) > 0)
    if rows.size == 0:
        return x
    sel = slice(None) if rows.size == x.shape[0] else rows     # no copies in the usual case
    linear = np.flatnonzero(~rotary)
    M, A = lin.orientation_rows[sel], lin.A[sel]
    shift = a_x(objective_jacobian(M, A[:, :, rotary]), d_r[sel])   # what the rounding did
    step = NormalFactor(objective_jacobian(M, A[:, :, linear]),
                        np.asarray(lam, dtype=float)[linear]).step(shift)
    if rows.size == x.shape[0]:
        x[:, linear] += step
    else:
        x[np.ix_(rows, linear)] += step
    return x


def solve_with_rotary_fixed(qp, bounds, lin, x, box, steps, reachable, lam, rotary):
    """A bounded window's corrections x (n, na) with the rotary ones rounded to the grid and fixed
    there, the linear ones solved again under every bound (``qp``: the window's
    :class:`~mtcomp.planner._qp.WindowQP`; ``box`` = (lower, upper) and ``steps`` = (step_lo,
    step_hi) as it takes them, anchor row first). The never-worse rows keep their tolerance where the
    linear axes can keep it; a row only the rotary axes move (the tool axis) may take what the
    rounded turn gives it. Returns the per-block re-solve (:func:`round_rotary`) when that QP has no
    solution."""
    start = round_rotary(bounds, lin, x, rotary, lam)
    if bounds.grid is None or not rotary.any() or np.array_equal(start[:, rotary], x[:, rotary]):
        return start
    lower, upper = (np.array(a, dtype=float, copy=True) for a in box)
    lower[1:, rotary] = start[:, rotary]
    upper[1:, rotary] = start[:, rotary]
    c, A = lin.objective()
    J, lo, hi = never_worse_rows(objective_residual(lin.orientation_rows, lin.b0), c, A, reachable)
    # the rows as the rounded turn leaves them, the linear axes re-solved: a row beyond its room
    # there (the tool axis, which no linear axis turns) gets that much room
    at = a_x(A, start)
    lo = np.minimum(lo, at - 1e-9)
    hi = np.maximum(hi, at + 1e-9)
    y = box_optimum(A, c, lam, rotary, start, (lower, upper), steps, (lo, hi))
    if y is not None:
        return y
    na = x.shape[1]
    H = np.concatenate([np.eye(na)[None], gram(A, lam)])
    g = np.vstack([np.zeros((1, na)), at_b(A, c)])
    x0 = np.vstack([lower[:1], start])
    sol, status = qp.solve(H, g, lower, upper, steps[0], steps[1], x0, J, lo, hi)
    if status not in ("solved", "solved inaccurate"):
        return start
    out = sol[1:].copy()
    out[:, rotary] = start[:, rotary]       # exactly on the grid (OSQP meets l = u to its tolerance)
    return out


def box_optimum(A, c, lam, rotary, start, box, steps, worse):
    """The usual case of :func:`solve_with_rotary_fixed` without OSQP: each block's own best linear
    correction for the rounded turn ``start[:, rotary]``, clipped to the box (the tip's Jacobian in
    X, Y, Z is a rotation, so clipping gives the box's optimum). Where that keeps every step bound
    and never-worse row (``worse`` = (lo, hi) of ``A x``), it is the window's optimum, the objective
    being a sum over blocks; None where it does not (then OSQP solves the window)."""
    lower, upper = box
    linear = ~rotary
    y = start.copy()
    y[:, linear] = NormalFactor(A[:, :, linear], np.asarray(lam, dtype=float)[linear]).step(
        c + a_x(A[:, :, rotary], start[:, rotary]))
    y = np.clip(y, lower[1:], upper[1:])
    d = np.diff(np.vstack([lower[:1], y]), axis=0)
    ay = a_x(A, y)
    if (np.all(d >= steps[0] - 1e-9) and np.all(d <= steps[1] + 1e-9)
            and np.all(ay >= worse[0] - 1e-9) and np.all(ay <= worse[1] + 1e-9)):
        return y
    return None

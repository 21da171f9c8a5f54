"""Tool centre point (TCP) programs: the program's words and the axis positions the controller reaches.

In TCP mode (LinuxCNC ``M428`` ... ``M429``, Fanuc ``G43.4`` ... ``G49``) a program gives the tool
tip in the workpiece frame (X Y Z, plus the work offset) and the rotary axes' positions (A B C), and
the controller's kinematics finds the linear axes' positions. mtcomp's planner works on axis
positions, so a TCP block is turned into the axes the controller reaches (:func:`axes_of_tcp`), its
correction is planned there, and the corrected axes are written back as the tip and angles the
controller turns into them (:func:`tcp_of_axes`): the program stays in TCP mode.

For fixed rotary angles the nominal tip is an affine function of the linear axes,
``tip = M lin + b`` (M a rotation: the rotary axes turn the table, the linear axes move the tool or
the table straight), so the inverse is exact: ``lin = M^-1 (tip - b)``, with M and b from
:func:`mtcomp.kinematics.forward` at the block's angles. Machines with X, Y and Z (any rotary axes
on either side whose angles the program gives) are covered.

Units: mm and rad; arrays (N, n_axes) in ``machine.axis_names`` order.
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..kinematics import forward
from ..machine import Machine


def _linear_columns(machine: Machine) -> np.ndarray:
    """Column of X, Y and Z in ``machine.axis_names`` (InputError without all three)."""
    names = machine.axis_names
    missing = [a for a in "XYZ" if a not in names]
    if missing:
        raise InputError(f"tool centre point programs need the axes X, Y and Z (the machine has no "
                         f"{', '.join(missing)})")
    return np.array([names.index(a) for a in "XYZ"])


def _affine(machine: Machine, q: np.ndarray, lin: np.ndarray):
    """(M (N, 3, 3), b (N, 3)): the nominal tip is ``M q[:, lin] + b`` at the angles of ``q``."""
    q0 = np.array(q, dtype=float)
    q0[:, lin] = 0.0
    b = forward(machine, q0)[0]
    M = np.empty((q0.shape[0], 3, 3))
    for k, j in enumerate(lin):
        qj = q0.copy()
        qj[:, j] = 1.0
        M[:, :, k] = forward(machine, qj)[0] - b
    return M, b


def axes_of_tcp(machine: Machine, words: np.ndarray) -> np.ndarray:
    """(N, n_axes) the axis positions the controller reaches for TCP words (N, n_axes): X Y Z the
    tool tip in the workpiece frame (mm), the rotary axes their angles (rad, kept)."""
    words = np.atleast_2d(np.asarray(words, dtype=float))
    lin = _linear_columns(machine)
    if not machine.rotary_axes:
        return words.copy()
    M, b = _affine(machine, words, lin)
    out = words.copy()
    out[:, lin] = np.linalg.solve(M, (words[:, lin] - b)[:, :, None])[:, :, 0]
    return out


def tcp_of_axes(machine: Machine, q: np.ndarray) -> np.ndarray:
    """(N, n_axes) the TCP words of axis positions q (N, n_axes): X Y Z the nominal tool tip in the
    workpiece frame, the rotary axes as they are. The inverse of :func:`axes_of_tcp`."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    lin = _linear_columns(machine)
    out = q.copy()
    out[:, lin] = forward(machine, q)[0]
    return out

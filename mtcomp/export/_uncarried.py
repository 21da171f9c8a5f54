"""The model's single-valued errors no exported table carries, and what they do at the tool tip.

A controller's tables are 1-D: each holds the component errors of one axis along that axis, read
with every other axis at the pose the tables are built for (:mod:`._tables`). The correction they
make at a pose q is the sum over the axes of each carried column at q's position of that axis. A
rotary axis's location (the offset and tilt of its line), its zero offset, a squareness whose
straightness the format has no table for, the spindle's tilt: each makes a tool-tip error that such
a sum does not hold (a C line's offset e moves the tip by (R(C) - I) e: zero at C = 0, 2 |e| at
C = 180 deg). For each such value of the model this module finds, over the volume the data reached
(linear axes at the ends and the tables' pose, rotary axes swept), the largest tool-tip error the
value alone makes that the written tables do not take away, and says which of the controller's
parameters carry it where that is known.
"""
from __future__ import annotations

import math

import numpy as np

from ..models.evaluate import deviation
from ._tables import FULL, LINEAR, MEAN, component_names, fit_line

#: the largest step of the sweep of a rotary axis (deg)
SWEEP_DEG = 15.0

#: a value whose uncarried tool-tip error stays below this (um) goes unmentioned
FLOOR_UM = 0.1

_FANUC_TCP = ("FANUC Series 30i-MODEL A, Tool center point control for 5-axis machining, A-79348E")
_HAAS = "Haas mill operator's manual, Next Generation Control, Settings 255-257"
_HEIDENHAIN = ("HEIDENHAIN Technical Manual iTNC 530 HSCI, KinematicsComp: 'Geometry errors of axes' "
               "and the recommended transformation chains")


#: what is said of a value the data do not determine, in place of who carries it
UNDETERMINED = ("not determined by the data: its value in the model is one of many that fit the data "
                "alike, so no value of it is a correction to enter (in a parameter, a setting or a "
                "program): a rotary axis line's offset read at one stylus length or ball height trades "
                "with the spindle's tilt and the tool's length, a tilt with a squareness, a zero offset "
                "with the axis's positioning error at the angles read (identify --verbose lists what "
                "each trades with); measure it apart (an R-test at two stylus lengths or ball heights "
                "for a line's offset and tilt; the axis's angle read where it is zero for a zero "
                "offset) and fit again; mtcomp compensate leaves uncorrected what moves with it")


def carrier(fmt: str, machine, name: str) -> str:
    """Which of the controller's own parameters carry the value ``name`` (a sentence), or the advice
    to correct the program instead."""
    rotary = {ax.name for ax in machine.rotary_axes}
    offset = name[0] in "XYZ" and name[1] == "0" and name[-1] in rotary     # X0C: a line's offset
    if fmt == "heidenhain":
        return ("the TNC's kinematics description takes an ISO 230-1 position error (X0C and the "
                "like) as a transformation entry (Trans) of its chain with the KinematicsComp option "
                f"({_HEIDENHAIN}); without it, correct the program with mtcomp compensate")
    if fmt == "fanuc" and offset:
        return ("a table-rotation machine's tool centre point control (G43.4, parameter 19680 = 12) "
                "holds where the rotary axis lines lie: parameters 19700-19702 (rotary table "
                "position) and 19703-19705 (intersection offset vector between the first and second "
                f"rotation axes of the table), in mm ({_FANUC_TCP}): correct the value set there by "
                "this offset, or correct the program with mtcomp compensate; on a Haas control the "
                "lines its G234 and G254 turn about are the machine rotary zero point (MRZP), "
                f"settings 255-257 (MRZP X, Y, Z offsets; {_HAAS}): there it is a correction of "
                "the setting that holds this line")
    return ("no parameter of this controller that takes it is known to mtcomp: correct the program "
            "with mtcomp compensate")


def volume_poses(machine, volume: dict, pose: np.ndarray) -> np.ndarray:
    """(N, n_axes) poses over ``volume`` (axis -> (lo, hi), mm or rad): each linear axis at its ends
    and at ``pose``'s position (a location error's effect is affine in a linear axis), each rotary
    axis swept in steps of at most :data:`SWEEP_DEG`; axes without a volume at ``pose``."""
    levels = []
    for i, ax in enumerate(machine.axes):
        if ax.name not in volume:
            levels.append(np.array([pose[i]]))
            continue
        lo, hi = volume[ax.name]
        if ax.is_rotary:
            n = int(math.ceil((hi - lo) / math.radians(SWEEP_DEG) - 1e-9)) + 1
            levels.append(np.linspace(lo, hi, max(n, 2)))
        else:
            levels.append(np.unique([lo, min(max(pose[i], lo), hi), hi]))
    grids = np.meshgrid(*levels, indexing="ij")
    return np.column_stack([g.ravel() for g in grids])


def _tip(fitted, p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """(N, 3) mm: the tool-tip deviation with parameter values ``p`` at poses q (N, n_axes), the
    model's reference context."""
    return deviation(fitted.model, fitted.clamp(q)[0], p, fitted.context(q.shape[0]))[:, :3]


def uncarried_tip(fitted, tables, carried: dict, p: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """(N, 3) mm: the tool-tip deviation the values ``p`` alone make at poses Q, from the tables'
    pose, less what the written tables carry of it (each carried translation column of each axis
    table, as the controller adds them; a LINEAR one as its least-squares line over the table)."""

    machine, pose = fitted.machine, tables.pose
    zero = _tip(fitted, p, pose[None, :])
    rest = _tip(fitted, p, Q) - zero
    for a, t in tables.tables.items():
        names = component_names(a)
        cols = [j for j in range(3) if carried.get((a, names[j])) in (FULL, MEAN, LINEAR)]
        if not cols:
            continue
        i = machine.index(a)
        lo, hi = t.data_region
        s, back = np.unique(np.clip(Q[:, i], lo, hi), return_inverse=True)
        q = np.tile(pose, (len(s) + len(t.positions), 1))
        q[:len(s), i] = s
        q[len(s):, i] = np.clip(t.positions, lo, hi)
        E = _tip(fitted, p, q) - zero
        for j in cols:
            e = E[:len(s), j]
            if carried[(a, names[j])] == LINEAR:
                k = ~t.held             # the table's points inside the region (beyond: held)
                c0, c1 = fit_line(t.positions[k], E[len(s):, j][k])
                e = c0 + c1 * s
            rest[:, j] -= e[back.ravel()]
    return rest


def uncarried_lines(fitted, tables, carried: dict, fmt: str) -> tuple[list, float | None]:
    """(lines, largest um): one line per single-valued error of the model (squareness, spindle
    tilt, rotary location and zero offset) whose tool-tip error the tables leave above
    :data:`FLOOR_UM` somewhere over the volume, largest first, with its value, standard error, that
    largest error and the pose it occurs at, and a mark [n] to the line that says who carries it
    (:func:`carrier`, one line per sentence after them); the largest tool-tip error of all of them
    together (None when there are none)."""
    from ..identification.report import location_values
    machine = fitted.machine
    Q = volume_poses(machine, tables.volume, tables.pose)
    found, together = [], np.zeros(len(fitted.params))
    for v in location_values(fitted):
        if v.status == "held":
            continue
        k = fitted.params.index(v.name)
        p = np.zeros(len(fitted.params))
        p[k] = fitted.params.values[k]
        rest = np.linalg.norm(uncarried_tip(fitted, tables, carried, p, Q), axis=1) * 1e3
        if not rest.max() >= FLOOR_UM:
            continue
        if v.status == "undetermined":
            # what the printed report and MODEL.json say of it: no standard error; its value is the
            # fit's choice, no correction to enter anywhere, so neither it nor its size is given
            found.append((-np.inf, f"{v.name} ({v.meaning}): not determined by the data (no standard "
                          "error: the data do not fix it alone)", UNDETERMINED))
            continue
        together[k] = p[k]
        at = Q[int(np.argmax(rest))]
        where = " ".join(f"{ax.name}{at[i] * (180 / math.pi if ax.is_rotary else 1):g}"
                         for i, ax in enumerate(machine.axes))
        sd = f" +- {v.sd:.2g} {v.unit}" if np.isfinite(v.sd) else \
            f" {v.unit} (no standard error: the model carries no covariance)"
        found.append((float(rest.max()), f"{v.name} ({v.meaning}) {v.value:+.2f}{sd}: up to "
                      f"{rest.max():.2f} um at the tool tip (at {where})", carrier(fmt, machine, v.name)))
    if not found:
        return [], None
    marks = list(dict.fromkeys(c for _, _, c in sorted(found, key=lambda f: -f[0])))
    lines = [f"{text} [{marks.index(c) + 1}]" for _, text, c in sorted(found, key=lambda f: -f[0])]
    lines += [f"[{i + 1}] {c}" for i, c in enumerate(marks)]
    if not together.any():
        return lines, None
    worst = np.linalg.norm(uncarried_tip(fitted, tables, carried, together, Q), axis=1).max() * 1e3
    return lines, float(worst)

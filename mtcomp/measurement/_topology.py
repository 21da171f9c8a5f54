"""Which order of a machine's rotary axes a ball-bar file fits, for the message that refuses a
reading no bar length explains (:meth:`mtcomp.measurement.readings.BallbarModel.check_readings`):
a machine file whose topology stacks the rotary axes the other way round (``ACFXYZ``, A carried by
C, for a trunnion whose A carries the C table, ``CAFXYZ``) puts the balls tens of millimetres from
where they are once both axes have turned, and the message then names the topology, not the bar."""
from __future__ import annotations

from dataclasses import replace
from itertools import permutations

import numpy as np

from ..errors import InputError
from ..kinematics import tool2wp


def ball_distances(machine, q, table_ball, tool_ball) -> np.ndarray:
    """(n,) mm: the nominal distance of the balls at axis positions ``q`` (n, na): the table ball
    (n, 3) fixed in the workpiece frame, the tool ball (n, 3) relative to the tool tip in the tool
    frame."""
    T = tool2wp(machine, q)
    tool = T[:, :3, 3] + np.einsum("nij,nj->ni", T[:, :3, :3], tool_ball)
    return np.linalg.norm(tool - table_ball, axis=1)


def fitting_topologies(machine, q, table_ball, tool_ball, length, tol_mm: float) -> list[str]:
    """The topologies that stack ``machine``'s rotary axes in another order (the letters of its
    topology permuted among the rotary axes' places) under which every row's balls lie within
    ``tol_mm`` of the bar's ``length`` (n,) mm apart."""
    from ..machine import parse_topology
    topo = machine.topology
    places = [k for k, c in enumerate(topo) if c in "ABC"]
    out = []
    for order in permutations([topo[k] for k in places]):
        letters = list(topo)
        for k, c in zip(places, order):
            letters[k] = c
        other = "".join(letters)
        if other == topo:
            continue
        wp, tool = parse_topology(other)
        candidate = replace(machine, topology=other, workpiece_chain=wp, tool_chain=tool)
        with np.errstate(invalid="ignore"):
            if np.all(np.abs(ball_distances(candidate, q, table_ball, tool_ball) - length) <= tol_mm):
                out.append(other)
    return out


def carried_text(topology: str) -> str:
    """'C carried by A' for CAFXYZ: which rotary axis rides on which (the one nearer F carries the
    ones further out on its side)."""
    f = topology.index("F")
    sides = (topology[:f][::-1], topology[f + 1:])
    said = []
    for side in sides:
        rot = [c for c in side if c in "ABC"]
        said += [f"{outer} carried by {inner}" for inner, outer in zip(rot, rot[1:])]
    return ", ".join(said)


def refuse_other_topology(bar, length, i: int, tol_mm: float) -> None:
    """InputError naming the topology when the ball-bar file's lengths ``length`` (n,) mm fit the
    machine's rotary axes stacked in another order (:func:`fitting_topologies`); ``bar``: the
    BallbarModel, row ``i`` the first whose length does not fit the machine file."""
    machine = bar.model.machine
    if sum(a.is_rotary for a in machine.axes) < 2:
        return
    d = bar.data
    fits = fitting_topologies(machine, bar.q, d.table_ball, d.tool_ball, length, tol_mm)
    if not fits:
        return
    here = float(ball_distances(machine, bar.q[i:i + 1], d.table_ball[i:i + 1],
                                d.tool_ball[i:i + 1])[0])
    raise InputError(f"length_mm {length[i]:g} is not the distance of the balls there with the "
                     f"machine file's topology {machine.topology} ({carried_text(machine.topology)}: "
                     f"{here:.4f} mm); with {fits[0]} ({carried_text(fits[0])}) the balls lie the "
                     "bar's length apart in every row: is the machine file's topology wrong?",
                     d.path, row=int(d.row[i]))

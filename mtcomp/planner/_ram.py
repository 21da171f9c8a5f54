"""The ram outside the region its data reached (docs/planner.md, *Blocks that get no correction*).

A block whose only axis outside the model's support is the ram (:func:`mtcomp.models.chain.ram_axis`:
a tool longer or shorter than the data's, a cut deeper than the data's) is corrected but for the
ram's own correction: across the tool its errors are those of the other carriages, which the data
measured, and the ram's straightness and tilts, which the model takes at their values at the edge
of the data; along the tool, the ram's own errors where it now stands were never measured. With
``--extrapolate`` every block is corrected whole, as before.

That holds only while the tool tip stays at the heights the data's tips reached: the other
carriages' angular errors move the tip across the tool by their angle times the tip's height, and
data taken at one height leave those angles open (held at zero, with no standard error to gate
them). A block whose tip is also beyond those heights is outside whole. The heights: the ram's
range less the data's tool lengths beyond the machine's (``info.tool_length_mm``; the ram's range
itself for a model that does not record them), a range that holds every tip the data had."""
from __future__ import annotations

import numpy as np

from ..models.chain import guideway_positions, ram_axis
from ._small import any_rows, any_rows_but


class RamRule:
    """The rule for one machine and one plan, and what it saw (the ranges the summary names)."""

    def __init__(self, machine, extrapolate: bool, support=None, tools=None):
        self.machine = machine
        self.extrapolate = bool(extrapolate)
        #: the ram's name, None without one
        self.ram = ram_axis(machine)
        self.col = None if self.ram is None else machine.index(self.ram)
        self.rotary = np.array([a.is_rotary for a in machine.axes], bool)
        #: (lo, hi) mm, the heights of the tool tips the data reached (module docstring), or None
        self.tips = None
        if self.col is not None and support is not None and np.isfinite(support[0][self.col]):
            lo, hi = float(support[0][self.col]), float(support[1][self.col])
            shortest, longest = (tools if tools else (machine.tool_length,) * 2)
            self.tips = (lo - max(longest - machine.tool_length, 0.0),
                         hi - min(shortest - machine.tool_length, 0.0))
        #: [lo, hi] mm: where the tools put the ram of the blocks so corrected (Summary.ram_asked)
        self.ram_asked = [np.inf, -np.inf]
        #: [shortest, longest] tool length (mm) of the blocks planned (Summary.tools_asked)
        self.tools_asked = [np.inf, -np.inf]

    def widen(self, outside, q, known) -> np.ndarray:
        """``outside`` ((n, na) bool) with every known axis of a block marked whose ram is outside
        and whose tool tip (``q``'s ram column, mm) is beyond the data's tips' heights: outside
        whole (module docstring)."""
        if self.tips is None or self.extrapolate or not outside[:, self.col].any():
            return outside
        z = q[:, self.col]
        beyond = outside[:, self.col] & ((z < self.tips[0] - 1e-6) | (z > self.tips[1] + 1e-6))
        if not beyond.any():
            return outside
        out = outside.copy()
        out[beyond] = known[beyond]
        return out

    def whole_outside(self, outside) -> np.ndarray:
        """(n,) bool: the blocks left uncorrected whole for the support (none with --extrapolate):
        an axis of ``outside`` ((n, na) bool) outside it other than the ram."""
        if self.extrapolate:
            return np.zeros(outside.shape[0], bool)
        if self.col is None:
            return any_rows(outside)
        return any_rows_but(outside, self.col)

    def pins(self, nodes) -> np.ndarray:
        """What the bounds pin to zero (:meth:`~._nodes.NodeSet.pins`), and the ram's own
        correction of a block that is corrected though its ram is outside the support."""
        pins = nodes.pins(self.rotary)
        if self.col is None or self.extrapolate:
            return pins
        ram_out = nodes.outside[:, self.col] & ~nodes.pinned
        if not ram_out.any():
            return pins
        pins = np.array(np.broadcast_to(pins[:, None] if pins.ndim == 1 else pins, nodes.q.shape))
        pins[:, self.col] |= ram_out
        return pins

    def unflag(self, flags, nodes) -> None:
        """No bound is named for the ram's own correction where this rule pinned it, nor for the
        rotary axes of a node whose tool-axis correction is not made (``NodeSet.axis_left``)."""
        if nodes.axis_left is not None and nodes.axis_left.any():
            flags[np.ix_(nodes.axis_left, self.rotary)] = False
        if self.col is not None and not self.extrapolate:
            flags[nodes.outside[:, self.col], self.col] = False

    def note(self, q, outside, pinned, tool_length=None, given=None) -> None:
        """Widen :attr:`tools_asked` by the tools (``tool_length`` (n,) mm, None or NaN the
        machine's) of the blocks whose every axis the program has given (``given`` (n,) bool, None:
        all; the others are not corrected: a block after a home move under G49, whose length is
        0, says nothing of the tools that cut) and :attr:`ram_asked` by the ram positions of the
        blocks corrected but for the ram (``outside`` (n, na), ``pinned`` (n,) of the blocks at
        ``q``)."""
        if self.col is None:
            return
        L0 = self.machine.tool_length
        tools = np.full(q.shape[0], L0) if tool_length is None else \
            np.nan_to_num(np.asarray(tool_length, dtype=float), nan=L0)
        counted = tools if given is None else tools[given]
        if counted.size:
            self.tools_asked[0] = min(self.tools_asked[0], float(counted.min()))
            self.tools_asked[1] = max(self.tools_asked[1], float(counted.max()))
        rows = outside[:, self.col] & ~pinned
        if self.extrapolate or not rows.any():
            return
        z = guideway_positions(self.machine, q[rows], tools[rows])[:, self.col]
        self.ram_asked[0] = min(self.ram_asked[0], float(z.min()))
        self.ram_asked[1] = max(self.ram_asked[1], float(z.max()))

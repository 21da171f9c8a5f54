"""The ram outside the region its data reached (docs/planner.md, *Blocks that get no correction*).

A block whose only axis outside the model's support is the ram (:func:`mtcomp.models.chain.ram_axis`:
a tool longer or shorter than the data's, a cut deeper than the data's) is corrected but for the
ram's own correction: across the tool its errors are those of the other carriages, which the data
measured, and the ram's straightness and tilts, which the model takes at their values at the edge
of the data; along the tool, the ram's own errors where it now stands were never measured. With
``--extrapolate`` every block is corrected whole, as before."""
from __future__ import annotations

import numpy as np

from ..models.chain import guideway_positions, ram_axis
from ._small import any_rows


class RamRule:
    """The rule for one machine and one plan, and what it saw (the ranges the summary names)."""

    def __init__(self, machine, extrapolate: bool):
        self.machine = machine
        self.extrapolate = bool(extrapolate)
        #: the ram's name, None without one
        self.ram = ram_axis(machine)
        self.col = None if self.ram is None else machine.index(self.ram)
        #: [lo, hi] mm: where the tools put the ram of the blocks so corrected (Summary.ram_asked)
        self.ram_asked = [np.inf, -np.inf]
        #: [shortest, longest] tool length (mm) of the blocks planned (Summary.tools_asked)
        self.tools_asked = [np.inf, -np.inf]

    def whole_outside(self, outside) -> np.ndarray:
        """(n,) bool: the blocks left uncorrected whole for the support (none with --extrapolate):
        an axis of ``outside`` ((n, na) bool) outside it other than the ram."""
        if self.extrapolate:
            return np.zeros(outside.shape[0], bool)
        if self.col is None:
            return any_rows(outside)
        return any_rows(np.delete(outside, self.col, axis=1))

    def pins(self, nodes) -> np.ndarray:
        """What the bounds pin to zero (:meth:`~._nodes.NodeSet.box_pins`), and the ram's own
        correction of a block that is corrected though its ram is outside the support."""
        pins = nodes.box_pins()
        if self.col is None or self.extrapolate:
            return pins
        ram_out = nodes.outside[:, self.col] & ~nodes.pinned
        if not ram_out.any():
            return pins
        pins = np.array(np.broadcast_to(pins[:, None] if pins.ndim == 1 else pins, nodes.q.shape))
        pins[:, self.col] |= ram_out
        return pins

    def unflag(self, flags, nodes) -> None:
        """No bound is named for the ram's own correction where this rule pinned it."""
        if self.col is not None and not self.extrapolate:
            flags[nodes.outside[:, self.col], self.col] = False

    def note(self, q, outside, pinned, tool_length=None) -> None:
        """Widen :attr:`tools_asked` by the blocks' tools (``tool_length`` (n,) mm, None or NaN the
        machine's) and :attr:`ram_asked` by the ram positions of the blocks corrected but for the
        ram (``outside`` (n, na), ``pinned`` (n,) of the blocks at ``q``)."""
        if self.col is None:
            return
        L0 = self.machine.tool_length
        tools = np.full(q.shape[0], L0) if tool_length is None else \
            np.nan_to_num(np.asarray(tool_length, dtype=float), nan=L0)
        if tools.size:
            self.tools_asked[0] = min(self.tools_asked[0], float(tools.min()))
            self.tools_asked[1] = max(self.tools_asked[1], float(tools.max()))
        rows = outside[:, self.col] & ~pinned
        if self.extrapolate or not rows.any():
            return
        z = guideway_positions(self.machine, q[rows], tools[rows])[:, self.col]
        self.ram_asked[0] = min(self.ram_asked[0], float(z.min()))
        self.ram_asked[1] = max(self.ram_asked[1], float(z.max()))

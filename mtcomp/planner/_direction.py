"""An axis the model's data read approaching from one side only (docs/planner.md, *One approach
direction*).

A model the same in both approach directions corrects a block with the error its data read. Where
every reading of an axis that states its approach direction states the same one (MODEL.json
``info["reversal"]``'s ``one_direction``: :func:`mtcomp.identification.reversal.data_reversal`) and
the model holds no backlash term on it, the error on the other side is that error plus the axis's
reversal, which nothing measured: a correction there carries it into the part. So a block whose
end that axis approaches from the other side, or from a side not known (the axis has not moved
since the start, a tool change or a home move: the machine stands wherever its last move left
it), is unsure: its standard error is infinite and the standard-error gate leaves it, and its
contour, uncorrected, as it does a block over the limit. Without a limit (``--max-correction-sd-um
0``) the rule does not act, as the gate does not.
"""
from __future__ import annotations

import numpy as np

from ._small import any_rows


def _one_direction(fitted) -> dict:
    """axis -> '+' or '-' as :func:`mtcomp.identification.reversal.one_direction_axes`; {} without a
    record of one direction, checked first so that compensate imports no fitting code for a model
    without one (tests/test_planner_speed.py)."""
    record = fitted.info.get("reversal") if isinstance(fitted.info, dict) else None
    if not isinstance(record, dict) or not any(isinstance(r, dict) and "one_direction" in r
                                               for r in record.values()):
        return {}
    from ..identification.reversal import one_direction_axes
    return one_direction_axes(fitted)


class DirectionRule:
    """The rule for one plan, and what it saw: per axis [blocks approaching from the other side,
    blocks whose approach is not known, first line] (:attr:`seen`), and the blocks it left
    uncorrected (:attr:`blocks`, the first one's line :attr:`line`)."""

    def __init__(self, planner):
        fitted = planner.problem.fitted
        names = list(planner.machine.axis_names)
        read = _one_direction(fitted) if planner.options.max_correction_sd_um else {}
        #: axis -> '+' or '-', the side the data read
        self.read = {a: s for a, s in read.items() if a in names}
        self._cols = [names.index(a) for a in self.read]
        self._sign = np.array([1 if s == "+" else -1 for s in self.read.values()], np.int8)
        record = fitted.info.get("reversal") if self.read else {}
        #: axis -> the files that read it
        self.files = {a: list(record[a].get("files", [])) for a in self.read}
        self.seen: dict = {a: [0, 0, 0] for a in self.read}
        #: the rule acts (an axis read from one side, a limit asked, a covariance to gate with):
        #: BLOCKS.csv has the column ``direction_not_read``
        self.active = bool(self.read) and planner.ev.has_uncertainty
        self.blocks = 0
        self.line = 0

    def unread(self, dirs) -> np.ndarray | None:
        """(n,) bool: the blocks with an axis of :attr:`read` approached (``dirs`` (n, na), +1,
        -1, 0 not known) from the side its data did not read or not known; None when none is."""
        if not self._cols or dirs is None:
            return None
        d = np.asarray(dirs)[:, self._cols]
        out = any_rows(d != self._sign[None, :])
        return out if out.any() else None

    def note(self, dirs, gated, line) -> None:
        """Count the blocks ``gated`` ((n,) bool or None: those the rule left uncorrected, not
        those left for another reason first), per axis and side, with their ``line`` (n,)."""
        if gated is None or not np.any(gated):
            return
        rows = np.flatnonzero(gated)
        d = np.asarray(dirs)[rows][:, self._cols]
        lines = np.asarray(line)[rows]
        self.line = self.line or int(lines[0])
        self.blocks += rows.size
        for k, a in enumerate(self.read):
            other, unknown = d[:, k] == -self._sign[k], d[:, k] == 0
            entry = self.seen[a]
            entry[0] += int(other.sum())
            entry[1] += int(unknown.sum())
            if not entry[2] and (other | unknown).any():
                entry[2] = int(lines[np.argmax(other | unknown)])

    def text(self, blocks, source_line) -> list[str]:
        """The summary's line on the blocks left uncorrected (``blocks(k)``: 'k blocks';
        ``source_line``: a planner line -> the user's file's line)."""
        if not self.blocks:
            return []
        parts = []
        for a, sign in self.read.items():
            other_side, unknown, first = self.seen[a]
            if not other_side + unknown:
                continue
            other = "-" if sign == "+" else "+"
            said = [f"{other_side} approach {a} in {other}"] if other_side else []
            said += [f"{unknown} with {a}'s approach not known (it had not moved since the start, "
                     "a tool change or a home move)"] if unknown else []
            parts.append(f"{' and '.join(said)}, where the model's data "
                         f"({', '.join(self.files[a]) or 'its files'}) read {a} approaching in "
                         f"{sign} only (first at line {source_line(first)})")
        return [f"{blocks(self.blocks)} not corrected for an approach direction the model's data "
                f"never read: {'; '.join(parts)}: the axis's reversal (backlash) there is not "
                "measured, and a correction read from the other side would carry it into the part "
                "(BLOCKS.csv uncertain 1, correction_sd_um blank; their contours are left whole); "
                "measure the axis approaching from both sides (ISO 230-2 runs are bidirectional), "
                "or let the program reach it from the side read"]


def unsure_rows(planner, datum, tool_length, dirs) -> tuple:
    """(datum_out, unread, either): the blocks whose part's datum lies outside the support
    (:meth:`._datum.DatumRule.outside`), those :meth:`DirectionRule.unread` finds, and the union
    of the two (each (n,) bool or None): their standard error is infinite (``Planner._sd_um``)."""
    datum_out = planner.datum.outside(datum, tool_length)
    unread = planner.direction.unread(dirs)
    either = unread if datum_out is None else datum_out if unread is None else datum_out | unread
    return datum_out, unread, either


def note_unsure(planner, datum, dirs, gated, datum_out, unread, line) -> np.ndarray | None:
    """Count the blocks ``gated`` (``Planner._sd_um``'s: made infinite by :func:`unsure_rows`) for
    their datum, and for an approach direction not read those not counted for their datum; return
    the latter ((n,) bool, None when there are none: BLOCKS.csv's ``direction_not_read``)."""
    if gated is None:
        return None
    planner.datum.note(datum, gated & datum_out if datum_out is not None else None, line)
    if unread is None:
        return None
    mine = gated & unread & (True if datum_out is None else ~datum_out)
    planner.direction.note(dirs, mine, line)
    return mine if mine.any() else None

"""What the corrected blocks of a program assume at zero, added up for compensate's summary
(:class:`AssumedTally`; the rules: :mod:`mtcomp.models.assumed`)."""
from __future__ import annotations

import numpy as np

from ..models.assumed import Assumed, held_words, never_words


class AssumedTally:
    """What the corrected blocks of a program assume at zero, added up over its results."""

    def __init__(self, assumed: Assumed):
        self.assumed = assumed
        self.mask = 0
        self.blocks = 0
        self.line = 0
        self.arm_mm = 0.0
        self.away_mm = np.zeros(len(assumed.never))

    def add(self, rows: np.ndarray, line: np.ndarray) -> None:
        """rows : (n, width) :meth:`Assumed.blocks` of the corrected blocks; line (n,) theirs."""
        mask = rows[:, 0].astype(np.int64)
        acts = mask != 0
        if not acts.any():
            return
        self.blocks += int(acts.sum())
        self.line = self.line or int(line[np.argmax(acts)])
        self.mask |= int(np.bitwise_or.reduce(mask[acts]))
        self.arm_mm = max(self.arm_mm, float(rows[acts, 1].max()))
        self.away_mm = np.maximum(self.away_mm, rows[acts, 2:].max(axis=0))

    def _items(self):
        """(never-moved axes acting: (name, held position, largest distance), held groups acting)."""
        a = self.assumed
        never = [(n, pos, float(self.away_mm[k])) for k, (n, _, pos) in enumerate(a.never)
                 if self.mask >> k & 1]
        groups = [g for b, g in enumerate(a.groups) if self.mask >> (len(a.never) + b) & 1]
        return never, groups

    def as_dict(self) -> dict | None:
        """SUMMARY.json ``assumed_zero`` (None when no corrected block assumes anything)."""
        if not self.blocks:
            return None
        never, groups = self._items()
        return {"blocks": self.blocks, "line": self.line,
                "never_moved": {n: {"held_mm": pos, "largest_distance_mm": d} for n, pos, d in never},
                "held_components": groups, "largest_arm_mm": self.arm_mm}

    def text(self, corrected: int) -> str:
        """The summary's note ('' when no corrected block assumes anything)."""
        if not self.blocks:
            return ""
        never, groups = self._items()
        said = []
        for n, pos, d in never:
            said.append(never_words(n, pos, f", the corrected blocks stand up to {d:.0f} mm from it"))
        if groups:
            arm = (f": their effect over arms up to {self.arm_mm:.0f} mm" if self.arm_mm >= 0.5
                   else ": their effect")
            said.append(f"{held_words(groups, self.assumed.angular, self.assumed.partly)} (held at zero where the data leave them open{arm} "
                        "is not in the standard errors)")
        return (f"note: the corrections assume zero for {' and for '.join(said)}; on "
                f"{self.blocks} of the {corrected} corrected blocks (first at line {self.line}; "
                "BLOCKS.csv column assumed_arm_mm): the figures after are the model's, on these "
                "assumptions, not a measurement; measure there (the axis moved, at the heights "
                "and offsets the program uses) to know them")

"""Whether a fit leaves each file as close as the file's own repeats allow (the classical lack-of-fit
test against pure error, e.g. Draper and Smith 1998, "Applied Regression Analysis", section 2.1).

A repeat group is the set of readings of one file at one set-up of the machine (same column,
positions, approach direction, feed, tool, optic: :func:`mtcomp.measurement.outliers.setup_keys`)
in different runs; the scatter about its mean is pure error, which no model of the machine removes.
What a fit leaves of the mean of each set-up, both approach directions together (a base model holds
no reversal, and balanced runs average it out), is its lack of fit. A model of one machine fitted to
that machine's files leaves those means about as far off as their repeats' scatter allows; files of
two machines fitted as one leave each other's differences, many times that. So does a model that
lacks an effect the machine has, which is `mtcomp diagnose`'s business."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..measurement.outliers import row_groups, setup_keys
from .result import error_unit

#: a file whose set-ups' means the fit leaves more than this many times as far off as their repeats'
#: scatter allows does not agree with the fit (rms over rms: 9 times the variance)
DISAGREE_RATIO = 3.0
#: degrees of freedom of repeats a file needs before its scatter is trusted as its noise
MIN_REPEAT_DOF = 5


@dataclass(frozen=True)
class LackOfFit:
    """One file's agreement with a fit, in one error unit. left : rms of the fit's residual means over
    the file's set-ups (both approach directions together). allowed : the rms those means would
    have from the repeats' scatter alone. ratio : left / allowed."""

    tag: str
    unit: str
    left: float
    allowed: float

    @property
    def ratio(self) -> float:
        return self.left / self.allowed if self.allowed > 0 else float("inf")


def lack_of_fit(result, datasets) -> list[LackOfFit]:
    """Per file (of ``result.files``, read from ``datasets`` in the same order) and error unit with at
    least :data:`MIN_REPEAT_DOF` degrees of freedom of repeats: its :class:`LackOfFit`. Files
    without repeat structure (ball bar, cmm ...) or repeats say nothing."""
    out = []
    for f, data in zip(result.files, datasets):
        keys = setup_keys(data)
        if keys is None or f.n_obs == 0:
            continue
        both = setup_keys(data, directions=False)
        units = np.array([error_unit(c) for c in f.columns])
        for unit in dict.fromkeys(units.tolist()):
            sel = (units == unit) & np.isfinite(f.residual)
            _, col = np.unique(f.columns[sel].astype(str), return_inverse=True)
            r, rows = f.residual[sel], f.rows[sel]
            g = row_groups(np.column_stack([keys[rows], col]))
            n = np.bincount(g)
            dof = int(np.sum(n[n >= 2] - 1))
            if dof < MIN_REPEAT_DOF:
                continue
            mean = np.bincount(g, weights=r) / n
            s2 = float(np.sum((r - mean[g]) ** 2)) / dof
            G = row_groups(np.column_stack([both[rows], col]))
            nG = np.bincount(G)
            left = np.sqrt(np.mean((np.bincount(G, weights=r) / nG) ** 2))
            out.append(LackOfFit(f.tag, unit, float(left), float(np.sqrt(s2 * np.mean(1.0 / nG)))))
    return out


def disagreement_note(result, datasets) -> str | None:
    """One line when a fit of two or more files leaves one of them more than :data:`DISAGREE_RATIO`
    times as far off as its repeats allow (:func:`lack_of_fit`), naming the worst; None otherwise
    (one file alone: what the model misses of it is diagnose's to say)."""
    if len(datasets) < 2:
        return None
    judged = lack_of_fit(result, datasets)
    worst = max(judged, key=lambda x: x.ratio, default=None)
    if worst is None or not worst.ratio > DISAGREE_RATIO:
        return None
    # the file that pulls the fit off may be one without repeats, which this test cannot judge
    unjudged = [f.tag for f in result.files if f.tag not in {x.tag for x in judged}]
    others = (f"; it cannot judge the files without repeats: "
              f"{', '.join(unjudged)}" if unjudged else "")
    return (f"the files do not agree: the fit of them all leaves {worst.tag}'s readings {worst.left:.3g} "
            f"{worst.unit} rms off at its set-ups (mean of its runs), where its repeats allow "
            f"{worst.allowed:.2g} {worst.unit} ({worst.ratio:.0f} times){others}: files of different "
            "machines fitted as one, or of one machine that changed between them? (mtcomp diagnose "
            "names an effect the model lacks)")

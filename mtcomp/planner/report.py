"""BLOCKS.csv and the summary that ``mtcomp compensate`` prints.

One row per output block (every G0/G1 line written for a motion, internal nodes included):

* ``line``: source line of the block; ``inserted``: 1 for an internal node the planner added;
  ``rapid``: 1 for a G0 move;
* corrected axis positions as written: ``x_mm, y_mm, z_mm`` and ``a_deg, b_deg, c_deg`` (present axes);
* corrections, written minus nominal: ``cx_um, cy_um, cz_um`` and ``ca_urad, cb_urad, cc_urad``;
* predicted tool-tip deviation (actual minus nominal, workpiece frame) before and after correction:
  ``ex_before_um, ey_before_um, ez_before_um, e_before_um`` (length), the same with ``_after``;
* 5-axis machines: tool-axis deviation (actual minus nominal unit vector, x/y/z components, in urad)
  ``ei_before_urad, ej_before_urad, ek_before_urad, e_axis_before_urad`` and ``_after``;
* ``active_bounds``: the bounds that kept the planner from removing the error at this block,
  separated by ``;``: ``cx_max`` / ``cx_min`` (max correction), ``travel_x_max`` / ``travel_x_min``
  (travel), ``step_x`` (max change from the block before), ``reversal_x``, ``arc_x``, ``crc_x``
  (the link bounds into the block, or into the block after it where they hold this one's
  correction),
  ``standing_c`` (a rotary axis the program does not move there keeps its correction); empty when
  none, and on a block left uncorrected for another reason (no bound acted there).
* ``unknown_axes``: the axes whose position the program has not given at this block (e.g. ``Z``
  after a tool change); such a block gets no correction and those axes are not written: their
  position and correction cells, and the block's predicted deviations, are blank.
* ``outside_support``: the axes outside the region the model's data reached; without
  ``--extrapolate`` such a block gets no correction.
* ``corrected``: 1 if the block is written with its correction (in full, or as far as the bounds in
  ``active_bounds`` let it); 0: not, or not on every axis that asked for one: an unknown axis,
  outside the support, uncertain (below), or a bound held an axis's whole correction (named in
  ``active_bounds``).
* ``correction_sd_um``: the standard error of the block's correction (um, from the model's
  covariance; blank where it was not evaluated: an unknown axis, outside the support, a model
  without a covariance, or no limit asked); ``uncertain``: 1 when the block was left uncorrected
  because that exceeds ``--max-correction-sd-um``, or because the block shares a contour (a run of
  feed moves cut one after the other) with such a block: a contour is corrected whole or not at all.
* ``direction_not_read`` (only when the model's data read an axis approaching from one side only):
  1 where the block was left uncorrected because that axis approaches it from the other side, or
  from a side not known (its standard error is then infinite: ``uncertain`` 1); its contour's other
  blocks have ``uncertain`` 1 and 0 here.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ._bounds import FLAG_KINDS, HOLDING, flag_name
from ._small import any_rows, any_rows_but, row_max, row_norm
from ._qp import NEVER_WORSE_TOL
from .problem import unsure_advice
from ._result import PlanResult
from ._assumed import AssumedTally
from ._partial import PartialTally

#: a block counts as made worse when its deviation along an axis grows by more than this (um): the
#: planner's never-worse rows allow NEVER_WORSE_TOL (half the output grid), rounding as much again
WORSE_TOL_UM = 2 * NEVER_WORSE_TOL
#: every kind of bound but the standing rule's (it has a line of its own in the summary)
_NOT_STANDING = np.array([kind != "standing" for kind in FLAG_KINDS])


def report_columns(axis_names, five_axis: bool, assumed: bool = False, unread: bool = False) -> list[str]:
    """BLOCKS.csv's columns (``assumed``: the model holds something at zero, :mod:`._assumed`,
    and a column says how far it acts on each block; ``unread``: the model's data read an axis
    from one side only, :mod:`._direction`, and the last column marks the blocks left for it)."""
    cols = ["line", "inserted", "rapid"]
    cols += [f"{a.lower()}_deg" if a in "ABC" else f"{a.lower()}_mm" for a in axis_names]
    cols += [f"c{a.lower()}_urad" if a in "ABC" else f"c{a.lower()}_um" for a in axis_names]
    for when in ("before", "after"):
        cols += [f"ex_{when}_um", f"ey_{when}_um", f"ez_{when}_um", f"e_{when}_um"]
        if five_axis:
            cols += [f"ei_{when}_urad", f"ej_{when}_urad", f"ek_{when}_urad", f"e_axis_{when}_urad"]
    cols += ["active_bounds", "unknown_axes", "outside_support", "corrected", "correction_sd_um",
             "uncertain"]
    return cols + (["assumed_arm_mm"] if assumed else []) + (["direction_not_read"] if unread else [])


def _assumed_arm_mm(result: PlanResult) -> np.ndarray | None:
    """(n,) BLOCKS.csv's ``assumed_arm_mm``: the largest distance over which what the model holds at
    zero acts on the block's correction (its arm, its distance from where the data held an axis
    they never moved), NaN (blank) where nothing acts; None when the model assumes nothing."""
    a = result.assumed
    if a is None:
        return None
    arm = a[:, 1:].max(axis=1) if a.shape[1] > 1 else np.zeros(a.shape[0])
    return np.where(a[:, 0] != 0, arm, np.nan)


def _numeric_columns(result: PlanResult, axis_names) -> tuple[list, list, np.ndarray]:
    """(the numeric columns of BLOCKS.csv before the text ones, each (n,), their printf formats,
    (n,) bool: the rows whose position is blank, an axis not known)."""
    rot = np.array([a in "ABC" for a in axis_names])
    pos = np.where(rot, np.degrees(result.corrected), result.corrected)
    # an axis the program has not positioned has no position to show, and a deviation predicted there
    # means nothing: blank cells (not a made-up 0)
    pos = np.where(result.unknown, np.nan, pos)
    blank = any_rows(result.unknown)
    corr = np.where(rot, result.correction * 1e6, result.correction * 1e3)
    corr = np.where(result.unknown, np.nan, corr)
    cols = [result.line.astype(np.int64), result.inserted.astype(int), result.rapid.astype(int)]
    fmts = ["%d", "%d", "%d"]
    for j in range(len(axis_names)):
        cols.append(pos[:, j])
        fmts.append("%.4f")
    for j in range(len(axis_names)):
        cols.append(corr[:, j])
        fmts.append("%.6f" if rot[j] else "%.4f")
    five = result.before_axis is not None
    for dev, dax in ((result.before, result.before_axis), (result.after, result.after_axis)):
        um = np.where(blank[:, None], np.nan, dev * 1e3)
        cols += [um[:, 0], um[:, 1], um[:, 2], row_norm(um)]
        fmts += ["%.4f"] * 4
        if five:
            ur = np.where(blank[:, None], np.nan, dax * 1e6)
            cols += [ur[:, 0], ur[:, 1], ur[:, 2], row_norm(ur)]
            fmts += ["%.4f"] * 4
    return cols, fmts, blank


def _unread(result: PlanResult, n: int) -> np.ndarray:
    """(n,) BLOCKS.csv's ``direction_not_read``: 1 where the block was left uncorrected because an
    axis its data read from one side only approaches it from the other or a side not known."""
    return np.zeros(n) if result.unread is None else result.unread.astype(float)


def report_rows(result: PlanResult, axis_names, max_correction_sd_um: float | None = None,
                unread: bool = False) -> list[str]:
    """CSV text lines (with newline) of one planned result (``max_correction_sd_um``: the limit
    the plan used, for the ``uncertain`` column; ``unread``: the ``direction_not_read`` column)."""
    cols, fmts, blank = _numeric_columns(result, axis_names)
    bounds = result.active_bounds(axis_names)
    unknown = _axis_letters(result.unknown, axis_names)
    outside = _axis_letters(result.outside, axis_names)
    sd = ["" if not np.isfinite(v) else f"{v:.4f}" for v in result.sd_um.tolist()]
    uncertain = _uncertain(result, max_correction_sd_um).astype(int).tolist()
    arm = _assumed_arm_mm(result)
    extra = [] if arm is None else [["" if not np.isfinite(v) else f"{v:.1f}" for v in arm.tolist()]]
    if unread:
        extra.append([f"{v:.0f}" for v in _unread(result, len(result)).tolist()])
    fmt = ",".join(fmts) + ",%s,%s,%s,%d,%s,%d" + ",%s" * len(extra) + "\n"
    lines = [fmt % row for row in zip(*[c.tolist() for c in cols], bounds, unknown, outside,
                                        result.corrected_blocks().astype(int).tolist(), sd, uncertain,
                                        *extra)]
    for i in np.flatnonzero(blank):
        lines[i] = ",".join("" if f == "nan" else f for f in lines[i][:-1].split(",")) + "\n"
    return lines


def report_table(result: PlanResult, axis_names, max_correction_sd_um: float | None = None,
                 unread: bool = False):
    """:func:`report_rows` as numbers, for a compiled formatter: (values (n, k), decimals (k,),
    blank (k,), special (n,) bool). Row i of BLOCKS.csv is column j of values written as
    ``"%.{decimals[j]}f"`` (an empty field where decimals[j] < 0, and for NaN where blank[j]),
    joined by commas, except for the ``special`` rows (an active bound, an axis not known or
    outside the model's region: text in the columns of letters), which :func:`report_rows`
    writes."""
    cols, fmts, unknown = _numeric_columns(result, axis_names)
    n = len(result)
    special = unknown | any_rows(result.flags) | any_rows(result.outside)
    empty = np.zeros(n)
    cols = cols + [empty, empty, empty, result.corrected_blocks().astype(float), result.sd_um,
                   _uncertain(result, max_correction_sd_um).astype(float)]
    decimals = [0 if f == "%d" else int(f[2]) for f in fmts] + [-1, -1, -1, 0, 4, 0]
    blank = np.zeros(len(cols), bool)
    blank[-2] = True
    arm = _assumed_arm_mm(result)
    if arm is not None:
        cols.append(arm)
        decimals.append(1)
        blank = np.append(blank, True)
    if unread:
        cols.append(_unread(result, n))
        decimals.append(0)
        blank = np.append(blank, False)
    return np.column_stack(cols), np.array(decimals), blank, special


def _uncertain(result: PlanResult, limit: float | None) -> np.ndarray:
    """(n,) bool: blocks left uncorrected because their correction's standard error exceeds limit,
    or that of another block of their contour (``PlanResult.gated``), or because their correction
    (and every one of their contour's) is not told from zero by it (``PlanResult.indistinct``)."""
    if not limit:
        return np.zeros(len(result), bool)
    with np.errstate(invalid="ignore"):
        out = (result.sd_um > limit) | result.gated
    return out if result.indistinct is None else out | result.indistinct


def _finite(pair) -> list | None:
    """[lo, hi] as floats for JSON, None when not known."""
    return None if pair is None or not np.all(np.isfinite(pair)) else [float(v) for v in pair]


def _axis_letters(mask, axis_names) -> list[str]:
    """Per row the letters of the axes set in mask (n, na) ('' when none)."""
    out = [""] * mask.shape[0]
    for i in np.flatnonzero(any_rows(mask)):
        out[i] = "".join(a for a, m in zip(axis_names, mask[i]) if m)
    return out


@dataclass
class Summary:
    """Totals over a planned program (what the command prints)."""

    axis_names: tuple
    blocks: int = 0
    inserted: int = 0
    bounded_blocks: int = 0
    flag_counts: dict = field(default_factory=dict)
    max_before_um: float = 0.0
    max_after_um: float = 0.0
    worst_line: int = 0
    sum_sq_before: float = 0.0
    sum_sq_after: float = 0.0
    max_axis_before_urad: float | None = None
    max_axis_after_urad: float | None = None
    not_converged: int = 0
    unknown_blocks: int = 0
    evaluated: int = 0
    outside_blocks: int = 0
    outside_axes: dict = field(default_factory=dict)
    first_outside_line: int = 0
    extrapolate: bool = False
    support_known: bool = True
    #: the ram (Z on XFYZ, CAFXYZ, CBFXYZ; None: none) and the range its data reached (mm, None:
    #: not stated); blocks corrected but for the ram's own correction, their ram outside that range
    #: (:meth:`Planner.pins`), the first one's line, and where their tools put the ram ([lo, hi], mm:
    #: the Planner's ``ram_asked``, shared)
    ram: str | None = None
    ram_measured: tuple | None = None
    ram_blocks: int = 0
    #: every block with an axis outside the region (corrected, in part or not at all)
    outside_any: int = 0
    ram_line: int = 0
    #: blocks left uncorrected (as uncertain) because their part's datum lies outside the region the
    #: model's data reached, and the first one's line (set by compensate after the run)
    datum_blocks: int = 0
    datum_line: int = 0
    #: the summary's lines on them (naming each datum, its axis and the data's range)
    datum_lines: list = field(default_factory=list)
    #: blocks left uncorrected (as uncertain) because an axis the model's data read approaching
    #: from one side only approaches them from the other or from a side not known (not counted
    #: in datum_blocks), and the summary's line on them (set by compensate: :mod:`._direction`)
    direction_blocks: int = 0
    direction_lines: list = field(default_factory=list)
    #: why some standard errors were infinite (the Evaluator's ``infinite_causes``, set by
    #: compensate); None: not said, taken as values the data did not determine
    infinite_causes: set | None = None
    ram_asked: list = field(default_factory=lambda: [np.inf, -np.inf])
    #: [shortest, longest] tool length (mm) of the model's data (None: not stated) and of the
    #: program's blocks (the Planner's ``tools_asked``, shared)
    tools_measured: list | None = None
    tools_asked: list = field(default_factory=lambda: [np.inf, -np.inf])
    #: the limit on a correction's standard error (um) the plan used, None: none
    max_correction_sd_um: float | None = None
    uncertain_blocks: int = 0
    #: of those, the blocks left uncorrected only because their contour has a block over the limit
    contour_blocks: int = 0
    #: of those, the blocks whose correction (every one of their contour's) is within two standard
    #: errors of zero (PlanResult.indistinct), and the first one's line
    indistinct_blocks: int = 0
    indistinct_line: int = 0
    max_sd_um: float = 0.0
    sd_undetermined: bool = False
    sd_seen: bool = False
    #: the model carries a covariance (without one no block's standard error is known)
    has_covariance: bool = True
    #: what the warning that no block was corrected adds on its likely cause (set by compensate:
    #: a work offset given without an axis the program positions, where blocks left the region)
    uncorrected_cause: str = ""
    #: the same figures over the corrected blocks only (``corrected`` = 1 in BLOCKS.csv)
    corrected_blocks: int = 0
    corrected_max_before_um: float = 0.0
    corrected_max_after_um: float = 0.0
    corrected_sum_sq_before: float = 0.0
    corrected_sum_sq_after: float = 0.0
    #: blocks whose deviation along some axis the correction made larger than uncorrected (by more
    #: than WORSE_TOL_UM): where the bounds forbade both correcting and leaving the block as it was
    worse_blocks: int = 0
    worse_max_um: float = 0.0
    worse_line: int = 0
    #: blocks the step bound moved by more than their own error asks for (the ramp in or out of a
    #: larger correction of a block after or before them), and the first one's line
    ramp_blocks: int = 0
    ramp_line: int = 0
    #: feed moves' blocks the step bound held to part of their own correction (a ramp in the cut),
    #: and the first one's line
    cut_ramp_blocks: int = 0
    cut_ramp_line: int = 0
    #: blocks written without the correction of an axis because a bound held all of it (not
    #: corrected), per bound name how often it held an axis so, and the first one's line
    held_blocks: int = 0
    held_counts: dict = field(default_factory=dict)
    held_line: int = 0
    #: of those, the blocks held only because an axis's direction was not known (it had not moved
    #: since the start, a tool change or a home move: PlanResult.undirected), and the first's line
    blind_blocks: int = 0
    blind_line: int = 0
    #: blocks (corrected or held, not pinned) with a rotary axis the standing rule kept at its
    #: correction (PlanResult.standing), the first one's line, the largest tool-axis deviation left
    #: in them (urad)
    standing_blocks: int = 0
    standing_line: int = 0
    standing_axis_urad: float = 0.0
    #: what the corrected blocks assume at zero (:class:`._assumed.AssumedTally`; None: the model
    #: assumes nothing)
    assumed: AssumedTally | None = None
    #: the blocks whose tool axis was not corrected (:mod:`._partial`)
    partial: PartialTally = field(default_factory=PartialTally)

    def _add_uncertain(self, r: PlanResult, uncertain: np.ndarray):
        """Count the blocks of ``r`` left uncorrected as unsure (``uncertain`` (n,) bool), apart
        those of a contour over the limit and those not told from zero, and the standard errors."""
        self.uncertain_blocks += int(uncertain.sum())
        self.contour_blocks += int(np.count_nonzero(uncertain & r.gated))
        if r.indistinct is not None and (uncertain & r.indistinct).any():
            quiet = uncertain & r.indistinct
            self.indistinct_blocks += int(quiet.sum())
            self.indistinct_line = self.indistinct_line or int(r.line[np.argmax(quiet)])
        finite = np.isfinite(r.sd_um)
        if finite.any():
            self.max_sd_um = max(self.max_sd_um, float(np.max(r.sd_um[finite])))
            self.sd_seen = True
        # an infinite standard error: the correction moves with values the data did not determine
        self.sd_undetermined |= bool(np.isposinf(r.sd_um).any())

    def add(self, r: PlanResult):
        n = len(r)
        if n == 0:
            return
        self.blocks += n
        self.inserted += int(np.count_nonzero(r.inserted))
        unknown = any_rows(r.unknown)
        self.unknown_blocks += int(unknown.sum())
        outside = any_rows(r.outside) & ~unknown
        self.outside_any += int(outside.sum())
        if self.ram is not None and not self.extrapolate:
            j = self.axis_names.index(self.ram)
            ram_only = outside & ~any_rows_but(r.outside, j)
            outside &= ~ram_only
            ram_only &= ~r.pinned
            if ram_only.any():
                self.ram_blocks += int(ram_only.sum())
                self.ram_line = self.ram_line or int(r.line[np.argmax(ram_only)])
        self._add_uncertain(r, _uncertain(r, self.max_correction_sd_um) & ~unknown
                            & ~(outside & ~self.extrapolate))
        if outside.any():
            self.outside_blocks += int(outside.sum())
            if not self.first_outside_line:
                self.first_outside_line = int(r.line[np.argmax(outside)])
            for j, a in enumerate(self.axis_names):
                k = int((r.outside[:, j] & ~unknown).sum())
                if k:
                    self.outside_axes[a] = self.outside_axes.get(a, 0) + k
        # predictions at unknown positions mean nothing: the statistics leave those blocks out
        if unknown.any():
            r = r.take(~unknown)
            if len(r) == 0:
                return
        self.evaluated += len(r)
        self.partial.add(r)
        self._add_standing(r)
        flagged = bool(r.flags.any())
        if flagged:
            # the standing rule has its own line (_add_standing): no bound hit of its own
            hit = r.flags & _NOT_STANDING if r.standing is not None else r.flags
            self.bounded_blocks += int(any_rows(hit).sum())
            self._count_flags(self.flag_counts, hit)
        eb = row_norm(r.before) * 1e3
        ea = row_norm(r.after) * 1e3
        self.max_before_um = max(self.max_before_um, float(eb.max()))
        i = int(np.argmax(ea))
        if ea[i] >= self.max_after_um:
            self.max_after_um = float(ea[i])
            self.worst_line = int(r.line[i])
        self.sum_sq_before += float(np.sum(eb ** 2))
        self.sum_sq_after += float(np.sum(ea ** 2))
        self._add_worse(r)
        if flagged:             # a ramp is a block the step bound held
            self._add_ramps(r)
            self._add_held(r)
        done = r.corrected_blocks()
        k = int(np.count_nonzero(done))
        if k:
            if k < len(r):           # every block corrected (the usual case): no copies
                eb, ea = eb[done], ea[done]
            self.corrected_blocks += k
            self.corrected_max_before_um = max(self.corrected_max_before_um, float(eb.max()))
            self.corrected_max_after_um = max(self.corrected_max_after_um, float(ea.max()))
            self.corrected_sum_sq_before += float(np.sum(eb ** 2))
            self.corrected_sum_sq_after += float(np.sum(ea ** 2))
            if self.assumed is not None and r.assumed is not None:
                self.assumed.add(r.assumed[done], r.line[done])
        if r.before_axis is not None:
            ab = float(np.sqrt(np.sum(r.before_axis ** 2, axis=1)).max()) * 1e6
            aa = float(np.sqrt(np.sum(r.after_axis ** 2, axis=1)).max()) * 1e6
            self.max_axis_before_urad = max(self.max_axis_before_urad or 0.0, ab)
            self.max_axis_after_urad = max(self.max_axis_after_urad or 0.0, aa)
        self.not_converged += len(r) - int(np.count_nonzero(r.converged))

    def _add_worse(self, r: PlanResult) -> None:
        grown = row_max(np.abs(r.after) - np.abs(r.before))
        grown *= 1e3
        worse = grown > WORSE_TOL_UM
        if worse.any():
            self.worse_blocks += int(worse.sum())
            i = int(np.argmax(grown))
            if grown[i] > self.worse_max_um:
                self.worse_max_um, self.worse_line = float(grown[i]), int(r.line[i])

    def _add_standing(self, r: PlanResult) -> None:
        """Count the blocks (not pinned) with a rotary axis the standing rule kept at its correction
        and the largest tool-axis deviation left in them."""
        if r.standing is None or r.after_axis is None:
            return
        st = any_rows(r.standing) & ~r.pinned
        if not st.any():
            return
        if not self.standing_blocks:
            self.standing_line = int(r.line[np.argmax(st)])
        self.standing_blocks += int(st.sum())
        left = float(row_norm(r.after_axis[st]).max()) * 1e6
        self.standing_axis_urad = max(self.standing_axis_urad, left)

    def _standing_text(self, blocks) -> list[str]:
        """The summary's line on the blocks with a rotary axis the program holds (3+2 machining)."""
        if not self.standing_blocks:
            return []
        return [f"{blocks(self.standing_blocks)} with a rotary axis the program does not move "
                f"there, outside tool centre point mode (3+2 or indexed machining; first at line "
                f"{self.standing_line}): that axis keeps the correction it had when it last moved "
                "and its word is not added or changed (it may be clamped); the tip is corrected "
                "with the linear axes alone, and the tool-axis deviation stays: up to "
                f"{self.standing_axis_urad:.3f} urad there (BLOCKS.csv e_axis_after_urad; "
                "standing_<axis> in active_bounds where the rule took a correction away)"]

    def _add_held(self, r: PlanResult) -> None:
        """Count the blocks with an axis whose whole correction a bound held (``PlanResult.held``),
        and per bound name the axes it held so."""
        held = any_rows(r.held)
        if not held.any():
            return
        if not self.held_blocks:
            self.held_line = int(r.line[np.argmax(held)])
        self.held_blocks += int(held.sum())
        self._count_flags(self.held_counts, r.flags & r.held[:, :, None] & HOLDING)
        if r.undirected is not None:
            # every axis held, held by the reversal rule for want of a direction
            blind = r.held & r.flags[..., FLAG_KINDS.index("reversal")] & r.undirected
            only = held & ~any_rows(r.held & ~blind)
            if only.any():
                if not self.blind_blocks:
                    self.blind_line = int(r.line[np.argmax(only)])
                self.blind_blocks += int(only.sum())

    def _count_flags(self, into: dict, flags: np.ndarray) -> None:
        """Add to ``into`` (bound name -> count) how often each bound is set in flags (n, na,
        len(FLAG_KINDS))."""
        counts = flags.sum(axis=0)
        for j, a in enumerate(self.axis_names):
            for k, kind in enumerate(FLAG_KINDS):
                if counts[j, k]:
                    name = flag_name(kind, a)
                    into[name] = into.get(name, 0) + int(counts[j, k])

    def _add_ramps(self, r: PlanResult) -> None:
        """Count the blocks whose step flag is set and whose linear correction is longer than their
        own tip deviation by more than WORSE_TOL_UM: they carry part of a neighbour's correction."""
        step = r.flags[..., FLAG_KINDS.index("step")]
        if not step.any():
            return
        linear = [j for j, a in enumerate(self.axis_names) if a not in "ABC"]
        longer = row_norm(r.correction[:, linear]) * 1e3 > row_norm(r.before) * 1e3 + WORSE_TOL_UM
        ramp = any_rows(step) & longer
        if ramp.any():
            if not self.ramp_blocks:
                self.ramp_line = int(r.line[np.argmax(ramp)])
            self.ramp_blocks += int(ramp.sum())
        cut = any_rows(step) & ~longer & ~r.rapid & ~r.pinned
        if cut.any():
            if not self.cut_ramp_blocks:
                self.cut_ramp_line = int(r.line[np.argmax(cut)])
            self.cut_ramp_blocks += int(cut.sum())

    @property
    def rms_before_um(self) -> float:
        """Root mean square of the evaluated blocks' predicted deviation before correction (um)."""
        return float(np.sqrt(self.sum_sq_before / max(self.evaluated, 1)))

    @property
    def rms_after_um(self) -> float:
        """Root mean square of the evaluated blocks' predicted deviation after correction (um)."""
        return float(np.sqrt(self.sum_sq_after / max(self.evaluated, 1)))

    def as_dict(self) -> dict:
        """The figures as the keys of ``mtcomp compensate --json`` (um; counts of blocks)."""
        nc = max(self.corrected_blocks, 1)
        out = {"blocks": self.blocks, "internal_nodes": self.inserted,
               "evaluated_blocks": self.evaluated,
               "max_before_um": self.max_before_um,
               "rms_before_um": self.rms_before_um,
               "max_after_um": self.max_after_um,
               "rms_after_um": self.rms_after_um,
               "worst_line": self.worst_line,
               "corrected": {"blocks": self.corrected_blocks,
                             "max_before_um": self.corrected_max_before_um,
                             "rms_before_um": float(np.sqrt(self.corrected_sum_sq_before / nc)),
                             "max_after_um": self.corrected_max_after_um,
                             "rms_after_um": float(np.sqrt(self.corrected_sum_sq_after / nc))},
               "uncorrected": {"unknown_axes": self.unknown_blocks,
                               "outside_support": 0 if self.extrapolate else self.outside_blocks,
                               "uncertain": self.uncertain_blocks - self.contour_blocks
                                            - self.indistinct_blocks - self.direction_blocks,
                               "direction_not_read": self.direction_blocks,
                               "uncertain_contour": self.contour_blocks,
                               "indistinct_from_zero": self.indistinct_blocks,
                               "held_by_bounds": self.held_blocks,
                               "held_direction_unknown": self.blind_blocks},
               "ram_outside_support": {"blocks": self.ram_blocks, "line": self.ram_line,
                                       "measured_mm": _finite(self.ram_measured),
                                       "asked_mm": _finite(self.ram_asked if self.ram_blocks else None)},
               "datum_outside_support": {"blocks": self.datum_blocks, "line": self.datum_line},
               "max_correction_sd_um": self.max_correction_sd_um,
               # the largest finite one (strict JSON has no Infinity); whether any correction
               # moved with values the data did not determine (an infinite one)
               "largest_correction_sd_um": (self.max_sd_um if self.max_correction_sd_um
                                            and self.sd_seen else None),
               "correction_sd_undetermined": self.sd_undetermined if self.infinite_causes is None
                                             else bool(self.infinite_causes or self.datum_blocks),
               "outside_support_blocks": self.outside_any,
               "bounded_blocks": self.bounded_blocks,
               "active_bounds": dict(sorted(self.flag_counts.items())),
               "not_converged": self.not_converged,
               "worse_than_uncorrected": {"blocks": self.worse_blocks,
                                          "largest_um": self.worse_max_um,
                                          "line": self.worse_line},
               "ramped_blocks": {"blocks": self.ramp_blocks, "line": self.ramp_line},
               "cut_ramp_blocks": {"blocks": self.cut_ramp_blocks, "line": self.cut_ramp_line},
               "standing_rotary": {"blocks": self.standing_blocks, "line": self.standing_line,
                                   "max_axis_after_urad": self.standing_axis_urad}}
        if self.max_axis_before_urad is not None:
            out["max_axis_before_urad"] = self.max_axis_before_urad
            out["max_axis_after_urad"] = (self.max_axis_after_urad if not self.partial.axis_blocks
                                          else self.partial.axis_after_urad)
        out.update(self.partial.as_dict())
        assumed = self.assumed.as_dict() if self.assumed is not None else None
        if assumed is not None:
            out["assumed_zero"] = assumed
        return out

    @property
    def _on_assumptions(self) -> str:
        """What the figures after rest on, when a held component acts on a corrected block."""
        return (" (the model's, assuming zero where the note below says)"
                if self.assumed is not None and self.assumed.blocks else "")

    def text(self) -> str:
        def blocks(k: int) -> str:
            return f"{k} block" if k == 1 else f"{k} blocks"
        lines = [f"{blocks(self.blocks)} planned ({self.inserted} internal nodes inserted)"]
        if self.evaluated:
            lines += [f"predicted tool-tip deviation before: max {self.max_before_um:.3f} um, "
                      f"rms {self.rms_before_um:.3f} um",
                      f"predicted tool-tip deviation after:  max {self.max_after_um:.3f} um "
                      f"(line {self.worst_line}), rms {self.rms_after_um:.3f} um"
                      + self._on_assumptions]
        else:       # no figure rather than a 0.000 that reads as a perfect machine
            lines.append("predicted tool-tip deviation: not evaluated (no block has every axis "
                         "position given)")
        # blocks with an unknown axis are not in the figures; those outside the region are
        included = self.evaluated - self.corrected_blocks
        if included > 0:
            lines.append(f"(these figures include the {blocks(included)} left uncorrected, "
                         "listed below)")
            c = self.as_dict()["corrected"]
            lines.append(f"over the {blocks(c['blocks'])} corrected: before max "
                         f"{c['max_before_um']:.3f} um, rms {c['rms_before_um']:.3f} um; after max "
                         f"{c['max_after_um']:.3f} um, rms {c['rms_after_um']:.3f} um"
                         + self._on_assumptions)
        if self.max_axis_before_urad is not None:
            lines.append(self.partial.axis_text(self.max_axis_before_urad, self.max_axis_after_urad))
        if self.bounded_blocks:
            detail = ", ".join(f"{k} {v}" for k, v in sorted(self.flag_counts.items()))
            lines.append(f"{blocks(self.bounded_blocks)} hit a bound ({detail}); worst remaining "
                         f"predicted deviation {self.max_after_um:.3f} um at line {self.worst_line}")
        else:
            lines.append("0 blocks hit a bound")
        lines += self._standing_text(blocks)
        if self.ramp_blocks:
            lines.append(f"{blocks(self.ramp_blocks)} corrected by more than their own error "
                         f"(first at line {self.ramp_line}): the step bound (--max-step-um, "
                         "--max-step-urad) ramps a larger correction in over the blocks before it "
                         "and out over those after, the other axes holding those blocks' own tip "
                         "(BLOCKS.csv: step_<axis> in active_bounds)")
        if self.cut_ramp_blocks:
            lines.append(f"{blocks(self.cut_ramp_blocks)} in the cut carry a ramp (first at line "
                         f"{self.cut_ramp_line}): feed moves the step bound (--max-step-um, "
                         "--max-step-urad) held to part of their correction, a step from the block "
                         "before, the rest of their error kept (BLOCKS.csv: rapid 0 and step_<axis> "
                         "in active_bounds); a straight feed move after a block left uncorrected "
                         "gets the nodes its ramp needs, from where it enters the region the data "
                         "reached, so that the ramp ends where the move ends")
        if self.worse_blocks:
            lines.append(f"warning: {blocks(self.worse_blocks)} left worse than uncorrected along an "
                         f"axis (up to {self.worse_max_um:.3f} um more, at line {self.worse_line}): "
                         "the bounds forbade both following the error and leaving the block as it "
                         "was (a larger --max-step-um lets the correction follow)")
        if self.not_converged:
            lines.append(f"warning: {blocks(self.not_converged)} did not converge within the "
                         "iteration limit")
        lines += self._not_corrected(blocks)
        if self.max_correction_sd_um and not self.has_covariance:
            lines.append("note: the model carries no covariance (identify, diagnose and a thermal "
                         "diagnosis write one; an older model file may not): no block's correction "
                         "could be checked against --max-correction-sd-um")
        if self.assumed is not None and self.assumed.blocks:
            lines.append(self.assumed.text(self.corrected_blocks))
        if not self.support_known:
            lines.append("note: the model does not state the region its data reached; every "
                         "block was corrected as if inside it")
        if self.blocks and not self.corrected_blocks:
            lines.append("warning: no block was corrected (for the reasons above): the output "
                         "carries no correction" + self.uncorrected_cause)
        return "\n".join(lines)

    def _ram_text(self, blocks) -> str:
        """The line on the blocks corrected but for the ram's own correction."""
        others = ", ".join(a for a in self.axis_names if a != self.ram)
        lo, hi = self.ram_measured or (np.nan, np.nan)
        return (f"{blocks(self.ram_blocks)} with the ram ({self.ram}) outside the {lo:g} .. {hi:g} mm "
                f"its data reached (at {self.ram_asked[0]:g} .. {self.ram_asked[1]:g} mm, where their "
                f"tools and depths put it; first at line {self.ram_line}): {others} corrected, the "
                f"ram's own errors taken at their values at the edge of the data (a continuation no "
                f"standard error sizes); {self.ram} not corrected (pass --extrapolate to correct it "
                f"too)")

    def _tools_text(self) -> str:
        """A note when the program's tools are longer or shorter than the model's data's."""
        if self.ram is None or not self.tools_measured or not np.all(np.isfinite(self.tools_asked)):
            return ""
        lo, hi = self.tools_measured
        if lo - 1e-6 <= self.tools_asked[0] and self.tools_asked[1] <= hi + 1e-6:
            return ""
        return (f"note: the program's tools are {self.tools_asked[0]:g} .. {self.tools_asked[1]:g} mm "
                f"long, the model's data were taken with {lo:g} .. {hi:g} mm: the X Y offset of a "
                f"tool's tip from the probe's, which grows with its length through the ram's "
                f"tilts, is carried beyond the lengths the data had (the ram's tilt profiles held "
                f"at the data's edge), further than its standard error says")

    def _not_corrected(self, blocks) -> list[str]:
        """The summary's lines on the blocks left uncorrected, by why (``blocks(k)``: 'k blocks')."""
        out = []
        if self.unknown_blocks:
            out.append(f"{blocks(self.unknown_blocks)} not corrected: an axis position the program "
                       "had not given (at the start, after a home move, tool change or offset "
                       "change); those axes are not written"
                       + ("; an axis the program never names (a 3-axis program on a 5-axis "
                          "machine) is told by --start-position, e.g. A=0,C=0"
                          if self.unknown_blocks == self.blocks else ""))
        if self.outside_blocks:
            axes = ", ".join(f"{a} {k}" for a, k in self.outside_axes.items())
            what = ("corrected anyway (--extrapolate)" if self.extrapolate
                    else "not corrected (pass --extrapolate to correct them)")
            out.append(f"{blocks(self.outside_blocks)} outside the region the model's data reached "
                       f"({axes}; first at line {self.first_outside_line}): {what}")
        if self.ram_blocks:
            out.append(self._ram_text(blocks))
        tools = self._tools_text()
        if tools:
            out.append(tools)
        # the blocks unsure for their datum or an approach direction alone have their own lines
        # (compensate's datum notes, :mod:`._direction`)
        out += self.datum_lines + self.direction_lines
        named = self.datum_blocks + self.direction_blocks + self.indistinct_blocks
        if self.uncertain_blocks > named:
            out.append(self._unsure_text(blocks, self.uncertain_blocks - self.contour_blocks - named))
        if self.indistinct_blocks:
            out.append(f"{blocks(self.indistinct_blocks)} not corrected: the correction is within "
                       "two of its standard errors of zero in every component, so the data do not "
                       "tell it from none (a contour only when that holds on every one of its "
                       f"blocks; first at line {self.indistinct_line}; BLOCKS.csv uncertain 1, "
                       "column correction_sd_um): measure more, or more often, to tell it")
        if self.held_blocks:
            out.append(self._held_text(blocks(self.held_blocks)))
        out += self.partial.lines()
        return out

    def _unsure_text(self, blocks, own: int) -> str:
        """The line on the blocks left uncorrected for their standard error (``own`` of them over
        the limit, not said elsewhere) and those of the same contours."""
        causes = ({"undetermined"} if self.sd_undetermined else set()) \
            if self.infinite_causes is None else self.infinite_causes
        shared = (f"{blocks(self.contour_blocks)} of the same contours (a run of feed moves cut one "
                  "after the other is corrected whole or not at all: corrected in part, it would "
                  "step where the correction stops)" if self.contour_blocks else "")
        if own <= 0:        # the contours of blocks said above
            return f"{shared}: not corrected either"
        return (f"{blocks(own)} not corrected: the model is unsure there "
                f"(a correction's standard error above {self.max_correction_sd_um:g} um, "
                + "; ".join(([f"largest finite {self.max_sd_um:.3f} um"] if self.sd_seen else [])
                            + (["some not determined by the model's data at all"] if causes else []))
                + "; BLOCKS.csv column correction_sd_um)"
                + (f", and {shared}" if shared else "") + "; "
                + unsure_advice(float("inf") if causes else self.max_sd_um,
                                self.max_correction_sd_um, causes=causes))

    def _held_text(self, counted: str) -> str:
        """The summary's line on the blocks with an axis whose whole correction a bound held."""
        detail = ", ".join(f"{k} {v}" for k, v in sorted(self.held_counts.items()))
        why = ""
        if any(k.startswith("reversal_") for k in self.held_counts):
            why = ("; reversal: a correction there would move the axis against the direction it "
                   "came to the block from, or, where that direction is not known (the first move "
                   "or hole after a tool change or a home move), at all: the machine's play "
                   "(backlash) would turn that move into an error of its own")
        if self.blind_blocks:
            why += (f"; {self.blind_blocks} of them only because the axis had not moved since the "
                    "start, a tool change or a home move (its direction not known; first at line "
                    f"{self.blind_line}, such as a G43 line's approach of Z): a move of the "
                    "program's own to that position first gives the correction a direction")
        return (f"{counted} not corrected on every axis: a bound held the whole correction of an "
                f"axis ({detail}; first at line {self.held_line}; BLOCKS.csv active_bounds){why}")

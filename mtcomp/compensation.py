"""One compensation of one program with one model: what ``mtcomp compensate`` and ``mtcomp study`` run.

:func:`compensate_program` streams the program twice (once planned, once rewritten by
:func:`mtcomp.toolpaths.write_corrected`), so memory stays flat for any length, and returns a
:class:`CompensationRun`: the planner's :class:`~mtcomp.planner.Summary`, what the writer did with
drilling cycles, the notes to tell the user and, when asked, the same figures under other models
(:class:`Judge`: a later re-measurement, or a draw of the model from its covariance).

The settings (:class:`CompensationSettings`) are the command line's flags in file units (um, urad,
degC); the planner's problem and options are built from them here, once.
"""
from __future__ import annotations

import contextlib
import math
import re
import time
from dataclasses import dataclass, field, replace

import numpy as np

from .errors import InputError
from .machine import TravelError
from .io.atomic import atomic_write
from .planner import (CompensationProblem, Planner, PlannerOptions, Summary, output_grid,
                      report_columns, report_rows)
from .planner.report import report_table
from .planner._assumed import AssumedTally
from .planner._partial import PartialTally
from .planner._bounds import FLAG_KINDS
from .planner._parallel import read_ahead
from .planner._small import any_rows, row_norm
from .planner.problem import DEFAULT_MAX_CORRECTION_SD_UM
from .toolpaths.words import WORK_SYSTEMS, frame_dwo, frame_local, frame_tcp
from .toolpaths import iter_segment_chunks, write_corrected
from .toolpaths._fast import format_table, g_codes
from .toolpaths.source import open_program
from ._compensation_notes import _run_notes, datum_notes

_DIGITS = b"0123456789."
#: kinds of bound -> their columns in PlanResult.flags
_BOUND_KINDS = {kind: [FLAG_KINDS.index(f) for f in flags] for kind, flags in
                (("max_correction", ("max", "min")), ("travel", ("travel_max", "travel_min")),
                 ("max_step", ("step",)))}


@dataclass(frozen=True)
class CompensationSettings:
    """How to compensate (``mtcomp compensate``'s flags; file units).

    method : 'qp', 'pinv' or 'newton' (:class:`~mtcomp.planner.PlannerOptions`).
    max_correction_um, max_correction_urad, max_step_um, max_step_urad : bounds for every linear /
        rotary axis (um, urad); None: the machine file's [compensation] table.
    axis_max_correction, axis_max_step : axis name -> bound of that axis alone (um for linear axes,
        urad for rotary ones), over the ones above.
    orientation_weight : um of tip deviation that weigh as much as 1 urad of tool-axis deviation.
    subdivide_tol_um : internal nodes where the corrected path would miss a midpoint by more (0: none).
    ramp_nodes : a straight feed move after a block left uncorrected gets the nodes of the step
        bound's ramp (PlannerOptions.ramp_nodes; set off where the program's writer cannot write
        them: a Heidenhain program, cutter radius compensation).
    chord_tol_um : chord tolerance of arcs written as lines.
    temperatures : sensor name -> degC while the program runs; spindle_rpm : warm spindle speed.
    probed_temperatures, probed_spindle_rpm : the same when the part's datum was probed (empty,
        None: at the thermal record's first reading, thermal.context.record_reference).
    probe_tool_length : mm, the length of the probe the part's datum was probed with in X and Y
        (None: the machine file's tool length): FittedModel.probe_tool_length.
    extrapolate : correct blocks outside the region the model's data reached too, and at
        temperatures and spindle speeds outside the range of the model's thermal record (else refused).
    max_correction_sd_um : the limit on a correction's standard error (um); None: the default; 0: none.
    units : 'mm' or 'inch' for a program without G20/G21 (None: the machine file's, else mm).
    start_position : axis name -> position (mm, deg) of axes known before the program starts.
    threads : planner threads (0: automatic; a study's worker uses 1).
    dialect : the controller's dialect ('linuxcnc', 'fanuc', 'haas', 'grbl', 'heidenhain', 'generic'; None:
        detected from the program), see :mod:`mtcomp.toolpaths.dialect`.
    """

    method: str = "qp"
    max_correction_um: float | None = None
    max_correction_urad: float | None = None
    max_step_um: float | None = None
    max_step_urad: float | None = None
    axis_max_correction: dict = field(default_factory=dict)
    axis_max_step: dict = field(default_factory=dict)
    orientation_weight: float = 1.0
    subdivide_tol_um: float = 0.5
    ramp_nodes: bool = True
    chord_tol_um: float = 1.0
    temperatures: dict = field(default_factory=dict)
    spindle_rpm: float | None = None
    probed_temperatures: dict = field(default_factory=dict)
    probed_spindle_rpm: float | None = None
    probe_tool_length: float | None = None
    extrapolate: bool = False
    max_correction_sd_um: float | None = None
    units: str | None = None
    start_position: dict = field(default_factory=dict)
    threads: int = 0
    dialect: str | None = None

    def sd_limit(self) -> float | None:
        """The limit on a correction's standard error the plan uses (um), None for none."""
        v = DEFAULT_MAX_CORRECTION_SD_UM if self.max_correction_sd_um is None else self.max_correction_sd_um
        return v or None

    def check(self, where: str = "") -> None:
        """InputError (one line, prefixed by ``where``) for a bound or tolerance that is not a
        positive number."""
        def positive(v, name, allow_zero=False):
            if v is None:
                return
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) \
                    or v < 0 or (v == 0 and not allow_zero):
                raise InputError(f"{where}{name} must be a positive number, got {v!r}")
        for name in ("max_correction_um", "max_step_um", "max_step_urad", "chord_tol_um",
                     "orientation_weight"):
            positive(getattr(self, name), name)
        positive(self.max_correction_urad, "max_correction_urad", allow_zero=True)
        positive(self.subdivide_tol_um, "subdivide_tol_um", allow_zero=True)
        positive(self.max_correction_sd_um, "max_correction_sd_um", allow_zero=True)
        positive(self.probe_tool_length, "probe_tool_length", allow_zero=True)
        for table in ("axis_max_correction", "axis_max_step"):
            for axis, v in getattr(self, table).items():
                positive(v, f"{table} {axis}")


def start_position(machine, values: dict) -> tuple[np.ndarray, np.ndarray]:
    """axis name -> position (mm, deg) -> (initial position (na,) mm/rad, known mask (na,))."""
    pos = np.zeros(machine.n_axes)
    known = np.zeros(machine.n_axes, bool)
    for a, v in values.items():
        j = machine.index(a)
        pos[j] = math.radians(v) if machine.axes[j].is_rotary else v
        known[j] = True
    return pos, known


def parse_start_position(machine, flags) -> dict:
    """``--start-position A=0,C=0`` (repeatable) -> {axis: value (mm, deg)}; InputError otherwise."""
    out = {}
    for flag in flags:
        for item in filter(None, (t.strip() for t in flag.split(","))):
            m = re.fullmatch(r"([A-Za-z])\s*=\s*([+-]?(?:\d+\.?\d*|\.\d+))", item)
            if not m:
                raise InputError(f"--start-position {flag}: {item!r} is not an axis value such as "
                                 "A=0")
            a = m.group(1).upper()
            if a not in machine.axis_names:
                raise InputError(f"--start-position {flag}: machine {machine.name} has no {a} axis")
            out[a] = float(m.group(2))
    return out


def build_problem(fitted, settings: CompensationSettings, inch: bool) -> CompensationProblem:
    """The planner's problem: the machine file's bounds overridden by the settings (per axis last)."""
    machine = fitted.machine
    problem = CompensationProblem.from_machine(
        fitted, settings.max_correction_um, settings.max_correction_urad, settings.max_step_um,
        settings.max_step_urad, grid=output_grid(machine, inch),
        orientation_weight=settings.orientation_weight)
    if not settings.axis_max_correction and not settings.axis_max_step:
        return problem
    corr, step = problem.max_correction.copy(), problem.max_step.copy()
    for table, out in ((settings.axis_max_correction, corr), (settings.axis_max_step, step)):
        for a, v in table.items():
            if a not in machine.axis_names:
                raise InputError(f"machine {machine.name} has no {a} axis (its axes: "
                                 f"{', '.join(machine.axis_names)})")
            j = machine.index(a)
            held = machine.axes[j].is_rotary and a in (fitted.held or {}) and out is corr
            out[j] = 0.0 if held else v * (1e-6 if machine.axes[j].is_rotary else 1e-3)
    return replace(problem, max_correction=corr, max_step=step)


def uses_inches(path, block: int = 1 << 22) -> bool:
    """True if the program contains a G20 word anywhere (comments included: a cautious guess that
    only sets the rounding grid of the output). Reads the file in blocks: memory stays flat."""
    return bool(words_in(path, (b"20",), block))


def words_in(path, codes, block: int = 1 << 22) -> set:
    """The G ``codes`` (bytes, e.g. b"20") the file holds as :func:`_has_g` reads them, in one pass
    of blocks that stops once every code is found. InputError when the file cannot be read."""
    try:
        f = open(path, "rb")
    except FileNotFoundError:
        raise InputError("no such file", path) from None
    except OSError as exc:
        raise InputError(f"cannot open: {exc.strerror}", path) from None
    found = set()
    # one buffer for every block (new ones cost more than the scan): the last 16 bytes of a block
    # again at its front, so that a word cut by the block's end is read with the next block
    text = bytearray(16 + block)
    view = memoryview(text)
    kept = 0
    with f:
        while len(found) < len(codes):
            got = f.readinto(view[kept:kept + block])
            n = kept + got
            if not got:
                text[n] = ord(" ")
                found |= _g_codes(text, [c for c in codes if c not in found], n + 1)
                break
            found |= _g_codes(text, [c for c in codes if c not in found], n - 8)
            kept = min(16, n)
            text[:kept] = text[n - kept:n]
    return found


def _has_g(text: bytes, code: bytes = b"20") -> bool:
    """True if ``text`` holds G20, G020 or G0020 (G or g; ``code`` instead of 20) not followed by a
    digit or '.' (the end of the text counts as not followed)."""
    return bool(_g_codes(text, [code]))


def _g_codes(text: bytes, codes, n: int | None = None) -> set:
    """The ``codes`` (two-digit bytes) that :func:`_has_g` finds in ``text`` (its first ``n`` bytes,
    None: all), from one pass over the text for its G letters: the few bytes after each are
    compared; in the G-code reader's compiled code (:func:`.toolpaths._fast.g_codes`) where it is
    built, else vectorised over the letters."""
    n = len(text) if n is None else n
    found = g_codes(text, n, codes) if codes else set()
    if found is not None:
        return found
    a = np.frombuffer(text, np.uint8, count=n)
    g = np.flatnonzero((a | 0x20) == ord("g"))        # G or g
    if g.size == 0 or not codes:
        return set()
    n = a.size
    # the 5 bytes after each G, a space past the end of the text
    after = []
    for k in range(1, 6):
        at = g + k
        after.append(np.where(at < n, a[np.minimum(at, n - 1)], ord(" ")))
    ends_ok = np.ones(256, bool)
    ends_ok[np.frombuffer(_DIGITS, np.uint8)] = False
    found = set()
    for code in codes:
        for zeros in range(3):
            word = b"0" * zeros + code
            ok = ends_ok[after[len(word)]]
            for k, ch in enumerate(word):
                ok &= after[k] == ch
            if ok.any():
                found.add(code)
                break
    return found


#: rows of the chunks a program is read and planned in: the memory a compensation holds grows with it
#: (about 2.4 kB a row: 280 MB at 65536, 200 MB at this), its time hardly changes
CHUNK_ROWS = 32768

#: the speed of rapid moves (mm/min) in a program's run time (:func:`block_times`); machine files
#: do not state one
RAPID_MM_MIN = 10000.0


def block_times(machine, chunk, t0: float = 0.0, rapid_seen: bool = False) -> tuple[np.ndarray, bool]:
    """((n,) seconds from the program's start at which it reaches each row's end, whether a rapid
    was timed): feed moves at their feed (mm/min, the path length over the linear axes), rapids at
    :data:`RAPID_MM_MIN`; a move without a feed, or one of rotary axes alone, takes no time."""
    lin = [j for j, a in enumerate(machine.axes) if not a.is_rotary]
    length = np.sqrt(np.sum((chunk.end[:, lin] - chunk.start[:, lin]) ** 2, axis=1))
    rapid = np.asarray(chunk.rapid, bool)
    feed = np.where(rapid, RAPID_MM_MIN, np.asarray(chunk.feed, dtype=float))
    with np.errstate(divide="ignore", invalid="ignore"):
        dt = np.where(np.isfinite(feed) & (feed > 0), 60.0 * length / feed, 0.0)
    return t0 + np.cumsum(dt), rapid_seen or bool(np.any(rapid & (length > 0)))


class Judge:
    """The tool-tip deviation of the planned blocks under another model of the same machine (a later
    re-measurement, or a draw of the model from its covariance): before correction and after it,
    over the blocks the plan corrected. The same evaluator as the planner's (one simulator), its
    corrections referenced to the part's datum as this model has it (the machinist probes the datum
    on the machine the judge stands for), probed in the one thermal state the compensation took
    (:meth:`probed_as`; this model's own reference only when the compensating model has none)."""

    def __init__(self, fitted, settings: CompensationSettings, label: str = "judge"):
        from .planner._evaluate import Evaluator
        from .thermal.context import thermal_context
        self.label = label
        fitted = _thermal_model(fitted, settings)[0]
        self.fitted = fitted
        thermal, _ = thermal_context(fitted, settings.temperatures, settings.spindle_rpm,
                                     settings.extrapolate, every_sensor=False)
        _probed(fitted, settings)        # before the state is written: the record's means
        fitted.context_defaults.update(thermal)
        fitted.probe_tool_length = settings.probe_tool_length
        self.ev = Evaluator(CompensationProblem.from_machine(fitted))
        self.count = 0
        self.max_before_um = self.max_after_um = 0.0
        self.sum_sq_before = self.sum_sq_after = 0.0

    def probed_as(self, fitted) -> None:
        """The part's datum probed in the thermal state the compensating model ``fitted`` has
        (``fitted.probed``, resolved once from it and the settings): one probing, one state, not
        this model's own record's first reading. Kept as it is when ``fitted`` corrects no drift."""
        if fitted.probed is not None:
            self.fitted.probed = dict(fitted.probed)
            self.fitted.probed_from_record = False      # no reading of this model's record

    def add(self, chunk, res) -> None:
        """Accumulate one planned chunk: ``chunk`` the machine-frame SegmentChunk the plan was made
        for, ``res`` its PlanResult (rows per node; ``res.counts`` nodes per chunk row)."""
        done = res.corrected_blocks()
        if not done.any():
            return
        rows = np.repeat(np.arange(len(chunk)), res.counts)[done]
        cols = {"feed": np.asarray(chunk.feed)[rows]}
        dirs = np.asarray(chunk.dirs)[rows]
        for j, a in enumerate(self.fitted.machine.axis_names):
            cols[f"dir_{a}"] = dirs[:, j].astype(float)
        if chunk.tool_length is not None:
            cols["tool_length"] = np.asarray(chunk.tool_length)[rows]
        for name, values in (chunk.context or {}).items():
            cols[name] = np.asarray(values)[rows]
        ctx = self.fitted.context(rows.size, cols)
        q = res.nominal[done]
        x = res.correction[done] * self.ev.D
        target = self.ev.target(q)
        if chunk.datum is not None:
            target = target + self.ev.datum_reference(np.asarray(chunk.datum)[rows], ctx)
        before = self.ev.residual(q, np.zeros_like(x), ctx, target)[:, :3] / self.ev.S[:3]
        after = self.ev.residual(q, x, ctx, target)[:, :3] / self.ev.S[:3]
        eb = np.sqrt(np.sum(before ** 2, axis=1)) * 1e3
        ea = np.sqrt(np.sum(after ** 2, axis=1)) * 1e3
        self.count += rows.size
        self.max_before_um = max(self.max_before_um, float(eb.max()))
        self.max_after_um = max(self.max_after_um, float(ea.max()))
        self.sum_sq_before += float(np.sum(eb ** 2))
        self.sum_sq_after += float(np.sum(ea ** 2))

    def as_dict(self) -> dict:
        """{blocks, rms_before_um, max_before_um, rms_after_um, max_after_um} over the corrected blocks."""
        n = max(self.count, 1)
        return {"blocks": self.count, "rms_before_um": math.sqrt(self.sum_sq_before / n),
                "max_before_um": self.max_before_um, "rms_after_um": math.sqrt(self.sum_sq_after / n),
                "max_after_um": self.max_after_um}


@dataclass
class CompensationRun:
    """What one compensation did.

    summary : the planner's Summary (figures over the blocks, under the compensating model).
    written : the writer's counts (``cycle_blocks``, ``cycle_lines``).
    notes : lines to tell the user (units assumed, drilling cycles, datum, feeds).
    assumed : the lines on the thermal state assumed and the drift's reference ('' without drift).
    stats : the planner's statistics (windows, OSQP solves ...).
    judges : Judge label -> its figures (:meth:`Judge.as_dict`).
    correction_rms_um, correction_max_um : size of the linear corrections written, over the
        corrected blocks (the correction effort).
    bound_blocks : {'max_correction', 'max_step', 'travel'} -> blocks (every axis known) at which a
        bound of that kind acted on some axis.
    seconds : wall time.
    dialect : 'dialect: NAME (how it was found)'.
    """

    summary: Summary
    written: dict
    notes: list
    assumed: str
    stats: dict
    judges: dict
    correction_rms_um: float
    correction_max_um: float
    seconds: float
    bound_blocks: dict = field(default_factory=dict)
    dialect: str = ""


class _Tally:
    """What a compensation counts beside the planner's Summary, chunk by chunk: feed moves without a
    feed, the correction effort, the blocks a bound held, and the program's run time at its feeds
    (for temperatures along it)."""

    def __init__(self, machine):
        self.machine = machine
        self.linear = np.array([not a.is_rotary for a in machine.axes])
        self.no_feed_blocks, self.no_feed_line = 0, 0
        self.sum_sq, self.max, self.n = 0.0, 0.0, 0
        self.bound_blocks = dict.fromkeys(_BOUND_KINDS, 0)
        self.t_s, self.rapid_timed = 0.0, False
        #: tool centre point blocks; (line before, first line) of each run of them (lines read)
        self.tcp_blocks, self.tcp_runs, self._last = 0, [], (0, False)
        #: blocks under Haas' G254 (dynamic work offset), the first one's line (read)
        self.dwo_blocks, self.dwo_line = 0, 0

    def read(self, chunk) -> None:
        """A chunk as read (program frame): its feed moves without a feed, its tool centre point
        blocks."""
        feedless = ~np.asarray(chunk.rapid, bool) & np.isnan(chunk.feed)
        if feedless.any():
            self.no_feed_blocks += int(feedless.sum())
            self.no_feed_line = self.no_feed_line or int(chunk.line[np.argmax(feedless)])
        if not len(chunk):
            return
        tcp, dwo = frame_tcp(chunk.frame), frame_dwo(chunk.frame)
        self.tcp_blocks += int(np.count_nonzero(tcp))
        self.dwo_line = self.dwo_line or (int(chunk.line[np.argmax(dwo)]) if dwo.any() else 0)
        self.dwo_blocks += int(np.count_nonzero(dwo))
        lines = np.asarray(chunk.line, np.int64)
        before = np.concatenate([[self._last[1]], tcp[:-1]])
        for i in np.flatnonzero(tcp & ~before).tolist():
            self.tcp_runs.append((int(lines[i - 1]) if i else self._last[0], int(lines[i])))
        self._last = (int(lines[-1]), bool(tcp[-1]))

    def clock(self, chunk) -> np.ndarray:
        """(n,) seconds from the program's start at each row's end (:func:`block_times`)."""
        t_end, self.rapid_timed = block_times(self.machine, chunk, self.t_s, self.rapid_timed)
        self.t_s = float(t_end[-1]) if len(t_end) else self.t_s
        return t_end

    def planned(self, res) -> None:
        """A chunk's PlanResult: the bounds that acted, the corrections' size."""
        if res.flags.any():
            known = ~any_rows(res.unknown)
            for kind, cols in _BOUND_KINDS.items():
                hit = np.zeros(len(known), bool)
                for k in cols:
                    hit |= any_rows(res.flags[:, :, k])
                self.bound_blocks[kind] += int(np.count_nonzero(hit & known))
        done = res.corrected_blocks()
        k = int(np.count_nonzero(done))
        if k:
            # no copies when every block is corrected and every axis linear (the usual case)
            c = res.correction if self.linear.all() else res.correction[:, self.linear]
            c = row_norm(c if k == len(done) else c[done]) * 1e3
            self.sum_sq += float(np.sum(c ** 2))
            self.max = max(self.max, float(c.max()))
            self.n += k

    def feed_note(self, fitted) -> list[str]:
        feed_terms = [t.key() for t in fitted.model.terms if t.uses_feed]
        if not feed_terms or not self.no_feed_blocks:
            return []
        k = self.no_feed_blocks
        return [f"warning: {k} feed move{'s' if k != 1 else ''} from line {self.no_feed_line} on have "
                f"no feed (no F word before them): the model's feed terms ({', '.join(feed_terms)}) "
                "take them at 0 mm/min"]


def _program_units(found: set, settings: CompensationSettings, machine) -> tuple[bool, bool, list]:
    """(the program starts in inch, it holds inch anywhere (the output grid), notes on what was
    taken for a program that states no units); ``found``: the program's G codes of
    :func:`words_in`, G20 and G21 among them when it has them."""
    inch_anywhere = b"20" in found
    if b"20" in found or b"21" in found:
        return False, inch_anywhere, []
    units = settings.units or machine.units
    if units is None:
        note = ("warning: the program has no G20/G21 and neither --units nor the machine file's "
                "'units' says which: taken as mm")
        units = "mm"
    else:
        note = (f"the program has no G20/G21: taken as {units} "
                f"({'--units' if settings.units else 'machine file'})")
    start_inch = units == "inch"
    return start_inch, start_inch, [note]


def _thermal_model(fitted, settings: CompensationSettings, series=None) -> tuple:
    """(the model to compensate with, '' or the sentence saying the drift is not compensated): with
    no temperature, readings or spindle speed given, the machine's thermal state while the program
    runs is not known, so the drift terms correct nothing (the model's reference temperatures are
    the mean over its record, not the machine's state now: they would correct a drift nobody
    measured, about 10 um on the real record)."""
    from .thermal.context import TIME_DRIVEN, has_tip_drift, time_driven
    given = bool(settings.temperatures) or settings.spindle_rpm is not None or series is not None
    if given or not has_tip_drift(fitted.model):
        # a copy of what the thermal state is written into: the caller's model is not changed
        return replace(fitted, context_defaults=dict(fitted.context_defaults)), ""
    if time_driven(fitted.model):
        return fitted.without_drift(), f"thermal drift not compensated: {TIME_DRIVEN}"
    return fitted.without_drift(), ("thermal drift not compensated: no temperature or spindle speed "
                                    "given, so the machine's thermal state is not known (give "
                                    "--temperature, --temperatures or --spindle-rpm)")


def _feed_use(fitted, series) -> str:
    """What makes the corrections depend on the programmed feed, said for the reader's refusal of
    an F it cannot read for sure (:mod:`.toolpaths.word_use`): the model's feed terms, the
    temperatures of a series looked up at each block's time (its length over its feed); '' where
    nothing does."""
    terms = [t.key() for t in fitted.model.terms if t.uses_feed]
    uses = [f"the model's feed terms ({', '.join(terms)})"] if terms else []
    if series is not None:
        uses.append("the temperatures looked up at each block's time (its length over its feed)")
    return " and ".join(uses)


def _probed(fitted, settings: CompensationSettings, series=None) -> str:
    """Sets ``fitted.probed`` (and ``probed_from_record``) to
    :func:`mtcomp.thermal.context.probed_state` of the settings (and ``series``'s sensors); the line
    saying which reference the drift is corrected from."""
    from .thermal.context import probed_state
    cut = set(settings.temperatures) | set(series.temps if series is not None else ())
    fitted.probed, line = probed_state(fitted, cut, settings.spindle_rpm,
                                       settings.probed_temperatures, settings.probed_spindle_rpm,
                                       settings.extrapolate)
    fitted.probed_from_record = not settings.probed_temperatures and settings.probed_spindle_rpm is None
    return line


def _checked_series(fitted, settings: CompensationSettings, series):
    """The temperature series without the sensors the settings give (a flag wins), every reading
    checked against the model's record (InputError beyond it unless ``settings.extrapolate``)."""
    from .thermal.context import thermal_context
    if series is None:
        return None
    series = type(series)(series.t_s, {k: v for k, v in series.temps.items()
                                       if k not in settings.temperatures})
    for state in series.extremes():
        thermal_context(fitted, {**settings.temperatures, **state}, settings.spindle_rpm,
                        settings.extrapolate)
    return series


def _series_sentence(fitted, settings: CompensationSettings, series, tally: _Tally) -> str:
    """What was assumed of the thermal state when the temperatures follow a series."""
    from .thermal.context import thermal_context
    first = {k: float(v[0]) for k, v in series.temps.items()}
    start = thermal_context(fitted, {**settings.temperatures, **first}, settings.spindle_rpm, True)[1]
    return (f"{start}; from there {', '.join(series.temps)} follow the readings along the program's "
            f"run time ({len(series.t_s)} readings over {float(series.t_s[-1] - series.t_s[0]):g} s; "
            f"the program takes {tally.t_s:.0f} s at its feeds"
            + (f", rapids at {RAPID_MM_MIN:g} mm/min" if tally.rapid_timed else "")
            + ("; the last reading holds after it" if tally.t_s > series.t_s[-1] else "") + ")")


def _report_lines(res, axis_names, sd_limit, unread=False) -> list[str]:
    """BLOCKS.csv's text of one planned chunk, in pieces (:func:`~mtcomp.planner.report_rows`'
    lines): the numbers written by the compiled formatter when there is one (a million rows took
    10 s in Python's ``%``), the few rows with text in them by report_rows, put in place of their
    lines (the text is not cut into a string per line: that took longer than writing it)."""
    values, decimals, blank, special = report_table(res, axis_names, sd_limit, unread)
    text = format_table(values, decimals, blank)
    if text is None:
        return report_rows(res, axis_names, sd_limit, unread)
    rows = np.flatnonzero(special)
    if not rows.size:
        return [text]
    # where each row's line ends (the text is ASCII: a character is a byte)
    ends = np.flatnonzero(np.frombuffer(text.encode("ascii"), np.uint8) == ord("\n")) + 1
    pieces, at = [], 0
    for i, line in zip(rows.tolist(), report_rows(res.take(rows), axis_names, sd_limit, unread)):
        pieces += [text[at:int(ends[i - 1]) if i else 0], line]
        at = int(ends[i])
    pieces.append(text[at:])
    return pieces


def _to_program_frame(res, chunk, off, setup) -> None:
    """The planned nodes back in the program's frame and words (less the work offset ``off`` (n,
    na) of each row; a tool centre point row's axes as its tip and angles: ``setup.to_program``):
    what is written and reported. The planner works on the output grid; a row's end is the
    program's own position plus its correction, so a word written with more decimals than the
    grid keeps them."""
    res.corrected = setup.to_program(chunk, res.corrected, res.counts, off)
    res.nominal = setup.to_program(chunk, res.nominal, res.counts, off)
    local = frame_local(chunk.frame)
    if local.any():
        # under G52, G68, a mirror or scaling the correction reported is the written one, in the
        # program's frame, like the positions (the planner's is along the machine's axes)
        rows = local if len(res.nominal) == len(chunk) else np.repeat(local, res.counts)
        res.correction[rows] = res.corrected[rows] - res.nominal[rows]
    if len(res.nominal) == len(chunk):         # one node a row (no internal nodes): every row
        exact = chunk.end - res.nominal
        res.nominal += exact
        res.corrected += exact
    else:
        ends = np.cumsum(res.counts) - 1
        for j in range(chunk.end.shape[1]):    # a column at a time: numpy takes rows one by one
            exact = chunk.end[:, j] - res.nominal[ends, j]
            res.nominal[ends, j] += exact
            res.corrected[ends, j] += exact
    res.corrected = setup.written(chunk, res.corrected, res.nominal, res.counts)


def compensate_program(fitted, program, output, settings: CompensationSettings, setup=None,
                       report=None, progress=None, judges=(), temperature_series=None,
                       io_progress=None) -> CompensationRun:
    """Compensate ``program`` with the model ``fitted`` into ``output`` (written atomically, with
    the BLOCKS.csv ``report`` when given). ``setup``: the program's work offsets and tool lengths
    (:func:`mtcomp.toolpaths.offsets.load_setup`; None: none). ``progress``: callable(blocks done)
    every few seconds; ``io_progress``: callable(what, line), told the lines a program with code
    has executed as it is expanded (``'expanded'``, :func:`mtcomp.toolpaths.source.open_program`), the
    program lines read for the plan as the reader goes (``'read'``,
    :func:`mtcomp.toolpaths.iter_segment_chunks`) and the line up to which the output is written
    (``'written'``, a chunk at a time). ``judges``:
    :class:`Judge` objects that evaluate the plan under their models.
    ``temperature_series``: a :class:`~mtcomp.thermal.context.TemperatureSeries`, the temperatures
    along the program's run time (each block at the time the program reaches its end at its feeds,
    :func:`block_times`); a sensor also in ``settings.temperatures`` keeps that value.
    A program with no block to correct (no motion, or only moves passed through) is written
    unchanged, byte for byte, and a note says so."""
    from .thermal.context import thermal_context
    from .toolpaths.offsets import ProgramSetup
    t0 = time.perf_counter()
    machine = fitted.machine
    settings.check()
    fitted, unknown_state = _thermal_model(fitted, settings, temperature_series)
    thermal, assumed = thermal_context(fitted, settings.temperatures, settings.spindle_rpm,
                                       settings.extrapolate, every_sensor=temperature_series is None)
    assumed = unknown_state or assumed
    series = _checked_series(fitted, settings, temperature_series)
    probe_line = _probed(fitted, settings, temperature_series)   # before the state is written
    for judge in judges:        # one probing: a judge takes the state resolved here (Judge.probed_as)
        judge.probed_as(fitted)
    fitted.context_defaults.update(thermal)
    fitted.probe_tool_length = settings.probe_tool_length
    setup = setup if setup is not None else ProgramSetup(machine)
    with contextlib.ExitStack() as stack:
        expanded = None if io_progress is None else (lambda lines: io_progress("expanded", lines))
        src = stack.enter_context(open_program(program, settings.dialect, progress=expanded,
                                                 fixed_format=machine.fixed_format))
        src.feed_use = _feed_use(fitted, series)
        # one pass over the program as read (an expansion, a conversational program's G-code) for
        # its units and for cutter radius compensation (the note); a conversational program's
        # blocks stay one to one, so it is planned without internal nodes
        found = words_in(src, (b"20", b"21", b"41", b"42"))
        if src.translated or b"41" in found or b"42" in found:
            # one output block per source block: a conversational program's blocks, and a program
            # under cutter radius compensation, whose controller offsets the moves as written
            # (a Sinumerik program's writer writes a straight move's ramp nodes as blocks)
            settings = replace(settings, subdivide_tol_um=0.0, ramp_nodes=src.sinumerik is not None
                               and b"41" not in found and b"42" not in found)
        run_ = _compensate_source(fitted, src, output, settings, setup, report, progress, judges,
                                  series, assumed, found, stack, t0, io_progress)
    run_.assumed = "\n".join(line for line in (run_.assumed, probe_line) if line)
    return run_


def _compensate_source(fitted, src, output, settings, setup, report, progress, judges, series,
                       assumed, found, stack, t0, io_progress) -> CompensationRun:
    """:func:`compensate_program` once the program is open (``src``, closed by ``stack``)."""
    machine = fitted.machine
    program = src.source
    start_inch, inch, notes = _program_units(found, settings, machine)
    start_pos, start_known = start_position(machine, settings.start_position)
    sd_limit = settings.sd_limit()
    read_progress = None if io_progress is None else (lambda lines: io_progress("read", lines))
    planner, summary = _planner(fitted, settings, inch, src, progress)
    tally = _Tally(machine)
    offsets_of = {}
    read = dict(chord_tol_mm=settings.chord_tol_um * 1e-3, initial_position=start_pos,
                inch=start_inch, initial_known=start_known)

    def machine_chunks():
        for chunk in iter_segment_chunks(src, machine, chunk_size=CHUNK_ROWS, progress=read_progress,
                                         **read):
            tally.read(chunk)
            mchunk, off = setup.apply(chunk, src)
            if series is not None:
                mchunk.context = {f"temp_{k}": v for k, v in series.at(tally.clock(chunk)).items()}
            offsets_of[id(mchunk)] = (chunk, off)
            yield mchunk

    def corrections(rep):
        # with threads to spare the program is read in a thread of its own: the planner's thread,
        # the longest of the three, only plans
        chunks = machine_chunks()
        if planner.threads > 1:
            chunks = read_ahead(chunks, name="mtcomp-reader")
        for mchunk, res in planner.iter_chunks(chunks):
            chunk, off = offsets_of.pop(id(mchunk))
            for judge in judges:
                judge.add(mchunk, res)
            tally.planned(res)
            _to_program_frame(res, chunk, off, setup)
            # the source line of each block (the report and the summary name the user's file)
            res.line = src.source_lines_of(res.line)
            summary.add(res)
            if rep is not None:
                rep.writelines(_report_lines(res, machine.axis_names, sd_limit, planner.direction.active))
            yield chunk, res.corrected, res.counts
            if io_progress is not None and len(chunk):   # the writer is done with the chunk
                io_progress("written", int(chunk.line[-1]))

    written, rep = {}, None
    if report is not None:        # committed when the caller's stack closes, after the output
        rep = stack.enter_context(atomic_write(report, "w", newline=""))
        rep.write(",".join(report_columns(machine.axis_names, machine.is_five_axis,
                                          summary.assumed is not None, planner.direction.active)) + "\n")
    try:
        write_corrected(src, output, machine, corrections(rep), stats=written, **read)
    except TravelError as e:
        raise _travel_error_with_offsets(e, setup) from None
    if summary.blocks == 0:
        # nothing to correct (a macro without moves, a file of subroutines nothing in it calls,
        # moves all passed through): the user's file is the corrected program, byte for byte
        with open(program, "rb") as f, atomic_write(output, "wb") as out:
            out.write(f.read())
        written["unchanged"] = True
    gated = {k: [n, int(src.source_lines_of(np.array([line]))[0])]
             for k, (n, line) in planner.datum.gated.items()}
    summary.datum_blocks = sum(n for n, _ in gated.values())
    summary.uncorrected_cause = _offset_cause(setup, summary)
    summary.datum_line = min((line for _, line in gated.values()), default=0)
    datum, summary.datum_lines = datum_notes(fitted, setup, gated)
    summary.direction_blocks, summary.infinite_causes = planner.direction.blocks, planner.ev.infinite_causes
    summary.direction_lines = planner.direction.text(
        lambda k: f"{k} block" if k == 1 else f"{k} blocks",
        lambda line: int(src.source_lines_of(np.array([line]))[0]))
    notes += _run_notes(src, written, fitted, setup, tally, found, datum)
    if series is not None:
        assumed = _series_sentence(fitted, settings, series, tally)
    return CompensationRun(summary, written, notes, assumed, planner.stats,
                           {j.label: j.as_dict() for j in judges},
                           math.sqrt(tally.sum_sq / max(tally.n, 1)), tally.max,
                           time.perf_counter() - t0, tally.bound_blocks, src.summary())


def _offset_cause(setup, summary) -> str:
    """What the warning that no block was corrected adds where a work offset given without an
    axis the program positions (taken as 0) put blocks outside the region the data reached, on
    that axis: the offset and the axis ("" otherwise)."""
    if summary.corrected_blocks or not summary.outside_blocks:
        return ""
    short = [(w, [a for a in left if summary.outside_axes.get(a)])
             for w, left in setup.left_out().items()]
    short = [(w, left) for w, left in short if left]
    if not short:
        return ""
    said = "; ".join(f"{', '.join(left)} of work offset {WORK_SYSTEMS[w]} taken as 0 (not given)"
                     for w, left in short)
    return (f"; {said}: the program stands outside the region the model's data reached on "
            f"{', '.join(sorted({a for _, left in short for a in left}))}: give that offset's "
            "every axis")


def _travel_error_with_offsets(e: TravelError, setup) -> TravelError:
    """A position outside the travel, and the work offsets taken as 0 because nobody gave them:
    the error says so (the usual cause is an offset left out, not a wrong program)."""
    missing = sorted(w for w in setup.used_wcs if w not in setup.work_offsets)
    if missing:
        names = ", ".join(WORK_SYSTEMS[w] for w in missing)
        return TravelError(f"{e.message}, with work offset {names} taken as 0 (nobody gave it): "
                           "give --work-offset or --offsets", e.path, e.line, e.row, e.axis)
    # an offset given without the axis that left the travel: that axis of it was taken as 0
    short = sorted(w for w in setup.used_wcs if w in setup.given_axes
                   and e.axis is not None and e.axis not in setup.given_axes[w])
    if not short:
        return e
    names = ", ".join(WORK_SYSTEMS[w] for w in short)
    return TravelError(f"{e.message}, with {e.axis} of work offset {names} taken as 0 (not given)",
                       e.path, e.line, e.row, e.axis)


def _planner(fitted, settings: CompensationSettings, inch: bool, src, progress) -> tuple:
    """(the Planner of this compensation, the Summary its results are added to); ``src``: the
    program as read (its errors name the user's file and line)."""
    sd_limit = settings.sd_limit()
    options = PlannerOptions(method=settings.method, subdivide_tol_um=settings.subdivide_tol_um or None,
                             ramp_nodes=settings.ramp_nodes,
                             progress=progress, extrapolate=settings.extrapolate,
                             max_correction_sd_um=sd_limit, threads=settings.threads)
    planner = Planner(build_problem(fitted, settings, inch), options, source=src)
    summary = Summary(fitted.machine.axis_names, extrapolate=settings.extrapolate,
                      support_known=fitted.support is not None, max_correction_sd_um=sd_limit,
                      has_covariance=fitted.uncertainty is not None, ram=planner.ram.ram,
                      ram_measured=(fitted.support or {}).get(planner.ram.ram),
                      ram_asked=planner.ram.ram_asked, tools_asked=planner.ram.tools_asked,
                      tools_measured=fitted.info.get("tool_length_mm")
                      if isinstance(fitted.info, dict) else None,
                      assumed=None if planner.ev.assumed is None else AssumedTally(planner.ev.assumed),
                      partial=PartialTally(planner.partial.limit_urad, planner.partial.rotary))
    return planner, summary

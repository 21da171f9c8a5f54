"""`mtcomp compensate MACHINE MODEL.json IN.nc -o OUT.nc`: bounded per-block axis corrections.

The program is streamed twice (once planned, once rewritten by :func:`mtcomp.toolpaths.write_corrected`)
so memory stays flat for any length. OUT.nc and BLOCKS.csv are written atomically: on any error
neither exists. Flags override the machine file's [compensation] table. docs/planner.md,
docs/toolpaths.md (what is read and written, offsets).
"""
from __future__ import annotations


def add_arguments(parser):
    from . import add_dialect_argument, add_offset_arguments
    from ..planner.problem import DEFAULT_MAX_CORRECTION_SD_UM
    parser.add_argument("machine", metavar="MACHINE", help="built-in machine name or machine TOML file")
    parser.add_argument("model", metavar="MODEL.json", help="fitted error model")
    parser.add_argument("program", metavar="IN.nc", help="NC program (G-code)")
    parser.add_argument("-o", "--output", metavar="OUT.nc", required=True,
                        help="where to write the corrected program")
    parser.add_argument("--method", choices=("qp", "pinv", "newton"), default="qp",
                        help="qp: bounded optimisation over the whole program (default); pinv: one "
                             "pseudo-inverse step per block (Qi and Yang 2016); newton: that step "
                             "iterated")
    parser.add_argument("--max-correction-um", type=float, metavar="U", default=None,
                        help="largest correction of a linear axis per block (um)")
    parser.add_argument("--max-correction-urad", type=float, metavar="R", default=None,
                        help="largest correction of a rotary axis per block (urad; 0: the rotary "
                             "axes are never corrected, the linear axes alone correct the tip)")
    parser.add_argument("--max-step-um", type=float, metavar="S", default=None,
                        help="largest change of a linear correction between consecutive blocks (um)")
    parser.add_argument("--max-step-urad", type=float, metavar="S", default=None,
                        help="the same for rotary axes (urad; default: max-step-um scaled like the "
                             "correction bounds)")
    parser.add_argument("--orientation-weight", type=float, metavar="W", default=1.0,
                        help="5-axis: um of tool-tip deviation that weigh as much as 1 urad of "
                             "tool-axis deviation (default 1: a 1 m lever; the tool's working "
                             "length in m, e.g. 0.05, favours the tip)")
    parser.add_argument("--report", metavar="BLOCKS.csv", default=None,
                        help="write one row per output block: positions, corrections, predicted "
                             "deviation before and after, active bounds")
    parser.add_argument("--json", metavar="SUMMARY.json", default=None,
                        help="write the summary's figures as JSON (blocks, deviation before and "
                             "after over all evaluated blocks and over the corrected ones only, "
                             "blocks left uncorrected, bounds, drilling cycles)")
    parser.add_argument("--subdivide-tol-um", type=float, metavar="T", default=0.5,
                        help="insert internal nodes in a feed move where the corrected path would "
                             "miss its midpoint by more than T um (default 0.5; 0: end points only)")
    parser.add_argument("--chord-tol-um", type=float, metavar="T", default=1.0,
                        help="chord tolerance (um, default 1): arcs are read as chords within it, and an "
                             "arc is written as an arc (or arcs) where the corrected path stays within "
                             "it of one, else as G1 chords within it (a Heidenhain arc: refused)")
    _add_thermal_arguments(parser)
    parser.add_argument("--extrapolate", action="store_true",
                        help="correct blocks outside the region the model's data reached too "
                             "(default: they get no correction, and the summary counts them), and "
                             "accept temperatures and spindle speeds outside the range of the "
                             "model's thermal record (default: refused)")
    parser.add_argument("--max-correction-sd-um", type=float, metavar="SD", default=None,
                        help="leave a block uncorrected where its correction's standard error (from "
                             "the model's covariance) exceeds SD um: the model is unsure there "
                             f"(default {DEFAULT_MAX_CORRECTION_SD_UM:g}; 0: no limit); nor a correction "
                             "within two standard errors of zero, nor a tool-axis correction over "
                             "SD / W urad (W: --orientation-weight)")
    parser.add_argument("--units", choices=("mm", "inch"), default=None,
                        help="what a program without G20/G21 is written in (default: the machine "
                             "file's 'units', else mm with a warning)")
    add_offset_arguments(parser, "work offsets (G54 ...) and tool lengths (H1 ...) of the program; "
                                 "see docs/toolpaths.md",
                         "a work offset: where the program's zero sits in machine axis positions "
                         "(mm, deg; repeatable; wins over --offsets)")
    parser.add_argument("--start-position", metavar="A=0,C=0", action="append", default=[],
                        help="axes that stand at a known position (program frame; mm, deg) before "
                             "the program starts, e.g. the rotary axes of a 5-axis machine that a "
                             "3-axis program never names (default: no axis is known at the start)")
    add_dialect_argument(parser)
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress lines on stderr")


def _add_thermal_arguments(parser):
    """The options of the thermal state while the program runs and when its datum was probed."""
    from . import add_probed_arguments
    parser.add_argument("--temperature", metavar="NAME=DEGC", action="append", default=[],
                        help="temperature of sensor NAME (as in temp_NAME_c of the thermal file) while "
                             "the program runs, for the model's thermal drift (repeatable; every sensor "
                             "the drift reads must be given, here or in --temperatures: a missing "
                             "one is refused, naming it; refused outside the range of the "
                             "model's thermal record unless --extrapolate)")
    parser.add_argument("--temperatures", metavar="READINGS.csv", default=None,
                        help="temperature readings, a column temp_NAME_c per sensor as in the "
                             "thermal file: one row while the program runs, or a time series (a t_s "
                             "column, seconds from the program's start) followed along the program's "
                             "run time at its feeds (--temperature wins for a sensor given both ways)")
    parser.add_argument("--spindle-rpm", type=float, metavar="RPM", default=None,
                        help="spindle speed the machine has run at long enough to be warm, for the "
                             "model's spindle-heat drift (default: spindle stopped for long)")
    add_probed_arguments(parser, "temperature of sensor NAME when the part's datum (G54 ...) was "
                         "probed: the drift since then is corrected (repeatable, each sensor given "
                         "above; default: the drift since the thermal record's first reading)",
                         "the same for --spindle-rpm: the speed the spindle had run at long enough "
                         "to be warm when the datum was probed")
    parser.add_argument("--probed-with-tool-length", type=float, metavar="MM", default=None,
                        help="the length of the probe (or tool) the part's datum was found with in "
                             "X and Y: every tool's X Y correction is referenced to that probe's "
                             "tip at the datum, its Z correction to its own tip there (each tool "
                             "set in Z on its own). Default: the machine file's tool length")


def _positive(value, flag, allow_zero=False):
    import math

    from ..errors import InputError
    if value is None:
        return None
    if not math.isfinite(value) or value < 0 or (value == 0 and not allow_zero):
        what = "0 or a positive number" if allow_zero else "a positive number"
        raise InputError(f"{flag} must be {what}, got {value:g}")
    return value


def _output_paths(args):
    """(OUT.nc, BLOCKS.csv or None, SUMMARY.json or None), none of them an input nor each other."""
    from ..errors import InputError
    from ..io.atomic import check_output_path
    inputs = [args.program, args.model] + ([args.temperatures] if args.temperatures else [])
    out = check_output_path(args.output, inputs)
    report = None
    if args.report is not None:
        report = check_output_path(args.report, inputs)
        if report.resolve() == out.resolve():
            raise InputError("--report and -o name the same file", args.report)
    summary_json = None
    if args.json is not None:
        summary_json = check_output_path(args.json, inputs)
        if summary_json.resolve() in {out.resolve()} | ({report.resolve()} if report else set()):
            raise InputError("--json names the same file as -o or --report", args.json)
    return out, report, summary_json


def _thermal_state(args, fitted):
    """(temperatures sensor -> degC, a TemperatureSeries or None, columns of the readings file not
    read, temperatures at probing sensor -> degC), checked against the model before any work (the model file named)."""
    from ..thermal.context import (TemperatureSeries, check_readings, parse_assignments,
                                   probed_state, read_temperature_row, thermal_context)
    temperatures, unread, series = {}, [], None
    flags = parse_assignments(args.temperature, "--temperature")
    if args.temperatures:
        readings, unread = read_temperature_row(args.temperatures)
        check_readings(fitted, readings, args.temperatures, flags, args.extrapolate)
        if isinstance(readings, TemperatureSeries):
            series = readings
        else:
            temperatures = readings
    temperatures.update(flags)
    thermal_context(fitted, temperatures, args.spindle_rpm, args.extrapolate, source=args.model)
    probed = parse_assignments(args.probed_at_temperature, "--probed-at-temperature")
    probed_state(fitted, set(temperatures) | set(series.temps if series else ()), args.spindle_rpm,
                 probed, args.probed_at_spindle_rpm, args.extrapolate, source=args.model)
    return temperatures, series, unread, probed


def _write_summary(path, run_) -> None:
    import json

    from ..io.atomic import atomic_write
    figures = run_.summary.as_dict()
    figures["drilling_cycles"] = {"kept_lines": run_.written.get("cycle_blocks", 0),
                                  "passed_through_lines": run_.written.get("cycle_lines", 0)}
    # motion lines passed through uncorrected with no BLOCKS.csv row, by why (the summary's line)
    figures["passed_through_moves"] = {why: n for why, (n, _line) in
                                       (run_.written.get("passed_moves") or {}).items()}
    # lines written with axis words they did not name (the summary's line), the first one's line
    lines, first = run_.written.get("added_axis_words") or (0, 0)
    figures["added_axis_words"] = {"lines": lines, "line": first}
    with atomic_write(path, "w") as f:
        json.dump(figures, f, indent=2)
        f.write("\n")


def _reversal_note(fitted) -> str | None:
    """:func:`mtcomp.export.reversal_note` of the model, for a model whose file records its data's
    reversals (``info["reversal"]``); None without that record (export and the identification it
    imports are not loaded)."""
    if not (isinstance(fitted.info, dict) and fitted.info.get("reversal")):
        return None
    from ..export import reversal_note
    return reversal_note(fitted)


def _print_run(args, machine, fitted, run_, seconds, unread, written) -> None:
    print(f"mtcomp compensate: method {args.method}, {machine.name} ({machine.topology}), "
          f"{seconds:.1f} s")
    if run_.dialect:
        print(run_.dialect)
    if run_.assumed:
        print(run_.assumed)
    if "spindle_rpm" in unread:
        print(f"note: {args.temperatures}: column spindle_rpm not read (the spindle's state is "
              "--spindle-rpm)")
    print(run_.summary.text())
    for line in run_.notes:
        print(line)
    reversal = _reversal_note(fitted)
    if reversal:
        print(f"note: {reversal}")
    st = run_.stats
    if args.method == "qp" and st["windows"]:
        print(f"qp: {st['windows_qp']} of {st['windows']} windows needed OSQP "
              f"({st['qp_solves']} solves)")
    if st.get("links_relaxed"):
        n = len(st["links_relaxed"])
        print(f"note: at {n} block{'' if n == 1 else 's'} the rule that a correction keeps each "
              "axis's direction (or an arc's one correction under G41/G42, or the offset plane's "
              "correction held under G41/G42) gave way to the other "
              "bounds from where a window starts; the written motion there may differ in "
              "direction from the one the model was evaluated with")
    if st.get("qp_failed"):
        print(f"warning: OSQP failed on {st['qp_failed']} windows; their corrections were clamped "
              "to the bounds instead (reported as active bounds)")
    print(f"wrote {written[0]}" + (f" and {' and '.join(map(str, written[1:]))}" if written[1:] else ""))


class Progress:
    """compensate's progress lines on ``stream`` (None: none), one every ``every_s`` seconds while
    the work goes on, none in a shorter run: the lines a program with code has executed while it
    is expanded, the program's lines read, the blocks planned, the line up to which the output is
    written, and a compiler run of the model's C code under way
    (once per model structure: a 5-axis model's Jacobian takes tens of seconds, and nothing else
    reports during it). A thread of its own writes them, so that whatever runs (the reader of a
    tool centre point program, which reads it line by line in Python, a compiler run, the
    planner) the lines keep coming. ``t0``: the command's start (time.perf_counter)."""

    #: seconds between two lines (and before the first)
    EVERY_S = 3.0
    _WHAT = {"tip_pjacobian_function": "standard-error function",
             "axis_pjacobian_function": "tool axis's standard-error function",
             "deviation_qjacobian_function": "deviation and Jacobian",
             "deviation_function": "deviation"}

    def __init__(self, stream, t0: float, every_s: float | None = None):
        import threading
        self.stream, self.t0 = stream, t0
        self.every_s = self.EVERY_S if every_s is None else every_s
        self.lines = self.blocks = self.written = self.expanded = 0
        self.compile = None                     # (what, since) of a compiler run under way
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="mtcomp-progress", daemon=True)

    def io(self, what: str, line: int) -> None:
        """The program read up to ``line`` for the plan (``what`` 'read'), written up to it
        ('written'), or ``line`` lines of a program with code executed ('expanded')."""
        if what == "read":
            self.lines = max(self.lines, int(line))
        elif what == "expanded":
            self.expanded = max(self.expanded, int(line))
        else:
            self.written = max(self.written, int(line))

    def planned(self, blocks: int) -> None:
        self.blocks = int(blocks)

    def compiling(self, name: str, started: bool) -> None:
        import time
        self.compile = (self._WHAT.get(name, name), time.perf_counter()) if started else None

    def line(self, now: float) -> str:
        """The progress line at ``now`` (time.perf_counter)."""
        parts = [f"{self.lines} lines read" if self.lines else
                 f"running the program's code, {self.expanded} lines executed" if self.expanded
                 else "reading the program"]
        if self.blocks:
            parts.append(f"{self.blocks} blocks planned")
        if self.written:
            parts.append(f"written up to line {self.written}")
        compile_ = self.compile
        if compile_ is not None:
            parts.append(f"compiling the model's {compile_[0]} to C, {now - compile_[1]:.0f} s so "
                         "far (once per model; later runs reuse it)")
        return f"mtcomp compensate: {', '.join(parts)} ({now - self.t0:.0f} s)"

    def _run(self):
        import time
        while not self._stop.wait(self.every_s):
            self.stream.write(self.line(time.perf_counter()) + "\n")
            self.stream.flush()

    def __enter__(self):
        if self.stream is not None:
            self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join()


def run(args) -> int:
    import gc
    import sys
    import time

    from ..compensation import CompensationSettings, compensate_program, parse_start_position
    from ..machine import load_machine
    from ..models.compiled import compile_notices
    from ..models.model_file import load_model
    from ..toolpaths.offsets import load_setup

    t0 = time.perf_counter()
    for flag, v in (("--max-correction-um", args.max_correction_um),
                    ("--max-step-um", args.max_step_um), ("--max-step-urad", args.max_step_urad),
                    ("--chord-tol-um", args.chord_tol_um),
                    ("--orientation-weight", args.orientation_weight)):
        _positive(v, flag)
    # 0: the rotary axes are never corrected
    _positive(args.max_correction_urad, "--max-correction-urad", allow_zero=True)
    _positive(args.subdivide_tol_um, "--subdivide-tol-um", allow_zero=True)
    _positive(args.max_correction_sd_um, "--max-correction-sd-um", allow_zero=True)
    _positive(args.probed_with_tool_length, "--probed-with-tool-length", allow_zero=True)
    out, report, summary_json = _output_paths(args)
    machine = load_machine(args.machine)
    model_notes: list = []
    fitted = load_model(args.model, machine, model_notes)
    for n in model_notes:
        sys.stderr.write(f"note: {n}\n")
    temperatures, series, unread, probed = _thermal_state(args, fitted)
    settings = CompensationSettings(
        method=args.method, max_correction_um=args.max_correction_um,
        max_correction_urad=args.max_correction_urad, max_step_um=args.max_step_um,
        max_step_urad=args.max_step_urad, orientation_weight=args.orientation_weight,
        subdivide_tol_um=args.subdivide_tol_um, chord_tol_um=args.chord_tol_um,
        temperatures=temperatures, spindle_rpm=args.spindle_rpm, probed_temperatures=probed,
        probed_spindle_rpm=args.probed_at_spindle_rpm, probe_tool_length=args.probed_with_tool_length,
        extrapolate=args.extrapolate,
        max_correction_sd_um=args.max_correction_sd_um, units=args.units,
        start_position=parse_start_position(machine, args.start_position), dialect=args.dialect)
    setup = load_setup(machine, args.offsets, args.work_offset, args.tool_length)

    # what this process holds by now (the modules imported, the model) lives to its end: Python's
    # collector no longer goes through it at each full collection the planning sets off
    gc.freeze()
    # the summary JSON is written after the program and BLOCKS.csv, which are complete by then: a
    # failed run leaves none of the three (the first two are renamed into place only on success)
    with Progress(None if args.quiet else sys.stderr, t0) as progress, \
            compile_notices(progress.compiling if not args.quiet else None):
        run_ = compensate_program(fitted, args.program, out, settings, setup, report=report,
                                  progress=progress.planned, temperature_series=series,
                                  io_progress=progress.io)
    if summary_json is not None:
        _write_summary(summary_json, run_)
    _print_run(args, machine, fitted, run_, time.perf_counter() - t0, unread,
               [p for p in (out, report, summary_json) if p is not None])
    return 0

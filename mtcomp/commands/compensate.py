"""`mtcomp compensate MACHINE MODEL.json IN.nc -o OUT.nc`: bounded per-block axis corrections.

The program is streamed twice (once planned, once rewritten by :func:`mtcomp.toolpaths.write_corrected`)
so memory stays flat for any length. OUT.nc and BLOCKS.csv are written atomically: on any error
neither exists. Flags override the machine file's [compensation] table. docs/planner.md,
docs/toolpaths.md (what is read and written, offsets).
"""
from __future__ import annotations

_DIGITS = b"0123456789."


def add_arguments(parser):
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
                        help="largest correction of a rotary axis per block (urad)")
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
                        help="chord tolerance for arcs written as G1 polylines (um, default 1)")
    parser.add_argument("--temperature", metavar="NAME=DEGC", action="append", default=[],
                        help="temperature of sensor NAME (as in temp_NAME_c of the thermal file) while "
                             "the program runs, for the model's thermal drift (repeatable; sensors not "
                             "given keep the model's reference)")
    parser.add_argument("--spindle-rpm", type=float, metavar="RPM", default=None,
                        help="spindle speed the machine has run at long enough to be warm, for the "
                             "model's spindle-heat drift (default: spindle stopped for long)")
    parser.add_argument("--extrapolate", action="store_true",
                        help="correct blocks outside the region the model's data reached too "
                             "(default: they get no correction, and the summary counts them)")
    parser.add_argument("--max-correction-sd-um", type=float, metavar="SD", default=None,
                        help="leave a block uncorrected where its correction's standard error (from "
                             "the model's covariance) exceeds SD um: the model is unsure there "
                             f"(default {DEFAULT_MAX_CORRECTION_SD_UM:g}; 0: no limit)")
    parser.add_argument("--units", choices=("mm", "inch"), default=None,
                        help="what a program without G20/G21 is written in (default: the machine "
                             "file's 'units', else mm with a warning)")
    parser.add_argument("--offsets", metavar="OFFSETS.toml", default=None,
                        help="work offsets (G54 ...) and tool lengths (H1 ...) of the program; "
                             "see docs/toolpaths.md")
    parser.add_argument("--work-offset", metavar="G54=X..,Y..,Z..", action="append", default=[],
                        help="a work offset: where the program's zero sits in machine axis "
                             "positions (mm, deg; repeatable; wins over --offsets)")
    parser.add_argument("--tool-length", metavar="H1=L", action="append", default=[],
                        help="length (mm) of the tool of G43 H1 (repeatable; wins over --offsets)")
    parser.add_argument("--start-position", metavar="A=0,C=0", action="append", default=[],
                        help="axes that stand at a known position (program frame; mm, deg) before "
                             "the program starts, e.g. the rotary axes of a 5-axis machine that a "
                             "3-axis program never names (default: no axis is known at the start)")
    parser.add_argument("--quiet", action="store_true", help="no progress lines on stderr")


def _positive(value, flag, allow_zero=False):
    import math

    from ..errors import InputError
    if value is None:
        return None
    if not math.isfinite(value) or value < 0 or (value == 0 and not allow_zero):
        raise InputError(f"{flag} must be a positive number, got {value:g}")
    return value


def _datum_notes(fitted, setup) -> list[str]:
    """One line for each part's datum (the origin of a work offset the program used) outside the
    region the model's data reached: the corrections are referenced to the model's deviation there,
    which is then its continuation beyond the data."""
    import numpy as np

    from ..toolpaths.offsets import WORK_SYSTEMS
    support = fitted.support or {}
    machine = fitted.machine
    out = []
    for w in sorted(setup.used_wcs):
        datum = setup._offset_table()[w]
        off = [a for a, v in zip(machine.axis_names, datum)
               if a in support and not support[a][0] - 1e-6 <= v <= support[a][1] + 1e-6]
        if off:
            where = ", ".join(f"{a} {np.degrees(datum[machine.index(a)]) if machine.axis(a).is_rotary else datum[machine.index(a)]:g}"
                              for a in off)
            out.append(f"note: the part's datum of {WORK_SYSTEMS[w]} ({where}) lies outside the region "
                       "the model's data reached: the corrections are referenced to the model's "
                       "deviation there, its continuation beyond the data")
    return out


def _start_position(machine, flags):
    """--start-position A=0,C=0 (repeatable) -> (initial position (na,) mm/rad, known mask (na,))."""
    import math
    import re

    import numpy as np

    from ..errors import InputError
    pos = np.zeros(machine.n_axes)
    known = np.zeros(machine.n_axes, bool)
    for flag in flags:
        for item in filter(None, (t.strip() for t in flag.split(","))):
            m = re.fullmatch(r"([A-Za-z])\s*=\s*([+-]?(?:\d+\.?\d*|\.\d+))", item)
            if not m:
                raise InputError(f"--start-position {flag}: {item!r} is not an axis value such as "
                                 "A=0")
            a = m.group(1).upper()
            if a not in machine.axis_names:
                raise InputError(f"--start-position {flag}: machine {machine.name} has no {a} axis")
            j = machine.index(a)
            v = float(m.group(2))
            pos[j] = math.radians(v) if machine.axes[j].is_rotary else v
            known[j] = True
    return pos, known


def uses_inches(path, block: int = 1 << 22) -> bool:
    """True if the program contains a G20 word anywhere (comments included: a cautious guess that
    only sets the rounding grid of the output). Reads the file in blocks: memory stays flat."""
    return _has_word(path, b"20", block)


def states_units(path, block: int = 1 << 22) -> bool:
    """True if the program contains a G20 or a G21 word anywhere."""
    return _has_word(path, b"20", block) or _has_word(path, b"21", block)


def _has_word(path, code: bytes, block: int) -> bool:
    from ..errors import InputError
    try:
        f = open(path, "rb")
    except FileNotFoundError:
        raise InputError("no such file", path) from None
    except OSError as exc:
        raise InputError(f"cannot open: {exc.strerror}", path) from None
    tail = b""
    with f:
        while True:
            data = f.read(block)
            if not data:
                return _has_g(tail + b" ", code)
            text = tail + data
            if _has_g(text[:-8], code):
                return True
            tail = text[-16:]


def _has_g(text: bytes, code: bytes = b"20") -> bool:
    """True if ``text`` holds G20, G020 or G0020 (G or g; ``code`` instead of 20) not followed by a
    digit or '.' (the end of the text counts as not followed). Vectorised over the G letters."""
    import numpy as np
    a = np.frombuffer(text, np.uint8)
    g = np.flatnonzero((a | 0x20) == ord("g"))        # G or g
    if g.size == 0:
        return False
    pad = np.concatenate([a, np.full(6, ord(" "), np.uint8)])     # room after the last G
    after_ok = np.ones(256, bool)
    after_ok[np.frombuffer(_DIGITS, np.uint8)] = False
    n = a.size
    for zeros in range(3):
        word = g + 1
        ok = np.ones(g.size, bool)
        for k, ch in enumerate(b"0" * zeros + code):
            ok &= (word + k < n) & (pad[word + k] == ch)
        end = word + zeros + 2
        ok &= (end >= n) | after_ok[pad[np.minimum(end, n)]]
        if ok.any():
            return True
    return False


def run(args) -> int:
    import contextlib
    import sys
    import time

    import numpy as np

    from ..errors import InputError
    from ..io.atomic import atomic_write, check_output_path
    from ..machine import load_machine
    from ..models.model_file import load_model
    from ..planner import (CompensationProblem, Planner, PlannerOptions, Summary, output_grid,
                           report_columns, report_rows)
    from ..toolpaths import iter_segment_chunks, write_corrected
    from ..toolpaths.offsets import load_setup

    t0 = time.perf_counter()
    for flag, v in (("--max-correction-um", args.max_correction_um),
                    ("--max-correction-urad", args.max_correction_urad),
                    ("--max-step-um", args.max_step_um), ("--max-step-urad", args.max_step_urad),
                    ("--chord-tol-um", args.chord_tol_um),
                    ("--orientation-weight", args.orientation_weight)):
        _positive(v, flag)
    _positive(args.subdivide_tol_um, "--subdivide-tol-um", allow_zero=True)
    inputs = [args.program, args.model]
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
    machine = load_machine(args.machine)
    fitted = load_model(args.model, machine)
    from ..thermal.context import parse_assignments, thermal_context
    thermal, assumed = thermal_context(fitted, parse_assignments(args.temperature, "--temperature"),
                                       args.spindle_rpm)
    fitted.context_defaults.update(thermal)
    setup = load_setup(machine, args.offsets, args.work_offset, args.tool_length)
    notes = []
    start_inch = False
    if not states_units(args.program):
        units = args.units or machine.units
        if units is None:
            units = "mm"
            notes.append("warning: the program has no G20/G21 and neither --units nor the machine "
                         "file's 'units' says which: taken as mm")
        else:
            notes.append(f"the program has no G20/G21: taken as {units} "
                         f"({'--units' if args.units else 'machine file'})")
        start_inch = units == "inch"
    inch = start_inch or uses_inches(args.program)
    start_pos, start_known = _start_position(machine, args.start_position)
    problem = CompensationProblem.from_machine(
        fitted, args.max_correction_um, args.max_correction_urad, args.max_step_um,
        args.max_step_urad, grid=output_grid(machine, inch), orientation_weight=args.orientation_weight)

    def progress(done):
        sys.stderr.write(f"mtcomp compensate: {done} blocks planned ({time.perf_counter() - t0:.0f} s)\n")
        sys.stderr.flush()

    from ..planner.problem import DEFAULT_MAX_CORRECTION_SD_UM
    sd_limit = (DEFAULT_MAX_CORRECTION_SD_UM if args.max_correction_sd_um is None
                else _positive(args.max_correction_sd_um, "--max-correction-sd-um", allow_zero=True)) or None
    options = PlannerOptions(method=args.method, subdivide_tol_um=args.subdivide_tol_um or None,
                             progress=None if args.quiet else progress,
                             extrapolate=args.extrapolate, max_correction_sd_um=sd_limit)
    chord_tol = args.chord_tol_um * 1e-3
    planner = Planner(problem, options, source=args.program)
    summary = Summary(machine.axis_names, extrapolate=args.extrapolate,
                      support_known=fitted.support is not None, max_correction_sd_um=sd_limit,
                      has_covariance=fitted.uncertainty is not None)
    offsets_of = {}
    no_feed = {"blocks": 0, "line": 0}        # feed moves before any F word

    with contextlib.ExitStack() as stack:
        rep = None
        if report is not None:
            rep = stack.enter_context(atomic_write(report, "w", newline=""))
            rep.write(",".join(report_columns(machine.axis_names, machine.is_five_axis)) + "\n")

        def machine_chunks():
            for chunk in iter_segment_chunks(args.program, machine, chord_tol_mm=chord_tol,
                                             initial_position=start_pos, inch=start_inch,
                                             initial_known=start_known):
                feedless = ~np.asarray(chunk.rapid, bool) & np.isnan(chunk.feed)
                if feedless.any():
                    no_feed["blocks"] += int(feedless.sum())
                    no_feed["line"] = no_feed["line"] or int(chunk.line[np.argmax(feedless)])
                mchunk, off = setup.apply(chunk)
                offsets_of[id(mchunk)] = (chunk, off)
                yield mchunk

        def corrections():
            for mchunk, res in planner.iter_chunks(machine_chunks()):
                chunk, off = offsets_of.pop(id(mchunk))
                # back to the program's frame: what is written and reported
                node_off = np.repeat(off, res.counts, axis=0)
                res.corrected = res.corrected - node_off
                res.nominal = res.nominal - node_off
                summary.add(res)
                if rep is not None:
                    rep.writelines(report_rows(res, machine.axis_names, sd_limit))
                yield chunk, res.corrected, res.counts
            if summary.blocks == 0:
                # raised while the outputs are still temporary files: nothing is written
                raise InputError("no motion block in the program: nothing to compensate", args.program)

        written = {}
        write_corrected(args.program, out, machine, corrections(), chord_tol_mm=chord_tol,
                        initial_position=start_pos, inch=start_inch, initial_known=start_known,
                        stats=written)
        if summary_json is not None:
            import json
            figures = summary.as_dict()
            figures["drilling_cycles"] = {"kept_lines": written.get("cycle_blocks", 0),
                                          "passed_through_lines": written.get("cycle_lines", 0)}
            with atomic_write(summary_json, "w") as f:     # written with the others, at the end
                json.dump(figures, f, indent=2)
                f.write("\n")
    def cycle_lines(k):
        return f"{k} drilling cycle line{'' if k == 1 else 's'} (G73, G81-G89)"
    if written.get("cycle_blocks"):
        notes.append(f"{cycle_lines(written['cycle_blocks'])} kept as cycles, each hole corrected "
                     "where the model applies (X Y Z to the hole's bottom, R moved with Z; BLOCKS.csv "
                     "says which)")
    if written.get("cycle_lines"):
        notes.append(f"{cycle_lines(written['cycle_lines'])} passed through unchanged and "
                     "uncorrected: hole position, R or Z not known, or drilling along another "
                     "axis than Z")
    notes += _datum_notes(fitted, setup)
    feed_terms = [t.key() for t in fitted.model.terms if t.uses_feed]
    if feed_terms and no_feed["blocks"]:
        notes.append(f"warning: {no_feed['blocks']} feed move{'s' if no_feed['blocks'] != 1 else ''} "
                     f"from line {no_feed['line']} on have no feed (no F word before them): the model's "
                     f"feed terms ({', '.join(feed_terms)}) take them at 0 mm/min")
    elapsed = time.perf_counter() - t0
    print(f"mtcomp compensate: method {args.method}, {machine.name} ({machine.topology}), "
          f"{elapsed:.1f} s")
    if assumed:
        print(assumed)
    print(summary.text())
    for line in notes + setup.notes():
        print(line)
    st = planner.stats
    if args.method == "qp" and st["windows"]:
        print(f"qp: {st['windows_qp']} of {st['windows']} windows needed OSQP "
              f"({st['qp_solves']} solves)")
    if st.get("qp_failed"):
        print(f"warning: OSQP failed on {st['qp_failed']} windows; their corrections were clamped "
              "to the bounds instead (reported as active bounds)")
    extra = [str(p) for p in (report, summary_json) if p is not None]
    print(f"wrote {out}" + (f" and {' and '.join(extra)}" if extra else ""))
    return 0

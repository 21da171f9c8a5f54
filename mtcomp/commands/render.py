"""``mtcomp render MACHINE MODEL.json IN.nc [--compensated OUT.nc] [--report BLOCKS.csv] -o MAP.png``.

The workpiece surface the program cuts, coloured by the model's predicted deviation along the surface
normal (um), before and after compensation side by side on one colour scale; a .vtp with the same
stem is written next to the PNG for ParaView. The compensated blocks are paired with the original
ones through the programs' line structure, or through the compensation report's source lines.
See docs/render.md.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from ..errors import InputError


def add_arguments(parser):
    from . import add_dialect_argument, add_offset_arguments, add_probed_arguments
    parser.add_argument("machine", help="built-in machine name or machine TOML file")
    parser.add_argument("model", help="MODEL.json (from identify or diagnose)")
    parser.add_argument("program", help="the NC program (G-code) as written for the part")
    parser.add_argument("--compensated", metavar="OUT.nc",
                        help="the compensated program (from mtcomp compensate): adds the 'after' map")
    parser.add_argument("--report", metavar="BLOCKS.csv",
                        help="the report of mtcomp compensate: the 'after' map at its corrected "
                             "positions, paired with the program by source line")
    parser.add_argument("-o", "--output", required=True, metavar="MAP.png",
                        help="the PNG to write; MAP.vtp is written next to it")
    parser.add_argument("--tool-radius-mm", type=float, default=None, metavar="R",
                        help="ball-end radius (or the cutter radius with --flank-mm): draw the map at "
                             "the contact points (default: from the header of a built-in test part, "
                             "else 0: at the tool tips)")
    parser.add_argument("--flank-mm", type=float, default=None, metavar="L",
                        help="map the flank of the tool (5-axis side milling): contact lines along the "
                             "tool axis over L mm from the tip (default: from the header of a built-in "
                             "test part, else off: the surface of the tool tips)")
    parser.add_argument("--flank-side", choices=("outer", "inner"), default="outer",
                        help="with --flank-mm or an in-plane map: the tool works outside the "
                             "contour (a boss, default) or inside it (a pocket)")
    parser.add_argument("--normal", choices=("auto", "surface", "in-plane", "holes", "path"),
                        default="auto",
                        help="the direction the deviation is measured along: surface (the normal "
                             "of the cut surface), in-plane (a planar contour's normal in its "
                             "plane, across the tool axis: the error of the contour's position), "
                             "holes (each drilled hole's position error across the tool axis, "
                             "with arrows; its depth error in the titles), path (a 3-D path drawn "
                             "as its lines: the deviation across the path), auto (default: holes "
                             "for a drilling program (one that also mills is mapped by what it "
                             "mills, the holes left out and said), in-plane when the program cuts in planes "
                             "across the tool axis, a 2-D contour; path when the tool-tip surface "
                             "would be mostly walls seen edge-on; else surface)")
    parser.add_argument("--glyphs", action="store_true",
                        help="draw the deviation vectors as exaggerated arrows")
    parser.add_argument("--glyph-scale", type=float, default=None, metavar="K",
                        help="arrow exaggeration factor (default: largest arrow = 1/10 of the part)")
    parser.add_argument("--range-um", type=float, default=None, metavar="U",
                        help="colour scale -U..U um (default: the largest |deviation| of both maps)")
    add_offset_arguments(parser, "work offsets of the program, as for compensate (each block "
                                 "placed by its own work system, as compensate places it)",
                         "where the program's zero sits in machine axis positions (mm), as given "
                         "to compensate: the model is evaluated there")
    add_dialect_argument(parser)
    parser.add_argument("--chord-tol-um", type=float, metavar="T", default=None,
                        help="the chord tolerance compensate was given (um): the program's arcs are "
                             "read as the same chords, which the report's blocks follow (default: "
                             "compensate's default, 1)")
    parser.add_argument("--temperature", metavar="NAME=DEGC", action="append", default=[],
                        help="the machine's temperatures while the program runs, as given to "
                             "compensate (repeatable): the model's thermal drift is mapped at them "
                             "(default: no drift mapped, as compensate corrects none without them)")
    parser.add_argument("--spindle-rpm", type=float, metavar="RPM", default=None,
                        help="the spindle speed given to compensate, for a spindle-heat drift")
    add_probed_arguments(parser, "the temperatures when the part's datum was probed, as given to "
                         "compensate (repeatable): the drift since probing is mapped (default: the "
                         "drift since the thermal record's first reading)",
                         "the spindle speed at probing given to compensate")
    parser.add_argument("--extrapolate", action="store_true",
                        help="accept temperatures and spindle speeds outside the range of the "
                             "model's thermal record (default: refused, as compensate does)")
    parser.add_argument("--size", default="1400x700", metavar="WxH", help="image size in pixels")
    parser.add_argument("--backend", choices=("auto", "pyvista", "matplotlib"), default="auto",
                        help="renderer (auto: pyvista off-screen, matplotlib if VTK cannot render)")


class Progress:
    """Progress lines on ``stream`` for a render that takes a while: nothing in the first
    ``quiet_s`` seconds; after that, one line per stage (``mtcomp render: 4.2 s: <stage> ...``)
    and a last one when done. Called with the stage's text."""

    def __init__(self, stream, quiet_s: float = 3.0, clock=None):
        import time
        self.stream = stream
        self.quiet_s = quiet_s
        self.clock = clock or time.monotonic
        self.t0 = self.clock()
        self.stage = ""
        self.said = False

    def _say(self, text):
        self.stream.write(f"mtcomp render: {self.clock() - self.t0:.1f} s: {text}\n")
        self.stream.flush()
        self.said = True

    def __call__(self, stage: str) -> None:
        if self.stage and self.clock() - self.t0 > self.quiet_s:
            self._say(f"{self.stage} done; {stage} ...")
        self.stage = stage

    def done(self) -> None:
        if self.said or self.clock() - self.t0 > self.quiet_s:
            self._say(f"{self.stage} done" if self.stage else "done")


def _size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise InputError(f"--size must look like 1400x700, got {text!r}") from None
    if not (100 <= w <= 8000 and 100 <= h <= 8000):
        raise InputError(f"--size {text}: width and height must be 100..8000 pixels")
    return w, h


def run(args) -> int:
    import sys

    from ..io.atomic import check_output_path
    from ..machine import load_machine
    from ..models import load_model
    from ..viz.surface import program_error_map, read_program_points

    out = Path(args.output)
    _check_numbers(args)
    size = _size(args.size)
    inputs = [args.model, args.program] + ([args.compensated] if args.compensated else []) \
        + ([args.report] if args.report else [])
    for p in inputs:
        if not Path(p).is_file():
            raise InputError("no such file", p)
    check_output_path(out, inputs, ".png", "the map")
    check_output_path(out.with_suffix(".vtp"), inputs)
    progress = Progress(sys.stderr)
    progress("reading the model")
    machine = load_machine(args.machine)
    setup = _setup(args, machine)
    model_notes: list = []
    fitted = load_model(args.model, machine, model_notes)
    for n in model_notes:
        sys.stderr.write(f"note: {n}\n")
    fitted, drift_note = _thermal_state(args, fitted)
    progress("reading the program")
    tol = None if args.chord_tol_um is None else args.chord_tol_um * 1e-3
    program = read_program_points(args.program, machine, args.dialect, tol, setup)
    try:
        machine.check_travel(program.machine_q, program.line, program.known, args.program)
    except InputError as e:
        # the map is still drawn: tell, not refuse
        where = ("the program's coordinates taken as axis positions: give --work-offset or "
                 "--offsets" if not setup.work_offsets else "the program's coordinates plus the "
                 "work offset given")
        print(f"note: {e} ({where})", file=sys.stderr)
    smap = program_error_map(machine, fitted, program, args.compensated,
                             tool_radius_mm=args.tool_radius_mm, flank_length_mm=args.flank_mm,
                             flank_side=args.flank_side, report=args.report, normal=args.normal,
                             progress=progress, setup=setup)
    for tool in smap.info.get("tools_assumed", ()):
        print(f"assumed: tool length of {tool} = the machine's tool_length_mm "
              f"({machine.tool_length:g} mm); give --tool-length or --offsets")
    if drift_note:
        smap.notes.append(drift_note)
    from ..viz.render import render_error_map
    clim = None if args.range_um is None else (-args.range_um, args.range_um)
    progress(f"drawing {smap.points.shape[0]} points")
    res = render_error_map(smap, out, glyphs=args.glyphs or args.glyph_scale is not None,
                           glyph_scale=args.glyph_scale, clim=clim, window_size=size,
                           backend=args.backend)
    progress.done()
    _print_summary(args, smap, res)
    from ..models.assumed import model_note
    said = model_note(fitted, machine, "the predicted deviations")
    if said:
        print(said)
    print(f"wrote {res.png} ({res.backend}) and {res.vtp}")
    return 0


def _thermal_state(args, fitted):
    """(the model to map with, '' or the note saying the drift is not mapped or what it is
    referenced to): the model's thermal drift at the temperatures and spindle speed given, less the
    drift at the datum's probing (--probed-at-...), as compensate takes them; with none given,
    no drift, as compensate corrects none (its reference state is no state the machine was in)."""
    from dataclasses import replace

    from ..thermal.context import (TIME_DRIVEN, has_tip_drift, parse_assignments, probed_state,
                                   thermal_context, time_driven)
    temperatures = parse_assignments(args.temperature, "--temperature")
    probed = parse_assignments(args.probed_at_temperature, "--probed-at-temperature")
    if temperatures or args.spindle_rpm is not None:
        fitted = replace(fitted, context_defaults=dict(fitted.context_defaults))
        thermal, _ = thermal_context(fitted, temperatures, args.spindle_rpm, args.extrapolate,
                                     source=args.model)
        fitted.probed, line = probed_state(fitted, set(temperatures), args.spindle_rpm, probed,
                                           args.probed_at_spindle_rpm, args.extrapolate, args.model)
        fitted.context_defaults.update(thermal)     # after: the record's means are a reference
        fitted.probed_from_record = not probed and args.probed_at_spindle_rpm is None
        return fitted, line if fitted.probed_from_record else ""   # the reference when none given
    probed_state(fitted, (), None, probed, args.probed_at_spindle_rpm, source=args.model)
    if not has_tip_drift(fitted.model):
        return fitted, ""
    if time_driven(fitted.model):     # nothing render or compensate is given moves it
        return fitted.without_drift(), f"thermal drift not mapped: {TIME_DRIVEN}"
    return fitted.without_drift(), ("thermal drift not mapped: no temperature or spindle speed "
                                    "given (give render the --temperature / --spindle-rpm that "
                                    "compensate was given)")


def _setup(args, machine):
    """The program's set-up as compensate takes it: --offsets, --work-offset, --tool-length (read
    once)."""
    from ..toolpaths.offsets import load_setup
    return load_setup(machine, args.offsets, args.work_offset, args.tool_length)


def _check_numbers(args) -> None:
    """InputError for a glyph scale, tool radius, flank length, colour range or chord tolerance out
    of its bounds."""
    if args.chord_tol_um is not None and not args.chord_tol_um > 0:
        raise InputError(f"--chord-tol-um must be > 0, got {args.chord_tol_um}")
    if args.glyph_scale is not None and not args.glyph_scale > 0:
        raise InputError(f"--glyph-scale must be > 0, got {args.glyph_scale}")
    if args.tool_radius_mm is not None and not args.tool_radius_mm >= 0:
        raise InputError(f"--tool-radius-mm must be >= 0, got {args.tool_radius_mm}")
    if args.flank_mm is not None and not args.flank_mm >= 0:
        raise InputError(f"--flank-mm must be >= 0, got {args.flank_mm}")
    if args.range_um is not None and not args.range_um > 0:
        raise InputError(f"--range-um must be > 0, got {args.range_um}")


def _print_summary(args, smap, res) -> None:
    """What the map shows, printed: its surface or contour, its warnings and legend, the
    predicted deviation before and after, and the files written (``res``: the RenderResult)."""
    from ..viz.render import map_notes, uncorrected_legend
    from ..viz.surface import program_hints
    st = res.stats
    hints = program_hints(args.program)
    flank = args.flank_mm if args.flank_mm is not None else hints.get("flank_length_mm", 0.0)
    info = smap.info
    if smap.normal_kind == "in-plane":
        levels = info.get("levels", 0)
        print(f"contour: {len(smap.segments)} wall segments in {levels or 'no'} plane"
              f"{'' if levels == 1 else 's'} across the tool axis (in-plane map"
              + ("" if args.normal == "in-plane" else ": a planar program; --normal surface maps "
                 "the deviation along the tool axis instead") + ")")
        if info.get("clearing_moves"):
            print(f"  {info['clearing_moves']} moves with cut path on both sides (raster or "
                  "offset passes clearing material: no wall) left out")
        along = "along the contour's normal in its plane"
    elif smap.normal_kind == "holes":
        how = ("drilling cycles" if info.get("drilling_cycles") else "plunges along the tool axis, "
               "consecutive ones at one place (a hole's pecks) one hole")
        print(f"holes: {st['n_points']} ({how}); the map shows each hole's position error across "
              "the tool axis, its direction as an arrow")
        along = None
    elif smap.normal_kind == "path":
        print(f"path: {len(smap.segments)} feed moves drawn as lines in space"
              + ({True: " (no surface: most of the tool-tip surface would be walls seen "
                        "edge-on)",
                  "tool axis": " (no surface seen along one axis: the tool axis turns against the "
                               "part, a 5-axis program)"}.get(info.get("path_segments"), ""))
              + "; the map shows the size of the deviation across the path")
        along = "across the path: its size"
    else:
        what = f"flank contact lines, {flank:g} mm" if flank > 0 else "tool-tip surface"
        print(f"surface: {st['n_points']} points, {st['n_triangles']} triangles ({what}"
              + (f"; recognised the {hints['part']}" if hints else "") + ")")
        if info.get("steep_triangles"):
            print(f"  {info['steep_triangles']} triangles steeper than 80 deg left out (walls seen "
                  "from above: slivers between their levels; --normal in-plane maps a wall)")
        along = "along the surface normal"
    for line in map_notes(smap):
        print(line)
    for line in uncorrected_legend(smap):
        print(f"{line}: drawn grey, marked")
    if along is None:
        for key, label in (("before", "before"), ("after", "after: ")):
            if f"rms_{key}_um" in st:
                print(f"model prediction {label} hole position RMS {st[f'rms_{key}_um']:.3f} um, "
                      f"max {st[f'max_{key}_um']:.3f} um; depth RMS "
                      f"{st[f'depth_rms_{key}_um']:.3f} um, max {st[f'depth_max_{key}_um']:.3f} um")
        return
    print(f"model prediction before: RMS {st['rms_before_um']:.3f} um, max {st['max_before_um']:.3f} "
          f"um (deviation {along})")
    if "rms_after_um" in st:
        print(f"model prediction after:  RMS {st['rms_after_um']:.3f} um, max "
              f"{st['max_after_um']:.3f} um")

"""The command-line commands, one module each (``add_arguments`` and ``run``), and what they share."""
from __future__ import annotations

import sys

import numpy as np


def note_outside_travel(machine, datasets) -> None:
    """Tell the user (stderr, one line each) of readings beyond the machine's travel, of what the files
    carry beyond what mtcomp reads (columns it does not read, a points file without tool_mm, values
    that look like mm under *_um columns: mtcomp.measurement.columns), and of velocity files read in
    the bed's sense or of an axis that carries the tool."""
    from ..measurement.columns import file_notes
    from ..measurement.readings import positions_by_file
    # each file's axis positions and which of them it gives, worked out once for both checks
    files = [(data, q, _given(data, machine, q)) for data, q in positions_by_file(machine, datasets)]
    for note in (outside_travel(machine, files) + file_notes(machine, datasets)
                 + static_at_zero(machine, files, _angular_fitted(datasets))):
        print(f"note: {note}", file=sys.stderr)
    for d in datasets:
        if getattr(d, "bed_sense", False):
            print(f"note: {d.path}: every velocity along the moving axis is minus the "
                  "feed signed by dir_<axis>: read as the table's own motion (the bed's sense) and "
                  "taken in the axis's sense (negated)", file=sys.stderr)
        tool_side = sorted({a for a in getattr(d, "axis", ()) if getattr(d, "kind", "") == "velocity"
                            and a in machine.axis_names and machine.axis(a).side == "tool"})
        if tool_side:
            print(f"note: {d.path}: on {machine.name} axis {', '.join(tool_side)} "
                  "carries the tool, not the table: M and N are read as points of its carriage "
                  "(Yang et al.'s two-point method measures a table: check the machine file's "
                  "topology if the file is of a table)", file=sys.stderr)


def _angular_fitted(datasets):
    """axis -> whether a fit of ``datasets`` takes angular errors of that axis: a laser file names
    one (pitch, yaw or roll of the axis), or a volumetric file (points, ball bar, CMM) is among them,
    which with runs at other positions determines them (mtcomp.identification.unmeasured)."""
    from ..identification.unmeasured import angular_motion, named_components, volumetric
    data = [getattr(d, "data", d) for d in datasets]
    named, vol = named_components(data), volumetric(data)
    return lambda axis: vol or any(angular_motion(g) and g.startswith(f"{axis}:") for g in named)


def _given(data, machine, q) -> np.ndarray:
    """(n, n_axes) bool: the positions of ``q`` the file gives (a laser file's static axes without a
    column are not its own)."""
    return (data.positions_given(machine) if hasattr(data, "positions_given")
            else np.ones(q.shape, dtype=bool))


def static_at_zero(machine, files, angular) -> list[str]:
    """One sentence per laser file that gives, in no row, the position of a linear axis of the
    machine it does not move (no ``x_mm``/``y_mm``/``z_mm`` column, or every cell blank) while another
    file places that axis elsewhere than 0, when ``angular(axis)`` says the fit takes angular errors
    of the file's moving axis: the run is taken at 0 on that axis, which sets the Abbe arms through
    which those errors act on its readings. A file alone (an ISO 230-2 run), or positioning runs
    alone, get none: no other reading ties the arms to anything, or no angular error acts through
    them. ``files``: (data, axis positions (n, n_axes), which of them the file gives) per file."""
    names = machine.axis_names
    linear = [a.name for a in machine.axes if not a.is_rotary]
    spans = []                      # (data, given (n, n_axes), axis -> (lowest, highest) nonzero given)
    for data, q, given in files:
        at = {a: q[given[:, names.index(a)], names.index(a)] for a in linear}
        spans.append((data, given, {a: (float(v.min()), float(v.max())) for a, v in at.items()
                                    if np.any(np.abs(v) > 1e-3)}))
    notes = []
    for data, given, _ in spans:
        if getattr(data, "kind", "") != "laser":
            continue
        moving = sorted(set(np.asarray(data.axis).tolist()))
        if not any(angular(a) for a in moving):
            continue
        others = [p for d, _, p in spans if d is not data]
        zero = {a: [p[a] for p in others if a in p] for a in linear
                if a not in moving and not given[:, names.index(a)].any()}
        zero = {a: r for a, r in zero.items() if r}
        if not zero:
            continue
        span = {a: (min(lo for lo, _ in r), max(hi for _, hi in r)) for a, r in zero.items()}
        where = ", ".join(f"{a} {lo:g} mm" if lo == hi else f"{a} {lo:g} to {hi:g} mm"
                          for a, (lo, hi) in span.items())
        cols = ", ".join(f"{a.lower()}_mm" for a in zero)
        notes.append(f"{data.path}: no column {cols}: the run is taken at "
                     f"{', '.join(f'{a} = 0' for a in zero)} in every row, where the other files place "
                     f"{'it' if len(zero) == 1 else 'them'} ({where}); those positions are the Abbe arms "
                     f"through which the angular errors of {'/'.join(moving)} (pitch, yaw) act on its "
                     f"readings: give {cols} (where the run was made)")
    return notes


def outside_travel(machine, files) -> list[str]:
    """One sentence per (file, axis) whose rows take the axis beyond the machine's travel (1 um, 1e-6
    deg): data of another machine, or a wrong travel (not an error: a travel may be nominal). A rotary
    axis only when its travel is less than a turn, each angle taken in the turn from its lower end.
    ``files``: (data, axis positions (n, n_axes), which of them the file gives) per file."""
    notes = []
    for data, q, given in files:
        for j, ax in enumerate(machine.axes):      # rotary: radians inside, degrees told
            scale = np.degrees(1.0) if ax.is_rotary else 1.0
            lo, hi = (t * scale for t in ax.travel)
            v = q[:, j] * scale
            if ax.is_rotary and hi - lo >= 360.0:
                continue
            tol, unit = (1e-6, "deg") if ax.is_rotary else (1e-3, "mm")
            # the turn from just below the lower end: an angle a hair under it stays under it
            v = (lo - tol) + np.mod(v - lo + tol, 360.0) if ax.is_rotary else v
            out = np.flatnonzero(given[:, j] & ((v < lo - tol) | (v > hi + tol)))
            if out.size:
                v = q[out, j] * scale
                why = ("a travel_deg written in radians?" if ax.is_rotary and max(abs(lo), abs(hi))
                       <= 6.3 else "data of another machine, or a machine file whose travel is wrong?")
                notes.append(f"{data.path}: {out.size} row(s) take {ax.name} to {v.min():.6g}.."
                             f"{v.max():.6g} {unit}, outside the machine's travel {lo:.6g}..{hi:.6g} "
                             f"{unit} ({why})")
    return notes


def add_offset_arguments(parser, offsets_help: str, work_offset_help: str) -> None:
    """``--offsets OFFSETS.toml``, ``--work-offset G54=X..,Y..,Z..`` and ``--tool-length H1=L``
    (both repeatable): where the program's zero sits on the machine and how long its tools are
    (docs/toolpaths.md); compensate and render take the same, so that a map shows the program
    compensate planned."""
    parser.add_argument("--offsets", metavar="OFFSETS.toml", default=None, help=offsets_help)
    parser.add_argument("--work-offset", metavar="G54=X..,Y..,Z..", action="append", default=[],
                        help=work_offset_help)
    parser.add_argument("--tool-length", metavar="H1=L", action="append", default=[],
                        help="length (mm) of the tool of G43 H1, or of a tool a Sinumerik program "
                             "calls by name: --tool-length \"DRILL 8.5=123.4\" for "
                             "T=\"DRILL 8.5\" (repeatable; wins over --offsets)")


#: the controllers whose rules differ, for ``--dialect`` (docs/toolpaths.md)
DIALECT_CHOICES = ("linuxcnc", "fanuc", "haas", "grbl", "heidenhain", "sinumerik", "rrf",
                   "beagleg", "generic")


def add_probed_arguments(parser, temperature_help: str, rpm_help: str) -> None:
    """``--probed-at-temperature`` and ``--probed-at-spindle-rpm``: the thermal state when the
    part's datum was probed (compensate and render take them alike)."""
    parser.add_argument("--probed-at-temperature", metavar="NAME=DEGC", action="append", default=[],
                        help=temperature_help)
    parser.add_argument("--probed-at-spindle-rpm", type=float, metavar="RPM", default=None,
                        help=rpm_help)


def add_dialect_argument(parser) -> None:
    """``--dialect``: the controller that runs the program (default: detected from it)."""
    parser.add_argument("--dialect", choices=DIALECT_CHOICES, default=None,
                        help="the controller that runs the program, for the rules that differ "
                             "between controllers (G80, G98, LinuxCNC O-words and parameters, Fanuc "
                             "macro B, Heidenhain conversational, Siemens Sinumerik, "
                             "RepRapFirmware's macro codes, BeagleG's parameters and arcs; see "
                             "docs/toolpaths.md). Default: "
                             "detected from the program (generic when nothing in it names a "
                             "controller)")


def add_cmm_arguments(parser) -> None:
    """``--cmm-program`` and ``--cmm-tool-radius``: what cut the part of a cmm file (docs/measurements.md)."""
    parser.add_argument("--cmm-program", metavar="[CMM.csv=]PART.nc", action="append", default=[],
                        help="the G-code that cut the part a cmm file measured (its cutter locations "
                             "say which pose made each surface point); CMM.csv= may be left out when "
                             "one cmm file is given; repeat for several")
    parser.add_argument("--cmm-tool-radius", metavar="[CMM.csv=]MM", action="append", default=[],
                        help="the radius of the ball-end tool that cut it, mm")
    parser.add_argument("--cmm-path-offset", action="store_true",
                        help="the programs' ball centres sit off the nominal surface by more than "
                             "the machine's errors (a compensated program): that offset along each "
                             "point's normal is part of what was cut (points on the passes)")
    add_offset_arguments(parser, "work offsets (G54 ...) and tool lengths (H1 ...) of the programs "
                         "of --cmm-program, as compensate takes them; see docs/toolpaths.md",
                         "a work offset of the programs of --cmm-program: where their zero sat in "
                         "machine axis positions when they cut the part (mm; repeatable; wins over "
                         "--offsets)")


def _split_file_value(value: str, data_paths) -> tuple[str | None, str]:
    """``CMM.csv=VALUE`` -> (CMM.csv, VALUE) when the text before an '=' names one of the data files
    (a program path may hold '=' too); (None, value) otherwise."""
    from ..io.atomic import same_file
    for i, ch in enumerate(value):
        if ch == "=" and i and any(same_file(value[:i], p) for p in data_paths):
            return value[:i], value[i + 1:]
    return None, value


def cmm_programs(args) -> list[str]:
    """The program paths ``--cmm-program`` names and the ``--offsets`` file: inputs, which no output
    may overwrite."""
    return ([_split_file_value(value, args.data)[1] for value in args.cmm_program]
            + ([args.offsets] if args.offsets else []))


def attach_cmm_cuts(args, machine, datasets) -> None:
    """Give each cmm data set the cutting moves of the program ``--cmm-program`` names, read here on
    ``machine`` (the measurement model reads no G-code), and the tool radius of ``--cmm-tool-radius``
    (``CMM.csv=VALUE``, or ``VALUE`` alone when there is one cmm file). InputError (one line) for a
    flag that names no cmm file, a program that does not exist or has no cutting moves, a radius that
    is not a positive number, a value given twice, or a cmm file left without either."""
    from pathlib import Path

    from ..errors import InputError
    from ..io.atomic import same_file
    from ..toolpaths.cutter import read_cut_program
    cmm = [d for d in datasets if d.kind == "cmm"]

    def target(flag, value):
        name, rest = _split_file_value(value, [d.path for d in datasets])
        if name is None and "=" in value and not (flag == "--cmm-program" and Path(value).is_file()):
            left = value.split("=", 1)[0]
            raise InputError(f"{flag} {value}: " + (f"{left} is none of the data files" if left else
                                                    "name the cmm file before '=' (CMM.csv=...)"))
        if name is not None:
            hit = next(d for d in datasets if same_file(name, d.path))
            if hit.kind != "cmm":
                raise InputError(f"{flag} {value}: {name} is a {hit.kind} file, not a cmm file")
            return hit, rest
        if len(cmm) != 1:
            raise InputError(f"{flag} {value}: " + ("no cmm file among the data" if not cmm else
                             f"{len(cmm)} cmm files; write CMM.csv={value}"))
        return cmm[0], value

    given = set()
    programs = {}

    def once(flag, value, d):
        if (flag, id(d)) in given:
            raise InputError(f"{flag} {value}: {d.path} has its {flag[6:].replace('-', ' ')} given twice")
        given.add((flag, id(d)))

    for value in args.cmm_program:
        d, program = target("--cmm-program", value)
        once("--cmm-program", value, d)
        if not program:
            raise InputError(f"--cmm-program {value}: give the G-code file after '='")
        if Path(program).is_dir():
            raise InputError(f"--cmm-program {value}: a folder, not a G-code file", program)
        if not Path(program).is_file():
            raise InputError(f"--cmm-program {value}: no such file", program)
        programs[id(d)] = program
    for value in args.cmm_tool_radius:
        d, text = target("--cmm-tool-radius", value)
        once("--cmm-tool-radius", value, d)
        try:
            radius = float(text)
        except ValueError:
            radius = float("nan")
        if not (radius > 0 and np.isfinite(radius)):
            raise InputError(f"--cmm-tool-radius {value}: the radius must be a positive number of mm")
        d.tool_radius_mm = radius
    if args.cmm_path_offset and not cmm:
        raise InputError("--cmm-path-offset: no cmm file among the data")
    for d in cmm:
        d.include_path_offset = bool(args.cmm_path_offset)
        missing = [f for f, v in (("--cmm-program", programs.get(id(d))),
                                  ("--cmm-tool-radius", d.tool_radius_mm)) if v is None]
        if missing:
            raise InputError(f"a cmm file is read with the G-code that cut the part and the radius of "
                             f"its ball-end tool: give {' and '.join(missing)}", d.path)
    setup = _cut_setup(args, machine, bool(cmm))
    for d in cmm:
        d.cut = read_cut_program(programs[id(d)], machine, setup)


def _cut_setup(args, machine, any_cmm: bool):
    """The work offsets and tool lengths of the cut programs (``--offsets``, ``--work-offset``,
    ``--tool-length``: compensate's options, :func:`mtcomp.toolpaths.offsets.load_setup`); None
    when none is given. InputError when one is given but no cmm file is among the data."""
    from ..errors import InputError
    from ..toolpaths.offsets import load_setup
    given = [f for f, v in (("--offsets", args.offsets), ("--work-offset", args.work_offset),
                            ("--tool-length", args.tool_length)) if v]
    if not given:
        return None
    if not any_cmm:
        raise InputError(f"{given[0]}: the offsets are those of the program that cut a cmm part "
                         "(--cmm-program), and no cmm file is among the data")
    return load_setup(machine, args.offsets, args.work_offset, args.tool_length)


#: a cmm file's points lying further than this (mm, median along their normals) from the ball-centre
#: path of the program that cut them get a note: the radius or the part's placement is off
CMM_GAP_NOTE_MM = 0.05


def note_cmm_gaps(machine, datasets) -> None:
    """Tell the user (stderr) of a cmm file whose points sit off the program's ball-centre path along
    their normals: a wrong ``--cmm-tool-radius`` (a wall cut with a 3 mm ball read as 4 mm lies 1 mm
    off) or a part not where the program put it. Not an error: the fit would take a radius offset."""
    from ..measurement.cut import cut_poses, path_offsets
    for d in datasets:
        if d.kind != "cmm" or d.cut is None or d.tool_radius_mm is None or not len(d):
            continue
        radius = float(d.tool_radius_mm)
        q = cut_poses(machine, d, d.cut, radius)[0]
        med = -float(np.median(path_offsets(machine, d, q, radius)))   # points off the path, mm
        if abs(med) > CMM_GAP_NOTE_MM:
            print(f"note: {d.path}: the points lie a median {med:+.3f} mm off the "
                  f"ball-centre path of {d.cut.path} along their normals: is the tool radius "
                  f"{d.tool_radius_mm:g} mm right (it would be {d.tool_radius_mm - med:.3g} mm), and the "
                  "part where the program put it?", file=sys.stderr)

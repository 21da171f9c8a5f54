"""`mtcomp diagnose MACHINE DATA... --json REPORT.json [-o MODEL.json] [--start MODEL.json]`.

Fits the base model to every DATA file, finds what it gets wrong (residual analysis against every
context the data carry), extends it with the effects that earn their place on held-out data, and
reports the gain. The printed report is for a metrologist (findings, the final model's error
components per axis, residuals per file and per laser target; --verbose adds its parameters);
REPORT.json has the keys of docs/diagnose.md; MODEL.json is the extended model (read by compensate,
predict and render). Progress lines go to stderr. Outputs are written atomically, and only after the
whole diagnosis succeeded. docs/diagnose.md.
"""
from __future__ import annotations

from . import add_cmm_arguments


def add_arguments(parser):
    parser.add_argument("machine", metavar="MACHINE", help="built-in machine name or machine TOML file")
    parser.add_argument("data", metavar="DATA", nargs="+",
                        help="measurement files (points, laser, ballbar, thermal, ...: docs/measurements.md)")
    parser.add_argument("--json", metavar="REPORT.json", required=True,
                        help="where to write the report (verdict, noise_um, base, findings, final)")
    parser.add_argument("-o", "--output", metavar="MODEL.json", default=None,
                        help="also write the extended model (base model plus the terms found)")
    parser.add_argument("--start", metavar="MODEL.json", default=None,
                        help="start from this model of the machine (e.g. identify's output): its base "
                             "(knots, harmonics) is diagnosed and its values start the fit")
    parser.add_argument("--known-setup", metavar="FILE", action="append", default=[],
                        help="a data file whose set-up is known (repeatable): a ball-bar file of a "
                             "calibrated bar, a points or cmm file whose instrument frame is the "
                             "machine's; as identify's --known-setup. Without it, the files --start's "
                             "model was fitted with a known set-up")
    parser.add_argument("--channel-axis", metavar="NAME=AXIS", action="append", default=[],
                        help="thermal file: channel disp_NAME_um reads the tool tip along machine axis "
                             "AXIS (X, Y or Z), so its drift acts where compensation needs it "
                             "(repeatable; channels named x, y, z, or named in a column axis_NAME "
                             "of the file, need none)")
    parser.add_argument("--plot", metavar="DRIFT.png", default=None,
                        help="thermal file: draw each channel's drift over time, measured and "
                             "predicted forward in time (ISO 230-3 style)")
    add_cmm_arguments(parser)
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress lines on stderr")
    parser.add_argument("-v", "--verbose", action="store_true",
                        help="also print every parameter of the final model (value and standard "
                             "error), those the data do not determine, and the per-target table of "
                             "laser components with many targets")


def run(args) -> int:
    import json
    import sys

    from ..diagnose import diagnose
    from ..errors import InputError
    from . import attach_cmm_cuts, cmm_programs, note_cmm_gaps, note_outside_travel
    from ..io.atomic import atomic_write, check_distinct_inputs, check_output_path
    from ..measurement.files import read_measurements
    from ..machine import load_machine
    from ..models.model_file import _json_default, save_model

    check_distinct_inputs(args.data)
    inputs = list(args.data) + ([args.start] if args.start else []) + cmm_programs(args)
    report_path = check_output_path(args.json, inputs)
    model_path = check_output_path(args.output, inputs) if args.output else None
    plot_path = check_output_path(args.plot, inputs, ".png", "--plot") if args.plot else None
    outputs = [p.resolve() for p in (report_path, model_path, plot_path) if p is not None]
    if len(set(outputs)) < len(outputs):
        raise InputError("--json, -o and --plot must name different files", args.json)
    channel_axes = {}
    for item in args.channel_axis:
        name, sep, axis = item.partition("=")
        if not sep or not name or not axis:
            raise InputError(f"--channel-axis {item!r}: write NAME=AXIS, e.g. ch3=Z")
        channel_axes[name] = axis
    machine = load_machine(args.machine)
    start = None
    if args.start:
        from ..models.model_file import load_model
        start = load_model(args.start, machine)
    datasets = [read_measurements(path) for path in args.data]
    if start is not None and len(datasets) == 1 and datasets[0].kind == "thermal":
        raise InputError("--start applies to geometric data; a thermal file alone is diagnosed on its own",
                         args.start)
    known_setup = _known_setup(args, start, datasets)
    attach_cmm_cuts(args, machine, datasets)
    note_outside_travel(machine, datasets)
    note_cmm_gaps(machine, datasets)

    def progress(line):
        if not args.quiet:
            print(f"diagnose: {line}", file=sys.stderr, flush=True)

    if len(datasets) == 1 and datasets[0].kind == "thermal":
        # a thermal record alone: drift models validated forward in time (docs/thermal.md)
        from ..thermal import diagnose_thermal
        result = diagnose_thermal(machine, datasets[0], channel_axes or None, progress)
    elif sum(d.kind == "thermal" for d in datasets) == 1:
        # a thermal record beside geometric files: each on its own path, one report and one model
        from ..thermal import diagnose_with_record
        result = diagnose_with_record(machine, datasets, channel_axes or None, progress, start,
                                      known_setup)
    else:
        result = diagnose(machine, datasets, progress=progress, channel_axes=channel_axes or None,
                          start=start, known_setup=known_setup)
    if plot_path is not None and result.thermal is None:
        raise InputError("--plot draws the drift of one thermal file; the data are not one thermal file",
                         args.data[0])
    if getattr(result, "sign_note", None):
        print(f"warning: {result.sign_note}", file=sys.stderr)
    result.model.info["command"] = "mtcomp diagnose " + " ".join(sys.argv[2:]) if len(sys.argv) > 2 \
        else "mtcomp diagnose"
    print(result.summary(details=_details(result, machine, datasets, args.verbose)))
    report = result.to_dict()
    report["seconds"] = round(result.seconds, 3)
    report["files"] = [str(p) for p in args.data]
    with atomic_write(report_path) as f:
        json.dump(report, f, indent=1, default=_json_default)
        f.write("\n")
    print(f"\nwrote {report_path}")
    if model_path is not None:
        save_model(model_path, result.model)
        print(f"wrote {model_path}")
    if plot_path is not None:
        from ..thermal.plot import plot_drift
        with atomic_write(plot_path, "wb") as f:
            plot_drift(result.thermal, f)
        print(f"wrote {plot_path}")
    return 0


def _details(result, machine, datasets, verbose: bool) -> list[str]:
    """The final model in a metrologist's terms (mtcomp.identification.report): its error components
    per axis, the rms residual of every file and the laser readings per target; with ``verbose`` its
    parameters. Nothing for a thermal record alone, whose drift model has no axis errors; beside
    geometric files, of those files."""
    datasets = [d for d in datasets if d.kind != "thermal"]
    if not datasets:
        return []
    from ..identification.predict import predict_readings
    from ..identification.report import (component_lines, file_rms_lines, laser_target_tables,
                                         parameter_lines)
    # geometric files carry no thermal state: predicted without the drift a record beside them
    # brought (at the record's mean temperatures it would shift every file by a constant)
    model = result.model.without_drift()
    predictions = [predict_readings(model, d, machine) for d in datasets]
    excluded = [(o.path, o.row, o.column) for o in result.outliers]
    lines = [""] + component_lines(model) + [""]
    lines += ["final model's residuals" + (" (outliers left out)" if excluded else "") + ":"]
    lines += file_rms_lines(model, datasets, machine, excluded, predictions)
    targets = laser_target_tables(model, datasets, machine, verbose, predictions)
    if targets:
        lines += [""] + targets
    if verbose:
        lines += [""] + parameter_lines(model)
    return lines + [""]


def _known_setup(args, start, datasets) -> list:
    """The files whose set-up is known: ``--known-setup``'s, else those the start model was fitted
    with a known set-up (identify's ``--known-setup``, recorded in the model), said once."""
    import sys

    from ..identification.problem import unique_tags
    if args.known_setup or start is None:
        return list(args.known_setup)
    recorded = set(start.info.get("known_setup", ()))
    known = [t for t in unique_tags(datasets) if t in recorded]
    if known:
        print(f"note: the set-up of {', '.join(known)} taken as known, as the start model was fitted "
              "(--known-setup); give --known-setup to choose", file=sys.stderr)
    return known

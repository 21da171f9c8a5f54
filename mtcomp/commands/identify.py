"""`mtcomp identify MACHINE DATA... -o MODEL.json`: fit the base error model to measurement files.

Every DATA file is read (its kind is told by its columns, docs/measurements.md), all of them are fitted at
once (:func:`mtcomp.identification.fit.identify`), the report is printed (the error components per
axis in a metrologist's terms, the residual of every file, laser readings per target; the raw
parameters with --verbose) and MODEL.json is written atomically (nothing is written on error; an
input is never overwritten). docs/identification.md.
"""
from __future__ import annotations

from . import add_cmm_arguments


def add_arguments(parser):
    parser.add_argument("machine", metavar="MACHINE", help="built-in machine name or machine TOML file")
    parser.add_argument("data", metavar="DATA", nargs="+",
                        help="measurement files (points, laser, ballbar, and any kind with a "
                             "registered measurement model)")
    parser.add_argument("-o", "--output", metavar="MODEL.json", required=True,
                        help="where to write the fitted model")
    parser.add_argument("--hold", metavar="NAME", action="append", default=[],
                        help="hold parameters at zero (repeat, or give a comma-separated list): a "
                             "name (EAX_b3), a component (EAX: all its terms), an axis letter (X: all "
                             "its errors), or squareness, spindle, C:location ...; e.g. --hold "
                             "X,Y,Z,squareness for axes a controller already compensates")
    parser.add_argument("--weights", choices=("unit", "noise"), default="unit",
                        help="unit: every residual in um or urad, with one noise per unit (um, "
                             "urad) estimated from the fit's residuals when the data hold both "
                             "(default); noise: one noise per file and unit")
    parser.add_argument("--known-setup", metavar="FILE", action="append", default=[],
                        help="a file whose set-up is known: a points or cmm file whose instrument "
                             "frame is the workpiece frame (no set-up translation and rotation is "
                             "fitted), or a ball-bar file of a calibrated bar (no length offset is "
                             "fitted); repeat for several")
    add_cmm_arguments(parser)
    parser.add_argument("-v", "--verbose", action="store_true",
                        help="also print every parameter (value and standard error), the files' "
                             "set-ups, the combinations the data cannot determine, and the per-target "
                             "table of laser components with many targets")
    parser.add_argument("--rcond", type=float, default=None, metavar="R",
                        help="relative singular value below which a combination of parameters counts "
                             "as undetermined and is held at zero (default 1e-6)")


def run(args) -> int:
    import sys

    from ..errors import InputError
    from ..identification.fit import DEFAULT_RCOND, identify
    from . import attach_cmm_cuts, cmm_programs, note_cmm_gaps, note_outside_travel
    from ..io.atomic import check_distinct_inputs, check_output_path
    from ..measurement.files import read_measurements
    from ..machine import load_machine
    from ..models.model_file import save_model

    check_distinct_inputs(args.data)
    out = check_output_path(args.output, list(args.data) + cmm_programs(args))
    machine = load_machine(args.machine)
    hold = [h.strip() for item in args.hold for h in item.split(",") if h.strip()]
    rcond = DEFAULT_RCOND if args.rcond is None else args.rcond
    if not (0.0 < rcond < 1.0):
        raise InputError(f"--rcond must lie between 0 and 1, got {rcond}")
    datasets = [read_measurements(path) for path in args.data]
    attach_cmm_cuts(args, machine, datasets)
    note_outside_travel(machine, datasets)
    note_cmm_gaps(machine, datasets)
    for data in datasets:
        if data.kind == "velocity":
            print(f"note: {data.path}: identify fits the machine's base model, which "
                  "has no instantaneous rotation centre: the yaw's centre and its motion with "
                  "position and feed, which these velocities measure, go into the other errors; "
                  "mtcomp diagnose with the same files tests the centre's terms and adds those the "
                  "data support (docs/diagnose.md)", file=sys.stderr)
    result = identify(machine, datasets, hold=hold, weights=args.weights, rcond=rcond,
                      known_setup=list(args.known_setup),
                      info={"command": "mtcomp identify " + " ".join(sys.argv[2:]) if len(sys.argv) > 2
                            else "mtcomp identify"})
    save_model(out, result.fitted_model)      # before printing: a closed pipe must not lose it
    if not result.converged:
        print(f"warning: {_not_converged_note(result)}", file=sys.stderr)
    from ..identification.agreement import disagreement_note
    disagree = disagreement_note(result, datasets)
    if disagree:
        print(f"warning: {disagree}", file=sys.stderr)
        from ..identification.signflip import reversed_sign_note
        flipped = reversed_sign_note(result, datasets, result.problem)
        if flipped:
            print(f"warning: {flipped}", file=sys.stderr)
    from ..identification.report import component_lines, laser_target_tables
    components = component_lines(result.fitted_model)
    print(result.summary(verbose=args.verbose, components=components,
                         targets=laser_target_tables(result.fitted_model, datasets, machine,
                                                     verbose=args.verbose)))
    from ..export import reversal_note
    # the report's --hold hint (identification.report.hold_hint) again where the run ends
    hint = next((line.strip()[len("hint: "):] for line in components if line.strip().startswith("hint: ")),
                None)
    for note in (reversal_note(result.fitted_model), _weights_note(result, args.weights), hint):
        if note:
            print(f"note: {note}")
    print(f"\nwrote {out}")
    return 0


#: files whose rms residuals (um) differ by more than this factor under one shared variance get a note
WEIGHTS_NOTE_RATIO = 3.0


def _weights_note(result, weights: str) -> str | None:
    """One line when, under ``--weights unit`` (one residual variance for every file's readings in
    um), the files' rms residuals in um differ by more than :data:`WEIGHTS_NOTE_RATIO`: the standard errors of what
    the quieter files fix are then too large; ``--weights noise`` gives each file its own."""
    if weights != "unit":
        return None
    rms = {tag: max(v for c, v in cols.items() if c.endswith("_um"))
           for tag, cols in result.rms().items() if any(c.endswith("_um") for c in cols)}
    rms = {t: v for t, v in rms.items() if v > 0}
    if len(rms) < 2 or max(rms.values()) <= WEIGHTS_NOTE_RATIO * min(rms.values()):
        return None
    loud, quiet = max(rms, key=rms.get), min(rms, key=rms.get)
    return (f"the files' rms residuals differ ({loud} {rms[loud]:.3g} um, {quiet} {rms[quiet]:.3g} "
            "um): with --weights unit one residual variance serves every file's um, so the standard "
            "errors of what the quieter files fix are too large; --weights noise weights each file "
            "by its own noise")


def _not_converged_note(result) -> str:
    """What a fit that did not converge left unsettled, and what a user can do about it."""
    moved = (result.unsettled or {}).get("moved", [])
    what = ", ".join(f"{name} by {step:.3g} {unit}" + (f" ({k:.2g} standard errors)" if k == k else "")
                     for name, step, unit, k in moved)
    share = (result.unsettled or {}).get("share", float("nan"))
    stands = " (a tenth of their standard errors at most: it stands)" if moved and all(
        k < 0.1 for *_, k in moved) else ""
    return (f"the fit did not converge in {result.iterations} iterations: its last step still moved "
            f"{what or 'the unknowns'} and took {share:.2g} of the weighted residual sum; the model "
            f"written is that of the last step{stands}. The model is nearly linear in its parameters, "
            "so an effect it lacks (a backlash, a periodic error: mtcomp diagnose names them) leaves "
            "residuals but should not keep the fit from settling: fix the parameters that keep "
            "moving (--hold NAME)")

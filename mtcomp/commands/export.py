"""`mtcomp export MACHINE MODEL.json --format FORMAT -o OUT`: the controller's own compensation tables.

The model is evaluated on a grid of each axis over the region its data reached (clipped by
``--range``), the component errors are written in the controller's format, and a README beside the
tables (and the summary on stderr) says how to load them, the limits and signs, and what of the model
the controller cannot hold. docs/export.md.
"""
from __future__ import annotations

FORMAT_HELP = {
    "linuxcnc": "COMP_FILE per joint (+ ini lines, matrixkins squareness); OUT: a directory",
    "siemens": "Sinumerik LEC %_N_AX_EEC_INI and CEC %_N_NC_CEC_INI; OUT: a directory",
    "heidenhain": "TNC axis error compensation .COM tables and the .CMA; OUT: a directory",
    "fanuc": "pitch error compensation parameter list; OUT: a directory",
    "isg": "Beckhoff/ISG TF5280 volumetric compensation CSV; OUT: a directory",
    "klipper": "[skew_correction] profile; OUT: one file",
}


def add_arguments(parser):
    from ..export import FORMAT_NAMES
    from ..planner.problem import DEFAULT_MAX_CORRECTION_SD_UM
    parser.add_argument("machine", metavar="MACHINE", help="built-in machine name or machine TOML file")
    parser.add_argument("model", metavar="MODEL.json", help="fitted model (identify or diagnose)")
    parser.add_argument("--format", required=True, choices=FORMAT_NAMES,
                        help="; ".join(f"{k}: {v}" for k, v in FORMAT_HELP.items()).replace("%", "%%"))
    parser.add_argument("-o", "--output", metavar="OUT", required=True,
                        help="output directory (file for klipper); files of the same names in an "
                             "existing directory are replaced")
    parser.add_argument("--grid-mm", type=float, default=None, metavar="STEP",
                        help="grid step of linear axes in mm (default: the smallest of 1, 2, 2.5, 5 "
                             "x 10^k mm, at least 1 mm, that fits the controller's point limit)")
    parser.add_argument("--grid-deg", type=float, default=None, metavar="STEP",
                        help="grid step of rotary axes in deg (default as --grid-mm)")
    parser.add_argument("--range", metavar="AXIS=LO:HI", action="append", default=[],
                        help="clip the table of AXIS to LO..HI (mm or deg); repeat per axis")
    parser.add_argument("--at", metavar="AXIS=POS[,AXIS=POS]", action="append", default=[],
                        help="where the other axes stand while each axis's table is read (mm, or "
                             "deg for a rotary axis), e.g. Z=-200,X=-300 (default: each linear axis "
                             "at the middle of its data, a rotary axis at its reference position)")
    parser.add_argument("--max-points", type=int, default=None, metavar="N",
                        help="points per table the controller holds (default per format: linuxcnc "
                             "256, siemens 125, heidenhain 256, fanuc 128, isg 1024)")
    parser.add_argument("--comp-type", type=int, choices=(0, 1), default=1,
                        help="linuxcnc COMP_FILE_TYPE: 1 trims (default), 0 actual positions")
    parser.add_argument("--sign", choices=("correction", "error"), default=None,
                        help="siemens CEC, heidenhain, fanuc: enter the correction (minus the error, "
                             "the default) or the error itself; these signs are not public, check "
                             "one point on the machine")
    parser.add_argument("--max-correction-sd-um", type=float, default=None, metavar="UM",
                        help="an axis whose correction's standard error (the model's covariance) "
                             "exceeds UM um anywhere on its table, or none of whose values is told "
                             "from zero by it (within two of them), gets no table, as compensate "
                             f"leaves such blocks uncorrected (default {DEFAULT_MAX_CORRECTION_SD_UM:g}; "
                             "0: no limit, and neither rule)")
    parser.add_argument("--fanuc-unit-um", type=float, default=1.0, metavar="U",
                        help="fanuc detection unit in um (default 1)")
    parser.add_argument("--fanuc-max-value", type=int, default=127, metavar="V",
                        help="fanuc: largest magnitude of one pitch error value (default 127; "
                             "depends on the series)")


def run(args) -> int:
    import math
    import sys

    from ..errors import InputError
    from ..export import (component_tables, exporter, parse_ranges, plan_grids, table_region,
                          write_result)
    from ..export._ends import points_inside
    from ..export._output import ONE_POSE, left_out
    from ..export._tables import parse_pose, reference_positions, table_pose
    from ..machine import load_machine
    from ..models.model_file import load_model
    from ..planner.problem import DEFAULT_MAX_CORRECTION_SD_UM

    machine = load_machine(args.machine)
    model_notes: list = []
    fitted = load_model(args.model, machine, model_notes)
    rest = _left_to_compensate(fitted)
    for n in model_notes:
        sys.stderr.write(f"note: {n}\n")
    fmt = exporter(args.format)
    max_points = fmt.MAX_POINTS if args.max_points is None else args.max_points
    if max_points < 2:
        raise InputError(f"--max-points must be at least 2, got {max_points}")
    if args.fanuc_max_value < 1:
        raise InputError(f"--fanuc-max-value must be a positive whole number, got {args.fanuc_max_value}")
    ranges = parse_ranges(args.range, machine)
    region, source, notes = table_region(fitted, ranges)
    volume = dict(region)
    if fmt.LINEAR_ONLY:
        for a in list(region):
            if machine.axis(a).is_rotary:
                del region[a]
    anchors = reference_positions(machine) if getattr(fmt, "ANCHOR_AT_REFERENCE", False) else None
    grids = plan_grids(machine, region, max_points, args.grid_mm, args.grid_deg, fmt.INCLUDE_END,
                       what=args.format, anchors=anchors)
    for a in [a for a, g in grids.items() if points_inside(g, *region[a]) < 2]:
        del grids[a]
        notes.append(f"axis {a}: no table: its region is shorter than one grid step")
    sd_limit = DEFAULT_MAX_CORRECTION_SD_UM if args.max_correction_sd_um is None else args.max_correction_sd_um
    if not (sd_limit >= 0 and math.isfinite(sd_limit)):
        raise InputError(f"--max-correction-sd-um must be 0 or a positive number, got {sd_limit:g}")
    pose = table_pose(machine, volume, parse_pose(args.at, machine))
    tables = component_tables(fitted, grids, region, notes, source, sd_limit, volume, pose)
    if not tables.tables:
        why = "; ".join(n for n in tables.notes if n.startswith("axis ")) or "no axis has a region"
        raise InputError(f"nothing to export: {why}", args.model)
    result = fmt.export(tables, comp_type=args.comp_type, sign=args.sign, unit_um=args.fanuc_unit_um,
                        max_value=args.fanuc_max_value)
    written = write_result(result, args.output, [args.model, args.machine])
    lines, worst = left_out(tables, result.carried)
    err = sys.stderr
    err.write(f"mtcomp export --format {args.format}: " + ", ".join(
        f"{a} {len(t.positions)} points" for a, t in tables.tables.items()) + "\n")
    for n in tables.notes + result.notes + rest:
        err.write(f"  note: {n}\n")
    for line in lines:
        err.write(f"  left out: {line}\n")
    for a, w in worst.items():
        err.write(f"  remaining along {a} {ONE_POSE} (largest translation the tables do not "
                  f"carry): {w * 1e3:.3f} um\n")
    single, together = result.not_carried(tables)
    for line in single:
        err.write(f"  not carried: {line}\n")
    if together is not None:
        err.write(f"  remaining over the volume from the errors not carried that the data determine, "
                  f"together: up to {together:.2f} um at the tool tip\n")
    for p in written:
        print(f"wrote {p}")
    return 0


def _left_to_compensate(fitted) -> list:
    """The notes on the model's terms no table holds. A controller's tables hold errors along the
    axes' positions (and direction), not along feed, time or temperature: the feed terms are
    evaluated at feed 0, and the drift terms are left out (:func:`mtcomp.export.component_tables`
    evaluates the model without them): a drift model's value is no error of an axis, and export
    is given no thermal state."""
    at_rest = [t.key() for t in fitted.model.terms if t.uses_feed]
    drift = [t.key() for t in fitted.model.terms if t.kind in ("thermal_drift", "channel_drift")]
    rest = [f"the tables leave out what depends on feed ({', '.join(at_rest)}): they hold the model "
            "at feed 0 (mtcomp compensate applies these terms block by block)"] if at_rest else []
    rest += [f"the tables leave out the thermal drift ({', '.join(drift)}): they hold the machine's "
             "geometry; mtcomp compensate corrects the drift since the part's datum was probed, given "
             "the temperatures while the program runs"] if drift else []
    return rest

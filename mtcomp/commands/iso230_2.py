"""`mtcomp iso230-2 LASER.csv [--json OUT.json]`: ISO 230-2 evaluation of laser positioning runs."""
from __future__ import annotations

import json


def add_arguments(parser):
    parser.add_argument("laser", metavar="LASER.csv",
                        help="laser file (SPEC 3.2) with positioning runs: component EXX, EYY, EZZ, "
                             "EAA, EBB or ECC, both directions, at least 2 runs (5 in the standard cycle)")
    parser.add_argument("--json", metavar="OUT.json", default=None,
                        help="also write the figures as JSON: one object per axis (A_um, B_um, E_um, "
                             "M_um, R_um ... ; _urad and _arcsec for rotary axes)")


def run(args) -> int:
    from ..errors import InputError
    from ..identification.iso230_2 import evaluate_iso230_2
    from ..io.atomic import atomic_write, check_output_path
    from ..measurement.files import read_measurements

    out = check_output_path(args.json, [args.laser]) if args.json else None
    data = read_measurements(args.laser)
    if data.kind != "laser":
        raise InputError(f"this is a {data.kind} file; iso230-2 needs a laser file (columns axis, "
                         "component, target_mm or target_deg, dir, run, value_um or value_urad)",
                         args.laser)
    report = evaluate_iso230_2(data)
    print(report.summary())
    if out is not None:
        with atomic_write(out) as f:
            json.dump(report.to_dict(), f, indent=2)
            f.write("\n")
        print(f"\nwrote {out}")
    return 0

"""`mtcomp iso230-2 LASER.csv... [--json OUT.json] [--plot OUT.png]`: ISO 230-2 evaluation of laser
positioning runs, file by file, with outlier readings, run-to-run drift and implausible units flagged,
and an optional plot of the runs."""
from __future__ import annotations

import json


def add_arguments(parser):
    parser.add_argument("laser", metavar="LASER.csv", nargs="+",
                        help="laser files (docs/measurements.md) with positioning runs: component EXX, EYY, EZZ, "
                             "EAA, EBB or ECC, both directions, at least 2 runs (5 in the standard "
                             "cycle); each file is evaluated on its own")
    parser.add_argument("--json", metavar="OUT.json", default=None,
                        help="also write the figures as JSON: one object per axis (A_um, B_um, E_um, "
                             "M_um, R_um ... ; _urad and _arcsec for rotary axes, 'outliers', the run "
                             "means and the drift: run_means_um, drift, drift_um ...); with "
                             "several files, one such object per file, keyed by the file name")
    parser.add_argument("--plot", metavar="OUT.png", default=None,
                        help="also draw the runs: deviation against target, each run in its own "
                             "colour, both directions, mean and +-2 s bands, outliers ringed; beside it "
                             "the run means against run number (the drift) (needs matplotlib)")


def run(args) -> int:
    from pathlib import Path

    import numpy as np

    from ..errors import InputError
    from ..identification.iso230_2 import evaluate_iso230_2, plot_runs, positioning_component
    from ..io.atomic import atomic_write, check_output_path
    from ..measurement.files import read_measurements

    out = check_output_path(args.json, args.laser) if args.json else None
    plot = check_output_path(args.plot, args.laser, ".png", "--plot") if args.plot else None
    if plot is not None:
        import importlib.util
        if importlib.util.find_spec("matplotlib") is None:
            raise InputError("--plot needs matplotlib (pip install matplotlib)", args.plot)
    if out is not None and plot is not None and out.resolve() == plot.resolve():
        raise InputError("--json and --plot name the same file", args.json)
    names = [Path(p).name for p in args.laser]
    if len(set(names)) != len(names):
        dup = next(n for n in names if names.count(n) > 1)
        raise InputError("two files of the same name; the JSON keys them by name", dup)
    reports = []
    for path in args.laser:
        data = read_measurements(path)
        if data.kind != "laser":
            raise InputError(f"this is a {data.kind} file; iso230-2 needs a laser file (columns axis, "
                             "component, target_mm or target_deg, dir, run, value_um or value_urad)", path)
        for axis in np.unique(data.axis):
            # the rows evaluated: this axis's positioning component (the others are skipped anyway)
            rows = (data.axis == axis) & (data.component == positioning_component(str(axis)))
            f = data.context.feed[rows]
            feeds = np.unique(f[np.isfinite(f)])
            if feeds.size > 1:
                raise InputError(f"runs of {axis} at {feeds.size} feeds ({', '.join(f'{v:g}' for v in feeds)} "
                                 "mm/min): ISO 230-2 evaluates one feed at a time; give each feed its own "
                                 "file (diagnose takes them all together)", path)
        reports.append(evaluate_iso230_2(data))
    print("\n\n".join(r.summary() for r in reports))
    if out is not None:
        doc = reports[0].to_dict() if len(reports) == 1 else {n: r.to_dict() for n, r in zip(names, reports)}
        with atomic_write(out) as f:
            json.dump(doc, f, indent=2)
            f.write("\n")
        print(f"\nwrote {out}")
    if plot is not None:
        plot_runs(reports, plot)
        print(f"wrote {plot}")
    return 0

"""`mtcomp study STUDY.toml -o RESULTS/`: a correction study on Dask (docs/study.md).

Every task (one compensation and its evaluation) is kept under RESULTS/tasks/ as it finishes; a
re-run computes only the tasks that are new or were not finished. RESULTS/ gets results.parquet and
results.csv (one row per task), three plots and index.html.
"""
from __future__ import annotations


def add_arguments(parser):
    parser.add_argument("study", metavar="STUDY.toml", help="what to run (docs/study.md)")
    parser.add_argument("-o", "--output", metavar="RESULTS/", required=True,
                        help="folder for the results (created; finished tasks kept in it)")
    parser.add_argument("--scheduler", metavar="tcp://HOST:8786", default=None,
                        help="run on this existing Dask cluster (its workers need mtcomp and the "
                             "study's files at the same paths) instead of a local one")
    parser.add_argument("--workers", type=int, metavar="N", default=None,
                        help="worker processes of the local cluster (default: the CPUs available)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar on stderr")


def run(args) -> int:
    from pathlib import Path

    from ..errors import InputError
    from ..study import check_study, load_study, plot_summary, run_study, write_html, write_tables

    study = load_study(args.study)
    out = Path(args.output)
    if out.exists() and not out.is_dir():
        raise InputError("-o must name a folder (it is a file)", out)
    if args.workers is not None and args.workers < 1:
        raise InputError(f"--workers must be 1 or more, got {args.workers}")
    if args.scheduler and args.workers is not None:
        raise InputError("--workers sets the local cluster's size; with --scheduler the cluster "
                         "has its own workers")
    check_study(study)
    n = len(study.tasks())
    draws = (f"{study.draws + 1} draws (the model, and {study.draws} from its covariance)"
             if study.draws else "1 model (no draws)")
    print(f"mtcomp study: {n} tasks ({len(study.programs)} programs x {len(study.models)} models x "
          f"{len(study.methods)} methods x {len(study.bounds)} bound settings x "
          f"{len(study.temperatures)} temperatures x {draws})")
    try:
        result = run_study(study, out, scheduler=args.scheduler, workers=args.workers,
                           progress=not args.quiet)
    except KeyboardInterrupt:
        import sys
        print(f"mtcomp study: interrupted; every finished task is kept in {out / 'tasks'}: run the "
              "same command again to go on", file=sys.stderr)
        return 130
    tables = write_tables(result.rows, out)
    plots = plot_summary(result.rows, out)
    page = write_html(result.rows, plots, out, f"mtcomp study: {study.path.name}")
    where = f"on {args.scheduler}" if args.scheduler else f"on {result.workers} local workers"
    computed = (f"{result.computed} computed {where}" if result.computed else
                "nothing new to compute")
    print(f"mtcomp study: {computed}, {result.cached} kept from before, {result.failed} failed; "
          f"{result.seconds:.1f} s")
    ok = [r for r in result.rows if r["status"] == "ok" and r["rms_after_um"] is not None]
    if ok:
        import numpy as np
        before = np.median([r["rms_before_um"] for r in ok])
        after = np.median([r["rms_after_um"] for r in ok])
        print(f"median over the finished tasks: rms error {before:.3f} um before, {after:.3f} um "
              "after (corrected blocks)")
    bad = [r for r in result.rows if r["status"] != "ok"]
    for r in bad[:5]:
        print(f"failed: {r['program']} ({r['model']}, {r['method']}, {r['bounds']}, "
              f"temperature {r['temperature']}, draw {r['draw']}): {r['error']}")
    if len(bad) > 5:
        print(f"... and {len(bad) - 5} more failed tasks (results.csv, index.html)")
    print(f"wrote {', '.join(str(p) for p in tables + plots + [page])}")
    return 0

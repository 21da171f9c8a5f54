"""The model `mtcomp diagnose` writes (MODEL.json), against the truth and against identify's model of
the same files, on the independent machine's campaigns of the diagnosis's truth tests (tests/truth,
which shares no code with mtcomp; tests/test_diagnose_truth.py).

For each campaign: the model diagnose wrote (identify's penalised fit of the final model: REPORT.json's
``final.written``, docs/diagnose.md, *The model written*), and the rms error
of the tool-tip deviation that model predicts, and that identify's model of the same files predicts,
against the truth's: over a grid of the region the data reach (5 positions per linear axis the data
moved; the rotary axes at 0; every axis approached in +), the mean of the difference removed (the
files' set-ups leave a constant open; ``region_error_um`` of tests/diagnose_truth.py). Last the
counts: campaigns that wrote the penalised fit, and those whose penalised fit fitted the data
clearly worse than the least squares (``fits_worse``).

    PYTHONPATH=tests python benchmarks/bench_diagnose_written.py              # every campaign
    PYTHONPATH=tests python benchmarks/bench_diagnose_written.py --only 9650 7008
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

try:
    from diagnose_truth import region_error_um, run
    from truth import FeedAbbe
    from truth.hidden import hidden_case
except ImportError:
    raise SystemExit("bench_diagnose_written: run it with tests/ on PYTHONPATH "
                     "(PYTHONPATH=tests python benchmarks/bench_diagnose_written.py)") from None

from mtcomp.identification.fit import identify
from mtcomp.machine import load_machine
from mtcomp.measurement.files import read_measurements

def campaigns() -> list:
    """(seed, effect, campaign kind, topology, hidden effect or None) of every campaign of
    tests/test_diagnose_truth.py: its parametrised cases, then its two tests of one campaign."""
    import test_diagnose_truth as t
    out = []
    for test in (t.test_rivals_the_data_do_not_tell_apart_are_not_named,
                 t.test_hidden_effect_on_the_independent_machine,
                 t.test_clean_campaign_finer_than_the_default_base_raises_no_alarm):
        names, values = next(m.args for m in test.pytestmark if m.name == "parametrize")
        for v in values:
            row = dict(zip(names.split(","), v))
            out.append((row["seed"], row.get("effect", ""), row["kind"], row["topology"], row.get("hidden")))
    return out + [(7016, "backlash", "laser", "cbfxyz", None),
                  (2, "feed_dependent_abbe", "rich", "xfyz",
                   FeedAbbe("X", angles="C", angle_gain_per_m_min=0.23, irc_shift_mm_per_m_min=(0.0, 41.0, 0.0)))]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--only", type=int, nargs="*", help="the seeds to run (default: all)")
    args = ap.parse_args(argv)
    counts = {"penalised": 0, "fits worse": 0}
    with tempfile.TemporaryDirectory() as tmp:
        for seed, effect, kind, topology, hidden in campaigns():
            if args.only and seed not in args.only:
                continue
            t0 = time.perf_counter()
            case = hidden_case(seed, effect, kind, topology, Path(tmp) / str(seed), hidden=hidden)
            d, _ = run(case)
            written = d.final.get("written") or {}
            kind_written = written.get("model", "none")
            counts[kind_written] = counts.get(kind_written, 0) + 1
            counts["fits worse"] += bool(written.get("fits_worse"))
            fit = identify(load_machine(topology), [read_measurements(p) for p in case.paths])
            err_d = region_error_um(case.machine, d.model)
            err_i = region_error_um(case.machine, fit.fitted_model)
            weak = written.get("largest_sd_um")
            print(f"{seed} {effect or 'clean'} {kind} {topology}: written {kind_written}"
                  + (f" (weakest {weak:.3g} um)" if weak is not None else "")
                  + (f"; error against the truth: diagnose {err_d:.3g} um, identify {err_i:.3g} um"
                     if np.isfinite(err_d) else "; no error against the truth: the data moved no "
                     "linear axis (region_error_um weighs the region the linear axes reach)")
                  + f" ({time.perf_counter() - t0:.0f} s)", flush=True)
    print(f"penalised fit written: {counts['penalised']}; of them fitting the data clearly worse than "
          f"the least squares: {counts['fits worse']}")


if __name__ == "__main__":
    main()

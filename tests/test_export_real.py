"""`mtcomp export --format linuxcnc` on real ISO 230-2 runs (shared/data/real; skipped when absent).

A table exported from a model fitted on runs 1-3 is applied to the held-out runs 4-5 the way
LinuxCNC applies a COMP_FILE (benchmarks/bench_export_real.py, which prints the figures). Oracles:
the pitch table built directly from runs 1-3 is recomputed from mtcomp's ISO 230-2 evaluation (its
mean unidirectional positional deviations); the target is a held-out residual within 1.1x of that
pitch table's. The figures docs/export.md quotes from the benchmark are checked against a run.
"""
import importlib.util
import re
from pathlib import Path

import numpy as np
import pytest

from mtcomp.identification.iso230_2 import evaluate_axis
from real_data import ISO230_2, ROOT

needs_real = pytest.mark.skipif(not ISO230_2.is_dir(), reason=f"real ISO 230-2 runs absent ({ISO230_2})")
#: a figure quoted in the docs and the run agree within this (um, or the ratio's own units) ...
DOC_ATOL = 0.02
#: ... or this fraction of the figure, whichever is larger
DOC_RTOL = 0.02


def _bench():
    spec = importlib.util.spec_from_file_location("bench_export_real", ROOT / "benchmarks" / "bench_export_real.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def results():
    bench = _bench()
    return {name: bench.compare(ISO230_2 / f"{name}.csv") for name in bench.FILES}


@needs_real
@pytest.mark.parametrize("name", ["ess_b02_x", "psi_mcu1025_x"])
def test_pitch_table_of_the_benchmark_is_the_iso230_2_mean_deviation(name):
    bench = _bench()
    rows = bench.read_rows(ISO230_2 / f"{name}.csv")
    train = [r for r in rows if int(r["run"]) in (1, 2, 3)]
    test = [r for r in rows if int(r["run"]) in (4, 5)]
    t, d, v = bench.arrays(train)
    iso = evaluate_axis(rows[0]["axis"], t, d, np.array([int(r["run"]) for r in train]), v)
    tt, dt, vt = bench.arrays(test)
    k = np.array([np.argmin(np.abs(iso.targets - x)) for x in tt])
    corrected = vt - np.where(dt > 0, iso.mean_up[k], iso.mean_down[k])
    np.testing.assert_allclose(bench.pitch_table_residual(train, test), corrected, rtol=0, atol=1e-9)


@needs_real
def test_exported_linuxcnc_tables_correct_held_out_runs(results):
    for name, r in results.items():
        print(f"{name}: raw {r['raw_um']:.2f} um, pitch table {r['pitch_um']:.2f} um, mtcomp identify "
              f"{r['identify_um']:.2f} um, diagnose {r['diagnose_um']:.2f} um")
        assert r["identify_um"] < r["raw_um"]
        assert r["diagnose_um"] < r["raw_um"]


@needs_real
def test_exported_table_is_within_1p1_of_a_pitch_table_from_the_same_runs(results):
    for name, r in results.items():
        assert r["diagnose_um"] <= 1.1 * r["pitch_um"], name


def _quoted_table() -> dict:
    """file -> (raw, pitch, identify, diagnose, diagnose/pitch) as docs/export.md quotes the
    benchmark's output (the text block of its section 'On real runs')."""
    doc = (ROOT / "docs" / "export.md").read_text()
    section = doc[doc.index("## On real runs"):]
    block = section[section.index("```text"):]
    block = block[:block.index("```", 7)]
    rows = {}
    for line in block.splitlines():
        m = re.match(r"(\w+)((?:\s+-?\d+\.\d+){5})\s*$", line)
        if m:
            rows[m.group(1)] = tuple(float(v) for v in m.group(2).split())
    return rows


def test_the_docs_quote_every_file_of_the_benchmark():
    # runs without the real data: the docs' table names the benchmark's files, five figures each
    assert sorted(_quoted_table()) == sorted(_bench().FILES)


@needs_real
def test_figures_quoted_in_the_docs_agree_with_a_run(results):
    for name, quoted in _quoted_table().items():
        r = results[name]
        run = (r["raw_um"], r["pitch_um"], r["identify_um"], r["diagnose_um"], r["diagnose_um"] / r["pitch_um"])
        for label, q, v in zip(("raw", "pitch", "identify", "diagnose", "diagnose/pitch"), quoted, run):
            assert abs(q - v) <= max(DOC_ATOL, DOC_RTOL * abs(v)), (
                f"docs/export.md quotes {name} {label} {q}, the benchmark gives {v:.2f}")

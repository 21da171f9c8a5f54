"""The compensation's Summary gives its rms figures as attributes (a limits study reads them from
the Python API), equal to the rms over BLOCKS.csv's evaluated rows (a second route to the figure)."""
import csv

import numpy as np

from mtcomp.compensation import CompensationSettings, compensate_program

from test_planner_core import fitted_model


def test_summary_rms_is_the_rms_of_the_blocks_written(tmp_path):
    fitted = fitted_model("xfyz", 21)
    prog = tmp_path / "p.nc"
    lines = ["G21 G90 G17", "G0 X0 Y0 Z10", "G1 Z-1 F500"]
    lines += [f"G1 X{40 * np.cos(t):.3f} Y{40 * np.sin(t):.3f}" for t in np.linspace(0, 6, 60)]
    prog.write_text("\n".join(lines + ["M2"]) + "\n")
    rep = tmp_path / "b.csv"
    run = compensate_program(fitted, prog, tmp_path / "o.nc", CompensationSettings(), report=rep)
    with open(rep, newline="") as f:
        rows = [r for r in csv.DictReader(f) if r["e_before_um"] not in ("", None)]
    before = np.array([float(r["e_before_um"]) for r in rows])
    after = np.array([float(r["e_after_um"]) for r in rows])
    s = run.summary
    assert s.evaluated == len(rows) > 50
    np.testing.assert_allclose(s.rms_before_um, np.sqrt(np.mean(before ** 2)), rtol=1e-3)
    np.testing.assert_allclose(s.rms_after_um, np.sqrt(np.mean(after ** 2)), rtol=1e-3, atol=1e-4)
    assert s.rms_after_um < s.rms_before_um
    assert s.as_dict()["rms_after_um"] == s.rms_after_um

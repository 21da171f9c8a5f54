"""A part's datum outside the region the model's data reached leaves the blocks referenced to it
uncorrected (docs/planner.md, *One datum*): every correction is the block's deviation less the
model's deviation at the datum, and there that deviation is the model carried past its data, which
no data determine.

Oracle: the independent truth machine (tests/truth) with X's positioning a sine of 8 um over a
600 mm period; a laser run of X over -100 .. 100 mm only; the part's datum G54 at X 300 mm, the
program's blocks at machine X -100 .. 100 mm (inside the data). On the truth, the datum-relative
error a correction referenced to the model's continuation at X 300 leaves is worse than none."""
import csv
import json

import numpy as np
import pytest

from mtcomp.cli import main
from truth import TruthMachine
from truth import campaigns as tc
from truth import profiles as P

DATUM_X = 300.0
#: program X (G54) of the blocks: machine X -100 .. 100 mm
PROGRAM_X = np.arange(-400.0, -199.0, 25.0)


def _truth() -> TruthMachine:
    truth = TruthMachine.zero("xfyz")
    truth.components["X"]["EXX"] = P.Sines((8e-3,), (600.0,), (2.0 * np.pi * 400.0 / 600.0,))
    return truth


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    folder = tmp_path_factory.mktemp("datum_outside")
    truth = _truth()
    laser = tc.laser(truth, folder / "lx.csv", np.random.default_rng(3), "X", components=["EXX"],
                     targets=np.arange(-100.0, 101.0, 25.0), n_runs=1,
                     static={"Y": 0.0, "Z": 0.0}, noise_um=0.05).path
    model = folder / "model.json"
    assert main(["identify", "xfyz", str(laser), "-o", str(model)]) == 0
    prog = folder / "prog.nc"
    prog.write_text("G21 G90 G17\nG54\nG0 X-400. Y0. Z0.\n"
                    + "".join(f"G1 X{x:.1f} F500\n" for x in PROGRAM_X[1:]) + "M30\n")
    return folder, model, prog, truth


def _compensate(folder, model, prog, capsys, *extra):
    out, rep, js = folder / "out.nc", folder / "blocks.csv", folder / "summary.json"
    capsys.readouterr()
    assert main(["compensate", "xfyz", str(model), str(prog), "-o", str(out), "--report", str(rep),
                 "--json", str(js), "--work-offset", f"G54=X{DATUM_X:g},Y0,Z0",
                 "--subdivide-tol-um", "0", *extra]) == 0
    with open(rep, newline="") as f:
        rows = [r for r in csv.DictReader(f) if r["x_mm"]]
    return capsys.readouterr().out, rows, json.loads(js.read_text())


def _truth_error_after_um(truth, rows) -> np.ndarray:
    """(n,) um: the truth's X error of each block as written (program X plus its correction), less
    the truth's error at the datum (what the probed offset holds)."""
    x = np.array([float(r["x_mm"]) + float(r["cx_um"] or 0.0) * 1e-3 for r in rows]) + DATUM_X
    q = np.column_stack([x, np.zeros_like(x), np.zeros_like(x)])
    at = truth.true_deviation(q)[0][:, 0] - truth.true_deviation(np.array([[DATUM_X, 0, 0]]))[0][0, 0]
    # the correction moves the axis: the tip lands at the corrected position's actual place
    return (at + (x - (np.array([float(r["x_mm"]) for r in rows]) + DATUM_X))) * 1e3


def test_a_datum_outside_the_data_leaves_the_blocks_uncorrected(campaign, capsys):
    folder, model, prog, truth = campaign
    text, rows, summary = _compensate(folder, model, prog, capsys)
    assert len(rows) == PROGRAM_X.size
    assert all(r["corrected"] == "0" and r["uncertain"] == "1" and r["correction_sd_um"] == ""
               and float(r["cx_um"]) == 0.0 for r in rows), rows
    assert summary["datum_outside_support"] == {"blocks": PROGRAM_X.size, "line": 3}
    assert summary["uncorrected"]["uncertain"] == PROGRAM_X.size
    assert summary["corrected"]["blocks"] == 0
    line = next(t for t in text.splitlines() if "the part's datum of G54" in t)
    assert line.startswith(f"{PROGRAM_X.size} blocks not corrected: the part's datum of G54 (X 300) "
                           "lies outside the region the model's data reached (X -100 .. 100 mm; "
                           "first at line 3)")
    assert "--extrapolate" in line and "measure there" in line
    # said once, among the reasons, not again as a generic unsure line
    assert "the model is unsure there" not in text
    assert text.index(line) < text.index("warning: no block was corrected")


def test_extrapolate_corrects_against_the_continuation(campaign, capsys):
    """With --extrapolate the blocks are corrected as before, referenced to the model's value at
    the datum: on the truth that makes blocks worse (why it is not the default)."""
    folder, model, prog, truth = campaign
    text, rows, summary = _compensate(folder, model, prog, capsys, "--extrapolate")
    assert all(r["corrected"] == "1" for r in rows)
    assert summary["datum_outside_support"]["blocks"] == 0
    assert "note: the part's datum of G54 (X 300) lies outside the region" in text
    before = np.abs(_truth_error_after_um(truth, [dict(r, cx_um="0") for r in rows]))
    after = np.abs(_truth_error_after_um(truth, rows))
    # the truth's error at machine X 300 (-6.9 um) is not the model's continuation there
    assert np.max(after - before) > 3.0, (before, after)


def test_blocks_left_for_another_reason_are_not_counted_for_their_datum(campaign, capsys, tmp_path):
    """Two blocks whose Y and Z the program has not given are left uncorrected for that, before
    any standard error is asked: the datum's line counts the others only (it counted every block
    referenced to the datum, so 2 blocks were said twice); with no limit on the standard error
    (``--max-correction-sd-um 0``) nothing is gated for the datum and no line says it is."""
    folder, model, _, _ = campaign
    prog = tmp_path / "prog.nc"
    prog.write_text("G21 G90 G17\nG54\nG0 X-400.\nG1 X-375. F500\nG0 Y0. Z0.\n"
                    + "".join(f"G1 X{x:.1f}\n" for x in PROGRAM_X[2:]) + "M30\n")
    text, rows, summary = _compensate(folder, model, prog, capsys)
    unknown = sum(1 for r in rows if not r["y_mm"] or not r["z_mm"])
    assert unknown >= 2
    gated = len(rows) - unknown
    assert summary["datum_outside_support"]["blocks"] == gated
    assert summary["uncorrected"]["uncertain"] == gated
    assert any(t.startswith(f"{gated} blocks not corrected: the part's datum of G54") for t in text.splitlines())
    text, rows, summary = _compensate(folder, model, prog, capsys, "--max-correction-sd-um", "0")
    assert "blocks not corrected: the part's datum" not in text
    assert summary.get("datum_outside_support", {"blocks": 0})["blocks"] == 0

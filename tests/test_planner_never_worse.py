"""Bounds never leave a block worse than uncorrected: at a backlash reversal under the step bound
the correction cannot follow the error's jump; the blocks on either side are corrected partly
(never pushed past their error), and a block the bounds do force worse is counted and named."""
import csv

import numpy as np

from mtcomp.cli import main
from mtcomp.models import Backlash, save_model
from test_export_formats import random_model

BL_UM = 30.0
SLOPE = -40.0


def _model(tmp_path, backlash=BL_UM, slope=SLOPE):
    """Errors of X alone: a backlash and a positioning error linear in X (every other 0)."""
    fm = random_model("xfyz", (Backlash("X"),), 3, 0.0, None)     # every geometric error 0
    fm.params.set_file_value("BL_X", backlash)
    fm.params.set_file_value("EXX_1", slope)
    p = tmp_path / "model.json"
    save_model(p, fm)
    return p


def _compensate(tmp_path, model, program: str, step_um: float, *extra) -> list:
    """Compensate ``program``; the rows of its BLOCKS.csv."""
    prog = tmp_path / "p.nc"
    prog.write_text(program)
    report = tmp_path / "B.csv"
    assert main(["compensate", "xfyz", str(model), str(prog), "-o", str(tmp_path / "o.nc"),
                 "--report", str(report), "--max-step-um", str(step_um), "--quiet", *extra]) == 0
    return _rows(report)


def _rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_a_reversal_under_the_step_bound_leaves_no_block_worse(tmp_path, capsys):
    model = _model(tmp_path)
    prog = tmp_path / "zig.nc"
    prog.write_text("G21 G90 G54\nG0 X150 Y0 Z0\nG1 X200 F500\nG1 X150\nG1 X200\nG1 X150\nM30\n")
    report = tmp_path / "B.csv"
    assert main(["compensate", "xfyz", str(model), str(prog), "-o", str(tmp_path / "o.nc"),
                 "--report", str(report), "--json", str(tmp_path / "S.json"),
                 "--max-step-um", "5"]) == 0
    said = capsys.readouterr()
    rows = [r for r in _rows(report) if r["unknown_axes"] == ""]
    before = np.array([float(r["ex_before_um"]) for r in rows])
    after = np.array([float(r["ex_after_um"]) for r in rows])
    cx = np.array([float(r["cx_um"]) for r in rows])
    # a model of X's errors alone: a correction of X moves the deviation 1:1 (the oracle of the
    # after column); the ends at X200 (approached +) and X150 (approached -) differ by the backlash
    # and the positioning error between them, so a 5 um step cannot follow the reversal
    ends = {int(r["line"]): float(r["ex_before_um"]) for r in rows if r["inserted"] == "0"}
    assert abs(ends[3] - ends[4]) > 20.0
    sign = min((1.0, -1.0), key=lambda s: np.max(np.abs(after - before - s * cx)))
    np.testing.assert_allclose(after, before + sign * cx, rtol=0, atol=0.02)
    # the step bound binds (the correction ramps 5 um a block across each 30 um reversal) ...
    assert any(r["active_bounds"] for r in rows)
    assert np.max(np.abs(np.diff(cx))) <= 5.0 + 1e-9
    # ... and no block is worse than uncorrected (the rounding's 0.1 um aside)
    assert np.all(np.abs(after) <= np.abs(before) + 0.1)
    import json
    summary = json.loads((tmp_path / "S.json").read_text())
    assert summary["worse_than_uncorrected"]["blocks"] == 0
    assert "worse than uncorrected" not in said.out + said.err


def test_nodes_zero_correction_can_reach_from_the_anchor_by_hand():
    """Anchor 12 um, step 5 um: zero is out of reach for the first two nodes (5, 10 um of the way),
    reached from the third; a node the step bound does not apply into (after a rapid) resets it."""
    from mtcomp.planner._qp import reachable_nodes
    free = np.zeros(6, bool)
    np.testing.assert_array_equal(reachable_nodes(np.array([12.0, 0.0, -3.0]), free,
                                                  np.array([5.0, 5.0, 5.0])),
                                  [False, False, True, True, True, True])
    free[1] = True
    np.testing.assert_array_equal(reachable_nodes(np.array([12.0, 0.0, -3.0]), free,
                                                  np.array([5.0, 5.0, 5.0])),
                                  [False, True, True, True, True, True])
    assert reachable_nodes(None, free, np.ones(3)).all()       # the program's first window


def test_a_move_from_a_position_not_given_comes_from_an_unknown_direction(tmp_path, capsys):
    """Backlash alone (BL 30 um: +-15 um by approach direction). The first move of a program starts
    where the program has not said: the direction it arrives from is not known, so the backlash
    term takes the mean of both (0): the datum X0 gets no correction (it got -15 um, as if X had come
    from below). The next move, from a known X, has its direction: +-15 um."""
    rows = _compensate(tmp_path, _model(tmp_path, slope=0.0),
                       "G21 G90 G54\nG0 X0 Y0 Z5\nG1 X10 F500\nG1 X0\nM30\n", 100)
    ends = {int(r["line"]): float(r["ex_before_um"]) for r in rows if r["inserted"] == "0"}
    assert ends[2] == 0.0
    assert abs(abs(ends[3] - ends[4]) - BL_UM) < 1e-3 and abs(ends[3] + ends[4]) < 1e-3
    lines = (tmp_path / "o.nc").read_text().splitlines()
    assert lines[1] == "G0 X0 Y0 Z5"


def test_a_block_after_a_home_move_does_not_hold_back_the_cut_before_it(tmp_path):
    """After `G91 G28 Y0` the next block's Y is not known: it is left uncorrected. The machine went
    home in between, not along the cut, so the step bound does not tie the two: the cut before the
    home move ends fully corrected (it was ramped down to the uncorrected block's 0)."""
    rows = _compensate(tmp_path, _model(tmp_path, backlash=0.0),
                       "G21 G90 G54\nG0 X150 Y0 Z0\nG1 X200 F500\nG91 G28 Y0\nG90 G1 X150\nM30\n", 5)
    end = [r for r in rows if r["line"] == "3" and r["inserted"] == "0"][0]
    assert abs(float(end["ex_before_um"])) > 6.0           # more than one step of the bound
    assert abs(float(end["ex_after_um"])) < 0.1 and end["active_bounds"] == ""
    after = [r for r in rows if r["line"] == "5"][0]
    assert after["unknown_axes"] == "Y" and after["active_bounds"] == ""

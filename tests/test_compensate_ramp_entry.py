"""A feed move after a block left uncorrected carries the step bound's ramp itself, from where it
enters the region the model's data reached, so that the cut after it is corrected whole
(docs/planner.md, *Bounds*).

By hand: a model whose only error is a thermal drift of X, 1.2 um/degC since its record's first
reading (20 degC), the same everywhere: at 30 degC every block is 12 um off in X and its correction
is -12 um. The data reached X -50 .. 50 mm. The program's rapid ends at X-60 (outside: no
correction), the feed move G1 X-40 enters the region at X-50, and G1 X40 cuts. With the step bound
5 um a block, the entering move needs ceil(12 / 5) - 1 = 2 nodes: the first where it enters (X-50,
a micrometre inside), the second half way from there to its end (X-45); their corrections -5 and
-10 um, the move's end and the cut after it -12 um (no error left). Before, the move's end took
-5 um and the cut's end -10 um: 2 um of the drift left at the end of the cut, 7 um at its start,
the ramp cut into the part."""
import csv
import json

import numpy as np
import pytest

from mtcomp import load_machine
from mtcomp.cli import main
from mtcomp.models import ErrorModel, FittedModel, save_model
from mtcomp.models.terms import ThermalDrift

import replay_sinumerik

PROGRAM = "G21 G90\nG0 X-60 Y0 Z5\nG1 X-40 F300\nG1 X40\nG0 Z20\nM30\n"


def _model(path):
    fitted = FittedModel.zero(ErrorModel(load_machine("xfyz").with_basis("polynomial"), [
        ThermalDrift("temperature", ("temp_head",), "X", absolute=True, channels=("x",))]))
    fitted.params.set_file_value("TD_X_temp_head", 1.2)           # um/degC
    fitted.info["context_ranges"] = {"temp_head": [18.0, 40.0]}
    fitted.info["thermal_first_reading"] = {"temp_head": 20.0}
    fitted.support = {"X": (-50.0, 50.0), "Y": (-50.0, 50.0), "Z": (-100.0, 100.0)}
    save_model(path, fitted)
    return path


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("ramp_entry")
    (folder / "in.nc").write_text(PROGRAM)
    out = folder / "out.nc"
    code = main(["compensate", "xfyz", str(_model(folder / "m.json")), str(folder / "in.nc"),
                 "-o", str(out), "--report", str(folder / "B.csv"), "--json",
                 str(folder / "S.json"), "--temperature", "head=30", "--max-step-um", "5",
                 "--subdivide-tol-um", "0", "-q"])
    assert code == 0
    with open(folder / "B.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    return rows, json.loads((folder / "S.json").read_text()), folder


def test_the_entering_move_carries_the_ramp_and_the_cut_is_corrected_whole(run):
    rows, _summary, _folder = run
    moved = [r for r in rows if r["line"] in ("3", "4")]
    nominal_x = [float(r["x_mm"]) - float(r["cx_um"]) * 1e-3 for r in moved]
    np.testing.assert_allclose(nominal_x, [-49.999, -45.0005, -40.0, 40.0], rtol=0, atol=1e-3)
    assert [r["inserted"] for r in moved] == ["1", "1", "0", "0"]
    np.testing.assert_allclose([float(r["cx_um"]) for r in moved], [-5.0, -10.0, -12.0, -12.0],
                               rtol=0, atol=1e-9)
    # the drift left (um): 12 less the correction
    np.testing.assert_allclose([float(r["ex_after_um"]) for r in moved], [7.0, 2.0, 0.0, 0.0],
                               rtol=0, atol=1e-3)
    assert [r["active_bounds"] for r in moved] == ["step_x", "step_x", "", ""]
    # the rapid outside keeps no correction
    rapid = [r for r in rows if r["line"] == "2"]
    assert [(r["outside_support"], float(r["cx_um"])) for r in rapid] == [("X", 0.0)]


def test_the_summary_says_which_blocks_in_the_cut_carry_a_ramp(run, capsys):
    _rows, summary, folder = run
    assert summary["cut_ramp_blocks"] == {"blocks": 2, "line": 3}
    main(["compensate", "xfyz", str(folder / "m.json"), str(folder / "in.nc"), "-o",
          str(folder / "out2.nc"), "--temperature", "head=30", "--max-step-um", "5",
          "--subdivide-tol-um", "0", "-q"])
    out = capsys.readouterr().out
    assert "2 blocks in the cut carry a ramp (first at line 3): feed moves the step bound" in out


def test_a_sinumerik_program_gets_the_ramp_nodes_as_blocks_before_the_move(run, capsys):
    """A Sinumerik program is written one block per source block, but for the ramp's nodes: they
    are G1 blocks before the move's line, at the planned positions and the move's feed, so the
    controller runs the ramp the plan has (replayed independently: the nodes, then the move)."""
    _rows, _summary, folder = run
    src = folder / "P.MPF"
    src.write_text("%_N_P_MPF\n;$PATH=/_N_MPF_DIR\nN10 G17 G90 G71\nN20 G0 X-60 Y0 Z5\n"
                   "N30 G1 X-40 F300.\nN40 G1 X40\nN50 G0 Z20\nN60 M30\n")
    out = folder / "P_out.MPF"
    capsys.readouterr()
    assert main(["compensate", "xfyz", str(folder / "m.json"), str(src), "-o", str(out),
                 "--temperature", "head=30", "--max-step-um", "5", "-q"]) == 0
    lines = out.read_text().splitlines()
    at = lines.index("N20 G0 X-60 Y0 Z5")
    assert lines[at + 3:at + 6] == ["N30 G1 X-40.0120 F300.", "N40 G1 X39.9880", "N50 G0 Z20"]
    nodes = [[float(w[1:]) for w in t.split()[1:4]] for t in lines[at + 1:at + 3]]
    assert [t.split()[0] + " " + t.split()[-1] for t in lines[at + 1:at + 3]] == ["G1 F300."] * 2
    # written: the planned node (X -49.999 and -45.0005 by hand, to 1 um) plus -5 and -10 um
    np.testing.assert_allclose(nodes, [[-49.999 - 0.005, 0.0, 5.0], [-45.0005 - 0.010, 0.0, 5.0]],
                               rtol=0, atol=1e-3)
    moves = [m for m in replay_sinumerik.replay(out.read_bytes()).moves if m.kind == "feed"]
    np.testing.assert_allclose([m.end["X"] for m in moves], [nodes[0][0], nodes[1][0], -40.012,
                                                             39.988], rtol=0, atol=1e-9)


@pytest.mark.parametrize("limit", ["20", "5"])
def test_a_rapid_the_two_standard_error_rule_leaves_is_ramped_out_of_as_one_over_the_limit(
        tmp_path, limit):
    """By hand: X's slope 40 um/m (standard error 3) and a curvature of X of 0 whose standard error
    is 9 um at X300, the slope's 0.9: the rapid G0 X300 would take -12 um, 1.33 of its standard errors
    (hypot(9, 0.9) = 9.04 um): left uncorrected by the two-standard-error rule under the limit 20 um,
    for being over it under the limit 5 um.
    Either way G1 X50 needs -2 um with the step bound 0.5 um a block: ceil(2 / 0.5) - 1 = 3 nodes
    evenly along it (X 237.5, 175, 112.5: -0.5, -1, -1.5 um), and the cut is corrected whole
    (-2 um at X50, -1.6 at X40: none of the 40 um/m left)."""
    fitted = FittedModel.zero(ErrorModel(load_machine("xfyz").with_basis("polynomial")))
    fitted.params.set_file_value("EXX_1", 40.0)
    fitted.support = {"X": (-400.0, 400.0), "Y": (-300.0, 300.0)}
    fitted.uncertainty = {"names": ["EXX_1", "EXX_2"], "covariance": np.diag([3e-3 ** 2, 0.1 ** 2]),
                          "undetermined": np.zeros((2, 0))}
    save_model(tmp_path / "m.json", fitted)
    (tmp_path / "in.nc").write_text("G21 G90\nG0 X300 Y0 Z0\nG1 X50 F1000\nG1 X40\nM30\n")
    assert main(["compensate", "xfyz", str(tmp_path / "m.json"), str(tmp_path / "in.nc"), "-o",
                 str(tmp_path / "out.nc"), "--report", str(tmp_path / "B.csv"), "--work-offset",
                 "G54=X0,Y0,Z0", "--max-step-um", "0.5", "--subdivide-tol-um", "0",
                 "--max-correction-sd-um", limit, "-q"]) == 0
    with open(tmp_path / "B.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    rapid, moved = rows[0], rows[1:]
    assert (rapid["line"], rapid["corrected"], rapid["uncertain"]) == ("2", "0", "1")
    np.testing.assert_allclose(float(rapid["ex_before_um"]) / float(rapid["correction_sd_um"]),
                               12.0 / np.hypot(9.0, 0.9), rtol=1e-3, atol=0)
    assert [r["line"] + r["inserted"] for r in moved] == ["31", "31", "31", "30", "40"]
    nominal_x = [float(r["x_mm"]) - float(r["cx_um"]) * 1e-3 for r in moved]
    np.testing.assert_allclose(nominal_x, [237.5, 175.0, 112.5, 50.0, 40.0], rtol=0, atol=2e-3)
    np.testing.assert_allclose([float(r["cx_um"]) for r in moved], [-0.5, -1.0, -1.5, -2.0, -1.6],
                               rtol=0, atol=1e-3)
    np.testing.assert_allclose([float(r["ex_after_um"]) for r in moved[3:]], [0.0, 0.0],
                               rtol=0, atol=1e-3)

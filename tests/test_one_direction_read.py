"""An axis the data read approaching from one side only: compensate leaves the blocks that approach
it from the other side (or from a side not known) uncorrected, counts and marks them, and says
why; export's LinuxCNC table carries the side read only.

Truth: a positioning error in plain numpy, P(x, d) = e(x) + d B / 2 (ISO 230-2: the reversal B is
the mean up less the mean down), read by a laser approaching in + only. The blocks that approach
in - and their approach directions are derived here by hand from the program; the tool-tip
deviation after correction is evaluated on the truth at the written position, relative to the
part's datum (X 0) probed approaching in +.
"""
import csv
import json

import numpy as np
import pytest

from mtcomp.cli import main
from mtcomp.identification.reversal import data_reversal
from mtcomp.measurement.files import read_measurements

B_UM = 10.0                                           # the truth's reversal, um


def _e(x):
    return 0.02 * np.asarray(x, dtype=float)          # 20 um/m, um


def _truth(x, d):
    """um: the positioning error at x (mm) approached in direction d."""
    return _e(x) + 0.5 * d * B_UM


def _laser_plus(path, rng, axis="X", unit="um", targets=range(-350, 351, 50), error=_truth):
    """Three runs of the positioning of ``axis`` read approaching in + only."""
    col = "target_deg" if unit == "urad" else "target_mm"
    rows = [f"axis,component,{col},dir,run,value_{unit}"]
    for run in (1, 2, 3):
        for t in targets:
            rows.append(f"{axis},E{axis}{axis},{t},1,{run},{error(t, 1) + rng.normal(0, 0.02):.4f}")
    path.write_text("\n".join(rows) + "\n")
    return path


PROGRAM = """G21 G90 G17
G0 X-300 Y0 Z0
G0 X-250
G1 X-150 F1000
G1 X-50
G1 X50
G0 X300
G0 X350
G1 X250
G1 X150
G1 X100
G0 X200
M30
"""
#: source line -> (X at its end, approach direction of X there): by hand from PROGRAM (line 2
#: comes from a position not given: its approach is not known)
BLOCKS = {2: (-300, 0), 3: (-250, 1), 4: (-150, 1), 5: (-50, 1), 6: (50, 1), 7: (300, 1),
          8: (350, 1), 9: (250, -1), 10: (150, -1), 11: (100, -1), 12: (200, 1)}
UNREAD = {2, 9, 10, 11}


def _rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


@pytest.fixture(scope="module")
def plus_model(tmp_path_factory):
    folder = tmp_path_factory.mktemp("one_direction")
    laser = _laser_plus(folder / "x_plus.csv", np.random.default_rng(3))
    model = folder / "m.json"
    assert main(["identify", "xfyz", str(laser), "-o", str(model)]) == 0
    return folder, model


def test_blocks_approached_from_the_side_not_read_are_left_and_none_ends_worse(plus_model, capsys):
    """On main every block was corrected with the + reading: lines 9 to 11 (approached in -) ended
    10 um off the truth, from 5, 3 and 2 um. Now they, and line 2 (approach not known), are left
    uncorrected, counted, marked and said; the blocks approached in + are corrected to the truth."""
    folder, model = plus_model
    prog = folder / "p.nc"
    prog.write_text(PROGRAM)
    capsys.readouterr()
    assert main(["compensate", "xfyz", str(model), str(prog), "-o", str(folder / "o.nc"),
                 "--report", str(folder / "b.csv"), "--json", str(folder / "s.json")]) == 0
    out = capsys.readouterr().out
    rows = {int(r["line"]): r for r in _rows(folder / "b.csv")}
    assert set(rows) == set(BLOCKS)
    after, worse = {}, []
    for k, (x, d) in BLOCKS.items():
        c = float(rows[k]["cx_um"]) * 1e-3
        before = _truth(x, d or 1) - _truth(0.0, 1)
        after[k] = c * 1e3 + _truth(x + c, d or 1) - _truth(0.0, 1)
        if abs(after[k]) > abs(before) + 0.05:
            worse.append((k, before, after[k]))
    assert worse == []
    assert {k for k, r in rows.items() if r["direction_not_read"] == "1"} == UNREAD
    for k, r in rows.items():
        c = float(r["cx_um"])
        if k in UNREAD:
            assert r["corrected"] == "0" and r["uncertain"] == "1" and c == 0.0
        else:       # corrected to the truth, but where the step bound ramps into a block left
            assert r["corrected"] == "1", k
            assert abs(after[k]) < 0.3 or "step_x" in r["active_bounds"], (k, after[k])
    summary = json.loads((folder / "s.json").read_text())
    assert summary["uncorrected"]["direction_not_read"] == len(UNREAD)
    assert summary["uncorrected"]["uncertain"] == 0
    assert summary["correction_sd_undetermined"] is False
    said = [line for line in out.splitlines() if "approach direction the model's data never read" in line]
    assert len(said) == 1 and "3 approach X in -" in said[0] and "1 with X's approach not known" in said[0] \
        and "read X approaching in + only" in said[0] and "first at line 2" in said[0], said


def test_linuxcnc_table_carries_the_side_read(plus_model):
    """LinuxCNC's COMP_FILE has a column per approach side: the forward one holds the + reading
    (the truth's, relative to the reference position X 0: -20 um/m), the reverse one nothing."""
    folder, model = plus_model
    assert main(["export", "xfyz", str(model), "--format", "linuxcnc", "-o", str(folder / "exp")]) == 0
    lines = (folder / "exp" / "x.comp").read_text().split("\n")
    table = np.array([[float(v) for v in line.split()] for line in lines if line])
    nominal, forward, reverse = table.T
    # one step beyond each end of the data (both inside the travel) the table is zero
    np.testing.assert_allclose(forward[1:-1], -(_e(nominal[1:-1]) - _e(0.0)) * 1e-3, rtol=0, atol=3e-4)
    assert forward[0] == forward[-1] == 0.0 and np.all(reverse == 0.0)
    assert "reverse column carries no correction" in (folder / "exp" / "ini_lines.txt").read_text()


def test_rotary_axis_read_from_one_side(tmp_path, capsys):
    """B read by a rotary laser approaching in + only: a block whose B last moved in -, or has not
    moved since the start, is left uncorrected, also when the block itself moves only X (the
    approach is the axis's last motion); blocks after a + move of B are corrected."""
    laser = _laser_plus(tmp_path / "b_plus.csv", np.random.default_rng(5), "B", "urad", range(0, 91, 15),
                        lambda t, d: 3.0 * t + 0.5 * d * 200.0)
    assert main(["identify", "cbfxyz", str(laser), "-o", str(tmp_path / "m.json")]) == 0
    prog = tmp_path / "p.nc"
    prog.write_text("G21 G90 G17\nG0 X0 Y0 Z50 B0 C0\nG1 B30 F1000\nG1 X10\nG1 B60\nG0 B90\n"
                    "G1 B45 F1000\nG1 X20\nG0 B75\nM30\n")
    assert main(["compensate", "cbfxyz", str(tmp_path / "m.json"), str(prog), "-o",
                 str(tmp_path / "o.nc"), "--report", str(tmp_path / "b.csv"), "--quiet"]) == 0
    rows = {int(r["line"]): r for r in _rows(tmp_path / "b.csv")}
    assert {k for k, r in rows.items() if r["direction_not_read"] == "1"} == {2, 7, 8}
    assert {k for k, r in rows.items() if r["corrected"] == "1"} == {3, 4, 5, 6, 9}
    assert "read B approaching in + only" in capsys.readouterr().out


def _points(path, dir_b="1", b=(0, 15, 30)):
    rows = ["x_mm,y_mm,z_mm,b_deg,c_deg,dx_um,dy_um,dz_um,dir_b,dir_x"]
    for i, angle in enumerate(b):
        rows.append(f"{100 + i},0,20,{angle},0,1,1,1,{dir_b},1")
    path.write_text("\n".join(rows) + "\n")
    return read_measurements(path)


def test_points_state_an_approach_only_where_they_move_the_axis(tmp_path):
    """An R-test's points file with dir_b +1 in every row reads B from + only, and X (which moves,
    dir_x +1) too; blank cells state nothing, nor does an axis held at one position."""
    assert data_reversal([_points(tmp_path / "r.csv")]) == {
        "X": {"one_direction": "+", "files": ["r"]}, "B": {"one_direction": "+", "files": ["r"]}}
    assert "B" not in data_reversal([_points(tmp_path / "blank.csv", dir_b="")])
    assert "B" not in data_reversal([_points(tmp_path / "held.csv", b=(15, 15, 15))])
    both = _points(tmp_path / "both.csv", dir_b="-1")
    assert "B" not in data_reversal([_points(tmp_path / "r.csv"), both])

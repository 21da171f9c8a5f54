"""A drift correction's standard error is the drift prediction's: the part's datum is probed before
the drift, so referencing to it takes nothing away (the intercept of an absolute drift model and
its temperature terms stay together). Oracle: `mtcomp predict` on a record row at the same
temperatures (the measurement model's prediction and its standard error), on the real 46 h record."""
import csv

import pytest

from mtcomp.cli import main
from real_data import THERMAL


def _rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_drift_correction_and_its_standard_error_are_the_drift_prediction(tmp_path, capsys):
    model = tmp_path / "M.json"
    assert main(["diagnose", "xfyz", str(THERMAL), "--channel-axis", "ch3=Z", "--json",
                 str(tmp_path / "R.json"), "-o", str(model)]) == 0
    row = dict(_rows(THERMAL)[6000])            # 25 h into the record, spindle warm before
    temps = [c for c in row if c.startswith("temp_")]
    (tmp_path / "T.csv").write_text(",".join(temps) + "\n" + ",".join(row[c] for c in temps) + "\n")
    # the same state as a record row the model predicts: spindle stopped long (no lag), t 0
    row.update(t_s="0", spindle_rpm="0")
    (tmp_path / "one.csv").write_text(",".join(row) + "\n" + ",".join(row.values()) + "\n")
    assert main(["predict", "xfyz", str(model), str(tmp_path / "one.csv"), "-o",
                 str(tmp_path / "P.csv")]) == 0
    pred = _rows(tmp_path / "P.csv")[0]
    prog = tmp_path / "p.nc"
    prog.write_text("G21 G90\nG0 X0 Y0 Z10\nG1 Z-5 F500\nG1 X100\nG1 Y100\nM30\n")
    assert main(["compensate", "xfyz", str(model), str(prog), "-o", str(tmp_path / "o.nc"),
                 "--temperatures", str(tmp_path / "T.csv"), "--report", str(tmp_path / "B.csv"),
                 "--quiet"]) == 0
    capsys.readouterr()
    blocks = [r for r in _rows(tmp_path / "B.csv") if r["unknown_axes"] == ""]
    assert blocks and all(r["corrected"] == "1" for r in blocks)
    for r in blocks:
        # the Z deviation of the tip is the Z channel's prediction (the same sign convention)
        assert float(r["ez_before_um"]) == pytest.approx(float(pred["pred_disp_ch3_um"]), abs=2e-3)
        assert float(r["correction_sd_um"]) == pytest.approx(float(pred["pred_disp_ch3_um_sd"]),
                                                             rel=2e-3, abs=1e-3)
    assert float(blocks[0]["correction_sd_um"]) < 0.5      # was 4.04: the intercept's alone

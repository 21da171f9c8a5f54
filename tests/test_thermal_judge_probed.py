"""A judge (a re-measurement's model, the truth) takes the part's datum in the thermal state the
compensation took it in, resolved once from the compensating model: the compensating model's
record's first reading, not the judge's own record's. Oracle: `mtcomp predict` of the judge's model
at the running state and at that first reading (a drift model's deviation is the same at every
pose, so every corrected block's deviation before correction is their difference)."""
import csv
import json

import pytest

from mtcomp.cli import main
from real_data import THERMAL


def _rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_the_judge_takes_the_datum_at_the_compensating_models_first_reading(tmp_path):
    from mtcomp.compensation import CompensationSettings, Judge, compensate_program
    from mtcomp.machine import load_machine
    from mtcomp.models.model_file import load_model
    record = _rows(THERMAL)
    # every third reading (less to fit); the same machine's record from 8 h on: another first reading
    for name, part in (("A", record[::3]), ("B", record[2001::3])):
        src = tmp_path / f"{name}.csv"
        src.write_text(",".join(record[0]) + "\n" + "\n".join(",".join(r.values()) for r in part) + "\n")
        assert main(["diagnose", "xfyz", str(src), "--channel-axis", "ch3=Z", "--json",
                     str(tmp_path / f"R{name}.json"), "-o", str(tmp_path / f"{name}.json"), "--quiet"]) == 0
    first = json.loads((tmp_path / "A.json").read_text())["info"]["thermal_first_reading"]
    other = json.loads((tmp_path / "B.json").read_text())["info"]["thermal_first_reading"]
    assert first != other
    now = record[6000]
    temps = {c[5:-2]: float(now[c]) for c in now if c.startswith("temp_")}
    # the judge's model at the running state and at the compensating model's first reading
    rows = [dict(now, t_s="0", spindle_rpm="0"),
            dict(now, t_s="1", spindle_rpm="0", **{f"{f}_c": repr(v) for f, v in first.items()
                                                  if f.startswith("temp_")})]
    (tmp_path / "S.csv").write_text(",".join(rows[0]) + "\n"
                                    + "\n".join(",".join(r.values()) for r in rows) + "\n")
    assert main(["predict", "xfyz", str(tmp_path / "B.json"), str(tmp_path / "S.csv"), "-o",
                 str(tmp_path / "P.csv")]) == 0
    at_now, at_first = (float(r["pred_disp_ch3_um"]) for r in _rows(tmp_path / "P.csv"))
    machine = load_machine("xfyz")
    settings = CompensationSettings(temperatures=temps, max_correction_sd_um=0,
                                    max_correction_um=500, max_step_um=500)
    judge = Judge(load_model(tmp_path / "B.json", machine), settings)
    prog = tmp_path / "p.nc"
    prog.write_text("G21 G90\nG0 X0 Y0 Z10\nG1 Z-5 F500\nG1 X100\nG1 Y100\nM30\n")
    compensate_program(load_model(tmp_path / "A.json", machine), prog, tmp_path / "o.nc", settings,
                       judges=[judge])
    seen = judge.as_dict()
    assert seen["blocks"] > 0
    assert seen["max_before_um"] == pytest.approx(abs(at_now - at_first), rel=0, abs=2e-3)
    assert seen["rms_before_um"] == pytest.approx(abs(at_now - at_first), rel=0, abs=2e-3)

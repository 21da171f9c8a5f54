"""BLOCKS.csv under a frame the program moved itself: positions and corrections as written."""
import csv

import pytest

from test_compensate_cli import _model, _run


@pytest.mark.parametrize("frame", ["G68 X0 Y0 R30.", "G51.1 X0", "G52 X10. Y5."])
def test_blocks_csv_reports_the_written_correction_under_a_frame(tmp_path, capsys, frame):
    """Under G68, a mirror or G52 BLOCKS.csv's positions are the program's words as written; its
    correction columns are too (written minus nominal), not the machine's correction vector."""
    _, _, model = _model(tmp_path, "xfyz", seed=5, scale=20.0)
    p = tmp_path / "f.nc"
    moves = [(5.0, 0.0), (15.0, 0.0), (15.0, 3.0), (5.0, 3.0)]
    p.write_text("O0001\nG21 G90 G17\nG0 X0 Y0 Z10.\n" + frame + "\nG0 X5. Y0\nG1 Z-1. F100\n"
                 + "".join(f"G1 X{x:.1f} Y{y:.1f} F300\n" for x, y in moves[1:]) + "M30\n")
    report = tmp_path / "B.csv"
    code, _o, err = _run(["compensate", "xfyz", str(model), str(p), "-o", str(tmp_path / "o.nc"),
                          "--dialect", "fanuc", "--report", str(report), "--subdivide-tol-um", "0",
                          "--quiet"], capsys)
    assert code == 0, err
    rows = [r for r in csv.DictReader(open(report)) if int(r["line"]) >= 7]
    assert len(rows) == 3
    for r, (x, y) in zip(rows, moves[1:]):
        assert float(r["x_mm"]) - x == pytest.approx(float(r["cx_um"]) * 1e-3, abs=6e-5)
        assert float(r["y_mm"]) - y == pytest.approx(float(r["cy_um"]) * 1e-3, abs=6e-5)
    assert any(abs(float(r["cx_um"])) > 1.0 for r in rows)

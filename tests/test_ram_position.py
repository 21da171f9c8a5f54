"""The ram is where the tool put it in every rule that reads positions, as in the model
(docs/conventions.md, "Tool length"): on the built-in xfyz (L0 = 100 mm) a 200 mm stylus at tip z
puts the ram at z + 100. Data taken with it at tips z = 0..50 read the ram at 100..150 mm (the top
of its travel): that is the range the report gives, the region compensate and export keep to, and
the position diagnose reads a structure along. A block cut with a 0 mm tool at tip z = 100 has the
ram at z = 0, at tip z = 50 at -50: both outside that region (compensate leaves out their Z word);
one cut with the 100 mm tool at tip
z = 120 has it at 120, inside (the commanded rule had 50 inside and 120 outside)."""
import csv
from types import SimpleNamespace

import numpy as np
import pytest

from mtcomp import load_machine
from mtcomp.cli import main
from mtcomp.measurement import read_measurements

STYLUS = 200.0
ZS = (0.0, 25.0, 50.0)           # tip z of the data: the ram at 100, 125, 150


def _points(path):
    rng = np.random.default_rng(1)
    rows = ["x_mm,y_mm,z_mm,tool_mm,dx_um,dy_um,dz_um"]
    for x in (-100, 0, 100):
        for y in (-100, 0, 100):
            for z in ZS:
                # X's positioning error, 40 um/m, over the noise: corrections the data tell from
                # none (a correction within two standard errors of zero is not made)
                d = rng.normal(0.0, 0.3, 3) + np.array([0.04 * x, 0.0, 0.0])
                rows.append(f"{x},{y},{z:g},{STYLUS:g},{d[0]:.3f},{d[1]:.3f},{d[2]:.3f}")
    path.write_text("\n".join(rows) + "\n")
    return path


@pytest.fixture(scope="module")
def fitted_model(tmp_path_factory):
    d = tmp_path_factory.mktemp("ram")
    src = _points(d / "p.csv")
    out = d / "m.json"
    assert main(["identify", "xfyz", str(src), "-o", str(out)]) == 0
    return src, out


def test_guideway_positions_by_hand():
    from mtcomp.models.chain import guideway_positions
    m = load_machine("xfyz")
    q = np.array([[1.0, 2.0, 0.0], [1.0, 2.0, 100.0], [1.0, 2.0, 100.0]])
    got = guideway_positions(m, q, np.array([200.0, 0.0, np.nan]))
    np.testing.assert_array_equal(got, [[1.0, 2.0, 100.0], [1.0, 2.0, 0.0], [1.0, 2.0, 100.0]])


def test_identify_records_and_reports_where_the_ram_stood(fitted_model, capsys):
    from mtcomp.models import load_model
    src, out = fitted_model
    fitted = load_model(out)
    assert fitted.support["Z"] == (100.0, 150.0)          # commanded: 0 .. 50
    assert fitted.support["X"] == (-100.0, 100.0)
    assert main(["identify", "xfyz", str(src), "-o", str(out.with_name("m2.json"))]) == 0
    text = capsys.readouterr().out
    assert "Z from 100 to 150 mm:" in text, text


def test_compensate_leaves_the_z_word_of_a_block_whose_ram_is_outside_the_data(fitted_model, tmp_path):
    _, model = fitted_model
    prog = tmp_path / "p.ngc"
    # H1 = 0 mm: tips z 100 and 50 put the ram at 0 and -50 (outside 100..150); H2 = 100 mm: tip
    # z 120 puts it at 120 (inside)
    prog.write_text("G21 G90 G17\nT1 M6\nG43 H1\nG1 X0 Y0 Z100 F1000\nG1 X50 Y0 Z100\n"
                    "G1 X0 Y0 Z50\nG1 X50 Y0 Z50\n"
                    "T2 M6\nG43 H2\nG1 X0 Y0 Z120\nG1 X50 Y0 Z120\nM30\n")
    report = tmp_path / "r.csv"
    assert main(["compensate", "xfyz", str(model), str(prog), "-o", str(tmp_path / "out.ngc"),
                 "--tool-length", "H1=0", "--tool-length", "H2=100", "--report", str(report),
                 ]) == 0
    with open(report) as f:
        rows = [r for r in csv.DictReader(f) if r.get("inserted", "0") == "0"]
    outside = {float(r["z_mm"]): r["outside_support"] for r in rows}
    assert outside[100.0] == "Z" and outside[50.0] == "Z" and outside[120.0] == "", rows
    # the ram alone outside: X and Y corrected, its own Z word not (docs/planner.md)
    for r in rows:
        if r["outside_support"] == "Z":
            assert r["corrected"] == "1" and float(r["cz_um"] or 0.0) == 0.0, r


def test_planner_block_status_reads_the_ram_where_the_tool_put_it(fitted_model):
    from mtcomp.models import load_model
    from mtcomp.planner import CompensationProblem, Planner, PlannerOptions
    fitted = load_model(fitted_model[1])
    planner = Planner(CompensationProblem.from_machine(fitted), PlannerOptions(threads=1))
    q = np.array([[0.0, 0.0, 50.0], [0.0, 0.0, 120.0], [0.0, 0.0, 0.0]])
    _, outside, _, _ = planner.block_status(q, np.ones(q.shape, bool), np.full(3, np.nan), np.zeros(q.shape),
                                         tool_length=np.array([0.0, 100.0, STYLUS]))
    np.testing.assert_array_equal(outside[:, 2], [True, False, False])


def test_export_tables_cover_the_ram_s_range(fitted_model):
    from mtcomp.export._tables import table_region
    from mtcomp.models import load_model
    region, source, _ = table_region(load_model(fitted_model[1]))
    assert region["Z"] == (100.0, 150.0) and source["Z"] == "data"


def test_predict_blanks_the_sd_where_the_ram_is_outside(fitted_model, tmp_path):
    f = tmp_path / "q.csv"
    f.write_text("x_mm,y_mm,z_mm,tool_mm,dx_um,dy_um,dz_um\n0,0,50,0,0,0,0\n0,0,120,100,0,0,0\n")
    out = tmp_path / "pred.csv"
    assert main(["predict", "xfyz", str(fitted_model[1]), str(f), "-o", str(out)]) == 0
    with open(out) as fh:
        rows = list(csv.DictReader(fh))
    assert rows[0]["pred_dx_um_sd"] == "" and rows[1]["pred_dx_um_sd"] != "", rows


def test_diagnose_stack_stands_the_ram_where_the_tool_put_it(fitted_model):
    from mtcomp.diagnose._stack import build_stack
    st = build_stack(load_machine("xfyz"), [read_measurements(fitted_model[0], "points")])
    np.testing.assert_array_equal(st.stood[:, 2], st.q[:, 2] + STYLUS - 100.0)
    np.testing.assert_array_equal(st.stood[:, :2], st.q[:, :2])


def test_a_structure_is_read_along_where_the_ram_stood():
    """Every reading at commanded z = 0, with tools of 100..400 mm: the ram stood at 0..300 mm, and
    a bump of its positioning error at 200 mm shows along Z there (along the commanded Z, one
    position, there is nothing to see)."""
    from mtcomp.diagnose import _analysis as an
    rng = np.random.default_rng(7)
    n = 400
    m = load_machine("xfyz")
    zr = np.sort(rng.uniform(0.0, 300.0, n))
    q = np.zeros((n, 3))
    stood = q.copy()
    stood[:, 2] = zr
    st = SimpleNamespace(machine=m, q=q, stood=stood, series=np.full(n, "s", dtype=object),
                         dirs=np.zeros((n, 3)), feed=np.full(n, np.nan), arm=np.zeros((n, 3)),
                         spindle=np.full(n, np.nan), run=np.full(n, -1), t=np.full(n, np.nan),
                         unit=np.full(n, "um"), kinds=["points"], file=np.zeros(n, dtype=int),
                         row=np.arange(n), temps={}, moving=np.full(n, ""),
                         g={"X": np.zeros(n), "Y": np.zeros(n), "Z": np.full(n, 1e3)})
    r = 0.3 * rng.normal(size=n) + 2.0 * np.exp(-0.5 * ((zr - 200.0) / 15.0) ** 2)
    found = an.find_structure(st, r, {"um": 0.3})
    assert found and found[0].variable == "Z position", found
    assert found[0].lo <= 200.0 <= found[0].hi

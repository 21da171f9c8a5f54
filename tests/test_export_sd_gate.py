"""export leaves out the table of an axis whose correction the model does not know well enough, as
compensate leaves such blocks uncorrected (--max-correction-sd-um, the same default).

The model: identify on laser runs of X with a 200 mm gap between the targets (tests/
test_identify_penalty.py's case): across the gap EXX rests on the penalty, and its standard error is
larger there. The oracle of a table point's standard error is written here from the model's basis
functions (the standard error of EXX at s less EXX at the reference position 0, from the model's
covariance): a second formulation, where export takes the model's Jacobian."""
from __future__ import annotations

import numpy as np
import pytest

from mtcomp.cli import main
from mtcomp.export._tables import table_sd_um
from mtcomp.models import save_model
from test_identify_penalty import _gap_fit


@pytest.fixture(scope="module")
def gap(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("gap")
    fm, spline = _gap_fit(tmp, lambda t: 5.0 * np.sin(2 * np.pi * t / 500.0), "wave")
    save_model(tmp / "m.json", fm)
    at = np.arange(-300.0, 300.1, 25.0)
    J = np.zeros((at.size, len(fm.params.names)))
    for j, phi, phi0 in zip(spline.kept(False), spline.functions(at, False),
                            spline.functions(np.array([0.0]), False)):
        J[:, fm.params.index(f"EXX_b{j}")] = 1e3 * (phi - phi0)          # um per coefficient
    return fm, tmp / "m.json", at, fm.prediction_std(J)


def test_a_table_point_s_standard_error_is_that_of_its_error_less_the_reference_s(gap):
    fm, _, at, sd = gap
    q = np.zeros((at.size, 3))
    q[:, 0] = at
    for d in (1.0, -1.0):
        got = table_sd_um(fm, q, np.zeros(3), {"X": d})
        np.testing.assert_allclose(got, sd, rtol=1e-3, atol=1e-4)
    # zero at the reference position (the table's zero), growing away from it
    assert sd[at == 0.0] == 0.0 and sd.max() > 0.3 and np.all(np.diff(sd[at >= 0][:5]) > 0)


def _export(model, out, *extra):
    return main(["export", "xfyz", str(model), "--format", "linuxcnc", "-o", str(out),
                 "--grid-mm", "25", *extra])


def test_the_table_is_left_out_when_its_standard_error_passes_the_limit(gap, tmp_path, capsys):
    fm, model, at, sd = gap
    top = float(sd.max())
    assert _export(model, tmp_path / "under", "--max-correction-sd-um", f"{1.01 * top:.6g}") == 0
    written = (tmp_path / "under" / "x.comp").read_text()
    capsys.readouterr()
    # the limit just under the largest: X has no table, and X is all the data moved
    assert _export(model, tmp_path / "over", "--max-correction-sd-um", f"{0.99 * top:.6g}") == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "nothing to export" in err
    assert f"axis X: no table: its correction's standard error reaches {top:.3g} um" in err
    assert "--max-correction-sd-um" in err and not (tmp_path / "over").exists()
    assert "more data there, or a larger --max-correction-sd-um, writes the table" in err
    # far beyond the limit (more than 10 times): only more data is advised
    assert _export(model, tmp_path / "far", "--max-correction-sd-um", f"{top / 11:.6g}") == 2
    err = capsys.readouterr().err
    assert "the data do not determine them (a standard error 11 times the limit)" in err
    assert "or a larger" not in err
    # no limit: the same table as under a limit it passes
    assert _export(model, tmp_path / "none", "--max-correction-sd-um", "0") == 0
    assert (tmp_path / "none" / "x.comp").read_text() == written


def test_compensate_sees_the_same_standard_error_at_the_same_position(gap, tmp_path):
    """A program at the table's points with the work offset at the reference position: each
    block's correction_sd_um in BLOCKS.csv is the table point's standard error."""
    import csv
    fm, model, at, sd = gap
    prog = tmp_path / "x.nc"
    prog.write_text("G21 G90 G54\n" + "".join(f"G1 X{x:g} Y0 Z0 F1000\n" for x in at) + "M30\n")
    rep = tmp_path / "b.csv"
    assert main(["compensate", "xfyz", str(model), str(prog), "-o", str(tmp_path / "o.nc"),
                 "--report", str(rep), "--max-correction-sd-um", "1000", "--quiet",
                 "--subdivide-tol-um", "0", "--work-offset", "G54=X0,Y0,Z0"]) == 0
    with open(rep, newline="") as f:
        rows = [r for r in csv.DictReader(f) if r["inserted"] == "0"]
    got = np.array([float(r["correction_sd_um"]) for r in rows])
    np.testing.assert_allclose(got, sd, rtol=1e-3, atol=1e-4)


def test_a_model_without_covariance_is_written_and_the_note_says_it_was_not_checked(gap, tmp_path,
                                                                                    capsys):
    import json
    _, model, _, _ = gap
    d = json.loads(model.read_text())
    d.pop("uncertainty", None)
    bare = tmp_path / "bare.json"
    bare.write_text(json.dumps(d))
    assert _export(bare, tmp_path / "out") == 0
    assert "no table could be checked against --max-correction-sd-um" in capsys.readouterr().err


def test_advice_for_undetermined_corrections_names_the_limit_that_writes_them():
    """A correction resting on values nothing determined has an infinite standard error: every finite
    --max-correction-sd-um leaves it out, and 0 (no limit, compensate's and export's documented
    switch) writes it; the advice must say so, not that no value writes them."""
    from mtcomp.planner.problem import unsure_advice
    text = unsure_advice(float("inf"), 5.0)
    assert "no finite --max-correction-sd-um writes them, only 0 (no limit)" in text
    assert "no --max-correction-sd-um writes" not in text

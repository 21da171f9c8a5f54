"""`mtcomp demo` end to end into tmp_path: every file it mentions, nothing outside its folder, and
the hidden effect found and compensated (checked against the virtual machine's known truth)."""
from __future__ import annotations

import csv
import json
import re
import subprocess
import sys

import numpy as np
import pytest

NUM = r"(-?\d+(?:\.\d+)?)"


@pytest.fixture(scope="module")
def demo_run(tmp_path_factory):
    base = tmp_path_factory.mktemp("demo")
    cwd = base / "cwd"
    cwd.mkdir()
    out = base / "nested" / "out"  # does not exist yet: the demo creates it
    (base / "nested").mkdir()
    res = subprocess.run([sys.executable, "-m", "mtcomp", "demo", "--out", str(out)], cwd=cwd,
                         capture_output=True, text=True, timeout=600)
    return res, out, cwd


def test_demo_runs_and_writes_only_into_its_folder(demo_run):
    res, out, cwd = demo_run
    assert res.returncode == 0, res.stdout + res.stderr
    for k in range(1, 7):
        assert f"[{k}/6]" in res.stdout
    assert list(cwd.iterdir()) == []
    expected = {"MODEL_base.json", "identify.txt", "REPORT.json", "MODEL.json", "diagnose.txt",
                "bowl.nc", "bowl_compensated.nc", "BLOCKS.csv", "compensate.txt",
                "bowl_compensated_base.nc", "compensate_base.txt", "map.png", "map.vtp", "map_cut.png",
                "map_cut.vtp", "campaign"}
    assert {p.name for p in out.iterdir()} == expected
    assert len(list((out / "campaign").glob("*.csv"))) >= 10
    listed = re.search(r"^files in .*?: (.*), campaign/ \((\d+) CSV files\)$", res.stdout, re.M)
    assert listed, res.stdout
    assert set(listed.group(1).split(", ")) | {"campaign"} == expected
    assert int(listed.group(2)) == len(list((out / "campaign").glob("*.csv")))


def test_demo_finds_the_hidden_backlash(demo_run):
    from mtcomp import load_machine
    from mtcomp.demo import HIDDEN_BACKLASH_UM
    from mtcomp.models import load_model
    res, out, _ = demo_run
    report = json.loads((out / "REPORT.json").read_text())
    assert report["verdict"] == "explained"
    found = [f for f in report["findings"] if f["effect"] == "backlash" and f["axis"] == "X"]
    assert len(found) == 1
    assert found[0]["params"]["magnitude_um"] == pytest.approx(HIDDEN_BACKLASH_UM, abs=0.3)
    assert found[0]["heldout_rms_after_um"] < 0.5 * found[0]["heldout_rms_before_um"]
    model = load_model(out / "MODEL.json", load_machine("xfyz"))
    assert model.params["BL_X"] * 1e3 == pytest.approx(HIDDEN_BACKLASH_UM, abs=0.3)
    assert "BL_X" not in load_model(out / "MODEL_base.json").params


def test_demo_compensation_helps_on_the_virtual_machine(demo_run):
    res, out, _ = demo_run
    rows = {}
    for label in ("uncompensated", "base model comp.", "extended model"):
        m = re.search(rf"{re.escape(label)}\s+rms {NUM} um, max {NUM} um", res.stdout)
        assert m, res.stdout
        rows[label] = (float(m.group(1)), float(m.group(2)))
    # the part's form error (true normal error less the best rigid motion: the datum is probed)
    assert rows["extended model"][0] < 0.5 * rows["uncompensated"][0]
    assert rows["extended model"][0] < rows["base model comp."][0]
    assert re.search(rf"form error removed \(truth rms\)\s+{NUM} % with the base model, {NUM} % "
                     r"with the extended model \(Qi and Yang 2016: about 30 % on a real cut\)", res.stdout)


def test_demo_map_and_blocks_agree_with_the_summary(demo_run):
    pv = pytest.importorskip("pyvista")
    res, out, _ = demo_run
    before = re.search(rf"predicted by MODEL.json\s+before rms {NUM} um, max {NUM} um", res.stdout)
    after = re.search(rf"^\s+after  rms {NUM} um, max {NUM} um", res.stdout, re.M)
    assert before and after, res.stdout
    mesh = pv.read(out / "map.vtp")
    for arr, m in (("dn_before_um", before), ("dn_after_um", after)):
        dn = np.asarray(mesh.point_data[arr])
        assert np.sqrt(np.mean(dn ** 2)) == pytest.approx(float(m.group(1)), abs=0.0006)
        assert np.max(np.abs(dn)) == pytest.approx(float(m.group(2)), abs=0.0006)
    # the second map is the bowl as the virtual machine cut it: the summary's truth figures
    cut = re.search(rf"extended model\s+rms {NUM} um, max {NUM} um", res.stdout)
    first = re.search(rf"uncompensated\s+rms {NUM} um, max {NUM} um", res.stdout)
    mesh = pv.read(out / "map_cut.vtp")
    from mtcomp.demo import form_error
    for arr, m in (("dn_before_um", first), ("dn_after_um", cut)):
        dn = form_error(np.asarray(mesh.point_data[arr]), np.asarray(mesh.points),
                        np.asarray(mesh.point_data["normal"]))
        assert np.sqrt(np.mean(dn ** 2)) == pytest.approx(float(m.group(1)), abs=0.0006)
    with open(out / "BLOCKS.csv", newline="") as f:
        blocks = list(csv.DictReader(f))
    assert "line" in blocks[0] and "cx_um" in blocks[0]
    assert len(blocks) > 1000
    # the machine's bound; a block before the program has positioned X has no correction of X (blank)
    assert max(abs(float(b["cx_um"])) for b in blocks if b["cx_um"]) <= 50.0 + 1e-6
    assert all(b["cx_um"] or "X" in b["unknown_axes"] for b in blocks)


def test_demo_refuses_a_file_as_its_folder(tmp_path):
    f = tmp_path / "taken"
    f.write_text("x")
    res = subprocess.run([sys.executable, "-m", "mtcomp", "demo", "--out", str(f)], cwd=tmp_path,
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 2
    assert res.stderr.count("\n") == 1 and "taken" in res.stderr
    assert f.read_text() == "x"


def test_the_summary_docs_demo_quotes_is_the_one_printed(demo_run):
    """docs/demo.md quotes the summary of the default seed: every line and figure of it is printed
    today (figures to their last quoted digit or 1 %)."""
    from pathlib import Path

    from test_docs_examples import check_quoted
    res = demo_run[0]
    doc = (Path(__file__).resolve().parents[1] / "docs" / "demo.md").read_text()
    block = re.search(r"```\n(summary\n.*?)```", doc, re.S)
    assert block, "docs/demo.md has no summary block"
    printed = res.stdout.splitlines()
    start = printed.index("summary")
    assert check_quoted(block.group(1).splitlines(), printed[start:]) == []

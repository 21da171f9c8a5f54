"""Every example runs as a script, writes nothing where it is run, and prints its key figures (which
are checked against what the virtual machine's truth implies); the figures docs/demo.md's table
quotes of each are the ones it prints today."""
from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
DEMO_DOC = EXAMPLES.parent / "docs" / "demo.md"
NUM = r"(-?\d+(?:\.\d+)?)"


def assert_doc_quotes(script: str, printed: list[float], skip: int = 0) -> None:
    """The numbers of the 'mtcomp' cell of ``script``'s row in docs/demo.md's table (after the
    first ``skip``) are ``printed``, each to its last quoted digit."""
    row = next(r for r in DEMO_DOC.read_text().splitlines() if r.startswith(f"| `{script}`"))
    cell = row.split(" | ")[2]
    quoted = re.findall(r"\d+(?:\.\d+)?", cell)[skip:]
    assert len(quoted) == len(printed), (cell, printed)
    for q, v in zip(quoted, printed):
        digits = len(q.split(".")[1]) if "." in q else 0
        assert abs(float(q) - v) <= 0.5 * 10.0 ** -digits + 1e-9, \
            f"docs/demo.md quotes {q} for {script}, the script prints {v}"


def run_example(name, tmp_path, *args):
    work = tmp_path / "cwd"
    work.mkdir()
    res = subprocess.run([sys.executable, str(EXAMPLES / name), *args], cwd=work, capture_output=True,
                         text=True, timeout=180)
    assert res.returncode == 0, res.stdout + res.stderr
    assert list(work.iterdir()) == []  # nothing written where it was run
    return res.stdout


def test_seed000_irc_beats_traditional_abbe_compensation(tmp_path):
    out = run_example("seed000_irc_abbe.py", tmp_path)
    rows = {}
    for feed, paper in (("180", "0.81"), ("240", "1.12"), ("300", "1.18")):
        m = re.search(rf"^\s+{feed}\s+{NUM}\.\.{NUM}\s+{NUM}\s+{NUM}\s+{NUM}\s+{NUM}\s+{NUM}\s+{NUM}\s+"
                      rf"{re.escape(paper)}\s*$", out, re.M)
        assert m, out
        rows[feed] = [float(v) for v in m.groups()]
    for feed, (y_lo, y_hi, before, trad, irc, gain_t, gain_i, diff) in rows.items():
        assert 0 < y_lo <= y_hi < 210          # the IRC lies between the scale and the point B
        assert irc < trad < before             # both compensations help, the IRC one more
        assert diff == pytest.approx(trad - irc, abs=0.011)
        assert diff > 0.5
    # the truth's IRC moves away from the scale with feed, so the IRC advantage grows with feed
    assert rows["180"][7] < rows["300"][7]
    assert rows["180"][0] < rows["240"][0] < rows["300"][0]
    assert_doc_quotes("seed000_irc_abbe.py", [rows[f][7] for f in ("180", "240", "300")])


def test_seed002_compensation_removes_positioning_error_and_backlash(tmp_path):
    out_dir = tmp_path / "files"
    out = run_example("seed002_rotary_laser.py", tmp_path, "--out", str(out_dir))
    fig = {}
    for key in "ABEMR":
        m = re.search(rf"^{key}  .*?\s{NUM}\s+{NUM}\s*$", out, re.M)
        assert m, out
        fig[key] = (float(m.group(1)), float(m.group(2)))
    assert fig["A"][1] < 0.2 * fig["A"][0]
    assert fig["B"][1] < 0.1 * fig["B"][0]
    m = re.search(rf"backlash: truth {NUM} arcsec, measured {NUM} arcsec", out)
    assert m, out
    assert float(m.group(2)) == pytest.approx(float(m.group(1)), abs=0.3)  # 1 urad noise, 60 readings
    assert_doc_quotes("seed002_rotary_laser.py", [*fig["A"], *fig["B"], float(m.group(1))])
    assert sorted(p.name for p in out_dir.iterdir()) == ["rotary_laser_c_after.csv",
                                                         "rotary_laser_c_before.csv"]


def test_seed003_prediction_error_is_at_the_papers_level(tmp_path):
    out = run_example("seed003_three_sphere.py", tmp_path)
    mean = re.search(rf"^mean \(um\)\s+{NUM}\s+0\.30\s*$", out, re.M)
    mx = re.search(rf"^max \(um\)\s+{NUM}\s+0\.78\s*$", out, re.M)
    assert mean and mx, out
    assert 0 < float(mean.group(1)) < float(mx.group(1)) < 1.5
    assert_doc_quotes("seed003_three_sphere.py", [float(mean.group(1)), float(mx.group(1))])
    for comp in ("EXC", "EYC", "EZC", "EAC", "EBC"):
        assert re.search(rf"^{comp}\s+{NUM}\s+{NUM}\s+u(m|rad)\s*$", out, re.M), out


def test_seed001_compensation_reduces_the_cmm_total_error(tmp_path):
    out_dir = tmp_path / "files"
    out = run_example("seed001_bowl.py", tmp_path, "--out", str(out_dir))
    rows = {}
    for label in ("total error, sum |dn| (um)", "mean |dn| (um)", "rms (um)", "max |dn| (um)"):
        m = re.search(rf"^{re.escape(label)}\s+{NUM}\s+{NUM}\s*$", out, re.M)
        assert m, out
        rows[label] = (float(m.group(1)), float(m.group(2)))
    total_before, total_after = rows["total error, sum |dn| (um)"]
    assert rows["mean |dn| (um)"][0] == pytest.approx(total_before / 100, abs=0.006)  # 100 points
    assert total_after < 0.7 * total_before          # at least the paper's 30 %
    # what remains is the CMM noise (0.3 um) and the fit, not the machine's errors
    assert rows["rms (um)"][1] < 0.8
    m = re.search(rf"total error reduced by {NUM} % \(paper: about 30 % on a real cut\)", out)
    assert m and float(m.group(1)) == pytest.approx(100 * (1 - total_after / total_before), abs=0.6)
    assert_doc_quotes("seed001_bowl.py", [total_before, total_after, float(m.group(1))])
    for name in ("bowl.nc", "bowl_pinv.nc", "MODEL.json", "cmm_uncompensated.csv",
                 "cmm_compensated.csv"):
        assert (out_dir / name).is_file()


def test_study_bounds_prints_what_each_bound_buys(tmp_path):
    out = run_example("study_bounds.py", tmp_path, "--programs", "2", "--draws", "1", "--workers", "2")
    assert "2 programs x 1 models x 1 methods x 5 bound settings x 1 temperatures x 2 draws" in out
    rows = {}
    for name in ("50 um", "3 um", "2 um", "1 um", "0.5 um"):
        m = re.search(rf"^{re.escape(name)}\s+{NUM}\s+{NUM}\s+{NUM}\.\.{NUM}\s+{NUM}\s*$", out, re.M)
        assert m, out
        rows[name] = [float(v) for v in m.groups()]
    before, wide, lo, hi, bounded = rows["50 um"]
    assert wide < 0.3 * before and bounded == 0.0      # wide bounds: most of the error removed
    assert lo <= wide <= hi                             # draw 0 lies within the draws' range
    afters = [rows[n][1] for n in rows]
    # a tighter bound never buys accuracy (the same programs, the same judge)
    assert all(b >= a - 1e-3 for a, b in zip(afters, afters[1:]))
    assert rows["0.5 um"][4] > 50 and rows["0.5 um"][1] > 2 * wide

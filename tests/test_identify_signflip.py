"""A laser file whose sign is reversed (written as target - measured, or taken with the laser's
direction set the wrong way) is named by `identify` when it disagrees with the others and agrees with
them reversed, and by `diagnose` when its final model leaves it unexplained; the file is never
reversed.

Oracle: the independent truth machine (tests/truth): three positioning runs of X at three set-ups
of one random machine, the third written with its sign reversed by hand. Reversed back it is a run
of the same machine as the other two, so it must agree with them to their noise (0.2 um); as written
it is off by twice its error. The linearised refit (:mod:`mtcomp.identification.signflip`) is
checked against a second formulation: the fit of the files with the third reversed back."""
from __future__ import annotations

import csv

import numpy as np

from mtcomp.cli import main
from mtcomp.identification import signflip
from mtcomp.identification.fit import identify
from mtcomp.machine import load_machine
from mtcomp.measurement.files import read_measurements
from truth import TruthMachine
from truth import campaigns as tc

NOISE_UM = 0.2


def _runs(tmp_path, seed=0):
    """Three positioning runs of X of one random truth machine, at one place (Y = Z = 0): they
    differ by their set-ups (laser zero) and noise only."""
    rng = np.random.default_rng(seed)
    truth = TruthMachine.random("xfyz", rng)
    return [tc.laser(truth, tmp_path / f"run{k}.csv", rng, "X", components=("EXX",),
                     noise_um=NOISE_UM).path for k in range(3)]


def _reversed(path, out):
    rows = list(csv.reader(open(path, newline="")))
    i = rows[0].index("value_um")
    for r in rows[1:]:
        r[i] = repr(-float(r[i])) if r[i] else r[i]
    with open(out, "w", newline="") as f:
        csv.writer(f).writerows(rows)
    return out


def test_a_laser_file_with_its_sign_reversed_is_named(tmp_path, capsys):
    runs = _runs(tmp_path)
    bad = _reversed(runs[2], tmp_path / "run2_reversed.csv")
    out = tmp_path / "m.json"
    assert main(["identify", "xfyz", str(runs[0]), str(runs[1]), str(bad), "-o", str(out)]) == 0
    err = capsys.readouterr().err
    told = [ln for ln in err.splitlines() if "sign reversed" in ln]
    assert len(told) == 1, err
    assert told[0].startswith(f"warning: {bad}: its readings agree with the other files with their "
                              "sign reversed")
    assert "error = measured - target (ISO 230-2)" in told[0] and "laser's direction" in told[0]
    assert "reversed instead" not in told[0]        # two runs against one: the data tell which
    assert out.exists()
    # the right files: nothing of the kind
    assert main(["identify", "xfyz", *map(str, runs), "-o", str(tmp_path / "ok.json")]) == 0
    assert "sign reversed" not in capsys.readouterr().err


def test_the_linearised_refit_is_the_fit_of_the_file_reversed_back(tmp_path):
    runs = _runs(tmp_path)
    bad = _reversed(runs[2], tmp_path / "run2_reversed.csv")
    machine = load_machine("xfyz")
    data = [read_measurements(p) for p in (runs[0], runs[1], bad)]
    res = identify(machine, data)
    R = signflip._refits(res.problem, res, [2])
    rms = signflip._file_rms(res, R)
    # a second formulation: the files as they should be, fitted by identify
    right = identify(machine, [read_measurements(p) for p in runs])
    truth_rms = [f.rms_error_units()["um"] for f in right.files]
    # as written the reversed run is off by twice the machine's X error; reversed back, it and the
    # others sit at the noise, as identify's fit of the right files leaves them
    assert rms[2, 0] > 5 * NOISE_UM
    np.testing.assert_allclose(rms[:, 1], truth_rms, rtol=0.25)
    assert signflip.reversed_sign_note(res, data, res.problem).startswith(f"{bad}: ")


def test_laser_runs_of_two_machines_are_not_called_reversed(tmp_path, capsys):
    rng = np.random.default_rng(0)
    a, b = TruthMachine.random("xfyz", rng), TruthMachine.random("xfyz", rng)
    runs = [tc.laser(m, tmp_path / f"{name}.csv", rng, "X", components=("EXX",), noise_um=NOISE_UM).path
            for m, name in ((a, "a"), (a, "a_again"), (b, "b"))]
    assert main(["identify", "xfyz", *map(str, runs), "-o", str(tmp_path / "m.json")]) == 0
    err = capsys.readouterr().err
    assert "the files do not agree" in err and "sign reversed" not in err, err
    assert "cannot judge" not in err                # every file has repeats to judge it by
    # beside a ball bar (no repeats): the test cannot judge it, and says so, naming it (a new
    # user's R-test file in radians pulled the fit off while the warning named a laser file only)
    bar = tc.ballbar_circles(a, tmp_path / "bar.csv", rng, planes=("XY",)).path
    assert main(["identify", "xfyz", *map(str, runs), str(bar), "-o", str(tmp_path / "m2.json")]) == 0
    told = [ln for ln in capsys.readouterr().err.splitlines() if "do not agree" in ln]
    assert len(told) == 1 and "it cannot judge the files without repeats: bar" in told[0], told


def test_diagnose_names_the_reversed_file_it_leaves_unexplained(tmp_path, capsys):
    runs = _runs(tmp_path)
    bad = _reversed(runs[2], tmp_path / "run2_reversed.csv")
    report = tmp_path / "r.json"
    assert main(["diagnose", "xfyz", str(runs[0]), str(runs[1]), str(bad), "--json", str(report),
                 "-q"]) == 0
    captured = capsys.readouterr()
    told = [ln for ln in captured.err.splitlines() if "sign reversed" in ln]
    assert len(told) == 1 and told[0].startswith(f"warning: {bad}: its readings agree"), captured.err
    assert "verdict: unexplained" in captured.out
    # the right files: explained, nothing said
    assert main(["diagnose", "xfyz", *map(str, runs), "--json", str(report), "-q"]) == 0
    assert "sign reversed" not in capsys.readouterr().err


def test_diagnose_records_the_tools_its_data_were_taken_with_as_identify_does(tmp_path, capsys):
    """diagnose's MODEL.json records the data's tool lengths (info.tool_length_mm) as identify's
    does, so that compensate says when a program's tools are longer or shorter (a new user's
    diagnosed model had none, and the note never came)."""
    import json
    runs = _runs(tmp_path)
    assert main(["identify", "xfyz", *map(str, runs), "-o", str(tmp_path / "i.json")]) == 0
    assert main(["diagnose", "xfyz", *map(str, runs), "-o", str(tmp_path / "d.json"), "-q",
                 "--json", str(tmp_path / "r.json")]) == 0
    capsys.readouterr()
    tools = [json.loads((tmp_path / f"{k}.json").read_text())["info"].get("tool_length_mm")
             for k in "id"]
    assert tools[0] is not None and tools[1] == tools[0], tools

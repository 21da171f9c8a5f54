"""A model without a reversal term whose data show one: export (and compensate, through
:func:`mtcomp.export.reversal_note`) says so in one line, with the size per axis and diagnose.

Oracles: the reversal recorded from the data is checked against the truth the laser file was
written with, and its p-value against a second formulation: the F test of two nested least-squares
fits (one mean per target, against one mean per target and direction), computed here with numpy.
"""
import json
import re

import numpy as np
import pytest
from scipy.stats import f as fisher_f

from laser_files import write_x_positioning
from mtcomp.cli import main
from mtcomp.export import reversal_note
from mtcomp.identification.fit import identify
from mtcomp.identification.reversal import REVERSAL_P, data_reversal
from mtcomp.machine import load_machine
from mtcomp.measurement.files import read_measurements
from mtcomp.models import Backlash, save_model
from mtcomp.models.model_file import load_model
from test_export_formats import random_model

TARGETS = (-20, -10, 0, 10, 20, 30, 40)


def _profile(t):
    return 8.0 * np.sin(t / 9.0) + 0.05 * t


def _laser(tmp_path, reversal_um, noise_um=0.3, seed=7, n_runs=3):
    """X positioning runs whose reversal (mean up minus mean down) at target t is reversal_um(t)."""
    return write_x_positioning(tmp_path / "x_runs.csv", TARGETS,
                               lambda t, d: _profile(t) + 0.5 * d * reversal_um(t), n_runs, noise_um,
                               np.random.default_rng(seed))


def _nested_f_test(path):
    """(F, p) of 'one mean per target and direction' against 'one mean per target' (numpy lstsq)."""
    rows = [line.split(",") for line in path.read_text().splitlines()[1:]]
    t = np.array([float(r[2]) for r in rows])
    d = np.array([int(r[3]) for r in rows])
    y = np.array([float(r[5]) for r in rows])
    targets = np.unique(t)
    A = np.column_stack([(t == s).astype(float) for s in targets])
    B = np.column_stack([A, A * d[:, None]])

    def rss(X):
        beta, *_ = np.linalg.lstsq(X, y, rcond=None)
        return float(np.sum((y - X @ beta) ** 2))

    m, dof = len(targets), len(y) - 2 * len(targets)
    F = (rss(A) - rss(B)) / m / (rss(B) / dof)
    return F, float(fisher_f.sf(F, m, dof))


def test_recorded_reversal_is_the_data_reversal_and_its_f_test(tmp_path):
    truth = lambda t: -25.0 + 0.2 * t         # noqa: E731  (a reversal that changes along X)
    path = _laser(tmp_path, truth)
    rec = data_reversal([read_measurements(path)])["X"]
    expected = np.array([truth(t) for t in TARGETS])
    # noise 0.3 um per reading, 3 runs per direction: a B_i is within 4 sd (0.25 um each) of the truth
    assert rec["B_mean_um"] == pytest.approx(expected.mean(), abs=0.4)
    assert rec["B_um"] == pytest.approx(expected[np.argmax(np.abs(expected))], abs=1.0)
    assert rec["n_targets"] == len(TARGETS) and rec["files"] == ["x_runs"]
    # the p-value against the nested least-squares formulation, on data where it is not 0 to
    # double precision: a small reversal at the noise
    small = _laser(tmp_path, lambda t: 0.35, noise_um=0.5, seed=3)
    F, p = _nested_f_test(small)
    assert 1e-12 < p < 0.9
    assert data_reversal([read_measurements(small)])["X"]["p_value"] == pytest.approx(p, rel=1e-9, abs=0)


def test_noise_without_reversal_is_not_called_a_reversal(tmp_path):
    for seed in range(5):
        path = _laser(tmp_path, lambda t: 0.0, noise_um=2.0, seed=seed)
        assert data_reversal([read_measurements(path)])["X"]["p_value"] > REVERSAL_P


def test_single_runs_cannot_be_judged(tmp_path):
    path = _laser(tmp_path, lambda t: -25.0, n_runs=1)
    rec = data_reversal([read_measurements(path)])["X"]
    assert rec["p_value"] is None and rec["B_mean_um"] == pytest.approx(-25.0, abs=1.5)


def _size(text, before="X "):
    """The reversal (um) the text gives after ``before``."""
    return float(re.search(re.escape(before) + r"\(?([+-]\d+\.\d) um", text).group(1))


def _identified(tmp_path, path):
    """identify() on ``path`` with the data's reversal recorded as MODEL.json records it."""
    data = [read_measurements(path)]
    fitted = identify(load_machine("xfyz"), data).fitted_model
    fitted.info["reversal"] = data_reversal(data)
    out = tmp_path / "model.json"
    save_model(out, fitted)
    return out


def test_export_says_once_that_the_tables_drop_the_data_reversal(tmp_path, capsys):
    model = _identified(tmp_path, _laser(tmp_path, lambda t: -25.0))
    assert main(["export", "xfyz", str(model), "--format", "linuxcnc", "-o", str(tmp_path / "lc")]) == 0
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if "reversal" in line]
    assert len(lines) == 1, err
    assert _size(lines[0]) == pytest.approx(-25.0, abs=0.5) and "mtcomp diagnose" in lines[0]
    assert lines[0].strip() == "note: " + reversal_note(load_model(model))
    comp = np.loadtxt(tmp_path / "lc" / "x.comp")
    np.testing.assert_array_equal(comp[:, 1], comp[:, 2])    # what the note warns of
    ini = (tmp_path / "lc" / "ini_lines.txt").read_text()
    assert _size(ini, "ITS DATA SHOW ONE ") == pytest.approx(-25.0, abs=0.5) and "the reversal is in the two columns" not in ini
    assert reversal_note(load_model(model)) in (tmp_path / "lc" / "README.txt").read_text()


def test_no_note_when_the_model_holds_the_reversal_or_the_data_show_none(tmp_path, capsys):
    fitted = random_model("xfyz", (Backlash("X"),), 5, 10.0, {"X": (-20.0, 40.0)})
    fitted.params.set_file_value("BL_X", -25.0)
    fitted.info["reversal"] = data_reversal([read_measurements(_laser(tmp_path, lambda t: -25.0))])
    assert reversal_note(fitted) is None
    save_model(tmp_path / "bl.json", fitted)
    assert main(["export", "xfyz", str(tmp_path / "bl.json"), "--format", "linuxcnc", "-o", str(tmp_path / "a")]) == 0
    assert "reversal (mean up" not in capsys.readouterr().err
    comp = np.loadtxt(tmp_path / "a" / "x.comp")
    # trims: minus the error; one step beyond each end of the data the table is zero
    np.testing.assert_allclose(comp[1:-1, 2] - comp[1:-1, 1], -25.0e-3, rtol=0, atol=1e-6)
    assert np.all(comp[[0, -1], 1:] == 0.0)
    assert "the reversal is in the two columns" in (tmp_path / "a" / "ini_lines.txt").read_text()
    none = _identified(tmp_path, _laser(tmp_path, lambda t: 0.0, noise_um=2.0))
    assert reversal_note(load_model(none)) is None


def test_a_diagnose_model_says_diagnose_did_not_keep_it(tmp_path):
    model = _identified(tmp_path, _laser(tmp_path, lambda t: -25.0))
    data = json.loads(model.read_text())
    data["info"]["diagnose"] = {"verdict": "none"}
    model.write_text(json.dumps(data))
    note = reversal_note(load_model(model))
    assert _size(note) == pytest.approx(-25.0, abs=0.5) and "did not keep a backlash term" in note


def test_identify_then_export_on_the_command_line(tmp_path, capsys):
    laser = _laser(tmp_path, lambda t: -25.0)
    assert main(["identify", "xfyz", str(laser), "-o", str(tmp_path / "m.json")]) == 0
    assert main(["export", "xfyz", str(tmp_path / "m.json"), "--format", "isg", "-o", str(tmp_path / "i")]) == 0
    assert _size(capsys.readouterr().err) == pytest.approx(-25.0, abs=0.5)


def _compensate_lines(tmp_path, capsys, laser, x_far: float, word: str) -> list[str]:
    """The lines of compensate's output holding ``word``, for a model identified from ``laser``
    and a program along X to ``x_far``."""
    assert main(["identify", "xfyz", str(laser), "-o", str(tmp_path / "m.json")]) == 0
    prog = tmp_path / "p.nc"
    prog.write_text(f"G21 G90\nG0 X10 Y0 Z0\nG1 X{x_far:g} F500\nG1 X20\nM30\n")
    capsys.readouterr()
    assert main(["compensate", "xfyz", str(tmp_path / "m.json"), str(prog), "-o",
                 str(tmp_path / "o.nc"), "--quiet"]) == 0
    return [line for line in capsys.readouterr().out.splitlines() if word in line]


def test_compensate_says_it_too(tmp_path, capsys):
    said = _compensate_lines(tmp_path, capsys, _laser(tmp_path, lambda t: -25.0), 100, "reversal")
    assert len(said) == 1 and "mtcomp diagnose" in said[0]
    assert _size(said[0]) == pytest.approx(-25.0, abs=0.5)


def test_diagnose_records_the_reversal_its_data_show(tmp_path, capsys):
    """A diagnosed model records the data's reversal too, so that export can name one diagnose did
    not keep (it was recorded by identify only)."""
    laser = _laser(tmp_path, lambda t: -25.0)
    assert main(["diagnose", "xfyz", str(laser), "--json", str(tmp_path / "r.json"), "-o",
                 str(tmp_path / "m.json")]) == 0
    rec = json.loads((tmp_path / "m.json").read_text())["info"]["reversal"]
    assert rec["X"]["B_mean_um"] == pytest.approx(-25.0, abs=0.5)
    assert rec["X"]["p_value"] < REVERSAL_P


def test_identify_says_what_the_data_show_of_a_reversal(tmp_path, capsys):
    """identify prints the same one line as export and compensate when its data reverse (here
    -25 um at every target), and none when they do not."""
    for reversal, said in ((-25.0, True), (0.0, False)):
        folder = tmp_path / f"r{int(-reversal)}"
        folder.mkdir()
        data = _laser(folder, lambda t, r=reversal: r)
        assert main(["identify", "xfyz", str(data), "-o", str(folder / "m.json")]) == 0
        lines = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("note: the data show a reversal")]
        assert len(lines) == (1 if said else 0), lines
        if said:
            assert re.search(r"X -25\.\d um", lines[0]), lines[0]


def test_one_approach_direction_is_recorded_and_said(tmp_path, capsys):
    """X's positioning read approaching in + only (the bidirectional runs' + rows kept): the data
    cannot know the reversal, so the model records X as read from + only and compensate says that
    it leaves the moves approaching in - uncorrected (an identifiability tester's campaign: an 8 um
    reversal made 29 of 121 lines worse, without a word). The same runs read
    both ways record a reversal, not one direction; a Y file read both ways adds nothing."""
    both = _laser(tmp_path, lambda t: -8.0)
    lines = both.read_text().splitlines()
    plus = tmp_path / "x_plus.csv"
    plus.write_text("\n".join([lines[0]] + [r for r in lines[1:] if r.split(",")[3] == "1"]) + "\n")
    assert data_reversal([read_measurements(plus)]) == {"X": {"one_direction": "+", "files": ["x_plus"]}}
    assert "one_direction" not in data_reversal([read_measurements(both)])["X"]
    said = _compensate_lines(tmp_path, capsys, plus, 40, "the data read the approach X in + only")
    assert len(said) == 1 and "compensate leaves uncorrected the blocks that approach X in -" \
        in said[0], said

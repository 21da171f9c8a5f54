"""identify says when one residual variance serves files of very different noise (--weights unit)
and names --weights noise; not when the files are alike, nor under --weights noise."""
import numpy as np

from laser_files import write_positioning
from mtcomp.cli import main

TARGETS = tuple(range(-40, 41, 10))


def _notes(tmp_path, capsys, noise_x, noise_y, *extra):
    rng = np.random.default_rng(5)
    x = write_positioning(tmp_path / "x.csv", "X", TARGETS, lambda t, d: 5 * np.sin(t / 30), 5, noise_x, rng)
    y = write_positioning(tmp_path / "y.csv", "Y", TARGETS, lambda t, d: 3 * np.cos(t / 20), 5, noise_y, rng)
    assert main(["identify", "xfyz", str(x), str(y), "-o", str(tmp_path / "m.json"), *extra]) == 0
    return [ln for ln in capsys.readouterr().out.splitlines() if "rms residuals differ" in ln]


def test_files_of_very_different_noise_get_the_note(tmp_path, capsys):
    notes = _notes(tmp_path, capsys, 3.0, 0.3)
    assert len(notes) == 1 and "--weights noise" in notes[0]
    # the loud file first, then the quiet one, each with its rms (about its noise, in um)
    tags = notes[0].split("(")[1].split(")")[0]
    assert tags.startswith("x ") and ", y " in tags


def test_alike_files_and_noise_weights_get_none(tmp_path, capsys):
    assert _notes(tmp_path, capsys, 1.0, 1.0) == []
    assert _notes(tmp_path, capsys, 3.0, 0.3, "--weights", "noise") == []

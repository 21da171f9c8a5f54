"""G92 (coordinate system offset set by the program): followed where it is exact, refused in one
line where not. Hand-derived machine positions and written words, a G92 before any move (the
offset assumed 0, said once), G92.1, G92 with G52 (LinuxCNC shares their offsets; Fanuc refused),
and compensated programs replayed by the test-side controller (tests/replay.py), which follows
G92 by its own code."""
import math
import re
from pathlib import Path

import numpy as np
import pytest

from mtcomp.errors import InputError
from mtcomp.machine import load_machine
from mtcomp.toolpaths import iter_segment_chunks
from mtcomp.toolpaths.source import open_program
from replay import Tolerance, compare, replay
from test_compensate_cli import _model, _read_report, _run
from test_toolpaths_dialect import mode  # noqa: F401  (the fixture: both reader paths)
from test_toolpaths_frames import corrected_with_notes

XFYZ = load_machine("xfyz")
CORPUS = Path(__file__).parent / "data" / "gcode_corpus"


def _linear_x(q):
    """A correction that depends on machine X only: 1e-4 x (mm)."""
    return np.column_stack([1e-4 * q[:, 0], 0 * q[:, 0], 0 * q[:, 0]])


def _corrected(tmp_path, text, dialect="grbl", correction=_linear_x):
    """(machine ends (n, 3), known (n, 3), output lines, notes) of ``text`` written with the
    machine-frame correction ``correction(machine ends)``, through the same steps as compensate."""
    return corrected_with_notes(tmp_path, text, dialect, correction)


def test_g92_at_a_known_position_places_later_blocks_and_takes_its_correction_back(tmp_path, mode):
    """At X10, `G92 X0`: the offset is 10, so `X5` is machine X15 (correction 1.5 um there). The
    output's G92 line is the source's, read where the corrected tool stands (X10.0010), so its
    offset is 10.0010: the word reaching machine 15.0015 is X5.0005. The source's and the output's
    machine positions are replayed by hand below."""
    text = "G21 G90\nG0 X10. Y0 Z5.\nG92 X0\nG1 X5. F100\nX-2.\nM30\n"
    ends, known, lines, notes = _corrected(tmp_path, text)
    np.testing.assert_allclose(ends[:, 0], [10.0, 15.0, 8.0], rtol=0, atol=1e-12)
    assert known.all()
    assert lines == ["G21 G90", "G0 X10.0010 Y0 Z5.", "G92 X0", "G1 X5.0005 F100", "X-2.0002",
                     "M30"]
    # the output on the controller: offset = where it stands less the declared value
    offset = 10.0010 - 0.0
    for word, machine in ((5.0005, 15.0), (-2.0002, 8.0)):
        assert math.isclose(word + offset, machine * (1 + 1e-4), rel_tol=0, abs_tol=1e-9)
    assert not notes


def test_g92_under_g91_moves_are_increments_from_the_declared_value(tmp_path, mode):
    """After `G92 X0` the output's controller reads X0 wherever it stands: the increment to the
    written X5.0005 (see above) is 5.0005."""
    text = "G21 G90\nG0 X10. Y0 Z5.\nG92 X0\nG91\nG1 X5. F100\nX-7.\nG90\nM30\n"
    _ends, _known, lines, _notes = _corrected(tmp_path, text)
    assert lines[4:6] == ["G1 X5.0005 F100", "X-7.0007"]


def test_g92_before_any_move_is_taken_with_offset_zero_and_said(tmp_path, mode):
    """`G92 Z50 X-10` before any move: X and Z are known at the declared values (their machine
    positions assumed to be the program's, plus the work offset), Y is not until named; the
    first block (Y not known) gets no correction, the next ones do."""
    text = "G21 G90\nG92 Z50. X-10.\nG0 Z10.\nG0 X0 Y0\nG1 X20. F100\nM30\n"
    ends, known, lines, notes = _corrected(tmp_path, text)
    np.testing.assert_allclose(ends[:, [0, 2]], [[-10, 10], [0, 10], [20, 10]], rtol=0, atol=1e-12)
    assert known.tolist() == [[True, False, True], [True, True, True], [True, True, True]]
    assert lines == ["G21 G90", "G92 Z50. X-10.", "G0 Z10.", "G0 X0 Y0", "G1 X20.0020 F100", "M30"]
    assert len(notes) == 1 and notes[0].startswith("assumed: G92 at line 2 sets X Z where")


def test_g92_before_any_move_through_compensate_says_it_once(tmp_path, capsys):
    _machine, _fitted, model = _model(tmp_path, "xfyz", seed=5)
    prog, out = tmp_path / "in.nc", tmp_path / "out.nc"
    prog.write_text("G21 G90\nG92 X0 Y0 Z0\nG1 X5. F300\nY5.\nG92 X0 Y0\nG1 X5.\nM30\n")
    code, stdout, err = _run(["compensate", "xfyz", str(model), str(prog), "-o", str(out),
                              "--dialect", "grbl"], capsys)
    assert code == 0, err
    said = [ln for ln in (stdout + err).splitlines() if "assumed: G92" in ln]
    assert len(said) == 1 and "line 2 sets X Y Z" in said[0]


def test_g92_1_cancels_the_offset(tmp_path, mode):
    """`G92 X0` at X10, `G92.1`: the offset is 0 again, every axis unknown until named; `G0 X5 Y0
    Z5` is machine X5."""
    text = "G21 G90\nG0 X10. Y0 Z5.\nG92 X0\nG92.1\nG0 X5. Y0 Z5.\nM30\n"
    ends, known, lines, _notes = _corrected(tmp_path, text)
    np.testing.assert_allclose(ends[:, 0], [10.0, 5.0], rtol=0, atol=1e-12)
    assert lines[4] == "G0 X5.0005 Y0 Z5."


def test_g92_while_g52_on_linuxcnc_shares_its_offset(tmp_path, mode):
    """LinuxCNC: G52 and G92 share one offset. At program X10 under G52 X100 (machine 110),
    `G92 X0` makes the offset 110: `X5` is machine 115. A G52 after it sets the offset to its
    value (X7: machine 7 + 20 = 27), in the output too."""
    text = ("G21 G90\nG0 X10. Y0 Z5.\nG52 X100.\nG1 X10. F100\nG92 X0\nG1 X5.\nG52 X20.\n"
            "G1 X7.\nM30\n")
    ends, known, lines, _notes = _corrected(tmp_path, text, "linuxcnc")
    np.testing.assert_allclose(ends[:, 0], [10.0, 110.0, 115.0, 27.0], rtol=0, atol=1e-12)
    assert known.all()
    # at the G92 the output stands at program X10.0110 (machine 110.0110): its offset is 110.0110,
    # so machine 115.0115 is written X5.0005; G52 X20. is the same offset in both: X7.0027
    assert lines[3:8] == ["G1 X10.0110 F100", "G92 X0", "G1 X5.0005", "G52 X20.", "G1 X7.0027"]


@pytest.mark.parametrize("text, words", [
    ("G0 X1. Y1. Z1.\nG52 X5.\nG92 X0\n", ["p.nc:3:", "G92 while G52 is in force", "fanuc"]),
    ("G0 X1. Y1. Z1.\nG92 X0\nG52 X5.\n", ["p.nc:3:", "G52 while a G92 offset is in force"]),
])
def test_g92_with_g52_on_fanuc_is_refused(tmp_path, text, words):
    p = tmp_path / "p.nc"
    p.write_text(text)
    with pytest.raises(InputError) as exc:
        with open_program(p, "fanuc") as src:
            list(iter_segment_chunks(src, XFYZ))
    msg = str(exc.value)
    assert "\n" not in msg and all(w in msg for w in words), msg


@pytest.mark.parametrize("text, line, words", [
    ("G0 X1 Y1 Z1\nG91\nG92 X0\n", 3, ["G92 under G91"]),
    ("G0 X1 Y1 Z1\nG92\n", 2, ["G92 without axis words"]),
    ("G0 X1 Y1 Z1\nG92 X0 G0 Y2\n", 2, ["G92 and a move in one block"]),
    ("G0 X1 Y1 Z1\nG92.3\n", 2, ["G92.3"]),
    ("G0 X1 Y1 Z1\nT2 M6\nG92 Z0\n", 3, ["G92 Z where the program has lost the position"]),
    ("G0 X1 Y1 Z1\nG55\nG92 X0\n", 3, ["G92 X where the program has lost the position"]),
])
def test_refusals_name_the_line_and_the_construct(tmp_path, mode, text, line, words):
    p = tmp_path / "p.nc"
    p.write_text(text)
    with pytest.raises(InputError) as exc:
        with open_program(p, "grbl") as src:
            list(iter_segment_chunks(src, XFYZ))
    msg = str(exc.value)
    assert f"p.nc:{line}:" in msg and "\n" not in msg and all(w in msg for w in words), msg


def test_g92_after_homing_is_followed(tmp_path, mode):
    """After `G28` the axes stand at home in the source and in the output alike: a G92 there is
    the before-any-move case (offset assumed 0)."""
    text = "G21 G90\nG0 X1. Y1. Z1.\nG28\nG92 X0 Y0 Z0\nG1 X3. F100\nM30\n"
    ends, _known, lines, notes = _corrected(tmp_path, text)
    np.testing.assert_allclose(ends[-1], [3, 0, 0], rtol=0, atol=1e-12)
    assert lines[4] == "G1 X3.0003 F100" and len(notes) == 1


def test_g92_keeps_its_offset_across_a_work_system_change(tmp_path, mode):
    """grbl (and every controller): the G92 offset applies in every work system."""
    text = "G21 G90\nG0 X10. Y0 Z5.\nG92 X0\nG55\nG0 X5. Y0 Z5.\nM30\n"
    ends, _known, _lines, _notes = _corrected(tmp_path, text)
    np.testing.assert_allclose(ends[:, 0], [10.0, 15.0], rtol=0, atol=1e-12)


# ------------------------------------------------------------- compensated and replayed
BOUND_UM = 20.0
TOL = Tolerance(axis_mm=BOUND_UM * 1e-3 + 2e-4, axis_deg=1.0,
                path_mm=math.sqrt(3) * (BOUND_UM * 1e-3 + 2e-4) + 2e-3)


def _compensated(tmp_path, capsys, text, name, dialect="grbl"):
    _machine, _fitted, model = _model(tmp_path, "xfyz", seed=3, scale=30.0)
    prog, out, rep = tmp_path / f"{name}.nc", tmp_path / f"{name}.out.nc", tmp_path / "b.csv"
    prog.write_text(text)
    code, _o, err = _run(["compensate", "xfyz", str(model), str(prog), "-o", str(out), "--quiet",
                          "--dialect", dialect, "--max-correction-um", str(BOUND_UM),
                          "--subdivide-tol-um", "0", "--report", str(rep)], capsys)
    assert code == 0, err
    return prog.read_bytes(), out.read_bytes(), _read_report(rep)


def test_output_reaches_the_source_position_plus_the_reported_correction(tmp_path, capsys):
    """Each block of the output, replayed on the controller (its own G92 offsets, set where the
    output stands), ends at the source's replayed end plus the correction BLOCKS.csv reports."""
    text = ("G21 G90\nG0 X10. Y20. Z5.\nG1 X40. F500\nG92 X0 Y0\nG1 X30. Y10.\nG1 X-20.\n"
            "G92 Y100.\nG1 Y110.\nG92.1\nG0 X12. Y3. Z4.\nM30\n")
    src, out, rows = _compensated(tmp_path, capsys, text, "p")
    a, b = replay(src).moves, replay(out).moves
    assert len(a) == len(b) == len(rows) == 6
    moved = 0.0
    for m_src, m_out, row in zip(a, b, rows):
        assert m_src.line + 1 == int(row["line"])
        for axis in "XYZ":
            c = float(row[f"c{axis.lower()}_um"]) * 1e-3
            got = m_out.end[axis] - m_src.end[axis]
            assert math.isclose(got, c, rel_tol=0, abs_tol=1.5e-4), (row["line"], axis, got, c)
            moved = max(moved, abs(c))
    assert moved > 1e-3          # the corrections are not zero


@pytest.mark.parametrize("name, fix", [
    # the real programs with G92 before any move, without the lines refused for other reasons
    ("cncwebsim_fresa.gcode", lambda t: t.replace("\x01", "")),
    ("cncwebsim_fresa2.cnc", lambda t: re.sub(r"(?m)^(G1 X145 Y-36\.4) R20", r"\1", t)),
])
def test_corpus_programs_with_g92_move_like_the_source(tmp_path, capsys, name, fix):
    text = fix((CORPUS / name).read_text(encoding="latin-1"))
    src, out, _rows = _compensated(tmp_path, capsys, text, "prog")
    src_moves, out_moves = compare(src, out, TOL, name=name)
    assert len(src_moves) > 50
    shift = max(abs(m.end[a] - n.end[a]) for m, n in zip(src_moves, out_moves) for a in "XYZ"
                if m.end[a] is not None and n.end[a] is not None)
    assert shift > 1e-3         # corrected somewhere

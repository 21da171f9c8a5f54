"""Under cutter radius compensation (G41/G42, Heidenhain RL/RR) the controller offsets every move
in the offset plane perpendicular to its own direction: a block that does not move in the plane
must get no plane words (a micro-move there swings the offset vector by up to 180 degrees), and a
block that does may have its direction turned by its correction only a little (CRC_TURN). The
oracle is the tests' own type-C offset (crc_offset.py, from the controllers' descriptions): the
tool centre's path of the written program must be the source's moved by about the correction."""
import csv
import math
import re

import numpy as np
import pytest

from crc_offset import compare_centres, heidenhain_as_gcode
from mtcomp.cli import main
from mtcomp.planner._links import CRC_TURN
from test_gcode_corpus import _machine_file, _model_file
from test_planner_crc_arcs import _both_readers
from test_planner_reversal_written import _model

#: the safety tester's programs (plunges and retracts of Z under G41, G41 and G40 lines naming
#: only Z, a G68 rotation, Heidenhain RL, Sinumerik)
PROGRAMS = {
    "crc2.nc": ("%\nO2001\nG21 G17 G90 G40 G49 G80\nG54 G0 X-20. Y-20.\nG43 H1 Z50.\nG0 Z5.\n"
                "G41 D1 G1 X0. Y0. F500.\nG1 Z-2. F300.\nG1 Y100. F500.\nG1 Z-4.\nG1 X200.\n"
                "G1 Z5.\nG40 G1 X220. Y120.\nG0 Z50.\nM30\n%\n", "fanuc"),
    "crc3.nc": ("%\nO2002\nG21 G17 G90 G40 G49 G80\nG54 G0 X0. Y-20.\nG43 H1 Z5.\n"
                "G41 D1 G1 Z-2. F300.\nG1 Y100. F500.\nG3 X50. Y150. R50.\nG1 X200.\n"
                "G40 G1 Z5.\nG0 X250.\nM30\n%\n", "fanuc"),
    "f_c5.nc": ("%\nO6004\nG21 G17 G90\nG54 G0 X10. Y10. Z10.\nG68 X0. Y0. R30.\n"
                "G1 X20. Y20. F300.\nG41 D1 G1 X30. Y30.\nG1 Z-1.\nG1 X40.\nG40 G1 X50. Y50.\n"
                "G69\nM30\n%\n", "fanuc"),
    "s_ctrans.mpf": ("%_N_T9_MPF\nG17 G90 G71 G40 G54\nG0 X0 Y0 Z10\nG1 X10 F300\n"
                     "G41 G1 X20 Y5\nG1 Z5\nG1 Y30\nG40 G1 X40\nM30\n", "sinumerik"),
    "h1.h": ("0 BEGIN PGM H1 MM\n1 TOOL CALL 1 Z S1000\n2 L Z+50 R0 FMAX\n3 L X-20 Y-20 R0 FMAX\n"
             "4 L Z+5 R0 FMAX\n5 L X+0 Y+0 RL F500\n6 L Z-2 F300\n7 L Y+100 F500\n8 L Z-4\n"
             "9 L X+200\n10 L Z+5\n11 L X+220 Y+120 R0\n12 L Z+50 FMAX\n13 END PGM H1 MM\n", None),
}
#: the tool radius of the oracle (mm)
R_MM = 5.0


@pytest.fixture(scope="module")
def large_model(tmp_path_factory):
    """The corpus test's XFYZ machine with a model of 100 times the usual errors (as the safety
    tester's), so that every block asks for a correction of tens of um that changes with Z."""
    d = tmp_path_factory.mktemp("crc_plane")
    machine = _machine_file(d, "XFYZ")
    return machine, _model_file(d, machine, factor=100.0)


def _compensate(tmp_path, machine, model, name, text, *extra):
    src, out, rep = tmp_path / name, tmp_path / f"out_{name}", tmp_path / "B.csv"
    src.write_text(text)
    assert main(["compensate", str(machine), str(model), str(src), "-o", str(out), "--report",
                 str(rep), "--quiet", *extra]) == 0
    with open(rep, newline="") as f:
        return out.read_text(), list(csv.DictReader(f))


def _plane_words(line: str, letters="XY"):
    return set(re.findall(rf"(?<![A-Z])([{letters}])\s*[-+]?[\d.]", line.split("(")[0].split(";")[0]))


def _under_compensation(lines):
    """The lines, None for those not run under cutter radius compensation (in force, or switched
    on or off by the line)."""
    on = False
    for line in lines:
        code = re.findall(r"G0*4([012])(?![\d.])|\b(RL|RR|R0)\b", line.upper())
        was = on
        if code:
            on = code[-1][0] in ("1", "2") or code[-1][1] in ("RL", "RR")
        yield line if (on or was) else None


@pytest.mark.parametrize("name", sorted(PROGRAMS))
def test_no_plane_micro_moves_under_cutter_compensation(tmp_path, large_model, name):
    """A block under compensation that does not move in the plane (a plunge, a retract, a G41 or
    G40 line naming only Z) is written without plane words, and the tool centre's path of the
    written program is the source's moved by no more than the correction (on the code before
    this rule, crc3.nc's G41 line got an 11.5 um move toward the part: the oracle's moves in the
    plane differ, and the centre path left the contour by millimetres)."""
    text, dialect = PROGRAMS[name]
    out, _rows = _compensate(tmp_path, *large_model, name, text, "--max-correction-um", "1000",
                             "--max-step-um", "1000", *(["--dialect", dialect] if dialect else []))
    src_lines, out_lines = text.splitlines(), out.splitlines()
    assert len(src_lines) == len(out_lines)
    checked = 0
    for s, o in zip(_under_compensation(src_lines), out_lines):
        if s is not None and not _plane_words(s):
            assert not _plane_words(o), (s, o)
            checked += 1
    assert checked >= 1
    src, written = text.encode(), out.encode()
    if name.endswith(".h"):
        src, written = heidenhain_as_gcode(text), heidenhain_as_gcode(out)
    far, swing, corr = compare_centres(src, written, R_MM)
    assert far <= corr + 1e-3, (far, corr)
    assert swing <= 5e-3, swing


def test_offset_plane_g18(tmp_path, large_model, monkeypatch):
    """In G18 the plane is Z X: a move of Y alone under G41 gets no X or Z word, a move of Z does
    get its correction; the readers mark the rows with the plane (the compiled one and Python's
    alike)."""
    from mtcomp.machine import load_machine
    text = ("G21 G90 G18 G54\nG0 X-20 Y-20 Z-20\nG1 Y5 F300\nG41 G1 X0 Z0\nG1 Y-2\n"
            "G1 X100\nG1 Y5\nG40 G1 X120 Z20\nM2\n")
    out, _rows = _compensate(tmp_path, *large_model, "g18.ngc", text, "--max-correction-um",
                             "1000", "--max-step-um", "1000")
    lines = out.splitlines()
    assert _plane_words(lines[4], "XZ") == set() and _plane_words(lines[6], "XZ") == set(), lines
    assert "Z" in _plane_words(lines[5], "XZ")      # corrected where the block moves in the plane
    p = tmp_path / "g18.ngc"
    for chunk in _both_readers(p, load_machine(large_model[0]), monkeypatch):
        np.testing.assert_array_equal(chunk.cutter_comp, [0, 0, 18, 18, 18, 18, 18])


#: under G42 the short chamfer of line 6 (71 um) follows a move of +X; X has a backlash, so the
#: correction flips there
CHAMFER = ("G21 G90 G17 G54\nG0 X-20 Y-20 Z5\nG1 Z-2 F100\nG42 D1 G1 X0 Y0 F300\nG1 X100\n"
           "G1 X99.95 Y0.05\nG1 Y50\nG1 X0\nG1 Y0.5\nG40 G1 X-20 Y-20\nG0 Z5\nM2\n")


def test_a_short_block_keeps_its_direction(tmp_path):
    """A block too short to take a change of its correction without turning by more than
    CRC_TURN keeps (about) the correction of the block before: the written chamfer turns by at
    most that, and the tool centre's path is the source's moved by the correction. Before the
    rule the chamfer took a 5 um step of X's correction (a turn of 4 degrees), which swung its
    offset and moved the centre path 263 um off the source's."""
    out, rows = _compensate(tmp_path, "xfyz", _model(tmp_path), "c.ngc", CHAMFER)
    lines = out.splitlines()
    prev = np.array([float(v) for v in re.findall(r"X([-\d.]+)", lines[4])] + [0.0])
    end = np.array([float(re.search(r"X([-\d.]+)", lines[5]).group(1)),
                    float(re.search(r"Y([-\d.]+)", lines[5]).group(1))])
    d_in, d_out = np.array([-0.05, 0.05]), end - prev
    turn = math.atan2(abs(d_in[0] * d_out[1] - d_in[1] * d_out[0]), d_in @ d_out)
    assert turn <= math.atan(CRC_TURN) * 1.01, turn
    assert any("crc_x" in r["active_bounds"] for r in rows if r["line"] == "6")
    far, swing, corr = compare_centres(CHAMFER.encode(), out.encode(), R_MM)
    assert far <= corr + 1e-3, (far, corr)
    assert swing <= 5e-3, swing


@pytest.mark.parametrize("name", ["dxf2gcode_IFluegel Rippen b2 0201 a.ngc",
                                  "linuxcnc_gmoccapy_2_tools_with_cutter_radius_compensation.ngc"])
def test_corpus_programs_under_cutter_compensation(tmp_path, name):
    """Two programs of the corpus that plunge or retract Z under G41/G42, on the corpus test's
    machine and model: the same moves offset in the plane, and the tool centre's path within the
    correction of the source's (tool radius 0.5 mm, below their smallest arc's). Before the rule
    the written programs had plane moves of a few tenths of a um on those lines, and their tool
    centre's paths left the source's by 0.45 and 0.82 mm."""
    from pathlib import Path
    src = Path(__file__).parent / "data" / "gcode_corpus" / name
    machine = _machine_file(tmp_path, "XFYZ")
    out, _rows = _compensate(tmp_path, machine, _model_file(tmp_path, machine), "p.ngc",
                             src.read_text(encoding="latin-1"), "--units", "mm")
    far, swing, corr = compare_centres(src.read_bytes(), out.encode("latin-1"), 0.5)
    assert far <= corr + 1e-4, (far, corr)
    assert swing <= 1e-4, swing

"""G-code reader and writer: hand-derived blocks, arcs against the circle, errors, round trip."""
import math

import numpy as np
import pytest

from mtcomp import InputError, load_machine
from mtcomp.toolpaths import iter_segment_chunks, read_program, write_corrected
from mtcomp.toolpaths.gcode import SegmentChunk

XFYZ = load_machine("xfyz")
CAFXYZ = load_machine("cafxyz")


@pytest.fixture(autouse=True, params=["compiled", "python"])
def gcode_path(request, monkeypatch):
    """Every test runs on the compiled fast path and on the pure-Python path."""
    from mtcomp.toolpaths import _fast
    if request.param == "python":
        monkeypatch.setenv("MTCOMP_NO_FAST_GCODE", "1")
    elif not _fast.available():
        pytest.skip("no C compiler: the compiled G-code path is not available")
    return request.param

SAMPLE = """%
O1000 (TEST)
N10 G21 G90 G17 ; setup
N20 G0 X10. Y10. Z5.
N30 G1 Z-1. F200 M8
X20. (cont)
N40 G2 X30. Y20. I0 J10.
G3 X20. Y30. R10.
G91 G1 X-5.
M30
%
"""


def _write(tmp_path, text, name="in.nc"):
    p = tmp_path / name
    p.write_bytes(text.encode("latin-1") if isinstance(text, str) else text)
    return p


def test_blocks_hand_derived(tmp_path):
    prog = read_program(_write(tmp_path, SAMPLE), XFYZ)
    lines = [b.line for b in prog.blocks]
    assert lines == [4, 5, 6, 7, 8, 9]
    b = prog.blocks
    np.testing.assert_allclose(b[0].start, [0, 0, 0], rtol=0, atol=0)
    np.testing.assert_allclose(b[0].end, [10, 10, 5], rtol=0, atol=0)
    assert b[0].rapid and math.isnan(b[0].feed)
    np.testing.assert_allclose(b[1].end, [10, 10, -1], rtol=0, atol=0)
    assert b[1].feed == 200.0 and b[1].words == ["F200", "M8"] and b[1].number == "N30"
    # modal continuation: G1 and F200 still in force
    assert b[2].motion == 1 and b[2].feed == 200.0
    # dirs: Z went down at line 5 and stays -1, X went up at line 6; Y has moved only from a
    # position the program had not given (line 4): the direction it arrived from is not known (0)
    np.testing.assert_array_equal(b[2].dirs[-1], [1, 0, -1])
    # G2 from (20,10) about (20,20) clockwise to (30,20): 270 deg through (10,20) and (20,30)
    np.testing.assert_allclose(b[3].centre, [20, 20, -1], rtol=0, atol=1e-12)
    np.testing.assert_allclose(b[3].end, [30, 20, -1], rtol=0, atol=0)
    assert b[3].points[:, 0].min() == pytest.approx(10.0, abs=2e-3)
    assert b[3].points[:, 1].max() == pytest.approx(30.0, abs=2e-3)
    # last chord of the G2 ends moving in -Y at X = 30 (the rightmost point, coming down)
    np.testing.assert_array_equal(b[3].dirs[-1], [1, -1, -1])
    # G3 R10 from (30,20) to (20,30): the 90 deg arc about (20,20)
    np.testing.assert_allclose(b[4].centre[:2], [20, 20], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(b[4].dirs[-1], [-1, 1, -1])
    # G91 X-5 from (20,30)
    np.testing.assert_allclose(b[5].end, [15, 30, -1], rtol=0, atol=1e-12)


def _check_arc(points, centre, radius, normal, ccw, chord_tol):
    """Every chord end on the circle, every chord within the tolerance, turning the right way."""
    rel = points - centre
    inplane = rel - np.outer(rel @ normal, normal)
    np.testing.assert_allclose(np.linalg.norm(inplane, axis=1), radius, rtol=0, atol=1e-9)
    mids = 0.5 * (inplane[1:] + inplane[:-1])
    sag = radius - np.linalg.norm(mids, axis=1)
    assert sag.max() <= chord_tol * (1 + 1e-9)
    assert sag.max() >= 0.3 * chord_tol           # not needlessly fine either
    turn = np.cross(inplane[:-1], inplane[1:]) @ normal
    assert np.all(turn > 0) if ccw else np.all(turn < 0)


@pytest.mark.parametrize("plane, code, normal, start, words", [
    # G17: XY, seen from +Z; G18: ZX, seen from +Y; G19: YZ, seen from +X
    (17, 3, [0, 0, 1], (10, 0, 0), "X0 Y10 I-10 J0"),
    (17, 2, [0, 0, 1], (10, 0, 0), "X0 Y10 I-10 J0"),
    (18, 3, [0, 1, 0], (10, 0, 0), "X0 Z10 I-10 K0"),
    (18, 2, [0, 1, 0], (10, 0, 0), "X0 Z10 I-10 K0"),
    (19, 3, [1, 0, 0], (0, 10, 0), "Y0 Z10 J-10 K0"),
    (19, 2, [1, 0, 0], (0, 10, 0), "Y0 Z10 J-10 K0"),
])
def test_arc_planes_and_senses(tmp_path, plane, code, normal, start, words):
    text = f"G{plane} G0 X{start[0]} Y{start[1]} Z{start[2]}\nG{code} {words} F100\n"
    prog = read_program(_write(tmp_path, text), XFYZ, chord_tol_mm=1e-3)
    arc = prog.blocks[1]
    pts = np.vstack([arc.start, arc.points])
    normal = np.array(normal, float)
    _check_arc(pts, np.zeros(3), 10.0, normal, code == 3, 1e-3)
    # the swept angle, from the same points: 90 deg one way, 270 deg the other
    rel = pts
    ang = np.arctan2(np.cross(rel[:-1], rel[1:]) @ normal, np.einsum("ij,ij->i", rel[:-1], rel[1:]))
    sweep = abs(ang.sum())
    # oracle by the right-hand rule: rotating the start about +normal by +90 deg lands on the end
    # exactly when the CCW arc is the short one
    rot90 = np.cross(normal, np.array(start, float))
    short_is_ccw = np.allclose(rot90, arc.end, atol=1e-9)
    expected = math.pi / 2 if (code == 3) == short_is_ccw else 1.5 * math.pi
    assert sweep == pytest.approx(expected, rel=0, abs=1e-9)


def test_helix_and_full_circle(tmp_path):
    text = "G0 X5 Y0 Z0\nG3 X5 Y0 Z-2 I-5 J0 F300\n"
    prog = read_program(_write(tmp_path, text), XFYZ, chord_tol_mm=1e-4)
    arc = prog.blocks[1]
    pts = np.vstack([arc.start, arc.points])
    _check_arc(pts, np.zeros(3), 5.0, np.array([0, 0, 1.0]), True, 1e-4)
    # Z falls linearly with the angle: full turn -> -2
    ang = np.unwrap(np.arctan2(pts[:, 1], pts[:, 0]))
    np.testing.assert_allclose(pts[:, 2], -2.0 * ang / (2 * math.pi), rtol=0, atol=1e-12)
    assert ang[-1] == pytest.approx(2 * math.pi, rel=0, abs=1e-12)
    assert np.all(arc.dirs[:, 2] == -1)


def test_major_arc_negative_r(tmp_path):
    text = "G0 X10 Y0\nG3 X0 Y10 R-10 F100\n"
    arc = read_program(_write(tmp_path, text), XFYZ).blocks[1]
    # R < 0 takes the long way: centre on the far side of the chord, at (10, 10)
    np.testing.assert_allclose(arc.centre[:2], [10, 10], rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.hypot(arc.points[:, 0] - 10, arc.points[:, 1] - 10), 10,
                               rtol=0, atol=1e-9)


def test_inch_and_incremental(tmp_path):
    text = "G20 G91\nG1 X1 Y-0.5 F10\nX1\nG21 G90 G1 X1\n"
    prog = read_program(_write(tmp_path, text), XFYZ, initial_known=True)
    b = prog.blocks
    np.testing.assert_allclose(b[0].end, [25.4, -12.7, 0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(b[1].end, [50.8, -12.7, 0], rtol=0, atol=1e-12)
    assert b[0].feed == pytest.approx(254.0, rel=1e-15, abs=0)
    # G21 G90 on line 4: back to absolute mm; feed stays 254 mm/min
    np.testing.assert_allclose(b[2].end, [1, -12.7, 0], rtol=0, atol=1e-12)
    assert b[2].feed == pytest.approx(254.0, rel=1e-15, abs=0)
    out = tmp_path / "out.nc"
    write_corrected(tmp_path / "in.nc", out, XFYZ, None, initial_known=True)
    lines = out.read_text().splitlines()
    # incremental lines stay incremental: without a correction the program comes out as it is
    assert lines == text.splitlines()
    # without initial_known the program has not said where X is: the controller moves it from
    # wherever it stands, so the incremental lines pass through uncorrected, X Y Z unknown until
    # line 4 gives X
    b = read_program(tmp_path / "in.nc", XFYZ).blocks
    assert [x.line for x in b] == [4] and b[0].known.tolist() == [True, False, False]
    write_corrected(tmp_path / "in.nc", out, XFYZ, None)
    lines = out.read_text().splitlines()
    assert lines[:3] == text.splitlines()[:3]
    assert lines[3] == "G21 G90 G1 X1"      # as written (an absolute line after G91 ones)


def test_rotary_words_in_degrees(tmp_path):
    text = "G0 X1 Y2 Z3 A-30 C370.5\nG1 C10 F500\n"
    prog = read_program(_write(tmp_path, text), CAFXYZ)
    np.testing.assert_allclose(prog.blocks[0].end, [1, 2, 3, math.radians(-30), math.radians(370.5)],
                               rtol=0, atol=1e-15)
    # the first line moves every axis from a position not given: directions not known (0); C then
    # turns down
    np.testing.assert_array_equal(prog.blocks[1].dirs[-1], [0, 0, 0, 0, -1])
    out = tmp_path / "out.nc"
    write_corrected(tmp_path / "in.nc", out, CAFXYZ, None)
    # unchanged blocks are written as they are (their own spelling of the numbers)
    assert out.read_text() == text
    corr = [(c, c.end + np.radians([0, 0, 0, 1e-3, 0.5]), np.ones(len(c), int))
            for c in iter_segment_chunks(tmp_path / "in.nc", CAFXYZ)]
    write_corrected(tmp_path / "in.nc", out, CAFXYZ, iter(corr))
    assert out.read_text() == "G0 X1 Y2 Z3 A-29.9990 C371.0000\nG1 C10.5000 F500\n"


def test_home_moves_and_dwell(tmp_path):
    text = "G0 X5 Y5 Z5\nG91 G28 Z0\nG90\nG4 X2.5\nG0 X1\nG53 Z-10\nG0 Y1\n"
    prog = read_program(_write(tmp_path, text), XFYZ)
    b = prog.blocks
    assert [x.line for x in b] == [1, 5, 7]
    np.testing.assert_allclose(b[1].start[:2], [5, 5], rtol=0, atol=0)   # X not moved by the dwell
    # Z is not known after the home move (G28) nor after the move in machine coordinates (G53)
    assert [x.known.tolist() for x in b] == [[True] * 3, [True, True, False], [True, True, False]]
    out = tmp_path / "out.nc"
    shift = [(c, c.end + 0.001, np.ones(len(c), int)) for c in iter_segment_chunks(tmp_path / "in.nc",
                                                                                    XFYZ)]
    write_corrected(tmp_path / "in.nc", out, XFYZ, iter(shift))
    assert out.read_text().splitlines() == [
        "G0 X5.0010 Y5.0010 Z5.0010", "G91 G28 Z0", "G90", "G4 X2.5", "G0 X1.0010",
        "G53 Z-10", "G0 Y1.0010"]


@pytest.mark.parametrize("text, line, msg", [
    ("G0 X1\nG1 X1.2.3\n", 2, "unexpected character '.'"),
    ("axis,component,target_mm,dir\nX,EXX,0,1\n", 1, "looks like a CSV file"),
    ("G0 X1\nG1 X--1\n", 2, "word X without a valid number"),
    ("G1 X1 F100\nG1 Y#<depth>\n", 2, "named parameter #<depth>: used before it is set"),
    ("G0 X1\no200 sub\n", 2, "o200 sub without its o200 endsub"),
    ("G0 X1\nO100 IF [#1 GT 2]\n", 2, "o100 if without its o100 endif"),
    ("#5221 = 5\n", 1, "assignment to parameter #5221"),
    ("G0 X1\nTRAORI\n", 2, "TRAORI"),
    ("G0 X1\nG43.5 H1\n", 2, "G43.5 .tool centre point"),
    ("G0 X1\nM98 P1000\n", 2, "M98 .subprogram call"),
    # (an arc from a position not given, absolute or incremental, and a helix from a height not
    # given pass through as written: tests/test_toolpaths_unknown_start.py)
    ("G93\nG0 X0 Y0\nG1 X1\n", 3, "G93 .inverse time feed.: the G1 block has no F word"),
    ("G0 X1\nG0 A10\n", 2, "no A axis"),
    ("G0 X1\nG1 B10\n", 2, "no B axis"),
    ("G0 X0 Y0\nG2 X10 Y0 I4 J0 F100\n", 2, "radius inconsistent"),
    ("G0 X0 Y0\nG2 X30 Y0 R10 F100\n", 2, "R arc impossible"),
    ("G0 X0 Y0\nG2 X0 Y0 R10 F100\n", 2, "start = end"),
    ("G0 X0\n(unclosed\n", 2, "not closed"),
    ("X10\n", 1, "without a motion mode"),
    ("G0 G1 X1\n", 1, "two motion codes"),
    ("G0 X1 X2\n", 1, "appears twice"),
    ("G92.3\n", 1, "G92.3"),
    # moves that stop where a signal comes: the position after them is not the program's (a corrected
    # later block once carried the probe's target Z). G38.2 is read where it is a probing move
    # (LinuxCNC, grbl, FluidNC: tests/test_toolpaths_controller_values.py), refused on a Fanuc
    ("O1000\nG0 X10. Y0 Z5.\nG38.2 Z-10. F100\nG1 X20. Y3.\n", 3, "G38.2 .probing move"),
    ("G0 X10 Y0 Z5\nG31 Z-10 F100\n", 2, "G31 .skip function"),
    # coordinates that are not axis positions, and curves mtcomp does not follow
    ("G16\nG1 X50 Y45 F100\n", 1, "G16 .polar coordinates"),
    ("G0 X0 Y0\nG12.1\n", 2, "G12.1 .polar coordinate interpolation"),
    ("G0 X0 Y0\nG5.2 X1 Y1 P1 L3\n", 2, "G5.2 .NURBS"),
    # (a spline passes through on LinuxCNC, BeagleG and generic: tests/test_toolpaths_beagleg.py)
    ("(grbl)\nG0 X0 Y0\nG5 X10 Y0 I5 J5 P1 Q2 F100\n", 3, "G5 .cubic spline. is not supported"),
    ("G0 X0 Y0 Z0\nG2 G5.1 X10 Y0 I5 J5 F100\n", 2, "G5.1 .quadratic spline"),   # once read as an arc
    ("G0 X0 Y0 Z0\nG31.1 X10 F100\n", 2, "G31.1 .multi-step skip"),
    ("G0 X0 Y0 Z0\nG37 Z-10\n", 2, "G37 .automatic tool length"),
    ("G0 X0 Y0\nG112\n", 2, "G112 .polar coordinate interpolation"),
    # LinuxCNC's multi-turn arc: P turns (one turn was cut, and P landed on a straight move)
    ("G0 X0 Y0 Z0\nG2 X10 Y0 I-10 J0 P3 F100\n", 2, "arc G2 with a P word"),
    ("G76 X1 Z-1 P1\n", 1, "canned cycle G76"),
    ("G1 X1 I2 F10\n", 1, "I word in a G1 block"),
    ("G0 X0 Y0\nG17\nG2 X1 Y1 K2 F10\n", 3, "not an offset in plane G17"),
    ("G1 X1 F-5\n", 1, "feed F must be positive"),
    ("G1 X1\xe9 F5\n", 1, "unexpected character"),
    ("/G1 X1 F5\n", 1, "block delete"),
])
def test_bad_input_names_file_and_line(tmp_path, text, line, msg):
    p = _write(tmp_path, text)
    with pytest.raises(InputError, match=msg) as exc:
        read_program(p, XFYZ)
    assert exc.value.line == line and exc.value.path == str(p)
    assert f"{p}:{line}: " in str(exc.value)
    out = tmp_path / "out.nc"
    with pytest.raises(InputError):
        write_corrected(p, out, XFYZ, None)
    assert not out.exists() and [q.name for q in tmp_path.iterdir()] == ["in.nc"]


def test_missing_file_and_overwrite_refused(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        read_program(tmp_path / "nope.nc", XFYZ)
    p = _write(tmp_path, SAMPLE)
    with pytest.raises(InputError, match="overwrite an input"):
        write_corrected(p, p, XFYZ, None)
    assert p.read_text() == SAMPLE


def test_round_trip_keeps_lines_and_coordinates(tmp_path):
    p = _write(tmp_path, SAMPLE.replace("\n", "\r\n"))
    out = tmp_path / "out.nc"
    write_corrected(p, out, XFYZ, None)
    src = p.read_bytes().split(b"\r\n")
    dst = out.read_bytes().split(b"\r\n")
    motion = {4, 5, 6, 7, 8, 9}
    # non-motion lines byte for byte, in place (the arcs add lines after them)
    assert dst[:3] == src[:3]
    assert dst[-3:] == src[-3:]  # M30, %, and the empty rest after the last line ending
    nin = read_program(p, XFYZ).segments()
    nout = read_program(out, XFYZ).segments()
    np.testing.assert_allclose(nout.end, nin.end, rtol=0, atol=5.01e-5)
    np.testing.assert_array_equal(nout.rapid, nin.rapid)
    np.testing.assert_allclose(nout.feed, nin.feed, rtol=0, atol=0, equal_nan=True)
    assert set(nin.line.tolist()) == motion
    # writing the output again changes nothing: the written form is a fixed point
    out2 = tmp_path / "out2.nc"
    write_corrected(out, out2, XFYZ, None)
    assert out2.read_bytes() == out.read_bytes()


def test_corrections_with_inserted_nodes(tmp_path):
    p = _write(tmp_path, "N1 G0 X0 Y0 Z0\nN2 G1 X10 F100 (cut)\nM30\n")
    chunks = list(iter_segment_chunks(p, XFYZ))

    def corr():
        for c in chunks:
            pts, counts = [], []
            for r in range(len(c)):
                if c.line[r] == 2:        # split the cut in two and lift the middle by 1 um
                    mid = 0.5 * (c.start[r] + c.end[r]) + [0, 0, 1e-3]
                    pts += [mid, c.end[r] + [0, 0.002, 0]]
                    counts.append(2)
                else:
                    pts.append(c.end[r])
                    counts.append(1)
            yield c, np.array(pts), np.array(counts)
    out = tmp_path / "out.nc"
    assert write_corrected(p, out, XFYZ, corr()) == 2
    # modal output: line 1 unchanged (as written), then only what changes
    assert out.read_text() == ("N1 G0 X0 Y0 Z0\n"
                               "N2 G1 X5.0000 Z0.0010 F100 (cut)\n"
                               "X10.0000 Y0.0020 Z0.0000\nM30\n")


def test_corrections_that_do_not_match_are_refused(tmp_path):
    p = _write(tmp_path, "G0 X0\nG1 X10 F100\n")
    chunks = list(iter_segment_chunks(p, XFYZ))
    c = chunks[0]
    out = tmp_path / "out.nc"
    with pytest.raises(ValueError, match="points must be"):
        write_corrected(p, out, XFYZ, iter([(c, c.end[:1], np.ones(len(c), int))]))
    shifted = SegmentChunk(c.line + 1, c.start, c.end, c.feed, c.dirs, c.rapid, c.from_arc)
    with pytest.raises(ValueError, match="do not match"):
        write_corrected(p, out, XFYZ, iter([(shifted, c.end, np.ones(len(c), int))]))
    nan_end = c.end.copy()
    nan_end[1, 0] = np.nan
    with pytest.raises(ValueError, match="non-finite point for line 2"):
        write_corrected(p, out, XFYZ, iter([(c, nan_end, np.ones(len(c), int))]))
    with pytest.raises(ValueError, match="ended before"):
        write_corrected(p, out, XFYZ, iter([]))
    assert not out.exists()


def test_chunks_split_blocks_and_concatenate(tmp_path):
    p = _write(tmp_path, SAMPLE)
    whole = read_program(p, XFYZ).segments()
    chunks = list(iter_segment_chunks(p, XFYZ, chunk_size=7))
    assert all(len(c) == 7 for c in chunks[:-1]) and 1 <= len(chunks[-1]) <= 7
    cat = SegmentChunk.concatenate(chunks, 3)
    for f in ("line", "start", "end", "feed", "dirs", "rapid", "from_arc"):
        np.testing.assert_array_equal(getattr(cat, f), getattr(whole, f))
    # segments chain: each start is the previous end
    np.testing.assert_array_equal(cat.start[1:], cat.end[:-1])
    assert cat.dirs.dtype == np.int8 and cat.start.shape == (len(cat), 3)
    assert cat.tool_length is None and cat.datum is None
    # what a caller set on every chunk (the tool lengths, the part's datum) is kept, row for row
    from dataclasses import replace
    marked = [replace(c, tool_length=np.full(len(c), 50.0 + k), datum=np.full((len(c), 3), float(k)))
              for k, c in enumerate(chunks)]
    cat = SegmentChunk.concatenate(marked, 3)
    np.testing.assert_array_equal(cat.tool_length, np.concatenate([c.tool_length for c in marked]))
    np.testing.assert_array_equal(cat.datum, np.concatenate([c.datum for c in marked]))
    assert SegmentChunk.concatenate(marked[:1] + chunks[1:], 3).datum is None   # not on every chunk


def test_initial_position(tmp_path):
    p = _write(tmp_path, "G91 G1 X1 F10\nG90 G28\nG1 Y1\n")
    init = np.array([5.0, 0.0, 2.0])
    prog = read_program(p, XFYZ, initial_position=init)
    np.testing.assert_allclose(prog.blocks[0].start, init, rtol=0, atol=0)
    np.testing.assert_allclose(prog.blocks[0].end, [6, 0, 2], rtol=0, atol=0)
    np.testing.assert_allclose(prog.blocks[1].start, init, rtol=0, atol=0)    # G28: home = initial
    c = SegmentChunk.concatenate(list(iter_segment_chunks(p, XFYZ, initial_position=init)), 3)
    np.testing.assert_allclose(c.end, [[6, 0, 2], [5, 1, 2]], rtol=0, atol=0)
    out = tmp_path / "out.nc"
    write_corrected(p, out, XFYZ, None, initial_position=init)
    assert out.read_text() == "G91 G1 X1 F10\nG90 G28\nG1 Y1\n"      # G91 stays incremental
    # after G28 (every axis home) only Y is known again
    assert [b.known.tolist() for b in prog.blocks] == [[True] * 3, [False, True, False]]


def test_incremental_home_move_keeps_its_meaning(tmp_path):
    # the output stays in G91 as the source is: G28 Z0 keeps its meaning with no line added
    p = _write(tmp_path, "G91 G1 X1 F100\nG28 Z0\nG1 X1\n(end)\n")
    out = tmp_path / "out.nc"
    write_corrected(p, out, XFYZ, None, initial_known=True)
    assert out.read_text() == "G91 G1 X1 F100\nG28 Z0\nG1 X1\n(end)\n"


def test_fanuc_contour_control_modes_pass_through(tmp_path):
    """G05 P10000 / G05 P0 (high-precision contour control) and G05.1 Q1 (AI contour control) are
    modes, not curves: they pass through unchanged and the moves around them are read."""
    text = "G21 G90\nG05 P10000\nG05.1 Q1\nG0 X1 Y2 Z3\nG1 X4 F100\nG05.1 Q0\nG05 P0\n"
    prog = read_program(_write(tmp_path, text), XFYZ)
    assert [b.line for b in prog.blocks] == [4, 5]
    out = tmp_path / "out.nc"
    write_corrected(tmp_path / "in.nc", out, XFYZ, None)
    assert out.read_text().splitlines()[1:3] == ["G05 P10000", "G05.1 Q1"]

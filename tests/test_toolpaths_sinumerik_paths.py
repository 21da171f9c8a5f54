"""The Sinumerik constructs of real 840D programs besides the end points (mtcomp.toolpaths:
sinumerik, sinumerik_paths, sinumerik_out): path control and settings that move nothing, circles by their
radius CR=, the programmable offset TRANS/ATRANS and blocks in machine coordinates SUPA/G53/G153,
against hand-derived values and the independent replay of tests/replay_sinumerik.py."""
import math
import re

import numpy as np
import pytest

import replay_sinumerik
from mtcomp.cli import main
from mtcomp.errors import InputError
from mtcomp.machine import load_machine
from mtcomp.toolpaths.gcode import iter_segment_chunks, read_program, write_corrected
from mtcomp.toolpaths.sinumerik import translate
from replay import Tolerance
from test_gcode_corpus import _machine_file, _model_file
from test_toolpaths_sinumerik_840d import compensated

HEAD = "%_N_PATHS_MPF\n;$PATH=/_N_MPF_DIR\n"


def _write(tmp_path, body: str, name="p.mpf"):
    path = tmp_path / name
    path.write_bytes((HEAD + body).encode("latin-1"))
    return path


def _gcode(tmp_path, body: str) -> list:
    return translate(_write(tmp_path, body)).gcode


def _shifted(path, machine, shift, chord_tol_mm=0.001):
    for chunk in iter_segment_chunks(path, machine, chord_tol_mm):
        yield chunk, chunk.end + shift(chunk.end), np.ones(len(chunk), np.int64)


def _lines_after(path, shift, chord_tol_mm=0.001):
    """The program written with every point moved by ``shift(points)`` (mm): its lines."""
    machine = load_machine("xfyz")
    out = path.parent / "out.mpf"
    write_corrected(path, out, machine, _shifted(path, machine, shift, chord_tol_mm),
                    chord_tol_mm=chord_tol_mm)
    return out.read_text(encoding="latin-1").splitlines()


def _refused(tmp_path, capsys, body):
    """The one line of a refusal by compensate (exit status 2, nothing written)."""
    machine = _machine_file(tmp_path, "XFYZ")
    argv = ["compensate", machine, _model_file(tmp_path, machine), _write(tmp_path, body),
            "-o", tmp_path / "out.mpf"]
    assert main([str(a) for a in argv]) == 2 and not (tmp_path / "out.mpf").exists()
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "Traceback" not in err[0], err
    return err[0]


# ---------------------------------------------------------------------------- settings
SETTINGS = """N10 G17 G90 G71 G54 G642 ADIS=0.05 ADISPOS=0.5 SOFT FFWON COMPCAD FNORM
N15 CYCLE832(0.01,_FINISH,1)
N20 T1 M6
N30 D1
N40 G0 X0 Y0 Z10
N50 MSG("ROUGH; X10 (SIDE)")
N60 G1 Z-1 F200
N70 STOPRE
N80 G4 F2
N90 G645 G62 BRISK FFWOF COMPCURV
N100 G1 X10
N110 G4 S30
N120 DRIVE COMPON G641 G643 G644 G621 FENDNORM
N130 COMPOF TRAFOOF G64 G60 G9
N140 G1 Y10
N150 M30
"""


def test_path_control_and_settings_move_nothing(tmp_path):
    # the G-code equivalent is that of the moves alone (by hand): the settings add no line, the
    # dwell G4 F2 is two seconds and leaves the feed F200, G4 S30 (revolutions) adds none
    assert _gcode(tmp_path, SETTINGS) == [
        "G54 G43.1", "G17 G90 G21", "T1 M6 G43 H1", "G43.1", "G0 X0 Y0 Z10", "G1 Z-1 F200",
        "G4 P2", "G1 X10", "G1 Y10", "M30"]
    # MSG and CYCLE832 are no subprograms: every axis stays known (Y Z written after N100)
    blocks = read_program(_write(tmp_path, SETTINGS), load_machine("xfyz")).blocks
    assert [b.known.tolist() for b in blocks[-2:]] == [[True] * 3, [True] * 3]


def test_settings_lines_are_kept_byte_for_byte(tmp_path):
    path = _write(tmp_path, SETTINGS)
    lines = _lines_after(path, lambda p: np.tile([0.01, 0.0, 0.0], (len(p), 1)))
    src = path.read_text(encoding="latin-1").splitlines()
    moved = {"N40", "N60", "N100", "N140"}
    assert [a for a in src if a.split(" ")[0] not in moved] == \
        [b for b in lines if b.split(" ")[0] not in moved]
    assert lines[6] == "N40 G0 X0.0100 Y0 Z10"
    # the corrections are written on the programmed points, the smoothing is the controller's
    assert lines[12] == "N100 G1 X10.0100"


# ---------------------------------------------------------------------------- CR= circles
@pytest.mark.parametrize("move, centre", [
    ("G2 X6 Y0 CR=5", "I3 J-4"),       # clockwise, at most 180 deg: right of the chord
    ("G3 X6 Y0 CR=5", "I3 J4"),        # counter-clockwise: left
    ("G2 X6 Y0 CR=-5", "I3 J4"),       # more than 180 deg: the other side
    ("G3 X6 Y0 CR=-5", "I3 J-4"),
    ("G2 X6 Y0 CR=3", "I3 J0"),        # a half circle
    ("G3 X=2*3 CR=-(4+1) Z-2", "I3 J-4"),   # expressions, and a helix to Z-2
])
def test_a_circle_by_its_radius_has_the_centre_of_the_manual(tmp_path, move, centre):
    # chord 6, radius 5: the centre 4 from the chord's middle (3, 0) (3-4-5 by hand)
    got = _gcode(tmp_path, f"N10 G0 X0 Y0 Z0\nN20 {move}\nM30\n")
    words = " ".join(w for w in got[-2].split() if w[0] in "IJ")
    assert words == centre


@pytest.mark.parametrize("block, words", [
    ("G2 X6 Y0 CR=2.9", "CR=2.9 is smaller than half the chord (3 mm)"),
    ("G2 X0 Y0 CR=5", "ends where it starts"),
    ("G2 X6 Y0 CR=5 I=AC(3) J=AC(4)", "both its radius CR= and its centre"),
    ("G1 X6 Y0 CR=5", "CR= outside a circle"),
    ("G2 X6 Y0 Z-4 I3 J4 TURN=.5", "TURN=.5 is not a whole number of additional turns"),
    ("G1 X6 Y0 TURN=2", "TURN= outside a circle"),
    ("TRANS X10 G1", "TRANS with other words than its axis values"),
    ("TRANS A10", "TRANS of a rotary axis"),
    ("ROT Z45", "a programmable frame (ROT with values)"),
    ("ROT RPL=45", "a programmable frame (ROT with values)"),
    ("AROT Z45", "a programmable frame (AROT)"),
    ("ASCALE X2", "a programmable frame (ASCALE)"),
    ('T="" M6', 'the tool name T="" is not read'),
    ("T2.5 M6", "the tool number T2.5 is not a whole number"),
])
def test_what_cannot_be_followed_is_refused_in_one_line(tmp_path, capsys, block, words):
    err = _refused(tmp_path, capsys, f"N10 G0 X0 Y0 Z0\nN20 {block}\nM30\n")
    assert "p.mpf:4:" in err and words in err, err


QUARTER = "N10 G0 X10 Y0 Z5\nN20 G1 Z-1 F100\nN30 G3 X0 Y10 CR=10\nN40 G0 Z5\nM30\n"


def test_a_translated_circle_keeps_its_radius(tmp_path):
    lines = _lines_after(_write(tmp_path, QUARTER), lambda p: np.tile([0.01, 0, 0], (len(p), 1)))
    assert lines[2:6] == ["N10 G0 X10.0100 Y0 Z5", "N20 G1 Z-1 F100", "N30 G3 X0.0100 Y10 CR=10",
                          "N40 G0 Z5"]


def _points(move, n=200):
    """Points (n, 2) along a replayed circle move (angle and radius linear from start to end)."""
    cx, cy = move.centre
    a0 = math.atan2(move.start["Y"] - cy, move.start["X"] - cx)
    r0 = math.hypot(move.start["X"] - cx, move.start["Y"] - cy)
    r1 = math.hypot(move.end["X"] - cx, move.end["Y"] - cy)
    u = np.linspace(0, 1, n)
    r = r0 + (r1 - r0) * u
    a = a0 + move.sweep * u
    return np.column_stack([cx + r * np.cos(a), cy + r * np.sin(a)])


def test_a_scaled_circle_gets_the_radius_of_its_moved_centre(tmp_path):
    # every point scaled by 1 + 1e-4 about the origin: the ends go to (10.001, 0) and (0, 10.001);
    # the circle's centre is moved by the mean correction of its ends, (0.0005, 0.0005), so its
    # radius is |(10.001, 0) - (0.0005, 0.0005)| = 10.0005000 (by hand), CR=10.0005; that circle
    # stays within 0.3 um of the scaled one (radius 10.001 about the origin), inside the 1 um
    # chord tolerance
    path = _write(tmp_path, QUARTER)
    lines = _lines_after(path, lambda p: 1e-4 * p)
    assert lines[4] == "N30 G3 X0 Y10.0010 CR=10.0005"
    arc = [m for m in replay_sinumerik.replay("\n".join(lines).encode()).moves if m.kind == "arc"]
    assert len(arc) == 1
    np.testing.assert_allclose(arc[0].centre, [0.0005, 0.0005], rtol=0, atol=2e-6)
    # from the angle -atan(0.0005 / 10.0005) to pi / 2 plus as much
    assert arc[0].sweep == pytest.approx(math.pi / 2 + 2 * math.atan(0.0005 / 10.0005), rel=0,
                                         abs=1e-6)
    off = np.abs(np.hypot(*_points(arc[0]).T) - 10.001)
    assert 0.1e-3 < off.max() <= 0.3e-3


def test_a_circle_by_radius_the_correction_bends_is_written_in_pieces(tmp_path):
    # three quarters of a circle of radius 20 from (20, 0) to (0, -20) counter-clockwise about
    # (0, 0) (CR=-20: more than 180 deg); every point moved by 2e-4 * y in X: the corrected path
    # (20 cos t + 0.004 sin t, 20 sin t) is an ellipse no circle through its ends holds within
    # 1 um (one misses it by 2.1 um), so the block is written as circle pieces about absolute
    # centres I=AC J=AC, the CR= word giving way to the first's; replayed independently, every
    # point of the pieces is within 1 um (and 0.1 um for the written decimals) of the ellipse
    path = _write(tmp_path, "N10 G0 X20 Y0 Z5\nN20 G1 Z-1 F100\nN30 G3 X0 Y-20 CR=-20\n"
                            "N40 G0 Z5\nM30\n")
    lines = _lines_after(path, lambda p: np.outer(p[:, 1], [2e-4, 0, 0]))
    assert "circle written in pieces" in lines[2]
    assert re.fullmatch(r"N30 G3 X\S+ Y\S+ I=AC\(\S+\) J=AC\(\S+\)", lines[5]), lines[5]
    arcs = [m for m in replay_sinumerik.replay("\n".join(lines).encode()).moves if m.kind == "arc"]
    assert len(arcs) >= 2 and lines[5 + len(arcs) - 1].startswith("X-0.0040 Y-20 ")
    assert sum(m.sweep for m in arcs) == pytest.approx(1.5 * math.pi, rel=0, abs=1e-3)
    x, y = np.vstack([_points(m) for m in arcs]).T
    # on the ellipse x - 2e-4 y = 20 cos t, y = 20 sin t: the radius error of (x - 2e-4 y, y)
    assert np.max(np.abs(np.hypot(x - 2e-4 * y, y) - 20.0)) <= 1.1e-3


def test_a_half_circle_by_radius_keeps_its_radius_when_its_chord_shortens(tmp_path):
    # a half circle G2 from (60, 60) to (60, 40) (CR=-10, a quality engineer's contour) with Y
    # scaled by 1 - 2.5e-5 about Y 40: the start goes to Y59.9995, the chord to 19.9995 mm, the
    # corrected path a half ellipse of half-axes 10 and 9.99975 about (60, 49.99975). The written
    # radii next to half the chord (9.99975) are 9.9997, 0.05 um short: the controller's half
    # circle about the chord's middle, and 9.9998, whose centre lies sqrt(9.9998^2 - 9.99975^2) =
    # 31.6 um (by hand) off the chord: that circle misses by 31.6 um and the block was written
    # about I=AC J=AC. Now CR=-9.9997: the half circle, within 0.25 um of the ellipse (by hand:
    # the circle of radius 9.99975 about its centre meets it at the ends and on the Y axis, and
    # stands 0.25 um inside it at X 50)
    path = _write(tmp_path, "N10 G0 X60 Y60 Z5\nN20 G1 Z-4 F100\nN30 G2 X60 Y40 CR=-10\n"
                            "N40 G0 Z5\nM30\n")
    lines = _lines_after(path, lambda p: np.outer(p[:, 1] - 40.0, [0.0, -2.5e-5, 0.0]))
    assert lines[2:7] == ["N10 G0 X60 Y59.9995 Z5", "N20 G1 Z-4 F100", "N30 G2 X60 Y40 CR=-9.9997",
                          "N40 G0 Z5", "M30"]
    arc = [m for m in replay_sinumerik.replay("\n".join(lines).encode()).moves if m.kind == "arc"]
    assert len(arc) == 1
    np.testing.assert_allclose(arc[0].centre, [60.0, 49.99975], rtol=0, atol=1e-9)
    x, y = _points(arc[0]).T
    off = np.abs(np.hypot((x - 60.0) / 10.0, (y - 49.99975) / 9.99975) - 1.0) * 10.0
    assert 0.24e-3 < off.max() <= 0.26e-3


def test_a_circle_by_radius_written_to_its_corrected_z_keeps_its_radius(tmp_path):
    # a quarter circle CR=10 at Z-1, Z corrected by 2e-4 * x: +2 um at its start (10, 0), none at
    # its end (0, 10); no circle at one Z holds that within 1 um, the helix from Z-0.998 to Z-1
    # does (it misses z = -1 + 0.002 cos t by 0.42 um at most, by hand as in the helix test
    # above). It stays one piece, so it keeps its form: its words, Z added, CR= (it was written
    # "X0.0000 Y10.0000 Z-1.0000 I=AC(0.0000) J=AC(0.0000)")
    path = _write(tmp_path, QUARTER)
    lines = _lines_after(path, lambda p: np.outer(p[:, 0], [0.0, 0.0, 2e-4]))
    assert lines[3:6] == ["N20 G1 Z-0.9980 F100", "N30 G3 X0 Y10 Z-1.0000 CR=10", "N40 G0 Z5"]
    arc = [m for m in replay_sinumerik.replay("\n".join(lines).encode()).moves if m.kind == "arc"]
    u = np.linspace(0, 1, 401)
    z = arc[0].start["Z"] + (arc[0].end["Z"] - arc[0].start["Z"]) * u
    miss = np.abs(z - (-1 + 0.002 * np.cos(0.5 * np.pi * u)))
    assert 0.40e-3 < miss.max() <= 0.43e-3


def test_a_circle_by_radius_compensated_against_the_replay(tmp_path, capsys):
    """compensate's output, replayed independently, cuts the source's circles by radius up to the
    correction."""
    body = ("N10 G17 G90 G71 G54 G642 SOFT\nN20 T1 M6\nN30 D1\nN40 G0 X10 Y0 Z5\n"
            "N50 G1 Z-1 F100\nN60 G3 X0 Y10 CR=10\nN70 G2 X-10 Y20 CR=-10\nN80 G1 X-20\n"
            "N90 G0 Z5\nM30\n")
    src = _write(tmp_path, body)
    out = compensated(tmp_path, capsys, src, "XFYZ", 5.0, "--units", "mm")
    replay_sinumerik.compare(src.read_bytes(), out.read_bytes(),
                             Tolerance(axis_mm=0.06, axis_deg=0.1, path_mm=0.1), name="cr")
    text = out.read_text(encoding="latin-1")
    assert re.search(r"^N70 G2 X\S+ Y\S+ CR=-10", text, re.M), text


# ---------------------------------------------------------------------------- TRANS / ATRANS
FRAMES = """N10 G54 G0 X0 Y0 Z10
N20 TRANS X100 Y50
N30 G1 X0 Y0 F100
N40 ATRANS X10 Z-2
N50 G1 X0 Z0
N60 G3 X10 Y10 I=AC(10) J=AC(0)
N70 TRANS
N80 G1 X0 Y0
N90 ROT
N100 M30
"""


def test_trans_and_atrans_shift_the_program_coordinates(tmp_path):
    # by hand: TRANS X100 Y50, then ATRANS X10 Z-2 (110, 50, -2), then TRANS clears it; the
    # circle's absolute centre (10, 0) is (120, 50) in the work offset's frame, I 10 J 0 from
    # the start (110, 50)
    assert _gcode(tmp_path, FRAMES)[1:] == [
        "G0 X0 Y0 Z10", "G1 X100 Y50 F100", "G1 X110 Z-2", "G3 X120 Y60 I10 J0", "G1 X0 Y0",
        "M30"]


def test_positions_stay_known_across_a_frame_change(tmp_path):
    # the tool stays where it is: N80 X0 Y0 after TRANS is a move from (120, 60, -2), and Z
    # (not named since N50) is still known
    blocks = read_program(_write(tmp_path, FRAMES), load_machine("xfyz")).blocks
    assert blocks[-1].known.tolist() == [True, True, True]
    np.testing.assert_allclose(blocks[-1].start, [120.0, 60.0, -2.0], rtol=0, atol=1e-12)


def test_lines_under_a_frame_are_written_in_the_program_frame(tmp_path):
    path = _write(tmp_path, FRAMES)
    lines = _lines_after(path, lambda p: np.tile([0.01, 0.0, 0.0], (len(p), 1)))
    assert lines[2:12] == ["N10 G54 G0 X0.0100 Y0 Z10", "N20 TRANS X100 Y50",
                           "N30 G1 X0.0100 Y0 F100", "N40 ATRANS X10 Z-2", "N50 G1 X0.0100 Z0",
                           "N60 G3 X10.0100 Y10 I=AC(10.0100) J=AC(0)", "N70 TRANS",
                           "N80 G1 X0.0100 Y0", "N90 ROT", "N100 M30"]
    src = path.read_bytes()
    out = "\n".join(lines).encode()
    a, b = replay_sinumerik.replay(src).moves, replay_sinumerik.replay(out).moves
    np.testing.assert_allclose([[m.end[x] + (0.01 if x == "X" else 0) for x in "XYZ"] for m in a],
                               [[m.end[x] for x in "XYZ"] for m in b], rtol=0, atol=1e-9)


def test_a_hole_under_trans_is_drilled_in_the_shifted_frame(tmp_path):
    # CYCLE81(RTP 10, RFP 0, SDIS 2, DP -5) under TRANS Z-3: R -1, bottom -8, retract to 7
    got = _gcode(tmp_path, "N10 G0 X0 Y0 Z20\nN20 TRANS X5 Z-3\nN30 G0 X0 Y0\n"
                           "N40 CYCLE81(10,0,2,-5)\nM30\n")
    assert got[1:5] == ["G0 X5 Y0", "G99 G81 X5 Y0 R-1 Z-8", "G80", "G0 Z7"]


# ---------------------------------------------------------------------------- SUPA / G53
SUPA = """N10 G54 G0 X10 Y20 Z30
N20 T1 M6
N30 D1
N40 G0 X10 Y20 Z30
N50 G0 SUPA Z0 D0
N60 G53 X-100
N70 D1
N80 G0 Y25
N90 G153 G0 Y0
N100 G0 X5 Z40
N110 M30
"""


def test_a_block_in_machine_coordinates_is_g53_of_the_equivalent(tmp_path):
    got = _gcode(tmp_path, SUPA)
    assert got[4:] == ["G0 X10 Y20 Z30", "G49", "G53 G0 Z0", "G53 G0 X-100", "G43 H1",
                       "G0 Y25", "G53 G0 Y0", "G0 X5 Z40", "M30"]


def test_a_block_in_machine_coordinates_passes_and_its_axes_are_unknown(tmp_path):
    path = _write(tmp_path, SUPA)
    lines = _lines_after(path, lambda p: np.tile([0.01, 0.01, 0.01], (len(p), 1)))
    # the SUPA, G53, G153 blocks as written; after them only the axes a block names are written
    assert lines[2:] == ["N10 G54 G0 X10.0100 Y20.0100 Z30.0100", "N20 T1 M6", "N30 D1",
                         "N40 G0 X10.0100 Y20.0100 Z30.0100", "N50 G0 SUPA Z0 D0",
                         "N60 G53 X-100", "N70 D1", "N80 G0 Y25.0100", "N90 G153 G0 Y0",
                         "N100 G0 X5.0100 Z40.0100", "N110 M30"]
    # the replay's oracle: X Z unknown from N50/N60 until N100 names them, Y unknown after N90
    positioned = replay_sinumerik.positioned_per_line("\n".join(lines))
    assert positioned[6][1] == {"Y", "X"} and positioned[7][1] == {"Y"}
    assert positioned[10][1] == set() and positioned[11][1] == {"X", "Z"}


@pytest.mark.parametrize("body, words", [
    ("N10 G0 X0 Y0 Z0\nN20 G2 SUPA X5 Y5 I=AC(0) J=AC(5)\n", "a circle in machine coordinates"),
    ("N10 G0 X0 Y0 Z0\nN20 MCALL CYCLE81(10,0,2,-5)\nN30 SUPA X5\n", "under a modal call"),
    ("N10 G0 X0 Y0 Z0\nN20 G4 F2 X5\n", "a dwell G4 with axis words"),
])
def test_machine_blocks_and_dwells_mtcomp_cannot_follow_are_refused(tmp_path, capsys, body, words):
    err = _refused(tmp_path, capsys, body + "M30\n")
    assert words in err, err
    assert re.search(r"p\.mpf:\d+:", err)


def test_a_circle_by_radius_from_an_unknown_position_is_refused(tmp_path):
    with pytest.raises(InputError, match="a circle from a position the program has not given"):
        translate(_write(tmp_path, "N10 G0 X0 Y0 Z0\nN20 G0 SUPA X0\nN30 G2 X6 Y0 CR=5\nM30\n"))


# ---------------------------------------------------------------------------- helices
def test_a_helix_gets_its_corrected_z(tmp_path):
    # half a turn from (20, 0, -1) to (-20, 0, -2) about (0, 0), Z corrected by 1e-4 * x: +2 um
    # at the start, -2 um at the end, so the end is Z-2.0020; the helix written (Z linear in the
    # angle from -0.998 to -2.002) misses the corrected path z(u) = -1 - u + 0.002 cos(pi u) by
    # -0.002 + 0.004 u + 0.002 cos(pi u), at most 0.42 um (u = 0.22, by hand)
    path = _write(tmp_path, "N10 G0 X20 Y0 Z5\nN20 G1 Z-1 F100\n"
                            "N30 G3 X-20 Y0 Z-2 I=AC(0) J=AC(0)\nN40 G0 Z5\nM30\n")
    lines = _lines_after(path, lambda p: np.outer(p[:, 0], [0, 0, 1e-4]))
    assert lines[3:6] == ["N20 G1 Z-0.9980 F100", "N30 G3 X-20 Y0 Z-2.0020 I=AC(0) J=AC(0)",
                          "N40 G0 Z4.9980"]
    arc = [m for m in replay_sinumerik.replay("\n".join(lines).encode()).moves if m.kind == "arc"]
    u = np.linspace(0, 1, 401)
    z = arc[0].start["Z"] + (arc[0].end["Z"] - arc[0].start["Z"]) * u
    miss = np.abs(z - (-1 - u + 0.002 * np.cos(np.pi * u)))
    assert 0.40e-3 < miss.max() <= 0.43e-3


def test_a_helix_by_radius_gets_its_corrected_z(tmp_path):
    path = _write(tmp_path, "N10 G0 X20 Y0 Z5\nN20 G1 Z-1 F100\nN30 G3 X0 Y20 Z-2 CR=20\n"
                            "N40 G0 Z5\nM30\n")
    lines = _lines_after(path, lambda p: np.tile([0.01, 0.0, 0.002], (len(p), 1)))
    assert lines[4] == "N30 G3 X0.0100 Y20 Z-1.9980 CR=20"


def test_a_helix_of_a_whole_turn_is_refused_in_one_line(tmp_path, capsys):
    err = _refused(tmp_path, capsys, "N10 G0 X20 Y0 Z5\nN20 G1 Z-1 F100\n"
                                     "N30 G3 Z-3 I=AC(0) J=AC(0)\nM30\n")
    assert "p.mpf:5:" in err and "a helix of a whole turn" in err, err


@pytest.mark.parametrize("body", [
    "N10 G0 X0 Y0 Z20\nN20 TRANS X5 Y7 Z-3\nN30 G0 X0 Y0\nN40 CYCLE81(10,0,2,-5)\nN50 G0 X20\nM30\n",
    "N10 G0 X0 Y0 Z20\nN20 ATRANS X5 Y7\nN30 MCALL CYCLE81(10,0,2,-5)\nN40 G0 X0 Y0\nN50 X10 Y0\n"
    "N60 MCALL\nN70 G0 X20\nM30\n",
])
def test_holes_under_trans_with_no_correction_write_the_program_unchanged(tmp_path, body):
    """Under TRANS/ATRANS a hole's position in the program's frame was compared with (and stored
    as) the writer's G-code-frame position: a block `X0.0000 Y0.0000` was added before the call,
    and the next block got `Y0.0000`. With no correction the output is the input."""
    lines = _lines_after(_write(tmp_path, body), lambda p: np.zeros((len(p), 3)))
    assert lines == (HEAD + body).splitlines()


def test_a_half_circle_by_radius_rounded_by_a_fraction_of_a_micron_is_read():
    """CR=5 to an end 10.0004 mm away (a CAM half circle, its end rounded): half the chord is 0.2 um
    longer than the radius; taken as a half circle about the chord's middle, as the R arcs of the
    G-code dialects are (within 0.01 mm); 0.03 mm longer is refused."""
    from mtcomp.toolpaths.sinumerik_paths import RadiusError, radius_centre
    np.testing.assert_allclose(radius_centre((0.0, 0.0), (10.0004, 0.0), 5.0, False), (5.0002, 0.0),
                               rtol=0, atol=1e-12)
    with pytest.raises(RadiusError, match="smaller than half the chord"):
        radius_centre((0.0, 0.0), (10.06, 0.0), 5.0, False)
    # the sides by hand (a 3-4-5 triangle): G2 CR=5 from (0,0) to (8,0) turns about (4,-3), G3 (4,3);
    # CR=-5 the other side
    np.testing.assert_allclose(radius_centre((0, 0), (8, 0), 5.0, False), (4, -3), rtol=0, atol=1e-12)
    np.testing.assert_allclose(radius_centre((0, 0), (8, 0), 5.0, True), (4, 3), rtol=0, atol=1e-12)
    np.testing.assert_allclose(radius_centre((0, 0), (8, 0), -5.0, True), (4, -3), rtol=0, atol=1e-12)


@pytest.mark.parametrize("body, line, says", [
    # a frame turned by CYCLE800: the next positions are in it (a safety tester's finding: the
    # corrections were written as if no frame were in force)
    ('N10 G0 X0 Y0 Z10\nN20 CYCLE800(0,"TABLE",100000,57,0,0,0,30,0,0,0,0,0,-1,100,1)\n'
     "N30 G1 X20 Y5 Z5 F300\nM30\n", 4, "CYCLE800 with a rotation or an offset"),
    ('N10 G0 X0 Y0 Z10\nN20 CYCLE800(1,"TABLE",0,57,5,0,0,0,0,0,0,0,0,1)\nN30 G1 X20\nM30\n', 4,
     "CYCLE800 with a rotation or an offset"),
    # frames set through the system variables (mirror, rotation, shift): not followed
    ("N10 G0 X0 Y0 Z10\nN20 $P_PFRAME=CMIRROR(X)\nN30 G1 X-20 Y5 F300\nM30\n", 4,
     "the system variable $P_PFRAME"),
    ("N10 G0 X0 Y0 Z10\nN20 $P_PFRAME=CROT(Z,90)\nN30 G1 X20 F300\nM30\n", 4,
     "the system variable $P_PFRAME"),
])
def test_a_frame_mtcomp_does_not_follow_is_refused_in_one_line(tmp_path, capsys, body, line, says):
    err = _refused(tmp_path, capsys, body)
    assert f"p.mpf:{line}:" in err and says in err, err


@pytest.mark.parametrize("call", ["CYCLE800()", 'CYCLE800(0,"TABLE",100000,57,0,0,0,0,0,0,0,0,0,-1)'])
def test_cycle800_that_cancels_the_swivel_passes_through(tmp_path, capsys, call):
    """CYCLE800() (and one whose angles and offsets are all 0) cancels the swivelled frame: the
    block passes through and the positions after it are unknown until named (the X of N30, whose
    Y and Z are not given again, is not corrected; N40 names them all and is)."""
    body = f"N10 G0 X0 Y0 Z10\nN20 {call}\nN30 G1 X20 F300\nN40 G0 X0 Y0 Z10\nM30\n"
    machine = _machine_file(tmp_path, "XFYZ")
    out = tmp_path / "out.mpf"
    argv = ["compensate", machine, _model_file(tmp_path, machine), _write(tmp_path, body),
            "-o", out, "--quiet"]
    assert main([str(a) for a in argv]) == 0
    capsys.readouterr()
    lines = out.read_text().splitlines()
    k = HEAD.count("\n")
    assert lines[k + 1:k + 3] == [f"N20 {call}", "N30 G1 X20 F300"]
    assert lines[k + 3] != "N40 G0 X0 Y0 Z10"             # named again: corrected

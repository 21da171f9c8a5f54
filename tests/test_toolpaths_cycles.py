"""Drilling cycles (G73, G81-G89) kept as cycles with corrected hole positions: hand-written
programs checked block by block and line by line, on the compiled and the pure-Python path.

The expectations are derived by hand from the RS-274 / Fanuc rules: in G90, X Y give the hole, Z its
bottom, R the R plane (all sticky); in G91, X Y are steps repeated L times, R is measured from the Z
the cycle starts at and Z from the R plane; G98 leaves the tool at the initial level, G99 at the R
plane. The corrections below move X by +1.2 um, Y by -2.1 um and Z by +3.3 um on every known axis,
so each written word shows which correction it carries.
"""
import numpy as np
import pytest

from mtcomp import InputError, load_machine
from mtcomp.toolpaths import iter_segment_chunks, read_program, write_corrected
from replay import Tolerance, compare
from test_toolpaths_gcode import gcode_path  # noqa: F401  (autouse: compiled and Python path)

XFYZ = load_machine("xfyz")
SHIFT = np.array([0.0012, -0.0021, 0.0033])

PROGRAM = """G21 G90 G17
G0 X0 Y0 Z10
G98 G81 X5 Y5 Z-3 R2 F100
X10
G99 G83 X20 Y5 Z-8 R1 Q2
Y10
G80
G0 Z10
G91 G98 G73 X5 Y0 Z-4 R-8 Q1 L3
G90 G80
G0 X0 Y0
M30
"""


def _write(path, shift=SHIFT, stats=None, machine=XFYZ):
    """The program corrected by ``shift`` on every known axis (rotary axes beyond it by 0)."""
    out = path.with_name("out.nc")
    shift = np.concatenate([shift, np.zeros(len(machine.axis_names) - len(shift))])
    corr = [(c, c.end + np.where(c.known, shift, 0.0), np.ones(len(c), int))
            for c in iter_segment_chunks(path, machine)]
    write_corrected(path, out, machine, iter(corr), stats=stats)
    return out.read_text().splitlines()


def test_cycle_blocks_are_the_hole_bottoms(tmp_path):
    p = tmp_path / "in.nc"
    p.write_text(PROGRAM)
    b = read_program(p, XFYZ).blocks
    assert [x.line for x in b] == [2, 3, 4, 5, 6, 8, 9, 11]
    holes = {x.line: x.points.tolist() for x in b if x.cycle is not None}
    assert holes == {3: [[5, 5, -3]], 4: [[10, 5, -3]], 5: [[20, 5, -8]], 6: [[20, 10, -8]],
                     # G91 from (20, 10, 10): R plane 10 - 8 = 2, bottom 2 - 4 = -2, X steps of 5
                     9: [[25, 10, -2], [30, 10, -2], [35, 10, -2]]}
    cyc = {x.line: x.cycle for x in b if x.cycle is not None}
    assert [(c.r_level, c.z_bottom, c.retract) for c in cyc.values()] == [
        (2, -3, 98), (2, -3, 98), (1, -8, 99), (1, -8, 99), (2, -2, 98)]
    # where each cycle leaves the tool: G98 the initial level 10, G99 the R plane 1
    assert [x.end[2] for x in b if x.cycle is not None] == [10, 10, 1, 1, 10]
    assert all(x.known.all() for x in b)
    seg = list(iter_segment_chunks(p, XFYZ))[0]
    assert seg.cycle.tolist() == [False] + [True] * 4 + [False] + [True] * 3 + [False]
    assert seg.feed[seg.cycle].tolist() == [100.0] * 7
    assert seg.dirs[1, 2] == -1                       # the drill goes down into the hole


def test_cycles_are_written_with_corrected_holes(tmp_path):
    p = tmp_path / "in.nc"
    p.write_text(PROGRAM)
    stats = {}
    out = _write(p, stats=stats)
    assert out == [
        "G21 G90 G17",
        "G0 X0.0012 Y-0.0021 Z10.0033",
        "G98 G81 X5.0012 Y4.9979 Z-2.9967 R2.0033 F100",     # R moves with Z: depth kept
        "X10.0012",                                          # Y, Z, R as the output holds them
        "G99 G83 X20.0012 Y4.9979 Z-7.9967 R1.0033 Q2",
        "Y9.9979",
        "G80",
        "G0 Z10.0033",
        # incremental with L3: absolute, one line per hole, L dropped
        "G98 G73 X25.0012 Y9.9979 Z-1.9967 R2.0033 Q1",
        "X30.0012 Y9.9979",
        "X35.0012 Y9.9979",
        "G90 G80",
        "G0 X0.0012 Y-0.0021",          # G98: Z stands at the initial level 10.0033 already
        "M30"]
    assert stats == {"cycle_lines": 0, "cycle_blocks": 5}


def test_uncorrected_cycles_are_written_as_the_source(tmp_path):
    p = tmp_path / "in.nc"
    p.write_text(PROGRAM.replace("G91 G98 G73 X5 Y0 Z-4 R-8 Q1 L3", "G98 G73 X25. Y10 Z-2 R2 Q1"))
    out = _write(p, shift=np.zeros(3))
    assert out == p.read_text().splitlines()


def test_sticky_words_are_restated_when_the_output_holds_others(tmp_path):
    # the first hole is corrected, the second not: its Z and R must be written again
    p = tmp_path / "in.nc"
    p.write_text("G21 G90\nG0 X0 Y0 Z10\nG99 G81 X5 Y5 Z-3 R2 F100\nX10\n")
    out = p.with_name("out.nc")

    def corr():
        for c in iter_segment_chunks(p, XFYZ):
            pts = c.end.copy()
            pts[c.line == 3] += SHIFT
            yield c, pts, np.ones(len(c), int)
    write_corrected(p, out, XFYZ, corr())
    assert out.read_text().splitlines()[2:] == ["G99 G81 X5.0012 Y4.9979 Z-2.9967 R2.0033 F100",
                                                "X10 Y5.0000 Z-3.0000 R2.0000"]


def test_retract_level_decides_what_is_known_after(tmp_path):
    p = tmp_path / "in.nc"
    # no G98/G99 stated: Z after the cycle is not known; G98 with R above the start: not known
    # (controllers differ); the next move names only X, so Z is not written
    p.write_text("G21 G90\nG0 X0 Y0 Z10\nG81 X5 Y5 Z-3 R2 F100\nG80\nG0 X1\nG0 Z1\n"
                 "G98 G81 X5 Y5 Z-3 R2 F100\nG80\nG0 X2\n")
    b = read_program(p, XFYZ).blocks
    known = {x.line: x.known.tolist() for x in b}
    assert known[5] == [True, True, False] and known[9] == [True, True, False]
    out = _write(p)
    assert out[4] == "G0 X1.0012" and out[8] == "G0 X2.0012"


def test_cycle_at_unknown_position_passes_through(tmp_path):
    p = tmp_path / "in.nc"
    p.write_text("G21 G90\nG0 X0 Y0 Z10\nG28 G91 X0 Y0\nG90\nG98 G81 Z-3 R2 F100\nX10 Y5\n"
                 "G80\nG0 Z10\n")
    b = read_program(p, XFYZ).blocks
    # line 5 drills at an X Y the program does not know: passed through; line 6 gives X and Y
    assert [x.line for x in b] == [2, 6, 8]
    stats = {}
    out = _write(p, stats=stats)
    src = p.read_text().splitlines()
    assert out[0] == src[0] and out[2:5] == src[2:5]
    assert out[5] == "X10.0012 Y4.9979 Z-2.9967 R2.0033"
    # the G28 of line 3 moves X and Y home: a move passed through uncorrected, counted; line 6
    # gets the Z its hole's depth needs, a word it did not name: counted too
    assert stats == {"cycle_lines": 1, "cycle_blocks": 1, "passed_moves": {"home": (1, 3)},
                     "added_axis_words": (1, 6)}


@pytest.mark.parametrize("text, line, words", [
    ("G0 X0 Y0 Z10\nG91 G99 G81 X5 Z-3 R-8 F100\nX5\n", 3, "continued without G98"),
    ("G0 X0 Y0\nG91 G98 G81 X5 Z-3 R-8 F100\n", 2, "from a position the program has not given"),
    ("G0 X0 Y0 Z10\nG91 G98 G81 X5 Z-3 R-8 A10 F100\n", 2,
     "incremental (G91) drilling cycle G81: a rotary axis word A on the line"),
    ("G0 X0 Y0 Z10\nG98 G81 X5 Z-3 R2 L0 F100\n", 2, "repeat count 0"),
])
def test_unclear_incremental_cycles_are_refused(tmp_path, text, line, words):
    p = tmp_path / "in.nc"
    p.write_text("G21 G90\n" + text)
    machine = load_machine("cafxyz") if "A10" in text else XFYZ
    with pytest.raises(InputError) as e:
        read_program(p, machine)
    msg = str(e.value)
    assert words in msg and f":{line + 1}:" in msg and "\n" not in msg


def test_words_keep_their_places(tmp_path):
    # pcb2gcode writes R and Z first, FreeCAD R last; Y keeps the value the output holds
    p = tmp_path / "in.nc"
    p.write_text("G21 G90\nG0 X0 Y0 Z10\nG81 R5.00000 Z-2.50000 F1000.00000 X12.55500 Y10.94500\n"
                 "G98 G83 X-2.827 Z-4.000 F60.000 Q0.100 R3.000\nG80\n")
    out = _write(p)
    assert out[2:4] == ["G81 R5.00330 Z-2.49670 F1000.00000 X12.55620 Y10.94290",   # 5 decimals kept
                        "G98 G83 X-2.8258 Z-3.9967 F60.000 Q0.100 R3.0033"]


def test_unchanged_coordinates_keep_their_spelling(tmp_path):
    # five decimals in the source: an uncorrected line as written; the next hole's Y corrected,
    # its Z and R still those the controller holds from the source's spelling
    p = tmp_path / "in.nc"
    p.write_text("G21 G90\nG0 X0 Y0 Z10\nG99 G81 X1.23456 Y2 Z-2.50004 R1.00004 F100\nX3\n")
    out = p.with_name("out.nc")
    corr = []
    for c in iter_segment_chunks(p, XFYZ):
        pts = c.end.copy()
        pts[c.line == 4] += [0.0, 0.0012, 0.0]
        corr.append((c, pts, np.ones(len(c), int)))
    write_corrected(p, out, XFYZ, iter(corr))
    assert out.read_text().splitlines()[2:] == ["G99 G81 X1.23456 Y2 Z-2.50004 R1.00004 F100",
                                                "X3 Y2.0012"]


def test_real_pcb2gcode_drill_program_line_by_line(tmp_path):
    # pcb2gcode's drill file (inch, G81 without G98/G99), every known axis moved by +0.0001 in in X,
    # -0.0002 in in Y, +0.0003 in in Z: the holes carry it, R moves with Z, the rest as published
    from pathlib import Path
    src = Path(__file__).parent / "data" / "gcode_corpus" / \
        "pcb2gcode_example_board_new_default_drill.ngc"
    p = tmp_path / "in.ngc"
    p.write_bytes(src.read_bytes())
    out = _write(p, shift=np.array([0.0001, -0.0002, 0.0003]) * 25.4)
    lines = src.read_text().splitlines()
    expected = list(lines)
    expected[12] = "G00 Z1.00030 (Retract)"
    expected[20] = "G0 Z0.08030"                 # after M6 only Z; X and Y not given yet
    expected[23:26] = ["G81 R0.08030 Z-0.06269 F30.00000 X0.90010 Y-0.45020",
                       "X1.65010 Y-0.55020", "X1.65010 Y-0.80020"]
    # no G98/G99 in the program: Z after the cycle is not known until the retract names it
    expected[28] = "G00 Z1.00030 ( All done -- retract )"
    assert out == expected


def test_haas_peck_words_are_not_a_repeat_count(tmp_path):
    """Haas G83 writes I (first peck), J (reduction) and K (minimum peck): K is then no repeat count.
    In G90 the line is corrected once; in G91 with L2 the L gives the count and K0.5 stays."""
    p = tmp_path / "in.nc"
    p.write_text("G21 G90 G17\nG0 X0 Y0 Z10\nG98 G83 X5 Y5 Z-3 R2 I1 J0.2 K0.5 F100\n"
                 "G91 G98 G83 X5 Y0 Z-4 R-8 I1 J0.2 K0.5 L2\nG90 G80\nM30\n")
    holes = [x.points.tolist() for x in read_program(p, XFYZ).blocks if x.cycle is not None]
    # second line from (5, 5, 10): R plane 2, bottom -2, two steps of 5 in X
    assert holes == [[[5, 5, -3]], [[10, 5, -2], [15, 5, -2]]]
    out = _write(p)
    assert out[2] == "G98 G83 X5.0012 Y4.9979 Z-2.9967 R2.0033 I1 J0.2 K0.5 F100"
    assert out[3] == "G98 G83 X10.0012 Y4.9979 Z-1.9967 R2.0033 I1 J0.2 K0.5"
    assert out[4].startswith("X15.0012")


def test_fanuc_k_is_the_repeat_count_without_l(tmp_path):
    p = tmp_path / "in.nc"
    p.write_text("G21 G90 G17\nG0 X0 Y0 Z10\nG91 G98 G81 X5 Y0 Z-4 R-8 K2 F100\nG90 G80\nM30\n")
    holes = [x.points.tolist() for x in read_program(p, XFYZ).blocks if x.cycle is not None]
    assert holes == [[[5, 0, -2], [10, 0, -2]]]


@pytest.mark.parametrize("text, written", [
    # G18 drills along Y: Z3 X4 place the hole, Y-5 is its bottom; G98 takes Y back to the
    # initial level (not followed: Y unknown after), so the next lines write X and Z, never Y
    ("G0 X0 Y5 Z10\nG18 G98 G81 Z3 X4 R2 Y-5 F100\nG80\nG17\nG0 X20\nG1 Z0 F100\n",
     ["G0 X20.0012 Z3.0033", "G1 Z0.0033 F100"]),
    # G19 drills along X: Y3 Z4 place the hole, X-5 is its bottom; X unknown after it
    ("G0 X10 Y0 Z5\nG99 G19 G81 Y3 Z4 R2 X-5 F100\nG80\nG17\nG0 Y20\nG1 X0 F100\n",
     ["G0 Y19.9979 Z4.0033", "G1 X0.0012 F100"]),
])
def test_cycle_in_another_plane_leaves_its_drilling_axis_unknown(tmp_path, text, written):
    # a G18/G19 cycle passes through uncorrected (LinuxCNC's interp_cycles.cc: convert_cycle_zx
    # drills along Y, convert_cycle_yz along X); the axis it drills along is not where its word
    # says after it (that word is the bottom), the plane's two axes are
    p = tmp_path / "in.nc"
    p.write_text("G21 G90 G17\n" + text)
    out = _write(p)
    assert out[2:5] == p.read_text().splitlines()[2:5]     # the cycle line, G80, G17 as written
    assert out[5:7] == written
    # the replay (tests/replay.py, the plane's drilling axis from LinuxCNC's source) moves both alike
    compare(p.read_bytes(), "\n".join(out).encode() + b"\n",
            Tolerance(axis_mm=0.005, axis_deg=0.01, path_mm=0.01))


CBFXYZ = load_machine("cbfxyz")          # axes X Y Z B C
#: 5-axis drilling: the first hole at B0 C0 is corrected; the second line turns B, so it and the
#: rest of its series pass through as written (where the control turns B and along which axis it
#: then drills is its own rule); X Y Z are not known after them, B and C are
ROTARY_SERIES = """G21 G90 G17
G0 X0 Y0 Z10 B0 C0
G98 G81 X5 Y5 Z-3 R2 F100
X10 Z-4 B90. R2
X20 Y5
G80
G0 X30 Y5
G0 Z10
M30
"""


def test_cycle_series_turning_a_rotary_axis_passes_through(tmp_path):
    p = tmp_path / "in.nc"
    p.write_text(ROTARY_SERIES)
    blocks = read_program(p, CBFXYZ).blocks
    assert [b.line for b in blocks] == [2, 3, 7, 8]
    # after the series X Y Z are not known until given again; B stands at 90 deg
    assert blocks[2].known.tolist() == [True, True, False, True, True]
    assert blocks[2].start[3] == pytest.approx(np.pi / 2, abs=1e-12)
    stats = {}
    out = _write(p, stats=stats, machine=CBFXYZ)
    src = ROTARY_SERIES.splitlines()
    assert out[2] == "G98 G81 X5.0012 Y4.9979 Z-2.9967 R2.0033 F100"
    assert out[3:6] == src[3:6]
    # no Z added to the rapid: the program had not given Z again after the cycle
    assert out[6:8] == ["G0 X30.0012 Y4.9979", "G0 Z10.0033"]
    assert stats["cycle_lines"] == 2 and stats["cycle_blocks"] == 1


@pytest.mark.parametrize("line", ["X10 B90.", "X10 Z-4 B90."])
def test_rotary_cycle_line_on_a_corrected_cycles_levels_is_refused(tmp_path, line):
    # the passed line would drill from the R plane (or to the bottom) the output's cycle holds,
    # corrected for the hole before it: refused, naming the level it does not give
    p = tmp_path / "in.nc"
    p.write_text(f"G21 G90 G17\nG0 X0 Y0 Z10 B0 C0\nG98 G81 X5 Y5 Z-3 R2 F100\n{line}\nG80\n")
    with pytest.raises(InputError) as e:
        _write(p, machine=CBFXYZ)
    msg = str(e.value)
    assert ":4:" in msg and "passed through uncorrected without its own R" in msg
    assert "R2.0033" in msg and "\n" not in msg

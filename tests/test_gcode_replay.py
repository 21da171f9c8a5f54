"""Every accepted program of the corpus (tests/data/gcode_corpus) and its compensated version
replayed as a controller would (tests/replay.py, written from the RS-274 rules without mtcomp's
reader): the same motion up to the correction, block by block (a block may be split into pieces
along its path), no motion the source lacks, every line without motion kept byte for byte, and the
size of the output against the input's."""
import math
import re
import statistics

import numpy as np
import pytest

import replay_heidenhain
import replay_sinumerik
from replay import Tolerance, compare, replay
from test_gcode_corpus import (DIALECTS, PROGRAMS, REFUSED, UNCHANGED, _dialect_option,
                               _model_file, _topology, axis_letters, program_machine_file,
                               run_once, source_bytes)

#: the correction bounds passed to compensate; the model's errors are larger, so they bind
BOUND_UM, BOUND_URAD = 20.0, 500.0
#: a corrected word rounded to the writer's decimals (at worst 4 in inch: 1.27 um)
ROUNDING_MM = 1.3e-3
CHORD_UM = 1.0
TOL = Tolerance(axis_mm=BOUND_UM * 1e-3 + ROUNDING_MM,
                axis_deg=math.degrees(BOUND_URAD * 1e-6) + 1e-4,
                path_mm=math.sqrt(3) * (BOUND_UM * 1e-3 + ROUNDING_MM) + CHORD_UM * 1e-3 + 1e-3)
#: a Sinumerik program's full circles (one block each) are written within this chord tolerance
SINUMERIK_CHORD_UM = 5.0
ACCEPTED = [p for p in PROGRAMS if p.name not in REFUSED]
#: accepted programs whose output today does not move like the source, and why
KNOWN_WRONG: dict = {}
#: accepted programs in which no block can be corrected on the machine of their own axes, and why
#: (their output is still replayed against the source)
UNCORRECTED = {
    # after CYCLE800() (the swivel cycle, which mtcomp cannot see: every axis unknown after it)
    # the program never names its rotary axes A and C again, so no block has every axis given
    "sinumerikcas_CAM TEST.MPF": "A and C unknown after CYCLE800() to the end",
}


def _compensated(prog, tmp_path_factory) -> bytes:
    """A corpus program compensated by a model whose corrections reach the bound (once a
    session: the aggregate tests below read it again)."""
    siemens = _is_sinumerik(prog.read_bytes())

    def argv(folder):
        # a Sinumerik program on the machine of its own axes: on the corpus test's CBFXYZ machine
        # the C axis it never names is lost at its first subprogram call, and nothing would be
        # corrected (or checked here)
        text = prog.read_text(encoding="latin-1")
        own = axis_letters(text) & set("ABC")
        topology = ("C" * ("C" in own) + "A" * ("A" in own) + "B" * ("B" in own and "A" not in own)
                    + "FXYZ") if siemens else _topology(text)
        machine = program_machine_file(folder, prog, topology)
        # a conversational or Sinumerik program's arc is not split (its blocks stay one to one),
        # so under this strong model, whose correction changes by tens of um around one arc, its
        # arcs are refused (tests/test_toolpaths_heidenhain.py); it is replayed at the usual size,
        # a Sinumerik program's full circles of 48 mm radius with a chord tolerance of 5 um
        one_to_one = prog.suffix == ".h" or siemens
        model = _model_file(folder, machine, factor=1.0 if one_to_one else 30.0)
        return ["compensate", str(machine), str(model), str(prog), "-o", str(folder / "out.nc"),
                "--quiet", "--units", "mm", "--max-correction-um", str(BOUND_UM),
                "--max-correction-urad", str(BOUND_URAD),
                "--chord-tol-um", str(SINUMERIK_CHORD_UM if siemens else CHORD_UM)
                ] + _dialect_option(prog)
    code, _stdout, err, out = run_once(tmp_path_factory, f"replay-{prog.name}", argv)
    assert code == 0, (prog.name, err)
    return out


@pytest.mark.parametrize("prog", [
    pytest.param(p, marks=pytest.mark.xfail(strict=False, reason=KNOWN_WRONG[p.name]))
    if p.name in KNOWN_WRONG else p for p in ACCEPTED], ids=[p.name for p in ACCEPTED])
def test_output_moves_like_the_source_up_to_the_correction(prog, tmp_path_factory, capsys):
    out = _compensated(prog, tmp_path_factory)
    capsys.readouterr()
    if prog.name in UNCHANGED:      # nothing to correct: the file as it is
        assert out == prog.read_bytes()
        return
    src = source_bytes(prog)
    if prog.suffix == ".h":         # Heidenhain conversational: its own replay
        src_moves, _out = replay_heidenhain.compare(src, out, TOL, name=prog.name)
        assert src_moves, f"{prog.name}: the replay found no motion"
        return
    if _is_sinumerik(src):          # Siemens Sinumerik: its own replay
        tol = Tolerance(TOL.axis_mm, TOL.axis_deg, TOL.path_mm + SINUMERIK_CHORD_UM * 1e-3)
        src_moves, out_moves = replay_sinumerik.compare(src, out, tol, name=prog.name)
        assert src_moves, f"{prog.name}: the replay found no motion"
        # the model's corrections are written: most moves end elsewhere than in the source
        ends = {tuple(m.end.items()) for m in src_moves}
        moved = sum(tuple(m.end.items()) not in ends for m in out_moves)
        assert moved > len(src_moves) // 2 or (prog.name in UNCORRECTED and moved == 0)
        return
    # a program of BeagleG's given --dialect beagleg is replayed with BeagleG's rules
    beagleg = True if DIALECTS.get(prog.name) == "beagleg" else None
    src_moves, out_moves = compare(src, out, _tolerance(src), name=prog.name, beagleg=beagleg)
    assert src_moves, f"{prog.name}: the replay found no motion"


def _is_sinumerik(src: bytes) -> bool:
    return replay_sinumerik.is_sinumerik(src)


def _tolerance(src: bytes) -> Tolerance:
    """TOL, or for a tool centre point program (M428, G43.4, M128: X Y Z are the tool tip on the
    turning table) TOL widened by what the rotary axes' corrections move the tip: at most the
    table's turn by the angle bound (each of its rotary axes), times the tip's largest distance
    from the origin, through which this machine's rotary axis lines pass."""
    if not re.search(rb"(?im)^[^(;\n]*\b(M428|M128|G43\.4)\b", src):
        return TOL
    r = max(math.sqrt(sum(m.end[k] ** 2 for k in "XYZ")) for m in replay(src).moves
            if all(m.end.get(k) is not None for k in "XYZ"))
    turn = 2 * r * BOUND_URAD * 1e-6
    return Tolerance(TOL.axis_mm + turn, TOL.axis_deg, TOL.path_mm + turn)


def test_the_correction_is_not_zero(tmp_path_factory, capsys):
    # the model is strong enough that most programs get corrected end points somewhere
    moved = 0
    for prog in ACCEPTED:
        if prog.name in UNCHANGED:
            continue
        play = replay_heidenhain.replay if prog.suffix == ".h" else \
            replay_sinumerik.replay if _is_sinumerik(prog.read_bytes()) else replay
        a = play(prog.read_bytes()).moves
        b = play(_compensated(prog, tmp_path_factory)).moves
        ends_a = {tuple(m.end.items()) for m in a}
        moved += any(tuple(m.end.items()) not in ends_a for m in b)
    capsys.readouterr()
    assert moved >= len(ACCEPTED) // 2, moved


def _median_ratio(tmp_path_factory):
    ratios = [len(_compensated(p, tmp_path_factory)) / p.stat().st_size for p in ACCEPTED]
    print("output size / input size:", " ".join(f"{r:.2f}" for r in sorted(ratios)))
    return statistics.median(ratios)


def test_median_output_size_with_corrections_at_their_bound(tmp_path_factory, capsys):
    """With this strong model every line's every axis carries a correction at its bound, so most
    lines get the axes they did not name: 1.35 times the input today. The goal of 1.2 is checked
    with the corpus test's model (tests/test_gcode_corpus.py: 1.11)."""
    median = _median_ratio(tmp_path_factory)
    with capsys.disabled():
        print(f"\nmedian output / input size: {median:.2f}")
    assert median <= 1.5


# ---------------------------------------------------------------------------------------------
# the replay and the comparison against hand-derived cases

def _ends(program: bytes):
    return [tuple(m.end[a] for a in "XYZ") for m in replay(program).moves]


def test_replay_follows_units_increments_and_planes():
    moves = replay(b"G20 G90\nG0 X1 Y2 Z3\nG91 G1 X1\nG90 G18 G2 X3 Z2 I1 K0\n").moves
    np.testing.assert_allclose([[m.end[a] for a in "XYZ"] for m in moves],
                               [[25.4, 50.8, 76.2], [50.8, 50.8, 76.2], [76.2, 50.8, 50.8]],
                               rtol=0, atol=1e-12)
    # the arc in the ZX plane (Z first, X second, Y the normal): centre (Z, X) = (3 in, 3 in) from
    # the offsets; from (0, -1) in to (-1, 0) in about it, clockwise: a quarter turn
    np.testing.assert_allclose(moves[2].centre, (76.2, 76.2), rtol=0, atol=1e-12)
    assert moves[2].sweep == pytest.approx(-math.pi / 2, rel=0, abs=1e-12)


def test_replay_expands_drilling_cycles_with_their_retract():
    # G99: back to R after each hole; G98: back to the initial level 10 (above R 2)
    g99 = _ends(b"G21 G0 X0 Y0 Z10\nG99 G81 X1 Y1 Z-3 R2 F100\nX2\nG80\n")
    assert g99[1:] == [(1, 1, 10), (1, 1, 2), (1, 1, -3), (1, 1, 2),
                       (2, 1, 2), (2, 1, 2), (2, 1, -3), (2, 1, 2)]
    g98 = _ends(b"G21 G0 X0 Y0 Z10\nG98 G81 X1 Y1 Z-3 R2 F100\nX2\n")
    assert g98[4] == (1, 1, 10) and g98[-1] == (2, 1, 10)
    # G91: R from the current level, Z from R, L holes 1 apart
    g91 = _ends(b"G21 G0 X0 Y0 Z10\nG91 G99 G81 X1 R-8 Z-5 L2\n")
    assert g91[1:] == [(1, 0, 10), (1, 0, 2), (1, 0, -3), (1, 0, 2),
                       (2, 0, 2), (2, 0, 2), (2, 0, -3), (2, 0, 2)]


def test_replay_forgets_positions_after_home_moves_and_tool_changes():
    moves = replay(b"G21 G0 X1 Y1 Z1\nG28 G91 Z0\nG90 G0 X2\nT2 M6\nG0 X3\n"
                   b"G53 G0 Y0\nG04 P1 G0 X4\n").moves
    assert [tuple(m.end[a] for a in "XYZ") for m in moves] == [
        (1, 1, 1), (1, 1, None), (2, 1, None), (3, 1, None), (3, None, None), (4, None, None)]


SRC = b"G21\nG0 X0 Y0 Z5\nG1 Z0 F100\nG1 X10 (cut)\nG2 X20 Y0 I5 J0\nM30\n"


def test_compare_accepts_a_correction_and_a_split_block():
    compare(SRC, SRC.replace(b"X10 (cut)", b"X10.015 (cut)"), TOL)
    split = SRC.replace(b"G1 X10 (cut)", b"G1 X5.01 (cut)\nX10.01")
    assert split.count(b"\n") == SRC.count(b"\n") + 1
    compare(SRC, split, TOL)
    # the arc as two arcs
    compare(SRC, SRC.replace(b"G2 X20 Y0 I5 J0", b"G2 X15 Y5 I5 J0\nX20 Y0 I0 J-5"), TOL)


@pytest.mark.parametrize("out, message", [
    (SRC.replace(b"X10 (cut)", b"X10.03 (cut)"), "no matching output motion"),
    (SRC.replace(b"M30", b"M30 (end)"), "line without motion"),
    (SRC.replace(b"M30", b"G1 X30\nM30"), "moves where the source does not"),
    (SRC.replace(b"G1 X10 (cut)", b"G1 X5 Y1 (cut)\nX10"), "no matching output motion"),
    (SRC.replace(b"G2 X20", b"G3 X20"), "no matching output motion"),      # the other half circle
    (SRC.replace(b"G0 X0 Y0 Z5", b"G0 X0 Y0 Z5 A0"), "no matching output motion"),
    (SRC.replace(b"G21\n", b"G20\n"), "line without motion"),
])
def test_compare_sees_motion_the_source_lacks(out, message):
    with pytest.raises(AssertionError, match=message):
        compare(SRC, out, TOL)


W_SRC = b"G20 G90\nG0 X0 Y0 Z.2 W0\nG1 X1. F10\nW-1.\nG1 X2. W-1.\nM30\n"


@pytest.mark.parametrize("out, message", [
    (W_SRC.replace(b"\nW-1.\n", b"\nW-1.0001\n"), "no matching output motion"),  # W corrected
    (W_SRC.replace(b"X2. W-1.", b"X2."), None),          # W held where it stood: the same motion
    (W_SRC.replace(b"\nW-1.\n", b"\n"), "no matching output motion"),            # W dropped
    (W_SRC.replace(b"G1 X1. F10", b"G1 X1. W.5 F10"), "no matching output motion"),    # W added
])
def test_compare_carries_the_quill_w_exactly(out, message):
    # the quill W (parallel to Z) is never corrected: a W the output moves elsewhere is caught
    src_moves, _ = compare(W_SRC, W_SRC, TOL)
    assert [m.end["W"] for m in src_moves] == [0.0, 0.0, -25.4, -25.4]      # inch: 1 in = 25.4 mm
    if message is None:
        compare(W_SRC, out, TOL)
    else:
        with pytest.raises(AssertionError, match=message):
            compare(W_SRC, out, TOL)


G91_SRC = b"G21 G90\nG0 X0 Y0 Z5\nG91 G1 X10. F100\nX10.\nY5. (up)\nG90 G0 Z5\nM30\n"


def test_compare_replays_incremental_output():
    # the output in G91 as the source: the first increment carries the correction (+15 um in X),
    # the others as written; the replay adds them up to the corrected ends
    out = G91_SRC.replace(b"G91 G1 X10.", b"G91 G1 X10.015")
    src_moves, out_moves = compare(G91_SRC, out, TOL)
    assert [m.end["X"] for m in out_moves[1:4]] == pytest.approx([10.015, 20.015, 20.015],
                                                                 rel=0, abs=1e-12)
    # an increment that keeps a correction twice lands 15 um further on: out of tolerance at the
    # bound of 20 um plus rounding
    with pytest.raises(AssertionError, match="no matching output motion"):
        compare(G91_SRC, out.replace(b"\nX10.\n", b"\nX10.015\n"), TOL)
    # twice as many increments of Y (no Y5 -> Y10): the replay sees it
    with pytest.raises(AssertionError, match="no matching output motion"):
        compare(G91_SRC, out.replace(b"Y5. (up)", b"Y10. (up)"), TOL)


def test_replay_runs_a_zero_radius_circle_as_a_block_that_does_not_move():
    moves = replay(b"G21 G0 X1 Y2 Z3\nG3 X1 Y2 I0.000 F100\nG3 X1 Y2 I0.5\n").moves
    assert [m.kind for m in moves] == ["rapid", "none", "arc"]
    assert moves[1].start == moves[1].end == moves[0].end and moves[1].centre is None
    assert moves[2].sweep == pytest.approx(2 * math.pi, rel=0, abs=1e-12)
    # the circle written at the corrected point of the move before matches; elsewhere it does not
    src = b"G21\nG0 X1 Y2 Z3\nG3 X1 Y2 I0.000 F100\nM30\n"
    compare(src, src.replace(b"X1 Y2", b"X1.01 Y2"), TOL)
    with pytest.raises(AssertionError, match="no matching output motion"):
        compare(src, src.replace(b"G3 X1 Y2", b"G3 X1.03 Y2"), TOL)


def test_replay_reads_a_touch_off_after_homing():
    # $H leaves every axis unknown; G10 L20 makes the named ones read the values
    moves = replay(b"G21 G0 X1 Y2 Z3\n$H\nG0 X4\nG10 L20 P1 X0 Y0\nG0 X5\n").moves
    assert [tuple(m.end[a] for a in "XYZ") for m in moves] == [
        (1, 2, 3), (4, None, None), (5, 0, None)]


def test_the_distance_to_a_steep_helix_is_the_nearest_point_s():
    # a ramp into a cut (Fusion 360's lead-in helix in hazzy_Countour and pocket.ngc): radius 1 mm,
    # 0.1 rad of arc, 1 mm of Z. A point moved 0.01 mm in the plane along the circle's tangent (a
    # corrected end point) is, at its own angle, 0.01 rad further on, where the helix stands
    # 0.1 mm higher; its nearest point of the helix is 0.01 / sqrt(1 + 0.1 ** 2) mm away
    from replay import Move, _off_path
    r, sweep, dz = 1.0, 0.1, 1.0
    move = Move(line=0, kind="arc", start={"X": r, "Y": 0.0, "Z": 0.0},
                end={"X": r * math.cos(sweep), "Y": r * math.sin(sweep), "Z": dz},
                plane=17, centre=(0.0, 0.0), sweep=sweep)
    at = 0.5 * sweep
    on = np.array([r * math.cos(at), r * math.sin(at), 0.5 * dz])
    moved = on + 0.01 * np.array([-math.sin(at), math.cos(at), 0.0])
    # by brute force: the nearest of 200001 points of the helix (5 nm apart)
    ts = np.linspace(0.0, 1.0, 200001)
    helix = np.stack([r * np.cos(ts * sweep), r * np.sin(ts * sweep), ts * dz], axis=1)
    brute = np.min(np.linalg.norm(helix - moved, axis=1))
    assert brute == pytest.approx(0.01 / math.sqrt(1 + 0.1 ** 2), abs=1e-5)
    assert _off_path(dict(zip("XYZ", moved)), move) == pytest.approx(brute, abs=1e-8)
    # across the helix in the plane (radially), the distance at the point's angle was exact
    across = on + 0.01 * np.array([math.cos(at), math.sin(at), 0.0])
    assert _off_path(dict(zip("XYZ", across)), move) == pytest.approx(0.01, abs=1e-9)

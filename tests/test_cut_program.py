"""The program that cut a CMM part is read at the G-code level and handed to the measurement model as
its cutting moves (mtcomp.toolpaths.cutter.read_cut_program -> mtcomp.measurement.cut.CutProgram):
the moves checked against a program read by hand, the moves going into the cmm model as they are, and
a program with nothing to cut refused on the command line."""
from __future__ import annotations

import numpy as np
import pytest

from mtcomp import load_machine
from mtcomp.cli import main
from mtcomp.errors import InputError
from mtcomp.measurement.cut import CutProgram
from mtcomp.sim import cmm_plan
from mtcomp.toolpaths.cutter import read_cut_program

# G0 to (10, 0, 5), plunge to Z0 at F500, cut to X20 at F800, then leave with G0
PROGRAM = "G21 G90\nG0 X10 Y0 Z5\nG1 Z0 F500\nG1 X20 F800\nG0 Z5\nM30\n"


def test_the_cutting_moves_are_the_g1_blocks_read_by_hand(tmp_path):
    path = tmp_path / "cut.nc"
    path.write_text(PROGRAM)
    cut = read_cut_program(path, load_machine("xfyz"))        # axes X, Y, Z
    assert isinstance(cut, CutProgram) and str(cut) == cut.path == str(path)
    np.testing.assert_array_equal(cut.line, [3, 4])           # the G0 lines 2 and 5 are left out
    np.testing.assert_allclose(cut.start, [[10, 0, 5], [10, 0, 0]], rtol=0, atol=1e-12)
    np.testing.assert_allclose(cut.end, [[10, 0, 0], [20, 0, 0]], rtol=0, atol=1e-12)
    np.testing.assert_allclose(cut.feed, [500, 800], rtol=0, atol=0)
    # the G0 moves every axis from a position the program has not given: directions not known
    # (0); then Z down, then X up; Y never moves from a known position (0)
    np.testing.assert_array_equal(cut.dirs, [[0, 0, -1], [1, 0, -1]])


@pytest.mark.parametrize("text, problem", [("G21 G90\nM30\n", "no motion"),
                                           ("G21 G90\nG0 X10\nG0 Z5\nM30\n", "only G0")])
def test_a_program_with_nothing_to_cut_is_refused_naming_it(tmp_path, text, problem):
    path = tmp_path / "empty.nc"
    path.write_text(text)
    with pytest.raises(InputError, match=problem) as err:
        read_cut_program(path, load_machine("xfyz"))
    assert err.value.path == str(path)


def test_the_simulated_cmm_plan_hands_the_read_moves_to_the_cmm_model(tmp_path):
    path = tmp_path / "cut.nc"
    path.write_text(PROGRAM)
    cut = read_cut_program(path, load_machine("xfyz"))
    plan = cmm_plan([[15.0, 3.0, 3.0]], [[0.0, 1.0, 0.0]], cut, 3.0, sample_mm=0.5)
    assert plan.options["cut"] is cut and plan.options["tool_radius_mm"] == 3.0
    assert plan.options["sample_mm"] == 0.5
    with pytest.raises(TypeError, match="read_cut_program"):     # the simulator reads no G-code
        cmm_plan([[15.0, 3.0, 3.0]], [[0.0, 1.0, 0.0]], path, 3.0)


def test_a_cmm_program_with_only_rapids_fails_the_command_writing_nothing(tmp_path, capsys):
    program = tmp_path / "rapids.nc"
    program.write_text("G21 G90\nG0 X10 Y0 Z5\nG0 Z0\nM30\n")
    part = tmp_path / "part.csv"
    part.write_text("x_mm,y_mm,z_mm,nx,ny,nz,dn_um,kind\n10,0,0,0,0,1,1.5,cmm\n12,0,0,0,0,1,1.0,cmm\n")
    out = tmp_path / "model.json"
    rc = main(["identify", "xfyz", str(part), "-o", str(out), "--cmm-program", str(program),
               "--cmm-tool-radius", "3"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and not out.exists()
    assert len(err) == 1 and str(program) in err[0] and "only G0" in err[0], err


def test_a_cut_program_s_own_work_offset_places_its_moves(tmp_path):
    """G10 L2 P1 sets G54 from its line on, as compensate reads it: the moves are the program's plus
    (100, 0, 0), and the part's datum is there (before: refused). By hand."""
    p = tmp_path / "p.nc"
    p.write_text("G21 G90\nG10 L2 P1 X100 Y0 Z0\nG0 X1 Y2 Z3\nG1 X20 F500\nM30\n")
    m = load_machine("xfyz")
    cut = read_cut_program(p, m)
    np.testing.assert_array_equal(cut.start, [[101.0, 2.0, 3.0]])
    np.testing.assert_array_equal(cut.end, [[120.0, 2.0, 3.0]])
    np.testing.assert_array_equal(cut.datum, [100.0, 0.0, 0.0])
    np.testing.assert_array_equal(cut.part_origin(m), [100.0, 0.0, 0.0])


@pytest.mark.parametrize("text, line, words", [
    ("G21 G90\nG0 X1 Y2 Z3\nG1 X20 W-2 F500\nM30\n", None, "U, V or W"),
])
def test_a_cut_program_the_ball_centres_cannot_follow_is_refused(tmp_path, text, line, words):
    p = tmp_path / "p.nc"
    p.write_text(text)
    with pytest.raises(InputError) as exc:
        read_cut_program(p, load_machine("xfyz"))
    assert words in exc.value.message and exc.value.line == line


# a part cut in tool centre point mode (M428 on the table-table machine CAFXYZ): X Y Z are the tip on
# the part, the surface point; the move at line 5 tilts A by 10 deg and turns C by 20 deg while the
# tip goes straight
TCP_PROGRAM = ("G21 G90\nM428\nG0 X40 Y0 Z60 A-30 C0\nG1 Z20 F400\nG1 X30 Y10 A-20 C20\n"
               "G1 X20\nM429\nM30\n")


def test_a_tcp_cut_program_is_read_at_the_axes_that_put_the_tip_on_its_words(tmp_path):
    """The independent truth machine's nominal tip at the moves' axes is the program's tip: at every
    move's end its words, and at every piece's ends on the straight line between the words (the
    controller moves the tip straight); X approaches line 6's end from the side its axis comes."""
    from test_toolpaths_tcp import _truth_axes
    from truth.machine import TruthMachine
    path = tmp_path / "tcp.ngc"
    path.write_text(TCP_PROGRAM)
    cut = read_cut_program(path, load_machine("cafxyz"))
    truth = TruthMachine.zero("cafxyz")
    words = {4: (40, 0, 60, -30, 0, 40, 0, 20), 5: (40, 0, 20, -30, 0, 30, 10, 20),
             6: (30, 10, 20, -20, 20, 20, 10, 20)}        # line: start X Y Z A C, end X Y Z
    assert sorted(set(cut.line.tolist())) == [4, 5, 6]
    ends = {k: cut.end[np.flatnonzero(cut.line == k)[-1]] for k in words}
    aim = {k: np.array(w[5:]) for k, w in words.items()}
    for k in words:
        tip = truth.nominal_pose(ends[k][None])[0][0]
        np.testing.assert_allclose(tip, aim[k], rtol=0, atol=1e-9)
    for k, w in words.items():
        rows = np.flatnonzero(cut.line == k)
        tips = truth.nominal_pose(np.vstack([cut.start[rows], cut.end[rows]]))[0]
        a, b = np.array(w[:3]), aim[k]
        u = (tips - a) @ (b - a) / ((b - a) @ (b - a))
        off = np.linalg.norm(a + u[:, None] * (b - a) - tips, axis=1)
        assert off.max() <= 1e-9 and u.min() >= -1e-9 and u.max() <= 1 + 1e-9
    # line 6's approach direction of X: the sign of axis X's move by the truth's own inverse
    # kinematics of its words (the tip's X goes back; the turned table's axis X need not)
    q = _truth_axes(truth, [dict(zip("XYZAC", (30, 10, 20, -20, 20))),
                            dict(zip("XYZAC", (20, 10, 20, -20, 20)))])
    assert cut.dirs[np.flatnonzero(cut.line == 6)[-1], 0] == np.sign(q[1, 0] - q[0, 0]) != 0


def test_a_tcp_cutting_move_with_an_axis_not_given_is_refused(tmp_path):
    path = tmp_path / "tcp.ngc"
    path.write_text("G21 G90\nM428\nG0 X40 Y0 Z60\nG1 Z20 F400\nM429\nM30\n")
    with pytest.raises(InputError, match="tool centre point mode with an axis") as exc:
        read_cut_program(path, load_machine("cafxyz"))
    assert exc.value.line == 4

"""A tool centre point program is compensated with the approach directions of the machine's axes,
not of the tip words: where a rotary axis turns the part, a tip moving one way is an axis moving
the other, and a backlash's correction belongs to the axis's side.

Checked on the independent virtual machine (tests/truth, which shares no code with mtcomp): the
compensated program is read back as a controller reads it (tests/replay.py), turned into axes by
the truth's own kinematics, and 'cut' on the truth with each axis's approach direction taken from
those axes' motion."""
from __future__ import annotations

import numpy as np

from mtcomp.cli import main
from mtcomp.models import Backlash, save_model
from replay import replay
from test_export_formats import random_model
from test_toolpaths_tcp import _truth_axes
from truth.effects import Backlash as TruthBacklash
from truth.machine import Context, TruthMachine

BL_UM = 30.0

# CAFXYZ: the part sits on the C table (on an A trunnion), X Y Z carry the spindle; in TCP mode
# (M428) X Y Z are the tip in the part's frame. The tip first moves +X at C0 (axis X +1); then the
# table turns half a turn under the standing tip (G1 C180: the tip word X stays 10, axis X goes
# from +10 to -10: -1); from then on the part's +X points along the machine's -X, so the tip's
# +X moves (X20, X30, X40) are axis X moving -X, and the Y move between them leaves axis X where
# it is (its direction stays -1). The tip words' X never reverses: its direction stays +1.
PROGRAM = """G21 G90 G94 G17
M428
G0 X-10 Y0 Z10 A0 C0
G1 X0 F500
G1 X10
G1 C180
G1 X20
G1 Y5
G1 X30
G1 X40
M429
M30
"""


def _x_directions(x: np.ndarray, eps: float = 1e-9) -> np.ndarray:
    """The truth's rule: the sign of each move of axis X (mm), carried where it moves at most
    ``eps`` (mm), 0 before its first move."""
    d, out = 0.0, []
    for step in np.diff(x, prepend=x[0]):
        if abs(step) > eps:
            d = float(np.sign(step))
        out.append(d)
    return np.array(out)


def _tip_errors_um(truth: TruthMachine, aim: np.ndarray, moves: list) -> np.ndarray:
    """(n,) um, the truth's tip at the axes of ``moves`` (its own kinematics; each axis X approached
    from the side its motion came from) less the nominal tip ``aim`` (n, 3)."""
    q = _truth_axes(truth, [m.end for m in moves])
    tip = truth.true_pose(q, context=Context(dirs={"X": _x_directions(q[:, 0])}))[0]
    return 1e3 * np.linalg.norm(tip - aim, axis=1)


def test_a_backlash_is_corrected_on_the_side_the_axis_comes_from(tmp_path):
    """A backlash of X of 30 um, the compensating model's and the truth's: uncorrected every block
    whose X has moved is 15 um off; corrected with the tip words' directions the blocks after the
    half turn get the correction of the wrong side (30 um off); with the axes' they are on."""
    fm = random_model("cafxyz", (Backlash("X"),), 3, 0.0, None)
    fm.params.set_file_value("BL_X", BL_UM)
    model, prog, out = tmp_path / "model.json", tmp_path / "ring.ngc", tmp_path / "out.ngc"
    save_model(model, fm)
    prog.write_text(PROGRAM)
    assert main(["compensate", "cafxyz", str(model), str(prog), "-o", str(out), "--quiet"]) == 0
    truth = TruthMachine.zero("cafxyz").with_effects(TruthBacklash("X", BL_UM))
    src = [m for m in replay(prog.read_bytes()).moves]
    dst = [m for m in replay(out.read_bytes()).moves]
    assert len(dst) == len(src) == 8
    aim = truth.nominal_pose(_truth_axes(truth, [m.end for m in src]))[0]
    x_axis = _truth_axes(truth, [m.end for m in src])[:, 0]
    # the geometry the docstring describes: the tip words' X never goes back, the axis's does
    np.testing.assert_allclose(x_axis, [-10, 0, 10, -10, -20, -20, -30, -40], rtol=0, atol=1e-9)
    before = _tip_errors_um(truth, aim, src)
    after = _tip_errors_um(truth, aim, dst)
    rms = lambda e: float(np.sqrt(np.mean(e[1:] ** 2)))     # noqa: E731 (the feed moves)
    print(f"tip error on the truth: rms {rms(before):.3f} -> {rms(after):.3f} um")
    np.testing.assert_allclose(before[1:], BL_UM / 2, rtol=1e-6, atol=0)
    assert rms(after) <= rms(before) / 3


def test_render_maps_the_program_with_the_axes_directions(tmp_path):
    """render's map of a TCP program evaluates each block with the approach directions of the axes
    the controller reaches, as compensate plans it: X's are those of the truth's axes (the tip
    words' X never reverses)."""
    from mtcomp.machine import load_machine
    from mtcomp.viz.program import read_program_points
    prog = tmp_path / "ring.ngc"
    prog.write_text(PROGRAM)
    points = read_program_points(prog, load_machine("cafxyz"))
    truth = TruthMachine.zero("cafxyz")
    x_axis = _truth_axes(truth, [m.end for m in replay(prog.read_bytes()).moves])[:, 0]
    np.testing.assert_array_equal(points.dirs[:, 0], _x_directions(x_axis))


def test_the_directions_carry_from_chunk_to_chunk(tmp_path):
    """The program read in chunks of 5 rows (the half turn in the first, the Y move that leaves axis
    X where it stands opening the second): each chunk's X directions, placed on the machine, are
    the truth axes'."""
    from mtcomp.machine import load_machine
    from mtcomp.toolpaths import iter_segment_chunks
    from mtcomp.toolpaths.offsets import ProgramSetup
    from mtcomp.toolpaths.source import open_program
    prog = tmp_path / "ring.ngc"
    prog.write_text(PROGRAM)
    machine = load_machine("cafxyz")
    setup = ProgramSetup(machine)
    with open_program(prog, None) as src:
        dirs = [setup.apply(c, src)[0].dirs[:, 0] for c in iter_segment_chunks(src, machine,
                                                                               chunk_size=5)]
    assert [len(d) for d in dirs] == [5, 3]
    x_axis = _truth_axes(TruthMachine.zero("cafxyz"),
                         [m.end for m in replay(prog.read_bytes()).moves])[:, 0]
    np.testing.assert_array_equal(np.concatenate(dirs), _x_directions(x_axis))


# The first feed move after a TCP rapid from an unknown position: the plunge at A-30 moves axes Y
# and Z, not X, so X's direction is not known there (the rapid came from where the program has not
# said). The machine's X-Y squareness makes X's error change along the plunge (axis Y moves 20 mm),
# so a correction that followed it would move axis X and give it a direction of its own: the backlash
# the model evaluated at 'not known' would then be half of it off. The reversal rule holds X's
# correction there, as it does in any program.
PLUNGE = """G21 G90 G94 G17
M428
G0 X40 Y0 Z60 A-30 C0
G1 Z20 F400
G1 X39.848 Y3.486 C5
G1 X39.392 Y6.946 C10
M429
M30
"""
C0Y_URAD = 200.0


def test_a_plunge_after_a_tcp_rapid_keeps_x_where_its_direction_is_not_known(tmp_path):
    """The truth and the model: a 30 um X backlash and a 200 urad X-Y squareness (C0Y). Cut on the
    truth, the plunge's tip is within the squareness's own X error along the plunge (4 um) of its
    aim: X's correction held, the axis does not move, its direction stays not known (the mean the
    model took). Without the rule the correction moved axis X and the backlash took half its
    play (15 um) on top."""
    from mtcomp.models import ErrorModel, FittedModel
    from mtcomp.models.params import ParameterSet
    from mtcomp.machine import load_machine
    model = ErrorModel(load_machine("cafxyz").with_basis("polynomial"), (Backlash("X"),))
    ps = ParameterSet(model.param_specs)
    ps.set_file_value("BL_X", BL_UM)
    ps.set_file_value("C0Y", C0Y_URAD)
    path, prog, out = tmp_path / "model.json", tmp_path / "plunge.ngc", tmp_path / "out.ngc"
    save_model(path, FittedModel(model, ps, support=None))
    prog.write_text(PLUNGE)
    assert main(["compensate", "cafxyz", str(path), str(prog), "-o", str(out), "--quiet"]) == 0
    truth = TruthMachine.zero("cafxyz").with_effects(TruthBacklash("X", BL_UM))
    truth.squareness["C0Y"] = C0Y_URAD * 1e-6
    src, dst = replay(prog.read_bytes()).moves, replay(out.read_bytes()).moves
    assert len(dst) == len(src) == 4
    q_src = _truth_axes(truth, [m.end for m in src])
    q_out = _truth_axes(truth, [m.end for m in dst])
    # the geometry: the plunge moves axis Y by 20 mm (sin 30 deg of 40 mm), not axis X
    np.testing.assert_allclose(q_src[1, :2] - q_src[0, :2], [0.0, -20.0], rtol=0, atol=1e-9)
    aim = truth.nominal_pose(q_src)[0]
    # a move of axis X of at most 0.1 um (the program's resolution) keeps its direction: the rounded
    # tip words put the axis within nm of where it stood
    dirs = _x_directions(q_out[:, 0], 1e-4)
    tip = truth.true_pose(q_out, context=Context(dirs={"X": dirs}))[0]
    err = 1e3 * np.linalg.norm(tip - aim, axis=1)
    print(f"plunge after the rapid: X direction {dirs[1]:+.0f}, tip error {err[1]:.3f} um")
    assert dirs[1] == 0
    assert err[1] <= 1e-3 * C0Y_URAD * 20.0 + 0.2

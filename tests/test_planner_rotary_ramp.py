"""A 5-axis program on a CA table whose C axis line is off by X0C: a Z-only plunge before a turn of C
that needs more Y correction than one step of the bound allows. C stands in the plunge (no C word
there: a standing rotary axis keeps its correction, docs/planner.md), so the plunge is written as it
was and the turns of C, which move C, carry the correction with their own turn; the turn is written
in whole steps of 1e-4 deg, and the linear corrections are re-solved for the rounded turn, so no
block ends worse than uncorrected. The oracle is the C axis offset by hand:

with the table turned by C about an axis through o = (X0C, 0, 0) instead of the origin, a workpiece
point w sits at o + R(C) (w - o) in the machine frame, so the point under the tool tip p is
w = R(-C) p + (I - R(-C)) o, and the deviation (actual minus nominal, workpiece frame) of a block
commanded at p, C when the program meant p0, C0 is R(-C) p + (I - R(-C)) o - R(-C0) p0: at p = p0,
C = C0 it is X0C (1 - cos C, sin C, 0) whatever p.
"""
import csv
import json
import re

import numpy as np
import pytest

from mtcomp.cli import main
from mtcomp.models import save_model
from test_export_formats import random_model

X0C_UM = 15.0
#: the plunge at X300: a step of C (1e-4 deg, 1.745 urad) moves its tip 0.52 um along Y
PROGRAM = """(CA table, machine coordinates, no TCP)
G21 G90 G17 G54
G0 Z150
G0 A0 C0
G0 X300 Y0
G1 Z50 F500
G1 C30 X259.8076 Y150
G1 C60 X150 Y259.8076
G1 C90 X0 Y300
G0 Z150
M30
"""
PLUNGE = 6


def _model(tmp_path):
    fm = random_model("cafxyz", (), 3, 0.0, None)        # every error 0 ...
    fm.params.set_file_value("X0C", X0C_UM)               # ... but the C axis line's offset in X
    p = tmp_path / "m.json"
    save_model(p, fm)
    return p


def _compensate(tmp_path, *extra):
    prog = tmp_path / "p.nc"
    prog.write_text(PROGRAM)
    out, rep, js = tmp_path / "o.nc", tmp_path / "B.csv", tmp_path / "S.json"
    # endpoint-accurate (no internal nodes): one block per line, the C moves' errors as they are
    assert main(["compensate", "cafxyz", str(_model(tmp_path)), str(prog), "-o", str(out),
                 "--report", str(rep), "--json", str(js), "--subdivide-tol-um", "0", *extra]) == 0
    with open(rep, newline="") as f:
        rows = list(csv.DictReader(f))
    return out.read_text().splitlines(), rows, json.loads(js.read_text())


def _positions(lines):
    """{line number: (x, y, z mm, a, c deg)} of each motion line, axis words carried modally."""
    pos = dict.fromkeys("XYZAC", np.nan)
    out = {}
    for k, text in enumerate(lines, start=1):
        words = dict(re.findall(r"([XYZAC])(-?\d+\.?\d*)", text.split("(")[0]))
        if re.match(r"G[01]\b", text) and words:
            pos.update({a: float(v) for a, v in words.items()})
            out[k] = tuple(pos[a] for a in "XYZAC")
    return out


def _deviation_um(written, meant):
    """Tip deviation (um, workpiece frame) of a block commanded at ``written`` that the program meant
    at ``meant`` (x, y, z, a, c in mm and deg; A = 0), from the offset axis by hand (module doc)."""
    def table_to_work(c_deg, v):
        c = np.radians(c_deg)
        return np.array([np.cos(c) * v[0] + np.sin(c) * v[1], -np.sin(c) * v[0] + np.cos(c) * v[1],
                         v[2]])
    o = np.array([X0C_UM * 1e-3, 0.0, 0.0])
    p, p0 = np.array(written[:3]), np.array(meant[:3])
    actual = table_to_work(written[4], p) + o - table_to_work(written[4], o)
    return (actual - table_to_work(meant[4], p0)) * 1e3


def _evaluated(rows):
    return {int(r["line"]): r for r in rows if r["unknown_axes"] == ""}


def test_the_offset_axis_model_gives_the_hand_derived_deviation(tmp_path):
    """The before columns are X0C (1 - cos C, sin C, 0); the after columns are the hand replay of the
    written program (the oracle of everything below)."""
    lines, rows, _ = _compensate(tmp_path)
    meant, written = _positions(PROGRAM.splitlines()), _positions(lines)
    ev = _evaluated(rows)
    assert sorted(ev) == [5, 6, 7, 8, 9, 10]
    for k, r in ev.items():
        c = np.radians(meant[k][4])
        np.testing.assert_allclose([float(r[f"e{a}_before_um"]) for a in "xyz"],
                                   [X0C_UM * (1 - np.cos(c)), X0C_UM * np.sin(c), 0.0],
                                   rtol=0, atol=2e-3)
        np.testing.assert_allclose([float(r[f"e{a}_after_um"]) for a in "xyz"],
                                   _deviation_um(written[k], meant[k]), rtol=0, atol=0.01)


def test_the_plunge_gets_no_turn_and_the_turns_carry_the_ramp(tmp_path, capsys):
    """Y must go from the plunge's 0 to -7.5 um at C30 (X0C sin 30 deg): more than one 5 um step.
    C stands in the plunge: it is written as it was (before the standing rule it got a Y ramp and a
    turn of C holding its tip, a C word on a line that has none). The turns of C carry the
    correction (Y on its step bound, the turn holding the rest of the tip); no block ends worse
    than uncorrected (by the hand replay), and the summary counts the blocks where C stood."""
    lines, rows, summary = _compensate(tmp_path, "--max-step-um", "5")
    said = capsys.readouterr().out
    meant, written = _positions(PROGRAM.splitlines()), _positions(lines)
    plunge = _evaluated(rows)[PLUNGE]
    assert lines[PLUNGE - 1] == "G1 Z50 F500"
    assert float(plunge["cc_urad"]) == 0.0 and float(plunge["cy_um"]) == 0.0
    turn = _evaluated(rows)[PLUNGE + 1]
    assert float(turn["cc_urad"]) != 0.0 and "step_y" in turn["active_bounds"].split(";")
    for k in _evaluated(rows):
        before = np.abs(_deviation_um(meant[k], meant[k]))
        after = np.abs(_deviation_um(written[k], meant[k]))
        assert np.all(after <= before + 0.1), (k, before, after)
    # the turn takes what the 5 um step leaves of the 7.5 um (C's grid: 0.52 um per step at X300)
    assert np.max(np.abs(_deviation_um(written[PLUNGE + 1], meant[PLUNGE + 1]))) <= 0.3
    assert summary["worse_than_uncorrected"]["blocks"] == 0
    # A stands in every block after its G0 A0 C0 (lines 5 to 10), C in lines 5, 6 and 10
    assert summary["standing_rotary"]["blocks"] == 6 and summary["standing_rotary"]["line"] == 5
    assert "worse than uncorrected" not in said


def test_without_a_binding_step_bound_the_plunge_gets_no_word(tmp_path, capsys):
    """The same program with a step bound that does not bind: the plunge, whose own error is 0, is
    written as it was, and no block is said to carry a ramp."""
    lines, rows, summary = _compensate(tmp_path, "--max-step-um", "40")
    assert lines[PLUNGE - 1] == "G1 Z50 F500"
    assert summary["ramped_blocks"]["blocks"] == 0 and summary["bounded_blocks"] == 0
    assert "more than their own error" not in capsys.readouterr().out


def test_rounding_a_turn_re_solves_the_linear_corrections_by_hand():
    """One block 300 mm from the C axis: 1 urad of C moves the tip 0.3 um along Y. A correction of
    C = 2.6 urad with Y = -0.78 um (the pair holds the tip) is written as C = 1.745 urad (one step of
    1e-4 deg); Y is re-solved to -0.3 * 1.745 um, the pair still holding the tip."""
    from mtcomp.machine import load_machine
    from mtcomp.planner import CompensationProblem, output_grid
    from mtcomp.planner._bounds import Bounds
    from mtcomp.planner._pointwise import Linearization
    from mtcomp.planner._rotary_grid import rotary_columns, round_rotary
    from test_export_formats import random_model as _random
    machine = load_machine("cafxyz")
    fitted = _random("cafxyz", (), 3, 0.0, None)
    problem = CompensationProblem.from_machine(fitted, grid=output_grid(machine))
    bounds = Bounds(problem)
    # objective rows: tip x, y, z (um) and the tool axis (nothing turns it at tilt 0)
    A = np.zeros((1, 6, 5))
    A[0, 0, 0] = A[0, 1, 1] = A[0, 2, 2] = 1.0
    A[0, 1, 4] = 0.3                                # um of tip along Y per urad of C
    b = np.zeros((1, 6))
    lin = Linearization(np.zeros((1, 5)), np.zeros((1, 5)), b, A, b, b, np.ones(1, int),
                        np.ones(1, bool), np.eye(3)[None])
    x = np.array([[0.0, -0.78, 0.0, 0.0, 2.6]])
    lam = problem.regularization_weights
    y = round_rotary(bounds, lin, x, rotary_columns(machine), lam)
    step = np.radians(1e-4) * 1e6
    assert y[0, 4] == pytest.approx(step, rel=1e-12)
    np.testing.assert_allclose(y[0, :4], [0.0, -0.3 * step, 0.0, 0.0], rtol=0, atol=1e-5)
    # the tip as the pair left it: 0
    assert abs(y[0, 1] + 0.3 * y[0, 4]) < 1e-5


def test_a_turn_under_half_a_grid_step_leaves_the_block_as_it_was(tmp_path, capsys):
    """A spindle tilted 0.8 urad about X (A0S) and no other error, tool length 0: the tip is where it
    should be everywhere, the tool axis 0.8 urad off. Turning A by -0.8 urad would remove that, with a
    Y move holding the tip (the A axis's lever); but 0.8 urad is under half a step of the written
    A (1e-4 deg = 1.745 urad): A is written as it was, so Y must be too, and the program comes out
    byte for byte. Before, the Y partner (0.3 um at Z 290) was written without its turn: every block
    0.3 um worse than uncorrected."""
    fm = random_model("cafxyz", (), 3, 0.0, None)
    fm.params.set_file_value("A0S", 0.8)
    model = tmp_path / "m.json"
    save_model(model, fm)
    text = "G21 G90 G17 G54\nG0 X100 Y0 Z290 A0 C0\nG1 Z280 F500\nG1 X50\nG0 Z295\nM30\n"
    prog, out, js = tmp_path / "p.nc", tmp_path / "o.nc", tmp_path / "S.json"
    prog.write_text(text)
    assert main(["compensate", "cafxyz", str(model), str(prog), "-o", str(out), "--json", str(js),
                 "--subdivide-tol-um", "0"]) == 0
    assert out.read_text() == text
    summary = json.loads(js.read_text())
    assert summary["max_after_um"] == pytest.approx(0.0, abs=1e-6)
    assert summary["worse_than_uncorrected"]["blocks"] == 0
    assert summary["max_axis_after_urad"] == pytest.approx(0.8, abs=1e-3)   # left, and said
    assert "worse than uncorrected" not in capsys.readouterr().out


def test_the_box_shortcut_is_the_window_qp_with_the_turn_fixed(monkeypatch):
    """Scattered blocks on a CA table at A = C = 0 (no step bound between them; the workpiece axes
    are the machine's, so a correction clipped to its box leaves no tip component worse), corrections
    bounded to 3 um so that the box binds: the window needs OSQP, and its rounded turn is solved
    again. Each block's own best X/Y/Z for the rounded turn, clipped to the box, must be what OSQP
    finds for the whole window with the turn fixed (the second formulation here, forced by refusing
    the shortcut)."""
    from mtcomp.machine import load_machine
    from mtcomp.planner import CompensationProblem, PlannerOptions, output_grid, plan_arrays
    from mtcomp.planner import _rotary_grid
    machine = load_machine("cafxyz")
    fitted = random_model("cafxyz", (), 11, 4.0, None)
    problem = CompensationProblem.from_machine(fitted, max_correction_um=3.0,
                                               grid=output_grid(machine))
    rng = np.random.default_rng(5)
    n = 40
    q = np.column_stack([rng.uniform(-200, 200, n), rng.uniform(-150, 150, n),
                         rng.uniform(-100, 100, n), np.zeros(n), np.zeros(n)])
    rapid = np.ones(n, bool)
    taken = []
    shortcut = _rotary_grid.box_optimum

    def spy(*args):
        y = shortcut(*args)
        taken.append(y is not None)
        return y
    monkeypatch.setattr(_rotary_grid, "box_optimum", spy)
    fast = plan_arrays(problem, q, rapid=rapid, options=PlannerOptions(always_qp=True))
    assert taken == [True] and fast.flags.any()
    monkeypatch.setattr(_rotary_grid, "box_optimum", lambda *args: None)
    slow = plan_arrays(problem, q, rapid=rapid, options=PlannerOptions(always_qp=True))
    grid = np.asarray(output_grid(machine))
    assert np.all(np.abs(fast.correction - slow.correction) <= grid + 1e-12)
    np.testing.assert_allclose(fast.after * 1e3, slow.after * 1e3, rtol=0, atol=0.06)
    np.testing.assert_array_equal(fast.correction[:, 3:], slow.correction[:, 3:])


def test_a_step_the_plan_put_on_its_bound_is_named_after_the_turn_moved_it_off():
    """Grid 0.1 um, S = 5 um. The plan (before its turn was rounded) ramps Y from -1.6 to -6.6 um,
    on the step bound; re-solved for the rounded turn, the pair is written -1.7 and -6.6 (4.9 apart).
    The first block wanted 0 (its own error), the second -5.7: the step bound caused both, and
    step_y names it with the plan; from the written pair alone nothing would be named."""
    from mtcomp.machine import load_machine
    from mtcomp.planner import CompensationProblem, output_grid
    from mtcomp.planner._bounds import Bounds
    fitted = random_model("cafxyz", (), 3, 0.0, None)
    b = Bounds(CompensationProblem.from_machine(fitted, max_step_um=5.0,
                                                grid=output_grid(load_machine("cafxyz"))))
    x, desired, planned = (np.zeros((2, 5)) for _ in range(3))
    x[:, 1] = [-1.7, -6.6]
    desired[:, 1] = [0.0, -5.7]
    planned[:, 1] = [-1.6, -6.6]
    exempt, q = np.array([True, False]), np.zeros((2, 5))
    y, flags = b.enforce(x, q, exempt, None, desired=desired, planned=planned)
    np.testing.assert_allclose(y[:, 1], [-1.7, -6.6], rtol=0, atol=1e-9)
    assert flags[:, 1, 4].tolist() == [True, True] and not flags[:, [0, 2, 3, 4]].any()
    _, alone = b.enforce(x, q, exempt, None, desired=desired)
    assert not alone.any()

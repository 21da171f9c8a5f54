"""A rotary axis the program does not move (3+2 machining, outside tool centre point mode) keeps its
correction: its word is never added or changed there, and the linear axes alone correct the tip.

Oracle: the independent truth machine (tests/truth, no mtcomp code) with the same errors as the
model: the C axis line off by X0C = 15 um and tilted by A0C = 20 urad, on a CB trunnion. With B0 C30
the tip's deviation needs +2 um of X where the program holds X at the end of its travel (the travel
bound holds X): before the rule the planner turned B and C to move the tip in X instead, writing
B and C words on lines that have none (a clamped table in 3+2 machining). And by hand, the bound on
the change of a standing axis's correction (:mod:`mtcomp.planner._links`).
"""
import csv
import json
import re

import numpy as np
import pytest

from mtcomp.cli import main
from mtcomp.models import save_model
from test_export_formats import random_model
from truth import TruthMachine

X0C_UM, A0C_URAD = 15.0, 20.0
#: B and C set once, then only X Y Z; X at its travel's end (400 mm)
PROGRAM = """G21 G90 G17 G54
G0 B0 C30
G0 X400 Y-60
G0 Z50
G1 Z-2 F400
G1 Y60
G1 Y0
G0 Z50
M30
"""
FIRST_HELD = 3          # the lines after B and C were set


def _compensate(tmp_path):
    fm = random_model("cbfxyz", (), 3, 0.0, None)
    fm.params.set_file_value("X0C", X0C_UM)
    fm.params.set_file_value("A0C", A0C_URAD)
    model, prog = tmp_path / "m.json", tmp_path / "p.nc"
    save_model(model, fm)
    prog.write_text(PROGRAM)
    out, rep, js = tmp_path / "o.nc", tmp_path / "B.csv", tmp_path / "S.json"
    assert main(["compensate", "cbfxyz", str(model), str(prog), "-o", str(out), "--report", str(rep),
                 "--json", str(js), "--subdivide-tol-um", "0", "--quiet"]) == 0
    with open(rep, newline="") as f:
        rows = [r for r in csv.DictReader(f) if r["unknown_axes"] == ""]
    return out.read_text().splitlines(), rows, json.loads(js.read_text())


def _positions(lines):
    """{line: (x, y, z mm, b, c rad)} of each motion line, words carried modally."""
    pos = dict.fromkeys("XYZBC", np.nan)
    out = {}
    for k, text in enumerate(lines, start=1):
        words = dict(re.findall(r"([XYZBC])(-?\d+\.?\d*)", text))
        if re.match(r"G[01]\b", text) and words:
            pos.update({a: float(v) for a, v in words.items()})
            out[k] = np.array([pos["X"], pos["Y"], pos["Z"], np.radians(pos["B"]),
                               np.radians(pos["C"])])
    return out


def _truth():
    t = TruthMachine.zero("cbfxyz")
    t.location["X0C"] = X0C_UM * 1e-3
    t.location["A0C"] = A0C_URAD * 1e-6
    return t


def test_a_standing_rotary_axis_gets_no_word_and_the_tip_is_not_made_worse(tmp_path):
    lines, rows, summary = _compensate(tmp_path)
    # no B or C word after the line that set them
    for text in lines[FIRST_HELD - 1:]:
        assert not re.search(r"[BC]-?\d", text), text
    truth = _truth()
    meant, written = _positions(PROGRAM.splitlines()), _positions(lines)
    ks = [int(r["line"]) for r in rows]
    assert ks == [4, 5, 6, 7, 8]
    q0 = np.array([meant[k] for k in ks])
    qw = np.array([written[k] for k in ks])
    tip0, _ = truth.nominal_pose(q0)
    before = (truth.true_pose(q0)[0] - tip0) * 1e3
    after = (truth.true_pose(qw)[0] - tip0) * 1e3
    # the model's before and after columns are the truth's (the same errors, another code)
    for r, b, a in zip(rows, before, after):
        np.testing.assert_allclose([float(r[f"e{c}_before_um"]) for c in "xyz"], b, rtol=0, atol=0.01)
        np.testing.assert_allclose([float(r[f"e{c}_after_um"]) for c in "xyz"], a, rtol=0, atol=0.02)
        assert "travel_x_max" in r["active_bounds"].split(";")
        assert float(r["cx_um"]) == 0.0 and float(r["cc_urad"]) == 0.0
    # X held, Y and Z corrected: every block better than uncorrected on the truth
    assert np.all(np.linalg.norm(after, axis=1) < np.linalg.norm(before, axis=1) - 5.0)
    # the orientation error stays (the truth's tool-axis deviation), and the summary says so
    ax_dev = np.linalg.norm(truth.true_deviation(qw)[1], axis=1) * 1e6
    st = summary["standing_rotary"]
    assert st["blocks"] == 5 and st["line"] == 4
    assert st["max_axis_after_urad"] == pytest.approx(ax_dev.max(), abs=0.01)
    assert ax_dev.max() > 10.0


def test_the_standing_bound_keeps_the_correction_by_hand():
    """Three nodes on a CB trunnion (X Y Z B C), the correction before them 12 urad on C: C moves
    into the first (free), stands in the next two (held at the first's), while X, unbound by the
    rule, takes what it is asked. With C wanting -40, -40, -54 urad the written C is -40 (its box
    allows it), -40, -40; in a pinned node (no correction) C still keeps its -40 (it stands there
    with it), X gets 0."""
    from mtcomp.machine import load_machine
    from mtcomp.planner import CompensationProblem, output_grid
    from mtcomp.planner._bounds import Bounds, STANDING
    from mtcomp.planner._links import node_links
    from mtcomp.planner._nodes import NodeSet
    machine = load_machine("cbfxyz")
    fitted = random_model("cbfxyz", (), 3, 0.0, None)
    problem = CompensationProblem.from_machine(fitted, max_step_um=50.0, max_step_urad=500.0)
    bounds = Bounds(problem)
    dp = np.zeros((3, 5))
    dp[0, 4] = 1e4                                  # C moves into the first node only
    dp[:, 1] = 100.0                                # Y moves in each
    standing = np.zeros((3, 5), bool)
    standing[1:, 3:] = True                         # B and C stand in the last two
    lo, hi, kind = node_links(dp, np.ones((3, 5)), np.zeros(5, bool), np.zeros(3, bool),
                              np.zeros((3, 5), bool), np.full(5, 0.1), standing)
    assert np.all(kind[standing] == STANDING) and np.all(lo[standing] == 0.0)
    assert np.all(hi[standing] == 0.0) and np.all(kind[~standing] == 0)
    q = np.zeros((3, 5))
    q[:, 2] = -50.0
    x = np.zeros((3, 5))
    x[:, 0] = [3.0, 4.0, 5.0]
    x[:, 4] = [-40.0, -40.0, -54.0]
    prev = np.array([0.0, 0.0, 0.0, 0.0, 12.0])
    y, flags = bounds.enforce(x, q, np.zeros(3, bool), prev, links=(lo, hi, kind))
    np.testing.assert_allclose(y[:, 4], [-40.0, -40.0, -40.0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(y[:, 0], [3.0, 4.0, 5.0], rtol=0, atol=1e-12)
    assert flags[2, 4, -1] and not flags[1, 4].any()        # standing_c where it took 14 urad
    # a pinned node: its linear axes get nothing, a standing rotary axis keeps what it stands with
    n = 3
    nodes = NodeSet(q, np.zeros((n, 0)), np.zeros(n, bool), np.arange(n), np.zeros(n, bool),
                    np.zeros(n, bool), np.zeros((n, 5), bool), np.zeros((n, 5), bool),
                    np.array([False, False, True]), np.full(n, np.nan), np.zeros(n, bool),
                    np.zeros(n, bool), lo, hi, kind)
    y, _ = bounds.enforce(x, q, np.zeros(3, bool), prev, links=nodes.links,
                          limits=bounds.limits(q, nodes.box_pins()))
    np.testing.assert_allclose(y[2], [0.0, 0.0, 0.0, 0.0, -40.0], rtol=0, atol=1e-12)


def test_a_zero_rotary_bound_corrects_no_rotary_axis(tmp_path, capsys):
    """--max-correction-urad 0 (refused before as not positive): the C table of
    test_planner_rotary_ramp, whose turns of C take a turn of their own otherwise, is written with
    every C word as it was; X and Y correct the tip (the hand replay of the offset C axis: no block
    worse, the turns better), and only the zero bound is named for A or C, on one side. A negative
    bound is refused."""
    from test_planner_rotary_ramp import PROGRAM as CA_PROGRAM, _compensate as ca_compensate
    from test_planner_rotary_ramp import _deviation_um, _evaluated, _positions as ca_positions
    lines, rows, summary = ca_compensate(tmp_path, "--max-correction-urad", "0")
    meant = CA_PROGRAM.splitlines()
    assert [re.findall(r"[AC]-?[\d.]+", t) for t in lines] == \
        [re.findall(r"[AC]-?[\d.]+", t) for t in meant]
    assert all(float(r["cc_urad"] or 0) == 0.0 and float(r["ca_urad"] or 0) == 0.0 for r in rows)
    # the zero bound alone is named for A and C, on the side the turn was wanted (not both)
    for r in rows:
        named = [b for b in r["active_bounds"].split(";") if b[:2] in ("ca", "cc") or
                 b[-1:] in ("a", "c")]
        assert set(named) <= {"ca_max", "ca_min", "cc_max", "cc_min"}, named
        assert len({b[:2] for b in named}) == len(named), named
    m, w = ca_positions(meant), ca_positions(lines)
    for k in _evaluated(rows):
        before, after = np.abs(_deviation_um(m[k], m[k])), np.abs(_deviation_um(w[k], m[k]))
        assert np.all(after <= before + 0.1), (k, before, after)
    assert np.linalg.norm(_deviation_um(w[10], m[10])) < 1.0 < np.linalg.norm(
        _deviation_um(m[10], m[10]))
    capsys.readouterr()
    with pytest.raises(SystemExit) as e:
        main(["compensate", "--help"])
    assert e.value.code == 0
    assert "0: the rotary axes are never corrected" in " ".join(capsys.readouterr().out.split())
    prog = tmp_path / "p.nc"
    out = tmp_path / "neg.nc"
    assert main(["compensate", "cafxyz", str(tmp_path / "m.json"), str(prog), "-o", str(out),
                 "--max-correction-urad", "-1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--max-correction-urad must be 0 or a positive number" in err[0]
    assert not out.exists()

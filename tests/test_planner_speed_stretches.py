"""A bounded window solved on the stretches where its bounds act gives the whole window's QP: the
plan against OSQP on every whole window (the second formulation), the stretches and the bound
violations that choose them by hand, and the fall-back where a stretch's edge is held by a step."""
import numpy as np
import pytest

from mtcomp.models import Backlash
from mtcomp.planner import CompensationProblem, PlannerOptions, output_grid, plan_arrays
from mtcomp.planner import _local_qp, engine
from mtcomp.planner._bounds import INF
from test_export_formats import random_model


def _reversals(n=4000, period=800, backlash_um=30.0):
    """X back and forth over 100 mm (a reversal every period / 2 blocks) under a 30 um backlash and
    a positioning error linear in X: each reversal jumps the wanted correction by more than the
    5 um step bound, everywhere else the unbounded correction keeps every bound."""
    fm = random_model("xfyz", (Backlash("X"),), 3, 0.0, None)     # every geometric error 0
    fm.params.set_file_value("BL_X", backlash_um)
    fm.params.set_file_value("EXX_1", -40.0)
    k = np.arange(n)
    phase = (k % period) / (period / 2)
    x = 100.0 + 100.0 * np.where(phase < 1, phase, 2 - phase)
    q = np.column_stack([x, np.full(n, 20.0), np.full(n, -30.0)])
    dirs = np.ones((n, 3))
    dirs[:, 0] = np.where(phase < 1, 1.0, -1.0)
    problem = CompensationProblem.from_machine(fm, max_correction_um=50.0, max_step_um=5.0,
                                               grid=output_grid(fm.machine))
    return problem, q, dirs


def _plan(monkeypatch, problem, q, dirs, stretches_on=True):
    """(plan, outcomes of solve_stretches (True: taken), the windows' QP corrections)."""
    outcomes, planned = [], []
    real = _local_qp.solve_stretches

    def spy(*args):
        got = real(*args) if stretches_on else None
        outcomes.append(got is not None)
        return got

    real_window = engine.Planner._solve_window

    def window(self, *args):
        x, plan = real_window(self, *args)
        if plan is not None:
            planned.append(plan.copy())
        return x, plan

    monkeypatch.setattr(engine, "solve_stretches", spy)
    monkeypatch.setattr(engine.Planner, "_solve_window", window)
    opts = PlannerOptions(window=1024, overlap=64, subdivide_tol_um=None, threads=1)
    res = plan_arrays(problem, q, np.full(q.shape[0], 1000.0), dirs, options=opts)
    monkeypatch.undo()
    return res, outcomes, planned


@pytest.mark.parametrize("margins", [_local_qp.MARGINS, (1,)])
def test_stretches_give_the_whole_windows_plan(monkeypatch, margins):
    """With the default margins every bounded window is solved on its stretches; with a margin of 1
    node a 30 um jump cannot be ramped in at 5 um a block within the stretch, and every window falls
    back to the whole window: the plan is the same either way."""
    problem, q, dirs = _reversals()
    monkeypatch.setattr(_local_qp, "MARGINS", margins)
    fast, taken, fast_x = _plan(monkeypatch, problem, q, dirs)
    slow, off, slow_x = _plan(monkeypatch, problem, q, dirs, stretches_on=False)
    assert len(taken) == len(off) >= 4 and not any(off)
    if margins == (1,):
        assert not any(taken)                 # every window fell back to the whole window
    else:
        assert all(taken)
    # the ramps acted: the step bound is named, no written step exceeds it
    assert fast.flags[..., 4].sum() > 10
    assert np.max(np.abs(np.diff(fast.correction[:, 0]))) * 1e3 <= 5.0 + 1e-6
    for f in ("corrected", "flags", "iterations"):
        np.testing.assert_array_equal(getattr(fast, f), getattr(slow, f))
    np.testing.assert_allclose(fast.after, slow.after, rtol=0, atol=1e-12)
    assert len(fast_x) == len(slow_x)
    for a, b in zip(fast_x, slow_x):            # um, before rounding: OSQP's polished optimum
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-6)


def test_a_stretch_whose_edge_step_is_held_is_refused():
    """A 30 um jump under a 5 um step bound, the blocks after it weighing 100 times more than those
    before (no never-worse rows): the whole window ramps up over the cheap blocks before the jump,
    further back than a margin of 2 nodes reaches. The stretch of margin 2 has a solution, with its
    first step held at the bound by the fixed neighbour: solve_stretches must refuse it (None), not
    write a plan that is not the window's. Margin 8 gives the whole window's optimum (OSQP on all
    40 nodes, the oracle)."""
    n = 40
    x_free = np.where(np.arange(n) < 20, 0.0, 30.0)[:, None]     # a 30 um jump at node 20
    weight = np.where(np.arange(n) < 20, 1.0, 10.0)[:, None, None]
    box = (np.full((n + 1, 1), -50.0), np.full((n + 1, 1), 50.0))
    box[0][0], box[1][0] = 0.0, 0.0                              # the anchor at zero
    steps = (np.full((n, 1), -5.0), np.full((n, 1), 5.0))
    lam = np.array([1e-6])
    get_qp = _qp_factory()

    def relinearise(idx, xi):                    # the residual w (x - x_free) is linear
        return weight[idx, :, 0] * (xi - x_free[idx]), weight[idx]

    got = {}
    for margin in (2, 8):
        keep, _local_qp.MARGINS = _local_qp.MARGINS, (margin,)
        try:
            got[margin] = _local_qp.solve_stretches(_linearization(x_free, weight), box, steps,
                                                    np.zeros(n, bool), lam, 0.01, 5, get_qp,
                                                    relinearise)
        finally:
            _local_qp.MARGINS = keep
    assert got[2] is None
    x, solves = got[8]
    assert solves == 2                           # re-linearised once, then nothing moved
    H = np.concatenate([np.eye(1)[None], weight ** 2 + lam[0]])
    g = np.vstack([np.zeros((1, 1)), -(weight[:, :, 0] ** 2) * x_free])
    whole, status = get_qp(n + 1, 1).solve(H, g, box[0], box[1], *steps, np.zeros((n + 1, 1)))
    assert status == "solved"
    np.testing.assert_allclose(x, whole[1:], rtol=0, atol=1e-6)
    # by hand: the ramp of 5 um steps lies before the jump and starts more than 2 nodes before it
    d = np.diff(np.vstack([[0.0], x])[:, 0])
    assert np.all(np.abs(d) <= 5.0 + 1e-6)
    assert np.sum(d > 5.0 - 1e-6) >= 5 and x[16, 0] > 1.0
    np.testing.assert_allclose(x[:10, 0], 0.0, rtol=0, atol=1e-4)
    assert abs(x[20, 0] - 30.0) < 1.0
    np.testing.assert_allclose(x[21:, 0], 30.0, rtol=0, atol=1e-3)


def _linearization(x_free, weight):
    """A window whose residual is w (x - x_free) per node (one row, one axis), at x = 0."""
    from mtcomp.planner._pointwise import Linearization
    n = x_free.shape[0]
    b = -weight[:, :, 0] * x_free
    return Linearization(x_free.copy(), np.zeros((n, 1)), b, weight.copy(), b.copy(),
                         np.zeros((n, 1)), np.ones(n, int), np.ones(n, bool), np.zeros((n, 0, 0)))


def _qp_factory():
    from mtcomp.planner._qp import WindowQP
    made = {}

    def get(N, rows):
        if (N, rows) not in made:
            made[(N, rows)] = WindowQP(N, 1, rows)
        return made[(N, rows)]
    return get


def test_stretches_cover_the_bad_nodes_with_their_margin_by_hand():
    bad = np.zeros(100, bool)
    bad[[3, 10, 60, 61, 97]] = True
    # 3 and 10 are 7 apart: their stretches with margin 2 (1..5, 8..12) would share fixed
    # neighbours 6 and 7 only if 2 * 2 + 2 >= 7 - 1: kept apart; 97's reaches the end
    assert _local_qp.stretches(bad, 2) == [(1, 5), (8, 12), (58, 63), (95, 99)]
    assert _local_qp.stretches(bad, 3) == [(0, 13), (57, 64), (94, 99)]
    assert _local_qp.stretches(np.zeros(5, bool), 3) == []


def test_violations_name_both_nodes_of_a_step_and_the_never_worse_rows_by_hand():
    n, na = 6, 2
    x = np.zeros((n, na))
    lower, upper = np.full((n + 1, na), -1.0), np.full((n + 1, na), 1.0)
    lower[0], upper[0] = 0.0, 0.0                    # the anchor
    step_lo, step_hi = np.full((n, na), -0.5), np.full((n, na), 0.5)
    J = np.ones((n, 1, na))
    worse = (J, np.full((n, 1), -INF), np.full((n, 1), INF))
    assert not _local_qp.violations(x, lower, upper, step_lo, step_hi, worse).any()
    x[2, 1] = 0.6                                    # steps 1->2 and 2->3 over 0.5
    x[5, 0] = 1.2                                    # over the box, and the step 4->5
    assert _local_qp.violations(x, lower, upper, step_lo, step_hi, worse).tolist() == \
        [False, True, True, True, True, True]
    x[:] = 0.0
    x[0, 0] = 0.7                                    # the step from the anchor (at 0) into node 0
    assert _local_qp.violations(x, lower, upper, step_lo, step_hi, worse).tolist() == \
        [True, True] + [False] * 4
    x[:] = 0.0
    step_lo[:], step_hi[:] = -INF, INF
    worse = (J, np.full((n, 1), -0.1), np.full((n, 1), 0.1))
    x[4] = [0.3, -0.1]                               # J x = 0.2 > 0.1 at node 4
    assert _local_qp.violations(x, lower, upper, step_lo, step_hi, worse).tolist() == \
        [False] * 4 + [True, False]

"""Planner core: nominal Jacobian, the seed-001 step, agreement of qp / newton / IPOPT / cvxpy, bounds,
windows, 5-axis orientation, internal nodes. Oracles: finite differences of the kinematics and of
the model's actual tip, numpy lstsq, the IPOPT solution of the nonlinear problem, hand-derived
clamping, dense evaluation along the corrected path."""
import math

import numpy as np
import pytest

from mtcomp import load_machine
from mtcomp.kinematics import forward
from mtcomp.models import Backlash, ErrorModel, FeedOffset, FittedModel, PeriodicError, deviation
from mtcomp.planner import (CompensationProblem, PlannerOptions, nominal_pose_jacobian, output_grid,
                            plan_arrays, plan_chunks, plan_with_cvxpy)
from mtcomp.planner._bounds import Bounds
from mtcomp.toolpaths.gcode import SegmentChunk
from oracles.planner_reference import solve_reference

UNIT_SCALE = {"um": 10e-3, "urad": 20e-6, "mm": 50.0, "1": 0.05}
LOOSE = dict(max_correction_um=1000.0, max_correction_urad=1e5, max_step_um=1000.0)


def fitted_model(name, seed, terms=(), basis="bspline"):
    """A synthetic model of machine-tool size: ~10 um and ~20 urad per parameter (on the polynomial
    basis; a spline has many more parameters, whose random values add up to larger errors)."""
    machine = load_machine(name).with_basis(basis)
    model = ErrorModel(machine, terms)
    fitted = FittedModel.zero(model)
    rng = np.random.default_rng(seed)
    fitted.params.values[:] = rng.normal(size=model.n_params) * np.array(
        [UNIT_SCALE[s.unit] for s in model.param_specs])
    return fitted


def random_blocks(machine, rng, n):
    """Poses inside half the travel; tilt axis kept away from its singular zero."""
    lo, hi = machine.travel_bounds()
    q = rng.uniform(0.5 * lo, 0.5 * hi, (n, machine.n_axes))
    for j, ax in enumerate(machine.axes):
        if ax.is_rotary and ax.name in "AB":
            q[:, j] = np.radians(rng.uniform(15.0, 60.0, n)) * rng.choice([-1, 1], n)
    feed = rng.uniform(100.0, 5000.0, n)
    dirs = rng.choice([-1, 1], (n, machine.n_axes))
    return q, feed, dirs


def smooth_blocks(machine, rng, n):
    """Blocks along a smooth path between two random poses: the errors vary smoothly."""
    q0, feed, dirs = random_blocks(machine, rng, 2)
    t = np.linspace(0.0, 1.0, n)[:, None]
    q = q0[0] + t * (q0[1] - q0[0])
    return q, np.full(n, feed[0]), np.repeat(dirs[:1], n, axis=0)


def actual_pose(fitted, q, feed, dirs):
    """Independent evaluation: nominal kinematics plus the model's deviation, (n, 6)."""
    m = fitted.machine
    cols = {"feed": feed}
    cols.update({f"dir_{a}": dirs[:, j].astype(float) for j, a in enumerate(m.axis_names)})
    c = fitted.context(q.shape[0], cols)
    tip, axis = forward(m, q)
    return np.concatenate([tip, axis], axis=1) + deviation(fitted.model, q, fitted.params.values, c)


def nominal_pose(machine, q):
    tip, axis = forward(machine, q)
    return np.concatenate([tip, axis], axis=1)


@pytest.mark.parametrize("name", ["xfyz", "cafxyz", "cbfxyz"])
def test_nominal_jacobian_matches_finite_differences(name):
    m = load_machine(name).with_basis("polynomial")
    rng = np.random.default_rng(5)
    lo, hi = m.travel_bounds()
    q = rng.uniform(lo, hi, (7, m.n_axes))
    tip, axis, J = nominal_pose_jacobian(m, q)
    t0, a0 = forward(m, q)
    np.testing.assert_allclose(tip, t0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(axis, a0, rtol=0, atol=1e-15)
    Jf = np.zeros_like(J)
    for j in range(m.n_axes):
        h = np.zeros(m.n_axes)
        h[j] = 1e-6
        Jf[:, :, j] = (nominal_pose(m, q + h) - nominal_pose(m, q - h)) / 2e-6
    np.testing.assert_allclose(J, Jf, rtol=0, atol=2e-7)


@pytest.mark.parametrize("name", ["xfyz", "cafxyz"])
def test_pinv_is_one_seed001_step_against_finite_differences_and_lstsq(name):
    fitted = fitted_model(name, 11)
    m = fitted.machine
    rng = np.random.default_rng(12)
    q, feed, dirs = random_blocks(m, rng, 12)
    # next to nothing of the regularisation, which lstsq does not have
    problem = CompensationProblem.from_machine(fitted, regularization=1e-12,
                                               rotary_regularization=1e-12, **LOOSE)
    res = plan_arrays(problem, q, feed, dirs, options=PlannerOptions(method="pinv"))
    rows = 6 if m.is_five_axis else 3
    W = np.array([1e3] * 3 + [1e6] * 3)[:rows]         # um and urad, orientation weight 1
    e = (actual_pose(fitted, q, feed, dirs) - nominal_pose(m, q))[:, :rows]
    expected = np.zeros_like(q)
    for i in range(q.shape[0]):
        J = np.zeros((rows, m.n_axes))
        for j in range(m.n_axes):
            h = np.zeros(m.n_axes)
            h[j] = 1e-6
            qi = np.array([q[i] + h, q[i] - h])
            p = actual_pose(fitted, qi, np.repeat(feed[i], 2), np.repeat(dirs[i:i + 1], 2, axis=0))
            J[:, j] = (p[0, :rows] - p[1, :rows]) / 2e-6
        expected[i] = -np.linalg.lstsq(W[:, None] * J, W * e[i], rcond=None)[0]
    scale = problem.axis_scale
    # the planner counts the tool axis in the directions the rotary axes turn it (tilt 15 deg or
    # more here): the same step as counting all of it, since five axes remove the whole deviation
    np.testing.assert_allclose(res.correction * scale, expected * scale, rtol=0, atol=2e-3)
    # before: the deviation of the uncorrected block
    np.testing.assert_allclose(res.before, e[:, :3], rtol=0, atol=1e-12)


def test_pinv_agrees_with_the_dcm_step_to_first_order():
    """models.dcm.pinv_correction (the seed's differential-change Jacobian, first-order errors)."""
    from oracles.dcm import pinv_correction
    fitted = fitted_model("xfyz", 21)
    m = fitted.machine
    q, _, _ = random_blocks(m, np.random.default_rng(22), 20)
    res = plan_arrays(CompensationProblem.from_machine(fitted, **LOOSE), q,
                      options=PlannerOptions(method="pinv"))
    dq = pinv_correction(fitted.model, fitted.params.values, q, errors="exact")
    # eq. 30: command q - dq; the two differ by J_q (1e-4) times the correction (10 um)
    np.testing.assert_allclose(res.correction * 1e3, -dq * 1e3, rtol=0, atol=0.02)
    assert np.abs(res.correction).max() * 1e3 > 5.0


@pytest.mark.parametrize("name", ["xfyz", "cafxyz"])
def test_unbounded_qp_newton_ipopt_agree_and_remove_the_error(name):
    terms = [Backlash("X"), FeedOffset("Y", signed=True)]
    fitted = fitted_model(name, 31, terms)
    m = fitted.machine
    q, feed, dirs = random_blocks(m, np.random.default_rng(32), 25)
    problem = CompensationProblem.from_machine(fitted, **LOOSE)
    ref = solve_reference(problem, q, feed, dirs)
    scale = problem.axis_scale
    for method in ("newton", "qp"):
        res = plan_arrays(problem, q, feed, dirs, options=PlannerOptions(method=method, always_qp=True))
        np.testing.assert_allclose(res.correction * scale, ref * scale, rtol=0, atol=0.01)
        assert not res.flags.any()
        # independent check of the result: actual pose at the corrected position vs nominal
        err = actual_pose(fitted, res.corrected, feed, dirs) - nominal_pose(m, q)
        assert np.abs(err[:, :3]).max() * 1e3 < 0.01
        if m.is_five_axis:
            assert np.abs(err[:, 3:]).max() * 1e6 < 0.01
            assert np.abs(res.before_axis).max() * 1e6 > 10.0     # there was an orientation error
        assert np.abs(res.before).max() * 1e3 > 5.0
        np.testing.assert_allclose(res.after, err[:, :3], rtol=0, atol=1e-8)


@pytest.mark.parametrize("name", ["xfyz", "cafxyz"])
def test_bounded_qp_matches_ipopt_and_cvxpy_and_keeps_bounds(name):
    fitted = fitted_model(name, 41, basis="polynomial")
    m = fitted.machine
    rng = np.random.default_rng(42)
    n = 30
    q, feed, dirs = smooth_blocks(m, rng, n)
    rapid = np.zeros(n, bool)
    rapid[10] = True
    shift = np.array([150.0 if a.name == "X" else 0.2 if a.is_rotary else 0.0 for a in m.axes])
    q[10:] += shift                     # a long rapid into block 10
    before = plan_arrays(CompensationProblem.from_machine(fitted, **LOOSE), q, feed, dirs, rapid)
    need = np.abs(before.correction * CompensationProblem.from_machine(fitted).axis_scale)
    B_lin = float(np.median(need[:, :3].max(axis=1)))       # about half the blocks need more
    problem = CompensationProblem.from_machine(fitted, max_correction_um=B_lin, max_step_um=0.5,
                                               max_correction_urad=30.0)
    scale = problem.axis_scale
    res = plan_arrays(problem, q, feed, dirs, rapid, options=PlannerOptions(always_qp=True))
    ref = solve_reference(problem, q, feed, dirs, rapid)
    cvx = plan_with_cvxpy(problem, q, feed, dirs, rapid)
    np.testing.assert_allclose(res.correction * scale, ref * scale, rtol=0, atol=0.01)
    np.testing.assert_allclose(res.correction * scale, cvx * scale, rtol=0, atol=1e-3)
    c = res.correction * scale
    B = np.where([a.is_rotary for a in m.axes], 30.0, B_lin)
    S = np.where([a.is_rotary for a in m.axes], 30.0 * 0.5 / B_lin, 0.5)
    assert np.all(np.abs(c) <= B + 1e-6)
    steps = np.abs(np.diff(c, axis=0))
    steps[9] = 0.0                       # the move into block 10 is a rapid: exempt
    assert np.all(steps <= S + 1e-6)
    assert np.abs(np.diff(c, axis=0))[9].max() > S.min()   # and the exemption is used
    assert res.flags.any()
    hit = res.flags.any(axis=(1, 2))
    # where no bound acted the block is fully corrected; where one acted an error remains
    if np.any(~hit):
        assert np.abs(res.after[~hit]).max() * 1e3 < 0.05
    assert np.linalg.norm(res.after[hit], axis=1).max() * 1e3 > 0.1


def test_enforce_clamps_by_hand():
    """B = 8, S = 3, wanted [0, 10, 10, 0, -10]: box first, then the step bound, forward."""
    fitted = fitted_model("xfyz", 1)
    problem = CompensationProblem.from_machine(fitted, max_correction_um=8.0, max_step_um=3.0)
    b = Bounds(problem)
    x = np.zeros((5, 3))
    x[:, 0] = [0.0, 10.0, 10.0, 0.0, -10.0]
    y, flags = b.enforce(x, np.zeros((5, 3)), np.zeros(5, bool), None)
    np.testing.assert_allclose(y[:, 0], [0.0, 3.0, 6.0, 3.0, 0.0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(y[:, 1:], 0.0, rtol=0, atol=0)
    # step_x acted on blocks 1..4; cx_max never binds (3 and 6 < 8)
    assert flags[:, 0, 4].tolist() == [False, True, True, True, True]
    assert not flags[:, 0, :2].any()
    # exempt block 4 (a rapid): it takes the box-clipped value -8 at once
    y2, flags2 = b.enforce(x, np.zeros((5, 3)), np.array([0, 0, 0, 0, 1], bool), None)
    np.testing.assert_allclose(y2[:, 0], [0.0, 3.0, 6.0, 3.0, -8.0], rtol=0, atol=1e-12)
    assert flags2[4, 0, 1] and not flags2[4, 0, 4]


def test_grid_makes_bounds_exact_after_rounding():
    fitted = fitted_model("cafxyz", 51)
    m = fitted.machine
    rng = np.random.default_rng(52)
    q, feed, dirs = random_blocks(m, rng, 60)
    grid = output_grid(m)
    problem = CompensationProblem.from_machine(fitted, max_correction_um=5.0, max_step_um=1.0,
                                               max_correction_urad=40.0, grid=grid)
    for method in ("qp", "newton", "pinv"):
        res = plan_arrays(problem, q, feed, dirs, options=PlannerOptions(method=method, window=16,
                                                                         overlap=4))
        k = res.correction / grid                   # whole grid steps
        np.testing.assert_allclose(k, np.round(k), rtol=0, atol=1e-6)
        np.testing.assert_allclose(res.nominal / grid, np.round(res.nominal / grid), rtol=0, atol=1e-6)
        c = res.correction * problem.axis_scale
        B = np.array([5.0] * 3 + [40.0] * 2)
        S = np.array([1.0] * 3 + [8.0] * 2)
        assert np.all(np.abs(c) <= B + 1e-6)
        assert np.all(np.abs(np.diff(c, axis=0)) <= S + 1e-6)
        assert res.flags.any()


def test_windows_keep_the_step_bound_across_window_joins_and_agree_when_inactive():
    fitted = fitted_model("xfyz", 61)
    m = fitted.machine
    n = 300
    t = np.linspace(0.0, 1.0, n)
    q = np.stack([-300 + 600 * t, 200 * np.sin(6 * t), -50 + 20 * t], axis=1)
    bounded = CompensationProblem.from_machine(fitted, max_correction_um=4.0, max_step_um=0.2)
    win = plan_arrays(bounded, q, options=PlannerOptions(window=32, overlap=8, always_qp=True))
    c = win.correction * 1e3
    assert np.all(np.abs(np.diff(c, axis=0)) <= 0.2 + 1e-6)
    assert np.all(np.abs(c) <= 4.0 + 1e-6)
    assert win.flags.any()
    whole = plan_arrays(bounded, q, options=PlannerOptions(window=4096, always_qp=True))
    # windowing costs little against the whole-program optimum
    assert np.linalg.norm(win.after, axis=1).max() <= np.linalg.norm(whole.after, axis=1).max() + 0.5e-3
    loose = CompensationProblem.from_machine(fitted, **LOOSE)
    a = plan_arrays(loose, q, options=PlannerOptions(window=32, overlap=8, always_qp=True))
    b = plan_arrays(loose, q, options=PlannerOptions(method="newton"))
    np.testing.assert_allclose(a.correction * 1e3, b.correction * 1e3, rtol=0, atol=1e-3)


def _segment_chunk(machine, points, feed=1000.0):
    """One feed segment per row from consecutive points (first row starts at points[0])."""
    n = points.shape[0] - 1
    step = np.diff(points, axis=0)
    dirs = np.where(step >= 0, 1, -1).astype(np.int8)
    return SegmentChunk(np.arange(1, n + 1), points[:-1].copy(), points[1:].copy(), np.full(n, feed),
                        dirs, np.zeros(n, bool), np.zeros(n, bool))


def test_internal_nodes_where_the_error_varies_along_a_long_move():
    """A 40 mm periodic error of 3 um on X: a 41 mm move needs internal nodes; checked by evaluating
    the model densely along the corrected polyline (what the control interpolates)."""
    fitted = fitted_model("xfyz", 71, [PeriodicError("X", 40.0)])
    fitted.params["PER_X_c"] = 3e-3
    fitted.params["PER_X_s"] = 1e-3
    m = fitted.machine
    pts = np.array([[-20.0, 10.0, -30.0], [21.3, 10.0, -30.0]])
    chunk = _segment_chunk(m, pts)
    problem = CompensationProblem.from_machine(fitted, **LOOSE)

    def worst_along(tol):
        out = list(plan_chunks(problem, [chunk], PlannerOptions(subdivide_tol_um=tol,
                                                               max_subdivision_depth=8)))
        (_, res), = out
        # the corrected start: the start point corrected on its own (as the previous block would be)
        start = plan_arrays(problem, pts[:1], np.array([1000.0]), np.array([[1, 1, 1]])).corrected
        nodes_c = np.vstack([start, res.corrected])
        nodes_n = np.vstack([pts[:1], res.nominal])
        s = np.linspace(0.0, 1.0, 41)[1:]
        qc = np.concatenate([a + s[:, None] * (b - a) for a, b in zip(nodes_c[:-1], nodes_c[1:])])
        qn = np.concatenate([a + s[:, None] * (b - a) for a, b in zip(nodes_n[:-1], nodes_n[1:])])
        k = qc.shape[0]
        err = actual_pose(fitted, qc, np.full(k, 1000.0), np.ones((k, 3), int)) - nominal_pose(m, qn)
        return len(res), int(res.counts[0]), np.linalg.norm(err[:, :3], axis=1).max() * 1e3

    n_plain, _, worst_plain = worst_along(None)
    n_sub, count, worst_sub = worst_along(0.2)
    assert n_plain == 1 and worst_plain > 2.0
    assert n_sub == count > 8
    assert worst_sub < 0.3


def test_cvxpy_user_constraints_no_z_and_nothing_on_the_first_blocks():
    fitted = fitted_model("xfyz", 81, basis="polynomial")
    n = 40
    q = np.column_stack([np.linspace(-100, 100, n), np.linspace(-50, 50, n), np.full(n, -20.0)])
    problem = CompensationProblem.from_machine(fitted, max_correction_um=30.0, max_step_um=1.0)
    free = plan_with_cvxpy(problem, q)
    dq = plan_with_cvxpy(problem, q, extra_constraints=lambda x: [x[:, 2] == 0, x[:10, :] == 0])
    np.testing.assert_allclose(dq[:, 2], 0.0, rtol=0, atol=1e-9)
    np.testing.assert_allclose(dq[:10], 0.0, rtol=0, atol=1e-9)
    # after block 10 X and Y ramp up by at most the step bound, then follow the free solution
    steps = np.abs(np.diff(dq[:, :2], axis=0)) * 1e3
    assert np.all(steps <= 1.0 + 1e-6)
    np.testing.assert_allclose(dq[-5:, :2], free[-5:, :2], rtol=0, atol=2e-6)
    # Z is left uncorrected: its error stays (the actual Z at the blocks equals the model's EZ error)
    err = actual_pose(fitted, q + dq, np.full(n, np.nan), np.zeros((n, 3))) - nominal_pose(fitted.machine, q)
    base = actual_pose(fitted, q, np.full(n, np.nan), np.zeros((n, 3))) - nominal_pose(fitted.machine, q)
    np.testing.assert_allclose(err[-5:, 2], base[-5:, 2], rtol=0, atol=1e-4 * 1e-3 + 1e-7)
    assert np.abs(base[:, 2]).max() > 1e-3


def test_streaming_in_small_chunks_gives_the_same_plan():
    """Chunk boundaries must not matter: windows run over the stream of output blocks."""
    fitted = fitted_model("xfyz", 91)
    m = fitted.machine
    n = 200
    t = np.linspace(0.0, 1.0, n + 1)
    pts = np.stack([-200 + 400 * t, 150 * np.sin(5 * t), -40 + 30 * t], axis=1)
    whole = _segment_chunk(m, pts)
    problem = CompensationProblem.from_machine(fitted, max_correction_um=5.0, max_step_um=0.3,
                                               grid=output_grid(m))
    opts = PlannerOptions(window=16, overlap=4, subdivide_tol_um=None)
    (_, ref), = list(plan_chunks(problem, [whole], opts))
    parts = [SegmentChunk(*(getattr(whole, f)[a:a + 37] for f in
                            ("line", "start", "end", "feed", "dirs", "rapid", "from_arc")))
             for a in range(0, n, 37)]
    out = list(plan_chunks(problem, parts, opts))
    assert [len(c) for c, _ in out] == [len(p) for p in parts]
    assert all(len(r) == len(c) and np.all(r.counts == 1) for c, r in out)
    got = np.vstack([r.corrected for _, r in out])
    np.testing.assert_allclose(got, ref.corrected, rtol=0, atol=1e-12)
    assert ref.flags.any()
    c = ref.correction * 1e3
    assert np.all(np.abs(np.diff(c, axis=0)) <= 0.3 + 1e-6) and np.all(np.abs(c) <= 5.0 + 1e-6)


def test_tilt_zero_turns_no_table_after_a_tool_axis_error_no_rotary_axis_removes():
    """CA table at A = 0: the tool axis is parallel to C, so no rotary axis can remove the X
    component of a tool-axis deviation (only a B axis could). The planner must not turn C after it
    through the model's tiny C-dependence of the tool axis, with X/Y paying up to their bounds: C
    stays within a few urad, no bound acts, and the tip ends as close as with X/Y/Z alone (the same
    problem with zero rotary bounds). At A = 30 deg the tool axis is still corrected."""
    fitted = fitted_model("cafxyz", 91)
    m = fitted.machine
    ia, ic = m.index("A"), m.index("C")
    gx, gy = np.meshgrid(np.linspace(-300.0, 300.0, 5), np.linspace(-200.0, 200.0, 3))
    n = gx.size
    q = np.column_stack([gx.ravel(), gy.ravel(), np.full(n, -50.0), np.zeros(n), np.zeros(n)])
    rapid = np.ones(n, bool)             # scattered blocks: no step bound between them
    problem = CompensationProblem.from_machine(fitted)          # 50 um, 500 urad
    rotary = np.array([a.is_rotary for a in m.axes])
    xyz_only = CompensationProblem(fitted, np.where(rotary, 0.0, problem.max_correction),
                                   problem.max_step)
    best = np.linalg.norm(plan_arrays(xyz_only, q, rapid=rapid).after, axis=1).max() * 1e3
    qp = None
    for method in ("qp", "newton", "pinv"):
        res = plan_arrays(problem, q, rapid=rapid,
                          options=PlannerOptions(method=method, always_qp=True))
        c = res.correction * problem.axis_scale
        assert np.abs(c[:, ic]).max() < 3.0                       # urad
        assert not res.flags.any()
        assert np.linalg.norm(res.after, axis=1).max() * 1e3 < best + 0.02
        qp = c if qp is None else qp
    # an error there was, and it stays: no rotary axis reaches it
    assert np.abs(res.before_axis[:, 0]).max() * 1e6 > 20.0
    np.testing.assert_allclose(res.after_axis[:, 0], res.before_axis[:, 0], rtol=0, atol=0.5e-6)
    ref = solve_reference(problem, q, rapid=rapid)
    np.testing.assert_allclose(qp, ref * problem.axis_scale, rtol=0, atol=0.01)
    # tilted 30 deg the rotary axes turn the tool well: its deviation is corrected
    q30 = q.copy()
    q30[:, ia] = np.radians(30.0)
    res = plan_arrays(problem, q30, rapid=rapid)
    assert np.abs(res.before_axis).max() * 1e6 > 20.0
    assert np.abs(res.after_axis).max() * 1e6 < 0.05
    assert np.abs(res.correction[:, ic]).max() * 1e6 > 20.0


def test_tilt_zero_move_is_not_split_after_a_tool_axis_error_no_rotary_axis_removes():
    """The midpoint test of internal nodes counts the tool axis as the objective does: at A = 0 a
    deviation in X that no correction removes is missed at every midpoint and must not split the
    move into 2^6 pieces; the tip along the corrected move still stays within the tolerance."""
    fitted = fitted_model("cafxyz", 91)
    m = fitted.machine
    pts = np.array([[-300.0, 100.0, -50.0, 0.0, 0.0], [300.0, 100.0, -50.0, 0.0, 0.0]])
    chunk = _segment_chunk(m, pts)
    problem = CompensationProblem.from_machine(fitted, **LOOSE)
    (_, res), = plan_chunks(problem, [chunk], PlannerOptions(subdivide_tol_um=0.5))
    assert np.abs(res.after_axis[:, 0]).max() * 1e6 > 5.0      # the deviation no axis removes
    # 64 pieces when the whole tool-axis deviation was counted; here 22 (17 for the tip alone, the
    # rest for the tool axis's Y component, which A corrects)
    assert int(res.counts[0]) < 32
    # dense check of the tip along the corrected polyline (as in the test above)
    start = plan_arrays(problem, pts[:1], np.array([1000.0]), np.ones((1, 5), int)).corrected
    nodes_c, nodes_n = np.vstack([start, res.corrected]), np.vstack([pts[:1], res.nominal])
    s = np.linspace(0.0, 1.0, 21)[1:]
    qc = np.concatenate([a + s[:, None] * (b - a) for a, b in zip(nodes_c[:-1], nodes_c[1:])])
    qn = np.concatenate([a + s[:, None] * (b - a) for a, b in zip(nodes_n[:-1], nodes_n[1:])])
    k = qc.shape[0]
    err = actual_pose(fitted, qc, np.full(k, 1000.0), np.ones((k, 5), int)) - nominal_pose(m, qn)
    assert np.linalg.norm(err[:, :3], axis=1).max() * 1e3 < 0.6

"""The planner's column-loop reductions and its bound checks on broadcast limits give numpy's
numbers: the row maximum against ``np.max(axis=1)``, the first broken bound on one row broadcast
against the same bounds made whole, the summary's 'made worse' figures against a replay in numpy."""
import numpy as np
import pytest

from mtcomp.planner import CompensationProblem, PlannerOptions, output_grid, plan_arrays
from mtcomp.planner._bounds import Bounds
from mtcomp.planner._small import down_columns, row_max
from mtcomp.planner.report import WORSE_TOL_UM, Summary

from test_planner_core import fitted_model


@pytest.mark.parametrize("op", [np.add, np.subtract, np.multiply, np.divide, np.maximum, np.minimum,
                                np.greater, np.less])
def test_down_columns_is_numpys_broadcast_bit_for_bit(op):
    """A row broadcast over the rows ((3,), (1, 3), a read-only broadcast), a column slice of a
    wider array and two whole arrays, into a new array or in place: numpy's own numbers and dtype,
    C-ordered."""
    rng = np.random.default_rng(3)
    a = rng.normal(size=(1000, 3)) * 10.0 ** rng.integers(-6, 6, size=(1000, 3))
    wide = rng.normal(size=(1000, 6))
    v = rng.normal(size=3)
    same, zeros = np.full(3, 1e3), np.array([0.0, -0.0, 0.0])      # a row of one number, or not
    cases = [(a, v), (v, a), (a, v[None, :]), (a, np.broadcast_to(v, a.shape)), (wide[:, :3], a),
             (a, wide[:, 3:]), (a, a[::-1].copy()), (a[:0], v), (a, same), (same[None, :], a),
             (wide[:, :3], same), (-np.abs(a) * 0.0, zeros), (zeros, -np.abs(a) * 0.0)]
    for x, y in cases:
        with np.errstate(invalid="ignore", divide="ignore"):      # 0 / 0 among the zeros
            got, want = down_columns(op, x, y), op(x, y)
        assert got.dtype == want.dtype and got.flags.c_contiguous
        np.testing.assert_array_equal(got, want)
        assert np.array_equal(np.signbit(got), np.signbit(want))        # -0.0 stays -0.0
    if op not in (np.greater, np.less):
        inplace = a.copy()
        assert down_columns(op, inplace, v, out=inplace) is inplace
        np.testing.assert_array_equal(inplace, op(a, v))


@pytest.mark.parametrize("cols", [1, 3, 6])
def test_row_max_is_numpys_including_nan_rows(cols):
    a = np.random.default_rng(cols).normal(size=(200, cols))
    a[7, cols - 1] = np.nan
    a[11, 0] = np.nan
    np.testing.assert_array_equal(row_max(a), np.max(a, axis=1))


def test_first_violation_on_broadcast_limits_is_that_of_whole_limits():
    fitted = fitted_model("xfyz", 5)
    problem = CompensationProblem.from_machine(fitted, max_correction_um=10.0, max_step_um=2.0,
                                               grid=output_grid(fitted.machine))
    b = Bounds(problem)
    rng = np.random.default_rng(8)
    n = 500
    exempt = np.zeros(n, bool)
    lo, hi = np.broadcast_to(-b.B, (n, 3)), np.broadcast_to(b.B, (n, 3))
    for k in (None, 0, 17, 499):
        # a smooth correction inside the bounds with steps below the step bound, one entry pushed
        # just past the box at block k
        x = np.cumsum(rng.uniform(-0.05, 0.05, size=(n, 3)), axis=0)
        if k is not None:
            x[k, k % 3] = (b.B[k % 3] + 1e-6) * (-1) ** k
        want = b.first_violation(x, np.array(lo), np.array(hi), exempt, None)
        assert want == k
        assert b.first_violation(x, lo, hi, exempt, None) == want


def test_summary_counts_blocks_made_worse_as_a_replay():
    fitted = fitted_model("xfyz", 3)
    # a correction bound of 2 um against deviations of several um: bounded blocks everywhere
    problem = CompensationProblem.from_machine(fitted, max_correction_um=2.0, max_step_um=0.5,
                                               grid=output_grid(fitted.machine))
    rng = np.random.default_rng(4)
    q = np.column_stack([rng.uniform(-200, 200, 300), rng.uniform(-100, 100, 300),
                         rng.uniform(-50, 0, 300)])
    res = plan_arrays(problem, q, options=PlannerOptions(method="pinv", threads=1))
    s = Summary(tuple(fitted.machine.axis_names))
    s.add(res)
    grown = np.max(np.abs(res.after) - np.abs(res.before), axis=1) * 1e3
    worse = grown > WORSE_TOL_UM
    assert s.worse_blocks == int(worse.sum())
    assert s.worse_max_um == (float(grown.max()) if worse.any() else 0.0)
    eb = np.sqrt(np.sum(res.before ** 2, axis=1)) * 1e3
    np.testing.assert_allclose(s.corrected_max_before_um, eb[~res.pinned].max(), rtol=0, atol=0)
    assert s.corrected_blocks == int((~res.pinned).sum())
    assert s.not_converged == int((~res.converged).sum())


@pytest.mark.parametrize("datums", [1, 2])
def test_datum_reference_is_the_deviation_at_each_blocks_datum(datums):
    # one datum: one row broadcast over the blocks; two: a row per block. Oracle: the model's
    # deviation at the datum evaluated block by block
    from mtcomp.planner._evaluate import Evaluator
    fitted = fitted_model("xfyz", 11)
    ev = Evaluator(CompensationProblem.from_machine(fitted, max_correction_um=50.0))
    n = 40
    datum = np.zeros((n, 3))
    datum[:] = [120.0, -35.0, -60.0]
    if datums == 2:
        datum[25:] = [-80.0, 40.0, -10.0]
    ctx = fitted.context(n)
    ref = ev.datum_reference(datum, ctx)
    assert ref.shape == (n, 3)
    names = fitted.model.context_names
    tool = ctx[:, names.index("tool_length")] if "tool_length" in names else np.zeros(n)
    want = np.concatenate([fitted.datum_deviation(datum[i:i + 1], tool[i:i + 1]) for i in range(n)])
    np.testing.assert_allclose(ref, want, rtol=0, atol=1e-15)
    assert np.ptp(want[:, 0]) > 0 if datums == 2 else np.ptp(want[:, 0]) == 0

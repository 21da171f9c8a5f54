"""The Newton iteration of a chunk gives every block what it gives the block alone: blocks that
converge at once (no deviation left to correct) and blocks that need their Jacobian again (a large
nonlinear error) beside the rest, whether the chunk goes on computing every block or only those
still iterating. The oracle is the same iteration run on each block by itself (a chunk of one)."""
import numpy as np
import pytest

from mtcomp.planner import CompensationProblem
from mtcomp.planner import _pointwise
from mtcomp.planner._evaluate import Evaluator
from mtcomp.planner._pointwise import solve_newton

from test_planner_core import LOOSE, fitted_model

TOL_UM, MAX_IT = 1e-3, 20


def _blocks(seed, n, zero, scale):
    """Evaluator, poses, context and a datum reference that leaves ``zero`` blocks with nothing to
    correct; ``scale`` multiplies the model's parameters (large: a strongly nonlinear model)."""
    fitted = fitted_model("xfyz", seed)
    fitted.params.values[:] *= scale
    ev = Evaluator(CompensationProblem.from_machine(fitted, **LOOSE))
    rng = np.random.default_rng(seed)
    q = np.column_stack([rng.uniform(-300, 300, n), rng.uniform(-150, 150, n),
                         rng.uniform(-80, 0, n)])
    ctx = fitted.context(n)
    b0 = ev.residual_jacobian_rows(q, ctx)[0]
    ref = np.zeros_like(b0)
    ref[zero] = b0[zero] / ev.S            # the deviation there is the reference: none to correct
    return ev, q, ctx, ref


def _alone(ev, q, ctx, ref, lam):
    """solve_newton block by block: the oracle (nothing in it can depend on the other blocks)."""
    return [solve_newton(ev, q[i:i + 1], ctx[i:i + 1], lam, TOL_UM, MAX_IT, ref[i:i + 1])
            for i in range(q.shape[0])]


@pytest.mark.parametrize("n_zero,scale,again", [(1, 1.0, False), (3, 200.0, False), (3, 1000.0, True),
                                                (3, 3000.0, True), (150, 1.0, False),
                                                (150, 3000.0, True)])
def test_newton_of_a_chunk_is_that_of_each_block_alone(monkeypatch, n_zero, scale, again):
    # one backend for the chunk and its blocks alone (no compilation in between)
    monkeypatch.setenv("MTCOMP_COMPILE_MIN_POSES", str(10 ** 12))
    n = 200
    zero = np.random.default_rng(n_zero).choice(n, n_zero, replace=False)
    ev, q, ctx, ref = _blocks(7, n, zero, scale)
    lam = ev.problem.regularization_weights
    modes = []
    for name in ("_whole_iteration", "_compact_iteration", "_relinearise"):
        f = getattr(_pointwise, name)
        monkeypatch.setattr(_pointwise, name,
                            lambda *a, _f=f, _n=name: modes.append(_n) or _f(*a))
    jacobians = []
    evaluate_jacobian = ev.residual_jacobian
    monkeypatch.setattr(ev, "residual_jacobian",
                        lambda *a, **k: jacobians.append(len(a[0])) or evaluate_jacobian(*a, **k))
    lin = solve_newton(ev, q, ctx, lam, TOL_UM, MAX_IT, ref)
    monkeypatch.setattr(ev, "residual_jacobian", evaluate_jacobian)
    chunk_modes = list(modes)   # the chunk's (the blocks alone below add theirs)
    alone = _alone(ev, q, ctx, ref, lam)
    for field in ("iterations", "converged"):
        np.testing.assert_array_equal(getattr(lin, field),
                                      np.concatenate([getattr(a, field) for a in alone]))
    for field in ("x", "x_lin", "b", "A", "b0"):
        np.testing.assert_allclose(getattr(lin, field),
                                   np.concatenate([getattr(a, field) for a in alone]),
                                   rtol=0, atol=1e-12)
    assert set(lin.iterations[zero]) == {1}
    others = np.setdiff1d(np.arange(n), zero)
    assert lin.iterations[others].min() >= 2
    # the cases reach what they are for: a few blocks done at once keep every block computed,
    # many done leave the rest computed alone; the blocks of a nonlinear model converge over
    # several iterations, and the more nonlinear ones need their Jacobian again (the step of
    # some blocks shrinks less than tenfold)
    few_done = n_zero <= n * (1 - _pointwise.WHOLE_SHARE)
    if scale == 1:          # every other block converges at its second iteration
        assert ("_compact_iteration" in chunk_modes) == (not few_done)
    else:                   # they converge over many: the chunk goes over to the active blocks
        assert "_compact_iteration" in chunk_modes
        assert ("_whole_iteration" in chunk_modes[1:]) == few_done
    assert lin.converged.all()
    assert (len(jacobians) > 1) == again

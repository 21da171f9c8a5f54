"""The bounded compensation problem as a cvxpy problem, for constraints of one's own.

:func:`build_cvxpy_problem` returns the QP of one linearisation (the same as one OSQP window, over the
whole program) with its variable, so that a user can add constraints and solve it with any cvxpy
solver; :func:`plan_with_cvxpy` repeats it, re-linearising, until the corrections settle (the SQP of
the qp method). Example (docs/planner.md)::

    cq = build_cvxpy_problem(problem, q, feed, dirs)
    extra = [cq.x[:, 2] == 0,          # no Z correction
             cq.x[:100, :] == 0]       # no correction on the first 100 blocks
    dq = plan_with_cvxpy(problem, q, feed, dirs, extra_constraints=lambda x: [x[:, 2] == 0])

The linearisation enters through cvxpy Parameters (DPP), so re-solving after an update reuses the
compiled problem. Units: ``x`` is in um (linear axes) and urad (rotary axes); the returned corrections
of :func:`plan_with_cvxpy` are in mm and rad.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._evaluate import objective_residual
from ._pointwise import Linearization
from ._qp import NEVER_WORSE_TOL
from .engine import NodeSet, Planner
from .problem import CompensationProblem, PlannerOptions


@dataclass
class CvxpyProblem:
    """problem : cp.Problem. x : cp.Variable (n, n_axes), corrections in um / urad.
    nodes : the blocks (NodeSet). constraints : the bound constraints (a list one can extend).
    A, c : Parameters of the linearised weighted residual r_k = sum_j A[k][j] * x[:, j] + c[k]
        (on 5-axis machines its tool-axis rows as the objective counts them, see docs/planner.md).
    scale : (n_axes,) um or urad per mm or rad."""

    problem: object
    x: object
    nodes: NodeSet
    constraints: list
    A: list
    c: list
    scale: np.ndarray
    objective: object

    def update(self, lin: Linearization):
        """Set the parameters to the linearisation lin of the objective's residual (b + A (x -
        x_lin), its tool-axis rows as the objective counts them: ``Linearization.objective``)."""
        const, A = lin.objective()
        for k in range(len(self.A)):
            self.c[k].value = const[:, k]
            for j in range(len(self.A[k])):
                self.A[k][j].value = A[:, k, j]

    def with_constraints(self, extra: list):
        """A new cp.Problem: this objective, these bounds and the extra constraints."""
        import cvxpy as cp
        return cp.Problem(self.objective, self.constraints + list(extra))


def _setup(problem, q, feed, dirs, rapid):
    planner = Planner(problem, PlannerOptions(method="newton", subdivide_tol_um=None))
    nodes, lin = planner.nodes_from_arrays(q, feed, dirs, rapid)
    return planner, nodes, lin


def build_cvxpy_problem(problem: CompensationProblem, q, feed=None, dirs=None, rapid=None,
                        linearization: Linearization | None = None, _setup_result=None) -> CvxpyProblem:
    """The bounded QP of blocks given as arrays (see :func:`plan_arrays`), linearised at the unbounded
    per-block solution (or at ``linearization``)."""
    import cvxpy as cp
    planner, nodes, lin = _setup_result or _setup(problem, q, feed, dirs, rapid)
    n, na = nodes.q.shape
    rows = planner.ev.rows
    x = cp.Variable((n, na), name="x")
    A = [[cp.Parameter(n, name=f"A_{k}_{j}") for j in range(na)] for k in range(rows)]
    c = [cp.Parameter(n, name=f"c_{k}") for k in range(rows)]
    resid = [sum(cp.multiply(A[k][j], x[:, j]) for j in range(na)) + c[k] for k in range(rows)]
    lam = problem.regularization_weights
    objective = cp.Minimize(0.5 * sum(cp.sum_squares(r) for r in resid)
                            + 0.5 * sum(lam[j] * cp.sum_squares(x[:, j]) for j in range(na)))
    b = planner.bounds
    l, u = b.box(nodes.q)
    cons = [x >= l, x <= u]
    idx = np.array([i for i in range(1, n) if not nodes.exempt[i]], dtype=int)
    if idx.size:
        d = x[idx, :] - x[idx - 1, :]
        Sm = np.broadcast_to(b.S, (idx.size, na))
        cons += [d <= Sm, d >= -Sm]
    cons += _link_constraints(x, nodes)
    # never worse than uncorrected, per row the objective counts (the QP's last rows, :mod:`._qp`)
    lin0 = linearization or lin
    room = np.abs(objective_residual(lin0.orientation_rows, lin0.b0)) + NEVER_WORSE_TOL
    cons += [cp.abs(resid[k]) <= room[:, k] for k in range(rows)]
    cq = CvxpyProblem(cp.Problem(objective, cons), x, nodes, cons, A, c, b.D, objective)
    cq.update(lin0)
    return cq


def _link_constraints(x, nodes) -> list:
    """The link bounds of :mod:`._links` on x_i - x_(i-1) (each axis keeps its direction where the
    model's error depends on it), as the QP has them."""
    if nodes.link_lo is None or x.shape[0] < 2:
        return []
    cons = []
    for bound, sign in ((nodes.link_lo, 1.0), (nodes.link_hi, -1.0)):
        for j in range(x.shape[1]):
            idx = np.flatnonzero(np.abs(bound[1:, j]) < 1e29) + 1
            if idx.size:
                cons.append(sign * (x[idx, j] - x[idx - 1, j]) >= sign * bound[idx, j])
    return cons


def plan_with_cvxpy(problem: CompensationProblem, q, feed=None, dirs=None, rapid=None,
                    extra_constraints=None, solver: str | None = None, step_tol_um: float = 0.01,
                    max_iterations: int = 20, **solve_kwargs) -> np.ndarray:
    """(n, n_axes) corrections (mm, rad): the qp method's SQP solved with cvxpy.

    extra_constraints : callable(x) -> list of cvxpy constraints on x (um / urad), or None.
    solver : a cvxpy solver name (default: CLARABEL when installed).
    """
    import cvxpy as cp
    setup = _setup(problem, q, feed, dirs, rapid)
    planner, nodes, lin = setup
    cq = build_cvxpy_problem(problem, q, feed, dirs, rapid, _setup_result=setup)
    prob = cq.with_constraints(extra_constraints(cq.x) if extra_constraints else [])
    if solver is None:
        solver = "CLARABEL" if "CLARABEL" in cp.installed_solvers() else None
    for _ in range(max_iterations):
        prob.solve(solver=solver, **solve_kwargs)
        if prob.status not in ("optimal", "optimal_inaccurate"):
            raise RuntimeError(f"cvxpy: {prob.status}")
        x = np.asarray(cq.x.value)
        moved = np.max(np.abs(x - lin.x_lin), axis=1) >= step_tol_um
        if not np.any(moved):
            break
        b, A, _ = planner.ev.residual_jacobian(nodes.q, x, nodes.context, lin.target)
        lin.b, lin.A, lin.x_lin = b, A, x.copy()
        cq.update(lin)
    return x / cq.scale

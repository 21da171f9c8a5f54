"""The nonlinear compensation problem in CasADi Opti, solved by IPOPT: the planner's reference.

No linearisation, no windows: the exact model over the whole program at once,

    minimise    1/2 sum_i ||M_i S (actual_pose(q_i + dq_i, c_i) - nominal_pose(q_i))||^2 + 1/2 sum_j lam_j ||x_j||^2
    subject to  the same correction, travel and step bounds as the QP, and its never-worse rows
                |r_i| <= |r_i(dq = 0)| + tol per row

with x the corrections in um / urad (see :mod:`mtcomp.planner._qp`) and M_i the identity on the tip
rows and ``Evaluator.orientation_rows`` on the tool-axis rows (a constant of block i). Meant for small programs (tests
compare qp, newton and cvxpy with it); it is slow for long ones.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from mtcomp.planner._qp import NEVER_WORSE_TOL
from mtcomp.planner.engine import Planner
from mtcomp.planner.problem import CompensationProblem, PlannerOptions


def solve_reference(problem: CompensationProblem, q, feed=None, dirs=None, rapid=None,
                    tol: float = 1e-12) -> np.ndarray:
    """(n, n_axes) corrections (mm, rad) of blocks given as arrays (see :func:`plan_arrays`)."""
    planner = Planner(problem, PlannerOptions(method="newton", subdivide_tol_um=None))
    nodes, lin = planner.nodes_from_arrays(q, feed, dirs, rapid)
    n, na = nodes.q.shape
    ev, b = planner.ev, planner.bounds
    rows = ev.rows
    model = problem.fitted.model
    opti = ca.Opti()
    X = opti.variable(na, n)
    F = model.pose_function.map(n, [False, True, False], [False, False], {})
    tip, axis = F(nodes.q.T + X / ev.D[:, None], ev.p, nodes.context.T)
    pose = ca.vertcat(tip, axis)[:rows, :]
    r = (pose - lin.target.T) * ev.S[:, None]
    if rows == 6:
        M = lin.orientation_rows
        e = r[3:6, :]
        r = ca.vertcat(r[:3, :], *[sum(ca.DM(M[:, k, j]).T * e[j, :] for j in range(3))
                                   for k in range(3)])
    # never worse than uncorrected, per row the objective counts (the QP's last rows)
    r0 = lin.b0 * 1.0
    if rows == 6:
        r0 = np.hstack([r0[:, :3], np.einsum("nkj,nj->nk", lin.orientation_rows, r0[:, 3:6])])
    room = (np.abs(r0) + NEVER_WORSE_TOL).T
    opti.subject_to(opti.bounded(-room, r, room))
    lam = problem.regularization_weights
    opti.minimize(0.5 * ca.sumsqr(r) + 0.5 * ca.sumsqr(np.sqrt(lam)[:, None] * X))
    l, u = b.box(nodes.q)
    opti.subject_to(opti.bounded(l.T, X, u.T))
    idx = [i for i in range(1, n) if not nodes.exempt[i]]
    if idx:
        dX = ca.horzcat(*[X[:, i] - X[:, i - 1] for i in idx])
        Sm = np.repeat(b.S[:, None], len(idx), axis=1)
        opti.subject_to(opti.bounded(-Sm, dX, Sm))
    opti.set_initial(X, np.clip(lin.x, l, u).T)
    opti.solver("ipopt", {"print_time": False},
                {"print_level": 0, "tol": tol, "constr_viol_tol": 1e-12, "max_iter": 3000,
                 "sb": "yes"})
    sol = opti.solve()
    x = np.asarray(sol.value(X)).reshape(na, n).T
    return x / ev.D

"""Compensation planner: bounded per-block axis corrections (docs/planner.md).

Public names:

* :class:`CompensationProblem` (what to solve: model, bounds, weights, output grid) and
  :class:`PlannerOptions` (how: method ``qp`` / ``pinv`` / ``newton``, windows, tolerances);
  :func:`output_grid` (the resolution of written coordinates).
* :class:`Planner` (streams a program chunk by chunk), :func:`plan_arrays` (blocks given as arrays),
  :func:`plan_chunks` (SegmentChunks), :class:`PlanResult` (one row per output block).
* :func:`build_cvxpy_problem`, :func:`plan_with_cvxpy`: the same bounded problem in cvxpy, to add
  constraints of one's own.
* :func:`nominal_pose_jacobian`: nominal tool pose and its exact Jacobian
  (:func:`mtcomp.kinematics.pose_jacobian`).
* BLOCKS.csv: :func:`report_columns`, :func:`report_rows`, :class:`Summary`.
"""
from ..kinematics import pose_jacobian as nominal_pose_jacobian
from .engine import NodeSet, Planner, PlanResult, plan_arrays, plan_chunks
from .problem import METHODS, CompensationProblem, PlannerOptions, output_grid
from .report import Summary, report_columns, report_rows

__all__ = ["nominal_pose_jacobian", "NodeSet", "Planner", "PlanResult", "plan_arrays", "plan_chunks",
           "METHODS", "CompensationProblem", "PlannerOptions", "output_grid", "Summary",
           "report_columns", "report_rows", "build_cvxpy_problem", "plan_with_cvxpy"]


def __getattr__(name):  # cvxpy is imported only when used
    if name in ("build_cvxpy_problem", "plan_with_cvxpy"):
        from . import cvxpy_problem
        return getattr(cvxpy_problem, name)
    raise AttributeError(name)

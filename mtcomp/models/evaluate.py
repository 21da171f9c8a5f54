"""Evaluating an error model on many poses at once.

``Evaluator`` runs one of the model's CasADi functions over N poses. It uses generated C code,
compiled once and cached (``mtcomp.models.compiled``) when a C compiler is there, and CasADi's own
``map`` otherwise. Inputs and outputs are numpy arrays, one row per pose, internal units.
"""
from __future__ import annotations

import numpy as np

from .chain import ErrorModel


def _as_rows(a, n_cols, n_rows, what):
    a = np.asarray(a, dtype=float)
    if a.ndim == 1:
        a = np.broadcast_to(a, (n_rows, a.shape[0]))
    if a.shape != (n_rows, n_cols):
        raise ValueError(f"{what} must have shape ({n_rows}, {n_cols}), got {a.shape}")
    return np.ascontiguousarray(a)


def casadi_map_call(function, q, p, c):
    """Evaluate a CasADi function of (q, p, c) on N poses with CasADi's own map.

    q (N, nq), p (np,) shared by every pose, c (N, nc). Returns a list of arrays, one per output,
    each (N, rows*cols) in column-major order of the output (CasADi's layout).
    """
    n = q.shape[0]
    fm = function.map(n, [False, True, False], [False] * function.n_out(), {})
    res = fm(q.T, p, c.T)
    if function.n_out() == 1:
        res = [res]
    outs = []
    for k, r in enumerate(res):
        r = np.asarray(r)
        rows, cols = function.size_out(k)
        # mapped output is rows x (cols * n), block j holds pose j
        outs.append(r.reshape(rows, n, cols).transpose(1, 2, 0).reshape(n, rows * cols, order="C")
                    if cols > 1 else r.T.copy())
    return outs


def _unpack(flat, rows, cols):
    """(N, rows*cols) column-major per pose -> (N, rows, cols)."""
    n = flat.shape[0]
    return flat.reshape(n, cols, rows).transpose(0, 2, 1)


def evaluate(model: ErrorModel, name: str, q, p, c=None, backend: str = "auto"):
    """Evaluate ``model.<name>`` (e.g. 'deviation_jacobian_function') on N poses.

    q : (N, n_axes) mm and rad. p : (n_params,) internal units. c : (N, n_context) or None (defaults).
    Returns a list of arrays shaped (N, rows, cols) per output (cols 1 squeezed to (N, rows)).
    """
    function = getattr(model, name)
    q = np.atleast_2d(np.asarray(q, dtype=float))
    n = q.shape[0]
    q = _as_rows(q, model.machine.n_axes, n, "q")
    p = np.asarray(p, dtype=float).reshape(-1)
    if p.shape != (model.n_params,):
        raise ValueError(f"p must have shape ({model.n_params},), got {p.shape}")
    c = model.default_context(n) if c is None else _as_rows(c, model.n_context, n, "context")
    outs = None
    if backend in ("auto", "compiled"):
        from . import compiled
        outs = compiled.call(model, name, function, q, p, c, required=(backend == "compiled"))
    if outs is None:
        outs = casadi_map_call(function, q, p, c)
    result = []
    for k, flat in enumerate(outs):
        rows, cols = function.size_out(k)
        result.append(flat if cols == 1 else _unpack(flat, rows, cols))
    return result


def deviation(model: ErrorModel, q, p, c=None, backend: str = "auto") -> np.ndarray:
    """(N, 6): tool-tip deviation (mm) and tool-axis deviation, workpiece frame."""
    return evaluate(model, "deviation_function", q, p, c, backend)[0]


def deviation_and_jacobians(model: ErrorModel, q, p, c=None, backend: str = "auto"):
    """(dev (N, 6), J_q (N, 6, n_axes), J_p (N, 6, n_params))."""
    return tuple(evaluate(model, "deviation_jacobian_function", q, p, c, backend))

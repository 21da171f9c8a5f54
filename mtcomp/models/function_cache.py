"""The one cache of CasADi functions built from an error model.

Building a function of a 5-axis model (the symbolic chain, its Jacobians) takes a second or more, so
each is built once per model *structure* (:meth:`~mtcomp.models.ErrorModel.structure_key`: machine,
terms, parameter and context names) and shared by every model of that structure: a model file read
twice, a copy made for a thread or a worker, a model rebuilt with the same knots. The functions of
the :data:`KEPT` structures used last are kept (the knots that the data choose make every campaign
a new structure, so a long-running process must not keep them all).

Compiled C (:mod:`mtcomp.models.compiled`) is keyed by the same structure key.
"""
from __future__ import annotations

import threading
from collections import OrderedDict
from typing import Callable

import casadi as ca

#: model structures whose functions are kept
KEPT = 16

_functions: "OrderedDict[str, dict[str, ca.Function]]" = OrderedDict()
_lock = threading.Lock()


def model_function(model, name: str, build: Callable[[], ca.Function]) -> ca.Function:
    """The CasADi function ``name`` of ``model``: ``build()``'s result, built once per model structure.

    ``name`` must say what is built (two builders must not share a name); ``build`` takes no
    argument and may only depend on the model's structure. Thread-safe (two threads may both build
    a missing function; the first one stored is returned to both).
    """
    key = model.structure_key()
    with _lock:
        funcs = _functions.get(key)
        if funcs is None:
            funcs = _functions[key] = {}
        _functions.move_to_end(key)
        while len(_functions) > KEPT:
            _functions.popitem(last=False)
        f = funcs.get(name)
    if f is None:
        f = build()
        with _lock:
            f = funcs.setdefault(name, f)
    return f


def forget() -> None:
    """Drop every cached function (they are built again when asked for)."""
    with _lock:
        _functions.clear()

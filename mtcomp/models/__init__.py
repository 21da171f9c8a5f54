"""Symbolic error models of machine tools (CasADi), their parameters and MODEL.json.

Public names:

* :class:`ErrorModel` (chain.py): the exact homogeneous-transform error chain of a machine.
* :class:`ParamSpec`, :class:`ParameterSet` (params.py): ISO 230-1 names and units.
* extension terms (terms.py): Backlash, PeriodicError, FeedOffset, AbbeIRC, RotaryErrorMotion,
  ThermalDrift, ChannelDrift.
* :class:`FittedModel`, :func:`save_model`, :func:`load_model` (model_file.py).
* :func:`deviation`, :func:`deviation_and_jacobians`, :func:`evaluate` (evaluate.py).
"""
from .chain import BASE_CONTEXT, ErrorModel, base_param_specs, context_defaults
from .evaluate import deviation, deviation_and_jacobians, evaluate
from .model_file import FittedModel, load_model, save_model
from .params import ParameterSet, ParamSpec
from .terms import (AbbeIRC, Backlash, ChannelDrift, FeedOffset, PeriodicError, RotaryErrorMotion, Term,
                    ThermalDrift, term_from_dict)

__all__ = ["BASE_CONTEXT", "ErrorModel", "base_param_specs", "context_defaults", "deviation",
           "deviation_and_jacobians", "evaluate", "FittedModel", "load_model", "save_model",
           "ParameterSet", "ParamSpec", "AbbeIRC", "Backlash", "ChannelDrift", "FeedOffset", "PeriodicError",
           "RotaryErrorMotion", "Term", "ThermalDrift", "term_from_dict"]

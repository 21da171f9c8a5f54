"""MODEL.json: one file that identify, diagnose, compensate, predict and render share.

Layout (file units: um, urad, mm; see docs/model_file.md)::

    {"format": "mtcomp-model", "version": 1,
     "machine": {... the machine description, as in its TOML ...},
     "terms": [{"kind": "backlash", "axis": "X"}, ...],        # extension terms, in order
     "parameters": {"EXX_1": {"value": 1.2, "unit": "um", "group": "X:EXX", "base": true,
                              "std_error": 0.1}, ...},
     "context_defaults": {"temp_t1": 21.0},                   # optional
     "support": {"X": [-20.0, 20.0], "C": [-180.0, 180.0]},   # optional: where the data reach
     "info": {...}}                                           # free: fit summary, provenance

``support`` is the identified region: for each axis that moved in the fitted data, the lowest and
highest position it took (mm, deg). An axis not listed never moved in the data: what its errors are
is not known, and the model holds them at zero. A model without ``support`` (written by hand, or by
an older mtcomp) claims nothing about its region.
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..io.atomic import atomic_write
from ..machine import Machine, machine_from_dict
from .chain import ErrorModel
from .params import ParameterSet
from .terms import term_from_dict

FORMAT = "mtcomp-model"


@dataclass
class FittedModel:
    """An error model with parameter values: what MODEL.json holds.

    model : the symbolic ErrorModel (machine + extension terms).
    params : ParameterSet on ``model.param_specs`` (internal units).
    context_defaults : values for context channels a data set may lack (e.g. reference temperatures).
    info : free-form provenance (fit summary, command line).
    support : axis name -> (lowest, highest) position the data reached, internal units (mm, rad);
        axes that did not move in the data are absent. ``None``: the region is not known.
    """

    model: ErrorModel
    params: ParameterSet
    context_defaults: dict = field(default_factory=dict)
    info: dict = field(default_factory=dict)
    support: dict | None = None

    @property
    def machine(self) -> Machine:
        return self.model.machine

    @classmethod
    def zero(cls, model: ErrorModel) -> "FittedModel":
        return cls(model, ParameterSet(model.param_specs))

    def context(self, n: int, columns: dict | None = None) -> np.ndarray:
        """(n, n_context) block context: given columns, else the model's defaults."""
        c = self.model.default_context(n)
        for i, name in enumerate(self.model.context_names):
            if columns is not None and name in columns:
                col = np.asarray(columns[name], dtype=float)
                c[:, i] = np.where(np.isfinite(col), col, c[:, i])
            elif name in self.context_defaults:
                c[:, i] = self.context_defaults[name]
        return c

    def to_json_dict(self) -> dict:
        return {"format": FORMAT, "version": 1, "machine": self.machine.to_dict(),
                "terms": [t.to_dict() for t in self.model.terms],
                "parameters": self.params.to_json_dict(),
                "context_defaults": dict(self.context_defaults),
                **({} if self.support is None else {"support": support_to_file(self.machine, self.support)}),
                "info": self.info}


def support_to_file(machine: Machine, support: dict) -> dict:
    """Support in file units (mm, deg), axes in machine order."""
    out = {}
    for a in machine.axis_names:
        if a in support:
            f = 180.0 / np.pi if machine.axis(a).is_rotary else 1.0
            out[a] = [float(support[a][0]) * f, float(support[a][1]) * f]
    return out


def support_from_file(machine: Machine, data, path) -> dict | None:
    """Inverse of :func:`support_to_file`, with checks (InputError naming the key)."""
    if data is None:
        return None
    if not isinstance(data, dict):
        raise InputError("'support' must be an object axis -> [low, high]", path)
    out = {}
    for a, v in data.items():
        if a not in machine.axis_names:
            raise InputError(f"'support' names axis {a!r}, which the machine does not have", path)
        if (not isinstance(v, list) or len(v) != 2
                or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v)
                or not v[0] <= v[1]):
            raise InputError(f"'support' of axis {a} must be [low, high] with low <= high", path)
        f = np.pi / 180.0 if machine.axis(a).is_rotary else 1.0
        out[a] = (float(v[0]) * f, float(v[1]) * f)
    return out


def save_model(path: str | os.PathLike, fitted: FittedModel) -> None:
    """Write MODEL.json atomically."""
    with atomic_write(path) as f:
        json.dump(fitted.to_json_dict(), f, indent=1, default=_json_default)
        f.write("\n")


def _json_default(o):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"not JSON serialisable: {type(o)}")


def load_model(path: str | os.PathLike, machine: Machine | None = None) -> FittedModel:
    """Read MODEL.json. With ``machine``, check that the file was made for a machine of that topology
    and the same axes (the machine given on the command line wins for travel and compensation)."""
    p = os.fspath(path)
    try:
        with open(p, encoding="utf-8") as f:
            data = json.load(f)
    except FileNotFoundError:
        raise InputError("no such model file", p) from None
    except json.JSONDecodeError as exc:
        raise InputError(f"not valid JSON (line {exc.lineno}: {exc.msg})", p) from None
    except UnicodeDecodeError:
        raise InputError("not a text file", p) from None
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise InputError(f"not an mtcomp model file (expected \"format\": \"{FORMAT}\")", p)
    if "machine" not in data or "parameters" not in data:
        raise InputError("model file needs 'machine' and 'parameters'", p)
    file_machine = machine_from_dict(data["machine"], path=p)
    if machine is not None:
        if machine.topology != file_machine.topology:
            raise InputError(f"model was made for a {file_machine.topology} machine, not "
                             f"{machine.topology}", p)
        for a, b in zip(machine.axes, file_machine.axes):
            if (a.degree, a.fourier_order, a.error_motion_order) != \
                    (b.degree, b.fourier_order, b.error_motion_order):
                raise InputError(f"model's axis {a.name} has another error-model structure than the "
                                 "machine given (degree or Fourier orders differ)", p)
        file_machine = machine  # travel, tool length and compensation: the given machine's
    terms = tuple(term_from_dict(t, p) for t in data.get("terms", []))
    try:
        model = ErrorModel(file_machine, terms)
    except ValueError as exc:
        raise InputError(f"inconsistent model terms: {exc}", p) from None
    if not isinstance(data["parameters"], dict):
        raise InputError("'parameters' must be an object", p)
    params = ParameterSet(model.param_specs).with_values_from_json(data["parameters"], p)
    std = np.full(len(params), np.nan)
    for name, entry in data["parameters"].items():
        if isinstance(entry, dict) and "std_error" in entry:
            std[params.index(name)] = float(entry["std_error"]) / params.specs[params.index(name)].to_file
    params.std_errors = std
    cd = data.get("context_defaults", {})
    if not isinstance(cd, dict):
        raise InputError("'context_defaults' must be an object", p)
    support = support_from_file(model.machine, data.get("support"), p)
    return FittedModel(model, params, {str(k): float(v) for k, v in cd.items()}, data.get("info", {}),
                       support)

"""Random parameter values: truths for the virtual machine and for identification tests (internal units)."""
from __future__ import annotations

import numpy as np

from ..machine import Machine
from ..models import ErrorModel, FittedModel, ParameterSet


def _param_sd(spec, machine: Machine) -> float:
    """Standard deviation of a random truth parameter, in its file unit (um, urad, mm ...)."""
    name, unit, group = spec.name, spec.unit, spec.group
    if group == "squareness":
        return 30.0
    if group == "tool":
        return 2.0
    if group.endswith(":location"):
        return 10.0 if unit == "um" else 20.0
    if ":" in group and group.split(":")[1].startswith("E") and spec.base:
        comp = group.split(":")[1]
        suffix = name.rsplit("_", 1)[1]
        if suffix.isdigit():                              # linear polynomial coefficient
            k = int(suffix)
            if comp[1] in "ABC":
                return (15.0, 8.0, 4.0)[min(k, 3) - 1]
            if comp[1] == comp[2]:
                return (10.0, 5.0, 3.0)[min(k, 3) - 1]
            return (3.0, 4.0, 2.0)[min(k, 3) - 1]
        return 8.0 if unit == "urad" else 2.0           # rotary harmonics
    kind = group.split(":")[0]
    return {"backlash": 5.0 if unit == "um" else 15.0, "periodic_error": 1.0,
            "feed_dependent_offset": 0.5, "rotary_pdge": 3.0 if unit == "um" else 6.0,
            "thermal_drift": 3.0, "channel_drift": 3.0}.get(kind, _extension_sd(spec))


def _extension_sd(spec) -> float:
    if spec.name.startswith("IRC_"):
        return 40.0 if spec.name.endswith("0") else 50.0
    if spec.name.startswith("AG_"):
        return 0.05
    return 1.0


def random_truth(machine: Machine, rng: np.random.Generator, scale: float = 1.0, terms=(),
                 context_defaults: dict | None = None) -> FittedModel:
    """A realistic random truth: base parameters of machine-tool size plus the given extension terms.

    Linear axes: positioning polynomials ~10, 5, 3 um at 1 m (k = 1, 2, 3), straightness ~3 um,
    angular ~15, 8, 4 urad; squareness ~30 urad; rotary axis location ~10 um / 20 urad, angular
    positioning harmonics ~8 urad; tool length error ~2 um. Extension terms: backlash ~5 um
    (15 urad rotary), periodic error ~1 um, rotary error motions ~3 um / 6 urad, drift ~3 um per unit
    of feature, IRC shifts ~50 mm. Every standard deviation times ``scale``; every parameter drawn.
    """
    model = ErrorModel(machine, terms)
    sd = np.array([_param_sd(spec, machine) * scale / spec.to_file for spec in model.param_specs])
    values = random_parameters(model, rng, sd=sd, mask=np.ones(model.n_params, dtype=bool))
    params = ParameterSet(model.param_specs, values)
    return FittedModel(model, params, dict(context_defaults or {}), {"source": "mtcomp.sim.random_truth"})


def random_parameters(model: ErrorModel, rng: np.random.Generator, um: float = 10.0, urad: float = 20.0,
                      mask=None, sd=None) -> np.ndarray:
    """(n_params,) random parameter values, internal units: N(0, sd) inside ``mask``, zero outside.

    sd : (n_params,) standard deviations, internal units; default flat: ``um`` (um) for um
        parameters, ``urad`` (urad) for the others. mask : (n_params,) bool, default
        ``model.base_mask``. :func:`random_truth` draws with sizes that depend on the kind of parameter.
    """
    mask = model.base_mask if mask is None else mask
    if sd is None:
        sd = np.array([um * 1e-3 if s.unit == "um" else urad * 1e-6 for s in model.param_specs])
    return np.where(mask, rng.normal(size=model.n_params) * sd, 0.0)

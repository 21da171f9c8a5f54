"""The virtual machine, and the one engine that turns a model's prediction into simulated readings.

:func:`simulated_columns` evaluates a bound measurement model (:mod:`mtcomp.measurement.readings`, the
same models identification fits) and adds Gaussian noise; :class:`VirtualMachine` uses it to write
measurement files from plans, :func:`simulate` to fill the readings of a set built in memory.
"""
from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..machine import Machine
from ..measurement.files import MeasurementSet, read_measurements
from ..models import FittedModel
from ._plans import Plan
from ._sets import with_values, write_columns


def noise_sd(column: str, noise_um: float, noise_urad: float, noise_velocity_mm_min: float = 0.0) -> float:
    """Standard deviation of the noise of a measured column, in that column's file unit (its name's
    suffix: ``_um`` noise_um, ``_urad`` noise_urad, ``_mm`` noise_um / 1000, ``_mm_min`` the velocity)."""
    if column.endswith("_mm_min"):
        return noise_velocity_mm_min
    if column.endswith("_urad"):
        return noise_urad
    if column.endswith("_um"):
        return noise_um
    if column.endswith("_mm"):
        return noise_um * 1e-3
    raise ValueError(f"no noise for column {column!r}")


def simulated_columns(mmodel, p, nuisance, sd: dict[str, float], rng: np.random.Generator
                      ) -> dict[str, np.ndarray]:
    """Readings (file units) of the columns named in ``sd``: what the bound measurement model
    ``mmodel`` predicts for parameters p and nuisance values (internal units), plus N(0, sd[column])
    noise in the column's file unit, drawn from ``rng`` column by column in the order of ``sd``;
    a column with sd 0 draws nothing. (n_rows,) arrays; NaN where the model predicts none."""
    pred = mmodel.predict_columns(np.asarray(p, dtype=float), nuisance)
    out = {}
    for col, s in sd.items():
        v = np.asarray(pred[f"pred_{col}"], dtype=float)
        if s > 0:
            v = v + rng.normal(size=v.shape) * s
        out[col] = v
    return out


def simulate(model, data: MeasurementSet, p, nuisance=None, noise_um: float = 0.0,
             noise_urad: float = 0.0, rng=None, context_defaults=None) -> MeasurementSet:
    """``data`` (points, laser or ballbar) with its readings replaced by what ``model`` predicts for
    parameters p (internal units) and the file's nuisance parameters (default zero), plus Gaussian
    noise (um for translational readings and lengths, urad for angular ones; ``rng`` default
    ``default_rng(0)``). Blank cells stay blank."""
    from ..measurement.readings import measurement_model
    if data.kind not in ("points", "laser", "ballbar"):
        raise ValueError(f"simulate does not handle {data.kind} sets")
    if data.kind == "points":
        columns = ("dx_um", "dy_um", "dz_um") + (("dn_um",) if "dn_um" in data.measured else ())
    elif data.kind == "laser":
        columns = tuple(c for c in ("value_um", "value_urad") if c in data.value_columns)
    else:
        columns = ("length_mm",)
    mm = measurement_model(model, data, context_defaults)
    sd = {c: noise_sd(c, noise_um, noise_urad) for c in columns}
    cols = simulated_columns(mm, p, nuisance, sd, np.random.default_rng(0) if rng is None else rng)
    if data.kind == "points":
        values = {}
        for k, col in enumerate(("dx_um", "dy_um", "dz_um")):
            values[col] = np.where(np.isfinite(data.deviation[:, k]), cols[col] * 1e-3, np.nan)
        if "dn_um" in cols:
            values["dn_um"] = np.where(np.isfinite(data.normal_deviation), cols["dn_um"] * 1e-3, np.nan)
        return with_values(data, values)
    if data.kind == "laser":
        v = np.zeros(len(data))
        if "value_um" in cols:
            v = np.where(~data.angular, cols["value_um"] * 1e-3, v)
        if "value_urad" in cols:
            v = np.where(data.angular, cols["value_urad"] * 1e-6, v)
        return with_values(data, {"value": np.where(np.isfinite(data.value), v, np.nan)})
    return with_values(data, {"length_mm": np.where(np.isfinite(data.length), cols["length_mm"], np.nan)})


class VirtualMachine:
    """A machine with known errors that produces measurement files.

    machine : the machine (must match ``truth.machine`` in topology and axes).
    truth : the error model and its parameter values (internal units).
    noise_um : standard deviation of translational readings (points, laser um, ball-bar lengths,
        CMM, thermal channels), um. noise_urad : angular readings, urad.
    noise_velocity_mm_min : velocity readings (velocity files), mm/min.
    rng : numpy Generator (or seed) for the noise.
    nuisance : nuisance name (without the file tag, e.g. 'length_offset', 'X:EXX:offset') -> value in
        internal units; unnamed nuisances are 0 (the instruments are perfect apart from noise).
    """

    def __init__(self, machine: Machine, truth: FittedModel, noise_um: float = 0.3,
                 noise_urad: float = 0.5, rng=None, noise_velocity_mm_min: float = 1e-4,
                 nuisance: dict | None = None):
        if machine.topology != truth.machine.topology or machine.axis_names != truth.machine.axis_names:
            raise ValueError(f"truth was made for {truth.machine.topology}, not {machine.topology}")
        self.machine = machine
        self.truth = truth
        self.noise_um = float(noise_um)
        self.noise_urad = float(noise_urad)
        self.noise_velocity_mm_min = float(noise_velocity_mm_min)
        self.rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
        self.nuisance = dict(nuisance or {})

    # ---------------------------------------------------------------------------------------------
    def noise_sd(self, column: str) -> float:
        """Standard deviation of the noise of a measured column, in that column's file unit."""
        return noise_sd(column, self.noise_um, self.noise_urad, self.noise_velocity_mm_min)

    def measurement_model(self, plan: Plan, data: MeasurementSet):
        """The registered measurement model of the plan's kind, bound to the truth and ``data``."""
        from ..measurement.readings import model_class_for
        from ..measurement.drift import drift_context
        options = dict(plan.options)
        options.setdefault("extra_context", drift_context(self.truth.model, data))
        return model_class_for(plan.kind, data.path)(self.truth.model, data, self.truth.context_defaults,
                                                     machine=self.machine, **options)

    def _nuisance_vector(self, mmodel) -> np.ndarray:
        out = np.zeros(mmodel.n_nuisance)
        for i, nm in enumerate(mmodel.nuisance_names):
            short = nm.split(":", 1)[1] if ":" in nm else nm
            out[i] = self.nuisance.get(short, self.nuisance.get(nm, 0.0))
        return out

    def readings(self, plan: Plan, data: MeasurementSet, noise: bool = True) -> dict[str, np.ndarray]:
        """Measured columns (file units) for the rows of ``data``: model prediction plus noise."""
        mmodel = self.measurement_model(plan, data)
        sd = {c: self.noise_sd(c) if noise else 0.0 for c in plan.measured}
        return simulated_columns(mmodel, self.truth.params.values, self._nuisance_vector(mmodel), sd,
                                 self.rng)

    def measure(self, plan: Plan, path: str | os.PathLike | None = None, noise: bool = True
                ) -> MeasurementSet:
        """Simulate one file: write it to ``path`` (measurement CSV; default: a temporary file) and return
        the measurement set read back from it."""
        with tempfile.TemporaryDirectory(prefix="mtcomp-sim-") as tmp:
            template = Path(tmp) / f"{plan.name}.csv"
            cols = dict(plan.columns)
            for c in plan.measured:
                cols[c] = np.full(len(plan), np.nan)
            write_columns(template, cols)
            data = read_measurements(template, kind=plan.kind)
            values = self.readings(plan, data, noise)
            cols.update(values)
            out = Path(path) if path is not None else template
            write_columns(out, cols)
            return read_measurements(out, kind=plan.kind)

    def campaign(self, plans, out_dir: str | os.PathLike, gap_s: float = 600.0,
                 noise: bool = True) -> dict[str, MeasurementSet]:
        """Run plans one after another (each starts ``gap_s`` after the previous one ends, so ``t_s``
        runs on through the campaign); write ``<out_dir>/<plan.name>.csv``; name -> data read back."""
        out_dir = Path(out_dir)
        if not out_dir.is_dir():
            raise InputError("output folder does not exist", str(out_dir))
        t = 0.0
        result = {}
        for plan in plans:
            p = plan.shifted(t) if "t_s" in plan.columns else plan
            result[plan.name] = self.measure(p, out_dir / f"{plan.name}.csv", noise)
            t = max(t, p.duration_s) + gap_s
        return result

"""One task of a study: one compensation and its evaluation, as one row of the results table.

:func:`run_task` is a pure function of its :class:`~mtcomp.study.spec.Task` (and the bytes of the
files it names): it runs on a Dask worker, streams its program inside the task (the corrected
program goes to a temporary file that is deleted: a study keeps figures, not programs), and returns
a flat dict. An input error becomes the row's ``error`` (one line) instead of stopping the study.

The row (units in the names; docs/study.md):

* the task's labels: ``program, model, judge, method, bounds, temperature, draw``, and ``task``
  (the first 16 hex digits of its key);
* ``status`` ('ok' or 'error') and ``error`` (the one-line message, '' when ok);
* ``blocks`` (planned output blocks), ``evaluated_blocks`` (every axis known), ``corrected_blocks``;
  blocks left uncorrected and why: ``uncorrected_unknown_axes``, ``uncorrected_outside_support``,
  ``uncorrected_uncertain``;
* the predicted tool-tip error over the corrected blocks, under the judging model (the judge model,
  else the model itself): ``rms_before_um, max_before_um, rms_after_um, max_after_um``; the same
  under the model the compensation was planned with: ``plan_rms_after_um, plan_max_after_um``
  (all blank when no block was corrected);
* the share of evaluated blocks held by each kind of bound: ``share_max_correction``,
  ``share_max_step``, ``share_travel`` (0..1);
* the correction effort: ``correction_rms_um, correction_max_um`` (length of the linear correction
  vector over the corrected blocks);
* ``seconds``: the compensation's wall time on its worker.
"""
from __future__ import annotations

import functools
import os
import tempfile
import time
from dataclasses import replace

import numpy as np

from ..errors import InputError
from .spec import Task

#: the row's columns in order (see the module docstring)
COLUMNS = ("task", "program", "model", "judge", "method", "bounds", "temperature", "draw", "status",
           "error", "blocks", "evaluated_blocks", "corrected_blocks", "uncorrected_unknown_axes",
           "uncorrected_outside_support", "uncorrected_uncertain", "rms_before_um", "max_before_um",
           "rms_after_um", "max_after_um", "plan_rms_after_um", "plan_max_after_um",
           "share_max_correction", "share_max_step", "share_travel", "correction_rms_um",
           "correction_max_um", "seconds")


@functools.lru_cache(maxsize=8)
def _machine(name: str, machine_id: str):
    """The machine, loaded once per worker process and machine (``machine_id``: its name, or its
    file's hash, so that a file changed in place is read anew)."""
    from ..machine import load_machine
    return load_machine(name)


@functools.lru_cache(maxsize=16)
def _model(path: str, model_hash: str, machine_name: str, machine_id: str):
    """The model file, loaded once per worker process and content (``model_hash``: its SHA-256, so
    that a file replaced in place, whatever its time stamp, is read anew); callers take a copy
    before changing it."""
    from ..models.model_file import load_model
    return load_model(path, _machine(machine_name, machine_id))


def load_fitted(path: str, model_hash: str, machine_name: str, machine_id: str):
    """A fresh FittedModel of ``path`` (its CasADi functions shared with earlier loads)."""
    m = _model(path, model_hash, machine_name, machine_id)
    return replace(m, params=m.params.copy(), context_defaults=dict(m.context_defaults))


def draw_model(fitted, draw: int, seed: int, model_key: str):
    """The model with its parameters drawn from their covariance (``draw`` > 0), or the model itself
    (``draw`` 0). The draw is reproducible: its generator is seeded by (seed, draw, the model
    file's hash); the directions the data left undetermined are not drawn (they stay at zero, as
    everywhere in mtcomp). InputError for a model without a covariance."""
    if draw == 0:
        return fitted
    factor = fitted.covariance_factor()
    if factor is None:
        raise InputError("the model carries no covariance to draw from (identify, diagnose and a "
                         "thermal diagnosis write one)")
    idx, F = factor
    rng = np.random.default_rng([seed, draw, int(model_key[:12], 16)])
    p = np.array(fitted.params.values, dtype=float)
    p[idx] += F @ rng.standard_normal(F.shape[1])
    params = fitted.params.copy()
    params.values[:] = p
    return replace(fitted, params=params)


def run_task(task: Task) -> dict:
    """Run one task; returns its row (see the module docstring). Never raises for bad input: the
    row's ``status`` is 'error' and ``error`` says why in one line."""
    from ..compensation import Judge, compensate_program
    from ..toolpaths.offsets import load_setup
    row = {c: None for c in COLUMNS}
    row.update(task.labels, task=task.key[:16], status="ok", error="")
    t0 = time.perf_counter()
    try:
        machine = _machine(task.machine, task.machine_id)
        fitted = draw_model(load_fitted(task.model, task.model_hash, task.machine, task.machine_id),
                            task.draw, task.seed, task.model_hash)
        judging = (load_fitted(task.judge, task.judge_hash, task.machine, task.machine_id)
                   if task.judge else load_fitted(task.model, task.model_hash, task.machine,
                                                  task.machine_id))
        setup = load_setup(machine, task.offsets)
        judge = Judge(judging, task.settings)
        fd, tmp = tempfile.mkstemp(suffix=".nc", prefix="mtcomp-study-")
        os.close(fd)
        try:
            run = compensate_program(fitted, task.program, tmp, task.settings, setup, judges=[judge])
        finally:
            if os.path.exists(tmp):
                os.unlink(tmp)
    except InputError as exc:
        row.update(status="error", error=str(exc), seconds=time.perf_counter() - t0)
        return row
    s = run.summary.as_dict()
    judged = run.judges[judge.label]
    n = max(s["evaluated_blocks"], 1)
    shares = {f"share_{k}": v / n for k, v in run.bound_blocks.items()}
    if judged["blocks"] == 0:
        # no block corrected: there is no remaining error to show, not a perfect one
        judged = dict.fromkeys(judged, None)
        s["corrected"].update(rms_after_um=None, max_after_um=None)
    row.update(blocks=s["blocks"], evaluated_blocks=s["evaluated_blocks"],
               corrected_blocks=s["corrected"]["blocks"],
               uncorrected_unknown_axes=s["uncorrected"]["unknown_axes"],
               uncorrected_outside_support=s["uncorrected"]["outside_support"],
               uncorrected_uncertain=s["uncorrected"]["uncertain"],
               rms_before_um=judged["rms_before_um"], max_before_um=judged["max_before_um"],
               rms_after_um=judged["rms_after_um"], max_after_um=judged["max_after_um"],
               plan_rms_after_um=s["corrected"]["rms_after_um"],
               plan_max_after_um=s["corrected"]["max_after_um"],
               correction_rms_um=run.correction_rms_um, correction_max_um=run.correction_max_um,
               seconds=run.seconds, **shares)
    return row

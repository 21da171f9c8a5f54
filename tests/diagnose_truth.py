"""diagnose on the independent machine (tests/truth): run a hidden case, score what was named, and
measure seed 000's gain where a user feels it (the true error of a compensated line). Shared by
tests/test_diagnose_truth.py and benchmarks/bench_diagnose.py --truth."""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from mtcomp.diagnose import diagnose
from mtcomp.identification.predict import predict_readings
from mtcomp.machine import load_machine
from mtcomp.measurement.files import read_measurements
from truth import Context
from truth.hidden import NOISE_UM, NOISE_URAD, SEED000_FEEDS, SEED000_OFFSET_MM, HiddenCase


@dataclass
class Score:
    """right : the hidden effect named on its axis (a local defect: 'unexplained' on its axis and
    nothing named; a clean case: nothing found). wrong : names given that are not the hidden effect on
    its axis. alarm : a clean case with any finding. ratio : final held-out rms over the truth's noise
    (um readings; urad when a campaign has only angular readings)."""

    right: bool
    wrong: list
    alarm: bool
    verdict: str
    ratio: float
    seconds: float


def run(case: HiddenCase, **kw):
    """(Diagnosis, seconds) of ``case``'s files on mtcomp's machine of the same topology."""
    machine = load_machine(case.topology)
    data = [read_measurements(p) for p in case.paths]
    t0 = time.perf_counter()
    d = diagnose(machine, data, **kw)
    return d, time.perf_counter() - t0


def score(case: HiddenCase, d, seconds: float = 0.0, noise_um: float = NOISE_UM) -> Score:
    named = [f for f in d.findings if f.effect != "unexplained"]

    def right_name(f):
        if f.effect != case.effect:
            return False
        return case.effect == "thermal_drift" or f.axis == case.axis
    wrong = [f"{f.effect} {f.axis}".strip() for f in named if not right_name(f)]
    if not case.effect:
        right = not d.findings
    elif case.effect == "local_defect":
        un = [f for f in d.findings if f.effect == "unexplained"]
        right = not named and bool(un) and un[-1].axis == case.axis
        wrong = [f"{f.effect} {f.axis}" for f in named]
    else:
        right = any(right_name(f) for f in named)
    h = d.final.get("heldout_rms_um")
    ratio = float(h) / noise_um if h is not None else float("nan")
    if h is None and d.final.get("heldout_rms_urad") is not None:     # angular readings only
        ratio = float(d.final["heldout_rms_urad"]) / NOISE_URAD
    return Score(right, wrong, bool(not case.effect and d.findings), d.verdict, ratio, seconds)


def compensated_line_error(case: HiddenCase, model) -> dict:
    """Seed 000: the true positioning error (um) of the 210 mm Abbe-offset line compensated with
    ``model``, at each feed (mm/min) -> rms along X. The compensated command is the target minus the
    model's predicted reading; the truth says where the measured point then goes. One constant, common
    to all feeds, is removed (the part's datum is set once, whatever the feed)."""
    data = read_measurements(case.paths[1])
    pred = predict_readings(model, data).columns["pred_value_um"]
    feed = np.asarray(data.context.feed, float)
    err = {}
    for f in SEED000_FEEDS:
        rows = feed == f
        xt = np.unique(data.target[rows])
        e_model = np.array([pred[rows & (data.target == v)].mean() for v in xt]) * 1e-3
        q = np.zeros((xt.size, case.machine.n_axes))
        q[:, 0] = xt - e_model
        ctx = Context(np.full(xt.size, f), {"X": np.ones(xt.size)}, np.zeros(xt.size))
        reading = case.machine.laser_reading("X", "EXX", q, (0.0, SEED000_OFFSET_MM, 0.0), None, ctx)
        err[f] = (reading + q[:, 0] - xt) * 1e3
    datum = np.mean(np.concatenate(list(err.values())))
    return {f: float(np.sqrt(np.mean((e - datum) ** 2))) for f, e in err.items()}


def region_error_um(truth, fitted) -> float:
    """rms (um) of the tool-tip deviation ``fitted`` predicts less the truth's, over a grid of the
    region its data reach (5 positions per linear axis the data moved, the axes the data held where
    they held them, the rotary axes at 0, every axis approached in +), the mean difference removed
    (the files' set-ups leave a constant open); nan when the data moved no linear axis."""
    import itertools

    from mtcomp.models.evaluate import evaluate
    names = list(fitted.model.machine.axis_names)
    axes = [a for a in names if a in "XYZ" and a in fitted.support]
    if not axes:
        return float("nan")
    pts = np.array(list(itertools.product(*[np.linspace(*fitted.support[a], 5) for a in axes])))
    q = np.zeros((len(pts), len(names)))
    for a, v in (fitted.held or {}).items():
        if a in "XYZ":
            q[:, names.index(a)] = v
    for j, a in enumerate(axes):
        q[:, names.index(a)] = pts[:, j]
    n = len(q)
    # the truth's q lists its axes in the order X Y Z A B C, as mtcomp's machines do
    true, _ = truth.true_deviation(q, None, Context(0.0, {a: np.ones(n) for a in names}))
    c = fitted.context(n, {f"dir_{a.lower()}": np.ones(n) for a in names})
    model = evaluate(fitted.model, "deviation_function", q, fitted.params.values, c)[0][:, :3]
    diff = (model - true) * 1e3
    return float(np.sqrt(np.mean((diff - diff.mean(axis=0)) ** 2)))

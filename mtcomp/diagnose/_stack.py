"""All observations of a campaign stacked into one linearised problem, with their context.

Every measurement file is bound to one *probe* error model: the base model plus every
extension term diagnose may need (backlash of each axis, feed-dependent Abbe terms of each linear
axis, error motions of each rotary axis, a unit tool-tip drift). Its exact CasADi Jacobian, taken at
the base fit, gives the columns of every candidate extension at once: extension parameters are zero
there, so the Jacobian of an extended model at that point is a column subset of the probe's. Columns
that need a shape chosen later (a period, a drift feature) are built from two probe derivatives:

* ``g[axis]`` (n,): derivative of each observation with respect to the positioning error of the axis
  (EXX for X, ECC for C), from the Backlash term evaluated with every approach direction set to +1;
* ``h[d]`` (n,): derivative with respect to a tool-tip translation along d (X, Y, Z), from a
  ThermalDrift term with a constant feature; ``hc[channel]`` the same for the other channels of
  thermal files (ChannelDrift). Thermal files read drift relative to their first reading
  (mtcomp.measurement.readings_extra.ThermalModel), so their drift columns use features minus the feature at
  that reading (``Stack.feature``).

Units: observations ``y`` in error units (um for lengths, urad for angles, um/min for velocities;
ball-bar lengths in um), each unit its own class for the noise floor and the weights;
parameters in internal units (mm, rad), so ``J`` is file unit per internal unit.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from ..errors import InputError
from ..measurement.files import MeasurementSet
from ..machine import Machine
from ..models.chain import ErrorModel, guideway_positions
from ..models.terms import AbbeIRC, Backlash, RotaryErrorMotion, ThermalDrift, positioning_component

#: name of the constant context channel the probe's drift terms read
ONE = "_one"
#: the rotary error motions diagnose can add (ISO 230-1 letters before the axis letter)
MOTION_LETTERS = ("EX", "EY", "EZ", "EA", "EB")
#: harmonics of a rotary error-motion candidate when the data hold few angles (Tan et al. 2026: one
#: revolution carries them all)
PDGE_ORDER = 3
#: the most harmonics a rotary error-motion candidate may have; within it, the data's distinct angles
#: set the highest (:func:`pdge_orders`) and held-out data choose among the orders (``_candidates``)
MAX_PDGE_ORDER = 8


def pdge_orders(machine: Machine, datasets) -> dict:
    """Rotary axis -> the highest harmonic of its error-motion candidates: as many as the distinct
    angles the data hold determine (:func:`mtcomp.models.basis.auto_fourier_order`), at least
    ``PDGE_ORDER`` and at most ``MAX_PDGE_ORDER``."""
    from ..measurement.readings import data_positions
    from ..models.basis import auto_fourier_order
    pos = data_positions(machine, datasets)
    return {ax.name: int(min(MAX_PDGE_ORDER, max(PDGE_ORDER, auto_fourier_order(pos.get(ax.name, ())))))
            for ax in machine.rotary_axes}


def probe_terms(machine: Machine, orders: dict | None = None) -> list:
    """The extension terms of the probe model (see module docstring), in a fixed order. ``orders``:
    rotary axis -> harmonics of its error-motion terms (default ``PDGE_ORDER``)."""
    terms = [Backlash(a) for a in machine.axis_names]
    for ax in machine.linear_axes:
        terms.append(AbbeIRC(ax.name, angles="ABC", feed=True, angle_gain=True, angle_feed=True))
    for ax in machine.rotary_axes:
        if ax.error_motion_order > 0:
            continue
        for letters in MOTION_LETTERS:
            comp = f"{letters}{ax.name}"
            if comp != positioning_component(ax.name):
                terms.append(RotaryErrorMotion(comp, order=(orders or {}).get(ax.name, PDGE_ORDER)))
    terms.append(ThermalDrift("probe", (ONE,), "XYZ"))
    return terms


@dataclass(eq=False)
class Stack:
    """Every scalar observation of a campaign, with its context (one entry per observation).

    y : (n,) observed value, file units (um or urad).
    unit : (n,) 'um' or 'urad'.
    file : (n,) index into ``paths``; paths : the files.
    series : (n,) label of the series an observation belongs to ('file:X:EXX', 'file:dx_um' ...).
    column : (n,) measured column ('dx_um', 'value_um', 'disp_ch1_um' ...); component : (n,) ISO name
        for laser rows ('EXX'), the channel for thermal rows, '' otherwise.
    row : (n,) 0-based data row in its file.
    q : (n, n_axes) axis positions, mm and rad (zeros for files without poses).
    moving : (n,) the moving axis of laser and velocity rows, '' otherwise.
    dirs : (n, n_axes) approach direction (+1, -1, 0 unknown) of each axis.
    feed : (n,) mm/min (NaN unknown); t : (n,) s (NaN unknown); run : (n,) int (-1 unknown);
    spindle : (n,) rev/min (NaN unknown); temps : name -> (n,) degC (NaN unknown).
    arm : (n, 3) mm optic offset (Abbe arm of the set-up) of laser rows, 0 otherwise.
    setup : (n, 7) what else fixes a reading besides the axis positions: tool length (mm) and, for
        ball-bar rows, table-ball and tool-ball centres (mm); used to match repeated readings.
    J : (n, n_probe) probe Jacobian at ``p`` (file unit per internal unit); D : (n, n_nuisance).
    pred : (n,) probe prediction at ``p``, ``nuisance``.
    g : axis -> (n,) derivative with respect to that axis's positioning error (file unit per mm or
        per rad); h : 'X','Y','Z' -> (n,) derivative with respect to a tip translation (per mm);
        hc : channel -> (n,) derivative with respect to a thermal channel drift (per mm).
    """

    machine: Machine
    probe: ErrorModel
    paths: list
    y: np.ndarray
    unit: np.ndarray
    file: np.ndarray
    series: np.ndarray
    column: np.ndarray
    component: np.ndarray
    row: np.ndarray
    q: np.ndarray
    moving: np.ndarray
    dirs: np.ndarray
    feed: np.ndarray
    t: np.ndarray
    run: np.ndarray
    spindle: np.ndarray
    temps: dict
    arm: np.ndarray
    setup: np.ndarray
    nuisance_names: list
    kinds: list
    J: np.ndarray = None
    D: np.ndarray = None
    pred: np.ndarray = None
    p: np.ndarray = None
    nuisance: np.ndarray = None
    g: dict = field(default_factory=dict)
    h: dict = field(default_factory=dict)
    hc: dict = field(default_factory=dict)
    datasets: list = field(default_factory=list)
    known_setup: list = field(default_factory=list)   # tags of the files whose set-up is known
    _models: list = field(default_factory=list)
    _features: dict = field(default_factory=dict)

    def __len__(self):
        return len(self.y)

    @property
    def n_base(self) -> int:
        return int(self.probe.base_mask.sum())

    def index(self, name: str) -> int:
        return self.probe.param_names.index(name)

    def guideway(self, a: str) -> np.ndarray:
        """(n,) where axis ``a`` stood on its guideway at each observation, where its error profiles
        were read (mm, rad): the commanded position, but for the ram that of a row whose tool is
        longer than the machine's by d is q + d (docs/conventions.md, "Tool length"; the model's
        own rule, :func:`mtcomp.models.chain.guideway_positions`)."""
        return self.stood[:, self.machine.axis_names.index(a)]

    @cached_property
    def stood(self) -> np.ndarray:
        """(n, na) where every axis stood on its guideway (:meth:`guideway`; the model's own rule,
        :func:`mtcomp.models.chain.guideway_positions`): the positions diagnose reads a residual
        structure along."""
        return guideway_positions(self.machine, self.q, self.setup[:, 0])

    def columns(self, names) -> np.ndarray:
        """(n, k) probe Jacobian columns of the named parameters."""
        return self.J[:, [self.index(nm) for nm in names]]

    def feature(self, name: str) -> np.ndarray:
        """(n,) drift feature ``name`` of every observation (names and definitions of
        :func:`mtcomp.measurement.drift.feature_value`); 0 where unknown.
        Thermal files get the feature minus its value at their first reading (they read drift
        relative to it)."""
        if name not in self._features:
            from ..measurement.drift import _time_order, feature_value
            out = np.zeros(len(self))
            for fi, data in enumerate(self.datasets):
                sel = self.file == fi
                v = feature_value(name, data.context)
                if v is None:
                    raise KeyError(name)
                v = np.nan_to_num(np.asarray(v, dtype=float), nan=0.0)
                if data.kind == "thermal":
                    order = _time_order(data.context.t)
                    v = v - v[order[0] if order.size else 0]
                out[sel] = v[self.row[sel]]
            self._features[name] = out
        return self._features[name]

    def evaluate(self, p: np.ndarray, nuisance: np.ndarray, jacobian: bool = True) -> None:
        """Evaluate the probe at (p, nuisance): sets ``pred`` (and ``J``, ``D``, ``g``, ``h``)."""
        preds, Js, Ds = [], [], []
        for (mm, scale, nsl) in self._models:
            nu = nuisance[nsl]
            if jacobian:
                pr, J, Jn = mm.predict_and_jacobian(p, nu)
                Js.append(J * scale[:, None])
                D = np.zeros((len(pr), len(nuisance)))
                D[:, nsl] = Jn * scale[:, None]
                Ds.append(D)
            else:
                pr = mm.predict(p, nu)
            preds.append(pr * scale)
        self.pred = np.concatenate(preds)
        self.p = np.asarray(p, dtype=float).copy()
        self.nuisance = np.asarray(nuisance, dtype=float).copy()
        if jacobian:
            self.J = np.vstack(Js)
            self.D = np.vstack(Ds)
            self._derived()

    def _derived(self):
        m = self.machine
        for k, a in enumerate(m.axis_names):
            # the probe saw dir = +1 where unknown: g = 2 J_BL / dir_probe
            dprobe = np.where(self.dirs[:, k] == 0, 1.0, self.dirs[:, k])
            self.g[a] = 2.0 * self.J[:, self.index(f"BL_{a}")] * dprobe
        thermal = np.array([k == "thermal" for k in self.kinds])[self.file]
        for d in "XYZ":
            h = self.J[:, self.index(f"TD_{d}_{ONE}")].copy()
            # thermal files: channel x, y, z reads the tip along X, Y, Z (um per mm)
            h[thermal] = np.where(self.component[thermal] == d.lower(), 1e3, 0.0)
            self.h[d] = h
        for ch in np.unique(self.component[thermal]):
            if ch not in ("x", "y", "z"):
                self.hc[str(ch)] = np.where(thermal & (self.component == ch), 1e3, 0.0)


def build_stack(machine: Machine, datasets: list[MeasurementSet], extra_context=None,
                known_setup=()) -> Stack:
    """Stack the observations of ``datasets`` and bind them to the probe model (not yet evaluated).
    ``known_setup``: the files whose set-up is known, as identify's ``--known-setup`` names them
    (:func:`mtcomp.identification.problem.known_setup_tags`): no set-up is fitted for them."""
    probe = ErrorModel(machine, probe_terms(machine, pdge_orders(machine, datasets)))
    parts = {k: [] for k in ("y", "unit", "file", "series", "column", "component", "row", "q", "moving",
                             "dirs", "feed", "t", "run", "spindle", "arm", "setup")}
    temp_names = sorted({n for d in datasets for n in d.context.temperatures})
    temps = {n: [] for n in temp_names}
    models, nuis_names, kinds = [], [], []
    from ..identification.problem import known_setup_tags, unique_tags
    tags = unique_tags(datasets)
    known = known_setup_tags(datasets, known_setup)
    for fi, data in enumerate(datasets):
        mm = _probe_measurement_model(machine, probe, data, tags[fi], tags[fi] in known)
        r, n = mm.obs_row, mm.n_obs
        rows, scale = _file_rows(machine, probe, data, mm, tags[fi], fi)
        for k, v in rows.items():
            parts[k].append(v)
        for name in temp_names:
            v = data.context.temperatures.get(name)
            temps[name].append(v[r] if v is not None else np.full(n, np.nan))
        nsl = slice(len(nuis_names), len(nuis_names) + mm.n_nuisance)
        nuis_names.extend(mm.nuisance_names)
        models.append((mm, scale, nsl))
        kinds.append(data.kind)
    cat = {k: np.concatenate(v) for k, v in parts.items()}
    st = Stack(machine=machine, probe=probe, paths=[d.path for d in datasets], y=cat["y"],
               unit=cat["unit"], file=cat["file"], series=cat["series"], column=cat["column"],
               component=cat["component"], row=cat["row"], q=cat["q"], moving=cat["moving"],
               dirs=cat["dirs"], feed=cat["feed"], t=cat["t"], run=cat["run"].astype(np.int64),
               spindle=cat["spindle"], temps={k: np.concatenate(v) for k, v in temps.items()},
               arm=cat["arm"], setup=cat["setup"], nuisance_names=nuis_names, kinds=kinds)
    st._models = models
    st.datasets = list(datasets)
    st.known_setup = sorted(known)
    return st


def _probe_measurement_model(machine: Machine, probe, data, tag: str, known_setup: bool = False):
    """The measurement model of one file on the probe model (its set-up not fitted where
    ``known_setup``); InputError when it has no readings."""
    from ..measurement.readings import measurement_model
    # the probe reads each axis's backlash column at dir +1 where the file does not say; a cut
    # part's approach directions are the program's (its measurement model finds them)
    extra = {} if data.kind == "cmm" else {
        f"dir_{a}": np.where(data.context.dir_of(a) == 0, 1.0, data.context.dir_of(a).astype(float))
        for a in machine.axis_names}
    extra[ONE] = np.ones(len(data))
    mm = measurement_model(probe, data, None, tag=tag, extra_context=extra,
                           **({"setup": "known"} if known_setup else {}))
    if mm.n_obs == 0:
        raise InputError("the file has no measured values", data.path)
    return mm


def _file_rows(machine: Machine, probe, data, mm, tag: str, fi: int) -> tuple[dict, np.ndarray]:
    """({stack column: this file's rows}, scale of each observation to um or urad) of one file."""
    from ..identification.result import error_unit
    r = mm.obs_row
    cols = np.asarray(mm.obs_column, dtype=object).astype(str)
    scale = np.asarray(mm.obs_unit_scale, dtype=float).copy()
    unit = np.array([error_unit(c) for c in cols], dtype=object).astype(str)
    scale = np.where(scale == 1.0, 1e3, scale)     # ball-bar lengths: mm -> um
    n = mm.n_obs
    q = getattr(mm, "q", None)
    comp, moving, series, arm = _series_rows(data, tag, cols, r, n)
    dirs, feed = _block_context(machine, probe, data, mm, r)
    ctx = data.context
    rows = {"y": mm.observed * scale, "unit": unit, "file": np.full(n, fi), "column": cols, "row": r,
            "q": q[r] if isinstance(q, np.ndarray) and q.ndim == 2 else np.zeros((n, machine.n_axes)),
            "component": np.asarray(comp, dtype=object), "moving": np.asarray(moving, dtype=object),
            "series": series, "arm": arm, "setup": _setup_rows(machine, data, r, n),
            "dirs": dirs, "feed": feed, "t": ctx.t[r], "run": ctx.run[r], "spindle": ctx.spindle_rpm[r]}
    return rows, scale


def _series_rows(data, tag: str, cols: np.ndarray, r: np.ndarray, n: int):
    """(component, moving axis, series, optic arm (n, 3) mm) of a file's observations."""
    if data.kind == "laser":
        comp = data.component[r].astype(str)
        moving = data.axis[r].astype(str)
        series = np.array([f"{tag}:{a}:{c}" for a, c in zip(moving, comp)], dtype=object)
        return comp, moving, series, data.optic[r]
    comp = np.array([c[5:-3] if c.startswith("disp_") else "" for c in cols], dtype=object)
    moving = np.asarray(getattr(data, "axis", np.full(len(data), "", dtype=object)))[r].astype(str) \
        if data.kind == "velocity" else np.full(n, "")
    series = np.array([f"{tag}:{c}" for c in cols], dtype=object)
    return comp, moving, series, np.zeros((n, 3))


def _setup_rows(machine: Machine, data, r: np.ndarray, n: int) -> np.ndarray:
    """(n, 7) set-up of each observation, mm: tool length, table ball, tool ball."""
    setup = np.zeros((n, 7))
    setup[:, 0] = machine.tool_length
    if data.kind == "points":
        setup[:, 0] = data.tool_lengths(machine)[r]
    elif data.kind == "ballbar":
        setup[:, 1:4] = data.table_ball[r]
        setup[:, 4:7] = data.tool_ball[r]
    return setup


def _block_context(machine: Machine, probe, data, mm, r: np.ndarray):
    """((n, n_axes) approach directions, (n,) feed mm/min) of a file's observations."""
    if data.kind == "cmm":
        # a cut part's block context is the program's (the cutter location that made each point),
        # not the CMM file's own columns
        names = probe.context_names
        return (np.column_stack([mm.c[r, names.index(f"dir_{a}")] for a in machine.axis_names]),
                mm.c[r, names.index("feed")])
    ctx = data.context
    return (np.column_stack([ctx.dir_of(a)[r].astype(float) for a in machine.axis_names]), ctx.feed[r])

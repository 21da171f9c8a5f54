"""Measurement campaigns on a :class:`~truth.machine.TruthMachine`, written as SPEC section 3 CSV files.

Every writer takes the machine, an output path and an ``rng`` (``np.random.Generator``; set-ups and
noise are drawn from it), writes one CSV file with :mod:`csv` (header row; lengths and positions in
mm, rotary positions in deg, translational readings in um, angular readings in urad, feed in mm/min,
time in s, temperatures in degC; blank cell = not measured) and returns a :class:`CampaignResult`:
the path, the columns as arrays (as written), the set-up that was applied and the ideal readings
(no set-up, no noise) in file units.

``setup=False`` switches the file's set-up off (zero offsets, no rotation); ``noise_* = 0`` switches
the noise off: then the readings are exactly the machine's (see each writer for the formula).
Rows are in the order they were measured; ``t_s`` advances with moves (distance / feed) and dwells.
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import transforms as T
from .effects import SpindleSchedule, ThermalDrift, ThermalEnvironment
from .machine import Context, TruthMachine

INTEGER_COLUMNS = ("dir", "run", "seq")


@dataclass
class CampaignResult:
    """path : the CSV written. columns : {column: (n,) array or list} as written (file units).
    setup : what the file's set-up was (file units, keys per writer). ideal : {column: (n,)} the
    readings without set-up and noise (file units). context : the :class:`Context` of the rows.
    q : (n, n_axes) commanded axis positions, mm and rad."""

    path: Path
    columns: dict
    setup: dict = field(default_factory=dict)
    ideal: dict = field(default_factory=dict)
    context: Context | None = None
    q: np.ndarray | None = None


# ---------------------------------------------------------------------------------------- csv
def _cell(name, v):
    if isinstance(v, str):
        return v
    if v is None:
        return ""
    v = float(v)
    if not math.isfinite(v):
        return ""
    if name in INTEGER_COLUMNS or name.startswith("dir_"):
        return str(int(round(v)))
    return format(v, ".12g")


def write_csv(path, columns: dict) -> Path:
    """Write ``columns`` ({name: sequence}, all of one length) as CSV; NaN and None as blank cells."""
    path = Path(path)
    names = list(columns)
    n = len(next(iter(columns.values())))
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(names)
        for i in range(n):
            w.writerow([_cell(k, columns[k][i]) for k in names])
    return path


def _axis_columns(machine: TruthMachine, q) -> dict:
    """x_mm, y_mm, z_mm and the rotary a_deg/b_deg/c_deg of the axes present (deg)."""
    out = {}
    for k, a in enumerate(machine.axis_names):
        if a in "XYZ":
            out[f"{a.lower()}_mm"] = q[:, k].copy()
        else:
            out[f"{a.lower()}_deg"] = np.degrees(q[:, k])
    return out


def _signed(rng, lo, hi, size=None):
    return rng.uniform(lo, hi, size) * rng.choice([-1.0, 1.0], size)


def random_setup_rotation(rng, lo_urad=5.0, hi_urad=50.0) -> np.ndarray:
    """(3,) rad: a small rotation vector with components of 5-50 urad and random signs."""
    return _signed(rng, lo_urad, hi_urad, 3) * 1e-6


class _Clock:
    def __init__(self, t0=0.0):
        self.t = float(t0)

    def move(self, distance, feed_per_min, dwell_s):
        if feed_per_min > 0:
            self.t += abs(distance) / feed_per_min * 60.0
        self.t += dwell_s
        return self.t


def _environment(machine: TruthMachine, environment):
    """The environment a campaign records: ``environment`` when given, else, for a machine with a
    :class:`ThermalDrift` effect, a :class:`ThermalEnvironment` on the schedule of its first
    spindle-driven drift (or :data:`DEFAULT_SCHEDULE`), else None (no temperature columns)."""
    if environment is not None:
        return environment
    drifts = [e for e in machine.effects if isinstance(e, ThermalDrift)]
    if not drifts:
        return None
    schedule = next((e.schedule for e in drifts if e.driver == "spindle" and e.schedule), None)
    return ThermalEnvironment(schedule or DEFAULT_SCHEDULE)


def _with_environment(env, ctx: Context, cols: dict, t) -> None:
    """Fill the context's temperatures and spindle speed from ``env`` at times ``t`` and add the
    ``spindle_rpm`` and ``temp_<name>_c`` columns (nothing when env is None)."""
    if env is None:
        return
    ctx.temperatures = env.temperatures(t)
    ctx.spindle_rpm = env.schedule.rpm(t)
    cols["spindle_rpm"] = ctx.spindle_rpm
    for name, v in ctx.temperatures.items():
        cols[f"temp_{name}_c"] = v


# ---------------------------------------------------------------------------------------- points
def points(machine: TruthMachine, path, rng, *, grid=(5, 5, 4), margin=0.1, plane: dict | None = None,
           rotary_deg=None, tool_lengths_mm=None, directions=(1, -1), feeds_mm_min=(500.0, 2000.0, 5000.0),
           repeats: int = 1, setup: bool = True, noise_um: float = 0.3, t0_s: float = 0.0,
           dwell_s: float = 3.0, environment: ThermalEnvironment | None = None) -> CampaignResult:
    """Volumetric points file (SPEC 3.1): dx, dy, dz (um) of the tool tip at a grid of commanded poses.

    grid : points per linear axis (X, Y, Z) over the travel shrunk by ``margin`` (fraction) at each end.
    plane : e.g. ``{"Z": 0.0}`` fixes that axis (mm): a plane only.
    rotary_deg : list of tuples of rotary positions (deg) in the machine's rotary order (A/B then C);
        default for 5-axis machines: tilt in (0, -30, 30) x C in (0, 90, 180, 270); ignored on 3 axes.
    tool_lengths_mm : two or more tool lengths (``tool_mm``); default (L, L + 60) with L the machine's.
    directions : approach directions; each pose is read once per direction with every axis approached
        from that side (``dir_x`` ... ``dir_c``). feeds_mm_min : each reading's feed drawn from these.
    repeats : passes over everything (``run`` 1..repeats).
    setup : the tracker's set-up. A tracker aligned to the part reports the actual tip p (workpiece
        frame) as ``R_s p + t_s``; the file holds d = R_s p + t_s - p_nominal (um), with t_s a
        translation of 2-30 um per component and R_s a rotation (about the workpiece origin) by a
        rotation vector of 5-50 urad per component (``setup["translation_um"]``,
        ``setup["rotation_urad"]``). environment : a :class:`ThermalEnvironment` whose spindle speed
        and temperatures are written (``spindle_rpm``, ``temp_<name>_c``) and fed to thermal effects;
        default: one on the machine's spindle schedule when it has a :class:`ThermalDrift`, else none
        (the same holds for the laser and ballbar writers).

    Returns ideal ``dx_um, dy_um, dz_um`` = actual minus nominal tip (no set-up, no noise).
    """
    lin = [a for a in machine.axis_names if a in "XYZ"]
    rot = [a for a in machine.axis_names if a in "ABC"]
    plane = {k.upper(): v for k, v in (plane or {}).items()}
    axes_values = []
    for a, n in zip("XYZ", grid):
        lo, hi = machine.travel[a]
        pad = margin * (hi - lo)
        axes_values.append(np.array([plane[a]]) if a in plane else np.linspace(lo + pad, hi - pad, n))
    lattice = np.stack(np.meshgrid(*axes_values, indexing="ij"), axis=-1).reshape(-1, 3)
    if rot:
        if rotary_deg is None:
            tilts = (0.0, -30.0, 30.0) if len(rot) == 2 else (0.0,)
            rotary_deg = [(t, c) for t in tilts for c in (0.0, 90.0, 180.0, 270.0)] if len(rot) == 2 \
                else [(c,) for c in (0.0, 90.0, 180.0, 270.0)]
        rotary = np.radians(np.asarray(rotary_deg, float).reshape(-1, len(rot)))
    else:
        rotary = np.zeros((1, 0))
    L0 = machine.tool_length_mm
    tools = (L0, L0 + 60.0) if tool_lengths_mm is None else tuple(tool_lengths_mm)
    rows_q, rows_L, rows_dir, rows_run, rows_t, rows_feed = [], [], [], [], [], []
    clock = _Clock(t0_s)
    prev = None
    for run in range(1, repeats + 1):
        for L in tools:
            for r in rotary:
                for d in directions:
                    for p in lattice:
                        q = np.zeros(machine.n_axes)
                        for k, a in enumerate(lin):
                            q[machine.index(a)] = p["XYZ".index(a)]
                        for k, a in enumerate(rot):
                            q[machine.index(a)] = r[k]
                        feed = float(rng.choice(feeds_mm_min))
                        dist = 0.0 if prev is None else float(np.linalg.norm(q[:3] - prev[:3]))
                        prev = q
                        rows_t.append(clock.move(dist, feed, dwell_s))
                        rows_q.append(q)
                        rows_L.append(L)
                        rows_dir.append(d)
                        rows_run.append(run)
                        rows_feed.append(feed)
    q = np.array(rows_q)
    n = len(q)
    L = np.array(rows_L)
    dirs = np.array(rows_dir, float)
    t = np.array(rows_t)
    feed = np.array(rows_feed)
    ctx = Context(feed, {a: dirs for a in machine.axis_names}, t)
    env_cols: dict = {}
    _with_environment(_environment(machine, environment), ctx, env_cols, t)
    tip, _ = machine.true_pose(q, L, ctx)
    tip0, _ = machine.nominal_pose(q, L)
    ideal = (tip - tip0) * 1e3
    if setup:
        t_um = _signed(rng, 2.0, 30.0, 3)
        w = random_setup_rotation(rng)
    else:
        t_um, w = np.zeros(3), np.zeros(3)
    Rs = T.rotation_about(w if np.linalg.norm(w) > 0 else [0, 0, 1.0], np.linalg.norm(w))[0, :3, :3]
    reported = (tip @ Rs.T + t_um * 1e-3 - tip0) * 1e3
    reported = reported + rng.normal(0.0, noise_um, reported.shape) if noise_um > 0 else reported
    cols = _axis_columns(machine, q)
    cols["tool_mm"] = L
    cols.update({"dx_um": reported[:, 0], "dy_um": reported[:, 1], "dz_um": reported[:, 2],
                 "feed_mm_min": feed})
    for a in machine.axis_names:
        cols[f"dir_{a.lower()}"] = dirs
    cols["run"] = np.array(rows_run)
    cols["t_s"] = t
    cols.update(env_cols)
    write_csv(path, cols)
    return CampaignResult(Path(path), cols, {"translation_um": t_um, "rotation_urad": w * 1e6},
                          {"dx_um": ideal[:, 0], "dy_um": ideal[:, 1], "dz_um": ideal[:, 2]}, ctx, q)


# ---------------------------------------------------------------------------------------- laser
def laser(machine: TruthMachine, path, rng, axis: str, *, components=None, targets=None, n_targets=11,
          n_runs: int = 5, static: dict | None = None, optic_mm=(0.0, 0.0, 0.0), feed_mm_min=1000.0,
          tool_length_mm=None, setup: bool = True, noise_um: float = 0.2, noise_urad: float = 0.3,
          t0_s: float = 0.0, dwell_s: float = 4.0,
          environment: ThermalEnvironment | None = None) -> CampaignResult:
    """ISO 230-2 runs of one ``axis`` (SPEC 3.2), one set-up per component.

    components : default the six of a linear axis (EXX, EYX, EZX, EAX, EBX, ECX for X) or the
        positioning of a rotary axis (ECC for C). targets : mm or deg (default ``n_targets`` evenly
        over the travel minus 5 %; rotary: 0 .. 360 deg without 360 or the travel).
    n_runs : each run goes forward over the targets (``dir`` +1) then backward (``dir`` -1), reading
        at every target; ``seq`` numbers the readings of a set-up in order, ``run`` 1..n_runs.
    static : {axis letter: mm or deg} positions of the other axes (default 0), written as ``x_mm`` ...
        (the moving axis's column holds its target). optic_mm : (3,) the measured point relative to the
        tool tip (Abbe arm; a vector fixed to the tool, given in the workpiece frame at the nominal pose).
    feed_mm_min : the feed of the moves (mm/min, deg/min for rotary), or a sequence of feeds: then
        every component's ``n_runs`` are repeated at each feed, ``run`` numbering all runs of a
        component 1, 2, ... in order. tool_length_mm : default the machine's.

    Reading (:meth:`TruthMachine.laser_reading`): a translational component E<d><axis> reads the
    d-component of actual minus nominal position of the measured point (workpiece frame); an angular
    one the rotation of the tool relative to the workpiece about d (right-handed, small angle); in a
    run of a rotary axis carrying the workpiece both are negated (the table relative to the tool, i.e.
    ECC = actual minus commanded table angle as ISO 230-2 reports it). Set-up (``setup=True``): per
    component a zero offset (translational 1-10 um, angular 2-20 urad) and for straightness
    components of a linear axis a slope (optic misalignment, 5-50 urad = um/m) times the target in m:
    value = ideal + offset + slope * target_mm / 1000 (+ noise). ``setup["offset"]`` and
    ``setup["slope_urad"]`` hold them per component.
    """
    axis = axis.upper()
    rotary = axis in "ABC"
    if components is None:
        components = (f"E{axis}{axis}",) if rotary else tuple(f"E{d}{axis}" for d in "XYZABC")
    if targets is None:
        lo, hi = machine.travel[axis]
        if rotary:
            lo_d, hi_d = np.degrees([lo, hi])
            if hi_d - lo_d >= 360.0:
                targets = np.linspace(0.0, 360.0, n_targets, endpoint=False)
            else:
                pad = 0.05 * (hi_d - lo_d)
                targets = np.linspace(lo_d + pad, hi_d - pad, n_targets)
        else:
            pad = 0.05 * (hi - lo)
            targets = np.linspace(lo + pad, hi - pad, n_targets)
    targets = np.asarray(targets, float)
    static = {k.upper(): float(v) for k, v in (static or {}).items()}
    j = machine.index(axis)
    q_static = np.zeros(machine.n_axes)
    for a, v in static.items():
        if a != axis:
            q_static[machine.index(a)] = math.radians(v) if a in "ABC" else v
    feeds = np.atleast_1d(np.asarray(feed_mm_min, float))
    rows = {k: [] for k in ("component", "target", "dir", "run", "seq", "t", "feed")}
    clock = _Clock(t0_s)
    pos = targets[0]
    for comp in components:
        seq = 0
        run = 0
        for feed in feeds:
            for _ in range(n_runs):
                run += 1
                for d, order in ((1, targets), (-1, targets[::-1])):
                    for tg in order:
                        seq += 1
                        rows["t"].append(clock.move(tg - pos, feed, dwell_s))
                        pos = tg
                        for k, v in (("component", comp), ("target", tg), ("dir", d), ("run", run),
                                     ("seq", seq), ("feed", feed)):
                            rows[k].append(v)
    n = len(rows["target"])
    tg = np.array(rows["target"])
    q = np.tile(q_static, (n, 1))
    q[:, j] = np.radians(tg) if rotary else tg
    dirs = np.array(rows["dir"], float)
    t = np.array(rows["t"])
    feed_rows = np.array(rows["feed"])
    ctx = Context(feed_rows, {axis: dirs}, t)
    env_cols: dict = {}
    _with_environment(_environment(machine, environment), ctx, env_cols, t)
    comp_arr = np.array(rows["component"])
    angular = np.array([c[1] in "ABC" for c in comp_arr])
    ideal = np.zeros(n)
    for comp in components:
        sel = comp_arr == comp
        ideal[sel] = machine.laser_reading(axis, comp, q[sel], optic_mm, tool_length_mm, ctx.subset(sel))
    ideal = np.where(angular, ideal * 1e6, ideal * 1e3)
    offsets, slopes = {}, {}
    value = ideal.copy()
    for comp in components:
        sel = comp_arr == comp
        ang = comp[1] in "ABC"
        offsets[comp] = float(_signed(rng, 2.0, 20.0) if ang else _signed(rng, 1.0, 10.0)) if setup else 0.0
        straight = (not ang) and (not rotary) and comp[1] != axis
        slopes[comp] = float(_signed(rng, 5.0, 50.0)) if (setup and straight) else 0.0
        value[sel] += offsets[comp] + slopes[comp] * tg[sel] / 1000.0
        sigma = noise_urad if ang else noise_um
        if sigma > 0:
            value[sel] += rng.normal(0.0, sigma, int(sel.sum()))
    cols = {"axis": [axis] * n, "component": list(comp_arr),
            ("target_deg" if rotary else "target_mm"): tg, "dir": dirs, "run": np.array(rows["run"]),
            "seq": np.array(rows["seq"]),
            "value_um": np.where(angular, np.nan, value), "value_urad": np.where(angular, value, np.nan)}
    cols.update(_axis_columns(machine, q))
    for k, c in enumerate("xyz"):
        cols[f"optic_{c}_mm"] = np.full(n, float(optic_mm[k]))
    cols["feed_mm_min"] = feed_rows
    cols["t_s"] = t
    cols.update(env_cols)
    write_csv(path, cols)
    return CampaignResult(Path(path), cols, {"offset": offsets, "slope_urad": slopes},
                          {"value_um": np.where(angular, np.nan, ideal),
                           "value_urad": np.where(angular, ideal, np.nan)}, ctx, q)


# ---------------------------------------------------------------------------------------- ballbar
_PLANES = {"XY": ("X", "Y"), "YZ": ("Y", "Z"), "ZX": ("Z", "X")}


def _length_offset(rng, setup):
    return float(_signed(rng, 1.0, 20.0) * 1e-3) if setup else 0.0


def _ballbar_file(machine, path, rng, q, table_ball, tool_ball, L, ctx, extra, setup, noise_mm,
                  environment=None):
    n = len(q)
    extra = dict(extra)
    _with_environment(_environment(machine, environment), ctx, extra, ctx.t_s)
    true_len = machine.ballbar_length(q, table_ball, tool_ball, L, ctx)
    offset = _length_offset(rng, setup)
    length = true_len + offset + (rng.normal(0.0, noise_mm, n) if noise_mm > 0 else 0.0)
    cols = _axis_columns(machine, q)
    for k, c in enumerate("xyz"):
        cols[f"table_ball_{c}_mm"] = table_ball[:, k]
    for k, c in enumerate("xyz"):
        cols[f"tool_ball_{c}_mm"] = tool_ball[:, k]
    cols["length_mm"] = length
    cols.update(extra)
    if L is not None:
        cols["tool_mm"] = np.broadcast_to(np.asarray(L, float), (n,)).copy()
    write_csv(path, cols)
    return CampaignResult(Path(path), cols, {"length_offset_mm": offset}, {"length_mm": true_len}, ctx, q)


def ballbar_circles(machine: TruthMachine, path, rng, *, planes=("XY", "YZ", "ZX"), radius_mm=100.0,
                    centre_mm=None, n_points: int = 72, directions=(1, -1), feed_mm_min=1000.0,
                    tool_ball_mm=(0.0, 0.0, 0.0), tool_length_mm=None, setup: bool = True,
                    noise_mm: float = 0.0003, t0_s: float = 0.0, dwell_s: float = 0.0,
                    environment: ThermalEnvironment | None = None) -> CampaignResult:
    """ISO 230-4 circles (SPEC 3.3) in ``planes`` (``"XY"``: X towards Y, ``"YZ"``, ``"ZX"``), each in
    both ``directions`` (+1: counter-clockwise seen from the positive third axis), rotary axes at 0.

    The table ball sits at ``centre_mm`` (workpiece frame; default the middle of the travel); the tool
    ball at ``tool_ball_mm`` from the nominal tool tip (workpiece frame at the nominal pose); the
    commanded tip runs on the circle of ``radius_mm`` about ``centre - tool_ball``. ``dir_<axis>`` is
    the sign of that axis's last move (+1 for the axis normal to the plane).
    length_mm = actual centre distance + the file's calibration offset (1-20 um, ``setup=True``) +
    noise (``noise_mm``). ``tool_mm`` is written when ``tool_length_mm`` is given.
    """
    lin = [machine.index(a) for a in "XYZ"]
    if centre_mm is None:
        centre_mm = [0.5 * sum(machine.travel[a]) for a in "XYZ"]
    c = np.asarray(centre_mm, float)
    b = np.asarray(tool_ball_mm, float)
    rows_q, rows_dir, rows_t, rows_run = [], [], [], []
    clock = _Clock(t0_s)
    run = 0
    phi = np.linspace(0.0, 2 * np.pi, n_points, endpoint=False)
    for pl in planes:
        e1, e2 = ("XYZ".index(a) for a in _PLANES[pl.upper()])
        for d in directions:
            run += 1
            ang = phi if d > 0 else -phi
            prev = None
            for a in ang:
                tip = c - b
                tip[e1] += radius_mm * np.cos(a)
                tip[e2] += radius_mm * np.sin(a)
                if prev is None:
                    # approach along the tangent
                    step = np.zeros(3)
                    step[e1], step[e2] = -np.sin(a) * d, np.cos(a) * d
                    dist = 0.0
                else:
                    step = tip - prev
                    dist = float(np.linalg.norm(step))
                dirs = np.where(step > 1e-12, 1.0, np.where(step < -1e-12, -1.0, 0.0))
                if prev is not None:
                    dirs = np.where(dirs == 0, rows_dir[-1], dirs)
                dirs = np.where(dirs == 0, 1.0, dirs)
                prev = tip
                q = np.zeros(machine.n_axes)
                q[lin] = tip
                rows_q.append(q)
                rows_dir.append(dirs)
                rows_t.append(clock.move(dist, feed_mm_min, dwell_s))
                rows_run.append(run)
    q = np.array(rows_q)
    n = len(q)
    dirs = np.array(rows_dir)
    t = np.array(rows_t)
    ctx = Context(feed_mm_min, {a: dirs[:, k] for k, a in enumerate("XYZ")}, t)
    extra = {f"dir_{a.lower()}": dirs[:, k] for k, a in enumerate("XYZ")}
    extra.update({"feed_mm_min": np.full(n, float(feed_mm_min)), "run": np.array(rows_run), "t_s": t})
    table = np.tile(c, (n, 1))
    tool = np.tile(b, (n, 1))
    return _ballbar_file(machine, path, rng, q, table, tool, tool_length_mm, ctx, extra, setup, noise_mm,
                         environment)


def three_sphere(machine: TruthMachine, path, rng, *, heights_mm=(100.0, 200.0), bar_mm=100.0,
                 angles_deg=None, n_runs: int = 3, directions=(1, -1), feed_deg_min=3600.0,
                 tool_length_mm=None, setup: bool = True, noise_mm: float = 0.0003, t0_s: float = 0.0,
                 dwell_s: float = 2.0, environment: ThermalEnvironment | None = None) -> CampaignResult:
    """Seed 003: ball bar of ``bar_mm`` from a table ball on the C axis (``axis_point_C + (0, 0, h)``,
    workpiece frame = machine frame with every axis at zero) at each height h to a tool ball
    ``bar_mm`` along X, then Y, then Z from it (six set-ups); in each only C moves, through
    ``angles_deg`` (default every 10 deg) up (``dir_c`` +1) and back down (-1), ``n_runs`` times.

    The tool ball is the tool tip (``tool_ball = 0``), held at fixed axis positions X, Y, Z = the
    table ball's machine position + bar_mm along the set-up direction; the other rotary axis at 0.
    length_mm = actual centre distance + the file's calibration offset (1-20 um) + noise.
    """
    if "C" not in machine.axis_names:
        raise ValueError(f"the three-sphere method needs a C axis ({machine.topology})")
    angles = np.arange(0.0, 360.0, 10.0) if angles_deg is None else np.asarray(angles_deg, float)
    ap = machine.axis_point["C"]
    jc = machine.index("C")
    lin = [machine.index(a) for a in "XYZ"]
    rows_q, rows_tb, rows_dir, rows_run, rows_t = [], [], [], [], []
    clock = _Clock(t0_s)
    c_now = angles[0]
    for h in heights_mm:
        table = ap + np.array([0.0, 0.0, h])
        for k in range(3):
            tip = table.copy()
            tip[k] += bar_mm
            clock.move(0.0, 1.0, 120.0)
            for run in range(1, n_runs + 1):
                for d in directions:
                    for a in (angles if d > 0 else angles[::-1]):
                        rows_t.append(clock.move(a - c_now, feed_deg_min, dwell_s))
                        c_now = a
                        q = np.zeros(machine.n_axes)
                        q[lin] = tip
                        q[jc] = math.radians(a)
                        rows_q.append(q)
                        rows_tb.append(table)
                        rows_dir.append(d)
                        rows_run.append(run)
    q = np.array(rows_q)
    n = len(q)
    dirc = np.array(rows_dir, float)
    t = np.array(rows_t)
    ctx = Context(0.0, {"C": dirc}, t)
    extra = {"dir_c": dirc, "run": np.array(rows_run), "t_s": t}
    return _ballbar_file(machine, path, rng, q, np.array(rows_tb), np.zeros((n, 3)), tool_length_mm, ctx,
                         extra, setup, noise_mm, environment)


# ---------------------------------------------------------------------------------------- thermal
DEFAULT_SCHEDULE = SpindleSchedule(((0.0, 0.0), (1800.0, 2000.0), (5400.0, 6000.0), (12600.0, 0.0),
                                    (16200.0, 4000.0), (21600.0, 0.0)))


def thermal(machine: TruthMachine, path, rng, *, duration_h=8.0, interval_s=60.0, schedule=None,
            environment: ThermalEnvironment | None = None, q_setup=None, tool_length_mm=None,
            channels=("x", "y", "z"), setup: bool = True, noise_um: float = 0.1,
            noise_c: float = 0.02) -> CampaignResult:
    """A fixed set-up read every ``interval_s`` for ``duration_h`` (SPEC 3.5, ISO 230-3 style).

    schedule : spindle on/off blocks (:class:`SpindleSchedule`); default that of the machine's first
        spindle-driven :class:`ThermalDrift`, else :data:`DEFAULT_SCHEDULE`. environment : the
        temperatures (default :class:`ThermalEnvironment` on that schedule); they are written as
        ``temp_<name>_c`` (+ noise ``noise_c``) and fed to temperature-driven effects.
    q_setup : the axis positions of the set-up (default all 0). channels : ``disp_<c>_um`` for c in
        x, y, z: the components of the tool tip's deviation (workpiece frame). With ``setup=True`` the
        sensors are zeroed at the first reading (disp = d(t) - d(t_0)); otherwise they read d(t).
    """
    if schedule is None:
        schedule = next((e.schedule for e in machine.effects
                         if isinstance(e, ThermalDrift) and e.driver == "spindle" and e.schedule), None)
        schedule = schedule or DEFAULT_SCHEDULE
    env = environment or ThermalEnvironment(schedule)
    t = np.arange(0.0, duration_h * 3600.0 + 0.5 * interval_s, interval_s)
    n = len(t)
    q = np.tile(np.zeros(machine.n_axes) if q_setup is None else np.asarray(q_setup, float), (n, 1))
    temps = env.temperatures(t)
    rpm = schedule.rpm(t)
    ctx = Context(0.0, {}, t, temps, rpm)
    d, _ = machine.true_deviation(q, tool_length_mm, ctx)
    d = d * 1e3
    ref = d[0].copy() if setup else np.zeros(3)
    cols = {"t_s": t, "spindle_rpm": rpm}
    ideal = {}
    for c in channels:
        k = "xyz".index(c)
        v = d[:, k] - ref[k]
        ideal[f"disp_{c}_um"] = v
        cols[f"disp_{c}_um"] = v + (rng.normal(0.0, noise_um, n) if noise_um > 0 else 0.0)
    for name, v in temps.items():
        cols[f"temp_{name}_c"] = v + (rng.normal(0.0, noise_c, n) if noise_c > 0 else 0.0)
    write_csv(path, cols)
    return CampaignResult(Path(path), cols, {"zero_um": ref}, ideal, ctx, q)


# ---------------------------------------------------------------------------------------- velocity
def table_point_velocity(machine: TruthMachine, axis: str, s, points_xy, feed_mm_min, direction=1.0,
                         context: Context | None = None, h_mm: float = 1e-3) -> np.ndarray:
    """(N, 2) mm/min: minus the velocity, in the bed frame, of the table points ``points_xy`` (N, 2)
    (table frame coordinates, z = 0) while table ``axis`` moves at ``direction * feed_mm_min`` through
    ``s`` (N,) mm, every other axis at 0.

    The table moves by -s along the axis, so the sign is flipped to read the motion in the sense of the
    axis: with no error the result is ``+direction * feed`` along the axis (V0 of seed 000, as
    docs/measurements.md uses it). Central difference of the exact chain over +-h_mm. To first order
    ``v = V0 u + Omega e_z x (P - O)`` with Omega = dEC/ds V0 and O the pivot of the table's angular
    errors shifted by the straightness slope (O_x = p_x - dEYX/ds / dECX/ds for X)."""
    s = np.atleast_1d(np.asarray(s, float))
    n = len(s)
    j = machine.index(axis)
    P = np.zeros((n, 3))
    P[:, :2] = np.broadcast_to(np.asarray(points_xy, float), (n, 2))
    ctx = context if context is not None else Context(feed_mm_min, {axis: direction})
    qp = np.zeros((n, machine.n_axes))
    qm = np.zeros((n, machine.n_axes))
    qp[:, j] = s + h_mm
    qm[:, j] = s - h_mm
    xp = T.apply(machine.wp2bed(qp, ctx), P)
    xm = T.apply(machine.wp2bed(qm, ctx), P)
    rate = np.broadcast_to(np.asarray(direction, float) * np.asarray(feed_mm_min, float), (n,))
    return -((xp - xm) / (2 * h_mm))[:, :2] * rate[:, None]


def velocity(machine: TruthMachine, path, rng, *, axis: str = "X", start_mm=None, length_mm=200.0,
             step_mm=5.0, feeds_mm_min=(180.0, 240.0, 300.0), n_runs: int = 3, m_xy=(50.0, 150.0),
             n_xy=(250.0, 100.0), noise_mm_min: float = 1e-4, t0_s: float = 0.0) -> CampaignResult:
    """Seed 000 experiment (SPEC 3.6): the table moves along ``axis`` (a workpiece-side X or Y) over
    ``length_mm`` in ``step_mm`` steps from ``start_mm`` (default 10 % into the travel), ``n_runs``
    runs at each feed, always in the + direction (``dir_<axis>`` = +1); at each position the velocities
    of the table points M and N (table frame coordinates ``m_xy``, ``n_xy``) are read.

    Convention (SPEC is silent): velocities are those of :func:`table_point_velocity`: minus the
    table points' velocity in the bed frame, i.e. the motion in the sense of the axis (V0 = dir * feed
    along the axis, as docs/measurements.md uses it); a sensor on the bed reads the negative.
    Noise ``noise_mm_min`` per component. Returns ``ideal`` velocities and ``setup["irc_xy_mm"]``:
    the rotation centre solved from the ideal velocities by eq. 1 ((v - V0 e) . (O - P) = 0 for P = M, N).
    """
    axis = axis.upper()
    if axis not in ("X", "Y") or machine.side(axis) != "workpiece":
        raise ValueError(f"the velocity campaign moves a table axis X or Y; {machine.topology} has "
                         f"{axis} on the {machine.side(axis) if axis in machine.axis_names else 'no'} side")
    lo, hi = machine.travel[axis]
    start = lo + 0.1 * (hi - lo) if start_mm is None else float(start_mm)
    pos = start + np.arange(0.0, length_mm + 1e-9, step_mm)
    rows = []
    clock = _Clock(t0_s)
    for feed in feeds_mm_min:
        for run in range(1, n_runs + 1):
            clock.move(length_mm, 3000.0, 5.0)
            for s in pos:
                rows.append((s, feed, run, clock.move(step_mm, feed, 0.0)))
    s = np.array([r[0] for r in rows])
    feed = np.array([r[1] for r in rows])
    t = np.array([r[3] for r in rows])
    n = len(s)
    ctx = Context(feed, {axis: np.ones(n)}, t)
    vm = table_point_velocity(machine, axis, s, m_xy, feed, 1.0, ctx)
    vn = table_point_velocity(machine, axis, s, n_xy, feed, 1.0, ctx)
    k = "XY".index(axis)
    irc = np.full((n, 2), np.nan)
    for i in range(n):
        v0 = np.zeros(2)
        v0[k] = feed[i]
        U = np.array([vm[i] - v0, vn[i] - v0])
        if abs(np.linalg.det(U)) > 1e-300:
            irc[i] = np.linalg.solve(U, [U[0] @ m_xy, U[1] @ n_xy])
    noise = (lambda: rng.normal(0.0, noise_mm_min, n)) if noise_mm_min > 0 else (lambda: 0.0)
    cols = {"axis": [axis] * n, "feed_mm_min": feed, f"{axis.lower()}_mm": s,
            "m_x_mm": np.full(n, float(m_xy[0])), "m_y_mm": np.full(n, float(m_xy[1])),
            "m_vx_mm_min": vm[:, 0] + noise(), "m_vy_mm_min": vm[:, 1] + noise(),
            "n_x_mm": np.full(n, float(n_xy[0])), "n_y_mm": np.full(n, float(n_xy[1])),
            "n_vx_mm_min": vn[:, 0] + noise(), "n_vy_mm_min": vn[:, 1] + noise(),
            f"dir_{axis.lower()}": np.ones(n), "run": np.array([r[2] for r in rows]), "t_s": t}
    q = np.zeros((n, machine.n_axes))
    q[:, machine.index(axis)] = s
    write_csv(path, cols)
    ideal = {"m_vx_mm_min": vm[:, 0], "m_vy_mm_min": vm[:, 1], "n_vx_mm_min": vn[:, 0],
             "n_vy_mm_min": vn[:, 1]}
    return CampaignResult(Path(path), cols, {"irc_xy_mm": irc}, ideal, ctx, q)


# ---------------------------------------------------------------------------------------- a whole campaign
def full_campaign(machine: TruthMachine, folder, rng, *, points_grid=(5, 5, 4), laser_targets: int = 11,
                  noise_um: float = 0.3, noise_urad: float = 0.5, noise_mm: float = 0.0003,
                  setup: bool = True, with_thermal: bool = False, with_velocity: bool = False) -> dict:
    """A typical measurement campaign, one file per set-up, one after the other in time (each file's
    ``t_s`` starts where the previous ended): ``points`` (two tool lengths, both directions, three
    feeds), ``laser_<axis>`` for every linear axis (six components, a random optic offset of up to
    150 mm per direction, the other axes at random static positions) and for every rotary axis
    (positioning), ``ballbar`` (circles in XY, YZ, ZX), ``three_sphere`` (machines with C),
    optionally ``thermal`` (4 h) and ``velocity`` (a table X or Y). Returns {name: CampaignResult};
    files are written into ``folder`` as ``<name>.csv``."""
    from pathlib import Path as _P
    folder = _P(folder)
    out = {}
    t = 0.0

    def last_t(res):
        ts = res.columns.get("t_s")
        return float(np.max(ts)) + 60.0 if ts is not None and len(ts) else t

    out["points"] = points(machine, folder / "points.csv", rng, grid=points_grid, setup=setup,
                           noise_um=noise_um, t0_s=t)
    t = last_t(out["points"])
    for a in machine.axis_names:
        if a in "XYZ":
            static = {b: rng.uniform(*machine.travel[b]) * 0.5 for b in "XYZ" if b != a}
            optic = tuple(rng.uniform(-150, 150, 3))
            out[f"laser_{a.lower()}"] = laser(machine, folder / f"laser_{a.lower()}.csv", rng, a,
                                              n_targets=laser_targets, static=static, optic_mm=optic,
                                              setup=setup, noise_um=noise_um, noise_urad=noise_urad, t0_s=t)
        else:
            out[f"laser_{a.lower()}"] = laser(machine, folder / f"laser_{a.lower()}.csv", rng, a,
                                              n_targets=12, setup=setup, noise_urad=noise_urad, t0_s=t)
        t = last_t(out[f"laser_{a.lower()}"])
    out["ballbar"] = ballbar_circles(machine, folder / "ballbar.csv", rng, setup=setup, noise_mm=noise_mm,
                                     t0_s=t)
    t = last_t(out["ballbar"])
    if "C" in machine.axis_names:
        out["three_sphere"] = three_sphere(machine, folder / "three_sphere.csv", rng, setup=setup,
                                           noise_mm=noise_mm, t0_s=t)
        t = last_t(out["three_sphere"])
    if with_thermal:
        out["thermal"] = thermal(machine, folder / "thermal.csv", rng, duration_h=4.0, setup=setup,
                                 noise_um=noise_um / 3)
    if with_velocity:
        table = [a for a in ("X", "Y") if a in machine.axis_names and machine.side(a) == "workpiece"]
        if table:
            out["velocity"] = velocity(machine, folder / "velocity.csv", rng, axis=table[0], t0_s=t)
    return out

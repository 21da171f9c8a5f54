"""Plans: what a simulated measurement file measures, in which order, at which feed and when.

Each ``*_plan`` function returns a :class:`Plan` (columns in the file units of docs/measurements.md, the
measured columns left out); :class:`~mtcomp.sim.VirtualMachine` fills the readings. Times ``t_s`` advance
with moves at feed and dwells. Plan columns are in file units (mm, deg, mm/min, s); arguments in the units
their names and docstrings give.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import InputError
from ..machine import Machine
from ..measurement.cut import CutProgram


@dataclass
class Plan:
    """One measurement file to simulate.

    kind : measurement kind (points, laser, ballbar, cmm, thermal, velocity).
    name : file stem (``<name>.csv``).
    columns : column name -> (n,) values in FILE units (numbers or strings), in file order; the
        measured columns are left out (the virtual machine adds them).
    measured : the measured columns to fill (``dx_um``, ``value_um``, ``length_mm`` ...). A reading
        the measurement model predicts as NaN (e.g. ``value_um`` of an angular row) stays blank.
    options : options of the measurement model (cmm: ``cut``, ``tool_radius_mm``; thermal:
        ``setup_q``).
    """

    kind: str
    name: str
    columns: dict
    measured: tuple[str, ...]
    options: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return len(next(iter(self.columns.values())))

    @property
    def duration_s(self) -> float:
        """Time span of the plan (s): last ``t_s`` (0 when the plan has no times)."""
        t = self.columns.get("t_s")
        return float(np.nanmax(t)) if t is not None and len(t) else 0.0

    def shifted(self, dt_s: float) -> "Plan":
        """The same plan started ``dt_s`` seconds later."""
        cols = dict(self.columns)
        if "t_s" in cols:
            cols["t_s"] = np.asarray(cols["t_s"], dtype=float) + dt_s
        return replace(self, columns=cols)


class _Clock:
    """Campaign time: moves at feed, dwells; ``now`` in s."""

    def __init__(self, start_s: float = 0.0):
        self.now = float(start_s)

    def move(self, distance: float, feed_per_min: float, dwell_s: float = 0.0) -> float:
        self.now += abs(distance) / feed_per_min * 60.0 + dwell_s
        return self.now


def _axis_cells(machine: Machine, q: np.ndarray, columns: dict, prefix: str = "") -> None:
    """Add the axis-position columns (x_mm ... , a_deg ...) of poses q (n, na) mm and rad."""
    for j, a in enumerate(machine.axis_names):
        if a in "XYZ":
            columns[f"{prefix}{a.lower()}_mm"] = q[:, j]
        else:
            columns[f"{prefix}{a.lower()}_deg"] = np.degrees(q[:, j])


def _approach_dirs(q: np.ndarray, first=None) -> np.ndarray:
    """(n, na) +1/-1 approach direction of each axis at each pose of the sequence q: the sign of its
    last motion (``first`` or +1 before any motion)."""
    n, na = q.shape
    out = np.zeros((n, na))
    cur = np.ones(na) if first is None else np.asarray(first, dtype=float).copy()
    prev = q[0].copy()
    for i in range(n):
        step = q[i] - prev if i else np.zeros(na)
        moving = np.abs(step) > 1e-12
        cur[moving] = np.sign(step[moving])
        out[i] = cur
        prev = q[i]
    return out


def _default_targets(lo: float, hi: float, rotary: bool) -> np.ndarray:
    """ISO 230-2 style targets: at least 5 per metre (linear) or every 30 deg (rotary), irregular
    spacing (fixed pattern) so that periodic errors are not sampled at one phase."""
    if rotary:
        lo_d, hi_d = math.degrees(lo), math.degrees(hi)
        if hi_d - lo_d >= 360.0:                         # a full turn: 0, 30, ... 330 deg
            a = max(lo_d, 0.0) if lo_d <= 0.0 <= hi_d - 360.0 else lo_d
            return np.radians(np.arange(a, a + 360.0 - 1e-9, 30.0))
        a, b = lo_d + 5.0, hi_d - 5.0                    # room for the approach overrun
        if b - a >= 120.0:
            n = int(math.floor((b - a) / 30.0 + 1e-9)) + 1
            return np.radians(a + (b - a - 30.0 * (n - 1)) / 2 + 30.0 * np.arange(n))
        return np.radians(np.linspace(a, b, 5))
    margin = 0.05 * (hi - lo)
    a, b = lo + margin, hi - margin
    n = max(5, int(math.ceil(5.0 * (b - a) / 1000.0))) + 1
    base = np.linspace(a, b, n)
    jitter = np.random.default_rng(2302).uniform(-0.25, 0.25, n) * (b - a) / (n - 1)
    jitter[[0, -1]] = 0.0
    return np.round(base + jitter, 3)


def iso230_2_plan(machine: Machine, axis: str, targets=None, n_runs: int = 5,
                  components: tuple[str, ...] | None = None, static_q=None, optic_mm=(0.0, 0.0, 0.0),
                  feed_mm_min: float = 1000.0, dwell_s: float = 3.0, overrun: float | None = None,
                  start_s: float = 0.0, name: str | None = None) -> Plan:
    """Laser runs along one axis (a laser file), ISO 230-2 standard cycle: each run goes up through every
    target (dir +1) from below the first, then down (dir -1) from beyond the last.

    axis : moving axis. targets : (m,) mm or rad (default: :func:`_default_targets`). components :
        ISO 230-1 names read at each target (default the positioning component, EXX or ECC); each
        component is its own set-up (its runs follow one another in time). static_q : (na,) positions
        of the other axes, mm and rad (default 0). optic_mm : (3,) Abbe arm of the optic relative to
        the tool tip. feed_mm_min : feed (deg/min for a rotary axis). overrun : approach overrun, mm or
        rad (default 5 mm / 2 deg).
    """
    if axis not in machine.axis_names:
        raise InputError(f"machine {machine.name!r} has no axis {axis}")
    ax = machine.axis(axis)
    j = machine.index(axis)
    targets = _default_targets(*ax.travel, ax.is_rotary) if targets is None else \
        np.asarray(targets, dtype=float)
    components = components or (f"E{axis}{axis}",)
    overrun = (math.radians(2.0) if ax.is_rotary else 5.0) if overrun is None else overrun
    feed = math.radians(feed_mm_min) if ax.is_rotary else feed_mm_min
    q0 = np.zeros(machine.n_axes) if static_q is None else np.asarray(static_q, dtype=float)
    clock = _Clock(start_s)
    rows = []
    pos = targets[0] - overrun
    seq = 0
    for comp in components:
        for run in range(1, n_runs + 1):
            for d, order in ((1, targets), (-1, targets[::-1])):
                start = order[0] - d * overrun
                clock.move(start - pos, feed)
                pos = start
                for tgt in order:
                    t = clock.move(tgt - pos, feed, dwell_s)
                    pos = tgt
                    rows.append((comp, tgt, d, run, t, seq))
                    seq += 1
    n = len(rows)
    q = np.tile(q0, (n, 1))
    q[:, j] = [r[1] for r in rows]
    cols = {"axis": [axis] * n, "component": [r[0] for r in rows]}
    if ax.is_rotary:
        cols["target_deg"] = np.degrees(q[:, j])
    else:
        cols["target_mm"] = q[:, j]
    cols["dir"] = np.array([r[2] for r in rows], dtype=float)
    cols["run"] = np.array([r[3] for r in rows], dtype=float)
    _axis_cells(machine, q, cols)
    for k, c in enumerate("xyz"):
        cols[f"optic_{c}_mm"] = np.full(n, float(optic_mm[k]))
    if not ax.is_rotary:                                 # a feed in deg/min is not a feed_mm_min
        cols["feed_mm_min"] = np.full(n, feed_mm_min)
    cols["t_s"] = np.array([r[4] for r in rows])
    cols["seq"] = np.array([r[5] for r in rows], dtype=float)
    angular = [c[1] in "ABC" for c in cols["component"]]
    measured = tuple(m for m, present in (("value_um", not all(angular)), ("value_urad", any(angular)))
                     if present)
    return Plan("laser", name or f"laser_{axis.lower()}", cols, measured)


def rotary_laser_plan(machine: Machine, axis: str = "C", targets_deg=None, n_runs: int = 5,
                      feed_deg_min: float = 1800.0, dwell_s: float = 4.0, overrun_deg: float = 2.0,
                      static_q=None, start_s: float = 0.0, name: str | None = None) -> Plan:
    """Pi et al. (2017): angular positioning (E<axis><axis>, e.g. ECC) of a rotary axis read by a laser
    and a rotary indexer, both approach directions, ``n_runs`` runs (default targets every 30 deg)."""
    if axis not in machine.axis_names or not machine.axis(axis).is_rotary:
        raise InputError(f"machine {machine.name!r} has no rotary axis {axis}")
    targets = None if targets_deg is None else np.radians(np.asarray(targets_deg, dtype=float))
    return iso230_2_plan(machine, axis, targets, n_runs, (f"E{axis}{axis}",), static_q,
                         feed_mm_min=feed_deg_min, dwell_s=dwell_s, overrun=math.radians(overrun_deg),
                         start_s=start_s, name=name or f"rotary_laser_{axis.lower()}")


def volumetric_points_plan(machine: Machine, n_per_axis=(5, 4, 3), tool_lengths_mm=None,
                           rotary_deg: dict | None = None, margin: float = 0.1,
                           feed_mm_min: float = 2000.0, dwell_s: float = 2.0, n_runs: int = 1,
                           measured=("dx_um", "dy_um", "dz_um"), start_s: float = 0.0,
                           name: str = "points") -> Plan:
    """Deviations at commanded poses on a 3-D grid (a points file): a laser tracker / R-test campaign.

    n_per_axis : grid points along X, Y, Z (inside the travel shrunk by ``margin`` of each side).
    tool_lengths_mm : tool lengths (default the machine's and 100 mm longer); the grid is measured
        with each. rotary_deg : axis -> angles (deg) visited at every grid point (default 0; a
        five-axis machine gets C at 0, 90, 180, 270 and A/B at 0 and a tilt of 30 deg).
    The grid is visited in serpentine order, so approach directions change along the way.
    """
    lin = [a for a in machine.axes if not a.is_rotary]
    grids = []
    for a, n in zip(lin, n_per_axis):
        lo, hi = a.travel
        m = margin * (hi - lo)
        grids.append(np.linspace(lo + m, hi - m, n))
    if tool_lengths_mm is None:
        tool_lengths_mm = (machine.tool_length, machine.tool_length + 100.0)
    if rotary_deg is None:
        rotary_deg = {}
        for a in machine.rotary_axes:
            rotary_deg[a.name] = [0.0, 90.0, 180.0, 270.0] if a.name == "C" else [0.0, 30.0]
    rot_names = [a.name for a in machine.rotary_axes]
    rot_sets = [np.radians(np.asarray(rotary_deg.get(r, [0.0]), dtype=float)) for r in rot_names]
    rot_combos = np.array(np.meshgrid(*rot_sets, indexing="ij")).reshape(len(rot_names), -1).T \
        if rot_names else np.zeros((1, 0))
    poses = []
    flip_y = flip_z = False
    for xi in grids[0]:
        ys = grids[1][::-1] if flip_y else grids[1]
        for yi in ys:
            zs = grids[2][::-1] if flip_z else grids[2]
            for zi in zs:
                for rc in rot_combos:
                    poses.append(np.concatenate([[xi, yi, zi], rc]))
            flip_z = not flip_z
        flip_y = not flip_y
    grid_q = np.array(poses)
    lin_idx = [machine.index(a.name) for a in lin]
    rot_idx = [machine.index(r) for r in rot_names]
    q_all, tools, runs, times = [], [], [], []
    clock = _Clock(start_s)
    prev = None
    for run in range(1, n_runs + 1):
        for tl in tool_lengths_mm:
            clock.move(0.0, 1.0, 30.0)                  # tool change
            for g in grid_q:
                q = np.zeros(machine.n_axes)
                q[lin_idx] = g[:3]
                q[rot_idx] = g[3:]
                dist = 0.0 if prev is None else float(np.max(np.abs(q - prev)[lin_idx])) if lin_idx else 0.0
                clock.move(dist, feed_mm_min, dwell_s)
                prev = q
                q_all.append(q)
                tools.append(tl)
                runs.append(run)
                times.append(clock.now)
    q = np.array(q_all)
    cols: dict = {}
    _axis_cells(machine, q, cols)
    cols["tool_mm"] = np.array(tools, dtype=float)
    dirs = _approach_dirs(q)
    for j, a in enumerate(machine.axis_names):
        cols[f"dir_{a.lower()}"] = dirs[:, j]
    cols["feed_mm_min"] = np.full(len(q), feed_mm_min)
    cols["run"] = np.array(runs, dtype=float)
    cols["t_s"] = np.array(times)
    return Plan("points", name, cols, tuple(measured))


def _circle_dirs(u: np.ndarray, sense: int) -> np.ndarray:
    """Approach direction of cos/sin coordinates along a circle traversed with ``sense`` (+1 CCW):
    the sign of the velocity just before each point."""
    du = 1e-6 * sense
    cx = np.sign(np.cos(u) - np.cos(u - du))
    cy = np.sign(np.sin(u) - np.sin(u - du))
    return np.column_stack([cx, cy])


def ballbar_circles_plan(machine: Machine, radius_mm: float = 100.0, centre_mm=None,
                         planes=("XY", "YZ", "ZX"), senses=("ccw", "cw"), n_points: int = 180,
                         feed_mm_min: float = 1000.0, n_runs: int = 1, tool_ball_mm=(0.0, 0.0, 0.0),
                         start_s: float = 0.0, name: str = "ballbar_circles") -> Plan:
    """ISO 230-4 circular tests with a ball bar (a ballbar file): one full circle per plane and sense.

    centre_mm : (3,) table-ball centre, workpiece frame (default: middle of the linear travel). The
    tool ball sits at ``tool_ball_mm`` from the nominal tool tip; the commanded tip runs on a circle of
    radius ``radius_mm`` about ``centre - tool_ball``. Rotary axes stay at 0.
    """
    lo, hi = machine.travel_bounds()
    lin = [machine.index(a) for a in "XYZ"]
    centre = np.array([(lo[j] + hi[j]) / 2 for j in lin]) if centre_mm is None else \
        np.asarray(centre_mm, dtype=float)
    ball = np.asarray(tool_ball_mm, dtype=float)
    q_rows, dir_rows, run_rows, t_rows = [], [], [], []
    clock = _Clock(start_s)
    for run in range(1, n_runs + 1):
        for plane in planes:
            i, k = ("XYZ".index(plane[0]), "XYZ".index(plane[1]))
            for sense_name in senses:
                sense = 1 if sense_name.lower() == "ccw" else -1
                u = sense * np.arange(n_points) * 2 * math.pi / n_points
                clock.move(0.0, 1.0, 5.0)
                d = _circle_dirs(u, sense)
                for m in range(n_points):
                    q = np.zeros(machine.n_axes)
                    tip = centre - ball
                    tip[i] += radius_mm * math.cos(u[m])
                    tip[k] += radius_mm * math.sin(u[m])
                    q[lin] = tip
                    dr = np.full(machine.n_axes, np.nan)
                    dr[lin[i]], dr[lin[k]] = d[m]
                    clock.move(radius_mm * 2 * math.pi / n_points, feed_mm_min)
                    q_rows.append(q)
                    dir_rows.append(dr)
                    run_rows.append(run)
                    t_rows.append(clock.now)
    q = np.array(q_rows)
    dirs = np.array(dir_rows)
    n = len(q)
    cols: dict = {}
    _axis_cells(machine, q, cols)
    for k, c in enumerate("xyz"):
        cols[f"table_ball_{c}_mm"] = np.full(n, centre[k])
    for k, c in enumerate("xyz"):
        cols[f"tool_ball_{c}_mm"] = np.full(n, ball[k])
    for j, a in enumerate(machine.axis_names):
        if a in "XYZ":
            cols[f"dir_{a.lower()}"] = dirs[:, j]
    cols["feed_mm_min"] = np.full(n, feed_mm_min)
    cols["run"] = np.array(run_rows, dtype=float)
    cols["t_s"] = np.array(t_rows)
    return Plan("ballbar", name, cols, ("length_mm",))


def three_sphere_plan(machine: Machine, bar_mm: float = 100.0, heights_mm=(100.0, 200.0),
                      angles_deg=None, n_runs: int = 3, senses=(1, -1), feed_deg_min: float = 720.0,
                      dwell_s: float = 2.0, start_s: float = 0.0, name: str = "three_sphere") -> Plan:
    """The measurement of Tan et al. (2026): a ball bar of length ``bar_mm`` from a table ball on the C axis
    at each height h (workpiece frame, above the C axis point) to a tool ball at ``bar_mm`` along X, then Y,
    then Z (six set-ups); in each set-up only C moves, through ``angles_deg`` (default every 10 deg) up
    (dir_c +1) and back down (-1), ``n_runs`` times. The tool ball is the nominal tool tip.
    """
    if "C" not in machine.axis_names:
        raise InputError(f"the three-sphere method needs a C axis; machine {machine.name!r} "
                         f"({machine.topology}) has none")
    angles = np.arange(0.0, 360.0, 10.0) if angles_deg is None else np.asarray(angles_deg, dtype=float)
    ap = np.asarray(machine.axis("C").axis_point, dtype=float)
    jc = machine.index("C")
    lin = [machine.index(a) for a in "XYZ"]
    rows = []
    clock = _Clock(start_s)
    c_now = angles[0]
    for h in heights_mm:
        table = np.array([ap[0], ap[1], ap[2] + h])
        for k in range(3):
            tip = table.copy()
            tip[k] += bar_mm
            clock.move(0.0, 1.0, 120.0)                 # set-up of the bar
            for run in range(1, n_runs + 1):
                for sense in senses:
                    order = angles if sense > 0 else angles[::-1]
                    for a in order:
                        clock.move(a - c_now, feed_deg_min, dwell_s)
                        c_now = a
                        q = np.zeros(machine.n_axes)
                        q[lin] = tip
                        q[jc] = math.radians(a)
                        rows.append((q, table, sense, run, clock.now))
    q = np.array([r[0] for r in rows])
    n = len(q)
    cols: dict = {}
    _axis_cells(machine, q, cols)
    for k, c in enumerate("xyz"):
        cols[f"table_ball_{c}_mm"] = np.array([r[1][k] for r in rows])
    for c in "xyz":
        cols[f"tool_ball_{c}_mm"] = np.zeros(n)
    cols["dir_c"] = np.array([r[2] for r in rows], dtype=float)
    cols["run"] = np.array([r[3] for r in rows], dtype=float)
    cols["t_s"] = np.array([r[4] for r in rows])
    return Plan("ballbar", name, cols, ("length_mm",))


def thermal_plan(machine: Machine, duration_h: float = 8.0, interval_s: float = 60.0,
                 spindle_profile=((0.0, 0.0), (1800.0, 6000.0), (4 * 3600.0, 0.0)),
                 channels=("x", "y", "z"), temperatures: dict | None = None, setup_q=None,
                 start_s: float = 0.0, name: str = "thermal") -> Plan:
    """A fixed set-up read every ``interval_s`` for ``duration_h`` (a thermal file, ISO 230-3 style).

    spindle_profile : ((t_s, rpm), ...) steps of the spindle speed (relative to the plan's start).
    channels : displacement channels (``x``, ``y``, ``z`` read the tool tip; other names are
        :class:`~mtcomp.models.ChannelDrift` channels). temperatures : sensor -> (ambient degC, K per
        1000 rpm of heat, lag s); default a spindle sensor and a bed sensor. setup_q : (na,) set-up pose.
    """
    from ..measurement.drift import spindle_heat
    t = np.arange(0.0, duration_h * 3600.0 + 1e-9, interval_s)
    rpm = np.zeros_like(t)
    for ts, r in spindle_profile:
        rpm[t >= ts] = r
    temperatures = temperatures or {"spindle": (21.0, 1.2, 1200.0), "bed": (20.5, 0.25, 5400.0)}
    cols: dict = {"t_s": t + start_s, "spindle_rpm": rpm}
    for sensor, (ambient, gain, tau) in temperatures.items():
        cols[f"temp_{sensor}_c"] = ambient + gain * spindle_heat(t, rpm, tau) \
            + 0.1 * np.sin(2 * math.pi * t / 86400.0)
    options = {} if setup_q is None else {"setup_q": np.asarray(setup_q, dtype=float)}
    return Plan("thermal", name, cols, tuple(f"disp_{c}_um" for c in channels), options)


def velocity_plan(machine: Machine, axis: str = "X", start_mm: float | None = None,
                  length_mm: float = 200.0, step_mm: float = 5.0, n_runs: int = 3,
                  feeds_mm_min=(180.0, 240.0, 300.0), m_xy=(50.0, 150.0), n_xy=(250.0, 100.0),
                  start_s: float = 0.0, name: str = "velocity") -> Plan:
    """The experiment of Yang et al. (2020): the table moves along ``axis`` over ``length_mm`` in
    ``step_mm`` steps (41 positions for 200/5), ``n_runs`` repeats at each feed; at each position the
    velocities of the table points M and N (coordinates ``m_xy``, ``n_xy`` in the carriage frame, XY) are
    read.
    """
    if axis not in ("X", "Y") or axis not in machine.axis_names:
        raise InputError(f"velocity plans move axis X or Y of the machine, not {axis!r}")
    lo, _hi = machine.axis(axis).travel
    start = lo + 0.1 * (machine.axis(axis).travel[1] - lo) if start_mm is None else start_mm
    pos = start + np.arange(0.0, length_mm + 1e-9, step_mm)
    rows = []
    clock = _Clock(start_s)
    for feed in feeds_mm_min:
        for run in range(1, n_runs + 1):
            clock.move(length_mm, 3000.0, 5.0)          # rapid back to the start
            for s in pos:
                clock.move(step_mm, feed)
                rows.append((s, feed, run, clock.now))
    n = len(rows)
    cols: dict = {"axis": [axis] * n, "feed_mm_min": np.array([r[1] for r in rows])}
    cols[f"{axis.lower()}_mm"] = np.array([r[0] for r in rows])
    cols["m_x_mm"], cols["m_y_mm"] = np.full(n, m_xy[0]), np.full(n, m_xy[1])
    cols["n_x_mm"], cols["n_y_mm"] = np.full(n, n_xy[0]), np.full(n, n_xy[1])
    cols[f"dir_{axis.lower()}"] = np.ones(n)
    cols["run"] = np.array([r[2] for r in rows], dtype=float)
    cols["t_s"] = np.array([r[3] for r in rows])
    return Plan("velocity", name, cols, ("m_vx_mm_min", "m_vy_mm_min", "n_vx_mm_min", "n_vy_mm_min"))


def cmm_plan(points_mm, normals, program, tool_radius_mm: float, name: str = "cmm",
             **options) -> Plan:
    """A machined part measured on a CMM (a cmm file): nominal surface points (n, 3) mm with outward
    unit normals (n, 3), cut by ``program`` with a ball-end tool of ``tool_radius_mm``. ``program``
    is the program's cutting moves (a :class:`~mtcomp.measurement.cut.CutProgram`), read from its
    G-code by :func:`mtcomp.toolpaths.cutter.read_cut_program`: the simulator reads no G-code.
    Extra ``options`` go to the cmm measurement model (``sample_mm``, ``max_gap_mm``, ``tool_mm``)."""
    if not isinstance(program, CutProgram):
        raise TypeError("cmm_plan takes the program's cutting moves, "
                        "mtcomp.toolpaths.cutter.read_cut_program(path, machine), not "
                        f"{type(program).__name__}")
    pts = np.asarray(points_mm, dtype=float)
    nrm = np.asarray(normals, dtype=float)
    nrm = nrm / np.linalg.norm(nrm, axis=1, keepdims=True)
    cols = {"kind": ["cmm"] * len(pts), "x_mm": pts[:, 0], "y_mm": pts[:, 1], "z_mm": pts[:, 2],
            "nx": nrm[:, 0], "ny": nrm[:, 1], "nz": nrm[:, 2]}
    return Plan("cmm", name, cols, ("dn_um",),
                {"cut": program, "tool_radius_mm": float(tool_radius_mm), **options})


def standard_campaign(machine: Machine, n_runs: int = 1, thermal: bool = False) -> list[Plan]:
    """A campaign that determines the base model up to its known equivalences (a straightness
    slope and the matching squareness): for each linear axis a laser set-up of each of its six
    components, a volumetric points grid with two tool lengths, ISO 230-4 circles, and for each rotary
    axis a laser positioning test (plus, with a C axis, the three-sphere test of Tan et al. (2026)).
    ``n_runs`` laser runs per set-up; ``thermal`` adds an 8 h thermal test."""
    plans = []
    for ax in machine.linear_axes:
        a = ax.name
        comps = tuple(f"E{d}{a}" for d in "XYZ") + tuple(f"E{r}{a}" for r in "ABC")
        plans.append(iso230_2_plan(machine, a, components=comps, n_runs=n_runs))
    plans.append(volumetric_points_plan(machine))
    plans.append(ballbar_circles_plan(machine, n_points=72))
    for ax in machine.rotary_axes:
        plans.append(rotary_laser_plan(machine, ax.name, n_runs=n_runs))
    if "C" in machine.axis_names:
        plans.append(three_sphere_plan(machine, angles_deg=np.arange(0.0, 360.0, 30.0), n_runs=n_runs))
    if thermal:
        plans.append(thermal_plan(machine))
    return plans


# ------------------------------------------------------------------------ a campaign for diagnose
#: feeds (mm/min) of the feed runs of :func:`campaign_plans`, and the optic offsets (mm) of its Abbe runs
CAMPAIGN_FEEDS = (1000.0, 3500.0, 6000.0)
CAMPAIGN_ARMS = ((0.0, 0.0, 0.0), (80.0, 120.0, 100.0))


def _irregular_targets(rng_seed: int, lo: float, hi: float, n: int) -> np.ndarray:
    rng = np.random.default_rng(rng_seed)
    base = np.linspace(lo, hi, n)
    jit = rng.uniform(-0.35, 0.35, n) * (hi - lo) / (n - 1)
    jit[[0, -1]] = 0.0
    return np.round(np.sort(base + jit), 3)


def campaign_plans(machine: Machine, size: str = "small") -> list:
    """A realistic campaign for `diagnose` (the demo's, the examples' and the tests'):

    * per linear axis: an ISO 230-2 laser set-up (positioning and the three angular components),
      the positioning at three feeds (``CAMPAIGN_FEEDS``) and two optic offsets (``CAMPAIGN_ARMS``,
      the Abbe arms), and one fine single run with irregular steps (periodic errors);
    * a volumetric points grid with two tool lengths (and rotary angles on a five-axis machine),
      measured at the start, in the middle and at the end of the campaign (drift checks; plans
      'points', 'points_mid', 'points_end');
    * on a five-axis machine: rotary laser runs of each rotary axis (both directions) and the
      three-sphere ball-bar test of C (Tan et al. 2026).

    ``size``: 'small' (tests, about 2,500 readings on xfyz) or 'full' (benchmarks, about 5,000)."""
    small = size == "small"
    n_coarse, n_runs, n_fine = (11, 2, 160) if small else (21, 3, 220)
    plans = []
    for ax in machine.linear_axes:
        a = ax.name
        lo, hi = ax.travel
        m = 0.05 * (hi - lo)
        coarse = _irregular_targets(11 + "XYZ".index(a), lo + m, hi - m, n_coarse)
        fine = _irregular_targets(23 + "XYZ".index(a), lo + m, hi - m, n_fine)
        plans.append(iso230_2_plan(machine, a, coarse, n_runs,
                                       (f"E{a}{a}", f"EA{a}", f"EB{a}", f"EC{a}"),
                                       feed_mm_min=CAMPAIGN_FEEDS[0], name=f"laser_{a.lower()}"))
        for ai, arm in enumerate(CAMPAIGN_ARMS):
            # one set-up per optic offset, its runs at every feed (one laser zero for all feeds)
            parts = [iso230_2_plan(machine, a, coarse, n_runs, (f"E{a}{a}",), optic_mm=arm,
                                       feed_mm_min=feed, dwell_s=1.0) for feed in CAMPAIGN_FEEDS]
            plans.append(merge_plans(parts, f"laser_{a.lower()}_feeds_arm{ai}"))
        plans.append(iso230_2_plan(machine, a, fine, 1, (f"E{a}{a}",), feed_mm_min=CAMPAIGN_FEEDS[0],
                                       dwell_s=1.0, name=f"laser_{a.lower()}_fine"))
    rotary = {a.name: ([0.0, 90.0, 180.0, 270.0] if a.name == "C" else [0.0, 30.0])
              for a in machine.rotary_axes}
    points = volumetric_points_plan(machine, (2, 2, 2) if machine.rotary_axes else (4, 3, 3),
                                        rotary_deg=rotary or None, n_runs=1, name="points")
    plans.insert(0, points)
    plans.insert(len(plans) // 2, replace(points, name="points_mid"))
    for ax in machine.rotary_axes:
        plans.append(rotary_laser_plan(machine, ax.name, n_runs=n_runs + 1,
                                           name=f"rotary_laser_{ax.name.lower()}"))
    if "C" in machine.axis_names:
        plans.append(three_sphere_plan(machine, angles_deg=np.arange(0.0, 360.0, 20.0 if small else 10.0),
                                           n_runs=2, name="three_sphere"))
    # the points grid again in the middle and at the end (runs 2 and 3 of the same file): drift checks
    plans.append(replace(points, name="points_end"))
    return plans


def merge_plans(plans, name: str):
    """One plan made of ``plans`` run one after another (times and run numbers continue)."""
    cols = {}
    t0, run0 = 0.0, 0
    for p in plans:
        p2 = p.shifted(t0)
        runs = np.asarray(p2.columns["run"], dtype=float) + run0
        for k, v in p2.columns.items():
            v = runs if k == "run" else v
            cols.setdefault(k, []).extend(list(v))
        t0 = p2.duration_s + 10.0
        run0 = int(runs.max())
    cols = {k: (np.asarray(v) if not isinstance(v[0], str) else v) for k, v in cols.items()}
    if "seq" in cols:
        cols["seq"] = np.arange(len(cols["seq"]), dtype=float)
    return replace(plans[0], name=name, columns=cols)

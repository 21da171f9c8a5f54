"""Measurement sets built from arrays (no file), their readings replaced, and sets and columns written as CSV.

Each ``make_*`` returns the same object :func:`mtcomp.measurement.files.read_measurements` would return
for a CSV file with those columns (header and cells included, so ``mtcomp predict`` can repeat them).
:func:`with_values` puts readings into a set (e.g. :func:`mtcomp.sim.simulate`'s). :func:`random_campaign`
draws a rich campaign of such sets. Inputs in internal units (mm, rad); cells are written in file
units (um, urad, deg).
"""
from __future__ import annotations

import csv
import dataclasses

import numpy as np

from ..io.atomic import atomic_write
from ..measurement.files import BallbarData, Context, LaserData, MeasurementSet, PointsData, format_cell


def _context(n, dirs=None, feed=None, t=None, run=None) -> Context:
    return Context(feed=np.full(n, np.nan) if feed is None else np.asarray(feed, float),
                   dirs=np.zeros((n, 6), np.int8) if dirs is None else np.asarray(dirs, np.int8),
                   t=np.full(n, np.nan) if t is None else np.asarray(t, float),
                   run=np.full(n, -1, np.int64) if run is None else np.asarray(run, np.int64),
                   spindle_rpm=np.full(n, np.nan), temperatures={})


def _pose_columns(xyz, abc):
    """(abc (n, 3) rad, columns x_mm.. [a_deg..] in file units, names of the rotary columns)."""
    n = len(xyz)
    abc_a = np.zeros((n, 3)) if abc is None else np.asarray(abc, float)
    cols = {"x_mm": xyz[:, 0], "y_mm": xyz[:, 1], "z_mm": xyz[:, 2]}
    rotary = ()
    if abc is not None:
        rotary = ("a_deg", "b_deg", "c_deg")
        for k, name in enumerate(rotary):
            cols[name] = np.degrees(abc_a[:, k])
    return abc_a, cols, rotary


def _cells(columns: dict) -> tuple[tuple[str, ...], tuple[tuple[str, ...], ...]]:
    """(header, rows) of CSV cells for column name -> (n,) values in file units: numbers through
    :func:`format_cell` (NaN and None blank), anything else as text."""
    header = tuple(columns)
    cols = []
    for col in columns.values():
        if isinstance(col, np.ndarray) and col.dtype.kind in "fiu":
            cols.append([format_cell(float(v)) for v in col])
        else:
            cols.append(["" if v is None else format_cell(float(v)) if isinstance(v, (float, np.floating))
                         else str(v) for v in col])
    return header, tuple(zip(*cols)) if cols else ()


def _write_table(path, header, rows) -> None:
    """Write a header and rows of cells as a CSV file (atomically)."""
    with atomic_write(path, newline="") as f:
        writer = csv.writer(f, lineterminator="\n")
        writer.writerow(header)
        writer.writerows(rows)


def write_columns(path, columns: dict) -> None:
    """Write column name -> (n,) values (file units, numbers or text) as a CSV file (atomically)."""
    _write_table(path, *_cells(columns))


def make_points(xyz, abc=None, tool=None, deviation=None, normal=None, normal_deviation=None,
                path: str = "points.csv") -> PointsData:
    """Points set. xyz (n, 3) mm; abc (n, 3) rad or None; tool (n,) mm or None; deviation (n, 3) mm
    (NaN = not measured; default zeros); normal (n, 3) with normal_deviation (n,) mm for dn rows."""
    xyz = np.asarray(xyz, float)
    n = len(xyz)
    dev = np.zeros((n, 3)) if deviation is None else np.asarray(deviation, float)
    abc_a, cols, rotary = _pose_columns(xyz, abc)
    tool_a = np.full(n, np.nan) if tool is None else np.asarray(tool, float) * np.ones(n)
    if tool is not None:
        cols["tool_mm"] = tool_a
    measured = ["dx_um", "dy_um", "dz_um"]
    for k, name in enumerate(measured):
        cols[name] = dev[:, k] * 1e3
    nrm = np.full((n, 3), np.nan) if normal is None else np.asarray(normal, float)
    dn = np.full(n, np.nan)
    if normal is not None:
        dn = np.asarray(normal_deviation, float) if normal_deviation is not None else np.zeros(n)
        for k, name in enumerate(("nx", "ny", "nz")):
            cols[name] = nrm[:, k]
        cols["dn_um"] = dn * 1e3
        measured.append("dn_um")
    header, rows = _cells(cols)
    return PointsData(path=path, header=header, rows=rows, row=np.arange(1, n + 1), context=_context(n),
                      xyz=xyz, abc=abc_a, rotary_columns=rotary, tool=tool_a, deviation=dev,
                      normal_deviation=dn, normal=nrm, measured=tuple(measured))


def make_laser(axis, component, target, direction=None, run=None, static=None, optic=None,
               value=None, path: str = "laser.csv") -> LaserData:
    """Laser set. axis (n,) letters; component (n,) e.g. 'EXX'; target (n,) mm or rad; direction
    (n,) +1/-1 (default +1); run (n,) (default 0); static (n, 6) positions of X Y Z (mm) A B C (rad)
    (NaN or 0 where unused); optic (n, 3) mm; value (n,) mm or rad (default zeros)."""
    axis = np.asarray(axis, dtype="<U1")
    n = len(axis)
    component = np.asarray(component, dtype="<U3")
    target = np.asarray(target, float)
    direction = np.ones(n, np.int8) if direction is None else np.asarray(direction, np.int8)
    run = np.zeros(n, np.int64) if run is None else np.asarray(run, np.int64)
    static = np.zeros((n, 6)) if static is None else np.asarray(static, float)
    optic = np.zeros((n, 3)) if optic is None else np.asarray(optic, float)
    value = np.zeros(n) if value is None else np.asarray(value, float)
    angular = np.array([c[1] in "ABC" for c in component])
    rotary = np.isin(axis, list("ABC"))
    cols = {"axis": axis, "component": component}
    if (~rotary).any():
        cols["target_mm"] = np.where(rotary, np.nan, target)
    if rotary.any():
        cols["target_deg"] = np.where(rotary, np.degrees(target), np.nan)
    cols["dir"] = direction
    cols["run"] = run
    value_columns = []
    if (~angular).any():
        cols["value_um"] = np.where(angular, np.nan, value * 1e3)
        value_columns.append("value_um")
    if angular.any():
        cols["value_urad"] = np.where(angular, value * 1e6, np.nan)
        value_columns.append("value_urad")
    for k, name in enumerate(("x_mm", "y_mm", "z_mm")):
        cols[name] = static[:, k]
    for k, name in enumerate(("a_deg", "b_deg", "c_deg")):
        cols[name] = np.degrees(static[:, 3 + k])
    for k, name in enumerate(("optic_x_mm", "optic_y_mm", "optic_z_mm")):
        cols[name] = optic[:, k]
    header, rows = _cells(cols)
    dirs = np.zeros((n, 6), np.int8)
    for i, a in enumerate(axis):
        dirs[i, "XYZABC".index(a)] = direction[i]
    return LaserData(path=path, header=header, rows=rows, row=np.arange(1, n + 1),
                     context=_context(n, dirs=dirs, run=run), axis=axis, component=component,
                     angular=angular, target=target, dir=direction, run=run, value=value,
                     xyz=static[:, :3].copy(), abc=static[:, 3:].copy(), optic=optic,
                     seq=np.arange(n, dtype=np.int64), value_columns=tuple(value_columns))


def make_ballbar(xyz, table_ball, tool_ball, abc=None, length=None, path: str = "ballbar.csv") -> BallbarData:
    """Ball-bar set. xyz (n, 3) mm; table_ball (n, 3) or (3,) mm; tool_ball (n, 3) or (3,) mm
    (relative to the nominal tool tip); abc (n, 3) rad or None; length (n,) mm (default: nominal)."""
    xyz = np.asarray(xyz, float)
    n = len(xyz)
    tb = np.broadcast_to(np.asarray(table_ball, float), (n, 3)).copy()
    lb = np.broadcast_to(np.asarray(tool_ball, float), (n, 3)).copy()
    abc_a, cols, rotary = _pose_columns(xyz, abc)
    for k, a in enumerate("xyz"):
        cols[f"table_ball_{a}_mm"] = tb[:, k]
    for k, a in enumerate("xyz"):
        cols[f"tool_ball_{a}_mm"] = lb[:, k]
    length = np.zeros(n) if length is None else np.asarray(length, float)
    cols["length_mm"] = length
    header, rows = _cells(cols)
    return BallbarData(path=path, header=header, rows=rows, row=np.arange(1, n + 1), context=_context(n),
                       xyz=xyz, abc=abc_a, rotary_columns=rotary, table_ball=tb, tool_ball=lb,
                       length=length)


def with_values(data: MeasurementSet, values: dict[str, np.ndarray]) -> MeasurementSet:
    """A copy of ``data`` whose measured arrays are replaced (internal units) and whose cells follow.

    values : 'dx_um', 'dy_um', 'dz_um', 'dn_um' (points), 'value' (laser, mm or rad per row),
    'length_mm' (ballbar): (n,) arrays, internal units (mm, rad); NaN keeps a cell blank.
    """
    header = list(data.header)
    rows = [list(r) for r in data.rows]
    changes = {}

    def put(column, arr, scale):
        j = header.index(column)
        for i, v in enumerate(arr):
            rows[i][j] = format_cell(float(v) * scale)

    if data.kind == "points":
        dev = data.deviation.copy()
        for k, col in enumerate(("dx_um", "dy_um", "dz_um")):
            if col in values:
                dev[:, k] = values[col]
                put(col, values[col], 1e3)
        changes["deviation"] = dev
        if "dn_um" in values:
            changes["normal_deviation"] = np.asarray(values["dn_um"], float)
            put("dn_um", values["dn_um"], 1e3)
    elif data.kind == "laser":
        v = np.asarray(values["value"], float)
        changes["value"] = v
        for col, scale, sel in (("value_um", 1e3, ~data.angular), ("value_urad", 1e6, data.angular)):
            if col in header:
                put(col, np.where(sel, v, np.nan), scale)
    elif data.kind == "ballbar":
        changes["length"] = np.asarray(values["length_mm"], float)
        put("length_mm", values["length_mm"], 1.0)
    else:
        raise ValueError(f"with_values does not handle {data.kind} sets")
    changes["rows"] = tuple(tuple(r) for r in rows)
    return dataclasses.replace(data, **changes)


def random_campaign(machine, rng, n_points: int = 300, tool_lengths=(0.0, 100.0, 200.0),
                    laser_offsets: int = 2, laser_steps: int = 9, ballbar_radius: float = 100.0,
                    ballbar_steps: int = 36) -> dict[str, MeasurementSet]:
    """A rich random measurement campaign (readings zero; fill them with :func:`mtcomp.sim.simulate`):

    * ``points``: random poses over the whole work volume (rotary axes too), tool lengths drawn from
      ``tool_lengths``;
    * ``laser``: for every axis every component, each at ``laser_offsets`` set-ups with different
      static positions of the other axes and optic offsets (Abbe arms), ``laser_steps`` targets;
    * ``ballbar``: two circles of ``ballbar_radius`` in each of the XY, XZ and YZ planes, at random
      centres, rotary axes at zero.
    """
    lo, hi = machine.travel_bounds()
    names = machine.axis_names
    na = len(names)
    rot_lo = np.maximum(lo, -np.pi)
    rot_hi = np.minimum(hi, np.pi)
    lo_c = np.where([n in "ABC" for n in names], rot_lo, lo)
    hi_c = np.where([n in "ABC" for n in names], rot_hi, hi)
    q = rng.uniform(lo_c, hi_c, size=(n_points, na))
    xyz, abc = _xyz_abc(names, q)
    rotary = any(n in "ABC" for n in names)
    points = make_points(xyz, abc if rotary else None, tool=rng.choice(np.asarray(tool_lengths), n_points),
                         path="points.csv")
    laser = _random_laser(names, rng, lo_c, hi_c, laser_offsets, laser_steps)
    ballbar = _random_ballbar(names, rng, lo, hi, ballbar_radius, ballbar_steps)
    return {"points": points, "laser": laser, "ballbar": ballbar}


def _xyz_abc(names, qrows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """((n, 3) X, Y, Z mm, (n, 3) A, B, C rad) of axis positions ``qrows`` (n, len(names)); the
    machine's missing axes at zero."""
    xyz = np.zeros((len(qrows), 3))
    abc = np.zeros((len(qrows), 3))
    for k, n in enumerate(names):
        (xyz if n in "XYZ" else abc)[:, "XYZABC".index(n) % 3] = qrows[:, k]
    return xyz, abc


def _random_laser(names, rng, lo_c, hi_c, laser_offsets: int, laser_steps: int) -> MeasurementSet:
    """The laser runs of :func:`random_campaign`."""
    rows = {k: [] for k in ("axis", "component", "target", "direction", "run", "static", "optic")}
    for a_i, a in enumerate(names):
        comps = [f"E{d}{a}" for d in "XYZABC"]
        for setup in range(laser_offsets):
            static = np.zeros(6)
            qs = rng.uniform(lo_c, hi_c) * 0.6
            for k, n in enumerate(names):
                static["XYZABC".index(n)] = qs[k]
            optic = rng.uniform(-150.0, 150.0, 3)
            targets = np.linspace(lo_c[a_i], hi_c[a_i], laser_steps)
            for comp in comps:
                for direction, seq in ((1, targets), (-1, targets[::-1])):
                    for t in seq:
                        rows["axis"].append(a)
                        rows["component"].append(comp)
                        rows["target"].append(t)
                        rows["direction"].append(direction)
                        rows["run"].append(setup)
                        rows["static"].append(static)
                        rows["optic"].append(optic)
    return make_laser(rows["axis"], rows["component"], rows["target"], rows["direction"], rows["run"],
                      np.array(rows["static"]), np.array(rows["optic"]), path="laser.csv")


def _random_ballbar(names, rng, lo, hi, ballbar_radius: float, ballbar_steps: int) -> MeasurementSet:
    """The ball-bar circles of :func:`random_campaign`."""
    na = len(names)
    rotary = any(n in "ABC" for n in names)
    ang = np.linspace(0.0, 2 * np.pi, ballbar_steps, endpoint=False)
    bq, tb = [], []
    for i, j in ((0, 1), (0, 2), (1, 2)):
        for _ in range(2):
            c = np.zeros(na)
            for k, n in enumerate(names):
                if n in "XYZ":
                    c[k] = rng.uniform(lo[k] + ballbar_radius, hi[k] - ballbar_radius)
            ki = [k for k, n in enumerate(names) if n == "XYZ"[i]]
            kj = [k for k, n in enumerate(names) if n == "XYZ"[j]]
            if not ki or not kj:
                continue
            qq = np.tile(c, (ballbar_steps, 1))
            qq[:, ki[0]] += ballbar_radius * np.cos(ang)
            qq[:, kj[0]] += ballbar_radius * np.sin(ang)
            bq.append(qq)
            centre_xyz, _ = _xyz_abc(names, c[None, :])
            tb.append(np.tile(centre_xyz, (ballbar_steps, 1)))
    bq = np.vstack(bq)
    tb = np.vstack(tb)
    bxyz, babc = _xyz_abc(names, bq)
    tool_ball = np.array([0.0, 0.0, 0.0])
    return make_ballbar(bxyz, tb, tool_ball, babc if rotary else None,
                        length=np.linalg.norm(bxyz - tb, axis=1), path="ballbar.csv")


def write_measurements(path, data: MeasurementSet) -> None:
    """Write a measurement set's header and cells as a CSV file (atomically)."""
    _write_table(path, data.header, data.rows)

"""Measurement files (docs/measurements.md): points, laser, ballbar, cmm, thermal, velocity.

:func:`read_measurements` reads one CSV file, tells its kind from its columns and returns one of
:class:`PointsData`, :class:`LaserData`, :class:`BallbarData`, :class:`CmmData`, :class:`ThermalData`,
:class:`VelocityData` (all :class:`MeasurementSet`). Arrays are in internal units: mm, rad, mm/min,
s, degC (files: um -> mm, urad -> rad, deg -> rad on reading). Every set also keeps the original
header and cells (so ``mtcomp predict`` can repeat each input column verbatim), the 1-based data
``row`` of each observation (so later errors can name it) and a :class:`Context` with the optional
context columns. Blank cells mean "not measured" and become NaN.

Bad input raises :class:`mtcomp.errors.InputError` naming the file, the row and the column.
"""
from __future__ import annotations

import dataclasses
import math
import os
import re
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, ClassVar, Iterable

import numpy as np

from ..errors import InputError
from ..machine import AXIS_ORDER, LINEAR, ROTARY, Machine
from ..io.csvtable import CsvTable, parse_ints, parse_signs, read_csv_table
from .columns import check_axis_units, check_columns
from .thermal_checks import check_time_order, check_unit_columns
# the units of the files, and the writing of a file back (also read from here)
from .units import DEG, UM, URAD, file_unit_scale, format_cell, write_csv_with_columns  # noqa: F401

if TYPE_CHECKING:
    from .cut import CutProgram

#: relative tolerance on the length of a unit normal (nx, ny, nz)
NORMAL_TOLERANCE = 1e-3

KINDS = ("points", "laser", "ballbar", "cmm", "thermal", "velocity")

_XYZ = ("x_mm", "y_mm", "z_mm")
_ABC = ("a_deg", "b_deg", "c_deg")
_DXYZ = ("dx_um", "dy_um", "dz_um")
_NORMAL = ("nx", "ny", "nz")
_OPTIC = ("optic_x_mm", "optic_y_mm", "optic_z_mm")
_TABLE_BALL = ("table_ball_x_mm", "table_ball_y_mm", "table_ball_z_mm")
_TOOL_BALL = ("tool_ball_x_mm", "tool_ball_y_mm", "tool_ball_z_mm")
_VELOCITY = ("m_x_mm", "m_y_mm", "m_vx_mm_min", "m_vy_mm_min",
             "n_x_mm", "n_y_mm", "n_vx_mm_min", "n_vy_mm_min")
_DIR_COLUMNS = tuple(f"dir_{a.lower()}" for a in AXIS_ORDER)
_TEMP = re.compile(r"^temp_(.+)_c$")
_DISP = re.compile(r"^disp_(.+)_um$")
_COMPONENT = re.compile(r"^E([XYZABC])([XYZABC])$")

#: what each kind needs, for error messages
REQUIRED = {
    "points": "x_mm,y_mm,z_mm and dx_um/dy_um/dz_um (or dn_um with nx,ny,nz)",
    "laser": "axis,component,target_mm or target_deg,dir,run,value_um or value_urad",
    "ballbar": "x_mm,y_mm,z_mm,table_ball_x_mm,table_ball_y_mm,table_ball_z_mm,tool_ball_x_mm,"
               "tool_ball_y_mm,tool_ball_z_mm,length_mm",
    "cmm": "x_mm,y_mm,z_mm,nx,ny,nz,dn_um",
    "thermal": "t_s and disp_<name>_um",
    "velocity": "axis,feed_mm_min,x_mm/y_mm/z_mm," + ",".join(_VELOCITY),
}


@dataclass(eq=False)
class Context:
    """Context of every observation (struct of arrays, one entry per row; docs/measurements.md).

    feed : (n,) mm/min, NaN when blank or absent.
    dirs : (n, 6) approach direction (+1/-1, 0 when unknown) of axes X Y Z A B C, in that order.
    t : (n,) s since the start of the campaign, NaN when unknown.
    run : (n,) int repeat number, -1 when unknown.
    spindle_rpm : (n,) rev/min, NaN when unknown.
    temperatures : name -> (n,) degC (from ``temp_<name>_c``), NaN where blank.
    """

    feed: np.ndarray
    dirs: np.ndarray
    t: np.ndarray
    run: np.ndarray
    spindle_rpm: np.ndarray
    temperatures: dict[str, np.ndarray] = field(default_factory=dict)

    def dir_of(self, axis: str) -> np.ndarray:
        """(n,) approach direction of ``axis`` ('X'...'C'): +1, -1 or 0 (unknown)."""
        return self.dirs[:, AXIS_ORDER.index(axis)]

    def subset(self, index) -> "Context":
        return _subset(self, index)


@dataclass(eq=False)
class MeasurementSet:
    """What every measurement file gives; subclasses add the arrays of their kind.

    path : the file as given.
    header : (m,) original header cells, verbatim.
    rows : (n,) tuples of m original cells (strings), verbatim.
    row : (n,) int, 1-based data row of each observation in the file (the header is row 0).
    context : the context columns (:class:`Context`).
    """

    kind: ClassVar[str] = ""
    path: str
    header: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]
    row: np.ndarray
    context: Context

    def __len__(self) -> int:
        return len(self.rows)

    @property
    def prediction_columns(self) -> tuple[str, ...]:
        """Names of the ``pred_<column>`` columns ``mtcomp predict`` adds for this file
        (docs/identification.md)."""
        return ()

    def subset(self, index) -> "MeasurementSet":
        """The same set restricted to ``index`` (boolean mask or integer indices), all arrays sliced."""
        return _subset(self, index)

    def fail(self, message: str, index: int | None = None):
        """Raise InputError naming this file and, when ``index`` is given, the row of observation index."""
        raise InputError(message, self.path, row=None if index is None else int(self.row[index]))


class _CommandedPoses:
    """Mixin for kinds with commanded axis positions ``xyz`` (n, 3) mm and ``abc`` (n, 3) rad."""

    xyz: np.ndarray
    abc: np.ndarray
    rotary_columns: tuple[str, ...]

    def axis_positions(self, machine: Machine) -> np.ndarray:
        """(n, na) axis positions q in ``machine.axis_names`` order, mm and rad.

        A rotary axis of the machine whose column (``a_deg``...) is absent from the file is taken at
        0 for every row. A file whose rotary column names an axis the machine lacks is refused unless
        every value in it is 0.
        """
        _check_rotary_columns(self, machine)
        q = np.zeros((len(self.xyz), machine.n_axes))
        for k, name in enumerate(machine.axis_names):
            if name in LINEAR:
                q[:, k] = self.xyz[:, LINEAR.index(name)]
            elif f"{name.lower()}_deg" in self.rotary_columns:
                q[:, k] = self.abc[:, ROTARY.index(name)]
        return q


def _check_rotary_columns(data, machine: Machine) -> None:
    for col in data.rotary_columns:
        letter = col[0].upper()
        if letter not in machine.axis_names:
            vals = data.abc[:, ROTARY.index(letter)]
            bad = np.flatnonzero(np.nan_to_num(vals) != 0.0)
            if bad.size:
                data.fail(f"column {col}: machine {machine.name!r} ({machine.topology}) has no "
                          f"{letter} axis", bad[0])


@dataclass(eq=False)
class PointsData(_CommandedPoses, MeasurementSet):
    """Deviations at commanded poses (a points file, docs/measurements.md).

    xyz : (n, 3) mm commanded linear axis positions (nominal tool-tip position).
    abc : (n, 3) rad commanded A, B, C positions; 0 where the column is absent.
    rotary_columns : which of ``a_deg, b_deg, c_deg`` the file has.
    tool : (n,) mm tool length of each row, NaN where not given (use the machine's).
    deviation : (n, 3) mm measured deviation dx, dy, dz (workpiece frame), NaN where not measured.
    normal_deviation : (n,) mm measured deviation along ``normal`` (dn), NaN where not measured.
    normal : (n, 3) unit normal for ``normal_deviation``, NaN where not given.
    measured : which of ``dx_um, dy_um, dz_um, dn_um`` the file has.
    """

    kind: ClassVar[str] = "points"
    xyz: np.ndarray = None
    abc: np.ndarray = None
    rotary_columns: tuple[str, ...] = ()
    tool: np.ndarray = None
    deviation: np.ndarray = None
    normal_deviation: np.ndarray = None
    normal: np.ndarray = None
    measured: tuple[str, ...] = ()

    @property
    def prediction_columns(self) -> tuple[str, ...]:
        cols = ["pred_dx_um", "pred_dy_um", "pred_dz_um"]
        if "dn_um" in self.measured:
            cols.append("pred_dn_um")
        return tuple(cols)

    def tool_lengths(self, machine: Machine) -> np.ndarray:
        """(n,) mm tool length per row: ``tool_mm`` where given, else the machine's."""
        return np.where(np.isnan(self.tool), machine.tool_length, self.tool)


@dataclass(eq=False)
class LaserData(MeasurementSet):
    """Interferometer runs along one axis (a laser file, docs/measurements.md).

    axis : (n,) str, the moving axis of each row ('X'...'C').
    component : (n,) str, ISO 230-1 component (``E<dir><axis>``: EXX, EYX, ..., ECC).
    angular : (n,) bool, True for angular components (EA?, EB?, EC?), read from ``value_urad``.
    target : (n,) position of the moving axis, mm (linear) or rad (rotary).
    dir : (n,) int8 approach direction +1/-1.
    run : (n,) int run number.
    value : (n,) measured value, mm (translational) or rad (angular), NaN where blank.
    xyz : (n, 3) mm static positions x, y, z, NaN where absent or blank.
    abc : (n, 3) rad static positions a, b, c, NaN where absent or blank.
    optic : (n, 3) mm position of the measured point relative to the tool tip (Abbe arm); 0 where
        absent or blank.
    seq : (n,) int reading order; the file order (0, 1, ...) when the column is absent.
    """

    kind: ClassVar[str] = "laser"
    axis: np.ndarray = None
    component: np.ndarray = None
    angular: np.ndarray = None
    target: np.ndarray = None
    dir: np.ndarray = None
    run: np.ndarray = None
    value: np.ndarray = None
    xyz: np.ndarray = None
    abc: np.ndarray = None
    optic: np.ndarray = None
    seq: np.ndarray = None
    value_columns: tuple[str, ...] = ()

    @property
    def prediction_columns(self) -> tuple[str, ...]:
        return tuple(f"pred_{c}" for c in self.value_columns)

    def axis_positions(self, machine: Machine) -> np.ndarray:
        """(n, na) q in ``machine.axis_names`` order, mm and rad: the moving axis at ``target``, the
        others at their static columns (0 where absent or blank).

        InputError when a row moves, or a static column sets, an axis the machine lacks.
        """
        q = np.zeros((len(self), machine.n_axes))
        for i in np.flatnonzero(~np.isin(self.axis, machine.axis_names)):
            self.fail(f"axis {self.axis[i]}: machine {machine.name!r} ({machine.topology}) has no such "
                      "axis", i)
        for letter in ROTARY:
            if letter not in machine.axis_names:
                bad = np.flatnonzero(np.nan_to_num(self.abc[:, ROTARY.index(letter)]) != 0.0)
                if bad.size:
                    self.fail(f"column {letter.lower()}_deg: machine {machine.name!r} "
                              f"({machine.topology}) has no {letter} axis", bad[0])
        for k, name in enumerate(machine.axis_names):
            q[:, k] = np.where(self.axis == name, self.target, np.nan_to_num(self._static(name)))
        return q

    def positions_given(self, machine) -> np.ndarray:
        """(n, n_axes) bool: the file gives that axis's position in that row (the moving axis's
        target, or a static position column); the others are taken as 0 by :meth:`axis_positions`."""
        return np.column_stack([(self.axis == name) | np.isfinite(self._static(name))
                                for name in machine.axis_names])

    def _static(self, name: str) -> np.ndarray:
        """(n,) the static position column of axis ``name`` (NaN where absent or blank)."""
        return self.xyz[:, LINEAR.index(name)] if name in LINEAR else self.abc[:, ROTARY.index(name)]


@dataclass(eq=False)
class BallbarData(_CommandedPoses, MeasurementSet):
    """Ball-bar length readings (a ballbar file, docs/measurements.md).

    xyz : (n, 3) mm commanded linear axis positions; abc : (n, 3) rad rotary positions (0 if absent).
    table_ball : (n, 3) mm centre of the table ball, workpiece frame.
    tool_ball : (n, 3) mm centre of the tool ball relative to the nominal tool tip.
    length : (n,) mm measured centre distance, NaN where not measured.
    """

    kind: ClassVar[str] = "ballbar"
    xyz: np.ndarray = None
    abc: np.ndarray = None
    rotary_columns: tuple[str, ...] = ()
    table_ball: np.ndarray = None
    tool_ball: np.ndarray = None
    length: np.ndarray = None

    @property
    def prediction_columns(self) -> tuple[str, ...]:
        return ("pred_length_mm",)


@dataclass(eq=False)
class CmmData(MeasurementSet):
    """A machined part measured on a CMM (a cmm file, docs/measurements.md).

    xyz : (n, 3) mm nominal surface point, workpiece frame.
    normal : (n, 3) outward unit normal.
    normal_deviation : (n,) mm deviation along the normal (positive: material outside), NaN if blank.
    cut, tool_radius_mm : the cutting moves of the G-code that cut the part
        (:class:`~mtcomp.measurement.cut.CutProgram`, already read from the program) and the radius
        of its ball-end tool (mm); not in the file (docs/measurements.md): the commands read them
        from ``--cmm-program`` and ``--cmm-tool-radius`` (:func:`mtcomp.commands.attach_cmm_cuts`).
    include_path_offset : ``--cmm-path-offset``: the program's ball centres are not on the nominal
        surface's offset (a compensated program): their offset along the normal is part of what it cut.
    """

    kind: ClassVar[str] = "cmm"
    xyz: np.ndarray = None
    normal: np.ndarray = None
    normal_deviation: np.ndarray = None
    cut: CutProgram | None = None
    tool_radius_mm: float | None = None
    #: the program's own offset from the nominal surface counts (a compensated program's corrections)
    include_path_offset: bool = False

    @property
    def prediction_columns(self) -> tuple[str, ...]:
        return ("pred_dn_um",)

    def axis_positions(self, machine: Machine) -> np.ndarray:
        """(n, na) mm and rad: the pose of the program's moves ``cut`` that cut each surface point
        (its ball centre nearest to ``x + r n``), so that the part counts where the model's knots go
        and what the data cover. InputError when the program or the radius is not given."""
        if self.cut is None or self.tool_radius_mm is None:
            raise InputError("a cmm file needs the G-code that cut the part and the radius of its "
                             "ball-end tool: give --cmm-program and --cmm-tool-radius", self.path)
        from .cut import cut_poses
        return cut_poses(machine, self, self.cut, float(self.tool_radius_mm))[0]


@dataclass(eq=False)
class ThermalData(MeasurementSet):
    """Drift of a fixed set-up over time (a thermal file, docs/measurements.md).

    t : (n,) s since the start (also ``context.t``).
    channels : name -> (n,) mm displacement of channel ``disp_<name>_um``, NaN where blank.
    Spindle speed and temperatures are in ``context``.
    """

    kind: ClassVar[str] = "thermal"
    t: np.ndarray = None
    channels: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def prediction_columns(self) -> tuple[str, ...]:
        return tuple(f"pred_disp_{name}_um" for name in self.channels)


@dataclass(eq=False)
class VelocityData(MeasurementSet):
    """Two-point velocities of a moving table (a velocity file, docs/measurements.md; Yang et al.
    (2020), eq. 1).

    axis : (n,) str moving axis ('X' or 'Y').
    feed : (n,) mm/min commanded feed (also ``context.feed``).
    position : (n,) mm position of the moving axis at the reading.
    m_xy, n_xy : (n, 2) mm coordinates of the points M and N in the table plane.
    m_v, n_v : (n, 2) mm/min measured velocity components of M and N in the axis's own sense, NaN
        where not measured (a file in the bed's sense is negated on reading: ``bed_sense``).
    """

    kind: ClassVar[str] = "velocity"
    axis: np.ndarray = None
    feed: np.ndarray = None
    position: np.ndarray = None
    m_xy: np.ndarray = None
    m_v: np.ndarray = None
    n_xy: np.ndarray = None
    n_v: np.ndarray = None
    #: the file read the table's own motion (the bed's sense): its velocities were negated on reading
    bed_sense: bool = False

    @property
    def prediction_columns(self) -> tuple[str, ...]:
        return tuple(f"pred_{c}" for c in ("m_vx_mm_min", "m_vy_mm_min", "n_vx_mm_min", "n_vy_mm_min"))

    def signed_speed(self) -> np.ndarray:
        """(n,) mm/min the table's speed along its axis, in the axis's own sense: the feed signed by
        ``dir_<axis>``, or where that is blank by the sum of the measured velocities along the axis."""
        out = np.empty(len(self))
        for i, a in enumerate(self.axis):
            sign = float(self.context.dir_of(a)[i])
            if sign == 0.0:
                k = "XY".index(a)
                sign = -1.0 if np.nansum([self.m_v[i, k], self.n_v[i, k]]) < 0 else 1.0
            out[i] = sign * self.feed[i]
        return out

    def axis_positions(self, machine: Machine) -> np.ndarray:
        """(n, na) q in ``machine.axis_names`` order, mm: the moving axis at ``position``, NaN for the
        others (the file does not give them: they neither place knots nor widen what the data cover).
        Velocities follow the errors' slopes along the moving axis, so its positions count where the
        model's knots go and what the data cover."""
        q = np.full((len(self), machine.n_axes), np.nan)
        bad = np.flatnonzero(~np.isin(self.axis, machine.axis_names))
        if bad.size:
            self.fail(f"axis {self.axis[bad[0]]}: machine {machine.name!r} ({machine.topology}) has no "
                      "such axis", bad[0])
        for k, name in enumerate(machine.axis_names):
            q[self.axis == name, k] = self.position[self.axis == name]
        return q

    def positions_given(self, machine: Machine) -> np.ndarray:
        """(n, n_axes) bool: only the moving axis's position is given."""
        return np.column_stack([self.axis == name for name in machine.axis_names])

    def rotation_centre(self) -> np.ndarray:
        """(n, 2) mm instantaneous rotation centre O_p in the table plane (Yang et al. (2020),
        eq. 1).

        O_p lies on the line through M perpendicular to M's velocity relative to the table's
        translation V0 (feed, signed by ``dir_<axis>`` or else by the measured motion), and likewise
        for N: ``(v_M - V0 e) . (O_p - M) = 0``, ``(v_N - V0 e) . (O_p - N) = 0``. For axis X this is
        eq. 1 of Yang et al. (2020). NaN where the two lines are parallel.
        """
        out = np.full((len(self), 2), np.nan)
        speed = self.signed_speed()
        for i in range(len(self)):
            k = "XY".index(self.axis[i])
            v0 = np.zeros(2)
            v0[k] = speed[i]
            u = np.array([self.m_v[i] - v0, self.n_v[i] - v0])
            rhs = np.array([u[0] @ self.m_xy[i], u[1] @ self.n_xy[i]])
            if not np.all(np.isfinite(u)) or abs(np.linalg.det(u)) <= 1e-12 * np.abs(u).max() ** 2:
                continue
            out[i] = np.linalg.solve(u, rhs)
        return out


_CLASSES = {c.kind: c for c in (PointsData, LaserData, BallbarData, CmmData, ThermalData, VelocityData)}


# --------------------------------------------------------------------------------------------------
# reading

def read_measurements(path: str | os.PathLike, kind: str | None = None) -> MeasurementSet:
    """Read one measurement file (docs/measurements.md); its kind is told by its columns.

    path : a CSV file with a header row.
    kind : force one of :data:`KINDS`; only needed for a file with just ``x_mm,y_mm,z_mm,nx,ny,nz,
        dn_um``, which is both a cmm and a points file (a column ``kind`` whose cells all say
        ``points`` or ``cmm`` does the same from the file).
    Returns a :class:`PointsData`, :class:`LaserData`, :class:`BallbarData`, :class:`CmmData`,
    :class:`ThermalData` or :class:`VelocityData`. Raises InputError for a malformed file.
    """
    table = read_csv_table(path)
    check_axis_units(table)
    check_unit_columns(table)
    if kind is None:
        kind = detect_kind(table)
    elif kind not in KINDS:
        raise InputError(f"unknown measurement kind {kind!r} (known: {', '.join(KINDS)})", table.path)
    check_columns(table, kind)
    context = _read_context(table)
    return _READERS[kind](table, context)


def detect_kind(table: CsvTable) -> str:
    """The kind of a table from its columns; InputError when unknown or ambiguous."""
    names = set(table.names)
    if "kind" in names:
        values = {c.lower() for c in table.cells("kind")}
        if len(values) != 1 or not values <= set(KINDS):
            i = next(i for i, c in enumerate(table.cells("kind")) if c.lower() not in KINDS
                     or c.lower() != table.cells("kind")[0].lower())
            table.fail(f"column kind must name one kind ({', '.join(KINDS)}) in every row", i)
        return values.pop()
    signs = {
        "laser": names & {"component", "value_um", "value_urad", "target_mm", "target_deg"},
        "velocity": names & set(_VELOCITY),
        "ballbar": names & ({"length_mm"} | set(_TABLE_BALL) | set(_TOOL_BALL)),
        "thermal": {n for n in names if _DISP.match(n)},
        "points": names & set(_DXYZ),
    }
    found = [k for k, v in signs.items() if v]
    if not found and "dn_um" in names:
        if names & (set(_ABC) | {"tool_mm"}):
            found = ["points"]
        else:
            table.fail("ambiguous kind: columns x_mm,y_mm,z_mm,nx,ny,nz,dn_um fit both a cmm file and "
                       "a points file; add a column 'kind' saying cmm or points")
    if len(found) == 1:
        return found[0]
    expected = "; ".join(f"{k}: {v}" for k, v in REQUIRED.items())
    if not found:
        table.fail(f"unknown kind of measurement file: its columns fit none of the kinds "
                   f"(expected {expected})")
    clues = ", ".join(f"{k} ({', '.join(sorted(signs[k]))})" for k in found)
    table.fail(f"ambiguous kind: columns of several kinds: {clues}; expected {expected}")


def _require(table: CsvTable, kind: str, columns: Iterable[str]) -> None:
    for col in columns:
        if not table.has(col):
            table.fail(f"missing column {col} (a {kind} file needs {REQUIRED[kind]})")


def _vector(table: CsvTable, columns, required: bool, scale: float = 1.0, fill=math.nan) -> np.ndarray:
    """(n, len(columns)) from the given columns; absent columns give ``fill``."""
    cols = [table.floats(c, required=required, scale=scale) if table.has(c)
            else np.full(len(table.rows), fill) for c in columns]
    return np.stack(cols, axis=1)


def _read_context(table: CsvTable) -> Context:
    n = len(table.rows)
    dirs = np.zeros((n, 6), dtype=np.int8)
    for k, col in enumerate(_DIR_COLUMNS):
        if table.has(col):
            dirs[:, k] = parse_signs(table.cells(col), col, table.path, table.row)
    run = (parse_ints(table.cells("run"), "run", table.path, table.row, blank=-1, minimum=0)
           if table.has("run") else np.full(n, -1, dtype=np.int64))
    temps = {}
    for name in table.names:
        m = _TEMP.match(name)
        if m:
            temps[m.group(1)] = table.floats(name)
    feed = table.optional_floats("feed_mm_min")
    bad = np.flatnonzero(feed < 0)                      # blank (NaN) is allowed: no feed known
    if bad.size:
        table.fail("column feed_mm_min must not be negative (a feed is a speed: the approach "
                   "direction goes in dir)", bad[0])
    return Context(feed=feed, dirs=dirs, t=table.optional_floats("t_s"),
                   run=run, spindle_rpm=table.optional_floats("spindle_rpm"), temperatures=temps)


def _base(table: CsvTable, context: Context) -> dict:
    return dict(path=table.path, header=table.header, rows=table.rows, row=table.row, context=context)


def _check_normals(table: CsvTable, normal: np.ndarray, needed: np.ndarray) -> None:
    """Normals must be given where ``needed`` and of unit length wherever given."""
    given = np.all(np.isfinite(normal), axis=1)
    missing = np.flatnonzero(needed & ~given)
    if missing.size:
        table.fail("dn_um is given but the normal nx,ny,nz is blank", missing[0])
    partial = np.flatnonzero(~given & np.any(np.isfinite(normal), axis=1))
    if partial.size:
        table.fail("normal nx,ny,nz is only partly given", partial[0])
    length = np.linalg.norm(np.where(given[:, None], normal, 0.0), axis=1)
    bad = np.flatnonzero(given & (np.abs(length - 1.0) > NORMAL_TOLERANCE))
    if bad.size:
        table.fail(f"normal nx,ny,nz has length {length[bad[0]]:.6g}, not 1 (tolerance "
                   f"{NORMAL_TOLERANCE:g})", bad[0])


def _rotary_positions(table: CsvTable) -> tuple[np.ndarray, tuple[str, ...]]:
    present = tuple(c for c in _ABC if table.has(c))
    return _vector(table, _ABC, required=True, scale=DEG, fill=0.0), present


def _read_points(table: CsvTable, context: Context) -> PointsData:
    _require(table, "points", _XYZ)
    measured = tuple(c for c in (*_DXYZ, "dn_um") if table.has(c))
    if not measured:
        table.fail(f"missing column dx_um, dy_um, dz_um or dn_um (a points file needs "
                   f"{REQUIRED['points']})")
    n = len(table.rows)
    dn = table.optional_floats("dn_um", scale=UM)
    if table.has("dn_um"):
        _require(table, "points", _NORMAL)
    normal = _vector(table, _NORMAL, required=False)
    _check_normals(table, normal, np.isfinite(dn))
    abc, present = _rotary_positions(table)
    return PointsData(**_base(table, context), xyz=_vector(table, _XYZ, required=True), abc=abc,
                      rotary_columns=present, tool=table.optional_floats("tool_mm"),
                      deviation=_vector(table, _DXYZ, required=False, scale=UM),
                      normal_deviation=dn if table.has("dn_um") else np.full(n, np.nan),
                      normal=normal, measured=measured)


def _read_cmm(table: CsvTable, context: Context) -> CmmData:
    _require(table, "cmm", (*_XYZ, *_NORMAL, "dn_um"))
    normal = _vector(table, _NORMAL, required=True)
    _check_normals(table, normal, np.ones(len(table.rows), dtype=bool))
    return CmmData(**_base(table, context), xyz=_vector(table, _XYZ, required=True), normal=normal,
                   normal_deviation=table.floats("dn_um", scale=UM))


def _read_ballbar(table: CsvTable, context: Context) -> BallbarData:
    _require(table, "ballbar", (*_XYZ, *_TABLE_BALL, *_TOOL_BALL, "length_mm"))
    abc, present = _rotary_positions(table)
    return BallbarData(**_base(table, context), xyz=_vector(table, _XYZ, required=True), abc=abc,
                       rotary_columns=present,
                       table_ball=_vector(table, _TABLE_BALL, required=True),
                       tool_ball=_vector(table, _TOOL_BALL, required=True),
                       length=table.floats("length_mm"))


def _read_thermal(table: CsvTable, context: Context) -> ThermalData:
    _require(table, "thermal", ("t_s",))
    channels = {}
    for name in table.names:
        m = _DISP.match(name)
        if m:
            channels[m.group(1)] = table.floats(name, scale=UM)
    if not channels:
        table.fail(f"missing column disp_<name>_um (a thermal file needs {REQUIRED['thermal']})")
    t = table.floats("t_s", required=True)
    check_time_order(table, t)
    context.t = t
    return ThermalData(**_base(table, context), t=t, channels=channels)


def _axis_letters(table: CsvTable, allowed: str) -> np.ndarray:
    cells = [c.upper() for c in table.cells("axis")]
    for i, c in enumerate(cells):
        if len(c) != 1 or c not in allowed:
            if not c:
                table.fail("column axis is blank; a value is required", i)
            table.fail(f"column axis: {c!r} is not an axis (expected one of {', '.join(allowed)})", i)
    return np.asarray(cells, dtype="<U1")


#: a velocity along the moving axis further than this share of the feed from the signed feed is
#: refused (a real table's differs by parts per million)
VELOCITY_TOLERANCE = 0.1


def _read_velocity(table: CsvTable, context: Context) -> VelocityData:
    _require(table, "velocity", ("axis", "feed_mm_min", *_VELOCITY))
    axis = _axis_letters(table, LINEAR)
    other = np.flatnonzero(~np.isin(axis, ["X", "Y"]))
    if other.size:
        table.fail(f"column axis: {axis[other[0]]}: a velocity file's table moves along X or Y (the "
                   "velocities are read in the table plane XY)", other[0])
    position = np.full(len(axis), np.nan)
    for k, letter in enumerate("XY"):
        rows = axis == letter
        if rows.any():
            col = _XYZ[k]
            if not table.has(col):
                table.fail(f"missing column {col} (position of moving axis {letter})",
                           int(np.flatnonzero(rows)[0]))
            vals = table.floats(col)
            blank = np.flatnonzero(rows & np.isnan(vals))
            if blank.size:
                table.fail(f"column {col} is blank; the position of moving axis {letter} is required",
                           blank[0])
            position[rows] = vals[rows]
    feed = table.floats("feed_mm_min", required=True)
    bad = np.flatnonzero(feed <= 0)
    if bad.size:
        table.fail("column feed_mm_min must be positive", bad[0])
    context.feed = feed
    v = {c: table.floats(c, required=c.endswith("_mm")) for c in _VELOCITY}
    data = VelocityData(**_base(table, context), axis=axis, feed=feed, position=position,
                        m_xy=np.stack([v["m_x_mm"], v["m_y_mm"]], 1),
                        m_v=np.stack([v["m_vx_mm_min"], v["m_vy_mm_min"]], 1),
                        n_xy=np.stack([v["n_x_mm"], v["n_y_mm"]], 1),
                        n_v=np.stack([v["n_vx_mm_min"], v["n_vy_mm_min"]], 1))
    # a table axis's velocities read in the bed's sense (the table's own motion, the other way, ISO
    # 841): every reading along the axis is minus the signed feed. Eq. 1 and the model take the axis's
    # own sense; minus every velocity is that, and leaves the rotation centre where it is
    dirs = np.array([context.dir_of(a)[i] for i, a in enumerate(axis)])
    along = np.array([[data.m_v[i, "XY".index(a)], data.n_v[i, "XY".index(a)]] for i, a in enumerate(axis)])
    given = np.isfinite(along)
    if (dirs != 0).all() and given.any() and np.all(
            np.abs(along + (dirs * feed)[:, None])[given] <= VELOCITY_TOLERANCE * np.broadcast_to(feed[:, None], along.shape)[given]):
        data.m_v, data.n_v = -data.m_v, -data.n_v
        data.bed_sense = True
    # the table moves along its axis at the feed: a velocity along the axis far from it is a reading
    # of another axis, a unit slip, a sign against dir_<axis>, or a file that mixes the two senses
    speed = data.signed_speed()
    for i, a in enumerate(axis):
        k = "XY".index(a)
        for point, vel in (("m", data.m_v), ("n", data.n_v)):
            along = vel[i, k]
            if np.isfinite(along) and abs(along - speed[i]) > VELOCITY_TOLERANCE * feed[i]:
                table.fail(f"column {point}_v{a.lower()}_mm_min: {along:g} mm/min, but the table moves "
                           f"along {a} at {speed[i]:g} mm/min in the axis's own sense (feed_mm_min"
                           + (f" and dir_{a.lower()}" if context.dir_of(a)[i] else ", signed by the "
                              "velocities") + f"); more than {VELOCITY_TOLERANCE:.0%} off the feed is "
                           "not a table point's velocity", i)
    return data


def _read_laser(table: CsvTable, context: Context) -> LaserData:
    _require(table, "laser", ("axis", "component", "dir", "run"))
    if not (table.has("target_mm") or table.has("target_deg")):
        table.fail(f"missing column target_mm or target_deg (a laser file needs {REQUIRED['laser']})")
    value_columns = tuple(c for c in ("value_um", "value_urad") if table.has(c))
    if not value_columns:
        table.fail(f"missing column value_um or value_urad (a laser file needs {REQUIRED['laser']})")
    n = len(table.rows)
    axis = _axis_letters(table, AXIS_ORDER)
    component = np.asarray([c.upper() for c in table.cells("component")], dtype="<U3")
    for i, comp in enumerate(component):
        m = _COMPONENT.match(comp)
        if not m:
            table.fail(f"column component: {table.cells('component')[i]!r} is not an ISO 230-1 "
                       "component error (E<direction><axis>, e.g. EXX, EYX, ECC)", i)
        if m.group(2) != axis[i]:
            table.fail(f"column component: {comp} is an error of axis {m.group(2)}, but this row moves "
                       f"axis {axis[i]}", i)
    angular = np.asarray([c[1] in ROTARY for c in component], dtype=bool)
    rotary = np.isin(axis, list(ROTARY))

    target = np.full(n, np.nan)
    for col, rows, scale in (("target_mm", ~rotary, 1.0), ("target_deg", rotary, DEG)):
        if not rows.any():
            continue
        if not table.has(col):
            table.fail(f"missing column {col} (target of a {'rotary' if scale != 1.0 else 'linear'} "
                       "axis)", int(np.flatnonzero(rows)[0]))
        vals = table.floats(col, scale=scale)
        blank = np.flatnonzero(rows & np.isnan(vals))
        if blank.size:
            table.fail(f"column {col} is blank; a value is required", blank[0])
        target[rows] = vals[rows]

    um = table.optional_floats("value_um", scale=UM)
    urad = table.optional_floats("value_urad", scale=URAD)
    mixed = np.flatnonzero((angular & np.isfinite(um)) | (~angular & np.isfinite(urad)))
    if mixed.size:
        i = mixed[0]
        want, got = ("value_urad", "value_um") if angular[i] else ("value_um", "value_urad")
        table.fail(f"units mixed: component {component[i]} is "
                   f"{'angular' if angular[i] else 'translational'} and takes {want}, but {got} is "
                   "given", i)
    value = np.where(angular, urad, um)

    direction = parse_signs(table.cells("dir"), "dir", table.path, table.row, required=True)
    run = parse_ints(table.cells("run"), "run", table.path, table.row, minimum=0)
    for k, letter in enumerate(AXIS_ORDER):  # `dir` is the approach direction of the moving axis
        rows = (axis == letter) & (context.dirs[:, k] == 0)
        context.dirs[rows, k] = direction[rows]
    seq = (parse_ints(table.cells("seq"), "seq", table.path, table.row) if table.has("seq")
           else np.arange(n, dtype=np.int64))
    return LaserData(**_base(table, context), axis=axis, component=component, angular=angular,
                     target=target, dir=direction, run=run, value=value,
                     xyz=_vector(table, _XYZ, required=False),
                     abc=_vector(table, _ABC, required=False, scale=DEG),
                     optic=np.nan_to_num(_vector(table, _OPTIC, required=False, fill=0.0)),
                     seq=seq, value_columns=value_columns)


_READERS = {"points": _read_points, "laser": _read_laser, "ballbar": _read_ballbar, "cmm": _read_cmm,
            "thermal": _read_thermal, "velocity": _read_velocity}


# --------------------------------------------------------------------------------------------------
# subsets and runs

def _subset(obj, index):
    n = len(obj.row) if isinstance(obj, MeasurementSet) else len(obj.feed)
    idx = np.arange(n)[index]
    changes = {}
    for f in dataclasses.fields(obj):
        v = getattr(obj, f.name)
        if isinstance(v, np.ndarray) and v.ndim >= 1 and v.shape[0] == n:
            changes[f.name] = v[idx]
        elif isinstance(v, dict) and all(isinstance(a, np.ndarray) for a in v.values()):
            changes[f.name] = {k: a[idx] for k, a in v.items()}
        elif isinstance(v, Context):
            changes[f.name] = v.subset(idx)
        elif f.name == "rows":
            changes[f.name] = tuple(v[i] for i in idx)
    return dataclasses.replace(obj, **changes)


def group_runs(data: MeasurementSet) -> dict[int, MeasurementSet]:
    """Split ``data`` by its ``run`` column: run number -> subset, in increasing run order.

    Rows without a run number (blank cell or no column) are grouped under -1.
    """
    run = data.context.run
    return {int(r): data.subset(run == r) for r in np.unique(run)}


def split_runs(data: MeasurementSet, held_out: Iterable[int]) -> tuple[MeasurementSet, MeasurementSet]:
    """(fit part, held-out part): rows whose run is in ``held_out`` go to the second set."""
    mask = np.isin(data.context.run, np.asarray(list(held_out), dtype=np.int64))
    return data.subset(~mask), data.subset(mask)

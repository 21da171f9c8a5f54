"""Machine descriptions: topology, axes, travel, rotary axis lines (docs/machines.md).

A :class:`Machine` is a frozen description. Algorithms take it as an argument and never change it.
Internal units: mm and rad. The TOML file uses mm and deg.

Conventions (see docs/conventions.md):

* ``q``, the axis-position vector, lists the machine's axes in the fixed order X, Y, Z, A, B, C
  (only those present): ``machine.axis_names``.
* A linear axis at position ``s`` moves the tool by ``+s`` along its direction *relative to the
  workpiece*, whichever side of the bed it sits on (a table axis moves the table by ``-s``, as ISO 841
  prescribes for primed axes). A rotary axis at angle ``theta`` rotates its carrier by ``+theta``
  (right-hand rule) about its direction (A about X, B about Y, C about Z): a workpiece-side rotary axis
  turns the table, a tool-side one turns the head.
* With every axis at zero, the workpiece frame coincides with the machine frame and the tool tip sits
  at the origin; the spindle gauge point is ``tool_length`` above the tip along +Z.
"""
from __future__ import annotations

import math
import os
import re
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np

from .errors import InputError

LINEAR = "XYZ"
ROTARY = "ABC"
AXIS_ORDER = "XYZABC"
#: unit direction of each axis letter (A rotates about X, B about Y, C about Z)
AXIS_DIRECTION = {"X": 0, "Y": 1, "Z": 2, "A": 0, "B": 1, "C": 2}

BUILTIN_MACHINES = ("xfyz", "cafxyz", "cbfxyz")

#: knot intervals of a spline axis when neither the machine file nor the data choose them
DEFAULT_SPLINE_INTERVALS = 8
BASES = ("bspline", "polynomial")

DEFAULT_COMPENSATION = {"max_correction_um": 50.0, "max_correction_urad": 500.0, "max_step_um": 5.0}


class TravelError(InputError):
    """A position outside an axis's travel (an InputError: one line, exit status 2); ``axis``: the
    axis's name."""

    def __init__(self, message: str, path=None, line=None, row=None, axis: str | None = None):
        self.axis = axis
        super().__init__(message, path, line, row)


@dataclass(frozen=True)
class Axis:
    """One machine axis.

    name : 'X', 'Y', 'Z', 'A', 'B' or 'C'.
    side : 'workpiece' (between bed and workpiece) or 'tool' (between bed and tool).
    travel : (lower, upper) in mm (linear) or rad (rotary).
    axis_point : (3,) mm, a point of the nominal rotary axis line, machine frame, all axes at zero.
    basis : 'bspline' (default) or 'polynomial': the functions of the six component errors of a
        linear axis (mtcomp.models.basis, :func:`~mtcomp.models.basis.axis_spline`).
    degree : degree of those splines (1..3) or polynomials.
    spline_range : (lo, hi) mm that the spline knots span; None: chosen from the data by identify
        (:func:`mtcomp.models.basis.with_data_basis`), the travel until then.
    spline_intervals : number of equal knot intervals; None: chosen from the data (8 until then).
    fourier_order : harmonics of the angular positioning error of a rotary axis.
    fourier_from_data : the machine file leaves ``fourier_order`` open: identification sets it from
        the number of distinct angles in the data (:func:`mtcomp.models.basis.with_data_basis`).
    error_motion_order : harmonics of the radial, axial and tilt error motions of a rotary axis
        (0: none, the base model).
    """

    name: str
    side: str
    travel: tuple[float, float]
    axis_point: tuple[float, float, float] = (0.0, 0.0, 0.0)
    degree: int = 3
    fourier_order: int = 2
    error_motion_order: int = 0
    basis: str = "bspline"
    spline_range: tuple[float, float] | None = None
    spline_intervals: int | None = None
    fourier_from_data: bool = False

    @property
    def basis_from_data(self) -> bool:
        """True when identification chooses the spline knots from the data."""
        return self.basis == "bspline" and (self.spline_range is None or self.spline_intervals is None)

    @property
    def is_rotary(self) -> bool:
        return self.name in ROTARY

    @property
    def direction_index(self) -> int:
        """0, 1 or 2: the machine-frame direction the axis moves along or turns about."""
        return AXIS_DIRECTION[self.name]

    @property
    def direction(self) -> np.ndarray:
        e = np.zeros(3)
        e[self.direction_index] = 1.0
        return e


@dataclass(frozen=True)
class Machine:
    """A machine tool: topology, axes and compensation defaults.

    topology : e.g. 'XFYZ', 'CAFXYZ' (docs/conventions.md).
    axes : every axis, in the q order X Y Z A B C.
    workpiece_chain : axis names from the bed towards the workpiece.
    tool_chain : axis names from the bed towards the tool.
    tool_length : mm, spindle gauge point to tool tip.
    units : 'mm' or 'inch': what a program without G20/G21 means on this machine; None: not said.
    compensation : defaults for `mtcomp compensate` (max_correction_um, max_correction_urad, max_step_um).
    quill : the machine has a W quill parallel to Z (a horizontal boring mill: ``quill = true`` in
        the file's [axes.Z]); only then do programs' W words move the tool tip along Z
        (:mod:`mtcomp.toolpaths.quill`).
    calculator_input : the control reads a dimension word without a decimal point in whole units
        (Fanuc: parameter 3401#0 DPI = 1; Haas: Setting 162, Default To Float, on), said by
        ``calculator_input = true`` in the file; else a Fanuc or Haas program's ``X60`` is refused
        (:func:`mtcomp.toolpaths.word_use.check_point_words`).
    fixed_format : (digits before, after the point) where the control reads words without a
        decimal point in a fixed format (``fixed_format = "3.4"``: ``X0019685`` is 1.9685), else
        None (:mod:`mtcomp.toolpaths.fixed_format`).
    """

    name: str
    topology: str
    axes: tuple[Axis, ...]
    workpiece_chain: tuple[str, ...]
    tool_chain: tuple[str, ...]
    tool_length: float = 0.0
    compensation: dict = field(default_factory=lambda: dict(DEFAULT_COMPENSATION))
    source: str = ""
    units: str | None = None
    quill: bool = False
    calculator_input: bool = False
    fixed_format: tuple[int, int] | None = None

    @property
    def axis_names(self) -> tuple[str, ...]:
        return tuple(a.name for a in self.axes)

    @property
    def n_axes(self) -> int:
        return len(self.axes)

    def axis(self, name: str) -> Axis:
        for a in self.axes:
            if a.name == name:
                return a
        raise KeyError(name)

    def index(self, name: str) -> int:
        return self.axis_names.index(name)

    @property
    def linear_axes(self) -> tuple[Axis, ...]:
        return tuple(a for a in self.axes if not a.is_rotary)

    @property
    def rotary_axes(self) -> tuple[Axis, ...]:
        return tuple(a for a in self.axes if a.is_rotary)

    @property
    def is_five_axis(self) -> bool:
        return len(self.rotary_axes) > 0

    def with_basis(self, basis: str, **axis_fields) -> "Machine":
        """The same machine with every linear axis on ``basis`` ('bspline' or 'polynomial'), and any
        other Axis fields (``degree=2``, ``spline_intervals=4`` ...) set on those axes."""
        from dataclasses import replace
        if basis not in BASES:
            raise ValueError(f"basis must be one of {BASES}, got {basis!r}")
        return replace(self, axes=tuple(a if a.is_rotary else replace(a, basis=basis, **axis_fields)
                                        for a in self.axes))

    def travel_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(lower, upper), each (n_axes,), mm and rad."""
        lo = np.array([a.travel[0] for a in self.axes])
        hi = np.array([a.travel[1] for a in self.axes])
        return lo, hi

    def check_travel(self, q, line=None, known=None, source=None, tol: float = 1e-9) -> None:
        """InputError naming ``source`` and the first row's ``line`` where an axis position of ``q``
        (n, n_axes; mm, rad) lies outside the axis's travel; ``known`` (n, n_axes) bool limits the
        check to the positions a program has given. ``source`` may be a program as read
        (:class:`~mtcomp.toolpaths.source.ProgramSource`): the line is then named in the user's
        file (an expanded or translated program's lines are not the file's)."""
        lo, hi = self.travel_bounds()
        # compared down the columns (order F): in numpy's own order a row of bounds broadcast over
        # the rows is compared one row of a few axes at a time, ten times slower
        bad = np.less(q, lo - tol, order="F")
        bad |= np.greater(q, hi + tol, order="F")
        if known is not None:
            bad &= known
        if np.any(bad):
            i, j = np.argwhere(bad)[0]
            ax = self.axes[j]
            if ax.is_rotary:
                v, a, b, u = np.degrees(q[i, j]), np.degrees(lo[j]), np.degrees(hi[j]), "deg"
            else:
                v, a, b, u = q[i, j], lo[j], hi[j], "mm"
            where, k, suffix = source, int(line[i]) if line is not None else None, ""
            if hasattr(source, "locate"):
                where, k, suffix = source.locate(k)
            raise TravelError(f"{ax.name} {v:.4f} {u} is outside the travel of axis {ax.name} "
                             f"({a:g} .. {b:g} {u}) of machine {self.name}{suffix}", where, k,
                              axis=ax.name)

    def to_dict(self) -> dict:
        """The machine as TOML-like data (mm, deg), for MODEL.json."""
        axes = {}
        for a in self.axes:
            d: dict = {}
            if a.is_rotary:
                d["travel_deg"] = [math.degrees(a.travel[0]), math.degrees(a.travel[1])]
                d["axis_point_mm"] = list(a.axis_point)
                d["fourier_order"] = a.fourier_order
                d["error_motion_order"] = a.error_motion_order
            else:
                d["travel_mm"] = list(a.travel)
                d["basis"] = a.basis
                d["degree"] = a.degree
                if a.basis == "bspline" and a.spline_range is not None:
                    d["spline_range_mm"] = list(a.spline_range)
                if a.basis == "bspline" and a.spline_intervals is not None:
                    d["spline_intervals"] = a.spline_intervals
            axes[a.name] = d
        if self.quill:
            axes["Z"]["quill"] = True
        d = {"name": self.name, "topology": self.topology, "tool_length_mm": self.tool_length,
             "axes": axes, "compensation": dict(self.compensation)}
        if self.units is not None:
            d["units"] = self.units
        if self.calculator_input:
            d["calculator_input"] = True
        if self.fixed_format is not None:
            d["fixed_format"] = "%d.%d" % self.fixed_format
        return d


def parse_topology(topology: str, path: str | None = None) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """'CAFXYZ' -> (workpiece chain bed->workpiece ('A', 'C'), tool chain bed->tool ('X', 'Y', 'Z'))."""
    if not isinstance(topology, str) or not topology:
        raise InputError("topology must be a non-empty string such as 'XFYZ'", path)
    topo = topology.strip().upper()
    if topo.count("F") != 1:
        raise InputError(f"topology {topology!r} must contain exactly one 'F' (the bed)", path)
    for ch in topo:
        if ch != "F" and ch not in AXIS_ORDER:
            raise InputError(f"topology {topology!r}: unknown letter {ch!r} (axes are X Y Z A B C, "
                             "F is the bed)", path)
    letters = topo.replace("F", "")
    if len(set(letters)) != len(letters):
        raise InputError(f"topology {topology!r} names an axis twice", path)
    if not letters:
        raise InputError(f"topology {topology!r} has no axes", path)
    before, after = topo.split("F")
    # letters before F are listed from the workpiece towards the bed: reverse for bed -> workpiece
    return tuple(reversed(before)), tuple(after)


def _number_list(value, n, what, path):
    if not isinstance(value, (list, tuple)) or len(value) != n:
        raise InputError(f"{what} must be a list of {n} numbers", path)
    out = []
    for v in value:
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise InputError(f"{what} must be a list of {n} finite numbers, got {value!r}", path)
        out.append(float(v))
    return out


def _positive_int(value, what, path, minimum=0):
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise InputError(f"{what} must be a whole number >= {minimum}, got {value!r}", path)
    return value


def _fixed_format(value, path) -> tuple[int, int] | None:
    """(digits before the point, digits after it) of ``fixed_format = "3.4"``, or None."""
    m = re.match(r"^([1-9])\.([0-9])$", value) if isinstance(value, str) else None
    if value is not None and m is None:
        raise InputError(f"fixed_format must be a string of the digits before and after the point, "
                         f"as \"3.4\", got {value!r}", path)
    return None if m is None else (int(m.group(1)), int(m.group(2)))


def machine_from_dict(data: dict, path: str | None = None) -> Machine:
    """Build and validate a Machine from TOML data (mm, deg). Raises InputError naming the key."""
    if not isinstance(data, dict):
        raise InputError("machine description must be a table", path)
    known = {"name", "topology", "tool_length_mm", "axes", "compensation", "units",
             "calculator_input", "fixed_format"}
    for key in data:
        if key not in known:
            raise InputError(f"unknown key {key!r} (known: {', '.join(sorted(known))})", path)
    if "topology" not in data:
        raise InputError("missing key 'topology'", path)
    wp_chain, tool_chain = parse_topology(data["topology"], path)
    name = data.get("name", Path(path).stem if path else "machine")
    if not isinstance(name, str):
        raise InputError("name must be a string", path)
    tool_length = data.get("tool_length_mm", 0.0)
    if isinstance(tool_length, bool) or not isinstance(tool_length, (int, float)) \
            or not math.isfinite(tool_length) or tool_length < 0:
        raise InputError(f"tool_length_mm must be a finite number >= 0, got {tool_length!r}", path)
    units = data.get("units")
    if units is not None and units not in ("mm", "inch"):
        raise InputError(f"units must be \"mm\" or \"inch\", got {units!r}", path)
    axes_data = data.get("axes", {})
    if not isinstance(axes_data, dict):
        raise InputError("[axes] must be a table of axis tables", path)
    letters = set(wp_chain) | set(tool_chain)
    for key in axes_data:
        if key not in letters:
            raise InputError(f"[axes.{key}] is not an axis of topology {data['topology']!r}", path)
    axes = []
    for letter in AXIS_ORDER:
        if letter not in letters:
            continue
        if letter not in axes_data:
            raise InputError(f"axis {letter} of topology {data['topology']!r} has no [axes.{letter}] "
                             "table (travel is required)", path)
        ad = axes_data[letter]
        if not isinstance(ad, dict):
            raise InputError(f"[axes.{letter}] must be a table", path)
        side = "workpiece" if letter in wp_chain else "tool"
        axes.append(_linear_axis(letter, side, ad, path) if letter in LINEAR
                    else _rotary_axis(letter, side, ad, path))
    comp = _compensation(data, path)
    calculator = data.get("calculator_input", False)
    if not isinstance(calculator, bool):
        raise InputError(f"calculator_input must be true or false, got {calculator!r}", path)
    fixed = _fixed_format(data.get("fixed_format"), path)
    return Machine(name=name, topology=str(data["topology"]).strip().upper(), axes=tuple(axes),
                   workpiece_chain=wp_chain, tool_chain=tool_chain, tool_length=float(tool_length),
                   compensation=comp, source=path or "", units=units,
                   quill=_quill(axes_data.get("Z", {}), path), calculator_input=calculator,
                   fixed_format=fixed)


def _quill(z_table: dict, path) -> bool:
    """``quill`` of the [axes.Z] table: true when the machine has a W quill along Z (default
    false)."""
    quill = z_table.get("quill", False)
    if not isinstance(quill, bool):
        raise InputError(f"[axes.Z] quill must be true or false, got {quill!r}", path)
    return quill


def _refuse_unknown_keys(table: dict, allowed: set, where: str, what: str, path) -> None:
    """InputError naming the first key of ``table`` not in ``allowed`` (``where``: the table's name,
    ``what``: what it describes)."""
    for k in table:
        if k not in allowed:
            raise InputError(f"{where}: unknown key {k!r} for {what} "
                             f"(known: {', '.join(sorted(allowed))})", path)


def _linear_axis(letter: str, side: str, ad: dict, path) -> Axis:
    """The linear axis ``letter`` of its table ``ad`` (travel in mm)."""
    keys = {"travel_mm", "degree", "basis", "spline_range_mm", "spline_intervals"}
    # quill: the Z axis's only (a W quill along Z: :func:`_quill`)
    _refuse_unknown_keys(ad, keys | {"quill"} if letter == "Z" else keys, f"[axes.{letter}]",
                         "a linear axis", path)
    if "travel_mm" not in ad:
        raise InputError(f"[axes.{letter}]: linear axis without travel_mm", path)
    lo, hi = _number_list(ad["travel_mm"], 2, f"[axes.{letter}] travel_mm", path)
    if not lo < hi:
        raise InputError(f"[axes.{letter}] travel_mm: lower {lo} must be below upper {hi}", path)
    degree = _positive_int(ad.get("degree", 3), f"[axes.{letter}] degree", path, 1)
    basis = ad.get("basis", "bspline")
    if basis not in BASES:
        raise InputError(f"[axes.{letter}] basis must be one of {', '.join(BASES)}, got {basis!r}",
                         path)
    if basis == "bspline" and degree > 3:
        raise InputError(f"[axes.{letter}] degree of a spline must be 1, 2 or 3, got {degree}", path)
    srange = None
    if "spline_range_mm" in ad:
        srange = tuple(_number_list(ad["spline_range_mm"], 2, f"[axes.{letter}] spline_range_mm",
                                    path))
        if not srange[0] < srange[1]:
            raise InputError(f"[axes.{letter}] spline_range_mm: lower must be below upper", path)
    nint = None
    if "spline_intervals" in ad:
        nint = _positive_int(ad["spline_intervals"], f"[axes.{letter}] spline_intervals", path, 1)
    return Axis(letter, side, (lo, hi), degree=degree, basis=basis, spline_range=srange,
                spline_intervals=nint)


def _rotary_axis(letter: str, side: str, ad: dict, path) -> Axis:
    """The rotary axis ``letter`` of its table ``ad`` (travel in deg in the file, rad in the Axis)."""
    _refuse_unknown_keys(ad, {"travel_deg", "axis_point_mm", "fourier_order", "error_motion_order"},
                         f"[axes.{letter}]", "a rotary axis", path)
    if "travel_deg" not in ad:
        raise InputError(f"[axes.{letter}]: rotary axis without travel_deg", path)
    if "axis_point_mm" not in ad:
        raise InputError(f"[axes.{letter}]: rotary axis without axis_point_mm (a point on its "
                         "nominal axis line)", path)
    lo, hi = _number_list(ad["travel_deg"], 2, f"[axes.{letter}] travel_deg", path)
    if not lo < hi:
        raise InputError(f"[axes.{letter}] travel_deg: lower {lo} must be below upper {hi}", path)
    point = _number_list(ad["axis_point_mm"], 3, f"[axes.{letter}] axis_point_mm", path)
    order = _positive_int(ad.get("fourier_order", 2), f"[axes.{letter}] fourier_order", path)
    fourier_from_data = "fourier_order" not in ad
    emo = _positive_int(ad.get("error_motion_order", 0), f"[axes.{letter}] error_motion_order",
                        path)
    return Axis(letter, side, (math.radians(lo), math.radians(hi)), tuple(point),
                fourier_order=order, error_motion_order=emo, fourier_from_data=fourier_from_data)


def _compensation(data: dict, path) -> dict:
    """The [compensation] table over the defaults (each a positive number; max_correction_urad
    may be 0)."""
    comp = dict(DEFAULT_COMPENSATION)
    comp_data = data.get("compensation", {})
    if not isinstance(comp_data, dict):
        raise InputError("[compensation] must be a table", path)
    for k, v in comp_data.items():
        if k not in DEFAULT_COMPENSATION:
            raise InputError(f"[compensation]: unknown key {k!r} (known: "
                             f"{', '.join(sorted(DEFAULT_COMPENSATION))})", path)
        # max_correction_urad may be 0: the rotary axes are never corrected
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0 \
                or (v == 0 and k != "max_correction_urad"):
            raise InputError(f"[compensation] {k} must be a positive number, got {v!r}", path)
        comp[k] = float(v)
    return comp


def load_machine(name_or_path: str | os.PathLike) -> Machine:
    """A built-in machine by name (``xfyz``, ``cafxyz``, ``cbfxyz``) or a TOML file path."""
    s = os.fspath(name_or_path)
    if s.lower() in BUILTIN_MACHINES:
        text = resources.files("mtcomp").joinpath(f"machines/{s.lower()}.toml").read_text()
        return machine_from_dict(tomllib.loads(text), path=f"<built-in {s.lower()}>")
    p = Path(s)
    if not p.exists():
        raise InputError(f"no such machine: not a built-in ({', '.join(BUILTIN_MACHINES)}) "
                         "and no such file", s)
    try:
        data = tomllib.loads(p.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        hint = ""
        if p.read_text(encoding="utf-8", errors="replace").lstrip().startswith("{"):
            hint = ("; it looks like a JSON file (a model file?): the machine file (TOML, or a "
                    "built-in name) comes first")
        raise InputError(f"not valid TOML: {exc}{hint}", s) from None
    except UnicodeDecodeError:
        raise InputError("not a text file", s) from None
    return machine_from_dict(data, path=s)


def builtin_machine_summaries() -> list[str]:
    out = []
    for name in BUILTIN_MACHINES:
        m = load_machine(name)
        trav = ", ".join(
            f"{a.name} {math.degrees(a.travel[0]):g}..{math.degrees(a.travel[1]):g} deg" if a.is_rotary
            else f"{a.name} {a.travel[0]:g}..{a.travel[1]:g} mm" for a in m.axes)
        out.append(f"{name:8s} {m.topology:8s} {m.name}: {trav}")
    return out

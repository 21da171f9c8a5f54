"""Parameters of an error model: ISO 230-1 names, units in files, values inside.

Every parameter has an internal value (mm or rad, or mm and rad per unit of its basis) and a file
value (um or urad, ...). ``ParamSpec.to_file`` is the factor from internal to file units.

Naming (docs/parameters.md has the full table and the notation of the papers in docs/references.md):

* ``EXX_1 .. EXX_3``: coefficient k of the polynomial of component error EXX of axis X in the axis
  position in metres: ``EXX(s) = sum_k EXX_k * (s / 1000 mm)**k`` (no constant term: every error is
  zero at the axis zero). File unit ``um`` (the contribution at s = 1 m), ``urad`` for angular ones.
* ``C0Y``, ``B0Z``, ``A0Z``: squareness (urad). ``X0C``, ``Y0C`` (um) and ``A0C``, ``B0C`` (urad):
  location of the C axis line. ``ECC_0``: zero offset of C; ``ECC_c1``, ``ECC_s1``: harmonics of the
  angular positioning error (urad). ``EXC_c1`` ...: harmonics of the error motions.
* ``TOOL_dL``: tool length error (um), the tip sits lower by ``TOOL_dL`` along the tool axis.
* Extension terms (backlash, IRC, drift ...) add their own names (see mtcomp.models.terms).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

#: factor from internal unit to file unit
UNIT_FACTORS = {"um": 1e3, "urad": 1e6, "mm": 1.0, "rad": 1.0, "1": 1.0, "deg": 180.0 / np.pi}


@dataclass(frozen=True)
class ParamSpec:
    """One parameter.

    name : unique name, e.g. 'EXX_2'.
    unit : file unit ('um', 'urad', 'mm', '1').
    group : what it belongs to, e.g. 'X:EXX', 'squareness', 'C:location', 'backlash:X'.
    base : True for the base model, False for an extension term.
    description : one line, for summaries.
    """

    name: str
    unit: str
    group: str
    base: bool = True
    description: str = ""

    @property
    def to_file(self) -> float:
        return UNIT_FACTORS[self.unit]


@dataclass
class ParameterSet:
    """Values (internal units) of an ordered list of parameters, with optional standard errors and
    which of them a fit varied (``vary``, None: not recorded), in the manner of lmfit's Parameters."""

    specs: tuple[ParamSpec, ...]
    values: np.ndarray = None
    std_errors: np.ndarray | None = None
    meta: dict = field(default_factory=dict)
    vary: np.ndarray | None = None

    def __post_init__(self):
        self.specs = tuple(self.specs)
        if self.values is None:
            self.values = np.zeros(len(self.specs))
        self.values = np.asarray(self.values, dtype=float).copy()
        if self.values.shape != (len(self.specs),):
            raise ValueError(f"values must have shape ({len(self.specs)},), got {self.values.shape}")
        names = [s.name for s in self.specs]
        if len(set(names)) != len(names):
            raise ValueError("duplicate parameter names")
        self._index = {n: i for i, n in enumerate(names)}
        if self.vary is not None:
            self.vary = np.asarray(self.vary, dtype=bool).copy()
            if self.vary.shape != (len(self.specs),):
                raise ValueError(f"vary must have shape ({len(self.specs)},), got {self.vary.shape}")

    @property
    def stderr(self) -> np.ndarray:
        """(n,) standard errors, internal units (NaN where not known: held or undetermined)."""
        return np.full(len(self.specs), np.nan) if self.std_errors is None else self.std_errors

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(s.name for s in self.specs)

    def __len__(self):
        return len(self.specs)

    def __contains__(self, name):
        return name in self._index

    def index(self, name: str) -> int:
        return self._index[name]

    def __getitem__(self, name: str) -> float:
        return float(self.values[self._index[name]])

    def __setitem__(self, name: str, value: float):
        self.values[self._index[name]] = value

    def file_values(self) -> np.ndarray:
        return self.values * np.array([s.to_file for s in self.specs])

    def set_file_value(self, name: str, value: float):
        self.values[self._index[name]] = value / self.specs[self._index[name]].to_file

    def copy(self) -> "ParameterSet":
        return ParameterSet(self.specs, self.values.copy(),
                            None if self.std_errors is None else self.std_errors.copy(), dict(self.meta),
                            None if self.vary is None else self.vary.copy())

    def reindexed(self, specs) -> "ParameterSet":
        """The same values on another list of specs (new names get 0, dropped names are lost)."""
        out = ParameterSet(specs)
        for i, s in enumerate(out.specs):
            if s.name in self._index:
                out.values[i] = self.values[self._index[s.name]]
        return out

    def to_json_dict(self) -> dict:
        fv = self.file_values()
        out = {}
        for i, s in enumerate(self.specs):
            entry = {"value": float(fv[i]), "unit": s.unit, "group": s.group, "base": s.base}
            if self.std_errors is not None and np.isfinite(self.std_errors[i]):
                entry["std_error"] = float(self.std_errors[i] * s.to_file)
            out[s.name] = entry
        return out

    def with_values_from_json(self, data: dict, path=None) -> "ParameterSet":
        from ..errors import InputError
        out = self.copy()
        for name, entry in data.items():
            if name not in out._index:
                raise InputError(f"parameter {name!r} is not part of this model", path)
            if not isinstance(entry, dict) or "value" not in entry:
                raise InputError(f"parameter {name!r} needs an object with 'value'", path)
            spec = out.specs[out._index[name]]
            unit = entry.get("unit", spec.unit)
            if unit != spec.unit:
                raise InputError(f"parameter {name!r} is in {unit!r}, expected {spec.unit!r}", path)
            v = entry["value"]
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
                raise InputError(f"parameter {name!r} has a non-numeric value {v!r}", path)
            out.set_file_value(name, float(v))
        return out


def with_base_flag(spec: ParamSpec, base: bool) -> ParamSpec:
    return replace(spec, base=base)

"""STUDY.toml: what a correction study runs, read and checked before anything starts.

A study is the product programs x models x methods x bound settings x temperatures x draws; each
element is one :class:`Task` (one compensation and its evaluation). Paths in the file are relative
to the file. The format is in docs/study.md; every key is checked here, with a one-line error that
names the file and the key.

A task's ``key`` is the SHA-256 of everything its result depends on: the bytes of the program, the
model, the judge model, the machine file and the offsets file, the settings, the draw and the seed.
A re-run or a widened grid finds the finished tasks by it (:mod:`mtcomp.study.runner`).
"""
from __future__ import annotations

import glob
import hashlib
import itertools
import json
import math
import os
import tomllib
from dataclasses import asdict, dataclass, field
from pathlib import Path

from ..compensation import CompensationSettings
from ..errors import InputError

#: bumped when a task's result changes for the same inputs (new columns, another evaluation)
RESULT_VERSION = 2

_TOP_KEYS = {"machine", "programs", "models", "judge", "methods", "draws", "seed", "temperatures",
             "offsets", "compensate", "bounds"}
_BOUND_KEYS = {"name", "max_correction_um", "max_correction_urad", "max_step_um", "max_step_urad",
               "axis_max_correction", "axis_max_step"}
#: [compensate] keys: the settings every task shares (besides its bounds, method and temperatures)
_COMPENSATE_KEYS = {"orientation_weight", "subdivide_tol_um", "chord_tol_um", "spindle_rpm",
                    "extrapolate", "max_correction_sd_um", "units", "start_position"}
METHODS = ("qp", "pinv", "newton")


@dataclass(frozen=True)
class Task:
    """One compensation and its evaluation: pure function of these fields (and the files' bytes).

    program, model, judge, machine, offsets : absolute paths (judge, offsets: None when not given;
        machine: a built-in name or a path).
    labels : the names the results table shows (program and model paths relative to the study
        file, the bound setting's name, the temperatures).
    settings : the compensation settings of this task.
    draw : 0 compensates with the model itself; k > 0 with the k-th draw of the model from its
        covariance (seeded by ``seed``, the draw and ``model_hash``, the SHA-256 of the model file:
        draw k is the same model in every task of the study).
    judge_hash, machine_id : the judge file's SHA-256, the machine's name or its file's SHA-256 (a
        worker keeps what it loaded under these, so a file changed in place is read anew).
    key : SHA-256 hex of the inputs (see the module's docstring).
    """

    program: str
    model: str
    judge: str | None
    machine: str
    offsets: str | None
    settings: CompensationSettings
    draw: int
    seed: int
    labels: dict
    model_hash: str = ""
    key: str = ""
    judge_hash: str | None = None
    machine_id: str = ""


@dataclass
class Study:
    """A study file, read and checked: the axes of its grid and the files they name."""

    path: Path
    machine: str
    programs: list
    models: list
    judge: str | None = None
    methods: list = field(default_factory=lambda: ["qp"])
    draws: int = 0
    seed: int = 0
    temperatures: list = field(default_factory=lambda: [{}])
    offsets: str | None = None
    compensate: dict = field(default_factory=dict)
    bounds: list = field(default_factory=lambda: [{"name": "machine"}])

    def tasks(self) -> list[Task]:
        """Every task of the grid, in a fixed order (program, model, method, bounds, temperature,
        draw), each with its key (the files are hashed once: later calls give the same list)."""
        if getattr(self, "_tasks", None) is not None:
            return self._tasks
        base = self.path.parent
        digest = {}

        def file_hash(p):
            if p is None:
                return None
            if p not in digest:
                digest[p] = _sha256(p)
            return digest[p]

        machine_id = file_hash(self.machine) if os.path.isfile(self.machine) else self.machine
        out = []
        for prog, model, method, bound, temps, draw in itertools.product(
                self.programs, self.models, self.methods, self.bounds, self.temperatures,
                range(self.draws + 1)):
            values = {k: v for k, v in bound.items() if k != "name"}
            settings = CompensationSettings(method=method, temperatures=dict(temps), threads=1,
                                            **self.compensate, **values)
            labels = {"program": _relative(prog, base), "model": _relative(model, base),
                      "judge": _relative(self.judge, base) if self.judge else "",
                      "method": method, "bounds": bound["name"],
                      "temperature": temperature_label(temps), "draw": draw}
            ident = {"version": RESULT_VERSION, "program": file_hash(prog), "model": file_hash(model),
                     "judge": file_hash(self.judge), "machine": machine_id,
                     "offsets": file_hash(self.offsets), "settings": asdict(settings),
                     "draw": draw, "seed": self.seed if draw else 0}
            key = hashlib.sha256(json.dumps(ident, sort_keys=True).encode()).hexdigest()
            out.append(Task(prog, model, self.judge, self.machine, self.offsets, settings, draw,
                            self.seed, labels, file_hash(model), key, file_hash(self.judge),
                            machine_id))
        self._tasks = out
        return out


def temperature_label(temps: dict) -> str:
    """{'t1': 25.0} -> 't1=25'; {} -> 'none' (no thermal state: the drift is not compensated)."""
    return ",".join(f"{k}={v:g}" for k, v in sorted(temps.items())) or "none"


def _sha256(path) -> str:
    h = hashlib.sha256()
    try:
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror}", path) from None
    return h.hexdigest()


def _relative(path, base: Path) -> str:
    try:
        return str(Path(path).relative_to(base.resolve()))
    except ValueError:
        return str(path)


def load_study(path) -> Study:
    """Read and check STUDY.toml. InputError (one line naming the file and the key) for a missing
    or unknown key, a value of the wrong kind, a glob that matches nothing or a file that does not
    exist."""
    path = Path(path)
    try:
        with open(path, "rb") as f:
            data = tomllib.load(f)
    except FileNotFoundError:
        raise InputError("no such study file", path) from None
    except IsADirectoryError:
        raise InputError("a folder, not a study file", path) from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"not valid TOML: {exc}", path) from None
    base = path.resolve().parent

    def fail(msg):
        raise InputError(msg, path)

    unknown = sorted(set(data) - _TOP_KEYS)
    if unknown:
        fail(f"unknown key {unknown[0]!r} (known: {', '.join(sorted(_TOP_KEYS))})")
    for key in ("machine", "programs", "models"):
        if key not in data:
            fail(f"missing key {key!r}")
    machine = _string(data["machine"], "machine", fail)
    if machine.endswith(".toml") or os.sep in machine or "/" in machine:
        machine = str(_existing(base / machine, "machine", fail))
    programs = _files(data["programs"], "programs", base, fail)
    models = _files(data["models"], "models", base, fail)
    judge = None
    if "judge" in data:
        judge = str(_existing(base / _string(data["judge"], "judge", fail), "judge", fail))
    offsets = None
    if "offsets" in data:
        offsets = str(_existing(base / _string(data["offsets"], "offsets", fail), "offsets", fail))
    methods = _list(data.get("methods", ["qp"]), "methods", fail)
    for m in methods:
        if m not in METHODS:
            fail(f"methods: unknown method {m!r} (choose {', '.join(METHODS)})")
    draws = data.get("draws", 0)
    if isinstance(draws, bool) or not isinstance(draws, int) or draws < 0:
        fail(f"draws must be a whole number of 0 or more, got {draws!r}")
    seed = data.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        fail(f"seed must be a whole number of 0 or more, got {seed!r}")
    temperatures = _temperatures(data.get("temperatures", [{}]), fail)
    compensate = _compensate(data.get("compensate", {}), fail)
    bounds = _bounds(data.get("bounds", [{"name": "machine"}]), compensate, fail)
    return Study(path.resolve(), machine, programs, models, judge, list(dict.fromkeys(methods)),
                 draws, seed, temperatures, offsets, compensate, bounds)


def _string(v, key, fail) -> str:
    if not isinstance(v, str) or not v:
        fail(f"{key} must be a text (a name or a path), got {v!r}")
    return v


def _list(v, key, fail) -> list:
    if isinstance(v, str):
        return [v]
    if not isinstance(v, list) or not v:
        fail(f"{key} must be a list with at least one entry")
    return v


def _existing(p: Path, key, fail) -> Path:
    if not p.is_file():
        fail(f"{key}: no such file {p}")
    return p.resolve()


def _files(v, key, base: Path, fail) -> list[str]:
    """Files and globs (relative to the study file) -> sorted absolute paths, each once."""
    out = []
    for pattern in _list(v, key, fail):
        pattern = _string(pattern, key, fail)
        full = str(base / pattern)
        if glob.has_magic(pattern):
            hits = sorted(p for p in glob.glob(full, recursive=True) if os.path.isfile(p))
            if not hits:
                fail(f"{key}: {pattern!r} matches no file")
            out += [str(Path(p).resolve()) for p in hits]
        else:
            out.append(str(_existing(Path(full), key, fail)))
    return list(dict.fromkeys(out))


def _number(v, where, fail, allow_zero=False) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0 \
            or (v == 0 and not allow_zero):
        fail(f"{where} must be a {'number of 0 or more' if allow_zero else 'positive number'}, "
             f"got {v!r}")
    return float(v)


def _temperatures(v, fail) -> list[dict]:
    if not isinstance(v, list) or not v:
        fail("temperatures must be a list of tables such as [{}, {t1 = 25.0}] ({} keeps the "
             "model's reference)")
    out = []
    for i, row in enumerate(v):
        if not isinstance(row, dict):
            fail(f"temperatures[{i}] must be a table such as {{t1 = 25.0}}")
        for name, t in row.items():
            if isinstance(t, bool) or not isinstance(t, (int, float)) or not math.isfinite(t):
                fail(f"temperatures[{i}] {name} must be a temperature in degC, got {t!r}")
        out.append({k: float(t) for k, t in row.items()})
    return out


def _compensate(v, fail) -> dict:
    if not isinstance(v, dict):
        fail("[compensate] must be a table")
    unknown = sorted(set(v) - _COMPENSATE_KEYS)
    if unknown:
        fail(f"[compensate] unknown key {unknown[0]!r} (known: {', '.join(sorted(_COMPENSATE_KEYS))}; "
             "bounds go in [[bounds]])")
    out = dict(v)
    for key in ("orientation_weight", "chord_tol_um", "spindle_rpm"):
        if key in out:
            out[key] = _number(out[key], f"[compensate] {key}", fail, allow_zero=key == "spindle_rpm")
    for key in ("subdivide_tol_um", "max_correction_sd_um"):
        if key in out:
            out[key] = _number(out[key], f"[compensate] {key}", fail, allow_zero=True)
    if "extrapolate" in out and not isinstance(out["extrapolate"], bool):
        fail("[compensate] extrapolate must be true or false")
    if "units" in out and out["units"] not in ("mm", "inch"):
        fail(f"[compensate] units must be 'mm' or 'inch', got {out['units']!r}")
    if "start_position" in out:
        sp = out["start_position"]
        if not isinstance(sp, dict):
            fail("[compensate] start_position must be a table such as {A = 0.0, C = 0.0}")
        out["start_position"] = {str(a).upper(): _signed(x, f"[compensate] start_position {a}", fail)
                                 for a, x in sp.items()}
    return out


def _signed(v, where, fail) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        fail(f"{where} must be a number, got {v!r}")
    return float(v)


def _bounds(v, compensate, fail) -> list[dict]:
    if not isinstance(v, list) or not v:
        fail("bounds must be a list of [[bounds]] tables")
    out, names = [], set()
    for i, row in enumerate(v):
        if not isinstance(row, dict):
            fail(f"bounds[{i}] must be a table")
        unknown = sorted(set(row) - _BOUND_KEYS)
        if unknown:
            fail(f"bounds[{i}]: unknown key {unknown[0]!r} (known: {', '.join(sorted(_BOUND_KEYS))})")
        b = {"name": row.get("name", f"bounds{i + 1}")}
        if not isinstance(b["name"], str) or not b["name"]:
            fail(f"bounds[{i}]: name must be a text")
        if b["name"] in names:
            fail(f"bounds[{i}]: the name {b['name']!r} is used twice")
        names.add(b["name"])
        for key in ("max_correction_um", "max_correction_urad", "max_step_um", "max_step_urad"):
            if key in row:
                b[key] = _number(row[key], f"bounds[{i}] {key}", fail)
        for key in ("axis_max_correction", "axis_max_step"):
            if key in row:
                t = row[key]
                if not isinstance(t, dict) or not t:
                    fail(f"bounds[{i}] {key} must be a table such as {{Z = 5.0}} (um; urad for "
                         "rotary axes)")
                b[key] = {str(a).upper(): _number(x, f"bounds[{i}] {key} {a}", fail)
                          for a, x in t.items()}
        out.append(b)
    return out

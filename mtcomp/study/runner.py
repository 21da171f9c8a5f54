"""Run a study's tasks on Dask, keep every finished one, write the results table.

The engine is dask.distributed: by default a LocalCluster of worker processes on this machine (one
thread each: a task is CPU-bound Python and NumPy), started and stopped here; or an existing cluster
at ``scheduler`` (its workers need mtcomp installed and the study's files at the same paths).

Every task's row is kept in ``RESULTS/tasks/<key>.json`` the moment it is finished: written by the
worker itself where it can reach RESULTS/ (always on a LocalCluster), and by this driver when the
row arrives. A re-run, a widened grid, or a run after a kill loads those rows and submits only the
tasks that have none. A task that failed (bad input, a worker lost) is recorded in the table with
its one-line error and tried again on the next run. The driver holds result rows only, never a
program's blocks.
"""
from __future__ import annotations

import json
import math
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from ..errors import InputError
from ..io.atomic import atomic_write
from .spec import Study, Task
from .task import COLUMNS, run_task

#: where finished tasks' rows are kept, inside RESULTS/
TASKS_DIR = "tasks"


@dataclass
class StudyRun:
    """What :func:`run_study` did: the rows in task order, and how they were obtained (``computed``
    now, ``cached``: kept from an earlier run; ``failed``: the rows with an error, of either)."""

    rows: list
    computed: int
    cached: int
    failed: int
    seconds: float
    workers: int


def _row_path(out: Path, task: Task) -> Path:
    return out / TASKS_DIR / f"{task.key}.json"


def _keep(row: dict) -> bool:
    """A row worth keeping: a result. A failed task is tried again on the next run (a file that was
    missing may be back; an error is quick to find again)."""
    return row["status"] == "ok"


def _write_row(path: Path, row: dict) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_write(path, "w") as f:
        json.dump(row, f)


def run_task_kept(task: Task, tasks_dir: str | None) -> dict:
    """:func:`run_task`, its row written to ``tasks_dir/<key>.json`` when that folder is reachable
    from here (the worker): a finished task survives the driver being killed."""
    row = run_task(task)
    if tasks_dir is not None and os.path.isdir(tasks_dir) and _keep(row):
        try:
            _write_row(Path(tasks_dir) / f"{task.key}.json", row)
        except OSError:
            pass                # not writable from this worker: the driver writes it on arrival
    return row


def _load_row(path: Path) -> dict | None:
    try:
        with open(path) as f:
            row = json.load(f)
    except (OSError, ValueError):
        return None             # absent, or cut short: computed again
    return row if isinstance(row, dict) and set(COLUMNS) <= set(row) else None


def check_study(study: Study) -> None:
    """Load the machine and every model once, here, so that a study that cannot run stops before
    it starts (one line): a machine or model file that does not load, a model without a covariance
    when draws are asked, an axis the machine does not have."""
    from ..machine import load_machine
    from ..models.model_file import load_model
    from ..thermal.context import thermal_context
    from ..toolpaths.offsets import load_setup
    try:
        machine = load_machine(study.machine)
    except InputError as exc:
        raise InputError(f"machine: {exc}", study.path) from None
    if study.offsets:
        load_setup(machine, study.offsets)
    for path in study.models + ([study.judge] if study.judge else []):
        fitted = load_model(path, machine)
        if study.draws and path in study.models and fitted.uncertainty is None:
            raise InputError(f"draws = {study.draws}: the model carries no covariance to draw from "
                             "(identify, diagnose and a thermal diagnosis write one)", path)
        for temps in study.temperatures:
            try:
                thermal_context(fitted, temps, study.compensate.get("spindle_rpm"),
                                study.compensate.get("extrapolate", False))
            except InputError as exc:
                raise InputError(f"temperatures {temps}: {exc.args[0] if exc.args else exc} "
                                 f"(model {Path(path).name})", study.path) from None
    axes = set(machine.axis_names)
    for i, b in enumerate(study.bounds):
        for key in ("axis_max_correction", "axis_max_step"):
            for a in b.get(key, {}):
                if a not in axes:
                    raise InputError(f"bounds[{i}] {key}: machine {machine.name} has no {a} axis",
                                     study.path)
    for a in study.compensate.get("start_position", {}):
        if a not in axes:
            raise InputError(f"[compensate] start_position: machine {machine.name} has no {a} axis",
                             study.path)


class Progress:
    """done/total and the time left, on stderr: rewritten in place on a terminal, a line every
    ``every`` seconds otherwise."""

    def __init__(self, total: int, cached: int, stream=None, every: float = 5.0):
        self.total, self.cached = total, cached
        self.stream = stream or sys.stderr
        self.tty = hasattr(self.stream, "isatty") and self.stream.isatty()
        self.every = 0.5 if self.tty else every
        self.t0 = time.monotonic()
        self.t_first = None     # when the first task finished: the time left is reckoned from it
        self.last = 0.0
        self.done = 0
        self.failed = 0
        self.shown = -1         # done when last shown

    def say(self, text: str) -> None:
        self.stream.write(text + "\n")
        self.stream.flush()

    def update(self, failed: bool = False, final: bool = False) -> None:
        now = time.monotonic()
        if not final:
            self.done += 1
            self.failed += bool(failed)
            if self.t_first is None:
                self.t_first = now
        if final and self.shown == self.done and not self.tty:
            return
        if not final and now - self.last < self.every and self.done < self.total - self.cached:
            return
        self.last, self.shown = now, self.done
        todo = self.total - self.cached
        elapsed = now - self.t0
        # from the first finished task on: the cluster's start and the workers' first loading of
        # the model are not a task's time
        rate = (self.done - 1) / (now - self.t_first) if self.done > 1 and now > self.t_first else 0
        left = (todo - self.done) / rate if rate else (0.0 if self.done >= todo else math.nan)
        width = 30
        filled = int(width * (self.cached + self.done) / max(self.total, 1))
        bar = "#" * filled + "." * (width - filled)
        text = (f"mtcomp study: [{bar}] {self.cached + self.done}/{self.total} tasks"
                f"{f' ({self.cached} kept from before)' if self.cached else ''}"
                f"{f', {self.failed} failed' if self.failed else ''}, "
                f"{_duration(elapsed)} elapsed, {_duration(left)} left")
        self.stream.write(("\r" + text + (" " * 4) + ("\n" if final else "")) if self.tty else text + "\n")
        self.stream.flush()


def _duration(s: float) -> str:
    if math.isnan(s):
        return "?"
    s = int(round(s))
    return f"{s // 3600}h{s // 60 % 60:02d}m" if s >= 3600 else f"{s // 60}m{s % 60:02d}s"


#: seconds the driver waits for the scheduler at ``--scheduler`` to take the connection and answer
SCHEDULER_TIMEOUT_S = 20.0


def _connect(scheduler: str):
    """A dask Client of the cluster at ``scheduler``; InputError when it cannot be reached.

    Dask's Client tries a refused connection again and again until its timeout (a scheduler may be
    starting); a wrong port or host name would keep the user waiting :data:`SCHEDULER_TIMEOUT_S`.
    A plain TCP connection is tried first, so that a refused one, or a host that does not resolve,
    fails at once."""
    import socket

    from dask.distributed import Client
    from distributed.comm.addressing import parse_address, parse_host_port
    try:
        scheme, location = parse_address(scheduler, strict=False)
        host, port = parse_host_port(location, default_port=8786)
    except ValueError:
        scheme = None                   # not host:port: Dask's Client says what is wrong
    try:
        if scheme in ("tcp", "tls"):
            socket.create_connection((host, port), timeout=SCHEDULER_TIMEOUT_S).close()
        return Client(scheduler, timeout=f"{SCHEDULER_TIMEOUT_S}s")
    except (OSError, TimeoutError) as exc:
        why = exc.strerror if isinstance(exc, OSError) and exc.strerror else exc
        raise InputError(f"--scheduler {scheduler}: cannot reach the Dask scheduler ({why})") from None


def run_study(study: Study, out, scheduler: str | None = None, workers: int | None = None,
              progress: bool = True) -> StudyRun:
    """Run every task of ``study`` not yet kept under ``out`` (RESULTS/), on a LocalCluster of
    ``workers`` processes (default: the CPUs available) or on the cluster at ``scheduler``
    (``tcp://HOST:8786``). Returns the rows of every task in the study's order."""
    from dask.distributed import Client, LocalCluster, as_completed
    t0 = time.monotonic()
    out = Path(out)
    tasks = study.tasks()
    rows: dict[str, dict] = {}
    for t in tasks:
        row = _load_row(_row_path(out, t))
        if row is not None:
            rows[t.key] = row
    unique = {t.key: t for t in tasks}                      # the same task twice in a grid runs once
    todo = [t for k, t in unique.items() if k not in rows]
    kept = len(unique) - len(todo)
    bar = Progress(len(unique), kept) if progress else None
    computed = 0
    n_workers = 0
    if todo:
        tasks_dir = str((out / TASKS_DIR).resolve())
        if bar and not scheduler:
            bar.say(f"mtcomp study: starting {workers or len(os.sched_getaffinity(0))} local "
                    f"worker{'s' if (workers or 2) > 1 else ''} for {len(todo)} tasks ...")
        if scheduler:
            client, cluster = _connect(scheduler), None
        else:
            n_workers = workers or len(os.sched_getaffinity(0))
            cluster = LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True,
                                   dashboard_address=None, silence_logs=40)
            client = Client(cluster)
        try:
            (out / TASKS_DIR).mkdir(parents=True, exist_ok=True)      # once the cluster is there
            n_workers = len(client.scheduler_info()["workers"]) or n_workers
            futures = client.map(run_task_kept, todo, tasks_dir=tasks_dir,
                                 key=[f"mtcomp-study-{t.key}" for t in todo])
            by_key = {f.key: t for f, t in zip(futures, todo)}
            for fut in as_completed(futures):
                task = by_key[fut.key]
                try:
                    row = fut.result()
                except Exception as exc:            # a worker lost, an internal error: not kept
                    row = {c: None for c in COLUMNS}
                    row.update(task.labels, task=task.key[:16], status="error",
                               error=f"{type(exc).__name__}: {exc}".splitlines()[0])
                if _keep(row) and not _row_path(out, task).exists():
                    _write_row(_row_path(out, task), row)
                rows[task.key] = row
                computed += 1
                fut.release()
                if bar:
                    bar.update(failed=row["status"] != "ok")
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
    if bar:
        bar.update(final=True)
    ordered = [{c: rows[t.key].get(c) for c in COLUMNS} for t in tasks]
    for row, t in zip(ordered, tasks):
        row.update(t.labels, task=t.key[:16])        # labels as this study names them
    failed = sum(r["status"] != "ok" for r in ordered)
    return StudyRun(ordered, computed, kept, failed, time.monotonic() - t0, n_workers)


def write_tables(rows: list[dict], out) -> list[Path]:
    """results.parquet (pyarrow) and results.csv under ``out``, one row per task; written atomically."""
    import csv

    import pyarrow as pa
    import pyarrow.parquet as pq
    out = Path(out)
    types = {c: pa.string() for c in ("task", "program", "model", "judge", "method", "bounds",
                                      "temperature", "status", "error")}
    types.update({c: pa.int64() for c in ("draw", "blocks", "evaluated_blocks", "corrected_blocks",
                                          "uncorrected_unknown_axes", "uncorrected_outside_support",
                                          "uncorrected_uncertain")})
    schema = pa.schema([(c, types.get(c, pa.float64())) for c in COLUMNS])
    table = pa.Table.from_pylist(rows, schema=schema)
    parquet, csv_path = out / "results.parquet", out / "results.csv"
    with atomic_write(parquet, "wb") as f:
        pq.write_table(table, f)
    with atomic_write(csv_path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(COLUMNS)
        for r in rows:
            w.writerow(["" if r[c] is None else (f"{r[c]:.6g}" if isinstance(r[c], float) else r[c])
                        for c in COLUMNS])
    return [parquet, csv_path]

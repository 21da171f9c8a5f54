"""Threads for the per-block work of the planner, and a read-ahead thread for a stream of chunks.

Every block's unbounded solution (and the subdivision test at a midpoint) depends on that block
alone, so a chunk can be cut into parts solved at the same time: the compiled model and numpy's
loops over long vectors run without Python's global lock. The parts are joined in order and give
the same numbers as one call (each block goes through the same operations).
"""
from __future__ import annotations

import os
import queue
import threading
from concurrent.futures import ThreadPoolExecutor

#: fewer blocks than this per part are not worth a thread
MIN_PART = 8192

_pools: dict[int, ThreadPoolExecutor] = {}
_pools_lock = threading.Lock()


def available_threads() -> int:
    """CPUs this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:          # not on Linux
        return os.cpu_count() or 1


#: environment variable that sets the number of threads when the option says automatic (0)
THREADS_ENV = "MTCOMP_THREADS"


def resolve_threads(threads: int) -> int:
    """The number of threads for an option value: 0 = automatic: ``$MTCOMP_THREADS`` if set (a
    positive whole number), else the CPUs available, at most 4."""
    if threads == 0:
        env = os.environ.get(THREADS_ENV, "").strip()
        if env.isdigit() and int(env) > 0:
            return int(env)
        return max(1, min(4, available_threads()))
    return max(1, int(threads))


def _pool(workers: int) -> ThreadPoolExecutor:
    with _pools_lock:
        pool = _pools.get(workers)
        if pool is None:
            pool = _pools[workers] = ThreadPoolExecutor(workers, thread_name_prefix="mtcomp-planner")
        return pool


def split_rows(fn, n: int, threads: int, *arrays):
    """``fn(*parts)`` on consecutive row ranges of ``arrays`` (each with n rows) in up to ``threads``
    threads. Returns the list of results in row order (one element when not split)."""
    parts = min(threads, n // MIN_PART)
    if parts < 2:
        return [fn(*arrays)]
    bounds = [n * k // parts for k in range(parts + 1)]
    pieces = [[a[bounds[k]:bounds[k + 1]] for a in arrays] for k in range(parts)]
    futures = [_pool(threads - 1).submit(fn, *p) for p in pieces[1:]]
    first = fn(*pieces[0])
    return [first] + [f.result() for f in futures]


_DONE = object()


def read_ahead(iterator, depth: int = 1, name: str = "mtcomp-read-ahead"):
    """Yield the items of ``iterator`` while a thread (named ``name``) already computes the next
    ``depth`` of them.

    Exceptions of the iterator are raised here, in order. Closing this generator stops the thread
    at its next item (it never runs more than ``depth`` + 1 items ahead).
    """
    q: queue.Queue = queue.Queue(maxsize=depth)
    stop = threading.Event()

    def put(item) -> bool:
        while not stop.is_set():
            try:
                q.put(item, timeout=0.1)
                return True
            except queue.Full:
                continue
        return False

    def work():
        try:
            for item in iterator:
                if not put((True, item)):
                    return
            put((True, _DONE))
        except BaseException as exc:     # handed to the consumer, raised there
            put((False, exc))

    thread = threading.Thread(target=work, name=name, daemon=True)
    thread.start()
    try:
        while True:
            ok, item = q.get()
            if not ok:
                raise item
            if item is _DONE:
                return
            yield item
    finally:
        stop.set()
        thread.join()

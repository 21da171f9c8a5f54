"""Single-threaded BLAS while diagnosing.

Diagnosis solves thousands of small (about 100 x 100) normal equations. Multi-threaded OpenBLAS is
much slower than one thread on such sizes, and dramatically so on a busy machine (threads spin while
waiting for cores). :func:`single_threaded_blas` sets the OpenBLAS libraries loaded in this process
to one thread and restores their setting afterwards (the same mechanism as threadpoolctl, without
the dependency); it does nothing where no OpenBLAS is found.
"""
from __future__ import annotations

import contextlib
import ctypes

_SETTERS = ("openblas_set_num_threads", "openblas_set_num_threads64_", "scipy_openblas_set_num_threads64_",
            "scipy_openblas_set_num_threads")
_GETTERS = ("openblas_get_num_threads", "openblas_get_num_threads64_", "scipy_openblas_get_num_threads64_",
            "scipy_openblas_get_num_threads")


def _openblas_handles():
    out = []
    try:
        with open("/proc/self/maps", encoding="utf-8") as f:
            paths = {line.split()[-1] for line in f if "openblas" in line.lower() and "/" in line}
    except OSError:
        return out
    for path in sorted(paths):
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        setter = next((getattr(lib, n) for n in _SETTERS if hasattr(lib, n)), None)
        getter = next((getattr(lib, n) for n in _GETTERS if hasattr(lib, n)), None)
        if setter is not None and getter is not None:
            out.append((setter, getter))
    return out


@contextlib.contextmanager
def single_threaded_blas():
    """Run the block with every loaded OpenBLAS at one thread."""
    import scipy.linalg  # noqa: F401  (load scipy's BLAS too, so that it is found)
    handles = _openblas_handles()
    saved = []
    for setter, getter in handles:
        try:
            saved.append((setter, int(getter())))
            setter(1)
        except Exception:  # noqa: BLE001 - a foreign library: leave it alone
            continue
    try:
        yield
    finally:
        for setter, n in saved:
            setter(n)

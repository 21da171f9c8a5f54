"""How many threads the BLAS under numpy and scipy may use for mtcomp's small dense algebra."""
from __future__ import annotations


def one_blas_thread():
    """A context in which BLAS (numpy's and scipy's) runs on one thread, restored on exit.

    A fit's dense algebra is on matrices of a few hundred unknowns (eigen-decompositions, Cholesky
    factors, the penalty weights' search): too small for threads to pay, while threads that wait for
    a core, or spin after each call, cost processor time the fit's own thread needed. On a shared
    2-core machine the 100,000-point fit of benchmarks/bench_identify.py took 12 s of processor
    time with two BLAS threads and 2.1 s with one (docs/identification.md, *Performance*); its
    large products run on one thread too (block by block, each block in cache)."""
    from threadpoolctl import threadpool_limits
    return threadpool_limits(limits=1, user_api="blas")

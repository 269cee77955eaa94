"""The command line's BLAS threads: one, unless the user set the count (:func:`blas_threads_limited`)."""

from __future__ import annotations

import contextlib
import os
import sys
from typing import Any

__all__ = ["BLAS_THREAD_VARS", "blas_threads_limited"]

#: The environment variables that set the BLAS / OpenMP thread counts: a user who sets any of them decides.
BLAS_THREAD_VARS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


@contextlib.contextmanager
def blas_threads_limited() -> Any:
    """Within: one BLAS thread, unless the user set one of :data:`BLAS_THREAD_VARS`.

    casep's matrices are small (n <= a few hundred columns, rows reduced block by block), so BLAS
    threads buy little and, on a shared machine, cost much (OpenBLAS threads spin while they wait):
    on a loaded 2-core machine ``casep separate`` of a 100 Hz range flight took 158 s with two BLAS
    threads and 18 s with one (``python benchmarks/bench_blas_threads.py``, medians of 3).
    Before NumPy loads, the environment is set (the BLAS library reads it once, when it loads;
    child processes inherit it); after, threadpoolctl limits the loaded libraries, SciPy's own BLAS library (a
    second OpenBLAS beside NumPy's) loaded first, since one loaded later keeps its default threads.
    """
    if any(v in os.environ for v in BLAS_THREAD_VARS):
        yield
        return
    if "numpy" not in sys.modules:
        saved = {v: os.environ.get(v) for v in BLAS_THREAD_VARS}
        os.environ.update({v: "1" for v in BLAS_THREAD_VARS})
        try:
            yield
        finally:
            for v, old in saved.items():
                if old is None:
                    os.environ.pop(v, None)
                else:
                    os.environ[v] = old
        return
    import scipy.linalg  # noqa: F401  (SciPy's own BLAS library, loaded now so that the limit reaches it)
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1):
        yield

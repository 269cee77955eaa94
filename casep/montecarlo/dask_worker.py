"""Dask worker preload of ``casep montecarlo``'s LocalCluster: one BLAS thread; SIGINT ignored, SIGTERM ends it.

Ctrl-C reaches the whole process group; the parent handles it and closes the cluster, so a
worker must not die of it on its own (with a traceback). Runs in the worker process's main
thread (where :func:`signal.signal` is allowed) when the worker starts. Workers of a cluster of
one's own take it with ``dask worker ... --preload casep.montecarlo.dask_worker``. A forked worker
inherits the parent's Python handlers; SIGTERM goes back to the default (the nanny's
terminate ends the worker at once).
"""

from __future__ import annotations

import signal
import threading
from typing import Any

__all__ = ["dask_setup"]

_LIMITS: list[Any] = []  # the worker's thread-pool limit, held for its life


def dask_setup(worker: Any) -> None:  # noqa: ARG001 (Dask's preload hook)
    from threadpoolctl import threadpool_limits

    # one BLAS/OpenMP thread for the worker's life (a forked worker inherits the parent's pools;
    # Dask's OMP/OPENBLAS_NUM_THREADS=1 only reach a spawned one)
    _LIMITS.append(threadpool_limits(limits=1))
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)

"""Dask worker preload of ``casep montecarlo``'s LocalCluster: one BLAS thread; SIGINT ignored, SIGTERM ends it;
the worker ends with the process that started it.

Ctrl-C reaches the whole process group; the parent handles it and closes the cluster, so a
worker must not die of it on its own (with a traceback). Runs in the worker process's main
thread (where :func:`signal.signal` is allowed) when the worker starts. Workers of a cluster of
one's own take it with ``dask worker ... --preload casep.montecarlo.dask_worker``. A forked worker
inherits the parent's Python handlers; SIGTERM goes back to the default (the nanny's
terminate ends the worker at once).

Why the worker watches its parent itself (:func:`end_with_parent`): Dask's own watch is a pipe
whose write end only the parent holds, so that the worker reads end-of-file when the parent dies.
Forked workers inherit every descriptor open in the parent, including the write ends of the
pipes of the workers created before them; when two workers' pipes both exist before either
fork (the event loop creates the second while a thread forks the first, which happens on loaded
cores), each worker holds the other's pipe open and neither reads end-of-file: both outlive a
SIGKILLed parent for ever.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import sys
import threading
import time
from typing import Any

__all__ = ["dask_setup", "end_with_parent"]

_LIMITS: list[Any] = []  # the worker's thread-pool limit, held for its life

#: seconds between two looks at the parent process id
POLL_S = 0.25

_PR_SET_PDEATHSIG = 1  # linux/prctl.h


def _parent_death_signal() -> None:
    """Linux: the kernel sends SIGKILL to this process when the thread that forked it ends."""
    import ctypes

    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
    except (OSError, AttributeError):  # no prctl: the poll below remains
        pass


def end_with_parent(parent: int | None = None) -> None:
    """End this process (``os._exit(1)``) as soon as process `parent` is gone, however it died.

    Parameters
    ----------
    parent
        The id of the process whose death ends this one; default: the :mod:`multiprocessing` parent of this process
        (a Dask nanny, or ``casep montecarlo`` for its LocalCluster). Nothing happens if there is
        none (a worker started without a nanny).

    Notes
    -----
    On Linux a parent-death signal (``prctl(PR_SET_PDEATHSIG, SIGKILL)``) ends the process at once;
    everywhere a daemon thread compares :func:`os.getppid` with `parent` every :data:`POLL_S`
    seconds (a dead parent's children are re-parented, so the id changes), which also covers a
    parent that died before this call and a forking thread that ends before its process.
    """
    if parent is None:
        proc = multiprocessing.parent_process()
        if proc is None or proc.pid is None:
            return
        parent = proc.pid
    if sys.platform.startswith("linux"):
        _parent_death_signal()

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(POLL_S)
        os._exit(1)

    if os.getppid() != parent:  # died already
        os._exit(1)
    threading.Thread(target=watch, name="casep: end with parent", daemon=True).start()


def dask_setup(worker: Any) -> None:  # noqa: ARG001 (Dask's preload hook)
    from threadpoolctl import threadpool_limits

    end_with_parent()
    # one BLAS/OpenMP thread for the worker's life (a forked worker inherits the parent's pools;
    # Dask's OMP/OPENBLAS_NUM_THREADS=1 only reach a spawned one)
    _LIMITS.append(threadpool_limits(limits=1))
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)

"""Dask worker preload of ``casep montecarlo``'s LocalCluster: the worker ignores SIGINT.

Ctrl-C reaches the whole process group; the parent handles it and closes the cluster, so a
worker must not die of it on its own (with a traceback). Runs in the worker process's main
thread (where :func:`signal.signal` is allowed) when the worker starts.
"""

import signal
import threading


def dask_setup(worker) -> None:  # noqa: ARG001 (Dask's preload hook)
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)

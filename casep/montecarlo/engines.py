"""Where the tasks run: in this process, or on Dask; and how signals end a campaign.

An engine has one method, ``run(ctx, jobs)``: it takes ``(key, (linear, other, runs))`` jobs
(:func:`casep.montecarlo.tasks.run_task`'s arguments) and yields ``(key, result)`` as tasks
finish, in any order.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import sys
import threading
from collections.abc import Iterable, Iterator
from contextlib import ExitStack, contextmanager
from typing import Any

from casep.montecarlo.tasks import Context, run_task

__all__ = ["DaskEngine", "InProcess", "Terminated", "sigterm_raises"]

Job = tuple[Any, tuple[Any, ...]]


def _fresh_offload_executor() -> None:
    """In a forked child: a new executor for :func:`distributed.utils.offload` (registered with
    :func:`os.register_at_fork` when this module is imported; nothing when Dask is not loaded).

    Dask runs part of its work on one module-level thread (``distributed.utils._offload_executor``): the
    scheduler orders every submitted graph there, and the comms (de)serialise messages over 10 MiB there. A
    fork copies that executor but not its thread, and the executor never starts another one (its count of
    threads is already at its maximum), so in a child forked from a process that has used Dask the work sent to
    it never runs: a cluster started in that child (a campaign in a forked process) waits for ever on its
    first submitted task, and a worker forked from such a process (``casep montecarlo``'s LocalCluster forks
    its workers) for ever on its first message over 10 MiB. Measured: a Monte Carlo in a forked child of a
    process that had run one campaign hung until killed, every time; with this hook it ran 9 times of 9. A fork
    of a process with other Dask threads alive can still hang on a lock one of them held (2 of 6 forked test
    runs): the test suite starts its Dask example in a new interpreter.
    """
    utils: Any = sys.modules.get("distributed.utils")
    if utils is None or not hasattr(utils, "_offload_executor"):
        return
    from concurrent.futures import ThreadPoolExecutor

    utils._offload_executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="Dask-Offload")


if hasattr(os, "register_at_fork"):  # POSIX
    os.register_at_fork(after_in_child=_fresh_offload_executor)


class InProcess:
    """Tasks run here, in order (``workers=1``)."""

    def run(self, ctx: Context, jobs: Iterable[Job]) -> Iterator[tuple[Any, dict[str, Any]]]:
        for key, args in jobs:
            yield key, run_task(ctx, *args)


class Terminated(BaseException):
    """SIGTERM received (see :func:`sigterm_raises`); like KeyboardInterrupt, not an Exception."""


@contextmanager
def sigterm_raises() -> Iterator[None]:
    """Within: SIGTERM raises :class:`Terminated` in the main thread (elsewhere a no-op).

    So that ``casep montecarlo`` ends its workers and exits 143 with one line instead of
    dying with them orphaned.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum: int, frame: Any) -> None:
        raise Terminated

    old = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old)


@contextmanager
def _deferred_signals() -> Iterator[None]:
    """Within: SIGINT and SIGTERM are held, then re-raised to the handlers of before (main thread)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    got: list[int] = []
    old = {s: signal.signal(s, lambda signum, frame: got.append(signum)) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h)
        if got:
            signal.raise_signal(got[0])


def _ending_workers_at_once(cluster: Any) -> Any:
    """An exit callback for the stack that holds `cluster`: when the campaign ends by an exception (Ctrl-C,
    SIGTERM, an error), the local worker processes are sent SIGTERM (the preload restores its default action:
    :mod:`casep.montecarlo.dask_worker`) before the cluster closes. A worker busy in a task does not answer
    the nanny's request to close, and the nanny waits for it (about 4 s on two workers) before it kills; its
    task's result would be thrown away anyway. A campaign that ends normally closes its idle workers as usual."""
    import logging

    def on_exit(exc_type: Any, exc: Any, tb: Any) -> bool:
        if exc_type is not None:
            logging.getLogger("distributed").setLevel(logging.CRITICAL)  # the closed comms are expected
            for nanny in list(getattr(cluster, "workers", {}).values()):
                pid = getattr(getattr(nanny, "process", None), "pid", None)
                if pid:
                    try:
                        os.kill(pid, signal.SIGTERM)
                    except OSError:  # already gone
                        pass
        return False  # the exception goes on

    return on_exit


class DaskEngine:
    """Tasks on a Dask cluster: a LocalCluster of `workers` single-threaded processes, or `scheduler`.

    The local workers ignore SIGINT (:mod:`casep.montecarlo.dask_worker`: Ctrl-C reaches the
    whole process group; this process handles it and closes the cluster) and have one BLAS
    thread (Dask's pre-spawn environment sets OMP/MKL/OPENBLAS_NUM_THREADS=1; each task also
    limits it by threadpoolctl, which covers remote workers). They end with this process, even
    on SIGKILL (the preload's :func:`~casep.montecarlo.dask_worker.end_with_parent`). The cluster
    and client close with `stack`.
    """

    def __init__(self, stack: ExitStack, workers: int, scheduler: str | None) -> None:
        import logging

        import dask
        from distributed import Client, LocalCluster

        # An interrupted cluster's closing can leave asyncio tasks failed on closed comms; asyncio
        # logs them ("Task exception was never retrieved") on stderr: not ours to show.
        aio = logging.getLogger("asyncio")
        stack.callback(aio.setLevel, aio.level)
        aio.setLevel(logging.CRITICAL)
        dist = logging.getLogger("distributed")  # quietened while ending workers at once (below)
        stack.callback(dist.setLevel, dist.level)
        if scheduler:
            try:
                self.client = stack.enter_context(Client(scheduler, timeout="20s"))
            except OSError as exc:  # unreachable: say which option
                raise ValueError(f"--scheduler {scheduler}: no Dask scheduler answers there ({exc})") from None
        else:
            # dashboard_address ":0": the scheduler's HTTP server (no dashboard without bokeh) on a
            # free port; None still binds 8787 and warns when another cluster holds it
            # Forked workers inherit casep, NumPy, SciPy and numba's compiled kernels already loaded
            # here; spawned ones import and compile them again (measured: ~3 s of CPU per worker).
            # Python >= 3.12 deprecates fork in a threaded process: spawn there.
            fork = "fork" in multiprocessing.get_all_start_methods() and sys.version_info < (3, 12)
            with _deferred_signals(), dask.config.set(
                    {"distributed.worker.multiprocessing-method": "fork" if fork else "spawn"}):
                cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                       dashboard_address=":0", silence_logs=logging.CRITICAL,
                                       preload=["casep.montecarlo.dask_worker"])
                stack.enter_context(cluster)
                stack.push(_ending_workers_at_once(cluster))
                self.client = stack.enter_context(Client(cluster))
        self.ctx_future: Any = None

    def run(self, ctx: Context, jobs: Iterable[Job]) -> Iterator[tuple[Any, dict[str, Any]]]:
        from distributed import as_completed

        if self.ctx_future is None:  # the campaign's data go to every worker once
            self.ctx_future = self.client.scatter(ctx, broadcast=True, hash=False)
        futures = {self.client.submit(run_task, self.ctx_future, *args, pure=False): key for key, args in jobs}
        try:
            for fut in as_completed(futures):
                yield futures[fut], fut.result()
        finally:
            self.client.cancel(list(futures))

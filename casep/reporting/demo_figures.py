"""The figures of ``casep demo`` (:mod:`casep.workflows.demo`), and the worker process that draws them.

Each figure function takes plain arrays and writes one PNG (:func:`casep.reporting.plots.save_figure`), so
that it can run in another process: :class:`FigureJobs` draws the figures in one worker process (a new
interpreter, ``python -m casep.reporting.demo_figures``) while the demo computes, each figure as soon as its
data exist, or here and now without a worker. The worker imports matplotlib while the demo simulates its
flight (:func:`warm_up`); on two or more cores, the figures cost the demo little wall time. The same
functions draw the same pixels in either process.

The titles are placed at the top of their panel (``y=1.0``, where matplotlib would put them anyway: no
panel has tick labels or an offset text above it) instead of being placed by measuring every tick label
of the panel first.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Mapping, Sequence

from casep._cores import usable_cores

if TYPE_CHECKING:  # NumPy is imported by the figures: ``casep demo`` starts the worker before it imports NumPy
    import numpy as np

__all__ = ["FigureJobs", "plot_demo_residuals", "plot_coefficient_errors", "plot_rels_convergence", "warm_up",
           "spare_core", "serve"]


def _band(ax: Any, t: np.ndarray, r: np.ndarray, bins: int = 1000) -> None:
    """Residuals against time as their min-max band per time bin (what a 1000-pixel-wide line of
    19 501 noisy samples shows anyway, drawn in half the time)."""
    k = t.size // bins
    if k < 2:
        ax.plot(t, r, lw=0.5)
        return
    m = k * bins
    tb, rb = t[:m].reshape(bins, k), r[:m].reshape(bins, k)
    ax.fill_between(tb[:, 0], rb.min(axis=1), rb.max(axis=1), lw=0, color="C0", step="post")
    if m < t.size:
        ax.plot(t[m:], r[m:], lw=0.5, color="C0")


def plot_demo_residuals(path: str | os.PathLike, t: np.ndarray, residuals: np.ndarray, title: str) -> Path:
    """Velocity residuals (N, 3), m/s, against time `t` (N,), s: one panel per axis (Figures 3-4 of the paper)."""
    from casep.reporting.plots import pyplot, save_figure, set_margins

    plt = pyplot()
    fig, axes = plt.subplots(3, 1, figsize=(8, 6), sharex=True)
    for i, ax in enumerate(axes):
        _band(ax, t, residuals[:, i])
        ax.set_ylabel(f"{'xyz'[i]} (m/s)")
        ax.grid(alpha=0.3)
    axes[0].set_title(title, fontsize=10, y=1.0)
    axes[-1].set_xlabel("time (s)")
    set_margins(fig, left=0.95, right=0.12, bottom=0.5, top=0.28, hspace=0.12)  # y ticks up to 6 characters
    return save_figure(fig, path, layout=None)


def plot_coefficient_errors(path: str | os.PathLike, names: Sequence[str], errors: Mapping[str, np.ndarray]) -> Path:
    """``|estimate - true| / CRLB std`` of each coefficient (log scale), one marker colour per method
    (`errors`: method label -> (n,) array, in legend order), with the 1 and 2 std lines."""
    import numpy as np

    from casep.reporting.plots import plain_log_ticks, pyplot, save_figure, set_margins

    plt = pyplot()
    fig, ax = plt.subplots(figsize=(11, 4.5))
    x = np.arange(len(names))
    for k, (label, z) in enumerate(errors.items()):
        ax.semilogy(x + (k - 3) * 0.08, z, "o", ms=3, label=label)
    plain_log_ticks(ax.yaxis)
    ax.axhline(1.0, color="k", lw=1, ls="--")
    ax.axhline(2.0, color="k", lw=0.8, ls=":")
    ax.set_xticks(x, list(names), rotation=90, fontsize=7)
    ax.set_ylabel("|estimate - true| / CRLB std")
    ax.set_title("Error of each coefficient against its Cramer-Rao std (one flight)", y=1.0)
    ax.legend(fontsize=7, ncol=4)
    ax.grid(True, which="both", alpha=0.3)
    set_margins(fig, left=0.85, right=0.12, bottom=0.55, top=0.3)
    return save_figure(fig, path, layout=None)


def plot_rels_convergence(path: str | os.PathLike, t: np.ndarray, z: np.ndarray, names: Sequence[str]) -> Path:
    """RELS estimates against time in units of the final CRLB std: `z` (K, m), ``(estimate - true) / std``
    at the times `t` (K,), s, of the coefficients `names` (m), with the +-2 std band."""
    from casep.reporting.plots import pyplot, save_figure, set_margins

    plt = pyplot()
    fig, ax = plt.subplots(figsize=(8, 4))
    for j, name in enumerate(names):
        ax.plot(t, z[:, j], lw=1, label=name)
    ax.axhspan(-2, 2, color="0.9", zorder=0)
    ax.set_ylim(-10, 10)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("(estimate - true) / final CRLB std")
    ax.set_title("RELS convergence of the six best-determined coefficients", y=1.0)
    ax.legend(fontsize=8, ncol=3)
    ax.grid(alpha=0.3)
    set_margins(fig, left=0.8, right=0.12, bottom=0.5, top=0.3)
    return save_figure(fig, path, layout=None)


def warm_up() -> None:
    """Import matplotlib's pyplot on the Agg backend and draw a small figure with a log axis to memory: the
    fonts and the text layout are loaded once, by the worker,
    while the demo simulates (the figures' pixels do not depend on it)."""
    import io

    from casep.reporting.plots import plain_log_ticks, pyplot

    plt = pyplot()
    fig, ax = plt.subplots(figsize=(2, 2))
    ax.semilogy([1.0, 2.0], [1e-3, 1e2], "o-")
    plain_log_ticks(ax.yaxis)
    ax.set_title("warm-up", fontsize=9)
    fig.savefig(io.BytesIO(), format="png", dpi=20)
    plt.close(fig)


def spare_core() -> bool:
    """Whether a worker process would run beside this one: two or more usable cores, and a 1-minute load
    average below their number where the platform tells it.

    On a busy machine a second process gains no CPU time (Linux shares the CPU between sessions, not
    between processes, when its scheduler groups them, as it does by default), and the worker's start-up
    (a new interpreter importing NumPy and matplotlib, about 0.5 s of CPU more than drawing here) is lost.
    """
    n = usable_cores()  # casep._cores: the CPU affinity, as Monte Carlo's default worker count
    if n < 2:
        return False
    try:
        return os.getloadavg()[0] < n
    except (AttributeError, OSError):  # pragma: no cover - no load average (Windows)
        return True


class FigureJobs:
    """Figures drawn in one worker process as they are submitted, or here and now (``parallel=False``).

    The worker is ``python -m casep.reporting.demo_figures`` (:func:`serve`): it imports matplotlib while
    the caller goes on, then draws each figure it is sent, in order. A job is a figure function of this module
    or of :mod:`casep.reporting.plots` with its arguments (picklable: arrays, plain data, results), sent
    through the worker's standard input by a thread of this process, so that :meth:`draw` never waits for
    the worker. A new interpreter rather than :mod:`multiprocessing`: no fork of a process that may hold
    threads, and no import of the caller's main script (a script that calls :func:`casep.run_demo` at its
    top level works as it is).

    Use as a context manager: leaving it waits for every figure (a failed figure raises its error here, a
    worker that stopped raises RuntimeError); leaving it by an error stops the worker.
    """

    def __init__(self, parallel: bool) -> None:
        self._proc: Any = None
        self._jobs: list[Any] = []
        if parallel:
            import queue
            import subprocess
            import threading

            self._proc = subprocess.Popen([sys.executable, "-m", "casep.reporting.demo_figures"],
                                          stdin=subprocess.PIPE, stdout=subprocess.PIPE)
            self._queue: queue.SimpleQueue[Any] = queue.SimpleQueue()
            self._feeder = threading.Thread(target=self._feed, daemon=True)
            self._feeder.start()

    def _feed(self) -> None:
        """Write the queued jobs to the worker (None: close its input), in this thread."""
        import pickle

        stdin = self._proc.stdin
        try:
            while (job := self._queue.get()) is not None:
                pickle.dump(job, stdin, protocol=pickle.HIGHEST_PROTOCOL)
                stdin.flush()
        except OSError:  # the worker stopped: said when its results are read
            pass
        finally:
            try:
                stdin.close()
            except OSError:
                pass

    def draw(self, fn: Callable[..., Any], *args: Any) -> None:
        """Draw one figure: ``fn(*args)``, in the worker when there is one."""
        if self._proc is None:
            fn(*args)
        else:
            self._queue.put((fn, args))
            self._jobs.append(fn)

    def __enter__(self) -> FigureJobs:
        return self

    def __exit__(self, kind: Any, exc: Any, tb: Any) -> None:
        if self._proc is None:
            return
        import pickle

        self._queue.put(None)  # no more jobs: the worker ends when it has drawn those it has
        failed = kind is not None  # an error here: the figures are not waited for
        try:
            for fn in () if failed else self._jobs:
                try:
                    ok, value = pickle.load(self._proc.stdout)
                except EOFError:
                    raise RuntimeError(f"the figure worker stopped before drawing {fn.__name__} "
                                       f"(exit status {self._proc.wait()})") from None
                if not ok:
                    raise value
        except BaseException:
            failed = True  # a figure failed: the others are not waited for
            raise
        finally:
            if failed and self._proc.poll() is None:
                self._proc.kill()
            self._feeder.join()
            self._proc.stdout.close()
            self._proc.wait()


def serve() -> None:
    """The worker of :class:`FigureJobs`: read pickled ``(function, args)`` jobs from standard input until it
    closes; run each; write ``(True, result)`` or ``(False, exception)`` to standard output for each."""
    import gc
    import pickle

    src, dst = sys.stdin.buffer, sys.stdout.buffer
    sys.stdout = sys.stderr  # standard output carries the results only
    warm_up()
    gc.freeze()  # the modules' objects, alive to the end: left out of the garbage collections that follow
    while True:
        try:
            fn, args = pickle.load(src)
        except EOFError:
            gc.freeze()  # and out of the interpreter's collections at exit (0.4-0.6 s of CPU with matplotlib)
            return
        try:
            reply: tuple[bool, Any] = (True, fn(*args))
        except Exception as exc:  # noqa: BLE001 - any failure goes back to the caller, which raises it
            reply = (False, exc)
        try:
            data = pickle.dumps(reply)
        except Exception:  # noqa: BLE001 - an exception that does not pickle: its text
            data = pickle.dumps((False, RuntimeError(f"{type(reply[1]).__name__}: {reply[1]}")))
        dst.write(data)
        dst.flush()


if __name__ == "__main__":
    try:
        serve()
    except (KeyboardInterrupt, BrokenPipeError):  # Ctrl-C reaches the worker too; the demo says it stopped
        sys.exit(1)

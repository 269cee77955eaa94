"""How a ``casep`` process ends: without the interpreter's last garbage collections (:func:`freeze_at_exit`)."""

from __future__ import annotations

__all__ = ["freeze_at_exit"]


def freeze_at_exit() -> None:
    """Leave the objects alive at exit out of the interpreter's last garbage collections (registered once).

    While it unloads the modules at exit, the interpreter collects garbage several times over every object
    still alive: once the command had finished, that took 0.5-1.1 s of CPU after ``casep demo`` (CasADi, numba,
    SciPy and NumPy loaded) and 0.2-0.4 s after ``casep separate`` of the example flight. :func:`gc.freeze` at
    exit (an atexit function, so only when the process ends, whoever called :func:`casep.cli.main`) moves them
    out of those collections; objects freed by their reference counts are freed as before, reference cycles
    still alive at exit are left to the end of the process.
    """
    import atexit
    import gc

    atexit.unregister(gc.freeze)
    atexit.register(gc.freeze)

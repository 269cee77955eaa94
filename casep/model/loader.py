"""Find and load model files (``models/*.py``, each with one ``build()`` function).

A model is named either by a path to a ``.py`` file or by a name looked up, in order, in the
folders of the ``CASEP_MODEL_PATH`` environment variable (``os.pathsep``-separated) and in
casep's built-in model folder. Files are loaded with
:func:`importlib.util.spec_from_file_location`; ``sys.path`` is never touched.

A model file is Python and **runs as code** with the rights of the user: casep loads one only
from its built-in model folder, a folder of ``CASEP_MODEL_PATH`` or a path given explicitly
(``--model path/to/file.py``), never from the current directory by name. Treat a model file
like any script you run.

A file that does not compile, raises or calls ``sys.exit`` while loading or in ``build()``
gives a one-line :class:`ModelFileError` (a :class:`casep.ModelDefinitionError`; the command
line prints it and exits 2) naming the file and the line: the SyntaxError's line, or the
deepest line of the traceback inside the model file.
"""

from __future__ import annotations

import contextlib
import importlib.util
import math
import os
import signal
import threading
import time
import traceback
from pathlib import Path
from typing import Any, Sequence

from casep.model._model import ErrorModel, ModelDefinitionError
from casep.model.base import SymbolicModel

__all__ = ["ModelFileError", "build_model", "load_model", "model_dirs", "available_models", "find_model_file",
           "run_model_file", "with_time_offset", "TIME_OFFSET", "model_file_reference", "model_names", "where_in_file",
           "load_model_file"]


def model_dirs() -> list[Path]:
    """Folders searched for a model given by name, in search order."""
    dirs = [Path(p) for p in os.environ.get("CASEP_MODEL_PATH", "").split(os.pathsep) if p]
    here = Path(__file__).resolve().parents[1]  # the casep package
    # Installed wheel: casep/models; source checkout or editable install: <repo>/models.
    for cand in (here / "models", here.parent / "models"):
        if cand.is_dir() and cand not in dirs:
            dirs.append(cand)
    return dirs


def model_names(dirs: Sequence[Path]) -> list[str]:
    """Names of the model files (``*.py``, not ``_*``) in `dirs`, in search order (first one wins on a clash)."""
    seen: list[str] = []
    for d in dirs:
        for p in sorted(d.glob("*.py")):
            if not p.name.startswith("_") and p.stem not in seen:
                seen.append(p.stem)
    return seen


def available_models() -> list[str]:
    """Names of the models found in :func:`model_dirs` (first one wins on a clash)."""
    return model_names(model_dirs())


def find_model_file(model: str | os.PathLike, dirs: Sequence[Path] | None = None, *, what: str = "model",
                    use: str = "a path to a .py file with a build() function") -> Path:
    """Resolve a model name or path to its file.

    Raises
    ------
    ValueError
        When nothing matches; the message lists the available models.
    """
    if not isinstance(model, (str, os.PathLike)):
        raise TypeError(f"`model` must be a name or a path, got {type(model).__name__}")
    text = os.fspath(model)
    if text.endswith(".py") or os.sep in text or (os.altsep and os.altsep in text):
        path = Path(text)
        if not path.is_file():
            raise ValueError(f"model file `{text}` does not exist")
        return path
    dirs = model_dirs() if dirs is None else list(dirs)
    for d in dirs:
        path = d / f"{text}.py"
        if path.is_file():
            return path
    raise ValueError(f"unknown {what} `{text}`. Use one of: {', '.join(model_names(dirs)) or '(none found)'}; "
                     f"or {use}")


class ModelFileError(ModelDefinitionError):
    """A model file fails to load: the message names the file and, where known, the line."""


def where_in_file(path: Path, exc: BaseException) -> str:
    """``model file <path>, line <n>``: the line of `exc` in `path` (its deepest frame there)."""
    line = None
    if isinstance(exc, SyntaxError) and exc.filename and Path(exc.filename).resolve() == path.resolve():
        line = exc.lineno
    else:
        target = path.resolve()
        for frame, lineno in traceback.walk_tb(exc.__traceback__):
            if Path(frame.f_code.co_filename).resolve() == target:
                line = lineno  # keep the deepest
    return f"model file {path}" + (f", line {line}" if line else "")


def _describe(exc: BaseException) -> str:
    """One line: ``NameError: name 'ca' is not defined`` (a SyntaxError without its location)."""
    if isinstance(exc, SystemExit):
        return f"SystemExit({exc.code!r}): a model file must not exit; build() must return a casep.ErrorModel"
    msg = exc.msg if isinstance(exc, SyntaxError) else str(exc)
    msg = " ".join(str(msg).split())
    return f"{type(exc).__name__}: {msg}" if msg else type(exc).__name__


#: Longest a model file may take to load and build, s (``CASEP_MODEL_TIMEOUT`` overrides it): the
#: built-in models take well under a second; a file that loops forever ends with a ModelFileError.
MODEL_LOAD_TIMEOUT_S = 60.0


class _LoadTimeout(BaseException):
    """Raised by the alarm inside a model file that takes too long (never leaves this module); a
    BaseException, so that an ``except Exception`` in the model file does not swallow it."""


def _timeout_s() -> float:
    text = os.environ.get("CASEP_MODEL_TIMEOUT", "")
    try:
        v = float(text) if text else MODEL_LOAD_TIMEOUT_S
    except ValueError:
        raise ModelDefinitionError(f"CASEP_MODEL_TIMEOUT must be a number of seconds, got {text!r}") from None
    if not (v > 0 and math.isfinite(v)):
        raise ModelDefinitionError(f"CASEP_MODEL_TIMEOUT must be finite and > 0 s, got {text!r}")
    return v


@contextlib.contextmanager
def _time_limit(seconds: float):
    """Raise :class:`_LoadTimeout` in this thread after `seconds` (a real-time interval timer, SIGALRM).

    Only on the main thread of a POSIX process (where Python delivers signals); elsewhere (a worker
    thread, Windows) no limit. The timer and handler in place before are put back, with the time
    spent here taken off a pending timer. A loop inside a C extension is interrupted only when it
    returns to Python.
    """
    if not hasattr(signal, "setitimer") or threading.current_thread() is not threading.main_thread():
        yield
        return

    def alarm(signum, frame):
        raise _LoadTimeout

    start = time.monotonic()
    old_handler = signal.signal(signal.SIGALRM, alarm)
    old_delay, old_interval = signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old_handler)
        if old_delay > 0:  # someone else's timer: what is left of it
            signal.setitimer(signal.ITIMER_REAL, max(old_delay - (time.monotonic() - start), 1e-6), old_interval)


def run_model_file(path: Path, kind: type[SymbolicModel] = ErrorModel) -> Any:
    """Execute the model file and its ``build()``; any failure becomes a one-line ModelFileError,
    and so does taking longer than :data:`MODEL_LOAD_TIMEOUT_S` (``CASEP_MODEL_TIMEOUT``).

    `kind`: the class ``build()`` must return (:class:`ErrorModel`,
    :class:`casep.model.tracking.TrackingModel` for a tracking model file,
    :class:`casep.calibration.CalibrationModel` for a ground-test model file).
    """
    spec = importlib.util.spec_from_file_location(f"casep_model_{path.stem}", path)
    if spec is None or spec.loader is None:
        raise ModelFileError(f"model file {path}: cannot be loaded as Python")
    module = importlib.util.module_from_spec(spec)
    stage = "loading"
    limit = _timeout_s()
    try:
        with _time_limit(limit):
            spec.loader.exec_module(module)
            build = getattr(module, "build", None)
            if not callable(build):
                raise ModelFileError(f"model file {path}: Missing: build(). Use: def build() -> {kind.PUBLIC_NAME}")
            stage = "build()"
            result = build()
    except _LoadTimeout as exc:
        raise ModelFileError(f"{where_in_file(path, exc)}{', in build()' if stage == 'build()' else ''}: still running "
                             f"after {limit:g} s (an endless loop?); a model file should load in well under a "
                             "second (limit: CASEP_MODEL_TIMEOUT=SECONDS)") from None
    except ModelFileError:
        raise  # from this file, or from a model it extends (that one names its own file)
    except (Exception, SystemExit) as exc:  # KeyboardInterrupt still interrupts
        where = where_in_file(path, exc)
        raise ModelFileError(f"{where}{', in build()' if stage == 'build()' else ''}: {_describe(exc)}") from exc
    if not isinstance(result, kind):
        uses = {"TrackingModel": "a tracking model: use it with --tracking-model (casep.load_tracking_model)",
                "ErrorModel": "an instrument model: use it with --model (casep.load_model)",
                "CalibrationModel": "a ground-test model: use it with casep calibrate "
                                    "(casep.calibration.load_calibration_model)"}
        use = uses.get(type(result).__name__, "")
        raise ModelFileError(f"model file {path}: build() returned {type(result).__name__}, not {kind.PUBLIC_NAME}"
                             + (f"; it is {use}" if use else ""))
    # Where the model came from (results record it when its name alone does not find it) and the
    # file's docstring (casep models -v); a model extending another keeps the outermost file's.
    if isinstance(result, ErrorModel):
        result.source_file = str(path.resolve())
        result.source_doc = (module.__doc__ or "").strip()
    return result


_run_file = run_model_file  # the instrument-model case


def build_model(model: str | os.PathLike) -> ErrorModel:
    """Run a model file's ``build()`` and return the model *unlocked*.

    Use this to extend a model in another model file; :func:`load_model` for use.

    Raises
    ------
    ModelFileError
        (a :class:`ModelDefinitionError`) when the file does not compile, raises or exits
        while loading or in ``build()``, or returns something else than an ErrorModel: one line
        naming the file and the line of the file where it failed.
    """
    return _run_file(find_model_file(model))


def load_model(model: str | os.PathLike | ErrorModel) -> ErrorModel:
    """Load a model by name or path and set it up (an :class:`ErrorModel` is set up as is).

    Parameters
    ----------
    model : str, path or ErrorModel
        ``"platform36"``, ``"models/my_model.py"`` or a declared model.

    Returns
    -------
    ErrorModel
        Locked, with its Jacobian functions built.
    """
    if isinstance(model, ErrorModel):
        return model.setup()
    return load_model_file(find_model_file(model))


def load_model_file(path: Path, kind: type[SymbolicModel] = ErrorModel) -> Any:
    """:func:`run_model_file` and ``setup()``: the model of the file, set up; a setup error names the file."""
    built = run_model_file(path, kind)
    try:
        return built.setup()
    except ModelFileError:
        raise
    except ModelDefinitionError as exc:  # setup()'s checks name the term; add the file
        raise ModelFileError(f"model file {path}: {exc}") from exc


#: The tracking time offset term every model can gain (:func:`with_time_offset`).
TIME_OFFSET = "dt_trk"


def with_time_offset(model: str | os.PathLike | ErrorModel) -> ErrorModel:
    """A model plus the tracking time offset ``dt_trk`` (ms, per flight), set up.

    Tracking time tags late by ``dt_trk`` give ``v_trk(t) = v(t - dt_trk) ~ v(t) - a(t) dt_trk``, so
    ``dv`` gains ``a(t) dt_trk`` with ``a`` the kinematic acceleration (flight signals ``a_x``,
    ``a_y``, ``a_z``; :func:`casep.io.files.read_flight_pair` derives them from the telemetry
    velocity when the file has none). A model that has ``dt_trk`` already is returned as it is.
    """
    import casadi as ca

    base = load_model(model)
    if TIME_OFFSET in base.names:
        return base
    source = model if isinstance(model, (str, os.PathLike)) else base.name
    m = build_model(source)  # unlocked: the term is added to it
    m.name = f"{base.name}+dt_trk"
    m.source_file = None  # a derived model: its file alone does not build it (no model_file in results)
    m.description = f"{base.description or base.name} + tracking time offset dt_trk (ms, per flight)"
    c = m.declare(dt_trk=("ms", 20.0), per_flight=True)  # tracking time-tag delay, ms (SI: s)
    a = ca.vertcat(m.signal("a_x"), m.signal("a_y"), m.signal("a_z"))  # kinematic acceleration, m/s^2
    m.set_velocity_error(m.output("velocity_error") + a * c.dt_trk)  # dv += a(t) dt_trk (a lever arm kept)
    m.setup()
    return m


def model_file_reference(model: ErrorModel) -> str | None:
    """The model's file when its name alone does not find that file (a model loaded from a path), else None.

    A result records it (``model_file``) so that a later ``impact`` or ``fuse`` finds the model again.
    """
    src = getattr(model, "source_file", None)
    if not src:
        return None
    try:
        found = find_model_file(model.name)
    except (ValueError, TypeError):
        return src
    return None if str(found.resolve()) == src else src

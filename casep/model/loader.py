"""Find and load model files (``models/*.py``, each with one ``build()`` function).

A model is named either by a path to a ``.py`` file or by a name looked up, in order, in the
folders of the ``CASEP_MODEL_PATH`` environment variable (``os.pathsep``-separated) and in
casep's built-in model folder. Files are loaded with
:func:`importlib.util.spec_from_file_location`; ``sys.path`` is never touched.

A model file is Python and **runs as code** with the rights of the user: casep loads one only
from its built-in model folder, a folder of ``CASEP_MODEL_PATH`` or a path given explicitly
(``--model path/to/file.py``), never from the current directory by name. Treat a model file
like any script you run. Before it runs a model file that is not shipped with casep, casep says so
on stderr (``casep: running model file PATH``), once per file and process.

A model named by a *file* (a result, prior, truth or manifest) is never run on the file's word:
:func:`load_recorded_model` loads a model shipped with casep by its name, and any other model only
when the user names it (``--model``, API ``model=``); the SHA-256 a result records for its model
file (``model_sha256``, :func:`model_record`) must then be that of the file named.

A file that does not compile, raises or calls ``sys.exit`` while loading or in ``build()``
gives a one-line :class:`ModelFileError` (a :class:`casep.ModelDefinitionError`; the command
line prints it and exits 2) naming the file and the line: the SyntaxError's line, or the
deepest line of the traceback inside the model file.
"""

from __future__ import annotations

import contextlib
import hashlib
import importlib.util
import math
import os
import signal
import sys
import threading
import time
import traceback
from pathlib import Path
from typing import Any, Sequence, TypedDict

from casep.model.base import SymbolicModel
from casep.model.error_model import ErrorModel, ModelDefinitionError

__all__ = ["ModelFileError", "build_model", "load_model", "model_dirs", "available_models", "find_model_file",
           "run_model_file", "with_time_offset", "add_time_offset",
           "TIME_OFFSET", "TIME_OFFSET_MAGNITUDE_MS", "model_file_reference", "model_names", "where_in_file",
           "load_model_file", "shipped_model_dirs", "shipped_model_file", "model_record",
           "load_recorded_model", "shipped_model", "default_model", "PHI0_MODELS", "RICHER_MODELS"]


def shipped_model_dirs() -> list[Path]:
    """The folders of the models shipped with casep: ``casep/models`` (an installed wheel) and the
    source checkout's ``models/`` (an editable install)."""
    here = Path(__file__).resolve().parents[1]  # the casep package
    return [cand for cand in (here / "models", here.parent / "models") if cand.is_dir()]


def model_dirs() -> list[Path]:
    """Folders searched for a model given by name, in search order (``CASEP_MODEL_PATH``, then shipped)."""
    dirs = [Path(p) for p in os.environ.get("CASEP_MODEL_PATH", "").split(os.pathsep) if p]
    return dirs + [d for d in shipped_model_dirs() if d not in dirs]


def shipped_model_file(name: str) -> Path | None:
    """The file of the model shipped with casep called `name` (a plain name, no path), or None."""
    if not name or name.endswith(".py") or any(c in name for c in ("/", "\\", os.sep)) or name.startswith(("_", ".")):
        return None
    for d in shipped_model_dirs():
        path = d / f"{name}.py"
        if path.is_file():
            return path
    return None


def _is_shipped(path: str | os.PathLike) -> bool:
    real = Path(path).resolve()
    return any(real.parent == d.resolve() for d in shipped_model_dirs())


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
    try:
        source = Path(path).read_bytes()  # the bytes hashed are the bytes run
    except OSError as exc:
        raise ModelFileError(f"model file {path}: cannot read ({exc.strerror})") from None
    _announce(path)
    stage = "loading"
    limit = _timeout_s()
    try:
        with _time_limit(limit):
            exec(compile(source, str(path), "exec"), module.__dict__)  # a model file is code (module notes)
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
        result.source_sha256 = hashlib.sha256(source).hexdigest()
    return result


_announced: set[str] = set()


def _announce(path: Path) -> None:
    """``casep: running model file PATH`` on stderr before a model file not shipped with casep runs
    (once per file and process): a file that hangs or misbehaves is named before it does."""
    real = str(Path(path).resolve())
    if real in _announced or _is_shipped(real):
        return
    _announced.add(real)
    print(f"casep: running model file {path}", file=sys.stderr, flush=True)


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
        ``"platform36"``, ``"models/my_model.py"`` or a declared model; a name or path ending in ``+dt_trk``
        (``"platform36+dt_trk"``): that model with the tracking time offset added (:func:`with_time_offset`).

    Returns
    -------
    ErrorModel
        Locked, with its Jacobian functions built.
    """
    if isinstance(model, ErrorModel):
        return model.setup()
    if str(model).endswith(TIME_OFFSET_SUFFIX) and str(model) != TIME_OFFSET_SUFFIX:  # platform36+dt_trk
        return with_time_offset(str(model)[: -len(TIME_OFFSET_SUFFIX)])
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
#: The name of a model with the term added: ``platform36+dt_trk``.
TIME_OFFSET_SUFFIX = "+" + TIME_OFFSET
#: The declared magnitude of ``dt_trk``, ms: the tracking time-tag delay a model with the term expects.
TIME_OFFSET_MAGNITUDE_MS = 20.0


def with_time_offset(model: str | os.PathLike | ErrorModel) -> ErrorModel:
    """A model plus the tracking time offset ``dt_trk`` (ms, per flight), set up.

    Tracking time tags late by ``dt_trk`` give ``v_trk(t) = v(t - dt_trk) ~ v(t) - a(t) dt_trk``, so
    ``dv`` gains ``a(t) dt_trk`` with ``a`` the kinematic acceleration (flight signals ``a_x``,
    ``a_y``, ``a_z``; :func:`casep.io.files.read_flight_pair` derives them from the telemetry
    velocity when the file has none). A model that has ``dt_trk`` already is returned as it is.
    """
    base = load_model(model)
    if TIME_OFFSET in base.names:
        return base
    source = model if isinstance(model, (str, os.PathLike)) else (base.source_file or base.name)
    m = add_time_offset(build_model(source))  # unlocked: the term is added to it
    m.setup()
    return m


def base_model_name(name: str) -> str:
    """The name of the model without the per-flight tracking time offset :func:`with_time_offset` adds
    (``platform36+dt_trk`` -> ``platform36``): the instrument's model, which flights with and without the term share."""
    return name[: -len(TIME_OFFSET_SUFFIX)] if name.endswith(TIME_OFFSET_SUFFIX) and name != TIME_OFFSET_SUFFIX \
        else name


def add_time_offset(m: ErrorModel) -> ErrorModel:
    """Declare ``dt_trk`` (ms, per flight) in an unlocked model and add ``a(t) dt_trk`` to its direct velocity
    error (:func:`with_time_offset`); renames it ``<name>+dt_trk``. Returns `m`, still unlocked."""
    import casadi as ca

    m.description = f"{m.description or m.name} + tracking time offset dt_trk (ms, per flight)"
    m.name = f"{m.name}{TIME_OFFSET_SUFFIX}"  # its file is the base model's (load_recorded_model adds the term)
    c = m.declare(dt_trk=("ms", TIME_OFFSET_MAGNITUDE_MS), per_flight=True)  # tracking time-tag delay, ms (SI: s)
    a = ca.vertcat(m.signal("a_x"), m.signal("a_y"), m.signal("a_z"))  # kinematic acceleration, m/s^2
    m.set_velocity_error(m.output("velocity_error") + a * c.dt_trk)  # dv += a(t) dt_trk (a lever arm kept)
    return m


def model_file_reference(model: ErrorModel) -> str | None:
    """The model's file when it is not shipped with casep (a model loaded from a path or from
    ``CASEP_MODEL_PATH``), else None: a result records it (``model_file``) so that a message can say
    which file to give with ``--model``."""
    src = getattr(model, "source_file", None)
    return None if not src or _is_shipped(src) else src


class ModelRecord(TypedDict):
    """What a result records of its model's file (:func:`model_record`)."""

    model_file: str | None
    model_sha256: str | None


def model_record(model: ErrorModel) -> ModelRecord:
    """What a result records of its model's file: ``{"model_file": ..., "model_sha256": ...}``
    (:func:`model_file_reference`; the SHA-256 of the file that ran, None for a model declared in code)."""
    return ModelRecord(model_file=model_file_reference(model), model_sha256=getattr(model, "source_sha256", None))


def shipped_model(name: str) -> ErrorModel | None:
    """The model shipped with casep called `name` (``platform36``, ``platform36+dt_trk``), set up; None
    for any other name: a name read from a file never runs a file that is not casep's own."""
    base = base_model_name(name)
    path = shipped_model_file(base)
    if path is None:
        return None
    return with_time_offset(path) if base != name else load_model_file(path)


def _path_like(name: str) -> bool:
    return name.endswith(".py") or "/" in name or "\\" in name


def _given_model(given: str | os.PathLike | ErrorModel, name: str, where: str, option: str,
                 model_file: str | None = None) -> ErrorModel:
    """The model the user named, for a file that records model `name` (a ``+dt_trk`` name gains the term)."""
    model = load_model(given)
    if _path_like(name):  # an old record of the file's path as its model: the file the user names stands
        return model
    if name and name != model.name and name == model.name + TIME_OFFSET_SUFFIX:
        model = with_time_offset(model)
    if name and name != model.name:
        raise ValueError(f"{where} is of model `{name}`, not of model `{model.name}`: give {option} "
                         f"{model_file or name} (or leave it out), or a result of `{model.name}`")
    return model


def load_recorded_model(name: str | None, *, sha256: str | None = None, model_file: str | None = None,
                        given: str | os.PathLike | ErrorModel | None = None, where: str = "the file",
                        option: str = "--model") -> ErrorModel:
    """The model a file (a result, prior, truth) records, loaded without running code on the file's word.

    Parameters
    ----------
    name : str or None
        The model name the file records (its ``model`` field).
    sha256, model_file : str, optional
        The SHA-256 and path of the model file the file records (``model_sha256``, ``model_file``).
    given : str, path or ErrorModel, optional
        The model the user named (``--model``, API ``model=``): it is loaded (and may run), and must be
        of model `name` and, when the file records one, of its SHA-256.
    where : str
        The file, as messages name it (``--result r.json``).
    option : str
        The option that names a model, as messages name it.

    Returns
    -------
    ErrorModel
        Set up: `given`, or the model shipped with casep called `name`.

    Raises
    ------
    ValueError
        A file that names no model, or a model not shipped with casep while the user named none (saying
        which option to give), or a model file whose SHA-256 is not the recorded one (both files, both
        hashes). A shipped model file changed since (another casep version) is a CasepWarning with both.
    """
    if given is not None:
        if isinstance(given, (str, os.PathLike)):
            path = find_model_file(given)
            if not _is_shipped(path):  # a user's file: its hash before it runs (a shipped one: its name first)
                from casep.io.provenance import file_sha256

                _check_sha256(file_sha256(path), str(path), sha256, model_file, where, option, error=True)
            given = load_model_file(path)
        model = _given_model(given, name or "", where, option, model_file)
        _check_sha256(model.source_sha256, model.source_file, sha256, model_file, where, option, error=True)
        return model
    if not name:
        raise ValueError(f"{where} names no model (no `model` field): give the model ({option} NAME|FILE.py, "
                         "API model=...)")
    shipped = shipped_model(name)
    if shipped is None:
        base = base_model_name(name)
        recorded = f" (model file {model_file}" + (f", sha256 {sha256}" if sha256 else "") + ")" if model_file else ""
        file = model_file or (base if _path_like(base) else f"path/to/{base}.py")
        raise ValueError(f"{where} is of model `{name}`{recorded}, which is not shipped with casep; a model file "
                         f"is Python code, and casep runs one only when you name it: give {option} {file} (or "
                         f"{option} NAME in CASEP_MODEL_PATH; API: model=...)")
    _check_sha256(shipped.source_sha256, shipped.source_file, sha256, model_file, where, option, error=False)
    return shipped


def _check_sha256(have: str | None, path: str | None, sha256: str | None, model_file: str | None, where: str,
                  option: str, *, error: bool) -> None:
    """The recorded SHA-256 against `have`, that of the model file `path` (skipped when either is unknown)."""
    if not sha256 or not have or sha256 == have:
        return
    msg = (f"{where} was estimated with model file {model_file or '(not recorded)'} of sha256 {sha256}, but "
           f"{path} has sha256 {have}")
    if error:
        raise ValueError(f"{msg}: give {option} with the model file the result was estimated with (if the file was "
                         "changed on purpose and declares the same coefficients, delete `model_sha256` from the file "
                         "to read it with the new one)")
    import warnings

    from casep.exceptions import CasepWarning

    warnings.warn(f"{msg} (the model shipped with this casep version); its coefficients are checked by name and unit",
                  CasepWarning, stacklevel=3)


#: the shipped models with an initial attitude error, by the model without one they extend
PHI0_MODELS = {"strapdown12": "strapdown15_phi0", "strapdown33": "strapdown42_extended"}
#: the shipped models with more terms than a model, by the model: what to try when it does not describe a flight
#: (:func:`casep.checks.plausibility.misfit_advice`)
RICHER_MODELS = {"strapdown12": "strapdown33 or strapdown42_extended",
                 "strapdown15_phi0": "strapdown42_extended (strapdown33 with phi0)",
                 "strapdown15_axial": "strapdown33 or strapdown42_extended",
                 "strapdown6_window": "strapdown12_window, or for a ground vehicle strapdown9_vehicle_window or "
                                      "strapdown7_speed_window",
                 "strapdown33": "strapdown42_extended",
                 "platform36": "platform39_misalignment, platform36_timeoffset or platform36_leverarm"}


def default_model(flight: str | os.PathLike | None, imu: bool = False) -> str:
    """The model ``casep separate`` takes without ``--model``, from the flight's header alone
    (:func:`casep.io.files.header_facts`).

    - a raw IMU record (`imu`): ``strapdown33`` (the levelling's own phi0 is added);
    - a flight whose header names the shipped model that made it (``casep simulate``'s ``# model NAME, seed``
      line): that model, or, when ``casep navigate`` levelled the telemetry on the pad, the same model with an
      initial attitude error (:data:`PHI0_MODELS`): the levelling turns the accelerometer errors on the pad into
      a start tilt (:func:`casep.checks.plausibility.levelling_problem`);
    - a strapdown telemetry (``q_*``, ``fb_*``, ``w_*``): ``strapdown42_extended``, every body-frame term of
      strapdown33 (biases, scale factors, misalignments, g-sensitivity) plus the initial attitude error that a
      telemetry levelled on the pad or starting after lift-off needs, accelerometer second order and lever arm.
      A smaller model fails such data as a misfit instead of saying which terms the flight determines: a
      roll programme's flight (strapdown-boost) made with strapdown33 fails strapdown15_phi0 with scale factors
      of 100 %;
    - anything else: ``platform36``.
    """
    if imu:
        return "strapdown33"
    if flight is None or not Path(flight).is_file():
        return "platform36"
    from casep.io.files import header_facts

    facts = header_facts(flight)
    named = facts["simulated_model"]
    if named is not None and shipped_model_file(named) is not None:
        return PHI0_MODELS.get(named, named) if facts["levelled"] else named
    return "strapdown42_extended" if facts["strapdown"] else "platform36"

"""Find and load model files (``models/*.py``, each with one ``build()`` function).

A model is named either by a path to a ``.py`` file or by a name looked up, in order, in the
folders of the ``CASEP_MODEL_PATH`` environment variable (``os.pathsep``-separated) and in
casep's built-in model folder. Files are loaded with
:func:`importlib.util.spec_from_file_location`; ``sys.path`` is never touched.
"""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path

from .model import ErrorModel, ModelDefinitionError

__all__ = ["build_model", "load_model", "model_dirs", "available_models", "find_model_file"]


def model_dirs() -> list[Path]:
    """Folders searched for a model given by name, in search order."""
    dirs = [Path(p) for p in os.environ.get("CASEP_MODEL_PATH", "").split(os.pathsep) if p]
    here = Path(__file__).resolve().parent
    # Installed wheel: casep/models; source checkout or editable install: <repo>/models.
    for cand in (here / "models", here.parent / "models"):
        if cand.is_dir() and cand not in dirs:
            dirs.append(cand)
    return dirs


def available_models() -> list[str]:
    """Names of the models found in :func:`model_dirs` (first one wins on a clash)."""
    seen: list[str] = []
    for d in model_dirs():
        for p in sorted(d.glob("*.py")):
            if not p.name.startswith("_") and p.stem not in seen:
                seen.append(p.stem)
    return seen


def find_model_file(model: str | os.PathLike) -> Path:
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
    for d in model_dirs():
        path = d / f"{text}.py"
        if path.is_file():
            return path
    raise ValueError(
        f"unknown model `{text}`. Use one of: {', '.join(available_models()) or '(none found)'}; "
        "or a path to a .py file with a build() function"
    )


def build_model(model: str | os.PathLike) -> ErrorModel:
    """Run a model file's ``build()`` and return the model *unlocked*.

    Use this to extend a model in another model file; :func:`load_model` for use.
    """
    path = find_model_file(model)
    spec = importlib.util.spec_from_file_location(f"casep_model_{path.stem}", path)
    if spec is None or spec.loader is None:
        raise ValueError(f"model file `{path}` cannot be loaded as Python")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    build = getattr(module, "build", None)
    if not callable(build):
        raise ModelDefinitionError(
            f"model file `{path}`: Missing: build(). Use: def build() -> casep.ErrorModel"
        )
    result = build()
    if not isinstance(result, ErrorModel):
        raise ModelDefinitionError(
            f"model file `{path}`: build() returned {type(result).__name__}, not casep.ErrorModel"
        )
    return result


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
    return build_model(model).setup()

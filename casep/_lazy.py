"""Lazy package attributes (PEP 562): a package's public names imported on first access.

So that ``import casep.cli`` (``casep --help``, ``casep methods``) does not import CasADi,
numba, SciPy or pandas for names it never uses; ``from casep import solve_ols`` and
``casep.solve_ols`` work as before.
"""

from __future__ import annotations

import importlib
from typing import Any, Callable, Mapping

__all__ = ["attach"]


def attach(package: str, modules: Mapping[str, tuple[str, ...]], namespace: dict[str, Any],
           subpackages: tuple[str, ...] = ()) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """``__getattr__`` and ``__dir__`` for `package`.

    Parameters
    ----------
    package : str
        The package's ``__name__``.
    modules : mapping
        Module (absolute) -> the names it provides.
    namespace : dict
        The package's ``globals()``: a name, once imported, is stored there (later look-ups
        do not come back here).
    subpackages : tuple of str
        Submodules reachable as attributes (``casep.io``) without importing them first.
    """
    where = {name: module for module, names in modules.items() for name in names}

    def __getattr__(name: str) -> Any:
        if name in where:
            value = getattr(importlib.import_module(where[name]), name)
        elif name in subpackages:
            value = importlib.import_module(f"{package}.{name}")
        else:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        namespace[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted(set(namespace) | set(where) | set(subpackages))

    return __getattr__, __dir__

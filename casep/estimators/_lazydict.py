"""A result's diagnostics, their costly entries computed on first use."""

from __future__ import annotations

from typing import Any, Mapping

__all__ = ["LazyDiagnostics"]


class LazyDiagnostics(dict):
    """A result's diagnostics whose costly entries are computed on first use, then kept.

    A plain ``dict`` to every reader (``isinstance``, ``json.dumps``, ``{**d}``, ``d[key]``): the
    entries named by ``lazy`` (the Cramer-Rao std, variance inflation factors and near-dependency
    groups) are computed by ``compute()`` the first time any of them, or the whole mapping, is read,
    so that a solve (a Monte Carlo run) that reads only the estimate does not pay for them.
    """

    def __init__(self, data: Mapping[str, Any], lazy: tuple[str, ...], compute: Any) -> None:
        super().__init__(data)
        self._pending: tuple[tuple[str, ...], Any] | None = (lazy, compute)

    def _force(self) -> None:
        if self._pending is not None:
            keys, compute = self._pending
            self._pending = None
            values = compute()
            for k in keys:
                if not dict.__contains__(self, k):
                    dict.__setitem__(self, k, values[k])

    def _lazy(self, key: Any) -> bool:
        return self._pending is not None and key in self._pending[0]

    def __getitem__(self, key: Any) -> Any:
        if self._lazy(key):
            self._force()
        return dict.__getitem__(self, key)

    def get(self, key: Any, default: Any = None) -> Any:
        if self._lazy(key):
            self._force()
        return dict.get(self, key, default)

    def __contains__(self, key: Any) -> bool:
        return self._lazy(key) or dict.__contains__(self, key)

    def copy(self) -> dict[str, Any]:
        self._force()
        return dict(dict.items(self))

    def __eq__(self, other: object) -> bool:
        self._force()
        if isinstance(other, LazyDiagnostics):
            other._force()
        return dict.__eq__(self, other)

    __hash__ = None

    def __reduce__(self) -> Any:  # pickled (dask workers) as the plain dict it stands for
        self._force()
        return (dict, (dict(dict.items(self)),))


def _forcing(name: str) -> Any:
    """The dict method `name`, after the pending entries are computed."""
    plain = getattr(dict, name)

    def method(self: LazyDiagnostics, *args: Any) -> Any:
        self._force()
        return plain(self, *args)

    method.__name__ = name
    return method


# Whatever reads the whole mapping (iteration, its size, views, its text) computes the pending entries first.
for _name in ("__iter__", "__len__", "keys", "items", "values", "__repr__"):
    setattr(LazyDiagnostics, _name, _forcing(_name))

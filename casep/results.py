"""The protocol every casep result follows.

Every result type (an estimate, a several-flight estimate, an impact miss, a Monte Carlo
campaign, a manoeuvre design, a calibration, a radar fit, the demo, and the analyses of a fit:
diagnostics, noise model, whiteness test, noise identification, outlier flags, de-noising) is
a record of what was computed, with five members:

``to_dict()``
    Plain data (``str``, ``int``, ``float``, ``bool``, ``None``, lists and dicts of them; every
    number finite, ``None`` where there is none), what ``json.dump`` writes and what
    :mod:`casep.io` reads back.
``text()``
    The human-readable account that the command line prints.
``success``
    Whether the computation reached what it set out to (``False``: do not use the numbers
    without reading ``message``).
``status``
    An integer code: 0 for a result that cannot fail (an analysis that always completes),
    otherwise the type's own codes (an estimate: 1 every coefficient estimated, 2 some not
    identifiable, -1 none; a design: 0 solved, 1 not).
``message``
    One line saying what happened (or, for a result that cannot fail, what it is).

A result that cannot fail takes ``success``, ``status`` and ``message`` from :class:`Completed`
(``message``: its :attr:`Completed.what`). The names of an earlier casep (``table()``,
``to_json()``, ``report()``, ``summary()``) stay one release as aliases made by
:func:`deprecated_alias`, which warn with a :class:`DeprecationWarning`.

Derived diagnostics (Cramer-Rao bounds, variance inflation factors, groups of
coefficients a flight cannot separate) are computed on first use and cached, as
statsmodels' results do, so that a solve, or a Monte Carlo run, pays only for what it is asked.
``settings`` hold the inputs of the computation only; everything it found is in the result's
own fields or its diagnostics. Writers to files live in :mod:`casep.io`.
"""

from __future__ import annotations

import warnings
from typing import Any, Callable, ClassVar, Protocol, runtime_checkable

__all__ = ["Result", "Completed", "OfEstimate", "deprecated_alias", "PROTOCOL", "DEPRECATED_NAMES"]

#: The members every result has.
PROTOCOL = ("text", "to_dict", "success", "status", "message")
#: Names of an earlier casep for ``text`` / ``to_dict``, kept one release as warning aliases.
DEPRECATED_NAMES = ("table", "to_json", "report", "summary")


@runtime_checkable
class Result(Protocol):
    """What every casep result provides (see the module docstring)."""

    @property
    def success(self) -> bool:
        """Whether the computation reached what it set out to."""
        ...

    @property
    def status(self) -> int:
        """0 for a result that cannot fail, else the type's own code."""
        ...

    @property
    def message(self) -> str:
        """One line: what happened, or what the result is."""
        ...

    def to_dict(self) -> dict[str, Any]:
        """The result as plain data, ready for ``json.dump``."""
        ...

    def text(self) -> str:
        """The result as the command line prints it."""
        ...


class Completed:
    """``success``, ``status`` and ``message`` of a result that cannot fail.

    An analysis that always completes (a noise identification, a whiteness test, outlier flags)
    is a success with status 0, and its message says what it is: ``what``, set by each class.
    """

    #: What the result is, for its message (e.g. ``"noise identification (Allan deviation)"``).
    what: ClassVar[str] = "result"

    @property
    def success(self) -> bool:
        """Always True: the computation cannot fail."""
        return True

    @property
    def status(self) -> int:
        """Always 0."""
        return 0

    @property
    def message(self) -> str:
        """What the result is: :attr:`what`."""
        return self.what


class OfEstimate:
    """``success``, ``status`` and ``message`` of a result built around an estimate: its ``result``'s.

    A radar fit or a multiposition calibration succeeds or fails as the
    :class:`~casep.estimators.result.EstimateResult` it holds in ``result``.
    """

    result: Any

    @property
    def success(self) -> bool:
        """Whether the estimate it holds succeeded."""
        return bool(self.result.success)

    @property
    def status(self) -> int:
        """The estimate's status."""
        return int(self.result.status)

    @property
    def message(self) -> str:
        """The estimate's message."""
        return str(self.result.message)


def deprecated_alias(new: str, old: str) -> Callable[..., Any]:
    """A method `old` that warns (:class:`DeprecationWarning`) and calls the method `new`.

    Class body use: ``table = deprecated_alias("text", "table")``.
    """

    def alias(self: Any, *args: Any, **kwargs: Any) -> Any:
        warnings.warn(f"{type(self).__name__}.{old}() is deprecated and will be removed in the next release; "
                      f"use {new}()", DeprecationWarning, stacklevel=2)
        return getattr(self, new)(*args, **kwargs)

    alias.__name__ = alias.__qualname__ = old
    alias.__doc__ = f"Deprecated: :meth:`{new}` (this name warns and goes in the next release)."
    return alias

"""The protocol every casep result follows.

Every result type (an estimate, a several-flight estimate, an impact miss, a Monte Carlo
campaign, a manoeuvre design, a calibration, a radar fit, the demo) is a frozen record of what
was computed, with two ways out:

``to_dict()``
    Plain data (``str``, ``int``, ``float``, ``bool``, ``None``, lists and dicts of them),
    what ``json.dump`` writes and what :mod:`casep.io` reads back.
``text()``
    The human-readable account that the command line prints.

Derived diagnostics (Cramer-Rao bounds, variance inflation factors, groups of
coefficients a flight cannot separate) are computed on first use and cached, as
statsmodels' results do, so that a solve, or a Monte Carlo run, pays only for what it is asked.
``settings`` hold the inputs of the computation only; everything it found is in the result's
own fields or its diagnostics. Writers to files live in :mod:`casep.io`.
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

__all__ = ["Result"]


@runtime_checkable
class Result(Protocol):
    """What every casep result provides (see the module docstring)."""

    def to_dict(self) -> dict[str, Any]:
        """The result as plain data, ready for ``json.dump``."""
        ...

    def text(self) -> str:
        """The result as the command line prints it."""
        ...

"""Flight data: the :class:`FlightData` type and its error.

A flight is sample times ``t`` (s, strictly increasing, need not be uniform), the platform
specific force ``f`` (N x 3, m/s^2, from telemetry) and the velocity error ``dv`` (N x 3, m/s,
telemetry minus tracking). Files are read and written by :mod:`casep.flight_io`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["FlightData", "FlightDataError", "min_samples", "check_enough_samples"]

AXES = ("x", "y", "z")
FORCE_COLUMNS = tuple(f"f_{a}" for a in AXES)
DV_COLUMNS = tuple(f"dv_{a}" for a in AXES)


class FlightDataError(ValueError):
    """Bad flight data. Attributes `source`, `column` and `row` locate the problem.

    Parameters
    ----------
    source : str
        File name (or ``"<memory>"``).
    message : str
        What is wrong.
    column : str, optional
        Offending column.
    row : int or str, optional
        1-based data row (after the header), or ``"header"``.
    line : int, optional
        1-based line of the file.
    """

    def __init__(self, source: str, message: str, column: str | None = None,
                 row: int | str | None = None, line: int | None = None) -> None:
        self.source, self.column, self.row, self.line = source, column, row, line
        where = []
        if column is not None:
            where.append(f"column `{column}`")
        if row is not None:
            where.append((f"row {row}" if row != "header" else "header")
                         + (f" (line {line})" if line is not None else ""))
        super().__init__(f"{source}: {', '.join(where) + ': ' if where else ''}{message}")


def _first_bad_row(values: np.ndarray) -> int | None:
    bad = np.flatnonzero(~np.isfinite(values))
    return int(bad[0]) if bad.size else None


@dataclass(frozen=True)
class FlightData:
    """One flight: time, specific force and velocity error, validated on creation.

    Parameters
    ----------
    t : (N,) array_like
        Time, s, strictly increasing.
    f : (N, 3) array_like
        Platform specific force, m/s^2 (x downrange, y up, z cross-range).
    dv : (N, 3) array_like
        Velocity error telemetry minus tracking, m/s.
    source : str, optional
        Where the data came from (used in error messages and reports).
    """

    t: np.ndarray
    f: np.ndarray
    dv: np.ndarray
    source: str = "<memory>"
    meta: dict = field(default_factory=dict, compare=False)

    def __post_init__(self) -> None:
        src = self.source
        t = np.array(self.t, dtype=float)
        f = np.array(self.f, dtype=float)
        dv = np.array(self.dv, dtype=float)
        if t.ndim != 1:
            raise FlightDataError(src, f"`t` must be 1-D, got shape {t.shape}", "t")
        for name, arr, cols in (("f", f, FORCE_COLUMNS), ("dv", dv, DV_COLUMNS)):
            if arr.shape != (t.size, 3):
                raise FlightDataError(src, f"`{name}` must have shape ({t.size}, 3), got {arr.shape}", name)
            for i, col in enumerate(cols):
                r = _first_bad_row(arr[:, i])
                if r is not None:
                    raise FlightDataError(src, f"value {arr[r, i]:g} is not finite", col, r + 1)
        r = _first_bad_row(t)
        if r is not None:
            raise FlightDataError(src, f"value {t[r]:g} is not finite", "t", r + 1)
        step = np.flatnonzero(np.diff(t) <= 0)
        if step.size:
            k = int(step[0]) + 1
            raise FlightDataError(src, f"time {t[k]:.10g} s does not increase (previous row: {t[k - 1]:.10g} s)", "t", k + 1)
        for name, arr in (("t", t), ("f", f), ("dv", dv)):
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)

    @property
    def n_samples(self) -> int:
        """Number of samples N."""
        return int(self.t.size)


def min_samples(n_coefficients: int) -> int:
    """Fewest samples that leave one degree of freedom for the noise estimate.

    The first sample carries no information (S_V(t0) = 0 for a model without initial
    terms), so 3 (N - 1) > n is needed: N >= n // 3 + 2.
    """
    return n_coefficients // 3 + 2


def check_enough_samples(flight: FlightData, n_coefficients: int, model_name: str) -> None:
    """Raise :class:`FlightDataError` when `flight` is too short for a model."""
    need = min_samples(n_coefficients)
    if flight.n_samples < need:
        raise FlightDataError(
            flight.source,
            f"{flight.n_samples} samples are too few for model `{model_name}` with "
            f"{n_coefficients} coefficients: need at least {need}",
            "t", flight.n_samples,
        )

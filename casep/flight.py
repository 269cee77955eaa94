"""Flight data: the :class:`FlightData` type and the flight-file readers.

A flight is sample times ``t`` (s, strictly increasing, need not be uniform), the platform
specific force ``f`` (N x 3, m/s^2, from telemetry) and the velocity error ``dv`` (N x 3, m/s,
telemetry minus tracking). File format: ``../shared/spec/interfaces.md``.

Every reader raises :class:`FlightDataError` naming the file, the column and the row (data
rows count from 1 after the header; the file line is given too) for a missing column, an
empty, non-numeric, NaN or infinite value, or time that does not strictly increase.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ._io import atomic_open

__all__ = ["FlightData", "FlightDataError", "read_flight", "read_flight_csv", "write_flight_csv", "min_samples"]

AXES = ("x", "y", "z")
FORCE_COLUMNS = tuple(f"f_{a}" for a in AXES)
DV_COLUMNS = tuple(f"dv_{a}" for a in AXES)
VTEL_COLUMNS = tuple(f"v_tel_{a}" for a in AXES)
VTRK_COLUMNS = tuple(f"v_trk_{a}" for a in AXES)


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


def _data_line(path: Path, row: int) -> int | None:
    """File line (1-based) of data row `row` (1-based), skipping comments and blank lines."""
    seen = -1  # the header is row 0
    try:
        with open(path, encoding="utf-8", errors="replace") as fh:
            for lineno, text in enumerate(fh, 1):
                s = text.strip()
                if not s or s.startswith("#"):
                    continue
                seen += 1
                if seen == row:
                    return lineno
    except OSError:
        return None
    return None


def _numeric_column(path: Path, frame, col: str) -> np.ndarray:
    """Column `col` as float64, or FlightDataError at the first bad cell."""
    import pandas as pd

    raw = frame[col]
    values = pd.to_numeric(raw, errors="coerce").to_numpy(dtype=float)
    r = _first_bad_row(values)
    if r is None:
        return values
    cell = raw.iloc[r]
    text = cell.strip().lower().lstrip("+-") if isinstance(cell, str) else None
    if text is None and pd.isna(cell):
        what = "empty value"  # only empty cells become NA: keep_default_na=False
    elif text == "nan" or (text is None and np.isnan(values[r])):
        what = "NaN value"
    elif np.isinf(values[r]):
        what = f"infinite value {cell}"
    else:
        what = f"non-numeric value {cell!r}"
    raise FlightDataError(str(path), what, col, r + 1, _data_line(path, r + 1))


def read_flight_csv(path: str | os.PathLike) -> FlightData:
    """Read a flight CSV file (header row, ``#`` comments, extra columns ignored).

    Parameters
    ----------
    path : str or path-like
        File with columns ``t, f_x, f_y, f_z`` and either ``dv_x, dv_y, dv_z`` or
        ``v_tel_x/y/z`` and ``v_trk_x/y/z`` (then dv = v_tel - v_trk).

    Returns
    -------
    FlightData

    Raises
    ------
    FlightDataError
        Naming file, column and row of the first problem.
    """
    import pandas as pd

    path = Path(path)
    src = str(path)
    if not path.is_file():
        raise FlightDataError(src, "file does not exist")
    try:
        frame = pd.read_csv(path, comment="#", skip_blank_lines=True, keep_default_na=False,
                            na_values=[""], skipinitialspace=True)
    except pd.errors.EmptyDataError:
        raise FlightDataError(src, "file has no header row and no data") from None
    except pd.errors.ParserError as exc:
        raise FlightDataError(src, f"malformed CSV: {exc}".strip()) from None
    except UnicodeDecodeError as exc:
        raise FlightDataError(src, f"not a UTF-8 text file ({exc.reason})") from None
    frame.columns = [str(c).strip() for c in frame.columns]
    header_line = _data_line(path, 0)
    have = set(frame.columns)

    def need(cols: tuple[str, ...], hint: str = "") -> None:
        for c in cols:
            if c not in have:
                raise FlightDataError(src, f"missing column (header has: {', '.join(frame.columns)}){hint}",
                                      c, "header", header_line)

    need(("t",) + FORCE_COLUMNS)
    dv_cols = DV_COLUMNS if set(DV_COLUMNS) & have or not (set(VTEL_COLUMNS) & have) else None
    if dv_cols is not None:
        need(DV_COLUMNS, ". Use: dv_x, dv_y, dv_z, or v_tel_x/y/z with v_trk_x/y/z")
        cols = ("t",) + FORCE_COLUMNS + DV_COLUMNS
    else:
        need(VTEL_COLUMNS + VTRK_COLUMNS, ". Use: v_tel_x/y/z with v_trk_x/y/z, or dv_x, dv_y, dv_z")
        cols = ("t",) + FORCE_COLUMNS + VTEL_COLUMNS + VTRK_COLUMNS
    data = {c: _numeric_column(path, frame, c) for c in cols}
    if dv_cols is not None:
        dv = np.column_stack([data[c] for c in DV_COLUMNS])
    else:
        dv = np.column_stack([data[a] - data[b] for a, b in zip(VTEL_COLUMNS, VTRK_COLUMNS)])
    if frame.shape[0] == 0:
        raise FlightDataError(src, "file has a header but no data rows", "t", "header", header_line)
    t = data["t"]
    step = np.flatnonzero(np.diff(t) <= 0)
    if step.size:
        k = int(step[0]) + 1
        raise FlightDataError(src, f"time {t[k]:.10g} s does not increase (previous row: {t[k - 1]:.10g} s)",
                              "t", k + 1, _data_line(path, k + 1))
    f = np.column_stack([data[c] for c in FORCE_COLUMNS])
    return FlightData(t, f, dv, source=src)


def read_flight(path: str | os.PathLike) -> FlightData:
    """Read a flight file, choosing the reader by extension (``.csv``; anything else as CSV)."""
    return read_flight_csv(path)


def write_flight_csv(flight: FlightData, path: str | os.PathLike, *, comments: list[str] | None = None) -> None:
    """Write a flight as CSV (``t, f_x, f_y, f_z, dv_x, dv_y, dv_z``), atomically.

    Parameters
    ----------
    flight : FlightData
    path : str or path-like
    comments : list of str, optional
        Lines written first, each prefixed with ``# ``.

    Notes
    -----
    Values use ``repr`` precision (17 significant digits), so reading the file back gives
    the same floats. The file is written to a temporary name and renamed, so a failure
    leaves no half-written file.
    """
    if not isinstance(flight, FlightData):
        raise TypeError(f"`flight` must be a FlightData, got {type(flight).__name__}")
    path = Path(path)
    data = np.column_stack([flight.t, flight.f, flight.dv])
    header = ",".join(("t",) + FORCE_COLUMNS + DV_COLUMNS)
    with atomic_open(path) as fh:
        for line in comments or []:
            fh.write(f"# {line}\n")
        fh.write(header + "\n")
        np.savetxt(fh, data, delimiter=",", fmt="%.17g")

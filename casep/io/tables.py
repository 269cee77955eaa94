"""A flight file read into columns: CSV (comma, semicolon or tab separated) or Parquet.

:class:`Table` reads a file once (pandas' C reader for CSV, pyarrow column by column for
Parquet) and gives its columns as float64 arrays, raising
:class:`~casep.io.flight.FlightDataError` naming the file, the column and the row (data rows
count from 1 after the header; CSV errors give the file line too) for a missing or repeated
column, a column that is not numeric (bool, date-time, text in Parquet; the dtype is named), an
empty, non-numeric, NaN or infinite value, a magnitude above
:data:`~casep.io.flight.MAX_ABS_VALUE`, or time that does not strictly increase. The readers of
:mod:`casep.io.files` (flights), :mod:`casep.io.trajectory` and the radar readers are built on it.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Callable

import numpy as np

from casep.io.flight import AXES, DV_COLUMNS, FORCE_COLUMNS, FlightDataError, too_large
from casep.io.locate import csv_lines, is_parquet
from casep.io.strapdown import BODY_FORCE_COLUMNS, STRAPDOWN_COLUMNS

__all__ = ["Table", "table_force", "apparent_velocity_to_force", "CSV_SEPARATORS", "KNOWN_COLUMNS",
           "APPARENT_COLUMNS", "VTEL_COLUMNS", "VTRK_COLUMNS", "header_columns"]

APPARENT_COLUMNS = tuple(f"W_{a}" for a in AXES)
VTEL_COLUMNS = tuple(f"v_tel_{a}" for a in AXES)
VTRK_COLUMNS = tuple(f"v_trk_{a}" for a in AXES)
#: Every column a reader may use: a repeated one is refused.
KNOWN_COLUMNS = ("t",) + FORCE_COLUMNS + APPARENT_COLUMNS + DV_COLUMNS + VTEL_COLUMNS + VTRK_COLUMNS


def _csv_line_locator(path: Path) -> Callable[[int], int | None]:
    """Map a data row (1-based; 0 = header) to its file line, skipping comments and blanks."""

    def line_of(row: int) -> int | None:
        return csv_lines(path, [row]).get(row)

    return line_of


#: Column separators a CSV flight file may use: comma (casep, MATLAB writetable's default),
#: semicolon (Excel in locales with a decimal comma), tab (writetable 'Delimiter','tab').
CSV_SEPARATORS = (",", ";", "\t")
_SEPARATOR_NAMES = {",": "comma", ";": "semicolon", "\t": "tab"}


def _csv_header(path: Path) -> tuple[list[str], str]:
    """The header's names as pandas sees them (first line that is not blank or a ``#`` comment,
    text after ``#`` dropped), before pandas renames a repeated ``dv_x`` to ``dv_x.1``, and the
    column separator.

    The separator is the one of :data:`CSV_SEPARATORS` that splits the header into the most names
    (names are identifiers such as ``t``, ``f_x``, so none contains a separator): read from the
    header alone, it costs nothing, and the data are then parsed by pandas' C reader with it.
    """
    import csv

    with open(path, encoding="utf-8", errors="replace", newline="") as fh:
        for text in fh:
            text = text.split("#", 1)[0].lstrip("\ufeff")  # a byte-order mark (Excel's "CSV UTF-8")
            if text.strip():
                sep = max(CSV_SEPARATORS, key=lambda c: (text.count(c), c == ","))  # ties: comma
                return [c.strip() for c in next(csv.reader([text], delimiter=sep, skipinitialspace=True))], sep
    return [], ","


def _nul_line(path: Path) -> int | None:
    """The file line (1-based) of the first NUL byte of a text file, or None (a memory-mapped search).

    A NUL byte is no character of a CSV file: it is what a recorder that stopped leaves in the space it had
    reserved, or a binary file given as text. pandas' C parser ends a field at one silently.
    """
    import mmap

    with open(path, "rb") as fh:
        if os.fstat(fh.fileno()).st_size == 0:
            return None
        with mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ) as mm:
            at = mm.find(b"\0")
            return None if at < 0 else mm[:at].count(b"\n") + 1


def _refuse_nul(path: Path) -> None:
    """A FlightDataError naming the file, the data row and the line of the first NUL byte."""
    line = _nul_line(path)
    if line is None:
        return
    row: int | str | None = None
    with open(path, encoding="utf-8", errors="replace") as fh:
        seen = -1  # the header is row 0 (comments and blank lines skipped, as pandas reads them)
        for lineno, text in enumerate(fh, 1):
            st = text.replace("\0", "").strip()
            if lineno == line:
                row = "header" if seen < 0 else seen + 1
                break
            if st and not st.startswith("#"):
                seen += 1
    raise FlightDataError(str(path), "NUL byte(s) in a text file (a recorder's unwritten space, or a binary file?): "
                          "cut the file where its data end, or export it again", None, row, line)


def _parquet_header(path: Path) -> list[str]:
    import pyarrow.parquet as pq

    return list(pq.read_schema(path).names)


def header_columns(path: str | os.PathLike) -> list[str]:
    """The column names of a flight file from its header alone, no data read (CSV: :func:`_csv_header`, Parquet:
    its schema); [] when the header cannot be read (:class:`Table` then says why)."""
    p = Path(path)
    try:
        return _parquet_header(p) if is_parquet(p) else _csv_header(p)[0]
    except Exception:  # any unreadable file: the reader that follows names the problem
        return []


def _read_parquet_frame(path: Path) -> tuple[Any, dict[str, np.ndarray]]:
    """A Parquet file as a DataFrame, one column at a time, and the null cells of each column that has any.

    Reading the whole table and converting it holds the data three to four times at once (Arrow
    buffers, pandas' consolidated block, its copy): 1.3 GB for a 5e6-sample flight of 280 MB.
    Column by column, each float column is a zero-copy view of its Arrow buffer, so reading
    costs about the size of the data. A null becomes NaN in the frame; the null masks keep it apart
    from a NaN value (a null is a missing cell, as an empty CSV cell is).
    """
    import pandas as pd
    import pyarrow.parquet as pq

    pf = pq.ParquetFile(path)
    columns, nulls = {}, {}
    for name in pf.schema_arrow.names:
        col = pf.read(columns=[name], use_threads=False).column(0)
        if col.null_count:
            nulls[name] = col.is_null().to_numpy(zero_copy_only=False)
        if col.num_chunks == 1 and col.null_count == 0 and str(col.type) in ("double", "float"):
            columns[name] = col.chunk(0).to_numpy(zero_copy_only=True)
        else:
            columns[name] = col.to_pandas()  # other types keep their pandas dtype (checked later)
    return pd.DataFrame(columns, copy=False), nulls


def _refuse_json(path: Path) -> None:
    """A JSON file given where a flight table (CSV or Parquet) is read: refused saying what the file is (a casep
    result, a coefficient table, a radar station) and which command or option takes it, instead of a CSV parser's
    message about its line 1908."""
    with open(path, "rb") as fh:
        head = fh.read(4096).lstrip(b"\xef\xbb\xbf \t\r\n")
    if head[:1] not in (b"{", b"["):
        return
    from casep.io.result_json import load_json, looks_like_result

    src = str(path)
    try:
        data = load_json(path, "flight")
    except ValueError:  # not JSON after all (or broken JSON): the CSV reader says what it finds
        return
    table = "a flight is a CSV or Parquet table with columns t, f_x, f_y, f_z and dv_x.. (or v_tel_x.. and v_trk_x..)"
    if looks_like_result(data):
        what = (f"a result JSON (model {data.get('model') or '?'}, method {data.get('method') or '?'}), not flight "
                f"data ({table}). A result is read by `casep fuse RESULT...`, `casep impact --result RESULT` and "
                "`--prior RESULT` of `casep separate` and `casep design`")
    elif isinstance(data, dict) and {"lat", "lon"} <= set(data):
        what = (f"a radar station JSON, not flight data ({table}). A station is given with "
                "`casep separate TELEMETRY --radar STATION.json MEASUREMENTS.csv --launch-site ...`")
    else:
        what = (f"a JSON file, not flight data ({table}). A coefficient table (name: value or {{mean, std}}) is "
                "given with --bounds or --prior")
    raise FlightDataError(src, what)


class Table:
    """A file read into a DataFrame, with error helpers that locate rows."""

    def __init__(self, path: str | os.PathLike) -> None:
        import pandas as pd

        self.path = Path(path)
        self.src = str(self.path)
        if self.path.is_dir():
            raise FlightDataError(self.src, "is a directory, not a flight file")
        if not self.path.exists():
            raise FlightDataError(self.src, "file does not exist")
        if not self.path.is_file():
            raise FlightDataError(self.src, "not a regular file (a device, FIFO or socket?)")
        self.sep = ","
        self.strapdown: dict[str, Any] | None = None  # what table_force found in q_*, fb_*, w_*
        self.nulls: dict[str, np.ndarray] = {}  # Parquet: the null cells of each column that has any
        if is_parquet(self.path):
            self.line_of: Callable[[int], int | None] = lambda row: None
            self._refuse_repeated(self._parquet(_parquet_header))  # before pandas, which fails on them
            frame, self.nulls = self._parquet(_read_parquet_frame)
        else:
            _refuse_nul(self.path)  # before pandas, whose C parser ends a field at a NUL silently
            _refuse_json(self.path)  # a result, prior or station file given as a flight: say what it is
            try:
                header, self.sep = _csv_header(self.path)
                frame = pd.read_csv(self.path, sep=self.sep, comment="#", skip_blank_lines=True,
                                    keep_default_na=False, na_values=[""], skipinitialspace=True,
                                    encoding="utf-8-sig")
            except pd.errors.EmptyDataError:
                raise FlightDataError(self.src, "file has no header row and no data") from None
            except pd.errors.ParserError as exc:
                raise FlightDataError(self.src, f"malformed CSV: {exc}".strip()) from None
            except UnicodeDecodeError as exc:
                raise FlightDataError(self.src, f"not a UTF-8 text file ({exc.reason})") from None
            self.line_of = _csv_line_locator(self.path)
            self._refuse_repeated(header)
        frame.columns = [str(c).strip() for c in frame.columns]
        self.frame = frame
        self.columns = set(frame.columns)

    @classmethod
    def from_columns(cls, columns: dict[str, np.ndarray], source: str) -> Table:
        """A table held in memory (named 1-D columns), read and checked as a file's would be; `source`
        names it in messages (rows are counted from 1, with no file line)."""
        import pandas as pd

        self = cls.__new__(cls)
        self.path, self.src, self.sep = Path(source), source, ","
        self.strapdown, self.nulls = None, {}
        self.line_of = lambda row: None
        self.frame = pd.DataFrame({k: np.asarray(v, dtype=float) for k, v in columns.items()})
        self.columns = set(self.frame.columns)
        return self

    def _parquet(self, reader: Callable):
        """``reader(path)``, with pyarrow's errors as :class:`FlightDataError`."""
        try:
            return reader(self.path)
        except ImportError:
            raise FlightDataError(self.src, "reading Parquet needs pyarrow: pip install pyarrow") from None
        except Exception as exc:  # pyarrow raises its own error types
            raise FlightDataError(self.src, f"not a readable Parquet file ({exc})") from None

    def _refuse_repeated(self, header: list[str]) -> None:
        """A column casep reads must appear once (pandas would silently rename the second)."""
        for col in KNOWN_COLUMNS:
            at = [i + 1 for i, name in enumerate(header) if name == col]
            if len(at) > 1:
                raise self.error(f"column name repeated (header positions {', '.join(map(str, at))}): "
                                 "keep one", col, "header")

    def error(self, message: str, column: str | None = None, row: int | str | None = None) -> FlightDataError:
        line = self.line_of(0 if row == "header" else int(row)) if row is not None else None
        return FlightDataError(self.src, message, column, row, line)

    def has(self, cols: tuple[str, ...]) -> bool:
        return all(c in self.columns for c in cols)

    def require(self, cols: tuple[str, ...], hint: str = "") -> None:
        for c in cols:
            if c not in self.columns:
                sep = "" if self.sep == "," else f"; columns read as {_SEPARATOR_NAMES[self.sep]}-separated"
                if len(self.frame.columns) == 1:  # one name holding them all: another separator
                    other = next((c for c in (" ", "|", ":") if c in str(self.frame.columns[0]).strip()), None)
                    if other is not None:
                        sep += (f"; the header looks {'space' if other == ' ' else repr(other)}-separated: casep "
                                "reads comma-, semicolon- or tab-separated files")
                raise self.error(f"missing column (header has: {', '.join(self.frame.columns)}{sep}){hint}",
                                 c, "header")
        if self.frame.shape[0] == 0:
            raise self.error("file has a header but no data rows", cols[0], "header")

    def _check_dtype(self, col: str) -> None:
        """Numeric (int, unsigned or float) columns only: a bool, date-time, complex or (in
        Parquet) text column is refused, naming its dtype. A CSV text column goes on to the
        per-cell check, which names the first cell that is not a number."""
        dtype = self.frame[col].dtype
        if dtype.kind in "iuf" or (dtype.kind == "O" and not is_parquet(self.path)):
            return
        hint = {"M": "; give time in seconds (e.g. seconds since lift-off)",
                "m": "; give time in seconds", "b": "; give numbers"}.get(dtype.kind, "")
        raise self.error(f"column has dtype {dtype}, not a number{hint}", col, "header")

    def missing(self, col: str) -> np.ndarray:
        """The cells of `col` that are missing: empty in CSV (only those read as NaN, keep_default_na=False),
        null in Parquet (a NaN value is not missing)."""
        if is_parquet(self.path):
            return self.nulls.get(col, np.zeros(self.frame.shape[0], dtype=bool))
        return self.frame[col].isna().to_numpy(dtype=bool)

    def all_missing(self, cols: tuple[str, ...]) -> np.ndarray:
        """The rows whose cells of every column in `cols` are missing (:meth:`missing`): a velocity vector
        not given on that row (a sample without tracking). A row with only some of them missing is not one:
        :meth:`numeric` then refuses it, naming its first missing cell."""
        return np.logical_and.reduce([self.missing(c) for c in cols])

    def numeric(self, col: str, skip: np.ndarray | None = None) -> np.ndarray:
        """Column as float64, or the error at its first bad cell (rows `skip`, a boolean mask, are NaN, unchecked)."""
        import pandas as pd

        self._check_dtype(col)
        raw = self.frame[col]
        values = pd.to_numeric(raw, errors="coerce").to_numpy(dtype=float)
        if skip is not None and skip.any():
            values = np.where(skip, np.nan, values)  # a new array: `values` may view a read-only Arrow buffer
        bad = np.flatnonzero(~np.isfinite(values) if skip is None else ~np.isfinite(values) & ~skip)
        if not bad.size:
            big = too_large(values if skip is None else np.where(skip, 0.0, values))
            if big is not None:
                raise self.error(big[1], col, big[0] + 1)
            return values
        r = int(bad[0])
        cell = raw.iloc[r]
        if isinstance(cell, str):
            text = cell.strip().lower().lstrip("+-")
            what = ("NaN value" if text == "nan" else f"infinite value {cell}" if np.isinf(values[r])
                    else f"non-numeric value {cell!r}")
            if self.sep != "," and "," in cell and pd.notna(pd.to_numeric(cell.replace(",", "."), errors="coerce")):
                what += (f" (a decimal comma? the columns are {_SEPARATOR_NAMES[self.sep]}-separated, numbers "
                         "need a decimal point: save the file with '.' as decimal separator, e.g. MATLAB "
                         "writetable, or Excel with the system separators set to '.')")
        elif isinstance(cell, (float, np.floating)) and np.isinf(cell):
            what = f"infinite value {cell}"
        elif isinstance(cell, (float, np.floating)) and is_parquet(self.path):
            what = "null value" if col in self.nulls and self.nulls[col][r] else "NaN value"
        else:
            what = "empty value"  # CSV: only empty cells become NaN (keep_default_na=False)
        raise self.error(what, col, r + 1)

    def signals(self, rows: np.ndarray | slice = slice(None)) -> dict[str, np.ndarray]:
        """Every numeric column that is not a known one, as float64 (NaN kept), at `rows`."""
        import pandas as pd

        out = {}
        for col in self.frame.columns:
            if col in KNOWN_COLUMNS or col in out:
                continue
            raw = self.frame[col]
            if raw.dtype.kind in "iuf":
                out[col] = raw.to_numpy(dtype=float)[rows]
            elif raw.dtype.kind == "O" and not is_parquet(self.path):
                values = pd.to_numeric(raw, errors="coerce").to_numpy(dtype=float)
                text = raw[np.isnan(values)].dropna().astype(str).str.strip().str.lower().str.lstrip("+-")
                if text.isin(["nan", "inf", "infinity", ""]).all():  # numbers, NaN or empty cells
                    out[col] = values[rows]
        return out

    def strapdown_signals(self, signals: dict[str, np.ndarray], meta: dict[str, Any]) -> None:
        """After :func:`table_force`: the sign-continuous quaternions into `signals` (at their rows), the
        checks' findings into ``meta["strapdown"]``."""
        if self.strapdown is None:
            return
        for i, c in enumerate(STRAPDOWN_COLUMNS[:4]):
            signals[c] = self.strapdown["q"][:, i]
        meta["strapdown"] = self.strapdown["info"]

    def vectors(self, cols: tuple[str, ...], skip: np.ndarray | None = None) -> np.ndarray:
        return np.column_stack([self.numeric(c, skip) for c in cols])

    def time(self) -> np.ndarray:
        t = self.numeric("t")
        step = np.flatnonzero(np.diff(t) <= 0)
        if step.size:
            k = int(step[0]) + 1
            raise self.error(f"time {t[k]:.10g} s does not increase (previous row: {t[k - 1]:.10g} s)", "t", k + 1)
        return t


def apparent_velocity_to_force(t: np.ndarray, W: np.ndarray) -> np.ndarray:
    """Specific force ``f = dW/dt`` (m/s^2) from accumulated apparent velocity ``W`` (m/s).

    Second-order finite differences on the non-uniform grid (:func:`numpy.gradient` with
    coordinates, second-order one-sided at the ends): error O(dt^2 f'').
    """
    t = np.asarray(t, dtype=float)
    W = np.asarray(W, dtype=float)
    if W.shape != (t.size, 3):
        raise ValueError(f"`W` must have shape ({t.size}, 3), got {W.shape}")
    if t.size < 3:
        raise ValueError(f"`t` needs at least 3 samples to differentiate `W`, got {t.size}")
    return np.gradient(W, t, axis=0, edge_order=2)


def table_force(tab: Table, t: np.ndarray) -> tuple[np.ndarray, str]:
    """The specific force of a table, m/s^2, and the columns it came from (``"f"`` or ``"W"``).

    ``f_x, f_y, f_z`` when the file has them (or has no ``W_*``), else the derivative of the
    apparent velocity ``W_x, W_y, W_z`` (:func:`apparent_velocity_to_force`); a strapdown file without
    either: ``f = C(q) fb`` from ``q_*`` and ``fb_*`` (``"q, fb"``, :func:`casep.io.strapdown.strapdown_force`).
    The strapdown columns are checked whenever the file has them; what the checks found and the
    sign-continuous quaternions are left in ``tab.strapdown`` for the reader's meta and signals.
    """
    strapdown = any(c in tab.columns for c in STRAPDOWN_COLUMNS)
    given = tab.has(FORCE_COLUMNS) or any(c in tab.columns for c in APPARENT_COLUMNS)
    if strapdown and (not given or tab.has(STRAPDOWN_COLUMNS)):  # q_*, fb_*, w_*: checked whenever present
        from casep.io.strapdown import strapdown_force

        f_body, info, q = strapdown_force(tab, t)
        tab.strapdown = {"info": info, "q": q}
        if tab.has(VTEL_COLUMNS):  # the INS's velocity must be the integral of C(q) fb + g
            from casep.io.strapdown import check_kinematics

            info["kinematics"] = check_kinematics(tab.src, t, q, tab.vectors(BODY_FORCE_COLUMNS),
                                                  tab.vectors(VTEL_COLUMNS), error=tab.error)
        if not given:
            return f_body, "q, fb"
        if tab.has(FORCE_COLUMNS):
            from casep.io.strapdown import compare_force

            compare_force(tab.src, tab.vectors(FORCE_COLUMNS), f_body)
    if tab.has(FORCE_COLUMNS) or not any(c in tab.columns for c in APPARENT_COLUMNS):
        tab.require(FORCE_COLUMNS, ". Use: f_x, f_y, f_z (m/s^2), or W_x, W_y, W_z (apparent velocity, m/s)")
        return tab.vectors(FORCE_COLUMNS), "f"
    tab.require(APPARENT_COLUMNS, ". Use: W_x, W_y, W_z (apparent velocity, m/s), or f_x, f_y, f_z")
    if t.size < 3:
        raise tab.error("apparent velocity needs at least 3 samples to differentiate", "W_x", t.size)
    return apparent_velocity_to_force(t, tab.vectors(APPARENT_COLUMNS)), "W"

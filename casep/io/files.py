"""Reading and writing flight files: CSV and Parquet, one file or telemetry + tracking.

Formats (``docs/reference/file-formats.md``): a header row, one row per sample, ``#`` comment
lines (CSV), other numeric columns kept as signals (below), text columns ignored.

- time ``t`` (s, strictly increasing);
- specific force ``f_x, f_y, f_z`` (m/s^2), or telemetered apparent velocity ``W_x, W_y, W_z``
  (m/s, accumulated specific force), turned into ``f = dW/dt`` by second-order finite
  differences on the (possibly non-uniform) time grid (:func:`apparent_velocity_to_force`);
- velocity error ``dv_x, dv_y, dv_z`` (m/s), or ``v_tel_x/y/z`` and ``v_trk_x/y/z`` (then
  dv = v_tel - v_trk);
- any other numeric column (``a_*``, ``r_*``, ``v_*``, attitude, body rate, temperature, ...)
  is kept as a *signal* (``FlightData.signals``, file units) for model files that use it; a
  column with text in it is ignored. Its values are checked when a model uses it.

Two files (:func:`read_flight_pair`): a telemetry file (``t``, force or apparent velocity,
``v_tel_*``) and a tracking file at its own rate (``t``, ``v_trk_*``). The flight keeps every
telemetry sample from the first one to the end of tracking (S_V is integrated from the
first telemetry sample); tracking is interpolated onto the telemetry times inside its span
(cubic spline by default, linear on request), and those samples are the ``observed`` ones.

Every reader raises :class:`~casep.io.flight.FlightDataError` naming the file, the column and
the row (data rows count from 1 after the header; CSV errors give the file line too) for a
missing or repeated column, a column that is not numeric (bool, date-time, text in Parquet;
the dtype is named), an empty, non-numeric, NaN or infinite value, a magnitude above
:data:`~casep.io.flight.MAX_ABS_VALUE`, or time that does not strictly increase. Writers are
atomic: a failure leaves no half-written file.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Callable

import numpy as np

from casep.io._atomic import atomic_open
from casep.io.flight import AXES, DV_COLUMNS, FORCE_COLUMNS, FlightData, FlightDataError, too_large

__all__ = [
    "read_json_table",
    "read_flight", "read_flight_pair", "pair_flight", "PAIR_GRIDS", "write_flight",
    "write_table", "apparent_velocity_to_force", "locate_samples", "where", "csv_lines",
]

APPARENT_COLUMNS = tuple(f"W_{a}" for a in AXES)
VTEL_COLUMNS = tuple(f"v_tel_{a}" for a in AXES)
VTRK_COLUMNS = tuple(f"v_trk_{a}" for a in AXES)
PARQUET_SUFFIXES = (".parquet", ".pq")
#: Every column a reader may use: a repeated one is refused.
KNOWN_COLUMNS = ("t",) + FORCE_COLUMNS + APPARENT_COLUMNS + DV_COLUMNS + VTEL_COLUMNS + VTRK_COLUMNS


def _is_parquet(path: Path) -> bool:
    return path.suffix.lower() in PARQUET_SUFFIXES


def _csv_line_locator(path: Path) -> Callable[[int], int | None]:
    """Map a data row (1-based; 0 = header) to its file line, skipping comments and blanks."""

    def line_of(row: int) -> int | None:
        return csv_lines(path, [row]).get(row)

    return line_of


def csv_lines(path: str | os.PathLike, data_rows) -> dict[int, int]:
    """File line of each given data row (1-based, after the header; comments and blank lines
    skipped, as pandas reads them), in one pass over the file: ``{row: line}``."""
    want = set(int(r) for r in data_rows)
    out: dict[int, int] = {}
    if not want:
        return out
    last = max(want)
    seen = -1  # the header is row 0
    try:
        with open(path, encoding="utf-8", errors="replace") as fh:
            for lineno, text in enumerate(fh, 1):
                st = text.strip()
                if not st or st.startswith("#"):
                    continue
                seen += 1
                if seen in want:
                    out[seen] = lineno
                    if seen >= last:
                        break
    except OSError:
        pass
    return out


def locate_samples(flight: FlightData, samples) -> list[dict]:
    """Where samples of a flight come from: ``{"sample", "t", "file", "row", "line"}`` each.

    ``row`` is the 1-based data row of the file (after the header), ``line`` its line in a CSV
    file (comments and blank lines counted; None for Parquet). For a telemetry + tracking pair
    on the tracking grid the file is the tracking file; on the telemetry grid the telemetry file.
    """
    samples = [int(k) for k in samples]
    meta = flight.meta if isinstance(flight.meta, dict) else {}
    src = meta.get("rows_file")
    index = meta.get("rows_index")  # data row (0-based) of each sample in `src`, when not the identity
    if src is None:
        return [{"sample": k, "t": float(flight.t[k]), "file": None, "row": None, "line": None} for k in samples]
    rows = [int(index[k]) + 1 if index is not None else k + 1 for k in samples]
    lines = csv_lines(src, rows) if not _is_parquet(Path(src)) else {}
    return [{"sample": k, "t": float(flight.t[k]), "file": str(src), "row": r, "line": lines.get(r)}
            for k, r in zip(samples, rows)]


def where(loc: dict) -> str:
    """``line 1703 of f.csv (t = 85.1 s)``, or the row for Parquet, or the sample when no file."""
    t = f"t = {loc['t']:.6g} s"
    if loc.get("file") is None:
        return f"sample {loc['sample'] + 1} ({t})"
    name = Path(loc["file"]).name
    if loc.get("line") is not None:
        return f"line {loc['line']} of {name} ({t})"
    return f"row {loc['row']} of {name} ({t})"


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


def _parquet_header(path: Path) -> list[str]:
    import pyarrow.parquet as pq

    return list(pq.read_schema(path).names)


def _read_parquet_frame(path: Path):
    """A Parquet file as a DataFrame, one column at a time.

    Reading the whole table and converting it holds the data three to four times at once (Arrow
    buffers, pandas' consolidated block, its copy): 1.3 GB for a 5e6-sample flight of 280 MB.
    Column by column, each float column is a zero-copy view of its Arrow buffer, so reading
    costs about the size of the data.
    """
    import pandas as pd
    import pyarrow.parquet as pq

    pf = pq.ParquetFile(path)
    columns = {}
    for name in pf.schema_arrow.names:
        col = pf.read(columns=[name], use_threads=False).column(0)
        if col.num_chunks == 1 and col.null_count == 0 and str(col.type) in ("double", "float"):
            columns[name] = col.chunk(0).to_numpy(zero_copy_only=True)
        else:
            columns[name] = col.to_pandas()  # other types keep their pandas dtype (checked later)
    return pd.DataFrame(columns, copy=False)


class _Table:
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
        if _is_parquet(self.path):
            self.line_of: Callable[[int], int | None] = lambda row: None
            self._refuse_repeated(self._parquet(_parquet_header))  # before pandas, which fails on them
            frame = self._parquet(_read_parquet_frame)
        else:
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
        line = self.line_of(0 if row == "header" else row) if row is not None else None
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
        if dtype.kind in "iuf" or (dtype.kind == "O" and not _is_parquet(self.path)):
            return
        hint = {"M": "; give time in seconds (e.g. seconds since lift-off)",
                "m": "; give time in seconds", "b": "; give numbers"}.get(dtype.kind, "")
        raise self.error(f"column has dtype {dtype}, not a number{hint}", col, "header")

    def numeric(self, col: str) -> np.ndarray:
        """Column as float64, or the error at its first bad cell."""
        import pandas as pd

        self._check_dtype(col)
        raw = self.frame[col]
        values = pd.to_numeric(raw, errors="coerce").to_numpy(dtype=float)
        bad = np.flatnonzero(~np.isfinite(values))
        if not bad.size:
            big = too_large(values)
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
        elif isinstance(cell, (float, np.floating)) and _is_parquet(self.path):
            what = "NaN value"
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
            elif raw.dtype.kind == "O" and not _is_parquet(self.path):
                values = pd.to_numeric(raw, errors="coerce").to_numpy(dtype=float)
                text = raw[np.isnan(values)].dropna().astype(str).str.strip().str.lower().str.lstrip("+-")
                if text.isin(["nan", "inf", "infinity", ""]).all():  # numbers, NaN or empty cells
                    out[col] = values[rows]
        return out

    def vectors(self, cols: tuple[str, ...]) -> np.ndarray:
        return np.column_stack([self.numeric(c) for c in cols])

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


def _force(tab: _Table, t: np.ndarray) -> tuple[np.ndarray, str]:
    if tab.has(FORCE_COLUMNS) or not any(c in tab.columns for c in APPARENT_COLUMNS):
        tab.require(FORCE_COLUMNS, ". Use: f_x, f_y, f_z (m/s^2), or W_x, W_y, W_z (apparent velocity, m/s)")
        return tab.vectors(FORCE_COLUMNS), "f"
    tab.require(APPARENT_COLUMNS, ". Use: W_x, W_y, W_z (apparent velocity, m/s), or f_x, f_y, f_z")
    if t.size < 3:
        raise tab.error("apparent velocity needs at least 3 samples to differentiate", "W_x", t.size)
    return apparent_velocity_to_force(t, tab.vectors(APPARENT_COLUMNS)), "W"


def read_flight(path: str | os.PathLike) -> FlightData:
    """Read a one-file flight (CSV, or Parquet by extension ``.parquet``/``.pq``).

    Parameters
    ----------
    path : str or path-like
        Columns ``t``, ``f_*`` or ``W_*``, and ``dv_*`` or ``v_tel_*`` with ``v_trk_*``; any
        other numeric column becomes a signal (``FlightData.signals``).

    Returns
    -------
    FlightData
        ``meta`` records the file format, which force and velocity columns were used and,
        with ``v_tel_*`` columns, the telemetry speed at the first sample
        (``start_speed_m_s``, for :func:`casep.io.flight.late_start_evidence`).

    Raises
    ------
    FlightDataError
        Naming file, column and row of the first problem.
    """
    tab = _Table(path)
    tab.require(("t",))
    t = tab.time()
    f, force_from = _force(tab, t)
    if tab.has(DV_COLUMNS) or not any(c in tab.columns for c in VTEL_COLUMNS):
        tab.require(DV_COLUMNS, ". Use: dv_x, dv_y, dv_z, or v_tel_x/y/z with v_trk_x/y/z")
        dv, dv_from = tab.vectors(DV_COLUMNS), "dv"
    else:
        tab.require(VTEL_COLUMNS + VTRK_COLUMNS, ". Use: v_tel_x/y/z with v_trk_x/y/z, or dv_x, dv_y, dv_z")
        v_tel = tab.vectors(VTEL_COLUMNS)
        dv, dv_from = v_tel - tab.vectors(VTRK_COLUMNS), "v_tel - v_trk"
    meta = {"format": "parquet" if _is_parquet(tab.path) else "csv", "force": force_from, "dv": dv_from,
            "rows_file": str(tab.path)}  # sample k is data row k + 1 (locate_samples)
    if dv_from != "dv":
        meta["start_speed_m_s"] = float(np.linalg.norm(v_tel[0]))
        meta["telemetry_velocity_change_m_s"] = (v_tel[-1] - v_tel[0]).tolist()  # for casep.analysis.checks
    signals, src = tab.signals(), tab.src
    del tab  # the file's columns, before FlightData takes its own copies (long flights: one copy at a time)
    return FlightData(t, f, dv, source=src, meta=meta, signals=signals)


#: Where a telemetry + tracking pair is evaluated (``read_flight_pair(grid=...)``).
PAIR_GRIDS = ("tracking", "telemetry")


# ------------------------------------------------------------------ tracking frames
def _check_tracking_frame(tracking: str | os.PathLike, tracking_frame: str, site) -> None:
    """`tracking_frame` is one of casep.frames.TRACKING_FRAMES; an Earth-fixed one needs a LaunchSite."""
    from casep.frames import TRACKING_FRAMES, LaunchSite

    if tracking_frame not in TRACKING_FRAMES:
        raise ValueError(f"`tracking_frame` must be one of {', '.join(TRACKING_FRAMES)}, got {tracking_frame!r}")
    if tracking_frame == "launch" and site is not None:
        raise ValueError(f"{tracking}: `site` is used only with an Earth-fixed tracking_frame ('ecef' or 'geodetic'); "
                         "launch-frame tracking needs no site")
    if tracking_frame != "launch" and not isinstance(site, LaunchSite):
        raise ValueError(f"{tracking}: {tracking_frame} tracking needs the launch site and launch time to be turned "
                         "into the launch-inertial frame: give site=LaunchSite(lat_deg, lon_deg, h_m, azimuth_deg, t0) "
                         "(CLI: --launch-site LAT LON H AZ --launch-time T0)")


def _tracking_velocity(trk: "_Table", t_trk: np.ndarray, tracking_frame: str,
                       site) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """The tracking velocity in the launch-inertial frame, m/s (casep.frames), from the file's own time tags,
    and (Earth-fixed frames) the tracked ECEF position and Earth-relative velocity (m, m/s; None for launch)."""
    from casep.frames import ECEF_COLUMNS, GEODETIC_COLUMNS, ecef_to_launch, geodetic_to_ecef

    if tracking_frame == "launch":
        return trk.vectors(VTRK_COLUMNS), None, None
    if tracking_frame == "ecef":
        r, v = trk.vectors(ECEF_COLUMNS[1:4]), trk.vectors(ECEF_COLUMNS[4:7])
    else:
        lat, lon, h, ve, vn, vu = (trk.numeric(c) for c in GEODETIC_COLUMNS[1:])
        for col, values, lim in (("lat", lat, 90.0), ("lon", lon, 360.0)):
            bad = np.flatnonzero(np.abs(values) > lim)
            if bad.size:
                raise trk.error(f"{values[bad[0]]:g} deg is outside +-{lim:g} deg (latitude and longitude in degrees)",
                                col, int(bad[0]) + 1)
        r, v = geodetic_to_ecef(lat, lon, h, ve, vn, vu)
    return ecef_to_launch(site, t_trk, r, v)[1], r, v


def _tracking_hint(trk: "_Table", tracking_frame: str) -> str:
    """What a tracking file lacks, and the frame its columns suggest."""
    from casep.frames import ECEF_COLUMNS, GEODETIC_COLUMNS

    if tracking_frame == "ecef":
        return ". Use (ECEF, m, m/s): " + ", ".join(ECEF_COLUMNS)
    if tracking_frame == "geodetic":
        return ". Use (deg, deg, m, m/s east/north/up): " + ", ".join(GEODETIC_COLUMNS)
    for frame, cols in (("ecef", ECEF_COLUMNS), ("geodetic", GEODETIC_COLUMNS)):
        if trk.has(cols):
            return (f". Use: t, v_trk_x, v_trk_y, v_trk_z; this file has {frame} columns: read it with "
                    f"tracking_frame='{frame}' and site=LaunchSite(...) (CLI: --tracking-frame {frame} "
                    "--launch-site LAT LON H AZ --launch-time T0)")
    return ". Use: t, v_trk_x, v_trk_y, v_trk_z"
# ------------------------------------------------------------------ end tracking frames


def read_flight_pair(telemetry: str | os.PathLike, tracking: str | os.PathLike, *,
                     interpolation: str = "cubic", grid: str = "tracking",
                     time_offset: float | str | None = None, tracking_frame: str = "launch",
                     site=None, time_shift: float = 0.0) -> FlightData:
    """Combine a telemetry file and a tracking file recorded at different rates.

    Parameters
    ----------
    telemetry : path
        ``t``, ``f_*`` or ``W_*``, ``v_tel_*``; its other numeric columns become signals
        (the tracking file's other columns are not read).
    tracking : path
        ``t``, ``v_trk_*``, at its own times.
    interpolation : {"cubic", "linear"}, optional
        How the velocity of the other source is carried to the grid's times (see `grid`): a
        not-a-knot cubic spline (error of order dt^4 times the 4th derivative, default) or
        linear (error ~ a dt^2 / 8: 0.016 m/s at 50 m/s^2 and 20 Hz, not negligible against
        0.1 m/s noise).
    grid : {"tracking", "telemetry"}, optional
        Where dv is formed. ``"tracking"`` (default): at the tracking times, ``dv = v_tel(t_trk) -
        v_trk``, the (smooth, nearly noise-free) telemetry velocity interpolated; each tracking
        sample is one row, so its noise stays white and the std are honest. ``"telemetry"``: at
        the telemetry times, the tracking velocity interpolated, which spreads each tracking
        sample's noise over ``f_tel / f_trk`` correlated rows: white-noise std then understate the
        error by about ``sqrt(f_tel / f_trk)`` (casep 0.1's behaviour, kept for comparison).
    time_offset : float, "auto" or None, optional
        Tracking time tags late by this many seconds: they are shifted back before the pair is
        formed. ``"auto"``: the coarse offset that lines up the velocities
        (:func:`casep.io.align.coarse_time_offset`; the model term ``dt_trk`` then finds the
        rest). None (default): no shift, but the coarse offset is still computed and a
        :class:`~casep.exceptions.TimeOffsetWarning` gives it when it exceeds a tracking sample
        period (a first-order ``dt_trk`` is not meant for that). ``meta["time_alignment"]`` records it.
    tracking_frame : {"launch", "ecef", "geodetic"}, optional
        Frame of the tracking file. ``"launch"`` (default): ``t, v_trk_*``, launch-inertial.
        ``"ecef"``: ``t, r_ecef_x/y/z, v_ecef_x/y/z`` (m, m/s; WGS84, Earth-fixed, velocity relative
        to the rotating Earth). ``"geodetic"``: ``t, lat, lon, h, v_east, v_north, v_up`` (deg, deg, m
        above the ellipsoid, m/s in the local ENU axes). Earth-fixed tracking is turned into the
        launch-inertial velocity (:mod:`casep.frames`, Earth rotation included) at the file's own
        time tags, before any `time_offset` shift; ``meta["tracking_frame"]`` records frame and site.
    site : casep.frames.LaunchSite, optional
        Launch point, azimuth and launch time (in the tracking file's time scale): required with an
        Earth-fixed `tracking_frame` (ValueError naming the file otherwise). The set-up checks
        (:func:`casep.io.flight.setup_evidence`) compare the first tracked position with it and
        the telemetry velocity at its first sample with its pad velocity; ``meta["setup"]``.
    time_shift : float, optional
        How the time scales relate, s: tracking time minus telemetry time for the same instant
        (tracking in seconds of day, telemetry from lift-off at 12:00:00: 43200). Tracking time
        tags ``T`` become ``T - time_shift`` in the telemetry's scale; the launch time stays in the
        tracking scale. Default 0 (one time scale). Telemetry and tracking that do not overlap
        after it are an error that gives both spans.

    Returns
    -------
    FlightData
        Every telemetry sample from the first one to the end of tracking (with ``grid="tracking"``
        the tracking times inserted among them, force and signals linearly interpolated there):
        S_V is integrated from the first telemetry sample, so the instrument errors before tracking
        starts are kept. dv is observed (``observed``) at the tracking times (or at the telemetry
        samples inside the tracking span) and NaN elsewhere. ``meta`` records the grid, the spans
        (s), the samples before tracking (``unobserved``) and after it (``telemetry_dropped``), and
        the telemetry speed at the first sample (``start_speed_m_s``).
    """
    if interpolation not in ("cubic", "linear"):
        raise ValueError(f"`interpolation` must be 'cubic' or 'linear', got {interpolation!r}")
    if grid not in PAIR_GRIDS:
        raise ValueError(f"`grid` must be one of {', '.join(PAIR_GRIDS)}, got {grid!r}")
    _check_tracking_frame(tracking, tracking_frame, site)
    tel, trk = _Table(telemetry), _Table(tracking)
    tel.require(("t",))
    from casep.frames import ECEF_COLUMNS, GEODETIC_COLUMNS

    trk.require({"launch": ("t",) + VTRK_COLUMNS, "ecef": ECEF_COLUMNS, "geodetic": GEODETIC_COLUMNS}[tracking_frame],
                _tracking_hint(trk, tracking_frame))
    tel.require(VTEL_COLUMNS, ". Use: v_tel_x, v_tel_y, v_tel_z")
    t_tel = tel.time()
    f, force_from = _force(tel, t_tel)
    v_tel = tel.vectors(VTEL_COLUMNS)
    t_raw = trk.time()  # the tracking file's own time scale (the launch time's)
    if site is not None:
        _check_launch_time(trk, t_raw, site)
    v_trk, r_ecef, v_ecef = _tracking_velocity(trk, t_raw, tracking_frame, site)  # launch-inertial
    if t_raw.size < (4 if interpolation == "cubic" else 2):
        raise trk.error(f"{t_raw.size} tracking samples are too few for {interpolation} interpolation", "t", t_raw.size)
    shift_scale = _time_shift(time_shift)
    t_trk = t_raw - shift_scale  # the telemetry's time scale
    inside = (t_tel >= t_trk[0]) & (t_tel <= t_trk[-1])
    if inside.sum() < 2:
        raise tel.error(_no_overlap_message(t_tel, t_raw, shift_scale), "t")
    align = None
    if time_offset is None or time_offset == "auto":
        from casep.io.align import coarse_time_offset

        try:
            align = coarse_time_offset(t_tel, v_tel, t_trk, v_trk, max_offset=min(2.0, 0.25 * (t_trk[-1] - t_trk[0])))
        except ValueError:
            if time_offset == "auto":
                raise
    import warnings

    from casep.exceptions import SetupWarning, TimeOffsetWarning

    if time_offset == "auto":
        shift = align.tau
    elif time_offset is None:
        shift = 0.0
        if align is not None and align.exceeds_period and align.explains:
            # only when the shift explains the data: a wrong site or frame leaves a misfit no shift removes
            warnings.warn(f"{tel.src} + {trk.src}: the tracking time tags look {align.tau * 1e3:.1f} ms late "
                          f"(velocity increments line up best there: mean squared difference {align.cost:.3g} against "
                          f"{align.cost_at_zero:.3g} m^2/s^2 unshifted, {100 * align.gain:.3g} % of the misfit "
                          "removed, "
                          f"F = {align.f_statistic:.3g}), more than a tracking sample period "
                          f"({align.tracking_period * 1e3:.4g} ms); align them (--time-offset auto) and let dt_trk "
                          "estimate the rest", TimeOffsetWarning, stacklevel=2)
    else:
        try:
            shift = float(time_offset)
        except (TypeError, ValueError):
            raise ValueError(f"`time_offset` must be a number of seconds, 'auto' or None, "
                             f"got {time_offset!r}") from None
        if not np.isfinite(shift):
            raise ValueError(f"`time_offset` must be finite, got {shift}")
        if abs(shift) > MAX_TIME_OFFSET:
            span = t_trk[-1] - t_trk[0]
            warnings.warn(SetupWarning(
                f"{trk.src}: a tracking time offset of {shift:.6g} s ({shift * 1e3:.6g} ms) is far beyond tracking "
                f"latencies (milliseconds, below {MAX_TIME_OFFSET:g} s; --time-offset is in milliseconds) and is "
                f"{100 * abs(shift) / span:.3g} % of the {span:.4g} s tracking span. If the two files count time from "
                "different origins, state it with time_shift (--time-shift SECONDS, manifest time_shift_s)."),
                stacklevel=2)
    mode = "auto" if time_offset == "auto" else ("none" if time_offset is None else "given")
    extra = {"time_alignment": {**(align.to_dict() if align is not None else {}), "applied_s": shift, "mode": mode}}
    signals = tel.signals()
    if not all(f"a_{a}" in signals for a in "xyz"):
        # the kinematic acceleration for a time-offset term: d v_tel / dt (cubic spline), exact kinematics
        from scipy.interpolate import CubicSpline

        acc = CubicSpline(t_tel, v_tel, axis=0).derivative()(t_tel)
        signals.update({f"a_{a}": acc[:, i] for i, a in enumerate("xyz")})
        extra["kinematic_acceleration"] = "a_x, a_y, a_z: d v_tel / dt (cubic spline of the telemetry velocity)"
    if tracking_frame != "launch":
        extra["tracking_frame"] = {"frame": tracking_frame, "site": site.to_dict()}
    flight = pair_flight(t_tel, f, v_tel, t_trk - shift, v_trk, signals=signals, interpolation=interpolation,
                         grid=grid, source=f"{tel.src} + {trk.src}",
                         meta={"force": force_from, "telemetry": tel.src, "tracking": trk.src, **extra})
    flight.meta["rows_file"] = str(trk.path if flight.meta.get("rows_side") == "tracking" else tel.path)
    if shift_scale:
        flight.meta["time_shift_s"] = shift_scale
    if tracking_frame != "launch":  # the late-start check: speed relative to the pad, not the Earth's rotation
        from casep.io.flight import setup_evidence

        ev = setup_evidence(site, t_tel, v_tel, t_raw, r_ecef, v_ecef, time_shift=shift_scale)
        flight.meta["start_speed_m_s"] = ev["pad"]["speed_relative_m_s"]
        flight.meta["tracking_frame"]["pad_velocity_m_s"] = ev["pad"]["pad_velocity_m_s"]
        flight.meta["setup"] = ev
    if r_ecef is not None and not any(c in flight.signals for c in STATE_SIGNALS):  # Earth-fixed: the state
        from casep.frames import ecef_to_launch

        r_l, v_l = ecef_to_launch(site, t_raw, r_ecef, v_ecef)  # launch-inertial, at the file's own time tags
        flight = _with_tracked_state(flight, t_trk - shift, r_l, v_l)
    return flight


#: Launch-inertial position and velocity columns (m, m/s): the burnout state of casep.impact.
STATE_SIGNALS = ("r_x", "r_y", "r_z", "v_x", "v_y", "v_z")


def _with_tracked_state(flight: FlightData, t_trk: np.ndarray, r: np.ndarray, v: np.ndarray) -> FlightData:
    """The flight with the tracked position and velocity (Earth-fixed tracking turned launch-inertial) as the
    signals ``r_*``, ``v_*`` on its time grid: a not-a-knot cubic spline through the tracking samples inside
    their span, NaN outside (before tracking starts). What the impact analysis reads as the burnout state."""
    import dataclasses

    from scipy.interpolate import CubicSpline

    t = np.asarray(flight.t)
    inside = (t >= t_trk[0]) & (t <= t_trk[-1])
    sig = dict(flight.signals)
    for name, values in zip(STATE_SIGNALS, np.column_stack([r, v]).T):
        col = np.full(t.size, np.nan)
        col[inside] = CubicSpline(t_trk, values)(t[inside])
        sig[name] = col
    meta = {**flight.meta, "state_from": "tracking (r_*, v_*: launch-inertial, spline on the flight's times)"}
    return dataclasses.replace(flight, signals=sig, meta=meta)


#: A given tracking time offset above this, s, is no latency: a warning suggests `time_shift`.
MAX_TIME_OFFSET = 2.0
#: The launch time must lie within this of the tracking file's time tags, s (a day: seconds of day,
#: of a week's GPS time or since an epoch all put it within hours of the tracking).
MAX_LAUNCH_TIME_GAP = 86400.0


def _time_shift(value) -> float:
    """`time_shift`: a finite number of seconds."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not np.isfinite(value):
        raise ValueError(f"`time_shift` (tracking time minus telemetry time, s) must be a finite number, got {value!r}")
    return float(value)


def _check_launch_time(trk: "_Table", t_raw: np.ndarray, site) -> None:
    """The launch time in the tracking file's time scale: within :data:`MAX_LAUNCH_TIME_GAP` of its time tags."""
    gap = max(t_raw[0] - site.t0, site.t0 - t_raw[-1], 0.0)
    if gap > MAX_LAUNCH_TIME_GAP:
        raise trk.error(f"the launch time {site.t0:.10g} s is {gap:.4g} s from the tracking time tags "
                        f"[{t_raw[0]:.10g}, {t_raw[-1]:.10g}] s (more than {MAX_LAUNCH_TIME_GAP:g} s): give it in the "
                        "tracking file's time scale (--launch-time, manifest launch_time_s)", "t")


def _no_overlap_message(t_tel: np.ndarray, t_raw: np.ndarray, shift: float) -> str:
    """Telemetry and tracking that do not overlap: both spans, and the shift that would line them up."""
    after = t_raw[0] - shift - t_tel[0]
    scale = f" (after time_shift {shift:g} s: [{t_raw[0] - shift:.10g}, {t_raw[-1] - shift:.10g}] s)" if shift else ""
    return (f"telemetry time [{t_tel[0]:.10g}, {t_tel[-1]:.10g}] s and tracking time [{t_raw[0]:.10g}, "
            f"{t_raw[-1]:.10g}] s{scale} share fewer than 2 telemetry samples: the tracking starts {after:.6g} s "
            f"{'after' if after >= 0 else 'before'} the telemetry. Telemetry and tracking must be on one time scale; "
            "if they count from different origins (seconds of day against seconds from lift-off), state how they "
            f"relate: time_shift = tracking time - telemetry time (e.g. {t_raw[0] - t_tel[0]:.10g} if both start "
            "together; CLI --time-shift, manifest time_shift_s)")


def pair_flight(t_tel: np.ndarray, f: np.ndarray, v_tel: np.ndarray, t_trk: np.ndarray, v_trk: np.ndarray, *,
                signals: dict[str, np.ndarray] | None = None, interpolation: str = "cubic", grid: str = "tracking",
                source: str = "<memory>", meta: dict | None = None) -> FlightData:
    """The flight of a telemetry + tracking pair held in arrays (see :func:`read_flight_pair`).

    Parameters
    ----------
    t_tel, f, v_tel : arrays
        Telemetry times (s, increasing), specific force (m/s^2) and velocity (m/s).
    t_trk, v_trk : arrays
        Tracking times (s, increasing) and velocity (m/s).
    signals : dict, optional
        Other telemetry columns at `t_tel`.

    Notes
    -----
    With ``grid="tracking"`` a tracking time within 1e-9 s of a telemetry time is that sample;
    the others are inserted, with ``f`` and the signals linearly interpolated (S_V integrates
    ``f`` by the trapezoid rule, so a linearly interpolated sample leaves its first-order terms
    unchanged). Tracking samples outside the telemetry span are dropped (counted in
    ``meta["tracking_dropped"]``).
    """
    from scipy.interpolate import CubicSpline

    t_tel, t_trk = np.asarray(t_tel, dtype=float), np.asarray(t_trk, dtype=float)
    f, v_tel, v_trk = (np.asarray(a, dtype=float) for a in (f, v_tel, v_trk))
    signals = dict(signals or {})

    def carry(t_from, v_from, t_to):  # velocity of one source at the other's times
        if interpolation == "cubic":
            return CubicSpline(t_from, v_from, axis=0)(t_to)
        return np.column_stack([np.interp(t_to, t_from, v_from[:, i]) for i in range(3)])

    keep = t_tel <= t_trk[-1]  # from the first telemetry sample to the end of tracking
    extra: dict = {}
    trk_gaps, tel_gaps = _gaps(t_trk), _gaps(t_tel)
    if grid == "telemetry":
        t, observed = t_tel[keep], (t_tel[keep] >= t_trk[0])
        in_gap = _inside(t, trk_gaps)
        if in_gap.any():  # tracking interpolated across a gap invents data: those rows are not observed
            _warn_gaps("tracking", trk_gaps, int(np.count_nonzero(in_gap & observed)), "telemetry samples", source)
            observed &= ~in_gap
            extra["gap_rows_left_out"] = int(np.count_nonzero(in_gap))
        dv = np.full((t.size, 3), np.nan)  # not observed before tracking starts
        dv[observed] = v_tel[keep][observed] - carry(t_trk, v_trk, t[observed])  # v_tel - v_trk(t_tel)
        f_out = f[keep]
        sig = {k: v[keep] for k, v in signals.items()}
        how = f"v_tel - v_trk at telemetry times ({interpolation} interpolation of tracking)"
        extra.update(rows_side="telemetry", rows_index=np.flatnonzero(keep))
    else:
        use = (t_trk >= t_tel[0]) & (t_trk <= t_tel[-1])
        in_gap = _inside(t_trk, tel_gaps) & use
        if in_gap.any():  # telemetry velocity interpolated across a telemetry gap: those tracking rows left out
            _warn_gaps("telemetry", tel_gaps, int(np.count_nonzero(in_gap)), "tracking samples", source)
            use &= ~in_gap
            extra["gap_rows_left_out"] = int(np.count_nonzero(in_gap))
        tt = t_trk[use]
        t_keep = t_tel[keep]
        j = np.clip(np.searchsorted(t_keep, tt), 1, t_keep.size - 1)
        near = np.minimum(np.abs(t_keep[j] - tt), np.abs(t_keep[j - 1] - tt))
        on = near <= 1e-9
        t = np.union1d(t_keep, tt[~on])  # telemetry samples and the tracking times between them
        idx = np.clip(np.searchsorted(t, tt - 1e-9), 0, t.size - 1)  # each tracking time's row
        observed = np.zeros(t.size, bool)
        observed[idx] = True
        dv = np.full((t.size, 3), np.nan)
        dv[idx] = carry(t_tel, v_tel, tt) - v_trk[use]  # v_tel(t_trk) - v_trk
        f_out = np.column_stack([np.interp(t, t_tel, f[:, i]) for i in range(3)])
        sig = {k: np.interp(t, t_tel, v) for k, v in signals.items()}
        how = f"v_tel - v_trk at tracking times ({interpolation} interpolation of telemetry)"
        extra = {**extra, "tracking_dropped": int((~use).sum()), "inserted": int((~on).sum()), "rows_side": "tracking"}
        rows_index = np.full(t.size, -1)
        rows_index[idx] = np.flatnonzero(use)  # the tracking data row of each observed sample
        extra["rows_index"] = rows_index
    if trk_gaps or tel_gaps:
        extra["gaps_s"] = {"tracking": trk_gaps, "telemetry": tel_gaps}
    meta = {"format": "pair", "grid": grid, "dv": how, **(meta or {}), **extra,
            "telemetry_span_s": [float(t_tel[0]), float(t_tel[-1])],
            "tracking_span_s": [float(t_trk[0]), float(t_trk[-1])],
            "span_s": [float(t[0]), float(t[-1])], "observed_span_s": [float(t[observed][0]), float(t[observed][-1])],
            "unobserved": int((~observed).sum()), "telemetry_dropped": int((~keep).sum()),
            "start_speed_m_s": float(np.linalg.norm(v_tel[0])),
            "telemetry_velocity_change_m_s": (v_tel[keep][-1] - v_tel[0]).tolist()}  # for casep.analysis.checks
    return FlightData(t, f_out, dv, source=source, meta=meta, observed=observed, signals=sig)


#: A step this many times the median sample step is a gap that interpolation must not bridge ...
GAP_FACTOR = 5.0
#: ... and at least this long, s (a few missing samples at 20 Hz are bridged well by a cubic spline).
GAP_MIN_S = 0.5


def _gaps(t: np.ndarray) -> list[list[float]]:
    """``[[start, end], ...]`` of the steps of `t` above :data:`GAP_FACTOR` x its median step and :data:`GAP_MIN_S`."""
    if t.size < 3:
        return []
    step = np.diff(t)
    big = np.flatnonzero((step > GAP_FACTOR * np.median(step)) & (step > GAP_MIN_S))
    return [[float(t[k]), float(t[k + 1])] for k in big]


def _inside(t: np.ndarray, gaps: list[list[float]]) -> np.ndarray:
    """Samples strictly inside one of the `gaps`."""
    out = np.zeros(t.size, dtype=bool)
    for a, b in gaps:
        out |= (t > a) & (t < b)
    return out


def _warn_gaps(which: str, gaps: list[list[float]], rows: int, what: str, source: str) -> None:
    import warnings

    from casep.exceptions import GapWarning

    listed = ", ".join(f"{b - a:.4g} s from t = {a:.10g} s" for a, b in gaps[:5]) + (" ..." if len(gaps) > 5 else "")
    warnings.warn(GapWarning(
        f"{source}: the {which} has {len(gaps)} gap(s) ({listed}; above {GAP_FACTOR:g} x its median step and "
        f"{GAP_MIN_S:g} s): interpolating across them would invent data, so the {rows} {what} inside are left out of "
        "the regression (S_V is still integrated through them)"), stacklevel=4)


def write_table(path: str | os.PathLike, columns: dict[str, np.ndarray], *,
                comments: list[str] | None = None) -> None:
    """Write named 1-D columns as CSV (``%.17g``, exact round trip) or Parquet, atomically.

    Parameters
    ----------
    path : path
        ``.parquet`` / ``.pq`` writes Parquet (needs pyarrow), anything else CSV.
    columns : dict of str -> (N,) array
        Column name to values, in order.
    comments : list of str, optional
        CSV only: lines written first as ``# ...`` (Parquet keeps them as metadata).
    """
    path = Path(path)
    names = list(columns)
    data = np.column_stack([np.asarray(columns[c], dtype=float) for c in names])
    if _is_parquet(path):
        try:
            import pyarrow as pa
            import pyarrow.parquet as pq
        except ImportError:
            raise ValueError(f"{path}: writing Parquet needs pyarrow: pip install pyarrow") from None
        table = pa.table({c: data[:, i] for i, c in enumerate(names)},
                         metadata={"comments": "\n".join(comments or [])})
        with atomic_open(path, binary=True) as fh:
            pq.write_table(table, fh)
        return
    with atomic_open(path) as fh:
        for line in comments or []:
            fh.write(f"# {line}\n")
        fh.write(",".join(names) + "\n")
        np.savetxt(fh, data, delimiter=",", fmt="%.17g")


def write_flight(flight: FlightData, path: str | os.PathLike, *, comments: list[str] | None = None) -> None:
    """Write a flight (``t, f_x, f_y, f_z, dv_x, dv_y, dv_z``, then its signals) as CSV or Parquet, atomically."""
    if not isinstance(flight, FlightData):
        raise TypeError(f"`flight` must be a FlightData, got {type(flight).__name__}")
    if flight.n_observed < flight.n_samples:
        raise ValueError(f"{path}: the flight has {flight.n_samples - flight.n_observed} samples without tracking, "
                         "which the one-file format cannot hold; keep the telemetry and tracking files")
    cols = {"t": flight.t}
    cols.update({c: flight.f[:, i] for i, c in enumerate(FORCE_COLUMNS)})
    cols.update({c: flight.dv[:, i] for i, c in enumerate(DV_COLUMNS)})
    cols.update(flight.signals)
    write_table(path, cols, comments=comments)


def read_json_table(path: str | os.PathLike, option: str) -> dict:
    """A JSON object keyed by coefficient name (``--bounds``, ``--prior``, ``--truth``, ``--scales``).

    Read strictly (:func:`casep.io.result_json.load_json`: a key repeated in one object, or
    nesting too deep to decode, is refused). Errors name the option and the file (``ValueError``);
    the entries are checked by the caller, which knows the model's coefficients.
    """
    from casep.io.result_json import load_json

    data = load_json(path, option)
    if not isinstance(data, dict):
        raise ValueError(f"{option} {path}: must hold a JSON object keyed by coefficient name")
    return data

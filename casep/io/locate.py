"""Where the samples of a flight come from: data row and file line, for messages that name them.

A flight read from a file records the file (``meta["rows_file"]``) and, when its samples are not
the file's rows one to one, the data row of each sample (``meta["rows_index"]``);
:func:`locate_samples` turns sample indices into ``{"sample", "t", "file", "row", "line"}`` and
:func:`where` into text (``line 1703 of f.csv (t = 85.1 s)``).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Iterable

from casep.io.flight import FlightData

__all__ = ["csv_lines", "locate_samples", "where", "is_parquet", "PARQUET_SUFFIXES"]

#: File name endings read and written as Parquet; anything else is CSV.
PARQUET_SUFFIXES = (".parquet", ".pq")


def is_parquet(path: str | os.PathLike) -> bool:
    """Whether `path` names a Parquet file (by its extension, :data:`PARQUET_SUFFIXES`)."""
    return Path(path).suffix.lower() in PARQUET_SUFFIXES


def csv_lines(path: str | os.PathLike, data_rows: Iterable[int]) -> dict[int, int]:
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


def locate_samples(flight: FlightData, samples: Iterable[int]) -> list[dict]:
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
    lines = csv_lines(src, rows) if not is_parquet(src) else {}
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



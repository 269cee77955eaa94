"""Writers of results: JSON, MATLAB/Octave ``.mat`` and CSV, each all or nothing.

They take plain data (dicts, lists, arrays), not a result object: the result types turn
themselves into it (``EstimateResult.to_dict``, its MAT fields, its coefficient rows). Writing
goes through :func:`casep.io._atomic.atomic_open`, so a file appears whole or not at all.
Library: :func:`scipy.io.savemat` for ``.mat`` (MATLAB 5 format, compressed), the standard
:mod:`json` and :mod:`csv` modules for the others.
"""

from __future__ import annotations

import csv
import json
import math
import os
from typing import Any, Mapping, Sequence

import numpy as np

from casep.io._atomic import atomic_open

__all__ = ["write_json_atomic", "write_mat_fields", "write_coefficients_csv", "mat_value", "jsonable"]


def jsonable(v: Any) -> Any:
    """Tuples and numpy scalars as JSON values (non-finite floats as None)."""
    if isinstance(v, dict):
        return {str(k): jsonable(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [jsonable(x) for x in v]
    if isinstance(v, (np.floating, float)):
        f = float(v)
        return f if math.isfinite(f) else None
    if isinstance(v, np.integer):
        return int(v)
    return v


def write_json_atomic(data: dict[str, Any], path: str | os.PathLike) -> None:
    """Write JSON to `path` through a temporary file and a rename: never half-written."""
    try:
        text = json.dumps(data, indent=2, allow_nan=False) + "\n"
    except ValueError:  # NaN or inf somewhere: say where, and what put it there
        where = _first_non_finite(data)
        raise ValueError(f"{path}: cannot write a non-finite value ({where[1]!r}) at `{where[0]}`: the input that "
                         "produced it is out of range (a prior, bound or option far beyond its plausible values?)"
                         if where else f"{path}: cannot write a non-finite value") from None
    with atomic_open(path) as fh:
        fh.write(text)


def _first_non_finite(v: Any, where: str = "") -> tuple[str, float] | None:
    """The path (``settings.prior.Kg0x.mean``) and value of the first NaN or inf in a JSON-like value."""
    items: Any
    if isinstance(v, dict):
        items = v.items()
    elif isinstance(v, (list, tuple)):
        items = ((f"[{i}]", x) for i, x in enumerate(v))
    else:
        return (where, float(v)) if isinstance(v, float) and not math.isfinite(v) else None
    for k, x in items:
        key = k if str(k).startswith("[") else (f"{where}.{k}" if where else str(k))
        hit = _first_non_finite(x, where + key if str(k).startswith("[") else key)
        if hit:
            return hit
    return None


def mat_value(v: Any) -> Any:
    """A JSON-like value as scipy.io.savemat stores it, or None to leave it out.

    Numbers -> double (null -> NaN), strings -> char, lists of numbers -> double vectors,
    lists of strings -> cellstr, dicts with MATLAB-valid keys -> struct.
    """
    if v is None:
        return np.nan
    if isinstance(v, (bool, np.bool_)):
        return bool(v)
    if isinstance(v, (int, float, np.integer, np.floating)):
        return float(v)
    if isinstance(v, str):
        return v
    if isinstance(v, (list, tuple)):
        if all(x is None or (isinstance(x, (int, float)) and not isinstance(x, bool)) for x in v):
            return np.array([np.nan if x is None else float(x) for x in v], dtype=float)
        if all(isinstance(x, str) for x in v):
            return np.array(list(v), dtype=object)
        return None
    if isinstance(v, dict):
        out = {k: mv for k, x in v.items()
               if isinstance(k, str) and k.isidentifier() and k[0].isalpha() and (mv := mat_value(x)) is not None}
        return out or None
    return None


def write_mat_fields(data: Mapping[str, Any], path: str | os.PathLike, *,
                     structs: Mapping[str, Any] | None = None) -> None:
    """Write variables to a MATLAB/Octave ``.mat`` file (scipy.io.savemat), atomically.

    Parameters
    ----------
    data : mapping
        Variable name -> array, number, string or object array (cellstr); written as given.
    path : path
    structs : mapping, optional
        Variable name -> JSON-like value, written as a struct where its fields are simple
        (:func:`mat_value`: numbers, strings, flat lists, nested such structs), left out otherwise.
    """
    from scipy.io import savemat

    out = dict(data)
    for key, v in (structs or {}).items():
        value = mat_value(v)
        if isinstance(value, dict):
            out[key] = value
    with atomic_open(path, binary=True) as fh:
        savemat(fh, out, long_field_names=True, oned_as="column", do_compression=True)


def write_coefficients_csv(rows: Sequence[Mapping[str, Any]], path: str | os.PathLike) -> None:
    """Write one row per coefficient (name, unit, estimate, std, reason) atomically.

    `rows`: dicts with ``name``, ``unit``, ``estimate``, ``std`` (None where missing) and optionally
    ``reason``. Missing values are empty cells; numbers keep 17 significant digits.
    """
    with atomic_open(path) as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(["name", "unit", "estimate", "std", "reason"])
        for row in rows:
            w.writerow([row["name"], row["unit"]] + ["" if row[k] is None else repr(float(row[k]))
                                                     for k in ("estimate", "std")] + [row.get("reason", "")])

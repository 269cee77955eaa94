"""Reading result JSON files: casep's own and those written by other tools or by hand.

One reader (:func:`read_result_data`) serves every place that takes a result: ``--prior``,
``casep fuse``, ``casep impact --result`` and :meth:`casep.EstimateResult.from_json`. The
accepted forms are written down in ``docs/guide/result-files.md``:

- the documented form: a ``coefficients`` list of ``{name, unit, estimate, std}`` objects (and
  optionally ``reason``), with an optional ``covariance`` (n x n, natural units, model order);
- the flat-array form: parallel arrays ``names``, ``units``, ``estimates``, ``std`` (MATLAB's
  ``jsonencode`` of a struct; a one-element array may be a bare value, a 1 x 1 covariance a
  number), with the same optional ``covariance``;
- casep's own result JSON, which holds both forms: the ``coefficients`` list is read and the
  flat arrays must agree with it (the first coefficient that disagrees is named).

Any other key (``model``, ``method``, ``sigma``, ``settings``, ...) is optional; where present
its type is checked. Types are strict (pydantic ``strict`` mode): ``true`` or ``"0.1"`` is not a
number. ``null`` is a missing value: an estimate without value (the coefficient is not
identifiable), a std without value, or a covariance row and column of such a coefficient.

JSON itself is read strictly too (:func:`load_json`): a key repeated in one object is refused
(``json``'s ``object_pairs_hook``; Python would keep the last silently), and so is nesting deeper
than the decoder's recursion limit (without a ``RecursionError``).

The covariance is checked (:func:`check_covariance`): shape, finite values, a non-negative
diagonal, symmetry, positive semi-definiteness, and agreement of ``std`` with the square root of
its diagonal. Errors are :class:`ValueError` naming the file and the field (``covariance[3][5]``,
``coefficients[2].std``); the command line prints them and exits 2.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from typing import Any, Callable, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

__all__ = ["load_json", "ResultData", "read_result_data", "parse_result_data", "check_covariance",
           "looks_like_result", "MAX_RESULT_VALUE", "STD_RTOL", "FORMS_RTOL", "SYMMETRY_RTOL", "PSD_TOL"]

#: Largest |estimate| or |std| accepted, natural units (covariance entries: its square). Far beyond
#: any instrument error in any unit; keeps every product and inverse of the fuse finite.
MAX_RESULT_VALUE = 1e30
#: ``std`` and ``sqrt(diag(covariance))`` must agree to this relative tolerance (values rounded to
#: 4 significant digits by hand still pass).
STD_RTOL = 1e-3
#: The ``coefficients`` list and the flat arrays of one file must agree to this relative tolerance.
FORMS_RTOL = 1e-9
#: ``|C_ij - C_ji| <= SYMMETRY_RTOL sqrt(C_ii C_jj)``.
SYMMETRY_RTOL = 1e-6
#: Smallest eigenvalue of the correlation matrix accepted as rounding of a positive semi-definite one.
PSD_TOL = 1e-8


# ----------------------------------------------------------------------------- strict JSON
def _no_repeats(pairs: list[tuple[str, Any]]) -> dict:
    out: dict = {}
    for k, v in pairs:
        if k in out:
            raise ValueError(f"key `{k}` appears twice in one object (which value is meant?); keep one")
        out[k] = v
    return out


def load_json(path: str | os.PathLike, option: str) -> Any:
    """Read a JSON file strictly: ValueError naming `option` and the file for an unreadable file,
    invalid JSON, a key repeated within one object, or nesting too deep to decode."""
    try:
        with open(path, encoding="utf-8") as fh:
            text = fh.read()
    except OSError as exc:
        raise ValueError(f"{option} {path}: cannot read ({exc.strerror})") from None
    except UnicodeDecodeError as exc:
        raise ValueError(f"{option} {path}: not a UTF-8 text file ({exc.reason})") from None
    return loads_json(text, f"{option} {path}")


def loads_json(text: str, where: str) -> Any:
    """:func:`load_json` of a string; `where` starts every message."""
    try:
        return json.loads(text, object_pairs_hook=_no_repeats)
    except json.JSONDecodeError as exc:
        raise ValueError(f"{where}: not valid JSON (line {exc.lineno}: {exc.msg})") from None
    except RecursionError:
        raise ValueError(f"{where}: JSON nested too deeply to read (thousands of levels); a result, prior or "
                         "bounds file needs three") from None
    except ValueError as exc:  # from _no_repeats
        raise ValueError(f"{where}: {exc}") from None


# ----------------------------------------------------------------------------- the schema (pydantic)
Number = float  # strict mode: int or float, never bool or str


def _listify(v: Any) -> Any:
    """MATLAB's jsonencode writes a one-element array as a bare value."""
    return v if isinstance(v, list) or v is None else [v]


class _Coefficient(BaseModel):
    """One entry of the documented form's ``coefficients`` list."""

    model_config = ConfigDict(strict=True, extra="allow")
    name: str
    unit: str
    estimate: Number | None
    std: Number | None
    reason: str | None = None


class _ResultFile(BaseModel):
    """Every key a result file may hold, with its type; the two forms' checks come after."""

    model_config = ConfigDict(strict=True, extra="allow", protected_namespaces=())
    model: str | None = None
    model_file: str | None = None
    model_sha256: str | None = Field(default=None, pattern="^[0-9a-f]{64}$")  # hex SHA-256 of the model file
    coefficients: list[_Coefficient] | None = None
    names: list[str] | None = None
    units: list[str] | None = None
    estimates: list[Number | None] | None = None
    std: list[Number | None] | None = None
    covariance: list[list[Number | None]] | None = None
    si_factors: list[Number | None] | None = None
    method: str | None = None
    sigma: Number | None = None
    sigma_source: str | None = None
    std_kind: str | None = None
    rank: int | None = None
    status: int | None = None
    success: bool | None = None
    message: str | None = None
    n_samples: int | None = None
    settings: dict[str, Any] | None = None
    diagnostics: dict[str, Any] | None = None
    denoise: dict[str, Any] | None = None
    extras: dict[str, Any] | None = None
    residual_rms: dict[str, Number | None] | None = None

    @field_validator("names", "units", "estimates", "std", "si_factors", mode="before")
    @classmethod
    def _one_element(cls, v: Any) -> Any:
        return _listify(v)

    @field_validator("covariance", mode="before")
    @classmethod
    def _scalar_covariance(cls, v: Any) -> Any:
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            return [[v]]  # MATLAB: a 1 x 1 matrix is a number
        if isinstance(v, list) and v and all(isinstance(x, (int, float)) and not isinstance(x, bool) or x is None
                                             for x in v):
            return [[x] for x in v] if len(v) == 1 else v  # [c] for a 1 x 1; else the shape check names it
        return v


def _field(loc: tuple) -> str:
    out = ""
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out


def _pydantic_message(exc: ValidationError, where: str) -> str:
    """The first error as one line: file, field, what is wrong, the value found."""
    e = exc.errors()[0]
    loc = tuple(p for p in e["loc"] if p not in ("list[nullable[float]]", "float", "int", "str"))
    name = _field(loc) or "(top level)"
    if e["type"] == "missing":
        return f"{where}: missing field `{name}`"
    value = e.get("input")
    shown = json.dumps(value)[:60] if isinstance(value, (str, int, float, bool, type(None))) else type(value).__name__
    return f"{where}: field `{name}`: {e['msg'].lower()}, got {shown}"


# ----------------------------------------------------------------------------- the parsed result
@dataclass(frozen=True)
class ResultData:
    """A result file's coefficients, read and checked (natural units, the file's order).

    ``estimate`` is NaN where the file has no value; ``std`` is None when the file gives none at
    all; ``covariance`` None when absent (NaN rows and columns for coefficients without estimate).
    ``fields`` holds the other keys, type-checked (``method``, ``sigma``, ``settings``, ...).
    """

    source: str
    form: Literal["coefficients", "arrays", "both"]
    names: tuple[str, ...]
    units: tuple[str, ...]
    estimate: np.ndarray
    std: np.ndarray | None
    covariance: np.ndarray | None
    reasons: dict[str, str] = field(default_factory=dict)
    fields: dict[str, Any] = field(default_factory=dict)

    @property
    def model(self) -> str:
        return self.fields.get("model") or ""


#: Keys that make a JSON object a result file rather than a prior mapping (keyed by coefficient name).
RESULT_KEYS = ("coefficients", "names", "estimates", "covariance", "model")


def looks_like_result(data: Any) -> bool:
    """True for a JSON object in one of the result forms (as opposed to a prior mapping)."""
    return isinstance(data, dict) and any(k in data for k in RESULT_KEYS)


def _array(values: list) -> np.ndarray:
    return np.array([np.nan if v is None else float(v) for v in values], dtype=float)


def _close(a: float, b: float, rtol: float) -> bool:
    if math.isnan(a) or math.isnan(b):
        return math.isnan(a) and math.isnan(b)
    return abs(a - b) <= rtol * max(abs(a), abs(b)) or a == b


def read_result_data(path: str | os.PathLike, option: str = "result") -> ResultData:
    """Read and check a result file (see the module notes); ValueError naming `option`, file and field."""
    return parse_result_data(load_json(path, option), f"{option} {os.fspath(path)}")


def parse_result_data(data: Any, where: str = "result") -> ResultData:
    """Check a decoded result JSON object (see the module notes); `where` starts every message."""
    if not isinstance(data, dict):
        raise ValueError(f"{where}: must hold a JSON object (a result: `coefficients` list or `names`/`units`/"
                         f"`estimates`/`std` arrays), got a JSON {type(data).__name__}")
    if not any(k in data for k in ("coefficients", "names", "estimates")):
        raise ValueError(f"{where}: not a result: missing field `coefficients` (a list of {{name, unit, estimate, "
                         "std}}), or the arrays `names`, `units`, `estimates`, `std`; see docs/guide/result-files.md")
    try:
        f = _ResultFile.model_validate(data)
    except ValidationError as exc:
        raise ValueError(_pydantic_message(exc, where)) from None
    flat = [k for k in ("names", "units", "estimates", "std") if getattr(f, k) is not None]
    form: Literal["coefficients", "arrays", "both"]
    names: tuple[str, ...]
    units: tuple[str, ...]
    if f.coefficients is not None:
        rows = f.coefficients
        names = tuple(r.name for r in rows)
        units = tuple(r.unit for r in rows)
        est = _array([r.estimate for r in rows])
        std = _array([r.std for r in rows])
        reasons = {r.name: r.reason for r in rows if r.reason}
        form = "both" if flat else "coefficients"
        if flat:
            _check_forms_agree(f, names, units, est, std, where)
    else:
        for k in ("names", "units", "estimates", "std"):
            if getattr(f, k) is None:
                what = f"field `{k}` is null" if k in data else f"missing field `{k}`"
                raise ValueError(f"{where}: {what} (the flat-array form needs names, units, estimates and std "
                                 "as lists, null entries for no value; or give a `coefficients` list)")
        assert f.names is not None and f.units is not None and f.estimates is not None and f.std is not None
        names, units = tuple(f.names), tuple(f.units)
        est, std = _array(f.estimates), _array(f.std)
        for k, size in (("units", len(units)), ("estimates", est.size), ("std", std.size)):
            if size != len(names):
                raise ValueError(f"{where}: field `{k}` has {size} entries for {len(names)} names")
        reasons = {}
        form = "arrays"
    if not names:
        raise ValueError(f"{where}: no coefficients")
    field_name = "coefficients" if f.coefficients is not None else "names"
    seen: dict[str, int] = {}
    for i, n in enumerate(names):
        if n in seen:
            raise ValueError(f"{where}: field `{field_name}`: coefficient `{n}` appears twice (entries {seen[n]} "
                             f"and {i})")
        seen[n] = i
    _check_values(names, est, std, where, f.coefficients is not None)
    std_out = None if np.all(np.isnan(std)) else std  # no std at all (a method that defines none)
    cov = None
    if f.covariance is not None:
        cov = check_covariance(f.covariance, names, est, std, where)
    fields = f.model_dump(exclude={"coefficients", "names", "units", "estimates", "std", "covariance"})
    return ResultData(source=where, form=form, names=names, units=units, estimate=est, std=std_out, covariance=cov,
                      reasons=reasons, fields=fields)


def _check_forms_agree(f: _ResultFile, names, units, est, std, where: str) -> None:
    """Both forms in one file: the flat arrays must say what the `coefficients` list says."""
    n = len(names)
    for k in ("names", "units", "estimates", "std"):
        v = getattr(f, k)
        if v is not None and len(v) != n:
            raise ValueError(f"{where}: the two forms disagree: `{k}` has {len(v)} entries, `coefficients` {n}")
    fl_names = f.names or names
    for i in range(n):
        if fl_names[i] != names[i]:
            raise ValueError(f"{where}: the two forms disagree at entry {i}: `coefficients[{i}].name` is "
                             f"`{names[i]}`, `names[{i}]` is `{fl_names[i]}`; edit both, or delete the flat arrays")
        checks: list[tuple[str, str, Any, Any, Callable[[Any, Any], bool]]] = []
        if f.units is not None:
            checks.append(("unit", "units", units[i], f.units[i], lambda a, b: a == b))
        if f.estimates is not None:
            checks.append(("estimate", "estimates", est[i], np.nan if f.estimates[i] is None else f.estimates[i],
                           lambda a, b: _close(float(a), float(b), FORMS_RTOL)))
        if f.std is not None:
            checks.append(("std", "std", std[i], np.nan if f.std[i] is None else f.std[i],
                           lambda a, b: _close(float(a), float(b), FORMS_RTOL)))
        for what, key, a, b, same in checks:
            if not same(a, b):
                raise ValueError(f"{where}: the two forms disagree on `{names[i]}`: `coefficients[{i}].{what}` is "
                                 f"{_show(a)}, `{key}[{i}]` is {_show(b)}; edit both, or delete the flat arrays "
                                 "(names, units, estimates, std)")


def _show(v: Any) -> str:
    if isinstance(v, str):
        return f"`{v}`"
    return "null" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{float(v):.17g}"


def _check_values(names, est, std, where: str, listed: bool) -> None:
    def fld(i: int, what: str) -> str:
        return f"coefficients[{i}].{what}" if listed else f"{'estimates' if what == 'estimate' else what}[{i}]"

    for i, n in enumerate(names):
        for what, v in (("estimate", est[i]), ("std", std[i])):
            if math.isinf(v):
                raise ValueError(f"{where}: field `{fld(i, what)}` ({n}) is {v}: give a finite number, or null "
                                 "for no value")
            if abs(v) > MAX_RESULT_VALUE:
                raise ValueError(f"{where}: field `{fld(i, what)}` ({n}) is {v:g}, beyond the magnitude limit "
                                 f"{MAX_RESULT_VALUE:g} (natural units): a unit or typing mistake?")
        if std[i] < 0:
            raise ValueError(f"{where}: field `{fld(i, 'std')}` ({n}) is {std[i]:g}: a std must be >= 0")


def check_covariance(cov: Any, names, est: np.ndarray, std: np.ndarray | None, where: str) -> np.ndarray:
    """The covariance as an (n, n) array, checked; NaN rows/columns for coefficients without estimate.

    Checks, each a ValueError naming `where`, the field and the coefficient(s): shape n x n; entries
    finite, null only on a row or column of a coefficient without estimate, within
    ``MAX_RESULT_VALUE**2``; diagonal >= 0; symmetric (``SYMMETRY_RTOL``); positive semi-definite (the
    correlation matrix's smallest eigenvalue >= ``-PSD_TOL``); ``std`` equal to ``sqrt(diag)``
    (``STD_RTOL``).
    """
    n = len(names)
    rows = cov if isinstance(cov, list) else None
    if rows is None or len(rows) != n or any(not isinstance(r, list) or len(r) != n for r in rows):
        shape = (f"{len(rows)} rows of {sorted({len(r) for r in rows if isinstance(r, list)})} entries"
                 if isinstance(rows, list) else type(cov).__name__)
        raise ValueError(f"{where}: field `covariance` must be {n} x {n} (one row per coefficient, model order), "
                         f"got {shape}")
    C = np.array([[np.nan if v is None else float(v) for v in r] for r in rows], dtype=float)
    # Rows and columns that must be numbers: coefficients with an estimate and a std (a bounded
    # result's coefficient at a bound, or fixed, has an estimate but no std, and no covariance row).
    have = np.isfinite(est)
    if std is not None and np.any(np.isfinite(std)):
        have &= np.isfinite(std)
    for i in range(n):
        for j in range(n):
            v = C[i, j]
            if np.isnan(v):
                if have[i] and have[j]:
                    raise ValueError(f"{where}: field `covariance[{i}][{j}]` ({names[i]}, {names[j]}) is null or "
                                     "NaN, but both coefficients have an estimate and a std")
            elif not math.isfinite(v) or abs(v) > MAX_RESULT_VALUE**2:
                raise ValueError(f"{where}: field `covariance[{i}][{j}]` ({names[i]}, {names[j]}) is {v:g}: give a "
                                 f"finite number within {MAX_RESULT_VALUE**2:g}")
    k = [int(v) for v in np.flatnonzero(have)]
    Ck = C[np.ix_(k, k)]
    d = np.diag(Ck)
    for a, j in enumerate(k):
        if d[a] < 0:
            raise ValueError(f"{where}: field `covariance[{j}][{j}]` ({names[j]}) is {d[a]:g}: a variance must be "
                             ">= 0")
    s = np.sqrt(d)
    tol = SYMMETRY_RTOL * np.outer(s, s)
    asym = np.abs(Ck - Ck.T) - tol
    if asym.size and asym.max() > 0:
        a, b = (int(v) for v in np.unravel_index(int(np.argmax(asym)), asym.shape))
        i, j = k[a], k[b]
        raise ValueError(f"{where}: field `covariance` is not symmetric: [{i}][{j}] ({names[i]}, {names[j]}) is "
                         f"{C[i, j]:.6g}, [{j}][{i}] is {C[j, i]:.6g}")
    if std is not None:
        for a, j in enumerate(k):
            if not np.isnan(std[j]) and not _close(float(std[j]), float(s[a]), STD_RTOL):
                raise ValueError(f"{where}: `{names[j]}`: std {std[j]:.6g} but sqrt(covariance[{j}][{j}]) = "
                                 f"{s[a]:.6g}: the std and the covariance disagree (relative tolerance {STD_RTOL:g})")
    pos = s > 0
    if pos.sum() >= 2:
        sp = s[pos]
        rho = Ck[np.ix_(pos, pos)] / np.outer(sp, sp)
        w, V = np.linalg.eigh(0.5 * (rho + rho.T))
        if w[0] < -PSD_TOL:
            lead = np.argsort(-np.abs(V[:, 0]))[:3]
            who = ", ".join(names[k[np.flatnonzero(pos)[t]]] for t in lead)
            raise ValueError(f"{where}: field `covariance` is not positive semi-definite: its correlation matrix has "
                             f"eigenvalue {w[0]:.3g} (direction mostly {who}); a covariance matrix cannot")
    return 0.5 * (C + C.T)


def require_invertible(cov: np.ndarray, names, where: str) -> np.ndarray:
    """The Cholesky factor of the correlation matrix of `cov` (estimated coefficients only): for
    users that need its inverse (the fuse); ValueError naming the file when it is singular."""
    d = np.diag(cov)
    zero = [names[j] for j in range(len(names)) if d[j] == 0]
    if zero:
        raise ValueError(f"{where}: field `covariance` is singular: zero variance for {', '.join(zero[:5])} "
                         "(a fixed coefficient carries no information to combine)")
    s = np.sqrt(d)
    rho = cov / np.outer(s, s)
    try:
        return np.linalg.cholesky(rho)
    except np.linalg.LinAlgError:
        w, V = np.linalg.eigh(rho)
        lead = np.argsort(-np.abs(V[:, 0]))[:3]
        raise ValueError(f"{where}: field `covariance` is singular (smallest eigenvalue of its correlation matrix "
                         f"{w[0]:.3g}; direction mostly {', '.join(names[t] for t in lead)}): its inverse, the "
                         "information, does not exist") from None

"""imucal's calibration JSON (``FerrarisCalibrationInfo``, format 2.0): export and import.

imucal's model (``imucal/ferraris_calibration_info.py``): a raw accelerometer reading
``u_a = K_a R_a a + b_a`` and gyro reading ``u_g = K_g R_g w + K_ga a + b_g``, with a the
calibrated acceleration in m/s^2 and w the rate in deg/s; ``K`` diagonal (scale), ``R`` with
unit-norm rows (misalignment), so ``M = K R`` is any 3 x 3 matrix: ``K = diag(|row_i(M)|)``,
``R = K^-1 M``. casep's ``ferraris`` model estimates ``M_a, b_a, M_g, K_ga, b_g`` directly
(linear in them); this module converts. The JSON holds ``acc_unit, gyr_unit, from_acc_unit,
from_gyr_unit, comment, K_a, R_a, b_a, K_g, R_g, K_ga, b_g, cal_type, _format_version`` and
nothing else (imucal's loader passes every key to its dataclass), so casep's std stay in the casep
result JSON; the comment says so.
"""

from __future__ import annotations

import os
from typing import Any, Mapping

import numpy as np

__all__ = ["to_imucal", "from_imucal", "read_imucal", "write_imucal", "imucal_prior", "stated_prior", "IMUCAL_KEYS"]

IMUCAL_KEYS = ("K_a", "R_a", "b_a", "K_g", "R_g", "K_ga", "b_g")
_AX = "xyz"


def _matrix(values: Mapping[str, float], prefix: str) -> np.ndarray:
    return np.array([[values[f"{prefix}_{i}{j}"] for j in _AX] for i in _AX], dtype=float)


def _kr(M: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``M = K R``: K diagonal with the row norms, R with unit-norm rows."""
    k = np.linalg.norm(M, axis=1)
    return np.diag(k), M / k[:, None]


def to_imucal(calibration, *, comment: str | None = None) -> dict:
    """imucal's calibration JSON (dict) of a ``ferraris`` calibration.

    Parameters
    ----------
    calibration : Calibration or EstimateResult
        Of a model with imucal's parameters (``Ma_ij, ba_i, Mg_ij, Kga_ij, bg_i``).
    """
    from casep._version import __version__

    res = getattr(calibration, "result", calibration)
    values = {n: float(v) for n, v in zip(res.names, res.estimate)}
    need = ([f"Ma_{i}{j}" for i in _AX for j in _AX] + [f"ba_{i}" for i in _AX]
            + [f"Mg_{i}{j}" for i in _AX for j in _AX] + [f"Kga_{i}{j}" for i in _AX for j in _AX]
            + [f"bg_{i}" for i in _AX])
    missing = [n for n in need if n not in values or not np.isfinite(values[n])]
    if missing:
        raise ValueError(f"model `{res.model}` has no imucal form: Missing (or not estimated): {', '.join(missing)}. "
                         "Use: --model ferraris")
    K_a, R_a = _kr(_matrix(values, "Ma"))
    K_g, R_g = _kr(_matrix(values, "Mg"))
    settings = getattr(calibration, "settings", {}) or {}
    return {
        "acc_unit": "m/s^2", "gyr_unit": "deg/s",
        "from_acc_unit": settings.get("acc_unit", "a.u."), "from_gyr_unit": settings.get("gyr_unit", "a.u."),
        "comment": comment if comment is not None else
        f"casep {__version__} calibrate, model {res.model}, method {res.method}; std and covariance in the casep "
        "result JSON",
        "K_a": K_a.tolist(), "R_a": R_a.tolist(), "b_a": [values[f"ba_{i}"] for i in _AX],
        "K_g": K_g.tolist(), "R_g": R_g.tolist(), "K_ga": _matrix(values, "Kga").tolist(),
        "b_g": [values[f"bg_{i}"] for i in _AX], "cal_type": "Ferraris", "_format_version": "2.0",
    }


def write_imucal(calibration, path: str | os.PathLike, **kw) -> None:
    """Write :func:`to_imucal` atomically (imucal reads it with ``CalibrationInfo.from_json_file``)."""
    from casep.io.result_files import write_json_atomic

    write_json_atomic(to_imucal(calibration, **kw), path)


def read_imucal(source: str | os.PathLike | Mapping) -> dict:
    """An imucal calibration JSON (file or dict), checked: its seven matrices as arrays, and the units."""
    if isinstance(source, Mapping):
        d, where = dict(source), "imucal calibration"
    else:
        from casep.io.result_json import load_json

        where = f"imucal calibration {source}"
        d = load_json(source, "imucal calibration")
    if not isinstance(d, dict) or d.get("cal_type") not in ("Ferraris", "Turntable"):
        raise ValueError(f"{where}: not an imucal Ferraris/Turntable calibration (cal_type {d.get('cal_type')!r})")
    out: dict[str, Any] = {}
    for k in IMUCAL_KEYS:
        try:
            a = np.asarray(d[k], dtype=float)
        except (KeyError, TypeError, ValueError):
            raise ValueError(f"{where}: Missing or non-numeric `{k}`") from None
        want = (3,) if k.startswith("b_") else (3, 3)
        if a.shape != want or not np.all(np.isfinite(a)):
            raise ValueError(f"{where}: `{k}` must be {' x '.join(map(str, want))} finite numbers, got shape {a.shape}")
        out[k] = a
    if d.get("acc_unit", "m/s^2") != "m/s^2" or d.get("gyr_unit", "deg/s") != "deg/s":
        raise ValueError(f"{where}: calibrates to {d.get('acc_unit')} and {d.get('gyr_unit')}; casep's ferraris model "
                         "is per m/s^2 and deg/s")
    out["from_acc_unit"], out["from_gyr_unit"] = d.get("from_acc_unit"), d.get("from_gyr_unit")
    return out


def from_imucal(source) -> dict[str, float]:
    """The ``ferraris`` model's coefficients (name -> value, natural units) of an imucal calibration."""
    d = read_imucal(source)
    Ma, Mg = d["K_a"] @ d["R_a"], d["K_g"] @ d["R_g"]
    out = {}
    for i, a in enumerate(_AX):
        for j, b in enumerate(_AX):
            out[f"Ma_{a}{b}"] = float(Ma[i, j])
    out.update({f"ba_{a}": float(d["b_a"][i]) for i, a in enumerate(_AX)})
    for i, a in enumerate(_AX):
        for j, b in enumerate(_AX):
            out[f"Mg_{a}{b}"] = float(Mg[i, j])
    for i, a in enumerate(_AX):
        for j, b in enumerate(_AX):
            out[f"Kga_{a}{b}"] = float(d["K_ga"][i, j])
    out.update({f"bg_{a}": float(d["b_g"][i]) for i, a in enumerate(_AX)})
    return out


def imucal_prior(source, std: Mapping[str, float] | float) -> dict:
    """An imucal calibration as a Gaussian prior of the ``ferraris`` model.

    imucal states no uncertainty, so the std is the caller's: a mapping name -> std (natural
    units; every coefficient) or one number, a relative std (``0.01``: 1 % of each value's size,
    with the size of a matrix's largest entry for its small off-diagonal ones).

    Returns
    -------
    dict
        ``{name: {"mean", "std"}}`` for ``method="map"`` (``options={"prior": ...}``).
    """
    return stated_prior(from_imucal(source), std, "imucal prior")


def stated_prior(values: Mapping[str, float], std: Mapping[str, float] | float, what: str) -> dict:
    """``{name: {"mean", "std"}}`` of `values` (ferraris names) with the caller's std: a mapping
    name -> std, or one relative std (of each value's size, with the size of a matrix's largest
    entry for its small off-diagonal ones: the group of a name is its prefix, ``Ma``, ``bg``, ...)."""
    if isinstance(std, Mapping):
        missing = [n for n in values if n not in std]
        if missing:
            raise ValueError(f"{what}: Missing std for {', '.join(missing)}")
        return {n: {"mean": v, "std": float(std[n])} for n, v in values.items()}
    rel = float(std)
    if not (np.isfinite(rel) and rel > 0):
        raise ValueError(f"{what}: the relative std must be finite and > 0, got {std}")
    size: dict[str, float] = {}
    for n, v in values.items():
        size[n.split("_")[0]] = max(size.get(n.split("_")[0], 0.0), abs(v))
    return {n: {"mean": v, "std": rel * size[n.split("_")[0]]} for n, v in values.items()}

"""imu_tk's calibration files (``PREFIX_acc.calib``, ``PREFIX_gyro.calib``): write and read.

imu_tk (``CalibratedTriad_::save``/``load``) stores a triad's calibration as whitespace-separated
text: the misalignment matrix T (3 rows of 3), a blank line, the scale matrix K (3 x 3, diagonal),
a blank line, the bias B (3 rows of 1); the calibrated reading is ``T K (raw - B)``. casep's
``multiposition`` model is this convention (:mod:`casep.calibration.multiposition`), so the export
is exact; a file read back gives T, K, B.

As a prior of casep's ``ferraris`` model (``casep calibrate --prior PREFIX_acc.calib --prior-rel-std R``,
as an imucal JSON): ``M_a = (T_a K_a)^-1`` (``Ma_ij``, reading unit per m/s^2), ``ba_i = B_a``, and
from ``PREFIX_gyro.calib`` when it exists ``M_g = (T_g K_g)^-1 pi/180`` (``Mg_ij``, reading unit per
deg/s), ``bg_i = B_g``; imu_tk has no g-sensitivity (``Kga``: no prior). The session must be read in
the unit imu_tk calibrated (raw counts, or what the files' scales are per).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

__all__ = ["imu_tk_files", "write_imu_tk", "read_imu_tk", "format_imu_tk", "from_imu_tk", "imu_tk_prior"]


def imu_tk_files(prefix: str | os.PathLike) -> tuple[str, str]:
    """``PREFIX_acc.calib``, ``PREFIX_gyro.calib``."""
    return f"{prefix}_acc.calib", f"{prefix}_gyro.calib"


def format_imu_tk(T: np.ndarray, K: np.ndarray, B: np.ndarray) -> str:
    """The text of one triad's file (17 significant digits: the values round-trip exactly)."""
    rows = lambda M: "\n".join(" ".join(f"{v:.17g}" for v in r) for r in np.atleast_2d(M))  # noqa: E731
    return f"{rows(T)}\n\n{rows(K)}\n\n{rows(np.reshape(B, (3, 1)))}\n"


def write_imu_tk(cal, prefix: str | os.PathLike) -> tuple[str, str]:
    """Write a :class:`casep.calibration.handturned.MultipositionCalibration` as imu_tk's two files.

    The biases are in the session's reading unit and the scales in SI per reading unit, as imu_tk
    (which calibrates raw readings).
    """
    from casep.calibration.multiposition import acc_matrix, gyro_matrix

    out = imu_tk_files(prefix)
    for path, TK, k, b in ((out[0], acc_matrix(cal.acc.x), cal.acc.x[3:6], cal.acc.x[6:9]),
                           (out[1], gyro_matrix(cal.gyro.x), cal.gyro.x[6:9], cal.gyro.bias)):
        Path(path).write_text(format_imu_tk(TK / k[None, :], np.diag(k), b))
    return out


def read_imu_tk(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(T, K, B) of an imu_tk calibration file.

    Raises
    ------
    ValueError
        Naming the file and what is wrong (not 3 + 3 rows of 3 numbers and 3 of 1; a T whose
        diagonal is not 1, a K not diagonal).
    """
    try:
        text = Path(path).read_text()
    except OSError as exc:
        raise ValueError(f"imu_tk file {path}: cannot be read ({exc})") from None
    rows = [ln.split() for ln in text.splitlines() if ln.strip()]
    try:
        vals = [[float(v) for v in r] for r in rows]
    except ValueError:
        raise ValueError(f"imu_tk file {path}: not numbers") from None
    if len(vals) != 9 or any(len(r) != 3 for r in vals[:6]) or any(len(r) != 1 for r in vals[6:]):
        raise ValueError(f"imu_tk file {path}: expected T (3 rows of 3), K (3 rows of 3), B (3 rows of 1); "
                         f"got rows of {[len(r) for r in vals]}")
    T, K, B = np.array(vals[:3]), np.array(vals[3:6]), np.array(vals[6:]).ravel()
    if not np.allclose(np.diag(T), 1.0, rtol=0, atol=1e-12) or np.any(K[~np.eye(3, dtype=bool)] != 0):
        raise ValueError(f"imu_tk file {path}: T must have a unit diagonal and K be diagonal")
    return T, K, B


def from_imu_tk(acc_path: str | os.PathLike, gyro_path: str | os.PathLike | None = None) -> dict[str, float]:
    """The ``ferraris`` model's coefficients (name -> value, natural units) of imu_tk's files (module notes)."""
    import math

    out: dict[str, float] = {}
    for path, Mname, bname, unit in ((acc_path, "Ma", "ba", 1.0), (gyro_path, "Mg", "bg", math.pi / 180.0)):
        if path is None:
            continue
        T, K, B = read_imu_tk(path)
        M = np.linalg.inv(T @ K) * unit  # reading per m/s^2; per rad/s times pi/180 = per deg/s
        for i, a in enumerate("xyz"):
            for j, b in enumerate("xyz"):
                out[f"{Mname}_{a}{b}"] = float(M[i, j])
        out.update({f"{bname}_{a}": float(B[i]) for i, a in enumerate("xyz")})
    return out


def imu_tk_prior(acc_path: str | os.PathLike, std, gyro_path: str | os.PathLike | None = None) -> dict:
    """imu_tk's files as a Gaussian prior of the ``ferraris`` model: ``{name: {"mean", "std"}}``.

    `std`: a mapping name -> std or one relative std (:func:`casep.calibration.imucal.stated_prior`:
    imu_tk states no uncertainty). `gyro_path` defaults to ``PREFIX_gyro.calib`` beside
    ``PREFIX_acc.calib`` when it exists.
    """
    from casep.calibration.imucal import stated_prior

    p = str(acc_path)
    if gyro_path is None and p.endswith("_acc.calib") and Path(p[:-len("_acc.calib")] + "_gyro.calib").is_file():
        gyro_path = p[:-len("_acc.calib")] + "_gyro.calib"
    return stated_prior(from_imu_tk(acc_path, gyro_path), std, f"imu_tk prior {acc_path}")

"""Raw IMU files: body rates and specific forces, or angle and velocity increments, checked at the edge.

Two layouts (CSV or Parquet, one row per sample, body axes):

- **rates**: ``t`` (s), ``w_x, w_y, w_z`` (body rate, rad/s), ``fb_x, fb_y, fb_z`` (body specific
  force, m/s^2), each sampled at ``t``;
- **increments**: ``t`` (s), ``dth_x, dth_y, dth_z`` (angle increment, rad: the integral of the
  body rate), ``dvb_x, dvb_y, dvb_z`` (velocity increment, m/s: the integral of the body specific
  force), each over the sample period that ends at ``t``.

Checks: a missing column, a bad cell or time that does not increase is an error naming the file,
column and row (:class:`casep.io.tables.Table`). Lost samples (a step over 1.5 times the median) are
integrated across, with a :class:`~casep.exceptions.GapWarning` giving their count and the longest
gap; an increment after a gap covers one nominal period and stands for the whole step (the rate
held over the lost samples). Rates beyond any gyro's full scale (200 rad/s) are an error (deg/s
declared rad/s), rates over 35 rad/s (2000 deg/s) or specific forces over 50 g a
:class:`~casep.exceptions.PlausibilityWarning`, with the numbers.
"""

from __future__ import annotations

import math
import os
import warnings
from dataclasses import dataclass

import numpy as np

from casep.exceptions import GapWarning, PlausibilityWarning

__all__ = ["ImuData", "read_imu", "check_imu", "RATE_COLUMNS", "FORCE_COLUMNS", "DTHETA_COLUMNS", "DV_COLUMNS",
           "GAP_FACTOR", "sample_periods", "with_rates"]

RATE_COLUMNS = ("w_x", "w_y", "w_z")
FORCE_COLUMNS = ("fb_x", "fb_y", "fb_z")
DTHETA_COLUMNS = ("dth_x", "dth_y", "dth_z")
DV_COLUMNS = ("dvb_x", "dvb_y", "dvb_z")
#: A step longer than this many median steps has lost samples.
GAP_FACTOR = 1.5
#: Rates beyond this are refused (no gyro's full scale reaches it: deg/s declared rad/s), rad/s.
MAX_RATE = 200.0
#: Rates beyond this (2000 deg/s, the largest common full scale) and specific forces beyond 50 g are warned about.
WARN_RATE = 35.0
WARN_FORCE = 50 * 9.80665


@dataclass
class ImuData:
    """IMU samples in SI units, body axes.

    Attributes
    ----------
    t : (N,) ndarray
        Times, s, increasing.
    w, f : (N, 3) ndarray
        Body rate (rad/s) and specific force (m/s^2): measured (rates) or the increments over their
        sample period divided by it (increments).
    kind : str
        ``"rates"`` or ``"increments"``.
    dtheta, dv : (N, 3) ndarray or None
        Increments: each row over the period ending at ``t`` (after a gap: scaled to the whole step).
    source : str
        The file, for messages.
    gaps : int
        Steps with lost samples.
    """

    t: np.ndarray
    w: np.ndarray
    f: np.ndarray
    kind: str = "rates"
    dtheta: np.ndarray | None = None
    dv: np.ndarray | None = None
    source: str = "<memory>"
    gaps: int = 0


def read_imu(path: str | os.PathLike) -> ImuData:
    """Read and check an IMU file (layout by its columns: rates, else increments); see the module docstring."""
    from casep.io.tables import Table

    tab = Table(path)
    if tab.has(("t",) + DTHETA_COLUMNS + DV_COLUMNS) and not tab.has(RATE_COLUMNS):
        tab.require(("t",) + DTHETA_COLUMNS + DV_COLUMNS)
        t = tab.time()
        return check_imu(ImuData(t, np.zeros((len(t), 3)), np.zeros((len(t), 3)), "increments",
                                 tab.vectors(DTHETA_COLUMNS), tab.vectors(DV_COLUMNS), tab.src))
    tab.require(("t",) + RATE_COLUMNS + FORCE_COLUMNS,
                "; an IMU file holds t, w_x..w_z (rad/s), fb_x..fb_z (m/s^2), or t, dth_x..dth_z (rad), "
                "dvb_x..dvb_z (m/s)")
    t = tab.time()
    return check_imu(ImuData(t, tab.vectors(RATE_COLUMNS), tab.vectors(FORCE_COLUMNS), "rates", source=tab.src))


def check_imu(imu: ImuData) -> ImuData:
    """Check an IMU record (gaps, units) and, for increments, fill ``w``, ``f``; returns it.

    Raises
    ------
    ValueError
        Fewer than 3 samples, time not increasing, or a rate beyond :data:`MAX_RATE`.
    """
    t = np.asarray(imu.t, float)
    if t.ndim != 1 or len(t) < 3:
        raise ValueError(f"{imu.source}: an IMU record needs at least 3 samples, got {t.size}")
    h = np.diff(t)
    if np.any(h <= 0):
        k = int(np.flatnonzero(h <= 0)[0]) + 1
        raise ValueError(f"{imu.source}: column t, row {k + 1}: time {t[k]:.10g} s does not increase")
    h_med = float(np.median(h))
    lost = np.flatnonzero(h > GAP_FACTOR * h_med)
    if imu.kind == "increments":
        cover = np.concatenate([[h_med], np.where(h > GAP_FACTOR * h_med, h_med, h)])  # what each row integrates
        scale = np.concatenate([[1.0], h])[:, None] / cover[:, None]
        scale[0] = 1.0
        imu.dtheta = np.asarray(imu.dtheta, float) * scale  # after a gap: the rate held over the whole step
        imu.dv = np.asarray(imu.dv, float) * scale
        step = sample_periods(t)[:, None]
        imu.w, imu.f = imu.dtheta / step, imu.dv / step
    if lost.size:
        k = int(lost[np.argmax(h[lost])])
        missing = int(np.sum(np.round(h[lost] / h_med) - 1))
        gaps = f"{lost.size} gap{'s' if lost.size > 1 else ''}"
        warnings.warn(f"{imu.source}: {gaps} in t (about {missing} samples lost at the median step "
                      f"{h_med:.4g} s); the longest {h[k]:.4g} s after t = {t[k]:.10g} s (row {k + 1}): "
                      "integrated across it, the rate and specific force taken linear (rates) or held (increments)",
                      GapWarning, stacklevel=2)
    imu.gaps = int(lost.size)
    _check_units(imu)
    return imu


def sample_periods(t: np.ndarray) -> np.ndarray:
    """The period each increment row is divided by to give a rate, s: the step ending at its time (the
    median step for the first row)."""
    h = np.diff(t)
    return np.concatenate([[float(np.median(h))], h])


def with_rates(imu: ImuData, w: np.ndarray, f: np.ndarray) -> ImuData:
    """A copy of `imu` with body rate `w` (rad/s) and specific force `f` (m/s^2) in place of its own; increments
    become them times :func:`sample_periods` (the inverse of :func:`check_imu`'s division)."""
    import dataclasses

    out = dataclasses.replace(imu, w=np.asarray(w, float), f=np.asarray(f, float))
    if imu.kind == "increments":
        step = sample_periods(imu.t)[:, None]
        out.dtheta, out.dv = out.w * step, out.f * step
    return out


def _check_units(imu: ImuData) -> None:
    """Rates beyond any full scale: error; beyond 2000 deg/s or forces beyond 50 g: warning; with the numbers."""
    wn = np.linalg.norm(imu.w, axis=1)
    k = int(np.argmax(wn))
    cols = "dth_*" if imu.kind == "increments" else "w_*"
    if wn[k] > MAX_RATE:
        raise ValueError(f"{imu.source}: columns {cols}, row {k + 1}: body rate {wn[k]:.4g} rad/s "
                         f"({math.degrees(wn[k]):.4g} deg/s) is beyond any gyro's full scale: the rates look like "
                         "deg/s (give rad/s)")
    if wn[k] > WARN_RATE:
        warnings.warn(f"{imu.source}: columns {cols}, row {k + 1}: body rate {wn[k]:.4g} rad/s "
                      f"({math.degrees(wn[k]):.4g} deg/s), beyond the 2000 deg/s of common gyros: deg/s given as "
                      "rad/s?", PlausibilityWarning, stacklevel=3)
    fn = np.linalg.norm(imu.f, axis=1)
    k = int(np.argmax(fn))
    if fn[k] > WARN_FORCE:
        cols = "dvb_*" if imu.kind == "increments" else "fb_*"
        warnings.warn(f"{imu.source}: columns {cols}, row {k + 1}: specific force {fn[k]:.4g} m/s^2 "
                      f"({fn[k] / 9.80665:.3g} g) is beyond 50 g: units?", PlausibilityWarning, stacklevel=3)

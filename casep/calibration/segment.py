"""Automatic segmentation of a hand-turned session: static poses and the motions between them.

The detector of imu_tk (Tedaldi, Pretto and Menegatti, ICRA 2014): for every sample the variance
of each accelerometer axis over a centred window of ``w`` samples, and its magnitude

    v(t) = || (var a_x, var a_y, var a_z) ||_2      (reading unit^2)

A sample is static when ``v(t) <= k v_init``, ``v_init`` the mean of ``v`` over the initial static
period, and the gyro's window mean square about its initial bias, ``v_g(t)``, is at most ``k v_g,init``
(a turn about gravity leaves the accelerometers unchanged: imu_tk's detector calls it static, and its
rows then spoil the gyro bias; the MPU-9150 sessions have 20-deg turns of this kind). The initial
period is the first ``init_s`` seconds, which the session must begin with. A run of static samples
at least ``min_static_s`` long is a pose (untrimmed: the centred window sees a motion half a window
ahead, :func:`static_runs`); a shorter one is
rejected (and listed). The multiplier ``k`` is chosen from the session, as imu_tk does: for every
``k`` of a sweep, the poses found are calibrated (:func:`casep.calibration.multiposition.fit_accelerometer`,
the magnitude of gravity) and the ``k`` of the smallest RMS misfit per pose wins (a too small
``k`` splits poses and loses them, a too large one lets the ends of the motions into them).

Checks of the result (numbers in every message):

- fewer than ``min_poses`` poses (9 coefficients of the accelerometer model): :class:`SegmentError`;
- gravity directions that do not span the sphere: the smallest singular value of the ``n x 3``
  matrix of pose directions over ``sqrt(n)`` (1/sqrt(3) = 0.577 for directions spread evenly,
  0 for directions in a plane) below ``SPREAD_ERROR``: :class:`SegmentError`; below ``SPREAD_WARN``:
  :class:`PoseSpreadWarning`;
- motion inside a pose: the gyro turns by more than ``max_turn_deg`` (bias from the initial
  period removed): :class:`StaticMotionWarning`;
- an initial period that is not static (its window variance rises above ``INIT_RISE`` times its
  median): :class:`SegmentError`.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from casep._kernels import runs
from casep.calibration.session import SegmentError
from casep.exceptions import CasepWarning
from casep.results import Completed

__all__ = ["Segmentation", "detect_static", "window_variance", "window_mean", "PoseSpreadWarning",
           "StaticMotionWarning", "pose_spread", "pose_cone_deg", "warn_turns", "static_runs", "static_statistic",
           "detector",
           "MAX_TURN_DEG", "MULTIPLIERS", "SPREAD_ERROR", "SPREAD_WARN", "INIT_RISE", "MIN_POSES"]

#: imu_tk's sweep of threshold multipliers of the initial period's variance.
MULTIPLIERS = tuple(float(k) for k in range(2, 11))
#: Smallest singular value of the pose directions / sqrt(n): error below, warning below.
SPREAD_ERROR = 0.1
SPREAD_WARN = 0.25
#: The initial period is not static if its window variance rises above this many times its median.
INIT_RISE = 10.0
#: A pose in which the gyro turns by more than this (deg) is warned of.
MAX_TURN_DEG = 2.0
#: Poses needed by the 9-coefficient accelerometer model.
MIN_POSES = 9


class PoseSpreadWarning(CasepWarning):
    """The poses' gravity directions span the sphere poorly: some coefficients are barely separated."""


class StaticMotionWarning(CasepWarning):
    """The gyro turns inside an interval the accelerometers call static (e.g. a turn about gravity)."""


@dataclass(frozen=True)
class Segmentation(Completed):
    """What :func:`detect_static` found (row positions of the session, end excluded).

    Attributes
    ----------
    init : (int, int)
        The initial static period (also the first pose).
    poses : list of (int, int)
        Static intervals, time order (the first is the initial period's).
    threshold, multiplier, init_variance : float
        ``threshold = multiplier * init_variance`` (reading unit^2).
    gyro_threshold : float
        ``multiplier`` times the gyro's initial window mean square (reading unit^2).
    window : int
        Samples of the variance window.
    rejected : list of (int, int, str)
        Static runs not used, and why.
    sweep : list of (float, int, float)
        ``(multiplier, poses, RMS misfit per pose)`` of every multiplier tried (misfit NaN: too few poses).
    spread : float
        Smallest singular value of the pose directions over sqrt(n).
    turns_deg : list of float
        Angle the gyro turns inside each pose (initial-period bias removed), deg (empty for raw counts).
    rate : float
        Sample rate, Hz.
    statistic : (N,) ndarray or None
        The detector's statistic per sample in units of the initial period (static: at most
        `multiplier`), for the figure of the segmentation; not in :meth:`to_dict`.
    """

    what: ClassVar[str] = "segmentation of a calibration session into static poses and motions"

    init: tuple[int, int]
    poses: list
    threshold: float
    multiplier: float
    init_variance: float
    window: int
    rate: float
    rejected: list = field(default_factory=list)
    sweep: list = field(default_factory=list)
    spread: float = math.nan
    turns_deg: list = field(default_factory=list)
    gyro_threshold: float = math.nan
    statistic: np.ndarray | None = field(default=None, repr=False, compare=False)

    @property
    def motions(self) -> list[tuple[int, int]]:
        """The motion between consecutive poses: rows from the end of one to the start of the next."""
        return [(self.poses[i][1], self.poses[i + 1][0]) for i in range(len(self.poses) - 1)]

    def to_dict(self) -> dict:
        return {"init": list(self.init), "poses": [list(p) for p in self.poses], "threshold": self.threshold,
                "multiplier": self.multiplier, "init_variance": self.init_variance, "window": self.window,
                "rate_hz": self.rate, "rejected": [list(r) for r in self.rejected],
                "sweep": [[k, n, _finite(r)] for k, n, r in self.sweep], "spread": _finite(self.spread),
                "turns_deg": list(self.turns_deg), "gyro_threshold": _finite(self.gyro_threshold)}

    def text(self) -> str:
        """What was found: poses, their lengths, the threshold, the rejected intervals."""
        L = np.array([(b - a) / self.rate for a, b in self.poses])
        lines = [f"segmentation: {len(self.poses)} static poses (lengths {L.min():.3g}..{L.max():.3g} s, median "
                 f"{np.median(L):.3g} s), {len(self.motions)} motions; initial period rows {self.init[0]}-"
                 f"{self.init[1] - 1} ({(self.init[1] - self.init[0]) / self.rate:.3g} s)",
                 f"  threshold {self.threshold:.4g} (reading unit^2) = {self.multiplier:g} x the initial period's "
                 f"window variance {self.init_variance:.4g} (gyro: {self.gyro_threshold:.4g}, mean square about "
                 f"the initial bias); window {self.window} samples; "
                 f"direction spread {self.spread:.3f} (0.577: even, 0: a plane)"]
        if self.sweep:
            lines.append("  sweep (multiplier: poses, RMS misfit): " + "; ".join(
                f"{k:g}: {n}, {r:.3g}" for k, n, r in self.sweep))
        if self.rejected:
            lines.append(f"  rejected {len(self.rejected)}: " + "; ".join(
                f"rows {a}-{b - 1} ({why})" for a, b, why in self.rejected[:12])
                + (" ..." if len(self.rejected) > 12 else ""))
        return "\n".join(lines)


def _finite(v: float) -> float | None:
    """`v`, or None for NaN (JSON)."""
    return float(v) if math.isfinite(v) else None


def window_variance(x: np.ndarray, window: int) -> np.ndarray:
    """Per-axis variance of `x` (N, 3) over a centred window of `window` samples (shorter at the ends), (N, 3).

    ``var = E[x^2] - E[x]^2`` from cumulative sums of the centred data (the session mean removed
    first, so raw counts near 32768 lose no digits).
    """
    x = np.asarray(x, dtype=float) - np.mean(x, axis=0)
    m = window_mean(x, window)
    return np.maximum(window_mean(x * x, window) - m * m, 0.0)


def window_mean(x: np.ndarray, window: int) -> np.ndarray:
    """Mean of `x` (N, k) over a centred window of `window` samples (shorter at the ends), (N, k), by
    cumulative sums: rows ``[i - window // 2, i + window - window // 2)`` clipped to the data."""
    x = np.asarray(x, dtype=float)
    n = len(x)
    h = window // 2
    lo = np.clip(np.arange(n) - h, 0, n)
    hi = np.clip(np.arange(n) + window - h, 0, n)
    c = np.concatenate([np.zeros((1,) + x.shape[1:]), np.cumsum(x, axis=0)])
    return (c[hi] - c[lo]) / (hi - lo).reshape((-1,) + (1,) * (x.ndim - 1))


def static_runs(v: np.ndarray, threshold: float, init_end: int, min_len: int):
    """Poses (the initial period first) and the rejected runs for one threshold.

    A run is not trimmed: the window centred on a sample reaches half a window ahead, so the
    statistic crosses the threshold before the motion starts, by up to half a window (an abrupt
    motion raises it as soon as it enters the window; one that needs more than half the window to
    raise the variance past ``k`` times the noise moves the readings by about the noise there).
    """
    mask = v <= threshold
    mask[:init_end] = True  # the initial period is a pose by definition
    poses, rejected = [], []
    for a, b in runs(mask):
        if b - a >= min_len or a == 0:
            poses.append((a, b))
        else:
            rejected.append((a, b, f"static {b - a} samples < {min_len}"))
    return poses, rejected


def detect_static(acc: np.ndarray, gyr: np.ndarray, rate: float, *, gravity: float | None = None,
                  window_s: float = 0.5, init_s: float = 5.0, min_static_s: float = 0.5,
                  multipliers=MULTIPLIERS, min_poses: int = MIN_POSES, max_turn_deg: float = MAX_TURN_DEG,
                  acc_si: float = 1.0, gyr_si: float | None = 1.0, source: str = "session") -> Segmentation:
    """Find the static poses of a hand-turned session (module notes).

    Parameters
    ----------
    acc, gyr : (N, 3) ndarray
        Readings in their unit (`acc_si`, `gyr_si`: its SI value; 1 for m/s^2 and rad/s; for raw
        counts, `acc_si` 1: the accelerometer fit of the sweep carries the scale, and `gyr_si` None:
        no check of the turn inside a pose).
    rate : float
        Sample rate, Hz.
    gravity : float, optional
        Local gravity for the sweep's fits, m/s^2 (default G0; the choice of `k` hardly depends on it).
    window_s, init_s, min_static_s : float
        Variance window, initial static period, shortest pose, s.
    multipliers : sequence of float
        The threshold multipliers tried.
    max_turn_deg : float
        A pose in which the gyro turns by more than this: :class:`StaticMotionWarning`.

    Raises
    ------
    SegmentError
        Initial period not static; fewer than `min_poses` poses; pose directions in a plane.
    """
    from casep.calibration.multiposition import fit_accelerometer
    from casep.units import G0

    acc = np.asarray(acc, dtype=float)
    gyr = np.asarray(gyr, dtype=float)
    w, init_end, min_len, v, v_init, vg_init = detector(acc, gyr, rate, window_s, init_s, min_static_s, source)
    g = G0 if gravity is None else float(gravity)
    sweep, best = [], None
    for k in multipliers:
        poses, rejected = static_runs(v, k, init_end, min_len)
        rms = math.nan
        if len(poses) >= min_poses:
            means = np.array([acc[a:b].mean(axis=0) for a, b in poses]) * acc_si
            fit = fit_accelerometer(means, g, counts=np.array([b - a for a, b in poses]))
            rms = float(np.sqrt(np.mean(fit.residuals ** 2)))
            if best is None or rms < best[0]:
                best = (rms, k, poses, rejected, fit.calibrate(means))
        sweep.append((float(k), len(poses), rms))
    if best is None:
        most = max(sweep, key=lambda s: s[1])
        raise SegmentError(f"{source}: too few static poses: at most {most[1]} (multiplier {most[0]:g}) of at least "
                           f"{min_poses} {min_static_s:g}-s poses the 9-coefficient accelerometer model needs. Use: "
                           "hold the sensor still in more orientations, or a shorter --min-static")
    _, k, poses, rejected, cal = best
    spread = pose_spread(cal)
    turns = _check_poses(poses, spread, gyr, init_end, rate, gyr_si, max_turn_deg, source)
    return Segmentation(init=(0, poses[0][1]), poses=poses, threshold=k * v_init, multiplier=float(k),
                        init_variance=v_init, window=w, rate=float(rate), rejected=rejected, sweep=sweep,
                        spread=spread, turns_deg=turns, gyro_threshold=k * vg_init, statistic=v)


def detector(acc: np.ndarray, gyr: np.ndarray, rate: float, window_s: float, init_s: float, min_static_s: float,
             source: str) -> tuple:
    """The detector's sizes in samples (window, end of the initial period, shortest pose) and its
    statistic (:func:`static_statistic`): ``(w, init_end, min_len, v, v_init, vg_init)``.

    Raises
    ------
    SegmentError
        A session shorter than the initial period plus one window, or one that does not begin at rest.
    """
    n = len(acc)
    w = max(3, int(round(window_s * rate)))
    init_end = int(round(init_s * rate))
    min_len = max(2, int(round(min_static_s * rate)))
    if init_end + w > n:
        raise SegmentError(f"{source}: {n} samples ({n / rate:.3g} s) is shorter than the initial static period "
                           f"{init_s:g} s plus one window ({window_s:g} s). Use: a shorter --init or --window")
    return (w, init_end, min_len, *static_statistic(acc, gyr, w, init_end, rate, init_s, source))


def static_statistic(acc, gyr, w, init_end, rate, init_s, source):
    """The detector's statistic ``max(v_a / v_a,init, v_g / v_g,init)`` per sample, ``v_a,init``, ``v_g,init``.

    ``v_a`` is imu_tk's (module notes); ``v_g = sum_axes mean_window (w - b0)^2`` (b0 the initial
    period's mean gyro reading) adds what the accelerometers cannot see: a turn about gravity.
    """
    v = np.linalg.norm(window_variance(acc, w), axis=1)
    core = slice(w // 2, init_end - w // 2) if init_end > w else slice(0, init_end)
    vi = v[core]
    med = float(np.median(vi))
    if np.max(vi) > INIT_RISE * med or med <= 0:
        at = int(np.argmax(vi)) + (core.start or 0)
        raise SegmentError(f"{source}: no initial static period: over the first {init_s:g} s the window variance "
                           f"of the accelerometers rises to {np.max(vi) / max(med, 1e-300):.3g} times its median "
                           f"(row {at}, t = {at / rate:.3g} s; static: below {INIT_RISE:g}). Use: start the session "
                           "with the sensor at rest, or a shorter --init")
    d2 = np.sum((gyr - gyr[core].mean(axis=0)) ** 2, axis=1)
    vg = window_mean(d2, w)  # window mean of |w - b0|^2
    # a gyro quantised to a constant reading at rest has vg_init = 0: floor it far below any turn
    vg_init = max(float(np.mean(vg[core])), 1e-12 * float(np.mean(vg)), 1e-300)
    v_init = float(np.mean(vi))
    return np.maximum(v / v_init, vg / vg_init), v_init, vg_init


def pose_spread(f: np.ndarray) -> float:
    """Smallest singular value of the unit directions of `f` (n, 3) over sqrt(n): 0.577 spread evenly, 0 a plane."""
    dirs = f / np.linalg.norm(f, axis=1)[:, None]
    return float(np.linalg.svd(dirs, compute_uv=False)[-1] / math.sqrt(len(f)))


def pose_cone_deg(f: np.ndarray) -> float:
    """Largest angle between the unit directions of `f` (n, 3) and their mean direction, deg
    (90 or more: the directions surround the sensor; a few tens: the poses lie in one cone)."""
    dirs = f / np.linalg.norm(f, axis=1)[:, None]
    c = dirs.mean(axis=0)
    nc = float(np.linalg.norm(c))
    if nc < 1e-12:
        return 180.0
    return float(np.degrees(np.arccos(np.clip(dirs @ (c / nc), -1.0, 1.0))).max())


def _check_poses(poses, spread, gyr, init_end, rate, gyr_si, max_turn_deg, source) -> list[float]:
    """The spread error/warning and the motion-inside-a-pose warning; the turn in each pose, deg."""
    if spread < SPREAD_ERROR:
        raise SegmentError(f"{source}: the {len(poses)} poses' gravity directions do not span the sphere: smallest "
                           f"singular value / sqrt(n) {spread:.3g} < {SPREAD_ERROR} (0.577: spread evenly). Use: "
                           "turn the sensor so that each axis points up and down")
    if spread < SPREAD_WARN:
        warnings.warn(f"{source}: the {len(poses)} poses' gravity directions span the sphere poorly: smallest "
                      f"singular value / sqrt(n) {spread:.3g} < {SPREAD_WARN} (0.577: spread evenly); scale, "
                      "bias and misalignment are poorly separated", PoseSpreadWarning, stacklevel=3)
    if gyr_si is None:  # raw counts of unknown scale: the turn is not known in degrees before the gyro fit
        return []
    bias = gyr[:init_end].mean(axis=0)
    turns = [math.degrees(float(np.linalg.norm((gyr[a:b] - bias).sum(axis=0))) * gyr_si / rate) for a, b in poses]
    warn_turns(poses, turns, max_turn_deg, source)
    return turns


def warn_turns(poses: list, turns: list[float], max_turn_deg: float, source: str) -> None:
    """:class:`StaticMotionWarning` naming the poses in which the gyro turns by more than `max_turn_deg` (deg)."""
    moving = [(i, t) for i, t in enumerate(turns) if t > max_turn_deg]
    if moving:
        warnings.warn(f"{source}: the gyro turns inside {len(moving)} static pose(s): " + ", ".join(
            f"rows {poses[i][0]}-{poses[i][1] - 1} by {t:.3g} deg" for i, t in moving[:5])
            + f" (more than {max_turn_deg:g} deg; a turn about gravity the accelerometers do not see?)",
            StaticMotionWarning, stacklevel=4)

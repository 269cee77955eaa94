"""Tracking epochs that cannot be right, found against the telemetry's own motion, and a drifting clock.

A GNSS receiver that loses lock may repeat its last fix, report fresh-looking but wrong epochs, or
hold a 1 Hz solution over its 10 Hz output. The telemetry (the IMU) says how the vehicle moved
between two tracking epochs: ``V(t) = int a dt``, ``a`` the kinematic acceleration the pair reader
derives from the telemetry velocity (signals ``a_*``). With ``dv = v_tel - v_trk`` at the tracking
epochs, the tracking's own change between two epochs is ``dV - d(dv)``. :func:`screen_tracking`
finds, on a telemetry + tracking pair formed at the tracking times:

- **stale epochs**: a row whose velocity repeats the previous row's exactly (a repeated fix, or a velocity held
  while the positions go on; ``meta["tracking_repeats"]``, :func:`casep.io.pair.repeated_rows`) while the
  telemetry moved by more than :data:`STALE_MOTION` since the fix it repeats, and an Earth-fixed file's row whose
  position repeats the previous row's (``meta["tracking_frozen"]``) while the telemetry moved away from it by more
  than :data:`STALE_POSITION` plus :data:`STALE_MOTION` times the time since the fix (a cruising vehicle's repeated
  fix is metres off before its velocity is 0.5 m/s off). Both in one frame (:func:`casep.io.pair.stale_epochs`).
  The fix itself is kept (it was right at its time); its repeats are left out. On the pad a repeated fix of a
  vehicle at rest is kept (a receiver's static hold: zero Earth-fixed velocity, one position), and inside the
  window the navigation was levelled over (:func:`rest_window`) a repeat is a fix: the vehicle stands there by the
  levelling's premise while the first pass's INS, not yet corrected, drifts.
- **impossible jumps** (the physics check): between consecutive remaining epochs, ``|d(dv)|`` above
  ``JUMP_TOL + JUMP_RATE dt`` (10 m/s, plus 2 m/s^2 = 200 mg of instrument error acceleration per
  second between them) is a tracking velocity change the IMU rules out. The epochs are cut into
  segments at such jumps; a segment shorter than :data:`MIN_SEGMENT_S` is left out (a glitch or a
  burst of wrong epochs between consistent stretches), except the first when it joins the flight's first
  sample, where dv is 0 (the pad), under the same rule; when no segment is kept, the longest is.
- **excursions** (the physics check at the tracking's own noise level): wrong epochs a few m/s off while the
  vehicle does tens or hundreds of m/s stay below that rule, but not below the tracking's own noise. Between
  consecutive epochs of a stretch, ``|d(dv)|`` above :data:`EXCURSION_SIGMAS` robust sigma of the stretch's
  epoch-to-epoch changes (per axis, 1.4826 MAD) plus ``JUMP_RATE dt`` plus what a time-tag error of
  :data:`casep.model.loader.TIME_OFFSET_MAGNITUDE_MS` makes of the acceleration's change (``|d a| dt_trk``) is a
  jump; a jump away and a jump back within :data:`MIN_SEGMENT_S` whose sum is within the same rule (the
  dv returns to its course: the epochs between them were off by one offset) leave the epochs between them out.
  A lone jump (a step that stays: a time tag at lift-off, a change of the receiver's solution) leaves nothing
  out; the fit judges it.
- **clock drift**: the time offset of the tracking against the telemetry estimated in
  :data:`DRIFT_WINDOWS` windows (``dv ~ quadratic in t + a(t) tau_w`` per window, each axis its own
  quadratic, one ``tau_w``; windows whose acceleration barely changes cannot see it and are skipped),
  and a straight line through the ``tau_w`` (three windows or more): its slope in ppm with its std,
  the std scaled up by the line's reduced chi-square when the windows disagree more than their own
  std say (instrument errors the quadratics leave in bias each window differently). A slope beyond
  :data:`DRIFT_MIN_PPM` and 4 std is warned about (a single ``dt_trk`` does not model it);
  otherwise the figures are recorded. On a fit's residuals, where too few windows see an offset (a boost and a
  coast: the coast's acceleration barely changes), the whole flight is fitted at once, ``a (tau + eps t)``
  beside a constant per axis: the coast's steady acceleration carries the drift's ramp.

- **noise that changes between stretches** (stretches: the kept epochs split at pauses of
  :data:`MIN_SEGMENT_S` or more): the robust scatter of ``d(dv)`` per stretch (the median change
  removed, MAD, over sqrt 2); a ratio beyond :data:`NOISE_RATIO` between the noisiest and the
  quietest is warned about: one noise level per axis weights both alike, and the std of what the
  noisy stretch determines are understated by up to that ratio.

Each finding is a :class:`~casep.exceptions.TrackingQualityWarning` with the times, the number of
epochs and the sizes; ``meta["tracking_screen"]`` records them.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from casep._kernels import ar1_long_run_factor, cumulative_trapezoid, runs
from casep.checks.time_offset import kinematic_acceleration
from casep.exceptions import TrackingQualityWarning
from casep.io.files import ONE_FILE_TELEMETRY
from casep.io.flight import FlightData
from casep.io.pair import HELD_RUN_SHARE, HELD_SHARE, JUMP_RATE, STALE_MOTION, STALE_POSITION, stale_epochs
from casep.noise.model import whiten_blocks
from casep.noise.robust import MAD_SIGMA, MIN_SEGMENT_S, stretches
from casep.regression.linalg import analyze_rank, reduce_qr_blocks
from casep.regression.rows import GLITCH_GROSS

if TYPE_CHECKING:
    from casep.regression.problem import Problem

__all__ = ["TrackingScreen", "screen_tracking", "stale_epochs", "rest_window", "keep_screen", "clock_drift",
           "clock_drift_unmeasured", "fit_clock_drift", "clock_drift_record",
           "offset_halves", "halves_line", "telemetry_clock_line",
           "drift_determined", "stretches", "stretch_noise", "noise_problem",
           "determined", "determined_message", "plausible_size", "combination_terms", "stretch_sigma", "MAX_TERMS",
           "imu_noise_effect", "imu_sample_noise", "white_sample_std", "unresolved_noise", "NOISE_RESOLUTION_SHARE",
           "imu_bias_effect", "IMU_INSTABILITY_TAU", "imu_noise_beside_bound", "IMU_INSTABILITY_SIZE", "IMU_REML_ROWS",
           "rest_white_std", "IMU_NOISE_AT_REST", "pad_white_std", "IMU_NOISE_PAD", "imu_noise_on_pad",
           "white_std_error", "allan_white_error", "NOISE_DIFF_ORDERS", "WHITE_STD_ERROR", "NOISE_SWITCH_SIGMAS",
           "STALE_MOTION", "STALE_POSITION", "HELD_SHARE", "HELD_RUN_SHARE", "JUMP_TOL", "JUMP_RATE",
           "EXCURSION_SIGMAS", "MIN_SEGMENT_S", "DRIFT_MIN_PPM", "NOISE_RATIO"]

#: The physics check: a jump of dv between consecutive epochs above JUMP_TOL + JUMP_RATE dt (m/s, m/s^2) ...
JUMP_TOL = 10.0
#: An excursion's jumps: beyond this many robust sigma of the stretch's epoch-to-epoch change of dv: the fit's gross
#: glitch (:data:`casep.regression.rows.GLITCH_GROSS`, 10: Gaussian noise gives P = 1.6e-23 per axis).
EXCURSION_SIGMAS = GLITCH_GROSS
#: ... cuts the epochs into segments; a segment shorter than MIN_SEGMENT_S (s) is left out, and a pause that long
#: splits them into stretches with a noise level each (:func:`casep.noise.robust.stretches`, the robust filter's
#: split: one rule in the lower layer)
#: A clock drift is warned about beyond this (ppm) and 4 std.
DRIFT_MIN_PPM = 20.0
#: Windows for the drift, and the least spread of the acceleration (m/s^2) that lets a window see an offset.
DRIFT_WINDOWS = 6
DRIFT_MIN_ACCEL = 2.0
#: A window sees an offset with this many epochs or more; the drift needs this many such windows (a line
#: through the windows' offsets and a scatter to check it against).
DRIFT_MIN_EPOCHS = 10
DRIFT_MIN_WINDOWS = 3
#: Stretches of the tracking whose noise differs by more than this factor are warned about.
NOISE_RATIO = 5.0
#: The IMU's white noise is carried to the tracking epochs in blocks of this length, s (:func:`imu_noise_effect`).
IMU_NOISE_BLOCK_S = 0.2


@dataclass
class TrackingScreen:
    """What :func:`screen_tracking` found: spans ``(t_first, t_last, epochs)`` (s), the drift (ppm, NaN: not
    determined), and the rows of the tracking file left out (``left_out_rows``, 0-based)."""

    stale: list = field(default_factory=list)
    rejected: list = field(default_factory=list)
    largest_jump_m_s: float = 0.0
    drift_ppm: float = math.nan
    drift_std_ppm: float = math.nan
    epochs: int = 0
    kept: int = 0
    stretches: list = field(default_factory=list)
    left_out_rows: list = field(default_factory=list)
    excursions: list = field(default_factory=list)
    largest_excursion_m_s: float = 0.0

    def to_dict(self) -> dict:
        """Plain data (JSON: NaN as null)."""
        out = dataclasses.asdict(self)
        for k in ("drift_ppm", "drift_std_ppm"):
            out[k] = None if not math.isfinite(out[k]) else out[k]
        return out


def screen_summary(screen: dict | None, top: int = 3) -> str:
    """What a flight's tracking screen (``meta["tracking_screen"]``, :meth:`TrackingScreen.to_dict`) left out, in a
    clause: how many epochs of how many, the stale and the physics-rejected spans (the first `top` of each, by time);
    "" when it left out none."""
    if not screen or screen.get("kept", 0) >= screen.get("epochs", 0):
        return ""

    def spans(key: str, what: str) -> str:
        found = screen.get(key) or []
        if not found:
            return ""
        said = ", ".join(f"t = {a:.6g}..{b:.6g} s ({n})" for a, b, n in found[:top])
        more = f" and {len(found) - top} more" if len(found) > top else ""
        return f"{what} {_span_epochs(found)} in {len(found)} span{'s' if len(found) > 1 else ''}: {said}{more}"

    parts = [p for p in (spans("stale", "stale (repeated fixes)"), spans("rejected", "rejected by the physics check"),
                         spans("excursions", "off the telemetry's course and back (the physics check at the noise)"))
             if p]
    return (f"the tracking screen left out {screen['epochs'] - screen['kept']} of its {screen['epochs']} epochs"
            + (f" ({'; '.join(parts)})" if parts else ""))


def _span_epochs(spans: list) -> int:
    """The epochs in spans ``(t_first, t_last, epochs)`` (:class:`TrackingScreen`'s), summed."""
    return sum(n for *_, n in spans)


def _spans(t: np.ndarray, flagged: np.ndarray) -> list[tuple[float, float, int]]:
    """Runs of consecutive flagged epochs (:func:`casep._kernels.runs`): ``(t_first, t_last, count)``."""
    return [(float(t[a]), float(t[b - 1]), b - a) for a, b in runs(flagged)]


def _located(flight: FlightData, idx: np.ndarray, flagged: np.ndarray, top: int = 6) -> str:
    """The first `top` runs of flagged epochs (of the observed samples `idx`) by file line and time, and how many."""
    from pathlib import Path

    from casep.io.locate import locate_samples

    flagged_runs = runs(flagged)
    locs = locate_samples(flight, [idx[k] for a, b in flagged_runs[:top] for k in (a, b - 1)])
    parts = []
    for i, (a, b) in enumerate(flagged_runs[:top]):
        first, last = locs[2 * i], locs[2 * i + 1]
        one = b - a == 1  # one epoch: its line and time, not a span from it to itself
        key = "line" if first["line"] is not None else "row"
        at = "" if first["file"] is None else (
            f"{key} {first[key]}" if one else f"{key}s {first[key]}..{last[key]}") + f" of {Path(first['file']).name}, "
        span = f"{first['t']:.10g} s" if one else f"{first['t']:.10g}..{last['t']:.10g} s"
        parts.append(f"{at}t = {span} ({b - a})")
    return ", ".join(parts) + (f" and {len(flagged_runs) - top} more" if len(flagged_runs) > top else "")


def _acceleration(flight: FlightData) -> np.ndarray | None:
    """The kinematic acceleration, (N, 3) m/s^2: the signals ``a_*`` of a pair; of a one-file flight without them
    ``f + g`` (flat-Earth gravity, :func:`casep.checks.time_offset.kinematic_acceleration`: over the seconds of a stale
    run its error is far below :data:`STALE_MOTION`); None when neither."""
    if all(f"a_{c}" in flight.signals for c in "xyz"):
        a = np.column_stack([flight.signals[f"a_{c}"] for c in "xyz"])
    elif flight.meta.get("format") != "pair":
        a = kinematic_acceleration(flight.t, flight.f)
    else:
        return None
    return a if np.all(np.isfinite(a)) else None


def _velocity_change(a: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``V(t) = int a dt`` (trapezoid) of the kinematic acceleration `a` at times `t`, (N, 3) m/s."""
    return cumulative_trapezoid(a, t)


def _screened(meta: dict) -> bool:
    """Whether :func:`screen_tracking` judges a flight: a pair formed at the tracking times, or a one-file flight
    with tracking columns (``v_trk_*``: its sample k is data row k), not screened already."""
    if "tracking_screen" in meta:
        return False
    if meta.get("format") == "pair":
        return meta.get("rows_side") == "tracking" and "rows_index" in meta
    return meta.get("dv") == ONE_FILE_TELEMETRY and "tracking_repeats" in meta


def _file_rows(flight: FlightData) -> np.ndarray:
    """The tracking file's data row of each sample, (N,): a pair's ``meta["rows_index"]`` (-1: no tracking row);
    a one-file flight's sample k is its data row k."""
    index = flight.meta.get("rows_index")
    return np.arange(flight.t.size) if index is None else np.asarray(index)


def _stale(flight: FlightData, idx: np.ndarray, V: np.ndarray) -> np.ndarray:
    """Of the observed epochs `idx`: :func:`stale_epochs` (the file's repeated rows ``meta["tracking_repeats"]``; an
    Earth-fixed pair's rows of a repeated position ``meta["tracking_frozen"]`` and the telemetry's position less the
    tracking's per row, ``meta["tracking_position_gap"]``, :func:`casep.io.pair.position_gap`)."""
    meta = flight.meta
    rows = _file_rows(flight)[idx]
    is_rep = np.isin(rows, np.asarray(meta.get("tracking_repeats", []), dtype=int))
    frozen = gap = None
    if "tracking_frozen" in meta and "tracking_position_gap" in meta:
        frozen = np.isin(rows, np.asarray(meta["tracking_frozen"], dtype=int))
        gap = np.asarray(meta["tracking_position_gap"], dtype=float)[rows]
    return stale_epochs(flight.t[idx], V[idx], flight.dv[idx], is_rep, frozen, gap, rest_window(meta))


def rest_window(meta: dict) -> list[float] | None:
    """Where the vehicle stood by the navigation's premise, ``[T1, T2]`` s of the flight's time: the window an IMU was
    levelled over (``meta["rest_window_s"]``, :mod:`casep.workflows.imu_separate`'s ``--align``) or the one a
    navigated telemetry's header names (``meta["levelled"]["window"]``); None when neither."""
    window = meta.get("rest_window_s") or (meta.get("levelled") or {}).get("window")
    return None if window is None else [float(window[0]), float(window[1])]


def _impossible(t: np.ndarray, dv: np.ndarray, start: float | None = None) -> tuple[np.ndarray, float]:
    """Epochs in segments shorter than MIN_SEGMENT_S between jumps the IMU rules out; and the largest jump, m/s.

    `start` (s, at or before ``t[0]``): where dv is 0, the first telemetry sample (the model's ``S_V(t0) = 0``; an
    INS aligned on the pad starts at the pad's velocity). It is an epoch like the others: the first segment, when
    its first dv is within the jump rule of 0 since `start`, holds the pad and is kept however short (a receiver
    that loses lock a second after lift-off leaves only that second of right fixes before its wrong ones)."""
    if t.size < 2:
        return np.zeros(t.size, bool), 0.0
    jump = np.linalg.norm(np.diff(dv, axis=0), axis=1)
    cut = jump > JUMP_TOL + JUMP_RATE * np.diff(t)
    seg = np.concatenate([[0], np.cumsum(cut)])
    first = np.flatnonzero(np.concatenate([[True], cut]))
    last = np.concatenate([first[1:] - 1, [t.size - 1]])
    long = t[last] - t[first] >= MIN_SEGMENT_S
    if start is not None and start <= t[0] and np.linalg.norm(dv[0]) <= JUMP_TOL + JUMP_RATE * (t[0] - start):
        long[0] = True  # joined to the pad's dv = 0
    if not long.any():
        long[np.argmax(t[last] - t[first])] = True
    largest = float(jump[cut].max()) if cut.any() else 0.0
    return ~long[seg], largest


def _excursions(t: np.ndarray, dv: np.ndarray, acc: np.ndarray) -> tuple[np.ndarray, float]:
    """Epochs between a jump of dv away from its course and the jump back (module notes: excursions), of the epochs
    `t` (s) with `dv` and the telemetry's kinematic acceleration `acc` there (m/s, m/s^2); and the largest of those
    jumps, m/s.

    A jump: ``|d(dv)|`` between consecutive epochs of a stretch (:func:`stretches`) beyond ``EXCURSION_SIGMAS s +
    JUMP_RATE dt + |d a| dt_trk``, ``s`` the stretch's robust sigma of the change (1.4826 MAD, its largest axis; a
    stretch without scatter has no jump). A jump away and the next jump back within :data:`MIN_SEGMENT_S` whose sum is
    within ``EXCURSION_SIGMAS sqrt(2) s`` plus both jumps' other allowances (the dv returns where it would have
    been) leave the epochs between them out; any other jump leaves nothing out."""
    from casep.model.loader import TIME_OFFSET_MAGNITUDE_MS

    out = np.zeros(t.size, bool)
    if t.size < 3:
        return out, 0.0
    d = np.diff(dv, axis=0)
    s = np.zeros(d.shape[0])  # each change's stretch's robust sigma of the change, m/s (0: none)
    for a, b in stretches(t):
        dd = d[a:b - 1]
        s[a:b - 1] = MAD_SIGMA * float(np.max(np.median(np.abs(dd - np.median(dd, axis=0)), axis=0)))
    other = JUMP_RATE * np.diff(t) + np.linalg.norm(np.diff(acc, axis=0), axis=1) * TIME_OFFSET_MAGNITUDE_MS * 1e-3
    jump = np.linalg.norm(d, axis=1)
    cuts = np.flatnonzero((s > 0) & (jump > EXCURSION_SIGMAS * s + other))
    largest, i = 0.0, 0
    while i + 1 < cuts.size:
        a, b = cuts[i], cuts[i + 1]  # away between epochs a and a + 1, back between b and b + 1
        back = np.linalg.norm(d[a] + d[b]) <= EXCURSION_SIGMAS * math.sqrt(2.0) * max(s[a], s[b]) + other[a] + other[b]
        if t[b] - t[a + 1] < MIN_SEGMENT_S and back:
            out[a + 1:b + 1] = True
            largest = max(largest, float(jump[a]), float(jump[b]))
            i += 2
        else:
            i += 1
    return out, largest


def clock_drift(t: np.ndarray, dv: np.ndarray, a: np.ndarray, windows: int = DRIFT_WINDOWS,
                order: int = 2) -> tuple[float, float]:
    """The drift of the tracking time offset, ppm, and its std (module notes); on a fit's residuals (`order` 0) where
    fewer than :data:`DRIFT_MIN_WINDOWS` windows see an offset, the whole flight at once
    (:func:`_whole_flight_drift`: a boost and a coast); NaN when neither sees it.

    Parameters
    ----------
    t : (n,) ndarray
        Tracking epochs, s.
    dv : (n, 3) ndarray
        ``v_tel - v_trk`` there, m/s.
    a : (n, 3) ndarray
        The telemetry's kinematic acceleration there, m/s^2 (a late tracking time tag ``tau``: ``dv += a tau``).
    windows : int
        Windows the span is cut into; each gives one offset.
    order : int
        Degree of the polynomial trend each axis has of its own in each window, fitted beside the offset: 2 on a
        raw dv (the instrument errors' slow part), 0 on a fit's residuals (:func:`fit_clock_drift`).
    """
    centre, tau, var = [], [], []
    for lo, hi, k in _drift_windows(t, a, windows):
        if k is None:
            continue
        coef, cov = _offset_fit(t[k], dv[k], a[k], lo, hi, order)
        centre.append(0.5 * (lo + hi))
        tau.append(coef[-1])
        var.append(cov[-1, -1])
    if len(tau) < DRIFT_MIN_WINDOWS:
        return _whole_flight_drift(t, dv, a, order)
    w = 1.0 / np.maximum(np.asarray(var), 1e-30)
    X = np.column_stack([np.ones(len(tau)), np.asarray(centre) - np.mean(centre)])
    cov = np.linalg.inv(X.T @ (w[:, None] * X))
    line = cov @ (X.T @ (w * np.asarray(tau)))
    res = np.asarray(tau) - X @ line
    birge = max(1.0, float(np.sum(w * res**2)) / (len(tau) - 2))  # the windows disagree more than their std say:
    return float(line[1]) * 1e6, math.sqrt(cov[1, 1] * birge) * 1e6  # errors the trends left in, the std grow


def _offset_fit(t: np.ndarray, dv: np.ndarray, a: np.ndarray, lo: float, hi: float, order: int,
                drift: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """The least-squares fit of one window (epochs `t` in ``[lo, hi]``): ``dv`` ~ each axis' polynomial trend of
    degree `order` + ``a tau`` (+ ``a (t - t_mid) eps`` with `drift`), its coefficients (``tau`` then ``eps``
    last) and their covariance. Correlated noise (Gauss-Markov, instrument errors the trends leave): the
    white-noise covariance times the AR(1) long-run factor ``(1 + rho) / (1 - rho)`` of the residuals, ``rho``
    their lag-1 autocorrelation pooled over the axes."""
    tm = 0.5 * (lo + hi)
    n, m = t.size, order + 1  # trend terms per axis
    A = np.zeros((3 * n, 3 * m + 1 + int(drift)))
    for j in range(3):  # rows of axis j: its own polynomial trend, and the shared offset (and its drift)
        for p in range(m):
            A[j::3, m * j + p] = ((t - tm) / (hi - lo)) ** p
        A[j::3, 3 * m] = a[:, j]
        if drift:
            A[j::3, 3 * m + 1] = a[:, j] * (t - tm)
    y = dv.reshape(-1)
    coef, *_ = np.linalg.lstsq(A, y, rcond=None)
    r = (y - A @ coef).reshape(n, 3)
    long_run = float(ar1_long_run_factor(np.sum(r[1:] * r[:-1]), np.sum(r[:-1] ** 2)))
    return coef, np.linalg.pinv(A.T @ A) * float(np.sum(r**2)) / max(3 * n - A.shape[1], 1) * long_run


def _whole_flight_drift(t: np.ndarray, dv: np.ndarray, a: np.ndarray, order: int) -> tuple[float, float]:
    """The drift (ppm, std) from the whole flight at once, where too few windows see an offset (a boost and a
    coast: the acceleration changes in the boost only): one fit of ``a (tau + eps (t - t_mid))`` beside a
    constant per axis (:func:`_offset_fit` over the whole span, `eps` the drift). On a fit's residuals only
    (`order` 0, :func:`fit_clock_drift`): on the raw dv a trend per axis over the whole flight does not hold the
    instrument errors, whose dv follows the acceleration too. NaN where `order` is not 0 or the whole flight does
    not see a drift (:func:`_whole_flight_unseen`)."""
    if order != 0 or _whole_flight_unseen(t, a):
        return math.nan, math.nan
    coef, cov = _offset_fit(t, dv, a, float(t[0]), float(t[-1]), 0, drift=True)
    return float(coef[-1]) * 1e6, math.sqrt(max(float(cov[-1, -1]), 0.0)) * 1e6


def _whole_flight_unseen(t: np.ndarray, a: np.ndarray, windows: int = DRIFT_WINDOWS) -> str:
    """Why the whole flight at once (:func:`_whole_flight_drift`) does not see a drift, or an empty string: its
    acceleration must spread by :data:`DRIFT_MIN_ACCEL` (the offset apart from the constants), and be that large
    (median norm) over :data:`DRIFT_MIN_EPOCHS` epochs or more in :data:`DRIFT_MIN_WINDOWS` of the windows (the
    drift's ramp ``a eps t`` over a span: a coast's steady acceleration carries it, a pad's none)."""
    spread = float(np.max(np.ptp(a, axis=0))) if t.size else 0.0
    if not spread >= DRIFT_MIN_ACCEL:
        return f"over the whole flight the acceleration spreads by {spread:.2g} m/s^2"
    carry = sum(int(k.sum() >= DRIFT_MIN_EPOCHS and np.median(np.linalg.norm(a[k], axis=1)) >= DRIFT_MIN_ACCEL)
                for _, _, k in _window_masks(t, windows))
    if carry < DRIFT_MIN_WINDOWS:
        return (f"nor the whole flight at once: its acceleration is {DRIFT_MIN_ACCEL:g} m/s^2 or more over "
                f"{DRIFT_MIN_EPOCHS} epochs in {carry} of the windows, {DRIFT_MIN_WINDOWS} needed")
    return ""


def _drift_windows(t: np.ndarray, a: np.ndarray, windows: int = DRIFT_WINDOWS
                   ) -> list[tuple[float, float, np.ndarray | None]]:
    """The windows :func:`clock_drift` cuts the epochs `t` into: ``(t_lo, t_hi, mask)``, the mask of the window's
    epochs, or None where the window cannot see an offset (fewer than :data:`DRIFT_MIN_EPOCHS` epochs, or the
    acceleration `a` spreads by less than :data:`DRIFT_MIN_ACCEL` over them on every axis)."""
    out: list[tuple[float, float, np.ndarray | None]] = []
    for lo, hi, k in _window_masks(t, windows):
        seen = k.sum() >= DRIFT_MIN_EPOCHS and np.max(np.ptp(a[k], axis=0)) >= DRIFT_MIN_ACCEL
        out.append((lo, hi, k if seen else None))
    return out


def _window_masks(t: np.ndarray, windows: int) -> list[tuple[float, float, np.ndarray]]:
    """The `windows` equal spans of the epochs `t` (s) the drift rules judge: ``(t_lo, t_hi, mask)``."""
    edges = np.linspace(t[0], t[-1], windows + 1)
    return [(float(lo), float(hi), (t >= lo) & (t <= hi)) for lo, hi in zip(edges[:-1], edges[1:])]


def clock_drift_unmeasured(t: np.ndarray, a: np.ndarray, windows: int = DRIFT_WINDOWS) -> str:
    """Why :func:`clock_drift` gives NaN for epochs `t` (s) and the acceleration `a` there (m/s^2): the windows
    that see an offset and why the others do not, as text; an empty string when enough windows see one."""
    if t.size < 2:
        return f"{t.size} tracking epoch(s): no time span to measure a drift over"
    wins = _drift_windows(t, a, windows)
    seen = sum(k is not None for *_, k in wins)
    if seen >= DRIFT_MIN_WINDOWS:
        return ""
    few, still = [], []
    for lo, hi, k in wins:
        if k is not None:
            continue
        m = (t >= lo) & (t <= hi)
        n = int(m.sum())
        if n < DRIFT_MIN_EPOCHS:
            few.append(f"{lo:.4g}..{hi:.4g} s ({n})")
        else:
            still.append(f"{lo:.4g}..{hi:.4g} s ({float(np.max(np.ptp(a[m], axis=0))):.2g} m/s^2)")
    parts = []
    if few:
        parts.append(f"{len(few)} have fewer than {DRIFT_MIN_EPOCHS} epochs ({', '.join(few)})")
    if still:
        parts.append(f"in {len(still)} the acceleration spreads by less than {DRIFT_MIN_ACCEL:g} m/s^2, so a "
                     f"time offset does not show ({', '.join(still)})")
    whole = _whole_flight_unseen(t, a, windows)
    return (f"only {seen} of the {windows} windows the tracking's time span is cut into see a time offset, "
            f"{DRIFT_MIN_WINDOWS} needed: {'; '.join(parts)}" + (f"; {whole}" if whole else ""))


def stretch_noise(t: np.ndarray, dv: np.ndarray) -> list[tuple[float, float, int, float]]:
    """Per stretch (:func:`stretches`): ``(t_first, t_last, epochs, scatter m/s)``, the scatter the MAD of the
    changes of dv (their median removed) over sqrt 2, largest axis."""
    out = []
    for a, b in stretches(t):
        d = np.diff(dv[a:b], axis=0)
        mad = np.median(np.abs(d - np.median(d, axis=0)), axis=0)
        out.append((float(t[a]), float(t[b - 1]), int(b - a), float(np.max(mad)) * MAD_SIGMA / math.sqrt(2)))
    return out


def screen_tracking(flight: FlightData, *, drift_warning: bool = True) -> FlightData:
    """`flight` without its stale and impossible tracking epochs (module notes), the findings warned and recorded.

    Only a telemetry + tracking pair formed at the tracking times with the telemetry's acceleration
    (:func:`casep.io.files.read_flight_pair`), or a one-file flight with ``v_tel_*`` and ``v_trk_*`` columns
    (:func:`casep.io.files.read_flight`), is screened, once; any other flight (or one screened already:
    ``meta["tracking_screen"]``) is returned as it is.

    `drift_warning` False: the clock drift of the raw dv is recorded but not warned; a separation that follows
    measures and warns it on its residuals (:func:`fit_clock_drift`).

    Warns
    -----
    TrackingQualityWarning
        Stale epochs, epochs left out by the physics check, a clock drift: times, counts and sizes.
    """
    meta = flight.meta
    acc = _acceleration(flight) if _screened(meta) else None
    if acc is None:
        return flight
    V = _velocity_change(acc, flight.t)
    idx = np.flatnonzero(flight.observed)
    t = flight.t[idx]
    stale = _stale(flight, idx, V)
    fresh = np.flatnonzero(~stale)
    bad_fresh, largest = _impossible(t[fresh], flight.dv[idx[fresh]], float(flight.t[0]))
    rejected = np.zeros(idx.size, bool)
    rejected[fresh[bad_fresh]] = True
    rest = np.flatnonzero(~(stale | rejected))  # the physics check at the tracking's noise, on what is left
    off, largest_off = _excursions(t[rest], flight.dv[idx[rest]], acc[idx[rest]])
    excursion = np.zeros(idx.size, bool)
    excursion[rest[off]] = True
    keep = ~(stale | rejected | excursion)
    a = acc[idx[keep]]
    own_clock = meta.get("format") == "pair"  # a one-file flight's rows tag telemetry and tracking alike
    drift, drift_std = clock_drift(t[keep], flight.dv[idx[keep]], a) if own_clock and keep.sum() >= 20 \
        else (math.nan, math.nan)
    screen = TrackingScreen(_spans(t, stale), _spans(t, rejected), largest, drift, drift_std, int(idx.size),
                            int(keep.sum()), excursions=_spans(t, excursion), largest_excursion_m_s=largest_off)
    screen.stretches = stretch_noise(t[keep], flight.dv[idx[keep]])
    screen.left_out_rows = [int(r) for r in _file_rows(flight)[idx[~keep]]]
    _warn(flight.source, screen, _located(flight, idx, stale) if stale.any() else "",
          _located(flight, idx, rejected) if rejected.any() else "", drift_warning,
          _located(flight, idx, excursion) if excursion.any() else "")
    if keep.all():
        return dataclasses.replace(flight, meta={**meta, "tracking_screen": screen.to_dict()})
    observed = flight.observed.copy()
    observed[idx[~keep]] = False
    return dataclasses.replace(flight, observed=observed, meta={**meta, "tracking_screen": screen.to_dict()})


def keep_screen(flight: FlightData, screen: dict | None) -> FlightData:
    """`flight` with the tracking rows a screen of the same tracking file left out (``screen["left_out_rows"]``,
    :func:`screen_tracking`'s ``meta["tracking_screen"]``) left out again and the screen recorded, without
    screening anew; `flight` as it is when `screen` is None.

    The passes of an iteration that re-navigates the same IMU record and pairs it with the same tracking
    (:mod:`casep.workflows.imu_separate`) keep the first pass's screen: a fixed point needs the same rows
    in every pass, and what the screen tests (a repeated fix while the IMU moved by more than
    :data:`STALE_MOTION`, jumps beyond :data:`JUMP_TOL` + :data:`JUMP_RATE` dt, or beyond :data:`EXCURSION_SIGMAS`
    sigma of the noise between consecutive epochs) is larger by orders of magnitude than what a correction of
    the IMU's errors (smooth in time) changes between passes.
    """
    if screen is None:
        return flight
    observed = flight.observed.copy()
    rows = _file_rows(flight)
    observed[np.isin(rows, np.asarray(screen["left_out_rows"], dtype=int)) & (rows >= 0)] = False
    return dataclasses.replace(flight, observed=observed, meta={**flight.meta, "tracking_screen": screen})


def drift_determined(drift_ppm: float, drift_std_ppm: float) -> bool:
    """The clock-drift rule: a drift beyond :data:`DRIFT_MIN_PPM` and 4 std (warned about)."""
    return math.isfinite(drift_ppm) and abs(drift_ppm) > max(DRIFT_MIN_PPM, 4.0 * drift_std_ppm)


def halves_line(h: dict) -> str:
    """The report's line of :func:`offset_halves`' record `h`: the two offsets, the drift, and either that it is
    beyond the rule (warned) or how large a drift the one ``dt_trk`` may have taken in without a word (2 std)."""
    text = (f"tracking clock drift (dt_trk split at the middle of the flight): {h['first_ms']:.3g} ms seen at "
            f"t = {h['t_first_s']:.4g} s, {h['second_ms']:.3g} ms at t = {h['t_second_s']:.4g} s: "
            f"{h['ppm']:.3g} +- {h['std_ppm']:.2g} ppm")
    if drift_determined(h["ppm"], h["std_ppm"]):
        return text + " (beyond 4 std: the clocks run at different rates, which one dt_trk does not model)"
    bound = abs(h["ppm"]) + 2.0 * h["std_ppm"]
    ms = bound * (h["t_second_s"] - h["t_first_s"]) * 1e-3
    return (text + f"; not determined: a drift up to {bound:.3g} ppm ({ms:.2g} ms between those times) would be "
            "taken into the one dt_trk unseen (a drift known otherwise: --clock-drift PPM)")


def telemetry_clock_line(record: dict, carried: dict | None = None) -> str:
    """The report's line of :func:`casep.workflows.telemetry_clock.telemetry_clock_record`'s `record`: the drift, and
    either that it is beyond the rule or the drifts the data allow (2 std) and where the rule would warn; with
    `carried` (``diagnostics["clock_drift"]["carried"]``: :func:`casep.workflows.telemetry_clock.carry_telemetry_clock`)
    what its std carry of it."""
    given = f"--clock-drift {record['given_ppm']:g} given" if record["given_ppm"] else "no clock drift given"
    text = (f"telemetry clock drift ({given}; estimated beside the coefficients, tags and integration steps): "
            f"{record['ppm']:.4g} +- {record['std_ppm']:.2g} ppm")
    said = (carried or {}).get("said")  # the drift carried in the std, said by its workflow
    tail = f"; {said}" if said else ""
    if record["determined"]:
        return text + " (beyond the clock-drift rule: the clocks run at different rates)" + tail
    b, sd = record["beyond_given_ppm"], record["std_ppm"]
    rule = record.get("warns_beyond_ppm") or max(DRIFT_MIN_PPM, 4.0 * sd)
    moves = record.get("moves") or []
    moved = (f"; a drift of {rule:.3g} ppm not modelled would move " + ", ".join(
        f"{m['name']} by {m['z']:+.2g} std" for m in moves)) if moves else ""
    return (text + f"; not determined: the data allow {b - 2 * sd:.3g} to {b + 2 * sd:.3g} ppm beyond the one given "
            f"(2 std, to first order in the drift), which the coefficients would take in unseen; the test warns only "
            f"beyond {rule:.3g} ppm ({DRIFT_MIN_PPM:g} ppm and 4 std){moved} (a drift known otherwise: "
            "--clock-drift PPM)" + tail)


def _warn_drift(source: str, drift_ppm: float, drift_std_ppm: float, of: str) -> bool:
    """Warn (TrackingQualityWarning) when the clock drift is beyond :data:`DRIFT_MIN_PPM` and 4 std; `of`: what it
    was measured on, said in the message. Returns whether it warned."""
    if not drift_determined(drift_ppm, drift_std_ppm):
        return False
    warnings.warn(TrackingQualityWarning(
        f"{source}: the tracking time offset drifts by {drift_ppm:.4g} +- {drift_std_ppm:.2g} ppm "
        f"({drift_ppm * 0.1:.3g} ms per 100 s{of}): the telemetry and tracking clocks run at different rates, "
        "which one time offset (dt_trk) does not model: state it (--clock-drift PPM, manifest clock_drift_ppm)"),
        stacklevel=4)
    return True


def fit_clock_drift(flight: FlightData, residual: np.ndarray) -> tuple[float, float] | None:
    """The clock drift (ppm, std; :func:`clock_drift`) measured on a fit's residuals ``dv - S_V D`` (`residual`,
    (n, 3) at the flight's observed epochs) instead of the raw dv, warned as the screen warns; None when the flight
    has no clock of its own to drift (not a pair of files) or the residuals do not match its epochs.

    The raw dv holds the instrument errors, whose dv follows the acceleration too (an accelerometer scale factor
    gives ``sa int f dt``): a window's offset fit takes part of them, differently in each window, and the line
    through the windows' offsets then shows a drift there is not (1700 +- 300 ppm on an aircraft whose clock did
    not drift). The fit's residuals keep the drift, which no error model term takes (a late tag ``eps t`` gives
    ``dv = a eps t``), and lose the instrument errors. With those gone, a window needs no trend of its own (order 0:
    a constant per axis): a quadratic trend per axis and window takes part of ``a tau`` wherever the acceleration
    is itself near a quadratic over the window (an aircraft's turns of 20-30 s), and the windows' offsets then
    scatter by several of their std (one aircraft's truth dv: -27 to 106 ms for a constant 40 ms, a drift of
    1939 +- 307 ppm; with constants 226 +- 172 ppm)."""
    if flight.meta.get("format") != "pair":
        return None
    acc = _acceleration(flight)
    idx = np.flatnonzero(flight.observed)
    r = np.asarray(residual, dtype=float)
    if acc is None or idx.size < 20 or r.shape != (idx.size, 3) or not np.all(np.isfinite(r)):
        return None
    drift, std = clock_drift(flight.t[idx], r, acc[idx], order=0)
    _warn_drift(flight.source, drift, std, ", on the fit's residuals")
    return drift, std


def offset_halves(source: str, problem: Problem, noise: dict | None = None) -> dict | None:
    """The clock drift seen by the fit itself: its time offset (``dt_trk``) split at the middle of the observed
    span, one for each half, beside every other coefficient of the fit (OLS on its raw rows, S_V block by block;
    the std white times the AR(1) long-run factor of the residuals, as :func:`_offset_fit`). A drift ``eps`` makes
    the two offsets differ by ``eps (t2 - t1)``, ``t_i`` the half's time weighted by how much it sees of the
    offset (``|a|^2``); with the fit's noise model (`noise`, ``diagnostics["noise"]`` with its ``axes``) the rows are
    whitened by it, its Gauss-Markov part as well as its white (GLS): the AR(1) factor of the residuals misses the
    long-run variance of a Gauss-Markov plus white mixture (at 50 Hz, tau 1 s, 0.1 + 0.05 m/s: lag-1 correlation
    0.78, a factor 8 where the mixture's is near 80), and its std were 3-5 x too small: 34.4 +- 6.3 ppm on a clean
    simulated boost. Warned as :func:`clock_drift` (:func:`_warn_drift`), and said either way in the report
    (:func:`halves_line`). On a coast alone the drift's ramp ``a eps t`` is an accelerometer bias's: the second
    half sees the drift only where its acceleration changes. The residuals' test (:func:`fit_clock_drift`) cannot
    see a drift the fit took into its other coefficients and its offset; this one measures it, or says how large
    a drift the flight leaves unseen (a MEMS rocket's 104 ppm over 40 s: 64 +- 93 ppm, where the residuals gave
    -2914 +- 30291 ppm). `source`: the flight, for the message.

    Returns
    -------
    dict or None
        ``first_ms``, ``second_ms`` (the two offsets, in the coefficient's unit scaled to ms), ``difference_ms``,
        ``std_ms``, ``t_first_s``, ``t_second_s``, ``ppm``, ``std_ppm``; None when the fit has no time offset, no
        rows, or a half sees none of it.
    """
    from casep.model.loader import TIME_OFFSET

    names = list(problem.names)
    if TIME_OFFSET not in names:
        return None
    raw = problem.raw_problem()
    if raw.y is None or raw.t is None or not raw.has_rows:
        return None
    y, t = np.asarray(raw.y, dtype=float), np.asarray(raw.t, dtype=float)
    if y.ndim != 2 or t.shape != (y.shape[0],):
        return None
    j = names.index(TIME_OFFSET)
    late = t >= 0.5 * (t[0] + t[-1])
    seen = np.zeros(t.size)  # how much each epoch sees of the offset, |a|^2

    model = _noise_model(noise)

    def rows():  # [S_V, the offset's column over the second half], block by block (S_V is not held whole), in
        for sl, S_b, y_b in raw.blocks():  # time order, whitened by the fit's noise model where it has one
            c = S_b[:, :, j]
            seen[sl] = np.sum(c**2, axis=1)
            yield sl, np.concatenate([S_b, (c * late[sl, None])[:, :, None]], axis=2), y_b

    def whitened():
        return rows() if model is None else whiten_blocks(rows(), t, model)

    red = reduce_qr_blocks(((S_b, y_b) for _, S_b, y_b in whitened()), len(names) + 1)
    if not (np.sum(seen[late]) > 0 and np.sum(seen[~late]) > 0):
        return None
    ra = analyze_rank(red)  # the project's rank rule (max(m, n) eps of the largest singular value)
    V_r, s_inv = ra.pinv_factors()
    inv = V_r * s_inv  # R^+ = V_r diag(1/s_r) U_r^T, scaled coordinates
    z = inv @ (ra.U[:, : ra.rank].T @ red.qty)
    x = np.where(red.scale > 0, z / np.where(red.scale > 0, red.scale, 1.0), 0.0)  # natural units
    r = np.empty_like(y)
    for sl, S_b, y_b in whitened():  # the residuals, in time order (their AR(1) long-run factor: 1 when whitened)
        r[sl] = y_b - S_b @ x
    long_run = 1.0 if model is not None else float(ar1_long_run_factor(np.sum(r[1:] * r[:-1]), np.sum(r[:-1] ** 2)))
    var = float(np.sum(r**2)) / max(r.size - ra.rank, 1) * long_run
    std_x = math.sqrt(var * float(np.sum(inv[-1] ** 2))) / red.scale[-1]  # sqrt((R^T R)^+_nn), natural unit
    to_ms = float(problem.si_factors[j]) * 1e3  # the coefficient's unit in ms
    first, diff, std = x[j] * to_ms, x[-1] * to_ms, std_x * to_ms
    t1, t2 = (float(np.sum(seen[k] * t[k]) / np.sum(seen[k])) for k in (~late, late))
    out = {"first_ms": float(first), "second_ms": float(first + diff), "difference_ms": float(diff),
           "std_ms": float(std), "t_first_s": t1, "t_second_s": t2,
           "ppm": float(diff / (t2 - t1) * 1e3), "std_ppm": float(std / (t2 - t1) * 1e3)}
    _warn_drift(source, out["ppm"], out["std_ppm"],
                f", the fit's time offset {first:.3g} ms over its first half (seen at t = {t1:.4g} s) and "
                f"{first + diff:.3g} ms over its second (t = {t2:.4g} s), differing by {diff:.3g} +- {std:.2g} ms")
    return out


def _noise_model(noise: dict | None):
    """The :class:`casep.noise.model.NoiseModel` of a fit's ``diagnostics["noise"]`` record, or None without one."""
    from casep.noise.model import NoiseModel

    if not isinstance(noise, dict) or "axes" not in noise:
        return None
    try:
        return NoiseModel.from_dict(noise)
    except (KeyError, TypeError, ValueError):
        return None


def clock_drift_record(flight: FlightData, residual: np.ndarray) -> dict | None:
    """:func:`fit_clock_drift` as ``diagnostics["clock_drift"]`` records it: ``ppm``, ``std_ppm`` (None where not
    measured), ``on`` and, where the drift is not measured, ``why_not`` (:func:`clock_drift_unmeasured`); None
    where :func:`fit_clock_drift` gives None (no clock of its own)."""
    drift = fit_clock_drift(flight, residual)
    if drift is None:
        return None
    record: dict = {"ppm": drift[0] if math.isfinite(drift[0]) else None,
                    "std_ppm": drift[1] if math.isfinite(drift[1]) else None, "on": "the fit's residuals"}
    if record["ppm"] is None:
        acc = _acceleration(flight)
        idx = np.flatnonzero(flight.observed)
        why = clock_drift_unmeasured(flight.t[idx], acc[idx]) if acc is not None else "no telemetry acceleration"
        record["why_not"] = why or "the windows' offsets do not give a line"  # said, not warned: a short or quiet
        # flight (the shipped 40 s examples) cannot show a drift, which is no sign of anything wrong
    return record


def _warn(source: str, s: TrackingScreen, stale: str, rejected: str, drift: bool = True, excursions: str = "") -> None:
    """The screen's TrackingQualityWarnings (`stale`, `rejected`, `excursions`: the runs located in the file; the clock
    drift unless `drift` is False: a fit follows, whose residuals :func:`fit_clock_drift` measures it on)."""
    if s.stale:
        n = _span_epochs(s.stale)
        warnings.warn(TrackingQualityWarning(
            f"{source}: {n} stale tracking epochs (a fix or its velocity repeated, or held within "
            f"{HELD_SHARE:g} of the telemetry's change, while the telemetry moved by more than {STALE_MOTION:g} m/s "
            f"since it, or a position repeated while the telemetry moved away from it by more than "
            f"{STALE_POSITION:g} m + {STALE_MOTION:g} m/s x the time since it) left out, in {len(s.stale)} span(s): "
            f"{stale}"), stacklevel=3)
    if s.rejected:
        n = _span_epochs(s.rejected)
        warnings.warn(TrackingQualityWarning(
            f"{source}: {n} tracking epochs fail the physics check against the telemetry (velocity jumps up to "
            f"{s.largest_jump_m_s:.4g} m/s, beyond {JUMP_TOL:g} m/s + {JUMP_RATE:g} m/s^2 x the time between epochs, "
            f"in stretches shorter than {MIN_SEGMENT_S:g} s) and are left out: {rejected}"), stacklevel=3)
    if s.excursions:
        n = _span_epochs(s.excursions)
        warnings.warn(TrackingQualityWarning(
            f"{source}: {n} tracking epochs in {len(s.excursions)} span(s) are off the telemetry's course: the "
            f"velocity difference jumps away (by up to {s.largest_excursion_m_s:.3g} m/s, beyond {EXCURSION_SIGMAS:g} "
            "robust sigma of its epoch-to-epoch change in the stretch) and back within "
            f"{MIN_SEGMENT_S:g} s, a motion the IMU rules out (the physics check at the tracking's noise); they are "
            f"wrong epochs and left out: {excursions}"), stacklevel=3)
    if drift:
        _warn_drift(source, s.drift_ppm, s.drift_std_ppm, "")
    noise = [x for x in s.stretches if x[3] > 0]
    if len(noise) > 1 and max(x[3] for x in noise) > NOISE_RATIO * min(x[3] for x in noise):
        ratio = max(x[3] for x in noise) / min(x[3] for x in noise)
        listed = ", ".join(f"{a:.10g}..{b:.10g} s ({n} epochs): {sd:.3g} m/s" for a, b, n, sd in noise)
        warnings.warn(TrackingQualityWarning(
            f"{source}: the tracking noise differs {ratio:.3g}-fold between stretches ({listed}; scatter of the "
            "epoch-to-epoch change of dv): one noise level per axis weights them alike, so the std of what the noisy "
            f"stretch determines are understated by up to {ratio:.3g} x; see `casep diagnose` for the combinations "
            "each stretch determines"), stacklevel=3)


def noise_problem(flight: FlightData) -> str | None:
    """The screen's finding that the tracking noise differs between stretches beyond NOISE_RATIO, or None."""
    screen = flight.meta.get("tracking_screen") if isinstance(flight.meta, dict) else None
    noise = [x for x in (screen or {}).get("stretches", []) if x[3] > 0]
    if len(noise) < 2:
        return None
    ratio = max(x[3] for x in noise) / min(x[3] for x in noise)
    if ratio <= NOISE_RATIO:
        return None
    listed = ", ".join(f"{a:.10g}..{b:.10g} s: {sd:.3g} m/s" for a, b, _, sd in noise)
    return f"the tracking noise differs {ratio:.3g}-fold between stretches ({listed})"


def imu_sample_noise(flight: FlightData, t_rows: np.ndarray) -> tuple[np.ndarray, float, np.ndarray] | None:
    """The IMU's white noise as :func:`imu_noise_effect` measures it: ``(s, h, samples)``, ``s`` (6,) the per-sample
    std of ``fb_x, fb_y, fb_z`` (m/s^2) and ``w_x, w_y, w_z`` (rad/s), ``h`` the sample step (s), ``samples`` the
    telemetry's own samples up to the last epoch of `t_rows`; None when the flight does not hold them.

    ``s`` is ``meta[IMU_NOISE_AT_REST]`` when given; else :func:`white_sample_std` of the samples, per column the
    pad's figure instead (``meta[IMU_NOISE_PAD]``, :func:`pad_white_std`, which ``casep separate --imu`` measures
    on its pad window) where the record's is above it beyond their sampling errors (:func:`_with_pad`: the record
    counts motion).

    A flight holds them when its velocity is a navigated telemetry's, ``v_tel``, integrated from its ``q, fb, w``
    (so it carries their noise): a telemetry paired with a tracking file (:func:`casep.io.pair.pair_flight`), or one
    file with ``v_tel_*`` and ``v_trk_*`` (:func:`casep.io.files.read_flight`: every row a telemetry sample). Not a
    file of ``dv_*`` (or a simulated flight): nothing says its dv was integrated from the samples beside it (a
    simulation's is the linear model's, its samples without noise)."""
    sig = flight.signals
    meta = flight.meta if isinstance(flight.meta, dict) else {}
    if not all(c in sig for c in ("q_w", "q_x", "q_y", "q_z", "fb_x", "w_x")) or t_rows.size == 0:
        return None
    if "rows_index" in meta:
        # the telemetry's own samples, a tracking epoch on one of them included (its columns are the file's); the
        # tracking epochs inserted between them, their columns interpolated, left out
        own = np.array(meta.get("telemetry_samples", np.asarray(meta["rows_index"]) < 0), dtype=bool)
    elif meta.get("dv") == ONE_FILE_TELEMETRY and meta.get("format") != "pair":
        own = np.ones(flight.t.size, dtype=bool)  # one file: its rows are the telemetry's samples
    else:
        return None
    if "ins_valid" in sig:
        own &= np.asarray(sig["ins_valid"]) > 0
    own &= flight.t <= t_rows[-1]
    i = np.flatnonzero(own)
    if i.size < 10:
        return None
    h = float(np.median(np.diff(flight.t[i])))
    given = flight.meta.get(IMU_NOISE_AT_REST) if isinstance(flight.meta, dict) else None
    if given is not None:
        return np.asarray(given, dtype=float), h, i
    raw = np.column_stack([sig[c][i] for c in IMU_NOISE_COLUMNS])
    return _with_pad(white_sample_std(raw), i.size, meta.get(IMU_NOISE_PAD))[0], h, i


def imu_noise_on_pad(flight: FlightData, t_rows: np.ndarray) -> list[str]:
    """The IMU columns whose per-sample std :func:`imu_sample_noise` took from the pad (``meta[IMU_NOISE_PAD]``,
    :func:`pad_white_std`) rather than from the record's own samples: those where the record's figure counts
    motion (:func:`_with_pad`); none without a pad's figure or with a figure given at rest."""
    meta = flight.meta if isinstance(flight.meta, dict) else {}
    pad = meta.get(IMU_NOISE_PAD)
    if not pad or meta.get(IMU_NOISE_AT_REST) is not None:
        return []
    got = imu_sample_noise(flight, t_rows)
    if got is None:
        return []
    raw = np.column_stack([flight.signals[c][got[2]] for c in IMU_NOISE_COLUMNS])
    return [c for c, p in zip(IMU_NOISE_COLUMNS, _with_pad(white_sample_std(raw), got[2].size, pad)[1]) if p]


def _with_pad(record: np.ndarray, n: int, pad: dict | None) -> tuple[np.ndarray, np.ndarray]:
    """``(s, from the pad (6,) bool)``: per column the record's figure `record` (:func:`white_sample_std` of its `n`
    samples), or the pad's (``{"std", "rel_error"}``, :func:`pad_white_std`) where that is below the record's by
    more than :data:`NOISE_SWITCH_SIGMAS` of the two figures' relative sampling errors combined: there the record
    counts motion the pad does not have (a smooth motion's differences fall with their order, so the record's rises
    above the pad's through a motion rough up to the Nyquist frequency, a vibration the IMU measures correctly among
    them, or through a noise that grew in flight: the differences cannot tell the two apart, and a sensor whose own
    noise grows under vibration is then understated by the ratio); elsewhere the record's, from more samples."""
    if not pad:
        return record, np.zeros(record.shape, dtype=bool)
    s_pad, e_pad = np.asarray(pad["std"], dtype=float), np.asarray(pad["rel_error"], dtype=float)
    e = np.hypot(e_pad, white_std_error(n))
    below = s_pad < record * (1.0 - NOISE_SWITCH_SIGMAS * e)
    return np.where(below, s_pad, record), below


#: A per-sample std measured at or below this share of its column's largest magnitude is the samples' rounding, not
#: an instrument's noise: a real IMU's is above 1e-6 of its range (a navigation-grade unit at 100 Hz: ~3e-6 rad/s of a
#: 1 rad/s rate, ~5e-4 m/s^2 of 50 m/s^2), a noise-free record's second differences are its values' rounding (1e-16).
NOISE_RESOLUTION_SHARE = 1e-9
#: The IMU columns of :func:`imu_sample_noise`'s ``s``, in its order.
IMU_NOISE_COLUMNS = ("fb_x", "fb_y", "fb_z", "w_x", "w_y", "w_z")


def imu_noise_beside_bound(flight: FlightData, t_rows: np.ndarray) -> str | None:
    """What a bound of the tracking noise alone (``casep diagnose``) leaves out of a telemetry that holds its IMU's
    samples: a line with the IMU's white noise as measured (:func:`imu_sample_noise`), which ``casep separate``
    carries in its std (its velocity and attitude random walks); None without the samples or where the record shows
    no IMU noise above its rounding (:func:`unresolved_noise`)."""
    measured = imu_sample_noise(flight, t_rows)
    if measured is None:
        return None
    s, _, samples = measured
    shown = [c for c in IMU_NOISE_COLUMNS if c not in unresolved_noise(flight, s, samples)]
    if not shown:
        return None
    acc, gyr = s[:3], s[3:]
    return (f"the bound holds the tracking noise only: the IMU's own noise, measured on this telemetry's samples "
            f"(per sample up to {float(np.max(acc)):.3g} m/s^2 and {float(np.max(gyr)):.3g} rad/s; "
            f"{', '.join(shown)}), is not in it; `casep separate` carries it in its std, which can be larger")


def unresolved_noise(flight: FlightData, s: np.ndarray, samples: np.ndarray) -> list[str]:
    """The IMU columns whose per-sample std `s` measured on `samples` (:func:`imu_sample_noise`) is at or below
    :data:`NOISE_RESOLUTION_SHARE` of the column's largest magnitude there: the record does not show their noise
    (noise-free, held or smoothed samples, or most of them at rest without noise), which is then not measured."""
    sig = flight.signals
    return [c for c, v in zip(IMU_NOISE_COLUMNS, s)
            if not v > NOISE_RESOLUTION_SHARE * float(np.max(np.abs(np.asarray(sig[c])[samples]), initial=0.0))]


#: A flight's ``meta`` key: the IMU's white noise per sample (6: ``fb_x, fb_y, fb_z`` m/s^2, ``w_x, w_y, w_z``
#: rad/s) measured at rest by :func:`rest_white_std`, which :func:`imu_sample_noise` then takes instead of the
#: record's own second differences.
IMU_NOISE_AT_REST = "imu_white_std_at_rest"
#: Averaging time at which :func:`rest_white_std` reads the noise density, s.
REST_TAU_S = 1.0


def rest_white_std(x: np.ndarray, h: float, tau: float = REST_TAU_S) -> np.ndarray:
    """Per-column std per sample of the white noise that integrates into the random walks, measured on samples
    `x` (n, k) at rest (step `h`, s): the overlapping Allan deviation at `tau` (at most a tenth of the span)
    times ``sqrt(tau / h)`` (white noise of std ``s`` per sample has ``adev(tau) = s sqrt(h / tau)``).

    :func:`white_sample_std` reads every sample-to-sample change as noise: vibration near the Nyquist
    frequency (an engine, a road: real motion, or aliased, but zero-mean within a tenth of a second) then
    counts as a white density that it is not, and the random walks it makes are too large by the ratio. At
    `tau` the vibration is averaged out and what is left is the density a window of seconds integrates. A
    noise whose Allan deviation still falls beyond `tau` (vibration slower than `tau`) is overstated, one
    that rises (flicker, a bias that wanders) is not a white density at all: neither is made smaller here.
    """
    from casep.noise.identification import allan_deviation, avar_white

    x = np.asarray(x, dtype=float)
    if x.ndim != 2 or x.shape[0] < 20 or not np.all(np.isfinite(x)) or not (np.isfinite(h) and h > 0):
        raise ValueError(f"rest_white_std: `x` must be (n >= 20, k) finite samples and `h` > 0 s, got shape "
                         f"{x.shape} and h = {h}")
    tau = float(min(tau, x.shape[0] * h / 10.0))
    adev = np.array([allan_deviation(x[:, c], h, np.array([tau]))[1][0] for c in range(x.shape[1])])
    return adev / math.sqrt(float(avar_white(np.array([tau]), h, 1.0)[0]))  # adev of unit white noise at tau


def white_sample_std(x: np.ndarray) -> np.ndarray:
    """Per-column std of the white noise on the samples `x` (n, k) beside a motion: per difference order ``k`` in
    :data:`NOISE_DIFF_ORDERS` the robust scatter of the k-th differences over their noise gain,
    ``MAD(d_k) * 1.4826 / sqrt(C(2k, k))`` (white noise of std s gives ``var(d_k) = C(2k, k) s^2``: 6 s^2 for the
    second), and of those the least.

    Each order reads the noise plus what the motion leaves in its differences (an independent symmetric addition
    never makes the scatter of a Gaussian smaller), so the least is the closest bound: the k-th difference of a
    smooth motion is about ``h^k x^(k)``, a motion at frequency ``nu`` shrinks by ``2 sin(pi nu h)`` per order
    against the noise's gain, so one well below the Nyquist frequency is gone by the sixth where it filled the
    second (a 2 Hz, 1 rad/s roll rate at 100 Hz: 6e-3 rad/s in the second differences, 1e-7 in the sixth). On a
    white noise every order reads alike (the least of the five: 1-1.5 % below the second's figure on 3000-24000
    samples, within its sampling error, :func:`white_std_error`; 4.4 % below the noise on 181, against an error of
    11 %). A motion as rough as the noise up to the Nyquist
    frequency (broadband vibration the IMU measures correctly, an engine's, a road's, a profile's jitter sampled at
    its own rate) falls no faster than the noise and stays in every order: it is read as noise (the std then too
    large, not too small); only a record at rest tells it apart (:func:`pad_white_std`)."""
    x = np.asarray(x, dtype=float)
    out = np.full(x.shape[1:], np.inf)
    for k in NOISE_DIFF_ORDERS:
        if x.shape[0] <= k:
            break
        d = np.diff(x, k, axis=0)
        out = np.minimum(out, np.median(np.abs(d - np.median(d, axis=0)), axis=0) * MAD_SIGMA
                         / math.sqrt(math.comb(2 * k, k)))
    return out


#: The difference orders :func:`white_sample_std` reads the white noise on (the least of their figures).
NOISE_DIFF_ORDERS = (2, 3, 4, 5, 6)
#: Relative sampling error of :func:`white_sample_std` on a white noise, times ``sqrt(n)`` (simulated: 1.3-1.55 on
#: 3000-24000 samples; the MAD's 1.17 on independent samples, more on the correlated differences).
WHITE_STD_ERROR = 1.5
#: A quieter figure (the pad's against the record's, the Allan deviation's against the differences') replaces the
#: other when below it by more than this many of their combined relative sampling errors.
NOISE_SWITCH_SIGMAS = 3.0
#: A flight's ``meta`` key: the IMU's white noise per sample measured on the pad declared at rest
#: (:func:`pad_white_std`: ``{"std": (6,), "rel_error": (6,), "span": (T1, T2)}``), which
#: :func:`imu_sample_noise` takes per column where the record's own figure counts motion (:func:`_with_pad`).
IMU_NOISE_PAD = "imu_white_std_pad"


def white_std_error(n: int) -> float:
    """The relative sampling error of :func:`white_sample_std` on `n` samples of a white noise
    (:data:`WHITE_STD_ERROR` over ``sqrt(n)``)."""
    return WHITE_STD_ERROR / math.sqrt(max(n, 1))


def allan_white_error(n: int, h: float, tau: float = REST_TAU_S) -> float:
    """The relative sampling error of :func:`rest_white_std` on `n` samples of step `h` of a white noise:
    ``1 / sqrt(2 edf)``, ``edf = 3 (N - 1) / (2 m) - 2 (N - 2) / N`` (the overlapping Allan variance's equivalent
    degrees of freedom for a white rate noise, ``N = n + 1`` points, ``m = tau / h``; simulated: 0.19-0.21 on
    10 averaging times, 0.11 on 29; this formula: 0.196 and 0.110)."""
    tau = float(min(tau, n * h / 10.0))
    N, m = n + 1, max(tau / h, 1.0)
    edf = max(3.0 * (N - 1) / (2.0 * m) - 2.0 * (N - 2) / N, 1.0)
    return 1.0 / math.sqrt(2.0 * edf)


def pad_white_std(x: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """The IMU's white noise per sample measured on samples `x` (n, 6) at rest on the pad (step `h`, s):
    ``(std, relative sampling error)`` per column.

    The pad has no trajectory, so its differences (:func:`white_sample_std`) read the sensors' noise, unless a
    vibration is there (an engine running: motion the IMU measures correctly, zero-mean within a tenth of a
    second): then the Allan deviation at :data:`REST_TAU_S` (:func:`rest_white_std`), which averages it out, lies
    below them. Per column the differences' figure, more precise (1.5 / sqrt(n) against about
    ``0.58 / sqrt(T / tau)``), unless the Allan deviation's is below it by more than :data:`NOISE_SWITCH_SIGMAS`
    of their combined errors: there the Allan deviation's."""
    x = np.asarray(x, dtype=float)
    d, a = white_sample_std(x), rest_white_std(x, h)
    e_d, e_a = white_std_error(x.shape[0]), allan_white_error(x.shape[0], h)
    vib = a < d * (1.0 - NOISE_SWITCH_SIGMAS * math.hypot(e_d, e_a))
    return np.where(vib, a, d), np.where(vib, e_a, e_d)


def imu_noise_effect(flight: FlightData, t_rows: np.ndarray, weights: np.ndarray,
                     levelling: tuple[tuple[float, float], np.ndarray] | None = None,
                     instability: tuple[float, float, float] | None = None,
                     noise: tuple[np.ndarray, float, np.ndarray] | None = None) -> np.ndarray | None:
    """``weights @ G`` (k, m): ``G`` (3M, m) the velocity errors ``dv`` at the M epochs `t_rows` (rows x, y, z per
    epoch) that the IMU's white noise makes, per unit of m independent standard normal variables
    (``Cov = G G^T``), seen through `weights` (k, 3M) (``G`` itself is never held: it grows with epochs times
    blocks); None when the flight does not hold the IMU's own samples (a strapdown telemetry pair: ``q_*``,
    ``fb_*``, ``w_*`` at its rows).

    The noise is the error model's own sensor error taken as white: per axis, a per-sample std ``s`` measured as
    the scatter of the differences of consecutive telemetry samples, the least over orders 2-6 of each order's
    scatter over its noise gain (:func:`white_sample_std`; first differences kept the motion's slope, and a
    noise-free 25 Hz record of a rolling flight read as 0.015 rad/s of gyro noise, 3.6e-4 rad/s with second
    differences; a 100 Hz boost with 1e-4 rad/s, 2e-3 m/s^2 of noise read as 1.1-1.3e-4 and 2.0-2.6e-3 from first
    differences, 1.01e-4 and 2.03-2.10e-3 from second), or the pad's figure where the record's counts motion
    (:func:`imu_sample_noise`), at the sample step ``h``. Over a block ``j`` of :data:`IMU_NOISE_BLOCK_S` (``n_j``
    samples, mean attitude ``C_j``) it is a constant error of std ``s h sqrt(n_j)`` integrated, so after the block,
    with ``phidot = -C delta_w`` and ``dv_dot = C delta_f + f x phi``::

        dv(t) += C_j diag(s_a h sqrt(n_j)) xi_j  -  [F(t) - F(t_j)] x C_j diag(s_g h sqrt(n_j)) xi'_j,

    ``F(t) = int f dt`` (navigation-frame specific force, ``F(t_j)`` its mean over the block: the sum over blocks
    then equals the integral ``int (t - tau)^2 dtau`` of a tilt random walk within ``t b^2 / 12``), ``xi``
    standard normal; a block counts at the epochs after its last sample. This is the random walk of
    velocity and of attitude that tracking noise does not hold: on a quiet pad the tilt's random walk under
    gravity is as large as what the tracking determines (simulated rocket: ``python benchmarks/rocket_rawlog.py``).

    With `levelling` (``((T1, T2), L)``: casep aligned the navigation on the pad over ``[T1, T2]``, from its
    first sample on, and ``L`` (3 x 3) is the start attitude error per unit of the window's mean body specific
    force error, the derivative of the alignment itself: ``u x (C delta_f) / g`` for levelling alone, with the
    heading's share where the heading constraint turns a tilt) the accelerometer noise there also tilts the
    start, ``phi0 = L mean(delta_f)``, which acts from the first sample on: ``dv(t) += (F(t) - F(T1)) x phi0``.
    A block's share of the window mean is its samples inside the window (a block cut by ``T2``: within one
    block's noise). A gyrocompassed heading's gyro noise is not carried.

    With `instability` (``(tau, q_a, q_g)``: the IMU's bias instability of :func:`imu_bias_effect`, correlation time
    ``tau`` s, variances ``q_a`` (m/s^2)^2 and ``q_g`` (rad/s)^2 per body axis) its columns follow the white noise's:
    ``G = [G_white, sqrt(q_a) G_a, sqrt(q_g) G_g]``.

    `noise`: :func:`imu_sample_noise` of `flight` and `t_rows` when the caller measured it already (None: measured
    here).
    """
    terms = _imu_noise_blocks(flight, t_rows, levelling, noise)
    if terms is None:
        return None
    W = np.asarray(weights, dtype=float).reshape(-1, t_rows.size, 3)
    out = _seen_blocks(terms, t_rows, W, terms.ga, terms.gg)
    if terms.level is not None:
        win, Phi, F0 = terms.level  # blocks in the window, phi0 per unit xi (bw, 3, 3), F at the window's start
        dF = terms.F_rows - F0  # (M, 3): phi0 acts from the start on
        G = np.cross(dF[:, None, :, None], Phi[None], axisa=2, axisb=2, axisc=2)  # (M, bw, 3 axes, 3 xi)
        out[:, win, :3] += np.einsum("kmi,mbij->kbj", W, G)
    white = out.reshape(W.shape[0], -1)
    if instability is None:
        return white
    tau, q_a, q_g = instability
    E_a, E_g = _bias_columns(terms, t_rows, W, tau)
    return np.column_stack([white, math.sqrt(q_a) * E_a, math.sqrt(q_g) * E_g])


def _seen_blocks(terms: "_ImuBlocks", t_rows: np.ndarray, W: np.ndarray, ga: np.ndarray, gg: np.ndarray
                 ) -> np.ndarray:
    """``(k, B, 6)``: the velocity errors at the epochs that each block's accelerometer (``ga``, B x 3 x 3) and gyro
    (``gg``) error per unit ``xi`` make, seen through `W` (k, M, 3) (:func:`imu_noise_effect`)."""
    # Block b counts at the epochs r with t_end_b <= t_r; with dF = F_r - F_mid_b (the attitude error acts from the
    # block's middle on) its column j is ga_b[:, j] and -dF x gg_b[:, j], seen through W_r: W_r . (dF x g) =
    # g . (W_r x dF). Summed over those epochs: Ws_b = sum W_r, Xs_b = sum W_r x F_r (suffix sums over the epochs in
    # time order), so out[b] = ga_b^T Ws_b and -gg_b^T (Xs_b - Ws_b x F_mid_b): every epoch once, not once per block.
    order = np.argsort(t_rows, kind="stable")
    Wo = W[:, order]
    Xo = np.cross(Wo, terms.F_rows[order][None], axis=2)
    zero = np.zeros((W.shape[0], 1, 3))
    Ws = np.concatenate([np.cumsum(Wo[:, ::-1], axis=1)[:, ::-1], zero], 1)  # [:, i]: the epochs from the i-th on
    Xs = np.concatenate([np.cumsum(Xo[:, ::-1], axis=1)[:, ::-1], zero], 1)
    first = np.searchsorted(np.asarray(t_rows, dtype=float)[order], terms.t_end, side="left")
    Wb, Xb = Ws[:, first], Xs[:, first]  # (k, B, 3)
    return np.concatenate([np.einsum("kbi,bij->kbj", Wb, ga),
                           -np.einsum("kbi,bij->kbj", Xb - np.cross(Wb, terms.F_mid[None], axis=2), gg)], 2)


#: A flight's ``meta`` key: the correlation time (s) of the IMU's bias instability (:func:`imu_bias_effect`), whose
#: size the tracking noise's refit beside the IMU's noise then fits (:func:`casep.noise.known.fit_tracking`); absent:
#: the IMU's noise is white only.
IMU_INSTABILITY_TAU = "imu_instability_tau_s"
#: A flight's ``meta`` key: the two variances ``(q_a, q_g)`` ((m/s^2)^2, (rad/s)^2) of the bias instability of
#: :data:`IMU_INSTABILITY_TAU`, given rather than fitted (a size pooled over a run's windows:
#: :func:`casep.noise.known.pool_parts`); the tracking noise is then refitted beside the IMU's noise at them.
IMU_INSTABILITY_SIZE = "imu_instability_variances"
#: A flight's ``meta`` key: a list to which the tracking noise's refit beside the IMU's noise appends the rows of its
#: restricted likelihood (:class:`casep.noise.known.RemlRows`: the IMU's known noise with the instability's parts
#: unscaled), for a size pooled over several records (:func:`casep.noise.known.pool_parts`).
IMU_REML_ROWS = "imu_reml_rows"


def imu_bias_effect(flight: FlightData, t_rows: np.ndarray, weights: np.ndarray, tau: float
                    ) -> tuple[np.ndarray, np.ndarray] | None:
    """The IMU's bias instability seen through `weights` (k, 3M): ``(G_a, G_g)``, each (k, 3B), the velocity errors at
    the epochs `t_rows` per unit variance of a first-order Gauss-Markov bias per body axis of the accelerometers and
    the gyros (``Cov = q_a G_a G_a^T + q_g G_g G_g^T``); None when the flight does not hold the IMU's samples.

    The bias ``b`` (body axes) is stationary with variance ``q`` and correlation time `tau`, held over each block of
    :func:`imu_noise_effect` (``b_j`` at the block's mean time ``t_j``): ``b_0 ~ N(0, q)``, ``b_j = a_j b_(j-1) +
    w_j``, ``a_j = exp(-(t_j - t_(j-1)) / tau)``, ``Var w_j = q (1 - a_j^2)``. A block's bias is an error of the
    sensor held for its ``n_j`` samples, so it enters as the white noise's does with ``s h sqrt(n_j)`` replaced by
    ``h n_j`` (``dv_dot = C delta_f + f x phi``, ``phidot = -C delta_w``)::

        dv(t) = sum_j E_j b_j,   E_j = C_j h n_j (accelerometer),  -[F(t) - F(t_j)] x C_j h n_j (gyro)

    and with ``b_j = sum_(l <= j) (a_(l+1) .. a_j) w_l`` the columns of ``w_l`` per unit std are
    ``R_l sqrt(1 - a_l^2)`` (``R_l = E_l + a_(l+1) R_(l+1)``, a backward recursion over the blocks; ``a_0 = 0``).
    A white bias (``tau`` below the block) is the white noise's, a constant one (``tau`` beyond the record) the
    model's bias itself: the estimate's bias absorbs it, and its variance ``q`` is then the estimate's."""
    terms = _imu_noise_blocks(flight, t_rows, None)
    if terms is None:
        return None
    W = np.asarray(weights, dtype=float).reshape(-1, t_rows.size, 3)
    return _bias_columns(terms, t_rows, W, tau)


def _bias_columns(terms: "_ImuBlocks", t_rows: np.ndarray, W: np.ndarray, tau: float) -> tuple[np.ndarray, np.ndarray]:
    """:func:`imu_bias_effect`'s ``(G_a, G_g)`` on the blocks `terms`."""
    if not (np.isfinite(tau) and tau > 0):
        raise ValueError(f"the IMU's bias instability needs a correlation time > 0 s, got {tau}")
    E = _seen_blocks(terms, t_rows, W, terms.unit, terms.unit)  # (k, B, 6) per unit bias held over the block
    a = _bias_transitions(terms.t_mid, tau)
    R = np.empty_like(E)
    R[:, -1] = E[:, -1]
    for j in range(E.shape[1] - 2, -1, -1):
        R[:, j] = E[:, j] + a[j + 1] * R[:, j + 1]
    R *= np.sqrt(1.0 - a**2)[None, :, None]
    return R[:, :, :3].reshape(W.shape[0], -1), R[:, :, 3:].reshape(W.shape[0], -1)


def _bias_transitions(t_mid: np.ndarray, tau: float) -> np.ndarray:
    """``a_j`` (B,) of :func:`imu_bias_effect`: ``exp(-(t_j - t_(j-1)) / tau)``, ``a_0 = 0`` (the stationary start)."""
    return np.concatenate([[0.0], np.exp(-np.diff(t_mid) / tau)])


@dataclass(frozen=True)
class _ImuBlocks:
    """The blocks of :func:`imu_noise_effect`: their last sample's time ``t_end`` (B,), the velocity error ``ga``
    (B, 3, 3) and attitude error ``gg`` (B, 3, 3) per unit xi, ``F`` at the block's middle ``F_mid`` (B, 3), ``F``
    at the epochs ``F_rows`` (M, 3), the levelling's ``(window mask (B,), Phi (bw, 3, 3), F(T1))`` or None."""

    t_end: np.ndarray
    ga: np.ndarray
    gg: np.ndarray
    F_mid: np.ndarray
    F_rows: np.ndarray
    level: tuple | None
    unit: np.ndarray  # (B, 3, 3): C_j h n_j, the velocity (attitude) error per unit bias held over the block
    t_mid: np.ndarray  # (B,): the blocks' mean sample times


def _imu_noise_blocks(flight: FlightData, t_rows: np.ndarray, levelling: tuple | None,
                      noise: tuple[np.ndarray, float, np.ndarray] | None = None) -> _ImuBlocks | None:
    """The IMU noise's blocks (:func:`imu_noise_effect`; `noise` :func:`imu_sample_noise`'s, measured here when None);
    None when the flight does not hold the IMU's samples."""
    from casep.rotations import quat_to_dcm

    noise = imu_sample_noise(flight, t_rows) if noise is None else noise
    if noise is None:
        return None
    s, h, i = noise
    sig = flight.signals
    t = flight.t[i]
    C = quat_to_dcm(np.column_stack([sig[f"q_{a}"][i] for a in "wxyz"]))
    f = flight.f[i]
    F = cumulative_trapezoid(f, t)
    block = np.floor((t - t[0]) / IMU_NOISE_BLOCK_S).astype(int)
    nb = int(block[-1]) + 1
    counts = np.bincount(block, minlength=nb)
    used = np.flatnonzero(counts)
    C_sum = np.stack([np.bincount(block, C[:, r, c], nb) for r in range(3) for c in range(3)], 1).reshape(nb, 3, 3)
    Cj = C_sum[used] / counts[used, None, None]
    t_end = t[np.cumsum(counts)[used] - 1]  # the blocks' last samples (t increases)
    F_mid = np.stack([np.bincount(block, F[:, a], nb)[used] for a in range(3)], 1) / counts[used, None]
    n_eff = _block_samples(t, counts, used, h)
    root = h * np.sqrt(n_eff)[:, None, None]
    F_rows = np.column_stack([np.interp(t_rows, t, F[:, a]) for a in range(3)])
    level = None if levelling is None else _levelling_noise(t, F, block, (nb, used, n_eff), s[:3], levelling)
    t_mid = np.bincount(block, t, nb)[used] / counts[used]
    return _ImuBlocks(t_end, Cj * s[:3] * root, Cj * s[3:] * root, F_mid, F_rows, level,
                      Cj * (h * n_eff)[:, None, None], t_mid)


def _skew(v: np.ndarray) -> np.ndarray:
    """``[v x]`` (..., 3, 3) of vectors (..., 3): ``[v x] u = v x u``."""
    out = np.zeros(v.shape + (3,))
    out[..., 0, 1], out[..., 0, 2], out[..., 1, 2] = -v[..., 2], v[..., 1], -v[..., 0]
    out[..., 1, 0], out[..., 2, 0], out[..., 2, 1] = v[..., 2], -v[..., 1], v[..., 0]
    return out


def imu_noise_states(flight: FlightData, t_rows: np.ndarray, levelling: tuple | None = None,
                     instability_tau: float | None = None):
    """The noise of :func:`imu_noise_effect` at the epochs `t_rows` as a linear state
    (:class:`casep.noise.known.KnownStates`; the same ``Cov = G G^T``, exactly); None when the flight does not hold
    the IMU's samples.

    The state is ``z = (V, Phi, Psi, phi0, R)``: the velocity random walk ``V = sum ga_j xi_j``, the attitude random
    walk ``Phi = sum gg_j xi'_j`` and ``Psi = sum F_j x gg_j xi'_j`` over the blocks ended by the epoch (``F_j`` the
    block's middle), so that ``- sum (F(t) - F_j) x gg_j xi'_j = -F(t) x Phi + Psi``; the levelling's start tilt
    ``phi0 = sum_w Lv_w xi_w`` over the window's blocks (with `levelling`), and ``R`` the part of ``phi0`` the
    blocks not yet ended still hold. The rows' map::

        H_r = [I,  -[F_r x],  I,  [(F_r - F(T1)) x],  0]

    ``phi0`` acts from the first epoch on, before the window's accelerometer noise that makes it has ended in
    ``V``: the blocks are drawn given it (a Gaussian bridge). With ``Sigma_j = sum_(w >= j) Lv_w Lv_w^T`` (the
    window's blocks not yet ended), ``R`` starts at ``phi0`` (prior ``Cov = Sigma_1`` for both) and block ``j``
    draws::

        xi_j = K_j R + e_j,   K_j = Lv_j^T Sigma_j^+,   Cov e_j = I - Lv_j^T Sigma_j^+ Lv_j,
        V += ga_j xi_j,       R -= Lv_j xi_j

    (the conditional law of ``xi_j`` given the rest of the sum: exact). ``T_r`` and ``Q_r`` compose the blocks
    ended in ``(t_(r-1), t_r]`` (for r = 0, up to ``t_0``).

    With `instability_tau` the bias instability of :func:`imu_bias_effect` (correlation time `instability_tau`, s)
    is carried too, its size left free: six more states, the biases ``b_a``, ``b_g`` (body axes) held over block
    ``j``, which add ``E_j b_j`` (``V += C_j h n_j b_a``, ``Phi += C_j h n_j b_g``, ``Psi += F_j x C_j h n_j b_g``)
    and then move on, ``b <- a_(j+1) b + w``. Their prior and noise are per unit variance, in the state's
    ``parts`` (``q_a``: the accelerometers', ``q_g``: the gyros'): :meth:`casep.noise.known.KnownStates.scaled`
    forms the covariance at given ``(q_a, q_g)``, exactly ``Sigma_white + q_a G_a G_a^T + q_g G_g G_g^T``.
    """
    from casep.noise.known import KnownStates

    terms = _imu_noise_blocks(flight, t_rows, levelling)
    if terms is None:
        return None
    B, M = terms.t_end.size, t_rows.size
    s0 = 9 if terms.level is None else 15
    s = s0 + (0 if instability_tau is None else 6)
    Lv = np.zeros((B, 3, 3))
    P0 = np.zeros((s, s))
    if terms.level is not None:
        win, Phi, F0 = terms.level
        Lv[np.flatnonzero(win)] = Phi
        Sig = np.cumsum((Lv @ np.swapaxes(Lv, 1, 2))[::-1], axis=0)[::-1]  # Sigma_j: the blocks from j on
        P0[9:15, 9:15] = np.tile(Sig[0], (2, 2))
    H = np.zeros((M, 3, s))
    H[:, :, :3] = np.eye(3)
    H[:, :, 3:6] = -_skew(terms.F_rows)
    H[:, :, 6:9] = np.eye(3)
    if terms.level is not None:
        H[:, :, 9:12] = _skew(terms.F_rows - F0)
    T, Q = np.tile(np.eye(s), (M, 1, 1)), np.zeros((M, s, s))
    parts: list[tuple[np.ndarray, np.ndarray]] = []
    if instability_tau is not None:
        a_b = np.append(_bias_transitions(terms.t_mid, instability_tau), 0.0)
        for k in range(2):  # the accelerometers' and the gyros' per unit variance: stationary prior, no noise yet
            P0_k = np.zeros((s, s))
            P0_k[s0 + 3 * k:s0 + 3 * k + 3, s0 + 3 * k:s0 + 3 * k + 3] = np.eye(3)
            parts.append((np.zeros((M, s, s)), P0_k))
    epoch = np.searchsorted(t_rows, terms.t_end, side="left")  # the first epoch at or after the block's end
    for j in range(B):
        r = int(epoch[j])
        if r >= M:
            break
        A, G = np.eye(s), np.zeros((s, 6))
        if instability_tau is not None:  # the block's bias acts, then moves on to the next block's
            A[:3, s0:s0 + 3] = terms.unit[j]
            A[3:6, s0 + 3:] = terms.unit[j]
            A[6:9, s0 + 3:] = _skew(terms.F_mid[j]) @ terms.unit[j]
            A[s0:, :] *= 0.0
            A[s0:, s0:] = a_b[j + 1] * np.eye(6)
        G[3:6, 3:] = terms.gg[j]
        G[6:9, 3:] = _skew(terms.F_mid[j]) @ terms.gg[j]
        if np.any(Lv[j]):
            Si = np.linalg.pinv(Sig[j])
            K = Lv[j].T @ Si
            e_cov = np.eye(3) - Lv[j].T @ Si @ Lv[j]
            lam, vec = np.linalg.eigh(0.5 * (e_cov + e_cov.T))
            root = vec * np.sqrt(np.clip(lam, 0.0, None))
            A[:3, 12:15] = terms.ga[j] @ K
            A[12:15, 12:15] -= Lv[j] @ K
            G[:3, :3], G[12:15, :3] = terms.ga[j] @ root, -Lv[j] @ root
        else:
            G[:3, :3] = terms.ga[j]
        T[r] = A @ T[r]
        Q[r] = A @ Q[r] @ A.T + G @ G.T
        for k, (Q_k, _) in enumerate(parts):
            w = np.zeros(s)
            w[s0 + 3 * k:s0 + 3 * k + 3] = 1.0 - a_b[j + 1] ** 2
            Q_k[r] = A @ Q_k[r] @ A.T + np.diag(w)
    return KnownStates(T, Q, H, P0, tuple(parts))


def _block_samples(t: np.ndarray, counts: np.ndarray, used: np.ndarray, h: float) -> np.ndarray:
    """The IMU samples each used block spans, ``(first sample of the next block - its first) / h`` (the last:
    to its last sample, plus one): the telemetry's own samples leave out those a tracking epoch took over
    (:func:`casep.io.pair.pair_flight` makes a tracking time on a telemetry sample that sample), whose noise the
    velocity integrated all the same."""
    first = t[np.concatenate([[0], np.cumsum(counts[used])[:-1]])]
    span = np.diff(np.append(first, t[-1] + h))
    return np.maximum(np.rint(span / h), counts[used])


def _levelling_noise(t: np.ndarray, F: np.ndarray, block: np.ndarray, blocks: tuple, s_a: np.ndarray,
                     levelling: tuple) -> tuple | None:
    """The start tilt the accelerometer noise in the levelling window leaves, per block and unit xi
    (:func:`imu_noise_effect`; `blocks`: their number, the used ones and the samples each spans):
    ``(blocks in the window (mask over used), Phi (bw, 3, 3), F(T1))``."""
    nb, used, n_eff = blocks
    window, L = levelling
    inside = (t >= window[0]) & (t <= window[1])
    if int(inside.sum()) < 2:
        return None
    frac = np.bincount(block[inside], minlength=nb)[used] / np.bincount(block, minlength=nb)[used]
    win = frac > 0
    n_w = float(np.sum(frac * n_eff))  # the IMU samples the window mean is over
    share = frac[win] * np.sqrt(n_eff[win]) / n_w  # the window mean's weight on the block's xi
    Phi = share[:, None, None] * (np.asarray(L, dtype=float) * s_a)[None]  # body axes of the mean: the pad's
    return win, Phi, F[int(np.argmax(inside))]


def determined(problem, stretches: list, scales: dict[str, float], top: int = 3,
               imu: FlightData | None = None, about: np.ndarray | None = None,
               consider: np.ndarray | None = None) -> tuple[list[dict], float]:
    """The combinations of coefficients the flight determines when each stretch is weighted by its own noise.

    Rows weighted by ``1 / sigma_s`` (the stretch's scatter, :func:`stretch_noise`; the largest for rows in no
    stretch), coefficients scaled by their declared magnitudes (``z_j = x_j / scale_j``):
    ``A = U diag(s) V^T``; combination ``c_i = V_i . z`` is estimated as ``U_i . y_w / s_i`` with std
    ``k / s_i``, ``k = sqrt(max(1, chi2 / dof))`` of the weighted fit (noise larger than the scatter says:
    the std grow with it). A combination is determined when its std is below 1 (its declared magnitude).

    The scatter of changes sees only the fast part of a stretch's noise: a receiver's Gauss-Markov error (seconds
    of correlation time) or a constant lag barely changes from one epoch to the next, yet counts as one error
    over many epochs. So the weighted fit is made twice: after the first, each stretch's ``sigma_s`` is
    multiplied by ``sqrt(kappa_s)``, ``kappa_s`` the AR(1) long-run variance factor of its residuals (largest
    axis, :func:`casep.noise.whiteness.ar1_long_run_factor`), and the combinations are those of the second.
    With `imu` (the flight, a strapdown telemetry pair) the IMU's own white noise, which the velocity integrates
    into a random walk, adds ``|| (U_i / (s_i sigma))^T G ||^2`` to each combination's variance (``G`` of
    :func:`imu_noise_effect` at the epochs ``problem.t``). On the simulated sounding rocket both matter
    (``python benchmarks/rocket_rawlog.py``, 24 flights): white weighting gave RMS z 1.45 (coverage 0.83), and
    1.12 with the IMU's noise taken out of the simulation; both carried, 1.16 (0.91), the rest the linear
    model's second order (biases / 10: 0.96, 0.97). With `consider` (N, 3, c: the rows' shift for one std of each
    consider parameter beside the fit, :func:`casep.workflows.imu_separate.consider_columns`: the given heading, the
    steps between samples and gaps of a raw IMU record, its clock's drift) each combination gains their variance
    ``|| (U_i / (s_i sigma))^T K ||^2`` as ``consider_var``, kept apart from ``std``: which combinations the flight
    determines, and their plausible size, are the record's (the consider terms are parameters beside the rows, as
    :func:`casep.workflows.imu_separate._with_consider_std` has it for the iterated passes); the caller adds it to
    the std stated (:func:`casep.workflows.judging.judge_tracking`).

    With `about` (natural units, the coefficients the problem was linearised about: the S_V and dv of an
    iterated pass, :mod:`casep.workflows.imu_separate`) ``problem.y`` is the residual left at `about`, so the
    fit estimates the combinations of ``D - about``: ``correction`` is that, ``estimate`` the total
    ``V_i . (about / scale) + correction`` (the same std).

    Returns
    -------
    combinations : list of dict
        ``terms`` (name -> weight on ``x / scale``: the `top` largest and those that matter at the plausible
        size, :func:`combination_terms`), ``more`` (how many terms the text leaves out), ``weights`` (all, model
        order),
        ``estimate``, ``std``, ``correction`` (the estimate less the combination of `about`); best first.
    k : float
        The std factor.
    """
    S, y, t = problem.sv(), problem.y, problem.t
    sig = stretch_sigma(problem, stretches, scales)
    scale = np.array([scales.get(nm, 1.0) for nm in problem.names])
    n = len(problem.names)
    U, sv, Vt, keep, z, r = _weighted_svd(S, y, sig, scale)
    yw = (y / sig[:, None]).reshape(-1)
    k = math.sqrt(max(1.0, float(r @ r) / max(yw.size - int(keep.sum()), 1)))
    extra = np.zeros(sv.size)
    seen = None if imu is None else imu_noise_effect(imu, t, (U[:, keep] / np.repeat(sig, 3)[:, None]).T)
    if seen is not None:  # the IMU noise's variance of each combination's estimate (U_i . y_w / s_i)
        extra[keep] = np.sum(seen**2, axis=1) / sv[keep] ** 2
    beside = None
    K = None if consider is None else np.asarray(consider, dtype=float)
    if K is not None and K.shape[:2] == y.shape:  # the consider parameters' variance, kept apart
        shift = (U[:, keep] / np.repeat(sig, 3)[:, None]).T @ K.reshape(y.size, -1)
        beside = np.zeros(sv.size)
        beside[keep] = np.sum(shift**2, axis=1) / sv[keep] ** 2
    base = np.zeros(n) if about is None else Vt @ (np.asarray(about, dtype=float) / scale)
    out = []
    for i in np.flatnonzero(keep):
        std = math.sqrt((k / sv[i]) ** 2 + extra[i])
        if std >= 1.0:
            continue
        sign = 1.0 if Vt[i, np.argmax(np.abs(Vt[i]))] >= 0 else -1.0
        out.append({"estimate": sign * float(base[i] + z[i]), "std": std, "weights": (sign * Vt[i]).tolist(),
                    "correction": sign * float(z[i])})
        if beside is not None:
            out[-1]["consider_var"] = float(beside[i])
    size = plausible_size(out)
    for c in out:
        c["terms"], c["more"] = combination_terms(problem.names, np.array(c["weights"]), c["std"], size, top)
    return out, k


#: A combination's text lists at most this many terms (:func:`combination_terms`); its weights are all in the JSON.
MAX_TERMS = 8


def plausible_size(combos: list[dict]) -> float:
    """The size, in declared magnitudes, a coefficient combination the flight does not determine plausibly has:
    the declared magnitude (1), or the largest determined combination's estimate when that is larger (the
    declared magnitudes then understate the instrument: a MEMS unit under a navigation-grade model). The text of a
    combination (:func:`combination_terms`) and the curvature of the undetermined part
    (:meth:`casep.workflows.imu_separate._Run.determined_curvature`) use it."""
    return max([1.0] + [abs(float(c["estimate"])) for c in combos])


def combination_terms(names: list[str], w: np.ndarray, std: float, size: float, top: int = 3) -> tuple[dict, int]:
    """The terms a combination ``sum_j w_j x_j / scale_j`` (estimated to `std`) is written with: its `top` largest,
    and every term that moves it by its std or more at the plausible `size` (``|w_j| size >= std``,
    :func:`plausible_size`), at most :data:`MAX_TERMS`; and how many terms of weight >= 0.005 are not written
    (a MEMS gyro bias of 500 declared magnitudes at weight 0.08 is 40 units of a combination known to 0.8)."""
    order = np.argsort(-np.abs(w))
    matter = int(np.sum(np.abs(w) * size >= std))
    shown = order[:min(max(top, matter), MAX_TERMS)]
    more = int(np.sum(np.abs(w[order[shown.size:]]) >= 0.005))
    return {names[m]: float(w[m]) for m in shown}, more


def stretch_sigma(problem, stretches: list, scales: dict[str, float]) -> np.ndarray:
    """The noise (m/s) of each epoch of `problem` the combinations of :func:`determined` are weighted by: the
    scatter of its stretch (the largest for epochs in no stretch), times ``sqrt(kappa_s)``, the AR(1) long-run
    variance factor of the stretch's residuals of the fit weighted by the scatter alone (:func:`determined`)."""
    from casep.noise.whiteness import ar1_long_run_factor

    t = problem.t
    noise = [x for x in stretches if x[3] > 0]
    sig = np.full(t.size, max(x[3] for x in noise))
    for a, b, _, sd in noise:
        sig[(t >= a) & (t <= b)] = sd
    scale = np.array([scales.get(nm, 1.0) for nm in problem.names])
    e = _weighted_svd(problem.sv(), problem.y, sig, scale)[5].reshape(-1, 3)
    for a, b, _, _sd in noise:  # the stretch's long-run variance: its sigma times sqrt(kappa)
        m = (t >= a) & (t <= b)
        es = e[m]
        kappa = ar1_long_run_factor(np.sum(es[1:] * es[:-1], axis=0), np.sum(es * es, axis=0))
        sig[m] *= math.sqrt(float(np.max(kappa)))
    return sig


def _weighted_svd(S: np.ndarray, y: np.ndarray, sig: np.ndarray, scale: np.ndarray) -> tuple:
    """The fit of ``y / sig`` on ``S / sig`` in the declared magnitudes: ``A = U diag(s) V^T``, the components kept
    (``s > 1e-12 s_max``), their estimates ``z_i = U_i . y_w / s_i`` and the weighted residual ``r``."""
    n = S.shape[2]
    A = (S / sig[:, None, None]).reshape(-1, n) * scale
    yw = (y / sig[:, None]).reshape(-1)
    U, sv, Vt = np.linalg.svd(A, full_matrices=False)
    keep = sv > sv[0] * 1e-12
    z = np.zeros(sv.size)
    z[keep] = (U[:, keep].T @ yw) / sv[keep]
    return U, sv, Vt, keep, z, yw - U[:, keep] @ (U[:, keep].T @ yw)


def determined_message(why: str, combos: list[dict], k: float, n: int, scales: dict[str, float]) -> str:
    """The failure message of a flight whose tracking noise differs between stretches (`why`, :func:`noise_problem`):
    what it determines (:func:`determined`: `combos`, std factor `k`) of its `n` coefficients."""
    said = "; ".join(" + ".join(f"{w:.2g} {nm}/{scales.get(nm, 1.0):g}" for nm, w in c["terms"].items())
                     + (f" (+ {c['more']} smaller terms)" if c.get("more") else "")
                     + f" = {c['estimate']:.3g} +- {c['std']:.2g}" for c in combos[:6])
    return (f"failed: {why}: one noise level per axis weights them alike, so the std of the coefficients are not "
            f"honest. Weighted by each stretch's own noise (std x {k:.3g} for the weighted fit's misfit), the flight "
            f"determines {len(combos)} of {n} combinations better than their declared magnitudes (coefficient / "
            f"declared magnitude)" + (f": {said}" if said else "") + ("; ..." if len(combos) > 6 else ""))

"""Plausibility checks on a flight and residual checks on a fit.

casep cannot see the units of a file, nor the time alignment of telemetry and tracking; a
unit mistake or a time-tag offset gives a confident, badly biased estimate. These checks
look for the signatures such mistakes leave and say so, with the numbers and the likely
cause: a :class:`~casep.exceptions.PlausibilityWarning` (or a subclass) for legal but
suspicious data, a :class:`~casep.io.flight.FlightDataError` for data that cannot be a boost
flight.

:func:`check_flight` (before estimation)
    - **Specific force** ``f``. Zero in every row: error (no powered flight, S_V = 0).
      Peak ``|f|`` above ``1e4 g``: error (no rocket boost exceeds ~100 g; gun-launch
      setbacks of 1e4 g last milliseconds and no platform INS flies through them). Peak
      below 1 g: warning; a vehicle needs ``f = T/m > 1 g`` to lift off, so a boost that
      includes lift-off always exceeds 1 g; a peak of a few units is the signature of ``f``
      in g (multiply by 9.80665). Peak above 100 g: warning (cm/s^2, mm/s^2?). ``f`` in
      ft/s^2 (factor 3.28) stays inside the plausible range and is *not* detectable.
    - **Time** ``t``. Median step below 1 us (above 1 MHz): error; no telemetry is sampled
      that fast (``t`` in 1e-12 s steps, or time in the wrong unit). Median step below
      0.1 ms (above 10 kHz) or above 1 s (below 1 Hz), or duration above 1 h: warning with
      the unit that would make it plausible (ms, us, min). A single step far below the
      median (a near-duplicate time tag): warning naming the row.
    - **Velocity gained** ``int |f| dt``: above 20 km/s (more than any rocket flight gives:
      orbit needs ~9.5 km/s with losses, escape ~12 km/s) is a warning; it catches ``t``
      in ms or ``f`` in the wrong unit when neither alone is conclusive.
    - **dv noise**: the sample-to-sample scatter of dv (robust, from second differences)
      above 5 m/s, far above radar or GNSS tracking noise (0.01-1 m/s): dv in cm/s or mm/s?
      dv in ft/s (factor 3.28) scales signal and noise alike and is *not* detectable from
      ``t, f, dv`` alone.
    - **Velocity columns** (files with ``v_tel_*``, ``v_trk_*``): the telemetered velocity
      change ``v_tel(end) - v_tel(0)`` against ``int (f + g) dt`` with the flat-Earth g of the
      launch frame (ratio 0.9986 on the ``paper`` boost); outside 0.8-1.25 is a warning with the
      unit that fits (ft/s gives 3.28, cm/s 100, km/s 0.001).

:func:`check_fit` (after estimation, on ``r = dv - S_V D_hat``)
    - **Noise-free data**: residual RMS at the rounding level of dv (below 1e-9 max |dv|):
      :class:`~casep.exceptions.NoiseFreeWarning`, the std reflect rounding only.
    - **Outliers**: a spike of size A at row k leaves ``d_k = r_k - (r_{k-1} + r_{k+1})/2 = A``
      while smooth model errors leave ``d ~ r'' dt^2 / 2``; rows where ``|d_k|`` exceeds
      10 robust (MAD) sigma of d and of r, and 1 cm/s, are named, with their size in noise sigma
      (``MAD(d) / sqrt(1.5)``: the sample-to-sample scatter, which the outlier's pull on the
      fit does not inflate). The check runs on the raw dv (after de-noising, the residuals of the
      thresholded dv are sparse and heavy-tailed, not noise).
    - **Tracking time offset**: see :func:`time_offset_test`.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from casep.analysis.linalg import reduce_qr_blocks
from casep.exceptions import (
    NoiseFreeWarning,
    NoiseLevelWarning,
    OutlierWarning,
    PlausibilityWarning,
    TimeOffsetWarning,
)
from casep.io.flight import FlightData, FlightDataError
from casep.units import G0

__all__ = ["check_flight", "check_fit", "check_sigma", "time_offset_test", "TimeOffsetTest", "GRAVITY_LAUNCH"]

#: Gravity in the launch-inertial (platform) frame, x downrange, y up: flat, uniform Earth.
GRAVITY_LAUNCH = np.array([0.0, -G0, 0.0])

# Specific force, m/s^2: a boost is ~1-30 g (1 g needed to lift off, ~100 g the hardest motors).
F_PEAK_LOW, F_PEAK_HIGH, F_PEAK_IMPOSSIBLE = G0, 100.0 * G0, 1e4 * G0
# Time: telemetry is sampled at 1 Hz .. 10 kHz; nothing is sampled at 1 MHz; boosts last < 1 h.
STEP_LOW, STEP_HIGH, STEP_IMPOSSIBLE, DURATION_HIGH = 1e-4, 1.0, 1e-6, 3600.0
DUPLICATE_STEP = 1e-3  # a step below this fraction of the median is a near-duplicate time tag
DW_HIGH = 2e4  # m/s: no rocket flight gains more than ~20 km/s of specific-force velocity
DV_NOISE_HIGH = 5.0  # m/s: tracking noise is 0.01-1 m/s
NOISE_FREE = 1e-9  # residual RMS / max |dv| at or below this: rounding only
OUTLIER_Z = 10.0  # robust sigma of the spike statistic; Gaussian P(|z| > 10) ~ 1.5e-23
OFFSET_T = 5.0  # |t| of the offset / jerk terms; Gaussian P(|t| > 5) ~ 6e-7
EFFECT_MIN = 1e-3  # m/s: RMS of a term's part outside span S_V below which it cannot matter against
#                   any tracking noise (keeps noise-free data, where every effect is "significant", quiet)
NOISE_FLOOR = 1e-3  # m/s: an outlier must exceed OUTLIER_Z times at least this (interpolation ripple
#                    of noise-free two-rate data at staging is ~1e-4 m/s)
MAD_SIGMA = 1.482602218505602  # sigma = MAD / Phi^-1(3/4) for Gaussian data


def _warn(message: str, category: type[Warning] = PlausibilityWarning) -> None:
    warnings.warn(message, category, stacklevel=3)


def _robust_sigma(x: np.ndarray) -> float:
    """``1.4826 * median |x - median x|``: sigma of the Gaussian bulk, blind to a few outliers."""
    return float(MAD_SIGMA * np.median(np.abs(x - np.median(x))))


def _spikes(x: np.ndarray) -> np.ndarray:
    """``d_k = x_k - (x_{k-1} + x_{k+1}) / 2`` along axis 0 (interior rows): a spike's signature."""
    return x[1:-1] - 0.5 * (x[:-2] + x[2:])


def _unit_hint(value: float, lo: float, hi: float, candidates: tuple[tuple[str, float], ...]) -> str:
    """The `candidates` (text, factor) that bring ``value * factor`` into ``[lo, hi]``."""
    fits = [text for text, k in candidates if lo <= value * k <= hi]
    return f" Is it {' or '.join(fits)}?" if fits else ""


# ----------------------------------------------------------------------------------- flight


def check_flight(flight: FlightData) -> None:
    """Check that a flight can be a boost flight in SI units; warn or raise otherwise.

    Parameters
    ----------
    flight : FlightData

    Raises
    ------
    FlightDataError
        Zero or impossibly large specific force; time steps below 1 us.

    Warns
    -----
    PlausibilityWarning
        Peak specific force, duration, sample rate, velocity gained or dv noise outside the
        range of boost flights, with the unit mistake that would explain it (module notes).
    """
    t, f = flight.t, flight.f
    _check_time(flight)
    peak = _check_force(flight)
    if t.size >= 2 and peak > 0:
        dW = float(np.sum(0.5 * (np.linalg.norm(f[1:], axis=1) + np.linalg.norm(f[:-1], axis=1)) * np.diff(t)))
        if dW > DW_HIGH:  # int |f| dt, trapezoid
            _warn(f"{flight.source}: the specific force integrates to {dW:.4g} m/s of velocity over "
                  f"{t[-1] - t[0]:.4g} s, more than any rocket gains (< {DW_HIGH:g} m/s): check the "
                  "units of t (s) and f (m/s^2).")
    _check_dv_noise(flight)
    _check_velocity_units(flight)


#: |v_tel(end) - v_tel(0)| / |int (f + g) dt| outside this range: the velocity columns and f
#: disagree on units. The flat-Earth g of :data:`GRAVITY_LAUNCH` makes the ratio 0.9986 on the
#: ``paper`` boost (195 s, 195 km downrange), so 20 % is a wide margin; ft/s gives 3.28.
VELOCITY_RATIO_RANGE = (0.8, 1.25)


def _check_velocity_units(flight: FlightData) -> None:
    """Compare the telemetered velocity change with the integral of f + g (files with v_tel)."""
    change = flight.meta.get("telemetry_velocity_change_m_s")
    t, f = flight.t, flight.f
    if change is None or t.size < 2:
        return
    a = f + GRAVITY_LAUNCH  # kinematic acceleration, flat-Earth gravity
    expected = np.sum(0.5 * (a[1:] + a[:-1]) * np.diff(t)[:, None], axis=0)  # trapezoid of a
    e, g = float(np.linalg.norm(expected)), float(np.linalg.norm(change))
    if e < 1.0:  # no velocity gained: nothing to compare
        return
    ratio = g / e
    lo, hi = VELOCITY_RATIO_RANGE
    if lo <= ratio <= hi:
        return
    hint = _unit_hint(ratio, lo, hi, (("ft/s (multiply v_tel and v_trk by 0.3048)", 0.3048),
                                      ("km/s (multiply by 1000)", 1e3), ("cm/s (divide by 100)", 1e-2),
                                      ("mm/s (divide by 1000)", 1e-3)))
    _warn(f"{flight.source}: the telemetered velocity changes by {g:.4g} m/s over {t[-1] - t[0]:.4g} s but "
          f"the specific force plus gravity integrates to {e:.4g} m/s (ratio {ratio:.3g}, expected "
          f"{lo:g}-{hi:g}): the velocity columns (v_tel_*, v_trk_*) and f disagree on units.{hint}")


def _force_columns(flight: FlightData) -> str:
    return "W_x, W_y, W_z (as dW/dt)" if flight.meta.get("force") == "W" else "f_x, f_y, f_z"


def _check_force(flight: FlightData) -> float:
    """Peak |f| in range, or warn / raise; returns the peak, m/s^2."""
    cols = _force_columns(flight)
    peak = float(np.max(np.linalg.norm(flight.f, axis=1)))
    if peak == 0.0:
        raise FlightDataError(flight.source, f"the specific force ({cols}) is zero in every row: "
                              "not a powered flight, nothing to estimate", cols.split(",")[0])
    if peak > F_PEAK_IMPOSSIBLE:
        hint = _unit_hint(peak, F_PEAK_LOW, F_PEAK_HIGH, (("cm/s^2", 1e-2), ("mm/s^2", 1e-3), ("um/s^2", 1e-6)))
        raise FlightDataError(flight.source, f"peak specific force {peak:.4g} m/s^2 ({peak / G0:.4g} g) is above "
                              f"{F_PEAK_IMPOSSIBLE / G0:.0e} g: not a boost flight in m/s^2.{hint}", cols.split(",")[0])
    if peak < F_PEAK_LOW:
        hint = " It looks like f in g: multiply by 9.80665." if peak * G0 >= F_PEAK_LOW else ""
        _warn(f"{flight.source}: peak specific force ({cols}) is {peak:.4g} m/s^2 ({peak / G0:.3g} g), below "
              f"the 1 g any vehicle needs to lift off (boosts reach ~1-30 g).{hint}")
    elif peak > F_PEAK_HIGH:
        hint = _unit_hint(peak, F_PEAK_LOW, F_PEAK_HIGH, (("cm/s^2 (divide by 100)", 1e-2),
                                                         ("mm/s^2 (divide by 1000)", 1e-3)))
        _warn(f"{flight.source}: peak specific force ({cols}) is {peak:.4g} m/s^2 ({peak / G0:.4g} g), above "
              f"the {F_PEAK_HIGH / G0:g} g of the hardest rocket motors.{hint}")
    return peak


def _check_time(flight: FlightData) -> None:
    """Median step and duration of a boost flight's telemetry, or warn / raise."""
    t = flight.t
    if t.size < 2:
        return
    steps = np.diff(t)
    h, T = float(np.median(steps)), float(t[-1] - t[0])
    figures = f"median time step {h:.4g} s ({1 / h:.4g} Hz), duration {T:.4g} s"
    if h < STEP_IMPOSSIBLE:
        raise FlightDataError(flight.source, f"{figures}: no telemetry is sampled above "
                              f"{1 / STEP_IMPOSSIBLE:.0e} Hz; is t in seconds?", "t")
    scales = (("ms (divide by 1000)", 1e-3), ("us (divide by 1e6)", 1e-6), ("ns (divide by 1e9)", 1e-9),
              ("min (multiply by 60)", 60.0), ("h (multiply by 3600)", 3600.0))
    if h < STEP_LOW or h > STEP_HIGH or T > DURATION_HIGH:
        # A unit that brings both the step and the duration into range.
        fits = [u for u, k in scales if STEP_LOW <= h * k <= STEP_HIGH and T * k <= DURATION_HIGH]
        hint = f" Is t in {' or '.join(fits)}?" if fits else ""
        _warn(f"{flight.source}: {figures}; telemetry of a boost is sampled at 1 Hz-10 kHz and lasts "
              f"less than {DURATION_HIGH:g} s.{hint}")
    k = int(np.argmin(steps))
    if steps[k] < DUPLICATE_STEP * h:
        _warn(f"{flight.source}: column `t`, row {k + 2}: time step {steps[k]:.3g} s from the previous row, "
              f"{h / steps[k]:.3g} times below the median step {h:.4g} s: a near-duplicate time tag?")


def _check_dv_noise(flight: FlightData) -> None:
    """Robust sample-to-sample scatter of dv against tracking noise."""
    if flight.n_observed < 5:
        return
    # White noise of sigma s gives Var(d_k) = 1.5 s^2; smooth dv contributes ~dv'' dt^2 / 2.
    noise = np.array([_robust_sigma(d) for d in _spikes(flight.dv[flight.observed]).T]) / np.sqrt(1.5)
    i = int(np.argmax(noise))
    if noise[i] > DV_NOISE_HIGH:
        hint = _unit_hint(noise[i], 1e-3, 1.0, (("cm/s (divide by 100)", 1e-2), ("mm/s (divide by 1000)", 1e-3)))
        _warn(f"{flight.source}: column `dv_{'xyz'[i]}`: sample-to-sample noise {noise[i]:.4g} m/s, far "
              f"above radar or GNSS tracking noise (0.01-1 m/s).{hint}")


# -------------------------------------------------------------------------------------- fit


@dataclass(frozen=True)
class TimeOffsetTest:
    """Augmented-regression test of the residuals for a tracking time offset and a jerk term.

    Attributes
    ----------
    offset, offset_std, offset_t : float
        Coefficient of ``a(t)`` (s; a tracking time offset dt_trk), its std and t-statistic.
    jerk, jerk_std, jerk_t : float
        Coefficient of ``da/dt`` (s^2), its std and t-statistic (NaN when not testable).
    offset_rms, jerk_rms : float
        RMS over the 3N rows of each term's part outside span S_V, m/s: its practical size.
    inflation : float
        Variance factor ``(1 + rho) / (1 - rho)`` for the residuals' lag-1 correlation.
    """

    offset: float
    offset_std: float
    offset_t: float
    jerk: float
    jerk_std: float
    jerk_t: float
    inflation: float
    offset_rms: float = 0.0
    jerk_rms: float = 0.0


def kinematic_acceleration(t: np.ndarray, f: np.ndarray) -> np.ndarray:
    """``a = f + g`` in the launch-inertial frame with uniform gravity :data:`GRAVITY_LAUNCH`, m/s^2.

    A flat-Earth approximation: true gravity falls by 3 % at 100 km altitude and turns by
    ~1 deg per 110 km of downrange; a few per cent of g is negligible against a boost's
    10-50 m/s^2 for detecting an offset (it only scales the offset estimate by ~1e-3).
    """
    return np.asarray(f, dtype=float) + GRAVITY_LAUNCH


def _row_blocks(S) -> tuple:
    """``(blocks(), n, nonzero)``: (row slice, S block (k, 3, n)) in time order, for an array or a Problem."""
    if _is_problem(S):
        return (lambda: ((sl, S_b) for sl, S_b, _ in S.blocks())), S.n, S.red.scale > 0
    S = np.asarray(S, dtype=float)
    N = S.shape[0]

    def blocks(rows: int = 16384):
        for s in range(0, N, rows):
            yield slice(s, min(s + rows, N)), S[s:s + rows]

    return blocks, S.shape[-1], np.any(S.reshape(-1, S.shape[-1]) != 0.0, axis=0)


def _is_problem(S) -> bool:
    """A :class:`casep.analysis.problem.Problem` (by its interface: problem.py imports this module)."""
    return hasattr(S, "blocks") and hasattr(S, "red") and hasattr(S, "has_rows")


def _shares_problem_test(S, dv: np.ndarray) -> bool:
    """Whether the residuals are those of S's own Problem (so its one time-offset test applies)."""
    return _is_problem(S) and S.y is not None and (dv is S.y or np.array_equal(dv, S.y))


def _problem_time_offset_test(problem, t: np.ndarray, f: np.ndarray):
    """:func:`time_offset_test`, once per Problem: by Frisch-Waugh-Lovell it depends on the residuals
    only through their part off span S, which is dv's whatever the estimate, so every method solved
    on one Problem (``casep demo``) shares one test."""
    if not hasattr(problem, "_time_offset_test"):
        problem._time_offset_test = time_offset_test(problem, problem.y, t, f)  # r -> dv: same projection
    return problem._time_offset_test


def time_offset_test(S: np.ndarray, r: np.ndarray, t: np.ndarray, f: np.ndarray) -> TimeOffsetTest | None:
    """Test residuals for a tracking time offset: ``r = S d + a(t) dt + (da/dt) c + e``.

    Tracking time tags late by dt give ``v_trk(t) = v(t - dt) ~ v(t) - a(t) dt``, so
    ``dv += a(t) dt``, not integrated: a regressor outside the span of S_V. The test adds
    the columns ``a(t)`` and ``da/dt`` (stacked over the three axes, one shared coefficient
    each, as a model term would be) to S and reads their coefficients off the last 2 x 2
    block of the QR factor of ``[S | a | j] / c`` (:func:`casep.analysis.linalg.reduce_qr`):
    ``R22 beta = q2``, ``Cov(beta) = s^2 kappa (R22^T R22)^-1`` with
    ``s^2 = RSS / (m - p)`` and ``kappa = max_axis (1 + rho) / (1 - rho)`` (rho = lag-1
    autocorrelation of the augmented residuals, clipped to [0, 0.999]): the long-run
    variance of AR(1) noise against a smooth regressor, so correlated noise does not
    read as a signal. By Frisch-Waugh-Lovell the test does not depend on the estimate
    that produced `r` (any D_hat leaves the same projection off span S).

    `S` may be a :class:`~casep.analysis.problem.Problem`: its rows are then regenerated block
    by block (twice), never held whole.

    Cost: one QR of the 3N x (n + 2) matrix, about one OLS solve (0.04 s against 0.03 s on
    the paper flight at 100 Hz, 19 501 samples), small beside building S_V and reading the
    file, and negligible beside GLS, RLS or the bounded QP.

    Parameters
    ----------
    S : (N, 3, n) array_like
        Regression matrix of the fit.
    r : (N, 3) array_like
        Residuals ``dv - S D_hat``, m/s.
    t, f : array_like
        Times (s) and specific force (N, 3), m/s^2.

    Returns
    -------
    TimeOffsetTest or None
        None when ``a`` is constant or indistinguishable from S_V (no test possible).
    """
    blocks, n, nonzero = _row_blocks(S)
    t = np.asarray(t, dtype=float)
    N = t.size
    X = np.empty((N, 3, 2))  # [a | da/dt] per sample and axis (built in place: long flights)
    X[:, :, 0] = f  # a = f + g (kinematic_acceleration), in place
    X[:, :, 0] += GRAVITY_LAUNCH
    for i in range(3):
        X[:, i, 1] = np.gradient(X[:, i, 0], t) if N >= 2 else 0.0
    usable = np.array([np.any(X[:, :, j] != 0.0) for j in range(2)])
    if not usable[0]:
        return None
    if not usable.all():
        X = X[:, :, usable]
    p, k = int(nonzero.sum()) + X.shape[2], X.shape[2]
    if 3 * N <= p + 2:
        return None
    y = np.asarray(r, dtype=float).reshape(N, 3)

    def augmented():  # [S (non-zero columns: zero ones would leave arbitrary Householder vectors) | a | j]
        for sl, S_b in blocks():
            yield np.concatenate([S_b[:, :, nonzero], X[sl]], axis=2).reshape(-1, p), y[sl].reshape(-1)

    red = reduce_qr_blocks(augmented(), p)
    R22, q2 = red.R[-k:, -k:], red.qty[-k:]
    if np.min(np.abs(np.diag(R22))) < 1e-6:  # ||x_perp|| / ||x|| (unit-norm columns): no separation
        return None
    coef_all = np.linalg.lstsq(red.R, red.qty, rcond=None)[0]  # augmented fit, scaled coordinates
    coef = coef_all / np.where(red.scale > 0, red.scale, 1.0)
    # Lag-1 autocorrelation per axis of the augmented residuals, accumulated block by block
    num, den, last = np.zeros(3), np.zeros(3), None
    for A_b, y_b in augmented():
        e = (y_b - A_b @ coef).reshape(-1, 3)
        den += np.einsum("ki,ki->i", e, e)
        num += np.einsum("ki,ki->i", e[1:], e[:-1]) + (last * e[0] if last is not None else 0.0)
        last = e[-1].copy()
    rho = num / np.maximum(den, 1e-300)
    rho = np.clip(rho, 0.0, 0.999)
    kappa = float(np.max((1.0 + rho) / (1.0 - rho)))  # AR(1) long-run variance factor
    s2 = red.rho2 / (3 * N - p)
    beta = np.linalg.solve(R22, q2) / red.scale[-k:]  # natural units
    Rinv = np.linalg.inv(R22)
    std = np.sqrt(s2 * kappa * np.sum(Rinv**2, axis=1)) / red.scale[-k:]  # diag (R22^T R22)^-1
    effect = np.abs(beta) * red.scale[-k:] / np.sqrt(np.sum(Rinv**2, axis=1) * 3 * N)  # |b| ||x_perp|| / sqrt(m)
    out = [beta[0], std[0], beta[0] / std[0]]
    out += [beta[1], std[1], beta[1] / std[1]] if k == 2 else [np.nan] * 3
    return TimeOffsetTest(*(float(v) for v in out), inflation=kappa, offset_rms=float(effect[0]),
                          jerk_rms=float(effect[1]) if k == 2 else 0.0)


def check_fit(S: np.ndarray, dv: np.ndarray, result, *, t: np.ndarray, f: np.ndarray,
              source: str = "<memory>", outliers_handled: bool = False) -> None:
    """Residual checks after an estimate: noise-free data, outliers, tracking time offset.

    Parameters
    ----------
    S : (N, 3, n) array_like or Problem
        Regression matrix the estimate used (a :class:`~casep.analysis.problem.Problem`: its
        rows regenerated block by block).
    dv : (N, 3) array_like
        Velocity error the estimate used, m/s.
    result : EstimateResult
        The estimate (coefficients without an estimate count as 0).
    t, f : array_like
        Times (s) and specific force (N, 3) of the same rows.
    source : str, optional
        Flight name for the messages.
    outliers_handled : bool, optional
        The fit removed or down-weighted its outliers already (a robust fit): no outlier warning.

    Warns
    -----
    NoiseFreeWarning, OutlierWarning, TimeOffsetWarning
        See the module notes and :func:`time_offset_test`.
    """
    dv = np.asarray(dv, dtype=float).reshape(-1, 3)
    x = np.nan_to_num(np.asarray(result.estimate, dtype=float), nan=0.0)
    blocks, _, _ = _row_blocks(S)
    r = np.empty_like(dv)
    for sl, S_b in blocks():
        r[sl] = dv[sl] - S_b @ x  # dv - S D_hat, block by block
    t = np.asarray(t, dtype=float)
    rms, scale = float(np.sqrt(np.mean(r**2))), float(np.max(np.abs(dv)))
    if rms <= NOISE_FREE * scale or scale == 0.0:
        _warn(f"{source}: residual RMS {rms:.3g} m/s is at the rounding level of dv (max |dv| {scale:.3g} m/s): "
              "the data carry no noise, so the std reflect rounding only.", NoiseFreeWarning)
        return
    if not outliers_handled:
        _check_outliers(r, t, source, locate=S.locate if _is_problem(S) and hasattr(S, "locate") else None)
    if f is None:  # rows without their specific force (a problem from arrays): no time-offset test
        return
    if _shares_problem_test(S, dv):
        del r  # long flights: the shared test reads dv, not the residuals
        test = _problem_time_offset_test(S, t, f)
    else:
        test = time_offset_test(S, r, t, f)
    if test is None:
        return
    offset = abs(test.offset_t) > OFFSET_T and test.offset_rms > EFFECT_MIN
    if offset:
        _warn(f"{source}: residuals track the kinematic acceleration a = f + g: a tracking time offset of "
              f"{1e3 * test.offset:.3g} +- {1e3 * test.offset_std:.2g} ms would explain them "
              f"(t = {test.offset_t:.3g}); model it (dt_trk) or align the time tags.", TimeOffsetWarning)
    # An offset dt also gives the jerk term -dt^2/2 (second order of v(t - dt)): one warning then.
    if not offset and abs(test.jerk_t) > OFFSET_T and test.jerk_rms > EFFECT_MIN:
        _warn(f"{source}: residuals track the jerk da/dt: coefficient {test.jerk:.3g} +- {test.jerk_std:.2g} s^2 "
              f"(t = {test.jerk_t:.3g}); tracking smoothing or interpolation that distorts the velocity?",
              TimeOffsetWarning)


def _check_outliers(r: np.ndarray, t: np.ndarray, source: str, top: int = 5, locate=None) -> None:
    """Name the rows whose residual spikes above :data:`OUTLIER_Z` robust sigma."""
    if r.shape[0] < 5:
        return
    d = _spikes(r)
    hits = []
    for i in range(3):
        s_d, s_r = _robust_sigma(d[:, i]), _robust_sigma(r[:, i])
        # in robust sigma of d, and at least as many of r (correlated noise has s_d << s_r)
        z = np.abs(d[:, i]) / max(s_d, s_r, NOISE_FLOOR)
        # a spike A at row k gives d = A at k and -A/2 at k +- 1: keep the local maxima only
        peak = (z > OUTLIER_Z) & (z >= np.roll(z, 1)) & (z >= np.roll(z, -1))
        for j in np.flatnonzero(peak):
            k = j + 1  # row of r (0-based)
            noise = s_d / np.sqrt(1.5)  # white-noise sigma from the spike statistic, blind to smooth misfit
            hits.append((float(z[j]), k, i, float(d[j, i]), float(d[j, i] / noise) if noise > 0 else np.inf))
    if not hits:
        return
    hits.sort(reverse=True)
    if locate is not None:  # the file's line and the time, as every other message names a row
        from casep.io.files import where

        places = [where(loc) for loc in locate([k for _, k, *_ in hits[:top]])]
    else:
        places = [f"sample {k + 1} (t = {t[k]:.6g} s)" for _, k, *_ in hits[:top]]
    rows = "; ".join(f"{p} dv_{'xyz'[i]} {size:+.3g} m/s = {zr:+.3g} noise sigma"
                     for p, (_, k, i, size, zr) in zip(places, hits[:top]))
    more = f" and {len(hits) - top} more" if len(hits) > top else ""
    _warn(f"{source}: {len(hits)} outlier(s) in dv: {rows}{more}. They bias every coefficient: remove them "
          "(--exclude-outliers), fit robustly (--robust) or correct these rows.", OutlierWarning)


#: A given sigma and the least-squares residual std differing by more than this factor ...
SIGMA_FACTOR = 3.0
#: ... with a two-sided chi-square p-value below this: a warning.
SIGMA_P = 1e-3


def check_sigma(problem, sigma: float, source: str = "<memory>") -> dict | None:
    """Compare a given noise std with the least-squares residual std of the same data.

    Under white noise of std `sigma`, ``RSS / sigma^2 ~ chi-square(m - rank)``, with RSS the
    least-squares residual sum of squares (the smallest misfit the model allows). A
    :class:`~casep.exceptions.NoiseLevelWarning` when the ratio ``s_LS / sigma`` is outside
    ``[1 / SIGMA_FACTOR, SIGMA_FACTOR]`` and the two-sided p-value is below :data:`SIGMA_P`: every
    std of the result scales with sigma (``--sigma 1e-3`` on 0.1 m/s noise: std 100 x too small).

    Parameters
    ----------
    problem : Problem
    sigma : float
        The given noise std, m/s.
    source : str, optional

    Returns
    -------
    dict or None
        ``{"sigma_given", "residual_std", "ratio", "chi2", "dof", "p_value"}`` when it warns, else None.
    """
    from scipy.stats import chi2 as chi2_dist

    dof = int(problem.m - problem.rank().rank)
    if dof < 1 or not sigma > 0:
        return None
    rss = float(problem.ls_rss())
    s_ls = float(np.sqrt(rss / dof))
    ratio = s_ls / sigma
    stat = rss / sigma**2
    p = float(2 * min(chi2_dist.sf(stat, dof), chi2_dist.cdf(stat, dof)))
    if 1 / SIGMA_FACTOR <= ratio <= SIGMA_FACTOR or p >= SIGMA_P:
        return None
    out = {"sigma_given": float(sigma), "residual_std": s_ls, "ratio": ratio, "chi2": stat, "dof": dof, "p_value": p}
    _warn(f"{source}: the given noise sigma {sigma:.4g} m/s disagrees with the least-squares residual std "
          f"{s_ls:.4g} m/s (ratio {ratio:.3g}; chi-square {stat:.4g} on {dof} dof, p = {p:.2g}): every std scales with "
          f"sigma, so they are {'too small' if ratio > 1 else 'too large'} by about {max(ratio, 1 / ratio):.3g} x. "
          "Leave sigma out to estimate it, or check its unit (m/s).", NoiseLevelWarning)
    return out

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
      in g (multiply by 9.80665); a peak just under 1 g (above ``F_AT_REST`` g) is an
      accelerometer at rest in m/s^2 (a record with no lift-off), not ``f`` in g. Strapdown
      telemetry's body specific force (``fb_*``, no ``f_*``) peaking below ``F_AT_REST`` g but
      above 1 g read in g: error (its accelerometers read g at rest or in level flight). Peak above
      100 g: warning (cm/s^2, mm/s^2?). ``f`` in ft/s^2 (factor 3.28) stays inside the
      plausible range and is *not* detectable. A strapdown record's ``C(q) fb`` whose time mean along the
      vertical (y, up) is below -0.5 g: error (over any span it is g plus the vertical speed gained over
      the span's length; an accelerometer's sign or a navigation frame other than casep's launch frame).
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
      unit that fits, outside 0.4-2.5 (a unit's factor: ft/s gives 3.28, cm/s 100, km/s 0.001) a
      :class:`~casep.io.flight.FlightDataError` naming the columns and the numbers.

Before estimation, with the model: :func:`check_enough_samples`, :func:`check_dv_not_zero` (errors),
:func:`warn_setup` (the set-up evidence the pair reader recorded, :mod:`casep.io.setup`) and
:func:`casep.checks.late_start.warn_late_start`.

:func:`check_fit` (after estimation, on ``r = dv - S_V D_hat``)
    - **Noise-free data**: residual RMS at the rounding level of dv (below 1e-9 max |dv|):
      :class:`~casep.exceptions.NoiseFreeWarning`, the std reflect rounding only.
    - **Outliers**: a spike of size A at row k leaves ``d_k = r_k - (r_{k-1} + r_{k+1})/2 = A``
      while smooth model errors leave ``d ~ r'' dt^2 / 2``; rows where ``|d_k|`` exceeds
      10 robust (MAD) sigma of d and of r, and 1 cm/s, are named, with their size in noise sigma
      (``MAD(d) / sqrt(1.5)``: the sample-to-sample scatter, which the outlier's pull on the
      fit does not inflate). The check runs on the raw dv (after de-noising, the residuals of the
      thresholded dv are sparse and heavy-tailed, not noise).
    - **Tracking time offset**: see :func:`casep.checks.time_offset.time_offset_test`.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np

from casep._special import MAD_SIGMA  # sigma = MAD_SIGMA * MAD for Gaussian data
from casep.checks.time_offset import (
    EFFECT_MIN,
    is_problem,
    kinematic_acceleration,
    problem_time_offset_test,
    row_blocks,
    shares_problem_test,
    time_offset_test,
)
from casep.checks.tracking_quality import _velocity_change, screen_summary, stretch_noise
from casep.exceptions import (
    NoiseFreeWarning,
    NoiseLevelWarning,
    OutlierWarning,
    PlausibilityWarning,
    SetupWarning,
    TimeOffsetWarning,
)
from casep.io.flight import (  # DUPLICATE_STEP, the time range: the one rule
    DUPLICATE_STEP,
    DURATION_HIGH,
    DV_COLUMNS,
    STEP_HIGH,
    STEP_IMPOSSIBLE,
    STEP_LOW,
    FlightData,
    FlightDataError,
    time_unit_factors,
)
from casep.regression.problem import (  # NOISE_FREE re-exported: the one constant
    NOISE_FREE,
    is_rounding_level,
    rounding_level,
)
from casep.units import G0

__all__ = ["NOISE_FREE", "check_flight", "check_fit", "check_sigma", "check_enough_samples", "check_dv_not_zero",
           "min_samples", "dv_noise", "misfit_problem", "misfit_noise_floor", "MISFIT_RATIO", "MISFIT_NOISE_FLOOR",
           "setup_problems", "warn_setup", "levelling_problem", "SLOW_NOISE_SHARE", "SLOW_NOISE_RATIO",
           "UNIT_FACTORS", "unit_factor", "misfit_advice"]


# Specific force, m/s^2: a boost is ~1-30 g (1 g needed to lift off, ~100 g the hardest motors).
F_PEAK_LOW, F_PEAK_HIGH, F_PEAK_IMPOSSIBLE = G0, 100.0 * G0, 1e4 * G0
# A peak below 1 g but above this fraction of it is an accelerometer at rest (|f| = local gravity), not f in g.
F_AT_REST = 0.95
# Time: telemetry is sampled at 1 Hz .. 10 kHz; nothing is sampled at 1 MHz; boosts last < 1 h (casep.io.flight's,
# the readers' rule of a time unit: time_unit_factors).
DW_HIGH = 2e4  # m/s: no rocket flight gains more than ~20 km/s of specific-force velocity
DV_NOISE_HIGH = 5.0  # m/s: tracking noise is 0.01-1 m/s
OUTLIER_Z = 10.0  # robust sigma of the spike statistic; Gaussian P(|z| > 10) ~ 1.5e-23
OFFSET_T = 5.0  # |t| of the offset / jerk terms; Gaussian P(|t| > 5) ~ 6e-7
NOISE_FLOOR = 1e-3  # m/s: an outlier must exceed OUTLIER_Z times at least this (interpolation ripple
#                    of noise-free two-rate data at staging is ~1e-4 m/s)


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
#: disagree on units. The flat-Earth g of :func:`kinematic_acceleration` makes the ratio 0.9986 on the
#: ``paper`` boost (195 s, 195 km downrange), so 20 % is a wide margin; ft/s gives 3.28.
VELOCITY_RATIO_RANGE = (0.8, 1.25)
#: Outside this range the ratio is a unit's factor (ft/s 3.28, cm/s 100, km/s 1e-3, mm/s 1e3), not a flight's
#: gravity model: the flight is refused (every estimate would be scaled by it), naming the columns and the numbers.
VELOCITY_RATIO_REFUSED = (0.4, 2.5)


def _check_velocity_units(flight: FlightData) -> None:
    """Compare the telemetered velocity change with the integral of f + g (files with v_tel), and the tracking
    velocity change with the telemetered one over the same times (a pair of files): one rule, :func:`_units_ratio`."""
    change = flight.meta.get("telemetry_velocity_change_m_s")
    t, f = flight.t, flight.f
    if change is None or t.size < 2:
        return
    expected = _integrated_acceleration(t, f)
    _force_or_time_units(flight, change, expected)
    _units_ratio(change, expected, flight.source, "v_tel_x", lambda g, e, r: (
        f"the telemetered velocity changes by {g:.4g} m/s over {t[-1] - t[0]:.4g} s but the specific force "
        f"plus gravity integrates to {e:.4g} m/s (ratio {r:.3g}, expected {{lo:g}}-{{hi:g}}): the velocity "
        "columns (v_tel_*, v_trk_*) and f disagree on units."), "v_tel and v_trk")
    trk = flight.meta.get("tracking_velocity_change_m_s")
    tel = flight.meta.get("telemetry_velocity_change_at_tracking_m_s")
    if trk is not None and tel is not None:
        source = str(flight.meta.get("tracking") or flight.source)
        _units_ratio(trk, tel, source, "v_trk_x", lambda g, e, r: (
            f"the tracking velocity (v_trk_x, v_trk_y, v_trk_z of {source}) changes by {g:.4g} m/s but the "
            f"telemetered velocity (v_tel_* of {flight.meta.get('telemetry', 'the telemetry')}) by {e:.4g} m/s "
            f"over the same times (ratio {r:.3g} over the flight, expected {{lo:g}}-{{hi:g}}): the two files "
            "disagree on units."),
            "v_trk")


#: A unit's factor k makes the measured velocity changes ``k`` times the expected ones at every epoch and on every
#: axis; a drifting navigated velocity (instrument errors, larger than the vehicle's speed changes on a short
#: window) does not. Above this fraction of the measured changes left unexplained by the best scale the ratio
#: is no units test but a drift, which the fit estimates: the units rule says nothing.
SCALED_COPY_UNEXPLAINED = 0.25


def _integrated_acceleration(t: np.ndarray, f: np.ndarray) -> np.ndarray:
    """``int (f + g) dt`` over the flight (trapezoid; flat-Earth g, :func:`kinematic_acceleration`), m/s."""
    return _velocity_change(kinematic_acceleration(t, f), t)[-1]


def _force_or_time_units(flight: FlightData, change, expected: np.ndarray) -> None:
    """Before the velocity columns are blamed: f in g or t in ms also break ``v_tel`` against ``int (f + g) dt``.

    When the velocity change disagrees with `expected` but agrees (ratio within :data:`VELOCITY_RATIO_RANGE`)
    with the integral of ``G0 f`` (f in g) or over ``t / 1000`` (t in ms), that column is named.

    Raises
    ------
    FlightDataError
        Naming the force's first column or ``t``, with both ratios.
    """
    g, e = float(np.linalg.norm(change)), float(np.linalg.norm(expected))
    lo, hi = VELOCITY_RATIO_RANGE
    if e < 1.0 or lo <= g / e <= hi:
        return
    cols = _force_columns(flight)
    t, f = flight.t, flight.f
    alternatives = [(cols, "in g", f"multiply them by {G0:g}", lambda: _integrated_acceleration(t, G0 * f))]
    if "ms (divide by 1000)" in _time_units(float(np.median(np.diff(t))), float(t[-1] - t[0])):
        alternatives.append(("t", "in ms", "divide it by 1000", lambda: _integrated_acceleration(1e-3 * t, f)))
    for what, unit, fix, alt in alternatives:
        e_alt = float(np.linalg.norm(alt()))
        if e_alt > 0.0 and lo <= g / e_alt <= hi:
            raise FlightDataError(flight.source, (
                f"the telemetered velocity changes by {g:.4g} m/s but the specific force plus gravity integrates to "
                f"{e:.4g} m/s over {t[-1] - t[0]:.4g} s (ratio {g / e:.3g}, expected {lo:g}-{hi:g}); read with {what} "
                f"{unit}, it integrates to {e_alt:.4g} m/s (ratio {g / e_alt:.3g}): {what} "
                f"{'are' if ',' in what else 'is'} {unit}, {fix}"),
                what.split(",")[0])


def _unexplained_by_scale(measured: np.ndarray, expected: np.ndarray) -> float:
    """RMS of ``measured - k expected`` over the RMS of `measured`, ``k`` the least-squares scale, rows (epoch, axis).

    ``k = sum(m . e) / sum(e . e)``; 0 for a scaled copy, ~1 when `measured` is unrelated to `expected`."""
    mm, ee = float(np.sum(measured * measured)), float(np.sum(expected * expected))
    if mm == 0.0 or ee == 0.0:
        return 1.0
    k = float(np.sum(measured * expected)) / ee
    return float(np.sqrt(max(mm - k * k * ee, 0.0) / mm))


def _units_ratio(measured, expected, source: str, column: str, what, columns: str) -> None:
    """The units rule of a velocity change against the one it must equal: the ratio, the least-squares scale
    ``k = sum(m . e) / sum(e . e)`` over the rows (epochs; one row for the end alone), outside
    :data:`VELOCITY_RATIO_RANGE`, the changes a scaled copy of each other (:func:`_unexplained_by_scale`
    within :data:`SCALED_COPY_UNEXPLAINED`), warns with the unit that fits, outside :data:`VELOCITY_RATIO_REFUSED`
    (a unit's factor) raises a :class:`~casep.io.flight.FlightDataError` naming `source` and `column`. The scale of
    every epoch, not the last one's ratio: a vehicle that ends where it started at rest (a car drive) has a last
    change of its speed near zero, and the navigation's drift over the whole flight would make any ratio of it.

    `what(|measured|, |expected|, ratio)`: the message (the changes at the epoch of the largest expected one), with
    ``{lo}``, ``{hi}`` for the range.
    """
    m, x = np.atleast_2d(np.asarray(measured, float)), np.atleast_2d(np.asarray(expected, float))
    i = int(np.argmax(np.linalg.norm(x, axis=1)))
    e, g = float(np.linalg.norm(x[i])), float(np.linalg.norm(m[i]))
    if e < 1.0:  # no velocity gained: nothing to compare
        return
    ratio = float(np.sum(m * x)) / float(np.sum(x * x))
    lo, hi = VELOCITY_RATIO_RANGE
    if lo <= ratio <= hi or _unexplained_by_scale(m, x) > SCALED_COPY_UNEXPLAINED:
        return
    hint = _unit_hint(ratio, lo, hi, ((f"ft/s (multiply {columns} by 0.3048)", 0.3048),
                                      ("km/s (multiply by 1000)", 1e3), ("cm/s (divide by 100)", 1e-2),
                                      ("mm/s (divide by 1000)", 1e-3)))
    text = what(g, e, ratio).format(lo=lo, hi=hi) + hint
    low, high = VELOCITY_RATIO_REFUSED
    if not low <= ratio <= high:  # a unit's factor (ft/s 3.28, km/s 1e-3, ...): every estimate would be wrong
        raise FlightDataError(source, text + " Convert the columns to m/s (f to m/s^2)", column)
    _warn(f"{source}: {text}")


def _force_columns(flight: FlightData) -> str:
    return {"W": "W_x, W_y, W_z (as dW/dt)", "q, fb": "fb_x, fb_y, fb_z (as C(q) fb)"}.get(flight.meta.get("force", ""),
                                                                                          "f_x, f_y, f_z")


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
    if peak < F_PEAK_LOW and F_PEAK_LOW <= peak * G0 and peak < F_AT_REST * G0 and flight.meta.get("force") == "q, fb":
        # the body specific force of a strapdown INS: its accelerometers read |fb| = g at rest and in level flight,
        # more under thrust or lift; a record that never comes near 1 g (F_AT_REST) but would peak above it in g is
        # fb in g, as the velocity check of a file with v_tel_* and the pad check of raw IMU data refuse it
        k = int(np.argmax(np.linalg.norm(flight.f, axis=1)))
        raise FlightDataError(
            flight.source, f"the body specific force peaks at {peak:.4g} m/s^2 ({peak / G0:.3g} g) at t = "
            f"{flight.t[k]:.6g} s and never reaches the {F_AT_REST:g} g an accelerometer reads at rest or in level "
            f"flight: fb_* in m/s^2 cannot be a strapdown INS's; read in g (times {G0:g}) it peaks at "
            f"{peak * G0:.4g} m/s^2 ({peak:.3g} g). Give fb_x, fb_y, fb_z in m/s^2 (multiply by {G0:g})",
            "fb_x, fb_y, fb_z", k + 1)
    if flight.meta.get("force") == "q, fb":
        _check_vertical_force(flight)
    if peak < F_PEAK_LOW:
        # f in g reads |f| ~ 1 at rest and a few in a boost; f in m/s^2 at rest reads |f| = g, just under 1 g
        # (local gravity 9.78-9.83 m/s^2): a record with no lift-off, not a unit mistake
        hint = (f" An accelerometer at rest reads |f| = g: the record holds no lift-off (a vehicle on the pad?); "
                f"f in g would read about 1, not {peak:.3g}." if peak >= F_AT_REST * G0
                else " It looks like f in g: multiply by 9.80665." if peak * G0 >= F_PEAK_LOW else "")
        _warn(f"{flight.source}: peak specific force ({cols}) is {peak:.4g} m/s^2 ({peak / G0:.3g} g), below "
              f"the 1 g any vehicle needs to lift off (boosts reach ~1-30 g).{hint}")
    elif peak > F_PEAK_HIGH:
        hint = _unit_hint(peak, F_PEAK_LOW, F_PEAK_HIGH, (("cm/s^2 (divide by 100)", 1e-2),
                                                         ("mm/s^2 (divide by 1000)", 1e-3)))
        _warn(f"{flight.source}: peak specific force ({cols}) is {peak:.4g} m/s^2 ({peak / G0:.4g} g), above "
              f"the {F_PEAK_HIGH / G0:g} g of the hardest rocket motors.{hint}")
    return peak


#: The least mean vertical specific force (in g) of a strapdown record: over any span ``T`` it is ``g + (v_up(end) -
#: v_up(start)) / T``, at least 0 unless the vehicle gains downward speed faster than in free fall (thrust
#: downward); below -0.5 g the record's ``C(q) fb`` cannot be a vehicle's.
F_UP_MEAN_MIN = -0.5


def _check_vertical_force(flight: FlightData) -> None:
    """A strapdown record's ``C(q) fb`` whose mean along the launch frame's vertical (y, up) is below
    :data:`F_UP_MEAN_MIN` g: a FlightDataError naming the ``fb_*`` columns (an accelerometer's sign, or
    quaternions whose navigation frame is not casep's launch frame, y up)."""
    t = flight.t
    T = float(t[-1] - t[0]) if t.size > 1 else 0.0
    if T <= 0.0:
        return
    up = float(np.sum(0.5 * (flight.f[1:, 1] + flight.f[:-1, 1]) * np.diff(t))) / T  # time mean of f_y
    if up >= F_UP_MEAN_MIN * G0:
        return
    k = int(np.argmin(flight.f[:, 1]))
    raise FlightDataError(
        flight.source, f"the specific force C(q) fb points down on average: its mean along the launch frame's "
        f"vertical (y, up) is {up:.4g} m/s^2 ({up / G0:.3g} g) over t = {t[0]:.6g} .. {t[-1]:.6g} s, lowest "
        f"{flight.f[k, 1]:.4g} m/s^2 at t = {t[k]:.6g} s. Over any span it is g plus the vertical speed gained over "
        "the span's length, at least 0 unless the vehicle is driven downward faster than it falls: an "
        "accelerometer's sign (fb_*), or quaternions whose navigation frame is not casep's launch frame (x downrange, "
        "y up)", "fb_x, fb_y, fb_z", k + 1)


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
    if h < STEP_LOW or h > STEP_HIGH or T > DURATION_HIGH:
        fits = _time_units(h, T)
        hint = f" Is t in {' or '.join(fits)}?" if fits else ""
        _warn(f"{flight.source}: {figures}; telemetry of a boost is sampled at 1 Hz-10 kHz and lasts "
              f"less than {DURATION_HIGH:g} s.{hint}")
    k = int(np.argmin(steps))
    if steps[k] < DUPLICATE_STEP * h:
        _warn(f"{flight.source}: column `t`, row {k + 2}: time step {steps[k]:.3g} s from the previous row, "
              f"{h / steps[k]:.3g} times below the median step {h:.4g} s: a near-duplicate time tag?")


def _time_units(h: float, T: float) -> list[str]:
    """The names of :func:`time_unit_factors`."""
    return [u for u, _ in time_unit_factors(h, T)]


def dv_noise(flight: FlightData) -> np.ndarray:
    """The robust sample-to-sample noise of dv per axis, m/s: ``MAD(d) / sqrt(1.5)``, ``d`` the spike statistic of
    the observed rows (white noise of sigma s gives ``Var d = 1.5 s^2``; a smooth dv contributes ``~dv'' dt^2 / 2``)."""
    return np.array([_robust_sigma(d) for d in _spikes(flight.dv[flight.observed]).T]) / np.sqrt(1.5)


def _check_dv_noise(flight: FlightData) -> None:
    """Robust sample-to-sample scatter of dv against tracking noise."""
    if flight.n_observed < 5:
        return
    noise = dv_noise(flight)
    i = int(np.argmax(noise))
    if noise[i] > DV_NOISE_HIGH:
        hint = _unit_hint(noise[i], 1e-3, 1.0, (("cm/s (divide by 100)", 1e-2), ("mm/s (divide by 1000)", 1e-3)))
        _warn(f"{flight.source}: column `dv_{'xyz'[i]}`: sample-to-sample noise {noise[i]:.4g} m/s, far "
              f"above radar or GNSS tracking noise (0.01-1 m/s).{hint}")


# ----------------------------------------------------------------------------- with the model
def min_samples(n_coefficients: int) -> int:
    """Fewest samples that leave one degree of freedom for the noise estimate.

    The first sample carries no information (S_V(t0) = 0 for a model without initial
    terms), so 3 (N - 1) > n is needed: N >= n // 3 + 2.
    """
    return n_coefficients // 3 + 2


def check_enough_samples(flight: FlightData, n_coefficients: int, model_name: str) -> None:
    """Raise :class:`FlightDataError` when `flight` has too few observed samples for a model."""
    need = min_samples(n_coefficients)
    n = flight.n_observed
    if n < need:
        part = "" if n == flight.n_samples else f" observed (tracking covers {n} of {flight.n_samples})"
        screened = screen_summary(flight.meta.get("tracking_screen"))
        raise FlightDataError(
            flight.source,
            f"{n} samples{part} are too few for model `{model_name}` with "
            f"{n_coefficients} coefficients: need at least {need}" + (f"; {screened}" if screened else ""),
            "t", int(np.flatnonzero(flight.observed)[-1]) + 1 if n else flight.n_samples,
        )


def _dv_columns(flight: FlightData) -> str:
    return "v_tel_* - v_trk_*" if str(flight.meta.get("dv", "dv")).startswith("v_tel") else ", ".join(DV_COLUMNS)


def check_dv_not_zero(flight: FlightData) -> None:
    """Refuse a flight whose velocity error is exactly zero at every observed sample.

    Such a dv carries no information (no error and no tracking noise): the fit would report
    sigma 0 and std 0. It is nearly always an unfilled column or telemetry compared with
    itself. One rule for ``separate`` and ``diagnose``.
    """
    dv = flight.dv[flight.observed_index()]
    if not np.any(dv):
        raise FlightDataError(flight.source, f"the velocity error (columns {_dv_columns(flight)}) is exactly 0 at "
                                             f"all {dv.shape[0]} observed samples: nothing to estimate (an unfilled "
                                             "column, or telemetry compared with itself?)")


def setup_problems(flight: FlightData) -> list[str]:
    """The failed set-up checks of a flight (``meta["setup"]["problems"]``, :func:`casep.io.setup.setup_evidence`)."""
    ev = flight.meta.get("setup") if isinstance(flight.meta, dict) else None
    return list(ev.get("problems", [])) if isinstance(ev, dict) else []


def levelling_problem(flight: FlightData, model: Any, estimates: dict[str, float] | None = None) -> str | None:
    """Why `model` cannot describe a telemetry that ``casep navigate`` levelled on the pad, or None.

    Levelling makes the INS's mean specific force over the pad window vertical, so at the first sample
    its attitude is off by ``phi0_h = u x (C delta_f) / g`` (a horizontal accelerometer bias ``b`` tilts it
    by ``b / g`` rad): the velocity error on the pad is cancelled, and in flight the tilt returns it as
    ``f x phi0``. A model whose accelerometer errors reach dv but which has no initial attitude error
    (``initial_misalignment``) predicts ``b t`` on the pad instead, and its estimates are biased by many std
    (an aircraft levelled over 38 s, strapdown12: ``ba_x`` 12 std off; with ``strapdown15_phi0``: 1.2).
    The header line of :func:`casep.io.files.levelled_comment` (``flight.meta["levelled"]``) tells such a
    telemetry; `estimates` (natural units, by name: the coefficients the flight determines) give the tilt the
    estimate's ``ba_*`` (mg) leave; where one of them is missing from `estimates` (not determined) the message says
    so and gives no size.
    """
    lev = flight.meta.get("levelled") if isinstance(flight.meta, dict) else None
    if not lev or not hasattr(model, "numeric") or "fb_x" not in model.signals:  # a strapdown model only
        return None
    if not model.numeric("accel_columns").size or np.any(model.numeric("phi0") != 0):
        return None
    (t1, t2), span = lev["window"], float(flight.t[-1] - flight.t[0])
    tilt = ""
    if estimates and all(f"ba_{a}" in estimates for a in "xyz") and all(f"fb_{a}" in flight.signals for a in "xyz"):
        pad = (flight.t >= t1) & (flight.t <= t2)
        u = np.array([flight.signals[f"fb_{a}"][pad if pad.any() else slice(None)].mean() for a in "xyz"])
        b = np.array([estimates[f"ba_{a}"] for a in "xyz"]) * 1e-3  # mg -> g
        phi = float(np.linalg.norm(np.cross(u / np.linalg.norm(u), b)))  # rad: the bias across the pad's vertical
        tilt = (f" (the estimate's ba_x, ba_y, ba_z {b[0] * 1e3:.3g}, {b[1] * 1e3:.3g}, {b[2] * 1e3:.3g} mg: a start "
                f"tilt of {phi * 206264.8:.3g} arcsec, {phi * G0 * span:.3g} m/s over the {span:.4g} s flight at 1 g)")
    elif estimates is not None and all(f"ba_{a}" in model.names for a in "xyz"):
        left = [f"ba_{a}" for a in "xyz" if f"ba_{a}" not in estimates]
        tilt = (f" (its size is not given: the flight does not determine {', '.join(left)}, and a tilt formed from "
                "their values would say nothing)")
    from casep.model.loader import PHI0_MODELS

    use = PHI0_MODELS.get(model.name.split("+")[0], "a model with the initial attitude error phi0_x..z")
    return (f"{flight.source}: casep navigate levelled this telemetry on the pad over [{t1:g}, {t2:g}] s, which turns "
            f"the accelerometer errors on the pad into a start attitude error{tilt}; model {model.name} has no "
            f"initial attitude error to take it, so its estimates are biased: use {use} (phi0 free), or "
            "`casep separate --imu` on the raw record (the levelling's own phi0 from the coefficients)")


def warn_setup(flight: FlightData) -> list[str]:
    """Warn (:class:`~casep.exceptions.SetupWarning`) once per failed set-up check; returns their messages."""
    problems = setup_problems(flight)
    for msg in problems:
        warnings.warn(SetupWarning(f"{flight.source}: set-up check failed: {msg}."), stacklevel=3)
    return problems


# -------------------------------------------------------------------------------------- fit


def check_fit(S: np.ndarray, dv: np.ndarray, result, *, t: np.ndarray, f: np.ndarray,
              source: str = "<memory>", outliers_handled: bool = False, excluded=None, noise=None) -> None:
    """Residual checks after an estimate: noise-free data, outliers, tracking time offset.

    Parameters
    ----------
    S : (N, 3, n) array_like or Problem
        Regression matrix the estimate used (a :class:`~casep.regression.problem.Problem`: its
        rows regenerated block by block).
    dv : (N, 3) array_like
        Velocity error the estimate used, m/s.
    result : EstimateResult
        The estimate: its :meth:`~casep.estimators.result.EstimateResult.fitted_coefficients` give the
        fitted values (where a coefficient has no estimate, the solver's solution).
    t, f : array_like
        Times (s) and specific force (N, 3) of the same rows.
    source : str, optional
        Flight name for the messages.
    outliers_handled : bool, optional
        The fit removed or down-weighted its outliers already (a robust fit): no outlier warning.
    excluded : array_like of int, optional
        Samples the fit removed (a robust fit's glitches, excluded outliers): left out of the
        time-offset test, which would otherwise read them as a signal.
    noise : NoiseModel, optional
        The noise model the fit whitened its rows for: the time-offset test whitens its rows for it too
        (:func:`casep.checks.time_offset.time_offset_test`).

    Warns
    -----
    NoiseFreeWarning, OutlierWarning, TimeOffsetWarning
        See the module notes and :func:`time_offset_test`.
    """
    dv = np.asarray(dv, dtype=float).reshape(-1, 3)
    x = result.fitted_coefficients()  # the solver's solution: it reproduces the determined combinations
    blocks, _, _ = row_blocks(S)
    r = np.empty_like(dv)
    for sl, S_b in blocks():
        r[sl] = dv[sl] - S_b @ x  # dv - S D_hat, block by block
    t = np.asarray(t, dtype=float)
    rms, scale = float(np.sqrt(np.mean(r**2))), float(np.max(np.abs(dv)))
    pb: Any = S if is_problem(S) else None  # a Problem: the data's own rule (the noise model and robust filter ask it)
    if pb is not None:
        rms = pb.ls_rms()
    if pb.is_noise_free() if pb is not None else is_rounding_level(rms, scale):
        floor = float(getattr(pb, "interpolation_floor", 0.0) or 0.0)
        level = (f"at the interpolation floor of the pair ({floor:.3g} m/s: one file's velocity carried to the "
                 "other's times): the data carry no noise, so the std reflect interpolation only"
                 if floor > rounding_level(scale) else f"at the rounding level of dv (max |dv| {scale:.3g} m/s): the "
                 "data carry no noise, so the std reflect rounding only")
        _warn(f"{source}: residual RMS {rms:.3g} m/s is {level}.", NoiseFreeWarning)
        return
    if not outliers_handled:
        _check_outliers(r, t, source, locate=S.locate if is_problem(S) and hasattr(S, "locate") else None)
    if f is None:  # rows without their specific force (a problem from arrays): no time-offset test
        return
    keep = None
    if excluded is not None and len(excluded):
        keep = np.ones(dv.shape[0], dtype=bool)
        keep[np.asarray(excluded, dtype=int)] = False
    if keep is None and shares_problem_test(S, dv):
        del r  # long flights: the shared test reads dv, not the residuals
        test = problem_time_offset_test(S, t, f, noise)
    else:
        test = time_offset_test(S, r, t, f, keep=keep, noise=noise)
    if test is None:
        return
    from casep.model.loader import TIME_OFFSET

    offset = abs(test.offset_t) > OFFSET_T and test.offset_rms > EFFECT_MIN
    if offset and TIME_OFFSET not in (getattr(result, "names", None) or ()):
        # with dt_trk in the model the offset is estimated: a(t) lies in the span of S_V, its test is moot
        _warn(f"{source}: residuals track the kinematic acceleration a = f + g: a tracking time offset of "
              f"{1e3 * test.offset:.3g} +- {1e3 * test.offset_std:.2g} ms would explain them "
              f"(t = {test.offset_t:.3g}{_freed(test)}); model it ({_offset_advice(result)}) or align the time tags.",
              TimeOffsetWarning)
    # An offset dt also gives the jerk term -dt^2/2 (second order of v(t - dt)): one warning then.
    if not offset and abs(test.jerk_t) > OFFSET_T and test.jerk_rms > EFFECT_MIN:
        _warn(f"{source}: residuals track the jerk da/dt: coefficient {test.jerk:.3g} +- {test.jerk_std:.2g} s^2 "
              f"(t = {test.jerk_t:.3g}{_freed(test)}); tracking smoothing or interpolation that distorts the velocity?",
              TimeOffsetWarning)


def _offset_advice(result) -> str:
    """How to model the tracking time offset: the fit's model with ``+dt_trk`` (casep.model.loader.load_model)."""
    from casep.model.loader import TIME_OFFSET_SUFFIX

    name = getattr(result, "model", "") or "MODEL"
    return f"dt_trk: --model {name}{TIME_OFFSET_SUFFIX}, or a model file with its term"


def _freed(test) -> str:
    """What a time-offset test's message says of the samples it freed at steps of the acceleration."""
    return (f"; {test.freed} sample(s) at a step of the acceleration, where the first-order term a(t) dt does "
            "not hold, left out" if test.freed else "")


#: A fit's residual RMS above this many times the tracking's sample-to-sample noise (:func:`dv_noise`, at least
#: :data:`MISFIT_NOISE_FLOOR`) on an axis whose residuals the noise model leaves correlated is a model error.
MISFIT_RATIO = 100.0
#: m/s: the noise the ratio is taken against at least (the low end of radar and GNSS tracking noise), so that
#: tracking held between fixes (no sample-to-sample scatter) is not read as noise-free; the slow noise's rule
#: drops it on a record with no sample-to-sample change at that level at all (:func:`misfit_noise_floor`).
MISFIT_NOISE_FLOOR = 0.01
#: A fitted Gauss-Markov correlation time at least this share of the span of the tracked epochs: the noise model
#: takes the residuals for a noise as slow as the record, which the record cannot tell from the drift a model error
#: (or the coefficients) leaves (:func:`misfit_problem`) ...
SLOW_NOISE_SHARE = 0.5
#: ... and, on that axis, a residual RMS above this many times the tracking's sample-to-sample noise: a model error
#: absorbed as noise. Honest correlated tracking noise (tau about a second) is far below both.
SLOW_NOISE_RATIO = 10.0


#: Unit mix-ups by the factor they scale a quantity with (a quantity read in the wrong unit is this factor, or
#: its inverse, times its true value): a fitted scale near one of them points to the mix-up.
UNIT_FACTORS = ((1000.0, "a factor 1000: mm/s or km/s for m/s, mg for g, ms for s"),
                (180.0 / np.pi, "57.3: degrees for radians (deg/s in rad/s columns?)"),
                (G0, "9.81: g for m/s^2"), (3600.0, "3600: per hour for per second"),
                (3.6, "3.6: km/h for m/s"))
#: How close (relative) a ratio must come to a factor of :data:`UNIT_FACTORS` to name it.
UNIT_FACTOR_TOL = 0.03


def unit_factor(ratio: float) -> str | None:
    """The unit mix-up of :data:`UNIT_FACTORS` that `ratio` (or its inverse) matches within
    :data:`UNIT_FACTOR_TOL`, or None (a ratio that is no unit factor, or not positive)."""
    if not (np.isfinite(ratio) and ratio > 0):
        return None
    r = max(ratio, 1.0 / ratio)
    return next((what for k, what in UNIT_FACTORS if abs(r / k - 1.0) <= UNIT_FACTOR_TOL), None)


def misfit_advice(model: str, names, units, estimates, std=None) -> str:
    """What to check when `model` does not describe a flight, most likely first: the model lacks terms the data
    need (the richer shipped model, :data:`casep.model.loader.RICHER_MODELS`), a saturated sensor, the frame or
    set-up; a unit mix-up only when a fitted scale points to it: a scale factor (ppm) whose ``1 + s`` is a factor of
    :data:`UNIT_FACTORS` (:func:`unit_factor`; rates in deg/s read as rad/s fit ``sg = 57.3 - 1``) and, with
    `std`, is determined to within that match (``2 std <= UNIT_FACTOR_TOL`` of the factor: an undetermined scale
    of 56 +- 20 says nothing of units)."""
    from casep.model.loader import RICHER_MODELS

    richer = RICHER_MODELS.get(str(model).split("+")[0])
    first = (f"model {model} may lack terms the data need: try {richer}" if richer else
             f"model {model} may lack terms the data need (a richer model)")
    sd = [None] * len(names) if std is None else list(std)
    hits = [f"{n} {x:.4g} ppm is a scale of {1.0 + x * 1e-6:.4g}, {what}"
            for n, u, x, e in zip(names, units, estimates, sd)
            if u == "ppm" and x is not None and np.isfinite(x) and (what := unit_factor(1.0 + x * 1e-6))
            and (e is None or (np.isfinite(e) and 2 * e * 1e-6 <= UNIT_FACTOR_TOL * abs(1.0 + x * 1e-6)))]
    units_part = f"; the numbers point to a unit mix-up: {'; '.join(hits[:3])}" if hits else ""
    return f"{first}; else a saturated sensor the INS integrated, a frame or set-up mistake{units_part}"


def misfit_problem(flight: FlightData, residual_rms: dict, correlated, *,
                   runs: tuple[int, int, int] | None = None, advice: str | None = None,
                   noise: dict | None = None) -> str | None:
    """Why a fit's residuals are a model error rather than noise, or None.

    Tracking noise, white or correlated, has a sample-to-sample part: radar and GNSS velocities scatter by
    0.01-1 m/s from one epoch to the next, and a Gauss-Markov error of std ``s`` and time constant ``T``
    steps by ``s sqrt(2 dt / T)``. A residual RMS of :data:`MISFIT_RATIO` (100) times that scatter or more
    would need a Gauss-Markov error smooth over ``10^4`` samples. Together with residuals that the fitted
    noise model leaves correlated (the whiteness test rejects that axis: `correlated`), it is what a model
    error leaves (a saturated sensor the INS integrated, a frame or set-up mistake, a missing term): the
    noise model then absorbs it as a slow Gauss-Markov error of metres per second and the estimates
    take the rest, far from the instruments' (hundreds of mg, degrees per second), whatever their std say.
    A robust fit can hide the same misfit from the whiteness test: it rejects the stretch the model cannot
    follow as "glitches" and down-weights the rest; rejections mostly in runs of consecutive samples
    (`runs`, :func:`casep.regression.rows.mostly_runs`) then stand for the correlation, since a glitch is
    isolated. A noise model can also whiten such a misfit away: a Gauss-Markov noise whose fitted correlation time
    is :data:`SLOW_NOISE_SHARE` of the tracked span or more (as slow as the record: the noise model fits the
    signal) on an axis whose residual RMS is :data:`SLOW_NOISE_RATIO` times the sample-to-sample noise or more
    (at least its noisiest stretch's: a noise that differs between stretches is judged elsewhere) (`noise`, the
    result's ``diagnostics["noise"]``) is the same finding, said with the correlation time.

    Parameters
    ----------
    flight : FlightData
        The flight fitted (its observed dv).
    residual_rms : dict
        Residual RMS per axis ``{"x": m/s, ...}`` (``EstimateResult.residual_rms``).
    correlated : sequence of str
        The axes whose whitened residuals the whiteness test rejects.
    runs : (int, int, int), optional
        A robust fit's rejections: (samples in runs, samples rejected, runs), when most are in runs; the
        message then names them instead of the whiteness test.
    advice : str, optional
        What to check, most likely first (:func:`misfit_advice`: the model's missing terms before units).
    noise : dict, optional
        The fitted noise model's record (``diagnostics["noise"]``: per axis ``tau_s``).

    Returns
    -------
    str or None
        The axes, their residual RMS, their noise and the ratio.
    """
    if flight.n_observed < 5:
        return None
    own = dv_noise(flight)
    sample = np.maximum(own, MISFIT_NOISE_FLOOR)
    bad = [(a, float(residual_rms.get(a) or 0.0), float(sample[i])) for i, a in enumerate("xyz")
           if a in correlated and (residual_rms.get(a) or 0.0) > MISFIT_RATIO * sample[i]]
    advice = advice or ("the model may lack terms the data need; else a saturated sensor the INS integrated, a frame "
                        "or set-up mistake")
    if not bad:
        quiet = misfit_noise_floor(flight)
        return _slow_noise_problem(flight, residual_rms, noise, np.maximum(own, quiet), advice,
                                   by_stretch=quiet >= MISFIT_NOISE_FLOOR)
    listed = ", ".join(f"{a} {r:.4g} m/s = {r / n:.3g} x {n:.2g} m/s" for a, r, n in bad)
    how = "correlated after the noise model" if runs is None else \
        (f"the robust fit rejected {runs[0]} of its {runs[1]} rejected samples in {runs[2]} run(s) of consecutive "
         "samples (a stretch the model cannot follow, not glitches)")
    return (f"residual RMS at least {MISFIT_RATIO:g} times the tracking's sample-to-sample noise, and {how}, "
            f"on {len(bad)} axis(es) ({listed}): a model error, not noise; the estimates absorb it: " + advice)


def misfit_noise_floor(flight: FlightData) -> float:
    """The sample-to-sample noise (m/s) :func:`misfit_problem` takes the tracking's to be at least when it judges a
    noise model as slow as the record (:data:`SLOW_NOISE_SHARE`, :data:`SLOW_NOISE_RATIO`).

    :data:`MISFIT_NOISE_FLOOR` where anything in the observed dv changes from one sample to the next by that much
    (the spike statistic of :func:`dv_noise` within each stretch of the tracking, :func:`casep.noise.robust.stretches`,
    any row, any axis): noise, or the step where tracking held between
    fixes is refreshed, whose holds would otherwise read as noise-free. A record with no such change anywhere carries
    no tracking noise at that level and holds no fixes (a simulated flight with noise-free tracking): the floor is
    then the pair's interpolation floor (``meta["interpolation_floor_m_s"]``, what carrying one file's velocity to
    the other's times errs by; 0 for one file), the residual a noise-free pair leaves, as
    :meth:`casep.regression.problem.Problem.is_noise_free` takes it. On such a record nothing supports a tracking
    noise at all, and a Gauss-Markov noise as slow as the record over residuals far above its own sample-to-sample
    change is the noise model fitting the signal. Under the fixed floor that misfit went unjudged: on the noise-free
    ``strapdown-boost`` (strapdown33's errors, the 15-term ``strapdown15_axial`` fitted) a residual of 0.2 to 5 mm/s,
    38 to 670 times the record's sample-to-sample change, whitened by a Gauss-Markov noise of 188 s (the record
    190 s), was a success with a gyro bias 569 of its std off. The 100-times rule keeps the fixed floor: a correct
    model's residual on a quiet record (an iterated pass's remainder, 2e-6 m/s on a noise-free car window, 100 times
    its 1.8e-8 m/s sample-to-sample change) is smooth and correlated too, and is no misfit."""
    from casep.noise.robust import stretches

    tt, dv = flight.t[flight.observed], flight.dv[flight.observed]
    d = [np.abs(_spikes(dv[a:b])) for a, b in stretches(tt)]
    if d and max(float(np.nanmax(x, initial=0.0)) for x in d) < MISFIT_NOISE_FLOOR:
        meta = flight.meta if isinstance(flight.meta, dict) else {}
        return float(meta.get("interpolation_floor_m_s") or 0.0)
    return MISFIT_NOISE_FLOOR


def _slow_noise_problem(flight: FlightData, residual_rms: dict, noise: dict | None, sample: np.ndarray,
                        advice: str, by_stretch: bool = True) -> str | None:
    """:func:`misfit_problem`'s finding of a noise model as slow as the record over residuals far above the
    sample-to-sample noise `sample` (m/s per axis, with `by_stretch` at least the noisiest stretch's scatter:
    :func:`casep.checks.tracking_quality.stretch_noise`; :data:`SLOW_NOISE_SHARE`, :data:`SLOW_NOISE_RATIO`), or
    None. Without `by_stretch` (a record with no sample-to-sample change at :data:`MISFIT_NOISE_FLOOR`:
    :func:`misfit_noise_floor`) the stretches' scatter, from first differences, is the slope of a smooth dv, not
    noise."""
    axes = (noise or {}).get("axes") if isinstance(noise, dict) else None
    if not isinstance(axes, dict):
        return None
    tt = flight.t[flight.observed]
    span = float(tt[-1] - tt[0]) if tt.size > 1 else 0.0
    if not span > 0:
        return None
    # against the noisiest stretch's scatter where the noise differs between stretches (a quiet pad, a noisy
    # flight after a reacquisition): the robust scatter of the whole record is the quiet one's
    noisiest = max((n for *_, n in stretch_noise(tt, flight.dv[flight.observed])), default=0.0) if by_stretch else 0.0
    sample = np.maximum(sample, noisiest)
    slow = []
    for i, a in enumerate("xyz"):
        tau, r = (axes.get(a) or {}).get("tau_s"), float(residual_rms.get(a) or 0.0)
        if isinstance(tau, (int, float)) and tau >= SLOW_NOISE_SHARE * span and r > SLOW_NOISE_RATIO * sample[i]:
            slow.append(f"{a} tau {tau:.3g} s, residual RMS {r:.4g} m/s = {r / sample[i]:.3g} x {sample[i]:.2g} m/s")
    if not slow:
        return None
    return (f"the noise model took the residuals for a Gauss-Markov noise as slow as the record ({span:.4g} s of "
            f"tracking; correlation time at least {SLOW_NOISE_SHARE:g} of it) with a residual RMS at least "
            f"{SLOW_NOISE_RATIO:g} times the tracking's sample-to-sample noise, on {len(slow)} axis(es) "
            f"({'; '.join(slow)}): a noise the record cannot tell from a drift, fitted over a misfit that is likelier "
            "a model error (the noise model fits the signal); the estimates and their std rest on it: " + advice)


def _check_outliers(r: np.ndarray, t: np.ndarray, source: str, top: int = 5, locate=None) -> None:
    """Name the rows whose residual spikes above :data:`OUTLIER_Z` robust sigma of their own stretch.

    Each stretch of the tracking (:func:`casep.noise.robust.stretches`: split at its pauses) is judged
    by its own noise level: one sigma over a quiet pad and a noisy flight after a reacquisition (0.06 against
    1.7 m/s) is the pad's, and would name every flight epoch an outlier. A stretch too short for a noise level of
    its own is not judged; rows without times (a problem from arrays) are one stretch."""
    from casep.noise.robust import stretches

    timed = np.ndim(t) == 1 and len(t) == len(r)
    hits = []
    for a, b in stretches(t) if timed else [(0, len(r))]:
        rs = r[a:b]
        d = _spikes(rs)
        for i in range(3):
            s_d, s_r = _robust_sigma(d[:, i]), _robust_sigma(rs[:, i])
            # in robust sigma of d, and at least as many of r (correlated noise has s_d << s_r)
            z = np.abs(d[:, i]) / max(s_d, s_r, NOISE_FLOOR)
            # a spike A at row k gives d = A at k and -A/2 at k +- 1: keep the local maxima only
            peak = (z > OUTLIER_Z) & (z >= np.roll(z, 1)) & (z >= np.roll(z, -1))
            for j in np.flatnonzero(peak):
                k = a + j + 1  # row of r (0-based)
                noise = s_d / np.sqrt(1.5)  # white-noise sigma from the spike statistic, blind to smooth misfit
                hits.append((float(z[j]), k, i, float(d[j, i]), float(d[j, i] / noise) if noise > 0 else np.inf))
    if not hits:
        return
    hits.sort(reverse=True)
    if locate is not None:  # the file's line and the time, as every other message names a row
        from casep.io.locate import where

        places = [where(loc) for loc in locate([k for _, k, *_ in hits[:top]])]
    else:
        places = [f"sample {k + 1}" + (f" (t = {t[k]:.6g} s)" if timed else "") for _, k, *_ in hits[:top]]
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

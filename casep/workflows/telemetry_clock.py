"""A strapdown telemetry's clock against the tracking's: the drift as one more coefficient with its exact effect.

An INS integrates its samples over the steps its own clock says, and tags its states with the same clock. A clock
running fast by ``d`` against the tracking's (casep's drift ``eps = -d``: the tracking time tags late by ``eps t``
more at telemetry time ``t``, :func:`casep.io.pair.telemetry_time`) does two things to ``dv = v_tel - v_trk``:

- the states are tagged late: ``dv += a eps t`` (``a`` the kinematic acceleration), the time offset's drift;
- every integration step is stretched by ``1 + d``: the velocity from the INS's start and the attitude are scaled,
  a common scale factor on every accelerometer and gyro and on the gravitation's integral
  (:func:`casep.io.strapdown.clock_stretch` ``E``): ``dv += d E = -eps E``.

So the drift's column, per ppm, is ``1e-6 (a t - E)``. On a boost at steady thrust from rest ``a t`` and the
accelerometers' part of ``E`` cancel: a tag-only model (the time offset split between the flight's halves,
:func:`casep.checks.tracking_quality.offset_halves`) read 80 ppm as -13.2 +- 6.4 ppm and said a drift up to
25.9 ppm would go unseen. The column is estimated beside the coefficients with the fit's own whitening and noise
model (:func:`casep.workflows.row_estimators.column_estimates`, the rule every such test uses), so its std is that
of the fit's noise (the halves' std was white noise times an AR(1) factor, 4-5x too small under Gauss-Markov plus
white tracking noise: 34 +- 6.3 ppm on a clean flight). A drift given (``--clock-drift``) is taken out of both the
tracking's tags and the telemetry's velocity (:func:`casep.io.files.read_flight_pair`); the test then measures
the drift beyond it.

Beyond the clock-drift rule (:func:`casep.checks.tracking_quality.drift_determined`) the drift is warned about
when none was given, and fails the result (``STATUS_SETUP``) when one was: the data contradict it, and when the
drift they point to is the given one's opposite within the test's 4 std the message names the sign.
"""

from __future__ import annotations

import dataclasses
import warnings
from typing import Any

import numpy as np

from casep.estimators.result import EstimateResult
from casep.io.flight import FlightData

__all__ = ["drift_column", "launch_time", "telemetry_clock_record", "judge_telemetry_clock", "carry_telemetry_clock",
           "telemetry_gravitation", "MOVES_SAID"]

#: The coefficients a drift at the edge of the test moves most, said at most this many (:func:`_moves`).
MOVES_SAID = 3


def telemetry_gravitation(flight: FlightData) -> Any:
    """The gravitation of a strapdown telemetry's frame at the telemetry's times and launch-inertial positions
    (:func:`casep.navigation.strapdown.launch_gravitation`), or None when no launch site ties the frame to the
    Earth. The site of ``casep navigate``'s header (``meta["telemetry_site"]``, its launch time in the
    telemetry's time scale), else the one given with Earth-fixed tracking (``meta["tracking_frame"]``, its launch
    time in the tracking's scale: :func:`casep.io.pair.tracking_time` of the telemetry's, with ``meta["time_shift_s"]``
    and ``meta["clock_drift_ppm"]``)."""
    from casep.frames import LaunchSite
    from casep.gravity import launch_gravitation
    from casep.io.pair import tracking_time

    meta = flight.meta if isinstance(flight.meta, dict) else {}
    shift, drift = 0.0, 0.0
    site = meta.get("telemetry_site")
    if site is None:
        site = (meta.get("tracking_frame") or {}).get("site")
        shift, drift = float(meta.get("time_shift_s", 0.0)), float(meta.get("clock_drift_ppm", 0.0))
    if site is None:
        return None
    G = launch_gravitation(LaunchSite(**site))
    return G if not (shift or drift) else (lambda t, r: G(tracking_time(t, shift, drift), r))


def launch_time(flight: FlightData, t_tel: np.ndarray) -> float:
    """The launch time of a strapdown telemetry pair in the telemetry's time scale (s): its header's site
    (``meta["telemetry_site"]``), else the one given with Earth-fixed tracking (:func:`casep.io.pair.telemetry_time`
    of its launch time, with ``meta["time_shift_s"]`` and ``meta["clock_drift_ppm"]``), else the telemetry's first
    time `t_tel` (its INS's start)."""
    from casep.io.pair import telemetry_time

    meta = flight.meta if isinstance(flight.meta, dict) else {}
    site = meta.get("telemetry_site")
    if isinstance(site, dict) and site.get("t0") is not None:
        return float(site["t0"])
    site = (meta.get("tracking_frame") or {}).get("site")
    if isinstance(site, dict) and site.get("t0") is not None:
        return float(telemetry_time(float(site["t0"]), float(meta.get("time_shift_s", 0.0)),
                                    float(meta.get("clock_drift_ppm", 0.0))))
    return float(t_tel[0])


def drift_column(flight: FlightData, t: np.ndarray, offset: bool = False,
                 offset_fitted: bool = False) -> np.ndarray | None:
    """The rows' change (N, 3), m/s per ppm of the drift ``eps`` (module notes), at the times `t` (s, the problem's
    rows) of a strapdown telemetry pair; with `offset`, (N, 3, 2): a late tag's ``a`` per ms beside it; None where the
    flight is not one (no ``pair_inputs`` with the strapdown signals, no kinematic acceleration). The tags' drift
    counts from :func:`casep.io.pair.drift_pivot` (the launch time, :func:`launch_time`, where the fit has its time
    offset, `offset_fitted`, or the pairing measured it; else 0)."""
    from casep.io.files import R_TEL_COLUMNS
    from casep.io.pair import drift_pivot
    from casep.io.strapdown import clock_stretch

    meta = flight.meta if isinstance(flight.meta, dict) else {}
    inp = meta.get("pair_inputs")
    if meta.get("format") != "pair" or inp is None:
        return None
    cols = ("q_w", "q_x", "q_y", "q_z", "fb_x", "fb_y", "fb_z", "w_x", "w_y", "w_z")
    if not all(c in inp.signals for c in cols) or not all(f"a_{k}" in flight.signals for k in "xyz"):
        return None
    sig = inp.signals
    t_tel = np.asarray(inp.t_tel, dtype=float)
    gravitation = telemetry_gravitation(flight)
    r = np.column_stack([np.asarray(sig[c], dtype=float) for c in R_TEL_COLUMNS]) \
        if gravitation is not None and all(c in sig for c in R_TEL_COLUMNS) else None
    E = clock_stretch(t_tel, np.column_stack([sig[c] for c in cols[:4]]), np.column_stack([sig[c] for c in cols[4:7]]),
                      np.column_stack([sig[c] for c in cols[7:]]), np.asarray(inp.v_tel, dtype=float), r,
                      None if r is None else gravitation)
    t = np.asarray(t, dtype=float)
    rows = np.searchsorted(flight.t, t)
    if np.any(rows >= flight.t.size) or not np.allclose(flight.t[np.minimum(rows, flight.t.size - 1)], t):
        return None
    a = np.column_stack([np.asarray(flight.signals[f"a_{k}"], dtype=float)[rows] for k in "xyz"])
    E_t = np.column_stack([np.interp(t, t_tel, E[:, j]) for j in range(3)])
    align = meta.get("time_alignment")
    pivot = drift_pivot(launch_time(flight, t_tel),
                        offset_fitted or (isinstance(align, dict) and align.get("mode") == "auto"))
    col = 1e-6 * (a * (t - pivot)[:, None] - E_t)
    return col if not offset else np.stack([col, 1e-3 * a], axis=2)  # and a time offset's, per ms


def telemetry_clock_record(res: EstimateResult, flight: FlightData, problem: Any,
                           scales: dict | None = None) -> dict | None:
    """The drift beyond the one given, estimated as one more coefficient (:func:`drift_column`,
    :func:`casep.workflows.row_estimators.column_estimates`): ``ppm`` (the clocks' drift the data point to),
    ``std_ppm``, ``given_ppm``, ``beyond_given_ppm``, ``determined`` (the clock-drift rule on the drift beyond the
    given one), ``unseen_ppm`` (``|beyond| + 2 std``), ``warns_beyond_ppm`` (the rule's threshold), ``moves`` (what a
    drift that large, not modelled, does to the determined coefficients: :func:`_moves`, `scales` the model's
    declared magnitudes), ``on``; None where there is no column or no noise model to whiten with."""
    from casep.checks.tracking_quality import DRIFT_MIN_PPM, drift_determined
    from casep.workflows.row_estimators import column_estimates

    if problem.y is None or problem.t is None:
        return None
    from casep.model.loader import TIME_OFFSET

    # without the fit's own time offset, one beside the drift: the tags' drift counts from an origin it moves
    offset = TIME_OFFSET not in res.names
    cols = drift_column(flight, np.asarray(problem.t, dtype=float), offset, not offset)
    if cols is None:
        return None
    col = cols[:, :, 0] if offset else cols
    try:
        est = column_estimates(res, problem, flight, cols)
    except (ValueError, np.linalg.LinAlgError):
        return None
    if est is None or not (np.all(np.isfinite(est[0])) and np.all(np.isfinite(est[1]))) or est[1][0] <= 0:
        return None
    beyond, std = float(est[0][0]), float(est[1][0])
    given = float(flight.meta.get("clock_drift_ppm", 0.0))
    rule = max(DRIFT_MIN_PPM, 4.0 * std)
    return {"ppm": given + beyond, "std_ppm": std, "given_ppm": given, "beyond_given_ppm": beyond,
            "determined": bool(drift_determined(beyond, std)), "unseen_ppm": abs(beyond) + 2.0 * std,
            "warns_beyond_ppm": rule, "moves": _moves(res, problem, col, rule, scales),
            "on": "the telemetry clock's rate as one more coefficient (its tags and the INS's integration steps, "
                  "the fit's whitening, S_V projected out)"}


def _moves(res: EstimateResult, problem: Any, col: np.ndarray, ppm: float, scales: dict | None) -> list[dict]:
    """The coefficients a drift of `ppm` not modelled moves most, in the fit's std (before the drift is carried,
    :func:`carry_telemetry_clock`; at most :data:`MOVES_SAID`, those
    beyond 1 std): the fit's estimator (its noise model's whitening: the rule of
    :func:`casep.workflows.row_estimators.column_estimates`) on the rows the drift adds (`col` (N, 3) per ppm),
    ``name``, ``shift`` (the coefficient's unit), ``z``; only coefficients the flight determines (std below their
    declared magnitude in `scales`, or without one: the time offset): an undetermined one's shift lies along what
    the rows cannot tell apart, and says nothing."""
    from casep.workflows.row_estimators import _estimators

    n = len(res.names)
    est = _estimators(np.eye(n), np.ones(n), res, problem)  # the fit's estimator: its whitening, on the raw rows
    if est is None:
        return []
    shift = est[1] @ (ppm * np.asarray(col, dtype=float)).reshape(-1)
    std = np.asarray(res.std, dtype=float) if res.std is not None else np.full(n, np.nan)
    mag = np.array([(scales or {}).get(nm, np.inf) for nm in res.names], dtype=float)
    ok = np.isfinite(std) & (std > 0) & np.isfinite(np.asarray(res.estimate, dtype=float)) & (std < mag)
    zs = np.where(ok, np.abs(shift) / np.where(ok, std, 1.0), 0.0)
    order = [int(k) for k in np.argsort(-zs) if zs[k] > 1.0][:MOVES_SAID]
    return [{"name": res.names[k], "shift": float(shift[k]), "z": float(shift[k] / std[k])} for k in order]


def carry_telemetry_clock(res: EstimateResult, flight: FlightData, problem: Any) -> EstimateResult:
    """`res` with the drift beyond the one given (its record ``diagnostics["clock_drift"]["telemetry"]``,
    :func:`judge_telemetry_clock`) carried in its covariance and std as the ``--imu`` path carries it
    (:func:`casep.workflows.imu_separate.clock_carried`, :func:`casep.workflows.imu_separate.with_drift`: a consider
    parameter, its std ``meta["clock_drift_std_ppm"]`` by :func:`casep.workflows.imu_separate.given_clock_std`'s
    rule), said in ``diagnostics["clock_drift"]["carried"]``, the key of the ``--imu`` path's; `res` itself without a
    record, with one carried already, or with a std of 0. A drift the data cannot tell goes into the scale factors
    and the time offset unseen: a line alone (:func:`casep.checks.tracking_quality.telemetry_clock_line`) left the
    std as if the clocks ran at one rate."""
    from casep.workflows.imu_separate import carried_said, clock_carried, given_clock_std, with_drift

    clock = res.diagnostics.get("clock_drift") or {}
    record = clock.get("telemetry")
    if record is None or "carried" in clock or problem.t is None:
        return res
    meta = flight.meta if isinstance(flight.meta, dict) else {}
    std = given_clock_std(record["given_ppm"], meta.get("clock_drift_std_ppm"), "`clock_drift_std`")
    from casep.model.loader import TIME_OFFSET

    col = drift_column(flight, np.asarray(problem.t, dtype=float), offset_fitted=TIME_OFFSET in res.names) \
        if std > 0 else None
    if col is None:
        return res
    carried = clock_carried(record, std)
    out = with_drift(res, problem, col * carried["effective_std_ppm"], carried)
    carried["said"] = carried_said(carried, "a telemetry clock drift")
    return dataclasses.replace(out, diagnostics={**out.diagnostics, "clock_drift": {**clock, "carried": carried}})


def _sign_named(record: dict) -> bool:
    """The drift the data point to (which contradict the given one: the rule) is the given one's opposite, within the
    rule's 4 std."""
    g = record["given_ppm"]
    return g != 0.0 and abs(record["ppm"] + g) <= 4.0 * record["std_ppm"]


def judge_telemetry_clock(res: EstimateResult, flight: FlightData, problem: Any,
                          scales: dict | None = None, carry: bool = True) -> EstimateResult | None:
    """`res` with ``diagnostics["clock_drift"]`` the record of :func:`telemetry_clock_record` (its ``telemetry``
    key, ``ppm``, ``std_ppm`` and ``on`` too), with `carry` the drift carried in its covariance and std
    (:func:`carry_telemetry_clock`; without it, later: the linear result's IMU noise refits the tracking noise and
    sets the covariance anew), warned (TrackingQualityWarning) when no drift was given and the data
    see one, failed (``STATUS_SETUP``) when the given one is contradicted; None where the record cannot be formed
    (not a strapdown telemetry pair: the tag-only tests apply), on noise-free rows and on a flight with a set-up
    problem (as :meth:`casep.workflows.imu_separate._Run.clock_judged`)."""
    from casep.checks.plausibility import setup_problems
    from casep.checks.tracking_quality import DRIFT_MIN_PPM
    from casep.estimators.registry import STATUS_SETUP, failed
    from casep.exceptions import TrackingQualityWarning

    if problem.y is None or problem.is_noise_free() or setup_problems(flight):  # no std to test against; rows that
        return None  # are a set-up mistake
    record = telemetry_clock_record(res, flight, problem, scales)
    if record is None:
        return None
    out = dataclasses.replace(res, diagnostics={**res.diagnostics, "clock_drift": {
        "ppm": record["ppm"], "std_ppm": record["std_ppm"], "on": record["on"], "telemetry": record}})
    if carry:
        out = carry_telemetry_clock(out, flight, problem)
    if not record["determined"]:
        return out
    effect = (f"{record['beyond_given_ppm']:+.4g} +- {record['std_ppm']:.2g} ppm beyond the one given, beyond "
              f"{DRIFT_MIN_PPM:g} ppm and 4 std; a telemetry clock fast by d tags its states d t late and stretches "
              "every integration step of its INS by 1 + d")
    if record["given_ppm"] == 0.0:
        warnings.warn(TrackingQualityWarning(
            f"{flight.source}: the telemetry clock drifts against the tracking's by {record['ppm']:.4g} +- "
            f"{record['std_ppm']:.2g} ppm ({effect}); the coefficients take it in, so the estimates are off by more "
            f"than their std say: state it (--clock-drift {record['ppm']:.4g}, manifest clock_drift_ppm; "
            "negative when the telemetry clock runs fast)"), stacklevel=4)
        return out
    sign = (f" It is the opposite of the one given: was the sign stated the wrong way round (--clock-drift "
            f"{-record['given_ppm']:g}; negative when the telemetry clock runs fast)?") if _sign_named(record) else ""
    return failed(out, STATUS_SETUP, (
        f"failed: {flight.source}: the data contradict the clock drift given (--clock-drift "
        f"{record['given_ppm']:g} ppm): they point to {record['ppm']:.4g} +- {record['std_ppm']:.2g} ppm ({effect})."
        f"{sign}"))

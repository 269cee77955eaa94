"""The rates' unit of a raw IMU record, judged by its separation: the record as read against the record read in the
units of :data:`casep.units.RATE_UNIT_MISTAKES` (deg/s in rad/s columns).

A pad cannot always tell: a tactical gyro's bias of 10-20 deg/h is comparable to the Earth rate, so rates in deg/s
read as rad/s miss the Earth-rate match of :func:`casep.navigation.alignment._check_pad_rate`, and their mean pad
rate, 57.3 times the Earth rate plus that bias, is the size of a consumer MEMS gyro's bias read in rad/s (a
tactical car record at 51 N written in deg/s, Groves' Profile_1 with its own errors: 0.0066 rad/s, 1.6 times the
Earth rate in deg/s, where a MEMS bias lands with a chance of 34 %).
The tracking can: the rates of a moving vehicle read 57.3 times too large turn the navigation far from it, and no
linear error model takes that in (that record as read: the heading 35 deg off, estimates beyond the linear model,
a residual RMS of 5.2 m/s after one linear pass; in deg/s: 0.027 m/s, the tracking's noise). Where a separation
misfits beyond the noise, one linear pass of each other reading is made; one that fits the rows
:data:`UNIT_READING_RATIO` times better than the record as read is named, first: the heading, the estimates beyond
the linear model and the misfit a wrong unit leaves are its consequences.
"""

from __future__ import annotations

import copy
import math
import warnings
from typing import Any

import numpy as np

__all__ = ["UNIT_READING_RATIO", "rate_unit_reading"]

#: A reading of the rates in another unit is named the cause of a failed separation when its one linear pass leaves a
#: residual RMS this many times below the separation's as read (that deg/s car record: 0.0271 against 7.64 m/s,
#: 282 times; one pass each way 191 times; the same record in rad/s read as deg/s 24 times worse; the simulated rail
#: launch of ``tests/workflows/test_imu_units.py``: the wrong reading 88 to 165 times worse, tactical or MEMS biases).
UNIT_READING_RATIO = 10.0


def rate_unit_reading(run: Any, res: Any, flight: Any, spec: Any) -> dict | None:
    """The reading of the rates of `run`'s record (:class:`casep.workflows.imu_separate._Run`) in another unit of
    :data:`casep.units.RATE_UNIT_MISTAKES` that fits the tracking :data:`UNIT_READING_RATIO` times better (residual
    RMS) than `res`, the separation as read, or None.

    Tried only where `res` misfits beyond the noise: a residual RMS on some axis above
    :data:`casep.checks.plausibility.SLOW_NOISE_RATIO` times the tracking's sample-to-sample noise
    (:func:`casep.checks.plausibility.dv_noise`, at least :data:`~casep.checks.plausibility.MISFIT_NOISE_FLOOR`).
    The other reading is one linear pass from the prior fitted by `spec` (the passes' first fit: OLS under white
    noise), its warnings not said; a reading that cannot be navigated or fitted is no finding. The record: the unit, the
    columns, both residual RMS, the noise, the pad's mean rate under both readings and ``said``.
    """
    from casep.checks.plausibility import MISFIT_NOISE_FLOOR, SLOW_NOISE_RATIO, dv_noise
    from casep.navigation.alignment import OMEGA_EARTH
    from casep.navigation.imu import DTHETA_COLUMNS, RATE_COLUMNS, with_rates
    from casep.units import RATE_UNIT_MISTAKES

    imu = getattr(run, "imu", None)
    if imu is None or res.residuals is None or flight.n_observed < 5:
        return None
    r = np.asarray(res.residuals, float).reshape(-1, 3)
    per_axis = np.sqrt(np.nanmean(r**2, axis=0))
    noise = np.maximum(dv_noise(flight), MISFIT_NOISE_FLOOR)
    if not np.any(per_axis > SLOW_NOISE_RATIO * noise):
        return None
    as_read = float(np.sqrt(np.nanmean(r**2)))
    cols = ", ".join(DTHETA_COLUMNS if imu.kind == "increments" else RATE_COLUMNS)
    for unit, k in RATE_UNIT_MISTAKES:
        name, how = unit.split(" (")[0], unit.split(" (", 1)[-1].rstrip(")")
        other = copy.copy(run)
        other.heading, other.pair = dict(run.heading), dict(run.pair)
        other.imu = with_rates(imu, imu.w * k, imu.f)
        other.imu_k, other.nav, other.inputs_said = other.imu, None, True
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                fit, nav, _, _, _ = other.solve(None, spec)
        except (ValueError, ArithmeticError, np.linalg.LinAlgError):
            continue
        if fit.residuals is None:
            continue
        reading = float(np.sqrt(np.nanmean(np.asarray(fit.residuals, float) ** 2)))
        if not reading * UNIT_READING_RATIO <= as_read:
            continue
        sel = (imu.t >= run.window[0]) & (imu.t <= run.window[1])  # the pad as read, and read in `unit`
        w_read = float(np.linalg.norm(imu.w[sel].mean(axis=0))) if np.any(sel) else None
        w_unit = float(np.linalg.norm(nav.alignment.w_mean)) if nav.alignment is not None else None
        e_body = nav.alignment.C_tb.T @ run.nav_site.earth_rate if nav.alignment is not None else None
        bias_unit = None if e_body is None else float(np.linalg.norm(nav.alignment.w_mean - e_body))
        dh = math.radians(1.0 / 3600.0)
        pad = ""
        if w_read is not None and w_unit is not None and bias_unit is not None:
            pad = (f"; the pad cannot tell them apart (its mean rate as read {w_read:.3g} rad/s, a gyro bias of "
                   f"{w_read / dh:.4g} deg/h, a MEMS gyro's; read in {name} {w_unit / OMEGA_EARTH:.3g} "
                   f"times the Earth rate, a gyro bias of {bias_unit / dh:.3g} deg/h), the tracking can")
        said = (f"{imu.source}: the rates look like {name}: read so (columns {cols} times {k:.6g}), one "
                f"linear pass of the record fits the tracking to a residual RMS of {reading:.3g} m/s, "
                f"{as_read / reading:.3g} times below the {as_read:.3g} m/s the separation as read leaves (the "
                f"tracking's sample-to-sample noise {float(np.max(noise)):.2g} m/s){pad}: give rad/s ({how})")
        return {"unit": unit, "factor": k, "columns": cols, "residual_rms_as_read": as_read,
                "residual_rms_reading": reading, "ratio": as_read / reading, "noise": float(np.max(noise)),
                "pad_rate_as_read": w_read, "pad_rate_reading": w_unit, "pad_bias_reading": bias_unit,
                "said": said,
                "rule": f"tried where a residual RMS exceeds {SLOW_NOISE_RATIO:g} times the tracking's "
                        f"sample-to-sample noise; named where one linear pass of the other reading leaves a residual "
                        f"RMS {UNIT_READING_RATIO:g} times below the separation's as read"}
    return None

"""Readings held at a sensor's full scale in casep's judgement of the data: the declared full scale checked, and
the strapdown telemetry screened.

The rule itself (which readings are at a full scale, declared or not, and when a run of them is a saturation) is
:mod:`casep.fullscale`, in casep's root so that the attitude check of :mod:`casep.io.strapdown` applies it too; its
names are re-exported here for calibration and navigation. What a saturated reading spoils is the caller's
judgement: a turn of a calibration, a static pose's mean, or a navigation from that sample on.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from casep.fullscale import (
    ADC_BITS,
    CLIP_MARGIN,
    CLIP_RUN,
    DECLARED_EXCEEDED,
    FULL_SCALE_UNITS,
    HELD_FRACTION,
    NOISE_ALPHA,
    NOISE_STEPS,
    NOMINAL_RANGES,
    HeldFullScale,
    beyond_declared,
    held_full_scale,
    held_mask,
    noise_cannot_hold,
    resolution,
    white_noise,
)

if TYPE_CHECKING:
    from casep.io.flight import FlightData

__all__ = ["held_full_scale", "held_mask", "HeldFullScale", "check_full_scale", "FULL_SCALE_UNITS",
           "with_full_scales", "screen_saturation", "SENSOR_COLUMNS",
           "NOMINAL_RANGES", "ADC_BITS", "CLIP_RUN", "CLIP_MARGIN", "HELD_FRACTION", "NOISE_ALPHA", "NOISE_STEPS",
           "noise_cannot_hold", "white_noise", "resolution", "DECLARED_EXCEEDED", "beyond_declared"]


def check_full_scale(value, name: str, flag: str, unit: str) -> float:
    """A declared full scale (+-`value`, in `unit`): a finite number > 0, else the one option-error form
    (:func:`casep.exceptions.refusal`: ``option --gyr-range (`gyr_range`) must be a finite number > 0 (deg/s),
    got '-2'``)."""
    from casep.exceptions import refusal

    try:
        v = float(value)
    except (TypeError, ValueError):
        raise refusal(name, flag, f"a finite number > 0 ({unit})", value) from None
    if not (math.isfinite(v) and v > 0):
        raise refusal(name, flag, f"a finite number > 0 ({unit})", value)
    return v


#: The strapdown telemetry's sensor columns (:mod:`casep.io.strapdown`, SI) screened by :func:`screen_saturation`.
SENSOR_COLUMNS = {"gyro": ("w_x", "w_y", "w_z"), "accelerometer": ("fb_x", "fb_y", "fb_z")}


def with_full_scales(flight: FlightData, *, gyr_range: float | None = None,
                     acc_range: float | None = None) -> FlightData:
    """`flight` with its sensors' declared full scales (SI: rad/s, m/s^2; None: not declared) recorded in
    ``meta["full_scales"]`` for :func:`screen_saturation`."""
    import dataclasses

    return dataclasses.replace(flight, meta={**flight.meta, "full_scales": {"gyr_range": gyr_range,
                                                                             "acc_range": acc_range}})


def screen_saturation(flight: FlightData) -> FlightData:
    """`flight` without the rows from its first saturated body rate or body specific force on, said with a warning.

    A strapdown telemetry file (``w_*``, ``fb_*``: :mod:`casep.io.strapdown`) holds the readings the INS
    integrated; where they are held at a full scale (:func:`held_full_scale`, the rule of calibration and
    navigation; the declared full scales of ``meta["full_scales"]``, :func:`with_full_scales`, else the nominal
    ranges) the INS integrated the full scale instead of the motion, and its attitude and velocity stay wrong
    from that sample to the end of the record (an attitude error ``phi`` turns every later specific force into
    a velocity error ``f x phi``). The observed rows from the first saturated telemetry sample on are left out
    (``observed`` False), as the raw-IMU path leaves them out; ``meta["saturation"]`` records what was found.
    Where the attitude check of :mod:`casep.io.strapdown` found the attitude following the motion through the
    clip (``meta["strapdown"]["rate_clipped"]``: only the written rates clipped), the file's rates there are not
    the ones the INS integrated and a model's gyro terms computed from them would be wrong: the same rows are left
    out, and the warning says so.
    A flight screened already, or without those columns, is returned as it is.

    Warns
    -----
    SaturationWarning
        The columns, their runs at full scale (rows and times of the telemetry), the full scale, and the rows left
        out.
    """
    import dataclasses
    import warnings

    from casep.exceptions import SaturationWarning

    meta = flight.meta
    if "saturation" in meta:
        return flight
    inp = meta.get("pair_inputs")  # a pair: the telemetry's own samples, at its own rate
    t_src, sig = (inp.t_tel, inp.signals) if inp is not None else (flight.t, flight.signals)
    declared = meta.get("full_scales") or {}
    found: list[str] = []
    first = math.inf
    for sensor, cols in SENSOR_COLUMNS.items():
        if not all(c in sig for c in cols):
            continue
        fs = declared.get("gyr_range" if sensor == "gyro" else "acc_range")
        unit, per = FULL_SCALE_UNITS[sensor]
        x = np.column_stack([sig[c] for c in cols])
        beyond = beyond_declared(x, sensor, fs)
        if beyond is not None:  # the raw-IMU path's refusal (casep.navigation.imu), here for telemetry
            from casep.io.flight import FlightDataError

            j, row, said = beyond
            raise FlightDataError(flight.source, f"at t = {t_src[row]:.10g} s {said}", cols[j], row + 1)
        for h in held_full_scale(x, sensor, declared=fs):
            n = sum(b - a for a, b in h.runs)
            a0, b1 = h.runs[0][0], h.runs[-1][1] - 1
            first = min(first, float(t_src[a0]))
            found.append(f"{cols[h.axis]} at its {h.side} {h.value / per:.6g} {unit} ({h.why}) for {n} samples in "
                         f"{len(h.runs)} run(s), rows {a0 + 1}..{b1 + 1}, t = {t_src[a0]:.10g} .. {t_src[b1]:.10g} s")
    if not found:
        return dataclasses.replace(flight, meta={**meta, "saturation": None})
    cut = flight.observed & (flight.t >= first)
    if (meta.get("strapdown") or {}).get("rate_clipped"):  # the attitude check: the INS's attitude did not clip
        why = ("The INS's attitude followed the motion there (its check against the integrated rate), so the file's "
               f"rates are not the ones it integrated: a model's gyro terms would be wrong from t = {first:.10g} s on")
    else:
        why = ("The INS integrated the full scale, not the motion: its attitude and velocity are wrong from "
               f"t = {first:.10g} s on")
    warnings.warn(SaturationWarning(
        f"{flight.source}: the telemetry's sensors saturated: " + "; ".join(found) + f". {why}, so the "
        f"{int(cut.sum())} observed rows from there (of {flight.n_observed}) are left out of the fit"), stacklevel=3)
    rec = {"from_s": first, "rows_left_out": int(cut.sum()), "found": found}
    return dataclasses.replace(flight, observed=flight.observed & ~cut, meta={**meta, "saturation": rec})

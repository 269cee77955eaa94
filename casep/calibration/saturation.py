"""Saturation of a hand-turned session: readings held at the sensor's full scale.

The rule is :func:`casep.fullscale.held_full_scale`, the one navigation uses too: a run of
3 or more readings at a full scale (a declared one, within 1 % of it; else a converter's limit for raw
counts, a nominal range for a physical unit, held at the column's extreme). This module turns the
session's units into it and judges what a saturated reading spoils.

Where it matters: a gyro clipped inside a motion integrates to a wrong turn (the result is no success);
an accelerometer clipped inside a static pose gives a wrong pose mean (the pose is left out of the
fit, with a warning naming it). An accelerometer clipped during a motion does no harm: only the poses'
means are used.
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from casep.calibration.session import ACC_UNITS, GYR_UNITS, RAW_UNIT
from casep.checks.saturation import (
    ADC_BITS,
    CLIP_RUN,
    FULL_SCALE_UNITS,
    NOMINAL_RANGES,
    HeldFullScale,
    check_full_scale,
    held_full_scale,
    held_mask,
)
from casep.exceptions import CasepWarning, SaturationWarning
from casep.units import ACC_RANGES_G, FULL_SCALE_TOLERANCE, GYR_RANGES_DPS

__all__ = ["SaturationWarning", "FullScaleWarning", "implied_full_scale", "saturated_runs",
           "check_gyro_saturation", "clipped_poses", "converter", "check_full_scale", "declared_range",
           "warn_implied_full_scale",
           "ADC_BITS", "ACC_RANGES_G", "GYR_RANGES_DPS", "FULL_SCALE_TOLERANCE", "FULL_SCALE_UNITS"]


class FullScaleWarning(CasepWarning):
    """Raw counts whose fitted scale implies another full scale than the one declared (both, and the ratio)."""


def declared_range(full_scale_si: float | None, unit: str, sensor: str) -> float | None:
    """The declared full scale to check the readings against, SI (m/s^2, rad/s): None when none is declared
    or the readings are raw counts (their full scale is the converter's limit)."""
    return None if unit == RAW_UNIT else full_scale_si


def saturated_runs(x: np.ndarray, sensor: str, unit: str, declared: float | None = None,
                   min_run: int = CLIP_RUN) -> list[HeldFullScale]:
    """Per axis and side at full scale: ``(axis, side, value, why, runs)``, the runs of at least `min_run`
    readings at it (:func:`casep.fullscale.held_full_scale` in the session's `unit`; `declared`: SI)."""
    si = None if unit == RAW_UNIT else (ACC_UNITS if sensor == "accelerometer" else GYR_UNITS)[unit]
    return held_full_scale(x, sensor, si=si, declared=declared, min_run=min_run)


def _inside(found, intervals: list[tuple[int, int]], n: int):
    """The runs of `found` (saturated_runs) that overlap `intervals`."""
    mask = np.zeros(n, bool)
    for a, b in intervals:
        mask[a:b] = True
    return [(j, side, ext, why, [(a, b) for a, b in long if mask[a:b].any()]) for j, side, ext, why, long in found]


def check_gyro_saturation(gyr: np.ndarray, motions: list[tuple[int, int]], unit: str, source: str,
                          declared: float | None = None) -> list[str]:
    """SaturationWarning for a gyro axis held at its full scale inside a motion (the turn is misread); the messages."""
    msgs = []
    for j, side, ext, why, long in _inside(saturated_runs(gyr, "gyro", unit, declared), motions, len(gyr)):
        if long:
            a, b = max(long, key=lambda r: r[1] - r[0])
            msgs.append(f"gyro {'xyz'[j]}: {sum(e - s for s, e in long)} samples at its {side} {ext:.6g} ({why}) "
                        f"in {len(long)} run(s) inside motions, the longest rows {a}-{b - 1}")
    if msgs:
        warnings.warn(f"{source}: the sensor saturates: " + "; ".join(msgs) + ". The turns through them are "
                      "misread: turn more slowly, or use a wider range", SaturationWarning, stacklevel=3)
    return msgs


def clipped_poses(acc: np.ndarray, poses: list[tuple[int, int]], unit: str, source: str,
                  declared: float | None = None) -> list[int]:
    """The poses in which an accelerometer axis is held at its full scale (their mean is wrong), with a
    SaturationWarning naming each: axis, value, why it is the full scale, the pose's rows and the fraction
    of its samples at it. Returns their indices."""
    bad: dict[int, list[str]] = {}
    for h in saturated_runs(acc, "accelerometer", unit, declared):
        j, side, ext, why, long = h
        held = held_mask([h], acc.shape)[:, j]
        for i, (a, b) in enumerate(poses):
            at = int(np.count_nonzero(held[a:b]))
            if at:
                bad.setdefault(i, []).append(f"{'xyz'[j]} at its {side} {ext:.6g} ({why}) in {at / (b - a):.0%} "
                                             "of its samples")
    if bad:
        warnings.warn(f"{source}: the accelerometer saturates in {len(bad)} of {len(poses)} static poses, left out "
                      "of the fit: " + "; ".join(f"pose rows {poses[i][0]}-{poses[i][1] - 1}: " + ", ".join(m)
                                                for i, m in list(bad.items())[:6])
                      + (" ..." if len(bad) > 6 else "") + ". A clipped axis gives a wrong pose mean: use a wider "
                      "range", SaturationWarning, stacklevel=3)
    return sorted(bad)


def converter(biases: np.ndarray, readings: np.ndarray | None = None) -> tuple[int, float]:
    """A raw-count converter's word length b and the count it reads at zero input.

    Unsigned (every reading >= 0, `readings` when given, and the biases' median above 64): ``b`` the word length
    whose mid-scale ``2^(b-1)``, its zero, is nearest the biases' median. Else signed, zero 0: 16-bit, or the
    shortest of ADC_BITS whose half range holds the readings when they exceed 16 bits.
    """
    med = float(np.median(np.abs(biases)))
    if med > 64 and (readings is None or float(np.min(readings)) >= 0.0):
        bits = min(ADC_BITS, key=lambda b: abs(math.log2(med) - (b - 1)))
        return bits, 2.0 ** (bits - 1)
    top = float(np.max(np.abs(readings))) if readings is not None and np.size(readings) else 0.0
    return min((b for b in ADC_BITS if b >= 16 and 2.0 ** (b - 1) > top), default=ADC_BITS[-1]), 0.0


def implied_full_scale(scales: np.ndarray, biases: np.ndarray, sensor: str, declared_si: float | None = None,
                       readings: np.ndarray | None = None) -> dict:
    """The full scale raw counts imply: ``max_i s_i * H`` in g or deg/s, H the converter's half range.

    ``H = 2^(b-1)``, b the word length of :func:`converter` (an unsigned converter reads its zero at its
    mid-scale; a signed one at 0). The nearest nominal range (ACC_RANGES_G, GYR_RANGES_DPS), or the declared full
    scale `declared_si` (m/s^2, rad/s; ``declared`` true), and the ratio are given: without a time column a gyro's is
    proportional to the assumed rate, so a ratio far from 1 says the rate (or the declared range) is wrong.
    """
    bits, zero = converter(biases, readings)
    half = 2.0 ** (bits - 1)
    (name, per), ranges = FULL_SCALE_UNITS[sensor], NOMINAL_RANGES[sensor]
    fs = float(np.max(np.abs(scales))) * half / per
    near = declared_si / per if declared_si is not None else min(ranges, key=lambda r: abs(math.log(fs / r)))
    return {"full_scale": fs, "unit": name, "bits": bits, "half_range_counts": half, "zero_counts": zero,
            "nominal": near,
            "ratio": fs / near, "declared": declared_si is not None}


def warn_implied_full_scale(fs: dict, sensor: str, source: str, rate_assumed: bool) -> None:
    """FullScaleWarning when raw counts imply a full scale off the declared one by more than FULL_SCALE_TOLERANCE."""
    if not fs["declared"] or abs(fs["ratio"] - 1.0) <= FULL_SCALE_TOLERANCE:
        return
    u = fs["unit"]
    why = "a wrong declared range" + (" or a wrong --rate (no t column: the gyro's scale is proportional to it)"
                                      if sensor == "gyro" and rate_assumed else "")
    warnings.warn(f"{source}: the {sensor}'s raw counts imply a full scale of +-{fs['full_scale']:.4g} {u} over "
                  f"+-{fs['half_range_counts']:.0f} counts (a {fs['bits']}-bit converter), {fs['ratio']:.4g} x the "
                  f"declared +-{fs['nominal']:.4g} {u}: {why}", FullScaleWarning, stacklevel=3)

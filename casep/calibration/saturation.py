"""Saturation of a hand-turned session: readings held at the sensor's full scale.

A sensor saturates when its reading reaches the end of its range: the converter's limit for raw
counts, or the nominal range of the part once converted to a physical unit. Quantised readings
repeat values naturally (three equal counts at the smooth peak of a turn's rate), so a repeated
value alone is no saturation. Here an axis saturates when

- a run of at least ``min_run`` samples holds the column's extreme value (its maximum or minimum), and
- that value is at a full scale (:func:`full_scale`): a declared one; else, for raw counts, a limit of
  an ``b``-bit converter (unsigned ``0`` / ``2^b - 1``, signed ``-2^(b-1)`` / ``2^(b-1) - 1``, b in
  ADC_BITS, within ``max(1, 2^b / 1000)`` counts and at least a tenth of the half range from the
  column's median); for a physical unit, a nominal range of ACC_RANGES_G / GYR_RANGES_DPS within
  FULL_SCALE_TOLERANCE.

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
from casep.exceptions import CasepWarning, SaturationWarning
from casep.units import ACC_RANGES_G, FULL_SCALE_TOLERANCE, GYR_RANGES_DPS

__all__ = ["SaturationWarning", "FullScaleWarning", "full_scale", "implied_full_scale", "saturated_runs",
           "check_gyro_saturation", "clipped_poses", "check_full_scale", "declared_range", "warn_implied_full_scale",
           "ADC_BITS", "ACC_RANGES_G", "GYR_RANGES_DPS", "FULL_SCALE_TOLERANCE"]

#: Word lengths of the converters raw counts come from.
ADC_BITS = (8, 10, 12, 14, 16, 18, 20, 24, 32)


class FullScaleWarning(CasepWarning):
    """Raw counts whose fitted scale implies another full scale than the one declared (both, and the ratio)."""


#: The unit of each sensor's full scale at the edge (command line), and SI per that unit.
FULL_SCALE_UNITS = {"accelerometer": ("g", ACC_UNITS["g"]), "gyro": ("deg/s", math.pi / 180.0)}


def check_full_scale(value, name: str, flag: str, unit: str) -> float:
    """A declared full scale (+-`value`, in `unit`): a finite number > 0, else the one option-error form."""
    from casep.exceptions import refusal

    try:
        v = float(value)
    except (TypeError, ValueError):
        raise refusal(name, flag, f"a finite number > 0 ({unit})", value) from None
    if not (math.isfinite(v) and v > 0):
        raise refusal(name, flag, f"a finite number > 0 ({unit})", value)
    return v


def declared_range(full_scale_si: float | None, unit: str, sensor: str) -> tuple[float, float] | None:
    """The readings' range ``(-F, F)`` in their unit of a declared full scale F (SI: m/s^2, rad/s); None when none is
    declared or the readings are raw counts (their full scale is the converter's limit, :func:`full_scale`)."""
    if full_scale_si is None or unit == RAW_UNIT:
        return None
    f = (ACC_UNITS if sensor == "accelerometer" else GYR_UNITS)[unit]
    return (-full_scale_si / f, full_scale_si / f)


def full_scale(ext: float, side: str, column: np.ndarray, unit: str, sensor: str,
               declared: tuple[float, float] | None = None) -> str | None:
    """Why the column's extreme `ext` (its ``maximum`` or ``minimum``, `side`) is the sensor's full scale, or None.

    `declared`: the readings' range ``(low, high)`` in their unit; a reading within 0.5 % of the span
    of one end is at it. Else the module's rules for raw counts and physical units.
    """
    top = side == "maximum"
    if declared is not None:
        lo, hi = declared
        end = hi if top else lo
        return f"the declared full scale {end:g}" if abs(ext - end) <= 0.005 * (hi - lo) else None
    if unit == RAW_UNIT:
        med = float(np.median(column))
        for b in ADC_BITS:
            for rail, kind in (((2 ** b - 1, "unsigned"), (2 ** (b - 1) - 1, "signed")) if top
                               else ((0, "unsigned"), (-(2 ** (b - 1)), "signed"))):
                if abs(ext - rail) <= max(1.0, 2.0 ** b / 1000) and abs(ext - med) >= 0.1 * 2.0 ** (b - 1):
                    return (f"the {kind} {b}-bit converter's limit {rail}" if rail else
                            "the unsigned converter's limit 0")
        return None
    if (ext > 0) != top:
        return None
    table, ranges, name = ((ACC_UNITS, ACC_RANGES_G, "g") if sensor == "accelerometer"
                           else (GYR_UNITS, GYR_RANGES_DPS, "deg/s"))
    per = ACC_UNITS["g"] if name == "g" else math.pi / 180.0  # SI per unit of the nominal ranges
    v = abs(ext) * table[unit] / per
    near = min(ranges, key=lambda r: abs(v / r - 1.0))
    return f"the nominal +-{near:g} {name} range" if abs(v / near - 1.0) <= FULL_SCALE_TOLERANCE else None


def saturated_runs(x: np.ndarray, sensor: str, unit: str, declared: tuple[float, float] | None = None,
                   min_run: int = 3) -> list[tuple[int, str, float, str, list[tuple[int, int]]]]:
    """Per axis and side at full scale: ``(axis, side, value, why, runs)``, the runs of at least `min_run`
    samples (start, end excluded) that hold the column's extreme value."""
    from casep.calibration.segment import runs

    out = []
    for j in range(x.shape[1]):
        for side, ext in (("maximum", float(x[:, j].max())), ("minimum", float(x[:, j].min()))):
            long = [(a, b) for a, b in runs(x[:, j] == ext) if b - a >= min_run]
            why = full_scale(ext, side, x[:, j], unit, sensor, declared) if long else None
            if why:
                out.append((j, side, ext, why, long))
    return out


def _inside(found, intervals: list[tuple[int, int]], n: int):
    """The runs of `found` (saturated_runs) that overlap `intervals`."""
    mask = np.zeros(n, bool)
    for a, b in intervals:
        mask[a:b] = True
    return [(j, side, ext, why, [(a, b) for a, b in long if mask[a:b].any()]) for j, side, ext, why, long in found]


def check_gyro_saturation(gyr: np.ndarray, motions: list[tuple[int, int]], unit: str, source: str,
                          declared: tuple[float, float] | None = None) -> list[str]:
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
                  declared: tuple[float, float] | None = None) -> list[int]:
    """The poses in which an accelerometer axis is held at its full scale (their mean is wrong), with a
    SaturationWarning naming each: axis, value, why it is the full scale, the pose's rows and the fraction
    of its samples at it. Returns their indices."""
    bad: dict[int, list[str]] = {}
    for j, side, ext, why, long in saturated_runs(acc, "accelerometer", unit, declared):
        for i, (a, b) in enumerate(poses):
            at = int(np.count_nonzero(acc[a:b, j] == ext))
            if any(s < b and e > a for s, e in long):
                bad.setdefault(i, []).append(f"{'xyz'[j]} at its {side} {ext:.6g} ({why}) in {at / (b - a):.0%} "
                                             "of its samples")
    if bad:
        warnings.warn(f"{source}: the accelerometer saturates in {len(bad)} of {len(poses)} static poses, left out "
                      "of the fit: " + "; ".join(f"pose rows {poses[i][0]}-{poses[i][1] - 1}: " + ", ".join(m)
                                                for i, m in list(bad.items())[:6])
                      + (" ..." if len(bad) > 6 else "") + ". A clipped axis gives a wrong pose mean: use a wider "
                      "range", SaturationWarning, stacklevel=3)
    return sorted(bad)


def implied_full_scale(scales: np.ndarray, biases: np.ndarray, sensor: str, declared_si: float | None = None) -> dict:
    """The full scale raw counts imply: ``max_i s_i * H`` in g or deg/s, H the converter's half range.

    ``H = 2^(b-1)`` for the word length b whose mid-scale ``2^(b-1)`` is nearest the biases' median (an
    unsigned converter reads its zero there); biases near 0 (a signed converter) are taken as 16-bit.
    The nearest nominal range (ACC_RANGES_G, GYR_RANGES_DPS), or the declared full scale `declared_si`
    (m/s^2, rad/s; ``declared`` true), and the ratio are given: without a time column a gyro's is
    proportional to the assumed rate, so a ratio far from 1 says the rate (or the declared range) is wrong.
    """
    med = float(np.median(np.abs(biases)))
    bits = min(ADC_BITS, key=lambda b: abs(math.log2(max(med, 1.0)) - (b - 1))) if med > 64 else 16
    half = 2.0 ** (bits - 1)
    per, ranges, name = ((ACC_UNITS["g"], ACC_RANGES_G, "g") if sensor == "accelerometer"
                         else (math.pi / 180.0, GYR_RANGES_DPS, "deg/s"))
    fs = float(np.max(np.abs(scales))) * half / per
    near = declared_si / per if declared_si is not None else min(ranges, key=lambda r: abs(math.log(fs / r)))
    return {"full_scale": fs, "unit": name, "bits": bits, "half_range_counts": half, "nominal": near,
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

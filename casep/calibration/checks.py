"""The checks of a ground test against its pattern: units, rate, labels, gaps, misfits, rotation signs.

A session is refused (ValueError naming segment and numbers) when its static accelerometer means
are far from gravity in the declared unit (:func:`check_gravity`), its turns integrate to far from
their declared angles in the declared gyro unit and rate (:func:`check_turn_angles`; for a hand-turned
session its fitted scales, :func:`check_acc_scale` and :func:`check_gyro_scale`), or a static
mean points away from the stated position (:func:`check_positions`); warned about (a
:class:`casep.exceptions.CasepWarning`) when a turn has gaps in time (:class:`TimeGapWarning`), a
static segment misfits the model (:class:`PositionMisfitWarning`) or a turn's reading has the sign
opposite to its angle (:class:`RotationSignWarning`).
"""

from __future__ import annotations

import math
import warnings
from typing import Sequence

import numpy as np

from casep.calibration.rows import sample_steps
from casep.calibration.session import ACC_UNITS, GYR_UNITS, RAW_UNIT, Segment, Session
from casep.exceptions import CasepWarning
from casep.regression.problem import rounding_level

__all__ = ["RotationSignWarning", "PositionMisfitWarning", "TimeGapWarning", "GRAVITY_TOLERANCE", "MISFIT_Z",
           "TURN_TOLERANCE", "check_gravity", "check_turn_angles",
           "gyro_scale_hint", "check_gyro_scale", "acc_scale_hint", "check_acc_scale", "scale_off",
           "check_gaps",
           "check_positions", "warn_misfit",
           "check_rotation_signs", "segment_misfits"]

#: A static segment's |mean specific force| may differ from gravity by this fraction (physical units).
GRAVITY_TOLERANCE = 0.10
#: A turn's integrated gyro reading may differ from its declared angle by this fraction (physical units).
TURN_TOLERANCE = 0.25
#: A studentized segment misfit above this is warned about.
MISFIT_Z = 4.0


class RotationSignWarning(CasepWarning):
    """A rotation's gyro reading has the opposite sign of the expected angle (segment and numbers)."""


class PositionMisfitWarning(CasepWarning):
    """A static segment misfits the model far more than the others (segment and numbers)."""


class TimeGapWarning(CasepWarning):
    """Samples are missing inside a turn (segment, gaps, samples missing): integrated over the recorded times."""


def check_gravity(segs: Sequence[Segment], session: Session, gravity: float) -> None:
    """Refuse readings in a physical unit whose static |mean| is off gravity by more than GRAVITY_TOLERANCE.

    A static accelerometer senses ``|f| = g``; a mean far from it in the declared unit is a unit mistake
    (raw counts declared as m/s^2, g as m/s^2, ...): the units that would give g are named.
    """
    unit = session.acc_unit
    if unit not in ACC_UNITS:
        return  # raw counts: any scale
    for s in segs:
        if s.kind != "static":
            continue
        raw = float(np.linalg.norm(session.acc[s.rows].mean(axis=0)))  # |mean|, declared unit
        m = raw * ACC_UNITS[unit]  # m/s^2
        if abs(m / gravity - 1.0) <= GRAVITY_TOLERANCE:
            continue
        hint = acc_scale_hint(m / gravity, unit)
        si = "" if unit == "m/s^2" else f" = {m:.6g} m/s^2"
        raise ValueError(f"{session.source}: {s.where}: the static accelerometer mean has |f| = {raw:.6g} {unit}"
                         f"{si}, {m / gravity:.4g} x gravity ({gravity:.6g} m/s^2; more than "
                         f"{GRAVITY_TOLERANCE:.0%} off): {hint}")


def acc_scale_hint(ratio: float, unit: str) -> str:
    """The likely mistake when accelerometer readings are `ratio` x the true specific force (declared `unit`).

    Another unit `u` with ``|ratio k_u / k_declared - 1| <= GRAVITY_TOLERANCE`` (``k`` the unit's
    m/s^2 per unit: g declared m/s^2 reads 1/9.81 x the truth), else raw counts. Used by
    :func:`check_gravity` (ratio: |static mean| / gravity) and :func:`check_acc_scale` (1 / the fitted scale).
    """
    fits = [u for u, k in ACC_UNITS.items()
            if u != unit and abs(ratio * k / ACC_UNITS[unit] - 1.0) <= GRAVITY_TOLERANCE]
    if fits:
        return f"the readings look like {' or '.join(fits)}: --acc-unit {fits[0]}"
    return f"raw counts? Use: --acc-unit {RAW_UNIT} with a raw-readings model (ferraris)"


def scale_off(scales: np.ndarray, tolerance: float) -> float | None:
    """The readings' common factor ``median_i |1 / s_i|`` when a fitted scale is off: ``|1/|s_i| - 1| > tolerance``.

    None when every scale is within `tolerance` (a sensor's own scale error is a few percent).
    """
    ratios = 1.0 / np.maximum(np.abs(np.asarray(scales, dtype=float)), 1e-300)
    return None if np.all(np.abs(ratios - 1.0) <= tolerance) else float(np.median(ratios))


def check_acc_scale(scales: np.ndarray, session: Session) -> None:
    """Refuse fitted accelerometer scales (true per reading, SI) off 1 by more than GRAVITY_TOLERANCE.

    A scale `s_i` means the readings are ``1 / s_i`` x the specific force: the ratio :func:`check_gravity`
    tests on labelled static segments, named by the same rule (:func:`acc_scale_hint`, on the median).
    """
    unit, s = session.acc_unit, np.asarray(scales, dtype=float)
    median = scale_off(s, GRAVITY_TOLERANCE) if unit in ACC_UNITS else None  # raw counts: any scale
    if median is None:
        return
    raise ValueError(f"{session.source}: the fitted accelerometer scales are {', '.join(f'{v:.4g}' for v in s)} "
                     f"(read as {unit}): the readings are {median:.4g} x the specific force (more than "
                     f"{GRAVITY_TOLERANCE:.0%} off 1): {acc_scale_hint(median, unit)}")


def check_turn_angles(segs: Sequence[Segment], session: Session) -> None:
    """Refuse gyro readings in a physical unit whose turns integrate to far from their declared angles.

    Per turn k about axis `a_k` with declared angle `theta_k`, the reading integrated over the turn
    (the rectangle rule of the rows, :func:`casep.calibration.rows.sample_steps`), less the gyro bias
    (the mean of the static segments' means) over the turn's duration `T_k`, in degrees:

        ratio_k = a_k . sum_i (u_i - b) dt_i / theta_k

    A gyro's scale error is a few percent; a ratio off 1 by more than TURN_TOLERANCE (in magnitude:
    the sign is :func:`check_rotation_signs`' business) is a unit, rate or angle mistake. The
    message names the one that would give ~1: another unit (deg/s declared rad/s: 57.3), the rate
    (without a `t` column every integral scales with 1 / --rate: a rate twice the true one gives
    0.5), or the angle (two turns declared as one: 2).
    """
    unit = session.gyr_unit
    rots = [s for s in segs if s.kind == "rotation"]
    if unit not in GYR_UNITS or not rots:
        return  # raw counts: any scale
    static = [s for s in segs if s.kind == "static"]
    bias = np.mean([session.gyr[s.rows].mean(axis=0) for s in static], axis=0) if static else np.zeros(3)
    turns = []  # (segment, axis, declared angle deg, integrated angle deg, ratio)
    for s in rots:
        axis, declared = s.axis, s.angle_deg
        assert axis is not None and declared is not None  # a rotation segment has both
        dt = sample_steps(s, session.t, session.rate)
        turn = float(((session.gyr[s.rows] - bias) * dt[:, None]).sum(axis=0) @ axis)  # unit * s
        deg = turn * GYR_UNITS[unit] * 180.0 / math.pi
        turns.append((s, axis, declared, deg, deg / declared))
    seg, axis, declared, deg, ratio = max(turns, key=lambda x: abs(math.log(max(abs(x[4]), 1e-300))))
    if abs(abs(ratio) - 1.0) <= TURN_TOLERANCE:
        return
    median = float(np.median([abs(x[4]) for x in turns]))  # the turns' common factor
    angle = (f"the turns are about {declared * float(np.median([x[4] for x in turns])):+.3g} deg, not "
             f"{declared:+g} (--angle or the segments' angle_deg), or the segment boundaries cut the turns")
    hint = gyro_scale_hint(median, session, angle)
    each = ", ".join(f"`{x[0].name}` {x[4]:.4g}" for x in turns)
    raise ValueError(f"{session.source}: {seg.where}: the gyro reading integrates to {deg:+.6g} deg about "
                     f"{np.round(axis, 3).tolist()} (bias removed, read as {unit} at {session.rate:.6g} Hz), "
                     f"{ratio:.4g} x the declared angle {declared:+g} deg (every turn: {each}; more than "
                     f"{TURN_TOLERANCE:.0%} off 1 in magnitude): {hint}")


def gyro_scale_hint(ratio: float, session: Session, otherwise: str) -> str:
    """The likely mistake when the gyro readings integrate to `ratio` x the true rotation (declared unit and rate).

    A gyro's own scale error is a few percent, so a common factor `ratio` off 1 by more than
    TURN_TOLERANCE is a mistake of the declaration. In order:

    - another unit `u` with ``|ratio k_u / k_declared - 1| <= TURN_TOLERANCE`` (``k`` the unit's rad/s
      per unit): deg/s declared rad/s reads 57.3 x the truth, rad/s declared deg/s 1/57.3;
    - without a `t` column, the rate: every integral is ``sum_i u_i / rate``, so ``rate x ratio`` Hz
      gives 1 (a rate twice the true one gives 0.5);
    - else `otherwise` (the caller's other explanation).

    Used by :func:`check_turn_angles` (ratio: integrated over declared angle) and
    :func:`check_gyro_scale` (ratio: 1 / the fitted scale).
    """
    unit = session.gyr_unit
    units = [u for u, k in GYR_UNITS.items() if u != unit and abs(ratio * k / GYR_UNITS[unit] - 1.0) <= TURN_TOLERANCE]
    if units:
        f = GYR_UNITS[unit] / GYR_UNITS[units[0]]  # readings in units[0] read as `unit`: f x the truth
        factor = f"{f:.4g}" if f >= 1.0 else f"1/{1.0 / f:.4g}"
        return (f"the readings look like {' or '.join(units)}: --gyr-unit {units[0]} (read as {unit} they are "
                f"{factor} x the truth)")
    if session.t_column:
        return otherwise
    return (f"with no `t` column every turn integral is the readings' sum / --rate, so --rate {session.rate:.6g} Hz "
            f"is probably wrong (about {session.rate * ratio:.3g} Hz would give 1); or {otherwise}")


def check_gyro_scale(scales: np.ndarray, session: Session) -> None:
    """Refuse fitted gyro scales (true rate per reading, SI) off 1 by more than TURN_TOLERANCE in a physical unit.

    A scale `s_i` means the readings integrate to ``1 / s_i`` x the rotation the accelerometers see between
    the poses: the ratio :func:`check_turn_angles` tests for declared angles, and the same rule
    (:func:`gyro_scale_hint`, on the median of ``|1 / s_i|``) names the likely mistake.
    """
    unit, s = session.gyr_unit, np.asarray(scales, dtype=float)
    median = scale_off(s, TURN_TOLERANCE) if unit in GYR_UNITS else None  # raw counts: any scale
    if median is None:
        return
    hint = gyro_scale_hint(median, session, f"the readings are not a gyro's in {unit}, or the sensor is broken")
    raise ValueError(f"{session.source}: the fitted gyro scales are {', '.join(f'{v:.4g}' for v in s)} (read as "
                     f"{unit} at {session.rate:.6g} Hz): the readings turn {median:.4g} x the rotation the "
                     f"accelerometers see between the poses (more than {TURN_TOLERANCE:.0%} off 1): {hint}")


def check_gaps(rots: Sequence[Segment], t: np.ndarray, rate: float) -> None:
    """TimeGapWarning for a turn whose time steps exceed 1.5 / rate (samples missing)."""
    for s in rots:
        step = np.diff(t[s.rows])
        gaps = step > 1.5 / rate
        if gaps.any():
            missing = int(np.round(step[gaps] * rate).sum()) - int(gaps.sum())
            warnings.warn(f"{s.where}: {int(gaps.sum())} gap(s) in time inside the turn (largest {step.max():.4g} s "
                          f"against the {1.0 / rate:.4g} s step; about {missing} samples missing): the turn is "
                          "integrated over the recorded times", TimeGapWarning, stacklevel=3)


def check_positions(segs: Sequence[Segment], acc: np.ndarray, unit: str) -> None:
    """Refuse a static segment whose accelerometer mean points away from its stated gravity.

    The means are centred on their average when the stated directions balance (a Ferraris set),
    so a raw bias does not count; a segment whose centred mean makes more than 45 deg with its
    stated direction is mislabelled (the nearest axis is named).
    """
    st = [s for s in segs if s.kind == "static"]
    if len(st) < 2:
        return
    means = np.array([acc[s.rows].mean(axis=0) for s in st])
    dirs = np.array([s.gravity for s in st])
    centre = means.mean(axis=0) if np.linalg.norm(dirs.sum(axis=0)) < 1e-9 else np.zeros(3)
    for s, m, e in zip(st, means, dirs):
        v = m - centre
        nv = float(np.linalg.norm(v))
        if nv == 0:
            continue
        cos = float(v @ e) / nv
        if cos < math.cos(math.radians(45.0)):
            k = int(np.argmax(np.abs(v)))
            looks = f"{'+' if v[k] > 0 else '-'}{'xyz'[k]}"
            raise ValueError(f"{s.where}: the accelerometer mean [{', '.join(f'{x:.4g}' for x in m)}] {unit} points "
                             f"{math.degrees(math.acos(max(-1.0, min(1.0, cos)))):.0f} deg away from the stated "
                             f"gravity {e.round(3).tolist()} (it looks like gravity along {looks}): a mislabelled "
                             "position? Fix the label or the segment's gravity")


def warn_misfit(static, S_static, r, level, sensor, unit, reading_scale, S_fit) -> None:
    """PositionMisfitWarning for a static segment whose studentized row residual exceeds MISFIT_Z.

    `S_static`, `r`: the static rows and their residuals in the fit of the rows `S_fit` (the static
    rows first); leverage ``h = diag(S (S^T S)^+ S^T)`` of the fit.
    """
    U, sv, _ = np.linalg.svd(S_fit, full_matrices=False)
    keep = sv > sv[0] * 1e-10 if sv.size else sv > 0
    h = np.sum(U[:, keep] ** 2, axis=1)[:S_static.shape[0]]
    # residuals at the rounding level of the rows (a noise-free session: casep's one rule) are no misfit
    floor = float(rounding_level(reading_scale))
    z = np.where(np.abs(r) <= floor, 0.0, r / (max(level, floor, 1e-300) * np.sqrt(np.clip(1.0 - h, 1e-12, None))))
    for k, s in enumerate(static):
        zk = z[3 * k:3 * k + 3]
        if np.max(np.abs(zk)) > MISFIT_Z:
            i = int(np.argmax(np.abs(zk)))
            warnings.warn(f"{s.where}: the {sensor} mean misfits the model by {r[3 * k + i]:+.4g} {unit} "
                          f"on {'xyz'[i]}, {abs(zk[i]):.3g} x its std from the other positions' level ({level:.4g} "
                          f"{unit}): a bad position or a wrong label?", PositionMisfitWarning, stacklevel=3)


def check_rotation_signs(model, rots, gyr, gravity, rate, est, unit) -> None:
    """RotationSignWarning where the fitted sensitivity about a turn's axis is negative."""
    x = np.where(np.isfinite(est), est, 0.0)
    for s in rots:
        f = gravity * s.gravity
        a = s.axis
        z = np.zeros(3)
        # d reading / d omega along the axis, per rad/s: [y(f, a) - y(f, 0)] . a (the reading is affine in omega)
        dy = (model.known("gyro_reading", f, a) - model.known("gyro_reading", f, z)
              + (model.jacobian("gyro_reading", f, a) - model.jacobian("gyro_reading", f, z)) @ x)
        sens = float(dy @ a) * math.pi / 180.0  # per deg/s
        if sens < 0:
            integral = float(gyr[s.rows].sum(axis=0) @ a / rate)
            warnings.warn(
                f"{s.where}: the gyro reading about {np.round(a, 3).tolist()} integrates to {integral:+.5g} {unit} s, "
                f"the opposite sign of the expected angle {s.angle_deg:+g} deg: the fitted scale about that axis is "
                f"{sens:.5g} {unit} per deg/s. The turn went the other way (--angle {-s.angle_deg:+g}) or the gyro "
                "axis is inverted", RotationSignWarning, stacklevel=3)


def segment_misfits(segments: Sequence[Segment], seg: Sequence[tuple[str, int]], sd: Sequence,
                    r: np.ndarray, s_i: np.ndarray, unit: str) -> dict[str, dict]:
    """Per segment the residual of its row, the noise std of that row and their RMS ratio.

    `seg`, `sd`: per block of rows the segment name with its number of row triples and the rows'
    noise std (as :func:`casep.calibration.rows.sensor_rows` gives them); `r`: the residuals of the
    unweighted rows; `s_i`: the sample noise per axis; `unit`: the sensor's reading unit. A static
    segment's residual is the mean of its rows, its noise ``s_i / sqrt(n)``; a turn's, its one row
    (unit times s, an integral) and its integrated white noise.
    """
    out: dict[str, dict] = {}
    k0 = 0
    for (name, k), sdv in zip(seg, sd):
        rr = r[k0:k0 + 3 * k].reshape(k, 3)
        k0 += 3 * k
        segment = next(s for s in segments if s.name == name)
        if segment.kind == "static":
            noise = s_i / math.sqrt(len(segment.rows))
            resid = rr.mean(axis=0)
        else:
            noise = np.asarray(sdv)
            resid = rr[0]
        ratio = float(np.sqrt(np.mean(resid**2)) / max(float(np.sqrt(np.mean(noise**2))), 1e-300))
        out[name] = {"residual": resid.tolist(), "noise_std": noise.tolist(), "ratio": ratio,
                     "unit": unit if segment.kind == "static" else f"{unit} s"}  # a turn's row: an integral
    return out

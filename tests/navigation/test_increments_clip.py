"""Clipped samples of an increments record (casep.navigation.imu.check_imu): judged on the increments as the IMU
gave them, each over its period, not on increments divided by steps of t whose rounding looks like noise."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from casep.checks.saturation import CLIP_MARGIN, held_full_scale
from casep.exceptions import SaturationWarning
from casep.navigation.imu import ImuData, check_imu, sample_periods

H, T0, N = 0.005, 990.0, 6000


def _boost(rng=None, noise=(0.0, 0.0)):
    """Increments (rad, m/s per H) of a boost: a pad (a constant specific force with 0.17 g on z, a constant rate)
    for 10 s, then a smooth lift-off and roll (the pad's specific force on z its column's maximum); `noise`
    (rad/s, m/s^2) white on the rates."""
    t = T0 + H * np.arange(N)  # the steps of t differ in their last bits
    s = np.clip(t - (T0 + 10.0), 0.0, None)
    r = np.minimum(1.0, s / 5.0)
    roll = np.radians(60.0) * np.minimum(1.0, s / 2.0) * (1 + np.clip((s - 10.0) / 2, 0, 1))
    w = np.column_stack([roll, np.radians(2.0) * np.sin(0.5 * s), np.radians(1.5) * np.sin(0.3 * s)])
    w = w + [7e-5, 1e-5, -1e-5]
    f = np.column_stack([9.67 + 30.0 * np.minimum(1.0, s / 0.5) ** 2, 0.4 * np.sin(0.7 * s),
                         1.7059 - 2.0 * r**2 + 0.3 * np.sin(s) * r])
    if rng is not None:
        w = w + noise[0] * rng.standard_normal(w.shape)
        f = f + noise[1] * rng.standard_normal(f.shape)
    return t, w * H, f * H


def test_a_noise_free_increments_record_held_on_its_pad_is_no_clip():
    """The pad's constant increments, divided by the steps of t, differ in their last bits and the old reading of
    them saw a rail entered and left at 0.174 g; read as the IMU gave them they are a state held from the first
    sample: no SaturationWarning, nothing marked (the same record as rates neither)."""
    t, dth, dv = _boost()
    assert held_full_scale(dv / sample_periods(t)[:, None], "accelerometer") != []  # what went wrong
    with warnings.catch_warnings():
        warnings.simplefilter("error", SaturationWarning)
        imu = check_imu(ImuData(t, np.zeros_like(dth), np.zeros_like(dv), "increments", dth, dv))
        assert imu.clipped is None
        assert check_imu(ImuData(t, dth / H, dv / H)).clipped is None


@pytest.mark.parametrize("declared", [None, 100.0])
def test_clipped_increments_are_found_and_said_in_their_own_unit(declared):
    """A noisy roll 120 deg/s whose increments the IMU clipped at 100 deg/s times its period to the end of the
    record: found (implied, or declared with --gyr-range 100), the rows from the first clip on marked, the message
    in rad over the period and in deg/s."""
    rng = np.random.default_rng(2)
    t, dth, dv = _boost(rng, (1e-4, 2e-3))
    cap = math.radians(100.0) * H
    dth[:, 0] = np.minimum(dth[:, 0], cap)
    fs = None if declared is None else math.radians(declared)
    level = cap if declared is None else (1 - CLIP_MARGIN) * cap  # declared: within 1 % of it is at it
    first = int(np.flatnonzero(dth[:, 0] < level)[-1]) + 1  # the clip lasts to the end
    with pytest.warns(SaturationWarning) as rec:
        imu = check_imu(ImuData(t, np.zeros_like(dth), np.zeros_like(dv), "increments", dth, dv), gyr_range=fs)
    said = " ".join(str(m.message) for m in rec if m.category is SaturationWarning)
    why = "the declared 100 deg/s" if declared else "a full scale +-100 deg/s implied"
    assert f"dth_x: {N - first} samples at full scale ({why}" in said
    assert "its maximum 0.00872665 rad over 0.005 s = 100 deg/s" in said and "dth_y" not in said and "dvb" not in said
    assert imu.clipped is not None and np.array_equal(imu.clipped, np.arange(N) >= first)


@pytest.mark.parametrize("kind", ["rates", "increments"])
def test_a_declared_full_scale_the_record_exceeds_is_refused_naming_column_and_row(kind):
    """The same roll read up to 100 deg/s, declared with --gyr-range 20: a sensor clipped at 20 deg/s cannot read
    100 (main called the whole roll clipped at the declared 20 and navigated the rest); refused, naming the column,
    the first row beyond 1.5 times the declared range, the reading and the option. 100 deg/s declared: no error."""
    rng = np.random.default_rng(2)
    t, dth, dv = _boost(rng, (1e-4, 2e-3))
    dth[:, 0] = np.minimum(dth[:, 0], math.radians(100.0) * H)
    imu = ImuData(t, np.zeros_like(dth), np.zeros_like(dv), "increments", dth, dv) if kind == "increments" else \
        ImuData(t, dth / H, dv / H)
    first = int(np.flatnonzero(np.abs(dth[:, 0]) > 1.5 * math.radians(20.0) * H)[0])
    col = "dth_x" if kind == "increments" else "w_x"
    with pytest.raises(ValueError, match=rf"column `{col}`, row {first + 1} \(t = .*\): the gyro reads up to 100 "
                                         r"deg/s, 5 times the declared full scale 20 deg/s \(--gyr-range\)"):
        check_imu(imu, gyr_range=math.radians(20.0))
    with pytest.warns(SaturationWarning):
        check_imu(imu, gyr_range=math.radians(100.0))

"""Single-sample spikes in a raw IMU record (casep.navigation.imu.single_sample_spikes): named with column, row,
time, size and what the navigation takes from them; steps, corners, vibration bursts and quantisation are not."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from casep.exceptions import OutlierWarning
from casep.navigation import ImuData, check_imu
from casep.navigation.imu import single_sample_spikes
from casep.units import G0

RATE = 20.0


def _boost(n: int, rng, noise_w: float, noise_f: float):
    """A pad, a thrust step from 1 g to 5 g at row 200 (and off at row 1400), a rolling and pitching motion."""
    t = np.arange(n) / RATE - 10.0
    thrust = np.where((t >= 0.0) & (t < 60.0), 4.0 * G0, 0.0)
    f = np.column_stack([G0 + thrust + 0.2 * np.sin(0.3 * t), 0.5 * np.sin(0.7 * t), 0.3 * np.cos(0.4 * t)])
    w = np.column_stack([np.radians(60.0) * np.clip(t / 2.0, 0.0, 1.0), 0.05 * np.sin(0.5 * t),
                         0.03 * np.sin(1.3 * t)])
    return t, w + noise_w * rng.standard_normal(w.shape), f + noise_f * rng.standard_normal(f.shape)


@pytest.mark.parametrize("noise", [0.0, 1.0])
def test_a_single_sample_glitch_is_named_and_a_thrust_step_is_not(noise):
    """+50 m/s^2 on one fb_x sample (a glitch: 2.5 m/s at 20 Hz) during the boost, with and without
    sensor noise: one warning naming fb_x, the row, the time, the size and the velocity it adds (size times the
    step, computed here); the thrust steps on and off (4 g), the corners of the motion are no spike."""
    rng = np.random.default_rng(4)
    t, w, f = _boost(3000, rng, 2e-3 * noise, 2e-2 * noise)
    assert single_sample_spikes(w) == [] and single_sample_spikes(f) == []
    f[900, 0] += 50.0
    found = single_sample_spikes(f)
    assert [(k, j) for k, j, *_ in found] == [(900, 0)]
    size = f[900, 0] - max(f[899, 0], f[901, 0])  # the smaller of the two differences
    assert found[0][2] == pytest.approx(size, rel=1e-12) and 49.0 < size < 50.5
    with pytest.warns(OutlierWarning) as rec:
        check_imu(ImuData(t, w, f, source="boost.csv"))
    said = [str(r.message) for r in rec]
    assert len(said) == 1
    assert f"fb_x row 901 (t = {t[900]:.10g} s): {size:+.4g} m/s^2" in said[0]
    assert f"adding {size / RATE:+.3g} m/s to the velocity" in said[0] and "1 single-sample spike" in said[0]


def test_a_gyro_spike_names_the_attitude_and_the_velocity_error_it_grows():
    """A 0.5 rad/s spike on w_z at row 1000: the attitude turned by 0.5 / 20 rad, the velocity error it grows
    per second |f| times that."""
    rng = np.random.default_rng(6)
    t, w, f = _boost(3000, rng, 2e-3, 2e-2)
    w[1000, 2] += 0.5
    with pytest.warns(OutlierWarning) as rec:
        check_imu(ImuData(t, w, f))
    said = str(rec[0].message)
    size = w[1000, 2] - max(w[999, 2], w[1001, 2])
    assert f"w_z row 1001 (t = {t[1000]:.10g} s): {size:+.4g} rad/s" in said
    assert f"turning the attitude by {math.degrees(size / RATE):.3g} deg" in said
    assert f"growing by {size / RATE * np.linalg.norm(f[1000]):.3g} m/s per s" in said


def test_vibration_bursts_quantised_readings_and_real_drives_are_no_spike():
    """A burst of vibration (alternating samples 30 times the noise, over six rows): motion, not one bad sample;
    a quantised accelerometer at rest whose counts flip by one; the real car drive (tests/data/car_drive: engine
    running at rest, then pulling out), which its own noise explains: nothing named, no warning."""
    from pathlib import Path

    rng = np.random.default_rng(9)
    t, w, f = _boost(3000, rng, 2e-3, 2e-2)
    f[1500:1506, 1] += 0.6 * np.array([1, -1, 1, -1, 1, -1])
    assert single_sample_spikes(f) == []
    lsb = G0 / 16384.0
    counts = np.round(np.tile([0.0, 0.0, G0], (4000, 1)) / lsb + 0.3 * rng.standard_normal((4000, 3))) * lsb
    assert single_sample_spikes(counts) == []
    car = np.loadtxt(Path(__file__).resolve().parents[1] / "data" / "car_drive" / "imu.csv.gz", delimiter=",",
                     skiprows=1)
    assert single_sample_spikes(car[:, 1:4]) == [] and single_sample_spikes(car[:, 4:7]) == []
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_imu(ImuData(car[:, 0], car[:, 1:4], car[:, 4:7]))

"""The tilt taken out of the specific force at rest (benchmarks/car_drive.py, ``tilt_free_force``): a body rocking on
its springs, its attitude integrated exactly from a known body rate (SciPy's rotations, not the function's small-angle
cross product), and an accelerometer bias that wanders."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation


@pytest.fixture(scope="module")
def car():
    from conftest import benchmark_module

    with benchmark_module("car_drive") as mod:
        yield mod


def _rocking(rng, n: int = 3000, step: float = 0.01):
    """Times, the body rate (rad/s) and the specific force in the body (m/s^2) of a body at rest on a slope
    (f_n not vertical in its mean body axes) rocking about x at 1.3 Hz (2 mrad) and about y at 0.7 Hz (0.5 mrad), with
    a slow roll out and back of 1 mrad over the record (a constant rate is a gyro bias: the mean rate goes); the
    attitude is the exact product of each step's rotation."""
    t = step * np.arange(n)
    w = np.column_stack([2e-3 * 2 * np.pi * 1.3 * np.cos(2 * np.pi * 1.3 * t)
                         + 1e-3 * np.pi / t[-1] * np.sin(2 * np.pi * t / t[-1]),
                         5e-4 * 2 * np.pi * 0.7 * np.cos(2 * np.pi * 0.7 * t + 0.4),
                         2e-4 * np.sin(2 * np.pi * 0.2 * t)])
    att = [Rotation.identity()]
    for k in range(n - 1):  # the body turns by the mean rate over each step (exact for the midpoint rotation)
        att.append(att[-1] * Rotation.from_rotvec(0.5 * (w[k] + w[k + 1]) * step))
    f_n = np.array([0.25, -0.15, 9.79])
    f_b = np.stack([a.inv().apply(f_n) for a in att])
    return t, w, f_b


def test_a_rocking_body_leaves_a_constant_force(car, rng):
    """No accelerometer error: the force with the tilt taken out is constant to the second order of the angles
    (3 mrad: 1e-4 m/s^2 here), where the rocking moves fb_y by g 2 mrad = 0.02 m/s^2 and fb_x by 5e-3; a constant gyro
    bias (removed with the mean rate) changes nothing."""
    t, w, f = _rocking(rng)
    for bias in (0.0, 3e-3):
        out = car.tilt_free_force(f, w + bias, t)
        assert np.ptp(f[:, 1]) > 0.03 and np.ptp(f[:, 0]) > 0.008
        assert np.abs(out - out.mean(axis=0)).max() < 1e-4


def test_the_wander_of_the_bias_is_left_and_the_allan_deviation_is_the_biass(car, rng):
    """A bias random walk on fb_y (and white noise) under the rocking: what is left is the bias and the noise (to the
    second order of the angles), and its Allan deviation at 10 s is the bias's own within 2 %, while the rocking
    alone makes it several times larger."""
    import allantools

    t, w, f = _rocking(rng)
    b = np.zeros_like(f)
    b[:, 1] = 1e-4 * np.cumsum(rng.standard_normal(t.size)) + 2e-3 * rng.standard_normal(t.size)
    out = car.tilt_free_force(f + b, w, t)
    np.testing.assert_allclose(out - out.mean(axis=0), b - b.mean(axis=0), rtol=0.0, atol=2e-4)
    ad = [allantools.oadev(x, rate=100.0, data_type="freq", taus=np.array([10.0]))[1][0]
          for x in (out[:, 1], b[:, 1], f[:, 1] + b[:, 1])]
    assert ad[0] == pytest.approx(ad[1], rel=0.02)
    assert ad[2] > 3.0 * ad[1]

"""regular_time: the uniform grid of a fixed-rate IMU under jittered time tags, against closed forms."""

from __future__ import annotations

import math

import numpy as np

from casep.navigation.imu import regular_time
from casep.rotations import increments_from_rates

STEP = 0.0100029  # a 100 Hz IMU whose oscillator is 290 ppm slow, tagged by a millisecond counter


def _tags(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """The true sample times and their tags: read up to 1 ms late, then truncated to the millisecond."""
    rng = np.random.default_rng(seed)
    true = 3.0 + STEP * np.arange(n)
    return true, np.floor((true + rng.uniform(0.0, 1e-3, n)) * 1e3) / 1e3


def test_grid_recovered_from_millisecond_tags():
    """The grid is the true one shifted by the tags' mean lateness (1 ms: reading up to 1 ms late, floored)
    to far below the tag error; the step to 1e-8 relative."""
    true, tags = _tags(3000, 1)
    grid = regular_time(tags)
    assert grid is not None
    assert np.max(np.abs(tags - true)) > 5e-4  # the tags do jitter
    lateness = float(np.mean(grid - true))
    assert abs(lateness) < 1e-3
    assert np.max(np.abs(grid - true - lateness)) < 5e-5
    assert abs(np.mean(np.diff(grid)) / STEP - 1.0) < 1e-8 * 3000


def test_lost_sample_or_rate_change_is_not_a_grid():
    """A lost sample shifts later tags by a whole step; a rate change bends the line: None."""
    _, tags = _tags(2000, 2)
    assert regular_time(np.delete(tags, 700)) is None
    bent = tags + np.where(np.arange(tags.size) > 1000, 0.01 * (np.arange(tags.size) - 1000) * STEP, 0.0)
    assert regular_time(bent) is None


def test_grid_removes_the_attitude_random_walk_of_jittered_tags():
    """A rate vibrating near the Nyquist frequency, w = A sin(2 pi f t): its angle is the closed form
    A (1 - cos 2 pi f t) / (2 pi f); integrated on the tags it random-walks away, on the grid it does not."""
    true, tags = _tags(3000, 3)
    A, f = 0.05, 37.0  # 2.9 deg/s at 37 Hz, as a car engine's on a 100 Hz IMU
    w = np.zeros((true.size, 3))
    w[:, 0] = A * np.sin(2 * math.pi * f * (true - true[0]))
    exact = A * (1 - math.cos(2 * math.pi * f * (true[-1] - true[0]))) / (2 * math.pi * f)
    grid = regular_time(tags)
    assert grid is not None
    on_tags = increments_from_rates(tags, w, np.zeros_like(w)).dtheta[:, 0].sum()
    on_grid = increments_from_rates(grid, w, np.zeros_like(w)).dtheta[:, 0].sum()
    on_true = increments_from_rates(true, w, np.zeros_like(w)).dtheta[:, 0].sum()
    assert abs(on_tags - exact) > 10 * abs(on_grid - exact)  # 1e-3 rad against the quadrature's 5e-5
    assert abs(on_grid - on_true) < 1e-3 * abs(on_grid - exact)  # the grid integrates as the true times do

"""The time-offset test under Gauss-Markov plus white tracking noise: whitened for the fit's noise model, its
t-statistic is standard normal; the lag-1 AR(1) factor alone makes it several times too large."""

from __future__ import annotations

import numpy as np
from conftest import bias_scale_rows, gm_white_noise

from casep.checks.time_offset import GRAVITY_LAUNCH, time_offset_test
from casep.noise.model import NoiseModel
from casep.regression.problem import Problem
from casep.units import G0

RATE, TAU, GM, WHITE = 50.0, 1.0, 0.1, 0.05  # Hz, s, m/s, m/s: the strapdown-boost scenario's tracking noise


def _rows():
    """A 60 s boost at 50 Hz (5 g, a step to 2 g at 30 s, a lateral wobble); S: initial velocity errors,
    accelerometer biases and the scale factor along the thrust."""
    t = np.arange(0.0, 60.0, 1.0 / RATE)
    up = np.array([0.1, 0.99, 0.0]) / np.linalg.norm([0.1, 0.99, 0.0])
    f = np.where(t < 30.0, 5.0 * G0, 2.0 * G0)[:, None] * up
    f[:, 2] += 2.0 * np.sin(0.7 * t)
    return t, f, bias_scale_rows(t, f, up)


def _noise(t: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    return gm_white_noise(t, rng, TAU, GM, WHITE)


def test_offset_t_is_standard_normal_when_whitened_for_the_noise_model():
    """40 seeded draws without an offset: RMS t 0.7-1.3 whitened for the true model (the RMS of 40 standard
    normals has std 0.11), above 1.8 with the lag-1 factor (about 3: the white part lowers the lag-1
    correlation, not the Gauss-Markov part's long-run variance); a 20 ms offset is still found whitened."""
    t, f, S = _rows()
    share = WHITE**2 / (GM**2 + WHITE**2)
    model = NoiseModel(kind="gmw", tau=(TAU,) * 3, share=(share,) * 3)
    white, lag1 = [], []
    for seed in range(40):
        dv = _noise(t, np.random.default_rng(seed))
        pb = Problem.from_arrays(S, dv, t, f=f)
        white.append(time_offset_test(pb, dv, t, f, noise=model).offset_t)
        lag1.append(time_offset_test(pb, dv, t, f).offset_t)
    rms_w, rms_1 = float(np.sqrt(np.mean(np.square(white)))), float(np.sqrt(np.mean(np.square(lag1))))
    assert 0.7 <= rms_w <= 1.3, rms_w
    assert rms_1 > 1.8, rms_1
    dv = _noise(t, np.random.default_rng(99)) + (f + GRAVITY_LAUNCH) * 0.020
    test = time_offset_test(Problem.from_arrays(S, dv, t, f=f), dv, t, f, noise=model)
    assert test.inflation == 1.0 and abs(test.offset - 0.020) < 4 * test.offset_std and test.offset_t > 5

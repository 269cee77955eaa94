"""The time-offset test under Gauss-Markov plus white tracking noise: whitened for the fit's noise model, its
t-statistic is standard normal; the lag-1 AR(1) factor alone makes it several times too large."""

from __future__ import annotations

import numpy as np

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
    F = np.concatenate([[np.zeros(3)], np.cumsum(0.5 * (f[1:] + f[:-1]) * np.diff(t)[:, None], axis=0)])
    S = np.zeros((t.size, 3, 7))
    S[:, :, :3] = np.eye(3)
    S[:, :, 3:6] = t[:, None, None] * np.eye(3)
    S[:, :, 6] = np.einsum("ki,i->k", F, up)[:, None] * up
    return t, f, S


def _noise(t: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Gauss-Markov (exact discretisation, stationary start) plus white noise per axis, independent of casep."""
    phi = np.exp(-np.diff(t) / TAU)
    e = rng.standard_normal((t.size, 3))
    g = np.empty((t.size, 3))
    g[0] = GM * e[0]
    for k in range(1, t.size):
        g[k] = phi[k - 1] * g[k - 1] + GM * np.sqrt(1.0 - phi[k - 1] ** 2) * e[k]
    return g + WHITE * rng.standard_normal((t.size, 3))


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

"""The time-offset test at a step of the acceleration (a burnout within one sample): the tracking late by dt
ramps over the samples within dt after the step, where the first-order term ``a(t) dt`` jumps; the test frees
those samples (casep.checks.time_offset.step_rows) and finds the offset within its std."""

from __future__ import annotations

import numpy as np
from conftest import bias_scale_rows, gm_white_noise

from casep.checks.time_offset import GRAVITY_LAUNCH, acceleration_steps, time_offset_test
from casep.noise.model import NoiseModel
from casep.regression.problem import Problem
from casep.units import G0

RATE, TAU, GM, WHITE, STEP_T = 50.0, 1.0, 0.1, 0.05, 30.0  # Hz, s, m/s, m/s, s
UP = np.array([0.1, 0.99, 0.0]) / np.linalg.norm([0.1, 0.99, 0.0])


def _force(t: np.ndarray) -> np.ndarray:
    """5 g along UP, 2 g from STEP_T on (the sample at STEP_T has 2 g), a lateral wobble 2 sin(0.7 t) m/s^2."""
    f = np.where(t < STEP_T, 5.0 * G0, 2.0 * G0)[:, None] * UP
    f[:, 2] += 2.0 * np.sin(0.7 * t)
    return f


def _late(t: np.ndarray, dt: float) -> np.ndarray:
    """``v(t) - v(t - dt)``, the integral of ``a = f + g`` over ``[t - dt, t]`` in closed form: what tracking dt
    late adds to dv, the ramp across the step included."""
    before = np.clip(np.minimum(t, STEP_T) - (t - dt), 0.0, dt)  # the part of [t - dt, t] before the step
    out = ((5.0 * G0 * before + 2.0 * G0 * (dt - before))[:, None] * UP) + GRAVITY_LAUNCH * dt
    out[:, 2] += 2.0 / 0.7 * (np.cos(0.7 * (t - dt)) - np.cos(0.7 * t))
    return out


def _rows():
    t = np.arange(0.0, 60.0, 1.0 / RATE)
    f = _force(t)
    return t, f, bias_scale_rows(t, f, UP)  # initial velocity errors, accelerometer biases, the scale factor


def _noise(t: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    return gm_white_noise(t, rng, TAU, GM, WHITE)


def test_acceleration_steps_finds_the_step_not_the_smooth_flight():
    """The 3 g step and nothing else (the lateral wobble's change within a sample, <= 0.028 m/s^2, adds < 2e-5 to
    the step's norm); the same 3 g over a 1 s cosine taper is no step."""
    t, f, _ = _rows()
    at, size = acceleration_steps(f + GRAVITY_LAUNCH)
    assert list(t[at]) == [STEP_T] and abs(size[0] - 3.0 * G0) < 1e-4, (t[at], size)
    taper = 0.5 - 0.5 * np.cos(np.pi * np.clip(t - STEP_T, 0.0, 1.0))  # 0 -> 1 over [STEP_T, STEP_T + 1]
    smooth = f.copy()
    smooth[:, :2] = ((5.0 - 3.0 * taper) * G0)[:, None] * UP[:2]
    assert acceleration_steps(smooth + GRAVITY_LAUNCH)[0].size == 0


def test_offset_at_a_step_is_found_within_its_std():
    """A 30 ms offset, exact (the ramp across the step), Gauss-Markov plus white noise whitened for its model,
    10 seeds: each within 3 std and the mean z within 3/sqrt(10) ~ 0.95 of 0. Before the step's samples were
    freed: z -5.3 to -7.4 on every seed."""
    t, f, S = _rows()
    share = WHITE**2 / (GM**2 + WHITE**2)
    model = NoiseModel(kind="gmw", tau=(TAU,) * 3, share=(share,) * 3)
    z = []
    for seed in range(10):
        dv = _noise(t, np.random.default_rng(seed)) + _late(t, 0.030)
        test = time_offset_test(Problem.from_arrays(S, dv, t, f=f), dv, t, f, noise=model)
        assert test.freed > 0 and test.offset_t > 5
        z.append((test.offset - 0.030) / test.offset_std)
    assert np.max(np.abs(z)) < 3.0 and abs(np.mean(z)) < 0.95, z

"""The robust filter's start: the samples before its first accepted one are judged backward."""

from __future__ import annotations

import numpy as np

from casep.noise.model import NoiseModel
from casep.noise.robust import robust_filter
from casep.simulation.noise import ar1_noise

GM = NoiseModel(kind="gm", tau=(1.0, 1.0, 1.0))


def _started_late(level: float, seed: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Markov residuals (tau 1 s, std 0.1) of a flight tracked from a moment when the y axis
    stood at `level` m/s: the state the noise carries from before tracking decays as exp(-t / tau)."""
    t = np.arange(400) * 0.05
    e = ar1_noise(t, 0.1, 1.0, np.random.default_rng(seed))
    e[:, 1] += level * np.exp(-t / 1.0)
    return e, t


def test_a_flight_starting_away_from_zero_keeps_its_first_samples():
    """10 std at the first sample, ordinary innovations: forward alone rejected the first samples as a
    run (no prediction before the first accepted one); judged backward, none is a glitch."""
    e, t = _started_late(1.0)
    rw = robust_filter(e, t, GM, scale=0.1)
    assert list(rw.rejected) == []


def test_a_glitch_on_the_first_sample_is_still_rejected_alone():
    for level in (0.0, 1.0):
        e, t = _started_late(level)
        e[0, 0] += 1.5  # 15 std
        rw = robust_filter(e, t, GM, scale=0.1)
        assert list(rw.rejected) == [0], level
        e[1, 2] -= 1.2  # and the second: two glitches of different size and axis
        assert list(robust_filter(e, t, GM, scale=0.1).rejected) == [0, 1], level


"""The robust filter's innovation variance carries the fit's own uncertainty (``H P H^T + R``), in closed form.

A residual at an epoch where the fit cannot say what the flight did (at lift-off the specific force jumps
tenfold, so every scale factor, misalignment, attitude and time-tag error grows as much) is not a glitch
unless it is beyond the noise and that uncertainty together; a glitch still is.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from casep.noise.model import NoiseModel
from casep.noise.robust import REJECT, robust_filter

SIGMA = 0.1  # m/s, the noise (given: the robust scale is not estimated here)


def _white_case(size: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Residuals zero but sample 50 (axis 0: `size` m/s), its prediction factor G = (0.09, 0.12) (|G| = 0.15)."""
    t = np.arange(100) * 0.1
    e = np.zeros((100, 3))
    e[50, 0] = size
    G = np.zeros((100, 3, 2))
    G[50, 0] = (0.09, 0.12)
    return e, t, G


def test_white_axis_threshold_is_noise_and_prediction_together():
    """nu = e / sqrt(sigma^2 + |G|^2) = e / 0.180 m/s: rejected just above 4 x 0.180, kept just below; without
    the prediction a residual of 5 sigma is rejected."""
    edge = REJECT * math.sqrt(SIGMA**2 + 0.15**2)
    for size, rejected in ((edge * (1 + 1e-6), [50]), (edge * (1 - 1e-6), []), (0.5, [])):
        e, t, G = _white_case(size)
        assert list(robust_filter(e, t, NoiseModel.white(), scale=SIGMA, predicted=G).rejected) == rejected, size
    e, t, _ = _white_case(0.5)
    assert list(robust_filter(e, t, NoiseModel.white(), scale=SIGMA).rejected) == [50]  # 5 sigma, no prediction


@pytest.mark.parametrize("side", [1, -1])
def test_gauss_markov_innovation_from_the_last_kept_sample(side):
    """tau 1 s, 0.1 s steps: the innovation of sample 50 from sample 49 is e_50 / sqrt(sigma^2 (1 - a^2) +
    |G_50 - a G_49|^2); after it the residuals decay as the AR(1) does (innovations 0: kept)."""
    tau, dt = 1.0, 0.1
    a = math.exp(-dt / tau)
    t = np.arange(100) * dt
    G = np.zeros((100, 3, 2))
    G[49:, 1] = (0.02, 0.0)  # the prediction before the jump
    G[50:, 1] = (0.02, 0.3)  # ... and after it: |G_50 - a G_49|^2 = (0.02 (1 - a))^2 + 0.09
    var = SIGMA**2 * (1 - a * a) + (0.02 * (1 - a)) ** 2 + 0.3**2
    edge = REJECT * math.sqrt(var)
    gm = NoiseModel(kind="gm", tau=(tau, tau, tau))
    for size, rejected in ((edge * (1 + 1e-6), [50]), (edge * (1 - 1e-6), [])):
        e = np.zeros((100, 3))
        e[50:, 1] = side * size * a ** np.arange(50)
        assert list(robust_filter(e, t, gm, scale=SIGMA, predicted=G).rejected) == rejected, size
        # without the prediction the same step is 1.21 / 0.0426 = 28 sigma: rejected (a run from it)
        assert robust_filter(e, t, gm, scale=SIGMA).rejected[0] == 50


def test_a_two_metre_glitch_is_rejected_where_the_prediction_is_uncertain():
    """A wrong epoch of a receiver (2 m/s off) in 0.03 m/s noise where the fit's prediction is uncertain to
    0.18 m/s (growing to 0.3 m/s over 0.5 s): 12 of the combined sigma, rejected, alone; the epochs beside it, which
    the fit misses by 1.5 of its own std (up to 9 of the noise's), kept."""
    rng = np.random.default_rng(4)
    t = np.arange(400) * 0.1
    e = rng.normal(0, 0.03, (400, 3))
    G = np.zeros((400, 3, 1))
    G[200:, :, 0] = 0.3 * np.minimum((t[200:, None] - t[200]) / 0.5, 1.0)  # uncertainty growing over 0.5 s
    e[200:205] += G[200:205, :, 0] * 1.5  # the fit misses by 1.5 of its own std: not glitches
    e[203, 2] += 2.0
    rw = robust_filter(e, t, NoiseModel.white(), predicted=G)
    assert list(rw.rejected) == [203]
    assert {202, 203, 204} <= set(robust_filter(e, t, NoiseModel.white()).rejected)  # the noise alone


def test_predicted_must_match_the_residuals():
    e, t, G = _white_case(0.1)
    with pytest.raises(ValueError, match="shape"):
        robust_filter(e, t, NoiseModel.white(), scale=SIGMA, predicted=G[:, :2])

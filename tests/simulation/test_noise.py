"""Tracking-noise models (casep.simulation.noise)."""

from __future__ import annotations

import numpy as np
import pytest

from casep.simulation.noise import NoiseModel, ar1_noise


def _lag1(x):
    x = x - x.mean(0)
    return np.sum(x[1:] * x[:-1], 0) / np.sum(x * x, 0)


def test_white_statistics(rng):
    n = NoiseModel("white", 0.1).sample(np.arange(50_000) * 0.01, rng)
    np.testing.assert_allclose(n.std(0), 0.1, rtol=0.03)
    assert np.all(np.abs(_lag1(n)) < 0.02)


def test_ar1_statistics_and_stationarity(rng):
    t = np.arange(200_000) * 0.01
    n = ar1_noise(t, 0.1, 0.05, rng)  # a = exp(-0.2) = 0.819
    np.testing.assert_allclose(n.std(0), 0.1, rtol=0.05)
    np.testing.assert_allclose(_lag1(n), np.exp(-0.2), atol=0.01)
    # Variance at the first sample equals the stationary one (n_0 ~ N(0, sigma^2)).
    first = np.array([ar1_noise(t[:2], 0.1, 0.05, np.random.default_rng(k))[0, 0] for k in range(3000)])
    np.testing.assert_allclose(first.std(), 0.1, rtol=0.05)


def test_outliers_and_gaps(rng):
    m = NoiseModel("white", 0.1, outlier_rate=0.01, outlier_sigma=5.0, gaps=((1.0, 0.5),))
    t = np.arange(100_000) * 0.01
    n = m.sample(t, rng)
    share = np.mean(np.abs(n) > 1.0)  # nearly all outliers exceed 10 sigma of the base noise
    assert 0.007 < share < 0.011
    keep = m.keep_mask(t)
    assert not keep[(t >= 1.0) & (t < 1.5)].any() and keep[(t < 1.0) | (t >= 1.5)].all()


def test_validation():
    with pytest.raises(ValueError, match="`tau` must be > 0"):
        NoiseModel("ar1", 0.1)
    with pytest.raises(ValueError, match="`kind` must be"):
        NoiseModel("pink", 0.1)
    with pytest.raises(ValueError, match="each gap must be"):
        NoiseModel(gaps=((1.0, -1.0),))
    with pytest.raises(TypeError, match="`rng` must be a numpy.random.Generator"):
        NoiseModel().sample(np.arange(3.0), 42)

"""The standard-library tail probabilities against SciPy's (the library they stand in for)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import chdtrc, ndtr

from casep._special import chi2_sf, normal_sf


@pytest.mark.parametrize("k", [1, 2, 3, 4, 7, 10, 11, 24, 41, 79])
def test_chi2_sf_is_scipys(k):
    x = np.geomspace(1e-6, 3000.0, 300)
    mine = np.array([chi2_sf(k, float(v)) for v in x])
    ref = chdtrc(k, x)
    live = ref > 1e-300  # below, both are at the end of the doubles
    np.testing.assert_allclose(mine[live], ref[live], rtol=1e-12, atol=0.0)
    assert np.all(mine[~live] <= 1e-290)
    assert np.all(np.diff(mine) <= 1e-15 * mine[:-1] + 1e-300)  # a survival function (to rounding)


def test_chi2_sf_edges():
    assert chi2_sf(3, 0.0) == 1.0 and chi2_sf(3, -1.0) == 1.0
    assert chi2_sf(3, math.inf) == 0.0
    assert math.isnan(chi2_sf(3, math.nan))
    for bad in (0, -2, 2.5, True):
        with pytest.raises(ValueError, match="`k` must be a positive int"):
            chi2_sf(bad, 1.0)  # type: ignore[arg-type]


def test_normal_sf_is_scipys():
    x = np.linspace(-8.0, 8.0, 161)
    np.testing.assert_allclose([normal_sf(float(v)) for v in x], ndtr(-x), rtol=1e-13, atol=0.0)


def test_mad_sigma_is_the_normal_ratio_of_std_to_mad():
    """``MAD_SIGMA = 1 / Phi^-1(3/4)`` (the standard library's normal quantile), the one constant of every MAD scale."""
    import statistics

    from casep._special import MAD_SIGMA
    from casep.checks import plausibility
    from casep.estimators import huber
    from casep.noise import robust

    assert abs(MAD_SIGMA - 1.0 / statistics.NormalDist().inv_cdf(0.75)) < 1e-15
    assert robust.MAD_SIGMA is huber.MAD_SIGMA is plausibility.MAD_SIGMA

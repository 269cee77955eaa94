"""The one rule of casep's std from a covariance, and of the undetermined coefficients' NaN."""

from __future__ import annotations

import numpy as np

from casep.regression.linalg import covariance_std, undetermined_nan


def test_the_std_is_the_root_of_the_diagonal_with_a_roundings_negative_variance_zero():
    """``sqrt(diag C)`` of a covariance built from known std and correlations; a diagonal entry a rounding made
    negative reads 0 (not NaN), a NaN stays NaN."""
    s = np.array([0.5, 3.0, 2e-7])
    R = np.array([[1.0, 0.3, -0.2], [0.3, 1.0, 0.1], [-0.2, 0.1, 1.0]])
    C = R * np.outer(s, s)
    np.testing.assert_allclose(covariance_std(C), s, rtol=1e-15)
    C[2, 2] = -1e-30
    C[1, 1] = np.nan
    got = covariance_std(C)
    assert got[0] == 0.5 and np.isnan(got[1]) and got[2] == 0.0


def test_undetermined_coefficients_have_nan_rows_columns_and_std():
    """The rows and columns of the undetermined coefficients NaN in place, the others untouched; their std NaN."""
    C = np.arange(16.0).reshape(4, 4) + 16.0 * np.eye(4)
    und = np.array([False, True, False, True])
    out = undetermined_nan(C.copy(), und)
    assert np.all(np.isnan(out[und])) and np.all(np.isnan(out[:, und]))
    np.testing.assert_array_equal(out[np.ix_(~und, ~und)], C[np.ix_(~und, ~und)])
    std = covariance_std(out)
    assert np.all(np.isnan(std[und])) and np.all(np.isfinite(std[~und]))

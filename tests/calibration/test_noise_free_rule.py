"""Calibration judges a noise-free session by casep's one noise-free rule (casep.regression.problem)."""

from __future__ import annotations

import warnings
from types import SimpleNamespace

import numpy as np
import pytest

from casep.calibration.checks import PositionMisfitWarning, warn_misfit
from casep.regression.problem import NOISE_FREE, rounding_level


@pytest.mark.parametrize("scale", [1.0, 2.5e4])
def test_residuals_at_the_rounding_level_are_no_misfit(scale):
    """Residuals below rounding_level(scale) (a noise-free session's, of a file of ~10 digits) warn of no
    position, however small the level they are compared with; ten times the level, they do."""
    rng = np.random.default_rng(3)
    static = [SimpleNamespace(where=f"segment {k}") for k in range(6)]
    S = rng.normal(size=(18, 4))
    r_small = 0.3 * rounding_level(scale) * rng.uniform(-1.0, 1.0, 18)  # within the rounding level
    level = 1e-3 * NOISE_FREE * scale  # a level estimated from rounding alone
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warn_misfit(static, S, r_small, level, "accelerometer", "a.u.", scale, S)
    r_big = r_small.copy()
    r_big[4] = 10.0 * rounding_level(scale)  # beyond the rounding level: a misfit of segment 1
    with pytest.warns(PositionMisfitWarning, match="segment 1"):
        warn_misfit(static, S, r_big, level, "accelerometer", "a.u.", scale, S)

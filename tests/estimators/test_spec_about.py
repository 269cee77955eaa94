"""A fit linearised at a point (an iteration's pass) fits the correction from there: a prior's means and bounds
move with it (:meth:`casep.FitSpec.about`), so that they stay on the coefficients."""

from __future__ import annotations

import numpy as np

from casep.estimators.bounded import shift_bounds
from casep.estimators.map import shift_prior, solve_map
from casep.estimators.spec import FitSpec


def test_map_of_the_correction_with_the_shifted_prior_is_the_map_of_the_coefficients():
    """Linear rows y = S D + e: MAP of the correction x = D - a (rows y - S a, prior moved by -a) plus a is the MAP of
    D itself, correlations included (independent of casep's passes: the same posterior in two coordinates)."""
    rng = np.random.default_rng(3)
    S = rng.normal(size=(40, 4))
    y = S @ np.array([1.0, -2.0, 0.5, 3.0]) + rng.normal(0, 0.1, 40)
    names = ["a", "b", "c", "d"]
    prior = {"a": {"mean": 0.8, "std": 0.3}, "b": {"mean": -1.0, "std": 2.0}, "c": {"mean": 0.4, "std": 0.1},
             "correlation": {"names": ["a", "b"], "matrix": [[1.0, 0.4], [0.4, 1.0]]}}
    at = np.array([0.9, -1.7, 0.0, 2.5])
    whole = solve_map(S, y, prior, names=names, sigma=0.1)
    spec = FitSpec("map", {"prior": prior}).about(names, at)
    assert spec.options["prior"] == shift_prior(prior, {"a": 0.9, "b": -1.7, "d": 2.5})
    step = solve_map(S, y - S @ at, spec.options["prior"], names=names, sigma=0.1)
    np.testing.assert_allclose(step.estimate + at, whole.estimate, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(step.covariance, whole.covariance, rtol=1e-10, atol=1e-14)
    assert FitSpec("map", {"prior": prior}).about(names, np.zeros(4)).options["prior"] == prior
    assert shift_bounds({"a": [0.0, 2.0], "b": [None, 1.0], "c": 0.5}, {"a": 0.5, "b": 1.0}) == \
        {"a": [-0.5, 1.5], "b": [None, 0.0], "c": 0.5}

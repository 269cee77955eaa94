"""A fit with exactly dependent columns: residuals, the robust filter, the checks and the impact miss use the
solver's solution (casep.estimators.solution), never the missing estimates replaced by 0.

Independent references: the true coefficients of a simulated flight (the miss G D_true, the noise std of the
simulation), and a closed-form null space in the unit test of the determined-combination rule.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import casep
from casep.estimators.solution import Solution

#: The shipped platform39_misalignment (phi0 exactly dependent on the Ka1 cross terms: 3 null directions).
TRUTH = {"Kg0x": 3.0, "Ka0x": 1.2, "Ka1xy": 60.0, "Ka1yx": 40.0, "phi0z": 20.0, "phi0x": -10.0}
NOISE_STD = 0.0993  # the paper scenario's white noise, m/s


@pytest.fixture(scope="module")
def sim39():
    from casep.simulation.simulate import simulate_flight

    return simulate_flight("paper", seed=4, rate=4.0, model="platform39_misalignment", truth=TRUTH)


@pytest.fixture(scope="module")
def fit39(sim39):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # ill-conditioning and the like: not what this tests
        return casep.separate(sim39.flight, sim39.model)


def test_dependent_columns_keep_the_fit(fit39):
    res = fit39
    assert np.isnan(res.estimate).sum() == 9 and res.solution is not None
    rms = np.array(list(res.residual_rms.values()))
    assert np.all(np.abs(rms / NOISE_STD - 1.0) < 0.15), rms  # the noise, not the dropped combinations
    assert "robust" not in res.diagnostics  # no sample called a glitch
    assert res.success


def test_impact_miss_is_the_determined_combination(sim39, fit39):
    model = sim39.model
    a = casep.impact_analysis(sim39.flight, fit39, model)
    assert a.success and a.determined.all()
    D = np.array([TRUTH.get(n, 0.0) for n in model.names])
    true_miss = a.sensitivity @ D
    z = (a.miss - true_miss) / a.std
    assert np.all(np.abs(z) < 4.0), (a.miss, true_miss, a.std)
    assert np.all(a.std > 1e-3 * np.abs(true_miss))  # an honest std, not the 0 of a dropped term


def test_solution_json_round_trip(fit39):
    back = casep.EstimateResult.from_json(fit39.to_dict())
    assert back.solution is not None
    np.testing.assert_allclose(back.fitted_coefficients(), fit39.fitted_coefficients(), rtol=1e-12)


def test_determined_rule_closed_form():
    # S = [a, 2a, b]: D0 + 2 D1 is determined, D0 alone is not; null space (2, -1, 0)
    sol = Solution(np.array([1.0, 2.0, 3.0]), np.eye(3), np.array([[2.0], [-1.0], [0.0]]))
    G = np.array([[1.0, 2.0, 5.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    v, c, ok = sol.combination(G)
    assert ok.tolist() == [True, False, True]
    assert v[0] == pytest.approx(1.0 + 4.0 + 15.0) and np.isnan(v[1])
    assert c is not None and c[0, 0] == pytest.approx(1 + 4 + 25) and np.isnan(c[1, 1])


def test_impact_not_determined_is_a_failure(sim39, fit39):
    from casep.impact.miss import _Coefficients, _linear_miss

    model = sim39.model
    n = len(model.names)
    G = np.zeros((2, n))
    G[0, model.names.index("phi0z")] = 1.0  # phi0z alone: not determined
    G[1, model.names.index("Kg0x")] = 1.0
    coef = _Coefficients(fit39.estimate, fit39.covariance, tuple("estimated" for _ in range(n)), {}, "")
    lin = _linear_miss(fit39, model.names, coef, G, [])
    assert lin.determined.tolist() == [False, True] and np.isnan(lin.miss[0]) and "phi0z" in lin.note


def test_a_consider_term_widens_the_solution_as_the_stated_covariance(fit39):
    """A consider term (:func:`casep.workflows.row_estimators.with_extra_covariance`) reaches the solution's
    covariance, which the iteration's step reads, by the same ``g g^T`` as the stated covariance, and the
    coefficients the fit does not determine stay without a std."""
    from casep.workflows.row_estimators import with_extra_covariance

    m = len(fit39.names)
    g = np.linspace(0.5, 1.5, m) * np.sqrt(np.nan_to_num(np.diag(fit39.solution.covariance)))
    out = with_extra_covariance(fit39, np.outer(g, g))
    np.testing.assert_allclose(out.solution.covariance - fit39.solution.covariance, np.outer(g, g), rtol=1e-12)
    finite = np.isfinite(fit39.covariance)
    np.testing.assert_allclose(out.covariance[finite], (fit39.covariance + np.outer(g, g))[finite], rtol=1e-12)
    assert np.array_equal(np.isnan(out.std), np.isnan(fit39.std))
    own = np.isfinite(fit39.std)
    np.testing.assert_allclose(out.std[own], np.sqrt(fit39.std[own] ** 2 + g[own] ** 2), rtol=1e-10)

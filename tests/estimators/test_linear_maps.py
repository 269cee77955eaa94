"""The estimators' linear maps (batched Monte Carlo): K y (+ b) is the solver's estimate.

Each public ``*_linear_map`` must reproduce its solver on the same data: estimate to 1e-10
(relative to the largest estimate), reported std and covariance to 1e-9, and the same
undetermined coefficients. Independent check: the solvers' own code paths (QR reduction,
U-D recursion for RLS).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from casep.estimators.map import map_linear_map, solve_map
from casep.estimators.ols import ols_linear_map, solve_ols
from casep.estimators.pcr import pcr_linear_map, solve_pcr
from casep.estimators.registry import METHODS, run_method
from casep.estimators.ridge import ridge_linear_map, solve_ridge
from casep.estimators.rls import rls_linear_map, solve_rls
from casep.exceptions import IllConditionedWarning

N, NCOEF = 400, 6
SCALES = np.array([1e-3, 1.0, 30.0, 1e2, 0.5, 5e-2])  # columns of very different size, as S_V's


def _problem(rng, zero_column: bool = False):
    S = rng.standard_normal((N, 3, NCOEF)) * SCALES
    S[:, :, 4] += 0.3 * S[:, :, 3] / SCALES[3] * SCALES[4]  # some collinearity
    if zero_column:
        S[:, :, 5] = 0.0
    D = rng.standard_normal(NCOEF) / SCALES
    y = S @ D + 0.1 * rng.standard_normal((N, 3))
    return S, y


def _check(lm, res, S, y, sigma=None):
    X, std = lm.apply(S.reshape(-1, NCOEF), y.reshape(-1, 1))
    est, sd = X[:, 0], std[:, 0]
    np.testing.assert_array_equal(np.isnan(est), np.isnan(res.estimate))
    ok = ~np.isnan(res.estimate)
    scale = np.max(np.abs(res.estimate[ok] * SCALES[ok]))
    np.testing.assert_allclose(est[ok] * SCALES[ok], res.estimate[ok] * SCALES[ok], rtol=0, atol=1e-10 * scale)
    np.testing.assert_allclose(sd[ok], res.std[ok], rtol=1e-9)
    s2 = 1.0 if lm.dof is None else res.diagnostics["sigma"] ** 2
    np.testing.assert_allclose(lm.cov[np.ix_(ok, ok)] * s2, res.covariance[np.ix_(ok, ok)], rtol=1e-9,
                               atol=1e-12 * np.max(np.abs(res.covariance[np.ix_(ok, ok)])))


@pytest.fixture(autouse=True)
def _quiet():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IllConditionedWarning)
        yield


@pytest.mark.parametrize("zero_column", [False, True])
def test_ols_linear_map_equals_solver(rng, zero_column):
    S, y = _problem(rng, zero_column)
    lm = ols_linear_map(S)
    _check(lm, solve_ols(S, y), S, y)
    assert lm.dof == 3 * N - (NCOEF - zero_column)
    # independent: K S = I on the estimable coefficients (an unbiased linear estimator)
    ok = ~lm.undetermined
    np.testing.assert_allclose(
        (lm.K @ S.reshape(-1, NCOEF))[np.ix_(ok, ok)] * SCALES[ok][:, None] / SCALES[ok][None, :],
        np.eye(int(ok.sum())), atol=1e-10)


@pytest.mark.parametrize("zero_column", [False, True])
@pytest.mark.parametrize("p0, weight", [(1e6, 1.0), (1e-2, 3.0)])
def test_rls_linear_map_equals_recursion(rng, zero_column, p0, weight):
    S, y = _problem(rng, zero_column)
    _check(rls_linear_map(S, p0=p0, weight=weight), solve_rls(S, y, p0=p0, weight=weight), S, y)


@pytest.mark.parametrize("n_components", [None, 3])
def test_pcr_linear_map_equals_solver(rng, n_components):
    S, y = _problem(rng)
    _check(pcr_linear_map(S, n_components=n_components, max_condition_index=50.0),
           solve_pcr(S, y, n_components=n_components, max_condition_index=50.0), S, y)


@pytest.mark.parametrize("zero_column", [False, True])
def test_map_linear_map_equals_solver(rng, zero_column):
    S, y = _problem(rng, zero_column)
    prior = {"c1": {"mean": 0.5, "std": 0.2}, "c3": {"mean": -0.01, "std": 1e-3}}
    if zero_column:
        prior["c5"] = {"mean": 2.0, "std": 1.0}  # determined by the prior alone
    lm = map_linear_map(S, prior, 0.1)
    assert lm.dof is None and np.any(lm.b != 0)
    _check(lm, solve_map(S, y, prior, sigma=0.1), S, y)


def test_ridge_linear_map_equals_solver(rng):
    S, y = _problem(rng)
    _check(ridge_linear_map(S, 1e-2), solve_ridge(S, y, lam=1e-2), S, y)


def test_linear_map_is_applied_to_many_runs_at_once(rng):
    S, y = _problem(rng)
    Y = np.stack([y.reshape(-1), 2 * y.reshape(-1), -y.reshape(-1)], axis=1)
    X, std = ols_linear_map(S).apply(S.reshape(-1, NCOEF), Y)
    np.testing.assert_allclose(X[:, 1], 2 * X[:, 0], rtol=1e-12)  # linear in y
    np.testing.assert_allclose(std[:, 2], std[:, 0], rtol=1e-12)  # sigma from |residual|


def test_linear_map_options_are_checked(rng):
    S, _ = _problem(rng)
    with pytest.raises(ValueError, match="p0"):
        rls_linear_map(S, p0=-1.0)
    with pytest.raises(ValueError, match="n_components"):
        pcr_linear_map(S, n_components=NCOEF + 1)
    with pytest.raises(ValueError, match="sigma"):
        map_linear_map(S, {}, 0.0)


@pytest.mark.parametrize("method", [k for k, m in METHODS.items() if m.linear_map is not None])
def test_declared_linear_map_equals_the_methods_solver(rng, method):
    """Every method that declares a linear map (Method.linear_map, what batched Monte Carlo uses) reproduces
    its own solver through the registry interface, options given by name."""
    S, y = _problem(rng)
    names = [f"c{j}" for j in range(NCOEF)]
    opts = {"ridge": {"lam": 1e-2}, "rls": {"p0": 1e8, "weight": 2.0}, "pcr": {"n_components": 4},
            "map": {"prior": {"c0": {"mean": 0.0, "std": 1e3}, "c2": {"mean": 0.1, "std": 0.01}}}}.get(method, {})
    sigma = 0.1 if "prior" in opts else None  # MAP is linear in y for a given sigma only
    lm = METHODS[method].linear_map(S, names=names, sigma=sigma, **opts)
    res = run_method(method, S, y, None, opts, names=names, sigma=sigma)
    _check(lm, res, S, y)


def test_ols_linear_map_up_to_partners_equals_solver(rng):
    """Column 5 exactly dependent on columns 0 and 1 but excited 1e-9 of them: with declared magnitudes the solver
    reports 0 and 1 with the solution of least size in those magnitudes (casep.regression.linalg.PartnerBound) and
    leaves 5 undetermined; the map, made to report as the solver does, gives the same estimates, std and
    covariance (and without magnitudes all three stay undetermined in both)."""
    import casep

    S, _ = _problem(rng)
    S[:, :, 5] = 1e-9 * (S[:, :, 0] / SCALES[0] + S[:, :, 1] / SCALES[1]) * SCALES[5]
    y = S @ (rng.standard_normal(NCOEF) / SCALES) + 0.1 * rng.standard_normal((N, 3))
    names = [f"c{j}" for j in range(NCOEF)]
    mags = {n: float(1.0 / s) for n, s in zip(names, SCALES)}
    res = solve_ols(casep.Problem.from_arrays(S, y, names=names, magnitudes=mags))
    lm = ols_linear_map(S).up_to_partners(S.reshape(-1, NCOEF), names, mags, res.diagnostics["sigma"])
    assert np.isnan(res.estimate[5]) and np.all(np.isfinite(res.estimate[:5]))
    _check(lm, res, S, y)
    bare = ols_linear_map(S)
    assert bare.up_to_partners(S.reshape(-1, NCOEF), names, {}, 0.1) is bare
    assert np.isnan(solve_ols(casep.Problem.from_arrays(S, y, names=names)).estimate[[0, 1, 5]]).all()

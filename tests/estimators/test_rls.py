"""RLS and RELS (casep.estimators.rls) against closed forms, OLS and simulated ARMAX noise."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import augmented_lstsq
from scipy.signal import lfilter

import casep


def test_rls_equals_ridge_closed_form_at_p0_1e6(paper_problem):
    # (I / p0 + S^T S)^-1 S^T y on the real ill-conditioned flight, w = 1.
    S, y, _ = paper_problem
    p0 = 1e6
    ref = augmented_lstsq(S.reshape(-1, 36), y.reshape(-1), np.full(36, 1 / np.sqrt(p0)), np.zeros(36))
    res = casep.solve_rls(S, y, p0=p0)
    np.testing.assert_allclose(res.estimate, ref, rtol=1e-6, atol=0)
    assert res.method == "rls" and res.status == 1


def test_rls_weight_enters_as_measurement_precision(paper_problem):
    S, y, _ = paper_problem
    w, p0 = 25.0, 1e4
    ref = augmented_lstsq(S.reshape(-1, 36) * np.sqrt(w), y.reshape(-1) * np.sqrt(w),
                          np.full(36, 1 / np.sqrt(p0)), np.zeros(36))
    np.testing.assert_allclose(casep.solve_rls(S, y, p0=p0, weight=w).estimate, ref, rtol=1e-6)


def test_rls_large_p0_equals_ols(paper_problem):
    S, y, _ = paper_problem
    ols = casep.solve_ols(S, y)
    rls = casep.solve_rls(S, y, p0=1e16)
    assert np.max(np.abs(rls.estimate - ols.estimate) / ols.std) < 1e-3
    np.testing.assert_allclose(rls.std, ols.std, rtol=1e-3)


def test_forgetting_factor_equals_exponentially_weighted_ls(rng):
    # With lambda < 1 and a diffuse P0 the estimate minimises sum_k lambda^(N-1-k) |y_k - h_k x|^2.
    N, n, lam = 400, 4, 0.99
    S = rng.standard_normal((N, 3, n))
    x = rng.standard_normal(n)
    y = S @ x + 0.1 * rng.standard_normal((N, 3))
    res = casep.solve_rls(S, y, p0=1e12, forgetting=lam)
    wts = np.sqrt(lam ** (N - 1 - np.arange(N)))[:, None]
    ref = np.linalg.lstsq((S * wts[:, :, None]).reshape(-1, n), (y * wts).reshape(-1), rcond=None)[0]
    np.testing.assert_allclose(res.estimate, ref, rtol=1e-6)


def test_history_converges_to_final(paper_problem):
    S, y, _ = paper_problem
    res = casep.solve_rls(S, y, history_stride=100)
    assert res.history.shape == (len(range(0, S.shape[0], 100)), 36)
    assert res.settings["history_stride"] == 100
    np.testing.assert_allclose(res.history[-1], res.estimate, rtol=1e-3, atol=1e-12)


@pytest.mark.montecarlo
def test_rels_recovers_ma1_coefficient(rng):
    """ARMAX-type noise e(k) = v(k) + c v(k-1): RELS estimates c within its tolerance."""
    N, n, c_true = 6000, 5, 0.6
    S = np.cumsum(rng.standard_normal((N, 3, n)), axis=0) * 0.05  # slowly varying regressors
    x = rng.standard_normal(n)
    v = 0.1 * rng.standard_normal((N, 3))
    e = lfilter([1.0, c_true], [1.0], v, axis=0)
    res = casep.solve_rls(S, S @ x + e, noise_order=1, p0=1e8)
    c_hat = res.extras.ma_coefficients[0]
    assert abs(c_hat - c_true) < 0.05, c_hat
    assert res.method == "rels"
    np.testing.assert_allclose(res.sigma, 0.1, rtol=0.05)  # whitened innovations


def test_rels_equals_rls_in_white_noise(paper_problem):
    S, y, _ = paper_problem
    rls = casep.solve_rls(S, y)
    rels = casep.solve_rls(S, y, noise_order=1)
    ma = rels.extras
    assert abs(ma.ma_coefficients[0]) < 3 * ma.ma_std[0] + 0.02
    assert np.all(np.abs(rels.estimate - rls.estimate) < rls.std)


def test_prior_residual_variant_runs_and_differs_little(paper_problem):
    S, y, _ = paper_problem
    a = casep.solve_rls(S, y, noise_order=2, residuals="posterior")
    b = casep.solve_rls(S, y, noise_order=2, residuals="prior")
    assert np.all(np.abs(a.estimate - b.estimate) < a.std)


def test_zero_columns_stay_out(platform36, truth36):
    from casep.simulation.simulate import simulate_flight

    sim = simulate_flight("paper-pitch", seed=0, rate=10.0)
    S = casep.build_sv(platform36, sim.flight.t, sim.flight.f)
    res = casep.solve_rls(S, sim.flight.dv, names=platform36.names)
    assert res.status == 2 and len(res.diagnostics["unidentifiable"]) == 12
    assert np.isfinite(res.estimate).sum() == 24


def test_bad_arguments(paper_problem):
    S, y, _ = paper_problem
    for kw, msg in (({"p0": -1}, r"\(`p0`\) must be finite and > 0"),
                    ({"forgetting": 1.5}, r"\(`forgetting`\) must be in \[0.5, 1\]"),
                    ({"weight": 0}, r"\(`weight`\) must be finite and > 0"),
                    ({"noise_order": -1}, r"\(`noise_order`\) must be an int >= 0"),
                    ({"residuals": "both"}, r"\(`residuals`\) must be"),
                    ({"history_stride": 0}, r"\(`history_stride`\) must be")):
        with pytest.raises(ValueError, match=msg):
            casep.solve_rls(S, y, **kw)
    with pytest.raises(ValueError, match=r"must be \(N, 3, n\)"):
        casep.solve_rls(S.reshape(-1, 36), y.reshape(-1))


# --- wind-up with forgetting < 1, and failed results -------------------------

def test_forgetting_0_9_no_longer_winds_up_and_is_flagged_failed(paper_problem):
    # Before: estimates 1e16, residual RMS 1e11 m/s, success True. With stabilized forgetting
    # P <= P_0 at every sample and the estimate stays bounded; a memory of 10 samples (30
    # scalar measurements for 36 coefficients) cannot fit the flight, and the result says so.
    S, y, _ = paper_problem
    res = casep.solve_rls(S, y, forgetting=0.9, sigma=0.1, history_stride=1)
    assert np.all(np.isfinite(res.estimate)) and np.all(np.isfinite(res.std))
    assert np.max(np.abs(res.history)) < 1e3  # 1e16 without the safeguard
    prior_std = 0.1 * np.sqrt(1e6)  # sqrt(sigma^2 w p0)
    assert np.all(res.history_std <= prior_std * (1 + 1e-9))  # P_k <= P_0
    assert not res.success and res.status == -3
    assert "does not fit the data" in res.message and "forgetting" in res.message


def test_stabilized_forgetting_equals_regularised_weighted_ls(rng):
    # theta_N = (P_0^-1 + w sum lambda^(N-1-k) S_k^T S_k)^-1 w sum lambda^(N-1-k) S_k^T y_k, and the
    # same matrix (times sigma^2 w) is the covariance; a prior that matters (p0 = 0.05).
    N, n, lam, p0, w = 300, 4, 0.97, 0.05, 2.0
    S = rng.standard_normal((N, 3, n)) * np.array([1.0, 0.2, 3.0, 0.05])
    y = S @ rng.standard_normal(n) + 0.1 * rng.standard_normal((N, 3))
    res = casep.solve_rls(S, y, p0=p0, weight=w, forgetting=lam, history_stride=1)
    for k in (N - 1, 150, 3):
        a = lam ** (k - np.arange(k + 1))[:, None, None]  # lambda^(k - j), samples 0..k
        A = np.eye(n) / p0 + w * np.einsum("kai,kaj->ij", a * S[: k + 1], S[: k + 1])
        theta = np.linalg.solve(A, w * np.einsum("kai,ka->i", a * S[: k + 1], y[: k + 1]))
        np.testing.assert_allclose(res.history[k], theta, rtol=1e-9, atol=1e-12)
        std = np.sqrt(np.diag(res.sigma**2 * w * np.linalg.inv(A)))
        np.testing.assert_allclose(res.history_std[k], std, rtol=1e-9)
    np.testing.assert_allclose(res.estimate, res.history[-1], rtol=1e-12)


def test_mild_forgetting_stays_near_ols_and_succeeds(paper_problem):
    S, y, _ = paper_problem
    ols = casep.solve_ols(S, y)
    res = casep.solve_rls(S, y, forgetting=0.999)
    assert res.success and res.status == 1
    # within 4 OLS std of OLS (RLS at lambda = 1 is 2.4 std away through the p0 = 1e6 prior)
    assert np.max(np.abs(res.estimate - ols.estimate) / ols.std) < 4.0


def test_unexcited_direction_stays_at_prior_under_forgetting(rng):
    # Column 0 is excited at sample 0 only and is orthogonal to the others afterwards: plain
    # forgetting would grow its variance as lambda^-k (0.95^-499 ~ 1e11); stabilized forgetting
    # returns it to the prior p0.
    N, n, lam, p0 = 500, 3, 0.95, 1e2
    S = np.zeros((N, 3, n))
    S[:, :, 1:] = rng.standard_normal((N, 3, n - 1))
    S[0, 0, :] = [1.0, 0.0, 0.0]
    S[0, 1:, 0] = 0.0
    y = S @ np.array([0.3, 1.0, -2.0]) + 0.01 * rng.standard_normal((N, 3))
    res = casep.solve_rls(S, y, p0=p0, forgetting=lam, sigma=0.01, history_stride=1)
    prior_std = 0.01 * np.sqrt(p0)  # sqrt(sigma^2 w p0), w = 1
    assert np.all(res.history_std[:, 0] <= prior_std * (1 + 1e-12))
    np.testing.assert_allclose(res.history_std[-1, 0], prior_std, rtol=1e-8)  # all information forgotten
    assert res.success


def test_finish_marks_non_finite_and_misfit_results_failed(rng):
    from casep.estimators._base import finish, prepare

    N, n = 200, 3
    S = rng.standard_normal((N, 3, n))
    y = S @ np.array([1.0, -1.0, 0.5]) + 0.1 * rng.standard_normal((N, 3))
    pb = prepare(S, y, None, None, None, None)
    kw = {"settings": {}}
    good = finish(pb, "test", np.array([1.0, -1.0, 0.5]), np.eye(n) * 1e-4, 0.1, **kw)
    assert good.success and good.status == 1
    nonfinite = finish(pb, "test", np.array([1.0, np.inf, 0.5]), np.eye(n), 0.1, **kw)
    assert not nonfinite.success and nonfinite.status == -2 and "c1" in nonfinite.message
    inf_std = finish(pb, "test", np.array([1.0, -1.0, 0.5]), np.diag([1.0, np.inf, 1.0]), 0.1, **kw)
    assert not inf_std.success and inf_std.status == -2
    # NaN std = not defined by the method (bounded: a coefficient at its bound): not a failure
    assert finish(pb, "test", np.array([1.0, -1.0, 0.5]), np.diag([1.0, np.nan, 1.0]), 0.1, **kw).success
    nan_res = finish(pb, "test", np.array([1.0, -1.0, 0.5]), None, 0.1, residuals=np.full(3 * N, np.nan), **kw)
    assert nan_res.status == -2 and "non-finite residuals" in nan_res.message
    huge = finish(pb, "test", np.array([1e3, -1.0, 0.5]), np.eye(n), 0.1, **kw)
    assert not huge.success and huge.status == -3 and "does not fit the data" in huge.message
    # The threshold: residual RMS 3 x the least-squares residual std (a bias b in c0 adds b^2 to
    # the residual power, the columns having unit variance): 2.2 x passes, 3.6 x fails.
    ls = pb.ols_sigma()
    assert finish(pb, "test", np.array([1.0 + 2 * ls, -1.0, 0.5]), np.eye(n), 0.1, **kw).success
    worse = finish(pb, "test", np.array([1.0 + 3.5 * ls, -1.0, 0.5]), np.eye(n), 0.1, **kw)
    assert worse.status == -3


# --- covariance history ---------------------------------------------------------

def test_history_std_last_row_equals_final_std(paper_problem):
    S, y, _ = paper_problem
    assert (S.shape[0] - 1) % 100 == 0  # the last history row is the last sample
    for order in (0, 1):
        res = casep.solve_rls(S, y, history_stride=100, noise_order=order)
        assert res.history_std.shape == res.history.shape
        np.testing.assert_allclose(res.history_std[-1, :36], res.std, rtol=1e-10)
        if order:
            np.testing.assert_allclose(res.history_std[-1, 36], res.extras.ma_std[0],
                                       rtol=1e-10)


def test_history_std_equals_closed_form_of_first_k_samples(rng):
    # lambda = 1: P_k = (P_0^-1 + w S_k^T S_k)^-1 over samples 0..k; std = sqrt(diag(sigma^2 w P_k)).
    N, n, p0, w, stride = 300, 4, 10.0, 4.0, 7
    S = rng.standard_normal((N, 3, n)) * np.array([1.0, 0.1, 10.0, 0.5])
    y = S @ rng.standard_normal(n) + 0.2 * rng.standard_normal((N, 3))
    res = casep.solve_rls(S, y, p0=p0, weight=w, history_stride=stride)
    for row in (0, 5, 20):
        k = row * stride
        Sk = S[: k + 1].reshape(-1, n)
        Pk = np.linalg.inv(np.eye(n) / p0 + w * Sk.T @ Sk)
        ref = np.sqrt(np.diag(res.sigma**2 * w * Pk))
        np.testing.assert_allclose(res.history_std[row], ref, rtol=1e-9)

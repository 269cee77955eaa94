"""RLS and RELS (casep.rls) against closed forms, OLS and simulated ARMAX noise."""

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
    c_hat = res.diagnostics["noise_model"]["ma_coefficients"][0]
    assert abs(c_hat - c_true) < 0.05, c_hat
    assert res.method == "rels"
    np.testing.assert_allclose(res.sigma, 0.1, rtol=0.05)  # whitened innovations


def test_rels_equals_rls_in_white_noise(paper_problem):
    S, y, _ = paper_problem
    rls = casep.solve_rls(S, y)
    rels = casep.solve_rls(S, y, noise_order=1)
    ma = rels.diagnostics["noise_model"]
    assert abs(ma["ma_coefficients"][0]) < 3 * ma["ma_std"][0] + 0.02
    assert np.all(np.abs(rels.estimate - rls.estimate) < rls.std)


def test_prior_residual_variant_runs_and_differs_little(paper_problem):
    S, y, _ = paper_problem
    a = casep.solve_rls(S, y, noise_order=2, residuals="posterior")
    b = casep.solve_rls(S, y, noise_order=2, residuals="prior")
    assert np.all(np.abs(a.estimate - b.estimate) < a.std)


def test_zero_columns_stay_out(platform36, truth36):
    from casep.simulate import simulate_flight

    sim = simulate_flight("paper-pitch", seed=0, rate=10.0)
    S = casep.build_sv(platform36, sim.flight.t, sim.flight.f)
    res = casep.solve_rls(S, sim.flight.dv, names=platform36.names)
    assert res.status == 2 and len(res.diagnostics["unidentifiable"]) == 12
    assert np.isfinite(res.estimate).sum() == 24


def test_bad_arguments(paper_problem):
    S, y, _ = paper_problem
    for kw, msg in (({"p0": -1}, "`p0` must be finite and > 0"), ({"forgetting": 1.5}, r"`forgetting` must be finite and in \(0, 1\]"),
                    ({"weight": 0}, "`weight` must be finite and > 0"), ({"noise_order": -1}, "`noise_order` must be an int >= 0"),
                    ({"residuals": "both"}, "`residuals` must be"), ({"history_stride": 0}, "`history_stride` must be")):
        with pytest.raises(ValueError, match=msg):
            casep.solve_rls(S, y, **kw)
    with pytest.raises(ValueError, match=r"must be \(N, 3, n\)"):
        casep.solve_rls(S.reshape(-1, 36), y.reshape(-1))

"""Ridge (casep.estimators.ridge): closed form vs cvxpy/Clarabel, GCV and L-curve choices."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import augmented_lstsq

import casep
from casep.estimators.ridge import gcv_curve


def test_closed_form_equals_augmented_lstsq_and_cvxpy(paper_problem):
    S, y, _ = paper_problem
    lam = 1e-4
    svd = casep.solve_ridge(S, y, lam=lam)
    ref = augmented_lstsq(S.reshape(-1, 36), y.reshape(-1), np.full(36, np.sqrt(lam)) * np.linalg.norm(
        S.reshape(-1, 36), axis=0), np.zeros(36))
    np.testing.assert_allclose(svd.estimate, ref, rtol=1e-8)
    cvx = casep.solve_ridge(S, y, lam=lam, solver="cvxpy")
    np.testing.assert_allclose(cvx.estimate, svd.estimate, rtol=1e-6)


def test_gcv_picks_the_minimiser_on_a_designed_case(rng):
    # Known spectrum: GCV on a fine grid and the chosen lambda agree.
    m, n = 2000, 8
    Q, _ = np.linalg.qr(rng.standard_normal((m, n)))
    V, _ = np.linalg.qr(rng.standard_normal((n, n)))
    s = np.logspace(0, -4, n)
    S = (Q * s) @ V.T
    x = V @ (np.r_[np.ones(4), np.zeros(4)] * 3)
    y = S @ x + 0.01 * rng.standard_normal(m)
    res = casep.solve_ridge(S, y, lam="gcv")
    red = casep.reduce_qr(S, y)
    U, sv, _ = np.linalg.svd(red.R)
    beta = U.T @ red.qty
    grid = np.logspace(-14, 2, 20001)
    g = gcv_curve(sv, beta, red.rho2, m, grid)
    lam_grid = grid[np.argmin(g)]
    assert res.extras.lam == pytest.approx(lam_grid, rel=2e-3)
    assert gcv_curve(sv, beta, red.rho2, m, np.array([res.extras.lam]))[0] <= g.min() * (1 + 1e-9)


def test_lcurve_is_between_extremes(paper_problem):
    S, y, _ = paper_problem
    res = casep.solve_ridge(S, y, lam="lcurve")
    assert res.extras.rule == "lcurve" and 1e-12 < res.extras.lam < 1.0


def test_ridge_tends_to_ols_and_std_formula(paper_problem):
    S, y, _ = paper_problem
    ols = casep.solve_ols(S, y)
    tiny = casep.solve_ridge(S, y, lam=1e-16)
    assert np.max(np.abs(tiny.estimate - ols.estimate) / ols.std) < 1e-3
    big = casep.solve_ridge(S, y, lam=1e3)
    assert np.all(big.std < ols.std)  # shrinkage lowers the sampling variance
    assert big.extras.effective_dof < 36


def test_bad_arguments(paper_problem):
    S, y, _ = paper_problem
    with pytest.raises(ValueError, match=r"\(`lam`\) must be a number > 0, 'gcv' or 'lcurve'"):
        casep.solve_ridge(S, y, lam="aic")
    with pytest.raises(ValueError, match=r"\(`lam`\) must be finite and > 0"):
        casep.solve_ridge(S, y, lam=-1.0)
    with pytest.raises(ValueError, match=r"\(`solver`\) must be"):
        casep.solve_ridge(S, y, lam=1.0, solver="scs")

"""Ordinary least squares on the column-scaled, QR-reduced system.

Notes
-----
With ``Z = S diag(c)^-1`` (unit-norm columns) and the reduction of :mod:`casep.linalg`,
``[Z | y] = Q [[R, q], [0, rho]]`` and ``R = U diag(s) V^T``::

    x_Z    = V_r diag(1/s_r) U_r^T q                 (minimum-norm LS solution, scaled)
    D_hat  = x_Z / c                                 (natural units)
    RSS    = rho^2 + ||U_{r+}^T q||^2                (the part of q outside range(R))
    sigma^2 = RSS / (m - r)                           (unbiased; r = numerical rank)
    Cov(D_hat) = sigma^2 diag(1/c) V_r diag(1/s_r^2) V_r^T diag(1/c)

For a full-rank S this is ``sigma^2 (S^T S)^-1``. Coefficients whose column is zero or in
an exact dependency are *not estimable* (their unit vector is not in the row space of S):
they are reported as NaN with a reason. Every estimable coefficient has the same value and
variance in every least-squares solution, so the minimum-norm solution reports them
correctly. No normal equations are formed, and nothing is truncated silently: the rank
threshold is explicit (`rcond`) and its consequences are in the result.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from .linalg import analyze_rank, condition_numbers, reduce_qr, unidentifiable_reasons
from .result import EstimateResult

__all__ = ["solve_ols"]


def _labels(n: int, names, units, si_factors) -> tuple[tuple[str, ...], tuple[str, ...], np.ndarray]:
    names = tuple(f"c{j}" for j in range(n)) if names is None else tuple(names)
    units = ("",) * n if units is None else tuple(units)
    si = np.ones(n) if si_factors is None else np.asarray(si_factors, dtype=float)
    for label, seq in (("names", names), ("units", units), ("si_factors", si)):
        if len(seq) != n:
            raise ValueError(f"`{label}` has {len(seq)} entries but `S` has {n} columns")
    return names, units, si


def solve_ols(
    S: np.ndarray,
    y: np.ndarray,
    *,
    names: Sequence[str] | None = None,
    units: Sequence[str] | None = None,
    si_factors: Sequence[float] | None = None,
    sigma: float | None = None,
    rcond: float | None = None,
) -> EstimateResult:
    """Least-squares estimate of ``D`` in ``y = S D + e`` with honest standard deviations.

    Parameters
    ----------
    S : (N, 3, n) or (m, n) array_like
        Regression matrix in natural units (from :func:`casep.build_sv`).
    y : (N, 3) or (m,) array_like
        Observed velocity error, m/s.
    names, units, si_factors : sequence, optional
        Coefficient labels for the result (default ``c0, c1, ...``).
    sigma : float, optional
        Known noise standard deviation, m/s; default: estimated from the residuals.
    rcond : float, optional
        Rank threshold, see :func:`casep.linalg.analyze_rank`.

    Returns
    -------
    EstimateResult
        ``status`` 1: every coefficient estimated; 2: some are not identifiable on this
        data (reported NaN with a reason); -1: none is.
    """
    S_arr = np.asarray(S, dtype=float)
    if S_arr.ndim not in (2, 3):
        raise ValueError(f"`S` must be (m, n) or (N, 3, n), got {S_arr.ndim}-D")
    n = S_arr.shape[-1]
    names, units, si = _labels(n, names, units, si_factors)
    if sigma is not None and (not np.isfinite(sigma) or sigma <= 0):
        raise ValueError(f"`sigma` must be finite and > 0, got {sigma}")
    y_arr = np.asarray(y, dtype=float)
    red = reduce_qr(S_arr, y_arr)
    ra = analyze_rank(red, rcond)
    m, r = red.m, ra.rank
    if m <= r:
        raise ValueError(f"`S` has {m} rows, not more than its rank {r}: no degree of freedom for the noise")
    V, inv_s = ra.pinv_factors()
    Uq = ra.U.T @ red.qty
    xz = V @ (inv_s * Uq[:r])  # x_Z = V_r diag(1/s_r) U_r^T q
    inv_c = np.where(red.scale > 0, 1.0 / np.where(red.scale > 0, red.scale, 1.0), 0.0)
    x_all = xz * inv_c  # natural units, minimum-norm solution
    rss = red.rho2 + float(np.sum(Uq[r:] ** 2))  # RSS = rho^2 + ||U_{r+}^T q||^2
    sigma_hat = float(np.sqrt(rss / (m - r)))  # sigma^2 = RSS / (m - r)
    sig = sigma_hat if sigma is None else float(sigma)
    W = V * inv_s  # V_r diag(1/s_r)
    cov = sig**2 * (W @ W.T) * np.outer(inv_c, inv_c)
    ok = ra.estimable
    est = np.where(ok, x_all, np.nan)
    cov[~ok, :] = np.nan
    cov[:, ~ok] = np.nan
    std = np.sqrt(np.diag(cov))
    residuals = y_arr.reshape(-1) - S_arr.reshape(m, n) @ x_all
    reasons = unidentifiable_reasons(ra, names)
    n_ok = int(ok.sum())
    if n_ok == n:
        status, message = 1, f"all {n} coefficients estimated"
    elif n_ok:
        status, message = 2, (f"{n - n_ok} of {n} coefficients not identifiable on this data "
                              "(zero or exactly dependent columns); the other estimated")
    else:
        status, message = -1, "no coefficient is identifiable on this data"
    diagnostics = {**condition_numbers(red, ra), "sigma": sig, "rank": r,
                   "unidentifiable": [names[j] for j in np.flatnonzero(~ok)]}
    N = m // 3 if S_arr.ndim == 3 else m
    return EstimateResult(
        method="ols", names=names, units=units, estimate=est, std=std, covariance=cov,
        reasons=reasons, residuals=residuals.reshape(S_arr.shape[:-1]) if S_arr.ndim == 3 else residuals,
        sigma=sig, rank=r, status=status, message=message, success=status > 0, si_factors=si,
        settings={"rcond": ra.rcond, "sigma": "estimated" if sigma is None else float(sigma)},
        diagnostics=diagnostics, n_samples=N,
    )

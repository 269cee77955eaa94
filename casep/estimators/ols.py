"""Ordinary least squares on the column-scaled, QR-reduced system.

Notes
-----
With ``Z = S diag(c)^-1`` (unit-norm columns) and the reduction of :mod:`casep.analysis.linalg`,
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

from casep.estimators._base import Problem, finish, prepare
from casep.estimators.result import EstimateResult

__all__ = ["solve_ols"]


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
        Rank threshold, see :func:`casep.analysis.linalg.analyze_rank`.

    Returns
    -------
    EstimateResult
        ``status`` 1: every coefficient estimated; 2: some are not identifiable on this
        data (reported NaN with a reason); -1: none is.
    """
    pb = prepare(S, y, names, units, si_factors, sigma, rcond)
    x, cov, sig = least_squares(pb)
    return finish(pb, "ols", x, cov, sig,
                  settings={"rcond": pb.ra.rcond, "sigma": "estimated" if pb.sigma is None else pb.sigma})


def least_squares(pb: Problem) -> tuple[np.ndarray, np.ndarray, float]:
    """Minimum-norm LS solution, covariance and sigma of a prepared problem (natural units)."""
    ra, red = pb.ra, pb.red
    V, inv_s = ra.pinv_factors()
    Uq = ra.U.T @ red.qty
    inv_c = pb.inv_c
    x = (V @ (inv_s * Uq[: ra.rank])) * inv_c  # x_Z = V_r diag(1/s_r) U_r^T q, then / c
    sig = pb.ols_sigma() if pb.sigma is None else pb.sigma  # sigma^2 = RSS / (m - r)
    W = V * inv_s  # V_r diag(1/s_r)
    cov = sig**2 * (W @ W.T) * np.outer(inv_c, inv_c)
    return x, cov, sig

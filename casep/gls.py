"""Generalised least squares for first-order Gauss-Markov (AR(1)) tracking noise.

Notes
-----
Each axis' noise is stationary Gauss-Markov with correlation time ``tau``. With
``a_k = exp(-(t_k - t_{k-1}) / tau)`` the whitening of :func:`casep.diagnostics.ar1_whiten`
(``w_0 = e_0``, ``w_k = (e_k - a_k e_{k-1}) / sqrt(1 - a_k^2)``) turns the noise white, so
least squares on the whitened ``S`` and ``dv`` is the GLS estimate with its honest
covariance ``sigma^2 (S^T Sigma^-1 S)^-1``, which attains the Gauss-Markov Cramer-Rao bound.

``tau="auto"`` estimates ``tau`` by restricted maximum likelihood (REML), which accounts
for the degrees of freedom the regression absorbs (the lag-1 autocorrelation of OLS
residuals underestimates tau by ~13 % here, and iterating does not help)::

    -2 l_R(tau) = (m - p) ln RSS_w(tau) + 3 sum_k ln(1 - a_k^2) + ln det(S_w^T S_w) + const

with ``S_w``, ``RSS_w`` from the unit-sigma whitening; minimised over ``ln tau`` in
[median(dt) / 5, duration]. A ``tau`` at the lower end is white noise in effect (GLS = OLS).
Measured (60 runs, paper-ar1 at 20 Hz, tau 1 s): tau 0.99 +- 0.06, coverage of the 95 %
intervals 0.947 (OLS with white-noise std: 0.24).

Why it matters (``README``, Monte Carlo): with tau = 1 s at 100 Hz the white-noise std of
OLS cover the truth in 11 % of runs instead of 95 %.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from ._estimator import finish, prepare
from .diagnostics import ar1_whiten
from .linalg import reduce_qr
from .ols import least_squares
from .result import EstimateResult

__all__ = ["solve_gls", "estimate_tau"]


def _whiten(S: np.ndarray, y: np.ndarray, t: np.ndarray, tau: float) -> tuple[np.ndarray, np.ndarray]:
    return ar1_whiten(S, t, 1.0, tau), ar1_whiten(y[:, :, None], t, 1.0, tau)[:, :, 0]


def estimate_tau(S: np.ndarray, y: np.ndarray, t: np.ndarray) -> float:
    """REML estimate of the Gauss-Markov correlation time (see module notes), s."""
    from scipy.optimize import minimize_scalar

    N, _, p = S.shape
    m = 3 * N
    dt = np.diff(t)

    def neg2_reml(log_tau: float) -> float:
        tau = float(np.exp(log_tau))
        a = np.exp(-dt / tau)
        red = reduce_qr(*_whiten(S, y, t, tau))
        d = np.abs(np.diag(red.R))
        live = (d > 0) & (red.scale > 0)
        logdet = 2.0 * np.sum(np.log(d[live])) + 2.0 * np.sum(np.log(red.scale[live]))  # ln det(S_w^T S_w)
        return (m - p) * np.log(red.rho2) + 3.0 * np.sum(np.log1p(-(a**2))) + logdet

    lo, hi = np.log(np.median(dt) / 5.0), np.log(t[-1] - t[0])
    res = minimize_scalar(neg2_reml, bounds=(lo, hi), method="bounded", options={"xatol": 1e-4})
    return float(np.exp(res.x))


def solve_gls(
    S: np.ndarray,
    y: np.ndarray,
    t: np.ndarray,
    *,
    tau: float | str = "auto",
    sigma: float | None = None,
    names: Sequence[str] | None = None,
    units: Sequence[str] | None = None,
    si_factors: Sequence[float] | None = None,
    rcond: float | None = None,
) -> EstimateResult:
    """GLS estimate of ``D`` under Gauss-Markov noise of correlation time `tau`.

    Parameters
    ----------
    S : (N, 3, n) array_like
        Regression in natural units, samples in time order.
    y : (N, 3) array_like
        Velocity error, m/s.
    t : (N,) array_like
        Sample times, s.
    tau : float or "auto", optional
        Correlation time, s, or its REML estimate (default).
    sigma : float, optional
        Stationary noise std, m/s (default: from the whitened residuals).

    Returns
    -------
    EstimateResult
        ``method`` "gls"; residuals are ``dv - S_V D_hat`` (not whitened); diagnostics
        (condition numbers, CRLB) are those of the whitened regression.
    """
    S = np.asarray(S, dtype=float)
    y = np.asarray(y, dtype=float)
    if S.ndim != 3 or S.shape[1] != 3:
        raise ValueError(f"`S` must be (N, 3, n) in time order, got shape {S.shape}")
    t = np.asarray(t, dtype=float)
    if t.shape != (S.shape[0],):
        raise ValueError(f"`t` must have {S.shape[0]} samples, got shape {t.shape}")
    if np.any(np.diff(t) <= 0):
        raise ValueError("`t` must be strictly increasing")
    if isinstance(tau, str):
        if tau != "auto":
            raise ValueError(f"`tau` must be a number > 0 or 'auto', got {tau!r}")
        tau_used, rule = estimate_tau(S, y.reshape(S.shape[0], 3), t), "reml"
    else:
        if isinstance(tau, bool) or not np.isfinite(tau) or tau <= 0:
            raise ValueError(f"`tau` must be finite and > 0 s, got {tau}")
        tau_used, rule = float(tau), "given"
    pb = prepare(*_whiten(S, y.reshape(S.shape[0], 3), t, tau_used), names, units, si_factors, sigma, rcond)
    x, cov, sig = least_squares(pb)  # sigma: whitened residual std = stationary sigma
    fit = y.reshape(S.shape[0], 3) - S @ x  # dv - S_V D_hat, not whitened
    return finish(pb, "gls", x, cov, sig, residuals=fit.reshape(-1),
                  settings={"tau": tau_used, "tau_rule": rule, "sigma": "estimated" if pb.sigma is None else pb.sigma})

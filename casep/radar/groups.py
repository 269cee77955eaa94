"""Noise std per measurement group of the stacked radar regression, and the group reductions.

A group is one station's measurements of one type (range, azimuth, elevation, range rate).
"""

from __future__ import annotations

import math

import numpy as np

from casep.regression.linalg import covariance_std

__all__ = ["estimate_group_sigmas", "group_reductions", "stacked_ls"]


def estimate_group_sigmas(S: np.ndarray, y: np.ndarray, rows: list[np.ndarray], sigma: np.ndarray,
                          fixed: np.ndarray, *, floor: np.ndarray, iterations: int = 30,
                          rtol: float = 1e-5) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Noise std per group from the weighted least-squares residuals, degrees of freedom corrected.

    Iterates ``sigma_g^2 = sum_{i in g} r_i^2 / (m_g - h_g)`` with ``r`` the residuals of the fit
    weighted by the current std and ``h_g = sum_{i in g} h_ii = trace(F_g^T F_g (F^T F)^+)`` the
    group's share of the leverages (``F`` the weighted S); at the fixed point the weighted residual
    sum of squares equals ``m - rank``, the REML condition for group variances of a linear model
    at these leverages.

    Each group is reduced once (casep's TSQR, :func:`casep.regression.linalg.reduce_qr`:
    ``S_g = Q_g R_g``, ``q_g = Q_g^T y_g``, ``rho_g^2`` the rest); a weighting is then the
    least-squares problem of the stacked ``R_g / sigma_g`` (``G n`` rows), and the group's residual
    sum of squares is ``|q_g - R_g x|^2 + rho_g^2``: exact, and independent of the number of rows.

    Returns
    -------
    sigma : (G,) ndarray
        Per group, SI (the `fixed` ones as given).
    x : (n,) ndarray
        Weighted least-squares estimate at the final std.
    std : (n,) ndarray
        Its std (unit weighted noise).
    """
    sigma = np.array(sigma, dtype=float)
    red = group_reductions(S, y, rows)
    grams = [R.T @ R for R, _, _ in red]  # S_g^T S_g
    x = cov = None
    for _ in range(iterations):
        x, cov = stacked_ls(red, sigma)
        new = sigma.copy()
        for g, (R, q, rho2) in enumerate(red):
            if fixed[g]:
                continue
            lev = float(np.sum(grams[g] * cov)) / sigma[g] ** 2  # trace(F_g^T F_g Cov), Cov symmetric
            dof = max(rows[g].size - lev, 1.0)
            rss = float(np.sum((q - R @ x) ** 2)) + rho2
            new[g] = max(math.sqrt(max(rss, 0.0) / dof), float(floor[g]))
        done = np.all(np.abs(new - sigma) <= rtol * sigma)
        sigma = new
        if done:
            break
    x, cov = stacked_ls(red, sigma)
    return sigma, x, covariance_std(cov)


def group_reductions(S: np.ndarray, y: np.ndarray, rows: list[np.ndarray]) -> list[tuple]:
    """Per group ``(R_g, q_g, rho_g^2)`` with ``S_g = Q_g R_g``, ``q_g = Q_g^T y_g`` (casep's TSQR).

    ``|y_g - S_g x|^2 = |q_g - R_g x|^2 + rho_g^2`` for every x, and ``S_g^T S_g = R_g^T R_g``, also on
    any subset of the columns: every bound and fit of the stacked regression follows from these.
    """
    from casep.regression.linalg import reduce_qr

    out = []
    for r in rows:
        rg = reduce_qr(S[r], y[r])
        out.append((rg.R * rg.scale[None, :], rg.qty, float(rg.rho2)))  # R of S_g itself (S_g = Q R diag(scale))
    return out


def stacked_ls(red, sigma: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Least squares of the stacked group reductions ``[R_g / sigma_g] x = [q_g / sigma_g]``, columns
    equilibrated, minimum norm on an exact null space: estimate and covariance (unit weighted noise)."""
    F = np.vstack([R / s for (R, _, _), s in zip(red, sigma)])
    f = np.concatenate([q / s for (_, q, _), s in zip(red, sigma)])
    c = np.linalg.norm(F, axis=0)
    c = np.where(c > 0, c, 1.0)
    U, sv, Vt = np.linalg.svd(F / c, full_matrices=False)
    keep = sv > sv[0] * max(F.shape) * np.finfo(float).eps
    Wm = Vt[keep].T / sv[keep]
    x = (Wm @ (U[:, keep].T @ f)) / c
    cov = (Wm @ Wm.T) / np.outer(c, c)
    return x, cov

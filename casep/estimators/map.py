"""Maximum a posteriori (MAP) estimate with a Gaussian prior per coefficient.

Notes
-----
Prior ``D_j ~ N(mu_j, tau_j^2)`` (natural units, e.g. from ground calibration; a coefficient
without a prior, or with ``tau = inf``, is flat), noise ``N(0, sigma^2)`` (given, or the
least-squares residual std). The posterior is Gaussian with::

    Cov^-1 = S^T S / sigma^2 + diag(1 / tau^2)
    mean   = Cov (S^T y / sigma^2 + diag(1 / tau^2) mu)

computed without normal equations as the least-squares solution of the stacked system
(scaled coordinates ``z = c D``, reduced ``(R, q)``)::

    [ R / sigma          ] z = [ q / sigma       ]
    [ diag(1/(c_j tau_j)) ]     [ mu_j / tau_j   ]      (rows for coefficients with a prior)

by SVD; the posterior covariance is ``V diag(1/s^2) V^T`` of that stacked matrix.
Coefficients that neither the data nor a prior determine (zero or dependent columns with a
flat prior) are reported without an estimate.
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

from casep.estimators._base import finish, prepare
from casep.model._model import unknown_coefficient_message
from casep.estimators.result import EstimateResult, MAPExtras

__all__ = ["solve_map", "parse_prior"]


def parse_prior(prior: Mapping, names: Sequence[str], source: str = "`prior`") -> tuple[np.ndarray, np.ndarray]:
    """``{name: {"mean": m, "std": s}}`` to mean and std arrays (std inf where absent)."""
    if not isinstance(prior, Mapping):
        raise TypeError(f"{source} must be a mapping of coefficient name to {{'mean', 'std'}}")
    n = len(names)
    mu, tau = np.zeros(n), np.full(n, np.inf)
    for name, spec in prior.items():
        if name not in names:
            raise ValueError(unknown_coefficient_message(name, names, source))
        if not isinstance(spec, Mapping) or "mean" not in spec or "std" not in spec:
            raise ValueError(f"{source}: `{name}` must be {{\"mean\": m, \"std\": s}}, got {spec!r}")
        try:
            m_, s_ = float(spec["mean"]), float(spec["std"])
        except (TypeError, ValueError):
            raise ValueError(f"{source}: `{name}` mean and std must be numbers, got {spec!r}") from None
        if not np.isfinite(m_):
            raise ValueError(f"{source}: `{name}` mean must be finite, got {m_}")
        if np.isnan(s_) or s_ <= 0 or (np.isfinite(s_) and not np.isfinite(1.0 / s_)):
            raise ValueError(f"{source}: `{name}` std must be > 0 (inf for no prior), got {s_:g}")
        j = list(names).index(name)
        mu[j], tau[j] = m_, s_
    return mu, tau


def solve_map(
    S: np.ndarray,
    y: np.ndarray | None = None,
    prior: Mapping | None = None,
    *,
    sigma: float | None = None,
    names: Sequence[str] | None = None,
    units: Sequence[str] | None = None,
    si_factors: Sequence[float] | None = None,
    rcond: float | None = None,
) -> EstimateResult:
    """Posterior mean and covariance of ``D`` under a Gaussian prior.

    Parameters
    ----------
    prior : mapping
        ``{name: {"mean": m, "std": s}}`` in natural units; absent names are flat.
    sigma : float, optional
        Noise std, m/s (default: the least-squares residual std).
    """
    if prior is None:
        raise ValueError("`prior` is required for method `map`. Use: --prior FILE or prior={...}")
    pb = prepare(S, y, names, units, si_factors, sigma, rcond)
    mu, tau = parse_prior(prior, pb.names)
    sig = pb.ols_sigma() if pb.sigma is None else pb.sigma
    c = pb.red.scale
    cs = np.where(c > 0, c, 1.0)  # zero columns: z_j = D_j
    has = np.isfinite(tau)
    P = np.diag(1.0 / (cs * tau))[has]  # prior rows: z_j / (c_j tau_j) = mu_j / tau_j
    A = np.vstack([pb.red.R / sig, P])
    b = np.concatenate([pb.red.qty / sig, (mu / tau)[has]])
    Ua, s, Vt = np.linalg.svd(A, full_matrices=False)
    r = int(np.sum(s > pb.ra.rcond * s[0]))
    z = Vt[:r].T @ ((Ua[:, :r].T @ b) / s[:r])
    W = Vt[:r].T / s[:r]
    cov = (W @ W.T) / np.outer(cs, cs)  # posterior covariance, natural units
    null = Vt[r:].T
    undetermined = np.linalg.norm(null, axis=1) > 1e-8 if null.size else np.zeros(pb.n, bool)
    prior = {n: {"mean": float(m), "std": float(t)} for n, m, t in zip(pb.names, mu, tau) if np.isfinite(t)}
    return finish(pb, "map", z / cs, cov, sig, undetermined=undetermined, extras=MAPExtras(prior),
                  settings={"prior": prior, "sigma": "estimated" if pb.sigma is None else pb.sigma})


# ------------------------------------------------------------------ linear map (batched Monte Carlo)
__all__ += ["map_linear_map"]


def map_linear_map(S: np.ndarray, prior: Mapping, sigma: float, *, names: Sequence[str] | None = None,
                   rcond: float | None = None):
    """The linear map of :func:`solve_map` with a given noise std: ``D = K y + b``.

    The posterior mean is the least-squares solution of the stacked system of the module
    Notes, ``z = A^+ [Q^T y / sigma; mu / tau]``, so ``K = diag(1/c) A^+[:, :n] Q^T / sigma``
    and ``b = diag(1/c) A^+[:, n:] (mu / tau)``.

    Parameters
    ----------
    S : (N, 3, n) or (m, n) array_like
        Regression matrix in natural units.
    prior : mapping
        ``{name: {"mean": m, "std": s}}`` in natural units (see :func:`parse_prior`).
    sigma : float
        Noise std, m/s (the map is linear in ``y`` only for a given sigma).
    names : sequence of str, optional
        Coefficient names the prior refers to (default ``c0, c1, ...``).
    rcond : float, optional
        Rank threshold, as :func:`solve_map`.

    Returns
    -------
    casep.estimators.ols.LinearMap
        The posterior covariance at `sigma`, ``dof`` None.
    """
    from casep.estimators._base import check_positive
    from casep.estimators.ols import LinearMap, scaled_factors

    sigma = check_positive("sigma", sigma, allow_none=False)
    pb, Q, U, s, Vt = scaled_factors(S, rcond)
    names = pb.names if names is None else tuple(names)
    mu, tau = parse_prior(prior, names)
    cs = np.where(pb.red.scale > 0, pb.red.scale, 1.0)
    has = np.isfinite(tau)
    A = np.vstack([((U * s) @ Vt) / sigma, np.diag(1.0 / (cs * tau))[has]])  # [R / sigma; prior rows]
    Ua, sa, Vta = np.linalg.svd(A, full_matrices=False)
    r = int(np.sum(sa > pb.ra.rcond * sa[0]))
    W = Vta[:r].T / sa[:r]
    Ainv = W @ Ua[:, :r].T  # A^+
    K = (Ainv[:, :pb.n] @ Q.T) / (sigma * cs[:, None])
    b = (Ainv[:, pb.n:] @ (mu / tau)[has]) / cs
    cov = (W @ W.T) / np.outer(cs, cs)  # posterior covariance, natural units
    null = Vta[r:].T
    undetermined = np.linalg.norm(null, axis=1) > 1e-8 if null.size else np.zeros(pb.n, bool)
    return LinearMap(K, b, cov, None, undetermined)

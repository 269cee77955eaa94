"""Principal-component regression: truncated SVD of the column-scaled system.

Notes
-----
With ``R = U diag(s) V^T`` (reduced, unit-norm columns) and ``beta = U^T q``, PCR keeps the
first ``k`` directions::

    z_k    = V_k diag(1/s_k) beta_k,     D = z / c
    Cov(z) = sigma^2 V_k diag(1/s_k^2) V_k^T,   sigma^2 = RSS_k / (m - k)

Truncation rule (documented default): keep direction i while its condition index
``s_0 / s_i <= max_condition_index`` (default 1000), or exactly ``n_components``. The
dropped directions are what the flight cannot determine at that level: each is reported as
a combination ``sum_j v_ij c_j D_j`` of named coefficients (its largest loadings), with its
condition index. PCR is biased along the dropped directions (the estimate has no component
there); the std is the sampling std of the kept part only. With every component kept it is
least squares.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from casep.estimators._base import check_positive, finish, prepare
from casep.estimators.result import EstimateResult, PCRExtras

__all__ = ["solve_pcr", "DEFAULT_MAX_CONDITION_INDEX"]

DEFAULT_MAX_CONDITION_INDEX = 1000.0


def _combination(v: np.ndarray, names: Sequence[str], top: int = 4) -> dict[str, float]:
    order = np.argsort(-np.abs(v))[:top]
    return {names[j]: float(v[j]) for j in order if abs(v[j]) > 1e-3}


def solve_pcr(
    S: np.ndarray,
    y: np.ndarray | None = None,
    *,
    n_components: int | None = None,
    max_condition_index: float = DEFAULT_MAX_CONDITION_INDEX,
    sigma: float | None = None,
    names: Sequence[str] | None = None,
    units: Sequence[str] | None = None,
    si_factors: Sequence[float] | None = None,
    rcond: float | None = None,
) -> EstimateResult:
    """Principal-component estimate of ``D``.

    Parameters
    ----------
    n_components : int, optional
        Directions to keep (overrides `max_condition_index`); at most the rank.
    max_condition_index : float, optional
        Keep directions with ``s_0 / s_i`` up to this (default 1000).

    Returns
    -------
    EstimateResult
        ``diagnostics["dropped_directions"]``: list of ``{"condition_index",
        "combination": {name: loading on c_j D_j}}``.
    """
    max_condition_index = check_positive("max_condition_index", max_condition_index, allow_none=False)
    pb = prepare(S, y, names, units, si_factors, sigma, rcond)
    s, Vt, r = pb.ra.s, pb.ra.Vt, pb.ra.rank
    if n_components is None:
        k = int(np.sum(s[:r] >= s[0] / max_condition_index))
        rule = f"condition index <= {max_condition_index:g}"
    else:
        if isinstance(n_components, bool) or not isinstance(n_components, (int, np.integer)) or not 1 <= n_components:
            raise ValueError(f"`n_components` must be an int >= 1, got {n_components!r}")
        if n_components > r:
            raise ValueError(f"`n_components` = {n_components} exceeds the rank {r} of `S`")
        k = int(n_components)
        rule = f"{k} components"
    beta = pb.ra.U.T @ pb.red.qty
    Vk = Vt[:k].T
    z = Vk @ (beta[:k] / s[:k])  # z_k = V_k diag(1/s_k) beta_k
    rss = pb.red.rho2 + float(np.sum(beta[k:] ** 2))
    sig = float(np.sqrt(rss / (pb.m - k))) if pb.sigma is None else pb.sigma
    W = Vk / s[:k]
    inv_c = pb.inv_c
    cov = sig**2 * (W @ W.T) * np.outer(inv_c, inv_c)
    dropped = [{"condition_index": float(s[0] / s[i]) if s[i] > 0 else None,
                "combination": _combination(Vt[i], pb.names)} for i in range(k, pb.n)]
    return finish(pb, "pcr", z * inv_c, cov, sig,
                  settings={"n_components": k, "rule": rule,
                            "sigma": "estimated" if pb.sigma is None else pb.sigma},
                  diagnostics={"dropped_directions": dropped},
                  extras=PCRExtras(k, rule, dropped, None if n_components is not None else float(max_condition_index)))


# ------------------------------------------------------------------ linear map (batched Monte Carlo)
__all__ += ["pcr_linear_map"]


def pcr_linear_map(S: np.ndarray, *, n_components: int | None = None,
                   max_condition_index: float = DEFAULT_MAX_CONDITION_INDEX, rcond: float | None = None):
    """The linear map of :func:`solve_pcr`: ``D = diag(1/c) V_k diag(1/s_k) U_k^T Q^T y``.

    Parameters
    ----------
    S : (N, 3, n) or (m, n) array_like
        Regression matrix in natural units.
    n_components, max_condition_index, rcond : optional
        As :func:`solve_pcr` (the same ``k`` directions are kept).

    Returns
    -------
    casep.estimators.ols.LinearMap
        Covariance ``V_k diag(1/s_k^2) V_k^T`` (natural units) per unit noise variance,
        ``dof = m - k``.
    """
    from casep.estimators.ols import LinearMap, scaled_factors

    max_condition_index = check_positive("max_condition_index", max_condition_index, allow_none=False)
    pb, Q, U, s, Vt = scaled_factors(S, rcond)
    r, s_ref = pb.ra.rank, pb.ra.s  # the solver's singular values decide k
    if n_components is None:
        k = int(np.sum(s_ref[:r] >= s_ref[0] / max_condition_index))
    elif isinstance(n_components, bool) or not isinstance(n_components, (int, np.integer)) \
            or not 1 <= n_components <= r:
        raise ValueError(f"`n_components` must be an int in [1, {r}] (the rank of `S`), got {n_components!r}")
    else:
        k = int(n_components)
    W = Vt[:k].T / s[:k]  # V_k diag(1/s_k)
    K = (W @ (Q @ U[:, :k]).T) * pb.inv_c[:, None]
    cov = (W @ W.T) * np.outer(pb.inv_c, pb.inv_c)
    return LinearMap(K, np.zeros(pb.n), cov, float(pb.m - k), ~pb.ra.estimable)

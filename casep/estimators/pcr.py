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

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Sequence, Unpack

import numpy as np

from casep.estimators._base import Prepared, finish
from casep.estimators._options import Interval, Labels, Method, Option

if TYPE_CHECKING:
    from casep.estimators.ols import LinearMap
    from casep.estimators.result import EstimateResult
    from casep.regression.problem import Problem

__all__ = ["solve_pcr", "DEFAULT_MAX_CONDITION_INDEX", "PCR", "PCRExtras"]

DEFAULT_MAX_CONDITION_INDEX = 1000.0

#: Its options (``casep separate --components``) and solver keywords.
N_COMPONENTS = Option("n_components", "--components", None, (Interval(int, 1),),
                      "principal components kept (default: CI <= 1000)")
MAX_CONDITION_INDEX = Option("max_condition_index", "--max-condition-index", DEFAULT_MAX_CONDITION_INDEX,
                             (Interval(float, 0, None, "neither"),), "keep directions with s_0 / s_i up to this")


@dataclass(frozen=True)
class PCRExtras:
    """PCR: components kept, the rule, the condition-index cut (None when `n_components` was
    given) and the dropped directions (condition index, leading loadings)."""

    n_components: int
    rule: str
    dropped_directions: list
    max_condition_index: float | None = None

    def describe(self, res: Any) -> list[str]:
        """Its part of the settings line."""
        out = [f"{self.n_components} of {len(res.names)} components kept ({self.rule})"]
        ci = [d["condition_index"] for d in self.dropped_directions if d["condition_index"] is not None]
        if self.dropped_directions:
            span = "-" if not ci else f"{min(ci):.3g}" if min(ci) == max(ci) else f"{min(ci):.3g} .. {max(ci):.3g}"
            out.append(f"{len(self.dropped_directions)} dropped (condition index {span})")
        return out

    @staticmethod
    def old_form(settings: dict, diagnostics: dict, extras: dict | None) -> tuple[dict, dict, dict | None]:
        """A result file of an earlier casep: the dropped directions also in ``diagnostics``; earlier still,
        ``settings["n_components"]`` the components kept and ``settings["rule"]`` the rule."""
        settings, diagnostics = dict(settings), dict(diagnostics)
        dropped = diagnostics.pop("dropped_directions", None)
        rule = settings.pop("rule", None)
        if isinstance(rule, str) and rule.startswith("condition index <= "):  # the default rule: k was found
            k = settings.get("n_components")
            settings["n_components"] = None
            settings["max_condition_index"] = float(rule.rsplit(" ", 1)[1])
            if extras is None and isinstance(k, int) and dropped is not None:
                extras = {"n_components": k, "rule": rule, "dropped_directions": dropped,
                          "max_condition_index": settings["max_condition_index"]}
        elif extras is None and isinstance(rule, str) and dropped is not None:
            extras = {"n_components": settings.get("n_components"), "rule": rule, "dropped_directions": dropped}
        return settings, diagnostics, extras


def _combination(v: np.ndarray, names: Sequence[str], top: int = 4) -> dict[str, float]:
    order = np.argsort(-np.abs(v))[:top]
    return {names[j]: float(v[j]) for j in order if abs(v[j]) > 1e-3}


def kept_components(s: np.ndarray, rank: int, n_components: int | None, max_condition_index: float) -> int:
    """How many directions PCR keeps: `n_components` (at most the rank), else those with condition
    index ``s_0 / s_i <= max_condition_index``; the solver and its linear map share this rule."""
    if n_components is None:
        return int(np.sum(s[:rank] >= s[0] / max_condition_index))
    if n_components > rank:
        raise ValueError(f"`n_components` = {n_components} exceeds the rank {rank} of `S`")
    return int(n_components)


def solve_pcr(S: np.ndarray | Problem, y: np.ndarray | None = None, *, n_components: int | None = None,
              max_condition_index: float = DEFAULT_MAX_CONDITION_INDEX, **labels: Unpack[Labels]) -> EstimateResult:
    """Principal-component estimate of ``D``.

    Parameters
    ----------
    S, y : array_like or Problem
        Regression (natural units) and velocity error, as :func:`casep.solve_ols`.
    n_components : int, optional
        Directions to keep (overrides `max_condition_index`); at most the rank.
    max_condition_index : float, optional
        Keep directions with ``s_0 / s_i`` up to this (default 1000).
    **labels
        ``names``, ``units``, ``si_factors``, ``sigma``, ``rcond``, as :func:`casep.solve_ols`.

    Returns
    -------
    EstimateResult
        ``extras`` (:class:`PCRExtras`): the components kept, the rule and the dropped directions
        (list of ``{"condition_index", "combination": {name: loading on c_j D_j}}``); ``settings``: the
        inputs `n_components` and `max_condition_index`.
    """
    return PCR.call(S, y, n_components=n_components, max_condition_index=max_condition_index, **labels)


def _solve(pb: Prepared, *, method: Method, max_condition_index: float,
           n_components: int | None = None) -> EstimateResult:
    s, Vt, r = pb.ra.s, pb.ra.Vt, pb.ra.rank
    k = kept_components(s, r, n_components, max_condition_index)
    rule = f"condition index <= {max_condition_index:g}" if n_components is None else f"{k} components"
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
    return finish(pb, method, z * inv_c, cov, sig,
                  settings={"n_components": n_components, "max_condition_index": max_condition_index,  # inputs
                            "sigma": "estimated" if pb.sigma is None else pb.sigma},
                  extras=PCRExtras(k, rule, dropped, None if n_components is not None else float(max_condition_index)))


# ------------------------------------------------------------------ linear map (batched Monte Carlo)
__all__ += ["pcr_linear_map"]


def pcr_linear_map(S: np.ndarray, *, n_components: int | None = None,
                   max_condition_index: float = DEFAULT_MAX_CONDITION_INDEX, rcond: float | None = None) -> LinearMap:
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

    n_components = N_COMPONENTS.check(n_components)
    max_condition_index = MAX_CONDITION_INDEX.check(max_condition_index)
    pb, Q, U, s, Vt = scaled_factors(S, rcond)
    k = kept_components(pb.ra.s, pb.ra.rank, n_components, max_condition_index)  # the solver's singular values
    W = Vt[:k].T / s[:k]  # V_k diag(1/s_k)
    K = (W @ (Q @ U[:, :k]).T) * pb.inv_c[:, None]
    cov = (W @ W.T) * np.outer(pb.inv_c, pb.inv_c)
    return LinearMap(K, np.zeros(pb.n), cov, float(pb.m - k), ~pb.ra.estimable)


#: Principal-component regression (biased along the dropped directions).
PCR = Method("pcr", "principal-component regression", _solve, "solve_pcr", (N_COMPONENTS,),
             keywords=(MAX_CONDITION_INDEX,), batched=True, extras_type=PCRExtras, regularised=True,
             linear_map=lambda S, **kw: pcr_linear_map(S, n_components=kw.get("n_components"), rcond=kw.get("rcond"),
                                                       max_condition_index=kw.get("max_condition_index",
                                                                                  DEFAULT_MAX_CONDITION_INDEX)))

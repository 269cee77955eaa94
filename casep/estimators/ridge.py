"""Ridge regression on the column-scaled, QR-reduced system; lambda by GCV or L-curve.

Notes
-----
In scaled coordinates ``z = c * D`` (unit-norm columns ``Z = S / c``) ridge solves::

    min_z ||y - Z z||^2 + lambda ||z||^2  =  min_z ||q - R z||^2 + rho^2 + lambda ||z||^2

With ``R = U diag(s) V^T`` and ``beta = U^T q``::

    z(lambda)   = V diag(s / (s^2 + lambda)) beta
    RSS(lambda) = sum_i (lambda / (s_i^2 + lambda))^2 beta_i^2 + rho^2
    tr H        = sum_i s_i^2 / (s_i^2 + lambda)
    GCV(lambda) = m RSS / (m - tr H)^2                       (Golub, Heath & Wahba 1979)
    Cov(z)      = sigma^2 V diag(s^2 / (s^2 + lambda)^2) V^T,  sigma^2 = RSS / (m - tr H)

The covariance is the sampling covariance of the (biased) ridge estimator; the bias
``-lambda V diag(1 / (s^2 + lambda)) V^T z_true`` is not in the std. L-curve: the corner of
``(log RSS, log ||z||)`` is the point of maximum curvature over ``log lambda``
(Hansen 1992). ``solver="cvxpy"`` solves the same problem with cvxpy + Clarabel on the
n x n reduced system (never on the 3N rows) as an independent cross-check.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Unpack

import numpy as np

from casep.estimators._base import Prepared, finish
from casep.estimators._options import Choices, Interval, Labels, Method, Option

if TYPE_CHECKING:
    from casep.estimators.ols import LinearMap
    from casep.estimators.result import EstimateResult
    from casep.regression.problem import Problem

__all__ = ["solve_ridge", "gcv_curve", "lcurve_corner", "RIDGE", "RidgeExtras"]

#: Its option (``casep separate --lambda``) and solver keyword.
LAM = Option("lam", "--lambda", "gcv", (Choices(("gcv", "lcurve")), Interval(float, 0, None, "neither")),
             "ridge parameter on unit-norm columns, or its rule")
SOLVER = Option("solver", "--solver", "svd", (Choices(("svd", "cvxpy")),),
                "closed form through the SVD of the reduced triangle, or cvxpy + Clarabel")


@dataclass(frozen=True)
class RidgeExtras:
    """Ridge: lambda (scaled coordinates), the rule that chose it, effective dof tr(H)."""

    lam: float
    rule: str
    effective_dof: float

    def describe(self, res: Any) -> list[str]:
        """Its part of the settings line."""
        rule = {"gcv": "GCV", "lcurve": "L-curve corner"}.get(self.rule, self.rule)
        return [f"lambda {self.lam:.4g} on unit-norm columns ({rule})",
                f"effective dof {self.effective_dof:.3g} of {len(res.names)}"]

    @staticmethod
    def old_form(settings: dict, diagnostics: dict, extras: dict | None) -> tuple[dict, dict, dict | None]:
        """A result file of an earlier casep: ``settings["lambda"]`` was the lambda found,
        ``settings["lambda_rule"]`` its rule and ``diagnostics["effective_dof"]`` tr H; read as the input
        asked (the rule, or the given lambda) and the extras."""
        if "lambda_rule" not in settings:
            return settings, diagnostics, extras
        settings, diagnostics = dict(settings), dict(diagnostics)
        rule, lam = settings.pop("lambda_rule"), settings.get("lambda")
        dof = diagnostics.pop("effective_dof", None)
        if extras is None and isinstance(lam, (int, float)) and isinstance(dof, (int, float)):
            extras = {"lam": float(lam), "rule": rule, "effective_dof": float(dof)}
        settings["lambda"] = lam if rule == "given" else rule
        return settings, diagnostics, extras


def _ridge_terms(s: np.ndarray, beta: np.ndarray, rho2: float, lam: np.ndarray):
    lam = np.atleast_1d(lam)[:, None]
    s2 = s[None, :] ** 2
    shrink = lam / (s2 + lam)
    rss = np.sum((shrink * beta) ** 2, axis=1) + rho2
    trh = np.sum(s2 / (s2 + lam), axis=1)
    znorm2 = np.sum((s[None, :] / (s2 + lam) * beta) ** 2, axis=1)
    return rss, trh, znorm2


def gcv_curve(s: np.ndarray, beta: np.ndarray, rho2: float, m: int, lam: np.ndarray) -> np.ndarray:
    """GCV(lambda) = m RSS / (m - tr H)^2 on a grid of lambda values."""
    rss, trh, _ = _ridge_terms(s, beta, rho2, lam)
    return m * rss / (m - trh) ** 2


def _grid(s: np.ndarray) -> np.ndarray:
    pos = s[s > 0]
    lo, hi = np.log10(pos.min() ** 2) - 4, np.log10(pos.max() ** 2) + 2
    return np.logspace(lo, hi, 400)


def _gcv_lambda(s, beta, rho2, m) -> float:
    from casep.noise.fit import bounded_minimum  # scipy's bounded Brent search, without importing scipy.optimize

    grid = _grid(s)
    g = gcv_curve(s, beta, rho2, m, grid)
    k = int(np.argmin(g))
    a, b = np.log10(grid[max(k - 1, 0)]), np.log10(grid[min(k + 1, grid.size - 1)])
    u = bounded_minimum(lambda u: float(gcv_curve(s, beta, rho2, m, np.array([10.0**u]))[0]), a, b, xatol=1e-6)
    return float(10.0 ** u)


def lcurve_corner(s: np.ndarray, beta: np.ndarray, rho2: float) -> float:
    """Lambda at the maximum curvature of the L-curve (log RSS, log ||z||)."""
    grid = _grid(s)
    rss, _, zn = _ridge_terms(s, beta, rho2, grid)
    t = np.log(grid)
    x, y = np.log(rss), 0.5 * np.log(zn)
    dx, dy = np.gradient(x, t), np.gradient(y, t)
    ddx, ddy = np.gradient(dx, t), np.gradient(dy, t)
    kappa = (dx * ddy - dy * ddx) / np.maximum((dx**2 + dy**2) ** 1.5, 1e-300)
    return float(grid[int(np.argmax(kappa[2:-2])) + 2])


def _cvxpy_ridge(R: np.ndarray, q: np.ndarray, lam: float) -> np.ndarray:
    import cvxpy as cp

    z = cp.Variable(R.shape[1])
    prob = cp.Problem(cp.Minimize(cp.sum_squares(R @ z - q) + lam * cp.sum_squares(z)))
    prob.solve(solver=cp.CLARABEL, tol_gap_abs=1e-10, tol_gap_rel=1e-10, tol_feas=1e-10)
    if prob.status != cp.OPTIMAL:
        raise RuntimeError(f"cvxpy/Clarabel ridge did not converge: {prob.status}")
    return np.asarray(z.value, dtype=float)


def solve_ridge(S: np.ndarray | Problem, y: np.ndarray | None = None, *, lam: float | str = "gcv",
                solver: str = "svd", **labels: Unpack[Labels]) -> EstimateResult:
    """Ridge estimate of ``D`` on unit-norm columns.

    Parameters
    ----------
    S, y : array_like or Problem
        Regression (natural units) and velocity error, as :func:`casep.solve_ols`.
    lam : float or {"gcv", "lcurve"}, optional
        Ridge parameter for the unit-norm columns, or the rule choosing it (default GCV).
    solver : {"svd", "cvxpy"}, optional
        Closed form through the SVD of the reduced triangle, or cvxpy + Clarabel.
    **labels
        ``names``, ``units``, ``si_factors``, ``rcond`` as :func:`casep.solve_ols`; ``sigma``: noise
        std for the reported std (default: ``RSS / (m - tr H)``).

    Returns
    -------
    EstimateResult
        ``settings["lambda"]`` the input (the rule or the given value); ``extras``
        (:class:`RidgeExtras`): the lambda used, its rule and the effective dof tr H.
    """
    return RIDGE.call(S, y, lam=lam, solver=solver, **labels)


def _solve(pb: Prepared, *, method: Method, lam: float | str, solver: str) -> EstimateResult:
    U, s, Vt = pb.ra.U, pb.ra.s, pb.ra.Vt
    beta = U.T @ pb.red.qty
    m = pb.m
    asked = lam  # the input: a rule or a number
    rule = lam if isinstance(lam, str) else "given"
    if lam == "gcv":
        lam = _gcv_lambda(s, beta, pb.red.rho2, m)
    elif lam == "lcurve":
        lam = lcurve_corner(s, beta, pb.red.rho2)
    lam = float(lam)
    filt = s / (s**2 + lam)  # z = V diag(s / (s^2 + lambda)) U^T q
    z = Vt.T @ (filt * beta) if solver == "svd" else _cvxpy_ridge(pb.red.R, pb.red.qty, lam)
    rss, trh, _ = _ridge_terms(s, beta, pb.red.rho2, np.array([lam]))
    sig = float(np.sqrt(rss[0] / (m - trh[0]))) if pb.sigma is None else pb.sigma
    G = Vt.T * (s / (s**2 + lam))  # Cov(z) = sigma^2 G G^T
    inv_c = pb.inv_c
    cov = sig**2 * (G @ G.T) * np.outer(inv_c, inv_c)
    return finish(pb, method, z * inv_c, cov, sig,
                  settings={"lambda": asked, "solver": solver,  # inputs; found: extras
                            "sigma": "estimated" if pb.sigma is None else pb.sigma},
                  extras=RidgeExtras(float(lam), rule, float(trh[0])))


# ------------------------------------------------------------------ linear map (batched Monte Carlo)
__all__ += ["ridge_linear_map"]


def ridge_linear_map(S: np.ndarray, lam: float, *, rcond: float | None = None) -> LinearMap:
    """The linear map of :func:`solve_ridge` at a given lambda: ``D = diag(1/c) V diag(s/(s^2+lambda)) U^T Q^T y``.

    Returns
    -------
    casep.estimators.ols.LinearMap
        Covariance ``G G^T`` per unit noise variance (``G = diag(1/c) V diag(s/(s^2+lambda))``),
        ``dof = m - tr H``.
    """
    from casep.estimators.ols import LinearMap, scaled_factors

    if isinstance(lam, str):
        raise ValueError(f"`lam` must be a number > 0 for the linear map (a rule chooses it per run), got {lam!r}")
    lam = LAM.check(lam)
    pb, Q, U, s, Vt = scaled_factors(S, rcond)
    G = Vt.T * (s / (s**2 + lam))  # z = V diag(s / (s^2 + lambda)) U^T Q^T y
    K = (G @ (Q @ U).T) * pb.inv_c[:, None]
    cov = (G @ G.T) * np.outer(pb.inv_c, pb.inv_c)
    trh = float(np.sum(s**2 / (s**2 + lam)))  # tr H
    return LinearMap(K, np.zeros(pb.n), cov, pb.m - trh, ~pb.ra.estimable)


#: Ridge regression (biased towards 0 along poorly determined directions).
RIDGE = Method("ridge", "ridge regression (GCV, L-curve or given lambda)", _solve, "solve_ridge", (LAM,),
               keywords=(SOLVER,), extras_type=RidgeExtras, regularised=True,
               linear_map=lambda S, **kw: ridge_linear_map(S, kw["lam"], rcond=kw.get("rcond")))

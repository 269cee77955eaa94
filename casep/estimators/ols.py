"""Ordinary least squares on the column-scaled, QR-reduced system.

Notes
-----
With ``Z = S diag(c)^-1`` (unit-norm columns) and the reduction of :mod:`casep.regression.linalg`,
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

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Unpack

import numpy as np

from casep.estimators._base import Prepared, determined_up_to_partners, finish, prepare
from casep.estimators._options import Labels, Method
from casep.regression.linalg import REFINE_ABOVE, covariance_std, qr_forward_error, refine_least_squares
from casep.regression.problem import Problem as RegressionProblem

if TYPE_CHECKING:
    from casep.estimators.result import EstimateResult
    from casep.regression.problem import Problem

__all__ = ["solve_ols", "OLS", "OLSExtras", "least_squares"]


@dataclass(frozen=True)
class OLSExtras:
    """OLS: the relative singular-value cut of the rank decision (``settings["rcond"]``: the one asked
    for, None for the default ``max(m, n) eps``)."""

    rcond: float

    @staticmethod
    def old_form(settings: dict, diagnostics: dict, extras: dict | None) -> tuple[dict, dict, dict | None]:
        """A result file of an earlier casep: ``settings["rcond"]`` was the threshold used (given or
        the default; as an input it gives the same rank decision), the only record of it without extras."""
        if extras is None and isinstance(settings.get("rcond"), (int, float)):
            extras = {"rcond": float(settings["rcond"])}
        return settings, diagnostics, extras

    def describe(self, res: Any) -> list[str]:
        """Its part of the settings line."""
        return [f"rcond {self.rcond:.3g}"]


def solve_ols(S: np.ndarray | Problem, y: np.ndarray | None = None, **labels: Unpack[Labels]) -> EstimateResult:
    """Least-squares estimate of ``D`` in ``y = S D + e`` with honest standard deviations.

    Parameters
    ----------
    S : (N, 3, n) or (m, n) array_like, or Problem
        Regression matrix in natural units (from :func:`casep.build_sv`), or a
        :class:`~casep.regression.problem.Problem` (then `y` is omitted: the problem holds it).
    y : (N, 3) or (m,) array_like
        Observed velocity error, m/s.
    **labels
        ``names``, ``units``, ``si_factors`` (coefficient labels, default ``c0, c1, ...``),
        ``sigma`` (known noise std, m/s; default: estimated from the residuals) and ``rcond``
        (rank threshold, see :func:`casep.regression.linalg.analyze_rank`):
        :class:`~casep.estimators._options.Labels`.

    Returns
    -------
    EstimateResult
        ``status`` 1: every coefficient estimated; 2: some (or all, their combinations determined) are not
        identifiable on this data (reported NaN with a reason); -1: nothing is (rank 0).
    """
    return OLS.call(S, y, **labels)


def _solve(pb: Prepared, *, method: Method) -> EstimateResult:
    x, cov, sig = least_squares(pb)
    return finish(pb, method, x, cov, sig, extras=OLSExtras(float(pb.ra.rcond)),  # the rank threshold used
                  settings={"rcond": pb.rcond_asked, "sigma": "estimated" if pb.sigma is None else pb.sigma})


def least_squares(pb: Prepared, *, refine: bool = True) -> tuple[np.ndarray, np.ndarray, float]:
    """Minimum-norm LS solution, covariance and sigma of a prepared problem (natural units).

    When the predicted error of the QR solve (:func:`casep.regression.linalg.qr_forward_error`)
    exceeds :data:`~casep.regression.linalg.REFINE_ABOVE` and the rows are held in memory (a problem
    that regenerates S_V is not integrated again for it), the solution gets one step of iterative
    refinement with its residual in extended precision
    (:func:`~casep.regression.linalg.refine_least_squares`). A well-conditioned fit skips it, and so
    does ``refine=False`` (the inner solves of an iteration whose end point is what counts).
    """
    ra, red = pb.ra, pb.red
    V, inv_s = ra.pinv_factors()
    Uq = ra.U.T @ red.qty
    inv_c = pb.inv_c
    x_Z = V @ (inv_s * Uq[: ra.rank])  # x_Z = V_r diag(1/s_r) U_r^T q
    x = x_Z * inv_c  # D = x_Z / c
    if refine and pb.problem.rows_in_memory and qr_forward_error(red, ra, x_Z) > REFINE_ABOVE:
        x = refine_least_squares(red, ra, x, pb.problem.blocks)  # residual in extended precision
    sig = pb.ols_sigma() if pb.sigma is None else pb.sigma  # sigma^2 = RSS / (m - r)
    W = V * inv_s  # V_r diag(1/s_r)
    cov = sig**2 * (W @ W.T) * np.outer(inv_c, inv_c)
    return x, cov, sig


# ------------------------------------------------------------------ linear map (batched Monte Carlo)
__all__ += ["LinearMap", "ols_linear_map", "scaled_factors"]


@dataclass(frozen=True)
class LinearMap:
    """An estimator that is a fixed linear function of the data: ``D = K y + b`` (natural units).

    Attributes
    ----------
    K : (n, m) ndarray
        Acts on the stacked data ``y`` (rows x, y, z per sample, as ``S.reshape(-1, n)``).
    b : (n,) ndarray
        Offset (the prior's pull for MAP; zero otherwise).
    cov : (n, n) ndarray
        Covariance the solver reports: for noise std 1 when ``dof`` is set (multiply by
        ``sigma^2``, ``sigma^2 = ||y - S D||^2 / dof`` as the solver estimates it), else for
        the sigma the map was built with.
    dof : float or None
        Residual degrees of freedom of the solver's sigma estimate; None when sigma is given.
    undetermined : (n,) bool ndarray
        Coefficients the solver reports without an estimate (NaN).
    """

    K: np.ndarray
    b: np.ndarray
    cov: np.ndarray
    dof: float | None
    undetermined: np.ndarray

    def apply(self, S: np.ndarray, Y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Estimates and std for data columns ``Y`` (m, runs): ``(n, runs)`` each, NaN where undetermined."""
        X = self.K @ Y + self.b[:, None]  # D = K y + b, every run at once
        sd = covariance_std(self.cov)
        if self.dof is None:
            std = np.repeat(sd[:, None], Y.shape[1], axis=1)
        else:
            sig = np.sqrt(np.sum((Y - S @ X) ** 2, axis=0) / self.dof)  # sigma^2 = RSS / dof, per run
            std = sd[:, None] * sig[None, :]
        und = self.undetermined[:, None]
        return np.where(und, np.nan, X), np.where(und, np.nan, std)

    def up_to_partners(self, S: np.ndarray, names: Sequence[str], magnitudes: Mapping[str, float],
                       sigma: float) -> LinearMap:
        """The map as the solver's result reports it (:func:`casep.estimators._base.finish`): the exactly dependent
        coefficients the data determine in practice (:class:`~casep.regression.linalg.PartnerBound` with the declared
        `magnitudes`) get the solution of least size in units of the magnitudes, ``D = Pi (K y + b)``, covariance
        ``Pi C Pi^T``. `S` is the map's ``(m, n)`` regression, `sigma` the noise std at which the rule judges a
        coefficient's std (the covariance is per unit noise variance when ``dof`` is set)."""
        if not (magnitudes and self.undetermined.any()):
            return self
        S_arr = np.asarray(S, dtype=float)
        pb = prepare(RegressionProblem.from_arrays(S_arr, np.zeros(S_arr.shape[:-1]), names=names,
                                                   magnitudes=magnitudes), None, None, None, None, None)
        unit = sigma**2 if self.dof is not None else 1.0
        _, cov_w, und, _, Pi = determined_up_to_partners(pb, np.zeros(pb.n), self.cov * unit, self.undetermined)
        if Pi is None:
            return self
        return LinearMap(Pi @ self.K, Pi @ self.b, cov_w / unit, self.dof, und)  # cov_w = Pi C Pi^T, at `unit`


def scaled_factors(S: np.ndarray, rcond: float | None = None):
    """The problem of `S` (no data), ``Q`` of ``Z = S diag(1/c) = Q R`` and the SVD of that ``R``.

    Returns ``(pb, Q, U, s, Vt)``: `pb` is :func:`casep.estimators._base.prepare`'s problem
    (scale, rank and rcond as the solvers use them), ``R = U diag(s) Vt``.
    """
    S_arr = np.asarray(S, dtype=float)
    pb = prepare(S_arr, np.zeros(S_arr.shape[:-1]), None, None, None, None, rcond)
    cs = np.where(pb.red.scale > 0, pb.red.scale, 1.0)
    Q, R = np.linalg.qr(pb.S / cs, mode="reduced")  # Z = Q R
    U, s, Vt = np.linalg.svd(R)
    return pb, Q, U, s, Vt


def ols_linear_map(S: np.ndarray, *, rcond: float | None = None) -> LinearMap:
    """The linear map of :func:`solve_ols`: ``D = K y``, ``Cov = sigma^2 K K^T``.

    Parameters
    ----------
    S : (N, 3, n) or (m, n) array_like
        Regression matrix in natural units.
    rcond : float, optional
        Rank threshold, as :func:`solve_ols`.

    Returns
    -------
    LinearMap
        ``K = diag(1/c) V_r diag(1/s_r) U_r^T Q^T`` (minimum-norm LS), covariance per unit
        noise variance, ``dof = m - r``.
    """
    pb, Q, U, s, Vt = scaled_factors(S, rcond)
    r = pb.ra.rank
    W = Vt[:r].T / s[:r]  # V_r diag(1/s_r)
    K = (W @ (Q @ U[:, :r]).T) * pb.inv_c[:, None]  # x_Z = V_r diag(1/s_r) U_r^T Q^T y, then / c
    cov = (W @ W.T) * np.outer(pb.inv_c, pb.inv_c)
    return LinearMap(K, np.zeros(pb.n), cov, float(pb.m - r), ~pb.ra.estimable)


#: Ordinary least squares: the reference every other method is judged against.
OLS = Method("ols", "least squares on the scaled QR reduction", _solve, "solve_ols", batched=True,
             extras_type=OLSExtras, linear_map=lambda S, **kw: ols_linear_map(S, rcond=kw.get("rcond")), hac=True)

"""Robust (Huber) least squares by iteratively reweighted least squares, with outlier flags.

Notes
-----
Tracking data have glitches. The Huber M-estimate minimises ``sum rho(r_i / s)`` with::

    rho(u) = u^2 / 2                 |u| <= c
           = c |u| - c^2 / 2         |u| >  c          (c = 1.345: 95 % efficiency in Gaussian noise)

over the scalar rows ``r_i = y_i - S_i D`` (three per sample). IRLS: with weights
``w_i = min(1, c / |r_i / s|)`` solve weighted least squares on the scaled QR reduction
(:func:`casep.estimators.ols.least_squares` on ``sqrt(w) S``, ``sqrt(w) y``), re-estimate the scale
``s = 1.4826 MAD(r)`` and repeat until ``max |dD| / std < tol``. A full-rank regression takes each step
on one orthonormal basis of ``S`` instead (:class:`_Basis`: the same solution, an ``m x n`` product per step
instead of a QR; 0.38 -> 0.17 CPU s per fit of the 20 Hz paper flight with 2 % glitches).

Covariance (Huber 1981, eq. 7.6.5; statsmodels RLM "H1")::

    Cov(D) = K^2 [sum psi(u_i)^2 / (m - p)] / [mean psi'(u_i)]^2  s^2 (S^T S)^-1,
    K = 1 + (p / m) var(psi') / mean(psi')^2,   psi(u) = clip(u, -c, c)

Rows whose studentized residual ``|r_i| / s`` exceeds ``flag`` (default 4: P = 6e-5 per row
in Gaussian noise) are reported as outliers (sample row, axis, time index, size in s).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Mapping, Unpack

import numpy as np

from casep._special import MAD_SIGMA  # sigma = MAD_SIGMA * MAD for Gaussian data
from casep.estimators._base import Prepared, finish, prepare
from casep.estimators._options import Interval, Labels, Method, Option, SeveralFlights
from casep.estimators.ols import least_squares

if TYPE_CHECKING:
    from casep.estimators.result import EstimateResult
    from casep.regression.joint import JointProblem
    from casep.regression.problem import Problem

__all__ = ["solve_huber", "HUBER_C", "HUBER", "HuberExtras"]

#: Huber's tuning constant: 95 % asymptotic efficiency at the Gaussian.
HUBER_C = 1.345
_MAX_FLAGS = 50

#: Its solver keywords (not command-line options).
C = Option("c", "--huber-c", HUBER_C, (Interval(float, 0, None, "neither"),),
           "Huber constant in units of the noise scale")
FLAG = Option("flag", "--flag", 4.0, (Interval(float, 0, None, "neither"),),
              "studentized residual above which a row is flagged as an outlier")
TOL = Option("tol", "--tol", 1e-8, (Interval(float, 0, None, "neither"),), "IRLS stops below this step, in std")
MAX_ITER = Option("max_iter", "--max-iter", 50, (Interval(int, 1),), "IRLS iterations at most")


@dataclass(frozen=True)
class HuberExtras:
    """Huber: tuning constant c (in scale units), IRLS iterations, the MAD scale (m/s) and
    the flagged outlier rows (count, threshold, largest studentized residuals)."""

    c: float
    iterations: int
    scale: float
    outliers: dict

    def describe(self, res: Any) -> list[str]:
        """Its part of the settings line."""
        return [f"Huber c {self.c:g}, {self.iterations} IRLS iterations, scale {self.scale:.4g}",
                f"{self.outliers.get('count', 0)} rows flagged above {self.outliers.get('threshold_sigma', 0):g} sigma"]

    @staticmethod
    def old_form(settings: dict, diagnostics: dict, extras: dict | None) -> tuple[dict, dict, dict | None]:
        """A result file of an earlier casep: the outliers also in ``diagnostics["outliers"]``; earlier
        still, ``settings`` held the iterations, the scale, ``flag_sigma`` and ``outliers_flagged``."""
        settings, diagnostics = dict(settings), dict(diagnostics)
        outliers = diagnostics.pop("outliers", None)
        found = {k: settings.pop(k, None) for k in ("iterations", "scale", "outliers_flagged")}
        if "flag_sigma" in settings:
            settings["flag"] = settings.pop("flag_sigma")
        if extras is None and outliers is not None and found["iterations"] is not None and found["scale"] is not None:
            extras = {"c": settings.get("c", HUBER_C), "iterations": found["iterations"], "scale": found["scale"],
                      "outliers": outliers}
        return settings, diagnostics, extras


def solve_huber(S: np.ndarray | Problem, y: np.ndarray | None = None, *, c: float = HUBER_C, flag: float = 4.0,
                tol: float = 1e-8, max_iter: int = 50, **labels: Unpack[Labels]) -> EstimateResult:
    """Huber M-estimate of ``D`` in ``y = S D + e`` with heavy-tailed (glitchy) noise.

    Parameters
    ----------
    S : (N, 3, n) or (m, n) array_like, or Problem
        Regression matrix, natural units.
    y : (N, 3) or (m,) array_like
        Velocity error, m/s.
    c : float, optional
        Huber constant in units of the noise scale (default 1.345).
    flag : float, optional
        Studentized residual above which a row is flagged as an outlier (default 4).
    tol, max_iter : optional
        IRLS stops when no estimate moves by more than ``tol`` std.
    **labels
        ``names``, ``units``, ``si_factors``, ``rcond`` as :func:`casep.solve_ols`; ``sigma``: known
        noise scale, m/s (default: robust MAD estimate, updated each iteration).

    Returns
    -------
    EstimateResult
        ``extras`` (:class:`HuberExtras`): c, IRLS iterations, the scale, the outliers (count,
        threshold, rows (sample, axis, size in sigma) of the largest);
        ``settings``: the inputs c, flag, tol, max_iter.
    """
    return HUBER.call(S, y, c=c, flag=flag, tol=tol, max_iter=max_iter, **labels)


def _solve(pb: Prepared, *, method: Method, c: float, flag: float, tol: float, max_iter: int) -> EstimateResult:
    rcond = pb.ra.rcond
    A, b = pb.S, pb.y  # (m, n) natural units, (m,)
    w = np.ones(b.size)
    x = least_squares(pb, refine=False)[0]  # the start of the iteration
    scale = pb.sigma
    it = 0
    basis = _Basis(pb) if pb.ra.rank == pb.n else None
    for _it in range(1, max_iter + 1):
        it = _it  # the iteration count is reported after the loop
        r = b - A @ x
        scale = pb.sigma or float(MAD_SIGMA * np.median(np.abs(r - np.median(r))))  # s = 1.4826 MAD
        if not scale > 0:
            break  # an exact fit: nothing to down-weight
        u = np.abs(r) / scale
        w = np.minimum(1.0, c / np.maximum(u, 1e-300))  # w_i = min(1, c / |u_i|)
        found = basis.weighted(w, b) if basis is not None else None
        if found is None:
            sw = np.sqrt(w)
            pw = prepare(A * sw[:, None], b * sw, pb.names, pb.units, pb.si_factors, 1.0, rcond)
            x_new, cov_unit, _ = least_squares(pw, refine=False)  # weighted LS; cov for unit sigma
            var_unit = np.diag(cov_unit)
        else:
            x_new, var_unit = found
        step = np.abs(x_new - x) / np.sqrt(np.maximum(var_unit, 1e-300)) / scale
        x = x_new
        if np.all(step[np.isfinite(step)] < tol):
            break
    r = b - A @ x
    m, p = b.size, pb.ra.rank
    if not scale or not scale > 0:
        scale = float(np.sqrt(np.sum(r**2) / max(m - p, 1)))
    u = r / scale if scale > 0 else np.zeros_like(r)
    psi = np.clip(u, -c, c)  # psi(u)
    dpsi = (np.abs(u) <= c).astype(float)  # psi'(u)
    mean_d = max(float(dpsi.mean()), 1.0 / m)
    K = 1.0 + (p / m) * float(dpsi.var()) / mean_d**2
    factor = K**2 * (float(np.sum(psi**2)) / (m - p)) / mean_d**2  # Huber's H1 correction
    _, cov_ols_unit, _ = least_squares(prepare(A, b, pb.names, pb.units, pb.si_factors, 1.0, rcond), refine=False)
    cov = factor * scale**2 * cov_ols_unit  # s^2 (S^T S)^-1 scaled by the H1 factor
    sig = float(scale * np.sqrt(factor))
    big = np.flatnonzero(np.abs(u) > flag)
    order = big[np.argsort(-np.abs(u[big]))][:_MAX_FLAGS]
    rows = [{"sample": int(i // 3), "axis": "xyz"[i % 3], "size_sigma": float(u[i])} for i in order] \
        if A.shape[0] == 3 * (A.shape[0] // 3) else [{"row": int(i), "size_sigma": float(u[i])} for i in order]
    outliers = {"count": int(big.size), "threshold_sigma": float(flag), "largest": rows}
    return finish(pb, method, x, cov, sig, residuals=r,
                  settings={"c": c, "flag": flag, "tol": tol, "max_iter": max_iter,  # inputs; found: extras
                            "sigma": "robust (MAD) scale" if pb.sigma is None else pb.sigma},
                  sigma_source=None if pb.sigma is not None else "robust",
                  extras=HuberExtras(float(c), int(it), float(scale), outliers))


class _Basis:
    """The weighted least squares of an IRLS step on one orthonormal basis of the full-rank regression.

    ``Z = S / c = Q R`` once; with weights ``w`` the step solves ``min ||sqrt(w) (y - Z x_Z)||``, i.e.
    ``G x_Q = Q^T W y`` with ``G = Q^T W Q`` and ``R x_Z = x_Q``, and the unit-sigma covariance of
    ``x_Z`` is ``R^-1 G^-1 R^-T``. ``G``'s eigenvalues lie in ``[min w, max w]`` (``Q`` orthonormal),
    so it is well conditioned where the weights are not extreme: an ``m x n`` product and an
    ``n x n`` Cholesky per step instead of a QR of the weighted ``m x n`` rows, their rank
    analysis and its SVD. The same solution as that QR path (it is the minimum-norm one only at
    full rank, which is why this needs the full-rank problem) to rounding, tested to 1e-9 of the
    std in ``tests/estimators/test_huber.py``. A step whose weights could make the weighted
    problem lose rank at the problem's rank threshold is left to the QR path (:meth:`weighted`
    returns None).
    """

    def __init__(self, pb: Prepared) -> None:
        self.inv_c = pb.inv_c
        self.Q, R = np.linalg.qr(pb.S * pb.inv_c)
        self.Rinv = np.linalg.inv(R)
        s = pb.ra.s
        self.kappa = float(s[0] / s[-1]) if s[-1] > 0 else np.inf
        self.rcond = float(pb.ra.rcond)

    def weighted(self, w: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """``(x, diagonal of the unit-sigma covariance)`` in natural units, or None (module rule above)."""
        # the condition of the weighted rows after their own column scaling (the QR path's) is at most
        # kappa(R) (max w / min w): kappa(R) sqrt(kappa(G)), times sqrt(max w / min w) for the column
        # norms; it must stay well inside the rank threshold
        wmin, wmax = float(w.min()), float(w.max())
        if not (wmin > 0 and self.kappa * wmax / wmin < 1e-2 / max(self.rcond, 1e-300)):
            return None
        wQ = self.Q * w[:, None]
        try:
            L = np.linalg.cholesky(wQ.T @ self.Q)  # G = L L^T
        except np.linalg.LinAlgError:
            return None
        Linv = np.linalg.inv(L)
        xq = Linv.T @ (Linv @ (wQ.T @ b))  # G^-1 Q^T W y
        B = self.Rinv @ Linv.T  # R^-1 L^-T: the covariance of x_Z is B B^T
        return (self.Rinv @ xq) * self.inv_c, np.einsum("ij,ij->i", B, B) * self.inv_c ** 2


def _flights_finish(res: EstimateResult, jp: JointProblem, state: Any, options: Mapping[str, Any]) -> EstimateResult:
    """Each flagged row's flight and its sample in that flight (the stacked rows are flight after flight)."""
    import dataclasses

    if not isinstance(res.extras, HuberExtras):
        return res
    starts = np.asarray(jp.segment_starts)
    rows = []
    for r in res.extras.outliers["largest"]:
        k = int(np.searchsorted(starts, r["sample"], side="right") - 1)  # the flight of the stacked sample
        rows.append({**r, "flight": jp.layout.labels[k], "flight_sample": int(r["sample"] - starts[k])})
    return dataclasses.replace(res, extras=dataclasses.replace(res.extras,
                                                               outliers={**res.extras.outliers, "largest": rows}))


#: Huber's M-estimate; with several flights it estimates the scale of the whitened rows (about 1) itself.
HUBER = Method("huber", "robust (Huber) least squares by IRLS, outliers flagged", _solve, "solve_huber",
               keywords=(C, FLAG, TOL, MAX_ITER), extras_type=HuberExtras, own_scale=True,
               flights=SeveralFlights(sigma=None, finish=_flights_finish))

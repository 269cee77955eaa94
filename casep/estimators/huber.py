"""Robust (Huber) least squares by iteratively reweighted least squares, with outlier flags.

Notes
-----
Tracking data have glitches. The Huber M-estimate minimises ``sum rho(r_i / s)`` with::

    rho(u) = u^2 / 2                 |u| <= c
           = c |u| - c^2 / 2         |u| >  c          (c = 1.345: 95 % efficiency in Gaussian noise)

over the scalar rows ``r_i = y_i - S_i D`` (three per sample). IRLS: with weights
``w_i = min(1, c / |r_i / s|)`` solve weighted least squares on the scaled QR reduction
(:func:`casep.estimators.ols.least_squares` on ``sqrt(w) S``, ``sqrt(w) y``), re-estimate the scale
``s = 1.4826 MAD(r)`` and repeat until ``max |dD| / std < tol``.

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
    for _it in range(1, max_iter + 1):
        it = _it  # the iteration count is reported after the loop
        r = b - A @ x
        scale = pb.sigma or float(MAD_SIGMA * np.median(np.abs(r - np.median(r))))  # s = 1.4826 MAD
        if not scale > 0:
            break  # an exact fit: nothing to down-weight
        u = np.abs(r) / scale
        w = np.minimum(1.0, c / np.maximum(u, 1e-300))  # w_i = min(1, c / |u_i|)
        sw = np.sqrt(w)
        pw = prepare(A * sw[:, None], b * sw, pb.names, pb.units, pb.si_factors, 1.0, rcond)
        x_new, cov_unit, _ = least_squares(pw, refine=False)  # weighted LS; cov for unit sigma
        step = np.abs(x_new - x) / np.sqrt(np.maximum(np.diag(cov_unit), 1e-300)) / scale
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

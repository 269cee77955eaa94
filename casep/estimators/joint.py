"""Several flights in one estimate: stacked reductions, consistency between flights, fusion.

Notes
-----
The flights' stacked, whitened reduction over ``theta = [D_shared, D_pf(1), ..., D_pf(K)]`` is the
data's: :mod:`casep.regression.joint` (:class:`~casep.regression.joint.JointLayout`,
:func:`~casep.regression.joint.joint_reduction`, re-exported here). Here: are the flights consistent?

Consistency of the flights on a shared coefficient j (flights estimate it independently, their
noises being independent): with ``d_k``, ``v_k`` flight k's own estimate and variance (flights where
it is estimable alone), ``dbar = sum(d_k / v_k) / sum(1 / v_k)``::

    chi2_j = sum_k (d_k - dbar)^2 / v_k     ~ chi2(K_j - 1) when the flights agree

Overall (a Chow test): with ``RSS_k`` flight k's own least-squares residual and ``RSS_joint,k`` its
residual under the joint estimate::

    chi2 = sum_k (RSS_joint,k - RSS_k) / sigma_k^2     ~ chi2(sum_k r_k - r_joint)

(``r``: ranks), since the separate fits are the joint model with the shared coefficients freed per
flight. Both are exact for known sigma_k and asymptotically so for estimated ones.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
from scipy import stats

# The stacked reduction of several flights is the data's (casep.regression.joint); re-exported here.
from casep.regression.joint import JointLayout, flight_rss, joint_reduction

__all__ = ["JointLayout", "joint_reduction", "flight_rss", "coefficient_consistency", "overall_consistency",
           "stack_sqrt_information", "WARN_P", "FAIL_P", "largest_disagreements"]

#: p of a consistency test (several flights' Chow test, fused results' chi-square) below which the estimates
#: are said to disagree: a :class:`~casep.exceptions.ConsistencyWarning` with the numbers ...
WARN_P = 0.01
#: ... and below which the combined result fails (``success`` False): about 5 sigma, far beyond chance.
FAIL_P = 1e-6


@dataclass(frozen=True)
class Consistency:
    """A chi-square test of agreement: statistic, degrees of freedom, p-value."""

    chi2: float
    dof: int
    p_value: float

    def to_dict(self) -> dict:
        return {"chi2": self.chi2, "dof": self.dof, "p_value": self.p_value}


def coefficient_consistency(estimates: np.ndarray, variances: np.ndarray) -> Consistency | None:
    """Do independent flights agree on one coefficient? (module notes: chi2_j).

    Parameters
    ----------
    estimates, variances : (K,) array_like
        Each flight's own estimate and variance; NaN where the flight alone does not determine it.

    Returns
    -------
    Consistency, or None when fewer than two flights determine the coefficient.
    """
    d = np.asarray(estimates, dtype=float)
    v = np.asarray(variances, dtype=float)
    ok = np.isfinite(d) & np.isfinite(v) & (v > 0)
    if ok.sum() < 2:
        return None
    d, w = d[ok], 1.0 / v[ok]
    dbar = np.sum(w * d) / np.sum(w)  # inverse-variance weighted mean
    chi2 = float(np.sum(w * (d - dbar) ** 2))  # sum (d_k - dbar)^2 / v_k
    dof = int(ok.sum() - 1)
    return Consistency(chi2, dof, float(stats.chi2.sf(chi2, dof)))


def overall_consistency(rss_joint: Sequence[float], rss_own: Sequence[float], sigmas: Sequence[float],
                        ranks_own: Sequence[int], rank_joint: int, resid_dof: int | None = None) -> Consistency | None:
    """Chow test of all shared coefficients at once (module notes); None when it has no degree of freedom.

    With `resid_dof` (``sum_k (m_k - r_k)``), the F form: the statistic is divided by the separate
    fits' whitened residual variance ``s^2 = sum_k RSS_k / sigma_k^2 / resid_dof`` and referred to
    ``F(q, resid_dof)`` (reported as ``chi2 = q F``), so a common error in the sigmas does not
    change it; with each sigma_k estimated from flight k's own residuals ``s^2 = 1`` and it is the
    chi-square form.
    """
    s2 = np.asarray(sigmas, dtype=float) ** 2
    chi2 = float(np.sum((np.asarray(rss_joint) - np.asarray(rss_own)) / s2))
    dof = int(np.sum(ranks_own)) - int(rank_joint)
    if dof < 1:
        return None
    chi2 = max(chi2, 0.0)
    if resid_dof is None:
        return Consistency(chi2, dof, float(stats.chi2.sf(chi2, dof)))
    scale = float(np.sum(np.asarray(rss_own) / s2)) / resid_dof  # s^2 of the separate fits
    F = chi2 / dof / scale  # ((RSS_joint - RSS_own) / q) / s^2
    return Consistency(F * dof, dof, float(stats.f.sf(F, dof, resid_dof)))


def largest_disagreements(per_coefficient: dict[str, dict], k: int = 3) -> str:
    """The `k` coefficients whose own test (:func:`coefficient_consistency`, as dicts by name) disagrees most:
    ``"Ka0y chi2 41.2 (p 1.4e-10), ..."``; "none testable" when no coefficient has a test."""
    worst = sorted(per_coefficient, key=lambda m: per_coefficient[m]["p_value"])[:k]
    return ", ".join(f"{m} chi2 {per_coefficient[m]['chi2']:.4g} (p {per_coefficient[m]['p_value']:.2g})"
                     for m in worst) or "none testable"


def stack_sqrt_information(factors: Sequence[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """Fuse Gaussian results given as square-root information ``(R_k, z_k)``, natural units.

    A result with information ``Lambda_k = R_k^T R_k`` and ``Lambda_k D_k = R_k^T z_k`` combines with
    the others as ``Lambda = sum_k Lambda_k``, ``Lambda D = sum_k R_k^T z_k``; stacking the factors
    and one QR gives ``(R, z)`` with the same information without forming it (no squared condition
    number).
    """
    if not factors:
        raise ValueError("nothing to fuse")
    n = factors[0][0].shape[1]
    for R, z in factors:
        if R.shape[1] != n or z.shape != (R.shape[0],):
            raise ValueError("square-root information factors of different sizes")
    M = np.vstack([np.column_stack([R, z]) for R, z in factors])
    Rz = np.asarray(np.linalg.qr(M, mode="r"))
    out = np.zeros((n, n + 1))
    out[: min(n, Rz.shape[0])] = Rz[:n]
    return np.triu(out[:, :n]), out[:, n].copy()

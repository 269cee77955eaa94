"""Several flights in one estimate: stacked reductions, consistency between flights, fusion.

Notes
-----
Flight k (k = 1..K) reduces its column-scaled regression once (:mod:`casep.analysis.linalg`):
with ``Z_k = S_k diag(c_k)^-1`` and ``[Z_k | y_k] = Q_k [[R_k, q_k], [0, rho_k]]``::

    ||y_k - S_k D||^2 = ||q_k - R_k diag(c_k) D||^2 + rho_k^2

The coefficients are shared by all flights except the per-flight ones (``per_flight=True`` in the
model: time offset, initial velocity error, initial misalignment), which each flight has
separately. The joint parameter vector is ``theta = [D_shared, D_pf(1), ..., D_pf(K)]`` and flight
k's coefficients are ``D_k = P_k theta`` (a column selection). Each flight is weighted by its
noise variance, so the joint weighted least squares is::

    min_theta  sum_k ||y_k - S_k P_k theta||^2 / sigma_k^2
             = || A theta - b ||^2 + sum_k rho_k^2 / sigma_k^2,
    A = [R_k diag(c_k) P_k / sigma_k]_k  (K n x p),   b = [q_k / sigma_k]_k

``A`` has K n rows whatever the flights' lengths: the 3 N_k rows are never stacked. It is reduced
again (column-scaled QR) into the ``ReducedSystem`` every solver takes, with ``m = sum_k 3 N_k``
and the whitened residual ``sum_k rho_k^2 / sigma_k^2`` carried along, so the joint noise scale is
1 (the sigma_k are the weights).

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

from casep.analysis.linalg import ReducedSystem, analyze_rank, least_squares_rss, reduce_qr

__all__ = ["JointLayout", "joint_reduction", "flight_rss", "coefficient_consistency", "overall_consistency",
           "stack_sqrt_information"]


@dataclass(frozen=True)
class JointLayout:
    """Where each flight's coefficients sit in the joint parameter vector.

    Parameters
    ----------
    names : sequence of str
        The model's coefficient names, model order.
    per_flight : (n,) bool array_like
        Coefficients each flight has separately.
    labels : sequence of str
        One label per flight (file name); per-flight names become ``name[label]``.
    """

    names: tuple[str, ...]
    per_flight: np.ndarray
    labels: tuple[str, ...]

    def __post_init__(self) -> None:
        pf = np.asarray(self.per_flight, dtype=bool)
        if pf.shape != (len(self.names),):
            raise ValueError(f"`per_flight` has {pf.size} entries but the model has {len(self.names)} coefficients")
        if not self.labels:
            raise ValueError("no flight")
        if len(set(self.labels)) != len(self.labels):
            raise ValueError(f"flight labels repeat: {list(self.labels)}")
        object.__setattr__(self, "per_flight", pf)

    @property
    def n_flights(self) -> int:
        return len(self.labels)

    @property
    def shared(self) -> np.ndarray:
        """Model indices of the shared coefficients."""
        return np.flatnonzero(~self.per_flight)

    @property
    def n_params(self) -> int:
        """Length of theta: shared + K x per-flight."""
        return int(self.shared.size + self.n_flights * self.per_flight.sum())

    def columns(self, k: int) -> np.ndarray:
        """``P_k`` as an index array: model coefficient j of flight k -> its column of theta."""
        pf = np.flatnonzero(self.per_flight)
        cols = np.empty(len(self.names), dtype=int)
        cols[self.shared] = np.arange(self.shared.size)
        cols[pf] = self.shared.size + k * pf.size + np.arange(pf.size)
        return cols

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Names of theta: shared names, then ``name[label]`` per flight."""
        pf = [self.names[j] for j in np.flatnonzero(self.per_flight)]
        return tuple(self.names[j] for j in self.shared) + tuple(
            f"{name}[{label}]" for label in self.labels for name in pf)

    def expand(self, values: Sequence, k: int | None = None) -> list:
        """Model-order per-coefficient values (units, scales) repeated into theta order."""
        out: list = [None] * self.n_params
        for kk in range(self.n_flights) if k is None else (k,):
            for j, col in enumerate(self.columns(kk)):
                out[col] = values[j]
        return out


def flight_rss(red: ReducedSystem, rcond: float | None = None) -> tuple[float, int]:
    """A flight's own least-squares residual sum of squares and rank.

    ``RSS = rho^2 + ||U_{r+}^T q||^2`` (the part of q outside the range of R).
    """
    ra = analyze_rank(red, rcond)
    return least_squares_rss(red, ra), ra.rank


def joint_reduction(reds: Sequence[ReducedSystem], sigmas: Sequence[float], layout: JointLayout) -> ReducedSystem:
    """The weighted stacked least squares of several flights as one reduced system over theta.

    Parameters
    ----------
    reds : sequence of ReducedSystem
        Each flight's reduction (same model, model order).
    sigmas : sequence of float
        Each flight's noise std, m/s (its weight is 1 / sigma^2).
    layout : JointLayout

    Returns
    -------
    ReducedSystem
        Of ``A theta = b`` (see the module notes), with ``m`` the total number of rows of the
        flights and ``rho2`` the whitened residual outside every flight's range, so that
        ``||b - A theta||^2 + rho2 = sum_k ||y_k - S_k P_k theta||^2 / sigma_k^2``.
    """
    if len(reds) != layout.n_flights or len(sigmas) != layout.n_flights:
        raise ValueError(f"{len(reds)} reductions and {len(sigmas)} sigmas for {layout.n_flights} flights")
    n = len(layout.names)
    p = layout.n_params
    A = np.zeros((layout.n_flights * n, p))
    b = np.zeros(layout.n_flights * n)
    rho2 = 0.0
    for k, (red, sig) in enumerate(zip(reds, sigmas)):
        if red.n != n:
            raise ValueError(f"flight {layout.labels[k]}: {red.n} coefficients, the model has {n}")
        if not (np.isfinite(sig) and sig > 0):
            raise ValueError(f"flight {layout.labels[k]}: sigma must be finite and > 0, got {sig}")
        rows = slice(k * n, (k + 1) * n)
        A[rows, layout.columns(k)] = red.R * red.scale / sig  # R_k diag(c_k) P_k / sigma_k
        b[rows] = red.qty / sig  # q_k / sigma_k
        rho2 += red.rho2 / sig**2  # rho_k^2 / sigma_k^2
    joint = reduce_qr(A, b)
    return ReducedSystem(R=joint.R, qty=joint.qty, rho2=joint.rho2 + rho2, scale=joint.scale,
                         m=int(sum(r.m for r in reds)))


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
    Rz = np.linalg.qr(M, mode="r")
    out = np.zeros((n, n + 1))
    out[: min(n, Rz.shape[0])] = Rz[:n]
    return np.triu(out[:, :n]), out[:, n].copy()

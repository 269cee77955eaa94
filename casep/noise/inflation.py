"""The std of a least-squares fit whose noise model was estimated (REML): the noise parameters' uncertainty.

Least squares on rows whitened by a fitted noise model reports ``Phi(theta_hat) = (X^T Sigma(theta_hat)^-1 X)^-1``,
the covariance it would have if the noise parameters ``theta`` (per axis: correlation time, white share, variance)
were known. They are estimated from the same rows; on a short record (a hundred samples per axis, a few
correlation times) that uncertainty is not small, and the plug-in std are too small in two ways: the estimate
varies with ``theta_hat`` beside the noise (Kackar and Harville 1984), and ``Phi(theta_hat)`` itself is biased
low (Harville and Jeske 1992). Kenward and Roger (1997, 2009) correct both to ``O(1/N)``::

    Phi_A = Phi + 2 Phi [sum_ij W_ij (Q_ij - P_i Phi P_j - R_ij / 4)] Phi
    P_i = X^T (d Sigma^-1 / d theta_i) X,    Q_ij = X^T (d Sigma^-1 / d theta_i) Sigma (d Sigma^-1 / d theta_j) X,
    R_ij = X^T Sigma^-1 (d^2 Sigma / d theta_i d theta_j) Sigma^-1 X,    W = I(theta)^-1  (REML information)

Written here as the two parts it is made of, each computed where it is cheap and exact::

    Phi_A = Phi(theta_hat) + Lambda - 1/2 sum_ij W_ij d^2 Phi / d theta_i d theta_j,
    Lambda = Phi [sum_ij W_ij (Q_ij - P_i Phi P_j)] Phi

(``d^2 Phi = Phi P_j Phi P_i Phi + Phi P_i Phi P_j Phi - Phi (Q_ij + Q_ji - R_ij) Phi``, so the sum is Kenward and
Roger's). ``Lambda`` is the covariance the estimate gains from ``theta_hat`` (``d beta_hat / d theta_i = Phi
X^T (d Sigma^-1 / d theta_i) (y - X beta_hat)``, whose covariance is ``Phi (Q_ij - P_i Phi P_j) Phi``); the last
term is minus the bias of ``Phi(theta_hat)`` (its second-order Taylor term, ``theta_hat`` unbiased to first order).

* ``Phi``, ``P_i`` and the second derivatives of ``Phi``: central differences of the REML Gram matrices
  (:class:`casep.noise.fit.Reml`: one whitening per trial, ``(p + 1)``-square matrices).
* ``Q_ij`` (zero between axes, whose noises are independent): ``G_i = (d Sigma_a^-1 / d theta_i) X_a`` by central
  differences of ``W^T W X_a`` (the whitening and its transpose, :mod:`casep.noise.model`) and ``Sigma_a G_j`` by
  the exponential kernel's forward and backward recursions
  (:func:`casep.noise.known.axis_covariance_times`): O(N p) per parameter, never an
  N x N matrix.
* ``W``: twice the inverse Hessian of ``-2 l_R`` (the observed REML information) by central differences, the
  variances not profiled.

The std then carry the t variance. ``Phi_A`` is the estimate's variance, but ``Phi_A(theta_hat)`` itself scatters:
``z = (beta_hat - beta) / sqrt(Phi_A(theta_hat))`` is Student's t with ``nu`` degrees of freedom (Kenward and
Roger's Satterthwaite step, per coefficient ``k``)::

    nu_k = 2 (Phi_A)_kk^2 / Var(Phi_kk(theta_hat)),    Var = g^T W g,    g_i = d Phi_kk / d theta_i = -(Phi P_i Phi)_kk

whose variance is ``nu / (nu - 2)``, not 1. casep's std mean that ``z`` has unit variance (RMS z 1, its Monte Carlo
checks), so the covariance is ``Phi_A nu / (nu - 2)`` with ``nu`` the median of the coefficients' ``nu_k`` (held at
:data:`MIN_DOF` or more): one factor, so that the covariance keeps its correlations (a factor per coefficient would
break the near-dependencies of an ill-conditioned fit, whose combinations are determined far better than its
coefficients). The 1.96-std interval is then
``t_nu``'s 95 % interval to within a percent for ``nu >= 6`` (``1.96 sqrt(nu / (nu - 2))`` against its quantile).
Measured (``tests/noise/test_noise_inflation.py``, 60 samples per axis, nine parameters): plug-in RMS z 1.28,
coverage 0.87; ``Phi_A`` alone 1.09-1.16, 0.90-0.92; with the t variance 0.98, 0.944.

Parametrisation (the bias term depends on it): ``ln tau``, the white share's logit and the variances ``v_a``
themselves (REML variance estimates are unbiased, so a covariance linear in them has no bias term of its own).
A parameter at an end of its search interval (a correlation time at the sample spacing or the record's length,
a white share at 0 or 1) is held (not a free parameter at the optimum). Directions of ``-2 l_R`` without positive
curvature carry no information and are left out of ``W``. The correction never narrows a std: the corrected
covariance is at least the plug-in one (its negative part, in the plug-in's metric, dropped).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from casep.noise.fit import SHARE_LOGIT, Reml, estimable_basis, tau_search_bounds
from casep.noise.known import axis_covariance_times
from casep.noise.model import NoiseModel, _series_transpose, whiten_series

__all__ = ["Inflation", "parameter_inflation", "t_variance_factor", "STEP", "MIN_DOF"]

#: Central-difference step in the parameters (ln tau, logit w; relative in the variances).
STEP = 2e-3
#: The fewest degrees of freedom a coefficient's std is given (``nu / (nu - 2)`` is 2 there; below it the
#: t variance grows without bound, and a record so short is said by its other checks).
MIN_DOF = 4.0
#: A parameter within this distance of an end of its search interval (ln tau, logit w) is held.
_AT_EDGE = 0.05


@dataclass(frozen=True)
class Inflation:
    """The correction of a REML-whitened least-squares covariance (module notes).

    Attributes
    ----------
    basis : (n, p) ndarray
        Natural-unit coefficients from the estimable basis (:func:`casep.noise.fit.estimable_basis`).
    phi : (p, p) ndarray
        ``Phi(theta_hat)`` in the basis (the plug-in covariance).
    delta : (p, p) ndarray
        ``Phi_A - Phi`` in the basis.
    parameters : list of str
        The noise parameters whose uncertainty it carries.
    info : dict
        ``std_factor_median``, ``std_factor_max`` (corrected over plug-in std of the coefficients), the
        number of informative directions of the REML information, the parameters.
    """

    basis: np.ndarray
    phi: np.ndarray
    delta: np.ndarray
    parameters: list[str]
    info: dict = field(default_factory=dict)
    dof: np.ndarray | None = None

    def natural(self) -> np.ndarray:
        """``Phi_A - Phi`` in natural units, (n, n) (without the t variance: :meth:`adjusted`)."""
        return self.basis @ self.delta @ self.basis.T

    @property
    def t_factor(self) -> float:
        """The t variance ``nu / (nu - 2)`` at the median of the coefficients' degrees of freedom (module notes)."""
        fin = self.dof[np.isfinite(self.dof)] if self.dof is not None else np.zeros(0)
        return float(t_variance_factor(np.median(fin))) if fin.size else 1.0

    def adjusted(self, covariance: np.ndarray) -> np.ndarray:
        """The covariance a least-squares fit reported (``Phi`` in natural units, the solver's own numbers) with the
        noise parameters' uncertainty: ``t_factor (covariance + B delta B^T)``."""
        return self.t_factor * (np.asarray(covariance, dtype=float) + self.natural())


def t_variance_factor(dof: np.ndarray | float) -> np.ndarray:
    """``nu / (nu - 2)``, the variance of Student's t with `dof` degrees of freedom, with `dof` held at
    :data:`MIN_DOF` or more (1 where infinite)."""
    nu = np.maximum(np.asarray(dof, dtype=float), MIN_DOF)
    return np.where(np.isfinite(nu), nu / (nu - 2.0), 1.0)


class _Point:
    """The noise parameters as a vector (module notes' parametrisation) and back."""

    def __init__(self, noise: NoiseModel, sigma2: float, free_scales: bool, lo: float, hi: float) -> None:
        self.taus = list(noise.tau)
        self.shares = list(noise.share)
        self.v = [sigma2 * s * s for s in noise.scale]
        self.names: list[str] = []
        self.where: list[tuple[str, int]] = []
        x0: list[float] = []
        given = noise.rule == "given"
        for j, a in enumerate("xyz"):
            tau = self.taus[j]
            if tau is not None and not given and lo + _AT_EDGE < np.log(tau) < hi - _AT_EDGE:
                self.names.append(f"tau_{a}")
                self.where.append(("tau", j))
                x0.append(float(np.log(tau)))
            w = self.shares[j]
            if tau is not None and w > 0:
                lw = float(np.log(w / (1.0 - w)))
                if SHARE_LOGIT[0] + _AT_EDGE < lw < SHARE_LOGIT[1] - _AT_EDGE:
                    self.names.append(f"white_share_{a}")
                    self.where.append(("share", j))
                    x0.append(lw)
        if free_scales:
            for j, a in enumerate("xyz"):
                self.names.append(f"variance_{a}")
                self.where.append(("v", j))
                x0.append(self.v[j])
        else:
            self.names.append("variance")
            self.where.append(("v", -1))
            x0.append(self.v[0])
        self.x0 = np.array(x0)
        self.ratio = np.array(self.v) / self.v[0]

    def steps(self) -> np.ndarray:
        return np.array([STEP * abs(x) if kind == "v" else STEP for (kind, _), x in zip(self.where, self.x0)])

    def unpack(self, x: np.ndarray) -> tuple[list, list, list]:
        taus, shares, v = list(self.taus), list(self.shares), list(self.v)
        for (kind, j), val in zip(self.where, x):
            if kind == "tau":
                taus[j] = float(np.exp(val))
            elif kind == "share":
                shares[j] = float(1.0 / (1.0 + np.exp(-val)))
            elif j >= 0:
                v[j] = float(val)
            else:
                v = [float(val * r) for r in self.ratio]
        return taus, shares, v


def _grams(reml: Reml, taus, shares) -> tuple[np.ndarray, list[float]]:
    gs = [reml.gram(j, taus[j], shares[j]) for j in range(3)]
    return np.stack([g[0] for g in gs]), [g[1] for g in gs]


def _neg2(reml: Reml, pt: _Point, x: np.ndarray) -> float:
    """-2 l_R (variances not profiled) at the parameter vector `x`."""
    taus, shares, v = pt.unpack(x)
    if min(v) <= 0:
        return np.inf
    Ms, lds = _grams(reml, taus, shares)
    G = sum(Ms[j] / v[j] for j in range(3))
    try:
        L = np.linalg.cholesky(G)
    except np.linalg.LinAlgError:
        return np.inf
    p = reml.p
    return float(sum(reml.N * np.log(v[j]) + lds[j] for j in range(3))
                 + 2.0 * np.sum(np.log(np.abs(np.diag(L)[:p]))) + L[p, p] ** 2)


def _information(reml: Reml, pt: _Point, h: np.ndarray) -> np.ndarray:
    """Half the Hessian of -2 l_R at the estimate (the observed REML information), central differences."""
    k = pt.x0.size
    E = np.diag(h)
    f0 = _neg2(reml, pt, pt.x0)
    H = np.empty((k, k))
    for i in range(k):
        H[i, i] = (_neg2(reml, pt, pt.x0 + E[i]) - 2.0 * f0 + _neg2(reml, pt, pt.x0 - E[i])) / h[i] ** 2
        for j in range(i):
            H[i, j] = H[j, i] = (_neg2(reml, pt, pt.x0 + E[i] + E[j]) - _neg2(reml, pt, pt.x0 + E[i] - E[j])
                                 - _neg2(reml, pt, pt.x0 - E[i] + E[j]) + _neg2(reml, pt, pt.x0 - E[i] - E[j])) \
                / (4.0 * h[i] * h[j])
    return 0.5 * H


def _precision(reml: Reml, pt: _Point, x: np.ndarray) -> np.ndarray:
    """``X^T Sigma^-1 X`` in the basis at the parameter vector `x`."""
    taus, shares, v = pt.unpack(x)
    Ms = _grams(reml, taus, shares)[0]
    p = reml.p
    return sum(Ms[j, :p, :p] / v[j] for j in range(3))


def _weighted_rows(reml: Reml, j: int, tau: float | None, share: float) -> np.ndarray:
    """``W^T W X_a`` of axis j at unit variance (the rows times the inverse correlation)."""
    X = reml.Z[j][:, :-1]
    U = whiten_series(X, reml.t, tau, share)[0]
    return _series_transpose(U, reml.t, tau, share)


def _g(reml: Reml, pt: _Point, i: int, h: float) -> tuple[int, np.ndarray]:
    """(axis, ``G_i = (d Sigma_a^-1 / d theta_i) X_a``) of parameter i (module notes); axis -1: all three."""
    kind, j = pt.where[i]
    taus, shares, v = pt.unpack(pt.x0)
    if kind == "v":
        axes = range(3) if j < 0 else [j]
        # Sigma_a^-1 = W^T W / v_a: d / d v_a = -W^T W / v_a^2 (common variance: v_a = r_a v, d v_a / d v = r_a)
        return j, np.stack([-_weighted_rows(reml, a, taus[a], shares[a]) / v[a] ** 2
                            * (pt.ratio[a] if j < 0 else 1.0) for a in axes])
    up, dn = pt.x0.copy(), pt.x0.copy()
    up[i] += h
    dn[i] -= h
    tu, su, _ = pt.unpack(up)
    td, sd, _ = pt.unpack(dn)
    G = (_weighted_rows(reml, j, tu[j], su[j]) - _weighted_rows(reml, j, td[j], sd[j])) / (2.0 * h * v[j])
    return j, G[None]


def _q(reml: Reml, pt: _Point, gs: list[tuple[int, np.ndarray]], i: int, k: int) -> np.ndarray:
    """``Q_ik = G_i^T Sigma G_k`` (zero between different axes)."""
    (ai, Gi), (ak, Gk) = gs[i], gs[k]
    taus, shares, v = pt.unpack(pt.x0)
    p = reml.p
    out = np.zeros((p, p))
    axes_i = list(range(3)) if ai < 0 else [ai]
    axes_k = list(range(3)) if ak < 0 else [ak]
    for a in set(axes_i) & set(axes_k):
        gi = Gi[axes_i.index(a)]
        gk = Gk[axes_k.index(a)]
        # Sigma_a G_k: unit-variance correlation (1 - w) exp(-|dt| / tau) + w I (white axis: I), times v_a
        c, d = (1.0 - shares[a], shares[a]) if taus[a] is not None else (0.0, 1.0)
        out += gi.T @ (v[a] * axis_covariance_times(gk, reml.t, taus[a], c, d))
    return out


def parameter_inflation(problem, noise: NoiseModel, *, raw: bool = False) -> Inflation | None:
    """The correction of the least-squares covariance of `problem`'s rows whitened by the REML noise model `noise`
    for the noise parameters' uncertainty (module notes); None when nothing was estimated (white noise of one std,
    a model not from REML, rows without times, no free parameter at the estimate).

    Parameters
    ----------
    problem : Problem
        The rows the noise model was fitted on (samples kept), in time order with their times.
    noise : NoiseModel
        Its REML fit (with ``sigma``).
    raw : bool
        Return Kenward and Roger's correction as it is (negative parts kept, no degrees of freedom), with
        ``info["lambda"]`` and ``info["bias"]`` its two parts: for tests.
    """
    if noise.rule not in ("reml", "given") or problem.t is None or problem.y is None or noise.sigma is None \
            or not np.isfinite(noise.sigma) or noise.sigma <= 0:
        return None
    if all(t is None for t in noise.tau) and all(s == 1.0 for s in noise.scale):
        return None  # white noise of one std: nothing but sigma, which the std's own estimate carries
    basis = estimable_basis(problem)
    reml = Reml(problem, basis)
    p = reml.p
    if p == 0:
        return None
    lo, hi = tau_search_bounds(problem.t)
    free_scales = noise.kind != "auto" or any(s != 1.0 for s in noise.scale)
    pt = _Point(noise, float(noise.sigma) ** 2, free_scales, lo, hi)
    h = pt.steps()
    info = _information(reml, pt, h)
    if not np.all(np.isfinite(info)):
        return None
    lam, U = np.linalg.eigh(0.5 * (info + info.T))
    keep = lam > 1e-10 * max(float(lam.max()), 1e-300)
    W = (U[:, keep] / lam[keep]) @ U[:, keep].T  # W = I^-1 over the informative directions
    A = _precision(reml, pt, pt.x0)
    Phi = np.linalg.inv(A)
    k = pt.x0.size
    E = np.diag(h)
    Pd = [(_precision(reml, pt, pt.x0 + E[i]) - _precision(reml, pt, pt.x0 - E[i])) / (2.0 * h[i]) for i in range(k)]
    gs = [_g(reml, pt, i, h[i]) for i in range(k)]
    inner = np.zeros((p, p))
    bias = np.zeros((p, p))
    phi_at = lambda x: np.linalg.inv(_precision(reml, pt, x))  # noqa: E731
    for i in range(k):
        for j in range(i + 1):
            if W[i, j] == 0.0:
                continue
            term = _q(reml, pt, gs, i, j) - Pd[i] @ Phi @ Pd[j]
            if i == j:
                d2 = (phi_at(pt.x0 + E[i]) - 2.0 * Phi + phi_at(pt.x0 - E[i])) / h[i] ** 2
                inner += W[i, i] * term
                bias += W[i, i] * d2
            else:
                d2 = (phi_at(pt.x0 + E[i] + E[j]) - phi_at(pt.x0 + E[i] - E[j]) - phi_at(pt.x0 - E[i] + E[j])
                      + phi_at(pt.x0 - E[i] - E[j])) / (4.0 * h[i] * h[j])
                inner += W[i, j] * (term + term.T)
                bias += 2.0 * W[i, j] * d2
    delta = Phi @ inner @ Phi - 0.5 * bias
    delta = 0.5 * (delta + delta.T)
    if raw:
        return Inflation(basis, Phi, delta, list(pt.names),
                         {"lambda": Phi @ inner @ Phi, "bias": -0.5 * bias})
    # never narrower than the plug-in: the negative part of delta in Phi's metric dropped
    Lc = np.linalg.cholesky(Phi)
    Li = np.linalg.inv(Lc)
    d, V = np.linalg.eigh(Li @ delta @ Li.T)
    delta = Lc @ ((V * np.clip(d, 0.0, None)) @ V.T) @ Lc.T
    dof = _satterthwaite(basis, Phi, delta, Pd, W)
    inf = Inflation(basis, Phi, delta, list(pt.names), dof=dof)
    plug = np.diag(basis @ Phi @ basis.T)
    ok = plug > 0
    rel = np.sqrt(np.diag(inf.adjusted(basis @ Phi @ basis.T))[ok] / plug[ok]) if ok.any() else np.ones(1)
    fin = dof[ok & np.isfinite(dof)]
    inf.info.update({"std_factor_median": float(np.median(rel)), "std_factor_max": float(np.max(rel)),
                     "dof_min": float(fin.min()) if fin.size else None,
                     "dof_median": float(np.median(fin)) if fin.size else None, "t_factor": inf.t_factor,
                     "information_directions": int(keep.sum()), "parameters": list(pt.names)})
    return inf


def _satterthwaite(basis: np.ndarray, Phi: np.ndarray, delta: np.ndarray, Pd: list[np.ndarray],
                   W: np.ndarray) -> np.ndarray:
    """Each natural coefficient's degrees of freedom ``nu_k = 2 (Phi_A)_kk^2 / Var((Phi(theta_hat))_kk)``,
    ``Var = g^T W g`` with ``g_i = d (Phi)_kk / d theta_i = -(B Phi P_i Phi B^T)_kk`` (Kenward and Roger's
    Satterthwaite step); inf where the plug-in does not depend on the parameters."""
    A = basis @ Phi
    g = np.stack([-np.einsum("kp,pq,kq->k", A, P, A) for P in Pd])  # (parameters, n)
    var = np.einsum("ik,ij,jk->k", g, W, g)
    adj = np.einsum("kp,pq,kq->k", basis, Phi + delta, basis)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(var > 0, 2.0 * adj**2 / np.where(var > 0, var, 1.0), np.inf)

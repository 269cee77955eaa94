"""A slow sensor drift in the std of a hand-turned calibration, estimated from the session itself.

A consumer MEMS bias wanders: over a session of minutes it moves like a first-order Gauss-Markov
process ``d(t)`` of stationary variance ``sigma_d^2`` and correlation time ``tau``. The pose means
then carry, besides their white noise, errors correlated across poses by their time separation:

    Cov(e_k, e_l) = v0 (W_kl + rho D_kl(tau)),     D_kl(tau) = S_kl exp(-|t_k - t_l| / tau)

(``W`` the white noise's shape, ``S`` how the drift enters each row: 1 for a gyro pose mean,
``w_k w_l a_k . a_l`` for the accelerometer's misfit rows, ``a_k`` the row's gradient in the
reading). A least-squares estimate ``x = x_true + A e`` then has ``C = A Cov(e) A^T``, of which
``v0 (A W A^T)`` (the white noise alone) is the usual ``s^2 (J^T J)^-1``.

``(v0, rho, tau)`` are not known. The rows' misfit (or the series' scatter about its mean) is
projected on the space the fit cannot absorb (``Q``, an orthonormal basis of the complement of the
fitted columns ``X``), where its likelihood does not depend on the coefficients (REML):

    l(rho, tau) = -1/2 (n log v0 + log det Q^T M Q),   v0 = y^T (Q^T M Q)^-1 y / n,   y = Q^T r

(``M = W + rho D``, ``n`` = rows - columns; several series share ``rho, tau`` and each has its
``v0``). For each ``tau`` of a grid (log-spaced from the median pose length to the session's length) ``rho`` is
the best of a grid (0, then 1e-2..1e3 log-spaced: the profile likelihood); ``C`` is the average over
``tau`` of those points' ``A Cov(e) A^T``, each weighted by ``exp(l)`` (flat prior in log ``tau``). White
noise alone puts ``rho`` at or near 0 and gives the usual covariance; a drift the misfit shows widens
it, most for the biases, whose error is the drift's common part over the session.

What a session cannot show: a drift slower than the session (``tau`` near or beyond its length) is, for
the most part, a bias the session cannot tell from the constant one; its scatter about the session's
mean is small while its common part is up to ``sigma_d``. Seeded simulation (30 poses, ~125 s; drift std
2e-3 m/s^2 (0.2 mg) and 3e-4 rad/s (62 deg/h), the sizes the MPU-9150 sessions show,
``benchmarks/allan_real_sessions.py``; most of a pose mean's variance; 60 draws per line, two seed
sets, ``tests/calibration/test_drift.py``): the biases' RMS z is 0.9-1.0 (accelerometer) and 0.84-0.93 (gyro)
with white noise alone, 1.0-1.15 and 0.7-1.0 at ``tau`` 10-20 s, 1.2-1.3 and 0.8-1.1 at 30 s, ~1.6 at
60 s and ~1.8 at 100 s; the scales and misalignments' 0.97-1.07 throughout (the former std, white noise
alone: the biases' 1.5-2.8 at ``tau`` 20-30 s).
:func:`drift_note` says so with the numbers when the misfit shows a slow drift: most of a pose mean's
variance, most weight at ``tau`` >= a quarter of the session, and a likelihood ratio against white noise
alone, ``-2 ln Lambda`` at the best ``(rho, tau)``, above :data:`casep.noise.model.AUTO_LR` (casep's rule
for a richer noise kind; ``rho`` on its boundary under white noise). The std itself is always the
average (a drift too small to be told from white noise still widens it): a test would make it the
white-noise std whenever the test misses a real drift (seeded simulation: the biases' RMS z 1.25-1.8
instead of 0.9-1.2).

What the session cannot show needs a prior: the sensor's drift (a datasheet's bias instability, or a long
static recording's Allan deviation) as a Gauss-Markov std and ``tau``, :func:`fit_drift_prior` (``casep
calibrate --acc-drift / --gyr-drift``): ``C = A (v0 W + sigma_d^2 D(tau)) A^T``, ``v0`` by REML with the drift
known. Seeded simulation as above, the true drift as prior: the biases' RMS z 0.97-1.02, the accelerometer's
scales and misalignments' 1.02-1.06, at ``tau`` 5 to 1000 s (200 draws each); without it 1.6-2.0 at 100 s,
2.9-3.5 at 300 s. Without a prior, :func:`slow_bound` gives the largest drift of correlation time the session's
length the rows allow (95 %) and the covariance with it: the report states it beside the bias std.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from casep.noise.model import AUTO_LR

__all__ = ["DriftFit", "fit_drift", "fit_drift_prior", "drift_grid", "drift_note", "prior_note", "null_basis",
           "RATIOS", "GM_ALLAN_PEAK"]

#: The peak of a first-order Gauss-Markov process's Allan deviation, as a fraction of its std (at an averaging
#: time of about 1.89 tau): a datasheet's bias instability B taken as that peak is a drift of std B / GM_ALLAN_PEAK.
GM_ALLAN_PEAK = 0.6198

#: The drift-to-white variance ratios of the grid (0: white noise alone).
RATIOS = np.r_[0.0, np.geomspace(1e-2, 1e3, 16)]

#: Correlation times per grid (log-spaced between the median pose length and the session's length).
N_TAU = 10

#: A drift share of a pose mean's variance above which :func:`drift_note` speaks (with most weight at a slow ``tau``).
DRIFT_SHARE = 0.5
#: A correlation time above this fraction of the session is slow: the std holds below it (module notes).
SLOW = 0.25


@dataclass(frozen=True)
class DriftFit:
    """The drift the rows show: per ``tau`` of the grid its weight, best ``rho`` and ``v0`` per series; ``C``;
    ``lr_stat``: -2 ln Lambda of the best drift against white noise; ``bound``: the largest drift at the slowest
    ``tau`` of the grid the rows allow (:func:`slow_bound`).

    ``covariance``: (k, q, q), one per series.
    """

    weights: np.ndarray
    ratios: np.ndarray
    v0: np.ndarray
    taus: np.ndarray
    covariance: np.ndarray
    lr_stat: float = 0.0
    loglik: float = -np.inf
    prior: np.ndarray | None = None
    bound: dict | None = None

    @property
    def drift_share(self) -> float:
        """The drift's share of a pose mean's variance, ``rho / (1 + rho)`` averaged over ``tau`` (0: white)."""
        if self.prior is not None:
            s2 = self.prior ** 2
            return float(np.mean(s2 / (s2 + self.v0[0])))
        return float(np.sum(self.weights * self.ratios / (1.0 + self.ratios)))

    @property
    def shown(self) -> bool:
        """Whether the rows show a drift: ``-2 ln Lambda`` against white noise above :data:`AUTO_LR`."""
        return self.lr_stat > AUTO_LR

    @property
    def sigma_d(self) -> np.ndarray:
        """The drift's stationary std per series, ``sqrt(rho v0)`` averaged over ``tau`` (the row's unit);
        with a prior, the prior's."""
        if self.prior is not None:
            return self.prior
        return np.sqrt(np.sum(self.weights[:, None] * self.ratios[:, None] * self.v0, axis=0))


def null_basis(X: np.ndarray, m: int) -> np.ndarray:
    """An orthonormal basis (m, m - rank X) of the complement of the columns of `X` (column-scaled)."""
    d = np.linalg.norm(X, axis=0)
    d[d == 0] = 1.0
    U, s, _ = np.linalg.svd(X / d, full_matrices=True)
    rank = int(np.sum(s > s[0] * m * np.finfo(float).eps)) if s.size and s[0] > 0 else 0
    return U[:, rank:]


def drift_grid(t: np.ndarray, pose_s: np.ndarray) -> np.ndarray:
    """Correlation times (s) of the grid: N_TAU log-spaced from the median pose length `pose_s` to the span of `t`."""
    lo = max(float(np.median(pose_s)), 1e-3)
    hi = max(float(np.ptp(t)), 2.0 * lo)
    return np.geomspace(lo, hi, N_TAU)


def fit_drift(r: np.ndarray, X: np.ndarray, W: np.ndarray, S: np.ndarray, t: np.ndarray, taus: np.ndarray,
              A: np.ndarray, scale: float) -> DriftFit:
    """The covariance ``A Cov(e) A^T`` with the drift the rows show (module notes).

    Parameters
    ----------
    r : (m,) or (m, k) ndarray
        The rows' misfit (or series); the k columns share ``rho, tau`` and have their own ``v0``.
    X : (m, p) ndarray
        The columns the fit absorbs (projected out).
    W, S : (m, m) ndarray
        The white noise's shape and the drift's row coupling (``D = S exp(-|dt| / tau)``).
    t : (m,) ndarray
        Each row's time, s.
    taus : (n_tau,) ndarray
        Correlation times of the grid, s.
    A : (q, m) ndarray
        The estimate's sensitivity to the rows: ``x - x_true = A e``.
    scale : float
        The data's magnitude: rows whose RMS is at its rounding level
        (:func:`casep.regression.problem.is_rounding_level`) are noise-free, taken as white.
    """
    from scipy.linalg import eigh

    from casep.regression.problem import is_rounding_level

    r = np.asarray(r, dtype=float)
    r = r[:, None] if r.ndim == 1 else r
    m, k = r.shape
    Q = null_basis(X, m)
    n = Q.shape[1]
    lag = np.abs(t[:, None] - t[None, :])
    Wq = Q.T @ W @ Q
    y = Q.T @ r
    logdet_w = float(np.linalg.slogdet(Wq)[1])
    AWA = A @ W @ A.T
    best = np.zeros(len(taus), dtype=int)
    ll0 = -np.inf
    ll, v0, ADA = np.full(len(taus), -np.inf), np.zeros((len(taus), k)), []
    for j, tau in enumerate(taus):
        D = S * np.exp(-lag / tau)
        ADA.append(A @ D @ A.T)
        # Q^T M Q = Wq + rho Dq, diagonal (I + rho lam) in the generalized eigenbasis V (V^T Wq V = I)
        lam, V = eigh(Q.T @ D @ Q, Wq)
        lam = np.clip(lam, 0.0, None)
        z2 = (V.T @ y) ** 2  # (n, k)
        f = 1.0 + RATIOS[:, None] * lam[None, :]  # (n_rho, n)
        v = (1.0 / f) @ z2 / n  # (n_rho, k): v0 profiled per ratio
        with np.errstate(divide="ignore"):
            lr = -0.5 * (n * np.sum(np.log(v), axis=1) + k * (logdet_w + np.sum(np.log(f), axis=1)))
        lr = np.where(np.all(v > 0, axis=1), lr, -np.inf)
        if is_rounding_level(float(np.sqrt(np.mean(r * r))), scale):
            lr[1:] = -np.inf  # no noise, no drift: the usual covariance
        ll0 = lr[0]  # rho = 0: the same at every tau
        best[j] = int(np.argmax(lr))
        ll[j], v0[j] = lr[best[j]], v[best[j]]
    bound = slow_bound(lr, v, taus[-1], AWA, ADA[-1])
    lr_stat = 2.0 * float(np.max(ll) - ll0) if np.isfinite(ll0) else 0.0
    if np.isfinite(ll).any():
        w = np.exp(ll - np.max(ll))
    else:  # a noise-free misfit: nothing to scale
        w = np.r_[1.0, np.zeros(len(taus) - 1)]
    w /= w.sum()
    rho = RATIOS[best]
    C = sum(w[j] * v0[j][:, None, None] * (AWA + rho[j] * ADA[j])[None] for j in range(len(taus)))
    return DriftFit(weights=w, ratios=rho, v0=v0, taus=np.asarray(taus, dtype=float), covariance=np.asarray(C),
                    lr_stat=lr_stat, loglik=float(np.max(ll)) - 0.5 * n * k, bound=bound)


#: Half the 95 % point of chi-square with one degree of freedom: a profile likelihood's 95 % interval.
HALF_CHI2_95 = 1.92


def slow_bound(lr: np.ndarray, v: np.ndarray, tau: float, AWA: np.ndarray, ADA: np.ndarray) -> dict | None:
    """The largest drift at correlation time `tau` (the session's length) the rows allow, and the covariance with it.

    ``rho`` of the grid whose profile likelihood `lr` (over RATIOS, ``v`` its ``v0`` per series) is within
    HALF_CHI2_95 of the best at that ``tau`` (a 95 % upper bound; ``at_grid_end``: the grid's last ratio, a
    lower bound of the bound). A drift this slow is, for the most part, a bias the session cannot tell from the
    constant one: this is what a session without a drift prior cannot exclude (:func:`drift_note`).
    """
    if not np.isfinite(lr).any():
        return None
    ok = np.flatnonzero(lr >= np.max(lr) - HALF_CHI2_95)
    i = int(ok[-1])
    rho = float(RATIOS[i])
    C = v[i][:, None, None] * (AWA + rho * ADA)[None]
    return {"tau_s": float(tau), "sigma_d": np.sqrt(rho * v[i]), "covariance": C, "at_grid_end": i == len(RATIOS) - 1}


def drift_note(fit: DriftFit, what: str, unit: str, session_s: float, bias_std: np.ndarray,
               bias_unit: str, prior_flag: str = "") -> str | None:
    """A sentence when the rows show a slow drift (share above DRIFT_SHARE, most weight at ``tau`` >= SLOW times the
    session): its size, and that it can move the biases by up to its std beyond `bias_std` (module notes), and the
    option `prior_flag` that gives the drift; else None."""
    slow = float(np.sum(fit.weights[fit.taus >= SLOW * session_s]))
    if fit.drift_share < DRIFT_SHARE or slow < 0.5 or not fit.shown:
        return None
    sd = ", ".join(f"{v:.3g}" for v in np.atleast_1d(fit.sigma_d))
    bs = ", ".join(f"{v:.3g}" for v in np.atleast_1d(bias_std))
    return (f"a slow drift in the {what}: {100 * fit.drift_share:.0f} % of a pose mean's variance is a drift of std "
            f"{sd} {unit} (white noise alone: 0 %), {100 * slow:.0f} % of its weight at a correlation time of "
            f"{SLOW * session_s:.0f} s or more. The bias std ({bs} {bias_unit}) holds for a drift correlation time "
            f"up to about a quarter of the session's {session_s:.0f} s; a slower drift is a bias the session cannot "
            "tell from the constant one and can move the bias by up to the drift's std. Use: "
            + (f"{prior_flag} (the sensor's drift, a datasheet's or from a long static recording's Allan deviation: "
               "the std then carries it), " if prior_flag else "")
            + "a longer session, or an initial static period long enough to measure the drift (Allan deviation)")


def fit_drift_prior(r: np.ndarray, X: np.ndarray, W: np.ndarray, S: np.ndarray, t: np.ndarray, A: np.ndarray,
                    sigma_d: np.ndarray, tau: float) -> DriftFit:
    """The covariance ``A (v0 W + sigma_d^2 D(tau)) A^T`` with the drift given (a datasheet's), ``v0`` by REML.

    What the session cannot show, a drift as slow as the session or slower, is then in the std: its common part
    over the poses moves the biases by up to ``sigma_d``. The white level ``v0`` of each series is the maximum of
    the projected rows' likelihood with the drift's part known (module notes; in the generalized eigenbasis of
    ``(Q^T D Q, Q^T W Q)`` the covariance is ``diag(v0 + sigma_d^2 lam_i)``):

        l(v0) = -1/2 sum_i [log(v0 + s2 lam_i) + z_i^2 / (v0 + s2 lam_i)] - 1/2 log det Q^T W Q

    Parameters
    ----------
    r, X, W, S, t, A :
        As :func:`fit_drift`.
    sigma_d : (k,) ndarray
        The drift's stationary std per series, in the rows' unit.
    tau : float
        Its correlation time, s.
    """
    from scipy.linalg import eigh
    from scipy.optimize import minimize_scalar

    r = np.asarray(r, dtype=float)
    r = r[:, None] if r.ndim == 1 else r
    m, k = r.shape
    s2 = np.broadcast_to(np.asarray(sigma_d, dtype=float) ** 2, (k,))
    Q = null_basis(X, m)
    D = S * np.exp(-np.abs(t[:, None] - t[None, :]) / tau)
    Wq = Q.T @ W @ Q
    lam, V = eigh(Q.T @ D @ Q, Wq)
    lam = np.clip(lam, 0.0, None)
    z2 = (V.T @ (Q.T @ r)) ** 2
    logdet_w = float(np.linalg.slogdet(Wq)[1])
    v0, ll = np.zeros(k), 0.0
    for j in range(k):
        def nll(u, j=j):
            c = np.exp(u) + s2[j] * lam
            return 0.5 * float(np.sum(np.log(c) + z2[:, j] / c))

        mean_z2 = max(float(np.mean(z2[:, j])), np.finfo(float).tiny)
        best = minimize_scalar(nll, bounds=(np.log(mean_z2) - 30.0, np.log(mean_z2) + 2.0), method="bounded",
                               options={"xatol": 1e-6})
        v0[j] = float(np.exp(best.x))
        ll -= float(best.fun) + 0.5 * logdet_w
    AWA, ADA = A @ W @ A.T, A @ D @ A.T
    C = np.array([v0[j] * AWA + s2[j] * ADA for j in range(k)])
    return DriftFit(weights=np.ones(1), ratios=np.zeros(1), v0=v0[None, :], taus=np.array([float(tau)]),
                    covariance=C, loglik=ll, prior=np.sqrt(s2))


def prior_note(prior: DriftFit, free: DriftFit, what: str, unit: str) -> str | None:
    """A sentence when the rows show more drift than the prior allows: the data's own drift (:func:`fit_drift`)
    beats the prior's by ``-2 ln Lambda`` above AUTO_LR and is larger; else None."""
    lr = 2.0 * (free.loglik - prior.loglik)
    if lr <= AUTO_LR or np.all(free.sigma_d <= prior.sigma_d):
        return None
    sd = ", ".join(f"{v:.3g}" for v in np.atleast_1d(free.sigma_d))
    ps = ", ".join(f"{v:.3g}" for v in np.atleast_1d(prior.sigma_d))
    return (f"more drift in the {what} than the prior allows: std {sd} {unit} at a correlation time near "
            f"{float(np.exp(np.sum(free.weights * np.log(free.taus)))):.3g} s against the prior's {ps} {unit} at "
            f"{float(prior.taus[0]):.3g} s (-2 ln Lambda {lr:.1f} > {AUTO_LR:g}): the std, from the prior, is too "
            "small. Use: a prior that matches the sensor, or none (the std then follows the session's own drift)")

"""Fitting the noise model of the rows (:class:`casep.analysis.noise.NoiseModel`) by REML.

REML
----
The restricted log-likelihood of ``theta = (tau_a, r_a)`` with ``sigma^2`` profiled out::

    -2 l_R(theta) = (m - p) ln RSS_w + sum_a [N ln r_a^2 + sum_k ln(1 - a_k^2)] + ln det(Z_w^T Z_w)

with ``Z = S V_p`` a basis of the estimable column space (rank ``p``, :mod:`casep.analysis.linalg`),
``RSS_w`` the whitened residual sum of squares and ``m = 3 N``. It is evaluated from one
``(p + 1) x (p + 1)`` triangle per axis (the QR of the axis' whitened ``[Z  dv]``): stacking the
three triangles scaled by ``1 / r_a`` and factoring again gives the log-determinant on its
diagonal and ``RSS_w`` in its last element. Each ``tau_a`` is found by a bounded scalar search in
``ln tau`` over ``[median(dt) / 5, duration]`` (coordinate-wise, twice over the axes), each ``r_a``
by the REML fixed point ``r_a^2 = RSS_a / (N - h_a)`` (``h_a`` the leverage of the axis' rows).

``auto`` fits Gauss-Markov noise on every axis, then keeps it on an axis only when the likelihood
ratio against white noise there, ``-2 ln Lambda_a``, exceeds :data:`AUTO_LR` (tau = 0 is on the
boundary, so the null distribution is ``(chi2_0 + chi2_1) / 2``; 5.41 is its 1 % point), and keeps
separate axis scales only when they beat one common scale by :data:`AUTO_LR_SCALE` (chi2_2 at 1 %).
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any, Callable, Sequence

import numpy as np

from casep.analysis.noise import (
    AUTO_LR,
    AUTO_LR_SCALE,
    NoiseModel,
    _coeffs,
    check_noise_kind,
    check_tau,
    whiten_axis,
)

__all__ = ["fit_noise", "tau_search_bounds", "with_kind", "Reml", "estimable_basis", "bounded_minimum"]


class Reml:
    """-2 l_R of per-axis (tau, scale) from per-axis Gram matrices (module notes).

    Axis ``a`` at ``tau_a`` contributes ``M_a = [Z_w y_w]^T [Z_w y_w]`` (unit scale, ``Z = S B``
    with orthonormal columns before whitening, so ``M_a`` is well conditioned); with the scales,
    ``G = sum_a M_a / r_a^2 = T^T T`` (Cholesky) gives ``ln det(Z_w^T Z_w) = 2 sum ln T_jj`` (j < p)
    and ``RSS_w = T_pp^2``.
    """

    def __init__(self, problem, basis: np.ndarray) -> None:
        self.pb = problem
        self.B = basis  # (n, p): natural-unit columns -> estimable basis Z = S B
        self.p = basis.shape[1]
        self.t = problem.t
        self.N = problem.n_samples
        self._cache: dict[tuple[int, float | None], tuple[np.ndarray, float]] = {}
        self._Z: list[np.ndarray] | None = None
        if problem._S is not None:  # rows kept: project once
            X = problem._S @ self.B  # (N, 3, p)
            self._Z = [np.concatenate([X[:, j, :], problem.y[:, j, None]], axis=1) for j in range(3)]

    def gram(self, j: int, tau: float | None) -> tuple[np.ndarray, float]:
        """(M_a, sum_k ln(1 - a_k^2)) of axis j at tau (unit scale), cached."""
        key = (j, None if tau is None else float(tau))
        if key not in self._cache:
            if self._Z is not None:
                W = _whiten_unit(self._Z[j], self.t, tau)
                M = W.T @ W
            else:
                M = np.zeros((self.p + 1, self.p + 1))
                prev = None
                for sl, S_b, y_b in self.pb.blocks():
                    X = np.concatenate([S_b[:, j, :] @ self.B, y_b[:, j, None]], axis=1)
                    tb = self.t[sl]
                    W = whiten_axis(X, tb, tau, 1.0, prev)
                    prev = (float(tb[-1]), X[-1].copy())
                    M += W.T @ W
            ld = 0.0
            if tau is not None:
                ld = float(np.sum(np.log(-np.expm1(-2.0 * np.diff(self.t) / tau))))  # sum ln(1 - a_k^2)
            self._cache[key] = (M, ld)
        return self._cache[key]

    def _factor(self, Ms: Sequence[np.ndarray], scales) -> np.ndarray | None:
        G = sum(Ms[j] / scales[j] ** 2 for j in range(3))
        try:
            return np.linalg.cholesky(G).T  # G = T^T T, T upper
        except np.linalg.LinAlgError:
            return None

    def evaluate(self, taus: Sequence[float | None], scales) -> tuple[float, np.ndarray | None]:
        """(-2 l_R, T) at the given taus and scales."""
        gs = [self.gram(j, taus[j]) for j in range(3)]
        T = self._factor([g[0] for g in gs], scales)
        if T is None:
            return np.inf, None
        d = np.abs(np.diag(T)[: self.p])
        rss = float(T[self.p, self.p] ** 2)
        m = 3 * self.N
        if not rss > 0 or np.any(d == 0):
            return np.inf, None
        val = ((m - self.p) * np.log(rss) + 2.0 * np.sum(np.log(d))
               + sum(self.N * np.log(scales[j] ** 2) + gs[j][1] for j in range(3)))
        return float(val), T

    def fit_scales(self, taus: Sequence[float | None], scales: Sequence[float] | None = None,
                   free: bool = True) -> tuple[float, tuple[float, float, float]]:
        """-2 l_R with the axis scales at their REML fixed point (or all 1 when not `free`)."""
        if not free:
            return self.evaluate(taus, (1.0, 1.0, 1.0))[0], (1.0, 1.0, 1.0)
        sc = np.ones(3) if scales is None else np.array(scales, dtype=float)
        Ms = [self.gram(j, taus[j])[0] for j in range(3)]
        p = self.p
        for _ in range(50):
            T = self._factor(Ms, sc)
            if T is None:
                return np.inf, (float(sc[0]), float(sc[1]), float(sc[2]))
            Tp = T[:p, :p]
            beta = np.linalg.solve(Tp, T[:p, p]) if p else np.zeros(0)
            v = np.concatenate([beta, [-1.0]])
            Ginv = np.linalg.inv(Tp.T @ Tp) if p else np.zeros((0, 0))  # (Z_w^T Z_w)^-1
            new = np.empty(3)
            for j in range(3):
                rss_j = max(float(v @ Ms[j] @ v), 0.0)  # ||[Z_a y_a] (beta, -1)||^2
                h = float(np.sum(Ms[j][:p, :p] * Ginv)) / sc[j] ** 2  # leverage of the axis' rows
                new[j] = np.sqrt(rss_j / max(self.N - h, 1.0))  # r_a^2 = RSS_a / (N - h_a)
            if not np.all(new > 0):
                return np.inf, (float(sc[0]), float(sc[1]), float(sc[2]))
            new /= new[0]
            done = np.max(np.abs(np.log(new / sc))) < 1e-7
            sc = new
            if done:
                break
        return self.evaluate(taus, sc)[0], (float(sc[0]), float(sc[1]), float(sc[2]))


def _whiten_unit(X: np.ndarray, t: np.ndarray, tau: float | None) -> np.ndarray:
    """``whiten_axis(X, t, tau, 1.0)`` written in place into one new array (the same operations in the
    same order, so the same numbers, with two passes over the rows fewer; the search whitens each axis'
    rows about 50 times)."""
    a, g = _coeffs(t, tau)
    W = np.empty_like(X)
    W[0] = X[0]
    body = W[1:]
    np.multiply(X[:-1], a[:, None], out=body)
    np.subtract(X[1:], body, out=body)  # e_k - a_k e_(k-1)
    body *= g[:, None]  # u_k = (e_k - a_k e_(k-1)) / sqrt(1 - a_k^2)
    return W


def tau_search_bounds(t: np.ndarray) -> tuple[float, float]:
    """Search interval of ln tau: [ln(median(dt) / 5), ln(duration)]."""
    return float(np.log(np.median(np.diff(t)) / 5.0)), float(np.log(t[-1] - t[0]))


def estimable_basis(problem) -> np.ndarray:
    """(n, p) map from natural-unit coefficients to a basis of the estimable column space."""
    ra = problem.rank()
    V, inv_s = ra.pinv_factors()  # R = U s V^T of the scaled system Z = S / c = Q R
    inv_c = np.where(problem.red.scale > 0, 1.0 / np.where(problem.red.scale > 0, problem.red.scale, 1.0), 0.0)
    return inv_c[:, None] * V * inv_s  # S c^-1 V s^-1 = Q U_r: orthonormal columns spanning S


def fit_noise(problem, kind: str = "auto", tau=None, *, xatol: float = 5e-3) -> NoiseModel:
    """The noise model of a problem's rows (module notes).

    Parameters
    ----------
    problem : Problem
        Rows ``(N, 3)`` in time order, with times.
    kind : {"auto", "gm", "white"}
        ``white``: one std, no correlation (nothing is fitted). ``gm``: Gauss-Markov on every
        axis, tau by REML unless given, axis scales by REML. ``auto``: as ``gm``, then white on
        the axes where the likelihood-ratio test does not reject it, one common scale unless the
        axis scales are significant.
    tau : float, three floats or None
        Given correlation time(s), s (``gm`` only).
    xatol : float
        Tolerance of the search in ln tau.

    Returns
    -------
    NoiseModel
    """

    check_noise_kind(kind)
    taus_given = check_tau(tau)
    if kind == "white":
        if taus_given is not None:
            raise ValueError("`tau` given with noise 'white': use noise 'gm'")
        return NoiseModel.white()
    if taus_given is not None and kind == "auto":
        raise ValueError("`tau` given with noise 'auto': a given tau means noise 'gm'")
    if problem.y is None or problem.t is None or problem.y.ndim != 2 or problem.y.shape[1] != 3:
        if kind == "auto":  # nothing to test a correlation on: white, and said
            return replace(NoiseModel.white(), kind="auto", rule="white: rows without sample times")
        raise ValueError(f"problem `{problem.source}`: a Gauss-Markov noise model needs rows (N, 3) with their times")
    if problem.n_samples < 3:
        raise ValueError(f"problem `{problem.source}`: {problem.n_samples} samples are too few to fit a noise model")
    reml = Reml(problem, estimable_basis(problem))
    lo, hi = tau_search_bounds(problem.t)

    if taus_given is not None:
        val, sc = reml.fit_scales(taus_given)
        return NoiseModel(kind="gm", tau=taus_given, scale=sc, rule="given",
                          sigma=_sigma(reml, taus_given, sc), extra={"neg2_reml": val})

    best, taus, scales = _search_taus(reml, [True, True, True], lo, hi, xatol, free=True)
    if not np.isfinite(best):
        if kind == "gm":
            raise ValueError(f"problem `{problem.source}`: the Gauss-Markov likelihood is not finite anywhere "
                             "(residuals at the rounding level: noise-free data?); use noise 'white'")
        return replace(NoiseModel.white(), kind="auto", rule="white: no finite Gauss-Markov likelihood (noise-free?)")
    if kind == "gm":
        return NoiseModel(kind="gm", tau=tuple(taus), scale=scales, rule="reml", sigma=_sigma(reml, taus, scales),
                          extra={"neg2_reml": best})

    # auto: white on an axis where the likelihood ratio does not reject it. The ratio with the
    # other axes held is an upper bound of the one with them refitted; refit only where it matters.
    lr = []
    for j in range(3):
        tt = list(taus)
        tt[j] = None
        quick = reml.fit_scales(tt, scales)[0] - best
        if np.isfinite(quick) and (quick < 0.5 * AUTO_LR or quick > 20.0 * AUTO_LR):
            lr.append(max(quick, 0.0))
            continue
        corr = [k != j for k in range(3)]
        val_j = _search_taus(reml, corr, lo, hi, xatol, free=True, start=taus, polish_only=True)[0]
        lr.append(max(val_j - best, 0.0) if np.isfinite(val_j) else np.inf)  # -2 ln Lambda_a
    corr = [lr[j] > AUTO_LR for j in range(3)]
    chosen0 = [taus[j] if corr[j] else None for j in range(3)]
    val_free, sc_free = reml.fit_scales(chosen0, scales)
    taus_free = chosen0
    if not all(corr[j] for j in range(3)) and any(corr):
        val_free, taus_free, sc_free = _search_taus(reml, corr, lo, hi, xatol, free=True, start=taus,
                                                    polish_only=True)
    val_one, taus_one, _ = _search_taus(reml, corr, lo, hi, xatol, free=False, start=taus, polish_only=True)
    lr_scale = max(val_one - val_free, 0.0) if np.isfinite(val_one - val_free) else 0.0
    free = lr_scale > AUTO_LR_SCALE
    chosen, sc, val = (taus_free, sc_free, val_free) if free else (taus_one, (1.0, 1.0, 1.0), val_one)
    return NoiseModel(kind="auto", tau=tuple(chosen), scale=sc, rule="reml", lr=tuple(float(v) for v in lr),
                      lr_scale=float(lr_scale), sigma=_sigma(reml, chosen, sc), extra={"neg2_reml": val})


#: What the tau search sees where the likelihood is not finite (a rounding-level residual).
_NO_LIKELIHOOD = 1e300


def _search_taus(reml: Reml, corr: Sequence[bool], lo: float, hi: float, xatol: float, *, free: bool,
                 start: Sequence[float | None] | None = None, polish_only: bool = False):
    """Minimise -2 l_R over ln tau of the correlated axes, coordinate-wise (scales by their fixed point).

    Returns ``(-2 l_R, taus, scales)`` (tau None on the white axes). Without `start`, one common
    tau is found first over the whole interval; then each axis is searched in turn within a
    factor 4 of its current value (widened when the minimum lands on an edge), and once more
    within 25 %.
    """
    state: dict[str, Any] = {"scales": None}

    def value(tt) -> float:
        v, sc = reml.fit_scales(tt, state["scales"], free=free)
        if np.isfinite(v):
            state["scales"] = sc
            return v
        return _NO_LIKELIHOOD  # the search needs finite values

    if not any(corr):
        v, sc = reml.fit_scales([None, None, None], free=free)
        return v, [None, None, None], sc
    if start is None:
        x = bounded_minimum(lambda x: value([float(np.exp(x)) if c else None for c in corr]), lo, hi, xatol)
        taus = [float(np.exp(x)) if c else None for c in corr]
    else:
        taus = [(start[j] if start[j] is not None else float(np.exp(lo))) if corr[j] else None for j in range(3)]
    widths = (np.log(1.25),) if polish_only else (np.log(4.0), np.log(1.25))
    for w in widths:
        for j in range(3):
            if not corr[j]:
                continue
            x0 = float(np.log(taus[j] or np.exp(lo)))
            a, b = max(lo, x0 - w), min(hi, x0 + w)
            for _ in range(20):
                def f(x, j=j):
                    tt = list(taus)
                    tt[j] = float(np.exp(x))
                    return value(tt)
                x = float(bounded_minimum(f, a, b, xatol))
                edge = 3 * xatol
                if x - a < edge and a > lo:
                    a, b = max(lo, a - 2 * w), a + edge
                elif b - x < edge and b < hi:
                    a, b = b - edge, min(hi, b + 2 * w)
                else:
                    break
            taus[j] = float(np.exp(x))
    v, sc = reml.fit_scales(taus, state["scales"], free=free)
    return (v if v < _NO_LIKELIHOOD else np.inf), taus, sc


def bounded_minimum(func: Callable[[float], float], a: float, b: float, xatol: float, maxfun: int = 500) -> float:
    """Minimiser of `func` on ``[a, b]`` by Brent's bounded method (golden section with parabolic steps).

    The algorithm and the numbers of ``scipy.optimize.minimize_scalar(func, bounds=(a, b),
    method="bounded", options={"xatol": xatol}).x`` (the same steps and function values,
    ``tests/analysis/test_bounded_minimum.py``), without importing ``scipy.optimize`` (0.2 s, most of the
    noise fit of a short flight). At most `maxfun` evaluations.
    """
    sqrt_eps = math.sqrt(2.2e-16)
    golden_mean = 0.5 * (3.0 - math.sqrt(5.0))
    fulc = a + golden_mean * (b - a)
    nfc = xf = x = fulc
    rat = e = 0.0
    fx = func(x)
    num = 1
    ffulc = fnfc = fx
    xm = 0.5 * (a + b)
    tol1 = sqrt_eps * np.abs(xf) + xatol / 3.0
    tol2 = 2.0 * tol1
    while np.abs(xf - xm) > (tol2 - 0.5 * (b - a)):
        golden = True
        if np.abs(e) > tol1:  # try a parabola through the three best points
            golden = False
            r = (xf - nfc) * (fx - ffulc)
            q = (xf - fulc) * (fx - fnfc)
            p = (xf - fulc) * q - (xf - nfc) * r
            q = 2.0 * (q - r)
            if q > 0.0:
                p = -p
            q = np.abs(q)
            r = e
            e = rat
            if (np.abs(p) < np.abs(0.5 * q * r)) and (p > q * (a - xf)) and (p < q * (b - xf)):  # acceptable
                rat = (p + 0.0) / q
                x = xf + rat
                if ((x - a) < tol2) or ((b - x) < tol2):
                    si = np.sign(xm - xf) + ((xm - xf) == 0)
                    rat = tol1 * si
            else:
                golden = True
        if golden:  # golden-section step into the larger part
            e = a - xf if xf >= xm else b - xf
            rat = golden_mean * e
        si = np.sign(rat) + (rat == 0)
        x = xf + si * np.maximum(np.abs(rat), tol1)
        fu = func(x)
        num += 1
        if fu <= fx:
            if x >= xf:
                a = xf
            else:
                b = xf
            fulc, ffulc = nfc, fnfc
            nfc, fnfc = xf, fx
            xf, fx = x, fu
        else:
            if x < xf:
                a = x
            else:
                b = x
            if (fu <= fnfc) or (nfc == xf):
                fulc, ffulc = nfc, fnfc
                nfc, fnfc = x, fu
            elif (fu <= ffulc) or (fulc == xf) or (fulc == nfc):
                fulc, ffulc = x, fu
        xm = 0.5 * (a + b)
        tol1 = sqrt_eps * np.abs(xf) + xatol / 3.0
        tol2 = 2.0 * tol1
        if num >= maxfun:
            break
    return xf


def _sigma(reml: Reml, taus, scales) -> float:
    """REML sigma of the x axis: sqrt(RSS_w / (m - p))."""
    _, T = reml.evaluate(taus, scales)
    if not isinstance(T, np.ndarray):
        return float("nan")
    return float(abs(T[reml.p, reml.p]) / np.sqrt(3 * reml.N - reml.p))


def with_kind(noise: NoiseModel, kind: str) -> NoiseModel:
    """The same fitted model relabelled with what was asked."""
    return replace(noise, kind=kind)

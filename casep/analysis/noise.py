"""The noise of the regression rows: white or first-order Gauss-Markov per axis, fitted by REML.

Tracking noise on a range is coloured: the velocity a radar or an optical track delivers is
smoothed, and its error is close to first-order Gauss-Markov (AR(1) on the sample times) with a
correlation time of about a second. Least squares with a white-noise std is then several times
overconfident. The noise model belongs to the data, so every estimator solves on the same
whitened rows (:meth:`casep.analysis.problem.Problem.whitened`).

Model
-----
Axis ``a`` (x, y, z) of the velocity error has stationary std ``sigma_a = sigma r_a`` (``r_x = 1``)
and, for Gauss-Markov noise, correlation time ``tau_a``: between samples ``k - 1`` and ``k``
(any spacing: non-uniform, across a gap)::

    e_k = a_k e_{k-1} + sqrt(1 - a_k^2) sigma_a w_k,     a_k = exp(-(t_k - t_{k-1}) / tau_a),  w_k ~ N(0, 1)

and white noise is ``a_k = 0``. The whitening (exact for this covariance, the Cholesky factor
of its inverse)::

    u_0 = e_0 / r_a,     u_k = (e_k - a_k e_{k-1}) / (r_a sqrt(1 - a_k^2))

makes the noise white with std ``sigma``; it is applied to ``S`` and ``dv`` alike, so least squares
on the whitened rows is the GLS estimate and every estimator's std holds.

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

from dataclasses import dataclass, field, replace
from typing import Any, Iterable, Iterator, Sequence

import numpy as np

__all__ = ["NOISE_KINDS", "AUTO_LR", "AUTO_LR_SCALE", "NoiseModel", "whiten", "whiten_blocks",
           "fit_noise", "check_noise_kind", "ljung_box", "WhitenessTest", "whiteness_test", "find_gaps"]

#: The noise kinds a problem can be given.
NOISE_KINDS = ("white", "gm", "auto")
#: ``auto``: -2 ln Lambda of Gauss-Markov against white noise on one axis above which the axis is
#: Gauss-Markov: 1 % point of (chi2_0 + chi2_1) / 2 (the chi2_1 2 % point).
AUTO_LR = 5.412
#: ``auto``: -2 ln Lambda of three axis scales against one above which they are kept: chi2_2 1 % point.
AUTO_LR_SCALE = 9.210
AXES = ("x", "y", "z")


def check_noise_kind(kind: str) -> str:
    """Validate a noise kind (``white``, ``gm`` or ``auto``), naming the parameter."""
    if kind not in NOISE_KINDS:
        raise ValueError(f"`noise` must be one of {', '.join(NOISE_KINDS)}, got {kind!r}")
    return kind


def _check_tau(tau) -> tuple[float, float, float] | None:
    """A given correlation time: one value for every axis or three, s, each in (0, 1e4]."""
    if tau is None or (isinstance(tau, str) and tau == "auto"):
        return None
    vals = np.atleast_1d(np.asarray(tau, dtype=float)) if not isinstance(tau, str) else None
    if vals is None or vals.size not in (1, 3):
        raise ValueError(f"`tau` must be a number > 0 s, three of them (x, y, z) or 'auto', got {tau!r}")
    vals = np.broadcast_to(vals, (3,))
    for a, v in zip(AXES, vals):
        if not (np.isfinite(v) and 0.0 < v <= 1e4):
            raise ValueError(f"`tau` ({a}) must be in (0, 1e4] s (a correlation time above 1e4 s exceeds any "
                             f"flight), got {v}")
    return (float(vals[0]), float(vals[1]), float(vals[2]))


@dataclass(frozen=True)
class NoiseModel:
    """The noise of a problem's rows, per axis.

    Attributes
    ----------
    kind : {"white", "gm", "auto"}
        What was asked.
    tau : tuple of 3 (float or None)
        Correlation time per axis, s; None where the axis is white.
    scale : tuple of 3 float
        Std of each axis relative to x (``sigma_a = sigma scale_a``).
    rule : str
        How tau and scale were had: ``"given"`` or ``"reml"``.
    lr : tuple of 3 float, optional
        ``auto``: -2 ln Lambda of Gauss-Markov against white noise per axis.
    lr_scale : float, optional
        ``auto``: -2 ln Lambda of three axis scales against one.
    sigma : float, optional
        REML estimate of the x-axis stationary std, m/s.
    """

    kind: str = "white"
    tau: tuple = (None, None, None)
    scale: tuple = (1.0, 1.0, 1.0)
    rule: str = "given"
    lr: tuple | None = None
    lr_scale: float | None = None
    sigma: float | None = None
    extra: dict = field(default_factory=dict, compare=False)

    @classmethod
    def white(cls) -> "NoiseModel":
        """White noise of one std on every axis (ordinary least squares)."""
        return cls()

    @classmethod
    def gauss_markov(cls, tau, scale: Sequence[float] = (1.0, 1.0, 1.0)) -> "NoiseModel":
        """Gauss-Markov noise of given correlation time (one value or one per axis), s."""
        taus = _check_tau(tau)
        if taus is None:
            raise ValueError("`tau` is required (a number > 0 s or three)")
        return cls(kind="gm", tau=taus, scale=tuple(float(s) for s in scale), rule="given")

    @property
    def is_white(self) -> bool:
        """True when no axis is correlated and the axes share one std (plain least squares)."""
        return all(t is None for t in self.tau) and all(s == 1.0 for s in self.scale)

    def axis_kinds(self) -> tuple[str, str, str]:
        return tuple("white" if t is None else "gm" for t in self.tau)  # type: ignore[return-value]

    def line(self) -> str:
        """One line for the console: what the noise is and why."""
        parts = []
        for j, a in enumerate(AXES):
            p = f"{a} " + ("white" if self.tau[j] is None else f"GM tau {self.tau[j]:.3g} s")
            if self.sigma is not None:
                p += f" std {self.sigma * self.scale[j]:.3g} m/s"
            elif self.scale[j] != 1.0:
                p += f" scale {self.scale[j]:.3g}"
            if self.lr is not None:
                p += f" (LR {self.lr[j]:.3g})"
            parts.append(p)
        how = {"reml": "REML", "given": "given"}.get(self.rule, self.rule)
        head = f"noise {self.kind}" + (f" ({how}" + (f"; GM where LR > {AUTO_LR:g}, 1 %" if self.kind == "auto" else "")
                                        + ")")
        scale = "" if self.lr_scale is None else f"; axis scales LR {self.lr_scale:.3g} (kept > {AUTO_LR_SCALE:g})"
        return f"{head}: " + ", ".join(parts) + scale

    def to_dict(self) -> dict:
        """JSON-ready description."""
        d: dict[str, Any] = {"kind": self.kind, "rule": self.rule,
             "axes": {a: {"model": "white" if self.tau[j] is None else "gauss-markov",
                          "tau_s": self.tau[j], "scale": self.scale[j],
                          **({"std_m_s": self.sigma * self.scale[j]} if self.sigma is not None else {}),
                          **({"lr": self.lr[j]} if self.lr is not None else {})}
                      for j, a in enumerate(AXES)}}
        if self.lr is not None:
            d["lr_threshold"] = AUTO_LR
        if self.lr_scale is not None:
            d["lr_scale"], d["lr_scale_threshold"] = self.lr_scale, AUTO_LR_SCALE
        d.update(self.extra)
        return d


# --------------------------------------------------------------------------- whitening
def _coeffs(t: np.ndarray, tau: float | None) -> tuple[np.ndarray, np.ndarray]:
    """``(a_k, 1 / sqrt(1 - a_k^2))`` for k >= 1 (a = 0 for white noise)."""
    dt = np.diff(t)
    if tau is None:
        return np.zeros(dt.size), np.ones(dt.size)
    a = np.exp(-dt / tau)  # a_k = exp(-dt_k / tau)
    return a, 1.0 / np.sqrt(-np.expm1(-2.0 * dt / tau))  # 1 - a^2 without cancellation


def _whiten_axis(X: np.ndarray, t: np.ndarray, tau: float | None, scale: float,
                 prev: tuple[float, np.ndarray] | None = None) -> np.ndarray:
    """Whiten the rows ``X`` (N, k) of one axis; `prev` = (time, row) before the first, if any."""
    if prev is not None:
        X = np.concatenate([prev[1][None], X])
        t = np.concatenate([[prev[0]], t])
    a, g = _coeffs(t, tau)
    W = np.empty_like(X)
    W[0] = X[0]
    W[1:] = (X[1:] - a[:, None] * X[:-1]) * g[:, None]  # u_k = (e_k - a_k e_{k-1}) / sqrt(1 - a_k^2)
    W /= scale
    return W[1:] if prev is not None else W


def whiten(S: np.ndarray, y: np.ndarray, t: np.ndarray, noise: NoiseModel,
           weights: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Whitened ``(S_w, y_w)`` of ``S`` (N, 3, n) and ``y`` (N, 3) on the times ``t`` (module notes).

    `weights` (N, 3), optional, multiply the whitened rows by ``sqrt(w)`` (robust fits).
    """
    S = np.asarray(S, dtype=float)
    y = np.asarray(y, dtype=float)
    Sw = np.empty_like(S)
    yw = np.empty_like(y)
    for j in range(3):
        X = np.concatenate([S[:, j, :], y[:, j, None]], axis=1)
        W = _whiten_axis(X, t, noise.tau[j], noise.scale[j])
        Sw[:, j, :], yw[:, j] = W[:, :-1], W[:, -1]
    if weights is not None:
        sw = np.sqrt(weights)
        Sw *= sw[:, :, None]
        yw *= sw
    return Sw, yw


def whiten_blocks(blocks: Iterable[tuple[slice, np.ndarray, np.ndarray]], t: np.ndarray, noise: NoiseModel,
                  weights: np.ndarray | None = None) -> Iterator[tuple[slice, np.ndarray, np.ndarray]]:
    """Whiten ``(row slice, S block, y block)`` in time order, carrying the last row across blocks."""
    prev: list[tuple[float, np.ndarray] | None] = [None, None, None]
    for sl, S_b, y_b in blocks:
        tb = t[sl]
        Sw = np.empty(S_b.shape)
        yw = np.empty(y_b.shape)
        for j in range(3):
            X = np.concatenate([S_b[:, j, :], y_b[:, j, None]], axis=1)
            W = _whiten_axis(X, tb, noise.tau[j], noise.scale[j], prev[j])
            prev[j] = (float(tb[-1]), X[-1].copy())
            Sw[:, j, :], yw[:, j] = W[:, :-1], W[:, -1]
        if weights is not None:
            sw = np.sqrt(weights[sl])
            Sw *= sw[:, :, None]
            yw *= sw
        yield sl, Sw, yw


# --------------------------------------------------------------------------- REML
class _Reml:
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
                W = _whiten_axis(self._Z[j], self.t, tau, 1.0)
                M = W.T @ W
            else:
                M = np.zeros((self.p + 1, self.p + 1))
                prev = None
                for sl, S_b, y_b in self.pb.blocks():
                    X = np.concatenate([S_b[:, j, :] @ self.B, y_b[:, j, None]], axis=1)
                    tb = self.t[sl]
                    W = _whiten_axis(X, tb, tau, 1.0, prev)
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


def tau_search_bounds(t: np.ndarray) -> tuple[float, float]:
    """Search interval of ln tau: [ln(median(dt) / 5), ln(duration)]."""
    return float(np.log(np.median(np.diff(t)) / 5.0)), float(np.log(t[-1] - t[0]))


def _estimable_basis(problem) -> np.ndarray:
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
    taus_given = _check_tau(tau)
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
    reml = _Reml(problem, _estimable_basis(problem))
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


def _search_taus(reml: _Reml, corr: Sequence[bool], lo: float, hi: float, xatol: float, *, free: bool,
                 start: Sequence[float | None] | None = None, polish_only: bool = False):
    """Minimise -2 l_R over ln tau of the correlated axes, coordinate-wise (scales by their fixed point).

    Returns ``(-2 l_R, taus, scales)`` (tau None on the white axes). Without `start`, one common
    tau is found first over the whole interval; then each axis is searched in turn within a
    factor 4 of its current value (widened when the minimum lands on an edge), and once more
    within 25 %.
    """
    from scipy.optimize import minimize_scalar

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
        r = minimize_scalar(lambda x: value([float(np.exp(x)) if c else None for c in corr]), bounds=(lo, hi),
                            method="bounded", options={"xatol": xatol})
        taus = [float(np.exp(r.x)) if c else None for c in corr]
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
                r = minimize_scalar(f, bounds=(a, b), method="bounded", options={"xatol": xatol})
                x = float(r.x)
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


def _sigma(reml: _Reml, taus, scales) -> float:
    """REML sigma of the x axis: sqrt(RSS_w / (m - p))."""
    _, T = reml.evaluate(taus, scales)
    if not isinstance(T, np.ndarray):
        return float("nan")
    return float(abs(T[reml.p, reml.p]) / np.sqrt(3 * reml.N - reml.p))


def with_kind(noise: NoiseModel, kind: str) -> NoiseModel:
    """The same fitted model relabelled with what was asked."""
    return replace(noise, kind=kind)


# --------------------------------------------------------------------------- whiteness
def ljung_box(x: np.ndarray, lags: int, segments: np.ndarray | None = None) -> tuple[float, float]:
    """Ljung-Box ``Q = n (n + 2) sum_k rho_k^2 / (n - k)`` of a series and its chi2(lags) p-value.

    `segments`: segment id per sample; lag products are taken only within a segment (a gap in
    the time tags is not a lag).
    """
    from scipy.stats import chi2

    x = np.asarray(x, dtype=float)
    x = x - x.mean()
    n = x.size
    den = float(x @ x)
    if den == 0 or n <= lags + 1:
        return 0.0, 1.0
    q = 0.0
    for k in range(1, lags + 1):
        prod = x[k:] * x[:-k]
        if segments is not None:
            prod = prod[segments[k:] == segments[:-k]]
        rho = float(prod.sum()) / den  # rho_k
        q += rho**2 / (n - k)
    q *= n * (n + 2)
    return float(q), float(chi2.sf(q, lags))


@dataclass(frozen=True)
class WhitenessTest:
    """Residual whiteness per axis (Ljung-Box) and how much too small the white std are."""

    q: tuple[float, float, float]
    p: tuple[float, float, float]
    lags: int
    alpha: float
    std_factor: float | None = None  # median Gauss-Markov / white std over the estimable coefficients
    std_factor_max: float | None = None

    @property
    def rejected(self) -> tuple[str, ...]:
        """The axes whose residuals are not white at `alpha` (Bonferroni over the axes)."""
        return tuple(a for a, p in zip(AXES, self.p) if p < self.alpha / 3)

    def to_dict(self) -> dict:
        return {"test": "ljung-box", "lags": self.lags, "alpha": self.alpha,
                "axes": {a: {"q": self.q[j], "p": self.p[j]} for j, a in enumerate(AXES)},
                "rejected": list(self.rejected), "std_factor_median": self.std_factor,
                "std_factor_max": self.std_factor_max}

    def message(self) -> str:
        parts = ", ".join(f"{a} Q {self.q[j]:.3g} (p {self.p[j]:.2g})"
                          for j, a in enumerate(AXES) if a in self.rejected)
        factor = ""
        if self.std_factor is not None and self.std_factor >= 1.0:
            factor = (f"; the reported std are about {self.std_factor:.2g}x too small (median over the coefficients "
                      f"of the Gauss-Markov std of the same data / the white std; up to {self.std_factor_max:.2g}x)")
        elif self.std_factor is not None:
            factor = (f"; a Gauss-Markov model of the same data gives std {self.std_factor:.2g}x the reported ones "
                      f"(median over the coefficients; up to {self.std_factor_max:.2g}x): the white std are not "
                      "the right ones, some too large here; if the residuals are a model error (frames, time "
                      "tags, a missing term) no noise model makes the std right")
        return (f"residuals are not white ({parts}, Ljung-Box on {self.lags} lags){factor}. Use --noise auto "
                "(or gm)")


def default_lags(n: int) -> int:
    """Lags of the whiteness test and the HAC std: Newey-West's ``floor(4 (n / 100)^(2/9))``."""
    return max(1, int(np.floor(4.0 * (n / 100.0) ** (2.0 / 9.0))))


def find_gaps(t: np.ndarray, factor: float = 3.0) -> list[dict]:
    """Gaps in the sample times longer than `factor` x the median spacing.

    Returns ``[{"start": t before, "length": s, "row": 1-based row after the gap, "t_after": s}]``.
    """
    t = np.asarray(t, dtype=float)
    if t.size < 3:
        return []
    dt = np.diff(t)
    med = float(np.median(dt))
    return [{"start": float(t[k]), "length": float(dt[k]), "row": int(k + 2), "t_after": float(t[k + 1])}
            for k in np.flatnonzero(dt > factor * med)]


def segments_of(t: np.ndarray, gap_factor: float = 3.0) -> np.ndarray:
    """Segment id per sample: a new segment after a spacing above `gap_factor` x the median."""
    dt = np.diff(t)
    return np.concatenate([[0], np.cumsum(dt > gap_factor * np.median(dt))])


def whiteness_test(residuals: np.ndarray, t: np.ndarray, *, alpha: float = 0.01, lags: int | None = None
                   ) -> WhitenessTest:
    """Ljung-Box test per axis of residuals ``(N, 3)`` on their time spacing (gaps break the lags)."""
    r = np.asarray(residuals, dtype=float)
    L = default_lags(r.shape[0]) if lags is None else int(lags)
    seg = segments_of(np.asarray(t, dtype=float))
    qs, ps = zip(*(ljung_box(r[:, j], L, seg) for j in range(3)))
    return WhitenessTest(tuple(qs), tuple(ps), L, alpha)

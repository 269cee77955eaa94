"""Fitting the noise model of the rows (:class:`casep.noise.model.NoiseModel`) by REML.

REML
----
The restricted log-likelihood of ``theta = (tau_a, w_a, r_a)`` (correlation time, white share,
relative std per axis) with ``sigma^2`` profiled out::

    -2 l_R(theta) = (m - p) ln RSS_w + sum_a [N ln r_a^2 + sum_k ln F_ak] + ln det(Z_w^T Z_w)

with ``Z = S V_p`` a basis of the estimable column space (rank ``p``, :mod:`casep.regression.linalg`),
``F_ak`` the innovation variances of the whitening (:mod:`casep.noise.model`; ``1 - a_k^2`` for
Gauss-Markov, 1 for white), ``RSS_w`` the whitened residual sum of squares and ``m = 3 N``. It is
evaluated from one ``(p + 1) x (p + 1)`` Gram matrix per axis: ``G = sum_a M_a / r_a^2 = T^T T``
gives the log-determinant on the diagonal of ``T`` and ``RSS_w = T_pp^2``.

``[Z  dv]`` of each axis is formed once per fit (one pass over S_V, never again); a trial is then

* Gauss-Markov: from lag products grouped by the distinct spacings ``d`` (formed once). With
  ``D_k = z_k - z_(k-1)`` and ``c = 1 - a = -expm1(-d / tau)``, the whitened row is
  ``u_k = (D_k + c z_(k-1)) / sqrt(1 - a^2)``, so::

      M(tau) = z_0 z_0^T + sum_d [A_d + c_d (B_d + B_d^T) + c_d^2 C_d] / (1 - a_d^2),
      A_d = sum D_k D_k^T,  B_d = sum D_k z_(k-1)^T,  C_d = sum z_(k-1) z_(k-1)^T   (k: dt_k = d)

  O(G p^2) per trial for G distinct spacings (written with the differences ``D``, so no
  cancellation when ``dt << tau``); when the spacings are nearly all distinct (jittered time tags)
  the rows ``Z`` are whitened instead, O(N p^2);
* Gauss-Markov plus white: one pass of the innovations filter over ``Z`` (O(N p), compiled) and
  its Gram.

Each ``tau_a`` is found by a bounded scalar search in ``ln tau`` over ``[median(dt) / 5,
duration]``, each white share ``w_a`` in its logit, coordinate-wise; each ``r_a`` by the REML fixed
point ``r_a^2 = RSS_a / (N - h_a)`` (``h_a`` the leverage of the axis' rows).

``auto`` (per axis, nested kinds white < gm < gmw): Gauss-Markov is fitted on every axis and kept
on an axis where the likelihood ratio against white noise there, ``-2 ln Lambda_a``, exceeds
:data:`AUTO_LR`; on the Gauss-Markov axes Gauss-Markov plus white is fitted and kept where its
likelihood ratio against Gauss-Markov exceeds :data:`AUTO_LR`. Each test has one parameter on the
boundary of its space under the null (tau = 0, resp. the white share = 0), so the null
distribution is ``(chi2_0 + chi2_1) / 2`` (Self & Liang); 5.41 is its 1 % point. Separate axis
scales are kept only when they beat one common scale by :data:`AUTO_LR_SCALE` (chi2_2 at 1 %).
An axis the tests leave at the simpler kind is then probed (:data:`PROBE_SPACINGS`, :data:`PROBE_SHARE`):
where the simpler kind does not beat the probe by :data:`AUTO_LR` (a short window, whose columns absorb
the slow part of the noise) Gauss-Markov plus white is taken, with an ``UndecidedNoiseWarning``.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Callable, Sequence

import numpy as np

from casep._kernels import ar1_terms, reml_scale_fit
from casep.noise.model import (
    AUTO_LR,
    AUTO_LR_SCALE,
    NoiseModel,
    check_noise_kind,
    check_tau,
    whiten_series,
)

__all__ = ["fit_noise", "tau_search_bounds", "tau_profile", "tau_kept", "with_kind", "Reml", "estimable_basis",
           "bounded_minimum", "nelder_mead", "SHARE_LOGIT"]

_EPS = float(np.finfo(float).eps)


def _lapack_kernels() -> tuple[Callable[..., np.ndarray], Callable[..., tuple[np.ndarray, int]]]:
    """(Cholesky L, inverse of an upper triangular matrix) of float64 matrices: the LAPACK kernels of
    numpy.linalg.cholesky and numpy.linalg.inv without their wrappers, the same numbers in a third of the time on
    the (p + 1)-square matrices of a REML fixed-point step, where the wrappers' checks cost more than the
    factorisation. The inverse returns ``(inverse, info)``, info 1 for a zero on the diagonal (not definite).
    SciPy's triangular inverse (dtrtri) is faster still on the 36-square factor, but its import costs more than a
    CLI fit's scale steps save (``casep separate`` on the example flight: 0.76 CPU s with it, 0.65 without). A
    Cholesky failure is a NaN factor (:meth:`Reml._factor`)."""
    try:
        from numpy.linalg import _umath_linalg as ul

        def upper_inv(a: np.ndarray) -> tuple[np.ndarray, int]:
            if not a.diagonal().all():
                return a, 1
            return ul.inv(a, signature="d->d"), 0

        return ul.cholesky_lo, upper_inv
    except ImportError:  # pragma: no cover - another numpy's layout
        def chol(a: np.ndarray, signature: str = "d->d") -> np.ndarray:
            try:
                return np.linalg.cholesky(a)
            except np.linalg.LinAlgError:
                return np.full_like(a, np.nan)

        def inv(a: np.ndarray) -> tuple[np.ndarray, int]:
            if not np.all(np.diagonal(a)):
                return a, 1
            return np.linalg.inv(a), 0

        return chol, inv


_cholesky, _upper_inv = _lapack_kernels()

#: Search interval of the white share's logit ``ln(w / (1 - w))``: w in [6e-6, 0.99999].
SHARE_LOGIT = (-12.0, 12.0)


class _LagProducts:
    """Lag products of one axis' ``[Z dv]`` grouped by the distinct spacings (module notes)."""

    def __init__(self, X: np.ndarray, uniq: np.ndarray, inv: np.ndarray) -> None:
        D = X[1:] - X[:-1]  # D_k = z_k - z_(k-1)
        Xp = X[:-1]
        k = X.shape[1]
        G = uniq.size
        self.A, self.B, self.C = (np.empty((G, k, k)) for _ in range(3))
        order = np.argsort(inv, kind="stable")
        bounds = np.searchsorted(inv[order], np.arange(G + 1))
        for g in range(G):
            idx = order[bounds[g]:bounds[g + 1]]
            Dg, Pg = D[idx], Xp[idx]
            self.A[g] = Dg.T @ Dg
            B = Dg.T @ Pg
            self.B[g] = B + B.T
            self.C[g] = Pg.T @ Pg
        self.first = np.outer(X[0], X[0])
        self._flat = [m.reshape(G, k * k) for m in (self.A, self.B, self.C)]  # views: the sums over d as one dot
        self.d = uniq
        self.count = np.bincount(inv, minlength=G)

    def gram(self, tau: float) -> tuple[np.ndarray, float]:
        """(M(tau), sum_k ln(1 - a_k^2))."""
        a, b = ar1_terms(self.d, tau)  # a_d, 1 - a_d^2
        c = -np.expm1(-self.d / tau)  # 1 - a_d without cancellation
        k = self.first.shape[0]
        A, B, C = self._flat  # np.tensordot(w, A, 1) is this dot of w (1, G) and A (G, k^2): its numbers, less overhead
        M = self.first + np.dot((1.0 / b)[None, :], A).reshape(k, k) + np.dot((c / b)[None, :], B).reshape(k, k) \
            + np.dot((c * c / b)[None, :], C).reshape(k, k)
        return M, float(self.count @ np.log(b))


class Reml:
    """-2 l_R of per-axis (tau, white share, scale) from per-axis Gram matrices (module notes).

    Axis ``a`` at ``(tau_a, w_a)`` contributes ``M_a = [Z_w y_w]^T [Z_w y_w]`` (unit scale, ``Z = S B``
    with orthonormal columns before whitening, so ``M_a`` is well conditioned); with the scales,
    ``G = sum_a M_a / r_a^2 = T^T T`` (Cholesky) gives ``ln det(Z_w^T Z_w) = 2 sum ln T_jj`` (j < p)
    and ``RSS_w = T_pp^2``. ``[Z dv]`` is formed once, here.
    """

    #: Lag products are used while the distinct spacings number at most this share of the samples.
    LAG_GROUPS = 0.25
    #: :meth:`fit_scales` compiled where an axis has a white share (:meth:`_fit_scales`); False: numpy's kernels
    #: throughout (the reference of ``tests/noise/test_reml_compiled.py``).
    COMPILED = True

    def __init__(self, problem, basis: np.ndarray) -> None:
        self.pb = problem
        self.B = basis  # (n, p): natural-unit columns -> estimable basis Z = S B
        self.p = basis.shape[1]
        self.t = problem.t
        self.N = problem.n_samples
        self._cache: dict[tuple, tuple[np.ndarray, float]] = {}
        self._fits: dict[tuple, tuple[float, tuple[float, float, float]]] = {}  # fit_scales' answers
        self.Z = self._project(problem)
        uniq, inv = np.unique(np.diff(self.t), return_inverse=True)  # the distinct spacings d
        self._lags: list[_LagProducts | None] = [None, None, None]
        if uniq.size <= self.LAG_GROUPS * self.N:
            self._lags = [_LagProducts(Z, uniq, inv) for Z in self.Z]

    def _project(self, problem) -> list[np.ndarray]:
        """``[S_a B  dv_a]`` per axis (N, p + 1): one pass over S_V."""
        if problem._S is not None:  # rows kept
            X = problem._S @ self.B  # (N, 3, p)
            return [np.concatenate([X[:, j, :], problem.y[:, j, None]], axis=1) for j in range(3)]
        Z = [np.empty((self.N, self.p + 1)) for _ in range(3)]
        for sl, S_b, y_b in problem.blocks():
            X = S_b @ self.B
            for j in range(3):
                Z[j][sl, :-1] = X[:, j, :]
                Z[j][sl, -1] = y_b[:, j]
        return Z

    def gram(self, j: int, tau: float | None, share: float = 0.0) -> tuple[np.ndarray, float]:
        """(M_a, sum_k ln F_k) of axis j at (tau, white share) (unit scale), cached."""
        key = (j, None if tau is None else float(tau), float(share) if tau is not None else 0.0)
        if key not in self._cache:
            lags = self._lags[j]
            if tau is None:
                Z = self.Z[j]
                self._cache[key] = (Z.T @ Z, 0.0)
            elif share == 0.0 and lags is not None:
                self._cache[key] = lags.gram(float(tau))
            else:
                W, ld, _ = whiten_series(self.Z[j], self.t, float(tau), float(share))
                self._cache[key] = (W.T @ W, ld)
            if len(self._cache) > 4096:  # a long search: keep the memory bounded
                self._cache.pop(next(iter(self._cache)))
        return self._cache[key]

    @staticmethod
    def _factor(Ms: np.ndarray, scales) -> np.ndarray | None:
        """Upper T with ``T^T T = G = sum_a M_a / r_a^2`` (`Ms` stacked (3, p + 1, p + 1)); None if not definite."""
        G = Ms[0] / scales[0] ** 2
        G += Ms[1] / scales[1] ** 2
        G += Ms[2] / scales[2] ** 2
        with np.errstate(invalid="ignore"):  # not definite: NaN (numpy.linalg.cholesky would raise)
            L = _cholesky(G, signature="d->d")
        return L.T if np.isfinite(L[-1, -1]) else None  # G = T^T T, T upper

    def evaluate(self, taus: Sequence[float | None], scales, shares: Sequence[float] = (0.0, 0.0, 0.0)
                 ) -> tuple[float, np.ndarray | None]:
        """(-2 l_R, T) at the given taus, scales and white shares."""
        gs = [self.gram(j, taus[j], shares[j]) for j in range(3)]
        return self._value(np.stack([g[0] for g in gs]), [g[1] for g in gs], scales)

    def _value(self, Ms: np.ndarray, logdets: Sequence[float], scales) -> tuple[float, np.ndarray | None]:
        """(-2 l_R, T) from the axes' Gram matrices `Ms` (3, p + 1, p + 1) and ``sum_k ln F_k`` (:meth:`gram`)."""
        T = self._factor(Ms, scales)
        if T is None:
            return np.inf, None
        d = np.abs(T.diagonal()[: self.p])
        rss = float(T[self.p, self.p] ** 2)
        m = 3 * self.N
        if not rss > 0 or (d == 0).any():
            return np.inf, None
        val = ((m - self.p) * np.log(rss) + 2.0 * np.log(d).sum()
               + sum(self.N * np.log(scales[j] ** 2) + logdets[j] for j in range(3)))
        return float(val), T

    def fit_scales(self, taus: Sequence[float | None], scales: Sequence[float] | None = None,
                   free: bool = True, shares: Sequence[float] = (0.0, 0.0, 0.0)
                   ) -> tuple[float, tuple[float, float, float]]:
        """-2 l_R with the axis scales at their REML fixed point (or all 1 when not `free`)."""
        if not free:
            return self.evaluate(taus, (1.0, 1.0, 1.0), shares)[0], (1.0, 1.0, 1.0)
        # a search asks the same point from the same start again (a polish from where the last search ended, a
        # nested test's null): the same answer, kept (the evaluator's, one problem's rows; bounded as the Grams are)
        key = (tuple(None if v is None else float(v) for v in taus),
               None if scales is None else tuple(float(v) for v in scales), tuple(float(v) for v in shares))
        if key not in self._fits:
            self._fits[key] = self._fit_scales(taus, scales, shares)
            if len(self._fits) > 4096:
                self._fits.pop(next(iter(self._fits)))
        return self._fits[key]

    def _fit_scales(self, taus: Sequence[float | None], scales: Sequence[float] | None,
                    shares: Sequence[float]) -> tuple[float, tuple[float, float, float]]:
        """:meth:`fit_scales` with free scales, computed: compiled (:func:`casep._kernels.reml_scale_fit`) where an
        axis is whitened with a white share (its filter is compiled: numba is loaded already), else by numpy's LAPACK
        kernels (the same steps; without numba's import and set-up, 0.3 s, on a fit of white or Gauss-Markov rows)."""
        sc = np.ones(3) if scales is None else np.array(scales, dtype=float)
        gs = [self.gram(j, taus[j], shares[j]) for j in range(3)]
        Ms = np.stack([g[0] for g in gs])  # (3, p + 1, p + 1)
        if self.COMPILED and any(taus[j] is not None and float(shares[j]) > 0.0 for j in range(3)):
            val, sc3, _ = reml_scale_fit(Ms, sc, self.N, self.p, np.array([g[1] for g in gs], dtype=float))
            return val, sc3
        p = self.p
        Mflat = Ms.reshape(3, -1)  # G = sum_a M_a / r_a^2 as one dot
        Mpp = np.ascontiguousarray(Ms[:, :p, :p]).reshape(3, p * p)  # h_a = tr(M_a,pp Ginv) as one dot
        Myy = Ms[:, p, p]
        with np.errstate(invalid="ignore"):  # not definite: NaN (numpy.linalg.cholesky would raise)
            sc, ok = self._scale_steps(sc, Mflat, Mpp, Ms, Myy)
        if not ok:
            return np.inf, (float(sc[0]), float(sc[1]), float(sc[2]))
        return self._value(Ms, [g[1] for g in gs], sc)[0], (float(sc[0]), float(sc[1]), float(sc[2]))

    def _scale_steps(self, sc: np.ndarray, Mflat: np.ndarray, Mpp: np.ndarray, Ms: np.ndarray, Myy: np.ndarray
                     ) -> tuple[np.ndarray, bool]:
        """:meth:`fit_scales`' fixed-point steps from `sc`: (the scales, True) at convergence, (the scales of the
        step that failed, False) where G is not definite or an axis' RSS vanishes. Called under
        ``np.errstate(invalid="ignore")`` (a Cholesky failure is a NaN factor), set once for every step."""
        p = self.p
        v = np.empty(p + 1)  # (beta, -1)
        v[p] = -1.0
        for _ in range(50):
            L = _cholesky(np.dot(sc ** -2, Mflat).reshape(p + 1, p + 1), signature="d->d")
            if not np.isfinite(L[-1, -1]):
                return sc, False
            T = L.T  # G = T^T T, T upper
            Ti, info = _upper_inv(T[:p, :p]) if p else (np.zeros((0, 0)), 0)  # T_p^-1 (upper)
            if info != 0:  # a zero on T_p's diagonal: not definite
                return sc, False
            np.matmul(Ti, T[:p, p], out=v[:p])  # beta = T_p^-1 T[:p, p]
            Ginv = Ti @ Ti.T  # (Z_w^T Z_w)^-1 = (T_p^T T_p)^-1
            rss = np.maximum(np.matmul(Ms, v) @ v, 0.0)  # ||[Z_a y_a] (beta, -1)||^2
            h = (Mpp @ Ginv.ravel()) / sc ** 2  # leverage of each axis' rows (Ginv symmetric)
            new = np.sqrt(rss / np.maximum(self.N - h, 1.0))  # r_a^2 = RSS_a / (N - h_a)
            if not (new > 0).all():
                return sc, False
            new /= new[0]
            # converged to 1e-7 in ln r, or to the rounding of RSS_a = v^T M_a v (relative eps M_a,pp / RSS_a):
            # below it the steps are rounding noise (residuals ~1e-8 of |dv|: ln r moves by O(1) at random)
            tol = max(1e-7, 10.0 * _EPS * float((Myy / np.maximum(rss, 1e-300)).max()))
            done = np.abs(np.log(new / sc)).max() < tol
            sc = new
            if done:
                break
        return sc, True


def tau_search_bounds(t: np.ndarray) -> tuple[float, float]:
    """Search interval of ln tau: [ln(median(dt) / 5), ln(duration)]."""
    return float(np.log(np.median(np.diff(t)) / 5.0)), float(np.log(t[-1] - t[0]))


def estimable_basis(problem) -> np.ndarray:
    """(n, p) map from natural-unit coefficients to a basis of the estimable column space."""
    ra = problem.rank()
    V, inv_s = ra.pinv_factors()  # R = U s V^T of the scaled system Z = S / c = Q R
    inv_c = np.where(problem.red.scale > 0, 1.0 / np.where(problem.red.scale > 0, problem.red.scale, 1.0), 0.0)
    return inv_c[:, None] * V * inv_s  # S c^-1 V s^-1 = Q U_r: orthonormal columns spanning S


def fit_noise(problem, kind: str = "auto", tau=None, *, xatol: float = 5e-3, reml: Reml | None = None) -> NoiseModel:
    """The noise model of a problem's rows (module notes).

    Parameters
    ----------
    problem : Problem
        Rows ``(N, 3)`` in time order, with times.
    kind : {"auto", "gm", "gmw", "white"}
        ``white``: one std, no correlation (nothing is fitted). ``gm``: Gauss-Markov on every
        axis, tau by REML unless given, axis scales by REML. ``gmw``: Gauss-Markov plus white on
        every axis, tau (unless given) and the white share by REML. ``auto``: per axis the
        simplest of white, gm, gmw that the likelihood-ratio tests do not reject, one common
        scale unless the axis scales are significant.
    tau : float, three floats or None
        Given correlation time(s), s (``gm`` and ``gmw`` only).
    xatol : float
        Tolerance of the searches in ln tau (and the white share's logit).
    reml : Reml, optional
        The REML evaluator of this `problem` (``Reml(problem, estimable_basis(problem))``) to reuse, with the Gram
        matrices it has cached (:func:`tau_profile`'s fits of one problem); the same numbers as a new one.

    Returns
    -------
    NoiseModel
    """
    check_noise_kind(kind)
    taus_given = check_tau(tau)
    if kind == "white":
        if taus_given is not None:
            raise ValueError("`tau` given with noise 'white': use noise 'gm' or 'gmw'")
        return NoiseModel.white()
    if taus_given is not None and kind == "auto":
        raise ValueError("`tau` given with noise 'auto': a given tau means noise 'gm' (or 'gmw')")
    if problem.y is None or problem.t is None or problem.y.ndim != 2 or problem.y.shape[1] != 3:
        if kind == "auto":  # nothing to test a correlation on: white, and said
            return replace(NoiseModel.white(), kind="auto", rule="white: rows without sample times")
        raise ValueError(f"problem `{problem.source}`: a Gauss-Markov noise model needs rows (N, 3) with their times")
    if problem.n_samples < 3:
        raise ValueError(f"problem `{problem.source}`: {problem.n_samples} samples are too few to fit a noise model")
    if reml is None:
        reml = Reml(problem, estimable_basis(problem))
    elif reml.pb is not problem:
        raise ValueError("`reml` is another problem's")
    lo, hi = tau_search_bounds(problem.t)
    if taus_given is not None:
        if kind == "gm":
            val, sc = reml.fit_scales(taus_given)
            return NoiseModel(kind="gm", tau=taus_given, scale=sc, rule="given",
                              sigma=_sigma(reml, taus_given, sc), extra={"neg2_reml": val})
        fit = _Search(reml, lo, hi, xatol, free=True, fixed_tau=True).run([True] * 3, list(taus_given), [True] * 3)
        return _model("gmw", fit, reml, rule="given")
    fit = _Search(reml, lo, hi, xatol, free=True).run([True] * 3)
    if not np.isfinite(fit.value):
        if kind != "auto":
            raise ValueError(f"problem `{problem.source}`: the Gauss-Markov likelihood is not finite anywhere "
                             "(residuals at the rounding level: noise-free data?); use noise 'white'")
        return replace(NoiseModel.white(), kind="auto", rule="white: no finite Gauss-Markov likelihood (noise-free?)")
    if kind == "gm":
        return _model("gm", fit, reml)
    if kind == "gmw":
        return _model("gmw", _Search(reml, lo, hi, xatol, free=True).run([True] * 3, fit.taus, [True] * 3,
                                                                         scales=fit.scales), reml)
    return _auto(reml, fit, lo, hi, xatol)


#: :func:`tau_profile`: points per axis, spaced evenly in ln tau over the search interval
#: (:func:`tau_search_bounds`), and the profile's -2 ln Lambda beyond which a point is left out (chi2_1, 95 %).
PROFILE_POINTS = 7
PROFILE_LR = 3.841


def tau_profile(problem, points: int = PROFILE_POINTS, level: float = PROFILE_LR
                ) -> tuple[NoiseModel, list[list[tuple[float, NoiseModel]]]]:
    """The Gauss-Markov plus white noise model of a problem's rows (``fit_noise(problem, "gmw")``) and, per axis,
    the models along its correlation time's profile likelihood: ``(fit, [[(weight, model), ...] per axis])``.

    On axis ``a`` the correlation time is held at `points` values spaced evenly in ``ln tau`` over the search
    interval (:func:`tau_search_bounds`, a uniform prior in ``ln tau`` there), the other axes' at the fit's, and
    the white shares and scales are fitted again by REML (``fit_noise(problem, "gmw", tau=...)``). The points whose
    ``-2 l_R`` is within `level` of the axis's best (its profile's 95 % interval) are kept, each weighted by its
    restricted likelihood (``exp(-(-2 l_R - min) / 2)``, the weights of an axis summing to 1): the posterior of
    ``ln tau`` on that interval. A few hundred epochs hold tau to a factor of several (a 20 s record of tau 1 s:
    REML's tau from 0.14 to 9.5 s over 12 seeds), and a combination's variance can grow several times over that
    range (:func:`casep.workflows.row_estimators.tau_spread`).

    The search interval's top is the record length, and it caps the average: beyond it the record cannot tell a
    Gauss-Markov noise from a drift its coefficients absorb (the profile stays flat) while the scale REML gives it,
    and so the variance it adds along a bias, keeps growing with tau; an uncapped average over what the record does
    not bound is no std. An axis whose kept interval reaches the record length has a tau the record does not bound
    from above (:func:`tau_kept` says which): the average there stops at the record length, and the caller says so.
    The bottom needs no such cap: a Gauss-Markov noise of tau below the sample spacing is white noise."""
    reml = Reml(problem, estimable_basis(problem))  # one evaluator for the fit and every point: Gram matrices once
    base = fit_noise(problem, "gmw", reml=reml)
    lo, hi = tau_search_bounds(problem.t)
    grid = np.exp(np.linspace(lo, hi, int(points)))
    out: list[list[tuple[float, NoiseModel]]] = []
    for j in range(3):
        fits = []
        for tj in grid:
            tt = [float(v) for v in base.tau]
            tt[j] = float(tj)
            fits.append(fit_noise(problem, "gmw", tau=tt, reml=reml))
        d = np.array([f.extra["neg2_reml"] for f in fits], dtype=float)
        d = d - np.min(d[np.isfinite(d)])
        keep = np.isfinite(d) & (d < level)
        w = np.exp(-d[keep] / 2.0)
        out.append([(float(v), f) for v, f in zip(w / w.sum(), [f for f, k in zip(fits, keep) if k])])
    return base, out


def tau_kept(t: np.ndarray, profile: tuple) -> list[tuple[float, float, bool]]:
    """Per axis of a :func:`tau_profile` of rows at times `t`: the smallest and largest tau kept (s) and whether the
    kept interval reaches the search interval's top, the record length (:func:`tau_search_bounds`): then the record
    does not bound that axis's tau from above (:func:`tau_profile`'s notes)."""
    top = float(np.exp(tau_search_bounds(np.asarray(t, dtype=float))[1]))
    out = []
    for j, points in enumerate(profile[1]):
        taus = [float(nm.tau[j]) for _, nm in points]
        out.append((min(taus), max(taus), max(taus) >= top * (1.0 - 1e-9)))
    return out


class _Fit:
    """A point of the search: -2 l_R, taus (None: white axis), white shares, scales."""

    def __init__(self, value: float, taus, shares, scales) -> None:
        self.value, self.taus, self.shares, self.scales = value, list(taus), list(shares), tuple(scales)


def _model(kind: str, fit: _Fit, reml: Reml, rule: str = "reml", **kw) -> NoiseModel:
    return NoiseModel(kind=kind, tau=tuple(fit.taus), scale=fit.scales, rule=rule, share=tuple(fit.shares),
                      sigma=_sigma(reml, fit.taus, fit.scales, fit.shares), extra={"neg2_reml": fit.value}, **kw)


def _auto(reml: Reml, gm: _Fit, lo: float, hi: float, xatol: float) -> NoiseModel:
    """``auto`` after the Gauss-Markov fit of every axis (module notes): the nested tests per axis."""
    search = _Search(reml, lo, hi, xatol, free=True)
    # white against Gauss-Markov per axis; the ratio with the other axes held is an upper bound of
    # the one with them refitted: refit only where it matters
    lr = []
    for j in range(3):
        tt = list(gm.taus)
        tt[j] = None
        quick = reml.fit_scales(tt, gm.scales)[0] - gm.value
        if np.isfinite(quick) and (quick < 0.5 * AUTO_LR or quick > 20.0 * AUTO_LR):
            lr.append(max(quick, 0.0))
            continue
        val_j = search.run([k != j for k in range(3)], gm.taus, polish_only=True).value
        lr.append(max(val_j - gm.value, 0.0) if np.isfinite(val_j) else np.inf)  # -2 ln Lambda_a
    corr = [lr[j] > AUTO_LR for j in range(3)]
    taus0 = [gm.taus[j] if corr[j] else None for j in range(3)]
    cur = search.run(corr, taus0, polish_only=True) if (any(corr) and not all(corr)) else \
        _Fit(*_value_scales(reml, taus0, gm.scales))
    # what the data cannot tell apart: the richer kind where the simpler one does not beat it at its probe
    probe = _undecided(reml, search, cur, corr)
    forced = [v is not None for v in probe]
    if any(f and not c for f, c in zip(forced, corr)):  # white axes undecided: Gauss-Markov searched afresh
        corr = [c or f for c, f in zip(corr, forced)]
        cur = search.run(corr, [gm.taus[j] if corr[j] else None for j in range(3)])
    # Gauss-Markov plus white against Gauss-Markov on the Gauss-Markov axes
    lr_white: list[float | None] = [None, None, None]
    tried = [corr[j] and (forced[j] or _whitened_p(reml, cur, j) < SCREEN_P) for j in range(3)]
    if any(tried):
        mix = search.run(corr, cur.taus, tried, scales=cur.scales, polish_only=not any(forced))
        keep_w = [False] * 3
        for j in range(3):
            if not tried[j]:
                continue
            null = search.run(corr, mix.taus, [c and k != j for k, c in enumerate(tried)],
                              shares=[0.0 if k == j else w for k, w in enumerate(mix.shares)],
                              scales=mix.scales, polish_only=True, only=j)
            lr_j = max(null.value - mix.value, 0.0) if np.isfinite(null.value) else float("inf")
            lr_white[j], keep_w[j] = lr_j, lr_j > AUTO_LR or forced[j]
        if any(keep_w):
            shares = [mix.shares[j] if keep_w[j] else 0.0 for j in range(3)]
            cur = search.run(corr, mix.taus, keep_w, shares=shares, scales=mix.scales, polish_only=True)
    # one common scale unless the axis scales are significant
    one = _Search(reml, lo, hi, xatol, free=False).run(corr, cur.taus, [w > 0 for w in cur.shares],
                                                       shares=cur.shares, polish_only=True)
    lr_scale = max(one.value - cur.value, 0.0) if np.isfinite(one.value - cur.value) else 0.0
    chosen = cur if lr_scale > AUTO_LR_SCALE else one
    model = _model("auto", chosen, reml, lr=tuple(float(v) for v in lr), lr_scale=float(lr_scale),
                   lr_white=tuple(lr_white))
    if any(v is not None and v >= 0.0 for v in probe):  # said where the simpler kind fits better, not enough
        model.extra["undecided"] = _warn_undecided(reml, [v if v is not None and v >= 0.0 else None
                                                          for v in probe], lr)
    return model


#: ``auto``: probes of the next richer kind on an axis the tests left at the simpler one. A white axis
#: is probed with Gauss-Markov noise of these correlation times, in median sample spacings (a
#: correlation over 4 to 8 samples cuts the effective number of samples, and so widens the std, by
#: about as much); a Gauss-Markov axis with Gauss-Markov plus white noise of this white share (tau
#: refitted). Where the simpler kind does not beat the probe by :data:`AUTO_LR` the data cannot tell
#: the two apart: a window of few samples per correlation time, whose coefficient columns absorb the
#: slow part of the noise. The richer kind (REML) is then taken: the conservative choice, as the
#: simpler one leaves the std too small when it is wrong. On a long flight the probes are beaten by
#: tens to hundreds, so the tests' choice stands.
PROBE_SPACINGS = (4.0, 8.0)
PROBE_SHARE = 0.3


def _undecided(reml: Reml, search: _Search, cur: _Fit, corr: Sequence[bool]) -> list[float | None]:
    """Per axis the margin -2 ln Lambda by which the chosen kind beats its probe (module notes,
    :data:`PROBE_SPACINGS`), where it is below :data:`AUTO_LR`; None where the choice stands. A negative
    margin is a probe the likelihood prefers (a white part the screen let pass, glitches): taken, not said."""
    dt = float(np.median(np.diff(reml.t)))
    out: list[float | None] = [None, None, None]
    for j in range(3):
        if corr[j] and cur.shares[j] > 0:
            continue
        if corr[j]:
            sh = [PROBE_SHARE if k == j else w for k, w in enumerate(cur.shares)]
            vals = [search.run(corr, cur.taus, shares=sh, scales=cur.scales, only=j).value]
        else:
            vals = []
            for m in PROBE_SPACINGS:
                tt = list(cur.taus)
                tt[j] = m * dt
                vals.append(reml.fit_scales(tt, cur.scales)[0])
        margin = min(vals) - cur.value
        if np.isfinite(margin) and margin < AUTO_LR:
            out[j] = float(margin)
    return out


def _warn_undecided(reml: Reml, probe: Sequence[float | None], lr: Sequence[float]) -> dict:
    """The :class:`~casep.exceptions.UndecidedNoiseWarning` of the axes the probes left undecided; their numbers."""
    import warnings

    from casep.exceptions import UndecidedNoiseWarning
    from casep.noise.model import AXES

    dt = float(np.median(np.diff(reml.t)))
    span = float(reml.t[-1] - reml.t[0])
    info = {AXES[j]: {"probe_margin": probe[j], "lr_gm": float(lr[j])} for j in range(3) if probe[j] is not None}
    taus = "/".join(f"{m * dt:.3g}" for m in PROBE_SPACINGS)
    axes = ", ".join(f"{a} (margin {v['probe_margin']:.2f})" for a, v in info.items())
    warnings.warn(UndecidedNoiseWarning(
        f"{reml.pb.source}: noise auto: {reml.N} samples over {span:.3g} s for {reml.p} estimable combinations "
        f"cannot tell the noise kinds apart on axes {axes}: the simpler kind beats Gauss-Markov noise of tau "
        f"{taus} s (or a white share {PROBE_SHARE:g}) by -2 ln Lambda below {AUTO_LR:g}; Gauss-Markov plus white "
        "taken there, the conservative choice (the simpler kind leaves the std too small when it is wrong)"),
        stacklevel=4)
    return info


#: ``auto``: the white part is tried on a Gauss-Markov axis when the residuals whitened by the
#: Gauss-Markov fit fail a Ljung-Box test at this level (a white part makes them correlated: lag-1
#: covariance ``-a_k w``); it is then kept only by the likelihood-ratio test at 1 %, so the
#: screen costs no size and little power, and spares the filter passes on plain Gauss-Markov data.
SCREEN_P = 0.2


def _whitened_p(reml: Reml, fit: _Fit, j: int) -> float:
    """Ljung-Box p-value of axis j's residuals whitened by `fit` (Gauss-Markov on that axis)."""
    from casep.noise.whiteness import default_lags, ljung_box

    _, T = reml.evaluate(fit.taus, fit.scales, fit.shares)
    if T is None:
        return 1.0
    p = reml.p
    v = np.concatenate([np.linalg.solve(T[:p, :p], T[:p, p]), [-1.0]])  # (beta, -1) in the basis Z
    u = whiten_series((reml.Z[j] @ v)[:, None], reml.t, fit.taus[j], fit.shares[j])[0][:, 0]
    return ljung_box(u, default_lags(u.size))[1]


def _value_scales(reml: Reml, taus, scales) -> tuple[float, list, list, tuple]:
    val, sc = reml.fit_scales(taus, scales)
    return val, list(taus), [0.0, 0.0, 0.0], sc


#: What the searches see where the likelihood is not finite (a rounding-level residual).
_NO_LIKELIHOOD = 1e300


class _Search:
    """Minimise -2 l_R over ln tau (and the white share's logit) per axis, coordinate-wise, the axis
    scales at their fixed point (or one common scale when not `free`).

    Without a start, one common tau is found first over the whole interval; then each axis' tau is
    searched in turn within a factor 4 of its current value (widened when the minimum lands on an
    edge), and once more within 25 %; on an axis with a white part tau and the share's logit
    together (Nelder-Mead: they trade along a ridge). The axis scales are at their fixed point at
    every trial.
    """

    def __init__(self, reml: Reml, lo: float, hi: float, xatol: float, *, free: bool, fixed_tau: bool = False):
        self.reml, self.lo, self.hi, self.xatol, self.free, self.fixed_tau = reml, lo, hi, xatol, free, fixed_tau
        self.scales: tuple | None = None

    def value(self, taus, shares) -> float:
        """-2 l_R with the axis scales at their fixed point (started from the last one)."""
        v, sc = self.reml.fit_scales(taus, self.scales, free=self.free, shares=shares)
        if np.isfinite(v):
            self.scales = sc
        return v if np.isfinite(v) else _NO_LIKELIHOOD  # the search needs finite values

    def rescale(self, taus, shares) -> None:
        """The axis scales at their fixed point for the current taus and shares."""
        v, sc = self.reml.fit_scales(taus, self.scales, free=self.free, shares=shares)
        if np.isfinite(v):
            self.scales = sc

    def run(self, corr: Sequence[bool], start: Sequence[float | None] | None = None,
            mixed: Sequence[bool] = (False, False, False), *, shares: Sequence[float] | None = None,
            scales=None, polish_only: bool = False, only: int | None = None) -> _Fit:
        """The minimum with Gauss-Markov on the axes `corr`, a white share searched on the axes `mixed`
        (else held at `shares`, default 0); `only`: search that axis alone."""
        self.scales = None if scales is None else tuple(scales)
        ww = [float(shares[j]) if shares is not None and corr[j] and not mixed[j] else 0.0 for j in range(3)]
        for j in range(3):
            if mixed[j] and shares is not None and shares[j] > 0:
                ww[j] = float(shares[j])
            elif mixed[j]:
                ww[j] = 0.1  # a start inside the interval
        lo, hi = self.lo, self.hi
        if not any(corr):
            v, sc = self.reml.fit_scales([None, None, None], free=self.free)
            return _Fit(v, [None, None, None], [0.0] * 3, sc)
        if start is None:
            x = bounded_minimum(lambda x: self.value([float(np.exp(x)) if c else None for c in corr], ww),
                                lo, hi, self.xatol)
            taus = [float(np.exp(x)) if c else None for c in corr]
        else:
            taus = [(start[j] if start[j] is not None else float(np.exp(lo))) if corr[j] else None
                    for j in range(3)]
        widths = ((np.log(1.25), 1.0),) if polish_only else ((np.log(4.0), 4.0), (np.log(1.25), 1.0))
        axes = [j for j in range(3) if corr[j] and (only is None or j == only)]
        for w, wv in widths:
            for j in axes:
                if mixed[j] and not self.fixed_tau:  # tau and the white share trade along a ridge: jointly
                    taus[j], ww[j] = self._both(j, taus, ww, w)
                else:
                    if not self.fixed_tau:
                        taus[j] = self._tau(j, taus, ww, w)
                    if mixed[j]:
                        ww[j] = self._share(j, taus, ww, wv)
                self.rescale(taus, ww)
        v, sc = self.reml.fit_scales(taus, self.scales, free=self.free, shares=ww)
        return _Fit(v if v < _NO_LIKELIHOOD else np.inf, taus, ww, sc)

    def _tau(self, j: int, taus: list, ww: list, w: float) -> float:
        lo, hi, xatol = self.lo, self.hi, self.xatol
        x0 = float(np.log(taus[j] or np.exp(lo)))
        a, b = max(lo, x0 - w), min(hi, x0 + w)
        x = x0
        for _ in range(20):
            def f(x, j=j):
                tt = list(taus)
                tt[j] = float(np.exp(x))
                return self.value(tt, ww)
            x = float(bounded_minimum(f, a, b, xatol))
            edge = 3 * xatol
            if x - a < edge and a > lo:
                a, b = max(lo, a - 2 * w), a + edge
            elif b - x < edge and b < hi:
                a, b = b - edge, min(hi, b + 2 * w)
            else:
                break
        return float(np.exp(x))

    def _both(self, j: int, taus: list, ww: list, w: float) -> tuple[float, float]:
        """(tau, white share) of axis j by Nelder-Mead in (ln tau, logit w), inside the search intervals."""
        box = np.array([[self.lo, self.hi], SHARE_LOGIT])

        def f(z):
            z = np.clip(z, box[:, 0], box[:, 1])
            tt, w2 = list(taus), list(ww)
            tt[j], w2[j] = float(np.exp(z[0])), 1.0 / (1.0 + math.exp(-z[1]))
            return self.value(tt, w2)
        z0 = np.array([math.log(taus[j]), math.log(ww[j] / (1.0 - ww[j]))])
        z = np.clip(nelder_mead(f, z0, np.array([max(w, 0.5), 2.0]), 2.0 * self.xatol, maxfun=150),
                    box[:, 0], box[:, 1])
        return float(np.exp(z[0])), 1.0 / (1.0 + math.exp(-z[1]))

    def _share(self, j: int, taus: list, ww: list, wv: float) -> float:
        lo, hi = SHARE_LOGIT
        v0 = float(np.log(ww[j] / (1.0 - ww[j])))

        def f(v):
            w2 = list(ww)
            w2[j] = 1.0 / (1.0 + math.exp(-v))  # w = 1 / (1 + e^-v)
            return self.value(taus, w2)
        v = float(bounded_minimum(f, max(lo, v0 - wv), min(hi, v0 + wv), self.xatol))
        return 1.0 / (1.0 + math.exp(-v))


def nelder_mead(func: Callable[[np.ndarray], float], x0: np.ndarray, step: np.ndarray, xatol: float,
                maxfun: int = 400) -> np.ndarray:
    """Minimiser of `func` near `x0` by the Nelder-Mead simplex (reflection 1, expansion 2, contraction
    1/2, shrink 1/2), the first simplex ``x0`` and ``x0 + step_i e_i``; stops when every vertex is
    within `xatol` of the best in every coordinate, or after `maxfun` evaluations."""
    n = x0.size
    X = np.vstack([x0] + [x0 + step[i] * np.eye(n)[i] for i in range(n)])
    F = np.array([func(x) for x in X])
    nf = n + 1
    while nf < maxfun:
        o = np.argsort(F)
        X, F = X[o], F[o]
        if np.max(np.abs(X[1:] - X[0])) <= xatol:
            break
        c = X[:-1].mean(axis=0)  # centroid of all but the worst
        xr = c + (c - X[-1])
        fr = func(xr)
        nf += 1
        if fr < F[0]:
            xe = c + 2.0 * (c - X[-1])
            fe = func(xe)
            nf += 1
            X[-1], F[-1] = (xe, fe) if fe < fr else (xr, fr)
        elif fr < F[-2]:
            X[-1], F[-1] = xr, fr
        else:
            xc = c + 0.5 * ((xr if fr < F[-1] else X[-1]) - c)  # outside or inside contraction
            fc = func(xc)
            nf += 1
            if fc < min(fr, F[-1]):
                X[-1], F[-1] = xc, fc
            else:  # shrink towards the best
                X[1:] = X[0] + 0.5 * (X[1:] - X[0])
                F[1:] = [func(x) for x in X[1:]]
                nf += n
    return X[int(np.argmin(F))]


def bounded_minimum(func: Callable[[float], float], a: float, b: float, xatol: float, maxfun: int = 500) -> float:
    """Minimiser of `func` on ``[a, b]`` by Brent's bounded method (golden section with parabolic steps).

    The algorithm and the numbers of ``scipy.optimize.minimize_scalar(func, bounds=(a, b),
    method="bounded", options={"xatol": xatol}).x`` (the same steps and function values,
    ``tests/noise/test_bounded_minimum.py``), without importing ``scipy.optimize`` (0.2 s, most of the
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


def _sigma(reml: Reml, taus, scales, shares=(0.0, 0.0, 0.0)) -> float:
    """REML sigma of the x axis: sqrt(RSS_w / (m - p))."""
    _, T = reml.evaluate(taus, scales, shares)
    if not isinstance(T, np.ndarray):
        return float("nan")
    return float(abs(T[reml.p, reml.p]) / np.sqrt(3 * reml.N - reml.p))


def with_kind(noise: NoiseModel, kind: str) -> NoiseModel:
    """The same fitted model relabelled with what was asked."""
    return replace(noise, kind=kind)

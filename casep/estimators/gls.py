"""Generalised least squares for first-order Gauss-Markov (AR(1)) tracking noise, with a white part.

Notes
-----
Each axis' noise is stationary Gauss-Markov with correlation time ``tau``, plus (when the data
ask for it) white measurement noise of variance share ``w`` (one ``tau`` and one ``w`` for every
axis). With ``a_k = exp(-(t_k - t_{k-1}) / tau)`` the whitening of :mod:`casep.noise.model`
(``w = 0``: ``w_0 = e_0``, ``w_k = (e_k - a_k e_{k-1}) / sqrt(1 - a_k^2)``; ``w > 0``: the
innovations of the Kalman filter) turns the noise white, so least squares on the whitened ``S``
and ``dv`` is the GLS estimate with its honest covariance ``sigma^2 (S^T Sigma^-1 S)^-1``, which
attains the Cramer-Rao bound.

``tau="auto"`` also tests a white part: ``w`` by REML in (ln tau, logit w) from the
Gauss-Markov optimum, kept when ``-2 ln Lambda`` against ``w = 0`` exceeds
:data:`casep.noise.model.AUTO_LR` (w = 0 on the boundary: null ``(chi2_0 + chi2_1) / 2``, 1 %).
Without it GM-plus-white data is fitted as one short correlation time and the std are about 2x
too small. A given ``tau`` means pure Gauss-Markov with that tau.

``tau="auto"`` estimates ``tau`` by restricted maximum likelihood (REML), which accounts
for the degrees of freedom the regression absorbs (the lag-1 autocorrelation of OLS
residuals underestimates tau by ~13 % here, and iterating does not help)::

    -2 l_R(tau, w) = (m - p) ln RSS_w + 3 sum_k ln F_k + ln det(S_w^T S_w) + const

(``F_k = 1 - a_k^2`` for ``w = 0``, the innovation variances of the filter otherwise)

with ``S_w``, ``RSS_w`` from the unit-sigma whitening; minimised over ``ln tau`` in
[median(dt) / 5, duration]. A ``tau`` at the lower end is white noise in effect (GLS = OLS).
Measured (60 runs, paper-ar1 at 20 Hz, tau 1 s): tau 0.99 +- 0.06, coverage of the 95 %
intervals 0.947 (OLS with white-noise std: 0.24).

Why it matters (``docs/results/cramer-rao.md``): with tau = 1 s at 100 Hz the white-noise std of
OLS cover the truth in 11 % of runs instead of 95 %.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Mapping, Sequence, Unpack

import numpy as np

from casep.estimators._base import Prepared, finish, prepare
from casep.estimators._options import Choices, Interval, Labels, Method, Option, SeveralFlights
from casep.estimators.ols import OLS, least_squares
from casep.noise.fit import SHARE_LOGIT, nelder_mead, tau_search_bounds  # one search of both REMLs
from casep.noise.model import AUTO_LR, NoiseModel, whiten_series
from casep.regression.problem import Problem

if TYPE_CHECKING:
    from casep.estimators.result import EstimateResult
    from casep.regression.joint import JointProblem

__all__ = ["solve_gls", "estimate_tau", "estimate_noise", "GLS", "GLSExtras"]

#: Its option (``casep separate --tau``; the noise model's tau for every other method).
TAU = Option("tau", "--tau", "auto", (Choices(("auto",)), Interval(float, 0, 1e4, "right", "s")),
             "Gauss-Markov correlation time of the noise model, every method (auto: REML)",
             # Correlation times beyond ~3 h exceed any boost flight; exp(-dt/tau) -> 1 loses all digits.
             why="s; a correlation time above 1e4 s exceeds any flight")


@dataclass(frozen=True)
class GLSExtras:
    """GLS: the Gauss-Markov correlation time tau (s) used and where it came from ("given", "reml");
    with several flights, each flight's own (``flight_taus``, label -> s) and ``tau`` their mean.
    ``settings["tau"]`` holds what was asked: "auto" or the given tau. ``white_share``: the white
    part's share of the noise variance (0: pure Gauss-Markov)."""

    tau: float
    tau_rule: str
    flight_taus: dict[str, float] | None = None
    white_share: float = 0.0

    def describe(self, res: Any) -> list[str]:
        """Its part of the settings line."""
        how = "REML estimate" if self.tau_rule == "reml" else "given"
        if self.flight_taus:
            each = ", ".join(f"{k} {v:.4g}" for k, v in self.flight_taus.items())
            return [f"Gauss-Markov tau per flight ({how}): {each} s"]
        white = f" plus white (share {self.white_share:.3g} of the variance)" if self.white_share else ""
        return [f"Gauss-Markov tau {self.tau:.4g} s ({how}){white}"]

    @staticmethod
    def old_form(settings: dict, diagnostics: dict, extras: dict | None) -> tuple[dict, dict, dict | None]:
        """A result file of an earlier casep: ``settings["tau"]`` was the tau found (a number, or per
        flight a dict) and ``settings["tau_rule"]`` its rule; read as the input asked and the extras."""
        if "tau_rule" not in settings:
            return settings, diagnostics, extras
        settings = dict(settings)
        rule, tau = settings.pop("tau_rule"), settings.get("tau")
        per = tau if isinstance(tau, dict) else None
        taus: list[Any] = list(per.values()) if per else [tau]
        if extras is None and all(isinstance(v, (int, float)) for v in taus):
            extras = {"tau": float(np.mean([float(v) for v in taus])), "tau_rule": rule, "flight_taus": per}
        elif extras is not None and per and extras.get("flight_taus") is None:
            extras = {**extras, "flight_taus": per}
        settings["tau"] = "auto" if rule == "reml" else taus[0]
        return settings, diagnostics, extras


def _whiten_axes(S: np.ndarray, t: np.ndarray, tau: float, share: float = 0.0) -> tuple[np.ndarray, float]:
    """(N, 3, k) rows whitened per axis at unit std (:func:`casep.noise.model.whiten_series`), sum ln F."""
    W = np.empty(S.shape)
    ld = 0.0
    for j in range(3):
        W[:, j, :], ldj, _ = whiten_series(S[:, j, :], t, tau, share)
        ld += ldj
    return W, ld


def _whiten(S: np.ndarray, y: np.ndarray, t: np.ndarray, tau: float, share: float = 0.0
            ) -> tuple[np.ndarray, np.ndarray]:
    W = _whiten_axes(np.concatenate([S, y[:, :, None]], axis=2), t, tau, share)[0]
    return W[:, :, :-1], W[:, :, -1]


def _neg2_reml(S: np.ndarray, Y: np.ndarray, t: np.ndarray, tau: float, share: float = 0.0) -> np.ndarray:
    """-2 l_R(tau, w) + const of each column of ``Y`` (module notes), one factorisation for all.

    Parameters
    ----------
    S : (N, 3, p) regression; Y : (N, 3, k) velocity errors, one run per column.

    Notes
    -----
    One QR of ``[Z  Y_w]`` (``Z``: whitened ``S`` scaled to unit columns, zero columns
    dropped): the diagonal of its leading block gives ``ln det(S_w^T S_w)`` and the column
    norms of its trailing block ``R_22`` the residual sums ``RSS_w`` of every run, with no
    cancellation.
    """
    N, _, p = S.shape
    W, logF = _whiten_axes(np.concatenate([S, Y], axis=2), t, tau, share)  # logF = 3 sum_k ln F_k
    Sw = W[:, :, :p].reshape(-1, p)
    c = np.sqrt(np.einsum("ij,ij->j", Sw, Sw))  # column norms of S_w
    live = c > 0
    Yw = W[:, :, p:].reshape(-1, Y.shape[-1])
    q = int(live.sum())
    R = np.asarray(np.linalg.qr(np.hstack([Sw[:, live] / c[live], Yw]), mode="r"))  # [Z Y_w] = Q R
    d = np.abs(np.diag(R)[:q])
    ok = d > 0
    logdet = 2.0 * np.sum(np.log(d[ok])) + 2.0 * np.sum(np.log(c[live][ok]))  # ln det(S_w^T S_w)
    rss = np.einsum("ij,ij->j", R[q:, q:], R[q:, q:])  # ||(I - P_Z) y_w||^2 = column norms of R_22
    return (3 * N - p) * np.log(rss) + logF + logdet


class _Reml:
    """:func:`_neg2_reml` of fixed ``S``, ``Y`` and ``t`` at any ``(tau, w)``, what does not depend on them formed
    once: a search evaluates it at 15 to 120 points.

    Notes
    -----
    ``S`` at unit columns is factored once, ``S / c = Q R0``; whitening acts on each axis' time series,
    so it commutes with the column map, ``(S / c)_w = Q_w R0``, and

        ln det(S_w^T S_w) = ln det(Q_w^T Q_w) + 2 sum ln |R0_jj| + 2 sum ln c_j.

    ``Y`` is replaced by its residuals ``Y - Q Q^T Y``: a multiple of ``S`` added to ``y`` leaves every
    ``RSS_w`` unchanged. Each evaluation then whitens ``[Q  Y_r]`` (each axis contiguous) and forms its
    Gram matrix ``M``: ``Q`` has orthonormal columns before whitening, so ``M`` is well conditioned (the
    REML of :mod:`casep.noise.fit` uses it the same way), ``ln det(Q_w^T Q_w)`` is twice the log-diagonal of
    the Cholesky factor ``L`` of ``M_QQ`` and ``RSS_w = diag(M_YY) - colsum((L^-1 M_QY)^2)``, where the
    residuals make the subtracted part small (no cancellation). It replaces a QR of the whole
    ``3N x (p + k)`` whitened matrix by a Gram matrix and a ``p x p`` Cholesky: the same values to ~1e-9
    (``tests/estimators/test_gls.py``), a third of the CPU time.
    A rank-deficient ``S`` (``R0`` with a diagonal below 1e-10 of its largest) is evaluated by
    :func:`_neg2_reml` itself.
    """

    def __init__(self, S: np.ndarray, Y: np.ndarray, t: np.ndarray) -> None:
        self.S, self.Y, self.t = S, Y, t
        N, _, p = S.shape
        k = Y.shape[-1]
        S2 = S.reshape(-1, p)
        c = np.sqrt(np.einsum("ij,ij->j", S2, S2))
        live = c > 0
        Q, R0 = np.linalg.qr(S2[:, live] / c[live])
        d0 = np.abs(np.diag(R0))
        self.full = bool(d0.size) and bool(d0.min() > 1e-10 * d0.max())
        if not self.full:
            return
        self.q, self.m_p = int(live.sum()), 3 * N - p
        self.const = 2.0 * float(np.sum(np.log(d0)) + np.sum(np.log(c[live])))
        Y2 = Y.reshape(-1, k)
        X = np.concatenate([Q, Y2 - Q @ (Q.T @ Y2)], axis=1).reshape(N, 3, self.q + k)
        self.axes = [np.ascontiguousarray(X[:, j, :]) for j in range(3)]

    def __call__(self, tau: float, share: float = 0.0) -> np.ndarray:
        """-2 l_R(tau, w) + const of each column of ``Y`` (the constant :func:`_neg2_reml`'s)."""
        if not self.full:
            return _neg2_reml(self.S, self.Y, self.t, tau, share)
        q = self.q
        M = np.zeros((self.axes[0].shape[1],) * 2)
        logF = 0.0
        for X in self.axes:
            W, ld, _ = whiten_series(X, self.t, tau, share)
            M += W.T @ W
            logF += ld
        try:
            L = np.linalg.cholesky(M[:q, :q])
        except np.linalg.LinAlgError:
            return _neg2_reml(self.S, self.Y, self.t, tau, share)
        V = np.linalg.solve(L, M[:q, q:])
        rss = np.diagonal(M[q:, q:]) - np.einsum("ij,ij->j", V, V)
        logdet = 2.0 * float(np.sum(np.log(np.diagonal(L)))) + self.const
        return self.m_p * np.log(rss) + logF + logdet


def estimate_tau(S: np.ndarray, y: np.ndarray, t: np.ndarray) -> float:
    """REML estimate of the Gauss-Markov correlation time (see module notes), s."""
    return _tau_search(_Reml(S, np.asarray(y, dtype=float).reshape(S.shape[0], 3, 1), t))


def _tau_search(reml: _Reml) -> float:
    """:func:`estimate_tau` with its objective formed."""
    from scipy.optimize import minimize_scalar

    res = minimize_scalar(lambda x: float(reml(float(np.exp(x)))[0]), bounds=tau_search_bounds(reml.t),
                          method="bounded", options={"xatol": 1e-4})
    return float(np.exp(res.x))


def estimate_noise(S: np.ndarray, y: np.ndarray, t: np.ndarray) -> tuple[float, float]:
    """REML ``(tau, white share)`` (module notes): the Gauss-Markov tau, then the white part where the
    likelihood-ratio test keeps it (share 0 otherwise)."""
    reml = _Reml(S, np.asarray(y, dtype=float).reshape(S.shape[0], 3, 1), t)
    tau = _tau_search(reml)
    lo, hi = tau_search_bounds(t)
    box = np.array([[lo, hi], SHARE_LOGIT])

    def f(z: np.ndarray) -> float:
        z = np.clip(z, box[:, 0], box[:, 1])
        return float(reml(float(np.exp(z[0])), 1.0 / (1.0 + np.exp(-z[1])))[0])
    z = np.clip(nelder_mead(f, np.array([np.log(tau) + 1.0, np.log(0.1 / 0.9)]), np.array([1.0, 2.0]), 1e-3),
                box[:, 0], box[:, 1])
    lr = float(reml(tau)[0]) - f(z)  # -2 ln Lambda of the white part
    if not lr > AUTO_LR:
        return tau, 0.0
    return float(np.exp(z[0])), float(1.0 / (1.0 + np.exp(-z[1])))


def solve_gls(S: np.ndarray | Problem, y: np.ndarray | None = None, t: np.ndarray | None = None, *,
              tau: float | str = "auto", **labels: Unpack[Labels]) -> EstimateResult:
    """GLS estimate of ``D`` under Gauss-Markov noise of correlation time `tau`.

    Parameters
    ----------
    S : (N, 3, n) array_like or Problem
        Regression in natural units, samples in time order (a Problem holds its times).
    y : (N, 3) array_like
        Velocity error, m/s.
    t : (N,) array_like
        Sample times, s.
    tau : float or "auto", optional
        Correlation time, s, or its REML estimate (default).
    **labels
        ``names``, ``units``, ``si_factors``, ``rcond`` as :func:`casep.solve_ols`; ``sigma``:
        stationary noise std, m/s (default: from the whitened residuals).

    Returns
    -------
    EstimateResult
        ``method`` "gls"; residuals are ``dv - S_V D_hat`` (not whitened); diagnostics
        (condition numbers, CRLB) are those of the whitened regression.
    """
    if isinstance(S, Problem) and t is not None and S.t is None:
        S = Problem.from_arrays(S.sv(), S._need_rows(), t, names=S.names, units=S.units, si_factors=S.si_factors,
                                model=S.model)
    return GLS.call(S, y, None if isinstance(S, Problem) else t, tau=tau, **labels)


def _solve(pb: Prepared, *, method: Method, tau: float | str) -> EstimateResult:
    problem = pb.problem
    S, t = problem.sv(), problem.t
    if S.ndim != 3 or S.shape[1] != 3:
        raise ValueError(f"`S` must be (N, 3, n) in time order, got shape {S.shape}")
    if t is None:
        raise ValueError("`t` is required (the sample times)")
    if np.any(np.diff(t) <= 0):
        raise ValueError("`t` must be strictly increasing")
    y = np.asarray(problem.y, dtype=float).reshape(S.shape[0], 3)
    if isinstance(tau, str):
        (tau_used, share), rule = estimate_noise(S, y, t), "reml"
    else:
        tau_used, share, rule = float(tau), 0.0, "given"
    pw = prepare(*_whiten(S, y, t, tau_used, share), pb.names, pb.units, pb.si_factors, pb.sigma, pb.ra.rcond,
                 model=problem.model)
    x, cov, sig = least_squares(pw)  # sigma: whitened residual std = stationary sigma
    fit = y - S @ x  # dv - S_V D_hat, not whitened
    return finish(pw, method, x, cov, sig, residuals=fit.reshape(-1),
                  settings={"tau": tau, "sigma": "estimated" if pb.sigma is None else pb.sigma},  # inputs
                  extras=GLSExtras(float(tau_used), rule, white_share=share))  # found (REML) or the given tau


def _noise_model(res: EstimateResult) -> NoiseModel:
    """The noise model GLS fitted: one Gauss-Markov tau (and white share) for every axis."""
    w = float(getattr(res.extras, "white_share", 0.0))
    return NoiseModel(kind="gmw" if w else "gm", tau=(res.extras.tau,) * 3, rule=res.extras.tau_rule, share=(w,) * 3)


# ------------------------------------------------------------------ several flights
def _flight_rows(problems: Sequence[Problem], options: Mapping[str, Any], noise: str,
                 robust: str | None) -> tuple[list[Problem], list[float]]:
    """Each flight's rows whitened by its own Gauss-Markov correlation time (REML per flight, or the given tau)."""
    if robust not in (None, "auto", "none") or noise == "white":
        raise ValueError("method `gls` is ols with one Gauss-Markov tau per flight: for noise 'white' or a robust "
                         "fit use method ols with `noise` and `robust`")
    tau = options.get("tau", "auto")
    out, taus = [], []
    for p in problems:
        if p.t is None:
            raise ValueError(f"flight `{p.source}` has no sample times: GLS needs them")
        S, y = p.sv(), p._need_rows().reshape(-1, 3)
        tk, share = estimate_noise(S, y, p.t) if isinstance(tau, str) else (float(tau), 0.0)
        Sw, yw = _whiten(S, y, p.t, tk, share)
        q = Problem.from_arrays(Sw, yw, p.t, names=p.names, units=p.units, si_factors=p.si_factors, model=p.model)
        q.source = p.source
        out.append(q)
        taus.append(float(tk))
    return out, taus


def _flights_finish(res: EstimateResult, jp: JointProblem, taus: list[float],
                    options: Mapping[str, Any]) -> EstimateResult:
    """The least-squares result of the whitened flights as GLS's: the tau asked in its settings, each
    flight's tau in its extras."""
    import dataclasses

    tau = options.get("tau", "auto")
    rule = "given" if not isinstance(tau, str) else "reml"
    return dataclasses.replace(
        res, method="gls", extras=GLSExtras(float(np.mean(taus)), rule, dict(zip(jp.layout.labels, taus))),
        settings={"tau": tau, "sigma": res.settings["sigma"]},
        message=res.message + f"; GLS: each flight whitened by its own tau ({rule})")


#: Lattice of the batched REML search: coarse step in ln tau, its subdivision, and the
#: half-width (fine steps) of each run's window around its predicted minimum.
_COARSE_STEP, _FINE_DIV, _WINDOW = 1.0, 8, 3


def estimate_tau_many(S: np.ndarray, Y: np.ndarray, t: np.ndarray) -> np.ndarray:
    """REML estimates of tau for many runs sharing ``S`` and ``t`` (Monte Carlo), s.

    Parameters
    ----------
    S : (N, 3, p) array_like
        Regression in natural units.
    Y : (N, 3, k) array_like
        Velocity errors of k runs, m/s.
    t : (N,) array_like
        Sample times, s.

    Returns
    -------
    (k,) ndarray
        Within ~1e-6 relative of each run's REML optimum (measured on paper-ar1; tested to
        2e-5), closer than :func:`estimate_tau`, whose search stops at 1e-4 in ln tau.

    Notes
    -----
    The whitening and factorisation at a given tau serve every run (:class:`_Reml`), so
    the runs share one lattice of ln tau instead of each running its own search: every
    ``_COARSE_STEP`` over the whole interval, then the ``_FINE_DIV`` times finer lattice around
    the minimum each run's coarse values predict, widened until the run's lattice minimum is
    inside (the runs' minima cluster, so few points are added), then the minimum of the
    degree-6 polynomial through the seven lattice values around each run's lattice minimum.
    A minimum on an end of the interval is taken as that end, as the bounded search does.
    """
    S = np.asarray(S, dtype=float)
    Y = np.asarray(Y, dtype=float)
    lo, hi = tau_search_bounds(t)
    nf = _FINE_DIV * max(1, int(np.ceil((hi - lo) / _COARSE_STEP)))
    step = (hi - lo) / nf  # x_j = lo + j step, j = 0..nf
    f: dict[int, np.ndarray] = {}
    reml = _Reml(S, Y, t)

    def ensure(js) -> None:
        for j in sorted(set(js) - f.keys()):
            f[j] = reml(float(np.exp(lo + j * step)))

    k = Y.shape[-1]

    def around(j: int, w: int) -> range:  # lattice indices j-w..j+w inside the interval
        return range(max(0, j - w), min(nf, j + w) + 1)

    def values(j: int, r: int) -> list[float]:  # run r's values at j-3..j+3 (NaN: not there)
        return [float(f[i][r]) if i in f else np.nan for i in range(j - 3, j + 4)]

    ensure(range(0, nf + 1, _FINE_DIV))
    coarse = np.array(sorted(f))
    ic = np.argmin(np.array([f[j] for j in coarse]), axis=0)  # each run's coarse minimum
    centre = [int(coarse[i]) + int(round(_FINE_DIV * _lattice_vertex(
        [f[int(coarse[i + d])][r] if 0 <= i + d < coarse.size else np.nan for d in range(-3, 4)])))
        for r, i in enumerate(ic)]  # its predicted fine-lattice minimum
    best = list(centre)
    for _ in range(nf + 1):  # widen each run's window until its lattice minimum is inside
        ensure(j for c in set(centre) for j in around(c, _WINDOW))
        moved = False
        for r in range(k):
            js = around(centre[r], _WINDOW)
            best[r] = min(js, key=lambda j: f[j][r])
            if best[r] in (js[0], js[-1]) and 0 < best[r] < nf:
                centre[r], moved = best[r], True
        if not moved:
            break
    ensure(j for b in set(best) for j in around(b, 3))  # the seven values of the vertex
    return np.exp([lo + (b + _lattice_vertex(values(b, r))) * step for r, b in enumerate(best)])


def _lattice_vertex(v: Sequence[float]) -> float:
    """Offset (in steps, within [-1, 1]) of the minimum of the polynomial through lattice values.

    `v` holds the values at offsets -h..h (odd length, NaN beyond an end of the interval):
    the polynomial through all the finite ones (degree 2h inside the interval), 0 when the
    middle value is an end of the interval.
    """
    va = np.asarray(v, dtype=float)
    h = va.size // 2
    if not (np.isfinite(va[h - 1]) and np.isfinite(va[h + 1])):
        return 0.0  # minimum on an end of the interval
    u = np.arange(-h, h + 1.0)
    use = np.isfinite(va)  # contiguous: NaN only beyond an end
    P = np.polynomial.Polynomial.fit(u[use], va[use], int(use.sum()) - 1, domain=[-1, 1], window=[-1, 1])
    d1, d2 = P.deriv(), P.deriv(2)
    cand = [0.0]
    for root in d1.roots():
        z = float(np.real(root))
        for _ in range(3):  # Newton on P' = 0: roots with a tiny leading term are loose
            z -= float(d1(z) / d2(z)) if d2(z) != 0 else 0.0
        if -1.0 <= z <= 1.0:
            cand.append(z)
    return float(min(cand, key=lambda z: float(P(z))))


def _shared_taus(S: np.ndarray, Y: np.ndarray, t: np.ndarray) -> list[dict[str, Any]]:
    """Monte Carlo: each run's REML tau from one lattice for the runs sharing `S` and `t`."""
    return [{"tau": float(tau)} for tau in estimate_tau_many(S, Y, t)]


#: GLS: least squares in Gauss-Markov noise (its own noise model: one tau for every axis).
GLS = Method("gls", "least squares in Gauss-Markov noise (AR(1) whitening)", _solve, "solve_gls", (TAU,),
             needs_time=True, extras_type=GLSExtras, own_noise_model=_noise_model, noise_in_time=True,
             shared_options=_shared_taus, max_runs_per_task=16,
             flights=SeveralFlights(rows=_flight_rows, solve_as=OLS, finish=_flights_finish))

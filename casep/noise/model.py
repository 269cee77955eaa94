"""The noise of the regression rows per axis: white, Gauss-Markov, or Gauss-Markov plus white, fitted by REML.

Tracking noise on a range is coloured: the velocity a radar or an optical track delivers is
smoothed, and its error is close to first-order Gauss-Markov (AR(1) on the sample times) with a
correlation time of about a second, usually with a white measurement noise on top. Least squares
with a white-noise std is then several times overconfident, and a Gauss-Markov model without the
white part is too (it fits a short correlation time to the mixture). The noise model belongs to
the data, so every estimator solves on the same whitened rows
(:meth:`casep.regression.problem.Problem.whitened`).

Model
-----
Axis ``a`` (x, y, z) of the velocity error has stationary std ``sigma_a = sigma r_a`` (``r_x = 1``)
and is the sum of a Gauss-Markov part ``g`` (variance share ``1 - w_a``, correlation time
``tau_a``) and a white part ``v`` (variance share ``w_a``, the *white share*)::

    e_k = g_k + v_k,    g_k = a_k g_(k-1) + sqrt(1 - a_k^2) sqrt(1 - w_a) sigma_a n_k,
    a_k = exp(-(t_k - t_(k-1)) / tau_a),    Var v_k = w_a sigma_a^2,    n_k ~ N(0, 1)

at any spacing (non-uniform, across a gap). The kinds nest: *white* (no ``g``: ``tau`` None),
*gm* (Gauss-Markov, ``w_a = 0``) and *gmw* (Gauss-Markov plus white, ``0 < w_a < 1``).

Whitening
---------
The innovations of the Kalman filter of ``g`` whiten the series exactly (the Cholesky factor of
the inverse covariance, computed recursively; never an N x N matrix). With unit ``sigma_a``::

    P_k^- = a_k^2 P_(k-1) + (1 - w)(1 - a_k^2),    F_k = P_k^- + w,    K_k = P_k^- / F_k
    u_k = (e_k - a_k m_(k-1)) / sqrt(F_k),         m_k = a_k m_(k-1) + K_k (e_k - a_k m_(k-1)),
    P_k = P_k^- w / F_k,                           (first sample: a = 0, P^- = 1 - w)

``1 - a_k^2`` is computed as ``-expm1(-2 dt_k / tau)`` (:func:`casep._kernels.ar1_terms`). The
gains depend only on the times and the parameters, so the same recursion whitens every column of
``S`` and ``dv``; least squares on the whitened rows is the GLS estimate and every estimator's std
holds. ``ln det`` of the correlation matrix is ``sum_k ln F_k``. For ``w = 0`` the recursion is
the AR(1) difference ``u_k = (e_k - a_k e_(k-1)) / sqrt(1 - a_k^2)`` (vectorised); for ``w > 0``
it runs compiled (:func:`casep._kernels.gmw_filter`). The rows are divided by ``r_a``.

The noise model is fitted by REML (:func:`casep.noise.fit.fit_noise`); the whitened
residuals are tested for whiteness by :func:`casep.noise.whiteness.whiteness_test`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, ClassVar, Iterable, Iterator, Mapping, Sequence

import numpy as np

from casep._kernels import ar1_terms, gmw_filter
from casep.results import Completed

__all__ = ["NOISE_KINDS", "AUTO_LR", "AUTO_LR_SCALE", "NoiseModel", "whiten", "whiten_blocks", "whiten_axis",
           "whiten_series", "whiten_transpose", "check_noise_kind", "check_tau", "NOISE_HELP"]

#: The noise kinds a problem can be given (the API's ``noise=`` and the command line's ``--noise``).
NOISE_KINDS = ("auto", "gm", "gmw", "white")
#: One line per kind, for the command line's help.
NOISE_HELP = ("auto (white, Gauss-Markov or Gauss-Markov plus white per axis by likelihood-ratio tests, said in "
              "the output), gm (Gauss-Markov per axis, --tau or REML), gmw (Gauss-Markov plus white per axis, "
              "REML), white (a whiteness test warns when the residuals contradict it)")
#: ``auto``: -2 ln Lambda of one nested kind against the next simpler one on one axis (Gauss-Markov
#: against white: tau on the boundary; Gauss-Markov plus white against Gauss-Markov: the white
#: share 0 on the boundary) above which the richer kind is taken: 1 % point of the null
#: distribution (chi2_0 + chi2_1) / 2 (the chi2_1 2 % point).
AUTO_LR = 5.412
#: ``auto``: -2 ln Lambda of three axis scales against one above which they are kept: chi2_2 1 % point.
AUTO_LR_SCALE = 9.210
AXES = ("x", "y", "z")


def check_noise_kind(kind: str) -> str:
    """Validate a noise kind (:data:`NOISE_KINDS`), naming the parameter."""
    if kind not in NOISE_KINDS:
        raise ValueError(f"`noise` must be one of {', '.join(NOISE_KINDS)}, got {kind!r}")
    return kind


def check_tau(tau) -> tuple[float, float, float] | None:
    """A given correlation time: one value for every axis or three, s, each in (0, 1e4]; None for none or 'auto'."""
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
class NoiseModel(Completed):
    """The noise of a problem's rows, per axis (module notes).

    Attributes
    ----------
    kind : {"white", "gm", "gmw", "auto"}
        What was asked.
    tau : tuple of 3 (float or None)
        Correlation time of the Gauss-Markov part per axis, s; None where the axis is white.
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
    share : tuple of 3 float
        White share ``w_a`` of each axis' variance (0: pure Gauss-Markov or white axis): the
        Gauss-Markov std is ``sigma_a sqrt(1 - w_a)``, the white std ``sigma_a sqrt(w_a)``.
    lr_white : tuple of 3 (float or None), optional
        ``auto``: -2 ln Lambda of Gauss-Markov plus white against Gauss-Markov per axis (None where
        not tried: a white axis, or a Gauss-Markov one whose whitened residuals pass the screen of
        :data:`casep.noise.fit.SCREEN_P`).
    """

    what: ClassVar[str] = "noise model of the rows"

    kind: str = "white"
    tau: tuple = (None, None, None)
    scale: tuple = (1.0, 1.0, 1.0)
    rule: str = "given"
    lr: tuple | None = None
    lr_scale: float | None = None
    sigma: float | None = None
    extra: dict = field(default_factory=dict, compare=False)
    share: tuple = (0.0, 0.0, 0.0)
    lr_white: tuple | None = None

    def __post_init__(self) -> None:
        for a, w, tau in zip(AXES, self.share, self.tau):
            if not 0.0 <= w < 1.0 or (w > 0.0 and tau is None):
                raise ValueError(f"noise model: the white share of axis {a} must be in [0, 1) and 0 on a white "
                                 f"axis, got {w} (tau {tau})")

    @classmethod
    def white(cls) -> "NoiseModel":
        """White noise of one std on every axis (ordinary least squares)."""
        return cls()

    @classmethod
    def gauss_markov(cls, tau, scale: Sequence[float] = (1.0, 1.0, 1.0), share=0.0) -> "NoiseModel":
        """Gauss-Markov noise of given correlation time (one value or one per axis), s; with a white
        share `share` (one value or one per axis, in [0, 1)) Gauss-Markov plus white."""
        taus = check_tau(tau)
        if taus is None:
            raise ValueError("`tau` is required (a number > 0 s or three)")
        shares = tuple(float(w) for w in np.broadcast_to(np.asarray(share, dtype=float), (3,)))
        return cls(kind="gmw" if any(shares) else "gm", tau=taus, scale=tuple(float(s) for s in scale),
                   rule="given", share=shares)

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "NoiseModel":
        """The model of :meth:`to_dict` (also of a result written before the white share existed)."""
        axes = d["axes"]
        lr_w = tuple(axes[a].get("lr_white") for a in AXES) if "lr_white" in axes["x"] else None
        return cls(kind=d["kind"], tau=tuple(axes[a]["tau_s"] for a in AXES),
                   scale=tuple(axes[a]["scale"] for a in AXES), rule=d["rule"],
                   lr=tuple(np.inf if axes[a]["lr"] is None else axes[a]["lr"] for a in AXES)
                   if "lr" in axes["x"] else None,
                   lr_scale=d.get("lr_scale"), sigma=axes["x"].get("std_m_s"),
                   share=tuple(float(axes[a].get("white_share", 0.0)) for a in AXES), lr_white=lr_w)

    @property
    def is_white(self) -> bool:
        """True when no axis is correlated and the axes share one std (plain least squares)."""
        return all(t is None for t in self.tau) and all(s == 1.0 for s in self.scale)

    def axis_kinds(self) -> tuple[str, str, str]:
        """``white``, ``gm`` or ``gmw`` per axis."""
        return tuple("white" if t is None else ("gmw" if w > 0 else "gm")  # type: ignore[return-value]
                     for t, w in zip(self.tau, self.share))

    def text(self) -> str:
        """One line for the console: :meth:`line`."""
        return self.line()

    def _axis_text(self, j: int) -> str:
        kind = self.axis_kinds()[j]
        p = f"{AXES[j]} " + ("white" if kind == "white" else
                             f"GM tau {self.tau[j]:.3g} s" + (" + white" if kind == "gmw" else ""))
        if self.sigma is not None:
            sd = self.sigma * self.scale[j]
            p += (f" std {sd:.3g} m/s" if kind != "gmw" else
                  f" std {sd * np.sqrt(1.0 - self.share[j]):.3g} + {sd * np.sqrt(self.share[j]):.3g} m/s")
        elif self.scale[j] != 1.0:
            p += f" scale {self.scale[j]:.3g}"
        if kind == "gmw" and self.sigma is None:
            p += f" (white share {self.share[j]:.3g})"
        if self.lr is not None:
            p += f" (LR {self.lr[j]:.3g}" + ("" if self.lr_white is None or self.lr_white[j] is None
                                             else f", white part LR {self.lr_white[j]:.3g}") + ")"
        return p

    def line(self) -> str:
        """One line for the console: what the noise is and why."""
        how = {"reml": "REML", "given": "given"}.get(self.rule, self.rule)
        test = f"; each richer kind where its LR > {AUTO_LR:g}, 1 %" if self.kind == "auto" else ""
        head = f"noise {self.kind} ({how}{test})"
        scale = "" if self.lr_scale is None else f"; axis scales LR {self.lr_scale:.3g} (kept > {AUTO_LR_SCALE:g})"
        return f"{head}: " + ", ".join(self._axis_text(j) for j in range(3)) + scale

    def to_dict(self) -> dict:
        """JSON-ready description (read back by :meth:`from_dict`)."""
        names = {"white": "white", "gm": "gauss-markov", "gmw": "gauss-markov+white"}
        axes: dict[str, dict[str, Any]] = {}
        for j, (a, kind) in enumerate(zip(AXES, self.axis_kinds())):
            ax: dict[str, Any] = {"model": names[kind], "tau_s": self.tau[j], "scale": self.scale[j]}
            if kind == "gmw":
                ax["white_share"] = self.share[j]
            if self.sigma is not None:
                ax["std_m_s"] = self.sigma * self.scale[j]
                if kind == "gmw":
                    ax["std_gm_m_s"] = ax["std_m_s"] * float(np.sqrt(1.0 - self.share[j]))
                    ax["std_white_m_s"] = ax["std_m_s"] * float(np.sqrt(self.share[j]))
            if self.lr is not None:
                ax["lr"] = _statistic(self.lr[j])
            if self.lr_white is not None:
                ax["lr_white"] = _statistic(self.lr_white[j])
            axes[a] = ax
        d: dict[str, Any] = {"kind": self.kind, "rule": self.rule, "axes": axes}
        if self.lr is not None:
            d["lr_threshold"] = AUTO_LR
            d["lr_null"] = "(chi2_0 + chi2_1) / 2, 1 %"
        if self.lr_scale is not None:
            d["lr_scale"], d["lr_scale_threshold"] = _statistic(self.lr_scale), AUTO_LR_SCALE
        d.update({k: _statistic(v) if isinstance(v, float) else v for k, v in self.extra.items()})
        return d


def _statistic(v: float | None) -> float | None:
    """A test statistic as JSON holds it: None where it is infinite (the simpler model has no finite
    likelihood: residuals at the rounding level on that axis), which JSON cannot hold as a number."""
    return None if v is None or not np.isfinite(v) else float(v)


#: The state a whitening carries from one block of samples to the next: (time of the last sample,
#: the filter's estimate m of each column (the last row for Gauss-Markov), its variance P).
State = tuple[float, np.ndarray, float]


def whiten_series(X: np.ndarray, t: np.ndarray, tau: float | None, share: float = 0.0,
                  state: State | None = None) -> tuple[np.ndarray, float, State]:
    """Whiten the rows ``X`` (N, k) of one axis at unit std (module notes): ``(W, sum ln F_k, state)``.

    `state`: what the whitening of the samples before these left (None: these are the first).
    White (`tau` None): ``W = X``. Gauss-Markov (``share = 0``): the AR(1) difference, vectorised.
    Gauss-Markov plus white: the innovations filter, compiled.
    """
    X = np.asarray(X, dtype=float)
    if tau is None:
        return X.copy(), 0.0, (float(t[-1]), X[-1].copy(), 0.0)
    dt = np.empty(t.size)
    dt[0] = np.inf if state is None else t[0] - state[0]  # inf: no previous sample (a = 0, P^- = 1 - w)
    np.subtract(t[1:], t[:-1], out=dt[1:])
    if share == 0.0:
        a, b = ar1_terms(dt, tau)  # a_k, 1 - a_k^2
        g = 1.0 / np.sqrt(b)
        W = np.empty_like(X)
        W[0] = (X[0] - a[0] * state[1]) * g[0] if state is not None else X[0]
        np.multiply(X[:-1], a[1:, None], out=W[1:])
        np.subtract(X[1:], W[1:], out=W[1:])  # e_k - a_k e_(k-1)
        W[1:] *= g[1:, None]  # u_k = (e_k - a_k e_(k-1)) / sqrt(1 - a_k^2)
        return W, float(np.sum(np.log(b))), (float(t[-1]), X[-1].copy(), 0.0)
    m = np.zeros(X.shape[1]) if state is None else state[1].copy()
    P = np.array([0.0 if state is None else state[2]])
    W = np.empty_like(X)
    logdet = gmw_filter(np.ascontiguousarray(X), dt, float(tau), float(share), m, P, W)
    return W, logdet, (float(t[-1]), m, float(P[0]))


def whiten_axis(X: np.ndarray, t: np.ndarray, tau: float | None, scale: float,
                prev: State | None = None, share: float = 0.0) -> np.ndarray:
    """Whiten the rows ``X`` (N, k) of one axis of relative std `scale` (:func:`whiten_series`);
    `prev`: the state the samples before left, if any."""
    W = whiten_series(X, t, tau, share, prev)[0]
    W /= scale
    return W


def _series_transpose(V: np.ndarray, t: np.ndarray, tau: float | None, share: float) -> np.ndarray:
    """``W^T V`` for the whitening ``W`` of one axis at unit std (:func:`whiten_series`, from the first sample).

    The filter is ``u_k = (e_k - a_k m_(k-1)) / sqrt(F_k)``, ``m_k = alpha_k m_(k-1) + K_k e_k`` with
    ``alpha_k = a_k (1 - K_k)``; its transpose runs backwards with the adjoint ``rho_k`` of ``m_k``::

        rho_(N-1) = 0,   rho_k = -a_(k+1) v_(k+1) / sqrt(F_(k+1)) + alpha_(k+1) rho_(k+1),
        (W^T v)_k = v_k / sqrt(F_k) + K_k rho_k

    (Gauss-Markov: ``K = 1``, ``alpha = 0``). O(N k); never an N x N matrix.
    """
    V = np.asarray(V, dtype=float)
    if tau is None:
        return V.copy()
    dt = np.empty(t.size)
    dt[0] = np.inf
    np.subtract(t[1:], t[:-1], out=dt[1:])
    a, b = ar1_terms(dt, tau)
    F, K = np.empty(t.size), np.empty(t.size)
    P = 0.0
    for k in range(t.size):  # the gains of gmw_filter (they depend on the times and the parameters only)
        Pm = a[k] * a[k] * P + (1.0 - share) * b[k]
        F[k] = Pm + share
        K[k] = Pm / F[k]
        P = Pm * share / F[k]
    g = 1.0 / np.sqrt(F)
    alpha = a * (1.0 - K)
    Z = V * g[:, None]
    rho = np.zeros(V.shape[1])
    for k in range(t.size - 2, -1, -1):
        rho = -a[k + 1] * g[k + 1] * V[k + 1] + alpha[k + 1] * rho
        Z[k] += K[k] * rho
    return Z


def whiten_transpose(V: np.ndarray, t: np.ndarray, noise: NoiseModel) -> np.ndarray:
    """``W^T V`` of the whitening ``W`` of :func:`whiten` (rows ``V`` (N, 3, k) per axis, at unit ``sigma``).

    With ``u = W e`` the whitened rows of raw rows ``e`` (N, 3), ``W^T W`` is the inverse of their correlation
    (``Cov e = sigma^2 (W^T W)^-1``): the GLS estimate of :func:`whiten`'s rows is linear in the raw rows, ``x =
    (U^T U)^+ (W^T U)^T e`` with ``U = W S``, and ``W^T U`` is what it needs to carry another error of the raw rows
    (the IMU's own noise) to the estimate exactly.
    """
    V = np.asarray(V, dtype=float)
    out = np.empty_like(V)
    for j in range(3):
        out[:, j, :] = _series_transpose(V[:, j, :], np.asarray(t, dtype=float), noise.tau[j], noise.share[j])
        out[:, j, :] /= noise.scale[j]
    return out


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
        W = whiten_axis(X, t, noise.tau[j], noise.scale[j], None, noise.share[j])
        Sw[:, j, :], yw[:, j] = W[:, :-1], W[:, -1]
    if weights is not None:
        sw = np.sqrt(weights)
        Sw *= sw[:, :, None]
        yw *= sw
    return Sw, yw


def whiten_blocks(blocks: Iterable[tuple[slice, np.ndarray, np.ndarray]], t: np.ndarray, noise: NoiseModel,
                  weights: np.ndarray | None = None) -> Iterator[tuple[slice, np.ndarray, np.ndarray]]:
    """Whiten ``(row slice, S block, y block)`` in time order, carrying the filter state across blocks."""
    prev: list[State | None] = [None, None, None]
    for sl, S_b, y_b in blocks:
        tb = t[sl]
        Sw = np.empty(S_b.shape)
        yw = np.empty(y_b.shape)
        for j in range(3):
            X = np.concatenate([S_b[:, j, :], y_b[:, j, None]], axis=1)
            W, _, prev[j] = whiten_series(X, tb, noise.tau[j], noise.share[j], prev[j])
            W /= noise.scale[j]
            Sw[:, j, :], yw[:, j] = W[:, :-1], W[:, -1]
        if weights is not None:
            sw = np.sqrt(weights[sl])
            Sw *= sw[:, :, None]
            yw *= sw
        yield sl, Sw, yw

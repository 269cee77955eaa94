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

The noise model is fitted by REML (:func:`casep.analysis.noise_fit.fit_noise`); the residuals are
tested for whiteness by :func:`casep.analysis.whiteness.whiteness_test`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, ClassVar, Iterable, Iterator, Sequence

import numpy as np

from casep.results import Completed

__all__ = ["NOISE_KINDS", "AUTO_LR", "AUTO_LR_SCALE", "NoiseModel", "whiten", "whiten_blocks", "whiten_axis",
           "check_noise_kind", "check_tau"]

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

    what: ClassVar[str] = "noise model of the rows"

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
        taus = check_tau(tau)
        if taus is None:
            raise ValueError("`tau` is required (a number > 0 s or three)")
        return cls(kind="gm", tau=taus, scale=tuple(float(s) for s in scale), rule="given")

    @property
    def is_white(self) -> bool:
        """True when no axis is correlated and the axes share one std (plain least squares)."""
        return all(t is None for t in self.tau) and all(s == 1.0 for s in self.scale)

    def axis_kinds(self) -> tuple[str, str, str]:
        return tuple("white" if t is None else "gm" for t in self.tau)  # type: ignore[return-value]

    def text(self) -> str:
        """One line for the console: :meth:`line`."""
        return self.line()

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


def _coeffs(t: np.ndarray, tau: float | None) -> tuple[np.ndarray, np.ndarray]:
    """``(a_k, 1 / sqrt(1 - a_k^2))`` for k >= 1 (a = 0 for white noise)."""
    dt = np.diff(t)
    if tau is None:
        return np.zeros(dt.size), np.ones(dt.size)
    a = np.exp(-dt / tau)  # a_k = exp(-dt_k / tau)
    return a, 1.0 / np.sqrt(-np.expm1(-2.0 * dt / tau))  # 1 - a^2 without cancellation


def whiten_axis(X: np.ndarray, t: np.ndarray, tau: float | None, scale: float,
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
        W = whiten_axis(X, t, noise.tau[j], noise.scale[j])
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
            W = whiten_axis(X, tb, noise.tau[j], noise.scale[j], prev[j])
            prev[j] = (float(tb[-1]), X[-1].copy())
            Sw[:, j, :], yw[:, j] = W[:, :-1], W[:, -1]
        if weights is not None:
            sw = np.sqrt(weights[sl])
            Sw *= sw[:, :, None]
            yw *= sw
        yield sl, Sw, yw

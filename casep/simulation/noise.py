"""Tracking-noise models for simulated flights: white, first-order Gauss-Markov (AR(1)),
outliers and data gaps. Randomness only through a :class:`numpy.random.Generator`.

Gauss-Markov / AR(1) with correlation time ``tau`` and stationary std ``sigma``, exact
discretisation on possibly non-uniform times::

    a_k = exp(-(t_k - t_{k-1}) / tau)
    n_0 ~ N(0, sigma^2),   n_k = a_k n_{k-1} + sigma sqrt(1 - a_k^2) w_k,   w_k ~ N(0, 1)

so ``Var(n_k) = sigma^2`` for every k and the lag-1 correlation on a uniform grid of step
``dt`` is ``exp(-dt / tau)`` (``1 - a_k^2`` from :func:`casep._kernels.ar1_terms`, exact when
``dt << tau``). ``white_sigma`` adds independent white measurement noise ``N(0, white_sigma^2)``
on top of either kind: Gauss-Markov plus white, the usual radar / GNSS mixture.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import numpy as np

from casep._kernels import ar1_terms

__all__ = ["NoiseModel", "ar1_noise", "white_noise"]


def _check_rng(rng) -> np.random.Generator:
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"`rng` must be a numpy.random.Generator, got {type(rng).__name__}")
    return rng


def white_noise(n: int, sigma: float, rng: np.random.Generator, axes: int = 3) -> np.ndarray:
    """``(n, axes)`` independent N(0, sigma^2) samples."""
    return sigma * _check_rng(rng).standard_normal((n, axes))


def ar1_noise(t: np.ndarray, sigma: float, tau: float, rng: np.random.Generator, axes: int = 3) -> np.ndarray:
    """Stationary first-order Gauss-Markov noise at times `t` (see module notes)."""
    rng = _check_rng(rng)
    t = np.asarray(t, dtype=float)
    if not np.isfinite(tau) or tau <= 0:
        raise ValueError(f"`tau` must be finite and > 0 s, got {tau}")
    a, one_minus_a2 = ar1_terms(np.diff(t), tau)  # a_k, 1 - a_k^2
    w = rng.standard_normal((t.size, axes))
    out = np.empty((t.size, axes))
    out[0] = sigma * w[0]
    b = sigma * np.sqrt(one_minus_a2)
    for k in range(1, t.size):  # n_k = a_k n_{k-1} + sigma sqrt(1 - a_k^2) w_k
        out[k] = a[k - 1] * out[k - 1] + b[k - 1] * w[k]
    return out


@dataclass(frozen=True)
class NoiseModel:
    """Tracking-noise specification.

    Parameters
    ----------
    kind : {"white", "ar1"}
        White, or first-order Gauss-Markov.
    sigma : float
        Standard deviation per axis, m/s.
    tau : float, optional
        Correlation time of ``"ar1"``, s.
    outlier_rate : float, optional
        Probability per sample and axis of an outlier.
    outlier_sigma : float, optional
        Std of an outlier's added error, m/s.
    gaps : tuple of (start, length), optional
        Time windows (s) with no samples (rows are removed from the flight).
    white_sigma : float, optional
        Std of white measurement noise added to the base process, m/s (``"ar1"`` with it:
        Gauss-Markov plus white).
    """

    kind: str = "white"
    sigma: float = 0.1
    tau: float | None = None
    outlier_rate: float = 0.0
    outlier_sigma: float = 0.0
    gaps: tuple[tuple[float, float], ...] = ()
    white_sigma: float = 0.0

    def __post_init__(self) -> None:
        if self.kind not in ("white", "ar1"):
            raise ValueError(f"`kind` must be 'white' or 'ar1', got {self.kind!r}")
        if not np.isfinite(self.sigma) or self.sigma < 0:
            raise ValueError(f"`sigma` must be finite and >= 0, got {self.sigma}")
        if self.kind == "ar1" and (self.tau is None or not self.tau > 0):
            raise ValueError(f"`tau` must be > 0 for 'ar1' noise, got {self.tau}")
        if not (np.isfinite(self.white_sigma) and self.white_sigma >= 0):
            raise ValueError(f"`white_sigma` must be finite and >= 0, got {self.white_sigma}")
        if not 0.0 <= self.outlier_rate < 1.0:
            raise ValueError(f"`outlier_rate` must be in [0, 1), got {self.outlier_rate}")
        if self.outlier_sigma < 0:
            raise ValueError(f"`outlier_sigma` must be >= 0, got {self.outlier_sigma}")
        for g in self.gaps:
            if len(g) != 2 or not g[1] > 0:
                raise ValueError(f"each gap must be (start, length > 0), got {g}")

    def without_noise(self) -> "NoiseModel":
        """The same tracking (kind, gaps) without noise or outliers: ``dv = S_V D`` to rounding."""
        return replace(self, sigma=0.0, white_sigma=0.0, outlier_rate=0.0, outlier_sigma=0.0)

    def lag1_at(self, dt: float) -> float:
        """Expected lag-1 autocorrelation of the noise (without outliers) at sample step `dt` (s):
        ``exp(-dt / tau) sigma^2 / (sigma^2 + white_sigma^2)``."""
        if self.kind == "white" or self.tau is None:
            return 0.0
        total = self.sigma**2 + self.white_sigma**2
        return float(np.exp(-dt / self.tau) * self.sigma**2 / total) if total > 0 else 0.0

    def sample(self, t: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Noise at times `t`, ``(N, 3)`` m/s: base process plus outliers."""
        rng = _check_rng(rng)
        t = np.asarray(t, dtype=float)
        if self.kind == "white":
            n = white_noise(t.size, self.sigma, rng)
        else:
            assert self.tau is not None  # a Gauss-Markov model has one (checked on construction)
            n = ar1_noise(t, self.sigma, self.tau, rng)
        if self.white_sigma > 0:
            n = n + white_noise(t.size, self.white_sigma, rng)
        if self.outlier_rate > 0:
            hit = rng.random(n.shape) < self.outlier_rate
            n = n + hit * self.outlier_sigma * rng.standard_normal(n.shape)
        return n

    def describe(self) -> str:
        """One line: ``white 0.1 m/s`` or ``Gauss-Markov tau 1 s 0.09 m/s + white 0.045 m/s``, outliers, gaps."""
        text = (f"white {self.sigma:.3g} m/s" if self.kind == "white"
                else f"Gauss-Markov tau {self.tau:.3g} s {self.sigma:.3g} m/s")
        if self.white_sigma > 0:
            text += f" + white {self.white_sigma:.3g} m/s"
        if self.outlier_rate > 0:
            text += f", outliers {self.outlier_rate:.3g} per sample and axis (std {self.outlier_sigma:.3g} m/s)"
        if self.gaps:
            text += f", {len(self.gaps)} tracking gap(s)"
        return text

    def keep_mask(self, t: np.ndarray) -> np.ndarray:
        """True for samples outside every gap."""
        keep = np.ones(np.shape(t), dtype=bool)
        for start, length in self.gaps:
            keep &= ~((t >= start) & (t < start + length))
        return keep

    def to_dict(self) -> dict:
        """Plain-dict form for the truth sidecar."""
        d = asdict(self)
        d["gaps"] = [list(g) for g in self.gaps]
        return d

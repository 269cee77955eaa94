"""Noise identification from residuals: Allan deviation and a choice of noise model.

Notes
-----
The residuals ``e_k`` of a least-squares fit, per axis, sampled every ``dt``, are read as a
"frequency" series; their overlapping Allan variance at ``tau = m dt`` is computed by
``allantools.oadev`` (NIST SP 1065, eq. 11). Three noise models have closed-form Allan variances:

- white, variance ``s^2`` per sample:              ``AVAR = s^2 dt / tau``
- Gauss-Markov (first order), variance ``q^2``, correlation time ``T``:
  ``AVAR = (q^2 T^2 / tau^2) (2 tau / T - 3 + 4 exp(-tau / T) - exp(-2 tau / T))``
  (white-like ``2 q^2 T / tau`` for ``tau >> T``, random-walk-like ``2 q^2 tau / (3 T)`` for ``tau << T``);
  for the sampled process the exact AR(1) sums are used (:func:`avar_gauss_markov` with ``dt``)
- random walk, increment variance ``w^2`` per sample: ``AVAR = w^2 (2 m^2 + 1) / (6 m)``, ``m = tau / dt``

Each is fitted to the axes' mean Allan variance by weighted least squares in ``log AVAR``
(weights from the Allan variance's own relative error, ``2 ade / ad``); the choice is the
smallest ``chi2 + k ln(n)`` (BIC; k parameters, n averaging times); a Gauss-Markov fit whose
``T`` exceeds three times the longest averaging time is a random walk within the record, and is
reported as one. Averaging times stop at a
tenth of the record: beyond, the fitted smooth regressors have absorbed the noise's slow part.
A Gauss-Markov choice feeds ``--method gls --tau T``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from casep.results import Completed, deprecated_alias

__all__ = ["NoiseIdentification", "allan_deviation", "identify_noise", "avar_white", "avar_gauss_markov",
           "avar_random_walk"]

MODELS = ("white", "gauss_markov", "random_walk")


def avar_white(tau: np.ndarray, dt: float, s2: float) -> np.ndarray:
    """Allan variance of white noise of variance `s2` per sample: ``s^2 dt / tau``."""
    return s2 * dt / np.asarray(tau, dtype=float)


def avar_gauss_markov(tau: np.ndarray, q2: float, T: float, dt: float | None = None) -> np.ndarray:
    """Allan variance of a first-order Gauss-Markov process (variance `q2`, correlation time `T`).

    With `dt`, exactly for the sampled process (AR(1), ``a = exp(-dt / T)``) averaged over
    ``m = tau / dt`` samples: ``AVAR = Var(mean of m) - Cov(consecutive means)``, i.e.
    ``q^2 / m^2 [m + 2 sum_{d<m} (m - d) a^d - sum_{d<2m} min(d, 2m - d) a^d]``; without, the
    continuous form of the module notes.
    """
    tau = np.asarray(tau, dtype=float)
    if dt is None:
        x = tau / T
        small = x < 1e-3
        core = np.where(small, (2.0 / 3.0) * x**3, 2 * x - 3 + 4 * np.exp(-x) - np.exp(-2 * x))  # series for tiny x
        return q2 * core / x**2
    a = np.exp(-dt / T)
    out = np.empty(tau.shape)
    for i, mm in enumerate(np.round(tau / dt).astype(int).ravel()):
        d = np.arange(1, 2 * mm)
        ad = a ** d
        var_mean = mm + 2 * np.sum(np.where(d < mm, mm - d, 0) * ad)  # sum_{i,j<m} a^|i-j|
        cov_next = np.sum(np.minimum(d, 2 * mm - d) * ad)  # sum_{i<m<=j<2m} a^(j-i)
        out.flat[i] = q2 * (var_mean - cov_next) / mm**2
    return out


def avar_random_walk(tau: np.ndarray, dt: float, w2: float) -> np.ndarray:
    """Allan variance of a random walk of increment variance `w2` per sample: ``w^2 (2 m^2 + 1) / (6 m)``."""
    m = np.asarray(tau, dtype=float) / dt
    return w2 * (2 * m**2 + 1) / (6 * m)


def allan_deviation(x: np.ndarray, dt: float, taus: np.ndarray | str = "octave"):
    """Overlapping Allan deviation of a uniformly sampled series (``allantools.oadev``, frequency data).

    Returns
    -------
    (taus, adev, adev_error)
    """
    import allantools

    t, ad, ade, _ = allantools.oadev(np.asarray(x, dtype=float), rate=1.0 / dt, data_type="freq", taus=taus)
    return np.asarray(t), np.asarray(ad), np.asarray(ade)


@dataclass(frozen=True)
class NoiseIdentification(Completed):
    """Allan deviation of the residuals and the fitted noise models.

    Attributes
    ----------
    dt : float
        Sample step, s.
    taus : (k,) ndarray
        Averaging times, s.
    adev : (3, k) ndarray
        Allan deviation per axis, m/s.
    avar : (k,) ndarray
        The axes' mean Allan variance (what the models are fitted to), (m/s)^2.
    fits : dict
        Per model: its parameters (``s``: white std m/s; ``q``, ``T``: Gauss-Markov std m/s and
        correlation time s; ``w``: random-walk step std m/s), ``chi2`` and ``bic``.
    choice : str
        ``"white"``, ``"gauss_markov"`` or ``"random_walk"``.
    """

    what: ClassVar[str] = "noise identification (Allan deviation of the residuals)"

    dt: float
    taus: np.ndarray
    adev: np.ndarray
    avar: np.ndarray
    avar_error: np.ndarray
    fits: dict = field(default_factory=dict)
    choice: str = "white"

    def model_avar(self, model: str, taus: np.ndarray | None = None) -> np.ndarray:
        """The fitted model's Allan variance at `taus` (default: the measured ones)."""
        taus = self.taus if taus is None else np.asarray(taus, dtype=float)
        p = self.fits[model]
        if model == "white":
            return avar_white(taus, self.dt, p["s"] ** 2)
        if model == "gauss_markov":
            return avar_gauss_markov(taus, p["q"] ** 2, p["T"], self.dt)
        return avar_random_walk(taus, self.dt, p["w"] ** 2)

    @property
    def recommendation(self) -> str:
        """What to estimate with, given the choice."""
        if self.choice == "white":
            return "white noise: OLS's std are right (--method ols)"
        if self.choice == "gauss_markov":
            T = self.fits["gauss_markov"]["T"]
            return f"Gauss-Markov noise with tau {T:.3g} s: --method gls --tau {T:.3g} (or --tau auto)"
        span = self.dt * 10 * self.taus.size
        return (f"random-walk noise: OLS's std are too small; --method gls with a long tau (e.g. --tau {span:.3g}) "
                "or --method rels approximate it")

    report = deprecated_alias("text", "report")

    def text(self) -> str:
        """Allan deviation fits of the residuals, the chosen noise model and the recommendation."""
        lines = [f"Allan deviation of the residuals (dt {self.dt:.4g} s, {self.taus.size} averaging times "
                 f"{self.taus[0]:.3g}-{self.taus[-1]:.3g} s)"]
        for k in MODELS:
            p = self.fits[k]
            par = ", ".join(f"{n} {v:.4g}" for n, v in p.items() if n not in ("chi2", "bic"))
            lines.append(f"  {k:<13} {par}; chi2 {p['chi2']:.4g}, BIC {p['bic']:.4g}"
                         + ("  <- chosen" if k == self.choice else ""))
        lines.append(self.recommendation)
        return "\n".join(lines)

    def to_dict(self) -> dict:
        return {"dt": self.dt, "taus": self.taus.tolist(), "adev": self.adev.tolist(), "fits": self.fits,
                "choice": self.choice, "recommendation": self.recommendation}


def identify_noise(residuals: np.ndarray, dt: float, *, max_fraction: float = 0.1) -> NoiseIdentification:
    """Allan deviation of residuals and the noise model that explains it best (module notes).

    Parameters
    ----------
    residuals : (N, 3) or (N,) array_like
        Fit residuals, m/s, uniformly sampled every `dt` s (NaN rows dropped at the ends only).
    dt : float
        Sample step, s.
    max_fraction : float, optional
        Longest averaging time as a fraction of the record (default 0.1).
    """
    from scipy.optimize import minimize_scalar

    e = np.asarray(residuals, dtype=float)
    e = e.reshape(e.shape[0], -1)
    if not np.all(np.isfinite(e)):
        raise ValueError("`residuals` must be finite (drop rows without tracking first)")
    if not (np.isfinite(dt) and dt > 0):
        raise ValueError(f"`dt` must be finite and > 0 s, got {dt}")
    N = e.shape[0]
    if N < 64:
        raise ValueError(f"{N} samples are too few for an Allan deviation (64 or more)")
    m = np.unique(np.round(np.logspace(0, np.log10(max(2.0, max_fraction * N)), 24)).astype(int))
    taus = m * dt
    per = [allan_deviation(e[:, i], dt, taus) for i in range(e.shape[1])]
    taus = per[0][0]
    adev = np.array([p[1] for p in per])
    avar = np.mean(adev**2, axis=0)
    rel = np.mean([2 * p[2] / np.maximum(p[1], 1e-300) for p in per], axis=0) / np.sqrt(e.shape[1])  # d log AVAR
    w = 1.0 / np.maximum(rel, 1e-3) ** 2
    la = np.log(avar)
    n = taus.size

    def scale_fit(shape: np.ndarray) -> tuple[float, float]:  # log AVAR = log c + log shape: c and chi2
        lc = np.sum(w * (la - np.log(shape))) / np.sum(w)
        return float(np.exp(lc)), float(np.sum(w * (la - lc - np.log(shape)) ** 2))

    fits: dict = {}
    c, chi = scale_fit(avar_white(taus, dt, 1.0))
    fits["white"] = {"s": float(np.sqrt(c)), "chi2": chi, "bic": chi + 1 * np.log(n)}
    c, chi = scale_fit(avar_random_walk(taus, dt, 1.0))
    fits["random_walk"] = {"w": float(np.sqrt(c)), "chi2": chi, "bic": chi + 1 * np.log(n)}
    lo, hi = np.log(dt / 10), np.log(taus[-1] * 10)
    grid = np.linspace(lo, hi, 60)
    chis = [scale_fit(avar_gauss_markov(taus, 1.0, np.exp(g), dt))[1] for g in grid]
    k = int(np.argmin(chis))
    best = minimize_scalar(lambda g: scale_fit(avar_gauss_markov(taus, 1.0, np.exp(g), dt))[1],
                           bounds=(grid[max(k - 1, 0)], grid[min(k + 1, grid.size - 1)]), method="bounded")
    T = float(np.exp(best.x))
    c, chi = scale_fit(avar_gauss_markov(taus, 1.0, T, dt))
    fits["gauss_markov"] = {"q": float(np.sqrt(c)), "T": T, "chi2": chi, "bic": chi + 2 * np.log(n)}
    choice = min(MODELS, key=lambda k_: fits[k_]["bic"])
    if choice == "gauss_markov" and T > 3 * taus[-1]:
        choice = "random_walk"  # a correlation time beyond the record: a random walk within it
    return NoiseIdentification(float(dt), taus, adev, avar, rel, fits, choice)

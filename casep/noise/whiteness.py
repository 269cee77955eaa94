"""Whiteness of the residuals: the Ljung-Box test per axis, across gaps in the sample times.

The std of a fit are honest only when its whitened residuals are white (for noise ``white`` the
raw residuals; for a Gauss-Markov or Gauss-Markov-plus-white model the residuals whitened by it,
:mod:`casep.noise.model`). :func:`whiteness_test` says per axis whether they are, and
:meth:`WhitenessTest.message` how much too small the std then are (the std of a Gauss-Markov plus
white model of the same data over the reported ones) and which noise model to ask for.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from casep._kernels import ar1_long_run_factor  # the AR(1) rule, shared with the set-up checks of io
from casep.noise.model import AXES
from casep.results import Completed

#: Level of the test (Bonferroni over the axes) of residuals whitened by a noise model fitted to the same data
#: (every kind but white): a fitted model's residuals fail at 1 % on about 1 flight in 100 by chance, a
#: warning on the default path of every such flight; a model that misses a white part or a model error
#: gives Q in the hundreds, far beyond this level too.
ALPHA_FITTED = 1e-3

__all__ = ["ALPHA_FITTED", "ar1_long_run_factor", "ljung_box", "WhitenessTest", "whiteness_test", "default_lags",
           "find_gaps", "segments_of"]


def ljung_box(x: np.ndarray, lags: int, segments: np.ndarray | None = None) -> tuple[float, float]:
    """Ljung-Box ``Q = n (n + 2) sum_k rho_k^2 / (n - k)`` of a series and its chi2(lags) p-value.

    `segments`: segment id per sample; lag products are taken only within a segment (a gap in
    the time tags is not a lag).
    """
    from casep._special import chi2_sf  # without importing scipy.special (its import, 0.1-0.6 s)

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
    return float(q), chi2_sf(int(lags), float(q))


@dataclass(frozen=True)
class WhitenessTest(Completed):
    """Residual whiteness per axis (Ljung-Box) and how much too small the white std are.

    A test that rejects whiteness is a finding, not a failure: ``success`` True, ``status`` 0;
    :meth:`text` says what it found.
    """

    what: ClassVar[str] = "Ljung-Box whiteness test of the residuals"

    q: tuple[float, float, float]
    p: tuple[float, float, float]
    lags: int
    alpha: float
    std_factor: float | None = None  # median richer-model / reported std over the estimable coefficients
    std_factor_max: float | None = None
    kind: str = "white"  # the noise kind asked of the fit tested (its whitened residuals unless white)

    @property
    def rejected(self) -> tuple[str, ...]:
        """The axes whose residuals are not white at `alpha` (Bonferroni over the axes)."""
        return tuple(a for a, p in zip(AXES, self.p) if p < self.alpha / 3)

    def to_dict(self) -> dict:
        return {"test": "ljung-box", "lags": self.lags, "alpha": self.alpha, "noise": self.kind,
                "axes": {a: {"q": self.q[j], "p": self.p[j]} for j, a in enumerate(AXES)},
                "rejected": list(self.rejected), "std_factor_median": self.std_factor,
                "std_factor_max": self.std_factor_max}

    def text(self) -> str:
        """The whiteness of the residuals per axis, in one line (the warning's text): the axes, their Q and p, the
        factor by which the std are too small, what to do."""
        parts = ", ".join(f"{a} Q {self.q[j]:.3g} (p {self.p[j]:.2g})"
                          for j, a in enumerate(AXES) if a in self.rejected)
        what = "residuals are not white" if self.kind == "white" else \
            f"residuals whitened by the noise model ({self.kind}) are still correlated"
        factor = ""
        if self.std_factor is not None and self.std_factor >= 1.0:
            factor = (f"; the reported std are about {self.std_factor:.2g}x too small (median over the coefficients "
                      f"of the Gauss-Markov plus white std of the same data / the reported std; up to "
                      f"{self.std_factor_max:.2g}x)")
        elif self.std_factor is not None:
            factor = (f"; a Gauss-Markov plus white model of the same data gives std {self.std_factor:.2g}x the "
                      f"reported ones (median over the coefficients; up to {self.std_factor_max:.2g}x): the std "
                      "are not the right ones, some too large here")
        advice = {"white": "Use --noise auto (or gmw)", "gm": "Use --noise auto (or gmw)"}.get(
            self.kind, "The noise is not of the modelled family (--noise gmw fits a white part on every axis), or "
                       "the residuals hold a model error (frames, time tags, a missing term) that no noise model "
                       "makes right: the std may be too small")
        return f"{what} ({parts}, Ljung-Box on {self.lags} lags){factor}. {advice}"


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

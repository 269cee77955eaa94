"""Wavelet de-noising of the velocity error, as the paper describes it (PyWavelets).

Per axis: ``wavedec`` to `level` with the chosen wavelet and boundary extension, threshold
the detail coefficients level by level, ``waverec``.

Boundary extension (paper Eq. 10-13, L = extension length):

============= ===================================================================
``zero``       0..0 | c_0 .. c_{N-1} | 0..0                                  (Eq. 10)
``periodic``   c_{N-L}..c_{N-1} | c | c_0..c_{L-1}                            (Eq. 11)
``symmetric``  c_{L-1}..c_0 | c | c_{N-1}..c_{N-L}  (about the boundary, point
               repeated; PyWavelets ``symmetric``)                            (Eq. 12)
``reflect``    c_L..c_1 | c_0 .. c_{N-1} | c_{N-2}..c_{N-L-1} (about the boundary
               point, not repeated; PyWavelets ``reflect``)                    (Eq. 13)
============= ===================================================================

Threshold modes: ``soft`` (shrink by the threshold), ``hard`` (keep or kill), ``garrote``
(non-negative garrote, ``x - T^2 / x`` above T), ``forced`` (all detail coefficients to
zero: only the approximation is kept).

Threshold rules, for coefficients of unit-variance noise (:func:`select_threshold`):

- ``sqtwolog``: universal threshold ``sqrt(2 ln n)``;
- ``rigrsure``: Stein's unbiased risk. With ``s_k`` the sorted squares ``x_(k)^2``,
  ``risk_k = (n - 2k + sum_{i<=k} s_i + (n - k) s_k) / n`` (k = 1..n); T = sqrt(s_k*) at the
  minimum;
- ``heursure``: MATLAB's mix: ``eta = (||x||^2 - n) / n``, ``crit = log2(n)^1.5 / sqrt(n)``;
  universal if ``eta < crit``, else ``min(rigrsure, universal)``;
- ``minimaxi``: ``0.3936 + 0.1829 log2(n)`` for n > 32, else 0 (Donoho & Johnstone);
- ``bayes``: BayesShrink, ``T = 1 / sigma_x`` with ``sigma_x^2 = max(mean(x^2) - 1, 0)``
  (``T = max |x|``, i.e. kill all, when ``sigma_x = 0``).

Noise scaling, as MATLAB's ``wden``: ``one`` (coefficients taken as unit variance),
``sln`` (one sigma for all levels: ``MAD(d_1) / 0.6745`` of the finest details), ``mln``
(``sigma_j = MAD(d_j) / 0.6745`` per level). The level threshold is ``sigma_j * T(d_j /
sigma_j)``; ``sqtwolog`` and ``minimaxi`` use n = all coefficients of the decomposition,
the data-driven rules the level's own coefficients. MAD here is ``median(|d|)`` (wavelet
details have zero mean).

Default level: the largest without boundary domination, ``pywt.dwt_max_level(N,
filter length)``; asking for more warns with the number.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
import pywt

from casep.exceptions import CasepWarning
from casep.results import Completed

__all__ = ["denoise", "denoise_signal", "select_threshold", "mad_sigma", "max_level", "extend",
           "DenoiseResult", "EXTENSIONS", "RULES", "MODES", "SCALINGS"]

EXTENSIONS = {"zero": "zero", "periodic": "periodic", "symmetric": "symmetric", "reflect": "reflect"}
RULES = ("sqtwolog", "rigrsure", "heursure", "minimaxi", "bayes")
MODES = ("soft", "hard", "forced", "garrote")
SCALINGS = ("one", "sln", "mln")
_MAD_FACTOR = 0.6745


def extend(x: np.ndarray, length: int, extension: str) -> np.ndarray:
    """The signal padded by `length` samples each side, as the transform sees it."""
    _check_choice("extension", extension, EXTENSIONS)
    return pywt.pad(np.asarray(x, dtype=float), length, EXTENSIONS[extension])


def _check_choice(name: str, value: str, choices) -> None:
    if value not in choices:
        raise ValueError(f"`{name}` must be one of {', '.join(choices)}, got {value!r}")


def select_threshold(x: np.ndarray, rule: str) -> float:
    """Threshold for coefficients `x` of unit-variance noise (see module notes)."""
    _check_choice("rule", rule, RULES)
    x = np.asarray(x, dtype=float).ravel()
    n = x.size
    if n == 0:
        return 0.0
    universal = float(np.sqrt(2.0 * np.log(n)))
    if rule == "sqtwolog":
        return universal
    if rule == "minimaxi":
        return 0.3936 + 0.1829 * np.log2(n) if n > 32 else 0.0
    if rule == "rigrsure":
        return _rigrsure(x)
    if rule == "heursure":
        eta = (x @ x - n) / n
        crit = np.log2(n) ** 1.5 / np.sqrt(n)
        return universal if eta < crit else min(_rigrsure(x), universal)
    sigma_x2 = max(float(np.mean(x**2)) - 1.0, 0.0)  # BayesShrink
    return float(1.0 / np.sqrt(sigma_x2)) if sigma_x2 > 0 else float(np.max(np.abs(x)))


def _rigrsure(x: np.ndarray) -> float:
    n = x.size
    s = np.sort(x**2)
    k = np.arange(1, n + 1)
    risks = (n - 2 * k + np.cumsum(s) + (n - k) * s) / n  # SURE(T = sqrt(s_k))
    return float(np.sqrt(s[int(np.argmin(risks))]))


def mad_sigma(d: np.ndarray) -> float:
    """Noise std from wavelet details: ``median(|d|) / 0.6745``."""
    return float(np.median(np.abs(np.asarray(d, dtype=float)))) / _MAD_FACTOR


def max_level(n: int, wavelet: str = "sym8") -> int:
    """Largest decomposition level without boundary domination (``pywt.dwt_max_level``)."""
    return int(pywt.dwt_max_level(n, pywt.Wavelet(wavelet).dec_len))


def _wavelet(name: str) -> pywt.Wavelet:
    if not isinstance(name, str) or name not in pywt.wavelist(kind="discrete"):
        raise ValueError(f"`wavelet` must be a discrete PyWavelets wavelet (e.g. sym8, db4, coif3), got {name!r}")
    return pywt.Wavelet(name)


def denoise_signal(x: np.ndarray, *, wavelet: str = "sym8", level: int | None = None, rule: str = "sqtwolog",
                   mode: str = "soft", extension: str = "symmetric", scaling: str = "sln",
                   threshold: float | None = None) -> tuple[np.ndarray, float]:
    """De-noise one 1-D signal; returns it and the noise std estimated from its finest details.

    `threshold`, when given, replaces the rule: a fixed threshold in units of each level's
    noise sigma (0 keeps every coefficient: perfect reconstruction).
    """
    x = np.asarray(x, dtype=float)
    w = _wavelet(wavelet)
    _check_choice("rule", rule, RULES)
    _check_choice("mode", mode, MODES)
    _check_choice("extension", extension, EXTENSIONS)
    _check_choice("scaling", scaling, SCALINGS)
    if threshold is not None and (not np.isfinite(threshold) or threshold < 0):
        raise ValueError(f"`threshold` must be finite and >= 0, got {threshold}")
    top = max_level(x.size, wavelet)
    if level is None:
        level = max(top, 1)
    elif isinstance(level, bool) or not isinstance(level, (int, np.integer)) or level < 1:
        raise ValueError(f"`level` must be an int >= 1, got {level!r}")
    elif level > top:
        warnings.warn(f"wavelet level {level} exceeds {top}, the largest level without boundary domination "
                      f"for {x.size} samples and {wavelet}; the coarse levels are mostly boundary extension",
                      CasepWarning, stacklevel=3)
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="Level value of .* is too high")
        coeffs = pywt.wavedec(x, w, mode=EXTENSIONS[extension], level=level)
    details = coeffs[1:]  # coarsest first: d_L .. d_1
    sigma1 = mad_sigma(details[-1])
    n_all = sum(c.size for c in coeffs)
    out = [coeffs[0]]
    for d in details:
        if mode == "forced":
            out.append(np.zeros_like(d))
            continue
        s = 1.0 if scaling == "one" else sigma1 if scaling == "sln" else mad_sigma(d)
        if threshold is not None:
            thr = s * threshold
        elif s <= 0 or s < np.sqrt(np.finfo(float).eps) * np.max(np.abs(d), initial=0.0):
            thr = 0.0  # no noise to speak of at this level
        elif rule in ("sqtwolog", "minimaxi"):
            thr = s * select_threshold(np.empty(n_all), rule)
        else:
            thr = s * select_threshold(d / s, rule)
        out.append(pywt.threshold(d, thr, mode=mode) if thr > 0 else d.copy())
    rec = pywt.waverec(out, w, mode=EXTENSIONS[extension])[: x.size]
    return rec, sigma1


@dataclass(frozen=True)
class DenoiseResult(Completed):
    """De-noised velocity error and what was done to it (result protocol: :mod:`casep.results`)."""

    what: ClassVar[str] = "wavelet de-noising of the velocity error"

    dv: np.ndarray  # (N, 3) m/s
    sigma: np.ndarray  # (3,) noise std per axis from the finest details, m/s
    settings: dict = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """The ``denoise`` entry of the result JSON."""
        return {"method": "wavelet", **self.settings,
                "sigma": {a: float(s) for a, s in zip("xyz", self.sigma)}}

    def text(self) -> str:
        """One line: the settings and the noise std per axis (from the finest details), m/s."""
        how = ", ".join(f"{k} {v}" for k, v in self.settings.items())
        sig = ", ".join(f"{a} {float(s):.4g}" for a, s in zip("xyz", self.sigma))
        return f"wavelet de-noising ({how}): noise std {sig} m/s, {self.dv.shape[0]} samples"


def denoise(dv: np.ndarray, *, wavelet: str = "sym8", level: int | None = None, rule: str = "sqtwolog",
            mode: str = "soft", extension: str = "symmetric", scaling: str = "sln",
            threshold: float | None = None) -> DenoiseResult:
    """De-noise each axis of the velocity error ``dv`` (N, 3).

    Parameters
    ----------
    dv : (N, 3) array_like
        Velocity error, m/s.
    wavelet : str, optional
        Discrete wavelet (default ``sym8``).
    level : int, optional
        Decomposition level (default: :func:`max_level`; more warns).
    rule : {"sqtwolog", "rigrsure", "heursure", "minimaxi", "bayes"}, optional
    mode : {"soft", "hard", "forced", "garrote"}, optional
    extension : {"zero", "periodic", "symmetric", "reflect"}, optional
    scaling : {"one", "sln", "mln"}, optional
    threshold : float, optional
        Fixed threshold in noise-sigma units, replacing `rule`.

    Returns
    -------
    DenoiseResult
    """
    dv = np.asarray(dv, dtype=float)
    if dv.ndim != 2 or dv.shape[1] != 3:
        raise ValueError(f"`dv` must have shape (N, 3), got {dv.shape}")
    if dv.shape[0] < 2:
        raise ValueError(f"`dv` needs at least 2 samples, got {dv.shape[0]}")
    _wavelet(wavelet)  # validate before choosing the default level
    lvl = max(max_level(dv.shape[0], wavelet), 1) if level is None else level
    cols, sig = [], []
    for i in range(3):
        with warnings.catch_warnings():
            if i:  # warn once, not per axis
                warnings.simplefilter("ignore", CasepWarning)
            y, s = denoise_signal(dv[:, i], wavelet=wavelet, level=lvl, rule=rule, mode=mode,
                                  extension=extension, scaling=scaling, threshold=threshold)
        cols.append(y)
        sig.append(s)
    settings = {"wavelet": wavelet, "level": lvl, "threshold_rule": rule, "threshold_mode": mode,
                "extension": extension, "scaling": scaling}
    if threshold is not None:
        settings["threshold"] = float(threshold)
    return DenoiseResult(np.column_stack(cols), np.array(sig), settings)

"""Robust row weights in coloured noise: a robust filter on the one-step innovations.

A glitch (one sample of tracking far off) in Gauss-Markov noise spreads over two whitened rows
(its own innovation and the next one's), so down-weighting whitened residuals row by row, as
Huber's IRLS does in white noise, removes good data next to every glitch and lets the rest of
the glitch leak in. The robust filter (Masreliez; Martin & Thomson) instead walks the residuals
``e_k`` of a fit in time order and predicts each from the last sample it accepted::

    nu_k = (e_k - a_k e_j) / (r_a sqrt(1 - a_k^2)),    a_k = exp(-(t_k - t_j) / tau_a),   u_k = nu_k / s

(``j`` the last accepted sample, ``s`` a robust scale of the innovations: 1.4826 MAD). A sample
with ``|u_k| > reject`` on any axis is rejected: it is removed from the regression and the
recursion goes on from sample ``j`` (exactly the whitening across a gap), so the glitch does not
enter the next innovation. The kept samples get the weight of the chosen function on each axis:

* Huber: ``w = min(1, c / |u|)``, ``c = 1.345`` (95 % efficiency at the Gaussian);
* bisquare: ``w = (1 - (u / c)^2)^2`` for ``|u| < c``, ``c = 4.685``; 0 beyond (rejected).

On an axis with a white part (Gauss-Markov plus white) the innovations are those of its
Gauss-Markov part, as above: the white part inflates them by a common factor that the robust scale
``s`` absorbs (an approximation; the whitening of the fit itself is exact).

A fit's residual at a sample is also the error of the fit's prediction there: where the coefficients are
poorly determined and the regressors change fast (at lift-off the specific force jumps tenfold, so scale
factors, misalignments, the attitude error and a time-tag error ``a dt`` all grow by as much) that error is
far larger than the noise, and a good epoch would be rejected for what the fit cannot say. Given the fit's
factor ``G_k = S_k L`` (``L L^T`` its coefficient covariance), the innovation's variance is that of a Kalman
filter carrying the coefficients as its state, ``H P H^T + R``::

    var(nu_k) = (r_a s_k)^2 (1 - a_k^2) + |G_k - a_k G_j|^2

(``|G_k|^2`` on a white axis): a glitch is a sample beyond what the noise and the fit's own uncertainty
allow together. Where the fit determines the coefficients well, ``|G|^2`` is about ``n / N`` of the noise
variance and changes nothing.

More than :data:`MAX_RUN` rejections in a row are taken as a real change (a step the model does
not have), not a glitch: the run is accepted again, so the filter cannot lose track. The samples
before the first one accepted have no prediction forward; they are judged backward, from the
next accepted sample (:func:`_sequential`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from casep._kernels import ar1_terms
from casep._special import MAD_SIGMA  # sigma = MAD_SIGMA * MAD for Gaussian data
from casep.noise.model import NoiseModel

__all__ = ["ROBUST_FUNCTIONS", "RobustWeights", "robust_filter", "stretches", "HUBER_C", "BISQUARE_C", "REJECT",
           "MAX_RUN", "MIN_SEGMENT_S", "MIN_STRETCH_EPOCHS"]

ROBUST_FUNCTIONS = ("huber", "bisquare")
HUBER_C = 1.345
BISQUARE_C = 4.685
#: |u| above which a sample is rejected (Huber); a Gaussian innovation exceeds it with P = 6e-5.
REJECT = 4.0
#: Consecutive rejections after which the filter accepts again (a step, not a glitch).
MAX_RUN = 10
#: A pause of the tracking this long or more (s) splits its epochs into stretches (:func:`stretches`); the tracking
#: screen also leaves out a segment between jumps shorter than this
#: (:mod:`casep.checks.tracking_quality`).
MIN_SEGMENT_S = 3.0
#: A stretch has a noise level of its own with this many epochs or more (:func:`stretches`).
MIN_STRETCH_EPOCHS = 5


def stretches(t: np.ndarray) -> list[tuple[int, int]]:
    """The stretches of the epochs `t` (s, increasing): ``(first, stop)`` index ranges split at pauses of
    :data:`MIN_SEGMENT_S` or more, each with :data:`MIN_STRETCH_EPOCHS` epochs or more (fewer give no noise level
    of their own): the split every per-stretch noise level uses (the robust filter's scale, the outlier check,
    the tracking screen's noise per stretch)."""
    t = np.asarray(t, dtype=float)
    cut = np.flatnonzero(np.diff(t) >= MIN_SEGMENT_S) + 1
    return [(int(a), int(b)) for a, b in zip(np.concatenate([[0], cut]), np.concatenate([cut, [t.size]]))
            if b - a >= MIN_STRETCH_EPOCHS]


@dataclass(frozen=True)
class RobustWeights:
    """The outcome of the robust filter on one fit's residuals.

    Attributes
    ----------
    keep : (N,) bool ndarray
        Samples kept in the regression.
    weights : (N, 3) ndarray
        Weight of each kept sample's axis row (1 for rejected samples: unused).
    u : (N, 3) ndarray
        Standardized innovations ``nu / s_k``, each by the scale of its stretch.
    scale : float
        Robust scale ``s`` of the innovations (in units of the x-axis noise std), over the whole flight.
    precision : (N,) ndarray, optional
        Each sample's ``(s / s_k)^2``, ``s_k`` the scale of its stretch of the tracking (:func:`stretches`): the
        weight that whitens its rows to the scale ``s`` (default 1 everywhere); the rows a fit solves carry it
        times `weights`.
    """

    keep: np.ndarray
    weights: np.ndarray
    u: np.ndarray
    scale: float
    precision: np.ndarray | None = None

    @property
    def row_weights(self) -> np.ndarray:
        """The weights of the rows a fit solves: `weights` times `precision`."""
        return self.weights if self.precision is None else self.weights * self.precision[:, None]

    @property
    def rejected(self) -> np.ndarray:
        """Indices of the rejected samples."""
        return np.flatnonzero(~self.keep)


def _innovations(e: np.ndarray, t: np.ndarray, noise: NoiseModel, keep: np.ndarray) -> np.ndarray:
    """Innovations of every sample from the last kept one before it (unit scale)."""
    N = e.shape[0]
    nu = np.empty_like(e)
    last = np.full(N, -1)
    idx = np.flatnonzero(keep)
    # last kept sample strictly before k
    pos = np.searchsorted(idx, np.arange(N), side="left") - 1
    last[pos >= 0] = idx[pos[pos >= 0]]
    has = last >= 0
    for j in range(3):
        sc = noise.scale[j]
        tau = noise.tau[j]
        nu[:, j] = e[:, j] / sc
        if tau is None:
            continue
        a, b = ar1_terms(t[has] - t[last[has]], tau)  # a_k, 1 - a_k^2
        nu[has, j] = (e[has, j] - a * e[last[has], j]) / (sc * np.sqrt(b))
    return nu


def robust_filter(residuals: np.ndarray, t: np.ndarray, noise: NoiseModel, *, function: str = "huber",
                  scale: float | None = None, reject: float | None = None, floor: float = 0.0,
                  predicted: np.ndarray | None = None) -> RobustWeights:
    """Robust weights and rejected samples of a fit's raw residuals ``(N, 3)`` (module notes).

    Parameters
    ----------
    residuals : (N, 3) array_like
        ``dv - S D`` of every sample, m/s, in time order.
    t : (N,) array_like
        Sample times, s.
    noise : NoiseModel
        Correlation time and relative scale per axis.
    function : {"huber", "bisquare"}
    scale : float, optional
        Known innovation scale (the x-axis noise std, m/s); default 1.4826 MAD of the innovations, per stretch of
        the tracking (:func:`stretches`: split at its pauses, as the outlier check judges them), so that a noisier
        stretch after a reacquisition is judged by its own noise, not the quiet one's, and its rows weighted by it
        (``precision``); epochs outside a stretch take the whole flight's.
    reject : float, optional
        Rejection threshold in scale units (default :data:`REJECT` for Huber, ``c`` for bisquare).
    floor : float, optional
        Least innovation scale, m/s: what the data carry without noise (rounding, the interpolation of a pair
        of files; :func:`casep.regression.problem.is_rounding_level`). On noise-free data the MAD is ~0 and,
        unfloored, every rounding-level residual would be a rejection.
    predicted : (N, 3, r) array_like, optional
        The fit's prediction factor ``G = S L`` (m/s; ``S`` the rows' sensitivities, ``L L^T`` the fit's
        coefficient covariance): the innovations' variance gains the fit's prediction variance (module notes),
        in the rejections and the weights (``u`` stays the innovation over the noise alone).
    """
    if function not in ROBUST_FUNCTIONS:
        raise ValueError(f"`robust` must be one of {', '.join(ROBUST_FUNCTIONS)}, got {function!r}")
    e = np.asarray(residuals, dtype=float)
    t = np.asarray(t, dtype=float)
    N = e.shape[0]
    c = HUBER_C if function == "huber" else BISQUARE_C
    thr = float(reject) if reject is not None else (REJECT if function == "huber" else BISQUARE_C)
    # pass 1: innovations from the previous sample; scale from their MAD (glitches are few)
    keep = np.ones(N, dtype=bool)
    nu = _innovations(e, t, noise, keep)
    s = float(scale) if scale is not None else _mad_scale(nu)
    s = max(s, float(floor))  # s = max(1.4826 MAD, floor)
    if not s > 0:
        return RobustWeights(keep, np.ones_like(e), np.zeros_like(e), 0.0)
    sk = np.full(N, s)  # each sample's scale: its stretch's (a stretch without scatter of its own: the flight's)
    if scale is None and N == t.size:
        for a, b in stretches(t):
            sk[a:b] = max(_mad_scale(nu[a:b]), float(floor)) or s
    G = None if predicted is None else np.asarray(predicted, dtype=float)
    if G is not None and G.shape[:2] != e.shape:
        raise ValueError(f"`predicted` must have the shape (N, 3, r) of the residuals (N, 3), got {G.shape}")
    # pass 2: sequential, from the last accepted sample (a rejected one is a gap)
    keep = _sequential(e, t, noise, sk, thr, G)
    nu = _innovations(e, t, noise, keep)
    u = nu / sk[:, None]
    au = np.abs(u)
    if G is not None:  # Huber's weight is 1 up to c whatever widens the innovation: those rows need no inflation
        rows = np.flatnonzero(np.any(au > c, axis=1)) if function == "huber" else np.arange(N)
        au[rows] /= _inflation(t, noise, keep, sk, G, rows)
    if function == "huber":
        w = np.minimum(1.0, c / np.maximum(au, 1e-300))  # w = min(1, c / |u|)
    else:
        w = np.where(au < c, (1.0 - (u / c) ** 2) ** 2, 0.0)  # Tukey's bisquare
    w[~keep] = 1.0
    return RobustWeights(keep, w, u, s, None if np.all(sk == s) else (s / sk) ** 2)


def _inflation(t: np.ndarray, noise: NoiseModel, keep: np.ndarray, sk: np.ndarray, G: np.ndarray,
               rows: np.ndarray) -> np.ndarray:
    """``sqrt(1 + |G_k - a_k G_j|^2 / ((r_a s_k)^2 (1 - a_k^2)))`` (len(rows), 3) of the samples `rows`: by how much the
    fit's prediction variance widens each innovation (``j`` the last kept sample before ``k``; ``|G_k|^2`` over
    ``(r_a s_k)^2`` on a white axis and with no ``j``)."""
    idx = np.flatnonzero(keep)
    pos = np.searchsorted(idx, rows, side="left") - 1
    last = np.where(pos >= 0, idx[np.maximum(pos, 0)], -1)
    has = last >= 0
    out = np.empty((rows.size, 3))
    for j in range(3):
        var = (sk[rows] * noise.scale[j]) ** 2
        d = G[rows, j].copy()
        if noise.tau[j] is not None:
            a, b = ar1_terms(t[rows[has]] - t[last[has]], noise.tau[j])
            d[has] -= a[:, None] * G[last[has], j]
            var[has] *= b
        out[:, j] = np.sqrt(1.0 + np.sum(d**2, axis=1) / var)
    return out


def _mad_scale(nu: np.ndarray) -> float:
    """1.4826 MAD of innovations ``(n, 3)`` (their median per axis removed), all axes together."""
    return float(MAD_SIGMA * np.median(np.abs(nu - np.median(nu, axis=0))))


def _sequential(e: np.ndarray, t: np.ndarray, noise: NoiseModel, s: np.ndarray, thr: float,
                G: np.ndarray | None = None) -> np.ndarray:
    """Keep mask of the sequential filter (compiled: :func:`casep._kernels.robust_filter_keep`), its start
    decided backward.

    Forward, a sample with no accepted sample before it has no prediction: it is judged by its
    own size ``e_k / (r_a s)``. A flight whose residuals start away from zero (a level the noise
    carries over from before tracking began) would lose its first samples as a run. A stationary
    AR(1) process reads the same backward, so the samples before ``k0``, the first sample both
    directions keep, are judged backward, each from the next kept sample; from ``k0`` on the
    forward decisions stand (each depends only on the kept samples from ``k0``).
    """
    keep = _forward(e, t, noise, s, thr, G)
    if keep.size == 0 or keep[0]:
        return keep  # the first sample has no prediction but passed: nothing to decide backward
    back = _forward(e[::-1], t[-1] - t[::-1], noise, s[::-1], thr, None if G is None else G[::-1])[::-1]  # reversed
    both = np.flatnonzero(keep & back)
    if both.size:
        keep[:both[0]] = back[:both[0]]
    return keep


def _forward(e: np.ndarray, t: np.ndarray, noise: NoiseModel, s: np.ndarray, thr: float,
             G: np.ndarray | None = None) -> np.ndarray:
    from casep._kernels import robust_filter_keep

    inv_tau = np.array([0.0 if tau is None else 1.0 / tau for tau in noise.tau])
    scale = np.asarray(s, dtype=float)[:, None] * np.asarray(noise.scale, dtype=float)  # (N, 3): each sample's
    keep = np.ones(e.shape[0], dtype=np.bool_)
    robust_filter_keep(np.ascontiguousarray(e, dtype=float), np.ascontiguousarray(t, dtype=float), inv_tau, scale,
                       float(thr), MAX_RUN, keep, None if G is None else np.ascontiguousarray(G))
    return keep

"""Inner loops that numpy alone does not express: the S_V recursions, the robust filter, RLS/RELS.

numba (``cache=True``, :mod:`casep._compiled`) is imported on the first call that needs it, not when
casep is imported: its import and the set-up of its target on the first cached kernel take about 0.3 s,
longer than a short flight's whole computation. So:

- :func:`sv_integrate_chunk`: two running trapezoid sums, in numpy (``np.cumsum``: a sequential
  accumulation, the same additions in the same order as the compiled loop, so the same numbers) for a
  flight of up to :data:`NUMPY_SAMPLES` samples, compiled for a longer one;
- :func:`robust_filter_keep`: vectorised while every sample is kept, the scalar recursion (``math``, as the
  compiled loop it replaced) near the threshold and after a rejection;
- :func:`lfilter`: the all-pole filter of RELS, a loop over Python floats for up to :data:`PYTHON_FILTER_STEPS`
  steps (:func:`all_pole_filter_python`), compiled beyond (``scipy.signal`` would cost more to import);
- :func:`rels_ud`: the Bierman U-D recursion, compiled;
- :func:`ar1_terms`: the one place of the AR(1) step coefficients ``a = exp(-dt / tau)`` and
  ``1 - a^2 = -expm1(-2 dt / tau)`` (no cancellation when ``dt << tau``); every whitening of casep calls it;
- :func:`cumulative_trapezoid`: the running trapezoid integral of samples over their times, zero at the first
  sample, the one place of that sum (``np.cumsum`` of ``(y_(k-1) + y_k) / 2 * dt_k``: sequential, so the same numbers
  as the loop);
- :func:`runs`: the runs of True in a mask (start, end), the one run-length rule of the robust fit's misfit
  check and of the saturation and static-pose checks;
- :func:`gmw_filter`: the innovations (Kalman-filter) whitening of Gauss-Markov plus white noise, compiled
  (:func:`gmw_filter_numpy`: the same recursion as a plain loop, the reference of the tests);
- :func:`joint_filter`: the same whitening with a known linear noise state beside it (the IMU's own noise),
  compiled (:func:`joint_filter_numpy`: its reference);
- :func:`reml_scale_fit`: the REML fixed point of the noise model's axis scales and ``-2 l_R`` there, compiled
  (:meth:`casep.noise.fit.Reml._fit_scales` with numpy's LAPACK kernels: its reference).

The callers (:mod:`casep.model.sv`, :mod:`casep.noise.robust`, :mod:`casep.estimators.rls`, :mod:`casep.noise.fit`)
validate every argument. ``tests/test_kernels.py`` checks each against the compiled loop, a plain loop or scipy, bit
for bit; the two with matrix factorisations (:func:`joint_filter`, :func:`reml_scale_fit`) against numpy's to the
rounding (``tests/noise/test_noise_known.py``, ``tests/noise/test_reml_compiled.py``).
"""

from __future__ import annotations

import math
import sys
from typing import Callable, cast

import numpy as np

__all__ = ["ar1_long_run_factor", "ar1_terms", "cumulative_trapezoid", "runs", "gmw_filter", "gmw_filter_numpy",
           "joint_filter", "joint_filter_numpy", "reml_scale_fit",
           "robust_filter_keep", "sv_integrate_chunk", "sv_integrate_chunk_numpy", "rels_ud", "lfilter",
           "NUMPY_SAMPLES", "PYTHON_FILTER_STEPS", "all_pole_filter_python"]


#: The longest flight whose S_V :func:`sv_integrate_chunk` integrates in numpy (unless numba is loaded already);
#: a longer one is compiled from its first sample. numba's import and the set-up of its target on the first
#: cached kernel cost about 0.4 s of CPU; numpy's sums cost about 2.5 us a sample more than the compiled
#: loop's (platform36, CasADi's Jacobians included in both): a flight of 131 072 samples (22 min at 100 Hz)
#: loses at most 0.33 s to numpy, a shorter one saves numba's set-up whenever nothing else needs it
#: (``casep separate`` on a 100 Hz range flight).
NUMPY_SAMPLES = 1 << 17

#: The most samples times the filter's order (one at least) that :func:`lfilter`'s all-pole filter runs as a loop over
#: Python floats (:func:`all_pole_filter_python`) instead of the compiled kernel: 0.3-0.7 us a step, 0.04-0.09 s at
#: this size, against 0.3-0.5 s of CPU to compile the kernel on its first call (a new clone, a new numba cache) and
#: about 0.1 s to load it from numba's cache (``casep demo``'s RELS: 58 503 steps twice).
PYTHON_FILTER_STEPS = 1 << 17


def cumulative_trapezoid(y: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The trapezoid integral of the samples `y` (N, ...) over their times `t` (N,) from the first sample, (N, ...):
    ``Y_0 = 0``, ``Y_k = Y_(k-1) + (y_(k-1) + y_k) / 2 * (t_k - t_(k-1))``, a sequential sum along the first axis."""
    y = np.asarray(y, dtype=float)
    dt = np.diff(np.asarray(t, dtype=float)).reshape((-1,) + (1,) * (y.ndim - 1))
    out = np.zeros_like(y)
    np.cumsum(0.5 * (y[1:] + y[:-1]) * dt, axis=0, out=out[1:])
    return out


def runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """The runs of True in `mask`: (start, end) with end excluded, in order."""
    d = np.diff(np.concatenate([[0], np.asarray(mask, dtype=np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist()))


def ar1_terms(dt, tau) -> tuple[np.ndarray, np.ndarray]:
    """``(a, 1 - a^2)`` of an AR(1) step of length `dt` (s) for correlation time `tau` (s), elementwise::

        a = exp(-dt / tau),     1 - a^2 = -expm1(-2 dt / tau)

    The second form keeps its digits when ``dt << tau`` (``1 - a**2`` loses ``log10(tau / dt)`` of
    them). ``dt = inf`` (no previous sample) gives ``a = 0``, ``1 - a^2 = 1``.
    """
    x = np.asarray(dt, dtype=float) / tau
    return np.exp(-x), -np.expm1(-2.0 * x)


def gmw_filter(X: np.ndarray, dt: np.ndarray, tau: float, share: float, m: np.ndarray, P: np.ndarray,
               out: np.ndarray) -> float:
    """Whiten the columns of `X` (K, k) for unit-variance Gauss-Markov plus white noise; returns ``sum ln F_k``.

    The noise is ``e_k = g_k + v_k`` with ``g`` AR(1) of correlation time `tau` and variance
    ``q = 1 - share``, ``v`` white of variance `share`. The Kalman filter of ``g`` (gains from the
    times and the parameters only, so one recursion whitens every column)::

        P_k^- = a_k^2 P_(k-1) + q (1 - a_k^2),   F_k = P_k^- + share,   K_k = P_k^- / F_k
        u_k = (x_k - a_k m_(k-1)) / sqrt(F_k),   m_k = a_k m_(k-1) + K_k (x_k - a_k m_(k-1)),
        P_k = P_k^- share / F_k

    ``dt`` (K,): time from the previous sample (``inf`` for the first of a series: ``P^- = q``);
    ``m`` (k,) and ``P`` (1,): the filter state, carried in place from block to block; `out` (K, k)
    the whitened rows. ``share = 0`` is AR(1) (``K = 1``, ``m_k = x_k`` exactly). Compiled
    (:func:`casep._compiled.gmw_filter`); :func:`gmw_filter_numpy` is the same recursion in Python.
    """
    from casep._compiled import gmw_filter as kernel

    return float(kernel(X, dt, float(tau), float(share), m, P, out))


def gmw_filter_numpy(X: np.ndarray, dt: np.ndarray, tau: float, share: float, m: np.ndarray, P: np.ndarray,
                     out: np.ndarray) -> float:
    """:func:`gmw_filter` as a plain loop over the samples (the reference of the compiled kernel)."""
    q = 1.0 - share
    a_all, b_all = ar1_terms(dt, tau)
    logdet = 0.0
    for k in range(X.shape[0]):
        a, b = float(a_all[k]), float(b_all[k])
        Pm = a * a * P[0] + q * b  # P_k^- = a^2 P + q (1 - a^2)
        F = Pm + share
        nu = X[k] - a * m  # x_k - a_k m_(k-1)
        out[k] = nu * (1.0 / math.sqrt(F))
        if share == 0.0:
            m[:] = X[k]  # K = 1: the state is the sample
        else:
            m[:] = a * m + (Pm / F) * nu
        P[0] = Pm * share / F
        logdet += math.log(F)
    return logdet


def joint_filter(X: np.ndarray, T: np.ndarray, Q: np.ndarray, H: np.ndarray, P0: np.ndarray, a: np.ndarray,
                 qb: np.ndarray, d: np.ndarray, out: np.ndarray) -> float:
    """Whiten rows ``X`` (M, 3, k) of Gauss-Markov plus white noise per axis plus a known linear state; returns
    ``sum ln det F_r`` (inf where ``F_r`` is not positive definite).

    Per epoch r: the state ``x = (z, g)`` (s + 3), ``z_r = T_r z_(r-1) + w``, ``Cov w = Q_r``, ``z_(-1) ~ N(0,
    P0)``; ``g_(a,r) = a_(a,r) g_(a,r-1) + n``, ``Var n = qb_(a,r)`` (``c_a (1 - a^2)``); the rows ``e_r = H_r z_r
    + g_r + v_r``, ``Var v_a = d_a``. With ``Hx = [H_r  I]`` and the predicted ``m^-``, ``P^-``::

        F_r = Hx P^- Hx^T + diag d = L L^T,   u_r = L^-1 (x_r - Hx m^-),   W = P^- Hx^T L^-T,
        m_r = m^- + W u_r,                    P_r = P^- - W W^T

    (``W u = K nu`` and ``W W^T = K F K^T`` of the Kalman gain ``K = P^- Hx^T F^-1``); `out` (3M, k) the rows
    ``u_r``. Compiled (:func:`casep._compiled.joint_filter`); :func:`joint_filter_numpy` is the same recursion in
    numpy.
    """
    from casep._compiled import joint_filter as kernel

    return float(kernel(X, T, Q, H, P0, a, qb, d, out))


def reml_scale_fit(Ms: np.ndarray, scales: np.ndarray, n_samples: int, p: int, logdets: np.ndarray
                   ) -> tuple[float, tuple[float, float, float], bool]:
    """The axis scales ``r_a`` at their REML fixed point, started from `scales` (3,), and ``-2 l_R`` there:
    ``(value, scales, ok)`` (:mod:`casep.noise.fit`'s notes).

    `Ms` (3, p + 1, p + 1) C-contiguous: each axis' Gram matrix ``[Z_w y_w]^T [Z_w y_w]`` at unit scale (`p` the
    estimable combinations); `logdets` (3,): each axis' ``sum_k ln F_k``; `n_samples`: ``N`` per axis. Each step
    factors ``G = sum_a M_a / r_a^2 = T^T T`` and sets ``r_a^2 = RSS_a / (N - h_a)`` (``h_a = tr(M_a,pp
    (T_p^T T_p)^-1)``), normalised to ``r_x = 1``, until ``ln r`` moves less than ``max(1e-7, 10 eps
    max_a M_a,yy / RSS_a)`` (at most 50 steps); the value is ``(3N - p) ln T_pp^2 + 2 sum_j ln T_jj + sum_a (N ln
    r_a^2 + logdet_a)``. ``ok`` False: a step where ``G`` is not definite or an axis' RSS vanishes (its scales
    returned, the value inf); the value is inf too where ``G`` at the scales found is not definite.

    Compiled (:func:`casep._compiled.reml_scale_fit`: Cholesky, triangular inverse and products by scalar loops,
    each step of :meth:`casep.noise.fit.Reml._scale_steps` and the value of :meth:`casep.noise.fit.Reml._value`);
    those two with numpy's LAPACK kernels are its reference: the same steps, the numbers to the rounding of the
    factorisations (a step that lands within that rounding of the stop rule's tolerance may take one step more or
    less: scales within the tolerance, 1e-7 in ``ln r``).
    """
    from casep._compiled import reml_scale_fit as kernel

    val, sc, ok = kernel(Ms, scales, int(n_samples), int(p), logdets)
    return float(val), (float(sc[0]), float(sc[1]), float(sc[2])), bool(ok)


def joint_filter_numpy(X, T, Q, H, P0, a, qb, d, out) -> float:
    """:func:`joint_filter` with numpy's matrices (the reference of the compiled kernel)."""
    M, _, k = X.shape
    s = T.shape[1]
    m = np.zeros((s + 3, k))
    P = np.zeros((s + 3, s + 3))
    P[:s, :s] = P0
    logdet = 0.0
    for r in range(M):
        Phi = np.zeros((s + 3, s + 3))
        Phi[:s, :s], Phi[s:, s:] = T[r], np.diag(a[r])
        P = Phi @ P @ Phi.T
        P[:s, :s] += Q[r]
        P[s:, s:] += np.diag(qb[r])
        m = Phi @ m
        Hx = np.concatenate([H[r], np.eye(3)], axis=1)
        PH = P @ Hx.T
        try:
            L = np.linalg.cholesky(Hx @ PH + np.diag(d))
        except np.linalg.LinAlgError:
            return math.inf
        out[3 * r:3 * r + 3] = np.linalg.solve(L, X[r] - Hx @ m)
        W = np.linalg.solve(L, PH.T).T
        m = m + W @ out[3 * r:3 * r + 3]
        P = P - W @ W.T
        logdet += 2.0 * float(np.sum(np.log(np.diag(L))))
    return logdet


def sv_integrate_chunk(n_samples: int) -> Callable[..., None]:
    """The kernel that trapezoid-integrates one chunk of S_V in place, for a flight of `n_samples` samples.

    The kernel's arguments (see :mod:`casep.model.sv` for the equations): ``G`` (K, 3, ng), ``A`` (K, 3,
    na): Jacobians per sample; ``f`` (K, 3); ``half_dt`` (K,) = dt_k / 2; ``gcols``, ``acols``: their
    columns; ``phi`` (3, ng), ``G_prev`` (3, ng), ``I_prev`` (3, n), ``S_prev`` (3, n): carries, updated
    in place; ``out`` (K, 3, n): S_V rows of the chunk.

    :func:`sv_integrate_chunk_numpy` for a flight of up to :data:`NUMPY_SAMPLES` samples (unless numba is
    loaded already), the compiled loop for a longer one: the same additions in the same order, so the
    same numbers (``tests/test_kernels.py``).
    """
    if "casep._compiled" in sys.modules or n_samples > NUMPY_SAMPLES:
        from casep._compiled import sv_integrate_chunk as kernel

        return cast(Callable[..., None], kernel)
    return sv_integrate_chunk_numpy


def sv_integrate_chunk_numpy(G, A, f, half_dt, gcols, acols, phi, G_prev, I_prev, S_prev, out) -> None:
    """The kernel of :func:`sv_integrate_chunk` in numpy: each running sum one ``np.cumsum`` (sequential)."""
    K = G.shape[0]
    if K == 0:
        return
    h = half_dt[:, None, None]
    # Phi_k = Phi_{k-1} + (G_{k-1} + G_k) dt_k / 2
    Phi = _running_trapezoid(phi, G_prev, G, h)  # (K, 3, ng)
    # I_k (from zero) += [f x] Phi_k in the gyro columns, then += the Delta Jacobian in the accelerometer columns
    fx, fy, fz = f[:, 0, None], f[:, 1, None], f[:, 2, None]
    Icur = np.zeros((K,) + I_prev.shape)
    _add_columns(Icur, gcols, np.stack([fy * Phi[:, 2] - fz * Phi[:, 1],  # (fy Phi_z - fz Phi_y,
                                        fz * Phi[:, 0] - fx * Phi[:, 2],  #  fz Phi_x - fx Phi_z,
                                        fx * Phi[:, 1] - fy * Phi[:, 0]], axis=1))  # fx Phi_y - fy Phi_x)
    _add_columns(Icur, acols, A)
    # S_k = S_{k-1} + (I_{k-1} + I_k) dt_k / 2
    out[:] = _running_trapezoid(S_prev, I_prev, Icur, h)
    # carries for the next chunk
    phi[:] = Phi[-1]
    G_prev[:] = G[-1]
    I_prev[:] = Icur[-1]
    S_prev[:] = out[-1]


def _running_trapezoid(start: np.ndarray, last: np.ndarray, values: np.ndarray, h: np.ndarray) -> np.ndarray:
    """``X_k = X_(k-1) + (v_(k-1) + v_k) h_k`` for k = 1..K from ``X_0 = start``, ``v_0 = last``: (K, ...)."""
    acc = np.empty((values.shape[0] + 1,) + start.shape)
    acc[0] = start
    inc = acc[1:]
    np.add(last, values[0], out=inc[0])
    np.add(values[:-1], values[1:], out=inc[1:])
    inc *= h
    return np.cumsum(acc, axis=0, out=acc)[1:]  # a sequential accumulation: the loop's additions


def _add_columns(target: np.ndarray, cols: np.ndarray, values: np.ndarray) -> None:
    """``target[:, :, cols[j]] += values[:, :, j]`` for each j in order (a repeated column sums its terms)."""
    if cols.size == 0:
        return
    if cols.size == 1 or np.all(np.diff(cols) == 1):  # a range: a view
        target[:, :, cols[0]:cols[-1] + 1] += values
    elif np.unique(cols).size == cols.size:  # distinct columns
        target[:, :, cols] += values
    else:
        for j, c in enumerate(cols):
            target[:, :, c] += values[:, :, j]


def rels_ud(H, y, x, U, D, weight, forgetting, n_c, posterior, stride, history, history_var, D0, past, k0):
    """Recursive (extended) least squares with Bierman's U-D scalar updates, in place
    (:func:`casep._compiled.rels_ud`, compiled by numba on the first call). A read-only `y` is copied: numba
    compiles a read-only array as another signature (1.5 s of CPU more)."""
    from casep._compiled import rels_ud as kernel

    y = np.require(y, requirements=("C", "W"))

    return kernel(H, y, x, U, D, weight, forgetting, n_c, posterior, stride, history, history_var, D0, past, k0)


def lfilter(b, a, x, axis: int = -1) -> np.ndarray:
    """``scipy.signal.lfilter(b, a, x, axis)``; an all-pole filter (``b = [1]``, ``a[0] = 1``) of a 2-D `x` along
    axis 0 as a loop over Python floats up to :data:`PYTHON_FILTER_STEPS` steps (:func:`all_pole_filter_python`),
    compiled beyond (:func:`casep._compiled.all_pole_filter`): the same operations, so the same numbers, without
    importing ``scipy.signal`` (0.3-0.5 s with the ``scipy.stats`` it imports)."""
    a = np.asarray(a, dtype=float)
    x = np.asarray(x)
    ax = axis % x.ndim if x.ndim else axis
    if list(np.ravel(b)) == [1.0] and a.ndim == 1 and a.size and a[0] == 1.0 and x.ndim == 2 and ax == 0 \
            and x.dtype == np.float64:
        y = np.empty_like(x)
        if x.size * max(a.size - 1, 1) <= PYTHON_FILTER_STEPS:
            all_pole_filter_python(a, x, y)
        else:
            from casep._compiled import all_pole_filter

            all_pole_filter(np.ascontiguousarray(a), x, y)
        return y
    from scipy.signal import lfilter as scipy_lfilter

    return scipy_lfilter(b, a, x, axis=axis)


def all_pole_filter_python(a: np.ndarray, x: np.ndarray, y: np.ndarray) -> None:
    """:func:`casep._compiled.all_pole_filter` (``y = lfilter([1], a, x, axis=0)``, x and y (N, m), ``a[0] = 1``) as a
    loop over Python floats: the same operations in the same order (IEEE doubles both), so the same numbers."""
    N, m = x.shape
    K = a.size - 1
    coef = [float(v) for v in a]
    for j in range(m):
        col = x[:, j].tolist()
        out = [0.0] * N
        if K == 0:
            out = [xn * 1.0 for xn in col]
        else:
            Z = [0.0] * K
            for k, xn in enumerate(col):
                yn = Z[0] + 1.0 * xn  # y = z_0 + b_0 x
                for i in range(K - 1):
                    Z[i] = Z[i + 1] + xn * 0.0 - yn * coef[i + 1]  # z_i = z_(i+1) + b_(i+1) x - a_(i+1) y
                Z[K - 1] = xn * 0.0 - yn * coef[K]
                out[k] = yn
        y[:, j] = out


def robust_filter_keep(e, t, inv_tau, scale, thr, max_run, keep, pred=None) -> None:
    """Sequential robust filter (see :mod:`casep.noise.robust`): reject a sample whose innovation
    from the last kept one exceeds ``thr`` on any axis, at most ``max_run`` in a row.

    e (N, 3) residuals; t (N,); inv_tau (3,) = 1 / tau (0 for white); scale (3,) = r_a s, or (N, 3): each sample's
    (a noise level per stretch of the tracking); keep (N,) bool, written; pred (N, 3, r), optional: each sample's
    fitted value's factor ``G_k = S_k L`` (``L L^T`` the fit's coefficient covariance): the innovation from sample
    ``j`` has the variance ``(scale_k^2 (1 - a^2) + |G_k - a G_j|^2)`` (``|G_k|^2`` added on a white axis and
    for a sample with no prediction), the Kalman filter's ``H P H^T + R``.

    While every sample is kept the last kept one is the previous sample, so the innovations are
    computed for all samples at once; the samples near or over the threshold, and the run after a
    rejection, are then decided one by one with the scalar formula (``math``: the numbers of the
    compiled loop this replaces). Glitches are rare, so the loop is short.
    """
    with np.errstate(divide="ignore", invalid="ignore"):  # as compiled: a zero step or scale gives inf, not a warning
        _robust_filter_keep(e, t, inv_tau, scale, thr, max_run, keep, pred)


def _robust_filter_keep(e, t, inv_tau, scale, thr, max_run, keep, pred=None) -> None:
    N = e.shape[0]
    keep[:] = True
    if N == 0:
        return
    scale = np.broadcast_to(np.asarray(scale, dtype=float), e.shape)  # each sample's scale
    # innovation of each sample from the previous one: nu_k = (e_k - a_k e_{k-1}) / (scale_k sqrt(1 - a_k^2)),
    # a_k = exp(-dt_k / tau); e_k / scale_k on a white axis and for the first sample
    # with `pred` the innovations' variance only grows: the candidates of the noise alone include every rejection,
    # and each is decided below with the prediction's variance (a glitch is rare, so is the scalar formula)
    nu = e / scale
    a, b = ar1_terms(np.diff(t)[:, None] * inv_tau, 1.0)  # a_k, 1 - a_k^2 of dt_k / tau
    corr = (e[1:] - a * e[:-1]) / (scale[1:] * np.sqrt(b))
    nu[1:] = np.where(inv_tau == 0.0, nu[1:], corr)
    near = np.abs(nu).max(axis=1) > thr * (1.0 - 1e-9)  # decided exactly below
    near |= ~np.isfinite(nu).all(axis=1)
    candidates = np.flatnonzero(near)
    k = 0
    for c in candidates:
        if c < k:
            continue  # decided in the run of an earlier candidate
        k = int(c)  # samples before it kept: the last kept one is k - 1
        last = k - 1
        run = 0
        while k < N:
            if _big(e, t, inv_tau, scale, thr, k, last, pred) and run < max_run:
                keep[k] = False
                run += 1
                k += 1
            else:
                last = k  # kept: the filter is back on the previous sample
                k += 1
                break


def _big(e, t, inv_tau, scale, thr, k: int, last: int, pred=None) -> bool:
    """Whether sample k's innovation from sample `last` (-1: none) exceeds `thr` on any axis."""
    for j in range(3):
        if inv_tau[j] == 0.0 or last < 0:
            sd = scale[k, j] if pred is None else math.sqrt(scale[k, j] ** 2 + float(pred[k, j] @ pred[k, j]))
            nu = e[k, j] / sd
        else:
            a, b = ar1_terms((t[k] - t[last]) * inv_tau[j], 1.0)  # a_k, 1 - a_k^2
            if pred is None:
                nu = (e[k, j] - float(a) * e[last, j]) / (scale[k, j] * math.sqrt(float(b)))
            else:
                d = pred[k, j] - float(a) * pred[last, j]
                nu = (e[k, j] - float(a) * e[last, j]) / math.sqrt(scale[k, j] ** 2 * float(b) + float(d @ d))
        if abs(nu) > thr:
            return True
    return False


def ar1_long_run_factor(num: np.ndarray | float, den: np.ndarray | float, rho_max: float = 0.999) -> np.ndarray:
    """``(1 + rho) / (1 - rho)`` with ``rho = num / den`` (the lag-1 autocorrelation of residuals: ``num`` the sum
    of products of consecutive residuals, ``den`` the sum of squares) clipped to [0, `rho_max`]: the long-run
    variance of AR(1) noise over its variance, the factor by which white-noise least squares understates the
    variance of a smooth regressor's coefficient (or of a mean) in such noise (at least 1; 1999 at most with the
    default `rho_max`)."""
    rho = np.clip(np.asarray(num, dtype=float) / np.maximum(np.asarray(den, dtype=float), 1e-300), 0.0, rho_max)
    return (1.0 + rho) / (1.0 - rho)

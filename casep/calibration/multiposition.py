"""Model ``multiposition``: calibration of a hand-turned session from gravity alone (no turntable, no labels).

Convention (imu_tk's, Tedaldi, Pretto and Menegatti, ICRA 2014): the calibrated reading is

    a_cal = T_a K_a (a - b_a),      w_cal = T_g K_g (w - b_g)

with ``K = diag(s_x, s_y, s_z)`` (SI per reading unit: 1 for readings already in m/s^2 or rad/s,
~1e-3 for raw counts) and the misalignment (small angles, rad)

    T_a = [[1, -a_yz, a_zy], [0, 1, -a_zx], [0, 0, 1]]                 (upper triangular: the
    T_g = [[1, -g_yz, g_zy], [g_xz, 1, -g_zx], [-g_xy, g_yx, 1]]        accelerometer x axis defines the frame)

Beside them, casep's ``ferraris`` names and units (the reading as a function of the truth,
``y = M f + b``, ``docs/guide/calibration.md``): ``M_a = (T_a K_a)^-1`` (``Ma_ij``, reading unit per
m/s^2), ``ba_i = b_a`` (reading unit); ``M_g = (T_g K_g)^-1`` (``Mg_ij``, reading unit per rad/s),
``bg_i = b_g``; their std by the delta method.

Accelerometer: at rest ``|a_cal| = g`` in every pose: the residual of pose k (its mean reading
``abar_k`` over ``n_k`` samples, weight ``sqrt(n_k / mean n)``)

    r_k = sqrt(n_k / nbar) (|T_a K_a (abar_k - b_a)| - g)

minimised by Levenberg-Marquardt on the analytic Jacobian (column-scaled, so raw counts near 32768
and scales of 1e-3 are one problem). The covariance is that of the final linearisation scaled by
the residual: ``C = s^2 (J^T J)^-1``, ``s^2 = sum r_k^2 / (m - 9)``.

Gyro: the bias is the mean gyro reading over all poses (the Earth's rate, <= 7.3e-5 rad/s, is
neglected). Over the motion j between poses j and j+1, the calibrated rate, held over each sample
interval ``dt``, turns the sensor by ``R_j = prod_k exp([w_cal,k dt]x)`` (the quaternion integral
as rotation matrices, composed pairwise). Gravity is fixed in the world, so its direction
measured by the calibrated accelerometers, ``u_j = a_cal,j / |a_cal,j|``, must satisfy

    r_j = R_j^T u_j - u_{j+1} = 0       (3 components, 2 independent)

solved by Levenberg-Marquardt on a forward-difference Jacobian (9 coefficients: 6 misalignments,
3 scales); ``C = s^2 (J^T J)^-1``, ``s^2 = sum |r_j|^2 / (2 m - 9)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from casep.regression.linalg import covariance_std

__all__ = ["AccFit", "GyroFit", "fit_accelerometer", "fit_gyro", "acc_matrix", "gyro_matrix", "rotations",
           "integrate_motions", "gyro_residuals", "ACC_NAMES", "GYRO_NAMES"]

#: imu_tk's accelerometer parameters (misalignment rad, scale SI per reading unit, bias reading unit).
ACC_NAMES = ("a_yz", "a_zy", "a_zx", "sa_x", "sa_y", "sa_z", "ba_x", "ba_y", "ba_z")
#: imu_tk's gyro parameters (misalignment rad, scale SI per reading unit); the bias apart.
GYRO_NAMES = ("g_yz", "g_zy", "g_xz", "g_zx", "g_xy", "g_yx", "sg_x", "sg_y", "sg_z")


def acc_matrix(x: np.ndarray) -> np.ndarray:
    """``T_a K_a`` of the accelerometer parameters `x` (ACC_NAMES order)."""
    a_yz, a_zy, a_zx = x[:3]
    T = np.array([[1.0, -a_yz, a_zy], [0.0, 1.0, -a_zx], [0.0, 0.0, 1.0]])
    return T * np.asarray(x[3:6])[None, :]


def gyro_matrix(x: np.ndarray) -> np.ndarray:
    """``T_g K_g`` of the gyro parameters `x` (GYRO_NAMES order)."""
    g_yz, g_zy, g_xz, g_zx, g_xy, g_yx = x[:6]
    T = np.array([[1.0, -g_yz, g_zy], [g_xz, 1.0, -g_zx], [-g_xy, g_yx, 1.0]])
    return T * np.asarray(x[6:9])[None, :]


def _lm(fun, x0: np.ndarray, max_iter: int = 100, tol: float = 1e-13):
    """Levenberg-Marquardt: ``fun(x) -> (r, J)``; column-scaled steps; returns (x, r, J, iterations, converged)."""
    x = np.asarray(x0, dtype=float).copy()
    r, J = fun(x)
    cost, lam = float(r @ r), 1e-6
    for it in range(1, max_iter + 1):
        d = np.linalg.norm(J, axis=0)
        d[d == 0] = 1.0
        Js = J / d
        # (Js^T Js + lam I) z = -Js^T r, as the least-squares problem [Js; sqrt(lam) I] z = [-r; 0]
        A = np.vstack([Js, math.sqrt(lam) * np.eye(len(x))])
        z = np.linalg.lstsq(A, np.concatenate([-r, np.zeros(len(x))]), rcond=None)[0]
        dx = z / d
        xn = x + dx
        rn, Jn = fun(xn)
        cn = float(rn @ rn)
        if np.isfinite(cn) and cn <= cost:
            small = np.all(np.abs(dx) <= tol * (np.abs(x) + tol)) or cost - cn <= 1e-10 * cost
            x, r, J, cost, lam = xn, rn, Jn, cn, max(lam / 10.0, 1e-12)
            if small:
                return x, r, J, it, True
        else:
            lam *= 10.0
            if lam > 1e12:
                return x, r, J, it, cost == 0.0
    return x, r, J, max_iter, False


def _covariance(J: np.ndarray, r: np.ndarray, dof: int) -> tuple[np.ndarray, float]:
    """``s^2 (J^T J)^-1`` with ``s^2 = r.r / dof``, and s: the covariance of the last linearisation.

    The Gauss-Newton step of the last linearisation, ``J dx = -r``, is solved as a casep estimate (least
    squares on a :class:`~casep.regression.problem.Problem`: column-scaled QR and its rank analysis, the
    one linear solve of casep), of known noise std s; its covariance is the fit's. The damped
    Levenberg-Marquardt steps before it (:func:`_lm`) are an optimiser's trial steps, not estimates.
    """
    from casep.estimators.ols import solve_ols
    from casep.regression.problem import Problem

    s2 = float(r @ r) / dof if dof > 0 else math.nan
    if not s2 > 0:  # no residual dof, or a fit exact to the last digit: no noise level to scale by
        d = np.linalg.norm(J, axis=0)
        d[d == 0] = 1.0
        return (s2 if s2 == s2 else math.nan) * np.linalg.pinv((J / d).T @ (J / d)) / np.outer(d, d), \
            math.sqrt(s2) if s2 == s2 else math.nan
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # conditioning: judged by the calibration's own checks
        step = solve_ols(Problem.from_arrays(J, -r), sigma=math.sqrt(s2))
    cov = np.asarray(step.covariance, dtype=float)
    return np.where(np.isfinite(cov), cov, math.nan), math.sqrt(s2)


@dataclass(frozen=True)
class AccFit:
    """Accelerometer fit: ``x`` (ACC_NAMES), its covariance, the residual per pose (|a_cal| - g, m/s^2),
    the (weighted) Jacobian of the final linearisation."""

    x: np.ndarray
    covariance: np.ndarray
    residuals: np.ndarray
    sigma: float
    iterations: int
    converged: bool
    gravity: float
    jacobian: np.ndarray | None = None

    @property
    def std(self) -> np.ndarray:
        return covariance_std(self.covariance)

    def calibrate(self, a: np.ndarray) -> np.ndarray:
        """``T_a K_a (a - b_a)`` of readings `a` (n, 3), m/s^2."""
        return (np.asarray(a, dtype=float) - self.x[6:9]) @ acc_matrix(self.x).T


def fit_accelerometer(means: np.ndarray, gravity: float, *, counts: np.ndarray | None = None,
                      x0: np.ndarray | None = None) -> AccFit:
    """Scale, misalignment and bias of an accelerometer triad from its pose means (module notes).

    Parameters
    ----------
    means : (m, 3) ndarray
        Mean reading of each static pose (reading unit; m >= 10 for a residual scale).
    gravity : float
        Local gravity, m/s^2.
    counts : (m,) ndarray, optional
        Samples per pose (weights ``sqrt(n_k / nbar)``); default equal.
    x0 : (9,) ndarray, optional
        Start; default: per axis the bias half-way between the extreme means and the scale that
        maps their half-range to `gravity`.
    """
    a = np.asarray(means, dtype=float)
    m = len(a)
    w = np.ones(m) if counts is None else np.sqrt(np.asarray(counts, dtype=float) / np.mean(counts))
    if x0 is None:
        lo, hi = a.min(axis=0), a.max(axis=0)
        half = np.where(hi - lo > 0, (hi - lo) / 2.0, 1.0)
        x0 = np.concatenate([np.zeros(3), gravity / half, (hi + lo) / 2.0])

    def fun(x):
        TK = acc_matrix(x)
        d = a - x[6:9]
        v = d @ TK.T  # a_cal per pose
        nv = np.linalg.norm(v, axis=1)
        u = v / nv[:, None]
        e = d * x[3:6]  # K (a - b)
        J = np.empty((m, 9))
        J[:, 0] = -u[:, 0] * e[:, 1]  # dv/da_yz = (-e_y, 0, 0)
        J[:, 1] = u[:, 0] * e[:, 2]  # dv/da_zy = (e_z, 0, 0)
        J[:, 2] = -u[:, 1] * e[:, 2]  # dv/da_zx = (0, -e_z, 0)
        T = TK / x[3:6][None, :]
        for i in range(3):
            J[:, 3 + i] = (u @ T[:, i]) * d[:, i]  # dv/ds_i = T[:, i] d_i
            J[:, 6 + i] = -(u @ T[:, i]) * x[3 + i]  # dv/db_i = -T[:, i] s_i
        return w * (nv - gravity), w[:, None] * J

    x, r, J, it, ok = _lm(fun, np.asarray(x0, dtype=float))
    cov, s = _covariance(J, r, m - 9)
    return AccFit(x=x, covariance=cov, residuals=r / w, sigma=s, iterations=it, converged=ok, gravity=float(gravity),
                  jacobian=J)


def rotations(phi: np.ndarray) -> np.ndarray:
    """``exp([phi]x)`` (Rodrigues) of rotation vectors `phi` (n, 3), (n, 3, 3)."""
    phi = np.asarray(phi, dtype=float)
    th2 = np.sum(phi * phi, axis=1)
    th = np.sqrt(th2)
    small = th < 1e-4
    ths = np.where(small, 1.0, th)
    A = np.where(small, 1.0 - th2 / 6.0, np.sin(ths) / ths)  # sin(th)/th
    B = np.where(small, 0.5 - th2 / 24.0, (1.0 - np.cos(ths)) / ths ** 2)  # (1 - cos th)/th^2
    K = np.zeros((len(phi), 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -phi[:, 2], phi[:, 1], -phi[:, 0]
    K[:, 1, 0], K[:, 2, 0], K[:, 2, 1] = phi[:, 2], -phi[:, 1], phi[:, 0]
    return np.eye(3)[None] + A[:, None, None] * K + B[:, None, None] * (K @ K)


def integrate_motions(w: np.ndarray, dt, motions: list[tuple[int, int]]) -> np.ndarray:
    """The rotation of each motion, ``R_j = prod_{k in motion j} exp([w_k dt_k]x)`` (time order), (m, 3, 3).

    `dt`: the sample interval (s), or one per row of `w` (the time to the next sample).

    The products of all motions at once: padded with identities to a power of two and composed in
    pairs, ``(R1 R2)(R3 R4)...``, log2(L) vectorised steps.
    """
    L = max(b - a for a, b in motions)
    size = 1 << max(0, (L - 1).bit_length())
    R = np.broadcast_to(np.eye(3), (len(motions), size, 3, 3)).copy()
    j = np.concatenate([np.full(b - a, i) for i, (a, b) in enumerate(motions)])
    p = np.concatenate([np.arange(b - a) for a, b in motions])
    rows = np.concatenate([np.arange(a, b) for a, b in motions])
    step = dt if np.ndim(dt) == 0 else np.asarray(dt, dtype=float)[rows][:, None]
    R[j, p] = rotations(w[rows] * step)
    while R.shape[1] > 1:
        R = R[:, 0::2] @ R[:, 1::2]
    return R[:, 0]


@dataclass(frozen=True)
class GyroFit:
    """Gyro fit: ``x`` (GYRO_NAMES), its covariance, the bias (reading unit) and its std, residuals (m, 3)."""

    x: np.ndarray
    covariance: np.ndarray
    bias: np.ndarray
    bias_std: np.ndarray
    residuals: np.ndarray
    sigma: float
    iterations: int
    converged: bool
    settings: dict = field(default_factory=dict)
    jacobian: np.ndarray | None = None

    @property
    def std(self) -> np.ndarray:
        return covariance_std(self.covariance)


def gyro_residuals(x: np.ndarray, gyr: np.ndarray, rate: float, motions: list[tuple[int, int]],
                   u_start: np.ndarray, u_end: np.ndarray, bias: np.ndarray,
                   dt: np.ndarray | None = None) -> np.ndarray:
    """``r_j = R_j^T u_j - u_{j+1}`` of every motion, stacked (3 m,): the gyro misfit (module notes).

    `dt`: (N,) time from each sample to the next, s (a session with timestamps); default ``1 / rate``.
    """
    gyr = np.asarray(gyr, dtype=float)
    rows = np.concatenate([np.arange(a, b) for a, b in motions])
    local, k0 = [], 0
    for a, b in motions:  # the motions' rows in the stacked array
        local.append((k0, k0 + b - a))
        k0 += b - a
    step = 1.0 / float(rate) if dt is None else np.asarray(dt, dtype=float)[rows]
    R = integrate_motions((gyr[rows] - bias) @ gyro_matrix(x).T, step, local)
    return (np.einsum("mji,mj->mi", R, np.asarray(u_start, dtype=float)) - np.asarray(u_end, dtype=float)).ravel()


def gyro_start(gyr: np.ndarray, rate: float, motions: list[tuple[int, int]], u_start: np.ndarray, u_end: np.ndarray,
               bias: np.ndarray, scale0: float | None = 1.0, dt: np.ndarray | None = None) -> tuple[np.ndarray, float]:
    """:func:`fit_gyro`'s start and its sum of squared residuals.

    The misfit is periodic in the angles: a start far from the scale (a wrong unit, raw counts) ends in a
    wrong minimum, so the start is the best of a logarithmic grid of common scales (no misalignment).
    """
    grid = np.logspace(-7, 1, 49) if scale0 is None else scale0 * np.logspace(-2.5, 2.5, 21)
    costs = [float(np.sum(gyro_residuals(np.r_[np.zeros(6), np.full(3, c)], gyr, rate, motions, u_start, u_end, bias,
                                         dt) ** 2)) for c in grid]
    k = int(np.argmin(costs))
    return np.r_[np.zeros(6), np.full(3, float(grid[k]))], costs[k]


def fit_gyro(gyr: np.ndarray, rate: float, motions: list[tuple[int, int]], u_start: np.ndarray,
             u_end: np.ndarray, bias: np.ndarray, *, x0: np.ndarray | None = None,
             bias_std: np.ndarray | None = None, scale0: float | None = 1.0,
             dt: np.ndarray | None = None) -> GyroFit:
    """Scale and misalignment of a gyro triad from the change of the gravity direction over each motion.

    Parameters
    ----------
    gyr : (N, 3) ndarray
        Gyro readings (reading unit).
    rate : float
        Sample rate, Hz.
    motions : list of (int, int)
        Rows of each motion (end excluded).
    u_start, u_end : (m, 3) ndarray
        Unit gravity direction (calibrated accelerometers) in the poses before and after each motion.
    bias : (3,) ndarray
        Gyro bias (reading unit), subtracted.
    x0 : (9,) ndarray, optional
        Start (default: no misalignment, the three scales `scale0`).
    dt : (N,) ndarray, optional
        Time from each sample to the next, s (timestamps with jitter or gaps); default ``1 / rate``.
    scale0 : float or None
        Expected scale, SI per reading unit (1 for readings in rad/s): the start is the best, by the
        misfit, of a logarithmic grid of 21 common scales from `scale0`/316 to 316 `scale0`; None
        (raw counts): of 49 from 1e-7 to 10.
    """
    m = len(motions)

    def resid(x):
        return gyro_residuals(x, gyr, rate, motions, u_start, u_end, bias, dt)

    def fun(x):
        # forward differences: an O(h) error of J moves the minimum by O(h r), nothing at r = 0 (noise-free)
        r = resid(x)
        h = 1e-7 * np.maximum(np.abs(x), np.r_[np.full(6, 1.0), np.abs(x[6:9])])
        J = np.empty((len(r), 9))
        for i in range(9):
            e = np.zeros(9)
            e[i] = h[i]
            J[:, i] = (resid(x + e) - r) / h[i]
        return r, J

    if x0 is None:
        x0 = gyro_start(gyr, rate, motions, u_start, u_end, bias, scale0, dt)[0]
    x0 = np.asarray(x0, dtype=float)
    x, r, J, it, ok = _lm(fun, x0, max_iter=50, tol=1e-11)
    cov, s = _covariance(J, r, 2 * m - 9)
    return GyroFit(x=x, covariance=cov, bias=np.asarray(bias, dtype=float),
                   bias_std=np.full(3, math.nan) if bias_std is None else np.asarray(bias_std, dtype=float),
                   residuals=r.reshape(m, 3), sigma=s, iterations=it, converged=ok, jacobian=J)

"""Strapdown mechanisation in the launch-inertial frame: attitude, velocity and position from IMU data.

The navigation frame is casep's launch-inertial frame L (:mod:`casep.frames`): inertial, so the
attitude needs no Earth-rate or transport-rate term and the velocity no Coriolis term; the Earth's
rotation enters through the gravitation ``G`` alone (:func:`casep.gravity.gravitation_ecef`: normal
gravity minus the centrifugal acceleration, evaluated at the vehicle's ECEF position and turned
into L). Over the interval ``k`` from ``t_{k-1}`` to ``t_k`` (``h_k = t_k - t_{k-1}``)::

    q_k   = q_{k-1} (x) exp(phi_k / 2),          phi_k = dtheta_k + coning_k            (attitude)
    dV_k  = dv_k + a1 phi x dv_k + a2 phi x (phi x dv_k) + sculling_k                    (body, t_{k-1} axes)
            a1 = (1 - cos|phi|)/|phi|^2,  a2 = (1 - sin|phi|/|phi|)/|phi|^2,  phi = dtheta_k
    v_k   = v_{k-1} + C(q_{k-1}) dV_k + (G_{k-1} + G_k) h_k / 2                           (velocity)
    r_k   = r_{k-1} + (v_{k-1} + v_k) h_k / 2                                             (position)

``q`` is the Hamilton quaternion, scalar first, that rotates body vectors into L (``C(q)``); the
rotation compensation (``a1``, ``a2``) is exact for a constant rate and specific force over the
interval. The coning and sculling terms depend on the input (:func:`increments_from_rates`,
:func:`increments_from_deltas`): both are the classical second-order corrections, exact for a
rate and a specific force linear in time over the interval (rates) or over two intervals
(increments, Ignagni's previous-sample form).

The attitude chain does not depend on position, so it is one parallel prefix product
(``log2 N`` vectorised quaternion products). The gravitation couples velocity and position; it is
solved window by window (about 5 s) by fixed-point (Picard) iteration on the whole window, each
pass one vectorised gravity evaluation: with the gravity gradient ``~3e-6 s^-2`` a pass shrinks the
position error of the previous one by ``~1e-5``, so two to four passes reach 1e-7 m.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from casep._kernels import cumulative_trapezoid
from casep.gravity import launch_gravitation  # the gravitation in L (one place: io needs it too)
from casep.rotations import (
    Increments,
    dcm_to_quat,
    increments_from_deltas,
    increments_from_rates,
    quat_from_rotvec,
    quat_multiply,
    quat_rotate,
    quat_to_dcm,
)

__all__ = ["quat_multiply", "quat_rotate", "quat_from_rotvec", "quat_to_dcm", "dcm_to_quat",
           "increments_from_rates", "increments_from_deltas", "propagate_attitude", "body_velocity_increments",
           "propagate_translation", "launch_gravitation", "Increments", "MAX_PASSES"]

#: Fixed-point passes of the gravity iteration a window may take; more: not converged.
MAX_PASSES = 12
#: Gravitation in L at times t and positions r: ``(t (N,), r (N, 3)) -> (N, 3)`` m/s^2.
Gravity = Callable[[np.ndarray, np.ndarray], np.ndarray]


def propagate_attitude(q0: np.ndarray, inc: Increments) -> np.ndarray:
    """Attitude at every sample: ``q_k = q0 (x) exp(phi_1/2) (x) ... (x) exp(phi_k/2)``, (N, 4), unit norm.

    The chain of products is a parallel prefix scan (Hillis-Steele: after the pass of stride d each
    entry holds the product of the last ``2d`` steps), so ``log2 N`` vectorised products replace
    N sequential ones; rounding grows as ``log2 N`` products, not N.
    """
    P = quat_from_rotvec(inc.dtheta + inc.coning)
    d = 1
    while d < len(P):
        P[d:] = quat_multiply(P[:-d], P[d:])  # the right side is evaluated before the assignment
        d *= 2
    q = np.vstack([q0[None, :], quat_multiply(q0, P)])
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def body_velocity_increments(inc: Increments) -> np.ndarray:
    """``dV_k = dv + a1 phi x dv + a2 phi x (phi x dv) + sculling`` in the body axes at ``t_{k-1}``, (N-1, 3).

    ``a1 = (1 - cos a)/a^2``, ``a2 = (1 - sin(a)/a)/a^2`` with ``a = |phi|``, ``phi = dtheta``: the
    rotation of the body over the interval, exact for a constant rate and specific force.
    """
    phi, dv = inc.dtheta, inc.dv
    a2 = np.sum(phi * phi, axis=1, keepdims=True)
    a = np.sqrt(a2)
    small = a2 < 1e-6
    safe = np.where(small, 1.0, a2)
    c1 = np.where(small, 0.5 - a2 / 24.0, (1.0 - np.cos(a)) / safe)  # series where the quotients cancel
    c2 = np.where(small, 1.0 / 6.0 - a2 / 120.0, (1.0 - np.sinc(a / np.pi)) / safe)
    c = np.cross(phi, dv)
    return dv + c1 * c + c2 * np.cross(phi, c) + inc.sculling


def _gravity_on_grid(gravity: Gravity, t: np.ndarray, r: np.ndarray, spacing_s: float) -> np.ndarray:
    """`gravity` at nodes about `spacing_s` apart (and the ends), linearly interpolated to every sample.

    The gravitation changes over a node spacing of 0.05 s by its gradient (3e-6 s^-2) times the
    distance flown; what linear interpolation misses is its curvature along the path (~5e-13 m^-1
    s^-2 times (v dt)^2 / 8: 2e-10 m/s^2 at 1 km/s), far below any accelerometer.
    """
    step = max(1, int(spacing_s / max(float(np.median(np.diff(t))), 1e-12))) if len(t) > 1 else 1
    idx = np.unique(np.concatenate([np.arange(0, len(t), step), [len(t) - 1]]))
    g_nodes = gravity(t[idx], r[idx])
    return np.column_stack([np.interp(t, t[idx], g_nodes[:, c]) for c in range(3)])


def propagate_translation(t: np.ndarray, dV: np.ndarray, r0: np.ndarray, v0: np.ndarray,
                          gravity: Gravity | None, *, window_s: float = 5.0, tol_m: float = 1e-7,
                          max_passes: int = MAX_PASSES,
                          gravity_spacing_s: float = 0.05) -> tuple[np.ndarray, np.ndarray, int]:
    """Velocity and position from the velocity increments `dV` in L (N-1, 3) and the gravitation.

    Parameters
    ----------
    t : (N,) ndarray
        Sample times, s, increasing.
    dV : (N-1, 3) ndarray
        ``C(q_{k-1}) dV_k``: the specific-force velocity increments in L, m/s.
    r0, v0 : (3,) ndarray
        Position (m) and velocity (m/s) in L at ``t[0]``.
    gravity : callable or None
        ``gravity(t, r)`` -> (N, 3) gravitation in L, m/s^2 (:func:`launch_gravitation`); None: none
        (a test in a gravity-free inertial frame).
    window_s, tol_m, max_passes
        The fixed-point iteration: windows of `window_s`, passes until the position moves by less
        than `tol_m` (or `max_passes`).
    gravity_spacing_s
        The gravitation is evaluated this far apart and interpolated (:func:`_gravity_on_grid`).

    Returns
    -------
    r, v : (N, 3) ndarray
    passes : int
        The largest number of passes a window needed (``max_passes + 1``: one did not converge).
    """
    n = len(t)
    r, v = np.empty((n, 3)), np.empty((n, 3))
    r[0], v[0] = r0, v0
    h = np.diff(t)[:, None]
    step = max(1, int(round(window_s / float(np.median(h))))) if n > 1 else 1
    worst = 0
    for s in range(0, n - 1, step):
        e = min(s + step, n - 1)
        tt, hh = t[s:e + 1], h[s:e]
        rr = r[s] + v[s] * (tt - tt[0])[:, None]  # first guess: constant velocity
        passes = 0
        while passes <= max_passes:
            passes += 1
            g = _gravity_on_grid(gravity, tt, rr, gravity_spacing_s) if gravity is not None else np.zeros_like(rr)
            vv = v[s] + np.vstack([np.zeros(3), np.cumsum(dV[s:e] + 0.5 * (g[:-1] + g[1:]) * hh, axis=0)])
            new = r[s] + cumulative_trapezoid(vv, tt)
            moved = float(np.max(np.abs(new - rr)))
            rr = new
            if gravity is None or moved < tol_m:
                break
        worst = max(worst, passes)
        r[s:e + 1], v[s:e + 1] = rr, vv
    return r, v, worst

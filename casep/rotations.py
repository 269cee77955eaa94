"""Hamilton quaternions (scalar first) and the angle increments of sampled body rates, in numpy.

The one place of casep's numeric rotation rules: the flight-data checks (:mod:`casep.io.strapdown`)
and the strapdown navigator (:mod:`casep.navigation.strapdown`) both use them. A quaternion
``q = (w, x, y, z)`` rotates body vectors into its frame, ``v_frame = q (x) v (x) q* = C(q) v``;
the step from ``q_{k-1}`` to ``q_k`` in body axes is ``q_{k-1}* (x) q_k = exp(phi_k / 2)``, whose
rotation vector ``phi_k`` the navigator forms from the body rate as ``dtheta_k + coning_k``
(:func:`rotation_increments`).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["quat_multiply", "quat_conjugate", "quat_rotate", "quat_from_rotvec", "quat_to_rotvec", "quat_to_dcm",
           "dcm_to_quat", "Increments", "increments_from_rates", "increments_from_deltas", "rotation_increments"]


def quat_multiply(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product ``p (x) q`` of quaternions (scalar first), broadcast over leading axes."""
    pw, px, py, pz = np.moveaxis(np.asarray(p, float), -1, 0)
    qw, qx, qy, qz = np.moveaxis(np.asarray(q, float), -1, 0)
    return np.stack([pw * qw - px * qx - py * qy - pz * qz,
                     pw * qx + px * qw + py * qz - pz * qy,
                     pw * qy - px * qz + py * qw + pz * qx,
                     pw * qz + px * qy - py * qx + pz * qw], axis=-1)


def quat_conjugate(q: np.ndarray) -> np.ndarray:
    """``q* = (w, -x, -y, -z)``: the inverse rotation of a unit quaternion."""
    return np.asarray(q, float) * np.array([1.0, -1.0, -1.0, -1.0])


def quat_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``q (x) v (x) q*``: body vectors `v` into the frame of `q`, ``v + 2 w (u x v) + 2 u x (u x v)``."""
    q = np.asarray(q, float)
    w, u = q[..., :1], q[..., 1:]
    c = np.cross(u, v)
    return v + 2.0 * w * c + 2.0 * np.cross(u, c)


def quat_from_rotvec(phi: np.ndarray) -> np.ndarray:
    """``exp(phi / 2)``: the quaternion of the rotation vector `phi` (rad), ``(cos(a/2), sin(a/2) phi/a)``, a=|phi|."""
    phi = np.asarray(phi, float)
    a = np.linalg.norm(phi, axis=-1, keepdims=True)
    half_sinc = 0.5 * np.sinc(a / (2.0 * np.pi))  # sin(a/2)/a, 1/2 at a = 0
    return np.concatenate([np.cos(0.5 * a), half_sinc * phi], axis=-1)


def quat_to_rotvec(q: np.ndarray) -> np.ndarray:
    """``log(q) * 2``: the rotation vector (rad, angle at most pi) of unit quaternions, (..., 3).

    ``phi = 2 atan2(|u|, w) u / |u|`` with ``q = (w, u)`` taken with ``w >= 0`` (q and -q are one
    rotation); ``2 u / w`` in the limit ``|u| -> 0``.
    """
    q = np.asarray(q, float)
    q = np.where(q[..., :1] < 0, -q, q)
    w, u = q[..., :1], q[..., 1:]
    n = np.linalg.norm(u, axis=-1, keepdims=True)
    safe = np.where(n > 0, n, 1.0)
    factor = np.where(n > 0, 2.0 * np.arctan2(n, w) / safe, 2.0 / np.where(w > 0, w, 1.0))
    return factor * u


def quat_to_dcm(q: np.ndarray) -> np.ndarray:
    """The rotation matrices ``C(q)`` (body -> frame) of unit quaternions, (..., 3, 3)."""
    w, x, y, z = np.moveaxis(np.asarray(q, float), -1, 0)
    return np.stack([np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
                     np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
                     np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1)], -2)


def dcm_to_quat(C: np.ndarray) -> np.ndarray:
    """The unit quaternion (scalar first, ``w >= 0``) of a rotation matrix (3, 3) (Shepperd's method)."""
    C = np.asarray(C, float)
    tr = np.trace(C)
    k = int(np.argmax([tr, C[0, 0], C[1, 1], C[2, 2]]))
    if k == 0:
        s = 2.0 * math.sqrt(1.0 + tr)
        q = [0.25 * s, (C[2, 1] - C[1, 2]) / s, (C[0, 2] - C[2, 0]) / s, (C[1, 0] - C[0, 1]) / s]
    elif k == 1:
        s = 2.0 * math.sqrt(1.0 + 2 * C[0, 0] - tr)
        q = [(C[2, 1] - C[1, 2]) / s, 0.25 * s, (C[0, 1] + C[1, 0]) / s, (C[0, 2] + C[2, 0]) / s]
    elif k == 2:
        s = 2.0 * math.sqrt(1.0 + 2 * C[1, 1] - tr)
        q = [(C[0, 2] - C[2, 0]) / s, (C[0, 1] + C[1, 0]) / s, 0.25 * s, (C[1, 2] + C[2, 1]) / s]
    else:
        s = 2.0 * math.sqrt(1.0 + 2 * C[2, 2] - tr)
        q = [(C[1, 0] - C[0, 1]) / s, (C[0, 2] + C[2, 0]) / s, (C[1, 2] + C[2, 1]) / s, 0.25 * s]
    out = np.array(q)
    return out if out[0] >= 0 else -out


class Increments:
    """Angle and velocity increments of the intervals between samples, with their corrections.

    Attributes
    ----------
    dtheta, dv : (N-1, 3) ndarray
        Integrals of the body rate (rad) and body specific force (m/s) over interval k (from
        ``t_{k-1}`` to ``t_k``).
    coning, sculling : (N-1, 3) ndarray
        The coning correction (rad, added to ``dtheta`` to form the rotation vector) and the
        sculling correction (m/s, added to the rotation-compensated ``dv``).
    """

    def __init__(self, dtheta: np.ndarray, dv: np.ndarray, coning: np.ndarray, sculling: np.ndarray) -> None:
        self.dtheta, self.dv, self.coning, self.sculling = dtheta, dv, coning, sculling


def _interval_weights(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Quadrature of each interval (N-1) from the samples around it: ``int y = sum_j W[k, j] y[nodes[k, j]]``.

    The cubic through the interval's two samples and one either side (the quadratic at the ends; the
    trapezoid for 2 samples), integrated exactly by two-point Gauss-Legendre; uneven steps (lost
    samples) enter through the nodes. Fourth order: the increments an integrating IMU would give.
    """
    n, h = len(t), np.diff(t)
    width = min(4, n)
    first = np.minimum(np.clip(np.arange(n - 1) - 1, 0, None), n - width)  # each stencil's first sample
    nodes = first[:, None] + np.arange(width)  # (N-1, width)
    x = t[nodes]
    mid, d = 0.5 * (t[:-1] + t[1:]), h / (2.0 * math.sqrt(3.0))
    weights = np.zeros((n - 1, width))
    for g in (mid - d, mid + d):  # the two Gauss points of each interval, weight h/2 each
        for j in range(width):
            L = 0.5 * h
            for i in range(width):
                if i != j:
                    L = L * (g - x[:, i]) / (x[:, j] - x[:, i])
            weights[:, j] += L
    return nodes, weights


def increments_from_rates(t: np.ndarray, w: np.ndarray, f: np.ndarray) -> Increments:
    """Increments of sampled body rates `w` (rad/s) and specific forces `f` (m/s^2) at times `t`.

    ``dtheta`` and ``dv`` are the integrals over each interval of the cubic through the four nearest
    samples (:func:`_interval_weights`: fourth order, so the increments are those an integrating
    IMU would give to that order), and the coning and sculling corrections those of
    :func:`increments_from_deltas`. The first interval, without a previous one, takes the
    corrections of a rate and force linear over it::

        coning   = 1/2 int alpha x w dtau        = h^2/12 w_0 x w_1
        sculling = 1/2 int (alpha x f - w x nu)  = h^2/12 (w_0 x f_1 - w_1 x f_0)

    (``alpha``, ``nu`` the running integrals of ``w`` and ``f`` over the interval).
    """
    nodes, weights = _interval_weights(t)
    inc = increments_from_deltas(np.einsum("kj,kjc->kc", weights, w[nodes]), np.einsum("kj,kjc->kc", weights, f[nodes]))
    h = t[1] - t[0]
    inc.coning[0] = h * h / 12.0 * np.cross(w[0], w[1])
    inc.sculling[0] = h * h / 12.0 * (np.cross(w[0], f[1]) - np.cross(w[1], f[0]))
    return inc


def increments_from_deltas(dtheta: np.ndarray, dv: np.ndarray) -> Increments:
    """Corrections of measured angle (rad) and velocity (m/s) increments, one row per interval.

    Ignagni's previous-sample forms (exact for a rate and a specific force linear in time over the
    two intervals, at equal steps)::

        coning_k   = dtheta_{k-1} x dtheta_k / 12
        sculling_k = (dtheta_{k-1} x dv_k + dv_{k-1} x dtheta_k) / 12

    The first interval, without a previous one, gets none.
    """
    con, scul = np.zeros_like(dtheta), np.zeros_like(dv)
    con[1:] = np.cross(dtheta[:-1], dtheta[1:]) / 12.0
    scul[1:] = (np.cross(dtheta[:-1], dv[1:]) + np.cross(dv[:-1], dtheta[1:])) / 12.0
    return Increments(dtheta, dv, con, scul)


def rotation_increments(t: np.ndarray, w: np.ndarray) -> np.ndarray:
    """The navigator's rotation vectors ``phi_k = dtheta_k + coning_k`` (rad, (N-1, 3)) of body rates `w` (rad/s).

    Those of :func:`increments_from_rates`: the attitude step ``q_{k-1}* (x) q_k`` of a strapdown
    solution integrated from `w` is ``exp(phi_k / 2)``.
    """
    w = np.asarray(w, float)
    inc = increments_from_rates(np.asarray(t, float), w, np.zeros_like(w))
    return inc.dtheta + inc.coning

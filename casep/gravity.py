"""WGS84 normal gravity: the closed form of the ellipsoid's field, at any point outside the Earth.

The normal gravity field is the field of the WGS84 level ellipsoid (semi-axes ``a``, ``b``, mass
``GM``, rotating at ``omega_E``): gravitation plus the centrifugal acceleration of the rotating
Earth. Its closed form in ellipsoidal-harmonic coordinates (NIMA TR8350.2 eqs. 4-5 to 4-10;
Heiskanen & Moritz 2-145) holds at any height, so a rocket at 300 km and a stand in a
laboratory use the same formula. With ``E = sqrt(a^2 - b^2)`` (linear eccentricity) and, at the
ECEF point ``(x, y, z)`` with ``p = hypot(x, y)``, ``r^2 = x^2 + y^2 + z^2``::

    u^2  = (r^2 - E^2) / 2 [1 + sqrt(1 + 4 E^2 z^2 / (r^2 - E^2)^2)]     # the point's ellipsoid u = const
    beta = atan(z sqrt(u^2 + E^2) / (u p))                               # reduced latitude
    w    = sqrt((u^2 + E^2 sin^2 beta) / (u^2 + E^2))
    q(u) = 1/2 [(1 + 3 u^2/E^2) atan(E/u) - 3 u/E],   q0 = q(b)
    q'   = 3 (1 + u^2/E^2) (1 - u/E atan(E/u)) - 1
    g_u  = -1/w [GM / (u^2 + E^2) + omega^2 a^2 E / (u^2 + E^2) q'/q0 (sin^2 beta / 2 - 1/6) - omega^2 u cos^2 beta]
    g_b  = 1/w [omega^2 a^2 / sqrt(u^2 + E^2) q/q0 - omega^2 sqrt(u^2 + E^2)] sin beta cos beta

``g_u`` along the unit vector ``e_u`` normal to the ellipsoid through the point, ``g_b`` along
``e_beta`` (north: above the ellipsoid the centrifugal part ``-omega^2 sqrt(u^2 + E^2)`` wins and
the plumb line leans towards the equator, about ``-8.1e-9 h sin(2 phi)`` m/s^2); both are turned
into ECEF by ``e_u = (u cos(beta) cos(lon), u cos(beta) sin(lon), sqrt(u^2 + E^2) sin(beta)) /
(w sqrt(u^2 + E^2))`` and ``e_beta = (-sin(beta) cos(lon), -sin(beta) sin(lon), u cos(beta) /
sqrt(u^2 + E^2)) / w``. On the ellipsoid (``u = b``)
``g_b = 0`` and ``|g|`` is Somigliana's ``gamma_e (1 + k sin^2 phi) / sqrt(1 - e^2 sin^2 phi)``.

The gravitation (mass attraction alone, what an inertial navigator integrates) is the normal
gravity minus the centrifugal acceleration: ``G = g + omega x (omega x r)``, ``omega = (0, 0,
omega_E)``. The normal gravity omits the local anomaly (up to ~1e-4 relative): a stand whose
gravity was measured should give it.
"""

from __future__ import annotations

import math

import numpy as np

from casep.frames import OMEGA_EARTH
from casep.units import G0

__all__ = ["GRAVITY_LAUNCH", "kinematic_acceleration",
           "normal_gravity", "normal_gravity_ecef", "gravitation_ecef", "WGS84_A", "WGS84_F", "WGS84_GM",
           "GAMMA_E", "GAMMA_P", "launch_gravitation"]

#: WGS84 semi-major axis (m) and flattening.
WGS84_A = 6378137.0
WGS84_F = 1.0 / 298.257223563
#: WGS84 geocentric gravitational constant (with the atmosphere), m^3/s^2.
WGS84_GM = 3.986004418e14
#: Normal gravity at the equator and at the poles, m/s^2 (TR8350.2 table 3.4).
GAMMA_E = 9.7803253359
GAMMA_P = 9.8321849378
_B = WGS84_A * (1.0 - WGS84_F)  # semi-minor axis, m
_E = math.sqrt(WGS84_A ** 2 - _B ** 2)  # linear eccentricity, m


def _q(u: np.ndarray | float) -> np.ndarray | float:
    """``q(u) = 1/2 [(1 + 3 u^2/E^2) atan(E/u) - 3 u/E]``."""
    return 0.5 * ((1.0 + 3.0 * u * u / _E ** 2) * np.arctan(_E / u) - 3.0 * u / _E)


_Q0 = float(_q(_B))


def normal_gravity_ecef(r_ecef) -> np.ndarray:
    """WGS84 normal gravity (gravitation plus centrifugal) at ECEF points, m/s^2, in ECEF axes.

    Parameters
    ----------
    r_ecef : (3,) or (N, 3) array_like
        ECEF positions, m; each more than half the semi-major axis from the centre.

    Returns
    -------
    ndarray
        The normal gravity vectors, the shape of `r_ecef` (the closed form of the module docstring).
    """
    r = np.asarray(r_ecef, dtype=float)
    one = r.ndim == 1
    r = np.atleast_2d(r)
    x, y, z = r[:, 0], r[:, 1], r[:, 2]
    p2, r2 = x * x + y * y, x * x + y * y + z * z
    if not np.all(np.isfinite(r)) or np.any(r2 < (0.5 * WGS84_A) ** 2):
        raise ValueError("normal_gravity_ecef: positions must be finite and outside half the Earth's radius")
    s = r2 - _E ** 2
    u2 = 0.5 * s * (1.0 + np.sqrt(1.0 + 4.0 * _E ** 2 * z * z / (s * s)))
    u = np.sqrt(u2)
    big = np.sqrt(u2 + _E ** 2)
    p = np.sqrt(p2)
    beta = np.arctan2(z * big, u * p)
    lon = np.arctan2(y, x)
    sb, cb = np.sin(beta), np.cos(beta)
    w = np.sqrt((u2 + _E ** 2 * sb * sb) / (u2 + _E ** 2))
    om2 = OMEGA_EARTH ** 2
    qp = 3.0 * (1.0 + u2 / _E ** 2) * (1.0 - u / _E * np.arctan(_E / u)) - 1.0
    g_u = -(WGS84_GM / (u2 + _E ** 2) + om2 * WGS84_A ** 2 * _E / (u2 + _E ** 2) * qp / _Q0
            * (0.5 * sb * sb - 1.0 / 6.0) - om2 * u * cb * cb) / w
    g_b = (om2 * WGS84_A ** 2 / big * _q(u) / _Q0 - om2 * big) * sb * cb / w
    cl, sl = np.cos(lon), np.sin(lon)
    e_u = np.column_stack([u * cb * cl, u * cb * sl, big * sb]) / (w * big)[:, None]
    e_b = np.column_stack([-sb * cl, -sb * sl, u * cb / big]) / w[:, None]
    g = g_u[:, None] * e_u + g_b[:, None] * e_b
    return g[0] if one else g


def gravitation_ecef(r_ecef) -> np.ndarray:
    """Gravitation (mass attraction alone) at ECEF points, m/s^2: ``g + omega x (omega x r)``.

    What an accelerometer at rest in inertial space does not sense and an inertial navigator adds:
    the normal gravity :func:`normal_gravity_ecef` with the centrifugal acceleration
    ``-omega x (omega x r) = omega_E^2 (x, y, 0)`` taken out.
    """
    r = np.asarray(r_ecef, dtype=float)
    g = normal_gravity_ecef(r)
    centrifugal = OMEGA_EARTH ** 2 * np.concatenate([r[..., :2], np.zeros(r.shape[:-1] + (1,))], axis=-1)
    return g - centrifugal


def normal_gravity(latitude_deg: float, height_m: float = 0.0) -> float:
    """WGS84 normal gravity at geodetic latitude `latitude_deg` (deg) and ellipsoidal height `height_m` (m), m/s^2.

    The magnitude of :func:`normal_gravity_ecef` at that point (longitude 0: the field is symmetric
    about the polar axis).

    Raises
    ------
    ValueError
        Latitude outside [-90, 90] deg or height outside [-12000, 50000] m (a stand near the
        Earth's surface; :func:`normal_gravity_ecef` takes any point outside the Earth).
    """
    if not (math.isfinite(latitude_deg) and -90.0 <= latitude_deg <= 90.0):
        raise ValueError(f"--latitude {latitude_deg} deg: must be in [-90, 90]")
    if not (math.isfinite(height_m) and -12000.0 <= height_m <= 50000.0):
        raise ValueError(f"--height {height_m} m: must be in [-12000, 50000] (near the Earth's surface)")
    e2 = 1.0 - (_B / WGS84_A) ** 2
    phi = math.radians(latitude_deg)
    n = WGS84_A / math.sqrt(1.0 - e2 * math.sin(phi) ** 2)  # prime-vertical radius of curvature
    r = np.array([(n + height_m) * math.cos(phi), 0.0, (n * (1.0 - e2) + height_m) * math.sin(phi)])
    return float(np.linalg.norm(normal_gravity_ecef(r)))


#: Gravity in the launch-inertial (platform) frame, x downrange, y up: flat, uniform Earth.
GRAVITY_LAUNCH = np.array([0.0, -G0, 0.0])


def kinematic_acceleration(t: np.ndarray, f: np.ndarray) -> np.ndarray:
    """``a = f + g`` in the launch-inertial frame with uniform gravity :data:`GRAVITY_LAUNCH`, m/s^2.

    A flat-Earth approximation: true gravity falls by 3 % at 100 km altitude and turns by
    ~1 deg per 110 km of downrange; a few per cent of g is negligible against a boost's
    10-50 m/s^2 for detecting an offset (it only scales the offset estimate by ~1e-3).
    """
    return np.asarray(f, dtype=float) + GRAVITY_LAUNCH


def launch_gravitation(site):  # -> (t, r) -> gravitation
    """The gravitation in L at launch-inertial positions and times: ``C^T Rz(theta) G(r_E)``.

    ``r_E`` from :func:`casep.frames.launch_to_ecef`, ``G`` :func:`casep.gravity.gravitation_ecef`,
    the vector turned back with :func:`casep.frames.ecef_to_launch_vector`.
    """
    from casep.frames import ecef_to_launch_vector, launch_to_ecef

    def gravity(t: np.ndarray, r: np.ndarray) -> np.ndarray:
        r_e, _ = launch_to_ecef(site, t, r, np.zeros_like(r))
        return ecef_to_launch_vector(site, t, gravitation_ecef(r_e))

    return gravity

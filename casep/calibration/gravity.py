"""Local gravity from latitude and height: the WGS84 normal gravity (Somigliana's formula).

On the ellipsoid (Somigliana, the closed form of the WGS84 normal gravity, NIMA TR8350.2 eq. 4-1):

    gamma(phi) = gamma_e (1 + k sin^2 phi) / sqrt(1 - e^2 sin^2 phi),   k = b gamma_p / (a gamma_e) - 1

and above it, to second order in the height h (TR8350.2 eq. 4-3):

    gamma(phi, h) = gamma(phi) [1 - 2 h / a (1 + f + m - 2 f sin^2 phi) + 3 h^2 / a^2]

The normal gravity omits the local anomaly (up to ~1e-4 relative, 0.5 mGal..100 mGal): a stand
whose gravity was measured should give it (``--gravity``).
"""

from __future__ import annotations

import math

__all__ = ["normal_gravity", "WGS84_A", "WGS84_F", "GAMMA_E", "GAMMA_P"]

#: WGS84 semi-major axis (m) and flattening.
WGS84_A = 6378137.0
WGS84_F = 1.0 / 298.257223563
#: Normal gravity at the equator and at the poles, m/s^2 (TR8350.2 table 3.4).
GAMMA_E = 9.7803253359
GAMMA_P = 9.8321849378
_E2 = 6.69437999014e-3  # first eccentricity squared
_B = WGS84_A * (1.0 - WGS84_F)  # semi-minor axis, m
_K = _B * GAMMA_P / (WGS84_A * GAMMA_E) - 1.0  # Somigliana's constant, 0.00193185265241
_M = 0.00344978650684  # omega^2 a^2 b / GM


def normal_gravity(latitude_deg: float, height_m: float = 0.0) -> float:
    """WGS84 normal gravity at geodetic latitude `latitude_deg` (deg) and ellipsoidal height `height_m` (m), m/s^2.

    Raises
    ------
    ValueError
        Latitude outside [-90, 90] deg or height outside [-12000, 50000] m (the second-order
        height series is meant for the Earth's surface and the low atmosphere).
    """
    if not (math.isfinite(latitude_deg) and -90.0 <= latitude_deg <= 90.0):
        raise ValueError(f"--latitude {latitude_deg} deg: must be in [-90, 90]")
    if not (math.isfinite(height_m) and -12000.0 <= height_m <= 50000.0):
        raise ValueError(f"--height {height_m} m: must be in [-12000, 50000] (near the Earth's surface)")
    s2 = math.sin(math.radians(latitude_deg)) ** 2
    g0 = GAMMA_E * (1.0 + _K * s2) / math.sqrt(1.0 - _E2 * s2)  # Somigliana
    h = float(height_m)
    return g0 * (1.0 - 2.0 * h / WGS84_A * (1.0 + WGS84_F + _M - 2.0 * WGS84_F * s2) + 3.0 * h * h / WGS84_A ** 2)

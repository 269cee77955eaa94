"""WGS84 normal gravity (casep.gravity) against independent forms of the same field.

- On the ellipsoid: Somigliana's closed form (magnitude) and the ellipsoid normal (direction, pymap3d).
- Anywhere outside: the gradient, by central differences, of the zonal spherical-harmonic potential
  ``V = GM/r [1 - sum_n J_n (a/r)^n P_n(sin phi')]`` with the WGS84 normal field's J2, J4, J6
  (TR8350.2 table 3.?; the series is truncated at J6, whose next term is ~1e-11 g).
- Above the ellipsoid: the north component of the normal gravity, ``-8.08e-9 h sin(2 phi)`` m/s^2
  (the first-order plumb-line curvature of the normal field), to 3 % at 10 km.
"""

from __future__ import annotations

import math

import numpy as np
import pymap3d
import pytest
from numpy.polynomial import legendre

from casep.frames import OMEGA_EARTH
from casep.gravity import GAMMA_E, WGS84_GM, gravitation_ecef, normal_gravity, normal_gravity_ecef

A = 6378137.0
J = {2: 1.082629821313e-3, 4: -2.37091222e-6, 6: 6.08347e-9}  # the WGS84 normal field's zonal coefficients
POINTS = [(45.0, 10.0, 0.0), (30.0, -100.0, 0.0), (50.4, -3.6, 1e4), (10.0, 0.0, 3e5), (80.0, 0.0, 1e6),
          (-60.0, 30.0, 2e5), (0.0, 45.0, 5e4)]


def _potential(r: np.ndarray) -> float:
    rn = float(np.linalg.norm(r))
    s = r[2] / rn
    return WGS84_GM / rn * (1.0 - sum(Jn * (A / rn) ** n * legendre.legval(s, [0] * n + [1]) for n, Jn in J.items()))


def _ecef(lat, lon, h):
    return np.array(pymap3d.geodetic2ecef(lat, lon, h))


def test_on_the_ellipsoid_gravity_is_somiglianas_and_along_the_normal():
    for lat, lon, h in POINTS:
        if h:
            continue
        g = normal_gravity_ecef(_ecef(lat, lon, 0.0))
        s2 = math.sin(math.radians(lat)) ** 2
        somigliana = GAMMA_E * (1 + 0.00193185265241 * s2) / math.sqrt(1 - 6.69437999014e-3 * s2)
        assert np.linalg.norm(g) == pytest.approx(somigliana, abs=1e-9)
        up = np.array(pymap3d.enu2ecefv(0.0, 0.0, 1.0, lat, lon))
        assert np.linalg.norm(np.cross(g, up)) < 1e-10  # along the normal
        assert g @ up < 0


def test_gravitation_is_the_gradient_of_the_zonal_potential_at_any_height():
    for lat, lon, h in POINTS:
        r = _ecef(lat, lon, h)
        grad = np.array([(_potential(r + e) - _potential(r - e)) / 2.0 for e in np.eye(3)])  # 1 m steps
        assert np.linalg.norm(gravitation_ecef(r) - grad) < 5e-8, (lat, h)  # differences: ~1e-8 m/s^2


def test_gravity_is_gravitation_plus_the_centrifugal_acceleration():
    r = np.array([_ecef(*p) for p in POINTS])
    centrifugal = OMEGA_EARTH ** 2 * np.column_stack([r[:, 0], r[:, 1], np.zeros(len(r))])
    np.testing.assert_allclose(normal_gravity_ecef(r), gravitation_ecef(r) + centrifugal, atol=1e-12)
    assert normal_gravity_ecef(r[0]).shape == (3,)


def test_the_plumb_line_leans_to_the_equator_above_the_ellipsoid():
    for lat in (20.0, 45.0, -50.0):
        g = normal_gravity_ecef(_ecef(lat, 0.0, 1e4))
        north = np.array(pymap3d.enu2ecefv(0.0, 1.0, 0.0, lat, 0.0))
        assert g @ north == pytest.approx(-8.08e-9 * 1e4 * math.sin(math.radians(2 * lat)), rel=0.03)


def test_the_scalar_normal_gravity_is_the_vectors_magnitude_and_the_calibration_name_is_the_same():
    from casep.calibration import gravity as calibration_gravity

    assert calibration_gravity.normal_gravity is normal_gravity
    for lat, lon, h in POINTS:
        if h <= 5e4:
            assert normal_gravity(lat, h) == pytest.approx(np.linalg.norm(normal_gravity_ecef(_ecef(lat, lon, h))),
                                                           abs=1e-12)
    with pytest.raises(ValueError, match="outside half"):
        normal_gravity_ecef([1.0, 2.0, 3.0])

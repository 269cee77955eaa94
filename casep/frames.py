"""Tracking frames: launch-inertial <-> ECEF (WGS84, rotating) <-> geodetic + local ENU velocity.

casep's platform frame is the *launch-inertial* frame (:mod:`casep`): origin at the launch point
at the launch time ``t0``, x downrange (horizontal, at azimuth ``azimuth_deg`` from north,
clockwise), y up (the WGS84 ellipsoid normal at the launch point), z = x cross y; the axes are
those of that Earth-fixed triad at ``t0``, then held fixed in inertial space. Radar and GNSS
tracking come in Earth-fixed frames: ECEF (WGS84) or geodetic latitude, longitude, height with a
velocity in the local east-north-up (ENU) axes. This module converts between them.

What pymap3d does (WGS84 ellipsoid, ``deg=True``): geodetic <-> ECEF positions
(:func:`pymap3d.geodetic2ecef`, :func:`pymap3d.ecef2geodetic`) and the ENU <-> ECEF rotation of
vectors at a point (:func:`pymap3d.enu2ecefv`, :func:`pymap3d.ecef2enuv`). What casep does by
hand: the launch triad, and the Earth's rotation (``omega_E = 7.292115e-5`` rad/s about the ECEF
z axis, constant; no precession, nutation or polar motion over a flight of minutes).

Equations (``theta = omega_E (t - t0)``, ``Rz(a)`` the active rotation by ``a`` about z,
``w = (0, 0, omega_E)`` in ECEF, ``C`` the launch triad at t0 as ECEF columns, ``r_s`` the launch
point in ECEF)::

    r_I  = r_s + C r_L                 # launch-inertial -> the inertial frame that was ECEF at t0
    r_E  = Rz(theta)^T r_I             # = R3(theta) r_I: ECEF has turned by theta since t0
    v_I  = Rz(theta) (v_E + w x r_E)   # transport theorem: inertial velocity of an ECEF point
    v_L  = C^T v_I

and back ``r_L = C^T (Rz(theta) r_E - r_s)``, ``v_E = Rz(theta)^T C v_L - w x r_E``. The
platform is inertial, so the specific force it senses (and S_V) does not depend on any of this:
only the *tracking velocity* must be brought into the launch-inertial frame before
``dv = v_tel - v_trk`` is formed.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

__all__ = ["OMEGA_EARTH", "TRACKING_FRAMES", "LaunchSite", "launch_to_ecef", "ecef_to_launch",
           "geodetic_to_ecef", "ecef_to_geodetic", "launch_to_geodetic", "geodetic_to_launch",
           "ECEF_COLUMNS", "GEODETIC_COLUMNS", "ecef_to_launch_vector"]

#: Earth rotation rate, rad/s (WGS84 / IERS value, about the ECEF z axis).
OMEGA_EARTH = 7.292115e-5

#: Frames a tracking file may be in (``read_flight_pair(tracking_frame=...)``).
TRACKING_FRAMES = ("launch", "ecef", "geodetic")
#: Columns of an ECEF tracking file (m, m/s) and of a geodetic one (deg, deg, m, m/s east/north/up).
ECEF_COLUMNS = ("t", "r_ecef_x", "r_ecef_y", "r_ecef_z", "v_ecef_x", "v_ecef_y", "v_ecef_z")
GEODETIC_COLUMNS = ("t", "lat", "lon", "h", "v_east", "v_north", "v_up")


def _finite(name: str, value, lo: float = -math.inf, hi: float = math.inf) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not math.isfinite(value) or not lo <= value <= hi:
        raise ValueError(f"LaunchSite: `{name}` must be a finite number in [{lo:g}, {hi:g}], got {value!r}")
    return float(value)


@dataclass(frozen=True)
class LaunchSite:
    """Launch point, launch azimuth and launch time: what ties the launch-inertial frame to the Earth.

    Parameters
    ----------
    lat_deg, lon_deg : float
        Geodetic latitude and longitude of the launch point, deg (WGS84).
    h_m : float
        Height above the WGS84 ellipsoid, m.
    azimuth_deg : float
        Azimuth of the platform x axis (downrange), deg from north, clockwise (90 = east).
    t0 : float
        Launch time in the tracking file's time scale, s: the instant at which the launch-inertial
        frame coincides with the Earth-fixed launch triad.
    """

    lat_deg: float
    lon_deg: float
    h_m: float
    azimuth_deg: float
    t0: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "lat_deg", _finite("lat_deg", self.lat_deg, -90.0, 90.0))
        object.__setattr__(self, "lon_deg", _finite("lon_deg", self.lon_deg, -360.0, 360.0))
        object.__setattr__(self, "h_m", _finite("h_m", self.h_m, -1e4, 1e5))
        object.__setattr__(self, "azimuth_deg", _finite("azimuth_deg", self.azimuth_deg, -360.0, 360.0))
        object.__setattr__(self, "t0", _finite("t0", self.t0))
        if abs(self.lat_deg) > 89.999:  # east/north undefined at the poles
            raise ValueError(f"LaunchSite: `lat_deg` must be within +-89.999 deg (no launch azimuth at a pole), "
                             f"got {self.lat_deg}")

    @functools.cached_property
    def r_site(self) -> np.ndarray:
        """Launch point, ECEF, m (pymap3d.geodetic2ecef); computed once (a navigation asks it per window)."""
        import pymap3d

        r = np.array(pymap3d.geodetic2ecef(self.lat_deg, self.lon_deg, self.h_m), dtype=float)
        r.flags.writeable = False  # shared by every caller
        return r

    @functools.cached_property
    def C(self) -> np.ndarray:
        """Launch-to-ECEF rotation at t0, (3, 3): columns are the launch x, y, z axes in ECEF; computed once."""
        import pymap3d

        lat, lon = self.lat_deg, self.lon_deg
        east = np.array(pymap3d.enu2ecefv(1.0, 0.0, 0.0, lat, lon), dtype=float)
        north = np.array(pymap3d.enu2ecefv(0.0, 1.0, 0.0, lat, lon), dtype=float)
        up = np.array(pymap3d.enu2ecefv(0.0, 0.0, 1.0, lat, lon), dtype=float)
        az = math.radians(self.azimuth_deg)
        x = math.sin(az) * east + math.cos(az) * north  # azimuth from north, clockwise (towards east)
        z = np.cross(x, up)  # right-handed: z = x cross y
        C = np.column_stack([x, up, z])
        C.flags.writeable = False  # shared by every caller
        return C

    @property
    def earth_rate(self) -> np.ndarray:
        """Earth rotation vector in launch-inertial axes, rad/s: ``C^T (0, 0, omega_E)``."""
        return self.C.T @ np.array([0.0, 0.0, OMEGA_EARTH])

    @property
    def earth_centre(self) -> np.ndarray:
        """The WGS84 centre (a point of the rotation axis) in launch-inertial coordinates, m: ``-C^T r_s``."""
        return -self.C.T @ self.r_site

    def to_dict(self) -> dict:
        return {"lat_deg": self.lat_deg, "lon_deg": self.lon_deg, "h_m": self.h_m,
                "azimuth_deg": self.azimuth_deg, "t0": self.t0}


def _rz(theta: np.ndarray) -> np.ndarray:
    """Active rotations by `theta` (rad) about z, (N, 3, 3)."""
    c, s = np.cos(theta), np.sin(theta)
    R = np.zeros(theta.shape + (3, 3))
    R[..., 0, 0], R[..., 0, 1], R[..., 1, 0], R[..., 1, 1], R[..., 2, 2] = c, -s, s, c, 1.0
    return R


def _prepare(t, *arrays):
    t = np.atleast_1d(np.asarray(t, dtype=float))
    out = [np.atleast_2d(np.asarray(a, dtype=float)) for a in arrays]
    for a in out:
        if a.shape != (t.size, 3):
            raise ValueError(f"positions and velocities must have shape ({t.size}, 3) for {t.size} times, "
                             f"got {a.shape}")
    return t, out


def _omega_cross(r: np.ndarray) -> np.ndarray:
    """``w x r`` with ``w = (0, 0, omega_E)``: (-omega r_y, omega r_x, 0)."""
    return np.column_stack([-OMEGA_EARTH * r[:, 1], OMEGA_EARTH * r[:, 0], np.zeros(len(r))])


def launch_to_ecef(site: LaunchSite, t, r, v) -> tuple[np.ndarray, np.ndarray]:
    """Launch-inertial position and velocity at times `t` -> ECEF (WGS84, rotating).

    Parameters
    ----------
    site : LaunchSite
    t : (N,) array_like
        Times in the tracking time scale, s (the frames coincide at ``site.t0``).
    r, v : (N, 3) array_like
        Launch-inertial position (m) and velocity (m/s).

    Returns
    -------
    r_ecef, v_ecef : (N, 3) ndarray
        m and m/s, Earth-fixed (v_ecef is the velocity relative to the rotating Earth).

    Notes
    -----
    ``r_E = Rz(theta)^T (r_s + C r_L)`` and ``v_E = Rz(theta)^T C v_L - w x r_E`` with
    ``theta = omega_E (t - t0)``. ``Rz(theta)^T r_s`` is computed on its own and added last, so
    that :func:`ecef_to_launch` subtracts the very same number: the round trip is exact to the
    rounding of ``r_E`` itself (half an ulp of 6.4e6 m = 4.7e-10 m per component).
    """
    t, (r, v) = _prepare(t, r, v)
    RzT = np.swapaxes(_rz(OMEGA_EARTH * (t - site.t0)), -1, -2)
    C = site.C
    base = RzT @ site.r_site  # Rz^T r_s: the launch point's inertial position seen in ECEF at t
    r_e = base + np.einsum("nij,nj->ni", RzT, r @ C.T)  # Rz^T (r_s + C r_L)
    v_e = np.einsum("nij,nj->ni", RzT, v @ C.T) - _omega_cross(r_e)  # Rz^T C v_L - w x r_E
    return r_e, v_e


def ecef_to_launch(site: LaunchSite, t, r_ecef, v_ecef) -> tuple[np.ndarray, np.ndarray]:
    """ECEF position and velocity at times `t` -> launch-inertial (inverse of :func:`launch_to_ecef`).

    Notes
    -----
    ``r_L = C^T Rz(theta) (r_E - Rz(theta)^T r_s)`` and ``v_L = C^T Rz(theta) (v_E + w x r_E)``:
    the transport theorem adds the velocity of the Earth-fixed point under the vehicle
    (``omega_E`` times its distance from the axis: 465 m/s on the equator, 329 m/s at 45 deg).
    """
    t, (r_e, v_e) = _prepare(t, r_ecef, v_ecef)
    Rz = _rz(OMEGA_EARTH * (t - site.t0))
    RzT = np.swapaxes(Rz, -1, -2)
    C = site.C
    d = r_e - RzT @ site.r_site  # r_E - Rz^T r_s, the same base as the forward conversion
    r_l = np.einsum("nij,nj->ni", Rz, d) @ C  # C^T Rz d (row-vector form)
    v_l = np.einsum("nij,nj->ni", Rz, v_e + _omega_cross(r_e)) @ C  # C^T Rz (v_E + w x r_E)
    return r_l, v_l


def ecef_to_launch_vector(site: LaunchSite, t, a_ecef) -> np.ndarray:
    """Free vectors (accelerations, axes) given in ECEF axes at times `t` -> launch-inertial axes.

    ``a_L = C^T Rz(theta) a_E``, ``theta = omega_E (t - t0)``: the rotation of
    :func:`ecef_to_launch` without the origin shift and without the transport term.
    """
    t, (a,) = _prepare(t, a_ecef)
    return np.einsum("nij,nj->ni", _rz(OMEGA_EARTH * (t - site.t0)), a) @ site.C


def geodetic_to_ecef(lat, lon, h, v_east, v_north, v_up) -> tuple[np.ndarray, np.ndarray]:
    """Geodetic position (deg, deg, m, WGS84) and local ENU velocity (m/s) -> ECEF (m, m/s).

    pymap3d: ``geodetic2ecef`` for the position, ``enu2ecefv`` (the ENU axes at the point itself)
    for the velocity.
    """
    import pymap3d

    lat, lon, h = (np.asarray(a, dtype=float) for a in (lat, lon, h))
    r = np.column_stack(pymap3d.geodetic2ecef(lat, lon, h))
    v = np.column_stack(pymap3d.enu2ecefv(np.asarray(v_east, float), np.asarray(v_north, float),
                                          np.asarray(v_up, float), lat, lon))
    return r, v


def ecef_to_geodetic(r_ecef, v_ecef) -> tuple[np.ndarray, ...]:
    """ECEF (m, m/s) -> latitude, longitude (deg), height (m) and east, north, up velocity (m/s).

    pymap3d: ``ecef2geodetic`` (You 2000, closed form with one correction) and ``ecef2enuv``.
    """
    import pymap3d

    r, v = np.atleast_2d(np.asarray(r_ecef, float)), np.atleast_2d(np.asarray(v_ecef, float))
    lat, lon, h = pymap3d.ecef2geodetic(r[:, 0], r[:, 1], r[:, 2])
    lat, lon, h = (np.atleast_1d(np.asarray(a, dtype=float)) for a in (lat, lon, h))
    lat, h = _refine_latitude(r, lat)
    ve, vn, vu = pymap3d.ecef2enuv(v[:, 0], v[:, 1], v[:, 2], lat, lon)
    return lat, lon, h, np.asarray(ve, float), np.asarray(vn, float), np.asarray(vu, float)


def _refine_latitude(r: np.ndarray, lat_deg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Three fixed-point steps on pymap3d's geodetic latitude, and the height from it.

    pymap3d's closed form (one correction) leaves latitude errors that grow with height: measured
    round trips geodetic -> ECEF -> geodetic -> ECEF of 1.1e-6 m at 100 km and 7.8e-3 m at
    1000 km. Each step ``lat <- atan2(z + e^2 N(lat) sin(lat), p)`` (the ellipsoid normal through
    the point meets the polar axis at ``z = -e^2 N sin(lat)``) shrinks the error by about ``e^2``
    (0.0067); ``h = p cos(lat) + z sin(lat) - a sqrt(1 - e^2 sin^2(lat))`` holds at the poles too.
    """
    import pymap3d

    ell = pymap3d.Ellipsoid.from_name("wgs84")
    a, b = ell.semimajor_axis, ell.semiminor_axis
    e2 = 1.0 - (b / a) ** 2
    p, z = np.hypot(r[:, 0], r[:, 1]), r[:, 2]
    lat = np.radians(lat_deg)
    for _ in range(3):
        s = np.sin(lat)
        lat = np.arctan2(z + e2 * a / np.sqrt(1.0 - e2 * s * s) * s, p)  # N(lat) = a / sqrt(1 - e^2 sin^2 lat)
    s, c = np.sin(lat), np.cos(lat)
    h = p * c + z * s - a * np.sqrt(1.0 - e2 * s * s)
    return np.degrees(lat), h


def launch_to_geodetic(site: LaunchSite, t, r, v) -> tuple[np.ndarray, ...]:
    """Launch-inertial -> (lat, lon, h, v_east, v_north, v_up): :func:`launch_to_ecef` then :func:`ecef_to_geodetic`."""
    return ecef_to_geodetic(*launch_to_ecef(site, t, r, v))


def geodetic_to_launch(site: LaunchSite, t, lat, lon, h, v_east, v_north, v_up) -> tuple[np.ndarray, np.ndarray]:
    """(lat, lon, h, v_east, v_north, v_up) -> launch-inertial position and velocity."""
    return ecef_to_launch(site, t, *geodetic_to_ecef(lat, lon, h, v_east, v_north, v_up))

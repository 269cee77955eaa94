"""The simulator's Earth and air: gravity constants, the 1976 standard atmosphere, the drag table,
and the Earth turning under a launch-inertial frame (the assumptions: :mod:`casep.simulation.trajectory`).
"""

from __future__ import annotations

import math

import numpy as np

from casep.units import G0

__all__ = ["MU_EARTH", "R_EARTH", "atmosphere", "atmosphere_many", "axial_drag_coefficient",
           "axial_drag_coefficients", "RotatingEarth", "air_relative", "air_relative_rate"]

MU_EARTH = 3.986004418e14  # m^3/s^2
R_EARTH = 6_371_000.0  # m
_R_AIR = 287.05287  # J/(kg K)

# U.S. Standard Atmosphere 1976: base geopotential height (m), lapse rate (K/m).
_H_BASE = np.array([0.0, 11_000.0, 20_000.0, 32_000.0, 47_000.0, 51_000.0, 71_000.0, 84_852.0])
_LAPSE = np.array([-0.0065, 0.0, 0.001, 0.0028, 0.0, -0.0028, -0.002])
_T_BASE = np.empty(8)
_P_BASE = np.empty(8)
_T_BASE[0], _P_BASE[0] = 288.15, 101_325.0
for _i in range(7):
    _dh = _H_BASE[_i + 1] - _H_BASE[_i]
    _T_BASE[_i + 1] = _T_BASE[_i] + _LAPSE[_i] * _dh
    if _LAPSE[_i] == 0.0:
        _P_BASE[_i + 1] = _P_BASE[_i] * math.exp(-G0 * _dh / (_R_AIR * _T_BASE[_i]))
    else:
        _P_BASE[_i + 1] = _P_BASE[_i] * (_T_BASE[_i + 1] / _T_BASE[_i]) ** (-G0 / (_LAPSE[_i] * _R_AIR))

#: Axial-force coefficient C_A against Mach number (table, linear in between).
_MACH = np.array([0.0, 0.8, 1.1, 1.5, 2.0, 3.0, 5.0, 10.0])
_CA = np.array([0.30, 0.32, 0.55, 0.48, 0.40, 0.32, 0.25, 0.25])


def atmosphere(h: float) -> tuple[float, float]:
    """Density (kg/m^3) and speed of sound (m/s) at geometric altitude `h` (m)."""
    hg = R_EARTH * h / (R_EARTH + h)  # geopotential height
    if hg < 0.0:
        hg = 0.0
    if hg >= _H_BASE[-1]:
        T = _T_BASE[-1]
        rho_top = _P_BASE[-1] / (_R_AIR * T)
        return rho_top * math.exp(-(hg - _H_BASE[-1]) * G0 / (_R_AIR * T)), math.sqrt(1.4 * _R_AIR * T)
    i = int(np.searchsorted(_H_BASE, hg, side="right") - 1)
    L, Tb, Pb = _LAPSE[i], _T_BASE[i], _P_BASE[i]
    T = Tb + L * (hg - _H_BASE[i])
    if L == 0.0:
        P = Pb * math.exp(-G0 * (hg - _H_BASE[i]) / (_R_AIR * Tb))
    else:
        P = Pb * (T / Tb) ** (-G0 / (L * _R_AIR))
    return P / (_R_AIR * T), math.sqrt(1.4 * _R_AIR * T)


def atmosphere_many(h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`atmosphere` at many altitudes `h` (M,), m: density (kg/m^3) and speed of sound (m/s), (M,) each."""
    hg = np.maximum(R_EARTH * h / (R_EARTH + h), 0.0)  # geopotential height
    top = hg >= _H_BASE[-1]
    i = np.clip(np.searchsorted(_H_BASE, hg, side="right") - 1, 0, _LAPSE.size - 1)
    L, Tb, Pb, Hb = _LAPSE[i], _T_BASE[i], _P_BASE[i], _H_BASE[i]
    T = np.where(top, _T_BASE[-1], Tb + L * (hg - Hb))
    iso = L == 0.0
    P = np.empty_like(hg)
    P[iso] = Pb[iso] * np.exp(-G0 * (hg[iso] - Hb[iso]) / (_R_AIR * Tb[iso]))
    grad = ~iso
    P[grad] = Pb[grad] * (T[grad] / Tb[grad]) ** (-G0 / (L[grad] * _R_AIR))
    rho = P / (_R_AIR * T)
    rho_top = _P_BASE[-1] / (_R_AIR * _T_BASE[-1])
    rho[top] = rho_top * np.exp(-(hg[top] - _H_BASE[-1]) * G0 / (_R_AIR * _T_BASE[-1]))  # exponential above
    return rho, np.sqrt(1.4 * _R_AIR * T)


def axial_drag_coefficient(mach: float) -> float:
    """Axial-force coefficient C_A at Mach `mach` (the table above, linear in between, held outside)."""
    return float(np.interp(mach, _MACH, _CA))


def axial_drag_coefficients(mach: np.ndarray) -> np.ndarray:
    """:func:`axial_drag_coefficient` at many Mach numbers (M,)."""
    return np.interp(mach, _MACH, _CA)


class RotatingEarth:
    """The simulator's sphere turning rigidly with the Earth, in launch-inertial coordinates.

    Its assumptions: the "Rotating Earth" notes of :mod:`casep.simulation.trajectory`.
    """

    def __init__(self, site) -> None:
        from casep.frames import OMEGA_EARTH

        self.site = site
        self.w = site.earth_rate  # rad/s, launch axes: C^T (0, 0, omega_E)
        self.o = site.earth_centre  # WGS84 centre, a point of the axis, m
        self.k = self.w / OMEGA_EARTH  # unit vector of the axis
        self.omega = OMEGA_EARTH
        self.c0 = np.array([0.0, -R_EARTH, 0.0])  # the sphere's centre at lift-off (t = 0)
        from casep.navigation.strapdown import launch_gravitation

        self._gravitation = launch_gravitation(site)  # the navigator's own: WGS84, turning with the Earth

    def gravity(self, t: np.ndarray | float, pos: np.ndarray) -> np.ndarray:
        """The gravitation (mass attraction, what an inertial platform does not sense) at launch-inertial
        positions `pos` (3,) or (M, 3), m, and times `t`, s: WGS84's,
        :func:`casep.navigation.strapdown.launch_gravitation`, the field :func:`casep.navigation.navigate`
        integrates; m/s^2, the shape of `pos`."""
        pos = np.asarray(pos, dtype=float)
        g = self._gravitation(np.atleast_1d(np.asarray(t, dtype=float)), np.atleast_2d(pos))
        return g[0] if pos.ndim == 1 else g

    def pad(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Position and velocity (M, 3), m and m/s, of the launch point at times `t` (M,), turning with the Earth."""
        pos = self._turned(np.zeros(3), t)  # the launch point is the origin at lift-off
        return pos, np.cross(self.w, pos - self.o)

    def rotate(self, p: np.ndarray, t: float) -> np.ndarray:
        """`p` (about the axis point) turned by omega_E t about the axis (Rodrigues)."""
        a = self.omega * t
        k = self.k
        return p * math.cos(a) + np.cross(k, p) * math.sin(a) + k * (k @ p) * (1.0 - math.cos(a))

    def centre(self, t: float) -> np.ndarray:
        """The sphere's centre at `t`, m."""
        return self.o + self.rotate(self.c0 - self.o, t)  # the sphere's centre circles the axis

    def centres(self, t: np.ndarray) -> np.ndarray:
        """The sphere's centre at each of the times `t` (M,), (M, 3) m (:meth:`centre` at many times)."""
        return self._turned(self.c0, t)

    def _turned(self, point: np.ndarray, t: np.ndarray) -> np.ndarray:
        """The Earth-fixed `point` (3,) at lift-off, at each of the times `t` (M,): (M, 3) m (Rodrigues)."""
        a = self.omega * np.asarray(t, dtype=float)[:, None]
        k, p = self.k, point - self.o
        return self.o + p * np.cos(a) + np.cross(k, p) * np.sin(a) + k * (k @ p) * (1.0 - np.cos(a))

    def air_velocity(self, pos: np.ndarray) -> np.ndarray:
        """Velocity of the co-rotating air at `pos`, m/s."""
        return np.cross(self.w, pos - self.o)  # co-rotating atmosphere: w x (r - o)


def air_relative(state: dict, pos: np.ndarray, vel: np.ndarray) -> np.ndarray:
    """Velocity relative to the air, ``v - w x (r - o)``; the inertial one when the Earth does not turn
    (``state["earth"]`` None)."""
    earth = state.get("earth")
    return vel if earth is None else vel - earth.air_velocity(pos)


def air_relative_rate(state: dict, vel: np.ndarray, acc: np.ndarray) -> np.ndarray:
    """Rate of :func:`air_relative`, ``a - w x v``; the inertial acceleration when the Earth does not turn."""
    earth = state.get("earth")
    return acc if earth is None else acc - np.cross(earth.w, vel)

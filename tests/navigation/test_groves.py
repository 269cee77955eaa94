"""``navigate`` on a published trajectory: 30 s of the aircraft truth profile of Groves' textbook.

The profile (tests/data/groves, BSD; level flight east at 200 m/s, 10 km, 50.4 deg N, rolling into
a 14 deg banked turn) gives position, NED velocity and attitude at 100 Hz. The ideal IMU is derived
from it by an independent route: the inertial velocity ``Rz(theta) (v_E + omega x r_E)`` and the
attitude ``Rz(theta) C_n^e C_b^n`` are differentiated by eighth-order central differences, and the
gravitation is the gradient (central differences) of the zonal spherical-harmonic potential
(J2, J4, J6), not casep's closed form. casep then navigates it from the truth state at the first
sample, and position, velocity and attitude are compared with the truth over the 30 s.

The tolerances come from the route, not from casep. The profile's attitude has steps in angular
acceleration at the roll-in, where differences of a non-smooth signal err for a few samples: a
transient attitude error of 2.1e-5 rad (measured), 4e-9 rad elsewhere. During the turn the
profile's own north velocity jitters by ~7e-4 m/s from sample to sample, which the derivative
route smooths: the velocity error (measured 1.2e-3 m/s at most) is that jitter, the position error
(measured 2.7e-3 m) its integral. The bounds are about 3 times the measured figures.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pymap3d
from numpy.polynomial import legendre
from scipy.spatial.transform import Rotation

from casep.frames import OMEGA_EARTH, LaunchSite, ecef_to_launch
from casep.navigation import ImuData, check_imu, navigate_from
from casep.navigation.strapdown import dcm_to_quat, quat_multiply

PROFILE = Path(__file__).resolve().parents[1] / "data" / "groves" / "Profile_3_15-45s.csv"
GM, A = 3.986004418e14, 6378137.0
J = {2: 1.082629821313e-3, 4: -2.37091222e-6, 6: 6.08347e-9}  # the WGS84 normal field's zonal coefficients
D8 = np.array([1 / 280, -4 / 105, 1 / 5, -4 / 5, 0.0, 4 / 5, -1 / 5, 4 / 105, -1 / 280])  # d/dt, 8th order


def _potential(r: np.ndarray) -> np.ndarray:
    rn = np.linalg.norm(r, axis=1)
    s = r[:, 2] / rn
    return GM / rn * (1.0 - sum(Jn * (A / rn) ** n * legendre.legval(s, [0] * n + [1]) for n, Jn in J.items()))


def _gravitation(r: np.ndarray) -> np.ndarray:
    return np.column_stack([(_potential(r + e) - _potential(r - e)) / 2.0 for e in np.eye(3)])  # 1 m steps


def _derivative(y: np.ndarray, h: float) -> np.ndarray:
    """Central differences, valid on y[4:-4]."""
    out = np.zeros((len(y) - 8,) + y.shape[1:])
    for j, c in enumerate(D8):
        if c:
            out += c * y[j:len(y) - 8 + j]
    return out / h


def _rz(theta: np.ndarray) -> np.ndarray:
    c, s = np.cos(theta), np.sin(theta)
    R = np.zeros((len(theta), 3, 3))
    R[:, 0, 0], R[:, 0, 1], R[:, 1, 0], R[:, 1, 1], R[:, 2, 2] = c, -s, s, c, 1.0
    return R


def _truth_and_imu():
    d = np.loadtxt(PROFILE, delimiter=",")
    t, lat, lon, h = d[:, 0], d[:, 1], d[:, 2], d[:, 3]
    r_e = np.column_stack(pymap3d.geodetic2ecef(lat, lon, h))
    v_e = np.column_stack(pymap3d.enu2ecefv(d[:, 5], d[:, 4], -d[:, 6], lat, lon))
    Rz = _rz(OMEGA_EARTH * (t - t[0]))  # the inertial frame: ECEF at the first sample
    v_i = np.einsum("nij,nj->ni", Rz, v_e + np.cross([0.0, 0.0, OMEGA_EARTH], r_e))
    ned = np.stack([np.column_stack(pymap3d.enu2ecefv(*axis, lat, lon)) for axis in ([0, 1, 0], [1, 0, 0], [0, 0, -1])],
                   axis=2)  # columns: north, east, down in ECEF
    C_ib = Rz @ ned @ Rotation.from_euler("ZYX", d[:, [9, 8, 7]], degrees=True).as_matrix()
    dt = t[1] - t[0]
    inner = slice(4, -4)
    f_i = _derivative(v_i, dt) - _gravitation(np.einsum("nij,nj->ni", Rz, r_e)[inner])
    Om = np.einsum("nji,njk->nik", C_ib[inner], _derivative(C_ib, dt))  # C^T dC/dt = [w x]
    w_b = 0.5 * np.column_stack([Om[:, 2, 1] - Om[:, 1, 2], Om[:, 0, 2] - Om[:, 2, 0], Om[:, 1, 0] - Om[:, 0, 1]])
    f_b = np.einsum("nji,nj->ni", C_ib[inner], f_i)
    site = LaunchSite(lat[0], lon[0], h[0], 0.0, t[0])  # L: the triad at the first sample, x north
    r_l, v_l = ecef_to_launch(site, t[inner], r_e[inner], v_e[inner])
    C_lb = site.C.T @ C_ib[inner]
    return site, t[inner], w_b, f_b, r_l, v_l, C_lb


def test_navigating_groves_aircraft_profile_follows_the_truth():
    site, t, w_b, f_b, r_l, v_l, C_lb = _truth_and_imu()
    assert np.abs(w_b).max() > 0.05 and t[-1] - t[0] > 29  # the cut holds the roll into the turn
    res = navigate_from(check_imu(ImuData(t, w_b, f_b)), site, dcm_to_quat(C_lb[0]), r_l[0], v_l[0])
    assert res.success
    q_true = np.array([dcm_to_quat(C) for C in C_lb])
    dq = quat_multiply(q_true * np.array([1, -1, -1, -1]), res.q)
    attitude = 2.0 * np.linalg.norm(dq[:, 1:], axis=1)
    dv, dr = np.abs(res.v - v_l).max(), np.abs(res.r - r_l).max()
    assert attitude.max() < 6e-5, attitude.max()
    assert np.median(attitude) < 1e-7  # away from the roll-in transient
    assert dv < 4e-3, dv
    assert dr < 1e-2, dr
    # the frame is what the tracking chain uses: r_l, v_l came from casep.frames.ecef_to_launch
    assert np.linalg.norm(res.v[-1] - res.v[0]) > 10.0  # the turn changed the velocity (the test could fail)

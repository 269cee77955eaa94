"""The predicted radar measurement h(r, v) of a station and its Jacobian H, exact from CasADi.

Chain (see :mod:`casep.frames`; ``theta = omega_E (t - t0)``, ``Rz`` the rotation about the ECEF
z axis, ``C`` the launch triad at t0 as ECEF columns, ``r_s`` the launch point, ``r_st`` the
station (ECEF), ``M`` the ECEF -> station east-north-up rotation, rows east, north, up)::

    r_E = Rz(theta)^T (r_s + C r_L)                  # launch-inertial -> ECEF (Earth turned by theta)
    v_E = Rz(theta)^T C v_L - w x r_E                # velocity relative to the rotating Earth
    a_E = Rz(theta)^T C a_L - 2 w x v_E - w x (w x r_E)   # relative acceleration (a_L kinematic)
    (e, n, u) = M (r_E - r_st),   (e', n', u') = M v_E,   (e'', n'', u'') = M a_E
    rho = sqrt(e^2 + n^2 + u^2)                      # range, m
    A   = atan2(e, n)                                # azimuth from north, clockwise, rad
    E   = atan2(u, sqrt(e^2 + n^2))                  # elevation above the WGS84-normal horizon, rad
    rho' = (e e' + n n' + u u') / rho                # range rate, m/s
    rho'' = (|(e', n', u')|^2 + (e, n, u).(e'', n'', u'') - rho'^2) / rho   # range acceleration (time bias in rho')
    A' = (n e' - e n') / (e^2 + n^2)                 # angle rates (time-bias terms)
    E' = (u' (e^2 + n^2) - u (e e' + n n')) / (rho^2 sqrt(e^2 + n^2))

``H = d(rho, A, E, rho')/d(r_L, v_L)`` (4 x 6) is CasADi's exact derivative of the same
expression graph. The measurement is geometric (straight line of sight, no refraction, no
light time: 1 ms at 300 km, which a user term can model as a time bias).
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np

from casep.frames import OMEGA_EARTH, LaunchSite

__all__ = ["RadarGeometry", "wrap_angle", "GEOMETRY_COLUMNS"]

#: Columns of :attr:`RadarGeometry.evaluate`'s geometry, the inputs of a tracking model.
GEOMETRY_COLUMNS = ("range", "azimuth", "elevation", "range_rate", "azimuth_rate", "elevation_rate",
                    "range_acceleration", "east", "north", "up")


def wrap_angle(a: np.ndarray) -> np.ndarray:
    """Angles wrapped to [-pi, pi) (azimuth residuals across north)."""
    return (np.asarray(a, dtype=float) + math.pi) % (2.0 * math.pi) - math.pi


def _function() -> ca.Function:
    x = ca.SX.sym("x", 6)  # r_L (m), v_L (m/s), launch-inertial
    acc = ca.SX.sym("a", 3)  # kinematic acceleration a_L (m/s^2), launch-inertial
    dt = ca.SX.sym("dt")  # t - t0, s
    p = ca.SX.sym("p", 24)  # C (9, column-major), Rz-free launch point r_s (3), M (9, column-major), r_st (3)
    C = ca.reshape(p[0:9], 3, 3)
    r_s = p[9:12]
    M = ca.reshape(p[12:21], 3, 3)
    r_st = p[21:24]
    th = OMEGA_EARTH * dt
    c, s = ca.cos(th), ca.sin(th)
    RzT = ca.vertcat(ca.horzcat(c, s, 0), ca.horzcat(-s, c, 0), ca.horzcat(0, 0, 1))  # Rz(theta)^T
    r_L, v_L = x[0:3], x[3:6]
    r_E = ca.mtimes(RzT, r_s) + ca.mtimes(RzT, ca.mtimes(C, r_L))  # Rz^T r_s + Rz^T C r_L (as casep.frames)
    v_E = ca.mtimes(RzT, ca.mtimes(C, v_L)) - ca.vertcat(-OMEGA_EARTH * r_E[1], OMEGA_EARTH * r_E[0], 0)
    w = ca.vertcat(0, 0, OMEGA_EARTH)
    # relative acceleration in ECEF: a_E = Rz^T C a_L - 2 w x v_E - w x (w x r_E)
    a_E = ca.mtimes(RzT, ca.mtimes(C, acc)) - 2 * ca.cross(w, v_E) - ca.cross(w, ca.cross(w, r_E))
    enu = ca.mtimes(M, r_E - r_st)
    enu_dot = ca.mtimes(M, v_E)
    enu_ddot = ca.mtimes(M, a_E)
    e, n, u = enu[0], enu[1], enu[2]
    hor = ca.sqrt(e**2 + n**2)
    rho = ca.sqrt(e**2 + n**2 + u**2)
    az = ca.atan2(e, n)
    el = ca.atan2(u, hor)
    rho_dot = ca.dot(enu, enu_dot) / rho
    rho_ddot = (ca.dot(enu_dot, enu_dot) + ca.dot(enu, enu_ddot) - rho_dot**2) / rho
    ed, nd, ud = enu_dot[0], enu_dot[1], enu_dot[2]
    az_dot = (n * ed - e * nd) / hor**2  # d atan2(e, n) / dt
    el_dot = (ud * hor**2 - u * (e * ed + n * nd)) / (rho**2 * hor)  # d atan2(u, hor) / dt
    rates = ca.vertcat(az_dot, el_dot)
    meas = ca.vertcat(rho, az, el, rho_dot)
    H = ca.jacobian(meas, x)  # exact, 4 x 6
    geo = ca.vertcat(meas, rates, rho_ddot, enu)  # GEOMETRY_COLUMNS order
    return ca.Function("radar_h", [x, acc, dt, p], [geo, ca.densify(H)], ["x", "a", "dt", "p"], ["geometry", "H"])


_FUNCTION: ca.Function | None = None
_GEOMETRY_ONLY: ca.Function | None = None


def _shared_function() -> ca.Function:
    """``_function()``, built on first use and shared by every :class:`RadarGeometry`."""
    global _FUNCTION
    if _FUNCTION is None:
        _FUNCTION = _function()
    return _FUNCTION


def _geometry_function() -> ca.Function:
    """``_function()`` without its Jacobian output ``H`` (the same geometry expression, half the work):
    for the finite differences that read ``h`` only."""
    global _GEOMETRY_ONLY
    if _GEOMETRY_ONLY is None:
        f = _shared_function()
        _GEOMETRY_ONLY = ca.Function("radar_g", f.sx_in(), [f(*f.sx_in())[0]], f.name_in(), ["geometry"])
    return _GEOMETRY_ONLY


#: ``_function()`` mapped serially over n samples, by n (the parameter vector shared: ``reduce_in``);
#: a fit evaluates the same few sample counts many times.
_MAPPED: dict[tuple[int, bool], ca.Function] = {}


def _mapped_function(n: int, jacobian: bool = True) -> ca.Function:
    """``_shared_function()`` (or ``_geometry_function()`` without `jacobian`) mapped over `n` samples
    (built once per `n`, at most 32 kept)."""
    f = _MAPPED.get((n, jacobian))
    if f is None:
        if len(_MAPPED) >= 32:
            _MAPPED.clear()
        base = _shared_function() if jacobian else _geometry_function()
        f = _MAPPED[(n, jacobian)] = base.map(base.name() + "_map", "serial", n, [3], [])
    return f


class RadarGeometry:
    """Predicted measurements of one station for a launch site: ``h`` and ``H`` per sample.

    Parameters
    ----------
    site : LaunchSite
        Ties the launch-inertial frame to the Earth (launch point, azimuth, launch time t0).
    station : Station
        :class:`casep.radar.stations.Station` (its ECEF position and ENU axes by pymap3d).
    """

    def __init__(self, site: LaunchSite, station) -> None:
        _shared_function()  # built here, once per process
        self.site = site
        self.station = station
        self._p = self._parameters(0.0, np.zeros(3))

    def _parameters(self, dt0: float, d_enu: np.ndarray) -> np.ndarray:
        """The CasADi parameter vector with the launch time moved by `dt0` (s), the station by `d_enu` (m, ENU)."""
        enu = self.station.enu_rows
        return np.concatenate([self.site.C.ravel(order="F"), self.site.r_site, enu.ravel(order="F"),
                               self.station.r_ecef + enu.T @ d_enu, [dt0]])

    def evaluate(self, t: np.ndarray, r: np.ndarray, v: np.ndarray,
                 a: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Geometry and Jacobian at times `t` for launch-inertial positions `r` and velocities `v`.

        `a`: the kinematic acceleration (launch-inertial, m/s^2), used only for the range
        acceleration column (NaN there without it).

        Returns
        -------
        geometry : (N, 10) ndarray
            :data:`GEOMETRY_COLUMNS` (m, rad, rad, m/s, rad/s, rad/s, m/s^2, m, m, m); azimuth in (-pi, pi].
        H : (N, 4, 6) ndarray
            d(range, azimuth, elevation, range_rate) / d(r, v).
        """
        t = np.asarray(t, dtype=float)
        x = np.hstack([np.asarray(r, dtype=float), np.asarray(v, dtype=float)])
        if x.shape != (t.size, 6):
            raise ValueError(f"`r` and `v` must be ({t.size}, 3), got {np.shape(r)} and {np.shape(v)}")
        if t.size == 0:
            return np.zeros((0, len(GEOMETRY_COLUMNS))), np.zeros((0, 4, 6))
        acc = np.zeros((t.size, 3)) if a is None else np.asarray(a, dtype=float).reshape(t.size, 3)
        geo, H = self._evaluate(t, x, acc, self._p, a is None)
        assert H is not None  # computed: jacobian=True
        return geo, H

    def _evaluate(self, t: np.ndarray, x: np.ndarray, acc: np.ndarray, p: np.ndarray,
                  no_acc: bool, jacobian: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
        """:meth:`evaluate` on the stacked state ``x = [r, v]`` with the parameter vector `p`
        (``H`` not computed, ``None``, without `jacobian`)."""
        # Evaluated through a CasADi FunctionBuffer straight into numpy arrays (converting the DM
        # results element by element cost as much as the evaluation). CasADi is column-major: the
        # mapped input x (6 x N) is the C-contiguous (N, 6) array, the output geometry (10 x N) is
        # (N, 10), and H (4 x 6N, sample after sample) is (N, 6, 4).
        n = t.size
        buf, run = _mapped_function(n, jacobian).buffer()
        args = [np.ascontiguousarray(a, dtype=float) for a in (x, acc, t - self.site.t0 - p[-1], p[:-1])]
        geo = np.empty((n, len(GEOMETRY_COLUMNS)))
        Ht = np.empty((n, 6, 4)) if jacobian else None
        for i, a in enumerate(args):
            buf.set_arg(i, memoryview(a))  # type: ignore[arg-type, call-arg]  # size: the memoryview's
        buf.set_res(0, memoryview(geo))  # type: ignore[arg-type, call-arg]
        if Ht is not None:
            buf.set_res(1, memoryview(Ht))  # type: ignore[arg-type, call-arg]
        run()
        if no_acc:
            geo[:, GEOMETRY_COLUMNS.index("range_acceleration")] = np.nan
        return geo, None if Ht is None else Ht.transpose(0, 2, 1)

    def setup_jacobian(self, t: np.ndarray, r: np.ndarray, v: np.ndarray, a: np.ndarray | None = None,
                       *, station: bool = True, step_time: float = 0.01, step_position: float = 1.0) -> np.ndarray:
        """Sensitivity of (range, azimuth, elevation, range rate) to the set-up: launch time and station position.

        Central differences (exact to ``O(step^2)``: the chain is smooth on the scale of the steps)::

            d h / d t0    = (h(t0 + dt) - h(t0 - dt)) / (2 dt)               (per s; dt = `step_time`)
            d h / d e_k   = (h(r_st + d e_k) - h(r_st - d e_k)) / (2 d)        (per m; d = `step_position`)

        with ``e_k`` the station's east, north and up axes (azimuth differences wrapped).

        Returns
        -------
        (N, 4, 4) ndarray, or (N, 4, 1) with ``station=False``
            ``[sample, measurement type, (t0, east, north, up)]``, SI.
        """
        t = np.asarray(t, dtype=float)
        x = np.hstack([np.asarray(r, dtype=float), np.asarray(v, dtype=float)])
        acc = np.zeros((t.size, 3)) if a is None else np.asarray(a, dtype=float).reshape(t.size, 3)
        steps = [(step_time, np.zeros(3))] + ([(0.0, step_position * e) for e in np.eye(3)] if station else [])
        out = np.empty((t.size, 4, len(steps)))
        for k, (dt0, d) in enumerate(steps):
            hp, _ = self._evaluate(t, x, acc, self._parameters(dt0, d), False, jacobian=False)
            hm, _ = self._evaluate(t, x, acc, self._parameters(-dt0, -d), False, jacobian=False)
            diff = hp[:, :4] - hm[:, :4]
            diff[:, 1] = wrap_angle(diff[:, 1])
            out[:, :, k] = diff / (2.0 * (step_time if k == 0 else step_position))
        return out

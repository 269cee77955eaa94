"""Impact point of a vacuum ballistic flight from a burnout state, and its exact Jacobian.

Earth model of the simulator (:mod:`casep.simulation.trajectory`): a sphere of radius
``R_E = 6 371 000`` m centred at ``c = (0, -R_E, 0)`` in the launch-inertial frame, inverse-square
gravity ``mu = 3.986004418e14`` m^3/s^2, not rotating, no atmosphere. The flight after burnout is
then a Kepler conic and its intersection with the sphere has a closed form (no integration).

The closed form is written once with CasADi symbols, so the Jacobian with respect to the
6-vector burnout state ``x_b = (r, v)`` is exact (algorithmic differentiation), not a finite
difference. The tests check the impact point against an independent adaptive integration of
the two-body equations with an event at ``|r - c| = R_E`` (:func:`impact_point_ode`) and the
Jacobian against central finite differences.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from casep.simulation.trajectory import MU_EARTH, R_EARTH

__all__ = ["EARTH_CENTRE", "BallisticError", "impact_functions", "impact", "impact_point", "impact_jacobian",
           "impact_point_ode", "ground_coordinates"]

#: Earth centre in the launch-inertial frame, m.
EARTH_CENTRE = np.array([0.0, -R_EARTH, 0.0])


class BallisticError(ValueError):
    """The burnout state has no ballistic impact (escape, orbit, or below the surface)."""


@functools.lru_cache(maxsize=1)
def impact_functions():
    """The named CasADi functions of the closed-form impact (built once).

    Returns
    -------
    dict of str -> casadi.Function
        ``impact``: ``(r, v) -> (downrange, crossrange)``, m;
        ``impact_point``: ``(r, v) -> p`` (3, impact position, launch frame, m);
        ``impact_jacobian``: ``(r, v) -> J`` (2 x 6, d(downrange, crossrange) / d(r, v));
        ``conic``: ``(r, v) -> (p, e, cos_nu_i)`` (semi-latus rectum m, eccentricity, cosine of
        the impact true anomaly: the impact exists when ``|cos_nu_i| <= 1``).

    Notes
    -----
    With ``R = r - c`` (from the Earth centre) and ``v``::

        h_vec = R x v,  h = |h_vec|,  p = h^2 / mu                (semi-latus rectum)
        e cos(nu_0) = p / |R| - 1                                (conic equation at burnout)
        e sin(nu_0) = h (R . v) / (mu |R|)                        (radial velocity = mu e sin(nu) / h)
        e = sqrt((e cos nu_0)^2 + (e sin nu_0)^2),  nu_0 = atan2(e sin nu_0, e cos nu_0)
        cos(nu_i) = (p / R_E - 1) / e                            (|R| = R_E on the conic)
        nu_i = -acos(cos nu_i)                                   (descending branch: sin nu_i < 0)
        dnu = (nu_i - nu_0) mod 2 pi                             (angle flown in the orbit plane)
        u = cos(dnu) R/|R| + sin(dnu) (h_vec/h) x (R/|R|)        (unit vector centre -> impact)
        p_impact = c + R_E u
        downrange = R_E atan2(u_x, u_y),  crossrange = R_E asin(u_z)

    (launch point at ``u0 = (0, 1, 0)``, ``docs/reference/file-formats.md`` "Impact JSON").
    """
    import casadi as ca

    r = ca.SX.sym("r", 3)
    v = ca.SX.sym("v", 3)
    R = r - ca.DM(EARTH_CENTRE)  # from the Earth centre
    Rn = ca.norm_2(R)
    hv = ca.cross(R, v)  # specific angular momentum
    h = ca.norm_2(hv)
    p = h**2 / MU_EARTH  # semi-latus rectum
    ec = p / Rn - 1.0  # e cos(nu_0)
    es = h * ca.dot(R, v) / (MU_EARTH * Rn)  # e sin(nu_0)
    e = ca.sqrt(ec**2 + es**2)
    nu0 = ca.atan2(es, ec)  # true anomaly at burnout, (-pi, pi]
    cos_nui = (p / R_EARTH - 1.0) / e
    nui = -ca.acos(cos_nui)  # descending branch
    d = nui - nu0
    dnu = ca.if_else(d < 0, d + 2 * math.pi, d)  # angle from burnout to impact, [0, 2 pi)
    Rhat = R / Rn
    w = ca.cross(hv / h, Rhat)  # in the orbit plane, 90 deg ahead of Rhat
    u = ca.cos(dnu) * Rhat + ca.sin(dnu) * w  # centre -> impact, unit
    point = ca.DM(EARTH_CENTRE) + R_EARTH * u
    down = R_EARTH * ca.atan2(u[0], u[1])
    cross = R_EARTH * ca.asin(u[2])
    x = ca.vertcat(r, v)
    jac = ca.jacobian(ca.vertcat(down, cross), x)  # 2 x 6, exact
    return {
        "impact": ca.Function("impact", [r, v], [down, cross], ["r", "v"], ["downrange", "crossrange"]),
        "impact_point": ca.Function("impact_point", [r, v], [point], ["r", "v"], ["p"]),
        "impact_jacobian": ca.Function("impact_jacobian", [r, v], [jac], ["r", "v"], ["J"]),
        "conic": ca.Function("conic", [r, v], [p, e, cos_nui], ["r", "v"], ["p", "e", "cos_nu_i"]),
    }


def _state(r, v) -> tuple[np.ndarray, np.ndarray]:
    r = np.asarray(r, dtype=float).reshape(-1)
    v = np.asarray(v, dtype=float).reshape(-1)
    if r.shape != (3,) or v.shape != (3,):
        raise ValueError(f"`r` and `v` must be 3-vectors, got shapes {np.shape(r)} and {np.shape(v)}")
    if not (np.all(np.isfinite(r)) and np.all(np.isfinite(v))):
        raise ValueError(f"burnout state is not finite: r = {r.tolist()}, v = {v.tolist()}")
    return r, v


def check_ballistic(r, v) -> None:
    """Raise :class:`BallisticError` when the state ``(r, v)`` has no impact on the sphere."""
    r, v = _state(r, v)
    alt = float(np.linalg.norm(r - EARTH_CENTRE) - R_EARTH)
    if alt < 0.0:
        raise BallisticError(f"burnout state is {-alt:.1f} m below the Earth's surface (|r - c| < R_E)")
    p, e, c = (float(x) for x in impact_functions()["conic"](r, v))
    speed = float(np.linalg.norm(v))
    if not abs(c) <= 1.0:  # cos(nu_i) > 1: perigee radius p / (1 + e) above R_E
        raise BallisticError(f"no ballistic impact from the burnout state (speed {speed:.1f} m/s, altitude "
                             f"{alt:.0f} m, eccentricity {e:.4g}, perigee radius {p / (1 + e):.0f} m > R_E): "
                             "the conic does not meet the Earth")
    if e >= 1.0 and float(np.dot(r - EARTH_CENTRE, v)) >= 0.0:  # open conic, moving away: never returns
        raise BallisticError(f"no ballistic impact from the burnout state (speed {speed:.1f} m/s, altitude "
                             f"{alt:.0f} m): escape trajectory (eccentricity {e:.4g} >= 1) climbing")


def impact(r, v) -> tuple[float, float]:
    """Downrange and crossrange of the impact point, m (closed-form Kepler; see :func:`impact_functions`)."""
    r, v = _state(r, v)
    check_ballistic(r, v)
    d, c = impact_functions()["impact"](r, v)
    return float(d), float(c)


def impact_point(r, v) -> np.ndarray:
    """Impact position in the launch-inertial frame, m (3,)."""
    r, v = _state(r, v)
    check_ballistic(r, v)
    return np.array(impact_functions()["impact_point"](r, v)).reshape(3)


def impact_jacobian(r, v) -> np.ndarray:
    """Exact 2 x 6 Jacobian ``d(downrange, crossrange) / d(r_x, r_y, r_z, v_x, v_y, v_z)``, m/m and m/(m/s)."""
    r, v = _state(r, v)
    check_ballistic(r, v)
    return np.array(impact_functions()["impact_jacobian"](r, v))


def ground_coordinates(point) -> tuple[float, float]:
    """Downrange and crossrange (m) of a point on (or above) the sphere: ``R_E atan2(u_x, u_y)``, ``R_E asin(u_z)``."""
    u = np.asarray(point, dtype=float) - EARTH_CENTRE
    u = u / np.linalg.norm(u)
    return float(R_EARTH * math.atan2(u[0], u[1])), float(R_EARTH * math.asin(u[2]))


def impact_point_ode(r, v, *, rtol: float = 1e-12, atol: float = 1e-9, t_max: float = 2.0e5
                     ) -> tuple[np.ndarray, float]:
    """Impact position and time of flight by integrating the two-body equations (reference).

    An independent route to :func:`impact_point`: ``r'' = -mu (r - c) / |r - c|^3`` integrated
    with scipy's DOP853 and an event at ``|r - c| - R_E = 0`` crossed downwards.

    Returns
    -------
    (3,) ndarray, float
        Impact position (launch frame, m) and time of flight (s).
    """
    from scipy.integrate import solve_ivp

    r, v = _state(r, v)

    def rhs(_t, x):
        R = x[:3] - EARTH_CENTRE
        return np.concatenate([x[3:], -MU_EARTH * R / np.linalg.norm(R) ** 3])  # r' = v, v' = g

    def ground(_t, x):
        return np.linalg.norm(x[:3] - EARTH_CENTRE) - R_EARTH  # altitude

    ground.terminal, ground.direction = True, -1.0  # type: ignore[attr-defined]  # solve_ivp's event attributes
    sol = solve_ivp(rhs, (0.0, t_max), np.concatenate([r, v]), method="DOP853", rtol=rtol, atol=atol,
                    events=ground)
    if not sol.t_events[0].size:
        raise BallisticError(f"no impact within {t_max:g} s of ballistic flight")
    return sol.y_events[0][0][:3].copy(), float(sol.t_events[0][0])

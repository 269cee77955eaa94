"""Boost-phase point-mass (3-DOF) trajectory in the launch-inertial frame.

Assumptions (every one is a choice, stated here and in docs/guide/simulation.md):

- **Frame**: launch-inertial, origin at the launch point; x downrange (horizontal at
  launch), y up (local vertical at launch), z cross-range, right-handed. The Earth does
  not rotate in this frame (launch-site velocity and Coriolis terms are left out: they
  change the trajectory, not the error-separation problem).
- **Earth**: sphere of radius ``R_E = 6 371 000`` m, centre at ``(0, -R_E, 0)``;
  inverse-square gravity ``g = -mu r / |r|^3`` with ``mu = 3.986004418e14`` m^3/s^2 (over a rotating
  Earth WGS84's instead: below); altitude ``h = |r| - R_E``.
- **Atmosphere**: U.S. Standard Atmosphere 1976 below 84.852 km geopotential (seven layers,
  hydrostatic), exponential above with the last layer's scale height; speed of sound
  ``sqrt(1.4 R T)``.
- **Aerodynamics**: axial drag only, ``D = q S C_A(M)`` along the body axis, with a
  tabulated ``C_A(M)`` (0.30 subsonic, 0.55 peak at Mach 1.1, 0.25 at Mach 5+).
- **Propulsion**: per stage a constant thrust ``T`` and specific impulse ``Isp``, mass flow
  ``T / (Isp g0)``, linear ignition ramp and linear tail-off, and a coast after burnout;
  the spent stage's dry mass drops at burnout. Stage 1 ignites on the pad (hold-down), so the
  flight starts at full thrust.
- **Attitude**: the body axis points along pitch ``theta`` (from x towards y) and yaw
  ``psi`` (out of plane, towards +z): ``e_b = (cos psi cos theta, cos psi sin theta, sin psi)``.
  Pitch programme: vertical rise, a pitch-over kick at constant rate, then a gravity turn
  (``theta`` follows the velocity's in-plane pitch, the kick's angle of attack decaying with
  time constant ``tau``). Optional yaw manoeuvre ``psi(t) = A sin(2 pi (t - t_a) / P)`` on
  ``[t_a, t_b]``, so that the z-axis terms of the error model see some excitation.
  Optional attitude offsets (:class:`AttitudeProfile`, used by ``casep design``): piecewise-linear
  pitch and yaw offsets (deg) at knot times, added to the pitch law and the yaw law above (held at
  the first/last knot's value outside the knots); the integration is cut at the knots (kinks).
- **Sensed specific force**: ``f = (T - D) e_b / m`` (gravity is not sensed).
- **Attitude and body rate** (for lever-arm terms): roll is zero; the body-to-platform
  rotation is ``C = Rz(theta) Ry(-psi)`` (body x axis = ``e_b``), its rate
  ``omega_p = theta_dot e_z - psi_dot Rz(theta) e_y`` (platform frame) and the body rate
  ``omega_b = C^T omega_p``; ``theta_dot`` and ``psi_dot`` are exact derivatives of the attitude
  law (in the gravity turn, of the velocity's pitch, from the kinematic acceleration).
- **Rotating Earth** (``simulate_boost(..., rotating_earth=True, site=LaunchSite)``, off by
  default): the equations stay those of the launch-inertial frame (no Coriolis or centrifugal
  term: the frame is inertial); what changes is the Earth. It turns at ``omega_E`` about the WGS84
  polar axis (``site.earth_rate`` in launch axes, through ``site.earth_centre``), as
  :mod:`casep.frames` assumes, and the simulator's sphere turns with it rigidly (its centre starts
  at ``(0, -R_E, 0)`` and circles the axis), so the altitude (the atmosphere's) follows the rotating
  sphere; the gravitation is WGS84's at the vehicle's Earth-fixed position
  (:func:`casep.navigation.strapdown.launch_gravitation`, the field :func:`casep.navigation.navigate`
  integrates, so a raw IMU simulated on this trajectory navigates back to it). The
  vehicle starts with the velocity of the pad, ``w x (0 - o)`` (329 m/s east at 45 deg); drag,
  Mach number and the gravity-turn attitude use the velocity relative to the co-rotating
  atmosphere ``v_rel = v - w x (r - o)`` (whose rate is ``a - w x v``). The platform is inertial, so
  the sensed specific force is still ``(T - D) e_b / m``; seen from the Earth the trajectory has the
  Coriolis and centrifugal accelerations (``casep.frames`` converts; tests check them against the
  closed forms).

:func:`simulate_boost` integrates the equations with an adaptive Runge-Kutta method (DOP853,
rtol 1e-10) piece by piece between thrust discontinuities and evaluates ``f`` exactly from
the state at the sample times (never by differencing).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from casep.simulation.environment import (
    MU_EARTH,
    R_EARTH,
    RotatingEarth,
    air_relative,
    air_relative_rate,
    atmosphere,
    atmosphere_many,
    axial_drag_coefficient,
    axial_drag_coefficients,
)
from casep.simulation.vehicle import (
    DEFAULT_VEHICLE,
    AttitudeProfile,
    PitchProgramme,
    Stage,
    Vehicle,
    YawManoeuvre,
    check_propellant,
    thrust,
    thrust_many,
    thrust_profile,
)
from casep.units import G0

# The vehicle types and the Earth constants are names of this module too.
__all__ = ["body_to_platform", "sampled_trajectory", "sample_times",
           "Stage", "Vehicle", "PitchProgramme", "YawManoeuvre", "AttitudeProfile",
           "BoostTrajectory", "simulate_boost", "atmosphere", "DEFAULT_VEHICLE", "MU_EARTH", "R_EARTH"]


@dataclass(frozen=True)
class BoostTrajectory:
    """Sampled boost trajectory.

    Attributes
    ----------
    t : (N,) s; position, velocity : (N, 3) m, m/s (launch-inertial); specific_force :
    (N, 3) m/s^2 as the platform senses it; mass : (N,) kg; altitude : (N,) m;
    events : dict of event name -> time (s); vehicle : Vehicle; acceleration : (N, 3)
    kinematic acceleration (specific force + gravity), m/s^2; attitude : (N, 3) pitch theta,
    yaw psi, roll (0), rad; body_rate : (N, 3) omega_b, rad/s, body frame (see the module notes).
    """

    t: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    specific_force: np.ndarray
    mass: np.ndarray
    altitude: np.ndarray
    events: dict
    vehicle: Vehicle
    acceleration: np.ndarray | None = None
    attitude: np.ndarray | None = None
    body_rate: np.ndarray | None = None
    _segments: list = field(repr=False, compare=False, default_factory=list)
    _aoa0: float = field(repr=False, compare=False, default=0.0)
    _earth: RotatingEarth | None = field(repr=False, compare=False, default=None)  # None: not rotating

    @property
    def site(self) -> Any:
        """The :class:`casep.frames.LaunchSite` of a rotating-Earth trajectory, else None."""
        return None if self._earth is None else self._earth.site

    @property
    def earth(self) -> RotatingEarth | None:
        """The turning Earth of a rotating-Earth trajectory, else None."""
        return self._earth

    def sample(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """True position and velocity at arbitrary `times` within the flight (dense output)."""
        times = np.asarray(times, dtype=float)
        self._dense()
        pos = np.empty((times.size, 3))
        vel = np.empty((times.size, 3))
        done = np.zeros(times.size, dtype=bool)
        for t0, t1, sol, *_ in self._segments:
            sel = (times >= t0) & (times <= t1) & ~done
            if np.any(sel):
                x = sol(times[sel])
                pos[sel], vel[sel] = x[0:3].T, x[3:6].T
                done |= sel
        if not np.all(done):
            bad = times[~done][0]
            raise ValueError(f"`times` contains {bad} s, outside the flight [{self.t[0]}, {self.t[-1]}] s")
        return pos, vel

    def _dense(self) -> None:
        """ValueError for a trajectory without the integration's dense output (built from stored samples)."""
        if not self._segments:
            raise ValueError("this trajectory holds its samples only (built from stored states, not integrated "
                             "here): it has no state between them; fly it with simulate_boost")

    def kinematics(self, times: np.ndarray) -> dict[str, np.ndarray]:
        """True state at arbitrary `times` within the flight (dense output, exact attitude law).

        Returns ``{"position", "velocity", "acceleration", "attitude", "body_rate"}``, each
        (M, 3), in the units of the class attributes.
        """
        times = np.atleast_1d(np.asarray(times, dtype=float))
        self._dense()
        out = {k: np.full((times.size, 3), np.nan) for k in ("position", "velocity", "acceleration",
                                                               "attitude", "body_rate")}
        state: dict[str, Any] = {"aoa0": self._aoa0, "earth": self._earth}
        done = np.zeros(times.size, dtype=bool)
        last_t1 = self._segments[-1][1]
        for t0, t1, sol, k, kind in self._segments:  # a piece owns [t0, t1), the last one [t0, t1]
            idx = np.flatnonzero((times >= t0) & ((times < t1) | ((t1 == last_t1) & (times <= t1))) & ~done)
            if idx.size:
                rows = _sampled(self.vehicle, self.vehicle.stages[k], kind, times[idx], t0, t1, sol(times[idx]), state)
                for key in out:
                    out[key][idx] = rows[key]
            done[idx] = True
        if not np.all(done):
            raise ValueError(f"`times` contains {times[~done][0]} s, outside the flight [{self.t[0]}, {self.t[-1]}] s")
        return out

    def summary(self) -> dict:
        """Burnout speed, altitude, flight-path angle and specific-force figures."""
        g = np.linalg.norm(self.specific_force, axis=1) / G0
        v = self.velocity[-1]
        return {
            "duration_s": float(self.t[-1] - self.t[0]),
            "burnout_speed_m_s": float(np.linalg.norm(v)),
            "burnout_altitude_m": float(self.altitude[-1]),
            "burnout_flight_path_deg": float(np.degrees(np.arctan2(v[1], math.hypot(v[0], v[2])))),
            "downrange_m": float(self.position[-1, 0]),
            "crossrange_m": float(self.position[-1, 2]),
            "liftoff_specific_force_g": float(g[0]),
            "max_specific_force_g": float(g.max()),
            "events_s": dict(self.events),
        }


def _angles(vehicle: Vehicle, t: float, v: np.ndarray, a: np.ndarray | None, state: dict
            ) -> tuple[float, float, float, float]:
    """Pitch theta, yaw psi (rad) and, when the kinematic acceleration `a` is given, their
    time derivatives (rad/s; else NaN)."""
    p = vehicle.pitch
    half_pi = 0.5 * math.pi
    t_kick_end = p.vertical + p.kick
    theta_dot = psi_dot = 0.0 if a is not None else math.nan
    if t < p.vertical:
        theta = half_pi
    elif t < t_kick_end:
        theta = half_pi - math.radians(p.kick_rate) * (t - p.vertical)
        theta_dot = -math.radians(p.kick_rate) if a is not None else math.nan
    else:
        theta_v = math.atan2(v[1], v[0])  # in-plane velocity pitch
        decay = state["aoa0"] * math.exp(-(t - t_kick_end) / p.tau)
        theta = theta_v + decay
        if a is not None:  # d atan2(vy, vx)/dt = (vx ay - vy ax) / (vx^2 + vy^2); d decay/dt = -decay / tau
            theta_dot = (v[0] * a[1] - v[1] * a[0]) / (v[0] ** 2 + v[1] ** 2) - decay / p.tau
    y = vehicle.yaw
    psi = math.radians(y.offset) if y is not None else 0.0
    if y is not None and y.start <= t <= y.end:
        w = 2.0 * math.pi / y.period
        psi += math.radians(y.amplitude) * math.sin(w * (t - y.start))
        if a is not None:
            psi_dot = math.radians(y.amplitude) * w * math.cos(w * (t - y.start))
    if vehicle.attitude is not None:  # designed offsets, added to both laws
        d_theta, d_psi, d_theta_dot, d_psi_dot = vehicle.attitude.offsets(t)
        base = vehicle.attitude.base(t)
        if base is not None:  # pitch programme open loop from the first knot on
            theta = base[0]
            if a is not None:
                theta_dot = base[1]
        theta += d_theta
        psi += d_psi
        if a is not None:
            theta_dot += d_theta_dot
            psi_dot += d_psi_dot
    return theta, psi, theta_dot, psi_dot


def body_to_platform(theta: np.ndarray, psi: np.ndarray, roll: np.ndarray | None = None) -> np.ndarray:
    """C = Rz(theta) Ry(-psi) Rx(roll), (..., 3, 3): body-to-platform rotation (body x = e_b)."""
    theta, psi = np.asarray(theta, dtype=float), np.asarray(psi, dtype=float)
    roll = np.zeros_like(theta) if roll is None else np.asarray(roll, dtype=float)
    ct, st, cp, sp, cr, sr = np.cos(theta), np.sin(theta), np.cos(psi), np.sin(psi), np.cos(roll), np.sin(roll)
    one, zero = np.ones_like(ct), np.zeros_like(ct)
    Rz = np.stack([np.stack([ct, -st, zero], -1), np.stack([st, ct, zero], -1), np.stack([zero, zero, one], -1)], -2)
    Ry = np.stack([np.stack([cp, zero, -sp], -1), np.stack([zero, one, zero], -1), np.stack([sp, zero, cp], -1)], -2)
    Rx = np.stack([np.stack([one, zero, zero], -1), np.stack([zero, cr, -sr], -1), np.stack([zero, sr, cr], -1)], -2)
    return Rz @ Ry @ Rx


def _attitude(vehicle: Vehicle, t: float, v: np.ndarray, state: dict) -> np.ndarray:
    theta, psi, _, _ = _angles(vehicle, t, v, None, state)
    cp = math.cos(psi)
    return np.array([cp * math.cos(theta), cp * math.sin(theta), math.sin(psi)])


def _forces(vehicle, stage, kind, t, t0, t1, x, state):
    """Specific force (m/s^2, sensed), gravity (m/s^2) and mass flow (kg/s)."""
    pos, vel, m = x[0:3], x[3:6], x[6]
    earth = state.get("earth")
    r = pos + np.array([0.0, R_EARTH, 0.0]) if earth is None else pos - earth.centre(t)
    rn = math.sqrt(r @ r)
    grav = -MU_EARTH * r / rn**3 if earth is None else earth.gravity(t, pos)  # rotating: WGS84's (module notes)
    h = rn - R_EARTH
    rho, a = atmosphere(h)
    vel = air_relative(state, pos, vel)  # relative to the (co-rotating) air
    speed = math.sqrt(vel @ vel)
    ca = axial_drag_coefficient(speed / a)
    drag = 0.5 * rho * speed**2 * vehicle.area * ca  # axial drag, N
    T = thrust(stage, kind, t, t0, t1)
    e_b = _attitude(vehicle, t, vel, state)
    f = (T - drag) / m * e_b  # f = (T - D) e_b / m: gravity is not sensed
    return f, grav, -T / (stage.isp * G0)


def _angles_many(vehicle: Vehicle, t: np.ndarray, v: np.ndarray, a: np.ndarray, aoa0: float
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_angles` at many samples: times `t` (M,), air-relative velocity `v` and its rate `a` (M, 3);
    pitch, yaw (rad) and their rates (rad/s), (M,) each."""
    p = vehicle.pitch
    t_kick_end = p.vertical + p.kick
    theta = np.full(t.shape, 0.5 * math.pi)
    theta_dot = np.zeros(t.shape)
    kick = (t >= p.vertical) & (t < t_kick_end)
    theta[kick] = 0.5 * math.pi - math.radians(p.kick_rate) * (t[kick] - p.vertical)
    theta_dot[kick] = -math.radians(p.kick_rate)
    turn = t >= t_kick_end
    vt, at = v[turn], a[turn]
    decay = aoa0 * np.exp(-(t[turn] - t_kick_end) / p.tau)
    theta[turn] = np.arctan2(vt[:, 1], vt[:, 0]) + decay  # in-plane velocity pitch + the kick's decaying AoA
    # d atan2(vy, vx)/dt = (vx ay - vy ax) / (vx^2 + vy^2); d decay/dt = -decay / tau
    theta_dot[turn] = (vt[:, 0] * at[:, 1] - vt[:, 1] * at[:, 0]) / (vt[:, 0] ** 2 + vt[:, 1] ** 2) - decay / p.tau
    y = vehicle.yaw
    psi = np.full(t.shape, math.radians(y.offset) if y is not None else 0.0)
    psi_dot = np.zeros(t.shape)
    if y is not None:
        sine = (t >= y.start) & (t <= y.end)
        w = 2.0 * math.pi / y.period
        psi[sine] += math.radians(y.amplitude) * np.sin(w * (t[sine] - y.start))
        psi_dot[sine] = math.radians(y.amplitude) * w * np.cos(w * (t[sine] - y.start))
    if vehicle.attitude is not None:  # designed offsets, added to both laws
        d_theta, d_psi, d_theta_dot, d_psi_dot = vehicle.attitude.offsets_many(t)
        on, base, base_dot = vehicle.attitude.base_many(t)  # pitch programme open loop from the first knot on
        theta[on], theta_dot[on] = base[on], base_dot[on]
        theta += d_theta
        psi += d_psi
        theta_dot += d_theta_dot
        psi_dot += d_psi_dot
    return theta, psi, theta_dot, psi_dot


def _sampled(vehicle: Vehicle, stage: Stage, kind: str, t: np.ndarray, t0: float, t1: float, y: np.ndarray,
             state: dict) -> dict[str, np.ndarray]:
    """The state at many samples of one piece: times `t` (M,), integrated state `y` (7, M).

    :func:`_forces` and :func:`_attitude_rates` with arrays (the same equations, evaluated for all
    samples at once): ``{"position", "velocity", "specific_force", "acceleration", "attitude",
    "body_rate"}``, (M, 3) each.
    """
    pos, vel, m = y[0:3].T, y[3:6].T, y[6]
    earth = state.get("earth")
    r = pos + np.array([0.0, R_EARTH, 0.0]) if earth is None else pos - earth.centres(t)
    rn = np.sqrt(np.sum(r * r, axis=1))
    grav = -MU_EARTH * r / (rn**3)[:, None] if earth is None else earth.gravity(t, pos)  # g = -mu r / |r|^3
    rho, a_sound = atmosphere_many(rn - R_EARTH)
    v_rel = air_relative(state, pos, vel)  # relative to the (co-rotating) air
    speed = np.sqrt(np.sum(v_rel * v_rel, axis=1))
    drag = 0.5 * rho * speed**2 * vehicle.area * axial_drag_coefficients(speed / a_sound)  # axial drag, N
    T = thrust_many(stage, kind, t, t0, t1)
    acc_rel = np.zeros_like(v_rel)  # the attitude's rates need the acceleration: first the attitude alone
    theta, psi, _, _ = _angles_many(vehicle, t, v_rel, acc_rel, state["aoa0"])
    cp = np.cos(psi)
    e_b = np.stack([cp * np.cos(theta), cp * np.sin(theta), np.sin(psi)], axis=1)
    f = ((T - drag) / m)[:, None] * e_b  # f = (T - D) e_b / m: gravity is not sensed
    acc = f + grav  # kinematic acceleration = specific force + gravity
    theta, psi, theta_dot, psi_dot = _angles_many(vehicle, t, v_rel, air_relative_rate(state, vel, acc),
                                                  state["aoa0"])
    ct, st, cp, sp = np.cos(theta), np.sin(theta), np.cos(psi), np.sin(psi)
    # omega_p = theta_dot e_z - psi_dot Rz(theta) e_y; omega_b = C^T omega_p with C = Rz(theta) Ry(-psi):
    # C = [[ct cp, -st, -ct sp], [st cp, ct, -st sp], [sp, 0, cp]]
    o0, o1, o2 = psi_dot * st, -psi_dot * ct, theta_dot
    body = np.stack([ct * cp * o0 + st * cp * o1 + sp * o2,
                     -st * o0 + ct * o1,
                     -ct * sp * o0 - st * sp * o1 + cp * o2], axis=1)
    return {"position": pos, "velocity": vel, "specific_force": f, "acceleration": acc,
            "attitude": np.stack([theta, psi, np.zeros_like(theta)], axis=1), "body_rate": body}


def simulate_boost(vehicle: Vehicle = DEFAULT_VEHICLE, rate: float = 100.0, *, rotating_earth: bool = False,
                   site=None) -> BoostTrajectory:
    """Fly `vehicle` through its powered flight and sample it at `rate` Hz.

    Parameters
    ----------
    vehicle : Vehicle, optional
        Stages, mass, pitch programme, optional yaw manoeuvre.
    rate : float, optional
        Sample rate, Hz (samples at ``k / rate`` from lift-off to the last burnout).
    rotating_earth : bool, optional
        Earth turning at ``omega_E`` (module notes): the vehicle starts with the pad's velocity,
        drag and attitude use the velocity relative to the co-rotating air. Needs `site`.
    site : casep.frames.LaunchSite, optional
        Launch point and azimuth; its ``t0`` must be 0 (the simulated time is from lift-off).

    Returns
    -------
    BoostTrajectory
    """
    from scipy.integrate import solve_ivp  # here, not at import: the CLI and separate() never need it

    if not isinstance(vehicle, Vehicle):
        raise TypeError(f"`vehicle` must be a Vehicle, got {type(vehicle).__name__}")
    if not np.isfinite(rate) or rate <= 0:
        raise ValueError(f"`rate` must be finite and > 0 Hz, got {rate}")
    earth = None
    if rotating_earth:
        from casep.frames import LaunchSite

        if not isinstance(site, LaunchSite):
            raise ValueError("`rotating_earth` needs `site`, a casep.frames.LaunchSite (launch point and azimuth)")
        if site.t0 != 0.0:
            raise ValueError(f"`site.t0` must be 0 for a simulated flight (its time is from lift-off), got {site.t0}")
        earth = RotatingEarth(site)
    elif site is not None:
        raise ValueError("`site` is used only with `rotating_earth=True`")
    cuts, events = _cuts(vehicle)
    check_propellant(vehicle)
    t_out = sample_times(cuts, rate)
    x = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, vehicle.liftoff_mass])
    if earth is not None:
        x[3:6] = earth.air_velocity(np.zeros(3))  # on the pad: the Earth's rotation velocity there
    state: dict[str, Any] = {"aoa0": 0.0, "earth": earth}
    p = vehicle.pitch
    t_kick_end = p.vertical + p.kick
    states = np.empty((t_out.size, 7))  # the integrated state (position, velocity, mass) at the sample times
    segments = []
    dropped: set[int] = set()
    for t0, t1, k, kind in cuts:
        stage = vehicle.stages[k]
        for j in range(k + (kind == "coast")):
            if j not in dropped:  # separation: the spent stage's dry mass goes at its burnout
                x[6] -= vehicle.stages[j].dry_mass
                dropped.add(j)
        if abs(t0 - t_kick_end) < 1e-12:
            v = air_relative(state, x[0:3], x[3:6])
            theta_kick = 0.5 * math.pi - math.radians(p.kick_rate) * p.kick
            state["aoa0"] = theta_kick - math.atan2(v[1], v[0])

        def rhs(t, y, stage=stage, kind=kind, t0=t0, t1=t1):
            f, grav, mdot = _forces(vehicle, stage, kind, t, t0, t1, y, state)
            return np.concatenate([y[3:6], f + grav, [mdot]])

        sol = solve_ivp(rhs, (t0, t1), x, method="DOP853", rtol=1e-10, atol=1e-8, dense_output=True)
        if not sol.success:  # pragma: no cover - DOP853 on a smooth piece
            raise RuntimeError(f"trajectory integration failed on [{t0}, {t1}] s: {sol.message}")
        segments.append((t0, t1, sol.sol, k, kind))
        idx = _piece_samples(t_out, t0, t1, last=cuts[-1][1] == t1)
        states[idx] = sol.sol(np.minimum(t_out[idx], t1)).T
        x = sol.y[:, -1].copy()
    return sampled_trajectory(vehicle, rate, states, state["aoa0"], earth=earth, segments=segments)


def _cuts(vehicle: Vehicle) -> tuple[list[tuple[float, float, int, str]], dict]:
    """The pieces of the flight, integrated one by one: the thrust profile's (ignition, burn, tail-off,
    coast), cut further at the end of the kick (the attitude law switches there) and at the knots of the
    attitude offsets (kinks); and the events, name -> time (s)."""
    pieces, events = thrust_profile(vehicle)
    splits = [vehicle.pitch.vertical + vehicle.pitch.kick] + (list(vehicle.attitude.times)
                                                              if vehicle.attitude is not None else [])
    cuts = []
    for t0, t1, k, kind in pieces:
        inner = sorted({s for s in splits if t0 + 1e-9 < s < t1 - 1e-9})
        edges = [t0] + inner + [t1]
        cuts += [(a, b, k, kind) for a, b in zip(edges[:-1], edges[1:])]
    return cuts, events


def sample_times(cuts: list, rate: float) -> np.ndarray:
    """The sample times ``k / rate`` from lift-off to the end of the last piece of `cuts`, s."""
    n = int(math.floor(cuts[-1][1] * rate + 1e-9)) + 1
    return np.arange(n) / rate


def _piece_samples(t_out: np.ndarray, t0: float, t1: float, last: bool) -> np.ndarray:
    """Indices of the samples a piece [t0, t1) owns (the last piece [t0, t1])."""
    return np.flatnonzero((t_out >= t0) & ((t_out < t1) | (last & (t_out <= t1 + 1e-9))))


def sampled_trajectory(vehicle: Vehicle, rate: float, states: np.ndarray, aoa0: float, *,
                       earth: RotatingEarth | None = None, segments: list | None = None) -> BoostTrajectory:
    """The :class:`BoostTrajectory` of `vehicle` at `rate` Hz from its integrated state at the sample times.

    `states` (N, 7): position (m), velocity (m/s) and mass (kg) at ``k / rate``; `aoa0`: the angle of attack
    at the end of the kick (rad). The specific force, acceleration, attitude and body rate are computed from
    them piece by piece (:func:`_sampled`), as :func:`simulate_boost` does: a trajectory built from the
    states :func:`simulate_boost` integrated is the same trajectory. `segments`: the pieces' dense output
    (without it, :meth:`BoostTrajectory.sample` and :meth:`~BoostTrajectory.kinematics` refuse times
    between the samples).
    """
    cuts, events = _cuts(vehicle)
    t_out = sample_times(cuts, rate)
    if states.shape != (t_out.size, 7):
        raise ValueError(f"`states` must be ({t_out.size}, 7) for this vehicle at {rate:g} Hz, got {states.shape}")
    n = t_out.size
    state: dict[str, Any] = {"aoa0": aoa0, "earth": earth}
    f_out, acc, att, body_rate = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3))
    for t0, t1, k, kind in cuts:
        idx = _piece_samples(t_out, t0, t1, last=cuts[-1][1] == t1)
        got = _sampled(vehicle, vehicle.stages[k], kind, t_out[idx], t0, t1, states[idx].T, state)
        f_out[idx], acc[idx], att[idx], body_rate[idx] = (got["specific_force"], got["acceleration"],
                                                          got["attitude"], got["body_rate"])
    pos, vel, mass = states[:, 0:3].copy(), states[:, 3:6].copy(), states[:, 6].copy()
    r = pos + np.array([0.0, R_EARTH, 0.0]) if earth is None else pos - earth.centres(t_out)
    alt = np.linalg.norm(r, axis=1) - R_EARTH
    out = BoostTrajectory(t=t_out, position=pos, velocity=vel, specific_force=f_out, mass=mass, altitude=alt,
                          events=events, vehicle=vehicle, acceleration=acc, attitude=att, body_rate=body_rate,
                          _segments=[] if segments is None else segments, _aoa0=aoa0, _earth=earth)
    if not (np.all(np.isfinite(f_out)) and np.all(np.isfinite(pos))):  # pragma: no cover
        raise RuntimeError("trajectory produced non-finite values")
    return out

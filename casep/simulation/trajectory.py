"""Boost-phase point-mass (3-DOF) trajectory in the launch-inertial frame.

Assumptions (every one is a choice, stated here and in docs/guide/simulation.md):

- **Frame**: launch-inertial, origin at the launch point; x downrange (horizontal at
  launch), y up (local vertical at launch), z cross-range, right-handed. The Earth does
  not rotate in this frame (launch-site velocity and Coriolis terms are left out: they
  change the trajectory, not the error-separation problem).
- **Earth**: sphere of radius ``R_E = 6 371 000`` m, centre at ``(0, -R_E, 0)``;
  inverse-square gravity ``g = -mu r / |r|^3`` with ``mu = 3.986004418e14`` m^3/s^2;
  altitude ``h = |r| - R_E``.
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
  at ``(0, -R_E, 0)`` and circles the axis), so gravity and altitude follow the rotating sphere. The
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
from dataclasses import asdict, dataclass, field

import numpy as np

from casep.units import G0

__all__ = ["body_to_platform", "Stage", "Vehicle", "PitchProgramme", "YawManoeuvre", "AttitudeProfile",
           "BoostTrajectory", "simulate_boost", "atmosphere", "DEFAULT_VEHICLE", "MU_EARTH", "R_EARTH"]

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


@dataclass(frozen=True)
class Stage:
    """One stage. Thrust N, Isp s, burn s (ignition ramp to end of tail-off), dry mass kg
    dropped at burnout, ramps s, coast s after burnout (before the next ignition)."""

    thrust: float
    isp: float
    burn: float
    dry_mass: float
    ignition: float = 0.5
    tail_off: float = 2.0
    coast: float = 0.0


@dataclass(frozen=True)
class PitchProgramme:
    """Vertical rise (s), pitch-over kick rate (deg/s) and length (s), AoA decay (s)."""

    vertical: float = 8.0
    kick_rate: float = 1.0
    kick: float = 6.0
    tau: float = 6.0


@dataclass(frozen=True)
class YawManoeuvre:
    """``psi(t) = offset + amplitude sin(2 pi (t - start) / period)`` (deg), the sine for start <= t <= end.

    ``offset`` (deg, whole flight): a flight azimuth off the platform's x axis, so the trajectory has
    a cross-range component.
    """

    amplitude: float = 2.0
    period: float = 80.0
    start: float = 20.0
    end: float = 180.0
    offset: float = 0.0


@dataclass(frozen=True)
class AttitudeProfile:
    """Piecewise-linear attitude offsets added to the pitch and yaw laws (a designed manoeuvre).

    ``times`` (s, strictly increasing), ``pitch`` and ``yaw`` (deg, one per knot): the offset at t
    is the linear interpolation of the knots, the first (last) knot's value before (after) them.

    ``base_times`` (s) and ``base_pitch`` (rad), optional: the nominal pitch programme flown open loop
    from the first knot on (a cubic spline through these samples, typically the nominal flight's
    attitude), instead of the gravity-turn law that follows the velocity. With it the flown pitch is
    exactly base + offset; without it the offset is added to the law, whose feedback on the velocity
    then turns the flight further.
    """

    times: tuple[float, ...]
    pitch: tuple[float, ...]
    yaw: tuple[float, ...]
    base_times: tuple[float, ...] | None = None
    base_pitch: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        t = np.asarray(self.times, dtype=float)
        if t.ndim != 1 or t.size < 2 or not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
            raise ValueError(f"`times` must be two or more finite, strictly increasing knot times, got {self.times!r}")
        for name in ("pitch", "yaw"):
            v = np.asarray(getattr(self, name), dtype=float)
            if v.shape != t.shape or not np.all(np.isfinite(v)):
                raise ValueError(f"`{name}` must be {t.size} finite offsets (deg), got {getattr(self, name)!r}")
        object.__setattr__(self, "times", tuple(float(x) for x in t))
        object.__setattr__(self, "pitch", tuple(float(x) for x in self.pitch))
        object.__setattr__(self, "yaw", tuple(float(x) for x in self.yaw))
        if (self.base_times is None) != (self.base_pitch is None):
            raise ValueError("`base_times` and `base_pitch` go together")
        if self.base_times is not None:
            bt, bp = np.asarray(self.base_times, dtype=float), np.asarray(self.base_pitch, dtype=float)
            if bt.ndim != 1 or bt.size < 4 or np.any(np.diff(bt) <= 0) or bp.shape != bt.shape \
                    or not (np.all(np.isfinite(bt)) and np.all(np.isfinite(bp))):
                raise ValueError("`base_times` (strictly increasing, 4 or more) and `base_pitch` (rad) must be "
                                 "finite and of one length")
            if bt[0] > t[0] or bt[-1] < t[-1]:
                raise ValueError(f"`base_times` must cover the knots [{t[0]:g}, {t[-1]:g}] s")
            object.__setattr__(self, "base_times", tuple(float(x) for x in bt))
            object.__setattr__(self, "base_pitch", tuple(float(x) for x in bp))

    def base(self, t: float) -> tuple[float, float] | None:
        """Open-loop nominal pitch (rad) and its rate (rad/s) at `t`, or None (law flown) before the
        first knot or without a base programme."""
        if self.base_times is None or t < self.times[0]:
            return None
        spline = self.__dict__.get("_spline")
        if spline is None:
            from scipy.interpolate import CubicSpline

            spline = CubicSpline(self.base_times, self.base_pitch)
            object.__setattr__(self, "_spline", spline)
        tc = min(t, self.base_times[-1])
        return float(spline(tc)), float(spline(tc, 1)) if t <= self.base_times[-1] else 0.0

    def offsets(self, t: float) -> tuple[float, float, float, float]:
        """Pitch and yaw offsets (rad) at `t` and their rates (rad/s; the slope of the segment, 0 outside)."""
        times = self.times
        if t <= times[0] or t >= times[-1]:
            k = 0 if t <= times[0] else -1
            return math.radians(self.pitch[k]), math.radians(self.yaw[k]), 0.0, 0.0
        i = int(np.searchsorted(times, t, side="right")) - 1
        h = times[i + 1] - times[i]
        u = (t - times[i]) / h
        dp, dy = self.pitch[i + 1] - self.pitch[i], self.yaw[i + 1] - self.yaw[i]
        return (math.radians(self.pitch[i] + u * dp), math.radians(self.yaw[i] + u * dy),
                math.radians(dp / h), math.radians(dy / h))


@dataclass(frozen=True)
class Vehicle:
    """Lift-off mass kg (all stages and payload), reference area m^2, stages in order."""

    liftoff_mass: float
    area: float
    stages: tuple[Stage, ...]
    pitch: PitchProgramme = field(default_factory=PitchProgramme)
    yaw: YawManoeuvre | None = None
    attitude: AttitudeProfile | None = None

    def __post_init__(self) -> None:
        if not self.stages:
            raise ValueError("`stages` is empty")
        for k, s in enumerate(self.stages):
            for name in ("thrust", "isp", "burn"):
                v = getattr(s, name)
                if not np.isfinite(v) or v <= 0:
                    raise ValueError(f"stage {k + 1} `{name}` must be finite and > 0, got {v}")
            if s.ignition + s.tail_off > s.burn:
                raise ValueError(f"stage {k + 1}: `ignition` + `tail_off` exceed `burn`")
        if self.liftoff_mass <= sum(s.dry_mass for s in self.stages):
            raise ValueError("`liftoff_mass` must exceed the sum of the stages' dry masses")

    def to_dict(self) -> dict:
        """Plain-dict form for the truth sidecar."""
        return asdict(self)


#: Two-stage vehicle of the built-in scenarios (measured with ``simulate_boost``, 100 Hz):
#: 1.78 g at lift-off, 5.24 g before stage-1 tail-off (98 s), 5-s coast, 5.0 g before stage-2
#: tail-off;
#: 195 s powered flight; burnout 4.13 km/s at 195 km altitude, flight-path angle 25 deg.
DEFAULT_VEHICLE = Vehicle(
    liftoff_mass=40_000.0,
    area=2.0,
    stages=(
        Stage(thrust=700_000.0, isp=265.0, burn=100.0, dry_mass=3_100.0, ignition=0.0, tail_off=2.0, coast=5.0),
        Stage(thrust=200_000.0, isp=290.0, burn=90.0, dry_mass=0.0, ignition=0.5, tail_off=2.0, coast=0.0),
    ),
    pitch=PitchProgramme(vertical=8.0, kick_rate=1.6, kick=8.0, tau=6.0),
)


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
    _earth: object = field(repr=False, compare=False, default=None)  # _RotatingEarth, or None: not rotating

    @property
    def site(self):
        """The :class:`casep.frames.LaunchSite` of a rotating-Earth trajectory, else None."""
        return None if self._earth is None else self._earth.site

    def sample(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """True position and velocity at arbitrary `times` within the flight (dense output)."""
        times = np.asarray(times, dtype=float)
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

    def kinematics(self, times: np.ndarray) -> dict[str, np.ndarray]:
        """True state at arbitrary `times` within the flight (dense output, exact attitude law).

        Returns ``{"position", "velocity", "acceleration", "attitude", "body_rate"}``, each
        (M, 3), in the units of the class attributes.
        """
        times = np.atleast_1d(np.asarray(times, dtype=float))
        out = {k: np.full((times.size, 3), np.nan) for k in ("position", "velocity", "acceleration",
                                                               "attitude", "body_rate")}
        state = {"aoa0": self._aoa0, "earth": self._earth}
        done = np.zeros(times.size, dtype=bool)
        last_t1 = self._segments[-1][1]
        for t0, t1, sol, k, kind in self._segments:  # a piece owns [t0, t1), the last one [t0, t1]
            idx = np.flatnonzero((times >= t0) & ((times < t1) | ((t1 == last_t1) & (times <= t1))) & ~done)
            for i in idx:
                y = sol(times[i])
                f, grav, _ = _forces(self.vehicle, self.vehicle.stages[k], kind, times[i], t0, t1, y, state)
                rows = dict(zip(out, (y[0:3], y[3:6], f + grav)))
                rows["attitude"], rows["body_rate"] = _attitude_rates(
                    self.vehicle, times[i], *_relative(state, y[0:3], y[3:6], f + grav), state)
                for key, value in rows.items():
                    out[key][i] = value
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


def _thrust_profile(vehicle: Vehicle):
    """Piecewise thrust schedule: list of (t_start, t_end, stage index, kind)."""
    pieces, events, t = [], {}, 0.0
    for k, s in enumerate(vehicle.stages):
        n = k + 1
        events[f"stage{n}_ignition"] = t
        t_full, t_tail, t_end = t + s.ignition, t + s.burn - s.tail_off, t + s.burn
        if s.ignition > 0:
            pieces.append((t, t_full, k, "ramp_up"))
        pieces.append((t_full, t_tail, k, "full"))
        if s.tail_off > 0:
            pieces.append((t_tail, t_end, k, "tail_off"))
        events[f"stage{n}_burnout"] = t_end
        if s.coast > 0 and k + 1 < len(vehicle.stages):
            pieces.append((t_end, t_end + s.coast, k, "coast"))
            t = t_end + s.coast
        else:
            t = t_end
    return pieces, events


def _thrust(stage: Stage, kind: str, t: float, t0: float, t1: float) -> float:
    if kind == "full":
        return stage.thrust
    if kind == "ramp_up":
        return stage.thrust * (t - t0) / (t1 - t0)
    if kind == "tail_off":
        return stage.thrust * (t1 - t) / (t1 - t0)
    return 0.0


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


def _attitude_rates(vehicle: Vehicle, t: float, v: np.ndarray, a: np.ndarray, state: dict
                    ) -> tuple[np.ndarray, np.ndarray]:
    """(pitch, yaw, roll = 0) in rad and the body rate omega_b (rad/s, body frame)."""
    theta, psi, theta_dot, psi_dot = _angles(vehicle, t, v, a, state)
    # omega_p = theta_dot e_z - psi_dot Rz(theta) e_y  (C = Rz(theta) Ry(-psi))
    omega_p = np.array([psi_dot * math.sin(theta), -psi_dot * math.cos(theta), theta_dot])
    ct, st, cp, sp = math.cos(theta), math.sin(theta), math.cos(psi), math.sin(psi)
    # C = Rz(theta) Ry(-psi) (roll 0) written out: body_to_platform's product for one sample, without
    # numpy's per-call overhead (19 501 samples: 2.5 s -> 0.1 s)
    C = np.array([[ct * cp, -st, -ct * sp], [st * cp, ct, -st * sp], [sp, 0.0, cp]])
    return np.array([theta, psi, 0.0]), C.T @ omega_p  # omega_b = C^T omega_p


def _attitude(vehicle: Vehicle, t: float, v: np.ndarray, state: dict) -> np.ndarray:
    theta, psi, _, _ = _angles(vehicle, t, v, None, state)
    cp = math.cos(psi)
    return np.array([cp * math.cos(theta), cp * math.sin(theta), math.sin(psi)])


class _RotatingEarth:
    """The simulator's sphere turning rigidly with the Earth, in launch-inertial coordinates (module notes)."""

    def __init__(self, site) -> None:
        from casep.frames import OMEGA_EARTH

        self.site = site
        self.w = site.earth_rate  # rad/s, launch axes: C^T (0, 0, omega_E)
        self.o = site.earth_centre  # WGS84 centre, a point of the axis, m
        self.k = self.w / OMEGA_EARTH  # unit vector of the axis
        self.omega = OMEGA_EARTH
        self.c0 = np.array([0.0, -R_EARTH, 0.0])  # the sphere's centre at lift-off (t = 0)

    def rotate(self, p: np.ndarray, t: float) -> np.ndarray:
        """`p` (about the axis point) turned by omega_E t about the axis (Rodrigues)."""
        a = self.omega * t
        k = self.k
        return p * math.cos(a) + np.cross(k, p) * math.sin(a) + k * (k @ p) * (1.0 - math.cos(a))

    def centre(self, t: float) -> np.ndarray:
        return self.o + self.rotate(self.c0 - self.o, t)  # the sphere's centre circles the axis

    def air_velocity(self, pos: np.ndarray) -> np.ndarray:
        return np.cross(self.w, pos - self.o)  # co-rotating atmosphere: w x (r - o)


def _relative(state: dict, pos: np.ndarray, vel: np.ndarray, acc: np.ndarray | None = None):
    """Velocity (and its rate) relative to the air: v - w x (r - o), a - w x v; the inertial ones without rotation."""
    earth = state.get("earth")
    if earth is None:
        return vel, acc
    return vel - earth.air_velocity(pos), (None if acc is None else acc - np.cross(earth.w, vel))


def _forces(vehicle, stage, kind, t, t0, t1, x, state):
    """Specific force (m/s^2, sensed), gravity (m/s^2) and mass flow (kg/s)."""
    pos, vel, m = x[0:3], x[3:6], x[6]
    earth = state.get("earth")
    r = pos + np.array([0.0, R_EARTH, 0.0]) if earth is None else pos - earth.centre(t)
    rn = math.sqrt(r @ r)
    grav = -MU_EARTH * r / rn**3
    h = rn - R_EARTH
    rho, a = atmosphere(h)
    vel = _relative(state, pos, vel)[0]  # relative to the (co-rotating) air
    speed = math.sqrt(vel @ vel)
    ca = float(np.interp(speed / a, _MACH, _CA))
    drag = 0.5 * rho * speed**2 * vehicle.area * ca  # axial drag, N
    T = _thrust(stage, kind, t, t0, t1)
    e_b = _attitude(vehicle, t, vel, state)
    f = (T - drag) / m * e_b  # f = (T - D) e_b / m: gravity is not sensed
    return f, grav, -T / (stage.isp * G0)


def _check_propellant(vehicle: Vehicle) -> None:
    """Refuse a vehicle that burns more propellant than it carries (mass -> 0: the integration would
    fail or crawl). Stage k burns ``thrust (burn - ignition/2 - tail_off/2) / (Isp g0)`` kg (the
    trapezoid thrust profile); at its burnout the mass must still exceed the dry masses on board."""
    m = vehicle.liftoff_mass
    for k, st in enumerate(vehicle.stages):
        burned = st.thrust * (st.burn - 0.5 * st.ignition - 0.5 * st.tail_off) / (st.isp * G0)
        dry = sum(s_.dry_mass for s_ in vehicle.stages[k:])
        if m - burned <= dry:
            raise ValueError(f"stage {k + 1} burns {burned:.0f} kg of propellant but carries {m - dry:.0f} kg (thrust "
                             f"{st.thrust:.4g} N, Isp {st.isp:.4g} s, burn {st.burn:.4g} s): not a flyable vehicle")
        m -= burned + st.dry_mass


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
        earth = _RotatingEarth(site)
    elif site is not None:
        raise ValueError("`site` is used only with `rotating_earth=True`")
    pieces, events = _thrust_profile(vehicle)
    _check_propellant(vehicle)
    t_final = pieces[-1][1]
    n = int(math.floor(t_final * rate + 1e-9)) + 1
    t_out = np.arange(n) / rate
    x = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, vehicle.liftoff_mass])
    if earth is not None:
        x[3:6] = earth.air_velocity(np.zeros(3))  # on the pad: the Earth's rotation velocity there
    state = {"aoa0": 0.0, "earth": earth}
    p = vehicle.pitch
    t_kick_end = p.vertical + p.kick
    pos, vel, f_out, mass = (np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3)), np.empty(n))
    acc, att, rate = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3))
    segments = []
    # Split pieces further at the end of the kick (attitude law switches there) and at the knots of
    # the attitude offsets (kinks).
    splits = [t_kick_end] + (list(vehicle.attitude.times) if vehicle.attitude is not None else [])
    cuts = []
    for t0, t1, k, kind in pieces:
        inner = sorted({s for s in splits if t0 + 1e-9 < s < t1 - 1e-9})
        edges = [t0] + inner + [t1]
        cuts += [(a, b, k, kind) for a, b in zip(edges[:-1], edges[1:])]
    dropped: set[int] = set()
    for t0, t1, k, kind in cuts:
        stage = vehicle.stages[k]
        for j in range(k + (kind == "coast")):
            if j not in dropped:  # separation: the spent stage's dry mass goes at its burnout
                x[6] -= vehicle.stages[j].dry_mass
                dropped.add(j)
        if abs(t0 - t_kick_end) < 1e-12:
            v = _relative(state, x[0:3], x[3:6])[0]
            theta_kick = 0.5 * math.pi - math.radians(p.kick_rate) * p.kick
            state["aoa0"] = theta_kick - math.atan2(v[1], v[0])

        def rhs(t, y, stage=stage, kind=kind, t0=t0, t1=t1):
            f, grav, mdot = _forces(vehicle, stage, kind, t, t0, t1, y, state)
            return np.concatenate([y[3:6], f + grav, [mdot]])

        sol = solve_ivp(rhs, (t0, t1), x, method="DOP853", rtol=1e-10, atol=1e-8, dense_output=True)
        if not sol.success:  # pragma: no cover - DOP853 on a smooth piece
            raise RuntimeError(f"trajectory integration failed on [{t0}, {t1}] s: {sol.message}")
        segments.append((t0, t1, sol.sol, k, kind))
        last = cuts[-1][1] == t1
        sel = (t_out >= t0) & ((t_out < t1) | (last & (t_out <= t1 + 1e-9)))
        idx = np.flatnonzero(sel)
        ys = sol.sol(np.minimum(t_out[idx], t1))
        for i, y in zip(idx, ys.T):
            f_out[i], grav, _ = _forces(vehicle, stage, kind, t_out[i], t0, t1, y, state)
            acc[i] = f_out[i] + grav  # kinematic acceleration = specific force + gravity
            att[i], rate[i] = _attitude_rates(vehicle, t_out[i], *_relative(state, y[0:3], y[3:6], acc[i]), state)
        pos[idx], vel[idx], mass[idx] = ys[0:3].T, ys[3:6].T, ys[6]
        x = sol.y[:, -1].copy()
    r = pos + np.array([0.0, R_EARTH, 0.0]) if earth is None else pos - np.array([earth.centre(t) for t in t_out])
    alt = np.linalg.norm(r, axis=1) - R_EARTH
    out = BoostTrajectory(t=t_out, position=pos, velocity=vel, specific_force=f_out, mass=mass, altitude=alt,
                          events=events, vehicle=vehicle, acceleration=acc, attitude=att, body_rate=rate,
                          _segments=segments, _aoa0=state["aoa0"], _earth=earth)
    if not (np.all(np.isfinite(f_out)) and np.all(np.isfinite(pos))):  # pragma: no cover
        raise RuntimeError("trajectory produced non-finite values")
    return out

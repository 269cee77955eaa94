"""The simulated vehicle: stages, pitch programme, yaw manoeuvre, designed attitude offsets, the
built-in two-stage vehicle, and its thrust schedule (the assumptions: :mod:`casep.simulation.trajectory`).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

from casep.units import G0

__all__ = ["Stage", "PitchProgramme", "YawManoeuvre", "AttitudeProfile", "Vehicle", "DEFAULT_VEHICLE",
           "thrust_profile", "thrust", "thrust_many", "check_propellant"]


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

    #: Vertical rise after lift-off, s.
    vertical: float = 8.0
    #: Pitch rate of the kick, deg/s.
    kick_rate: float = 1.0
    #: Length of the kick, s.
    kick: float = 6.0
    #: Time constant of the decay of the kick's angle of attack in the gravity turn, s.
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


    def base_many(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`base` at many times `t` (M,): where it applies (bool), pitch (rad) and rate (rad/s) there
        (NaN elsewhere)."""
        t = np.asarray(t, dtype=float)
        on = np.zeros(t.shape, dtype=bool) if self.base_times is None else t >= self.times[0]
        theta, rate = np.full(t.shape, np.nan), np.full(t.shape, np.nan)
        if np.any(on):
            self.base(float(t[on][0]))  # builds the spline
            spline = self.__dict__["_spline"]
            assert self.base_times is not None
            tc = np.minimum(t[on], self.base_times[-1])
            theta[on] = spline(tc)
            rate[on] = np.where(t[on] <= self.base_times[-1], spline(tc, 1), 0.0)
        return on, theta, rate

    def offsets_many(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`offsets` at many times `t` (M,): pitch and yaw offsets (rad) and their rates (rad/s), (M,) each."""
        t = np.asarray(t, dtype=float)
        times, pitch, yaw = np.asarray(self.times), np.radians(self.pitch), np.radians(self.yaw)
        out = t <= times[0]
        after = t >= times[-1]
        i = np.clip(np.searchsorted(times, t, side="right") - 1, 0, times.size - 2)
        h = times[i + 1] - times[i]
        u = (t - times[i]) / h
        dp, dy = np.diff(self.pitch)[i], np.diff(self.yaw)[i]
        p = np.radians(np.asarray(self.pitch)[i] + u * dp)
        y = np.radians(np.asarray(self.yaw)[i] + u * dy)
        p_dot, y_dot = np.radians(dp / h), np.radians(dy / h)
        for mask, k in ((out, 0), (after, -1)):  # held at the first (last) knot's value, rate 0
            p[mask], y[mask], p_dot[mask], y_dot[mask] = pitch[k], yaw[k], 0.0, 0.0
        return p, y, p_dot, y_dot


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


def thrust_profile(vehicle: Vehicle):
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


def thrust(stage: Stage, kind: str, t: float, t0: float, t1: float) -> float:
    """Thrust (N) of `stage` at `t` in a piece [t0, t1] of the schedule of kind `kind` (:func:`thrust_profile`)."""
    if kind == "full":
        return stage.thrust
    if kind == "ramp_up":
        return stage.thrust * (t - t0) / (t1 - t0)
    if kind == "tail_off":
        return stage.thrust * (t1 - t) / (t1 - t0)
    return 0.0


def thrust_many(stage: Stage, kind: str, t: np.ndarray, t0: float, t1: float) -> np.ndarray:
    """:func:`thrust` at many times `t` (M,) of one piece, N."""
    t = np.asarray(t, dtype=float)
    if kind == "full":
        return np.full(t.shape, stage.thrust)
    if kind == "ramp_up":
        return stage.thrust * (t - t0) / (t1 - t0)
    if kind == "tail_off":
        return stage.thrust * (t1 - t) / (t1 - t0)
    return np.zeros(t.shape)


def check_propellant(vehicle: Vehicle) -> None:
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

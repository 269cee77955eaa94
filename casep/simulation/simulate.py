"""Simulated flights with injected instrument errors and tracking noise.

``dv = S_V(t) D_true + n(t)``: the model's S_V on the sampled specific force times the true
coefficients, plus tracking noise from the scenario's :class:`~casep.simulation.noise.NoiseModel`;
in the gap windows there is no tracking: the flight keeps every telemetry sample (t, f and the
telemetry signals), with dv and the tracked ``r_*, v_*`` NaN and ``observed`` False there, as a
telemetry + tracking pair has them (the instrument errors keep accumulating through a gap, and S_V is
integrated from lift-off even when tracking starts later).
For two-rate data, telemetry velocity is ``v_tel = v_true + S_V D_true`` at telemetry times
and tracking is ``v_trk(t_k) = v_true(t_k - offset) + n(t_k)`` at its own times.

Every simulated flight carries, beside ``t, f_*, dv_*``, the columns of ``docs/reference/file-formats.md``
(0.2) that model files may use as signals (:data:`SIGNAL_COLUMNS`): ``a_*`` the true
kinematic acceleration (specific force + gravity, m/s^2) at t; ``r_*`` and ``v_*`` the tracked
position and velocity (launch-inertial frame, m and m/s) with ``v_tel = v_* + dv`` exactly;
``att_pitch, att_yaw, att_roll`` the attitude (rad, body-to-platform ``C = Rz(pitch) Ry(-yaw)
Rx(roll)``, roll 0 in this 3-DOF simulation) and ``omega_x, omega_y, omega_z`` the body rate
(rad/s, body frame), both true at t. Tracking may be given a time offset ``dt`` (its time tags
late: ``v_trk(t) = v_point(t - dt)``, exact, not linearised) and a lever arm ``l`` (the tracked
point at ``C l`` from the platform, body frame: ``r_point = r + C l``,
``v_point = v + C (omega_b x l)``). Before lift-off the vehicle is at rest on the pad; after
burnout it is extrapolated ballistically (constant gravity), for offsets of a few ms.

Rotating Earth (``rotating_earth=True, site=LaunchSite(..., t0=0)``, see
:mod:`casep.simulation.trajectory`): everything above stays launch-inertial (``r_*, v_*`` include
the Earth's rotation velocity); :meth:`TwoRateData.write` can write the tracking file in ECEF or
geodetic coordinates instead (``tracking_frame``), which ``read_flight_pair(tracking_frame=...,
site=...)`` turns back.

All randomness comes from ``numpy.random.default_rng(seed)``: the same seed gives the same
bytes, another seed other noise.
"""

from __future__ import annotations

import dataclasses
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from casep._kernels import cumulative_trapezoid
from casep.io._atomic import atomic_open
from casep.io.files import simulated_comment, write_flight, write_table
from casep.io.flight import FlightData
from casep.io.pair import STATE_SIGNALS
from casep.model.error_model import ErrorModel, unknown_coefficient_message
from casep.model.loader import load_model
from casep.model.strapdown import BODY_FORCE_COLUMNS, BODY_RATE_COLUMNS, QUATERNION_COLUMNS
from casep.model.sv import build_sv
from casep.simulation.scenarios import Scenario, get_scenario
from casep.simulation.strapdown import SensorNoise, rolled, strapdown_signals
from casep.simulation.trajectory import BoostTrajectory, body_to_platform, simulate_boost

if TYPE_CHECKING:
    from casep.frames import LaunchSite

__all__ = ["SIGNAL_COLUMNS", "trajectory_signals", "sv_inputs", "with_roll", "SimulatedFlight", "simulate_flight",
           "scenario_setup",
           "write_simulation", "truth_path", "TwoRateData", "simulate_two_rate", "truth_vector", "check_seed"]


#: Signal columns of every simulated flight: name -> unit (see the module notes).
SIGNAL_COLUMNS = {**{f"a_{a}": "m/s^2" for a in "xyz"}, **{f"r_{a}": "m" for a in "xyz"},
                  **{f"v_{a}": "m/s" for a in "xyz"}, "att_pitch": "rad", "att_yaw": "rad", "att_roll": "rad",
                  **{f"omega_{a}": "rad/s" for a in "xyz"}}


#: Units of the strapdown telemetry columns a strapdown scenario adds (no f_*: f = C(q) fb).
STRAPDOWN_UNITS = {**{c: "1" for c in QUATERNION_COLUMNS}, **{c: "m/s^2" for c in BODY_FORCE_COLUMNS},
                   **{c: "rad/s" for c in BODY_RATE_COLUMNS}}


def sampled_kinematics(traj: BoostTrajectory) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Kinematic acceleration, attitude and body rate of `traj` at its sample times (what
    :func:`~casep.simulation.trajectory.simulate_boost` records); ValueError for a trajectory without them."""
    if traj.acceleration is None or traj.attitude is None or traj.body_rate is None:
        raise ValueError("the trajectory has no acceleration, attitude or body rate: fly it with simulate_boost")
    return traj.acceleration, traj.attitude, traj.body_rate


def _tracked_point(traj: BoostTrajectory, times: np.ndarray, lever: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Position and velocity of the tracked point (lever arm `lever`, m, body frame) at `times`."""
    t0, t1 = traj.t[0], traj.t[-1]
    inside = (times >= t0) & (times <= t1)
    pos, vel = np.zeros((times.size, 3)), np.zeros((times.size, 3))  # before lift-off: at rest on the pad
    att, rate = np.zeros((times.size, 3)), np.zeros((times.size, 3))
    acceleration, attitude, body_rate = sampled_kinematics(traj)
    att[:, 0] = attitude[0, 0]
    if np.array_equal(times, traj.t):  # the sample times: no dense-output evaluation needed
        pos, vel, att, rate = traj.position.copy(), traj.velocity.copy(), attitude, body_rate
    elif inside.any():
        k = traj.kinematics(times[inside])
        pos[inside], vel[inside], att[inside], rate[inside] = (k["position"], k["velocity"], k["attitude"],
                                                                k["body_rate"])
    early = times < t0
    earth = traj.earth
    if early.any() and earth is not None:  # rotating Earth: on the pad, turning with the Earth
        pos[early], vel[early] = earth.pad(times[early])
    late = times > t1
    if late.any():  # after burnout: ballistic, r + v dt + g dt^2 / 2 with gravity g at burnout
        g = acceleration[-1] - traj.specific_force[-1]
        d = (times[late] - t1)[:, None]
        pos[late] = traj.position[-1] + traj.velocity[-1] * d + 0.5 * g * d**2
        vel[late] = traj.velocity[-1] + g * d
        att[late], rate[late] = attitude[-1], body_rate[-1]
    if np.any(lever):
        C = body_to_platform(att[:, 0], att[:, 1], att[:, 2])
        pos = pos + C @ lever  # r_point = r + C l
        vel = vel + np.einsum("kij,kj->ki", C, np.cross(rate, lever))  # v_point = v + C (omega_b x l)
    return pos, vel


def trajectory_signals(traj: BoostTrajectory, *, time_offset: float = 0.0,
                       lever_arm: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """The :data:`SIGNAL_COLUMNS` of a trajectory, noise-free, at its sample times.

    Parameters
    ----------
    traj : BoostTrajectory
    time_offset : float, optional
        Tracking time tags late by this much, s: ``r_*, v_*`` are the tracked point's at t - offset.
    lever_arm : (3,) array_like, optional
        Tracked point from the platform, m, body frame.
    """
    lever = np.zeros(3) if lever_arm is None else np.asarray(lever_arm, dtype=float)
    pos, vel = _tracked_point(traj, traj.t - time_offset, lever)
    acceleration, attitude, body_rate = sampled_kinematics(traj)
    cols = {}
    for prefix, arr in (("a", acceleration), ("r", pos), ("v", vel)):
        cols.update({f"{prefix}_{a}": arr[:, i] for i, a in enumerate("xyz")})
    cols.update(att_pitch=attitude[:, 0], att_yaw=attitude[:, 1], att_roll=attitude[:, 2])
    cols.update({f"omega_{a}": body_rate[:, i] for i, a in enumerate("xyz")})
    return cols


def _check_tracking(time_offset: float, lever_arm) -> tuple[float, np.ndarray]:
    if isinstance(time_offset, bool) or not isinstance(time_offset, (int, float)) or not np.isfinite(time_offset) \
            or abs(time_offset) > 1.0:
        raise ValueError(f"`time_offset` must be a finite number of seconds within +-1 s (--tracking-offset "
                         f"within +-1000 ms), got {time_offset!r} s")
    lever = np.zeros(3) if lever_arm is None else np.asarray(lever_arm, dtype=float)
    if lever.shape != (3,) or not np.all(np.isfinite(lever)):
        raise ValueError(f"`lever_arm` must be 3 finite numbers (m, body frame), got {lever_arm!r}")
    return float(time_offset), lever


@dataclass(frozen=True)
class SimulatedFlight:
    """A simulated flight with everything needed to check an estimate against the truth."""

    flight: FlightData
    trajectory: BoostTrajectory
    model: ErrorModel
    truth: np.ndarray  # natural units, model order
    noise: np.ndarray  # the tracking noise, (N, 3) m/s at every sample; dv holds it where observed
    scenario: Scenario
    seed: int
    tracking: dict = dataclasses.field(default_factory=dict)  # injected time offset (ms), lever arm (m)

    def truth_dict(self) -> dict:
        """The ``<name>.truth.json`` sidecar of ``docs/reference/file-formats.md``."""
        return {
            "model": self.model.name,
            "coefficients": {n: float(v) for n, v in zip(self.model.names, self.truth)},
            "units": dict(zip(self.model.names, self.model.units)),
            "noise": self.scenario.noise.to_dict(),
            "trajectory": {"scenario": self.scenario.name, "description": self.scenario.description,
                           "rate_hz": self.scenario.rate, "vehicle": self.scenario.vehicle.to_dict(),
                           "summary": self.trajectory.summary()},
            "seed": self.seed,
            "tracking": {"time_offset_ms": 0.0, "lever_arm_m": [0.0, 0.0, 0.0], **self.tracking},
            "signals": {**SIGNAL_COLUMNS, **(STRAPDOWN_UNITS if self.scenario.strapdown else {})},
            **({"roll_programme": self.scenario.roll.to_dict()} if self.scenario.roll is not None else {}),
        }


def truth_vector(model: ErrorModel, truth: dict, source: str = "truth") -> np.ndarray:
    """True coefficients in model order, natural units, from ``{name: value}`` (missing names: 0).

    Raises ValueError naming `source` for a name the model lacks (with a "did you mean") or a value
    that is not a finite number.
    """
    for name in truth:
        if name not in model.names:
            raise ValueError(unknown_coefficient_message(name, model.names, f"{source} (model `{model.name}`)"))
    values = np.array([truth.get(n, 0.0) for n in model.names], dtype=object)
    for n, v in zip(model.names, values):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
            raise ValueError(f"{source}: `{n}` must be a finite number (natural units), got {v!r}")
    return values.astype(float)




def scenario_setup(scenario: str | Scenario, rate: float | None = None, *, rotating_earth: bool = False,
                   site=None, trajectory: BoostTrajectory | None = None
                   ) -> tuple[Scenario, BoostTrajectory, ErrorModel, np.ndarray]:
    """The noise-free part of a scenario: scenario at `rate`, trajectory, model, true coefficients.

    `rotating_earth`, `site`: :func:`~casep.simulation.trajectory.simulate_boost`'s rotating-Earth option.
    `trajectory`: the scenario's vehicle flown at `rate` already (non-rotating Earth; e.g.
    :func:`casep.simulation.stored.stored_trajectory`), used instead of flying it again.
    """
    sc = get_scenario(scenario).with_rate(rate)
    model = load_model(sc.model)
    if trajectory is None:
        trajectory = simulate_boost(sc.vehicle, sc.rate, rotating_earth=rotating_earth, site=site)
    elif (trajectory.vehicle != sc.vehicle or trajectory.t.size < 2 or trajectory.t[1] != 1.0 / sc.rate
          or rotating_earth or site is not None):
        raise ValueError(f"`trajectory` is not scenario `{sc.name}`'s vehicle flown at {sc.rate:g} Hz over a "
                         "non-rotating Earth")
    traj = with_roll(sc, trajectory)
    return sc, traj, model, truth_vector(model, sc.truth)


def with_roll(sc: Scenario, traj: BoostTrajectory) -> BoostTrajectory:
    """`traj` flown with the scenario's roll programme (a strapdown scenario), else `traj` itself."""
    return traj if sc.roll is None else rolled(traj, sc.roll)


def sv_inputs(sc: Scenario, traj: BoostTrajectory, model: ErrorModel, truth: np.ndarray,
              signals: dict[str, np.ndarray] | None = None) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The specific force and signal columns S_V of a scenario's flight is built on.

    A platform scenario: the trajectory's specific force and :func:`trajectory_signals` (or `signals`). A
    strapdown one: ``f = C(q) fb`` and the strapdown columns beside them, the IMU's body errors at `truth`
    (:func:`casep.simulation.strapdown.strapdown_signals`).
    """
    sig = trajectory_signals(traj) if signals is None else signals
    if sc.roll is None:
        return traj.specific_force, sig
    force, columns = strapdown_signals(traj, model, truth)
    return force, {**sig, **columns}


def check_seed(seed: int) -> int:
    """`seed` as an int, or ValueError: a seed is a non-negative int (not a bool)."""
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"`seed` must be a non-negative int, got {seed!r}")
    return int(seed)


def simulate_flight(scenario: str | Scenario = "paper", *, seed: int = 0, rate: float | None = None,
                    model: str | os.PathLike | None = None, truth: dict | None = None,
                    time_offset: float = 0.0, lever_arm: np.ndarray | None = None, rotating_earth: bool = False,
                    site=None, trajectory: BoostTrajectory | None = None,
                    tracking_rate: float | None = None) -> SimulatedFlight:
    """Simulate one flight of a scenario.

    Parameters
    ----------
    scenario : str or Scenario, optional
        ``"paper"``, ``"paper-pitch"``, ``"paper-ar1"`` or a :class:`Scenario`.
    seed : int, optional
        Seed of the noise generator.
    rate : float, optional
        Sample rate, Hz (default: the scenario's).
    model : str or path, optional
        Error model to inject instead of the scenario's (name or model file).
    truth : dict, optional
        ``{name: value}`` true coefficients in natural units instead of the scenario's
        (coefficients not named are 0; required in practice with another `model`, whose
        names the scenario's truth need not share).
    time_offset : float, optional
        Tracking time tags late by this much, s: ``v_trk(t) = v_point(t - offset)`` (exact).
    lever_arm : (3,) array_like, optional
        Tracked point from the platform, m, body frame.
    rotating_earth, site : optional
        Rotating Earth at the launch site (:func:`~casep.simulation.trajectory.simulate_boost`).
    trajectory : BoostTrajectory, optional
        The scenario's vehicle flown at `rate` already, used instead of flying it again
        (:func:`casep.simulation.stored.stored_trajectory`: the demo's; one without dense output takes no
        `time_offset` or `lever_arm`).
    tracking_rate : float, optional
        Tracking rate, Hz, dividing the flight's `rate` (:func:`tracking_step`): the tracking (dv and the tracked
        state ``r_*``, ``v_*``) at every ``rate / tracking_rate``-th sample from the first, the others untracked
        (a GNSS receiver slower than the IMU of a strapdown flight); default every sample.

    Returns
    -------
    SimulatedFlight
    """
    seed = check_seed(seed)
    sc = get_scenario(scenario)
    if model is not None or truth is not None:
        sc = dataclasses.replace(sc, model=sc.model if model is None else os.fspath(model),
                                 truth=sc.truth if truth is None else dict(truth))
    time_offset, lever = _check_tracking(time_offset, lever_arm)
    every = tracking_step(sc.with_rate(rate).rate, tracking_rate)  # before the flight is flown
    if model is not None and truth is None:  # the scenario's truth is for its own model: say so when it does not fit
        names = load_model(sc.model).names
        other = [n for n in sc.truth if n not in names]
        if other:
            raise ValueError(f"no truth given: scenario `{get_scenario(scenario).name}`'s default truth is for model "
                             f"`{get_scenario(scenario).model}` and names {', '.join(other[:5])}"
                             f"{' ...' if len(other) > 5 else ''}, which model `{sc.model}` lacks: give the true "
                             "coefficients of this model (--truth FILE, truth=)")
    sc, traj, error_model, true_D = scenario_setup(sc, rate, rotating_earth=rotating_earth, site=site,
                                                   trajectory=trajectory)
    rng = np.random.default_rng(seed)
    if sc.roll is not None and time_offset and np.any(lever):  # the rolled attitude is known at the samples only
        raise ValueError("a strapdown scenario takes a tracking time offset or a lever arm, not both")
    # strapdown: q_*, measured fb_* and w_*; f = C(q) fb as the file's reader computes it
    force, sig = sv_inputs(sc, traj, error_model, true_D, trajectory_signals(traj, time_offset=time_offset,
                                                                             lever_arm=lever))
    tracked = np.column_stack([sig[f"v_{a}"] for a in "xyz"])
    # dv = v_tel - v_trk = (v + S_V D) - (v_point(t - dt) - n) = S_V D + (v - v_point(t - dt)) + n
    clean = build_sv(error_model, traj.t, force, signals=sig) @ true_D + (traj.velocity - tracked)
    noise = sc.noise.sample(traj.t, rng)
    # every telemetry sample stays (S_V integrates from lift-off, across the gaps); tracking exists outside the
    # gap windows only: dv and the tracked state r_*, v_* are NaN inside them, as a telemetry + tracking pair has them
    keep = sc.noise.keep_mask(traj.t) & (np.arange(traj.t.size) % every == 0)
    dv = np.where(keep[:, None], clean + noise, np.nan)
    for i, a in enumerate("xyz"):
        sig[f"v_{a}"] = tracked[:, i] - noise[:, i]  # tracked velocity as measured: v_tel = v_* + dv
    for name in STATE_SIGNALS:
        sig[name] = np.where(keep, sig[name], np.nan)
    meta = {"scenario": sc.name, "seed": seed, **({"unobserved": int((~keep).sum())} if not keep.all() else {})}
    if sc.roll is not None:
        meta["force"] = "q, fb"  # as read back: the file has no f_*
    flight = FlightData(traj.t, force, dv, source=f"simulated:{sc.name}:seed{seed}", meta=meta,
                        observed=keep, signals=sig)
    return SimulatedFlight(flight=flight, trajectory=traj, model=error_model, truth=true_D, noise=noise,
                           scenario=sc, seed=seed,
                           tracking={"time_offset_ms": time_offset * 1e3, "lever_arm_m": lever.tolist(),
                                     **({} if tracking_rate is None else {"rate_hz": sc.rate / every}),
                                     **({"rotating_earth": True, "launch_site": traj.site.to_dict()}
                                        if traj.site is not None else {})})


def tracking_step(rate: float, tracking_rate: float | None) -> int:
    """Every how many samples of a flight at `rate` (Hz) its tracking at `tracking_rate` (Hz) is: ``rate /
    tracking_rate``, a whole number (to 1e-9 relative), or ValueError; 1 when `tracking_rate` is None."""
    if tracking_rate is None:
        return 1
    if isinstance(tracking_rate, bool) or not isinstance(tracking_rate, (int, float, np.integer, np.floating)) \
            or not np.isfinite(tracking_rate) or tracking_rate <= 0:
        raise ValueError(f"`tracking_rate` must be a finite number of Hz > 0, got {tracking_rate!r}")
    k = round(rate / tracking_rate)
    if k < 1 or abs(k * tracking_rate - rate) > 1e-9 * rate:
        raise ValueError(f"the tracking rate {tracking_rate:g} Hz must divide the flight's rate {rate:g} Hz (the "
                         f"tracking is every k-th sample): {rate:g} / k Hz, e.g. "
                         + ", ".join(f"{rate / j:g}" for j in (1, 2, 5, 10) if rate / j >= 1.0))
    return k


def truth_path(path: str | os.PathLike) -> Path:
    """Sidecar path: ``flight.csv`` -> ``flight.truth.json``."""
    path = Path(path)
    return path.with_name(path.stem + ".truth.json")


def write_simulation(sim: SimulatedFlight, path: str | os.PathLike, *, imu: str | os.PathLike | None = None,
                     imu_pad: float = 0.0, imu_sensor: SensorNoise | None = None) -> tuple[Path, Path]:
    """Write the flight file (CSV or Parquet by extension) and its truth sidecar.

    `imu`: a strapdown flight's raw IMU file too (:func:`casep.simulation.strapdown.imu_table`), with
    `imu_pad` s on the pad before lift-off and `imu_sensor` its white noise and full scales
    (:class:`casep.simulation.strapdown.SensorNoise`; None: noise-free). Everything is checked before the first
    file is written.
    """
    path = Path(path)
    sc = sim.scenario
    imu_columns = None
    if imu is not None:
        if not sc.strapdown:
            raise ValueError(f"--imu-output needs a strapdown scenario (strapdown-boost); `{sc.name}` is a platform "
                             "flight")
        from casep.simulation.strapdown import imu_table

        imu_columns = imu_table(sim.trajectory, sim.model, sim.truth, pad=imu_pad, sensor=imu_sensor)
    write_flight(sim.flight, path, force=not sc.strapdown, comments=[
        f"casep simulated flight: scenario {sc.name} ({sc.description})",
        simulated_comment(sim.model.name, sim.seed, 1.0 / float(np.median(np.diff(sim.flight.t)))),
    ])
    if imu_columns is not None:
        assert imu is not None
        write_table(imu, imu_columns, comments=[
            f"casep simulated raw IMU: scenario {sc.name}, model {sim.model.name}, seed {sim.seed}",
            "w_* body rate rad/s and fb_* body specific force m/s^2 as measured; true_q_* (Hamilton, scalar first, "
            "body to launch-inertial), true_r_* m, true_v_* m/s: the truth",
            "noise-free (the model's errors only)" if imu_sensor is None else imu_sensor.comment()])
    side = truth_path(path)
    with atomic_open(side) as fh:
        fh.write(json.dumps(sim.truth_dict(), indent=2) + "\n")
    return path, side


@dataclass(frozen=True)
class TwoRateData:
    """Telemetry and tracking of one simulated flight at their own rates."""

    t_tel: np.ndarray
    f: np.ndarray  # specific force at telemetry times, m/s^2
    W: np.ndarray  # accumulated apparent velocity (trapezoid of f), m/s
    v_tel: np.ndarray
    t_trk: np.ndarray
    v_trk: np.ndarray
    truth: np.ndarray
    model: ErrorModel
    acceleration: np.ndarray | None = None  # kinematic acceleration at telemetry times, m/s^2
    r_trk: np.ndarray | None = None  # tracked position, launch-inertial, m (noise-free)
    site: LaunchSite | None = None  # the launch site of a rotating-Earth flight, else None

    def write(self, telemetry: str | os.PathLike, tracking: str | os.PathLike, *, apparent: bool = False,
              tracking_frame: str = "launch") -> None:
        """Telemetry file (``t``, ``f_*`` or ``W_*``, ``v_tel_*``, ``a_*``) and tracking file.

        The tracking file is ``t, v_trk_*`` (launch-inertial, ``tracking_frame="launch"``), or
        ``t, r_ecef_*, v_ecef_*`` (``"ecef"``) or ``t, lat, lon, h, v_east, v_north, v_up``
        (``"geodetic"``) converted by :mod:`casep.frames` with the flight's launch site (a
        rotating-Earth flight; its ``t0`` is 0: lift-off).
        """
        from casep.frames import ECEF_COLUMNS, GEODETIC_COLUMNS, TRACKING_FRAMES, ecef_to_geodetic, launch_to_ecef

        if tracking_frame not in TRACKING_FRAMES:
            raise ValueError(f"`tracking_frame` must be one of {', '.join(TRACKING_FRAMES)}, got {tracking_frame!r}")
        if tracking_frame != "launch" and (self.site is None or self.r_trk is None):
            raise ValueError(f"{tracking_frame} tracking needs a rotating-Earth flight (simulate_two_rate("
                             "rotating_earth=True, site=LaunchSite(...))): the launch site ties the frames")
        cols = {"t": self.t_tel}
        src, prefix = (self.W, "W") if apparent else (self.f, "f")
        cols.update({f"{prefix}_{a}": src[:, i] for i, a in enumerate("xyz")})
        cols.update({f"v_tel_{a}": self.v_tel[:, i] for i, a in enumerate("xyz")})
        if self.acceleration is not None:  # a signal for time-offset models (platform36_timeoffset)
            cols.update({f"a_{a}": self.acceleration[:, i] for i, a in enumerate("xyz")})
        write_table(telemetry, cols)
        if tracking_frame == "launch":
            write_table(tracking, {"t": self.t_trk, **{f"v_trk_{a}": self.v_trk[:, i] for i, a in enumerate("xyz")}})
            return
        site = self.site
        assert site is not None  # checked above for every frame but "launch"
        r_e, v_e = launch_to_ecef(site, self.t_trk, self.r_trk, self.v_trk)
        values = (*r_e.T, *v_e.T) if tracking_frame == "ecef" else ecef_to_geodetic(r_e, v_e)
        names = ECEF_COLUMNS if tracking_frame == "ecef" else GEODETIC_COLUMNS
        write_table(tracking, {"t": self.t_trk, **dict(zip(names[1:], values))}, comments=[
            f"casep simulated tracking, {tracking_frame} (WGS84), launch site {site.to_dict()} "
            "(t0: lift-off, t = 0)"])


def simulate_two_rate(scenario: str | Scenario = "paper", *, seed: int = 0, telemetry_rate: float = 100.0,
                      tracking_rate: float = 20.0, time_offset: float = 0.0,
                      tracking_start: float | None = None, rotating_earth: bool = False,
                      site=None) -> TwoRateData:
    """Telemetry and tracking of a scenario at different rates, with a tracking time offset.

    Parameters
    ----------
    scenario : str or Scenario
    seed : int
    telemetry_rate, tracking_rate : float
        Hz.
    time_offset : float
        Tracking time tags lag the truth by this much, s: ``v_trk(t) = v_true(t - offset)``.
    tracking_start : float, optional
        First tracking time, s (default: from lift-off): ranges rarely track from t = 0.
        Telemetry still starts at lift-off.
    rotating_earth, site : optional
        Rotating Earth at the launch site (:func:`~casep.simulation.trajectory.simulate_boost`);
        then :meth:`TwoRateData.write` can write ECEF or geodetic tracking.
    """
    seed = check_seed(seed)
    if not np.isfinite(tracking_rate) or tracking_rate <= 0:
        raise ValueError(f"`tracking_rate` must be finite and > 0 Hz, got {tracking_rate}")
    if not np.isfinite(time_offset):
        raise ValueError(f"`time_offset` must be finite, got {time_offset}")
    sc, traj, model, truth = scenario_setup(scenario, telemetry_rate, rotating_earth=rotating_earth, site=site)
    rng = np.random.default_rng(seed)
    v_tel = traj.velocity + build_sv(model, traj.t, traj.specific_force) @ truth
    W = cumulative_trapezoid(traj.specific_force, traj.t)
    lo, hi = max(traj.t[0], traj.t[0] + time_offset), min(traj.t[-1], traj.t[-1] + time_offset)
    if tracking_start is not None:
        if not lo <= tracking_start < hi:
            raise ValueError(f"`tracking_start` must be in [{lo:g}, {hi:g}) s, got {tracking_start}")
        lo = tracking_start
    t_trk = np.arange(np.ceil(lo * tracking_rate), np.floor(hi * tracking_rate) + 1) / tracking_rate
    r_true, v_true = traj.sample(t_trk - time_offset)
    v_trk = v_true + sc.noise.sample(t_trk, rng)
    return TwoRateData(traj.t, traj.specific_force, W, v_tel, t_trk, v_trk, truth, model, traj.acceleration,
                       r_true, traj.site)

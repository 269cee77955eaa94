"""Strapdown flights: a roll programme on the boost trajectory, body-frame IMU errors, strapdown telemetry.

The simulated vehicle's specific force is axial (thrust minus drag along the body x axis), so a roll
about that axis changes nothing in the trajectory: it is added kinematically. With the pitch-yaw
attitude ``C0 = Rz(theta) Ry(-psi)`` and its body rate ``w0`` (:mod:`casep.simulation.trajectory`),
the rolled attitude and body rate are::

    C = C0 Rx(phi),      w = Rx(phi)^T w0 + (phi_dot, 0, 0)      (C_dot = C [w x])

and the true body specific force ``fb = C^T f``. The IMU measures ``fb + delta_f`` and ``w + delta_w``,
the body-frame errors of the scenario's strapdown model at its true coefficients
(``delta_f = C^T Delta``, ``delta_w = -C^T phidot`` from the model's own outputs). The telemetry carries
the attitude ``q`` (the true one: the INS attitude error is arcseconds, far below what changes S_V),
the measured ``fb`` and ``w``, and no ``f_*``: ``f = C(q) fb`` as :func:`casep.io.read_flight` computes
it, so a flight read back from its file has exactly the S_V it was simulated with.

Raw IMU output (:func:`imu_table`): ``t, w_x, w_y, w_z, fb_x, fb_y, fb_z`` as the IMU measured them,
optionally after a stationary pad segment before lift-off (t < 0), with the truth trajectory beside
them (``true_q_*``, ``true_r_*``, ``true_v_*``; launch-inertial). A step of the truth at a sample time (lift-off
after the pad, the pitch kick's ends) is written as the mean of its sides at that sample
(:func:`casep.navigation.imu.split_steps`), which the integration takes exactly. On a rotating-Earth trajectory
the pad turns with the Earth and the whole record is what :func:`casep.navigation.navigate` reproduces (the simulator's
gravitation is the navigator's, :mod:`casep.simulation.trajectory`). By default the record is noise-free (the
model's errors only, to rounding); :class:`SensorNoise` adds the sensors' white noise (angle and velocity random
walk densities, drawn per sample) and clips the readings at declared full scales, as a real IMU's record has them.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np

from casep._kernels import cumulative_trapezoid
from casep.io.strapdown import quaternion_dcm_array
from casep.model.strapdown import BODY_FORCE_COLUMNS, BODY_RATE_COLUMNS, QUATERNION_COLUMNS
from casep.navigation.imu import split_steps
from casep.simulation.trajectory import BoostTrajectory, body_to_platform
from casep.units import G0

__all__ = ["RollProgramme", "rolled", "strapdown_signals", "imu_table", "IMU_COLUMNS", "rail_launch",
           "with_drawn_errors", "SensorNoise"]

#: The columns of a raw IMU file before the truth columns.
IMU_COLUMNS = ("t",) + BODY_RATE_COLUMNS + BODY_FORCE_COLUMNS


#: One hour's square root in seconds' (a density per sqrt(h) divided by it is per sqrt(s)).
SQRT_HOUR_S = 60.0


@dataclass(frozen=True)
class SensorNoise:
    """The raw IMU record's white sensor noise and full scales (:func:`imu_table`).

    ``arw_deg_sqrt_h``: the gyros' angle random walk, deg/sqrt(h); ``vrw_m_s_sqrt_h``: the accelerometers' velocity
    random walk, m/s/sqrt(h) (1 m/s/sqrt(h) = 1700 ug/sqrt(Hz)); 0: none. A density ``N`` per sqrt(s) sampled at
    the step ``h`` is a per-sample std ``N / sqrt(h)``, independent between samples and axes, drawn from
    ``numpy.random.default_rng(seed)``. ``gyr_range_rad_s``, ``acc_range_m_s2``: full scales (SI), the readings
    (noise included) clipped to ``+-`` them; None: not clipped."""

    arw_deg_sqrt_h: float = 0.0
    vrw_m_s_sqrt_h: float = 0.0
    seed: int = 0
    gyr_range_rad_s: float | None = None
    acc_range_m_s2: float | None = None

    def __post_init__(self) -> None:
        for name in ("arw_deg_sqrt_h", "vrw_m_s_sqrt_h"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and np.isfinite(v) and v >= 0):
                raise ValueError(f"SensorNoise `{name}` must be a finite number >= 0, got {v!r}")
        for name in ("gyr_range_rad_s", "acc_range_m_s2"):
            v = getattr(self, name)
            if v is not None and not (isinstance(v, (int, float)) and np.isfinite(v) and v > 0):
                raise ValueError(f"SensorNoise `{name}` must be None or a finite number > 0, got {v!r}")

    def per_sample(self, h: float) -> tuple[float, float]:
        """The per-sample std at step `h` (s): ``(gyro rad/s, accelerometer m/s^2)``."""
        arw = np.radians(self.arw_deg_sqrt_h) / SQRT_HOUR_S  # rad/sqrt(s)
        vrw = self.vrw_m_s_sqrt_h / SQRT_HOUR_S  # m/s/sqrt(s)
        return float(arw / np.sqrt(h)), float(vrw / np.sqrt(h))

    def apply(self, t: np.ndarray, w: np.ndarray, fb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """`w` (rad/s) and `fb` (m/s^2), (n, 3) at the times `t`, with the noise (at the median step) and clipped."""
        sw, sf = self.per_sample(float(np.median(np.diff(t))))
        rng = np.random.default_rng(self.seed)
        w = w + rng.normal(0.0, 1.0, w.shape) * sw
        fb = fb + rng.normal(0.0, 1.0, fb.shape) * sf
        if self.gyr_range_rad_s is not None:
            w = np.clip(w, -self.gyr_range_rad_s, self.gyr_range_rad_s)
        if self.acc_range_m_s2 is not None:
            fb = np.clip(fb, -self.acc_range_m_s2, self.acc_range_m_s2)
        return w, fb

    def comment(self) -> str:
        """The raw IMU file's header line saying what was added."""
        ranges = [f"{lab} +-{v:.6g} {u}" for lab, v, u in (
            ("gyros", None if self.gyr_range_rad_s is None else np.degrees(self.gyr_range_rad_s), "deg/s"),
            ("accelerometers", None if self.acc_range_m_s2 is None else self.acc_range_m_s2 / G0, "g"))
            if v is not None]
        return (f"sensor white noise: angle random walk {self.arw_deg_sqrt_h:g} deg/sqrt(h), velocity random walk "
                f"{self.vrw_m_s_sqrt_h:g} m/s/sqrt(h) (seed {self.seed}); full scale: "
                + (", ".join(ranges) if ranges else "none (not clipped)"))


@dataclass(frozen=True)
class RollProgramme:
    """Roll rate piecewise linear through knots: ``times`` (s, increasing), ``rates`` (deg/s); 0 outside.

    The roll angle is its exact integral (piecewise quadratic), 0 at the first knot.
    """

    times: tuple[float, ...] = (10.0, 15.0, 80.0, 90.0, 150.0, 160.0)
    rates: tuple[float, ...] = (0.0, 60.0, 60.0, 120.0, 120.0, 0.0)

    def __post_init__(self) -> None:
        t, r = np.asarray(self.times, dtype=float), np.asarray(self.rates, dtype=float)
        if t.ndim != 1 or t.size < 2 or np.any(np.diff(t) <= 0) or r.shape != t.shape \
                or not np.all(np.isfinite(t)) or not np.all(np.isfinite(r)):
            raise ValueError("`times` (s, strictly increasing, 2 or more) and `rates` (deg/s, one per knot) must "
                             "be finite and of one length")

    def angle_rate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Roll angle (rad) and rate (rad/s) at times `t`."""
        t = np.asarray(t, dtype=float)
        kt, kr = np.asarray(self.times), np.radians(self.rates)
        at_knot = cumulative_trapezoid(kr, kt)
        i = np.clip(np.searchsorted(kt, t, side="right") - 1, 0, kt.size - 2)
        u = np.clip(t - kt[i], 0.0, None)
        slope = (kr[i + 1] - kr[i]) / (kt[i + 1] - kt[i])
        inside = (t >= kt[0]) & (t <= kt[-1])
        rate = np.where(inside, kr[i] + slope * u, 0.0)
        angle = np.where(t < kt[0], 0.0, np.where(t > kt[-1], at_knot[-1] + kr[-1] * (t - kt[-1]),
                                                    at_knot[i] + kr[i] * u + 0.5 * slope * u**2))
        return angle, rate

    def to_dict(self) -> dict:
        """Plain-dict form for the truth sidecar."""
        return {"times_s": list(self.times), "rates_deg_s": list(self.rates)}


def rolled(traj: BoostTrajectory, roll: RollProgramme) -> BoostTrajectory:
    """`traj` with the roll programme in its attitude (third column, rad) and body rate (module notes)."""
    if traj.attitude is None or traj.body_rate is None:
        raise ValueError("the trajectory has no attitude or body rate: fly it with simulate_boost")
    phi, phi_dot = roll.angle_rate(traj.t)
    c, s = np.cos(phi), np.sin(phi)
    w0 = traj.body_rate
    w = np.column_stack([w0[:, 0] + phi_dot, c * w0[:, 1] + s * w0[:, 2], -s * w0[:, 1] + c * w0[:, 2]])
    att = traj.attitude.copy()
    att[:, 2] = phi
    return dataclasses.replace(traj, attitude=att, body_rate=w)


def _body_errors(model: Any, q: np.ndarray, fb: np.ndarray, w: np.ndarray, t: np.ndarray,
                 truth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Body-frame ``delta_f = C^T Delta`` and ``delta_w = -C^T phidot`` (``C = C(q)``) of `model` at `truth`
    (natural units), time counted from ``t[0]``: :func:`casep.model.strapdown.body_errors`, after checking that the
    model uses no column a strapdown simulation does not make."""
    from casep.model.strapdown import body_errors

    missing = [c for c in model.signals if c not in QUATERNION_COLUMNS + BODY_FORCE_COLUMNS + BODY_RATE_COLUMNS]
    if missing:
        raise ValueError(f"model `{model.name}` uses column(s) {', '.join(missing)} that a strapdown simulation "
                         "does not make: inject a strapdown model (strapdown12, strapdown33)")
    return body_errors(model, q, fb, w, t - t[0], truth)


def strapdown_signals(traj: BoostTrajectory, model: Any, truth: np.ndarray) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Strapdown telemetry of a (rolled) trajectory with the body errors of `model` at `truth`.

    Returns
    -------
    f : (N, 3) ndarray
        ``C(q) fb_measured``, m/s^2: the navigation-frame specific force the file's reader computes.
    columns : dict
        ``q_*`` (true attitude, scalar first, body to navigation), ``fb_*`` and ``w_*`` as measured.
    """
    from scipy.spatial.transform import Rotation

    att = traj.attitude
    assert att is not None and traj.body_rate is not None
    C = body_to_platform(att[:, 0], att[:, 1], att[:, 2])
    q = Rotation.from_matrix(C).as_quat(scalar_first=True)
    q *= np.where(q[:, :1] < 0, -1.0, 1.0)  # w >= 0 (either sign is the attitude)
    fb = np.einsum("kji,kj->ki", C, traj.specific_force)  # fb = C^T f
    w = traj.body_rate
    df, dw = _body_errors(model, q, fb, w, traj.t, truth)
    fb_m, w_m = fb + df, w + dw
    cols = {**dict(zip(QUATERNION_COLUMNS, q.T)), **dict(zip(BODY_FORCE_COLUMNS, fb_m.T)),
            **dict(zip(BODY_RATE_COLUMNS, w_m.T))}
    return np.einsum("kij,kj->ki", C, fb_m), {k: np.ascontiguousarray(v) for k, v in cols.items()}


def imu_table(traj: BoostTrajectory, model: Any, truth: np.ndarray, *, pad: float = 0.0,
              sensor: SensorNoise | None = None) -> dict[str, np.ndarray]:
    """The raw IMU file's columns (module notes), with `pad` s standing on the pad before lift-off, and with
    `sensor` the sensors' white noise and full scales (:class:`SensorNoise`; None: noise-free, not clipped).

    On the pad (t < 0, at the flight's median sample step) the vehicle stands at its lift-off attitude,
    measured with the model's errors there. Over a non-rotating Earth it is at rest in the launch frame:
    ``fb = C0^T (-g)``, g the gravity at lift-off, ``w = 0``. On a rotating-Earth trajectory it turns with the
    Earth (``traj.earth``): attitude ``C(t) = R(omega_E t) C0``, position and velocity those of the launch
    point, ``w = C^T w_E`` (the Earth rate) and ``fb = C^T (w_E x v - G)`` (the reaction to WGS84 normal
    gravity, ``G`` the gravitation :func:`casep.navigation.navigate` integrates), so that the record, pad and
    flight, is what the navigator reproduces. Truth: ``true_q_*`` (scalar first, body to navigation),
    ``true_r_*`` (m) and ``true_v_*`` (m/s), launch-inertial.
    """
    if not (np.isfinite(pad) and pad >= 0):
        raise ValueError(f"`pad` must be a finite number of seconds >= 0, got {pad!r}")
    _, cols = strapdown_signals(traj, model, truth)
    t, pos, vel = traj.t, traj.position, traj.velocity
    q = np.column_stack([cols[c] for c in QUATERNION_COLUMNS])
    fb, w = (np.column_stack([cols[c] for c in names]) for names in (BODY_FORCE_COLUMNS, BODY_RATE_COLUMNS))
    if pad > 0:
        step = float(np.median(np.diff(t)))
        t_pad = t[0] - step * np.arange(int(np.ceil(pad / step - 1e-9)), 0, -1)
        q_pad, w_pad, fb_pad, pos_pad, vel_pad = _on_the_pad(traj, q[0], t_pad)
        df, dw = _body_errors(model, q_pad, fb_pad, w_pad, t_pad, truth)
        t = np.concatenate([t_pad, t])
        q = np.concatenate([q_pad, q])
        fb = np.concatenate([fb_pad + df, fb])
        w = np.concatenate([w_pad + dw, w])
        pos = np.concatenate([pos_pad, pos])
        vel = np.concatenate([vel_pad, vel])
    w, fb = split_steps(t, w, fb)  # a step at a sample (lift-off, a pitch kick): the record the navigation recovers
    if sensor is not None:
        w, fb = sensor.apply(t, w, fb)
    out = {"t": t}
    out.update({c: w[:, i] for i, c in enumerate(BODY_RATE_COLUMNS)})
    out.update({c: fb[:, i] for i, c in enumerate(BODY_FORCE_COLUMNS)})
    out.update({f"true_{c}": q[:, i] for i, c in enumerate(QUATERNION_COLUMNS)})
    for i, a in enumerate("xyz"):
        out[f"true_r_{a}"] = pos[:, i]
    for i, a in enumerate("xyz"):
        out[f"true_v_{a}"] = vel[:, i]
    return out


def _on_the_pad(traj: BoostTrajectory, q0: np.ndarray, t_pad: np.ndarray) -> tuple[np.ndarray, ...]:
    """True attitude (K, 4), body rate, body specific force, position and velocity (K, 3) of the vehicle standing
    on the pad at times `t_pad` (K,) before lift-off, at its lift-off attitude `q0` (:func:`imu_table`'s notes)."""
    from casep.rotations import quat_from_rotvec, quat_multiply

    k = t_pad.size
    earth = traj.earth
    if earth is None:  # at rest in the non-rotating launch frame
        assert traj.acceleration is not None
        q_pad = np.repeat(q0[None, :], k, axis=0)
        f = np.repeat((traj.specific_force[0] - traj.acceleration[0])[None, :], k, axis=0)  # -g, g at lift-off
        pos, vel = np.repeat(traj.position[:1], k, axis=0), np.zeros((k, 3))
    else:  # turning with the Earth: the attitude turned back by omega_E t, the pad's point and velocity
        q_pad = quat_multiply(quat_from_rotvec(earth.w[None, :] * t_pad[:, None]), q0)
        pos, vel = earth.pad(t_pad)
        f = np.cross(earth.w, vel) - earth.gravity(t_pad, pos)  # f = a - G, a = w x v the centripetal acceleration
    C = quaternion_dcm_array(q_pad)
    w = np.zeros((k, 3)) if earth is None else np.einsum("kji,j->ki", C, earth.w)  # w_b = C^T w_E
    return q_pad, w, np.einsum("kji,kj->ki", C, f), pos, vel


def rail_launch(site: Any, t: np.ndarray, *, elevation_deg: float, boost_g: float, burn_s: float, coast_g: float,
                lateral: tuple[float, float] = (0.0, 0.0), roll: tuple[float, float] = (2.0, 5.0),
                pitch_rate: float = -0.03, yaw: tuple[float, float] = (0.01, 0.3)) -> tuple[np.ndarray, np.ndarray]:
    """True body rate and specific force ``(w, f)``, (N, 3) each, of a rail launch: a raw IMU record's truth.

    Body x lies along the rail, elevated `elevation_deg` above the horizontal in the launch triad's x-y plane
    (x downrange at the site's azimuth, y up). Until lift-off (``site.t0``) the IMU stands still: ``w`` is the
    Earth's rate and ``f`` the reaction to normal gravity, both in body axes. From lift-off, ``u = t - t0``:
    ``f = (g0 boost_g`` for ``u < burn_s`` else ``g0 coast_g, lateral[0] sin(lateral[1] u), 0)`` and
    ``w = (roll[0] min(u / roll[1], 1), pitch_rate, yaw[0] sin(yaw[1] u))`` (rad/s). Navigating it
    (:func:`casep.navigation.navigate`) gives the flight that the examples, tests and benchmarks perturb. Lift-off and
    burn-out fall on samples, which read the value after them: a step between samples
    (:func:`casep.navigation.imu.sample_steps`), whose ambiguity ``casep separate --imu`` carries in the std;
    :func:`casep.navigation.imu.split_steps` of the record takes it away where the truth is its own navigation.
    """
    import math

    from casep.gravity import normal_gravity_ecef
    from casep.units import G0

    el = math.radians(elevation_deg)
    x, y = np.array([math.cos(el), math.sin(el), 0.0]), np.array([-math.sin(el), math.cos(el), 0.0])
    C_tb = np.column_stack([x, y, np.cross(x, y)])  # body -> launch triad: x along the rail
    w = np.tile(C_tb.T @ site.earth_rate, (t.size, 1))
    f = np.tile(C_tb.T @ -(site.C.T @ normal_gravity_ecef(site.r_site)), (t.size, 1))
    u = t[t >= site.t0] - site.t0
    side = lateral[0] * np.sin(lateral[1] * u) if lateral[0] else 0 * u
    f[t >= site.t0] = np.column_stack([np.where(u < burn_s, boost_g * G0, coast_g * G0), side, 0 * u])
    w[t >= site.t0] = np.column_stack([roll[0] * np.minimum(u / roll[1], 1.0), pitch_rate + 0 * u,
                                       yaw[0] * np.sin(yaw[1] * u)])
    return w, f


def with_drawn_errors(model: Any, q: np.ndarray, w: np.ndarray, fb: np.ndarray, t: np.ndarray,
                      rng: np.random.Generator, *, z: np.ndarray | None = None
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A raw IMU record measured with the body-frame errors of `model` drawn at their declared magnitudes.

    The coefficients are ``z * scales`` (natural units, the model's declared magnitudes), ``z`` a standard normal
    draw of one number per coefficient, in the model's order, taken from `rng` before anything else (so that a
    seeded generator gives the same coefficients, and the draws after them, as drawing them by hand). The errors
    are :func:`casep.model.strapdown.body_errors` at the true attitude, rate and specific force.

    Parameters
    ----------
    model : ErrorModel
        A strapdown model (its IMU errors use ``q_*``, ``fb_*``, ``w_*`` only), set up.
    q : (N, 4) ndarray
        True attitude, Hamilton, scalar first, body to navigation (a navigation's ``q``).
    w, fb : (N, 3) ndarray
        True body rate (rad/s) and specific force (m/s^2).
    t : (N,) ndarray
        Sample times, s; the errors' time is counted from ``t[0]``.
    rng : numpy.random.Generator
        Draws ``z``; later draws (tracking noise) continue from it.
    z : (n,) ndarray, optional
        The coefficients in declared magnitudes, given instead of drawn (`rng` then untouched).

    Returns
    -------
    w_measured, fb_measured : (N, 3) ndarray
        ``w + delta_w`` and ``fb + delta_f``.
    z : (n,) ndarray
        The coefficients in declared magnitudes (the truth a separation is scored against).
    """
    if z is None:
        z = rng.standard_normal(len(model.names))
    z = np.asarray(z, dtype=float)
    if z.shape != (len(model.names),):
        raise ValueError(f"`z` must hold one number per coefficient of `{model.name}` ({len(model.names)}), "
                         f"got shape {z.shape}")
    scales = np.array([model.scales[n] for n in model.names])
    df, dw = _body_errors(model, q, fb, w, np.asarray(t, dtype=float), z * scales)
    return w + dw, fb + df, z

"""A sounding-rocket flight with the problems real raw logs have: the raw IMU and the GNSS receiver's file.

What :func:`simulate_rocket` makes (all seeded, a 60 s flight at 800 Hz in well under a second):

- **the truth**: body rate and specific force chosen in body axes (on the pad at rest on the rotating
  Earth; a boost along the body x axis with a cosine tail-off, a roll ramp, a slow pitch-over, a
  tumble about body y after apogee), and the trajectory they imply, integrated by
  :func:`casep.navigation.navigate` from the pad with the true heading: the truth is what a perfect
  IMU navigates to, so the telemetry minus the truth is the instrument errors' effect alone;
- **the raw IMU** (``t, w_x..w_z, fb_x..fb_z``) at ``rate`` Hz with biases and scale factors per
  body axis (strapdown12's coefficients, in its units) and white noise; packets lost (one gap at
  burnout, others at random); the gyro clipped at its full scale ``gyr_range_dps`` once the tumble
  passes it; time tags on the flight computer's clock, which runs ``clock_ppm`` fast against GPS
  time (``t_imu = t0 + (t - t0)(1 + clock_ppm 1e-6)``, the launch time ``t0`` common to both);
- **the GNSS file** in ECEF (``t, r_ecef_*, v_ecef_*``, GPS time) at ``gps_rate`` Hz: white noise on
  the pad; lock lost ``lock_lost_s`` after lift-off, the last fix repeated (identical numbers) for
  ``stale_s``; then ``wrong_s`` of fresh-looking wrong epochs (a speed of ``wrong_speed`` m/s, the
  position crawling from the last fix); then reacquired: the solution ``gps_lag_s`` late, updated
  once every ``gps_step_s`` and repeated in between, with Gauss-Markov errors (``gps_gm_std`` m/s,
  ``gps_gm_tau`` s) and white noise.

:class:`RocketFlight` holds the two tables, the truth and every event with its time, so that a test
can compare what a tool masks and says with what was done.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from casep.frames import LaunchSite
from casep.units import G0

__all__ = ["RocketSpec", "RocketFlight", "simulate_rocket", "ROCKET_SITE", "QUICK_ROCKET", "HEADING_AXIS"]

#: A northern rocket range (lat, lon, h, launch azimuth, launch time in GPS seconds of the week).
ROCKET_SITE = LaunchSite(67.89, 21.1, 330.0, 30.0, 300000.0)


@dataclass(frozen=True)
class RocketSpec:
    """The flight and its faults (module notes); times from lift-off, s."""

    rate: float = 800.0
    pad_s: float = 20.0
    flight_s: float = 55.0
    burn_s: float = 4.0
    tail_off_s: float = 0.3
    thrust_g: float = 10.0
    elevation_deg: float = 85.0
    roll_dps: float = 180.0
    pitch_dps: float = -0.4
    tumble_start_s: float = 45.0
    tumble_dps: float = 2600.0
    gyr_range_dps: float = 2000.0
    gaps: int = 6
    burnout_gap_s: float = 0.075
    heading_error_deg: float = 0.2
    acc_bias_mg: float = 3.0
    acc_scale_ppm: float = 1000.0
    gyr_bias_dph: float = 30.0
    gyr_scale_ppm: float = 1000.0
    acc_noise: float = 0.01
    gyr_noise: float = 2e-4
    clock_ppm: float = 104.0
    gps_rate: float = 10.0
    gps_pad_noise: float = 0.03
    lock_lost_s: float = 0.5
    stale_s: float = 26.0
    wrong_s: float = 1.0
    wrong_speed: float = 2.0
    gps_lag_s: float = 0.4
    gps_step_s: float = 1.0
    gps_gm_std: float = 3.0
    gps_gm_tau: float = 5.0
    gps_white: float = 0.1


@dataclass
class RocketFlight:
    """A simulated rocket flight (module notes).

    Attributes
    ----------
    imu, gps : dict of str -> ndarray
        The raw IMU file's and the ECEF GNSS file's columns.
    truth_t, truth_v, truth_q : ndarray
        GPS times, the true launch-inertial velocity (m/s) and attitude (scalar first, body to launch-inertial)
        there, every IMU sample of the full record.
    coefficients : dict
        The injected strapdown12 coefficients (mg, ppm, deg/h).
    events : dict
        Lift-off, burnout, the gaps (start, length), the first clipped sample, the stale, wrong and
        reacquired spans of the GNSS (GPS time, s), the heading given to the navigation (deg).
    """

    spec: RocketSpec
    site: LaunchSite
    imu: dict
    gps: dict
    truth_t: np.ndarray
    truth_v: np.ndarray
    coefficients: dict
    events: dict = field(default_factory=dict)
    truth_q: np.ndarray | None = None

    @property
    def align_window(self) -> tuple[float, float]:
        """The pad span to level over, in the IMU's time scale (s): the pad but its last second."""
        t = self.imu["t"]
        return float(t[0]), float(self.site.t0 - 1.0)

    def write(self, imu_path, gps_path) -> None:
        """Write the IMU and GNSS files (CSV or Parquet by suffix)."""
        from casep.io.files import write_table

        write_table(imu_path, self.imu)
        write_table(gps_path, self.gps)

    def navigated(self, folder) -> tuple[Any, Any]:
        """The flight navigated (gyro full scale declared, the heading given) and paired with its GNSS file
        through files in `folder`, as ``casep navigate`` and ``casep separate --tracking-frame ecef`` would:
        ``(NavigationResult, FlightData)``."""
        from pathlib import Path

        from casep.io.files import read_flight_pair, write_table
        from casep.navigation import ImuData, check_imu, navigate

        d = Path(folder)
        imu = check_imu(ImuData(self.imu["t"], np.column_stack([self.imu[f"w_{a}"] for a in "xyz"]),
                                np.column_stack([self.imu[f"fb_{a}"] for a in "xyz"])),
                        gyr_range=math.radians(self.spec.gyr_range_dps))
        nav = navigate(imu, self.site, self.align_window, heading_deg=self.events["heading_deg"],
                       heading_axis=HEADING_AXIS, check_pad=False)  # at rest by construction: its gyro bias drifts
        write_table(d / "tel.parquet", nav.columns())
        write_table(d / "gps.parquet", self.gps)
        return nav, read_flight_pair(d / "tel.parquet", d / "gps.parquet", tracking_frame="ecef", site=self.site)

    def truth(self, q0: np.ndarray) -> dict[str, float]:
        """The true coefficients of ``strapdown15_phi0`` for a navigation that started at attitude `q0`: the
        injected ones, its initial attitude error ``phi0`` (arcsec; ``I - C(q0) C_true^T = [phi0 x]`` to first
        order) and ``dt_trk`` 0 (the lift-off fixes are not lagged; the drift adds 0.04 ms)."""
        from casep.rotations import quat_to_dcm

        assert self.truth_q is not None  # simulate_rocket records it
        E = np.eye(3) - quat_to_dcm(q0) @ quat_to_dcm(self.truth_q[0]).T
        phi = np.array([E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1]]) / 2
        return {**self.coefficients, **{f"phi0_{a}": math.degrees(phi[i]) * 3600 for i, a in enumerate("xyz")},
                "dt_trk": 0.0}


def _true_imu(sp: RocketSpec, site: LaunchSite, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Body rate and specific force of the flight (module notes), and the body -> launch triad at rest."""
    from casep.gravity import normal_gravity_ecef

    e = math.radians(sp.elevation_deg)
    C_tb = np.array([[math.cos(e), -math.sin(e), 0.0], [math.sin(e), math.cos(e), 0.0], [0.0, 0.0, 1.0]])
    g_t = site.C.T @ normal_gravity_ecef(site.r_site)
    w = np.tile(C_tb.T @ site.earth_rate, (t.size, 1))
    f = np.tile(C_tb.T @ -g_t, (t.size, 1))
    fly = t >= 0
    tf = t[fly]
    u = np.clip((sp.burn_s - tf) / sp.tail_off_s, 0.0, 1.0)  # 1 until the tail-off, 0 after burnout
    thrust = 0.5 * sp.thrust_g * G0 * (1.0 - np.cos(np.pi * u))
    drag = -0.4 * np.exp(-tf / 15.0)
    f[fly] = np.column_stack([thrust + drag, 0.02 * np.sin(7.0 * tf), 0.02 * np.cos(5.0 * tf)])
    roll = np.radians(sp.roll_dps) * np.clip(tf / sp.burn_s, 0.0, 1.0)
    tumble = np.radians(sp.tumble_dps) * np.clip((tf - sp.tumble_start_s) / 3.0, 0.0, 1.0)
    w[fly] += np.column_stack([roll, tumble, np.full(tf.size, np.radians(sp.pitch_dps))])
    return w, f, C_tb


#: The body axis whose azimuth the navigation is given: z, horizontal on the pad (the x axis points almost up,
#: so the azimuth of its horizontal projection moves by degrees with a tenth of a degree of tilt).
HEADING_AXIS = "z"


def _heading(site: LaunchSite, C_tb: np.ndarray) -> float:
    """The azimuth of the body axis HEADING_AXIS's horizontal projection, deg from north."""
    x_t = C_tb[:, "xyz".index(HEADING_AXIS)]
    return (site.azimuth_deg + math.degrees(math.atan2(x_t[2], x_t[0]))) % 360.0


def _measured(sp: RocketSpec, rng: np.random.Generator, w: np.ndarray, f: np.ndarray) -> tuple:
    """The IMU's readings with strapdown12's errors (coefficients drawn, natural units) and noise, clipped."""
    c = {**{f"ba_{a}": rng.normal(0, sp.acc_bias_mg) for a in "xyz"},
         **{f"sa_{a}": rng.normal(0, sp.acc_scale_ppm) for a in "xyz"},
         **{f"bg_{a}": rng.normal(0, sp.gyr_bias_dph) for a in "xyz"},
         **{f"sg_{a}": rng.normal(0, sp.gyr_scale_ppm) for a in "xyz"}}
    ba = np.array([c[f"ba_{a}"] for a in "xyz"]) * 1e-3 * G0
    sa = np.array([c[f"sa_{a}"] for a in "xyz"]) * 1e-6
    bg = np.radians(np.array([c[f"bg_{a}"] for a in "xyz"]) / 3600.0)
    sg = np.array([c[f"sg_{a}"] for a in "xyz"]) * 1e-6
    f_m = f * (1 + sa) + ba + rng.normal(0, sp.acc_noise, f.shape)
    w_m = w * (1 + sg) + bg + rng.normal(0, sp.gyr_noise, w.shape)
    fs = math.radians(sp.gyr_range_dps)
    return np.clip(w_m, -fs, fs), f_m, c


def _lost(sp: RocketSpec, rng: np.random.Generator, t: np.ndarray) -> tuple[np.ndarray, list]:
    """Samples kept: a gap of `burnout_gap_s` across burnout, `gaps` others of 10-50 ms in flight."""
    keep = np.ones(t.size, bool)
    starts = [sp.burn_s - 0.5 * sp.burnout_gap_s] + list(rng.uniform(1.0, sp.flight_s - 2.0, sp.gaps))
    lengths = [sp.burnout_gap_s] + list(rng.uniform(0.01, 0.05, sp.gaps))
    for a, n in zip(starts, lengths):
        keep[(t > a) & (t < a + n)] = False
    return keep, sorted(zip(starts, lengths))


def simulate_rocket(seed: int = 0, spec: RocketSpec | None = None, site: LaunchSite = ROCKET_SITE) -> RocketFlight:
    """Simulate the rocket flight of the module notes with seed `seed`."""
    from casep.navigation.imu import ImuData
    from casep.navigation.navigator import navigate

    sp = spec or RocketSpec()
    rng = np.random.default_rng(seed)
    t = np.arange(-round(sp.pad_s * sp.rate), round(sp.flight_s * sp.rate) + 1) / sp.rate  # from lift-off
    w, f, C_tb = _true_imu(sp, site, t)
    heading = _heading(site, C_tb)
    true = navigate(ImuData(t + site.t0, w, f, source="truth"), site, (site.t0 + t[0], site.t0 - 1.0),
                    heading_deg=heading, heading_axis=HEADING_AXIS)
    w_m, f_m, coef = _measured(sp, rng, w, f)
    keep, gaps = _lost(sp, rng, t)
    t_imu = site.t0 + t * (1 + sp.clock_ppm * 1e-6)
    imu = {"t": t_imu[keep], **{f"w_{a}": w_m[keep, i] for i, a in enumerate("xyz")},
           **{f"fb_{a}": f_m[keep, i] for i, a in enumerate("xyz")}}
    r_e, v_e = true.earth_relative()
    gps, spans = _gps(sp, rng, t, r_e, v_e, site.t0)
    clipped = np.flatnonzero(np.any(np.abs(w_m) >= math.radians(sp.gyr_range_dps), axis=1))
    events = {"lift_off": site.t0, "burnout": site.t0 + sp.burn_s, "gaps": [(site.t0 + a, n) for a, n in gaps],
              "first_clipped": float(site.t0 + t[clipped[0]]) if clipped.size else None,
              "heading_deg": heading + sp.heading_error_deg, "true_heading_deg": heading,
              "heading_axis": HEADING_AXIS, **spans}
    return RocketFlight(sp, site, imu, gps, t + site.t0, true.v, coef, events, true.q)


def _gps(sp: RocketSpec, rng: np.random.Generator, t: np.ndarray, r_e: np.ndarray, v_e: np.ndarray,
         t0: float) -> tuple[dict, dict]:
    """The ECEF GNSS file (module notes) from the true Earth-relative state at the IMU's true times."""
    tg = np.arange(math.ceil(t[0] * sp.gps_rate), math.floor(t[-1] * sp.gps_rate) + 1) / sp.gps_rate
    stale0 = sp.lock_lost_s
    wrong0 = stale0 + sp.stale_s
    back = wrong0 + sp.wrong_s
    at = lambda tt: np.column_stack([np.interp(tt, t, x) for x in np.column_stack([r_e, v_e]).T])  # noqa: E731
    state = at(tg)
    state[:, 3:] += rng.normal(0, sp.gps_pad_noise, (tg.size, 3))
    state[:, :3] += rng.normal(0, 1.0, (tg.size, 3))
    last = np.flatnonzero(tg < stale0)[-1]
    stale = (tg >= stale0) & (tg < wrong0)
    state[stale] = state[last]
    wrong = np.flatnonzero((tg >= wrong0) & (tg < back))
    u = rng.normal(size=3)
    v_wrong = sp.wrong_speed * u / np.linalg.norm(u) + rng.normal(0, 0.1, (wrong.size, 3))
    state[wrong, 3:] = v_wrong
    state[wrong, :3] = state[last, :3] + np.cumsum(v_wrong, axis=0) / sp.gps_rate
    after = tg >= back
    k = np.floor((tg[after] - back) / sp.gps_step_s + 1e-9).astype(int)  # the solution shown: its update
    fresh = back + k * sp.gps_step_s - sp.gps_lag_s  # ... is the state gps_lag_s before it
    phi = math.exp(-sp.gps_step_s / sp.gps_gm_tau)
    n_fix = int(k[-1]) + 1
    gm = np.zeros((n_fix, 3))
    gm[0] = rng.normal(0, sp.gps_gm_std, 3)
    for j in range(1, n_fix):
        gm[j] = phi * gm[j - 1] + rng.normal(0, sp.gps_gm_std * math.sqrt(1 - phi * phi), 3)
    err = gm + rng.normal(0, sp.gps_white, (n_fix, 3))
    state[after] = at(fresh)
    state[after, 3:] += err[k]
    state[after, :3] += 3.0 * err[k]
    cols = ("r_ecef_x", "r_ecef_y", "r_ecef_z", "v_ecef_x", "v_ecef_y", "v_ecef_z")
    gps = {"t": tg + t0, **{c: state[:, i] for i, c in enumerate(cols)}}
    spans = {"stale": (t0 + float(tg[stale][0]), t0 + float(tg[stale][-1])),
             "wrong": (t0 + float(tg[wrong][0]), t0 + float(tg[wrong][-1])),
             "reacquired": t0 + float(tg[after][0]), "gps_lag_s": sp.gps_lag_s}
    return gps, spans


#: A short flight with every fault, for tests: 400 Hz, 8 s on the pad, lock lost for 8 s, the tumble at 20 s.
QUICK_ROCKET = RocketSpec(rate=400.0, pad_s=8.0, flight_s=24.0, burn_s=3.0, stale_s=8.0, tumble_start_s=20.0,
                          gaps=3)

"""A simulated twin of the real car drive: its trajectory and its noise, constant known biases.

Is the std of a window honest on this chain? The twin keeps everything of the real drive that the
windows see except what is under suspicion on the real one (a model that does not fit, biases that
move): the trajectory (the RTK positions smoothed), the IMU's own noise as measured on the drive, the
RTK epochs, their noise and their rounding, the same conversion (velocity from differenced positions)
and the same chain (:func:`casep.workflows.windows.separate_windows`); the IMU's errors are the six
constant biases of ``strapdown6_window`` and nothing else (or, with `left_out`, also constant scale factors,
misalignments and g-sensitivity: the terms the window model leaves out). If the windows of the twin agree
(chi-square near its dof), casep's std are right for this chain and a disagreement on the real drive
is the data's or the model's; if not, the std are wrong.

The truth (Earth-fixed tangent frame ENU at the first RTK epoch, ``t``):

- position: a quintic smoothing spline per axis through the RTK positions (``s = n sigma^2`` with
  the epochs' white noise ``sigma``), its velocity and acceleration its derivatives;
- attitude of the car (x forward, y left, z up): heading along the spline's velocity, pitch along its
  climb, no roll, ``C_tc = Rz(psi) Ry(-theta)`` (where the car moves slower than 1 m/s the angles are
  interpolated linearly between the moving epochs, held at the ends; then a quintic smoothing spline),
  so ``w_c = Ry(theta) (0, 0, psi') + (0, -theta', 0)``; the IMU axes are the car's turned by a fixed
  mounting (x back, z up, tilted 6.8 deg as the real IMU on the pad);
- IMU: ``w = w_tb + C_bt C_te omega_E`` and ``fb = C_bt C_te (a_e + 2 omega_E x v_e - g(r_e))`` with
  WGS84 normal gravity (gravitation plus centrifugal), ``a_e, v_e`` the ECEF acceleration and velocity.

The noise, per IMU channel: the real record above 5 Hz (the real IMU minus its zero-phase low-pass:
engine and road vibration as driven) plus white noise low-passed at 5 Hz whose density is the pad's
(its Allan deviation at 1 s). The RTK positions: white noise (``--sim-pos-white``, 3 mm, the pad's
epoch-to-epoch scatter) plus Gauss-Markov (5 mm, 10 s: the pad's slower wander) per ENU axis, rounded as
the .pos file rounds them (1e-7 deg, 1 mm).
"""

from __future__ import annotations

import math
import os

import numpy as np

#: The real IMU's mounting in the car (x forward, y left, z up): x back, y right, z up, tilted about y
#: by the pad's mean specific force (atan(1.157 / 9.861) = 6.7 deg).
MOUNT_TILT_RAD = math.atan2(1.157, 9.861)
#: The biases of the twin: the real windows' weighted means (mg) and the pad's gyro rates (deg/h, about).
TRUE_BIASES = {"ba_x": -4.8, "ba_y": 2.3, "ba_z": 13.7, "bg_x": 120.0, "bg_y": -250.0, "bg_z": 610.0}
#: Below this speed (m/s) the car's heading and pitch are not taken from its velocity.
MOVING = 1.0
#: The IMU noise is split at this frequency, Hz.
SPLIT_HZ = 5.0


def _rot_z(a: np.ndarray) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    z, o = np.zeros_like(a), np.ones_like(a)
    return np.stack([np.stack([c, -s, z], -1), np.stack([s, c, z], -1), np.stack([z, z, o], -1)], -2)


def _rot_y(a: np.ndarray) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    z, o = np.zeros_like(a), np.ones_like(a)
    return np.stack([np.stack([c, z, s], -1), np.stack([z, o, z], -1), np.stack([-s, z, c], -1)], -2)


def _angle_spline(t: np.ndarray, angle: np.ndarray, moving: np.ndarray, sigma: float):
    """A quintic smoothing spline of an angle known where `moving`, linear in between, held at the ends."""
    from scipy.interpolate import UnivariateSpline

    filled = np.interp(t, t[moving], angle[moving])
    return UnivariateSpline(t, filled, k=5, s=t.size * sigma**2)


def _noise(x: np.ndarray, fs: float, pad: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """The real channel above SPLIT_HZ plus white noise below it at the pad's density (Allan deviation at 1 s)."""
    import allantools
    from scipy.signal import butter, sosfiltfilt

    sos = butter(4, SPLIT_HZ, fs=fs, output="sos")
    high = x - sosfiltfilt(sos, x)
    adev = allantools.oadev(x[pad], rate=fs, data_type="freq", taus=np.array([1.0]))[1][0]
    low = sosfiltfilt(sos, rng.normal(0.0, adev * math.sqrt(fs), x.size))
    return high + low


def left_out_errors(fb: np.ndarray, w: np.ndarray, c: dict[str, float]) -> tuple[np.ndarray, np.ndarray]:
    """The sensor errors of strapdown33's terms other than the biases (``models/strapdown33.py``: ``sa_i`` ppm,
    ``ma_ij`` arcsec, ``sg_i`` ppm, ``mg_ij`` arcsec, ``gg_ij`` deg/h/g; a term not in `c` is 0) for the body
    specific force `fb` (N, 3) m/s^2 and rate `w` (N, 3) rad/s: ``(delta_f, delta_w)``, m/s^2 and rad/s."""
    arcsec, deg_h = math.pi / 648000.0, math.pi / 180.0 / 3600.0
    df, dw = np.zeros_like(fb), np.zeros_like(w)
    for a, i in enumerate("xyz"):
        df[:, a] += c.get(f"sa_{i}", 0.0) * 1e-6 * fb[:, a]
        dw[:, a] += c.get(f"sg_{i}", 0.0) * 1e-6 * w[:, a]
        for b, j in enumerate("xyz"):
            if j != i:
                df[:, a] += c.get(f"ma_{i}{j}", 0.0) * arcsec * fb[:, b]
                dw[:, a] += c.get(f"mg_{i}{j}", 0.0) * arcsec * w[:, b]
            dw[:, a] += c.get(f"gg_{i}{j}", 0.0) * deg_h * fb[:, b] / 9.80665
    return df, dw


def simulate(data: str, out: str, seed: int, pos_white: float = 0.003, pos_gm: float = 0.005,
             pos_tau: float = 10.0, noise: bool = True,
             biases: dict[str, float] | None = None,
             record: dict | None = None,
             clock: tuple[float, float] = (0.0, 0.0),
             left_out: dict[str, float] | None = None,
             lever_arm: np.ndarray | None = None) -> tuple[str, str, float, dict[str, float]]:
    """Write the twin's IMU file (on the real IMU's uniform grid) and geodetic tracking file (velocity from
    differenced positions); return their paths, the time origin (GPST s) and the true biases.

    `noise` False: no IMU or position noise and no rounding (the exact truth, for checks); `biases`: other
    true biases (default :data:`TRUE_BIASES`); `record`, a dict, receives the truth at the IMU samples
    (``t``, ``C_eb`` body -> ECEF, ``r_e``, ``v_e``); `clock` (offset s, rate ppm): the IMU's samples taken at
    ``t`` are written at ``t + offset + rate 1e-6 (t - t_0)`` (a mapping of the IMU's counter onto GPS time that
    runs fast, as the data's does: ``car_drive.imu_clock_from_arrivals``); `left_out`: strapdown33's other terms
    (scale factors, misalignments, g-sensitivity; :func:`left_out_errors`) added to the IMU, constant over the drive;
    `lever_arm` (m, body axes, from the IMU): the positions are the antenna's at ``r + C l`` (the data's 5 cm,
    ``car_drive.LEVER_ARM_IMU``), the IMU's otherwise."""
    import pandas as pd
    import pymap3d as pm
    from car_drive import read_rtklib_pos, velocity_from_positions
    from scipy.interpolate import UnivariateSpline

    from casep.frames import OMEGA_EARTH
    from casep.gravity import normal_gravity_ecef
    from casep.navigation.imu import regular_time
    from casep.simulation.noise import ar1_noise

    rng = np.random.default_rng(seed)
    raw = pd.read_csv(os.path.join(data, "imu_1934_gpst_raw.csv.gz")).to_numpy()
    t_ref = float(np.floor(raw[0, 0]))
    grid = regular_time(raw[:, 0] - t_ref)
    assert grid is not None  # the drive's tags are a jittered grid (car_drive_causes.py tags)
    fs = 1.0 / float(np.mean(np.diff(grid)))
    pos = read_rtklib_pos(os.path.join(data, "gnss_1934_sf.pos"))
    tp = pos["t"] - t_ref
    lat0, lon0, h0 = pos["lat"][0], pos["lon"][0], pos["h"][0]
    enu = np.column_stack(pm.geodetic2enu(pos["lat"], pos["lon"], pos["h"], lat0, lon0, h0))
    sp = [UnivariateSpline(tp, enu[:, c], k=5, s=tp.size * (pos_white**2 + pos_gm**2)) for c in range(3)]
    v_ep = np.column_stack([s.derivative(1)(tp) for s in sp])
    moving = np.hypot(v_ep[:, 0], v_ep[:, 1]) > MOVING
    psi = _angle_spline(tp, np.unwrap(np.arctan2(v_ep[:, 1], v_ep[:, 0])), moving, 0.01)
    theta = _angle_spline(tp, np.arctan2(v_ep[:, 2], np.hypot(v_ep[:, 0], v_ep[:, 1])), moving, 0.01)

    keep = (grid >= tp[0]) & (grid <= tp[-1])
    t = grid[keep]
    r_t = np.column_stack([s(t) for s in sp])
    v_t = np.column_stack([s.derivative(1)(t) for s in sp])
    a_t = np.column_stack([s.derivative(2)(t) for s in sp])
    ps, th, dps, dth = psi(t), theta(t), psi.derivative(1)(t), theta.derivative(1)(t)
    C_tc = _rot_z(ps) @ _rot_y(-th)
    w_c = np.column_stack([np.sin(th) * dps, -dth, np.cos(th) * dps])
    M = _rot_z(np.array(math.pi)) @ _rot_y(np.array(MOUNT_TILT_RAD))
    C_tb = C_tc @ M
    w_tb = w_c @ M  # M^T w_c per row
    la, lo = math.radians(lat0), math.radians(lon0)
    C_et = np.array([[-math.sin(lo), -math.sin(la) * math.cos(lo), math.cos(la) * math.cos(lo)],
                     [math.cos(lo), -math.sin(la) * math.sin(lo), math.cos(la) * math.sin(lo)],
                     [0.0, math.cos(la), math.sin(la)]])
    r0 = np.array(pm.geodetic2ecef(lat0, lon0, h0))
    r_e, v_e, a_e = r0 + r_t @ C_et.T, v_t @ C_et.T, a_t @ C_et.T
    om = np.array([0.0, 0.0, OMEGA_EARTH])
    f_e = a_e + 2.0 * np.cross(om, v_e) - normal_gravity_ecef(r_e)
    C_be = np.swapaxes(C_tb, -1, -2) @ C_et.T
    fb = np.einsum("nij,nj->ni", C_be, f_e)
    w = w_tb + np.einsum("nij,j->ni", C_be, om)

    if record is not None:
        record.update(t=t, C_eb=C_et @ C_tb, r_e=r_e, v_e=v_e)
    b = dict(TRUE_BIASES if biases is None else biases)
    if left_out:
        df, dw = left_out_errors(fb, w, left_out)
        fb, w = fb + df, w + dw
    fb += np.array([b[f"ba_{a}"] for a in "xyz"]) * 9.80665e-3
    w += np.radians(np.array([b[f"bg_{a}"] for a in "xyz"]) / 3600.0)
    real = raw[keep]
    pad = t < tp[moving][0] - 5.0
    enu_m = np.column_stack([s(tp) for s in sp])
    if lever_arm is not None:  # the antenna at C_tb l from the IMU, at the tracking epochs
        C_tb_p = _rot_z(psi(tp)) @ _rot_y(-theta(tp)) @ M
        enu_m = enu_m + np.einsum("nij,j->ni", C_tb_p, np.asarray(lever_arm, float))
    if noise:
        w += np.column_stack([_noise(real[:, 4 + c], fs, pad, rng) for c in range(3)])
        fb += np.column_stack([_noise(real[:, 1 + c], fs, pad, rng) for c in range(3)])
        enu_m = enu_m + rng.normal(0.0, pos_white, (tp.size, 3)) + ar1_noise(tp, pos_gm, pos_tau, rng)
    lat, lon, h = pm.enu2geodetic(enu_m[:, 0], enu_m[:, 1], enu_m[:, 2], lat0, lon0, h0)
    if noise:  # as the .pos file writes them
        lat, lon, h = np.round(lat, 7), np.round(lon, 7), np.round(h, 3)
    sim_pos = {"t": pos["t"], "lat": lat, "lon": lon, "h": h}
    trk = velocity_from_positions(sim_pos)
    os.makedirs(out, exist_ok=True)
    imu_path, trk_path = os.path.join(out, "imu.csv"), os.path.join(out, "tracking.csv")
    t_label = t + clock[0] + clock[1] * 1e-6 * (t - t[0])
    pd.DataFrame({"t": t_label, "w_x": w[:, 0], "w_y": w[:, 1], "w_z": w[:, 2], "fb_x": fb[:, 0], "fb_y": fb[:, 1],
                  "fb_z": fb[:, 2]}).to_csv(imu_path, index=False, float_format="%.10g")
    pd.DataFrame({"t": trk["t"] - t_ref, "lat": trk["lat"], "lon": trk["lon"], "h": trk["h"], "v_east": trk["ve"],
                  "v_north": trk["vn"], "v_up": trk["vu"]}).to_csv(trk_path, index=False, float_format="%.11g")
    print(f"simulated twin (seed {seed}): {t.size} IMU samples {t[0]:.2f}-{t[-1]:.2f} s, largest |a_h| "
          f"{np.max(np.hypot(a_t[:, 0], a_t[:, 1])):.2f} m/s^2, largest |w| {math.degrees(np.max(np.abs(w_c))):.1f} "
          f"deg/s; true biases " + ", ".join(f"{k} {v:g}" for k, v in b.items())
          + (f"; IMU times written {clock[0] * 1e3:g} ms + {clock[1]:g} ppm off" if any(clock) else "")
          + (f"; left-out terms {len(left_out)} (" + ", ".join(f"{k} {v:.3g}" for k, v in left_out.items()) + ")"
             if left_out else "")
          + (f"; antenna at {np.asarray(lever_arm)} m from the IMU (body axes)" if lever_arm is not None else ""))
    return imu_path, trk_path, t_ref, {**b, **(left_out or {})}

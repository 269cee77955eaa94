"""Why the car drive's windows disagree: measurements of the candidate causes, one by one.

Each check is a measurement independent of the windows' chi-square it is meant to explain:

``nav``
    casep's navigation (fourth-order increments, coning and sculling, launch-inertial frame) against
    an independent first-order integration (trapezoidal rate, Earth-fixed frame, Coriolis) of the
    same window from the same state: how far apart are their velocities, against the window misfit?
``rtk``
    RTKLIB's velocity (a Kalman-filter state) against the velocity differenced from its RTK
    positions, ``(r_{k+1} - r_k) / h`` at the mid-time: the lag of the filter velocity that
    minimises the difference, and the RMS difference with and without it.
``tags``
    The IMU's time tags against the uniform grid they jitter about (:func:`casep.navigation.imu.regular_time`),
    and what integrating on the tags instead of the grid does to a window's velocity (the same samples,
    the same start).
``clock``
    The IMU's counter against the host's clock (when its lines arrived, the IMU time-tag file) and the host's
    clock against GPS (when the receiver's 4 Hz bursts arrived, the GNSS time-tag file): how far the data's
    linear stretch of the counter onto GPS time (``imu_1934_gpst_raw.csv.gz``) is off, and how it drifts
    (``car_drive.imu_clock_from_arrivals``).
``static``
    The gyro biases where the car stands still (the start, 201-208 s, the end): their mean rates, with
    the Allan deviation (allantools) at a third of the span as the std of each mean. How much the
    biases move over the drive, measured without any window.

``rocking``
    Is the horizontal accelerometers' wander at rest the sensor or the car rocking on its springs? At each stop:
    the Allan deviation (allantools) of ``fb_x``, ``fb_y``, ``fb_z``; ``fb_y`` against ``g`` times the roll angle
    the x gyro measures (``fb_x`` against the pitch angle, y gyro), both low-passed at 2 Hz: correlation and slope
    (``g`` = 9.81 m/s^2/rad if it is tilt), their coherence (SciPy) by band, and the Allan deviation with that tilt
    taken out (``car_drive.tilt_free_force``); then ``car_drive.horizontal_instability`` with and without it.

    OPENBLAS_NUM_THREADS=1 python benchmarks/car_drive_causes.py nav rtk static tags clock rocking \
        --figures docs/results/figures
"""

from __future__ import annotations

import argparse
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from car_drive import DATA, convert, imu_clock_from_arrivals, print_rest, read_rtklib_pos, spans_at_rest  # noqa: E402

OMEGA_E = 7.292115e-5


def _skew(a: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def _expm_so3(phi: np.ndarray) -> np.ndarray:
    """Rodrigues' formula, the rotation by the vector `phi` (rad)."""
    a = float(np.linalg.norm(phi))
    K = _skew(phi)
    if a < 1e-12:
        return np.eye(3) + K
    return np.eye(3) + math.sin(a) / a * K + (1.0 - math.cos(a)) / a**2 * K @ K


def first_order_ecef(t, w, f, C0, r0, v0):
    """Independent strapdown in ECEF: rate trapezoid, ``C_k = R(-W h) C_{k-1} exp(h (w_{k-1}+w_k)/2)``,
    ``v_k = v_{k-1} + h (C f)_trapezoid + h (g - 2 W x v_{k-1})``, normal gravity (with centrifugal)."""
    from casep.gravity import normal_gravity_ecef

    W = np.array([0.0, 0.0, OMEGA_E])
    n = len(t)
    C, r, v = C0.copy(), r0.copy(), v0.copy()
    V = np.empty((n, 3))
    V[0] = v
    for k in range(1, n):
        h = t[k] - t[k - 1]
        C_new = _expm_so3(-W * h) @ C @ _expm_so3(0.5 * h * (w[k - 1] + w[k]))
        a = 0.5 * (C @ f[k - 1] + C_new @ f[k]) + normal_gravity_ecef(r) - 2.0 * np.cross(W, v)
        v_new = v + h * a
        r = r + 0.5 * h * (v + v_new)
        v, C = v_new, C_new
        V[k] = v
    return V


def check_nav(imu, trk_path, site, pad, starts, length):
    """casep's window navigation against :func:`first_order_ecef` from the same state."""
    from casep.navigation.navigator import navigate
    from casep.navigation.strapdown import quat_to_dcm
    from casep.workflows import windows as W

    trk = W._Tracking(trk_path)
    nav0 = navigate(imu, site, pad, heading_deg=0.0)
    a = nav0.alignment
    from casep.navigation.imu import ImuData

    imu = ImuData(imu.t, imu.w - (a.w_mean - a.C_tb.T @ site.earth_rate), imu.f, source=imu.source)
    nav0 = navigate(imu, site, pad, heading_deg=0.0)
    for t_a in starts:
        j = int(np.searchsorted(nav0.t, t_a))
        t_a = float(nav0.t[j])
        C_eb = W._launch_from_ecef(site, t_a).T @ quat_to_dcm(nav0.q[j])
        site_k, nav = W._navigate_window(imu, trk, t_a, t_a + length, C_eb)
        _, v_casep = nav.earth_relative()
        r0 = trk.at(t_a, trk.r_e)
        sel = (imu.t >= t_a) & (imu.t <= t_a + length)
        v_ind = first_order_ecef(imu.t[sel], imu.w[sel], imu.f[sel], C_eb, r0, v_casep[0])
        d = v_casep - v_ind
        wn = np.linalg.norm(imu.w[sel], axis=1)
        print(f"  window {t_a:6.1f} s (max rate {math.degrees(wn.max()):.0f} deg/s): casep - first-order "
              f"velocity RMS {np.sqrt(np.mean(d**2)):.4f} m/s, at the end {np.linalg.norm(d[-1]):.4f} m/s; "
              f"casep - RTK RMS {np.sqrt(np.mean((v_casep - _interp3(trk.t, trk.v_e, nav.t))**2)):.3f} m/s "
              f"(uncorrected, before the fit)")


def _interp3(t, y, tq):
    return np.column_stack([np.interp(tq, t, y[:, c]) for c in range(y.shape[1])])


def check_rtk(data):
    """The filter velocity against the differenced positions, and its lag."""
    import pymap3d as pm

    pos = read_rtklib_pos(os.path.join(data, "gnss_1934_sf.pos"))
    t = pos["t"] - pos["t"][0]
    e, n, u = pm.geodetic2enu(pos["lat"], pos["lon"], pos["h"], pos["lat"][0], pos["lon"][0], pos["h"][0])
    r = np.column_stack([e, n, u])
    h = np.diff(t)
    ok = np.abs(h - np.median(h)) < 1e-3
    tm = 0.5 * (t[1:] + t[:-1])
    vd = np.diff(r, axis=0) / h[:, None]
    vk = np.column_stack([pos["ve"], pos["vn"], pos["vu"]])
    moving = np.hypot(vk[:, 0], vk[:, 1]) > 0.3
    lags = np.arange(-0.40, 0.401, 0.01)
    rms = []
    for lag in lags:  # the filter velocity at t taken as the true velocity at t - lag
        vk_at = _interp3(t - lag, vk, tm)
        m = ok & (np.interp(tm, t, moving.astype(float)) > 0.5)
        rms.append(np.sqrt(np.mean((vk_at[m] - vd[m]) ** 2, axis=0)))
    rms = np.array(rms)
    tot = np.sqrt(np.mean(rms[:, :2] ** 2, axis=1))
    best = int(np.argmin(tot))
    i0 = int(np.argmin(np.abs(lags)))
    print(f"  RTKLIB velocity vs differenced RTK positions (4 Hz, moving epochs): horizontal RMS difference "
          f"{tot[i0]:.4f} m/s at lag 0, least {tot[best]:.4f} m/s at lag {lags[best] * 1e3:+.0f} ms "
          f"(the filter velocity is the true one {lags[best] * 1e3:.0f} ms late)")
    print(f"  vertical RMS difference {rms[i0, 2]:.4f} m/s at lag 0; position std (median sdn) gives a differenced "
          f"velocity noise of about {np.median(np.abs(np.diff(vd[:, 0]))) / math.sqrt(2):.3f} m/s")
    return lags, tot


def check_tags(imu, starts, length, outdir=None):
    """Tags minus grid, and the velocity of casep's navigation on the tags minus on the grid, per window."""
    from casep.frames import LaunchSite
    from casep.navigation.imu import ImuData, regular_time
    from casep.navigation.navigator import navigate_from

    grid = regular_time(imu.t)
    if grid is None:
        print("  the tags are not a jittered uniform grid")
        return
    e = imu.t - grid
    h = np.diff(imu.t)
    print(f"  tags - grid: RMS {e.std() * 1e3:.2f} ms, largest {np.abs(e).max() * 1e3:.2f} ms; steps "
          f"{h.min() * 1e3:.1f}-{h.max() * 1e3:.1f} ms ({np.mean(np.abs(h - np.median(h)) > 5e-4) * 100:.0f} % off "
          f"the median), grid step {np.mean(np.diff(grid)) * 1e3:.4f} ms")
    from casep.frames import ecef_to_launch
    from casep.navigation.strapdown import launch_gravitation, quat_from_rotvec

    site = LaunchSite(0.0, 0.0, 0.0, 0.0, 0.0)
    r0, v0 = ecef_to_launch(site, np.zeros(1), site.r_site[None, :], np.zeros((1, 3)))
    curves = []
    for t_a in starts:
        vs = []
        sel = (imu.t >= t_a) & (imu.t <= t_a + length)
        f0 = imu.f[sel][:100].mean(axis=0)  # levelled on the first second: body f0 turned onto the local up
        up = -launch_gravitation(site)(np.zeros(1), r0)[0]
        axis = np.cross(f0, up)
        angle = math.atan2(np.linalg.norm(axis), float(f0 @ up))
        q0 = quat_from_rotvec(axis / np.linalg.norm(axis) * angle)
        for t in (imu.t, grid):
            sub = ImuData(t[sel] - t[sel][0], imu.w[sel], imu.f[sel], source=imu.source)
            vs.append(navigate_from(sub, site, q0, r0[0], v0[0]).v)
        d = np.linalg.norm(vs[0] - vs[1], axis=1)
        curves.append((t_a, d))
        print(f"  window {t_a:6.1f} s: |v on the tags - v on the grid| RMS {np.sqrt(np.mean(d**2)):.3f} m/s, "
              f"at the end {d[-1]:.3f} m/s")
    if outdir:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(1, 2, figsize=(10, 3))
        ax[0].plot(imu.t[:3000], e[:3000] * 1e3, ".", ms=2)
        ax[0].set_xlabel("t, s")
        ax[0].set_title("IMU time tags minus their uniform grid, ms", fontsize=9)
        for t_a, d in curves:
            ax[1].plot(np.arange(d.size) * float(np.mean(np.diff(grid))), d, label=f"window at {t_a:.0f} s")
        ax[1].set_xlabel("time in the window, s")
        ax[1].set_title("|velocity integrated on the tags - on the grid|, m/s", fontsize=9)
        ax[1].legend(fontsize=7)
        fig.tight_layout()
        path = os.path.join(outdir, "car-drive-tags.png")
        fig.savefig(path, dpi=80)
        print("figure", path)


def lag_figure(lags, tot, outdir: str) -> str:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    os.makedirs(outdir, exist_ok=True)
    fig, ax = plt.subplots(figsize=(5, 3))
    ax.plot(lags * 1e3, tot, "-")
    ax.set_xlabel("lag of RTKLIB's velocity, ms")
    ax.set_ylabel("RMS difference, m/s")
    ax.set_title("RTKLIB velocity vs differenced RTK positions (horizontal)", fontsize=9)
    fig.tight_layout()
    p = os.path.join(outdir, "car-drive-rtk-lag.png")
    fig.savefig(p, dpi=80)
    return p


def course_shift(t_imu: np.ndarray, imu: np.ndarray, pos: dict, t_ref: float,
                 spans: tuple[tuple[float, float], ...]) -> list[float]:
    """Per span, the shift of the IMU's times (s) that best lines the vertical gyro rate up with the course rate
    of the velocity differenced from the RTK positions (epochs above 3 m/s): ``course'(t) = -w_up(t_imu + shift)``
    in the least-squares sense, on a 5 ms grid refined by a parabola; the gyro rate (pad's mean removed, projected
    on the pad's vertical) is averaged over 0.25 s as the differenced velocity is. A clock whose offset drifts
    gives a shift that moves from span to span."""
    from casep.navigation.imu import regular_time

    grid = regular_time(t_imu)
    ti = t_imu if grid is None else grid
    pad = ti < 30.0
    up = imu[pad, 0:3].mean(axis=0)
    up /= np.linalg.norm(up)
    w_up = np.convolve((imu[:, 3:6] - imu[pad, 3:6].mean(axis=0)) @ up, np.ones(25) / 25, mode="same")
    tp = pos["t"] - t_ref
    rate = np.gradient(np.unwrap(np.arctan2(pos["ve"], pos["vn"])), tp)
    fast = np.hypot(pos["ve"], pos["vn"]) > 3.0
    lags = np.arange(-0.5, 0.3001, 0.005)
    out = []
    for a, b in spans:
        use = fast & (tp > a) & (tp < b)
        err = np.array([np.mean((rate[use] + np.interp(tp[use] - lag, ti, w_up)) ** 2) for lag in lags])
        j = int(np.clip(np.argmin(err), 1, lags.size - 2))
        y0, y1, y2 = err[j - 1:j + 2]
        out.append(float(lags[j] + 0.005 * 0.5 * (y0 - y2) / (y0 - 2.0 * y1 + y2)))
    return out


def check_clock(data: str, outdir: str | None = None) -> None:
    """Print (and draw) the IMU's and the host's clocks from the time-tag files (module docstring, ``clock``)."""
    import pandas as pd
    from car_drive import velocity_from_positions

    c = imu_clock_from_arrivals(data)
    raw = pd.read_csv(os.path.join(data, "imu_1934_gpst_raw.csv.gz")).to_numpy()
    pos = velocity_from_positions(read_rtklib_pos(os.path.join(data, "gnss_1934_sf.pos")))
    t_ref = float(np.floor(raw[0, 0]))
    spans = ((40.0, 190.0), (190.0, 340.0), (340.0, 490.0), (40.0, 545.0))
    for label, t in (("stretched (the data's)", raw[:, 0]), ("from the arrivals", c["t"])):
        sh = course_shift(t - t_ref, raw[:, 1:7], pos, t_ref, spans)
        print(f"IMU times {label}: the shift lining the gyro rate up with the RTK course rate, "
              + ", ".join(f"{a:.0f}-{b:.0f} s {x * 1e3:.0f} ms" for (a, b), x in zip(spans, sh)))
    m, f = c["mapped_minus"], c["imu_floor"]
    scatter = np.std(f[:, 1] - np.polyval(c["imu_line"], f[:, 0]))
    print(f"IMU counter against the host (earliest arrival per 10 s): rate {c['imu_line'][0] * 1e6:.1f} ppm, "
          f"floor about its line RMS {scatter * 1e3:.2f} ms")
    print(f"the data's stretched times minus that line: {c['start'] * 1e3:.0f} ms at the start, "
          f"{c['end'] * 1e3:.0f} ms at the end, {c['rate_ppm']:.0f} ppm ({c['rate_ppm'] * 30e-3:.1f} ms per 30 s)")
    print(f"host clock against GPS (earliest GNSS burst per 10 s against the 0.25 s grid): "
          f"{c['host_gps_ppm']:.0f} ppm, floor about its line RMS {c['host_gps_scatter'] * 1e3:.0f} ms")
    if outdir:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(1, 2, figsize=(10, 3))
        ax[0].plot(m[:, 0], m[:, 1] * 1e3, lw=1)
        ax[0].set_title("IMU times as mapped (linear stretch) minus the arrival line, ms", fontsize=9)
        ax[1].plot(f[:, 0], (f[:, 1] - np.polyval(c["imu_line"], f[:, 0])) * 1e3, "o", ms=3, label="IMU lines")
        g = c["gnss_floor"]
        ax[1].plot(g[:, 0], (g[:, 1] - g[0, 1]) * 1e3, "s", ms=3, label="GNSS bursts (from the first)")
        ax[1].legend(fontsize=8)
        ax[1].set_title("earliest arrival per 10 s about the IMU's line; GNSS against GPS, ms", fontsize=9)
        for a in ax:
            a.set_xlabel("host time from the file's start, s")
        fig.tight_layout()
        path = os.path.join(outdir, "car-drive-clock.png")
        fig.savefig(path, dpi=80)
        print("figure", path)


def check_rocking(imu, spans) -> None:
    """Print the stops' tilt analysis (module notes, ``rocking``)."""
    import allantools
    from car_drive import horizontal_instability, tilt_free_force
    from scipy import signal

    mg = 9.80665e-3
    for a, b in spans:
        m = (imu.t > a) & (imu.t < b)
        t, f, w = imu.t[m], imu.f[m] - imu.f[m].mean(axis=0), imu.w[m] - imu.w[m].mean(axis=0)
        fs = 1.0 / float(np.median(np.diff(t)))
        taus = np.array([1.0, 3.0, (b - a) / 3.0])
        theta = np.cumsum(w, axis=0) / fs
        theta -= theta.mean(axis=0)
        free = tilt_free_force(imu.f[m], imu.w[m], t)
        print(f"stop {a:.1f}-{b:.1f} s, Allan deviation at {np.round(taus, 1)} s (mg):")
        for c in range(3):
            ad = allantools.oadev(f[:, c], rate=fs, data_type="freq", taus=taus)[1] / mg
            print(f"  fb_{'xyz'[c]} {np.round(ad, 2)}")
        lp = signal.butter(4, 2.0 / (fs / 2.0))
        for c_f, c_w, sign in ((1, 0, 1.0), (0, 1, -1.0)):
            y, x = signal.filtfilt(*lp, f[:, c_f]), signal.filtfilt(*lp, theta[:, c_w])
            slope = np.linalg.lstsq(np.column_stack([np.ones_like(x), x, t - t.mean()]), y, rcond=None)[0][1]
            fr, coh = signal.coherence(f[:, c_f], w[:, c_w], fs=fs, nperseg=256)
            bands = ((0.4, 1.0), (1.0, 3.0), (3.0, 10.0))
            cb = [float(coh[(fr >= lo) & (fr < hi)].mean()) for lo, hi in bands]
            ad_free = allantools.oadev(free[:, c_f], rate=fs, data_type="freq", taus=taus)[1] / mg
            ad_tilt = allantools.oadev(9.80665 * theta[:, c_w], rate=fs, data_type="freq", taus=taus)[1] / mg
            print(f"  fb_{'xyz'[c_f]} against {'+' if sign > 0 else '-'}g x the angle about {'xyz'[c_w]} (below 2 Hz): "
                  f"correlation {sign * np.corrcoef(y, x)[0, 1]:+.2f}, slope {sign * slope:+.2f} m/s^2/rad; coherence "
                  + ", ".join(f"{lo:g}-{hi:g} Hz {v:.2f}" for (lo, hi), v in zip(bands, cb))
                  + f"; Allan deviation less the tilt {np.round(ad_free, 2)} mg "
                  f"(the tilt's own {np.round(ad_tilt, 2)})")
    print("horizontal_instability: the tilt taken out "
          + ", ".join(f"{n} {v:.2f} mg" for n, v in horizontal_instability(imu, spans).items()) + "; left in "
          + ", ".join(f"{n} {v:.2f} mg" for n, v in horizontal_instability(imu, spans, tilt=False).items()))


def main() -> None:
    from casep.frames import LaunchSite
    from casep.navigation.imu import read_imu

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("checks", nargs="+", choices=("nav", "rtk", "static", "tags", "clock", "rocking"))
    ap.add_argument("--figures", default=None, help="folder for the PNG figure of the RTK velocity lag")
    ap.add_argument("--data", default=DATA)
    ap.add_argument("--out", default="car_drive_out")
    ap.add_argument("--imu-time", choices=("tags", "uniform"), default="tags",
                    help="nav: integrate on the IMU's tags or on their uniform grid (regular_time)")
    ap.add_argument("--starts", type=float, nargs="+", default=[66.7, 396.7, 456.7])
    args = ap.parse_args()
    if "clock" in args.checks:
        check_clock(args.data, args.figures)
    if "rtk" in args.checks:
        lags, tot = check_rtk(args.data)
        if args.figures:
            print("figure", lag_figure(lags, tot, args.figures))
    if {"nav", "static", "tags", "rocking"} & set(args.checks):
        import pandas as pd

        imu_path, trk_path, t_ref = convert(args.data, args.out)
        imu = read_imu(imu_path)
        trk = pd.read_csv(trk_path)
        if args.imu_time == "uniform" and "nav" in args.checks:
            from casep.navigation.imu import regular_time

            grid = regular_time(imu.t)
            imu.t = imu.t if grid is None else grid
    if "tags" in args.checks:
        check_tags(imu, args.starts, 30.0, args.figures)
    if {"static", "rocking"} & set(args.checks):
        pos = read_rtklib_pos(os.path.join(args.data, "gnss_1934_sf.pos"))
        rest = spans_at_rest(pos["t"] - t_ref, pos["ve"], pos["vn"])
        if "static" in args.checks:
            print_rest(imu, rest)
        if "rocking" in args.checks:
            check_rocking(imu, rest)
    if "nav" in args.checks:
        site = LaunchSite(float(trk.lat[0]), float(trk.lon[0]), float(trk.h[0]), 0.0, 0.0)
        moving = float(trk.t[np.hypot(trk.v_east, trk.v_north) > 0.3].iloc[0])
        check_nav(imu, trk_path, site, (0.0, moving - 5.0), args.starts, 30.0)


if __name__ == "__main__":
    main()

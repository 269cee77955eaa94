"""A real car drive (consumer MEMS IMU at 100 Hz, RTK velocity at 4 Hz) separated in windows.

Data: rtklibexplorer/GNSS_IMU, drive_0708 (BSD-3; NOTES.md of the data folder): a TDK ICM-45686 IMU
on a car roof, the IMU clock mapped to GPS time (``imu_1934_gpst_raw.csv.gz``: GPST seconds, m/s^2,
rad/s), RTKLIB's solution ``gnss_1934_sf.pos`` (lat, lon, h and vn, ve, vu at 4 Hz, GPST).

The chain (:func:`casep.workflows.windows.separate_windows`): align on the static start, remove
the gyro biases seen there, then windows of ``--length`` s, each navigated from the RTK state at its
start and the running attitude, separated with ``strapdown6_window`` (biases + initial attitude and
velocity errors; the tracking time offset dt_trk comes with the geodetic tracking), and compared:
chi-square of the windows' biases against their weighted mean, and each window's biases predicting
every other window's dv at its end.

    OPENBLAS_NUM_THREADS=1 python benchmarks/car_drive.py --figures docs/results/figures
    python benchmarks/car_drive.py --write-cut tests/data/car_drive --cut 0 70   # the test suite's cut
"""

from __future__ import annotations

import argparse
import calendar
import datetime
import math
import os
import time
import warnings

import numpy as np

DATA = "/work/shared/data/rtklibexplorer_car"
#: GNSS antenna minus IMU, car axes (forward, right, down), m (the data's drive_config.py).
LEVER_ARM_CAR = np.array([0.0, -0.05, 0.0])
#: The same in the IMU's body axes (x back, y right, z up: the mounting's roll and yaw of 180 deg; its 5-7 deg
#: misalignment turns it by under 5 mm), the lever arm terms ``l_*`` of strapdown42_extended, and the std it is
#: taken with (the misalignment's 5 mm, the antenna's phase centre): stated before any run with them.
LEVER_ARM_IMU = {"l_x": 0.0, "l_y": -0.05, "l_z": 0.0}
LEVER_ARM_STD = 0.01
#: The std of the instrument terms the window model leaves out (strapdown33's names and units), the consider
#: covariance P_c (diagonal) of the windows' comparison: typical figures of a consumer MEMS IMU of the ICM-42688 /
#: ICM-45686 class (the data folder holds no datasheet): sensitivity (scale factor) tolerance 0.5 %, cross-axis
#: sensitivity (misalignment) 0.3 deg, gyro linear-acceleration sensitivity 0.1 deg/s/g. Fixed before any run
#: with them, not fitted to the chi-square.
LEFT_OUT_STD = {**{f"s{k}_{i}": 5000.0 for k in "ag" for i in "xyz"},
                **{f"m{k}_{i}{j}": 1080.0 for k in "ag" for i in "xyz" for j in "xyz" if i != j},
                **{f"gg_{i}{j}": 360.0 for i in "xyz" for j in "xyz"}}


def left_out_covariance(names) -> np.ndarray:
    """P_c of :data:`LEFT_OUT_STD` for the left-out terms `names` (their order)."""
    return np.diag([LEFT_OUT_STD[n] ** 2 for n in names])


def read_rtklib_pos(path: str) -> dict[str, np.ndarray]:
    """RTKLIB .pos with GPST calendar time and velocity columns: t (GPST s, Unix epoch), lat, lon, h, vn, ve, vu."""
    rows = [line.split() for line in open(path) if line.strip() and not line.startswith("%")]
    t = np.array([calendar.timegm(datetime.datetime.strptime(r[0] + " " + r[1], "%Y/%m/%d %H:%M:%S.%f").timetuple())
                  + float("0." + r[1].split(".")[1]) for r in rows])
    v = np.array([[float(x) for x in r[2:]] for r in rows])
    return {"t": t, "lat": v[:, 0], "lon": v[:, 1], "h": v[:, 2], "q": v[:, 3], "ns": v[:, 4], "vn": v[:, 13],
            "ve": v[:, 14], "vu": v[:, 15]}


def velocity_from_positions(pos: dict[str, np.ndarray], same_satellites: bool = False) -> dict[str, np.ndarray]:
    """The tracking at the mid-epochs: the mean ECEF velocity ``(r_{k+1} - r_k) / h_k`` between consecutive
    RTK positions, turned into east, north, up at the mid-point (the mean of the two ECEF positions).

    RTKLIB's velocity is a state of its Kalman filter: here it is the true velocity low-passed with a
    time constant of about 0.14 s (``benchmarks/car_drive_causes.py rtk``), while the RTK positions are
    tied to the carrier phase of each epoch. The differenced position is the mean velocity over the
    interval, the velocity at the mid-time to ``jerk h^2 / 24`` (a few mm/s for a car at h = 0.25 s).
    Only consecutive epochs at the nominal step are differenced. With `same_satellites`, only consecutive epochs
    that are both fixed (``q`` 1) and have the same number of satellites (``ns``): an RTK position's error (the
    multipath and the residual atmosphere of each satellite, weighted by the geometry) changes with the set of
    satellites, so a difference across a change of the set holds the change of that error over 0.25 s as velocity.
    On this drive it does not help: the windows agree less without those differences (docs/results/car-drive.md).
    """
    import pymap3d as pm

    x, y, z = pm.geodetic2ecef(pos["lat"], pos["lon"], pos["h"])
    r = np.column_stack([x, y, z])
    h = np.diff(pos["t"])
    keep = np.abs(h - np.median(h)) < 1e-3
    if same_satellites:
        keep &= (pos["ns"][1:] == pos["ns"][:-1]) & (pos["q"][1:] == 1) & (pos["q"][:-1] == 1)
    v = (np.diff(r, axis=0) / h[:, None])[keep]
    mid = (0.5 * (r[1:] + r[:-1]))[keep]
    lat, lon, alt = pm.ecef2geodetic(mid[:, 0], mid[:, 1], mid[:, 2])
    ve, vn, vu = pm.ecef2enuv(v[:, 0], v[:, 1], v[:, 2], lat, lon)
    return {"t": (0.5 * (pos["t"][1:] + pos["t"][:-1]))[keep], "lat": lat, "lon": lon, "h": alt, "ve": ve, "vn": vn,
            "vu": vu}


def _read_tag(path: str) -> tuple[float, np.ndarray]:
    """An RTKLIB time-tag file: the host's start time (GPST s, Unix epoch) and its (tick ms, file offset) rows."""
    import struct

    with open(path, "rb") as fh:
        fh.read(64)  # 60-byte text header, uint32 tick frequency
        t0 = struct.unpack("<I", fh.read(4))[0] + struct.unpack("<d", fh.read(8))[0]
        rec = np.frombuffer(fh.read(), dtype="<u4").reshape(-1, 2).astype(np.int64)
    return t0, rec


def _floor_line(t: np.ndarray, y: np.ndarray, bin_s: float = 10.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The least-squares line (slope, intercept) through the lowest `y` of each `bin_s` bin of `t` (a transfer
    delay only adds: the earliest arrival in a bin is the clock), with the bins' centres and lowest values."""
    edges = np.arange(t.min(), t.max() + bin_s, bin_s)
    c, lo = [], []
    for a, b in zip(edges[:-1], edges[1:]):
        m = (t >= a) & (t < b)
        if m.sum() > 5:
            c.append(0.5 * (a + b))
            lo.append(float(np.min(y[m])))
    return np.polyfit(c, lo, 1), np.array(c), np.array(lo)


def imu_clock_from_arrivals(data: str) -> dict[str, float | np.ndarray]:
    """The IMU's sample times on the host's clock from when its lines arrived, and the host's clock against GPS.

    ``imu_1934_gpst_raw.csv.gz`` maps the IMU's millisecond counter linearly onto [tag start, last tag]
    (``align_imu.py``), which assumes the first sample at the file's opening and the last at the last write.
    The time-tag file says when each block of lines reached the host (tick ms, file offset; the copy here lost
    its carriage returns, one byte per line, which the offsets still count): the earliest arrival per 10 s, less
    the counter, is a line in time (a constant transfer delay and the two clocks' rate difference). The GNSS
    tag file's bursts (one per 0.25 s epoch) against the 0.25 s grid give the host clock's rate against GPS the
    same way. Returns the corrected times (the earliest-arrival line: the transfer delay itself is unknown and
    left in, a constant), the mapped times' rate error against it (ppm), their offset at start and end (s) and
    the host's rate against GPS (ppm, with the scatter of its floor about its line, s).
    """
    import pandas as pd

    t0, rec = _read_tag(os.path.join(data, "imu_1934.csv.tag"))
    raw = open(os.path.join(data, "imu_1934.csv"), "rb").read()
    starts = np.r_[0, np.flatnonzero(np.frombuffer(raw, np.uint8) == 10) + 1]
    starts = starts + np.arange(starts.size)  # the CR each line had when the offsets were written
    ms = np.array([float(ln.split(b",")[6]) if ln.count(b",") == 6 else np.nan for ln in raw.split(b"\n")]) / 1e3
    first = ms[np.flatnonzero(np.isfinite(ms))[0]]
    line = np.searchsorted(starts, rec[:, 1], side="right") - 2  # the last line complete before the offset
    ok = (line >= 0) & np.isfinite(ms[np.clip(line, 0, ms.size - 1)])
    tick = rec[ok, 0] / 1e3
    (slope, icpt), ic, ilo = _floor_line(tick, tick - (ms[line[ok]] - first))
    mapped = pd.read_csv(os.path.join(data, "imu_1934_gpst_raw.csv.gz")).to_numpy()[:, 0]
    counter = ms[np.isfinite(ms)][1:-1] - first  # align_imu.py drops the first and the last line
    arr = counter + (icpt + slope * counter) / (1.0 - slope)  # tick = counter + icpt + slope tick
    corrected = t0 + arr
    tg0, rg = _read_tag(os.path.join(data, "gnss_1934.ubx.tag"))
    tk = rg[:, 0] / 1e3
    bursts = tk[np.r_[True, np.diff(tk) > 0.08]]
    late = bursts - bursts[0] - 0.25 * np.round((bursts - bursts[0]) / 0.25)
    (g_slope, g_icpt), gc, glo = _floor_line(bursts, late)
    d = mapped - corrected
    return {"t": corrected, "rate_ppm": float(np.polyfit(counter, d, 1)[0] * 1e6), "start": float(d[0]),
            "end": float(d[-1]), "host_gps_ppm": float(g_slope * 1e6),
            "host_gps_scatter": float(np.std(glo - np.polyval([g_slope, g_icpt], gc))),
            "imu_floor": np.column_stack([ic, ilo]), "imu_line": np.array([slope, icpt]),
            "gnss_floor": np.column_stack([gc, glo]), "gnss_line": np.array([g_slope, g_icpt]),
            "mapped_minus": np.column_stack([counter, d])}


def convert(data: str, out: str, cut: tuple[float, float] | None = None,
            velocity: str = "rtklib", imu_clock: str = "stretch") -> tuple[str, str, float]:
    """casep's IMU file (t, w_*, fb_*) and geodetic tracking file, time from the first IMU sample.

    `velocity`: ``"rtklib"`` the .pos file's velocity, ``"positions"`` :func:`velocity_from_positions`,
    ``"same-satellites"`` the same across no change of the satellite count or fix.
    `imu_clock`: ``"stretch"`` the mapped file's times, ``"arrivals"`` :func:`imu_clock_from_arrivals`.
    """
    import pandas as pd

    imu = pd.read_csv(os.path.join(data, "imu_1934_gpst_raw.csv.gz")).to_numpy()
    if imu_clock == "arrivals":
        clock = imu_clock_from_arrivals(data)
        imu[:, 0] = clock["t"]
        print(f"IMU clock from the tags' arrivals: the mapped times run {clock['rate_ppm']:.0f} ppm fast against "
              f"it ({clock['start'] * 1e3:.0f} ms at the start, {clock['end'] * 1e3:.0f} ms at the end); the host "
              f"clock against GPS (GNSS bursts) {clock['host_gps_ppm']:.0f} ppm, floor scatter "
              f"{clock['host_gps_scatter'] * 1e3:.0f} ms")
    pos = read_rtklib_pos(os.path.join(data, "gnss_1934_sf.pos"))
    if velocity in ("positions", "same-satellites"):
        pos = velocity_from_positions(pos, same_satellites=velocity == "same-satellites")
    t_ref = float(np.floor(imu[0, 0]))
    ti, tp = imu[:, 0] - t_ref, pos["t"] - t_ref
    si = np.ones(len(ti), bool) if cut is None else (ti >= cut[0]) & (ti <= cut[1])
    sp = np.ones(len(tp), bool) if cut is None else (tp >= cut[0] - 1.0) & (tp <= cut[1] + 1.0)
    os.makedirs(out, exist_ok=True)
    imu_path, trk_path = os.path.join(out, "imu.csv"), os.path.join(out, "tracking.csv")
    pd.DataFrame({"t": ti[si], "w_x": imu[si, 4], "w_y": imu[si, 5], "w_z": imu[si, 6], "fb_x": imu[si, 1],
                  "fb_y": imu[si, 2], "fb_z": imu[si, 3]}).to_csv(imu_path, index=False, float_format="%.7g")
    pd.DataFrame({"t": tp[sp], "lat": pos["lat"][sp], "lon": pos["lon"][sp], "h": pos["h"][sp],
                  "v_east": pos["ve"][sp], "v_north": pos["vn"][sp], "v_up": pos["vu"][sp]}).to_csv(
        trk_path, index=False, float_format="%.11g")
    return imu_path, trk_path, t_ref


def course_rate_ratio(imu, trk, pad: tuple[float, float]) -> float:
    """Slope of the tracked course rate on the vertical gyro rate (pad bias removed), epochs above 3 m/s.

    The course (azimuth of the horizontal velocity) turns clockwise as the body turns counterclockwise
    about the up axis, so the slope is -(1 + scale error of the vertical rate) when the car does not slip.
    """
    pad_rows = (imu.t >= pad[0]) & (imu.t <= pad[1])
    up = imu.f[pad_rows].mean(axis=0)
    up /= np.linalg.norm(up)
    w_up = (imu.w - imu.w[pad_rows].mean(axis=0)) @ up
    t, ve, vn = trk.t.to_numpy(), trk.v_east.to_numpy(), trk.v_north.to_numpy()
    rate = np.gradient(np.unwrap(np.arctan2(ve, vn)), t)
    use = np.hypot(ve, vn) > 3.0
    w = np.interp(t[use], imu.t, w_up)
    return float(np.sum(w * rate[use]) / np.sum(w * w))


def spans_at_rest(t: np.ndarray, ve: np.ndarray, vn: np.ndarray, speed: float = 0.05, least: float = 5.0,
                  trim: float = 1.0) -> list[tuple[float, float]]:
    """Spans where the speed stays below `speed` (m/s) for more than `least` s, `trim` s cut off each end.

    Judged on RTKLIB's filter velocity, whatever velocity the windows use: its lag (0.14 s) is far
    below the trim, and the differenced positions are too noisy for a 0.05 m/s threshold.
    """
    still = np.hypot(ve, vn) < speed
    edges = np.flatnonzero(np.diff(np.concatenate([[0], still.astype(int), [0]])))
    spans = [(float(t[a]) + trim, float(t[b - 1]) - trim) for a, b in zip(edges[::2], edges[1::2])]
    return [(a, b) for a, b in spans if b - a > least - 2 * trim]


def bias_instability(imu, spans) -> tuple[dict[str, float], list]:
    """How much the biases move over the record, measured at rest: the gyro biases (deg/h) and the vertical
    accelerometer's (|f|, mg) at each span, and as instability the RMS of their changes from the first span.

    The std of each mean is the Allan deviation (allantools) at a third of its span. The horizontal
    accelerometer biases are not seen at rest (the car stands on different slopes): no instability for them.
    """
    import allantools

    deg_h = 180.0 / math.pi * 3600.0
    rows = []
    for a, b in spans:
        m = (imu.t > a) & (imu.t < b)
        rate = 1.0 / float(np.median(np.diff(imu.t[m])))
        sd = [allantools.oadev(imu.w[m, c], rate=rate, data_type="freq", taus=np.array([(b - a) / 3.0]))[1][0] * deg_h
              for c in range(3)]
        rows.append((a, b, imu.w[m].mean(axis=0) * deg_h, np.array(sd),
                     np.linalg.norm(imu.f[m].mean(axis=0)) / 9.80665e-3))
    d_w = np.array([r[2] - rows[0][2] for r in rows[1:]])
    d_f = np.array([r[4] - rows[0][4] for r in rows[1:]])
    inst = {f"bg_{i}": float(np.sqrt(np.mean(d_w[:, k] ** 2))) for k, i in enumerate("xyz")}
    inst["ba_z"] = float(np.sqrt(np.mean(d_f**2)))
    return inst, rows


def tilt_free_force(f: np.ndarray, w: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The specific force at rest less what the body's small rotations make of it (m/s^2, rows as `f`).

    At rest the body turns by ``theta(t) = int (w - mean w) dt`` (the gyros' rate less its mean, the bias and the
    Earth rate; trapezoid, mean removed) about its mean attitude, and the mean specific force ``f0`` seen in the
    turned body is ``f0 + f0 x theta`` to first order (``C = I - [theta x]`` carries the body vectors back): a car
    rocking on its springs moves ``fb_y`` by ``+g theta_x`` and ``fb_x`` by ``-g theta_y`` with z up. What is left
    is the accelerometers' own error plus ``f0 x`` the integrated gyro noise (so an upper bound still), plus the
    lateral acceleration of a sensor above the rocking axis (``h theta''``, small below the rocking frequency).
    """
    from casep._kernels import cumulative_trapezoid

    f, w, t = np.asarray(f, float), np.asarray(w, float), np.asarray(t, float)
    dw = w - w.mean(axis=0)
    theta = cumulative_trapezoid(dw, t)
    theta -= theta.mean(axis=0)
    return f - np.cross(f.mean(axis=0), theta)


def horizontal_instability(imu, spans, tilt: bool = True) -> dict[str, float]:
    """The horizontal accelerometer biases' instability at rest (mg): at each span the Allan deviation of ``fb_x``,
    ``fb_y`` at a third of the span (as :func:`bias_instability` takes each mean's std), the largest over the spans.

    The change between the stops cannot be read for them (the car stands on different slopes); within a stop the
    slope is fixed, but the car rocks on its springs with the engine running, and ``g`` times the rocking angle is
    in ``fb_x``, ``fb_y``. With `tilt` (default) the rotation the gyros measure is taken out first
    (:func:`tilt_free_force`); what is left still holds the integrated gyro noise: an upper bound of the bias's own.
    """
    import allantools

    out = {}
    for c, n in ((0, "ba_x"), (1, "ba_y")):
        sd = []
        for a, b in spans:
            m = (imu.t > a) & (imu.t < b)
            rate = 1.0 / float(np.median(np.diff(imu.t[m])))
            f = tilt_free_force(imu.f[m], imu.w[m], imu.t[m]) if tilt else imu.f[m]
            sd.append(allantools.oadev(f[:, c], rate=rate, data_type="freq",
                                       taus=np.array([(b - a) / 3.0]))[1][0] / 9.80665e-3)
        out[n] = float(max(sd))
    return out


def print_rest(imu, spans) -> dict[str, float]:
    """Print :func:`bias_instability` span by span; return the instability."""
    inst, rows = bias_instability(imu, spans)
    for a, b, wm, sd, fm in rows:
        print(f"  at rest {a:5.1f}-{b:5.1f} s: gyro rate " + ", ".join(f"{x:5.0f} +- {e:3.0f}" for x, e in zip(wm, sd))
              + f" deg/h (x, y, z), |f| {fm:.1f} mg")
    print("  bias instability measured at rest (RMS change from the first span): "
          + ", ".join(f"{n} {v:.1f}" for n, v in inst.items()))
    return inst


def _rms(result) -> float:
    """RMS of a fit's residuals over its axes and samples, m/s."""
    return float(np.sqrt(np.nanmean(np.asarray(result.residuals, float) ** 2)))


def figures(res, outdir: str) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    os.makedirs(outdir, exist_ok=True)
    names = res.names
    mean = np.array(res.consistency["weighted_mean"])
    t = np.array([w.t_start for w in res.windows])
    fig, axes = plt.subplots(2, 3, figsize=(10, 5.5), sharex=True)
    for k, (ax, n) in enumerate(zip(axes.ravel(), names)):
        x = [dict(zip(w.result.names, w.result.estimate))[n] for w in res.windows]
        s = [dict(zip(w.result.names, w.result.std))[n] for w in res.windows]
        ok = np.array([bool(w.result.success) for w in res.windows])
        ax.errorbar(t[ok], np.array(x)[ok], yerr=np.array(s)[ok], fmt="o", ms=3, capsize=2)
        ax.plot(t[~ok], np.array(x)[~ok], "x", color="grey", label="not compared (failed)")
        ax.axhline(mean[k], color="k", lw=0.8)
        unit = res.windows[0].result.units[list(res.windows[0].result.names).index(n)]
        ax.set_title(f"{n} ({unit}), chi2 {res.consistency['chi2_per_coefficient'][n]:.0f} / "
                     f"{res.consistency['used'] - 1}", fontsize=9)
    for ax in axes[1]:
        ax.set_xlabel("window start, s")
    fig.suptitle("car drive: biases per 30 s window (+- 1 std) and their weighted mean", fontsize=10)
    fig.tight_layout()
    p1 = os.path.join(outdir, "car-drive-windows.png")
    fig.savefig(p1, dpi=80)
    fig2, ax = plt.subplots(1, 2, figsize=(10, 3))
    dt = [dict(zip(w.result.names, w.result.estimate)).get("dt_trk", np.nan) for w in res.windows]
    ds = [dict(zip(w.result.names, w.result.std)).get("dt_trk", np.nan) for w in res.windows]
    ax[0].errorbar(t, dt, yerr=ds, fmt="o", ms=3, capsize=2)
    ax[0].set_title("tracking time offset dt_trk per window, ms", fontsize=9)
    ax[1].plot(t, [_rms(w.result) for w in res.windows], "o", ms=3)
    ax[1].set_yscale("log")
    ax[1].set_title("RMS of the fit residuals per window, m/s", fontsize=9)
    for a in ax:
        a.set_xlabel("window start, s")
    fig2.tight_layout()
    p2 = os.path.join(outdir, "car-drive-offset.png")
    fig2.savefig(p2, dpi=80)
    return [p1, p2]


def _clock_trend(windows) -> None:
    """A clock drift between IMU and GNSS would make the windows' dt_trk a straight line in time: its weighted
    slope (ppm, with std), the chi-square about a constant and about the line, and what it moves within a window."""
    t = np.array([w.t_start for w in windows])
    dt = np.array([dict(zip(w.result.names, w.result.estimate))["dt_trk"] for w in windows])
    sd = np.array([dict(zip(w.result.names, w.result.std))["dt_trk"] for w in windows])
    X = np.column_stack([np.ones_like(t), t - t.mean()]) / sd[:, None]
    coef, *_ = np.linalg.lstsq(X, dt / sd, rcond=None)
    slope_std = math.sqrt(np.linalg.inv(X.T @ X)[1, 1])
    chi_line = float(np.sum((X @ coef - dt / sd) ** 2))
    mean = np.sum(dt / sd**2) / np.sum(1 / sd**2)
    chi_const = float(np.sum(((dt - mean) / sd) ** 2))
    length = windows[0].t_end - windows[0].t_start
    print(f"  dt_trk against time (a clock drift): slope {coef[1] * 1e3:.1f} +- {slope_std * 1e3:.1f} ppm, chi2 "
          f"{chi_const:.1f} on {t.size - 1} dof about a constant, {chi_line:.1f} on {t.size - 2} about the line; "
          f"within one {length:.0f} s window the drift moves the offset by {abs(coef[1]) * length:.2f} ms "
          f"(each window fits its own dt_trk, std {sd.min():.1f}-{sd.max():.1f} ms)")


def save_windows(res, path: str) -> None:
    """Pickle plain data per window (span, success, names, estimate, covariance, residuals and their times, the
    S_V rows at the end) for analyses that need no new run."""
    import pickle

    rows = []
    for w in res.windows:
        r = w.result
        rows.append({"t_start": w.t_start, "t_end": w.t_end, "success": bool(r.success), "names": list(r.names),
                     "estimate": np.asarray(r.estimate, float),
                     "covariance": None if r.covariance is None else np.asarray(r.covariance, float),
                     "residuals": np.asarray(r.residuals, float),
                     "t": np.asarray(getattr(r, "t", np.array([])), float),
                     "sv_end": w.sv_end, "sv_names": list(w.sv_names),
                     "consider_gain": w.consider_gain, "consider_names": list(w.consider_names),
                     "noise": (r.diagnostics or {}).get("noise_model", (r.diagnostics or {}).get("noise"))})
    with open(path, "wb") as fh:
        pickle.dump({"names": list(res.names), "windows": rows, "left_out_std": LEFT_OUT_STD}, fh)
    print("saved", path)


def main() -> None:
    from casep.frames import LaunchSite
    from casep.navigation.imu import read_imu, regular_time
    from casep.workflows.windows import consider_rows, separate_windows, window_consistency

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=DATA)
    ap.add_argument("--out", default="car_drive_out", help="where the converted files go")
    ap.add_argument("--length", type=float, default=30.0, help="window length, s")
    ap.add_argument("--imu-shift", type=float, default=0.0, help="added to the IMU times, s (a clock-offset probe)")
    ap.add_argument("--figures", default=None, help="folder for the PNG figures")
    ap.add_argument("--model", default="strapdown6_window", help="the window model (instrument terms + phi0 + dv0)")
    ap.add_argument("--noise", default=None, help="casep's --noise for every window (default: its default path)")
    ap.add_argument("--std", default=None, choices=("model", "hac"), help="casep's --std for every window")
    ap.add_argument("--robust", default=None, help="casep's --robust for every window")
    ap.add_argument("--write-cut", default=None, help="write the converted cut here and stop")
    ap.add_argument("--cut", type=float, nargs=2, default=(0.0, 70.0))
    ap.add_argument("--imu-time", choices=("tags", "uniform"), default="tags",
                    help="IMU times: the logger's tags, or the uniform grid they jitter about (regular_time)")
    ap.add_argument("--velocity", choices=("rtklib", "positions", "same-satellites"), default="rtklib",
                    help="tracked velocity: RTKLIB's filter state, or differenced RTK positions (same-satellites: "
                         "not across a change of the satellite count or of the fix)")
    ap.add_argument("--imu-clock", choices=("stretch", "arrivals"), default="stretch",
                    help="IMU counter onto GPST: the data's linear stretch, or the tags' earliest arrivals")
    ap.add_argument("--simulate", type=int, default=None, metavar="SEED",
                    help="run the chain on the drive's simulated twin (car_drive_sim.py: its trajectory and noise, "
                         "constant known biases; IMU on the grid, velocity from positions) instead of the data")
    ap.add_argument("--sim-clock", type=float, nargs=2, default=(0.0, 0.0), metavar=("OFFSET_S", "PPM"),
                    help="--simulate: the twin's IMU times written this far off (the data's: -0.140 279)")
    ap.add_argument("--end", type=float, default=None, help="use the record up to this time only, s")
    ap.add_argument("--offset", type=float, default=0.0,
                    help="start the windows this much later, s (the same drive cut at other places)")
    ap.add_argument("--save", default=None, help="pickle each window's span, estimate, covariance, residuals here")
    ap.add_argument("--consider", default="strapdown33",
                    help="a model holding the terms the window model leaves out: each window's consider gain for the "
                         "comparison with P_c from LEFT_OUT_STD ('none': no gains)")
    ap.add_argument("--sim-left-out", action="store_true",
                    help="--simulate: add the left-out terms to the twin, drawn from N(0, P_c) with the seed")
    ap.add_argument("--sim-lever-arm", action="store_true",
                    help="--simulate: the twin's positions are the antenna's, LEVER_ARM_IMU from the IMU")
    ap.add_argument("--imu-instability", type=float, default=None, metavar="TAU_S",
                    help="each window's std with the IMU's bias instability of this correlation time, its size fitted "
                         "per window beside the tracking noise (separate_windows' imu_instability_tau)")
    ap.add_argument("--pool-instability", action="store_true",
                    help="with --imu-instability: one size for the run's windows, fitted by their summed restricted "
                         "likelihood (separate_windows' imu_instability_pool)")
    ap.add_argument("--instability-measure", default=None, choices=("vibration", "speed"),
                    help="with --pool-instability: the variances scaled per window by this fit-free measure "
                         "(separate_windows' imu_instability_measure)")
    ap.add_argument("--pool-white", nargs="?", const="both", default=None, choices=("both", "gyro"),
                    help="the IMU's white noise in motion sized once for the run's windows, per sensor, against the "
                         "density at rest (separate_windows' imu_white_pool; with --pool-instability jointly); "
                         "'gyro': the gyros' only, the accelerometers' at the density at rest")
    args = ap.parse_args()
    if args.write_cut:  # the IMU file gzipped (-9), as the test suite holds it
        import gzip
        import shutil

        imu_path, trk_path, _ = convert(args.data, args.write_cut, tuple(args.cut), args.velocity)
        with open(imu_path, "rb") as src, gzip.open(imu_path + ".gz", "wb", compresslevel=9) as dst:
            shutil.copyfileobj(src, dst)
        os.remove(imu_path)
        print(imu_path + ".gz", trk_path)
        return
    truth = None
    if args.simulate is not None:
        from car_drive_sim import simulate

        left_out = None
        if args.sim_left_out:
            rng = np.random.default_rng([args.simulate, 7])
            left_out = {n: float(rng.normal(0.0, sd)) for n, sd in LEFT_OUT_STD.items()}
        lever = np.array(list(LEVER_ARM_IMU.values())) if args.sim_lever_arm else None
        imu_path, trk_path, t_ref, truth = simulate(args.data, args.out, args.simulate, clock=tuple(args.sim_clock),
                                                    left_out=left_out, lever_arm=lever)
    else:
        imu_path, trk_path, t_ref = convert(args.data, args.out, velocity=args.velocity,
                                            imu_clock=args.imu_clock)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        imu = read_imu(imu_path)
        if args.imu_time == "uniform":
            grid = regular_time(imu.t)
            if grid is None:
                raise SystemExit("--imu-time uniform: the IMU's tags are not a jittered uniform grid")
            print(f"IMU tags about their uniform grid: RMS {np.std(imu.t - grid) * 1e3:.2f} ms, largest "
                  f"{np.max(np.abs(imu.t - grid)) * 1e3:.2f} ms; steps {np.min(np.diff(imu.t)) * 1e3:.1f}-"
                  f"{np.max(np.diff(imu.t)) * 1e3:.1f} ms, grid step {np.mean(np.diff(grid)) * 1e3:.4f} ms")
            imu.t = grid
        imu.t = imu.t + args.imu_shift
        if args.end is not None:
            imu = type(imu)(imu.t[imu.t <= args.end], imu.w[imu.t <= args.end], imu.f[imu.t <= args.end],
                            source=imu.source)
        import pandas as pd

        trk = pd.read_csv(trk_path)
        site = LaunchSite(float(trk.lat[0]), float(trk.lon[0]), float(trk.h[0]), 0.0, 0.0)
        moving = float(trk.t[np.hypot(trk.v_east, trk.v_north) > 0.3].iloc[0])
        c0 = time.process_time()
        options = {k: v for k, v in (("noise", args.noise), ("std", args.std), ("robust", args.robust))
                   if v is not None}
        res = separate_windows(imu, trk_path, site, (0.0, moving - 5.0), length=args.length,
                               start=moving + 1.0 + args.offset, model=args.model, fit_options=options,
                               consider=None if args.consider == "none" else args.consider,
                               imu_instability_tau=args.imu_instability, imu_instability_pool=args.pool_instability,
                               imu_instability_measure=args.instability_measure,
                               imu_white_pool={None: False, "both": True, "gyro": "gyro"}[args.pool_white])
        cpu = time.process_time() - c0
    kinds: dict[str, int] = {}
    first: dict[str, str] = {}
    for w in caught:
        kinds[w.category.__name__] = kinds.get(w.category.__name__, 0) + 1
        first.setdefault(w.category.__name__, str(w.message)[:300])
    print(f"{len(res.windows)} windows of {args.length:g} s from t = {moving + 1:.1f} s (GPST {t_ref:.0f} + t); "
          f"{cpu:.1f} CPU s; warnings {kinds}")
    for k, m in first.items():
        print(f"  e.g. {k}: {m}")
    w_max = float(np.max(np.linalg.norm(imu.w, axis=1)))
    print(f"tracked course rate / vertical gyro rate over the epochs above 3 m/s: "
          f"{course_rate_ratio(imu, trk, (0.0, moving - 5.0)):.4f}")
    print(f"lever arm antenna - IMU {np.linalg.norm(LEVER_ARM_CAR):.2f} m: |w x l| <= {w_max * 0.05:.3f} m/s "
          f"(largest rate {math.degrees(w_max):.1f} deg/s), not modelled")
    shown = tuple(n for n in res.names if n.startswith(("ba_", "bg_")))
    print(" start  passes course    rms   dt_trk ms     " + "  ".join(f"{n:>14s}" for n in shown))
    for w in res.windows:
        r = w.result
        e, s = dict(zip(r.names, r.estimate)), dict(zip(r.names, r.std))
        course = "" if w.heading_from_course_deg is None else f"{w.heading_from_course_deg:.1f}"
        print(f"{w.t_start:6.1f} {w.passes:4d} {course:>8s} {_rms(r):6.3f} {e['dt_trk']:6.1f}+-{s['dt_trk']:4.1f}  "
              + "  ".join(f"{e[n]:7.1f}+-{s[n]:5.1f}" for n in shown))
    if res.instability is not None:
        pooled_instability(res, imu, trk, (0.0, moving - 5.0))
    if args.imu_instability is not None:
        sizes = [((w.result.diagnostics.get("noise") or {}).get("imu") or {}).get("instability") or {}
                 for w in res.windows]
        print(f"IMU bias instability (tau {args.imu_instability:g} s) fitted per window, accelerometer mg / gyro "
              "deg/h: " + ", ".join(f"{w.t_start:.0f} s {s.get('accelerometer_mg', math.nan):.3g} / "
                                    f"{s.get('gyro_deg_h', math.nan):.3g}" for w, s in zip(res.windows, sizes)))
    c = res.consistency
    if "chi2" not in c:  # fewer than two windows succeeded: nothing to compare
        print(f"no comparison: {c.get('message')}; windows failed: "
              + "; ".join(f"{w.t_start:.1f} s: {w.result.message}" for w in res.windows if not w.result.success))
        if args.save:
            save_windows(res, args.save)
        return
    print(f"chi-square of the windows against their weighted mean: {c['chi2']:.1f} on {c['dof']} dof, "
          f"p = {c['p_value']:.3g}: {'agree' if c['agree'] else 'do NOT agree'}")
    print("  per coefficient (dof " + f"{c['used'] - 1}): " + ", ".join(f"{n} {v:.0f}"
                                                                       for n, v in c["chi2_per_coefficient"].items()))
    print("  weighted mean: " + ", ".join(f"{n} {v:.2f}" for n, v in zip(res.names, c["weighted_mean"])))
    print(f"  the std would have to be {math.sqrt(c['chi2'] / c['dof']):.1f} times larger for chi2 = dof")
    acc = window_consistency(res.windows, tuple(n for n in res.names if n.startswith("ba_")))
    gyr = window_consistency(res.windows, tuple(n for n in res.names if n.startswith("bg_")))
    clock = window_consistency(res.windows, ("dt_trk",))
    for what, cc in (("accelerometer biases", acc), ("gyro biases", gyr), ("tracking time offset dt_trk", clock)):
        print(f"  {what}: chi2 {cc['chi2']:.1f} on {cc['dof']} dof, p = {cc['p_value']:.3g}, weighted mean "
              + ", ".join(f"{v:.2f}" for v in cc["weighted_mean"]))
    _clock_trend(res.windows)
    if truth is not None:
        print("  true biases of the twin: " + ", ".join(f"{n} {truth[n]:g}" for n in res.names if n in truth)
              + " (the gyro's less the pad's mean rate is what the windows see)")
        ok = [w for w in res.windows if w.result.success]
        for n in (n for n in res.names if n.startswith("ba_")):  # the pad removes no accelerometer bias
            z = np.array([(dict(zip(w.result.names, w.result.estimate))[n] - truth[n])
                          / dict(zip(w.result.names, w.result.std))[n] for w in ok])
            print(f"  {n}: (estimate - truth) / std over the {z.size} windows: RMS {np.sqrt(np.mean(z**2)):.2f}, "
                  f"mean {np.mean(z):+.2f}")
    pos = read_rtklib_pos(os.path.join(args.data, "gnss_1934_sf.pos"))
    rest = [(a, b) for a, b in spans_at_rest(pos["t"] - t_ref, pos["ve"], pos["vn"]) if b <= imu.t[-1]]  # --end
    inst = None
    if len(rest) > 1 and truth is None:
        inst = print_rest(imu, rest)
        cc = window_consistency(res.windows, res.names, instability=inst)
        print(f"  with it: chi2 {cc['chi2']:.1f} on {cc['dof']} dof, p = {cc['p_value']:.3g}, predictions within "
              f"1 std {cc['within_1_std']:.2f}, within 2 std {cc['within_2_std']:.2f}")
        hor, rocking = horizontal_instability(imu, rest), horizontal_instability(imu, rest, tilt=False)
        print("  horizontal accelerometers at rest, the largest Allan deviation at a third of a stop, the rotation "
              "the gyros measure taken out: " + ", ".join(f"{n} {v:.2f} mg" for n, v in hor.items())
              + " (with the car's rocking left in: " + ", ".join(f"{n} {v:.2f}" for n, v in rocking.items()) + ")")
    if args.consider != "none":
        # the gains of the terms LEFT_OUT_STD holds (a larger consider model's others, lever arm and second
        # order, are kept in --save for car_drive_windows.py)
        held = [k for k, n in enumerate(res.windows[0].consider_names) if n in LEFT_OUT_STD]
        terms = tuple(res.windows[0].consider_names[k] for k in held)
        P_c = left_out_covariance(terms)
        for label, inst_k in [("", None)] + ([(" and the instability at rest", inst)] if inst is not None else []):
            gains = [g[:, held] for g in consider_rows(res.windows, res.names)]
            cc = window_consistency(res.windows, res.names, instability=inst_k, consider=(gains, P_c))
            print(f"  with the left-out terms ({len(terms)} of {args.consider}, P_c from LEFT_OUT_STD) as consider "
                  f"parameters{label}: chi2 {cc['chi2']:.1f} on {cc['dof']} dof, p = {cc['p_value']:.3g}, predictions "
                  f"within 1 std {cc['within_1_std']:.2f}, within 2 std {cc['within_2_std']:.2f}; per coefficient "
                  + ", ".join(f"{n} {v:.0f}" for n, v in cc["chi2_per_coefficient"].items()))
            for part in ("ba_", "bg_"):  # each sensor's three biases alone, with their rows of the same gains
                rows = [k for k, n in enumerate(res.names) if n.startswith(part)]
                sub = tuple(res.names[k] for k in rows)
                cp = window_consistency(res.windows, sub, instability=None if inst_k is None else
                                        {n: v for n, v in inst_k.items() if n in sub},
                                        consider=([g[rows] for g in gains], P_c))
                print(f"    {part}* alone: chi2 {cp['chi2']:.1f} on {cp['dof']} dof, p = {cp['p_value']:.3g}, "
                      f"predictions within 1 std {cp['within_1_std']:.2f}, within 2 std {cp['within_2_std']:.2f}")
    print(f"held-out prediction of dv at the window end ({c['prediction_pairs']} ordered pairs x 3 axes): "
          f"within 1 std {c['within_1_std']:.2f} (0.68 expected), within 2 std {c['within_2_std']:.2f} (0.95), "
          f"median |z| {c['median_abs_z']:.2f} (0.67)")
    if args.save:
        save_windows(res, args.save)
    if args.figures:
        for p in figures(res, args.figures):
            print("figure", p)


def pooled_instability(res, imu, trk, pad: tuple[float, float]) -> None:
    """Print the pooled instability's size, its interval, each window's measure, and what the size implies at the
    stops (the measure there, beyond the pad's: the vibration at rest, or the speed, 0)."""
    from casep.workflows.windows import vibration_power

    ins = res.instability
    got = ins.get("pooled")
    if got is None:
        print(f"pooled IMU bias instability: {ins.get('note')}")
        return
    if "white_variance_scale" in ins:
        (ka, kg), (ia, ig) = ins["white_variance_scale"], ins["white_variance_scale_interval"]
        print(f"pooled IMU white noise in motion, variance scale against the pad's density: accelerometers {ka:.3g} "
              f"({ia[0]:.3g}-{ia[1]:.3g}), gyros {kg:.3g} ({ig[0]:.3g}-{ig[1]:.3g}); -2 l_R {got['neg2_reml']:.1f} "
              f"against {ins['neg2_reml_at_rest_density']:.1f} at the pad's density (1, 1)"
              + ("" if ins["tau_s"] is not None else f"; {got['evaluations']} evaluations"))
    if ins["tau_s"] is None:
        return
    lo_a, hi_a = ins["interval_mg_per_unit"]
    lo_g, hi_g = ins["interval_deg_h_per_unit"]
    print(f"pooled IMU bias instability (tau {ins['tau_s']:g} s, measure {ins['measure']} [{ins['measure_unit']}]): "
          f"accelerometers {ins['accelerometer_mg_per_unit']:.3g} mg ({lo_a:.3g}-{hi_a:.3g}), gyros "
          f"{ins['gyro_deg_h_per_unit']:.3g} deg/h ({lo_g:.3g}-{hi_g:.3g}) per unit measure (std per sqrt(measure)); "
          f"-2 l_R {got['neg2_reml']:.1f} against {got['neg2_reml_without']:.1f} without; {got['evaluations']} "
          f"evaluations; not pooled: {ins['not_pooled']}")
    print("  per window, measure and size (mg / deg/h): " + ", ".join(
        f"{w.t_start:.0f} s {m:.3g} ({ins['accelerometer_mg_per_unit'] * math.sqrt(m):.2g} / "
        f"{ins['gyro_deg_h_per_unit'] * math.sqrt(m):.3g})" for w, m in zip(res.windows, ins["measures"])))
    if ins["measure"] == "vibration":
        t = np.asarray(trk.t, float)
        speed = np.hypot(trk.v_east.to_numpy(), trk.v_north.to_numpy())
        p0 = vibration_power(imu, *pad)
        print(f"  the pad {pad[0]:.1f}-{pad[1]:.1f} s: in-band power {p0:.4g} (m/s^2)^2")
        from car_drive_drift import stops

        for a, b in stops(trk):
            if b - a < 1.0 or b > imu.t[-1]:
                continue
            m = max(vibration_power(imu, a, b) - p0, 0.0)
            print(f"  stop {a:.1f}-{b:.1f} s (speed below {np.max(speed[(t >= a) & (t <= b)]):.2f} m/s): in-band "
                  f"power {vibration_power(imu, a, b):.4g}, beyond the pad's {m:.3g}: the pooled term there "
                  f"{ins['accelerometer_mg_per_unit'] * math.sqrt(m):.3g} mg, "
                  f"{ins['gyro_deg_h_per_unit'] * math.sqrt(m):.3g} deg/h")


if __name__ == "__main__":
    main()

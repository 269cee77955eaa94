"""How the car drive's biases move, measured at the stops and against what each window drove (a saved run).

Reads a run saved by ``car_drive.py --save`` and the converted files it wrote (``--out``), and prints:

- **the stops**: every span where the tracked horizontal speed stays below 0.1 m/s for 2 s or more (0.5 s cut
  off each end; the start and three stops in the drive), the mean gyro rates and specific force there with the
  Allan deviation (allantools) of each mean at a third of its span, and from them each channel's movement
  between the stops: the std ``tau`` of an independent offset per stop that brings the chi-square of the stop
  means about their weighted mean to its dof (0 when the means agree within their own std). The vertical
  accelerometer's bias is read as ``|f|`` (a tilt moves it by second order only); the horizontal ones need the
  car's pitch and roll, which the road's grade from the RTK heights gives only to about 10 mrad (10 mg): the
  script prints the forward one ``f_x + g grade`` with the grade before and after each stop.
- **what the windows would need**: per coefficient, the ``tau`` that brings the windows' chi-square about their
  weighted mean to its dof (the same rule), to hold against the stops' ``tau``, which is measured without them.
- **the biases in the drive, without the windows' fits**: the vertical gyro bias per window from the course
  (:func:`course_bias`), the pitch-axis gyro bias from the road's grade (:func:`pitch_bias`; too coarse to judge
  by, printed to show it) and the forward accelerometer bias from the tracked speed and grade
  (:func:`forward_bias`), each against the fit's value of the same combination; their scatter over the windows
  is an upper bound of how much the bias moves (it holds the method's own error too);
- the six biases' chi-square with each measured movement as the instability of
  :func:`casep.workflows.windows.window_consistency` (none; car_drive.py's RMS change at the stops; the stops'
  movement beyond their means' own std; the upper bounds from the drive);
- **the candidates** for what moves the windows' biases: each coefficient against a per-window quantity (a
  weighted line through the windows, its chi-square about the weighted mean and about the line, and the line
  fitted on every other window predicting the rest, as ``car_drive_windows.py`` does for the speed): the
  window's mid-time and a warm-up ``exp(-t / T)``; its mean speed; its mean yaw rate, signed and absolute; its
  mean heading's sine and cosine; and the accelerometer's vibration power in bands of the 100 Hz record
  (5-20, 20-35, 35-50 Hz; what a vibration above 50 Hz aliases into lands in these bands too).

    python benchmarks/car_drive_drift.py base.pkl --out out
"""

from __future__ import annotations

import argparse
import os
import pickle
import sys

import numpy as np

from casep.gravity import normal_gravity

sys.path.insert(0, os.path.dirname(__file__))
from car_drive_windows import INSTABILITY_AT_REST, SIX, _windows  # noqa: E402

G_MG = 9.80665e-3
DEG_H = 180.0 / np.pi * 3600.0


def excess_std(x: np.ndarray, s: np.ndarray) -> float:
    """The std ``tau`` of an independent offset per value that brings ``sum (x - xbar)^2 / (s^2 + tau^2)`` (xbar
    weighted by the same) to ``n - 1``; 0 when the values already agree within `s`."""

    def chi2(tau: float) -> float:
        w = 1.0 / (s**2 + tau**2)
        return float(np.sum(w * (x - np.average(x, weights=w)) ** 2))

    if chi2(0.0) <= x.size - 1:
        return 0.0
    lo, hi = 0.0, float(np.ptp(x)) + float(s.max())
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if chi2(mid) > x.size - 1 else (lo, mid)
    return 0.5 * (lo + hi)


def stops(trk, speed: float = 0.1, least: float = 2.0, trim: float = 0.5) -> list[tuple[float, float]]:
    """Spans where the tracked horizontal speed stays below `speed` for `least` s or more, `trim` cut off."""
    t = trk.t.to_numpy()
    still = np.hypot(trk.v_east.to_numpy(), trk.v_north.to_numpy()) < speed
    e = np.flatnonzero(np.diff(np.concatenate([[0], still.astype(int), [0]])))
    return [(float(t[a]) + trim, float(t[b - 1]) - trim) for a, b in zip(e[::2], e[1::2])
            if t[b - 1] - t[a] >= least]


def _grades(trk, t_mid: float) -> tuple[float, float]:
    """The road's grade (rise over distance travelled, mrad) over 3-15 m before and after the car's position at
    `t_mid` (nan where the car did not travel that far within 60 s)."""
    lat0 = np.radians(trk.lat.to_numpy()[0])
    e = np.radians(trk.lon.to_numpy()) * 6378137.0 * np.cos(lat0)
    n = np.radians(trk.lat.to_numpy()) * 6378137.0
    s = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(e), np.diff(n)))])
    t = trk.t.to_numpy()
    s0 = np.interp(t_mid, t, s)
    out = []
    for lo, hi in ((-15.0, -3.0), (3.0, 15.0)):
        q = (s - s0 > lo) & (s - s0 < hi) & (np.abs(t - t_mid) < 60.0)
        out.append(float(np.polyfit(s[q], trk.h.to_numpy()[q], 1)[0]) * 1e3 if q.sum() > 3 else float("nan"))
    return out[0], out[1]


def at_stops(imu, trk) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Print the stops' means; return per channel (``bg_*`` deg/h, ``ba_z`` as ``|f|`` mg) the means and std."""
    import allantools

    t = imu.t.to_numpy()
    w = imu[["w_x", "w_y", "w_z"]].to_numpy()
    f = imu[["fb_x", "fb_y", "fb_z"]].to_numpy()
    rows = []
    pad = (t > 0.0) & (t < float(trk.t[np.hypot(trk.v_east, trk.v_north) > 0.3].iloc[0]) - 5.0)
    print("the pad (the chain's, 0 s to 5 s before the car moves): gyro "
          + ", ".join(f"{x:5.0f}" for x in w[pad].mean(axis=0) * DEG_H) + " deg/h, removed before the windows")
    print("the stops (tracked speed below 0.1 m/s for 2 s or more, 0.5 s cut off each end):")
    for a, b in stops(trk):
        m = (t > a) & (t < b)
        rate = 1.0 / float(np.median(np.diff(t[m])))
        taus = np.array([(b - a) / 3.0])
        sw = [allantools.oadev(w[m, c], rate=rate, data_type="freq", taus=taus)[1][0] * DEG_H for c in range(3)]
        sf = [allantools.oadev(f[m, c], rate=rate, data_type="freq", taus=taus)[1][0] / G_MG for c in range(3)]
        wm, fm = w[m].mean(axis=0) * DEG_H, f[m].mean(axis=0) / G_MG
        norm_sd = float(np.sqrt(np.sum((fm / np.linalg.norm(fm) * np.array(sf)) ** 2)))
        before, after = _grades(trk, 0.5 * (a + b))
        k = int(np.argmin(np.abs(trk.t.to_numpy() - 0.5 * (a + b))))
        gamma = normal_gravity(float(trk.lat.iloc[k]), float(trk.h.iloc[k])) / 9.80665
        rows.append((wm - w[pad].mean(axis=0) * DEG_H, np.array(sw), float(np.linalg.norm(fm)) - gamma * 1e3,
                     norm_sd, (a, b)))
        print(f"  {a:6.1f}-{b:6.1f} s: gyro " + ", ".join(f"{x:5.0f} +- {e:3.0f}" for x, e in zip(wm, sw))
              + f" deg/h; f_x {fm[0]:6.1f} +- {sf[0]:.1f}, |f| {np.linalg.norm(fm):7.2f} +- {norm_sd:.2f} mg "
              f"(less normal gravity {rows[-1][2]:.2f}); "
              f"grade before {before:+5.1f}, after {after:+5.1f} mrad: f_x + g grade {fm[0] + before:6.1f} .. "
              f"{fm[0] + after:6.1f} mg")
    out = {f"bg_{a}": (np.array([r[0][k] for r in rows]), np.array([r[1][k] for r in rows]))
           for k, a in enumerate("xyz")}
    out["ba_z"] = (np.array([r[2] for r in rows]), np.array([r[3] for r in rows]))
    out["spans"] = (np.array([r[4] for r in rows]), np.array([]))
    return out


def stops_in_windows(ws: list[dict], stop: dict) -> None:
    """Print each window that holds a stop: its biases against the stop's (gyro: the stop's mean rate less the
    pad's, which the chain removed before the windows; ``ba_z``: ``|f|`` less normal gravity), and the z-score of
    the difference with both std."""
    for k, (a, b) in enumerate(stop["spans"][0]):
        for w in ws:
            if w["t_start"] <= a and b <= w["t_end"]:
                parts = []
                for n in ("ba_z", "bg_x", "bg_y", "bg_z"):
                    i = w["names"].index(n)
                    x, s = w["estimate"][i], np.sqrt(w["covariance"][i, i])
                    y, e = stop[n][0][k], stop[n][1][k]
                    z = (x - y) / np.hypot(s, e)
                    parts.append(f"{n} {x:.1f} +- {s:.1f} against {y:.1f} +- {e:.1f} (z {z:+.1f})")
                print(f"  window {w['t_start']:.1f}-{w['t_end']:.1f} s holds the stop {a:.1f}-{b:.1f} s: "
                      + "; ".join(parts))


def course_bias(ws: list[dict], imu, trk, ratio: float, fast: float = 3.0, straight: float = 3.0,
                least: float = 20.0, quiet: bool = False) -> np.ndarray:
    """Print each window's vertical gyro bias from the course, without the window's fit, against the fit's.

    The course (azimuth of the tracked velocity) turns as the car's heading when it does not slip, so over a span
    ``T`` the vertical rate's bias (the pad's mean rate removed, as in the chain) is ``b = (int w_up dt + k
    delta_course) / T`` with ``w_up`` the rate about the pad's vertical and ``k = -1 / ratio`` the vertical rate's
    scale against the course rate (``ratio`` the drive's course rate / vertical rate; 1 without the scale). The
    span is the window's, shrunk to epochs where the car goes faster than `fast` m/s and turns slower than
    `straight` deg/s (a slip angle changing in a turn would enter), at least `least` s; the course at each end is
    the mean over +-0.5 s. The fit's value is ``u . bg`` with ``u`` the pad's vertical in the body. Returns per
    window the course's bias (k = 1, k = -1 / ratio), the fit's and its std; `quiet` prints nothing."""
    t = imu.t.to_numpy()
    w = imu[["w_x", "w_y", "w_z"]].to_numpy()
    f = imu[["fb_x", "fb_y", "fb_z"]].to_numpy()
    pad = (t > 0.0) & (t < float(trk.t[np.hypot(trk.v_east, trk.v_north) > 0.3].iloc[0]) - 5.0)
    u = f[pad].mean(axis=0) / np.linalg.norm(f[pad].mean(axis=0))
    w_up = (w - w[pad].mean(axis=0)) @ u
    tt, ve, vn = trk.t.to_numpy(), trk.v_east.to_numpy(), trk.v_north.to_numpy()
    moving = np.hypot(ve, vn) > 1.0
    # unwrapped over the moving epochs only: a standing car does not turn, but its course is noise
    course = np.full(tt.size, np.nan)
    course[moving] = np.unwrap(np.arctan2(ve[moving], vn[moving]))
    rate = np.full(tt.size, np.inf)
    rate[moving] = np.degrees(np.gradient(course[moving], tt[moving]))
    good = (np.hypot(ve, vn) > fast) & (np.abs(rate) < straight)
    rows = []
    say = (lambda *a: None) if quiet else print
    say(f"the vertical gyro bias per window from the course (deg/h; pad's vertical u = {np.round(u, 3)}; spans "
          f"where the car goes faster than {fast:g} m/s and turns slower than {straight:g} deg/s):")
    say("  window     span used   delta course deg  from the course (k = 1, k = -1/ratio)  the fit's u.bg")
    for win in ws:
        ok = np.flatnonzero(good & (tt >= win["t_start"] + 0.5) & (tt <= win["t_end"] - 0.5))
        if ok.size < 2 or tt[ok[-1]] - tt[ok[0]] < least:
            continue
        a, b = tt[ok[0]], tt[ok[-1]]
        ca = np.nanmean(course[np.abs(tt - a) <= 0.5])
        cb = np.nanmean(course[np.abs(tt - b) <= 0.5])
        m = (t >= a) & (t <= b)
        integral = float(np.trapezoid(w_up[m], t[m]))
        b1 = (integral + (cb - ca)) / (b - a) * DEG_H
        bk = (integral - (cb - ca) / ratio) / (b - a) * DEG_H
        i = [win["names"].index(n) for n in ("bg_x", "bg_y", "bg_z")]
        fit, sd = float(u @ win["estimate"][i]), float(np.sqrt(u @ win["covariance"][np.ix_(i, i)] @ u))
        rows.append((b1, bk, fit, sd))
        say(f"  {win['t_start']:6.1f}  {a:6.1f}-{b:6.1f}  {np.degrees(cb - ca):+8.1f}  {b1:+8.0f} {bk:+8.0f}  "
              f"{fit:+8.0f} +- {sd:4.0f}")
    r = np.array(rows)
    say(f"  scatter (std) over {len(r)} windows: from the course {r[:, 0].std(ddof=1):.0f} (k = 1), "
          f"{r[:, 1].std(ddof=1):.0f} (k = -1/ratio); the fits' {r[:, 2].std(ddof=1):.0f} (their std "
          f"{r[:, 3].min():.0f}-{r[:, 3].max():.0f}); the fits less the course, chi-square on {len(r)} (the course's "
          f"as known): {float(np.sum(((r[:, 2] - r[:, 0]) / r[:, 3]) ** 2)):.1f} (k = 1), "
          f"{float(np.sum(((r[:, 2] - r[:, 1]) / r[:, 3]) ** 2)):.1f} (k = -1/ratio); with the course's scatter "
          f"(k = 1) added to each fit's variance "
          f"{float(np.sum((r[:, 2] - r[:, 0]) ** 2 / (r[:, 3] ** 2 + r[:, 0].var(ddof=1)))):.1f}; the fits about their "
          "weighted "
          f"mean {float(np.sum(((r[:, 2] - np.average(r[:, 2], weights=r[:, 3] ** -2.0)) / r[:, 3]) ** 2)):.1f} "
          f"on {len(r) - 1}")
    return r


def pitch_bias(ws: list[dict], imu, trk, fast: float = 3.0, straight: float = 3.0, steady: float = 0.5,
               least: float = 20.0) -> np.ndarray:
    """Print each window's pitch-axis gyro bias from the road's grade, without the window's fit, against the fit's.

    The car's pitch follows the grade of the road it drives on, ``atan(v_up / |v_h|)`` of the tracked velocity
    (plus the mount's tilt, constant), when it neither brakes nor speeds up (the suspension's pitch). So over a
    span ``T`` the bias of the rate about the car's right axis (the pad's mean rate removed) is ``(int w_right dt
    - delta grade) / T``. The right axis in the body is ``e_fwd x u`` (``u`` the pad's vertical, ``e_fwd`` the
    horizontal body direction of the specific force that follows the tracked along-track acceleration on straight
    stretches, a regression); what the roll rate leaks in through an error of ``e_fwd`` (the bank of the road
    changing) is not taken out. Spans as :func:`course_bias` and at each end an along-track acceleration below
    `steady` m/s^2; the grade at each end the mean over +-0.5 s."""
    from scipy.ndimage import uniform_filter1d

    t = imu.t.to_numpy()
    w = imu[["w_x", "w_y", "w_z"]].to_numpy()
    f = imu[["fb_x", "fb_y", "fb_z"]].to_numpy()
    pad = (t > 0.0) & (t < float(trk.t[np.hypot(trk.v_east, trk.v_north) > 0.3].iloc[0]) - 5.0)
    u = f[pad].mean(axis=0) / np.linalg.norm(f[pad].mean(axis=0))
    tt, ve, vn, vu = (trk[c].to_numpy() for c in ("t", "v_east", "v_north", "v_up"))
    speed = np.hypot(ve, vn)
    moving = speed > 1.0
    course = np.full(tt.size, np.nan)
    course[moving] = np.unwrap(np.arctan2(ve[moving], vn[moving]))
    rate = np.full(tt.size, np.inf)
    rate[moving] = np.degrees(np.gradient(course[moving], tt[moving]))
    along = np.gradient(speed, tt)
    # the body's forward direction: the horizontal specific force against the along-track acceleration
    f_s = uniform_filter1d(f, 25, axis=0)
    f_h = np.column_stack([np.interp(tt, t, c) for c in (f_s - np.outer(f_s @ u, u)).T])
    use = (speed > fast) & (np.abs(rate) < straight)
    X = np.column_stack([np.ones(use.sum()), along[use]])
    slope = np.linalg.lstsq(X, f_h[use], rcond=None)[0][1]
    e_fwd = slope / np.linalg.norm(slope)
    e_right = np.cross(e_fwd, u)
    x_h = np.array([1.0, 0.0, 0.0]) - u[0] * u
    mount = np.degrees(np.arccos(np.clip(-x_h @ e_fwd / np.linalg.norm(x_h), -1.0, 1.0)))
    w_right = (w - w[pad].mean(axis=0)) @ e_right
    grade = np.arctan2(vu, speed)
    good = use & (np.abs(along) < steady)
    rows = []
    print(f"the pitch-axis gyro bias per window from the road's grade (deg/h; right axis in the body "
          f"{np.round(e_right, 3)}, forward {mount:.1f} deg from the body's -x; ends faster than {fast:g} m/s, "
          f"turning slower than {straight:g} deg/s, along-track acceleration below {steady:g} m/s^2):")
    print("  window     span used   delta grade deg  from the grade  the fit's e_right.bg")
    for win in ws:
        ok = np.flatnonzero(good & (tt >= win["t_start"] + 0.5) & (tt <= win["t_end"] - 0.5))
        if ok.size < 2 or tt[ok[-1]] - tt[ok[0]] < least:
            continue
        a, b = tt[ok[0]], tt[ok[-1]]
        ga = grade[(np.abs(tt - a) <= 0.5) & moving].mean()
        gb = grade[(np.abs(tt - b) <= 0.5) & moving].mean()
        m = (t >= a) & (t <= b)
        bias = (float(np.trapezoid(w_right[m], t[m])) - (gb - ga)) / (b - a) * DEG_H
        i = [win["names"].index(n) for n in ("bg_x", "bg_y", "bg_z")]
        fit = float(e_right @ win["estimate"][i])
        sd = float(np.sqrt(e_right @ win["covariance"][np.ix_(i, i)] @ e_right))
        rows.append((bias, fit, sd))
        print(f"  {win['t_start']:6.1f}  {a:6.1f}-{b:6.1f}  {np.degrees(gb - ga):+8.2f}  {bias:+8.0f}  "
              f"{fit:+8.0f} +- {sd:4.0f}")
    r = np.array(rows)
    about = float(np.sum(((r[:, 1] - np.average(r[:, 1], weights=r[:, 2] ** -2.0)) / r[:, 2]) ** 2))
    print(f"  scatter (std) over {len(r)} windows: from the grade {r[:, 0].std(ddof=1):.0f}; the fits' "
          f"{r[:, 1].std(ddof=1):.0f} (their std {r[:, 2].min():.0f}-{r[:, 2].max():.0f}); the fits less the grade's, "
          f"chi-square {float(np.sum(((r[:, 1] - r[:, 0]) / r[:, 2]) ** 2)):.1f} on {len(r)}; the fits about their "
          f"weighted mean {about:.1f} on {len(r) - 1}")
    return r


def forward_bias(ws: list[dict], imu, trk, slowest: float = 2.0) -> np.ndarray:
    """Print each window's forward accelerometer bias from the tracking, without the window's fit, against the fit's.

    Over a window the mean specific force along the car's forward axis is the mean along-track acceleration
    (the speed's change over the window, from the tracked speeds at its ends) plus gravity along the road's grade
    (``g sin atan(v_up / |v_h|)``, the mean over the window's epochs; the grade under the car as it drove) plus
    the bias; the pad's own slope is a common offset, so only the windows' differences are judged (the fits less
    these, about their weighted mean: chi-square on n - 1). The forward axis in the body is that of
    :func:`pitch_bias`; the fit's value is ``e_fwd . ba``. Windows where the car goes slower than `slowest` m/s
    (the grade is then not read) are left out. Not taken out: the suspension's pitch under acceleration and
    the lateral force leaking through an error of the forward axis."""
    from scipy.ndimage import uniform_filter1d

    t = imu.t.to_numpy()
    f = imu[["fb_x", "fb_y", "fb_z"]].to_numpy()
    pad = (t > 0.0) & (t < float(trk.t[np.hypot(trk.v_east, trk.v_north) > 0.3].iloc[0]) - 5.0)
    u = f[pad].mean(axis=0) / np.linalg.norm(f[pad].mean(axis=0))
    tt, ve, vn, vu = (trk[c].to_numpy() for c in ("t", "v_east", "v_north", "v_up"))
    speed = np.hypot(ve, vn)
    along = np.gradient(speed, tt)
    rate = np.degrees(np.gradient(np.unwrap(np.arctan2(ve, vn)), tt))
    f_s = uniform_filter1d(f, 25, axis=0)
    f_h = np.column_stack([np.interp(tt, t, c) for c in (f_s - np.outer(f_s @ u, u)).T])
    use = (speed > 3.0) & (np.abs(rate) < 3.0)
    slope = np.linalg.lstsq(np.column_stack([np.ones(use.sum()), along[use]]), f_h[use], rcond=None)[0][1]
    e_fwd = slope / np.linalg.norm(slope)
    g = 9.80665
    rows = []
    print(f"the forward accelerometer bias per window from the tracking (mg; forward axis in the body "
          f"{np.round(e_fwd, 3)}; windows faster than {slowest:g} m/s throughout):")
    print("  window   mean f_fwd  speed change/T  g grade   the rest   the fit's e_fwd.ba")
    for win in ws:
        a, b = win["t_start"], win["t_end"]
        q = (tt >= a) & (tt <= b)
        if speed[q].min() < slowest:
            continue
        m = (t >= a) & (t <= b)
        F = float((f[m] @ e_fwd).mean())
        A = float(np.interp(b, tt, speed) - np.interp(a, tt, speed)) / (b - a)
        Gr = float(g * np.sin(np.arctan2(vu[q], speed[q])).mean())
        i = [win["names"].index(n) for n in ("ba_x", "ba_y", "ba_z")]
        fit = float(e_fwd @ win["estimate"][i])
        sd = float(np.sqrt(e_fwd @ win["covariance"][np.ix_(i, i)] @ e_fwd))
        rest = (F - A - Gr) / G_MG
        rows.append((rest, fit, sd))
        print(f"  {a:6.1f}  {F / G_MG:8.1f}  {A / G_MG:8.1f}  {Gr / G_MG:8.1f}  {rest:8.1f}   {fit:+6.1f} +- {sd:4.1f}")
    r = np.array(rows)
    d = r[:, 1] - r[:, 0]
    w = r[:, 2] ** -2.0
    w2 = 1.0 / (r[:, 2] ** 2 + r[:, 0].var(ddof=1))
    exact = float(np.sum(w * (d - np.average(d, weights=w)) ** 2))
    wide = float(np.sum(w2 * (d - np.average(d, weights=w2)) ** 2))
    print(f"  scatter (std) over {len(r)} windows: from the tracking {r[:, 0].std(ddof=1):.1f}, the fits' "
          f"{r[:, 1].std(ddof=1):.1f} (their std {r[:, 2].min():.1f}-{r[:, 2].max():.1f}); the fits less the "
          f"tracking's about their weighted mean: chi-square {exact:.1f} on {len(r) - 1} "
          f"({wide:.1f} with the tracking's "
          f"scatter added to each fit's variance); the fits about theirs "
          f"{float(np.sum(w * (r[:, 1] - np.average(r[:, 1], weights=w)) ** 2)):.1f} on {len(r) - 1}")
    return r


def _line(x: np.ndarray, y: np.ndarray, s: np.ndarray, fit: np.ndarray, test: np.ndarray) -> tuple[float, float]:
    """A weighted line fitted on `fit`; on `test` the chi-square about the weighted mean and about the line (a
    common offset free, so the slope alone is judged)."""
    X = np.column_stack([np.ones(fit.size), x[fit]])
    b = np.linalg.lstsq(X / s[fit, None], y[fit] / s[fit], rcond=None)[0]
    w = 1.0 / s[test] ** 2
    r = y[test] - b[1] * x[test]
    return (float(np.sum(w * (y[test] - np.average(y[test], weights=w)) ** 2)),
            float(np.sum(w * (r - np.average(r, weights=w)) ** 2)))


def per_window(ws: list[dict], imu, trk) -> dict[str, np.ndarray]:
    """Each window's candidate quantities (module notes)."""
    from scipy.signal import butter, sosfiltfilt

    t, tt = imu.t.to_numpy(), trk.t.to_numpy()
    rate = 1.0 / float(np.median(np.diff(t)))
    f = imu[["fb_x", "fb_y", "fb_z"]].to_numpy()
    ve, vn = trk.v_east.to_numpy(), trk.v_north.to_numpy()
    bands = {}
    for lo, hi in ((5.0, 20.0), (20.0, 35.0), (35.0, 0.0)):
        sos = butter(4, [lo, hi] if hi else lo, "bandpass" if hi else "highpass", fs=rate, output="sos")
        bands[f"{lo:.0f}-{hi or rate / 2:.0f} Hz"] = sosfiltfilt(sos, f, axis=0)
    out: dict[str, list[float]] = {}

    def put(name: str, value: float) -> None:
        out.setdefault(name, []).append(value)

    for w in ws:
        m = (t >= w["t_start"]) & (t <= w["t_end"])
        q = (tt >= w["t_start"]) & (tt <= w["t_end"])
        mid = 0.5 * (w["t_start"] + w["t_end"])
        put("time (s)", mid)
        for T in (60.0, 150.0):
            put(f"exp(-t/{T:.0f} s)", float(np.exp(-mid / T)))
        put("speed (m/s)", float(np.hypot(ve[q], vn[q]).mean()))
        yaw = np.degrees(imu.w_z.to_numpy()[m])
        put("yaw rate (deg/s)", float(yaw.mean()))
        put("|yaw rate| (deg/s)", float(np.abs(yaw).mean()))
        put("mean f_x (m/s^2)", float(f[m, 0].mean()))
        put("mean f_y (m/s^2)", float(f[m, 1].mean()))
        heading = np.arctan2(ve[q], vn[q])
        moving = np.hypot(ve[q], vn[q]) > 1.0
        put("sin heading", float(np.sin(heading[moving]).mean()))
        put("cos heading", float(np.cos(heading[moving]).mean()))
        for name, x in bands.items():
            put(f"f_z power {name} (m/s^2)^2", float(np.mean(x[m, 2] ** 2)))
            put(f"|f| power {name} (m/s^2)^2", float(np.mean(np.sum(x[m] ** 2, axis=1))))
    return {k: np.array(v) for k, v in out.items()}


def main() -> None:
    import pandas as pd

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", help="a pickle written by car_drive.py --save")
    ap.add_argument("--out", default="car_drive_out", help="the folder car_drive.py --out wrote imu.csv and "
                    "tracking.csv to")
    ap.add_argument("--imu-shift", type=float, default=-0.245, help="the shift the run gave the IMU's times (s)")
    ap.add_argument("--course-ratio", type=float, default=-0.9938, help="the drive's course rate / vertical gyro "
                    "rate (car_drive.py prints it)")
    ap.add_argument("--names", nargs="+", default=list(SIX), help="the coefficients to test")
    args = ap.parse_args()
    run = pickle.load(open(args.run, "rb"))
    imu = pd.read_csv(os.path.join(args.out, "imu.csv"))
    trk = pd.read_csv(os.path.join(args.out, "tracking.csv"))
    imu["t"] = imu.t + args.imu_shift
    stop = at_stops(imu, trk)
    ws = [w for w in run["windows"] if w["success"]]
    stops_in_windows(ws, stop)
    est = {n: np.array([w["estimate"][w["names"].index(n)] for w in ws]) for n in args.names}
    std = {n: np.array([np.sqrt(w["covariance"][w["names"].index(n), w["names"].index(n)]) for w in ws])
           for n in args.names}
    print(f"movement between the stops against what the {len(ws)} windows would need (tau: chi-square = dof):")
    for n in args.names:
        line = f"  {n}: the windows {excess_std(est[n], std[n]):6.1f}"
        if n in stop:
            x, s = stop[n]
            d = x[1:] - x[0]
            line += (f", the stops {excess_std(x, s):6.1f} (RMS change from the first stop "
                     f"{np.sqrt(np.mean(d**2)):.1f}; changes " + ", ".join(f"{v:+.1f}" for v in d) + ")")
        print(line)
    stop.pop("spans")
    moved = {n: excess_std(*stop[n]) for n in stop}
    wide = {n: excess_std(stop[n][0], stop[n][1] / np.sqrt(3.0)) for n in stop}
    print("  (with each stop mean's std taken as the Allan deviation at the whole span, a third of the above for "
          "white noise: " + ", ".join(f"{n} {v:.1f}" for n, v in wide.items()) + ")")
    course = course_bias(ws, imu, trk, args.course_ratio)
    for fast, straight in ((5.0, 3.0), (3.0, 1.5), (3.0, 6.0)):
        r = course_bias(ws, imu, trk, args.course_ratio, fast=fast, straight=straight, quiet=True)
        print(f"  the same with faster than {fast:g} m/s, turning slower than {straight:g} deg/s: {len(r)} windows, "
              f"scatter from the course {r[:, 0].std(ddof=1):.0f} (k = 1), {r[:, 1].std(ddof=1):.0f} (k = -1/ratio); "
              f"the fits less the course, chi-square {float(np.sum(((r[:, 2] - r[:, 0]) / r[:, 3]) ** 2)):.1f} "
              f"(k = 1)")
    pitch_bias(ws, imu, trk)
    fwd = forward_bias(ws, imu, trk)
    from casep.workflows.windows import window_consistency

    wins = _windows(run, {round(w["t_start"] / 30.0) for w in ws})
    for label, inst in (("none", None), ("the RMS change at the stops (car_drive.py)", INSTABILITY_AT_REST),
                        ("the stops' movement beyond their means' std", moved),
                        ("the same, means' std a third", wide),
                        ("in the drive, upper bounds: ba_x the forward bias's scatter, bg_z the course's, the rest "
                         "car_drive.py's", {**INSTABILITY_AT_REST, "ba_x": float(fwd[:, 0].std(ddof=1)),
                                            "bg_z": float(course[:, 0].std(ddof=1))})):
        c = window_consistency(wins, SIX, instability=inst)
        print(f"  six biases, instability {label}: chi2 {c['chi2']:.1f} on {c['dof']} dof, p = {c['p_value']:.2g}; "
              f"predictions within 1 / 2 std {c['within_1_std']:.2f} / {c['within_2_std']:.2f}; per coefficient "
              + ", ".join(f"{n} {v:.0f}" for n, v in c["chi2_per_coefficient"].items()))
    cand = per_window(ws, imu, trk)
    print("the candidates' correlation with the speed: " + ", ".join(
        f"{k} {np.corrcoef(x, cand['speed (m/s)'])[0, 1]:+.2f}" for k, x in cand.items() if k != "speed (m/s)"))
    every, even, odd = np.arange(len(ws)), np.arange(0, len(ws), 2), np.arange(1, len(ws), 2)
    print(f"each coefficient against each window's quantity (chi-square about the weighted mean -> about a line, "
          f"{len(ws) - 1} -> {len(ws) - 2} dof; split halves: the line fitted on the even windows judged on the odd, "
          f"and the other way round):")
    for n in args.names:
        y, s = est[n], std[n]
        for k, x in cand.items():
            c0, c1 = _line(x, y, s, every, every)
            e0, e1 = _line(x, y, s, even, odd)
            o0, o1 = _line(x, y, s, odd, even)
            flag = "  <- held out" if e1 < 0.7 * e0 and o1 < 0.7 * o0 else ""
            print(f"  {n:5s} {k:34s} r {np.corrcoef(x, y)[0, 1]:+.2f}  {c0:6.1f} -> {c1:6.1f}; halves "
                  f"{e0:5.1f} -> {e1:5.1f}, {o0:5.1f} -> {o1:5.1f}{flag}")


if __name__ == "__main__":
    main()

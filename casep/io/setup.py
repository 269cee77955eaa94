"""Set-up evidence of an Earth-fixed telemetry + tracking pair, measured when the files are read.

The launch site, azimuth, launch time and time scales the user states tie the tracking to the
platform frame, and a mistake in them leaves a fit that looks fine (a 4000 km site error: sigma
0.1 m/s). Two numbers betray it, and only the reader has the raw tracking (ECEF position and
Earth-relative velocity at the file's own time tags) to measure them:

- the telemetry velocity at its first sample against the **pad velocity** of the stated site and
  azimuth. On the pad the platform moves with the Earth: ``v_pad = C^T Rz(theta) (w x r_s)``
  (409 m/s due east in Florida). While the tracking shows the vehicle (nearly) at rest relative to
  the Earth, ``d = v_tel(t0) - v_pad - C u`` must vanish, ``u`` the tracking's Earth-relative velocity
  at t0 and ``C`` the ECEF-to-launch rotation: a 0.1 deg azimuth error turns v_pad by 0.1 deg (0.71 m/s
  in Florida), a 10 deg one by 71 m/s. The decision is a chi-square on 3 dof, ``d^T Cov(u)^-1 d``
  against :data:`PAD_ALPHA`, and ``|d|`` above :data:`PAD_VELOCITY_TOL` (module notes of
  :func:`_velocity_at` for ``Cov(u)`` under correlated tracking noise);
- the **first tracked position** against the site: the vehicle cannot be further from the pad
  than its speed times the time since launch (a boost speeds up monotonically).

A tracking taken as launch-inertial (``--tracking-frame launch``) beside a telemetry casep navigated from the pad
has no site of its own to check, but the pad's rotation still shows: :func:`earth_relative_tracking` finds a
tracking relative to the rotating Earth by ``dv`` at its first epochs being the pad's launch-inertial velocity
(:mod:`casep.workflows.imu_separate` records it as a set-up problem).

:func:`casep.io.files.read_flight_pair` records :func:`setup_evidence` in ``flight.meta["setup"]``;
the checks of a flight before estimation (:func:`casep.checks.plausibility.warn_setup`) warn with it.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from casep.io.pair import tracking_time

__all__ = ["setup_evidence", "header_site_problem", "HEADER_SITE_DEG", "HEADER_SITE_M", "earth_relative_tracking",
           "heading_turn", "heading_problem", "HEADING_TURN_LIMIT",
           "EARTH_RELATIVE_RATIO", "PAD_VELOCITY_TOL", "PAD_ALPHA",
           "PAD_REST_SPEED", "PAD_FIT_WINDOW", "PAD_NOISE_SPAN", "POSITION_TOL", "LAUNCH_GAP_TOL"]

#: ``|d| = |v_tel(t0) - v_pad - C u|`` above this (m/s) and significant (:data:`PAD_ALPHA`): the stated site,
#: azimuth or launch time does not match the telemetry. An INS aligned on the pad starts within mm/s of
#: v_pad; 0.2 m/s is a 0.03 deg azimuth error in Florida.
PAD_VELOCITY_TOL = 0.2
#: Level of the chi-square (3 dof) of ``d`` against the covariance of the tracking's velocity at t0. Its
#: variances are estimated (from a few seconds of correlated noise), so the statistic has heavier tails
#: than chi2_3: 1e-5 (25.9) keeps the false failures of a right set-up with pad GNSS noise Gauss-Markov
#: 0.1 m/s (tau 1 s) + 0.05 m/s white per axis at 0.1 % (benchmarks/setup_pad_check.py), where the norm
#: test failed 3 flights in 5; a 0.1 deg azimuth error in Florida gives a chi-square of about 50 and more.
PAD_ALPHA = 1e-5
#: Tracking Earth-relative speed below which the vehicle is taken to be on (or just leaving) the pad, m/s.
PAD_REST_SPEED = 30.0
#: Seconds of tracking after the first telemetry sample used to estimate its Earth-relative velocity there.
PAD_FIT_WINDOW = 2.0
#: Seconds of tracking from the first telemetry sample whose samples at rest (speed below
#: :data:`PAD_NOISE_REST`) give the tracking's velocity noise per sample (module notes of :func:`_velocity_at`).
PAD_NOISE_SPAN = 10.0
#: Tracking speed (m/s) below which a sample counts as at rest for the noise estimate.
PAD_NOISE_REST = 2.0
#: the median of chi-square on 1 degree of freedom: ``median(v^2) / CHI2_1_MEDIAN`` estimates ``sigma^2``
CHI2_1_MEDIAN = 0.45493642311957283
#: First tracked position farther from the site than (time since launch x speed) + this, m: wrong site.
POSITION_TOL = 2000.0
#: First telemetry sample this far (s) from the stated launch time: the time scales or the launch time are off.
LAUNCH_GAP_TOL = 60.0


def _velocity_at(t: np.ndarray, v: np.ndarray, t0: float) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Earth-relative tracking velocity at `t0` from a straight-line fit over :data:`PAD_FIT_WINDOW` s of
    samples from `t0` on, the std of each component and the fitted acceleration; None when the tracking does
    not cover `t0`.

    The std of the intercept ``c0 = w^T v`` (``w`` the first row of the fit's pseudo-inverse, weights summing
    to 1) under correlated noise, per axis, is the larger of

    - ``s^2 q kappa``: the least-squares variance (``s^2`` the residual variance, ``q = [(A^T A)^-1]_00``)
      times the AR(1) long-run factor ``kappa = (1 + rho) / (1 - rho)`` of the residuals
      (:func:`casep._kernels.ar1_long_run_factor`): right for noise correlated over much less than
      the window;
    - ``sigma^2``, the variance of one sample about a straight line over the samples at rest within
      :data:`PAD_NOISE_SPAN` s: noise correlated over the whole window (a GNSS velocity's Gauss-Markov
      part, tau of a second or more) moves all the window's samples together, so ``c0`` errs by about one
      sample's error, ``Var(c0) -> sigma^2 (sum w)^2 = sigma^2``, which the window's own residuals cannot
      show (the line takes it up). Of the two estimates of ``sigma^2`` the larger: the scatter about that
      line, and ``median(v^2) / m1`` about zero, the velocity at rest (``m1`` = :data:`CHI2_1_MEDIAN`),
      which keeps a Gauss-Markov part slower than :data:`PAD_NOISE_SPAN` (tau 20 s: the line alone failed
      5.9 % of right set-ups, ``benchmarks/setup_pad_check.py``) and which the few samples of a lift-off
      inside the span do not move.
    """
    from casep._kernels import ar1_long_run_factor

    period = float(np.median(np.diff(t))) if t.size > 1 else np.inf
    if not (t[0] <= t0 + period and t[-1] >= t0):
        return None
    use = (t >= t0 - period) & (t <= t0 + max(PAD_FIT_WINDOW, 4 * period))
    if use.sum() < 4:
        return None
    A = np.column_stack([np.ones(use.sum()), t[use] - t0])  # v ~ c0 + c1 (t - t0): c0 = v(t0)
    coef, *_ = np.linalg.lstsq(A, v[use], rcond=None)
    r = v[use] - A @ coef
    s2 = np.sum(r**2, axis=0) / max(use.sum() - 2, 1)
    kappa = ar1_long_run_factor(np.sum(r[1:] * r[:-1], axis=0), np.sum(r * r, axis=0))
    var = s2 * np.linalg.inv(A.T @ A)[0, 0] * kappa
    rest = (t >= t0 - period) & (t <= t0 + PAD_NOISE_SPAN) & (np.linalg.norm(v, axis=1) < PAD_NOISE_REST)
    if rest.sum() >= 8:  # sigma^2 of one sample about a line through the samples at rest
        B = np.column_stack([np.ones(rest.sum()), t[rest] - t0])
        rb = v[rest] - B @ np.linalg.lstsq(B, v[rest], rcond=None)[0]
        var = np.maximum(var, np.sum(rb**2, axis=0) / (rest.sum() - 2))
        # sigma^2 about the velocity at rest, zero: ``median(v^2) / m1`` (``m1`` the median of chi-square on 1
        # dof), which a Gauss-Markov part slower than the span keeps and the few samples after a lift-off in
        # the span do not move
        var = np.maximum(var, np.median(v[rest] ** 2, axis=0) / CHI2_1_MEDIAN)
    return coef[0], np.sqrt(var), coef[1]


def _clock_offset(fit: tuple, e: float, tol: float, t_first: float) -> dict | None:
    """The clock offset that explains a tracking already moving while the telemetry is still on the pad.

    At the first telemetry sample the telemetry velocity is the pad's (``e`` within `tol`) but the tracking
    shows the vehicle moving at ``s`` m/s relative to the Earth, accelerating at ``|a|``: its time tags are
    early by about ``s / |a|`` (``dt_trk ~ -s / |a|``: the tracking's clock ahead of the telemetry's, a
    time_shift or range time-tag error), which no site, azimuth or launch time explains. None otherwise.
    """
    v0, std, acc = fit
    s, a, std = float(np.linalg.norm(v0)), float(np.linalg.norm(acc)), float(np.max(std))
    if not (e <= tol and s > tol and a > 1.0):  # 1 m/s^2: a vehicle lifting off, not one sitting on the pad
        return None
    dt = -s / a
    return {"dt_trk_s": dt, "tracking_speed_m_s": s, "acceleration_m_s2": a,
            "message": f"at the first telemetry sample (t = {t_first:.10g} s) the telemetry velocity is the pad's "
                       f"(within {e:.3g} m/s) but the tracking already shows the vehicle moving at {s:.3g} +- "
                       f"{std:.2g} m/s relative to the Earth, accelerating at {a:.3g} m/s^2: the tracking's time "
                       f"tags look about {-dt * 1e3:.3g} ms early (dt_trk about {dt * 1e3:.3g} ms: its clock ahead "
                       "of the telemetry's; a time_shift or range time-tag offset, not the site or azimuth)"}


def _pad_mismatch(site: Any, t_start: float, v_pad: np.ndarray, e: np.ndarray, fit: tuple
                  ) -> tuple[float, float, bool]:
    """``|d|``, its chi-square and whether the pad check fails (module notes).

    ``d = e - C u`` (``e = v_tel(t0) - v_pad``, ``u`` the tracking's Earth-relative velocity at t0, ECEF), with
    ``C`` the ECEF-to-launch rotation at t0 (the columns: :func:`casep.frames.ecef_to_launch` of the unit
    velocities less the pad's) and ``chi2 = d^T (C diag(std^2) C^T)^-1 d``. Fails when ``|d| >``
    :data:`PAD_VELOCITY_TOL` and ``P(chi2_3 > chi2) <`` :data:`PAD_ALPHA`.
    """
    from casep._special import chi2_sf
    from casep.frames import ecef_to_launch

    u, std, _ = fit
    cols = ecef_to_launch(site, [t_start] * 3, [site.r_site] * 3, np.eye(3))[1] - v_pad  # row k: C e_k
    C = cols.T
    d = e - C @ u
    cov = (C * np.maximum(std, 1e-12) ** 2) @ C.T
    chi2 = float(d @ np.linalg.solve(cov, d))
    gap = float(np.linalg.norm(d))
    return gap, chi2, bool(gap > PAD_VELOCITY_TOL and chi2_sf(3, chi2) < PAD_ALPHA)


def setup_evidence(site: Any, t_tel: np.ndarray, v_tel: np.ndarray, t_trk: np.ndarray, r_ecef: np.ndarray,
                   v_ecef: np.ndarray, *, time_shift: float = 0.0, clock_drift: float = 0.0) -> dict:
    """The numbers of the set-up checks of an Earth-fixed telemetry + tracking pair (module notes).

    Parameters
    ----------
    site : casep.frames.LaunchSite
        As stated by the user (launch time in the tracking time scale).
    t_tel, v_tel : (N,), (N, 3) arrays
        Telemetry times (telemetry time scale) and launch-inertial velocity, s and m/s.
    t_trk, r_ecef, v_ecef : (M,), (M, 3), (M, 3) arrays
        Tracking times (tracking time scale), ECEF position and Earth-relative velocity, s, m, m/s.
    time_shift, clock_drift : float
        Tracking time minus telemetry time (at telemetry time 0), s, and the clocks' drift, ppm
        (:func:`casep.io.pair.telemetry_time`).

    Returns
    -------
    dict
        ``spans`` (telemetry and tracking, both time scales), ``pad`` (pad velocity, the telemetry's,
        their difference, the tracking's Earth-relative speed at the first telemetry sample and its
        std, the rotation about the vertical and the speed ratio between v_tel and v_pad),
        ``first_tracked`` (time since launch, distance from the site, reach), and ``problems``: the
        messages of the checks that fail (empty when all pass). A tracking that moves while the
        telemetry is on the pad is a clock offset, not a set-up problem: ``pad["clock_offset"]`` (its
        dt_trk and message; the reader warns with it, the fit's ``dt_trk`` estimates it).
    """
    from casep.frames import ecef_to_launch

    t_tel, v_tel, t_trk = (np.asarray(a, dtype=float) for a in (t_tel, v_tel, t_trk))
    r_ecef, v_ecef = np.asarray(r_ecef, dtype=float), np.asarray(v_ecef, dtype=float)
    t_start = float(tracking_time(t_tel[0], time_shift, clock_drift))  # the first telemetry sample, tracking scale
    v_pad = ecef_to_launch(site, [t_start], [site.r_site], [[0.0, 0.0, 0.0]])[1][0]
    e = v_tel[0] - v_pad
    fit = _velocity_at(t_trk, v_ecef, t_start)
    s_trk, s_std = (float(np.linalg.norm(fit[0])), float(np.max(fit[1]))) if fit is not None else (None, None)
    # horizontal (x, z) parts in launch axes: the turn of v_tel(t0) from v_pad about the vertical y
    h_tel, h_pad = v_tel[0][[0, 2]], v_pad[[0, 2]]
    turn = float(np.degrees(np.arctan2(h_pad[0] * h_tel[1] - h_pad[1] * h_tel[0], h_pad @ h_tel)))
    pad = {"t_s": t_start, "pad_velocity_m_s": v_pad.tolist(), "telemetry_velocity_m_s": v_tel[0].tolist(),
           "speed_relative_m_s": float(np.linalg.norm(e)), "tracking_speed_m_s": s_trk, "tracking_speed_std_m_s": s_std,
           "turn_about_vertical_deg": turn,
           "speed_ratio": float(np.linalg.norm(v_tel[0]) / np.linalg.norm(v_pad)) if np.any(v_pad) else None}
    since = float(t_trk[0] - site.t0)
    dist = float(np.linalg.norm(r_ecef[0] - site.r_site))
    reach = max(since, 0.0) * float(np.linalg.norm(v_ecef[0]))  # a boost speeds up: mean speed <= current
    first = {"t_s": float(t_trk[0]), "since_launch_s": since, "distance_from_site_m": dist, "reach_m": reach,
             "tolerance_m": POSITION_TOL}
    spans = {"telemetry_s": [float(t_tel[0]), float(t_tel[-1])], "tracking_s": [float(t_trk[0]), float(t_trk[-1])],
             "time_shift_s": float(time_shift), "launch_time_s": float(site.t0),
             "telemetry_start_after_launch_s": t_start - site.t0}
    where = (f"site ({site.lat_deg:.8g} deg, {site.lon_deg:.8g} deg, {site.h_m:.6g} m), azimuth {site.azimuth_deg:.8g} "
             f"deg, launch time {site.t0:.10g} s")
    problems = []
    if dist > reach + POSITION_TOL:
        swapped = _swapped_distance(r_ecef[0], site)
        cause = (f"its latitude and longitude swapped put it {swapped / 1e3:.4g} km from the site: latitude and "
                 "longitude swapped, in the tracking file or in --launch-site" if swapped <= reach + POSITION_TOL
                 else f"the stated {where} is wrong")
        problems.append(f"the first tracked position (t = {t_trk[0]:.10g} s, {since:.4g} s after the launch time) is "
                        f"{dist / 1e3:.6g} km from the stated launch site, where the vehicle could be at most "
                        f"{reach / 1e3:.4g} km away (its speed then times the time since launch) + "
                        f"{POSITION_TOL / 1e3:g} km: {cause}")
    if fit is not None and s_trk is not None and s_std is not None and s_trk < PAD_REST_SPEED:
        gap, chi2, fails = _pad_mismatch(site, t_start, v_pad, e, fit)
        tol = max(PAD_VELOCITY_TOL, 5.0 * s_std)  # the scale of "the telemetry is at the pad's velocity"
        pad.update(mismatch_m_s=gap, chi2=chi2, tolerance_m_s=PAD_VELOCITY_TOL, alpha=PAD_ALPHA,
                   tracking_velocity_std_m_s=fit[1].tolist())
        clock = _clock_offset(fit, float(np.linalg.norm(e)), tol, t_tel[0]) if fails else None
        if clock is not None:  # not the site's frame: the two clocks (the fit's dt_trk estimates it)
            pad["clock_offset"] = clock
        elif fails:
            hint = ""
            if s_trk < 1.0:
                hint = (f"; v_tel is v_pad turned by {turn:.4g} deg about the vertical"
                        + (f" (azimuth {site.azimuth_deg - turn:.6g} deg, not {site.azimuth_deg:.6g}?)"
                           if abs(turn) > 1e-3 else "")
                        + f", speed ratio {pad['speed_ratio']:.6g}"
                        + (" (a latitude or height error?)" if abs(pad["speed_ratio"] - 1) > 1e-3
                           else ""))
            problems.append(f"at the first telemetry sample (t = {t_tel[0]:.10g} s) the telemetry velocity differs by "
                            f"{np.linalg.norm(e):.4g} m/s from the pad velocity ({np.linalg.norm(v_pad):.6g} m/s) "
                            "of the "
                            f"stated {where}, while the tracking shows the vehicle at {s_trk:.3g} +- {s_std:.2g} m/s "
                            f"relative to the Earth (std per axis): the two velocities differ by {gap:.4g} m/s (> "
                            f"{PAD_VELOCITY_TOL:g} m/s; chi-square {chi2:.3g} on 3 dof, p < {PAD_ALPHA:g}){hint}. The "
                            "launch site, azimuth or launch time does not match the telemetry's frame")
    if abs(t_start - site.t0) > LAUNCH_GAP_TOL:
        problems.append(f"the telemetry starts {t_start - site.t0:.6g} s after the stated launch time "
                        f"{site.t0:.10g} s (tracking time scale; time_shift {time_shift:g} s): more than "
                        f"{LAUNCH_GAP_TOL:g} s. State the "
                        "launch time in the tracking file's time scale and how the time scales relate (time_shift)")
    return {"spans": spans, "pad": pad, "first_tracked": first, "problems": problems}


#: The stated launch site and the one a telemetry's header names (``casep navigate`` writes 12 significant digits)
#: differ when a latitude, longitude or azimuth differs by more than this (deg: 1.1 m on the ground; a frame turned
#: by it moves a 10 km/s velocity by 1.7 mm/s, below any tracking's noise, so a site stated to 5 decimals passes) ...
HEADER_SITE_DEG = 1e-5
#: ... or the height by more than this (m: gravity changes by 3e-6 m/s^2 per m).
HEADER_SITE_M = 1.0


def header_site_problem(site: Any, header: Any) -> str | None:
    """Why the stated launch site (`site`, the one the tracking is turned into the launch-inertial frame with) is not
    the one the telemetry was navigated in (`header`: :func:`casep.io.files.navigation_site`, ``casep navigate``'s
    header), or None. The two frames then differ: an azimuth 3 deg off turns a 4 km/s velocity by 210 m/s, which the
    fit takes for instrument errors far beyond any instrument's. The launch times are not compared (each in its
    own file's time scale)."""
    if header is None:
        return None
    diffs = []
    for name, a, b, tol, unit in (("latitude", site.lat_deg, header.lat_deg, HEADER_SITE_DEG, "deg"),
                                  ("longitude", site.lon_deg, header.lon_deg, HEADER_SITE_DEG, "deg"),
                                  ("height", site.h_m, header.h_m, HEADER_SITE_M, "m"),
                                  ("azimuth", site.azimuth_deg, header.azimuth_deg, HEADER_SITE_DEG, "deg")):
        d = ((a - b + 180.0) % 360.0) - 180.0 if name in ("longitude", "azimuth") else a - b
        if abs(d) > tol:
            diffs.append(f"{name} {a:.10g} against {b:.10g} {unit} ({d:+.4g} {unit})")
    if not diffs:
        return None
    return (f"the stated launch site is not the one the telemetry was navigated in (its header: {header.lat_deg:.10g} "
            f"deg, {header.lon_deg:.10g} deg, {header.h_m:.10g} m, azimuth {header.azimuth_deg:.10g} deg): "
            f"{'; '.join(diffs)}. The tracking is turned into the stated site's launch frame, the telemetry is in the "
            "header's: state the header's site (--launch-site), or navigate the IMU again at the stated one")


def _swapped_distance(r_ecef: np.ndarray, site: Any) -> float:
    """The distance (m) from the launch site of the ECEF position `r_ecef` with its geodetic latitude and
    longitude swapped (inf when the swapped latitude is no latitude)."""
    from casep.frames import ecef_to_geodetic, geodetic_to_ecef

    lat, lon, h, *_ = ecef_to_geodetic(np.asarray(r_ecef, float)[None, :], np.zeros((1, 3)))
    if abs(float(lon[0])) > 90.0:
        return float("inf")
    r, _ = geodetic_to_ecef(lon, lat, h, [0.0], [0.0], [0.0])
    return float(np.linalg.norm(r[0] - site.r_site))


#: A launch-frame tracking whose velocity at its first epochs differs from the navigated telemetry's by the pad's
#: Earth-rotation velocity ``v_pad``: ``|dv0|`` above :data:`PAD_REST_SPEED` and more than this many times
#: ``|dv0 - v_pad|`` (an INS aligned on the pad starts within metres per second of the truth).
EARTH_RELATIVE_RATIO = 10.0


def earth_relative_tracking(site: Any, t: np.ndarray, dv: np.ndarray) -> str | None:
    """Why a tracking taken as launch-inertial is relative to the rotating Earth, or None.

    A telemetry casep navigated from the pad (``casep separate --imu``) is launch-inertial: on the pad it moves
    with the Earth's rotation, ``v_pad`` (329 m/s at latitude 45 deg). A tracking file in the same frame does too,
    so ``dv = v_tel - v_trk`` near the launch is the INS error of a few seconds of flight: metres per second. A
    tracking relative to the Earth (a receiver's local-level velocity, launch-fixed axes, or a simulation without
    the Earth's rotation) leaves ``dv ~ v_pad`` instead. With ``dv0`` the straight-line fit of dv at the first
    epoch over :data:`PAD_FIT_WINDOW` s (:func:`_velocity_at`), the tracking is Earth-relative when ``|dv0| >``
    :data:`PAD_REST_SPEED` and ``|dv0| >`` :data:`EARTH_RELATIVE_RATIO` ``|dv0 - v_pad|``.

    Parameters
    ----------
    site : casep.frames.LaunchSite
        The launch site and time of the telemetry's launch-inertial frame, in the time scale of `t`.
    t, dv : (M,), (M, 3) arrays
        The observed tracking epochs (s) and ``v_tel - v_trk`` there (m/s, launch-inertial axes).
    """
    from casep.frames import ecef_to_launch

    t, dv = np.asarray(t, dtype=float), np.asarray(dv, dtype=float)
    if t.size < 4 or t[0] - site.t0 > PAD_NOISE_SPAN:  # the first epoch long after the launch: INS errors grown
        return None
    fit = _velocity_at(t, dv, float(t[0]))
    if fit is None:
        return None
    dv0 = fit[0]
    v_pad = ecef_to_launch(site, [float(t[0])], [site.r_site], [[0.0, 0.0, 0.0]])[1][0]
    gap, rest = float(np.linalg.norm(dv0)), float(np.linalg.norm(dv0 - v_pad))
    if not (gap > PAD_REST_SPEED and gap > EARTH_RELATIVE_RATIO * rest):
        return None
    vec = ", ".join(f"{x:.4g}" for x in dv0)
    pad = ", ".join(f"{x:.4g}" for x in v_pad)
    return (f"at the first tracking epoch (t = {t[0]:.10g} s, {t[0] - site.t0:+.3g} s from the launch time) the "
            f"telemetry and tracking velocities differ by ({vec}) m/s, |dv| {gap:.4g} m/s, where an INS aligned on the "
            f"pad is off by metres per second: that is the pad's velocity in the launch-inertial frame, ({pad}) m/s "
            f"(the Earth's rotation at latitude {site.lat_deg:.6g} deg), to within {rest:.3g} m/s. The tracking is "
            "relative to the rotating Earth (local-level or launch-fixed axes, or a simulation without the Earth's "
            "rotation), not launch-inertial as --tracking-frame launch takes it: give the receiver's Earth-fixed "
            "file (--tracking-frame ecef or geodetic), or its velocity turned into the launch-inertial frame "
            "(casep.frames.ecef_to_launch)")


#: The turn (deg) of the navigated horizontal velocity against the tracking's beyond which the heading the navigation
#: started from is taken as wrong: the 30 deg beyond which casep refuses a gyrocompassed heading
#: (``casep.navigation.alignment.GYROCOMPASS_LIMIT_RAD``). An INS aligned within a few degrees turns the horizontal
#: velocity by that much; the instrument errors of a MEMS IMU over a minute turn a 25 m/s horizontal velocity by a few
#: degrees, the tracking's errors of metres per second by several.
HEADING_TURN_LIMIT = 30.0
#: Earth-relative horizontal tracking speed (m/s) from which an epoch's direction is compared (a near-vertical rocket
#: has 25 m/s at burnout; below 10 m/s the tracking's errors of a few m/s leave the direction tens of degrees open).
HEADING_MIN_SPEED = 10.0
#: Seconds from the first such epoch over which the directions are compared: early, before the INS errors grow.
HEADING_SPAN = 60.0
#: Fewest epochs the comparison needs.
HEADING_MIN_EPOCHS = 5
#: The turn must explain the horizontal misfit: the RMS of ``u_tel - u_trk`` more than this many times the RMS of
#: ``u_tel - R(turn) u_trk``.
HEADING_RATIO = 3.0


def heading_turn(site: Any, t: np.ndarray, v_tel: np.ndarray, v_trk: np.ndarray, r: np.ndarray) -> dict | None:
    """The turn about the vertical between the navigated and the tracked horizontal velocity early in flight.

    With ``u`` the velocity relative to the rotating Earth (:func:`casep.frames.launch_to_ecef`) in the launch triad
    fixed to the Earth (``C^T v_E``), its horizontal part taken in its x-z plane (y is up at the pad), and the epochs
    after the launch time where the tracking's ``|u_h|`` is at least
    :data:`HEADING_MIN_SPEED`, over :data:`HEADING_SPAN` s from the first: the turn ``psi`` (deg, clockwise seen from
    above, as an azimuth) that best maps the tracked onto the navigated ``u_h`` (``atan2(sum a x b, sum a . b)``),
    and the RMS misfit as given and after the turn. An INS started from a heading ``e`` deg clockwise of the truth
    navigates a velocity turned by ``e``. (:func:`casep.navigation.alignment.course_rotation` takes the same angle,
    counterclockwise, from the velocity changes since the first common epoch, to correct a heading; a rocket's
    tracking that comes back in the coast changes by a metre per second there: here the start is the pad at rest.)

    Parameters
    ----------
    site : casep.frames.LaunchSite
        The launch site and time (time scale of `t`).
    t : (M,) array
        Observed tracking epochs, s.
    v_tel, v_trk, r : (M, 3) arrays
        Navigated and tracked velocity (m/s) and the tracked position (m), launch-inertial.

    Returns
    -------
    dict or None
        ``turn_deg``, ``misfit_m_s`` (as given), ``rest_m_s`` (after the turn), ``epochs``, ``span_s`` (first and
        last epoch), ``speed_m_s`` (median tracked horizontal speed); None when fewer than
        :data:`HEADING_MIN_EPOCHS` epochs qualify.
    """
    from casep.frames import launch_to_ecef

    t = np.asarray(t, float)
    C = site.C
    a = (launch_to_ecef(site, t, r, v_trk)[1] @ C)[:, [0, 2]]  # C^T v_E: the launch triad fixed to the Earth
    b = (launch_to_ecef(site, t, r, v_tel)[1] @ C)[:, [0, 2]]
    speed = np.linalg.norm(a, axis=1)
    finite = np.all(np.isfinite(a), axis=1) & np.all(np.isfinite(b), axis=1)
    ok = (t > site.t0) & (speed >= HEADING_MIN_SPEED) & finite
    if np.count_nonzero(ok) < HEADING_MIN_EPOCHS:
        return None
    ok &= t <= t[ok][0] + HEADING_SPAN
    a, b, tt = a[ok], b[ok], t[ok]
    # launch z is at the azimuth of x + 90 deg: (x, z) -> the angle clockwise from x
    psi = float(np.arctan2(np.sum(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]),
                           np.sum(a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1])))
    c, s = np.cos(psi), np.sin(psi)
    turned = np.column_stack([c * a[:, 0] - s * a[:, 1], s * a[:, 0] + c * a[:, 1]])
    return {"turn_deg": float(np.degrees(psi)), "misfit_m_s": float(np.sqrt(np.mean(np.sum((b - a) ** 2, axis=1)))),
            "rest_m_s": float(np.sqrt(np.mean(np.sum((b - turned) ** 2, axis=1)))), "epochs": int(tt.size),
            "span_s": [float(tt[0]), float(tt[-1])], "speed_m_s": float(np.median(speed[ok]))}


def heading_problem(site: Any, t: np.ndarray, v_tel: np.ndarray, v_trk: np.ndarray, r: np.ndarray,
                    heading: str) -> str | None:
    """Why the heading the navigation started from is wrong (:func:`heading_turn` beyond
    :data:`HEADING_TURN_LIMIT`, the turn explaining the misfit by :data:`HEADING_RATIO`), or None.

    `heading` says where the heading came from (``"--heading 120 (body y)"``, ``"gyrocompassing"``); the other
    arguments as :func:`heading_turn`.
    """
    h = heading_turn(site, t, v_tel, v_trk, r)
    if h is None or abs(h["turn_deg"]) <= HEADING_TURN_LIMIT or h["misfit_m_s"] <= HEADING_RATIO * h["rest_m_s"]:
        return None
    side = "clockwise" if h["turn_deg"] > 0 else "anticlockwise"
    return (f"the navigated horizontal velocity (relative to the Earth) is turned {abs(h['turn_deg']):.3g} deg {side} "
            f"(seen from above) from the tracking's over {h['epochs']} epochs, t = {h['span_s'][0]:.10g}.."
            f"{h['span_s'][1]:.10g} s (median horizontal speed {h['speed_m_s']:.3g} m/s): they differ by "
            f"{h['misfit_m_s']:.3g} m/s RMS, by {h['rest_m_s']:.3g} m/s once turned back (> "
            f"{HEADING_TURN_LIMIT:g} deg, the turn explaining more than {HEADING_RATIO:g} times the misfit). The "
            f"heading of the alignment ({heading}) is about {h['turn_deg']:+.3g} deg off: an azimuth of another "
            "body axis (--heading-axis), or of another reference (magnetic, grid); no instrument error of a navigating "
            "IMU turns the velocity so far")

"""The strapdown navigation solution from raw IMU data: align on the pad, then integrate.

:func:`navigate` levels and heads the IMU over the pad window (:mod:`casep.navigation.alignment`),
starts from the pad at rest on the Earth at the window's first sample (its launch-inertial
position and velocity from :func:`casep.frames.ecef_to_launch`: before the launch time ``t0`` the
pad is not at the origin, and on the pad ``v_tel`` is the Earth's rotation, ``omega_E x r``), and
integrates (:mod:`casep.navigation.strapdown`) to the end of the record. The attitude at the start
is the pad's: ``C_L^b = C^T Rz(theta) C C_T^b`` (the Earth-fixed triad seen from L at that time).
"""

from __future__ import annotations

import warnings

import numpy as np

from casep.frames import LaunchSite
from casep.navigation.alignment import Alignment
from casep.navigation.imu import DTHETA_COLUMNS, RATE_COLUMNS, ImuData
from casep.navigation.result import NavigationResult

__all__ = ["navigate", "navigate_from", "pad_state", "check_pad_drift", "pad_noise_speed"]


def navigate(imu: ImuData, site: LaunchSite, align_window: tuple[float, float], *, heading_deg: float | None = None,
             heading_axis: str = "x", check_pad: bool = True, accel_bias_tolerance: float | None = None,
             gyro_bias_tolerance: float | None = None) -> NavigationResult:
    """Align on the pad over `align_window` and navigate in the launch-inertial frame to the end of `imu`.

    Parameters
    ----------
    imu : ImuData
        :func:`casep.navigation.imu.read_imu` (or an :class:`ImuData` checked by ``check_imu``).
    site : LaunchSite
        The launch point, azimuth and launch time ``t0`` defining the frame (in the IMU's time scale).
    align_window : (T1, T2)
        The span at rest on the pad, s; the navigation starts at its first sample.
    heading_deg, heading_axis
        See :func:`casep.navigation.alignment.align` (None: gyrocompassing, with a warning).
    accel_bias_tolerance : float, optional
        See :func:`casep.navigation.alignment.align` (None: its default, 80 mg).
    gyro_bias_tolerance : float, optional
        The gyro bias (rad/s) the mean pad rate may reach (:func:`casep.navigation.alignment.large_pad_rate`;
        None: :data:`casep.navigation.alignment.MAX_PAD_RATE`, 2.9 deg/s).
    check_pad : bool, optional
        Warn when the navigated speed over the window exceeds what the sensors allow at rest
        (:func:`check_pad_drift`); False for a simulator's own INS, whose pad is at rest by construction.

    Returns
    -------
    NavigationResult
        The strapdown telemetry from ``T1`` on: attitude, measured body rate and specific force,
        launch-inertial velocity and position.

    Raises
    ------
    ValueError
        The alignment's (:func:`casep.navigation.alignment.align`), and with `check_pad` a pad rate beyond any
        navigating gyro's bias with a navigated speed beyond what the sensors allow at rest (:func:`check_pad_drift`).
    """
    q0, r0, v0, t_s, alignment = pad_state(imu, site, align_window, heading_deg=heading_deg,
                                           heading_axis=heading_axis, accel_bias_tolerance=accel_bias_tolerance,
                                           gyro_bias_tolerance=gyro_bias_tolerance)
    res = navigate_from(imu, site, q0, r0, v0, t_start=t_s)
    res.alignment = alignment
    res.align_window = (float(align_window[0]), float(align_window[1]))
    if check_pad:
        check_pad_drift(res, imu, site, gyro_bias_tolerance=gyro_bias_tolerance)
    return res


#: The pad check's factor on the noise-driven speed (its std) and on the bias allowance's tilt.
PAD_NOISE_FACTOR, PAD_BIAS_FACTOR = 5.0, 3.0


def pad_noise_speed(s_f: np.ndarray, s_w: np.ndarray, dt: float, T, g: float) -> np.ndarray:
    """The speed a vehicle at rest navigates to after `T` s (scalar or array) from the sensors' white noise alone,
    m/s: ``sqrt(sum_i s_f,i^2 dt T + g^2 s_w,i^2 dt T^3 / 3)``, the accelerometers' velocity random walk and the gyros'
    angle random walk turned into a velocity by gravity (`s_f` (3,) m/s^2 and `s_w` (3,) rad/s per sample, step
    `dt` s, gravity `g` m/s^2): the noise term of :func:`check_pad_drift` and of the static hold's pad check
    (:func:`casep.workflows.judging.judge_pad_hold`)."""
    T = np.asarray(T, dtype=float)
    a = float(np.sum(np.asarray(s_f, dtype=float) ** 2)) * dt
    w = g**2 * float(np.sum(np.asarray(s_w, dtype=float) ** 2)) * dt / 3.0
    return np.sqrt(a * T + w * T**3)


def check_pad_drift(res: NavigationResult, imu: ImuData, site: LaunchSite, *, warn: bool = True,
                    gyro_bias_tolerance: float | None = None) -> None:
    """Warn (:class:`casep.exceptions.AlignmentWarning`) when the navigated speed over the pad window exceeds what
    the sensors allow a vehicle at rest.

    Over the window of length ``T`` (median step ``dt``, per-sample std ``s_f``, ``s_w`` per axis:
    :func:`casep.checks.tracking_quality.white_sample_std`), the levelling cancels the accelerometers' mean; what is
    left is their white noise's velocity random walk ``s_f sqrt(dt T)``, the gyros' angle random walk turned
    into a velocity by gravity, ``g s_w sqrt(dt) T^1.5 / sqrt 3``, and a horizontal gyro bias ``b``
    (:func:`casep.navigation.alignment.gyro_bias_allowance`) tilting it, ``g b T^2 / 2``::

        allowed = 5 sqrt(sum_i s_f,i^2 dt T + g^2 s_w,i^2 dt T^3 / 3) + 3 g b T^2 / 2 + | |f_mean| - g | T

    (the last term: the levelling cancels the accelerometers' mean across the vertical only; the part along it,
    an accelerometer bias the alignment accepted, drives the speed as ``b T``).

    Beyond it the vehicle moved in the window, or a gyro bias far beyond a navigation gyro's tilts the
    levelled attitude within seconds: the solution drifts as ``t^2`` from there on. When, besides, the mean pad
    rate is one :func:`casep.navigation.alignment.large_pad_rate` refuses (rates in deg/s read as rad/s, or a
    gyro bias beyond `gyro_bias_tolerance`, default :data:`~casep.navigation.alignment.MAX_PAD_RATE`) the navigation
    is worthless from its first seconds: a ``ValueError`` naming the rate columns, the window's rows and the numbers
    (the same rule as the pad rate's warning, :func:`casep.navigation.alignment.align`); a bias within the
    tolerance is the warning. ``warn=False``: that error only (a separation from the raw record, whose passes
    estimate the gyro biases that tilt the pad).
    """
    from casep.checks.tracking_quality import white_sample_std
    from casep.exceptions import AlignmentWarning
    from casep.navigation.alignment import gyro_bias_allowance, large_pad_rate

    t1, t2 = res.align_window
    sel = (imu.t >= t1) & (imu.t <= t2)
    if int(sel.sum()) < 3:
        return
    T, dt = t2 - t1, float(np.median(np.diff(imu.t[sel])))
    g = res.alignment.g_pad if res.alignment is not None else 9.80665
    noise = float(pad_noise_speed(white_sample_std(imu.f[sel]), white_sample_std(imu.w[sel]), dt, T, g))
    bias = g * gyro_bias_allowance(site) * T**2 / 2.0
    # the levelling cancels the accelerometers' mean across the vertical, not along it: |f| - g accepted by the
    # alignment (an accelerometer bias, casep.navigation.alignment.ACCEL_BIAS_TOLERANCE) drives the speed as b T
    vertical = abs(float(np.linalg.norm(res.alignment.f_mean)) - g) * T if res.alignment is not None else 0.0
    allowed = PAD_NOISE_FACTOR * noise + PAD_BIAS_FACTOR * bias + vertical
    drift = res.pad_drift()
    if drift > allowed:
        w_mean = imu.w[sel].mean(axis=0)
        rate = float(np.linalg.norm(w_mean))
        f_mean = res.alignment.f_mean if res.alignment is not None else imu.f[sel].mean(axis=0)
        large = large_pad_rate(w_mean, f_mean / np.linalg.norm(f_mean), imu.w, gyro_bias_tolerance)
        if large is not None and large[0]:
            rows = np.flatnonzero(sel)
            cols = ", ".join(DTHETA_COLUMNS if imu.kind == "increments" else RATE_COLUMNS)
            raise ValueError(f"--align {t1:g} {t2:g}: {imu.source}: columns {cols}, rows {rows[0] + 1}-"
                             f"{rows[-1] + 1}: mean body rate {rate:.4g} rad/s ({np.degrees(rate):.4g} deg/s) over "
                             f"the {T:.3g} s window declared at rest, and the navigated speed reaches {drift:.3g} m/s "
                             f"in it, above the {allowed:.3g} m/s its sensors allow: the navigation is wrong from its "
                             f"first seconds: {large[1]}; or the vehicle turned in the window (give a window at rest)")
        if not warn:
            return
        # the pad's own mean rate less the Earth rate in body axes, across the vertical: its horizontal gyro bias
        from casep.rotations import quat_to_dcm

        b_rate = imu.w[sel].mean(axis=0) - quat_to_dcm(res.q[0]).T @ site.earth_rate
        up = res.alignment.f_mean / np.linalg.norm(res.alignment.f_mean) if res.alignment is not None else None
        own = float(np.linalg.norm(b_rate - (b_rate @ up) * up)) if up is not None else 0.0
        tilt = g * own * T**2 / 2.0
        why = (f"the pad's own mean horizontal rate less the Earth rate, {own:.3g} rad/s (a gyro bias of that size, "
               f"{own / gyro_bias_allowance(site):.3g} x that allowance), "
               f"tilts it by {tilt:.2g} m/s x {PAD_BIAS_FACTOR:g}: the vehicle need not have moved; "
               "the solution drifts as t^2 from there (`casep separate --imu` estimates the gyro biases)"
               if drift <= PAD_NOISE_FACTOR * noise + PAD_BIAS_FACTOR * tilt + vertical else
               "the vehicle moved in the window, or a gyro bias tilts the attitude within seconds and the solution "
               "drifts as t^2 from there")
        warnings.warn(f"--align {t1:g} {t2:g}: {imu.source}: the navigated speed reaches {drift:.3g} m/s within the "
                      f"{T:.3g} s window declared at rest, above the {allowed:.3g} m/s its sensors allow (the noise's "
                      f"random walks {noise:.2g} m/s x {PAD_NOISE_FACTOR:g}, a gyro bias of "
                      f"{gyro_bias_allowance(site):.2g} rad/s, the allowance of a gyro that finds north, tilting it "
                      f"{bias:.2g} m/s x {PAD_BIAS_FACTOR:g}"
                      + (f", the vertical accelerometer bias {vertical:.2g} m/s" if vertical else "") + "); "
                      f"mean pad rate {rate:.3g} rad/s: {why}", AlignmentWarning, stacklevel=2)


def pad_state(imu: ImuData, site: LaunchSite, align_window: tuple[float, float], *, heading_deg: float | None = None,
              heading_axis: str = "x", accel_bias_tolerance: float | None = None, as_given: bool = True,
              gyro_bias_tolerance: float | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, Alignment]:
    """The state :func:`navigate` starts from: ``(q0, r0, v0, t_start, alignment)``.

    The attitude (Hamilton, scalar first, body -> launch-inertial), position (m) and velocity (m/s) of
    the pad at rest at the alignment window's first sample ``t_start``, and the alignment itself
    (:func:`casep.navigation.alignment.align`; arguments as :func:`navigate`; `as_given` False for a record an
    estimate has corrected, as :func:`~casep.navigation.alignment.align` takes it).
    """
    from casep.frames import ecef_to_launch, ecef_to_launch_vector
    from casep.navigation.alignment import ACCEL_BIAS_TOLERANCE, align
    from casep.navigation.strapdown import dcm_to_quat

    if not isinstance(site, LaunchSite):
        raise TypeError(f"`site` must be a casep.frames.LaunchSite, got {type(site).__name__}")
    cols = ", ".join(DTHETA_COLUMNS if imu.kind == "increments" else RATE_COLUMNS)
    tol = ACCEL_BIAS_TOLERANCE if accel_bias_tolerance is None else accel_bias_tolerance
    alignment = align(imu.t, imu.w, imu.f, align_window, site, heading_deg=heading_deg, heading_axis=heading_axis,
                      accel_bias_tolerance=tol, as_given=as_given, gyro_bias_tolerance=gyro_bias_tolerance,
                      rates_in=f"{imu.source}, columns {cols}")
    if as_given:
        _warn_outside_record(imu, align_window)
    t_s = imu.t[np.searchsorted(imu.t, align_window[0])][None]
    r0, v0 = ecef_to_launch(site, t_s, site.r_site[None, :], np.zeros((1, 3)))
    axes_e = (site.C @ alignment.C_tb).T  # rows: the body axes in ECEF at rest on the pad
    C_lb = ecef_to_launch_vector(site, np.repeat(t_s, 3), axes_e).T  # columns: the body axes in L at t_s
    return dcm_to_quat(C_lb), r0[0], v0[0], float(t_s[0]), alignment


def navigate_from(imu: ImuData, site: LaunchSite, q0: np.ndarray, r0: np.ndarray, v0: np.ndarray, *,
                  t_start: float | None = None) -> NavigationResult:
    """Navigate from a known state at the sample `t_start` (default: the first) to the end of `imu`.

    Parameters
    ----------
    imu : ImuData
    site : LaunchSite
        The frame (launch point, azimuth, ``t0``).
    q0 : (4,) array_like
        Attitude at `t_start`: Hamilton quaternion, scalar first, body -> launch-inertial.
    r0, v0 : (3,) array_like
        Launch-inertial position (m) and velocity (m/s) at `t_start`.
    t_start : float, optional
        A sample time of `imu`, s.

    Returns
    -------
    NavigationResult
        Without an alignment (``alignment`` None).
    """
    from casep.navigation.imu import steps_said
    from casep.navigation.strapdown import (
        Increments,
        body_velocity_increments,
        increments_from_deltas,
        increments_from_rates,
        launch_gravitation,
        propagate_attitude,
        propagate_translation,
        quat_rotate,
    )

    i0 = 0 if t_start is None else int(np.searchsorted(imu.t, t_start))
    if i0 >= len(imu.t) - 1:
        raise ValueError(f"t_start {t_start:g} s leaves fewer than 2 samples of {imu.source} (ends at {imu.t[-1]:g} s)")
    q0 = np.asarray(q0, float)
    if q0.shape != (4,) or abs(np.linalg.norm(q0) - 1.0) > 1e-6:
        raise ValueError(f"q0 must be a unit quaternion (4,), got {q0!r}")
    t = imu.t[i0:]
    if imu.kind == "increments":
        if imu.dtheta is None or imu.dv is None:
            raise ValueError(f"{imu.source}: increments without dtheta and dv (read it with read_imu or check_imu)")
        full = increments_from_deltas(imu.dtheta[i0:], imu.dv[i0:])  # row i0 is the first interval's previous one
        inc = Increments(full.dtheta[1:], full.dv[1:], full.coning[1:], full.sculling[1:])
    else:
        inc = _bridged(increments_from_rates(t, imu.w[i0:], imu.f[i0:]), t, imu.w[i0:], imu.f[i0:])
    q = propagate_attitude(q0, inc)
    dV = quat_rotate(q[:-1], body_velocity_increments(inc))
    r, v, passes = propagate_translation(t, dV, np.asarray(r0, float), np.asarray(v0, float),
                                         launch_gravitation(site))
    return NavigationResult(t=t, q=q, fb=imu.f[i0:], w=imu.w[i0:], v=v, r=r, site=site, alignment=None,
                            kind=imu.kind, gaps=imu.gaps, passes=passes, source=imu.source,
                            align_window=(float(t[0]), float(t[0])),
                            valid=None if imu.clipped is None else ~np.asarray(imu.clipped[i0:], bool),
                            steps_said=steps_said(imu))


def _bridged(inc, t: np.ndarray, w: np.ndarray, f: np.ndarray):
    """`inc` with each gap's increments those of its bridge (:func:`casep.navigation.imu.bridge_gaps`: a cubic
    fitted to the samples either side, not the cubic through the four nearest, which amplifies their noise
    across a long gap), and the coning and sculling corrections of the steps it touches recomputed."""
    from casep.navigation.imu import bridge_gaps
    from casep.navigation.strapdown import Increments, increments_from_deltas

    br = bridge_gaps(t, w, f)
    if not br.steps.size:
        return inc
    dtheta, dv = inc.dtheta.copy(), inc.dv.copy()
    dtheta[br.steps], dv[br.steps] = br.dtheta, br.dv
    new = increments_from_deltas(dtheta, dv)
    new.coning[0], new.sculling[0] = inc.coning[0], inc.sculling[0]  # the first step's own (no previous one)
    return Increments(new.dtheta, new.dv, new.coning, new.sculling)


#: The share of the asked alignment window its samples must span before the window is said to lie partly outside the
#: record (a window given a sample or two beyond the record's ends, as round numbers are, is not said).
ALIGN_COVERED = 0.9


def _warn_outside_record(imu: ImuData, window: tuple[float, float]) -> None:
    """An :class:`~casep.exceptions.AlignmentWarning` when `window` (``--align``) reaches beyond the record so that its
    samples span less than :data:`ALIGN_COVERED` of it: the levelling is then another window than the one asked (a
    launch time after the record's end is not said: a pad-only record is navigated so)."""
    from casep.exceptions import AlignmentWarning

    t = imu.t
    t1, t2 = float(window[0]), float(window[1])
    held = t[(t >= t1) & (t <= t2)]
    span = float(held[-1] - held[0]) if held.size else 0.0
    if (t1 < t[0] or t2 > t[-1]) and span < ALIGN_COVERED * (t2 - t1):
        warnings.warn(f"--align {t1:g} {t2:g}: {imu.source} holds {t[0]:.6g} .. {t[-1]:.6g} s, so the window's samples "
                      f"span {span:.4g} s of the {t2 - t1:.4g} s asked: the levelling is the mean over them only",
                      AlignmentWarning, stacklevel=3)

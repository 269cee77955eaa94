"""Alignment on the pad: levelling by the mean specific force, heading given or by gyrocompassing.

At rest on the Earth the accelerometers sense ``-g`` (the normal gravity, :mod:`casep.gravity`) and
the gyros the Earth rate. Over the window ``[T1, T2]`` the mean specific force ``f_b`` gives the
local vertical in body axes; the heading comes from a second direction, known in both frames
(the TRIAD construction)::

    body:   e1 = f_b/|f_b|,  e2 = unit(s_b - (s_b . e1) e1),  e3 = e1 x e2
    triad:  E1 = -g_T/|g_T|, E2 = unit(s_T - (s_T . E1) E1),  E3 = E1 x E2
    C_T^b = [E1 E2 E3] [e1 e2 e3]^T          (body -> Earth-fixed launch triad at the pad)

``s`` is either a body axis whose azimuth is given (``--heading``: the rail azimuth of the
longitudinal axis; in the triad the horizontal unit vector at that azimuth) or the mean gyro rate
(gyrocompassing: its horizontal part is the north component ``omega_E cos(lat)`` of the Earth
rate). A gyrocompassed heading is as good as the gyros: a horizontal gyro bias ``b`` turns it by
``b / (omega_E cos(lat))`` (1 deg/h: 3.8 deg at the equator, 5.4 deg at 45 deg), which the pad data
bound from below by the mismatch between the measured and the expected Earth rate; the warning
gives the figures.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from casep.exceptions import AlignmentWarning, PlausibilityWarning
from casep.frames import OMEGA_EARTH, LaunchSite
from casep.units import G0, MEMS_ACCEL_BIAS, MEMS_GYRO_BIAS

__all__ = ["Alignment", "align", "HEADING_AXES", "MAX_PAD_RATE", "ACCEL_BIAS_TOLERANCE", "AT_REST_SILENT",
           "FORCE_UNITS", "course_rotation", "gyro_bias_allowance", "mean_rate_std",
           "EARTH_RATE_CHI2", "deg_s_chance", "large_pad_rate", "pad_rate_causes", "PadRateCause",
           "GRADE_FLOOR", "CAUSE_FACTOR"]

#: Body axes whose azimuth ``--heading`` may give.
HEADING_AXES = ("x", "y", "z")
#: Gyrocompassing is refused when the heading would be known worse than this, rad.
GYROCOMPASS_LIMIT_RAD = math.radians(30.0)
#: The heading axis must lean at least this far from the vertical for its azimuth to fix a heading, rad.
MIN_AXIS_TILT_RAD = math.radians(2.0)
#: The accelerometer bias the mean pad specific force may differ from the normal gravity by, m/s^2: the largest of
#: consumer MEMS, 80 mg (:data:`casep.units.MEMS_ACCEL_BIAS`). Beyond it, an error; beyond
#: :data:`AT_REST_SILENT` a warning with the number (the bias is then part of what a separation estimates).
ACCEL_BIAS_TOLERANCE = MEMS_ACCEL_BIAS
#: Mean pad specific force within this of the normal gravity, m/s^2: said nothing of (49 mg, 5 % of g: the MEMS
#: biases of most records, which a separation estimates, and the normal gravity's omission of the local anomaly,
#: 1e-4 g).
AT_REST_SILENT = 0.05 * G0
#: The unit mistakes the pad's |f| is compared with: name, factor to m/s^2, the fix.
FORCE_UNITS = (("g", G0, "multiply by 9.80665"), ("ft/s^2", 0.3048, "multiply by 0.3048"),
               ("cm/s^2 (gal)", 0.01, "divide by 100"), ("mm/s^2", 0.001, "divide by 1000"))


@dataclass(frozen=True)
class Alignment:
    """The pad attitude and how it was found.

    Attributes
    ----------
    C_tb : (3, 3) ndarray
        Body -> Earth-fixed launch triad (columns: body axes in triad axes).
    method : str
        ``"heading"`` (given) or ``"gyrocompass"``.
    heading_deg : float
        Azimuth of the horizontal projection of body axis `heading_axis`, deg from north, clockwise.
    heading_std_deg : float or None
        Gyrocompassing: how well the heading is known (noise and the Earth-rate mismatch); None when given.
    f_mean, w_mean : (3,) ndarray
        Mean body specific force (m/s^2) and rate (rad/s) over the window.
    g_pad : float
        Normal gravity at the pad, m/s^2.
    rows : int
        Samples in the window.
    heading_axis : str
        The body axis whose azimuth `heading_deg` is: the one named, or when gyrocompassing with the
        named axis within 2 deg of the vertical, the most horizontal one.
    """

    C_tb: np.ndarray
    method: str
    heading_deg: float
    heading_std_deg: float | None
    f_mean: np.ndarray
    w_mean: np.ndarray
    g_pad: float
    rows: int
    heading_axis: str = "x"

    def to_dict(self) -> dict:
        return {"method": self.method, "heading_deg": self.heading_deg, "heading_std_deg": self.heading_std_deg,
                "f_mean": self.f_mean.tolist(), "w_mean": self.w_mean.tolist(), "g_pad": self.g_pad,
                "rows": self.rows, "heading_axis": self.heading_axis}


def _triad(e1: np.ndarray, s_b: np.ndarray, E1: np.ndarray, s_t: np.ndarray) -> np.ndarray:
    """``C_T^b`` from the vertical (`e1` body, `E1` triad) and a second direction (`s_b`, `s_t`); `s_t` may hold many
    directions (..., 3): one matrix each (..., 3, 3)."""
    def frame(a: np.ndarray, s: np.ndarray) -> np.ndarray:  # a one vector, s one or many
        a = a / np.linalg.norm(a)
        b = s - (s @ a)[..., None] * a
        b = b / (np.linalg.norm(b) if b.ndim == 1 else np.linalg.norm(b, axis=-1, keepdims=True))
        return np.stack([np.broadcast_to(a, b.shape), b, np.cross(a, b)], axis=-1)

    return frame(E1, s_t) @ frame(e1, s_b).T


def _horizontal(azimuth_deg: float, site: LaunchSite) -> np.ndarray:
    """Horizontal unit vector at `azimuth_deg` (from north, clockwise) in the launch triad (x at the site azimuth)."""
    d = math.radians(azimuth_deg - site.azimuth_deg)
    return np.array([math.cos(d), 0.0, math.sin(d)])  # z = x cross up points 90 deg clockwise of x


def _azimuth(v_t: np.ndarray, site: LaunchSite) -> float:
    """Azimuth (deg from north, clockwise, in [0, 360)) of the horizontal part of a triad vector."""
    return (site.azimuth_deg + math.degrees(math.atan2(v_t[2], v_t[0]))) % 360.0


def align(t: np.ndarray, w: np.ndarray, f: np.ndarray, window: tuple[float, float], site: LaunchSite, *,
          heading_deg: float | None = None, heading_axis: str = "x",
          rates_in: str = "columns w_x, w_y, w_z", accel_bias_tolerance: float = ACCEL_BIAS_TOLERANCE,
          as_given: bool = True, gyro_bias_tolerance: float | None = None, judge_earth_rate: bool = True) -> Alignment:
    """Level over `window` and fix the heading (given, or by gyrocompassing with a warning).

    Parameters
    ----------
    t, w, f : ndarray
        Times (s), body rates (rad/s, (N, 3)), body specific forces (m/s^2, (N, 3)).
    window : (T1, T2)
        The pad span, at rest on the Earth, s.
    site : LaunchSite
    heading_deg : float, optional
        Azimuth of the horizontal projection of body axis `heading_axis`, deg from north, clockwise
        (a rocket on its rail: the rail azimuth, with `heading_axis` its longitudinal axis).
        None: gyrocompassing.
    heading_axis : {"x", "y", "z"}
        Gyrocompassing: the axis whose azimuth is reported (the most horizontal one if this one is
        within 2 deg of the vertical).
    rates_in : str
        Where the rates come from, for messages (file and columns).
    accel_bias_tolerance : float, optional
        The accelerometer bias (m/s^2) the mean specific force may differ from the normal gravity by
        (:func:`_check_pad_force`); default :data:`ACCEL_BIAS_TOLERANCE` (80 mg, consumer MEMS).
    gyro_bias_tolerance : float, optional
        The gyro bias (rad/s) the mean pad rate may reach (:func:`large_pad_rate`); None: :data:`MAX_PAD_RATE`.
    as_given : bool
        The record as its file gives it (gyro signs the Earth rate decides are an error,
        :func:`_check_earth_rate`); False for a record an estimate has corrected (the passes of a separation from
        raw data: a trial correction is judged by its residuals, the warning is said once on the record as given).
    judge_earth_rate : bool
        False, with `as_given` False: :func:`_check_earth_rate`, whose only outcome there is a warning, is not made
        (the perturbed means of a derivative of the attitude, whose warnings the caller discards: the pass's own
        alignment says them once). The attitude is the same.

    Raises
    ------
    ValueError
        Fewer than 2 samples in the window, a mean specific force more than `accel_bias_tolerance` from
        the normal gravity (not at rest, or not in m/s^2: the message says which fits), rates in deg/s
        (the pad rate is the Earth rate times 57.3), a heading axis within 2 deg of the vertical, or gyros
        that cannot find north (heading known worse than 30 deg).
    """
    from casep.gravity import normal_gravity_ecef
    from casep.navigation.imu import time_step_problem

    t1, t2 = window
    sel = (t >= t1) & (t <= t2)
    n = int(sel.sum())
    if not t1 < t2 or n < 2:
        h = float(np.median(np.diff(t))) if t.size > 1 else 0.0
        why = time_step_problem(h) if h > 0 else None
        hint = f"; its {why}" if why is not None else ""
        raise ValueError(f"--align {t1:g} {t2:g}: the window must hold at least 2 samples (it holds {n}; the file "
                         f"spans {t[0]:g} .. {t[-1]:g} s{hint})")
    f_mean, w_mean = f[sel].mean(axis=0), w[sel].mean(axis=0)
    g_t = site.C.T @ normal_gravity_ecef(site.r_site)
    g0 = float(np.linalg.norm(g_t))
    fm = float(np.linalg.norm(f_mean))
    moved = float(np.max(np.linalg.norm(f[sel] - f_mean, axis=1)))
    _check_pad_force(fm, g0, moved, n, (t1, t2), accel_bias_tolerance)
    if moved > 0.1 * g0:
        warnings.warn(f"--align {t1:g} {t2:g}: the specific force departs from its mean by up to {moved:.3g} m/s^2 "
                      "during the window: the vehicle may have moved (the levelling is its mean)",
                      AlignmentWarning, stacklevel=2)
    up_b, up_t = f_mean / fm, -g_t / g0
    s_mean = mean_rate_std(w[sel])
    large = large_pad_rate(w_mean, up_b, w, gyro_bias_tolerance)
    if heading_axis not in HEADING_AXES:
        raise ValueError(f"heading_axis must be one of {HEADING_AXES}, got {heading_axis!r}")
    axis = np.eye(3)[HEADING_AXES.index(heading_axis)]
    tilt = math.acos(min(1.0, abs(float(axis @ up_b))))
    if heading_deg is not None:
        if tilt < MIN_AXIS_TILT_RAD:
            raise ValueError(f"--heading {heading_deg:g}: body {heading_axis} axis is {math.degrees(tilt):.2f} deg "
                             "from the vertical on the pad, so its azimuth does not fix the heading: give the azimuth "
                             "of a horizontal axis (--heading-axis)")
        C = _triad(up_b, axis, up_t, _horizontal(heading_deg, site))
        _check_pad_rate(w_mean, s_mean, n, (t1, t2), up_b, up_t, site, rates_in, C.T @ site.earth_rate,
                        large=large)
        if as_given or judge_earth_rate:
            _check_earth_rate(w[sel], w_mean, C, site, (t1, t2), rates_in, float(heading_deg), as_given,
                              pad=(up_b, up_t, axis))
        return Alignment(C, "heading", float(heading_deg) % 360.0, None, f_mean, w_mean, g0, n, heading_axis)
    _check_pad_rate(w_mean, s_mean, n, (t1, t2), up_b, up_t, site, rates_in, large=large)
    if tilt < MIN_AXIS_TILT_RAD:  # its azimuth means nothing: report the most horizontal axis's
        heading_axis = HEADING_AXES[int(np.argmin(np.abs(up_b)))]
    return _gyrocompass(w[sel], w_mean, f_mean, up_b, up_t, g0, site, n, (t1, t2), heading_axis)


def _check_pad_force(fm: float, g0: float, moved: float, n: int, window: tuple[float, float],
                     tolerance: float) -> None:
    """The mean pad specific force ``|f|`` against the normal gravity ``g0`` (m/s^2).

    Within :data:`AT_REST_SILENT`: nothing. Within `tolerance` (an accelerometer bias along the vertical): a
    :class:`~casep.exceptions.AlignmentWarning` with the size in mg, and the levelling goes on (the bias tilts it
    by at most ``b_h / g``; a separation estimates the bias with the rest). Beyond it a ``ValueError`` with the
    reason that fits: ``|f|`` times a unit's factor (:data:`FORCE_UNITS`) within `tolerance` of ``g0`` (the
    accelerometers are in that unit), a specific force that varies in the window by more than 0.1 g (the vehicle
    moved), or else a steady offset beyond the tolerance (a bias that large, or a vehicle not at rest).
    """
    off = fm - g0
    # the tolerance said as what it is: the default (consumer MEMS) or the user's own
    accepted = (f"the {1000 * tolerance / G0:.3g} mg accelerometer bias accepted (--accel-bias-tolerance MG, "
                + ("the default, the largest of consumer MEMS)" if tolerance == ACCEL_BIAS_TOLERANCE else
                   f"given; the default {1000 * ACCEL_BIAS_TOLERANCE / G0:.3g} mg is the largest of consumer MEMS)"))
    where = (f"--align {window[0]:g} {window[1]:g}: mean specific force {fm:.5g} m/s^2 over {n} samples, normal "
             f"gravity at the pad {g0:.5g} m/s^2 ({1000 * off / G0:+.3g} mg)")
    if abs(off) <= min(AT_REST_SILENT, tolerance):
        return
    if abs(off) <= tolerance:
        warnings.warn(f"{where}: an accelerometer bias of about {1000 * abs(off) / G0:.3g} mg along the vertical, "
                      f"within {accepted}; the levelling goes on and a separation estimates the bias",
                      AlignmentWarning, stacklevel=3)
        return
    units = [f"in {name} (|f| read so is {fm * k:.5g} m/s^2: {fix})" for name, k, fix in FORCE_UNITS
             if abs(fm * k - g0) <= tolerance]
    if units:
        why = ("the accelerometers look like they are " + " or ".join(units) + f"; else an offset of "
               f"{1000 * abs(off) / G0:.4g} mg, beyond {accepted}")
    elif moved > 0.1 * g0:
        why = (f"the specific force departs from its mean by up to {moved:.3g} m/s^2 in the window: the vehicle "
               "moved (give a window at rest)")
    else:
        why = (f"steady within {moved:.3g} m/s^2, {1000 * abs(off) / G0:.3g} mg from gravity, beyond {accepted}: an "
               "accelerometer bias that large, accelerometers not in m/s^2, or a vehicle not at rest")
    raise ValueError(f"{where}: not at rest on the pad in m/s^2: {why}")


#: A mean pad rate beyond this (2.9 deg/s, no gyro that navigates has such a bias) is warned about, rad/s; the
#: default gyro bias tolerance (:func:`large_pad_rate`).
MAX_PAD_RATE = 0.05


def large_pad_rate(w_mean: np.ndarray, up_b: np.ndarray, w: np.ndarray, tolerance: float | None = None
                   ) -> tuple[bool, str] | None:
    """The one rule for a mean pad rate beyond :data:`MAX_PAD_RATE`: a unit slip (deg/s read as rad/s) or a large
    gyro bias, told apart by the numbers where they can be.

    Parameters
    ----------
    w_mean : (3,) ndarray
        The mean body rate over the pad window as read, rad/s.
    up_b : (3,) ndarray
        The vertical in body axes (the mean specific force's direction).
    w : (N, 3) ndarray
        The whole record's rates as read, rad/s (their peak).
    tolerance : float, optional
        The gyro bias accepted, rad/s (``--gyro-bias-tolerance``); None: :data:`MAX_PAD_RATE`.

    Returns
    -------
    (refused, text) or None
        None when the rate is within both :data:`MAX_PAD_RATE` and `tolerance`. Else ``refused`` True with what it
        is: rates in deg/s when the record's peak rate is beyond the 2000 deg/s of common gyros
        (:data:`casep.navigation.imu.WARN_RATE`: the rates of a moving vehicle read 57.3 times too large),
        whatever the tolerance; otherwise "a gyro bias of X deg/s, or rates in deg/s" (the pad cannot tell: a
        bias is steady at rest as the Earth rate read in deg/s is; the Earth-rate match,
        :func:`_check_pad_rate`, tells them apart only when the gyro's own bias is small), refused beyond
        `tolerance`, and within it (``refused`` False) accepted with how fast the navigation's attitude drifts.
    """
    from casep.navigation.imu import WARN_RATE

    tol = MAX_PAD_RATE if tolerance is None else float(tolerance)
    rate = float(np.linalg.norm(w_mean))
    if rate <= min(tol, MAX_PAD_RATE):
        return None
    peak = float(np.max(np.linalg.norm(w, axis=1))) if len(w) else 0.0
    deg = math.degrees(1.0)
    if peak > WARN_RATE and rate > MAX_PAD_RATE:
        return True, (f"the rates are in deg/s: the pad rate is beyond the {MAX_PAD_RATE:g} rad/s bias of any gyro "
                      f"that navigates and the record's peak rate {peak:.4g} rad/s ({math.degrees(peak):.4g} deg/s) "
                      f"beyond the 2000 deg/s of common gyros (divided by 57.2958 they are {rate / deg:.3g} and "
                      f"{peak / deg:.3g} rad/s): give rad/s (multiply by pi/180)")
    h = float(np.linalg.norm(w_mean - (w_mean @ up_b) * up_b))  # across the vertical: it tilts the levelling
    both = (f"a gyro bias of {math.degrees(rate):.3g} deg/s, or rates in deg/s (divided by 57.2958 it is "
            f"{rate / deg:.3g} rad/s, {rate / deg / OMEGA_EARTH:.3g} times the Earth rate, a bias of "
            f"{rate:.3g} deg/s; the record's peak rate {peak:.3g} rad/s is within the 2000 deg/s of common gyros "
            "either way): the pad cannot tell")
    drift = (f"the navigation's attitude drifts by {math.degrees(rate):.3g} deg/s, {math.degrees(h):.3g} deg/s of "
             f"it tilting the vertical (a velocity error of g b t^2/2, {G0 * h / 2.0:.3g} m/s after 1 s)")
    if rate > tol:
        given = ("beyond the 0.05 rad/s bias of any gyro that navigates" if tolerance is None else
                 f"beyond the --gyro-bias-tolerance {math.degrees(tol):g} deg/s given")
        return True, (f"{both}; in deg/s give rad/s (multiply by pi/180); a bias that large, {given}: "
                      f"{drift}; --gyro-bias-tolerance {math.ceil(math.degrees(rate) * 10.0) / 10.0:g} (deg/s) "
                      "navigates with it")
    return False, (f"{both}; a bias within the --gyro-bias-tolerance {math.degrees(tol):g} deg/s given: {drift} "
                   "until a separation estimates the bias (`casep separate --imu`); in deg/s give rad/s (multiply "
                   "by pi/180)")
#: Rates are taken for deg/s when the pad rate divided by 57.2958 matches the Earth rate, beyond the noise of
#: the mean, within this fraction of the Earth rate: its vertical and horizontal parts when the heading is
#: gyrocompassed (the pad rate fixes the heading then), all three body components when the heading is given.
#: 5 % and 20 % (0.75 and 3 deg/h of gyro bias: tactical grade; the chance that a MEMS bias read in rad/s
#: lands there, :func:`deg_s_chance`, is then 0.08-0.22 % and 0.15 %).
DEG_S_MATCH = 0.05
DEG_S_MATCH_HEADING = 0.20
#: The noise of the mean pad rate (its std, :func:`mean_rate_std`) is allowed this many times in the match.
DEG_S_NOISE_Z = 3.0
#: The spread of the biases of gyros read in rad/s that the deg/s rule must not take for deg/s: a ball of
#: this radius, rad/s (:data:`casep.units.MEMS_GYRO_BIAS`, 0.42 deg/s, 100 times the Earth rate: consumer MEMS),
#: every bias in it equally likely.
MEMS_BIAS_SPREAD = MEMS_GYRO_BIAS
#: The largest chance that such a bias lands within the match by chance for which a match is an error; above
#: it (the noise of the mean widens the match) a match is a warning. 0.25 %: the 5 % match of a
#: gyrocompassed pad at the equator (0.22 %).
DEG_S_CHANCE = 0.0025
#: Beyond every match, a mean rate that divided by 57.2958 is still near the Earth rate is warned about as deg/s
#: when a consumer MEMS bias read in rad/s lands that near with at most this chance (1 %), judged by the most
#: specific comparison (all three components when the heading is given): a tactical gyro's 1 deg/h in deg/s,
#: gyrocompassed (6.7 % off, 0.15 % at 68 deg latitude), is; a MEMS gyro's 615 deg/h bias with the heading given
#: (a reviewer's record at 33 deg: 59 % off the Earth rate in body axes, 3.9 %), or a rate 57 times the Earth rate
#: across it (the size of a MEMS bias, 860 deg/h), is not.
DEG_S_WARN_CHANCE = 0.01
#: A match (the noise of the mean widening it) that a consumer MEMS bias read in rad/s lands in with a chance above
#: this (5 %) says nothing of the unit, and no deg/s hint is given: the real car drive's pad (a MEMS gyro in rad/s,
#: 0.19 deg/s of bias, 45 times the Earth rate, on a vibrating pad) matched the Earth rate in deg/s within the 59 % the
#: noise allowed with a chance of 24 %, and was hinted "rates in deg/s?". Rates truly in deg/s with a MEMS bias read
#: as rad/s are 57 times it, beyond :data:`MAX_PAD_RATE` from 0.05 deg/s of bias on: the large-rate rule says them.
DEG_S_HINT_CHANCE = 0.05


def deg_s_chance(tol: float, lat_deg: float, heading_given: bool) -> float:
    """The chance that a gyro bias read in rad/s, spread evenly over a ball of :data:`MEMS_BIAS_SPREAD`,
    matches the Earth rate in deg/s within ``tol`` (a fraction of the Earth rate) by chance.

    Scaled by ``D = 57.2958`` the match is a ball of radius ``r = D tol omega_E`` about one point when the
    heading is given (``4/3 pi r^3``), and a torus of tube radius ``r`` about the ring of radius
    ``R = D omega_E cos(lat)`` when only the vertical and horizontal parts are compared (``2 pi R pi r^2``),
    both divided by the ball's ``4/3 pi B^3`` (at most 1).
    """
    deg = math.degrees(1.0)
    r = deg * tol * OMEGA_EARTH
    vol = 4.0 / 3.0 * math.pi * r**3 if heading_given else \
        2.0 * math.pi * (deg * OMEGA_EARTH * math.cos(math.radians(lat_deg))) * math.pi * r**2
    return min(1.0, vol / (4.0 / 3.0 * math.pi * MEMS_BIAS_SPREAD**3))


def _check_pad_rate(w_mean: np.ndarray, s_mean: np.ndarray, n: int, window: tuple[float, float], up_b: np.ndarray,
                    up_t: np.ndarray, site: LaunchSite, rates_in: str, e_body: np.ndarray | None = None, *,
                    large: tuple[bool, str] | None = None) -> None:
    """At rest the gyros measure the Earth rate (7.3e-5 rad/s) plus their bias.

    Rates in deg/s read as rad/s give ``w = D (omega_b + b)`` with ``D = 180/pi = 57.2958``, and their
    noise D times too: an error when ``w / D`` is the Earth rate at the site within
    ``tol = m omega_E + DEG_S_NOISE_Z |s| / D`` (``s`` the std of the mean rate as read, `s_mean`): the
    vertical and horizontal parts, ``|(w.u/D - omega_E sin(lat), |w_h|/D - omega_E cos(lat))| < tol`` with
    ``m`` :data:`DEG_S_MATCH`; or, with the heading given (`e_body`, the Earth rate the alignment puts in
    body axes), ``|w / D - e_body| < tol`` with ``m`` :data:`DEG_S_MATCH_HEADING` (a wrong heading only
    misses a match).
    Read in rad/s, a gyro's noise of the mean is ``|s|``, its tolerance ``|s| / D`` negligible: only its bias
    lands it there, with the chance :func:`deg_s_chance`; when the noise widens the match so much that this
    chance exceeds :data:`DEG_S_CHANCE`, a match is a warning (the pad cannot tell deg/s from a MEMS bias).
    A match whose chance exceeds :data:`DEG_S_HINT_CHANCE` says nothing of the unit and is not said.
    A warning too when the mean is beyond :data:`MAX_PAD_RATE` (`large`, :func:`large_pad_rate`'s verdict), or when
    it is near the Earth rate in deg/s beyond the match but a MEMS bias lands that near with at most
    :data:`DEG_S_WARN_CHANCE` (the comparison of all three components when the heading is given: the gyrocompassed
    one ignores the heading, and a MEMS bias matches it 57 times as often). Its magnitude alone (about 57.3 times
    the Earth rate) says nothing: that is the size of a consumer MEMS bias (:data:`MEMS_BIAS_SPREAD`).
    """
    deg = math.degrees(1.0)
    rate = float(np.linalg.norm(w_mean))
    ratio = rate / OMEGA_EARTH
    omega_t = site.earth_rate
    up_rate = float(omega_t @ up_t)  # omega_E sin(lat)
    north_rate = float(np.linalg.norm(omega_t - up_rate * up_t))  # omega_E cos(lat)
    w_up = float(w_mean @ up_b)
    w_h = float(np.linalg.norm(w_mean - w_up * up_b))
    noise = DEG_S_NOISE_Z * float(np.linalg.norm(s_mean)) / deg / OMEGA_EARTH
    where = f"--align {window[0]:g} {window[1]:g}: {rates_in}: mean body rate at rest {rate:.4g} rad/s over {n} samples"
    tests = [(math.hypot(w_up / deg - up_rate, w_h / deg - north_rate) / OMEGA_EARTH, DEG_S_MATCH + noise, False,
              f"the Earth rate at latitude {site.lat_deg:g} deg (vertical {w_up / deg:.4g}, horizontal "
              f"{w_h / deg:.4g} rad/s")]
    if e_body is not None:  # the heading given fixes all three components (a wrong heading only misses a match)
        tests.append((float(np.linalg.norm(w_mean / deg - e_body)) / OMEGA_EARTH, DEG_S_MATCH_HEADING + noise, True,
                      f"the Earth rate the alignment puts in body axes ({', '.join(f'{v:.4g}' for v in w_mean / deg)} "
                      f"against {', '.join(f'{v:.4g}' for v in e_body)} rad/s"))
    judged = [(m, tol, deg_s_chance(tol, site.lat_deg, full), what) for m, tol, full, what in tests]
    def said(match: float, tol: float, what: str) -> str:
        return (f"{where}, {ratio:.2f} times the Earth rate {OMEGA_EARTH:.4g} rad/s: divided by 57.2958 it is {what}, "
                f"within {100 * match:.1f} % of the Earth rate; allowed {100 * tol:.1f} %, of which "
                f"{100 * noise:.1f} % the noise of the mean)")

    for match, tol, chance, what in judged:
        if match < tol and chance <= DEG_S_CHANCE:
            raise ValueError(f"{said(match, tol, what)}: the rates are in deg/s; give them in rad/s "
                             "(multiply by pi/180)")
    for match, tol, chance, what in judged:
        if match < tol and chance <= DEG_S_HINT_CHANCE:
            warnings.warn(f"{said(match, tol, what)}: rates in deg/s? The noise leaves the pad unable to tell: a gyro "
                          f"bias read in rad/s (MEMS, up to {math.degrees(MEMS_BIAS_SPREAD):.2g} deg/s) lands that "
                          f"close with a chance of {100 * chance:.2g} % (an error below {100 * DEG_S_CHANCE:g} %). "
                          f"Both readings: in rad/s, a gyro bias of {math.degrees(rate):.3g} deg/s "
                          f"({math.degrees(rate) * 3600:.3g} deg/h: a MEMS gyro's); in deg/s, the Earth rate within "
                          f"{100 * match:.0f} % of it, a bias of about {math.degrees(match * OMEGA_EARTH) * 3600:.2g} "
                          "deg/h. Give rad/s (multiply by pi/180) if they are deg/s", PlausibilityWarning,
                          stacklevel=3)
            return
    if large is not None:  # beyond any navigating gyro's bias: the one rule's verdict, said once
        warnings.warn(f"{where} ({math.degrees(rate):.4g} deg/s): {large[1]}; or a vehicle not at rest",
                      PlausibilityWarning, stacklevel=3)
        return
    match, tol, _, _ = judged[-1]  # the most specific: all three components when the heading is given
    chance = deg_s_chance(match, site.lat_deg, e_body is not None)
    if chance <= DEG_S_WARN_CHANCE:
        warnings.warn(f"{where}, {ratio:.1f} times the Earth rate {OMEGA_EARTH:.4g} rad/s: deg/s given as rad/s (57.3 "
                      f"times; divided by 57.2958 it differs from the Earth rate by {100 * match:.0f} % of it, "
                      f"beyond the {100 * tol:.1f} % that makes it an error; a consumer MEMS bias read in rad/s lands "
                      f"that near with a chance of only {100 * chance:.2g} %), a gyro bias of that size, or a vehicle "
                      "not at rest", PlausibilityWarning, stacklevel=3)


#: The chi-square (3 degrees of freedom, 0.1 % false alarms) beyond which a mean pad rate disagrees with the
#: Earth rate the alignment puts in body axes (:func:`_check_earth_rate`).
EARTH_RATE_CHI2 = 16.27
#: How much lower the chi-square of another sign per gyro axis must be to name it (a likelihood ratio of 90).
SIGN_CHI2_MARGIN = 9.0
#: Another sign per gyro axis whose chi-square is within this (3 degrees of freedom, 95 %) while the signs as given
#: are beyond :data:`EARTH_RATE_CHI2` is an error, not a warning: the navigation from such a pad turns the
#: vehicle's attitude about the wrong axes (a reviewer's aircraft record with gyro y, z negated: 37.9 as given, 0.218
#: flipped, the navigation 14 km underground after 7 minutes and exit 0).
SIGN_CHI2_CONSISTENT = 7.815


def gyro_bias_allowance(site: LaunchSite) -> float:
    """The gyro bias a gyro that finds north may have, rad/s: ``omega_E cos(lat) sin(30 deg)``, the horizontal
    bias that turns a gyrocompassed heading by the 30 deg beyond which casep refuses it (3.0e-5 rad/s, 6 deg/h,
    at 34 deg latitude). A gyro whose mean pad rate is beyond 3 times the Earth rate is of another grade (MEMS:
    its bias hides the Earth rate), and no pad test of the Earth rate is made on it."""
    omega_t = site.earth_rate
    up = site.C.T @ (site.r_site / np.linalg.norm(site.r_site))  # near enough the vertical for a bound
    return float(np.linalg.norm(omega_t - (omega_t @ up) * up)) * math.sin(GYROCOMPASS_LIMIT_RAD)


def mean_rate_std(x: np.ndarray) -> np.ndarray:
    """The std of the mean of each column of `x` (n, k) from its own scatter, corrected for AR(1) correlation:
    ``s^2 / n (1 + rho) / (1 - rho)``, ``rho`` the lag-1 autocorrelation (clipped to [0, 0.99]:
    :func:`casep._kernels.ar1_long_run_factor`)."""
    from casep._kernels import ar1_long_run_factor

    d = x - x.mean(axis=0)
    var = np.mean(d**2, axis=0)
    return np.sqrt(var / len(x) * ar1_long_run_factor(np.sum(d[1:] * d[:-1], axis=0), np.sum(d**2, axis=0), 0.99))


def _check_earth_rate(w_win: np.ndarray, w_mean: np.ndarray, C: np.ndarray, site: LaunchSite,
                      window: tuple[float, float], rates_in: str, heading_deg: float, refuse: bool = True,
                      pad: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> None:
    """With the heading given, the mean pad rate against the Earth rate the alignment puts in body axes.

    ``chi2(S) = sum_i (S_i w_mean_i - e_i)^2 / (s_i^2 + b^2)``, ``e = C^T omega_t``, ``s_i`` the std of the mean
    rate (:func:`mean_rate_std`), ``b`` :func:`gyro_bias_allowance`, ``S`` a sign per gyro axis (``S = +1``:
    as given). A warning when another ``S`` explains the pad rate better by more than :data:`SIGN_CHI2_MARGIN`
    and explains it (its chi-square within :data:`EARTH_RATE_CHI2`; a flip that only fits less badly is a gyro bias
    of a few Earth rates, which the message then names with its size) (gyro axes whose signs differ from the
    accelerometers'; negating all three accelerometers turns the levelled
    attitude over about the heading axis and looks the same: the specific force at rest is +g up, and the pad
    data cannot tell "+g down" from an upside-down vehicle with two gyro axes flipped), or when ``chi2(+1)`` is
    beyond :data:`EARTH_RATE_CHI2` (a heading other than the one given, a larger gyro bias); an error (`refuse`)
    when that other sign is within :data:`SIGN_CHI2_CONSISTENT` and the given one beyond :data:`EARTH_RATE_CHI2`.
    A warning too, naming them, when set-up mistakes explain the pad rate far better than the set-up as given
    (:func:`pad_rate_causes`; `pad` is the alignment's vertical in body and triad axes and the heading axis, which
    the other headings need). Not made when the
    mean rate exceeds 3 times the Earth rate (the gyro's bias hides it: MEMS) or the noise of the mean exceeds
    ``b``: there the pad cannot tell.
    """
    b = gyro_bias_allowance(site)
    s = mean_rate_std(w_win)
    if np.linalg.norm(w_mean) > 3 * OMEGA_EARTH or float(np.max(s)) > b:
        return
    e = C.T @ site.earth_rate
    signs = [np.array([sx, sy, sz]) for sx in (1, -1) for sy in (1, -1) for sz in (1, -1)]
    chi2 = [float(np.sum((S * w_mean - e) ** 2 / (s**2 + b**2))) for S in signs]
    k = int(np.argmin(chi2))
    # another sign is named only where it explains the pad rate (within the 0.1 % bound): a gyro bias of a few Earth
    # rates lowers the chi-square of some flip by chance, and naming it sent a MEMS user after a sign (a 25 deg/h
    # bias on an upright z gyro at 68 N: 74.9 as given, 44.5 with z negated)
    flipped = chi2[k] + SIGN_CHI2_MARGIN < chi2[0] and chi2[k] <= EARTH_RATE_CHI2
    causes = pad_rate_causes(w_mean, s, e, b, site, heading_deg, *pad) if pad is not None else []
    if not flipped and chi2[0] <= EARTH_RATE_CHI2 and not causes:
        return
    said = (f"--align {window[0]:g} {window[1]:g}: {rates_in}: the mean body rate at rest "
            f"({', '.join(f'{v:.3g}' for v in w_mean)}) rad/s is not the Earth rate the alignment puts in body axes "
            f"({', '.join(f'{v:.3g}' for v in e)}) rad/s: chi-square {chi2[0]:.3g} over 3 axes against the noise of "
            f"the mean ({', '.join(f'{v:.2g}' for v in s)} rad/s) and a gyro bias of up to {b:.2g} rad/s")
    named = ""
    if causes:
        dh = math.radians(1.0 / 3600.0)
        named = (f". As given the pad rate needs a gyro bias of {float(np.linalg.norm(w_mean - e)) / dh:.3g} deg/h; "
                 + "; ".join(f"{c.what}: a bias of {c.bias / dh:.3g} deg/h, {c.factor:.3g} times as likely"
                             for c in causes)
                 + f" (the evidence of each against the set-up as given, for a gyro bias of any grade from "
                   f"{GRADE_FLOOR / dh:g} to {b / dh:.3g} deg/h, the allowance of a gyro that finds north, beyond "
                   f"{CAUSE_FACTOR:g} times named; a larger bias can mimic them)"
                 + (": the pad rate alone cannot tell these apart" if len(causes) > 1 else "")
                 + "; the navigation from a wrong set-up turns the attitude and the velocity away from the truth")
    if flipped:
        axes = ", ".join(a for a, v in zip("xyz", signs[k]) if v < 0)
        said += (f"; with the signs of gyro {axes} changed it is {chi2[k]:.3g}: gyro axes whose signs differ from "
                 "the accelerometers', or a specific force given as +g down (at rest it is +g up: negated, the "
                 "levelling turns the vehicle over)")
        if refuse and chi2[0] > EARTH_RATE_CHI2 and chi2[k] <= SIGN_CHI2_CONSISTENT:
            cols = ", ".join(f"w_{a}" for a, v in zip("xyz", signs[k]) if v < 0)
            raise ValueError(f"{said}{named}. As given beyond {EARTH_RATE_CHI2:g} (0.1 %), with those signs within "
                             f"{SIGN_CHI2_CONSISTENT:g} (95 %): negate {cols}, or give the specific force +g up at "
                             "rest (fb_* negated), whichever the IMU's data sheet says (or the set-up named above); "
                             "the navigation would turn the attitude about the wrong axes")
    elif chi2[0] > EARTH_RATE_CHI2:  # beyond the bound as given, no sign explains it (a set-up named may)
        need = np.degrees(w_mean - e) * 3600.0
        said += (f" (> {EARTH_RATE_CHI2:g}, and no other sign per gyro axis within it): a heading other than "
                 f"{heading_deg:g} deg, or a larger gyro bias (the signs as given need "
                 f"{', '.join(f'{v:.3g}' for v in need)} deg/h, x, y, z: a MEMS gyro's is often larger)")
    said += named
    warnings.warn(said, AlignmentWarning, stacklevel=3)


#: The gyro grades the pad-rate evidence weighs (:func:`pad_rate_causes`): a bias of std ``sigma`` per axis, ``sigma``
#: log-uniform from this (a navigation-grade gyro's 0.001 deg/h, rad/s) to :func:`gyro_bias_allowance`.
GRADE_FLOOR = math.radians(0.001 / 3600.0)
#: A set-up mistake is named when the pad rate's evidence for it is this many times that for the set-up as given
#: (synthetic correct pads, gyro bias N(0, sigma^2) per axis: none of 60 named at sigma 1 and 3 deg/h, 2 of 60 at
#: 6.6 deg/h, about the allowance, 7 of 59 at 10 deg/h, beyond it: ``benchmarks/pad_rate_causes_mc.py --seed 1``;
#: a 1.5 deg/h gyro with two horizontal columns swapped, the latitude's sign or the heading 90 deg off:
#: 1e3 to 7e3). With the grades up to sqrt(3) times the Earth rate (every pad the test is made on) the swap and the
#: heading fall to 70-95: the pad rate determines them only for a gyro that finds north.
CAUSE_FACTOR = 300.0


class PadRateCause(NamedTuple):
    """A set-up mistake that explains the pad rate (:func:`pad_rate_causes`): ``what`` it is (the best of its kind,
    with its numbers), ``bias`` the gyro bias it leaves (rad/s), ``factor`` its evidence over the set-up as given."""

    what: str
    bias: float
    factor: float


def _log_evidence(r: np.ndarray, s: np.ndarray, b: float) -> np.ndarray:
    """``log p(r)`` of pad-rate residuals `r` (..., 3) (rad/s): a gyro bias ``N(0, sigma^2 I)`` plus the noise of the
    mean ``N(0, diag s^2)`` (`s` (3,), or one per residual (..., 3)), ``sigma`` log-uniform on
    [:data:`GRADE_FLOOR`, `b`] (241 grades)."""
    sig = np.geomspace(min(GRADE_FLOOR, b), b, 241)
    var = np.asarray(s, float)[..., None, :] ** 2 + sig[:, None] ** 2  # (..., G, 3)
    ll = -0.5 * np.sum(r[..., None, :] ** 2 / var + np.log(2.0 * math.pi * var), axis=-1)  # (..., G)
    top = ll.max(axis=-1)
    return top + np.log(np.mean(np.exp(ll - top[..., None]), axis=-1))


def pad_rate_causes(w_mean: np.ndarray, s: np.ndarray, e: np.ndarray, b: float, site: LaunchSite,
                    heading_deg: float, up_b: np.ndarray, up_t: np.ndarray, axis: np.ndarray) -> list[PadRateCause]:
    """The set-up mistakes the mean pad rate `w_mean` (rad/s, std of the mean `s`) names, against the Earth rate the
    alignment puts in body axes `e`, strongest first.

    Each hypothesis ``H`` predicts a pad rate ``e_H`` (read from the gyros as ``w_H``); its residual ``r_H = w_H -
    e_H`` is the gyro bias plus the noise of the mean. With the bias of unknown grade (:func:`_log_evidence`: std
    ``sigma`` per axis, log-uniform from :data:`GRADE_FLOOR` to `b`, :func:`gyro_bias_allowance`), the evidence
    ``p(r_H)`` weighs a small residual against a large one without a fixed bias allowance: a 1 deg/h gyro's pad
    rate explained to 1.5 deg/h by a mistake and to 19 deg/h as given favours the mistake by about 10^4, where a
    chi-square with a 6.6 deg/h allowance cannot tell (8 against 16.3). The kinds, each the mean evidence over its
    members (the look-elsewhere cost of trying many): the gyro columns permuted (5 permutations times 8 signs),
    their signs (7), the latitude's sign (the vertical Earth rate ``omega_E sin(lat)`` negated), the heading (every
    degree of azimuth, the given one among them: uniform over the circle). A kind is named when its evidence
    exceeds :data:`CAUSE_FACTOR` times that of the set-up as given and its best member explains the pad rate
    (chi-square within :data:`EARTH_RATE_CHI2` against the noise of the mean and the allowance `b`, the rule another
    gyro sign is named by), with that member. The pad rate is one vector: a swap of two horizontal axes is a heading
    mirrored, a negated vertical gyro a latitude of the other sign, and all that fit are named.
    """
    import itertools

    ev0 = float(_log_evidence(w_mean - e, s, b))
    u = up_b / np.linalg.norm(up_b)
    signs = [np.array(S, float) for S in itertools.product((1, -1), repeat=3)]
    perms = [p for p in itertools.permutations(range(3)) if p != (0, 1, 2)]
    kinds: list[tuple[str, list[tuple[str, np.ndarray, np.ndarray]]]] = []

    def cols(p: tuple[int, ...], S: np.ndarray) -> str:
        return ", ".join(f"{'-' if S[i] < 0 else ''}w_{'xyz'[p[i]]}" for i in range(3))

    kinds.append(("gyro axes", [(f"the gyro axes x, y, z read from {cols(p, S)}", S * w_mean[list(p)],
                                 np.asarray(s)[list(p)]) for p in perms for S in signs]))
    kinds.append(("gyro signs", [(f"the gyro signs as {cols((0, 1, 2), S)}", S * w_mean, s) for S in signs[1:]]))
    e_lat = e - 2.0 * float(e @ u) * u  # the vertical Earth rate omega_E sin(lat) negated
    heads = [(heading_deg + d) % 360.0 for d in range(360)]
    lat_name = f"a latitude of {-site.lat_deg:g} deg (the sign of --launch-site's latitude: given {site.lat_deg:g})"
    head_names = [f"a heading of {h:g} deg (the gyrocompass heading of the pad rate; given {heading_deg:g}, off by "
                  f"{((h - heading_deg + 180.0) % 360.0) - 180.0:+g} deg)" for h in heads]
    C_heads = _triad(up_b, axis, up_t, np.array([_horizontal(h, site) for h in heads]))  # (360, 3, 3), one per heading
    out = []
    for name, members in kinds:
        r = np.array([w - e for _, w, _ in members])
        ev = _log_evidence(r, np.array([m[2] for m in members]), b)
        out.append((name, ev, [m[0] for m in members], r))
    lat_r = w_mean - e_lat
    out.append(("latitude", np.array([float(_log_evidence(lat_r, s, b))]), [lat_name], lat_r[None, :]))
    head_r = w_mean - np.swapaxes(C_heads, -1, -2) @ site.earth_rate
    out.append(("heading", _log_evidence(head_r, s, b), head_names, head_r))
    causes = []
    for _, ev, names, r in out:
        log_mean = float(ev.max() + np.log(np.mean(np.exp(ev - ev.max()))))  # the kind's mean evidence
        factor = math.exp(min(700.0, log_mean - ev0))
        k = int(np.argmax(ev))
        # named only where it explains the pad rate within the bound, as another sign is (_check_earth_rate): a
        # MEMS bias of a few Earth rates makes some mistake far likelier than the set-up as given by chance (a
        # -46 deg/h y gyro at 68 N: a latitude's sign 4e43 times, needing 22 deg/h against an allowance of 2.9)
        explains = float(np.sum(r[k] ** 2 / (np.asarray(s) ** 2 + b**2))) <= EARTH_RATE_CHI2
        if factor >= CAUSE_FACTOR and explains:
            causes.append(PadRateCause(names[k], float(np.linalg.norm(r[k])), factor))
    return sorted(causes, key=lambda c: -c.factor)


def _gyrocompass(w_win: np.ndarray, w_mean: np.ndarray, f_mean: np.ndarray, up_b: np.ndarray, up_t: np.ndarray,
                 g0: float, site: LaunchSite, n: int, window: tuple[float, float], axis: str) -> Alignment:
    """Heading from the horizontal Earth rate; warns with how well it is known (the azimuth of body `axis`),
    refuses beyond 30 deg."""
    omega_t = site.earth_rate  # Earth rate in triad axes (the triad is Earth-fixed)
    north_rate = float(np.linalg.norm(omega_t - (omega_t @ up_t) * up_t))  # omega_E cos(lat)
    noise = float(np.linalg.norm(w_win.std(axis=0, ddof=1)) / math.sqrt(n))  # std of the mean rate, white noise
    C = _triad(up_b, w_mean, up_t, omega_t)
    mismatch = float(np.linalg.norm(w_mean - C.T @ omega_t))  # what the Earth rate does not explain: a bias bound
    std = math.hypot(noise, mismatch) / north_rate
    heading = _azimuth(C[:, HEADING_AXES.index(axis)], site)
    t1, t2 = window
    if std > GYROCOMPASS_LIMIT_RAD:
        raise ValueError(f"--align {t1:g} {t2:g}: the gyros cannot find north (mean rate {np.linalg.norm(w_mean):.3g} "
                         f"rad/s against the Earth rate {OMEGA_EARTH:.4g} rad/s, {north_rate:.3g} of it horizontal; "
                         f"the heading would be known to about {math.degrees(std):.0f} deg): give --heading")
    warnings.warn(f"heading by gyrocompassing over --align {t1:g} {t2:g}: body {axis} at azimuth {heading:.2f} deg, "
                  f"known to about {math.degrees(std):.2g} deg (noise of the mean rate {noise:.3g} rad/s, Earth-rate "
                  f"mismatch {mismatch:.3g} rad/s, against the horizontal Earth rate {north_rate:.4g} rad/s); an "
                  f"unseen horizontal gyro bias of 1 deg/h adds "
                  f"{math.degrees(math.radians(1 / 3600) / north_rate):.2g} deg; give --heading if it is known",
                  AlignmentWarning, stacklevel=3)
    return Alignment(C, "gyrocompass", heading, math.degrees(std), f_mean, w_mean, g0, n, axis)


def course_rotation(t_nav: np.ndarray, v_nav: np.ndarray, t_trk: np.ndarray, v_trk: np.ndarray,
                    r_ecef: np.ndarray) -> float:
    """The heading error of a navigation from the tracked course: the rotation about the vertical, rad.

    A vehicle that cannot find north on the pad (a MEMS gyro: its bias is tens to thousands of times
    the Earth rate) takes its heading from the tracked course once it moves. With ``dv_n``, ``dv_t`` the
    horizontal changes of the navigated and tracked Earth-relative velocity since the first common
    sample (changes, so a velocity error at the start does not count), both at the tracking times
    within the navigation's span,

        psi = atan2(sum (dv_n x dv_t) . u, sum dv_n . dv_t)

    turns the navigated velocity onto the tracked one about the local vertical ``u`` (right-handed:
    positive counterclockwise seen from above); the attitude is corrected by the same rotation,
    ``C_e^b <- R_u(psi) C_e^b``. Accelerometer biases turn ``dv_n`` by about their share of the
    speed change; what is left is estimated as the initial attitude error ``phi0`` of a window model.

    Parameters
    ----------
    t_nav, v_nav : (N,), (N, 3) ndarray
        Navigation times (s) and Earth-relative velocity in ECEF (m/s).
    t_trk, v_trk : (M,), (M, 3) ndarray
        Tracking times (same scale) and Earth-relative velocity in ECEF (m/s).
    r_ecef : (3,) ndarray
        Where the vertical is taken, m (ECEF).

    Raises
    ------
    ValueError
        Fewer than 3 tracking samples in the span, or a horizontal speed change under 1 m/s (no course).
    """
    from casep.gravity import normal_gravity_ecef

    up = -normal_gravity_ecef(np.asarray(r_ecef, float))
    up = up / np.linalg.norm(up)
    sel = (t_trk >= t_nav[0]) & (t_trk <= t_nav[-1])
    if int(sel.sum()) < 3:
        raise ValueError(f"course heading: {int(sel.sum())} tracking samples within {t_nav[0]:g} .. {t_nav[-1]:g} s "
                         "(at least 3 needed)")
    vn = np.column_stack([np.interp(t_trk[sel], t_nav, v_nav[:, c]) for c in range(3)])
    dn, dt = vn - vn[0], v_trk[sel] - v_trk[sel][0]
    dn, dt = dn - np.outer(dn @ up, up), dt - np.outer(dt @ up, up)
    change = float(np.max(np.linalg.norm(dt, axis=1)))
    if change < 1.0:
        raise ValueError(f"course heading: the tracked horizontal velocity changes by at most {change:.3g} m/s within "
                         f"{t_nav[0]:g} .. {t_nav[-1]:g} s: no course to take a heading from (start when it moves)")
    return math.atan2(float(np.sum(np.cross(dn, dt) @ up)), float(np.sum(dn * dt)))

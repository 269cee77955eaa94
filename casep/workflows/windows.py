"""A long free-inertial record cut into short windows: separated window by window, then compared.

A consumer MEMS IMU drifts out of the linear range of the error model within tens of seconds, so a
long record (a car drive, a UAV flight) cannot be separated as one flight. :func:`separate_windows`
cuts it into windows of a few tens of seconds, and for each one

1. navigates (:func:`casep.navigation.navigate_from`) from the tracked position and velocity at its
   first sample and the running attitude there, in a launch-inertial frame tied to that sample
   (site = the tracked point, azimuth 0, launch time = the window's start);
2. separates it (:func:`casep.separate`, the default noise path; Earth-fixed tracking brings the
   tracking time offset ``dt_trk``) with a window model: the instrument terms plus the initial
   attitude error ``phi0`` and initial velocity error ``dv0`` (``models/strapdown6_window.py``); the
   window's flight carries the tracked ground speed as the column :data:`GROUND_SPEED_COLUMN` (m/s,
   the horizontal tracked velocity's size at each sample) for a model whose terms depend on it
   (``models/strapdown7_speed_window.py``);
3. when ``|phi0|`` is beyond :data:`PHI0_LINEAR_RAD` (the ``f x phi`` term is then no longer linear),
   turns the starting attitude by the estimated ``phi0`` (``C_true = R(phi0) C_ins``,
   :func:`casep.model.strapdown.corrected_attitude`) and
   navigates and separates again, up to ``attitude_passes`` times;
4. carries the attitude to the next window corrected by the estimated attitude error at the end,
   ``phi(T) = phi0 + int phidot dt`` (the model's ``phidot`` at the window's samples).

The heading at the start comes from the tracked course (:func:`casep.navigation.alignment.course_rotation`)
over the first window, then from step 3. :func:`window_consistency` says whether the windows agree:
the chi-square of each window's instrument coefficients against their weighted mean, and how well
each window's coefficients predict every other window's dv at its end.
"""

from __future__ import annotations

import math
import os
import tempfile
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from casep.frames import LaunchSite

__all__ = ["Window", "WindowsResult", "separate_windows", "window_consistency", "consider_gain", "consider_rows",
           "gain_rows", "NUISANCE_PREFIXES", "PHI0_LINEAR_RAD", "GROUND_SPEED_COLUMN", "vibration_power",
           "VIBRATION_BAND_HZ"]

#: Coefficients that belong to one window only (not compared across windows): initial states, time offset.
NUISANCE_PREFIXES = ("phi0_", "dv0_", "dt_trk")
#: An initial attitude error beyond this is re-navigated from the corrected attitude, rad (1 deg: the
#: ``f x phi`` term then departs from its linear form by ``|phi|^2 / 2 |f|``, 1.5 mm/s^2 at 1 g).
PHI0_LINEAR_RAD = math.radians(1.0)


@dataclass
class Window:
    """One window: its start, frame, separation and how its initial attitude was found."""

    t_start: float
    t_end: float
    site: LaunchSite
    result: Any
    passes: int
    heading_from_course_deg: float | None
    sv_end: np.ndarray = field(repr=False, default_factory=lambda: np.zeros((3, 0)))
    sv_names: tuple[str, ...] = ()
    #: With ``separate_windows(consider=...)``: the consider gain of the left-out terms (rows the result's names,
    #: columns :attr:`consider_names`; :func:`consider_gain`), else None.
    consider_gain: np.ndarray | None = field(repr=False, default=None)
    consider_names: tuple[str, ...] = ()


@dataclass
class WindowsResult:
    """The windows and their consistency (:func:`window_consistency`)."""

    windows: list[Window]
    names: tuple[str, ...]
    consistency: dict[str, Any]
    #: With ``separate_windows(imu_instability_pool=True)`` or ``imu_white_pool=True``: the pooled sizes (the
    #: instability's, the white noise's scales) and how they were found.
    instability: dict[str, Any] | None = None

    @property
    def success(self) -> bool:
        """Whether the windows' instrument coefficients agree (chi-square p-value above 1 %)."""
        return bool(self.consistency.get("agree", False))

    @property
    def status(self) -> int:
        """0 the windows agree, 1 they do not (or fewer than two could be compared)."""
        return 0 if self.success else 1

    @property
    def message(self) -> str:
        """One line: how many windows, and whether they agree."""
        c = self.consistency
        if "chi2" not in c:
            return str(c.get("message", "nothing to compare"))
        verdict = "agree" if self.success else "do NOT agree"
        return (f"{c['used']} of {c['windows']} windows compared on {', '.join(self.names)}: chi-square "
                f"{c['chi2']:.4g} on {c['dof']} dof, p = {c['p_value']:.3g}: they {verdict}")

    def to_dict(self) -> dict[str, Any]:
        """Plain data: the consistency and, per window, its span, passes and coefficients."""
        return {"success": self.success, "status": self.status, "message": self.message,
                "consistency": self.consistency, "instability": self.instability,
                "windows": [{"t_start": w.t_start, "t_end": w.t_end, "passes": w.passes,
                             "heading_from_course_deg": w.heading_from_course_deg, "success": w.result.success,
                             "names": list(w.result.names), "estimate": np.asarray(w.result.estimate).tolist(),
                             "std": None if w.result.std is None else np.asarray(w.result.std).tolist()}
                            for w in self.windows]}

    def text(self) -> str:
        """The message, then one line per window with its instrument coefficients."""
        lines = [self.message]
        for w in self.windows:
            est = dict(zip(w.result.names, w.result.estimate))
            sd = dict(zip(w.result.names, w.result.std if w.result.std is not None else [np.nan] * len(est)))
            lines.append(f"  {w.t_start:9.3f} .. {w.t_end:9.3f} s: "
                         + ", ".join(f"{n} {est[n]:.4g} +- {sd[n]:.2g}" for n in self.names))
        return "\n".join(lines)


#: the window flight's column of the tracked ground speed, m/s (a signal a window model may use)
GROUND_SPEED_COLUMN = "ground_speed"


def _launch_from_ecef(site: LaunchSite, t: float) -> np.ndarray:
    """The rotation L <- ECEF at time `t` (columns: the ECEF axes in L)."""
    from casep.frames import ecef_to_launch_vector

    return ecef_to_launch_vector(site, np.full(3, t), np.eye(3)).T


class _Tracking:
    """Geodetic tracking (t, lat, lon, h, v_east, v_north, v_up) read once, interpolated to any time."""

    def __init__(self, path: str | os.PathLike) -> None:
        from casep.frames import GEODETIC_COLUMNS, geodetic_to_ecef
        from casep.io.tables import Table

        tab = Table(path)
        tab.require(GEODETIC_COLUMNS)
        self.path = path
        self.t = tab.time()
        self.geo = np.column_stack([tab.numeric(c) for c in GEODETIC_COLUMNS[1:4]])
        self.v_enu = np.column_stack([tab.numeric(c) for c in GEODETIC_COLUMNS[4:7]])
        self.r_e, self.v_e = geodetic_to_ecef(*self.geo.T, *self.v_enu.T)

    def at(self, t: float, values: np.ndarray) -> np.ndarray:
        return np.array([np.interp(t, self.t, values[:, c]) for c in range(values.shape[1])])


def _navigate_window(imu, trk: _Tracking, t_a: float, t_b: float, C_eb: np.ndarray):
    """Navigate [t_a, t_b] from the tracked state at t_a and the attitude C_eb (body -> ECEF)."""
    from casep.frames import ecef_to_launch
    from casep.navigation.imu import ImuData
    from casep.navigation.navigator import navigate_from
    from casep.navigation.strapdown import dcm_to_quat

    lat, lon, h = trk.at(t_a, trk.geo)
    site = LaunchSite(float(lat), float(lon), float(h), 0.0, t_a)
    r0, v0 = ecef_to_launch(site, np.array([t_a]), trk.at(t_a, trk.r_e)[None, :], trk.at(t_a, trk.v_e)[None, :])
    sel = (imu.t >= t_a) & (imu.t <= t_b)
    sub = ImuData(imu.t[sel], imu.w[sel], imu.f[sel], source=imu.source)
    nav = navigate_from(sub, site, dcm_to_quat(_launch_from_ecef(site, t_a) @ C_eb), r0[0], v0[0])
    return site, nav


def _separate_nav(nav, site: LaunchSite, trk: _Tracking, model, workdir: str, fit_options: dict,
                  imu_noise: np.ndarray | None = None, instability_tau: float | None = None,
                  given: tuple[float, float] | None = None, reml_rows: list | None = None,
                  white_parts: bool | str = False):
    from casep.checks.tracking_quality import (
        IMU_INSTABILITY_SIZE,
        IMU_INSTABILITY_TAU,
        IMU_NOISE_AT_REST,
        IMU_REML_ROWS,
        IMU_WHITE_PARTS,
    )
    from casep.io.files import read_flight_pair, write_table
    from casep.workflows.separate import separate

    tel = os.path.join(workdir, "window.parquet")
    v_en = np.column_stack([np.interp(nav.t, trk.t, trk.v_enu[:, c]) for c in (0, 1)])
    write_table(tel, {**nav.columns(), GROUND_SPEED_COLUMN: np.hypot(v_en[:, 0], v_en[:, 1])})
    flight = read_flight_pair(tel, trk.path, tracking_frame="geodetic", site=site)
    from casep.workflows.omitted_terms import JUDGED_ELSEWHERE

    # the terms a window's model leaves out: the windows' comparison carries them (separate_windows(consider=...))
    flight.meta[JUDGED_ELSEWHERE] = "casep.workflows.windows"
    if imu_noise is not None:
        flight.meta[IMU_NOISE_AT_REST] = imu_noise
    if instability_tau is not None:
        flight.meta[IMU_INSTABILITY_TAU] = instability_tau
    if given is not None:
        flight.meta[IMU_INSTABILITY_SIZE] = given
    if reml_rows is not None:
        flight.meta[IMU_REML_ROWS] = reml_rows
    if white_parts:
        flight.meta[IMU_WHITE_PARTS] = white_parts
    return flight, separate(flight, model, **fit_options)


def _attitude_error_end(model, result, flight) -> np.ndarray:
    """``phi(T) = phi0 + int phidot dt`` of the estimate, rad, navigation frame of the window."""
    est = dict(zip(result.names, result.estimate))
    D = np.array([est[n] for n in model.names])
    sig = np.column_stack([flight.signals[s] for s in model.signals]) if model.signals else np.zeros((len(flight.t), 0))
    fun = model.functions["phidot"]
    args = [flight.f.T, (flight.t - flight.t[0])[None, :]] + ([sig.T] if model.signals else [])
    n_in = fun.n_in()
    rate = np.array(fun.map(len(flight.t))(*args[:n_in - 1], D)).T  # (N, 3)
    return model.numeric("phi0") @ D + np.trapezoid(rate, flight.t, axis=0)


def separate_windows(imu, tracking: str | os.PathLike, site: LaunchSite, align: tuple[float, float], *,
                     length: float = 30.0, start: float | None = None, model: str = "strapdown6_window",
                     attitude_passes: int = 3, gyro_bias_from_pad: bool = True, imu_noise_from_pad: bool = True,
                     fit_options: dict | None = None, consider: str | None = None,
                     consider_terms: Sequence[str] | None = None,
                     imu_instability_tau: float | None = None, imu_instability_pool: bool = False,
                     imu_instability_measure: str | None = None, imu_white_pool: bool | str = False) -> WindowsResult:
    """Align on the pad, cut the rest of `imu` into windows of `length` s and separate each (module docstring).

    Parameters
    ----------
    imu : casep.navigation.ImuData
        Raw IMU data in the tracking file's time scale.
    tracking : path
        Geodetic tracking: ``t, lat, lon, h, v_east, v_north, v_up`` (deg, m, m/s).
    site : LaunchSite
        The pad (for the alignment; azimuth and launch time are not used further).
    align : (T1, T2)
        The span at rest: levelling, and with `gyro_bias_from_pad` the gyro biases (the mean rate
        minus the Earth rate), removed before navigating (what the windows then estimate is the rest).
        The heading is not known on the pad, so the Earth rate's horizontal part is taken at heading
        0: up to ``omega_E cos(lat)`` of it is left in the windows' gyro biases.
    length : float
        Window length, s.
    start : float, optional
        First window's start (default: the end of `align`).
    model : str
        A window model (instrument terms + ``phi0_*`` + ``dv0_*``).
    attitude_passes : int
        Navigations per window at most (the initial attitude corrected by ``phi0`` between them).
    gyro_bias_from_pad : bool
        Remove the pad's gyro biases before navigating.
    imu_noise_from_pad : bool
        The IMU's white noise density, which each window's std carries as velocity and attitude random
        walks, measured on the pad (:func:`casep.checks.tracking_quality.rest_white_std`, the Allan
        deviation at 1 s) instead of on each window's samples (their second differences, which count a
        moving vehicle's vibration as white sensor noise: on a car drive 2-50 times the density at 1 s).
    fit_options : dict, optional
        Keywords of :func:`casep.separate` (default: none, its default noise path).
    consider : str, optional
        A model that holds instrument terms the window model leaves out (``"strapdown33"``: scale factors,
        misalignments, g-sensitivity): each window's :attr:`Window.consider_gain` is then :func:`consider_gain` of
        `consider_terms` (default: the consider model's terms that the window model does not hold) on the
        window's last navigation, for ``window_consistency(..., consider=(gains, P_c))``.
    consider_terms : sequence of str, optional
        The left-out terms (names of the `consider` model).
    imu_instability_tau : float, optional
        The correlation time (s) of a bias instability of the IMU in each window's std beside its white noise
        (:func:`casep.checks.tracking_quality.imu_bias_effect`): its size per sensor fitted on each window by the
        restricted likelihood beside the tracking noise (``diagnostics["noise"]["imu"]["instability"]``, mg and
        deg/h). Default: white IMU noise only.
    imu_instability_pool : bool
        With `imu_instability_tau`: one size of the instability for the run's windows instead of one per window
        (a single record's restricted likelihood sizes it poorly when its tracking noise is itself correlated): the
        accelerometers' and the gyros' variances ``(q_a, q_g)`` fitted by the restricted likelihood summed over the
        windows, each window's tracking noise refitted at them (:func:`casep.noise.known.pool_parts`), then each
        window separated again with its size given (``meta[IMU_INSTABILITY_SIZE]``: the one rule of the
        instability's covariance). The result's :attr:`WindowsResult.instability` states the size, its interval
        and the windows that hold no refit (a white tracking noise model: their std do not carry the term).
    imu_instability_measure : str, optional
        With `imu_instability_pool`: the instability's variances scaled per window by a fit-free measure of what
        the vehicle does there, ``q_k = m_k q`` (one pooled ``q`` per sensor): ``"vibration"`` the accelerometers'
        power in :data:`VIBRATION_BAND_HZ` beyond the pad's (:func:`vibration_power`, (m/s^2)^2: zero at rest
        with the engine as on the pad), ``"speed"`` the window's mean tracked ground speed (m/s). Default: 1 per
        window (one size for all).
    imu_white_pool : bool or "gyro"
        With `imu_noise_from_pad`: the IMU's white noise in motion sized once for the run's windows, per sensor: the
        densities at rest times ``sqrt(k_a)`` (accelerometers) and ``sqrt(k_g)`` (gyros), ``(k_a, k_g)`` fitted by the
        restricted likelihood summed over the windows (:func:`casep.noise.known.pool_parts`, each window's tracking
        noise refitted at them; with `imu_instability_pool` jointly with the instability's variances), then each
        window separated again with its densities (``meta[IMU_NOISE_AT_REST]``). :attr:`WindowsResult.instability`
        states the scales, their intervals and ``-2 l_R`` at the density at rest, ``(1, 1)``. ``"gyro"``: the gyros'
        scale only, the accelerometers' density the one at rest (``k_a = 1``).

    Returns
    -------
    WindowsResult
        The windows (each with its :class:`~casep.EstimateResult`) and :func:`window_consistency` of
        the instrument coefficients (the model's names without :data:`NUISANCE_PREFIXES`).
    """
    from casep.model.loader import load_model
    from casep.model.strapdown import corrected_attitude
    from casep.navigation.alignment import course_rotation
    from casep.navigation.imu import ImuData
    from casep.navigation.navigator import navigate
    from casep.navigation.strapdown import quat_from_rotvec, quat_to_dcm

    if imu_instability_measure is not None and not imu_instability_pool:
        raise ValueError("imu_instability_measure scales a pooled instability: give imu_instability_pool=True")
    if imu_instability_pool and imu_instability_tau is None:
        raise ValueError("imu_instability_pool needs the instability's correlation time (imu_instability_tau)")
    if imu_white_pool not in (False, True, "gyro"):
        raise ValueError(f"imu_white_pool: True, 'gyro' or False, got {imu_white_pool!r}")
    if imu_white_pool and not imu_noise_from_pad:
        raise ValueError("imu_white_pool scales the white noise measured at rest: give imu_noise_from_pad=True")
    if imu_white_pool and imu_instability_tau is not None and not imu_instability_pool:
        raise ValueError("imu_white_pool with an instability pools both: give imu_instability_pool=True")
    pool = imu_instability_pool or imu_white_pool
    if imu_instability_measure not in (None, "vibration", "speed"):
        raise ValueError(f"imu_instability_measure: 'vibration', 'speed' or None, got {imu_instability_measure!r}")
    trk = _Tracking(tracking)
    base = load_model(model)
    extra = load_model(consider) if consider is not None else None  # built and set up once, for every window
    terms = () if extra is None else tuple(consider_terms) if consider_terms is not None else \
        tuple(n for n in extra.names if n not in base.names)
    nav0 = navigate(imu, site, align, heading_deg=0.0)
    a = nav0.alignment
    assert a is not None  # navigate always aligns
    if gyro_bias_from_pad:
        imu = ImuData(imu.t, imu.w - (a.w_mean - a.C_tb.T @ site.earth_rate), imu.f, source=imu.source)
        nav0 = navigate(imu, site, align, heading_deg=0.0)
    imu_noise = None
    if imu_noise_from_pad:
        from casep.checks.tracking_quality import rest_white_std

        pad = (imu.t >= align[0]) & (imu.t <= align[1])
        imu_noise = rest_white_std(np.column_stack([imu.f[pad], imu.w[pad]]), float(np.median(np.diff(imu.t[pad]))))
    pad_power = vibration_power(imu, *align) if imu_instability_measure == "vibration" else 0.0
    pooled: list[tuple] = []  # per window: (navigation, site, the refit's rows or None, measure)
    t_a = float(align[1] if start is None else start)
    j = int(np.searchsorted(nav0.t, t_a))
    t_a = float(nav0.t[j])
    C_eb = _launch_from_ecef(site, t_a).T @ quat_to_dcm(nav0.q[j])
    windows: list[Window] = []
    with tempfile.TemporaryDirectory() as workdir:
        while t_a + length <= min(imu.t[-1], trk.t[-1]):
            t_b = t_a + length
            course = None
            if not windows:  # the heading is unknown at the start: the tracked course turns it
                s0, n0 = _navigate_window(imu, trk, t_a, t_b, C_eb)
                _, v_e = n0.earth_relative()
                psi = course_rotation(n0.t, v_e, trk.t, trk.v_e, trk.at(t_a, trk.r_e))
                C_eb = quat_to_dcm(quat_from_rotvec(psi * _up(trk.at(t_a, trk.r_e)))) @ C_eb
                course = math.degrees(psi)
            for passes in range(1, attitude_passes + 1):
                site_k, nav = _navigate_window(imu, trk, t_a, t_b, C_eb)
                kept: list | None = [] if pool else None
                flight, res = _separate_nav(nav, site_k, trk, model, workdir, dict(fit_options or {}), imu_noise,
                                            imu_instability_tau, (0.0, 0.0) if imu_instability_pool else None, kept,
                                            imu_white_pool)
                est = dict(zip(res.names, res.estimate))
                phi0 = base.numeric("phi0") @ np.array([est[n] for n in base.names])
                if np.linalg.norm(phi0) <= PHI0_LINEAR_RAD or passes == attitude_passes:
                    break
                M = _launch_from_ecef(site_k, t_a)
                C_eb = M.T @ corrected_attitude(M @ C_eb, phi0)
            from casep.model.sv import build_sv

            S = build_sv(base, flight.t, flight.f, signals=flight.signals)
            windows.append(Window(t_a, float(nav.t[-1]), site_k, res, passes, course, S[-1], base.names))
            if extra is not None:
                windows[-1].consider_gain = consider_gain(flight, res, base, extra, terms)
                windows[-1].consider_names = terms
            if kept is not None:
                m = 1.0 if imu_instability_measure is None else \
                    max(vibration_power(imu, t_a, float(nav.t[-1])) - pad_power, 0.0) \
                    if imu_instability_measure == "vibration" else \
                    float(np.mean(np.hypot(*[np.interp(nav.t, trk.t, trk.v_enu[:, c]) for c in (0, 1)])))
                pooled.append((nav, site_k, kept[-1] if kept else None, m))
            phi_end = _attitude_error_end(base, res, flight)
            t_a = float(nav.t[-1])
            C_lb = corrected_attitude(quat_to_dcm(nav.q[-1]), phi_end)
            C_eb = _launch_from_ecef(site_k, t_a).T @ C_lb
        instability = None
        if pool:
            instability = _pool_instability(windows, pooled, imu_instability_tau, imu_instability_measure,
                                            lambda nav, site, given, noise: _separate_nav(
                                                nav, site, trk, model, workdir, dict(fit_options or {}), noise,
                                                imu_instability_tau, given)[1],
                                            imu_noise if imu_white_pool else None,
                                            imu_white_pool == "gyro")
    names = tuple(n for n in base.names if not n.startswith(NUISANCE_PREFIXES))
    return WindowsResult(windows, names, window_consistency(windows, names), instability)


#: The band (Hz) of :func:`vibration_power`: above a road vehicle's own motion (its manoeuvres, and its body on the
#: springs, below a few Hz), up to 0.45 of the sampling rate (None).
VIBRATION_BAND_HZ: tuple[float, float | None] = (10.0, None)


def vibration_power(imu, t_a: float, t_b: float, band: tuple[float, float | None] = VIBRATION_BAND_HZ) -> float:
    """The accelerometers' mean power in `band` over ``[t_a, t_b]``, summed over the three axes, (m/s^2)^2: the
    specific force band-passed (Butterworth of order 4, forwards and backwards: no phase), its squares averaged.
    White sensor noise of density ``s`` adds ``3 s^2 (f_hi - f_lo)`` (the pad's part is what a window's measure
    takes away, :func:`separate_windows`' ``imu_instability_measure``)."""
    from scipy.signal import butter, sosfiltfilt

    sel = (imu.t >= t_a) & (imu.t <= t_b)
    t = imu.t[sel]
    if t.size < 64:
        raise ValueError(f"vibration_power: {t.size} samples in {t_a:.3f}-{t_b:.3f} s, 64 at least")
    rate = 1.0 / float(np.median(np.diff(t)))
    lo, hi = band[0], 0.45 * rate if band[1] is None else band[1]
    if not 0.0 < lo < hi < rate / 2.0:
        raise ValueError(f"vibration_power: the band {lo:g}-{hi:g} Hz is not within 0-{rate / 2:g} Hz")
    x = sosfiltfilt(butter(4, [lo, hi], "bandpass", fs=rate, output="sos"), imu.f[sel], axis=0)
    return float(np.mean(np.sum(x**2, axis=1)))


def _pool_instability(windows: list[Window], pooled: list[tuple], tau: float | None, measure: str | None,
                      again, white: np.ndarray | None = None, gyro_only: bool = False) -> dict[str, Any]:
    """Size the instability (correlation time `tau`; None: none) and, with `white` (the densities at rest, 6), the
    white noise's two scales once for the windows (:func:`casep.noise.known.pool_parts` over the refits' rows kept in
    `pooled`: the white scales first, weight 1, then the instability's variances, weight the window's measure), then
    separate each window again at its size (`again(nav, site, given, densities)`); the record of
    :attr:`WindowsResult.instability`. `gyro_only`: the gyros' scale only (the rows hold one white part), the
    accelerometers' 1."""
    from casep.noise.known import pool_parts
    from casep.units import G0

    n_w, n_i = (0 if white is None else 1 if gyro_only else 2), (0 if tau is None else 2)
    have = [k for k, p in enumerate(pooled) if p[2] is not None and windows[k].result.success]
    if not have or (n_w == 0 and not any(pooled[k][3] > 0 for k in have)):
        return {"tau_s": tau, "measure": measure, "pooled": None,
                "note": "no window holds a refit beside the IMU's noise with a measure above 0: nothing sized"}
    weights = [[1.0] * n_w + [pooled[k][3]] * n_i for k in have]
    got = pool_parts([pooled[k][2] for k in have], weights,
                     reference=None if white is None else (1.0,) * n_w + (0.0,) * n_i)
    q = np.array(got.q)
    k_w, q_i = (np.concatenate([[1.0], q[:1]]) if gyro_only else q[:n_w]), q[n_w:]
    scale = None if white is None else np.sqrt(np.repeat(k_w, 3))
    for k in range(len(pooled)):
        nav, site, _, m = pooled[k]
        if not windows[k].result.success:
            continue
        if white is not None or (k in have and m > 0 and np.any(q_i > 0)):  # else its first separation stands
            windows[k].result = again(nav, site, None if tau is None else tuple(float(v) for v in m * q_i),
                                      None if white is None else white * scale)

    def natural(v: float, i: int) -> float:
        return math.sqrt(v) / G0 * 1e3 if i == 0 else math.degrees(math.sqrt(v)) * 3600.0

    out: dict[str, Any] = {"tau_s": tau, "measure": measure, "pooled": got.to_dict(),
                           "measures": [float(p[3]) for p in pooled],
                           "not_pooled": [windows[k].t_start for k in range(len(pooled)) if k not in have]}
    if white is not None:
        out.update({"white_variance_scale": [float(v) for v in k_w],
                    "white_variance_scale_interval": ([[1.0, 1.0]] if gyro_only else [])
                    + [list(got.interval[i]) for i in range(n_w)],
                    "white_at_rest": [float(v) for v in white],
                    "neg2_reml_at_rest_density": got.reference[1] if got.reference else None})
    if tau is not None:
        unit = {None: "1", "vibration": "(m/s^2)^2", "speed": "m/s"}[measure]
        out.update({"measure_unit": unit, "accelerometer_mg_per_unit": natural(q_i[0], 0),
                    "gyro_deg_h_per_unit": natural(q_i[1], 1),
                    "interval_mg_per_unit": [natural(v, 0) for v in got.interval[n_w]],
                    "interval_deg_h_per_unit": [natural(v, 1) for v in got.interval[n_w + 1]]})
    out["rule"] = ("one size for the windows, fitted by the restricted likelihood summed over them, each window's "
                   "tracking noise refitted at it (casep.noise.known.pool_parts)"
                   + ("; the white noise's densities in motion: those at rest times sqrt(k_a), sqrt(k_g)"
                      if white is not None else "")
                   + ("; a first-order Gauss-Markov bias per body axis of the accelerometers and the gyros, correlation"
                      " time given, variances m_k (q_a, q_g) in window k, m_k the fit-free measure (1 without one)"
                      if tau is not None else "")
                   + "; each window separated again at its size")
    return out


def gain_rows(S_w: np.ndarray, S_c: np.ndarray, t: np.ndarray, noise: Any = None) -> np.ndarray:
    """The consider gain ``A = (S_w^T W S_w)^-1 S_w^T W S_c`` (n x m) of a fit of the columns `S_w` (N, 3, n)
    whose data also hold ``S_c c`` (`S_c` (N, 3, m)), ``W`` the inverse of the rows' covariance under `noise`
    (a :class:`casep.noise.model.NoiseModel`; None: white, ordinary least squares), rows at the times `t` (N,).

    The fit's estimate of its own columns moves by ``A c``. Both sets of columns are whitened as the fit whitens
    its rows (:func:`casep.noise.model.whiten`), then ``A`` is the least-squares solution of the whitened ``S_w``
    for the whitened ``S_c`` (columns of ``S_w`` scaled to unit norm first; a column the rows do not determine
    takes the minimum-norm solution, as the fit's pseudo-inverse does)."""
    from casep.noise.model import NoiseModel, whiten

    S_w, S_c = np.asarray(S_w, float), np.asarray(S_c, float)
    N, _, n = S_w.shape
    m = S_c.shape[2]
    noise = NoiseModel.white() if noise is None else noise
    both = whiten(np.concatenate([S_w, S_c], axis=2), np.zeros((N, 3)), np.asarray(t, float), noise)[0]
    U = both.reshape(3 * N, n + m)
    scale = np.linalg.norm(U[:, :n], axis=0)
    scale[scale == 0.0] = 1.0
    A = np.linalg.lstsq(U[:, :n] / scale, U[:, n:], rcond=None)[0]
    return A / scale[:, None]


def consider_gain(flight, result, fit_model, consider_model, terms: Sequence[str]) -> np.ndarray:
    """The consider gain of one window's fit (:func:`gain_rows`): rows the names of `result` (its model `fit_model`,
    plus ``dt_trk`` when the fit added it), columns `terms`, S_V columns of `consider_model` (set up) along the
    same flight, whitened by the fit's noise model (``result.diagnostics["noise"]``; white when it has none).

    What it does not take: the robust filter's row weights and rejected rows (the fit's final pass keeps all
    rows at weights near 1 on a clean window) and the passes of an iterated fit (the gain is the linear fit's at
    the window's last navigation)."""
    from casep.checks.flight import flight_problem
    from casep.model.loader import TIME_OFFSET, load_model, with_time_offset
    from casep.noise.model import NoiseModel

    model = load_model(with_time_offset(fit_model)) if TIME_OFFSET in result.names else fit_model
    if tuple(model.names) != tuple(result.names):
        raise ValueError(f"consider_gain: the fit's names {tuple(result.names)} are not its model's {model.names}")
    missing = [n for n in terms if n not in consider_model.names]
    if missing:
        raise ValueError(f"consider_gain: {missing} not in the consider model `{consider_model.name}`")
    pb_w = flight_problem(flight, model, keep_sv=True)
    pb_c = flight_problem(flight, consider_model, keep_sv=True)
    if pb_w.t is None or pb_c.t is None or not np.array_equal(pb_w.t, pb_c.t):
        raise ValueError("consider_gain: the two models' rows are not the same samples")
    cols = [consider_model.names.index(n) for n in terms]
    nd = (result.diagnostics or {}).get("noise")
    noise = NoiseModel.from_dict(nd) if isinstance(nd, dict) and "axes" in nd else None
    return gain_rows(pb_w.sv(), pb_c.sv()[:, :, cols], pb_w.t, noise)


def consider_rows(windows: Sequence[Window], names: Sequence[str]) -> list[np.ndarray]:
    """Each window's :attr:`Window.consider_gain` restricted to the rows `names`: the gains of
    ``window_consistency(windows, names, consider=(gains, P_c))``, columns :attr:`Window.consider_names`."""
    out = []
    for w in windows:
        if w.consider_gain is None:
            raise ValueError(f"window at {w.t_start:.3f} s has no consider gain (separate_windows(consider=...))")
        rows = list(w.result.names)
        out.append(np.asarray(w.consider_gain, float)[[rows.index(n) for n in names]])
    return out


def _up(r_e: np.ndarray) -> np.ndarray:
    from casep.gravity import normal_gravity_ecef

    g = normal_gravity_ecef(r_e)
    return -g / np.linalg.norm(g)


def _instrument(window: Window, names: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
    res = window.result
    idx = [res.names.index(n) for n in names]
    cov = np.full((len(idx), len(idx)), np.nan) if res.covariance is None else res.covariance[np.ix_(idx, idx)]
    return res.estimate[idx], cov


def _joint_chi2(xs: Sequence[np.ndarray], covs: Sequence[np.ndarray], gains: Sequence[np.ndarray],
                P_c: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """Chi-square of windows about their common value when a left-out vector ``c ~ (0, P_c)``, the same in every
    window, moves window ``k``'s estimate by ``A_k c``: the stacked estimates' covariance has blocks
    ``delta_ij C_i + A_i P_c A_j^T``; returns (chi2, generalised least-squares common value, joint covariance)."""
    K, p = len(xs), len(xs[0])
    A = np.vstack([np.asarray(a, float).reshape(p, -1) for a in gains])
    S = A @ P_c @ A.T
    for k, c in enumerate(covs):
        S[k * p:(k + 1) * p, k * p:(k + 1) * p] += c
    H = np.tile(np.eye(p), (K, 1))
    x = np.concatenate(xs)
    Si = np.linalg.pinv(S)
    xbar = np.linalg.solve(H.T @ Si @ H, H.T @ Si @ x)
    r = x - H @ xbar
    return float(r @ Si @ r), xbar, S


def window_consistency(windows: Sequence[Window], names: Sequence[str],
                       instability: dict[str, float] | None = None,
                       consider: tuple[Sequence[np.ndarray], np.ndarray] | None = None) -> dict[str, Any]:
    """Do the windows' instrument coefficients agree, and does each predict the others' dv?

    Agreement: with ``x_k``, ``C_k`` each window's estimate and covariance of the coefficients
    `names`, the weighted mean ``xbar = (sum C_k^-1)^-1 sum C_k^-1 x_k`` and

        chi2 = sum_k (x_k - xbar)^T C_k^-1 (x_k - xbar),   dof = (K - 1) p

    (also per coefficient, from the diagonal); the windows agree when the p-value is above 1 %.

    `instability` (coefficient name -> std, the coefficient's units) is how much the instrument's
    coefficient itself wanders from window to window (a bias instability), measured apart from the
    windows (an Allan deviation, the sensor at rest at several times): each window's true value is
    then the common one plus an independent offset of that std, and ``C_k`` becomes
    ``C_k + diag(sigma^2)`` everywhere below. It must not be estimated from the spread it is judged by.

    `consider` = (gains, P_c): instrument terms the windows' model leaves out (scale factors, misalignments),
    the same vector ``c`` of covariance ``P_c`` in every window, moving window ``k``'s estimate by ``A_k c``
    (``gains[k]`` = ``A_k``, p x m, one per window in `windows`' order; the consider gain
    ``(S_w^T W S_w)^-1 S_w^T W S_c``). The windows' estimates are then correlated: chi2 is that of the stacked
    estimates about their generalised-least-squares common value against the joint covariance of blocks
    ``delta_ij C_i + A_i P_c A_j^T`` (a gain common to all windows shifts them all alike and adds nothing), and
    a prediction's std uses ``C_i + C_j + (A_i - A_j) P_c (A_i - A_j)^T``.

    Prediction: window ``i``'s coefficients predict window ``j``'s dv at its end by
    ``s_j (x_i - x_j)`` away from what ``j``'s own fit gives (``s_j`` the rows of S_V at ``j``'s
    last sample, instrument columns), with std ``sqrt(s_j (C_i + C_j) s_j^T)`` per axis; the fractions
    of ``|z| <= 1`` and ``<= 2`` over all ordered pairs and axes (0.68 and 0.95 when they agree).
    """
    from scipy.stats import chi2 as chi2_dist

    used = [k for k, w in enumerate(windows) if w.result.success and w.result.covariance is not None]
    ok = [windows[k] for k in used]
    xs, covs = zip(*(_instrument(w, names) for w in ok)) if ok else ((), ())
    p = len(names)
    wander = np.array([float((instability or {}).get(n, 0.0)) for n in names])
    if np.any(~np.isfinite(wander)) or np.any(wander < 0.0):
        raise ValueError(f"instability: each std must be finite and >= 0, got {instability!r}")
    covs = tuple(c + np.diag(wander**2) for c in covs)
    gains: list[np.ndarray] | None = None
    if consider is not None:
        all_gains, P_c = consider
        P_c = np.atleast_2d(np.asarray(P_c, float))
        if len(all_gains) != len(windows):
            raise ValueError(f"consider: {len(all_gains)} gains for {len(windows)} windows")
        gains = [np.asarray(all_gains[k], float).reshape(p, P_c.shape[0]) for k in used]
    out: dict[str, Any] = {"windows": len(windows), "used": len(ok), "names": list(names),
                           "instability": {n: float(v) for n, v in zip(names, wander)}}
    if len(ok) < 2:
        return {**out, "agree": False, "message": f"{len(ok)} window(s) with a covariance: nothing to compare"}
    dof = (len(ok) - 1) * p
    if gains is None:
        W = [np.linalg.pinv(c) for c in covs]
        xbar = np.linalg.solve(sum(W), sum(w @ x for w, x in zip(W, xs)))
        chi2 = float(sum((x - xbar) @ w @ (x - xbar) for w, x in zip(W, xs)))
        per = {n: float(sum((x[i] - xbar[i]) ** 2 / c[i, i] for x, c in zip(xs, covs)))
               for i, n in enumerate(names)}
    else:
        chi2, xbar, _ = _joint_chi2(xs, covs, gains, P_c)
        per = {n: _joint_chi2([x[[i]] for x in xs], [c[np.ix_([i], [i])] for c in covs],
                              [g[[i]] for g in gains], P_c)[0] for i, n in enumerate(names)}
    z = []
    for j, wj in enumerate(ok):
        if not wj.sv_end.size or not set(names) <= set(wj.sv_names):
            continue
        s = wj.sv_end[:, [wj.sv_names.index(n) for n in names]]
        for i in range(len(ok)):
            if i != j:
                cij = covs[i] + covs[j]
                if gains is not None:
                    dA = gains[i] - gains[j]
                    cij = cij + dA @ P_c @ dA.T
                sd = np.sqrt(np.einsum("ap,pq,aq->a", s, cij, s))
                z.append(s @ (xs[i] - xs[j]) / sd)
    zz = np.abs(np.concatenate(z)) if z else np.array([])
    pval = float(chi2_dist.sf(chi2, dof))
    return {**out, "chi2": chi2, "dof": dof, "p_value": pval, "agree": pval > 0.01, "weighted_mean": xbar.tolist(),
            "chi2_per_coefficient": per, "prediction_pairs": len(z),
            "within_1_std": float(np.mean(zz <= 1.0)) if zz.size else None,
            "within_2_std": float(np.mean(zz <= 2.0)) if zz.size else None,
            "median_abs_z": float(np.median(zz)) if zz.size else None}

"""A telemetry + tracking pair in arrays: tracking frames, time scales, gaps, the merged flight.

:func:`pair_flight` forms dv from telemetry and tracking held in arrays on the grid asked for
(:func:`casep.io.files.read_flight_pair` reads the two files and calls it); the helpers here turn
Earth-fixed tracking (ECEF, geodetic) into the launch-inertial velocity (:mod:`casep.frames`),
check the stated launch time and time scales against the files, and find the gaps that
interpolation must not bridge (a :class:`~casep.exceptions.GapWarning` then).
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from casep._kernels import cumulative_trapezoid, runs
from casep.io.flight import DUPLICATE_STEP, FlightData
from casep.io.tables import VTRK_COLUMNS, Table

__all__ = ["pair_flight", "PAIR_GRIDS", "STATE_SIGNALS", "GAP_FACTOR", "GAP_MIN_S", "MAX_TIME_OFFSET",
           "MAX_LAUNCH_TIME_GAP", "check_tracking_frame", "tracking_velocity", "tracking_hint", "with_tracked_state",
           "time_shift_seconds", "MAX_CLOCK_DRIFT_PPM", "clock_drift_ppm", "telemetry_time", "tracking_time",
           "drift_pivot",
           "check_launch_time", "no_overlap_message",
           "check_earth_fixed_units", "check_velocity_columns", "velocity_column_misfit", "COLUMN_WINDOW_S",
           "COLUMN_RATIO", "COLUMN_MISFIT_MIN", "fits_time_offset", "VALID_COLUMN", "repeated_rows",
           "stale_epochs", "held_epochs", "position_gap", "rest_window", "STALE_MOTION", "STALE_POSITION", "JUMP_RATE",
           "HELD_SHARE", "HELD_RUN_SHARE", "PairInputs",
           "repaired", "offset_second_order"]

#: The telemetry column marking the samples whose navigation solution is trusted (1) or not (0: after a clipped
#: IMU sample, :mod:`casep.navigation.imu`): :func:`pair_flight` leaves the rows where it is below 1 out.
VALID_COLUMN = "ins_valid"

def fits_time_offset(meta) -> bool:
    """Whether a flight's fit gains the tracking time offset ``dt_trk`` by default (the one rule).

    Yes when the tracking time tags were aligned automatically (``time_alignment`` mode ``auto``:
    the alignment's error of a few ms is left to estimate), or when the tracking comes from an
    Earth-fixed range (``tracking_frame`` ECEF or geodetic), whose clock is not the telemetry's: the
    offset between the two clocks is an ordinary range error, estimated jointly with its std
    (``dv += a(t) dt_trk``, :func:`casep.model.loader.with_time_offset`) instead of biasing the
    coefficients that correlate with the kinematic acceleration.

    The radar path decides its time terms elsewhere, and they are not this idea written twice: a radar
    station's time-tag delay is its tracking model's ``time_bias`` (one per station, always in the
    ``radar_biases`` model: each station is a range clock, as Earth-fixed tracking is here), the twin of
    ``dt_trk`` in the measurement domain (column ``dh/dt`` of the predicted range and angles instead of
    ``a(t)``); its ``dt_launch`` (:data:`casep.radar.regression.LAUNCH_TIME`, fitted with two or more
    stations) is an error of the launch epoch, which turns the launch-inertial frame about the Earth's
    axis by ``omega_E dt_launch`` -- no delay of any time tag. ``read_flight_pair(..., time_offset="auto")``
    is no estimate either: the coarse shift that lines the velocities up before the fit, whose rest this
    rule leaves to ``dt_trk``.

    Parameters
    ----------
    meta : dict
        The flight's ``meta`` (:func:`casep.io.files.read_flight_pair`).
    """
    if not isinstance(meta, dict):
        return False
    align = meta.get("time_alignment")
    return (isinstance(align, dict) and align.get("mode") == "auto") or isinstance(meta.get("tracking_frame"), dict)


#: Where a telemetry + tracking pair is evaluated (``read_flight_pair(grid=...)``).
PAIR_GRIDS = ("tracking", "telemetry")


def check_tracking_frame(tracking: str | os.PathLike, tracking_frame: str, site) -> None:
    """`tracking_frame` is one of casep.frames.TRACKING_FRAMES; an Earth-fixed one needs a LaunchSite."""
    from casep.frames import TRACKING_FRAMES, LaunchSite

    if tracking_frame not in TRACKING_FRAMES:
        raise ValueError(f"`tracking_frame` must be one of {', '.join(TRACKING_FRAMES)}, got {tracking_frame!r}")
    if tracking_frame == "launch" and site is not None:
        raise ValueError(f"{tracking}: `site` is used only with an Earth-fixed tracking_frame ('ecef' or 'geodetic'); "
                         "launch-frame tracking needs no site")
    if tracking_frame != "launch" and not isinstance(site, LaunchSite):
        raise ValueError(f"{tracking}: {tracking_frame} tracking needs the launch site and launch time to be turned "
                         "into the launch-inertial frame: give site=LaunchSite(lat_deg, lon_deg, h_m, azimuth_deg, t0) "
                         "(CLI: --launch-site LAT LON H AZ --launch-time T0)")


def tracking_velocity(trk: Table, t_trk: np.ndarray, tracking_frame: str,
                      site) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None, np.ndarray | None]:
    """The tracking velocity in the launch-inertial frame, m/s (casep.frames), from the file's own time tags,
    and (Earth-fixed frames) the tracked ECEF position and Earth-relative velocity and the launch-inertial position
    (m, m/s, m; None for launch)."""
    from casep.frames import ECEF_COLUMNS, GEODETIC_COLUMNS, ecef_to_launch, geodetic_to_ecef

    if tracking_frame == "launch":
        return trk.vectors(VTRK_COLUMNS), None, None, None
    if tracking_frame == "ecef":
        r, v = trk.vectors(ECEF_COLUMNS[1:4]), trk.vectors(ECEF_COLUMNS[4:7])
    else:
        lat, lon, h, ve, vn, vu = (trk.numeric(c) for c in GEODETIC_COLUMNS[1:])
        for col, values, lim in (("lat", lat, 90.0), ("lon", lon, 360.0)):
            bad = np.flatnonzero(np.abs(values) > lim)
            if bad.size:
                raise trk.error(f"{values[bad[0]]:g} deg is outside +-{lim:g} deg (latitude and longitude in degrees)",
                                col, int(bad[0]) + 1)
        r, v = geodetic_to_ecef(lat, lon, h, ve, vn, vu)
    check_earth_fixed_units(trk, t_trk, r, v, tracking_frame)
    if tracking_frame == "geodetic":
        check_velocity_columns(trk, t_trk, r, np.column_stack([ve, vn, vu]), tracking_frame, _enu_axes(lat, lon))
    else:
        check_velocity_columns(trk, t_trk, r, v, tracking_frame)
    r_l, v_l = ecef_to_launch(site, t_trk, r, v)
    return v_l, r, v, r_l


#: A repeated fix is stale when the telemetry moved by more than this since the fix it repeats, m/s.
STALE_MOTION = 0.5
#: A repeated position is stale when the telemetry moved away from it by more than this plus :data:`STALE_MOTION` times
#: the time since the fix it repeats, m. The repeat shares its fix's error (the metres of a code solution's, which
#: change over minutes), so what a fresh fix would show is the movement against its noise between consecutive fixes:
#: decimetres for a code solution, centimetres for a carrier-phase one; 1 m is beyond both. The time term is the
#: velocity rule integrated: an INS whose velocity stays within :data:`STALE_MOTION` of the fix's moves by less.
STALE_POSITION = 1.0
#: The instrument errors' allowance of the physics check (:mod:`casep.checks.tracking_quality`, with its
#: ``JUMP_TOL``) and of a held velocity's run, m/s^2.
JUMP_RATE = 2.0


def stale_epochs(t: np.ndarray, V: np.ndarray, dv: np.ndarray, repeated: np.ndarray,
                 frozen: np.ndarray | None = None, gap: np.ndarray | None = None,
                 rest: tuple[float, float] | list[float] | None = None) -> np.ndarray:
    """The stale tracking epochs (:mod:`casep.checks.tracking_quality`'s notes), (N,) bool: the repeats of a fix
    (`repeated`, the epochs whose file row repeats the previous one's velocity, :func:`repeated_rows`) while the
    telemetry moved by more than :data:`STALE_MOTION` since the fix, the repeats of a position (`frozen`, the epochs
    whose file row repeats the previous one's position) while the telemetry moved from it by more than
    :data:`STALE_POSITION` plus :data:`STALE_MOTION` times the time since the fix (beyond the telemetry's own
    velocity error at the fix, `dv` there, carried on), and the epochs of a velocity held
    with a jitter (:func:`held_epochs`). `t`: the epochs' times (s), `V`: the telemetry's velocity change there (m/s,
    any constant), `dv`: ``v_tel - v_trk`` there (m/s), `gap`: the telemetry's position less the tracking's there
    (m, any constant, :func:`position_gap`; NaN: not judged).

    Telemetry and tracking are compared in one frame: the velocity moved is the change of `dv` (the tracking turned
    into the telemetry's frame at each epoch's own time, :func:`casep.frames.ecef_to_launch`), not of `V`: a repeated
    Earth-fixed fix of a vehicle at rest is carried by the Earth's rotation as the telemetry is (0.02 m/s^2 in the
    launch-inertial frame at 51 deg), and a frozen position likewise. `rest` ``(T1, T2)``, s: where the vehicle is
    at rest by the navigation's own premise (the window it was levelled over, ``--align``): a repeat there is right
    and is a fix the later repeats are judged from (an INS not yet corrected, a first pass, drifts over a long pad
    while the vehicle stands: 1.45 m/s in 60 s with a tactical IMU). The one rule of the screen
    (:func:`casep.checks.tracking_quality.screen_tracking`) and of the coarse time alignment
    (:func:`casep.io.align.fresh_epochs`)."""
    moving = np.ones(t.size, bool) if rest is None else ~((t >= rest[0]) & (t <= rest[1]))
    out = _departed(t, dv, np.asarray(repeated, bool) & moving, STALE_MOTION, 0.0) | held_epochs(t, V, dv)
    if frozen is not None and gap is not None:
        out |= _departed(t, gap, np.asarray(frozen, bool) & moving, STALE_POSITION, STALE_MOTION, dv)
    return out


def rest_window(meta: dict) -> list[float] | None:
    """Where the vehicle stood by the navigation's premise, ``[T1, T2]`` s of the flight's time: the window an IMU was
    levelled over (``meta["rest_window_s"]``: :func:`casep.io.files.read_flight_pair`'s `rest_window`, the ``--align``
    of :mod:`casep.workflows.imu_separate`) or the one a navigated telemetry's header names
    (``meta["levelled"]["window"]``); None when neither. The one rule of the tracking screen
    (:func:`casep.checks.tracking_quality.screen_tracking`) and of the coarse time alignment
    (:func:`casep.io.align.fresh_epochs`, :func:`casep.io.files.read_flight_pair`) for the window
    :func:`stale_epochs` takes as `rest`."""
    window = meta.get("rest_window_s") or (meta.get("levelled") or {}).get("window")
    return None if window is None else [float(window[0]), float(window[1])]


def _departed(t: np.ndarray, x: np.ndarray, repeated: np.ndarray, limit: float, rate: float,
              slope: np.ndarray | None = None) -> np.ndarray:
    """The `repeated` epochs (the first epoch never is) at which `x` (N, k) moved from its value at the fix they
    repeat (the last epoch before them not repeated) by more than ``limit + rate (t - t_fix)``: :func:`stale_epochs`'
    rule for a velocity and for a position. `slope` (N, k): `x` is expected to go on from the fix at ``slope`` there
    (a position gap at the velocity gap ``dv`` of the fix: the telemetry's own velocity error then, which a vehicle
    at rest under a held fix shows as well as a moving one)."""
    is_rep = np.asarray(repeated, bool).copy()
    if is_rep.size:
        is_rep[0] = False
    anchor = np.maximum.accumulate(np.where(~is_rep, np.arange(is_rep.size), 0))  # the fix each epoch repeats
    since = t - t[anchor]
    moved = np.linalg.norm(x - x[anchor] - (0.0 if slope is None else slope[anchor] * since[:, None]), axis=1)
    return is_rep & (moved > limit + rate * since)


def position_gap(t_tel: np.ndarray, v_tel: np.ndarray, t_trk: np.ndarray, r_trk: np.ndarray) -> np.ndarray:
    """The telemetry's position less the tracking's at the tracking times `t_trk`, (M, 3) m, up to a constant: the
    telemetry velocity `v_tel` (launch-inertial, at `t_tel`) integrated from ``t_tel[0]`` (its cubic spline's
    antiderivative, the spline the pair carries the velocity by) less `r_trk` (the tracked launch-inertial position,
    :func:`casep.frames.ecef_to_launch` of the file's); NaN outside the telemetry's span. What
    :func:`stale_epochs` judges a frozen position by."""
    from scipy.interpolate import CubicSpline

    t_trk = np.asarray(t_trk, dtype=float)
    out = np.full((t_trk.size, 3), np.nan)
    inside = (t_trk >= t_tel[0]) & (t_trk <= t_tel[-1])
    if t_tel.size >= 2 and inside.any():
        out[inside] = CubicSpline(t_tel, np.asarray(v_tel, dtype=float), axis=0).antiderivative()(t_trk[inside]) \
            - np.asarray(r_trk, dtype=float)[inside]
    return out


#: A tracking velocity that changes between two epochs by at most this share of what the telemetry's velocity
#: changed (the kinematic acceleration integrated) is held there (:func:`held_epochs`) ...
HELD_SHARE = 0.1
#: ... and a run of such epochs over which the telemetry moved by more than :data:`STALE_MOTION` plus
#: :data:`JUMP_RATE` times its duration (the instrument errors' share: a MEMS INS on the pad drifts by 0.2 m/s per s
#: while a right tracking holds still) while the tracking changed by at most this share of it is stale, however it
#: jitters.
HELD_RUN_SHARE = 0.1


def held_epochs(t: np.ndarray, V: np.ndarray, dv: np.ndarray) -> np.ndarray:
    """The epochs of a tracking velocity held while the vehicle accelerates: not repeated exactly (a receiver that
    holds its last velocity and adds a few mm/s of jitter; :func:`casep.io.pair.repeated_rows` finds exact repeats
    only) but the physics rules it out.

    The tracking's own change between consecutive epochs is ``dV - d(dv)`` (``V`` the telemetry's velocity change,
    ``dv = v_tel - v_trk``). An epoch is held when that change is at most :data:`HELD_SHARE` of ``|dV|``; a run of
    held epochs is stale when over it (from the epoch before it, the last fresh one) the telemetry moved by more than
    :data:`STALE_MOTION` plus :data:`JUMP_RATE` times the run's duration (what instrument errors could move it: the
    physics check's allowance) and the tracking by at most :data:`HELD_RUN_SHARE` of that. An honest tracking follows
    the telemetry to within its noise and the INS's drift: at 10 Hz in a 1.7 g boost the velocity changes by 1.7 m/s
    per epoch, 10 times a GNSS velocity's noise and 100 times 10 % of it; on the pad or at a steady speed ``dV`` is
    below the noise and no run moves by STALE_MOTION."""
    n = V.shape[0]
    out = np.zeros(n, bool)
    if n < 3:
        return out
    own = V - dv  # the tracking's velocity, less a constant (v_tel - V at the first sample)
    dV = np.linalg.norm(np.diff(V, axis=0), axis=1)
    dT = np.linalg.norm(np.diff(own, axis=0), axis=1)
    held = np.concatenate([[False], dT <= HELD_SHARE * dV])
    for a, b in runs(held):  # epochs a..b-1 held; a - 1 the last fresh one
        moved = float(np.linalg.norm(V[b - 1] - V[a - 1]))
        changed = float(np.linalg.norm(own[b - 1] - own[a - 1]))
        if moved > STALE_MOTION + JUMP_RATE * float(t[b - 1] - t[a - 1]) and changed <= HELD_RUN_SHARE * moved:
            out[a:b] = True
    return out


def repeated_rows(trk: Table, tracking_frame: str, skip: np.ndarray | None = None,
                  part: str = "velocity") -> np.ndarray:
    """The tracking rows (0-based) whose velocity columns repeat the previous row's exactly: a receiver that has
    lost lock and repeats its last fix, or its last velocity while its positions go on (the velocity is what the
    separation compares; a stale velocity beside fresh positions is as wrong as a repeated fix). A record of the
    file, not a judgement (:mod:`casep.checks.tracking_quality` judges them against the telemetry's motion). Rows
    `skip` (a boolean mask: rows without tracking) are left out; a row is compared with the previous row not
    skipped. `part` ``"position"``: the rows whose position columns repeat (an Earth-fixed file's; none for the
    launch frame's, which has none)."""
    from casep.frames import ECEF_COLUMNS, GEODETIC_COLUMNS

    if part == "position" and tracking_frame == "launch":
        return np.zeros(0, int)
    cols: tuple[str, ...] = {"launch": VTRK_COLUMNS, "ecef": ECEF_COLUMNS[4:], "geodetic": GEODETIC_COLUMNS[4:]}[
        tracking_frame] if part != "position" else {"ecef": ECEF_COLUMNS[1:4], "geodetic": GEODETIC_COLUMNS[1:4]}[
        tracking_frame]
    x = trk.vectors(tuple(cols), skip=skip)
    idx = np.arange(x.shape[0]) if skip is None else np.flatnonzero(~skip)
    x = x[idx]
    return idx[1:][np.all(x[1:] == x[:-1], axis=1)]


def check_earth_fixed_units(trk: Table, t: np.ndarray, r: np.ndarray, v: np.ndarray, frame: str) -> None:
    """Refuse Earth-fixed tracking whose position or velocity is not in metres (m/s), naming the likely unit.

    A tracked vehicle is within 0.05-30 Earth radii of the centre: ``|r|`` far below 3e5 m
    (km read as m: about 6.4e3) is not an ECEF position in metres. The position's time
    derivative must match the velocity: ``ratio = median |dr/dt| / median |v|`` (central
    differences) near 1000 or 1/1000 is a velocity in km/s or a position in km.
    """
    from casep.frames import ECEF_COLUMNS, GEODETIC_COLUMNS

    norm = float(np.median(np.linalg.norm(r, axis=1)))
    col = ECEF_COLUMNS[1] if frame == "ecef" else GEODETIC_COLUMNS[3]
    if frame == "ecef" and norm < 3e5:
        unit = f"kilometres (x 1000: {norm * 1e3:.4g} m)" if 3e3 < norm < 3e4 else "not metres"
        raise trk.error(f"ECEF positions have a median norm of {norm:.4g} m, far below the Earth's radius "
                        f"(6.371e6 m): {unit}? The ECEF columns must be in metres and m/s", col)
    if t.size < 3:
        return
    speed = float(np.median(np.linalg.norm(v, axis=1)))
    rate = float(np.median(np.linalg.norm(np.gradient(r, t, axis=0), axis=1)))
    if speed > 1.0 and rate > 1.0 and not 0.1 < rate / speed < 10.0:
        _check_time_unit(trk, t, rate / speed)
        likely = ("the velocity in km/s" if 300 < rate / speed < 3000 else
                  "the position in km" if 300 < speed / rate < 3000 else "the two in different units")
        raise trk.error(f"the tracked position changes at a median {rate:.4g} m/s but the tracked velocity is a median "
                        f"{speed:.4g} m/s (ratio {rate / speed:.4g}): {likely}? Positions must be in m, velocities in "
                        "m/s", col)


#: Seconds of tracking over which the position's change is compared with the integrated velocity
#: (:func:`velocity_column_misfit`): long enough that a position noise of metres averages to a fraction of a m/s.
COLUMN_WINDOW_S = 2.0
#: A reading of the velocity columns (another order, other signs) is named when it brings the position's rate and
#: the velocity this many times closer (RMS) than the columns as read: it explains the misfit, 90 % of it or more.
COLUMN_RATIO = 10.0
#: ... and the columns as read miss the position's rate by more than this (m/s RMS): a disagreement beyond a
#: tracking's noise and lag.
COLUMN_MISFIT_MIN = 1.0


def _windows(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Start and end rows of consecutive windows of about :data:`COLUMN_WINDOW_S` s of tracking, none across a
    pause (a step over 3 median steps: the velocity is not integrated across it)."""
    if t.size < 3:
        return np.zeros(0, int), np.zeros(0, int)
    dt = np.diff(t)
    h = float(np.median(dt))
    if not h > 0:
        return np.zeros(0, int), np.zeros(0, int)
    n = max(2, int(round(COLUMN_WINDOW_S / h)))
    starts, ends = [], []
    cut = np.concatenate([[0], np.flatnonzero(~(dt <= 3.0 * h)) + 1, [t.size]])
    for a, b in zip(cut[:-1], cut[1:]):
        for i in range(a, b - n, n):
            starts.append(i)
            ends.append(i + n)
    return np.asarray(starts, int), np.asarray(ends, int)


def velocity_column_misfit(t: np.ndarray, r: np.ndarray, c: np.ndarray, basis: np.ndarray | None,
                           maps: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per window (:func:`_windows`) and per reading of the velocity columns, the mean misfit of the tracked
    position's change against the velocity integrated over the window (trapezoid), m/s.

    ``r`` (M, 3) ECEF positions (m); ``c`` (M, 3) the file's velocity columns; ``basis`` (M, 3, 3) the ECEF
    directions of the columns at each row (east, north, up for geodetic tracking: columns of the matrix), None for
    ECEF columns; ``maps`` (K, 3, 3): the velocity in the columns' axes read as ``maps[k] @ c``. Returns the
    misfits (K, W) (norm of the window's mean misfit vector), the window starts and ends (rows)."""
    i0, i1 = _windows(t)
    if i0.size == 0:
        return np.zeros((maps.shape[0], 0)), i0, i1
    B = np.broadcast_to(np.eye(3), (t.size, 3, 3)) if basis is None else basis
    g = B[:, :, :, None] * c[:, None, None, :]  # (M, 3, i, j): direction i of the columns times column j
    cum = cumulative_trapezoid(g, t)
    J = cum[i1] - cum[i0]  # (W, 3, i, j): integral over each window
    span = (t[i1] - t[i0])[None, :, None]
    d = ((r[i1] - r[i0])[None] - np.einsum("kij,wxij->kwx", maps, J)) / span
    return np.linalg.norm(d, axis=2), i0, i1


def _readings() -> list[tuple[tuple[int, ...], tuple[int, ...]]]:
    """The readings of three velocity columns: a permutation ``p`` and signs ``s`` (column i holds ``s_i`` times
    component ``p_i``), the columns as read first, then by the number of changes."""
    import itertools

    out = [(p, s) for p in itertools.permutations(range(3)) for s in itertools.product((1, -1), repeat=3)]
    return sorted(out, key=lambda ps: (sum(a != b for a, b in zip(ps[0], range(3))) + ps[1].count(-1)))


def _enu_axes(lat_deg: np.ndarray, lon_deg: np.ndarray) -> np.ndarray:
    """(M, 3, 3): the ECEF directions of east, north and up (columns) at each geodetic latitude and longitude (deg),
    the axes of :func:`casep.frames.geodetic_to_ecef`'s velocity."""
    la, lo = np.radians(np.asarray(lat_deg, float)), np.radians(np.asarray(lon_deg, float))
    sa, ca, so, co = np.sin(la), np.cos(la), np.sin(lo), np.cos(lo)
    e = np.column_stack([-so, co, np.zeros_like(la)])
    n = np.column_stack([-sa * co, -sa * so, ca])
    u = np.column_stack([ca * co, ca * so, sa])
    return np.stack([e, n, u], axis=2)


def check_velocity_columns(trk: Table, t: np.ndarray, r: np.ndarray, c: np.ndarray, frame: str,
                           basis: np.ndarray | None = None) -> None:
    """Refuse Earth-fixed tracking whose velocity columns are in another order or of another sign than their
    names say (east and north swapped, v_up holding the downward velocity, a NED file read as ENU), naming the
    columns and the numbers.

    The tracked position's change over windows of :data:`COLUMN_WINDOW_S` s is the velocity integrated over them:
    with ``D_w = r(end) - r(start) - integral v dt`` (ECEF, the velocity columns turned by their own axes at each
    row) per window, the misfit of a reading of the columns is the RMS of ``|D_w| / T_w`` over the windows. Each of
    the 47 other readings (an order of the three columns times their signs) is weighed against the columns as
    read; the simplest reading within a factor 2 of the best is named when the best is :data:`COLUMN_RATIO`
    times closer than the columns as read (it explains the misfit), and these miss by more than
    :data:`COLUMN_MISFIT_MIN`. A correct file is the best reading itself (any other adds a velocity component
    that the positions do not follow), so it is never named; a tracking whose noise hides the mistake is not
    either. ``c`` (M, 3) are the file's velocity columns, ``basis`` their ECEF axes per row (:func:`_enu_axes` for
    geodetic tracking; None: ECEF columns); ``r`` the ECEF positions."""
    from casep.frames import ECEF_COLUMNS, GEODETIC_COLUMNS

    names = GEODETIC_COLUMNS[4:] if frame == "geodetic" else ECEF_COLUMNS[4:]
    axes = ("east", "north", "up") if frame == "geodetic" else ("ECEF x", "ECEF y", "ECEF z")
    readings = _readings()
    maps = np.zeros((len(readings), 3, 3))
    for k, (p, s) in enumerate(readings):
        for i in range(3):
            maps[k, p[i], i] = s[i]  # component p_i = s_i column i
    d, i0, _ = velocity_column_misfit(t, r, np.asarray(c, float), basis, maps)
    ok = np.all(np.isfinite(d), axis=0)
    if np.count_nonzero(ok) < 3:
        return
    rms = np.sqrt(np.mean(d[:, ok] ** 2, axis=1))
    best = float(rms.min())
    if not (rms[0] > COLUMN_MISFIT_MIN and rms[0] > COLUMN_RATIO * best):
        return
    k = next(k for k in range(len(readings)) if rms[k] <= 2.0 * best)
    p, s = readings[k]
    holds = ", ".join(f"{names[i]} the {'' if s[i] > 0 else 'negated '}{axes[p[i]]} velocity"
                      for i in range(3) if (p[i], s[i]) != (i, 1))
    second = float(np.sort(rms)[1]) if k == int(np.argmin(rms)) else best
    raise trk.error(f"the velocity columns do not follow the tracked position: over {np.count_nonzero(ok)} windows "
                    f"of {COLUMN_WINDOW_S:g} s the position's change and the integrated velocity differ by "
                    f"{rms[0]:.4g} m/s RMS as the columns are named, by {rms[k]:.3g} m/s if they hold {holds} "
                    f"({rms[0] / rms[k]:.3g} times closer; of the 47 other orders and signs of the columns the next "
                    f"closest misses by {second:.3g} m/s): {holds}? Give the velocity columns in the order and sign "
                    "their names say (a swapped pair, a downward velocity in v_up, a NED file read as ENU)",
                    names[next(i for i in range(3) if (p[i], s[i]) != (i, 1))])


def _check_time_unit(trk: Table, t: np.ndarray, ratio: float) -> None:
    """Refuse tracking whose ``t`` is in another unit where that explains its position's rate against its velocity
    (`ratio`, ``median |dr/dt| / median |v|`` with ``t`` read as s): its median step and span out of the range of
    flight data and a unit of :func:`casep.io.flight.time_unit_factors` (the telemetry's rule) that brings them in
    and the ratio within 0.1-10 (t in ms reads the position's rate 1000 times slow, as a position in km would)."""
    from casep.io.flight import time_unit_factors

    h, span = float(np.median(np.diff(t))), float(t[-1] - t[0])
    for unit, k in time_unit_factors(h, span):
        name, how = unit.split(" ", 1)  # "ms", "(divide by 1000)"
        if 0.1 < ratio / k < 10.0:
            raise trk.error(f"t looks like {name}, not s: a median step of {h:.4g} and a span of {span:.4g} 's' are "
                            f"not a flight's, and read in {name} the tracked position's rate agrees with its velocity "
                            f"(ratio {ratio / k:.3g}; {ratio:.3g} as s): give t in s {how}", "t")


def tracking_hint(trk: Table, tracking_frame: str) -> str:
    """What a tracking file lacks, and the frame its columns suggest."""
    from casep.frames import ECEF_COLUMNS, GEODETIC_COLUMNS

    if tracking_frame == "ecef":
        return ". Use (ECEF, m, m/s): " + ", ".join(ECEF_COLUMNS)
    if tracking_frame == "geodetic":
        return ". Use (deg, deg, m, m/s east/north/up): " + ", ".join(GEODETIC_COLUMNS)
    for frame, cols in (("ecef", ECEF_COLUMNS), ("geodetic", GEODETIC_COLUMNS)):
        if trk.has(cols):
            return (f". Use: t, v_trk_x, v_trk_y, v_trk_z; this file has {frame} columns: read it with "
                    f"tracking_frame='{frame}' and site=LaunchSite(...) (CLI: --tracking-frame {frame} "
                    "--launch-site LAT LON H AZ --launch-time T0)")
    return ". Use: t, v_trk_x, v_trk_y, v_trk_z"


#: Launch-inertial position and velocity columns (m, m/s): the burnout state of casep.impact.
STATE_SIGNALS = ("r_x", "r_y", "r_z", "v_x", "v_y", "v_z")


def with_tracked_state(flight: FlightData, t_trk: np.ndarray, r: np.ndarray, v: np.ndarray) -> FlightData:
    """The flight with the tracked position and velocity (Earth-fixed tracking turned launch-inertial) as the
    signals ``r_*``, ``v_*`` on its time grid: a not-a-knot cubic spline through the tracking samples inside
    their span, NaN outside (before tracking starts). What the impact analysis reads as the burnout state."""
    import dataclasses

    from scipy.interpolate import CubicSpline

    t = np.asarray(flight.t)
    inside = (t >= t_trk[0]) & (t <= t_trk[-1])
    sig = dict(flight.signals)
    for name, values in zip(STATE_SIGNALS, np.column_stack([r, v]).T):
        col = np.full(t.size, np.nan)
        col[inside] = CubicSpline(t_trk, values)(t[inside])
        sig[name] = col
    meta = {**flight.meta, "state_from": "tracking (r_*, v_*: launch-inertial, spline on the flight's times)"}
    return dataclasses.replace(flight, signals=sig, meta=meta)


#: A given tracking time offset above this, s, is no latency: a warning suggests `time_shift`.
MAX_TIME_OFFSET = 2.0
#: The launch time must lie within this of the tracking file's time tags, s (a day: seconds of day,
#: of a week's GPS time or since an epoch all put it within hours of the tracking).
MAX_LAUNCH_TIME_GAP = 86400.0


def time_shift_seconds(value) -> float:
    """`time_shift`: a finite number of seconds."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not np.isfinite(value):
        raise ValueError(f"`time_shift` (tracking time minus telemetry time, s) must be a finite number, got {value!r}")
    return float(value)


#: A stated clock drift beyond this, ppm (1 %), is no drift of a clock (a crystal's is tens of ppm): a unit slip.
MAX_CLOCK_DRIFT_PPM = 1e4


def clock_drift_ppm(value) -> float:
    """`clock_drift`: a finite number of ppm within :data:`MAX_CLOCK_DRIFT_PPM`."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not np.isfinite(value):
        raise ValueError(f"`clock_drift` (the tracking time offset's drift, ppm) must be finite, got {value!r}")
    ppm = float(value)
    if abs(ppm) > MAX_CLOCK_DRIFT_PPM:
        raise ValueError(f"`clock_drift` {ppm:g} ppm is {abs(ppm) * 1e-4:.3g} % of the time: a clock drifts by "
                         f"at most {MAX_CLOCK_DRIFT_PPM:g} ppm (give ppm, not a fraction or ms)")
    return ppm


def telemetry_time(T, shift: float = 0.0, drift_ppm: float = 0.0):
    """The telemetry time of tracking time `T`: ``t = (T - shift) / (1 + eps)``, ``eps = drift_ppm 1e-6``.

    `shift` is tracking time minus telemetry time at telemetry time 0; a drift ``eps`` makes the tracking time tags
    late by ``eps t`` more at telemetry time ``t`` (``T - shift = t (1 + eps)``): the drift the clock-drift checks
    measure (:mod:`casep.checks.tracking_quality`, a late tag's ``dv = a eps t``), in the same sign."""
    return (np.asarray(T, dtype=float) - shift) / (1.0 + drift_ppm * 1e-6)


def drift_pivot(launch_time: float, offset_free: bool) -> float:
    """The telemetry time (s) about which a clock drift beyond the one given moves the tracking time tags (late by
    ``eps (t - pivot)`` at telemetry time ``t``): the flight's `launch_time` where the time offset is the data's
    (`offset_free`: a fitted ``dt_trk``, or one the pairing measured), which takes in what the drift does about any
    other origin and then reads the offset at the flight; else 0, where :func:`telemetry_time` ties the two clocks.
    About 0 with a fitted ``dt_trk``, a record tagged in GPS time of week (3e5 s) moved the offset under a drift of
    50 ppm by 15 s, and its std 2560x."""
    return float(launch_time) if offset_free else 0.0


def tracking_time(t, shift: float = 0.0, drift_ppm: float = 0.0):
    """The inverse of :func:`telemetry_time`: ``T = t (1 + eps) + shift``."""
    return np.asarray(t, dtype=float) * (1.0 + drift_ppm * 1e-6) + shift


def check_launch_time(trk: Table, t_raw: np.ndarray, site) -> None:
    """The launch time in the tracking file's time scale: within :data:`MAX_LAUNCH_TIME_GAP` of its time tags."""
    gap = max(t_raw[0] - site.t0, site.t0 - t_raw[-1], 0.0)
    if gap > MAX_LAUNCH_TIME_GAP:
        raise trk.error(f"the launch time {site.t0:.10g} s is {gap:.4g} s from the tracking time tags "
                        f"[{t_raw[0]:.10g}, {t_raw[-1]:.10g}] s (more than {MAX_LAUNCH_TIME_GAP:g} s): give it in the "
                        "tracking file's time scale (--launch-time, manifest launch_time_s)", "t")


def no_overlap_message(t_tel: np.ndarray, t_raw: np.ndarray, shift: float) -> str:
    """Telemetry and tracking that do not overlap: both spans, and the shift that would line them up."""
    after = t_raw[0] - shift - t_tel[0]
    scale = f" (after time_shift {shift:g} s: [{t_raw[0] - shift:.10g}, {t_raw[-1] - shift:.10g}] s)" if shift else ""
    return (f"telemetry time [{t_tel[0]:.10g}, {t_tel[-1]:.10g}] s and tracking time [{t_raw[0]:.10g}, "
            f"{t_raw[-1]:.10g}] s{scale} share fewer than 2 telemetry samples: the tracking starts {after:.6g} s "
            f"{'after' if after >= 0 else 'before'} the telemetry. Telemetry and tracking must be on one time scale; "
            "if they count from different origins (seconds of day against seconds from lift-off), state how they "
            f"relate: time_shift = tracking time - telemetry time (e.g. {t_raw[0] - t_tel[0]:.10g} if both start "
            "together; CLI --time-shift, manifest time_shift_s)")


def pair_flight(t_tel: np.ndarray, f: np.ndarray, v_tel: np.ndarray, t_trk: np.ndarray, v_trk: np.ndarray, *,
                signals: dict[str, np.ndarray] | None = None, interpolation: str = "cubic", grid: str = "tracking",
                source: str = "<memory>", meta: dict | None = None) -> FlightData:
    """The flight of a telemetry + tracking pair held in arrays (see :func:`read_flight_pair`).

    Parameters
    ----------
    t_tel, f, v_tel : arrays
        Telemetry times (s, increasing), specific force (m/s^2) and velocity (m/s).
    t_trk, v_trk : arrays
        Tracking times (s, increasing) and velocity (m/s).
    signals : dict, optional
        Other telemetry columns at `t_tel`.

    Notes
    -----
    With ``grid="tracking"`` a tracking time closer to a telemetry time than
    :data:`~casep.io.flight.DUPLICATE_STEP` times the median step of the merged grid is that sample
    (its dv is still evaluated at the tracking time; :func:`_merge_times`), so the grid holds no
    near-duplicate time tag of casep's making; the others are inserted, with ``f`` and the signals
    linearly interpolated (S_V integrates ``f`` by the trapezoid rule, so a linearly interpolated
    sample leaves its first-order terms unchanged); ``meta["telemetry_samples"]`` marks the telemetry's own samples
    (with or without a tracking epoch on them), whose columns are the file's. Tracking samples outside the telemetry
    span are dropped (counted in ``meta["tracking_dropped"]``).
    """
    from scipy.interpolate import CubicSpline

    t_tel, t_trk = np.asarray(t_tel, dtype=float), np.asarray(t_trk, dtype=float)
    f, v_tel, v_trk = (np.asarray(a, dtype=float) for a in (f, v_tel, v_trk))
    signals = dict(signals or {})

    def carry(t_from, v_from, t_to):  # velocity of one source at the other's times
        if interpolation == "cubic":
            return CubicSpline(t_from, v_from, axis=0)(t_to)
        return np.column_stack([np.interp(t_to, t_from, v_from[:, i]) for i in range(3)])

    keep = t_tel <= t_trk[-1]  # from the first telemetry sample to the end of tracking
    extra: dict = {}
    trk_gaps, tel_gaps = _gaps(t_trk), _gaps(t_tel)
    if grid == "telemetry":
        t, observed = t_tel[keep], (t_tel[keep] >= t_trk[0])
        in_gap = _inside(t, trk_gaps)
        if in_gap.any():  # tracking interpolated across a gap invents data: those rows are not observed
            _warn_gaps("tracking", trk_gaps, int(np.count_nonzero(in_gap & observed)), "telemetry samples", source)
            observed &= ~in_gap
            extra["gap_rows_left_out"] = int(np.count_nonzero(in_gap))
        dv = np.full((t.size, 3), np.nan)  # not observed before tracking starts
        dv[observed] = v_tel[keep][observed] - carry(t_trk, v_trk, t[observed])  # v_tel - v_trk(t_tel)
        f_out = f[keep]
        sig = {k: v[keep] for k, v in signals.items()}
        how = f"v_tel - v_trk at telemetry times ({interpolation} interpolation of tracking)"
        extra.update(rows_side="telemetry", rows_index=np.flatnonzero(keep), telemetry_samples=np.ones(t.size, bool))
    else:
        use = (t_trk >= t_tel[0]) & (t_trk <= t_tel[-1])
        in_gap = _inside(t_trk, tel_gaps) & use
        if in_gap.any():  # telemetry velocity interpolated across a telemetry gap: those tracking rows left out
            _warn_gaps("telemetry", tel_gaps, int(np.count_nonzero(in_gap)), "tracking samples", source)
            use &= ~in_gap
            extra["gap_rows_left_out"] = int(np.count_nonzero(in_gap))
        tt = t_trk[use]
        t_keep = t_tel[keep]
        t, idx, on = _merge_times(t_keep, tt)
        observed = np.zeros(t.size, bool)
        observed[idx] = True
        dv = np.full((t.size, 3), np.nan)
        dv[idx] = carry(t_tel, v_tel, tt) - v_trk[use]  # v_tel(t_trk) - v_trk
        f_out = np.column_stack([np.interp(t, t_tel, f[:, i]) for i in range(3)])
        sig = {k: np.interp(t, t_tel, v) for k, v in signals.items()}
        how = f"v_tel - v_trk at tracking times ({interpolation} interpolation of telemetry)"
        extra = {**extra, "tracking_dropped": int((~use).sum()), "inserted": int((~on).sum()), "rows_side": "tracking"}
        rows_index = np.full(t.size, -1)
        rows_index[idx] = np.flatnonzero(use)  # the tracking data row of each observed sample
        extra["rows_index"] = rows_index
        extra["telemetry_samples"] = np.isin(t, t_keep)  # a tracking epoch on a telemetry sample is still that sample
    if VALID_COLUMN in sig:
        observed = _valid_rows(t, observed, sig[VALID_COLUMN], extra, source)
    if trk_gaps or tel_gaps:
        extra["gaps_s"] = {"tracking": trk_gaps, "telemetry": tel_gaps}
    meta = {"format": "pair", "grid": grid, "dv": how, **(meta or {}), **extra,
            "telemetry_span_s": [float(t_tel[0]), float(t_tel[-1])],
            "tracking_span_s": [float(t_trk[0]), float(t_trk[-1])],
            "span_s": [float(t[0]), float(t[-1])], "observed_span_s": [float(t[observed][0]), float(t[observed][-1])],
            "unobserved": int((~observed).sum()), "telemetry_dropped": int((~keep).sum()),
            "start_speed_m_s": float(np.linalg.norm(v_tel[0])),
            "telemetry_velocity_change_m_s": (v_tel[keep][-1] - v_tel[0]).tolist(),  # for casep.checks.plausibility
            **_tracking_change(t_tel, v_tel, t_trk, v_trk, (meta or {}).get("tracking_frame", {}).get("site")),
            "interpolation_floor_m_s": interpolation_floor(*((t_trk, v_trk) if grid == "telemetry" else (t_tel, v_tel)),
                                                           carry, 4 if interpolation == "cubic" else 2)}
    meta["pair_inputs"] = PairInputs(t_tel, f, v_tel, t_trk, v_trk, signals, interpolation, grid, source)
    return FlightData(t, f_out, dv, source=source, meta=meta, observed=observed, signals=sig)


@dataclass(frozen=True)
class PairInputs:
    """What :func:`pair_flight` formed a pair from (its arguments), kept in ``meta["pair_inputs"]`` so that the pair
    can be formed again with the tracking time tags moved (:func:`repaired`)."""

    t_tel: np.ndarray
    f: np.ndarray
    v_tel: np.ndarray
    t_trk: np.ndarray
    v_trk: np.ndarray
    signals: dict
    interpolation: str
    grid: str
    source: str


def repaired(flight: FlightData, shift: float) -> FlightData | None:
    """The pair `flight` formed again with its tracking time tags `shift` seconds earlier (tracking `shift` late).

    A tracking offset ``dt_trk`` enters the model linearised, ``v_trk(t) = v(t - dt) ~ v(t) - a(t) dt``; the
    next term, ``j(t) dt^2 / 2`` (``j`` the jerk), is left in the residuals. Formed again at the offset
    estimated, the pair holds the tracking at its true times and the fit's ``dt_trk`` is the (small) rest.
    The samples the tracking screen left out (by tracking row) stay out; everything else the reader recorded
    is kept. None when the flight does not hold its pair's inputs (not formed by :func:`pair_flight`, or
    given the tracked state afterwards: :func:`with_tracked_state`).
    """
    import dataclasses

    meta = flight.meta if isinstance(flight.meta, dict) else {}
    inp = meta.get("pair_inputs")
    if not isinstance(inp, PairInputs) or "state_from" in meta:
        return None
    new = pair_flight(inp.t_tel, inp.f, inp.v_tel, inp.t_trk - shift, inp.v_trk, signals=inp.signals,
                      interpolation=inp.interpolation, grid=inp.grid, source=flight.source)
    observed = np.array(new.observed)
    if inp.grid == "tracking" and "rows_index" in meta:  # the screen's exclusions, by tracking row
        kept = np.asarray(meta["rows_index"])[np.asarray(flight.observed)]
        observed &= np.isin(new.meta["rows_index"], kept)
    merged = {**meta, **new.meta, "pair_inputs": inp, "pair_shift_s": float(shift)}  # shifts count from the inputs
    return dataclasses.replace(new, meta=merged, observed=observed,
                               dv=np.where(observed[:, None], new.dv, np.nan))


def offset_second_order(flight: FlightData, dt: float) -> float:
    """The second-order term of a tracking offset `dt` (s) that the linearised ``dt_trk`` leaves out, as an offset:
    ``dt^2 rms(j) / (2 rms(a))``, s (``j = d a / dt`` the jerk of the flight's kinematic acceleration, signals
    ``a_x, a_y, a_z``, RMS over the observed samples): the first-order column ``a`` carries ``a dt``, the term
    left out ``j dt^2 / 2``; 0 without those signals."""
    if not all(f"a_{c}" in flight.signals for c in "xyz") or flight.t.size < 3:
        return 0.0
    a = np.column_stack([flight.signals[f"a_{c}"] for c in "xyz"])
    j = np.gradient(a, flight.t, axis=0)
    obs = np.asarray(flight.observed) & np.all(np.isfinite(j), axis=1) & np.all(np.isfinite(a), axis=1)
    ra = float(np.sqrt(np.mean(a[obs] ** 2))) if obs.any() else 0.0
    return float(0.5 * dt**2 * np.sqrt(np.mean(j[obs] ** 2)) / ra) if ra > 0 else 0.0


def interpolation_floor(t: np.ndarray, v: np.ndarray, carry, order: int) -> float:
    """What carrying the velocity `v` (at times `t`) to other times errs by, from the data, m/s RMS (a level
    that the error stays below, not its mean).

    Carried from every other sample to the samples left out, the interpolation errs as at twice the step
    (``e_2``). Its error goes as ``h^p``: ``p`` is the interpolation's order (cubic spline 4, linear 2) where
    the velocity is smooth, but 2 near a kink of it (a thrust change: the acceleration jumps), and those
    kinks set the level (a 50 Hz boost: ``e_4 / e_2`` 4.8, not 16; carried to times a fraction of a step
    off the samples, the cubic error was 3.5 times ``e_2 / 16``). So the floor is ``e_2 / 4`` (``p = 2``, a
    velocity whose acceleration is bounded; linear interpolation is that order anyway). Noise in `v` adds
    ``~sigma / 4``, below the noise itself: a fit whose residuals are at this floor carries no noise
    (:func:`casep.regression.problem.is_rounding_level`). `order` bounds ``p`` from above.
    """
    if t.size < 8:
        return 0.0
    e = carry(t[::2], v[::2], t[1:-1:2]) - v[1:-1:2]
    return float(np.sqrt(np.mean(e**2))) / 2.0 ** min(order, 2)


def _tracking_change(t_tel: np.ndarray, v_tel: np.ndarray, t_trk: np.ndarray, v_trk: np.ndarray,
                     site: dict | None = None, epochs: int = 64) -> dict:
    """The tracking velocity changes from the first tracking sample inside the telemetry to up to `epochs` later
    ones spread over it, and the telemetry's over the same times (linear interpolation): one unit makes them
    scaled copies with ratio ~1 (the plausibility check's units rule), rows ``[epoch][axis]``.

    With the `site` of Earth-fixed tracking (:meth:`casep.frames.LaunchSite.to_dict`) both are relative to the pad
    at rest on the rotating Earth: the pad's launch-inertial velocity ``omega_E x r``, turning with the Earth
    (2.6 m/s in 120 s at 51 deg), is taken from both, so a vehicle at rest changes by nothing in either and the
    navigation's drift is not compared with the Earth's rotation. The times are the telemetry's, not the launch
    time's scale: an offset ``d`` turns the pad's change by ``omega_E d``, 4e-3 rad for a minute."""
    inside = np.flatnonzero((t_trk >= t_tel[0]) & (t_trk <= t_tel[-1]))
    if inside.size < 2:
        return {}
    a = inside[0]
    b = inside[np.unique(np.linspace(1, inside.size - 1, min(epochs, inside.size - 1)).round().astype(int))]
    tel = np.column_stack([np.interp(t_trk[b], t_tel, v_tel[:, i]) - np.interp(t_trk[a], t_tel, v_tel[:, i])
                           for i in range(3)])
    trk = v_trk[b] - v_trk[a]
    if site is not None:
        from casep.frames import LaunchSite, ecef_to_launch

        pad = LaunchSite(**site)
        tp = t_trk[np.concatenate([[a], b])]
        v_pad = ecef_to_launch(pad, tp, np.tile(pad.r_site, (tp.size, 1)), np.zeros((tp.size, 3)))[1]
        trk, tel = trk - (v_pad[1:] - v_pad[0]), tel - (v_pad[1:] - v_pad[0])
    return {"tracking_velocity_change_m_s": trk.tolist(), "telemetry_velocity_change_at_tracking_m_s": tel.tolist()}


def _merge_times(t_tel: np.ndarray, tt: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The merged grid of telemetry times `t_tel` and tracking times `tt`; each tracking time's row; which are samples.

    A tracking time within ``tol = DUPLICATE_STEP * median(diff(t))`` (at least 1e-9 s) of its nearest
    telemetry sample is that sample; the others are inserted. ``t`` depends on ``tol`` and ``tol`` on
    the median step of ``t``: iterated from 1e-9 s until ``tol`` no longer grows (matching more only
    removes inserted rows, so ``tol`` rises monotonically; a pass or two). The plausibility check's
    near-duplicate rule (:func:`casep.checks.plausibility.check_flight`) is the same one, so a merged
    step below it comes from the files themselves (two telemetry or two tracking times that close).
    """
    j = np.clip(np.searchsorted(t_tel, tt), 1, t_tel.size - 1)
    nearest = np.where(np.abs(t_tel[j] - tt) <= np.abs(t_tel[j - 1] - tt), j, j - 1)
    gap = np.abs(t_tel[nearest] - tt)
    tol = 1e-9
    for _ in range(20):
        on = gap <= tol
        t = np.union1d(t_tel, tt[~on])  # telemetry samples and the tracking times between them
        grown = DUPLICATE_STEP * float(np.median(np.diff(t))) if t.size > 1 else 0.0
        if grown <= tol:
            break
        tol = grown
    idx = np.searchsorted(t, np.where(on, t_tel[nearest], tt))  # each tracking time's row (its exact value is in t)
    return t, idx, on


def _valid_rows(t: np.ndarray, observed: np.ndarray, valid: np.ndarray, extra: dict, source: str) -> np.ndarray:
    """`observed` without the rows where the telemetry's :data:`VALID_COLUMN` is below 1, said with a warning."""
    import warnings

    from casep.exceptions import SaturationWarning

    bad = observed & ~(np.asarray(valid) >= 1.0)
    if not bad.any():
        return observed
    rows = np.flatnonzero(bad)
    if not (observed & ~bad).any():
        raise ValueError(
            f"{source}: the telemetry column {VALID_COLUMN} marks the navigation solution as not trusted (a clipped "
            f"IMU sample) on every observed row ({rows.size} rows, t = {t[rows[0]]:.10g} .. {t[rows[-1]]:.10g} s): "
            "no tracked row is left to separate. Declare the sensor's full scale if the clipping is not real, or "
            "use a flight whose tracking starts while the navigation is valid")
    extra["ins_invalid"] = {"from_s": float(t[rows[0]]), "to_s": float(t[rows[-1]]), "rows_left_out": int(rows.size)}
    warnings.warn(SaturationWarning(
        f"{source}: the telemetry column {VALID_COLUMN} marks the navigation solution as not trusted (a clipped IMU "
        f"sample) from t = {t[rows[0]]:.10g} s: the {rows.size} observed rows from there to t = {t[rows[-1]]:.10g} s "
        "are left out of the regression"), stacklevel=4)
    return observed & ~bad


#: A step this many times the median sample step is a gap that interpolation must not bridge ...
GAP_FACTOR = 5.0
#: ... and at least this long, s (a few missing samples at 20 Hz are bridged well by a cubic spline).
GAP_MIN_S = 0.5


def _gaps(t: np.ndarray) -> list[list[float]]:
    """``[[start, end], ...]`` of the steps of `t` above :data:`GAP_FACTOR` x its median step and :data:`GAP_MIN_S`."""
    if t.size < 3:
        return []
    step = np.diff(t)
    big = np.flatnonzero((step > GAP_FACTOR * np.median(step)) & (step > GAP_MIN_S))
    return [[float(t[k]), float(t[k + 1])] for k in big]


def _inside(t: np.ndarray, gaps: list[list[float]]) -> np.ndarray:
    """Samples strictly inside one of the `gaps`."""
    out = np.zeros(t.size, dtype=bool)
    for a, b in gaps:
        out |= (t > a) & (t < b)
    return out


def _warn_gaps(which: str, gaps: list[list[float]], rows: int, what: str, source: str) -> None:
    import warnings

    from casep.exceptions import GapWarning

    listed = ", ".join(f"{b - a:.4g} s from t = {a:.10g} s" for a, b in gaps[:5]) + (" ..." if len(gaps) > 5 else "")
    warnings.warn(GapWarning(
        f"{source}: the {which} has {len(gaps)} gap(s) ({listed}; above {GAP_FACTOR:g} x its median step and "
        f"{GAP_MIN_S:g} s): interpolating across them would invent data, so the {rows} {what} inside are left out of "
        "the regression (S_V is still integrated through them)"), stacklevel=4)


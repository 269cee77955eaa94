"""Reading and writing flight files: CSV and Parquet, one file or telemetry + tracking.

Formats (``docs/reference/file-formats.md``): a header row, one row per sample, ``#`` comment
lines (CSV), other numeric columns kept as signals (below), text columns ignored.

- time ``t`` (s, strictly increasing);
- specific force ``f_x, f_y, f_z`` (m/s^2), or telemetered apparent velocity ``W_x, W_y, W_z``
  (m/s, accumulated specific force), turned into ``f = dW/dt`` by second-order finite
  differences on the (possibly non-uniform) time grid (:func:`apparent_velocity_to_force`);
- velocity error ``dv_x, dv_y, dv_z`` (m/s), or ``v_tel_x/y/z`` and ``v_trk_x/y/z`` (then
  dv = v_tel - v_trk);
- or, for a strapdown system, ``q_w, q_x, q_y, q_z`` (INS attitude: Hamilton unit quaternion, scalar
  first, body to navigation), ``fb_x, fb_y, fb_z`` (body specific force, m/s^2) and ``w_x, w_y, w_z``
  (body rate, rad/s): ``f = C(q) fb`` when the file has no ``f_*`` / ``W_*``; the columns are checked
  whenever present (:mod:`casep.io.strapdown`) and kept as signals for the strapdown models;
- any other numeric column (``a_*``, ``r_*``, ``v_*``, attitude, body rate, temperature, ...)
  is kept as a *signal* (``FlightData.signals``, file units) for model files that use it; a
  column with text in it is ignored. Its values are checked when a model uses it.
- a row whose three ``dv_*`` cells are all empty (Parquet: null) is a telemetry sample without
  tracking (``FlightData.observed`` False): S_V is integrated across it, the regression leaves
  it out. :func:`write_flight` writes the samples without tracking so; a row with only some of its
  dv cells empty is an error naming the first of them. The same for the three ``v_trk_*`` cells of a
  ``v_tel``/``v_trk`` flight (an INS log with its slower GNSS fixes in one file).

Two files (:func:`read_flight_pair`): a telemetry file (``t``, force or apparent velocity,
``v_tel_*``) and a tracking file at its own rate (``t``, ``v_trk_*``). The flight keeps every
telemetry sample from the first one to the end of tracking (S_V is integrated from the
first telemetry sample); tracking is interpolated onto the telemetry times inside its span
(cubic spline by default, linear on request), and those samples are the ``observed`` ones.

Every reader raises :class:`~casep.io.flight.FlightDataError` naming the file, the column and
the row (data rows count from 1 after the header; CSV errors give the file line too) for a
missing or repeated column, a column that is not numeric (bool, date-time, text in Parquet;
the dtype is named), an empty, non-numeric, NaN or infinite value, a magnitude above
:data:`~casep.io.flight.MAX_ABS_VALUE`, or time that does not strictly increase. Writers are
atomic: a failure leaves no half-written file.

The columns are read by :class:`casep.io.tables.Table`; the pair is merged by
:func:`casep.io.pair.pair_flight`; :mod:`casep.io.locate` finds a sample's row and line.
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any

import numpy as np

from casep.gravity import launch_gravitation
from casep.io._atomic import atomic_open
from casep.io.flight import DV_COLUMNS, FORCE_COLUMNS, FlightData
from casep.io.locate import is_parquet
from casep.io.pair import (
    MAX_TIME_OFFSET,
    PAIR_GRIDS,
    STATE_SIGNALS,
    check_launch_time,
    check_tracking_frame,
    clock_drift_ppm,
    no_overlap_message,
    pair_flight,
    position_gap,
    repeated_rows,
    telemetry_time,
    time_shift_seconds,
    tracking_hint,
    tracking_velocity,
    with_tracked_state,
)
from casep.io.pair import (
    rest_window as pair_rest_window,
)
from casep.io.strapdown import STRAPDOWN_COLUMNS, clock_stretch
from casep.io.tables import VTEL_COLUMNS, VTRK_COLUMNS, Table, apparent_velocity_to_force, table_force

__all__ = [
    "header_facts", "navigation_site",
    "levelled_comment",
    "simulated_comment",
    "levelling_record",
    "read_json_table", "read_flight", "read_flight_pair", "write_flight", "write_table", "apparent_velocity_to_force",
    "acceleration_signals", "ONE_FILE_TELEMETRY",
]

#: ``meta["dv"]`` of a one-file flight whose dv is its navigated telemetry's velocity less its tracking's
#: (:func:`read_flight` of ``v_tel_*`` with ``v_trk_*``; a pair's says at which times it was formed).
ONE_FILE_TELEMETRY = "v_tel - v_trk"


R_TEL_COLUMNS = ("r_tel_x", "r_tel_y", "r_tel_z")  # launch-inertial position (casep navigate's output), m
#: casep navigate's header line naming the launch site (casep/cli/navigate.py writes it)
_NAV_SITE = re.compile(r"^#\s*launch site (\S+) (\S+) (\S+) azimuth (\S+) deg, launch time (\S+) s")
#: casep navigate's header line naming its pad alignment (:func:`levelled_comment` writes it)
_NAV_LEVELLED = re.compile(r"^#\s*alignment: levelled over \[(\S+), (\S+)\] s, heading (\S+)"
                           r"(?: \(body (\S+) at (\S+) deg\))?")
#: casep simulate's header line naming the model that made the flight (:func:`simulated_comment` writes it)
_SIM_MODEL = re.compile(r"^#\s*model (\S+), seed ")


def simulated_comment(model: str, seed: int | None, rate_hz: float) -> str:
    """The header line of ``casep simulate``'s flight naming the model that made it, its seed and its rate;
    :func:`header_facts` reads the model back (:func:`casep.model.loader.default_model` separates the flight
    with it)."""
    return f"model {model}, seed {seed}, rate {rate_hz:.6g} Hz; truth in the .truth.json sidecar"


def levelled_comment(window: tuple[float, float], alignment: Any) -> str:
    """The header line of ``casep navigate``'s telemetry saying that casep aligned it on the pad: levelled by
    the mean specific force over `window` (s) and headed as `alignment` (:class:`casep.navigation.alignment.Alignment`)
    says; :func:`levelling_record` reads it back."""
    how = "given" if alignment.method == "heading" else "gyrocompassed"
    return (f"alignment: levelled over [{window[0]:.10g}, {window[1]:.10g}] s, heading {how} "
            f"(body {alignment.heading_axis} at {alignment.heading_deg:.6g} deg)")


def _header(tab: Table | str | os.PathLike) -> list[str]:
    """The ``#`` comment lines at the top of a CSV table or file, or the comments :func:`write_table` keeps in a
    Parquet file's metadata, each as ``# line`` (none for a table not read from a file); only the header (the
    Parquet schema) is read."""
    path = tab.path if isinstance(tab, Table) else Path(tab)
    if not path.is_file():
        return []
    if is_parquet(path):
        try:
            import pyarrow.parquet as pq

            meta = pq.read_schema(path).metadata or {}
        except (ImportError, OSError, ValueError):
            return []
        text = meta.get(b"comments", b"").decode("utf-8", errors="replace")
        return [f"# {line}\n" for line in text.splitlines() if line]
    lines = []
    with open(path, encoding="utf-8", errors="replace") as fh:
        for line in fh:
            if not line.startswith("#"):
                break
            lines.append(line)
    return lines


def header_facts(flight: str | os.PathLike) -> dict:
    """What a flight file's header alone says for choosing its model (:func:`casep.model.loader.default_model`):
    ``simulated_model``, the model ``casep simulate`` names as the one that made the flight (its ``# model NAME,
    seed`` line) or None; ``levelled``, whether ``casep navigate`` levelled it on the pad (:func:`levelled_comment`);
    ``strapdown``, whether it has the strapdown telemetry's columns (``q_*``, ``fb_*``, ``w_*``). Only the header
    is read (:func:`casep.io.tables.header_columns`): the flight is read once, by the separation."""
    from casep.io.strapdown import BODY_FORCE_COLUMNS, BODY_RATE_COLUMNS, QUATERNION_COLUMNS
    from casep.io.tables import header_columns

    lines = _header(flight)
    cols = header_columns(flight)
    return {"simulated_model": next((m.group(1) for line in lines if (m := _SIM_MODEL.match(line))), None),
            "levelled": any(_NAV_LEVELLED.match(line) for line in lines),
            "strapdown": all(c in cols for c in QUATERNION_COLUMNS + BODY_FORCE_COLUMNS + BODY_RATE_COLUMNS)}


def levelling_record(tab: Table) -> dict | None:
    """``{"window": [T1, T2], "heading": "given" | "gyrocompassed", "heading_axis", "heading_deg"}`` when `tab`'s
    header says ``casep navigate`` levelled it on the pad (:func:`levelled_comment`; the body axis and its heading,
    deg, None where the line does not give them), else None: the levelling turned the accelerometer errors
    on the pad into a start tilt, which a model without an initial attitude error cannot describe
    (:func:`casep.checks.plausibility.levelling_problem`); the heading is the one the telemetry's turn about the
    vertical is held against (:mod:`casep.workflows.telemetry_heading`)."""
    for line in _header(tab):
        m = _NAV_LEVELLED.match(line)
        if m is not None:
            try:
                return {"window": [float(m.group(1)), float(m.group(2))], "heading": m.group(3),
                        "heading_axis": m.group(4), "heading_deg": None if m.group(5) is None else float(m.group(5))}
            except ValueError:
                return None
    return None


def navigation_site(tab: Table):
    """The launch site of a telemetry in the launch-inertial frame (``casep navigate``'s output: its header names the
    frame and the launch site, and it has the position ``r_tel_*``), a :class:`casep.frames.LaunchSite` whose ``t0``
    is in the telemetry's time scale; None for any other table (no such header or Parquet metadata, no ``r_tel_*``)."""
    if not tab.path.is_file() or not all(c in tab.columns for c in R_TEL_COLUMNS):
        return None
    site, inertial = None, False
    for line in _header(tab):
        inertial |= "launch-inertial frame" in line
        site = _NAV_SITE.match(line) or site
    if site is None or not inertial:
        return None
    from casep.frames import LaunchSite

    try:
        lat, lon, h, az, t0 = (float(g) for g in site.groups())
        return LaunchSite(lat, lon, h, az, t0)
    except ValueError:
        return None


def frame_unnamed(tab: Table) -> bool:
    """Whether `tab` has ``casep navigate``'s launch-inertial position ``r_tel_*`` in a file whose header does not
    name its frame and launch site (:func:`navigation_site` None: the ``#`` lines dropped). Its velocity may
    then be launch-inertial, the pad moving with the Earth's rotation, or in a frame with the pad at rest: the
    first-sample speed cannot be read (:func:`casep.checks.late_start.warn_late_start`)."""
    return tab.path.is_file() and all(c in tab.columns for c in R_TEL_COLUMNS) and navigation_site(tab) is None


def start_speed(tab: Table, t: np.ndarray, v_tel: np.ndarray) -> float:
    """The telemetry speed at the first sample relative to the Earth, m/s (the late-start check's
    ``start_speed_m_s``, :func:`casep.checks.late_start.late_start_evidence`).

    A telemetry in the launch-inertial frame (:func:`navigation_site`) carries the pad's own velocity from the
    Earth's rotation (up to 465 m/s): the speed is then that of :func:`casep.frames.launch_to_ecef`,
    ``|v_ECEF(t_0)|``; otherwise ``|v_tel(t_0)|`` (a frame with the pad at rest). The readers record beside it
    :func:`frame_unnamed` (``start_frame_unnamed``): a speed up to 465 m/s may then be the Earth's rotation
    (:func:`casep.checks.late_start.warn_late_start` says so).
    """
    ls = navigation_site(tab)
    if ls is None:
        return float(np.linalg.norm(v_tel[0]))
    from casep.frames import launch_to_ecef

    _, v_e = launch_to_ecef(ls, t[:1], tab.vectors(R_TEL_COLUMNS)[:1], v_tel[:1])
    return float(np.linalg.norm(v_e[0]))


def read_flight(path: str | os.PathLike) -> FlightData:
    """Read a one-file flight (CSV, or Parquet by extension ``.parquet``/``.pq``).

    Parameters
    ----------
    path : str or path-like
        Columns ``t``, ``f_*`` or ``W_*``, and ``dv_*`` or ``v_tel_*`` with ``v_trk_*``; any
        other numeric column becomes a signal (``FlightData.signals``). A row whose three
        ``dv_*`` (or ``v_trk_*``) cells are all empty (Parquet: null) is a telemetry sample without tracking:
        S_V is integrated across it, the regression leaves it out (``FlightData.observed``).

    Returns
    -------
    FlightData
        ``meta`` records the file format, which force and velocity columns were used and,
        with ``v_tel_*`` columns, the telemetry speed at the first sample
        (``start_speed_m_s``, for :func:`casep.checks.late_start.late_start_evidence`), and the
        number of rows without tracking (``unobserved``) when there are any.

    Raises
    ------
    FlightDataError
        Naming file, column and row of the first problem.
    """
    tab = Table(path)
    tab.require(("t",))
    t = tab.time()
    f, force_from = table_force(tab, t)
    observed = np.ones(t.size, dtype=bool)  # every sample tracked, unless dv says otherwise
    if tab.has(DV_COLUMNS) or not any(c in tab.columns for c in VTEL_COLUMNS):
        tab.require(DV_COLUMNS, ". Use: dv_x, dv_y, dv_z, or v_tel_x/y/z with v_trk_x/y/z")
        # a row whose three dv cells are all empty (Parquet: null) is a sample without tracking; a row with
        # only some of them empty is refused by Table.numeric, naming its first empty cell
        untracked = tab.all_missing(DV_COLUMNS)
        dv, dv_from = tab.vectors(DV_COLUMNS, skip=untracked), "dv"
        observed = ~untracked
    else:
        tab.require(VTEL_COLUMNS + VTRK_COLUMNS, ". Use: v_tel_x/y/z with v_trk_x/y/z, or dv_x, dv_y, dv_z")
        v_tel = tab.vectors(VTEL_COLUMNS)
        # the same rule for v_trk (an INS log at 50 Hz with its 10 Hz GNSS fixes): three empty cells, untracked
        untracked = tab.all_missing(VTRK_COLUMNS)
        dv, dv_from = v_tel - tab.vectors(VTRK_COLUMNS, skip=untracked), ONE_FILE_TELEMETRY
        observed = ~untracked
    meta: dict[str, Any] = {"format": "parquet" if is_parquet(tab.path) else "csv", "force": force_from, "dv": dv_from,
            "rows_file": str(tab.path)}  # sample k is data row k + 1 (locate_samples)
    if dv_from != "dv":
        meta["start_speed_m_s"] = start_speed(tab, t, v_tel)
        meta["start_frame_unnamed"] = frame_unnamed(tab)
        meta["levelled"] = levelling_record(tab)
        meta["telemetry_velocity_change_m_s"] = (v_tel[-1] - v_tel[0]).tolist()  # for casep.checks.plausibility
        meta["tracking_repeats"] = repeated_rows(tab, "launch", skip=~observed)  # for casep.checks.tracking_quality
    if not observed.all():
        meta["unobserved"] = int((~observed).sum())  # rows without tracking (all dv, or all v_trk, cells empty)
    signals, src = tab.signals(), tab.src
    tab.strapdown_signals(signals, meta)  # q_*, fb_*, w_*: the checked quaternions, what the checks found
    del tab  # the file's columns, before FlightData takes its own copies (long flights: one copy at a time)
    return FlightData(t, f, dv, source=src, meta=meta, observed=observed, signals=signals)



def _tracking_shift(tel: Table, trk: Table, t_tel: np.ndarray, v_tel: np.ndarray, t_trk: np.ndarray,
                    v_trk: np.ndarray, time_offset: float | str | None,
                    repeats: np.ndarray, frozen: np.ndarray | None = None,
                    r_trk: np.ndarray | None = None, stood: dict | None = None) -> tuple[float, dict[str, Any]]:
    """The shift of the tracking time tags :func:`read_flight_pair` applies, s, and its ``time_alignment`` record.

    ``"auto"``: the coarse offset that lines up the velocities of the epochs not stale
    (:func:`casep.io.align.fresh_epochs`; `repeats`: the file's repeated rows, :func:`repeated_rows`, `frozen` its
    rows of a repeated position and `r_trk` its launch-inertial positions, an Earth-fixed file's; `stood` where the
    telemetry stood, :func:`_stood`, its window :func:`casep.io.pair.rest_window`'s; the record's ``stale_left_out``
    counts the others); None: none, with a warning when that
    offset exceeds a tracking sample period and explains the misfit; a number: that shift (a warning
    beyond :data:`MAX_TIME_OFFSET`).
    """
    from casep.io.align import AUTO_MAX_STD, coarse_time_offset, fresh_epochs, unaligned_lateness

    align, stale = None, 0
    if time_offset is None or time_offset == "auto":
        # on the epochs the fit uses: a held (stale) velocity lags the vehicle and would read as late tags
        repeated, still = np.zeros(t_trk.size, bool), np.zeros(t_trk.size, bool)  # velocity, position repeated
        repeated[repeats] = True
        if frozen is not None:
            still[frozen] = True
        rest = pair_rest_window(stood or {})  # the telemetry at rest there: a repeat is a fix
        fresh = fresh_epochs(t_tel, v_tel, t_trk, v_trk, repeated, still, r_trk, rest)
        stale = int((~fresh).sum())
        try:
            align = coarse_time_offset(t_tel, v_tel, t_trk[fresh], v_trk[fresh],
                                       max_offset=min(2.0, 0.25 * (t_trk[-1] - t_trk[0])))
        except ValueError:
            if time_offset == "auto":
                raise
    import warnings

    from casep.exceptions import SetupWarning, TimeOffsetWarning

    if time_offset == "auto":
        assert align is not None  # "auto" re-raised a failed alignment above
        shift = align.tau
        if not align.std <= AUTO_MAX_STD * align.tracking_period:
            shift = 0.0
            warnings.warn(f"{tel.src} + {trk.src}: --time-offset auto: the velocities line up best with the tracking "
                          f"tags {align.tau * 1e3:.4g} ms late, but that offset's std is {align.std * 1e3:.3g} ms, "
                          f"more than {AUTO_MAX_STD:g} of a tracking sample period ({align.tracking_period * 1e3:.4g} "
                          "ms): the record barely determines it (too little acceleration to line up: a vehicle at "
                          "rest?). Not applied: the tags are used as they are", TimeOffsetWarning, stacklevel=3)
    elif time_offset is None:
        shift = 0.0
        if align is not None and unaligned_lateness({**align.to_dict(), "mode": "none"}) is not None:
            # only when the shift explains the data: a wrong site or frame leaves a misfit no shift removes
            warnings.warn(f"{tel.src} + {trk.src}: the tracking time tags look {align.tau * 1e3:.1f} ms late "
                          f"(velocity increments line up best there: mean squared difference {align.cost:.3g} against "
                          f"{align.cost_at_zero:.3g} m^2/s^2 unshifted, {100 * align.gain:.3g} % of the misfit "
                          "removed, "
                          f"F = {align.f_statistic:.3g}), more than a tracking sample period "
                          f"({align.tracking_period * 1e3:.4g} ms); align them (--time-offset auto) and let dt_trk "
                          "estimate the rest", TimeOffsetWarning, stacklevel=3)
    else:
        try:
            shift = float(time_offset)
        except (TypeError, ValueError):
            raise ValueError(f"`time_offset` must be a number of seconds, 'auto' or None, "
                             f"got {time_offset!r}") from None
        if not np.isfinite(shift):
            raise ValueError(f"`time_offset` must be finite, got {shift}")
        if abs(shift) > MAX_TIME_OFFSET:
            span = t_trk[-1] - t_trk[0]
            warnings.warn(SetupWarning(
                f"{trk.src}: a tracking time offset of {shift:.6g} s ({shift * 1e3:.6g} ms) is far beyond tracking "
                f"latencies (milliseconds, below {MAX_TIME_OFFSET:g} s; --time-offset is in milliseconds) and is "
                f"{100 * abs(shift) / span:.3g} % of the {span:.4g} s tracking span. If the two files count time from "
                "different origins, state it with time_shift (--time-shift SECONDS, manifest time_shift_s)."),
                stacklevel=3)
    mode = "auto" if time_offset == "auto" else ("none" if time_offset is None else "given")
    return shift, {**(align.to_dict() if align is not None else {}), **({"stale_left_out": stale} if stale else {}),
                   "applied_s": shift, "mode": mode}


def _stood(tel: Table, rest_window: tuple[float, float] | list[float] | None) -> dict[str, Any]:
    """Where the telemetry stood, as a flight's ``meta`` records it: ``levelled`` (its header's levelling,
    :func:`levelling_record`) and ``rest_window_s`` (the window given, :func:`read_flight_pair`), read by
    :func:`casep.io.pair.rest_window`."""
    given = {} if rest_window is None else {"rest_window_s": [float(rest_window[0]), float(rest_window[1])]}
    return {"levelled": levelling_record(tel), **given}


def read_flight_pair(telemetry: str | os.PathLike | Table, tracking: str | os.PathLike, *,
                     interpolation: str = "cubic", grid: str = "tracking",
                     time_offset: float | str | None = None, tracking_frame: str = "launch",
                     site=None, time_shift: float = 0.0, clock_drift: float = 0.0,
                     clock_drift_std: float | None = None, rest_window: tuple | list | None = None) -> FlightData:
    """Combine a telemetry file and a tracking file recorded at different rates.

    Parameters
    ----------
    telemetry : path or Table
        ``t``, ``f_*`` or ``W_*``, ``v_tel_*``; its other numeric columns become signals
        (the tracking file's other columns are not read). A :class:`casep.io.tables.Table` (one held in
        memory, :meth:`~casep.io.tables.Table.from_columns`) is read as its file would be.
    tracking : path
        ``t``, ``v_trk_*``, at its own times.
    interpolation : {"cubic", "linear"}, optional
        How the velocity of the other source is carried to the grid's times (see `grid`): a
        not-a-knot cubic spline (error of order dt^4 times the 4th derivative, default) or
        linear (error ~ a dt^2 / 8: 0.016 m/s at 50 m/s^2 and 20 Hz, not negligible against
        0.1 m/s noise).
    grid : {"tracking", "telemetry"}, optional
        Where dv is formed. ``"tracking"`` (default): at the tracking times, ``dv = v_tel(t_trk) -
        v_trk``, the (smooth, nearly noise-free) telemetry velocity interpolated; each tracking
        sample is one row, so its noise stays white and the std are honest. ``"telemetry"``: at
        the telemetry times, the tracking velocity interpolated, which spreads each tracking
        sample's noise over ``f_tel / f_trk`` correlated rows: white-noise std then understate the
        error by about ``sqrt(f_tel / f_trk)`` (casep 0.1's behaviour, kept for comparison).
    time_offset : float, "auto" or None, optional
        Tracking time tags late by this many seconds: they are shifted back before the pair is
        formed. ``"auto"``: the coarse offset that lines up the velocities
        (:func:`casep.io.align.coarse_time_offset`, on the tracking epochs the stale screen keeps:
        :func:`casep.io.align.fresh_epochs`; the model term ``dt_trk`` then finds the rest). None
        (default): no shift, but the coarse offset is still computed and a
        :class:`~casep.exceptions.TimeOffsetWarning` gives it when it exceeds a tracking sample
        period (a first-order ``dt_trk`` is not meant for that). ``meta["time_alignment"]`` records it.
    tracking_frame : {"launch", "ecef", "geodetic"}, optional
        Frame of the tracking file. ``"launch"`` (default): ``t, v_trk_*``, launch-inertial.
        ``"ecef"``: ``t, r_ecef_x/y/z, v_ecef_x/y/z`` (m, m/s; WGS84, Earth-fixed, velocity relative
        to the rotating Earth). ``"geodetic"``: ``t, lat, lon, h, v_east, v_north, v_up`` (deg, deg, m
        above the ellipsoid, m/s in the local ENU axes). Earth-fixed tracking is turned into the
        launch-inertial velocity (:mod:`casep.frames`, Earth rotation included) at the file's own
        time tags, before any `time_offset` shift; ``meta["tracking_frame"]`` records frame and site.
    site : casep.frames.LaunchSite, optional
        Launch point, azimuth and launch time (in the tracking file's time scale): required with an
        Earth-fixed `tracking_frame` (ValueError naming the file otherwise). The set-up checks
        (:func:`casep.io.setup.setup_evidence`) compare the first tracked position with it and
        the telemetry velocity at its first sample with its pad velocity; ``meta["setup"]``.
    time_shift : float, optional
        How the time scales relate, s: tracking time minus telemetry time for the same instant
        (tracking in seconds of day, telemetry from lift-off at 12:00:00: 43200). Tracking time
        tags ``T`` become ``T - time_shift`` in the telemetry's scale; the launch time stays in the
        tracking scale. Default 0 (one time scale). Telemetry and tracking that do not overlap
        after it are an error that gives both spans.
    clock_drift : float, optional
        How the clocks' rates differ, ppm: the tracking time tags late by ``clock_drift 1e-6 t`` more at
        telemetry time ``t`` (``T - time_shift = t (1 + clock_drift 1e-6)``, :func:`casep.io.pair.telemetry_time`;
        the drift the clock-drift checks measure, same sign: negative when the telemetry clock runs fast), taken
        out of the tags before the pair is formed. A strapdown telemetry (``q_*``, ``fb_*``, ``w_*``) was
        integrated by its INS over its clock's steps: the drift is taken out of its velocity too, ``v_tel + eps E``
        (:func:`casep.io.strapdown.clock_stretch`, with the gravitation where the telemetry's header or `site`
        gives the launch site; ``meta["clock_drift_of"]`` ``"telemetry"``). Default 0 (one rate; the fit's
        ``dt_trk`` takes a constant offset, not a drift).
    clock_drift_std : float, optional
        A strapdown telemetry's: the std of its clock's drift beyond `clock_drift`, ppm, carried into the
        separation's std (``meta["clock_drift_std_ppm"]``, checked there; the rule and its defaults:
        :func:`casep.workflows.imu_separate.given_clock_std`, the one of ``--imu``); 0: the rate exact.
    rest_window : (T1, T2), optional
        The window the telemetry was levelled over, s of its time (the vehicle at rest there by the navigation's
        premise), where its header does not name one: a navigation held in memory (``--imu``'s ``--align``,
        :mod:`casep.workflows.imu_separate`). ``meta["rest_window_s"]``; the tracking screen and the time alignment
        (`time_offset` ``"auto"``) take a repeated fix there as a fix (:func:`casep.io.pair.rest_window`, one rule).

    Returns
    -------
    FlightData
        Every telemetry sample from the first one to the end of tracking (with ``grid="tracking"``
        the tracking times inserted among them, force and signals linearly interpolated there):
        S_V is integrated from the first telemetry sample, so the instrument errors before tracking
        starts are kept. dv is observed (``observed``) at the tracking times (or at the telemetry
        samples inside the tracking span) and NaN elsewhere. ``meta`` records the grid, the spans
        (s), the samples before tracking (``unobserved``) and after it (``telemetry_dropped``),
        the telemetry speed at the first sample (``start_speed_m_s``) and, for ``casep navigate``'s
        telemetry, the launch site its header names (``telemetry_site``, :func:`navigation_site`).
    """
    if interpolation not in ("cubic", "linear"):
        raise ValueError(f"`interpolation` must be 'cubic' or 'linear', got {interpolation!r}")
    if grid not in PAIR_GRIDS:
        raise ValueError(f"`grid` must be one of {', '.join(PAIR_GRIDS)}, got {grid!r}")
    check_tracking_frame(tracking, tracking_frame, site)
    tel, trk = telemetry if isinstance(telemetry, Table) else Table(telemetry), Table(tracking)
    tel.require(("t",))
    from casep.frames import ECEF_COLUMNS, GEODETIC_COLUMNS

    trk.require({"launch": ("t",) + VTRK_COLUMNS, "ecef": ECEF_COLUMNS, "geodetic": GEODETIC_COLUMNS}[tracking_frame],
                tracking_hint(trk, tracking_frame))
    tel.require(VTEL_COLUMNS, ". Use: v_tel_x, v_tel_y, v_tel_z")
    t_tel = tel.time()
    f, force_from = table_force(tel, t_tel)
    v_tel = tel.vectors(VTEL_COLUMNS)
    t_raw = trk.time()  # the tracking file's own time scale (the launch time's)
    if site is not None:
        check_launch_time(trk, t_raw, site)
    v_trk, r_ecef, v_ecef, r_l = tracking_velocity(trk, t_raw, tracking_frame, site)  # launch-inertial (v, r_l)
    if t_raw.size < (4 if interpolation == "cubic" else 2):
        raise trk.error(f"{t_raw.size} tracking samples are too few for {interpolation} interpolation", "t", t_raw.size)
    shift_scale, drift = time_shift_seconds(time_shift), clock_drift_ppm(clock_drift)
    t_trk = telemetry_time(t_raw, shift_scale, drift)  # the telemetry's time scale
    span = (t_raw[-1] - t_raw[0]) / max(float(t_tel[-1] - t_tel[0]), 1e-300)
    if 300.0 < span < 3000.0:  # the tracking's times span ~1000 x the telemetry's: its t in ms
        raise trk.error(f"tracking time [{t_raw[0]:.10g}, {t_raw[-1]:.10g}] spans {span:.4g} x the telemetry's "
                        f"[{t_tel[0]:.10g}, {t_tel[-1]:.10g}] s: is the tracking file's t in ms (divide by 1000)?", "t")
    inside = (t_tel >= t_trk[0]) & (t_tel <= t_trk[-1])
    if inside.sum() < 2:
        raise tel.error(no_overlap_message(t_tel, t_raw, shift_scale), "t")
    repeats = repeated_rows(trk, tracking_frame)
    frozen = repeated_rows(trk, tracking_frame, part="position") if r_l is not None else None
    signals = tel.signals()
    strapdown: dict[str, Any] = {}
    tel.strapdown_signals(signals, strapdown)
    stretched = drift and all(c in signals for c in STRAPDOWN_COLUMNS)
    if stretched:  # the INS integrated over its clock's steps: the given drift out of its velocity as well
        q, fb, w = (np.column_stack([signals[c] for c in cols])
                    for cols in (STRAPDOWN_COLUMNS[:4], STRAPDOWN_COLUMNS[4:7], STRAPDOWN_COLUMNS[7:10]))
        gsite = navigation_site(tel) or site  # the INS's gravitation through its position error, where known
        r_ins = tel.vectors(R_TEL_COLUMNS) if gsite is not None and all(c in tel.columns for c in R_TEL_COLUMNS) \
            else None
        v_tel = v_tel + drift * 1e-6 * clock_stretch(t_tel, q, fb, w, v_tel, r_ins,
                                                     None if r_ins is None else launch_gravitation(gsite))
    stood = _stood(tel, rest_window)  # meta's "levelled" and "rest_window_s"
    shift, alignment = _tracking_shift(tel, trk, t_tel, v_tel, t_trk, v_trk, time_offset, repeats, frozen, r_l, stood)
    extra: dict[str, Any] = {"time_alignment": alignment, "tracking_repeats": repeats, **strapdown}
    if frozen is not None and r_l is not None:  # a frozen position judged by the telemetry's own (the screen)
        extra.update(tracking_frozen=frozen, tracking_position_gap=position_gap(t_tel, v_tel, t_trk - shift, r_l))
    if not all(f"a_{a}" in signals for a in "xyz"):
        signals.update(acceleration_signals(t_tel, v_tel))
        extra["kinematic_acceleration"] = "a_x, a_y, a_z: d v_tel / dt (cubic spline of the telemetry velocity)"
    if tracking_frame != "launch":
        extra["tracking_frame"] = {"frame": tracking_frame, "site": site.to_dict()}
    flight = pair_flight(t_tel, f, v_tel, t_trk - shift, v_trk, signals=signals, interpolation=interpolation,
                         grid=grid, source=f"{tel.src} + {trk.src}",
                         meta={"force": force_from, "telemetry": tel.src, "tracking": trk.src, **extra})
    flight.meta["rows_file"] = str(trk.path if flight.meta.get("rows_side") == "tracking" else tel.path)
    flight.meta["start_speed_m_s"] = start_speed(tel, t_tel, v_tel)
    nav_site = navigation_site(tel)
    flight.meta["start_frame_unnamed"] = frame_unnamed(tel)
    if nav_site is not None:  # the telemetry's own frame (its gravitation: casep.workflows.telemetry_iterate)
        flight.meta["telemetry_site"] = nav_site.to_dict()
    flight.meta.update({**stood, **({"time_shift_s": shift_scale} if shift_scale else {})})  # levelled, rest_window_s
    flight.meta.update({} if clock_drift_std is None else {"clock_drift_std_ppm": clock_drift_std})
    if drift:
        flight.meta["clock_drift_ppm"] = drift
        if stretched:
            flight.meta["clock_drift_of"] = "telemetry"
    if r_ecef is not None and v_ecef is not None:  # Earth-fixed tracking; the late-start check: speed relative
        # to the pad, not the Earth's rotation
        from casep.io.setup import setup_evidence

        ev = setup_evidence(site, t_tel, v_tel, t_raw, r_ecef, v_ecef, time_shift=shift_scale, clock_drift=drift)
        from casep.io.setup import header_site_problem

        other_site = header_site_problem(site, nav_site)
        if other_site is not None:
            ev["problems"].append(other_site)
        clock = ev["pad"].get("clock_offset")
        if clock is not None:
            import warnings

            from casep.exceptions import TimeOffsetWarning

            warnings.warn(f"{tel.src} + {trk.src}: {clock['message']}; the fit's dt_trk estimates it",
                          TimeOffsetWarning, stacklevel=2)
        flight.meta["start_speed_m_s"] = ev["pad"]["speed_relative_m_s"]
        flight.meta["start_frame_unnamed"] = False  # relative to the pad, from the Earth-fixed tracking
        flight.meta["tracking_frame"]["pad_velocity_m_s"] = ev["pad"]["pad_velocity_m_s"]
        flight.meta["setup"] = ev
    if r_l is not None and not any(c in flight.signals for c in STATE_SIGNALS):  # Earth-fixed: the state
        flight = with_tracked_state(flight, t_trk - shift, r_l, v_trk)
    return flight


def write_table(path: str | os.PathLike, columns: dict[str, np.ndarray], *,
                comments: list[str] | None = None, nan_as_missing: bool = False) -> None:
    """Write named 1-D columns as CSV (``%.17g``, exact round trip) or Parquet, atomically.

    Parameters
    ----------
    path : path
        ``.parquet`` / ``.pq`` writes Parquet (needs pyarrow), anything else CSV.
    columns : dict of str -> (N,) array
        Column name to values, in order.
    comments : list of str, optional
        CSV only: lines written first as ``# ...`` (Parquet keeps them as metadata).
    nan_as_missing : bool, optional
        Write NaN as a missing cell, empty in CSV and null in Parquet (what :func:`read_flight` takes
        for a sample without tracking in the dv columns), instead of ``nan`` / a NaN value.
    """
    path = Path(path)
    names = list(columns)
    data = np.column_stack([np.asarray(columns[c], dtype=float) for c in names])
    if is_parquet(path):
        try:
            import pyarrow as pa
            import pyarrow.parquet as pq
        except ImportError:
            raise ValueError(f"{path}: writing Parquet needs pyarrow: pip install pyarrow") from None
        table = pa.table({c: pa.array(data[:, i], from_pandas=nan_as_missing) for i, c in enumerate(names)},
                         metadata={"comments": "\n".join(comments or [])})
        with atomic_open(path, binary=True) as fh:
            pq.write_table(table, fh)
        return
    with atomic_open(path) as fh:
        for line in comments or []:
            fh.write(f"# {line}\n")
        fh.write(",".join(names) + "\n")
        np.savetxt(_EmptyNaN(fh) if nan_as_missing and np.isnan(data).any() else fh, data, delimiter=",", fmt="%.17g")


class _EmptyNaN:
    """A text file whose ``write`` leaves NaN cells empty: ``%.17g`` writes NaN as ``nan``, and
    no finite number or ``inf`` contains those letters, so removing them empties exactly the NaN cells."""

    def __init__(self, fh: Any) -> None:
        self.fh = fh

    def write(self, text: str) -> None:
        self.fh.write(text.replace("nan", ""))


def write_flight(flight: FlightData, path: str | os.PathLike, *, comments: list[str] | None = None,
                 force: bool = True) -> None:
    """Write a flight (``t, f_x, f_y, f_z, dv_x, dv_y, dv_z``, then its signals) as CSV or Parquet, atomically.

    ``force=False`` leaves ``f_*`` out: a strapdown flight, whose reader computes ``f = C(q) fb`` from its
    ``q_*`` and ``fb_*`` signals.

    A sample without tracking (``observed`` False) is written with its three dv cells empty (CSV) or null
    (Parquet), as are NaN signal values: :func:`read_flight` reads such a row back as not observed.
    """
    if not isinstance(flight, FlightData):
        raise TypeError(f"`flight` must be a FlightData, got {type(flight).__name__}")
    cols = {"t": flight.t}
    if force:
        cols.update({c: flight.f[:, i] for i, c in enumerate(FORCE_COLUMNS)})
    dv = np.where(flight.observed[:, None], flight.dv, np.nan)  # a sample without tracking: all three dv missing
    cols.update({c: dv[:, i] for i, c in enumerate(DV_COLUMNS)})
    cols.update(flight.signals)
    write_table(path, cols, comments=comments, nan_as_missing=True)


def read_json_table(path: str | os.PathLike, option: str) -> dict:
    """A JSON object keyed by coefficient name (``--bounds``, ``--prior``, ``--truth``, ``--scales``).

    Read strictly (:func:`casep.io.result_json.load_json`: a key repeated in one object, or
    nesting too deep to decode, is refused). Errors name the option and the file (``ValueError``);
    the entries are checked by the caller, which knows the model's coefficients.
    """
    from casep.io.result_json import load_json

    data = load_json(path, option)
    if not isinstance(data, dict):
        found = {list: "an array", str: "a string", bool: "true/false", type(None): "null"}.get(type(data), "a number")
        raise ValueError(f"{option} {path}: must hold a JSON object keyed by coefficient name ({{\"Kg0x\": ...}}), "
                         f"got {found}")
    return data


def acceleration_signals(t: np.ndarray, v: np.ndarray) -> dict[str, np.ndarray]:
    """The kinematic acceleration of a time-offset term, ``a = dv/dt`` (derivative of the cubic spline through the
    velocity `v` at the times `t`, m/s^2): signals ``a_x, a_y, a_z``. A pass that re-navigates the telemetry takes
    its own velocity's (the offset's row is ``a(t) dt_trk`` of the corrected trajectory, not of the raw one)."""
    from scipy.interpolate import CubicSpline

    acc = CubicSpline(np.asarray(t, float), np.asarray(v, float), axis=0).derivative()(np.asarray(t, float))
    return {f"a_{a}": acc[:, i] for i, a in enumerate("xyz")}

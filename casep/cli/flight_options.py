"""Shared argument groups of the commands that read flights: two-file input (grid, clocks, manifest), tracking
frames, radar stations, one's own trajectory; the IMU's declared full scales (also taken by calibrate)."""

from __future__ import annotations

import argparse
from typing import Any

from casep.cli.types import finite_float, time_offset

__all__ = ["FRAMES", "add_tracking", "add_grid", "add_frames", "add_launch_site", "add_radar",
           "add_own_trajectory", "add_full_scales", "full_scales"]

FRAMES = ("launch", "ecef", "geodetic")


def add_tracking(parser: Any, help: str) -> None:
    """``--tracking FILE`` (two-file input; once per flight)."""
    parser.add_argument("--tracking", metavar="FILE", default=None, action="append", help=help)


def add_grid(parser: Any, manifest: bool = True) -> None:
    """``--grid``, ``--time-offset``, ``--time-shift``, ``--clock-drift``; ``--manifest`` unless `manifest` is false."""
    parser.add_argument("--grid", choices=("tracking", "telemetry"), default="tracking",
                        help="with --tracking: form dv at the tracking times (default: one row per tracking "
                             "sample, white noise, honest std) or at the telemetry times (tracking interpolated: "
                             "std too small by about sqrt(f_tel / f_trk))")
    parser.add_argument("--time-offset", type=time_offset, default=None, metavar="auto|MS",
                        help="with --tracking: tracking time tags late by MS milliseconds, shifted back; 'auto': the "
                             "offset that lines up the velocity increments (then fit dt_trk for the rest); default: "
                             "none, with a warning when that offset exceeds a tracking sample period")
    parser.add_argument("--time-shift", type=finite_float, default=0.0, metavar="SECONDS",
                        help="with --tracking: how the time scales relate, tracking time minus telemetry time "
                             "(tracking in seconds of day, telemetry from lift-off at 12:00:00: 43200); default 0 "
                             "(one scale)")
    parser.add_argument("--clock-drift", type=finite_float, default=0.0, metavar="PPM",
                        help="with --tracking: how fast the tracking (GPS) clock runs against the telemetry's, ppm: "
                             "NEGATIVE when the telemetry (or IMU) clock runs fast, e.g. a flight computer 104 ppm "
                             "fast: --clock-drift -104 (the sign casep reports; taken out of the tracking tags and, "
                             "for a strapdown telemetry or with --imu, out of the INS's integration steps too; a "
                             "drift the data contradict fails); default 0")
    if manifest:  # impact has its own (a manifest of one flight, with its result)
        parser.add_argument("--manifest", metavar="FLIGHTS.toml", default=None,
                            help="TOML manifest listing each flight's telemetry, tracking, frame, site, launch time "
                                 "and time shift (docs/guide/range-data.md), instead of the flight files and these "
                                 "options")


def add_frames(parser: Any) -> None:
    """The tracking file's frame and the launch site tying it to the platform frame."""
    parser.add_argument("--tracking-frame", choices=FRAMES, default="launch",
                        help="with --tracking: frame of the tracking file: launch (t, v_trk_*, launch-inertial; "
                             "default), ecef (t, r_ecef_*, v_ecef_*, WGS84, m, m/s) or geodetic (t, lat, lon, h, "
                             "v_east, v_north, v_up; deg, deg, m, m/s); ecef and geodetic need --launch-site and "
                             "--launch-time")
    add_launch_site(parser)


def add_launch_site(parser: Any, *, required: bool = False, scale: str = "the tracking file's") -> None:
    """``--launch-site LAT LON H AZ`` and ``--launch-time T0``: what ties the launch-inertial frame to the Earth."""
    parser.add_argument("--launch-site", type=float, nargs=4, default=None, required=required,
                        metavar=("LAT", "LON", "H", "AZ"),
                        help="launch point (geodetic latitude, longitude, deg; height above the WGS84 ellipsoid, m) "
                             "and azimuth of the platform x axis (deg from north, clockwise)")
    parser.add_argument("--launch-time", type=float, default=None, required=required, metavar="T0",
                        help=f"launch time in {scale} time scale, s (the launch-inertial frame is the "
                             "Earth-fixed launch triad at T0)")


def add_radar(parser: Any) -> None:
    """Radar measurements of one or more stations (measurement domain)."""
    parser.add_argument("--radar", nargs=2, action="append", default=None, metavar=("STATION.json", "MEAS.csv"),
                        help="a radar station ({name, lat, lon, h}: deg, deg, m WGS84) and its measurements (t, range "
                             "m, azimuth deg from north, elevation deg, optional range_rate m/s); repeat per station. "
                             "The flight file is then the telemetry (t, f_*, v_tel_*, optional r_tel_*); needs "
                             "--launch-site and --launch-time")
    parser.add_argument("--tracking-model", default="radar_biases", metavar="NAME|FILE",
                        help="with --radar: the station error model (default radar_biases)")


def add_own_trajectory(parser: Any) -> None:
    """One's own trajectory (a flight file) and truth instead of the scenario's."""
    parser.add_argument("--flight", metavar="FILE", default=None,
                        help="one's own trajectory: a flight file (t, f_*, dv_* or v_tel_*/v_trk_*) whose times and "
                             "specific force replace the scenario's; needs --truth")
    parser.add_argument("--truth", metavar="TRUTH.json", default=None,
                        help='with --flight: true coefficients {"Kg0x": value, ...} (natural units) or a truth file of '
                             "casep simulate (its model and noise used; else white noise of the flight's own "
                             "least-squares residual std)")
    parser.add_argument("--model", default=None,
                        help="model name or .py file of --truth and --prior when it is not shipped with casep (a model "
                             "file is Python code: casep runs one only when it is named here, never on a file's word; "
                             "without --truth the runs use the scenario's model)")


def add_full_scales(parser: Any, what: str) -> None:
    """``--acc-range G`` and ``--gyr-range DPS``: the sensors' declared full scales (:func:`full_scales` checks
    them). `what`: what the command does with readings at them."""
    parser.add_argument("--acc-range", default=None, metavar="G", dest="acc_range",
                        help="the accelerometers' full scale +-G, g: 3 readings in a row at or beyond 99 %% of it "
                        "are clipped (casep.checks.saturation; default: the column's extreme held at a nominal "
                        f"range, or raw counts at the converter's limit); {what}")
    parser.add_argument("--gyr-range", default=None, metavar="DPS", dest="gyr_range",
                        help="the gyros' full scale +-DPS, deg/s (as --acc-range)")


def full_scales(args: argparse.Namespace) -> dict[str, float | None]:
    """``--acc-range G``, ``--gyr-range DPS`` checked (a finite number > 0, else the one form of a refused option:
    ``option --gyr-range (`gyr_range`) must be a finite number > 0 (deg/s), got '-2'``) and in SI:
    ``{"acc_range": m/s^2, "gyr_range": rad/s}`` (None: not given)."""
    from casep.checks.saturation import FULL_SCALE_UNITS, check_full_scale

    out: dict[str, float | None] = {}
    for key, sensor in (("acc_range", "accelerometer"), ("gyr_range", "gyro")):
        value = getattr(args, key)
        unit, si = FULL_SCALE_UNITS[sensor]
        out[key] = None if value is None else check_full_scale(value, key, "--" + key.replace("_", "-"), unit) * si
    return out


def flight_model(args: Any, imu: bool = False) -> str:
    """``args.model``, or the model the first flight file's header calls for
    (:func:`casep.model.loader.default_model`): one default for every command that reads a flight."""
    if args.model is None:
        from casep.model.loader import default_model

        flights = args.flight if isinstance(args.flight, list) else [args.flight] if args.flight else []
        args.model = default_model(flights[0] if flights else None, imu)
    return args.model

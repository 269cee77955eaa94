"""``casep simulate -o FLIGHT``: a boost flight with injected errors (casep.simulation); Earth-fixed tracking
(casep.simulation.earth_fixed) and radar stations (casep.cli.radar)."""

from __future__ import annotations

import argparse
from typing import Any

from casep.cli import inputs, outputs
from casep.cli.flight_options import FRAMES
from casep.cli.imu_output import add_imu_output, imu_sensor
from casep.cli.radar import add_simulate_radar, radar_only
from casep.cli.types import rate


def add_parser(sub: Any) -> None:
    from casep.simulation.scenarios import SCENARIOS

    p = sub.add_parser("simulate", help="simulate a boost flight with injected errors")
    p.add_argument("--scenario", default="paper", choices=list(SCENARIOS), help="scenario (default paper)")
    p.add_argument("--seed", type=int, default=0, help="noise seed (default 0)")
    p.add_argument("--noise-free", action="store_true",
                   help="no tracking noise or outliers (dv = S_V D to rounding): the first check of a model file or "
                        "a set-up, casep separate then recovers the truth to rounding")
    p.add_argument("--rate", type=rate, default=None, help="sample rate, Hz (default: scenario's)")
    p.add_argument("-o", "--output", required=True, metavar="FILE",
                   help="flight file (.csv, or .parquet); truth goes to <stem>.truth.json beside it")
    p.add_argument("--model", default=None, help="error model to inject, name or .py file (default: the scenario's)")
    p.add_argument("--truth", metavar="FILE", default=None,
                   help='true coefficients, JSON {"Kg0x": value, ...} natural units, or a .truth.json sidecar '
                        "(default: the scenario's; names not given are 0)")
    p.add_argument("--tracking-offset", type=float, default=0.0, metavar="MS",
                   help="tracking time tags late by MS milliseconds: v_trk(t) = v_true(t - MS) (default 0)")
    p.add_argument("--lever-arm", type=float, nargs=3, default=None, metavar=("LX", "LY", "LZ"),
                   help="tracked point from the platform, m, body frame (default 0 0 0); the flight file's "
                        "att_pitch/att_yaw/att_roll (rad) and omega_x/y/z (rad/s, body) columns describe the attitude")
    p.add_argument("--rotating-earth", action="store_true",
                   help="Earth turning at 7.292115e-5 rad/s (needs --launch-site): the vehicle starts with the "
                        "pad's velocity, drag relative to the co-rotating air; the flight stays launch-inertial")
    p.add_argument("--launch-site", type=float, nargs=4, default=None, metavar=("LAT", "LON", "H", "AZ"),
                   help="with --rotating-earth: launch point (deg, deg, m above WGS84) and azimuth of x (deg from "
                        "north, clockwise); lift-off is t = 0 (read back with --launch-time 0)")
    p.add_argument("--tracking-frame", choices=FRAMES, default="launch",
                   help="with --rotating-earth: ecef or geodetic writes two files, the telemetry (-o: t, f_*, v_tel_*, "
                        "a_*; a strapdown scenario's t, dv_*, q_*, fb_*, w_*, raw IMU with --imu-output) and the "
                        "tracking in that frame (--tracking-output); default launch: the one-file flight")
    p.add_argument("--tracking-rate", type=rate, default=None, metavar="HZ",
                   help="tracking sample rate (with --tracking-frame ecef|geodetic default 20; otherwise, and for "
                        "a strapdown scenario, the flight's --rate, which it must divide: every k-th sample tracked)")
    p.add_argument("--tracking-output", metavar="FILE", default=None,
                   help="with --tracking-frame ecef|geodetic: tracking file (default <stem>.tracking<suffix>)")
    add_imu_output(p)  # --imu-output, --imu-pad, the sensors' noise and full scales
    add_simulate_radar(p)  # --radar-station, --tracking-truth, --radar-rate, noise


def _site(args: argparse.Namespace) -> Any:
    """The LaunchSite (t0 = 0: lift-off), or None without --rotating-earth."""
    if not args.rotating_earth:
        if args.launch_site is not None or args.tracking_frame != "launch":
            raise ValueError("--launch-site and --tracking-frame ecef|geodetic need --rotating-earth")
        return None
    if args.launch_site is None:
        raise ValueError("--rotating-earth needs --launch-site LAT LON H AZ (deg, deg, m, deg from north)")
    return inputs.launch_site(args.launch_site, 0.0)


def run(args: argparse.Namespace) -> int:
    from casep.simulation.earth_fixed import read_truth, tracking_path, write_strapdown_earth_fixed
    from casep.simulation.simulate import truth_path

    site = _site(args)  # --rotating-earth --launch-site (tracking frames)
    if args.radar_station:
        from casep.cli.radar import simulate_radar

        if args.noise_free:
            raise ValueError("--noise-free is the tracking velocity's: with --radar-station the radar noise is "
                             "--range-noise and --angle-noise")
        return simulate_radar(args, site)
    radar_only(args, ("tracking_truth", "radar_rate", "range_noise", "angle_noise", "radar_range_rate"))
    from casep.simulation.scenarios import get_scenario

    scenario = get_scenario(args.scenario).without_noise() if args.noise_free else args.scenario
    out = args.output
    files = {"-o": out, "-o (truth sidecar)": truth_path(out)}
    if args.imu_output is not None:
        files["--imu-output"] = args.imu_output
    elif args.imu_pad:
        raise ValueError("--imu-pad needs --imu-output")
    if args.tracking_frame == "launch" and args.tracking_output is not None:
        raise ValueError("--tracking-output needs --tracking-frame ecef|geodetic")
    if args.tracking_frame != "launch":
        files = {"-o": out, "--tracking-output": args.tracking_output or tracking_path(out), **files}
    outputs.check(files, inputs.input_files(args, "truth"))
    if args.tracking_frame != "launch" and args.lever_arm is not None:
        raise ValueError("--lever-arm is not available with --tracking-frame ecef|geodetic yet; leave it out")
    if args.seed < 0:
        raise ValueError(f"`--seed` must be >= 0, got {args.seed}")
    sensor = imu_sensor(args)  # the raw IMU's white noise and full scales (None: noise-free)
    truth = None
    if args.truth:  # {"Kg0x": v, ...} or a sidecar {"coefficients": {...}}, checked against the model
        from casep.model.loader import load_model
        truth = read_truth(args.truth, load_model(args.model or get_scenario(args.scenario).model))
    strapdown = get_scenario(args.scenario).strapdown  # its tracking: the flight's own, at the flight's rate
    if args.tracking_frame != "launch" and not strapdown:
        if args.imu_output is not None:
            raise ValueError(f"--imu-output needs a strapdown scenario (strapdown-boost); `{args.scenario}` is not")
        return _earth_fixed(args, site, truth, scenario)
    from casep.simulation.simulate import simulate_flight, write_simulation

    sim = simulate_flight(scenario, seed=args.seed, rate=args.rate, model=args.model, truth=truth,
                          time_offset=args.tracking_offset * 1e-3, lever_arm=args.lever_arm,  # ms -> s
                          tracking_rate=args.tracking_rate,  # every k-th sample tracked
                          **({"rotating_earth": True, "site": site} if site is not None else {}))
    imu = {"imu": args.imu_output, "imu_pad": args.imu_pad, "imu_sensor": sensor}
    flight_path, side = write_simulation(sim, out, **imu) if args.tracking_frame == "launch" else \
        write_strapdown_earth_fixed(sim, out, files["--tracking-output"], frame=args.tracking_frame, **imu)
    s = sim.trajectory.summary()
    print(f"scenario {sim.scenario.name}: {sim.flight.n_samples} samples at {sim.scenario.rate:g} Hz, "
          f"{s['duration_s']:.1f} s powered flight")
    print(f"lift-off {s['liftoff_specific_force_g']:.2f} g, max {s['max_specific_force_g']:.2f} g; burnout "
          f"{s['burnout_speed_m_s'] / 1e3:.2f} km/s at {s['burnout_altitude_m'] / 1e3:.0f} km, "
          f"flight-path angle {s['burnout_flight_path_deg']:.1f} deg")
    print(f"wrote {flight_path}{'' if args.imu_output is None else ', ' + str(args.imu_output)}"
          f"{'' if args.tracking_frame == 'launch' else ', ' + str(files['--tracking-output'])} and {side}")
    if args.imu_output is not None and site is None:
        print("note: the raw IMU is of a non-rotating Earth (no Earth rate, spherical gravity), which `casep navigate` "
              "does not assume: for a record it navigates, add --rotating-earth --launch-site")
    return 0


def _earth_fixed(args: argparse.Namespace, site: Any, truth: Any, scenario: Any) -> int:
    """`--rotating-earth --tracking-frame ecef|geodetic`: telemetry, tracking and truth files."""
    from casep.simulation.earth_fixed import write_earth_fixed_flight

    ef = write_earth_fixed_flight(args.output, site, frame=args.tracking_frame, tracking=args.tracking_output,
                                  scenario=scenario, seed=args.seed, telemetry_rate=args.rate,
                                  time_offset_ms=args.tracking_offset, model=args.model, truth=truth,
                                  **({} if args.tracking_rate is None else {"tracking_rate": args.tracking_rate}))
    d = ef.data
    print(f"scenario {ef.scenario.name}, rotating Earth at ({site.lat_deg:g} deg, {site.lon_deg:g} deg, "
          f"{site.h_m:g} m), azimuth {site.azimuth_deg:g} deg: telemetry {d.t_tel.size} samples, tracking "
          f"({args.tracking_frame}) {d.t_trk.size} samples at {ef.truth_record['tracking']['rate_hz']:g} Hz")
    print(f"wrote {ef.telemetry}, {ef.tracking} and {ef.truth}; read back with: casep separate {ef.telemetry} "
          f"--tracking {ef.tracking} --tracking-frame {args.tracking_frame} --launch-site "
          f"{' '.join(f'{v:g}' for v in args.launch_site)} --launch-time 0")
    return 0

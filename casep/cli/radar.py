"""Radar stations and their errors: ``separate``/``diagnose`` with ``--radar``; ``simulate --radar-station``."""

from __future__ import annotations

import argparse
from typing import Any

from casep._version import __version__
from casep.cli import inputs, options, outputs
from casep.cli.types import positive_float

__all__ = ["separate_radar", "diagnose_radar", "add_simulate_radar", "simulate_radar", "radar_only"]


def _site(args: argparse.Namespace) -> Any:
    if len(args.flight) != 1:
        raise ValueError(f"--radar takes one telemetry file, got {len(args.flight)}")
    if args.tracking or args.tracking_frame != "launch":
        raise ValueError("--radar replaces --tracking/--tracking-frame: give the radar stations only")
    if args.launch_site is None or args.launch_time is None:
        raise ValueError("--radar needs --launch-site LAT LON H AZ and --launch-time T0 (the launch time in the radar "
                         "files' time scale): they tie the telemetry's launch-inertial frame to the stations")
    return inputs.launch_site(args.launch_site, args.launch_time)


def _radar_files(args: argparse.Namespace) -> list[Any]:
    return inputs.input_files(args, "flight") + [f for pair in args.radar for f in pair]


def separate_radar(args: argparse.Namespace, wavelet_options: dict) -> int:
    """`casep separate TEL --radar S1.json S1.csv ...`: instrument and station errors in one estimate."""
    from casep.io.files import read_json_table
    from casep.workflows.radar import check_radar_options, separate_radar

    # the options of separate() that do not apply with radar: one list (casep.workflows.radar.NOT_WITH_RADAR)
    check_radar_options({"wavelet_options": wavelet_options, **{k: getattr(args, k) for k in (
        "denoise", "outliers", "sigma", "std", "exclude_outliers")}}, cli=True,
        outputs={"--figures": args.figures, "--mat": args.mat, "--csv": args.csv})
    outputs.check({"--json": args.json, "--report": args.report}, _radar_files(args))
    site = _site(args)
    given = options.method_options(args)
    given.update({k: read_json_table(given[k], f"--{k}") for k in ("bounds", "prior") if k in given})
    spec = options.fit_spec(args, given)  # the one check of the request: method, options, --noise, --tau, --robust
    rr = separate_radar(args.flight[0], args.radar, site, args.model, args.tracking_model, spec=spec)
    print(rr.text())
    if args.json:
        outputs.write_json(rr.to_dict(), args.json)
        print(f"result written to {args.json}")
    if args.report:
        from casep.reporting.radar import write_radar_report

        print(f"report written to {write_radar_report(rr, args.report, source=args.flight[0])}")
    return outputs.status(rr.result)


def diagnose_radar(args: argparse.Namespace) -> int:
    """`casep diagnose TEL --radar ...`: CRLB with the tracking terms fixed and free, mixed groups, station gains."""
    from casep.radar.diagnostics import diagnostics_table
    from casep.workflows.radar import diagnose_radar

    outputs.check({"--json": args.json}, _radar_files(args))
    d = diagnose_radar(args.flight[0], args.radar, _site(args), args.model, args.tracking_model)
    print(diagnostics_table(d))
    if args.json:
        outputs.write_json({"casep_version": __version__, "model": args.model, "radar_diagnostics": d}, args.json)
        print(f"diagnostics written to {args.json}")
    return 0


def add_simulate_radar(parser: Any) -> None:
    """`simulate`: radar measurements of stations instead of a tracking file."""
    parser.add_argument("--radar-station", metavar="STATION.json", action="append", default=None,
                        help="with --rotating-earth: write radar measurements of this station (repeat per station): "
                             "-o is then the telemetry (t, f_*, v_tel_*, r_tel_*), each station <stem>.<name>.json "
                             "and <stem>.<name>.csv beside it")
    parser.add_argument("--tracking-truth", metavar="FILE", default=None,
                        help='with --radar-station: JSON {"S1": {"range_bias": 5, ...}, ...}, the tracking model\'s '
                             "units (m, ppm, arcsec, ms); default none")
    parser.add_argument("--radar-rate", type=positive_float, default=20.0, metavar="HZ",
                        help="with --radar-station: measurement rate (default 20)")
    parser.add_argument("--range-noise", type=float, default=3.0, metavar="M", help="range noise std (default 3 m)")
    parser.add_argument("--angle-noise", type=float, default=8.0, metavar="ARCSEC",
                        help="azimuth and elevation noise std (default 8 arcsec)")
    parser.add_argument("--radar-range-rate", action="store_true", help="also write range_rate (noise 0.05 m/s)")


def simulate_radar(args: argparse.Namespace, site: Any) -> int:
    """`casep simulate -o TEL.csv --rotating-earth --launch-site ... --radar-station S1.json ...`."""
    from casep.io.files import read_json_table
    from casep.radar.stations import read_station
    from casep.workflows.radar import radar_simulation_outputs, simulate_radar_files

    if site is None:
        raise ValueError("--radar-station needs --rotating-earth --launch-site LAT LON H AZ (the stations are on the "
                         "Earth)")
    if args.tracking_frame != "launch" or args.lever_arm is not None or args.tracking_offset:
        raise ValueError("--radar-station writes radar files: leave out --tracking-frame, --lever-arm and "
                         "--tracking-offset (a radar time-tag error is the tracking model's time_bias)")
    stations = [read_station(p) for p in args.radar_station]
    outputs.check(radar_simulation_outputs(args.output, stations),
                  inputs.input_files(args, "truth", "tracking_truth", "radar_station"))
    sim, files = simulate_radar_files(
        args.output, stations, site, truth=read_json_table(args.truth, "--truth") if args.truth else None,
        tracking_truth=read_json_table(args.tracking_truth, "--tracking-truth") if args.tracking_truth else None,
        scenario=args.scenario, seed=args.seed, telemetry_rate=args.rate or 100.0, radar_rate=args.radar_rate,
        model=args.model, noise={"range": args.range_noise, "azimuth": args.angle_noise, "elevation": args.angle_noise},
        range_rate=args.radar_range_rate)
    noise = "; ".join(f"{k} range {v['range']:g} m, angles {v['azimuth']:g} arcsec"
                      for k, v in sim.station_noise.items())
    print(f"scenario {sim.scenario}: telemetry {sim.telemetry.t.size} samples, "
          + ", ".join(f"{m.station.name} {m.t.size} samples" for m in sim.radars)
          + f" at {args.radar_rate:g} Hz (noise: {noise})")
    for name in sim.masked:
        if sim.masked[name] or sim.over_zenith[name]:
            print(f"station {name}: {sim.masked[name]} samples below its elevation mask dropped, "
                  f"{sim.over_zenith[name]} written over the top of the zenith (azimuth + 180, 180 - elevation)")
    print("wrote " + ", ".join(str(f) for f in files))
    radar = " ".join(f"--radar {files[1 + 2 * i]} {files[2 + 2 * i]}" for i in range(len(sim.radars)))
    print(f"separate with: casep separate {args.output} {radar} --launch-site "
          f"{' '.join(f'{v:g}' for v in args.launch_site)} --launch-time 0")
    return 0


_RADAR_DEFAULTS = {"tracking_model": "radar_biases", "tracking_truth": None, "radar_rate": 20.0, "range_noise": 3.0,
                   "angle_noise": 8.0, "radar_range_rate": False}


def radar_only(args: argparse.Namespace, names: tuple[str, ...]) -> None:
    """Radar options given without radar inputs are an error, not ignored."""
    for n in names:
        if getattr(args, n) != _RADAR_DEFAULTS[n]:
            need = "--radar-station" if args.command == "simulate" else "--radar"
            raise ValueError(f"--{n.replace('_', '-')} is used only with {need}")

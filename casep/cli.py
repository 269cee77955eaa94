"""Command line: ``casep separate``, ``casep diagnose``, ``casep simulate``, ``casep models``.
Thin wrappers over the public API.

The method options of ``casep separate`` (and ``--prior``/``--bounds`` of ``casep montecarlo``)
are generated from the estimator registry (:data:`casep.estimators.registry.OPTIONS`): one
argument group per set of methods, flag, help, default and rule from the table, the rule's
:meth:`~casep.estimators.registry.Option.parse` as the argparse type. Module level imports only
the standard library, the version and the registry; each command imports what it needs.

Exit status: 0 success, 2 bad usage or bad input (one line on stderr), 1 anything else, including
a `separate` result that is not successful (``success`` false: table and JSON still written);
141 (quietly, like any Unix tool ended by SIGPIPE) when the reader of stdout closes early
(``casep models | head -1``). ``casep models`` exits 0 when at least one model loads and
reports each model file that does not as a ``warning:`` line.
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import os
import sys
import warnings
from pathlib import Path
from typing import Sequence

from casep._version import __version__
from casep.estimators.registry import METHODS, OPTIONS, CoefficientTable, Interval, Option, check_method_options
from casep.exceptions import CasepWarning, IllConditionedWarning

# Only the standard library, the version and the registry (light: numpy) are imported here, so
# that building the parser and `casep --help` stay cheap; each command imports what it needs.

__all__ = ["main", "build_parser"]


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line, exit 2
        self.exit(2, f"{self.prog}: error: {message}\n")

    def parse_known_args(self, args=None, namespace=None):
        self._refuse_repeated(sys.argv[1:] if args is None else list(args))
        return super().parse_known_args(args, namespace)

    def _refuse_repeated(self, argv: list[str]) -> None:
        """An option that takes one value (``--launch-site``, ``--model``) given twice is an error: argparse
        would keep the last silently. Options that collect (``--tracking``, once per flight) may repeat.
        Only this parser's own options count (a subcommand's parser checks its own, when argparse hands
        it the rest of the line)."""
        seen: dict[int, str] = {}
        for token in argv:
            if token == "--":
                break
            action = self._option_string_actions.get(token.split("=", 1)[0]) if token.startswith("-") else None
            if action is None or isinstance(action, (argparse._AppendAction, argparse._CountAction,
                                                     argparse._HelpAction, argparse._VersionAction)):
                continue
            if id(action) in seen:
                self.error(f"{token.split('=', 1)[0]} given twice: it takes one value (argparse would keep the last "
                           "silently); flights with their own set-up go in a manifest (--manifest FLIGHTS.toml)")
            seen[id(action)] = token


def _positive_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not v > 0 or v == float("inf"):
        raise argparse.ArgumentTypeError(f"must be finite and > 0, got {text}")
    return v


def _rate(text: str) -> float:
    """A sample rate, Hz: (0, casep.simulation.scenarios.MAX_RATE_HZ]."""
    from casep.simulation.scenarios import check_rate

    v = _positive_float(text)
    try:
        return check_rate(v, "rate")
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc).removeprefix("rate ")) from None


def _ranged(name: str):
    """Argparse type for the common option `name` (``sigma``) of :data:`casep.estimators._base.OPTION_RANGES`:
    the API's check and message."""

    def parse(text: str) -> float:
        from casep.estimators._base import check_positive

        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
        try:
            return check_positive(name, v, allow_none=False)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None

    parse.__name__ = name
    return parse


def _order(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if v < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {text}")
    return v


def _rule_type(option: Option, rules=None):
    """Argparse type of a registry option: :meth:`Option.parse`, so a bad value is an error stating the rule.

    `rules` restricts the option to some of its rules (``diagnose --tau`` takes a number only).
    """
    opt = option if rules is None else Option(option.name, option.flag, option.default, rules, option.help)

    def parse(text: str):
        try:
            return opt.parse(text)
        except ValueError as exc:  # "--p0 must be ...": argparse names the argument already
            raise argparse.ArgumentTypeError(str(exc).removeprefix(f"{opt.flag} ")) from None

    parse.__name__ = option.name  # argparse names the type in some messages
    return parse


def _metavar(option: Option) -> str:
    """``gcv|lcurve|VALUE``, ``INT``, ``FILE``: what the rules take, for the usage line."""
    words = []
    for r in option.rules:
        if isinstance(r, CoefficientTable):
            words.append("FILE")
        elif isinstance(r, Interval):
            words.append("INT" if r.kind is int else "VALUE")
        else:
            words.extend(getattr(r, "values", ()))
    return "|".join(words)


def _option_help(option: Option, default: str | None = None) -> str:
    """Help of a registry option: its help, rule and default (or "required")."""
    required = [m for m, meth in METHODS.items() if option.name in meth.required]
    d = option.default
    if default is None and (d is not None or required):
        default = "required" if d is None else f"default {d:g}" if isinstance(d, float) else f"default {d}"
    return f"{option.help}; {option.rule}" + (f" ({default})" if default else "")


def _method_option_groups(parser: argparse.ArgumentParser) -> None:
    """One argument group per set of methods taking the same options, generated from the registry.

    Options shared by several methods (RLS and RELS) are in one group titled by all of them
    (``rls / rels options``); flag, help, default and rule come from
    :data:`casep.estimators.registry.OPTIONS`; the argparse type is :meth:`Option.parse`.
    """
    groups: dict[tuple[str, ...], list[str]] = {}
    for name in OPTIONS:
        takers = tuple(m for m, meth in METHODS.items() if name in meth.options)
        groups.setdefault(takers, []).append(name)
    for takers, names in groups.items():
        g = parser.add_argument_group(f"{' / '.join(takers) or 'unused'} options")
        for name in names:
            _add_option(g, OPTIONS[name])


def _add_option(group, option: Option, default: str | None = None) -> None:
    """The argument of a registry option (dest: its name; None when not given)."""
    group.add_argument(option.flag, dest=option.name, type=_rule_type(option), default=None,
                       metavar=_metavar(option), help=_option_help(option, default))


def _add_noise(parser, *, outputs: bool = True, default: str = "auto") -> None:
    """The noise-model options every method takes (casep.analysis.noise, casep.workflows.solve)."""
    g = parser.add_argument_group("noise model (every method)")
    g.add_argument("--noise", choices=("auto", "gm", "white"), default=default,
                   help=f"tracking noise (default {default}): auto (white or Gauss-Markov per axis by a "
                        "likelihood-ratio test, said in the output), gm (Gauss-Markov per axis, --tau or REML), white "
                        "(with separate, a whiteness test warns when the residuals contradict it)")
    g.add_argument("--robust", nargs="?", const="huber", choices=("auto", "huber", "bisquare", "none"),
                   default="auto",
                   help="robust fit for any method: glitches removed by a robust filter on the innovations, the rest "
                        "weighted; --robust alone: huber; auto (default): huber when the filter finds more glitches "
                        "than Gaussian noise explains (said in the output); none: never")
    if outputs:
        g.add_argument("--std", choices=("model", "hac"), default="model",
                       help="model (default) or hac: Newey-West std of a white-noise ols fit")
        g.add_argument("--exclude-outliers", type=float, nargs="?", const=0.01, default=None, metavar="ALPHA",
                       help="remove the samples whose studentized residual (whitened rows) is flagged at "
                            "family-wise chance ALPHA (default 0.01) and fit again; removed samples listed")


def _noise_kw(args: argparse.Namespace, opts: dict) -> dict:
    """separate()'s noise keywords from the options (--tau: the noise model's for every method)."""
    kw = {"noise": args.noise, "robust": args.robust}
    for k in ("std", "exclude_outliers"):
        if getattr(args, k, None) is not None:
            kw[k] = getattr(args, k)
    if args.method != "gls" and opts.get("tau") is not None:
        kw["tau"] = opts.pop("tau")
    return kw


def _noise_line(nd: dict) -> str:
    """One line of a result's ``diagnostics["noise"]``."""
    from casep.analysis.noise import NoiseModel

    axes = nd["axes"]
    if "note" in nd:
        return f"noise: {nd['note']}, tau {axes['x']['tau_s']:.3g} s ({nd['rule']})"
    nm = NoiseModel(kind=nd["kind"], tau=tuple(axes[a]["tau_s"] for a in "xyz"),
                    scale=tuple(axes[a]["scale"] for a in "xyz"), rule=nd["rule"],
                    lr=tuple(axes[a]["lr"] for a in "xyz") if "lr" in axes["x"] else None,
                    lr_scale=nd.get("lr_scale"), sigma=axes["x"].get("std_m_s"))
    return nm.line()


def _robust_line(rb: dict) -> str:
    """One line of a result's ``diagnostics["robust"]``."""
    places = ", ".join(r["where"] for r in rb.get("rejected", [])[:6])
    auto = rb.get("automatic")
    why = (f", automatic: the filter found {auto['glitches_found']} glitch(es) where Gaussian noise gives "
           f"{auto['expected_from_noise']:.2g}" if auto else "")
    more = ", ..." if rb["rejected_count"] > 6 else ""
    return (f"robust ({rb['function']}{why}): {rb['rejected_count']} sample(s) rejected as glitches"
            + (f": {places}{more}" if places else "")
            + f", {rb['downweighted']} row(s) down-weighted, {rb['iterations']} iteration(s)")


def _print_noise(res, joint: bool = False) -> None:
    """The noise model, the robust fit, the removed samples and the gaps, one line each (per flight)."""
    nd = res.diagnostics.get("noise")
    if joint:
        for label, d in (nd or {}).items():
            print(f"{label}: {_noise_line(d)}")
            if d.get("robust"):
                print(f"{label}: {_robust_line(d['robust'])}")
        return
    if nd:
        print(_noise_line(nd))
    rb = res.diagnostics.get("robust")
    if rb:
        print(_robust_line(rb))
    ex = res.diagnostics.get("excluded")
    if ex:
        places = ", ".join(f"{r['where']} {r['axis']}" for r in ex["samples"][:6])
        print(f"excluded: {ex['count']} sample(s) flagged at alpha {ex['alpha']:g} removed and the fit repeated"
              + (f": {places}{', ...' if ex['count'] > 6 else ''}" if places else ""))
    gaps = res.diagnostics.get("gaps")
    if gaps:
        parts = ", ".join(f"{g['length']:.3g} s before {g['where']}" for g in gaps[:6])
        print(f"tracking gaps: {len(gaps)} longer than 3 sample periods: {parts}{', ...' if len(gaps) > 6 else ''}")


def _read(args: argparse.Namespace):
    """The flight of a command: one file, telemetry + `--tracking`, or the one flight of `--manifest`."""
    from casep.io.files import read_flight, read_flight_pair

    man = getattr(args, "manifest_obj", None)
    if man is not None:
        if len(man.flights) != 1:
            raise ValueError(f"--manifest {man.source} lists {len(man.flights)} flights; this command reads one")
        return man.flights[0].read()
    tracking = args.tracking or []
    if len(tracking) > 1:
        raise ValueError(f"--tracking given {len(tracking)} times for one flight; give it once per flight")
    frames = _frame_options(args)  # --tracking-frame, --launch-site, --launch-time
    return (read_flight_pair(args.flight, tracking[0], grid=args.grid, time_offset=args.time_offset,
                             time_shift=getattr(args, "time_shift", 0.0), **frames)
            if tracking else read_flight(args.flight))


def _manifest(args: argparse.Namespace):
    """`--manifest FLIGHTS.toml` read (kept as ``args.manifest_obj``; ``args.flight`` its telemetry files), or None.

    The manifest holds each flight's files and set-up: the single-flight options are an error with it, and
    without it a flight file is needed."""
    path = getattr(args, "manifest", None)
    flights = args.flight if isinstance(args.flight, list) else [args.flight] if args.flight else []
    if not path:
        if not flights:
            raise ValueError("give a flight file, or --manifest FLIGHTS.toml")
        return None
    given = [flag for flag, on in (
        ("the flight files", flights), ("--tracking", args.tracking),
        ("--tracking-frame", getattr(args, "tracking_frame", "launch") != "launch"),
        ("--launch-site", getattr(args, "launch_site", None) is not None),
        ("--launch-time", getattr(args, "launch_time", None) is not None),
        ("--time-shift", getattr(args, "time_shift", 0.0) != 0.0),
        ("--time-offset", getattr(args, "time_offset", None) is not None),
        ("--grid", getattr(args, "grid", "tracking") != "tracking")) if on]
    if given:
        raise ValueError(f"--manifest {path} lists the flights with their files and set-up: leave out "
                         f"{', '.join(given)} (they describe one flight given on the command line)")
    from casep.io.manifest import read_manifest

    man = read_manifest(path)
    args.manifest_obj = man
    telemetry = [str(f.telemetry) for f in man.flights]
    args.flight = telemetry if isinstance(args.flight, list) else telemetry[0]
    return man


def _add_grid(parser, manifest: bool = True) -> None:
    parser.add_argument("--grid", choices=("tracking", "telemetry"), default="tracking",
                        help="with --tracking: form dv at the tracking times (default: one row per tracking "
                             "sample, white noise, honest std) or at the telemetry times (tracking interpolated: "
                             "std too small by about sqrt(f_tel / f_trk))")
    parser.add_argument("--time-offset", type=_time_offset, default=None, metavar="auto|MS",
                        help="with --tracking: tracking time tags late by MS milliseconds, shifted back; 'auto': the "
                             "offset that lines up the velocity increments (then fit dt_trk for the rest); default: "
                             "none, with a warning when that offset exceeds a tracking sample period")
    parser.add_argument("--time-shift", type=_finite_float, default=0.0, metavar="SECONDS",
                        help="with --tracking: how the time scales relate, tracking time minus telemetry time "
                             "(tracking in seconds of day, telemetry from lift-off at 12:00:00: 43200); default 0 "
                             "(one scale)")
    if manifest:  # impact has its own (a manifest of one flight, with its result)
        parser.add_argument("--manifest", metavar="FLIGHTS.toml", default=None,
                            help="TOML manifest listing each flight's telemetry, tracking, frame, site, launch time "
                                 "and time shift (docs/guide/range-data.md), instead of the flight files and these "
                                 "options")


def _finite_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"must be finite, got {text}")
    return v


def _positive_int(text: str) -> int:
    v = _order(text)
    if v < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1, got {text}")
    return v


def _time_offset(text: str):
    """`--time-offset`: 'auto', or milliseconds -> seconds."""
    if text == "auto":
        return "auto"
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be 'auto' or milliseconds, got {text!r}") from None
    if not math.isfinite(v) or abs(v) > 1e5:
        raise argparse.ArgumentTypeError(f"must be a finite number of milliseconds within +-1e5, got {text!r}")
    return v * 1e-3  # ms -> s


# ---------------------------------------------------------------- tracking frames
_FRAMES = ("launch", "ecef", "geodetic")


def _add_frames(parser) -> None:
    """`separate` / `diagnose`: the tracking file's frame and the launch site tying it to the platform frame."""
    parser.add_argument("--tracking-frame", choices=_FRAMES, default="launch",
                        help="with --tracking: frame of the tracking file: launch (t, v_trk_*, launch-inertial; "
                             "default), ecef (t, r_ecef_*, v_ecef_*, WGS84, m, m/s) or geodetic (t, lat, lon, h, "
                             "v_east, v_north, v_up; deg, deg, m, m/s); ecef and geodetic need --launch-site and "
                             "--launch-time")
    parser.add_argument("--launch-site", type=float, nargs=4, default=None, metavar=("LAT", "LON", "H", "AZ"),
                        help="launch point (geodetic latitude, longitude, deg; height above the WGS84 ellipsoid, m) "
                             "and azimuth of the platform x axis (deg from north, clockwise)")
    parser.add_argument("--launch-time", type=float, default=None, metavar="T0",
                        help="launch time in the tracking file's time scale, s (the launch-inertial frame is the "
                             "Earth-fixed launch triad at T0)")


def _frame_options(args: argparse.Namespace) -> dict:
    """read_flight_pair's `tracking_frame` and `site` from the command line (a missing site: the reader's error,
    which names the tracking file)."""
    # getattr: a command whose parser has no frame options (_add_frames) reads launch-frame tracking, as before
    frame = getattr(args, "tracking_frame", "launch")
    lsite, t0 = getattr(args, "launch_site", None), getattr(args, "launch_time", None)
    if frame == "launch":
        if lsite is not None or t0 is not None:
            raise ValueError("--launch-site and --launch-time are used only with --tracking-frame ecef or geodetic")
        return {}
    if not getattr(args, "tracking", None):
        raise ValueError(f"--tracking-frame {frame} describes a tracking file: give it with --tracking FILE")
    if (lsite is None) != (t0 is None):
        raise ValueError(f"--tracking-frame {frame} needs both --launch-site LAT LON H AZ and --launch-time T0, "
                         f"got only {'--launch-site' if t0 is None else '--launch-time'}")
    from casep.frames import LaunchSite

    return {"tracking_frame": frame, "site": None if lsite is None else LaunchSite(*lsite, t0)}


def _add_simulate_frames(parser) -> None:
    parser.add_argument("--rotating-earth", action="store_true",
                        help="Earth turning at 7.292115e-5 rad/s (needs --launch-site): the vehicle starts with the "
                             "pad's velocity, drag relative to the co-rotating air; the flight stays launch-inertial")
    parser.add_argument("--launch-site", type=float, nargs=4, default=None, metavar=("LAT", "LON", "H", "AZ"),
                        help="with --rotating-earth: launch point (deg, deg, m above WGS84) and azimuth of x (deg from "
                             "north, clockwise); lift-off is t = 0 (read back with --launch-time 0)")
    parser.add_argument("--tracking-frame", choices=_FRAMES, default="launch",
                        help="with --rotating-earth: ecef or geodetic writes two files, the telemetry (-o: t, f_*, "
                             "v_tel_*, a_*) and the tracking in that frame (--tracking-output); default launch: the "
                             "one-file flight")
    parser.add_argument("--tracking-rate", type=_rate, default=20.0, metavar="HZ",
                        help="with --tracking-frame ecef|geodetic: tracking sample rate (default 20)")
    parser.add_argument("--tracking-output", metavar="FILE", default=None,
                        help="with --tracking-frame ecef|geodetic: tracking file (default <stem>.tracking<suffix>)")


def _simulate_site(args: argparse.Namespace):
    """The LaunchSite of `casep simulate` (t0 = 0: lift-off), or None without --rotating-earth."""
    if not args.rotating_earth:
        if args.launch_site is not None or args.tracking_frame != "launch":
            raise ValueError("--launch-site and --tracking-frame ecef|geodetic need --rotating-earth")
        return None
    if args.launch_site is None:
        raise ValueError("--rotating-earth needs --launch-site LAT LON H AZ (deg, deg, m, deg from north)")
    from casep.frames import LaunchSite

    return LaunchSite(*args.launch_site, 0.0)


def _simulate_earth_fixed(args: argparse.Namespace, site, truth) -> int:
    """`casep simulate --rotating-earth --tracking-frame ecef|geodetic`: telemetry, tracking and truth files."""
    import dataclasses

    from casep.estimators.result import write_json_atomic
    from casep.io._atomic import check_outputs
    from casep.simulation.scenarios import get_scenario
    from casep.simulation.simulate import simulate_two_rate, truth_path

    out = Path(args.output)
    trk = Path(args.tracking_output) if args.tracking_output else out.with_name(f"{out.stem}.tracking{out.suffix}")
    check_outputs({"-o": out, "--tracking-output": trk, "-o (truth sidecar)": truth_path(out)},
                  inputs=_inputs(args, "truth"))
    if args.lever_arm is not None:
        raise ValueError("--lever-arm is not available with --tracking-frame ecef|geodetic yet; leave it out")
    sc = get_scenario(args.scenario)
    if args.model is not None or truth is not None:
        sc = dataclasses.replace(sc, model=args.model or sc.model, truth=sc.truth if truth is None else dict(truth))
    d = simulate_two_rate(sc, seed=args.seed, telemetry_rate=args.rate or sc.rate,
                          tracking_rate=args.tracking_rate, time_offset=args.tracking_offset * 1e-3,
                          rotating_earth=True, site=site)
    d.write(out, trk, tracking_frame=args.tracking_frame)
    write_json_atomic({"model": d.model.name, "coefficients": {n: float(v) for n, v in zip(d.model.names, d.truth)},
                       "units": dict(zip(d.model.names, d.model.units)), "noise": sc.noise.to_dict(),
                       "trajectory": {"scenario": sc.name, "description": sc.description,
                                      "rate_hz": args.rate or sc.rate, "vehicle": sc.vehicle.to_dict()},
                       "seed": args.seed,
                       "tracking": {"time_offset_ms": args.tracking_offset, "lever_arm_m": [0.0, 0.0, 0.0],
                                    "rotating_earth": True, "frame": args.tracking_frame, "file": str(trk),
                                    "rate_hz": args.tracking_rate, "launch_site": site.to_dict()}},
                      truth_path(out))
    print(f"scenario {sc.name}, rotating Earth at ({site.lat_deg:g} deg, {site.lon_deg:g} deg, {site.h_m:g} m), "
          f"azimuth {site.azimuth_deg:g} deg: telemetry {d.t_tel.size} samples, tracking ({args.tracking_frame}) "
          f"{d.t_trk.size} samples at {args.tracking_rate:g} Hz")
    print(f"wrote {out}, {trk} and {truth_path(out)}; read back with: casep separate {out} --tracking {trk} "
          f"--tracking-frame {args.tracking_frame} --launch-site {' '.join(f'{v:g}' for v in args.launch_site)} "
          "--launch-time 0")
    return 0
# ---------------------------------------------------------------- end tracking frames


def _read_flights(args: argparse.Namespace) -> list:
    """Several flights, each a file or (with `--tracking` once per flight, in flight order) a pair."""
    from casep.io.files import read_flight, read_flight_pair

    if getattr(args, "manifest_obj", None) is not None:
        return args.manifest_obj.read()  # each flight with its own frame, site, launch time and time shift
    tracking = args.tracking or []
    if tracking and len(tracking) != len(args.flight):
        raise ValueError(f"--tracking given {len(tracking)} times for {len(args.flight)} flights: give it once per "
                         "flight, in the order of the flights (telemetry A --tracking TA, B --tracking TB)")
    frames = _frame_options(args)  # --tracking-frame, --launch-site, --launch-time: the same for every flight
    if tracking:
        return [read_flight_pair(f, t, grid=args.grid, time_offset=args.time_offset,
                                 time_shift=getattr(args, "time_shift", 0.0), **frames)
                for f, t in zip(args.flight, tracking)]
    return [read_flight(f) for f in args.flight]


def _coefficient_file(args: argparse.Namespace, option: str, names) -> dict | None:
    """The `--bounds` or `--prior` file, loaded and checked against the model's coefficients."""
    from casep.estimators.bounded import parse_bounds
    from casep.estimators.map import parse_prior
    from casep.io.files import read_json_table

    path = getattr(args, option)
    if not path:
        return None
    data = read_json_table(path, f"--{option}")
    from casep.io.result_json import looks_like_result

    if option == "prior" and "calibration" in data:  # a ground calibration: the flight model's coefficients
        from casep.calibration.consistency import ground_prior

        data = ground_prior(data, getattr(args, "model", None) or "platform36")
    elif option == "prior" and looks_like_result(data):  # a result file (any form): its posterior
        from casep.estimators.map import prior_from_result
        from casep.estimators.result import read_result

        model = getattr(args, "model", None)
        res, model = read_result(path, model, option="--prior")
        _refuse_failed(res, f"--prior {path}")
        data = prior_from_result(res, model=model)  # per-flight coefficients (dt_trk) left flat
    {"bounds": parse_bounds, "prior": parse_prior}[option](data, names, source=f"--{option} {path}")
    return data


def build_parser() -> argparse.ArgumentParser:
    """The ``casep`` argument parser, with every command and option.

    Returns
    -------
    argparse.ArgumentParser
        A new parser; the documentation's command-line reference is generated from it.
    """
    return _parser()


def _parser() -> argparse.ArgumentParser:
    from casep.analysis.denoise import EXTENSIONS, MODES, RULES, SCALINGS
    from casep.simulation.scenarios import SCENARIOS

    p = _Parser(prog="casep", description="Guidance instrumentation error separation.")
    p.add_argument("--version", action="version", version=f"casep {__version__}")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)
    s = sub.add_parser("separate", help="estimate the error coefficients of a flight file")
    s.add_argument("flight", nargs="*", help="flight CSV or Parquet file (t, f_x.., dv_x.. or v_tel_x.., v_trk_x..); "
                   "several files: one estimate of the shared coefficients, per-flight ones per flight "
                   "(methods ols, ridge, bounded, pcr, map)")
    s.add_argument("--model", default="platform36", help="model name or .py file (default platform36)")
    s.add_argument("--method", default="ols", choices=METHODS, help="estimator (default ols)")
    s.add_argument("--sigma", type=_ranged("sigma"), default=None,
                   help="noise std, m/s (default: estimated from the residuals)")
    s.add_argument("--denoise", choices=("none", "wavelet"), default="none", help="de-noise dv first (default none)")
    s.add_argument("--wavelet", default=None, help="wavelet (default sym8)")
    s.add_argument("--level", type=_order, default=None, help="decomposition level (default: largest "
                   "without boundary domination)")
    s.add_argument("--threshold-rule", choices=RULES, default=None, help="threshold rule (default sqtwolog)")
    s.add_argument("--threshold-mode", choices=MODES, default=None, help="threshold mode (default soft)")
    s.add_argument("--extension", choices=tuple(EXTENSIONS), default=None,
                   help="boundary extension (default symmetric)")
    s.add_argument("--noise-scaling", choices=SCALINGS, default=None, help="noise scaling (default sln)")
    s.add_argument("--json", metavar="OUT", default=None, help="write the result JSON here")
    s.add_argument("--mat", metavar="OUT", default=None,
                   help="write the result as a MATLAB/Octave .mat file (names, estimates, std, covariance, ...)")
    s.add_argument("--csv", metavar="OUT", default=None,
                   help="write one row per coefficient here (name, unit, estimate, std, reason)")
    s.add_argument("--figures", metavar="DIR", default=None,
                   help="write residuals, estimates (and RLS/RELS history) PNG figures into DIR (created)")
    s.add_argument("--outliers", type=float, nargs="?", const=0.01, default=None, metavar="ALPHA",
                   help="flag rows by their studentized least-squares residual, with chance ALPHA (default 0.01) of "
                        "any false flag in a clean flight (white noise); rows named, in the JSON diagnostics")
    s.add_argument("--report", metavar="FILE", default=None,
                   help="write a self-contained HTML report (table, settings, diagnostics, figures) here")
    s.add_argument("--tracking", metavar="FILE", default=None, action="append",
                   help="tracking file (t, v_trk_*) at its own rate; FLIGHT is then the telemetry file "
                        "(t, f_* or W_*, v_tel_*); several flights: once per flight, in their order")
    _add_grid(s)  # --grid, --time-offset
    _add_frames(s)  # --tracking-frame, --launch-site, --launch-time
    _add_noise(s)  # --noise, --robust, --std, --exclude-outliers
    _add_radar(s)  # --radar STATION.json MEAS.csv, --tracking-model
    _method_option_groups(s)
    g = sub.add_parser("simulate", help="simulate a boost flight with injected errors")
    g.add_argument("--scenario", default="paper", choices=list(SCENARIOS), help="scenario (default paper)")
    g.add_argument("--seed", type=int, default=0, help="noise seed (default 0)")
    g.add_argument("--rate", type=_rate, default=None, help="sample rate, Hz (default: scenario's)")
    g.add_argument("-o", "--output", required=True, metavar="FILE",
                   help="flight file (.csv, or .parquet); truth goes to <stem>.truth.json beside it")
    g.add_argument("--model", default=None, help="error model to inject, name or .py file (default: the scenario's)")
    g.add_argument("--truth", metavar="FILE", default=None,
                   help='true coefficients, JSON {"Kg0x": value, ...} natural units, or a .truth.json sidecar '
                        "(default: the scenario's; names not given are 0)")
    g.add_argument("--tracking-offset", type=float, default=0.0, metavar="MS",
                   help="tracking time tags late by MS milliseconds: v_trk(t) = v_true(t - MS) (default 0)")
    g.add_argument("--lever-arm", type=float, nargs=3, default=None, metavar=("LX", "LY", "LZ"),
                   help="tracked point from the platform, m, body frame (default 0 0 0); the flight file's "
                        "att_pitch/att_yaw/att_roll (rad) and omega_x/y/z (rad/s, body) columns describe the attitude")
    _add_simulate_frames(g)  # --rotating-earth, --launch-site, --tracking-frame, --tracking-rate, --tracking-output
    _add_simulate_radar(g)  # --radar-station, --tracking-truth, --radar-rate, noise
    d = sub.add_parser("diagnose", help="what the flight can and cannot determine")
    d.add_argument("flight", nargs="*", help="flight file; several: what each determines alone and jointly")
    d.add_argument("--tracking", metavar="FILE", default=None, action="append",
                   help="tracking file (two-file input); several flights: once per flight, in their order")
    _add_grid(d)
    _add_frames(d)
    _add_radar(d)
    d.add_argument("--model", default="platform36", help="model name or .py file (default platform36)")
    d.add_argument("--sigma", type=_ranged("sigma"), default=None, help="noise std, m/s (default: estimated)")
    d.add_argument("--tau",
                   type=_rule_type(OPTIONS["tau"], [r for r in OPTIONS["tau"].rules if isinstance(r, Interval)]),
                   default=None, metavar="SECONDS", help="Gauss-Markov correlation time, s: AR(1) bound instead of "
                   "white; " + " | ".join(str(r) for r in OPTIONS["tau"].rules if isinstance(r, Interval)))
    d.add_argument("--prior", metavar="FILE", help="prior JSON (map format, or a result JSON: its estimate and "
                   "covariance): Bayesian bound and scales")
    d.add_argument("--scales", metavar="FILE", help='JSON {"Kg0x": typical magnitude, ...} for the "weak" verdict')
    d.add_argument("--json", metavar="OUT", default=None, help="write the diagnostics JSON here")
    d.add_argument("--figures", metavar="DIR", default=None,
                   help="write singular_values.png and variance_decomposition.png here")
    nz = sub.add_parser("noise", help="Allan deviation of the residuals: white, Gauss-Markov or random-walk noise")
    nz.add_argument("flight", nargs="?", help="flight file (or telemetry file with --tracking)")
    nz.add_argument("--tracking", metavar="FILE", default=None, action="append", help="tracking file (two-file input)")
    _add_grid(nz)
    _add_frames(nz)  # --tracking-frame, --launch-site, --launch-time
    nz.add_argument("--model", default="platform36", help="model name or .py file (default platform36)")
    nz.add_argument("--json", metavar="OUT", default=None, help="write the Allan deviation and the fits here")
    nz.add_argument("--figures", metavar="DIR", default=None, help="write allan.png into DIR (created)")
    dm = sub.add_parser("demo", help="the paper's scenario end to end: Table 1, figures, report")
    dm.add_argument("--out", metavar="DIR", default="casep-demo", help="output folder (default ./casep-demo)")
    dm.add_argument("--seed", type=_order, default=1, help="noise seed (default 1)")
    dm.add_argument("--rate", type=_rate, default=100.0, help="sample rate, Hz (default 100)")
    mc = sub.add_parser("montecarlo", help="seeded Monte Carlo of the estimators against the CRLB")
    mc.add_argument("--scenario", default="paper", choices=list(SCENARIOS), help="scenario (default paper)")
    mc.add_argument("--runs", type=_order, default=100, help="noise draws (default 100)")
    mc.add_argument("--methods", default="ols,rls,rels",
                    help=f"comma-separated: {', '.join(METHODS)}, ridge:<lambda> (fixed), wavelet+<method> (de-noised "
                         "first) (default ols,rls,rels)")
    mc.add_argument("--seed", type=_order, default=0, help="root seed (default 0)")
    mc.add_argument("--rate", type=_rate, default=None, help="sample rate, Hz (default: scenario's)")
    mc.add_argument("--workers", type=_order, default=None,
                    help="Dask LocalCluster worker processes, one thread each (default: all cores; 1: runs in this "
                         "process)")
    mc.add_argument("--json", metavar="OUT", default=None, help="write the Monte Carlo JSON here")
    mc.add_argument("--csv", metavar="OUT", default=None, help="write a CSV table here")
    mc.add_argument("--figure", metavar="PNG", default=None, help="write RMS/CRLB per coefficient here")
    takers = [m for o in ("prior", "bounds") for m, meth in METHODS.items() if o in meth.options]
    mg = mc.add_argument_group(f"{' / '.join(takers)} options (other methods: the registry's defaults)")
    _add_option(mg, OPTIONS["prior"], "default: the demo ground-calibration prior")
    _add_option(mg, OPTIONS["bounds"], "default: the demo spec-sheet box")
    mc.add_argument("--progress", action=argparse.BooleanOptionalAction, default=True,
                    help="progress on stderr: a bar on a terminal, else a line with the ETA every 5 s (default on)")
    mc.add_argument("--scheduler", metavar="ADDRESS", default=None,
                    help="run on this running Dask cluster (tcp://host:8786) instead of a LocalCluster of --workers")
    mc.add_argument("--dispersions", metavar="FILE", default=None,
                    help='JSON {"thrust_scale": {"dist": "normal", "mean": 1, "std": 0.01}, "launch_azimuth_deg": '
                         '{"dist": "uniform", "low": -2, "high": 2}, ...}: each run flies its own dispersed trajectory '
                         "(names: see casep.simulation.dispersions)")
    mc.add_argument("--truth-from-prior", metavar="FILE", dest="truth_from_prior", default=None,
                    help='JSON {"Kg0x": {"mean": m, "std": s}, ...}: each run draws its true coefficients from it '
                         "(also map's prior unless --prior is given)")
    _add_noise(mc, outputs=False, default="white")
    mc.add_argument("--tau", dest="noise_tau", type=_positive_float, default=None, metavar="S",
                    help="Gauss-Markov correlation time the methods assume, s (with --noise gm; default REML)")
    mc.add_argument("--out", metavar="DIR", default=None,
                    help="write runs.parquet/ (per-run results, one part per task) and summary.json here; a rerun "
                         "with the same settings resumes")
    _own_trajectory_options(mc)
    fu = sub.add_parser("fuse", help="combine results saved earlier (JSON with covariance) into one estimate")
    fu.add_argument("results", nargs="*", metavar="RESULT.json", help="two or more results of one model")
    fu.add_argument("--manifest", metavar="FLIGHTS.toml", default=None,
                    help="fuse the results the manifest lists (each flight's `result`), instead of RESULT.json files")
    fu.add_argument("--json", metavar="OUT", default=None, help="write the fused result JSON here")
    fu.add_argument("--model", default=None, help="model name or .py file (default: the one the results name)")
    me = sub.add_parser("methods", help="list the estimators, their options and capabilities")
    me.add_argument("--json", action="store_true", help="print the registry as JSON")
    m = sub.add_parser("models", help="list the available error models")
    m.add_argument("--verbose", "-v", action="store_true", help="list each model's coefficients")
    _impact_parser(sub)
    _design_parser(sub)
    _calibrate_parser(sub)
    return p


def _manifest_results(args: argparse.Namespace) -> None:
    """`fuse --manifest`: ``args.results`` from the flights' `result` keys (the files or the manifest, not both)."""
    if not getattr(args, "manifest", None):
        if len(args.results) < 2:
            raise ValueError(f"fuse needs two or more RESULT.json files (or --manifest), got {len(args.results)}")
        return
    if args.results:
        raise ValueError(f"--manifest {args.manifest} lists the results: leave out the RESULT.json files")
    from casep.io.manifest import read_manifest

    man = read_manifest(args.manifest)
    missing = [k + 1 for k, f in enumerate(man.flights) if f.result is None]
    if missing:
        raise ValueError(f"--manifest {args.manifest}: flight(s) {', '.join(map(str, missing))} have no `result` "
                         "(the result JSON of that flight) to fuse")
    args.results = [str(f.result) for f in man.flights]


def _impact_manifest(args: argparse.Namespace) -> None:
    """`impact --manifest`: its one flight's telemetry file as FLIGHT and its `result` unless --result is given."""
    if not getattr(args, "manifest", None):
        if not args.flight or not args.result:
            raise ValueError("impact needs FLIGHT and --result RESULT.json (or --manifest FLIGHTS.toml)")
        return
    if args.flight:
        raise ValueError(f"--manifest {args.manifest} names the flight: leave out FLIGHT")
    from casep.io.manifest import read_manifest

    man = read_manifest(args.manifest)
    if len(man.flights) != 1:
        raise ValueError(f"--manifest {args.manifest} lists {len(man.flights)} flights; impact reads one")
    f = man.flights[0]
    args.flight = str(f.telemetry)
    if f.tracking is not None:  # its tracking, frame, site and clocks: read as separate reads it
        args.manifest_obj = man
    if not args.result:
        if f.result is None:
            raise ValueError(f"--manifest {args.manifest}: the flight has no `result`; give --result RESULT.json")
        args.result = str(f.result)


def _own_trajectory_options(parser) -> None:
    """`montecarlo`: one's own trajectory (a flight file) and truth instead of the scenario's."""
    parser.add_argument("--flight", metavar="FILE", default=None,
                        help="one's own trajectory: a flight file (t, f_*, dv_* or v_tel_*/v_trk_*) whose times and "
                             "specific force replace the scenario's; needs --truth")
    parser.add_argument("--truth", metavar="TRUTH.json", default=None,
                        help='with --flight: true coefficients {"Kg0x": value, ...} (natural units) or a truth file of '
                             "casep simulate (its model and noise used; else white noise of the flight's own "
                             "least-squares residual std)")


def _own_trajectory(args: argparse.Namespace) -> tuple:
    """(flight path, truth dict, model name) of --flight/--truth, or (None, None, None)."""
    flight, truth = getattr(args, "flight", None), getattr(args, "truth", None)
    if not flight and not truth:
        return None, None, None
    if not (flight and truth):
        raise ValueError("--flight and --truth go together: one's own trajectory needs its true coefficients")
    from casep.io.files import read_json_table

    data = read_json_table(truth, "--truth")
    return flight, data, data.get("model") if isinstance(data.get("model"), str) else None


def _inputs(args: argparse.Namespace, *names: str) -> list:
    """The input files a command reads (an output must be none of them)."""
    files = []
    for n in names:
        v = getattr(args, n, None)
        files += v if isinstance(v, list) else [v]
    man = getattr(args, "manifest_obj", None)
    if man is not None:  # the manifest and every file it lists
        files += [man.source] + [str(p) for f in man.flights for p in (f.telemetry, f.tracking, f.result) if p]
    model = getattr(args, "model", None)
    return files + ([model] if model and Path(model).is_file() else [])


def _cmd_separate(args: argparse.Namespace) -> int:
    from casep.estimators.result import write_json_atomic
    from casep.io._atomic import check_outputs
    from casep.model.loader import load_model
    from casep.workflows.separate import separate

    wopts = {k: v for k, v in (("wavelet", args.wavelet), ("level", args.level), ("rule", args.threshold_rule),
                                ("mode", args.threshold_mode), ("extension", args.extension),
                                ("scaling", args.noise_scaling)) if v is not None}
    if args.radar:
        return _separate_radar(args, wopts)
    _radar_only(args, ("tracking_model",))
    _manifest(args)  # --manifest FLIGHTS.toml, or the flight files
    check_outputs({"--json": args.json, "--mat": args.mat, "--csv": args.csv, "--report": args.report},
                  inputs=_inputs(args, "flight", "tracking", "bounds", "prior"), folders={"--figures": args.figures})
    model = load_model(args.model)
    # Options of the method only (casep.estimators.registry): one given for another method is an error.
    given = {k: getattr(args, k) for k in OPTIONS if getattr(args, k) is not None}  # files: their names
    nkw = _noise_kw(args, given)  # --tau: the noise model's, for every method
    check_method_options(args.method, given)
    opts = {k: v for k, v in given.items() if k not in ("bounds", "prior")}
    bounds = _coefficient_file(args, "bounds", model.names)
    prior = _coefficient_file(args, "prior", model.names)
    if wopts and args.denoise != "wavelet":
        raise ValueError(f"wavelet options ({', '.join(wopts)}) need --denoise wavelet")
    if len(args.flight) > 1:
        return _separate_flights(args, model, opts, bounds, prior, nkw)
    args.flight = args.flight[0]
    flight = _read(args)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", CasepWarning)
        res = separate(flight, model, args.method, sigma=args.sigma, bounds=bounds, prior=prior,
                       denoise=args.denoise, wavelet_options=wopts or None, outliers=args.outliers, **opts, **nkw)
    for w in caught:  # on to main(), which prints them
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    cons = None
    if prior is not None:  # the prior (a ground calibration) against the flight estimated alone
        import dataclasses

        from casep.calibration.consistency import flight_prior_consistency

        try:
            cons = flight_prior_consistency(flight, model, prior, sigma=args.sigma)
            summary = cons.summary()
        except ValueError as exc:  # the flight alone determines none of the prior's coefficients
            summary = {"not_compared": str(exc)}
            warnings.warn(f"prior not compared with the flight alone: {exc}", CasepWarning, stacklevel=1)
        res = dataclasses.replace(res, diagnostics={**res.diagnostics, "prior_consistency": summary})
    align = flight.meta.get("time_alignment") if isinstance(flight.meta, dict) else None
    prov = _provenance(args, [flight])
    if args.json:
        write_json_atomic({**res.to_dict(), **({"time_alignment": align} if align else {}), "provenance": prov},
                          args.json)
    _write_exports(res, args, t=flight.t[flight.observed], provenance=prov)
    print(res.table())
    _print_noise(res)
    if args.outliers is not None:
        from casep.analysis.outliers import OutlierFlags

        o = res.diagnostics["outliers_studentized"]
        print("outliers: " + OutlierFlags(o["rows"], o["threshold"], o["rate"], o["rows_tested"]).summary())
    if align and align.get("applied_s"):
        dt = [res.estimate[i] for i, n in enumerate(res.names) if n == "dt_trk"]
        total = f"; the flight's offset = shift + dt_trk = {align['applied_s'] * 1e3 + dt[0]:.4g} ms" if dt else ""
        print(f"tracking time tags shifted back by {align['applied_s'] * 1e3:.4g} ms before the fit{total}")
    if cons is not None:
        print(cons.report())
    if args.json:
        print(f"result written to {args.json}")
    for label, path in (("MAT file", args.mat), ("CSV", args.csv)):
        if path:
            print(f"{label} written to {path}")
    _write_separate_outputs(args, res, flight, bounds, prior, caught, prov)
    return _result_status(res)


def _separate_flights(args: argparse.Namespace, model, opts: dict, bounds, prior, nkw: dict) -> int:
    """`casep separate A B ...`: several flights in one estimate (casep.workflows.flights)."""
    from casep.estimators.result import write_json_atomic
    from casep.workflows.flights import JOINT_METHODS, flights_summary, separate_flights

    for flag, value in (("--denoise wavelet", args.denoise == "wavelet" or None),
                        ("--figures", args.figures), ("--report", args.report), ("--mat", args.mat),
                        ("--csv", args.csv)):
        if value:
            raise ValueError(f"{flag} is not available with several flights yet; give one flight, or leave it out")
    if args.method not in JOINT_METHODS:
        raise ValueError(f"--method {args.method} cannot estimate several flights jointly yet. "
                         f"Use: --method {' | '.join(JOINT_METHODS)}")
    options = {**opts, **({"bounds": bounds} if bounds else {}), **({"prior": prior} if prior else {})}
    flights = _read_flights(args)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", CasepWarning)
        res, jp = separate_flights(flights, model, args.method, sigma=args.sigma, options=options, **nkw)
        summary = flights_summary(res, jp)
    for w in caught:
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    print(res.table())
    _print_noise(res, joint=True)
    ov = summary["consistency"]["overall"]
    for f in summary["flights"]:
        print(f"{f['file']}: {f['n_samples']} samples, sigma {f['sigma']:.4g} m/s")
    if ov:
        print(f"consistency of the flights (Chow test, F form): chi2 {ov['chi2']:.4g}, {ov['dof']} dof, "
              f"p {ov['p_value']:.3g}"
              + ("  <- the flights disagree: an unmodelled error in one of them?" if ov["p_value"] < 1e-3 else ""))
    if summary["consistency"].get("note"):
        print("note: " + summary["consistency"]["note"])
    if args.json:
        write_json_atomic({**_joint_json(res, jp, summary), "provenance": _provenance(args, flights)}, args.json)
        print(f"result written to {args.json}")
    return _result_status(res)


def _joint_json(res, jp, summary: dict) -> dict:
    """The result JSON with `coefficients` of the shared coefficients and a `flights` list.

    Format: docs/reference/file-formats.md, "Several flights".
    """
    d = res.to_dict()
    keep = [i for i, n in enumerate(res.names) if n in jp.layout.names]  # shared: the model's own names
    for key in ("coefficients", "names", "units", "estimates", "std", "si_factors"):
        if d.get(key) is not None:
            d[key] = [d[key][i] for i in keep]
    if d.get("covariance") is not None:
        d["covariance"] = [[d["covariance"][i][j] for j in keep] for i in keep]
    d["flights"] = summary["flights"]
    d["consistency"] = summary["consistency"]
    return d


def _cmd_noise(args: argparse.Namespace) -> int:
    """`casep noise FLIGHT`: OLS residuals' Allan deviation and the noise model (casep.analysis.noise_id)."""
    import numpy as np

    from casep.analysis.noise_id import identify_noise
    from casep.analysis.problem import Problem
    from casep.estimators.ols import solve_ols
    from casep.estimators.result import write_json_atomic
    from casep.io._atomic import check_outputs
    from casep.model.loader import load_model

    _manifest(args)  # --manifest FLIGHTS.toml (one flight), or the flight file
    check_outputs({"--json": args.json}, inputs=_inputs(args, "flight", "tracking"),
                  folders={"--figures": args.figures})
    model = load_model(args.model)
    problem = Problem.from_flight(_read(args), model)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", CasepWarning)  # conditioning: not the question here
        res = solve_ols(problem)
    r = problem.residuals(res.estimate).reshape(-1, 3)
    step = np.diff(problem.t)
    dt = float(np.median(step))
    if np.max(np.abs(step - dt)) > 0.01 * dt:
        raise ValueError(f"{problem.source}: sample steps vary from {step.min():.4g} to {step.max():.4g} s: the "
                         "Allan deviation needs a uniform step (gaps?)")
    noise = identify_noise(r, dt)
    print(noise.report())
    if args.json:
        write_json_atomic({"model": model.name, "source": problem.source, **noise.to_dict()}, args.json)
        print(f"written to {args.json}")
    if args.figures:
        from casep.reporting.plots import plot_allan

        Path(args.figures).mkdir(parents=True, exist_ok=True)
        print(f"figure: {plot_allan(noise, Path(args.figures) / 'allan.png')}")
    return 0


def _cmd_fuse(args: argparse.Namespace) -> int:
    """`casep fuse R1.json R2.json ...` (casep.workflows.flights.fuse_with_ground)."""
    from casep.estimators.result import read_result, write_json_atomic
    from casep.io._atomic import check_outputs

    _manifest_results(args)  # --manifest: each flight's `result`
    check_outputs({"--json": args.json}, inputs=list(args.results) + [args.model])
    from casep.calibration.calibrate import calibration_models
    from casep.estimators.result import result_from_data
    from casep.io.result_json import read_result_data
    from casep.workflows.flights import fuse_with_ground

    grounds, results = set(calibration_models()), []
    for path in args.results:  # every result form, checked against its model (or --model)
        rd = read_result_data(path, "RESULT")
        if rd.model in grounds:  # a ground calibration: mapped to its flight model below
            results.append(result_from_data(rd))
        else:
            results.append(read_result(path, args.model, option="RESULT")[0])
    for path, r in zip(args.results, results):
        _refuse_failed(r, f"RESULT {path}")
    _refuse_shared_inputs(list(args.results))
    # ground results: their flight-model part, tested against each flight; a disagreeing pair fails the fusion
    res, ground_text = fuse_with_ground(results, labels=list(args.results), model=args.model)
    if ground_text:
        print(ground_text + "\n")
    print(res.table())
    c = res.diagnostics["consistency"]
    ov = c["overall"]
    print(f"consistency of the results: chi2 {ov['chi2']:.4g}, {ov['dof']} dof, p {ov['p_value']:.3g}")
    if args.json:
        prov = _provenance(args, [], {f"result {k + 1}": p for k, p in enumerate(args.results)})
        write_json_atomic({**res.to_dict(), "provenance": prov}, args.json)
        print(f"result written to {args.json}")
    return _result_status(res)


def _refuse_failed(res, where: str) -> None:
    """A failed result (``success`` false) is no input for fusing or as a prior: exit 2 saying why."""
    if not res.success:
        raise ValueError(f"{where}: a failed result (status {res.status}: {res.message}); its estimate and std are "
                         "not usable as an input. Fix what failed and estimate again")


def _refuse_shared_inputs(paths: list) -> None:
    """Two results whose provenance names the same input file (sha256), or one result fused from another:
    the same data would count twice."""
    import hashlib

    def digest(path) -> str | None:
        try:
            return hashlib.sha256(Path(path).read_bytes()).hexdigest()
        except OSError:
            return None

    seen: dict[str, tuple[str, str]] = {}  # sha256 -> (result file, the file it names)
    for path in paths:
        own = digest(path)
        try:
            with open(path, encoding="utf-8") as fh:
                prov = json.load(fh).get("provenance") or {}
        except (OSError, ValueError, AttributeError):
            prov = {}  # read and checked by the result reader; a hand-written result has no provenance
        named = [(own, str(path))] if own else []
        for inp in prov.get("inputs", []) if isinstance(prov, dict) else []:
            if isinstance(inp, dict) and inp.get("sha256") and inp.get("role", "") not in ("prior", "bounds", "model"):
                named.append((inp["sha256"], str(inp.get("file", ""))))
        for d, name in named:
            if d in seen and seen[d][0] != str(path):
                raise ValueError(f"RESULT {path} and {seen[d][0]} were estimated from the same input file {name} "
                                 f"(sha256 {d[:12]}...): fusing them counts its data twice (std too small by sqrt 2); "
                                 "give each flight's result once")
        for d, name in named:
            seen.setdefault(d, (str(path), name))


def _diagnose_flights(args: argparse.Namespace, model, prior, scales) -> int:
    """`casep diagnose A B ...`: per coefficient, the CRLB of each flight alone and of all jointly."""
    from casep.estimators.result import format_number, write_json_atomic
    from casep.workflows.flights import diagnose_flights

    if args.tau:
        raise ValueError("--tau is not available with several flights yet; give one flight, or leave it out")
    flights = _read_flights(args)
    d = diagnose_flights(flights, model, sigma=args.sigma, prior=prior, scales=scales)
    k = len(d["flights"])
    print(f"model {model.name}, {k} flights: CRLB std alone and jointly (verdict: + identifiable, ~ weak, "
          "- unidentifiable)" + ("; joint bound with the prior" if prior is not None else ""))
    mark = {"identifiable": "+", "weak": "~", "unidentifiable": "-"}
    print(f"{'coefficient':12s} {'unit':9s}" + "".join(f" {'flight ' + str(i + 1):>14s}" for i in range(k))
          + f" {'joint':>14s}")
    for r in d["coefficients"]:
        cells = [f"{format_number(v, 12)} {mark[w]}" for v, w in zip(r["crlb_alone"], r["verdict_alone"])]
        print(f"{r['name']:12s} {r['unit']:9s}" + "".join(f" {c:>14s}" for c in cells)
              + f" {format_number(r['crlb_joint'], 12)} {mark[r['verdict_joint']]}")
    for i, (f, s) in enumerate(zip(d["flights"], d["sigmas"])):
        print(f"flight {i + 1}: {f}, sigma {s:.4g} m/s, identifiable alone {d['identifiable_alone'][i]}")
    print(f"identifiable jointly: {d['identifiable_joint']} of {len(d['coefficients'])}")
    if args.json:
        write_json_atomic({"model": model.name, **d, "provenance": _provenance(args, flights)}, args.json)
        print(f"diagnostics written to {args.json}")
    if args.figures:
        from casep.reporting.plots import plot_flights_crlb

        Path(args.figures).mkdir(parents=True, exist_ok=True)
        print(f"figure: {plot_flights_crlb(d, Path(args.figures) / 'flights_crlb.png', scales=scales or model.scales)}")
    return 0


def _provenance(args: argparse.Namespace, flights: list, extra_inputs: dict | None = None) -> dict:
    """The provenance record of a command's result (casep.io.provenance): files with SHA-256, frames, sites,
    time alignment, exclusions, the options as given and the command line."""
    from casep.io.provenance import provenance

    skip = {"command", "flight", "tracking", "manifest", "manifest_obj", "json", "mat", "csv", "report", "figures",
            "argv", "results"}
    options = {k: v for k, v in vars(args).items() if k not in skip and v is not None
               and isinstance(v, (str, int, float, bool, list))}
    model = getattr(args, "model", None)
    inputs = {"prior": getattr(args, "prior", None), "bounds": getattr(args, "bounds", None),
              "model": model if model and Path(str(model)).is_file() else None, **(extra_inputs or {})}
    return provenance(flights, inputs=inputs, options=options, argv=getattr(args, "argv", None),
                      manifest=getattr(args, "manifest_obj", None))


def _write_separate_outputs(args: argparse.Namespace, res, flight, bounds, prior, caught, prov=None) -> None:
    """`--figures DIR` and `--report FILE` of `separate` (matplotlib imported only when asked)."""
    if not (args.figures or args.report):
        return
    from casep.reporting.plots import separate_figures
    from casep.reporting.report import write_report

    files = None
    if args.figures:
        files = separate_figures(res, args.figures, flight.t[flight.observed], prior=prior, bounds=bounds)
        print(f"figures: {', '.join(str(f) for f in files)}")
    if args.report:
        lines = [str(w.message) for w in caught if issubclass(w.category, CasepWarning)
                 and not issubclass(w.category, IllConditionedWarning)]
        write_report(res, args.report, flight=flight, figures=files, prior=prior, bounds=bounds, warnings=lines,
                     source=flight.source, provenance=prov)
        print(f"report written to {args.report}")


def _result_status(res) -> int:
    """Exit status of a computed result: 0, or 1 (message on stderr) when it is not successful.

    The table and the JSON are still written: the JSON records ``success: false`` and the
    message, which is what a script or a later look at the run needs.
    """
    if res.success:
        return 0
    print(f"casep: result not successful: {res.message}", file=sys.stderr)
    return 1


def _write_exports(res, args: argparse.Namespace, *, t=None, provenance=None) -> None:
    """`--mat` (with the residuals' times and the provenance) and `--csv` of `separate`."""
    from casep.estimators.result import write_csv, write_mat

    if args.mat:
        write_mat(res, args.mat, t=t, provenance=provenance)
    if args.csv:
        write_csv(res, args.csv)


def _cmd_diagnose(args: argparse.Namespace) -> int:
    from casep.analysis.diagnostics import diagnose
    from casep.analysis.problem import Problem
    from casep.estimators.map import parse_prior, prior_information
    from casep.estimators.result import write_json_atomic
    from casep.io._atomic import check_outputs
    from casep.io.files import read_json_table
    from casep.model._model import unknown_coefficient_message
    from casep.model.loader import load_model

    if args.radar:
        return _diagnose_radar(args)
    _radar_only(args, ("tracking_model",))
    _manifest(args)  # --manifest FLIGHTS.toml, or the flight files
    check_outputs({"--json": args.json}, inputs=_inputs(args, "flight", "tracking", "prior", "scales"),
                  folders={"--figures": args.figures})
    model = load_model(args.model)
    prior = _coefficient_file(args, "prior", model.names)
    prior_std = None if prior is None else parse_prior(prior, model.names)[1]
    prior_rows = None if prior is None or "correlation" not in prior else prior_information(prior, model.names)[0]
    scales = None
    if args.scales:
        scales = read_json_table(args.scales, "--scales")
        for k, v in scales.items():
            if k not in model.names:
                raise ValueError(unknown_coefficient_message(k, model.names, f"--scales {args.scales}"))
            if not isinstance(v, (int, float)) or isinstance(v, bool) or not (v > 0 and math.isfinite(v)):
                raise ValueError(f"--scales {args.scales}: `{k}` must be a finite number > 0, got {v!r}")
    if len(args.flight) > 1:
        return _diagnose_flights(args, model, prior, scales)
    args.flight = args.flight[0]
    flight = _read(args)
    problem = Problem.from_flight(flight, model)  # reduced block by block: S_V never whole (white bound)
    diag = diagnose(problem, sigma=args.sigma, tau=args.tau, prior_std=prior_std, prior_information=prior_rows,
                    scales=model.scales if scales is None else scales)
    if args.json:
        write_json_atomic({"casep_version": __version__, "model": model.name, "n_samples": flight.n_observed,
                           "diagnostics": diag.to_dict(), "provenance": _provenance(args, [flight])}, args.json)
    print(f"model {model.name}, {flight.n_observed} samples")
    print(diag.report())
    if args.figures:
        from casep.reporting.plots import plot_singular_values, plot_variance_decomposition

        Path(args.figures).mkdir(parents=True, exist_ok=True)  # like demo --out
        a = plot_singular_values(diag, Path(args.figures) / "singular_values.png")
        b = plot_variance_decomposition(diag, Path(args.figures) / "variance_decomposition.png")
        print(f"figures: {a}, {b}")
    if args.json:
        print(f"diagnostics written to {args.json}")
    return 0


# ---------------------------------------------------------------- radar stations and their errors
def _add_radar(parser) -> None:
    """`separate` / `diagnose`: radar measurements of one or more stations (measurement domain)."""
    parser.add_argument("--radar", nargs=2, action="append", default=None, metavar=("STATION.json", "MEAS.csv"),
                        help="a radar station ({name, lat, lon, h}: deg, deg, m WGS84) and its measurements (t, range "
                             "m, azimuth deg from north, elevation deg, optional range_rate m/s); repeat per station. "
                             "The flight file is then the telemetry (t, f_*, v_tel_*, optional r_tel_*); needs "
                             "--launch-site and --launch-time")
    parser.add_argument("--tracking-model", default="radar_biases", metavar="NAME|FILE",
                        help="with --radar: the station error model (default radar_biases)")


def _radar_site(args: argparse.Namespace):
    from casep.frames import LaunchSite

    if len(args.flight) != 1:
        raise ValueError(f"--radar takes one telemetry file, got {len(args.flight)}")
    if args.tracking or args.tracking_frame != "launch":
        raise ValueError("--radar replaces --tracking/--tracking-frame: give the radar stations only")
    if args.launch_site is None or args.launch_time is None:
        raise ValueError("--radar needs --launch-site LAT LON H AZ and --launch-time T0 (the launch time in the radar "
                         "files' time scale): they tie the telemetry's launch-inertial frame to the stations")
    return LaunchSite(*args.launch_site, args.launch_time)


def _separate_radar(args: argparse.Namespace, wavelet_options: dict) -> int:
    """`casep separate TEL --radar S1.json S1.csv ...`: instrument and station errors in one estimate."""
    from casep.estimators.result import write_json_atomic
    from casep.io._atomic import check_outputs
    from casep.workflows.radar import check_radar_options, separate_radar

    # the options of separate() that do not apply with radar: one list (casep.workflows.radar.NOT_WITH_RADAR)
    check_radar_options({"wavelet_options": wavelet_options, **{k: getattr(args, k) for k in (
        "denoise", "outliers", "sigma", "noise", "robust", "std", "exclude_outliers")}}, cli=True,
        outputs={"--figures": args.figures, "--mat": args.mat, "--csv": args.csv})
    check_outputs({"--json": args.json, "--report": args.report},
                  inputs=_inputs(args, "flight") + [f for pair in args.radar for f in pair])
    site = _radar_site(args)
    options = {k: getattr(args, k) for k in OPTIONS if getattr(args, k) is not None}
    for k in ("bounds", "prior"):
        if k in options:
            from casep.io.files import read_json_table

            options[k] = read_json_table(options[k], f"--{k}")
    rr = separate_radar(args.flight[0], args.radar, site, args.model, args.tracking_model, args.method,
                        options=options)
    print(rr.table())
    if args.json:
        write_json_atomic(rr.to_dict(), args.json)
        print(f"result written to {args.json}")
    if args.report:
        from casep.reporting.radar import write_radar_report

        print(f"report written to {write_radar_report(rr, args.report, source=args.flight[0])}")
    return _result_status(rr.result)


def _diagnose_radar(args: argparse.Namespace) -> int:
    """`casep diagnose TEL --radar ...`: CRLB with the tracking terms fixed and free, mixed groups, station gains."""
    from casep.estimators.result import write_json_atomic
    from casep.io._atomic import check_outputs
    from casep.tracking.diagnostics import diagnostics_table
    from casep.workflows.radar import diagnose_radar

    check_outputs({"--json": args.json}, inputs=_inputs(args, "flight") + [f for pair in args.radar for f in pair])
    d = diagnose_radar(args.flight[0], args.radar, _radar_site(args), args.model, args.tracking_model)
    print(diagnostics_table(d))
    if args.json:
        write_json_atomic({"casep_version": __version__, "model": args.model, "radar_diagnostics": d}, args.json)
        print(f"diagnostics written to {args.json}")
    return 0


def _add_simulate_radar(parser) -> None:
    parser.add_argument("--radar-station", metavar="STATION.json", action="append", default=None,
                        help="with --rotating-earth: write radar measurements of this station (repeat per station): "
                             "-o is then the telemetry (t, f_*, v_tel_*, r_tel_*), each station <stem>.<name>.json "
                             "and <stem>.<name>.csv beside it")
    parser.add_argument("--tracking-truth", metavar="FILE", default=None,
                        help='with --radar-station: JSON {"S1": {"range_bias": 5, ...}, ...}, the tracking model\'s '
                             "units (m, ppm, arcsec, ms); default none")
    parser.add_argument("--radar-rate", type=_positive_float, default=20.0, metavar="HZ",
                        help="with --radar-station: measurement rate (default 20)")
    parser.add_argument("--range-noise", type=float, default=3.0, metavar="M", help="range noise std (default 3 m)")
    parser.add_argument("--angle-noise", type=float, default=8.0, metavar="ARCSEC",
                        help="azimuth and elevation noise std (default 8 arcsec)")
    parser.add_argument("--radar-range-rate", action="store_true", help="also write range_rate (noise 0.05 m/s)")


def _simulate_radar(args: argparse.Namespace, site) -> int:
    """`casep simulate -o TEL.csv --rotating-earth --launch-site ... --radar-station S1.json ...`."""
    from casep.io._atomic import check_outputs
    from casep.io.files import read_json_table
    from casep.tracking.stations import read_station
    from casep.workflows.radar import radar_simulation_outputs, simulate_radar_files

    if site is None:
        raise ValueError("--radar-station needs --rotating-earth --launch-site LAT LON H AZ (the stations are on the "
                         "Earth)")
    if args.tracking_frame != "launch" or args.lever_arm is not None or args.tracking_offset:
        raise ValueError("--radar-station writes radar files: leave out --tracking-frame, --lever-arm and "
                         "--tracking-offset (a radar time-tag error is the tracking model's time_bias)")
    stations = [read_station(p) for p in args.radar_station]
    check_outputs(radar_simulation_outputs(args.output, stations),
                  inputs=_inputs(args, "truth", "tracking_truth", "radar_station"))
    sim, files = simulate_radar_files(
        args.output, stations, site, truth=read_json_table(args.truth, "--truth") if args.truth else None,
        tracking_truth=read_json_table(args.tracking_truth, "--tracking-truth") if args.tracking_truth else None,
        scenario=args.scenario, seed=args.seed, telemetry_rate=args.rate or 100.0, radar_rate=args.radar_rate,
        model=args.model, noise={"range": args.range_noise, "azimuth": args.angle_noise, "elevation": args.angle_noise},
        range_rate=args.radar_range_rate)
    print(f"scenario {sim.scenario}: telemetry {sim.telemetry.t.size} samples, "
          + ", ".join(f"{m.station.name} {m.t.size} samples" for m in sim.radars)
          + f" at {args.radar_rate:g} Hz (noise: " + "; ".join(f"{k} range {v['range']:g} m, angles {v['azimuth']:g} "
                                                               "arcsec" for k, v in sim.station_noise.items()) + ")")
    print("wrote " + ", ".join(str(f) for f in files))
    radar = " ".join(f"--radar {files[1 + 2 * i]} {files[2 + 2 * i]}" for i in range(len(sim.radars)))
    print(f"separate with: casep separate {args.output} {radar} --launch-site "
          f"{' '.join(f'{v:g}' for v in args.launch_site)} --launch-time 0")
    return 0


_RADAR_DEFAULTS = {"tracking_model": "radar_biases", "tracking_truth": None, "radar_rate": 20.0, "range_noise": 3.0,
                   "angle_noise": 8.0, "radar_range_rate": False}


def _radar_only(args: argparse.Namespace, names) -> None:
    """Radar options given without radar inputs are an error, not ignored."""
    for n in names:
        if getattr(args, n) != _RADAR_DEFAULTS[n]:
            need = "--radar-station" if args.command == "simulate" else "--radar"
            raise ValueError(f"--{n.replace('_', '-')} is used only with {need}")


def _list_tracking_model(name: str, error: str, verbose: bool) -> bool:
    """`casep models`: a model file that is a tracking model is listed as such (True), not as broken."""
    if "it is a tracking model" not in error:
        return False
    from casep.model.tracking import load_tracking_model

    m = load_tracking_model(name)
    print(f"{name:<28} {m.n_coefficients:>3} terms per station (tracking model, --tracking-model)  {m.description}")
    if verbose:
        for nm, unit in zip(m.names, m.units):
            print(f"    {nm:<16} {unit}")
    return True
# ---------------------------------------------------------------- end radar


# ---------------------------------------------------------------- casep impact
def _impact_parser(sub) -> None:
    """`casep impact FLIGHT --result RESULT.json [--trajectory OTHER.csv] [--json OUT] [--figures DIR]`."""
    im = sub.add_parser("impact", help="the impact miss that the estimated instrument errors cause, and its budget")
    im.add_argument("flight", nargs="?", help="flight file the result was estimated on (t, f_*, r_*, v_*; last row = "
                    "burnout)")
    im.add_argument("--result", metavar="RESULT.json", help="result JSON of casep separate --json (required, or the "
                    "manifest flight's `result`)")
    im.add_argument("--manifest", metavar="FLIGHTS.toml", default=None,
                    help="a manifest of one flight: its telemetry file and (without --result) its `result`")
    im.add_argument("--tracking", metavar="FILE", default=None, action="append",
                    help="tracking file (two-file input, as for separate): Earth-fixed tracking (--tracking-frame "
                         "ecef|geodetic) also gives the burnout position and velocity")
    _add_grid(im, manifest=False)
    _add_frames(im)
    im.add_argument("--trajectory", metavar="OTHER", default=None,
                    help="apply the result to another trajectory's S_V and burnout state (t, f_*, r_*, v_*)")
    im.add_argument("--model", default=None, help="model name or .py file (default: the result's)")
    im.add_argument("--per-flight", metavar="NAME=VALUE", action="append", default=None,
                    help="value (natural units) of a per-flight coefficient a several-flight result does not "
                         "hold (default 0); repeat for several")
    im.add_argument("--top", type=_positive_int, default=None, help="table: only the TOP (>= 1) largest contributions")
    im.add_argument("--json", metavar="OUT", default=None, help="write the impact JSON here")
    im.add_argument("--figures", metavar="DIR", default=None,
                    help="write miss_budget.png and impact_ellipse.png into DIR (created)")


def _cmd_impact(args: argparse.Namespace) -> int:
    from casep.estimators.result import write_json_atomic
    from casep.impact.miss import impact_analysis, read_trajectory
    from casep.io._atomic import check_outputs

    _impact_manifest(args)  # --manifest: the flight's file and result
    check_outputs({"--json": args.json}, inputs=_inputs(args, "flight", "tracking", "result", "trajectory"),
                  folders={"--figures": args.figures})
    per_flight = {}
    for item in args.per_flight or ():
        name, eq, value = item.partition("=")
        try:
            per_flight[name.strip()] = float(value)
        except ValueError:
            raise ValueError(f"--per-flight {item}: give NAME=VALUE (natural units)") from None
        if not eq or not math.isfinite(per_flight[name.strip()]):
            raise ValueError(f"--per-flight {item}: give NAME=VALUE with a finite value (natural units)")
    if args.tracking or getattr(args, "manifest_obj", None) is not None:  # telemetry + tracking (options or manifest)
        flight = _read(args)
    else:
        _frame_options(args)  # --tracking-frame / --launch-site without --tracking: an error
        flight = read_trajectory(args.flight)  # dv unused (a radar-tracked telemetry file has none)
    other = read_trajectory(args.trajectory) if args.trajectory else None
    a = impact_analysis(flight, args.result, args.model, other, per_flight=per_flight or None)
    if args.json:
        write_json_atomic(a.to_json(), args.json)
    print(a.table(top=args.top))
    if args.figures:
        from casep.reporting.plots import impact_figures

        print(f"figures: {', '.join(str(f) for f in impact_figures(a, args.figures))}")
    if args.json:
        print(f"impact written to {args.json}")
    return 0
# ---------------------------------------------------------------- end casep impact


# ---------------------------------------------------------------- casep design
def _design_parser(sub) -> None:
    """`casep design [--scenario paper] [--maneuver yaw|pitch|both] [--objective A|D|miss] [--max-angle DEG]
    [--max-rate DEG_PER_S] [--prior FILE] [--json OUT] [-o FLIGHT.csv]`.

    Output: docs/reference/file-formats.md, "Design JSON".
    """
    from casep.simulation.scenarios import SCENARIOS

    de = sub.add_parser("design", help="the attitude manoeuvre that minimises the Cramer-Rao bound (IPOPT)")
    de.add_argument("--scenario", default="paper", choices=list(SCENARIOS), help="nominal flight (default paper)")
    de.add_argument("--maneuver", default="yaw", choices=("yaw", "pitch", "both"),
                    help="attitude axes the manoeuvre moves (default yaw)")
    de.add_argument("--objective", default="A", choices=("A", "D", "miss"),
                    help="A: trace of the covariance scaled by the declared magnitudes; D: its log det; miss: "
                         "variance of the nominal trajectory's predicted impact miss (default A)")
    de.add_argument("--max-angle", type=float, default=5.0, metavar="DEG",
                    help="largest offset from the nominal attitude, deg (default 5)")
    de.add_argument("--max-rate", type=float, default=2.0, metavar="DEG_PER_S",
                    help="largest offset rate, deg/s (default 2)")
    de.add_argument("--max-lateral", type=float, default=1.0, metavar="G",
                    help="largest lateral specific force, norm(f) sin(offset), g (default 1)")
    de.add_argument("--coefficients", metavar="NAMES", default=None,
                    help="comma-separated coefficients that matter: objective A over these only (default all)")
    de.add_argument("--knots", type=int, default=10, help="knots of the piecewise-linear offset (default 10)")
    de.add_argument("--starts", type=int, default=4, help="IPOPT starts (default 4)")
    de.add_argument("--seed", type=_order, default=0, help="seed of the random starts and of -o's noise (default 0)")
    de.add_argument("--rate", type=_rate, default=None, help="sample rate, Hz (default: scenario's)")
    de.add_argument("--prior", metavar="FILE", default=None,
                    help='prior JSON {"Kg0x": {"mean": m, "std": s}, ...} (natural units): Bayesian covariance')
    de.add_argument("--json", metavar="OUT", default=None, help="write the design JSON here")
    de.add_argument("--figure", metavar="PNG", default=None, help="write the manoeuvre and CRLB before/after here")
    de.add_argument("-o", "--output", metavar="FLIGHT", default=None,
                    help="simulate the designed flight into this flight file (truth in <stem>.truth.json)")
    _own_trajectory_options(de)


def _cmd_design(args: argparse.Namespace) -> int:
    from casep.design.optimize import design
    from casep.estimators.result import write_json_atomic
    from casep.io._atomic import check_outputs
    from casep.model.loader import load_model
    from casep.simulation.scenarios import get_scenario
    from casep.simulation.simulate import truth_path

    for flag, v, hi in (("--max-angle", args.max_angle, 45.0), ("--max-rate", args.max_rate, math.inf),
                        ("--max-lateral", args.max_lateral, math.inf)):
        if not (math.isfinite(v) and 0 < v <= hi):
            raise ValueError(f"{flag} must be > 0" + (f" and <= {hi:g}" if math.isfinite(hi) else "") + f", got {v:g}")
    if args.knots < 2 or args.starts < 1:
        raise ValueError(f"--knots must be >= 2 and --starts >= 1, got {args.knots} and {args.starts}")
    outputs = {"--json": args.json, "--figure": args.figure}
    if args.output:
        outputs.update({"-o": args.output, "-o (truth sidecar)": truth_path(args.output)})
    check_outputs(outputs, inputs=_inputs(args, "prior", "flight", "truth"))
    own_flight, own_truth, own_model = _own_trajectory(args)  # --flight FILE --truth TRUTH.json
    if own_flight and args.output:
        raise ValueError("-o simulates the designed flight of a scenario's vehicle; with --flight there is none")
    own_sigma = None
    if own_truth and isinstance(own_truth.get("noise"), dict):
        own_sigma = own_truth["noise"].get("sigma")
    prior = _coefficient_file(args, "prior", load_model(own_model or get_scenario(args.scenario).model).names)
    res = design(args.scenario, maneuver=args.maneuver, objective=args.objective, max_angle=args.max_angle,
                 max_rate=args.max_rate, max_lateral=args.max_lateral, prior=prior, knots=args.knots,
                 starts=args.starts, seed=args.seed, rate=None if own_flight else args.rate,
                 coefficients=None if args.coefficients is None else
                 [c.strip() for c in args.coefficients.split(",") if c.strip()],
                 flight=own_flight, model=own_model, sigma=own_sigma)
    s = res.solver
    print(f"{args.objective}-optimal {args.maneuver} manoeuvre, scenario {args.scenario}: objective "
          f"{res.before:.6g} -> {res.after:.6g} (design model); IPOPT {s['return_status']} (best of "
          f"{len(s['starts'])} starts; {sum(r['success'] for r in s['starts'])} solved), {res.timing['total']:.1f} s")
    v = res.verification
    if not v:  # one's own trajectory: no vehicle to re-fly
        print(f"own trajectory {own_flight}: the designed flight is not re-flown (no vehicle model); the 'after' "
              "bounds are the design model's prediction (the manoeuvre turns the specific force)")
    else:
        print(f"re-simulated: objective {v['before']:.6g} -> {v['after']:.6g}; CRLB prediction error max "
              f"{100 * v['crlb_prediction_error_max']:.1f} %")
    gain_d = (res.before - res.after) / abs(res.before) if res.before else 0.0
    gain_v = ((v["before"] - v["after"]) / abs(v["before"]) if v["before"] else 0.0) if v else gain_d
    if abs(gain_d - gain_v) > 0.05 * max(abs(gain_v), 1e-12) and abs(gain_d - gain_v) > 0.01:
        print(f"warning: the design model promised a {100 * gain_d:.1f} % change of the objective, the re-simulated "
              f"flights give {100 * gain_v:.1f} %: trust the re-simulated value (the JSON's before/after)")
    if v:
        b = v["burnout_change"]
        print(f"the designed flight burns out elsewhere: speed {b['speed_m_s']:+.1f} m/s, "
              f"altitude {b['altitude_m'] / 1e3:+.2f} km, crossrange {b['crossrange_m'] / 1e3:+.2f} km (no terminal "
              "constraint: a test flight, not the mission)")
    sc_noise = get_scenario(args.scenario).noise
    if sc_noise.kind != "white" and not own_flight:
        print(f"warning: scenario {args.scenario} has {sc_noise.kind} tracking noise; the design assumes white noise "
              "of the same sigma")
    m = res.maneuver.to_dict(res.x)
    print("knots s:   " + " ".join(f"{t:7.1f}" for t in m["knots_s"]))
    for axis in res.maneuver.axes:
        print(f"{axis + ' deg:':<11}" + " ".join(f"{a:7.2f}" for a in m[f"{axis}_deg"]))
    print(res.table())
    what = ("posterior std (prior included) < declared magnitude" if args.prior else "CRLB < declared magnitude")
    print(f"identifiable ({what}): {len(res.identifiable('before'))} before, "
          f"{len(res.identifiable('after'))} after: {', '.join(res.identifiable('after')) or 'none'}")
    if res.worse():
        print(f"worse after the design (bound x > 1.05): {', '.join(res.worse())}")
    if args.json:
        write_json_atomic(res.to_json(), args.json)
        print(f"design written to {args.json}")
    if args.figure:
        from casep.reporting.plots import plot_design

        print(f"figure written to {plot_design(res, args.figure)}")
    if args.output:
        from casep.simulation.simulate import simulate_flight, write_simulation

        flight_path, side = write_simulation(simulate_flight(res.scenario, seed=args.seed), args.output)
        print(f"designed flight written to {flight_path} and {side}")
    return 0 if s["success"] else 1
# ---------------------------------------------------------------- end casep design


def _cmd_demo(args: argparse.Namespace) -> int:
    from casep.workflows.demo import _summary_lines, impact_lines, run_demo

    res = run_demo(args.out, seed=args.seed, rate=args.rate)
    sim = res.sim
    print(f"casep demo: paper scenario, seed {sim.seed}, {sim.flight.n_samples} samples at {sim.scenario.rate:g} Hz, "
          f"white noise 0.1 m/s")
    print()
    print(res.table)
    print()
    d = res.diagnostics
    print(f"equilibrated condition number {d.condition_number_equilibrated:.3g}; "
          f"identifiable alone: {', '.join(n for n, v in d.identifiability.items() if v == 'identifiable')}")
    for line in _summary_lines(sim, res.results, d.crlb_std):
        print(line)
    print()
    for line in impact_lines(res.impact, res.true_miss):
        print(line)
    print()
    print(f"report and figures in {args.out}/ (report.md)")
    return 0


def _cmd_montecarlo(args: argparse.Namespace) -> int:
    from casep.estimators.map import parse_prior
    from casep.io._atomic import check_outputs
    from casep.io.files import read_json_table
    from casep.model.loader import load_model
    from casep.simulation.dispersions import parse_dispersions
    from casep.simulation.scenarios import get_scenario
    from casep.workflows.montecarlo import Terminated, run_montecarlo, sigterm_raises, write_figure

    check_outputs({"--json": args.json, "--csv": args.csv, "--figure": args.figure},
                  inputs=_inputs(args, "prior", "bounds", "dispersions", "truth_from_prior", "flight", "truth"))
    sc = get_scenario(args.scenario)
    own_flight, own_truth, own_model = _own_trajectory(args)  # --flight FILE --truth TRUTH.json
    names = load_model(own_model or sc.model).names
    prior, bounds = _coefficient_file(args, "prior", names), _coefficient_file(args, "bounds", names)
    dispersions = truth_prior = None
    if args.dispersions:
        dispersions = parse_dispersions(read_json_table(args.dispersions, "--dispersions"), len(sc.vehicle.stages),
                                        source=f"--dispersions {args.dispersions}")
    if args.truth_from_prior:
        where = f"--truth-from-prior {args.truth_from_prior}"
        truth_prior = read_json_table(args.truth_from_prior, "--truth-from-prior")
        if "correlation" in truth_prior and "correlation" not in names:
            raise ValueError(f"{where}: a `correlation` entry is not supported (marginal mean and std only)")
        parse_prior(truth_prior, names, source=where)
    if args.out and Path(args.out).exists() and not Path(args.out).is_dir():
        raise ValueError(f"--out {args.out}: exists and is not a folder")
    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    if args.runs < 1:
        raise ValueError(f"--runs must be >= 1, got {args.runs}")
    if args.workers is not None and args.workers < 1:
        raise ValueError(f"--workers must be >= 1, got {args.workers}")
    try:
        with sigterm_raises():
            res = run_montecarlo(args.scenario, runs=args.runs, methods=methods, seed=args.seed, rate=args.rate,
                                 workers=args.workers, progress=args.progress, prior=prior, bounds=bounds,
                                 scheduler=args.scheduler, dispersions=dispersions, truth_prior=truth_prior,
                                 out=args.out, flight=own_flight, truth=own_truth, noise=args.noise,
                                 tau=args.noise_tau, robust=args.robust)
    except (KeyboardInterrupt, Terminated) as exc:  # workers already ended; no report (--out: finished parts kept)
        print("casep: interrupted", file=sys.stderr)
        return 143 if isinstance(exc, Terminated) else 130
    print(f"scenario {res.scenario}, {res.runs} runs, seed {res.seed}")
    if args.out:
        print(f"resumed {res.resumed} of {res.tasks} tasks from {args.out}" if res.resumed else
              f"{res.tasks} tasks, none resumed")
    print(res.summary())
    from casep.io._atomic import output_group

    with output_group():  # the report files together or none (the --out store keeps its parts regardless)
        if args.json:
            res.write_json(args.json)
        if args.csv:
            res.write_csv(args.csv)
        if args.figure:
            write_figure(res, args.figure)
    for label, path in (("JSON", args.json), ("CSV", args.csv), ("figure", args.figure)):
        if path:
            print(f"{label} written to {path}")
    if args.out:
        print(f"per-run results in {Path(args.out) / 'runs.parquet'}, summary in {Path(args.out) / 'summary.json'}")
    return 0


def _cmd_simulate(args: argparse.Namespace) -> int:
    from casep.io._atomic import check_outputs
    from casep.io.files import read_json_table
    from casep.model.loader import load_model
    from casep.simulation.scenarios import get_scenario
    from casep.simulation.simulate import simulate_flight, truth_path, write_simulation

    site = _simulate_site(args)  # --rotating-earth --launch-site (tracking frames)
    if args.radar_station:
        return _simulate_radar(args, site)
    _radar_only(args, ("tracking_truth", "radar_rate", "range_noise", "angle_noise", "radar_range_rate"))
    if args.tracking_frame == "launch":
        if args.tracking_output is not None:
            raise ValueError("--tracking-output needs --tracking-frame ecef|geodetic")
        check_outputs({"-o": args.output, "-o (truth sidecar)": truth_path(args.output)},
                      inputs=_inputs(args, "truth"))
    if args.seed < 0:
        raise ValueError(f"`--seed` must be >= 0, got {args.seed}")
    truth = None
    if args.truth:  # {"Kg0x": v, ...} or a sidecar {"coefficients": {...}}, checked against the model
        from casep.simulation.simulate import _truth_vector

        truth = read_json_table(args.truth, "--truth")
        truth = truth["coefficients"] if isinstance(truth.get("coefficients"), dict) else truth
        _truth_vector(load_model(args.model or get_scenario(args.scenario).model), truth, f"--truth {args.truth}")
    if args.tracking_frame != "launch":
        return _simulate_earth_fixed(args, site, truth)
    sim = simulate_flight(args.scenario, seed=args.seed, rate=args.rate, model=args.model, truth=truth,
                          time_offset=args.tracking_offset * 1e-3, lever_arm=args.lever_arm,  # ms -> s
                          **({"rotating_earth": True, "site": site} if site is not None else {}))
    flight_path, side = write_simulation(sim, args.output)
    s = sim.trajectory.summary()
    print(f"scenario {sim.scenario.name}: {sim.flight.n_samples} samples at {sim.scenario.rate:g} Hz, "
          f"{s['duration_s']:.1f} s powered flight")
    print(f"lift-off {s['liftoff_specific_force_g']:.2f} g, max {s['max_specific_force_g']:.2f} g; burnout "
          f"{s['burnout_speed_m_s'] / 1e3:.2f} km/s at {s['burnout_altitude_m'] / 1e3:.0f} km, "
          f"flight-path angle {s['burnout_flight_path_deg']:.1f} deg")
    print(f"wrote {flight_path} and {side}")
    return 0


def _cmd_methods(args: argparse.Namespace) -> int:
    from casep.estimators.registry import describe

    table = describe()
    if args.json:
        print(json.dumps(table, indent=2))
        return 0
    for m in table:
        caps = [c for c, on in (("recursive", m["recursive"]), ("needs time", m["needs_time"]),
                                ("batched in montecarlo", m["batched_in_montecarlo"])) if on]
        print(f"{m['name']:<8} {m['summary']}; std {m['std_kind']}" + (f"; {', '.join(caps)}" if caps else ""))
        for o in m["options"]:
            d = o["default"]
            req = " (required)" if o["name"] in m["required"] else f" (default {d:g})" if isinstance(d, float) \
                else f" (default {d})"
            print(f"    {o['flag']:<14} {o['rule']}{req}: {o['help']}")
    return 0


def _cmd_models(args: argparse.Namespace) -> int:
    """List the models; a file that fails to load is a `warning:` line naming it and why.

    Exit 0 when at least one model loads (the broken ones are reported), 2 when none does.
    """
    from casep.model._model import ModelDefinitionError
    from casep.model.loader import available_models, load_model

    names = available_models()
    broken = 0
    for name in names:
        try:
            model = load_model(name)
        except ModelDefinitionError as exc:
            if _list_tracking_model(name, str(exc), args.verbose):
                continue
            broken += 1
            warnings.warn(f"model `{name}` not listed: {exc}", CasepWarning, stacklevel=1)
            continue
        print(f"{name:<28} {model.n_coefficients:>3} coefficients  {model.description}")
        if args.verbose:
            doc = getattr(model, "source_doc", "")
            if doc:  # the model file's docstring: its equations and conventions
                print("\n".join("    | " + line if line.strip() else "    |" for line in doc.splitlines()))
            scales = model.scales
            print(f"    {'coefficient':<12} {'unit':<10} {'magnitude':>10}  description")
            for nm, unit, own, what in zip(model.names, model.units, model.per_flight, model.descriptions):
                mag = f"{scales[nm]:.3g}" if nm in scales else "-"
                note = "; ".join(x for x in (what, "per flight" if own else "") if x)
                print(f"    {nm:<12} {unit:<10} {mag:>10}  {note}".rstrip())
            if model.signals:
                print(f"    signals: {', '.join(model.signals)}")
            if getattr(model, "source_file", None):
                print(f"    file: {model.source_file}")
    if broken and broken == len(names):
        print(f"casep: error: none of the {broken} model files loads (see the warnings)", file=sys.stderr)
        return 2
    return 0


def _calibrate_parser(sub) -> None:
    """`casep calibrate SESSION --rate HZ (--segments FILE | --label-column NAME) [--model NAME|FILE] [--method ...]
    --json OUT [--imucal OUT]` (casep.calibration)."""
    ca = sub.add_parser("calibrate", help="identify instrument error coefficients from a ground test "
                        "(static positions and rotations)")
    ca.add_argument("session", help="session CSV or Parquet: raw accelerometer and gyro columns (any units), "
                    "and `t` (s) or a sample-index column with --rate")
    ca.add_argument("--rate", type=float, default=None, metavar="HZ", help="sample rate, Hz (required without `t`)")
    seg = ca.add_mutually_exclusive_group(required=True)
    seg.add_argument("--segments", metavar="FILE", default=None,
                     help="segments JSON: imucal's section list {name: {start, end}} or a list of segments")
    seg.add_argument("--label-column", metavar="NAME", default=None, dest="label_column",
                     help="column labelling each row's segment (imucal's annotated sessions: part)")
    ca.add_argument("--model", default="ferraris", help="calibration model name (models/calibration) or .py file "
                    "(default ferraris; platform36_ground: the flight model's names and units, SI readings)")
    ca.add_argument("--method", default="ols", choices=[m for m, meth in METHODS.items()
                                                         if not meth.needs_time and m != "rels"],
                    help="estimator (default ols)")
    for name in ("prior", "bounds", "lam", "n_components", "p0", "weight", "forgetting", "noise_order"):
        _add_option(ca, OPTIONS[name])
    ca.add_argument("--prior-rel-std", type=float, default=None, dest="prior_rel_std", metavar="R",
                    help="with an imucal --prior: its relative std (imucal states none)")
    ca.add_argument("--sigma", type=float, default=None, help="noise std of the rows (default estimated per sensor): "
                    "reading units with --weighting segments|samples, 1 = as modelled with positions")
    ca.add_argument("--acc-columns", default="acc_x,acc_y,acc_z", help="accelerometer columns x,y,z")
    ca.add_argument("--gyr-columns", default="gyr_x,gyr_y,gyr_z", help="gyro columns x,y,z")
    ca.add_argument("--acc-unit", default="a.u.", help="accelerometer unit: a.u. (raw), m/s^2, g, mg")
    ca.add_argument("--gyr-unit", default="a.u.", help="gyro unit: a.u. (raw), deg/s, rad/s, deg/h")
    ca.add_argument("--gravity", type=float, default=None, metavar="M_S2",
                    help="gravity at the stand, m/s^2 (default 9.80665; imucal uses 9.81)")
    ca.add_argument("--angle", type=float, default=-360.0, metavar="DEG",
                    help="angle of imucal's x_rot/y_rot/z_rot turns, deg (default -360: clockwise, imucal's)")
    ca.add_argument("--weighting", choices=("positions", "segments", "samples"), default="positions",
                    help="rows: segment means weighted by a position-error (tilt) and noise model (default), "
                         "segment means of equal weight, or every sample (exact positions)")
    ca.add_argument("--json", metavar="OUT", required=True, help="write the calibration JSON (a casep result)")
    ca.add_argument("--imucal", metavar="OUT", default=None, help="also write imucal's calibration JSON (ferraris)")


def _cmd_calibrate(args: argparse.Namespace) -> int:
    """`casep calibrate`: one call of casep.calibration.calibrate_files, the report, the files (all or none)."""
    from casep.calibration.calibrate import calibrate_files
    from casep.calibration.imucal import to_imucal
    from casep.estimators.result import write_json_atomic
    from casep.io._atomic import check_outputs
    from casep.units import G0

    check_outputs({"--json": args.json, "--imucal": args.imucal},
                  inputs=[args.session, args.segments, args.prior, args.bounds])
    options = {k: getattr(args, k) for k in OPTIONS if getattr(args, k, None) is not None}
    cal = calibrate_files(args.session, rate=args.rate, segments=args.segments, label_column=args.label_column,
                          model=args.model, method=args.method, options=options,
                          acc_columns=args.acc_columns.split(","), gyr_columns=args.gyr_columns.split(","),
                          acc_unit=args.acc_unit, gyr_unit=args.gyr_unit,
                          gravity=G0 if args.gravity is None else args.gravity, angle_deg=args.angle,
                          weighting=args.weighting, sigma=args.sigma, prior_rel_std=args.prior_rel_std)
    imucal = to_imucal(cal) if args.imucal else None  # before any file: all outputs or none
    print(cal.report())
    write_json_atomic(cal.to_dict(), args.json)
    print(f"calibration written to {args.json}")
    if imucal is not None:
        write_json_atomic(imucal, args.imucal)
        print(f"imucal calibration written to {args.imucal}")
    return _result_status(cal.result)


#: Exit status when the reader of stdout goes away (``casep ... | head``): 128 + SIGPIPE, what the
#: shell reports for any Unix tool ended by the broken pipe, so ``set -o pipefail`` sees the same.
EXIT_BROKEN_PIPE = 141


def _quiet_on_broken_pipe(run):
    """Wrap `run` so a closed stdout ends it quietly with :data:`EXIT_BROKEN_PIPE`.

    The Python recipe (docs, "Note on SIGPIPE"): flush inside the guard so buffered output
    fails here, then point stdout at /dev/null so the interpreter's final flush is silent.
    """

    @functools.wraps(run)
    def guarded(argv: Sequence[str] | None = None) -> int:
        try:
            status = run(argv)
            sys.stdout.flush()
            return status
        except BrokenPipeError:
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
            os.close(devnull)
            return EXIT_BROKEN_PIPE

    return guarded


@_quiet_on_broken_pipe
def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status."""
    args = _parser().parse_args(argv)
    args.argv = ["casep", *(sys.argv[1:] if argv is None else argv)]  # the command line, for the provenance
    commands = {"separate": _cmd_separate, "diagnose": _cmd_diagnose, "simulate": _cmd_simulate,
                "montecarlo": _cmd_montecarlo, "demo": _cmd_demo, "models": _cmd_models, "methods": _cmd_methods,
                "fuse": _cmd_fuse, "impact": _cmd_impact, "noise": _cmd_noise, "design": _cmd_design,
                "calibrate": _cmd_calibrate}
    from contextlib import nullcontext

    from casep.io._atomic import output_group

    # All outputs of a command appear together or none (a failed second output leaves no first);
    # not for montecarlo, whose --out folder keeps every finished part for a resume.
    group = nullcontext() if args.command == "montecarlo" else output_group()
    try:
        with warnings.catch_warnings(record=True) as caught, group:
            warnings.simplefilter("always", CasepWarning)
            status = commands[args.command](args)
    except BrokenPipeError:
        raise  # the reader left: quiet exit, see _quiet_on_broken_pipe
    except (ValueError, TypeError, OSError) as exc:  # FlightDataError, ModelDefinitionError among them
        print(f"casep: error: {exc}", file=sys.stderr)
        return 2
    # casep's warnings become lines of the report (the ill-conditioning one is in the table).
    for w in caught:
        if issubclass(w.category, CasepWarning) and not issubclass(w.category, IllConditionedWarning):
            print(f"warning: {w.message}")
        elif not issubclass(w.category, CasepWarning):
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return status


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())

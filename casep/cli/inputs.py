"""What a command reads: its flights (files, telemetry + tracking pairs or a manifest) and its input files."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from casep.cli.site import launch_site

__all__ = ["read_one", "read_all", "use_manifest", "frame_options", "launch_site", "input_files", "coefficient_file",
           "own_trajectory"]


def frame_options(args: argparse.Namespace) -> dict[str, Any]:
    """read_flight_pair's `tracking_frame` and `site` from the command line (a missing site: the reader's error,
    which names the tracking file)."""
    # getattr: a command whose parser has no frame options reads launch-frame tracking
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
    return {"tracking_frame": frame, "site": None if lsite is None or t0 is None else launch_site(lsite, t0)}


def _pair(args: argparse.Namespace, flight: str, tracking: str, frames: dict[str, Any]) -> Any:
    from casep.io.files import read_flight_pair

    return read_flight_pair(flight, tracking, grid=args.grid, time_offset=args.time_offset,
                            time_shift=getattr(args, "time_shift", 0.0),
                            clock_drift=getattr(args, "clock_drift", 0.0),
                            clock_drift_std=getattr(args, "clock_drift_std", None), **frames)


def read_one(args: argparse.Namespace) -> Any:
    """The flight of a command: one file, telemetry + `--tracking`, or the one flight of `--manifest`."""
    from casep.io.files import read_flight

    man = getattr(args, "manifest_obj", None)
    if man is not None:
        if len(man.flights) != 1:
            raise ValueError(f"--manifest {man.source} lists {len(man.flights)} flights; this command reads one")
        return man.flights[0].read()
    tracking = args.tracking or []
    if len(tracking) > 1:
        raise ValueError(f"--tracking given {len(tracking)} times for one flight; give it once per flight")
    frames = frame_options(args)  # --tracking-frame, --launch-site, --launch-time
    return _pair(args, args.flight, tracking[0], frames) if tracking else read_flight(args.flight)


def read_all(args: argparse.Namespace) -> list[Any]:
    """Several flights, each a file or (with `--tracking` once per flight, in flight order) a pair."""
    from casep.io.files import read_flight

    if getattr(args, "manifest_obj", None) is not None:
        return list(args.manifest_obj.read())  # each flight with its own frame, site, launch time and time shift
    tracking = args.tracking or []
    if tracking and len(tracking) != len(args.flight):
        raise ValueError(f"--tracking given {len(tracking)} times for {len(args.flight)} flights: give it once per "
                         "flight, in the order of the flights (telemetry A --tracking TA, B --tracking TB)")
    frames = frame_options(args)  # the same for every flight
    if tracking:
        return [_pair(args, f, t, frames) for f, t in zip(args.flight, tracking)]
    return [read_flight(f) for f in args.flight]


def use_manifest(args: argparse.Namespace) -> Any:
    """`--manifest FLIGHTS.toml` read (kept as ``args.manifest_obj``; ``args.flight`` its telemetry files), or None.

    The manifest holds each flight's files and set-up: the single-flight options are an error with it, and
    without it a flight file is needed."""
    path = getattr(args, "manifest", None)
    flights = args.flight if isinstance(args.flight, list) else [args.flight] if args.flight else []
    if not path:
        if not flights:
            raise ValueError("give a flight file, or --manifest FLIGHTS.toml")
        return None
    on_line: frozenset[str] = getattr(args, "given", frozenset())  # given, whatever the values (cli.app.Parser)
    given = (["the flight files"] if flights else []) + [
        "--" + dest.replace("_", "-") for dest in ("tracking", "tracking_frame", "launch_site", "launch_time",
                                                   "time_shift", "clock_drift", "clock_drift_std", "time_offset",
                                                   "grid")
        if dest in on_line]
    if given:
        raise ValueError(f"--manifest {path} lists the flights with their files and set-up: leave out "
                         f"{', '.join(given)} (they describe one flight given on the command line)")
    from casep.workflows.manifest import read_manifest

    man = read_manifest(path)
    args.manifest_obj = man
    telemetry = [str(f.telemetry) for f in man.flights]
    args.flight = telemetry if isinstance(args.flight, list) else telemetry[0]
    return man


def input_files(args: argparse.Namespace, *names: str) -> list[Any]:
    """The input files a command reads (an output must be none of them)."""
    files: list[Any] = []
    for n in names:
        v = getattr(args, n, None)
        files += v if isinstance(v, list) else [v]
    man = getattr(args, "manifest_obj", None)
    if man is not None:  # the manifest and every file it lists
        files += [man.source] + [str(p) for f in man.flights for p in (f.telemetry, f.tracking, f.result) if p]
    model = getattr(args, "model", None)
    return files + ([model] if model and Path(model).is_file() else [])


def coefficient_file(args: argparse.Namespace, option: str, names: Any, *, fitted: bool = False) -> dict | None:
    """The `--bounds`/`--prior` file (coefficients.read_coefficient_file) or None; `fitted`: no result of the flight."""
    if not (path := getattr(args, option)):
        return None
    from casep.workflows.coefficients import read_coefficient_file

    return read_coefficient_file(path, option, names, model=getattr(args, "model", None),
                                 data_files=input_files(args, "flight", "tracking") if fitted else ())


def own_trajectory(args: argparse.Namespace) -> tuple[Any, Any, Any]:
    """(flight path, truth dict, model) of --flight/--truth, or (None, None, None). The model (also the dict's
    ``model``): the shipped one the truth names or ``--model`` (a file never runs code on its own word:
    :func:`casep.model.loader.load_recorded_model`); None when neither names one (the scenario's)."""
    flight, truth, given = getattr(args, "flight", None), getattr(args, "truth", None), getattr(args, "model", None)
    if not flight and not truth:
        if given and not getattr(args, "prior", None):
            raise ValueError(f"--model {given} names the model of a --truth or --prior file that is not shipped with "
                             "casep; without them the scenario's model is used: leave --model out")
        return None, None, None
    if not (flight and truth):
        raise ValueError("--flight and --truth go together: one's own trajectory needs its true coefficients")
    from casep.io.files import read_json_table
    from casep.model.loader import load_recorded_model

    data = read_json_table(truth, "--truth")
    name = data.get("model") if isinstance(data.get("model"), str) else None
    model = None if name is None and given is None else load_recorded_model(name, given=given, where=f"--truth {truth}")
    return flight, data if model is None else {**data, "model": model}, model

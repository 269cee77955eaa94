"""``casep impact FLIGHT --result RESULT.json``: the impact miss the estimated instrument errors cause, and its
budget (casep.impact.miss)."""

from __future__ import annotations

import argparse
import math
from typing import Any

from casep.cli import flight_options, inputs, options, outputs
from casep.cli.types import positive_int


def add_parser(sub: Any) -> None:
    p = sub.add_parser("impact", help="the impact miss that the estimated instrument errors cause, and its budget")
    p.add_argument("flight", nargs="?", help="flight file the result was estimated on (t, f_*, r_*, v_*; last row = "
                   "burnout)")
    p.add_argument("--result", metavar="RESULT.json", help="result JSON of casep separate --json (required, or the "
                   "manifest flight's `result`)")
    p.add_argument("--manifest", metavar="FLIGHTS.toml", default=None,
                   help="a manifest of one flight: its telemetry file and (without --result) its `result`")
    flight_options.add_tracking(p, "tracking file (two-file input, as for separate): Earth-fixed tracking "
                                   "(--tracking-frame ecef|geodetic) also gives the burnout position and velocity")
    flight_options.add_grid(p, manifest=False)
    flight_options.add_frames(p)
    p.add_argument("--trajectory", metavar="OTHER", default=None,
                   help="apply the result to another trajectory's S_V and burnout state (t, f_*, r_*, v_*)")
    options.add_model(p, None, "default: the result's")
    p.add_argument("--per-flight", metavar="NAME=VALUE", action="append", default=None,
                   help="value (natural units) of a per-flight coefficient a several-flight result does not "
                        "hold (default 0); repeat for several")
    p.add_argument("--top", type=positive_int, default=None, help="table: only the TOP (>= 1) largest contributions")
    options.add_json(p, "the impact JSON")
    p.add_argument("--figures", metavar="DIR", default=None,
                   help="write miss_budget.png and impact_ellipse.png into DIR (created)")


def _manifest(args: argparse.Namespace) -> None:
    """`--manifest`: its one flight's telemetry file as FLIGHT and its `result` unless --result is given."""
    if not getattr(args, "manifest", None):
        if args.flight and not args.result:
            _result_as_flight(args.flight)
        if not args.flight or not args.result:
            raise ValueError("impact needs FLIGHT and --result RESULT.json (or --manifest FLIGHTS.toml)")
        return
    if args.flight:
        raise ValueError(f"--manifest {args.manifest} names the flight: leave out FLIGHT")
    from casep.workflows.manifest import read_manifest

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


def _result_as_flight(path: str) -> None:
    """FLIGHT given a result JSON (and no --result): an error saying so, with the usage (the result's own flight files,
    from its provenance, when it names them)."""
    from pathlib import Path

    from casep.io.result_json import load_json, looks_like_result

    if Path(path).suffix.lower() != ".json":
        return
    try:
        data = load_json(path, "FLIGHT")
    except ValueError:
        return  # not JSON: read as a flight, which says what is wrong with it
    if not looks_like_result(data):
        return
    prov = data.get("provenance") if isinstance(data.get("provenance"), dict) else {}
    roles = {i.get("role"): i.get("file") for i in prov.get("inputs") or () if isinstance(i, dict)}
    flight = roles.get("flight") or roles.get("telemetry") or "FLIGHT"
    tracking = f" --tracking {roles['tracking']}" if roles.get("tracking") and roles.get("telemetry") else ""
    raise ValueError(f"{path} is a result JSON, not a flight file: impact applies a result to the flight it was "
                     f"estimated on. Use: casep impact {flight}{tracking} --result {path}")


def _per_flight(items: list[str] | None) -> dict[str, float]:
    """`--per-flight NAME=VALUE ...` -> {name: value}."""
    values: dict[str, float] = {}
    for item in items or ():
        name, eq, value = item.partition("=")
        try:
            values[name.strip()] = float(value)
        except ValueError:
            raise ValueError(f"--per-flight {item}: give NAME=VALUE (natural units)") from None
        if not eq or not math.isfinite(values[name.strip()]):
            raise ValueError(f"--per-flight {item}: give NAME=VALUE with a finite value (natural units)")
    return values


def run(args: argparse.Namespace) -> int:
    from casep.impact.miss import impact_analysis
    from casep.io.trajectory import read_trajectory

    _manifest(args)  # --manifest: the flight's file and result
    outputs.check({"--json": args.json}, inputs.input_files(args, "flight", "tracking", "result", "trajectory"),
                  {"--figures": args.figures})
    per_flight = _per_flight(args.per_flight)
    if args.tracking or getattr(args, "manifest_obj", None) is not None:  # telemetry + tracking (options or manifest)
        flight = inputs.read_one(args)
    else:
        inputs.frame_options(args)  # --tracking-frame / --launch-site without --tracking: an error
        flight = read_trajectory(args.flight)  # dv unused (a radar-tracked telemetry file has none)
    other = read_trajectory(args.trajectory) if args.trajectory else None
    a = impact_analysis(flight, args.result, args.model, other, per_flight=per_flight or None)
    if args.json:
        outputs.write_json(a.to_dict(), args.json)
    print(a.text(top=args.top))
    if args.figures:
        from casep.reporting.plots import impact_figures

        print(f"figures: {', '.join(str(f) for f in impact_figures(a, args.figures))}")
    if args.json:
        print(f"impact written to {args.json}")
    return 0 if a.success else 1

"""``casep noise FLIGHT``: Allan deviation of the residuals and the noise model (casep.workflows.noise_report)."""

from __future__ import annotations

import argparse
from typing import Any

from casep.cli import flight_options, inputs, options, outputs


def add_parser(sub: Any) -> None:
    p = sub.add_parser("noise", help="Allan deviation of the residuals: white, Gauss-Markov or random-walk noise")
    p.add_argument("flight", nargs="?", help="flight file (or telemetry file with --tracking)")
    flight_options.add_tracking(p, "tracking file (two-file input)")
    flight_options.add_grid(p)
    flight_options.add_frames(p)  # --tracking-frame, --launch-site, --launch-time
    options.add_model(p)
    options.add_json(p, "the Allan deviation and the fits")
    p.add_argument("--figures", metavar="DIR", default=None, help="write allan.png into DIR (created)")


def run(args: argparse.Namespace) -> int:
    from casep.model.loader import load_model
    from casep.workflows.noise_report import flight_noise

    inputs.use_manifest(args)  # --manifest FLIGHTS.toml (one flight), or the flight file
    outputs.check({"--json": args.json}, inputs.input_files(args, "flight", "tracking"), {"--figures": args.figures})
    model = load_model(flight_options.flight_model(args))  # the default model: separate's
    noise, problem = flight_noise(inputs.read_one(args), model)
    print(f"model {model.name}, {problem.source}")
    print(noise.text())
    if args.json:
        outputs.write_json({"model": model.name, "source": problem.source, **noise.to_dict()}, args.json)
        print(f"written to {args.json}")
    if args.figures:
        from casep.reporting.plots import plot_allan

        print(f"figure: {plot_allan(noise, outputs.folder(args.figures) / 'allan.png')}")
    return 0

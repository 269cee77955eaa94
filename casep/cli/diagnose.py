"""``casep diagnose FLIGHT [...]``: what the flight can and cannot determine (several flights; radar)."""

from __future__ import annotations

import argparse
from typing import Any

from casep._version import __version__
from casep.cli import flight_options, inputs, options, outputs
from casep.cli.radar import radar_only
from casep.cli.types import ranged, rule_type
from casep.estimators.registry import OPTIONS, Interval


def add_parser(sub: Any) -> None:
    from casep.noise.model import NOISE_KINDS

    p = sub.add_parser("diagnose", help="what the flight can and cannot determine")
    p.add_argument("flight", nargs="*", help="flight file; several: what each determines alone and jointly")
    flight_options.add_tracking(p, "tracking file (two-file input); several flights: once per flight, in their order")
    flight_options.add_grid(p)
    flight_options.add_frames(p)
    flight_options.add_radar(p)
    options.add_model(p)
    p.add_argument("--sigma", type=ranged("sigma"), default=None, help="noise std, m/s (default: estimated)")
    numbers = [r for r in OPTIONS["tau"].rules if isinstance(r, Interval)]
    p.add_argument("--tau", type=rule_type(OPTIONS["tau"], numbers), default=None, metavar="SECONDS",
                   help="Gauss-Markov correlation time, s: AR(1) bound instead of white; "
                        + " | ".join(str(r) for r in numbers))
    p.add_argument("--noise", choices=NOISE_KINDS, default="auto",
                   help="noise model of the bound, fitted to the residuals as separate does (default auto: white, "
                        "Gauss-Markov or Gauss-Markov plus white per axis by likelihood-ratio tests); --sigma or "
                        "--tau fix it instead")
    p.add_argument("--prior", metavar="FILE", help="prior JSON (map format, or a result JSON: its estimate and "
                   "covariance): Bayesian bound and scales")
    p.add_argument("--scales", metavar="FILE", help='JSON {"Kg0x": typical magnitude, ...} for the "weak" verdict')
    options.add_json(p, "the diagnostics JSON")
    p.add_argument("--figures", metavar="DIR", default=None,
                   help="write singular_values.png and variance_decomposition.png here")


def run(args: argparse.Namespace) -> int:
    flight_options.flight_model(args)  # the default model: separate's
    if args.radar:
        from casep.cli.radar import diagnose_radar

        return diagnose_radar(args)
    radar_only(args, ("tracking_model",))
    inputs.use_manifest(args)  # --manifest FLIGHTS.toml, or the flight files
    outputs.check({"--json": args.json}, inputs.input_files(args, "flight", "tracking", "prior", "scales"),
                  {"--figures": args.figures})
    from casep.estimators.map import parse_prior, prior_information
    from casep.model.loader import load_model
    from casep.workflows.coefficients import read_scales

    model = load_model(args.model)
    prior = inputs.coefficient_file(args, "prior", model.names, fitted=True)
    prior_std = None if prior is None else parse_prior(prior, model.names)[1]
    prior_rows = None if prior is None or "correlation" not in prior else prior_information(prior, model.names)[0]
    scales = read_scales(args.scales, model.names) if args.scales else None
    if len(args.flight) > 1:
        from casep.cli.separate_flights import diagnose_flights

        return diagnose_flights(args, model, prior, scales)
    args.flight = args.flight[0]
    flight = inputs.read_one(args)
    from casep.checks.diagnostics import diagnose, diagnose_noise
    from casep.checks.flight import flight_problem

    problem = flight_problem(flight, model, bound=True)  # S_V never whole (white bound)
    kw: dict[str, Any] = {"prior_std": prior_std, "prior_information": prior_rows,
                          "scales": model.scales if scales is None else scales}
    if args.sigma is not None or args.tau is not None:
        diag = diagnose(problem, sigma=args.sigma, tau=args.tau, **kw)
    else:  # the noise model separate fits by default
        diag = diagnose_noise(problem, args.noise, **kw)
    from casep.checks.tracking_quality import imu_noise_beside_bound

    beside = None if problem.t is None else imu_noise_beside_bound(flight, problem.t)
    if args.json:
        outputs.write_json({"casep_version": __version__, "model": model.name, "n_samples": flight.n_observed,
                            "diagnostics": diag.to_dict(), "imu_noise_not_in_bound": beside,
                            "provenance": outputs.provenance(args, [flight])},
                           args.json)
    print(f"model {model.name}, {flight.n_observed} samples")
    print(diag.text())
    if beside:
        print(beside)
    if args.figures:
        from casep.reporting.plots import plot_singular_values, plot_variance_decomposition

        folder = outputs.folder(args.figures)  # like demo --out
        a = plot_singular_values(diag, folder / "singular_values.png")
        b = plot_variance_decomposition(diag, folder / "variance_decomposition.png")
        print(f"figures: {a}, {b}")
    if args.json:
        print(f"diagnostics written to {args.json}")
    return 0

"""``casep design``: the attitude manoeuvre that minimises the Cramer-Rao bound (casep.design).

Output: docs/reference/file-formats.md, "Design JSON".
"""

from __future__ import annotations

import argparse
import math
from typing import Any

from casep.cli import flight_options, inputs, outputs
from casep.cli.types import order, rate


def add_parser(sub: Any) -> None:
    from casep.simulation.scenarios import SCENARIOS

    p = sub.add_parser("design", help="the attitude manoeuvre that minimises the Cramer-Rao bound (IPOPT)")
    p.add_argument("--scenario", default="paper", choices=list(SCENARIOS), help="nominal flight (default paper)")
    p.add_argument("--maneuver", default="yaw", choices=("yaw", "pitch", "both"),
                   help="attitude axes the manoeuvre moves (default yaw)")
    p.add_argument("--objective", default="A", choices=("A", "D", "miss"),
                   help="A: trace of the covariance scaled by the declared magnitudes; D: its log det; miss: "
                        "variance of the nominal trajectory's predicted impact miss (default A)")
    p.add_argument("--max-angle", type=float, default=5.0, metavar="DEG",
                   help="largest offset from the nominal attitude, deg (default 5)")
    p.add_argument("--max-rate", type=float, default=2.0, metavar="DEG_PER_S",
                   help="largest offset rate, deg/s (default 2)")
    p.add_argument("--max-lateral", type=float, default=1.0, metavar="G",
                   help="largest lateral specific force, norm(f) sin(offset), g (default 1)")
    p.add_argument("--coefficients", metavar="NAMES", default=None,
                   help="comma-separated coefficients that matter: objective A over these only (default all)")
    p.add_argument("--knots", type=int, default=10, help="knots of the piecewise-linear offset (default 10)")
    p.add_argument("--starts", type=int, default=4, help="IPOPT starts (default 4)")
    p.add_argument("--seed", type=order, default=0, help="seed of the random starts and of -o's noise (default 0)")
    p.add_argument("--rate", type=rate, default=None, help="sample rate, Hz (default: scenario's)")
    p.add_argument("--prior", metavar="FILE", default=None,
                   help='prior JSON {"Kg0x": {"mean": m, "std": s}, ...} (natural units): Bayesian covariance')
    p.add_argument("--json", metavar="OUT", default=None, help="write the design JSON here")
    p.add_argument("--figure", metavar="PNG", default=None, help="write the manoeuvre and CRLB before/after here")
    p.add_argument("-o", "--output", metavar="FLIGHT", default=None,
                   help="simulate the designed flight into this flight file (truth in <stem>.truth.json)")
    flight_options.add_own_trajectory(p)


def _check_limits(args: argparse.Namespace) -> None:
    """The limits, checked before the outputs and named by their flags. design() checks them too, naming its
    keywords (`max_angle`); this check is here so that the message names the option the user typed."""
    for flag, v, hi in (("--max-angle", args.max_angle, 45.0), ("--max-rate", args.max_rate, math.inf),
                        ("--max-lateral", args.max_lateral, math.inf)):
        if not (math.isfinite(v) and 0 < v <= hi):
            raise ValueError(f"{flag} must be > 0" + (f" and <= {hi:g}" if math.isfinite(hi) else "") + f", got {v:g}")


def run(args: argparse.Namespace) -> int:
    from casep.design.flown import design_lines
    from casep.design.optimize import design
    from casep.model.loader import load_model
    from casep.simulation.scenarios import get_scenario
    from casep.simulation.simulate import truth_path

    _check_limits(args)
    files = {"--json": args.json, "--figure": args.figure}
    if args.output:
        files.update({"-o": args.output, "-o (truth sidecar)": str(truth_path(args.output))})
    outputs.check(files, inputs.input_files(args, "prior", "flight", "truth"))
    own_flight, own_truth, own_model = inputs.own_trajectory(args)  # --flight FILE --truth TRUTH.json
    if own_flight and args.output:
        raise ValueError("-o simulates the designed flight of a scenario's vehicle; with --flight there is none")
    own_noise = own_truth.get("noise") if own_truth else None
    prior = inputs.coefficient_file(args, "prior", load_model(own_model or get_scenario(args.scenario).model).names)
    coefficients = None if args.coefficients is None else [c.strip() for c in args.coefficients.split(",")
                                                          if c.strip()]
    res = design(args.scenario, maneuver=args.maneuver, objective=args.objective, max_angle=args.max_angle,
                 max_rate=args.max_rate, max_lateral=args.max_lateral, prior=prior, knots=args.knots,
                 starts=args.starts, seed=args.seed, rate=None if own_flight else args.rate, coefficients=coefficients,
                 flight=own_flight, model=own_model,
                 sigma=own_noise.get("sigma") if isinstance(own_noise, dict) else None)
    for line in design_lines(res, scenario=args.scenario, maneuver=args.maneuver, own_flight=own_flight):
        print(line)
    if args.json:
        outputs.write_json(res.to_dict(), args.json)
        print(f"design written to {args.json}")
    if args.figure:
        from casep.reporting.plots import plot_design

        print(f"figure written to {plot_design(res, args.figure)}")
    if args.output:
        from casep.simulation.simulate import simulate_flight, write_simulation

        flight_path, side = write_simulation(simulate_flight(res.scenario, seed=args.seed), args.output)
        print(f"designed flight written to {flight_path} and {side}")
    return outputs.status(res)  # 1, the message on stderr, when the optimiser did not converge

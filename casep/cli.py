"""Command line: ``casep separate``, ``casep simulate``, ``casep models``. Thin wrappers over
the public API.

Exit status: 0 success, 2 bad usage or bad input (one line on stderr), 1 anything else.
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Sequence

from . import __version__
from .flight import FlightDataError
from .model import ModelDefinitionError
from .bounded import parse_bounds
from .denoise import EXTENSIONS, MODES, RULES, SCALINGS
from .map_estimator import parse_prior
from .model_loader import available_models, load_model
from .result import write_json_atomic
from .flight_io import read_flight, read_flight_pair
from .scenarios import SCENARIOS
from .separate import METHODS, separate
from .simulate import simulate_flight, write_simulation

__all__ = ["main"]


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line, exit 2
        self.exit(2, f"{self.prog}: error: {message}\n")


def _positive_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not v > 0 or v == float("inf"):
        raise argparse.ArgumentTypeError(f"must be finite and > 0, got {text}")
    return v


def _lambda(text: str) -> float | str:
    if text in ("gcv", "lcurve"):
        return text
    v = _positive_float(text)
    return v


def _forgetting(text: str) -> float:
    v = _positive_float(text)
    if v > 1:
        raise argparse.ArgumentTypeError(f"must be in (0, 1], got {text}")
    return v


def _order(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if v < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {text}")
    return v


def _load_json(path: str, option: str) -> dict:
    try:
        with open(path, encoding="utf-8") as fh:
            data = json.load(fh)
    except OSError as exc:
        raise ValueError(f"{option} {path}: cannot read ({exc.strerror})") from None
    except json.JSONDecodeError as exc:
        raise ValueError(f"{option} {path}: not valid JSON (line {exc.lineno}: {exc.msg})") from None
    if not isinstance(data, dict):
        raise ValueError(f"{option} {path}: must hold a JSON object keyed by coefficient name")
    return data


def _parser() -> argparse.ArgumentParser:
    p = _Parser(prog="casep", description="Guidance instrumentation error separation.")
    p.add_argument("--version", action="version", version=f"casep {__version__}")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)
    s = sub.add_parser("separate", help="estimate the error coefficients of a flight file")
    s.add_argument("flight", help="flight CSV file (t, f_x.., dv_x.. or v_tel_x.., v_trk_x..)")
    s.add_argument("--model", default="platform36", help="model name or .py file (default platform36)")
    s.add_argument("--method", default="ols", choices=METHODS, help="estimator (default ols)")
    s.add_argument("--sigma", type=_positive_float, default=None,
                   help="noise std, m/s (default: estimated from the residuals)")
    s.add_argument("--p0", type=_positive_float, default=1e6, help="RLS/RELS P0 = p0 I, natural units (default 1e6)")
    s.add_argument("--weight", type=_positive_float, default=1.0, help="RLS/RELS weight w (default 1)")
    s.add_argument("--forgetting", type=_forgetting, default=1.0, help="RLS/RELS forgetting factor (default 1)")
    s.add_argument("--noise-order", type=_order, default=1, help="RELS noise-model order (default 1)")
    s.add_argument("--lambda", dest="lam", type=_lambda, default="gcv", metavar="gcv|lcurve|VALUE",
                   help="ridge parameter for unit-norm columns, or its rule (default gcv)")
    s.add_argument("--bounds", metavar="FILE", help='bounded: JSON {"Kg0x": [lo, hi] or value, ...}, natural units')
    s.add_argument("--prior", metavar="FILE", help='map: JSON {"Kg0x": {"mean": m, "std": s}, ...}, natural units')
    s.add_argument("--components", type=_order, default=None, help="pcr: number of components to keep")
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
    s.add_argument("--tracking", metavar="FILE", default=None,
                   help="tracking file (t, v_trk_*) at its own rate; FLIGHT is then the telemetry file "
                        "(t, f_* or W_*, v_tel_*)")
    g = sub.add_parser("simulate", help="simulate a boost flight with injected errors")
    g.add_argument("--scenario", default="paper", choices=list(SCENARIOS), help="scenario (default paper)")
    g.add_argument("--seed", type=int, default=0, help="noise seed (default 0)")
    g.add_argument("--rate", type=_positive_float, default=None, help="sample rate, Hz (default: scenario's)")
    g.add_argument("-o", "--output", required=True, metavar="FILE",
                   help="flight file (.csv, or .parquet); truth goes to <stem>.truth.json beside it")
    m = sub.add_parser("models", help="list the available error models")
    m.add_argument("--verbose", "-v", action="store_true", help="list each model's coefficients")
    return p


def _cmd_separate(args: argparse.Namespace) -> int:
    model = load_model(args.model)
    bounds = prior = None
    if args.bounds:
        bounds = _load_json(args.bounds, "--bounds")
        parse_bounds(bounds, model.names, source=f"--bounds {args.bounds}")
    if args.prior:
        prior = _load_json(args.prior, "--prior")
        parse_prior(prior, model.names, source=f"--prior {args.prior}")
    if args.method == "rels" and args.noise_order < 1:
        raise ValueError(f"--noise-order must be >= 1 for rels, got {args.noise_order}")
    wopts = {k: v for k, v in (("wavelet", args.wavelet), ("level", args.level), ("rule", args.threshold_rule),
                                ("mode", args.threshold_mode), ("extension", args.extension),
                                ("scaling", args.noise_scaling)) if v is not None}
    if wopts and args.denoise != "wavelet":
        raise ValueError(f"wavelet options ({', '.join(wopts)}) need --denoise wavelet")
    flight = read_flight_pair(args.flight, args.tracking) if args.tracking else read_flight(args.flight)
    res = separate(flight, model, args.method, sigma=args.sigma, p0=args.p0, weight=args.weight,
                   forgetting=args.forgetting, noise_order=args.noise_order, lam=args.lam, bounds=bounds,
                   prior=prior, n_components=args.components, denoise=args.denoise,
                   wavelet_options=wopts or None)
    if args.json:
        write_json_atomic(res.to_dict(), args.json)
    print(res.table())
    if args.json:
        print(f"result written to {args.json}")
    return 0


def _cmd_simulate(args: argparse.Namespace) -> int:
    if args.seed < 0:
        raise ValueError(f"`--seed` must be >= 0, got {args.seed}")
    sim = simulate_flight(args.scenario, seed=args.seed, rate=args.rate)
    flight_path, side = write_simulation(sim, args.output)
    s = sim.trajectory.summary()
    print(f"scenario {sim.scenario.name}: {sim.flight.n_samples} samples at {sim.scenario.rate:g} Hz, "
          f"{s['duration_s']:.1f} s powered flight")
    print(f"lift-off {s['liftoff_specific_force_g']:.2f} g, max {s['max_specific_force_g']:.2f} g; burnout "
          f"{s['burnout_speed_m_s'] / 1e3:.2f} km/s at {s['burnout_altitude_m'] / 1e3:.0f} km, "
          f"flight-path angle {s['burnout_flight_path_deg']:.1f} deg")
    print(f"wrote {flight_path} and {side}")
    return 0


def _cmd_models(args: argparse.Namespace) -> int:
    for name in available_models():
        model = load_model(name)
        print(f"{name:<28} {model.n_coefficients:>3} coefficients  {model.description}")
        if args.verbose:
            for nm, unit in zip(model.names, model.units):
                print(f"    {nm:<10} {unit}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status."""
    args = _parser().parse_args(argv)
    try:
        return {"separate": _cmd_separate, "simulate": _cmd_simulate, "models": _cmd_models}[args.command](args)
    except (FlightDataError, ModelDefinitionError, ValueError, TypeError, OSError) as exc:
        print(f"casep: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())

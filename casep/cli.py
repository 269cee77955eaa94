"""Command line: ``casep separate``, ``casep models``. Thin wrappers over the public API.

Exit status: 0 success, 2 bad usage or bad input (one line on stderr), 1 anything else.
"""

from __future__ import annotations

import argparse
import sys
from typing import Sequence

from . import __version__
from .flight import FlightDataError
from .model import ModelDefinitionError
from .model_loader import available_models, load_model
from .result import write_json_atomic
from .separate import METHODS, separate

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
    s.add_argument("--json", metavar="OUT", default=None, help="write the result JSON here")
    m = sub.add_parser("models", help="list the available error models")
    m.add_argument("--verbose", "-v", action="store_true", help="list each model's coefficients")
    return p


def _cmd_separate(args: argparse.Namespace) -> int:
    res = separate(args.flight, args.model, args.method, sigma=args.sigma)
    if args.json:
        write_json_atomic(res.to_dict(), args.json)
    print(res.table())
    if args.json:
        print(f"result written to {args.json}")
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
        return {"separate": _cmd_separate, "models": _cmd_models}[args.command](args)
    except (FlightDataError, ModelDefinitionError, ValueError, TypeError, OSError) as exc:
        print(f"casep: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())

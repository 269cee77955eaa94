"""Shared argument groups: the method options (generated from the estimator registry), the noise model, the
sensors' full scales.

Flag, help, default and rule of a method option come from :data:`casep.estimators.registry.OPTIONS`;
the argparse type is the option's :meth:`~casep.estimators.registry.Option.parse`.
"""

from __future__ import annotations

import argparse
from typing import Any, Callable

from casep.cli.types import metavar, rule_type
from casep.estimators.registry import METHODS, NOISE_OPTIONS, OPTIONS, Option

__all__ = ["add_option", "method_option_groups", "add_noise", "add_model", "add_json", "method_options",
           "fit_spec"]


def option_help(option: Option, default: str | None = None) -> str:
    """Help of a registry option: its help, rule and default (or which methods need it)."""
    required = [m for m, meth in METHODS.items() if option.name in meth.required]
    d = option.default
    if default is None and (d is not None or required):
        default = (f"needed by --method {' and '.join(required)}" if d is None
                   else f"default {d:g}" if isinstance(d, float) else f"default {d}")
    return f"{option.help}; {option.rule}" + (f" ({default})" if default else "")


def per_axis_type(option: Option) -> Callable[[str], Any]:
    """Argparse type of an option given for all axes or per axis (``--tau 1,2,0.5``): one value by the option's
    rules (:func:`rule_type`); three comma-separated ones as a tuple of numbers (a part that is no number kept as
    written), checked with the fit request, whose refusal names the axis (:class:`casep.FitSpec`)."""
    one = rule_type(option)

    def number(part: str) -> Any:
        try:
            return float(part)
        except ValueError:
            return part.strip()

    def parse(text: str) -> Any:
        if "," not in text:
            return one(text)
        return tuple(number(part) for part in text.split(","))

    parse.__name__ = option.name
    return parse


def add_option(group: Any, option: Option, default: str | None = None) -> None:
    """The argument of a registry option (dest: its name; None when not given)."""
    if option.name in NOISE_OPTIONS:  # the noise model's too (tau): one value, or one per axis
        group.add_argument(option.flag, dest=option.name, type=per_axis_type(option), default=None,
                           metavar=metavar(option) + "|X,Y,Z",
                           help=option_help(option, default) + "; X,Y,Z: one per axis (the noise model's, every "
                                "method but those taking one tau)")
        return
    group.add_argument(option.flag, dest=option.name, type=rule_type(option), default=None,
                       metavar=metavar(option), help=option_help(option, default))


def method_option_groups(parser: argparse.ArgumentParser) -> None:
    """One argument group per set of methods taking the same options, generated from the registry.

    Options shared by several methods (RLS and RELS) are in one group titled by all of them
    (``rls / rels options``).
    """
    groups: dict[tuple[str, ...], list[str]] = {}
    for name in OPTIONS:
        takers = tuple(m for m, meth in METHODS.items() if name in meth.options)
        groups.setdefault(takers, []).append(name)
    for takers, names in groups.items():
        g = parser.add_argument_group(f"{' / '.join(takers) or 'unused'} options")
        for name in names:
            add_option(g, OPTIONS[name])


def method_options(args: argparse.Namespace) -> dict[str, Any]:
    """The registry options given on the command line (files: their names)."""
    return {k: getattr(args, k) for k in OPTIONS if getattr(args, k, None) is not None}


def add_noise(parser: Any, *, outputs: bool = True, default: str = "auto") -> None:
    """The noise-model options every method takes (casep.noise.model, casep.estimators.solve)."""
    from casep.estimators.spec import ROBUST_CHOICES, STD_CHOICES  # the fit request's choices, one list each
    from casep.noise.model import NOISE_HELP, NOISE_KINDS

    g = parser.add_argument_group("noise model (every method)")
    g.add_argument("--noise", choices=NOISE_KINDS, default=default,
                   help=f"tracking noise (default {default}): {NOISE_HELP}")
    g.add_argument("--robust", nargs="?", const="huber", choices=ROBUST_CHOICES,
                   default="auto",
                   help="robust fit for any method: glitches removed by a robust filter on the innovations, the rest "
                        "weighted; --robust alone: huber; auto (default): huber when the filter finds more glitches "
                        "than Gaussian noise explains (said in the output); none: never")
    if outputs:
        g.add_argument("--std", choices=STD_CHOICES, default="model",
                       help="model (default) or hac: Newey-West std of a white-noise ols fit")
        g.add_argument("--exclude-outliers", type=float, nargs="?", const=0.01, default=None, metavar="ALPHA",
                       help="remove the samples whose studentized residual (whitened rows) is flagged at "
                            "family-wise chance ALPHA (default 0.01) and fit again; removed samples listed")


#: The command line's options that make the fit request (besides every method option of the registry).
FIT_DESTS = ("method", "sigma", "denoise", "wavelet", "level", "threshold_rule", "threshold_mode", "extension",
             "noise_scaling", "outliers", "noise", "robust", "std", "exclude_outliers")


def fit_spec(args: argparse.Namespace, given: dict[str, Any], **fit: Any) -> Any:
    """The :class:`casep.FitSpec` of the command line: --method, its options (`given`), the noise options and
    `fit` (sigma, de-noising, outlier flags), checked once (:meth:`casep.FitSpec.build`).

    With ``--manifest`` whose ``[fit]`` table holds the request, that request (built when the manifest was
    read, :meth:`casep.workflows.manifest.Manifest.spec`); an option of the fit given on the command line too is
    then an error, whatever its value. Its prior or bounds file becomes ``--prior``/``--bounds`` (read as
    those are)."""
    from casep.estimators.spec import FitSpec

    man = getattr(args, "manifest_obj", None)
    if man is not None and man.spec() is not None:
        on_line = sorted(set(getattr(args, "given", ())) & {*FIT_DESTS, *OPTIONS})
        if on_line:
            flags = ", ".join(OPTIONS[d].flag if d in OPTIONS else "--" + d.replace("_", "-") for d in on_line)
            raise ValueError(f"--manifest {args.manifest} holds the fit request (its [fit] table): leave out "
                             f"{flags}, or the [fit] table")
        spec = man.spec()
        for key in ("prior", "bounds"):
            if isinstance(spec.options.get(key), str):
                setattr(args, key, spec.options[key])  # read and checked as --prior/--bounds are
        return spec

    kw = {"noise": args.noise, "robust": args.robust}
    for k in ("std", "exclude_outliers"):
        if getattr(args, k, None) is not None:
            kw[k] = getattr(args, k)
    return FitSpec.build(args.method, options=given, **kw, **fit)


def add_model(parser: Any, default: str | None = None,
              what: str = "default: the simulated model, strapdown42_extended (strapdown), platform36") -> None:
    """``--model NAME|FILE``; a flight command's default is None, resolved by
    :func:`casep.cli.flight_options.flight_model`."""
    parser.add_argument("--model", default=default, help=f"model name or .py file ({what})")


def add_json(parser: Any, what: str) -> None:
    """``--json OUT``."""
    parser.add_argument("--json", metavar="OUT", default=None, help=f"write {what} here")

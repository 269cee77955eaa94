"""Argparse types of the command line: each parses one string or raises ``ArgumentTypeError`` naming the rule.

Only the standard library and the estimator registry are imported at module level (``casep --help``
stays cheap); a type that needs more imports it when it parses.
"""

from __future__ import annotations

import argparse
import math
from typing import Any, Callable

from casep.estimators.registry import CoefficientTable, Interval, Option, option_label

__all__ = ["positive_float", "finite_float", "order", "positive_int", "rate", "ranged", "time_offset", "rule_type",
           "metavar", "choice_refusal"]


def _number(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None


def positive_float(text: str) -> float:
    """A finite number > 0."""
    v = _number(text)
    if not v > 0 or v == float("inf"):
        raise argparse.ArgumentTypeError(f"must be finite and > 0, got {text}")
    return v


def finite_float(text: str) -> float:
    """A finite number."""
    v = _number(text)
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"must be finite, got {text}")
    return v


def order(text: str) -> int:
    """An integer >= 0."""
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if v < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {text}")
    return v


def positive_int(text: str) -> int:
    """An integer >= 1."""
    v = order(text)
    if v < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1, got {text}")
    return v


def rate(text: str) -> float:
    """A sample rate, Hz: (0, casep.simulation.scenarios.MAX_RATE_HZ]."""
    from casep.simulation.scenarios import check_rate

    v = positive_float(text)
    try:
        return check_rate(v, "rate")
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc).removeprefix("rate ")) from None


def ranged(name: str) -> Callable[[str], float]:
    """Argparse type of the common option `name` (``sigma``): the estimators' own check and message."""

    def parse(text: str) -> float:
        from casep.estimators._base import check_positive

        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{option_label(name)} must be a number, got {text!r}") from None
        try:
            checked = check_positive(name, v, allow_none=False)
            return v if checked is None else checked
        except ValueError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None

    parse.__name__ = name
    return parse


def time_offset(text: str) -> float | str:
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


def choice_refusal(action: argparse.Action, value: Any) -> str:
    """A value outside an option's choices, in the one form of a refused option
    (:func:`casep.exceptions.refusal`): ``option --robust (`robust`) must be auto | none | ..., got 'x'``."""
    from casep.exceptions import refusal

    flag = max(action.option_strings, key=len)
    return str(refusal(action.dest, flag, " | ".join(map(str, action.choices or ())), value))


def rule_type(option: Option, rules: Any = None) -> Callable[[str], Any]:
    """Argparse type of a registry option: :meth:`Option.parse`, so a bad value is an error stating the rule.

    `rules` restricts the option to some of its rules (``diagnose --tau`` takes a number only).
    """
    opt = option if rules is None else Option(option.name, option.flag, option.default, rules, option.help)

    def parse(text: str) -> Any:
        try:
            return opt.parse(text)
        except ValueError as exc:  # "option --p0 (`p0`) must be ...": the one form (Parser.error prints it alone)
            raise argparse.ArgumentTypeError(str(exc)) from None

    parse.__name__ = option.name  # argparse names the type in some messages
    return parse


def metavar(option: Option) -> str:
    """``gcv|lcurve|VALUE``, ``INT``, ``FILE``: what the rules take, for the usage line."""
    words: list[str] = []
    for r in option.rules:
        if isinstance(r, CoefficientTable):
            words.append("FILE")
        elif isinstance(r, Interval):
            words.append("INT" if r.kind is int else "VALUE")
        else:
            words.extend(getattr(r, "values", ()))
    return "|".join(words)

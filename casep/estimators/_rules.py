"""The rules an option value must satisfy, and the option itself (scikit-learn's ``_parameter_constraints``).

:class:`Option` declares one option of a method (keyword, command-line flag, default, rules, help, why
its range is what it is); its rules are :class:`Interval`, :class:`Choices` and
:class:`CoefficientTable`. :data:`SIGMA` is the noise std every method takes. The methods' declarations
(:mod:`casep.estimators._options`) and the solvers' shared checks (:mod:`casep.estimators._base`) use these.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from casep.exceptions import option_label, refusal

__all__ = ["Rule", "Interval", "Choices", "CoefficientTable", "Option", "SIGMA", "option_label", "refusal"]



class Rule:
    """A declared rule an option value must satisfy.

    ``accepts(value)`` for Python values; ``parse(text)`` for command-line text (ValueError if
    the text is not of the rule's kind); ``str(rule)`` is how the rule reads in messages and
    ``casep methods``.
    """

    def accepts(self, value: Any) -> bool:  # pragma: no cover - interface
        raise NotImplementedError

    def parse(self, text: str) -> Any:  # pragma: no cover - interface
        raise NotImplementedError


@dataclass(frozen=True)
class Interval(Rule):
    """A finite int or float in an interval; ``closed`` in {"both", "left", "right", "neither"}."""

    kind: type
    low: float | None
    high: float | None = None
    closed: str = "both"
    unit: str = ""

    @property
    def low_closed(self) -> bool:
        return self.closed in ("both", "left")

    @property
    def high_closed(self) -> bool:
        return self.closed in ("both", "right")

    def is_number(self, value: Any) -> bool:
        """Of the rule's kind (an int for an int rule; bool is neither)."""
        if isinstance(value, (bool, np.bool_)):
            return False
        return isinstance(value, (int, np.integer)) if self.kind is int else \
            isinstance(value, (int, float, np.integer, np.floating))

    def accepts(self, value: Any) -> bool:
        if not self.is_number(value):
            return False
        v = float(value)
        if not math.isfinite(v):
            return False
        lo_ok = self.low is None or (v >= self.low if self.low_closed else v > self.low)
        hi_ok = self.high is None or (v <= self.high if self.high_closed else v < self.high)
        return lo_ok and hi_ok

    def parse(self, text: str) -> Any:
        try:
            return int(text) if self.kind is int else float(text)
        except ValueError:
            raise ValueError(f"not {'an integer' if self.kind is int else 'a number'}: {text!r}") from None

    def bounds_text(self) -> str:
        """``(0, 1e+30]`` or ``> 0``."""
        if self.high is None:
            return f"{'>=' if self.low_closed else '>'} {self.low:g}"
        return f"in {'[' if self.low_closed else '('}{self.low:g}, {self.high:g}{']' if self.high_closed else ')'}"

    def __str__(self) -> str:
        unit = f" {self.unit}" if self.unit else ""
        return f"{self.kind.__name__} {self.bounds_text()}{unit}"


@dataclass(frozen=True)
class Choices(Rule):
    """One of a few strings."""

    values: tuple[str, ...]

    def accepts(self, value: Any) -> bool:
        return isinstance(value, str) and value in self.values

    def parse(self, text: str) -> Any:
        if text not in self.values:
            raise ValueError(f"not one of {', '.join(self.values)}: {text!r}")
        return text

    def __str__(self) -> str:
        return " | ".join(self.values)


@dataclass(frozen=True)
class CoefficientTable(Rule):
    """A mapping keyed by coefficient name (in the API) or a JSON file of one (on the command line).

    The entries are checked against the model's coefficients by the solver's parser
    (:func:`casep.estimators.bounded.parse_bounds`, :func:`casep.estimators.map.parse_prior`),
    which is the only place that knows the names.
    """

    form: str

    def accepts(self, value: Any) -> bool:
        return isinstance(value, (Mapping, str, os.PathLike))  # a table, or its JSON file

    def parse(self, text: str) -> Any:
        return text  # a path: the command line reads and checks the file

    def __str__(self) -> str:
        return f"JSON file {self.form}"


@dataclass(frozen=True)
class Option:
    """One method option: keyword, CLI flag, default, rules, help, and why its range is what it is.

    A value is valid when one of `rules` accepts it (``None`` means "the default").
    """

    name: str
    flag: str
    default: Any
    rules: tuple[Rule, ...]
    help: str
    why: str = ""

    @property
    def rule(self) -> str:
        """The rules as text, e.g. ``gcv | lcurve | float > 0``."""
        return " | ".join(str(r) for r in self.rules)

    def refusal(self, value: Any, method: str | None = None) -> ValueError:
        """The one message form of a value the option's rules refuse (a fit request, the command line):
        ``option --lambda (`lam`) of method `ridge` must be gcv | lcurve | float > 0, got 'aic'``."""
        return refusal(self.name, self.flag, self.rule, value, method)

    @property
    def label(self) -> str:
        """How every message of a fit request names the option: ``option --lambda (`lam`)``."""
        return option_label(self.name, self.flag)

    def validate(self, value: Any, method: str | None = None) -> Any:
        """`value` if a rule accepts it, else ValueError naming the option (and method): :meth:`refusal`."""
        if value is None or any(r.accepts(value) for r in self.rules):
            return value
        raise self.refusal(value, method)

    def check(self, value: Any) -> Any:
        """The API's check of a value (the public ``solve_*`` functions): `value` (a float for a float
        rule) if a rule accepts it, else an error naming the option, its range and why."""
        if value is None or any(r.accepts(value) for r in self.rules if not isinstance(r, Interval)):
            return value
        intervals = [r for r in self.rules if isinstance(r, Interval)]
        if not intervals:
            raise ValueError(f"{self.label} must be {self.rule}, got {value!r}")
        iv = intervals[0]
        if iv.accepts(value):
            return int(value) if iv.kind is int else float(value)
        choices = [c for r in self.rules if isinstance(r, Choices) for c in r.values]
        if iv.kind is int:
            raise ValueError(f"{self.label} must be an int {iv.bounds_text()}, got {value!r}")
        if choices and not iv.is_number(value):
            quoted = [f"'{c}'" for c in choices]
            listed = quoted[0] if len(quoted) == 1 else ", ".join(quoted[:-1]) + " or " + quoted[-1]
            sep = ", " if len(quoted) > 1 else " or "
            num = "> 0" if iv.low == 0 and not iv.low_closed else iv.bounds_text()
            raise ValueError(f"{self.label} must be a number {num}{sep}{listed}, got {value!r}")
        if not iv.is_number(value):
            raise TypeError(f"{self.label} must be a number, got {type(value).__name__}")
        v = float(value)
        if iv.low is not None and iv.low >= 0 and not (math.isfinite(v) and v > 0):  # a positive quantity
            raise ValueError(f"{self.label} must be finite and > 0, got {value}")
        why = f" ({self.why})" if self.why else ""
        raise ValueError(f"{self.label} must be {iv.bounds_text()}{why}, got {value}")

    def parse(self, text: str) -> Any:
        """Command-line text -> a valid value (ValueError naming the rule otherwise)."""
        for r in self.rules:
            try:
                v = r.parse(text)
            except ValueError:
                continue
            if r.accepts(v) or isinstance(r, CoefficientTable):
                return v
        raise self.refusal(text)


#: The noise std every method takes (not a method option: a label of the data).
SIGMA = Option("sigma", "--sigma", None, (Interval(float, 0.0, 1e3, "right", "m/s"),),
               "known noise standard deviation, m/s (default: estimated)",
               # A noise std above 1 km/s is a unit mistake (mm/s, ft) or not a velocity at all: the whole powered
               # flight of the paper gains ~3 km/s. (No lower end beyond > 0: a noise-free simulation may state a
               # tiny sigma; the std underflow to 0 only below ~1e-150 m/s.)
               why="m/s; a velocity noise std above 1 km/s is not a tracking noise")

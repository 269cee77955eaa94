"""What a method declares: its options with their rules, its capabilities, its solver and hooks.

Each estimator module declares one :class:`Method` beside its solver (scikit-learn's
``_parameter_constraints`` idea): the options it takes, each with the rules a value must satisfy
(:class:`Interval`, :class:`Choices`, :class:`CoefficientTable`), its capabilities, what its std
mean, its typed extras, its linear map (batched Monte Carlo), the hint a failed result gets and its
hooks for several flights. :mod:`casep.estimators.registry` collects the declarations; the
workflows read nothing else.

Options are checked once, where they enter: :meth:`Method.check_options` (``casep.separate``, the
several-flight path, the command line) or :meth:`Method.call` (the public ``solve_*`` functions);
:meth:`Method.solve` takes them as checked.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Callable, Mapping, Sequence, TypedDict

import numpy as np

from casep.estimators.result import STD_KIND_MEANINGS

if TYPE_CHECKING:
    from casep.analysis.joint import JointProblem
    from casep.analysis.problem import Problem
    from casep.estimators.result import EstimateResult

__all__ = ["Rule", "Interval", "Choices", "CoefficientTable", "Option", "Labels", "Method", "SeveralFlights",
           "SIGMA"]


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

    def validate(self, value: Any, method: str | None = None) -> Any:
        """`value` if a rule accepts it, else ValueError naming the option (and method)."""
        if value is None or any(r.accepts(value) for r in self.rules):
            return value
        of = f" of method `{method}`" if method else ""
        raise ValueError(f"option `{self.name}` ({self.flag}){of} must be {self.rule}, got {value!r}")

    def check(self, value: Any) -> Any:
        """The API's check of a value (the public ``solve_*`` functions): `value` (a float for a float
        rule) if a rule accepts it, else an error naming the option, its range and why."""
        if value is None or any(r.accepts(value) for r in self.rules if not isinstance(r, Interval)):
            return value
        intervals = [r for r in self.rules if isinstance(r, Interval)]
        if not intervals:
            raise ValueError(f"`{self.name}` must be {self.rule}, got {value!r}")
        iv = intervals[0]
        if iv.accepts(value):
            return int(value) if iv.kind is int else float(value)
        choices = [c for r in self.rules if isinstance(r, Choices) for c in r.values]
        if iv.kind is int:
            raise ValueError(f"`{self.name}` must be an int {iv.bounds_text()}, got {value!r}")
        if choices and not iv.is_number(value):
            quoted = [f"'{c}'" for c in choices]
            listed = quoted[0] if len(quoted) == 1 else ", ".join(quoted[:-1]) + " or " + quoted[-1]
            sep = ", " if len(quoted) > 1 else " or "
            num = "> 0" if iv.low == 0 and not iv.low_closed else iv.bounds_text()
            raise ValueError(f"`{self.name}` must be a number {num}{sep}{listed}, got {value!r}")
        if not iv.is_number(value):
            raise TypeError(f"`{self.name}` must be a number, got {type(value).__name__}")
        v = float(value)
        if iv.low is not None and iv.low >= 0 and not (math.isfinite(v) and v > 0):  # a positive quantity
            raise ValueError(f"`{self.name}` must be finite and > 0, got {value}")
        why = f" ({self.why})" if self.why else ""
        raise ValueError(f"`{self.name}` must be {iv.bounds_text()}{why}, got {value}")

    def parse(self, text: str) -> Any:
        """Command-line text -> a valid value (ValueError naming the rule otherwise)."""
        for r in self.rules:
            try:
                v = r.parse(text)
            except ValueError:
                continue
            if r.accepts(v) or isinstance(r, CoefficientTable):
                return v
        raise ValueError(f"{self.flag} must be {self.rule}, got {text!r}")


#: The noise std every method takes (not a method option: a label of the data).
SIGMA = Option("sigma", "--sigma", None, (Interval(float, 0.0, 1e3, "right", "m/s"),),
               "known noise standard deviation, m/s (default: estimated)",
               # A noise std above 1 km/s is a unit mistake (mm/s, ft) or not a velocity at all: the whole powered
               # flight of the paper gains ~3 km/s. (No lower end beyond > 0: a noise-free simulation may state a
               # tiny sigma; the std underflow to 0 only below ~1e-150 m/s.)
               why="m/s; a velocity noise std above 1 km/s is not a tracking noise")


class Labels(TypedDict, total=False):
    """What every public solver takes besides the data and the method's options.

    names, units, si_factors : sequence
        Coefficient labels for the result (default ``c0, c1, ...``; a Problem holds its own).
    sigma : float
        Known noise standard deviation, m/s (default: estimated).
    rcond : float
        Rank threshold, see :func:`casep.analysis.linalg.analyze_rank`.
    """

    names: Sequence[str] | None
    units: Sequence[str] | None
    si_factors: Sequence[float] | np.ndarray | None
    sigma: float | None
    rcond: float | None


@dataclass(frozen=True)
class SeveralFlights:
    """A method's hooks for several flights (:func:`casep.workflows.flights.separate_flights`).

    The flights become one :class:`~casep.analysis.joint.JointProblem`: a reduction-based method
    solves its stacked reduction, a recursive one its rows flight after flight (its ``segments``).

    Attributes
    ----------
    rows : callable, optional
        ``rows(problems, options, noise, robust) -> (problems, state)``: each flight's rows as the
        method solves them (default, None: each flight's own noise model and robust cleaning).
    solve_as : Method, optional
        The method that solves the combined rows (GLS: least squares on AR(1)-whitened flights).
    sigma : float or None
        The joint solve's sigma: 1 for whitened rows; None lets the method estimate its scale (Huber).
    finish : callable, optional
        ``finish(result, joint_problem, state, options) -> result``: the method's own account of the
        joint result (GLS: its per-flight tau; Huber: the flight of each outlier).
    """

    rows: Callable[..., tuple[list[Problem], Any]] | None = None
    solve_as: Method | None = None
    sigma: float | None = 1.0
    finish: Callable[[EstimateResult, JointProblem, Any, Mapping[str, Any]], EstimateResult] | None = None


@dataclass(frozen=True)
class Method:
    """One estimator: its options, capabilities, solver and hooks (module docstring).

    Attributes
    ----------
    name, summary : str
        Registry name and one line for ``casep methods``.
    core : callable
        ``core(prepared, **options) -> EstimateResult`` on a prepared problem
        (:func:`casep.estimators._base.prepare`), options checked and complete.
    public : str
        Name of the public solver function in the method's module (``solve_ols``).
    option_specs : tuple of Option
        The options it takes (keywords of :func:`casep.separate`, flags of ``casep separate``).
    keywords : tuple of Option
        Further keywords of its public solver (not command-line options), checked the same way.
    required : tuple of str
        Options without which it cannot run.
    fixed : mapping
        Solver keywords this method always sets (``rls``: ``noise_order=0``).
    recursive, needs_time, batched : bool
        Processes the samples in time order with an estimate history; uses the sample times;
        is a fixed linear map of the data (solved for all Monte Carlo runs at once).
    std_kind : str
        What its std mean (:data:`casep.estimators.result.STD_KIND_MEANINGS`).
    extras_type : type or None
        The dataclass of its ``EstimateResult.extras`` (with ``describe(result)``).
    linear_map : callable or None
        ``linear_map(S, *, names, sigma, **options) -> LinearMap`` of a batched method.
    hint : str
        What a result of it that does not fit its data most likely means.
    regularised : bool
        Its estimates of poorly determined coefficients are set by the regularisation, not the data
        (an estimate far beyond its declared magnitude is then a warning, not a failure).
    own_noise_model : callable or None
        ``own_noise_model(result) -> NoiseModel`` of a method that fits its own noise model (GLS: one
        tau), instead of solving the rows the data's noise model whitens; None for the others.
    hac : bool
        Newey-West std (``std="hac"``) are defined for it (white-noise least squares).
    flights : SeveralFlights or None
        Its hooks for several flights (None: not available with several flights).
    """

    name: str
    summary: str
    core: Callable[..., EstimateResult]
    public: str
    option_specs: tuple[Option, ...] = ()
    keywords: tuple[Option, ...] = ()
    required: tuple[str, ...] = ()
    fixed: Mapping[str, Any] = field(default_factory=dict)
    recursive: bool = False
    needs_time: bool = False
    batched: bool = False
    std_kind: str = "sampling"
    extras_type: type | None = None
    linear_map: Callable[..., Any] | None = None
    hint: str = ""
    regularised: bool = False
    own_noise_model: Callable[[EstimateResult], Any] | None = None
    hac: bool = False
    flights: SeveralFlights | None = field(default_factory=SeveralFlights)

    def __post_init__(self) -> None:
        if self.std_kind not in STD_KIND_MEANINGS:
            raise ValueError(f"method {self.name}: std_kind must be {', '.join(STD_KIND_MEANINGS)}, "
                             f"got {self.std_kind!r}")
        unknown = [r for r in self.required if r not in self.options]
        if unknown:
            raise ValueError(f"method {self.name}: required option(s) {', '.join(unknown)} not among its options")

    @property
    def options(self) -> tuple[str, ...]:
        """Names of its options."""
        return tuple(o.name for o in self.option_specs)

    @property
    def solver(self) -> str:
        """Name of its public solver function (``solve_ols``)."""
        return self.public

    def option(self, name: str) -> Option:
        """Its option (or solver keyword) `name`."""
        for o in self.option_specs + self.keywords:
            if o.name == name:
                return o
        raise KeyError(name)

    def defaults(self) -> dict[str, Any]:
        """Every option's and keyword's default (None ones left out), and the fixed keywords."""
        out = {o.name: o.default for o in self.option_specs + self.keywords if o.default is not None}
        return {**out, **self.fixed}

    def check_options(self, given: Mapping[str, Any], *, takers: Mapping[str, Sequence[str]] | None = None,
                      flags: Mapping[str, str] | None = None) -> None:
        """Refuse options it does not take, values its rules refuse and missing required options.

        Parameters
        ----------
        given : mapping
            Option name -> value, for the options the caller set.
        takers : mapping, optional
            Option name -> the methods that take it (named in the message).
        flags : mapping, optional
            Option name -> its CLI flag, for options of other methods.
        """
        for name in given:
            if name not in self.options:
                who = list((takers or {}).get(name, ()))
                flag = (flags or {}).get(name, name)
                raise ValueError(f"option {flag} (`{name}`) is not taken by method `{self.name}`; it is an option of "
                                 f"{', '.join(who) or 'no method'}. Use: --method {who[0] if who else '...'}, "
                                 "or leave the option out")
        for name, value in given.items():
            self.option(name).validate(value, self.name)
        for name in self.required:
            if given.get(name) is None:
                o = self.option(name)
                raise ValueError(f"`{name}` is required for method `{self.name}`. Use: {o.flag} {o.rule}")

    def solve(self, problem: Problem, *, sigma: float | None = None, rcond: float | None = None,
              **options: Any) -> EstimateResult:
        """Solve `problem` with checked `options` (missing ones take their defaults).

        Parameters
        ----------
        problem : Problem
            The regression (its rows, or its reduction for a method that needs no rows).
        sigma : float, optional
            Known noise std, m/s.
        rcond : float, optional
            Rank threshold.
        **options
            Its options and solver keywords by name.
        """
        from casep.estimators._base import prepare

        opts = {**self.defaults(), **{k: v for k, v in options.items() if v is not None}}
        return self.core(prepare(problem, None, None, None, None, sigma, rcond), **opts)

    def call(self, S: np.ndarray | Problem, y: np.ndarray | None, t: np.ndarray | None = None, *,
             names: Sequence[str] | None = None, units: Sequence[str] | None = None,
             si_factors: Sequence[float] | np.ndarray | None = None, sigma: float | None = None,
             rcond: float | None = None,
             **options: Any) -> EstimateResult:
        """The public solver: arrays (or a Problem) and keywords checked, then :meth:`solve`."""
        from casep.estimators._base import prepare

        for name in list(options):
            try:
                spec = self.option(name)
            except KeyError:
                raise TypeError(f"{self.public}() got an unexpected keyword argument '{name}'") from None
            options[name] = spec.check(options[name])
        for name in self.required:
            if options.get(name) is None:
                o = self.option(name)
                raise ValueError(f"`{name}` is required for method `{self.name}`. Use: {o.flag} FILE or {name}={{...}}")
        pb = prepare(S, y, names, units, si_factors, sigma, rcond, t=t)
        opts = {**self.defaults(), **{k: v for k, v in options.items() if v is not None}}
        return self.core(pb, **opts)

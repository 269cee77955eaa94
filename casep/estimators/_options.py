"""What a method declares: its options (:mod:`casep.estimators._rules`), capabilities, solver and hooks.

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

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Callable, Mapping, Sequence, TypedDict

import numpy as np

from casep.estimators._base import prepare
from casep.estimators._meanings import STD_KIND_MEANINGS
from casep.estimators._rules import SIGMA, Choices, CoefficientTable, Interval, Option, Rule

if TYPE_CHECKING:
    from casep.estimators.result import EstimateResult
    from casep.regression.joint import JointProblem
    from casep.regression.problem import Problem

__all__ = ["Rule", "Interval", "Choices", "CoefficientTable", "Option", "Labels", "Method", "SeveralFlights",
           "SIGMA"]


class Labels(TypedDict, total=False):
    """What every public solver takes besides the data and the method's options.

    names, units, si_factors : sequence
        Coefficient labels for the result (default ``c0, c1, ...``; a Problem holds its own).
    sigma : float
        Known noise standard deviation, m/s (default: estimated).
    rcond : float
        Rank threshold, see :func:`casep.regression.linalg.analyze_rank`.
    """

    names: Sequence[str] | None
    units: Sequence[str] | None
    si_factors: Sequence[float] | np.ndarray | None
    sigma: float | None
    rcond: float | None


@dataclass(frozen=True)
class SeveralFlights:
    """A method's hooks for several flights (:func:`casep.workflows.flights.separate_flights`).

    The flights become one :class:`~casep.regression.joint.JointProblem`: a reduction-based method
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
        ``core(prepared, *, method, **options) -> EstimateResult`` on a prepared problem
        (:func:`casep.estimators._base.prepare`), options checked and complete; `method` is the Method
        that runs it (the result's name, ``std_kind`` and hint: :func:`casep.estimators._base.finish`).
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
    noise_in_time : bool
        Its noise model runs along time (AR(1), MA): meaningless on rows without a time order
        (the segment means of a ground calibration).
    own_scale : bool
        It estimates its noise scale itself (Huber's MAD) rather than from the residual sum of squares.
    shared_options : callable or None
        ``shared_options(S, Y, t) -> list of dict``: options that runs on one trajectory share, one dict per
        run, computed for all runs at once (Monte Carlo; GLS: one REML search of tau for a chunk of runs).
    max_runs_per_task : int or None
        Most Monte Carlo runs one task holds for it (GLS: the REML lattice of a small chunk).
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
    noise_in_time: bool = False
    own_scale: bool = False
    shared_options: Callable[..., list[dict[str, Any]]] | None = None
    max_runs_per_task: int | None = None
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
                raise ValueError(f"{o.label} is required for method `{self.name}`. Use: {o.flag} {o.rule}")

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
        opts = {**self.defaults(), **{k: v for k, v in options.items() if v is not None}}
        return self.core(prepare(problem, None, None, None, None, sigma, rcond), method=self, **opts)

    def call(self, S: np.ndarray | Problem, y: np.ndarray | None, t: np.ndarray | None = None, *,
             names: Sequence[str] | None = None, units: Sequence[str] | None = None,
             si_factors: Sequence[float] | np.ndarray | None = None, sigma: float | None = None,
             rcond: float | None = None,
             **options: Any) -> EstimateResult:
        """The public solver: arrays (or a Problem) and keywords checked, then :meth:`solve`."""

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
        return self.core(pb, method=self, **opts)

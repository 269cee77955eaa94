"""The estimator registry: every method's options, defaults, rules and capabilities in one table.

``casep separate`` (its option check and ``casep methods``) and :func:`casep.separate` read
this table, so an option the chosen method does not take is an error naming the option and
the method, instead of being silently ignored (``--method ols --lambda 5``).

Each :class:`Method` names its public solver, the options it takes (keywords of
:func:`casep.separate`, with the CLI flag, default and rule), and its capabilities:
``recursive`` (processes samples in time order, has an estimate history), ``needs_time``
(uses the sample times), ``batched`` (a fixed linear map of the data, solved for all runs at
once by ``casep montecarlo``) and ``std_kind`` (what its std mean: sampling, posterior or
conditional; see :data:`casep.estimators.result.STD_KIND_MEANINGS`).
"""

from __future__ import annotations

import dataclasses
import math
import os
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from casep.estimators.result import EXTRAS_TYPES, STD_KIND_MEANINGS

__all__ = ["Rule", "Interval", "Choices", "CoefficientTable", "Option", "Method", "OPTIONS", "METHODS",
           "check_method_options", "describe", "run_method",
           "NOISE_OPTIONS"]


class Rule:
    """A declared rule an option value must satisfy (scikit-learn's ``_parameter_constraints`` idea).

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

    def accepts(self, value: Any) -> bool:
        if isinstance(value, bool):
            return False
        if self.kind is int:
            if not isinstance(value, (int, np.integer)):
                return False
        elif not isinstance(value, (int, float, np.integer, np.floating)):
            return False
        v = float(value)
        if not math.isfinite(v):
            return False
        lo_ok = self.low is None or (v >= self.low if self.closed in ("both", "left") else v > self.low)
        hi_ok = self.high is None or (v <= self.high if self.closed in ("both", "right") else v < self.high)
        return lo_ok and hi_ok

    def parse(self, text: str) -> Any:
        try:
            return int(text) if self.kind is int else float(text)
        except ValueError:
            raise ValueError(f"not {'an integer' if self.kind is int else 'a number'}: {text!r}") from None

    def __str__(self) -> str:
        name = self.kind.__name__
        unit = f" {self.unit}" if self.unit else ""
        if self.high is None:
            return f"{name} {'>=' if self.closed in ('both', 'left') else '>'} {self.low:g}{unit}"
        lb = "[" if self.closed in ("both", "left") else "("
        rb = "]" if self.closed in ("both", "right") else ")"
        return f"{name} in {lb}{self.low:g}, {self.high:g}{rb}{unit}"


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
    """One method option: keyword of :func:`casep.separate`, CLI flag, default, rules.

    A value is valid when one of `rules` accepts it (``None`` means "the default").
    """

    name: str
    flag: str
    default: Any
    rules: tuple[Rule, ...]
    help: str

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

    def parse(self, text: str) -> Any:
        """Command-line text -> a valid value (ValueError naming the rule otherwise)."""
        errors = []
        for r in self.rules:
            try:
                v = r.parse(text)
            except ValueError as exc:
                errors.append(str(exc))
                continue
            if r.accepts(v) or isinstance(r, CoefficientTable):
                return v
            errors.append(f"{text} is outside {r}")
        raise ValueError(f"{self.flag} must be {self.rule}, got {text!r}")


@dataclass(frozen=True)
class Method:
    """One estimator: its solver, options and capabilities."""

    name: str
    solver: str
    summary: str
    options: tuple[str, ...] = ()
    required: tuple[str, ...] = ()
    recursive: bool = False
    needs_time: bool = False
    batched: bool = False
    fixed: tuple[tuple[str, Any], ...] = ()  # solver keywords this method always sets
    #: What the reported std mean (``sampling``, ``posterior`` or ``conditional``; see
    #: ``STD_KIND_MEANINGS``); the default ``std_kind`` of the method's results.
    std_kind: str = "sampling"

    def __post_init__(self) -> None:
        if self.std_kind not in STD_KIND_MEANINGS:
            raise ValueError(f"method {self.name}: std_kind must be {', '.join(STD_KIND_MEANINGS)}, "
                             f"got {self.std_kind!r}")

    @property
    def extras_type(self) -> type | None:
        """The dataclass of the method's ``EstimateResult.extras`` (``EXTRAS_TYPES``)."""
        return EXTRAS_TYPES.get(self.name)


#: Method-specific options (``sigma`` and the de-noising options apply to every method).
OPTIONS: dict[str, Option] = {o.name: o for o in (
    # Ranges as casep.estimators._base.OPTION_RANGES (the solvers' own checks), with the reasons there.
    Option("p0", "--p0", 1e6, (Interval(float, 0, 1e30, "right"),), "P0 = p0 I, natural units (a prior variance)"),
    Option("weight", "--weight", 1.0, (Interval(float, 1e-12, 1e12),), "measurement weight w (variance 1/w)"),
    Option("forgetting", "--forgetting", 1.0, (Interval(float, 0.5, 1, "both"),), "forgetting factor (stabilized)"),
    Option("noise_order", "--noise-order", 1, (Interval(int, 1),), "MA order of the noise model"),
    Option("lam", "--lambda", "gcv", (Choices(("gcv", "lcurve")), Interval(float, 0, None, "neither")),
           "ridge parameter on unit-norm columns, or its rule"),
    Option("bounds", "--bounds", None, (CoefficientTable("{name: [lo, hi] | value}"),), "box bounds and fixed values"),
    Option("prior", "--prior", None, (CoefficientTable("{name: {mean, std}}"),),
           "Gaussian prior per coefficient, or a result file (its estimate and covariance; "
           "docs/guide/result-files.md)"),
    Option("n_components", "--components", None, (Interval(int, 1),),
           "principal components kept (default: CI <= 1000)"),
    Option("tau", "--tau", "auto", (Choices(("auto",)), Interval(float, 0, 1e4, "right", "s")),
           "Gauss-Markov correlation time of the noise model, every method (auto: REML)"),
)}

#: Options of the noise model (:mod:`casep.analysis.noise`) that every method takes through
#: :func:`casep.separate`; ``gls`` also takes them as its own (its one tau for every axis).
NOISE_OPTIONS = ("tau",)

#: Every estimator, in the order of ``casep methods``.
METHODS: dict[str, Method] = {m.name: m for m in (
    Method("ols", "solve_ols", "least squares on the scaled QR reduction", batched=True),
    Method("rls", "solve_rls", "recursive least squares, paper Eq. (14), Bierman U-D",
           ("p0", "weight", "forgetting"), recursive=True, batched=True, fixed=(("noise_order", 0),),
           std_kind="posterior"),
    Method("rels", "solve_rls", "recursive extended least squares (MA noise model)",
           ("p0", "weight", "forgetting", "noise_order"), recursive=True, std_kind="posterior"),
    Method("ridge", "solve_ridge", "ridge regression (GCV, L-curve or given lambda)", ("lam",)),
    Method("bounded", "solve_bounded", "box-bounded least squares (Clarabel + exact polish)", ("bounds",),
           required=("bounds",), std_kind="conditional"),
    Method("pcr", "solve_pcr", "principal-component regression", ("n_components",), batched=True),
    Method("map", "solve_map", "maximum a posteriori with a Gaussian prior", ("prior",), required=("prior",),
           batched=True, std_kind="posterior"),
    Method("gls", "solve_gls", "least squares in Gauss-Markov noise (AR(1) whitening)", ("tau",),
           needs_time=True),
    Method("huber", "solve_huber", "robust (Huber) least squares by IRLS, outliers flagged"),
)}


def check_method_options(method: str, given: Mapping[str, Any]) -> None:
    """Refuse options that `method` does not take, and missing required ones.

    Parameters
    ----------
    method : str
        A key of :data:`METHODS`.
    given : mapping
        Option name (:data:`OPTIONS` key) -> value, for the options the caller set.

    Raises
    ------
    ValueError
        Naming the option (with its CLI flag), the method, and the methods that take it; or
        naming the option, the method and its rule when a value breaks the option's rules.
    """
    if method not in METHODS:
        raise ValueError(f"`method` must be one of {', '.join(METHODS)}, got {method!r}")
    m = METHODS[method]
    for name in given:
        if name not in m.options:
            takers = [k for k, v in METHODS.items() if name in v.options]
            flag = OPTIONS[name].flag if name in OPTIONS else name
            raise ValueError(f"option {flag} (`{name}`) is not taken by method `{method}`; it is an option of "
                             f"{', '.join(takers) or 'no method'}. Use: --method {takers[0] if takers else '...'}, "
                             "or leave the option out")
    for name, value in given.items():
        OPTIONS[name].validate(value, method)
    for name in m.required:
        if given.get(name) is None:
            raise ValueError(f"`{name}` is required for method `{method}`. Use: {OPTIONS[name].flag} "
                             f"{OPTIONS[name].rule}")


#: Where each solver lives (imported on first use, so that the registry imports no estimator).
_MODULES = {"solve_ols": "ols", "solve_rls": "rls", "solve_ridge": "ridge", "solve_bounded": "bounded",
            "solve_pcr": "pcr", "solve_map": "map", "solve_gls": "gls", "solve_huber": "huber"}


def solver(method: str):
    """The public solver function of a registered method."""
    import importlib

    name = METHODS[method].solver
    return getattr(importlib.import_module(f"casep.estimators.{_MODULES[name]}"), name)


def describe() -> list[dict[str, Any]]:
    """The registry as plain data (``casep methods --json``)."""
    out = []
    for m in METHODS.values():
        out.append({"name": m.name, "solver": f"casep.{m.solver}", "summary": m.summary,
                    "options": [{"name": o, "flag": OPTIONS[o].flag, "default": OPTIONS[o].default,
                                 "rule": OPTIONS[o].rule, "help": OPTIONS[o].help} for o in m.options],
                    "required": list(m.required), "recursive": m.recursive, "needs_time": m.needs_time,
                    "batched_in_montecarlo": m.batched, "std_kind": m.std_kind,
                    "std_kind_meaning": STD_KIND_MEANINGS[m.std_kind],
                    "extras": None if m.extras_type is None else
                    {"type": m.extras_type.__name__, "fields": [f.name for f in dataclasses.fields(m.extras_type)]}})
    return out


def run_method(method: str, S, y, t, options: Mapping[str, Any], **labels) -> Any:
    """Solve with a registered method: its public solver, its options, the labels.

    Parameters
    ----------
    method : str
        A key of :data:`METHODS`.
    S, y, t : array_like
        Regression ``(N, 3, n)``, velocity error ``(N, 3)`` and sample times ``(N,)``.
    options : mapping
        The method's options (keys of its :attr:`Method.options`; missing ones take the
        :data:`OPTIONS` default; required ones go to the solver positionally).
    **labels
        ``names``, ``units``, ``si_factors``, ``sigma`` and solver extras (e.g. PCR's
        ``max_condition_index``).

    Returns
    -------
    EstimateResult
    """
    check_method_options(method, {k: v for k, v in options.items() if v is not None})
    m = METHODS[method]
    args = [S, y] + ([t] if m.needs_time else []) + [options[r] for r in m.required]
    kw = {o: options.get(o, OPTIONS[o].default) for o in m.options if o not in m.required}
    kw = {k: v for k, v in kw.items() if v is not None}
    return solver(method)(*args, **kw, **dict(m.fixed), **labels)

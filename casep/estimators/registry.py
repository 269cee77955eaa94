"""The estimator registry: every method, as its module declares it.

Each estimator module declares its :class:`~casep.estimators._options.Method` beside its solver
(options with their rules, capabilities, extras, linear map, failure hint, hooks for several
flights); this module collects them by ordinary imports. ``casep separate`` (its option check and
``casep methods``), :func:`casep.separate`, the several-flight path and Monte Carlo read
:data:`METHODS` and nothing else, so an option the chosen method does not take is an error naming
the option and the method, instead of being silently ignored (``--method ols --lambda 5``).

Capabilities: ``recursive`` (processes samples in time order, has an estimate history),
``needs_time`` (uses the sample times), ``batched`` (a fixed linear map of the data, solved for
all runs at once by ``casep montecarlo``) and ``std_kind`` (what its std mean: sampling,
posterior or conditional; see :data:`casep.estimators.result.STD_KIND_MEANINGS`).

A method of one's own is one module declaring a ``Method``, registered with :func:`register`
(``docs/guide/adding-an-estimator.md``).
"""

from __future__ import annotations

import dataclasses
import sys
from typing import Any, Callable, Mapping

import numpy as np

from casep.estimators._base import (  # what a method's core uses (a method of one's own), and a result's judgement
    FAILURE_STATUSES,
    STATUS_DISAGREE,
    STATUS_MAGNITUDE,
    STATUS_MISFIT,
    STATUS_NOT_CONVERGED,
    STATUS_PRIOR_CONFLICT,
    STATUS_SETUP,
    STATUS_TRACKING,
    Prepared,
    check_magnitudes,
    declared_magnitude,
    failed,
    finish,
    not_determined,
    prepare,
)
from casep.estimators._options import (
    SIGMA,
    Choices,
    CoefficientTable,
    Interval,
    Labels,
    Method,
    Option,
    Rule,
    SeveralFlights,
)
from casep.estimators._rules import option_label, refusal
from casep.estimators.bounded import BOUNDED
from casep.estimators.gls import GLS
from casep.estimators.huber import HUBER
from casep.estimators.map import MAP
from casep.estimators.ols import OLS
from casep.estimators.pcr import PCR
from casep.estimators.result import EXTRAS_TYPES, STD_KIND_MEANINGS, EstimateResult
from casep.estimators.ridge import RIDGE
from casep.estimators.rls import RELS, RLS

__all__ = ["Rule", "Interval", "Choices", "CoefficientTable", "Option", "Method", "OPTIONS", "METHODS",
           "check_method_options", "describe", "run_method", "solver", "register", "unregister", "NOISE_OPTIONS",
           "option_ranges", "SIGMA", "SeveralFlights", "Labels", "Prepared", "prepare", "finish", "failed",
           "check_magnitudes", "declared_magnitude", "not_determined", "STATUS_SETUP", "STATUS_MAGNITUDE",
           "STATUS_TRACKING", "STATUS_MISFIT",
           "STATUS_NOT_CONVERGED", "STATUS_DISAGREE", "STATUS_PRIOR_CONFLICT", "FAILURE_STATUSES", "option_label",
           "refusal"]

#: Every estimator, in the order of ``casep methods``.
METHODS: dict[str, Method] = {m.name: m for m in (OLS, RLS, RELS, RIDGE, BOUNDED, PCR, MAP, GLS, HUBER)}


def _options() -> dict[str, Option]:
    """The options of every method by name (and the result's table of extras types, kept in step)."""
    EXTRAS_TYPES.clear()
    EXTRAS_TYPES.update({k: m.extras_type for k, m in METHODS.items() if m.extras_type is not None})
    out: dict[str, Option] = {}
    for m in METHODS.values():
        for o in m.option_specs:
            if o.name in out and out[o.name] != o:
                raise ValueError(f"method {m.name}: option `{o.name}` differs from the one of the same name "
                                 "another method declares")
            out.setdefault(o.name, o)
    return out


#: Method options by name (``sigma`` and the noise and de-noising options apply to every method).
OPTIONS: dict[str, Option] = _options()

#: Options of the noise model (:mod:`casep.noise.model`) that every method takes through
#: :func:`casep.separate`; ``gls`` also takes them as its own (its one tau for every axis).
NOISE_OPTIONS = ("tau",)


def register(method: Method, *, replace: bool = False) -> Method:
    """Add a method of one's own to the registry (``casep.separate(..., method=its name)``).

    Parameters
    ----------
    method : Method
        Its declaration (``docs/guide/adding-an-estimator.md``).
    replace : bool, optional
        Replace a registered method of the same name (default: ValueError).

    Returns
    -------
    Method
        `method`, so that ``MINE = register(Method(...))`` reads as one declaration.
    """
    if not isinstance(method, Method):
        raise TypeError(f"`method` must be a casep.estimators.registry.Method, got {type(method).__name__}")
    if method.name in METHODS and not replace:
        raise ValueError(f"method `{method.name}` is registered already (replace=True to replace it)")
    old = METHODS.get(method.name)
    METHODS[method.name] = method
    try:
        OPTIONS.clear()
        OPTIONS.update(_options())
    except ValueError:
        if old is None:
            del METHODS[method.name]
        else:
            METHODS[method.name] = old
        OPTIONS.update(_options())
        raise
    return method


def unregister(name: str) -> None:
    """Remove a method added by :func:`register`."""
    METHODS.pop(name)
    OPTIONS.clear()
    OPTIONS.update(_options())


def check_method_options(method: str, given: Mapping[str, Any]) -> None:
    """Refuse options that `method` does not take, values its rules refuse, and missing required ones.

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
        raise refusal("method", "--method", " | ".join(METHODS), method)
    own = set(METHODS[method].options)
    foreign = [name for name in given if name not in own]  # only these need the takers, for the message
    takers = {name: [k for k, v in METHODS.items() if name in v.options] for name in foreign}
    flags = {name: OPTIONS[name].flag for name in foreign if name in OPTIONS}
    METHODS[method].check_options(given, takers=takers, flags=flags)


def solver(method: str) -> Callable[..., EstimateResult]:
    """The public solver function of a registered method (``casep.solve_ols`` for ``ols``)."""
    m = METHODS[method]
    return getattr(sys.modules[m.core.__module__], m.public)


def describe() -> list[dict[str, Any]]:
    """The registry as plain data (``casep methods --json``)."""
    out = []
    for m in METHODS.values():
        out.append({"name": m.name, "solver": f"casep.{m.public}", "summary": m.summary,
                    "options": [{"name": o.name, "flag": o.flag, "default": o.default, "rule": o.rule, "help": o.help}
                                for o in m.option_specs],
                    "required": list(m.required), "recursive": m.recursive, "needs_time": m.needs_time,
                    "batched_in_montecarlo": m.batched, "std_kind": m.std_kind,
                    "std_kind_meaning": STD_KIND_MEANINGS[m.std_kind],
                    "extras": None if m.extras_type is None else
                    {"type": m.extras_type.__name__, "fields": [f.name for f in dataclasses.fields(m.extras_type)]}})
    return out


def run_method(method: str, S: Any, y: np.ndarray | None, t: np.ndarray | None, options: Mapping[str, Any],
               **labels: Any) -> EstimateResult:
    """Solve with a registered method: its options checked, missing ones at their defaults.

    Parameters
    ----------
    method : str
        A key of :data:`METHODS`.
    S, y, t : array_like, or a Problem and None
        Regression ``(N, 3, n)``, velocity error ``(N, 3)`` and sample times ``(N,)`` (used by a
        method that ``needs_time``), or a :class:`~casep.regression.problem.Problem` (`y` None).
    options : mapping
        The method's options (keys of its :attr:`Method.options`; missing ones take their defaults).
    **labels
        ``names``, ``units``, ``si_factors``, ``sigma``, ``rcond`` and solver keywords (e.g. PCR's
        ``max_condition_index``).

    Returns
    -------
    EstimateResult
    """
    from casep.estimators._base import prepare

    check_method_options(method, {k: v for k, v in options.items() if v is not None})
    m = METHODS[method]
    keys = ("names", "units", "si_factors", "sigma", "rcond")
    keywords = {k: m.option(k).check(v) for k, v in labels.items() if k not in keys}
    pb = prepare(S, y, labels.get("names"), labels.get("units"), labels.get("si_factors"), labels.get("sigma"),
                 labels.get("rcond"), t=t if m.needs_time else None)
    opts = {**m.defaults(), **{k: v for k, v in options.items() if v is not None}, **keywords}
    return m.core(pb, method=m, **opts)


def option_ranges() -> dict[str, tuple[float, float, bool, str]]:
    """``name -> (low, high, low_inclusive, why)`` of the bounded scalar options and ``sigma``: the
    ranges the Options declare."""
    out = {}
    for o in (SIGMA, *OPTIONS.values()):
        for r in o.rules:
            if isinstance(r, Interval) and r.kind is float and r.high is not None:
                out[o.name] = (float(r.low or 0.0), float(r.high), r.low_closed, o.why)
    return out

"""The estimators, their registry and their result.

Depends on :mod:`casep.regression` (the problem, its reduction and rank), :mod:`casep.noise`,
:mod:`casep.checks` (diagnostics, residual checks) and :mod:`casep.model` (names and units only).
A new estimator is one module here, one line in :mod:`casep.estimators.registry` and its test
(``docs/guide/adding-an-estimator.md``); outside casep, :func:`register`.

- one module per method, each declaring its :class:`Method` beside its solver: ``ols``, ``rls``
  (RLS and RELS), ``ridge``, ``bounded``, ``pcr``, ``map``, ``gls``, ``huber``
- :mod:`casep.estimators.registry`: the methods collected (:data:`METHODS`), option checks
- :mod:`casep.estimators.spec`: :class:`FitSpec`, what a user asks of a fit (method, options, sigma,
  :class:`NoiseSpec`), checked once where it enters casep; every path (workflows, calibration,
  Monte Carlo) takes it
- :mod:`casep.estimators.solve`: :func:`~casep.estimators.solve.fit`, the one entry point of every fit
  (one flight, several flights, radar, Monte Carlo, demo, calibration): the request's method on the rows
  of its noise model, then the residual checks
- :mod:`casep.estimators._options`: what a method declares (options, rules, capabilities, hooks)
- :mod:`casep.estimators._base`: the scaled reduction a solver works on, the result it builds
- :mod:`casep.estimators.result`: :class:`EstimateResult` (frozen; JSON, text)
- :mod:`casep.estimators.reading`: result files read back and checked against their model
- :mod:`casep.estimators.joint`: consistency of several flights, fusion by square-root information
"""

# The registry imports every estimator module (numpy only at import: cvxpy, numba and scipy load when a
# solver runs), so that the methods, their options and their results' extras types are known together.
from casep.estimators.bounded import solve_bounded
from casep.estimators.gls import solve_gls
from casep.estimators.huber import solve_huber
from casep.estimators.map import solve_map
from casep.estimators.ols import solve_ols
from casep.estimators.pcr import solve_pcr
from casep.estimators.registry import (
    METHODS,
    Choices,
    CoefficientTable,
    Interval,
    Method,
    Option,
    Prepared,
    SeveralFlights,
    describe,
    finish,
    prepare,
    register,
    unregister,
)
from casep.estimators.result import EstimateResult
from casep.estimators.ridge import solve_ridge
from casep.estimators.rls import solve_rls
from casep.estimators.spec import FitSpec, NoiseSpec

__all__ = ["solve_bounded", "solve_gls", "solve_huber", "solve_map", "solve_ols", "solve_pcr", "solve_ridge",
           "solve_rls", "METHODS", "describe", "register", "unregister", "Method", "SeveralFlights", "Option",
           "Interval", "Choices", "CoefficientTable", "Prepared", "prepare", "finish", "EstimateResult",
           "FitSpec", "NoiseSpec"]

"""The estimators, their registry and their result.

Depends on :mod:`casep.analysis` (reduction, rank, diagnostics) and :mod:`casep.model` (names
and units only). A new estimator is one module here, one line in :mod:`casep.estimators.registry`
and its test (``docs/guide/adding-an-estimator.md``); outside casep, :func:`register`.

- one module per method, each declaring its :class:`Method` beside its solver: ``ols``, ``rls``
  (RLS and RELS), ``ridge``, ``bounded``, ``pcr``, ``map``, ``gls``, ``huber``
- :mod:`casep.estimators.registry`: the methods collected (:data:`METHODS`), option checks
- :mod:`casep.estimators._options`: what a method declares (options, rules, capabilities, hooks)
- :mod:`casep.estimators._base`: the scaled reduction a solver works on, the result it builds
- :mod:`casep.estimators.result`: :class:`EstimateResult` (frozen; JSON, text)
- :mod:`casep.estimators.reading`: result files read back and checked against their model
- :mod:`casep.estimators.joint`: consistency of several flights, fusion by square-root information
"""

from casep._lazy import attach

# Imported on first use (PEP 562): the registry is read without importing every solver.
__getattr__, __dir__ = attach(__name__, {
    "casep.estimators.bounded": ("solve_bounded",), "casep.estimators.gls": ("solve_gls",),
    "casep.estimators.huber": ("solve_huber",), "casep.estimators.map": ("solve_map",),
    "casep.estimators.ols": ("solve_ols",), "casep.estimators.pcr": ("solve_pcr",),
    "casep.estimators.ridge": ("solve_ridge",), "casep.estimators.rls": ("solve_rls",),
    "casep.estimators.registry": ("METHODS", "describe", "register", "unregister", "Method", "SeveralFlights",
                                  "Option"),
    "casep.estimators.result": ("EstimateResult",)}, globals())

__all__ = ["solve_bounded", "solve_gls", "solve_huber", "solve_map", "solve_ols", "solve_pcr", "solve_ridge",
           "solve_rls", "METHODS", "describe", "register", "unregister", "Method", "SeveralFlights", "Option",
           "EstimateResult"]

"""The estimators, their registry and their result.

Depends on :mod:`casep.analysis` (reduction, rank, diagnostics) and :mod:`casep.model` (names
and units only). A new estimator is one module here, one line in :mod:`casep.estimators.registry`
and its test.

- :mod:`casep.estimators.registry`: method name -> solver, options with rules, capabilities
- :mod:`casep.estimators._base`: validation at the edge, the scaled reduction, the result
- :mod:`casep.estimators.result`: :class:`EstimateResult` (frozen; JSON, MAT, CSV)
- one module per method: ``ols``, ``rls`` (RLS and RELS), ``ridge``, ``bounded``, ``pcr``,
  ``map``, ``gls``, ``huber``
"""

from casep._lazy import attach

# Imported on first use (PEP 562): the registry is read without importing every solver.
__getattr__, __dir__ = attach(__name__, {
    "casep.estimators.bounded": ("solve_bounded",), "casep.estimators.gls": ("solve_gls",),
    "casep.estimators.huber": ("solve_huber",), "casep.estimators.map": ("solve_map",),
    "casep.estimators.ols": ("solve_ols",), "casep.estimators.pcr": ("solve_pcr",),
    "casep.estimators.ridge": ("solve_ridge",), "casep.estimators.rls": ("solve_rls",),
    "casep.estimators.registry": ("METHODS", "describe"), "casep.estimators.result": ("EstimateResult",)}, globals())

__all__ = ["solve_bounded", "solve_gls", "solve_huber", "solve_map", "solve_ols", "solve_pcr", "solve_ridge",
           "solve_rls", "METHODS", "describe", "EstimateResult"]

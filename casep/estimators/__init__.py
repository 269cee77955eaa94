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

from casep.estimators.bounded import solve_bounded
from casep.estimators.gls import solve_gls
from casep.estimators.huber import solve_huber
from casep.estimators.map import solve_map
from casep.estimators.ols import solve_ols
from casep.estimators.pcr import solve_pcr
from casep.estimators.registry import METHODS, describe
from casep.estimators.result import EstimateResult
from casep.estimators.ridge import solve_ridge
from casep.estimators.rls import solve_rls

__all__ = ["solve_bounded", "solve_gls", "solve_huber", "solve_map", "solve_ols", "solve_pcr", "solve_ridge",
           "solve_rls", "METHODS", "describe", "EstimateResult"]

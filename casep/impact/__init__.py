"""The miss that the instrument errors cause: impact point of the burnout state by vacuum
ballistic flight and the miss budget of an estimate (``docs/reference/file-formats.md`` "Impact JSON").

- :mod:`casep.impact.ballistic`: closed-form Kepler impact point and its exact Jacobian
- :mod:`casep.impact.miss`: S_P, miss sensitivities, predicted miss with covariance,
  contributions per coefficient and per near-dependency group, nonlinear miss
- :mod:`casep.impact.result`: :class:`ImpactAnalysis`, the miss budget (``to_dict()``, ``text()``)
- :func:`read_trajectory` (:mod:`casep.io.trajectory`): a trajectory file
"""

from casep._lazy import attach

# Imported on first use (PEP 562), see casep._lazy.
__getattr__, __dir__ = attach(__name__, {
    "casep.impact.ballistic": ("BallisticError", "impact", "impact_point", "impact_jacobian", "impact_point_ode"),
    "casep.impact.miss": ("impact_analysis", "burnout_state", "position_sensitivity", "cumulative_sp"),
    "casep.impact.result": ("ImpactAnalysis",),
    "casep.io.trajectory": ("read_trajectory",)},
    globals())

__all__ = ["BallisticError", "impact", "impact_point", "impact_jacobian", "impact_point_ode", "ImpactAnalysis",
           "impact_analysis", "burnout_state", "position_sensitivity", "cumulative_sp", "read_trajectory"]

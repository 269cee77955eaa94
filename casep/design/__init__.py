"""Optimal experiment design: the attitude manoeuvre that minimises a Cramer-Rao objective (``casep design``).

:mod:`casep.design.maneuver` (piecewise-linear attitude offsets), :mod:`casep.design.objective`
(S_V and the Fisher information as CasADi functions of the offsets; objectives A, D, miss) and
:mod:`casep.design.optimize` (:func:`design`: IPOPT from several starts, re-simulated check).
"""

from casep._lazy import attach

_LAZY_MODULES = {
    "casep.design.maneuver": ("Maneuver",),
    "casep.design.objective": ("DesignProblem", "OBJECTIVES"),
    "casep.design.optimize": ("design",),
    "casep.design.result": ("DesignResult",),
}
__getattr__, __dir__ = attach(__name__, _LAZY_MODULES, globals(), ())
__all__ = ["Maneuver", "DesignProblem", "OBJECTIVES", "design", "DesignResult"]

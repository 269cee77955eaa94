"""Deprecated: the names of casep 0.3's ``casep.analysis``, now in :mod:`casep.regression`,
:mod:`casep.noise` and :mod:`casep.checks`.

Importing this package warns (:class:`DeprecationWarning`); it goes in the next release. Its
modules (``casep.regression.problem`` and the like) are gone: import from the new packages.
"""

import warnings

from casep._lazy import attach

warnings.warn("casep.analysis is deprecated and goes in the next release: its names are in casep.regression "
              "(Problem, reduce_qr, prepare_rows, ...), casep.noise (NoiseModel, fit_noise, ...) and casep.checks "
              "(check_flight, check_fit, diagnose, ...)", DeprecationWarning, stacklevel=2)

# Imported on first use (PEP 562), see casep._lazy.
__getattr__, __dir__ = attach(__name__, {
    "casep.checks.plausibility": ("check_fit", "check_flight"),
    "casep.checks.diagnostics": ("Diagnostics", "diagnose"),
    "casep.regression.linalg": ("RankAnalysis", "ReducedSystem", "analyze_rank", "reduce_qr", "reduce_qr_blocks"),
    "casep.regression.problem": ("Problem",),
    "casep.noise.model": ("NoiseModel",),
    "casep.noise.fit": ("fit_noise",),
    "casep.noise.whiteness": ("whiteness_test",),
    "casep.noise.robust": ("robust_filter",),
    "casep.regression.rows": ("Rows", "prepare_rows")}, globals())

__all__ = ["check_fit", "check_flight", "Diagnostics", "diagnose", "RankAnalysis", "ReducedSystem",
           "analyze_rank", "reduce_qr", "reduce_qr_blocks", "Problem", "NoiseModel", "fit_noise", "whiteness_test",
           "robust_filter", "Rows", "prepare_rows"]
